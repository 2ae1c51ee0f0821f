"""Scenario description: the TOML schema, its validation and realistic defaults.

A scenario is a TOML file (see ``src/roadtwin/data/scenarios/*.toml``). Every table and
key is optional except ``[[alignment]]``; unknown keys are errors (typos must not pass
silently). Lengths are metres, stations are metres along the driven carriageway's
reference line (its median-side road edge) from the start of the run, curvatures are
1/m (positive turning left), grades are percent.

Tables
------
``[origin]`` lat, lon (degrees), alt (metres).  ``[traffic] side = "right" | "left"``.
``[[alignment]]`` elements in driving order: ``type = "straight"`` (``length``),
``"arc"`` (``radius``, ``length``, ``direction = "left" | "right"``) or ``"clothoid"``
(``length``; ``curvature_start``/``curvature_end`` in 1/m, each defaulting to the
curvature where the neighbouring element meets it).
``[vertical]`` ``start_z`` and ``[[vertical.grades]]`` (``station``, ``grade_pct``,
``curve_length``: a parabolic vertical curve centred on the grade change).
``[lanes]`` count, width, inner_shoulder, hard_shoulder and ``[[lanes.drops]]``
(``station`` where the outermost driving lane has tapered to zero, ``taper``).
``[[ramps]]`` type exit/entry, station (of the gore), lanes, parallel_length,
taper_length, radius, clothoid_length, curve_length, tail_length, ...
``[start]`` x, y (metres) and heading_deg of the reference line's start (default 0, 0,
20 degrees). ``[markings]``, ``[opposite]``, ``[[other_roads]]``, ``[car]``, ``[noise]``,
``[sensor]``, ``[osm]``, ``[output]``: see the dataclasses below for every key.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any, Literal

from .._errors import InputError
from ..frames import Origin

try:  # Python 3.11+
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]


@dataclass(frozen=True)
class AlignmentElement:
    """One horizontal alignment element of the mainline.

    ``kind`` is ``straight``, ``arc`` or ``clothoid``; ``curvature_start``/``_end`` are
    signed (1/m, left positive) and already resolved for clothoids.
    """

    kind: Literal["straight", "arc", "clothoid"]
    length_m: float
    curvature_start: float = 0.0
    curvature_end: float = 0.0


@dataclass(frozen=True)
class GradeChange:
    """Grade ``grade_pct`` from ``station_m`` on, reached through a parabolic vertical
    curve of ``curve_length_m`` centred on the station (0 = a kink)."""

    station_m: float
    grade_pct: float
    curve_length_m: float = 0.0


@dataclass(frozen=True)
class LaneDrop:
    """The outermost driving lane tapers to zero width, ending at ``station_m``."""

    station_m: float
    taper_m: float = 180.0


@dataclass(frozen=True)
class Lanes:
    """Cross-section of the driven carriageway (metres)."""

    count: int = 3
    width_m: float = 3.75
    inner_shoulder_m: float = 0.75
    """From the median-side road edge to the leftmost marking (RHT)."""
    hard_shoulder_m: float = 2.5
    drops: tuple[LaneDrop, ...] = ()


@dataclass(frozen=True)
class Ramp:
    """An exit or entry on the outer side of the driven carriageway.

    ``station_m`` is the gore (where the ramp road begins / ends). An exit has a
    deceleration lane of ``parallel_length_m`` after a ``taper_length_m`` taper before the
    gore; an entry an acceleration lane after it. The ramp road leaves (or joins) along a
    clothoid of ``clothoid_length_m``, an arc of ``radius_m`` and ``curve_length_m``, then
    a straight of ``tail_length_m``.
    """

    type: Literal["exit", "entry"]
    station_m: float
    lanes: int = 1
    parallel_length_m: float = 200.0
    taper_length_m: float = 60.0
    radius_m: float = 300.0
    clothoid_length_m: float = 90.0
    curve_length_m: float = 150.0
    tail_length_m: float = 100.0
    lane_width_m: float = 3.5
    inner_shoulder_m: float = 0.5
    name: str = ""
    elements: tuple[tuple[float, float, float], ...] = ()
    """Optional ramp shape in driving order: ``(length_m, curvature_start, curvature_end)``
    clothoids (1/m, left positive) replacing clothoid/arc/tail (real-geometry scenarios)."""
    osm_way_ids: tuple[int, ...] = ()
    """OSM link way ids of this ramp when the map input is real OSM (for truth.json)."""


@dataclass(frozen=True)
class Markings:
    """Paint: lane lines dashed ``dash_m`` / ``gap_m``, the line between a driving lane and
    a deceleration/acceleration lane dashed ``aux_dash_m`` / ``aux_gap_m``, edge lines solid."""

    dash_m: float = 6.0
    gap_m: float = 12.0
    aux_dash_m: float = 6.0
    aux_gap_m: float = 6.0
    lane_line_width_m: float = 0.15
    edge_line_width_m: float = 0.30


@dataclass(frozen=True)
class Opposite:
    """The opposite carriageway: its median-side edge ``median_m`` from ours."""

    enabled: bool = True
    median_m: float = 4.0
    ramps: bool = True
    """Mirror our ramps onto it (in OSM only): an exit here is an entry there."""


@dataclass(frozen=True)
class OtherRoad:
    """An unrelated road: ``overpass`` (straight, crossing at ``station_m`` at ``angle_deg``
    and ``clearance_m`` above) or ``local`` (straight, parallel at ``offset_m`` to the
    outer side, from ``station_m`` on)."""

    kind: Literal["overpass", "local"]
    station_m: float
    length_m: float = 300.0
    angle_deg: float = 75.0
    clearance_m: float = 7.0
    offset_m: float = 150.0
    highway: str = "primary"
    lane_width_m: float = 3.25
    name: str = ""


@dataclass(frozen=True)
class Car:
    """The mapping car: ``lane`` counted from the median side (1 = inner; 0 = the
    outermost lane that exists along the whole run), speed, start time."""

    lane: int = 0
    speed_kmh: float = 90.0
    rate_hz: float = 10.0
    t0_s: float = 0.0


@dataclass(frozen=True)
class Noise:
    """GNSS/INS pose errors: Gauss-Markov (smooth, random-walk-like) drift with the given
    standard deviations and correlation time, plus white jitter."""

    position_std_m: float = 0.02
    height_std_m: float = 0.03
    yaw_std_deg: float = 0.05
    correlation_s: float = 20.0
    jitter_m: float = 0.003


@dataclass(frozen=True)
class Sensor:
    """Road-edge extraction and lane-marking detection."""

    edge_spacing_m: float = 0.2
    edge_range_m: float = 25.0
    edge_noise_m: float = 0.03
    edge_height_noise_m: float = 0.02
    edge_dropout: float = 0.05
    trucks_per_km: float = 1.5
    truck_duration_s: tuple[float, float] = (1.0, 4.0)
    outlier_fraction: float = 0.01
    outlier_offset_m: tuple[float, float] = (0.3, 3.0)
    lane_spacing_m: float = 0.5
    lane_range_m: tuple[float, float] = (3.0, 30.0)
    lane_lateral_range_m: float = 12.0
    lane_noise_m: float = 0.03
    lane_miss: float = 0.03
    lane_false_positive: float = 0.005


@dataclass(frozen=True)
class OsmStyle:
    """How a mapper drew the roads: node spacing, offsets and noise (metres)."""

    curve_spacing_m: tuple[float, float] = (20.0, 80.0)
    straight_spacing_m: float = 250.0
    chord_error_m: float = 0.3
    way_offset_m: float = 1.5
    node_noise_m: float = 0.5
    missing_lanes_fraction: float = 0.3
    motorway_ref: str = "A 99"


@dataclass(frozen=True)
class Scenario:
    """A complete, validated scenario."""

    name: str
    origin: Origin
    alignment: tuple[AlignmentElement, ...]
    traffic_side: Literal["right", "left"] = "right"
    seed: int = 0
    description: str = ""
    start_z_m: float = 0.0
    grades: tuple[GradeChange, ...] = (GradeChange(0.0, 0.0),)
    lanes: Lanes = field(default_factory=Lanes)
    ramps: tuple[Ramp, ...] = ()
    markings: Markings = field(default_factory=Markings)
    opposite: Opposite = field(default_factory=Opposite)
    other_roads: tuple[OtherRoad, ...] = ()
    car: Car = field(default_factory=Car)
    noise: Noise = field(default_factory=Noise)
    sensor: Sensor = field(default_factory=Sensor)
    osm: OsmStyle = field(default_factory=OsmStyle)
    road_edges_format: Literal["laz", "las", "csv", "ply", "npy", "parquet"] = "laz"
    real_osm: str = ""
    """Bundled real OSM file used as the run's map instead of the simulated one (real_a9)."""
    start_xy_m: tuple[float, float] = (0.0, 0.0)
    """Mapping-frame position of the reference line's start (metres)."""
    start_heading_deg: float = 20.0
    """Heading of the reference line at its start (degrees CCW from east)."""

    @property
    def length_m(self) -> float:
        """Mainline length (metres)."""
        return float(sum(e.length_m for e in self.alignment))

    @property
    def side_sign(self) -> float:
        """-1 for right-hand traffic (lanes right of the reference line), +1 for left."""
        return -1.0 if self.traffic_side == "right" else 1.0

    @property
    def car_lane(self) -> int:
        """The driven lane (1 = median side), resolved."""
        if self.car.lane > 0:
            return self.car.lane
        return self.lanes.count - len(self.lanes.drops)


