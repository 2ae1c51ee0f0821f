"""Mapping-run loader: every road-edge format, lane-sample transforms, validation."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest

from _run_factory import EDGE_FORMATS, MARKINGS_T, write_run
from roadtwin._errors import InputError, InputWarning
from roadtwin.config import LoadConfig
from roadtwin.io import MappingRun, load_run, read_road_edges


@pytest.mark.parametrize("edge_format", EDGE_FORMATS)
def test_every_edge_format_loads_the_same_points(tmp_path, edge_format):
    truth = write_run(tmp_path / edge_format, edge_format=edge_format)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = load_run(truth.root)
    assert isinstance(run, MappingRun)
    np.testing.assert_allclose(run.edges, truth.edges, atol=1e-6, rtol=0)
    np.testing.assert_array_equal(run.edge_side, truth.edge_side)
    assert run.edges.dtype == np.float64
    assert run.edges.shape == (truth.edges.shape[0], 3)
    np.testing.assert_allclose(run.lane_samples, truth.lane_world, atol=1e-6, rtol=0)
    np.testing.assert_array_equal(run.lane_sample_frame, truth.lane_frame)
    np.testing.assert_array_equal(run.trajectory.frame, truth.frame)
    np.testing.assert_allclose(run.trajectory.xyz, truth.pose_xyz, atol=1e-6)
    assert (run.dropped_edge_points, run.dropped_lane_samples) == (0, 0)


def test_trajectory_yaw_unwrapped_across_pi(tmp_path):
    truth = write_run(tmp_path, yaw0=2.9)  # turns left through +pi; file holds wrapped yaw
    run = load_run(tmp_path)
    assert np.abs(np.diff(run.trajectory.yaw)).max() < 0.01
    np.testing.assert_allclose(run.trajectory.yaw, truth.yaw, atol=1e-8)
    assert run.trajectory.yaw[-1] > np.pi  # continuous, not wrapped back to -pi


@pytest.mark.parametrize("yaw0", [2.9, -0.4])
def test_time_keyed_lane_samples_lie_on_the_true_markings(tmp_path, yaw0):
    """t rows: pose interpolated (unwrapped yaw); samples land on circles around the arc
    centre at radius R - t_marking (independent of how the factory interpolated)."""
    radius = 600.0
    truth = write_run(tmp_path, lane_key="t", yaw0=yaw0, radius_m=radius)
    run = load_run(tmp_path)
    x0, y0 = 150.0, -80.0  # factory start point; centre is to the left of the start pose
    cx, cy = x0 - radius * np.sin(yaw0), y0 + radius * np.cos(yaw0)
    r = np.hypot(run.lane_samples[:, 0] - cx, run.lane_samples[:, 1] - cy)
    lateral = radius - r  # positive to the left of the driving direction
    expected = np.tile(np.asarray(MARKINGS_T), r.size // len(MARKINGS_T))
    # linear pose interpolation on a 2.5 m chord of a 600 m arc: sag 1.3 mm at most
    np.testing.assert_allclose(lateral, expected, atol=3e-3)
    np.testing.assert_allclose(run.lane_samples, truth.lane_world, atol=1e-6)
    assert set(np.unique(run.lane_sample_frame)) <= set(truth.frame.tolist())


def test_lane_sample_transform_by_hand(tmp_path):
    """One pose at (10, 20, 5) with yaw 90 deg: ego (2, 1) -> mapping (9, 22)."""
    (tmp_path / "run.toml").write_text(
        "[origin]\nlat = 47.0\nlon = 15.0\n[vehicle]\npose_height = 1.5\n[files]\n"
        'trajectory = "tr.csv"\nroad_edges = "e.csv"\nlane_samples = "l.csv"\n'
    )
    yaw = np.pi / 2
    pd.DataFrame(
        {
            "frame": [1, 2, 3],
            "t": [0.0, 0.1, 0.2],
            "x": [10.0, 10.0, 10.0],
            "y": [20.0, 22.0, 24.0],
            "z": [5.0, 5.0, 5.0],
            "yaw": [yaw] * 3,
        }
    ).to_csv(tmp_path / "tr.csv", index=False)
    pd.DataFrame({"x": [9.0, 11.0], "y": [21.0, 21.0], "z": [3.5, 3.5]}).to_csv(
        tmp_path / "e.csv", index=False
    )
    pd.DataFrame({"frame": [1, 3], "x": [2.0, 0.0], "y": [1.0, -1.75]}).to_csv(
        tmp_path / "l.csv", index=False
    )
    run = load_run(tmp_path, config=LoadConfig(min_driven_m=1.0))  # a 4 m run
    np.testing.assert_allclose(run.lane_samples, [[9.0, 22.0, 3.5], [11.75, 24.0, 3.5]], atol=1e-12)
    np.testing.assert_array_equal(run.lane_sample_frame, [1, 3])
    np.testing.assert_array_equal(run.edge_side, [0, 0])
    assert run.pose_height_m == 1.5
    assert run.frame.crs == "local"
    assert run.osm_path is None
    assert run.traffic_side == "right"


def test_lane_z_without_column_uses_pose_height(tmp_path):
    truth = write_run(tmp_path, with_lane_z=False, pose_height_m=1.8)
    run = load_run(tmp_path)
    np.testing.assert_allclose(run.lane_samples, truth.lane_world, atol=1e-6)
    # road surface: pose z minus the pose height
    idx = np.searchsorted(truth.frame, run.lane_sample_frame)
    np.testing.assert_allclose(run.lane_samples[:, 2], truth.pose_xyz[idx, 2] - 1.8, atol=1e-9)


def test_summary_numbers(tmp_path):
    truth = write_run(tmp_path, n_frames=200, speed_mps=25.0, rate_hz=10.0, radius_m=600.0)
    s = load_run(tmp_path).summary()
    assert s.frames == 200
    assert s.duration_s == pytest.approx(19.9, abs=1e-6)
    assert s.driven_length_m == pytest.approx(25.0 * 19.9, rel=1e-5)  # chords of an arc
    assert s.edge_points == truth.edges.shape[0]
    assert s.lane_samples == truth.lane_world.shape[0]
    xy = np.vstack([truth.pose_xyz[:, :2], truth.edges[:, :2]])
    assert s.bbox_m == pytest.approx((*xy.min(axis=0), *xy.max(axis=0)), abs=1e-6)
    assert s.crs == "local"


def test_far_points_are_dropped_with_a_count(tmp_path):
    truth = write_run(tmp_path, edge_format="csv")
    df = pd.read_csv(tmp_path / "road_edges.csv")
    far = pd.DataFrame(
        {"x": [5000.0, 5001.0, -4000.0], "y": [0.0, 1.0, 2.0], "z": 0.0, "side": "left"}
    )
    pd.concat([df.iloc[:10], far, df.iloc[10:]]).to_csv(tmp_path / "road_edges.csv", index=False)
    with pytest.warns(InputWarning, match=r"dropped 3 of .* road-edge points .* data row 11"):
        run = load_run(tmp_path)
    assert run.dropped_edge_points == 3
    assert run.summary().dropped_edge_points == 3
    np.testing.assert_allclose(run.edges, truth.edges, atol=1e-6)


def test_config_distance_limit(tmp_path):
    write_run(tmp_path)
    with pytest.warns(InputWarning) as record:
        run = load_run(tmp_path, config=LoadConfig(max_point_distance_m=5.0))
    messages = [str(w.message) for w in record]
    assert any("road-edge points farther than 5 m" in m for m in messages)
    assert any("lane samples farther than 5 m" in m for m in messages)
    assert run.dropped_edge_points > 0  # the right edge is 11.5 m away
    assert np.all(run.edge_side[run.edge_side != 0] == 1)


@pytest.mark.filterwarnings("ignore:You will likely lose important projection")
def test_projected_crs_and_traffic_side(tmp_path):
    write_run(tmp_path, crs="EPSG:32632", start_xy=(680000.0, 5540000.0))
    toml = (tmp_path / "run.toml").read_text().replace('side = "right"', 'side = "left"')
    (tmp_path / "run.toml").write_text(toml)
    run = load_run(tmp_path / "run.toml")  # the manifest path works too
    assert run.frame.crs == "EPSG:32632"
    assert run.traffic_side == "left"
    assert "+proj=utm" in run.frame.geo_reference
    assert run.trajectory.xyz[0, 0] == pytest.approx(680000.0)


def test_ply_with_float_vertices_and_faces(tmp_path):
    """A PLY written like point-cloud tools do: float32, big endian, a face element after."""
    pts = np.array([[1.5, 2.25, 3.0], [4.0, 5.5, -6.0], [7.0, 8.0, 9.125]], dtype=">f4")
    header = (
        b"ply\nformat binary_big_endian 1.0\nobj_info test\nelement vertex 3\n"
        b"property float x\nproperty float y\nproperty float z\nproperty int side\n"
        b"element face 1\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rec = np.empty(3, dtype=[("x", ">f4"), ("y", ">f4"), ("z", ">f4"), ("side", ">i4")])
    rec["x"], rec["y"], rec["z"], rec["side"] = pts[:, 0], pts[:, 1], pts[:, 2], [1, 2, 0]
    face = b"\x03" + np.array([0, 1, 2], ">i4").tobytes()
    (tmp_path / "e.ply").write_bytes(header + rec.tobytes() + face)
    xyz, side = read_road_edges(tmp_path / "e.ply")
    np.testing.assert_allclose(xyz, pts.astype(float), atol=0)
    np.testing.assert_array_equal(side, [1, -1, 0])


def test_many_points_with_text_sides(tmp_path):
    """50k points: CSV with text sides and NPY agree with what was written."""
    n = 50_000
    rng = np.random.default_rng(3)
    xyz = rng.normal(size=(n, 3)) * [100.0, 100.0, 1.0]
    words = np.where(rng.random(n) < 0.5, "left", "right")
    np.save(tmp_path / "big.npy", xyz)
    pd.DataFrame(xyz, columns=["x", "y", "z"]).assign(side=words).to_csv(
        tmp_path / "big.csv", index=False
    )
    a, side_a = read_road_edges(tmp_path / "big.csv")
    b, side_b = read_road_edges(tmp_path / "big.npy")
    np.testing.assert_allclose(a, xyz, atol=1e-9)
    np.testing.assert_array_equal(b, xyz)
    np.testing.assert_array_equal(side_a, np.where(words == "left", 1, -1))
    np.testing.assert_array_equal(side_b, 0)


def test_input_error_is_a_value_error(tmp_path):
    with pytest.raises(InputError, match=r"run\.toml: file not found"):
        load_run(tmp_path)
    with pytest.raises(ValueError, match=r"run\.toml"):
        load_run(tmp_path)


@pytest.mark.parametrize(("yaw0", "radius"), [(0.01, 5000.0), (-2.0, 800.0)])
def test_yaw_in_degrees_detected_even_for_small_angles(tmp_path, yaw0, radius):
    write_run(tmp_path, yaw0=yaw0, radius_m=radius, n_frames=60)
    df = pd.read_csv(tmp_path / "trajectory.csv")
    df["yaw"] = np.degrees(df["yaw"])
    df.to_csv(tmp_path / "trajectory.csv", index=False)
    with pytest.raises(InputError, match=r"trajectory\.csv: column 'yaw' is in degrees"):
        load_run(tmp_path)


def test_noisy_radian_yaw_is_accepted(tmp_path):
    """Realistic pose noise (3 cm, 0.5 deg) must not trip the yaw or jump checks."""
    write_run(tmp_path, yaw0=0.003, radius_m=5000.0, n_frames=300)
    df = pd.read_csv(tmp_path / "trajectory.csv")
    rng = np.random.default_rng(7)
    df[["x", "y"]] += rng.normal(0.0, 0.03, size=(len(df), 2))
    df["yaw"] += rng.normal(0.0, np.radians(0.5), size=len(df))
    df.to_csv(tmp_path / "trajectory.csv", index=False)
    run = load_run(tmp_path)
    assert run.trajectory.frame.size == 300


def test_npy_fourth_column_that_is_not_a_side_is_ignored(tmp_path):
    xyz = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    np.save(tmp_path / "e.npy", np.c_[xyz, [0.37, 12.0]])  # e.g. intensity
    with pytest.warns(InputWarning, match="4th column is not a side code"):
        got, side = read_road_edges(tmp_path / "e.npy")
    np.testing.assert_array_equal(got, xyz)
    np.testing.assert_array_equal(side, [0, 0])


def test_high_rate_noisy_poses_pass_the_yaw_check(tmp_path):
    """200 Hz poses (12 cm apart) with 3 cm noise: yaw checked over a longer baseline."""
    write_run(tmp_path, yaw0=1.0, radius_m=2000.0, n_frames=2000, rate_hz=200.0)
    df = pd.read_csv(tmp_path / "trajectory.csv")
    rng = np.random.default_rng(11)
    df[["x", "y"]] += rng.normal(0.0, 0.03, size=(len(df), 2))
    df.to_csv(tmp_path / "trajectory.csv", index=False)
    assert load_run(tmp_path).trajectory.frame.size == 2000
    df["yaw"] = np.degrees(df["yaw"])
    df.to_csv(tmp_path / "trajectory.csv", index=False)
    with pytest.raises(InputError, match="in degrees"):
        load_run(tmp_path)


def test_lane_sample_time_just_past_the_last_pose_is_clamped(tmp_path):
    truth = write_run(tmp_path, n_frames=40, rate_hz=10.0)
    lanes = pd.DataFrame(
        {"t": [truth.t[0] - 0.05, truth.t[-1] + 0.05], "x": [0.0, 0.0], "y": [0.0, 0.0]}
    )
    lanes.to_csv(tmp_path / "lane_samples.csv", index=False)
    run = load_run(tmp_path)
    np.testing.assert_allclose(run.lane_samples[:, :2], truth.pose_xyz[[0, -1], :2], atol=1e-9)
    np.testing.assert_array_equal(run.lane_sample_frame, truth.frame[[0, -1]])
