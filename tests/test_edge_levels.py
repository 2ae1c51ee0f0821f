"""The outer edge as one path through the levels of the edge points."""

from __future__ import annotations

import numpy as np

from roadtwin.mainline.edge_levels import edge_level_path, edge_steps


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


def _steps_of(s, d):
    edges = np.arange(-1.0, 1201.0, 2.0)
    return edge_steps(s, d, edges, edge_level_path(s, d, edges))


def test_step_sizes_hold_where_the_line_they_are_measured_from_wanders():
    # Offsets of the median-side edge from the smoothed trajectory: the car changes lanes
    # (3.5 m over 100 m around 300 m), so the edge's offset wanders before the step; a left
    # lane leaves at 700 m (the edge moves 3.6 m towards the carriageway). The segment's
    # median would mix both lane positions; the step measured next to it does not.
    rng = np.random.default_rng(11)
    lane_change = lambda s: 3.5 * np.clip((s - 250.0) / 100.0, 0.0, 1.0)  # noqa: E731
    s0, d0 = _line(rng, 0.0, 700.0, lambda s: 12.0 + lane_change(s))
    s1, d1 = _line(rng, 700.0, 1200.0, lambda s: 12.0 + lane_change(s) - 3.6)
    steps = _steps_of(np.concatenate([s0, s1]), np.concatenate([d0, d1]))
    assert steps.stations.size == 1
    assert abs(steps.stations[0] - 700.0) < 2.0
    assert abs((steps.offsets[1] - steps.offsets[0]) - (-3.6)) < 0.05


def test_step_sizes_of_steady_segments_ignore_a_converging_ramp_edge():
    # A steady edge (the line runs parallel to it): an inner lane joins at 400 m (the edge
    # moves out 3.5 m) and leaves at 800 m. Right before 400 m the entry ramp's edge
    # converges onto the new level, which biases the level bins next to the step; the
    # offsets are the segments' own levels to the centimetre.
    rng = np.random.default_rng(12)
    s0, d0 = _line(rng, 0.0, 400.0, lambda s: np.full(s.size, 10.0))
    s1, d1 = _line(rng, 400.0, 800.0, lambda s: np.full(s.size, 13.5))
    s2, d2 = _line(rng, 800.0, 1200.0, lambda s: np.full(s.size, 10.0))
    sr, dr = _line(rng, 380.0, 400.0, lambda s: 10.0 + 3.5 * (s - 380.0) / 20.0, spacing=0.05)
    s = np.concatenate([s0, s1, s2, sr])
    d = np.concatenate([d0, d1, d2, dr])
    steps = _steps_of(s, d)
    assert steps.stations.size == 2
    np.testing.assert_allclose(steps.offsets - steps.offsets[0], [0.0, 3.5, 0.0], atol=0.03)
    base = steps.from_base(0.0, 1200.0)
    np.testing.assert_allclose(base.offsets, [0.0, 3.5, 0.0], atol=0.03)


def test_a_level_held_for_a_bin_at_a_step_is_one_step_not_two():
    # A left exit at 700 m: the median-side edge moves 3.6 m towards the carriageway.
    # Right after the gore the exit ramp's edge crosses the level bins steeply (many
    # points in one bin, farther in than the new level), so the path holds a level for a
    # bin before settling. Both jumps refine to one station; counted as two steps of
    # -3.6 m each, every later segment lay 3.6 m off (town06-auto-s7: an 11.8 m lane).
    rng = np.random.default_rng(13)
    s0, d0 = _line(rng, 0.0, 700.0, lambda s: np.full(s.size, 12.0))
    s1, d1 = _line(rng, 700.0, 1200.0, lambda s: np.full(s.size, 8.4))
    sx, dx = _line(rng, 700.5, 701.5, lambda s: np.full(s.size, 4.9), spacing=0.01)
    steps = _steps_of(np.concatenate([s0, s1, sx]), np.concatenate([d0, d1, dx]))
    edges = np.arange(-1.0, 1201.0, 2.0)
    s_all, d_all = np.concatenate([s0, s1, sx]), np.concatenate([d0, d1, dx])
    level = edge_level_path(s_all, d_all, edges)
    c = 0.5 * (edges[1:] + edges[:-1])
    assert np.any(np.abs(level[(c > 699.0) & (c < 704.0)] - 4.9) < 0.3)  # the held level
    assert steps.stations.size == 1
    assert abs(steps.stations[0] - 700.0) < 3.0
    np.testing.assert_allclose(steps.offsets - steps.offsets[0], [0.0, -3.6], atol=0.05)


