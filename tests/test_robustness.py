"""Robustness: runs valid by DESIGN.md section 3 but written differently than our simulator.

One simulated base run (``straight_curve_2km``) per module; each variant is the base run
rewritten by ``benchmarks/robustness.py`` (other file formats, column orders, keys, frames,
noise). Format-only variants must load to the same arrays as the base run (mm); variants
that change the algorithm's input are built and evaluated against the truth.
"""

from __future__ import annotations

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


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """The simulated base run, read into memory, and its build."""
    root = tmp_path_factory.mktemp("robust")
    run_dir = rb.simulate_base("straight_curve_2km", root / "_base")
    data = rb.read_base(run_dir)
    row = rb.build_and_evaluate(run_dir, root / "_base" / "out")
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
    pytest.param(
        "shuffled_trajectory_rows",
        marks=pytest.mark.xfail(
            reason="io.read_trajectory checks 't' strictly increasing in FILE order instead "
            "of sorting the rows first; section 3 does not require sorted rows",
            strict=True,
        ),
    ),
]


@pytest.mark.parametrize("name", SAME_LOAD)
def test_variant_loads_like_base(base, name):
    run = _load(_write(base, name))
    ref = base["run"]
    np.testing.assert_allclose(run.trajectory.xy, ref.trajectory.xy, atol=1e-6)
    np.testing.assert_allclose(run.trajectory.yaw, ref.trajectory.yaw, atol=1e-6)
    z_shift = 1.8 if name == "pose_height_1.8" else 0.0
    np.testing.assert_allclose(run.trajectory.xyz[:, 2], ref.trajectory.xyz[:, 2] + z_shift, atol=1e-6)
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
    row = rb.run_variant(base["data"], name, base["root"])
    assert row["ok"], row.get("error")
    row["shift"] = rb.shift_vs_base(base["row"], row)
    return row


def _assert_accuracy(row: dict, *, edge=EDGE_RMSE_MAX_M, lane=LANE_RMSE_MAX_M) -> None:
    assert row["ramps_matched"] == row["ramps_true"] == 2, row["ramps"]
    assert row["edge_rmse"] <= edge, (row["edge_rmse"], row["edge_p95"], row["spikes"])
    assert row["lane_rmse"] <= lane, (row["lane_rmse"], row["lane_p95"])


def test_baseline_accuracy(base):
    _assert_accuracy(base["row"])


@pytest.mark.xfail(
    reason="mainline: the hard-shoulder width cubic of the last lane section overshoots in "
    "the last ~3 m of the run (negative width, road edge off by 3 m; check ERROR "
    "negative_width), and truth points within 1 m of the gore cuts match the connector's "
    "edge 6 m away; these 3 points alone lift the edge RMSE from ~0.02 to 0.08 m",
    strict=True,
)
def test_baseline_has_no_error_spikes(base):
    assert base["row"]["spikes"] == 0
    assert base["row"]["check_errors"] == 0


@pytest.mark.parametrize("name", ["crs_utm", "origin_far"])
def test_other_frame_gives_the_same_map(base, name):
    """A UTM CRS (large coordinates, grid convergence) or a far origin: the same road."""
    row = _build(base, name)
    assert row["shift"][1] <= SHIFT_P95_MAX_M, row["shift"]
    _assert_accuracy(row)


@pytest.mark.parametrize(
    "name",
    [
        "edges_csv_no_side",
        "edge_outliers_10pct",
        "occlusion_80m_left",
        "edge_range_15m",
        "lane_miss_frames_20pct",
        "lane_false_pos_5pct",
        "osm_no_lanes_tags",
        "osm_coarse_links",
    ],
)
def test_degraded_input_stays_accurate(base, name):
    _assert_accuracy(_build(base, name))


@pytest.mark.xfail(
    reason="with half the edge points the gore-cut spikes (road-end matching, see "
    "test_baseline_has_no_error_spikes) dominate: edge RMSE 0.165 m, p95 0.034 m",
    strict=True,
)
def test_half_edge_density_stays_accurate(base):
    _assert_accuracy(_build(base, "edge_density_half"))
