"""A lane that opens or closes at the outer edge while the edge is hidden: its taper
fitted to the part of it the sensor saw next to the gap.

Where the outer edge is occluded over a lane's taper, the shoulder width (edge minus
outermost marking) differs by a lane across the gap. Bridged linearly, the lane opens or
closes over the whole gap. When the taper's head or tail was seen (the edge still moving
where it comes out of the gap), a cubic taper fitted to the seen shoulder widths places
it; when nothing of it was seen, the linear bridge stays (with the taper anywhere in the
gap equally likely, it is the least-squares guess).

A line of such a lane first seen inside the gap, part of a lane from the line before it,
is carried back along its slope to where it left that line (:func:`taper_lines_back`), so
the outermost marking the edge is bridged along does not step there as at a gore.

Stations ``s`` and offsets are metres in the reference line's frame (offsets from the
reference edge towards the outer edge).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .gores import smoothstep
from .markings import _Track, typical_lane_width

FloatArray = NDArray[np.float64]

_TAPER_MIN_WIDTH_M = 1.0  # the shoulder changes by at least this across the gap: a lane
_SIDE_M = 60.0  # seen samples this far either side of the gap are fitted (metres)
_STEP_M = 1.0  # taper starts (ends) tried this far apart (metres)
_LENGTHS_M = np.arange(10.0, 251.0, 5.0)  # taper lengths tried (metres)
_RESIDUAL_CAP_M = 0.3  # a sample this far off counts as an outlier (truncated squares)
_GAIN_M2 = 0.05  # a seen taper explains the samples better than a hidden one by this
_LEVEL_SLACK_M = 1.0  # the fitted levels lie this close to the gap ends' widths (metres)
_END_AGREE_M = 0.3  # the taper passes this close to the widths seen at the gap's ends
_MIN_SIDE_SAMPLES = 5  # seen metres of edge needed on each side of the gap
_BIN_M = 1.0  # the samples are reduced to medians per this many metres


def fitted_gap_taper(
    s_seen: FloatArray,
    width_seen: FloatArray,
    gap: tuple[float, float],
    widths: tuple[float, float],
) -> tuple[float, float, float, float] | None:
    """A cubic taper of the shoulder width across an occlusion gap of the outer edge.

    Every taper whose head lies in the ``_SIDE_M`` before the gap or whose tail lies in
    the ``_SIDE_M`` after it (starts or ends ``_STEP_M`` apart, lengths ``_LENGTHS_M``)
    is tried, its two levels solved by least squares and scored by truncated squares
    (``_RESIDUAL_CAP_M``); only tapers that pass within ``_END_AGREE_M`` of the widths
    seen at the gap's ends count. The best is taken when it explains the seen widths
    better by ``_GAIN_M2`` (square metres) than a taper wholly inside the gap (a step
    anywhere in it: to the samples every such taper is the same, and a linear bridge is
    one of them): the seen samples then hold part of the taper.

    Parameters
    ----------
    s_seen, width_seen
        Stations (metres, sorted) and shoulder widths (metres, outer edge minus outermost
        marking) of the edge points seen (:func:`shoulder_widths`).
    gap
        First and last station of the gap (metres).
    widths
        Shoulder width (metres) at the seen station before and after the gap.

    Returns
    -------
    ``(s_start, length, width_before, width_after)`` (metres) of the taper
    ``width_before + (width_after - width_before) * smoothstep((s - s_start) / length)``,
    or None where the widths do not differ by a lane or the taper was not seen.
    """
    lo, hi = gap
    w0, w1 = widths
    if abs(w1 - w0) < _TAPER_MIN_WIDTH_M or hi <= lo:
        return None
    # the points within _SIDE_M of the gap (stations sorted: a slice, not a mask per gap)
    i0 = int(np.searchsorted(s_seen, lo - _SIDE_M, side="left"))
    i1 = int(np.searchsorted(s_seen, hi + _SIDE_M, side="right"))
    s_seen, width_seen = s_seen[i0:i1], width_seen[i0:i1]
    near = (s_seen < lo) | (s_seen > hi)
    # widths beyond both levels are no part of this taper (a ramp's edge at a gore, a
    # guardrail): left out before the levels are solved by least squares
    low, high = min(w0, w1) - _LEVEL_SLACK_M, max(w0, w1) + _LEVEL_SLACK_M
    near &= (width_seen >= low) & (width_seen <= high)
    s, w = _bin_medians(s_seen[near], width_seen[near])
    if min(np.count_nonzero(s < lo), np.count_nonzero(s > hi)) < _MIN_SIDE_SAMPLES:
        return None
    # heads seen before the gap, tails seen after it (the number of tapers tried does not
    # grow with the gap's length)
    offsets = np.arange(_STEP_M, _SIDE_M + 0.5 * _STEP_M, _STEP_M)
    heads, lengths = np.meshgrid(lo - offsets, _LENGTHS_M, indexing="ij")
    tails, lengths_t = np.meshgrid(hi + offsets, _LENGTHS_M, indexing="ij")
    s0 = np.concatenate([heads.ravel(), (tails - lengths_t).ravel()])
    length = np.concatenate([lengths.ravel(), lengths_t.ravel()])
    ramp = smoothstep((s[None, :] - s0[:, None]) / length[:, None])  # (tapers, samples)
    cost, wa, dw = _levels_and_cost(ramp, w)
    plausible = (np.abs(wa - w0) <= _LEVEL_SLACK_M) & (np.abs(wa + dw - w1) <= _LEVEL_SLACK_M)
    plausible &= np.abs(dw) >= _TAPER_MIN_WIDTH_M
    # the taper meets what was seen where the gap begins and ends (a shoulder already
    # widening before the gap is no flat level there: a9-239192816-s11, noisier sensor)
    for s_end, w_end in ((lo, w0), (hi, w1)):
        at_end = wa + dw * smoothstep((s_end - s0) / length)
        plausible &= np.abs(at_end - w_end) <= _END_AGREE_M
    cost = np.where(plausible, cost, np.inf)
    best = int(np.argmin(cost))
    if not np.isfinite(cost[best]):
        return None
    hidden_cost, _, _ = _levels_and_cost((s > hi).astype(float)[None, :], w)
    if float(hidden_cost[0]) - float(cost[best]) < _GAIN_M2:
        return None
    return float(s0[best]), float(length[best]), float(wa[best]), float(wa[best] + dw[best])


def _levels_and_cost(ramp: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per row of ``ramp`` (tapers x samples, 0 -> 1): the levels ``wa`` and ``dw`` of
    ``w = wa + dw * ramp`` by least squares and the truncated squares left (square
    metres; infinite where the levels are undetermined)."""
    n = w.size
    sr, srr = ramp.sum(axis=1), (ramp * ramp).sum(axis=1)
    sw, swr = w.sum(), ramp @ w
    det = n * srr - sr * sr  # normal equations of [1, ramp] x [wa, dw]
    ok = det > 1e-9
    det = np.where(ok, det, 1.0)
    wa = (srr * sw - sr * swr) / det
    dw = (n * swr - sr * sw) / det
    resid = wa[:, None] + dw[:, None] * ramp - w[None, :]
    cost = np.minimum(resid**2, _RESIDUAL_CAP_M**2).sum(axis=1)
    return np.where(ok, cost, np.inf), wa, dw


