"""Robustness benchmark: runs valid by DESIGN.md section 3 but written differently.

roadtwin is judged on runs written by other simulators. This script starts from our own
simulated runs (``roadtwin simulate``), rewrites them into VARIANT run folders (pure
post-processing with numpy/pandas/laspy/pyproj; every variant still follows section 3),
builds each one (``load_run`` -> ``load_osm`` -> ``build_map`` -> ``write_xodr``), checks it
(``check_network``) and evaluates it against the truth in the variant folder
(``evaluate_paths``, like ``roadtwin evaluate DIR/out/map.xodr DIR``).

Variants that change the mapping frame (UTM CRS, a far origin) transform the truth network
with the best rigid transform between the two frames (fit on a grid over the run; the
residual is printed), so RMSE against truth stays comparable.

Run::

    python benchmarks/robustness.py [--scenario straight_curve_2km ...] [--only NAME ...]
        [--workdir DIR] [--markdown FILE]

Prints one row per variant: build ok / error, ramps matched/true (+spurious), road-edge and
lane-boundary RMSE against truth, elevation RMSE, check errors, time.
"""

from __future__ import annotations

import argparse
import dataclasses
import gzip
import hashlib
import shutil
import tempfile
import time
import traceback
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

SCENARIOS = ("straight_curve_2km", "interchange_5km", "left_hand_2km")
REAL_OSM = Path("/work/shared/data/osm")

# ---------------------------------------------------------------------------
# an editable run in memory
# ---------------------------------------------------------------------------


@dataclass
class RunData:
    """A mapping run held in memory, written back by :func:`write_run`.

    ``edges`` has columns x, y, z, side (``"left"``/``"right"``); ``with_side`` decides
    whether the side is written. ``truth_xform`` maps truth xy of the base run into this
    run's frame (``(R, t, dz)``: rotation angle, translation, height offset).
    """

    manifest: dict
    traj: pd.DataFrame
    edges: pd.DataFrame
    lanes: pd.DataFrame
    base: Path
    truth_traj: pd.DataFrame
    osm_src: Path | None
    edge_format: str = "laz"
    with_side: bool = True
    edge_csv_columns: list[str] | None = None
    csv_style: dict = field(default_factory=dict)
    osm_rewrite: Callable[[bytes], bytes] | None = None
    truth_xform: tuple[float, tuple[float, float], float] | None = None
    traj_order: np.ndarray | None = None


def read_base(run_dir: Path) -> RunData:
    """Read a simulated run folder (our simulator's style) into :class:`RunData`."""
    import laspy
    import tomllib

    manifest = tomllib.loads((run_dir / "run.toml").read_text(encoding="utf-8"))
    files = manifest["files"]
    traj = pd.read_csv(run_dir / files["trajectory"])
    lanes = pd.read_csv(run_dir / files["lane_samples"])
    edge_path = run_dir / files["road_edges"]
    if edge_path.suffix in (".las", ".laz"):
        las = laspy.read(edge_path)
        side = np.asarray(las["side"])
        edges = pd.DataFrame(
            {
                "x": np.asarray(las.x, float),
                "y": np.asarray(las.y, float),
                "z": np.asarray(las.z, float),
                "side": np.where(side == 1, "left", np.where(side == 2, "right", "")),
            }
        )
    elif edge_path.suffix == ".csv":
        edges = pd.read_csv(edge_path, keep_default_na=False)
    else:  # pragma: no cover - bases are laz or csv
        raise ValueError(edge_path)
    osm = run_dir / files["osm"] if "osm" in files else None
    return RunData(
        manifest=manifest,
        traj=traj,
        edges=edges,
        lanes=lanes,
        base=run_dir,
        truth_traj=pd.read_csv(run_dir / "truth_trajectory.csv"),
        osm_src=osm,
    )


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    return '"' + str(v).replace("\\", "\\\\").replace('"', '\\"') + '"'


def _write_csv(df: pd.DataFrame, path: Path, style: dict) -> None:
    text = df.to_csv(index=False, float_format="%.6f", lineterminator=style.get("eol", "\n"))
    data = text.encode("utf-8")
    if style.get("bom"):
        data = b"\xef\xbb\xbf" + data
    path.write_bytes(data)


def _side_code(edges: pd.DataFrame) -> np.ndarray:
    s = edges["side"].astype(str).to_numpy()
    return np.where(s == "left", 1, np.where(s == "right", 2, 0)).astype(np.uint8)


def write_edges(rd: RunData, path: Path) -> None:
    """Write the road edges in ``rd.edge_format`` (with or without the side)."""
    import laspy

    e = rd.edges
    fmt = rd.edge_format
    if fmt in ("las", "laz"):
        header = laspy.LasHeader(point_format=3, version="1.2")
        if rd.with_side:
            header.add_extra_dim(laspy.ExtraBytesParams(name="side", type=np.uint8))
        extra = [c for c in e.columns if c not in ("x", "y", "z", "side", "intensity")]
        for c in extra:
            header.add_extra_dim(laspy.ExtraBytesParams(name=c, type=np.float32))
        xyz = e[["x", "y", "z"]].to_numpy(float)
        header.offsets = np.floor(xyz.min(axis=0))
        header.scales = np.array([0.001, 0.001, 0.001])
        las = laspy.LasData(header)
        las.x, las.y, las.z = xyz.T
        if "intensity" in e:
            las.intensity = e["intensity"].to_numpy().astype(np.uint16)
        if rd.with_side:
            las["side"] = _side_code(e)
        for c in extra:
            las[c] = e[c].to_numpy(np.float32)
        las.write(str(path))
    elif fmt == "csv":
        cols = rd.edge_csv_columns or [c for c in e.columns if rd.with_side or c != "side"]
        _write_csv(e[cols], path, rd.csv_style)
    elif fmt == "parquet":
        cols = [c for c in e.columns if rd.with_side or c != "side"]
        e[cols].to_parquet(path, index=False)
    elif fmt == "npy":
        if rd.with_side:
            arr = np.zeros(len(e), dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("side", "u1")])
            arr["x"], arr["y"], arr["z"] = (e[c].to_numpy(float) for c in "xyz")
            arr["side"] = _side_code(e)
        else:
            arr = e[["x", "y", "z"]].to_numpy(float)
        np.save(path, arr)
    elif fmt == "ply":  # binary little endian, float32 xyz (what most tools write)
        props = [("x", "<f4", "float"), ("y", "<f4", "float"), ("z", "<f4", "float")]
        if rd.with_side:
            props.append(("side", "u1", "uchar"))
        arr = np.zeros(len(e), dtype=[(n, d) for n, d, _ in props])
        for c in "xyz":
            arr[c] = e[c].to_numpy(float)
        if rd.with_side:
            arr["side"] = _side_code(e)
        head = ["ply", "format binary_little_endian 1.0", "comment robustness variant"]
        head.append(f"element vertex {len(e)}")
        head += [f"property {t} {n}" for n, _, t in props]
        head.append("end_header")
        path.write_bytes(("\n".join(head) + "\n").encode("ascii") + arr.tobytes())
    elif fmt == "ply_ascii":
        cols = ["x", "y", "z"] + (["side"] if rd.with_side else [])
        head = ["ply", "format ascii 1.0", f"element vertex {len(e)}"]
        head += [f"property {'double' if c != 'side' else 'uchar'} {c}" for c in cols]
        head.append("end_header")
        body = np.column_stack([e[c].to_numpy(float) for c in "xyz"])
        lines = [f"{a:.4f} {b:.4f} {c:.4f}" for a, b, c in body]
        if rd.with_side:
            lines = [f"{ln} {s}" for ln, s in zip(lines, _side_code(e), strict=True)]
        path.write_text("\n".join(head + lines) + "\n", encoding="ascii")
    else:  # pragma: no cover
        raise ValueError(fmt)


