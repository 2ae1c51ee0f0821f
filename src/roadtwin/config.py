"""Tunables of every stage: one frozen dataclass per stage with documented defaults.

Only the CLI reads TOML (``--config FILE`` with one table per stage); library code takes
these objects as keyword arguments. Each stage's module owns the meaning of its fields.
"""

from __future__ import annotations

import math
import typing
from dataclasses import dataclass, field, fields, replace
from typing import Any, ClassVar, Literal

from ._errors import InputError


def check_fields(config: Any, table: str) -> None:
    """Validate a stage configuration against its type hints, in place.

    Every field must have its annotated type: ``bool``; ``int`` (not a bool); ``float``
    (an int is converted; NaN and infinity refused); a ``Literal`` value. Numbers whose
    default is positive must be positive, unless the class lists the field in
    ``_ZERO_OK`` (zero allowed) or gives it a closed range in ``_RANGES``.

    Raises
    ------
    InputError
        Naming ``[table] key``, the value and what was expected.
    """
    hints = typing.get_type_hints(type(config))
    ranges: dict[str, tuple[float, float]] = getattr(config, "_RANGES", {})
    zero_ok: frozenset[str] = getattr(config, "_ZERO_OK", frozenset())
    for f in fields(config):
        value = getattr(config, f.name)
        hint = hints[f.name]
        shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
        where = f"config [{table}] {f.name} = {shown}"
        if typing.get_origin(hint) is Literal:
            allowed = typing.get_args(hint)
            if value not in allowed or isinstance(value, bool):
                msg = f"{where}: expected one of {', '.join(repr(a) for a in allowed)}"
                raise InputError(msg)
            continue
        if hint is bool:
            if not isinstance(value, bool):
                raise InputError(f"{where}: expected true or false")
            continue
        if hint not in (int, float):
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"{where}: expected {'an integer' if hint is int else 'a number'}")
        if hint is int and not isinstance(value, int):
            raise InputError(f"{where}: expected an integer")
        if not math.isfinite(value):
            raise InputError(f"{where}: expected a finite number")
        if hint is float and not isinstance(value, float):
            object.__setattr__(config, f.name, float(value))
        default = f.default
        if f.name in ranges:
            lo, hi = ranges[f.name]
            if not lo <= value <= hi:
                raise InputError(f"{where}: expected a number in [{lo:g}, {hi:g}]")
        elif isinstance(default, (int, float)) and default > 0:
            if f.name in zero_ok:
                if value < 0:
                    raise InputError(f"{where}: expected a number >= 0")
            elif value <= 0:
                raise InputError(f"{where}: expected a number > 0")


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
    min_driven_m: float = 50.0
    """A run whose vehicle drives less than this (metres) is refused: nothing to map."""
    max_driven_km: float = 500.0
    """A run longer than this (kilometres) is refused: cost and memory grow linearly with
    the length (about 1 GiB per 100 km with the default method); split longer runs."""
    max_poses: int = 2_000_000
    """A trajectory with more poses is refused (55 h at 10 Hz; at most ~1 GiB of arrays)."""
    max_points: int = 1_000_000_000
    """Road-edge point files and lane-sample tables with more rows are refused. They are
    read in chunks and reduced while reading (memory stays bounded), at about 0.3 s per
    million points on one core: this bounds the time, not the memory."""
    max_origin_distance_km: float = 200.0
    """Every pose must lie within this (kilometres) of the run's GPS origin (for the
    ``local`` frame: of (0, 0)); farther means a wrong CRS, units or origin."""
    allow_files_outside_run: bool = False
    """Files named in ``run.toml`` must lie inside the run folder (after following
    symbolic links) unless this is true."""
    cell_station_m: float = 0.25
    """Density reduction (:mod:`roadtwin.reduction`): cell length along the trajectory
    (metres)."""
    cell_lateral_m: float = 0.05
    """Density reduction: cell width across the trajectory (metres)."""
    edge_points_per_m: float = 4.0
    """Rows per metre of each road edge after the density reduction: one per station cell,
    each the mean of the edge's points in it (the simulator's default sensor gives ~4.6
    points per metre; more rows would repeat the same means)."""
    lane_samples_per_m: float = 4.0
    """Rows per metre of each lane marking after the density reduction."""
    reduce_factor: float = 2.0
    """Points are reduced only where a line is denser than this times its target
    (``edge_points_per_m`` / ``lane_samples_per_m``); sparser runs pass unchanged."""
    chunk_points: int = 1_000_000
    """Points (or CSV rows) read per chunk: bounds the working memory of loading."""

    def __post_init__(self) -> None:
        check_fields(self, "load")


