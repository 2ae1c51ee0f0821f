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
