"""Through-routes on an OpenDRIVE road network: which roads a car drives, in which direction.

A route is a chain of :class:`Traversal` (a non-junction road driven along ``+s`` or
against it) joined by :class:`Passage` objects (a road link, a ``direct`` junction or a
``default`` junction with its connecting roads). The direction of travel on each road
follows from the links: a road entered at its start is driven along ``+s`` on the lanes
of the traffic side (right lanes with right-hand traffic), a road entered at its end
against ``s`` on the other side's lanes. Only lane links that leave from lanes carrying
traffic in the direction of travel count, so a two-way road's junction connections for
the opposite direction are never taken.

Pure functions of a :class:`~roadtwin.model.RoadNetwork`; headings in radians, lengths in
metres (mapping frame).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from .._errors import InputError
from ..model import Lane, LaneSection, Road, RoadLink, RoadNetwork

TrafficSide = Literal["right", "left"]

TRAFFIC_LANE_TYPES = frozenset(
    {
        "driving", "entry", "exit", "onRamp", "offRamp", "connectingRamp", "bidirectional",
        "slipLane", "HOV", "bus", "taxi", "mwyEntry", "mwyExit", "special1", "special2",
        "special3",
    }
)  # fmt: skip
"""Lane types cars drive on (OpenDRIVE 1.4-1.8 names)."""

PAVED_LANE_TYPES = TRAFFIC_LANE_TYPES | {"shoulder", "stop", "restricted", "parking"}
"""Lane types that are part of the paved carriageway; everything else (border, sidewalk,
median, curb, biking, none, ...) lies outside the road edges."""

MAX_THROUGH_TURN_DEG = 60.0
"""A continuation that turns more than this at a road joint is not a through-route."""


@dataclass(frozen=True)
class Traversal:
    """A non-junction road driven along ``+s`` (``direction = 1``) or against it (-1)."""

    road_id: str
    direction: int


@dataclass(frozen=True)
class Connector:
    """A connecting road of a default junction used by a passage: driven in
    ``direction``; ``lane_links`` map lanes of the incoming road to its lanes."""

    road_id: str
    direction: int
    lane_links: tuple[tuple[int, int], ...]


@dataclass(frozen=True)
class Passage:
    """How the car gets from one traversal to the next.

    ``kind`` is ``"road"`` (a road link; lanes follow their successor/predecessor ids),
    ``"direct"`` (a direct junction; ``lane_links`` map lanes of the incoming road to the
    linked road) or ``"junction"`` (a default junction through ``connectors``).
    """

    kind: Literal["road", "direct", "junction"]
    source: Traversal
    target: Traversal
    junction_id: str = ""
    lane_links: tuple[tuple[int, int], ...] = ()
    connectors: tuple[Connector, ...] = ()


@dataclass(frozen=True)
class Route:
    """Traversals in driving order and the passages between them (``len - 1`` of them)."""

    traversals: tuple[Traversal, ...]
    passages: tuple[Passage, ...]

    @property
    def road_ids(self) -> tuple[str, ...]:
        return tuple(t.road_id for t in self.traversals)


def traffic_lane_sign(direction: int, traffic_side: TrafficSide) -> int:
    """Sign of the lane ids that carry traffic along ``direction`` (+1 along s, -1 against):
    right lanes (-1) along s with right-hand traffic, left lanes (+1) with left-hand."""
    along = -1 if traffic_side == "right" else 1
    return along if direction > 0 else -along


def side_lanes(section: LaneSection, sign: int) -> tuple[Lane, ...]:
    """Lanes of one side of a section, inner to outer (``sign`` -1 right, +1 left)."""
    return section.right if sign < 0 else section.left


def _end_section(road: Road, direction: int, *, at_exit: bool) -> LaneSection:
    """The lane section where a traversal leaves (``at_exit``) or enters the road."""
    last = (direction > 0) == at_exit
    return road.lane_sections[-1] if last else road.lane_sections[0]


def traffic_lane_ids(road: Road, direction: int, traffic_side: TrafficSide, *, at_exit: bool):
    """Ids of the traffic lanes of a traversal at the end it leaves or enters by."""
    sign = traffic_lane_sign(direction, traffic_side)
    sec = _end_section(road, direction, at_exit=at_exit)
    return [ln.id for ln in side_lanes(sec, sign) if ln.type in TRAFFIC_LANE_TYPES]


def _travel_heading(road: Road, direction: int, *, at_exit: bool) -> float:
    s = road.length if (direction > 0) == at_exit else 0.0
    h = float(road.heading(s)[0])
    return h if direction > 0 else h + math.pi


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _direction_from_contact(road: Road, contact: str | None, near_xy) -> int:
    if contact == "start":
        return 1
    if contact == "end":
        return -1
    # no contact point given: the end nearer the point we come from
    ends = road.xy([0.0, road.length])
    d0 = math.dist(ends[0], near_xy)
    d1 = math.dist(ends[1], near_xy)
    return 1 if d0 <= d1 else -1


def _links_from(lane_links, sign: int) -> tuple[tuple[int, int], ...]:
    return tuple((ll.from_lane, ll.to_lane) for ll in lane_links if ll.from_lane * sign > 0)


def continuations(
    network: RoadNetwork, traversal: Traversal, traffic_side: TrafficSide
) -> list[Passage]:
    """Every way to continue from ``traversal`` into another non-junction road.

    Junction connections count only when their lane links leave from lanes carrying
    traffic in the direction of travel (or when they list no lane links at all).
    """
    road = network.road(traversal.road_id)
    d = traversal.direction
    link: RoadLink | None = road.successor if d > 0 else road.predecessor
    if link is None:
        return []
    end_xy = road.xy([road.length if d > 0 else 0.0])[0]
    sign = traffic_lane_sign(d, traffic_side)
    if link.element_type == "road":
        target = network.id_to_road.get(link.element_id)
        if target is None or target.junction != "-1":
            return []
        td = _direction_from_contact(target, link.contact_point, end_xy)
        return [Passage("road", traversal, Traversal(target.id, td))]
    junction = network.id_to_junction.get(link.element_id)
    if junction is None:
        return []
    # connections from this road whose lane links leave from its traffic lanes
    usable = []
    for con in junction.connections:
        if con.incoming_road != road.id or con.connecting_road not in network.id_to_road:
            continue
        links = _links_from(con.lane_links, sign)
        if not con.lane_links or links:
            usable.append((con, links))
    if junction.type == "direct":
        return [
            Passage(
                "direct",
                traversal,
                Traversal(con.connecting_road, 1 if con.contact_point == "start" else -1),
                junction.id,
                links,
            )
            for con, links in usable
        ]
    grouped: dict[Traversal, list[Connector]] = {}
    out: list[Passage] = []
    for con, links in usable:
        conn = network.road(con.connecting_road)
        cd = 1 if con.contact_point == "start" else -1
        far = conn.successor if cd > 0 else conn.predecessor
        if far is None or far.element_type != "road" or far.element_id not in network.id_to_road:
            continue
        target = network.road(far.element_id)
        if target.junction != "-1":
            continue
        far_xy = conn.xy([conn.length if cd > 0 else 0.0])[0]
        td = _direction_from_contact(target, far.contact_point, far_xy)
        grouped.setdefault(Traversal(target.id, td), []).append(Connector(conn.id, cd, links))
    for target_t, conns in grouped.items():
        out.append(Passage("junction", traversal, target_t, junction.id, (), tuple(conns)))
    return out


def passage_turn_rad(network: RoadNetwork, passage: Passage) -> float:
    """Absolute heading change (radians) from leaving one road to entering the next."""
    a = network.road(passage.source.road_id)
    b = network.road(passage.target.road_id)
    h0 = _travel_heading(a, passage.source.direction, at_exit=True)
    h1 = _travel_heading(b, passage.target.direction, at_exit=False)
    return abs(_wrap(h1 - h0))


def passage_through_lanes(network: RoadNetwork, passage: Passage, traffic_side) -> int:
    """Number of traffic lanes of the incoming road that the passage carries on."""
    a = network.road(passage.source.road_id)
    lanes = set(traffic_lane_ids(a, passage.source.direction, traffic_side, at_exit=True))
    if passage.kind == "road":
        sec = _end_section(a, passage.source.direction, at_exit=True)
        fwd = passage.source.direction > 0
        return sum(
            1
            for ln in (*sec.left, *sec.right)
            if ln.id in lanes and (ln.successor if fwd else ln.predecessor) is not None
        )
    if passage.kind == "direct":
        return len({f for f, _ in passage.lane_links if f in lanes}) or len(lanes)
    return len({f for c in passage.connectors for f, _ in c.lane_links if f in lanes}) or 1


def _has_traffic(network: RoadNetwork, t: Traversal, traffic_side: TrafficSide) -> bool:
    road = network.road(t.road_id)
    sign = traffic_lane_sign(t.direction, traffic_side)
    return any(
        ln.type in TRAFFIC_LANE_TYPES for sec in road.lane_sections for ln in side_lanes(sec, sign)
    )


def _score(network: RoadNetwork, p: Passage, traffic_side: TrafficSide, other: str):
    """Sort key of a passage among alternatives (smaller is better): turns within the same
    10-degree band count as equal, then more through lanes win, then the smaller turn,
    then the lower id of the road that differs (``other``)."""
    turn = math.degrees(passage_turn_rad(network, p))
    lanes = passage_through_lanes(network, p, traffic_side)
    return (round(turn / 10.0), -lanes, turn, _id_key(other))


def _best_continuation(
    network: RoadNetwork, passages: Sequence[Passage], traffic_side: TrafficSide
) -> Passage | None:
    scored = []
    for p in passages:
        if not _has_traffic(network, p.target, traffic_side):
            continue
        if math.degrees(passage_turn_rad(network, p)) > MAX_THROUGH_TURN_DEG:
            continue
        scored.append((_score(network, p, traffic_side, p.target.road_id), p))
    if not scored:
        return None
    scored.sort(key=lambda item: item[0])
    return scored[0][1]


def _incoming(network: RoadNetwork, traffic_side: TrafficSide) -> dict[Traversal, list[Passage]]:
    """Every passage into each traversal."""
    out: dict[Traversal, list[Passage]] = {}
    for road in network.roads:
        if road.junction != "-1":
            continue
        for d in (1, -1):
            for p in continuations(network, Traversal(road.id, d), traffic_side):
                out.setdefault(p.target, []).append(p)
    return out


def _trim_ramp_start(
    network: RoadNetwork, route: Route, incoming: dict, traffic_side: TrafficSide
) -> Route:
    """Drop the leading roads of a walk that join it as a ramp: the walk starts after the
    last passage, before the first one that is the best of several ways into its road,
    that is not the best way into its road."""
    start = 0
    for i, p in enumerate(route.passages):
        others = incoming.get(p.target, [])
        if len(others) < 2:
            continue  # the only way in: part of whatever leads here
        best = min(
            (_score(network, q, traffic_side, q.source.road_id), q.source.road_id) for q in others
        )
        if best[1] == p.source.road_id:
            break
        start = i + 1
    return Route(route.traversals[start:], route.passages[start:])


def _id_key(road_id: str) -> tuple[int, float, str]:
    try:
        return (0, float(road_id), road_id)
    except ValueError:
        return (1, 0.0, road_id)


def _greedy_walk(network: RoadNetwork, start: Traversal, traffic_side: TrafficSide) -> Route:
    traversals = [start]
    passages: list[Passage] = []
    seen = {start.road_id}
    while True:
        options = continuations(network, traversals[-1], traffic_side)
        best = _best_continuation(network, options, traffic_side)
        if best is None or best.target.road_id in seen:
            break
        passages.append(best)
        traversals.append(best.target)
        seen.add(best.target.road_id)
    return Route(tuple(traversals), tuple(passages))


def route_length_m(network: RoadNetwork, route: Route) -> float:
    """Length of the route's roads plus the connecting roads it drives through (metres)."""
    total = sum(network.road(t.road_id).length for t in route.traversals)
    for p in route.passages:
        if p.connectors:
            total += max(network.road(c.road_id).length for c in p.connectors)
    return total


