"""The outer shoulder's own line where it lies beyond the sensor's reach.

Some roads paint a line on the hard shoulder itself, a fixed distance inside the outer
edge (CARLA Town06: a solid line 0.6 m inside it, the shoulder split in two). Driven in
an inner lane, that line lies beyond the sensor's lateral reach over most of the run and
is seen only where the road narrows or the car moves out; the outermost lane line and the
edge are seen all along. Where the run saw such a line at a steady distance from the edge
over a long stretch, with the outermost lane line a steady distance inside it, it goes on
at that distance wherever the same pattern (lane line and edge that far apart) is seen
and the line's place is out of the sensor's reach: unseen there is not absent
(town06-auto-lane1-s21 and -lane2-s22: the line 0.5 m off wherever it was missing).

Stations are metres along the reference line; offsets ``d`` metres from the reference
edge towards the carriageway (the lanes' frame, :func:`~.lanes.fit_lanes`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ._common import true_runs
from .markings import _marking_matrix, _Track

FloatArray = NDArray[np.float64]

_TO_EDGE_M = (0.25, 1.2)  # a shoulder's line lies this far inside the edge (metres) ...
_STEADY_M = 0.15  # ... steady to within this (interquartile range, metres) ...
_SEEN_MIN_M = 100.0  # ... over this much of the run at least (metres)
_GAP_M = (0.25, 1.5)  # the lane's outer line lies this far inside the shoulder's line ...
_MEDIAN_GAP_M = (0.25, 4.5)  # ... on the median side, also a lane width (metres) ...
_PATTERN_M = 0.25  # ... and this close to where the pattern puts it (metres)
_REACH_PERCENT = 99.0  # the sensor's reach: this percentile of the samples' distance
_REACH_MARGIN_M = 1.0  # a place this close inside the reach would have been seen
_CLEAR_M = 0.3  # no line of the run this close to the inferred one
_JOIN_M = 0.5  # the seen line's end this close to where the pattern puts it goes on


def _reach(s_lane: FloatArray, d_lane: FloatArray, car: tuple[FloatArray, FloatArray]) -> float:
    """The sensor's lateral reach (metres): how far from the car the lane samples lie."""
    away = np.abs(d_lane - np.interp(s_lane, car[0], car[1]))
    return float(np.percentile(away, _REACH_PERCENT)) if away.size else math.inf


def continue_shoulder_line(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    covered: NDArray[np.bool_],
    lane_samples: tuple[FloatArray, FloatArray],
    car: tuple[FloatArray, FloatArray] | None,
) -> list[_Track]:
    """``tracks`` with the outer shoulder's line (see the module) continued from its ends
    over the stretches next to them where it lies out of reach. ``d_edge`` (on ``grid``)
    is the outer edge, ``covered`` where it was seen; ``lane_samples`` and ``car`` the
    samples' and the car's stations and offsets (metres, the lanes' frame)."""
    if car is None or car[0].size < 2 or not tracks:
        return tracks
    return _continued(tracks, grid, np.where(covered, d_edge, np.nan), lane_samples, car, _GAP_M)


def continue_median_shoulder_line(
    tracks: list[_Track],
    grid: FloatArray,
    d_median: FloatArray,
    lane_samples: tuple[FloatArray, FloatArray],
    car: tuple[FloatArray, FloatArray] | None,
) -> list[_Track]:
    """``tracks`` with the inner shoulder's line continued from its ends where it lies out
    of reach: the same as :func:`continue_shoulder_line` on the median side (``d_median``
    the median-side edge on ``grid``, metres in the lanes' frame), where the line next to
    the shoulder's is the innermost lane's, a lane width away or a split shoulder's
    (``_MEDIAN_GAP_M``). Driven in an outer lane of a road widened by an entry, the inner
    shoulder's line, seen before the road widened, lies beyond the sensor's reach; the
    strip from the median edge to the innermost line seen, a lane and a 0.6-0.7 m
    shoulder, is read as one lane or as a lane and a shoulder station by station, as it is
    a little wider or narrower than a lane and 0.6 m (a9-239192816-opp-s12 at seed
    offset 860: the shoulder's line inferred to 1196 m of 1432, then a 4.3 m lane).

    Computed in the mirrored frame (``-d``), where the median edge is the outer one."""
    if car is None or car[0].size < 2 or not tracks:
        return tracks
    mirrored = [_mirrored(tr) for tr in tracks]
    out = _continued(
        mirrored,
        grid,
        -d_median,
        (lane_samples[0], -lane_samples[1]),
        (car[0], -car[1]),
        _MEDIAN_GAP_M,
    )
    if out is mirrored:
        return tracks
    return [tr if o is m else _mirrored(o) for tr, o, m in zip(tracks, out, mirrored, strict=True)]


