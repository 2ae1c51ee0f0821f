"""Lines beside a gore that were cut or left apart although they were the mainline's.

Runs with a noisier sensor (bench_real ``--noisy --seed-offset 320``).
krems-46762523-opp-s4:

* at the run's start the outer edge was unseen from 15 to 50 m; the line between the
  outer two lanes was first seen at 10 m, the one between the inner two at 20 m. Measured
  from the nearest line inward, the outer line "fell" by 3.7 m where that line began, and
  it was cut back to 24 m as a ramp line converging onto a gore: the two lanes were one
  10 m wide over the first 24 m and a route led nowhere;
* at a two-lane exit the line left as the mainline's edge line was broken for 11 m at the
  gore (the ramp's lines leave it there). Right after the gore the edge lies 0.2 m beyond
  it, so the line was taken for one the road is too narrow to hold and the two parts were
  not joined: a lane opened over 220 m to reach the second part (lanes 0.171 m RMSE).

melbourne-1019-lane1-s21: an entry's line ran parallel 3 m beyond the edge, then bent in
to meet the outermost line at the nose, all in a 110 m gap of the edge. Its samples were
left out as beyond the edge up to the gap and kept in it: it was the outermost marking
there and the edge bridged a shoulder's width beyond it, 5.9 m off (edge 0.988 m RMSE).
"""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.config import MainlineConfig
from roadtwin.mainline.hidden_gores import _place_hidden_gores, _snap_to_hidden_gores
from roadtwin.mainline.markings import _merge_collinear, _Track

CFG = MainlineConfig()
stations = np.arange(0.0, 900.5, CFG.grid_step_m)


def _line(k: int, lo: float, hi: float, d: float, *, drift: float = 0.0) -> _Track:
    """A line at ``d`` metres, drifting by ``drift`` m/m over its first 15 m."""
    g = stations[(lo <= stations) & (stations <= hi)]
    d_g = d + drift * np.minimum(g - lo, 15.0)
    return _Track(k, float(g[0]), float(g[-1]), g, d_g, "broken", g.size, g)


def test_a_line_inward_first_seen_later_is_no_convergence():
    tracks = [
        _line(0, 5.0, 400.0, 0.6),
        _line(1, 10.0, 400.0, 7.96, drift=-0.005),  # the noisy smoothing's start
        _line(2, 20.0, 400.0, 4.23),
    ]
    covered = (stations < 15.0) | (stations > 50.0)
    out, gores = _snap_to_hidden_gores(tracks, [], covered, stations, CFG)
    assert gores.size == 0
    assert [tr.lo for tr in out] == [5.0, 10.0, 20.0]


def test_a_ramp_line_converging_in_a_gap_is_still_cut_at_its_gore():
    # the same outer line, converging by 3 m onto the line inward before it runs on
    g = stations[stations >= 60.0]
    d = 7.9 + 3.0 * np.clip((110.0 - g) / 50.0, 0.0, 1.0)
    ramp = _Track(1, 60.0, 400.0, g, d, "broken", g.size, g)
    tracks = [_line(0, 0.0, 400.0, 0.6), ramp, _line(2, 0.0, 400.0, 4.23)]
    covered = (stations < 50.0) | (stations > 120.0)
    out, gores = _snap_to_hidden_gores(tracks, [], covered, stations, CFG)
    assert gores.size == 1
    assert abs(gores[0] - 110.0) < 3.0
    assert abs(out[1].lo - gores[0]) < 1e-9


def _edge(after: float, *, step_at: float = 107.0, entry_at: float | None = None) -> np.ndarray:
    """The outer edge: a lane and a shoulder beyond the line at 8.1 m up to the gore,
    ``after`` metres beyond the reference line after it (a lane again from ``entry_at``)."""
    edge = np.where(step_at > stations, 14.2, after)
    if entry_at is not None:
        edge = np.where(entry_at <= stations, 14.2, edge)
    return edge


def test_a_line_broken_at_a_gore_goes_on_as_the_edge_line():
    before, after = _line(0, 0.0, 100.0, 8.09), _line(1, 111.0, 400.0, 8.10)
    joined = _merge_collinear([before, after], CFG, stations, _edge(8.3))
    assert len(joined) == 1
    assert (joined[0].lo, joined[0].hi) == (0.0, 400.0)


