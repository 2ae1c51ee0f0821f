"""Ramps on the median side of the carriageway (a left exit or entry with right-hand
traffic, a right exit with left-hand traffic) in the simulator's canonical truth and the
car's path: the median-side edge steps at the gore, the reference line stays smooth and
the step is the road's lane offset.

Cases: a hand-built network with a left entry and a left exit at full width on a 1 km
curve (``tests/networks.median_ramps_network``), the real three-lane left exit of I-880 in
West Oakland and the right (median-side) exit of the Melbourne chain (left-hand traffic),
both from the osm_truth generator on the bundled extracts.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from networks import MEDIAN_RADIUS_M, median_ramps_network
from roadtwin.check import check_network
from roadtwin.frames import MappingFrame, Origin
from roadtwin.simulate.canonical import ChainFit, max_border_error_m
from roadtwin.simulate.osm_truth import truth_from_osm
from roadtwin.simulate.route import route_from_ids
from roadtwin.simulate.route_sensor import drive
from roadtwin.simulate.route_truth import RouteTruth, build_route_truth
from roadtwin.simulate.scenario import Car

OSM = Path(__file__).parent / "data" / "osm"


def _route_truth(network, road_ids, side) -> RouteTruth:
    route = route_from_ids(network, road_ids, traffic_side=side)
    return build_route_truth(
        network, route, frame=MappingFrame(Origin(0.0, 0.0)), traffic_side=side
    )


@pytest.fixture(scope="module")
def synthetic():
    network = median_ramps_network()
    return network, _route_truth(network, ["1", "2", "4"], "right")


def _osm_case(name: str, chain: int, seed: int):
    src = truth_from_osm(OSM / name, chain=chain, seed=seed)
    return src.network, _route_truth(src.network, list(src.route), src.style.traffic)


@pytest.fixture(scope="module")
def oakland():
    return _osm_case("west-oakland-i880.osm.bz2", 28393854, 1)


@pytest.fixture(scope="module")
def melbourne():
    return _osm_case("melbourne-lht.osm.pbf", 921, 2)


CASES = ["synthetic", "oakland", "melbourne"]


def _offset_at(road, u: float) -> float:
    return float(road.lane_offset.value(np.array([u]))[0])


def _edge_heading_and_curvature(fit: ChainFit, window_m: float = 2.0):
    """Per leg: stations, heading of the sampled source median edge and its curvature
    over +-``window_m`` (1/m), at samples at least a window from the leg's ends."""
    for sm, u in zip(fit.samples, fit.sample_u, strict=True):
        xy = sm.median[:, :2]
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        keep = np.concatenate([[True], np.diff(arc) > 1e-6])
        xy, arc, uu = xy[keep], arc[keep], u[keep]
        if arc[-1] < 3.0 * window_m:
            continue
        heading = np.unwrap(np.arctan2(*np.gradient(xy, arc, axis=0)[:, ::-1].T))
        ahead = np.interp(arc + window_m, arc, heading)
        behind = np.interp(arc - window_m, arc, heading)
        inner = (arc > window_m) & (arc < arc[-1] - window_m)
        yield uu[inner], heading[inner], ((ahead - behind) / (2.0 * window_m))[inner]


def test_left_entry_and_exit_become_lane_offset_steps(synthetic):
    _, truth = synthetic
    assert [(r.type, r.side) for r in truth.ramps] == [("entry", "inner"), ("exit", "inner")]
    main = truth.mainline
    # the reference line is one circle parallel to the edge of the longest road (road 4,
    # 1 m outside road 1's edge): no loop, no wiggle at the gores
    s = np.linspace(0.0, main.length, 4000)
    assert np.allclose(main.curvature(s), 1.0 / (MEDIAN_RADIUS_M + 1.0), rtol=2e-3)
    # the median edge's steps are the lane offset: +1.0 m on road 1, +4.5 m where the
    # entry's shoulder and lane run inside the through lanes, 0 after the exit
    pieces = main.lane_offset.pieces
    assert all(p.b == p.c == p.d == 0.0 for p in pieces)
    assert [round(p.a, 4) for p in pieces] == [1.0, 4.5, 0.0]
    cuts = [r.cut_station_m for r in truth.ramps]
    assert [p.s0 for p in pieces[1:]] == pytest.approx(cuts, abs=1e-9)
    sec_s0 = [ls.s0 for ls in main.lane_sections]
    assert all(min(abs(c - x) for x in sec_s0) < 1e-9 for c in cuts)
    # the written mainline roads carry the offset of their stretch
    written = [r for r in truth.network.roads if r.name == "mainline"]
    assert [round(_offset_at(r, 1.0), 4) for r in written] == [1.0, 4.5, 0.0]


@pytest.mark.parametrize("case", CASES)
def test_truth_within_a_millimetre_of_the_map(case, request):
    network, truth = request.getfixturevalue(case)
    assert any(r.side == "inner" for r in truth.ramps)
    for fit in [truth.mainline_fit, *(r.fit for r in truth.ramps)]:
        for err in (
            max_border_error_m(fit),
            max_border_error_m(fit, network=network, step_m=0.37),  # sampled afresh
        ):
            assert err["median_edge"] <= 0.001, (case, fit.road.name, err)
            assert err["lane_borders"] <= 0.001, (case, fit.road.name, err)