def _mirrored(tr: _Track) -> _Track:
    """``tr`` with its offsets negated (the median side as the outer one)."""
    return replace(tr, d=-tr.d, d_samples=-tr.d_samples)


def _continued(
    tracks: list[_Track],
    grid: FloatArray,
    seen_edge: FloatArray,
    lane_samples: tuple[FloatArray, FloatArray],
    car: tuple[FloatArray, FloatArray],
    gap_range: tuple[float, float],
) -> list[_Track]:
    """The work of :func:`continue_shoulder_line` with the edge where it was seen
    (``seen_edge``, NaN elsewhere) and the range of the gap between the shoulder's line
    and the next line inside it (metres): ``tracks`` itself where nothing is continued."""
    marks = _marking_matrix(tracks, grid)  # (tracks, grid), NaN where a track is absent
    step = float(grid[1] - grid[0])
    best: tuple[float, int, float, float] | None = None  # seen metres, track, to edge, gap
    for k, tr in enumerate(tracks):
        if tr.n == 0 or tr.mark != "solid":
            continue
        to_edge = seen_edge - marks[k]
        inner = np.where(marks < marks[k] - _CLEAR_M, marks, -np.inf).max(axis=0)
        gap = marks[k] - inner
        on = np.isfinite(to_edge) & np.isfinite(inner)
        on &= (to_edge >= _TO_EDGE_M[0]) & (to_edge <= _TO_EDGE_M[1])
        on &= (gap >= gap_range[0]) & (gap <= gap_range[1])
        seen = np.count_nonzero(on) * step
        if seen < _SEEN_MIN_M:
            continue
        q1, q3 = np.percentile(to_edge[on], [25, 75])
        g1, g3 = np.percentile(gap[on], [25, 75])
        if q3 - q1 > _STEADY_M or g3 - g1 > _STEADY_M:
            continue
        if best is None or seen > best[0]:
            best = (seen, k, float(np.median(to_edge[on])), float(np.median(gap[on])))
    if best is None:
        return tracks
    _, k, to_edge_m, gap_m = best
    line = seen_edge - to_edge_m
    car_d = np.interp(grid, car[0], car[1])
    out_of_reach = np.abs(line - car_d) >= _reach(*lane_samples, car) - _REACH_MARGIN_M
    others = np.delete(marks, k, axis=0)
    with np.errstate(invalid="ignore"):
        clear = ~np.any(np.abs(others - line) < _CLEAR_M, axis=0)
        lane_line = np.any(np.abs(others - (line - gap_m)) < _PATTERN_M, axis=0)
        beyond = ~np.any(others > line, axis=0)
    where = np.isfinite(line) & out_of_reach & clear & lane_line & beyond
    # the seen line goes on from its ends over the stretches next to them
    tr = tracks[k]
    own = np.flatnonzero((grid >= tr.lo) & (grid <= tr.hi))
    if own.size == 0:
        return tracks
    a, b = int(own[0]), int(own[-1]) + 1
    # it goes on only from an end where it is the shoulder's line (the track may be a
    # lane's line there, the road wider than where the pattern was seen: continued, it
    # jumped 4 m out to the shoulder's place over the run's last 2 m, town06-auto-lane2-s22
    # with a noisier sensor, and a lane 7.5 m wide)
    joins_start = own[0] > 0 and abs(float(tr.d[0]) - float(line[own[0] - 1])) <= _JOIN_M
    joins_end = b < grid.size and abs(float(tr.d[-1]) - float(line[b])) <= _JOIN_M
    for lo, hi in true_runs(where):
        if joins_start and lo < own[0] <= hi:
            a = lo  # the stretch that reaches the seen line's start
        if joins_end and lo <= own[-1] + 1 < hi:
            b = hi  # ... and the one that goes on from its end
    if a == own[0] and b == own[-1] + 1:
        return tracks
    before, after = grid[a : own[0]], grid[own[-1] + 1 : b]
    s_new = np.concatenate([before, tr.s, after])
    d_new = np.concatenate([line[a : own[0]], tr.d, line[own[-1] + 1 : b]])
    out = list(tracks)
    out[k] = replace(tr, lo=float(s_new[0]), hi=float(s_new[-1]), s=s_new, d=d_new)
    return out
