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
from .markings import _Track

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
    return [tr for k, tr in enumerate(tracks) if k not in drop]
