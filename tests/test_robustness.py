"""Robustness: runs valid by DESIGN.md section 3 but written differently than our simulator.

One simulated base run (``straight_curve_2km``) per module; each variant is the base run
rewritten by ``benchmarks/robustness.py`` (other file formats, column orders, keys, frames,
noise). Format-only variants must load to the same arrays as the base run (mm); variants
that change the algorithm's input are built and evaluated against the truth.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from roadtwin._errors import InputWarning
from roadtwin.io import load_run

_BENCH = Path(__file__).resolve().parents[1] / "benchmarks" / "robustness.py"
_spec = importlib.util.spec_from_file_location("roadtwin_bench_robustness", _BENCH)
rb = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = rb
_spec.loader.exec_module(rb)

EDGE_RMSE_MAX_M = 0.15  # road edges vs truth, metres
LANE_RMSE_MAX_M = 0.10  # lane boundaries vs truth, metres
SHIFT_P95_MAX_M = 0.01  # frame/format-only change: same map (p95 distance to the base build)


def _short_scenario(sc):
    """The demo scenario cut to its first 1 km (straight, clothoid, 300 m of arc) with its
    exit only: the same road and sensor, half the build time."""
    al = sc.alignment
    return dataclasses.replace(
        sc,
        name="straight_curve_1km",
        alignment=(al[0], al[1], dataclasses.replace(al[2], length_m=300.0)),
        ramps=sc.ramps[:1],
        grades=sc.grades[:1],
        other_roads=tuple(r for r in sc.other_roads if r.station_m < 900.0),
    )


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """The simulated base run, read into memory, and its build."""
    root = tmp_path_factory.mktemp("robust")
    run_dir = rb.simulate_base("straight_curve_2km", root / "_base", _short_scenario)
    data = rb.read_base(run_dir)
    row = rb.build_and_evaluate(run_dir, root / "_base" / "out", roundtrip=False)
    assert row["ok"], row.get("error")
    return {"root": root, "data": data, "row": row, "run": _load(run_dir)}


def _load(run_dir: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InputWarning)
        return load_run(run_dir)


def _write(base, name: str) -> Path:
    rd = rb.VARIANTS[name](base["data"], np.random.default_rng(0))
    return rb.write_run(rd, base["root"] / name)


def _sorted_rows(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]


# ---------------------------------------------------------------------------
# format-only variants: the loaded run must be the same (to the LAS mm grid)
# ---------------------------------------------------------------------------

SAME_LOAD = [
    "edges_no_side",
    "edges_las",
    "edges_csv",
    "edges_ply_f32",
    "edges_ply_ascii",
    "edges_npy",
    "edges_npy_no_side",
    "edges_parquet",
    "shuffled_points",
    "column_order",
    "extra_columns",
    "extra_columns_csv",
    "csv_bom_crlf",
    "traj_pitch_roll",
    "gps_epoch_t",
    "frame_gaps",
    "lanes_by_t_exact",
    "lanes_by_t_between",
    "pose_height_1.8",
    "shuffled_trajectory_rows",
    "edges_side_capitalised",
    "edges_side_int_codes",
    "frame_as_float",
    "lanes_rear_ego",
]


@pytest.mark.parametrize("name", SAME_LOAD)
def test_variant_loads_like_base(base, name):
    run = _load(_write(base, name))
    ref = base["run"]
    np.testing.assert_allclose(run.trajectory.xy, ref.trajectory.xy, atol=1e-6)
    np.testing.assert_allclose(run.trajectory.yaw, ref.trajectory.yaw, atol=1e-6)
    z_shift = 1.8 if name == "pose_height_1.8" else 0.0
    np.testing.assert_allclose(
        run.trajectory.xyz[:, 2], ref.trajectory.xyz[:, 2] + z_shift, atol=1e-6
    )
    assert run.edges.shape == ref.edges.shape
    tol = 6e-4 if name == "edges_ply_f32" else 1.1e-3  # float32 / LAS mm grid
    np.testing.assert_allclose(_sorted_rows(run.edges), _sorted_rows(ref.edges), atol=tol)
    if "no_side" not in name:
        assert (np.sort(run.edge_side) == np.sort(ref.edge_side)).all()
    else:
        assert (run.edge_side == 0).all()
    assert run.lane_samples.shape == ref.lane_samples.shape
    np.testing.assert_allclose(
        _sorted_rows(run.lane_samples), _sorted_rows(ref.lane_samples), atol=1e-3
    )


# ---------------------------------------------------------------------------
# variants that change what the algorithm sees: build + evaluate against truth
# ---------------------------------------------------------------------------


def _build(base, name: str) -> dict:
    row = rb.run_variant(base["data"], name, base["root"], roundtrip=False)
    assert row["ok"], row.get("error")
    row["shift"] = rb.shift_vs_base(base["row"], row)
    return row


def _assert_accuracy(row: dict, *, edge=EDGE_RMSE_MAX_M, lane=LANE_RMSE_MAX_M) -> None:
    assert row["ramps_matched"] == row["ramps_true"] == 1, row["ramps"]
    assert row["edge_rmse"] <= edge, (row["edge_rmse"], row["edge_p95"], row["spikes"])
    assert row["lane_rmse"] <= lane, (row["lane_rmse"], row["lane_p95"])


def test_baseline_accuracy(base):
    _assert_accuracy(base["row"])


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The full 2 km demo run (two gore cuts, run end on a junction-free road)."""
    root = tmp_path_factory.mktemp("robust_demo")
    run_dir = rb.simulate_base("straight_curve_2km", root / "_base")
    return {"root": root, "data": rb.read_base(run_dir), "dir": run_dir}