def _edge_file_name(fmt: str) -> str:
    return "road_edges." + ("ply" if fmt.startswith("ply") else fmt)


def _transform_truth(src: Path, dst: Path, xform) -> None:
    """Write ``src`` truth.xodr rigidly transformed (rotation, translation, dz) to ``dst``."""
    from roadtwin.model import CubicPiece, CubicProfile
    from roadtwin.xodr import read_xodr, write_xodr

    theta, (tx, ty), dz = xform
    c, s = np.cos(theta), np.sin(theta)
    net = read_xodr(src)
    roads = []
    for road in net.roads:
        geo = tuple(
            replace(g, x0=c * g.x0 - s * g.y0 + tx, y0=s * g.x0 + c * g.y0 + ty, hdg=g.hdg + theta)
            for g in road.geometry
        )
        pieces = road.elevation.pieces or (CubicPiece(0.0, 0.0),)
        elev = CubicProfile(tuple(replace(p, a=p.a + dz) for p in pieces))
        roads.append(replace(road, geometry=geo, elevation=elev))
    write_xodr(replace(net, roads=tuple(roads)), dst)


def write_run(rd: RunData, dst: Path) -> Path:
    """Write ``rd`` as a run folder (section 3) plus the (transformed) truth files."""
    dst.mkdir(parents=True, exist_ok=True)
    man = {k: dict(v) for k, v in rd.manifest.items()}
    man["files"]["road_edges"] = _edge_file_name(rd.edge_format)
    if rd.osm_src is not None:
        name = rd.osm_src.name
        low = name.lower()
        for suf in (".osm.pbf", ".osm.bz2", ".osm.gz", ".osm"):
            if low.endswith(suf):
                name = "map" + suf
                break
        data = rd.osm_src.read_bytes()
        if rd.osm_rewrite is not None:
            if name.endswith(".gz"):
                data = gzip.decompress(data)
                name = name[:-3]
            data = rd.osm_rewrite(data)
        (dst / name).write_bytes(data)
        man["files"]["osm"] = name
    else:
        man["files"].pop("osm", None)
    lines = ["# robustness variant"]
    for table, values in man.items():
        lines.append(f"[{table}]")
        lines += [f"{k} = {_toml_value(v)}" for k, v in values.items()]
    (dst / "run.toml").write_text("\n".join(lines) + "\n", encoding="utf-8")
    traj = rd.traj if rd.traj_order is None else rd.traj.iloc[rd.traj_order]
    _write_csv(traj, dst / man["files"]["trajectory"], rd.csv_style)
    _write_csv(rd.lanes, dst / man["files"]["lane_samples"], rd.csv_style)
    write_edges(rd, dst / man["files"]["road_edges"])
    shutil.copyfile(rd.base / "truth.json", dst / "truth.json")
    if rd.truth_xform is None:
        shutil.copyfile(rd.base / "truth.xodr", dst / "truth.xodr")
    else:
        _transform_truth(rd.base / "truth.xodr", dst / "truth.xodr", rd.truth_xform)
    return dst


# ---------------------------------------------------------------------------
# helpers for variants
# ---------------------------------------------------------------------------


def _copy(rd: RunData) -> RunData:
    return dataclasses.replace(
        rd,
        manifest={k: dict(v) for k, v in rd.manifest.items()},
        traj=rd.traj.copy(),
        edges=rd.edges.copy(),
        lanes=rd.lanes.copy(),
        csv_style=dict(rd.csv_style),
    )


def _pose_arrays(traj: pd.DataFrame):
    order = np.argsort(traj["frame"].to_numpy())
    return (
        traj["frame"].to_numpy()[order],
        traj[["x", "y", "z"]].to_numpy(float)[order],
        np.unwrap(traj["yaw"].to_numpy(float)[order]),
        traj["t"].to_numpy(float)[order],
    )


def lanes_to_map(rd: RunData) -> np.ndarray:
    """Lane samples in the mapping frame (x, y, z) by their frame's pose (as section 3)."""
    frames, xyz, yaw, _ = _pose_arrays(rd.traj)
    idx = np.searchsorted(frames, rd.lanes["frame"].to_numpy())
    ex, ey = rd.lanes["x"].to_numpy(float), rd.lanes["y"].to_numpy(float)
    ez = rd.lanes["z"].to_numpy(float) if "z" in rd.lanes else np.zeros(ex.size)
    c, s = np.cos(yaw[idx]), np.sin(yaw[idx])
    return np.column_stack(
        [xyz[idx, 0] + c * ex - s * ey, xyz[idx, 1] + s * ex + c * ey, xyz[idx, 2] + ez]
    )


