"""The whole-highway benchmark (issue on several runs and OSM roads).

Four parts, every run simulated with ground truth into ``--workdir`` (kept between
invocations; ``--fresh`` re-simulates):

1. **Fusion** -- the bundled ``straight_curve_2km`` driven ``--passes`` times (``roadtwin
   simulate --pass N``: same truth, new noise and occlusions): each pass built alone, every
   pair and all passes fused; lateral RMSE of road edges and lane boundaries against the
   truth, metres of the true median-side edge no pass saw (occlusions), build time.
2. **Both directions** -- a run along each carriageway (bundled ``straight_curve_2km`` and
   the real A9 chain 206615404 of ``north-bayreuth-a9.osm.gz``, ``--direction opposite``):
   per carriageway RMSE, lane count, ramps found / true / spurious, and for the whole map
   ``roadtwin check`` (own, SUMO, ASAM) and the drive of every route.
3. **One run + OSM** -- the forward run alone: the other carriageway from OSM against the
   opposite run's truth (OSM accuracy), its ramps, the roads beyond the ramps.
4. **OSM only vs SUMO netconvert** -- the A9 extract's motorways in a box from OSM alone
   (``roadtwin build --osm --bbox``) and netconvert's OSM to OpenDRIVE of the same box
   (motorways and links): lane-centre accuracy against the true carriageways of both
   directions (:mod:`roadtwin.highway.compare`), check errors, drive, wall time.

Run::

    python benchmarks/bench_highway.py [--workdir DIR] [--passes 4] [--fresh]
        [--parts fusion both one osm] [--json FILE]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

A9 = Path("/work/shared/data/osm/north-bayreuth-a9.osm.gz")
A9_CHAIN = 206615404
A9_BOX = (11.47, 50.02, 11.61, 50.045)
SCENARIO = "straight_curve_2km"
SEEDS = (1, 2, 3)  # truths of the A9 for the OSM-only comparison (OSM drawn off differently)


def _f(v, d: int = 3) -> str:
    return "-" if v is None else f"{v:.{d}f}"


def simulate_all(workdir: Path, passes: int, fresh: bool) -> dict[str, Path]:
    from roadtwin.simulate import simulate_osm_run, simulate_run
    from roadtwin.simulate.opposite import simulate_opposite_run

    todo = {f"sc-pass{k}": lambda p, k=k: simulate_run(SCENARIO, p, pass_index=k) for k in
            range(1, passes + 1)}  # fmt: skip
    todo["sc-opposite"] = lambda p: simulate_opposite_run(SCENARIO, p)
    for seed in SEEDS:
        tag = "" if seed == 1 else f"-s{seed}"
        todo[f"a9-forward{tag}"] = lambda p, seed=seed: simulate_osm_run(
            A9, p, chain=A9_CHAIN, seed=seed
        )
        todo[f"a9-opposite{tag}"] = lambda p, seed=seed: simulate_osm_run(
            A9, p, chain=A9_CHAIN, seed=seed, direction="opposite"
        )
    out = {}
    for name, fn in todo.items():
        path = workdir / name
        if fresh and path.exists():
            shutil.rmtree(path)
        if not (path / "truth.xodr").exists():
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fn(path)
        out[name] = path
    return out


def _load(paths):
    from roadtwin.highway import run_in_frame
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        runs = [load_run(p) for p in paths]
        frame = runs[0].frame
        runs = [run_in_frame(r, frame) for r in runs]  # once; build_highway finds them there
        around = np.vstack([r.trajectory.xy for r in runs])
        graph = load_osm(runs[0].osm_path, frame=frame, around_xy=around)
    return runs, graph


def _truth_rmse(network, run, truth_dir: Path) -> dict:
    from roadtwin.evaluation import evaluate
    from roadtwin.xodr import read_xodr

    rep = evaluate(network, run, truth=read_xodr(truth_dir / "truth.xodr")).runs[0]
    t = rep.truth
    return {
        "edge": t["road_edge"]["rmse_m"],
        "lane": t["lane_boundary"]["rmse_m"],
        "lane_count": t["lane_count"]["matched_fraction"],
    }


def _unseen_m(run, truth_dir: Path) -> int:
    """Metres of the true median-side edge without an edge point of ``run`` within 1 m."""
    from scipy.spatial import cKDTree

    from roadtwin.xodr import read_xodr

    truth = read_xodr(truth_dir / "truth.xodr")
    pts = []
    for r in truth.roads:
        if r.name == "mainline":
            s = np.arange(0.0, r.length, 1.0)
            pts.append(r.to_xy(s, r.lane_border_t(s, 0)))
    d, _ = cKDTree(run.edges[:, :2]).query(np.vstack(pts))
    return int(np.count_nonzero(d > 1.0))


# ---------------------------------------------------------------------------
# 1. fusion
# ---------------------------------------------------------------------------


def fusion(paths: dict[str, Path], passes: int) -> list[dict]:
    from roadtwin.highway import fuse_runs
    from roadtwin.pipeline import build_map

    names = [f"sc-pass{k}" for k in range(1, passes + 1)]
    runs, graph = _load([paths[n] for n in names])
    truth_dir = paths["sc-pass1"]
    rows = []
    combos = [(i,) for i in range(passes)]
    combos += list(itertools.combinations(range(passes), 2))
    if passes > 2:
        combos.append(tuple(range(passes)))
    for combo in combos:
        t0 = time.perf_counter()
        fused = fuse_runs([runs[i] for i in combo])
        res = build_map(fused.run, graph)
        dt = time.perf_counter() - t0
        row = {"passes": "+".join(str(i + 1) for i in combo), "build_s": dt}
        row |= _truth_rmse(res.network, fused.run, truth_dir)
        row["unseen_m"] = _unseen_m(fused.run, truth_dir)
        row["disagreements"] = len(fused.disagreements)
        rows.append(row)
    return rows


def print_fusion(rows: list[dict]) -> None:
    single = {r["passes"]: r for r in rows if "+" not in r["passes"]}
    print("| passes | edge RMSE m | lane boundary RMSE m | lane count | median-side edge unseen m "
          "| disagreements | beats every pass in it (edge / lane) | build s |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        parts = r["passes"].split("+")
        beats = "-"
        if len(parts) > 1:
            e = all(r["edge"] < single[p]["edge"] for p in parts)
            lane = all(r["lane"] < single[p]["lane"] for p in parts)
            beats = f"{'yes' if e else 'no'} / {'yes' if lane else 'no'}"
        print(
            f"| {r['passes']} | {_f(r['edge'])} | {_f(r['lane'])} | {_f(r['lane_count'])} | "
            f"{r['unseen_m']} | {r['disagreements']} | {beats} | {r['build_s']:.1f} |"
        )
    pairs = [r for r in rows if r["passes"].count("+") == 1]
    if pairs:
        mean_single_e = np.mean([r["edge"] for r in single.values()])
        mean_single_l = np.mean([r["lane"] for r in single.values()])
        print(
            f"\nmean over single passes: edge {mean_single_e:.4f} m, lane boundary "
            f"{mean_single_l:.4f} m; over pairs: edge "
            f"{np.mean([r['edge'] for r in pairs]):.4f} m, lane boundary "
            f"{np.mean([r['lane'] for r in pairs]):.4f} m"
        )


# ---------------------------------------------------------------------------
# 2./3. highway builds, check, drive
# ---------------------------------------------------------------------------


def _check_and_drive(network, out: Path, *, source: Path | None = None) -> dict:
    """``roadtwin check`` (own, SUMO, ASAM) and the drive of a map: ours written from
    ``network``, another tool's from its own file ``source`` (driven as a copy without its
    header ``<offset>``: esmini reports positions with the offset added, the drive's judge
    compares them with the map's own coordinates)."""
    from lxml import etree

    from roadtwin.check import check_file
    from roadtwin.drive import drive_map, find_esmini
    from roadtwin.xodr import write_xodr

    out.mkdir(parents=True, exist_ok=True)
    if source is None:
        path = drive_path = write_xodr(network, out / "map.xodr")
    else:
        path = out / source.name
        shutil.copy(source, path)
        tree = etree.parse(str(path))
        for el in tree.getroot().findall("header/offset"):
            el.getparent().remove(el)
        drive_path = out / f"no-offset-{source.name}"
        tree.write(str(drive_path))
    rep = check_file(path, external=True)
    row = {
        "own_errors": sum(f.severity == "error" for f in rep.findings),
        "consumers": {c.name: (c.status, c.errors, c.warnings) for c in rep.consumers},
    }
    esmini = find_esmini(None)
    if esmini is not None:
        d = drive_map(drive_path, out / "drive", esmini=esmini)
        row["drive"] = f"{d.count('passed')}/{len(d.results)}"
        row["esmini_warnings"] = len(d.warnings)
    return row