def _bin_medians(s: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Bin centre and median width per ``_BIN_M`` bin of stations ``s`` (metres): the
    fit's cost does not grow with the point density."""
    if s.size == 0:
        return s, w
    key = np.floor(s / _BIN_M).astype(np.int64)
    order = np.lexsort((w, key))
    key, w_o = key[order], w[order]
    first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    last = np.r_[first[1:], key.size]
    return (key[first] + 0.5) * _BIN_M, w_o[(first + last - 1) // 2]


def taper_widths(taper: tuple[float, float, float, float], s: FloatArray) -> FloatArray:
    """Shoulder width (metres) of a :func:`fitted_gap_taper` result at stations ``s``."""
    s_start, length, wa, wb = taper
    return wa + (wb - wa) * smoothstep((np.asarray(s, dtype=float) - s_start) / length)


def shoulder_widths(
    points: tuple[FloatArray, FloatArray], d_last: FloatArray, grid: FloatArray
) -> tuple[FloatArray, FloatArray] | None:
    """Stations (metres, sorted) and shoulder widths (metres) of the edge points
    (``points``: stations and offsets) against the outermost marking (``d_last``, metres on
    ``grid``), once for every gap of a run (:func:`fitted_gap_taper`); None without a
    marking."""
    have = np.isfinite(d_last)
    if np.count_nonzero(have) < 2:
        return None
    s_pts, d_pts = points
    order = np.argsort(s_pts, kind="stable")
    s_sorted = s_pts[order]
    return s_sorted, d_pts[order] - np.interp(s_sorted, grid[have], d_last[have])


_TAPER_SLOPE = 0.01  # a line first seen moving away from its neighbour this fast (m/m) ...
_TAPER_SHARE = (0.2, 0.8)  # ... this share of a lane from it is a taper's line, seen late
_TAPER_SLOPE_M = 10.0  # its slope is measured over this many metres (metres)


def taper_lines_back(
    d_last: FloatArray, tracks: list[_Track], grid: FloatArray, covered: NDArray[np.bool_]
) -> FloatArray:
    """The outermost marking (``d_last``, metres on ``grid``) with every line that is
    first seen in an occlusion gap of the edge as the outermost one, part of a lane from
    the line before it and moving away from it (a lane's taper line, its start unseen),
    carried back along its slope to where it left that line.

    The outermost marking stepped at such a line's first station and the gap was bridged
    as a gore there: the edge kept its width to that station and jumped by the line's
    separation (oakland-28393854-s7 with a noisier sensor: a lane gained beside the edge
    over 580-670 m, the edge hidden 565-748 m and its line first seen at 626 m, 1.9 m
    out: the edge 1.8 m off over 40 m). The sections later fit the line's taper itself.
    (A line last seen closing in on the next one is continued to where it meets it when
    the tracks are found already: :func:`.markings._continue_to_convergence`.)"""
    out = d_last.copy()
    if grid.size < 2:
        return out
    step = float(grid[1] - grid[0])
    lane = typical_lane_width(tracks, grid)
    n_slope = max(round(_TAPER_SLOPE_M / step), 2)
    for tr in tracks:
        i = min(max(int(np.searchsorted(grid, tr.lo)), 1), grid.size - 2)  # first station
        if covered[i] or not np.isfinite(out[i - 1]):
            continue
        at = grid[i : i + n_slope]
        d_tr = np.interp(at, tr.s, tr.d)
        if abs(float(out[i]) - float(d_tr[0])) > 1e-6:
            continue  # not the outermost line there
        sep = float(d_tr[0] - out[i - 1])
        slope = float(np.polyfit(at, d_tr, 1)[0]) if at.size >= 2 else 0.0
        if not (_TAPER_SHARE[0] * lane <= sep <= _TAPER_SHARE[1] * lane) or slope < _TAPER_SLOPE:
            continue
        k = np.arange(max(i - int(np.ceil(sep / slope / step)), 0), i)
        k = k[~covered[k]]
        out[k] = np.maximum(out[k], float(d_tr[0]) + slope * (grid[k] - grid[i]))
    return out
