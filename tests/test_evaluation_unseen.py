"""What a truth's lane boundaries are: borders a sensor can see, on no other road.

Two conventions of real truths are not mapping errors of a build:

* an HD map may split a shoulder into two unmarked strips (CARLA Town06: 0.64 m + 0.5 m
  beside the median): the border between them marks nothing on the road, and a build
  measured 0.5 m off it over the whole run; where the truth paints it, it counts only
  where the run's lane samples show that paint (a split beyond the sensor's reach is
  as unknowable as an unpainted one);
* a truth may keep a diverging lane on the mainline road for metres after the ramp road
  has begun on the same pavement (or grow an entry's lanes under the ramp's end): the
  mainline's "edge" then sweeps across the ramp's lanes.

Both are left out of the truth's boundaries; everything else is measured as before."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from roadtwin.evaluation import evaluate
from roadtwin.evaluation.frenet import on_pavement_of, unseen_boundary
from roadtwin.model import CubicPiece, CubicProfile, Lane, LaneSection, Line, Road, RoadMark
from test_evaluation import MAIN_WIDTHS, TRUTH_INFO, _lanes, make_run, make_truth


def _strip(lane_id: int, lane_type: str, width: float, mark: str) -> Lane:
    return Lane(lane_id, lane_type, CubicProfile.constant(width), (RoadMark(0.0, mark),))


SPLIT_SHOULDER = LaneSection(
    0.0,
    right=(
        _strip(-1, "shoulder", 0.64, "none"),
        _strip(-2, "shoulder", 0.5, "solid"),
        _strip(-3, "driving", 3.75, "broken"),
        _strip(-4, "driving", 3.75, "solid"),
        _strip(-5, "shoulder", 2.5, "none"),
    ),
)


def test_only_an_unmarked_border_between_two_non_driving_lanes_is_unseen():
    assert unseen_boundary(SPLIT_SHOULDER, -1).tolist() == [True]  # shoulder | shoulder
    assert unseen_boundary(SPLIT_SHOULDER, -2).tolist() == [False]  # shoulder | driving
    assert unseen_boundary(SPLIT_SHOULDER, -3).tolist() == [False]  # driving | driving
    assert unseen_boundary(SPLIT_SHOULDER, -5).tolist() == [False]  # the road edge
    painted = replace(
        SPLIT_SHOULDER,
        right=(_strip(-1, "shoulder", 0.64, "solid"), *SPLIT_SHOULDER.right[1:]),
    )
    assert unseen_boundary(painted, -1).tolist() == [False]  # a painted line is seen


def _painted_between(s_a: float, s_b: float) -> LaneSection:
    """SPLIT_SHOULDER with the split painted solid from ``s_a`` to ``s_b`` only (metres,
    section-relative; Town06 paints it over a few hundred metres of a road)."""
    split = Lane(
        -1,
        "shoulder",
        CubicProfile.constant(0.64),
        (RoadMark(0.0, "none"), RoadMark(s_a, "solid"), RoadMark(s_b, "none")),
    )
    return replace(SPLIT_SHOULDER, right=(split, *SPLIT_SHOULDER.right[1:]))


def test_a_split_painted_over_part_of_a_section_is_seen_there_only():
    section = _painted_between(100.0, 250.0)
    ds = np.array([0.0, 99.0, 100.0, 200.0, 249.9, 250.0, 399.0])
    np.testing.assert_array_equal(
        unseen_boundary(section, -1, ds), [True, True, False, False, False, True, True]
    )
    assert not unseen_boundary(section, -2, ds).any()


def _split_built_and_truth(s_a: float, s_b: float):
    """The truth with road 1's inner shoulder split 0.64 + 0.5 m, painted from ``s_a`` to
    ``s_b`` (metres) only; the build with one 1.14 m shoulder (else perfect)."""
    built = make_truth()
    whole = ((-1, "shoulder", 1.14), *MAIN_WIDTHS[1:])
    truth = _with_first_section(built, "1", _painted_between(s_a, s_b))
    built = _with_first_section(built, "1", LaneSection(0.0, right=_lanes(whole)))
    return built, truth


def _split_errors(built, truth, run) -> np.ndarray:
    rep = evaluate(built, run, truth=truth, truth_info=TRUTH_INFO).runs[0]
    return rep.details["truth/lane_boundary"].error_m


def test_a_partly_painted_split_is_measured_where_it_is_painted():
    """The truth's split (0.5 m from the build's nearest border) painted from 100 to
    250 m of road 1 only, and the run saw it: those 150 m are measured, 0.5 m off; a
    perfect map elsewhere. Before, the whole section's split counted (all of its 400 m)."""
    built, truth = _split_built_and_truth(100.0, 250.0)
    run = make_run(truth, edge_sigma=0.0, lane_sigma=0.0, seed=5)
    err = _split_errors(built, truth, run)
    off = np.abs(err) > 0.4
    assert np.max(np.abs(err)) == pytest.approx(0.5, abs=1e-3)
    step = 150.0 / np.count_nonzero(off)  # one point per truth_step_m along the 150 m
    assert 0.4 <= step <= 2.1
    assert np.count_nonzero(np.abs(err[~off]) > 1e-6) == 0


