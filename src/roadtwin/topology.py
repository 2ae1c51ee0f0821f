"""Mainline-ramp integration: cut the mainline at the ramps, build junctions and links.

The paper's topology rules ("Mainline-Ramp Integration"): an exit is a diverging
connection mainline -> ramp from the ramp's start, a merge a converging connection
ramp -> mainline at the ramp's end. Here every ramp event becomes one OpenDRIVE junction
with lane links (DESIGN.md section 6):

* ``junctions="default"`` (every consumer reads it): the mainline is cut into roads
  before and after a junction zone of ``junction_length_m``; inside the zone a
  *through* connecting road (the exact cut of the mainline) carries the through lanes,
  and a *ramp* connecting road -- a ParamPoly3 cubic Hermite curve that meets the
  mainline lane border and the ramp road exactly in position and heading -- carries the
  ramp lanes. Exit: from the deceleration lanes (or the outermost lane) into the ramp;
  merge: from the ramp into the acceleration lanes (or the outermost lane).
* ``junctions="direct"`` (OpenDRIVE 1.7+): the mainline is cut at the gore; the ramp
  road is linked directly (``linkedRoad``) to the mainline road before (exit) or after
  (merge) the gore.

Every road gets predecessor/successor links, every lane that continues across a link
gets lane predecessor/successor (or the junction's ``laneLink``), and all of them are
mutual. Mainline roads are ``"1", "2", ...`` in driving order (``name="mainline"``), ramp
roads ``name="exit"``/``"entry"``, connecting roads ``name="connector"``.
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Literal

import networkx as nx
import numpy as np

from .config import TopologyConfig
from .lane_drops import taper_lane_drops
from .mainline import cut_road
from .mainline.seal import add_linear_ramp, nonnegative_widths
from .model import (
    Connection,
    CubicPiece,
    CubicProfile,
    Junction,
    Lane,
    LaneLink,
    LaneSection,
    ParamPoly3,
    Road,
    RoadLink,
    RoadMark,
    RoadNetwork,
    chain_geometry,
    continue_width,
)
from .ramps import Ramp, hermite_piece, width_transition
from .ramps.records import FloatArray

log = logging.getLogger(__name__)

TrafficSide = Literal["right", "left"]

__all__ = [
    "Topology",
    "build_topology",
    "hermite_road",
    "lane_graph",
    "match_lanes_at",
    "true_lengths",
]


@dataclass(frozen=True)
class Topology:
    """Result of :func:`build_topology`.

    Attributes
    ----------
    roads : every road (mainline pieces, ramps, connecting roads).
    junctions : one junction per ramp.
    ramp_road_ids : id of the ramp road of each used ramp (same order as ``ramps``).
    ramps : the ramps that were integrated.
    skipped : ``(what, reason)`` of ramps that could not be integrated.
    """

    roads: tuple[Road, ...]
    junctions: tuple[Junction, ...]
    ramp_road_ids: tuple[str, ...]
    ramps: tuple[Ramp, ...]
    skipped: tuple[tuple[str, str], ...] = ()


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


def _traffic_lanes(section: LaneSection, side: TrafficSide) -> tuple[Lane, ...]:
    return section.right if side == "right" else section.left


def _border_xy(road: Road, s: float, side: TrafficSide) -> dict[int, tuple[FloatArray, FloatArray]]:
    """Inner and outer border points (mapping frame) of each traffic-side lane at ``s``."""
    s_arr = np.array([min(max(s, 0.0), road.length)])
    section = road.lane_sections[int(road.section_index(s_arr)[0])]
    out = {}
    for lane in _traffic_lanes(section, side):
        inner_id = lane.id + (1 if lane.id < 0 else -1)
        t_in = road.lane_border_t(s_arr, inner_id)
        t_out = road.lane_border_t(s_arr, lane.id)
        out[lane.id] = (road.to_xy(s_arr, t_in)[0], road.to_xy(s_arr, t_out)[0])
    return out


def match_lanes_at(
    a: Road,
    s_a: float,
    b: Road,
    s_b: float,
    *,
    traffic_side: TrafficSide = "right",
    tolerance_m: float = 0.25,
    min_width_m: float = 0.01,
) -> dict[int, int]:
    """Lanes of ``a`` at ``s_a`` -> lanes of ``b`` at ``s_b`` whose borders meet.

    Chosen by geometry, never by counting: a lane continues into the lane of the other
    road whose inner and outer border points both lie within ``tolerance_m`` of its own
    (metres, mapping frame), one partner each, nearest first. Lanes narrower than
    ``min_width_m`` at the contact are not linked (a lane that opens or closes there).
    Where lanes leave or join on either side (a gore on the outer or the median side),
    the ones that go on are found wherever they sit.
    """
    ba, bb = _border_xy(a, s_a, traffic_side), _border_xy(b, s_b, traffic_side)
    pairs = []
    for ia, (pa_in, pa_out) in ba.items():
        if float(np.hypot(*(pa_out - pa_in))) < min_width_m:
            continue
        for ib, (pb_in, pb_out) in bb.items():
            if float(np.hypot(*(pb_out - pb_in))) < min_width_m:
                continue
            d = max(float(np.hypot(*(pa_in - pb_in))), float(np.hypot(*(pa_out - pb_out))))
            if d <= tolerance_m:
                pairs.append((d, ia, ib))
    out: dict[int, int] = {}
    used: set[int] = set()
    for _, ia, ib in sorted(pairs):
        if ia in out or ib in used:
            continue
        out[ia] = ib
        used.add(ib)
    return out


def _set_lane_links(
    road: Road,
    *,
    predecessors: dict[int, int] | None = None,
    successors: dict[int, int] | None = None,
) -> Road:
    """Set lane predecessors in the first section / successors in the last section."""
    sections = list(road.lane_sections)

    def apply(sec: LaneSection, links: dict[int, int], attr: str) -> LaneSection:
        def one(lane: Lane) -> Lane:
            return replace(lane, **{attr: links.get(lane.id)})

        return replace(
            sec, left=tuple(one(x) for x in sec.left), right=tuple(one(x) for x in sec.right)
        )

    if predecessors is not None:
        sections[0] = apply(sections[0], predecessors, "predecessor")
    if successors is not None:
        sections[-1] = apply(sections[-1], successors, "successor")
    return replace(road, lane_sections=tuple(sections))


def hermite_road(
    start: tuple[float, float, float],
    end: tuple[float, float, float],
    *,
    road_id: str,
    widths_start: Sequence[float],
    widths_end: Sequence[float],
    traffic_side: TrafficSide = "right",
    heights: tuple[float, float] = (0.0, 0.0),
    rolls: tuple[float, float] = (0.0, 0.0),
    junction: str = "-1",
    name: str = "connector",
    lane_type: str = "driving",
    lane_types: Sequence[str] | None = None,
) -> Road:
    """A road whose reference line is one cubic Hermite ParamPoly3 between two poses.

    Parameters
    ----------
    start, end
        ``(x, y, heading)`` at the start and end (mapping frame, metres, radians). The
        curve meets both exactly in position and heading (tangent length = chord).
    widths_start, widths_end
        Lane widths (metres) at the two ends, inner to outer; each lane's width changes
        along a C1 cubic. Lanes lie right of the reference line (``-1, -2, ...``) for
        right-hand traffic, left of it for left-hand traffic.
    heights
        Elevation (metres) at the two ends; linear in between.
    rolls
        Superelevation (radians) at the two ends, changing along a C1 cubic: a connector
        meeting a superelevated road carries its roll there, so lane borders at equal t
        meet in plan and height (OpenDRIVE rotates t by the roll).
    lane_type, lane_types
        One type for every lane, or one per lane (inner to outer). Road marks follow the
        DESIGN.md layout: a shoulder before the driving lanes carries the solid edge line,
        driving lanes broken marks except the outermost (solid), a trailing shoulder none.
    """
    geometry = hermite_piece(start, end)
    length = geometry.length
    sign = -1 if traffic_side == "right" else 1
    lanes = []
    n = len(widths_start)
    types = list(lane_types) if lane_types is not None else [lane_type] * n
    driving_k = [k for k, t in enumerate(types[:n], start=1) if t != "shoulder"]
    last_driving = driving_k[-1] if driving_k else n
    for k, (wa, wb) in enumerate(zip(widths_start, widths_end, strict=False), start=1):
        width = CubicProfile(width_transition(float(wa), float(wb), length)[:1])
        if types[k - 1] == "shoulder":
            mark = "solid" if k < last_driving else "none"
        else:
            mark = "solid" if k == last_driving else "broken"
        lanes.append(
            Lane(
                sign * k,
                types[k - 1],  # type: ignore[arg-type]
                width,
                (RoadMark(0.0, mark),),  # type: ignore[arg-type]
            )
        )
    center = Lane(0, "none", road_marks=(RoadMark(0.0, "none"),))
    section = (
        LaneSection(0.0, center=center, right=tuple(lanes))
        if traffic_side == "right"
        else LaneSection(0.0, left=tuple(lanes), center=center)
    )
    z0, z1 = heights
    r0, r1 = (float(r) for r in rolls)
    superelevation = (
        None if r0 == 0.0 and r1 == 0.0 else CubicProfile(width_transition(r0, r1, length)[:1])
    )
    return Road(
        id=road_id,
        geometry=(geometry,),
        lane_sections=(section,),
        name=name,
        elevation=CubicProfile((CubicPiece(0.0, float(z0), (float(z1) - float(z0)) / length),)),
        superelevation=superelevation,
        junction=junction,
    )


def _curve_length(g: ParamPoly3) -> float:
    """True arc length of a ``normalized`` ParamPoly3 (Gauss-Legendre, 8 sub-intervals)."""
    nodes, weights = np.polynomial.legendre.leggauss(16)
    total = 0.0
    for k in range(8):
        p = (2 * k + 1 + nodes) / 16.0
        du = g.bU + p * (2.0 * g.cU + 3.0 * g.dU * p)
        dv = g.bV + p * (2.0 * g.cV + 3.0 * g.dV * p)
        total += float(np.hypot(du, dv) @ weights) / 16.0
    return total


def true_lengths(road: Road, *, tolerance_m: float = 1e-5) -> Road:
    """``road`` with every ``normalized`` ParamPoly3 declaring its true arc length.

    A cut of a normalized piece (:func:`roadtwin.mainline.cut_road`) keeps the station
    span as its length, which differs from the curve's arc length by millimetres; the
    ASAM checker compares the two (1 mm tolerance). The curves are unchanged; stations
    after a corrected piece move by that difference.
    """
    pieces = list(road.geometry)
    changed = False
    for i, g in enumerate(pieces):
        if isinstance(g, ParamPoly3) and g.p_range == "normalized":
            length = _curve_length(g)
            if abs(length - g.length) > tolerance_m:
                pieces[i] = replace(g, length=length)
                changed = True
    if not changed:
        return road
    return replace(road, geometry=chain_geometry(pieces))


def _widths(road: Road, s: float, lane_ids: Sequence[int]) -> list[float]:
    """Widths (metres) of ``lane_ids`` at station ``s`` of ``road``."""
    out = []
    s_arr = np.array([s])
    for lane_id in lane_ids:
        inner_id = lane_id + (1 if lane_id < 0 else -1)
        outer = road.lane_border_t(s_arr, lane_id)[0]
        inner = road.lane_border_t(s_arr, inner_id)[0]
        out.append(abs(float(outer - inner)))
    return out


def _continuous(
    pairs: dict[int, int], a: Road, s_a: float, b: Road, s_b: float, *, tol_m: float = 0.05
) -> dict[int, int]:
    """Keep the lane pairs whose widths agree within ``tol_m`` where ``a`` meets ``b``
    (a lane whose width jumps there -- a hard shoulder ending at a gore -- ends) and are
    not of zero width there (OpenDRIVE: a lane of zero width at a section end has no
    link there)."""
    out = {}
    for la, lb in pairs.items():
        wa, wb = _widths(a, s_a, [la])[0], _widths(b, s_b, [lb])[0]
        if abs(wa - wb) <= tol_m and min(wa, wb) > 0.01:
            out[la] = lb
    return out


_CLOSED_LANE_M = 2.0  # a driving lane narrower than this (metres) where it meets a
# non-driving lane has closed: it ends there instead of going on as that lane


def _end_to_start_links(
    up: Road,
    down: Road,
    traffic_side: TrafficSide,
    *,
    ramp_up: frozenset[int] = frozenset(),
    ramp_down: frozenset[int] = frozenset(),
) -> dict[int, int]:
    """Lanes of ``up`` at its end -> lanes of ``down`` at its start: their borders meet
    (:func:`match_lanes_at`), their widths go on (:func:`_continuous`, so both lanes are
    as wide there) and, where one is a driving lane and the other is not, they are at
    least ``_CLOSED_LANE_M`` wide (a driving lane that narrowed to 0.5-1.4 m and went on as
    a shoulder led esmini's car onto the shoulder: town06-auto-s3 and
    melbourne-408-opp-s9 with a noisier sensor) and neither is a lane a ramp leaves from
    (``ramp_up``, lanes of ``up``: an exit) or joins (``ramp_down``, lanes of ``down``: an
    entry). Such a lane goes on as the ramp's lane; linked on into the shoulder beside the
    gore as well, esmini drove a car bound along the mainline onto that shoulder
    (melbourne-408-lane1-s21 with a noisier sensor)."""
    pairs = match_lanes_at(up, up.length, down, 0.0, traffic_side=traffic_side)
    links = _continuous(pairs, up, up.length, down, 0.0)
    driving_up = {ln.id for ln in up.lane_sections[-1].lanes if ln.type == "driving"}
    driving_down = {ln.id for ln in down.lane_sections[0].lanes if ln.type == "driving"}
    mixed = [la for la, lb in links.items() if (la in driving_up) != (lb in driving_down)]
    drop = {
        la for la, w in zip(mixed, _widths(up, up.length, mixed), strict=True) if w < _CLOSED_LANE_M
    }
    drop |= {la for la in mixed if la in ramp_up or links[la] in ramp_down}
    return {la: lb for la, lb in links.items() if la not in drop}


def _continue_widths(road: Road, before: Road, links: dict[int, int], *, at_start: bool) -> Road:
    """``road`` whose first section's lanes linked from ``before``'s last section (``links``:
    lane of ``before`` -> lane of ``road``) start with the widths those lanes end with, so
    linked lane borders meet exactly (separately fitted sections differ by millimetres)."""
    if not links or not at_start:
        return road
    last = before.lane_sections[-1]
    span = before.length - last.s0
    w_end = {ln.id: float(ln.width.value(np.array([span]))[0]) for ln in (*last.left, *last.right)}
    target = {b: w_end[a] for a, b in links.items() if a in w_end}
    first = road.lane_sections[0]

    def fix(lane: Lane) -> Lane:
        return continue_width(lane, target[lane.id]) if lane.id in target else lane

    first = replace(
        first, left=tuple(fix(x) for x in first.left), right=tuple(fix(x) for x in first.right)
    )
    return replace(road, lane_sections=(first, *road.lane_sections[1:]))


_ALIGN_MAX_M = 0.05  # linked borders this far apart at a joint are moved onto each other
_ALIGN_FADE_M = 20.0  # ... by a lane-offset correction fading out over this (metres)


def _align_linked_borders(road: Road, before: Road, links: dict[int, int]) -> Road:
    """``road`` with its lane offset corrected at its start so that the outer borders of
    the lanes linked from ``before`` (``links``: lane of ``before`` -> lane of ``road``)
    meet those of ``before``'s end: two cuts of the mainline at a lane-offset step whose
    unlinked inner lanes differ by millimetres in total leave every linked border that far
    apart (14.7 mm on town06-auto-s9 with a noisier sensor, an ASAM error). Only a common
    shift of at most ``_ALIGN_MAX_M`` is corrected (both roads start from the same
    reference-line point); it fades out linearly over ``_ALIGN_FADE_M``."""
    if not links:
        return road
    s_end = np.array([before.length])
    s0 = np.array([0.0])
    gaps = np.array(
        [
            float(before.lane_border_t(s_end, a)[0]) - float(road.lane_border_t(s0, b)[0])
            for a, b in links.items()
        ]
    )
    shift = float(np.median(gaps))
    if not 1e-6 < abs(shift) <= _ALIGN_MAX_M or float(np.ptp(gaps)) > 1e-3:
        return road
    fade = min(_ALIGN_FADE_M, road.length)
    offset = add_linear_ramp(road.lane_offset, 0.0, fade, shift, 0.0, road.length)
    return replace(road, lane_offset=offset)


def _pose(road: Road, s: float) -> tuple[float, float, float]:
    x, y, h, _ = road.evaluate(np.array([s]))
    return float(x[0]), float(y[0]), float(h[0])


def _border_pose(road: Road, s: float, lane_id: int) -> tuple[tuple[float, float, float], float]:
    """Pose on the inner border of ``lane_id`` (metres, radians), road heading, and the
    road surface's height there (metres)."""
    inner_id = lane_id + (1 if lane_id < 0 else -1)
    s_arr = np.array([s])
    t = road.lane_border_t(s_arr, inner_id)
    xy = road.to_xy(s_arr, t)[0]
    pose = (float(xy[0]), float(xy[1]), float(road.heading(s_arr)[0]))
    return pose, float(road.surface_height(s_arr, t)[0])


