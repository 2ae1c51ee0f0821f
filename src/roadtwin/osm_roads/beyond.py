"""The roads beyond the ramps: no ramp ends in a dead end where OSM continues.

A ramp's OSM chain ends where the link meets another road (or at ``max_ramp_length_m``).
For each ramp the first OSM road beyond its far end -- the edge leaving the exit's end
(arriving at the entry's start) with the smallest turn -- is followed up to its next
junction (a node where more than two roads meet) or ``beyond_length_m``, and built as a
road of its own that continues the ramp exactly:

* its reference line starts at the ramp's far end pose (an entry's: ends at its start
  pose) with the ramp's curvature, and is a curvature-bounded clothoid spline fitted to
  the OSM way (:func:`roadtwin.ramps.fit_ramp_shape`; the first / last piece an exact
  Hermite piece onto the ramp's pose);
* it carries the lanes of the ramp's direction only (``lanes:forward``/``backward`` or
  half the ``lanes`` of a two-way way; Algorithm 2 for one-way ways), starting with the
  ramp's widths: the ramp's inner shoulder is a lane offset blending to zero, its outer
  shoulder closes and its lanes blend to the road's lane width over the first (entry:
  last) ``blend_length_m`` in a lane section of their own (driving lane ids never change
  along the road);
* a road link and lane links (lanes of the same role) join it to the ramp;
* OSM ``name`` (else ``ref``) is its OpenDRIVE ``name``, ``maxspeed`` its
  ``<type><speed>``, both also in ``userData`` with the OSM way ids.

Coordinates in the mapping frame (metres, radians CCW from +x). OSM data: (c)
OpenStreetMap contributors, ODbL.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from typing import Any

import networkx as nx
import numpy as np
from numpy.typing import NDArray

from .._errors import FitError
from ..config import HighwayConfig, RampConfig
from ..fitting import arc_length, fit_parampoly3_chain, resample_polyline
from ..model import (
    CubicPiece,
    CubicProfile,
    Lane,
    LaneSection,
    Road,
    RoadLink,
    RoadMark,
    chain_geometry,
)
from ..ramps import Ramp, RampChain, fit_ramp_shape, hermite_piece, width_transition
from .chains import directional_lanes, edge_xy, end_heading, maxspeed_mps, turn_rad

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

__all__ = ["BeyondRoad", "beyond_roads", "link_beyond"]

_MAX_TURN_RAD = math.radians(150.0)  # sharper than this is a U-turn, not a continuation
_MIN_LENGTH_M = 15.0

_ROAD_TYPES = {
    "motorway": "motorway",
    "motorway_link": "motorway",
    "trunk": "motorway",
    "trunk_link": "motorway",
    "primary": "rural",
    "primary_link": "rural",
    "secondary": "rural",
    "secondary_link": "rural",
    "tertiary": "rural",
    "tertiary_link": "rural",
}


@dataclass(frozen=True)
class BeyondRoad:
    """A road beyond a ramp's far end.

    Attributes
    ----------
    road : the road (provisional id ``"beyond"``), driving direction of the ramp's traffic.
    ramp_road_id : the ramp road it continues (exit) or feeds (entry).
    ramp_type : ``"exit"`` or ``"entry"``.
    edges : the OSM edges it follows, in the ramp traffic's direction.
    stop : why it ends: ``"junction"``, ``"length"`` or ``"end of OSM"``.
    """

    road: Road
    ramp_road_id: str
    ramp_type: str
    edges: tuple[tuple[Any, Any, int], ...]
    stop: str


def _junction_node(graph: nx.MultiDiGraph, node: Any) -> bool:
    """More than two roads meet at ``node`` (its distinct neighbours, either direction)."""
    return len(set(graph.successors(node)) | set(graph.predecessors(node))) > 2


def _follow(
    graph: nx.MultiDiGraph,
    first: tuple[Any, Any, int],
    *,
    forward: bool,
    limit_m: float,
) -> tuple[list[tuple[Any, Any, int]], str]:
    """Edges from ``first`` on (forward: leaving its end; else arriving at its start) up to
    the next junction node or ``limit_m``; and why it stopped."""
    edges = [first]
    total = float(graph.edges[first].get("length", 0.0))
    while total < limit_m:
        u, v, _ = edges[-1]
        node = v if forward else u
        back = u if forward else v
        if _junction_node(graph, node):
            return edges, "junction"
        pool = (
            [(node, w, k) for w, ks in graph.adj[node].items() for k in ks]
            if forward
            else [(w, node, k) for w, ks in graph.pred[node].items() for k in ks]
        )
        pool = [e for e in pool if (e[1] if forward else e[0]) != back and e not in edges]
        if not pool:
            return edges, "end of OSM"
        nxt = sorted(pool, key=lambda e: (str(e[0]), str(e[1]), e[2]))[0]
        edges.append(nxt)
        total += float(graph.edges[nxt].get("length", 0.0))
    return edges, "length"


def _first_edge(
    graph: nx.MultiDiGraph, chain: RampChain, heading: float, *, exit_: bool
) -> tuple[Any, Any, int] | None:
    """The OSM edge that continues the ramp beyond its far node: smallest turn."""
    node = chain.edges[-1][1] if exit_ else chain.edges[0][0]
    own = set(chain.edges)
    if exit_:
        pool = [(node, w, k) for w, ks in graph.adj[node].items() for k in ks]
    else:
        pool = [(w, node, k) for w, ks in graph.pred[node].items() for k in ks]
    ranked = []
    for e in pool:
        if e in own:
            continue
        xy = edge_xy(graph, *e)
        h = end_heading(xy, at_end=not exit_)
        turn = turn_rad(heading, h)
        if turn <= _MAX_TURN_RAD:
            ranked.append((turn, str(e[0]), str(e[1]), e[2], e))
    return min(ranked)[-1] if ranked else None


def _tags(graph: nx.MultiDiGraph, edges: list) -> dict[str, Any]:
    """Tags of the longest edge of a followed road (its class, lanes, name, ...)."""
    longest = max(edges, key=lambda e: float(graph.edges[e].get("length", 0.0)))
    return dict(graph.edges[longest])


def _widths_at(road: Road, s: float, traffic_side: str) -> list[tuple[str, float]]:
    """``(type, width)`` of the traffic-side lanes of ``road`` at station ``s``, inner to
    outer."""
    sec = road.lane_sections[int(road.section_index(np.array([s]))[0])]
    lanes = sec.right if traffic_side == "right" else sec.left
    ds = np.array([s - sec.s0])
    return [(ln.type, float(ln.width.value(ds)[0])) for ln in lanes]


def _section(lanes: list[Lane], s0: float, traffic_side: str) -> LaneSection:
    sign = -1 if traffic_side == "right" else 1
    lanes = [replace(ln, id=sign * (i + 1)) for i, ln in enumerate(lanes)]
    if traffic_side == "right":
        return LaneSection(s0, right=tuple(lanes))
    return LaneSection(s0, left=tuple(lanes))


def _cross_section(
    ramp_lanes: list[tuple[str, float]],
    n_lanes: int,
    lane_w: float,
    length: float,
    blend: float,
    *,
    exit_: bool,
    traffic_side: str,
) -> tuple[tuple[LaneSection, ...], CubicProfile]:
    """Lane sections and lane offset of a road beyond a ramp.

    Two sections: the ramp's driving lanes blending into the road's (to ``lane_w``, extra
    lanes opening, surplus ones closing, the outer shoulder closing) and the road's own
    ``n_lanes`` driving lanes; for an entry mirrored (the blend at the end). The ramp's
    inner shoulder becomes the lane offset, blending to zero: the lane ids of the driving
    lanes never change along the road (esmini follows a route by lane id)."""
    kinds = [t for t, _ in ramp_lanes]
    driving = [w for t, w in ramp_lanes if t == "driving"]
    first = kinds.index("driving") if "driving" in kinds else len(kinds)
    inner = sum(w for _, w in ramp_lanes[:first])
    outer = [w for _, w in ramp_lanes[first + len(driving) :]]

    def ramp_side(w_ramp: float, w_road: float) -> CubicProfile:
        # exit: from the ramp's width (at 0) to the road's (at blend); entry: reversed
        a, b = (w_ramp, w_road) if exit_ else (w_road, w_ramp)
        return CubicProfile(width_transition(a, b, blend)[:1])

    def mark(k: int, n: int) -> str:
        return "solid" if k == n else "broken"

    blend_lanes: list[Lane] = []
    n_blend = max(n_lanes, len(driving))
    for k in range(1, n_blend + 1):
        w_ramp = driving[k - 1] if k <= len(driving) else 0.0
        w_road = lane_w if k <= n_lanes else 0.0
        blend_lanes.append(
            Lane(0, "driving", ramp_side(w_ramp, w_road), (RoadMark(0.0, mark(k, n_blend)),))  # type: ignore[arg-type]
        )
    for w in outer:
        blend_lanes.append(Lane(0, "shoulder", ramp_side(w, 0.0), (RoadMark(0.0, "none"),)))
    road_lanes = [
        Lane(0, "driving", CubicProfile.constant(lane_w), (RoadMark(0.0, mark(k, n_lanes)),))  # type: ignore[arg-type]
        for k in range(1, n_lanes + 1)
    ]
    towards_lanes = -1.0 if traffic_side == "right" else 1.0
    if exit_:
        offset = CubicProfile(width_transition(towards_lanes * inner, 0.0, blend))
        a = _section(blend_lanes, 0.0, traffic_side)
        b = _section(road_lanes, blend, traffic_side)
        return _link_by_order(a, b, traffic_side, span=blend), offset
    lo, hi = width_transition(0.0, towards_lanes * inner, blend, s0=length - blend)
    offset = CubicProfile((CubicPiece(0.0, 0.0), lo, replace(hi, s0=length)))
    a = _section(road_lanes, 0.0, traffic_side)
    b = _section(blend_lanes, length - blend, traffic_side)
    return _link_by_order(a, b, traffic_side, span=length - blend), offset


def _link_by_order(
    a: LaneSection, b: LaneSection, side: str, *, span: float
) -> tuple[LaneSection, ...]:
    """Link the driving lanes of two consecutive sections (``a`` is ``span`` metres long)
    in order; lanes of zero width at the boundary (the blend section's shoulders, surplus
    lanes) get no link."""
    la = list(a.right if side == "right" else a.left)
    lb = list(b.right if side == "right" else b.left)
    da = [i for i, ln in enumerate(la) if ln.type == "driving"]
    db = [i for i, ln in enumerate(lb) if ln.type == "driving"]
    for i, j in zip(da, db, strict=False):
        w_end = float(la[i].width.value(np.array([span]))[0])
        w_start = float(lb[j].width.value(np.array([0.0]))[0])
        if min(w_end, w_start) < 0.01:
            continue
        la[i] = replace(la[i], successor=lb[j].id)
        lb[j] = replace(lb[j], predecessor=la[i].id)
    if side == "right":
        return replace(a, right=tuple(la)), replace(b, right=tuple(lb))
    return replace(a, left=tuple(la)), replace(b, left=tuple(lb))


def _ramp_pose(road: Road, *, exit_: bool) -> tuple[float, float, float, float]:
    s = road.length if exit_ else 0.0
    x, y, h, k = road.evaluate(np.array([s]))
    return float(x[0]), float(y[0]), float(h[0]), float(k[0])


def beyond_road(
    graph: nx.MultiDiGraph,
    ramp_road: Road,
    chain: RampChain,
    *,
    ramp_type: str,
    traffic_side: str = "right",
    lane_width_m: float = 3.5,
    config: HighwayConfig | None = None,
    ramp_config: RampConfig | None = None,
) -> BeyondRoad | None:
    """The road beyond one ramp's far end (see the module docstring), or None where OSM
    has no road there.

    Raises
    ------
    FitError
        The OSM road beyond is too short or its fit fails.
    """
    cfg = config or HighwayConfig()
    rcfg = ramp_config or RampConfig()
    rcfg = replace(rcfg, min_radius_m=max(rcfg.min_radius_m, cfg.beyond_min_radius_m))
    exit_ = ramp_type == "exit"
    x0, y0, h0, k0 = _ramp_pose(ramp_road, exit_=exit_)
    first = _first_edge(graph, chain, h0, exit_=exit_)
    if first is None:
        return None
    edges, stop = _follow(graph, first, forward=exit_, limit_m=cfg.beyond_length_m)
    if not exit_:
        edges = edges[::-1]
    xy = np.vstack(
        [edge_xy(graph, *e) if i == 0 else edge_xy(graph, *e)[1:] for i, e in enumerate(edges)]
    )
    tags = _tags(graph, edges)
    n = directional_lanes(tags)
    oneway = tags.get("oneway") is not False
    dense = resample_polyline(xy, 0.5)
    a = arc_length(dense)
    near_ramp = a <= cfg.beyond_length_m if exit_ else a >= a[-1] - cfg.beyond_length_m
    dense = dense[near_ramp]
    if dense.shape[0] < 4 or arc_length(dense)[-1] < _MIN_LENGTH_M:
        msg = f"the OSM road beyond it is shorter than {_MIN_LENGTH_M:.0f} m"
        raise FitError(msg)
    # the reference line (left edge of the lanes for right-hand traffic): a two-way way
    # is drawn on the centre line, a one-way way in the middle of its lanes
    d = np.gradient(dense, axis=0)
    normal = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(np.hypot(*d.T), 1e-9)[:, None]
    side = 1.0 if traffic_side == "right" else -1.0
    offset = 0.5 * n * lane_width_m if oneway else 0.0
    target = dense + side * offset * normal
    # fit from the ramp's pose outward (an entry's road backwards from the ramp's start)
    lane_side = -side if exit_ else side
    anchor = (x0, y0, h0 if exit_ else h0 + math.pi)
    tgt = target if exit_ else target[::-1]
    shape = fit_ramp_shape(
        tgt,
        np.full(tgt.shape[0], rcfg.osm_sigma_m),
        anchor=anchor,
        curvature0=k0 if exit_ else -k0,
        lane_side=lane_side,
        lanes=max(n, 1),
        widths=(0.3, lane_width_m, 0.3),
        config=rcfg,
    )
    line = shape.xy if exit_ else shape.xy[::-1]
    pieces = list(
        fit_parampoly3_chain(resample_polyline(line, 1.0), tolerance_m=rcfg.fit_tolerance_m)
    )
    if exit_:
        pieces[0] = hermite_piece((x0, y0, h0), pieces[0].end_pose())
    else:
        last = pieces[-1]
        pieces[-1] = hermite_piece((last.x0, last.y0, last.hdg), (x0, y0, h0))
    geometry = chain_geometry(pieces)
    length = float(sum(g.length for g in geometry))
    blend = min(rcfg.blend_length_m, 0.4 * length)
    ramp_lanes = _widths_at(ramp_road, ramp_road.length if exit_ else 0.0, traffic_side)
    sections, lane_offset = _cross_section(
        ramp_lanes, n, lane_width_m, length, blend, exit_=exit_, traffic_side=traffic_side
    )
    z = float(ramp_road.height(np.array([ramp_road.length if exit_ else 0.0]))[0])
    name = tags.get("name") or tags.get("ref") or ""
    way_ids = tuple(
        dict.fromkeys(int(graph.edges[e]["osmid"]) for e in edges if "osmid" in graph.edges[e])
    )
    user = [(f"roadtwin:osm_{k}", str(tags[k])) for k in ("name", "ref", "highway") if tags.get(k)]
    road = Road(
        id="beyond",
        geometry=geometry,
        lane_sections=sections,
        name=str(name),
        elevation=CubicProfile((CubicPiece(0.0, z),)),
        lane_offset=lane_offset,
        road_type=_ROAD_TYPES.get(str(tags.get("highway")), "town"),
        speed_limit_mps=maxspeed_mps(tags.get("maxspeed")),
        osm_way_ids=way_ids,
        user_data=tuple(user),
    )
    return BeyondRoad(road, ramp_road.id, ramp_type, tuple(edges), stop)


def link_beyond(ramp: Road, beyond: Road, *, exit_: bool, traffic_side: str) -> tuple[Road, Road]:
    """Road and lane links between a ramp road and the road beyond it (same-role lanes:
    shoulders with shoulders, driving lanes in order)."""
    if exit_:
        ramp = replace(ramp, successor=RoadLink("road", beyond.id, "start"))
        beyond = replace(beyond, predecessor=RoadLink("road", ramp.id, "end"))
    else:
        ramp = replace(ramp, predecessor=RoadLink("road", beyond.id, "end"))
        beyond = replace(beyond, successor=RoadLink("road", ramp.id, "start"))
    r_sec = ramp.lane_sections[-1 if exit_ else 0]
    b_sec = beyond.lane_sections[0 if exit_ else -1]
    r_lanes = list(r_sec.right if traffic_side == "right" else r_sec.left)
    b_lanes = list(b_sec.right if traffic_side == "right" else b_sec.left)
    pairs = {}
    # the ramp's inner shoulder is the road's lane offset there: not a lane to link
    for kind in ("driving", "shoulder-outer"):
        ra = _role(r_lanes, kind)
        ba = _role(b_lanes, kind)
        pairs.update({r_lanes[i].id: b_lanes[j].id for i, j in zip(ra, ba, strict=False)})
    back = {v: k for k, v in pairs.items()}
    attr_r, attr_b = ("successor", "predecessor") if exit_ else ("predecessor", "successor")
    r_lanes = [replace(ln, **{attr_r: pairs.get(ln.id)}) for ln in r_lanes]
    b_lanes = [replace(ln, **{attr_b: back.get(ln.id)}) for ln in b_lanes]

    def put(road: Road, k: int, lanes: list[Lane]) -> Road:
        sec = road.lane_sections[k]
        sec = (
            replace(sec, right=tuple(lanes))
            if traffic_side == "right"
            else replace(sec, left=tuple(lanes))
        )
        secs = list(road.lane_sections)
        secs[k] = sec
        return replace(road, lane_sections=tuple(secs))

    ramp = put(ramp, -1 if exit_ else 0, r_lanes)
    beyond = put(beyond, 0 if exit_ else -1, b_lanes)
    return ramp, beyond


def _role(lanes: list[Lane], kind: str) -> list[int]:
    """Indices of the lanes of one role (``kind``): the driving lanes
    (``"driving"``) or the shoulders after the last one (``"shoulder-outer"``)."""
    idx = [i for i, ln in enumerate(lanes) if ln.type == "driving"]
    if not idx:
        return []
    if kind == "driving":
        return idx
    return [i for i in range(idx[-1] + 1, len(lanes)) if lanes[i].type == "shoulder"]


def beyond_roads(
    graph: nx.MultiDiGraph,
    roads: dict[str, Road],
    ramps: list[tuple[str, Ramp]],
    chains: tuple[RampChain, ...],
    *,
    traffic_side: str = "right",
    lane_width_m: float = 3.5,
    config: HighwayConfig | None = None,
    ramp_config: RampConfig | None = None,
) -> tuple[list[BeyondRoad], list[str]]:
    """The road beyond every ramp (``(ramp road id, ramp)`` pairs; ``roads`` by id holds
    the ramp roads, ``chains`` the ramp stage's OSM chains). Returns the roads and notes
    (ramps whose far end has no OSM road beyond, or whose road could not be built)."""
    out: list[BeyondRoad] = []
    notes: list[str] = []
    for road_id, ramp in ramps:
        chain = next((c for c in chains if tuple(c.osm_way_ids) == tuple(ramp.osm_way_ids)), None)
        if chain is None:
            continue
        what = f"{ramp.type} ways {', '.join(str(w) for w in ramp.osm_way_ids)}"
        try:
            b = beyond_road(
                graph,
                roads[road_id],
                chain,
                ramp_type=ramp.type,
                traffic_side=traffic_side,
                lane_width_m=lane_width_m,
                config=config,
                ramp_config=ramp_config,
            )
        except FitError as exc:
            notes.append(f"no road beyond {what}: {exc}")
            continue
        if b is None:
            notes.append(f"{what}: OSM has no road beyond its far end")
            continue
        out.append(b)
    return out, notes
