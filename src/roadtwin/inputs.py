"""The inputs of a build: mapping runs in one mapping frame, and the OSM graph around them.

Runs may come in different mapping frames (origins, CRS): everything goes to the first
run's frame (:func:`run_in_frame`, pyproj through WGS84). :func:`load_runs_and_osm` reads
the runs and then the OSM extract around their trajectories.

Coordinates are mapping-frame metres.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .config import LoadConfig
from .frames import MappingFrame
from .io import MappingRun

FloatArray = NDArray[np.float64]

__all__ = [
    "load_osm_around",
    "load_runs",
    "load_runs_and_osm",
    "points_in_frame",
    "run_in_frame",
    "same_frame",
]


def same_frame(a: MappingFrame, b: MappingFrame) -> bool:
    """Whether two mapping frames are the same (georeference and altitude offset)."""
    return a.geo_reference == b.geo_reference and a.z_offset_m == b.z_offset_m


def points_in_frame(xyz: FloatArray, src: MappingFrame, dst: MappingFrame) -> FloatArray:
    """Points ``(N, 2+)`` from frame ``src`` to ``dst`` (through WGS84; z by the frames'
    altitude offsets)."""
    out = np.array(xyz, dtype=float, copy=True)
    if out.shape[0] == 0:
        return out
    lon, lat = src.to_lonlat(out[:, 0], out[:, 1])
    x, y = dst.from_lonlat(lon, lat)
    out[:, 0], out[:, 1] = x, y
    if out.shape[1] > 2:
        out[:, 2] += src.z_offset_m - dst.z_offset_m
    return out


def run_in_frame(run: MappingRun, frame: MappingFrame) -> MappingRun:
    """``run`` with its poses, edge points and lane samples in ``frame``.

    Positions go through WGS84 with pyproj; heights keep their altitude (``local`` frames
    count z from their origin's altitude); yaw turns with the grid (the direction to a
    point 1 m ahead, transformed). A run already in ``frame`` is returned unchanged.
    """
    if same_frame(run.frame, frame):
        return run
    traj = run.trajectory
    ahead = traj.xy + np.column_stack([np.cos(traj.yaw), np.sin(traj.yaw)])
    xyz = points_in_frame(traj.xyz, run.frame, frame)
    ahead_t = points_in_frame(ahead, run.frame, frame)
    d = ahead_t - xyz[:, :2]
    yaw = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    # keep the unwrapped branch of the original yaw (only the grid convergence changes)
    yaw += 2.0 * np.pi * np.round((traj.yaw[0] - yaw[0]) / (2.0 * np.pi))
    return replace(
        run,
        frame=frame,
        trajectory=replace(traj, xyz=xyz, yaw=yaw),
        edges=points_in_frame(run.edges, run.frame, frame),
        lane_samples=points_in_frame(run.lane_samples, run.frame, frame),
    )


def load_runs(run_dirs: list[str | Path], config: LoadConfig) -> list[MappingRun]:
    """The mapping runs of ``run_dirs``, every one moved into the first run's frame."""
    from .io import load_run

    loaded = [load_run(d, config=config) for d in run_dirs]
    return [run_in_frame(r, loaded[0].frame) for r in loaded]


def load_osm_around(
    runs: list[MappingRun],
    config: LoadConfig,
    *,
    osm: str | Path | None = None,
    osm_online: bool = False,
):
    """The OSM graph around every run's trajectory, in the first run's frame (the runs
    already there, :func:`load_runs`): from ``osm``, else the file the first run's
    ``run.toml`` names, or downloaded with ``osm_online``; None without a source."""
    from .osm import load_osm, load_osm_online

    frame = runs[0].frame
    around = np.vstack([r.trajectory.xy for r in runs])
    if osm_online:
        return load_osm_online(frame=frame, around_xy=around, config=config)
    path = osm or next((r.osm_path for r in runs if r.osm_path is not None), None)
    if path is None:
        return None
    return load_osm(path, frame=frame, around_xy=around, config=config)


def load_runs_and_osm(
    run_dirs: list[str | Path],
    config: LoadConfig,
    *,
    osm: str | Path | None = None,
    osm_online: bool = False,
):
    """:func:`load_runs`, then :func:`load_osm_around` them: ``(runs, graph)``.

    The two are read one after the other. Parsing the OSM extract in a second thread while
    the points load saved 0.5 s on a 10 M point run, but a SIGTERM during the parse could
    then hang the command at exit or leave the parse's temporary folder behind.
    """
    runs = load_runs(run_dirs, config)
    return runs, load_osm_around(runs, config, osm=osm, osm_online=osm_online)
