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


def test_the_part_of_that_line_inside_the_edge_after_a_merge_beyond_the_gap_is_kept():
    """melbourne-408-opp-s9 with a noisier sensor (seed offset 320): the parallel road's
    line, beyond the edge through the gap, went on inside the edge once that road merged
    past the gap, as the line of the lane the merge added; dropped whole, that line was
    missing (lanes 0.086 -> 0.141 m). From where it comes inside the edge on, it stays."""
    rng = np.random.default_rng(3)
    covered = ~((GAP[0] < GRID) & (GAP[1] > GRID))
    # the edge 13.8 m before the gap, 18.8 m after it; beyond 480 m the merged road's
    # lane widens the carriageway, the edge at 20.5 m
    d_edge = np.where(GRID < 360.0, 13.8, np.where(GRID < 480.0, 18.8, 20.5))
    line = _track(318.0, 600.0, 19.3, 19.3)
    line = _Track(1, line.lo, line.hi, line.s, np.where(line.s < 470.0, 19.3, 17.0), "broken",
                  line.n, line.s_samples, np.where(line.s_samples < 470.0, 19.3, 17.0))  # fmt: skip
    tracks = [_track(0.0, 600.0, 11.4, 11.4), line]
    s_before = rng.uniform(280.0, 316.0, 40)
    s_all = np.concatenate([np.arange(0.0, 600.0, 0.5), s_before])
    d_all = np.concatenate([np.full(1200, 11.4), 19.3 + rng.normal(0.0, 0.05, 40)])
    kept = without_other_roads_lines(tracks, GRID, d_edge, covered, (s_all, d_all))
    assert len(kept) == 2
    part = kept[1]
    # from where it is inside the edge (470 m: 17.0 m against 18.8 m) to its end
    assert part.lo == 470.0
    assert part.hi == 600.0
    assert float(np.max(part.d)) == 17.0
    assert part.n == np.count_nonzero(line.s_samples >= 470.0)
    # a part inside the edge shorter than a marking track must be is no line: dropped
    short = _Track(1, 318.0, 500.0, line.s[line.s <= 500.0], line.d[line.s <= 500.0], "broken",
                   0, line.s_samples[:0])  # fmt: skip
    kept = without_other_roads_lines([tracks[0], short], GRID, d_edge, covered, (s_all, d_all))
    assert len(kept) == 1
