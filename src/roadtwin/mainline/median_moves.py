"""The median-side edge where it is unseen beside a gore: it moves with the lanes.

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

Stations are metres along the reference line; offsets ``d`` metres from the reference
edge towards the carriageway (the lanes' frame, :func:`~.lanes.fit_lanes`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..model import CubicPiece, CubicProfile
from ._common import BoundaryTrack, true_runs

FloatArray = NDArray[np.float64]

__all__ = ["edge_moves", "with_edge_moves"]

MIN_MOVE_M = 1.5
"""A seen line moving less than this (metres) inside the unseen stretch leaves the edge
where the fit put it: noise and a curve's smoothing are smaller, a lane is larger."""
SEEN_BEYOND_M = 10.0
"""The line must be seen this far (metres) beyond the unseen stretch, where the edge is
seen too: its distance from the edge there is the one kept."""
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


def with_edge_moves(
    offset: CubicProfile, grid: FloatArray, move: FloatArray, sign: float
) -> CubicProfile:
    """The centre lane's offset (metres, t left positive) with the median-side edge moved
    by ``move`` (on ``grid``, metres towards the carriageway) where it is not 0: linear
    records every :data:`KNOT_M` metres there, the step profile ``offset`` elsewhere.
    ``sign`` is +1 for right-hand traffic (the carriageway lies right: negative t)."""
    if not np.any(move):
        return offset
    pieces = list(offset.pieces)
    starts = np.array([p.s0 for p in pieces])

    def base(s: float) -> float:
        return float(offset.value(np.array([s]))[0])

    knots: set[float] = set(starts.tolist())
    runs = true_runs(move != 0.0)
    every = max(1, round(KNOT_M / float(grid[1] - grid[0]))) if grid.size > 1 else 1
    for a, b in runs:
        idx = [*range(a, b, every), b - 1]
        knots.update(float(grid[i]) for i in idx)
        if b < grid.size:
            knots.add(float(grid[b]))  # back on the step profile
    ordered = sorted(knots)
    on = np.zeros(len(ordered), dtype=bool)
    for a, b in runs:
        on |= (np.array(ordered) >= grid[a]) & (np.array(ordered) <= grid[b - 1])
    new: list[CubicPiece] = []
    for k, s0 in enumerate(ordered):
        a_val = base(s0) - sign * float(np.interp(s0, grid, move)) * on[k]
        slope = 0.0
        if on[k] and k + 1 < len(ordered):  # the last one runs back onto the steps
            s1 = ordered[k + 1]
            a_next = base(s1 - 1e-9) - sign * float(np.interp(s1, grid, move))
            slope = (a_next - a_val) / (s1 - s0)
        new.append(CubicPiece(float(s0), a_val, slope))
    return CubicProfile(tuple(new))