# ---------------------------------------------------------------------------
# parsing
# ---------------------------------------------------------------------------


def bundled_scenarios() -> list[str]:
    """Names of the scenarios shipped in ``roadtwin/data/scenarios``."""
    folder = resources.files("roadtwin") / "data" / "scenarios"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def _scenario_path(path_or_name: str | Path) -> Path:
    path = Path(path_or_name)
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise InputError(f"{path}: scenario file not found")
        return path
    names = bundled_scenarios()
    if str(path_or_name) not in names:
        msg = f"{path_or_name!r}: no such scenario file or bundled scenario (bundled: {names})"
        raise InputError(msg)
    return Path(str(resources.files("roadtwin") / "data" / "scenarios" / f"{path_or_name}.toml"))


def load_scenario(path_or_name: str | Path) -> Scenario:
    """Read and validate a scenario TOML file or a bundled scenario by name.

    Raises
    ------
    InputError
        Naming the file, the table/key and what was expected.
    """
    path = _scenario_path(path_or_name)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    try:
        return scenario_from_dict(data, name=path.stem, base_dir=path.parent)
    except InputError as exc:
        raise InputError(f"{path}: {exc}") from None


def _table(data: dict[str, Any], key: str, allowed: set[str], where: str) -> dict[str, Any]:
    table = data.get(key, {})
    if not isinstance(table, dict):
        raise InputError(f"[{where}] must be a table")
    unknown = set(table) - allowed
    if unknown:
        msg = f"[{where}]: unknown keys {sorted(unknown)}; known: {sorted(allowed)}"
        raise InputError(msg)
    return table


