"""Cross-sections of roads built from OSM: widths from a measured road or defaults, lane
sections from the OSM lane counts.

A carriageway built from OSM has the measured carriageway's layout (DESIGN.md): inner
shoulder, driving lanes, hard shoulder, the reference line on the median-side edge. Where
the OSM lane count changes the outer driving lane opens from zero width after the change
(a lane gain) or closes to zero width before it (a lane drop), each over ``taper_m`` in
a lane section of its own; linked lanes keep their widths across section boundaries and
a lane has no link at its zero-width end.

Lane ids: ``-1`` inner shoulder, ``-2 .. -(n+1)`` driving, ``-(n+2)`` hard shoulder for
right-hand traffic (lanes right of the reference line); positive and mirrored for
left-hand traffic. Widths in metres, stations in metres along the road.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..model import CubicPiece, CubicProfile, Lane, LaneSection, Road, RoadMark
from ..ramps import width_transition

FloatArray = NDArray[np.float64]

__all__ = ["CrossSection", "lane_sections", "measured_cross_section"]

_MIN_DRIVING_M = 2.5  # a driving lane of the measured road narrower than this is a taper


@dataclass(frozen=True)
class CrossSection:
    """Widths (metres) of an OSM-built carriageway: driving lane, inner (median-side)
    shoulder, hard shoulder (0: none)."""

    lane_width_m: float = 3.5
    inner_shoulder_m: float = 0.75
    hard_shoulder_m: float = 2.5

    def half_width_m(self, lanes: float | FloatArray) -> float | FloatArray:
        """Distance (metres) from the median-side edge to the middle of ``lanes`` driving
        lanes (a number or an array of them): where OSM draws the way."""
        return self.inner_shoulder_m + 0.5 * lanes * self.lane_width_m


def _traffic_lanes(section: LaneSection, traffic_side: str) -> tuple[Lane, ...]:
    return section.right if traffic_side == "right" else section.left


def measured_cross_section(
    road: Road, *, traffic_side: str = "right", default: CrossSection | None = None
) -> CrossSection:
    """The typical widths of a measured carriageway: medians, every 10 m, of its driving
    lanes (at least 2.5 m wide), its median-side shoulder and its outer shoulder (lanes
    before the first / after the last driving lane); ``default`` where it has none."""
    base = default or CrossSection()
    s = np.arange(5.0, road.length, 10.0)
    if s.size == 0:
        return base
    driving: list[np.ndarray] = []
    inner: list[np.ndarray] = []
    hard: list[np.ndarray] = []
    sec_idx = road.section_index(s)
    for k in np.unique(sec_idx):
        sec = road.lane_sections[int(k)]
        ds = s[sec_idx == k] - sec.s0
        lanes = _traffic_lanes(sec, traffic_side)
        kinds = [ln.type for ln in lanes]
        if "driving" not in kinds:
            continue
        first, last = kinds.index("driving"), len(kinds) - 1 - kinds[::-1].index("driving")
        for i, ln in enumerate(lanes):
            w = ln.width.value(ds)
            if first <= i <= last and ln.type == "driving":
                driving.append(w[w >= _MIN_DRIVING_M])
            elif i < first:
                inner.append(w)
            elif i > last:
                hard.append(w)

    def median(parts: list[np.ndarray], fallback: float) -> float:
        values = np.concatenate(parts) if parts else np.zeros(0)
        return float(np.median(values)) if values.size else fallback

    return CrossSection(
        lane_width_m=median(driving, base.lane_width_m),
        inner_shoulder_m=median(inner, base.inner_shoulder_m),
        hard_shoulder_m=median(hard, base.hard_shoulder_m),
    )


def _closing(width: float, length: float) -> CubicProfile:
    """C1 cubic from ``width`` (at 0) to zero (at ``length``), metres."""
    t = max(length, 1e-6)
    return CubicProfile((CubicPiece(0.0, width, 0.0, -3.0 * width / t**2, 2.0 * width / t**3),))


def _opening(width: float, length: float, span: float) -> CubicProfile:
    """C1 cubic from zero to ``width`` over ``length`` (at most the section's ``span``),
    then constant."""
    a, b = width_transition(0.0, width, min(length, span))
    return CubicProfile((a, b))


def lane_sections(
    length_m: float,
    counts: list[tuple[float, int]] | list[tuple[float, int, bool]],
    cross: CrossSection,
    *,
    traffic_side: str = "right",
    taper_m: float = 80.0,
) -> tuple[LaneSection, ...]:
    """Lane sections of an OSM-built carriageway from its lane counts along the road.

    Parameters
    ----------
    length_m
        Road length (metres).
    counts
        ``(station, lanes[, gore])`` where each lane count starts (metres, sorted; the
        first at 0). ``gore`` True: the lanes gained or dropped there start or end at full
        width (an entry's lanes joining, an exit's lanes leaving: a gore, which the ramp
        stage finds in the sections); else they open or close over ``taper_m``.
    cross
        Widths; a zero shoulder width leaves that shoulder out.
    traffic_side
        ``"right"``: lanes right of the reference line (negative ids); ``"left"`` mirrored.
    taper_m
        Length (metres) over which a gained lane opens or a dropped lane closes.

    Returns
    -------
    Sections with lane links between them (lanes of the same role continue; an opening
    lane has no predecessor, a closing one no successor).
    """
    changes: list[tuple[float, int, bool]] = []
    for item in counts:
        s, n = float(item[0]), max(1, int(item[1]))
        gore = bool(item[2]) if len(item) > 2 else False  # type: ignore[misc]
        if not changes or n != changes[-1][1]:
            changes.append((min(max(s, 0.0), length_m), n, gore))
    changes[0] = (0.0, changes[0][1], False)
    changes = [c for i, c in enumerate(changes) if i == 0 or c[0] > changes[i - 1][0] + 1.0]
    # per section: (start, end, lanes, {driving lane index: width profile})
    plan: list[tuple[float, float, int, dict[int, CubicProfile]]] = []
    w = cross.lane_width_m
    for i, (start, n, gore) in enumerate(changes):
        end = changes[i + 1][0] if i + 1 < len(changes) else length_m
        gained = n - changes[i - 1][1] if i > 0 and changes[i - 1][1] < n and not gore else 0
        dropped = 0
        if i + 1 < len(changes) and changes[i + 1][1] < n and not changes[i + 1][2]:
            dropped = n - changes[i + 1][1]
        close_at = max(start + 0.5 * (end - start), end - taper_m) if dropped else end
        opening = {j: _opening(w, taper_m, close_at - start) for j in range(n - gained + 1, n + 1)}
        plan.append((start, close_at, n, opening))
        if dropped:
            span = end - close_at
            closing = {}
            for j in range(n - dropped + 1, n + 1):
                prof = opening.get(j)
                w0 = w if prof is None else float(prof.value(np.array([close_at - start]))[0])
                closing[j] = _closing(w0, span)
            plan.append((close_at, end, n, closing))
    sign = -1 if traffic_side == "right" else 1
    sections: list[LaneSection] = []
    keys_per: list[list[tuple]] = []
    for a, _b, n, special in plan:
        out: list[Lane] = []
        keys: list[tuple] = []
        if cross.inner_shoulder_m > 0:
            keys.append(("inner",))
            out.append(_lane(CubicProfile.constant(cross.inner_shoulder_m), "shoulder", "solid"))
        for j in range(1, n + 1):
            keys.append(("drive", j))
            width = special.get(j, CubicProfile.constant(w))
            out.append(_lane(width, "driving", "solid" if j == n else "broken"))
        if cross.hard_shoulder_m > 0:
            keys.append(("hard",))
            out.append(_lane(CubicProfile.constant(cross.hard_shoulder_m), "shoulder", "none"))
        out = [replace(ln, id=sign * (i + 1)) for i, ln in enumerate(out)]
        sections.append(
            LaneSection(a, right=tuple(out))
            if traffic_side == "right"
            else LaneSection(a, left=tuple(out))
        )
        keys_per.append(keys)
    bounds = [p[0] for p in plan] + [length_m]
    return _link(sections, keys_per, bounds, traffic_side)


def _lane(width: CubicProfile, lane_type: str, mark: str) -> Lane:
    return Lane(0, lane_type, width, (RoadMark(0.0, mark),))  # type: ignore[arg-type]


def _link(
    sections: list[LaneSection], keys_per: list[list[tuple]], bounds: list[float], side: str
) -> tuple[LaneSection, ...]:
    """Lane links between consecutive sections by lane role, except at zero width."""
    out = list(sections)
    for k in range(len(out) - 1):
        a, b = out[k], out[k + 1]
        la, lb = _traffic_lanes(a, side), _traffic_lanes(b, side)
        ia = {key: i for i, key in enumerate(keys_per[k])}
        ib = {key: i for i, key in enumerate(keys_per[k + 1])}
        span = bounds[k + 1] - bounds[k]
        succ: dict[int, int] = {}
        pred: dict[int, int] = {}
        for key, i in ia.items():
            j = ib.get(key)
            if j is None:
                continue
            w_end = float(la[i].width.value(np.array([span]))[0])
            w_start = float(lb[j].width.value(np.array([0.0]))[0])
            if min(w_end, w_start) < 0.01 or abs(w_end - w_start) > 1e-6:
                continue
            succ[la[i].id] = lb[j].id
            pred[lb[j].id] = la[i].id
        new_a = tuple(replace(ln, successor=succ.get(ln.id)) for ln in la)
        new_b = tuple(replace(ln, predecessor=pred.get(ln.id)) for ln in lb)
        out[k] = replace(a, right=new_a) if side == "right" else replace(a, left=new_a)
        out[k + 1] = replace(b, right=new_b) if side == "right" else replace(b, left=new_b)
    return tuple(out)
