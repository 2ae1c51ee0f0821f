"""Lane-marking peaks and their linking: the histogram of the lane samples per 5 m
column, its peaks (double lines told apart), and the peaks linked column by column into
raw tracks (:func:`_link_tracks`). :mod:`.markings` makes marking tracks of them.

Stations ``s`` and offsets ``d`` are metres in the reference line's frame (``d`` from the
reference edge towards the carriageway); a column is ``lane_column_m`` of station.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._signal import find_peaks
from ..config import MainlineConfig

FloatArray = NDArray[np.float64]


@dataclass
class _RawTrack:
    cols: list[int]
    d: list[float]
    slope: float = 0.0

    def add(self, col: int, value: float) -> None:
        """Append a column and update the slope (least squares over the last 4 columns,
        clipped to +-0.5 m per column)."""
        self.cols.append(col)
        self.d.append(value)
        if len(self.d) < 3:
            return
        c = self.cols[-4:]
        v = self.d[-4:]
        n = len(c)
        cm, vm = sum(c) / n, sum(v) / n
        var = 0.0
        cov = 0.0
        for ci, vi in zip(c, v, strict=True):
            var += (ci - cm) * (ci - cm)
            cov += (ci - cm) * (vi - vm)
        self.slope = min(max(cov / var, -0.5), 0.5)

    def predict(self, col: int) -> float:
        """Offset extrapolated linearly from the last few columns to column ``col``."""
        return self.d[-1] + self.slope * (col - self.cols[-1])


def _find_track_peaks(
    s: FloatArray, d: FloatArray, length: float, cfg: MainlineConfig, below_m: float = 0.0
) -> tuple[FloatArray, list[FloatArray]]:
    """Marking peaks per histogram column: column centres and the peak offsets in each.

    The histogram starts 1 m inside the reference edge, or whole bins more than
    ``below_m`` below that (metres; a frame that moves with a shifting pattern, whose
    offsets reach that far below their own): its bins stay where they are either way.
    All columns are searched in one ``find_peaks`` call: the columns are laid end to end,
    separated by zero padding at least as wide as the peak distance, so that neither the
    distance nor the prominence test reaches across columns.
    """
    from scipy.ndimage import gaussian_filter1d, uniform_filter1d

    col = cfg.lane_column_m
    n_col = max(1, math.ceil(length / col))
    d_lo = -1.0 - math.ceil(below_m / cfg.lane_bin_m) * cfg.lane_bin_m
    d_hi = float(np.nanmax(d)) + 1.0 if d.size else 1.0
    n_bin = max(4, math.ceil((d_hi - d_lo) / cfg.lane_bin_m))
    hist, _, _ = np.histogram2d(
        s, d, bins=(n_col, n_bin), range=((0.0, n_col * col), (d_lo, d_lo + n_bin * cfg.lane_bin_m))
    )
    hist = uniform_filter1d(hist, cfg.lane_window_columns, axis=0, mode="nearest")
    hist = gaussian_filter1d(hist, 1.5, axis=1, mode="constant")
    # height threshold: a fraction of the typical strong peak
    strong = np.percentile(hist.max(axis=1), 75) if hist.size else 0.0
    thr = max(0.15 * strong, 1e-9)
    min_dist = max(1, int(cfg.lane_min_separation_m / cfg.lane_bin_m))
    centres = (np.arange(n_col) + 0.5) * col
    bin_c = d_lo + (np.arange(n_bin) + 0.5) * cfg.lane_bin_m
    pad = min_dist + 1
    stride = n_bin + pad
    flat = np.zeros((n_col, stride))
    flat[:, :n_bin] = hist
    idx = find_peaks(flat.ravel(), height=thr, distance=min_dist, prominence=0.5 * thr)
    idx = np.union1d(idx, _double_line_peaks(flat, idx, thr, stride, cfg))
    row, j = np.divmod(idx, stride)
    # a column's first/last bin is never a peak (as for a search per column)
    inner = (j > 0) & (j < n_bin - 1)
    row, j = row[inner], j[inner]
    ks = np.arange(-2, 3)
    jj = np.clip(j[:, None] + ks[None, :], 0, n_bin - 1)
    wts = hist[row[:, None], jj]
    # centroid refinement over +-2 bins
    ref = (wts * bin_c[jj]).sum(axis=1) / np.maximum(wts.sum(axis=1), 1e-12)
    split = np.searchsorted(row, np.arange(1, n_col))
    peaks = np.split(ref, split)
    return centres, peaks


_DOUBLE_MIN_M = 0.35
"""Two parallel lines this far apart (metres) or more are two markings ..."""
_DOUBLE_SAME_M = 0.1
"""... where their separation stays within this (metres) ..."""
_DOUBLE_COLUMNS = 6
"""... over this many consecutive columns."""


def _double_line_peaks(
    flat: FloatArray, idx: NDArray[np.intp], thr: float, stride: int, cfg: MainlineConfig
) -> NDArray[np.intp]:
    """Peaks (indices into the padded histogram ``flat``) of the second line of a double
    line: closer to a peak ``idx`` than ``lane_min_separation_m`` but at least
    ``_DOUBLE_MIN_M`` from it, at the same separation (within ``_DOUBLE_SAME_M``) in
    ``_DOUBLE_COLUMNS`` consecutive columns.

    A shoulder split by a line 0.5 m beside the edge line (CARLA Town06, both sides) is
    two markings; as one, the two lines took turns as its track's peak and the lane
    borders jumped 0.5 m between them. A ramp's line leaving a marking at a gore moves
    away column by column and is not doubled here: resolved early, it split the mainline
    line in two at a bundled exit (which then took two lanes)."""
    fine_dist = max(1, int(_DOUBLE_MIN_M / cfg.lane_bin_m))
    fine = find_peaks(flat.ravel(), height=thr, distance=fine_dist, prominence=0.5 * thr)
    if idx.size == 0 or fine.size == 0:
        return np.zeros(0, dtype=np.intp)
    near = int(cfg.lane_min_separation_m / cfg.lane_bin_m)
    row_f, j_f = np.divmod(fine, stride)
    # the separation (bins, signed) of each fine peak from the nearest coarse peak of its
    # column (``idx`` is sorted, columns laid end to end); fine peaks that are coarse peaks
    # themselves are left out
    pos = np.searchsorted(idx, fine)
    best = np.full(fine.size, np.iinfo(np.int64).max)
    for cand in (pos - 1, pos):
        c = idx[np.clip(cand, 0, idx.size - 1)]
        same_row = (cand >= 0) & (cand < idx.size) & (c // stride == row_f)
        sep = np.where(same_row, fine - c, np.iinfo(np.int64).max)
        best = np.where(np.abs(sep) < np.abs(best), sep, best)
    extra = (np.abs(best) >= fine_dist) & (np.abs(best) < near)
    if not extra.any():
        return np.zeros(0, dtype=np.intp)
    rows, seps = row_f[extra], np.abs(best[extra])  # whichever of the two is higher
    tol = max(1, round(_DOUBLE_SAME_M / cfg.lane_bin_m))
    # at one separation and at one offset: a pair of lines moving sideways (a shift of the
    # whole pattern, lines crossing where it is lost) is left to the linking as before (as
    # two markings there, Town06's lines seen by a narrow sensor broke into pieces too
    # short to keep, and one lane 15 m wide was left)
    middle = 2 * j_f[extra] - best[extra]  # the pair's middle, in half bins
    keep = _runs_at(rows, seps, flat.shape[0], near + tol + 1, tol) & _runs_at(
        rows, middle, flat.shape[0], 2 * stride, 2 * tol
    )
    return fine[extra][keep].astype(np.intp)


def _runs_at(
    rows: NDArray[np.int64], values: NDArray[np.int64], n_rows: int, n_values: int, tol: int
) -> NDArray[np.bool_]:
    """Whether each ``(row, value)`` lies in a run of ``_DOUBLE_COLUMNS`` consecutive rows
    that each hold one within ``tol`` of ``value`` (integer bins)."""
    from scipy.ndimage import maximum_filter1d

    occ = np.zeros((n_rows, n_values), dtype=np.uint8)
    occ[rows, values] = 1
    occ = maximum_filter1d(occ, 2 * tol + 1, axis=1).astype(bool)
    k = _DOUBLE_COLUMNS
    csum = np.vstack([np.zeros((1, n_values), dtype=np.int64), np.cumsum(occ, axis=0)])
    full = (csum[k:] - csum[:-k]) == k  # a run of k starting at each row
    covered = np.zeros_like(occ)
    for lag in range(k):  # the rows each run covers
        covered[lag : lag + full.shape[0]] |= full
    return covered[rows, values]


_SETTLE_GAP_M = 25.0  # a line may go on at its last offset across at most this gap ...
_SETTLE_SLOPE = 0.04  # ... if it was moving no faster than a lane taper (m/m, 3.5 m in 90 m)
_SETTLE_LINK_M = 0.25  # ... and is seen again this close to its last offset (metres)
_SETTLE_WOBBLE_M = 0.1  # a line moving one way may step back this much (peak noise, metres)


def _settled_offset(track: _RawTrack, col: int, column_m: float) -> float:
    """The offset (metres) at which ``track`` may go on in column ``col`` (to within
    ``_SETTLE_LINK_M``) if its trend does not explain any peak there: its last offset,
    when it missed one column or more, but no more than ``_SETTLE_GAP_M``, while moving no
    faster than a taper; else inf. Only a taper's line qualifies: seen in every column up
    to the gap and moving one way all along (a sparse line that rose and fell again, a
    ramp's line crossing Town06's inner lanes out of a narrow sensor's reach, went on flat
    where it met another line and made one lane 18.5 m wide)."""
    gap = col - track.cols[-1]
    if gap < 2 or gap * column_m > _SETTLE_GAP_M or abs(track.slope) > _SETTLE_SLOPE * column_m:
        return np.inf
    if track.cols[-1] - track.cols[0] + 1 != len(track.cols):
        return np.inf
    steps = np.diff(track.d)
    if not (np.all(steps >= -_SETTLE_WOBBLE_M) or np.all(steps <= _SETTLE_WOBBLE_M)):
        return np.inf
    return track.d[-1]


_MET_GAP_COLUMNS = 4  # a line missed over this many columns ...
_MET_SLOPE = 0.015  # ... moving sideways this fast (m/m), a taper's, ...
_MET_LINE_M = 0.3  # ... and met another line that it came this close to (metres) ...
_MET_OVER_COLUMNS = 4  # ... closing the gap to it over its last this many columns ...
_MET_CLOSED_M = 0.5  # ... by this much at least (metres; a line beside it runs parallel)


def _met_another(
    tracks: list[_RawTrack], active: list[int], pred: FloatArray, col: int, column_m: float
) -> NDArray[np.bool_]:
    """Per active track, whether its trend guess is void in column ``col``: a taper's line
    (moving at ``_MET_SLOPE`` or faster; a flat line beside another, a dashed one where a
    solid one leaves it, is no taper), missed over ``_MET_GAP_COLUMNS`` columns or more
    (``column_m`` metres each; across a dash gap or two the trend stays trusted), that
    closed by ``_MET_CLOSED_M`` on a line running along the road over its last columns
    and would be carried onto or over it (that line within ``_MET_LINE_M`` behind the
    track's last offset up to ``pred``, its predicted offset, metres).

    Lines do not cross: a taper's line that met another ended there. Its slope linked it
    across a 55 m gap to the paint of a line beyond (melbourne-921-s2: an entry's line that
    met the next line at 520 m went on through two lanes to a gore's shoulder line at
    628 m). Judged against lines that move too, or after two missed columns already, it
    cut an entry's converging lines where a noisy peak split one of them, and a phantom
    line ran between them (melbourne-408-opp-s9, -921-s9 with a noisier sensor)."""
    out = np.zeros(len(active), dtype=bool)
    for k, i in enumerate(active):
        tr = tracks[i]
        if col - tr.cols[-1] < _MET_GAP_COLUMNS or abs(tr.slope) < _MET_SLOPE * column_m:
            continue
        step = math.copysign(1.0, pred[k] - tr.d[-1])
        c_before = tr.cols[max(-_MET_OVER_COLUMNS, -len(tr.cols))]
        d_before = tr.d[max(-_MET_OVER_COLUMNS, -len(tr.d))]
        for j in active:
            other = tracks[j]
            # the line met runs along the road (a through line); two lines converging
            # side by side (an entry's, where a noisy peak split one of them) are not
            # judged here
            if j == i or other.cols[-1] < tr.cols[-1] or other.cols[0] > c_before:
                continue
            if abs(other.slope) >= _MET_SLOPE * column_m:
                continue
            # the gap to the other line, ahead in the direction of the move, then and now
            gap_now = (other.d[-1] - tr.d[-1]) * step
            k_then = bisect.bisect_left(other.cols, c_before)
            gap_then = (other.d[min(k_then, len(other.d) - 1)] - d_before) * step
            converged = gap_then - gap_now >= _MET_CLOSED_M
            if converged and -_MET_LINE_M <= gap_now <= (pred[k] - tr.d[-1]) * step:
                out[k] = True
                break
    return out


_NO_LINK = 1e6
"""Cost of a peak and a track that none of the track's guesses reaches (no link)."""
_STAYS_PUT_COST = 0.25
"""Added (metres) to a link by the stays-put guess in a moving frame: the trend's guess is
preferred by this much, the nearer one wins beyond it (melbourne-408-opp-s9: the
median-side line's lagging trend took the new lanes' line 0.58 m from it while its own
peak lay 0.24 m from its stays-put guess). Taken pair by pair, guess by guess, the same
margin had cost melbourne-408-opp-s4+80 edge 0.097 -> 0.151 m (session 28)."""
_EDGE_NEAR_M = 2.0  # a line this near the outer edge (metres) may move with it ...
_EDGE_COST = 0.1  # ... its guess dearer than the trend's by this (metres)
_SETTLED_COST = 10.0
"""Added to a link by the settled-offset guess: more than any distance a guess may be
off, so it links a track only where that leaves no line its own trend explains
unlinked (a converging line must not take over the line it met)."""


def _link_tracks(
    peaks: list[FloatArray],
    cfg: MainlineConfig,
    frame_offset: FloatArray | None = None,
    edge: FloatArray | None = None,
) -> list[_RawTrack]:
    """Column peaks linked into tracks, one column after the other.

    In each column the active tracks' guesses (the trend, the stays-put guess in a moving
    frame, the settled offset) and the peaks are matched as a whole: as many links as the
    guesses' reaches allow, then the least distance, each guess's own extra cost added
    (an assignment, each peak and track used once). Taken pair by pair from the nearest,
    a track could take the peak another track needed and leave that one none: where
    Town06's split shoulder lines (0.5 m apart) swing out side by side at a lane gain, one
    line's track went unlinked for three columns and then took the other line's peaks
    (town06-auto-s3 with a noisier sensor, lanes 0.199 -> 0.177 m). A peak no track takes
    begins a track.

    ``frame_offset`` (metres per column): where the peaks are offsets in a frame that
    moves with the marking pattern (:mod:`.shift`), the frame's offset at each column. A
    line that stays where it is in the road while the pattern shifts around it (the
    median-side line where lanes are added beyond it) moves by minus the frame's move in
    the frame; its trend lags where the shift begins, and the track took the line that
    moves with the pattern instead (melbourne-408-opp-s9: the median-side line swapped
    for the new lanes' line, 2.3 m off over 100 m). Such a line may also go on where it
    stays put in the road.

    ``edge`` (metres per column, same frame, NaN where unseen): the outer edge. A line
    within ``_EDGE_NEAR_M`` of it may also go on at the distance it kept from it, where the
    edge moves: at a lane gain the shoulder's line swings out with the edge along an S,
    faster than its trend follows (town06-auto-s2: the line lost over 30 m, its pieces
    joined to the new lane's line, 0.8 m off)."""
    from scipy.optimize import linear_sum_assignment

    max_gap = max(1, round(cfg.lane_max_gap_m / cfg.lane_column_m))
    tracks: list[_RawTrack] = []
    active: list[int] = []
    for c, pk in enumerate(peaks):
        active = [i for i in active if c - tracks[i].cols[-1] <= max_gap]
        used_p: set[int] = set()
        if active and pk.size:
            pred = np.array([tracks[i].predict(c) for i in active])
            # across missed columns a taper's slope overshoots where the line flattens out
            # at its new offset (worn paint over a lane gain's last 25 m, oakland-28393854
            # with a noisier sensor): a line left without a peak may also go on at its last
            # offset, once every line that its own trend explains has taken its peak (a
            # converging line must not take over the line it met)
            last = np.array([_settled_offset(tracks[i], c, cfg.lane_column_m) for i in active])
            pred = np.where(_met_another(tracks, active, pred, c, cfg.lane_column_m), np.inf, pred)
            guesses = [(pred, cfg.lane_link_m, 0.0)]
            d_last = np.array([tracks[i].d[-1] for i in active])
            c_last = np.array([tracks[i].cols[-1] for i in active])
            if frame_offset is not None:
                still = d_last - (frame_offset[c] - frame_offset[c_last])
                # only where the frame moves (elsewhere it is the trend's own guess), and
                # for a line seen in the column before: across a gap another line may
                # have shifted into its place (krems-30799129-s11+20: an exit's line left
                # while the lines inward shifted out by a lane, and its track took the
                # line that arrived 20 m on, the gore 25 m late)
                moving = (np.abs(still - d_last) > 0.05) & (c_last == c - 1)
                guesses.append((np.where(moving, still, np.inf), cfg.lane_link_m, _STAYS_PUT_COST))
            if edge is not None:
                edge_then = edge[c_last]
                along = d_last + (edge[c] - edge_then)
                # NaN (unseen edge) compares False: no such guess
                follows = (np.abs(edge_then - d_last) <= _EDGE_NEAR_M) & (
                    np.abs(along - d_last) > 0.05
                )
                guesses.append((np.where(follows, along, np.inf), cfg.lane_link_m, _EDGE_COST))
            guesses.append((last, _SETTLE_LINK_M, _SETTLED_COST))
            total = np.full((pk.size, len(active)), _NO_LINK)
            for guess, tol, extra in guesses:
                cost = np.abs(pk[:, None] - guess[None, :])
                reached = np.where(cost <= tol, cost + extra, _NO_LINK)
                total = np.minimum(total, reached)
            for pi, ti in zip(*linear_sum_assignment(total), strict=True):
                if total[pi, ti] < _NO_LINK:
                    used_p.add(int(pi))
                    tracks[active[ti]].add(c, float(pk[pi]))
        for pi in range(pk.size):
            if pi not in used_p:
                tracks.append(_RawTrack([c], [float(pk[pi])]))
                active.append(len(tracks) - 1)
    return tracks