def test_a_line_across_a_road_too_narrow_for_it_stays_apart():
    # an exit's lane line and a later entry's at the same offset: between them the road
    # ends inside the line (real_a9), and where it goes on the edge is a lane beyond it
    before, after = _line(0, 0.0, 100.0, 8.09), _line(1, 160.0, 400.0, 8.10)
    apart = _merge_collinear([before, after], CFG, stations, _edge(7.8, entry_at=158.0))
    assert len(apart) == 2
    # the edge line of a road narrowing 0.2 m beyond it over the whole gap: apart too
    # where the line was a lane away from the edge on both sides
    apart = _merge_collinear([before, after], CFG, stations, _edge(8.3, entry_at=158.0))
    assert len(apart) == 2


def _entry_line(lo: float = 586.0, nose: float = 681.0) -> _Track:
    """An entry's line 3 m beyond the edge (14.2 m) up to 610 m, then bending in to meet
    the outermost line (11.6 m) at ``nose``, to 0.1 m."""
    g = np.arange(lo, nose + 0.5, 1.0)
    x = np.clip((g - 610.0) / (nose - 610.0), 0.0, 1.0)
    d = 17.2 - (17.2 - 11.7) * (3.0 * x**2 - 2.0 * x**3)
    return _Track(1, float(g[0]), float(g[-1]), g, d, "broken", g.size, g)


def test_a_ramp_line_beside_the_road_in_a_gap_is_the_ramps_up_to_the_nose():
    grid = np.arange(0.0, 900.5, 1.0)
    outer = _Track(0, 0.0, 900.0, grid, np.full(grid.size, 11.6), "solid", grid.size, grid)
    covered = (grid < 585.0) | (grid > 696.0)
    d_edge = np.where(grid < 690.0, 14.2, 18.8)
    out, gores = _snap_to_hidden_gores([outer, _entry_line()], [], covered, grid, CFG, d_edge)
    assert gores.size == 1
    assert 670.0 <= gores[0] <= 682.0
    assert out[1].lo == gores[0]
    # first seen inside the edge: a line of the road's own, kept
    inside = _entry_line()
    inside.d[:] -= 3.5
    out, gores = _snap_to_hidden_gores([outer, inside], [], covered, grid, CFG, d_edge)
    assert out[1].lo == 586.0
    # the exit's mirror: a line leaving the outermost one, beside the road up to the gap's end
    mirror = _entry_line()
    exit_line = _Track(
        1,
        1800.0 - mirror.hi,
        1800.0 - mirror.lo,
        (1800.0 - mirror.s)[::-1],
        mirror.d[::-1],
        "broken",
        mirror.n,
        (1800.0 - mirror.s)[::-1],
    )
    grid2 = np.arange(0.0, 1800.5, 1.0)
    outer2 = _Track(0, 0.0, 1800.0, grid2, np.full(grid2.size, 11.6), "solid", grid2.size, grid2)
    covered2 = (grid2 < 1800.0 - 696.0) | (grid2 > 1800.0 - 585.0)
    d_edge2 = np.where(grid2 > 1800.0 - 690.0, 14.2, 18.8)
    out, gores = _snap_to_hidden_gores([outer2, exit_line], [], covered2, grid2, CFG, d_edge2)
    assert gores.size == 1
    assert out[1].hi == gores[0]
    assert 1800.0 - 682.0 <= gores[0] <= 1800.0 - 670.0


def _acceleration_line() -> _Track:
    """An acceleration lane's line from an entry's nose at 523 m: 2.8 m beyond the
    outermost line (8.2 m) over 25 m, then closing onto it by 624 m (to 0.1 m)."""
    g = np.arange(523.0, 624.5, 1.0)
    x = np.clip((g - 548.0) / (624.0 - 548.0), 0.0, 1.0)
    d = 11.0 - (11.0 - 8.3) * (3.0 * x**2 - 2.0 * x**3)
    return _Track(3, float(g[0]), float(g[-1]), g, d, "broken", g.size, g)


