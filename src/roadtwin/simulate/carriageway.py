"""The carriageway along a route, leg by leg: which source lanes it is made of.

A *leg* is a stretch over which the carriageway is described by one set of source lanes:
one lane section of a road driven in one direction (``kind="road"``), or one passage
through a ``default`` junction (``kind="junction"``), whose lanes may come from several
parallel connecting roads (maps such as CARLA's model every lane of a junction as its own
connecting road).

*Carriageway* of a lane section and direction: the contiguous paved lanes
(:data:`~roadtwin.simulate.route.PAVED_LANE_TYPES`) around the innermost traffic lane of
that direction; paved non-traffic lanes across the centre line (an inner shoulder drawn as
the other side's lane 1) belong to it up to the first unpaved lane (a median).

Inside a junction, lanes of the incoming road that the passage does not carry (its
shoulders, or the lanes that leave for a ramp) and lanes of the outgoing road that arrive
from nowhere are *bridged*: matched in order from the carried lanes outwards (traffic
lanes with traffic lanes, the others with the others), their width blends smoothly from
the incoming to the outgoing width, and unmatched ones taper from / to zero. So the
carriageway's edges stay continuous through a junction whatever the map models there.
The exception are the lanes a ramp of the truth takes away from the route or brings onto
it on the median side (a left exit with right-hand traffic): they end or start at full
width at the junction's ends, where the ramp's own road begins or ends, so the median-side
edge steps there (the canonical truth turns the step into a lane offset step).

Frames: stations ``s`` are metres along a source road; ``p`` in [0, 1] is the relative
position along a leg in the direction of travel; positions are mapping-frame metres.
Sampling legs into dense cross-sections is :mod:`roadtwin.simulate.leg_samples`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._errors import InputError
from ..model import Lane, LaneSection, Road, RoadMark, RoadNetwork
from .route import (
    PAVED_LANE_TYPES,
    TRAFFIC_LANE_TYPES,
    Passage,
    Route,
    TrafficSide,
    Traversal,
    side_lanes,
    traffic_lane_sign,
)

FloatArray = NDArray[np.float64]
LaneKey = tuple[str, int]
"""A source lane: ``(road_id, lane_id)``."""

NO_MARK = RoadMark(0.0, "none", 0.0)


@dataclass(frozen=True)
class Span:
    """A source road driven from station ``s_start`` to ``s_end`` (metres; decreasing when
    driven against s). ``section`` pins the lane section (road legs), -1 = by station."""

    road_id: str
    s_start: float
    s_end: float
    section: int = -1

    @property
    def direction(self) -> int:
        return 1 if self.s_end >= self.s_start else -1

    def s_at(self, p: FloatArray) -> FloatArray:
        return self.s_start + np.asarray(p, float) * (self.s_end - self.s_start)


@dataclass(frozen=True)
class LegLane:
    """One lane of a leg, in carriageway order (median side first).

    ``source`` is the lane it is drawn from (``None``: a bridged lane whose width blends
    from ``bridge_m[0]`` at the leg start to ``bridge_m[1]`` at its end); ``up``/``down``
    the source lane it continues from / into at the leg's ends (for lane identity across
    legs); ``marks_up``/``marks_down`` the marks it carries
    in the first / second half (bridged lanes): ``(median-side border, outer border)``.
    """

    type: str
    source: LaneKey | None
    up: LaneKey | None
    down: LaneKey | None
    bridge_m: tuple[float, float] = (0.0, 0.0)
    marks_up: tuple[RoadMark, RoadMark] | None = None
    marks_down: tuple[RoadMark, RoadMark] | None = None
    section_ids: tuple[int | None, ...] = ()
    """Lane id of a carried lane in each lane section of its source road (lane ids may
    change from section to section; None where the lane does not run)."""


@dataclass(frozen=True)
class Leg:
    """A stretch of carriageway: ``spans`` (one per source road used) and its lanes."""

    kind: Literal["road", "junction"]
    spans: tuple[Span, ...]
    lanes: tuple[LegLane, ...]
    junction_id: str = ""

    @property
    def length_m(self) -> float:
        return max(abs(sp.s_end - sp.s_start) for sp in self.spans)

    def span(self, road_id: str) -> Span:
        return next(sp for sp in self.spans if sp.road_id == road_id)


# ---------------------------------------------------------------------------
# lane sections: the carriageway block, borders
# ---------------------------------------------------------------------------


def is_paved(lane_type: str) -> bool:
    return lane_type in PAVED_LANE_TYPES


def carriageway_lane_ids(section: LaneSection, sign: int) -> list[int]:
    """Lane ids of the carriageway of the side ``sign`` (-1 right, +1 left), median side
    first; empty when that side has no traffic lane."""
    ours = side_lanes(section, sign)
    others = side_lanes(section, -sign)
    first = next((i for i, ln in enumerate(ours) if ln.type in TRAFFIC_LANE_TYPES), None)
    if first is None:
        return []
    lo, hi = first, first
    while lo > 0 and is_paved(ours[lo - 1].type):
        lo -= 1
    while hi + 1 < len(ours) and is_paved(ours[hi + 1].type):
        hi += 1
    across: list[int] = []
    if lo == 0:
        for ln in others:
            if not is_paved(ln.type):
                break
            if ln.type in TRAFFIC_LANE_TYPES:  # an undivided road: the centre line bounds it
                across = []
                break
            across.append(ln.id)
    return [*reversed(across), *(ln.id for ln in ours[lo : hi + 1])]


def _section_border_t(road: Road, k: int, s: FloatArray, border: int) -> FloatArray:
    """Offset t (metres, left positive) of border ``border`` (the far border of lane
    ``border``; 0 = the centre line) evaluated with lane section ``k`` at stations s."""
    section = road.lane_sections[k]
    base = road.lane_offset.value(s)
    if border == 0:
        return base
    ds = s - section.s0
    side = section.left if border > 0 else section.right
    acc = np.zeros_like(s)
    for lane in side[: abs(border)]:
        acc = acc + lane.width.value(ds)
    return base + (acc if border > 0 else -acc)


def _near(lane_id: int) -> int:
    return lane_id - (1 if lane_id > 0 else -1)


def lane_borders_t(
    road: Road, lane_id: int, s: FloatArray, traffic_sign: int, section: int = -1
) -> tuple[FloatArray, FloatArray, int, int]:
    """Median-side and outer border offsets of a source lane at stations ``s`` and the
    border indices they are (a lane across the centre line has its far border inside)."""
    near, far = _near(lane_id), lane_id
    inner, outer = (near, far) if lane_id * traffic_sign > 0 else (far, near)
    if section < 0:
        idx = road.section_index(s)
        t_in = np.full(s.shape, np.nan)
        t_out = np.full(s.shape, np.nan)
        for k in np.unique(idx):
            sel = idx == k
            t_in[sel] = _section_border_t(road, int(k), s[sel], inner)
            t_out[sel] = _section_border_t(road, int(k), s[sel], outer)
        return t_in, t_out, inner, outer
    return (
        _section_border_t(road, section, s, inner),
        _section_border_t(road, section, s, outer),
        inner,
        outer,
    )


def lane_width_at(road: Road, lane_id: int, s: float, section: int) -> float:
    """Width (metres) of a source lane at station ``s`` evaluated in lane section
    ``section``."""
    s_arr = np.array([s])
    t_a = _section_border_t(road, section, s_arr, _near(lane_id))
    t_b = _section_border_t(road, section, s_arr, lane_id)
    return float(abs(t_b[0] - t_a[0]))


def border_marks(road: Road, section: int, border: int) -> tuple[RoadMark, ...]:
    """Road marks painted on border ``border`` of a lane section (0: the centre lane's)."""
    sec = road.lane_sections[section]
    if border == 0:
        return sec.center.road_marks
    try:
        return sec.lane(border).road_marks
    except KeyError:
        return ()


def section_range(road: Road, k: int) -> tuple[float, float]:
    s0 = road.lane_sections[k].s0
    s1 = road.section_end(k)
    return s0, s1


# ---------------------------------------------------------------------------
# legs of a route
# ---------------------------------------------------------------------------


def road_legs(
    network: RoadNetwork,
    traversal: Traversal,
    traffic_side: TrafficSide,
    *,
    keep_m: float | None = None,
    keep: Literal["start", "end"] = "start",
) -> list[Leg]:
    """One leg per lane section of a traversed road, in driving order.

    ``keep_m`` shortens the traversal to its first (``keep="start"``) or last (``"end"``)
    ``keep_m`` metres of travel.
    """
    road = network.road(traversal.road_id)
    d = traversal.direction
    sign = traffic_lane_sign(d, traffic_side)
    order = range(len(road.lane_sections)) if d > 0 else range(len(road.lane_sections) - 1, -1, -1)
    legs = []
    lo, hi = 0.0, road.length  # travel distance kept
    if keep_m is not None:
        lo, hi = (0.0, keep_m) if keep == "start" else (road.length - keep_m, road.length)
    for k in order:
        s0, s1 = section_range(road, k)
        if s1 - s0 < 1e-6:
            continue
        a, b = (s0, s1) if d > 0 else (s1, s0)
        # travel distances of the section's ends, clipped to the kept range
        da, db = (a, b) if d > 0 else (road.length - a, road.length - b)
        da, db = max(da, lo), min(db, hi)
        if db - da < 1e-6:
            continue
        a, b = (da, db) if d > 0 else (road.length - da, road.length - db)
        ids = carriageway_lane_ids(road.lane_sections[k], sign)
        if not ids:
            msg = (
                f"road {road.id}: lane section at s={s0:g} m has no {traffic_side}-hand-"
                f"traffic driving lane in the direction of travel"
            )
            raise InputError(msg)
        sec = road.lane_sections[k]
        n_sec = len(road.lane_sections)
        lanes = tuple(
            LegLane(
                sec.lane(i).type,
                (road.id, i),
                (road.id, i),
                (road.id, i),
                section_ids=tuple(i if j == k else None for j in range(n_sec)),
            )
            for i in ids
        )
        legs.append(Leg("road", (Span(road.id, a, b, k),), lanes))
    return legs


@dataclass(frozen=True)
class GapRule:
    """Which lanes outside a passage's carried lanes a junction leg bridges: lanes of the
    incoming (``up``) and outgoing (``down``) road in ``up_ids`` / ``down_ids``, and on
    which sides of the carried block (``"inner"``, ``"outer"``, ``"middle"``)."""

    up_ids: frozenset[int]
    down_ids: frozenset[int]
    up_gaps: frozenset[str] = frozenset({"inner", "outer", "middle"})
    down_gaps: frozenset[str] = frozenset({"inner", "outer", "middle"})
    leaving: frozenset[int] = frozenset()
    """Lanes of the incoming road that another passage of the junction carries away (a
    ramp's lanes). On the median side they are not bridged: they end at full width where
    the junction starts (the ramp's own road begins there), so the carriageway's
    median-side edge steps there instead of sweeping across the junction."""
    arriving: frozenset[int] = frozenset()
    """Lanes of the outgoing road that another passage feeds (a ramp's lanes); on the
    median side they start at full width where the junction ends."""


def passage_carried(passage: Passage) -> list[tuple[int, str, int]]:
    """``(incoming lane, connecting road, connecting lane)`` carried by a junction passage,
    ordered as the connections list them."""
    return [(f, c.road_id, t) for c in passage.connectors for f, t in c.lane_links]


def _gaps(order: list[int], carried: set[int]) -> dict[str, list[int]]:
    """Lanes of ``order`` (median side first) not in ``carried``, by gap: before the first
    carried lane (``inner``, nearest to the block first), after the last (``outer``,
    nearest first) and between (``middle``)."""
    idx = [i for i, lid in enumerate(order) if lid in carried]
    if not idx:
        return {"inner": [], "outer": [], "middle": []}
    lo, hi = min(idx), max(idx)
    return {
        "inner": [order[i] for i in range(lo - 1, -1, -1)],
        "outer": [order[i] for i in range(hi + 1, len(order))],
        "middle": [order[i] for i in range(lo + 1, hi) if order[i] not in carried],
    }


def _match(
    a: list[tuple[int, str]], b: list[tuple[int, str]]
) -> list[tuple[int | None, int | None]]:
    """Monotone matching of two lane lists (nearest to the carried block first): traffic
    lanes pair with traffic lanes, the others with the others; an unmatched lane is
    returned alone (it tapers)."""
    out: list[tuple[int | None, int | None]] = []
    i = j = 0
    while i < len(a) and j < len(b):
        ta = a[i][1] in TRAFFIC_LANE_TYPES
        tb = b[j][1] in TRAFFIC_LANE_TYPES
        if ta == tb:
            out.append((a[i][0], b[j][0]))
            i += 1
            j += 1
        elif ta:
            out.append((a[i][0], None))
            i += 1
        else:
            out.append((None, b[j][0]))
            j += 1
    out += [(a[k][0], None) for k in range(i, len(a))]
    out += [(None, b[k][0]) for k in range(j, len(b))]
    return out


def junction_leg(
    network: RoadNetwork,
    passage: Passage,
    up_leg: Leg,
    down_leg: Leg,
    traffic_side: TrafficSide,
    rule: GapRule,
) -> Leg:
    """The leg of a default-junction passage between the incoming road's last leg and the
    outgoing road's first leg (carried lanes plus bridged lanes; see the module doc)."""
    up_road = network.road(passage.source.road_id)
    down_road = network.road(passage.target.road_id)
    up_span, down_span = up_leg.spans[0], down_leg.spans[0]
    up_order = [ln.source[1] for ln in up_leg.lanes if ln.source is not None]
    down_order = [ln.source[1] for ln in down_leg.lanes if ln.source is not None]
    up_types = {ln.source[1]: ln.type for ln in up_leg.lanes if ln.source is not None}
    down_types = {ln.source[1]: ln.type for ln in down_leg.lanes if ln.source is not None}

    carried: list[LegLane] = []
    jumpy: list[tuple[int, int | None]] = []
    used_up: set[int] = set()
    used_down: set[int] = set()
    connector_by_id = {c.road_id: c for c in passage.connectors}
    for f, cid, t in passage_carried(passage):
        if f not in up_types:
            continue  # (a lane carried by two connecting roads splits: both are kept)
        conn = network.road(cid)
        c = connector_by_id[cid]
        section_ids = follow_lane(conn, t, c.direction)
        lane = _far_lane(conn, section_ids, c.direction)
        if lane is None:
            continue
        nxt = lane.successor if c.direction > 0 else lane.predecessor
        down_id = nxt if nxt in down_types else None
        if down_id is not None and down_id in used_down:
            down_id = None
        used_up.add(f)
        if down_id is not None:
            used_down.add(down_id)
        if not _continuous(conn, section_ids, c.direction, traffic_side):
            jumpy.append((f, down_id))  # drawn with a sideways jump: bridged instead
            continue
        carried.append(
            LegLane(
                _lane_type(conn, t),
                (cid, t),
                (up_road.id, f),
                (down_road.id, down_id) if down_id is not None else None,
                section_ids=section_ids,
            )
        )
    if not carried:
        msg = (
            f"junction {passage.junction_id}: no connecting road carries a lane of road "
            f"{up_road.id} into road {down_road.id} without a sideways jump"
        )
        raise InputError(msg)
    carried.sort(
        key=lambda ln: (
            up_order.index(ln.up[1]),  # type: ignore[index]
            down_order.index(ln.down[1]) if ln.down is not None else len(down_order),
        )
    )
    kept_up = {ln.up[1] for ln in carried}  # type: ignore[index]
    kept_down = {ln.down[1] for ln in carried if ln.down is not None}
    up_gaps = _gaps(up_order, kept_up)
    down_gaps = _gaps(down_order, kept_down)
    # a lane carried with a jump is bridged between its own two ends, wherever it lies
    rule = replace(
        rule,
        up_ids=rule.up_ids | {f for f, _ in jumpy},
        down_ids=rule.down_ids | {d for _, d in jumpy if d is not None},
    )
    k_up, k_down = up_span.section, down_span.section
    up_sign = traffic_lane_sign(up_span.direction, traffic_side)
    down_sign = traffic_lane_sign(down_span.direction, traffic_side)

    def bridged(a: int | None, b: int | None) -> LegLane:
        w_a = lane_width_at(up_road, a, up_span.s_end, k_up) if a is not None else 0.0
        w_b = lane_width_at(down_road, b, down_span.s_start, k_down) if b is not None else 0.0
        lane_type = up_types[a] if a is not None else down_types[b]  # type: ignore[index]
        if a is not None and b is not None and up_types[a] != down_types[b]:
            lane_type = down_types[b]
        marks_a = marks_b = None
        if a is not None:
            marks_a = _lane_marks_at(up_road, a, k_up, up_span.s_end, up_sign)
        if b is not None:
            marks_b = _lane_marks_at(down_road, b, k_down, down_span.s_start, down_sign)
        return LegLane(
            lane_type,
            None,
            (up_road.id, a) if a is not None else None,
            (down_road.id, b) if b is not None else None,
            (w_a, w_b),
            marks_a,
            marks_b,
        )

    def eligible(order: list[int], ids: frozenset[int], ok: bool) -> list[int]:
        # the run of eligible lanes next to the carried block: a lane beyond one that is
        # not bridged here would be placed where that one is
        out = []
        for i in order if ok else ():
            if i not in ids:
                break
            out.append(i)
        return out

    def side(gap: str) -> list[LegLane]:
        up_ids, down_ids = rule.up_ids, rule.down_ids
        if gap == "inner":  # a ramp's lanes on the median side end / start at full width
            up_ids, down_ids = up_ids - rule.leaving, down_ids - rule.arriving
        a = [(i, up_types[i]) for i in eligible(up_gaps[gap], up_ids, gap in rule.up_gaps)]
        b = [(i, down_types[i]) for i in eligible(down_gaps[gap], down_ids, gap in rule.down_gaps)]
        return [bridged(x, y) for x, y in _match(a, b)]

    inner = side("inner")
    outer = side("outer")
    # carried and middle lanes in carriageway order: by the incoming road's order, a lane
    # only the outgoing road has goes after the carried lane before it there
    up_rank = {ln.up[1]: float(up_order.index(ln.up[1])) for ln in carried}
    down_rank = {ln.down[1]: up_rank[ln.up[1]] for ln in carried if ln.down is not None}

    def rank(lane: LegLane) -> float:
        if lane.up is not None:
            return float(up_order.index(lane.up[1]))
        pos = down_order.index(lane.down[1])  # type: ignore[index]
        before = [down_rank[i] for i in down_order[:pos] if i in down_rank]
        return (max(before) if before else -1.0) + 0.5

    body = sorted([*carried, *side("middle")], key=rank)
    lanes = (*reversed(inner), *body, *outer)
    spans = tuple(
        Span(cid, 0.0, network.road(cid).length)
        if connector_by_id[cid].direction > 0
        else Span(cid, network.road(cid).length, 0.0)
        for cid in dict.fromkeys(ln.source[0] for ln in carried if ln.source is not None)
    )
    return Leg("junction", spans, lanes, passage.junction_id)


def _far_lane(conn: Road, section_ids: tuple[int | None, ...], direction: int) -> Lane | None:
    """The lane of a connecting road (its id per lane section, :func:`follow_lane`) in the
    lane section where a car driving along ``direction`` leaves the road (None: absent)."""
    k_far = len(conn.lane_sections) - 1 if direction > 0 else 0
    far_id = section_ids[k_far]
    return None if far_id is None else _lane_or_none(conn.lane_sections[k_far], far_id)


def passage_landing(network: RoadNetwork, passage: Passage) -> frozenset[int]:
    """Lanes of the target road that a junction passage leads into."""
    if passage.kind == "direct":
        return frozenset(t for _, t in passage.lane_links)
    out = set()
    for c in passage.connectors:
        conn = network.road(c.road_id)
        for _, t in c.lane_links:
            lane = _far_lane(conn, follow_lane(conn, t, c.direction), c.direction)
            nxt = (
                None if lane is None else (lane.successor if c.direction > 0 else lane.predecessor)
            )
            if nxt is not None:
                out.add(nxt)
    return frozenset(out)


def _lane_marks_at(
    road: Road, lane_id: int, section: int, s: float, traffic_sign: int
) -> tuple[RoadMark, RoadMark]:
    """Marks on the median-side and outer border of a source lane at station ``s``."""
    near, far = _near(lane_id), lane_id
    inner, outer = (near, far) if lane_id * traffic_sign > 0 else (far, near)
    return mark_at(road, section, inner, s), mark_at(road, section, outer, s)


MAX_SIDEWAYS_SLOPE = 0.5
"""A lane border moving sideways faster than this (metres per metre along the road) is a
jump of the drawing (a lane inserted with a lane-offset step), not a road."""


def _continuous(
    road: Road, section_ids: tuple[int | None, ...], direction: int, traffic_side: TrafficSide
) -> bool:
    """Whether a lane of ``road`` (its id per lane section) runs without a sideways jump
    of either border over the whole road."""
    s = np.linspace(0.0, road.length, max(3, int(np.ceil(road.length / 0.25)) + 1))
    span = Span(road.id, 0.0, road.length)
    lane = LegLane("", (road.id, 0), None, None, section_ids=section_ids)
    sign = traffic_lane_sign(direction, traffic_side)
    t_in, t_out, _, _ = carried_borders(road, lane, span, s, sign)
    if not (np.all(np.isfinite(t_in)) and np.all(np.isfinite(t_out))):
        return False
    slope = np.abs(np.diff(np.vstack([t_in, t_out]), axis=1)) / np.diff(s)[None, :]
    return bool(np.all(slope <= MAX_SIDEWAYS_SLOPE))


def follow_lane(road: Road, lane_id: int, direction: int) -> tuple[int | None, ...]:
    """Lane id in every lane section of ``road`` of the lane that has id ``lane_id`` in
    the section where a car driving along ``direction`` enters the road (lane links
    between sections; the same id when a lane has none and its type class matches)."""
    n = len(road.lane_sections)
    order = list(range(n)) if direction > 0 else list(range(n - 1, -1, -1))
    ids: list[int | None] = [None] * n
    current: int | None = lane_id
    for pos, k in enumerate(order):
        lane = None if current is None else _lane_or_none(road.lane_sections[k], current)
        if lane is None:
            break
        ids[k] = current
        if pos + 1 == len(order):
            break
        nxt = lane.successor if direction > 0 else lane.predecessor
        if nxt is None:
            same = _lane_or_none(road.lane_sections[order[pos + 1]], current)
            if same is not None and (same.type in TRAFFIC_LANE_TYPES) == (
                lane.type in TRAFFIC_LANE_TYPES
            ):
                nxt = current
        current = nxt
    return tuple(ids)


def _lane_or_none(section: LaneSection, lane_id: int):
    try:
        return section.lane(lane_id)
    except KeyError:
        return None


def _lane_type(road: Road, lane_id: int) -> str:
    for sec in road.lane_sections:
        lane = _lane_or_none(sec, lane_id)
        if lane is not None:
            return lane.type
    return "driving"


# ---------------------------------------------------------------------------
# lane identity across legs
# ---------------------------------------------------------------------------


def next_lane(
    network: RoadNetwork,
    leg: Leg,
    lane: LegLane,
    nxt: Leg,
    passage: Passage | None,
) -> LaneKey | None:
    """The source lane that ``lane`` continues into at the start of leg ``nxt``, in the
    namespace of ``nxt``'s ``up`` keys (None: it ends there).

    A junction leg's lanes name the incoming road's lanes at its start and the outgoing
    road's at its end, so across a junction leg the keys match directly; between road legs
    the lane links (successor/predecessor ids, or a direct junction's lane links) decide.
    """
    if lane.down is None:
        return None
    if leg.kind == "junction" or nxt.kind == "junction":
        return lane.down
    road_id, lane_id = lane.down
    road = network.road(road_id)
    span = leg.spans[0]
    src = _lane_or_none(road.lane_sections[span.section], lane_id)
    if src is None:
        return None
    nxt_span = nxt.spans[0]
    if passage is not None and passage.kind == "direct":
        hits = [t for f, t in passage.lane_links if f == lane_id]
        return (nxt_span.road_id, hits[0]) if hits else None
    link = src.successor if span.direction > 0 else src.predecessor
    if nxt_span.road_id == road_id and link is None:
        same = _lane_or_none(road.lane_sections[nxt_span.section], lane_id)
        back = (
            None if same is None else (same.predecessor if span.direction > 0 else same.successor)
        )
        if (
            same is not None
            and back in (None, lane_id)  # (not when it names another lane as its own)
            and (same.type in TRAFFIC_LANE_TYPES) == (src.type in TRAFFIC_LANE_TYPES)
        ):
            link = lane_id  # no lane link inside a road: the same id continues
    return (nxt_span.road_id, link) if link is not None else None


# ---------------------------------------------------------------------------
# borders of carried lanes
# ---------------------------------------------------------------------------


def carried_borders(road: Road, lane: LegLane, span: Span, s: FloatArray, traffic_sign: int):
    """Median-side and outer border offsets of a carried lane at stations ``s`` (NaN where
    it does not run) and the border index of each per lane section (None: absent)."""
    t_in = np.full(s.shape, np.nan)
    t_out = np.full(s.shape, np.nan)
    b_in: list[int | None] = [None] * len(road.lane_sections)
    b_out: list[int | None] = [None] * len(road.lane_sections)
    idx = road.section_index(s) if span.section < 0 else np.full(s.shape, span.section)
    for k, lane_id in enumerate(lane.section_ids):
        if lane_id is None:
            continue
        sel = idx == k
        ti, to, b_in[k], b_out[k] = lane_borders_t(road, lane_id, s[sel], traffic_sign, k)
        t_in[sel], t_out[sel] = ti, to
    return t_in, t_out, b_in, b_out


def mark_at(road: Road, section: int, border: int, s: float) -> RoadMark:
    """The road mark valid on a border at station ``s`` of lane section ``section``."""
    s0 = road.lane_sections[section].s0
    valid = [m for m in border_marks(road, section, border) if s0 + m.s_offset <= s + 1e-6]
    marks = valid or list(border_marks(road, section, border))
    return marks[-1] if valid else (marks[0] if marks else NO_MARK)


def route_legs(
    network: RoadNetwork,
    route: Route,
    traffic_side: TrafficSide,
    *,
    ramps: Sequence[Passage] = (),
) -> tuple[list[Leg], list[int]]:
    """All legs of a route's mainline in driving order, and for each passage the index of
    its first leg (its junction leg, or the next road's first leg).

    Junction legs bridge every lane the passage does not carry, so the carriageway stays
    whole, except the lanes that ``ramps`` (passages of the same junctions that the truth
    keeps as ramps) carry away from the route or onto it on the median side: those end or
    start at full width at the junction's ends (:class:`GapRule`).
    """
    per_road = [road_legs(network, t, traffic_side) for t in route.traversals]
    legs: list[Leg] = list(per_road[0])
    joints: list[int] = []
    for i, passage in enumerate(route.passages):
        nxt = per_road[i + 1]
        joints.append(len(legs))
        if passage.kind == "junction":
            up_ids = frozenset(ln.source[1] for ln in legs[-1].lanes if ln.source is not None)
            down_ids = frozenset(ln.source[1] for ln in nxt[0].lanes if ln.source is not None)
            here = [p for p in ramps if p.junction_id == passage.junction_id]
            leaving = frozenset(
                f
                for p in here
                if p.source == passage.source and p.target != passage.target
                for f, _, _ in passage_carried(p)
            )
            arriving = frozenset(
                d
                for p in here
                if p.target == passage.target and p.source != passage.source
                for d in passage_landing(network, p)
            )
            rule = GapRule(up_ids, down_ids, leaving=leaving, arriving=arriving)
            legs.append(junction_leg(network, passage, legs[-1], nxt[0], traffic_side, rule))
        legs.extend(nxt)
    return legs, joints


def leg_passages(route: Route, legs: list[Leg]) -> list[Passage | None]:
    """For each leg boundary ``i -> i+1`` the passage crossed there (None: same road)."""
    out: list[Passage | None] = []
    by_pair = {(p.source.road_id, p.target.road_id): p for p in route.passages}
    for a, b in itertools.pairwise(legs):
        ra = a.spans[0].road_id if a.kind == "road" else ""
        rb = b.spans[0].road_id if b.kind == "road" else ""
        out.append(by_pair.get((ra, rb)) if ra and rb and ra != rb else None)
    return out
