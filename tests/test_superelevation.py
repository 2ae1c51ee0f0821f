"""Superelevation: OpenDRIVE rotates the lateral axis about the reference line by the
roll, so a border at ``t`` lies ``t cos(roll)`` from the line in plan and ``t sin(roll)``
above it (ASAM's quality checker places borders so). Roads joined to a superelevated
mainline (junction connectors, ramps) must carry its roll at the contact, or their lane
borders miss the mainline's by ``t (1 - cos(roll))`` in plan (over 1 cm 12 m out at
0.08 rad: ASAM ``contact_point_no_horizontal_gaps``) and ``t sin(roll)`` in height.

Numbers checked: plan and height gaps of every linked lane border, computed here by the
standard's rotation (independently of :meth:`Road.to_xy`), at most 1 mm; the real ASAM
checker passes the written map (skipped where it is not installed).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from _run_factory import build_xodr_route
from roadtwin.check import check_file
from roadtwin.config import TopologyConfig
from roadtwin.model import CubicPiece, CubicProfile, Line, Road
from roadtwin.topology import build_topology
from roadtwin.xodr import read_xodr, write_xodr
from test_topology import _network, mainline_road, make_ramps

ROLL_START, ROLL_END = 0.03, 0.08


def _rolled(road: Road) -> Road:
    """The road with a superelevation rising from 0.03 to 0.08 rad along it."""
    length = road.length
    d = ROLL_END - ROLL_START
    roll = CubicProfile((CubicPiece(0.0, ROLL_START, 0.0, 3 * d / length**2, -2 * d / length**3),))
    return replace(road, superelevation=roll)


def _standard_point(road: Road, s: float, t: float) -> np.ndarray:
    """(x, y, z) of Frenet (s, t) by OpenDRIVE's rotation: yaw about z, then roll about s."""
    x, y, h, _ = road.evaluate(np.array([s]))
    roll = 0.0 if road.superelevation is None else float(road.superelevation.value(s))
    z = float(road.elevation.value(s))
    lateral = np.array([-math.sin(h[0]) * math.cos(roll), math.cos(h[0]) * math.cos(roll)])
    return np.array([x[0] + t * lateral[0], y[0] + t * lateral[1], z + t * math.sin(roll)])


def _border_points(road: Road, s: float, lane_id: int) -> np.ndarray:
    inner = lane_id + (1 if lane_id < 0 else -1)
    ts = [float(road.lane_border_t(np.array([s]), i)[0]) for i in (inner, lane_id)]
    return np.array([_standard_point(road, s, t) for t in ts])


def test_to_xy_and_project_follow_the_roll():
    road = replace(
        Road("1", (Line(0.0, 0.0, 0.0, 0.0, 100.0),), ()),
        superelevation=CubicProfile.constant(0.08),
        elevation=CubicProfile.constant(5.0),
    )
    s, t = np.array([10.0, 50.0]), np.array([-12.0, 7.5])
    xy = road.to_xy(s, t)
    np.testing.assert_allclose(xy[:, 1], t * math.cos(0.08), atol=1e-12)
    np.testing.assert_allclose(road.surface_height(s, t), 5.0 + t * math.sin(0.08), atol=1e-12)
    s_back, t_back = road.project(xy)
    np.testing.assert_allclose(s_back, s, atol=1e-9)
    np.testing.assert_allclose(t_back, t, atol=1e-9)


@pytest.fixture(scope="module", params=["default", "direct"])
def rolled_network(request):
    main = _rolled(mainline_road("right"))
    topo = build_topology(
        main,
        make_ramps(main, "right"),
        traffic_side="right",
        config=TopologyConfig(junctions=request.param),
    )
    assert not topo.skipped
    return _network(topo)