def test_a_stray_level_before_an_unseen_stretch_does_not_double_the_step():
    # A left fork at 700 m: the median-side edge moves 3.6 m towards the carriageway. A
    # stray cluster farther in (5.8 m) holds the path for one bin, and the path then goes
    # on unseen for 30 m before it is seen at the new level. The two jumps refine to
    # stations 5 m apart; counted as two steps, every later segment lay 7.2 m off
    # (melbourne-408-opp-s4 with a noisier sensor: a median edge 15.8 m in, lane RMSE
    # 2.9 m).
    rng = np.random.default_rng(15)
    s0, d0 = _line(rng, 0.0, 700.0, lambda s: np.full(s.size, 12.0))
    s1, d1 = _line(rng, 700.0, 1200.0, lambda s: np.full(s.size, 8.4))
    sx, dx = _line(rng, 700.4, 700.8, lambda s: np.full(s.size, 5.8), spacing=0.1)
    s, d = np.concatenate([s0, s1, sx]), np.concatenate([d0, d1, dx])
    edges = np.arange(-1.0, 1201.0, 2.0)
    c = 0.5 * (edges[1:] + edges[:-1])
    level = np.where(c < 700.0, 12.0, 8.4)
    level[c == 700.0] = 5.8
    level[(c > 700.0) & (c < 730.0)] = np.nan
    steps = edge_steps(s, d, edges, level)
    assert steps.stations.size == 1
    assert abs(steps.stations[0] - 700.0) < 1.0
    np.testing.assert_allclose(steps.offsets - steps.offsets[0], [0.0, -3.6], atol=0.05)


def _gap_case(rng, outer_after: float, after: float = 2.4, peel: bool = False):
    """Median-side edge 13.7 m from the car until 620 m, unseen 620-720 m (a truck), then
    ``after``; the other edge 6.0 m before the gap and ``outer_after`` after it, seen on
    both sides of the gap except 720-800 m (the same truck). ``peel``: the exit's edge
    is seen leaving the level over the last 8 m before the gap."""
    s0, d0 = _line(rng, 0.0, 620.0, lambda s: np.full(s.size, 13.7))
    s1, d1 = _line(rng, 720.0, 1200.0, lambda s: np.full(s.size, after))
    o0, a0 = _line(rng, 0.0, 620.0, lambda s: np.full(s.size, 6.0))
    o1, a1 = _line(rng, 800.0, 1200.0, lambda s: np.full(s.size, outer_after))
    if peel:
        d0 = np.where(s0 > 612.0, 13.7 + 0.04 * (s0 - 612.0) ** 2, d0)
    s, d = np.concatenate([s0, s1]), np.concatenate([d0, d1])
    edges = np.arange(-1.0, 1201.0, 2.0)
    across = (np.concatenate([o0, o1]), np.concatenate([a0, a1]))
    return edge_steps(s, d, edges, edge_level_path(s, d, edges), across=lambda: across)


def test_a_step_hidden_in_an_occlusion_is_told_by_the_carriageway_width():
    # Three lanes leave on the median side (a left fork) while a truck hides the edge:
    # the edge is 11.3 m nearer after the gap while the other edge moved 2.4 m away (the
    # car moved a lane to the left meanwhile): the carriageway is 8.9 m narrower. Without
    # the step the reference line swung 11 m across the lanes over the gap
    # (oakland-28393854-lane1 with a noisier sensor: edge RMSE 1.5 m).
    steps = _gap_case(np.random.default_rng(21), outer_after=8.4)
    assert steps.stations.size == 1
    assert abs(steps.stations[0] - 670.0) < 2.0  # the gap's middle
    np.testing.assert_allclose(steps.offsets - steps.offsets[0], [0.0, -11.3], atol=0.05)


def test_a_level_change_across_an_occlusion_with_the_width_kept_is_no_step():
    # The same gap, but the other edge moved out as far as this one moved in: the car
    # changed lanes unseen, the road did not change.
    steps = _gap_case(np.random.default_rng(22), outer_after=6.0 + 11.3)
    assert steps.stations.size == 0


def test_a_step_hidden_in_an_occlusion_lies_where_the_ramp_edge_peeled_off():
    # The exit's edge was seen leaving the level right before the gap: the gore is there
    steps = _gap_case(np.random.default_rng(23), outer_after=8.4, peel=True)
    assert steps.stations.size == 1
    assert abs(steps.stations[0] - 620.0) < 2.0


