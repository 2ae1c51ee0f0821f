"""A lane line seen beyond the outer edge's bound in an occlusion gap raises the bound.

a9-10959882-opp-s7 (the benchmark's A9 route, noisier sensor, seed offset 800): an
auxiliary lane opened by a long taper while the outer edge beyond it was unseen for
180 m; its outer line, seen over 95 m 11.1-11.9 m from the reference edge, lay beyond the
bound held across the gap (10.9 m), was cut, and the lane was typed a shoulder (edge
0.220 m, lanes 0.250 m; 0.096 / 0.102 m with the line kept).
"""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.mainline.lanes import _with_lane_lines_beyond

GRID = np.arange(0.0, 401.0, 1.0)
COVERED = (GRID < 100.0) | (GRID > 300.0)
BOUND = np.full(GRID.size, 10.9)


def _line(rng: np.random.Generator, lo: float, hi: float, d) -> tuple[np.ndarray, np.ndarray]:
    s = np.arange(lo, hi, 0.5)
    d = np.broadcast_to(np.asarray(d(s) if callable(d) else d, dtype=float), s.shape)
    return s, d + rng.normal(0.0, 0.05, s.size)


def _samples(*lines):
    s = np.concatenate([ln[0] for ln in lines])
    d = np.concatenate([ln[1] for ln in lines])
    order = np.argsort(s, kind="stable")
    return s[order], d[order]


def test_a_parallel_line_a_lane_out_raises_the_bound_over_the_gap():
    rng = np.random.default_rng(7)
    s, d = _samples(_line(rng, 0.0, 400.0, 8.0), _line(rng, 150.0, 250.0, 11.6))
    bound = _with_lane_lines_beyond(BOUND, COVERED, GRID, s, d)
    inside = (GRID >= 150.0) & (GRID <= 250.0)
    assert np.all(np.abs(bound[inside] - 11.6) < 0.1)
    # only over the gap, never lowered
    assert np.array_equal(bound[COVERED], BOUND[COVERED])
    assert np.all(bound >= BOUND)


@pytest.mark.parametrize(
    "beyond",
    [
        # a ramp's line leaving the road: not parallel
        lambda s: 11.3 + 0.08 * (s - 150.0),
        # a line only 40 m long
        None,
    ],
)
def test_no_raise_for_a_ramp_line_or_a_short_one(beyond):
    rng = np.random.default_rng(7)
    far = _line(rng, 150.0, 190.0, 11.6) if beyond is None else _line(rng, 150.0, 200.0, beyond)
    s, d = _samples(_line(rng, 0.0, 400.0, 8.0), far)
    bound = _with_lane_lines_beyond(BOUND, COVERED, GRID, s, d)
    assert np.array_equal(bound, BOUND)


def test_no_raise_without_a_line_a_lane_width_inside():
    # the nearest line inside lies 1.4 m in: a shoulder's split or a second edge line
    rng = np.random.default_rng(7)
    s, d = _samples(_line(rng, 0.0, 400.0, 10.2), _line(rng, 150.0, 250.0, 11.6))
    bound = _with_lane_lines_beyond(BOUND, COVERED, GRID, s, d)
    assert np.array_equal(bound, BOUND)
