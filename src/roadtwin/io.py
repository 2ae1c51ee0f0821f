"""Mapping-run loading and validation (DESIGN.md section 3).

A run folder holds ``run.toml`` and the files it names. :func:`load_run` reads them into
one :class:`MappingRun` of NumPy arrays in the mapping frame.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .frames import MappingFrame


@dataclass(frozen=True)
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


@dataclass(frozen=True)
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

    def summary(self) -> RunSummary:
        """Counts, driven length, duration and bounding box of the run."""
        xy = np.vstack([self.trajectory.xy, self.edges[:, :2]])
        return RunSummary(
            driven_length_m=self.trajectory.length_m,
            duration_s=float(self.trajectory.t[-1] - self.trajectory.t[0]),
            frames=int(self.trajectory.frame.size),
            edge_points=int(self.edges.shape[0]),
            lane_samples=int(self.lane_samples.shape[0]),
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


def load_run(run_dir: str | Path, *, config=None) -> MappingRun:
    """Load and validate a mapping-run folder (DESIGN.md section 3).

    Raises
    ------
    InputError
        With one line naming the file, row or field and what was expected.
    """
    raise NotImplementedError("filled in by the foundation issue")