def test_one_lane_ending_unseen_over_a_long_gap_is_bridged_as_a_taper():
    # 3.6 m over a 100 m gap is slower than a lane taper (0.06 m/m): the fit bridges it
    # and the lane structure around stays as seen (town06-auto-s2: a step there moved
    # the reference line's anchor and esmini's car jumped at two junctions)
    steps = _gap_case(np.random.default_rng(24), outer_after=6.0, after=13.7 - 3.6)
    assert steps.stations.size == 0


def test_an_exit_step_lies_where_the_ramp_edge_leaves_not_at_the_nose():
    # A left exit: the ramp's edge leaves the road's edge (12 m) at 600 m and bends away;
    # the nose, where the new edge 3.6 m nearer the carriageway begins, is at 620 m. The
    # leaving lane belongs to the ramp from 600 m (HD maps split there; CARLA Town06's
    # inner exits 11-20 m before the nose), and the ramp's edge inside the gore area is
    # not the road's.
    rng = np.random.default_rng(31)
    s0, d0 = _line(rng, 0.0, 620.0, lambda s: 12.0 + 0.01 * np.clip(s - 600.0, 0.0, None) ** 2)
    s1, d1 = _line(rng, 620.0, 1200.0, lambda s: np.full(s.size, 8.4))
    s2, d2 = _line(rng, 620.0, 660.0, lambda s: 12.0 + 0.01 * (s - 600.0) ** 2)
    s, d = np.concatenate([s0, s1, s2]), np.concatenate([d0, d1, d2])
    steps = _steps_of(s, d)
    assert steps.stations.size == 1
    assert 597.0 < steps.stations[0] < 603.0
    np.testing.assert_allclose(steps.offsets - steps.offsets[0], [0.0, -3.6], atol=0.05)
    (area,) = steps.areas
    assert abs(area[1] - 620.0) < 2.0
    ramp = steps.ramp_points(s, d)
    assert np.all(ramp[(s > 605.0) & (s < 618.0) & (d > 12.5)])
    assert not np.any(ramp[np.abs(d - 8.4) < 0.3])


def test_an_entry_step_lies_at_the_nose():
    # The road's edge nearer the carriageway ends at the nose (500 m) and the new lane's
    # edge comes in from beyond (1.6 m out at the nose), reaching its level (12 m) 20 m
    # after it. Unlike an exit's, an entry's lane begins at the nose (Town06's inner
    # entries; OSM-derived maps split every ramp there): placed 17 m after it, the step
    # put Town06's edge 3.7 m off.
    rng = np.random.default_rng(32)
    s0, d0 = _line(rng, 0.0, 500.0, lambda s: np.full(s.size, 8.4))
    s1, d1 = _line(rng, 500.0, 1200.0, lambda s: 12.0 + 0.004 * np.clip(520.0 - s, 0.0, None) ** 2)
    steps = _steps_of(np.concatenate([s0, s1]), np.concatenate([d0, d1]))
    assert steps.stations.size == 1
    assert 498.0 < steps.stations[0] < 502.0
    assert steps.areas.shape == (0, 3)


def test_a_step_station_belongs_to_the_segment_it_begins():
    # The lane section after a step starts at its station; evaluated there with the
    # offset before the step, the inner shoulder of a noisier oakland run began 11.5 m
    # wide and the seal left a 1 m bump that made esmini's car jump
    from roadtwin.mainline.edge_levels import EdgeSteps

    steps = EdgeSteps(np.array([1375.0]), np.array([0.0, -10.9]))
    np.testing.assert_allclose(steps.at(np.array([1374.9, 1375.0, 1375.1])), [0.0, -10.9, -10.9])


