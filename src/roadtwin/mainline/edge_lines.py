"""Edge lines that go on as lane lines where the road widens at an entry.

On a carriageway without a hard shoulder the line painted along the outer edge goes on as
the line between the through lanes and an acceleration lane where an entry widens the
road. The sections stage takes a marking track that lies along the edge over most of its
length for the edge's line (:mod:`.sections`), so such a track is split first where it
parts from the edge (:func:`split_edge_lines_at_steps`).
"""

from __future__ import annotations

import itertools
import logging
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .markings import _Track, track_part

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

_STEP_SIDE_M = (5.0, 30.0)  # a step's sides: this far before / after it (metres)
_APART_M = 1.5  # a line this far from the edge beside a step borders a lane (metres)


def split_edge_lines_at_steps(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    steps: FloatArray,
    edge_line_m: float,
) -> tuple[list[_Track], FloatArray]:
    """An edge line that goes on as a lane line where the road widens at an outer-edge
    step (an entry), split where it parts from the edge; the step moves there.

    On a carriageway without a hard shoulder the line painted along the edge goes on as
    the line between the through lanes and an acceleration lane where an entry widens
    the road. Where the marking track lies along the edge over most of its length (within
    ``edge_line_m``, metres), the sections stage takes all of it for the edge's line, and
    the acceleration lane was one lane with the through lane, 7 m wide (soderleden, seed
    7). Such a track is split where it parts from the edge before a step (``steps``:
    stations, metres) and lies more than 1.5 m from it beyond: its part along the edge is
    the edge's line, its part apart borders the new lane, and the step moves to where the
    line parts (the lane opens there). Tracks mostly apart from the edge are lane lines
    already and are left whole.

    Returns the tracks and the steps.
    """
    steps = np.sort(np.asarray(steps, dtype=float))
    if steps.size == 0:
        return tracks, steps
    out: list[_Track] = []
    moved = steps.copy()
    a_m, b_m = _STEP_SIDE_M
    for tr in tracks:
        gap = np.abs(np.interp(tr.s, grid, d_edge) - tr.d)
        if tr.s.size < 10 or float(np.median(gap)) >= edge_line_m:
            out.append(tr)
            continue
        cuts = []
        for k, st in enumerate(steps):
            if not (tr.lo < st - b_m and tr.hi > st + b_m):
                continue
            before = (tr.s > st - b_m) & (tr.s < st - a_m)
            after = (tr.s > st + a_m) & (tr.s < st + b_m)
            if not (before.any() and after.any()):
                continue
            if float(np.median(gap[before])) >= edge_line_m:
                continue
            if float(np.median(gap[after])) <= _APART_M:
                continue
            win = np.flatnonzero((tr.s > st - b_m) & (tr.s <= st + a_m))
            near = win[gap[win] < edge_line_m]
            cut = int(near[-1]) + 1 if near.size else int(np.searchsorted(tr.s, st))
            cuts.append(cut)
            moved[k] = float(tr.s[min(cut, tr.s.size - 1)])
        if not cuts:
            out.append(tr)
            continue
        for a, b in itertools.pairwise([0, *sorted(set(cuts)), tr.s.size]):
            if b <= a:
                continue
            out.append(track_part(tr, a, b))
        log.info(
            "mainline: an edge line goes on as a lane line at s=%s m: split there",
            ", ".join(f"{tr.s[min(c, tr.s.size - 1)]:.0f}" for c in cuts),
        )
    return [replace(tr, id=k) for k, tr in enumerate(out)], np.sort(moved)


__all__ = ["split_edge_lines_at_steps"]