@dataclass(frozen=True)
class MainlineConfig:
    """Mainline reconstruction (``roadtwin.mainline``)."""

    method: Literal["default", "paper"] = "default"
    """``default`` (continuous global fit, tracked lanes) or ``paper`` (the seed paper)."""
    heading_bias: bool = False
    """Default method: turn the lane samples back by the poses' heading error that near
    and far samples of the same line show (:mod:`roadtwin.heading_bias`). Off by default:
    on the real-layout benchmark it moves lane borders 1-3 cm closer to the truth on most
    runs (median lane RMSE 0.026 -> 0.024 m, the lane count right at 99 % of the stations
    on every run; noisier sensor 0.057 -> 0.052 and 0.062 -> 0.056 m), but with the
    noisier sensor the lane-structure decisions (tapers, sideways shifts) of more runs
    flip for the worse than for the better: 9 of 160 maps with a lane over 6 m, a failed
    route or a missed ramp, against 3 at the same commit (benchmarks/RESULTS.md,
    session 24)."""
    fit_tolerance_m: float = 0.02
    """Max deviation of the ParamPoly3 pieces from the smooth fitted edge (metres)."""
    paper_window_m: float = 100.0
    """Window length of the paper method (metres)."""
    paper_max_clusters: int = 6
    """Largest K tried by the paper's K-means lane clustering."""
    elevation_radius_m: float = 3.0
    """Search radius r for heights around each station (metres)."""
    grid_step_m: float = 1.0
    """Station step of the regular grids the default method smooths on (metres)."""
    edge_smoothing_m: float = 40.0
    """Cut-off wavelength of the road-edge smoother (metres): shape features shorter than
    this are treated as noise."""
    edge_outlier_mad: float = 4.0
    """Edge points farther than this many robust sigmas (1.4826 MAD, local) from the
    running fit are outliers."""
    edge_rank_cost: float = 3.0
    """Outer edge path (:mod:`roadtwin.mainline.edge_levels`): cost of each level of edge
    points inside the chosen one in a bin (the mainline's edge is the innermost level)."""
    edge_skip_cost: float = 0.6
    """... cost of skipping a bin that holds edge points (the mainline's edge unseen there,
    another road's edge seen instead); doubled beyond the first five such bins in a row."""
    edge_level_sigma_m: float = 0.15
    """... lateral change of the edge between neighbouring 2 m bins that costs 1."""
    edge_step_m: float = 2.0
    """... a level change larger than this is a step (a gore: about a lane width); smaller
    changes pay the continuity cost (a change of a metre between bins is neither)."""
    edge_step_cost: float = 6.0
    """... cost of a step."""
    edge_outlier_min_m: float = 0.08
    """Outlier threshold never below this (metres), so clean data keeps all points."""
    elevation_bin_m: float = 5.0
    """Bin length for heights and cross slope (metres)."""
    elevation_smoothing_m: float = 60.0
    """Cut-off wavelength of the elevation / cross-slope smoother (metres)."""
    elevation_tolerance_m: float = 0.005
    """Max deviation of the C1 elevation pieces from the smoothed heights (metres)."""
    elevation_gate_m: float = 0.5
    """Road-edge points farther above or below the surface under the car than this plus
    the steepest cross slope over their distance from the car belong to another level
    (a ramp passing over or under) and give no heights (metres)."""
    superelevation_max_rad: float = 0.1
    """Steepest plausible cross slope (radians; design guides stop at about 8 %); the
    superelevation is clipped to it."""
    superelevation_min_rad: float = 0.005
    """Superelevation is written only where the mean cross slope over
    ``superelevation_min_length_m`` exceeds this (radians) and is significant."""
    superelevation_min_length_m: float = 100.0
    """Shortest stretch of significant cross slope written as superelevation (metres)."""
    superelevation_k_sigma: float = 5.0
    """Significance of the cross slope: ``|mean| > k * standard error`` over a stretch
    (standard error from the robust height noise and the lateral spread of the points)."""
    superelevation_tolerance_rad: float = 0.001
    """Max deviation of the superelevation pieces from the smoothed cross slope (radians)."""
    lane_column_m: float = 5.0
    """Station step of the lane-marking histogram columns (metres)."""
    lane_window_columns: int = 1
    """Columns summed per marking search window (1: none; a wider window smears tapers,
    broken-line gaps are bridged by the track linking instead)."""
    lane_bin_m: float = 0.05
    """Lateral histogram bin of the lane-marking search (metres)."""
    lane_min_separation_m: float = 0.8
    """Two markings closer than this are one (metres)."""
    lane_link_m: float = 0.6
    """Max lateral jump between consecutive columns of one marking track (metres)."""
    lane_max_gap_m: float = 60.0
    """Longest stretch without observations bridged inside one track (metres)."""
    lane_min_track_m: float = 60.0
    """Marking tracks shorter than this are false positives (metres)."""
    lane_min_cut_track_m: float = 20.0
    """A marking track that the run's start or end cuts off only has to be this long
    (metres): a run that starts or ends inside an auxiliary lane sees a short piece."""
    lane_assign_m: float = 0.35
    """Lane samples within this of a track belong to it (metres)."""
    lane_smoothing_m: float = 30.0
    """Cut-off wavelength of the marking smoother (metres)."""
    lane_width_tolerance_m: float = 0.01
    """Max deviation of the lane-width pieces from the smoothed widths (metres)."""
    lane_taper_max_m: float = 250.0
    """A lane birth/end is extrapolated to zero width at most this far (metres)."""
    lane_split_m: float = 1.6
    """A marking that starts/ends within this of a neighbour opens/closes a tapering lane."""
    ramp_line_slope: float = 0.012
    """A marking whose offset changes faster than this (m/m) where it starts (inward) or
    ends (outward) is a ramp line crossing the corridor near a gore, not the mainline's."""
    painted_gore_max_m: float = 100.0
    """Longest painted gore (metres, tip of the paint to the physical nose): an exit's lanes
    split where the through lanes' outer marking turns solid, up to this far before the
    nose where the edge steps; an entry's after it (:mod:`roadtwin.mainline.painted_gores`).
    0 keeps every gore at the nose."""
    hidden_gore_slope: float = 0.004
    """Where the outer edge is occluded, a marking that starts (ends) converging (diverging)
    faster than this (m/m) is a ramp line up to the gore."""
    gore_shoulder_taper_m: float = 60.0
    """Where a gore lies in an occlusion gap of the outer edge and no hard-shoulder taper
    could be fitted at the run's seen gores, the shoulder closes to zero width at an entry's
    gore (opens from it after an exit's) over this length, metres (a ramp's own shoulder
    taper, :attr:`RampConfig.shoulder_taper_m`, has the same default)."""
    edge_line_m: float = 0.35
    """A marking closer than this to a road edge (metres) is the edge line along it, not
    the border of a lane."""
    shoulder_max_m: float = 2.2
    """A lane between a road edge and the nearest marking narrower than this is a shoulder
    (metres)."""
    edge_lane_min_m: float = 3.3
    """... one at least this wide is a driving lane (roads without shoulders); in between a
    shoulder unless the car drove in it (hard shoulders are 2.5-3.0 m)."""
    edge_lane_max_m: float = 5.5
    """... and one wider than this is paved area beside the lanes (a gore opening towards
    a ramp, a lay-by), a shoulder, unless the car drove in it (metres; a lane whose outer
    line was missed over a long stretch is split off it as a hidden lane before)."""
    hidden_lane_min_m: float = 2.0
    """An outer shoulder wider than the run's typical one by more than this hides a lane
    whose outer marking was not observed (metres)."""
    split_lane_min_m: float = 1.5
    """Two adjacent observed markings farther apart than the typical lane width plus this
    (metres), over 30 m, have a line between them that was not observed (a lane added by
    a long taper beside the through lane): it is inferred."""
    broken_gap_m: float = 3.0
    """Gaps between samples longer than this count towards a broken marking (metres)."""
    broken_gap_fraction: float = 0.3
    """A marking is broken if such gaps cover more than this fraction of its length."""
    min_section_m: float = 20.0
    """Lane sections shorter than this are merged into a neighbour (metres)."""
    seed: int = 0
    """Seed of the paper method's K-means and silhouette sub-sampling."""
    quality_bin_m: float = 25.0
    """Station bin of the stretch warnings (:mod:`roadtwin.mainline.quality`), metres."""
    quality_min_points: int = 15
    """Points a bin needs before its residuals count."""
    quality_edge_bias_m: float = 0.2
    """A bin whose edge points lie on median farther than this from the built edge
    (metres) is poorly determined (the sensor's own noise is a few centimetres)."""
    quality_marking_m: float = 0.3
    """A lane sample farther than this from every built lane boundary is unexplained."""
    quality_min_marking_samples: int = 8
    """Unexplained lane samples that line up in a bin (one dash of a broken line gives
    about 12) before the bin counts as a marking the map lacks."""
    quality_max_lane_m: float = 5.0
    """A driving lane wider than this (metres) is flagged: a boundary was missed."""
    quality_min_radius_m: float = 20.0
    """A mainline whose reference line turns tighter than this radius (metres, over 10 m)
    is flagged: no motorway or trunk carriageway does (CARLA Town06's tightest curve has
    29 m); its edge points were another road's or too few."""

    _ZERO_OK: ClassVar[frozenset[str]] = frozenset(
        {
            "edge_outlier_min_m",
            "superelevation_min_rad",
            "superelevation_k_sigma",
            "painted_gore_max_m",
        }
    )
    _RANGES: ClassVar[dict[str, tuple[float, float]]] = {
        "broken_gap_fraction": (0.0, 1.0),
        "seed": (0, 2**32 - 1),
        "paper_max_clusters": (2, 64),
    }

    def __post_init__(self) -> None:
        check_fields(self, "mainline")


