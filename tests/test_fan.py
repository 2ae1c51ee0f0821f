"""Lines of lanes gained together fan out of one point (:func:`roadtwin.mainline.tapers._fan`):
melbourne-921-s9 with a noisier sensor, two lanes gained beside the median at once, the
inner new lane's sparse line first seen halfway out, was tapered from its nearer
neighbour and split off it 20 m late, 0.9 m off."""

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.gores import smoothstep
from roadtwin.mainline.tapers import _fan, _taper

GRID = np.arange(0.0, 600.0, 1.0)
FAN_M = 365.0  # both new lines leave the innermost one (1.0 m) here ...
OVER_M = 65.0  # ... over this many metres, to 4.5 and 8.0 m


def _dmat(first_seen: float) -> np.ndarray:
    """Tracks x grid: the innermost line at 1.0 m; the outer new line 1.0 -> 8.0 m seen
    all along; the inner new line 1.0 -> 4.5 m first seen at ``first_seen``."""
    x = smoothstep((GRID - FAN_M) / OVER_M)
    inner_new = np.where(first_seen <= GRID, 1.0 + 3.5 * x, np.nan)
    outer_new = np.where(GRID >= FAN_M - 5.0, 1.0 + 7.0 * x, np.nan)
    return np.vstack([np.full(GRID.size, 1.0), outer_new, inner_new])


def test_a_line_first_seen_halfway_out_of_a_fan_goes_back_to_its_point():
    dmat = _dmat(391.0)
    s_zero, length, nearer = _fan(dmat, 2, GRID, "start")
    # where the two neighbours meet: 0.3 m apart, 8 m into the S
    assert FAN_M <= s_zero < FAN_M + 10.0
    assert abs(length - (391.0 - s_zero)) < 1e-9
    assert nearer == 1  # halfway between: the outer line is as near
    truth = 1.0 + 3.5 * smoothstep((GRID - FAN_M) / OVER_M)
    filled = (s_zero <= GRID) & (GRID < 391.0)
    assert float(np.max(np.abs(dmat[2, filled] - truth[filled]))) < 0.15


def test_taper_takes_the_fan_and_a_line_beside_two_parallel_ones_is_no_fan():
    dmat = _dmat(391.0)
    info = _taper(dmat, 2, GRID, "start", MainlineConfig())
    assert info is not None
    assert FAN_M <= info[0] < FAN_M + 10.0
    # the neighbours do not meet: a lane opening between two lines that stay
    parallel = np.vstack(
        [np.full(GRID.size, 1.0), np.full(GRID.size, 8.0), np.where(GRID >= 391.0, 4.5, np.nan)]
    )
    assert _fan(parallel, 2, GRID, "start") is None