def _ramp_lane_ids(road: Road, side: TrafficSide) -> list[int]:
    return [lane.id for lane in _traffic_lanes(road.lane_sections[0], side)]


def _ramp_lane_types(road: Road, side: TrafficSide) -> list[str]:
    return [lane.type for lane in _traffic_lanes(road.lane_sections[0], side)]


def _ramp_pairs(
    road: Road,
    section: LaneSection,
    sources: Sequence[int],
    shoulder: int | None,
    side: TrafficSide,
    *,
    main: Road | None = None,
    s_main: float = 0.0,
) -> list[tuple[int, int]]:
    """Mainline lane -> ramp lane pairs: the sources with the ramp's driving lanes (inner
    to outer), the mainline hard shoulder at a gore with the ramp's hard shoulder. The
    ramp's inner shoulder (and any surplus driving lane) opens from zero width: no pair."""
    lanes_ = _traffic_lanes(road.lane_sections[0], side)
    driving = [lane.id for lane in lanes_ if lane.type == "driving"]
    pairs = list(zip(sources, driving, strict=False))
    ids = {lane.id: lane for lane in _traffic_lanes(section, side)}
    outer = lanes_[-1] if len(lanes_) > 1 and lanes_[-1].type == "shoulder" else None
    if (
        shoulder is not None
        and outer is not None
        and shoulder in ids
        and ids[shoulder].type == "shoulder"
        and (main is None or _widths(main, s_main, [shoulder])[0] > 0.05)
    ):
        pairs.append((shoulder, outer.id))
    return pairs


