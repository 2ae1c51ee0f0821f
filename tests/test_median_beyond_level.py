"""The median-side edge beside another road's dense edge line ending next to it.

A ramp's curb line that comes in from the median and ends 7 m beside the mainline's edge
(krems-30799129-s11+920: 670 points over 60 m, denser than the edge's own) pulled the
first pass of the median edge fit 7 m outward, though the level path stayed on the edge
all along; the knot it tied was cut out and bridged 0.9 m off the edge over 100 m. Edge
points well beyond the level path are never the road's edge."""

from __future__ import annotations

import numpy as np

from roadtwin.fitting import PolylineFrame
from roadtwin.mainline import reference
from roadtwin.mainline.reference import _tight_turns, fit_median_edge

LENGTH = 600.0
EDGE_Y = 6.1


def _points(seed: int = 3) -> np.ndarray:
    """Median-side edge points left of a straight trajectory along +x: the edge at
    y = 6.1 m every 0.25 m, and a ramp's curb every 0.08 m coming in from y = 30 m at
    x = 300 m, levelling off at 13.5 m and ending at x = 390 m; 0.03 m noise."""
    rng = np.random.default_rng(seed)
    x = np.arange(0.0, LENGTH, 0.25)
    y = np.full(x.size, EDGE_Y)
    xr = np.arange(300.0, 390.0, 0.08)
    yr = 13.5 + 16.5 * np.clip((370.0 - xr) / 70.0, 0.0, 1.0) ** 2
    x, y = np.concatenate([x, xr]), np.concatenate([y, yr])
    return np.column_stack([x, y + rng.normal(0.0, 0.03, x.size)])


def _fit(pts: np.ndarray):
    traj = PolylineFrame.from_points(np.column_stack([np.arange(0.0, LENGTH, 1.0), np.zeros(600)]))
    return fit_median_edge(pts, traj), traj


def test_a_ramp_line_ending_beside_the_edge_does_not_pull_it():
    median, traj = _fit(_points())
    x = np.arange(100.0, 501.0, 2.0)
    y = np.interp(x, median.xy[:, 0], median.xy[:, 1])
    assert np.max(np.abs(y - EDGE_Y)) < 0.05
    assert _tight_turns(median.xy, traj, 20.0) == []


def test_points_beyond_the_level_path_are_left_out_only_where_it_is_seen():
    edges = np.array([0.0, 2.0, 4.0, 6.0])
    level = np.array([6.0, np.nan, 6.0])
    s = np.array([1.0, 1.0, 3.0, 5.0, 5.0])
    u = np.array([6.5, 7.0, 13.0, 6.7, 5.0])  # 0.5 / 1.0 beyond, unseen bin, 0.7, inward
    beyond = reference._beyond_level(s, u, edges, level)
    assert beyond.tolist() == [False, True, False, False, False]
