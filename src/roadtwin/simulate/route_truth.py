"""Ground truth of a route through any road network, laid out like our simulated runs.

The driven carriageway becomes one-directional roads named ``"mainline"`` (ids ``"1"``,
``"2"``, ...; reference line = the median-side edge, lanes on the traffic side inner to
outer), cut where a ramp leaves or joins it: an exit at the start of its junction (or at
a direct junction), an entry at the junction's end. A ramp on the median side (``side``
``"inner"``) takes its lanes away or brings them at full width there, and the mainline's
reference line runs on smoothly: the median-side edge's step is the lane offset of the
roads beyond it. Each branch that leaves or joins the
route becomes a road named ``"exit"`` / ``"entry"`` (ids from ``"101"``), followed up to
``ramp_length_m`` or its next junction, and is linked to the mainline by a ``direct``
junction (ids from ``"1001"``, one per cut) with lane links in both roles. All geometry
is fitted (:mod:`roadtwin.simulate.canonical`), so the source map may use any geometry
type and drive its roads either way.

Stations are metres along the whole mainline (the concatenation of the mainline roads).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from .._errors import FitError, InputError
from ..evaluation.mainline_truth import lane_borders
from ..frames import MappingFrame
from ..mainline.cut import cut_road
from ..model import (
    Connection,
    CubicProfile,
    Header,
    Junction,
    LaneLink,
    Road,
    RoadLink,
    RoadNetwork,
)
from .canonical import ChainFit, FitSettings, fit_chain, lane_keys, max_border_error_m
from .carriageway import (
    GapRule,
    Leg,
    junction_leg,
    leg_passages,
    next_lane,
    passage_carried,
    road_legs,
    route_legs,
)
from .route import (
    TRAFFIC_LANE_TYPES,
    Passage,
    Route,
    TrafficSide,
    Traversal,
    continuations,
    entries_into,
    passage_turn_rad,
)

log = logging.getLogger(__name__)

MAX_AUX_LANE_M = 600.0
"""A lane that begins at most this far before an exit it leads into (or ends at most this
far after the entry it comes from) is the ramp's auxiliary lane; longer ones are through
lanes that happen to lead into (come from) the ramp."""

MAX_RAMP_TURN_DEG = 120.0
"""A branch turning more than this at its junction (a U-turn) is not a ramp."""

BRANCH_PIECES_M = {"min_piece_m": 1.0, "width_min_piece_m": 2.0}
"""Shortest geometry and width pieces of a branch's fit. Coarser than the mainline's: a
branch that these cannot hold within ``max_branch_error_m`` (lanes of a crossroads that
fold or cross, which esmini cannot drive either) is left out of the truth."""


@dataclass(frozen=True)
class LeftOutRamp:
    """A ramp of the source map that the truth leaves out (too close to the window's end,
    too short, knotted, or not representable by one road), so that its run has no truth
    of it. ``xy`` is where it leaves (exit) or joins (entry) the mainline, mapping-frame
    metres; a built ramp there is neither matched nor spurious
    (:func:`roadtwin.evaluation.topology.topology_against_truth`)."""

    type: str
    what: str
    why: str
    xy: tuple[float, float]

    def to_dict(self) -> dict:
        """The truth.json record."""
        x, y = self.xy
        return {
            "type": self.type,
            "what": self.what,
            "why": self.why,
            "x": round(x, 3),
            "y": round(y, 3),
        }


@dataclass(frozen=True)
class RampTruth:
    """A ramp of the true network.

    ``station_m`` is the gore (where the ramp's paved band separates from the mainline's,
    on the mainline), ``cut_station_m`` where the mainline roads are cut for it (the
    junction), ``fit`` the ramp's fitted chain (its road is ``road``).
    """

    type: str
    road: Road
    fit: ChainFit
    station_m: float
    cut_station_m: float
    junction_id: str
    main_before: str
    main_after: str
    lanes: int
    aux_lane_ids: tuple[int, ...]
    source_roads: tuple[str, ...]
    name: str = ""
    side: str = "outer"
    """Side of the mainline's through lanes the ramp leaves or joins on: ``"outer"`` (the
    traffic side: right with right-hand traffic) or ``"inner"`` (the median side)."""


@dataclass(frozen=True)
class RouteTruth:
    """Everything the generic sensor and OSM writer need about a route's true roads."""

    frame: MappingFrame
    traffic_side: TrafficSide
    network: RoadNetwork
    mainline: Road
    mainline_fit: ChainFit
    mainline_road_starts: tuple[float, ...]
    ramps: tuple[RampTruth, ...]
    route: Route
    source_name: str = ""
    aux_keys: frozenset[int] = field(default_factory=frozenset)
    fit_error_m: dict[str, float] = field(default_factory=dict)
    left_out: tuple[LeftOutRamp, ...] = ()

    @property
    def sign(self) -> float:
        """-1 for right-hand traffic (lanes right of the reference line), +1 for left."""
        return -1.0 if self.traffic_side == "right" else 1.0

    @property
    def mainline_roads(self) -> tuple[Road, ...]:
        return tuple(r for r in self.network.roads if r.name == "mainline")


