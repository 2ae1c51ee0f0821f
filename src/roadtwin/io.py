"""Mapping-run loading and validation (DESIGN.md section 3).

A run folder holds ``run.toml`` and the files it names. :func:`load_run` reads them into
one :class:`MappingRun` of NumPy arrays in the mapping frame. File formats (CSV tables,
road-edge point clouds) are parsed in :mod:`roadtwin.pointfiles`; this module checks the
manifest, the trajectory and the lane samples, and transforms the samples into the
mapping frame. Point files are read in chunks and each chunk goes straight into the
density reduction (:mod:`roadtwin.reduction`): a run of tens of millions of points never
sits in memory, and what the later stages get is at most a few rows per metre of each line
(sparse runs pass unchanged). Everything is vectorised; bad input raises
:class:`~roadtwin._errors.InputError` with one line naming the file, row or field and what
was expected; suspicious but usable input warns with :class:`~roadtwin._errors.InputWarning`.
"""

from __future__ import annotations

import logging
import math
import os
import warnings
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ._errors import InputError, InputWarning
from .config import LoadConfig
from .frames import MappingFrame, Origin
from .pointfiles import (
    EDGE_SUFFIXES,
    check_coordinates,
    count_road_edges,
    float_column,
    int_column,
    iter_road_edges,
    iter_table,
    one_line,
    read_road_edges,
    read_table,
    require_columns,
    stack_columns,
)
from .progress import progress
from .reduction import CellAccumulator, Reduction, TrajectoryLine, trajectory_line

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

log = logging.getLogger(__name__)

__all__ = [
    "MappingRun",
    "RunSummary",
    "Trajectory",
    "iter_lane_samples",
    "load_run",
    "read_lane_samples",
    "read_road_edges",
    "read_trajectory",
    "reduce_run",
]


@dataclass(frozen=True, repr=False)
class Trajectory:
    """Vehicle poses, one per LiDAR frame, sorted by ``t``.

    Attributes
    ----------
    frame : (N,) int64 frame indices (unique).
    t : (N,) float64 seconds (any epoch), strictly increasing.
    xyz : (N, 3) float64 pose position, mapping frame, metres (z as in the file).
    yaw : (N,) float64 radians CCW from +x, unwrapped (continuous).
    pitch, roll : (N,) float64 radians, zeros where the file has none.
    """

    frame: NDArray[np.int64]
    t: NDArray[np.float64]
    xyz: NDArray[np.float64]
    yaw: NDArray[np.float64]
    pitch: NDArray[np.float64]
    roll: NDArray[np.float64]

    @property
    def xy(self) -> NDArray[np.float64]:
        """(N, 2) pose positions, mapping frame, metres."""
        return self.xyz[:, :2]

    def __repr__(self) -> str:
        return f"Trajectory({self.frame.size} poses, {self.length_m:.1f} m)"

    @property
    def length_m(self) -> float:
        """Driven length along the poses (metres)."""
        return float(np.sum(np.linalg.norm(np.diff(self.xy, axis=0), axis=1)))


@dataclass(frozen=True)
class RunSummary:
    """Counts and extents of a run, for ``roadtwin inspect`` and logs."""

    driven_length_m: float
    duration_s: float
    frames: int
    edge_points: int
    lane_samples: int
    dropped_edge_points: int
    dropped_lane_samples: int
    bbox_m: tuple[float, float, float, float]  # xmin, ymin, xmax, ymax (mapping frame)
    crs: str
    traffic_side: str


