"""Exit and entry gores moved from the kerb's nose to the painted tip."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.config import MainlineConfig
from roadtwin.mainline.markings import _Track
from roadtwin.mainline.painted_gores import move_gores_to_paint

GRID = np.arange(0.0, 1000.5, 0.5)


def _track(tid: int, lo: float, hi: float, d, samples: np.ndarray) -> _Track:
    s = GRID[(lo <= GRID) & (hi >= GRID)]
    d_s = d(s)
    return _Track(tid, lo, hi, s, d_s, "solid", samples.size, samples, d(samples))


def _seen(*tracks: _Track) -> np.ndarray:
    """Stations of every lane sample (the other markings fill the dash gaps)."""
    return np.sort(np.concatenate([tr.s_samples for tr in tracks]))


def _move(through: _Track, beyond: _Track, d_edge, nose: float, config=None):
    """The gore at ``nose`` moved to the paint, with every lane sample as seen."""
    return move_gores_to_paint(
        [through, beyond],
        GRID,
        d_edge,
        np.array([nose]),
        _seen(through, beyond),
        config or MainlineConfig(),
    )


def _dashed_then_solid(tip: float, *, exit_: bool) -> np.ndarray:
    """Stations of the through lanes' outer marking: 6 m dashes every 12 m beside the
    auxiliary lane, the solid edge line on the other side of ``tip``, 3 m from the nearest
    dash (less than a dash gap: the paint pins the tip)."""
    if exit_:
        dashes = np.concatenate(
            [np.arange(a, a + 6.0, 0.3) for a in np.arange(tip - 9.0, 0.0, -12.0)]
        )
        solid = np.arange(tip, 1000.0, 0.3)
    else:
        solid = np.arange(0.0, tip, 0.3)
        dashes = np.concatenate(
            [np.arange(a, a + 6.0, 0.3) for a in np.arange(tip + 3.0, 1000.0, 12.0)]
        )
    return np.sort(np.concatenate([dashes, solid]))


def test_exit_lanes_split_at_the_painted_tip_not_at_the_nose():
    # painted tip 498 m (the dashes end 495 m, the solid line starts at 498 m), nose 540 m
    tip, nose = 498.0, 540.0
    through = _track(
        0, 0.0, 1000.0, lambda s: np.full(s.size, 7.5), _dashed_then_solid(tip, exit_=True)
    )
    # the exit lane's outer marking: 3.5 m beyond, diverging with the ramp after the tip
    beyond = _track(
        1,
        0.0,
        560.0,
        lambda s: 11.0 + 0.002 * np.clip(s - tip, 0.0, None) ** 2,
        np.arange(0.0, 560.0, 0.3),
    )
    # outer edge: 2.5 m shoulder beyond the exit lane up to the nose, 0.3 m after it
    d_edge = np.where(nose > GRID, 13.5, 7.8)
    tracks, edge, breaks, painted = _move(through, beyond, d_edge, nose)
    assert breaks.tolist() == [pytest.approx(tip, abs=0.3)]  # one sample spacing
    assert painted == [(breaks[0], nose)]
    cut = next(tr for tr in tracks if tr.id == 1)
    assert cut.hi == breaks[0]
    assert cut.s[-1] == breaks[0]
    zone = (breaks[0] < GRID) & (nose > GRID)
    # the edge there: the through marking plus the shoulder opening from zero at the tip
    expect = 7.5 + 0.3 * (GRID[zone] - breaks[0]) / (nose - breaks[0])
    np.testing.assert_allclose(edge[zone], expect, atol=1e-9)
    # nothing moves outside the painted stretch
    np.testing.assert_array_equal(edge[~zone], d_edge[~zone])


def test_entry_mirrors_and_an_unpainted_gore_stays_at_the_nose():
    nose, tip = 300.0, 335.0
    through = _track(
        0, 0.0, 1000.0, lambda s: np.full(s.size, 7.5), _dashed_then_solid(tip, exit_=False)
    )
    beyond = _track(
        1, 280.0, 1000.0, lambda s: np.full(s.size, 11.0), np.arange(280.0, 1000.0, 0.3)
    )
    d_edge = np.where(nose > GRID, 7.8, 13.5)
    tracks, _, breaks, _ = _move(through, beyond, d_edge, nose)
    assert breaks.tolist() == [pytest.approx(tip, abs=0.3)]  # one sample spacing
    assert next(tr for tr in tracks if tr.id == 1).lo == breaks[0]
    # a solid marking all along shows no tip: the step stays at the nose
    solid = _track(0, 0.0, 1000.0, lambda s: np.full(s.size, 7.5), np.arange(0.0, 1000.0, 0.3))
    _, edge2, breaks2, painted2 = _move(solid, beyond, d_edge, nose)
    assert breaks2.tolist() == [nose]
    assert painted2 == []
    np.testing.assert_array_equal(edge2, d_edge)
    # and switched off, nothing moves
    off = MainlineConfig(painted_gore_max_m=0.0)
    _, edge3, breaks3, _ = _move(through, beyond, d_edge, nose, off)
    assert breaks3.tolist() == [nose]
    np.testing.assert_array_equal(edge3, d_edge)
