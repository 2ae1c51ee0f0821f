"""Two pieces of one line that closes a lane along an S, seen at its slow start and near
its end, are one marking (:func:`roadtwin.mainline.raw_joins._join_taper_pieces`):
a9-239192816-opp-s12 with a noisier sensor lost a lane closing over 125 m."""

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.gores import smoothstep
from roadtwin.mainline.linking import _RawTrack
from roadtwin.mainline.raw_joins import _join_taper_pieces

CFG = MainlineConfig()


def _taper(cols: range) -> _RawTrack:
    """A line closing from 19.4 m to 15.7 m along a cubic S over columns 0-25."""
    c = np.asarray(list(cols), dtype=float)
    return _RawTrack(list(cols), list(19.4 - 3.7 * smoothstep(c / 25.0)))


def test_the_start_and_the_end_of_a_closing_line_are_joined():
    through = _RawTrack(list(range(40)), [11.9] * 40)
    raw = [through, _taper(range(7)), _taper(range(16, 25))]
    # the linking's guess from the first piece falls short of the second by 0.6 m or more
    first = raw[1]
    guess = first.d[-1] + (first.d[-1] - first.d[-4]) / 3.0 * (16 - 6)
    assert abs(guess - raw[2].d[0]) > CFG.lane_link_m
    out = _join_taper_pieces(raw, CFG)
    assert len(out) == 2
    joined = [tr for tr in out if tr.d[0] > 19.0]
    assert len(joined) == 1
    assert joined[0].cols == list(range(7)) + list(range(16, 25))


def test_pieces_of_two_lines_that_go_on_are_not_joined():
    """town06-auto-lane1-s21+440: pieces of two broken lines a lane apart, each going on
    at its own offset in between."""
    a = _RawTrack(list(range(9)), [12.2] * 9)
    b = _RawTrack(list(range(16, 25)), [15.7] * 9)
    a_goes_on = _RawTrack([10, 12, 14], [12.2] * 3)
    assert len(_join_taper_pieces([a, b, a_goes_on], CFG)) == 3


def test_a_single_peak_is_no_piece_of_a_taper():
    one = _RawTrack([0], [19.4])
    rest = _taper(range(10, 25))
    assert len(_join_taper_pieces([one, rest], CFG)) == 2