def _num(table: dict[str, Any], key: str, default: float, where: str, *, lo=None, hi=None):
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"[{where}] {key}: expected a number, got {value!r}")
    value = float(value)
    if (
        not math.isfinite(value)
        or (lo is not None and value < lo)
        or (hi is not None and value > hi)
    ):
        raise InputError(f"[{where}] {key} = {value}: expected a value in [{lo}, {hi}]")
    return value


def _pair(table, key, default, where, *, lo=0.0):
    value = table.get(key, default)
    if not (isinstance(value, (list, tuple)) and len(value) == 2):
        raise InputError(f"[{where}] {key}: expected [min, max], got {value!r}")
    a, b = (float(v) for v in value)
    if not (lo <= a <= b):
        raise InputError(f"[{where}] {key} = {value}: expected {lo} <= min <= max")
    return (a, b)


def _dataclass_from_table(cls, table: dict[str, Any], where: str, keymap: dict[str, str]):
    """Fill a flat dataclass from a table whose TOML keys map to fields via ``keymap``."""
    allowed = set(keymap)
    unknown = set(table) - allowed
    if unknown:
        raise InputError(f"[{where}]: unknown keys {sorted(unknown)}; known: {sorted(allowed)}")
    defaults = cls()
    kwargs: dict[str, Any] = {}
    types = {f.name: f.type for f in fields(cls)}
    for key, fname in keymap.items():
        if key not in table:
            continue
        default = getattr(defaults, fname)
        if isinstance(default, tuple):
            kwargs[fname] = _pair(table, key, default, where)
        elif isinstance(default, bool):
            if not isinstance(table[key], bool):
                raise InputError(f"[{where}] {key}: expected true or false")
            kwargs[fname] = table[key]
        elif isinstance(default, str) or types[fname] == "str":
            kwargs[fname] = str(table[key])
        elif isinstance(default, int) and not isinstance(default, bool):
            value = table[key]
            if not isinstance(value, int) or isinstance(value, bool):
                raise InputError(f"[{where}] {key}: expected an integer, got {value!r}")
            kwargs[fname] = value
        else:
            kwargs[fname] = _num(table, key, default, where, lo=0.0)
    return cls(**kwargs)