def map_to_ego(pts: np.ndarray, pose_xyz: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Mapping-frame points into the level ego frame of the given poses."""
    d = pts[:, :2] - pose_xyz[:, :2]
    c, s = np.cos(yaw), np.sin(yaw)
    return np.column_stack(
        [c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], pts[:, 2] - pose_xyz[:, 2]]
    )


def edge_stations(rd: RunData) -> tuple[np.ndarray, np.ndarray]:
    """Station (m along the true trajectory) and distance to the nearest pose per edge point."""
    txy = rd.truth_traj[["x", "y"]].to_numpy(float)
    st = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(txy, axis=0).T))])
    d, i = cKDTree(txy).query(rd.edges[["x", "y"]].to_numpy(float))
    return st[i], d


def _gauss_markov(rng, n: int, std: float, corr_steps: float) -> np.ndarray:
    a = np.exp(-1.0 / corr_steps)
    w = rng.normal(0.0, std * np.sqrt(1 - a * a), n)
    out = np.empty(n)
    out[0] = rng.normal(0.0, std)
    for k in range(1, n):  # n poses (thousands): fine in a benchmark
        out[k] = a * out[k - 1] + w[k]
    return out


def reproject(rd: RunData, *, crs: str, origin: tuple[float, float] | None = None) -> RunData:
    """Move every mapping-frame coordinate into a new frame (``crs`` and/or a new origin).

    x, y of poses and edges are transformed with pyproj; yaw changes by the local grid
    convergence (a 1 m step along the heading transformed); lane samples (ego frame) are
    re-expressed relative to the transformed pose so that their mapping-frame positions
    transform exactly. In a projected CRS z becomes absolute (alt + local z).
    """
    from pyproj import Transformer

    from roadtwin.frames import MappingFrame, Origin

    out = _copy(rd)
    o = rd.manifest["origin"]
    alt = float(o.get("alt", 0.0))
    old = MappingFrame(Origin(float(o["lat"]), float(o["lon"]), alt), crs="local")
    new_origin = Origin(*(origin if origin is not None else (o["lat"], o["lon"])), alt)
    new = MappingFrame(new_origin, crs=crs)
    tr = Transformer.from_crs(old._crs, new._crs, always_xy=True)
    dz = alt if crs != "local" else 0.0

    def fwd(x, y):
        return np.column_stack(tr.transform(np.asarray(x, float), np.asarray(y, float)))

    lanes_map = lanes_to_map(rd)
    t = rd.traj
    xy = fwd(t["x"], t["y"])
    yaw = t["yaw"].to_numpy(float)
    ahead = fwd(t["x"] + np.cos(yaw), t["y"] + np.sin(yaw))
    new_yaw = np.arctan2(ahead[:, 1] - xy[:, 1], ahead[:, 0] - xy[:, 0])
    new_yaw = yaw + (new_yaw - yaw + np.pi) % (2 * np.pi) - np.pi
    out.traj["x"], out.traj["y"], out.traj["yaw"] = xy[:, 0], xy[:, 1], new_yaw
    out.traj["z"] = t["z"] + dz
    e = fwd(rd.edges["x"], rd.edges["y"])
    out.edges["x"], out.edges["y"], out.edges["z"] = e[:, 0], e[:, 1], rd.edges["z"] + dz
    # lane samples: transformed mapping position re-expressed in the new pose's ego frame
    lm = np.column_stack([fwd(lanes_map[:, 0], lanes_map[:, 1]), lanes_map[:, 2] + dz])
    frames, pxyz, pyaw, _ = _pose_arrays(out.traj)
    idx = np.searchsorted(frames, rd.lanes["frame"].to_numpy())
    ego = map_to_ego(lm, pxyz[idx], pyaw[idx])
    out.lanes["x"], out.lanes["y"] = ego[:, 0], ego[:, 1]
    if "z" in out.lanes:
        out.lanes["z"] = ego[:, 2]
    # truth: best rigid transform old -> new over the run's area
    txy = rd.truth_traj[["x", "y"]].to_numpy(float)
    lo, hi = txy.min(axis=0) - 300, txy.max(axis=0) + 300
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 25), np.linspace(lo[1], hi[1], 25))
    src = np.column_stack([gx.ravel(), gy.ravel()])
    dst = fwd(src[:, 0], src[:, 1])
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    h = (src - ms).T @ (dst - md)
    theta = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
    c, s = np.cos(theta), np.sin(theta)
    rot = np.array([[c, -s], [s, c]])
    trans = md - rot @ ms
    # residual on the trajectory itself (what matters for lateral RMSE)
    tdst = fwd(txy[:, 0], txy[:, 1])
    resid = np.linalg.norm(txy @ rot.T + trans - tdst, axis=1)
    out.truth_xform = (theta, (float(trans[0]), float(trans[1])), dz)
    out.manifest["frame"] = {"crs": crs}
    out.manifest["origin"] = {"lat": new_origin.lat_deg, "lon": new_origin.lon_deg, "alt": alt}
    out.csv_style["truth_residual_m"] = float(resid.max())
    return out


def rotate(rd: RunData, theta: float, *, yaw_range: str = "pi") -> RunData:
    """The same run at another place: every coordinate (poses, edges, OSM nodes, truth)
    rotated by ``theta`` (radians) about the mapping-frame origin. Yaw is written wrapped
    to (-pi, pi] (``yaw_range="pi"``) or [0, 2 pi) (``"2pi"``), as many INS export it."""
    from lxml import etree

    from roadtwin.frames import MappingFrame, Origin

    out = _copy(rd)
    c, s = np.cos(theta), np.sin(theta)

    def rot(x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        return c * x - s * y, s * x + c * y

    out.traj["x"], out.traj["y"] = rot(rd.traj["x"], rd.traj["y"])
    yaw = rd.traj["yaw"].to_numpy(float) + theta
    yaw = np.mod(yaw, 2 * np.pi) if yaw_range == "2pi" else np.angle(np.exp(1j * yaw))
    out.traj["yaw"] = yaw
    out.edges["x"], out.edges["y"] = rot(rd.edges["x"], rd.edges["y"])  # ego lane samples: as is
    o = rd.manifest["origin"]
    frame = MappingFrame(Origin(float(o["lat"]), float(o["lon"]), float(o.get("alt", 0.0))))

    def rewrite(data: bytes) -> bytes:
        root = etree.fromstring(data)
        nodes = list(root.iter("node"))
        lon = np.array([float(n.get("lon")) for n in nodes])
        lat = np.array([float(n.get("lat")) for n in nodes])
        x, y = frame.from_lonlat(lon, lat)
        lon2, lat2 = frame.to_lonlat(*rot(x, y))
        for n, a, b in zip(nodes, lon2, lat2, strict=True):
            n.set("lon", f"{a:.8f}")
            n.set("lat", f"{b:.8f}")
        for b in root.iter("bounds"):
            root.remove(b)
        return etree.tostring(root, xml_declaration=True, encoding="UTF-8")

    out.osm_rewrite = rewrite
    out.truth_xform = (theta, (0.0, 0.0), 0.0)
    return out


def utm_epsg(lat: float, lon: float) -> str:
    """EPSG code of the UTM zone of a WGS84 point."""
    zone = int((lon + 180.0) // 6.0) + 1
    return f"EPSG:{(32600 if lat >= 0 else 32700) + zone}"


# ---------------------------------------------------------------------------
# variants: (run, rng) -> run
# ---------------------------------------------------------------------------


def v_baseline(rd, rng):
    return _copy(rd)


def _fmt(fmt: str, side: bool = True):
    def f(rd, rng):
        out = _copy(rd)
        out.edge_format, out.with_side = fmt, side
        return out

    f.__doc__ = f"road edges as {fmt}{'' if side else ' without side'}"
    return f


def v_shuffle_points(rd, rng):
    out = _copy(rd)
    out.edges = out.edges.iloc[rng.permutation(len(out.edges))].reset_index(drop=True)
    out.lanes = out.lanes.iloc[rng.permutation(len(out.lanes))].reset_index(drop=True)
    return out


def v_shuffle_trajectory_rows(rd, rng):
    """Trajectory rows not sorted (section 3 does not say they are)."""
    out = _copy(rd)
    out.traj_order = rng.permutation(len(out.traj))
    return out


def _lanes_by_t(between: bool):
    def f(rd, rng):
        out = _copy(rd)
        pts = lanes_to_map(rd)
        frames, xyz, yaw, t = _pose_arrays(rd.traj)
        idx = np.searchsorted(frames, rd.lanes["frame"].to_numpy())
        ts = t[idx]
        if between:
            dt = np.median(np.diff(t))
            ts = np.clip(ts + rng.uniform(-0.45, 0.45, ts.size) * dt, t[0], t[-1])
        px = np.column_stack([np.interp(ts, t, xyz[:, k]) for k in range(3)])
        pyaw = np.interp(ts, t, yaw)
        ego = map_to_ego(pts, px, pyaw)
        cols = {"t": ts, "x": ego[:, 0], "y": ego[:, 1]}
        if "z" in rd.lanes:
            cols["z"] = ego[:, 2]
        out.lanes = pd.DataFrame(cols)
        return out

    return f


def v_lanes_no_z(rd, rng):
    out = _copy(rd)
    out.lanes = out.lanes.drop(columns=["z"], errors="ignore")
    return out


def v_pitch_roll(rd, rng):
    out = _copy(rd)
    xyz = rd.traj[["x", "y", "z"]].to_numpy(float)
    ds = np.hypot(*np.diff(xyz[:, :2], axis=0).T)
    grade = np.diff(xyz[:, 2]) / np.maximum(ds, 1e-3)
    pitch = -np.arctan(np.concatenate([grade, grade[-1:]]))
    out.traj["pitch"] = np.convolve(pitch, np.ones(21) / 21, mode="same")
    out.traj["roll"] = rng.normal(0.0, 0.01, len(xyz))
    return out


def v_column_order(rd, rng):
    out = _copy(rd)
    out.traj = out.traj[list(reversed(out.traj.columns))]
    out.lanes = out.lanes[list(reversed(out.lanes.columns))]
    out.edge_format = "csv"
    out.edge_csv_columns = ["side", "z", "y", "x"]
    return out


def v_extra_columns(rd, rng):
    out = _copy(rd)
    n = len(out.traj)
    out.traj["gps_week"] = 2300
    out.traj["quality"] = rng.integers(1, 5, n)
    out.traj["status"] = "RTK_FIXED"
    out.traj["vx"] = rng.normal(25.0, 0.1, n)
    out.lanes["confidence"] = rng.uniform(0.5, 1.0, len(out.lanes))
    out.lanes["type"] = "dashed"
    out.edges["intensity"] = rng.integers(0, 255, len(out.edges))
    out.edges["ring"] = rng.integers(0, 32, len(out.edges)).astype(float)
    return out


def v_extra_columns_csv(rd, rng):
    out = v_extra_columns(rd, rng)
    out.edge_format = "csv"
    return out


def v_gps_epoch(rd, rng):
    out = _copy(rd)
    out.traj["t"] = out.traj["t"] + 1_400_000_000.0
    return out


def v_frame_gaps(rd, rng):
    out = _copy(rd)
    old = out.traj["frame"].to_numpy()
    new = 1000 + np.cumsum(rng.integers(1, 4, old.size)) - 1
    mapping = dict(zip(old.tolist(), new.tolist(), strict=True))
    out.traj["frame"] = new
    out.lanes["frame"] = out.lanes["frame"].map(mapping)
    return out


def v_csv_bom_crlf(rd, rng):
    out = _copy(rd)
    out.csv_style.update(bom=True, eol="\r\n")
    out.edge_format = "csv"
    return out


def _pose_height(h: float, lane_z: bool = True):
    def f(rd, rng):
        out = _copy(rd)
        out.traj["z"] = out.traj["z"] + h
        if lane_z:
            out.lanes["z"] = out.lanes["z"] - h  # ego z is relative to the raised pose
        else:
            out.lanes = out.lanes.drop(columns=["z"])
        out.manifest["vehicle"] = {"pose_height": h}
        return out

    return f


def _crs(which: str):
    def f(rd, rng):
        o = rd.manifest["origin"]
        if which == "utm":
            return reproject(rd, crs=utm_epsg(o["lat"], o["lon"]))
        if which == "utm_wrong_zone":  # a valid CRS whose central meridian is 6 deg away
            code = int(utm_epsg(o["lat"], o["lon"]).split(":")[1]) + 1
            return reproject(rd, crs=f"EPSG:{code}")
        # far origin: the same local tmerc definition, origin 25 km west, 15 km south
        from roadtwin.frames import MappingFrame, Origin

        fr = MappingFrame(Origin(o["lat"], o["lon"], o.get("alt", 0.0)))
        lon, lat = fr.to_lonlat(np.array([-25000.0]), np.array([-15000.0]))
        return reproject(rd, crs="local", origin=(float(lat[0]), float(lon[0])))

    return f


def _wrap_theta(rd: RunData) -> float:
    """A rotation that makes the run's heading cross +-pi half-way through."""
    yaw = np.unwrap(rd.traj["yaw"].to_numpy(float))
    return float(np.pi - yaw[yaw.size // 2])


def _edge_noise(total_std: float):
    def f(rd, rng):
        out = _copy(rd)
        extra = np.sqrt(max(total_std**2 - 0.03**2, 0.0))
        out.edges["x"] = out.edges["x"] + rng.normal(0, extra, len(out.edges))
        out.edges["y"] = out.edges["y"] + rng.normal(0, extra, len(out.edges))
        return out

    return f


def v_outliers_10pct(rd, rng):
    out = _copy(rd)
    n = len(out.edges)
    pick = rng.random(n) < 0.10
    ang = rng.uniform(0, 2 * np.pi, pick.sum())
    r = rng.uniform(0.3, 3.0, pick.sum())
    out.edges.loc[pick, "x"] += r * np.cos(ang)
    out.edges.loc[pick, "y"] += r * np.sin(ang)
    out.edges.loc[pick, "z"] += rng.uniform(0.0, 1.5, pick.sum())
    return out


def _density(keep: float):
    def f(rd, rng):
        out = _copy(rd)
        out.edges = out.edges[rng.random(len(out.edges)) < keep].reset_index(drop=True)
        return out

    return f


def _occlusion(side: str, length: float = 80.0):
    def f(rd, rng):
        out = _copy(rd)
        st, _ = edge_stations(rd)
        mid = 0.45 * st.max()
        gone = (out.edges["side"] == side).to_numpy() & (np.abs(st - mid) < length / 2)
        out.edges = out.edges[~gone].reset_index(drop=True)
        return out

    return f


def _median_unseen_start(length: float):
    """No median-side (left) edge point over the run's first ``length`` metres: the edge
    out of the sensor's reach across a wide road, or hidden behind traffic."""

    def f(rd, rng):
        out = _copy(rd)
        st, _ = edge_stations(rd)
        gone = (out.edges["side"] == "left").to_numpy() & (st < length)
        out.edges = out.edges[~gone].reset_index(drop=True)
        return out

    return f


def _edge_range(limit: float):
    def f(rd, rng):
        out = _copy(rd)
        d, _ = cKDTree(rd.traj[["x", "y"]].to_numpy(float)).query(
            rd.edges[["x", "y"]].to_numpy(float)
        )
        out.edges = out.edges[d <= limit].reset_index(drop=True)
        return out

    return f


def v_lane_miss_20pct(rd, rng):
    out = _copy(rd)
    out.lanes = out.lanes[rng.random(len(out.lanes)) >= 0.2].reset_index(drop=True)
    return out


def v_lane_miss_frames_20pct(rd, rng):
    """Whole frames without lane samples (20 % of the frames, in runs of 10 frames)."""
    out = _copy(rd)
    f = out.lanes["frame"].to_numpy()
    block = (f - f.min()) // 10
    drop = rng.random(block.max() + 1) < 0.2
    out.lanes = out.lanes[~drop[block]].reset_index(drop=True)
    return out


def v_lane_false_positive(rd, rng):
    out = _copy(rd)
    n = int(0.05 * len(out.lanes))
    frames = rng.choice(out.traj["frame"].to_numpy(), n)
    fp = {"frame": frames, "x": rng.uniform(3, 30, n), "y": rng.uniform(-12, 12, n)}
    if "z" in out.lanes:
        fp["z"] = rng.normal(0, 0.03, n)
    out.lanes = (
        pd.concat([out.lanes, pd.DataFrame(fp)]).sort_values("frame", kind="stable")
    ).reset_index(drop=True)
    return out


def _pose_noise(kind: str, std: float = 0.10):
    def f(rd, rng):
        out = _copy(rd)
        n = len(out.traj)
        if kind == "drift":  # the car's error: poses AND the edges registered with them move
            dx = _gauss_markov(rng, n, std, 200.0)
            dy = _gauss_markov(rng, n, std, 200.0)
            _, i = cKDTree(rd.traj[["x", "y"]].to_numpy(float)).query(
                rd.edges[["x", "y"]].to_numpy(float)
            )
            out.edges["x"] = out.edges["x"] + dx[i]
            out.edges["y"] = out.edges["y"] + dy[i]
        else:  # white jitter on the poses alone (lane samples move with them)
            dx, dy = rng.normal(0, std, n), rng.normal(0, std, n)
        out.traj["x"] = out.traj["x"] + dx
        out.traj["y"] = out.traj["y"] + dy
        return out

    return f


def _osm_rewrite(kind: str):
    def f(rd, rng):
        from lxml import etree

        out = _copy(rd)

        def rewrite(data: bytes) -> bytes:
            root = etree.fromstring(data)
            for way in root.iter("way"):
                tags = {t.get("k"): t for t in way.iter("tag")}
                if kind == "no_lanes":
                    for k in ("lanes", "lanes:forward", "lanes:backward", "turn:lanes"):
                        if k in tags:
                            way.remove(tags[k])
                elif kind == "coarse_links":
                    hw = tags.get("highway")
                    if hw is not None and hw.get("v").endswith("_link"):
                        nds = list(way.iter("nd"))
                        keep = {0, len(nds) // 2, len(nds) - 1}
                        for j, nd in enumerate(nds):
                            if j not in keep:
                                way.remove(nd)
            return etree.tostring(root, xml_declaration=True, encoding="UTF-8")

        prev = rd.osm_rewrite
        out.osm_rewrite = rewrite if prev is None else (lambda data: rewrite(prev(data)))
        return out

    return f


def _chain(*names):
    def f(rd, rng):
        out = rd
        for n in names:
            out = VARIANTS[n](out, rng)
        return out

    return f


def _side_labels(kind: str):
    def f(rd, rng):
        out = _copy(rd)
        out.edge_format = "csv"
        side = out.edges["side"].astype(str)
        if kind == "capitalised":
            out.edges["side"] = side.str.capitalize()
        else:  # integer codes as many tools write them: 1 = left, 2 = right
            out.edges["side"] = np.where(side == "left", 1, 2)
        return out

    return f


def v_frame_as_float(rd, rng):
    out = _copy(rd)
    out.traj["frame"] = out.traj["frame"].astype(float)
    out.lanes["frame"] = out.lanes["frame"].astype(float)
    return out


def v_traj_2hz_lanes_by_t(rd, rng):
    """Poses at 2 Hz only (every 5th row); lane samples keyed by ``t`` of their frame."""
    out = _lanes_by_t(False)(rd, rng)
    keep = np.zeros(len(rd.traj), dtype=bool)
    keep[::5] = True
    keep[-1] = True
    out.traj = rd.traj[keep].reset_index(drop=True)
    # ego coordinates relative to the pose interpolated between the kept poses
    pts = lanes_to_map(rd)
    _, xyz, yaw, t = _pose_arrays(out.traj)
    ts = out.lanes["t"].to_numpy(float)
    px = np.column_stack([np.interp(ts, t, xyz[:, k]) for k in range(3)])
    ego = map_to_ego(pts, px, np.interp(ts, t, yaw))
    out.lanes["x"], out.lanes["y"] = ego[:, 0], ego[:, 1]
    if "z" in out.lanes:
        out.lanes["z"] = ego[:, 2]
    return out


def v_lanes_rear_ego(rd, rng):
    """Half the lane samples expressed in the frame 10 frames LATER (behind the car, ego
    x < 0), as a 360-degree sensor reports them."""
    out = _copy(rd)
    pts = lanes_to_map(rd)
    frames, xyz, yaw, _ = _pose_arrays(rd.traj)
    idx = np.searchsorted(frames, rd.lanes["frame"].to_numpy())
    later = np.where(rng.random(idx.size) < 0.5, np.minimum(idx + 10, frames.size - 1), idx)
    ego = map_to_ego(pts, xyz[later], yaw[later])
    out.lanes["frame"] = frames[later]
    out.lanes["x"], out.lanes["y"] = ego[:, 0], ego[:, 1]
    if "z" in out.lanes:
        out.lanes["z"] = ego[:, 2]
    return out


def v_stop_and_go(rd, rng):
    """The car stands still for 10 s half-way (100 extra poses at the same spot, 3 mm
    jitter); the sensor keeps reporting the same lane samples and edge points there."""
    out = _copy(rd)
    tr = rd.traj.sort_values("frame").reset_index(drop=True)
    k = len(tr) // 2
    dt = float(np.median(np.diff(tr["t"])))
    n_stop = 100
    stop = pd.DataFrame([tr.iloc[k]] * n_stop).reset_index(drop=True)
    stop["frame"] = tr["frame"].iloc[k] + 1 + np.arange(n_stop)
    stop["t"] = tr["t"].iloc[k] + dt * (1 + np.arange(n_stop))
    for c in ("x", "y"):
        stop[c] = stop[c] + rng.normal(0, 0.003, n_stop)
    after = tr.iloc[k + 1 :].copy()
    after["frame"] = after["frame"] + n_stop
    after["t"] = after["t"] + n_stop * dt
    out.traj = pd.concat([tr.iloc[: k + 1], stop, after]).reset_index(drop=True)
    lanes = rd.lanes.copy()
    f0 = int(tr["frame"].iloc[k])
    lanes.loc[lanes["frame"] > f0, "frame"] += n_stop
    at_k = rd.lanes[rd.lanes["frame"] == f0]
    reps = []
    for j in range(n_stop):
        r = at_k.copy()
        r["frame"] = f0 + 1 + j
        r["x"] = r["x"] + rng.normal(0, 0.03, len(r))
        r["y"] = r["y"] + rng.normal(0, 0.03, len(r))
        reps.append(r)
    out.lanes = pd.concat([lanes, *reps]).sort_values("frame", kind="stable")
    out.lanes = out.lanes.reset_index(drop=True)
    # edge points seen from the standing car: 20 more noisy looks at those within 25 m
    pose = tr[["x", "y"]].iloc[k].to_numpy(float)
    near = rd.edges[np.hypot(*(rd.edges[["x", "y"]].to_numpy(float) - pose).T) < 25.0]
    extra = pd.concat([near] * 20).reset_index(drop=True)
    for c in ("x", "y"):
        extra[c] = extra[c] + rng.normal(0, 0.03, len(extra))
    out.edges = pd.concat([rd.edges, extra]).reset_index(drop=True)
    return out


def _crop(lo: float, hi: float):
    """Only the part of the run between stations ``lo`` and ``hi`` (metres along the true
    trajectory): runs that start or end inside a gore area, or are short."""

    def f(rd, rng):
        out = _copy(rd)
        txy = rd.truth_traj[["x", "y"]].to_numpy(float)
        st = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(txy, axis=0).T))])
        keep_frames = rd.truth_traj["frame"].to_numpy()[(st >= lo) & (st <= hi)]
        out.traj = rd.traj[rd.traj["frame"].isin(keep_frames)].reset_index(drop=True)
        out.lanes = rd.lanes[rd.lanes["frame"].isin(keep_frames)].reset_index(drop=True)
        est, _ = edge_stations(rd)
        out.edges = rd.edges[(est >= lo - 20.0) & (est <= hi + 20.0)].reset_index(drop=True)
        return out

    return f


