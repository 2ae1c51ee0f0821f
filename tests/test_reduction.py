"""Density reduction: dense points -> a few rows per metre of each line, linear and exact.

Real simulated runs (the bundled 2 km scenario, its sensor at the default and at ten times
the density) and synthetic lines with known positions; numbers are asserted, not shapes.
"""

from __future__ import annotations

import dataclasses
import warnings
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomllib

from _run_factory import write_run
from roadtwin._errors import InputWarning
from roadtwin.config import LoadConfig, PipelineConfig
from roadtwin.evaluation import load_truth
from roadtwin.evaluation.metrics import _truth_mainline, self_consistency
from roadtwin.io import load_run, reduce_run
from roadtwin.osm import load_osm
from roadtwin.pipeline import build_map
from roadtwin.pointfiles import read_road_edges
from roadtwin.progress import listening
from roadtwin.reduction import CellAccumulator, trajectory_line
from roadtwin.simulate import simulate_run
from roadtwin.simulate.scenario import scenario_from_dict

CFG = LoadConfig()


def _scenario(**sensor):
    text = (
        resources.files("roadtwin") / "data" / "scenarios" / "straight_curve_2km.toml"
    ).read_text()
    doc = tomllib.loads(text)
    if sensor:
        doc["sensor"] = sensor
    return scenario_from_dict(doc, name="straight_curve_2km")


@pytest.fixture(scope="module")
def sparse_dir(tmp_path_factory) -> Path:
    return simulate_run(_scenario(), tmp_path_factory.mktemp("sparse") / "run")


@pytest.fixture(scope="module")
def dense_dir(tmp_path_factory) -> Path:
    """Ten times the default sensor density (0.02 m edge, 0.05 m lane spacing)."""
    run_dir = tmp_path_factory.mktemp("dense") / "run"
    return simulate_run(_scenario(edge_spacing_m=0.02, lane_spacing_m=0.05), run_dir)


def _repeat_edges(src: Path, dst: Path, repeats: int, *, seed: int = 0, shuffle=False) -> None:
    """Copy a run with every edge point repeated ``repeats`` times with 2 cm jitter (LAZ)."""
    import shutil

    import laspy

    dst.mkdir(parents=True, exist_ok=True)
    for name in ("run.toml", "trajectory.csv", "lane_samples.csv", "map.osm"):
        shutil.copy2(src / name, dst / name)
    las = laspy.read(src / "road_edges.laz")
    rng = np.random.default_rng(seed)
    xyz = np.tile(np.column_stack([las.x, las.y, las.z]), (repeats, 1))
    side = np.tile(np.asarray(las.side), repeats)
    xyz = xyz + rng.normal(0.0, 0.02, xyz.shape)
    if shuffle:
        order = rng.permutation(side.size)
        xyz, side = xyz[order], side[order]
    out = laspy.LasData(las.header)
    out.x, out.y, out.z = xyz.T
    out.side = side
    out.write(dst / "road_edges.laz")


def _line_rows_per_m(run, side: int) -> float:
    """Rows per metre along the run of the given edge side (dominant line + its outliers)."""
    return np.count_nonzero(run.edge_side == side) / run.trajectory.length_m


# ---------------------------------------------------------------------------
# whole runs
# ---------------------------------------------------------------------------


def test_sparse_run_passes_unchanged(sparse_dir):
    run = load_run(sparse_dir)
    raw, side = read_road_edges(sparse_dir / "road_edges.laz")
    assert not run.edge_reduction.reduced
    assert not run.lane_reduction.reduced
    np.testing.assert_array_equal(run.edges, raw)  # same points, same order
    np.testing.assert_array_equal(run.edge_side, side)
    assert run.edge_reduction.points == raw.shape[0]
    assert run.summary().edge_points == raw.shape[0]
    assert reduce_run(run) is run


def test_repeated_points_give_the_target_density_whatever_the_repeats(sparse_dir, tmp_path):
    rows = {}
    for repeats in (20, 60):
        _repeat_edges(sparse_dir, tmp_path / f"x{repeats}", repeats)
        run = load_run(tmp_path / f"x{repeats}")
        info = run.edge_reduction
        assert info.reduced
        assert info.points == repeats * read_road_edges(sparse_dir / "road_edges.laz")[0].shape[0]
        rows[repeats] = info.rows
        # one row per point is the limit: never more rows than the points they stand for
        assert info.rows < info.points / 5
        for side in (1, -1):
            per_m = _line_rows_per_m(run, side)
            assert 0.7 * CFG.edge_points_per_m < per_m < 1.6 * CFG.edge_points_per_m
    assert rows[60] == pytest.approx(rows[20], rel=0.1)  # density-invariant output