def _lane_metres(network: RoadNetwork, route: Route, traffic_side: TrafficSide) -> float:
    """Sum over the route's roads of length times traffic lanes (at least one)."""
    total = 0.0
    for t in route.traversals:
        road = network.road(t.road_id)
        lanes = max(1, len(traffic_lane_ids(road, t.direction, traffic_side, at_exit=False)))
        total += road.length * lanes
    return total


def find_through_route(network: RoadNetwork, *, traffic_side: TrafficSide = "right") -> Route:
    """The longest plausible through-route, chosen deterministically.

    From every non-junction road and direction with traffic lanes, follow at each joint
    the continuation with the smallest heading change (within a 10-degree band: the one
    carrying the most through lanes; then the lowest road id), never turning more than
    :data:`MAX_THROUGH_TURN_DEG` and never revisiting a road; leading roads that join the
    walk as a ramp (another road enters the next one by a better passage) are dropped.
    The walk with the most lane-metres (length times traffic lanes) wins; ties: the lowest
    start road id, driving along s first.

    Raises
    ------
    InputError
        The network has no road with traffic lanes.
    """
    best: Route | None = None
    best_len = -1.0
    starts = sorted((r for r in network.roads if r.junction == "-1"), key=lambda r: _id_key(r.id))
    incoming = _incoming(network, traffic_side)
    for road in starts:
        for d in (1, -1):
            t = Traversal(road.id, d)
            if not _has_traffic(network, t, traffic_side):
                continue
            walk = _trim_ramp_start(
                network, _greedy_walk(network, t, traffic_side), incoming, traffic_side
            )
            length = _lane_metres(network, walk, traffic_side)
            if length > best_len + 1e-6:
                best, best_len = walk, length
    if best is None:
        msg = f"no road with {traffic_side}-hand-traffic driving lanes in the network"
        raise InputError(msg)
    return best


