"""Marking lines do not cross, and the median-side edge stepping onto a line ends no lane.

Two defects of melbourne-921-s2, where the fit of its median-side edge moved by 0.16 m:
an entry's taper line that met the next line went on along its slope through two lanes,
linked across a 55 m gap to the shoulder line beyond an exit's gore; and at that gore on
the median side the mainline's innermost line, which the edge goes on from, was counted
with the exit's lanes (a 2-lane exit built with 3). And the other way: a lane drop's line
seen again past the fastest part of its S goes on there."""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.linking import _link_tracks, _RawTrack
from roadtwin.mainline.raw_joins import _join_late_pieces
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


# column peaks (5 m columns) of melbourne-408-opp-s9+80 where a lane drops: its line
# closes from 18.3 m onto the line at 14.8 m along an S, unseen over 6 columns in its
# fastest part, then seen for two columns before it meets that line
DROP_LINE = dict.fromkeys(range(40, 88), 18.3) | {
    88: 18.28,
    89: 18.33,
    90: 18.28,
    91: 18.17,
    92: 18.12,
    93: 17.87,
    94: 17.69,
}
DROP_LATE = {101: 15.83, 102: 15.53}


def _drop_tracks(late: dict[int, float]) -> list[_RawTrack]:
    line = _RawTrack([], [])
    for c, v in DROP_LINE.items():
        line.add(c, v)
    through = _RawTrack(list(range(30, 130)), [14.8] * 100)
    piece = _RawTrack([], [])
    for c, v in late.items():
        piece.add(c, v)
    return [through, line, piece]


def test_a_closing_line_seen_again_beyond_its_guess_goes_on_there():
    """Its trend (0.17 m a column) guessed 16.5 m at column 101, 0.67 m short of the
    piece: the piece, too short for a track, is the line's end, not dropped."""
    out = _join_late_pieces(_drop_tracks(DROP_LATE), MainlineConfig())
    assert len(out) == 2
    assert out[1].cols[-2:] == [101, 102]
    assert out[1].d[-1] == 15.53


def test_a_piece_off_a_line_s_course_or_long_enough_is_not_joined():
    cfg = MainlineConfig()
    # behind the line it left (back at 18 m): another line's paint
    assert len(_join_late_pieces(_drop_tracks({101: 18.0, 102: 18.0}), cfg)) == 3
    # beyond where the trend may carry it (2 m past the guess)
    assert len(_join_late_pieces(_drop_tracks({101: 14.5, 102: 14.4}), cfg)) == 3
    # a piece long enough for a track is a line of its own
    long_piece = dict.fromkeys(range(101, 101 + 12), 15.8)
    out = _join_late_pieces(_drop_tracks(long_piece), cfg)
    assert len(out) == 3
    # a line running along the road that paint appears beside later: not a taper
    flat = _drop_tracks(DROP_LATE)
    flat[1] = _RawTrack(list(range(40, 95)), [18.3] * 55)
    assert len(_join_late_pieces(flat, cfg)) == 3
