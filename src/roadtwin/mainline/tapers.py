"""Where a marking line begins or ends: tapers fitted to the line's approach to its
neighbour, strips closing where a split's paint ends, lines first seen late after an
entry's gore or splitting off a neighbour.

Stations ``s`` and offsets ``d`` are metres in the reference line's frame (``d`` from the
reference edge towards the carriageway); ``dmat`` is the marking matrix (tracks x grid
stations, NaN where a track is not).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from .gores import (
    smoothstep,
    taper_width,
)

FloatArray = NDArray[np.float64]

_RESIDUAL_WIDTH_M = 1.0  # a lane beginning/ending narrower than this is a taper's rest

_LATE_LINE_M = 60.0  # a line first seen this soon after an entry's gore ...
_LATE_LINE_LANE_M = 1.5  # ... this far from its neighbour (a lane, not a taper's tip)
_SPLIT_SAME_M = 0.3  # a neighbour this close to a line's offset was at the line
_SPLIT_MIN_M = 1.0  # ... and this far from it at the line's first station has left it

_STRIP_CLOSE_M = 20.0  # a line this near its neighbour that ends meets it over this (m)
_STRIP_SEEN_M = 50.0  # ... if it ran beside it this long (metres) ...
_STRIP_STEADY_M = 0.3  # ... at a separation varying by no more than this (metres)


def _first_seen(
    dmat: FloatArray, grid: FloatArray
) -> tuple[NDArray[np.bool_], NDArray[np.intp], int]:
    """Where each track of ``dmat`` is seen, its first grid index, and how many grid steps
    ``_LATE_LINE_M`` spans (a late-seen line is first seen that soon after its cause)."""
    seen = np.isfinite(dmat)
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    return seen, np.argmax(seen, axis=1), round(_LATE_LINE_M / max(step, 1e-9))


def _lines_to_gores(
    dmat: FloatArray, grid: FloatArray, d_edge: FloatArray, steps: FloatArray
) -> set[int]:
    """Lines first seen soon after an entry's gore begin at the gore: ``dmat`` (tracks x
    ``grid``, offsets in metres, NaN where absent) is filled in place from the line's
    first offset back to the step. Returns the tracks so filled: their lanes begin at
    the gore at full width, not by a taper (melbourne-921-s2: a taper fitted to a line
    unpainted after the gore opened the acceleration lane 25 m before the gore).

    At an entry's step the outer edge (``d_edge``) moves out and the entry's lanes begin
    at full width; a line between them that the sensor first saw ``_LATE_LINE_M`` or less
    later, already at least ``_LATE_LINE_LANE_M`` from its neighbour, was there from the
    gore. a9-8081560 driven in its third lane: an acceleration lane's outer line was first
    seen 48 m after the gore, and over those metres the lane was a shoulder 6.4 m wide. A
    line that would leave the road (beyond the edge) is left as it is. Not at an exit: the
    line between the through and the exit lane ends at the painted gore's tip, tens of
    metres before the step (extended, two exits were attached 10-24 m late)."""
    n_g = grid.size
    filled: set[int] = set()
    for b in steps:
        i_b = int(np.searchsorted(grid, b))
        if i_b <= 0 or i_b >= n_g - 1:
            continue
        if d_edge[min(i_b + 5, n_g - 1)] <= d_edge[max(i_b - 5, 0)]:
            continue  # the edge moves in: an exit
        seen, first, span = _first_seen(dmat, grid)  # again: earlier steps filled dmat
        late = (seen.sum(axis=1) >= 10) & (first > i_b) & (first - i_b <= span)
        for k in np.flatnonzero(late):
            i0 = int(first[k])
            d_k = float(dmat[k, i0])
            sep = np.abs(np.delete(dmat[:, i0], k) - d_k)
            sep = sep[np.isfinite(sep)]
            if sep.size == 0 or sep.min() < _LATE_LINE_LANE_M:
                continue
            if np.any(d_edge[i_b:i0] - d_k < 0.3):
                continue
            dmat[k, i_b:i0] = d_k
            filled.add(int(k))
    return filled


def _lines_from_splits(dmat: FloatArray, grid: FloatArray) -> None:
    """Lines first seen soon after a neighbouring line left their offset begin where it
    left: ``dmat`` (tracks x ``grid``, offsets in metres, NaN where absent) is filled in
    place back to the station where the neighbour was last within ``_SPLIT_SAME_M``.

    A lane opens between the two: the old line's position is kept by the new lane's inner
    (outer) line, which a noisier sensor may see only later (a broken line, markings
    missed), while the line that moves away is the new lane's other border. Without it the
    lane beside the old position widened to 5 m (melbourne-18-s11+80: the third lane
    opening over 100 m from s = 17 m, its inner line first seen at 61 m). The neighbour
    must have moved at least ``_SPLIT_MIN_M`` away by the line's first station, within
    ``_LATE_LINE_M`` of it, with no line between them."""
    seen, first, span = _first_seen(dmat, grid)
    for k in np.flatnonzero((seen.sum(axis=1) >= 10) & (first > 0)):
        i0 = int(first[k])
        d_k = float(dmat[k, i0])
        lo = max(i0 - span, 0)
        best: tuple[int, int] | None = None
        for j in range(dmat.shape[0]):
            if j == k or not seen[j, lo : i0 + 1].all():
                continue
            gap = np.abs(dmat[j, lo : i0 + 1] - d_k)
            if gap[-1] < _SPLIT_MIN_M:
                continue
            close = np.flatnonzero(gap < _SPLIT_SAME_M)
            if close.size == 0:
                continue
            i_s = lo + int(close[-1])
            between = [
                m
                for m in range(dmat.shape[0])
                if m not in (j, k)
                and seen[m, i_s:i0].any()
                and np.any((dmat[m, i_s:i0] - d_k) * (dmat[j, i_s:i0] - dmat[m, i_s:i0]) > 0.0)
            ]
            if not between and (best is None or i_s > best[0]):
                best = (i_s, j)
        if best is not None:
            dmat[k, best[0] : i0] = d_k


def _taper(
    dmat: FloatArray,
    k: int,
    grid: FloatArray,
    end: str,
    cfg: MainlineConfig,
    fixed: tuple[float, float] | None = None,
    samples: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[float, float, int] | None:
    """Extend track ``k`` at its start/end to where it meets its nearest neighbour.

    The separation from the neighbour is modelled as a smoothstep (cubic) taper whose
    mid-point and slope are measured where the separation passes half the full width.
    ``dmat`` is filled in place over the unobserved part of the taper. Returns
    ``(s_zero, taper_length, neighbour)`` or None if the track starts/ends at full width.
    ``fixed = (s_zero, taper)`` imposes the taper (an inferred marking that opens with
    an observed one) and overwrites the track over it. With the track's raw ``samples``
    (stations, offsets) the taper's zero station and length are refined by a least-squares
    fit of the cubic taper to them (:func:`_fit_taper`).
    """
    n_g = grid.size
    idx = np.nonzero(np.isfinite(dmat[k]))[0]
    i_edge = int(idx[0] if end == "start" else idx[-1])
    others = [j for j in range(dmat.shape[0]) if j != k and np.isfinite(dmat[j, i_edge])]
    if not others:
        return None
    jn = min(others, key=lambda j: abs(dmat[k, i_edge] - dmat[j, i_edge]))
    span = int(300.0 / cfg.grid_step_m)
    sl = (
        slice(i_edge, min(i_edge + span, n_g))
        if end == "start"
        else slice(max(i_edge - span, 0), i_edge + 1)
    )
    both = np.isfinite(dmat[k, sl]) & np.isfinite(dmat[jn, sl])
    gs = grid[sl][both]
    sep = np.abs(dmat[k, sl] - dmat[jn, sl])[both]
    if gs.size < 10:
        return None
    w_full = float(np.percentile(sep, 90))
    # the side of the neighbour the track runs on where it is open (at its very end the
    # two may have met)
    sgn = float(np.sign(np.median((dmat[k, sl] - dmat[jn, sl])[both])))
    if fixed is not None and w_full >= 1.0:
        s_zero, taper = fixed
        if end == "start":
            dmat[k, grid < s_zero] = np.nan
            fill = (grid >= s_zero) & (grid < s_zero + taper)
            x = (grid[fill] - s_zero) / taper
        else:
            dmat[k, grid > s_zero] = np.nan
            fill = (grid > s_zero - taper) & (grid <= s_zero)
            x = (s_zero - grid[fill]) / taper
        ok = fill & np.isfinite(dmat[jn])
        dmat[k, ok] = dmat[jn, ok] + sgn * w_full * smoothstep(x[ok[fill]])
        return s_zero, taper, jn
    sep0 = float(np.abs(dmat[k, i_edge] - dmat[jn, i_edge]))
    if w_full < 1.0 or sep0 > 0.7 * w_full:
        return None
    mid = (sep > 0.3 * w_full) & (sep < 0.7 * w_full)
    if np.count_nonzero(mid) < 3:
        return None
    slope, icpt = np.polyfit(gs[mid], sep[mid], 1)
    if abs(slope) < 1e-4:
        return None
    s50 = (0.5 * w_full - icpt) / slope
    taper = float(min(1.5 * w_full / abs(slope), cfg.lane_taper_max_m))
    s_edge = float(grid[i_edge])
    if end == "start":
        s_zero = float(np.clip(s50 - 0.5 * taper, grid[0], s_edge))
    else:
        s_zero = float(np.clip(s50 + 0.5 * taper, s_edge, grid[-1]))
    if abs(s_edge - s_zero) > taper:
        # the taper would have ended before the line was first seen (begun after it was
        # last seen): the line runs at full width there, it does not open or close (a
        # line seen at a steady separation from 703 m got a taper from the run's start,
        # outside the edge, town06-auto-lane1-s21+80)
        return None
    refined = _fit_taper(samples, dmat[jn], grid, s_zero, taper, w_full, end, cfg)
    if _neighbour_moves(dmat, k, jn, i_edge, end, grid):
        # the lane between them opens (closes) by the neighbour's move, seen: the line
        # keeps its own course, held back to where the two part
        s_zero = refined[0] if refined is not None else s_zero
        taper = refined[1] if refined is not None else taper
        if end == "start":
            dmat[k, grid < s_zero] = np.nan
            dmat[k, (grid >= s_zero) & (grid < s_edge)] = dmat[k, i_edge]
        else:
            dmat[k, grid > s_zero] = np.nan
            dmat[k, (grid > s_edge) & (grid <= s_zero)] = dmat[k, i_edge]
        return s_zero, taper, jn
    if refined is not None:
        # the taper model replaces the smoothed track over the whole taper: the smoother
        # rounds a taper's steep start off
        s_zero, taper = refined
        if end == "start":
            dmat[k, grid < s_zero] = np.nan
            fill = (grid >= s_zero) & (grid < s_zero + taper)
        else:
            dmat[k, grid > s_zero] = np.nan
            fill = (grid > s_zero - taper) & (grid <= s_zero)
    elif end == "start":
        fill = (grid >= s_zero) & (grid < s_edge)
    else:
        fill = (grid > s_edge) & (grid <= s_zero)
    x = (grid[fill] - s_zero) / taper if end == "start" else (s_zero - grid[fill]) / taper
    ok = fill & np.isfinite(dmat[jn])
    dmat[k, ok] = dmat[jn, ok] + sgn * w_full * smoothstep(x[ok[fill]])
    return s_zero, taper, jn


_MOVER_WINDOW_M = 60.0  # the two lines' courses are compared over this much (metres) ...
_MOVER_MIN_M = 1.0  # ... where the neighbour moves by this much at least ...
_MOVER_SHARE = 0.25  # ... and the line by at most this share of that ...
_MOVER_STRAIGHT_M = 0.3  # ... and this much (metres): it runs straight on ...
_SPLIT_BACK_M = 5.0  # ... where the neighbour lay this far before its start (after its end) ...
_SPLIT_NEAR_M = 0.5  # ... this close to it (metres): the two were one line


def _neighbour_moves(
    dmat: FloatArray, k: int, jn: int, i_edge: int, end: str, grid: FloatArray
) -> bool:
    """Whether line ``k``, beginning (``end`` "start") or ending at grid index ``i_edge``
    beside line ``jn``, holds its course there while ``jn`` moves away (towards it): the
    lane between them opens (closes) by ``jn``'s move. An edge line moving out by two
    lanes over 60 m while the broken line beginning where it was ran on straight
    (melbourne-18-s11 with a noisier sensor, seed offset 560): modelled as the straight
    line tapering away from the moving one, it crossed the lane inside it, 3.7 m to 0
    and back within 10 m, and esmini's car on that lane jumped 1.6 m and stuck. Not where
    ``jn`` was seen away from the line's start ``_SPLIT_BACK_M`` before it (from its end
    after it): the two were not one line before a split."""
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    n = max(int(_MOVER_WINDOW_M / step), 2)
    if end == "start":
        window = slice(i_edge, i_edge + n)
    else:
        window = slice(max(i_edge - n + 1, 0), i_edge + 1)
    both = np.flatnonzero(np.isfinite(dmat[k, window]) & np.isfinite(dmat[jn, window]))
    if both.size < 2:
        return False
    first, last = both[0], both[-1]
    move_k = abs(float(dmat[k, window][last] - dmat[k, window][first]))
    move_jn = abs(float(dmat[jn, window][last] - dmat[jn, window][first]))
    if not (move_jn >= _MOVER_MIN_M and move_k <= min(_MOVER_SHARE * move_jn, _MOVER_STRAIGHT_M)):
        return False
    # the neighbour left from where the line is (arrives where it was): one line before
    # the split; a neighbour seen sweeping past the line's start (a ramp's line crossing
    # at an inner entry, melbourne-408-opp-s4 at seed offset 260) is no split. Where the
    # neighbour was not seen there (both first seen mid-fan where lanes are added at the
    # edge, melbourne-18-s11 at seed offset 200) nothing says otherwise
    n_split = max(int(_SPLIT_BACK_M / step), 1)
    i_out = i_edge - n_split if end == "start" else i_edge + n_split
    if not 0 <= i_out < grid.size or not np.isfinite(dmat[jn, i_out]):
        return True
    return abs(float(dmat[jn, i_out] - dmat[k, i_edge])) <= _SPLIT_NEAR_M


_WITH_MEDIAN_SHOULDER_M = (0.3, 2.0)  # the innermost line this far from the median edge ...
_WITH_MEDIAN_REACH_M = 150.0  # ... goes on beside it this far at most ...
_WITH_MEDIAN_MOVE_M = 1.0  # ... where the edge moves by this much towards the next line ...
_WITH_MEDIAN_STEP_M = 20.0  # ... and no step of the edge lies this close to its end


def _lines_with_median_edge(
    dmat: FloatArray, grid: FloatArray, d_median: FloatArray, median_steps: FloatArray
) -> None:
    """The innermost line ending (beginning) a shoulder's width from the median-side edge
    while that edge goes on moving towards the next line out: the line goes on beside the
    edge at that width until it meets the next line, and the lane between them closes
    (opens) there by a taper. A lane dropped beside the median by a taper whose lines were
    unseen but where it began (town06-auto-lane2-s22 with a noisier sensor, seed offset
    260: the edge moved over the 80 m to where it was seen again) ended at full width
    where its line was last seen, the shoulder 4.1 m wide beside it: the drive's car in
    that lane had nowhere to go. ``dmat`` (tracks x ``grid``, metres towards the
    carriageway, NaN where a track is absent) is filled in place; ``d_median`` (on
    ``grid``) is the median-side edge with its moves, ``median_steps`` its steps and the
    gores its moves begin at (metres)."""
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    reach = int(_WITH_MEDIAN_REACH_M / step)
    n_g = grid.size
    for k in range(dmat.shape[0]):
        for end in ("end", "start"):
            idx = np.flatnonzero(np.isfinite(dmat[k]))
            if idx.size < 2:
                break
            i_edge = int(idx[-1] if end == "end" else idx[0])
            if i_edge in (0, n_g - 1):
                continue
            if (
                median_steps.size
                and np.min(np.abs(median_steps - grid[i_edge])) < _WITH_MEDIAN_STEP_M
            ):
                continue
            d_k = float(dmat[k, i_edge])
            width = d_k - float(d_median[i_edge])
            if not _WITH_MEDIAN_SHOULDER_M[0] < width <= _WITH_MEDIAN_SHOULDER_M[1]:
                continue
            at = dmat[:, i_edge]
            with np.errstate(invalid="ignore"):
                if np.any((at > d_median[i_edge]) & (at < d_k)):
                    continue  # not the innermost line
                outward = np.flatnonzero(np.isfinite(at) & (at > d_k + 1.0))
            if not outward.size:
                continue
            jn = int(outward[np.argmin(at[outward])])
            far = (
                np.arange(i_edge + 1, min(i_edge + 1 + reach, n_g))
                if end == "end"
                else np.arange(i_edge - 1, max(i_edge - 1 - reach, -1), -1)
            )
            line = d_median[far] + width
            meets = np.flatnonzero(~np.isfinite(dmat[jn, far]) | (line >= dmat[jn, far] - 0.1))
            if not meets.size or not np.isfinite(dmat[jn, far[meets[0]]]) or meets[0] < 2:
                continue
            part = far[: meets[0] + 1]
            if abs(float(d_median[part[-1]] - d_median[i_edge])) < _WITH_MEDIAN_MOVE_M:
                continue
            others = np.delete(dmat[:, part], [k, jn], axis=0)
            with np.errstate(invalid="ignore"):
                if np.any((others > d_median[part]) & (others < dmat[jn, part])):
                    continue  # another line between the edge and the next one
            dmat[k, part] = np.minimum(line[: meets[0] + 1], dmat[jn, part])


def _close_strip(dmat: FloatArray, k: int, grid: FloatArray, end: str) -> bool:
    """Let line ``k``, whose paint starts/ends beside another line closer than a lane's
    rest (``_RESIDUAL_WIDTH_M``), meet that line over ``_STRIP_CLOSE_M`` beyond its end.

    The strip between them is no lane (a shoulder split by a painted line, Town06's
    0.64 + 0.5 m): where the paint stops, the two strips become one shoulder. Left open,
    both strips ended unlinked at the section border, closed to zero width there, and
    every lane outside them stepped 1.15 m towards the median for 40 m
    (town06-auto-lane1-s21). Only a strip of steady width (within ``_STRIP_STEADY_M``
    over the ``_STRIP_SEEN_M`` next to the end) beside a line that runs on past the
    closing: a ramp's line starting near a mainline line at an entry converges with it
    and is no split shoulder (melbourne-921-s9 with a noisier sensor). ``dmat`` is filled
    in place. Returns whether the line met a neighbour."""
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    idx = np.flatnonzero(np.isfinite(dmat[k]))
    i_edge = int(idx[0] if end == "start" else idx[-1])
    n_seen = round(_STRIP_SEEN_M / step)
    n_close = round(_STRIP_CLOSE_M / step)
    if end == "start":
        seen, closing = slice(i_edge, i_edge + n_seen), slice(i_edge - n_close, i_edge)
    else:
        seen, closing = (
            slice(i_edge - n_seen + 1, i_edge + 1),
            slice(i_edge + 1, i_edge + n_close + 1),
        )
    if seen.start < 0 or closing.start < 0 or max(seen.stop, closing.stop) > grid.size:
        return False
    if not np.all(np.isfinite(dmat[k, seen])):
        return False
    others = [
        j
        for j in range(dmat.shape[0])
        if j != k and np.all(np.isfinite(dmat[j, seen])) and np.all(np.isfinite(dmat[j, closing]))
    ]
    if not others:
        return False
    jn = min(others, key=lambda j: abs(float(dmat[j, i_edge] - dmat[k, i_edge])))
    gaps = dmat[k, seen] - dmat[jn, seen]
    gap = float(dmat[k, i_edge] - dmat[jn, i_edge])
    if abs(gap) >= _RESIDUAL_WIDTH_M or float(np.ptp(gaps)) > _STRIP_STEADY_M:
        return False
    x = (
        np.linspace(0.0, 1.0, n_close + 1)[1:]
        if end == "start"
        else np.linspace(1.0, 0.0, n_close + 1)[:-1]
    )
    dmat[k, closing] = dmat[jn, closing] + gap * smoothstep(x)
    return True


def _fit_taper(
    samples: tuple[FloatArray, FloatArray] | None,
    d_neighbour: FloatArray,
    grid: FloatArray,
    s_zero: float,
    taper: float,
    w_full: float,
    end: str,
    cfg: MainlineConfig,
) -> tuple[float, float] | None:
    """Zero-width station and length (metres) of a cubic lane taper fitted to the raw
    samples of the opening (``end == "start"``) or closing marking, as separations from
    its neighbour (offsets ``d_neighbour`` on ``grid``, NaN where it is absent), starting
    from ``(s_zero, taper)``. None if there are too few samples in the taper or the fit
    leaves the plausible range."""
    from scipy.optimize import least_squares

    if samples is None or samples[0].size < 15:
        return None
    s_raw, d_raw = samples
    lo, hi = (s_zero, s_zero + taper) if end == "start" else (s_zero - taper, s_zero)
    have = np.isfinite(d_neighbour)
    if np.count_nonzero(have) < 2:
        return None
    win = (s_raw >= lo - 0.25 * taper) & (s_raw <= hi + 0.25 * taper)
    s_w = s_raw[win]
    sep = np.abs(d_raw[win] - np.interp(s_w, grid[have], d_neighbour[have]))
    # the taper itself must be seen, not only the full-width lane beside it
    if np.count_nonzero((sep > 0.2 * w_full) & (sep < 0.8 * w_full)) < 10:
        return None

    def residual(p: FloatArray) -> FloatArray:
        return sep - taper_width(s_w, w_full, p[0], max(p[1], 1.0), entry=end == "end")

    res = least_squares(
        residual, np.array([s_zero, taper]), loss="soft_l1", f_scale=0.1, x_scale=10.0
    )
    s_fit, l_fit = float(res.x[0]), float(res.x[1])
    if not (5.0 <= l_fit <= cfg.lane_taper_max_m) or abs(s_fit - s_zero) > taper:
        return None
    return s_fit, l_fit