@dataclass(frozen=True, repr=False)
class MappingRun:
    """Everything a mapping run provides, in the mapping frame.

    Attributes
    ----------
    root : folder of the run.
    frame : the mapping frame (origin, CRS, geoReference, WGS84 transforms).
    trajectory : vehicle poses.
    pose_height_m : height of the pose point above the road surface (metres).
    edges : (N, 3) road-edge points, mapping frame, metres.
    edge_side : (N,) int8, +1 left edge, -1 right edge, 0 unknown (no ``side`` column).
    lane_samples : (M, 3) lane-marking samples transformed to the mapping frame, metres;
        z is the pose z plus the sample's ego z (pose z minus pose_height if no ego z).
    lane_sample_frame : (M,) int64 frame index of each sample (nearest pose for ``t`` rows).
    osm_path : OSM file named in run.toml, or None.
    traffic_side : ``"right"`` or ``"left"``-hand traffic.
    input_files : run.toml and every file it names (outputs must never replace them).
    edge_reduction, lane_reduction : how dense points were reduced to the rows above
        (:class:`~roadtwin.reduction.Reduction`: points read, rows, density, the spread
        of the points behind each row), or None for points that were never looked at
        (a run built in memory; :func:`reduce_run` reduces it).
    heading_bias_removed : whether the lane samples were turned back by the poses'
        heading error already (:func:`roadtwin.heading_bias.remove_heading_bias`).
    """

    root: Path
    frame: MappingFrame
    trajectory: Trajectory
    pose_height_m: float
    edges: NDArray[np.float64]
    edge_side: NDArray[np.int8]
    lane_samples: NDArray[np.float64]
    lane_sample_frame: NDArray[np.int64]
    osm_path: Path | None
    traffic_side: Literal["right", "left"] = "right"
    dropped_edge_points: int = 0
    dropped_lane_samples: int = 0
    input_files: tuple[Path, ...] = ()
    edge_reduction: Reduction | None = None
    lane_reduction: Reduction | None = None
    heading_bias_removed: bool = False

    def __repr__(self) -> str:
        s = self.summary()
        return (
            f"MappingRun({str(self.root)!r}, {s.driven_length_m / 1000:.3f} km, "
            f"{s.frames} poses, {s.edge_points} edge points, {s.lane_samples} lane samples, "
            f"crs={self.frame.crs!r}, traffic_side={self.traffic_side!r})"
        )

    def summary(self) -> RunSummary:
        """Counts (points read, not rows kept), driven length, duration and bounding box."""
        xy = np.vstack([self.trajectory.xy, self.edges[:, :2]])
        er, lr = self.edge_reduction, self.lane_reduction
        return RunSummary(
            driven_length_m=self.trajectory.length_m,
            duration_s=float(self.trajectory.t[-1] - self.trajectory.t[0]),
            frames=int(self.trajectory.frame.size),
            edge_points=int(er.points if er is not None else self.edges.shape[0]),
            lane_samples=int(lr.points if lr is not None else self.lane_samples.shape[0]),
            dropped_edge_points=self.dropped_edge_points,
            dropped_lane_samples=self.dropped_lane_samples,
            bbox_m=(
                float(xy[:, 0].min()),
                float(xy[:, 1].min()),
                float(xy[:, 0].max()),
                float(xy[:, 1].max()),
            ),
            crs=self.frame.crs,
            traffic_side=self.traffic_side,
        )


# ---------------------------------------------------------------------------
# loading
# ---------------------------------------------------------------------------

TRAJECTORY_COLUMNS = ("frame", "t", "x", "y", "z", "yaw")
OSM_SUFFIXES = (".osm", ".osm.gz", ".osm.bz2", ".osm.pbf")
_MIN_MOTION_STEP_M = 0.2
_MOTION_BASELINE_M = 2.0
_MAX_YAW_ERROR_DEG = 15.0
"""Largest median difference between yaw and the direction of travel (degrees); a vehicle's
heading follows its track to within a few degrees (side slip, antenna offsets)."""
_MAX_POSE_HEIGHT_M = 10.0


@dataclass(frozen=True, repr=False)
class RunHeader:
    """What a mapping-run folder says before its points are read.

    Attributes
    ----------
    root, manifest_path : the run folder and its ``run.toml``.
    frame : the mapping frame.
    trajectory : the poses (mapping frame, metres, radians), validated.
    pose_height_m : height of the pose point above the road (metres).
    traffic_side : ``"right"`` or ``"left"``.
    files : the input files named in ``run.toml`` (``trajectory``, ``road_edges``,
        ``lane_samples``, optional ``osm``).
    """

    root: Path
    manifest_path: Path
    frame: MappingFrame
    trajectory: Trajectory
    pose_height_m: float
    traffic_side: Literal["right", "left"]
    files: dict[str, Path]

    @property
    def osm_path(self) -> Path | None:
        """The OSM file named in ``run.toml``, or None."""
        return self.files.get("osm")


def read_run_header(run_dir: str | Path, *, config: LoadConfig | None = None) -> RunHeader:
    """Read and validate ``run.toml`` and the trajectory of a run folder, not its points.

    What a later stage needs before the points (the frame, the trajectory, the OSM file)
    at the cost of reading the trajectory.
    Raises :class:`~roadtwin._errors.InputError` as :func:`load_run` does.
    """
    cfg = config if config is not None else LoadConfig()
    root = Path(run_dir)
    if root.is_file() and root.suffix == ".toml":
        manifest_path, root = root, root.parent
    else:
        manifest_path = root / "run.toml"
    if not root.is_dir():
        what = "not a folder" if root.exists() else "folder not found"
        msg = f"{root}: {what} (expected a mapping-run folder with run.toml, or its run.toml)"
        raise InputError(msg)
    manifest = _read_manifest(manifest_path)
    frame = _frame_from_manifest(manifest, manifest_path)
    pose_height = _number(manifest, "vehicle", "pose_height", manifest_path, default=0.0)
    if abs(pose_height) > _MAX_POSE_HEIGHT_M:
        msg = (
            f"{manifest_path}: [vehicle] pose_height = {pose_height:g}: expected the height of "
            f"the pose point above the road in metres (at most {_MAX_POSE_HEIGHT_M:g})"
        )
        raise InputError(msg)
    side = _traffic_side(manifest, manifest_path)
    files = _files_from_manifest(manifest, manifest_path, root, cfg)

    trajectory = read_trajectory(files["trajectory"], config=cfg)
    _check_origin_distance(trajectory, frame, files["trajectory"], manifest_path, cfg)
    return RunHeader(root, manifest_path, frame, trajectory, pose_height, side, files)