@pytest.mark.parametrize(("edge_before", "kept"), [(8.4, True), (10.0, False)])
def test_a_line_going_on_from_a_nose_seen_before_a_gap_is_the_roads(edge_before, kept):
    """a9-206615404-s7 with a noisier sensor (seed offset 920): an entry's nose was seen
    3 m before a 100 m gap of the outer edge, the edge 0.2 m beyond the outermost line
    there; the acceleration lane's line began at the nose, 2.8 m beyond that edge, and was
    cut back to its last 8 m as a ramp's line beside the road. The lane was built 3.7 m
    wide over its taper, 1.8 m off (edge 0.121 -> 0.056 m, lanes 0.145 -> 0.057 m). With
    the edge a shoulder's width out before the gap the line is still the ramp's."""
    grid = np.arange(0.0, 900.5, 1.0)
    lines = [
        _Track(k, 0.0, 900.0, grid, np.full(grid.size, d), "solid", grid.size, grid)
        for k, d in enumerate((0.7, 4.45, 8.2))
    ]
    covered = (grid < 518.0) | (grid > 615.0)
    d_edge = np.where(grid < 560.0, edge_before, 10.8)
    out, _ = _snap_to_hidden_gores([*lines, _acceleration_line()], [], covered, grid, CFG, d_edge)
    assert (out[3].lo == 523.0) is kept
    if not kept:
        assert out[3].lo >= 610.0


def test_an_edge_line_leaving_the_edge_where_a_lane_opens_stays_apart():
    """oakland-28393854-lane1-s21 with a noisier sensor (seed offset 320): the edge line
    (on the edge) went on, unseen for 30 m, as the line of a lane opening beside it by a
    taper; joined, it was one track, no section began there and the new lane was typed a
    shoulder over 190 m (lane count 96 -> 90 %)."""
    before, after = _line(0, 0.0, 579.0, 12.14), _line(1, 610.0, 900.0, 12.08)
    edge = 12.11 + np.clip((stations - 580.0) / 100.0, 0.0, 1.0) * 3.4
    apart = _merge_collinear([before, after], CFG, stations, edge)
    assert len(apart) == 2


def test_an_entry_line_first_seen_after_the_gap_that_hid_its_nose_has_its_gore_in_it():
    """melbourne-408-opp-s4 with a noisier sensor (seed offset 320): the outer edge was
    unseen from 214 to 269 m, where an entry's nose lay (268 m), the shoulder narrowing
    towards it; its lane's outer line was first seen at 283 m, but the edge right after
    the gap already lay a lane and a shoulder beyond the line inward. The line's start
    14 m past the gap put no gore in it: the lane was opened by a taper across the gap and
    the edge bridged 4-5 m off (edge 0.420 -> 0.090 m RMSE)."""
    grid = np.arange(0.0, 700.5, 1.0)
    through = _Track(0, 0.0, 700.0, grid, np.full(grid.size, 7.76), "broken", grid.size, grid)
    g = grid[grid >= 283.0]
    outer = _Track(1, 283.0, 700.0, g, np.full(g.size, 11.32), "broken", g.size, g)
    covered = (grid < 214.0) | (grid > 269.0)
    rng = np.random.default_rng(3)
    s_out = np.arange(0.0, 700.0, 0.5)
    shoulder = 7.76 + np.clip(2.0 * (268.0 - s_out) / 120.0, 0.0, 2.0)
    d_out = np.where(s_out < 268.0, shoulder, 13.69) + rng.normal(0.0, 0.04, s_out.size)
    seen = (s_out < 214.0) | (s_out > 269.0)
    out, placed, _ = _place_hidden_gores(
        [through, outer], s_out[seen], d_out[seen], covered, grid, 60.0
    )
    assert len(placed) == 1
    assert 214.0 <= placed[0] <= 269.0
    assert out[1].lo == pytest.approx(placed[0], abs=1.0)
    # where the edge after the gap is still the shoulder beside the line inward, the
    # line's late start is its own (a lane opening later): nothing is placed
    d_flat = np.where(s_out < 268.0, shoulder, 9.3)
    _, placed, _ = _place_hidden_gores(
        [through, outer], s_out[seen], d_flat[seen], covered, grid, 60.0
    )
    assert placed == []


