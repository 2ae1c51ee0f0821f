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
penalty for a rate off 0 and for changing it); each stretch of the path off 0 and of one
sign (one that goes out and comes back is two) is scaled so that the line pattern after
it matches the one before it (the pattern repeats every lane: of its matches a lane
apart, the one that leaves the lines inside the stretch straightest), and kept only where
it moves the lines by half a lane or more.

Broken lines give a window a dash or two, and the rates may catch little of a fast swing.
The outer edge, seen all through, moves with the whole pattern: where it moves by half a
lane or more, the line patterns either side match near its move and the lines a lane or
more inside it follow it rather than stay, the shift has the edge's shape
(:func:`_along_edge`).

Stations ``s`` and offsets ``d`` are metres in the reference line's frame (``d`` from the
reference edge towards the carriageway); rates are metres per metre.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from ._common import true_runs

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = ["OuterEdge", "ShiftFrame", "common_shift"]

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
STEADY_WINDOWS = 5
"""A stretch of this many windows or more whose lines each pile up best at a rate of one
sign (at least ``STEADY_RATE``, gaining ``STEADY_GAIN`` log-sharpness over rate 0) is a
shift the rate path missed, if its rates add up to ``MIN_TOTAL_M``."""
STEADY_RATE = 0.01
"""(m/m) see ``STEADY_WINDOWS``."""
STEADY_GAIN = 0.15
"""see ``STEADY_WINDOWS``."""
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
EDGE_BASE_M = 10.0
"""The outer edge's slope is taken over this length (metres) ..."""
EDGE_SLOPE = 0.01
"""... and it moves where the slope is at least this (m/m) the stretch's way."""
EDGE_STEP_SLOPE = 0.3
"""Steeper than this (m/m) the edge steps (a gore), it does not swing with the lines."""
EDGE_REACH_M = 100.0
"""A stretch is widened along the edge's move by at most this (metres) either way."""
EDGE_SEEN = 0.8
"""The edge must have been seen at this share of the stations of a widened stretch and of
the patterns either side together to witness it ..."""
EDGE_SEEN_END_M = 10.0
"""... and over at least this (metres) of each pattern beside it, for its level there."""
INSIDE_EDGE_M = 2.5
"""Only lines this far (metres) or more inside the outer edge tell a shift of the whole
pattern from a lane opening or closing at the edge, which moves the lines beside it."""
FOLLOW_M = 0.25
"""A sample lies on a line this close (metres) when lines moved and stayed are counted;
a line votes for the way it is found in more than ``FOLLOW_CLEAR`` times as many steps."""
FOLLOW_CLEAR = 2.0
FORK_STEPS = 3
"""A line found in this many steps of ``STEP_M`` off the innermost line, moved with the
pattern, forks from it: a lane opening beside the median (it votes for the move)."""
EDGE_SPAN_M = 150.0
"""A lane's shift of the whole pattern happens over at most this (metres); an edge that
moves over a longer stretch opens or closes a lane (a gore's taper), it witnesses none."""
EDGE_AGREE_M = 0.5
"""Where the outer edge witnesses a stretch, its shift is the one within this (metres) of
the edge's own move that best maps the line pattern before it onto the one after it (the
edge tells the lane, the lines the shift) ..."""
EDGE_MATCH_SHARE = 0.95
"""... if that matches at least this share as well as any shift by half a lane or more
that way, up to ``SNAP_M`` past the edge's move."""
LANE_STEP_M = 3.5
"""The line pattern repeats every lane (metres): a shift by one lane more or less matches
the patterns either side about as well."""
STRAIGHT_MARGIN_M = 20.0
"""The lines are straightened over the stretch and this far (metres) either side ..."""
STRAIGHT_GAIN = 0.3
"""... and a lane more or less than the pattern's match must pile them up sharper by at
least this (log-sharpness summed over the windows, about 2 % of a stretch's): the new
lanes' own lines move at a fraction of the shift and score for either (melbourne-921-s9
with a noisier sensor, seed offset 20: a 6.8 m shift, right, lost to 3.3 m by 0.19)."""