def test_a_painted_split_the_run_never_saw_is_not_measured():
    """The same painted split beyond the sensor's reach (no lane sample on it; Town06's
    0.64 + 0.5 m shoulders seen from the far lane): no build can place it, and it had
    made every Town06 run 0.5 m off over 400 m of its inner shoulder."""
    built, truth = _split_built_and_truth(100.0, 250.0)
    run = make_run(built, edge_sigma=0.0, lane_sigma=0.0, seed=5)  # no line at the split
    err = _split_errors(built, truth, run)
    assert np.max(np.abs(err)) == pytest.approx(0.0, abs=1e-6)


def test_a_split_seen_over_part_of_its_paint_is_measured_near_that_part():
    """Paint on the split seen only up to x = 150 m of road 1 (painted 100-250 m): it is
    measured from 100 m to 20 m past the last sample seen, not beyond."""
    built, truth = _split_built_and_truth(100.0, 250.0)
    run = make_run(truth, edge_sigma=0.0, lane_sigma=0.0, seed=5)
    split_t = -0.64  # road 1 runs along +x from the origin, its right side is -y
    x, y = run.lane_samples[:, 0], run.lane_samples[:, 1]
    unseen = (np.abs(y - split_t) < 0.05) & (x > 150.0) & (x < 400.0)
    run = replace(run, lane_samples=run.lane_samples[~unseen])
    run = replace(run, lane_sample_frame=np.zeros(run.lane_samples.shape[0], dtype=np.int64))
    rep = evaluate(built, run, truth=truth, truth_info=TRUTH_INFO).runs[0]
    pe = rep.details["truth/lane_boundary"]
    off = np.abs(pe.error_m) > 0.4
    assert pe.station_m[off].min() == pytest.approx(100.0, abs=1.0)
    assert pe.station_m[off].max() == pytest.approx(170.0, abs=1.0)


def _with_first_section(network, road_id: str, section: LaneSection):
    roads = tuple(
        replace(r, lane_sections=(section, *r.lane_sections[1:])) if r.id == road_id else r
        for r in network.roads
    )
    return replace(network, roads=roads)


def test_a_split_shoulder_is_measured_as_the_shoulder_it_is():
    """Truth road 1 has the inner shoulder split 0.64 + 0.5 m (0.75 m + 3.75 + 3.75 +
    2.5 m otherwise the same); the build has one 1.14 m shoulder: a perfect map."""
    built = make_truth()
    whole = ((-1, "shoulder", 1.14), *MAIN_WIDTHS[1:])
    truth = _with_first_section(built, "1", SPLIT_SHOULDER)
    built = _with_first_section(built, "1", LaneSection(0.0, right=_lanes(whole)))
    run = make_run(built, edge_sigma=0.0, lane_sigma=0.0, seed=5)
    res = evaluate(built, run, truth=truth, truth_info=TRUTH_INFO).runs[0].truth
    assert res["lane_boundary"]["max_m"] == pytest.approx(0.0, abs=1e-6)  # 0.5 m if counted
    assert res["road_edge"]["max_m"] == pytest.approx(0.0, abs=1e-6)