@dataclass(frozen=True)
class _Branch:
    kind: str  # exit | entry
    passage: Passage
    through: Passage
    through_index: int
    legs: tuple[Leg, ...]


# ---------------------------------------------------------------------------
# branches
# ---------------------------------------------------------------------------


def _carries_traffic(network: RoadNetwork, passage: Passage) -> bool:
    if passage.kind == "junction":
        for _, cid, t in passage_carried(passage):
            for sec in network.road(cid).lane_sections:
                for lane in (*sec.left, *sec.right):
                    if lane.id == t and lane.type in TRAFFIC_LANE_TYPES:
                        return True
        return False
    target = network.road(passage.target.road_id)
    ids = {t for _, t in passage.lane_links} or None
    return any(
        lane.type in TRAFFIC_LANE_TYPES and (ids is None or lane.id in ids)
        for sec in target.lane_sections
        for lane in (*sec.left, *sec.right)
    )


def _is_ramp(network: RoadNetwork, passage: Passage, route_roads: set[str]) -> bool:
    other = passage.target.road_id if passage.source.road_id in route_roads else None
    if other is None:
        other = passage.source.road_id
    if other in route_roads:
        return False
    if np.degrees(passage_turn_rad(network, passage)) > MAX_RAMP_TURN_DEG:
        return False
    return _carries_traffic(network, passage)


def _previous(network: RoadNetwork, t: Traversal) -> Traversal | None:
    """The traversal that leads into ``t`` by a plain road link (None at a junction)."""
    road = network.road(t.road_id)
    link = road.predecessor if t.direction > 0 else road.successor
    if link is None or link.element_type != "road":
        return None
    prev = network.id_to_road.get(link.element_id)
    if prev is None or prev.junction != "-1":
        return None
    if link.contact_point == "end":
        return Traversal(prev.id, 1)
    if link.contact_point == "start":
        return Traversal(prev.id, -1)
    return None


def _ramp_roads(
    network: RoadNetwork,
    first: Traversal,
    kind: str,
    length_m: float,
    traffic_side: TrafficSide,
    avoid: set[str],
) -> list[tuple[Traversal, float | None]]:
    """Traversals of a ramp beyond its junction (in driving order), each with the metres
    kept (None: the whole road), up to ``length_m`` or the next junction."""
    out: list[tuple[Traversal, float | None]] = []
    total = 0.0
    t: Traversal | None = first
    seen = set(avoid)
    while t is not None and t.road_id not in seen and total < length_m - 1e-6:
        seen.add(t.road_id)
        length = network.road(t.road_id).length
        keep = None if total + length <= length_m else length_m - total
        out.append((t, keep))
        total += length if keep is None else keep
        if kind == "exit":
            nxt = continuations(network, t, traffic_side)
            t = nxt[0].target if len(nxt) == 1 and nxt[0].kind == "road" else None
        else:
            t = _previous(network, t)
    return out if kind == "exit" else out[::-1]


