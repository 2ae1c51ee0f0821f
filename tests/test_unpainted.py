"""The outermost line across a stretch without samples follows the outer edge at the hard
shoulder's width (melbourne-921-s2: an acceleration lane's outer line unpainted for 46 m
after the gore, its track begun by four samples of the ramp's line 1.6 m inside it; the
lane was built 1.3 m narrow there, lanes 0.110 -> 0.065 m)."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.mainline.markings import _Track
from roadtwin.mainline.unpainted import follow_edge_across_unpainted

GRID = np.arange(0.0, 300.5, 0.5)
# the outer edge comes in by 3 m over the acceleration lane's taper
EDGE = np.interp(GRID, [0.0, 100.0, 250.0, 300.0], [24.3, 24.3, 21.3, 21.3])
SHOULDER_M = 2.6


def _track(s_samples, d_samples, k=0):
    d = np.interp(GRID, s_samples, d_samples)
    on = (s_samples[0] <= GRID) & (s_samples[-1] >= GRID)
    return _Track(
        k,
        float(s_samples[0]),
        float(s_samples[-1]),
        GRID[on],
        d[on],
        "solid",
        s_samples.size,
        s_samples,
        d_samples,
    )


def _line_with_stray_start():
    """Four samples of the ramp's line at 19.9-20.1 m (100-101.5 m), nothing to 150 m,
    then the line 2.6 m inside the edge."""
    s_ramp = np.array([100.0, 100.5, 101.0, 101.5])
    s_line = np.arange(150.0, 300.0, 0.5)
    s = np.concatenate([s_ramp, s_line])
    d = np.concatenate([[19.9, 19.95, 20.0, 20.1], np.interp(s_line, GRID, EDGE) - SHOULDER_M])
    return _track(s, d)


def test_a_line_begun_by_a_ramps_samples_follows_the_edge_from_its_start():
    tr = _line_with_stray_start()
    covered = np.ones(GRID.size, dtype=bool)
    (out,) = follow_edge_across_unpainted([tr], GRID, EDGE, covered, np.zeros(0))
    want = np.interp(out.s, GRID, EDGE) - SHOULDER_M
    stretch = out.s <= 150.0
    # bridged straight, the line lay 1.6 m inside at 100 m and 0.8 m at 125 m
    assert float(np.max(np.abs(tr.d[stretch] - want[stretch]))) > 1.5
    assert float(np.max(np.abs(out.d[stretch] - want[stretch]))) < 0.02
    assert np.array_equal(out.d[~stretch], tr.d[~stretch])
    assert np.array_equal(out.s_samples, tr.s_samples)


def test_the_shoulder_width_is_linear_between_the_two_ends():
    s = np.concatenate([np.arange(0.0, 100.0, 0.5), np.arange(160.0, 300.0, 0.5)])
    width = np.where(s < 100.0, 2.4, 2.8)
    tr = _track(s, np.interp(s, GRID, EDGE) - width)
    (out,) = follow_edge_across_unpainted(
        [tr], GRID, EDGE, np.ones(GRID.size, dtype=bool), np.zeros(0)
    )
    at = 130.0
    got = float(np.interp(at, out.s, out.d))
    assert got == pytest.approx(float(np.interp(at, GRID, EDGE)) - 2.6, abs=0.02)


def test_the_line_stays_where_the_edge_was_not_seen_or_steps_or_a_line_lies_beyond():
    tr = _line_with_stray_start()
    unseen = np.ones(GRID.size, dtype=bool)
    unseen[(GRID > 120.0) & (GRID < 130.0)] = False
    assert follow_edge_across_unpainted([tr], GRID, EDGE, unseen, np.zeros(0))[0] is tr
    seen = np.ones(GRID.size, dtype=bool)
    assert follow_edge_across_unpainted([tr], GRID, EDGE, seen, np.array([125.0]))[0] is tr
    beyond = _track(np.arange(90.0, 160.0, 0.5), np.full(140, 23.0), k=1)
    assert follow_edge_across_unpainted([tr, beyond], GRID, EDGE, seen, np.zeros(0))[0] is tr


def test_a_shoulder_closing_onto_the_line_or_changing_leaves_the_line_bridged():
    """The edge closes onto a straight line early in its unpainted stretch (a shoulder of
    1.2 m before, 0.3 m after, melbourne-408-lane2-s22): followed with a width linear
    between the two, the line bent 0.5 m. Likewise where both ends are shoulders but
    0.8 m apart in width. Both would move the line by 0.5-0.6 m."""
    s = np.concatenate([np.arange(0.0, 100.0, 0.5), np.arange(160.0, 300.0, 0.5)])
    line = np.full(s.size, 20.0)
    for after_m in (0.3, 2.0):
        edge = np.interp(
            GRID, [0.0, 100.0, 120.0, 300.0], [21.2, 21.2, 20.0 + after_m, 20.0 + after_m]
        )
        tr = _track(s, line)
        out = follow_edge_across_unpainted(
            [tr], GRID, edge, np.ones(GRID.size, dtype=bool), np.zeros(0)
        )
        assert out[0] is tr


def test_a_sparse_end_inside_the_track_leaves_the_stretch_bridged():
    """A broken line seen densely up to 90 m, then seven samples over 9 m (worn dashes),
    nothing for 25 m, then densely again at a narrower shoulder (krems-46762523 before an
    entry): the sparse end gives no width, and holding the other end's from there stepped
    the line 0.8 m at 100 m. Only a track's own first few samples are passed over."""
    s = np.concatenate(
        [np.arange(0.0, 90.0, 0.5), np.linspace(91.0, 100.0, 7), np.arange(125.0, 300.0, 0.5)]
    )
    edge = np.interp(GRID, [0.0, 100.0, 125.0, 300.0], [22.4, 22.4, 21.7, 21.7])
    tr = _track(s, np.full(s.size, 20.0))
    out = follow_edge_across_unpainted(
        [tr], GRID, edge, np.ones(GRID.size, dtype=bool), np.zeros(0)
    )
    assert out[0] is tr


def test_a_lane_closing_with_the_edge_is_no_shoulder_to_follow():
    """soderleden-s1 with a noisier sensor (seed offset 200): an acceleration lane 3.5 m
    wide with no outer line closes with the edge (10.5 -> 7.0 m over 215-240 m); the line
    between it and the through lanes (7.0 m) is unseen for 26 m up to the taper's end,
    with a few samples there. Followed along the edge at the "shoulder" width before the
    stretch, the line ran onto the next line inward (3.5 m) and closed a through lane
    (lanes 0.209 -> 0.039 m): it stays bridged."""
    edge = np.interp(GRID, [0.0, 215.0, 240.0, 300.0], [10.5, 10.5, 7.0, 7.0])
    s = np.concatenate([np.arange(100.0, 210.0, 0.5), np.arange(236.0, 240.0, 0.6)])
    line = _track(s, np.full(s.size, 7.0), k=0)
    inner = _track(np.arange(0.0, 300.0, 0.5), np.full(600, 3.5), k=1)
    covered = np.ones(GRID.size, dtype=bool)
    out = follow_edge_across_unpainted([line, inner], GRID, edge, covered, np.zeros(0))
    assert np.array_equal(out[0].d, line.d)
    # with no line inward there, the same edge is followed (the shoulder keeps its width)
    (alone,) = follow_edge_across_unpainted([line], GRID, edge, covered, np.zeros(0))
    assert float(np.min(alone.d)) < 4.0
