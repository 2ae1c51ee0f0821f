"""Results, shared helpers and the self-consistency metric of the mainline stage."""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .._errors import FitError, InputError
from ..fitting import (
    PolylineFrame,
    binned_statistics,
    moving_median,
    resample_polyline,
    savgol_smooth,
    whittaker_smooth,
)
from ..io import MappingRun
from ..model import (
    Road,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LaneEvent:
    """A lane that begins or ends inside the run (evidence of exits and entries).

    Attributes
    ----------
    s_m : station on the mainline road where the lane has zero width (birth: where it
        starts to open; end: where it has closed), metres.
    kind : ``"birth"`` or ``"end"``.
    side : road side of the lane, ``"right"`` or ``"left"`` (the outer side: ``"right"``
        for right-hand traffic).
    lane_id : id of the lane in the lane section where it exists.
    position : ``"outer"`` if the lane is the outermost non-shoulder lane (deceleration /
        acceleration lane), else ``"inner"``.
    taper_m : distance over which the lane opens (birth) or closes (end), metres; 0 if it
        starts / ends at full width (e.g. at a gore).
    width_m : width of the lane where it is fully open, metres.
    """

    s_m: float
    kind: Literal["birth", "end"]
    side: Literal["right", "left"]
    lane_id: int
    position: Literal["outer", "inner"]
    taper_m: float
    width_m: float


@dataclass(frozen=True)
class BoundaryTrack:
    """A lane marking followed along the reference line.

    ``s_m``/``d_m``: smoothed offset from the reference edge towards the carriageway
    (metres) on a regular station grid; ``mark``: observed type; ``n_samples``.
    """

    id: int
    s_m: FloatArray
    d_m: FloatArray
    mark: Literal["solid", "broken"]
    n_samples: int


@dataclass(frozen=True)
class Mainline:
    """Result of :func:`build_mainline`.

    Attributes
    ----------
    road : the mainline road (id ``"1"``, name ``"mainline"``), whole run.
    lane_events : lane births and ends, sorted by station.
    method : ``"default"`` or ``"paper"``.
    tracks : lane-marking tracks (default method; empty for the paper method).
    timings_s : seconds per stage.
    residuals : self-consistency RMSE (metres) of the paper's metric
        ``e = |t_measured - t_boundary(s)|``: ``road_edge``, ``lane_boundary``, ``overall``.
    stretches : where the run's own points disagree with the road (warnings with stations).
    """

    road: Road
    lane_events: tuple[LaneEvent, ...] = ()
    method: str = "default"
    tracks: tuple[BoundaryTrack, ...] = ()
    timings_s: dict[str, float] = field(default_factory=dict)
    residuals: dict[str, float] = field(default_factory=dict)
    stretches: tuple = ()
    """Stretches whose evidence disagrees with the road (:mod:`.quality` ``Stretch``)."""
    outer_edge_seen: tuple[tuple[float, float], ...] = ()
    """Stretches of the road (stations, metres) where the outer edge was seen: a lane that
    ends at full width there did not close before (:mod:`roadtwin.lane_drops`); empty for
    the paper method."""


@dataclass(frozen=True)
class _Partial:
    road: Road
    lane_events: tuple[LaneEvent, ...]
    method: str
    tracks: tuple[BoundaryTrack, ...] = ()
    outer_edge_seen: tuple[tuple[float, float], ...] = ()


def _sign(run: MappingRun) -> float:
    """+1 for right-hand traffic (reference = left edge, lanes at t < 0), -1 for left."""
    return 1.0 if run.traffic_side == "right" else -1.0


def road_surface_poses(run: MappingRun) -> FloatArray:
    """``(N, 3)`` the road surface under the car at each pose (the pose minus its height
    above the road; mapping frame, metres)."""
    poses = np.asarray(run.trajectory.xyz, dtype=float).copy()
    poses[:, 2] -= run.pose_height_m
    return poses


def _trajectory_frame(run: MappingRun, *, smooth_m: float = 31.0) -> PolylineFrame:
    """Frenet frame of the smoothed trajectory (1 m resampling, Savitzky-Golay), with the
    height of the road surface under the car (so that points of a road the run passes over
    or under are told from the driven road's)."""
    xyz = resample_polyline(road_surface_poses(run), 1.0)
    if xyz.shape[0] < 4:
        msg = "mainline: the trajectory is shorter than 4 m"
        raise InputError(msg)
    xyz = savgol_smooth(xyz, window=int(smooth_m), polyorder=3)
    return PolylineFrame.from_points(xyz)


def _split_edges(run: MappingRun, frame: PolylineFrame) -> tuple[FloatArray, FloatArray]:
    """Reference-side and outer-side edge points ``(N, 3)``, by ``edge_side`` or by the
    sign of the lateral offset from the trajectory where the side is unknown."""
    edges = np.asarray(run.edges, dtype=float)
    side = np.asarray(run.edge_side, dtype=np.int8)
    if edges.shape[0] == 0:
        msg = "mainline: the run has no road-edge points"
        raise InputError(msg)
    unknown = side == 0
    if np.any(unknown):
        _, t = frame.project(edges[unknown])
        side = side.copy()
        side[unknown] = np.where(t > 0, 1, -1).astype(np.int8)
    ref_side = 1 if run.traffic_side == "right" else -1
    return edges[side == ref_side], edges[side == -ref_side]


def _grid(lo: float, hi: float, step: float) -> FloatArray:
    n = max(2, math.ceil((hi - lo) / step) + 1)
    return lo + step * np.arange(n)


def edge_move_at(d_edge: FloatArray, i: NDArray[np.int64] | int, reach: int = 3) -> FloatArray:
    """How far (metres, outward positive) the outer edge ``d_edge`` (on the grid) moves
    across grid station(s) ``i``, from ``reach`` stations before to ``reach`` after
    (clipped to the grid); NaN where either end is."""
    i = np.asarray(i)
    after = d_edge[np.minimum(i + reach, d_edge.size - 1)]
    before = d_edge[np.maximum(i - reach, 0)]
    return np.asarray(after - before, dtype=float)


def true_runs(mask: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Index ranges ``[a, b)`` of the runs of True in ``mask``."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


TURN_WINDOW_M = 10.0  # the radius of a turn is taken over this length (metres)


def tight_turn_runs(
    heading: FloatArray, min_radius_m: float
) -> tuple[list[tuple[int, int]], FloatArray]:
    """Where a line turns tighter than ``min_radius_m`` (metres).

    ``heading`` (radians, unwrapped) is sampled every metre along the line; the radius is
    the heading change over ``TURN_WINDOW_M`` (so a joint of two geometry pieces does not
    count). Returns the index ranges ``[a, b)`` of the tight stretches (each window that
    turns too tight, whole) and the radius (metres) of the window starting at each index.
    """
    n = int(TURN_WINDOW_M)
    if heading.size <= n:
        return [], np.full(0, np.inf)
    radius = TURN_WINDOW_M / np.maximum(np.abs(heading[n:] - heading[:-n]), 1e-9)
    # every station of each tight window [i, i + n]: the full convolution has the
    # heading's length
    tight = np.convolve((radius < min_radius_m).astype(float), np.ones(n + 1)) > 0.0
    return true_runs(tight), radius


def _lam(cutoff_m: float, step_m: float, order: int = 2) -> float:
    """Whittaker smoothing strength for a cut-off wavelength (grid units)."""
    return (cutoff_m / (2.0 * math.pi * step_m)) ** (2 * order)


def robust_offset_fit(
    s: FloatArray,
    t: FloatArray,
    grid: FloatArray,
    *,
    cutoff_m: float,
    mad_k: float,
    min_threshold_m: float,
    iterations: int = 2,
    local_sigma_ends_m: float | None = None,
) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
    """Smooth function t(s) on a regular grid from scattered samples, robustly.

    First a per-bin median and a moving median give a robust prior; samples farther from
    it than ``mad_k`` robust sigmas (and ``min_threshold_m``) are dropped; inlier bin
    means weighted by counts are smoothed by a Whittaker smoother (gaps bridged); the
    rejection is repeated against the smooth fit. The sigma is local (a moving median of
    the absolute residuals). With ``local_sigma_ends_m`` (metres) it is local only that
    close to the first and last sample and one sigma for all samples in between, so that a
    second line running close beside the fitted one over a short stretch (a ramp marking
    joining a lane marking) cannot inflate it there, while a taper at an end of a marking,
    which the smoother follows late, keeps its samples.

    Returns
    -------
    values : (G,) smoothed offsets on ``grid``.
    inlier : (N,) mask of the samples kept.
    counts : (G,) inlier samples per grid bin.
    """
    step = float(grid[1] - grid[0])
    edges = np.concatenate([grid - 0.5 * step, [grid[-1] + 0.5 * step]])
    med, _, count = binned_statistics(s, t, edges)
    win = max(3, round(cutoff_m / 2.0 / step) | 1)
    prior = moving_median(med, window=win)
    prior = _fill_nan(grid, prior)
    lam = _lam(cutoff_m, step)
    inlier = np.ones(s.size, dtype=bool)
    fit = prior
    for _ in range(iterations):
        res = t - np.interp(s, grid, fit)
        absres = np.abs(res)
        med_abs, _, _ = binned_statistics(s, absres, edges)
        sigma = 1.4826 * _fill_nan(grid, moving_median(med_abs, window=max(win, 11)))
        sigma_s = np.interp(s, grid, sigma)
        if local_sigma_ends_m is not None:
            inside = (s > s.min() + local_sigma_ends_m) & (s < s.max() - local_sigma_ends_m)
            sigma_s[inside] = 1.4826 * float(np.median(absres))
        thr = np.maximum(mad_k * sigma_s, min_threshold_m)
        inlier = absres <= thr
        _, mean, count = binned_statistics(s[inlier], t[inlier], edges)
        w = count.astype(float)
        nz = w > 0
        if not np.any(nz):
            raise FitError("robust_offset_fit: every sample was rejected")
        w /= float(np.median(w[nz]))
        fit = whittaker_smooth(mean, w, lam=lam)
    return fit, inlier, count.astype(float)


def _fill_nan(x: FloatArray, y: FloatArray) -> FloatArray:
    ok = np.isfinite(y)
    if not np.any(ok):
        return np.zeros_like(y)
    return np.interp(x, x[ok], y[ok])


def _road_frame(
    road: Road, step_m: float = 0.5, *, heights: tuple[FloatArray, FloatArray] | None = None
) -> PolylineFrame:
    """Dense polyline frame of a road's reference line with road stations.

    ``heights``: ``(s, z)`` samples of the road surface along the road (metres) to give
    the frame heights (:class:`~roadtwin.fitting.PolylineFrame`), e.g. before the road has
    its elevation profile.
    """
    n = max(2, math.ceil(road.length / step_m) + 1)
    s = np.linspace(0.0, road.length, n)
    x, y, h, _ = road.evaluate(s)
    z = None if heights is None else np.interp(s, heights[0], heights[1])
    return PolylineFrame(s, np.stack([x, y], axis=1), np.stack([np.cos(h), np.sin(h)], axis=1), z)


@dataclass(frozen=True)
class PointResiduals:
    """Measured points of one kind against the nearest boundary of their kind.

    Attributes
    ----------
    s, t : station and lateral offset (left positive) of each point on the road, metres.
    error : signed ``t - t_boundary`` of the nearest boundary, metres.
    boundary : row of that boundary (edges: 0 reference line, 1 outer edge; markings:
        the lane whose outer border it is, inner to outer).
    fraction_used : share of the points within the road's ends that lie in its corridor.
    """

    s: FloatArray
    t: FloatArray
    error: FloatArray
    boundary: NDArray[np.int64]
    fraction_used: float


def point_residuals(road: Road, run: MappingRun) -> dict[str, PointResiduals]:
    """Road-edge points and lane samples against the nearest boundary of their kind.

    Only points between the two road edges (plus 1 m for edge points, 0.5 m for lane
    samples) count, as in the paper's corridor: ramp edges and markings beyond a gore and
    points of other roads are not measurements of this road. Keys ``road_edge`` and
    ``lane_boundary``.
    """
    frame = _road_frame(road)
    out: dict[str, PointResiduals] = {}
    for name, pts in (("road_edge", run.edges), ("lane_boundary", run.lane_samples)):
        empty = np.zeros(0)
        if pts.shape[0] == 0:
            out[name] = PointResiduals(empty, empty, empty, empty.astype(np.int64), 0.0)
            continue
        s, t = frame.project(pts)
        ok = (s >= 0) & (s <= road.length)
        s, t = s[ok], t[ok]
        edges = _border_matrix(road, s, edges=True)[:2]
        margin = 1.0 if name == "road_edge" else 0.5
        inside = (t >= np.nanmin(edges, axis=0) - margin) & (t <= np.nanmax(edges, axis=0) + margin)
        s, t = s[inside], t[inside]
        borders = _border_matrix(road, s, edges=(name == "road_edge"))
        signed = t[None, :] - borders
        if s.size and np.any(np.isfinite(signed)):
            nearest = np.nanargmin(np.where(np.isfinite(signed), np.abs(signed), np.inf), axis=0)
        else:
            nearest = np.zeros(s.size, dtype=np.int64)
        error = signed[nearest, np.arange(s.size)] if s.size else empty
        used = float(np.mean(inside)) if inside.size else 0.0
        out[name] = PointResiduals(s, t, error, nearest.astype(np.int64), used)
    return out


def self_consistency(road: Road, run: MappingRun) -> dict[str, float]:
    """RMSE of ``e = |t_measured - t_boundary(s)|`` (the paper's Table 4), metres.

    Edge points are compared with the nearer of the two road edges (reference line and
    the outer border of the outermost lane), lane samples with the nearest lane border at
    their station (the road edges included: a marking painted on an edge, e.g. the centre
    line of a two-way road on its reference line, is on a lane boundary). Only points between
    the two road edges (plus 1 m for edge points, 0.5 m for lane samples) count, as in the
    paper's corridor; ``<kind>_fraction_used`` says how many did.
    """
    out: dict[str, float] = {}
    errs = {}
    used: dict[str, float] = {}
    for name, res in point_residuals(road, run).items():
        errs[name] = np.abs(res.error)
        used[name] = res.fraction_used
    for name, e in errs.items():
        out[name] = float(np.sqrt(np.nanmean(e * e))) if e.size else math.nan
        out[f"{name}_fraction_used"] = used[name]
    both = np.concatenate(list(errs.values()))
    out["overall"] = float(np.sqrt(np.nanmean(both * both))) if both.size else math.nan
    return out


def _border_matrix(road: Road, s: FloatArray, *, edges: bool) -> FloatArray:
    """Lateral offsets (t) of road edges or of lane boundaries at stations ``s``."""
    sec_idx = road.section_index(s)
    n_max = max(len(sec.left) + len(sec.right) for sec in road.lane_sections)
    rows = np.full((n_max + 1, s.size), np.nan)
    for k in np.unique(sec_idx):
        sec = road.lane_sections[int(k)]
        sel = sec_idx == k
        side = sec.right if sec.right else sec.left
        ids = [ln.id for ln in side]
        if edges:
            rows[0, sel] = road.lane_border_t(s[sel], 0)
            if ids:
                rows[1, sel] = road.lane_border_t(s[sel], ids[-1])
        else:
            # every lane border, the road edges too: a centre line painted on a two-way
            # road's reference line, an edge line without a shoulder are lane markings
            rows[0, sel] = road.lane_border_t(s[sel], 0)
            for j, lid in enumerate(ids):
                rows[j + 1, sel] = road.lane_border_t(s[sel], lid)
    return rows


_TWO_LINES_BIN_M = 10.0  # edge points are split into two lines per this many metres ...
_TWO_LINES_MIN_POINTS = 12  # ... holding this many points at least ...
_TWO_LINES_GAP_M = 0.15  # ... at an empty gap this wide across them (metres) ...
_TWO_LINES_SHARE = 0.25  # ... with this share of the bin's points on either side ...
_TWO_LINES_APART_M = 0.35  # ... the two lines' medians this far apart (metres) ...
# ... in this many consecutive bins: a narrow median runs on for hundreds of metres; runs
# of 30 m beside gores are not one, and left out there they flipped lane-structure
# decisions (melbourne-921-s2 with a noisier sensor: edge 0.125 -> 0.393 m)
_TWO_LINES_BINS = 5
_TWO_LINES_SPLITS = 3  # splits tried one after the other (the far lines first)


def inner_line_points(s: FloatArray, u: FloatArray) -> NDArray[np.bool_]:
    """Mask of a side's road-edge points to fit: all but those of other, parallel
    lines of points beyond the edge (:func:`_outer_line_points`, the innermost line kept
    after each split: a far one split off first may leave a near one)."""
    keep = np.ones(s.size, dtype=bool)
    for _ in range(_TWO_LINES_SPLITS):
        idx = np.flatnonzero(keep)
        outer = _outer_line_points(s[idx], u[idx])
        if not outer.any():
            break
        keep[idx[outer]] = False
    return keep


def _outer_line_points(s: FloatArray, u: FloatArray) -> NDArray[np.bool_]:
    """Mask of the road-edge points of a second, parallel line of points beyond the edge.

    Across a narrow median the sensor may see the other carriageway's edge too: two lines
    of points a few decimetres apart (melbourne-408-opp, 0.55 m), which a robust fit
    averages (the edge 0.3 m into the median over 250 m); a kerb and a barrier's foot
    beyond it would do the same on the outer side. Where the residuals ``u`` (metres
    outward, away from the carriageway, from a fit of all points; stations ``s`` in
    metres) of a
    ``_TWO_LINES_BIN_M`` bin split at an empty gap of ``_TWO_LINES_GAP_M`` into two groups
    of ``_TWO_LINES_SHARE`` of the points or more whose medians lie ``_TWO_LINES_APART_M``
    apart, over ``_TWO_LINES_BINS`` consecutive bins, the road's edge is the inner line
    (as :func:`~.edge_levels.edge_level_path` takes the innermost level): the outer one's
    points are marked.
    """
    outer = np.zeros(s.size, dtype=bool)
    if s.size < _TWO_LINES_MIN_POINTS:
        return outer
    b = np.floor((s - float(np.min(s))) / _TWO_LINES_BIN_M).astype(np.int64)
    order = np.lexsort((u, b))
    b_o, u_o = b[order], u[order]
    n_bins = int(b_o[-1]) + 1
    count = np.bincount(b_o, minlength=n_bins)
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    rank = np.arange(s.size) - first[b_o]  # rank of each point within its bin
    # the gap after each point to the next one of its bin, where both sides hold the share
    gap = np.full(s.size, -np.inf)
    same = b_o[1:] == b_o[:-1]
    gap[:-1][same] = np.diff(u_o)[same]
    n = count[b_o]
    balanced = (rank + 1 >= _TWO_LINES_SHARE * n) & (n - rank - 1 >= _TWO_LINES_SHARE * n)
    gap = np.where(balanced & (n >= _TWO_LINES_MIN_POINTS), gap, -np.inf)
    widest = np.full(n_bins, -np.inf)
    np.maximum.at(widest, b_o, gap)
    # the split of each bin at its widest gap (the first such point)
    at_split = (gap == widest[b_o]) & np.isfinite(gap)
    split_rank = np.full(n_bins, -1)
    idx = np.flatnonzero(at_split)
    split_rank[b_o[idx[::-1]]] = rank[idx[::-1]]  # the lowest rank wins
    two = widest >= _TWO_LINES_GAP_M
    inner_part = rank <= split_rank[b_o]
    # the groups' medians (the bins' points are sorted: the middle one of each group)
    k_two = np.flatnonzero(two)
    n_in = split_rank[k_two] + 1
    med_in = u_o[first[k_two] + n_in // 2]
    med_out = u_o[first[k_two] + n_in + (count[k_two] - n_in) // 2]
    two[k_two] = med_out - med_in >= _TWO_LINES_APART_M
    # only runs of such bins: a line of points, not a bin's chance gap
    runs = np.zeros(n_bins, dtype=bool)
    for a, c in true_runs(two):
        if c - a >= _TWO_LINES_BINS:
            runs[a:c] = True
    outer[order[runs[b_o] & ~inner_part]] = True
    return outer