def load_run(
    run_dir: str | Path, *, config: LoadConfig | None = None, reduce: bool = True
) -> MappingRun:
    """Load and validate a mapping-run folder (DESIGN.md section 3).

    Parameters
    ----------
    run_dir
        Folder holding ``run.toml`` (or the path of the ``run.toml`` itself).
    config
        Loading thresholds and the density reduction; :class:`~roadtwin.config.LoadConfig`
        defaults if None.
    reduce
        Reduce dense point files to ``config.edge_points_per_m`` /
        ``config.lane_samples_per_m`` rows per metre of each line
        (:mod:`roadtwin.reduction`; runs below ``config.reduce_factor`` times that pass
        unchanged). ``False`` keeps every point (memory grows with the files).

    Returns
    -------
    MappingRun
        Poses, road-edge points and lane samples in the mapping frame (metres, radians).
        Points farther than ``config.max_point_distance_m`` from the trajectory are dropped
        with an :class:`~roadtwin._errors.InputWarning` and counted in ``dropped_*``.

    Raises
    ------
    InputError
        With one line naming the file, row or field and what was expected.
    """
    cfg = config if config is not None else LoadConfig()
    header = read_run_header(run_dir, config=cfg)
    root, manifest_path, files = header.root, header.manifest_path, header.files
    frame, trajectory, side = header.frame, header.trajectory, header.traffic_side
    pose_height = header.pose_height_m
    line = trajectory_line(trajectory.xy)
    edge_acc = _accumulator(line, cfg, kind="edges", reduce=reduce, n_groups=3)
    edge_path = files["road_edges"]
    with progress("load road edges", total=count_road_edges(edge_path), unit="points") as step:
        dropped_e = _stream(
            (
                (c.xyz, c.side.astype(np.int64) + 1, None, c.first_row)
                for c in iter_road_edges(
                    edge_path, chunk_points=cfg.chunk_points, max_points=cfg.max_points
                )
            ),
            edge_acc,
            edge_path,
            "road-edge points",
            cfg,
            step,
        )
    lane_acc = _accumulator(line, cfg, kind="lanes", reduce=reduce, n_groups=1)
    lane_path = files["lane_samples"]
    with progress("load lane samples", unit="samples") as step:
        dropped_l = _stream(
            (
                (xyz, np.zeros(len(xyz), np.int64), frames, row)
                for xyz, frames, row in iter_lane_samples(
                    lane_path,
                    trajectory,
                    pose_height_m=pose_height,
                    chunk_rows=cfg.chunk_points,
                    max_rows=cfg.max_points,
                )
            ),
            lane_acc,
            lane_path,
            "lane samples",
            cfg,
            step,
        )
    factor = cfg.reduce_factor if reduce else math.inf
    edge_rows = edge_acc.finish(target_per_m=cfg.edge_points_per_m, reduce_factor=factor)
    lane_rows = lane_acc.finish(
        target_per_m=cfg.lane_samples_per_m,
        reduce_factor=factor,
        payload_of_vertex=_vertex_frames(line, trajectory),
    )
    edges, edge_side = edge_rows.xyz, (edge_rows.group - 1).astype(np.int8)
    lane_samples, lane_frame = lane_rows.xyz, lane_rows.payload
    for what, rows in (("road edges", edge_rows), ("lane samples", lane_rows)):
        log.info("%s: %s", what, rows.info.describe())

    run = MappingRun(
        root=root,
        frame=frame,
        trajectory=trajectory,
        pose_height_m=pose_height,
        edges=edges,
        edge_side=edge_side,
        lane_samples=lane_samples,
        lane_sample_frame=lane_frame,
        osm_path=files.get("osm"),
        traffic_side=side,
        dropped_edge_points=dropped_e,
        dropped_lane_samples=dropped_l,
        input_files=(manifest_path, *files.values()),
        edge_reduction=edge_rows.info,
        lane_reduction=lane_rows.info,
    )
    s = run.summary()
    log.info(
        "loaded run %s: %.3f km, %d frames, %d edge points, %d lane samples "
        "(dropped %d / %d far from the trajectory)",
        root,
        s.driven_length_m / 1000.0,
        s.frames,
        s.edge_points,
        s.lane_samples,
        dropped_e,
        dropped_l,
    )
    return run


# ---------------------------------------------------------------------------
# run.toml
# ---------------------------------------------------------------------------


def _read_manifest(path: Path) -> dict[str, Any]:
    if not path.is_file():
        what = "not a file" if path.exists() else "file not found"
        msg = f"{path}: {what} (expected the run manifest run.toml in the run folder)"
        raise InputError(msg)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        msg = f"{path}: cannot read the run manifest ({one_line(exc)})"
        raise InputError(msg) from None
    if not text.strip():
        msg = f"{path}: file is empty (expected [origin], [frame] and [files] tables)"
        raise InputError(msg)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        msg = f"{path}: not valid TOML: {one_line(exc)}"
        raise InputError(msg) from None


def _table(manifest: dict[str, Any], name: str, path: Path, *, required: bool) -> dict:
    table = manifest.get(name)
    if table is None:
        if required:
            msg = f"{path}: missing table [{name}]"
            raise InputError(msg)
        return {}
    if not isinstance(table, dict):
        msg = f"{path}: [{name}] must be a table"
        raise InputError(msg)
    return table