def test_a_lane_kept_on_the_mainline_under_a_ramp_is_not_the_mainlines_edge():
    """Over road 1's last 20 m the truth keeps an exit lane (closing from 3.75 m to zero)
    while a true exit road already covers it: the truth's outer edge and the lane's border
    sweep across the exit's pavement. A build without that lane is exact; the points
    there are counted as on the ramp."""
    base = make_truth()
    road1 = next(r for r in base.roads if r.id == "1")
    closing = Lane(
        -4,
        "driving",
        CubicProfile((CubicPiece(0.0, 3.75, 0.0, -3 * 3.75 / 400.0, 2 * 3.75 / 8000.0),)),
        (RoadMark(0.0, "solid"),),
    )
    last = LaneSection(
        380.0,
        right=(*_lanes(MAIN_WIDTHS[:3]), closing, *_lanes(((-5, "shoulder", 2.5),))),
    )
    truth_road1 = replace(road1, lane_sections=(road1.lane_sections[0], last))
    # the exit's pavement from s = 380 m: 3.75 m lane and 2.5 m shoulder beyond the
    # through lanes (t = -8.25 .. -14.5 m)
    exit_early = Road(
        "11",
        (Line(0.0, 380.0, -8.25, 0.0, 60.0),),
        (LaneSection(0.0, right=_lanes(((-1, "driving", 3.75), (-2, "shoulder", 2.5)))),),
        name="exit",
    )
    truth = replace(
        base,
        roads=(*tuple(truth_road1 if r.id == "1" else r for r in base.roads), exit_early),
    )
    run = make_run(base, edge_sigma=0.0, lane_sigma=0.0, seed=6)
    rep = evaluate(base, run, truth=truth, truth_info=TRUTH_INFO).runs[0]
    assert rep.truth["on_ramp_points"] >= 30  # two borders over most of the 20 m
    off = {
        kind: np.count_nonzero(np.abs(rep.details[f"truth/{kind}"].error_m) > 0.35)
        for kind in ("road_edge", "lane_boundary")
    }
    # where the closing lane starts its edge is the exit's own edge (within the 0.3 m
    # margin of it): 3 points; 20 + 19 if the sweep were counted
    assert off == {"road_edge": 3, "lane_boundary": 0}


def test_on_pavement_needs_the_same_level():
    road = Road(
        "9",
        (Line(0.0, 0.0, 0.0, 0.0, 100.0),),
        (LaneSection(0.0, right=_lanes(((-1, "driving", 3.5),))),),
        name="exit",
    )
    pts = np.array([[50.0, -1.75, 0.0], [50.0, -1.75, 7.0], [50.0, -3.4, 0.0], [50.0, 2.0, 0.0]])
    np.testing.assert_array_equal(
        on_pavement_of([road], pts, margin_m=0.3), [True, False, False, False]
    )


def test_a_lane_border_on_the_road_edge_is_matched_as_either():
    """Where a lane has closed to zero width its border is the road edge: a build whose
    lane section ends a metre earlier has only the edge there (one point 3.5 m off, a
    lane RMSE of 0.09 m on a 1.7 km soderleden run, if matched by kind alone)."""
    from roadtwin.evaluation.metrics import _twins

    s = np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    t = np.array([0.0, -3.5, -3.55, 0.0, -3.5, -7.0])
    kinds = np.array(["road_edge", "lane_boundary", "road_edge"] * 2)
    np.testing.assert_array_equal(_twins(s, t, kinds), [False, True, True, False, False, False])
