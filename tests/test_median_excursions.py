"""A ramp leaving on the median side with no lane ending at full width: its edge peels off
the mainline's median edge and the mainline's own edge goes on beyond the gore at the
level it had. The reference line (the median edge) must not follow the ramp's edge.

Town06's inner exits are such ramps. Fitted into the reference line, the ramp's edge bent
the whole road up to 3 m towards the ramp over 40 m, every lane with it (edge RMSE 0.79 m
on the cropped Town06 route, 5.2 m off at 20-120 m from the exit's gore)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from _run_factory import build_xodr_route
from roadtwin.mainline.reference import median_excursions

TOWN06 = Path(__file__).parent / "data" / "xodr" / "town06-35-38.xodr.gz"


def _levels(bump_m: float, after_m: float) -> tuple[np.ndarray, np.ndarray]:
    """A level path on 2 m bins over 400 m: 0 up to 200 m, a bump outward rising to
    ``bump_m`` over 200-224 m (unseen over 224-230 m: the gore's nose), then
    ``after_m``."""
    centres = np.arange(1.0, 400.0, 2.0)
    level = np.zeros(centres.size)
    ramp = (centres > 200.0) & (centres < 224.0)
    level[ramp] = bump_m * (centres[ramp] - 200.0) / 24.0
    level[(centres >= 224.0) & (centres < 230.0)] = np.nan
    level[centres >= 230.0] = after_m
    return centres, level


def test_an_outward_bump_that_comes_back_is_an_excursion():
    spans, bases = median_excursions(*_levels(3.0, 0.0))
    assert spans.shape == (1, 2)
    # from where the ramp's edge leaves the base to the gore's nose
    assert spans[0, 0] == pytest.approx(200.0, abs=2.0)
    assert spans[0, 1] == pytest.approx(230.0, abs=2.0)
    assert bases[0] == pytest.approx(0.0, abs=0.05)


@pytest.mark.parametrize("after_m", [3.5, -3.5, 1.0])
def test_a_step_or_taper_to_another_level_is_no_excursion(after_m):
    """The levels either side differ: lanes begin or end there (a gore step, a taper)."""
    spans, _ = median_excursions(*_levels(3.0, after_m))
    assert spans.shape == (0, 2)


def test_an_auxiliary_lane_beside_the_median_is_no_excursion():
    """An entry's lane on the median side that runs on to the next exit: the edge steps
    out by a lane for 100 m and back, and stays level in between."""
    centres = np.arange(1.0, 800.0, 2.0)
    level = np.where((centres > 300.0) & (centres < 400.0), 3.5, 0.0)
    spans, _ = median_excursions(centres, level)
    assert spans.shape == (0, 2)


def test_an_auxiliary_lane_unseen_in_the_middle_is_no_excursion():
    """An auxiliary lane beside the median (between an inner entry and an inner exit),
    seen only at its ends, as the first pass of a fresh noisy Town06 run (seed 41)
    measured it from the trajectory (2 m bins). Its edge rises towards the exit at the
    lane's end; judged from that end, the whole lane looked like a ramp's edge, and its
    edge points were left out."""
    nan = np.nan
    seen_first = [
        13.39,
        13.39,
        13.42,
        13.35,
        13.42,
        13.42,
        13.42,
        13.37,
        13.42,
        13.28,
        13.17,
        13.17,
        13.10,
        12.98,
        12.92,
        12.89,
        12.88,
        12.88,
        12.67,
        nan,
        17.14,
        16.98,
        16.92,
        16.92,
        16.92,
        16.89,
        16.88,
        16.92,
    ]
    seen_last = [
        16.92,
        16.92,
        16.83,
        16.95,
        16.92,
        16.88,
        16.98,
        17.17,
        17.48,
        17.85,
        nan,
        13.11,
        12.95,
        13.06,
        13.12,
        13.17,
        13.20,
        13.33,
        13.33,
        13.39,
        13.42,
        13.46,
        13.42,
        13.42,
        13.48,
        13.40,
        13.42,
        13.42,
        13.42,
        13.42,
        13.42,
        13.39,
    ]
    lane = np.array([*seen_first, *[nan] * 40, *seen_last])
    centres = np.arange(1001.0, 1999.0, 2.0)
    level = np.full(centres.size, 13.4)
    first = int(np.searchsorted(centres, 1381.0))
    level[first : first + lane.size] = lane
    spans, _ = median_excursions(centres, level)
    assert spans.shape == (0, 2)


# The first pass's level path (2 m bins, metres from the smoothed trajectory) of
# town06-auto-s3 before its second inner exit: the car drifts 3.5 m away from the
# median with its lane (an outer lane gain) while the exit's edge peels off (1724-1742 m),
# unseen at the nose, the road's edge back at 16.6 m after it.
_DRIFTING = [
    *[13.34] * 9,
    *[13.37, 13.39, 13.45, 13.53],
    *[13.59] * 10,
    *[13.50, 13.39, 13.39, 13.38, 13.48, 13.45, 13.59, 13.59, 13.59, 13.59, 13.66, 13.81],
    *[13.84, 13.84, 13.87, 14.01, 14.09, 14.09, 14.19, 14.34, 14.34, 14.44, 14.59, 14.59],
    *[14.69, 14.84, 14.84, 15.03, 15.09, 15.09, 15.24, 15.34, 15.34, 15.48, 15.59, 15.61],
    *[15.71, 15.84, 15.89, 16.09, 16.36, 16.70, 17.01, 17.45, 17.95, 18.43, 19.12, 19.84],
    *[20.42, np.nan, np.nan, np.nan, 16.59, 16.68, 16.76, 16.84, 16.84, 16.87],
    *[16.84] * 19,
]


def test_an_excursion_in_a_drifting_frame_is_found_about_the_edges_course():
    centres = 1600.2 + 2.0 * np.arange(len(_DRIFTING))
    level = np.array(_DRIFTING)
    # against a level base the drift itself is outward for 80 m and more: nothing found
    assert median_excursions(centres, level)[0].shape == (0, 2)
    spans, bases = median_excursions(centres, level, drifting=True)
    assert spans.shape == (1, 2)
    assert 1722.0 < spans[0, 0] < 1730.0  # the peel-off (1724 m) ...
    assert 1747.0 < spans[0, 1] < 1751.0  # ... to the nose (1749 m)
    assert 15.9 < bases[0] < 16.7  # between the road's edge before and after


def test_a_long_departure_is_no_excursion():
    """An edge that is away for longer than a ramp's peel-off is the road's own."""
    centres = np.arange(1.0, 800.0, 2.0)
    level = np.where((centres > 200.0) & (centres < 500.0), 2.0, 0.0)
    spans, _ = median_excursions(centres, level)
    assert spans.shape == (0, 2)


@pytest.mark.parametrize("seed", [1, 2])
def test_the_mainline_does_not_bend_towards_an_inner_exit(tmp_path, seed):
    info, rep = build_xodr_route(
        TOWN06, tmp_path / "run", route=["35", "36", "37", "38"], seed=seed
    )
    edge = rep.details["truth/road_edge"]
    (exit_,) = [r for r in info["ramps"] if r["station_m"] < 100.0]
    assert exit_["side"] == "inner"
    # 20-90 m past the gore, clear of its junction zone and the entry's: the road's own
    gap = edge.station_m - exit_["station_m"]
    past = (gap > 20.0) & (gap < 90.0)
    assert np.count_nonzero(past) > 100
    assert float(np.max(np.abs(edge.error_m[past]))) < 0.6  # 5.2 m before
    assert rep.truth["road_edge"]["rmse_m"] < 0.3  # 0.79 m before