def _exit_case(gap: tuple[float, float] = (431.0, 486.0)):
    """An exit's mirror of the entry above: the outer line last seen at 417 m, the edge
    unseen over ``gap`` (stations, metres), a lane and a shoulder beyond the line up to it."""
    grid = np.arange(0.0, 700.5, 1.0)
    through = _Track(0, 0.0, 700.0, grid, np.full(grid.size, 7.76), "broken", grid.size, grid)
    g = grid[grid <= 417.0]
    outer = _Track(1, 0.0, 417.0, g, np.full(g.size, 11.32), "broken", g.size, g)
    covered = (grid < gap[0]) | (grid > gap[1])
    rng = np.random.default_rng(5)
    s_out = np.arange(0.0, 700.0, 0.5)
    shoulder = 7.76 + np.clip(2.0 * (s_out - gap[0]) / 120.0, 0.0, 2.0)
    d_out = np.where(s_out < gap[0], 13.69, shoulder) + rng.normal(0.0, 0.04, s_out.size)
    seen = (s_out < gap[0]) | (s_out > gap[1])
    return [through, outer], s_out[seen], d_out[seen], covered, grid


def test_an_exit_line_last_seen_before_the_gap_has_its_gore_in_it():
    """krems-46762523-s2 (seed offset 320): an exit's lane line ended 14 m before the gap
    that hid the nose, the edge still a lane beyond it there: no gore, the lane closed by a
    250 m taper (edge 0.229 -> 0.056 m with the gore in the gap). Not where a ramp's line
    showed the gore in the gap (kotka-33042885-s3, seed offset 200: the gore moved off
    it, 0.062 -> 0.073 m), at a gap of a metre after a seen step (melbourne-1019-s11,
    seed offset 200: 0.093 -> 0.115 m) or where a step was seen at the line's end."""
    tracks, s_out, d_out, covered, grid = _exit_case()
    out, placed, _ = _place_hidden_gores(tracks, s_out, d_out, covered, grid, 60.0)
    assert len(placed) == 1
    assert 431.0 <= placed[0] <= 486.0
    assert out[1].hi == pytest.approx(placed[0], abs=1.0)
    _, placed, _ = _place_hidden_gores(
        tracks, s_out, d_out, covered, grid, 60.0, line_gores=np.array([450.0])
    )
    assert placed == []
    _, placed, _ = _place_hidden_gores(*_exit_case(gap=(431.0, 431.0))[:5], 60.0)
    assert placed == []
    # the edge seen stepping in where the line ended (a9-206615404-s2, seed offset 200)
    seen_step = (np.array([417.0]), np.array([False]))
    _, placed, _ = _place_hidden_gores(tracks, s_out, d_out, covered, grid, 60.0, seen_step)
    assert placed == []


def test_a_lane_line_meeting_the_line_inward_outside_the_gap_is_not_cut():
    """krems-102561705-opp-s7 with a noisier sensor (seed offset 140): a new lane's line
    split from the outermost one (5673 m), ran a lane out beside the seen edge for 150 m
    and ended in a gap where the lane dropped, beyond the edge seen after it; taken for
    an exit's line beside the road, it was cut back to its first metre (edge 0.079 ->
    0.106 m). It met the line inward before the gap, where the edge lay beyond it."""
    grid = np.arange(0.0, 1000.5, 1.0)
    inner = _Track(0, 0.0, 1000.0, grid, np.full(grid.size, 7.95), "broken", grid.size, grid)
    g = np.arange(673.0, 885.5, 1.0)
    d = 8.05 + 3.4 * np.clip((g - 673.0) / 50.0, 0.0, 1.0)
    line = _Track(1, 673.0, 885.0, g, d, "broken", g.size, g)
    covered = ~(((grid >= 664.0) & (grid <= 692.0)) | ((grid >= 870.0) & (grid <= 888.0)))
    d_edge = np.where(grid < 664.0, 10.5, np.where(grid > 888.0, 10.5, 14.2))
    out, gores = _snap_to_hidden_gores([inner, line], [], covered, grid, CFG, d_edge)
    assert (out[1].lo, out[1].hi) == (673.0, 885.0)
    assert not np.any((gores > 660.0) & (gores < 690.0))