def _number(
    manifest: dict[str, Any],
    table: str,
    key: str,
    path: Path,
    *,
    default: float | None = None,
) -> float:
    values = _table(manifest, table, path, required=default is None)
    if key not in values:
        if default is None:
            msg = f"{path}: [{table}] {key} is missing (expected a number)"
            raise InputError(msg)
        return default
    value = values[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        msg = f"{path}: [{table}] {key} = {value!r}: expected a finite number"
        raise InputError(msg)
    return float(value)


def _frame_from_manifest(manifest: dict[str, Any], path: Path) -> MappingFrame:
    lat = _number(manifest, "origin", "lat", path)
    lon = _number(manifest, "origin", "lon", path)
    alt = _number(manifest, "origin", "alt", path, default=0.0)
    crs = _table(manifest, "frame", path, required=False).get("crs", "local")
    if not isinstance(crs, str) or not crs.strip():
        msg = f"{path}: [frame] crs = {crs!r}: expected 'local' or a pyproj CRS string"
        raise InputError(msg)
    try:
        origin = Origin(lat, lon, alt)
        return MappingFrame(origin, crs=crs.strip())
    except InputError as exc:
        msg = f"{path}: {one_line(exc)}"
        raise InputError(msg) from None


def _traffic_side(manifest: dict[str, Any], path: Path) -> Literal["right", "left"]:
    side = _table(manifest, "traffic", path, required=False).get("side", "right")
    if side not in ("right", "left"):
        msg = f"{path}: [traffic] side = {side!r}: expected 'right' or 'left'"
        raise InputError(msg)
    return side


def _files_from_manifest(
    manifest: dict[str, Any], path: Path, root: Path, cfg: LoadConfig
) -> dict[str, Path]:
    table = _table(manifest, "files", path, required=True)
    files: dict[str, Path] = {}
    real_root = Path(os.path.realpath(root))
    for key in ("trajectory", "road_edges", "lane_samples", "osm"):
        name = table.get(key)
        if name is None:
            if key == "osm":
                continue
            msg = f"{path}: [files] {key} is missing (expected a file name relative to the run)"
            raise InputError(msg)
        if not isinstance(name, str) or not name.strip():
            msg = f"{path}: [files] {key}: expected a file name (a string)"
            raise InputError(msg)
        file = root / name
        shown = name if len(name) <= 80 else name[:77] + "..."
        real = Path(os.path.realpath(file))
        if not cfg.allow_files_outside_run and not real.is_relative_to(real_root):
            msg = (
                f"{path}: [files] {key} = {shown!r} lies outside the run folder {root} "
                "(a run's files must be inside its folder; [load] allow_files_outside_run = "
                "true allows it)"
            )
            raise InputError(msg)
        if not file.exists():
            msg = f"{file}: file not found (named by [files] {key} in {path.name})"
            raise InputError(msg)
        if not file.is_file():
            msg = f"{file}: not a regular file (named by [files] {key} in {path.name})"
            raise InputError(msg)
        files[key] = file
    edge_name = files["road_edges"].name.lower()
    if not edge_name.endswith(EDGE_SUFFIXES):
        msg = (
            f"{files['road_edges']}: unsupported road-edge format "
            f"(expected one of {', '.join(EDGE_SUFFIXES)})"
        )
        raise InputError(msg)
    if "osm" in files:
        osm = files["osm"]
        if not osm.name.lower().endswith(OSM_SUFFIXES):
            msg = f"{osm}: unsupported OSM format (expected one of {', '.join(OSM_SUFFIXES)})"
            raise InputError(msg)
        if osm.stat().st_size == 0:
            msg = f"{osm}: OSM file is empty"
            raise InputError(msg)
    return files


# ---------------------------------------------------------------------------
# trajectory
# ---------------------------------------------------------------------------


def read_trajectory(path: str | Path, *, config: LoadConfig | None = None) -> Trajectory:
    """Read and validate ``trajectory.csv`` (``frame,t,x,y,z,yaw[,pitch,roll]``).

    Parameters
    ----------
    path
        CSV file with a header; any column order, extra columns ignored.
    config
        Thresholds for the jump check.

    Returns
    -------
    Trajectory
        Mapping-frame poses (metres), yaw unwrapped (radians, CCW from +x).

    Raises
    ------
    InputError
        Missing columns, NaN/inf, duplicate frames or times, yaw in degrees or
        not matching the direction of travel, jumps.
    """
    cfg = config if config is not None else LoadConfig()
    path = Path(path)
    what = "columns frame,t,x,y,z,yaw[,pitch,roll]"
    df = read_table(path, what, max_rows=cfg.max_poses)
    require_columns(df.columns, TRAJECTORY_COLUMNS, path, what)
    frame = int_column(df["frame"], path, "frame")
    t = float_column(df["t"], path, "t")
    xyz = np.column_stack([float_column(df[c], path, c) for c in ("x", "y", "z")])
    check_coordinates(xyz, path)
    yaw = float_column(df["yaw"], path, "yaw")
    n = t.size
    pitch = float_column(df["pitch"], path, "pitch") if "pitch" in df else np.zeros(n)
    roll = float_column(df["roll"], path, "roll") if "roll" in df else np.zeros(n)

    order = np.argsort(frame, kind="stable")
    dup = np.flatnonzero(np.diff(frame[order]) == 0)
    if dup.size:
        rows = sorted((int(order[dup[0]]) + 1, int(order[dup[0] + 1]) + 1))
        msg = (
            f"{path}: duplicate frame {frame[order[dup[0]]]} in data rows {rows[0]} and "
            f"{rows[1]} ({dup.size} duplicate(s); expected one row per frame)"
        )
        raise InputError(msg)
    if n < 2:
        msg = f"{path}: only {n} pose(s); expected at least 2 rows"
        raise InputError(msg)
    # Section 3 does not require rows in time order: sort them, then every pose time
    # must be distinct.
    by_time = np.argsort(t, kind="stable")
    t, frame, xyz, yaw = t[by_time], frame[by_time], xyz[by_time], yaw[by_time]
    pitch, roll = pitch[by_time], roll[by_time]
    dt = np.diff(t)
    if (dt <= 0).any():
        k = int(np.argmax(dt <= 0))
        rows = sorted((int(by_time[k]) + 1, int(by_time[k + 1]) + 1))
        msg = (
            f"{path}: data rows {rows[0]} and {rows[1]}, column 't': both at {t[k]} s "
            "(expected one pose per time stamp)"
        )
        raise InputError(msg)
    _check_motion(path, xyz[:, :2], t, cfg)
    _check_yaw(path, xyz[:, :2], yaw)
    _check_jumps(path, xyz[:, :2], t, cfg)
    return Trajectory(
        frame=frame,
        t=t,
        xyz=xyz,
        yaw=np.unwrap(yaw),
        pitch=pitch,
        roll=roll,
    )


def _wrap(angle: NDArray[np.float64]) -> NDArray[np.float64]:
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def _check_motion(
    path: Path, xy: NDArray[np.float64], t: NDArray[np.float64], cfg: LoadConfig
) -> None:
    """The vehicle must drive a plausible distance, in metres.

    A run shorter than ``min_driven_m`` has nothing to map: either the vehicle stood still
    or x/y hold longitude/latitude degrees (steps of 1e-5 that still lead somewhere).
    """
    steps = np.hypot(*np.diff(xy, axis=0).T)
    driven = float(steps.sum())
    duration = float(t[-1] - t[0])
    if driven < cfg.min_driven_m:
        net = float(np.hypot(*(xy.max(axis=0) - xy.min(axis=0))))
        degrees = (  # slow (under 0.01 units/s: 1 km/s in degrees) but going somewhere
            0.0 < driven < 0.01 * max(duration, 1e-9)
            and net > 0.5 * driven
            and bool(np.all(np.abs(xy[:, 0]) <= 180.0) and np.all(np.abs(xy[:, 1]) <= 90.0))
        )
        if degrees:
            msg = (
                f"{path}: columns 'x','y' look like longitude/latitude degrees (the poses "
                f"advance {driven:.2g} units in {duration:.0f} s, within [-180, 180] x "
                "[-90, 90]); expected metres in the mapping frame of run.toml"
            )
        else:
            msg = (
                f"{path}: the vehicle drives only {driven:.2f} m in {duration:.0f} s "
                f"({xy.shape[0]} poses; a standing vehicle?); a mapping run must drive at "
                f"least {cfg.min_driven_m:g} m"
            )
        raise InputError(msg)
    if driven > cfg.max_driven_km * 1000.0:
        msg = (
            f"{path}: the trajectory is {driven / 1000:.0f} km long; runs longer than "
            f"{cfg.max_driven_km:g} km ([load] max_driven_km) are refused: split the run"
        )
        raise InputError(msg)


def _check_yaw(path: Path, xy: NDArray[np.float64], yaw: NDArray[np.float64]) -> None:
    """Yaw must be radians, CCW from +x, along the direction of travel.

    The direction of travel is taken over a baseline of about ``_MOTION_BASELINE_M`` (several
    poses at high pose rates) so that position noise does not dominate it. The median
    difference must stay under ``_MAX_YAW_ERROR_DEG``; a compass heading (clockwise from
    north, ``pi/2 - yaw``) or a reversed yaw is named when it explains the data better.
    """
    seg = np.hypot(*np.diff(xy, axis=0).T)
    typical = float(np.median(seg))
    k = int(min(max(1, np.ceil(_MOTION_BASELINE_M / typical)) if typical > 0 else 1, len(xy) - 1))
    step = xy[k:] - xy[:-k]
    dist = np.hypot(step[:, 0], step[:, 1])
    moving = dist > _MIN_MOTION_STEP_M
    max_abs = float(np.max(np.abs(yaw)))
    if np.count_nonzero(moving) >= 3:
        motion = np.arctan2(step[moving, 1], step[moving, 0])
        y_mid = yaw[:-k][moving]

        def median_error_deg(candidate: NDArray[np.float64]) -> float:
            return float(np.degrees(np.median(np.abs(_wrap(candidate - motion)))))

        err_rad = median_error_deg(y_mid)
        err_deg = median_error_deg(np.radians(y_mid))
        if err_deg < 10.0 and err_rad > max(3.0 * err_deg, 8.0):
            msg = (
                f"{path}: column 'yaw' is in degrees (it matches the direction of travel only "
                f"read as degrees; max |yaw| = {max_abs:.1f}); expected radians, CCW from +x"
            )
            raise InputError(msg)
        compass = median_error_deg(np.pi / 2 - y_mid)
        backwards = median_error_deg(y_mid + np.pi)
        looks_compass = compass < 0.5 * err_rad and compass < _MAX_YAW_ERROR_DEG
        if err_rad > _MAX_YAW_ERROR_DEG or (looks_compass and err_rad > 5.0):
            hint = ""
            if looks_compass:
                hint = " (it looks like a compass heading, clockwise from north: pi/2 - yaw)"
            elif backwards < _MAX_YAW_ERROR_DEG:
                hint = " (it points backwards: off by 180 deg)"
            msg = (
                f"{path}: column 'yaw' does not match the direction of travel (median "
                f"difference {err_rad:.0f} deg, at most {_MAX_YAW_ERROR_DEG:g} expected){hint}; "
                "expected radians, CCW from +x (east)"
            )
            raise InputError(msg)
    elif max_abs > 2.0 * np.pi + 0.1:  # a vehicle that hardly moves cannot turn full circles
        msg = (
            f"{path}: column 'yaw' reaches |yaw| = {max_abs:.1f}, far beyond 2*pi: looks like "
            "degrees; expected radians, CCW from +x"
        )
        raise InputError(msg)


def _check_origin_distance(
    trajectory: Trajectory, frame: MappingFrame, path: Path, manifest: Path, cfg: LoadConfig
) -> None:
    """Poses far from the run's GPS origin mean a wrong CRS, wrong units or a wrong origin."""
    ox, oy = frame.origin_xy
    far = float(np.max(np.hypot(trajectory.xy[:, 0] - ox, trajectory.xy[:, 1] - oy)))
    if far > cfg.max_origin_distance_km * 1000.0:
        o = frame.origin
        msg = (
            f"{path}: poses lie up to {far / 1000:.0f} km from the GPS origin of {manifest} "
            f"(lat {o.lat_deg:g}, lon {o.lon_deg:g}) in crs {frame.crs!r}; expected within "
            f"{cfg.max_origin_distance_km:g} km ([load] max_origin_distance_km): wrong "
            "[frame] crs, units or [origin]?"
        )
        raise InputError(msg)


def _check_jumps(
    path: Path, xy: NDArray[np.float64], t: NDArray[np.float64], cfg: LoadConfig
) -> None:
    dist = np.hypot(*np.diff(xy, axis=0).T)
    dt = np.diff(t)
    median_step = float(np.median(dist))
    median_dt = float(np.median(dt))
    expected = 3.0 * median_step * dt / median_dt
    jump = (dist > cfg.max_pose_jump_m) & (dist > expected)
    if jump.any():
        i = int(np.argmax(jump))
        msg = (
            f"{path}: trajectory jumps {dist[i]:.1f} m between data rows {i + 1} and {i + 2} "
            f"(typical step {median_step:.2f} m; expected steps under "
            f"{max(cfg.max_pose_jump_m, float(expected[i])):.1f} m)"
        )
        raise InputError(msg)


# ---------------------------------------------------------------------------
# lane samples
# ---------------------------------------------------------------------------


def read_lane_samples(
    path: str | Path,
    trajectory: Trajectory,
    *,
    pose_height_m: float = 0.0,
    max_rows: int | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Read lane samples (ego frame) and transform them into the mapping frame.

    Parameters
    ----------
    path
        CSV ``frame,x,y[,z]`` (or ``t,x,y[,z]``): ego frame of that pose, metres; x forward
        along the yaw, y to the left, z up relative to the pose.
    trajectory
        Poses; a ``t`` row takes the pose interpolated in time (yaw unwrapped).
    pose_height_m
        Height of the pose point above the road; used for z when there is no ``z`` column.
    max_rows
        Refuse files with more rows (:attr:`~roadtwin.config.LoadConfig.max_points`).

    Returns
    -------
    xyz : (M, 3) float64 samples, mapping frame, metres. The 2-D transform of the paper:
        rotation by yaw and translation by the pose xy; pitch and roll are not applied.
        z = pose z + ego z, or pose z - pose_height_m without a ``z`` column.
    frame : (M,) int64 frame of each sample (nearest pose in time for ``t`` rows).
    """
    parts = list(
        iter_lane_samples(path, trajectory, pose_height_m=pose_height_m, max_rows=max_rows)
    )
    return np.vstack([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def iter_lane_samples(
    path: str | Path,
    trajectory: Trajectory,
    *,
    pose_height_m: float = 0.0,
    chunk_rows: int = 1_000_000,
    max_rows: int | None = None,
) -> Iterator[tuple[NDArray[np.float64], NDArray[np.int64], int]]:
    """:func:`read_lane_samples` in chunks of ``chunk_rows`` rows (file order).

    Yields ``(xyz, frame, first_row)``: mapping-frame samples, their frames and the data
    row of the chunk's first sample (0-based). The checks name rows of the whole file.
    """
    path = Path(path)
    what = "columns frame,x,y[,z] or t,x,y[,z]"
    traj_frame = trajectory.frame
    order = np.argsort(traj_frame)
    sorted_frames = traj_frame[order]
    row0 = 0
    for df in iter_table(path, what, chunk_rows=chunk_rows, max_rows=max_rows):
        require_columns(df.columns, ("x", "y"), path, what)
        ex = float_column(df["x"], path, "x", first_row=row0)
        ey = float_column(df["y"], path, "y", first_row=row0)
        ez = float_column(df["z"], path, "z", first_row=row0) if "z" in df else None
        check_coordinates(
            np.column_stack([ex, ey] if ez is None else [ex, ey, ez]), path, first_row=row0
        )
        if "frame" in df:
            frame = int_column(df["frame"], path, "frame", first_row=row0)
            pos = np.searchsorted(sorted_frames, frame)
            pos_c = np.minimum(pos, order.size - 1)
            found = sorted_frames[pos_c] == frame
            if not found.all():
                row = int(np.argmin(found))
                missing = np.unique(frame[~found])
                msg = (
                    f"{path}: data row {row0 + row + 1}, column 'frame': frame {frame[row]} "
                    f"has no pose in the trajectory ({missing.size} frame(s) without a pose, "
                    f"{np.count_nonzero(~found)} row(s); expected frames of trajectory.csv)"
                )
                raise InputError(msg)
            idx = order[pos_c]
            px, py, pz = trajectory.xyz[idx].T
            yaw = trajectory.yaw[idx]
        elif "t" in df:
            t = float_column(df["t"], path, "t", first_row=row0)
            t0, t1 = float(trajectory.t[0]), float(trajectory.t[-1])
            slack = float(np.median(np.diff(trajectory.t)))  # one frame interval at either end
            outside = (t < t0 - slack) | (t > t1 + slack)
            if outside.any():
                row = int(np.argmax(outside))
                msg = (
                    f"{path}: data row {row0 + row + 1}, column 't': {t[row]} is outside the "
                    f"trajectory's time span [{t0}, {t1}] ({np.count_nonzero(outside)} row(s); "
                    "no pose to interpolate)"
                )
                raise InputError(msg)
            tt = trajectory.t
            t = np.clip(t, t0, t1)
            px = np.interp(t, tt, trajectory.xyz[:, 0])
            py = np.interp(t, tt, trajectory.xyz[:, 1])
            pz = np.interp(t, tt, trajectory.xyz[:, 2])
            yaw = np.interp(t, tt, trajectory.yaw)  # yaw is unwrapped
            k = np.clip(np.searchsorted(tt, t), 1, tt.size - 1)
            nearest = np.where(t - tt[k - 1] <= tt[k] - t, k - 1, k)
            frame = trajectory.frame[nearest]
        else:
            msg = f"{path}: missing column 'frame' (expected {what})"
            raise InputError(msg)
        c, s = np.cos(yaw), np.sin(yaw)
        x = px + c * ex - s * ey
        y = py + s * ex + c * ey
        z = pz + ez if ez is not None else pz - pose_height_m
        yield stack_columns([x, y, z]), frame.astype(np.int64), row0
        row0 += ex.size


# ---------------------------------------------------------------------------
# distance to the trajectory and density reduction
# ---------------------------------------------------------------------------

# lines (edges, ramp edges, markings) a run may hold side by side: raw points are kept for
# an unchanged pass-through up to this many lines at the reduction threshold's density
_RAW_LINES = 4


def _accumulator(
    line: TrajectoryLine, cfg: LoadConfig, *, kind: str, reduce: bool, n_groups: int
) -> CellAccumulator:
    target = cfg.edge_points_per_m if kind == "edges" else cfg.lane_samples_per_m
    keep_raw = (
        math.inf
        if not reduce
        else cfg.reduce_factor * target * _RAW_LINES * (line.length + 2 * cfg.max_point_distance_m)
    )
    return CellAccumulator(
        line,
        n_groups=n_groups,
        station_bin_m=cfg.cell_station_m,
        lateral_bin_m=cfg.cell_lateral_m,
        max_lateral_m=cfg.max_point_distance_m,
        keep_raw_points=keep_raw,
    )


def _stream(
    chunks: Iterable[tuple[NDArray[np.float64], NDArray[np.int64], Any, int]],
    acc: CellAccumulator,
    path: Path,
    what: str,
    cfg: LoadConfig,
    advance: Callable[[float], object],
) -> int:
    """Feed chunks ``(xyz, group, payload, first_row)`` into ``acc``; returns the number of
    points dropped beyond ``max_point_distance_m`` (warned about, or refused if all).

    The kept points must also spread along the run (at least ``min_driven_m``, or the
    whole run if it is shorter): points that all sit at one spot are no road edge.
    """
    limit = cfg.max_point_distance_m
    total = dropped = 0
    first_far: int | None = None
    lo = np.full(2, np.inf)
    hi = np.full(2, -np.inf)
    for xyz, group, payload, first_row in chunks:
        near = acc.add(xyz, group, payload)
        n_far = int(near.size - np.count_nonzero(near))
        if n_far and first_far is None:
            first_far = first_row + int(np.argmin(near))
        if n_far < near.size:
            kept = xyz[near, :2] if n_far else xyz[:, :2]
            lo = np.minimum(lo, kept.min(axis=0))
            hi = np.maximum(hi, kept.max(axis=0))
        dropped += n_far
        total += near.size
        advance(near.size)
    if total and dropped == total:
        msg = (
            f"{path}: all {dropped} {what} are farther than {limit:g} m from the trajectory "
            "(expected points in the mapping frame of run.toml; wrong CRS or units?)"
        )
        raise InputError(msg)
    span = float(np.hypot(*(hi - lo))) if total else 0.0
    needed = min(cfg.min_driven_m, 0.5 * acc.line.length)
    if span < needed:
        msg = (
            f"{path}: the {what} span only {span:.1f} m, along a {acc.line.length:.0f} m "
            f"trajectory (all at one spot?); expected {what} along the run"
        )
        raise InputError(msg)
    if dropped:
        warnings.warn(
            f"{path}: dropped {dropped} of {total} {what} farther than {limit:g} m from "
            f"the trajectory (first: data row {(first_far or 0) + 1})",
            InputWarning,
            stacklevel=4,
        )
    return dropped


def _vertex_frames(line: TrajectoryLine, trajectory: Trajectory) -> NDArray[np.int64]:
    """Frame of the pose nearest (in station) to every vertex of the trajectory line."""
    seg = np.hypot(*np.diff(trajectory.xy, axis=0).T)
    s_pose = np.concatenate([[0.0], np.cumsum(seg)])
    k = np.clip(np.searchsorted(s_pose, line.s), 1, max(s_pose.size - 1, 1))
    if s_pose.size == 1:
        return np.full(line.s.size, trajectory.frame[0], dtype=np.int64)
    nearest = np.where(line.s - s_pose[k - 1] <= s_pose[k] - line.s, k - 1, k)
    return trajectory.frame[nearest].astype(np.int64)


def reduce_run(run: MappingRun, *, config: LoadConfig | None = None) -> MappingRun:
    """The density reduction of :func:`load_run` for a run built in memory.

    A run whose points went through the reduction already (``edge_reduction`` set) is
    returned as it is; otherwise its edge points and lane samples are counted in cells and,
    if denser than ``config.reduce_factor`` times the targets, replaced by the rows of
    :mod:`roadtwin.reduction` (a sparse run comes back with the same arrays). Points are
    not dropped here (``load_run`` did the distance check).
    """
    if run.edge_reduction is not None and run.lane_reduction is not None:
        return run
    cfg = config if config is not None else LoadConfig()
    line = trajectory_line(run.trajectory.xy)
    # no distance check here: every point stays, far ones in the outermost cells
    wide = replace(cfg, max_point_distance_m=_max_distance(line, run) + 1.0)
    edge_acc = _accumulator(line, wide, kind="edges", reduce=True, n_groups=3)
    lane_acc = _accumulator(line, wide, kind="lanes", reduce=True, n_groups=1)
    step = max(1, cfg.chunk_points)
    for i in range(0, run.edges.shape[0], step):
        edge_acc.add(run.edges[i : i + step], run.edge_side[i : i + step].astype(np.int64) + 1)
    for i in range(0, run.lane_samples.shape[0], step):
        lane_acc.add(
            run.lane_samples[i : i + step],
            np.zeros(min(step, run.lane_samples.shape[0] - i), np.int64),
            run.lane_sample_frame[i : i + step],
        )
    edge_rows = edge_acc.finish(target_per_m=cfg.edge_points_per_m, reduce_factor=cfg.reduce_factor)
    lane_rows = lane_acc.finish(
        target_per_m=cfg.lane_samples_per_m,
        reduce_factor=cfg.reduce_factor,
        payload_of_vertex=_vertex_frames(line, run.trajectory),
    )
    if not edge_rows.info.reduced and not lane_rows.info.reduced:
        return replace(run, edge_reduction=edge_rows.info, lane_reduction=lane_rows.info)
    return replace(
        run,
        edges=edge_rows.xyz,
        edge_side=(edge_rows.group - 1).astype(np.int8),
        lane_samples=lane_rows.xyz,
        lane_sample_frame=lane_rows.payload,
        edge_reduction=edge_rows.info,
        lane_reduction=lane_rows.info,
    )


def _max_distance(line: TrajectoryLine, run: MappingRun) -> float:
    """Largest distance of any run point from the trajectory line's vertices (metres)."""
    far = 0.0
    for pts in (run.edges, run.lane_samples):
        if pts.shape[0]:
            d, _ = line.tree.query(np.asarray(pts)[:, :2], workers=-1)
            far = max(far, float(np.max(d)))
    return far