def _parse_alignment(items: Any) -> tuple[AlignmentElement, ...]:
    if not isinstance(items, list) or not items:
        raise InputError("[[alignment]]: at least one element (straight/arc/clothoid) is required")
    raw: list[dict[str, Any]] = []
    for i, item in enumerate(items):
        where = f"alignment {i + 1}"
        kind = item.get("type")
        allowed = {
            "straight": {"type", "length"},
            "arc": {"type", "length", "radius", "direction"},
            "clothoid": {"type", "length", "curvature_start", "curvature_end"},
        }
        if kind not in allowed:
            raise InputError(f"[{where}] type: expected straight, arc or clothoid, got {kind!r}")
        unknown = set(item) - allowed[kind]
        if unknown:
            raise InputError(f"[{where}]: unknown keys {sorted(unknown)} for a {kind}")
        length = _num(item, "length", -1.0, where, lo=0.1)
        entry: dict[str, Any] = {"kind": kind, "length": length}
        if kind == "arc":
            radius = _num(item, "radius", 0.0, where, lo=10.0)
            direction = item.get("direction", "left")
            if direction not in ("left", "right"):
                raise InputError(f"[{where}] direction: expected left or right, got {direction!r}")
            k = (1.0 if direction == "left" else -1.0) / radius
            entry["k0"] = entry["k1"] = k
        elif kind == "clothoid":
            for key in ("curvature_start", "curvature_end"):
                if key in item:
                    entry[key] = _num(item, key, 0.0, where, lo=-0.1, hi=0.1)
        else:
            entry["k0"] = entry["k1"] = 0.0
        raw.append(entry)
    out = []
    for i, e in enumerate(raw):
        if e["kind"] == "clothoid":
            prev_k = raw[i - 1].get("k1", 0.0) if i > 0 else 0.0
            next_k = raw[i + 1].get("k0", 0.0) if i + 1 < len(raw) else 0.0
            e["k0"] = e.get("curvature_start", prev_k)
            e["k1"] = e.get("curvature_end", next_k)
        out.append(AlignmentElement(e["kind"], e["length"], e["k0"], e["k1"]))
    return tuple(out)


def _parse_grades(vertical: dict[str, Any], length: float) -> tuple[GradeChange, ...]:
    items = vertical.get("grades", [{"station": 0.0, "grade_pct": 0.0}])
    grades = []
    for i, item in enumerate(items):
        where = f"vertical.grades {i + 1}"
        unknown = set(item) - {"station", "grade_pct", "curve_length"}
        if unknown:
            raise InputError(f"[{where}]: unknown keys {sorted(unknown)}")
        grades.append(
            GradeChange(
                _num(item, "station", 0.0, where, lo=0.0, hi=length),
                _num(item, "grade_pct", 0.0, where, lo=-8.0, hi=8.0),
                _num(item, "curve_length", 0.0, where, lo=0.0),
            )
        )
    if grades[0].station_m != 0.0:
        grades.insert(0, GradeChange(0.0, 0.0))
    for a, b in itertools.pairwise(grades):
        if b.station_m - b.curve_length_m / 2 < a.station_m + a.curve_length_m / 2:
            msg = (
                f"[vertical.grades] vertical curves at stations {a.station_m} and "
                f"{b.station_m} overlap (or are not in increasing station order)"
            )
            raise InputError(msg)
    return tuple(grades)


_RAMP_KEYS = {
    "type": "type",
    "station": "station_m",
    "lanes": "lanes",
    "parallel_length": "parallel_length_m",
    "taper_length": "taper_length_m",
    "radius": "radius_m",
    "clothoid_length": "clothoid_length_m",
    "curve_length": "curve_length_m",
    "tail_length": "tail_length_m",
    "lane_width": "lane_width_m",
    "inner_shoulder": "inner_shoulder_m",
    "name": "name",
    "side": "side",
    "elements": "elements",
    "osm_way_ids": "osm_way_ids",
}