def v_no_osm(rd, rng):
    out = _copy(rd)
    out.osm_src = None
    return out


VARIANTS: dict[str, Callable] = {
    "baseline": v_baseline,
    "edges_no_side": _fmt("laz", side=False),
    "edges_las": _fmt("las"),
    "edges_csv": _fmt("csv"),
    "edges_csv_no_side": _fmt("csv", side=False),
    "edges_ply_f32": _fmt("ply"),
    "edges_ply_ascii": _fmt("ply_ascii"),
    "edges_ply_no_side": _fmt("ply", side=False),
    "edges_npy": _fmt("npy"),
    "edges_npy_no_side": _fmt("npy", side=False),
    "edges_parquet": _fmt("parquet"),
    "edges_parquet_no_side": _fmt("parquet", side=False),
    "shuffled_points": v_shuffle_points,
    "shuffled_trajectory_rows": v_shuffle_trajectory_rows,
    "lanes_by_t_exact": _lanes_by_t(False),
    "lanes_by_t_between": _lanes_by_t(True),
    "lanes_no_z": v_lanes_no_z,
    "traj_pitch_roll": v_pitch_roll,
    "column_order": v_column_order,
    "extra_columns": v_extra_columns,
    "extra_columns_csv": v_extra_columns_csv,
    "csv_bom_crlf": v_csv_bom_crlf,
    "gps_epoch_t": v_gps_epoch,
    "frame_gaps": v_frame_gaps,
    "pose_height_1.8": _pose_height(1.8),
    "pose_height_1.8_no_lane_z": _pose_height(1.8, lane_z=False),
    "rotated_yaw_wraps_pi": lambda rd, rng: rotate(rd, _wrap_theta(rd)),
    "rotated_yaw_0_2pi": lambda rd, rng: rotate(rd, _wrap_theta(rd) - np.pi, yaw_range="2pi"),
    "crs_utm": _crs("utm"),
    "crs_utm_next_zone": _crs("utm_wrong_zone"),
    "origin_far": _crs("far"),
    "edge_noise_5cm": _edge_noise(0.05),
    "edge_noise_8cm": _edge_noise(0.08),
    "edge_outliers_10pct": v_outliers_10pct,
    "edge_density_half": _density(0.5),
    "occlusion_80m_left": _occlusion("left"),
    "occlusion_80m_right": _occlusion("right"),
    "median_unseen_first_250m": _median_unseen_start(250.0),
    "edge_range_15m": _edge_range(15.0),
    "edge_range_9m": _edge_range(9.0),
    "lane_miss_20pct": v_lane_miss_20pct,
    "lane_miss_frames_20pct": v_lane_miss_frames_20pct,
    "lane_false_pos_5pct": v_lane_false_positive,
    "pose_drift_10cm": _pose_noise("drift"),
    "pose_jitter_10cm": _pose_noise("jitter"),
    "osm_no_lanes_tags": _osm_rewrite("no_lanes"),
    "osm_coarse_links": _osm_rewrite("coarse_links"),
    "no_osm": v_no_osm,
    "edges_side_capitalised": _side_labels("capitalised"),
    "edges_side_int_codes": _side_labels("int"),
    "frame_as_float": v_frame_as_float,
    "traj_2hz_lanes_by_t": v_traj_2hz_lanes_by_t,
    "lanes_rear_ego": v_lanes_rear_ego,
    "stop_and_go_10s": v_stop_and_go,
    "crop_start_in_exit_taper": _crop(420.0, 2000.0),
    "crop_gore_to_gore": _crop(600.0, 1300.0),
    "crop_end_at_exit_gore": _crop(0.0, 660.0),
    "crop_300m": _crop(800.0, 1100.0),
    "crop_gore_to_gore_100m": _crop(550.0, 1350.0),
    "lane_miss_and_false_pos": _chain("lane_miss_frames_20pct", "lane_false_pos_5pct"),
    "osm_no_lanes_coarse_links": _chain("osm_no_lanes_tags", "osm_coarse_links"),
}

