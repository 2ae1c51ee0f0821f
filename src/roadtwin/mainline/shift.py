"""The sideways shift of the marking pattern as a whole along the mainline.

Where lanes are added or dropped beside the median, every line beyond them moves sideways
by a lane width over 50-100 m in the reference line's frame (which follows the median-side
edge), and so do the lines where the carriageway swings out after an inner exit. Followed
line by line, such lines are lost: a column's peaks lie too far from where a track
predicts them, the steep parts are cut as ramp lines and the pieces are joined to the
wrong neighbours, so lanes come out up to 10 m wide. Found in a frame that moves with the
pattern, the lines are straight and link as anywhere else (:mod:`.markings`).

The shift is inferred for the whole run at once: over windows along the station, the
samples are sheared by every rate tried and scored by how sharply the lines pile up;
the rates of all windows are one path through these scores (dynamic programming, a
penalty for a rate off 0 and for changing it); each stretch of the path off 0 is scaled
so that the line pattern after it matches the one before it, and kept only where it moves
the lines by half a lane or more.

Stations ``s`` and offsets ``d`` are metres in the reference line's frame (``d`` from the
reference edge towards the carriageway); rates are metres per metre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ._common import true_runs

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["ShiftFrame", "common_shift"]

WINDOW_M = 20.0
"""Lines are straightened over windows this long (metres) ..."""
STEP_M = 5.0
"""... one every this many metres."""
RATES = np.linspace(-0.24, 0.24, 97)
"""Sideways rates tried (m/m): a lane width over 15 m at most."""
FINE_RATES = np.linspace(-0.06, 0.06, 49)
"""Rates tried (m/m) for what the lines still do in the frame of a first estimate."""
BIN_M = 0.1
"""Offset bins in which sheared samples pile up (metres)."""
RATE_PRIOR = 0.25
"""Log-sharpness a window must gain over rate 0 to leave it (no shift unless the lines
say so)."""
RATE_CHANGE = 6.0
"""Cost of a change of rate from one window to the next, per m/m (a shift is smooth)."""
SNAP_M = 1.5
"""A stretch's total shift is moved by at most this (metres) to match the line pattern
after it with the one before it."""
MIN_TOTAL_M = 1.75
"""Half a lane: a smaller shift the line-by-line linking follows by itself, and the frame
is left alone (metres)."""
SPREAD_WINDOWS = 3
"""The rate path is smoothed over this many windows either way (a triangle)."""
PATTERN_M = 30.0
"""Length of the line patterns compared before and after a shift (metres)."""
STAY_M = 0.3
"""A line whose peaks stay this close (metres) to their median offset from before a
shifting stretch to after it, more than ``STAY_INNER_M`` beyond the innermost line, did not
shift: the stretch is a lane added or dropped beside the lines that moved (at the outer
edge), not a shift of the whole pattern (beside the median, where only the innermost
line stays)."""
STAY_INNER_M = 2.0
"""(metres) see ``STAY_M``."""
OWNER_M = 0.6
"""A sample belongs to the line whose peak track lies this close (metres, with a column's
spacing counted as 0.5 m)."""


@dataclass(frozen=True)
class ShiftFrame:
    """The sideways shift (metres, towards the carriageway) the marking pattern has made
    by each station (metres) of ``stations``; piecewise linear in between."""

    stations: FloatArray
    shift: FloatArray

    def offset(self, s: FloatArray) -> FloatArray:
        """How far (metres) the frame lies from the reference line's at ``s``: offsets in
        the frame are ``d - offset(s)``. It is 0 up to the first shift: there the frame
        is the reference line's, and so are its peaks and tracks."""
        return np.interp(s, self.stations, self.shift)

    @property
    def deepest_m(self) -> float:
        """How far (metres, >= 0) offsets in the frame reach below their own: where the
        frame lies farthest out."""
        return max(0.0, float(np.max(self.shift)))

    def rate(self, s: FloatArray) -> FloatArray:
        """The pattern's sideways rate (m/m) at ``s``."""
        return np.interp(s, self.stations, np.gradient(self.shift, self.stations))


