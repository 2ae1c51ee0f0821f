"""Driving lanes that end where the road narrows: closed by a taper.

The mainline stage ends a lane at a lane-section border where its markings and the outer
edge say it ends. Where the outer edge was not seen over a lane drop, the edge's level
path steps inward at one station and the outermost driving lane ends there at full
width: a dead end for a driver (a simulator's car stops or jumps, ``roadtwin drive`` fails
the route). At an exit the same signature is right: the exit lane ends at the gore and
goes on into the ramp. So the decision is taken after the junctions are built, where an
exit's lane is linked into its ramp: a driving lane that still ends unlinked at a border
inside a road, where the road's width on its side shrinks by that lane, is a lane drop
and closes to zero width before the border; the lanes outside it move in with it.
Where the road does not narrow but only a shoulder covers the lane beyond the border (its
line unseen there, a shoulder as wide as the lane and the shoulder together), the lane
closes into the shoulder outside it, which widens over the same taper: a dead end
otherwise, and the outer edge stays where it was measured.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from .config import TopologyConfig
from .mainline.seal import _width_at, faded_width
from .model import Lane, Road
from .ramps.gores import _traffic_lanes
from .ramps.records import TrafficSide

_SHORTER_TAPERS_M = (40.0, 20.0, 10.0, 5.0)  # tried where the longest would go negative
_MIN_DROP_WIDTH_M = 1.0  # a narrower lane ending is a taper already
_ROOM_SHARE = 0.5  # the side must narrow by at least this share of the lane's width
_SAME_WIDTH_M = 0.3  # a linked outer lane this close to the closed lane's room takes it
_MIN_SEEN_TAPER_M = 10.0  # shortest taper where the edge was seen up to the lane's end (m)


def taper_lane_drops(
    road: Road,
    traffic_side: TrafficSide,
    *,
    max_taper_m: float = TopologyConfig.lane_drop_taper_m,
    edge_seen_until: Callable[[float], float] | None = None,
) -> tuple[Road, list[tuple[float, int]]]:
    """Close the driving lanes of ``road`` that end unlinked at full width where the road
    narrows (see the module docstring).

    Parameters
    ----------
    road
        A mainline road (its lanes linked across its section borders).
    traffic_side
        ``"right"``: the traffic lanes are the right lanes (negative ids), else the left.
    max_taper_m
        Longest taper (metres): the lane closes over this, or its section if shorter, or a
        shorter one where that would make its width negative. 0: nothing is closed.
    edge_seen_until
        The last station of ``road`` (metres) before a given one where the outer edge was
        seen: the taper begins no earlier (the lane was seen at full width there; at least
        ``_MIN_SEEN_TAPER_M`` long). None: no bound (soderleden-s9 with a noisier sensor:
        a lane seen at full width to 25 m before its end was closed over 60 m, 2 m off).

    Returns
    -------
    The road, and ``(station, lane id)`` of every lane closed (road station of the border,
    metres).
    """
    sections = list(road.lane_sections)
    closed: list[tuple[float, int]] = []
    if max_taper_m <= 0.0:
        return road, closed
    tapers = (max_taper_m, *(f for f in _SHORTER_TAPERS_M if f < max_taper_m))
    for k in range(len(sections) - 1):
        a, b = sections[k], sections[k + 1]
        len_a = b.s0 - a.s0
        lanes_a = list(_traffic_lanes(a, traffic_side))
        widths_a = [_width_at(ln, len_a) for ln in lanes_a]
        lanes_b = list(_traffic_lanes(b, traffic_side))
        # the room the side loses at the border: what lanes ending there leave behind
        room = sum(widths_a) - sum(_width_at(ln, 0.0) for ln in lanes_b)
        room_m = len_a
        if edge_seen_until is not None:
            room_m = min(room_m, max(b.s0 - edge_seen_until(b.s0), _MIN_SEEN_TAPER_M))
        fades = tuple(min(f, room_m) for f in tapers)
        for i in reversed(range(len(lanes_a))):
            lane, w = lanes_a[i], widths_a[i]
            if lane.type != "driving" or lane.successor is not None:
                continue
            if w < _MIN_DROP_WIDTH_M:
                continue
            if room >= _ROOM_SHARE * w:
                fixed = faded_width(lane, 0.0, len_a, at_start=False, fades_m=fades)
                if fixed is None:
                    continue
                lanes_a[i] = fixed
                room -= w
                closed.append((float(b.s0), lane.id))
                continue
            into = _into_shoulder(lanes_a, widths_a, i, lanes_b, len_a, fades)
            if into is not None:
                lanes_a[i], lanes_a[i + 1] = into
                closed.append((float(b.s0), lane.id))
        sections[k] = replace(a, **{traffic_side: tuple(lanes_a)})
    if not closed:
        return road, closed
    return replace(road, lane_sections=tuple(sections)), closed


def _into_shoulder(
    lanes_a: list[Lane],
    widths_a: list[float],
    i: int,
    lanes_b: list[Lane],
    len_a: float,
    fades: tuple[float, ...],
) -> tuple[Lane, Lane] | None:
    """Lane ``i`` of a section closed into the non-driving lane outside it, or None.

    The road does not narrow where the lane ends, but beyond the border only non-driving
    lanes cover it (its line was not seen there: a shoulder as wide as the lane and the
    shoulder before): the lane closes over the same fade as that outer lane widens, so the
    outer edge stays where it is (metres, widths at the section's end ``len_a``)."""
    if i + 1 >= len(lanes_a) or lanes_a[i + 1].type == "driving":
        return None
    inner = sum(widths_a[:i])
    lo, hi = inner, inner + widths_a[i]
    t = 0.0
    for ln in lanes_b:
        w_b = _width_at(ln, 0.0)
        overlap = min(hi, t + w_b) - max(lo, t)
        if ln.type == "driving" and overlap > _ROOM_SHARE * widths_a[i]:
            return None
        t += w_b
    outer = lanes_a[i + 1]
    if outer.successor is not None:
        nxt = [ln for ln in lanes_b if ln.id == outer.successor]
        target = widths_a[i + 1] + widths_a[i]
        if not nxt or abs(_width_at(nxt[0], 0.0) - target) > _SAME_WIDTH_M:
            return None  # the outer lane goes on as it is: the lane's room is not its
    for fade in fades:
        closed = faded_width(lanes_a[i], 0.0, len_a, at_start=False, fades_m=(fade,))
        wider = faded_width(
            outer, widths_a[i + 1] + widths_a[i], len_a, at_start=False, fades_m=(fade,)
        )
        if closed is not None and wider is not None:
            return closed, wider
    return None


__all__ = ["taper_lane_drops"]
