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
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.io import load_run
from roadtwin.mainline import build_mainline
from roadtwin.model import Road
from roadtwin.xodr import read_xodr

SCENARIOS = ("straight_curve_2km", "interchange_5km", "left_hand_2km", "long_20km")


def _side(sec):
    return sec.right or sec.left


def borders(road: Road, s: np.ndarray):
    """Reference-edge t, outer-edge t, lane-marking t matrix (K, N) and lane count."""
    sec_idx = road.section_index(s)
    kmax = max(len(_side(sec)) for sec in road.lane_sections)
    marks = np.full((kmax, s.size), np.nan)
    outer = np.full(s.size, np.nan)
    count = np.zeros(s.size, int)
    for k in np.unique(sec_idx):
        sec = road.lane_sections[int(k)]
        sel = sec_idx == k
        ids = [ln.id for ln in _side(sec)]
        count[sel] = len(ids)
        outer[sel] = road.lane_border_t(s[sel], ids[-1])
        for j, lid in enumerate(ids[:-1]):
            marks[j, sel] = road.lane_border_t(s[sel], lid)
    return road.lane_border_t(s, 0), outer, marks, count


def compare_road(built: Road, truth: Road, *, step_m: float = 1.0, s_lo=0.0, s_hi=None):
    """Errors (metres) of ``built`` against one truth road, sampled every ``step_m``."""
    s_hi = truth.length if s_hi is None else s_hi
    s_t = np.arange(s_lo + 0.5 * step_m, s_hi, step_m)  # off section boundaries
    if s_t.size == 0:
        return None
    ref_t, out_t, marks_t, count_t = borders(truth, s_t)
    out = {}
    pts_ref = truth.to_xy(s_t, ref_t)
    s_b, t_b = built.project(pts_ref)
    out["ref_edge"] = t_b - borders(built, s_b)[0]
    count_b = borders(built, s_b)[3]
    out["lane_count"] = (count_b == count_t).astype(float)
    z_true = truth.height(s_t)
    out["elevation"] = built.height(s_b) - z_true
    pts_out = truth.to_xy(s_t, out_t)
    s_b, t_b = built.project(pts_out)
    out["outer_edge"] = t_b - borders(built, s_b)[1]
    errs = []
    for j in range(marks_t.shape[0]):
        ok = np.isfinite(marks_t[j])
        if not np.any(ok):
            continue
        pts = truth.to_xy(s_t[ok], marks_t[j, ok])
        s_b, t_b = built.project(pts)
        _, _, marks_b, cnt_b = borders(built, s_b)
        same = cnt_b == count_t[ok]
        by_index = marks_b[j] if j < marks_b.shape[0] else np.full(s_b.size, np.nan)
        nearest = np.nanmin(np.abs(marks_b - t_b[None, :]), axis=0)
        errs.append(np.where(same & np.isfinite(by_index), np.abs(t_b - by_index), nearest))
    out["lane_boundary"] = np.concatenate(errs) if errs else np.zeros(0)
    # lane count at the middle of every true lane section (longer than 20 m)
    mids = []
    for k, sec in enumerate(truth.lane_sections):
        hi = truth.lane_sections[k + 1].s0 if k + 1 < len(truth.lane_sections) else truth.length
        if hi - sec.s0 > 20.0 and s_lo <= 0.5 * (sec.s0 + hi) <= s_hi:
            mids.append(0.5 * (sec.s0 + hi))
    if mids:
        s_m = np.asarray(mids)
        s_b, _ = built.project(truth.to_xy(s_m, borders(truth, s_m)[0]))
        out["section_count"] = (borders(built, s_b)[3] == borders(truth, s_m)[3]).astype(float)
    else:
        out["section_count"] = np.zeros(0)
    return out


def compare_to_truth(built: Road, truth_network, *, trim_m: float = 20.0):
    """Errors against every truth mainline road (the run's first/last ``trim_m`` skipped)."""
    roads = [r for r in truth_network.roads if r.name == "mainline"]
    roads.sort(key=lambda r: int(r.id) if r.id.isdigit() else 0)
    parts: dict[str, list] = {}
    for i, r in enumerate(roads):
        lo = trim_m if i == 0 else 0.0
        hi = r.length - trim_m if i == len(roads) - 1 else r.length
        res = compare_road(built, r, s_lo=lo, s_hi=hi)
        if res is None:
            continue
        for k, v in res.items():
            parts.setdefault(k, []).append(v)
    return {k: np.concatenate(v) for k, v in parts.items()}


def continuity(road: Road) -> tuple[float, float]:
    """Largest position gap (m) and heading kink (deg) between consecutive pieces."""
    gap, kink = 0.0, 0.0
    for a, b in zip(road.geometry[:-1], road.geometry[1:], strict=True):
        x, y, h = a.end_pose()
        gap = max(gap, math.hypot(x - b.x0, y - b.y0))
        dh = (h - b.hdg + math.pi) % (2 * math.pi) - math.pi
        kink = max(kink, abs(math.degrees(dh)))
    return gap, kink


def rmse(e) -> float:
    e = np.asarray(e, float)
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e * e))) if e.size else math.nan


def bench_run(run_dir: Path, method: str) -> dict:
    run = load_run(run_dir)
    t0 = time.perf_counter()
    ml = build_mainline(run, config=MainlineConfig(method=method))
    total = time.perf_counter() - t0
    truth = read_xodr(run_dir / "truth.xodr")
    res = compare_to_truth(ml.road, truth)
    gap, kink = continuity(ml.road)
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