@pytest.mark.parametrize(
    "name",
    [
        "baseline",
        "edge_density_half",  # gore stations were 1-2 m off (6 m spikes): fixed 19:57
    ],
)
def test_demo_run_has_no_error_spikes(demo, name):
    """No true boundary point of the 2 km demo more than 0.5 m off; edge RMSE <= 0.10 m."""
    rd = rb.VARIANTS[name](demo["data"], np.random.default_rng(0))
    run_dir = rb.write_run(rd, demo["root"] / name)
    row = rb.build_and_evaluate(run_dir, run_dir / "out", roundtrip=False)
    assert row["ok"], row.get("error")
    assert row["spikes"] == 0, (row["spikes"], row["edge_rmse"], row["edge_p95"])
    assert row["edge_rmse"] <= 0.10


def test_wrapped_yaw_builds_the_rotated_map(base):
    """Heading across +-pi (whole run, OSM and truth rotated): same accuracy, same map."""
    row = _build(base, "rotated_yaw_wraps_pi")
    assert row["shift"][1] <= SHIFT_P95_MAX_M, row["shift"]
    _assert_accuracy(row)


def test_utm_frame_gives_the_same_map(base):
    """A UTM CRS (large coordinates, grid convergence, absolute heights): the same road."""
    row = _build(base, "crs_utm")
    assert row["shift"][1] <= SHIFT_P95_MAX_M, row["shift"]
    _assert_accuracy(row)


@pytest.mark.parametrize(
    "name",
    [
        "edges_csv_no_side",
        "edge_outliers_10pct",
        "occlusion_80m_left",
        "edge_density_half",
        "lane_miss_and_false_pos",
        "osm_no_lanes_coarse_links",
    ],
)
def test_degraded_input_stays_accurate(base, name):
    _assert_accuracy(_build(base, name))


@pytest.mark.parametrize("name", ["rotated_yaw_wraps_pi", "rotated_yaw_0_2pi"])
def test_wrapped_yaw_loads_like_rotated_base(base, name):
    """Heading crossing +-pi, yaw written wrapped to (-pi, pi] or [0, 2 pi)."""
    rd = rb.VARIANTS[name](base["data"], np.random.default_rng(0))
    run = _load(rb.write_run(rd, base["root"] / name))
    theta = rd.truth_xform[0]
    c, s = np.cos(theta), np.sin(theta)
    rot = np.array([[c, -s], [s, c]])
    ref = base["run"]
    assert np.abs(np.diff(run.trajectory.yaw)).max() < 0.1  # unwrapped
    np.testing.assert_allclose(run.trajectory.xy, ref.trajectory.xy @ rot.T, atol=1e-5)
    np.testing.assert_allclose(
        _sorted_rows(run.lane_samples[:, :2]),
        _sorted_rows(ref.lane_samples[:, :2] @ rot.T),
        atol=1e-3,
    )


