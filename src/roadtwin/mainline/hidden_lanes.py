"""Lanes beyond the sensor's reach and lines the car did not see: where the strip between
the outermost (innermost) observed marking and the road edge is wider than a lane, the
whole lanes of the run's typical width it holds (:func:`_add_hidden_lanes`); where the
lanes shift onto the inner shoulder, that shoulder's line held at its offset.

Stations ``s`` and offsets ``d`` are metres in the reference line's frame (``d`` from the
reference edge towards the carriageway).
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from ..fitting import moving_median
from .markings import _marking_matrix, _Track, typical_lane_width

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


def _runs_of(
    values: NDArray[np.int64], splits: NDArray[np.bool_] | None = None
) -> list[tuple[int, int, int]]:
    """``(start, stop, value)`` of the runs of equal values; a run also ends before each
    index ``i`` with ``splits[i - 1]`` true (``splits`` has ``values.size - 1`` entries)."""
    change = np.diff(values) != 0
    if splits is not None:
        change |= splits
    cut = np.flatnonzero(change) + 1
    starts = np.concatenate([[0], cut])
    stops = np.concatenate([cut, [values.size]])
    return [(int(a), int(b), int(values[a])) for a, b in zip(starts, stops, strict=True)]


def _extreme_jumps(d_extreme: FloatArray, lane_m: float) -> NDArray[np.bool_]:
    """Where the extreme marking (metres, on the grid) moves by half a lane or more from
    one station to the next: another marking has become the extreme one."""
    step = np.abs(np.diff(d_extreme))
    return np.isfinite(step) & (step >= 0.5 * lane_m)


def _two_step_jumps(d_extreme: FloatArray, lane_m: float) -> NDArray[np.bool_]:
    """Where the extreme marking (metres, on the grid) moves by three quarters of a lane
    or more over two grid steps (a jump the moving median split into two halves; a lane
    shift moves it a few tenths of a metre per step): marked at the larger of the two."""
    out = np.zeros(max(d_extreme.size - 1, 0), dtype=bool)
    if d_extreme.size < 3:
        return out
    step = np.abs(np.diff(d_extreme))
    over_two = np.abs(d_extreme[2:] - d_extreme[:-2])
    i = np.flatnonzero(np.isfinite(over_two) & (over_two >= 0.75 * lane_m))
    out[np.where(step[i] >= step[i + 1], i, i + 1)] = True
    return out


def _hidden_lane_count(
    gap: FloatArray,
    lane_m: float,
    min_extra_m: float,
    grid_step_m: float,
    *,
    lanes_only: bool = False,
) -> NDArray[np.int64]:
    """Lanes hidden in a gap between the last observed marking and a road edge (minus its
    shoulder): 0 below one lane plus ``min_extra_m``, else the whole lanes that fit
    (at least one; a 0.4 m tolerance for narrower lanes), from the gap smoothed over 41 m.
    ``lanes_only`` (the gap holds lanes and no shoulder): one more where those would be
    wider than ``_HIDDEN_LANE_MAX_M`` and one more keeps them ``_HIDDEN_LANE_MIN_M`` wide."""
    ok = np.isfinite(gap)
    if not ok.any():
        return np.zeros(gap.size, dtype=np.int64)
    filled = np.interp(np.arange(gap.size), np.flatnonzero(ok), gap[ok])
    smooth = moving_median(filled, window=max(3, round(41.0 / grid_step_m) | 1))
    n = np.maximum(1, np.floor((smooth + 0.4) / lane_m)).astype(np.int64)
    # one lane more where the lanes would be wider than a lane can be and one more still
    # leaves them lane-wide (a 2-lane entry's lanes 3.4 m wide beside lanes of 3.7 m:
    # 6.8 m is no single lane)
    if lanes_only:
        more = (smooth / n > _HIDDEN_LANE_MAX_M) & (smooth / (n + 1) >= _HIDDEN_LANE_MIN_M)
        n = n + more
    n[(smooth < lane_m + min_extra_m) | ~ok] = 0
    if lanes_only:
        # a strip nowhere as wide as a lane is a shoulder, however narrow the run's usual
        # one (melbourne-18: no shoulder over most of the run, a 2.3 m one over 150 m);
        # a lane opening by a taper is narrower only at its ends, and where the lines
        # shift as a whole the strip is wide for a few metres only (unsmoothed: the 41 m
        # median kept town06-auto-s1's shift below 2.5 m and its lanes 3.5 m aside)
        for a, b, on in _runs_of((n > 0).astype(np.int64)):
            if on and float(np.max(filled[a:b])) < _HIDDEN_LANE_MIN_M:
                n[a:b] = 0
    return n


_HIDDEN_LANE_MAX_M = 4.5  # an inferred lane is at most this wide ...
_HIDDEN_LANE_MIN_M = 2.5  # ... and at least this (metres; the lane-width prior)
_HIDDEN_SMOOTH_M = 40.0  # window of the moving median of the extreme markings (metres)
_MIN_UNSEEN_SHOULDER_M = 0.3  # narrowest shoulder left beside lanes inferred out of sight


_SEEN_BEYOND_MIN_M = 10.0  # a wide outer strip that a line seen beyond it confirms: lanes from 10 m
_HANDOVER_M = 5.0  # an inferred line starting this close after an observed one ends ...
_HANDOVER_D_M = 0.5  # ... this close to its offset continues it (metres)


_EDGE_LANE_OVER_M = 30.0  # the strip beside a stretch of hidden lanes, over this long ...
_EDGE_LANE_STEADY_M = 0.5  # ... steady to within this (metres) ...
_EDGE_LANE_TAPER_M = 60.0  # ... and at most this far before (after) it (metres)
_EDGE_LANE_NARROWER_M = 0.3  # the lane goes on where the strip is at most this narrower


def _edge_lane_beside(
    outer_gap: FloatArray, n_out: NDArray[np.int64], a: int, b: int, cfg: MainlineConfig
) -> tuple[float, int, int] | None:
    """The lane the outer edge borders, with no line beyond it, just before grid index
    ``a`` (or just after ``b``) of a stretch of hidden outer lanes: ``(width, a, b)``,
    its width (metres) and the stretch widened back (ahead) over where the strip holds
    that lane, and over the edge's taper that opened (closes) it; None where there is
    none. The strip between the outermost marking and the edge (``outer_gap``) there
    holds no hidden lane (``n_out``), is steady over ``_EDGE_LANE_OVER_M`` within
    ``_EDGE_LANE_TAPER_M`` of the stretch, and is as wide as a lane and no hard shoulder
    (``edge_lane_min_m`` to ``_HIDDEN_LANE_MAX_M``; the lane types read such a strip as
    a driving lane, :func:`~.sections._lane_types`).

    Where a hard shoulder opens beyond such a lane (an added lane, the edge its outer
    border, then the edge moving out by a shoulder's width), the lane goes on: its line
    lies where the edge was. Read afresh, the wider strip was whole lanes of the run's
    typical width beside the run's typical shoulder, and the lane closed to zero width
    to open again by a taper (oakland-28393854-lane1-s21 with a noisier sensor, seed
    offset 320: lanes 0.149 m, the lane count wrong over 50 m). Where the run's typical
    shoulder is 3 m, a 3.6 m strip bordered by the edge was a shoulder in a section that
    the same line, starting only where the shoulder opened, did not split (seed offset
    560: the lane missing over 280 m, lane count 87.4 %)."""
    window = max(1, round(_EDGE_LANE_OVER_M / cfg.grid_step_m))
    # the edge moves out over a shoulder's taper before the stretch begins (after it ends)
    for back in range(0, round(_EDGE_LANE_TAPER_M / cfg.grid_step_m) + 1, max(1, window // 6)):
        for lo, hi in ((a - back - window, a - back), (b + back, b + back + window)):
            if lo < 0 or hi > outer_gap.size or np.any(n_out[lo:hi] > 0):
                continue
            strip = outer_gap[lo:hi]
            if not np.all(np.isfinite(strip)) or np.ptp(strip) >= _EDGE_LANE_STEADY_M:
                continue
            width = float(np.median(strip))
            if not cfg.edge_lane_min_m <= width <= _HIDDEN_LANE_MAX_M:
                continue
            # the line goes on (back) wherever the strip holds that lane
            holds = (outer_gap >= max(width - _EDGE_LANE_NARROWER_M, cfg.edge_lane_min_m)) & (
                n_out == 0
            )
            if hi <= a:
                # the first of the stations up to hi - 1 from which on it holds
                breaks = np.flatnonzero(~holds[: hi - 1])
                a1 = int(breaks[-1]) + 1 if breaks.size else 0
                return width, _taper_end(outer_gap, a1, -1), b
            # the last of the stations from lo on up to which it holds
            breaks = np.flatnonzero(~holds[lo + 1 :])
            b1 = lo + int(breaks[0]) if breaks.size else holds.size - 1
            return width, a, _taper_end(outer_gap, b1, 1) + 1
    return None


_OPENS_FROM_M = 0.5  # a lane opens (closes) by the edge's taper where the strip gets this narrow


def _taper_end(strip: FloatArray, i: int, step: int) -> int:
    """Index where the lane that the edge borders at index ``i`` opens (``step`` -1:
    looking back) or closes (+1: ahead) by the edge's own taper: the strip ``strip``
    (metres) narrows steadily from ``i`` to ``_OPENS_FROM_M`` or less; ``i`` where it does
    not (it was a shoulder before, or another line lies beyond)."""
    # the strip from i on in that direction, up to where it widens or is unknown
    ahead = strip[i::step] if step > 0 else strip[i::-1]
    stops = np.flatnonzero(~np.isfinite(ahead[1:]) | (ahead[1:] > ahead[:-1] + 0.02))
    steady = ahead[1 : 1 + (int(stops[0]) if stops.size else ahead.size - 1)]
    narrow = np.flatnonzero(steady <= _OPENS_FROM_M)
    return i + step * (int(narrow[0]) + 1) if narrow.size else i


_SPLIT_MIN_RUN_M = 30.0  # a lane too wide over at least this long holds a missed line


def _wide_lane_lines(
    tracks: list[_Track], grid: FloatArray, lane_m: float, min_extra_m: float
) -> list[tuple[int, int, FloatArray]]:
    """Lines missed between two adjacent observed markings: ``(start, stop, d)`` on the
    grid where the markings lie at least a lane plus ``min_extra_m`` apart over
    ``_SPLIT_MIN_RUN_M``.

    A lane added by a long taper widens beside the through lane; where the car saw the
    diverging line but not the new straight one (dashes far off, sparse), the two lanes
    were one lane up to twice as wide. Two lanes: the missed line lies a typical lane
    from the steadier of the two markings (the through lane's line; the other one
    diverges); more: evenly spaced.
    """
    if len(tracks) < 2:
        return []
    marks = _marking_matrix(tracks, grid)
    order = np.argsort(np.where(np.isfinite(marks), marks, np.inf), axis=0)
    d_sorted = np.take_along_axis(marks, order, axis=0)
    gaps = np.diff(d_sorted, axis=0)  # (T-1, G), NaN where a pair is incomplete
    wide = np.isfinite(gaps) & (gaps >= lane_m + min_extra_m)
    out: list[tuple[int, int, FloatArray]] = []
    if not wide.any():
        return out
    rows, cols = np.nonzero(wide)
    pairs = sorted(
        {(int(order[r, c]), int(order[r + 1, c])) for r, c in zip(rows, cols, strict=True)}
    )
    min_run = max(2, math.ceil(_SPLIT_MIN_RUN_M / float(np.median(np.diff(grid)))))
    for i, j in pairs:
        adjacent = (wide & (order[:-1] == i) & (order[1:] == j)).any(axis=0).astype(np.int64)
        for a, b, on in _runs_of(adjacent):
            if not on or b - a < min_run:
                continue
            d_i, d_j = marks[i, a:b], marks[j, a:b]
            n = max(2, round(float(np.median(d_j - d_i)) / lane_m))
            if n == 2:
                steady_i = np.ptp(d_i) <= np.ptp(d_j)
                out.append((a, b, d_i + lane_m if steady_i else d_j - lane_m))
            else:
                out.extend((a, b, d_i + (d_j - d_i) * k / n) for k in range(1, n))
    return out


def _held_at_ends(values: FloatArray, window: int) -> FloatArray:
    """``values`` (a moving median over ``window`` columns) held at the first (last) full
    window's value over the half window at each end of the run: there the window is cut
    short, and where the inner markings are seen only a few metres after the run starts
    the median of the few columns there flips between two lines (town06-auto-s2: the
    inferred inner lanes 1.7 m aside over the first 10 m, a step a car drove into)."""
    out = values.copy()
    idx = np.flatnonzero(np.isfinite(values))
    if idx.size <= window:
        return out
    half = window // 2
    first, last = idx[0] + half, idx[-1] - half
    out[idx[0] : first] = values[first]
    out[last + 1 : idx[-1] + 1] = values[last]
    return out


def _add_hidden_lanes(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    d_median: FloatArray,
    cfg: MainlineConfig,
    d_car: FloatArray | None = None,
) -> list[_Track]:
    """Infer unobserved markings where the road beyond the observed ones is lanes wide.

    Markings far from the car are not sampled (the sensor sees about 12 m sideways): on a
    wide road driven in an outer lane, the inner lanes; driven in an inner lane, the
    outer line of a deceleration lane. Where the strip between the outermost marking and
    the outer edge is wider than the run's typical hard shoulder by more than
    ``hidden_lane_min_m``, or the strip between the median-side edge and the innermost
    marking is wider than a lane by more than that margin less 1.4 m (inner shoulders are
    narrow), the whole lanes of the run's typical width (:func:`typical_lane_width`) that
    fit are added: evenly spaced up to the shoulder on the outer side; lane-wide from the
    observed marking on the median side, the rest as the inner shoulder (its edge line
    only where it is at least 0.3 m wide; a narrower rest widens the lanes; held in place
    where the number of lanes changes, :func:`_inner_shoulder_line`). Outer lanes
    are inferred over ``lane_min_track_m`` or more (a shorter wide strip there is a gore;
    from 10 m where the outermost marking jumps outward at the strip's end or before its
    start: a line seen beyond it, the outer line of a lane opening by a taper, lost
    across the taper as it moved out with the edge),
    median-side ones over 30 m or more: between an inner exit's paint tip and its nose
    the exit's lines diverge and are cut as ramp lines, and the lanes run on to the nose
    (56 m on town06-auto-s3, where they had been one lane 8.1 m wide).

    ``d_edge`` and ``d_median`` are the outer and median-side edges (metres from the
    reference edge towards the carriageway) at ``grid``. ``d_car``: the car's offset at
    ``grid`` (same frame). Where the strip beyond the outermost marking is wider than a
    lane over most of the run while the car drove more than two lanes and that strip
    away from the edge, the run's hard shoulder line lay beyond the sensor's reach: the
    strip is taken as whole lanes of the typical width and what remains of it as the
    shoulder (Town06 driven in its inner lane: the line 12.2 m from the car was never
    seen, and the outer lane and the shoulders made one 4.7 m "lane").
    """
    if not tracks:
        return tracks
    lane_m = typical_lane_width(tracks, grid)
    marks = _marking_matrix(tracks, grid)
    has = np.isfinite(marks).any(axis=0)
    d_last = np.where(has, np.nanmax(np.where(has, marks, 0.0), axis=0), np.nan)
    d_first = np.where(has, np.nanmin(np.where(has, marks, 0.0), axis=0), np.nan)
    # the outermost / innermost marking over a few tens of metres: where a marking track
    # starts a few metres late (at the run's start) or stops early, the extreme marking
    # jumps by lanes for those metres, and lanes inferred from it would jump with it
    window = max(3, round(_HIDDEN_SMOOTH_M / cfg.grid_step_m) | 1)
    d_last = _held_at_ends(np.where(has, moving_median(d_last, window=window), np.nan), window)
    d_first = _held_at_ends(np.where(has, moving_median(d_first, window=window), np.nan), window)
    min_run = math.ceil(cfg.lane_min_track_m / cfg.grid_step_m)
    min_run_seen = math.ceil(_SEEN_BEYOND_MIN_M / cfg.grid_step_m)
    out = list(tracks)

    def add(a: int, b: int, d: FloatArray, mark: str) -> None:
        g = grid[a:b]
        # where an observed marking stops being seen (the car changed lanes, an
        # occlusion) and the same line is inferred on from there, or two stretches of
        # inference meet, it is one line: a new track would start a lane there
        for k, tr in enumerate(out):
            if 0.0 < g[0] - tr.hi <= _HANDOVER_M and abs(tr.d[-1] - d[0]) < _HANDOVER_D_M:
                keep = g > tr.hi
                out[k] = replace(
                    tr,
                    hi=float(g[-1]),
                    s=np.concatenate([tr.s, g[keep]]),
                    d=np.concatenate([tr.d, d[keep]]),
                )
                return
            if 0.0 < tr.lo - g[-1] <= _HANDOVER_M and abs(tr.d[0] - d[-1]) < _HANDOVER_D_M:
                keep = g < tr.lo
                out[k] = replace(
                    tr,
                    lo=float(g[0]),
                    s=np.concatenate([g[keep], tr.s]),
                    d=np.concatenate([d[keep], tr.d]),
                )
                return
        out.append(_Track(len(out), float(g[0]), float(g[-1]), g, d, mark, 0, g[:0]))

    # between observed markings: a lane too wide holds a line that was not seen
    for a, b, d in _wide_lane_lines(tracks, grid, lane_m, cfg.split_lane_min_m):
        add(a, b, d, "broken")
        log.info(
            "mainline: an unobserved line inferred in a lane wider than %.1f m at s=%.0f..%.0f m",
            lane_m + cfg.split_lane_min_m,
            grid[a],
            grid[b - 1],
        )
    # outer side: the run's typical hard shoulder stays, whole lanes fill the rest
    outer_gap = d_edge - d_last
    if np.any(np.isfinite(outer_gap)):
        shoulder = float(np.nanmedian(outer_gap))
        if d_car is not None and shoulder >= lane_m + _MIN_UNSEEN_SHOULDER_M:
            car_to_edge = float(np.nanmedian(d_edge - d_car))
            if car_to_edge > 2.0 * lane_m + shoulder:
                lanes_in = math.floor((shoulder - _MIN_UNSEEN_SHOULDER_M) / lane_m)
                shoulder -= lanes_in * lane_m
        n_out = _hidden_lane_count(
            outer_gap - shoulder,
            lane_m,
            cfg.hidden_lane_min_m - lane_m,
            cfg.grid_step_m,
            lanes_only=True,
        )
        # a run ends where the outermost marking is another one (a track ending): lanes
        # inferred from it would jump by a lane there
        jumps = _extreme_jumps(d_last, lane_m)
        for a, b, on in _runs_of((n_out > 0).astype(np.int64), jumps):
            # a shorter wide strip is a gore, unless a line seen beyond it shows the lane:
            # the outer line of a lane that opens, lost across the taper as it moved
            # out with the edge, seen again at its new offset where the strip ends (or
            # seen before a lane's taper where it begins)
            seen_beyond = (b < grid.size and jumps[b - 1] and d_last[b] > d_last[b - 1]) or (
                a > 0 and jumps[a - 1] and d_last[a - 1] > d_last[a]
            )
            shortest = min_run_seen if seen_beyond else min_run
            if not on or b - a < shortest:
                continue
            inner, outer, n = d_last[a:b], d_edge[a:b] - shoulder, n_out[a:b]
            edge_lane = _edge_lane_beside(outer_gap, n_out, a, b, cfg)
            if edge_lane is not None:
                # the lane the edge bordered goes on at its width: its outer line is the
                # first one hidden, from where the edge began to move away from it, and
                # the rest of the strip is read from there
                width, a1, b1 = edge_lane
                line = np.minimum(d_last[a1:b1] + width, d_edge[a1:b1])
                unknown = np.flatnonzero(~np.isfinite(line[: a - a1]))
                first = a1 + (int(unknown[-1]) + 1 if unknown.size else 0)
                add(first, b1, line[first - a1 :], "solid")
                inner = np.minimum(inner + width, d_edge[a:b])
                n = np.maximum(n - 1, 0)
            if n.max() > 0:
                for a2, b2, line, mark in _outer_hidden_lines(
                    inner, outer, n, shortest, cfg.grid_step_m
                ):
                    add(a + a2, a + b2, line, mark)
            log.info(
                "mainline: up to %d unobserved outer lane(s) inferred at s=%.0f..%.0f m",
                int(n.max()),
                grid[a],
                grid[b - 1],
            )
    # median side: lanes of the typical width from the innermost marking, the rest is
    # the inner shoulder
    inner_gap = d_first - d_median
    n_in = _hidden_lane_count(inner_gap, lane_m, cfg.hidden_lane_min_m - 1.4, cfg.grid_step_m)
    min_run_in = math.ceil(_SPLIT_MIN_RUN_M / cfg.grid_step_m)
    # a run also ends where the median-side edge steps (a gore on the median side): the
    # lanes beside it begin or end there at full width; and where the innermost marking
    # is another one, also when the smoothing spread the jump over two grid steps
    median_steps = np.abs(np.diff(d_median)) >= 0.5 * lane_m
    splits = _extreme_jumps(d_first, lane_m) | _two_step_jumps(d_first, lane_m) | median_steps
    for a, b, on in _runs_of((n_in > 0).astype(np.int64), splits):
        if not on or b - a < min_run_in:
            continue
        shoulder_m = float(np.median(d_first[a:b] - d_median[a:b] - n_in[a:b] * lane_m))
        a0, b0 = a, b
        a, b, held = _shift_onto_shoulder(
            inner_gap, n_in == 0, a, b, splits, cfg.grid_step_m, shoulder_m
        )
        # a line first (last) seen where the lanes shift is the opening (closing) lane's
        # own: the sensor saw the lanes there, nothing is hidden (melbourne-408-opp-s4: two
        # lanes opening one after the other, a shoulder held beside them cut them into
        # tapers that jumped by a metre at a section border)
        if held[0] and _ends_within(tracks, grid[a], grid[a0], start=True):
            a, held = a0, (0, held[1])
        if held[1] and _ends_within(tracks, grid[b0 - 1], grid[b - 1], start=False):
            b, held = b0, (held[0], 0)
        first, median, n = d_first[a:b], d_median[a:b], n_in[a:b].copy()
        n[: held[0]] = 0
        n[n.size - held[1] :] = 0
        if float(np.median(first - median - n * lane_m)) >= 0.3:
            shoulder_line = _inner_shoulder_line(first - n * lane_m, n, cfg.grid_step_m)
            shoulder_line = _hold_shoulder(shoulder_line, median, inner_gap[a:b], held, cfg)
            for k in range(1, int(n.max())):
                line = first - k * lane_m
                # a lane line exists where the lane between it and the shoulder is open
                for a2, b2, inside in _runs_of((line - shoulder_line > 0.05).astype(np.int64)):
                    if inside and b2 - a2 >= min_run_in:
                        add(a + a2, a + b2, line[a2:b2], "broken")
            add(a, b, shoulder_line, "solid")
        else:
            # no room for a shoulder: the lanes share the whole strip
            for a2, b2, n2 in _runs_of(n):
                width = (first[a2:b2] - median[a2:b2]) / n2
                for k in range(1, n2):
                    add(a + a2, a + b2, first[a2:b2] - k * width, "broken")
        log.info(
            "mainline: up to %d unobserved median-side lane(s) inferred at s=%.0f..%.0f m",
            int(n.max()),
            grid[a],
            grid[b - 1],
        )
    return out


_OPEN_MIN_M = 0.2  # an inferred lane opening by a taper starts this wide (metres) ...
_OPEN_RATE_M = 0.1  # ... and widens (closes) by at least this per _OPEN_RATE_WINDOW_M
_OPEN_RATE_WINDOW_M = 10.0
_OPEN_SLACK_M = 0.5  # the outermost of the lanes there is at most this wider than the others


def _outer_hidden_lines(
    inner: FloatArray, outer: FloatArray, n: NDArray[np.int64], min_run: int, step_m: float
) -> list[tuple[int, int, FloatArray, str]]:
    """The lines of the hidden outer lanes of one stretch, the shoulder's line included:
    ``(start, stop, line, mark)`` on the stretch's grid, one per track.

    ``inner`` is the outermost observed marking, ``outer`` the shoulder's line and ``n``
    the whole lanes between them (``step_m``: the grid step; all metres). Where ``n`` is
    the same all along, the lanes share the strip evenly. Where it changes, a lane opens
    or closes beside the through lanes (an exit's deceleration lane, an entry's
    acceleration lane): the through lanes keep their width (the strip's share per lane
    where only the ``n.min()`` lanes open all along are), and their lines ``k`` such
    widths out run where the lane beyond is open, and on through the taper while that lane
    still narrows by at least ``_OPEN_RATE_M`` per ``_OPEN_RATE_WINDOW_M`` and is wider
    than ``_OPEN_MIN_M``.
    Where it is closed, the shoulder's line is that line's track: the shoulder's line of
    the open stretch is a new track that diverges from it (a taper, :mod:`.sections`).
    Split evenly instead, one lane 3.5 m wide grew to 6.6 m through an exit's taper on
    town06-auto-lane1-s21 and became two lanes at a section border, linked to neither:
    esmini found no lane path to the road's end.
    """
    strip = outer - inner
    n_max = int(n.max())
    if int(n.min()) == n_max:
        lines = [(0, n.size, inner + strip * k / n_max, "broken") for k in range(1, n_max)]
        return [*lines, (0, n.size, outer, "solid")]
    # the through lanes are those open all along: their width where only they are
    n_min = int(n.min())
    width = float(np.median(strip[n == n_min] / n_min))
    window = max(1, round(_OPEN_RATE_WINDOW_M / step_m))
    # open[k - 1]: where the line k widths out is a lane's border (a lane beyond it)
    opened = np.zeros((n_max - 1, n.size), dtype=bool)
    for k in range(1, n_max):
        rest = outer - (inner + k * width)  # the lanes beyond the line
        open_k = n > k
        for a, b, on in _runs_of(open_k.astype(np.int64)):
            if not on:
                continue
            while (
                a > 0
                and rest[a - 1] > _OPEN_MIN_M
                and (
                    a - 1 + window >= rest.size
                    or rest[a - 1 + window] - rest[a - 1] >= _OPEN_RATE_M
                )
            ):
                a -= 1
            while (
                b < rest.size
                and rest[b] > _OPEN_MIN_M
                and (b - window < 0 or rest[b - window] - rest[b] >= _OPEN_RATE_M)
            ):
                b += 1
            open_k[a:b] = True
        opened[k - 1] = open_k
    # lines open from the outside in: the count of open lines from the first
    n_open = np.cumprod(opened, axis=0).sum(axis=0)
    # the shoulder's line stays beside the outermost lane where the edge bulges out (at an
    # exit's gore the edge follows the ramp away): the shoulder takes the bulge up
    shoulder_line = np.minimum(outer, inner + (n_open + 1) * width + _OPEN_SLACK_M)
    out = []
    for j in range(1, n_max + 1):
        line = np.where(j <= n_open, inner + j * width, shoulder_line)
        for a, b, on in _runs_of((j <= n_open + 1).astype(np.int64)):
            if on and b - a >= min_run:
                out.append((a, b, line[a:b], "solid" if np.all(j > n_open[a:b]) else "broken"))
    return out


_SHIFT_RATE_MIN = 0.01  # the innermost marking moves sideways at least this fast ...
_SHIFT_RATE_MAX = 0.15  # ... and no faster (m/m) where the lanes shift onto the shoulder
_SHIFT_RATE_WINDOW_M = 10.0  # ... measured over this (metres)
_HELD_SHOULDER_M = 0.5  # the held line lies this close to the run's inner shoulder (metres)


def _shift_onto_shoulder(
    gap: FloatArray,
    no_lane: NDArray[np.bool_],
    a: int,
    b: int,
    splits: NDArray[np.bool_],
    step_m: float,
    shoulder_m: float,
) -> tuple[int, int, tuple[int, int]]:
    """A median-side run of hidden lanes ``[a, b)`` (grid indices) widened over the
    stretches before and after it where the innermost marking still moves towards the
    median-side edge (``gap``: its offset from that edge, metres): a lane opening (closing)
    there as the lanes shift sideways off (onto) the shoulder. The shoulder's line stays
    where the marking left it; the lane opens from zero width (melbourne-1226-s11: the
    shoulder widened with the shifting marking and became a lane 50 m late, all its lines
    0.3-0.6 m off where it did).

    Only stations without a hidden lane (``no_lane``) are added, and only where the
    marking left (reaches) the run's inner shoulder width ``shoulder_m`` (metres, to within
    ``_HELD_SHOULDER_M``): else the marking where the shift ends is a lane's line, not the
    shoulder's (Town06's wide inner shoulders, whose lane lines were out of reach, with a
    noisier sensor: a lane's line held as the shoulder's, lanes 0.39 -> 0.69 m). Returns
    the new ``a, b`` and how many grid stations were added at each end.
    """
    from scipy.ndimage import uniform_filter1d

    # the rate over _SHIFT_RATE_WINDOW_M: a flat step of the moving median is no end of
    # the shift (melbourne-408-opp-s4: the shoulder held 0.7 m out, mid-way up)
    window = max(1, round(_SHIFT_RATE_WINDOW_M / step_m))
    known = np.isfinite(gap)
    if not known.any():
        return a, b, (0, 0)
    idx = np.arange(gap.size)
    filled = np.interp(idx, idx[known], gap[known])  # a running mean spreads a NaN on
    rate = np.diff(uniform_filter1d(filled, window, mode="nearest")) / step_m
    finite = known[:-1] & known[1:]
    # diff index i joins stations i and i + 1: going back it adds i, going on i + 1
    opening = finite & ~splits & no_lane[:-1] & (rate >= _SHIFT_RATE_MIN)
    opening &= rate <= _SHIFT_RATE_MAX
    closing = finite & ~splits & no_lane[1:] & (-rate >= _SHIFT_RATE_MIN)
    closing &= -rate <= _SHIFT_RATE_MAX
    stop = np.flatnonzero(~opening[: max(a, 0)])
    a_new = int(stop[-1]) + 1 if stop.size else 0
    stop = np.flatnonzero(~closing[b - 1 :])
    b_new = b - 1 + int(stop[0]) + 1 if stop.size else gap.size
    if a_new < a and not abs(gap[a_new] - shoulder_m) <= _HELD_SHOULDER_M:
        a_new = a
    if b_new > b and not abs(gap[b_new - 1] - shoulder_m) <= _HELD_SHOULDER_M:
        b_new = b
    return a_new, b_new, (a - a_new, b_new - b)


def _ends_within(tracks: list[_Track], lo: float, hi: float, *, start: bool) -> bool:
    """Whether an observed track starts (``start``) or ends within ``[lo, hi]`` (metres,
    widened by ``_HANDOVER_M`` each way)."""
    return any(
        tr.n > 0 and lo - _HANDOVER_M <= (tr.lo if start else tr.hi) <= hi + _HANDOVER_M
        for tr in tracks
    )


def _hold_shoulder(
    line: FloatArray,
    median: FloatArray,
    gap: FloatArray,
    held: tuple[int, int],
    cfg: MainlineConfig,
) -> FloatArray:
    """The inner shoulder's line (metres, on a run's grid) held at the marking's offset
    from the median edge where the lanes began to shift (``held``: stations added before
    and after the run by :func:`_shift_onto_shoulder`), over the added stretch and on
    until the lane beside it has its typical width (the line inferred a lane-width inside
    the marking lies inside the held one)."""
    out = line.copy()
    window = max(1, round(_SHOULDER_HOLD_M / cfg.grid_step_m))
    before, after = held
    if before:
        at = median + gap[0]
        out[:before] = at[:before]
        reach = slice(before, min(before + window, out.size))
        out[reach] = np.maximum(out[reach], at[reach])
    if after:
        at = median + gap[-1]
        out[out.size - after :] = at[out.size - after :]
        reach = slice(max(out.size - after - window, 0), out.size - after)
        out[reach] = np.maximum(out[reach], at[reach])
    return out


_SHOULDER_HOLD_M = 120.0  # the inner shoulder's line is held over a change of lane count
# within this window (metres): longer than the 50-100 m over which the lanes shift


def _inner_shoulder_line(
    whole_lanes: FloatArray, n: NDArray[np.int64], step_m: float
) -> FloatArray:
    """The inner shoulder's line (metres, on the grid) from ``whole_lanes``: the innermost
    marking less the ``n`` whole hidden lanes.

    Where the number of lanes stays the same, that is where the line lies. Where it
    changes, the lanes shift sideways onto (off) the shoulder: the marking moves by a lane
    over 50-100 m and ``n`` drops (rises) by one halfway, so the line would jump by a lane
    there and the lane beside it would go on into the shoulder (end at full width). The
    shoulder's line stays where it was instead (the moving median of the line over
    ``_SHOULDER_HOLD_M``), and the lane beside it closes to (opens from) zero width.
    """
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    window = max(3, round(_SHOULDER_HOLD_M / step_m) | 1)
    if whole_lanes.size < window:
        return whole_lanes
    steady = minimum_filter1d(n, window) == maximum_filter1d(n, window)
    return np.where(steady, whole_lanes, moving_median(whole_lanes, window=window))
