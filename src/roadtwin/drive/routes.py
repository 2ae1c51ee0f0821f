"""Routes a driver can take through a map, found on its lane graph.

A route is a chain of lanes ``(road_id, section_index, lane_id)`` linked by lane links,
road links and junction lane links (:func:`roadtwin.evaluation.lane_graph`, which follows
each lane in its direction of travel, so maps of other tools with both carriageways on one
road work too), plus the waypoints a car follows along it. The routes of a map:

* ``mainline``: from every driving lane at the start of the mainline to its end;
* ``exit``: from the mainline into every road named ``exit``;
* ``entry``: from every road named ``entry`` onto the mainline;
* ``connection``: through every junction lane link of a driving lane that none of the
  routes above drives;
* ``road``: along every other road with driving lanes that no route touches yet (maps
  without roadtwin's road names: one route per driving direction).

Routes stay on driving lanes where the map allows it. A ramp that no lane path reaches (a
missing connection, a ramp linked to the wrong road) still becomes a route, with
``problem`` naming the road and lane where its lane chain breaks: it cannot be driven and
fails.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Literal

import networkx as nx
import numpy as np

from ..config import DriveConfig
from ..evaluation import lane_graph
from ..evaluation.frenet import mainline_roads, ramp_roads
from ..model import Road, RoadNetwork

__all__ = ["DRIVABLE", "LanePoint", "Route", "find_routes", "lane_type_at", "traffic_side"]

DRIVABLE = frozenset({"driving", "entry", "exit", "onRamp", "offRamp", "bidirectional"})
"""Lane types a car may drive on (OpenDRIVE; roadtwin writes ``driving``)."""

LaneNode = tuple[str, int, int]
"""A lane of one lane section: ``(road_id, section_index, lane_id)``."""

RouteKind = Literal["mainline", "exit", "entry", "connection", "road"]


@dataclass(frozen=True)
class LanePoint:
    """A point on a lane: road, lane and station ``s_m`` (metres along the road)."""

    road_id: str
    lane_id: int
    s_m: float


@dataclass(frozen=True)
class Route:
    """One drive through the map.

    Attributes
    ----------
    name : readable and unique, e.g. ``"exit road 4"``.
    kind : ``mainline``, ``exit``, ``entry``, ``connection`` or ``road``.
    lanes : the lane chain in driving order.
    waypoints : start, one point on every road in between, target (the car's route).
    length_m : planned distance from start to target along the lanes (metres).
    on_target_m : planned distance on the target road (the last road) up to the target.
    problem : why no lane chain exists (then ``lanes`` and ``waypoints`` are empty).
    """

    name: str
    kind: RouteKind
    lanes: tuple[LaneNode, ...] = ()
    waypoints: tuple[LanePoint, ...] = ()
    length_m: float = 0.0
    on_target_m: float = 0.0
    problem: str = ""

    @property
    def roads(self) -> tuple[str, ...]:
        """Road ids in driving order (each once)."""
        return tuple(dict.fromkeys(node[0] for node in self.lanes))

    @property
    def start(self) -> LanePoint:
        return self.waypoints[0]

    @property
    def target(self) -> LanePoint:
        return self.waypoints[-1]


# ---------------------------------------------------------------------------
# lanes: direction, span, width, type
# ---------------------------------------------------------------------------


def traffic_side(network: RoadNetwork) -> Literal["right", "left"]:
    """``left`` when every driving lane of the map is a left lane (a roadtwin map of
    left-hand traffic), else ``right``."""
    ids = [
        lane.id
        for road in network.roads
        for sec in road.lane_sections
        for lane in (*sec.left, *sec.right)
        if lane.type in DRIVABLE
    ]
    return "left" if ids and all(i > 0 for i in ids) else "right"


def _forward(lane_id: int, side: str) -> bool:
    """True when ``lane_id`` is driven towards increasing s."""
    return (lane_id < 0) == (side == "right")


def _section_range(road: Road, k: int) -> tuple[float, float]:
    s0 = road.lane_sections[k].s0
    s1 = road.section_end(k)
    return s0, s1


def _span(network: RoadNetwork, node: LaneNode, side: str) -> tuple[float, float]:
    """Stations where the car enters and leaves ``node`` (metres)."""
    road_id, k, lane_id = node
    s0, s1 = _section_range(network.road(road_id), k)
    return (s0, s1) if _forward(lane_id, side) else (s1, s0)


def _length(network: RoadNetwork, node: LaneNode, side: str) -> float:
    a, b = _span(network, node, side)
    return abs(b - a)


def _widths(road: Road, k: int, lane_id: int, s: np.ndarray) -> np.ndarray:
    """Width (metres) of ``lane_id`` of section ``k`` at stations ``s`` inside it."""
    s0, s1 = _section_range(road, k)
    s = np.clip(s, s0, max(s0, np.nextafter(s1, s0)))
    inner = lane_id + 1 if lane_id < 0 else lane_id - 1
    return np.abs(road.lane_border_t(s, lane_id) - road.lane_border_t(s, inner))


def lane_type_at(network: RoadNetwork, road_id: str, lane_id: int, s: np.ndarray) -> np.ndarray:
    """Lane type (``str`` array) of ``lane_id`` of road ``road_id`` at stations ``s``;
    ``"missing"`` where the road has no such lane (or no such road)."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    out = np.full(s.shape, "missing", dtype=object)
    road = network.id_to_road.get(road_id)
    if road is None:
        return out
    sec_idx = road.section_index(s)
    for k in np.unique(sec_idx):
        sec = road.lane_sections[int(k)]
        types = {lane.id: lane.type for lane in (*sec.left, *sec.right)}
        out[sec_idx == k] = types.get(lane_id, "missing")
    return out


# ---------------------------------------------------------------------------
# building one route from a lane chain
# ---------------------------------------------------------------------------


@dataclass
class _Ctx:
    network: RoadNetwork
    graph: nx.DiGraph  # every lane
    driving: nx.DiGraph  # driving lanes only, edges weighted by the length of their head
    side: str
    config: DriveConfig

    def length(self, node: LaneNode) -> float:
        return _length(self.network, node, self.side)


def _pick(nodes: list[LaneNode], prefer_road: str) -> LaneNode:
    """Deterministic choice among linked lanes: the same road first, then by id."""
    return sorted(nodes, key=lambda n: (n[0] != prefer_road, n[0], n[1], abs(n[2])))[0]


def _extend_back(ctx: _Ctx, path: list[LaneNode], limit_m: float) -> list[LaneNode]:
    """Prepend driving lanes leading into ``path`` until ``limit_m`` of approach."""
    out = list(path)
    total = 0.0
    while total < limit_m and out[0] in ctx.driving:
        preds = [p for p in ctx.driving.predecessors(out[0]) if p not in out]
        if not preds:
            break
        node = _pick(preds, out[0][0])
        out.insert(0, node)
        total += ctx.length(node)
    return out


def _extend_forward(ctx: _Ctx, path: list[LaneNode], limit_m: float) -> list[LaneNode]:
    """Append the driving lanes that continue ``path`` on its last road up to ``limit_m``."""
    out = list(path)
    road = out[-1][0]
    total = sum(ctx.length(n) for n in out if n[0] == road)
    while total < limit_m and out[-1] in ctx.driving:
        succ = [n for n in ctx.driving.successors(out[-1]) if n[0] == road and n not in out]
        if not succ:
            break
        node = _pick(succ, road)
        out.append(node)
        total += ctx.length(node)
    return out


def _usable(ctx: _Ctx, node: LaneNode, *, from_entry: bool) -> float | None:
    """Distance (metres from where the car enters ``node``) at which its lane is first
    (``from_entry``) / last wide enough, moved ``end_margin_m`` inside; None if never."""
    cfg = ctx.config
    a, b = _span(ctx.network, node, ctx.side)
    length = abs(b - a)
    d = np.linspace(0.0, length, max(2, math.ceil(length / 0.5) + 1))
    s = a + np.sign(b - a) * d
    width = _widths(ctx.network.road(node[0]), node[1], node[2], s)
    wide = np.nonzero(width >= cfg.min_lane_width_m)[0]
    if wide.size == 0:
        return None
    out = d[wide[0]] + cfg.end_margin_m if from_entry else d[wide[-1]] - cfg.end_margin_m
    return float(out) if 0.0 <= out <= length else None


def _make_route(
    ctx: _Ctx,
    name: str,
    kind: RouteKind,
    lanes: list[LaneNode],
    *,
    approach_m: float = 0.0,
    core_start: int = 0,
    follow_m: float = math.inf,
    via_junctions: bool = False,
) -> Route:
    """Waypoints and planned distances of a lane chain.

    The car starts ``approach_m`` before ``lanes[core_start]`` (or where the first lane is
    wide enough) and stops on the last road after at most ``follow_m`` or where the last
    lane stops being wide enough. Waypoints are the start and the target (the player finds
    the way, as for any user's scenario), with ``via_junctions`` also the middle of every
    junction connecting road of the chain (to drive one particular connection).
    """
    cfg = ctx.config
    spans = [_span(ctx.network, n, ctx.side) for n in lanes]
    lengths = [abs(b - a) for a, b in spans]
    cum = np.concatenate([[0.0], np.cumsum(lengths)])  # distance where each lane is entered
    last_road = lanes[-1][0]
    k_last = len(lanes) - 1
    while k_last > 0 and lanes[k_last - 1][0] == last_road:
        k_last -= 1
    u_lo = max(0.0, cum[core_start] - approach_m)
    u_start = None
    for i in range(len(lanes)):
        if cum[i + 1] <= u_lo:
            continue
        wide = _usable(ctx, lanes[i], from_entry=True)
        if wide is not None and max(u_lo - cum[i], wide) < lengths[i]:
            u_start = cum[i] + max(u_lo - cum[i], wide)
            break
    u_target = None
    if u_start is not None:
        # on the last road, where its lane is last wide enough; a last road whose lane
        # never is (a lane link onto a shoulder) still gets the target, at its end
        u_hi = cum[k_last] + follow_m
        u = min(cum[-1] - cfg.end_margin_m, u_hi)
        # a mainline lane that closes by a taper may narrow below the width over its last
        # road already (melbourne-921-s2: 1.6 m where the road began, esmini moved the car
        # into the lane beside it): its target is where it was last wide enough
        first = 0 if kind == "mainline" else k_last
        for j in range(len(lanes) - 1, first - 1, -1):
            wide = _usable(ctx, lanes[j], from_entry=False)
            if wide is not None:
                u = min(cum[j] + wide, u_hi)
                break
        if u - u_start >= cfg.reach_tolerance_m:
            u_target = u
    if u_start is None or u_target is None:
        return Route(name, kind, tuple(lanes), problem=_no_room(ctx, lanes))

    def at(u: float) -> tuple[int, LanePoint]:
        i = min(int(np.searchsorted(cum, u, side="right")) - 1, len(lanes) - 1)
        a, b = spans[i]
        return i, LanePoint(lanes[i][0], lanes[i][2], float(a + np.sign(b - a) * (u - cum[i])))

    i0, start = at(u_start)
    i1, target = at(u_target)
    used = lanes[i0 : i1 + 1]
    points = [start]
    for road_id, group in itertools.groupby(used, key=lambda n: n[0]):
        if road_id in (start.road_id, target.road_id) or not (
            via_junctions and ctx.network.road(road_id).junction != "-1"
        ):
            continue
        nodes = list(group)
        mid = 0.5 * (
            _span(ctx.network, nodes[0], ctx.side)[0] + _span(ctx.network, nodes[-1], ctx.side)[1]
        )
        k = int(ctx.network.road(road_id).section_index(mid))
        lane = next((n[2] for n in nodes if n[1] == k), nodes[0][2])
        points.append(LanePoint(road_id, lane, float(mid)))
    points.append(target)
    k_target = i1  # the first lane of the target's road (the last road's, or before it)
    while k_target > 0 and lanes[k_target - 1][0] == lanes[i1][0]:
        k_target -= 1
    on_target = u_target - max(u_start, cum[max(k_target, i0)])
    return Route(
        name, kind, tuple(used), tuple(points), float(u_target - u_start), float(on_target)
    )


def _no_room(ctx: _Ctx, lanes: list[LaneNode]) -> str:
    road_id, _, lane_id = lanes[0]
    return (
        f"no stretch of at least {ctx.config.min_lane_width_m:g} m lane width to drive "
        f"from road {road_id} lane {lane_id} to road {lanes[-1][0]} lane {lanes[-1][2]}"
    )


# ---------------------------------------------------------------------------
# where a lane chain breaks
# ---------------------------------------------------------------------------


def _describe(ctx: _Ctx, node: LaneNode) -> str:
    road_id, k, lane_id = node
    a, b = _span(ctx.network, node, ctx.side)
    return f"road {road_id} lane {lane_id} (section {k}, s={min(a, b):.1f}-{max(a, b):.1f} m)"


def _unconnected_note(ctx: _Ctx, node: LaneNode) -> str:
    """Why no lane leads into ``node``, from the road links around it."""
    road = ctx.network.road(node[0])
    if road.junction != "-1":
        junction = ctx.network.id_to_junction.get(road.junction)
        if junction is None:
            return f"; its junction {road.junction} does not exist"
        if not any(c.connecting_road == road.id for c in junction.connections):
            return f"; junction {junction.id} has no connection onto road {road.id}"
        return ""
    link = road.predecessor if _forward(node[2], ctx.side) else road.successor
    if link is None:
        return f"; road {road.id} has no link at that end"
    if link.element_type == "junction":
        junction = ctx.network.id_to_junction.get(link.element_id)
        leads_here = junction is not None and any(
            road.id in _linked_ids(ctx.network, c.connecting_road) or c.connecting_road == road.id
            for c in junction.connections
        )
        if not leads_here:
            return (
                f"; road {road.id} links to junction {link.element_id}, but no road of that "
                f"junction leads onto it"
            )
        return ""
    return f"; road {road.id} links to road {link.element_id}, whose lanes do not lead into it"


def _linked_ids(network: RoadNetwork, road_id: str) -> set[str]:
    road = network.id_to_road.get(road_id)
    if road is None:
        return set()
    return {
        link.element_id
        for link in (road.predecessor, road.successor)
        if link is not None and link.element_type == "road"
    }


def _chain_end(ctx: _Ctx, node: LaneNode, *, backward: bool) -> tuple[LaneNode, bool]:
    """Follow lane links from ``node`` until they stop or reach a lane that is not a
    driving lane; the last lane and whether it is drivable."""
    seen = {node}
    while True:
        nxt = ctx.graph.predecessors(node) if backward else ctx.graph.successors(node)
        cand = [n for n in nxt if n not in seen]
        if not cand:
            return node, True
        node = _pick(cand, node[0])
        if ctx.graph.nodes[node].get("type") not in DRIVABLE:
            return node, False
        seen.add(node)


def _break_into(ctx: _Ctx, target: LaneNode, what: str) -> str:
    start, drivable = _chain_end(ctx, target, backward=True)
    head = f"no driving lane of {what} leads into road {target[0]} lane {target[2]}: "
    if not drivable:
        kind = ctx.graph.nodes[start].get("type")
        return head + f"its lane chain comes from {_describe(ctx, start)}, a {kind} lane"
    return (
        head
        + f"its lane chain starts at {_describe(ctx, start)}, which no lane leads into"
        + _unconnected_note(ctx, start)
    )


def _break_out_of(ctx: _Ctx, source: LaneNode, what: str) -> str:
    end, drivable = _chain_end(ctx, source, backward=False)
    head = f"no driving lane path from road {source[0]} lane {source[2]} reaches {what}: "
    if not drivable:
        kind = ctx.graph.nodes[end].get("type")
        return head + f"its lane chain leads onto {_describe(ctx, end)}, a {kind} lane"
    return head + f"its lane chain ends at {_describe(ctx, end)}, which leads nowhere"


# ---------------------------------------------------------------------------
# the route finders
# ---------------------------------------------------------------------------


def _driving_nodes(ctx: _Ctx, road_ids: set[str], *, section: str | None = None) -> list:
    """Driving lanes of ``road_ids`` (``section="entry"``: only where the car enters the
    road, ``"exit"``: only where it leaves it), in travel direction."""
    out = []
    for node in ctx.driving.nodes:
        road_id, k, lane_id = node
        if road_id not in road_ids:
            continue
        n_sec = len(ctx.network.road(road_id).lane_sections)
        fwd = _forward(lane_id, ctx.side)
        if section == "entry" and k != (0 if fwd else n_sec - 1):
            continue
        if section == "exit" and k != (n_sec - 1 if fwd else 0):
            continue
        out.append(node)
    return sorted(out, key=lambda n: (n[0], n[1], abs(n[2])))


def _shortest(ctx: _Ctx, sources: list, targets: list) -> list[LaneNode] | None:
    """Shortest driving-lane chain from any source to any target (by length)."""
    if not sources or not targets:
        return None
    dist, paths = nx.multi_source_dijkstra(ctx.driving, set(sources), weight="w")
    reached = [t for t in targets if t in dist]
    if not reached:
        return None
    best = min(reached, key=lambda t: (dist[t], t[0], t[1], abs(t[2])))
    return list(paths[best])


def _follow(ctx: _Ctx, start: LaneNode, prefer: set[str]) -> list[LaneNode]:
    """The driving-lane chain from ``start`` as far as it goes (roads in ``prefer`` first,
    then the same road)."""
    path = [start]
    while path[-1] in ctx.driving:
        succ = [n for n in ctx.driving.successors(path[-1]) if n not in path]
        if not succ:
            return path
        path.append(_pick([n for n in succ if n[0] in prefer] or succ, path[-1][0]))
    return path


def _natural_end(ctx: _Ctx, node: LaneNode) -> bool:
    """A lane chain may end here: the lane narrows below ``min_lane_width_m`` (a lane
    drop), or the road ends without a link (the edge of the map)."""
    road = ctx.network.road(node[0])
    if _usable(ctx, node, from_entry=False) is None:
        return True
    b = _span(ctx.network, node, ctx.side)[1]
    width = _widths(road, node[1], node[2], np.array([b]))[0]
    if width < ctx.config.min_lane_width_m:
        return True
    at_road_end = math.isclose(b, road.length) or math.isclose(b, 0.0, abs_tol=1e-9)
    link = road.successor if _forward(node[2], ctx.side) else road.predecessor
    return at_road_end and link is None


def _mainline_chains(network: RoadNetwork, order: list[Road]) -> list[list[Road]]:
    """``order`` (mainline roads and their junctions' through roads, chain by chain)
    split into its chains: a map of a whole highway has one per carriageway."""
    joined = {
        frozenset((c.incoming_road, c.connecting_road))
        for j in network.junctions
        for c in j.connections
    }

    def linked(a: str, b: str) -> bool:
        return (
            b in _linked_ids(network, a)
            or a in _linked_ids(network, b)
            or frozenset((a, b)) in joined
        )

    chains: list[list[Road]] = []
    for road in order:
        if chains and linked(chains[-1][-1].id, road.id):
            chains[-1].append(road)
        else:
            chains.append([road])
    return chains


def _mainline_routes(ctx: _Ctx) -> list[Route]:
    """From every driving lane at the start of each mainline (one per carriageway) to its
    end, or as far as the lane goes where it ends in a taper (a lane drop) or leaves the
    mainline."""
    order = mainline_roads(ctx.network)
    chains = _mainline_chains(ctx.network, order)
    routes = []
    for chain in chains:
        named = [r for r in chain if r.name == "mainline"]
        if not named:
            continue
        first, last = named[0].id, named[-1].id
        targets = _driving_nodes(ctx, {last}, section="exit")
        for src in _driving_nodes(ctx, {first}, section="entry"):
            name = f"mainline lane {src[2]}"
            if len(chains) > 1:
                name = f"mainline road {first} lane {src[2]}"
            path = _shortest(ctx, [src], targets) or _follow(ctx, src, {r.id for r in chain})
            if path[-1] not in targets and not _natural_end(ctx, path[-1]):
                problem = _break_out_of(ctx, src, f"the end of the mainline (road {last})")
                routes.append(Route(name, "mainline", problem=problem))
                continue
            routes.append(_make_route(ctx, name, "mainline", path))
    return routes


def _ramp_routes(ctx: _Ctx) -> list[Route]:
    """From the mainline into every exit (with ``approach_m`` before its junction) and from
    every entry onto the mainline, each along the ramp / mainline up to ``follow_m``."""
    cfg = ctx.config
    main_ids = {r.id for r in ctx.network.roads if r.name == "mainline"}
    main_nodes = _driving_nodes(ctx, main_ids)
    routes = []
    for ramp in sorted(ramp_roads(ctx.network, with_connectors=False), key=lambda r: _id_key(r.id)):
        name = f"{ramp.name} road {ramp.id}"
        exit_ = ramp.name == "exit"
        kind: RouteKind = "exit" if exit_ else "entry"
        ramp_nodes = _driving_nodes(ctx, {ramp.id}, section="entry")
        sources, targets = (main_nodes, ramp_nodes) if exit_ else (ramp_nodes, main_nodes)
        path = _shortest(ctx, sources, targets)
        if path is None:
            if not ramp_nodes:
                problem = f"road {ramp.id} has no driving lane"
            elif exit_:
                problem = _break_into(ctx, ramp_nodes[0], "the mainline")
            else:
                problem = _break_out_of(ctx, ramp_nodes[0], "the mainline")
            routes.append(Route(name, kind, problem=problem))
            continue
        back, core = path, 0
        if exit_:  # the approach: mainline lanes before the junction
            back = _extend_back(ctx, path, cfg.approach_m)
            leave = next(k for k, n in enumerate(path) if n[0] not in main_ids)
            core = len(back) - len(path) + leave
        full = _extend_forward(ctx, back, cfg.follow_m)
        approach = cfg.approach_m if exit_ else 0.0
        routes.append(
            _make_route(
                ctx, name, kind, full, approach_m=approach, core_start=core, follow_m=cfg.follow_m
            )
        )
    return routes


def _id_key(road_id: str) -> tuple[int, float, str]:
    try:
        return (0, float(road_id), road_id)
    except ValueError:
        return (1, 0.0, road_id)


def _covered(routes: list[Route]) -> set[tuple[LaneNode, LaneNode]]:
    return {e for r in routes for e in itertools.pairwise(r.lanes)}


def _connection_edges(ctx: _Ctx) -> list[tuple[str, LaneNode, LaneNode]]:
    """``(junction id, incoming lane, connecting lane)`` of every junction lane link whose
    incoming lane is a driving lane, as the lane graph has it."""
    out = []
    for junction in sorted(ctx.network.junctions, key=lambda j: _id_key(j.id)):
        for conn in junction.connections:
            for ll in conn.lane_links:
                for u, v in _link_edges(ctx, junction.id, conn, ll.from_lane, ll.to_lane):
                    if ctx.graph.nodes[u].get("type") in DRIVABLE:
                        out.append((junction.id, u, v))
    return out


def _link_edges(ctx: _Ctx, junction_id: str, conn, from_lane: int, to_lane: int):
    """Lane-graph edges of one junction lane link (normally one)."""
    inc = ctx.network.id_to_road.get(conn.incoming_road)
    tgt = ctx.network.id_to_road.get(conn.connecting_road)
    if inc is None or tgt is None:
        return []
    edges = []
    for i_sec in {0, len(inc.lane_sections) - 1}:
        for t_sec in {0, len(tgt.lane_sections) - 1}:
            u, v = (inc.id, i_sec, from_lane), (tgt.id, t_sec, to_lane)
            if ctx.graph.has_edge(u, v):
                edges.append((u, v))
    return edges


def _connection_routes(ctx: _Ctx, covered: set) -> list[Route]:
    routes = []
    for junction_id, u, v in _connection_edges(ctx):
        if (u, v) in covered:
            continue
        name = f"junction {junction_id}: road {u[0]} lane {u[2]} -> road {v[0]} lane {v[2]}"
        path = [u, v]
        # through the connecting road(s) onto the road after the junction
        while ctx.network.road(path[-1][0]).junction != "-1":
            succ = [n for n in ctx.graph.successors(path[-1]) if n not in path]
            if not succ:
                break
            path.append(_pick(succ, path[-1][0]))
        if ctx.network.road(path[-1][0]).junction != "-1":
            end = path[-1]
            if _natural_end(ctx, end):
                # a lane that tapers out inside the junction (a ramp's second lane
                # merging): no route a driver keeps to
                covered.update(itertools.pairwise(path))
                continue
            problem = (
                f"road {end[0]} lane {end[2]} inside junction {junction_id} leads nowhere "
                f"(no lane link out of the junction)"
            )
            routes.append(Route(name, "connection", tuple(path), problem=problem))
            covered.update(itertools.pairwise(path))
            continue
        inside = [n for n in path if ctx.network.road(n[0]).junction != "-1"]
        if inside and all(_usable(ctx, n, from_entry=True) is None for n in inside):
            # a lane narrower than a car all through the junction (a lane opening from
            # zero width at a cut, 0.1-0.4 m there): no connection a driver takes; the
            # car changes into the lane where it is open
            covered.update(itertools.pairwise(path))
            continue
        back = _extend_back(ctx, path, ctx.config.approach_m)
        core = len(back) - len(path) + 1  # the first lane inside the junction
        full = _extend_forward(ctx, back, ctx.config.follow_m)
        route = _make_route(
            ctx,
            name,
            "connection",
            full,
            approach_m=ctx.config.approach_m,
            core_start=core,
            follow_m=ctx.config.follow_m,
            via_junctions=True,
        )
        routes.append(route)
        covered.update(itertools.pairwise(full))
    return routes


def _road_routes(ctx: _Ctx, routes: list[Route]) -> list[Route]:
    """One route per driving direction of every plain road no route touches."""
    touched = {n[0] for r in routes for n in r.lanes}
    out = []
    for road in sorted(ctx.network.roads, key=lambda r: _id_key(r.id)):
        if road.junction != "-1" or road.id in touched:
            continue
        for sign in (-1, 1):
            starts = [n for n in _driving_nodes(ctx, {road.id}, section="entry") if n[2] * sign > 0]
            if not starts:
                continue
            path = [starts[0]]
            path = _extend_forward(ctx, path, math.inf)
            out.append(_make_route(ctx, f"road {road.id} lane {starts[0][2]}", "road", path))
    return out


def find_routes(network: RoadNetwork, *, config: DriveConfig | None = None) -> list[Route]:
    """Every route a driver can take through ``network`` (see the module docstring).

    Parameters
    ----------
    network
        The map.
    config
        ``approach_m``, ``follow_m``, ``min_lane_width_m``, ``end_margin_m`` shape the routes.

    Returns
    -------
    list of Route
        In the order mainline, exits and entries (by road id), junction connections, other
        roads. Routes with a ``problem`` cannot be driven.
    """
    cfg = config or DriveConfig()
    side = traffic_side(network)
    graph = lane_graph(network, traffic_side=side)
    driving = graph.subgraph(n for n, d in graph.nodes(data=True) if d.get("type") in DRIVABLE)
    driving = nx.DiGraph(driving)
    for u, v in driving.edges:
        driving.edges[u, v]["w"] = _length(network, v, side)
    ctx = _Ctx(network, graph, driving, side, cfg)
    routes = _mainline_routes(ctx) + _ramp_routes(ctx)
    covered = _covered(routes)
    routes += _connection_routes(ctx, covered)
    routes += _road_routes(ctx, routes)
    return routes
