"""End-to-end benchmark: time and memory of every pipeline stage on runs of 1, 10 and 100 km.

Run: ``python benchmarks/bench_pipeline.py [--lengths 1 10 100] [--method default|paper]
[--workdir DIR] [--threads 1] [--json FILE]``; ``--only-osm`` runs the netconvert comparison
alone, ``--no-tracemalloc`` skips the (slow) memory pass. Results: ``benchmarks/RESULTS.md``.

The runs are simulated from the bundled ``long_20km`` scenario (DESIGN.md section 5 asks for
1, 10 and 100 km): its alignment period (straight 1200 m, clothoid-arc-clothoid R 1500 m left,
straight 800 m, clothoid-arc-clothoid R 2000 m right = 4200 m) is repeated, every second period
mirrored so that the road does not wind up into a spiral, and cut at a zero-curvature joint,
the rest filled with a straight; its grade pattern repeats every 20 km; its exit/entry pair
(exit at 3000 m, entry at 3500 m, an overpass between) repeats every 5 km (runs shorter than
5 km get one pair at 40 % / 60 % of the length). Simulated runs are cached in ``--workdir``
(``run_<L>km_s<seed>``) and reused when the scenario is unchanged.

Each length is measured in fresh subprocesses so memory figures are clean:

1. a timing pass (no tracing): seconds per stage and the process's peak RSS
   (``ru_maxrss``) after each stage, plus the child's total peak RSS;
2. a memory pass with ``tracemalloc`` (Python and NumPy allocations): the peak traced memory
   of each stage above what was allocated when the stage began (tracing slows Python code,
   so its times are not reported).

Stages: load run, load OSM, mainline, ramps, topology (the three ``build_map`` stages, called
one by one with ``build_map``'s wiring), write xodr / kml / geojson, check (own checks only:
``check_file(external=False)``, includes reading the file back), read truth, evaluate. The
external consumers (SUMO netconvert and the ASAM checker on ``map.xodr``) run once, on the
length given by ``--external-km``. Then SUMO ``netconvert --osm-files map.osm
--opendrive-output x.xodr`` converts the same simulated OSM file, against our OSM stage
(``load_osm`` in a fresh process: cold = first call including the osmnx import, warm = best
of ``--osm-repeat`` later calls; netconvert: best of as many whole-process runs).

Times are reported as wall and CPU seconds (user + system of the measuring process): on a
machine shared with other jobs the CPU seconds are the steadier measure. ``--threads N`` sets
the BLAS/OpenMP thread count of the measured processes.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path
from typing import Any

BASE_SCENARIO = "long_20km"
PERIOD_ELEMENTS = 8  # straight, clothoid, arc, clothoid, straight, clothoid, arc, clothoid
RAMP_SPACING_M = 5000.0
GRADE_PERIOD_M = 20000.0
BUILD_STAGES = (
    "load run",
    "load OSM",
    "mainline",
    "ramps",
    "topology",
    "write xodr",
    "write kml",
    "write geojson",
)
ALL_STAGES = (*BUILD_STAGES, "check (own)", "read truth", "evaluate")
LAZY_IMPORTS = (
    "osmnx",
    "geopandas",
    "sklearn.cluster",
    "scenariogeneration",
    "scipy.spatial",
    "scipy.signal",
    "scipy.interpolate",
    "scipy.optimize",
    "shapely",
    "pyproj",
    "laspy",
    "networkx",
    "lxml.etree",
)


# ---------------------------------------------------------------------------
# scenario of a given length, derived from long_20km
# ---------------------------------------------------------------------------


def _base_document() -> dict[str, Any]:
    try:
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]
    from importlib import resources

    path = resources.files("roadtwin") / "data" / "scenarios" / f"{BASE_SCENARIO}.toml"
    return tomllib.loads(path.read_text(encoding="utf-8"))


def _mirror(element: dict[str, Any]) -> dict[str, Any]:
    out = dict(element)
    if "direction" in out:
        out["direction"] = "right" if out["direction"] == "left" else "left"
    for key in ("curvature_start", "curvature_end"):
        if key in out:
            out[key] = -out[key]
    return out


def _alignment(period: list[dict[str, Any]], length_m: float) -> list[dict[str, Any]]:
    """Repeat ``period`` (mirrored every second time) up to ``length_m``, cut at a joint
    of zero curvature (after a straight or a closing clothoid), fill with a straight."""
    units: list[list[dict[str, Any]]] = []
    k = 0
    total = 0.0
    while total < length_m:
        items = period if k % 2 == 0 else [_mirror(e) for e in period]
        unit: list[dict[str, Any]] = []
        for e in items:
            unit.append(dict(e))
            if e["type"] == "straight" or (e["type"] == "clothoid" and len(unit) > 1):
                units.append(unit)
                total += sum(u["length"] for u in unit)
                unit = []
        k += 1
    out: list[dict[str, Any]] = []
    used = 0.0
    for unit in units:
        unit_len = sum(u["length"] for u in unit)
        if used + unit_len > length_m:
            break
        out.extend(unit)
        used += unit_len
    rest = length_m - used
    if rest >= 0.1:
        if out and out[-1]["type"] == "straight":
            out[-1] = {**out[-1], "length": out[-1]["length"] + rest}
        else:
            out.append({"type": "straight", "length": rest})
    return out


def _grades(vertical: dict[str, Any], length_m: float) -> dict[str, Any]:
    base = vertical.get("grades", [])
    grades: list[dict[str, Any]] = []
    k = 0
    while k * GRADE_PERIOD_M < length_m:
        for i, g in enumerate(base):
            g = dict(g)
            g["station"] = g["station"] + k * GRADE_PERIOD_M
            if k > 0 and i == 0:
                g["curve_length"] = 800.0  # re-enter the pattern through a vertical curve
            if g["station"] + g.get("curve_length", 0.0) / 2.0 <= length_m - 50.0:
                grades.append(g)
        k += 1
    return {**vertical, "grades": grades or [{"station": 0, "grade_pct": 0.0}]}


def bench_document(length_km: float) -> dict[str, Any]:
    """The ``long_20km`` scenario document stretched or cut to ``length_km``."""
    doc = _base_document()
    length_m = float(length_km) * 1000.0
    doc["name"] = f"bench_{length_km:g}km"
    doc["description"] = f"{length_km:g} km derived from {BASE_SCENARIO} for benchmarks"
    doc["alignment"] = _alignment(doc["alignment"][:PERIOD_ELEMENTS], length_m)
    doc["vertical"] = _grades(doc.get("vertical", {}), length_m)
    exit_t, entry_t = (dict(r) for r in doc["ramps"][:2])
    overpass = dict(doc["other_roads"][0]) if doc.get("other_roads") else None
    tail = entry_t.get("parallel_length", 250) + entry_t.get("taper_length", 80) + 100.0
    pairs: list[tuple[float, float]] = []
    k = 0
    while k * RAMP_SPACING_M + entry_t["station"] + tail <= length_m:
        off = k * RAMP_SPACING_M
        pairs.append((exit_t["station"] + off, entry_t["station"] + off))
        k += 1
    if not pairs and length_m >= 900.0:
        pairs.append((round(0.4 * length_m), round(0.6 * length_m)))
    doc["ramps"] = []
    doc["other_roads"] = []
    for ex, en in pairs:
        doc["ramps"] += [{**exit_t, "station": ex}, {**entry_t, "station": en}]
        if overpass is not None:
            doc["other_roads"].append({**overpass, "station": (ex + en) / 2.0})
    return doc


def bench_scenario(length_km: float):
    """A validated :class:`roadtwin.simulate.Scenario` of ``length_km``."""
    from roadtwin.simulate.scenario import scenario_from_dict

    doc = bench_document(length_km)
    return scenario_from_dict(doc, name=doc["name"])


def ensure_run(workdir: Path, length_km: float, seed: int) -> tuple[Path, float | None]:
    """Simulate (or reuse) the run of ``length_km``; returns its folder and the seconds the
    simulation took (``None`` if reused from the cache)."""
    from roadtwin.simulate import simulate_run

    doc = bench_document(length_km)
    stamp = json.dumps({"doc": doc, "seed": seed}, sort_keys=True, default=str)
    run_dir = workdir / f"run_{length_km:g}km_s{seed}"
    stamp_file = run_dir / ".bench_scenario.json"
    cached = (run_dir / "run.toml").is_file() and stamp_file.is_file()
    if cached and stamp_file.read_text(encoding="utf-8") == stamp:
        return run_dir, None
    t0 = time.perf_counter()
    simulate_run(bench_scenario(length_km), run_dir, seed=seed)
    elapsed = time.perf_counter() - t0
    stamp_file.write_text(stamp, encoding="utf-8")
    return run_dir, elapsed


# ---------------------------------------------------------------------------
# child process: run the stages of one length
# ---------------------------------------------------------------------------


def _maxrss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def child(run_dir: Path, out_json: Path, *, method: str, trace: bool, external: bool) -> None:
    """Run every stage once on ``run_dir`` and write per-stage numbers to ``out_json``."""
    import logging

    logging.disable(logging.WARNING)
    import warnings

    warnings.simplefilter("ignore")

    from roadtwin.check import check_file
    from roadtwin.config import PipelineConfig
    from roadtwin.evaluation import evaluate, load_truth
    from roadtwin.export import write_geojson, write_kml
    from roadtwin.io import load_run
    from roadtwin.mainline import build_mainline
    from roadtwin.model import Header, RoadNetwork
    from roadtwin.osm import load_osm
    from roadtwin.ramps import RampSet, build_ramps
    from roadtwin.topology import build_topology
    from roadtwin.xodr import write_xodr

    cfg = PipelineConfig()
    cfg = cfg.with_method(method)
    records: dict[str, dict[str, float]] = {}
    # Heavy libraries some stages import lazily (osmnx alone pulls in geopandas and
    # scikit-learn: seconds): imported up front and timed on their own, so that the stage
    # times are the work per run, not one-off start-up.
    t0, c0 = time.perf_counter(), time.process_time()
    for mod in LAZY_IMPORTS:
        with contextlib.suppress(ImportError):
            importlib.import_module(mod)
    imports = {"s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}
    start_rss = _maxrss_mb()
    if trace:
        tracemalloc.start()

    def stage(name: str, fn):
        base = 0
        if trace:
            tracemalloc.reset_peak()
            base = tracemalloc.get_traced_memory()[0]
        rss0 = _maxrss_mb()
        t0, c0 = time.perf_counter(), time.process_time()
        value = fn()
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        rss1 = _maxrss_mb()
        rec = {"s": dt, "cpu_s": cpu, "rss_mb": rss1, "rss_growth_mb": rss1 - rss0}
        if trace:
            cur, peak = tracemalloc.get_traced_memory()
            rec["traced_peak_mb"] = (peak - base) / 1e6
            rec["traced_kept_mb"] = (cur - base) / 1e6
        records[name] = rec
        return value

    out_dir = Path(tempfile.mkdtemp(prefix="bench-out-"))
    try:
        run = stage("load run", lambda: load_run(run_dir, config=cfg.load))
        osm_graph = stage(
            "load OSM",
            lambda: load_osm(
                run.osm_path, frame=run.frame, around_xy=run.trajectory.xy, config=cfg.load
            ),
        )
        mainline = stage("mainline", lambda: build_mainline(run, config=cfg.mainline))

        def ramps():
            if osm_graph is None or osm_graph.number_of_edges() == 0:
                return RampSet(ramps=(), candidates=())
            return build_ramps(
                osm_graph,
                mainline.road,
                trajectory_xy=run.trajectory.xy,
                traffic_side=run.traffic_side,
                config=cfg.ramps,
            )

        ramp_set = stage("ramps", ramps)
        topology = stage(
            "topology",
            lambda: build_topology(
                mainline.road, ramp_set.ramps, traffic_side=run.traffic_side, config=cfg.topology
            ),
        )
        header = Header(
            name=run_dir.name, rev_major=1, rev_minor=8, geo_reference=run.frame.geo_reference
        )
        network = RoadNetwork(header, topology.roads, topology.junctions)
        xodr = out_dir / "map.xodr"
        stage("write xodr", lambda: write_xodr(network, xodr))
        stage("write kml", lambda: write_kml(network, run.frame, out_dir / "map.kml"))
        stage("write geojson", lambda: write_geojson(network, run.frame, out_dir / "map.geojson"))
        report = stage("check (own)", lambda: check_file(xodr, external=False))
        truth, info = stage("read truth", lambda: load_truth(run_dir / "truth.xodr"))
        ev = stage(
            "evaluate", lambda: evaluate(network, run, truth=truth, truth_info=info, method=method)
        )
        result: dict[str, Any] = {
            "stages": records,
            "imports": imports,
            "start_rss_mb": start_rss,
            "roads": len(network.roads),
            "junctions": len(network.junctions),
            "ramps": len(topology.ramps),
            "mainline_km": sum(r.length for r in network.roads if r.name == "mainline") / 1e3,
            "poses": len(run.trajectory.xy),
            "check_errors": report.errors,
            "xodr_mb": xodr.stat().st_size / 1e6,
        }
        try:
            run_ev = ev.runs[0]
            result["truth_rmse_m"] = {
                k: run_ev.truth[k]["rmse_m"] for k in ("road_edge", "lane_boundary")
            }
        except (AttributeError, IndexError, KeyError, TypeError):  # extra information only
            pass
        if external:
            from roadtwin.consumers import run_asam, run_sumo

            t0 = time.perf_counter()
            sumo = run_sumo(xodr, network)
            t1 = time.perf_counter()
            asam = run_asam(xodr)
            t2 = time.perf_counter()
            result["external"] = {
                "sumo_s": t1 - t0,
                "asam_s": t2 - t1,
                "sumo": _consumer_text(sumo),
                "asam": _consumer_text(asam),
            }
    finally:
        shutil.rmtree(out_dir, ignore_errors=True)
    out_json.write_text(json.dumps(result, indent=1), encoding="utf-8")


def _consumer_text(res: Any) -> str:
    status = getattr(res, "status", "?")
    return (
        f"{status}, {getattr(res, 'errors', '?')} errors, {getattr(res, 'warnings', '?')} warnings"
    )


# ---------------------------------------------------------------------------
# parent: orchestrate, netconvert, tables
# ---------------------------------------------------------------------------


def run_measured(cmd: list[str], **kwargs) -> tuple[int, float, float, float]:
    """Run ``cmd``; return (exit code, wall seconds, CPU seconds (user + system) and peak
    RSS in MB of that process alone)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, **kwargs)
    _, status, usage = os.wait4(proc.pid, 0)
    elapsed = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    return proc.returncode, elapsed, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def run_child(
    run_dir: Path, *, method: str, trace: bool, external: bool, threads: int | None = None
) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="bench-child-") as tmp:
        out = Path(tmp) / "result.json"
        cmd = [
            sys.executable,
            __file__,
            "--child",
            str(run_dir),
            "--child-out",
            str(out),
            "--method",
            method,
        ]
        if trace:
            cmd.append("--child-trace")
        if external:
            cmd.append("--child-external")
        env = dict(os.environ)
        if threads:
            env.update({k: str(threads) for k in THREAD_VARS})
        code, wall, _, maxrss = run_measured(cmd, env=env)
        if code != 0 or not out.is_file():
            msg = f"benchmark child failed on {run_dir} (exit {code})"
            raise RuntimeError(msg)
        result = json.loads(out.read_text(encoding="utf-8"))
    result["wall_s"] = wall
    result["maxrss_mb"] = maxrss
    return result