# variants that need a different simulation (cannot be post-processed): scenario edits
SCENARIO_VARIANTS: dict[str, Callable] = {
    "edge_density_x3": lambda sc: replace(sc, sensor=replace(sc.sensor, edge_spacing_m=0.2 / 3)),
    "car_in_leftmost_lane": lambda sc: replace(sc, car=replace(sc.car, lane=1)),
}


# ---------------------------------------------------------------------------
# a run along a real OSM motorway (the map is the real extract)
# ---------------------------------------------------------------------------


def motorway_chain(osm_path: Path, *, max_m: float = 3000.0):
    """The longest chain of one-way ``highway=motorway`` ways in an OSM file.

    Returns ``(lonlat (N, 2), lanes)``: the chain's nodes and the most common ``lanes`` tag
    along it (2 if none).
    """
    import collections

    import osmium

    ways = []
    for w in osmium.FileProcessor(str(osm_path)).with_locations():
        if not w.is_way() or w.tags.get("highway") != "motorway":
            continue
        if w.tags.get("oneway", "yes") not in ("yes", "1", "true"):
            continue
        run: list = []  # a crop can cut a way: keep its runs of nodes with a location
        for n in [*w.nodes, None]:
            if n is not None and n.location.valid():
                run.append((n.ref, (n.lon, n.lat)))
                continue
            if len(run) >= 2:
                ways.append(([r[0] for r in run], [r[1] for r in run], w.tags.get("lanes")))
            run = []
    by_first = collections.defaultdict(list)
    for k, (ids, _, _) in enumerate(ways):
        by_first[ids[0]].append(k)

    def chain_from(k):
        seq, seen = [k], {k}
        while True:
            nxt = [j for j in by_first.get(ways[seq[-1]][0][-1], []) if j not in seen]
            if not nxt:
                return seq
            seq.append(nxt[0])
            seen.add(nxt[0])

    from roadtwin.frames import MappingFrame, Origin

    best, best_len = None, -1.0
    for k in range(len(ways)):
        seq = chain_from(k)
        ll = np.array([p for j in seq for p in ways[j][1]])
        fr = MappingFrame(Origin(float(ll[0, 1]), float(ll[0, 0]), 0.0))
        xy = np.column_stack(fr.from_lonlat(ll[:, 0], ll[:, 1]))
        length = float(np.hypot(*np.diff(xy, axis=0).T).sum())
        if length > best_len:
            best, best_len = seq, length
    ll = np.array([p for j in best for p in ways[j][1]])
    keep = np.concatenate([[True], np.any(np.diff(ll, axis=0) != 0, axis=1)])
    tags = [ways[j][2] for j in best if ways[j][2]]
    lanes = int(collections.Counter(tags).most_common(1)[0][0]) if tags else 2
    return ll[keep], min(max(lanes, 2), 4)


