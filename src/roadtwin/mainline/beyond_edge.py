"""Lines of another road seen through an occlusion gap of the outer edge.

Where the outer edge goes unseen, the lane samples are bounded by the wider of the edge's
levels at the gap's ends (:func:`~.lanes._edge_bound`): a lane gained inside the gap keeps
its lines. A line of a road running beside the mainline beyond its edge (a collector road,
a ramp beside a barrier) is then kept too where it runs through the gap, and becomes a
lane of the mainline (melbourne-408-opp-s9 with a noisier sensor: a parallel road's line
2.6 m beyond the edge, seen through a 100 m gap, made a 4.8 m lane of the shoulder, the
edge 2.3 m off). Such a line was seen beyond the edge right next to the gap, at the same
offset where its track begins (ends), and it does not come inside the edge at the gap's
other end (an entry's ramp line that becomes the acceleration lane's does, the edge having
stepped out beyond it).

Stations ``s`` and offsets ``d`` are metres in the reference line's frame (``d`` from the
reference edge towards the carriageway, :func:`~.lanes.fit_lanes`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._common import true_runs
from .markings import _Track, track_part

FloatArray = NDArray[np.float64]

__all__ = ["without_other_roads_lines"]

_AT_GAP_END_M = (5.0, 10.0)  # a track beginning this near a gap's start (before, after) ...
_BEYOND_M = 1.0  # ... this far beyond the edge seen there (metres) ...
_SEEN_BESIDE_M = 30.0  # ... on a line seen this far next to the gap (metres) ...
_SAME_LINE_M = 0.4  # ... by this many samples within this of its offset (metres)
_SEEN_SAMPLES = 8
_INSIDE_M = 0.3  # a line this far inside the edge at the gap's other end is the mainline's


def without_other_roads_lines(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    covered: NDArray[np.bool_],
    samples: tuple[FloatArray, FloatArray],
) -> list[_Track]:
    """The tracks without those of another road seen through an occlusion gap of the outer
    edge (``d_edge`` on ``grid``, metres, seen where ``covered``). ``samples``: stations
    and offsets (metres) of all lane samples of the run, beyond the edge too."""
    s_all, d_all = samples
    drop: set[int] = set()
    keep: dict[int, _Track] = {}
    for a, b in true_runs(~covered):
        if a == 0 or b >= grid.size:
            continue
        ends = ((float(grid[a - 1]), float(d_edge[a - 1])), (float(grid[b]), float(d_edge[b])))
        for k, tr in enumerate(tracks):
            for start in (True, False):
                (s_near, e_near), (s_far, e_far) = ends if start else ends[::-1]
                tip, d_tip = (tr.lo, float(tr.d[0])) if start else (tr.hi, float(tr.d[-1]))
                reach = _AT_GAP_END_M if start else _AT_GAP_END_M[::-1]
                if not (s_near - reach[0] <= tip <= s_near + reach[1]):
                    continue
                if d_tip < e_near + _BEYOND_M:
                    continue
                beside = (s_all < s_near) & (s_all >= s_near - _SEEN_BESIDE_M)
                if not start:
                    beside = (s_all > s_near) & (s_all <= s_near + _SEEN_BESIDE_M)
                same = beside & (np.abs(d_all - d_tip) < _SAME_LINE_M)
                if np.count_nonzero(same) < _SEEN_SAMPLES:
                    continue
                if tr.lo <= s_far <= tr.hi and np.interp(s_far, tr.s, tr.d) < e_far - _INSIDE_M:
                    continue
                drop.add(k)
                kept = _inside_part(tr, grid, d_edge, s_far, after=start)
                if kept is not None:
                    keep[k] = kept
    return [keep.get(k, tr) for k, tr in enumerate(tracks) if k not in drop or k in keep]


_KEPT_MIN_M = 60.0  # a dropped line's part inside the edge past the gap this long is kept


def _inside_part(
    tr: _Track, grid: FloatArray, d_edge: FloatArray, s_far: float, *, after: bool
) -> _Track | None:
    """The part of another road's track ``tr`` past the gap's far end ``s_far`` (after
    it, ``after``; else before it) from where it comes ``_INSIDE_M`` inside the edge
    on, if ``_KEPT_MIN_M`` long or more: that road merged, and its line goes on as the
    mainline's (melbourne-408-opp-s9 with a noisier sensor, seed offset 320: dropped
    whole, the line of a lane the merge added was missing, lanes 0.086 -> 0.141 m)."""
    inside = tr.d < np.interp(tr.s, grid, d_edge) - _INSIDE_M
    past = tr.s > s_far if after else tr.s < s_far
    idx = np.flatnonzero(past & inside)
    if idx.size == 0:
        return None
    i0, i1 = (int(idx[0]), tr.s.size) if after else (0, int(idx[-1]) + 1)
    if not np.all(inside[i0:i1]) or tr.s[i1 - 1] - tr.s[i0] < _KEPT_MIN_M:
        return None
    return track_part(tr, i0, i1)