@dataclass(frozen=True)
class RampConfig:
    """Ramp reconstruction from OSM (``roadtwin.ramps``)."""

    candidate_distance_m: float = 30.0
    """d_r of the paper's Algorithm 1: link edges within this of the trajectory (metres)."""
    max_ramp_length_m: float = 600.0
    """Ramp chains are followed along OSM link edges at most this far (metres)."""
    run_end_margin_m: float = 50.0
    """A branch with both ends on the driven carriageway is a bypass and no ramp, unless
    one end lies within this of the run's start or end (metres): there the map ends, and
    the branch is a ramp at its other end."""
    resample_step_m: float = 0.5
    """OSM polyline resampling step (metres), as in the paper."""
    savgol_window_m: float = 25.0
    """Savitzky-Golay window length along the ramp (metres)."""
    lane_width_m: float = 3.5
    """Ramp lane width (metres)."""
    blend_length_m: float = 60.0
    """Length over which the first ramp lanes blend from the widths of the mainline lanes they
    continue to the ramp lane width (metres)."""
    link_lane_rule: Literal["osm", "paper"] = "osm"
    """Lane count of a ``*_link`` way without lane tags: ``osm`` (1 lane, OSM's convention
    for link roads) or ``paper`` (the seed paper's Algorithm 2 class default: motorway 3,
    trunk/primary 2)."""
    lane_type: Literal["driving", "spec"] = "driving"
    """``driving`` ramp lanes (CARLA-friendly) or the spec's onRamp/offRamp types."""
    savgol_polyorder: int = 3
    """Polynomial order of the Savitzky-Golay smoothing."""
    mainline_match_m: float = 25.0
    """An OSM node is on the driven carriageway when it lies within this of the trajectory
    (metres) and has a non-link edge whose heading matches the driven direction."""
    max_heading_diff_deg: float = 40.0
    """Largest heading difference (degrees) between an OSM edge and the driven direction for
    a mainline edge, and between a ramp at its attachment and the driven direction."""
    min_ramp_length_m: float = 10.0
    """Ramp chains shorter than this (metres) after trimming are skipped with a warning."""
    gore_search_upstream_m: float = 150.0
    """A measured gore (a lane ending/starting at full width) is matched to an OSM attachment
    when it lies at most this far upstream of it (metres)."""
    gore_search_downstream_m: float = 300.0
    """... or at most this far downstream of it (metres) (entries: mirrored)."""
    fit_tolerance_m: float = 0.02
    """Max deviation of the ramp's ParamPoly3 pieces from the smoothed polyline (metres)."""
    snap_to_section_m: float = 5.0
    """Without a measured gore, an OSM attachment this close to a mainline lane-section
    boundary (metres) moves onto it (no sliver sections in the junction)."""
    inner_shoulder_width_m: float = 0.9
    """Default width of a ramp's inner (median-side) shoulder, metres, used where the LiDAR
    did not see the ramp. Mid-range of the AASHTO Green Book ramp cross-section (left
    shoulder 0.6-1.2 m, i.e. 2-4 ft; German RAA ramp cross-sections use 0.75-1.0 m)."""
    hard_shoulder_width_m: float = 2.4
    """Default width of a ramp's hard (outer) shoulder, metres, where the LiDAR did not see
    it. Mid-range of the AASHTO Green Book ramp right shoulder (1.8-3.0 m, i.e. 6-10 ft;
    German RAA: 2.0-2.5 m)."""
    shoulder_taper_m: float = 60.0
    """A ramp's inner shoulder opens from zero width at the gore (exit) or closes to zero
    width there (entry) over this length, metres (the gore area, where the two edges
    diverge)."""
    min_radius_m: float = 15.0
    """Smallest radius of a ramp's reference line (metres); on the side of its lanes the
    outer lane border keeps it too. Loop ramps go down to about 25-30 m in design
    guides; the bound only stops a fit from knotting."""
    shape_knot_m: float = 15.0
    """Knot spacing of the ramp's curvature (metres): curvature is linear between knots
    (a chain of clothoids)."""
    shape_step_m: float = 0.5
    """Step of the dense fitted reference line (metres)."""
    shape_smoothness: float = 2000.0
    """Weight of the second differences of the knot curvatures (per knot spacing squared)
    against the target points (in units of their sigma)."""
    osm_sigma_m: float = 2.0
    """Standard deviation of an OSM ramp point as a target of the ramp shape (metres): OSM
    is drawn 1-5 m off; the fit is robust beyond twice this."""
    evidence_sigma_m: float = 0.1
    """Standard deviation of the measured ramp line (where the LiDAR saw the ramp) as a
    target of the ramp shape (metres)."""
    use_evidence: bool = True
    """Shape the ramps' first part and widths from the measured points past the gores
    (False: OSM shape and default widths only, the paper's method)."""
    evidence_length_m: float = 200.0
    """Measured points (road edges, lane samples) up to this far along the ramp from its
    gore shape the ramp's first part and estimate its lane widths (metres)."""
    evidence_min_points: int = 40
    """At least this many measured points must be matched to the ramp's boundaries (and
    span ``evidence_min_span_m``) before they correct it; else OSM and defaults decide."""
    evidence_min_span_m: float = 20.0
    """Minimum extent along the ramp (metres) of the matched points."""
    evidence_max_shift_m: float = 15.0
    """A fit to the measured points that moves the ramp farther than this (metres) from the
    line fitted to the OSM shape alone is rejected (the points belong to another road).
    Generous on purpose: OSM itself can be metres off near the gore (drawn with offset, an
    OSM attachment far from the measured gore), which is what the fit corrects."""
    evidence_exclude_m: float = 0.3
    """Measured points within this (metres) of a mainline boundary of their kind belong to
    the mainline and are not used as ramp evidence."""

    _ZERO_OK: ClassVar[frozenset[str]] = frozenset(
        {
            "snap_to_section_m",
            "evidence_exclude_m",
            "gore_search_upstream_m",
            "gore_search_downstream_m",
            "inner_shoulder_width_m",
            "hard_shoulder_width_m",
        }
    )
    _RANGES: ClassVar[dict[str, tuple[float, float]]] = {
        "max_heading_diff_deg": (0.0, 180.0),
        "savgol_polyorder": (1, 10),
    }

    def __post_init__(self) -> None:
        check_fields(self, "ramps")


