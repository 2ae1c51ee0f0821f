"""A marking beside an edge strip that turns from solid to broken starts a section.

Seen from an inner lane, a lane gained on the outer side (the hard shoulder becomes a
lane, its own outer line out of the sensor's reach) shows only as the line beside the
shoulder turning from solid to broken (oakland-28393854-lane1-s21 at seed offset 860:
one section typed the shoulder before it a driving lane, lane count 71 %)."""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.mark_changes import pattern_changes
from roadtwin.mainline.markings import _Track

GRID = np.arange(0.0, 1201.0, 1.0)


def _paint(lo: float, hi: float, dash_m: float, gap_m: float) -> np.ndarray:
    """Sample stations every 0.5 m along dashes of ``dash_m`` with gaps of ``gap_m``
    (a solid line: ``gap_m`` 0)."""
    s = np.arange(lo, hi, 0.5)
    if gap_m <= 0.0:
        return s
    return s[(s - lo) % (dash_m + gap_m) < dash_m]


def _track(k: int, samples: np.ndarray, d: float) -> _Track:
    return _Track(k, 0.0, 1200.0, GRID, np.full(GRID.size, d), "broken", samples.size, samples)


def _dmat(tracks: list[_Track]) -> np.ndarray:
    return np.vstack([tr.d for tr in tracks])


def test_the_line_beside_the_shoulder_turning_broken_is_a_change():
    solid_then_broken = np.concatenate([_paint(0.0, 600.0, 1, 0), _paint(600.0, 1200.0, 3, 9)])
    tracks = [_track(0, _paint(0.0, 1200.0, 3, 9), 4.0), _track(1, solid_then_broken, 7.6)]
    changes = pattern_changes(tracks, _dmat(tracks), GRID, MainlineConfig())
    assert len(changes) == 1
    assert 600.0 <= GRID[changes[0]] <= 604.0  # the first gap after the last solid metre


def test_and_back_to_solid():
    broken_then_solid = np.concatenate([_paint(0.0, 500.0, 6, 12), _paint(500.0, 1200.0, 1, 0)])
    tracks = [_track(0, broken_then_solid, 7.6)]
    changes = pattern_changes(tracks, _dmat(tracks), GRID, MainlineConfig())
    assert len(changes) == 1
    assert 488.0 <= GRID[changes[0]] <= 501.0


def test_a_worn_stretch_is_no_change():
    """A solid line worn off over 35 m leaves one long gap, not a pattern."""
    s = _paint(0.0, 1200.0, 1, 0)
    worn = s[(s < 520.0) | (s > 555.0)]
    tracks = [_track(0, worn, 7.6)]
    assert pattern_changes(tracks, _dmat(tracks), GRID, MainlineConfig()) == []


def test_not_on_a_line_between_two_lanes():
    """A line with lines on both sides borders no edge strip: its pattern changing (an
    inner lane's line) starts nothing."""
    solid_then_broken = np.concatenate([_paint(0.0, 600.0, 1, 0), _paint(600.0, 1200.0, 3, 9)])
    tracks = [
        _track(0, _paint(0.0, 1200.0, 1, 0), 0.7),
        _track(1, solid_then_broken, 4.4),
        _track(2, _paint(0.0, 1200.0, 3, 9), 8.0),
    ]
    assert pattern_changes(tracks, _dmat(tracks), GRID, MainlineConfig()) == []


def test_not_where_the_line_is_out_of_reach():
    """A broken line whose samples end 600 m before the track does (out of reach beyond)
    did not turn solid there: the long unseen stretch is no solid paint."""
    tracks = [_track(0, _paint(0.0, 600.0, 3, 9), 7.6)]
    assert pattern_changes(tracks, _dmat(tracks), GRID, MainlineConfig()) == []