def highway_case(name: str, run_paths: list[Path], truths: dict[int, Path], out: Path) -> dict:
    from roadtwin.highway import build_highway
    from roadtwin.highway.evaluate import evaluate_carriageway
    from roadtwin.io import load_run
    from roadtwin.xodr import read_xodr

    runs, graph = _load(run_paths)
    t0 = time.perf_counter()
    res = build_highway(runs, graph)
    dt = time.perf_counter() - t0
    row: dict = {"case": name, "build_s": dt, "summary": res.summary(), "carriageways": []}
    for cw in res.carriageways:
        entry: dict = {"number": cw.number, "source": cw.source}
        truth_dir = truths.get(cw.number)
        if truth_dir is not None:
            info = json.loads((truth_dir / "truth.json").read_text())
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = evaluate_carriageway(
                    res.network, cw.number, load_run(truth_dir),
                    read_xodr(truth_dir / "truth.xodr"), truth_info=info,
                )  # fmt: skip
            t, tp = r["truth"], r["topology"]
            entry |= {
                "edge": t["road_edge"]["rmse_m"],
                "lane": t["lane_boundary"]["rmse_m"],
                "edge_p95": t["road_edge"]["p95_m"],
                "covered": t["covered_fraction"],
                "lane_count": t["lane_count"]["matched_fraction"],
                "ramps": f"{tp['matched']}/{tp['true_ramps']}",
                "spurious": len(tp["spurious"]),
                "connected": f"{tp['connected']}/{tp['built_ramps']}",
            }
        entry["built_ramps"] = len(cw.topology.ramps)
        row["carriageways"].append(entry)
    row["beyond"] = len(res.beyond)
    row |= _check_and_drive(res.network, out)
    return row