@dataclass(frozen=True)
class TopologyConfig:
    """Cutting the mainline and building junctions (``roadtwin.topology``)."""

    junctions: Literal["default", "direct"] = "default"
    """Junctions with connecting roads (every consumer) or OpenDRIVE 1.7 direct ones."""
    junction_length_m: float = 20.0
    """Length along the mainline of a junction with connecting roads (metres)."""
    min_road_length_m: float = 5.0
    """A ramp whose junction would leave a mainline road shorter than this is skipped."""
    lane_drop_taper_m: float = 60.0
    """Longest taper (metres) closing a driving lane that still ends unlinked at full width
    where the road narrows once the junctions are built (:mod:`roadtwin.lane_drops`);
    0 leaves such lanes as they are (the paper method)."""

    _ZERO_OK: ClassVar[frozenset[str]] = frozenset({"lane_drop_taper_m"})

    def __post_init__(self) -> None:
        check_fields(self, "topology")


@dataclass(frozen=True)
class EvaluationConfig:
    """Accuracy evaluation (``roadtwin.evaluation``)."""

    max_lateral_m: float = 40.0
    """Points farther than this (metres) from every mainline reference line are excluded."""
    end_tolerance_m: float = 0.1
    """A point projecting more than this (metres) beyond a road's start or end is not on it."""
    truth_step_m: float = 1.0
    """Spacing (metres) of the samples along every true boundary."""
    lane_count_min_width_m: float = 1.75
    """A driving lane counts towards the lane count where it is at least this wide (metres),
    so tapers count as half a lane."""
    ramp_match_distance_m: float = 60.0
    """Largest distance (metres) between a true and a built ramp's attachment points for
    them to be the same ramp."""
    self_consistency_scope: Literal["all", "mainline"] = "all"
    """Roads the run's points are compared with: ``all`` (mainline and ramp roads, the
    nearest boundary wins; gore points belong to the ramp) or ``mainline`` only."""

    _ZERO_OK: ClassVar[frozenset[str]] = frozenset({"end_tolerance_m"})

    def __post_init__(self) -> None:
        check_fields(self, "evaluation")


