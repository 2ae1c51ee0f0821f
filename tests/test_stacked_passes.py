"""A run that passes over itself: the points of the two levels stay apart.

Real chains do this (the Krems trunk road loops over itself at 6-12 degrees, 46 m above),
and so do runs that take a loop ramp. In plan the two passes overlap, so anything that
places a point at the nearest station in plan puts half of them on the wrong pass: the
mainline's edges and markings then follow the other level (12 m errors, a 7 m lane on
krems-30799129-s11). Points carry z, the trajectory carries the road surface's height:
projections in 3-D keep each point at its own level.

Case: ``tests/networks.self_crossing_network``, one motorway road that loops through 350
degrees and crosses its own first straight at 10 degrees, 9 m above it, simulated with
the default sensor.
"""

from __future__ import annotations

import numpy as np
import pytest

from networks import LOOP_RISE_M, self_crossing_network
from roadtwin.evaluation import evaluate_paths
from roadtwin.fitting import PolylineFrame
from roadtwin.io import load_run
from roadtwin.model import HEIGHT_WEIGHT, nearest_at_level
from roadtwin.osm import load_osm
from roadtwin.pipeline import build_map
from roadtwin.simulate import simulate_network_run
from roadtwin.xodr import read_xodr, write_xodr

# stations of the two passes over the crossing point (x = 237.1 m on y = 0)
_LOW_S = 237.1
_HIGH_S = 250.0 + 150.0 * np.radians(350.0) + 13.1


@pytest.fixture(scope="module")
def loop_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("loop") / "run"
    return simulate_network_run(self_crossing_network(), out, route=["1"], seed=3, name="loop")


@pytest.fixture(scope="module")
def loop_map(loop_run, tmp_path_factory):
    run = load_run(loop_run)
    osm = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    result = build_map(run, osm)
    path = tmp_path_factory.mktemp("loop_map") / "map.xodr"
    write_xodr(result.network, path)
    return path


def _crossing_points(road, lateral_m: float) -> np.ndarray:
    """(4, 3) points at ``lateral_m`` right of both passes near the crossing, on their
    own road surface."""
    s = np.array([_LOW_S - 20.0, _LOW_S + 5.0, _HIGH_S - 20.0, _HIGH_S + 5.0])
    xy = road.to_xy(s, np.full(s.size, -lateral_m)).reshape(-1, 2)
    return np.column_stack([xy, road.elevation.value(s)]), s


def test_road_projection_keeps_each_point_at_its_level():
    (road,) = self_crossing_network().roads
    pts, s_true = _crossing_points(road, 9.0)
    s, t = road.project(pts)
    np.testing.assert_allclose(s, s_true, atol=1e-3)
    np.testing.assert_allclose(t, -9.0, atol=1e-3)
    # the same points without heights: at least one goes to the other pass
    s_plan, _ = road.project(pts[:, :2])
    assert np.max(np.abs(s_plan - s_true)) > 100.0


def test_frame_projection_keeps_each_point_at_its_level():
    (road,) = self_crossing_network().roads
    s_line = np.linspace(0.0, road.length, int(road.length) + 1)
    xyz = np.column_stack([road.xy(s_line), road.elevation.value(s_line)])
    frame = PolylineFrame.from_points(xyz)
    assert frame.z is not None
    assert frame.z.max() == pytest.approx(LOOP_RISE_M)
    pts, s_true = _crossing_points(road, 9.0)
    s, t = frame.project(pts)
    np.testing.assert_allclose(s, s_true, atol=0.01)
    np.testing.assert_allclose(t, -9.0, atol=0.01)


def test_truth_evaluated_against_itself_is_exact(loop_run):
    # each true boundary point must be compared with its own level of the one road
    rep = evaluate_paths(loop_run / "truth.xodr", [loop_run]).runs[0]
    for kind in ("truth/road_edge", "truth/lane_boundary"):
        err = rep.details[kind].error_m
        assert np.max(np.abs(err)) < 1e-3, kind


