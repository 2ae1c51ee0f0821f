"""The median-side edge across a stretch the run does not see, along the line beside it.

Where the median-side edge is unseen over tens of metres (beyond the sensor's reach
across a wide carriageway, or hidden by traffic), the reference-line fit can only bridge
it smoothly between where it is seen. Where the lanes narrow there (the innermost lane
dropped by a taper on the median side, town06-auto-lane1-s21 at 325-362 m), the bridge
began its taper 25 m before the road's and the marking tracks, measured from it, kinked
and swapped: the dropped lane ended 2.7 m wide and its chain led onto the shoulder.

The inner shoulder's line is often seen where the edge is not: a line that keeps its
distance from the edge at both ends of the stretch, and that the car follows from one
end to the other through the stretch, says where the edge went in between
(:func:`edge_along_shoulder_line`). The edge points it adds are points like the others to
the fit; nothing is added where the line is not followed through, where its distance from
the edge differs at the two ends (a lane begins or ends between them), or where it goes
where the bridge would (an occlusion of a straight edge). The fit asks in its second
pass, whose frame follows the edge (the trajectory's first moves with the car's lane
changes, which a straight bridge does not), and in its third over the stretches the
second filled (in a frame that follows the line already, it leaves the bridge no more).

Stations ``s`` are metres along the fitting frame; offsets ``u`` metres towards the
median (the edge's side), in the same frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._common import true_runs

FloatArray = NDArray[np.float64]

__all__ = ["edge_along_shoulder_line"]

GAP_MIN_M = 20.0
"""An unseen stretch of the edge shorter than this (metres) is left to the fit's bridge."""
GAP_MAX_M = 400.0
"""Nor is one longer than this (metres): a line followed that far may be another."""
END_BINS = 3
"""Seen level bins at each end of a stretch that give the edge's level there."""
END_WINDOW_M = 20.0
"""Lane samples this far (metres) outside each end of the stretch give the line's distance
from the edge there."""
SHOULDER_MIN_M = 0.2
"""The shoulder's line lies at least this far (metres) inside the edge ..."""
SHOULDER_MAX_M = 2.0
"""... and at most this far: no lane lies between them."""
LINE_MIN_SAMPLES = 5
"""Lane samples the line needs in an end window."""
LINE_SAME_M = 0.3
"""Lane samples whose distances from the edge lie this close (metres) are one line's."""
KEEPS_DISTANCE_M = 0.3
"""The line's distance from the edge at the two ends of the stretch differs by at most
this (metres): it runs beside the edge through the stretch."""
FOLLOW_M = 0.3
"""A sample this close (metres) to where the line is expected may be the line's ..."""
FOLLOW_SAME_M = 0.2
"""... the line's level in a bin: the samples this close (metres) to the one nearest
where it is expected (a line beside it 0.6 m away, Town06's inner shoulder split painted
over parts of a section only, is not averaged in) ..."""
FOLLOW_SLOPE_MAX = 0.15
"""... the line moving sideways by at most this (m/m; a lane taper is 0.03-0.1) ..."""
FOLLOW_MISS_M = 24.0
"""... and not unseen over more than this (metres; longer than a dash period's gap)."""
ARRIVE_M = 0.3
"""The line followed on beyond the stretch must lie this close (metres) to the distance
from the edge it has there (the median over its bins there)."""
MIN_MOVE_M = 0.3
"""A line whose course (its level per bin, a median of its samples) takes the edge less
than this far (metres) from the straight bridge between the stretch's ends leaves the
edge to the fit: an occlusion alone. (0.5 m first; at 0.3 m 38 more of the 1200 runs
change, the reference nearer the truth's edge on 27 of them, farther on one by 0.03 m.)"""