_MIN_SOURCE_WIDTH_M = 0.5  # a mainline lane narrower than this at the junction feeds no ramp


def _valid_sources(
    section: LaneSection,
    wanted: Sequence[int],
    side: TrafficSide,
    ramp_side: str = "outer",
    *,
    main: Road | None = None,
    s_main: float = 0.0,
) -> list[int]:
    """The wanted mainline lanes that are driving lanes of ``section`` (a ramp is fed by
    driving lanes only) and, given ``main`` and the junction's station ``s_main``, at
    least ``_MIN_SOURCE_WIDTH_M`` wide there (a lane that has not opened yet links to
    nothing); else the driving lane on the ramp's side (the outermost, or the innermost
    for a ramp on the median side)."""
    driving = [lane.id for lane in _traffic_lanes(section, side) if lane.type == "driving"]
    if main is not None and driving:
        widths = _widths(main, s_main, driving)
        driving = [i for i, w in zip(driving, widths, strict=True) if w >= _MIN_SOURCE_WIDTH_M]
    got = [i for i in wanted if i in driving]
    return got or (driving[-1:] if ramp_side == "outer" else driving[:1])


def _driving_pairs(
    pairs: Sequence[tuple[int, int]], section: LaneSection, ramp_section: LaneSection, side
) -> list[tuple[int, int]]:
    """The (mainline lane, ramp lane) pairs that join two driving lanes: the junction lane
    links between mainline and ramp. The hard shoulder beside a gore keeps its width into
    the ramp but is not linked: esmini takes every junction lane link as a way to drive and
    logs "GetJunctionConnection target lane not driving" for one into a shoulder."""
    main = {lane.id: lane.type for lane in _traffic_lanes(section, side)}
    ramp = {lane.id: lane.type for lane in _traffic_lanes(ramp_section, side)}
    return [(x, y) for x, y in pairs if main.get(x) == "driving" and ramp.get(y) == "driving"]


