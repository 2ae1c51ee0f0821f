"""Dense cross-sections of a leg: its median-side edge, every lane's outer border and
their road marks, sampled along the leg in the direction of travel.

Carried lanes are evaluated on their source road (lane ids per lane section, traffic side
per direction); bridged lanes are stacked on the carried ones (inwards of the first,
outwards of the last) or fill the gap between two carried ones exactly. Samples fall on
every breakpoint of the source roads (geometry pieces, lane offset, widths, elevation),
so fits never smooth across a kink. Positions are mapping-frame metres; ``p`` in [0, 1]
is the relative position along the leg.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from .._errors import InputError
from ..model import Road, RoadMark, RoadNetwork
from .carriageway import (
    NO_MARK,
    FloatArray,
    Leg,
    LegLane,
    Span,
    border_marks,
    carried_borders,
    section_range,
)
from .route import TrafficSide, traffic_lane_sign


@dataclass(frozen=True)
class LegSamples:
    """Dense cross-sections of a leg at relative positions ``p`` (N,).

    ``median`` (N, 3) is the median-side edge, ``borders`` (K, N, 3) the outer border of
    each lane (mapping frame, metres, z the road surface); ``marks[k]`` the road marks of
    lane k's outer border and ``median_marks`` those of the median edge, each as
    ``(p_from, RoadMark)`` sorted by ``p_from``. ``marks`` come from the marks of
    the *up*/*down* source lanes for bridged lanes.
    """

    p: FloatArray
    median: FloatArray
    borders: FloatArray
    marks: tuple[tuple[tuple[float, RoadMark], ...], ...]
    median_marks: tuple[tuple[float, RoadMark], ...]
    exact: tuple[bool, ...] = field(default=())
    """Per lane: its outer border is a source border (False: derived from bridging)."""
    breaks: tuple[int, ...] = ()
    """Indices of interior samples where a source profile or geometry piece starts (a
    curvature jump or kink of some border): fits must not smooth across them."""
    roll: FloatArray | None = None
    """(N,) superelevation (radians, positive = the left side up in the direction of
    travel) of the first carried lane's source road; None where every source is flat."""


def _travel_out(road: Road, s: FloatArray, direction: int, out_sign: int) -> FloatArray:
    """Unit vectors (N, 2) pointing away from the median (to the traffic side)."""
    h = road.heading(s) + (0.0 if direction > 0 else np.pi)
    left = np.column_stack([-np.sin(h), np.cos(h)])
    return out_sign * left


def _marks_on(road: Road, span: Span, borders: list[int | None]) -> list[tuple[float, RoadMark]]:
    """Road marks along a span of the border with index ``borders[k]`` in lane section k,
    as ``(p_from, mark)`` (the first p_from is 0)."""
    length = span.s_end - span.s_start
    items: list[tuple[float, RoadMark]] = []
    for k, border in enumerate(borders):
        if border is None:
            continue
        s0, s1 = section_range(road, k)
        marks = border_marks(road, k, border)
        for i, m in enumerate(marks):
            a = s0 + m.s_offset
            b = s0 + marks[i + 1].s_offset if i + 1 < len(marks) else s1
            pa, pb = sorted(((a - span.s_start) / length, (b - span.s_start) / length))
            if min(pb, 1.0) > max(pa, 0.0) + 1e-9:
                items.append((max(pa, 0.0), m))
    items.sort(key=lambda it: it[0])
    if not items:
        return [(0.0, NO_MARK)]
    return [(0.0 if i == 0 else lo, m) for i, (lo, m) in enumerate(items)]


def _smoothstep(p: FloatArray) -> FloatArray:
    return p * p * (3.0 - 2.0 * p)


def sample_leg(
    network: RoadNetwork, leg: Leg, traffic_side: TrafficSide, *, step_m: float = 0.5
) -> LegSamples:
    """Cross-sections of a leg every ``step_m`` metres (both ends included)."""
    out_sign = -1 if traffic_side == "right" else 1
    # sample exactly at every breakpoint, at least 5 samples between two of them (so a
    # fit between breakpoints is a real cubic fit), about step_m apart otherwise
    cuts = _breakpoints(network, leg)
    bounds = np.concatenate([[0.0], cuts, [1.0]])
    parts = [
        np.linspace(a, b, max(5, int(np.ceil((b - a) * leg.length_m / step_m)) + 1))[:-1]
        for a, b in itertools.pairwise(bounds)
    ]
    p = np.concatenate([*parts, [1.0]])
    n = p.size
    break_idx = tuple(int(i) for i in np.searchsorted(p, cuts))
    K = len(leg.lanes)
    inner_xyz = np.full((K, n, 3), np.nan)
    outer_xyz = np.full((K, n, 3), np.nan)
    out_dir = np.full((K, n, 2), np.nan)
    marks: list[tuple[tuple[float, RoadMark], ...]] = [() for _ in range(K)]
    inner_marks: list[tuple[tuple[float, RoadMark], ...]] = [() for _ in range(K)]
    exact = [False] * K
    roll: FloatArray | None = None
    for k, lane in enumerate(leg.lanes):
        if lane.source is None:
            continue
        road = network.road(lane.source[0])
        span = leg.span(lane.source[0])
        s = span.s_at(p)
        if roll is None and road.superelevation is not None and road.superelevation.pieces:
            # against the source's s the lateral axis is flipped, and the roll with it
            roll = span.direction * road.roll(s)
        sign = traffic_lane_sign(span.direction, traffic_side)
        t_in, t_out, b_in, b_out = carried_borders(road, lane, span, s, sign)
        for arr, t in ((inner_xyz, t_in), (outer_xyz, t_out)):
            arr[k, :, :2] = road.to_xy(s, t)
            arr[k, :, 2] = road.surface_height(s, t)
        out_dir[k] = _travel_out(road, s, span.direction, out_sign)
        marks[k] = tuple(_marks_on(road, span, b_out))
        inner_marks[k] = tuple(_marks_on(road, span, b_in))
        exact[k] = bool(np.all(np.isfinite(t_out)))
    carried = [k for k in range(K) if leg.lanes[k].source is not None]
    if not carried:
        msg = f"leg through junction {leg.junction_id or '-'} has no source lane"
        raise InputError(msg)
    # bridged lanes: stacked inwards from the first carried lane, outwards from the others
    lo = carried[0]
    for k in range(lo - 1, -1, -1):
        w = _bridge_width(leg.lanes[k], p)
        outer_xyz[k] = inner_xyz[k + 1]
        out_dir[k] = out_dir[k + 1]
        inner_xyz[k, :, :2] = outer_xyz[k, :, :2] - out_dir[k] * w[:, None]
        inner_xyz[k, :, 2] = outer_xyz[k, :, 2]
    k = lo + 1
    while k < K:
        if leg.lanes[k].source is not None:
            k += 1
            continue
        run = [k]
        while run[-1] + 1 < K and leg.lanes[run[-1] + 1].source is None:
            run.append(run[-1] + 1)
        nxt = run[-1] + 1
        start = outer_xyz[k - 1]
        w = np.stack([_bridge_width(leg.lanes[j], p) for j in run])
        if nxt < K:  # between two carried lanes: the bridged lanes fill the gap exactly
            total = w.sum(axis=0)
            frac = np.where(total > 1e-9, w / np.where(total > 1e-9, total, 1.0), 1.0 / len(run))
            gap = inner_xyz[nxt] - start
            acc = np.zeros(n)
            for j, f in zip(run, frac, strict=True):
                inner_xyz[j] = start + acc[:, None] * gap
                acc = acc + f
                outer_xyz[j] = start + acc[:, None] * gap
                out_dir[j] = out_dir[k - 1]
        else:  # outside the last carried lane: stacked outwards
            for j, wj in zip(run, w, strict=True):
                inner_xyz[j] = outer_xyz[j - 1]
                out_dir[j] = out_dir[j - 1]
                outer_xyz[j, :, :2] = inner_xyz[j, :, :2] + out_dir[j] * wj[:, None]
                outer_xyz[j, :, 2] = inner_xyz[j, :, 2]
        k = nxt
    for k, lane in enumerate(leg.lanes):
        if lane.source is None:
            marks[k] = _bridge_marks(lane, 1)
            inner_marks[k] = _bridge_marks(lane, 0)
    return LegSamples(
        p, inner_xyz[0], outer_xyz, tuple(marks), inner_marks[0], tuple(exact), break_idx, roll
    )


def _breakpoints(network: RoadNetwork, leg: Leg) -> FloatArray:
    """Relative positions p in (0, 1) where a geometry piece, lane offset, width,
    elevation or superelevation record of a carried lane's road starts."""
    out = []
    for span in leg.spans:
        road = network.road(span.road_id)
        stations = [g.s0 for g in road.geometry]
        stations += [q.s0 for q in road.lane_offset.pieces]
        stations += [q.s0 for q in road.elevation.pieces]
        if road.superelevation is not None:
            stations += [q.s0 for q in road.superelevation.pieces]
        ks = [span.section] if span.section >= 0 else range(len(road.lane_sections))
        for k in ks:
            sec = road.lane_sections[k]
            for lane in (*sec.left, *sec.right):
                stations += [sec.s0 + q.s0 for q in lane.width.pieces]
        length = span.s_end - span.s_start
        ps = (np.asarray(stations, float) - span.s_start) / length
        out.append(ps[(ps > 1e-6) & (ps < 1.0 - 1e-6)])
    if not out:
        return np.zeros(0)
    return np.unique(np.round(np.concatenate(out), 9))


def _bridge_width(lane: LegLane, p: FloatArray) -> FloatArray:
    w0, w1 = lane.bridge_m
    return w0 + (w1 - w0) * _smoothstep(p)


def _bridge_marks(lane: LegLane, which: int) -> tuple[tuple[float, RoadMark], ...]:
    """A bridged lane's marks: the incoming lane's on the first half, the outgoing's on
    the second (``which`` 0: median-side border, 1: outer border)."""
    out: list[tuple[float, RoadMark]] = []
    if lane.marks_up is not None:
        out.append((0.0, lane.marks_up[which]))
    if lane.marks_down is not None:
        out.append((0.5 if out else 0.0, lane.marks_down[which]))
    return tuple(out) or ((0.0, NO_MARK),)