def _parse_ramps(items: list[dict[str, Any]], traffic_side: str) -> tuple[Ramp, ...]:
    ramps = []
    for i, item in enumerate(items):
        where = f"ramps {i + 1}"
        unknown = set(item) - set(_RAMP_KEYS)
        if unknown:
            raise InputError(
                f"[{where}]: unknown keys {sorted(unknown)}; known: {sorted(_RAMP_KEYS)}"
            )
        kind = item.get("type")
        if kind not in ("exit", "entry"):
            raise InputError(f"[{where}] type: expected exit or entry, got {kind!r}")
        side = item.get("side", traffic_side)
        if side != traffic_side:
            msg = (
                f"[{where}] side = {side!r}: only ramps on the outer ({traffic_side}) side of "
                f"a {traffic_side}-hand-traffic carriageway are supported"
            )
            raise InputError(msg)
        lanes = item.get("lanes", 1)
        if lanes not in (1, 2):
            raise InputError(f"[{where}] lanes: expected 1 or 2, got {lanes!r}")
        d = Ramp(kind, 0.0)
        ramps.append(
            Ramp(
                type=kind,
                station_m=_num(item, "station", -1.0, where, lo=0.0),
                lanes=int(lanes),
                parallel_length_m=_num(
                    item, "parallel_length", d.parallel_length_m, where, lo=10.0
                ),
                taper_length_m=_num(item, "taper_length", d.taper_length_m, where, lo=10.0),
                radius_m=_num(item, "radius", d.radius_m, where, lo=40.0),
                clothoid_length_m=_num(
                    item, "clothoid_length", d.clothoid_length_m, where, lo=10.0
                ),
                curve_length_m=_num(item, "curve_length", d.curve_length_m, where, lo=1.0),
                tail_length_m=_num(item, "tail_length", d.tail_length_m, where, lo=1.0),
                lane_width_m=_num(item, "lane_width", d.lane_width_m, where, lo=2.5, hi=5.0),
                inner_shoulder_m=_num(item, "inner_shoulder", d.inner_shoulder_m, where, lo=0.0),
                name=str(item.get("name", "")),
                elements=_ramp_elements(item.get("elements", []), where),
                osm_way_ids=tuple(int(v) for v in item.get("osm_way_ids", [])),
            )
        )
    return tuple(sorted(ramps, key=lambda r: r.station_m))


def _ramp_elements(items: Any, where: str) -> tuple[tuple[float, float, float], ...]:
    out = []
    for k, item in enumerate(items):
        if not (isinstance(item, list) and len(item) == 3):
            raise InputError(f"[{where}] elements[{k}]: expected [length, k_start, k_end]")
        length, k0, k1 = (float(v) for v in item)
        if not (length > 0 and abs(k0) < 0.1 and abs(k1) < 0.1):
            raise InputError(f"[{where}] elements[{k}]: length > 0 and |curvature| < 0.1 1/m")
        out.append((length, k0, k1))
    return tuple(out)


def aux_zone(ramp: Ramp) -> tuple[float, float]:
    """Station range (metres) of a ramp's deceleration/acceleration lane incl. taper."""
    extent = ramp.parallel_length_m + ramp.taper_length_m
    if ramp.type == "exit":
        return ramp.station_m - extent, ramp.station_m
    return ramp.station_m, ramp.station_m + extent


SHOULDER_TAPER_M = 80.0
"""Length over which the mainline hard shoulder re-appears after an exit gore / ends
before an entry gore (metres)."""


