"""The median-side edge where the sensor sees the other carriageway's edge too.

Across a narrow median (melbourne-408-opp: 0.55 m between the two carriageways' edges)
the median-side edge points form two parallel lines. A robust fit averaged them and put
the road's edge 0.3 m into the median over 250 m (edge RMSE 0.097 m, 0.107 m with a
noisier sensor). The road's edge is the inner line (nearest the carriageway)."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.fitting import PolylineFrame
from roadtwin.mainline._common import inner_line_points
from roadtwin.mainline.reference import fit_median_edge

LENGTH = 600.0


def _points(noise_m: float, seed: int = 5, *, second: bool = True) -> np.ndarray:
    """Median-side edge points (left of a straight trajectory along +x): the road's edge
    at y = 8.05 m all along, and from x = 200 to 450 m the other carriageway's at 8.60 m
    (as many points); every point in ``noise_m`` Gaussian noise."""
    rng = np.random.default_rng(seed)
    x = np.arange(0.0, LENGTH, 0.3)
    y = np.full(x.size, 8.05)
    if second:
        x2 = x[(x >= 200.0) & (x <= 450.0)]
        x, y = np.concatenate([x, x2]), np.concatenate([y, np.full(x2.size, 8.60)])
    return np.column_stack([x, y + rng.normal(0.0, noise_m, x.size)])


def _edge_y(ref_pts: np.ndarray) -> np.ndarray:
    """The fitted median edge's y at x = 250..400 m (metres)."""
    traj = PolylineFrame.from_points(np.column_stack([np.arange(0.0, LENGTH, 1.0), np.zeros(600)]))
    median = fit_median_edge(ref_pts, traj)
    x = np.arange(250.0, 401.0, 5.0)
    return np.interp(x, median.xy[:, 0], median.xy[:, 1])


@pytest.mark.parametrize("noise_m", [0.03, 0.06])
def test_the_road_edge_is_the_inner_of_two_lines_of_points(noise_m):
    y = _edge_y(_points(noise_m))
    assert np.max(np.abs(y - 8.05)) < 0.05


def test_one_line_of_points_keeps_every_point():
    """A single line, however noisy, is never split: no point is left out."""
    pts = _points(0.06, second=False)
    assert inner_line_points(pts[:, 0], pts[:, 1] - 8.05).all()
    assert np.max(np.abs(_edge_y(pts) - 8.05)) < 0.03
