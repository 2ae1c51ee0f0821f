"""Stretch warnings: where the run's own points disagree with the built mainline."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from roadtwin.mainline import poorly_determined
from roadtwin.model import CubicPiece, CubicProfile
from test_mainline import sample_run, truth_road


def _widen(road, section_index: int, lane_index: int, extra_m: float):
    """``road`` with one lane of one section ``extra_m`` wider (its outer borders move)."""
    secs = list(road.lane_sections)
    sec = secs[section_index]
    lanes = list(sec.right)
    lane = lanes[lane_index]
    p0 = lane.width.pieces[0]
    lanes[lane_index] = replace(
        lane, width=CubicProfile((replace(p0, a=p0.a + extra_m), *lane.width.pieces[1:]))
    )
    secs[section_index] = replace(sec, right=tuple(lanes))
    return replace(road, lane_sections=tuple(secs))


def test_true_road_explains_its_points():
    road = truth_road()
    run = sample_run(road, outliers=0.02)
    assert poorly_determined(road, run) == ()


def test_outer_edge_off_is_reported_with_its_stations():
    road = truth_road()
    run = sample_run(road)
    # the hard shoulder of the last section 1.2 m too wide: the built outer edge lies
    # 1.2 m outside the measured one from 1200 m to the end
    bad = _widen(road, 2, 4, 1.2)
    found = [st for st in poorly_determined(bad, run) if st.kind == "outer edge"]
    assert len(found) == 1
    st = found[0]
    assert st.s0_m <= 1200.0 + 25.0
    assert st.s1_m >= road.length - 25.0
    assert st.value_m == np.clip(st.value_m, 1.1, 1.3)  # points lie 1.2 m inside it
    assert "s=1200" in st.message() or "s=1175" in st.message()


def test_missed_marking_gives_a_wide_lane_and_unexplained_samples():
    road = truth_road()
    run = sample_run(road)
    # merge driving lanes 2 and 3 of the first section into one 7.5 m lane
    sec = road.lane_sections[0]
    lanes = list(sec.right)
    merged = replace(lanes[2], width=CubicProfile((CubicPiece(0.0, 7.5),)))
    lanes = [*lanes[:2], merged, *lanes[4:]]
    lanes = [replace(ln, id=-(i + 1)) for i, ln in enumerate(lanes)]
    secs = (replace(sec, right=tuple(lanes)), *road.lane_sections[1:])
    bad = replace(road, lane_sections=secs)
    kinds = {st.kind: st for st in poorly_determined(bad, run)}
    assert kinds["lane width"].value_m == np.clip(kinds["lane width"].value_m, 7.4, 7.6)
    assert kinds["lane width"].s1_m <= 925.0
    # the lane line between them was measured all along: its samples line up off the map
    missed = kinds["lane markings"]
    t_line = float(road.lane_border_t(np.array([400.0]), -3)[0])
    assert abs(missed.value_m - t_line) < 0.3
    assert missed.s0_m < 100.0
    assert 800.0 < missed.s1_m <= 925.0


def _unseen(stretches, kind):
    """The stretches of one kind (the unseen edges' and the others')."""
    return [st for st in stretches if st.kind == kind]


def test_short_occlusion_beside_a_measured_line_is_not_reported():
    road = truth_road()
    # both edges hidden over 80 m of the curve: the lines beside them were measured, the
    # edges keep their distance to them, and the bridge is as good as a measurement
    run = sample_run(road, gap=(420.0, 500.0))
    found = poorly_determined(road, run)
    assert _unseen(found, "outer edge unseen") == []
    assert _unseen(found, "reference edge unseen") == []


def test_unseen_reference_edge_is_reported_where_the_line_next_to_it_was_not_measured():
    road = truth_road()
    run = sample_run(road, gap=(420.0, 560.0))
    # 140 m unseen, the shoulder line 0.75 m from it measured all along: not reported
    assert _unseen(poorly_determined(road, run), "reference edge unseen") == []
    # without that line (out of reach from the outer lanes) a lane could hide there
    s, t = road.project(run.lane_samples[:, :2])
    shoulder_line = (s > 400.0) & (s < 600.0) & (np.abs(t) < 2.0)
    blind = replace(run, lane_samples=run.lane_samples[~shoulder_line])
    (st,) = _unseen(poorly_determined(road, blind), "reference edge unseen")
    assert 415.0 <= st.s0_m <= 425.0
    assert 555.0 <= st.s1_m <= 565.0
    assert np.isnan(st.value_m)
    assert "s=42" in st.message()
    assert "not measured either" in st.message()


def _without_aux_line(road, run, s0: float, s1: float):
    """``run`` without the lane samples of the deceleration lane's line (beyond 12.08 m)
    between stations ``s0`` and ``s1`` (metres): its paint worn, or out of reach."""
    s, t = road.project(run.lane_samples[:, :2])
    aux_line = (s > s0) & (s < s1) & (np.abs(t) > 12.08)
    return replace(run, lane_samples=run.lane_samples[~aux_line])


def test_lane_opening_unseen_at_the_edge_is_reported():
    road = truth_road()
    run = sample_run(road, gap=(880.0, 1000.0))
    # the deceleration lane opens 900-980 m inside the gap; with its line seen the line
    # next to the outer edge keeps its distance to it: not reported
    assert _unseen(poorly_determined(road, run), "outer edge unseen") == []
    # without its line (worn, out of reach) nothing measured where the lane opens
    blind = _without_aux_line(road, run, 880.0, 1000.0)
    (st,) = _unseen(poorly_determined(road, blind), "outer edge unseen")
    assert 875.0 <= st.s0_m <= 885.0
    assert 995.0 <= st.s1_m <= 1005.0
    assert "a lane there may be missed" in st.message()


def test_edge_moving_away_from_its_measured_line_over_a_gap_is_reported():
    road = truth_road()
    run = sample_run(road, gap=(200.0, 300.0))
    # a map whose shoulder widens by 1.5 m inside the gap, the line beside it measured
    sec = road.lane_sections[0]
    lanes = list(sec.right)
    p0 = lanes[-1].width.pieces[0]
    wider = CubicProfile(
        (
            CubicPiece(0.0, p0.a),
            CubicPiece(220.0, p0.a, 0.0, 3 * 1.5 / 60.0**2, -2 * 1.5 / 60.0**3),
            CubicPiece(280.0, p0.a + 1.5),
        )
    )
    lanes[-1] = replace(lanes[-1], width=wider)
    bad = replace(road, lane_sections=(replace(sec, right=tuple(lanes)), *road.lane_sections[1:]))
    (st,) = _unseen(poorly_determined(bad, run), "outer edge unseen")
    assert 195.0 <= st.s0_m <= 205.0
    assert 295.0 <= st.s1_m <= 305.0
    assert st.value_m == np.clip(st.value_m, 1.4, 1.6)
    assert "changes by 1.5 m" in st.message()


def test_reference_edge_unseen_at_the_runs_start_is_reported_though_its_line_was_seen():
    road = truth_road()
    # the first 150 m: the reference line is held at the trajectory's offset there, not
    # bridged between two seen ends, whatever the shoulder line beside it shows
    run = sample_run(road, gap=(-1.0, 150.0))
    (st,) = _unseen(poorly_determined(road, run), "reference edge unseen")
    assert st.s0_m == 0.0
    assert 145.0 <= st.s1_m <= 155.0
    # 80 m at the start: shorter than 100 m, and the line beside it was measured
    run = sample_run(road, gap=(-1.0, 80.0))
    assert _unseen(poorly_determined(road, run), "reference edge unseen") == []


def test_a_short_unseen_stretch_is_judged_by_its_own_stations():
    road = truth_road()
    # 60 m unseen where the deceleration lane opens (900-960 m), its line worn away there:
    # reported; with its line seen: not (a stretch shorter than the lines' reach window)
    run = sample_run(road, gap=(900.0, 960.0))
    assert _unseen(poorly_determined(road, run), "outer edge unseen") == []
    blind = _without_aux_line(road, run, 890.0, 970.0)
    (st,) = _unseen(poorly_determined(road, blind), "outer edge unseen")
    assert np.isnan(st.value_m)


def test_a_reference_line_turning_tighter_than_a_motorway_can_is_reported():
    from roadtwin.fitting import fit_parampoly3_chain
    from roadtwin.model import Road

    road = truth_road()
    assert [
        st for st in poorly_determined(road, sample_run(road)) if st.kind == "reference line"
    ] == []
    # a kink: 60 degrees within 20 m (radius about 19 m), as a mainline whose median-side
    # points were a diverging road's (melbourne-1019-lane1-s21 with a noisier sensor)
    s = np.arange(0.0, 400.0, 1.0)
    heading = np.radians(60.0) * np.clip((s - 200.0) / 20.0, 0.0, 1.0)
    xy = np.column_stack([np.cumsum(np.cos(heading)), np.cumsum(np.sin(heading))])
    kinked = replace(road, geometry=tuple(fit_parampoly3_chain(xy, tolerance_m=0.02)))
    kinked = Road(road.id, kinked.geometry, road.lane_sections, name=road.name)
    found = [
        st for st in poorly_determined(kinked, sample_run(kinked)) if st.kind == "reference line"
    ]
    assert len(found) == 1
    assert 180.0 <= found[0].s0_m <= 200.0
    assert 220.0 <= found[0].s1_m <= 240.0
    assert found[0].value_m == np.clip(found[0].value_m, 15.0, 25.0)
    assert "radius" in found[0].message()


def test_the_median_edge_fit_finds_its_own_knots_in_trajectory_stations():
    """melbourne-1019-lane1-s21 with a noisier sensor: the median-side edge, unseen over
    140 m before a median-side split, was fitted through another road's edge points and
    swung with a 6.7 m radius; esmini jumped 31 m there. Such knots are found on the fitted
    line (heading change over 10 m) and their edge points left out before a second fit."""
    from roadtwin.fitting import PolylineFrame
    from roadtwin.mainline.reference import _tight_turns

    s = np.arange(0.0, 600.0, 1.0)
    straight = np.column_stack([s, np.zeros_like(s)])
    traj = PolylineFrame.from_points(straight + np.array([0.0, -5.0]))
    assert _tight_turns(straight, traj, 20.0) == []
    # a gentle 300 m radius curve: none either
    arc = np.column_stack([300.0 * np.sin(s / 300.0), 300.0 * (1.0 - np.cos(s / 300.0))])
    assert _tight_turns(arc, PolylineFrame.from_points(arc), 20.0) == []
    # a swing of 90 degrees out and back within 30 m at 300 m
    heading = np.radians(90.0) * np.clip(1.0 - np.abs(s - 300.0) / 15.0, 0.0, 1.0)
    knotted = np.column_stack([np.cumsum(np.cos(heading)), np.cumsum(np.sin(heading))])
    (lo, hi), *rest = _tight_turns(knotted, traj, 20.0)
    assert rest == []
    assert 270.0 <= lo <= 300.0
    assert 290.0 <= hi <= 330.0
