"""Tunables of every stage: one frozen dataclass per stage with documented defaults.

Only the CLI reads TOML (``--config FILE`` with one table per stage); library code takes
these objects as keyword arguments. Each stage's module owns the meaning of its fields.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any, Literal


@dataclass(frozen=True)
class LoadConfig:
    """Input loading and validation (``roadtwin.io``, ``roadtwin.osm``)."""

    max_point_distance_m: float = 60.0
    """Road-edge points / lane samples farther than this from every pose are dropped."""
    max_pose_jump_m: float = 20.0
    """A step between consecutive poses longer than this (and than 3x the median step
    scaled by the time step) is a trajectory jump: an error."""
    osm_buffer_m: float = 400.0
    """OSM ways are cropped to this buffer around the trajectory before building the graph."""


@dataclass(frozen=True)
class MainlineConfig:
    """Mainline reconstruction (``roadtwin.mainline``)."""

    method: Literal["default", "paper"] = "default"
    """``default`` (continuous global fit, tracked lanes) or ``paper`` (the seed paper)."""
    fit_tolerance_m: float = 0.02
    """Max deviation of the ParamPoly3 pieces from the smooth fitted edge (metres)."""
    paper_window_m: float = 100.0
    """Window length of the paper method (metres)."""
    paper_max_clusters: int = 6
    """Largest K tried by the paper's K-means lane clustering."""
    elevation_radius_m: float = 3.0
    """Search radius r for heights around each station (metres)."""


@dataclass(frozen=True)
class RampConfig:
    """Ramp reconstruction from OSM (``roadtwin.ramps``)."""

    candidate_distance_m: float = 30.0
    """d_r of the paper's Algorithm 1: link edges within this of the trajectory (metres)."""
    max_ramp_length_m: float = 600.0
    """Ramp chains are followed along OSM link edges at most this far (metres)."""
    resample_step_m: float = 0.5
    """OSM polyline resampling step (metres), as in the paper."""
    savgol_window_m: float = 25.0
    """Savitzky-Golay window length along the ramp (metres)."""
    lane_width_m: float = 3.5
    """Ramp lane width (metres)."""
    blend_length_m: float = 60.0
    """Length over which a re-anchored ramp blends back into the OSM shape (metres)."""
    lane_type: Literal["driving", "spec"] = "driving"
    """``driving`` ramp lanes (CARLA-friendly) or the spec's onRamp/offRamp types."""


@dataclass(frozen=True)
class TopologyConfig:
    """Cutting the mainline and building junctions (``roadtwin.topology``)."""

    junctions: Literal["default", "direct"] = "default"
    """Junctions with connecting roads (every consumer) or OpenDRIVE 1.7 direct ones."""


@dataclass(frozen=True)
class PipelineConfig:
    """All stage configurations together."""

    load: LoadConfig = field(default_factory=LoadConfig)
    mainline: MainlineConfig = field(default_factory=MainlineConfig)
    ramps: RampConfig = field(default_factory=RampConfig)
    topology: TopologyConfig = field(default_factory=TopologyConfig)

    @classmethod
    def from_dict(cls, data: dict[str, dict[str, Any]]) -> PipelineConfig:
        """Build from ``{"mainline": {...}, ...}`` (as read from a TOML file)."""
        from ._errors import InputError

        parts: dict[str, Any] = {}
        for f in fields(cls):
            table = data.get(f.name, {})
            default = f.default_factory()  # type: ignore[misc]
            known = {g.name for g in fields(default)}
            unknown = set(table) - known
            if unknown:
                msg = f"config [{f.name}]: unknown keys {sorted(unknown)}; known: {sorted(known)}"
                raise InputError(msg)
            parts[f.name] = replace(default, **table)
        unknown_tables = set(data) - {f.name for f in fields(cls)}
        if unknown_tables:
            raise InputError(f"config: unknown tables {sorted(unknown_tables)}")
        return cls(**parts)