def common_shift(
    s: FloatArray,
    d: FloatArray,
    length: float,
    peak_s: FloatArray,
    peak_d: FloatArray,
    peak_track: IntArray,
    column_m: float,
) -> ShiftFrame | None:
    """The shift of the marking pattern along the run; None where it never shifts by
    ``MIN_TOTAL_M`` or more.

    Parameters
    ----------
    s, d
        Stations and offsets of the lane-marking samples (metres, reference frame).
    length
        Road length (metres).
    peak_s, peak_d, peak_track
        The histogram peaks linked into tracks (:func:`.markings._link_tracks`): station
        and offset (metres) of each peak and the track it belongs to. A line weighs the
        same in a window however many samples it has there (a solid line no more than a
        broken one): its samples are those nearest to its peaks.
    column_m
        Spacing of the histogram columns along the station (metres).
    """
    starts = np.arange(0.0, max(length - WINDOW_M, 0.0) + STEP_M, STEP_M)
    mids = starts + 0.5 * WINDOW_M
    if s.size == 0 or peak_s.size == 0 or mids.size < 2:
        return None
    owner = _owners(s, d, peak_s, peak_d, peak_track, column_m)
    sharp = _sharpness(s, d, owner, mids)
    if sharp is None:
        return None
    rate = _rate_path(sharp, RATES)
    for a, b in true_runs(rate != 0.0):
        total = float(np.sum(rate[a:b])) * STEP_M
        matched = _pattern_shift(
            s, d, owner, mids[a] - 0.5 * STEP_M, mids[b - 1] + 0.5 * STEP_M, total
        )
        if matched is not None and abs(total) > 1e-9:
            rate[a:b] *= matched / total
            total = matched
        s_a, s_b = mids[a] - 0.5 * STEP_M, mids[b - 1] + 0.5 * STEP_M
        if abs(total) < MIN_TOTAL_M or _a_line_stays(peak_s, peak_d, peak_track, s_a, s_b):
            rate[a:b] = 0.0
    if not np.any(rate != 0.0):
        return None
    # the path leaves 0 late and comes back early (the gentle ends of a shift gain too
    # little sharpness), and is steeper in between: spread it as far as it is short
    kernel = np.bartlett(2 * SPREAD_WINDOWS + 3)[1:-1]
    rate = np.convolve(rate, kernel / kernel.sum(), mode="same")
    # what the lines still do in that frame, found the same way at finer rates
    first_pass = ShiftFrame(mids, _integrate(rate))
    residual = _sharpness(s, d - first_pass.offset(s), owner, mids, FINE_RATES)
    if residual is not None:
        fine = _rate_path(residual, FINE_RATES)
        for a, b in true_runs(rate != 0.0):
            # the refined shape, with the total the line patterns either side agree on
            total = float(np.sum(rate[a:b]))
            refined = rate[a:b] + fine[a:b]
            if abs(float(np.sum(refined))) > 1e-9:
                rate[a:b] = refined * (total / float(np.sum(refined)))
    return ShiftFrame(mids, _integrate(rate))


def _a_line_stays(
    peak_s: FloatArray, peak_d: FloatArray, peak_track: IntArray, s_a: float, s_b: float
) -> bool:
    """Whether the stretch ``[s_a, s_b]`` (metres) moves only lines beyond the pattern:
    linked lines seen within ``PATTERN_M`` before and after it keep their offset all
    through (``STAY_M``; more than ``STAY_INNER_M`` beyond the innermost line seen
    before), and every peak inside the stretch off those lines lies beyond the outermost of
    them.

    A lane added at the outer edge moves the edge line and the lines beyond it out by a
    lane width while the lane lines inside stay: taken for a shift of the whole pattern,
    the lines that stayed were linked in the moving frame, each to the next one out, and
    three lane borders swept 3.5 m across the lanes over 140 m (town06-auto-s1). A lane
    added beside the median moves every line but the innermost; shifted by a lane width
    or two the pattern looks the same after it, and a line linked across may hop from
    one moving line to the next at one offset: there the moving lines cross the stretch
    inside it."""
    win = (peak_s >= s_a - PATTERN_M) & (peak_s <= s_b + PATTERN_M) & (peak_track >= 0)
    before = win & (peak_s < s_a)
    if not before.any():
        return False
    inner = float(np.min(peak_d[before]))
    tracks, inverse = np.unique(peak_track[win], return_inverse=True)
    d_w, s_w = peak_d[win], peak_s[win]
    n = tracks.size
    med = np.array([np.median(d_w[inverse == k]) for k in range(n)])
    spread = np.zeros(n)
    np.maximum.at(spread, inverse, np.abs(d_w - med[inverse]))
    seen_before = np.zeros(n, dtype=bool)
    seen_before[inverse[s_w < s_a]] = True
    seen_after = np.zeros(n, dtype=bool)
    seen_after[inverse[s_w > s_b]] = True
    stays = seen_before & seen_after & (spread <= STAY_M) & (med >= inner + STAY_INNER_M)
    if not stays.any():
        return False
    inside = (s_w >= s_a) & (s_w <= s_b) & ~stays[inverse]
    off_lines = np.min(np.abs(d_w[inside, None] - med[stays][None, :]), axis=1) > STAY_M
    moving = d_w[inside][off_lines]
    return bool(np.all(moving > float(np.max(med[stays]))))


def _integrate(rate: FloatArray) -> FloatArray:
    """The shift (metres) made by each window's centre from the rates (m/m)."""
    return np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * STEP_M)])


def _owners(
    s: FloatArray,
    d: FloatArray,
    peak_s: FloatArray,
    peak_d: FloatArray,
    peak_track: IntArray,
    column_m: float,
) -> IntArray:
    """The track each sample belongs to (-1: none within ``OWNER_M``)."""
    from scipy.spatial import cKDTree

    scale = 0.5 / column_m  # a column's spacing counts like 0.5 m across
    tree = cKDTree(np.column_stack([peak_s * scale, peak_d]))
    dist, idx = tree.query(np.column_stack([s * scale, d]))
    return np.where(dist < OWNER_M, peak_track[np.minimum(idx, peak_track.size - 1)], -1)