@pytest.mark.parametrize("case", CASES)
def test_reference_line_parallel_to_the_edge_and_smooth(case, request):
    _, truth = request.getfixturevalue(case)
    fit, main = truth.mainline_fit, truth.mainline
    for u, heading, k_edge in _edge_heading_and_curvature(fit):
        # an offset of the edge: the same heading at every sample
        dh = np.angle(np.exp(1j * (main.heading(u) - heading)))
        assert np.max(np.abs(dh)) < math.radians(0.05), case
        # radius above 50 m wherever the source edge's is (at the reference line's offset)
        offset = main.lane_offset.value(u)
        gentle = np.abs(k_edge / (1.0 + offset * k_edge)) < 1.0 / 50.0
        assert np.all(np.abs(main.curvature(u[gentle])) < 1.0 / 50.0), case
    # and around each median-side gore, at any station
    for r in truth.ramps:
        if r.side == "inner":
            s = np.linspace(max(r.cut_station_m - 50.0, 0.0), r.cut_station_m + 50.0, 2001)
            assert np.max(np.abs(main.curvature(s))) < 1.0 / 50.0, case


@pytest.mark.parametrize("case", ["oakland", "melbourne"])
def test_median_side_exit_steps_by_the_lanes_that_leave(case, request):
    _, truth = request.getfixturevalue(case)
    main = truth.mainline
    (ramp,) = [r for r in truth.ramps if r.side == "inner"]
    cut = ramp.cut_station_m
    sec = main.lane_sections[int(main.section_index(np.array([cut - 1e-6]))[0])]
    leaving = sum(
        float(sec.lane(i).width.value(np.array([cut - sec.s0]))[0]) for i in ramp.aux_lane_ids
    )
    step = _offset_at(main, cut + 1e-6) - _offset_at(main, cut - 1e-6)
    towards_median = 1.0 if truth.traffic_side == "right" else -1.0
    # the lanes leave at full width (3 lanes + shoulder in Oakland): the edge moves away
    # from the median by exactly their width, and nowhere else does the offset change
    assert leaving > 3.0
    assert step == pytest.approx(-towards_median * leaving, abs=0.002)
    inner_cuts = [r.cut_station_m for r in truth.ramps if r.side == "inner"]
    changes = [p.s0 for p in main.lane_offset.pieces[1:]]
    assert all(min(abs(c - x) for x in inner_cuts) < 1e-9 for c in changes)


@pytest.mark.parametrize("case", CASES)
def test_junction_lane_links_on_the_median_side(case, request):
    _, truth = request.getfixturevalue(case)
    net = truth.network
    for r in truth.ramps:
        junction = net.id_to_junction[r.junction_id]
        ramp_conn = next(
            c for c in junction.connections if r.road.id in (c.incoming_road, c.connecting_road)
        )
        through = next(c for c in junction.connections if c.id == "1")
        end = "from_lane" if r.type == "exit" else "to_lane"
        ramp_ends = {getattr(ll, end) for ll in ramp_conn.lane_links}
        main_ends = {getattr(ll, end) for ll in through.lane_links}
        assert ramp_ends
        if r.side == "inner":  # at full width, the innermost lanes, each one way only
            assert not ramp_ends & main_ends
            assert max(abs(i) for i in ramp_ends) < min(abs(i) for i in main_ends)
        # no traffic lane dead-ends at the gore (exit) or starts from nowhere (entry)
        u = r.cut_station_m + (-1e-6 if r.type == "exit" else 1e-6)
        main = truth.mainline
        sec = main.lane_sections[int(main.section_index(np.array([u]))[0])]
        wide = {
            ln.id
            for ln in (sec.right or sec.left)
            if ln.type == "driving" and ln.width.value(np.array([u - sec.s0]))[0] > 1.0
        }
        assert wide <= ramp_ends | main_ends, (case, r.type, wide, ramp_ends, main_ends)
    # no finding at the median-side ramps' junctions (Melbourne's outer entry has an
    # 11 mm link gap of its own, not about the median side)
    inner = {r.junction_id for r in truth.ramps if r.side == "inner"}
    inner |= {r.road.id for r in truth.ramps if r.side == "inner"}
    errors = [
        f
        for f in check_network(net)
        if f.severity == "error" and (f.junction in inner or f.road in inner)
    ]
    assert not errors, errors


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("lane", [0, 1, 2])
def test_car_drives_forward_and_leaves_ending_lanes_early(case, lane, request):
    _, truth = request.getfixturevalue(case)
    poses = drive(truth, replace(Car(), lane=lane))
    step = np.diff(poses.xyz[:, :2], axis=0)
    heading = np.arctan2(step[:, 1], step[:, 0])
    yaw_step = np.degrees(np.abs(np.angle(np.exp(1j * np.diff(poses.yaw)))))
    assert yaw_step.max() < 10.0, (case, lane, yaw_step.max())
    assert np.all(np.cos(heading - poses.yaw[:-1]) > 0.98), (case, lane)
    assert np.all(np.diff(poses.station) > 0.5), (case, lane)
    # at every median-side exit the car is in a lane that goes on, 30 m before the gore
    main = truth.mainline
    for r in truth.ramps:
        if r.side != "inner" or r.type != "exit":
            continue
        u = r.cut_station_m - 30.0
        i = int(np.argmin(np.abs(poses.station - u)))
        s_i = poses.station[i : i + 1]
        _, t = main.project(poses.xyz[i : i + 1, :2], s_init=s_i)
        outermost = max(r.aux_lane_ids, key=abs)
        band = sorted([main.lane_border_t(s_i, 0)[0], main.lane_border_t(s_i, outermost)[0]])
        assert not band[0] - 1.0 < t[0] < band[1] + 1.0, (case, lane, t[0], band)