# ---------------------------------------------------------------------------
# the stage
# ---------------------------------------------------------------------------


def _offset_steps(road: Road, *, min_step_m: float = 1e-3) -> list[float]:
    """Stations (metres) where ``road``'s lane offset jumps: the median-side edge steps
    where lanes begin or end at full width beside the centre lane."""
    out = []
    for piece in road.lane_offset.pieces[1:]:
        before, at = road.lane_offset.value(np.array([piece.s0 - 1e-9, piece.s0]))
        if abs(at - before) > min_step_m:
            out.append(float(piece.s0))
    return out


def _renumbering_borders(road: Road, traffic_side: TrafficSide) -> list[float]:
    """Section borders (metres) where a driving lane goes on under another id: a lane that
    begins or ends on the reference line's side of others renumbers every lane beyond it
    (a shoulder renumbered beside a lane added on the outside is no one's route).

    OpenDRIVE allows it, but players plan routes by lane id along a road (esmini's route
    planner logs "Lane id not available in lane section" and plans the junction
    connection of the wrong lane); roads split there and linked end to start say the
    same with the renumbering in the road links, which every player follows."""
    out = []
    sections = road.lane_sections
    for n in range(1, len(sections)):
        if any(
            ln.type == "driving" and ln.predecessor is not None and ln.predecessor != ln.id
            for ln in _traffic_lanes(sections[n], traffic_side)
        ):
            out.append(float(sections[n].s0))
    return out


def _split_stations(steps: Sequence[float], lo: float, hi: float, min_m: float) -> list[float]:
    """The stations of sorted ``steps`` (metres) where a mainline piece ``lo``..``hi`` is
    split: those inside it that leave no part shorter than ``min_m``. A step a metre or
    two past a junction's end made a road 1.9 m long that no car can drive a lane of
    (oakland-28393854-lane1-s21: a median shoulder renumbered 1.9 m past an exit's
    junction); such a step stays inside the road, its lanes linked by id there."""
    out: list[float] = []
    for x in steps:
        if x - (out[-1] if out else lo) >= min_m and hi - x >= min_m:
            out.append(float(x))
    return out


def _chain_roads(parts: list[Road], traffic_side: TrafficSide) -> list[Road]:
    """Consecutive parts of one road linked end to start (road and lane links by geometry).

    A lane offset that steps inside a road is exact but is read as a gap by checkers that
    evaluate a lane section's end with the offset record starting there (the ASAM rule
    ``contact_point_no_horizontal_gaps``); a road that ends there and a road that starts
    with the new offset say the same without that ambiguity."""
    parts = list(parts)
    for n in range(1, len(parts)):
        up, down = parts[n - 1], parts[n]
        links = _end_to_start_links(up, down, traffic_side)
        parts[n - 1] = _set_lane_links(
            replace(up, successor=RoadLink("road", down.id, "start")), successors=links
        )
        parts[n] = _set_lane_links(
            replace(down, predecessor=RoadLink("road", up.id, "end")),
            predecessors={b: a for a, b in links.items()},
        )
    return parts


def _seen_before(
    spans: dict[str, tuple[float, float]],
    road: Road,
    outer_edge_seen: Sequence[tuple[float, float]],
) -> Callable[[float], float] | None:
    """For a piece ``road`` of the mainline (``spans``: its start on the mainline and its
    length, metres): the last station of the piece (metres) before a given one where the
    outer edge was seen (``outer_edge_seen``: stretches in mainline stations), -inf where
    none; None where the piece is not one cut from the mainline as it is."""
    span = spans.get(road.id)
    if not outer_edge_seen or span is None or abs(span[1] - road.length) > 0.01:
        return None
    start = span[0]
    firsts = np.array([a for a, _ in outer_edge_seen]) - start
    lasts = np.array([b for _, b in outer_edge_seen]) - start

    def last_seen(station: float) -> float:
        began = firsts < station
        return float(np.max(np.minimum(lasts[began], station))) if np.any(began) else -np.inf

    return last_seen


def _closing_drops(
    road: Road,
    traffic_side: TrafficSide,
    max_taper_m: float,
    last_seen: Callable[[float], float] | None = None,
) -> Road:
    """``road`` with its dropped lanes closed by a taper (:mod:`roadtwin.lane_drops`)."""
    out, closed = taper_lane_drops(
        road, traffic_side, max_taper_m=max_taper_m, edge_seen_until=last_seen
    )
    for station, lane_id in closed:
        log.info(
            "road %s: driving lane %d ends at full width at s=%.0f m where the road narrows: "
            "closed by a taper",
            road.id,
            lane_id,
            station,
        )
    return out


@dataclass
class _Zone:
    ramp: Ramp
    a: float  # mainline station where the junction zone starts
    b: float  # ... and ends (a == b for direct junctions)


