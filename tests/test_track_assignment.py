"""Column peaks are matched to the tracks' guesses as a whole, not pair by pair.

Where two lines run close side by side and both move, the nearest pair first can give
one track the peak the other needed and leave that one without any: at Town06's lane gain
(its split shoulder lines, 0.5 m apart, swinging out together) one line's track went
unlinked for three columns and then took the other line's peaks."""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.linking import _link_tracks


def _two_lines(jump_a: float, jump_b: float) -> list[np.ndarray]:
    """Two flat lines at 10.0 and 10.5 m over 10 columns, then at 10.0 + ``jump_a`` and
    10.5 + ``jump_b`` over 10 more."""
    return [
        np.array([10.0, 10.5]) if c < 10 else np.sort(np.array([10.0 + jump_a, 10.5 + jump_b]))
        for c in range(20)
    ]


def test_each_of_two_lines_keeps_its_own_peak():
    """At column 10 the peaks lie 0.3 m beyond the first line and 0.4 m beyond the second:
    the second line's track is nearer the first peak (0.2 m), but taking it would leave
    the first line's track 0.9 m from the other, beyond its reach."""
    tracks = _link_tracks(_two_lines(0.3, 0.4), MainlineConfig())
    assert len(tracks) == 2
    first, second = sorted(tracks, key=lambda tr: tr.d[0])
    assert first.cols == list(range(20))
    assert second.cols == list(range(20))
    assert first.d[10] == 10.3
    assert second.d[10] == 10.9


def test_one_peak_goes_to_the_nearer_guess():
    """One line lost (worn paint): its peak goes to the track whose guess is nearer, the
    other track goes unlinked rather than taking it."""
    peaks = [np.array([10.0, 10.5]) if c < 10 else np.array([10.45]) for c in range(20)]
    tracks = _link_tracks(peaks, MainlineConfig())
    assert len(tracks) == 2
    first, second = sorted(tracks, key=lambda tr: tr.d[0])
    assert first.cols == list(range(10))
    assert second.cols == list(range(20))


def test_a_line_that_stays_put_keeps_its_peak_in_a_moving_frame():
    """In a frame that moves with the marking pattern (lanes added beyond the line), a
    line that stays where it is in the road moves by minus the frame's move; its trend
    lags where the shift begins. Here the frame moves 0.9 m in a column: the line's own
    peak lies 0.9 m from its trend's guess (out of reach) and on its stays-put guess,
    another line's peak 0.58 m from the trend's guess. The stays-put guess, dearer by
    0.25 m only, wins (melbourne-408-opp-s9: the median-side line's track took the new
    lanes' line 0.58 m from its trend, its own peak 0.24 m from the stays-put guess)."""
    move = np.array([0.0 if c < 11 else 0.9 * (c - 10) for c in range(20)])
    peaks = [
        np.array([5.0]) if c < 11 else np.sort(np.array([5.0 - move[c], 5.58])) for c in range(20)
    ]
    tracks = _link_tracks(peaks, MainlineConfig(), move)
    line = next(tr for tr in tracks if tr.cols[0] == 0)
    assert line.cols == list(range(20))
    assert line.d[11] == 5.0 - 0.9
    assert line.d[-1] == 5.0 - move[-1]
    other = [tr for tr in tracks if tr.cols[0] == 11]
    assert len(other) == 1
    assert other[0].d == [5.58] * 9


def test_lines_beside_the_outer_edge_swing_out_with_it():
    """A lane gain on the outer side: the edge and the shoulder's line 0.65 m inside it
    swing out 3.5 m along an S over 40 m, while the lane line inward stays and a new line
    leaves it 0.5 m inside the shoulder's line. The trend of the accelerating shoulder line
    lags; alone it lost the line and its pieces were joined to the new line (Town06's
    lane gain, town06-auto-s2: 0.8 m off). The line's guess that keeps its distance to
    the seen edge links every column."""
    column_m = MainlineConfig().lane_column_m
    x = np.clip((np.arange(40) * column_m - 60.0) / 40.0, 0.0, 1.0)
    swing = 3.5 * x * x * (3.0 - 2.0 * x)
    peaks = [
        np.array([15.1, 15.1 + sw, 15.6 + sw]) if sw > 0.5 else np.array([15.1, 15.6 + sw])
        for sw in swing
    ]
    edge = 16.25 + swing
    alone = _link_tracks(peaks, MainlineConfig())
    assert not any(tr.cols == list(range(40)) and tr.d[-1] == 19.1 for tr in alone)
    tracks = _link_tracks(peaks, MainlineConfig(), edge=edge)
    shoulder = next(tr for tr in tracks if tr.d[0] == 15.6)
    assert shoulder.cols == list(range(40))
    np.testing.assert_allclose(shoulder.d, 15.6 + swing)
    new = [tr for tr in tracks if tr.cols[0] > 0]
    assert len(new) == 1
    np.testing.assert_allclose(new[0].d, 15.1 + swing[new[0].cols])
    # unseen (NaN) edge: no such guess
    blind = _link_tracks(peaks, MainlineConfig(), edge=np.full(40, np.nan))
    assert [tr.cols for tr in blind] == [tr.cols for tr in alone]