def test_a_noisier_sensors_scattered_levels_are_followed_not_left_unseen():
    """Each 2 m bin's level scatters by 0.15 m (a noisier sensor): an entry's new outer
    edge (7 m -> 10.5 m at 100 m, the ramp's edge beside the mainline's before it) is
    followed from the gore on; with the configured 0.15 m sigma alone the path went on
    unseen at 7 m for 40 m, that cost less per bin than following the scatter."""
    rng = np.random.default_rng(11)
    s = np.arange(0.0, 300.0, 0.25)
    jitter = rng.normal(0.0, 0.15, 150)[(s // 2.0).astype(int)]  # one offset per bin
    d = np.where(s < 100.0, 7.0, 10.5) + jitter + rng.normal(0.0, 0.03, s.size)
    ramp = (s > 40.0) & (s < 100.0)  # the ramp's edge before the gore
    s = np.concatenate([s, s[ramp]])
    d = np.concatenate([d, 10.6 + rng.normal(0.0, 0.05, np.count_nonzero(ramp))])
    edges = np.arange(0.0, 301.0, 2.0)
    level = edge_level_path(s, d, edges)
    c = 0.5 * (edges[1:] + edges[:-1])
    after = c > 102.0
    assert np.mean(np.isfinite(level[after])) > 0.95
    assert np.nanmax(np.abs(level[after] - 10.5)) < 0.6
    before = c < 98.0
    assert np.nanmax(np.abs(level[before] - 7.0)) < 0.6


def _entry_before_gap(seen_after_nose_m: float):
    """An entry's nose at 500 m: the shoulder edge at 8.3 m before it, the new lane's edge
    at 14.3 m (a noisier sensor: points every 0.3 m, 0.08 m scatter) seen for
    ``seen_after_nose_m`` after it,
    then nothing for 80 m (a truck beside the car), the edge at 10.8 m beyond (the lane
    tapered away unseen)."""
    rng = np.random.default_rng(21)
    gap0 = 500.0 + seen_after_nose_m
    kw = {"spacing": 0.3, "noise": 0.08}
    parts = [
        _line(rng, 0.0, 500.0, lambda s: np.full(s.size, 8.3), **kw),
        _line(rng, 500.0, gap0, lambda s: np.full(s.size, 14.3), **kw),
        _line(rng, gap0 + 80.0, 800.0, lambda s: np.full(s.size, 10.8), **kw),
        # the ramp's edge converging onto the new lane's before the nose
        _line(rng, 440.0, 500.0, lambda s: 14.3 + 0.03 * (500.0 - s), **kw),
    ]
    s = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts])
    edges = np.arange(-1.0, 801.0, 2.0)
    return 0.5 * (edges[1:] + edges[:-1]), edge_level_path(s, d, edges)


def test_the_new_lanes_edge_seen_after_an_entrys_nose_is_followed():
    """a9-206615404-s1+380 (noisier sensor): the new lane's edge seen for 24 m after the
    nose (here 20 m), then an 80 m gap. Going on unseen at the shoulder's level under it
    cost 0.6 per bin, following the scattered level and stepping up 0.2 less: the path
    stayed at the shoulder, the lane's line outside it was dropped as a ramp's, and the
    edge was 5.9 m off. An own edge hidden while another road's is seen is short-lived (a
    vehicle beside the car hides both); beyond 5 bins going on unseen costs double."""
    c, level = _entry_before_gap(20.0)
    after_nose = (c > 502.0) & (c < 518.0)
    assert np.all(np.abs(level[after_nose] - 14.3) < 0.3)
    assert np.all(np.abs(level[(c > 420.0) & (c < 498.0)] - 8.3) < 0.3)


def test_an_outer_level_seen_briefly_after_a_step_may_still_be_gone_around():
    """The same with the outer level seen for 6 m only: stepping out to it and back costs
    more than going on unseen under it for 3 bins, which stays the cheaper path."""
    c, level = _entry_before_gap(6.0)
    assert not np.any(np.abs(level[(c > 500.0) & (c < 506.0)] - 14.3) < 0.3)


def test_most_of_a_step_seen_in_the_width_is_a_step_though_the_other_edge_moved_too():
    """melbourne-1019-lane1-s21 with a noisier sensor: an inner exit's 3.4 m step hidden
    in a 96 m gap, at whose far end the other edge has an exit's nose of its own: the
    width changed by 1.9 m only. Against a fixed 2 m the step was bridged as the car's
    lane change, the edge 3 m off; the car's own lane change keeps the width."""
    from roadtwin.config import MainlineConfig
    from roadtwin.mainline.edge_levels import _width_changes

    centres = np.arange(401.0, 1000.0, 2.0)
    gap = (590.0, 686.0)
    level = np.where(centres <= gap[0], 0.0, -3.4)
    level[(centres > gap[0]) & (centres < gap[1])] = np.nan
    across = np.where(centres <= gap[0], 15.9, 17.4)  # moved 1.5 m out
    cfg = MainlineConfig()
    assert _width_changes(gap, -3.4, centres, level, across, cfg)
    lane_change = np.where(centres <= gap[0], 15.9, 19.3)  # the car moved 3.4 m
    assert not _width_changes(gap, -3.4, centres, level, lane_change, cfg)
    # a three-lane fork still needs 2 m of width change: 1.9 m is the car's lane change
    # while the other edge moved too
    fork = np.where(centres <= gap[0], 0.0, -11.3)
    fork[np.isnan(level)] = np.nan
    other = np.where(centres <= gap[0], 15.9, 15.9 + 9.4)
    assert not _width_changes(gap, -11.3, centres, fork, other, cfg)
