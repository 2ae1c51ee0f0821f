"""Mainline reconstruction benchmark: accuracy against simulator truth and per-stage timing.

Usage::

    python benchmarks/bench_mainline.py                       # the bundled scenarios
    python benchmarks/bench_mainline.py --scenarios long_20km --methods default
    python benchmarks/bench_mainline.py --runs DIR1 DIR2      # already simulated run folders

For every run and method it builds the mainline, then measures, every 1 m along the TRUE
mainline roads (``name="mainline"`` in ``truth.xodr``): the lateral distance of the
reconstructed reference edge, outer edge and lane markings (same lane index where the lane
counts agree, else the nearest marking), the elevation error, the fraction of stations
whose lane count matches, the largest gap/kink between consecutive geometry pieces, the
paper's self-consistency RMSE and the stage timings.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.evaluation.mainline_truth import compare_mainline_road, geometry_continuity, rmse
from roadtwin.io import load_run
from roadtwin.mainline import build_mainline
from roadtwin.model import Road
from roadtwin.xodr import read_xodr

SCENARIOS = ("straight_curve_2km", "interchange_5km", "left_hand_2km", "long_20km")


def compare_to_truth(built: Road, truth_network, *, trim_m: float = 20.0):
    """Errors against every truth mainline road (the run's first/last ``trim_m`` skipped)."""
    roads = [r for r in truth_network.roads if r.name == "mainline"]
    roads.sort(key=lambda r: int(r.id) if r.id.isdigit() else 0)
    parts: dict[str, list] = {}
    for i, r in enumerate(roads):
        lo = trim_m if i == 0 else 0.0
        hi = r.length - trim_m if i == len(roads) - 1 else r.length
        res = compare_mainline_road(built, r, s_lo=lo, s_hi=hi)
        if res is None:
            continue
        for k, v in res.items():
            parts.setdefault(k, []).append(v)
    return {k: np.concatenate(v) for k, v in parts.items()}


def bench_run(run_dir: Path, method: str) -> dict:
    run = load_run(run_dir)
    t0 = time.perf_counter()
    ml = build_mainline(run, config=MainlineConfig(method=method))
    total = time.perf_counter() - t0
    truth = read_xodr(run_dir / "truth.xodr")
    res = compare_to_truth(ml.road, truth)
    gap, kink = geometry_continuity(ml.road)
    return {
        "run": run_dir.name,
        "method": method,
        "km": ml.road.length / 1000.0,
        "edge_rmse": rmse(np.concatenate([res["ref_edge"], res["outer_edge"]])),
        "ref_rmse": rmse(res["ref_edge"]),
        "outer_rmse": rmse(res["outer_edge"]),
        "outer_p95": float(np.percentile(np.abs(res["outer_edge"]), 95)),
        "sections_ok": f"{int(res['section_count'].sum())}/{res['section_count'].size}",
        "lane_rmse": rmse(res["lane_boundary"]),
        "lane_p95": float(np.percentile(np.abs(res["lane_boundary"]), 95)),
        "elev_rmse": rmse(res["elevation"]),
        "lane_count_ok": float(np.mean(res["lane_count"])),
        "sections": len(ml.road.lane_sections),
        "pieces": len(ml.road.geometry),
        "gap_mm": gap * 1000.0,
        "kink_deg": kink,
        "sc_edge": ml.residuals["road_edge"],
        "sc_lane": ml.residuals["lane_boundary"],
        "sc_overall": ml.residuals["overall"],
        "events": len(ml.lane_events),
        "time_s": total,
        "timings": ml.timings_s,
    }


COLUMNS = (
    ("run", "{}"),
    ("method", "{}"),
    ("km", "{:.1f}"),
    ("ref_rmse", "{:.3f}"),
    ("outer_rmse", "{:.3f}"),
    ("outer_p95", "{:.3f}"),
    ("lane_rmse", "{:.3f}"),
    ("lane_p95", "{:.3f}"),
    ("elev_rmse", "{:.3f}"),
    ("lane_count_ok", "{:.3f}"),
    ("sections_ok", "{}"),
    ("sections", "{}"),
    ("pieces", "{}"),
    ("gap_mm", "{:.2g}"),
    ("kink_deg", "{:.2g}"),
    ("sc_edge", "{:.3f}"),
    ("sc_lane", "{:.3f}"),
    ("sc_overall", "{:.3f}"),
    ("time_s", "{:.2f}"),
)


def markdown_table(rows: list[dict]) -> str:
    head = "| " + " | ".join(c for c, _ in COLUMNS) + " |"
    sep = "|" + "|".join("---" for _ in COLUMNS) + "|"
    body = ["| " + " | ".join(f.format(r[c]) for c, f in COLUMNS) + " |" for r in rows]
    return "\n".join([head, sep, *body])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", nargs="*", default=list(SCENARIOS))
    ap.add_argument("--runs", nargs="*", type=Path, default=None)
    ap.add_argument("--methods", nargs="*", default=["default", "paper"])
    ap.add_argument("--workdir", type=Path, default=None)
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = args.workdir or Path(tmp)
        runs = list(args.runs or [])
        if not runs:
            from roadtwin.simulate import simulate_run

            for name in args.scenarios:
                out = work / name
                if not (out / "run.toml").exists():
                    simulate_run(name, out)
                runs.append(out)
        for run_dir in runs:
            for method in args.methods:
                r = bench_run(run_dir, method)
                rows.append(r)
                stages = ", ".join(f"{k} {v:.2f}" for k, v in r["timings"].items())
                print(f"{r['run']} {method}: {stages}", file=sys.stderr)
    print(markdown_table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