def find_branches(
    network: RoadNetwork,
    route: Route,
    legs: list[Leg],
    joints: list[int],
    traffic_side: TrafficSide,
    *,
    ramp_length_m: float,
) -> list[_Branch]:
    """Exits leaving and entries joining the route at its junctions, with their legs."""
    route_roads = set(route.road_ids)
    out: list[_Branch] = []
    for i, through in enumerate(route.passages):
        if through.kind == "road":
            continue
        up_leg = legs[joints[i] - 1]
        after = joints[i] + (1 if through.kind == "junction" else 0)
        down_leg = legs[after]
        main_leg = legs[joints[i]] if through.kind == "junction" else None
        for p in continuations(network, route.traversals[i], traffic_side):
            if p.target == through.target or not _is_ramp(network, p, route_roads):
                continue
            chain = _ramp_roads(network, p.target, "exit", ramp_length_m, traffic_side, route_roads)
            ramp_legs: list[Leg] = []
            for t, keep in chain:
                ramp_legs += road_legs(network, t, traffic_side, keep_m=keep, keep="start")
            if not ramp_legs:
                continue
            if p.kind == "junction":
                rule = _exit_rule(up_leg, main_leg, p, ramp_legs[0])
                ramp_legs.insert(
                    0, junction_leg(network, p, up_leg, ramp_legs[0], traffic_side, rule)
                )
            out.append(_Branch("exit", p, through, i, tuple(ramp_legs)))
        for p in entries_into(network, through, traffic_side):
            if not _is_ramp(network, p, route_roads):
                continue
            chain = _ramp_roads(
                network, p.source, "entry", ramp_length_m, traffic_side, route_roads
            )
            ramp_legs = []
            for t, keep in chain:
                ramp_legs += road_legs(network, t, traffic_side, keep_m=keep, keep="end")
            if not ramp_legs:
                continue
            if p.kind == "junction":
                rule = _entry_rule(down_leg, main_leg, p, ramp_legs[-1])
                ramp_legs.append(
                    junction_leg(network, p, ramp_legs[-1], down_leg, traffic_side, rule)
                )
            out.append(_Branch("entry", p, through, i, tuple(ramp_legs)))
    return out


def _left_out(network: RoadNetwork, branch: _Branch, why: str) -> LeftOutRamp:
    """The record of a branch left out of the truth, placed where it leaves (exit) or
    joins (entry) the route: the reference line at the end of its leg on the route."""
    leg = branch.legs[0] if branch.kind == "exit" else branch.legs[-1]
    span = leg.spans[0]
    s = span.s_start if branch.kind == "exit" else span.s_end
    xy = network.road(span.road_id).xy(np.array([s]))[0]
    what = f"{branch.kind} via roads {','.join(_roads_of(branch))}"
    return LeftOutRamp(branch.kind, what, why, (float(xy[0]), float(xy[1])))


def _roads_of(branch: _Branch) -> tuple[str, ...]:
    return tuple(dict.fromkeys(sp.road_id for leg in branch.legs for sp in leg.spans))


def _ids(leg: Leg) -> list[int]:
    return [ln.source[1] for ln in leg.lanes if ln.source is not None]


def _away_gap(order: list[int], ramp: set[int], main: set[int]) -> str:
    """The side of the mainline lanes a ramp's lanes lie on: ``outer`` or ``inner``."""
    pos_r = [order.index(i) for i in ramp if i in order]
    pos_m = [order.index(i) for i in main if i in order]
    if not pos_r or not pos_m:
        return "outer"
    return "outer" if np.mean(pos_r) >= np.mean(pos_m) else "inner"


def _exit_rule(up_leg: Leg, main_leg: Leg | None, p: Passage, first: Leg) -> GapRule:
    up_order = _ids(up_leg)
    through = {ln.up[1] for ln in main_leg.lanes if ln.source is not None} if main_leg else set()
    ramp = {f for f, _, _ in passage_carried(p)}
    return GapRule(
        up_ids=frozenset(set(up_order) - through - ramp),
        down_ids=frozenset(_ids(first)),
        up_gaps=frozenset({_away_gap(up_order, ramp, through)}),
    )


def _entry_rule(down_leg: Leg, main_leg: Leg | None, p: Passage, last: Leg) -> GapRule:
    down_order = _ids(down_leg)
    through = (
        {ln.down[1] for ln in main_leg.lanes if ln.source is not None and ln.down is not None}
        if main_leg
        else set()
    )
    return GapRule(
        up_ids=frozenset(_ids(last)),
        down_ids=frozenset(set(down_order) - through),
        down_gaps=frozenset({_away_gap(down_order, set(down_order) - through, through)}),
    )


# ---------------------------------------------------------------------------
# assembly
# ---------------------------------------------------------------------------


def _section_index_at(fit: ChainFit, u: float, *, before: bool) -> int:
    sec_s0 = np.array([ls.s0 for ls in fit.road.lane_sections])
    probe = u - 1e-6 if before else u + 1e-6
    return int(np.clip(np.searchsorted(sec_s0, probe, side="right") - 1, 0, len(sec_s0) - 1))


