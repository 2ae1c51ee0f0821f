"""Density benchmark: build cost and accuracy from 0.1 M to 50 M road-edge points.

Run: ``python benchmarks/bench_density.py [--cases 2km-0.1M 2km-1M 2km-10M 2km-sim10x 10km
100km] [--workdir DIR] [--json FILE] [--src DIR] [--no-cli] [--no-startup] [--seeds 1 2 ...]``.

Cases (runs are cached in ``--workdir``):

- ``2km-0.1M``, ``2km-1M``, ``2km-10M``: the bundled ``straight_curve_2km`` run (seed 7) with
  its road-edge points repeated with 2 cm Gaussian jitter to 0.1 / 1 / 10 M points and its
  lane samples to a fifth of that (2 M at 10 M). Repeating adds no information: the map
  can at best be as accurate as from the sparse run.
- ``2km-sim10x``: the same scenario simulated with a sensor ten times as dense
  (``[sensor] edge_spacing_m = 0.02``, ``lane_spacing_m = 0.05``): independent points, so
  more data should give a better map.
- ``10km``, ``100km``: ``bench_pipeline``'s runs of that length (exit/entry pairs every 5 km)
  at 500 k edge points and 100 k lane samples per km, written the same way (50 M and 10 M
  points at 100 km).

Densified files keep the source order in blocks of 1000 source points (their repetitions
follow each block), as a mapper writes points in time order.

Every case runs in fresh child processes:

1. the load floor: ``laspy.read`` of the LAZ alone, then ``pandas.read_csv`` of the
   lane-sample CSV alone (seconds, peak RSS);
2. the build, stage by stage through :mod:`roadtwin.progress` (seconds and peak RSS
   ``ru_maxrss`` when each stage ends): load road edges, load lane samples (both inside
   ``load_run``), load OSM, mainline, ramps, topology, self-consistency, write xodr; then
   (not timed) the map against the simulator's truth: mainline edge, lane-boundary and
   elevation RMSE and the lane count;
3. ``roadtwin -q build --no-check --no-drive`` as a user runs it: wall seconds and the
   process's peak RSS (``os.wait4``).

``--src DIR`` measures another checkout's ``src`` (e.g. ``git archive main | tar -x -C
DIR``) with the same harness: the "before" columns of ``benchmarks/RESULTS.md``.
The start-up section times ``roadtwin --help`` and the time from launching
``roadtwin build`` to the start of its first stage. ``--seeds`` compares the truth RMSE
over simulator seeds: the 2 km run at the default sensor, at ten times its density (every
point, and reduced to rows) and repeated to 1 M points (one seed is no measure: a gore
placed a metre off puts one 6 m error into the RMSE of a whole run).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

JITTER_M = 0.02
BLOCK = 1_000  # source points per block of repetitions (about 100 m of road)


# ---------------------------------------------------------------------------
# dense runs
# ---------------------------------------------------------------------------


def _repeat_index(start: int, stop: int, counts: np.ndarray) -> np.ndarray:
    """Source rows ``start..stop`` repeated ``counts[i]`` times, in rounds (as ``np.tile``)."""
    idx = np.repeat(np.arange(start, stop), counts[start:stop])
    first = np.concatenate([[0], np.cumsum(counts[start:stop])[:-1]])
    rank = np.arange(idx.size) - np.repeat(first, counts[start:stop])
    return idx[np.lexsort((idx, rank))]


def _spread(total: int, m: int) -> np.ndarray:
    """Repetitions of each of ``m`` source rows so that they add up to ``total`` and
    differ by at most one (the extra ones spread evenly)."""
    i = np.arange(m + 1, dtype=np.int64)
    return np.diff((i * total) // m)


def densify_run(
    src: Path,
    dst: Path,
    *,
    edge_points: int,
    lane_samples: int,
    jitter_m: float = JITTER_M,
    seed: int = 0,
) -> None:
    """Copy a simulated run with its edge points and lane samples repeated with jitter.

    Parameters
    ----------
    src, dst
        Source run folder (``road_edges.laz``, ``lane_samples.csv``) and the new folder.
    edge_points, lane_samples
        Total counts to write: each source point is repeated ``n / n_src`` times (rounded,
        evenly spread so the density is the same all along the run) with ``jitter_m``
        Gaussian noise in x, y and z, in blocks of ``BLOCK`` source points (file order).
    """
    import laspy
    import pyarrow as pa
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(seed)
    dst.mkdir(parents=True, exist_ok=True)
    for name in ("run.toml", "trajectory.csv", "map.osm", "truth.xodr", "truth.json"):
        if (src / name).is_file():
            shutil.copy2(src / name, dst / name)
    las = laspy.read(src / "road_edges.laz")
    xyz = np.column_stack([las.x, las.y, las.z])
    side = np.asarray(las.side)
    header = laspy.LasHeader(point_format=0, version="1.2")
    header.add_extra_dim(laspy.ExtraBytesParams(name="side", type=np.uint8))
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.floor(xyz.min(axis=0)) - 1.0
    counts = _spread(edge_points, xyz.shape[0])
    with laspy.open(dst / "road_edges.laz", mode="w", header=header) as writer:
        for start in range(0, xyz.shape[0], BLOCK):
            idx = _repeat_index(start, min(start + BLOCK, xyz.shape[0]), counts)
            pts = xyz[idx] + rng.normal(0.0, jitter_m, (idx.size, 3))
            rec = laspy.ScaleAwarePointRecord.zeros(idx.size, header=header)
            rec.x, rec.y, rec.z = pts[:, 0], pts[:, 1], pts[:, 2]
            rec.side = side[idx]
            writer.write_points(rec)

    table = pcsv.read_csv(src / "lane_samples.csv")
    cols = {name: table.column(name).to_numpy() for name in table.column_names}
    m = cols["x"].size
    counts = _spread(lane_samples, m)
    parts = [_repeat_index(a, min(a + BLOCK, m), counts) for a in range(0, m, BLOCK)]
    idx = np.concatenate(parts)
    data = {}
    for name, values in cols.items():
        col = values[idx]
        if name in ("x", "y", "z"):
            col = np.round(col + rng.normal(0.0, jitter_m, idx.size), 4)
        data[name] = col
    with pa.OSFile(str(dst / "lane_samples.csv"), "wb") as fh:
        pcsv.write_csv(pa.table(data), fh)


# ---------------------------------------------------------------------------
# cases
# ---------------------------------------------------------------------------

CASES = ("2km-0.1M", "2km-1M", "2km-10M", "2km-sim10x", "10km", "100km")
EDGES_PER_KM = 500_000
LANES_PER_KM = 100_000


def _stamped(run_dir: Path, stamp: dict[str, Any]) -> bool:
    """Whether ``run_dir`` was made from ``stamp`` (the cache key)."""
    f = run_dir / ".bench_density.json"
    return f.is_file() and f.read_text(encoding="utf-8") == json.dumps(stamp, sort_keys=True)


def _stamp(run_dir: Path, stamp: dict[str, Any]) -> None:
    (run_dir / ".bench_density.json").write_text(json.dumps(stamp, sort_keys=True), "utf-8")


def _scenario_doc(**sensor: float) -> dict[str, Any]:
    from importlib import resources

    import tomllib

    text = resources.files("roadtwin") / "data" / "scenarios" / "straight_curve_2km.toml"
    doc = tomllib.loads(text.read_text(encoding="utf-8"))
    if sensor:
        doc["sensor"] = dict(sensor)
    return doc


def ensure_case(workdir: Path, case: str) -> Path:
    """The run folder of ``case`` (simulated and densified on first use)."""
    from roadtwin.simulate import simulate_run
    from roadtwin.simulate.scenario import scenario_from_dict

    base = workdir / "base_2km"
    if not _stamped(base, {"case": "base_2km", "seed": 7}):
        simulate_run(scenario_from_dict(_scenario_doc(), name="straight_curve_2km"), base, seed=7)
        _stamp(base, {"case": "base_2km", "seed": 7})
    if case == "2km-sparse":
        return base
    run_dir = workdir / case
    if case.startswith("2km-") and case.endswith("M"):
        n = round(float(case[4:-1]) * 1e6)
        stamp = {"case": case, "edges": n, "lanes": n // 5, "block": BLOCK}
        if not _stamped(run_dir, stamp):
            densify_run(base, run_dir, edge_points=n, lane_samples=n // 5)
            _stamp(run_dir, stamp)
        return run_dir
    if case == "2km-sim10x":
        stamp = {"case": case, "seed": 7}
        if not _stamped(run_dir, stamp):
            doc = _scenario_doc(edge_spacing_m=0.02, lane_spacing_m=0.05)
            simulate_run(scenario_from_dict(doc, name="straight_curve_2km"), run_dir, seed=7)
            _stamp(run_dir, stamp)
        return run_dir
    if case.endswith("km"):
        from bench_pipeline import ensure_run

        km = float(case[:-2])
        src, _ = ensure_run(workdir / "pipeline_runs", km, 20)
        stamp = {"case": case, "edges_per_km": EDGES_PER_KM, "lanes_per_km": LANES_PER_KM}
        if not _stamped(run_dir, stamp):
            densify_run(
                src,
                run_dir,
                edge_points=round(km * EDGES_PER_KM),
                lane_samples=round(km * LANES_PER_KM),
            )
            _stamp(run_dir, stamp)
        return run_dir
    raise SystemExit(f"unknown case {case!r}; known: {', '.join(CASES)}")


# ---------------------------------------------------------------------------
# child processes
# ---------------------------------------------------------------------------


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def child_floor(run_dir: Path, out_json: Path) -> None:
    """Read the edge LAZ with laspy alone, then the lane CSV with pandas alone."""
    import laspy
    import pandas as pd

    rec: dict[str, Any] = {}
    t0 = time.perf_counter()
    las = laspy.read(run_dir / "road_edges.laz")
    rec["laz_points"] = int(las.header.point_count)
    rec["laz_s"] = time.perf_counter() - t0
    rec["laz_rss_mb"] = _rss_mb()
    del las
    t0 = time.perf_counter()
    df = pd.read_csv(run_dir / "lane_samples.csv")
    rec["csv_rows"] = int(df.shape[0])
    rec["csv_s"] = time.perf_counter() - t0
    rec["rss_mb"] = _rss_mb()
    out_json.write_text(json.dumps(rec), encoding="utf-8")


def child_build(run_dir: Path, out_json: Path) -> None:
    """The build stage by stage (progress hook), then its accuracy against the truth."""
    import logging
    import tempfile
    import warnings

    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    t_import = time.perf_counter()
    from roadtwin.config import PipelineConfig
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map
    from roadtwin.xodr import write_xodr

    try:
        from roadtwin.inputs import load_runs_and_osm
    except ImportError:  # a checkout from before the concurrent load
        load_runs_and_osm = None
    stages: dict[str, dict[str, float]] = {}
    try:
        from roadtwin.progress import listening
    except ImportError:  # a checkout from before the progress hook
        listening = None

    class Bar:
        def __init__(self, name: str, total: float | None, unit: str) -> None:
            self.name, self.t0, self.c0 = name, time.perf_counter(), time.process_time()

        def update(self, n: float = 1) -> None:
            return None

        def close(self) -> None:
            stages[self.name] = {
                "s": time.perf_counter() - self.t0,
                "cpu_s": time.process_time() - self.c0,
                "rss_mb": _rss_mb(),
            }

    def timed(name: str, fn):
        t0, c0 = time.perf_counter(), time.process_time()
        value = fn()
        stages[name] = {
            "s": time.perf_counter() - t0,
            "cpu_s": time.process_time() - c0,
            "rss_mb": _rss_mb(),
        }
        return value

    imports_s = time.perf_counter() - t_import
    cfg = PipelineConfig()
    import contextlib

    ctx = listening(Bar) if listening is not None else contextlib.nullcontext()
    out = Path(tempfile.mkdtemp(prefix="bench-density-"))
    t_all = time.perf_counter()
    try:
        with ctx:
            if load_runs_and_osm is not None:  # what roadtwin build calls
                runs, osm = timed(
                    "load run and OSM", lambda: load_runs_and_osm([run_dir], cfg.load)
                )
                run = runs[0]
            else:
                run = timed("load run", lambda: load_run(run_dir, config=cfg.load))
                osm = timed(
                    "load OSM",
                    lambda: load_osm(
                        run.osm_path, frame=run.frame, around_xy=run.trajectory.xy, config=cfg.load
                    ),
                )
            result = timed("build map", lambda: build_map(run, osm, config=cfg))
            timed("write xodr", lambda: write_xodr(result.network, out / "map.xodr"))
        total_s = time.perf_counter() - t_all
        for name, sec in result.timings_s.items():  # checkouts without the progress hook
            stages.setdefault(name, {"s": sec, "cpu_s": float("nan"), "rss_mb": float("nan")})
        rec: dict[str, Any] = {"stages": stages, "total_s": total_s, "imports_s": imports_s}
        rec["rss_mb"] = _rss_mb()
        summary = run.summary()
        rec["edge_points"] = summary.edge_points
        rec["lane_samples"] = summary.lane_samples
        rec["edge_rows"] = int(run.edges.shape[0])
        rec["lane_rows"] = int(run.lane_samples.shape[0])
        rec["ramps"] = len(result.ramps)
        if (run_dir / "truth.xodr").is_file():
            from roadtwin.evaluation import load_truth
            from roadtwin.evaluation.metrics import _truth_mainline

            truth, _ = load_truth(run_dir / "truth.xodr")
            acc, _ = _truth_mainline(result.network, truth, cfg.evaluation)
            rec["truth"] = {
                "edge_rmse_m": acc["road_edge"]["rmse_m"],
                "lane_rmse_m": acc["lane_boundary"]["rmse_m"],
                "elevation_rmse_m": acc["elevation"]["rmse_m"],
                "lane_count_ok": acc["lane_count"]["matched_fraction"],
            }
    finally:
        shutil.rmtree(out, ignore_errors=True)
    out_json.write_text(json.dumps(rec), encoding="utf-8")


THREADS = "1"
"""BLAS/OpenMP threads of the measured processes (``roadtwin`` itself sets 1: see cli.py)."""


def _env(src: Path | None) -> dict[str, str]:
    env = dict(os.environ)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = THREADS
    paths = [str(Path(__file__).resolve().parent)]
    if src is not None:
        paths.insert(0, str(src))
    env["PYTHONPATH"] = os.pathsep.join([*paths, env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def run_child(mode: str, run_dir: Path, src: Path | None, timeout_s: float) -> dict[str, Any]:
    out = run_dir.parent / f".{run_dir.name}.{mode}.json"
    out.unlink(missing_ok=True)
    cmd = [sys.executable, __file__, f"--child-{mode}", str(run_dir), "--child-out", str(out)]
    proc = subprocess.run(cmd, env=_env(src), timeout=timeout_s, check=False)
    if proc.returncode != 0 or not out.is_file():
        return {"error": f"child exited {proc.returncode}"}
    return json.loads(out.read_text(encoding="utf-8"))


def run_cli(run_dir: Path, src: Path | None, timeout_s: float) -> dict[str, Any]:
    """``roadtwin -q build --no-check --no-drive``: wall seconds and peak RSS of the process."""
    import tempfile

    out = Path(tempfile.mkdtemp(prefix="bench-density-cli-"))
    args = ["-q", "build", str(run_dir), "-o", str(out), *NO_EXTRAS]
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-c", _MAIN, *args],
        env=_env(src),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        _, status, usage = os.wait4(proc.pid, 0)
    finally:
        shutil.rmtree(out, ignore_errors=True)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    return {"s": wall, "rss_mb": usage.ru_maxrss / 1024.0, "exit": proc.returncode}


# ---------------------------------------------------------------------------
# start-up
# ---------------------------------------------------------------------------

NO_EXTRAS = ("--no-check", "--no-drive")
_MAIN = "import sys; from roadtwin.cli import main; sys.exit(main())"
_FIRST_STAGE = """
import sys, time
import roadtwin.cli as cli
inner_factory = cli._progress_listener
def factory(args):
    inner = inner_factory(args)
    def listener(name, total, unit):
        if not getattr(listener, "seen", False):
            listener.seen = True
            print(f"\\nFIRST_STAGE {time.time():.6f} {name}", file=sys.stderr, flush=True)
        return inner(name, total, unit)
    return listener
