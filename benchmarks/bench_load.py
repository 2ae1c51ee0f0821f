"""Loading benchmark: a 1 M edge-point run (LAZ and CSV) and OSM cropping vs SUMO netconvert.

Run: ``python benchmarks/bench_load.py [--points 1000000] [--osm FILE]``. Prints a table:
time and peak traced memory (tracemalloc: Python + NumPy allocations) of ``load_run``, and
the time of ``load_osm`` around a 5 km motorway stretch of the whole A9 extract against
``netconvert`` converting the same whole extract to OpenDRIVE, with the ratio.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd

from roadtwin.io import load_run

A9 = Path("/work/shared/data/osm/north-bayreuth-a9.osm.gz")


def write_big_run(root: Path, n_points: int, fmt: str) -> None:
    """A 10 km run (4000 poses) with ``n_points`` road-edge points on two edges."""
    root.mkdir(parents=True, exist_ok=True)
    n_frames = 4000
    s = np.linspace(0.0, 10_000.0, n_frames)
    radius = 3000.0
    yaw = s / radius
    x, y = radius * np.sin(yaw), radius * (1.0 - np.cos(yaw))
    pd.DataFrame(
        {"frame": np.arange(n_frames), "t": s / 25.0, "x": x, "y": y, "z": 0.0, "yaw": yaw}
    ).to_csv(root / "trajectory.csv", index=False)
    se = np.linspace(0.0, 10_000.0, n_points // 2)
    ye = se / radius
    pts = []
    for off in (1.0, -11.0):
        pts.append(
            np.c_[(radius - off) * np.sin(ye), radius - (radius - off) * np.cos(ye), 0.01 * se]
        )
    edges = np.vstack(pts)
    side = np.repeat([1, 2], n_points // 2).astype(np.uint8)
    if fmt == "laz":
        import laspy

        header = laspy.LasHeader(point_format=3, version="1.4")
        header.offsets = edges.min(axis=0)
        header.scales = np.array([1e-3, 1e-3, 1e-3])
        header.add_extra_dim(laspy.ExtraBytesParams(name="side", type=np.uint8))
        las = laspy.LasData(header)
        las.x, las.y, las.z = edges.T
        las.side = side
        las.write(root / "road_edges.laz")
    else:
        pd.DataFrame({"x": edges[:, 0], "y": edges[:, 1], "z": edges[:, 2], "side": side}).to_csv(
            root / "road_edges.csv", index=False, float_format="%.4f"
        )
    ex = np.tile([5.0, 10.0], 3)
    ey = np.repeat([-0.5, -4.0, -7.5], 2)
    frames = np.repeat(np.arange(n_frames), ex.size)
    pd.DataFrame({"frame": frames, "x": np.tile(ex, n_frames), "y": np.tile(ey, n_frames)}).to_csv(
        root / "lane_samples.csv", index=False
    )
    (root / "run.toml").write_text(
        "[origin]\nlat = 49.97\nlon = 11.6\nalt = 400.0\n[files]\n"
        'trajectory = "trajectory.csv"\n'
        f'road_edges = "road_edges.{fmt}"\nlane_samples = "lane_samples.csv"\n'
    )


def bench_run(root: Path) -> tuple[float, float, int]:
    """(seconds, peak MiB traced, edge points) of load_run; best of 2 for time."""
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        run = load_run(root)
        times.append(time.perf_counter() - t0)
    tracemalloc.start()
    load_run(root)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return min(times), peak / 2**20, run.edges.shape[0]


def a9_trajectory(osm: Path, length_m: float = 5000.0):
    """A ``length_m`` stretch along the motorway (A 9 / A 70) of the extract, local frame."""
    import osmium

    from roadtwin.frames import MappingFrame, Origin
    from roadtwin.osm import load_osm

    lons, lats = [], []
    for obj in osmium.FileProcessor(str(osm), osmium.osm.NODE):
        lons.append(obj.location.lon)
        lats.append(obj.location.lat)
    frame = MappingFrame(Origin(float(np.mean(lats)), float(np.mean(lons)), 0.0))
    graph = load_osm(osm, frame=frame, around_xy=None)

    def on_a9(d: dict) -> bool:  # the extract's motorways: A 9 and A 70
        return d.get("highway") == "motorway"

    best = None
    for u, v, d in graph.edges(data=True):
        if not on_a9(d):
            continue
        pts, total, node, seen = [np.asarray(d["geometry"].coords)], d["length"], v, {u}
        while total < length_m and node not in seen:
            seen.add(node)
            nxt = [(w, e) for _, w, e in graph.out_edges(node, data=True) if on_a9(e)]
            if not nxt:
                break
            node, e = nxt[0]
            pts.append(np.asarray(e["geometry"].coords)[1:])
            total += e["length"]
        if best is None or total > best[0]:
            best = (total, np.vstack(pts))
        if total >= length_m:
            break
    total, xy = best
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]
    grid = np.arange(0.0, min(length_m, s[-1]), 2.5)
    return frame, np.c_[np.interp(grid, s, xy[:, 0]), np.interp(grid, s, xy[:, 1])]


def bench_osm(osm: Path) -> dict[str, float]:
    from roadtwin.osm import load_osm

    frame, traj = a9_trajectory(osm)
    t0 = time.perf_counter()
    graph = load_osm(osm, frame=frame, around_xy=traj)
    warm = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        np.save(Path(tmp) / "traj.npy", traj)
        code = (
            "import numpy as np, sys;"
            "from roadtwin.frames import MappingFrame, Origin;"
            "from roadtwin.osm import load_osm;"
            f"f = MappingFrame(Origin({frame.origin.lat_deg!r}, {frame.origin.lon_deg!r}, 0.0));"
            f"load_osm({str(osm)!r}, frame=f, around_xy=np.load({str(Path(tmp) / 'traj.npy')!r}))"
        )
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        cold = time.perf_counter() - t0
        netconvert = shutil.which("netconvert") or str(Path(sys.executable).parent / "netconvert")
        t0 = time.perf_counter()
        subprocess.run(
            [netconvert, "--osm-files", str(osm), "--opendrive-output", str(Path(tmp) / "a9.xodr")],
            check=True,
            capture_output=True,
        )
        sumo = time.perf_counter() - t0
    length = float(np.sum(np.hypot(*np.diff(traj, axis=0).T)))
    return {
        "traj_km": length / 1000.0,
        "warm": warm,
        "cold": cold,
        "netconvert": sumo,
        "edges": graph.number_of_edges(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--osm", type=Path, default=A9)
    args = parser.parse_args()
    print(f"{'case':<44} {'time s':>8} {'peak MiB':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        for fmt in ("laz", "csv"):
            root = Path(tmp) / fmt
            write_big_run(root, args.points, fmt)
            secs, peak, n = bench_run(root)
            print(f"{f'load_run, {n:,} edge points, {fmt.upper()}':<44} {secs:8.2f} {peak:9.0f}")
    if args.osm.is_file():
        r = bench_osm(args.osm)
        name = args.osm.name
        label = f"load_osm {name} around {r['traj_km']:.1f} km"
        print(f"{label:<44} {r['warm']:8.2f}")
        print(f"{'load_osm, new process incl. imports':<44} {r['cold']:8.2f}")
        print(f"{'netconvert whole extract -> OpenDRIVE':<44} {r['netconvert']:8.2f}")
        print(
            f"ratio netconvert / load_osm: {r['netconvert'] / r['warm']:.1f}x in-process, "
            f"{r['netconvert'] / r['cold']:.1f}x with process start and imports "
            f"({r['edges']} edges kept)"
        )


if __name__ == "__main__":
    main()