def unlink_width_jumps(road: Road, *, max_jump_m: float = 0.01) -> Road:
    """Drop lane links between consecutive lane sections where the linked widths jump.

    At a gore with no ramp attached (no OSM, or a ramp that was skipped) the auxiliary lane
    and the hard shoulder end or start at full width inside the mainline road: the road
    edge really jumps there. Such lanes end or start; linking them would claim a continuous
    lane whose width jumps (an error for checkers and a trap for simulators).

    Parameters
    ----------
    road
        Any road; lane links across its internal section boundaries are checked.
    max_jump_m
        Largest width change (metres) that still counts as the same lane continuing.
    """
    sections = list(road.lane_sections)
    changed = False
    for k in range(len(sections) - 1):
        a, b = sections[k], sections[k + 1]
        len_a = b.s0 - a.s0
        new_sides = {}
        for side in ("left", "right"):
            lanes_a = list(getattr(a, side))
            lanes_b = list(getattr(b, side))
            index_b = {ln.id: i for i, ln in enumerate(lanes_b)}
            for i, la in enumerate(lanes_a):
                if la.successor is None or la.successor not in index_b:
                    continue
                j = index_b[la.successor]
                lb = lanes_b[j]
                w_end = float(la.width.value(np.array([len_a]))[0])
                w_start = float(lb.width.value(np.array([0.0]))[0])
                if abs(w_end - w_start) > max_jump_m:
                    lanes_a[i] = replace(la, successor=None)
                    if lb.predecessor == la.id:
                        lanes_b[j] = replace(lb, predecessor=None)
                    changed = True
            new_sides[side] = (tuple(lanes_a), tuple(lanes_b))
        sections[k] = replace(a, left=new_sides["left"][0], right=new_sides["right"][0])
        sections[k + 1] = replace(b, left=new_sides["left"][1], right=new_sides["right"][1])
    return replace(road, lane_sections=tuple(sections)) if changed else road


def _width_at(road: Road, section: int, lane_id: int, at_end: bool) -> float | None:
    """Width (metres) of ``lane_id`` at the start or end of lane section ``section``."""
    sec = road.lane_sections[section]
    lane = next((ln for ln in (*sec.left, *sec.right) if ln.id == lane_id), None)
    if lane is None:
        return None
    hi = road.section_end(section)
    return float(lane.width.value(np.array([hi - sec.s0 if at_end else 0.0]))[0])


def prune_zero_width_links(
    roads: Sequence[Road], junctions: Sequence[Junction], *, min_width_m: float = 0.01
) -> tuple[tuple[Road, ...], tuple[Junction, ...]]:
    """Remove every lane link at which one of the two lanes has (almost) zero width.

    OpenDRIVE: a lane that appears or ends has no link at its zero-width end, and no lane
    links to a lane of zero width (the ASAM rules ``zero_width_at_start/end`` and
    ``new_lane_appear``). Links between lane sections of a road, between linked roads and
    junction lane links are all checked at their contact; both sides of a link go together
    so links stay mutual.
    """
    by_id = {r.id: r for r in roads}
    drop: set[tuple[str, int, int, str, int]] = set()  # (road, section, lane, attr, target)

    def narrow(road: Road, section: int, lane_id: int, at_end: bool) -> bool:
        w = _width_at(road, section, lane_id, at_end)
        return w is not None and w < min_width_m

    def end_section(road: Road, contact: str | None) -> tuple[int, bool]:
        return (0, False) if contact in (None, "start") else (len(road.lane_sections) - 1, True)

    for road in roads:
        secs = road.lane_sections
        for k, sec in enumerate(secs):
            for lane in (*sec.left, *sec.right):
                if lane.successor is not None:
                    if k + 1 < len(secs):
                        if narrow(road, k, lane.id, True) or narrow(
                            road, k + 1, lane.successor, False
                        ):
                            drop.add((road.id, k, lane.id, "succ", lane.successor))
                            drop.add((road.id, k + 1, lane.successor, "pred", lane.id))
                    elif road.successor is not None and road.successor.element_type == "road":
                        other = by_id.get(road.successor.element_id)
                        if other is not None:
                            j, j_end = end_section(other, road.successor.contact_point)
                            if narrow(road, k, lane.id, True) or narrow(
                                other, j, lane.successor, j_end
                            ):
                                drop.add((road.id, k, lane.id, "succ", lane.successor))
                if lane.predecessor is not None:
                    if k > 0:
                        if narrow(road, k, lane.id, False) or narrow(
                            road, k - 1, lane.predecessor, True
                        ):
                            drop.add((road.id, k, lane.id, "pred", lane.predecessor))
                            drop.add((road.id, k - 1, lane.predecessor, "succ", lane.id))
                        continue
                    link = road.predecessor
                    if link is not None and link.element_type == "road":
                        other = by_id.get(link.element_id)
                        if other is not None:
                            j, j_end = end_section(other, link.contact_point)
                            if narrow(road, 0, lane.id, False) or narrow(
                                other, j, lane.predecessor, j_end
                            ):
                                drop.add((road.id, 0, lane.id, "pred", lane.predecessor))
    new_junctions = []
    for junction in junctions:
        conns = []
        for conn in junction.connections:
            inc, tgt = by_id.get(conn.incoming_road), by_id.get(conn.connecting_road)
            if inc is None or tgt is None:
                conns.append(conn)
                continue
            ends_here = inc.successor is not None and inc.successor.element_id == junction.id
            i_sec, i_end = (len(inc.lane_sections) - 1, True) if ends_here else (0, False)
            t_sec, t_end = end_section(tgt, conn.contact_point)
            keep = tuple(
                ll
                for ll in conn.lane_links
                if not (
                    narrow(inc, i_sec, ll.from_lane, i_end) or narrow(tgt, t_sec, ll.to_lane, t_end)
                )
            )
            conns.append(replace(conn, lane_links=keep) if keep != conn.lane_links else conn)
        new_junctions.append(replace(junction, connections=tuple(conns)))

    def prune(road: Road) -> Road:
        secs = list(road.lane_sections)
        changed = False
        for k, sec in enumerate(secs):

            def one(lane: Lane, k: int = k) -> Lane:
                nonlocal changed
                out = lane
                if (road.id, k, lane.id, "succ", lane.successor) in drop or (
                    lane.successor is not None
                    and k == len(secs) - 1
                    and narrow(road, k, lane.id, True)
                ):
                    out = replace(out, successor=None)
                if (road.id, k, lane.id, "pred", lane.predecessor) in drop or (
                    lane.predecessor is not None and k == 0 and narrow(road, 0, lane.id, False)
                ):
                    out = replace(out, predecessor=None)
                changed |= out is not lane
                return out

            secs[k] = replace(
                sec, left=tuple(one(x) for x in sec.left), right=tuple(one(x) for x in sec.right)
            )
        return replace(road, lane_sections=tuple(secs)) if changed else road

    pruned = tuple(prune(r) for r in roads)
    # a road whose zero-width lane lost its link also loses the partner's link back
    by_id = {r.id: r for r in pruned}
    final = []
    for road in pruned:
        secs = list(road.lane_sections)
        changed = False
        for k in (0, len(secs) - 1):
            link = road.predecessor if k == 0 else road.successor
            if link is None or link.element_type != "road" or link.element_id not in by_id:
                continue
            other = by_id[link.element_id]
            other_link = other.successor if link.contact_point == "end" else other.predecessor
            if other_link is None or other_link.element_type != "road":
                continue  # linked through a junction: its laneLinks say who continues
            if other_link.element_id != road.id:
                continue
            j, _ = end_section(other, link.contact_point)
            back = {
                ln.id: (ln.successor if link.contact_point == "end" else ln.predecessor)
                for ln in (*other.lane_sections[j].left, *other.lane_sections[j].right)
            }

            def mutual(lane: Lane, k: int = k, back=back) -> Lane:
                nonlocal changed
                attr = "predecessor" if k == 0 else "successor"
                target = getattr(lane, attr)
                if target is not None and back.get(target) != lane.id:
                    changed = True
                    return replace(lane, **{attr: None})
                return lane

            sec = secs[k]
            secs[k] = replace(
                sec,
                left=tuple(mutual(x) for x in sec.left),
                right=tuple(mutual(x) for x in sec.right),
            )
        final.append(replace(road, lane_sections=tuple(secs)) if changed else road)
    return tuple(final), tuple(new_junctions)