def _lane_gain_in_gap(after: float) -> tuple[list[_Track], np.ndarray, np.ndarray]:
    """Four lines, the outermost at 11.8 m; the outer edge unseen from 551 to 694 m, seen
    at 14.9 m before and ``after`` metres beyond."""
    tracks = [_line(k, 0.0, 900.0, d) for k, d in enumerate((1.2, 4.7, 8.3, 11.8))]
    covered = (stations < 551.0) | (stations > 694.0)
    d_edge = np.interp(stations, [551.0, 694.0], [14.9, after])
    return tracks, covered, d_edge


def test_a_line_leaving_where_the_edge_widens_is_a_lane_gains_not_a_gore():
    """oakland-28393854-lane1-s21+380 (noisier sensor): a lane gained by a taper inside a
    143 m gap of the edge; its new edge line, leaving the old one at 581 m, was cut off as
    an exit's ramp line and the gore placed there stepped the edge out, the shoulder
    before it closing to the gore (edge 0.337 m RMSE, 3.6 m off)."""
    tracks, covered, d_edge = _lane_gain_in_gap(18.7)
    _, gores = _snap_to_hidden_gores(tracks, [(581.0, 11.83, True)], covered, stations, CFG, d_edge)
    assert gores.size == 0
    # a line meeting the outermost one there is an entry's: the edge widens at its gore
    _, gores = _snap_to_hidden_gores(
        tracks, [(581.0, 11.83, False)], covered, stations, CFG, d_edge
    )
    np.testing.assert_allclose(gores, [581.0], atol=1.0)


def test_a_line_leaving_where_the_edge_narrows_is_an_exits():
    tracks, covered, d_edge = _lane_gain_in_gap(11.4)
    _, gores = _snap_to_hidden_gores(tracks, [(581.0, 11.83, True)], covered, stations, CFG, d_edge)
    np.testing.assert_allclose(gores, [581.0], atol=1.0)
    _, gores = _snap_to_hidden_gores(
        tracks, [(581.0, 11.83, False)], covered, stations, CFG, d_edge
    )
    assert gores.size == 0


@pytest.mark.parametrize("entry", [True, False])
def test_a_ramp_line_seen_from_the_gaps_start_is_cut_at_the_gore_on_its_side(entry):
    """a9-10959882-opp-s7 with a noisier sensor (seed offset 620): the outer edge unseen
    from 352 to 425 m, an entry's nose at 419 m (a ramp line met the outermost line
    there). The ramp's line, seen from the gap's start 66 m before the nose and linked on
    past it for 37 m, was cut to *end* at the nose as if an exit's: the ramp's lane was
    the mainline's over 66 m, 5.7 m wide beside three shoulders (edge 0.351 m). Cut at the
    entry's gore it begins there; mirrored for an exit."""
    x = stations if entry else 900.0 - stations

    def line(k, d):
        return _Track(k, 0.0, 900.0, stations, np.full(stations.size, d), "broken", 1, stations)

    ramp_x = (x >= 353.0) & (x <= 456.0)
    g = stations[ramp_x]
    d = np.interp(x[ramp_x], [353.0, 419.0, 456.0], [13.8, 10.9, 9.8])
    ramp = _Track(3, float(g[0]), float(g[-1]), g, d, "solid", g.size, g)
    tracks = [line(0, 0.8), line(1, 4.5), line(2, 8.1), ramp]
    covered = (x < 352.0) | (x > 425.0)
    gore = 419.0 if entry else 481.0
    out, gores = _snap_to_hidden_gores(tracks, [(gore, 8.27, not entry)], covered, stations, CFG)
    assert gores.tolist() == [gore]
    cut = out[3]
    if entry:
        assert (cut.lo, cut.hi) == (gore, 456.0)
    else:
        assert (cut.lo, cut.hi) == (444.0, gore)
    assert [(tr.lo, tr.hi) for tr in out[:3]] == [(0.0, 900.0)] * 3