def make_osm_run(osm_path: Path, out: Path, *, seed: int = 3) -> Path:
    """Simulate a run along the longest motorway chain of a real OSM extract.

    The mainline follows the chain's smoothed shape (clothoid fit, reference line = left
    road edge for right-hand traffic), no simulated ramps (so every built ramp comes from the
    real OSM links), the map input is the real extract itself.
    """
    from roadtwin.frames import MappingFrame, Origin
    from roadtwin.simulate import simulate_run
    from roadtwin.simulate.from_osm import fit_clothoids, smooth_polyline
    from roadtwin.simulate.scenario import scenario_from_dict

    lonlat, lanes = motorway_chain(osm_path)
    lat0, lon0 = float(lonlat[0, 1]), float(lonlat[0, 0])
    frame = MappingFrame(Origin(lat0, lon0, 10.0))
    xy = np.column_stack(frame.from_lonlat(lonlat[:, 0], lonlat[:, 1]))
    sm, hdg, s = smooth_polyline(xy, window_m=120.0)
    off = 0.75 + lanes * 3.75 / 2.0
    edge = sm + off * np.column_stack([-np.sin(hdg), np.cos(hdg)])
    lo, hi = 60.0, min(s[-1] - 60.0, 60.0 + 3000.0)
    pick = (s >= lo) & (s <= hi)
    esm, ehdg, es = smooth_polyline(edge[pick], window_m=60.0)
    elems = fit_clothoids(es, ehdg, knot_spacing_m=60.0, start_heading=float(ehdg[0]))
    data = {
        "name": f"osm_{osm_path.name.split('.')[0]}",
        "seed": seed,
        "origin": {"lat": lat0, "lon": lon0, "alt": 10.0},
        "traffic": {"side": "right"},
        "start": {
            "x": float(esm[0, 0]),
            "y": float(esm[0, 1]),
            "heading_deg": float(np.degrees(ehdg[0])),
        },
        "alignment": [
            {"type": "clothoid", "length": ln, "curvature_start": k0, "curvature_end": k1}
            for ln, k0, k1 in elems
        ],
        "lanes": {"count": lanes, "width": 3.75, "inner_shoulder": 0.75, "hard_shoulder": 2.5},
        "opposite": {"enabled": False},
        "car": {"speed_kmh": 100},
        "output": {"road_edges_format": "laz", "real_osm": str(osm_path)},
    }
    sc = scenario_from_dict(data, name=data["name"])
    simulate_run(sc, out)
    # the simulator names a real .osm.pbf / .osm.bz2 "map.pbf" / "map.bz2" (not a section 3
    # suffix): give it a valid name
    toml = (out / "run.toml").read_text(encoding="utf-8")
    for bad, good in (("map.pbf", "map.osm.pbf"), ("map.bz2", "map.osm.bz2")):
        if (out / bad).is_file():
            (out / bad).replace(out / good)
            toml = toml.replace(f'"{bad}"', f'"{good}"')
    (out / "run.toml").write_text(toml, encoding="utf-8")
    return out