def build_topology(
    mainline_road: Road,
    ramps: Sequence[Ramp],
    *,
    traffic_side: TrafficSide = "right",
    config: TopologyConfig | None = None,
    outer_edge_seen: Sequence[tuple[float, float]] = (),
) -> Topology:
    """Cut the mainline at the ramps and connect everything with junctions and lane links.

    Parameters
    ----------
    mainline_road
        The measured mainline, one road over the run (driving direction).
    ramps
        Ramps from :func:`roadtwin.ramps.build_ramps` (each attached at ``station_m``).
    traffic_side
        ``"right"`` or ``"left"``-hand traffic.
    config
        ``junctions``: ``"default"`` (connecting roads) or ``"direct"``.
    outer_edge_seen
        Stretches of ``mainline_road`` (stations, metres) where its outer edge was seen
        (:attr:`roadtwin.mainline.Mainline.outer_edge_seen`): a dropped lane's taper
        begins after the last of them before the lane's end.

    Returns
    -------
    Topology
        Roads and junctions; ramps whose junction would overlap another one or leave a
        mainline road shorter than ``min_road_length_m`` are skipped and listed.
    """
    cfg = config or TopologyConfig()
    direct = cfg.junctions == "direct"
    length = mainline_road.length
    zl = 0.0 if direct else cfg.junction_length_m

    zones: list[_Zone] = []
    skipped: list[tuple[str, str]] = []
    last_end = 0.0
    steps = sorted(
        {*_offset_steps(mainline_road), *_renumbering_borders(mainline_road, traffic_side)}
    )
    borders = sorted({*steps, *(sec.s0 for sec in mainline_road.lane_sections[1:])})
    for ramp in sorted(ramps, key=lambda r: (r.station_m, r.type)):
        s = ramp.station_m
        a, b = (s, s + zl) if ramp.type == "exit" else (s - zl, s)
        # the through connecting road holds one lane section at one lane offset: across a
        # lane-offset step its lanes would not be linked (the mainline is split there into
        # linked roads), and lanes renumbered inside a connecting road mislead players
        # (esmini took a through lane's link into a shoulder). A section border or step
        # inside the zone (lanes that end or begin just past the gore) ends the zone there,
        # also one within a metre of its free end: a section a few centimetres long at the
        # start of a connecting road is one players read past (esmini "target lane not
        # driving", melbourne-921-s2). Never outwards: a lane ending at a border just past
        # the zone would end inside the junction (krems-102561705-s2, noisier sensor)
        if not direct and ramp.type == "exit":
            b = min([x for x in borders if a + 1.0 < x < b], default=b)
        elif not direct:
            a = max([x for x in borders if a < x < b - 1.0], default=a)
        # at the run's ends the junction may be shorter: an exit just before the end of the
        # run (an entry just after its start) still gets its junction
        if not direct and ramp.type == "exit" and length - b < cfg.min_road_length_m:
            b = max(length - cfg.min_road_length_m, a + cfg.min_road_length_m)
        elif not direct and ramp.type == "entry" and not zones and a < cfg.min_road_length_m:
            a = min(cfg.min_road_length_m, b - cfg.min_road_length_m)
        what = f"{ramp.type} at s={s:.0f} m"
        if a - last_end < cfg.min_road_length_m or length - b < cfg.min_road_length_m:
            skipped.append((what, "too close to the run's end or to another ramp's junction"))
            continue
        # a short ramp gives half its length to the connecting road (_ramp_connecting_road)
        if not direct and ramp.road.length < 2.0 * cfg.min_road_length_m:
            skipped.append((what, f"ramp shorter than {2.0 * cfg.min_road_length_m:.0f} m"))
            continue
        zones.append(_Zone(ramp, a, b))
        last_end = b

    n_main = len(zones) + 1
    next_id = n_main + 1

    def new_id() -> str:
        nonlocal next_id
        out = str(next_id)
        next_id += 1
        return out

    cuts = [0.0] + [x for z in zones for x in (z.a, z.b)] + [length]
    main_roads = [
        replace(
            cut_road(mainline_road, cuts[2 * i], cuts[2 * i + 1], road_id=str(i + 1)),
            name="mainline",
        )
        for i in range(n_main)
    ]
    # where each piece of the mainline starts on it, and how long it is (metres)
    spans = {road.id: (cuts[2 * i], road.length) for i, road in enumerate(main_roads)}
    ramp_roads: list[Road] = []
    connectors: list[Road] = []
    junctions: list[Junction] = []
    ramp_ids: list[str] = []
    per_zone = 1 if direct else 3  # ramp road (+ two connecting roads)
    junction_ids = [str(n_main + per_zone * len(zones) + 1 + k) for k in range(len(zones))]
    # the mainline between junctions is split where its lane offset steps (after
    # the junctions' ids): the first part keeps the piece's id
    split_ids = itertools.count(n_main + (per_zone + 1) * len(zones) + 1)
    tails: list[list[Road]] = []
    for i in range(n_main):
        inside = _split_stations(steps, cuts[2 * i], cuts[2 * i + 1], cfg.min_road_length_m)
        if not inside:
            tails.append([])
            continue
        ends = [cuts[2 * i], *inside, cuts[2 * i + 1]]
        parts = [
            replace(
                cut_road(
                    mainline_road,
                    lo,
                    hi,
                    road_id=main_roads[i].id if j == 0 else str(next(split_ids)),
                ),
                name="mainline",
            )
            for j, (lo, hi) in enumerate(itertools.pairwise(ends))
        ]
        spans.update({part.id: (lo, part.length) for part, lo in zip(parts, ends, strict=False)})
        main_roads[i] = parts[0]
        tails.append(parts[1:])

    for k, zone in enumerate(zones):
        ramp = zone.ramp
        jid = junction_ids[k]
        up = tails[k][-1] if tails[k] else main_roads[k]
        down = main_roads[k + 1]
        up_sec, down_sec = up.lane_sections[-1], down.lane_sections[0]
        ramp_id = new_id()
        ramp_ids.append(ramp_id)
        road = replace(ramp.road, id=ramp_id)
        rlanes = _ramp_lane_ids(road, traffic_side)
        rtypes = _ramp_lane_types(road, traffic_side)
        shoulder = getattr(ramp, "shoulder_lane_id", None)
        if ramp.type == "exit":
            sources = _valid_sources(
                up_sec, ramp.mainline_lane_ids, traffic_side, ramp.side, main=up, s_main=up.length
            )
            pairs = _ramp_pairs(
                road, up_sec, sources, shoulder, traffic_side, main=up, s_main=up.length
            )
        else:
            sources = _valid_sources(
                down_sec, ramp.mainline_lane_ids, traffic_side, ramp.side, main=down, s_main=0.0
            )
            pairs = _ramp_pairs(road, down_sec, sources, shoulder, traffic_side, main=down)
        # ramp driving lane k <-> mainline source lane k, hard shoulder <-> hard shoulder at
        # a gore (widths only, not linked); the other ramp lanes open from (entry: close to)
        # zero width
        paired = {y: x for x, y in pairs}
        pairs = _driving_pairs(
            pairs,
            up_sec if ramp.type == "exit" else down_sec,
            road.lane_sections[0 if ramp.type == "exit" else -1],
            traffic_side,
        )

        up = replace(up, successor=RoadLink("junction", jid))
        down = replace(down, predecessor=RoadLink("junction", jid))
        # the mainline lanes the ramp leaves from (exit) or joins (entry)
        on_main = frozenset(x for x, _ in pairs)
        ramp_up = on_main if ramp.type == "exit" else frozenset()
        ramp_down = frozenset() if ramp.type == "exit" else on_main
        if direct:
            through = _end_to_start_links(
                up, down, traffic_side, ramp_up=ramp_up, ramp_down=ramp_down
            )
            conns = [
                Connection(
                    "0",
                    up.id,
                    down.id,
                    "start",
                    tuple(LaneLink(x, y) for x, y in sorted(through.items(), reverse=True)),
                )
            ]
            if ramp.type == "exit":
                road = replace(road, predecessor=RoadLink("junction", jid))
                conns.append(
                    Connection(
                        "1", up.id, road.id, "start", tuple(LaneLink(x, y) for x, y in pairs)
                    )
                )
            else:
                road = replace(road, successor=RoadLink("junction", jid))
                conns.append(
                    Connection(
                        "1", road.id, down.id, "start", tuple(LaneLink(y, x) for x, y in pairs)
                    )
                )
            junctions.append(
                Junction(jid, tuple(conns), name=f"{ramp.type} {k + 1}", type="direct")
            )
        else:
            # through connecting road: the exact mainline between the zone ends
            t_id = new_id()
            through_road = replace(
                cut_road(mainline_road, zone.a, zone.b, road_id=t_id),
                name="connector",
                junction=jid,
                predecessor=RoadLink("road", up.id, "end"),
                successor=RoadLink("road", down.id, "start"),
            )
            into = _end_to_start_links(up, through_road, traffic_side, ramp_up=ramp_up)
            out_of = _end_to_start_links(through_road, down, traffic_side, ramp_down=ramp_down)
            through_road = _set_lane_links(
                _align_linked_borders(
                    _continue_widths(through_road, up, into, at_start=True), up, into
                ),
                predecessors={v: u for u, v in into.items()},
                successors=out_of,
            )
            down = _continue_widths(down, through_road, out_of, at_start=True)
            conns = [
                Connection(
                    "0",
                    up.id,
                    t_id,
                    "start",
                    tuple(LaneLink(x, y) for x, y in sorted(into.items(), reverse=True)),
                )
            ]
            c_id = new_id()
            road, conn_road, ramp_conn = _ramp_connecting_road(
                road,
                up if ramp.type == "exit" else down,
                exit_=ramp.type == "exit",
                ids=(ramp_id, c_id, jid),
                junction_length_m=zl,
                source_lane=sources[0],
                paired=paired,
                pairs=pairs,
                ramp_lanes=rlanes,
                lane_types=rtypes,
                traffic_side=traffic_side,
            )
            conns.append(ramp_conn)
            road = replace(road, name=ramp.type)
            connectors.extend([through_road, conn_road])
            junctions.append(Junction(jid, tuple(conns), name=f"{ramp.type} {k + 1}"))
        if tails[k]:
            tails[k][-1] = up
        else:
            main_roads[k] = up
        main_roads[k + 1] = down
        ramp_roads.append(road)

    main_roads = [
        unlink_width_jumps(r)
        for i, road in enumerate(main_roads)
        for r in _chain_roads([road, *tails[i]], traffic_side)
    ]
    main_roads = [
        _closing_drops(
            r, traffic_side, cfg.lane_drop_taper_m, _seen_before(spans, r, outer_edge_seen)
        )
        for r in main_roads
    ]
    # the cuts, fades and tapers above re-fit widths: none may dip below zero (a lane
    # closing at a cut ended at -1.7 mm, an error for ASAM and roadtwin check)
    roads, junctions_out = prune_zero_width_links(
        [true_lengths(nonnegative_widths(r)) for r in (*main_roads, *ramp_roads, *connectors)],
        junctions,
    )
    log.info(
        "topology: %d mainline roads, %d ramps, %d connecting roads, %d %s junctions",
        len(main_roads),
        len(ramp_roads),
        len(connectors),
        len(junctions),
        cfg.junctions,
    )
    return Topology(
        roads=roads,
        junctions=junctions_out,
        ramp_road_ids=tuple(ramp_ids),
        ramps=tuple(z.ramp for z in zones),
        skipped=tuple(skipped),
    )