def test_reduction_is_deterministic_and_independent_of_chunks_and_order(sparse_dir, tmp_path):
    _repeat_edges(sparse_dir, tmp_path / "a", 30)
    _repeat_edges(sparse_dir, tmp_path / "b", 30, shuffle=True)
    a1 = load_run(tmp_path / "a")
    a2 = load_run(tmp_path / "a")
    assert a1.edges.tobytes() == a2.edges.tobytes()  # same input -> same bytes
    small = load_run(tmp_path / "a", config=dataclasses.replace(CFG, chunk_points=37_123))
    shuffled = load_run(tmp_path / "b")
    for other in (small, shuffled):
        assert other.edges.shape == a1.edges.shape
        np.testing.assert_allclose(other.edges, a1.edges, atol=1e-6, rtol=0)
        np.testing.assert_array_equal(other.edge_side, a1.edge_side)


def test_dense_build_is_as_accurate_as_with_every_point(dense_dir):
    """Ten times the sensor density, reduced to rows, against the same run with every point:
    the map is as close to the truth (1.5 mm), and the self-consistency over all points
    (row errors plus the spread behind each row) is the same metric."""
    cfg = PipelineConfig()
    truth, _ = load_truth(dense_dir / "truth.xodr")
    result = {}
    for name, reduce in (("rows", True), ("points", False)):
        run = load_run(dense_dir, reduce=reduce)
        osm = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
        built = build_map(run, osm, config=cfg)
        acc, _ = _truth_mainline(built.network, truth, cfg.evaluation)
        sc = self_consistency(built.network, run)
        result[name] = (acc, sc, run)
    rows, points = result["rows"], result["points"]
    assert rows[2].edge_reduction.reduced
    assert rows[2].lane_reduction.reduced
    assert rows[2].edges.shape[0] < 0.5 * points[2].edges.shape[0]
    for kind in ("road_edge", "lane_boundary"):
        assert rows[0][kind]["rmse_m"] <= points[0][kind]["rmse_m"] + 0.0015
        assert rows[0][kind]["rmse_m"] < 0.05
    assert rows[0]["lane_count"]["matched_fraction"] >= points[0]["lane_count"]["matched_fraction"]
    for key in ("road_edge_rmse_m", "lane_boundary_rmse_m"):
        assert rows[1][key] == pytest.approx(points[1][key], rel=0.1)


# ---------------------------------------------------------------------------
# the accumulator on synthetic lines (straight trajectory along +x)
# ---------------------------------------------------------------------------


def _accumulator(length_m=400.0, **kw):
    x = np.linspace(0.0, length_m, int(length_m / 2.5) + 1)
    line = trajectory_line(np.column_stack([x, np.zeros_like(x)]))
    args = {
        "n_groups": 1,
        "station_bin_m": 0.25,
        "lateral_bin_m": 0.05,
        "max_lateral_m": 60.0,
        "keep_raw_points": 0,
    }
    args.update(kw)
    return CellAccumulator(line, **args)


def _line_points(rng, s0, s1, per_m, t, noise=0.03):
    n = int((s1 - s0) * per_m)
    return np.column_stack(
        [rng.uniform(s0, s1, n), t + rng.normal(0.0, noise, n), rng.normal(0.0, 0.01, n)]
    )


def test_outliers_keep_their_share_of_the_rows():
    rng = np.random.default_rng(1)
    line = _line_points(rng, 0.0, 400.0, 2000.0, -3.0)
    n_out = line.shape[0] // 100  # 1 % outliers 0.5-3 m beside the line
    out = np.column_stack(
        [
            rng.uniform(0.0, 400.0, n_out),
            -3.0 + rng.choice([-1, 1], n_out) * rng.uniform(0.5, 3.0, n_out),
            np.zeros(n_out),
        ]
    )
    pts = np.vstack([line, out])
    acc = _accumulator()
    acc.add(pts, np.zeros(pts.shape[0], np.int64))
    rows = acc.finish(target_per_m=10.0, reduce_factor=2.0)
    far = np.abs(rows.xyz[:, 1] + 3.0) > 0.4
    assert rows.info.reduced
    assert 0.004 < np.mean(far) < 0.02
    near = rows.xyz[~far, 1]
    assert abs(np.mean(near) + 3.0) < 0.003
    assert rows.xyz.shape[0] == pytest.approx(4000 * 1.01, rel=0.1)


