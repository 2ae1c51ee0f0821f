"""The median-side edge where the run does not see it: it moves with the lines it does.

At a gore on the median side whose edge the run does not see beyond it (an inner exit
whose mainline edge is unseen for tens of metres after the nose, an inner entry's before
it), :func:`~.reference.fit_median_edge` can only carry the edge across at the level it
has where it is seen again. Real layouts drop the exiting lane there and let the lanes
swing back towards the median over the next 50-100 m (Town06): the edge carried across
lay 3.3 m off, and the space between it and the lanes became an invented lane tapering
to zero. The lines the car does see say where the lanes go: the innermost one seen from
inside the unseen stretch out to where the edge is seen again keeps its distance from
the edge there, so the edge follows it (:func:`edge_moves`). A line that does not move
leaves the edge as it was (an occlusion of the edge alone).

Away from gores, across any stretch where the edge is unseen (:func:`unseen_stretches`),
the fit carries the edge along the course of its smoothed frame while the inner
shoulder's line, where the car sees it, says where the edge went: the shoulder keeps a
width linear between the stretch's ends beside that line (:func:`shoulder_moves`), as
the outer edge keeps the hard shoulder's (:func:`~.outer_edge._bridge_edge_gaps`); where
that line is seen only part of the way in (it leaves for an inner exit inside the stretch),
as far as it goes, and linearly from there to where the edge is seen again. The
lanes are then fitted again with the edge moved and the centre lane's offset carries the
move (:func:`with_edge_moves`).

Stations are metres along the reference line; offsets ``d`` metres from the reference
edge towards the carriageway (the lanes' frame, :func:`~.lanes.fit_lanes`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..model import CubicPiece, CubicProfile
from ._common import BoundaryTrack, true_runs

FloatArray = NDArray[np.float64]

__all__ = [
    "edge_moves",
    "moves_beside_steps",
    "shoulder_moves",
    "unseen_stretches",
    "with_edge_moves",
]

MIN_MOVE_M = 1.5
"""A seen line moving less than this (metres) inside the unseen stretch leaves the edge
where the fit put it: noise and a curve's smoothing are smaller, a lane is larger."""
SEEN_BEYOND_M = 10.0
"""The line must be seen this far (metres) beyond the unseen stretch, where the edge is
seen too: its distance from the edge there is the one kept."""
GAP_MIN_M = 20.0
"""An unseen stretch of the median-side edge at least this long (metres) is bridged along
its shoulder line (:func:`shoulder_moves`)."""
SHOULDER_MAX_M = 2.0
"""A line at most this far (metres) from the edge at both ends of the stretch is the inner
shoulder's line: no lane lies between them."""
SEEN_SHARE = 0.6
"""The share of the stretch's 5 m bins in which the shoulder line must be seen."""
THROUGH_SAME_M = 0.5
"""A lane line whose distance from the edge at the two ends of an unseen stretch differs
by at most this (metres) runs parallel to it through the stretch."""
THROUGH_BIN_M = 20.0
"""Bins (metres) in which a dashed lane line must be seen across an unseen stretch: longer
than a dash period (12 m in the US, 18 m in Germany)."""
MIN_SHOULDER_MOVE_M = 0.25
"""A shoulder's line that takes the edge less than this far (metres) from where the fit
put it leaves it there: the fit's bridging is as good as the line's noise (moves of 1-50
mm on the bundled scenarios, 0.8-1.3 m where a line wandered)."""
LINE_NEAR_M = 0.3
"""A lane sample this close (metres) to a track is the track's."""
LINE_SEEN_SHARE = 0.4
"""The share of a stretch's 5 m bins in which a lane line beside a step must be seen
(:func:`moves_beside_steps`; a dashed line is seen on its dashes only)."""
PART_SHORT_M = 10.0
"""A shoulder's line seen from one end of an unseen stretch must end at least this short
(metres) of the other end to be a part (:func:`_partial_line`): one seen (nearly) through
is a line through, whose distance from the edge at the far end says otherwise."""
KNOT_M = 4.0
"""Spacing (metres) of the lane-offset records that carry a move (linear in between)."""


