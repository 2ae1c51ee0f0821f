"""The outer edge as one path through the levels of the edge points."""

from __future__ import annotations

import numpy as np

from roadtwin.mainline.edge_levels import edge_level_path


def _line(rng, s0, s1, d_of_s, spacing=0.2, noise=0.03):
    s = np.arange(s0, s1, spacing)
    return s, d_of_s(s) + rng.normal(0.0, noise, s.size)


def test_path_keeps_the_mainline_edge_past_foreign_edges_and_takes_gore_steps():
    rng = np.random.default_rng(4)
    parts = [
        # the mainline edge: 12 m, a gore step down to 8.5 m at 600 m (an exit), unseen
        # 300..360 m (a truck beside the car)
        _line(rng, 0.0, 300.0, lambda s: np.full(s.size, 12.0)),
        _line(rng, 360.0, 600.0, lambda s: np.full(s.size, 12.0)),
        _line(rng, 600.0, 1000.0, lambda s: np.full(s.size, 8.5)),
        # another road's edge 6 m farther out, seen for 20 m of the gap (beside the truck)
        _line(rng, 330.0, 350.0, lambda s: np.full(s.size, 18.0)),
        # the exit ramp's edge running on from the gore, diverging
        _line(rng, 600.0, 800.0, lambda s: 12.0 + 0.0004 * (s - 600.0) ** 2),
        # a steep ramp edge crowding a few bins (many points per bin), and noise
        _line(rng, 850.0, 862.0, lambda s: 10.0 + 1.5 * (s - 850.0), spacing=0.02),
    ]
    s = np.concatenate([p[0] for p in parts] + [rng.uniform(0, 1000, 200)])
    d = np.concatenate([p[1] for p in parts] + [rng.uniform(5, 25, 200)])
    edges = np.arange(-1.0, 1001.0, 2.0)
    level = edge_level_path(s, d, edges)
    c = 0.5 * (edges[1:] + edges[:-1])
    seen = np.isfinite(level)
    expect = np.where(c < 600.0, 12.0, 8.5)
    assert np.max(np.abs(level[seen] - expect[seen])) < 0.15  # a level, not the fit
    # through the gap it goes on unseen rather than onto the ramp's edge
    assert not np.any(seen & (c > 302.0) & (c < 358.0))
    # it steps at the gore, within a bin
    after = c[seen & (np.abs(level - 8.5) < 0.2)]
    assert 599.0 <= after.min() <= 603.0
    assert np.count_nonzero(seen) > 0.9 * (c.size - 30)