@dataclass(frozen=True)
class OuterEdge:
    """The outer road edge as a witness of the shift: offsets ``d`` (metres, reference
    frame, NaN where no edge point was seen) at ``stations`` (metres, increasing)."""

    stations: FloatArray
    d: FloatArray

    @cached_property
    def seen(self) -> NDArray[np.bool_]:
        """Where an edge point was seen."""
        return np.isfinite(self.d)

    def at(self, s: FloatArray) -> FloatArray:
        """The edge's offset (metres) at stations ``s``, linear across where it was not
        seen."""
        return np.interp(s, self.stations[self.seen], self.d[self.seen])

    @cached_property
    def slope(self) -> FloatArray:
        """The edge's slope (m/m) at its stations over ``EDGE_BASE_M``."""
        half = 0.5 * EDGE_BASE_M
        return (self.at(self.stations + half) - self.at(self.stations - half)) / EDGE_BASE_M


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
    edge: OuterEdge | None = None,
) -> ShiftFrame | None:
    """The shift of the marking pattern along the run; None where it never shifts by
    ``MIN_TOTAL_M`` or more.

    The rates the lines show catch only part of a shift where they are broken lines with
    few dashes in a window (town06-auto-s1: 0.5 of 3.5 m). The outer edge is seen all
    through and moves with the whole pattern (a swing after an inner exit, lanes added
    beside the median): where it moves the stretch's way, the stretch is widened to where
    the edge starts and stops moving, the line patterns either side are matched near the
    edge's move (the edge tells which lane the pattern shifted by, the lines by how much),
    and where the lines inside follow the edge the shift has the edge's shape.

    Parameters
    ----------
    s, d
        Stations and offsets of the lane-marking samples (metres, reference frame).
    length
        Road length (metres).
    peak_s, peak_d, peak_track
        The histogram peaks linked into tracks (:func:`.linking._link_tracks`): station
        and offset (metres) of each peak and the track it belongs to. A line weighs the
        same in a window however many samples it has there (a solid line no more than a
        broken one): its samples are those nearest to its peaks.
    column_m
        Spacing of the histogram columns along the station (metres).
    edge
        The outer road edge (same frame); None: the rates and patterns alone.
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
    shaped = np.zeros(mids.size)  # the rates of stretches the edge shapes
    # the edge's own moves first (the rates may have caught none of a fast swing), then
    # the rate path's stretches where the edge moves too
    if edge is not None and np.count_nonzero(edge.seen) >= 2:
        seeds = _edge_runs(edge) + [
            (mids[a] - 0.5 * STEP_M, mids[b - 1] + 0.5 * STEP_M, float(np.sum(rate[a:b])))
            for a, b in true_runs(rate != 0.0)
        ]
        for s_a, s_b, way in seeds:
            if np.any(shaped[(mids >= s_a) & (mids <= s_b)] != 0.0):
                continue
            along = _along_edge(s, d, owner, mids, s_a, s_b, way, edge)
            if along is not None and not np.any((along != 0.0) & (shaped != 0.0)):
                shaped += along
    rate[shaped != 0.0] = 0.0

    def checked(rates: FloatArray, a: int, b: int, follow: bool) -> FloatArray | None:
        """The rates of windows ``a:b`` scaled to the shift the line patterns either side
        agree on; None where that is under ``MIN_TOTAL_M``, a line stays through it, or
        (``follow``) the lines seen before it are not found moved inside it."""
        total = float(np.sum(rates)) * STEP_M
        s_a, s_b = mids[a] - 0.5 * STEP_M, mids[b - 1] + 0.5 * STEP_M
        patterns = _line_patterns(s, d, owner, s_a, s_b, PATTERN_M)
        matched = _pattern_shift(s, d, owner, s_a, s_b, total, patterns=patterns)
        if matched is not None and abs(total) > 1e-9:
            matched = _straightest(s, d, owner, rates, s_a, s_b, matched, patterns)
            rates = rates * (matched / total)
            total = matched
        if abs(total) < MIN_TOTAL_M or _a_line_stays(peak_s, peak_d, peak_track, s_a, s_b):
            return None
        if follow and not _lines_follow(s, d, owner, s_a, s_b, _stretch_move(rates, s_a), np.inf):
            return None
        return rates

    for a, b in _one_way_runs(rate):
        if np.any(shaped[max(a - 1, 0) : b + 1] != 0.0):
            rate[a:b] = 0.0  # the rest of a stretch the edge shaped
            continue
        kept = checked(rate[a:b], a, b, follow=False)
        rate[a:b] = 0.0 if kept is None else kept
    # then the steady stretches no shift found so far touches
    best = _best_rates(sharp, RATES)
    for a, b in _steady_stretches(sharp, RATES, best, (rate != 0.0) | (shaped != 0.0)):
        kept = checked(best[a:b], a, b, follow=True)
        if kept is not None:
            rate[a:b] = kept
    if not np.any(rate != 0.0) and not np.any(shaped != 0.0):
        return None
    # the path leaves 0 late and comes back early (the gentle ends of a shift gain too
    # little sharpness), and is steeper in between: spread it as far as it is short
    kernel = np.bartlett(2 * SPREAD_WINDOWS + 3)[1:-1]
    rate = np.convolve(rate, kernel / kernel.sum(), mode="same") + shaped
    # what the lines still do in that frame, found the same way at finer rates
    first_pass = ShiftFrame(mids, _integrate(rate))
    residual = _sharpness(s, d - first_pass.offset(s), owner, mids, FINE_RATES)
    if residual is not None:
        fine = _rate_path(residual, FINE_RATES)
        for a, b in _one_way_runs(rate):
            # the refined shape, with the total the line patterns either side agree on
            # (the edge's shape too: a smoothed fit, it leads or trails the lines a little)
            total = float(np.sum(rate[a:b]))
            refined = rate[a:b] + fine[a:b]
            if abs(float(np.sum(refined))) > 1e-9:
                rate[a:b] = refined * (total / float(np.sum(refined)))
    return ShiftFrame(mids, _integrate(rate))


def _one_way_runs(rate: FloatArray) -> list[tuple[int, int]]:
    """Index ranges ``[a, b)`` of the windows whose rates are off 0 and of one sign.

    A stretch of the rate path that goes out and comes back (a lane added beside the
    median by a taper and dropped at an inner exit soon after) is two shifts: scaled as
    one to the small total its ends agree on, its rates were multiplied many times over
    (town06-auto-lane2-s22 with a noisier sensor: a 3.7 m swing came out as 7.6 m, every
    line a lane off for 80 m).
    """
    return sorted(true_runs(rate > 0.0) + true_runs(rate < 0.0))


def _edge_runs(edge: OuterEdge) -> list[tuple[float, float, float]]:
    """``(s_a, s_b, way)`` of every stretch (metres) where the outer edge moves one way
    (``EDGE_SLOPE``, ``way`` +-1) by ``MIN_TOTAL_M`` or more from its start to its end."""
    g = edge.stations
    out = []
    for way in (1.0, -1.0):
        for i, j in true_runs(way * edge.slope >= EDGE_SLOPE):
            ends = edge.at(g[[i, j - 1]])
            if way * float(ends[1] - ends[0]) >= MIN_TOTAL_M:
                out.append((float(g[i]), float(g[j - 1]), way))
    return sorted(out)


def _along_edge(
    s: FloatArray,
    d: FloatArray,
    owner: IntArray,
    mids: FloatArray,
    s_a: float,
    s_b: float,
    way: float,
    edge: OuterEdge,
) -> FloatArray | None:
    """The rates (m/m, one per window of ``mids``) of a stretch ``[s_a, s_b]`` (metres)
    that moves the lines ``way`` (its sign) where the outer edge witnesses it: the edge
    moves that way there, the stretch is widened to where it starts and stops moving, the
    line patterns either side match near the edge's move (``EDGE_AGREE_M``,
    ``EDGE_MATCH_SHARE``), by ``MIN_TOTAL_M`` or more, and the lines inside it follow the
    edge rather than stay (:func:`_lines_follow`). The rates follow the edge's shape,
    scaled to the patterns' shift. None where the edge does not witness the stretch."""
    if way == 0.0:
        return None
    moved = _edge_move(edge, s_a, s_b, way)
    if moved is None:
        return None
    e_a, e_b, e_total, level = moved
    if abs(e_total) < MIN_TOTAL_M - EDGE_AGREE_M:
        return None
    matched = _pattern_shift(s, d, owner, e_a, e_b, e_total, near_m=EDGE_AGREE_M)
    if matched is None or abs(matched) < MIN_TOTAL_M:
        return None
    start = float(edge.at(e_a))
    e_made = float(edge.at(e_b)) - start
    if way * e_made <= 0.0:
        return None
    move = lambda x: (edge.at(np.clip(x, e_a, e_b)) - start) * (matched / e_made)  # noqa: E731
    if not _lines_follow(s, d, owner, e_a, e_b, move, level - INSIDE_EDGE_M):
        return None
    lo = mids - 0.5 * STEP_M
    return (move(mids + 0.5 * STEP_M) - move(lo)) / STEP_M