def test_local_density_decides_the_rows_per_metre():
    """A mapper that slowed down: the first half ten times denser than the second; both get
    the target density, the sparse half is not thinned below it."""
    rng = np.random.default_rng(2)
    pts = np.vstack(
        [_line_points(rng, 0.0, 200.0, 3000.0, 5.0), _line_points(rng, 200.0, 400.0, 300.0, 5.0)]
    )
    acc = _accumulator()
    acc.add(pts, np.zeros(pts.shape[0], np.int64))
    rows = acc.finish(target_per_m=8.0, reduce_factor=2.0)
    first = np.count_nonzero(rows.xyz[:, 0] < 200.0) / 200.0
    second = np.count_nonzero(rows.xyz[:, 0] >= 200.0) / 200.0
    assert first == pytest.approx(8.0, rel=0.15)
    assert second == pytest.approx(8.0, rel=0.15)


def test_two_close_lines_stay_two_lines():
    """Markings 0.25 m apart (a double line): rows on each, none in between."""
    rng = np.random.default_rng(3)
    pts = np.vstack(
        [
            _line_points(rng, 0.0, 400.0, 1500.0, 2.0, noise=0.02),
            _line_points(rng, 0.0, 400.0, 1500.0, 2.25, noise=0.02),
        ]
    )
    acc = _accumulator()
    acc.add(pts, np.zeros(pts.shape[0], np.int64))
    t = acc.finish(target_per_m=5.0, reduce_factor=2.0).xyz[:, 1]
    between = (t > 2.07) & (t < 2.18)
    assert np.mean(between) < 0.02
    assert abs(np.mean(t[t < 2.125]) - 2.0) < 0.005
    assert abs(np.mean(t[t >= 2.125]) - 2.25) < 0.005


def test_cells_carry_the_lateral_spread():
    rng = np.random.default_rng(4)
    pts = _line_points(rng, 0.0, 400.0, 2000.0, 1.0, noise=0.03)
    acc = _accumulator()
    acc.add(pts, np.zeros(pts.shape[0], np.int64))
    rows = acc.finish(target_per_m=10.0, reduce_factor=2.0)
    # a row is the mean of its line's points in the station bin; its spread is their variance
    total = np.mean((rows.xyz[:, 1] - 1.0) ** 2 + rows.info.spread_m2)
    assert np.sqrt(total) == pytest.approx(0.03, rel=0.1)
    assert np.std(rows.xyz[:, 1]) < 0.01


# ---------------------------------------------------------------------------
# loading in chunks keeps every check
# ---------------------------------------------------------------------------


def test_far_points_counted_across_chunks(tmp_path):
    write_run(tmp_path, edge_format="csv")
    df = pd.read_csv(tmp_path / "road_edges.csv")
    far = df.iloc[:3].assign(x=df["x"].iloc[:3] + 5000.0)
    pd.concat([df.iloc[:130], far, df.iloc[130:]]).to_csv(tmp_path / "road_edges.csv", index=False)
    cfg = dataclasses.replace(CFG, chunk_points=50)  # the far points are in the third chunk
    with pytest.warns(InputWarning, match=r"dropped 3 of \d+ road-edge points .* data row 131\)"):
        run = load_run(tmp_path, config=cfg)
    assert run.dropped_edge_points == 3
    assert run.edges.shape[0] == df.shape[0]


def test_load_reports_progress_to_a_listener(sparse_dir):
    seen: dict[str, list] = {}

    class Bar:
        def __init__(self, name, total, unit):
            self.name = name
            seen[name] = [total, unit, 0.0, False]

        def update(self, n=1):
            seen[self.name][2] += n

        def close(self):
            seen[self.name][3] = True

    with listening(Bar), warnings.catch_warnings():
        warnings.simplefilter("error")
        run = load_run(sparse_dir)
    n = run.edges.shape[0]
    assert seen["load road edges"] == [n, "points", n, True]
    assert seen["load lane samples"][2] == run.lane_samples.shape[0]


def test_a_run_built_in_memory_is_reduced_by_the_pipeline_like_by_the_loader(sparse_dir, tmp_path):
    """build_map reduces a dense run that never went through load_run's reduction: the
    same rows as loading with the reduction (the cells do not depend on the chunks or
    the distance limit)."""
    _repeat_edges(sparse_dir, tmp_path / "x", 30)
    loaded = load_run(tmp_path / "x")
    raw = load_run(tmp_path / "x", reduce=False)
    bare = dataclasses.replace(raw, edge_reduction=None, lane_reduction=None)
    reduced = reduce_run(bare)
    assert reduced.edge_reduction.reduced
    assert reduced.edge_reduction.points == loaded.edge_reduction.points
    assert reduced.edges.shape == loaded.edges.shape
    np.testing.assert_allclose(reduced.edges, loaded.edges, atol=1e-6, rtol=0)
    np.testing.assert_array_equal(reduced.edge_side, loaded.edge_side)
    # the sparse lane samples of that run are not reduced: the same arrays come back
    assert not reduced.lane_reduction.reduced
    np.testing.assert_array_equal(reduced.lane_samples, raw.lane_samples)
