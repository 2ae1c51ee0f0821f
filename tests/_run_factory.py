"""Write small but real mapping runs (DESIGN.md section 3) for the IO and inspect tests.

The geometry is analytic so tests can compare loaded arrays with the truth: the vehicle
drives a left-hand arc of radius ``radius_m`` at constant speed; road edges lie at fixed
lateral offsets; lane markings at fixed offsets are sampled in each pose's ego frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

ORIGIN = {"lat": 49.97, "lon": 11.61, "alt": 420.0}
LEFT_EDGE_T = 1.2
RIGHT_EDGE_T = -11.5
MARKINGS_T = (-0.3, -3.9, -7.6)
EGO_X = (0.0, 6.0, 12.0)
EDGE_FORMATS = ("las", "laz", "ply-ascii", "ply-binary", "csv", "npy", "npy-structured", "parquet")


@dataclass(frozen=True)
class RunTruth:
    root: Path
    frame: np.ndarray
    t: np.ndarray
    pose_xyz: np.ndarray
    yaw: np.ndarray
    edges: np.ndarray
    edge_side: np.ndarray  # +1 left, -1 right
    lane_world: np.ndarray
    lane_frame: np.ndarray


def arc_pose(s, *, x0, y0, yaw0, radius_m):
    """Position and heading on a left-hand arc at arc length ``s`` (metres)."""
    yaw = yaw0 + s / radius_m
    x = x0 + radius_m * (np.sin(yaw) - np.sin(yaw0))
    y = y0 - radius_m * (np.cos(yaw) - np.cos(yaw0))
    return x, y, yaw


def offset_point(s, t_lat, **arc):
    x, y, yaw = arc_pose(s, **arc)
    return x - t_lat * np.sin(yaw), y + t_lat * np.cos(yaw)


def write_run(
    root: Path,
    *,
    edge_format: str = "csv",
    n_frames: int = 200,
    speed_mps: float = 25.0,
    rate_hz: float = 10.0,
    radius_m: float = 600.0,
    yaw0: float = 2.9,
    lane_key: str = "frame",
    pose_height_m: float = 0.0,
    with_lane_z: bool = True,
    osm: str | None = None,
    crs: str = "local",
    start_xy: tuple[float, float] = (150.0, -80.0),
    edge_step_m: float = 0.5,
    origin: dict[str, float] | None = None,
) -> RunTruth:
    """Write a run folder and return the truth it was written from."""
    origin = origin if origin is not None else ORIGIN
    root.mkdir(parents=True, exist_ok=True)
    arc = {"x0": start_xy[0], "y0": start_xy[1], "yaw0": yaw0, "radius_m": radius_m}
    frame = np.arange(n_frames, dtype=np.int64) + 1000
    t = 1.7e9 + np.arange(n_frames) / rate_hz
    s_pose = speed_mps * (t - t[0])
    px, py, yaw = arc_pose(s_pose, **arc)
    pz = 5.0 + 0.01 * s_pose + pose_height_m
    traj = pd.DataFrame(
        {
            "yaw": np.arctan2(np.sin(yaw), np.cos(yaw)),  # wrapped to (-pi, pi] as sensors do
            "x": px,
            "y": py,
            "z": pz,
            "t": t,
            "frame": frame,
            "pitch": np.zeros(n_frames),
            "roll": np.zeros(n_frames),
            "quality": 1,
        }
    )
    traj.to_csv(root / "trajectory.csv", index=False, float_format="%.9f")

    s_edge = np.arange(0.0, s_pose[-1], edge_step_m)
    lx, ly = offset_point(s_edge, LEFT_EDGE_T, **arc)
    rx, ry = offset_point(s_edge, RIGHT_EDGE_T, **arc)
    ez = 5.0 + 0.01 * s_edge
    edges = np.column_stack([np.r_[lx, rx], np.r_[ly, ry], np.r_[ez, ez - 0.2]])
    side = np.r_[np.ones(s_edge.size, np.int8), -np.ones(s_edge.size, np.int8)]
    edge_name = write_edges(root, edges, side, edge_format)

    # lane samples: markings at MARKINGS_T, sampled ahead of each pose in its ego frame
    if lane_key == "frame":
        s_at, p_x, p_y, p_z, p_yaw, key = s_pose, px, py, pz, yaw, frame
        lane_frame = np.repeat(frame, len(EGO_X) * len(MARKINGS_T))
    else:  # times between frames; pose interpolated linearly as the loader does
        t_q = t[:-1] + 0.37 / rate_hz
        s_at = speed_mps * (t_q - t[0])
        p_x = np.interp(t_q, t, px)
        p_y = np.interp(t_q, t, py)
        p_z = np.interp(t_q, t, pz)
        p_yaw = np.interp(t_q, t, yaw)
        key = t_q
        lane_frame = np.repeat(frame[:-1], len(EGO_X) * len(MARKINGS_T))
    rows = []
    world = []
    for dx in EGO_X:
        for m in MARKINGS_T:
            wx, wy = offset_point(s_at + dx, m, **arc)
            c, s = np.cos(p_yaw), np.sin(p_yaw)
            ex = c * (wx - p_x) + s * (wy - p_y)
            ey = -s * (wx - p_x) + c * (wy - p_y)
            wz = 5.0 + 0.01 * (s_at + dx)
            rows.append(np.column_stack([key, ex, ey, wz - p_z]))
            world.append(np.column_stack([wx, wy, wz if with_lane_z else p_z - pose_height_m]))
    # interleave so rows are grouped by frame
    arr = np.stack(rows, axis=1).reshape(-1, 4)
    world_arr = np.stack(world, axis=1).reshape(-1, 3)
    lanes = pd.DataFrame(arr, columns=[lane_key, "x", "y", "z"])
    if lane_key == "frame":
        lanes["frame"] = lanes["frame"].astype(np.int64)
    if not with_lane_z:
        lanes = lanes.drop(columns="z")
    lanes.to_csv(root / "lane_samples.csv", index=False, float_format="%.9f")

    files = [
        'trajectory = "trajectory.csv"',
        f'road_edges = "{edge_name}"',
        'lane_samples = "lane_samples.csv"',
    ]
    if osm:
        files.append(f'osm = "{osm}"')
    (root / "run.toml").write_text(
        "[origin]\n"
        f"lat = {origin['lat']}\nlon = {origin['lon']}\nalt = {origin['alt']}\n"
        f'[frame]\ncrs = "{crs}"\n'
        f"[vehicle]\npose_height = {pose_height_m}\n"
        "[files]\n" + "\n".join(files) + "\n"
        '[traffic]\nside = "right"\n',
        encoding="utf-8",
    )
    return RunTruth(
        root, frame, t, np.column_stack([px, py, pz]), yaw, edges, side, world_arr, lane_frame
    )


def write_edges(root: Path, edges: np.ndarray, side: np.ndarray, fmt: str) -> str:
    """Write road-edge points in ``fmt`` with a real library; returns the file name."""
    code = np.where(side > 0, 1, 2).astype(np.uint8)  # documented: 1 = left, 2 = right
    words = np.where(side > 0, "left", "right")
    if fmt in ("las", "laz"):
        import laspy

        header = laspy.LasHeader(point_format=3, version="1.4")
        header.offsets = np.round(edges.mean(axis=0), 3)
        header.scales = np.array([1e-6, 1e-6, 1e-6])
        header.add_extra_dim(laspy.ExtraBytesParams(name="side", type=np.uint8))
        las = laspy.LasData(header)
        las.x, las.y, las.z = edges[:, 0], edges[:, 1], edges[:, 2]
        las.side = code
        name = f"road_edges.{fmt}"
        las.write(root / name)
        return name
    if fmt == "ply-ascii":
        name = "road_edges.ply"
        with (root / name).open("w", encoding="ascii") as fh:
            fh.write(
                "ply\nformat ascii 1.0\ncomment road edges\n"
                f"element vertex {len(edges)}\nproperty double x\nproperty double y\n"
                "property double z\nproperty uchar side\nend_header\n"
            )
            np.savetxt(fh, np.column_stack([edges, code]), fmt=["%.9f"] * 3 + ["%d"])
        return name
    if fmt == "ply-binary":
        name = "road_edges.ply"
        data = np.empty(
            len(edges), dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("side", "u1")]
        )
        data["x"], data["y"], data["z"], data["side"] = edges[:, 0], edges[:, 1], edges[:, 2], code
        with (root / name).open("wb") as fh:
            fh.write(
                b"ply\nformat binary_little_endian 1.0\n"
                + f"element vertex {len(edges)}\n".encode()
                + b"property double x\nproperty double y\nproperty double z\n"
                + b"property uchar side\nend_header\n"
            )
            data.tofile(fh)
        return name
    if fmt == "csv":
        name = "road_edges.csv"
        pd.DataFrame({"x": edges[:, 0], "y": edges[:, 1], "z": edges[:, 2], "side": words}).to_csv(
            root / name, index=False, float_format="%.9f"
        )
        return name
    if fmt == "npy":
        name = "road_edges.npy"
        np.save(root / name, np.column_stack([edges, code.astype(float)]))
        return name
    if fmt == "npy-structured":
        name = "road_edges.npy"
        data = np.empty(len(edges), dtype=[("x", "f8"), ("y", "f8"), ("z", "f8"), ("side", "i1")])
        data["x"], data["y"], data["z"], data["side"] = edges[:, 0], edges[:, 1], edges[:, 2], code
        np.save(root / name, data)
        return name
    if fmt == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        name = "road_edges.parquet"
        table = pa.table(
            {"x": edges[:, 0], "y": edges[:, 1], "z": edges[:, 2], "side": words.tolist()}
        )
        pq.write_table(table, root / name)
        return name
    raise ValueError(fmt)


def motorway_start(osm_path: Path) -> tuple[float, float, float]:
    """(lat, lon, heading_rad) at the middle node of the longest one-way motorway way.

    Read with pyosmium (not the loader under test); heading in the local tmerc frame
    centred on that node, CCW from east, along the way's node order (direction of travel).
    """
    import osmium

    from roadtwin.frames import MappingFrame, Origin

    best: list[tuple[float, float]] = []
    proc = osmium.FileProcessor(str(osm_path)).with_locations()
    for obj in proc.with_filter(osmium.filter.TagFilter(("highway", "motorway"))):
        if obj.is_way() and obj.tags.get("oneway", "yes") == "yes":
            pts = [(n.lat, n.lon) for n in obj.nodes if n.location.valid()]
            if len(pts) > len(best):
                best = pts
    i = len(best) // 2
    lat, lon = best[i]
    frame = MappingFrame(Origin(lat, lon, 0.0))
    x, y = frame.from_lonlat(np.array([best[i + 1][1]] * 2), np.array([best[i + 1][0]] * 2))
    return lat, lon, float(np.arctan2(y[0], x[0]))


def write_run_on_osm(root: Path, osm_path: Path, **kwargs) -> RunTruth:
    """A run starting on a motorway of ``osm_path`` (copied into the run folder)."""
    import shutil

    lat, lon, heading = motorway_start(osm_path)
    root.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(osm_path, root / osm_path.name)
    kwargs.setdefault("n_frames", 120)
    kwargs.setdefault("radius_m", 5000.0)
    origin = {"lat": lat, "lon": lon, "alt": 400.0}
    return write_run(
        root, yaw0=heading, start_xy=(0.0, 0.0), osm=osm_path.name, origin=origin, **kwargs
    )


def build_xodr_route(xodr: Path, out: Path, *, seed: int, route: list[str] | None = None):
    """Simulate a run along an OpenDRIVE map's route into ``out``, build it with OSM and
    evaluate it against the map: ``(truth_info, run_report)``."""
    import json

    from roadtwin.evaluation import evaluate
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map
    from roadtwin.simulate import simulate_xodr_run
    from roadtwin.xodr import read_xodr

    run_dir = simulate_xodr_run(xodr, out, route=route, seed=seed)
    run = load_run(run_dir)
    graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    network = build_map(run, graph).network
    info = json.loads((run_dir / "truth.json").read_text())
    truth = read_xodr(run_dir / "truth.xodr")
    return info, evaluate(network, run, truth=truth, truth_info=info).runs[0]