def _lines_follow(
    s: FloatArray,
    d: FloatArray,
    owner: IntArray,
    s_a: float,
    s_b: float,
    move: Callable[[FloatArray], FloatArray],
    inside_of: float,
) -> bool:
    """Whether the lines seen before a stretch ``[s_a, s_b]`` (metres; over twice
    ``PATTERN_M``, broken lines are sparse) and lying inside ``inside_of`` (metres, a lane
    inside the outer edge) are found inside it moved by ``move(s)`` (metres) rather than
    where they were. Counted where the moved lines lie ``2 * FOLLOW_M`` or more from where
    they were and from where they end (a lane's shift brings each line to the next one's
    place): a line is found in a step of ``STEP_M`` where a sample lies within
    ``FOLLOW_M`` of it, and votes for where it is found ``FOLLOW_CLEAR`` times as often;
    more lines must vote for the move than against it, and more than half of them. A lane
    opening or closing at the outer edge moves the edge and the lines beside it alone
    (the edge line and a shoulder's split, soderleden-s7, Town06's entries) while the lane
    lines stay; a swing or a lane added beside the median moves all lines but the
    innermost (which does not vote). Lines vote, not samples: a solid line must not
    outweigh broken ones."""
    before = (s >= s_a - 2.0 * PATTERN_M) & (s < s_a) & (owner >= 0)
    if not before.any():
        return False
    tracks, inverse, counts = np.unique(owner[before], return_inverse=True, return_counts=True)
    medians = np.array([np.median(d[before][inverse == k]) for k in range(tracks.size)])
    # the innermost line stays in every case: it does not vote, however few of its dashes
    # were seen (town06-auto-s2 with a noisier sensor: the inner shoulder's line had two
    # samples, the next line out was taken for the innermost and no line was left to vote)
    innermost = float(np.min(medians))
    lines = np.sort(medians[counts >= 3])
    # one line seen as two tracks votes once
    lines = (
        lines[np.concatenate([[True], np.diff(lines) >= 2.0 * FOLLOW_M])] if lines.size else lines
    )
    # nor do the lines beside the edge
    lines = lines[(lines >= innermost + 2.0 * FOLLOW_M) & (lines <= inside_of)]
    # only where the moved lines lie apart from where they were and from the next line's
    # place (a shift by a lane brings each line to the next one's)
    s_in, d_in = s[(s >= s_a) & (s <= s_b)], d[(s >= s_a) & (s <= s_b)]
    made = move(s_in)
    total = float(move(np.array([s_b]))[0])
    apart = (np.abs(made) >= 2.0 * FOLLOW_M) & (np.abs(total - made) >= 2.0 * FOLLOW_M)
    if lines.size == 0 or not apart.any():
        return False
    s_in, d_in, made = s_in[apart], d_in[apart], made[apart]
    step = np.floor((s_in - s_a) / STEP_M).astype(np.int64)

    def found(at: FloatArray, shift: FloatArray) -> IntArray:
        """Per line of ``at``: in how many steps of ``STEP_M`` a sample lies on it."""
        near = np.abs(d_in[:, None] - (at[None, :] + shift[:, None])) < FOLLOW_M
        hit_step, hit_line = np.nonzero(near)
        pairs = np.unique(step[hit_step] * at.size + hit_line)
        return np.bincount(pairs % at.size, minlength=at.size)

    moved, stayed = found(lines, made), found(lines, np.zeros(s_in.size))
    # a line votes where it is found clearly more often one way; most lines must vote
    # for the move (a line seen on one side only, or as often either way, does not)
    for_move = int(np.sum(moved > FOLLOW_CLEAR * stayed))
    against = int(np.sum(stayed > FOLLOW_CLEAR * moved))
    # the innermost line stays, but a line forking off it (joining it) and moving with
    # the pattern is a lane opening (closing) beside the median, which a lane opening at
    # the edge never makes: it votes for the move, and the lines that are not found
    # either way (worn, out of reach) no longer count against it (melbourne-1019-s11+920:
    # the only line a lane out was worn over the 60 m it moved, 0.69 m lane RMSE there)
    fork = bool(found(np.array([innermost]), made - min(total, 0.0))[0] >= FORK_STEPS)
    return for_move + int(fork) > against and (fork or 2 * for_move > lines.size)


