"""Generalisation probe: real-layout runs from mapping systems unlike our default one.

roadtwin is judged on runs made by another simulator. ``probe_noise.py`` and the noisier
batches of ``bench_real.py`` change how *much* noise there is; this probe changes what the
mapping system *is*: how far sideways and ahead it sees, how densely it samples, how often
it records a frame, how fast the car drives, and how the run folder is written (edges as
CSV without a ``side`` column, lane samples placed by time instead of frame, a pose point
1.6 m above the road). Each variant is applied to the same routes (OSM chains of five
countries and the three HD maps), built with the default method, checked, evaluated
against the truth and driven, with the columns of ``bench_real.py``.

    python benchmarks/probe_sensor.py [--variants NAME ...] [--only ROUTE ...]
        [--workdir DIR] [--jobs N] [--external] [--drive] [--json FILE]

Variants (``VARIANTS``): ``narrow`` (markings seen 7 m sideways and 20 m ahead, edges
15 m), ``wide`` (20 m sideways, 50 m ahead, edges 40 m), ``sparse`` (edge points every
0.6 m, marking samples every 1.5 m, 5 Hz, 120 km/h), ``dense`` (0.05 m / 0.15 m, 20 Hz,
70 km/h), ``format`` (edges as CSV without ``side``, lane samples by ``t``, pose height
1.6 m), ``drift`` (0.06 m pose drift with a 60 s correlation time, 0.2 deg yaw).

OSM data: (c) OpenStreetMap contributors, ODbL (the extracts in ../shared/data/osm).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_real

_FROM_PROBES = (
    "a9-206615404",
    "kotka-37952515",
    "melbourne-408",
    "town06-auto",
    "soderleden",
    "e6mini",
)
ROUTES: tuple[tuple[str, str, str, int | None], ...] = (
    *(c for c in bench_real._PROBE_CHAINS if c[0] in _FROM_PROBES),
    ("oakland-11197879", "osm", "west-oakland-i880.osm.bz2", 11197879),
    ("krems-46762523", "osm", "krems-s5-trunk.osm.gz", 46762523),
)
"""``(name, source, file, chain)`` of the routes every variant drives."""

VARIANTS: dict[str, dict] = {
    "narrow": {
        "sensor": {"lane_lateral_range_m": 7.0, "lane_range_m": (3.0, 20.0), "edge_range_m": 15.0}
    },
    "wide": {
        "sensor": {"lane_lateral_range_m": 20.0, "lane_range_m": (2.0, 50.0), "edge_range_m": 40.0}
    },
    "sparse": {
        "sensor": {"edge_spacing_m": 0.6, "lane_spacing_m": 1.5},
        "car": {"rate_hz": 5.0, "speed_kmh": 120.0},
    },
    "dense": {
        "sensor": {"edge_spacing_m": 0.05, "lane_spacing_m": 0.15},
        "car": {"rate_hz": 20.0, "speed_kmh": 70.0},
    },
    "format": {"files": {"edges_csv_no_side": True, "lanes_by_time": True, "pose_height_m": 1.6}},
    "drift": {"noise": {"position_std_m": 0.06, "yaw_std_deg": 0.2, "correlation_s": 60.0}},
}
"""What each variant changes: fields of :class:`roadtwin.simulate.Sensor`, ``Car`` and
``Noise``, and ``files`` (how the run folder is written, applied after simulating)."""

SEED = 41
"""One seed for every probe run (no bench_real run uses it)."""


def _settings(variant: dict):
    from roadtwin.simulate import NetworkRunSettings

    base = NetworkRunSettings()
    return replace(
        base,
        sensor=replace(base.sensor, **variant.get("sensor", {})),
        car=replace(base.car, **variant.get("car", {})),
        noise=replace(base.noise, **variant.get("noise", {})),
    )


def _rewrite_files(run_dir: Path, files: dict) -> None:
    """Write the run folder the way another mapping system might (same content)."""
    import laspy
    import numpy as np

    toml = (run_dir / "run.toml").read_text(encoding="utf-8")
    if files.get("edges_csv_no_side"):
        las = laspy.read(run_dir / "road_edges.laz")
        xyz = np.column_stack([las.x, las.y, las.z])
        np.savetxt(run_dir / "edges.csv", xyz, fmt="%.4f", delimiter=",", header="X,Y,Z",
                   comments="")  # fmt: skip
        (run_dir / "road_edges.laz").unlink()
        toml = toml.replace('road_edges = "road_edges.laz"', 'road_edges = "edges.csv"')
    traj = list(csv.DictReader((run_dir / "trajectory.csv").open(encoding="utf-8")))
    height = float(files.get("pose_height_m", 0.0))
    if files.get("lanes_by_time") or height:
        t_of = {row["frame"]: row["t"] for row in traj}
        rows = list(csv.DictReader((run_dir / "lane_samples.csv").open(encoding="utf-8")))
        with (run_dir / "lane_samples.csv").open("w", encoding="utf-8", newline="") as fh:
            key = "t" if files.get("lanes_by_time") else "frame"
            fh.write(f"{key},x,y,z\n")
            for r in rows:
                stamp = t_of[r["frame"]] if key == "t" else r["frame"]
                fh.write(f"{stamp},{r['x']},{r['y']},{float(r['z']) - height:.4f}\n")
    if height:
        with (run_dir / "trajectory.csv").open("w", encoding="utf-8", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(traj[0].keys()))
            writer.writeheader()
            for row in traj:
                writer.writerow({**row, "z": f"{float(row['z']) + height:.6f}"})
        toml = toml.replace("pose_height = 0.0", f"pose_height = {height}")
    (run_dir / "run.toml").write_text(toml, encoding="utf-8")


def one(job: tuple) -> tuple[str, str, list[dict]]:
    """Simulate (once), build, judge one route under one variant (in a worker)."""
    import logging
    import warnings

    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    from roadtwin import simulate as sim

    (name, source, path, chain), vname, workdir, external, drive, osm_dir, xodr_dir = job
    variant = VARIANTS[vname]
    label = f"{name}-{vname}"
    run_dir = Path(workdir) / label / "run"
    if not (run_dir / "run.toml").is_file():
        settings = _settings(variant)
        if source == "xodr":
            sim.simulate_xodr_run(Path(xodr_dir) / path, run_dir, seed=SEED, settings=settings)
        else:
            sim.simulate_osm_run(
                Path(osm_dir) / path, run_dir, chain=chain, seed=SEED, settings=settings
            )
        if "files" in variant:
            _rewrite_files(run_dir, variant["files"])
    row = bench_real.build_and_judge(
        run_dir, Path(workdir) / label / "default", method="default", external=external,
        drive=drive,
    )  # fmt: skip
    return label, vname, [row]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workdir", type=Path, default=Path("/tmp/roadtwin-probe-sensor"))
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--only", nargs="*", default=None, help="route names (prefix match)")
    ap.add_argument("--external", action="store_true", help="also SUMO and the ASAM checker")
    ap.add_argument("--drive", action="store_true", help="drive every route in esmini")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--osm-dir", type=Path, default=bench_real.OSM_DIR)
    ap.add_argument("--xodr-dir", type=Path, default=bench_real.XODR_DIR)
    ap.add_argument("--json", type=Path, default=None, help="write every row as JSON")
    args = ap.parse_args(argv)
    routes = [r for r in ROUTES if not args.only or any(r[0].startswith(p) for p in args.only)]
    work = [
        (route, v, args.workdir, args.external, args.drive, args.osm_dir, args.xodr_dir)
        for v in args.variants
        for route in routes
    ]
    args.workdir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    results = bench_real.run_all(one, work, args.jobs)
    print(bench_real.format_rows(results))
    print()
    for vname in args.variants:
        part = [r for r in results if r[1] == vname]
        print(f"{vname}: " + bench_real.summary(part, "default"))
    print(f"\n{len(work)} runs in {time.perf_counter() - t0:.0f} s (jobs={args.jobs})")
    for label, _, rows in results:
        for r in rows:
            if r.get("trace"):
                print(f"\n--- {label}\n{r['trace']}", file=sys.stderr)
    if args.json:
        clean = [
            {"run": n, "variant": v, "rows": [{k: x for k, x in r.items() if k != "trace"}
                                              for r in rs]}
            for n, v, rs in results
        ]  # fmt: skip
        args.json.write_text(json.dumps(clean, indent=1, default=str) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