def _build_with(base, name: str, variant) -> dict:
    rd = variant(base["data"], np.random.default_rng(0))
    run_dir = rb.write_run(rd, base["root"] / name)
    row = rb.build_and_evaluate(run_dir, run_dir / "out", roundtrip=False)
    assert row["ok"], row.get("error")
    return row


def test_run_from_gore_area_to_gore_area(demo):
    """The 2 km demo cropped to 600-1300 m: starts 50 m before the exit gore (inside the
    deceleration lane), ends 50 m after the entry gore (inside the acceleration lane)."""
    row = _build_with(demo, "crop_600_1300", rb._crop(600.0, 1300.0))
    assert row["ramps_matched"] == 2, row["ramps"]
    assert row["lane_rmse"] <= LANE_RMSE_MAX_M, (row["lane_rmse"], row["spikes"])
    assert row["edge_rmse"] <= EDGE_RMSE_MAX_M


def test_run_ending_shortly_after_the_exit_gore(base):
    """The run ends 25 m after the exit gore (the median-side edge is occluded over its last
    80 m): the mainline reaches the run's end and the exit gets a shortened junction."""
    row = _build_with(base, "crop_end_675", rb._crop(0.0, 675.0))
    assert row["ramps_matched"] == 1, row["ramps"]
    assert row["edge_rmse"] <= EDGE_RMSE_MAX_M, (row["edge_rmse"], row["spikes"])
    assert row["lane_rmse"] <= LANE_RMSE_MAX_M, (row["lane_rmse"], row["spikes"])


@pytest.mark.xfail(
    reason="run ends 10 m after the exit gore: 8 m of mainline remain after the gore, less "
    "than a junction plus a mainline road of min_road_length_m (5 m) each, so topology "
    "skips the exit",
    strict=True,
)
def test_run_ending_just_after_the_exit_gore(base):
    row = _build_with(base, "crop_end_660", rb._crop(0.0, 660.0))
    assert row["ramps_matched"] == 1, row["ramps"]
    assert row["edge_rmse"] <= EDGE_RMSE_MAX_M, (row["edge_rmse"], row["spikes"])


def test_median_edge_unseen_at_the_start(base):
    """No median-side edge point over the first 250 m (out of reach across a wide road):
    the road still starts where the run does, its reference holding the offset from the
    trajectory it had where the edge was first seen, and the build says so. (The mainline
    had begun where the edge was first seen: 250 m of the run were not in the map.)"""
    from roadtwin.pipeline import build_map

    rd = rb.VARIANTS["median_unseen_first_250m"](base["data"], np.random.default_rng(0))
    run_dir = rb.write_run(rd, base["root"] / "median_unseen")
    result = build_map(_load(run_dir), None)
    main = [r for r in result.network.roads if r.name == "mainline"]
    xy = base["run"].trajectory.xy
    driven = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
    # the junction of the exit is not named mainline: 20-40 m
    assert driven - 45.0 < sum(r.length for r in main) < driven + 5.0
    assert any("median-side road edge was not seen" in w for w in result.warnings)
    row = rb.build_and_evaluate(run_dir, run_dir / "out", roundtrip=False)
    assert row["edge_rmse"] <= EDGE_RMSE_MAX_M, (row["edge_rmse"], row["spikes"])
    assert row["lane_rmse"] <= LANE_RMSE_MAX_M, (row["lane_rmse"], row["spikes"])


def test_left_hand_demo_edge_accuracy(tmp_path):
    """left_hand_2km's entry gore (1250 m) lies in a truck occlusion of the outer edge
    (1213-1283 m); the marking's solid/broken change and the hard-shoulder taper place it."""
    run_dir = rb.simulate_base("left_hand_2km", tmp_path / "run")
    row = rb.build_and_evaluate(run_dir, tmp_path / "out", roundtrip=False)
    assert row["ok"], row.get("error")
    assert row["ramps_matched"] == row["ramps_true"] == 2, row["ramps"]
    assert row["edge_rmse"] <= EDGE_RMSE_MAX_M, (row["edge_rmse"], row["spikes"])


def test_run_without_osm_is_valid(base):
    from roadtwin.check import check_network
    from roadtwin.pipeline import build_map

    rd = rb.VARIANTS["no_osm"](base["data"], np.random.default_rng(0))
    run = _load(rb.write_run(rd, base["root"] / "no_osm"))
    result = build_map(run, None)
    errors = [f for f in check_network(result.network) if f.severity == "error"]
    assert not errors, [f.message for f in errors]