def _edge_move(
    edge: OuterEdge, s_a: float, s_b: float, total: float
) -> tuple[float, float, float, float] | None:
    """``(s_a', s_b', move, level)``: the stretch ``[s_a, s_b]`` (metres) widened to where
    the outer edge starts and stops moving the way of ``total`` through it, how far
    (metres) the edge moved (median over ``PATTERN_M`` after less before) and its level
    before (that median, metres). None where the edge does not move that way inside the
    stretch, moves on beyond ``EDGE_REACH_M``, steps (``EDGE_STEP_SLOPE``) or was seen too
    little (``EDGE_SEEN``, ``EDGE_SEEN_END_M``)."""
    g, e, seen, slope = edge.stations, edge.d, edge.seen, edge.slope
    moving = np.sign(total) * slope >= EDGE_SLOPE
    runs = [(g[i], g[j - 1]) for i, j in true_runs(moving) if g[j - 1] >= s_a and g[i] <= s_b]
    if not runs:
        return None
    new_a, new_b = min(s_a, runs[0][0]), max(s_b, runs[-1][1])
    if new_a < s_a - EDGE_REACH_M or new_b > s_b + EDGE_REACH_M or new_b - new_a > EDGE_SPAN_M:
        return None
    inside = (g >= new_a) & (g <= new_b)
    if float(np.max(np.abs(slope[inside]))) > EDGE_STEP_SLOPE:
        return None
    before = (g >= new_a - PATTERN_M) & (g < new_a)
    after = (g > new_b) & (g <= new_b + PATTERN_M)
    around = before | inside | after
    if not before.any() or not after.any():
        return None
    if float(np.mean(seen[around])) < EDGE_SEEN:
        return None
    # either side, enough of it seen for its level: an occlusion right after the move
    # (melbourne-1019-lane1-s21 with a noisier sensor, seed offset 200: the edge seen on
    # 14 of the 30 m after a lane added beside the median) leaves the level seen there
    step = float(np.median(np.diff(g))) if g.size >= 2 else 1.0
    if min(np.count_nonzero(seen[m]) * step for m in (before, after)) < EDGE_SEEN_END_M:
        return None
    level = float(np.median(e[before & seen]))
    return new_a, new_b, float(np.median(e[after & seen])) - level, level


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
    inside it. The innermost line's peaks, where it is seen staying through the stretch's
    middle too, are none of those (a9-206615404-opp-s4 with a noisier sensor: an exit's
    lane and shoulder diverging over a 30 m gap of the outer edge, the lines inside
    staying, were taken for a shift of the whole pattern; in its frame the exit's line was
    no ramp line, and the mainline's edge followed the ramp 30 m past the gore, 7 m off)."""
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
    steady = seen_before & seen_after & (spread <= STAY_M)
    stays = steady & (med >= inner + STAY_INNER_M)
    if not stays.any():
        return False
    # the innermost line, seen staying through the stretch's middle too, is no moving
    # line inside it (a track linked across a shift at one offset hops from one moving
    # line to the next: it has no peaks where they are halfway)
    third = (s_b - s_a) / 3.0
    middle = np.zeros(n, dtype=bool)
    middle[inverse[(s_w > s_a + third) & (s_w < s_b - third)]] = True
    kept = stays | (steady & middle)
    inside = (s_w >= s_a) & (s_w <= s_b) & ~kept[inverse]
    off_lines = np.min(np.abs(d_w[inside, None] - med[kept][None, :]), axis=1) > STAY_M
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
    gain = _log_gain(sharp, rates)
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


def _log_gain(sharp: FloatArray, rates: FloatArray) -> FloatArray:
    """``(windows, rates)``: the log-sharpness (``sharp``, :func:`_sharpness`) each rate of
    ``rates`` gains over rate 0 in each window."""
    zero = int(np.argmin(np.abs(rates)))
    return np.log(sharp + 0.05) - np.log(sharp[:, zero : zero + 1] + 0.05)


def _best_rates(sharp: FloatArray, rates: FloatArray) -> FloatArray:
    """Each window's rate of ``rates`` (m/m) at which its lines pile up most sharply
    (``sharp``: see :func:`_sharpness`)."""
    return rates[np.argmax(sharp, axis=1)]


def _steady_stretches(
    sharp: FloatArray, rates: FloatArray, best: FloatArray, taken: NDArray[np.bool_]
) -> list[tuple[int, int]]:
    """Window ranges ``a:b`` of ``STEADY_WINDOWS`` or more, none ``taken``, whose lines
    pile up best at rates of one sign (``STEADY_RATE`` or more, gaining ``STEADY_GAIN``
    log-sharpness over rate 0) that add up to ``MIN_TOTAL_M`` (``best``: each window's
    best rate, :func:`_best_rates`).

    A few dashes per window gain little sharpness at any rate; the rate path pays
    ``RATE_PRIOR`` per window off 0 and ``RATE_CHANGE`` for following the S of a fast
    shift, and stays at 0 though window after window piles up best at rates of one sign
    (town06-auto-s3 with a noisier sensor: nine windows at 0.015-0.145 m/m, 2.3 m in all,
    over a lane added beside the median; the tracks swapped lines there, lanes 3.5 m off
    over 40 m). Such a stretch is checked like the path's own, and the lines seen before it
    must be found moved inside it (:func:`_lines_follow`): with sparse dashes the best
    rates of a few windows may lean one way by chance, and a pattern shifted by a lane
    matches itself."""
    best_gain = np.max(_log_gain(sharp, rates), axis=1)
    found: list[tuple[int, int]] = []
    for sign in (1.0, -1.0):
        one_way = (sign * best >= STEADY_RATE) & (best_gain >= STEADY_GAIN) & ~taken
        found += [
            (a, b)
            for a, b in true_runs(one_way)
            if b - a >= STEADY_WINDOWS and abs(float(np.sum(best[a:b]))) * STEP_M >= MIN_TOTAL_M
        ]
    return found


def _stretch_move(rates: FloatArray, s_a: float) -> Callable[[FloatArray], FloatArray]:
    """The shift (metres) made at stations ``x`` (metres) by the ``rates`` (m/m) of the
    windows of a stretch from ``s_a`` on, one per ``STEP_M``."""
    knots = s_a + STEP_M * np.arange(rates.size + 1)
    made = np.concatenate([[0.0], np.cumsum(rates) * STEP_M])
    return lambda x: np.interp(x, knots, made)


def _line_patterns(
    s: FloatArray, d: FloatArray, owner: IntArray, s_a: float, s_b: float, reach: float
) -> tuple[FloatArray, FloatArray] | None:
    """The line patterns over ``reach`` (metres) before ``s_a`` and after ``s_b``: per
    ``BIN_M`` offset bin, each line's samples weighing one line in all, smoothed; None
    without lines on either side."""
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

    before = pattern(s_a - reach, s_a)
    after = pattern(s_b, s_b + reach)
    return None if before is None or after is None else (before, after)


def _pattern_shift(
    s: FloatArray,
    d: FloatArray,
    owner: IntArray,
    s_a: float,
    s_b: float,
    total: float,
    near_m: float | None = None,
    patterns: tuple[FloatArray, FloatArray] | None = None,
) -> float | None:
    """The shift (metres) that best maps the line pattern over ``PATTERN_M`` before
    ``s_a`` onto the one after ``s_b``, within ``SNAP_M`` of ``total``; None without lines
    on either side. The rates integrate to a total a few tenths short or long (a window's
    sharpest rate averages over the window); the patterns say it to a bin. With
    ``near_m`` (metres): the best shift within that of ``total`` (the outer edge's move,
    which tells the lane), None where it matches less than ``EDGE_MATCH_SHARE`` as well
    as the best shift by ``MIN_TOTAL_M`` up to ``SNAP_M`` past ``total`` that way.
    ``patterns``: :func:`_line_patterns` over ``PATTERN_M`` already made (without
    ``near_m``)."""
    # near the edge's move the patterns are compared over twice the length: no other
    # lane's shift competes, and broken lines give few dashes over one
    if patterns is None:
        reach = PATTERN_M if near_m is None else 2.0 * PATTERN_M
        patterns = _line_patterns(s, d, owner, s_a, s_b, reach)
    if patterns is None:
        return None
    before, after = patterns
    n_bin = before.size
    lo, hi = total - SNAP_M, total + SNAP_M
    if near_m is not None:
        # every shift by half a lane or more the edge's way up to past its move competes
        # (an entry beside the edge moved it a lane farther than the lines went)
        lo, hi = (MIN_TOTAL_M, hi) if total > 0.0 else (lo, -MIN_TOTAL_M)
    shifts = np.round(np.arange(lo, hi + 1e-9, BIN_M) / BIN_M).astype(np.int64)
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
    if near_m is None:
        return float(shifts[int(np.argmax(score))] * BIN_M)
    close = np.abs(shifts * BIN_M - total) <= near_m + 1e-9
    if not close.any() or float(np.max(score[close])) < EDGE_MATCH_SHARE * float(score.max()):
        return None
    return float(shifts[close][int(np.argmax(score[close]))] * BIN_M)


def _straightest(
    s: FloatArray,
    d: FloatArray,
    owner: IntArray,
    rates: FloatArray,
    s_a: float,
    s_b: float,
    matched: float,
    patterns: tuple[FloatArray, FloatArray] | None = None,
) -> float:
    """Of the shift ``matched`` (metres) and the pattern's best matches a lane more and
    a lane less the same way (at least ``MIN_TOTAL_M``), the one whose move (``rates``
    of the stretch ``s_a``-``s_b``, m/m, scaled to it) leaves the lines in the stretch
    straightest: the line patterns either side repeat every lane, and the rates, short of
    a long swing's gentle ends, may sum to a lane less than the lines moved
    (melbourne-921-s9 with a noisier sensor, seed offset 500: two lanes added beside the
    median, the pattern shifted by 7.0 m, the rates said 5.1 m and the pattern snapped to
    3.6 m, the lines linked a lane apart from their own; -s2+560: one lane added, the
    pattern snapped to 6.8 m). ``matched`` unless another piles the lines up sharper by
    ``STRAIGHT_GAIN``, or where the lines in the stretch are not seen. ``patterns``: the
    stretch's :func:`_line_patterns` over ``PATTERN_M`` if already made."""
    if abs(matched) < MIN_TOTAL_M:
        return matched
    if patterns is None:
        patterns = _line_patterns(s, d, owner, s_a, s_b, PATTERN_M)
    total = float(np.sum(rates)) * STEP_M
    lo, hi = s_a - STRAIGHT_MARGIN_M, s_b + STRAIGHT_MARGIN_M
    sel = (s >= lo) & (s <= hi) & (owner >= 0)
    if np.count_nonzero(sel) < 20:
        return matched
    mids = np.arange(lo + 0.5 * WINDOW_M, hi - 0.5 * WINDOW_M + 1e-9, STEP_M)
    if mids.size < 2:
        return matched
    candidates = [matched]
    for k in (-1.0, 1.0):
        other = _pattern_shift(s, d, owner, s_a, s_b, matched + k * LANE_STEP_M, patterns=patterns)
        if (
            other is not None
            and np.sign(other) == np.sign(matched)
            and abs(other) >= MIN_TOTAL_M
            and abs(other - matched) >= 0.5 * LANE_STEP_M
        ):
            candidates.append(other)
    if len(candidates) == 1:
        return matched
    # in the stretch's own station frame: its first window at 0 (as :func:`_sharpness` wants)
    s_in, d_in, owner_in = s[sel], d[sel], owner[sel]
    scores = []
    for cand in candidates:
        move = _stretch_move(rates * (cand / total), s_a)
        sharp = _sharpness(s_in - lo, d_in - move(s_in), owner_in, mids - lo, np.zeros(1))
        scores.append(-np.inf if sharp is None else float(np.sum(np.log(sharp[:, 0] + 0.05))))
    best = int(np.argmax(scores))
    return float(candidates[best]) if scores[best] >= scores[0] + STRAIGHT_GAIN else matched