def _sharpness(
    s: FloatArray, d: FloatArray, owner: IntArray, mids: FloatArray, rates: FloatArray = RATES
) -> FloatArray | None:
    """``(windows, rates)``: how sharply the lines of each window pile up when sheared by
    each rate (sum over offset bins of the squared line weights; a line weighs 1 in a
    window); None without owned samples."""
    n_win = mids.size
    per = round(WINDOW_M / STEP_M)
    first = np.floor(s / STEP_M).astype(np.int64)
    win = (first[:, None] - np.arange(per)[None, :]).ravel()
    rep = np.repeat(np.arange(s.size), per)
    ok = (win >= 0) & (win < n_win) & (owner[rep] >= 0)
    win, rep = win[ok], rep[ok]
    if win.size == 0:
        return None
    n_track = int(owner.max()) + 1
    _, inverse, counts = np.unique(
        win * n_track + owner[rep], return_inverse=True, return_counts=True
    )
    weight = 1.0 / counts[inverse]
    ds = s[rep] - mids[win]
    d0 = d[rep]
    lo = float(np.min(d0)) - 4.0
    n_bin = math.ceil((float(np.max(d0)) + 4.0 - lo) / BIN_M) + 1
    sharp = np.zeros((n_win, rates.size))
    for k, r in enumerate(rates):
        b = np.clip(((d0 - r * ds - lo) / BIN_M).astype(np.int64), 0, n_bin - 1)
        sums = np.bincount(win * n_bin + b, weights=weight, minlength=n_win * n_bin)
        sharp[:, k] = np.sum(sums.reshape(n_win, n_bin) ** 2, axis=1)
    return sharp


def _rate_path(sharp: FloatArray, rates: FloatArray) -> FloatArray:
    """The rate (m/m) of every window: the path through the rates tried that gains the
    most log-sharpness over rate 0, less ``RATE_PRIOR`` per window off 0 and
    ``RATE_CHANGE`` per unit change between windows (Viterbi)."""
    n_win, n_rate = sharp.shape
    zero = int(np.argmin(np.abs(rates)))
    gain = np.log(sharp + 0.05) - np.log(sharp[:, zero : zero + 1] + 0.05)
    gain -= np.where(np.arange(n_rate) == zero, 0.0, RATE_PRIOR)[None, :]
    change = RATE_CHANGE * np.abs(rates[:, None] - rates[None, :])  # (to, from)
    score = gain[0].copy()
    back = np.zeros((n_win, n_rate), dtype=np.int64)
    rows = np.arange(n_rate)
    for w in range(1, n_win):
        total = score[None, :] - change
        back[w] = np.argmax(total, axis=1)
        score = total[rows, back[w]] + gain[w]
    path = np.zeros(n_win, dtype=np.int64)
    path[-1] = int(np.argmax(score))
    for w in range(n_win - 1, 0, -1):
        path[w - 1] = back[w, path[w]]
    return rates[path].copy()


def _pattern_shift(
    s: FloatArray, d: FloatArray, owner: IntArray, s_a: float, s_b: float, total: float
) -> float | None:
    """The shift (metres) that best maps the line pattern over ``PATTERN_M`` before
    ``s_a`` onto the one after ``s_b``, within ``SNAP_M`` of ``total``; None without lines
    on either side. The rates integrate to a total a few tenths short or long (a window's
    sharpest rate averages over the window); the patterns say it to a bin."""
    from scipy.ndimage import gaussian_filter1d

    lo_d = float(np.min(d)) - 10.0
    n_bin = math.ceil((float(np.max(d)) + 10.0 - lo_d) / BIN_M) + 1

    def pattern(lo: float, hi: float) -> FloatArray | None:
        sel = (s >= lo) & (s < hi) & (owner >= 0)
        if not sel.any():
            return None
        _, inverse, counts = np.unique(owner[sel], return_inverse=True, return_counts=True)
        b = np.clip(((d[sel] - lo_d) / BIN_M).astype(np.int64), 0, n_bin - 1)
        return gaussian_filter1d(np.bincount(b, 1.0 / counts[inverse], minlength=n_bin), 2.0)

    before = pattern(s_a - PATTERN_M, s_a)
    after = pattern(s_b, s_b + PATTERN_M)
    if before is None or after is None:
        return None
    shifts = np.round(np.arange(total - SNAP_M, total + SNAP_M + 1e-9, BIN_M) / BIN_M).astype(
        np.int64
    )
    score = np.array(
        [
            float(
                np.dot(
                    before[max(0, -k) : n_bin - max(0, k)], after[max(0, k) : n_bin - max(0, -k)]
                )
            )
            for k in shifts.tolist()
        ]
    )
    if score.max() <= 0.0:
        return None
    return float(shifts[int(np.argmax(score))] * BIN_M)