# ---------------------------------------------------------------------------
# lane graph (for routing checks)
# ---------------------------------------------------------------------------


def _ramp_connecting_road(
    road: Road,
    main: Road,
    *,
    exit_: bool,
    ids: tuple[str, str, str],
    junction_length_m: float,
    source_lane: int,
    paired: dict[int, int],
    pairs: list[tuple[int, int]],
    ramp_lanes: list[int],
    lane_types: list[str],
    traffic_side: str,
) -> tuple[Road, Road, Connection]:
    """The ramp road cut back by the junction, the connecting road between it and the
    mainline road ``main`` (``up`` of an exit, ``down`` of an entry) and the junction
    connection onto that connecting road.

    ``ids`` = (ramp road id, connecting road id, junction id). The connecting road runs in
    the driving direction: from the end of ``main`` into the ramp (exit) or from the ramp's
    end onto the start of ``main`` (entry), with the widths, heights and outer border of
    ``main``'s lane ``source_lane`` at its mainline end. ``pairs`` holds the linked
    (mainline lane, ramp lane) pairs (driving lanes), ``paired`` maps ramp lane -> mainline
    lane for the widths (with the hard shoulder at a gore).
    """
    ramp_id, c_id, jid = ids
    if exit_:
        cut_at = min(junction_length_m, 0.5 * road.length)
        road = cut_road(road, cut_at, road.length, road_id=ramp_id)
        s_main, s_ramp = main.length, 0.0
    else:
        cut_at = max(road.length - junction_length_m, 0.5 * road.length)
        road = cut_road(road, 0.0, cut_at, road_id=ramp_id)
        s_main, s_ramp = 0.0, road.length
    main_pose, main_z = _border_pose(main, s_main, source_lane)
    main_roll = float(main.roll(np.array([s_main]))[0])
    ramp_roll = float(road.roll(np.array([s_ramp]))[0])
    ramp_pose = _pose(road, s_ramp)
    main_widths = [
        _widths(main, s_main, [paired[i]])[0] if i in paired else 0.0 for i in ramp_lanes
    ]
    ramp_widths = _widths(road, s_ramp, ramp_lanes)
    ramp_z = float(road.height([s_ramp])[0])
    main_link = RoadLink("road", main.id, "end" if exit_ else "start")
    ramp_link = RoadLink("road", ramp_id, "start" if exit_ else "end")
    to_main = {y: x for x, y in pairs}
    same = {i: i for i in ramp_lanes}
    if exit_:
        poses, widths, heights, rolls = (
            (main_pose, ramp_pose),
            (main_widths, ramp_widths),
            (main_z, ramp_z),
            (main_roll, ramp_roll),
        )
    else:
        poses, widths, heights, rolls = (
            (ramp_pose, main_pose),
            (ramp_widths, main_widths),
            (ramp_z, main_z),
            (ramp_roll, main_roll),
        )
    conn_road = hermite_road(
        poses[0],
        poses[1],
        road_id=c_id,
        widths_start=widths[0],
        widths_end=widths[1],
        traffic_side=traffic_side,
        heights=heights,
        rolls=rolls,
        junction=jid,
        lane_types=lane_types,
    )
    conn_road = replace(
        conn_road,
        predecessor=main_link if exit_ else ramp_link,
        successor=ramp_link if exit_ else main_link,
    )
    conn_road = _set_lane_links(
        conn_road,
        predecessors=to_main if exit_ else same,
        successors=same if exit_ else to_main,
    )
    if exit_:
        road = replace(road, predecessor=RoadLink("junction", jid))
        connection = Connection(
            "1", main.id, c_id, "start", tuple(LaneLink(x, y) for x, y in pairs)
        )
    else:
        road = replace(road, successor=RoadLink("junction", jid))
        connection = Connection(
            "1", ramp_id, c_id, "start", tuple(LaneLink(i, i) for i in ramp_lanes)
        )
    return road, conn_road, connection