def edge_along_shoulder_line(
    centres: FloatArray,
    level: FloatArray,
    s_lane: FloatArray,
    u_lane: FloatArray,
    *,
    again: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Edge points in the unseen stretches of the median-side edge, where the inner
    shoulder's line is followed through them.

    Parameters
    ----------
    centres, level
        Station bin centres (metres) and the edge's level path (metres towards the median,
        NaN where unseen; ramps' excursions already left out) of
        :func:`~.edge_levels.edge_level_path`.
    s_lane, u_lane
        Stations and offsets (metres towards the median) of the lane samples, same frame.
    again
        ``(k, 2)`` station intervals (metres) filled by a previous call in a previous
        frame: only the stretches overlapping them are filled, whether or not the line
        leaves the straight bridge (it does not in a frame that follows it already).

    Returns
    -------
    Stations and offsets (metres) of the added edge points: each lane sample of the line
    followed through a stretch, moved out by the line's distance from the edge (linear
    in station between the two ends); and the ``(k, 2)`` station intervals filled.
    Empty where no stretch qualifies.
    """
    empty = (np.zeros(0), np.zeros(0), np.zeros((0, 2)))
    if centres.size < 2 or s_lane.size == 0:
        return empty
    step = float(np.median(np.diff(centres)))
    seen = np.isfinite(level)
    order = np.argsort(s_lane, kind="stable")
    s_sorted, u_sorted = s_lane[order], u_lane[order]
    edge = (centres[seen], level[seen])
    out_s: list[FloatArray] = []
    out_u: list[FloatArray] = []
    spans: list[tuple[float, float]] = []
    for a, b in true_runs(~seen):
        if a < END_BINS or b + END_BINS > level.size:
            continue
        if np.count_nonzero(seen[a - END_BINS : a]) < END_BINS:
            continue
        if np.count_nonzero(seen[b : b + END_BINS]) < END_BINS:
            continue
        lo, hi = centres[a] - 0.5 * step, centres[b - 1] + 0.5 * step
        if not GAP_MIN_M <= hi - lo <= GAP_MAX_M:
            continue
        if again is not None and not np.any((again[:, 0] < hi) & (again[:, 1] > lo)):
            continue
        edge_lo = float(np.mean(level[a - END_BINS : a]))
        edge_hi = float(np.mean(level[b : b + END_BINS]))
        gap_lo = _shoulder_width(s_sorted, u_sorted, lo - END_WINDOW_M, lo, edge)
        gap_hi = _shoulder_width(s_sorted, u_sorted, hi, hi + END_WINDOW_M, edge)
        if gap_lo is None or gap_hi is None or abs(gap_lo - gap_hi) > KEEPS_DISTANCE_M:
            continue
        line_lo = edge_lo - gap_lo
        # followed on into the window beyond the stretch, where the edge is seen again:
        # there it must keep the distance it has there (a taper may end past the gap)
        followed = _follow(s_sorted, u_sorted, lo, hi + END_WINDOW_M, line_lo, step)
        if followed is None:
            continue
        s_taken, u_taken, s_bin, u_bin = followed
        beyond = s_bin > hi
        if np.count_nonzero(beyond) < END_BINS:
            continue
        width_beyond = np.interp(s_bin[beyond], *edge) - u_bin[beyond]
        if abs(float(np.median(width_beyond)) - gap_hi) > ARRIVE_M:
            continue
        on = s_taken <= hi
        s_on, u_on = s_taken[on], u_taken[on]
        s_bin, u_bin = s_bin[~beyond], u_bin[~beyond]
        if s_bin.size == 0:
            continue
        # the line's distance from the edge, and the straight bridge, linear in station
        if again is None:
            course = u_bin + _linear(s_bin, lo, hi, gap_lo, gap_hi)
            bridge = _linear(s_bin, lo, hi, edge_lo, edge_hi)
            if float(np.max(np.abs(course - bridge))) < MIN_MOVE_M:
                continue
        out_s.append(s_on)
        out_u.append(u_on + _linear(s_on, lo, hi, gap_lo, gap_hi))
        spans.append((lo, hi))
    if not out_s:
        return empty
    return np.concatenate(out_s), np.concatenate(out_u), np.asarray(spans, dtype=float)


def _linear(s: FloatArray, lo: float, hi: float, at_lo: float, at_hi: float) -> FloatArray:
    """The value linear in station ``s`` (metres) from ``at_lo`` at ``lo`` to ``at_hi`` at
    ``hi``."""
    return at_lo + (at_hi - at_lo) * (s - lo) / (hi - lo)


def _shoulder_width(
    s_sorted: FloatArray,
    u_sorted: FloatArray,
    lo: float,
    hi: float,
    edge: tuple[FloatArray, FloatArray],
) -> float | None:
    """Distance (metres) from the edge of the line nearest inside it among the lane
    samples with stations in ``[lo, hi)`` (sorted ``s_sorted``), each sample measured
    from the edge's level at its own station (``edge``: the seen bins' centres and
    levels; a frame bending beside the edge moves both alike), or None without one."""
    i, j = np.searchsorted(s_sorted, [lo, hi])
    w = np.interp(s_sorted[i:j], *edge) - u_sorted[i:j]
    w = w[(w >= SHOULDER_MIN_M) & (w <= SHOULDER_MAX_M)]
    if w.size < LINE_MIN_SAMPLES:
        return None
    # the nearest distance with enough samples about it (a double line: its outer one)
    near = np.abs(w[:, None] - w[None, :]) < LINE_SAME_M
    dense = w[np.count_nonzero(near, axis=1) >= LINE_MIN_SAMPLES]
    if dense.size == 0:
        return None
    nearest = float(np.min(dense))
    return float(np.median(w[np.abs(w - nearest) < LINE_SAME_M]))


def _follow(
    s_sorted: FloatArray,
    u_sorted: FloatArray,
    lo: float,
    hi: float,
    start: float,
    step: float,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None:
    """The line at level ``start`` at station ``lo`` followed through ``[lo, hi]`` bin by
    bin (``step`` metres): the stations and offsets of the lane samples taken, and the
    bin centres where it was seen with its level (the samples' median) there; None where
    it is lost (unseen over more than ``FOLLOW_MISS_M``)."""
    i, j = np.searchsorted(s_sorted, [lo, hi])
    s, u = s_sorted[i:j], u_sorted[i:j]
    edges = np.arange(lo, hi + step, step)
    k = np.searchsorted(s, edges)
    take = np.zeros(s.size, dtype=bool)
    s_bin: list[float] = [lo]
    u_bin: list[float] = [start]
    slope = 0.0
    for m in range(edges.size - 1):
        centre = 0.5 * (edges[m] + edges[m + 1])
        expect = u_bin[-1] + slope * (centre - s_bin[-1])
        sel = np.arange(k[m], k[m + 1])
        sel = sel[np.abs(u[sel] - expect) < FOLLOW_M]
        if sel.size:
            nearest = u[sel[np.argmin(np.abs(u[sel] - expect))]]
            sel = sel[np.abs(u[sel] - nearest) < FOLLOW_SAME_M]
        if sel.size == 0:
            if centre - s_bin[-1] > FOLLOW_MISS_M:
                return None
            continue
        take[sel] = True
        s_bin.append(centre)
        u_bin.append(float(np.median(u[sel])))
        slope = _recent_slope(s_bin, u_bin)
    if hi - s_bin[-1] > FOLLOW_MISS_M:
        return None
    return s[take], u[take], np.asarray(s_bin[1:]), np.asarray(u_bin[1:])


SLOPE_BINS = 5
"""The line's slope: fitted to its levels in the last this many bins where it was seen."""


def _recent_slope(s_bin: list[float], u_bin: list[float]) -> float:
    """Slope (m/m) of the last ``SLOPE_BINS`` levels, clipped to ``FOLLOW_SLOPE_MAX``; 0
    with fewer than three."""
    if len(s_bin) < 3:
        return 0.0
    s = np.asarray(s_bin[-SLOPE_BINS:])
    u = np.asarray(u_bin[-SLOPE_BINS:])
    ds = s - s.mean()
    slope = float(np.sum(ds * (u - u.mean())) / max(float(np.sum(ds * ds)), 1e-9))
    return float(np.clip(slope, -FOLLOW_SLOPE_MAX, FOLLOW_SLOPE_MAX))
