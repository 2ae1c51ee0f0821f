"""National road style: traffic side, standard widths and lane-marking patterns by country.

The country is found from the origin with coarse bounding boxes (a few per country, first
match wins; good enough for the extracts we simulate, overridable by a setting). The
values are the usual motorway standards, rounded (sources: German RAA / RMS, Austrian RVS,
US MUTCD / AASHTO, UK TSRGD, Finnish and Australian AS 1742 road-marking rules, Japanese
expressway practice); where a country's rule was not certain the nearest common value is
used and noted.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from ..._errors import InputError
from ..scenario import Markings


@dataclass(frozen=True)
class RoadStyle:
    """One country's motorway cross-section and paint.

    Widths in metres; ``markings`` gives the dash/gap lengths (metres) of lane lines and of
    the line beside auxiliary (deceleration, acceleration, weaving) lanes and the paint
    widths; edge lines are solid.
    """

    country: str
    traffic: Literal["right", "left"]
    lane_width_m: float
    ramp_lane_width_m: float
    inner_shoulder_m: float
    hard_shoulder_m: float
    markings: Markings

    def to_dict(self) -> dict:
        """Plain dict for truth.json."""
        m = self.markings
        return {
            "country": self.country,
            "traffic": self.traffic,
            "lane_width_m": self.lane_width_m,
            "inner_shoulder_m": self.inner_shoulder_m,
            "hard_shoulder_m": self.hard_shoulder_m,
            "lane_line": {"dash_m": m.dash_m, "gap_m": m.gap_m, "width_m": m.lane_line_width_m},
            "aux_line": {
                "dash_m": m.aux_dash_m,
                "gap_m": m.aux_gap_m,
                "width_m": m.edge_line_width_m,
            },
            "edge_line": {"type": "solid", "width_m": m.edge_line_width_m},
        }


STYLES: dict[str, RoadStyle] = {
    # Germany: RAA motorway lanes 3.50-3.75 m, 0.75 m inner edge strip, 2.50 m hard
    # shoulder; RMS lane line 6 m / 12 m, 0.15 m; line beside an auxiliary lane 6 m / 6 m
    # and edge lines 0.30 m wide
    "DE": RoadStyle("DE", "right", 3.75, 3.5, 0.75, 2.5, Markings(6.0, 12.0, 6.0, 6.0, 0.15, 0.30)),
    # Austria: RVS lane line 6 m / 12 m as in Germany; 3.75 m lanes, 2.5-3.0 m shoulder
    "AT": RoadStyle("AT", "right", 3.75, 3.5, 0.6, 2.75, Markings(6.0, 12.0, 6.0, 6.0, 0.15, 0.25)),
    # USA: MUTCD lane line 10 ft / 30 ft, 4-6 in; dotted line at auxiliary lanes 3 ft / 9 ft,
    # 8 in; 12 ft lanes, 4 ft left and 10 ft right shoulders (AASHTO)
    "US": RoadStyle(
        "US", "right", 3.66, 3.66, 1.2, 3.0, Markings(3.05, 9.14, 0.91, 2.74, 0.15, 0.20)
    ),
    # United Kingdom (left-hand): lane line 2 m / 7 m; line at slip roads 1 m / 1 m (TSRGD
    # 1010); 3.65 m lanes, 0.7 m hard strip, 3.3 m hard shoulder
    "GB": RoadStyle("GB", "left", 3.65, 3.65, 0.7, 3.3, Markings(2.0, 7.0, 1.0, 1.0, 0.15, 0.25)),
    "IE": RoadStyle("IE", "left", 3.5, 3.5, 0.5, 2.5, Markings(2.0, 7.0, 1.0, 1.0, 0.15, 0.25)),
    # Finland: lane line 3 m / 9 m; auxiliary line 3 m / 3 m (nearest common value)
    "FI": RoadStyle("FI", "right", 3.5, 3.5, 0.75, 2.5, Markings(3.0, 9.0, 3.0, 3.0, 0.10, 0.20)),
    # Australia (left-hand): AS 1742.2 lane line 3 m / 9 m, continuity line 1 m / 3 m 0.2 m
    "AU": RoadStyle("AU", "left", 3.5, 3.5, 1.0, 2.5, Markings(3.0, 9.0, 1.0, 3.0, 0.10, 0.20)),
    "NZ": RoadStyle("NZ", "left", 3.5, 3.5, 1.0, 2.5, Markings(3.0, 7.0, 1.0, 3.0, 0.10, 0.20)),
    # Japan (left-hand): expressway lane line 8 m / 12 m (nearest common value)
    "JP": RoadStyle("JP", "left", 3.5, 3.5, 0.75, 2.5, Markings(8.0, 12.0, 3.0, 3.0, 0.15, 0.20)),
}
STYLES["CH"] = STYLES["DE"]

# (country, lon_min, lat_min, lon_max, lat_max); first match wins, so the smaller or
# more specific boxes come first
_BOXES: tuple[tuple[str, float, float, float, float], ...] = (
    ("AT", 9.53, 46.37, 13.0, 47.6),
    ("AT", 13.0, 46.37, 17.16, 48.55),
    ("AT", 14.5, 48.55, 17.16, 49.02),
    ("CH", 5.96, 45.82, 10.49, 47.6),
    ("DE", 5.87, 47.27, 15.04, 55.06),
    ("IE", -10.5, 51.4, -6.0, 55.4),
    ("GB", -8.2, 49.9, 1.8, 60.9),
    ("FI", 20.55, 59.8, 31.59, 70.1),
    ("US", -125.0, 24.4, -66.9, 49.4),
    ("US", -170.0, 51.0, -130.0, 71.5),
    ("AU", 112.9, -43.7, 153.7, -10.6),
    ("NZ", 166.0, -47.3, 179.0, -34.4),
    ("JP", 122.9, 24.0, 145.9, 45.6),
)


def country_at(lon_deg: float, lat_deg: float) -> str | None:
    """ISO code of the country whose coarse box holds the point, or None."""
    for code, lo_x, lo_y, hi_x, hi_y in _BOXES:
        if lo_x <= lon_deg <= hi_x and lo_y <= lat_deg <= hi_y:
            return code
    return None


def road_style(
    lon_deg: float, lat_deg: float, *, country: str = "auto", traffic: str = "auto"
) -> RoadStyle:
    """The style at a point (``country="auto"``) or of ``country``; ``traffic`` overrides
    the side of traffic. Outside every box: the German style (a neutral motorway)."""
    from dataclasses import replace

    code = country_at(lon_deg, lat_deg) if country == "auto" else country.upper()
    if code is None:
        code = "DE"
    if code not in STYLES:
        msg = f"unknown country {country!r} (known: {', '.join(sorted(STYLES))})"
        raise InputError(msg)
    style = STYLES[code]
    if traffic != "auto":
        if traffic not in ("right", "left"):
            msg = f"traffic must be 'auto', 'right' or 'left', got {traffic!r}"
            raise InputError(msg)
        style = replace(style, traffic=traffic)  # type: ignore[arg-type]
    return style
