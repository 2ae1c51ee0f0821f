"""The outermost line where it is not painted: it keeps the hard shoulder's width.

An acceleration lane's outer line is often unpainted (or worn, or hidden behind traffic)
for tens of metres after the gore, while the outer edge beyond its hard shoulder is seen
all along. The marking track bridges such a stretch by a straight line between the
samples either side, and where the track begins with a few samples of the ramp's own
line crossing it at the gore, that line starts at the ramp's offset: melbourne-921-s2's
acceleration lane was built 1.3 m narrow over 45 m. The hard shoulder keeps its width
along the lane (2.6-2.7 m on both sides of that stretch): across the stretch the line
follows the edge at the shoulder width measured beside it (:func:`follow_edge_across_unpainted`).

Stations are metres along the reference line; offsets ``d`` metres from the reference
edge towards the carriageway (the lanes' frame, :func:`~.lanes.fit_lanes`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .markings import _Track

FloatArray = NDArray[np.float64]

_UNPAINTED_MIN_M = 20.0  # a line without samples over at least this length is bridged
_END_WINDOW_M = 10.0  # the shoulder's width is measured from the samples this near an end
_END_MIN_SAMPLES = 8  # ... if there are at least this many ...
_END_MIN_SPAN_M = 4.0  # ... spanning at least this (metres): fewer may be another line
_SHOULDER_RANGE_M = (0.5, 4.0)  # a plausible hard shoulder's width (metres)
_WIDTH_CHANGE_MAX_M = 0.5  # a shoulder changing more between the ends is left bridged
_MOVE_MIN_M = 0.25  # moves smaller than this leave the track as it was (metres)
_STEP_CLEAR_M = 5.0  # no edge step inside the stretch by more than this (metres): the edge
# is another level there (at a gore the ramp's); one at its end (an entry's gore at the
# track's start) is where the line's own edge begins
_BEYOND_M = 0.5  # a line this much farther out makes the track not the outermost (metres)
_LANE_MIN_M = 2.5  # a followed line this near another one squeezes a lane (metres)


def _end_width(
    s_near: FloatArray, d_near: FloatArray, grid: FloatArray, d_edge: FloatArray
) -> float | None:
    """The hard shoulder's width (edge minus line, metres) from the samples ``s_near``,
    ``d_near`` beside one end of a stretch; None if they are too few or too short a
    piece to be the line's own, NaN if the width there is no shoulder's (the edge meets
    the line, or lies a lane beyond it)."""
    if s_near.size < _END_MIN_SAMPLES or float(np.ptp(s_near)) < _END_MIN_SPAN_M:
        return None
    width = float(np.median(np.interp(s_near, grid, d_edge) - d_near))
    lo, hi = _SHOULDER_RANGE_M
    return width if lo <= width <= hi else math.nan


def follow_edge_across_unpainted(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    covered: NDArray[np.bool_],
    breaks: FloatArray,
) -> list[_Track]:
    """Tracks whose outermost stretches without samples follow the outer edge.

    Where an observed track goes ``_UNPAINTED_MIN_M`` or more without a sample, no other
    line lies beyond it there, the outer edge was seen all along (``covered`` on ``grid``)
    and no edge step (``breaks``, stations in metres) lies inside it, the
    track across the stretch is the edge (``d_edge`` on ``grid``) less a shoulder width
    linear between the widths measured from the samples beside its two ends (if they
    differ by ``_WIDTH_CHANGE_MAX_M`` or less: a shoulder that changes more says nothing
    of the line's course). An end with
    fewer samples (a few of a ramp's line where the track begins at a gore) gives none:
    where those are the track's first (last) samples, the other end's width holds and the
    track is replaced from its start (to its end); elsewhere the stretch stays bridged.
    An end whose width is no shoulder's (outside ``_SHOULDER_RANGE_M``: the edge closing
    onto the line before an entry's gore, melbourne-408-lane2-s22, where following it bent
    the line 0.5 m) leaves the stretch bridged. Moves under ``_MOVE_MIN_M`` are left out.

    Returns the tracks, the moved ones replaced (their samples kept).
    """
    out = list(tracks)
    for k, tr in enumerate(tracks):
        ss, dd = tr.s_samples, tr.d_samples
        if tr.n == 0 or ss.size < 2 or dd.size != ss.size:
            continue
        d_new = tr.d.copy()
        for i in np.flatnonzero(np.diff(ss) >= _UNPAINTED_MIN_M):
            a, b = float(ss[i]), float(ss[i + 1])
            before = (ss >= a - _END_WINDOW_M) & (ss <= a)
            after = (ss >= b) & (ss <= b + _END_WINDOW_M)
            w_a = _end_width(ss[before], dd[before], grid, d_edge)
            w_b = _end_width(ss[after], dd[after], grid, d_edge)
            if w_a is None and w_b is None:
                continue
            if any(w is not None and math.isnan(w) for w in (w_a, w_b)):
                continue  # the shoulder closes or opens a lane there: not one width
            if w_a is not None and w_b is not None and abs(w_a - w_b) > _WIDTH_CHANGE_MAX_M:
                continue  # the shoulder changes: the edge does not say how the line goes
            # an end with few samples counts only where the track begins (ends) with them:
            # elsewhere they are a sparse stretch of the line itself, and following the
            # other end's width from there stepped the line 0.8 m (krems-46762523, a
            # broken line's gap before an entry)
            if w_a is None:
                if float(ss[0]) < a - _END_WINDOW_M:
                    continue
                a = float(tr.lo)  # the few samples before are where the track begins
            if w_b is None:
                if float(ss[-1]) > b + _END_WINDOW_M:
                    continue
                b = float(tr.hi)
            span = (grid >= a) & (grid <= b)
            if not span.any() or not covered[span].all():
                continue
            if breaks.size and np.any((breaks > a + _STEP_CLEAR_M) & (breaks < b - _STEP_CLEAR_M)):
                continue
            w0, w1 = (w_a, w_b) if w_a is not None and w_b is not None else (w_a or w_b,) * 2
            on = (tr.s >= a) & (tr.s <= b)
            if not on.any():
                continue
            x = (tr.s[on] - a) / max(b - a, 1e-9)
            line = np.interp(tr.s[on], grid, d_edge) - (w0 + (w1 - w0) * x)
            if float(np.max(np.abs(line - d_new[on]))) < _MOVE_MIN_M:
                continue
            if _line_beyond(tracks, k, a, b, np.minimum(line, d_new[on]).min()):
                continue
            if _squeezes_lane(tracks, k, tr.s[on], line):
                continue
            d_new[on] = line
        if not np.array_equal(d_new, tr.d):
            out[k] = replace(tr, d=d_new)
    return out


def _squeezes_lane(tracks: list[_Track], k: int, s: FloatArray, line: FloatArray) -> bool:
    """Whether the line followed along the edge (``line`` at stations ``s``, metres) comes
    nearer than ``_LANE_MIN_M`` to another track (where that runs): the strip beyond the
    line was a lane closing with the edge, not a shoulder keeping its width
    (soderleden-s1 with a noisier sensor, seed offset 200: an acceleration lane with no
    outer line, its 3.5 m taken for a shoulder; the line between it and the through lanes,
    unseen for 26 m up to its taper's end, followed the edge onto the next line inward and
    closed a through lane: lanes 0.209 m)."""
    for j, other in enumerate(tracks):
        if j == k:
            continue
        on = (s >= other.lo) & (s <= other.hi)
        if not on.any():
            continue
        apart = np.abs(line[on] - np.interp(s[on], other.s, other.d))
        if float(np.min(apart)) < _LANE_MIN_M:
            return True
    return False


def _line_beyond(tracks: list[_Track], k: int, a: float, b: float, d_min: float) -> bool:
    """Whether a track other than ``k`` lies more than ``_BEYOND_M`` beyond offset
    ``d_min`` somewhere between stations ``a`` and ``b`` (metres)."""
    for j, other in enumerate(tracks):
        if j == k or other.hi < a or other.lo > b:
            continue
        on = (other.s >= a) & (other.s <= b)
        if on.any() and float(np.max(other.d[on])) > d_min + _BEYOND_M:
            return True
    return False