@dataclass(frozen=True)
class DriveConfig:
    """Drive-throughs of a map in esmini (``roadtwin.drive``)."""

    speed_m_s: float = 25.0
    """Speed of the car on every route (metres per second; 25 m/s = 90 km/h)."""
    timestep_s: float = 0.05
    """esmini's fixed simulation step (seconds); the recording has one row per step."""
    approach_m: float = 150.0
    """Lane driven before the junction of an exit or a junction connection (metres), where
    the map has that much lane before it."""
    follow_m: float = 400.0
    """Longest stretch driven on the target road (metres); shorter roads to their end."""
    min_on_target_m: float = 50.0
    """A route passes only if the car drove at least this far on its target road (metres),
    or to the target when the road is shorter."""
    min_lane_width_m: float = 2.0
    """Routes start and end where their lane is at least this wide (metres), not inside a
    taper."""
    end_margin_m: float = 2.0
    """Start and target stay this far (metres) inside the lane's usable stretch."""
    reach_tolerance_m: float = 2.0
    """The car has reached the target within this distance (metres)."""
    max_jump_m: float = 1.0
    """Largest allowed jump (metres): the distance between where the car is after a step and
    where its own speed and heading would have put it. A continuous map gives millimetres
    (up to 0.56 m where esmini steps across a curvature jump of a tight arc far from the
    reference line, seen on CARLA's Town06); a 1.5 m gap across a link gives 1.5 m in any
    direction, while the raw step of 1.25 m + a sideways 1.5 m is only 1.95 m: a bound on
    the raw step ("no step over 2 m") would miss it."""
    workers: int = 2
    """esmini runs at the same time (each is one single-threaded process)."""
    stuck_s: float = 2.0
    """The car is stuck when it moved less than 0.1 m during this time (seconds)."""
    timeout_s: float = 120.0
    """Wall-clock limit of one esmini run (seconds)."""

    _ZERO_OK: ClassVar[frozenset[str]] = frozenset({"end_margin_m"})
    _RANGES: ClassVar[dict[str, tuple[float, float]]] = {"workers": (1, 64)}

    def __post_init__(self) -> None:
        check_fields(self, "drive")