def test_linked_lane_borders_meet_in_plan_and_height_on_a_superelevated_mainline(
    rolled_network,
):
    ids = rolled_network.id_to_road
    # (road, station, lane) -> (road, station, lane) for every lane link: road links
    # and the lane links of junction connections (a direct junction has only those)
    pairs = []
    for road in rolled_network.roads:
        for contact, link in (("start", road.predecessor), ("end", road.successor)):
            if link is None:
                continue
            s_a = 0.0 if contact == "start" else road.length
            section = road.lane_sections[0 if contact == "start" else -1]
            if link.element_type == "road":
                other = ids[link.element_id]
                s_b = 0.0 if link.contact_point == "start" else other.length
                for lane in (*section.left, *section.right):
                    target = lane.predecessor if contact == "start" else lane.successor
                    if target is not None:
                        pairs.append((road, s_a, lane.id, other, s_b, target))
                continue
            junction = rolled_network.id_to_junction[link.element_id]
            for conn in junction.connections:
                if conn.incoming_road != road.id:
                    continue
                other = ids[conn.connecting_road]
                s_b = 0.0 if conn.contact_point == "start" else other.length
                for ll in conn.lane_links:
                    pairs.append((road, s_a, ll.from_lane, other, s_b, ll.to_lane))
    worst_plan = worst_height = 0.0
    for road, s_a, lane_a, other, s_b, lane_b in pairs:
        pa = _border_points(road, s_a, lane_a)
        pb = _border_points(other, s_b, lane_b)
        worst_plan = max(worst_plan, float(np.hypot(*(pa - pb)[:, :2].T).max()))
        worst_height = max(worst_height, float(np.abs(pa - pb)[:, 2].max()))
    assert len(pairs) >= 10
    assert worst_plan <= 1e-3
    assert worst_height <= 1e-3


def test_asam_checker_finds_no_gap_on_a_superelevated_mainline(rolled_network, tmp_path):
    path = write_xodr(rolled_network, tmp_path / "rolled.xodr")
    report = check_file(path, external=True)
    asam = next(c for c in report.consumers if "asam" in c.name)
    if asam.status == "not installed":
        pytest.skip(asam.status)
    assert asam.status == "passed", asam
    assert asam.errors == 0


TOWN06 = Path(__file__).parent / "data" / "xodr" / "town06-35-38.xodr.gz"
TRUE_ROLL = 0.06


@pytest.fixture(scope="module")
def banked_town06(tmp_path_factory):
    """A run simulated along Town06's roads 35-38, every road banked by 0.06 rad, built
    with OSM and evaluated against the banked map."""
    tmp = tmp_path_factory.mktemp("banked")
    net = read_xodr(TOWN06)
    banked = replace(
        net,
        roads=tuple(replace(r, superelevation=CubicProfile.constant(TRUE_ROLL)) for r in net.roads),
    )
    path = write_xodr(banked, tmp / "banked.xodr")
    return build_xodr_route(path, tmp / "run", route=["35", "36", "37", "38"], seed=1)


def test_a_banked_map_is_simulated_banked_and_built_with_its_roll(banked_town06):
    _, rep = banked_town06
    truth = read_xodr(Path(rep.run_dir) / "truth.xodr").roads[0]
    stations = np.linspace(0.0, truth.length, 20)
    np.testing.assert_allclose(truth.roll(stations), TRUE_ROLL, atol=1e-4)
    assert rep.truth["elevation"]["rmse_m"] < 0.2  # 1.2 m 20 m out if the roll were lost


def test_lane_borders_of_a_banked_road_are_placed_along_the_rolled_surface(banked_town06):
    """Widths are written along the surface (plan width / cos(roll)): the outermost
    border, 20 m from the median edge, is off by 5 cm in plan otherwise (3.6 cm of it
    the roll's cosine)."""
    _, rep = banked_town06
    lanes = rep.details["truth/lane_boundary"]
    boundary, error = np.asarray(lanes.boundary), np.asarray(lanes.error_m)
    outermost = boundary == boundary.min()
    assert np.count_nonzero(outermost) > 300
    assert abs(float(np.mean(error[outermost]))) < 0.03  # 0.051 m in plan only
    assert rep.truth["lane_boundary"]["rmse_m"] < 0.035  # 0.040 m
    edge = rep.details["truth/road_edge"]
    outer = np.asarray(edge.boundary) == np.asarray(edge.boundary).min()
    assert float(np.sqrt(np.mean(np.asarray(edge.error_m)[outer] ** 2))) < 0.08  # 0.22 m