cli._progress_listener = factory
sys.exit(cli.main(sys.argv[1:]))
"""


def startup(run_dir: Path, src: Path | None, repeat: int = 5) -> dict[str, float]:
    """Best-of-``repeat`` seconds of ``roadtwin --help`` and from launching ``roadtwin build``
    to the start of its first stage (``import roadtwin.cli`` + ``main`` as the console
    script does; a checkout without the progress hook gives NaN)."""
    import tempfile

    env = _env(src)
    helps, firsts = [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-c", _MAIN, "--help"],
            capture_output=True,
            check=True,
            env=env,
        )
        helps.append(time.perf_counter() - t0)
        out = Path(tempfile.mkdtemp(prefix="bench-density-start-"))
        t_launch = time.time()
        proc = subprocess.Popen(
            [sys.executable, "-c", _FIRST_STAGE, "build", str(run_dir), "-o", str(out), *NO_EXTRAS],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        first = None
        assert proc.stderr is not None
        for line in proc.stderr:
            if "FIRST_STAGE" in line:
                first = float(line.split("FIRST_STAGE", 1)[1].split()[0]) - t_launch
                break
        proc.kill()
        proc.wait()
        shutil.rmtree(out, ignore_errors=True)
        if first is not None:
            firsts.append(first)
    return {"help_s": min(helps), "first_stage_s": min(firsts) if firsts else float("nan")}


# ---------------------------------------------------------------------------
# accuracy over seeds
# ---------------------------------------------------------------------------


def _truth_rmse(run_dir: Path, *, reduce: bool) -> tuple[float, float, float]:
    """Mainline edge, lane-boundary and elevation RMSE (metres) of a default build."""
    import logging
    import warnings

    from roadtwin.config import PipelineConfig
    from roadtwin.evaluation import load_truth
    from roadtwin.evaluation.metrics import _truth_mainline
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map

    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    cfg = PipelineConfig()
    run = load_run(run_dir, config=cfg.load, reduce=reduce)
    osm = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy, config=cfg.load)
    built = build_map(run, osm, config=cfg)
    truth, _ = load_truth(run_dir / "truth.xodr")
    acc, _ = _truth_mainline(built.network, truth, cfg.evaluation)
    return tuple(acc[k]["rmse_m"] for k in ("road_edge", "lane_boundary", "elevation"))


def accuracy_seeds(workdir: Path, seeds: list[int]) -> dict[int, dict[str, tuple]]:
    """Per seed: the 2 km scenario at the default sensor (sparse), at ten times the density
    with every point and reduced to rows, and the sparse run repeated to 1 M points."""
    from roadtwin.simulate import simulate_run
    from roadtwin.simulate.scenario import scenario_from_dict

    out: dict[int, dict[str, tuple]] = {}
    for seed in seeds:
        root = workdir / f"seed_{seed}"
        sparse, dense, rep = root / "sparse", root / "sim10x", root / "rep1M"
        if not _stamped(root, {"seed": seed, "block": BLOCK}):
            doc = _scenario_doc()
            simulate_run(scenario_from_dict(doc, name="straight_curve_2km"), sparse, seed=seed)
            doc = _scenario_doc(edge_spacing_m=0.02, lane_spacing_m=0.05)
            simulate_run(scenario_from_dict(doc, name="straight_curve_2km"), dense, seed=seed)
            densify_run(sparse, rep, edge_points=1_000_000, lane_samples=200_000, seed=seed)
            _stamp(root, {"seed": seed, "block": BLOCK})
        out[seed] = {
            "sparse": _truth_rmse(sparse, reduce=True),
            "sim10x points": _truth_rmse(dense, reduce=False),
            "sim10x rows": _truth_rmse(dense, reduce=True),
            "repeated 1M rows": _truth_rmse(rep, reduce=True),
        }
        print(
            f"seed {seed}: "
            + ", ".join(
                f"{k} {_f(v[0] * 1e3, 1)}/{_f(v[1] * 1e3, 1)}/{_f(v[2] * 1e3, 1)} mm"
                for k, v in out[seed].items()
            ),
            flush=True,
        )
    return out


def seeds_table(out: dict[int, dict[str, tuple]]) -> str:
    """Markdown: per variant, mean and median over seeds of edge / lane / elevation RMSE."""
    variants = list(next(iter(out.values())))
    lines = [
        "| run (2 km, per seed) | edge RMSE mean / median mm | lane RMSE mean / median mm "
        "| elevation RMSE mean / median mm |",
        "|---|---:|---:|---:|",
    ]
    for v in variants:
        vals = np.array([out[s][v] for s in out]) * 1e3
        cells = [f"{np.mean(vals[:, k]):.1f} / {np.median(vals[:, k]):.1f}" for k in range(3)]
        lines.append(f"| {v} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------

_STAGES = (
    "load road edges",
    "load lane samples",
    "load run",
    "load OSM",
    "load run and OSM",
    "mainline",
    "ramps",
    "topology",
    "self-consistency",
    "write xodr",
)


def _f(x: Any, digits: int = 2) -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "—"
    return f"{x:.{digits}f}"


def tables(results: dict[str, dict[str, Any]]) -> str:
    """Markdown tables: per case, and per stage (seconds, ns per input point)."""
    lines = [
        "| case | edge pts | lane samples | rows (edge / lane) | floor s (LAZ + CSV) | build s "
        "| x floor | `roadtwin build` s | peak RSS MB | edge RMSE | lane RMSE | elev RMSE "
        "| lanes ok |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for case, r in results.items():
        b, fl, cli = r.get("build", {}), r.get("floor", {}), r.get("cli", {})
        floor = fl.get("laz_s", np.nan) + fl.get("csv_s", np.nan)
        tr = b.get("truth", {})
        lines.append(
            f"| {case} | {b.get('edge_points', 0):,} | {b.get('lane_samples', 0):,} "
            f"| {b.get('edge_rows', 0):,} / {b.get('lane_rows', 0):,} "
            f"| {_f(fl.get('laz_s'))} + {_f(fl.get('csv_s'))} | {_f(b.get('total_s'))} "
            f"| {_f(b.get('total_s', np.nan) / floor, 1)} | {_f(cli.get('s'))} "
            f"| {_f(max(cli.get('rss_mb', 0.0), b.get('rss_mb', 0.0)), 0)} "
            f"| {_f(tr.get('edge_rmse_m'), 4)} | {_f(tr.get('lane_rmse_m'), 4)} "
            f"| {_f(tr.get('elevation_rmse_m'), 4)} | {_f(tr.get('lane_count_ok'), 3)} |"
        )
    lines += [
        "",
        "Per stage: seconds (CPU seconds) and ns per input point (edge + lane points):",
        "",
    ]
    names = list(results)
    lines.append("| stage | " + " | ".join(names) + " |")
    lines.append("|---|" + "---:|" * len(names))
    for stage in _STAGES:
        cells = []
        for case in names:
            b = results[case].get("build", {})
            st = b.get("stages", {}).get(stage)
            pts = b.get("edge_points", 0) + b.get("lane_samples", 0)
            if st is None or not pts:
                cells.append("—")
                continue
            per = st["s"] / pts * 1e9
            cells.append(f"{_f(st['s'])} ({_f(st.get('cpu_s'))}) · {per:.0f} ns")
        lines.append(f"| {stage} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", nargs="*", default=list(CASES), help=f"of {', '.join(CASES)}")
    p.add_argument("--workdir", type=Path, default=Path("/tmp/roadtwin-bench-density"))
    p.add_argument("--src", type=Path, default=None, help="measure this checkout's src folder")
    p.add_argument("--json", type=Path, default=None, help="write the raw numbers here")
    p.add_argument("--no-cli", action="store_true", help="skip the roadtwin build runs")
    p.add_argument("--no-startup", action="store_true", help="skip the start-up timings")
    p.add_argument("--timeout", type=float, default=3600.0, help="seconds per child")
    p.add_argument(
        "--seeds",
        type=int,
        nargs="*",
        default=[],
        help="also compare truth RMSE over these seeds (sparse / 10x sensor / repeated)",
    )
    p.add_argument("--child-floor", type=Path, default=None, help=argparse.SUPPRESS)
    p.add_argument("--child-build", type=Path, default=None, help=argparse.SUPPRESS)
    p.add_argument("--child-out", type=Path, default=None, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child_floor is not None:
        child_floor(args.child_floor, args.child_out)
        return 0
    if args.child_build is not None:
        child_build(args.child_build, args.child_out)
        return 0

    from bench_pipeline import machine

    args.workdir.mkdir(parents=True, exist_ok=True)
    info = machine()
    info["blas_threads"] = THREADS
    info["src"] = str(args.src) if args.src else "this checkout"
    print("# roadtwin density benchmark", flush=True)
    print(", ".join(f"{k}: {v}" for k, v in info.items()), flush=True)
    results: dict[str, dict[str, Any]] = {}
    for case in args.cases:
        run_dir = ensure_case(args.workdir, case)
        rec: dict[str, Any] = {"load_before": " ".join(f"{x:.1f}" for x in os.getloadavg())}
        rec["floor"] = run_child("floor", run_dir, args.src, args.timeout)
        rec["build"] = run_child("build", run_dir, args.src, args.timeout)
        if not args.no_cli:
            rec["cli"] = run_cli(run_dir, args.src, args.timeout)
        rec["load_after"] = " ".join(f"{x:.1f}" for x in os.getloadavg())
        results[case] = rec
        b = rec["build"]
        print(
            f"{case}: build {_f(b.get('total_s'))} s, peak {_f(b.get('rss_mb'), 0)} MB, "
            f"floor {_f(rec['floor'].get('laz_s'))} + {_f(rec['floor'].get('csv_s'))} s, "
            f"cli {_f(rec.get('cli', {}).get('s'))} s (load {rec['load_before']} -> "
            f"{rec['load_after']})",
            flush=True,
        )
    if results:
        print()
        print(tables(results))
    if not args.no_startup:
        start = startup(ensure_case(args.workdir, "2km-sparse"), args.src)
        info.update({k: f"{v:.3f}" for k, v in start.items()})
        print(
            f"\nstart-up: roadtwin --help {start['help_s']:.3f} s, first stage of a build "
            f"{start['first_stage_s']:.3f} s after launch (best of 5)"
        )
    seeds = {}
    if args.seeds:
        seeds = accuracy_seeds(args.workdir, args.seeds)
        print()
        print(seeds_table(seeds))
    if args.json:
        payload = {"machine": info, "results": results, "seeds": seeds}
        args.json.write_text(json.dumps(payload, indent=1), "utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