def _validate(sc: Scenario) -> None:
    length = sc.length_m
    lanes = sc.lanes
    if not 1 <= lanes.count <= 6:
        raise InputError(f"[lanes] count = {lanes.count}: expected 1..6")
    if len(lanes.drops) >= lanes.count:
        raise InputError("[lanes.drops]: cannot drop every lane")
    if not 2.5 <= lanes.width_m <= 5.0:
        raise InputError(f"[lanes] width = {lanes.width_m}: expected 2.5..5.0 m")
    zones: list[tuple[float, float, str]] = []
    for r in sc.ramps:
        a, b = aux_zone(r)
        pad = SHOULDER_TAPER_M
        zone = (a, b + pad) if r.type == "exit" else (a - pad, b)
        if zone[0] < 20.0 or zone[1] > length - 20.0:
            msg = (
                f"[ramps] {r.type} at station {r.station_m}: its lanes and tapers "
                f"({zone[0]:.0f}..{zone[1]:.0f} m) must lie inside the mainline (0..{length:.0f} m)"
            )
            raise InputError(msg)
        zones.append((*zone, f"{r.type} at station {r.station_m:g}"))
    for d in lanes.drops:
        zones.append((d.station_m - d.taper_m, d.station_m, f"lane drop at {d.station_m:g}"))
        if d.station_m - d.taper_m < 20.0 or d.station_m > length - 20.0:
            raise InputError(f"[lanes.drops] station {d.station_m}: taper outside the mainline")
    zones.sort()
    for za, zb in itertools.pairwise(zones):
        if zb[0] < za[1]:
            raise InputError(f"[ramps]/[lanes.drops]: {za[2]} overlaps {zb[2]}")
    if not 1 <= sc.car_lane <= lanes.count - len(lanes.drops):
        msg = (
            f"[car] lane = {sc.car.lane}: expected 1..{lanes.count - len(lanes.drops)} "
            "(a lane that exists along the whole run; 0 = outermost)"
        )
        raise InputError(msg)
    for o in sc.other_roads:
        if not 0.0 <= o.station_m <= length:
            raise InputError(f"[other_roads] {o.kind} station {o.station_m}: outside 0..{length}")