# ---------------------------------------------------------------------------
# build + evaluate
# ---------------------------------------------------------------------------

_OSM_CACHE: dict = {}


def simulate_base(scenario: str, root: Path, edit: Callable | None = None) -> Path:
    """Simulate a bundled scenario (optionally edited) into ``root``."""
    from roadtwin.simulate import load_scenario, simulate_run

    sc = load_scenario(scenario)
    if edit is not None:
        sc = edit(sc)
    return simulate_run(sc, root)


def build_and_evaluate(run_dir: Path, out_dir: Path, *, roundtrip: bool = True) -> dict:
    """Build ``run_dir`` into ``out_dir/map.xodr`` and evaluate it against its truth.

    With ``roundtrip=False`` (fast tests) the built network is evaluated in memory: no
    xodr written and read back, no ``check_network``.
    """
    from roadtwin.check import check_network
    from roadtwin.evaluation import evaluate, evaluate_paths, load_truth
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map
    from roadtwin.xodr import write_xodr

    row: dict = {"ok": False, "error": ""}
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            run = load_run(run_dir)
            graph = None
            if run.osm_path is not None:
                key = (
                    hashlib.sha1(run.osm_path.read_bytes()).hexdigest(),
                    run.frame.geo_reference,
                    run.frame.crs,
                )
                if key not in _OSM_CACHE:
                    _OSM_CACHE[key] = load_osm(
                        run.osm_path, frame=run.frame, around_xy=run.trajectory.xy
                    )
                graph = _OSM_CACHE[key]
            result = build_map(run, graph)
            if roundtrip:
                out_dir.mkdir(parents=True, exist_ok=True)
                write_xodr(result.network, out_dir / "map.xodr")
                findings = check_network(result.network)
                row["check_errors"] = sum(f.severity == "error" for f in findings)
                row["check_codes"] = sorted({f.code for f in findings if f.severity == "error"})
                rep = evaluate_paths(out_dir / "map.xodr", [run_dir]).runs[0]
            else:
                truth, info = load_truth(run_dir / "truth.xodr")
                rep = evaluate(result.network, run, truth=truth, truth_info=info).runs[0]
            t = rep.truth or {}
            topo = rep.topology or {}
            spikes = 0
            for k in ("truth/road_edge", "truth/lane_boundary"):
                if k in rep.details:
                    spikes += int(np.count_nonzero(np.abs(rep.details[k].error_m) > 0.5))
            row.update(
                ok=True,
                network=result.network,
                frame=run.frame,
                edge_rmse=(t.get("road_edge") or {}).get("rmse_m"),
                edge_p95=(t.get("road_edge") or {}).get("p95_m"),
                lane_rmse=(t.get("lane_boundary") or {}).get("rmse_m"),
                lane_p95=(t.get("lane_boundary") or {}).get("p95_m"),
                spikes=spikes,
                elev_rmse=(t.get("elevation") or {}).get("rmse_m"),
                lane_count=(t.get("lane_count") or {}).get("matched_fraction"),
                ramps=f"{topo.get('matched', '?')}/{topo.get('true_ramps', '?')}"
                + (f" +{len(topo['spurious'])}" if topo.get("spurious") else ""),
                ramps_matched=topo.get("matched"),
                ramps_true=topo.get("true_ramps"),
                typed=topo.get("type_correct"),
            )
        except Exception as exc:
            row["error"] = f"{type(exc).__name__}: {' '.join(str(exc).split())}"[:300]
            row["trace"] = traceback.format_exc(limit=6)
    row["warnings"] = [" ".join(str(w.message).split())[:160] for w in caught][:3]
    row["time_s"] = time.perf_counter() - t0
    return row


