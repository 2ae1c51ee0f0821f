"""A track's taper (roadtwin.mainline.tapers._taper) reaches where the track was seen."""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.tapers import _taper


def test_a_line_seen_at_a_steady_separation_gets_no_taper_from_far_off():
    """town06-auto-lane1-s21+80: the outer shoulder's line, unseen before 703 m, runs
    3.4-3.5 m beside its neighbour (then 5.2 m where the neighbour swings away and back).
    Its separation near where it starts lies just under 0.7 of the 90th percentile, so
    the flat stretch was fitted as a taper's middle: the line met its neighbour 700 m
    back, at the run's start, and was drawn outside the road edge all that way. A taper
    that would have ended before the line was first seen is none."""
    cfg = MainlineConfig()
    grid = np.arange(0.0, 1500.0, cfg.grid_step_m)
    # the separation drifts by 2 cm over the first 57 m, then the neighbour swings 1.75 m
    # away and back (the run's: 3.38-3.57 m, 5.18 m at 823 m, 3.48 m from 903 m)
    sep = np.where(grid < 760.0, 3.44 + 0.00035 * (grid - 703.0), 3.48)
    sep = sep + 1.75 * np.exp(-(((grid - 830.0) / 40.0) ** 2))
    neighbour = np.full(grid.size, 11.65)
    line = np.where(grid >= 703.0, 11.65 + sep, np.nan)
    dmat = np.vstack([neighbour, line])
    assert _taper(dmat, 1, grid, "start", cfg) is None
    assert np.all(np.isnan(dmat[1, grid < 703.0]))  # nothing filled in before it
    # a real opening (the line leaves its neighbour over 80 m from 900 m) keeps its taper
    opening = np.where(
        grid >= 900.0, 11.65 + 3.5 * np.clip((grid - 900.0) / 80.0, 0.0, 1.0), np.nan
    )
    dmat = np.vstack([np.full(grid.size, 11.65), opening])
    found = _taper(dmat, 1, grid, "start", cfg)
    assert found is not None
    s_zero, taper, neighbour_id = found
    assert neighbour_id == 0
    assert 850.0 <= s_zero <= 905.0
    assert taper <= cfg.lane_taper_max_m
