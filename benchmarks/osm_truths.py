"""Ground truths from every real OSM extract: build, check and plot two chains each.

Run from the repository root (needs ../shared/data/osm, or pass a folder):

    python benchmarks/osm_truths.py [OSM_DIR] [-o OUT_DIR] [--seed N] [--chains 2] [--no-consumers]

For each extract the longest distinct one-way motorway/trunk chains are turned into a
truth map (:func:`roadtwin.simulate.osm_truth.truth_from_osm`), written as OpenDRIVE,
checked with ``roadtwin check`` (own checks, SUMO netconvert, ASAM qc_opendrive) and
plotted over the OSM ways (``OUT_DIR/<extract>-<chain>.png``, plus a close-up of the
busiest interchange). Prints one table row per chain. OSM data (c) OpenStreetMap
contributors, ODbL.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from roadtwin.check import check_file
from roadtwin.simulate.osm_truth import OsmTruthSettings, truth_from_osm
from roadtwin.simulate.osm_truth.chain import _chain_length, all_chains, read_osm_roads
from roadtwin.simulate.osm_truth.layout import lane_count_at
from roadtwin.xodr import write_xodr

EXTRACTS = (
    "north-bayreuth-a9.osm.gz",
    "west-oakland-i880.osm.bz2",
    "kotka-e18.osm.pbf",
    "krems-s5-trunk.osm.gz",
    "melbourne-lht.osm.pbf",
)


def distinct_chains(path: Path, n: int, min_length_m: float = 600.0) -> list[int]:
    """First way ids of the ``n`` longest chains that share at most half their ways."""
    roads = read_osm_roads(path)
    out: list[list[int]] = []
    for c in all_chains(roads):
        if _chain_length(roads, c) < min_length_m:
            continue
        if any(len(set(c) & set(o)) > 0.5 * min(len(c), len(o)) for o in out):
            continue
        out.append(c)
        if len(out) == n:
            break
    return [c[0] for c in out]


def tag_match(truth, s: np.ndarray) -> float:
    """Share of stations where the full-width through lanes equal the OSM ``lanes`` tag,
    away (300 m) from the stations where the tag changes."""
    seg = np.array(truth.tagged_lanes)
    idx = np.clip(np.searchsorted(seg[:, 0], s, side="right") - 1, 0, len(seg) - 1)
    tagged = seg[idx, 2]
    changes = seg[1:, 0][np.diff(seg[:, 2]) != 0]
    away = (
        np.all(np.abs(s[:, None] - changes[None, :]) > 300.0, axis=1)
        if changes.size
        else np.ones(s.size, bool)
    )
    n = lane_count_at(truth.layout, s, kinds=("through",))
    return float(np.mean(n[away] == tagged[away])) if away.any() else 1.0


def plot_truth(truth, png: Path, *, focus: tuple[float, float, float] | None = None) -> None:
    """Lane borders of the truth over the OSM ways (mapping frame)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from roadtwin.simulate.osm_truth.chain import read_osm_roads as _read

    frame_roads = _read(truth.osm_path)
    from roadtwin.frames import MappingFrame

    frame = MappingFrame(truth.origin, "local")
    fig, ax = plt.subplots(figsize=(11, 11))
    for w in frame_roads.ways.values():
        x, y = frame.from_lonlat(w.lonlat[:, 0], w.lonlat[:, 1])
        ax.plot(x, y, color="0.6", lw=0.8, ls="--", zorder=1)
    colours = {
        "mainline": "tab:blue",
        "exit": "tab:red",
        "entry": "tab:green",
        "connector": "tab:purple",
    }
    for road in truth.network.roads:
        c = colours.get(road.name, "k")
        for k, sec in enumerate(road.lane_sections):
            s1 = road.lane_sections[k + 1].s0 if k + 1 < len(road.lane_sections) else road.length
            s = np.linspace(sec.s0, s1, max(2, int((s1 - sec.s0) / 0.5) + 2))
            lanes = sec.right or sec.left
            for lane in (0, *(x.id for x in lanes)):
                t = road.lane_border_t(s, lane)
                xy = road.to_xy(s, t)
                kind = next((x for x in lanes if x.id == lane), None)
                ls = "-"
                if kind is not None and kind.road_marks and kind.road_marks[0].type == "broken":
                    ls = (0, (4, 4))
                ax.plot(xy[:, 0], xy[:, 1], color=c, lw=0.7, ls=ls, zorder=2)
    if focus is not None:
        x, y, r = focus
        ax.set_xlim(x - r, x + r)
        ax.set_ylim(y - r, y + r)
    ax.set_aspect("equal")
    ax.set_title(
        f"{truth.osm_path.name}: truth lanes (blue mainline, red exits, green entries), OSM grey"
    )
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def busiest(truth) -> tuple[float, float, float] | None:
    """Centre and radius of the stretch with the most ramp gores within 600 m."""
    if not truth.ramps:
        return None
    st = np.array([r.station_m for r in truth.ramps])
    counts = [(np.sum(np.abs(st - s) < 600.0), -s) for s in st]
    s = -max(counts)[1]
    near = st[np.abs(st - s) < 600.0]
    mid = 0.5 * (near.min() + near.max())
    xy = truth.mainline.xy(np.array([mid]))[0]
    return float(xy[0]), float(xy[1]), max(250.0, 0.6 * (near.max() - near.min()) + 200.0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("osm_dir", nargs="?", default="../shared/data/osm")
    ap.add_argument("-o", "--out", default="osm_truths_out")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--chains", type=int, default=2)
    ap.add_argument("--no-consumers", action="store_true")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    cfg = OsmTruthSettings()
    header = (
        f"{'extract':28s} {'chain(way)':>11s} {'km':>6s} {'exit/entry':>10s} {'lanes':>7s} "
        f"{'lane%':>6s} {'weave':>5s} {'xing':>4s} {'Rmin':>6s} {'own':>4s} {'sumo':>4s} "
        f"{'asam':>4s} {'s':>5s}"
    )
    print(header)
    failed = 0
    for name in EXTRACTS:
        path = Path(args.osm_dir) / name
        if not path.is_file():
            print(f"{name}: missing", file=sys.stderr)
            continue
        for way in distinct_chains(path, args.chains):
            t0 = time.perf_counter()
            truth = truth_from_osm(path, chain=way, settings=cfg, seed=args.seed)
            dt = time.perf_counter() - t0
            stem = f"{name.split('.')[0]}-{way}"
            xodr = write_xodr(truth.network, out / f"{stem}.xodr")
            rep = check_file(xodr, external=not args.no_consumers)
            own = sum(f.severity == "error" for f in rep.findings)
            cons = {c.name.split()[0]: c for c in rep.consumers}

            def cerr(key: str, cons=cons) -> str:
                c = cons.get(key)
                return "-" if c is None or c.status not in ("passed", "failed") else str(c.errors)

            s = np.arange(0.0, truth.mainline.length, 5.0)
            n = lane_count_at(truth.layout, s)
            lanes = f"{n.min()}-{n.max()}"
            match = tag_match(truth, s)
            n_exit = sum(r.type == "exit" for r in truth.ramps)
            weave = sum("weaving" in x for x in truth.notes)
            xing = sum(len(r.crossings) for r in truth.ramps)
            rmin = min([r.min_radius_m for r in truth.ramps], default=float("nan"))
            failed += rep.errors
            print(
                f"{name:28s} {way:>11d} {truth.mainline.length / 1000:6.2f} "
                f"{n_exit:>4d}/{len(truth.ramps) - n_exit:<5d} {lanes:>7s} "
                f"{100 * match:6.1f} {weave:>5d} {xing:>4d} {rmin:6.1f} {own:>4d} "
                f"{cerr('sumo'):>4s} {cerr('asam'):>4s} {dt:5.1f}",
                flush=True,
            )
            plot_truth(truth, out / f"{stem}.png")
            focus = busiest(truth)
            if focus is not None:
                plot_truth(truth, out / f"{stem}-interchange.png", focus=focus)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