def route_from_ids(
    network: RoadNetwork, road_ids: Sequence[str], *, traffic_side: TrafficSide = "right"
) -> Route:
    """The route through ``road_ids`` (driving order), directions inferred from the links.

    Connecting roads may be listed too: they pick the junction passage they belong to and
    are then dropped (a passage uses every parallel connecting road between the same two
    roads, so the whole carriageway is kept).

    Raises
    ------
    InputError
        An unknown id, or two consecutive roads that no link or junction joins in a
        drivable direction.
    """
    ids = [str(i).strip() for i in road_ids if str(i).strip()]
    if not ids:
        raise InputError("route: no road ids given")
    for rid in ids:
        if rid not in network.id_to_road:
            raise InputError(f"route: road {rid!r} is not in the map")
    main = [i for i in ids if network.road(i).junction == "-1"]
    via = {i for i in ids if network.road(i).junction != "-1"}
    if not main:
        raise InputError("route: only connecting roads given; name the roads they join")
    options = [[d for d in (1, -1) if _has_traffic(network, Traversal(main[0], d), traffic_side)]]
    if not options[0]:
        msg = f"route: road {main[0]} has no {traffic_side}-hand-traffic driving lanes"
        raise InputError(msg)
    for d0 in options[0]:
        traversals = [Traversal(main[0], d0)]
        passages: list[Passage] = []
        ok = True
        for nxt in main[1:]:
            cands = [
                p
                for p in continuations(network, traversals[-1], traffic_side)
                if p.target.road_id == nxt
            ]
            if via:
                with_via = [p for p in cands if any(c.road_id in via for c in p.connectors)]
                cands = with_via or cands
            if not cands:
                ok = False
                break
            passages.append(cands[0])
            traversals.append(cands[0].target)
        if ok:
            return Route(tuple(traversals), tuple(passages))
    prev = main[0]
    for nxt in main[1:]:
        joined = any(
            p.target.road_id == nxt
            for d in (1, -1)
            for p in continuations(network, Traversal(prev, d), traffic_side)
        )
        if not joined:
            msg = (
                f"route: road {prev} does not continue into road {nxt} in a drivable "
                f"direction ({traffic_side}-hand traffic): no road link or junction "
                "connection with lane links from its traffic lanes"
            )
            raise InputError(msg)
        prev = nxt
    msg = f"route {','.join(ids)}: the roads do not form one drivable chain"
    raise InputError(msg)