def _links_between(
    network: RoadNetwork,
    fit_a: ChainFit,
    leg_a: int,
    fit_b: ChainFit,
    leg_b: int,
    passage: Passage | None,
) -> tuple[LaneLink, ...]:
    """Lane links from the lanes of leg ``leg_a`` of chain A (its last section) into the
    lanes of leg ``leg_b`` of chain B (its first section)."""
    la, lb = fit_a.legs[leg_a], fit_b.legs[leg_b]
    sec_a = _section_index_at(fit_a, fit_a.leg_u[leg_a][1], before=True)
    sec_b = _section_index_at(fit_b, fit_b.leg_u[leg_b][0], before=False)
    out = []
    for lane, key in zip(la.lanes, fit_a.keys[leg_a], strict=True):
        nxt = next_lane(network, la, lane, lb, passage)
        if nxt is None:
            continue
        for lane_b, key_b in zip(lb.lanes, fit_b.keys[leg_b], strict=True):
            if lane_b.up == nxt:
                ida, idb = fit_a.lane_id(sec_a, key), fit_b.lane_id(sec_b, key_b)
                if ida is not None and idb is not None:
                    out.append(LaneLink(ida, idb))
                break
    return tuple(out)


def _gore_station(mainline: Road, ramp: Road, cut_u: float, kind: str, side_sign: float) -> float:
    """Mainline station where the ramp's paved band stops overlapping the mainline's
    (exit: first such station after the cut; entry: last one before it)."""
    n = int(min(ramp.length, 400.0)) + 1
    s = np.linspace(0.0, min(ramp.length, 400.0), n)
    if kind == "entry":
        s = ramp.length - s
    ref_r, out_r, _, _ = lane_borders(ramp, s)
    guess = cut_u + (s if kind == "exit" else -(ramp.length - s))
    ends = []
    for t in (ref_r, out_r):
        u, tm = mainline.project(ramp.to_xy(s, t), s_init=guess, iterations=8)
        ends.append((u, tm))
    u = 0.5 * (ends[0][0] + ends[1][0])
    lo_r = np.minimum(ends[0][1], ends[1][1]) * -side_sign
    hi_r = np.maximum(ends[0][1], ends[1][1]) * -side_sign
    ref_m, out_m, _, _ = lane_borders(mainline, np.clip(u, 0.0, mainline.length))
    lo_m = np.minimum(ref_m, out_m) * -side_sign
    hi_m = np.maximum(ref_m, out_m) * -side_sign
    lo_r, hi_r = np.minimum(lo_r, hi_r), np.maximum(lo_r, hi_r)
    lo_m, hi_m = np.minimum(lo_m, hi_m), np.maximum(lo_m, hi_m)
    overlap = np.minimum(hi_r, hi_m) - np.maximum(lo_r, lo_m)
    apart = overlap < 0.05
    if not np.any(apart):
        return cut_u
    j = int(np.argmax(apart))
    return float(np.clip(u[j], 0.0, mainline.length))


