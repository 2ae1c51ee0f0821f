"""Marking lines do not cross, and the median-side edge stepping onto a line ends no lane.

Two defects of melbourne-921-s2, where the fit of its median-side edge moved by 0.16 m:
an entry's taper line that met the next line went on along its slope through two lanes,
linked across a 55 m gap to the shoulder line beyond an exit's gore; and at that gore on
the median side the mainline's innermost line, which the edge goes on from, was counted
with the exit's lanes (a 2-lane exit built with 3)."""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.markings import _link_tracks
from roadtwin.mainline.sections import _edge_takes_over

COLUMN_M = MainlineConfig().lane_column_m


def _taper_meets_line(*, with_line: bool) -> list[np.ndarray]:
    """Per 5 m column: a through line at 7.8 m (if ``with_line``) and a taper's line
    coming in from 11 m at 0.065 m/m, seen while more than 0.3 m from that line (to column
    8) and never again; 10 columns on, paint 3.2 m farther along its slope (another line,
    on the far side of the through line) for 6 columns. Peaks closer than 0.3 m are one."""
    slope = 0.065 * COLUMN_M
    out = []
    for c in range(30):
        cand = [7.8] if with_line else []
        taper = 11.0 - slope * c
        if c <= 10 and (not with_line or abs(taper - 7.8) > 0.3):
            cand.append(taper)
        if 18 <= c <= 23:
            cand.append(11.0 - slope * 18 + 0.05)
        out.append(np.sort(np.array(cand)))
    return out


def test_a_taper_line_that_met_another_does_not_go_on_across_it():
    tracks = _link_tracks(_taper_meets_line(with_line=True), MainlineConfig())
    taper = [tr for tr in tracks if tr.cols[0] == 0 and tr.d[0] > 10.0]
    assert len(taper) == 1
    assert taper[0].cols[-1] == 8  # it ended where it met the line at 7.8 m
    late = [tr for tr in tracks if tr.cols[0] == 18]
    assert len(late) == 1
    assert late[0].cols == list(range(18, 24))
    through = [tr for tr in tracks if abs(np.median(tr.d) - 7.8) < 0.05]
    assert len(through) == 1
    assert len(through[0].cols) == 30


def test_without_a_line_in_between_the_trend_still_bridges_the_gap():
    """The rule only stops a trend at another line: a lone line missed over 10 columns
    (worn paint) is still linked along its slope."""
    tracks = _link_tracks(_taper_meets_line(with_line=False), MainlineConfig())
    taper = [tr for tr in tracks if tr.cols[0] == 0]
    assert len(taper) == 1
    assert taper[0].cols[-1] == 23
    assert len(tracks) == 1


def test_the_median_edge_stepping_onto_a_line_ends_no_lane():
    grid = np.arange(0.0, 200.0, 1.0)
    d_median = np.where(grid < 100.0, 0.0, 8.0)  # an exit's two lanes leave at 100 m
    steps = np.array([100.0])
    # the innermost through line at 8.02 m: the edge goes on from it beyond the gore
    assert _edge_takes_over(8.02, 100.0, "end", grid, d_median, steps)
    # the exit's lines at 1.2 and 4.6 m end with their lanes
    assert not _edge_takes_over(4.6, 100.0, "end", grid, d_median, steps)
    assert not _edge_takes_over(1.2, 100.0, "end", grid, d_median, steps)
    # a line ending 40 m from any step of the edge: not the edge's
    assert not _edge_takes_over(8.02, 140.0, "end", grid, d_median, steps)
    # an entry's mirror: the edge steps from 8 m in to 0, the line at 8 m begins there
    d_entry = np.where(grid < 100.0, 8.0, 0.0)
    assert _edge_takes_over(7.95, 100.0, "start", grid, d_entry, steps)
    assert not _edge_takes_over(3.4, 100.0, "start", grid, d_entry, steps)