def mainline_points(network, step_m: float = 1.0) -> np.ndarray:
    """Points every ``step_m`` on every boundary of the mainline roads (mapping frame)."""
    from roadtwin.evaluation.frenet import section_boundaries

    pts = []
    for road in network.roads:
        if road.name != "mainline":
            continue
        s_all = np.arange(0.5, road.length - 0.5, step_m)
        sec_idx = road.section_index(s_all)
        for k in np.unique(sec_idx):
            s = s_all[sec_idx == k]
            for _, lid in section_boundaries(road.lane_sections[int(k)]):
                pts.append(road.to_xy(s, road.lane_border_t(s, lid)).reshape(-1, 2))
    return np.vstack(pts) if pts else np.zeros((0, 2))


def shift_vs_base(base_row: dict, row: dict) -> tuple[float, float] | None:
    """Median and p95 distance (m) from the base build's mainline boundaries (moved into the
    variant's frame with pyproj, exactly) to the variant build's mainline boundaries."""
    import shapely
    from pyproj import Transformer

    from roadtwin.evaluation.frenet import section_boundaries

    if not (base_row.get("ok") and row.get("ok")):
        return None
    pts = mainline_points(base_row["network"])
    if row.get("rotation"):
        c, s = np.cos(row["rotation"]), np.sin(row["rotation"])
        pts = pts @ np.array([[c, s], [-s, c]])
    bf, vf = base_row["frame"], row["frame"]
    if bf.geo_reference != vf.geo_reference:
        tr = Transformer.from_crs(bf._crs, vf._crs, always_xy=True)
        pts = np.column_stack(tr.transform(pts[:, 0], pts[:, 1]))
    lines = []
    for road in row["network"].roads:
        if road.name != "mainline":
            continue
        s_all = np.linspace(0.0, road.length, max(int(road.length / 0.5), 2))
        sec_idx = road.section_index(s_all)
        for k in np.unique(sec_idx):
            s = s_all[sec_idx == k]
            if s.size < 2:
                continue
            for _, lid in section_boundaries(road.lane_sections[int(k)]):
                lines.append(shapely.LineString(road.to_xy(s, road.lane_border_t(s, lid))))
    d = shapely.distance(shapely.points(pts), shapely.MultiLineString(lines))
    return float(np.median(d)), float(np.percentile(d, 95))


def run_variant(
    base: RunData, name: str, root: Path, seed: int = 0, *, roundtrip: bool = True
) -> dict:
    """Write variant ``name`` of ``base`` under ``root`` and build + evaluate it."""
    rng = np.random.default_rng(seed)
    try:
        rd = VARIANTS[name](base, rng)
        run_dir = write_run(rd, root / name)
    except Exception as exc:
        return {"ok": False, "error": f"variant not written: {type(exc).__name__}: {exc}"}
    row = build_and_evaluate(run_dir, root / name / "out", roundtrip=roundtrip)
    if name.startswith("rotated"):
        row["rotation"] = rd.truth_xform[0]
    if "truth_residual_m" in rd.csv_style:
        row["note"] = f"truth transform residual {rd.csv_style['truth_residual_m'] * 1000:.1f} mm"
    return row


def _f(v, digits=3) -> str:
    return "-" if v is None or v != v else f"{v:.{digits}f}"


def format_row(scenario: str, name: str, row: dict) -> str:
    if not row.get("ok"):
        return f"| {scenario} | {name} | ERROR: {row.get('error', '')[:200]} | | | | | | | |"
    shift = row.get("shift")
    codes = ",".join(row["check_codes"])
    return (
        f"| {scenario} | {name} | ok | {row['ramps']} | {_f(row['edge_rmse'])} / "
        f"{_f(row['edge_p95'])} | {_f(row['lane_rmse'])} / {_f(row['lane_p95'])} | "
        f"{row['spikes']} | {_f(row['elev_rmse'])} | "
        f"{'-' if shift is None else _f(shift[0]) + ' / ' + _f(shift[1])} | "
        f"{row['check_errors']}{' ' + codes if codes else ''} | {row['time_s']:.1f} |"
    )


HEADER = (
    "| scenario | variant | build | ramps matched/true | edge RMSE / p95 m | "
    "lane RMSE / p95 m | pts > 0.5 m | elev RMSE m | shift vs base p50 / p95 m | "
    "check errors | time s |\n|---|---|---|---|---|---|---|---|---|---|---|"
)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", nargs="*", default=list(SCENARIOS))
    p.add_argument("--only", nargs="*", default=None, help="variant names (default: all)")
    p.add_argument("--workdir", type=Path, default=None)
    p.add_argument("--markdown", type=Path, default=None, help="also write the table here")
    p.add_argument("--verbose", action="store_true", help="print tracebacks of failures")
    p.add_argument(
        "--real-osm",
        nargs="*",
        type=Path,
        default=[REAL_OSM / "kotka-e18.osm.pbf", REAL_OSM / "west-oakland-i880.osm.bz2"],
        help="real OSM extracts to drive a simulated run along (their longest motorway)",
    )
    args = p.parse_args(argv)
    root = args.workdir or Path(tempfile.mkdtemp(prefix="roadtwin-robust-"))
    names = args.only or list(VARIANTS) + list(SCENARIO_VARIANTS)
    lines = [HEADER]
    print(HEADER, flush=True)
    for scenario in args.scenario:
        base_dir = root / scenario / "_base"
        if not (base_dir / "run.toml").is_file():
            simulate_base(scenario, base_dir)
        base = read_base(base_dir)
        base_row = None
        for name in names:
            if name in SCENARIO_VARIANTS:
                d = root / scenario / name
                simulate_base(scenario, d, SCENARIO_VARIANTS[name])
                row = build_and_evaluate(d, d / "out")
            elif name in VARIANTS:
                row = run_variant(base, name, root / scenario)
            else:
                continue
            if name == "baseline":
                base_row = row
            if base_row is not None and not name.startswith("crop"):
                row["shift"] = shift_vs_base(base_row, row)
            line = format_row(scenario, name, row)
            if row.get("note"):
                line += f" {row['note']}"
            lines.append(line)
            print(line, flush=True)
            if args.verbose and row.get("trace"):
                print(row["trace"])
    for osm in args.real_osm:
        d = root / f"real_{osm.name.split('.')[0]}"
        try:
            make_osm_run(osm, d)
            row = build_and_evaluate(d, d / "out")
        except Exception as exc:
            row = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        line = format_row(d.name, "real OSM map + motorway", row)
        lines.append(line)
        print(line, flush=True)
        if args.verbose and row.get("trace"):
            print(row["trace"])
    if args.markdown:
        args.markdown.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"variant folders: {root}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