def build_route_truth(
    network: RoadNetwork,
    route: Route,
    *,
    frame: MappingFrame,
    traffic_side: TrafficSide = "right",
    ramp_length_m: float = 300.0,
    fit: FitSettings | None = None,
    name: str = "route",
    max_branch_error_m: float = 0.01,
) -> RouteTruth:
    """The canonical ground truth of ``route`` (see the module docstring).

    A branch whose canonical road would deviate from the map by more than
    ``max_branch_error_m`` (a tight urban turn whose lanes fold, lanes of separate
    connecting roads that cross) is left out with a warning.

    Raises
    ------
    InputError
        The route has no drivable carriageway somewhere.
    """
    legs, joints = route_legs(network, route, traffic_side)
    branches = find_branches(
        network, route, legs, joints, traffic_side, ramp_length_m=ramp_length_m
    )
    counter = [0]
    leg_pass = leg_passages(route, legs)
    main_keys = lane_keys(network, legs, leg_pass, counter=counter)
    # branches first: one that a road with a median-side reference line cannot hold
    # (lanes folding inside a tight turn, lanes of separate connectors crossing) is left
    # out of the truth altogether, so the run stays consistent with truth.xodr
    branch_fits: dict[int, ChainFit] = {}
    left_out: list[LeftOutRamp] = []
    branch_cfg = replace(fit or FitSettings(), **BRANCH_PIECES_M)
    for b_idx, b in enumerate(branches):
        passages: list[Passage | None] = [None] * (len(b.legs) - 1)
        keys = lane_keys(network, list(b.legs), passages, counter=counter)
        try:
            # (a branch whose median-side edge jumps, e.g. across a crossroads, folds and is
            # left out below, as before: the lane offset steps are the mainline's)
            bfit = fit_chain(
                network, list(b.legs), keys, traffic_side, road_id="", name=b.kind,
                settings=branch_cfg, median_steps=False,
            )  # fmt: skip
        except (FitError, InputError) as exc:
            log.warning("%s from %s left out: %s", b.kind, _roads_of(b), exc)
            left_out.append(_left_out(network, b, f"cannot be fitted: {exc}"))
            continue
        err = max_border_error_m(bfit)
        if max(err.values()) > max_branch_error_m:
            log.warning(
                "%s via roads %s left out of the truth: one road cannot represent it "
                "(borders %.2f m off; lanes fold or cross)",
                b.kind, ",".join(_roads_of(b)), max(err.values()),
            )  # fmt: skip
            left_out.append(_left_out(network, b, "one road cannot represent it"))
            continue
        branch_fits[b_idx] = bfit
    # the lanes of the kept ramps on the median side end / start at full width where the
    # ramp's road begins / ends (the median-side edge steps there): legs again with them
    ramp_legs, _ = route_legs(
        network, route, traffic_side, ramps=[branches[b].passage for b in branch_fits]
    )
    if ramp_legs != legs:
        legs = ramp_legs
        leg_pass = leg_passages(route, legs)
        main_keys = lane_keys(network, legs, leg_pass, counter=counter)
    cut_legs: dict[int, list[tuple[_Branch, ChainFit]]] = {}
    for b_idx, bfit in branch_fits.items():
        b = branches[b_idx]
        i = b.through_index
        at = joints[i] if b.kind == "exit" or b.through.kind == "direct" else joints[i] + 1
        cut_legs.setdefault(at, []).append((b, bfit))
    cuts = sorted(cut_legs)
    main_fit = fit_chain(
        network, legs, main_keys, traffic_side, road_id="0", name="mainline",
        breaks=tuple(cuts), settings=fit,
    )  # fmt: skip
    sign = -1.0 if traffic_side == "right" else 1.0
    cut_u = [main_fit.leg_u[c][0] for c in cuts]
    starts = [0.0, *cut_u]
    ends = [*cut_u, main_fit.road.length]
    main_ids = [str(k + 1) for k in range(len(starts))]
    junction_ids = [str(1001 + k) for k in range(len(cuts))]

    # ramps, ordered by their cut and type
    ramp_items = []
    for c_idx, c in enumerate(cuts):
        for b, bfit in sorted(cut_legs[c], key=lambda x: (x[0].kind, _roads_of(x[0]))):
            ramp_items.append((c_idx, c, b, bfit))
    ramps: list[RampTruth] = []
    ramp_roads: list[Road] = []
    connections: dict[int, list[Connection]] = {k: [] for k in range(len(cuts))}
    aux_keys: set[int] = set()
    first_sec = {}
    last_sec = {}
    for k, keys in enumerate(main_fit.section_keys):
        for key in keys:
            first_sec.setdefault(key, k)
            last_sec[key] = k
    n_sec = len(main_fit.section_keys)
    for r_idx, (c_idx, c, b, rfit) in enumerate(ramp_items):
        rid = str(101 + r_idx)
        rfit = replace(rfit, road=replace(rfit.road, id=rid))
        jid = junction_ids[c_idx]
        link = RoadLink("junction", jid)
        road = replace(
            rfit.road,
            predecessor=link if b.kind == "exit" else None,
            successor=link if b.kind == "entry" else None,
        )
        if b.kind == "exit":
            links = _links_between(network, main_fit, c - 1, rfit, 0, b.passage)
            conn = Connection("", main_ids[c_idx], rid, "start", links)
            sec = _section_index_at(main_fit, cut_u[c_idx], before=True)
            aux_ids = tuple(ll.from_lane for ll in links)
            for ll in links:
                key = main_fit.key_of(sec, ll.from_lane)
                first_u = main_fit.road.lane_sections[first_sec[key]].s0
                if first_sec[key] > 0 and cut_u[c_idx] - first_u <= MAX_AUX_LANE_M:
                    aux_keys.add(key)
        else:
            links = _links_between(network, rfit, len(b.legs) - 1, main_fit, c, b.passage)
            conn = Connection("", rid, main_ids[c_idx + 1], "start", links)
            sec = _section_index_at(main_fit, cut_u[c_idx], before=False)
            aux_ids = tuple(ll.to_lane for ll in links)
            for ll in links:
                key = main_fit.key_of(sec, ll.to_lane)
                last = last_sec[key]
                end_u = main_fit.road.lane_sections[last + 1].s0 if last + 1 < n_sec else math.inf
                if end_u - cut_u[c_idx] <= MAX_AUX_LANE_M:
                    aux_keys.add(key)
        connections[c_idx].append(conn)
        through = _links_between(network, main_fit, c - 1, main_fit, c, leg_pass[c - 1])
        main_sec = main_fit.road.lane_sections[sec]
        order = [ln.id for ln in (main_sec.right or main_sec.left)]
        end = "from_lane" if b.kind == "exit" else "to_lane"
        side = _away_gap(
            order, {getattr(ll, end) for ll in links}, {getattr(ll, end) for ll in through}
        )
        end_sec = road.lane_sections[0 if b.kind == "exit" else -1]
        n_lanes = sum(1 for ln in (end_sec.right or end_sec.left) if ln.type in TRAFFIC_LANE_TYPES)
        gore = _gore_station(main_fit.road, road, cut_u[c_idx], b.kind, sign)
        src = _roads_of(b)
        names = [network.road(x).name for x in src if network.road(x).junction == "-1"]
        ramps.append(
            RampTruth(
                type=b.kind,
                road=road,
                fit=rfit,
                station_m=gore,
                cut_station_m=cut_u[c_idx],
                junction_id=jid,
                main_before=main_ids[c_idx],
                main_after=main_ids[c_idx + 1],
                lanes=max(1, n_lanes),
                aux_lane_ids=aux_ids,
                source_roads=src,
                name=next((x for x in names if x), ""),
                side=side,
            )
        )
        ramp_roads.append(road)

    # mainline roads and junctions
    main_roads = []
    for k, (a, e) in enumerate(zip(starts, ends, strict=True)):
        part = cut_road(main_fit.road, a, e, road_id=main_ids[k])  # exact, re-based to 0
        if all(p.a == p.b == p.c == p.d == 0.0 for p in part.lane_offset.pieces):
            part = replace(part, lane_offset=CubicProfile())  # no step on this road
        main_roads.append(
            replace(
                part,
                predecessor=RoadLink("junction", junction_ids[k - 1]) if k > 0 else None,
                successor=RoadLink("junction", junction_ids[k]) if k < len(cuts) else None,
            )
        )
    junctions = []
    for c_idx, c in enumerate(cuts):
        through = _links_between(network, main_fit, c - 1, main_fit, c, leg_pass[c - 1])
        conns = [Connection("1", main_ids[c_idx], main_ids[c_idx + 1], "start", through)]
        conns += [replace(x, id=str(j + 2)) for j, x in enumerate(connections[c_idx])]
        names = sorted({r.type for r in ramps if r.junction_id == junction_ids[c_idx]})
        junctions.append(
            Junction(
                junction_ids[c_idx],
                tuple(conns),
                name=f"{'/'.join(names)} at {cut_u[c_idx]:.0f} m",
                type="direct",
            )
        )
    header = Header(name=name, geo_reference=frame.geo_reference, vendor="roadtwin-simulate")
    truth_net = RoadNetwork(header, (*main_roads, *ramp_roads), tuple(junctions))
    errors = max_border_error_m(main_fit)
    for r in ramps:
        e = max_border_error_m(r.fit)
        errors = {k: max(errors[k], e[k]) for k in errors}
    if errors["lane_borders"] > 0.005 or errors["median_edge"] > 0.005:
        log.warning(
            "canonical truth deviates from the source map by up to %.1f mm (median edge) / "
            "%.1f mm (lane borders)",
            errors["median_edge"] * 1000,
            errors["lane_borders"] * 1000,
        )
    if not main_roads:
        raise InputError("route: no mainline road could be built")
    return RouteTruth(
        frame=frame,
        traffic_side=traffic_side,
        network=truth_net,
        mainline=main_fit.road,
        mainline_fit=main_fit,
        mainline_road_starts=tuple(starts),
        ramps=tuple(ramps),
        route=route,
        source_name=name,
        aux_keys=frozenset(aux_keys),
        fit_error_m=errors,
        left_out=tuple(left_out),
    )