def scenario_from_dict(data: dict[str, Any], *, name: str = "scenario", base_dir=None) -> Scenario:
    """Validate a parsed scenario TOML document; see the module docstring for the schema."""
    top = {
        "name", "description", "seed", "origin", "traffic", "alignment", "vertical", "lanes",
        "ramps", "markings", "opposite", "other_roads", "car", "noise", "sensor", "osm", "output",
        "start",
    }  # fmt: skip
    unknown = set(data) - top
    if unknown:
        raise InputError(f"unknown top-level keys/tables {sorted(unknown)}; known: {sorted(top)}")
    origin_t = _table(data, "origin", {"lat", "lon", "alt"}, "origin")
    origin = Origin(
        _num(origin_t, "lat", 49.98, "origin", lo=-90, hi=90),
        _num(origin_t, "lon", 11.62, "origin", lo=-180, hi=180),
        _num(origin_t, "alt", 400.0, "origin", lo=-500, hi=9000),
    )
    traffic = _table(data, "traffic", {"side"}, "traffic")
    side = traffic.get("side", "right")
    if side not in ("right", "left"):
        raise InputError(f"[traffic] side: expected right or left, got {side!r}")
    alignment = _parse_alignment(data.get("alignment"))
    length = float(sum(e.length_m for e in alignment))
    vertical = _table(data, "vertical", {"start_z", "grades"}, "vertical")
    lanes_t = _table(
        data, "lanes", {"count", "width", "inner_shoulder", "hard_shoulder", "drops"}, "lanes"
    )
    count = lanes_t.get("count", 3)
    if not isinstance(count, int) or isinstance(count, bool):
        raise InputError(f"[lanes] count: expected an integer, got {count!r}")
    drops = []
    for i, item in enumerate(lanes_t.get("drops", [])):
        where = f"lanes.drops {i + 1}"
        if set(item) - {"station", "taper"}:
            raise InputError(f"[{where}]: unknown keys {sorted(set(item) - {'station', 'taper'})}")
        drops.append(
            LaneDrop(
                _num(item, "station", -1.0, where, lo=0.0),
                _num(item, "taper", 180.0, where, lo=20.0),
            )
        )
    lanes = Lanes(
        count=count,
        width_m=_num(lanes_t, "width", 3.75, "lanes", lo=0.0),
        inner_shoulder_m=_num(lanes_t, "inner_shoulder", 0.75, "lanes", lo=0.0, hi=5.0),
        hard_shoulder_m=_num(lanes_t, "hard_shoulder", 2.5, "lanes", lo=0.0, hi=5.0),
        drops=tuple(sorted(drops, key=lambda d: d.station_m)),
    )
    markings = _dataclass_from_table(
        Markings,
        data.get("markings", {}),
        "markings",
        {
            "dash": "dash_m",
            "gap": "gap_m",
            "aux_dash": "aux_dash_m",
            "aux_gap": "aux_gap_m",
            "lane_line_width": "lane_line_width_m",
            "edge_line_width": "edge_line_width_m",
        },
    )
    opposite = _dataclass_from_table(
        Opposite,
        data.get("opposite", {}),
        "opposite",
        {"enabled": "enabled", "median": "median_m", "ramps": "ramps"},
    )
    others = []
    for i, item in enumerate(data.get("other_roads", [])):
        where = f"other_roads {i + 1}"
        kind = item.get("type")
        if kind not in ("overpass", "local"):
            raise InputError(f"[{where}] type: expected overpass or local, got {kind!r}")
        body = {k: v for k, v in item.items() if k != "type"}
        road = _dataclass_from_table(
            _OtherRoadTable,
            body,
            where,
            {
                "station": "station_m",
                "length": "length_m",
                "angle_deg": "angle_deg",
                "clearance": "clearance_m",
                "offset": "offset_m",
                "highway": "highway",
                "lane_width": "lane_width_m",
                "name": "name",
            },
        )
        others.append(OtherRoad(kind, **{f.name: getattr(road, f.name) for f in fields(road)}))
    car = _dataclass_from_table(
        Car,
        data.get("car", {}),
        "car",
        {"lane": "lane", "speed_kmh": "speed_kmh", "rate_hz": "rate_hz", "t0": "t0_s"},
    )
    if not (10.0 <= car.speed_kmh <= 200.0 and 1.0 <= car.rate_hz <= 100.0):
        raise InputError("[car] speed_kmh must be 10..200 and rate_hz 1..100")
    noise = _dataclass_from_table(
        Noise, data.get("noise", {}), "noise", {f.name: f.name for f in fields(Noise)}
    )
    sensor = _dataclass_from_table(
        Sensor, data.get("sensor", {}), "sensor", {f.name: f.name for f in fields(Sensor)}
    )
    for key in ("edge_dropout", "outlier_fraction", "lane_miss", "lane_false_positive"):
        if getattr(sensor, key) > 0.5:
            raise InputError(f"[sensor] {key} = {getattr(sensor, key)}: expected a fraction <= 0.5")
    if sensor.edge_spacing_m < 0.02 or sensor.lane_spacing_m < 0.05:
        raise InputError("[sensor] edge_spacing_m >= 0.02 and lane_spacing_m >= 0.05 expected")
    osm = _dataclass_from_table(
        OsmStyle, data.get("osm", {}), "osm", {f.name: f.name for f in fields(OsmStyle)}
    )
    output = _table(data, "output", {"road_edges_format", "real_osm"}, "output")
    fmt = output.get("road_edges_format", "laz")
    if fmt not in ("laz", "las", "csv", "ply", "npy", "parquet"):
        raise InputError(
            f"[output] road_edges_format: expected laz/las/csv/ply/npy/parquet, got {fmt!r}"
        )
    real_osm = str(output.get("real_osm", ""))
    if real_osm and base_dir is not None:
        real_osm = str((Path(base_dir) / real_osm).resolve())
    start = _table(data, "start", {"x", "y", "heading_deg"}, "start")
    seed = data.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise InputError(f"seed: expected a non-negative integer, got {seed!r}")
    scenario = Scenario(
        name=str(data.get("name", name)),
        description=str(data.get("description", "")),
        origin=origin,
        alignment=alignment,
        traffic_side=side,
        seed=seed,
        start_z_m=_num(vertical, "start_z", 0.0, "vertical"),
        grades=_parse_grades(vertical, length),
        lanes=lanes,
        ramps=_parse_ramps(data.get("ramps", []), side),
        markings=markings,
        opposite=opposite,
        other_roads=tuple(others),
        car=car,
        noise=noise,
        sensor=sensor,
        osm=osm,
        road_edges_format=fmt,
        real_osm=real_osm,
        start_xy_m=(_num(start, "x", 0.0, "start"), _num(start, "y", 0.0, "start")),
        start_heading_deg=_num(start, "heading_deg", 20.0, "start", lo=-360.0, hi=360.0),
    )
    _validate(scenario)
    return scenario


@dataclass(frozen=True)
class _OtherRoadTable:
    station_m: float = 0.0
    length_m: float = 300.0
    angle_deg: float = 75.0
    clearance_m: float = 7.0
    offset_m: float = 150.0
    highway: str = "primary"
    lane_width_m: float = 3.25
    name: str = ""
