"""The median-side edge where it is unseen beside a gore moves with the lines seen there.

Town06 (the benchmark's town06-auto-s2): after an inner exit's gore the mainline's median
edge was unseen for 60 m while the remaining lanes swung back towards the median by a
lane width. Carried across at its old level, the edge lay 3.3 m off and an invented lane
tapered to zero between it and the lanes (edge RMSE 0.200 m; 0.075 m with the move)."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.mainline._common import BoundaryTrack
from roadtwin.mainline.median_moves import (
    edge_moves,
    shoulder_moves,
    unseen_stretches,
    with_edge_moves,
)
from roadtwin.mainline.reference import _unseen_beside_gores
from roadtwin.model import CubicPiece, CubicProfile

GRID = np.arange(0.0, 301.0, 1.0)


def _track(track_id: int, d: np.ndarray, n_samples: int = 500) -> BoundaryTrack:
    return BoundaryTrack(track_id, GRID, d, "broken", n_samples)


def _swing(start: float, end: float, d0: float, d1: float) -> np.ndarray:
    """An offset going from ``d0`` to ``d1`` between stations ``start`` and ``end``
    (smoothstep), constant either side."""
    x = np.clip((GRID - start) / (end - start), 0.0, 1.0)
    return d0 + (d1 - d0) * x * x * (3.0 - 2.0 * x)


def test_the_edge_follows_the_innermost_line_seen_beyond_the_gap():
    # an inner exit's gore at 100 m, the edge seen again at 160 m; the inner shoulder line
    # is inferred (no samples), the line the car sees swings 3.5 m towards the median
    tracks = (
        _track(1, np.full(GRID.size, 1.1), n_samples=0),
        _track(2, _swing(105.0, 160.0, 8.1, 4.6)),
        _track(3, _swing(105.0, 160.0, 11.6, 8.1)),
    )
    move, gores = edge_moves(np.array([[100.0, 160.0]]), tracks, GRID)
    assert gores.tolist() == [100.0]
    assert np.all(move[GRID < 100.0] == 0.0)
    assert np.all(move[GRID > 160.0] == 0.0)
    # the edge keeps the 4.6 m to the seen line that it has where it is seen again
    inside = (GRID >= 100.0) & (GRID <= 160.0)
    expected = _swing(105.0, 160.0, 8.1, 4.6)[inside] - 4.6
    assert move[inside] == pytest.approx(expected, abs=1e-9)
    assert move[GRID == 110.0][0] == pytest.approx(3.42, abs=0.01)


def test_an_entry_mirrors_it():
    tracks = (_track(2, _swing(140.0, 195.0, 4.6, 8.1)),)
    move, gores = edge_moves(np.array([[200.0, 140.0]]), tracks, GRID)
    assert gores.tolist() == [200.0]
    assert move[GRID == 195.0][0] == pytest.approx(3.5, abs=1e-9)
    assert np.all(move[(GRID < 140.0) | (GRID > 200.0)] == 0.0)


@pytest.mark.parametrize(
    "tracks",
    [
        # the line seen beyond the gap does not move: an occlusion of the edge alone
        (_track(2, np.full(GRID.size, 4.6)),),
        # the moving line is not seen (inferred): nothing says where the edge went
        (_track(2, _swing(105.0, 160.0, 8.1, 4.6), n_samples=0),),
        # a line that moves by less than a lane's worth (a curve's smoothing)
        (_track(2, _swing(105.0, 160.0, 5.6, 4.6)),),
    ],
)
def test_no_move_without_a_seen_line_moving_by_a_lane(tracks):
    move, gores = edge_moves(np.array([[100.0, 160.0]]), tracks, GRID)
    assert not np.any(move)
    assert gores.size == 0


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_the_lane_offset_carries_the_move(sign):
    """The centre lane moves towards the carriageway by the move (t negative for
    right-hand traffic), steps at the gore, and runs back onto the step profile without a
    gap where the edge is seen again."""
    base = CubicProfile((CubicPiece(0.0, 0.0), CubicPiece(250.0, sign * 3.5)))
    move = np.where((GRID >= 100.0) & (GRID <= 160.0), _swing(100.0, 160.0, 3.5, 0.0), 0.0)
    prof = with_edge_moves(base, GRID, move, sign, np.array([100.0]))
    s = np.arange(0.0, 300.0, 0.25)
    expected = base.value(s) - sign * np.interp(s, GRID, move) * (s >= 100.0)
    assert prof.value(s) == pytest.approx(expected, abs=0.02)  # linear records every 4 m
    # a step at the gore, none where the move ends, the median step kept
    assert prof.value(np.array([100.0]))[0] - prof.value(np.array([99.999]))[0] == pytest.approx(
        -sign * 3.5, abs=1e-6
    )
    for at in (161.0, 250.0):
        jump = prof.value(np.array([at]))[0] - prof.value(np.array([at - 1e-6]))[0]
        assert jump == pytest.approx(sign * 3.5 if at == 250.0 else 0.0, abs=1e-6)
    assert with_edge_moves(base, GRID, np.zeros(GRID.size), sign) is base
    # a move that is not at a gore runs in and out without a step (a shoulder's line
    # followed across an unseen stretch)
    bump = np.where((GRID > 120.0) & (GRID < 180.0), np.sin(np.pi * (GRID - 120.0) / 60.0), 0.0)
    prof = with_edge_moves(base, GRID, bump, sign)
    s = np.arange(0.0, 240.0, 0.01)
    assert np.max(np.abs(np.diff(prof.value(s)))) < 0.01
    assert prof.value(np.array([150.0]))[0] == pytest.approx(-sign * 1.0, abs=0.02)


def test_an_excursion_unseen_after_the_gore_hides_the_edge_beside_it():
    """Level path on 2 m bins: the ramp's edge peels off over 200-214 m, then nothing is
    seen up to 270 m, where the edge is back at its level."""
    centres = np.arange(1.0, 400.0, 2.0)
    level = np.zeros(centres.size)
    peel = (centres > 200.0) & (centres < 214.0)
    level[peel] = 0.25 * (centres[peel] - 200.0)
    level[(centres >= 214.0) & (centres < 270.0)] = np.nan
    spans = np.array([[200.0, 270.0]])
    rows = _unseen_beside_gores(centres, level, spans)
    assert rows.tolist() == [[214.0, 270.0]]
    # seen up to the nose: nothing hidden beside the gore
    level[(centres >= 214.0) & (centres < 230.0)] = 3.0
    level[(centres >= 230.0) & (centres < 270.0)] = 0.0
    assert _unseen_beside_gores(centres, level, spans).shape == (0, 2)


def _shoulder_run(line: np.ndarray, rng: np.random.Generator, *, seen_every_m: float = 2.0):
    """Lane samples along ``line`` (offsets on GRID) every ``seen_every_m`` metres, and
    median-side edge points every metre at offset 0 except over 100-190 m."""
    s_lane = np.arange(0.0, 300.0, seen_every_m)
    d_lane = np.interp(s_lane, GRID, line) + rng.normal(0.0, 0.03, s_lane.size)
    s_edge = np.arange(0.0, 300.0, 1.0)
    s_edge = s_edge[(s_edge < 100.0) | (s_edge > 190.0)]
    return s_lane, d_lane, s_edge, rng.normal(0.0, 0.03, s_edge.size)


def test_the_edge_follows_the_inner_shoulder_line_across_an_unseen_stretch():
    """a9-239192816-opp-s12 with a noisier sensor: the shoulder line wandered 1 m over a
    90 m stretch where the edge was unseen; the edge keeps the shoulder's width beside it
    (edge RMSE 0.103 -> 0.062 m)."""
    rng = np.random.default_rng(3)
    wander = np.where((GRID > 100.0) & (GRID < 190.0), np.sin(np.pi * (GRID - 100.0) / 90.0), 0.0)
    shoulder = 0.8 + wander
    lane_line = shoulder + 3.5
    s_lane, d_lane, s_edge, d_edge = _shoulder_run(shoulder, rng)
    d_median = np.zeros(GRID.size)
    gaps = unseen_stretches(s_edge, d_edge, GRID, d_median, 0.8)
    assert [(GRID[a], GRID[b - 1]) for a, b in gaps] == [(100.0, 190.0)]
    tracks = (_track(1, shoulder), _track(2, lane_line))
    move = shoulder_moves(gaps, tracks, s_lane, d_lane, GRID, d_median)
    assert move == pytest.approx(wander, abs=1e-9)
    # the line not seen through the stretch (worn paint over it): the edge stays
    seen = (s_lane < 105.0) | (s_lane > 180.0)
    assert not np.any(shoulder_moves(gaps, tracks, s_lane[seen], d_lane[seen], GRID, d_median))
    # a line wandering by centimetres: the fit's bridging is as good as the line
    s_l, d_l, _, _ = _shoulder_run(0.8 + 0.1 * wander, rng)
    small = (_track(1, 0.8 + 0.1 * wander), _track(2, lane_line))
    assert not np.any(shoulder_moves(gaps, small, s_l, d_l, GRID, d_median))
    # no shoulder line seen, the innermost line a lane away as far from the edge at both
    # ends of the stretch: the edge keeps its distance to it (oakland-28393854-s7 with a
    # noisier sensor, seed offset 440: the shoulder's line seen in a third of the bins of
    # a 145 m stretch, the edge bent 0.8 m with the car's frame; edge 0.108 -> 0.066 m)
    far = shoulder_moves(gaps, (_track(2, lane_line),), s_lane, d_lane + 3.5, GRID, d_median)
    assert far == pytest.approx(wander, abs=1e-9)
    # ... seen as dashes 3 m long every 12 m
    dashes = np.mod(s_lane, 12.0) < 3.0
    dashed = shoulder_moves(
        gaps, (_track(2, lane_line),), s_lane[dashes], d_lane[dashes] + 3.5, GRID, d_median
    )
    assert dashed == pytest.approx(wander, abs=1e-9)
    # ... but a lane farther from the edge past the stretch (a lane gained beside the
    # median in it): the edge stays
    gained = lane_line + 3.5 * (GRID > 150.0)
    s_g = np.arange(0.0, 300.0, 2.0)
    moved = shoulder_moves(
        gaps, (_track(2, gained),), s_g, np.interp(s_g, GRID, gained), GRID, d_median
    )
    assert not np.any(moved)


def test_the_edge_follows_the_shoulder_line_as_far_as_it_is_seen_into_the_stretch():
    """town06-auto-lane2-s22 with a noisier sensor: a lane added beside the median by a
    taper and dropped at an inner exit 70 m on, the edge unseen between. No line is seen
    through the stretch at one distance from the edge, so the fit's straight bridge stood:
    a 70 m slope, 2 m off where the shoulder's line was still seen. Now the shoulder keeps
    its width beside that line as far as it goes (to 160 m here), then the edge runs back
    linearly to where it is seen again (edge 0.330 -> 0.286 m there; krems-30799129-s11
    with a noisier sensor 0.144 -> 0.105 m, its lanes 0.171 -> 0.080 m)."""
    rng = np.random.default_rng(2)
    # the true edge from the fit's straight bridge (d_median = 0): out by 2 m at 160 m
    off = np.interp(GRID, [100.0, 130.0, 160.0, 190.0], [0.0, -2.0, -2.0, 0.0])
    shoulder = 1.2 + off
    lane_line = np.where(GRID < 175.0, 4.7 + off, 1.2)  # a lane dropped at the exit
    end = 160
    tracks = (
        BoundaryTrack(1, GRID[: end + 1], shoulder[: end + 1], "solid", 400),
        BoundaryTrack(2, GRID, lane_line, "broken", 400),
    )
    s_lane = np.arange(0.0, float(end), 2.0)
    d_lane = np.interp(s_lane, GRID, shoulder) + rng.normal(0.0, 0.03, s_lane.size)
    d_median = np.zeros(GRID.size)
    gaps = [(100, 190)]  # the edge unseen from 100 m to 189 m
    move = shoulder_moves(gaps, tracks, s_lane, d_lane, GRID, d_median)
    inside = (GRID >= 100.0) & (GRID <= 160.0)
    np.testing.assert_allclose(move[inside], off[inside], atol=1e-9)
    back = (GRID > 160.0) & (GRID < 190.0)
    np.testing.assert_allclose(move[back], -2.0 * (190.0 - GRID[back]) / 30.0, atol=1e-9)
    assert not np.any(move[(GRID < 100.0) | (GRID >= 190.0)])
    # a line ending 5 m short of the far end is seen (nearly) through: not a part
    near = (BoundaryTrack(1, GRID[:186], shoulder[:186], "solid", 400), tracks[1])
    s_n = np.arange(0.0, 185.0, 2.0)
    d_n = np.interp(s_n, GRID, shoulder)
    assert not np.any(shoulder_moves(gaps, near, s_n, d_n, GRID, d_median))
    # the line worn away inside the stretch: no part
    worn = s_lane < 105.0
    assert not np.any(shoulder_moves(gaps, tracks, s_lane[worn], d_lane[worn], GRID, d_median))


def test_a_move_next_to_a_gore_begins_and_ends_at_the_gore():
    """krems-30799129-s11 with a noisier sensor (seed offset 380): the unseen stretch a
    median-side move covers starts a grid station past an inner exit's gore, where the
    lane section begins; the move begun there left the lanes of that metre fitted to the
    unmoved edge and the lane offset stepped 3.0 m inside the section (the check's
    ``lane_jump``). The move now begins at the gore (and ends at one just past it)."""
    from roadtwin.mainline.reference import _from_gores

    move = np.zeros(GRID.size)
    move[(GRID >= 41.0) & (GRID <= 80.0)] = 2.99
    out = _from_gores(move, GRID, np.array([40.0, 81.0]))
    assert out[40] == pytest.approx(2.99)
    assert out[39] == 0.0
    assert out[81] == 0.0
    assert out[80] == pytest.approx(2.99)
    # no gore within 1.5 grid steps: as it was
    far = _from_gores(move, GRID, np.array([30.0, 95.0]))
    np.testing.assert_array_equal(far, move)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_a_move_begins_at_a_gore_between_grid_stations(sign):
    """melbourne-1226-s11 with a noisier sensor (seed offset 440): the median step (an
    inner entry's gore, where the lane section changes) lies at 531.5 m, between grid
    stations, and the move began at 532 m: the lane offset stepped there by the move
    (0.59 m half a metre inside the section, the check's ``lane_jump``). The move begins
    at the gore at its first station's size, and ends at one between stations."""
    gore_in, gore_out = 100.5, 160.5
    base = CubicProfile(
        (CubicPiece(0.0, 0.0), CubicPiece(gore_in, sign * 3.5), CubicPiece(gore_out, sign * 7.0))
    )
    g = GRID
    move = np.where((g > gore_in) & (g < gore_out), 0.6 + 0.01 * (g - 101.0), 0.0)
    prof = with_edge_moves(base, GRID, move, sign, np.array([gore_in, gore_out]))
    eps = 1e-6
    v = prof.value(np.array([gore_in - eps, gore_in, gore_in + 0.5, 101.0]))
    assert v[1] - v[0] == pytest.approx(sign * 3.5 - sign * 0.6, abs=1e-6)  # one step
    assert v[2] == pytest.approx(v[1], abs=1e-3)  # no second one half a metre on
    assert v[3] == pytest.approx(sign * 3.5 - sign * 0.6, abs=1e-3)
    # held from the last moved station to the gore, then on the step profile
    v = prof.value(np.array([160.0, gore_out - eps, gore_out]))
    assert v[1] == pytest.approx(v[0], abs=1e-6)
    assert v[2] == pytest.approx(sign * 7.0, abs=1e-9)


def test_relevelling_at_a_step_moves_the_records_that_continue_it():
    """Re-levelled at a step, only the record there moved: where a median-side move's
    records (every 4 m) continue it, the border then jumped by the re-levelling a record
    later (2.5 cm inside a lane section). The records that continue the step's record
    move with it, up to the next step."""
    from roadtwin.mainline.reference import _join_lanes_across_offset_steps
    from roadtwin.model import Lane, LaneSection, Line, Road

    def lanes(pred: bool) -> tuple:
        return (
            Lane(-1, "shoulder", CubicProfile.constant(1.0), predecessor=-1 if pred else None,
                 successor=None if pred else -1),
            Lane(-2, "driving", CubicProfile.constant(3.5), predecessor=-2 if pred else None,
                 successor=None if pred else -2),
        )  # fmt: skip

    offset = CubicProfile(
        (
            CubicPiece(0.0, -1.0),
            CubicPiece(40.0, -1.02, -0.001),  # 2 cm off the lanes before the step
            CubicPiece(44.0, -1.024, 0.0),  # continues it
            CubicPiece(70.0, -4.0),  # the next step
        )
    )
    road = Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, 100.0),),
        (LaneSection(0.0, right=lanes(False)), LaneSection(40.0, right=lanes(True))),
        lane_offset=offset,
    )
    joined = _join_lanes_across_offset_steps(road, np.array([40.0, 70.0]))
    at = np.array([40.0 - 1e-6, 40.0, 44.0 - 1e-6, 44.0, 69.0])
    v = joined.lane_offset.value(at)
    assert v[1] == pytest.approx(v[0], abs=1e-9)  # joined at the step
    assert v[3] == pytest.approx(v[2], abs=1e-6)  # and still continuous a record later
    assert v[4] == pytest.approx(-1.004, abs=1e-6)
    assert joined.lane_offset.value(np.array([80.0]))[0] == pytest.approx(-4.0)
