"""Ground truth: the scenario as an exact :class:`~roadtwin.model.RoadNetwork`.

Lane layout (brief, right-hand traffic; left-hand mirrors it with positive ids): the
reference line is the median-side road edge; lanes inner to outer are the inner shoulder,
the driving lanes, deceleration/acceleration lanes where they exist (tapering from/to
zero width in their own lane sections) and the hard shoulder. The mainline is cut into
roads ``"1", "2", ...`` (``name="mainline"``) at every gore; ramp roads (``"exit"`` /
``"entry"``, ids from 101) start/end at the gore on the outer border of the outermost
driving lane and are joined by OpenDRIVE ``direct`` junctions (ids from 1001) with lane
links. After an exit gore the mainline hard shoulder re-appears from zero width, before
an entry gore it tapers to zero (the ramp's hard shoulder continues the mainline's).
The opposite carriageway and unrelated roads are ``name="other"`` roads (ids from 201);
the opposite carriageway's own ramps exist only in the simulated OSM (so the ramp stage
has something to reject), not in the truth.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np

from ..frames import MappingFrame
from ..model import (
    Connection,
    CubicPiece,
    CubicProfile,
    Header,
    Junction,
    Lane,
    LaneLink,
    LaneSection,
    Line,
    Road,
    RoadLink,
    RoadMark,
    RoadNetwork,
)
from .alignment import (
    cut_pieces,
    cut_profile,
    elevation_profile,
    mainline_pieces,
    offset_pieces,
    ramp_pieces,
    reverse_pieces,
    shift_cubic,
    smoothstep_cubic,
)
from .scenario import SHOULDER_TAPER_M, Ramp, Scenario, aux_zone


@dataclass(frozen=True)
class LaneSpec:
    """One lane of a section: ``key`` identifies the same lane across sections,
    ``width`` is a cubic in the road's own station (its ``s0`` is absolute),
    ``mark`` the style of the paint on its outer border."""

    key: tuple
    kind: str  # inner | driving | aux | hard
    width: CubicPiece
    mark: str  # solid | lane | aux | none


@dataclass(frozen=True)
class SectionSpec:
    """Lanes between road stations ``s0`` and ``s1`` (metres)."""

    s0: float
    s1: float
    lanes: tuple[LaneSpec, ...]


@dataclass(frozen=True)
class MarkingLine:
    """A painted line: outer border of lane ``lane_id`` of ``road`` over ``[s0, s1]``.

    ``style`` is ``solid``, ``lane`` (dash/gap of lane lines) or ``aux``; ``phase_m`` is
    added to the station before applying the dash pattern (so mainline dashes stay in
    phase across roads)."""

    road: Road
    s0: float
    s1: float
    lane_id: int
    style: str
    phase_m: float = 0.0


@dataclass(frozen=True)
class RampTruth:
    """A ramp: its scenario entry, road, mainline station of its gore and sections."""

    ramp: Ramp
    road: Road
    station_m: float
    sections: tuple[SectionSpec, ...]


@dataclass(frozen=True)
class Truth:
    """Everything the sensor and OSM simulators need about the true road."""

    scenario: Scenario
    frame: MappingFrame
    network: RoadNetwork
    mainline: Road  # the whole driven carriageway as one road (all lane sections)
    sections: tuple[SectionSpec, ...]
    ramps: tuple[RampTruth, ...]
    opposite: Road | None
    others: tuple[Road, ...]
    mainline_road_starts: tuple[float, ...]  # mainline station where each mainline road starts

    @property
    def sign(self) -> float:
        return self.scenario.side_sign


# ---------------------------------------------------------------------------
# lane layouts
# ---------------------------------------------------------------------------


def _const(value: float) -> CubicPiece:
    return CubicPiece(0.0, float(value))


def mainline_sections(sc: Scenario) -> tuple[SectionSpec, ...]:
    """Lane sections of the whole driven carriageway (absolute mainline stations)."""
    length = sc.length_m
    ln = sc.lanes
    breaks = {0.0, length}
    for d in ln.drops:
        breaks |= {d.station_m - d.taper_m, d.station_m}
    for r in sc.ramps:
        a, b = aux_zone(r)
        g = r.station_m
        if r.type == "exit":
            breaks |= {a, a + r.taper_length_m, g, g + SHOULDER_TAPER_M}
        else:
            breaks |= {g - SHOULDER_TAPER_M, g, b - r.taper_length_m, b}
    stations = sorted(breaks)
    sections = []
    for a, b in itertools.pairwise(stations):
        m = 0.5 * (a + b)
        lanes: list[LaneSpec] = [
            LaneSpec(("inner",), "inner", _const(ln.inner_shoulder_m), "solid")
        ]
        n_active = ln.count - sum(1 for d in ln.drops if d.station_m <= m)
        dropping = [d for d in ln.drops if d.station_m - d.taper_m <= m < d.station_m]
        aux_ramp = [(i, r) for i, r in enumerate(sc.ramps) if aux_zone(r)[0] <= m < aux_zone(r)[1]]
        for j in range(1, n_active + 1):
            width = _const(ln.width_m)
            if dropping and j == n_active:
                d = dropping[0]
                width = smoothstep_cubic(d.station_m - d.taper_m, d.taper_m, ln.width_m, 0.0)
            last = j == n_active
            mark = "lane" if not last else ("aux" if aux_ramp else "solid")
            lanes.append(LaneSpec(("drive", j), "driving", width, mark))
        for i, r in aux_ramp:
            za, zb = aux_zone(r)
            w = r.lane_width_m
            if r.type == "exit":
                taper = m < za + r.taper_length_m
                width = smoothstep_cubic(za, r.taper_length_m, 0.0, w) if taper else _const(w)
            else:
                taper = m >= zb - r.taper_length_m
                width = (
                    smoothstep_cubic(zb - r.taper_length_m, r.taper_length_m, w, 0.0)
                    if taper
                    else _const(w)
                )
            for j in range(1, r.lanes + 1):
                mark = "solid" if j == r.lanes else "lane"
                lanes.append(LaneSpec(("aux", i, j), "aux", width, mark))
        hard = _const(ln.hard_shoulder_m)
        for r in sc.ramps:
            g = r.station_m
            if r.type == "exit" and g <= m < g + SHOULDER_TAPER_M:
                hard = smoothstep_cubic(g, SHOULDER_TAPER_M, 0.0, ln.hard_shoulder_m)
            if r.type == "entry" and g - SHOULDER_TAPER_M <= m < g:
                hard = smoothstep_cubic(
                    g - SHOULDER_TAPER_M, SHOULDER_TAPER_M, ln.hard_shoulder_m, 0.0
                )
        lanes.append(LaneSpec(("hard",), "hard", hard, "none"))
        sections.append(SectionSpec(a, b, tuple(lanes)))
    return tuple(sections)


def ramp_sections(ramp: Ramp, length_m: float, hard_shoulder_m: float) -> tuple[SectionSpec, ...]:
    """Lane sections of a ramp road: its inner shoulder grows from zero after the gore
    (exit) or shrinks to zero before it (entry) over the clothoid length."""
    tr = min(ramp.clothoid_length_m, 0.5 * length_m)
    drive = [
        LaneSpec(
            ("drive", j),
            "driving",
            _const(ramp.lane_width_m),
            "solid" if j == ramp.lanes else "lane",
        )
        for j in range(1, ramp.lanes + 1)
    ]
    hard = LaneSpec(("hard",), "hard", _const(hard_shoulder_m), "none")
    full = ramp.inner_shoulder_m
    if ramp.type == "exit":
        first = LaneSpec(("inner",), "inner", smoothstep_cubic(0.0, tr, 0.0, full), "solid")
        return (
            SectionSpec(0.0, tr, (first, *drive, hard)),
            SectionSpec(tr, length_m, (replace(first, width=_const(full)), *drive, hard)),
        )
    last = LaneSpec(("inner",), "inner", smoothstep_cubic(length_m - tr, tr, full, 0.0), "solid")
    return (
        SectionSpec(0.0, length_m - tr, (replace(last, width=_const(full)), *drive, hard)),
        SectionSpec(length_m - tr, length_m, (last, *drive, hard)),
    )


def _mark(style: str, sc: Scenario) -> tuple[RoadMark, ...]:
    m = sc.markings
    if style == "none":
        return (RoadMark(0.0, "none", 0.0),)
    if style == "solid":
        return (RoadMark(0.0, "solid", m.edge_line_width_m),)
    width = m.edge_line_width_m if style == "aux" else m.lane_line_width_m
    return (RoadMark(0.0, "broken", width),)


def _lane_ids(section: SectionSpec, sign: float) -> dict[tuple, int]:
    step = -1 if sign < 0 else 1
    return {lane.key: step * (i + 1) for i, lane in enumerate(section.lanes)}


def _build_sections(
    specs: tuple[SectionSpec, ...], sc: Scenario, *, s_a: float
) -> tuple[LaneSection, ...]:
    """Model lane sections of a road starting at absolute station ``s_a``."""
    sign = sc.side_sign
    out = []
    for k, spec in enumerate(specs):
        ids = _lane_ids(spec, sign)
        prev_ids = _lane_ids(specs[k - 1], sign) if k > 0 else {}
        next_ids = _lane_ids(specs[k + 1], sign) if k + 1 < len(specs) else {}
        lanes = []
        for lane in spec.lanes:
            width = replace(shift_cubic(lane.width, spec.s0), s0=0.0)
            start_w = width.a
            end_w = float(CubicProfile((width,)).value(spec.s1 - spec.s0))
            lanes.append(
                Lane(
                    ids[lane.key],
                    "shoulder" if lane.kind in ("inner", "hard") else "driving",
                    CubicProfile((width,)),
                    _mark(lane.mark, sc),
                    predecessor=prev_ids.get(lane.key) if start_w > 1e-9 or k == 0 else None,
                    successor=next_ids.get(lane.key) if end_w > 1e-9 else None,
                )
            )
        side = tuple(lanes)
        out.append(
            LaneSection(
                spec.s0 - s_a,
                left=side if sign > 0 else (),
                right=side if sign < 0 else (),
            )
        )
    return tuple(out)


def _sub_road(
    road_id: str,
    name: str,
    pieces,
    elevation: CubicProfile,
    specs: tuple[SectionSpec, ...],
    sc: Scenario,
    s_a: float,
    s_b: float,
    **kwargs,
) -> Road:
    inside = tuple(s for s in specs if s.s0 >= s_a - 1e-6 and s.s1 <= s_b + 1e-6)
    return Road(
        road_id,
        cut_pieces(pieces, s_a, s_b),
        _build_sections(inside, sc, s_a=s_a),
        name=name,
        elevation=cut_profile(elevation, s_a, s_b),
        **kwargs,
    )


def section_at(specs: tuple[SectionSpec, ...], s: float) -> SectionSpec:
    """The section containing station ``s`` (clipped to the first/last)."""
    starts = np.array([x.s0 for x in specs])
    return specs[int(np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(specs) - 1))]


def lanes_width_at(spec: SectionSpec, s: float, upto_kind: str | None = None) -> float:
    """Sum of the lane widths at station ``s`` of lanes up to the last of ``upto_kind``."""
    total = 0.0
    kinds = [lane.kind for lane in spec.lanes]
    last = max(i for i, k in enumerate(kinds) if k == upto_kind) if upto_kind else len(kinds) - 1
    for lane in spec.lanes[: last + 1]:
        total += float(CubicProfile((lane.width,)).value(s))
    return total


# ---------------------------------------------------------------------------
# the network
# ---------------------------------------------------------------------------


def _two_way_road(road_id: str, pieces, z: CubicProfile, width: float, road_type: str) -> Road:
    lane = Lane(1, "driving", CubicProfile.constant(width), (RoadMark(0.0, "solid", 0.15),))
    section = LaneSection(
        0.0,
        left=(lane,),
        center=Lane(0, "none", road_marks=(RoadMark(0.0, "broken", 0.15),)),
        right=(replace(lane, id=-1),),
    )
    return Road(road_id, tuple(pieces), (section,), name="other", elevation=z, road_type=road_type)


def _reverse_profile(profile: CubicProfile, length: float) -> CubicProfile:
    out = []
    pieces = profile.pieces
    for i in range(len(pieces) - 1, -1, -1):
        end = pieces[i + 1].s0 if i + 1 < len(pieces) else length
        start = max(pieces[i].s0, 0.0)
        if end <= start:
            continue
        q = shift_cubic(pieces[i], end)
        out.append(CubicPiece(length - end, q.a, -q.b, q.c, -q.d))
    return CubicProfile(tuple(out))


def build_truth(sc: Scenario) -> Truth:
    """The scenario's ground-truth road network (mapping frame ``local`` on its origin)."""
    frame = MappingFrame(sc.origin, "local")
    sign = sc.side_sign
    length = sc.length_m
    pieces = mainline_pieces(
        sc.alignment,
        start_heading_rad=math.radians(sc.start_heading_deg),
        start_xy_m=sc.start_xy_m,
    )
    elevation = elevation_profile(sc.grades, start_z_m=sc.start_z_m, length_m=length)
    specs = mainline_sections(sc)
    full = Road(
        "0",
        pieces,
        _build_sections(specs, sc, s_a=0.0),
        name="mainline",
        elevation=elevation,
    )
    cuts = [0.0, *[r.station_m for r in sc.ramps], length]
    n_main = len(cuts) - 1
    ramp_ids = [str(101 + i) for i in range(len(sc.ramps))]
    junction_ids = [str(1001 + i) for i in range(len(sc.ramps))]

    # ramps
    ramp_truths: list[RampTruth] = []
    for i, r in enumerate(sc.ramps):
        g = r.station_m
        spec = section_at(specs, g - 1e-6 if r.type == "exit" else g + 1e-6)
        t_b = sign * lanes_width_at(spec, g, "driving")
        _, _, h, k = (float(v[0]) for v in full.evaluate(np.array([g])))
        xy = full.to_xy(np.array([g]), np.array([t_b]))[0]
        rp = ramp_pieces(
            x=float(xy[0]),
            y=float(xy[1]),
            hdg=h,
            curvature_start=k / (1.0 - t_b * k),
            turn_sign=sign,
            radius_m=r.radius_m,
            clothoid_length_m=r.clothoid_length_m,
            curve_length_m=r.curve_length_m,
            tail_length_m=r.tail_length_m,
            kind=r.type,
            elements=r.elements,
        )
        rlen = rp[-1].s0 + rp[-1].length
        z_g = float(elevation.value(g))
        grade = float(elevation.derivative(g))
        z0 = z_g if r.type == "exit" else z_g - grade * rlen
        rspecs = ramp_sections(r, rlen, sc.lanes.hard_shoulder_m)
        link = RoadLink("junction", junction_ids[i])
        road = Road(
            ramp_ids[i],
            rp,
            _build_sections(rspecs, sc, s_a=0.0),
            name=r.type,
            elevation=CubicProfile((CubicPiece(0.0, z0, grade),)),
            predecessor=link if r.type == "exit" else None,
            successor=link if r.type == "entry" else None,
            road_type="motorway",
        )
        ramp_truths.append(RampTruth(r, road, g, rspecs))

    # mainline roads
    main_roads = []
    for j in range(n_main):
        pred = RoadLink("junction", junction_ids[j - 1]) if j > 0 else None
        succ = RoadLink("junction", junction_ids[j]) if j < n_main - 1 else None
        main_roads.append(
            _sub_road(
                str(j + 1),
                "mainline",
                pieces,
                elevation,
                specs,
                sc,
                cuts[j],
                cuts[j + 1],
                predecessor=pred,
                successor=succ,
            )
        )

    # junctions with lane links
    junctions = []
    for i, r in enumerate(sc.ramps):
        before = section_at(specs, r.station_m - 1e-6)
        after = section_at(specs, r.station_m + 1e-6)
        ids_b, ids_a = _lane_ids(before, sign), _lane_ids(after, sign)
        ramp_spec = ramp_truths[i].sections[0 if r.type == "exit" else -1]
        ids_r = _lane_ids(ramp_spec, sign)
        through = tuple(
            LaneLink(ids_b[k], ids_a[k]) for k in ids_b if k in ids_a and k[0] in ("inner", "drive")
        )
        conns = [Connection("1", main_roads[i].id, main_roads[i + 1].id, "start", through)]
        if r.type == "exit":
            links = [
                LaneLink(ids_b[("aux", i, j)], ids_r[("drive", j)]) for j in range(1, r.lanes + 1)
            ]
            links.append(LaneLink(ids_b[("hard",)], ids_r[("hard",)]))
            conns.append(Connection("2", main_roads[i].id, ramp_ids[i], "start", tuple(links)))
        else:
            links = [
                LaneLink(ids_r[("drive", j)], ids_a[("aux", i, j)]) for j in range(1, r.lanes + 1)
            ]
            links.append(LaneLink(ids_r[("hard",)], ids_a[("hard",)]))
            conns.append(Connection("2", ramp_ids[i], main_roads[i + 1].id, "start", tuple(links)))
        name = r.name or f"{r.type} at {r.station_m:.0f} m"
        junctions.append(Junction(junction_ids[i], tuple(conns), name=name, type="direct"))

    # opposite carriageway and unrelated roads
    others: list[Road] = []
    opposite = None
    ln = sc.lanes
    if sc.opposite.enabled:
        off = -sign * sc.opposite.median_m
        opp_pieces = reverse_pieces(offset_pieces(pieces, off))
        opp_len = opp_pieces[-1].s0 + opp_pieces[-1].length
        section_spec = SectionSpec(
            0.0,
            opp_len,
            (
                LaneSpec(("inner",), "inner", _const(ln.inner_shoulder_m), "solid"),
                *(
                    LaneSpec(
                        ("drive", j),
                        "driving",
                        _const(ln.width_m),
                        "solid" if j == ln.count else "lane",
                    )
                    for j in range(1, ln.count + 1)
                ),
                LaneSpec(("hard",), "hard", _const(ln.hard_shoulder_m), "none"),
            ),
        )
        opposite = Road(
            "201",
            opp_pieces,
            _build_sections((section_spec,), sc, s_a=0.0),
            name="other",
            elevation=_reverse_profile(elevation, opp_len),
        )
        others.append(opposite)
    for i, o in enumerate(sc.other_roads):
        s = o.station_m
        _x, _y, h, _ = (float(v[0]) for v in full.evaluate(np.array([s])))
        if o.kind == "overpass":
            t_c = -sign * sc.opposite.median_m / 2.0
            c = full.to_xy(np.array([s]), np.array([t_c]))[0]
            hdg = h + math.radians(o.angle_deg)
            x0 = c[0] - 0.5 * o.length_m * math.cos(hdg)
            y0 = c[1] - 0.5 * o.length_m * math.sin(hdg)
            z = CubicProfile.constant(float(elevation.value(s)) + o.clearance_m)
            line = Line(0.0, float(x0), float(y0), hdg, o.length_m)
        else:
            edge = lanes_width_at(section_at(specs, s), s)
            p = full.to_xy(np.array([s]), np.array([sign * (edge + o.offset_m)]))[0]
            z = CubicProfile.constant(float(elevation.value(s)))
            line = Line(0.0, float(p[0]), float(p[1]), h, o.length_m)
        road_type = "town" if o.highway == "residential" else "rural"
        others.append(_two_way_road(str(202 + i), (line,), z, o.lane_width_m, road_type))

    header = Header(name=sc.name, geo_reference=frame.geo_reference, vendor="roadtwin-simulate")
    network = RoadNetwork(
        header,
        (*main_roads, *(rt.road for rt in ramp_truths), *others),
        tuple(junctions),
    )
    return Truth(
        scenario=sc,
        frame=frame,
        network=network,
        mainline=full,
        sections=specs,
        ramps=tuple(ramp_truths),
        opposite=opposite,
        others=tuple(others),
        mainline_road_starts=tuple(cuts[:-1]),
    )


def marking_lines(truth: Truth) -> list[MarkingLine]:
    """Every painted line of the driven carriageway and its ramps (not the road edges):
    the outer border of each lane except the outermost one, section by section."""
    out: list[MarkingLine] = []
    sign = truth.sign

    def add(road: Road, specs, phase: float) -> None:
        for spec in specs:
            ids = _lane_ids(spec, sign)
            for lane in spec.lanes[:-1]:
                out.append(MarkingLine(road, spec.s0, spec.s1, ids[lane.key], lane.mark, phase))

    add(truth.mainline, truth.sections, 0.0)
    for rt in truth.ramps:
        add(rt.road, rt.sections, 0.0)
    return out


def outer_edge_id(specs: tuple[SectionSpec, ...], s, sign: float) -> np.ndarray:
    """Lane id of the outermost lane at each station (the road edge is its outer border)."""
    starts = np.array([x.s0 for x in specs])
    idx = np.clip(np.searchsorted(starts, np.asarray(s), side="right") - 1, 0, len(specs) - 1)
    counts = np.array([len(x.lanes) for x in specs])
    return (counts[idx] * (1 if sign > 0 else -1)).astype(int)