def lane_graph(
    network: RoadNetwork, *, traffic_side: TrafficSide = "right", lane_changes: bool = False
) -> nx.DiGraph:
    """Directed graph of the lanes a car can drive from one to the next.

    Nodes are ``(road_id, section_index, lane_id)`` (attribute ``type``); edges follow lane
    successor / predecessor links inside a road, road links, and junction connection lane
    links (default: into the connecting road; direct: into the linked road), each in the
    lane's direction of travel: with right-hand traffic right lanes (negative ids) drive
    towards +s and left lanes towards -s, mirrored for left-hand traffic (so other tools'
    maps with both carriageways on one road work too). With ``lane_changes``, neighbouring
    driving lanes of one section are connected both ways (``kind="change"``).
    """
    graph = nx.DiGraph()
    roads = network.id_to_road

    def forward(lane_id: int) -> bool:
        return (lane_id < 0) == (traffic_side == "right")

    def target_node(road_id: str, contact: str | None, lane_id: int):
        road = roads.get(road_id)
        if road is None:
            return None
        sec = 0 if contact in (None, "start") else len(road.lane_sections) - 1
        return (road_id, sec, lane_id)

    for road in network.roads:
        nsec = len(road.lane_sections)
        for k, section in enumerate(road.lane_sections):
            for lane in (*section.left, *section.right):
                node = (road.id, k, lane.id)
                graph.add_node(node, type=lane.type)
                fwd = forward(lane.id)
                nxt_lane = lane.successor if fwd else lane.predecessor
                inside = k + 1 < nsec if fwd else k > 0
                if inside:
                    if nxt_lane is not None:
                        graph.add_edge(node, (road.id, k + 1 if fwd else k - 1, nxt_lane))
                    continue
                link = road.successor if fwd else road.predecessor
                if link is None:
                    continue
                if link.element_type == "road":
                    if nxt_lane is not None:
                        tgt = target_node(link.element_id, link.contact_point, nxt_lane)
                        if tgt is not None:
                            graph.add_edge(node, tgt)
                    continue
                junction = network.id_to_junction.get(link.element_id)
                if junction is None:
                    continue
                for conn in junction.connections:
                    if conn.incoming_road != road.id:
                        continue
                    for ll in conn.lane_links:
                        if ll.from_lane == lane.id:
                            tgt = target_node(conn.connecting_road, conn.contact_point, ll.to_lane)
                            if tgt is not None:
                                graph.add_edge(node, tgt)
            if lane_changes:
                for side in (section.left, section.right):
                    for x, y in itertools.pairwise(side):
                        if x.type == "driving" and y.type == "driving":
                            graph.add_edge((road.id, k, x.id), (road.id, k, y.id), kind="change")
                            graph.add_edge((road.id, k, y.id), (road.id, k, x.id), kind="change")
    return graph
