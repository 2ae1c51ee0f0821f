"""What is seen at an occlusion gap of the median-side edge that says where a step of
the edge hidden in it lies.

Where the median-side edge goes unseen over a gap with its level changed across it (a
ramp leaving or joining on the median side, :func:`~.edge_levels.edge_steps`), the gap
alone says nothing of where in it the gore is. The lane samples and the edge points next
to it do:

* the edge's own line, seen into the gap, leaves the edge's level for the ramp at the
  gore (:func:`edge_line_departure`);
* lines between the two levels (the lanes that leave or join) run on into the gap as
  long as those lanes are there, and a ramp's among them leaves outward at its gore
  (:func:`lines_held_to`);
* a ramp's edge seen coming in onto the old level right before the gap (an entry) or
  leaving the new one right after it (an exit) puts the nose at that end of the gap
  (:func:`ramp_edge_meets`).

Lines are walked bin by bin (:func:`_walk_line`) from where they were seen next to the
gap. Stations ``s`` are metres along the frame, offsets ``u`` metres away from the
carriageway (the edge points' frame, :func:`~.edge_levels.edge_level_path`).
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = ["edge_line_departure", "lines_held_to", "ramp_edge_meets"]

_LINE_BAND_M = (0.1, 1.5)  # the edge's line lies this far inside the edge (metres)
_LINE_SIDE_M = 20.0  # ... judged over this much next to the gap, seen side
_LINE_BIN_M = 2.0  # the walk's bins (metres along)
_LINE_GATE_M = 0.35  # a sample this near the walk's prediction is the line's
_LINE_LOST_BINS = 7  # this many bins in a row without the line end the walk
_LINE_COURSE_BINS = 15  # the line's course: a straight fit to this many bins ...
_LINE_BEND_BINS = 8  # ... before the last this many ...
_LINE_LEAVES_M = 0.3  # ... the line this far outward of it in 3 bins has left it ...
_LINE_HELD_M = 0.1  # ... its bend starting before the last bin this near it ...
_LINE_BEYOND_M = 1.0  # ... and going on to this far beyond where it was held
_LINES_CLEAR_M = 0.5  # lines this far outward of the edge's inner level lie between levels
_LINES_APART_M = 0.3  # samples this far apart across (metres) belong to different lines
_LINES_SPREAD_M = 0.15  # ... and a line's samples lie this close to a straight course
_LINES_SIDE_M = 60.0  # a line between the levels is judged over this much next to the gap
_LINES_SEEN_BINS = 4  # ... seen in this many bins there at least (a dashed line: 3 m of 12)
_LINES_SEEN_SHARE = 0.25  # ... and in this share of the walk's bins up to where it is held
_LINES_LOST_BINS = 12  # ... lost for this many bins in a row (two dash periods), it ends
_LINES_LEAVE_RATE = 0.03  # ... it leaves it at this angle (m/m) at least ...
_LINES_DRIFT_RATE = 0.02  # ... from a course the frame tilts by this (m/m) at most ...
_LINES_GATE_GROWTH_M = 0.1  # ... its walk's gate grows by this per bin unseen ...
_LINE_GATE_MAX_M = 1.0  # ... up to this (lines lie 3 m apart and more)
_LINES_END_M = 12.0  # a line seen this near a gap's far end ran on across it (a dash period)
_THROUGH_BAND_M = (2.5, 6.0)  # a line that stays: this far inside the edge's inner level ...
_DRIFT_SPAN_BINS = 10  # ... its drift across the gap from bins seen over this many
_WALK_FIT_BINS = 10  # a walked line's slope: fitted to its bins seen over this many ...
_WALK_FIT_SPAN_BINS = 3  # ... spanning this many at least (else the last step's, smoothed)


def _walk_edge_line(
    s: FloatArray, u: FloatArray, gap: tuple[float, float], outer_level: float, *, forward: bool
) -> tuple[FloatArray, float, float, float] | None:
    """The line along the edge walked into the unseen stretch ``gap`` of the edge
    (arguments as :func:`edge_line_departure`): its offset per ``_LINE_BIN_M`` bin from the
    gap's start (``forward``) or end (NaN where not seen, the walk ending where it is lost
    for ``_LINE_LOST_BINS``), the offset it was held at next to the gap, the station the
    walk starts from and its direction (+1 forward, -1 back). None where no line holding
    one offset lies within ``_LINE_BAND_M`` inside the edge next to the gap."""
    direction = 1.0 if forward else -1.0
    start = gap[0] if forward else gap[1]
    along = direction * (s - start)
    band = (u > outer_level - _LINE_BAND_M[1]) & (u < outer_level - _LINE_BAND_M[0])
    side = band & (along > -_LINE_SIDE_M) & (along <= 0.0)
    n_side = int(_LINE_SIDE_M / _LINE_BIN_M)
    if not side.any():
        return None
    b = np.floor(-along[side] / _LINE_BIN_M).astype(np.int64)
    per_bin = np.full(n_side, -np.inf)
    np.maximum.at(per_bin, np.clip(b, 0, n_side - 1), u[side])
    seen = per_bin[np.isfinite(per_bin)]
    if seen.size < n_side // 2 or 1.4826 * float(np.median(np.abs(seen - np.median(seen)))) > 0.1:
        return None
    held = float(np.median(seen))
    return _walk_line(s, u, gap, held, 0.0, forward=forward), held, start, direction


def _walk_line(
    s: FloatArray,
    u: FloatArray,
    gap: tuple[float, float],
    held: float,
    slope: float,
    *,
    forward: bool,
    lost_bins: int = _LINE_LOST_BINS,
    gate_growth: float = 0.0,
) -> FloatArray:
    """A line walked bin by bin into ``gap`` from its start (``forward``) or back from its
    end, from offset ``held`` (metres) with ``slope`` (metres per ``_LINE_BIN_M`` bin) at
    that end: per bin its offset, NaN where not seen; the walk ends where the line is lost
    for ``lost_bins``. A sample within ``_LINE_GATE_M`` of the prediction (which
    follows the line's slope) is the line's; the gate grows by ``gate_growth`` (metres)
    per bin the line went unseen, up to ``_LINE_GATE_MAX_M`` (a dashed line bending away
    lies farther from a straight prediction at its next dash)."""
    direction = 1.0 if forward else -1.0
    start, end = (gap[0], gap[1]) if forward else (gap[1], gap[0])
    along = direction * (s - start)
    n_bins = int(np.ceil(abs(end - start) / _LINE_BIN_M))
    inside = (along > 0.0) & (along <= n_bins * _LINE_BIN_M)
    k_of = np.floor(along[inside] / _LINE_BIN_M).astype(np.int64)
    order = np.argsort(k_of, kind="stable")
    k_sorted, u_sorted = k_of[order], u[inside][order]
    first = np.searchsorted(k_sorted, np.arange(n_bins), side="left")
    last = np.searchsorted(k_sorted, np.arange(n_bins), side="right")
    pred, last_value, last_k = held + slope, held, -1
    track = np.full(n_bins, np.nan)
    for k in range(n_bins):
        cand = u_sorted[first[k] : last[k]]
        gate = min(_LINE_GATE_M + gate_growth * (k - last_k - 1), _LINE_GATE_MAX_M)
        cand = cand[np.abs(cand - pred) < gate]
        if not cand.size:
            if k - last_k >= lost_bins:
                break
            pred += slope
            continue
        value = float(np.median(cand))
        track[k] = value
        recent = np.flatnonzero(np.isfinite(track[: k + 1]))
        recent = recent[recent >= k - _WALK_FIT_BINS]
        if k - recent[0] >= _WALK_FIT_SPAN_BINS:
            # over the dashes seen lately: one dash's samples scatter by centimetres
            # across a metre or two, and a slope from two of them (the last step) sent
            # the prediction off a line bending away (melbourne-408-opp-s9 with a
            # noisier sensor: an inner exit's line lost 25 m into the gap, its step
            # bridged as a taper and the edge 6 m off)
            slope = float(np.polyfit(recent.astype(float), track[recent], 1)[0])
        else:
            slope = 0.5 * slope + 0.5 * (value - last_value) / (k - last_k)
        pred, last_value, last_k = value + slope, value, k
    return track


def edge_line_departure(
    s: FloatArray, u: FloatArray, gap: tuple[float, float], outer_level: float, *, forward: bool
) -> float | None:
    """Station (metres) where the line along the edge leaves the edge's outer level inside
    an unseen stretch ``gap`` of the edge: an exit's (``forward``: walked from the gap's
    start) or an entry's (walked back from its end) gore, where a ramp's line peels off
    (joins). None where no such line is seen next to the gap, it is lost in the gap
    before leaving, or it does not leave outward.

    ``s``, ``u``: lane samples (stations, offsets towards the edge, metres, the edge
    points' frame); ``outer_level``: the edge's level (same offsets) on the wider side
    of the gap. The line is the one nearest the edge within ``_LINE_BAND_M`` inside it
    over the ``_LINE_SIDE_M`` next to the gap; it is walked bin by bin (samples within
    ``_LINE_GATE_M`` of its prediction, which follows its slope). Where it lies more than
    ``_LINE_LEAVES_M`` outward of its course (a straight fit to the ``_LINE_COURSE_BINS``
    bins before the last ``_LINE_BEND_BINS``) over three bins, and goes on to lie
    ``_LINE_BEYOND_M`` outward of where it was held next to the gap, it has left (a line
    that bends back after moving in, an S beside a lane dropped at the edge, has not). The
    departure
    is the start of the bend, fitted as a hinge (:func:`_hinge_start`) within the
    ``_LINE_BEND_BINS`` before the last bin within ``_LINE_HELD_M`` of that course; the
    line must have been seen in half the bins up to there.
    """
    walk = _walk_edge_line(s, u, gap, outer_level, forward=forward)
    if walk is None:
        return None
    track, held, start, direction = walk
    x0 = _departure_bin(track, held)
    return None if x0 is None else float(start + direction * (x0 + 0.5) * _LINE_BIN_M)


_THROUGH_SEEN_SHARE = 0.5  # the edge's line walked through a gap: seen in this share of its bins


def edge_line_through(
    s: FloatArray,
    u: FloatArray,
    gap: tuple[float, float],
    outer_level: float,
    inner_level: float,
    *,
    forward: bool,
) -> bool:
    """Whether the line along the edge (:func:`_walk_edge_line`, arguments as
    :func:`edge_line_departure`) is seen holding its course through the whole unseen
    stretch ``gap``, to within ``_LINES_END_M`` of its far end, in
    ``_THROUGH_SEEN_SHARE`` of its bins, without leaving, while the edge's level on the
    other side (``inner_level``) lies inward of that line by ``_LINES_CLEAR_M`` or more.
    The edge cannot cross its own line: it held its level through the gap, and the step
    lies at the gap's far end (an exit's nose just after it, walked ``forward``; an
    entry's just before it). melbourne-1019-lane1-s21+q860: an inner exit's 4.5 m step
    under a 106 m gap, the inner shoulder's line seen 1 m inside the edge all through it,
    was bridged as a taper over the gap, the edge up to 4.2 m off."""
    walk = _walk_edge_line(s, u, gap, outer_level, forward=forward)
    if walk is None:
        return False
    track, held, _, _ = walk
    if inner_level > held - _LINES_CLEAR_M or _departure_bin(track, held) is not None:
        return False
    tracked = np.flatnonzero(np.isfinite(track))
    if not tracked.size:
        return False
    walked = int(tracked[-1]) + 1  # bins up to the last one the line was seen in
    return (
        walked * _LINE_BIN_M >= gap[1] - gap[0] - _LINES_END_M
        and tracked.size >= _THROUGH_SEEN_SHARE * walked
    )


def _departure_bin(track: FloatArray, held: float) -> float | None:
    """Where (bins of the walk, fractional) a walked line (:func:`_walk_line`, held at
    ``held`` next to the gap) leaves outward, as :func:`edge_line_departure` tells it;
    None where it does not."""
    tracked = np.flatnonzero(np.isfinite(track))
    for i, k in enumerate(tracked):
        # the line's course, straight over the bins before the last _LINE_BEND_BINS (a
        # frame drifting against the line, a bridged edge, tilts it; a ramp's line bends
        # away from it over tens of metres before it is clearly off)
        prev = tracked[
            (tracked >= k - _LINE_BEND_BINS - _LINE_COURSE_BINS) & (tracked < k - _LINE_BEND_BINS)
        ]
        nxt = tracked[i : i + 3]
        if prev.size < _LINE_COURSE_BINS // 3 or nxt.size < 3:
            continue
        coef = np.polyfit(prev.astype(float), track[prev], 1)
        if np.all(track[nxt] - np.polyval(coef, nxt.astype(float)) > _LINE_LEAVES_M):
            if np.max(track[tracked[i:]]) - held < _LINE_BEYOND_M:
                # it bends back after moving in (an S: the edge tapering in with a lane
                # dropped beside it), it does not leave beyond where it was held
                return None
            bend = tracked[(tracked >= k - _LINE_BEND_BINS) & (tracked < k)]
            near = bend[track[bend] - np.polyval(coef, bend.astype(float)) <= _LINE_HELD_M]
            held_to = int(near[-1]) if near.size else int(prev[-1])
            if np.count_nonzero(tracked <= held_to) < 0.5 * (held_to + 1):
                return None  # the line was not seen holding its course up to there
            # the last bin near the course lies metres after the bend's start (a ramp's
            # line leaves on a curve: 0.1 m off 7 m after it on a 250 m radius): the
            # start fitted as a hinge, off the course by c (x - x0)^2 after it
            fit = tracked[(tracked >= held_to - _LINE_BEND_BINS) & (tracked <= nxt[-1])]
            x0 = _hinge_start(fit.astype(float), track[fit] - np.polyval(coef, fit.astype(float)))
            x0 = min(max(x0, held_to - _LINE_BEND_BINS), held_to)
            return x0
    return None


def lines_held_to(
    s: FloatArray,
    u: FloatArray,
    gap: tuple[float, float],
    outer_level: float,
    inner_level: float,
    *,
    forward: bool,
) -> tuple[float, bool] | None:
    """The station (metres) farthest into the unseen stretch ``gap`` of the edge up to
    which a lane line lying between the edge's two levels (``outer_level`` on the wider
    side of the gap, ``inner_level`` on the other; offsets towards the edge, metres) is
    seen going on from where it was seen next to the gap, before it leaves outward
    (:func:`_departure_bin`, or off its straight course, :func:`_off_course_bin`): the
    lanes between the levels are still there, so the edge's step hidden in the gap lies
    beyond it (an exit's, walked from the gap's start, ``forward``) or before it (an
    entry's, walked back from its end). A line is a straight run of samples
    (``_LINES_SPREAD_M``) over the ``_LINES_SIDE_M`` next to the gap, seen in
    ``_LINES_SEEN_BINS`` of its bins, and must be seen in ``_LINES_SEEN_SHARE`` of the
    walk's bins up to where it is held (dashed lines are seen on their dashes only).
    None where no such line is seen in the gap; else the station and whether that line
    left outward there (a ramp's line: its gore is there).

    ``s``, ``u``: lane samples (stations, offsets towards the edge, metres, the edge
    points' frame).
    """
    direction = 1.0 if forward else -1.0
    start = gap[0] if forward else gap[1]
    lines = _lines_beside(
        s, u, gap, inner_level + _LINES_CLEAR_M, outer_level - _LINE_BAND_M[0], forward=forward
    )
    drift: float | None = None
    best: tuple[float, bool] | None = None
    for held, slope in lines:
        track = _walk_lane_line(s, u, gap, held, slope, forward=forward)
        x0 = _departure_bin(track, held)
        if x0 is None:
            x0 = _off_course_bin(track, held, slope)
        if x0 is None and _lost_before_end(track):
            if drift is None:
                drift = _through_drift(s, u, gap, inner_level, forward=forward)
            x0 = _leaving_from_start(track, held, slope, drift)
        tracked = np.flatnonzero(np.isfinite(track))
        if x0 is not None:
            # (none before it: the line left right where the gap begins)
            tracked = tracked[tracked <= x0]
        elif not tracked.size:
            continue
        if tracked.size and tracked.size < _LINES_SEEN_SHARE * (tracked[-1] + 1):
            continue
        reach = (x0 + 0.5 if x0 is not None else float(tracked[-1]) + 1.0) * _LINE_BIN_M
        if best is None or reach > best[0]:
            best = (reach, x0 is not None)
    return None if best is None else (float(start + direction * best[0]), best[1])


# a lane line's walk: dashed, lost after _LINES_LOST_BINS, its gate growing per bin unseen
_walk_lane_line = partial(_walk_line, lost_bins=_LINES_LOST_BINS, gate_growth=_LINES_GATE_GROWTH_M)


def _lines_beside(
    s: FloatArray, u: FloatArray, gap: tuple[float, float], lo: float, hi: float, *, forward: bool
) -> list[tuple[float, float]]:
    """The lines between offsets ``lo`` and ``hi`` (metres) over the ``_LINES_SIDE_M`` next
    to the gap's start (``forward``) or end: runs of samples ``_LINES_APART_M`` apart
    across at most, seen in ``_LINES_SEEN_BINS`` bins, on a straight course
    (``_LINES_SPREAD_M``); per line, inner to outer, its offset at the gap and its slope
    into it (metres per ``_LINE_BIN_M`` bin)."""
    direction = 1.0 if forward else -1.0
    along = direction * (s - (gap[0] if forward else gap[1]))
    side = (along > -_LINES_SIDE_M) & (along <= 0.0) & (u > lo) & (u < hi)
    if not side.any():
        return []
    order = np.argsort(u[side])
    u_side, a_side = u[side][order], along[side][order]
    groups = np.split(np.arange(u_side.size), np.flatnonzero(np.diff(u_side) > _LINES_APART_M) + 1)
    lines = []
    for g in groups:
        bins = np.floor(-a_side[g] / _LINE_BIN_M)
        if np.unique(bins).size < _LINES_SEEN_BINS:
            continue
        coef = np.polyfit(a_side[g], u_side[g], 1)
        resid = u_side[g] - np.polyval(coef, a_side[g])
        if 1.4826 * float(np.median(np.abs(resid - np.median(resid)))) > _LINES_SPREAD_M:
            continue
        lines.append((float(np.polyval(coef, 0.0)), float(coef[0]) * _LINE_BIN_M))
    return lines


def _through_drift(
    s: FloatArray, u: FloatArray, gap: tuple[float, float], inner_level: float, *, forward: bool
) -> float:
    """How fast (metres per ``_LINE_BIN_M`` bin, outward positive) a line of the lanes that
    stay drifts off its course across the gap: the nearest line a lane or more inside the
    edge's inner level (``_THROUGH_BAND_M``; the one along the new level may be a ramp's)
    walked across it, its slope there (a straight fit to bins seen over
    ``_DRIFT_SPAN_BINS`` or more) less its slope beside the gap; 0 where none is seen so.
    The frame across the gap is the fit's bridge, which tilts where the edge steps:
    oakland-11197879-opp-s4 with a noisier sensor (seed offset 380), every line drifting
    0.04-0.08 m/m in it, a 3-lane inner exit's line was told leaving where the gap began,
    25 m before the nose (edge 0.269 -> 0.787 m, a failed route)."""
    lines = _lines_beside(
        s,
        u,
        gap,
        inner_level - _THROUGH_BAND_M[1],
        inner_level - _THROUGH_BAND_M[0],
        forward=forward,
    )
    for held, slope in reversed(lines):
        track = _walk_lane_line(s, u, gap, held, slope, forward=forward)
        tracked = np.flatnonzero(np.isfinite(track))
        if tracked.size >= 5 and tracked[-1] - tracked[0] >= _DRIFT_SPAN_BINS:
            return float(np.polyfit(tracked + 0.5, track[tracked], 1)[0]) - slope
    return 0.0


def _lost_before_end(track: FloatArray) -> bool:
    """Whether a walked line (:func:`_walk_line`) was last seen ``_LINES_END_M`` or more
    before the gap's far end: seen on up to it, its lane was still there, no ramp's line
    yet, whatever its drift (oakland-28393854-s7 with a noisier sensor: a 3-lane inner
    exit's lines fanning out 0.03 m/m over the 80 m before the nose)."""
    tracked = np.flatnonzero(np.isfinite(track))
    return bool(tracked.size) and (track.size - 1 - tracked[-1]) * _LINE_BIN_M >= _LINES_END_M


def _off_course_bin(track: FloatArray, held: float, slope: float) -> float | None:
    """Where (bins of the walk) a walked line (:func:`_walk_line`) that kept following a
    gentle bend leaves its course outward: the tracked offsets fitted as a straight
    course (``held`` and ``slope``, metres per bin, from beside the gap, give its start;
    a frame bent across the gap by the fit's bridge tilts it by up to
    ``_LINES_DRIFT_RATE``) with a hinge, the line bending away by ``_LINES_LEAVE_RATE``
    (m/m) or more after it and ending ``_LINE_LEAVES_M`` or more off the course, two
    tracked bins beyond it. None where it does not leave. A ramp's line leaving at a
    small angle was walked on far beyond its gore (melbourne-408-opp-s4 with a noisier
    sensor: the step 18-35 m late), and a frame drifting 0.01 m/m against a straight line
    is no departure (melbourne-921-s2: one told 27 m before the gore)."""
    tracked = np.flatnonzero(np.isfinite(track))
    if tracked.size < 5:
        return None
    x = tracked.astype(float) + 0.5
    y = track[tracked] - (held + slope * x)
    k0 = np.arange(float(x[1]), float(x[-2]), 0.25)
    if not k0.size:
        return None
    hinge = np.clip(x[None, :] - k0[:, None], 0.0, None)
    # per candidate hinge: least squares of y = a + b x + c hinge (normal equations)
    basis = np.stack([np.ones_like(hinge), np.broadcast_to(x, hinge.shape), hinge], axis=2)
    gram = np.einsum("kni,knj->kij", basis, basis) + 1e-9 * np.eye(3)
    params = np.linalg.solve(gram, np.einsum("kni,n->ki", basis, y)[:, :, None])[:, :, 0]
    sse = np.sum((np.einsum("kni,ki->kn", basis, params) - y) ** 2, axis=1)
    best = int(np.argmin(sse))
    a, b, c = params[best]
    after = x > k0[best]
    per_bin_leave = _LINES_LEAVE_RATE * _LINE_BIN_M
    per_bin_drift = _LINES_DRIFT_RATE * _LINE_BIN_M
    if np.count_nonzero(after) < 2 or c < per_bin_leave or abs(b) > per_bin_drift:
        return None
    if float(y[-1] - (a + b * x[-1])) < _LINE_LEAVES_M:
        return None
    return float(k0[best])


def _leaving_from_start(
    track: FloatArray, held: float, slope: float, drift: float = 0.0
) -> float | None:
    """Where (bins) a walked line (:func:`_walk_line`, held at ``held`` with ``slope``
    metres per bin beside the gap) already leaving its course where the gap begins left
    it: its offsets off the course, less the lanes' own ``drift`` (metres per bin,
    :func:`_through_drift`), fitted as a straight line rising by ``_LINES_LEAVE_RATE`` or
    more, the last ``_LINE_BEYOND_M`` out at least; the bin where that line crosses the
    course (0 at the earliest). None where it does not leave so. A ramp's line bending
    away right at the gap's start, ever less steeply, has no straight stretch before a
    hinge (melbourne-408-opp-s9 with a noisier sensor: 3.3 m off over 80 m, the inner
    exit's step bridged as a taper, the edge 6 m off)."""
    tracked = np.flatnonzero(np.isfinite(track))
    if tracked.size < 5:
        return None
    x = tracked.astype(float) + 0.5
    y = track[tracked] - (held + (slope + drift) * x)
    rate, at0 = np.polyfit(x, y, 1)
    if rate < _LINES_LEAVE_RATE * _LINE_BIN_M or float(y[-1]) < _LINE_BEYOND_M:
        return None
    return float(max(-at0 / rate, 0.0))


def _hinge_start(x: FloatArray, off: FloatArray) -> float:
    """The ``x0`` (bins, in steps of a quarter bin over ``x``'s range) whose hinge
    ``c * max(x - x0, 0)^p`` (``c`` by least squares, ``p`` 2 for a line leaving on a
    curve or 1 for one leaving straight at an angle, whichever fits better) fits the
    offsets ``off`` (metres from a line's straight course) best. A curve fitted to a line
    leaving at an angle puts its start bins early (melbourne-921-s2 with a noisier
    sensor: 10 m before the gore)."""
    x0 = np.arange(float(x[0]), float(x[-1]), 0.25)
    if not x0.size:
        return float(x[0])
    best, best_sse = float(x0[0]), np.inf
    for power in (2.0, 1.0):
        q = np.clip(x[None, :] - x0[:, None], 0.0, None) ** power
        c = np.sum(q * off[None, :], axis=1) / np.maximum(np.sum(q * q, axis=1), 1e-12)
        sse = np.sum((off[None, :] - c[:, None] * q) ** 2, axis=1)
        k = int(np.argmin(sse))
        if sse[k] < best_sse:
            best, best_sse = float(x0[k]), float(sse[k])
    return best


_MEET_REACH_M = 25.0  # a ramp's edge meeting the edge at a gap's end: its points this near
_MEET_OUT_M = (0.4, 15.0)  # ... lying this far outward of the edge's level ...
_MEET_ON_M = 0.3  # ... on one straight line within this ...
_MEET_POINTS = 8  # ... this many at least ...
_MEET_BIN_M = 2.5  # ... spread over this many metres along ...
_MEET_BINS = 4  # ... in this many of them at least ...
_MEET_MAX_POINTS = 120  # (points tried as the line's ends)
_MEET_SLOPE = 0.1  # ... come in onto it by this much per metre at least ...
_MEET_AT_M = 2.0  # ... to within this (metres) at the gap's end


def ramp_edge_meets(
    s: FloatArray, u: FloatArray, end: float, level: float, direction: float
) -> bool:
    """Whether edge points beyond the gap's ``end`` (``direction`` -1: before its start,
    +1: after its end; stations ``s``, offsets ``u`` away from the carriageway, metres)
    run in onto ``level`` towards the gap, meeting it there: the edge of a ramp that
    joins (leaves) at its nose, whose lane the mainline gains (loses) beyond. Among the
    points within ``_MEET_REACH_M`` of the end lying outward of the level
    (``_MEET_OUT_M``; the ramp's far edge and stray points lie there too), of the
    straight lines through two of them that come in by ``_MEET_SLOPE`` per metre at
    least and lie within ``_MEET_AT_M`` of the level at the end, the one most lie on
    (``_MEET_ON_M``) must hold ``_MEET_POINTS`` spread over ``_MEET_BINS`` stretches of
    ``_MEET_BIN_M``, and its least-squares fit to them must still come in so."""
    dist = direction * (s - end)
    out = u - level
    near = (dist >= 0.0) & (dist < _MEET_REACH_M) & (out > _MEET_OUT_M[0]) & (out < _MEET_OUT_M[1])
    x, y = dist[near], out[near]
    if x.size < _MEET_POINTS:
        return False
    if x.size > _MEET_MAX_POINTS:  # every k-th along: the pairs stay few
        keep = np.argsort(x, kind="stable")[:: math.ceil(x.size / _MEET_MAX_POINTS)]
        x, y = x[keep], y[keep]
    i, j = np.triu_indices(x.size, k=1)
    ok = x[j] - x[i] > 1.0
    i, j = i[ok], j[ok]
    slope = (y[j] - y[i]) / (x[j] - x[i])
    at_end = y[i] - slope * x[i]
    # only lines that come in onto the level (the ramp's far edge, parallel to its near
    # one, meets it nowhere)
    ok = (slope >= _MEET_SLOPE) & (at_end <= _MEET_AT_M)
    if not ok.any():
        return False
    slope, at_end = slope[ok], at_end[ok]
    on = np.abs(y[None, :] - (at_end[:, None] + slope[:, None] * x[None, :])) < _MEET_ON_M
    best = int(np.argmax(np.count_nonzero(on, axis=1)))
    xs = x[on[best]]
    spread = np.unique((xs / _MEET_BIN_M).astype(np.int64)).size
    if xs.size < _MEET_POINTS or spread < _MEET_BINS:
        return False
    fit_slope, fit_at = np.polyfit(xs, y[on[best]], 1)
    return bool(fit_slope >= _MEET_SLOPE and fit_at <= _MEET_AT_M)
