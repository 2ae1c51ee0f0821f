"""Raw marking tracks (:mod:`.linking`) joined or carried on where one line's peaks went
to pieces: a taper's piece after the line it goes on from, a short piece where a moving
line's trend carries it past a gap, a short line into the peak of a line that closes on
it. Columns and offsets as in :mod:`.linking` (metres from the reference edge).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from .linking import _RawTrack

FloatArray = NDArray[np.float64]


_GOES_ON_COLUMNS = 2  # a line beginning within this many columns after another ended ...
_GOES_ON_M = 1.0  # ... this close (metres) to one of its last two offsets ...
_GOES_ON_MOVE_M = 1.0  # ... and moving inward by this much (metres) is its taper


def _join_tapers(raw: list[_RawTrack], cfg: MainlineConfig) -> list[_RawTrack]:
    """The raw tracks with every taper that goes on from a line that ended joined to that
    line (one marking).

    A taper is a raw track too short for a marking (``lane_min_track_m``) that moves
    inward by ``_GOES_ON_MOVE_M`` or more and begins within ``_GOES_ON_COLUMNS`` columns
    after a track long enough for one ended, within ``_GOES_ON_M`` of one of that track's
    last two offsets (the track's peaks after the matching one are dropped). Where a lane
    closes right past an exit's gore, its line splits there: the ramp's line goes out,
    the mainline's comes in. The linking may carry the track on along the ramp's line (cut
    off later as one); the taper, left on its own, was shorter than a track and dropped,
    and the closing lane became part of the shoulder (melbourne-408-lane1-s21 with a
    noisier sensor: lane count 97.7 %). Joined, the lane closes along its own line."""
    min_cols = cfg.lane_min_track_m / cfg.lane_column_m
    out = list(raw)  # joins build new tracks: the raw ones are never changed
    dropped: set[int] = set()
    for k, tr in enumerate(out):
        if tr.cols[-1] - tr.cols[0] + 1 >= min_cols or tr.d[0] - tr.d[-1] < _GOES_ON_MOVE_M:
            continue
        for j, line in enumerate(out):
            gap = tr.cols[0] - line.cols[-1]
            if j == k or j in dropped or not 1 <= gap <= _GOES_ON_COLUMNS:
                continue
            if line.cols[-1] - line.cols[0] + 1 < min_cols:
                continue
            miss = [abs(v - tr.d[0]) for v in line.d[-2:]]
            if min(miss) > _GOES_ON_M:
                continue
            keep = len(line.d) - (len(miss) - 1 - int(np.argmin(miss)))
            out[j] = _RawTrack(line.cols[:keep] + tr.cols, line.d[:keep] + tr.d, tr.slope)
            dropped.add(k)
            break
    return [tr for k, tr in enumerate(out) if k not in dropped]


_STEADY_M = 0.2  # a short line whose offsets span at most this much (metres) runs along ...
_MERGED_M = 0.1  # ... into a neighbour's peak until the two lie this close (metres) ...
_CLOSING_M = 0.05  # ... while the neighbour closes on it by this much (metres) a column


def _into_merging_peaks(
    raw: list[_RawTrack],
    cfg: MainlineConfig,
    peaks: tuple[NDArray[np.int64], FloatArray, NDArray[np.int64]],
) -> list[_RawTrack]:
    """The raw tracks, each one that runs along the road (offsets within ``_STEADY_M``)
    and is shorter than twice a marking's least length (``lane_min_track_m``) carried on
    at its offset over the columns beyond its ends where another line closes on it (by
    ``_CLOSING_M`` or more a column, nearer than ``lane_min_separation_m``): the two
    share one histogram peak there, and the other line took it. A lay-by's or a bay's
    line bulges out of a line and back in over 130 m, 1.3 m out at most, and the line it
    left goes on straight, dashed: it is a peak of its own only where the two lie 0.8 m
    apart, 60 m, too short for a track once a noisier sensor dropped a dash
    (krems-24980555-s11+80: the straight line lost, its boundary 1.3 m off). ``peaks``:
    every column peak once (column, offset, index of its raw track)."""
    min_cols = cfg.lane_min_track_m / cfg.lane_column_m
    peak_col, peak_d, peak_tr = peaks
    # the peaks sorted by column once: each column's are one slice
    by_col = np.argsort(peak_col, kind="stable")
    col_sorted = peak_col[by_col]
    out = list(raw)
    for k, tr in enumerate(raw):
        # a track as long as the shortest marking may still fall short of it where its
        # samples begin and end (a dashed line's first and last dash)
        if tr.cols[-1] - tr.cols[0] + 1 >= 2 * min_cols or max(tr.d) - min(tr.d) > _STEADY_M:
            continue
        level = float(np.median(tr.d))
        before: list[int] = []
        after: list[int] = []
        for step, found in ((-1, before), (1, after)):
            col = tr.cols[0] if step < 0 else tr.cols[-1]
            last = math.inf
            while True:
                col += step
                lo, hi = np.searchsorted(col_sorted, (col, col + 1))
                other = by_col[lo:hi][peak_tr[by_col[lo:hi]] != k]
                if not other.size:
                    break
                gap = float(np.min(np.abs(peak_d[other] - level)))
                if gap < _MERGED_M or gap >= cfg.lane_min_separation_m or last - gap < _CLOSING_M:
                    break
                found.append(col)
                last = gap
        if before or after:
            cols = before[::-1] + list(tr.cols) + after
            d = [level] * len(before) + list(tr.d) + [level] * len(after)
            out[k] = _RawTrack(cols, d, tr.slope)
    return out


_LATE_MIN_MISSED = 2  # a line unseen over this many columns or more ...
_LATE_SLOPE = 0.015  # ... moving sideways this fast (m/m, a taper's) ...
_LATE_SPREAD = 0.5  # ... may go on this share of its slope farther a missed column


def _join_late_pieces(raw: list[_RawTrack], cfg: MainlineConfig) -> list[_RawTrack]:
    """The raw tracks with each piece too short for a marking (``lane_min_track_m``)
    joined to the end of a track long enough for one that ended before it, where the
    piece lies where that track's trend carries it: at most ``lane_link_m`` behind its
    guess, and ahead of it by up to ``_LATE_SPREAD`` times its slope more for every
    column missed. The track moved at ``_LATE_SLOPE`` or faster and was unseen over
    ``_LATE_MIN_MISSED`` columns or more, within ``lane_max_gap_m``.

    A lane drop's line closes along an S, faster in its middle than where it was last
    seen, and paint is worn or missed most where it crosses the wheel paths: the linking
    guessed short of it (melbourne-408-opp-s9+80: a line last seen moving 0.17 m a column
    was seen again 7 columns on, 0.67 m beyond its guess, for two columns before it met
    the line it closes on), the piece was dropped as too short and the lane stayed open
    over 60 m. Widening the linking's own guess took the next line of a lane pattern
    shifting sideways instead (melbourne-921-s9): only a piece no track would keep is
    joined here."""
    min_cols = cfg.lane_min_track_m / cfg.lane_column_m
    max_gap = max(1, round(cfg.lane_max_gap_m / cfg.lane_column_m))
    slope_min = _LATE_SLOPE * cfg.lane_column_m
    out = list(raw)  # joined tracks are new objects: the input's are left as they are
    long_enough = [tr.cols[-1] - tr.cols[0] + 1 >= min_cols for tr in out]
    dropped: set[int] = set()
    for k in sorted(range(len(out)), key=lambda i: out[i].cols[0]):
        piece = out[k]
        if long_enough[k]:
            continue
        best, best_miss = -1, math.inf
        for j, line in enumerate(out):
            gap = piece.cols[0] - line.cols[-1]
            if j == k or j in dropped or not long_enough[j] or abs(line.slope) < slope_min:
                continue
            if not _LATE_MIN_MISSED < gap <= max_gap:
                continue
            guess = line.d[-1] + line.slope * gap
            ahead = (piece.d[0] - guess) * math.copysign(1.0, line.slope)
            reach = cfg.lane_link_m + _LATE_SPREAD * abs(line.slope) * (gap - 1)
            if -cfg.lane_link_m <= ahead <= reach and abs(ahead) < best_miss:
                best, best_miss = j, abs(ahead)
        if best >= 0:
            line = out[best]
            out[best] = _RawTrack(line.cols + piece.cols, line.d + piece.d, line.slope)
            dropped.add(k)
    return [tr for k, tr in enumerate(out) if k not in dropped]


_S_MIN_MISSED = 3  # pieces of one line this many columns apart or more ...
_S_CHORD_SLOPE = (0.015, 0.06)  # ... the straight line between them this steep (m/m) ...
_S_SLOPE_COLUMNS = 4  # ... each piece seen in this many columns, its slope over those at
# its end facing the other
_S_BACKWARDS = 0.2  # ... a share of the chord it may run against it (noise at a flat end)
_S_MONOTONE = 9.0  # ... Fritsch-Carlson: the cubic between them moves one way only
_S_STAYED_COLUMNS = 2  # ... and no line went on in between at either's offset this often


def _end_slope(track: _RawTrack, *, first: bool, n: int = _S_SLOPE_COLUMNS) -> float:
    """Least-squares slope (metres per column) over a raw track's first (last) ``n``
    columns; 0 for a single column."""
    cols = np.asarray(track.cols[:n] if first else track.cols[-n:], dtype=float)
    d = np.asarray(track.d[:n] if first else track.d[-n:], dtype=float)
    if cols.size < 2:
        return 0.0
    return float(np.polyfit(cols, d, 1)[0])


def _join_taper_pieces(raw: list[_RawTrack], cfg: MainlineConfig) -> list[_RawTrack]:
    """The raw tracks with two pieces of one line that moves sideways along an S (a lane
    taper's) joined where it went unseen in between and together they are long enough
    for a marking (``lane_min_track_m``), though one of them is not.

    The line between two pieces ``_S_MIN_MISSED`` columns apart or more (within
    ``lane_max_gap_m``) moves at a taper's rate (``_S_CHORD_SLOPE``), and each piece's own
    slope at the end facing the other goes the same way, so that the cubic through both
    ends with those slopes moves one way only (Fritsch-Carlson). A taper is slow at its
    ends and fastest in its middle: seen at its slow start and again near its end, the
    linking's guess from the first piece fell short of the second (a9-239192816-opp-s12
    with a noisier sensor: a lane closing over 125 m seen 40 m at its start and 25 m near
    its end, 35 m unseen in between, 0.7 m off the guess; both pieces dropped as too short,
    the lane was missing over 125 m). Pieces of two lines that each went on in between
    at their own offset are no taper (town06-auto-lane1-s21+440: pieces of two broken
    lines a lane apart, joined, swept a lane across over 80 m). Of several candidates the
    nearest is taken."""
    min_cols = cfg.lane_min_track_m / cfg.lane_column_m
    max_gap = max(1, round(cfg.lane_max_gap_m / cfg.lane_column_m))
    lo_slope, hi_slope = (v * cfg.lane_column_m for v in _S_CHORD_SLOPE)
    out = list(raw)
    dropped: set[int] = set()
    # every peak once: its column and offset
    peak_col = np.concatenate([np.asarray(tr.cols, dtype=np.int64) for tr in raw] or [[]])
    peak_d = np.concatenate([np.asarray(tr.d, dtype=float) for tr in raw] or [[]])

    def goes_on(c0: int, c1: int, level: float) -> bool:
        """Whether peaks near ``level`` were seen in columns ``c0:c1``: a line stayed."""
        sel = (peak_col >= c0) & (peak_col < c1) & (np.abs(peak_d - level) <= cfg.lane_link_m)
        return np.unique(peak_col[sel]).size >= _S_STAYED_COLUMNS

    def span(tr: _RawTrack) -> int:
        return tr.cols[-1] - tr.cols[0] + 1

    for k in sorted(range(len(out)), key=lambda i: out[i].cols[0]):
        piece = out[k]
        if k in dropped:
            continue
        best, best_gap = -1, max_gap + 1
        for j, line in enumerate(out):
            gap = piece.cols[0] - line.cols[-1]
            if j == k or j in dropped or not _S_MIN_MISSED <= gap <= max_gap:
                continue
            shortest = min(len(line.cols), len(piece.cols))
            if (
                shortest < _S_SLOPE_COLUMNS
                or min(span(line), span(piece)) >= min_cols
                or span(line) + gap + span(piece) - 1 < min_cols
            ):
                continue
            chord = (piece.d[0] - line.d[-1]) / gap
            if not lo_slope <= abs(chord) <= hi_slope:
                continue
            alpha = _end_slope(line, first=False) / chord
            beta = _end_slope(piece, first=True) / chord
            if min(alpha, beta) < -_S_BACKWARDS or alpha * alpha + beta * beta > _S_MONOTONE:
                continue
            between = (line.cols[-1] + 1, piece.cols[0])
            if goes_on(*between, line.d[-1]) or goes_on(*between, piece.d[0]):
                continue
            if gap < best_gap:
                best, best_gap = j, gap
        if best >= 0:
            line = out[best]
            out[best] = _RawTrack(line.cols + piece.cols, line.d + piece.d, piece.slope)
            dropped.add(k)
    return [tr for k, tr in enumerate(out) if k not in dropped]