def _consumer(cons: dict, name: str) -> str:
    got = next((v for k, v in cons.items() if name in k.lower()), None)
    return "-" if got is None else f"{got[0]} ({got[1]} errors, {got[2]} warnings)"


def print_cases(rows: list[dict]) -> None:
    print("| case | carriageway | source | edge RMSE m | lane RMSE m | edge p95 m | covered "
          "| lane count | ramps found/true | spurious | connected |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        for c in r["carriageways"]:
            print(
                f"| {r['case']} | {c['number']} | {c['source']} | {_f(c.get('edge'))} | "
                f"{_f(c.get('lane'))} | {_f(c.get('edge_p95'))} | {_f(c.get('covered'), 2)} | "
                f"{_f(c.get('lane_count'), 3)} | {c.get('ramps', '-')} | "
                f"{c.get('spurious', '-')} | {c.get('connected', '-')} |"
            )
    print("\n| case | roads | ramps | roads beyond ramps | own check errors | SUMO | ASAM | drive "
          "| build s |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        s = r["summary"]
        print(
            f"| {r['case']} | {s['roads']} | {s['exits'] + s['entries']} | {r['beyond']} | "
            f"{r['own_errors']} | {_consumer(r['consumers'], 'sumo')} | "
            f"{_consumer(r['consumers'], 'asam')} | {r.get('drive', '-')} | {r['build_s']:.1f} |"
        )


# ---------------------------------------------------------------------------
# 4. OSM only vs netconvert
# ---------------------------------------------------------------------------


def osm_only_vs_netconvert(paths: dict[str, Path], workdir: Path) -> list[dict]:
    from pyproj import Transformer

    from roadtwin.highway import build_osm_only
    from roadtwin.highway.area import OsmArea, load_area_graph
    from roadtwin.highway.compare import (
        carriageway_edges,
        compare_edges,
        compare_lane_centres,
        lane_centres,
    )
    from roadtwin.io import load_run
    from roadtwin.xodr import read_xodr

    frame = load_run(paths["a9-forward"]).frame  # every A9 truth is in this frame
    truths = {}
    for seed in SEEDS:
        tag = "" if seed == 1 else f"-s{seed}"
        for k, d in enumerate(("forward", "opposite"), start=1):
            net = read_xodr(paths[f"a9-{d}{tag}"] / "truth.xodr")
            keep = lambda r: r.name == "mainline"  # noqa: E731
            truths[(seed, k)] = (
                lane_centres(net, keep=keep),
                carriageway_edges(net, keep=keep),
            )

    def judge(tool: str, network, wall_s: float, transform=None) -> dict:
        centres = lane_centres(network, transform=transform)
        edges = carriageway_edges(network, transform=transform)
        row: dict = {"tool": tool, "wall_s": wall_s, "per_truth": {}}
        for key, (t_c, t_e) in truths.items():
            row["per_truth"][f"seed {key[0]} dir {key[1]}"] = {
                "centres": compare_lane_centres(centres, t_c),
                "edges": compare_edges(edges, t_e),
            }
        return row

    rows = []
    # ours: the same box, in the truths' frame (the CLI would use a frame on the box)
    t0 = time.perf_counter()
    area = OsmArea(A9, frame, "right", A9_BOX, "a9")
    res = build_osm_only(load_area_graph(area), frame, box_xy=area.box_xy)
    row = judge("roadtwin OSM-only", res.network, time.perf_counter() - t0)
    rows.append(row | _check_and_drive(res.network, workdir / "osm-only"))

    # netconvert: motorways and links of the box, its UTM frame moved into the truths'
    exe = shutil.which("netconvert") or str(Path(sys.executable).with_name("netconvert"))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "nc.xodr"
        t0 = time.perf_counter()
        subprocess.run(
            [exe, "--osm-files", str(A9), "--keep-edges.in-geo-boundary",
             ",".join(str(v) for v in A9_BOX), "--keep-edges.by-type",
             "highway.motorway,highway.motorway_link,highway.trunk,highway.trunk_link",
             "--opendrive-output", str(out)],
            check=True, capture_output=True,
        )  # fmt: skip
        dt = time.perf_counter() - t0
        shutil.copy(out, workdir / "netconvert.xodr")
    net = read_xodr(workdir / "netconvert.xodr")
    ox, oy = net.header.offset[:2] if net.header.offset else (0.0, 0.0)
    to_truth = Transformer.from_crs(net.header.geo_reference, frame.geo_reference, always_xy=True)

    def move(xy):
        x, y = to_truth.transform(xy[:, 0] + ox, xy[:, 1] + oy)
        return np.column_stack([x, y])

    row = judge("SUMO netconvert", net, dt, transform=move)
    rows.append(
        row | _check_and_drive(net, workdir / "netconvert", source=workdir / "netconvert.xodr")
    )
    return rows


def print_osm(rows: list[dict]) -> None:
    print("| tool | truth | lane-centre RMSE m | p95 m | lane count right | edge RMSE m "
          "| edge p95 m |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        for key, m in r["per_truth"].items():
            c, e = m["centres"], m["edges"]
            print(
                f"| {r['tool']} | {key} | {_f(c['rmse_m'])} | {_f(c['p95_m'])} | "
                f"{_f(c['lane_count_right'], 3)} | {_f(e['rmse_m'])} | {_f(e['p95_m'])} |"
            )
    print("\n| tool | pooled lane-centre RMSE m | mean lane count right | pooled edge RMSE m "
          "| own check errors | SUMO | ASAM | drive | wall s |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        per = list(r["per_truth"].values())
        w = np.array([m["centres"]["true_points"] for m in per], dtype=float)
        c = np.array([m["centres"]["rmse_m"] for m in per], dtype=float)
        e = np.array([m["edges"]["rmse_m"] for m in per], dtype=float)
        n = np.mean([m["centres"]["lane_count_right"] for m in per])
        print(
            f"| {r['tool']} | {np.sqrt(np.sum(w * c * c) / w.sum()):.3f} | {n:.3f} | "
            f"{np.sqrt(np.mean(e * e)):.3f} | {r['own_errors']} | "
            f"{_consumer(r['consumers'], 'sumo')} | {_consumer(r['consumers'], 'asam')} | "
            f"{r.get('drive', '-')} | {r['wall_s']:.2f} |"
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workdir", type=Path, default=Path("/tmp/roadtwin-bench-highway"))
    ap.add_argument("--passes", type=int, default=4)
    ap.add_argument("--fresh", action="store_true")
    ap.add_argument("--parts", nargs="+", default=["fusion", "both", "one", "osm"])
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    args.workdir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    paths = simulate_all(args.workdir, args.passes, args.fresh)
    print(f"simulated {len(paths)} runs in {time.perf_counter() - t0:.0f} s\n")
    doc: dict = {}
    if "fusion" in args.parts:
        doc["fusion"] = fusion(paths, args.passes)
        print("## Fusion of passes\n")
        print_fusion(doc["fusion"])
        print()
    cases = []
    w = args.workdir
    if "both" in args.parts:
        sc = {1: paths["sc-pass1"], 2: paths["sc-opposite"]}
        a9 = {1: paths["a9-forward"], 2: paths["a9-opposite"]}
        cases.append(highway_case("bundled, a run each way", list(sc.values()), sc, w / "b-sc"))
        cases.append(highway_case("A9, a run each way", list(a9.values()), a9, w / "b-a9"))
    if "one" in args.parts:
        sc = {1: paths["sc-pass1"], 2: paths["sc-opposite"]}
        a9 = {1: paths["a9-forward"], 2: paths["a9-opposite"]}
        cases.append(highway_case("bundled, one run + OSM", [sc[1]], sc, w / "o-sc"))
        cases.append(highway_case("A9, one run + OSM", [a9[1]], a9, w / "o-a9"))
    if cases:
        doc["cases"] = cases
        print("## Both carriageways\n")
        print_cases(cases)
        print()
    if "osm" in args.parts:
        doc["osm_only"] = osm_only_vs_netconvert(paths, args.workdir)
        print("## OSM only vs SUMO netconvert (A9 extract, box "
              f"{','.join(str(v) for v in A9_BOX)})\n")  # fmt: skip
        print_osm(doc["osm_only"])
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")
    if args.json:
        args.json.write_text(json.dumps(doc, indent=1, default=str) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