@dataclass(frozen=True)
class HighwayConfig:
    """The whole highway (``roadtwin.highway``, ``roadtwin.osm_roads``): several runs fused,
    both carriageways, the roads beyond the ramps, the OSM-only mode."""

    same_carriageway_m: float = 25.0
    """Two runs drive the same carriageway where their paths come this close (metres)
    with headings within 45 deg."""
    opposite_carriageway_m: float = 100.0
    """A run (or an OSM carriageway) this close (metres) with the opposite heading drives
    the other carriageway of the same highway."""
    min_overlap_m: float = 50.0
    """Shortest shared stretch (metres) that makes two paths the same / opposite
    carriageway."""
    join_gap_m: float = 60.0
    """A run starting within this distance (metres) of another's end continues it."""
    consistency_bin_m: float = 50.0
    """Length (metres) of the stretches in which overlapping runs are compared."""
    pose_sigma_m: float = 0.03
    """Lateral pose error of one run (metres, GNSS/INS drift): two runs may differ by
    about sqrt(2) times this without any fault."""
    disagree_sigmas: float = 4.0
    """Runs disagree where their offsets differ by more than this many standard errors."""
    min_disagreement_m: float = 0.10
    """... and by more than this (metres)."""
    min_bin_points: int = 20
    """Edge points a run needs in a stretch to be compared there."""
    opposite: bool = True
    """Build, from OSM, the carriageway that no run drove (at OSM accuracy)."""
    beyond: bool = True
    """Build, from OSM, the road beyond each ramp's far end and link the ramp to it."""
    beyond_length_m: float = 300.0
    """The road beyond a ramp is followed up to its next junction or this far (metres)."""
    beyond_min_radius_m: float = 20.0
    """Smallest radius (metres) of the reference line of a road beyond a ramp (its lanes
    turn a little tighter)."""
    median_smooth_m: float = 250.0
    """Smoothing length (metres) of the OSM median width along the road."""
    min_median_m: float = 0.5
    """Narrowest median (metres) between a measured and an OSM-built carriageway."""
    lane_taper_m: float = 80.0
    """Length (metres) over which an OSM-built lane opens or closes where the OSM lane
    count changes."""
    lane_width_m: float = 3.5
    """Lane width (metres) of OSM-built roads where no run measured one."""
    inner_shoulder_m: float = 0.75
    """Inner (median-side) shoulder (metres) of OSM-built carriageways without a run."""
    hard_shoulder_m: float = 2.5
    """Hard shoulder (metres) of OSM-built motorways without a run."""
    osm_fit_window_m: float = 800.0
    """An OSM-only carriageway is fitted (curvature-bounded clothoid spline) in windows of
    this length (metres), each anchored on the previous one."""
    min_carriageway_m: float = 200.0
    """OSM carriageways shorter than this (metres) are not built in the OSM-only mode."""

    _RANGES: ClassVar[dict[str, tuple[float, float]]] = {"min_bin_points": (1, 100000)}

    def __post_init__(self) -> None:
        check_fields(self, "highway")