def netconvert_osm(osm_path: Path, *, repeat: int = 3) -> dict[str, float] | None:
    """SUMO ``netconvert --osm-files OSM --opendrive-output x.xodr``: best of ``repeat``
    runs (wall and CPU seconds of the whole process, its peak RSS)."""
    exe = shutil.which("netconvert") or str(Path(sys.executable).with_name("netconvert"))
    if not Path(exe).is_file():
        return None
    walls, cpus, rss, code = [], [], [], 0
    with tempfile.TemporaryDirectory(prefix="bench-nc-") as tmp:
        cmd = [exe, "--osm-files", str(osm_path), "--opendrive-output", str(Path(tmp) / "x.xodr")]
        for _ in range(max(1, repeat)):
            code, wall, cpu, maxrss = run_measured(
                cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
            )
            walls.append(wall)
            cpus.append(cpu)
            rss.append(maxrss)
    return {"s": min(walls), "cpu_s": min(cpus), "maxrss_mb": max(rss), "exit": code}


def child_osm(run_dir: Path, out_json: Path, *, repeat: int) -> None:
    """Our OSM stage alone: cold (first call in a fresh process, with the osmnx import) and
    warm (best of ``repeat`` further calls), wall and CPU seconds."""
    import logging
    import warnings

    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    from roadtwin.io import load_run

    run = load_run(run_dir)
    t0, c0 = time.perf_counter(), time.process_time()
    from roadtwin.osm import load_osm

    for mod in LAZY_IMPORTS[:2]:  # what load_osm pulls in lazily (osmnx, geopandas)
        importlib.import_module(mod)
    load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    cold = {"s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0}
    walls, cpus = [], []
    for _ in range(max(1, repeat)):
        t0, c0 = time.perf_counter(), time.process_time()
        load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    warm = {"s": min(walls), "cpu_s": min(cpus)}
    out_json.write_text(json.dumps({"cold": cold, "warm": warm}), encoding="utf-8")


def osm_compare(run_dir: Path, *, repeat: int, threads: int | None) -> dict[str, Any]:
    """Our OSM stage (cold and warm) against netconvert on the run's ``map.osm``."""
    with tempfile.TemporaryDirectory(prefix="bench-osm-") as tmp:
        out = Path(tmp) / "osm.json"
        cmd = [sys.executable, __file__, "--child-osm", str(run_dir), "--child-out", str(out)]
        cmd += ["--osm-repeat", str(repeat)]
        env = dict(os.environ)
        if threads:
            env.update({k: str(threads) for k in THREAD_VARS})
        code, _, _, maxrss = run_measured(cmd, env=env)
        if code != 0:
            msg = f"OSM benchmark child failed on {run_dir} (exit {code})"
            raise RuntimeError(msg)
        ours = json.loads(out.read_text(encoding="utf-8"))
    ours["maxrss_mb"] = maxrss
    return {"ours": ours, "netconvert": netconvert_osm(run_dir / "map.osm", repeat=repeat)}


def machine() -> dict[str, str]:
    cpu = "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = "?"
    try:
        mem = subprocess.run(["free", "-h"], capture_output=True, text=True).stdout.splitlines()[1]
        mem = " ".join(mem.split()[:2]).replace("Mem: ", "") + " RAM"
    except (OSError, IndexError):
        pass
    return {
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "nproc": str(os.cpu_count()),
        "cpu": cpu,
        "memory": mem,
        "python": platform.python_version(),
        "load": " ".join(f"{x:.1f}" for x in os.getloadavg()),
    }


def _fmt(x: float | None, digits: int = 2) -> str:
    return "—" if x is None else f"{x:.{digits}f}"


def _stage_rows(r: dict[str, Any]) -> dict[str, dict[str, float]]:
    rows = dict(r["timing"]["stages"])
    st = r["timing"]["stages"]
    rows["build total (load run..write)"] = {
        k: sum(st[n][k] for n in BUILD_STAGES) for k in ("s", "cpu_s")
    }
    rows["all stages (+check, eval)"] = {k: sum(v[k] for v in st.values()) for k in ("s", "cpu_s")}
    return rows


def tables(results: dict[float, dict[str, Any]]) -> str:
    """Markdown: stage x length (wall s, CPU s, MB) and per-km cost with its growth."""
    lengths = sorted(results)
    names = [*ALL_STAGES, "build total (load run..write)", "all stages (+check, eval)"]
    per = {L: _stage_rows(results[L]) for L in lengths}
    lines = [
        "| stage | " + " | ".join(f"{L:g} km wall s | CPU s | MB" for L in lengths) + " |",
        "|---|" + "---:|---:|---:|" * len(lengths),
    ]
    imp = [results[L]["timing"]["imports"] for L in lengths]
    lines.append(
        "| (one-off imports: osmnx, sklearn, ...) | "
        + " | ".join(f"{i['s']:.2f} | {i['cpu_s']:.2f} | —" for i in imp)
        + " |"
    )
    for name in names:
        cells = []
        for L in lengths:
            rec = per[L].get(name)
            mem = results[L].get("memory", {}).get("stages", {}).get(name, {}).get("traced_peak_mb")
            cells += [_fmt(rec and rec["s"]), _fmt(rec and rec["cpu_s"]), _fmt(mem, 0)]
        bold = "**" if "total" in name or "all stages" in name else ""
        lines.append(f"| {bold}{name}{bold} | " + " | ".join(cells) + " |")
    lines.append(
        "| peak RSS of the process (MB) | "
        + " | ".join(f"— | — | {results[L]['timing']['maxrss_mb']:.0f}" for L in lengths)
        + " |"
    )
    lines.append("")
    lines.append(
        "wall s / CPU s: timing pass without tracing (CPU = user+system time of the process, "
        "less sensitive to other load on the machine); MB: peak tracemalloc memory of the "
        "stage above its start (memory pass)."
    )
    lines.append("")
    ref = min(lengths, key=lambda L: abs(L - 10.0))
    big = max(lengths)
    lines.append(
        "| stage | "
        + " | ".join(f"{L:g} km CPU s/km" for L in lengths)
        + f" | growth per km {big:g} km / {ref:g} km |"
    )
    lines.append("|---|" + "---:|" * (len(lengths) + 1))
    for name in names:
        cells = []
        per_km = {}
        for L in lengths:
            rec = per[L].get(name)
            per_km[L] = rec["cpu_s"] / results[L]["km"] if rec else None
            cells.append(_fmt(per_km[L], 3))
        growth = None
        if per_km.get(ref) and per_km.get(big) is not None and big != ref:
            growth = per_km[big] / per_km[ref]
        flag = ""
        if growth is not None and growth > 1.3 and per[big][name]["cpu_s"] > 0.5:
            flag = " (worse than linear)"
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {_fmt(growth)}{flag} |")
    return "\n".join(lines)


def osm_table(results: dict[float, dict[str, Any]]) -> str:
    """Markdown: our OSM stage (warm, and cold = first call with the osmnx import) against
    netconvert (best of N runs each)."""
    lines = [
        "| length | OSM file KB | ours warm wall s / CPU s | ours cold wall s / CPU s "
        "| netconvert wall s / CPU s | netconvert peak RSS MB | netconvert / ours warm (CPU) "
        "| netconvert / ours cold (CPU) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for L in sorted(results):
        r = results[L]
        cmp_ = r.get("osm")
        if not cmp_:
            continue
        warm, cold, nc = cmp_["ours"]["warm"], cmp_["ours"]["cold"], cmp_["netconvert"]
        lines.append(
            f"| {L:g} km | {r['osm_kb']:.0f} | {warm['s']:.2f} / {warm['cpu_s']:.2f} | "
            f"{cold['s']:.2f} / {cold['cpu_s']:.2f} | "
            f"{_fmt(nc and nc['s'])} / {_fmt(nc and nc['cpu_s'])} | "
            f"{_fmt(nc and nc['maxrss_mb'], 0)} | "
            f"{_fmt(nc and nc['cpu_s'] / max(warm['cpu_s'], 1e-3), 1)} | "
            f"{_fmt(nc and nc['cpu_s'] / max(cold['cpu_s'], 1e-3), 2)} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--lengths", type=float, nargs="+", default=[1.0, 10.0, 100.0], help="km")
    p.add_argument("--method", choices=("default", "paper"), default="default")
    p.add_argument("--workdir", type=Path, default=None, help="cache of simulated runs")
    p.add_argument("--seed", type=int, default=20)
    p.add_argument(
        "--external-km", type=float, default=10.0, help="run external consumers on this length"
    )
    p.add_argument(
        "--threads",
        type=int,
        default=None,
        help="BLAS/OpenMP threads in the measured processes (default: the libraries' own; "
        "1 gives steadier CPU times on a machine shared with other jobs)",
    )
    p.add_argument("--no-tracemalloc", action="store_true", help="skip the memory pass")
    p.add_argument("--no-netconvert", action="store_true", help="skip the OSM comparison")
    p.add_argument("--osm-repeat", type=int, default=3, help="runs per side in the OSM comparison")
    p.add_argument(
        "--only-osm", action="store_true", help="only the OSM comparison (no stage passes)"
    )
    p.add_argument("--child-osm", type=Path, default=None, help=argparse.SUPPRESS)
    p.add_argument("--json", type=Path, default=None, help="write the raw numbers here")
    p.add_argument("--child", type=Path, default=None, help=argparse.SUPPRESS)
    p.add_argument("--child-out", type=Path, default=None, help=argparse.SUPPRESS)
    p.add_argument("--child-trace", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--child-external", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)

    if args.child_osm is not None:
        child_osm(args.child_osm, args.child_out, repeat=args.osm_repeat)
        return 0
    if args.child is not None:
        child(
            args.child,
            args.child_out,
            method=args.method,
            trace=args.child_trace,
            external=args.child_external,
        )
        return 0

    tmp_ctx = None
    if args.workdir is None:
        tmp_ctx = tempfile.TemporaryDirectory(prefix="roadtwin-bench-")
        workdir = Path(tmp_ctx.name)
    else:
        workdir = args.workdir
        workdir.mkdir(parents=True, exist_ok=True)
    info = machine()
    info["blas_threads"] = str(args.threads or "library default")
    print(f"# roadtwin pipeline benchmark, method={args.method}", flush=True)
    print(", ".join(f"{k}: {v}" for k, v in info.items()), flush=True)
    results: dict[float, dict[str, Any]] = {}
    ext_len = min(args.lengths, key=lambda L: abs(L - args.external_km))
    try:
        for L in args.lengths:
            run_dir, sim_s = ensure_run(workdir, L, args.seed)
            print(
                f"[{L:g} km] run {run_dir} "
                + ("(cached)" if sim_s is None else f"(simulated in {sim_s:.1f} s)"),
                flush=True,
            )
            rec: dict[str, Any] = {
                "km": L,
                "simulate_s": sim_s,
                "osm_kb": (run_dir / "map.osm").stat().st_size / 1e3,
            }
            if not args.only_osm:
                timing = run_child(
                    run_dir,
                    method=args.method,
                    trace=False,
                    external=args.external_km > 0 and ext_len == L,
                    threads=args.threads,
                )
                print(
                    f"[{L:g} km] timing pass: "
                    + ", ".join(f"{k} {v['s']:.2f}" for k, v in timing["stages"].items())
                    + f"; peak RSS {timing['maxrss_mb']:.0f} MB",
                    flush=True,
                )
                rec["km"] = timing["mainline_km"] or L
                rec["timing"] = timing
                if not args.no_tracemalloc:
                    rec["memory"] = run_child(
                        run_dir,
                        method=args.method,
                        trace=True,
                        external=False,
                        threads=args.threads,
                    )
                    print(f"[{L:g} km] memory pass done", flush=True)
            if not args.no_netconvert:
                rec["osm"] = osm_compare(run_dir, repeat=args.osm_repeat, threads=args.threads)
                print(f"[{L:g} km] OSM comparison done", flush=True)
            results[L] = rec
    finally:
        if tmp_ctx is not None:
            tmp_ctx.cleanup()
    print()
    if not args.only_osm:
        print(tables(results))
        print()
    print(osm_table(results))
    timed = {L: r for L, r in results.items() if "timing" in r}
    for L, r in timed.items():
        ext = r["timing"].get("external")
        if ext:
            print(
                f"\nexternal consumers on the {L:g} km map (once): SUMO netconvert "
                f"{ext['sumo_s']:.2f} s ({ext['sumo']}), ASAM qc_opendrive {ext['asam_s']:.2f} s "
                f"({ext['asam']})"
            )
    print()
    for L, r in timed.items():
        t = r["timing"]
        print(
            f"{L:g} km: {t['roads']} roads, {t['junctions']} junctions, {t['ramps']} ramps, "
            f"{t['poses']} poses, xodr {t['xodr_mb']:.2f} MB, own check errors "
            f"{t['check_errors']}, truth RMSE {t.get('truth_rmse_m')}"
        )
    if args.json is not None:
        args.json.write_text(
            json.dumps({"machine": info, "method": args.method, "results": results}, indent=1),
            encoding="utf-8",
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