def test_mainline_of_a_run_passing_over_itself(loop_run, loop_map):
    rep = evaluate_paths(loop_map, [loop_run]).runs[0]
    for kind in ("truth/road_edge", "truth/lane_boundary"):
        err = rep.details[kind].error_m
        rmse = float(np.sqrt(np.mean(err**2)))
        # 0.014 / 0.017 m (0.36 m and 2.5 m at most before: the crossing's points went to
        # the other pass)
        assert rmse < 0.05, (kind, rmse)
        assert np.max(np.abs(err)) < 0.3, (kind, float(np.max(np.abs(err))))
    (road,) = [r for r in read_xodr(loop_map).roads if r.name == "mainline"]
    # the map's own road climbs where the truth does and is flat on the first straight
    z = road.elevation.value(np.array([100.0, road.length - 100.0]))
    np.testing.assert_allclose(z, [0.0, LOOP_RISE_M], atol=0.15)


def test_points_without_real_heights_are_placed_in_plan():
    # edge points exported with z = 0 along a road that climbs 9 m: their heights say
    # nothing about the level, so plan distance decides (3-D would pull them to the low
    # part of the loop)
    (road,) = self_crossing_network().roads
    s_true = np.array([900.0, 1000.0, 1100.0, 1400.0])
    xy = road.to_xy(s_true, np.full(s_true.size, -9.0)).reshape(-1, 2)
    s, t = road.project(np.column_stack([xy, np.zeros(s_true.size)]))
    np.testing.assert_allclose(s, s_true, atol=1e-3)
    np.testing.assert_allclose(t, -9.0, atol=1e-3)


def test_point_below_the_road_with_no_pass_there_keeps_its_station_in_plan():
    # an edge point of a road passing 3.05 m under the climbing part: no pass of the run
    # lies at its level, so the 3-D lookup (which finds a sample a few metres back, where
    # the road is lower) must not move it
    (road,) = self_crossing_network().roads
    s_tab, tree = road._projection_index
    z_tab = road.elevation.value(s_tab)
    s0 = 600.0
    xy = road.to_xy(np.array([s0]), np.array([-12.0])).reshape(-1, 2)
    pts = np.column_stack([xy, road.elevation.value(np.array([s0])) - 3.05])
    _, plan = tree.query(pts[:, :2])
    idx = nearest_at_level(tree, s_tab, z_tab, lambda: road._projection_index_3d, pts)
    assert idx.tolist() == plan.tolist()
    _, idx_3d = road._projection_index_3d.query(
        np.column_stack([pts[:, :2], HEIGHT_WEIGHT * pts[:, 2]])
    )
    assert idx_3d.tolist() != plan.tolist()  # what a plain 3-D lookup would take


def test_dense_run_passing_over_itself(loop_run, tmp_path):
    # 40 times the points (0.55 M, a real mapper's density): the density reduction places
    # points in cells along the trajectory in plan; the rows keep their own heights, so
    # the build still tells the two passes apart
    import shutil

    import laspy

    dense = tmp_path / "run"
    shutil.copytree(loop_run, dense)
    las = laspy.read(loop_run / "road_edges.laz")
    rng = np.random.default_rng(0)
    k = 40
    out = laspy.LasData(laspy.LasHeader(point_format=las.header.point_format))
    out.header.scales, out.header.offsets = las.header.scales, las.header.offsets
    for name, std in (("x", 0.03), ("y", 0.03), ("z", 0.02)):
        values = np.repeat(np.asarray(getattr(las, name)), k)
        setattr(out, name, values + rng.normal(0.0, std, values.size))
    out.write(dense / "road_edges.laz")
    run = load_run(dense)
    assert run.edge_reduction is not None
    assert run.edge_reduction.reduced
    osm = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    path = tmp_path / "map.xodr"
    write_xodr(build_map(run, osm).network, path)
    rep = evaluate_paths(path, [dense]).runs[0]
    for kind in ("truth/road_edge", "truth/lane_boundary"):
        err = rep.details[kind].error_m
        assert float(np.sqrt(np.mean(err**2))) < 0.05, kind
