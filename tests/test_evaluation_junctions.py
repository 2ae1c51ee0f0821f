"""Accuracy against truth where a ramp leaves: the same pavement split between roads at
different stations is no lateral error; a ramp lane in the wrong place still is."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from roadtwin.config import EvaluationConfig
from roadtwin.evaluation.metrics import _truth_mainline
from roadtwin.model import (
    Connection,
    Header,
    Junction,
    LaneLink,
    LaneSection,
    Line,
    Road,
    RoadLink,
    RoadNetwork,
    constant_lane,
)

LANE_M = 3.5
LENGTH_M = 600.0
JUNCTION_M = 20.0


def _section(n_lanes: int, *, succ: bool = False, pred: bool = False) -> LaneSection:
    """``n_lanes`` driving lanes, linked to the same ids across the ends asked for."""
    lanes = tuple(
        replace(
            constant_lane(-i, LANE_M),
            successor=-i if succ else None,
            predecessor=-i if pred else None,
        )
        for i in range(1, n_lanes + 1)
    )
    return LaneSection(0.0, right=lanes)


def exit_network(
    split_m: float, *, ramp_offset_m: float = 0.0, ramp_heading: float = 0.0
) -> RoadNetwork:
    """A straight 2-lane mainline with an exit lane (lane -3) up to ``split_m``; there a
    20 m junction splits it into a through connecting road (2 lanes) and a ramp connecting
    road (1 lane) that runs on beside the mainline, ``ramp_offset_m`` farther out (or
    ``ramp_heading`` radians off its heading)."""
    j = RoadLink("junction", "100")
    up = Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, split_m),),
        (_section(3),),
        name="mainline",
        successor=j,
    )
    through = Road(
        "101",
        (Line(0.0, split_m, 0.0, 0.0, JUNCTION_M),),
        (_section(2, succ=True, pred=True),),
        name="connector",
        predecessor=RoadLink("road", "1", "end"),
        successor=RoadLink("road", "2", "start"),
        junction="100",
    )
    y_ramp = -2 * LANE_M - ramp_offset_m
    ramp_conn = Road(
        "102",
        (Line(0.0, split_m, y_ramp, ramp_heading, JUNCTION_M),),
        (_section(1, succ=True),),
        name="connector",
        predecessor=RoadLink("road", "1", "end"),
        successor=RoadLink("road", "10", "start"),
        junction="100",
    )
    down = Road(
        "2",
        (Line(0.0, split_m + JUNCTION_M, 0.0, 0.0, LENGTH_M - split_m - JUNCTION_M),),
        (_section(2),),
        name="mainline",
        predecessor=j,
    )
    x_end, y_end, _ = ramp_conn.geometry[-1].end_pose()
    ramp = Road(
        "10",
        (Line(0.0, x_end, y_end, ramp_heading, 100.0),),
        (_section(1, pred=True),),
        name="exit",
        predecessor=j,
    )
    junction = Junction(
        "100",
        (
            Connection("0", "1", "101", "start", (LaneLink(-1, -1), LaneLink(-2, -2))),
            Connection("1", "1", "102", "start", (LaneLink(-3, -1),)),
        ),
    )
    return RoadNetwork(Header(), (up, through, down, ramp_conn, ramp), (junction,))


@pytest.mark.parametrize(
    ("built_split_m", "strict_lane_max_m"),
    # split late, the truth's lane borders are all the map's mainline borders too
    [(290.0, LANE_M), (310.0, 0.0)],
)
def test_junction_placed_apart_from_truths_is_no_lateral_error(built_split_m, strict_lane_max_m):
    """The truth ends its mainline road at 300 m, the map 10 m earlier or later: over those
    10 m the exit lane's edge is the mainline's in one and a ramp's in the other."""
    truth = exit_network(300.0)
    built = exit_network(built_split_m)
    res, details = _truth_mainline(built, truth, EvaluationConfig())
    for kind in ("road_edge", "lane_boundary"):
        # the same points as the strict metric, every one matched within a millimetre
        assert res[kind]["n"] == res[f"{kind}_strict"]["n"]
        assert res[kind]["max_m"] < 1e-3
        # the strict metric (kinds and roads must agree) sees a lane width over ~10 m
        expected = LANE_M if kind == "road_edge" else strict_lane_max_m
        assert res[f"{kind}_strict"]["max_m"] == pytest.approx(expected, abs=0.01)
        big = np.abs(details[f"truth/{kind}"].error_m) > 1.0
        assert not big.any()
    assert res["junction_points"] >= 20


def test_ramp_lane_in_the_wrong_place_is_still_an_error():
    """A ramp connecting road 1 m farther out than the truth's exit lane: the exit lane's
    edge, matched with the ramp's, is 1 m off where the map's junction starts early."""
    truth = exit_network(300.0)
    built = exit_network(290.0, ramp_offset_m=1.0)
    res, details = _truth_mainline(built, truth, EvaluationConfig())
    err = details["truth/road_edge"]
    near = (err.station_m > 290.5) & (err.station_m < 299.5) & (err.xy[:, 1] < -9.0)
    assert near.sum() >= 8
    np.testing.assert_allclose(np.abs(err.error_m[near]), 1.0, atol=0.01)
    assert res["road_edge"]["max_m"] == pytest.approx(1.0, abs=0.01)


def test_lane_count_across_the_carriageway_where_the_maps_split_it_apart():
    """Where the map's junction starts 10 m before the truth's, its mainline roads have one
    lane fewer than the truth's, its ramp connecting road carries that lane: counted across
    the carriageway the lanes agree. A ramp lane 3 m off the mainline is no lane of it."""
    truth = exit_network(300.0)
    res, _ = _truth_mainline(exit_network(290.0), truth, EvaluationConfig())
    assert res["lane_count"]["matched_fraction"] == pytest.approx(1.0)
    res, _ = _truth_mainline(exit_network(290.0, ramp_offset_m=3.0), truth, EvaluationConfig())
    stations = res["lane_count"]["stations"]
    # stations every metre: the 10 between 290 and 300 m count 2 lanes against 3
    assert res["lane_count"]["matched_fraction"] == pytest.approx(1.0 - 10 / stations, abs=1e-9)


def test_a_ramp_crossing_the_mainline_matches_none_of_its_boundaries():
    """A built ramp connecting road that leaves 10 m early heading 45 degrees off the
    mainline crosses the truth's exit lane: its borders are no lanes beside the mainline,
    the exit lane's edge stays a lane width off where the map's junction started early."""
    truth = exit_network(300.0)
    crossing = exit_network(290.0, ramp_heading=-0.8)
    res, details = _truth_mainline(crossing, truth, EvaluationConfig())
    err = details["truth/road_edge"]
    early = (err.station_m > 290.5) & (err.station_m < 299.5) & (err.xy[:, 1] < -9.0)
    assert early.sum() >= 8
    np.testing.assert_allclose(np.abs(err.error_m[early]), LANE_M, atol=0.01)
    assert res["lane_count"]["matched_fraction"] < 1.0
