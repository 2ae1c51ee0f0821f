"""Lines of another road seen through an occlusion gap of the outer edge are not the
mainline's (:mod:`roadtwin.mainline.beyond_edge`): melbourne-408-opp-s9 with a noisier
sensor, a parallel road's line 2.6 m beyond the edge kept through a 100 m gap made a
4.8 m lane of the shoulder."""

import numpy as np

from roadtwin.mainline.beyond_edge import without_other_roads_lines
from roadtwin.mainline.markings import _Track

GRID = np.arange(0.0, 601.0, 1.0)
GAP = (316.0, 415.0)


def _track(lo: float, hi: float, d0: float, d1: float) -> _Track:
    s = GRID[(lo <= GRID) & (hi >= GRID)]
    d = np.interp(s, [lo, hi], [d0, d1])
    return _Track(0, lo, hi, s, d, "broken", s.size, s.copy(), d.copy())


def _case(far_d: float, rng: np.random.Generator) -> list[_Track]:
    """The mainline's outer line at 11.4 m; a line at 16.45 m seen through the gap from
    its start, moving to ``far_d`` at the gap's end. The edge is at 13.8 m before the gap
    and 18.8 m after it; the line at 16.45 m was seen beyond the edge over 30 m before."""
    covered = ~((GAP[0] < GRID) & (GAP[1] > GRID))
    d_edge = np.where(GRID < 360.0, 13.8, 18.8)
    tracks = [_track(0.0, 600.0, 11.4, 11.4), _track(318.0, 417.0, 16.45, far_d)]
    s_before = rng.uniform(280.0, 316.0, 40)
    s_all = np.concatenate([np.arange(0.0, 600.0, 0.5), s_before])
    d_all = np.concatenate([np.full(1200, 11.4), 16.45 + rng.normal(0.0, 0.05, 40)])
    return without_other_roads_lines(tracks, GRID, d_edge, covered, (s_all, d_all))


def test_a_line_seen_beyond_the_edge_before_the_gap_and_at_it_after_is_dropped():
    kept = _case(19.3, np.random.default_rng(1))
    assert [float(tr.d[0]) for tr in kept] == [11.4]


def test_a_line_that_comes_inside_the_edge_after_the_gap_is_kept():
    # an entry's ramp line that becomes the acceleration lane's: the edge stepped out
    # beyond it inside the gap
    kept = _case(16.45, np.random.default_rng(2))
    assert len(kept) == 2