@dataclass(frozen=True)
class PipelineConfig:
    """All stage configurations together."""

    load: LoadConfig = field(default_factory=LoadConfig)
    mainline: MainlineConfig = field(default_factory=MainlineConfig)
    ramps: RampConfig = field(default_factory=RampConfig)
    topology: TopologyConfig = field(default_factory=TopologyConfig)
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    drive: DriveConfig = field(default_factory=DriveConfig)
    highway: HighwayConfig = field(default_factory=HighwayConfig)

    def with_method(self, method: Literal["default", "paper"]) -> PipelineConfig:
        """The same settings built with ``method``: the mainline method, the ramps' lane
        rule for untagged links (``paper``: the seed paper's Algorithm 2 class default) and
        whether lanes ending at full width are closed by a taper (not in the paper)."""
        paper = method == "paper"
        taper = 0.0 if paper else TopologyConfig.lane_drop_taper_m
        return replace(
            self,
            mainline=replace(self.mainline, method=method),
            ramps=replace(self.ramps, link_lane_rule="paper" if paper else "osm"),
            topology=replace(self.topology, lane_drop_taper_m=taper),
        )

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "config") -> PipelineConfig:
        """Build from ``{"mainline": {...}, ...}`` (as read from a TOML file).

        Every value is checked (type, finite, positive where it must be; see
        :func:`check_fields`); errors name ``source``, the table and the key.
        """
        parts: dict[str, Any] = {}
        known_tables = {f.name for f in fields(cls)}
        unknown_tables = set(data) - known_tables
        if unknown_tables:
            msg = (
                f"{source}: unknown tables {sorted(unknown_tables)}; known: {sorted(known_tables)}"
            )
            raise InputError(msg)
        for f in fields(cls):
            table = data.get(f.name, {})
            if not isinstance(table, dict):
                msg = f"{source}: [{f.name}] must be a table of settings, not a value"
                raise InputError(msg)
            default = f.default_factory()  # type: ignore[misc]
            known = {g.name for g in fields(default)}
            unknown = set(table) - known
            if unknown:
                msg = f"{source}: [{f.name}] unknown keys {sorted(unknown)}; known: {sorted(known)}"
                raise InputError(msg)
            try:
                parts[f.name] = replace(default, **table)
            except InputError as exc:
                raise InputError(f"{source}: {exc}") from None
        return cls(**parts)
