"""The outer edge steps where a ramp's edge leaves the road's, not at the nose.

HD maps split the road where the leaving lane's border parts from the through lanes'
(the start of the gore area); a map cut at the physical nose keeps the leaving lane
straight on the road while the ramp's pavement bends away. Numbers checked: the step
within 3 m of where the ramp's edge leaves, the road's edge inside the gore area on the
new level within 0.1 m, the ramp's edge points there not used.
"""

from __future__ import annotations

import numpy as np

from roadtwin.mainline.outer_edge import fit_outer_edge


def _line(rng, s0, s1, d_of_s, spacing=0.2, noise=0.03):
    s = np.arange(s0, s1, spacing)
    return s, d_of_s(s) + rng.normal(0.0, noise, s.size)


def test_an_outer_exit_steps_where_its_edge_leaves_the_road():
    rng = np.random.default_rng(41)
    leave = lambda s: 12.0 + 0.01 * np.clip(s - 600.0, 0.0, None) ** 2  # noqa: E731
    parts = [
        _line(rng, 0.0, 620.0, leave),  # the edge, then the ramp's edge peeling off
        _line(rng, 620.0, 1000.0, lambda s: np.full(s.size, 8.4)),  # past the nose
        _line(rng, 620.0, 680.0, leave),  # the ramp's edge beyond the nose
    ]
    s = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts])
    grid = np.arange(0.0, 1000.0, 1.0)
    d_edge, breaks, used, _ = fit_outer_edge(s, d, grid)
    assert breaks.size == 1
    assert abs(breaks[0] - 600.0) < 3.0  # the nose is at 620 m
    inside = (grid > 604.0) & (grid < 618.0)
    np.testing.assert_allclose(d_edge[inside], 8.4, atol=0.1)
    assert not np.any(used & (s > 604.0) & (s < 618.0) & (d > 9.5))


def test_an_outer_entry_steps_where_its_edge_has_joined_the_road():
    # mirrored: the nose at 400 m, the ramp's edge 0.8 m out there, on the new level
    # (12 m) from 420 m; before the nose the through edge (8.4 m)
    rng = np.random.default_rng(42)
    join = lambda s: 12.0 + 0.002 * np.clip(420.0 - s, 0.0, None) ** 2  # noqa: E731
    parts = [
        _line(rng, 0.0, 400.0, lambda s: np.full(s.size, 8.4)),
        _line(rng, 400.0, 1000.0, join),
    ]
    s = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts])
    grid = np.arange(0.0, 1000.0, 1.0)
    d_edge, breaks, _, _ = fit_outer_edge(s, d, grid)
    assert breaks.size == 1
    # the level path is noisy where the ramp's edge comes in slowly: the walk from the
    # nose stops within the last few metres of the area
    assert 408.0 < breaks[0] < 423.0
    inside = (grid > 402.0) & (grid < 408.0)
    np.testing.assert_allclose(d_edge[inside], 8.4, atol=0.1)