def edge_moves(
    unseen: FloatArray, tracks: tuple[BoundaryTrack, ...], grid: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """How far the median-side edge moves towards the carriageway where it is unseen
    beside a gore.

    Parameters
    ----------
    unseen
        ``(k, 2)`` rows of (gore station, station where the edge is seen again), metres:
        after an exit's gore the second is larger, before an entry's smaller
        (:attr:`~.reference.MedianEdge.unseen_beside_gores`).
    tracks
        The marking tracks of a first lane fit (offsets ``d`` towards the carriageway).
    grid
        Stations (metres) of the lane fit.

    Returns
    -------
    ``(G,)`` the move on ``grid`` (metres towards the carriageway, 0 outside the unseen
    stretches) and the gore stations where a move begins (ends) at full size: the edge
    steps there, a lane ending (beginning) at full width.
    """
    move = np.zeros(grid.size)
    gores: list[float] = []
    for gore, far in np.asarray(unseen, dtype=float).reshape(-1, 2):
        lo, hi = min(gore, far), max(gore, far)
        beyond = (far, far + SEEN_BEYOND_M) if far > gore else (far - SEEN_BEYOND_M, far)
        seen = [
            tr
            for tr in tracks
            if tr.n_samples > 0
            and tr.s_m[0] <= min(lo, beyond[0])
            and tr.s_m[-1] >= max(hi, beyond[1])
        ]
        if not seen:
            continue
        # the innermost line where the edge is seen again
        line = min(seen, key=lambda tr: float(np.interp(far, tr.s_m, tr.d_m)))
        inside = (grid >= lo) & (grid <= hi)
        delta = np.interp(grid[inside], line.s_m, line.d_m) - np.interp(far, line.s_m, line.d_m)
        if delta.size == 0 or float(np.max(delta)) < MIN_MOVE_M:
            continue
        move[inside] = np.maximum(move[inside], np.clip(delta, 0.0, None))
        gores.append(float(gore))
    return move, np.sort(np.asarray(gores, dtype=float))


def unseen_stretches(
    s_edge: FloatArray,
    d_edge: FloatArray,
    grid: FloatArray,
    d_median: FloatArray,
    on_edge_m: float,
) -> list[tuple[int, int]]:
    """Grid index ranges ``[a, b)`` over which no median-side edge point lies on the edge
    (``d_median`` on ``grid``, within ``on_edge_m``), at least :data:`GAP_MIN_M` long and
    with the edge seen on both sides. ``s_edge``, ``d_edge``: the edge points' stations and
    offsets (metres, towards the carriageway)."""
    on = np.abs(d_edge - np.interp(s_edge, grid, d_median)) < on_edge_m
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    idx = np.clip(np.round((s_edge[on] - grid[0]) / step).astype(int), 0, grid.size - 1)
    seen = np.zeros(grid.size, dtype=bool)
    seen[idx] = True
    out = []
    for a, b in true_runs(~seen):
        if a > 0 and b < grid.size and (b - a) * step >= GAP_MIN_M:
            out.append((a, b))
    return out


def _seen_share(
    tr: BoundaryTrack,
    s_lane: FloatArray,
    d_lane: FloatArray,
    lo: float,
    hi: float,
    bin_m: float = 5.0,
) -> float:
    """The share of the ``bin_m`` bins from ``lo`` to ``hi`` (stations, metres) in which a
    lane sample (``s_lane``, ``d_lane``) lies within :data:`LINE_NEAR_M` of the track
    ``tr``; 0 for an empty stretch."""
    inside = (s_lane >= lo) & (s_lane <= hi)
    near = inside & (np.abs(d_lane - np.interp(s_lane, tr.s_m, tr.d_m)) < LINE_NEAR_M)
    seen = np.histogram(s_lane[near], np.arange(lo, hi + bin_m, bin_m))[0] > 0
    return float(np.mean(seen)) if seen.size else 0.0


def _line_through(
    tracks: tuple[BoundaryTrack, ...],
    s_lane: FloatArray,
    d_lane: FloatArray,
    grid: FloatArray,
    d_median: FloatArray,
    i0: int,
    i1: int,
) -> tuple[BoundaryTrack, float, float] | None:
    """The line the median-side edge keeps its distance to across the unseen stretch
    between grid stations ``i0`` and ``i1`` (where it was last and first seen), with its
    distances from the edge there (metres): the inner shoulder's line (at most
    :data:`SHOULDER_MAX_M` from the edge at both ends) seen in :data:`SEEN_SHARE` of its
    5 m bins, else the innermost lane line as far from the edge at both ends (within
    :data:`THROUGH_SAME_M`) seen in that share of :data:`THROUGH_BIN_M` bins (dashes
    12-18 m apart): no lane begins or ends beside the median there, the lanes run on
    parallel to the edge. None where neither was seen."""
    lo, hi = float(grid[i0]), float(grid[i1])
    shoulder, through = [], []
    for tr in tracks:
        if tr.n_samples == 0 or tr.s_m[0] > lo or tr.s_m[-1] < hi:
            continue
        w0 = float(np.interp(lo, tr.s_m, tr.d_m)) - d_median[i0]
        w1 = float(np.interp(hi, tr.s_m, tr.d_m)) - d_median[i1]
        if 0.0 < w0 <= SHOULDER_MAX_M and 0.0 < w1 <= SHOULDER_MAX_M:
            shoulder.append((tr, w0, w1))
        elif w0 > 0.0 and abs(w1 - w0) <= THROUGH_SAME_M:
            through.append((tr, w0, w1))
    if shoulder:
        best = min(shoulder, key=lambda c: c[1])
        if _seen_share(best[0], s_lane, d_lane, lo, hi) >= SEEN_SHARE:
            return best
    for cand in sorted(through, key=lambda c: c[1]):
        if _seen_share(cand[0], s_lane, d_lane, lo, hi, THROUGH_BIN_M) >= SEEN_SHARE:
            return cand
    return None


def shoulder_moves(
    gaps: list[tuple[int, int]],
    tracks: tuple[BoundaryTrack, ...],
    s_lane: FloatArray,
    d_lane: FloatArray,
    grid: FloatArray,
    d_median: FloatArray,
) -> FloatArray:
    """How far the median-side edge moves (metres towards the carriageway, on ``grid``)
    across each unseen stretch ``gaps`` (:func:`unseen_stretches`) where the inner
    shoulder's line is seen through it: the shoulder keeps a width linear between the
    stretch's ends beside that line, instead of the edge holding the course the smoothed
    fit gave it (a9-239192816-opp-s12 with a noisier sensor: the line wandered 1 m over a
    90 m stretch, the edge bridged straight lay 0.8 m off). The line is the innermost
    track at most :data:`SHOULDER_MAX_M` from the edge at both ends and seen in
    :data:`SEEN_SHARE` of the stretch (``s_lane``, ``d_lane``: the lane samples, metres),
    else the innermost lane line as far from the edge at both ends and seen through
    (:func:`_line_through`; oakland-28393854-s7 with a noisier sensor: the shoulder's
    line seen in a third of a 145 m stretch, the edge bent 0.8 m with the car's frame);
    a move under :data:`MIN_SHOULDER_MOVE_M` is left out. Where the shoulder's line is
    seen only part of the way in from an end, the edge keeps beside it that far
    (:func:`_beside_partial_lines`).
    Where no such line is seen the edge stays as fitted (a lane gained or dropped beside
    the median moves the lines beyond the shoulder's, not the edge)."""
    move = np.zeros(grid.size)
    for a, b in gaps:
        i0, i1 = a - 1, b
        best = _line_through(tracks, s_lane, d_lane, grid, d_median, i0, i1)
        if best is None:
            move[a:b] = _beside_partial_lines(tracks, (s_lane, d_lane), grid, d_median, (i0, i1))
            continue
        tr, w0, w1 = best
        g = grid[a:b]
        line = np.interp(g, tr.s_m, tr.d_m)
        x = (g - grid[i0]) / (grid[i1] - grid[i0])
        shift = line - ((1.0 - x) * w0 + x * w1) - d_median[a:b]
        if float(np.max(np.abs(shift))) >= MIN_SHOULDER_MOVE_M:
            move[a:b] = shift
    return move


def _partial_line(
    tracks: tuple[BoundaryTrack, ...],
    samples: tuple[FloatArray, FloatArray],
    grid: FloatArray,
    d_median: FloatArray,
    i_seen: int,
    i_far: int,
) -> tuple[BoundaryTrack, float, float] | None:
    """The inner shoulder's line seen from grid station ``i_seen`` (an end of an unseen
    stretch, where the edge was seen) part of the way towards ``i_far`` (the other end),
    with its distance from the edge at ``i_seen`` and the station where it ends inside
    the stretch (metres): the innermost track at most :data:`SHOULDER_MAX_M` from the
    edge there that reaches at least :data:`GAP_MIN_M` into the stretch and ends
    :data:`PART_SHORT_M` or more short of its other end, seen in
    :data:`SEEN_SHARE` of the 5 m bins of that part (``samples``: the lane samples'
    stations and offsets, metres). None where there is none."""
    at, far = float(grid[i_seen]), float(grid[i_far])
    forward = far > at
    best = None
    for tr in tracks:
        if tr.n_samples == 0 or tr.s_m[0] > at or tr.s_m[-1] < at:
            continue
        end = float(tr.s_m[-1]) if forward else float(tr.s_m[0])
        if abs(end - at) < GAP_MIN_M or (end - far) * (1.0 if forward else -1.0) > -PART_SHORT_M:
            continue  # too short to say, or seen (nearly) through: not a part
        width = float(np.interp(at, tr.s_m, tr.d_m)) - d_median[i_seen]
        if not 0.0 < width <= SHOULDER_MAX_M or (best is not None and width >= best[1]):
            continue
        if _seen_share(tr, *samples, min(at, end), max(at, end)) >= SEEN_SHARE:
            best = (tr, width, end)
    return best


def _beside_partial_lines(
    tracks: tuple[BoundaryTrack, ...],
    samples: tuple[FloatArray, FloatArray],
    grid: FloatArray,
    d_median: FloatArray,
    ends: tuple[int, int],
) -> FloatArray:
    """The edge's move (metres towards the carriageway) on ``grid[i0 + 1 : i1]`` (``ends``:
    ``(i0, i1)``, where the edge was last and first seen), an
    unseen stretch no line is seen all through, where the inner shoulder's line is seen
    part of the way in from one end or both (:func:`_partial_line`): the shoulder keeps
    the width it had at that end beside the line as far as the line is seen, and the
    move runs linearly between there and the other end (0 where the edge is seen again,
    or where the line from that end ends). A lane added beside the median by a taper and
    left by an inner exit soon after (town06-auto-lane2-s22 with a noisier sensor, the
    edge unseen over the 70 m before the gore): the shoulder's line was seen to 35 m
    before the gore, the lines inside it lay straight, while the fit bridged the edge
    across as a 70 m slope, 2 m off beside the line (edge 0.330 -> 0.286 m). Zeros where
    no such line is seen or the move is under :data:`MIN_SHOULDER_MOVE_M`."""
    i0, i1 = ends
    g = grid[i0 + 1 : i1]
    move = np.zeros(g.size)
    known = np.zeros(g.size, dtype=bool)
    for i_seen, i_far in ((i0, i1), (i1, i0)):
        part = _partial_line(tracks, samples, grid, d_median, i_seen, i_far)
        if part is None:
            continue
        tr, width, end = part
        on = (g >= min(grid[i_seen], end)) & (g <= max(grid[i_seen], end)) & ~known
        move[on] = np.interp(g[on], tr.s_m, tr.d_m) - width - d_median[i0 + 1 : i1][on]
        known |= on
    if not known.any():
        return move
    # between the parts the move runs linearly to the seen ends, where it is 0
    xs = np.r_[grid[i0], g[known], grid[i1]]
    move[~known] = np.interp(g[~known], xs, np.r_[0.0, move[known], 0.0])
    if float(np.max(np.abs(move))) < MIN_SHOULDER_MOVE_M:
        return np.zeros(g.size)
    return move


def moves_beside_steps(
    gaps: list[tuple[int, int]],
    steps: FloatArray,
    tracks: tuple[BoundaryTrack, ...],
    s_lane: FloatArray,
    d_lane: FloatArray,
    grid: FloatArray,
    d_median: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """How far the median-side edge moves (metres towards the carriageway, on ``grid``)
    across the part of an unseen stretch (``gaps``, :func:`unseen_stretches`) between
    where the edge was last (first) seen and one of its ``steps`` (stations, metres)
    inside the stretch: the innermost lane line seen through that part keeps the
    distance from the edge it had where the edge was seen (the lanes beside it leave or
    join only at the step). The edge fit bridges the stretch smoothly onto the level
    beyond the step, which it measures in its own bent frame:
    oakland-28393854-s7 with a noisier sensor bent 2.2 m over the 80 m before a 3-lane
    inner exit whose nose was unseen, the lines beside it straight.

    A line is a track (``tracks``) covering the part and the seen end, seen (lane samples
    ``s_lane``, ``d_lane`` within :data:`LINE_NEAR_M`) in :data:`LINE_SEEN_SHARE` of its
    5 m bins; a move under :data:`MIN_SHOULDER_MOVE_M` is left out. Returns the move and
    the steps where a move ends (begins) at full size.
    """
    move = np.zeros(grid.size)
    ends: list[float] = []
    for a, b in gaps:
        inside = steps[(steps > grid[a - 1]) & (steps < grid[b])]
        if inside.size != 1:
            continue
        st = float(inside[0])
        for seen_i, lo, hi in ((a - 1, float(grid[a - 1]), st), (b, st, float(grid[b]))):
            if hi - lo < GAP_MIN_M:
                continue
            fork = _fork_beside_step(tracks, s_lane, d_lane, grid, d_median, st, lo < st)
            if fork is not None:
                part, shift, s_fork = fork
                move[part] = shift
                ends.extend((st, s_fork))
                continue
            part = (grid > lo) & (grid < hi)
            best = None
            for tr in tracks:
                if tr.n_samples == 0 or tr.s_m[0] > lo or tr.s_m[-1] < hi:
                    continue
                width = float(np.interp(grid[seen_i], tr.s_m, tr.d_m)) - d_median[seen_i]
                if width <= 0.0 or (best is not None and width >= best[1]):
                    continue
                if _seen_share(tr, s_lane, d_lane, lo, hi) >= LINE_SEEN_SHARE:
                    best = (tr, width)
            if best is None:
                continue
            tr, width = best
            shift = np.interp(grid[part], tr.s_m, tr.d_m) - width - d_median[part]
            if shift.size and float(np.max(np.abs(shift))) >= MIN_SHOULDER_MOVE_M:
                move[part] = shift
                ends.append(st)
    return move, np.unique(np.asarray(ends, dtype=float))


FORK_MEET_M = 0.6
"""Two lane lines this close (metres) meet: a ramp's line leaves (joins) a through line."""
FORK_APART_M = 3.0
"""... and the ramp's line lies at least this much (metres) farther towards the median
at the step: it left with the ramp's lanes."""
FORK_PARTING_M = 30.0
"""The lines part over at most this (metres) before they are :data:`FORK_MEET_M` apart."""
FORK_SEARCH_M = 150.0
"""How far (metres) from a step the meeting is searched for."""
FORK_STRAIGHT_M = 1.0
"""The through line stays within this (metres) of its offset at the step from the
meeting to the step."""


def _fork_beside_step(
    tracks: tuple[BoundaryTrack, ...],
    s_lane: FloatArray,
    d_lane: FloatArray,
    grid: FloatArray,
    d_median: FloatArray,
    st: float,
    exit_: bool,
) -> tuple[NDArray[np.bool_], FloatArray, float] | None:
    """Where the lanes beyond the through lanes leave at a median-side step found only
    where the edge is seen again (an inner exit's; ``exit_``) or join before the edge
    became unseen (an inner entry's): the gore is where the line between the last
    through lane and the first ramp lane forks, one branch going on beside the through
    lanes (the edge's new level a shoulder beyond it), the other leaving with the ramp's
    lanes towards the median (at least :data:`FORK_APART_M` away at the step). A 4-lane
    inner exit whose mainline edge was unseen for 90 m after its gore
    (melbourne-1226-s11 with a noisier sensor, seed offset 680) had the step placed
    where the edge was seen again, and the edge moved with the leaving lanes up to it:
    the ramp's lanes were the mainline's, 6.7 m off and the ramp missed.

    Returns the grid stations between the fork and the step, the edge's move there
    (metres towards the carriageway: the new level beside the through line) and the
    fork's station; None where no line forks within :data:`FORK_SEARCH_M` of the step."""
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    i_new = int(np.searchsorted(grid, st)) if exit_ else int(np.searchsorted(grid, st)) - 1
    if not 0 <= i_new < grid.size:
        return None
    level = float(d_median[i_new])
    at_step = float(grid[i_new])

    def at(tr: BoundaryTrack, s: FloatArray) -> FloatArray:
        inside = (s >= tr.s_m[0]) & (s <= tr.s_m[-1])
        return np.where(inside, np.interp(s, tr.s_m, tr.d_m), np.nan)

    # the through line: the innermost line beyond the edge's new level, a shoulder away
    through = [
        (float(at(tr, np.array([at_step]))[0]) - level, tr) for tr in tracks if tr.n_samples > 0
    ]
    through = [(w, tr) for w, tr in through if 0.0 < w <= SHOULDER_MAX_M]
    if not through:
        return None
    width, line = min(through, key=lambda item: item[0])
    lo, hi = (st - FORK_SEARCH_M, at_step) if exit_ else (at_step, st + FORK_SEARCH_M)
    span = grid[(grid >= lo) & (grid <= hi)]
    t_line = at(line, span)
    best: float | None = None
    for tr in tracks:
        if tr is line or tr.n_samples == 0:
            continue
        t_other = at(tr, span)
        gap = t_line - t_other  # > 0: the other line lies towards the median
        near_step = gap[-1] if exit_ else gap[0]
        meets = np.abs(gap) <= FORK_MEET_M
        meet = np.flatnonzero(meets)
        if not meet.size or not np.isfinite(near_step) or near_step < FORK_APART_M:
            continue
        # the lines part where the run of meeting stations next to the parting begins
        # (ends): the ramp's line starts on the through line and leaves it gradually
        last = meet[-1] if exit_ else meet[0]
        first = next(
            lo_ if exit_ else hi_ - 1 for lo_, hi_ in true_runs(meets) if lo_ <= last < hi_
        )
        s_meet = float(span[first])
        if abs(s_meet - float(span[last])) > FORK_PARTING_M:
            s_meet = float(span[last]) + (FORK_PARTING_M if not exit_ else -FORK_PARTING_M)
        if best is None or abs(st - s_meet) < abs(st - best):
            best = s_meet
    if best is None:
        return None
    part = (grid >= best) & (grid < st) if exit_ else (grid > st) & (grid <= best)
    t_part = at(line, grid[part])
    if not np.all(np.isfinite(t_part)):
        return None
    if t_part.size and np.max(np.abs(t_part - (level + width))) > FORK_STRAIGHT_M:
        return None
    lo, hi = (best, st) if exit_ else (st, best)
    if hi - lo < 2.0 * step or _seen_share(line, s_lane, d_lane, lo, hi) < LINE_SEEN_SHARE:
        return None
    return part, t_part - width - d_median[part], best


def with_edge_moves(
    offset: CubicProfile,
    grid: FloatArray,
    move: FloatArray,
    sign: float,
    gores: FloatArray | None = None,
) -> CubicProfile:
    """The centre lane's offset (metres, t left positive) with the median-side edge moved
    by ``move`` (on ``grid``, metres towards the carriageway) where it is not 0: linear
    records every :data:`KNOT_M` metres there, the step profile ``offset`` elsewhere.
    A move beginning or ending at one of the ``gores`` (stations, metres) steps there,
    where the lane sections change too; elsewhere it runs in from (out onto) the step
    profile over one grid step. ``sign`` is +1 for right-hand traffic (the carriageway
    lies right: negative t)."""
    if not np.any(move):
        return offset
    n = grid.size
    step = float(grid[1] - grid[0]) if n > 1 else 1.0
    at_gore = np.asarray(gores if gores is not None else [], dtype=float)

    def gore_at(s: float) -> bool:
        return bool(at_gore.size) and float(np.min(np.abs(at_gore - s))) <= 1.5 * step

    def gore_between(lo: float, hi: float) -> float | None:
        inside = at_gore[(at_gore > lo) & (at_gore < hi)]
        return float(inside[0]) if inside.size else None

    def base(s: float) -> float:
        return float(offset.value(np.array([s]))[0])

    knots: set[float] = {p.s0 for p in offset.pieces}
    on_spans: list[tuple[float, float]] = []  # stations where the move is applied
    hold: set[float] = set()  # last knots of a move that steps back at a gore
    # a move that begins at a gore between two grid stations begins at the gore itself,
    # where the lane section changes, at its first station's size: begun at the next
    # station, the lanes jumped by the move half a metre inside the section
    at_start: dict[float, float] = {}
    every = max(1, round(KNOT_M / step))
    for a, b in true_runs(move != 0.0):
        first = a if a == 0 or gore_at(float(grid[a])) else a - 1
        idx = [*range(first, b, every), b - 1]
        knots.update(float(grid[i]) for i in idx)
        begin = float(grid[first])
        gore = gore_between(float(grid[a - 1]), begin) if a > 0 and first == a else None
        if gore is not None:
            begin = gore
            at_start[gore] = float(move[a])
            knots.add(gore)
        if b < n:
            knots.add(float(grid[b]))  # back on the step profile
            if gore_at(float(grid[b])):
                hold.add(float(grid[b - 1]))
                gore = gore_between(float(grid[b - 1]), float(grid[b]))
                if gore is not None:
                    knots.add(gore)  # back on it at the gore, where the section changes
        on_spans.append((begin, float(grid[b - 1])))
    ordered = sorted(knots)
    on = [any(lo <= s0 <= hi for lo, hi in on_spans) for s0 in ordered]

    def moved(s0: float) -> float:
        return at_start.get(s0, float(np.interp(s0, grid, move)))

    new: list[CubicPiece] = []
    for k, s0 in enumerate(ordered):
        a_val = base(s0) - sign * moved(s0) * on[k]
        slope = 0.0
        if on[k] and k + 1 < len(ordered) and s0 not in hold:
            s1 = ordered[k + 1]
            a_next = base(s1 - 1e-9) - sign * moved(s1) * on[k + 1]
            slope = (a_next - a_val) / (s1 - s0)
        new.append(CubicPiece(float(s0), a_val, slope))
    return CubicProfile(tuple(new))
