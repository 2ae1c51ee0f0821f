"""Measured gores: where a mainline lane ends or begins wide enough to be a ramp's gore,
and the mainline lane/shoulder borders a ramp attaches to.

Stations in metres along the mainline road; lateral offsets ``t`` in metres, left positive.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from .._errors import FitError
from ..model import Lane, LaneSection, Road
from .records import (
    _MIN_GORE_WIDTH_M,
    _MIN_LINK_WIDTH_M,
    FloatArray,
    GoreEvent,
    RampSide,
    RampType,
    TrafficSide,
)

# ---------------------------------------------------------------------------
# measured gores
# ---------------------------------------------------------------------------


def _traffic_lanes(section: LaneSection, traffic_side: TrafficSide) -> tuple[Lane, ...]:
    return section.right if traffic_side == "right" else section.left


def _driving(lanes: tuple[Lane, ...]) -> list[Lane]:
    return [lane for lane in lanes if lane.type == "driving"]


def _gore_side(driving: list[Lane], changed: list[int]) -> tuple[RampSide, int] | None:
    """Side of the driving lanes ``changed`` (ids) among ``driving`` (inner to outer) and
    the driving lane next to them that goes on, or None if they are not at one end."""
    ids = [lane.id for lane in driving]
    k = len(changed)
    if k == 0 or k >= len(ids):
        return None
    if ids[-k:] == changed:
        return "outer", ids[-k - 1]
    if ids[:k] == changed:
        return "inner", ids[k]
    return None


def gore_events(road: Road, *, traffic_side: TrafficSide = "right") -> tuple[GoreEvent, ...]:
    """Gores the LiDAR saw: driving lanes that end or start at full width.

    Scans the mainline's lane sections (DESIGN.md lane layout). Where driving lanes wider
    than 1 m end at a section boundary without a successor, lanes leave through an exit;
    where they start wider than 1 m without a predecessor, lanes enter from a merge (the
    paper's lane-count-change rule). The lanes are the outermost driving lanes (an outer
    gore: deceleration/acceleration lanes) or the innermost (a gore on the median side).
    Tapers (width from or to zero) are not gores.
    """
    out: list[GoreEvent] = []
    sections = road.lane_sections
    for prev, nxt in itertools.pairwise(sections):
        dp = _driving(_traffic_lanes(prev, traffic_side))
        dn = _driving(_traffic_lanes(nxt, traffic_side))
        s_b = nxt.s0
        if len(dp) > len(dn) and dn:
            k = len(dp) - len(dn)
            for ending in (dp[-k:], dp[:k]):  # outer lanes first, then the median side
                widths = [float(lane.width.value(s_b - prev.s0)) for lane in ending]
                linked = any(lane.successor is not None for lane in ending)
                found = _gore_side(dp, [x.id for x in ending])
                if min(widths) > _MIN_GORE_WIDTH_M and found and not linked:
                    side, through = found
                    out.append(GoreEvent(s_b, "exit", tuple(x.id for x in ending), through, side))
                    break
        elif len(dn) > len(dp) and dp:
            k = len(dn) - len(dp)
            for starting in (dn[-k:], dn[:k]):
                widths = [float(lane.width.value(0.0)) for lane in starting]
                linked = any(lane.predecessor is not None for lane in starting)
                found = _gore_side(dn, [x.id for x in starting])
                if min(widths) > _MIN_GORE_WIDTH_M and found and not linked:
                    side, through = found
                    out.append(
                        GoreEvent(s_b, "entry", tuple(x.id for x in starting), through, side)
                    )
                    break
    return _without_broken_links(out)


def gores_from_lane_events(
    lane_events, road: Road, *, traffic_side: TrafficSide = "right", max_taper_m: float = 1.0
) -> tuple[GoreEvent, ...]:
    """Measured gores from the mainline stage's lane events.

    A lane that ends without a taper (``kind="end"``, ``taper_m`` below ``max_taper_m``)
    ends at an exit gore; one that is born without a taper starts at an entry gore.
    Events at the same station and kind are one gore with several lanes, on the outer
    side or on the median side (the innermost driving lanes).

    Parameters
    ----------
    lane_events
        :class:`roadtwin.mainline.LaneEvent` records (``s_m``, ``kind``, ``lane_id``,
        ``taper_m``).
    road
        The mainline road they refer to.
    """
    groups: dict[tuple[float, str], list[int]] = {}
    for ev in lane_events:
        if ev.taper_m > max_taper_m:
            continue
        kind = "exit" if ev.kind == "end" else "entry"
        groups.setdefault((round(float(ev.s_m), 6), kind), []).append(int(ev.lane_id))
    out = []
    for (s, kind), ids in sorted(groups.items()):
        ids = sorted(ids, key=abs)
        s_sec = s - 1e-6 if kind == "exit" else s + 1e-6
        section = road.lane_sections[int(road.section_index(np.array([s_sec]))[0])]
        found = _gore_side(_driving(_traffic_lanes(section, traffic_side)), ids)
        if found is None:
            continue
        side, through = found
        out.append(GoreEvent(s, kind, tuple(ids), through, side))  # type: ignore[arg-type]
    return _without_broken_links(out)


_SAME_STATION_M = 1.0  # an exit and an entry this close (metres) are at one station


def _without_broken_links(events: list[GoreEvent]) -> tuple[GoreEvent, ...]:
    """The gores less the exit-entry pairs at one station (within ``_SAME_STATION_M``) on
    one side: lanes that end there at full width and lanes that begin there at full width
    are one carriageway whose lane links broke (a lane structure the mainline stage could
    not resolve, e.g. both edges hidden at a fork), not a ramp leaving and another joining
    at the same point (melbourne-1019-lane1-s21, noisier sensor: such a pair took the
    entry 90 m past its gore)."""
    drop = {
        i
        for i, a in enumerate(events)
        for b in events
        if a.kind != b.kind
        and a.side == b.side
        and abs(a.station_m - b.station_m) <= _SAME_STATION_M
    }
    return tuple(ev for i, ev in enumerate(events) if i not in drop)


def edge_driving_lane(
    road: Road, s: float, *, traffic_side: TrafficSide = "right", side: RampSide = "outer"
) -> int:
    """Id of the outermost (``side="outer"``) or innermost driving lane of the section
    containing station ``s``."""
    section = road.lane_sections[int(road.section_index(np.array([s]))[0])]
    driving = _driving(_traffic_lanes(section, traffic_side))
    if not driving:
        msg = f"mainline road {road.id}: no driving lane at s={s:.1f} m"
        raise FitError(msg)
    return driving[-1].id if side == "outer" else driving[0].id


def outer_driving_lane(road: Road, s: float, *, traffic_side: TrafficSide = "right") -> int:
    """Id of the outermost driving lane of the section containing station ``s``."""
    return edge_driving_lane(road, s, traffic_side=traffic_side, side="outer")


def _outer_shoulder(
    road: Road,
    station: float,
    ramp_type: RampType,
    source_lane_ids: tuple[int, ...],
    traffic_side: TrafficSide,
) -> int | None:
    """The mainline hard shoulder just outside the gore's ending (exit) / starting (entry)
    lanes, or ``None``."""
    s = station - 1e-6 if ramp_type == "exit" else station + 1e-6
    section = road.lane_sections[int(road.section_index(np.array([s]))[0])]
    lanes_ = _traffic_lanes(section, traffic_side)
    ids = [lane.id for lane in lanes_]
    if not source_lane_ids or source_lane_ids[-1] not in ids:
        return None
    k = ids.index(source_lane_ids[-1])
    if k + 1 < len(lanes_) and lanes_[k + 1].type == "shoulder":
        lane_id = lanes_[k + 1].id
        s_arr = np.array([s])
        w = abs(
            float(road.lane_border_t(s_arr, lane_id)[0])
            - float(road.lane_border_t(s_arr, lane_id + (1 if lane_id < 0 else -1))[0])
        )
        # a shoulder of (near) zero width at the gore is opening/closing there: no link
        return lane_id if math.isfinite(w) and w > _MIN_LINK_WIDTH_M else None
    return None


def _carriageway_border_t(
    road: Road, s: FloatArray, traffic_side: TrafficSide, side: RampSide = "outer"
) -> FloatArray:
    """Lateral offset of the carriageway's border a ramp leaves from on ``side``: the outer
    border of the outermost driving lane, or the median-side edge (the centre lane)."""
    if side == "inner":
        return road.lane_border_t(s, 0)
    return _outer_border_t(road, s, traffic_side)


def _outer_border_t(road: Road, s: FloatArray, traffic_side: TrafficSide) -> FloatArray:
    """Lateral offset of the outer border of the outermost driving lane at each station."""
    out = np.full(s.shape, np.nan)
    idx = road.section_index(s)
    for k in np.unique(idx):
        sel = idx == k
        driving = _driving(_traffic_lanes(road.lane_sections[int(k)], traffic_side))
        if driving:
            out[sel] = road.lane_border_t(s[sel], driving[-1].id)
    return out
