"""Mainline reconstruction from a mapping run: reference line, elevation and lanes.

Two methods build the same :class:`Mainline` (one :class:`~roadtwin.model.Road` named
``"mainline"`` over the whole run, laid out as the shared lane layout says):

``default`` (DESIGN.md section 4)
    The median-side road edge (left for right-hand traffic, right for left-hand traffic)
    is fitted as ONE smooth curve along the whole run: edge points are projected into the
    Frenet frame of the smoothed trajectory, outliers are rejected by a local median/MAD
    test, per-metre bin means are smoothed by a penalised least-squares (Whittaker)
    smoother that bridges gaps, and the frame is replaced by the fitted edge and the fit
    repeated. The result is cut into ParamPoly3 pieces that share end points and headings
    (:func:`roadtwin.fitting.fit_parampoly3_chain`). Heights and cross slope are fitted per
    bin (edge points and poses) and smoothed; elevation becomes C1 cubic pieces.
    Lane-marking samples are followed as tracks along s in a station/offset histogram;
    short tracks are rejected; a marking that starts or ends next to a neighbour opens or
    closes a tapering lane (lane birth / end), extrapolated to zero width. Lane sections
    follow the set of tracks; the inner shoulder (edge to first marking) and the hard
    shoulder (last marking to the outer edge) are shoulder lanes; road marks are solid or
    broken from the gap statistics of the samples along each track.

``paper`` (the seed paper, kept as the baseline)
    100 m trajectory windows; a cubic per window fitted to the median-side edge points and
    turned into a ParamPoly3 (windows are independent, joints are not continuous);
    elevation = median height within radius r of stations, smoothed, one cubic per
    window; lane samples clustered per window by K-means on the lateral offset with
    k <= 6 chosen by silhouette; one cubic t(s) per cluster.

Frames: all input and output coordinates are in the mapping frame (metres). Internally
lateral offsets are handled as ``d`` = distance from the reference edge towards the
carriageway (``d = -t`` for right-hand traffic, ``d = t`` for left-hand traffic), so the
method is written once and mirrored by the sign.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ._errors import FitError, InputError
from .config import MainlineConfig
from .fitting import (
    PolylineFrame,
    binned_quantile,
    binned_statistics,
    fit_cubic_profile,
    fit_parampoly3_chain,
    moving_median,
    resample_polyline,
    savgol_smooth,
    shift_cubic_piece,
    whittaker_smooth,
)
from .io import MappingRun
from .model import (
    Arc,
    CubicPiece,
    CubicProfile,
    Geometry,
    Lane,
    LaneSection,
    Line,
    ParamPoly3,
    Road,
    RoadMark,
    Spiral,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

__all__ = ["BoundaryTrack", "LaneEvent", "Mainline", "build_mainline", "cut_road"]


# ---------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------


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
    """

    road: Road
    lane_events: tuple[LaneEvent, ...] = ()
    method: str = "default"
    tracks: tuple[BoundaryTrack, ...] = ()
    timings_s: dict[str, float] = field(default_factory=dict)
    residuals: dict[str, float] = field(default_factory=dict)


# ---------------------------------------------------------------------------
# entry point
# ---------------------------------------------------------------------------


def build_mainline(run: MappingRun, *, config: MainlineConfig | None = None) -> Mainline:
    """Reconstruct the driven mainline of a mapping run as one OpenDRIVE road.

    Parameters
    ----------
    run
        The mapping run (mapping frame, metres).
    config
        Stage settings; ``config.method`` selects ``"default"`` or ``"paper"``.

    Returns
    -------
    Mainline
        ``.road`` (reference line = median-side road edge, elevation, optional
        superelevation, lane sections per the shared lane layout) and lane events.

    Raises
    ------
    InputError
        Too few edge points on the median side to fit a reference line.
    """
    cfg = config or MainlineConfig()
    if cfg.method not in ("default", "paper"):
        msg = f"mainline: unknown method {cfg.method!r}; expected 'default' or 'paper'"
        raise InputError(msg)
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    if cfg.method == "paper":
        result = _build_paper(run, cfg, timings)
    else:
        result = _build_default(run, cfg, timings)
    t0 = time.perf_counter()
    residuals = self_consistency(result.road, run)
    timings["self_consistency"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    road = result.road
    log.info(
        "mainline (%s): %.0f m, %d pieces, %d lane sections, %d lane events, "
        "edge RMSE %.3f m, lane RMSE %.3f m, %.2f s",
        cfg.method,
        road.length,
        len(road.geometry),
        len(road.lane_sections),
        len(result.lane_events),
        residuals.get("road_edge", math.nan),
        residuals.get("lane_boundary", math.nan),
        timings["total"],
    )
    return Mainline(
        road=road,
        lane_events=result.lane_events,
        method=result.method,
        tracks=result.tracks,
        timings_s=timings,
        residuals=residuals,
    )


# ---------------------------------------------------------------------------
# shared helpers
# ---------------------------------------------------------------------------


def _sign(run: MappingRun) -> float:
    """+1 for right-hand traffic (reference = left edge, lanes at t < 0), -1 for left."""
    return 1.0 if run.traffic_side == "right" else -1.0


def _trajectory_frame(run: MappingRun, *, smooth_m: float = 31.0) -> PolylineFrame:
    """Frenet frame of the smoothed trajectory (1 m resampling, Savitzky-Golay)."""
    xy = resample_polyline(run.trajectory.xy, 1.0)
    if xy.shape[0] < 4:
        msg = "mainline: the trajectory is shorter than 4 m"
        raise InputError(msg)
    xy = savgol_smooth(xy, window=int(smooth_m), polyorder=3)
    return PolylineFrame.from_points(xy)


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
) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
    """Smooth function t(s) on a regular grid from scattered samples, robustly.

    First a per-bin median and a moving median give a robust prior; samples farther from
    it than ``mad_k`` local robust sigmas (and ``min_threshold_m``) are dropped; inlier bin
    means weighted by counts are smoothed by a Whittaker smoother (gaps bridged); the
    rejection is repeated against the smooth fit.

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
        thr = np.maximum(mad_k * np.interp(s, grid, sigma), min_threshold_m)
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


def _road_frame(road: Road, step_m: float = 0.5) -> PolylineFrame:
    """Dense polyline frame of a road's reference line with road stations."""
    n = max(2, math.ceil(road.length / step_m) + 1)
    s = np.linspace(0.0, road.length, n)
    x, y, h, _ = road.evaluate(s)
    return PolylineFrame(s, np.stack([x, y], axis=1), np.stack([np.cos(h), np.sin(h)], axis=1))


# ---------------------------------------------------------------------------
# default method
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class _Partial:
    road: Road
    lane_events: tuple[LaneEvent, ...]
    method: str
    tracks: tuple[BoundaryTrack, ...] = ()


def _build_default(run: MappingRun, cfg: MainlineConfig, timings: dict[str, float]) -> _Partial:
    sign = _sign(run)
    t0 = time.perf_counter()
    traj = _trajectory_frame(run)
    ref_pts, outer_pts = _split_edges(run, traj)
    if ref_pts.shape[0] < 10:
        side = "left" if sign > 0 else "right"
        msg = f"mainline: only {ref_pts.shape[0]} {side} (median-side) road-edge points"
        raise InputError(msg)
    timings["frame"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    ref_xy = fit_reference_edge(ref_pts, traj, config=cfg)
    geometry = fit_parampoly3_chain(ref_xy, tolerance_m=cfg.fit_tolerance_m)
    timings["reference_line"] = time.perf_counter() - t0

    base = Road("1", geometry, (LaneSection(0.0),), name="mainline")
    frame = _road_frame(base)
    length = base.length

    t0 = time.perf_counter()
    s_out, t_out = frame.project(outer_pts)
    s_lane, t_lane = frame.project(run.lane_samples)
    sections, events, tracks, used = fit_lanes(
        s_lane,
        -sign * t_lane,
        s_out,
        -sign * t_out,
        length=length,
        sign=sign,
        config=cfg,
    )
    timings["lanes"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    poses = run.trajectory.xyz.copy()
    poses[:, 2] -= run.pose_height_m
    elevation, superelevation = fit_elevation(
        frame, np.vstack([ref_pts, outer_pts[used], poses]), config=cfg
    )
    timings["elevation"] = time.perf_counter() - t0
    road = replace(
        base,
        elevation=elevation,
        superelevation=superelevation,
        lane_sections=sections,
        lane_offset=CubicProfile.constant(0.0),
    )
    return _Partial(road, events, "default", tracks)


def fit_reference_edge(
    ref_pts: FloatArray, traj: PolylineFrame, *, config: MainlineConfig | None = None
) -> FloatArray:
    """Smooth reference-edge polyline ``(G, 2)`` (mapping frame, ~1 m spacing).

    Edge points are fitted as a robust smooth offset from a frame, first the smoothed
    trajectory, then twice the previous fit itself (so the final smoothing acts on small
    residuals only and does not flatten lane changes of the vehicle).
    """
    cfg = config or MainlineConfig()
    step = cfg.grid_step_m
    frame = traj
    for it in range(3):
        s, t = frame.project(ref_pts)
        inside = (s >= -5.0) & (s <= frame.length + 5.0)
        s, t = s[inside], t[inside]
        if s.size < 10:
            raise InputError("mainline: the median-side road edge is not beside the trajectory")
        lo, hi = float(np.min(s)), float(np.max(s))
        if it == 0:
            lo, hi = max(lo, 0.0), min(hi, frame.length)
        grid = _grid(lo, hi, step)
        grid = grid[grid <= hi + 1e-9] if grid[-1] > hi + 0.5 * step else grid
        cutoff = cfg.edge_smoothing_m if it > 0 else max(cfg.edge_smoothing_m, 60.0)
        off, _, _ = robust_offset_fit(
            s,
            t,
            grid,
            cutoff_m=cutoff,
            mad_k=cfg.edge_outlier_mad,
            min_threshold_m=cfg.edge_outlier_min_m if it > 0 else 0.5,
        )
        xy, tg = frame.at(np.clip(grid, 0.0, frame.length))
        # beyond the frame ends extrapolate along the end tangents
        xy = xy + (grid - np.clip(grid, 0.0, frame.length))[:, None] * tg
        nrm = np.stack([-tg[:, 1], tg[:, 0]], axis=1)
        pts = xy + off[:, None] * nrm
        frame = PolylineFrame.from_points(resample_polyline(pts, step))
    return frame.xy


def fit_elevation(
    frame: PolylineFrame, points: FloatArray, *, config: MainlineConfig | None = None
) -> tuple[CubicProfile, CubicProfile | None]:
    """Elevation and (if significant) superelevation of the reference line.

    Per station bin a weighted plane ``z = e + g t`` is fitted to the height points
    (road-edge points, poses minus the pose height; mapping frame z), with one round of
    robust (MAD) rejection; ``e`` and ``g`` are smoothed along s and bridged over gaps.

    Returns
    -------
    elevation : C1 cubic profile of z at the reference line (metres).
    superelevation : profile of ``atan(g)`` (radians; positive = falling to the right),
        or None if ``|g|`` stays below ``config.superelevation_min_rad``.
    """
    cfg = config or MainlineConfig()
    s, t = frame.project(points)
    z = points[:, 2]
    ok = (s >= 0) & (s <= frame.length) & np.isfinite(z)
    s, t, z = s[ok], t[ok], z[ok]
    step = cfg.elevation_bin_m
    grid = _grid(0.0, frame.length, step)
    n = grid.size
    b = np.clip(np.rint(s / step).astype(np.int64), 0, n - 1)
    keep = np.ones(s.size, dtype=bool)
    e = g = np.zeros(n)
    lam = _lam(cfg.elevation_smoothing_m, step)
    for _ in range(2):
        w = keep.astype(float)
        sw = np.bincount(b, w, n)
        st = np.bincount(b, w * t, n)
        sz = np.bincount(b, w * z, n)
        stt = np.bincount(b, w * t * t, n)
        stz = np.bincount(b, w * t * z, n)
        with np.errstate(invalid="ignore", divide="ignore"):
            mt, mz = st / sw, sz / sw
            vt = stt / sw - mt * mt
            ctz = stz / sw - mt * mz
            g_bin = np.where(vt > 1.0, ctz / vt, np.nan)
        gw = np.where(np.isfinite(g_bin), sw * np.nan_to_num(vt), 0.0)
        g = whittaker_smooth(g_bin, gw, lam=lam) if np.any(gw > 0) else np.zeros(n)
        e_bin = np.where(sw > 0, mz - g * mt, np.nan)
        e = whittaker_smooth(e_bin, sw / max(float(np.median(sw[sw > 0])), 1e-12), lam=lam)
        res = z - (np.interp(s, grid, e) + np.interp(s, grid, g) * t)
        mad = float(np.median(np.abs(res))) * 1.4826
        keep = np.abs(res) <= max(4.0 * mad, 0.05)
    elevation = fit_cubic_profile(grid, e, tolerance=cfg.elevation_tolerance_m)
    superelevation = None
    if float(np.max(np.abs(g))) > cfg.superelevation_min_rad:
        superelevation = fit_cubic_profile(grid, np.arctan(g), tolerance=1e-4)
    return elevation, superelevation


# -- lanes ------------------------------------------------------------------


@dataclass
class _RawTrack:
    cols: list[int]
    d: list[float]

    def predict(self, col: int) -> float:
        """Offset extrapolated linearly from the last few columns to column ``col``."""
        if len(self.d) < 3:
            return self.d[-1]
        c = self.cols[-4:]
        v = self.d[-4:]
        cm, vm = sum(c) / len(c), sum(v) / len(v)
        var = sum((ci - cm) ** 2 for ci in c)
        slope = sum((ci - cm) * (vi - vm) for ci, vi in zip(c, v, strict=True)) / var
        slope = min(max(slope, -0.5), 0.5)
        return self.d[-1] + slope * (col - self.cols[-1])


def _find_track_peaks(
    s: FloatArray, d: FloatArray, length: float, cfg: MainlineConfig
) -> tuple[FloatArray, list[FloatArray]]:
    """Marking peaks per histogram column: column centres and the peak offsets in each."""
    from scipy.ndimage import gaussian_filter1d, uniform_filter1d
    from scipy.signal import find_peaks

    col = cfg.lane_column_m
    n_col = max(1, math.ceil(length / col))
    d_lo, d_hi = -1.0, float(np.nanmax(d)) + 1.0 if d.size else 1.0
    n_bin = max(4, math.ceil((d_hi - d_lo) / cfg.lane_bin_m))
    hist, _, _ = np.histogram2d(
        s, d, bins=(n_col, n_bin), range=((0.0, n_col * col), (d_lo, d_lo + n_bin * cfg.lane_bin_m))
    )
    hist = uniform_filter1d(hist, cfg.lane_window_columns, axis=0, mode="nearest")
    hist = gaussian_filter1d(hist, 1.5, axis=1, mode="constant")
    # height threshold: a fraction of the typical strong peak
    strong = np.percentile(hist.max(axis=1), 75) if hist.size else 0.0
    thr = max(0.15 * strong, 1e-9)
    min_dist = max(1, int(cfg.lane_min_separation_m / cfg.lane_bin_m))
    centres = (np.arange(n_col) + 0.5) * col
    peaks: list[FloatArray] = []
    bin_c = d_lo + (np.arange(n_bin) + 0.5) * cfg.lane_bin_m
    for row in hist:  # loop over columns (a few thousand), vectorised inside
        idx, _ = find_peaks(row, height=thr, distance=min_dist, prominence=0.5 * thr)
        if idx.size == 0:
            peaks.append(np.zeros(0))
            continue
        lo = np.clip(idx - 2, 0, n_bin - 1)
        hi = np.clip(idx + 2, 0, n_bin - 1)
        # centroid refinement over +-2 bins
        ks = np.arange(-2, 3)
        jj = np.clip(idx[:, None] + ks[None, :], lo[:, None], hi[:, None])
        wts = row[jj]
        peaks.append((wts * bin_c[jj]).sum(axis=1) / np.maximum(wts.sum(axis=1), 1e-12))
    return centres, peaks


def _link_tracks(peaks: list[FloatArray], cfg: MainlineConfig) -> list[_RawTrack]:
    """Greedy nearest-neighbour linking of column peaks into tracks."""
    max_gap = max(1, round(cfg.lane_max_gap_m / cfg.lane_column_m))
    tracks: list[_RawTrack] = []
    active: list[int] = []
    for c, pk in enumerate(peaks):
        active = [i for i in active if c - tracks[i].cols[-1] <= max_gap]
        used_p: set[int] = set()
        used_t: set[int] = set()
        if active and pk.size:
            pred = np.array([tracks[i].predict(c) for i in active])
            cost = np.abs(pk[:, None] - pred[None, :])
            for flat in np.argsort(cost, axis=None):
                pi, ti = divmod(int(flat), len(active))
                if cost[pi, ti] > cfg.lane_link_m:
                    break
                if pi in used_p or ti in used_t:
                    continue
                used_p.add(pi)
                used_t.add(ti)
                tr = tracks[active[ti]]
                tr.cols.append(c)
                tr.d.append(float(pk[pi]))
        for pi in range(pk.size):
            if pi not in used_p:
                tracks.append(_RawTrack([c], [float(pk[pi])]))
                active.append(len(tracks) - 1)
    return tracks


def _mark_type(s_samples: FloatArray, lo: float, hi: float, cfg: MainlineConfig) -> str:
    """``broken`` if long gaps between samples cover a large part of [lo, hi]."""
    ss = np.sort(s_samples[(s_samples >= lo) & (s_samples <= hi)])
    if ss.size < 3 or hi - lo <= 0:
        return "solid"
    gaps = np.diff(np.concatenate([[lo], ss, [hi]]))
    spacing = float(np.median(np.diff(ss))) if ss.size > 1 else 0.0
    limit = max(cfg.broken_gap_m, 3.0 * spacing)
    frac = float(np.sum(gaps[gaps > limit])) / (hi - lo)
    return "broken" if frac > cfg.broken_gap_fraction else "solid"


def fit_outer_edge(
    s: FloatArray, d: FloatArray, grid: FloatArray, *, config: MainlineConfig | None = None
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    """Outer road edge ``d_E(s)`` on ``grid`` from the outer-side edge points.

    The outer side also holds ramp edges beyond a gore and outward outliers (guardrails,
    vegetation), so the mainline edge is taken as the LOWEST cluster of offsets (near the
    first quartile of each bin). Steps (gores, where the edge jumps by a lane) split the
    fit into independent segments.

    Returns
    -------
    d_edge : (G,) offsets, metres (NaN only if there are no points at all).
    breaks : stations of the steps, metres.
    used : (N,) mask of the points that belong to the mainline edge.
    covered : (G,) grid stations with edge points within 3 m (False in occlusion gaps).
    """
    cfg = config or MainlineConfig()
    step = float(grid[1] - grid[0])
    used = np.zeros(s.size, dtype=bool)
    ok = np.isfinite(s) & np.isfinite(d) & (d > 0.5)
    if np.count_nonzero(ok) < 10:
        return np.full(grid.size, np.nan), np.zeros(0), used, np.zeros(grid.size, dtype=bool)
    bin_m = 2.0
    cgrid = _grid(float(grid[0]), float(grid[-1]), bin_m)
    cedges = np.concatenate([cgrid - 0.5 * bin_m, [cgrid[-1] + 0.5 * bin_m]])
    q_raw = binned_quantile(s[ok], d[ok], cedges, 0.25)
    q = moving_median(q_raw, window=5)
    have = np.isfinite(q)
    if not np.any(have):
        return np.full(grid.size, np.nan), np.zeros(0), used, np.zeros(grid.size, dtype=bool)
    qi = np.nonzero(have)[0]
    jumps = np.nonzero(np.abs(np.diff(q[qi])) > 1.0)[0]
    breaks = 0.5 * (cgrid[qi[jumps]] + cgrid[qi[jumps + 1]])
    # refine each step with the points: the low level starts (step down, an exit gore)
    # or ends (step up, an entry gore) exactly where the edge jumps
    sv, dv = s[ok], d[ok]
    for n, j in enumerate(jumps):
        q0, q1 = q[qi[j]], q[qi[j + 1]]
        low = min(q0, q1)
        win = (np.abs(sv - breaks[n]) < 10.0) & (np.abs(dv - low) < 0.5)
        if np.count_nonzero(win) >= 4:
            ss = np.sort(sv[win])
            breaks[n] = float(ss[1] if q1 < q0 else ss[-2])
    # a real step has edge points right before and after it; an occlusion gap has none
    real = [
        np.count_nonzero((sv >= b - 5.0) & (sv < b)) >= 3
        and np.count_nonzero((sv > b) & (sv <= b + 5.0)) >= 3
        for b in breaks
    ]
    breaks = breaks[np.asarray(real, dtype=bool)] if breaks.size else breaks
    # on the grid, so that edge segments and lane sections start at the same station
    breaks = grid[0] + step * np.rint((breaks - grid[0]) / step)
    bounds = np.concatenate([[grid[0] - 1.0], breaks, [grid[-1] + 1.0]])
    # lower-cluster reference per segment (the moving median must not mix the levels of
    # two sides of a step)
    qf = np.full(cgrid.size, np.nan)
    seg_of_bin = np.searchsorted(bounds, cgrid, side="right") - 1
    for k in range(bounds.size - 1):
        sel_b = seg_of_bin == k
        if np.any(sel_b):
            qf[sel_b] = moving_median(q_raw[sel_b], window=5)
    qf = _fill_nan(cgrid, qf)
    ref = qf[np.clip(np.rint((s - cgrid[0]) / bin_m).astype(np.int64), 0, cgrid.size - 1)]
    used = ok & (np.abs(d - ref) < 0.8)
    out = np.full(grid.size, np.nan)
    for a, b in itertools.pairwise(bounds):
        gsel = (grid >= a) & (grid < b)
        psel = used & (s >= a) & (s < b)
        if np.count_nonzero(gsel) < 4 or np.count_nonzero(psel) < 10:
            continue
        g = grid[gsel]
        fit, _, _ = robust_offset_fit(
            s[psel],
            d[psel],
            g,
            cutoff_m=cfg.edge_smoothing_m,
            mad_k=cfg.edge_outlier_mad,
            min_threshold_m=cfg.edge_outlier_min_m,
        )
        out[gsel] = fit
    su = np.sort(s[used])
    if su.size:
        pos = np.clip(np.searchsorted(su, grid), 1, su.size - 1)
        near = np.minimum(np.abs(grid - su[pos - 1]), np.abs(su[pos] - grid))
        covered = near < 3.0
    else:
        covered = np.zeros(grid.size, dtype=bool)
    if np.all(np.isnan(out)):
        out = _fill_nan(grid, np.interp(grid, cgrid, qf))
    else:
        # fill short unfitted segments by nearest value (keeps steps sharp)
        idx = np.nonzero(np.isfinite(out))[0]
        nearest = idx[np.clip(np.searchsorted(idx, np.arange(grid.size)), 0, idx.size - 1)]
        out = np.where(np.isfinite(out), out, out[nearest])
    return out, breaks, used, covered


def fit_lanes(
    s_lane: FloatArray,
    d_lane: FloatArray,
    s_outer: FloatArray,
    d_outer: FloatArray,
    *,
    length: float,
    sign: float,
    config: MainlineConfig | None = None,
) -> tuple[tuple[LaneSection, ...], tuple[LaneEvent, ...], tuple[BoundaryTrack, ...], FloatArray]:
    """Lane sections from lane samples and outer-edge points in the reference frame.

    Parameters
    ----------
    s_lane, d_lane
        Stations and offsets from the reference edge towards the carriageway (metres)
        of the lane-marking samples.
    s_outer, d_outer
        The same for the outer road-edge points.
    length
        Road length (metres).
    sign
        +1 right-hand traffic (lanes get negative ids), -1 left-hand traffic.

    Returns
    -------
    lane sections, lane events, marking tracks, mask of the outer-edge points used.
    """
    cfg = config or MainlineConfig()
    grid = np.minimum(_grid(0.0, length, cfg.grid_step_m), length)
    d_edge, breaks, used, covered = fit_outer_edge(s_outer, d_outer, grid, config=cfg)
    keep = (s_lane >= 0) & (s_lane <= length) & (d_lane > -0.5)
    if np.all(np.isfinite(d_edge)):
        keep &= d_lane < np.interp(s_lane, grid, d_edge) + 0.3
    s_l, d_l = s_lane[keep], d_lane[keep]
    tracks = _tracks_from_samples(s_l, d_l, grid, length, cfg)
    if not np.all(np.isfinite(d_edge)):
        last = max((float(np.max(tr.d)) for tr in tracks), default=3.0)
        d_edge = np.full(grid.size, last + 2.5)
        breaks = np.zeros(0)
    else:
        d_edge = _bridge_edge_gaps(d_edge, covered, tracks, grid)
    tracks = _add_hidden_lanes(tracks, grid, d_edge, cfg)
    sections, events, out_tracks = _sections_from_tracks(tracks, grid, d_edge, breaks, sign, cfg)
    return sections, events, out_tracks, used


@dataclass
class _Track:
    id: int
    lo: float
    hi: float
    s: FloatArray  # stations of d (grid or column centres)
    d: FloatArray
    mark: str
    n: int
    s_samples: FloatArray


def _tracks_from_samples(
    s: FloatArray, d: FloatArray, grid: FloatArray, length: float, cfg: MainlineConfig
) -> list[_Track]:
    """Marking tracks: histogram peaks linked along s, false positives removed, samples
    assigned exclusively to the nearest track, each track smoothed robustly."""
    if s.size < 10:
        return []
    centres, peaks = _find_track_peaks(s, d, length, cfg)
    raw = _link_tracks(peaks, cfg)
    col = cfg.lane_column_m
    cand: list[_Track] = []
    for tr in raw:
        lo = centres[tr.cols[0]] - 0.5 * col
        hi = centres[tr.cols[-1]] + 0.5 * col
        if hi - lo < cfg.lane_min_track_m:
            continue
        cand.append(
            _Track(len(cand), lo, hi, centres[tr.cols], np.asarray(tr.d), "solid", 0, s[:0])
        )
    if not cand:
        return []
    dist = np.full((len(cand), s.size), np.inf)
    for k, tr in enumerate(cand):
        inside = (s >= tr.lo - col) & (s <= tr.hi + col)
        dist[k, inside] = np.abs(d[inside] - np.interp(s[inside], tr.s, tr.d))
    owner = np.argmin(dist, axis=0)
    best = dist[owner, np.arange(s.size)]
    final: list[_Track] = []
    for k in range(len(cand)):
        sel = (owner == k) & (best < cfg.lane_assign_m)
        if np.count_nonzero(sel) < 10:
            continue
        ss_all = s[sel]
        lo, hi = float(np.min(ss_all)), float(np.max(ss_all))
        if hi - lo < cfg.lane_min_track_m:
            continue
        g = grid[(grid >= lo) & (grid <= hi)]
        if g.size < 4:
            continue
        fit, inl, _ = robust_offset_fit(
            ss_all,
            d[sel],
            g,
            cutoff_m=cfg.lane_smoothing_m,
            mad_k=cfg.edge_outlier_mad,
            min_threshold_m=cfg.edge_outlier_min_m,
        )
        keep_g = _trim_ramp_lines(g, fit, cfg)
        if np.count_nonzero(keep_g) * cfg.grid_step_m < cfg.lane_min_track_m:
            continue
        g, fit = g[keep_g], fit[keep_g]
        lo, hi = float(g[0]), float(g[-1])
        ss = ss_all[inl]
        ss = ss[(ss >= lo - 1.0) & (ss <= hi + 1.0)]
        mark = _mark_type(ss, lo, hi, cfg)
        final.append(_Track(len(final), lo, hi, g, fit, mark, int(ss.size), np.sort(ss)))
    return _merge_collinear(final, cfg)


def _trim_ramp_lines(g: FloatArray, d: FloatArray, cfg: MainlineConfig) -> NDArray[np.bool_]:
    """Mask of the part of a marking track that belongs to the mainline.

    Ramp markings cross the mainline corridor near a gore: before an entry gore they come
    in from outside, converging steeply (d decreasing), after an exit gore they leave
    (d increasing). A track's leading part that converges steeply and its trailing part
    that diverges steeply are cut off. (Lane tapers of the mainline itself open outward at
    their start and close inward at their end, so they are kept.)
    """
    keep = np.ones(g.size, dtype=bool)
    if g.size < 5:
        return keep
    slope = np.gradient(d, g)
    steep = cfg.ramp_line_slope
    # leading part: converging inward steeply
    flat = np.flatnonzero(slope > -steep)
    if flat.size == 0:
        return np.zeros(g.size, dtype=bool)  # converging all along: a ramp line
    if flat[0] > 0 and (g[flat[0]] - g[0]) >= 10.0:
        keep[: flat[0]] = False
    flat = np.flatnonzero(slope < steep)
    if flat.size == 0:
        return np.zeros(g.size, dtype=bool)
    if flat[-1] < g.size - 1 and (g[-1] - g[flat[-1]]) >= 10.0:
        keep[flat[-1] + 1 :] = False
    return keep


def _last_marking(tracks: list[_Track], grid: FloatArray) -> FloatArray:
    """Offset of the outermost marking track at each grid station (-inf where none)."""
    d_last = np.full(grid.size, -np.inf)
    for tr in tracks:
        sel = (grid >= tr.lo) & (grid <= tr.hi)
        d_last[sel] = np.maximum(d_last[sel], np.interp(grid[sel], tr.s, tr.d))
    return d_last


def _bridge_edge_gaps(
    d_edge: FloatArray, covered: NDArray[np.bool_], tracks: list[_Track], grid: FloatArray
) -> FloatArray:
    """Across occlusion gaps of the outer edge, keep the outer-shoulder width (edge minus
    outermost marking) linear between the gap ends instead of the edge offset itself, so
    the edge follows markings that were seen (tapers, gores inside the gap)."""
    d_last = _last_marking(tracks, grid)
    out = d_edge.copy()
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (~covered).astype(np.int8), [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if a == 0 or b >= grid.size or b - a < 5:
            continue
        i0, i1 = a - 1, b
        if not (np.isfinite(d_last[i0]) and np.isfinite(d_last[i1])):
            continue
        hw0, hw1 = d_edge[i0] - d_last[i0], d_edge[i1] - d_last[i1]
        x = (grid[a:b] - grid[i0]) / (grid[i1] - grid[i0])
        inner = d_last[a:b]
        ok = np.isfinite(inner)
        hw = (1 - x) * hw0 + x * hw1
        # a lane that starts/ends inside the gap (a gore): each side keeps its own width
        jump = np.flatnonzero(np.abs(np.diff(d_last[i0 : i1 + 1])) > 1.5)
        if jump.size == 1:
            hw = np.where(np.arange(b - a) < jump[0], hw0, hw1)
        out[a:b][ok] = inner[ok] + hw[ok]
    return out


def _add_hidden_lanes(
    tracks: list[_Track], grid: FloatArray, d_edge: FloatArray, cfg: MainlineConfig
) -> list[_Track]:
    """Infer an unobserved outer marking where the outer shoulder is a lane too wide.

    Markings far from the car may not be sampled (e.g. the outer line of a two-lane
    deceleration lane). Where the outermost marking is more than
    ``hidden_lane_min_m`` farther from the observed outer edge than the run's typical
    hard-shoulder width, a marking is placed that typical width inside the edge.
    """
    if not tracks:
        return tracks
    d_last = _last_marking(tracks, grid)
    gap = np.where(np.isfinite(d_last), d_edge - d_last, np.nan)
    if not np.any(np.isfinite(gap)):
        return tracks
    hw = float(np.nanmedian(gap))
    wide = np.isfinite(gap) & (gap > hw + cfg.hidden_lane_min_m)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], wide.astype(np.int8), [0]])))
    out = list(tracks)
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if (b - a) * cfg.grid_step_m < cfg.lane_min_track_m:
            continue
        g = grid[a:b]
        out.append(
            _Track(len(out), float(g[0]), float(g[-1]), g, d_edge[a:b] - hw, "solid", 0, g[:0])
        )
        log.info("mainline: unobserved marking inferred at s=%.0f..%.0f m", g[0], g[-1])
    return out


def _merge_collinear(tracks: list[_Track], cfg: MainlineConfig) -> list[_Track]:
    """Join a track that ends and another that starts at the same offset (occlusion)."""
    tracks = sorted(tracks, key=lambda tr: tr.lo)
    merged = True
    while merged:
        merged = False
        for i, a in enumerate(tracks):
            for j, b in enumerate(tracks):
                if i == j or b.lo <= a.hi - 1.0 or b.lo - a.hi > 5.0 * cfg.lane_max_gap_m:
                    continue
                if abs(a.d[-1] - b.d[0]) > cfg.lane_link_m:
                    continue
                tracks[i] = _Track(
                    a.id,
                    a.lo,
                    b.hi,
                    np.concatenate([a.s, b.s]),
                    np.concatenate([a.d, b.d]),
                    a.mark if a.n >= b.n else b.mark,
                    a.n + b.n,
                    np.concatenate([a.s_samples, b.s_samples]),
                )
                del tracks[j]
                merged = True
                break
            if merged:
                break
    return [replace(tr, id=k) for k, tr in enumerate(tracks)]


def _smoothstep(x: FloatArray) -> FloatArray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _taper(
    dmat: FloatArray, k: int, grid: FloatArray, end: str, cfg: MainlineConfig
) -> tuple[float, float, int] | None:
    """Extend track ``k`` at its start/end to where it meets its nearest neighbour.

    The separation from the neighbour is modelled as a smoothstep (cubic) taper whose
    mid-point and slope are measured where the separation passes half the full width.
    ``dmat`` is filled in place over the unobserved part of the taper. Returns
    ``(s_zero, taper_length, neighbour)`` or None if the track starts/ends at full width.
    """
    n_g = grid.size
    idx = np.nonzero(np.isfinite(dmat[k]))[0]
    i_edge = int(idx[0] if end == "start" else idx[-1])
    others = [j for j in range(dmat.shape[0]) if j != k and np.isfinite(dmat[j, i_edge])]
    if not others:
        return None
    jn = min(others, key=lambda j: abs(dmat[k, i_edge] - dmat[j, i_edge]))
    span = int(300.0 / cfg.grid_step_m)
    sl = (
        slice(i_edge, min(i_edge + span, n_g))
        if end == "start"
        else slice(max(i_edge - span, 0), i_edge + 1)
    )
    both = np.isfinite(dmat[k, sl]) & np.isfinite(dmat[jn, sl])
    gs = grid[sl][both]
    sep = np.abs(dmat[k, sl] - dmat[jn, sl])[both]
    if gs.size < 10:
        return None
    w_full = float(np.percentile(sep, 90))
    sep0 = float(np.abs(dmat[k, i_edge] - dmat[jn, i_edge]))
    if w_full < 1.0 or sep0 > 0.7 * w_full:
        return None
    mid = (sep > 0.3 * w_full) & (sep < 0.7 * w_full)
    if np.count_nonzero(mid) < 3:
        return None
    slope, icpt = np.polyfit(gs[mid], sep[mid], 1)
    if abs(slope) < 1e-4:
        return None
    s50 = (0.5 * w_full - icpt) / slope
    taper = float(min(1.5 * w_full / abs(slope), cfg.lane_taper_max_m))
    sgn = np.sign(dmat[k, i_edge] - dmat[jn, i_edge])
    s_edge = float(grid[i_edge])
    if end == "start":
        s_zero = float(np.clip(s50 - 0.5 * taper, grid[0], s_edge))
        fill = (grid >= s_zero) & (grid < s_edge)
        x = (grid[fill] - s_zero) / taper
    else:
        s_zero = float(np.clip(s50 + 0.5 * taper, s_edge, grid[-1]))
        fill = (grid > s_edge) & (grid <= s_zero)
        x = (s_zero - grid[fill]) / taper
    ok = fill & np.isfinite(dmat[jn])
    dmat[k, ok] = dmat[jn, ok] + sgn * w_full * _smoothstep(x[ok[fill]])
    return s_zero, taper, jn


def _sections_from_tracks(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    breaks: FloatArray,
    sign: float,
    cfg: MainlineConfig,
) -> tuple[tuple[LaneSection, ...], tuple[LaneEvent, ...], tuple[BoundaryTrack, ...]]:
    """Lane sections (constant set of tracks), lane links, road marks and lane events."""
    length = float(grid[-1])
    side: Literal["right", "left"] = "right" if sign > 0 else "left"
    n_g = grid.size
    dmat = np.full((len(tracks), n_g), np.nan)
    for k, tr in enumerate(tracks):
        lo = grid[0] if tr.lo - grid[0] < cfg.lane_max_gap_m else tr.lo
        hi = length if length - tr.hi < cfg.lane_max_gap_m else tr.hi
        sel = (grid >= lo) & (grid <= hi)
        dmat[k, sel] = np.interp(grid[sel], tr.s, tr.d)
    # births / ends inside the run
    raw_events: list[tuple[int, str, float, float, int | None]] = []
    for k in range(len(tracks)):
        for end in ("start", "end"):
            idx = np.nonzero(np.isfinite(dmat[k]))[0]
            if idx.size == 0:
                continue
            i_edge = idx[0] if end == "start" else idx[-1]
            if (end == "start" and i_edge == 0) or (end == "end" and i_edge == n_g - 1):
                continue
            info = _taper(dmat, k, grid, end, cfg)
            if info is None:
                s_ev = float(grid[i_edge])
                if breaks.size and np.min(np.abs(breaks - s_ev)) < 20.0:
                    s_ev = float(breaks[np.argmin(np.abs(breaks - s_ev))])
                raw_events.append((k, end, s_ev, 0.0, None))
            else:
                raw_events.append((k, end, info[0], info[1], info[2]))
    # sections: runs of a constant set of tracks
    present = np.isfinite(dmat)
    codes = np.zeros(n_g, dtype=np.int64)
    for k in range(len(tracks)):
        codes = codes * 2 + present[k].astype(np.int64) if len(tracks) < 60 else codes
    change = np.nonzero(np.diff(codes) != 0)[0] + 1
    starts = [0, *change.tolist()]
    # edge steps start a section too
    forced: set[int] = set()
    for b in breaks:
        i_b = int(np.clip(np.rint((b - grid[0]) / cfg.grid_step_m), 1, n_g - 1))
        # track changes next to an edge step belong to the gore: move them onto the step
        starts = [i for i in starts if i == 0 or abs(i - i_b) * cfg.grid_step_m >= 20.0]
        starts.append(i_b)
        forced.add(i_b)
    starts = sorted(set(starts))
    min_n = max(1, int(cfg.min_section_m / cfg.grid_step_m))
    merged_starts = [starts[0]]
    for i in starts[1:]:
        if n_g - i < min_n:
            continue
        if i - merged_starts[-1] >= min_n:
            merged_starts.append(i)
        elif i in forced and merged_starts[-1] != 0 and merged_starts[-1] not in forced:
            merged_starts[-1] = i
    starts = [*merged_starts, n_g]
    sections: list[LaneSection] = []
    bounds_per: list[list[tuple[object, object]]] = []
    members_per: list[list[int]] = []
    for a, b in itertools.pairwise(starts):
        b_inc = min(b + 1, n_g)
        votes = present[:, a:b].mean(axis=1)
        members = [k for k in range(len(tracks)) if votes[k] > 0.5]
        members.sort(key=lambda k: float(np.nanmedian(dmat[k, a:b])))
        gs = grid[a:b_inc]
        rel = gs - grid[a]
        rows = [np.zeros(gs.size)]
        labels: list[object] = ["ref"]
        for k in members:
            rows.append(_fill_nan(gs, dmat[k, a:b_inc]))
            labels.append(k)
        e = d_edge[a:b_inc].copy()
        if b_inc > b and b < n_g and abs(d_edge[b] - d_edge[b - 1]) > 0.5:
            e[-1] = 2 * e[-2] - e[-3] if e.size >= 3 else e[-2]  # no step inside
        rows.append(e)
        labels.append("edge")
        stack = np.maximum.accumulate(np.vstack(rows), axis=0)
        n_l = len(stack) - 1
        lanes: list[Lane] = []
        bounds: list[tuple[object, object]] = []
        for i in range(n_l):
            width = np.clip(stack[i + 1] - stack[i], 0.0, None)
            lane_type = "shoulder" if i in (0, n_l - 1) else "driving"
            if i == n_l - 1:
                mark = "none"
            else:
                tr = tracks[labels[i + 1]]  # type: ignore[index]
                mark = (
                    _mark_type(tr.s_samples, float(gs[0]), float(gs[-1]), cfg)
                    if gs[-1] - gs[0] >= 4 * cfg.broken_gap_m
                    else tr.mark
                )
            prof = fit_cubic_profile(rel, width, tolerance=cfg.lane_width_tolerance_m)
            lid = -(i + 1) if sign > 0 else i + 1
            lanes.append(Lane(lid, lane_type, prof, (RoadMark(0.0, mark),)))  # type: ignore[arg-type]
            bounds.append((labels[i], labels[i + 1]))
        sections.append(_make_section(float(grid[a]), lanes, sign))
        bounds_per.append(bounds)
        members_per.append(members)
    sections = _link_sections(sections, bounds_per)
    events = _events(raw_events, sections, members_per, dmat, grid, side, sign)
    out_tracks = tuple(
        BoundaryTrack(
            tr.id,
            grid[np.isfinite(dmat[tr.id])],
            dmat[tr.id][np.isfinite(dmat[tr.id])],
            tr.mark,  # type: ignore[arg-type]
            tr.n,
        )
        for tr in tracks
    )
    return tuple(sections), events, out_tracks


def _make_section(s0: float, lanes: list[Lane], sign: float) -> LaneSection:
    return LaneSection(s0, right=tuple(lanes)) if sign > 0 else LaneSection(s0, left=tuple(lanes))


def _side_lanes(sec: LaneSection) -> tuple[Lane, ...]:
    return sec.right if sec.right else sec.left


def _link_sections(
    sections: list[LaneSection], bounds_per: list[list[tuple[object, object]]]
) -> list[LaneSection]:
    """Lane predecessor/successor ids between consecutive sections of the road.

    Lanes with the same pair of borders continue; the shoulders always continue; a lane
    that shares one border with an unmatched lane continues unless it opens from zero
    width (a lane birth) / closes to zero width (a lane end).
    """
    preds: list[dict[int, int]] = [{} for _ in sections]
    succs: list[dict[int, int]] = [{} for _ in sections]
    for n in range(1, len(sections)):
        prev, cur = bounds_per[n - 1], bounds_per[n]
        prev_lanes, cur_lanes = _side_lanes(sections[n - 1]), _side_lanes(sections[n])
        prev_len = sections[n].s0 - sections[n - 1].s0
        mapping: dict[int, int] = {}
        for i, bd in enumerate(cur):
            for j, pb in enumerate(prev):
                if bd == pb:
                    mapping[i] = j
        mapping.setdefault(0, 0)
        if len(cur) - 1 not in mapping and len(prev) - 1 not in mapping.values():
            mapping[len(cur) - 1] = len(prev) - 1
        used = set(mapping.values())
        for i, bd in enumerate(cur):
            if i in mapping or float(cur_lanes[i].width.value(0.0)) < 0.3:
                continue
            for j, pb in enumerate(prev):
                if j in used or float(prev_lanes[j].width.value(prev_len)) < 0.3:
                    continue
                if bd[0] == pb[0] or bd[1] == pb[1]:
                    mapping[i] = j
                    used.add(j)
                    break
        for i, j in mapping.items():
            preds[n][i] = prev_lanes[j].id
            succs[n - 1][j] = cur_lanes[i].id
    out = []
    for n, sec in enumerate(sections):
        lanes = tuple(
            replace(ln, predecessor=preds[n].get(i), successor=succs[n].get(i))
            for i, ln in enumerate(_side_lanes(sec))
        )
        out.append(replace(sec, right=lanes) if sec.right else replace(sec, left=lanes))
    return out


def _events(
    raw_events: list[tuple[int, str, float, float, int | None]],
    sections: list[LaneSection],
    members_per: list[list[int]],
    dmat: FloatArray,
    grid: FloatArray,
    side: Literal["right", "left"],
    sign: float,
) -> tuple[LaneEvent, ...]:
    """Lane events: the lane between a track that starts/ends and its nearest neighbour."""
    s0s = np.array([sec.s0 for sec in sections])
    events = []
    for k, end, s_zero, taper, jn in raw_events:
        # the section where the lane exists: just after a birth, just before an end
        probe = s_zero + (1.0 + taper if end == "start" else -(1.0 + taper))
        probe = float(np.clip(probe, grid[0], grid[-1]))
        n = int(np.clip(np.searchsorted(s0s, probe, side="right") - 1, 0, len(sections) - 1))
        members = members_per[n]
        if k not in members:
            continue
        pos = members.index(k)
        i_p = int(np.clip(np.searchsorted(grid, probe), 0, grid.size - 1))
        # neighbour: the adjacent member nearer in offset
        cand = [p for p in (pos - 1, pos + 1) if 0 <= p < len(members)]
        if taper == 0.0:  # abrupt (gore): the lane whose outer border is the track
            outer_pos = pos
        elif jn is not None and jn in members:
            outer_pos = max(pos, members.index(jn))
        elif cand:
            p_nb = min(cand, key=lambda p: abs(dmat[members[p], i_p] - dmat[k, i_p]))
            outer_pos = max(pos, p_nb)
        else:
            outer_pos = pos
        lanes = _side_lanes(sections[n])
        lane_idx = outer_pos  # lane index whose outer border is member outer_pos
        if lane_idx == 0 and not cand:
            lane_idx = 1
        if lane_idx >= len(lanes) - 1:
            continue
        lane = lanes[lane_idx]
        driving = [ln for ln in lanes if ln.type == "driving"]
        position = (
            "outer" if driving and lane.id == driving[-1].id and len(driving) > 1 else "inner"
        )
        ds = probe - sections[n].s0
        events.append(
            LaneEvent(
                s_m=float(s_zero),
                kind="birth" if end == "start" else "end",
                side=side,
                lane_id=int(lane.id),
                position=position,  # type: ignore[arg-type]
                taper_m=float(taper),
                width_m=float(lane.width.value(ds)),
            )
        )
    return tuple(sorted(events, key=lambda e: e.s_m))


# ---------------------------------------------------------------------------
# paper method
# ---------------------------------------------------------------------------


def _build_paper(run: MappingRun, cfg: MainlineConfig, timings: dict[str, float]) -> _Partial:
    from sklearn.cluster import KMeans
    from sklearn.metrics import silhouette_score

    sign = _sign(run)
    rng = np.random.default_rng(cfg.seed)
    t0 = time.perf_counter()
    traj_xy = run.trajectory.xy
    traj_frame = PolylineFrame.from_points(resample_polyline(traj_xy, 1.0))
    ref_pts, outer_pts = _split_edges(run, traj_frame)
    s_ref, _ = traj_frame.project(ref_pts)
    win = cfg.paper_window_m
    n_win = max(1, math.ceil(traj_frame.length / win))
    pieces: list[Geometry] = []
    s0 = 0.0
    w_start = 0.0
    for w in range(n_win):
        w_end = min((w + 1) * win, traj_frame.length)
        sel = (s_ref >= w_start) & (s_ref < w_end)
        cover = float(np.ptp(s_ref[sel])) / max(w_end - w_start, 1e-9) if np.any(sel) else 0.0
        if (np.count_nonzero(sel) < 8 or cover < 0.6) and w < n_win - 1:
            continue  # too few points (occlusion): the window grows into the next one
        if np.count_nonzero(sel) < 8:
            break
        pts = ref_pts[sel, :2]
        # window frame: the trajectory heading over the window
        a_xy, _ = traj_frame.at(np.array([w_start]))
        b_xy, _ = traj_frame.at(np.array([w_end]))
        w_start = w_end
        direc = b_xy[0] - a_xy[0]
        ang = math.atan2(direc[1], direc[0])
        c, sn = math.cos(ang), math.sin(ang)
        loc = (pts - a_xy[0]) @ np.array([[c, -sn], [sn, c]])
        x, y = loc[:, 0], loc[:, 1]
        coef = np.polyfit(x, y, 3)[::-1]  # y = c0 + c1 x + c2 x^2 + c3 x^3
        # the cubic spans the whole window (also where occlusion left no points)
        xa, xb = 0.0, float(np.hypot(*direc))
        if xb - xa < 1.0 or np.ptp(x) < 5.0:
            continue
        # x(p) = xa + (xb - xa) p ; y(p) = poly(x(p)) -> cubic in p
        px = np.polynomial.Polynomial([xa, xb - xa])
        py = np.polynomial.Polynomial(coef)(px)
        U = np.pad(px.coef, (0, 4 - px.coef.size))
        V = np.pad(py.coef, (0, 4 - py.coef.size))[:4]
        start = np.array([U[0], V[0]])
        hdg_loc = math.atan2(V[1], U[1])
        cr, sr = math.cos(hdg_loc), math.sin(hdg_loc)
        rot = np.array([[cr, sr], [-sr, cr]])
        UV = np.stack([U, V], axis=1)
        UV[0] -= start
        UVr = UV @ rot.T
        x0 = a_xy[0] + np.array([c * start[0] - sn * start[1], sn * start[0] + c * start[1]])
        from .fitting import _cubic_arc_length

        coef_g = np.stack([UVr[:, 0], UVr[:, 1]], axis=1)
        length = _cubic_arc_length(coef_g)
        pieces.append(
            ParamPoly3(
                s0,
                float(x0[0]),
                float(x0[1]),
                ang + hdg_loc,
                length,
                aU=0.0,
                bU=float(UVr[1, 0]),
                cU=float(UVr[2, 0]),
                dU=float(UVr[3, 0]),
                aV=0.0,
                bV=0.0,
                cV=float(UVr[2, 1]),
                dV=float(UVr[3, 1]),
                p_range="normalized",
            )
        )
        s0 += length
    if not pieces:
        raise InputError("mainline (paper): no window has enough median-side edge points")
    base = Road("1", tuple(pieces), (LaneSection(0.0),), name="mainline")
    timings["reference_line"] = time.perf_counter() - t0

    # elevation: median within r of stations, smoothed, cubic per window
    t0 = time.perf_counter()
    from scipy.spatial import cKDTree

    poses = run.trajectory.xyz.copy()
    poses[:, 2] -= run.pose_height_m
    hpts = np.vstack([ref_pts, outer_pts, poses])
    tree = cKDTree(hpts[:, :2])
    st = np.arange(0.0, base.length, 1.0)
    cxy = base.xy(st)
    nbrs = tree.query_ball_point(cxy, cfg.elevation_radius_m)
    zmed = np.array([np.median(hpts[n, 2]) if n else np.nan for n in nbrs])
    zmed = _fill_nan(st, zmed)
    zs = savgol_smooth(zmed, window=21, polyorder=2)
    el_pieces = []
    for g in pieces:
        sel = (st >= g.s0) & (st <= g.s0 + g.length)
        if np.count_nonzero(sel) < 4:
            el_pieces.append(CubicPiece(g.s0, float(np.interp(g.s0, st, zs))))
            continue
        cf = np.polyfit(st[sel] - g.s0, zs[sel], 3)[::-1]
        el_pieces.append(CubicPiece(g.s0, *map(float, cf)))
    elevation = CubicProfile(tuple(el_pieces))
    timings["elevation"] = time.perf_counter() - t0

    # lanes: K-means per window on lateral offsets
    t0 = time.perf_counter()
    s_l, t_l = base.project(run.lane_samples)
    s_o, t_o = base.project(outer_pts)
    d_l, d_o = -sign * t_l, -sign * t_o
    sections: list[LaneSection] = []
    for g in pieces:
        lo, hi = g.s0, g.s0 + g.length
        # outer edge (the paper does not say): cubic through the window's nearest outer-
        # side edge points (ramp edges and outliers lie farther out)
        so = (s_o >= lo) & (s_o < hi) & (d_o > 0.5)
        edge_cf = None
        if np.count_nonzero(so) >= 8:
            be = np.arange(lo, hi + 5.0, 5.0)
            q25 = binned_quantile(s_o[so], d_o[so], be, 0.25)
            qb = np.clip(np.searchsorted(be, s_o[so], side="right") - 1, 0, q25.size - 1)
            idx = np.flatnonzero(so)
            so[idx[~(np.abs(d_o[so] - q25[qb]) < 0.5)]] = False
            if np.count_nonzero(so) >= 4 and np.ptp(s_o[so]) > 0.6 * (hi - lo):
                edge_cf = np.polyfit(s_o[so] - lo, d_o[so], 3)[::-1]
            elif np.count_nonzero(so) >= 1:
                edge_cf = np.array([float(np.median(d_o[so])), 0.0, 0.0, 0.0])
        d_max = 30.0 if edge_cf is None else float(np.polyval(edge_cf[::-1], 0.5 * (hi - lo))) + 0.3
        sel = (s_l >= lo) & (s_l < hi) & (d_l > -1.0) & (d_l < d_max)
        ds_ = s_l[sel] - lo
        dd = d_l[sel]
        bounds: list[FloatArray] = []
        if dd.size >= 20:
            X = dd[:, None]
            sub = rng.choice(dd.size, size=min(dd.size, 500), replace=False)
            best_k, best_sc, best_lab = 1, -1.0, None
            for k in range(2, cfg.paper_max_clusters + 1):
                if k >= sub.size:
                    break
                km = KMeans(n_clusters=k, n_init=1, random_state=cfg.seed).fit(X[sub])
                sc = silhouette_score(X[sub], km.labels_)
                if sc > best_sc:
                    best_k, best_sc, best_lab = k, sc, km
            if best_lab is not None:
                lab = best_lab.predict(X)
                order = np.argsort(best_lab.cluster_centers_[:, 0])
                for c_i in order:
                    m = lab == c_i
                    if np.count_nonzero(m) < 4:
                        continue
                    cf = np.polyfit(ds_[m], dd[m], 3)[::-1]
                    bounds.append(cf)
            del best_k
        if edge_cf is None:
            last = bounds[-1][0] if bounds else 3.0
            edge_cf = np.array([last + 2.5, 0.0, 0.0, 0.0])
        borders = [np.zeros(4), *bounds, edge_cf]
        n_l = len(borders) - 1
        lanes = []
        for i in range(n_l):
            wc = borders[i + 1] - borders[i]
            lane_type = "shoulder" if i in (0, n_l - 1) else "driving"
            mark = "none" if i == n_l - 1 else ("solid" if i in (0, n_l - 2) else "broken")
            lid = -(i + 1) if sign > 0 else i + 1
            lanes.append(
                Lane(
                    lid,
                    lane_type,
                    CubicProfile((CubicPiece(0.0, *map(float, wc)),)),  # type: ignore[arg-type]
                    (RoadMark(0.0, mark),),
                )  # type: ignore[arg-type]
            )
        sections.append(
            LaneSection(lo, right=tuple(lanes)) if sign > 0 else LaneSection(lo, left=tuple(lanes))
        )
    timings["lanes"] = time.perf_counter() - t0
    road = replace(
        base,
        elevation=elevation,
        lane_sections=tuple(sections),
        lane_offset=CubicProfile.constant(0.0),
    )
    return _Partial(road, (), "paper")


# ---------------------------------------------------------------------------
# self-consistency (the paper's metric)
# ---------------------------------------------------------------------------


def self_consistency(road: Road, run: MappingRun) -> dict[str, float]:
    """RMSE of ``e = |t_measured - t_boundary(s)|`` (the paper's Table 4), metres.

    Edge points are compared with the nearer of the two road edges (reference line and
    the outer border of the outermost lane), lane samples with the nearest lane boundary
    (outer borders of all lanes but the outermost) at their station. Only points between
    the two road edges (plus 1 m for edge points, 0.5 m for lane samples) count, as in the
    paper's corridor; ``<kind>_fraction_used`` says how many did.
    """
    frame = _road_frame(road)
    out: dict[str, float] = {}
    errs = {}
    used: dict[str, float] = {}
    for name, pts in (("road_edge", run.edges), ("lane_boundary", run.lane_samples)):
        if pts.shape[0] == 0:
            errs[name] = np.zeros(0)
            continue
        s, t = frame.project(pts)
        ok = (s >= 0) & (s <= road.length)
        s, t = s[ok], t[ok]
        # only points on the carriageway (+- margin): ramp edges/markings beyond a gore
        # and points of other roads are not measurements of this road
        edges = _border_matrix(road, s, edges=True)[:2]
        margin = 1.0 if name == "road_edge" else 0.5
        inside = (t >= np.nanmin(edges, axis=0) - margin) & (t <= np.nanmax(edges, axis=0) + margin)
        s, t = s[inside], t[inside]
        used[name] = float(np.mean(inside)) if inside.size else 0.0
        borders = _border_matrix(road, s, edges=(name == "road_edge"))
        errs[name] = np.nanmin(np.abs(borders - t[None, :]), axis=0)
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
        n = len(side)
        ids = [ln.id for ln in side]
        if edges:
            rows[0, sel] = road.lane_border_t(s[sel], 0)
            if ids:
                rows[1, sel] = road.lane_border_t(s[sel], ids[-1])
        else:
            for j, lid in enumerate(ids[: n - 1]):
                rows[j, sel] = road.lane_border_t(s[sel], lid)
    return rows


# ---------------------------------------------------------------------------
# cutting a road
# ---------------------------------------------------------------------------


def _cut_geometry(g: Geometry, a: float, b: float, s_new: float) -> Geometry:
    """The part of piece ``g`` between road stations ``a`` and ``b`` (exact)."""
    x, y, h, k = g.evaluate(np.array([a, b]))
    length = b - a
    if isinstance(g, ParamPoly3):
        L = g.length
        if g.p_range == "normalized":
            pa, pb = (a - g.s0) / L, (b - g.s0) / L
            sub = np.polynomial.Polynomial([pa, pb - pa])
        else:
            pa = a - g.s0
            sub = np.polynomial.Polynomial([pa, 1.0])
        U = np.polynomial.Polynomial([g.aU, g.bU, g.cU, g.dU])(sub)
        V = np.polynomial.Polynomial([g.aV, g.bV, g.cV, g.dV])(sub)
        Uc = np.pad(U.coef, (0, 4 - U.coef.size))[:4]
        Vc = np.pad(V.coef, (0, 4 - V.coef.size))[:4]
        UV = np.stack([Uc, Vc], axis=1)
        UV[0] = 0.0
        # rotate the old local frame to the tangent at the cut: new hdg = h[0]
        rel = float(h[0]) - g.hdg
        c, sn = math.cos(rel), math.sin(rel)
        UVr = UV @ np.array([[c, -sn], [sn, c]])
        return ParamPoly3(
            s_new,
            float(x[0]),
            float(y[0]),
            float(h[0]),
            length,
            aU=0.0,
            bU=float(UVr[1, 0]),
            cU=float(UVr[2, 0]),
            dU=float(UVr[3, 0]),
            aV=0.0,
            bV=float(UVr[1, 1]),
            cV=float(UVr[2, 1]),
            dV=float(UVr[3, 1]),
            p_range=g.p_range,
        )
    if isinstance(g, Spiral):
        return Spiral(
            s_new,
            float(x[0]),
            float(y[0]),
            float(h[0]),
            length,
            curv_start=float(k[0]),
            curv_end=float(k[1]),
        )
    if isinstance(g, Arc):
        return Arc(
            s_new, float(x[0]), float(y[0]), float(h[0]), length, curvature_per_m=g.curvature_per_m
        )
    if isinstance(g, Line):
        return Line(s_new, float(x[0]), float(y[0]), float(h[0]), length)
    if math.isclose(a, g.s0) and math.isclose(b, g.s0 + g.length):
        return replace(g, s0=s_new)
    msg = f"cut_road: cannot cut a {type(g).__name__} piece exactly"
    raise FitError(msg)


def _cut_profile(prof: CubicProfile, a: float, b: float) -> CubicProfile:
    """Profile restricted to [a, b] and re-based so that station a becomes 0."""
    if not prof.pieces:
        return prof
    s0s = np.array([p.s0 for p in prof.pieces])
    i0 = max(int(np.searchsorted(s0s, a, side="right")) - 1, 0)
    out = [shift_cubic_piece(prof.pieces[i0], a)]
    out.extend(p for p in prof.pieces[i0 + 1 :] if p.s0 < b - 1e-9)
    return CubicProfile(tuple(replace(p, s0=p.s0 - a) for p in out))


def _cut_lane(lane: Lane, ds: float, keep_pred: bool, keep_succ: bool, span: float) -> Lane:
    width = _cut_profile(lane.width, ds, ds + span)
    marks = [m for m in lane.road_marks if m.s_offset <= ds + 1e-9]
    later = [
        replace(m, s_offset=m.s_offset - ds)
        for m in lane.road_marks
        if ds + 1e-9 < m.s_offset < ds + span
    ]
    first = [replace(marks[-1], s_offset=0.0)] if marks else []
    return replace(
        lane,
        width=width,
        road_marks=tuple(first + later),
        predecessor=lane.predecessor if keep_pred else None,
        successor=lane.successor if keep_succ else None,
    )


def cut_road(road: Road, s_start: float, s_end: float, *, road_id: str) -> Road:
    """The exact part of ``road`` between stations ``s_start`` and ``s_end``.

    Geometry pieces are cut by re-expanding them about the cut (ParamPoly3: the cubic is
    re-parametrised and rotated to the local heading, so positions and headings are
    identical to the original's); elevation, superelevation, lane offset and lane widths
    are Taylor-shifted; lane sections are clipped; stations are re-based to 0. Road links
    are cleared, and lane links at the two cut ends (inner lane links are kept).

    Parameters
    ----------
    road
        The road to cut.
    s_start, s_end
        Stations on ``road`` (metres), ``0 <= s_start < s_end <= road.length``.
    road_id
        Id of the new road.
    """
    length = road.length
    a = float(np.clip(s_start, 0.0, length))
    b = float(np.clip(s_end, 0.0, length))
    if not b > a:
        msg = f"cut_road: need s_start < s_end within [0, {length:.3f}], got {s_start}, {s_end}"
        raise InputError(msg)
    geo: list[Geometry] = []
    for g in road.geometry:
        ga, gb = g.s0, g.s0 + g.length
        lo, hi = max(a, ga), min(b, gb)
        if hi - lo <= 1e-9:
            continue
        geo.append(_cut_geometry(g, lo, hi, lo - a))
    sec_s0 = np.array([sc.s0 for sc in road.lane_sections])
    i0 = max(int(np.searchsorted(sec_s0, a, side="right")) - 1, 0)
    secs = [road.lane_sections[i0]] + [
        sc for sc in road.lane_sections[i0 + 1 :] if sc.s0 < b - 1e-9
    ]
    new_secs: list[LaneSection] = []
    for j, sc in enumerate(secs):
        sa = max(sc.s0, a)
        nxt = secs[j + 1].s0 if j + 1 < len(secs) else b
        span = min(nxt, b) - sa
        ds = sa - sc.s0
        first, last = j == 0, j == len(secs) - 1
        fn = lambda ln, f=first, l_=last, d_=ds, sp=span: _cut_lane(ln, d_, not f, not l_, sp)  # noqa: E731
        new_secs.append(
            replace(
                sc,
                s0=sa - a,
                left=tuple(fn(ln) for ln in sc.left),
                right=tuple(fn(ln) for ln in sc.right),
                center=fn(sc.center),
            )
        )
    return replace(
        road,
        id=road_id,
        geometry=tuple(geo),
        lane_sections=tuple(new_secs),
        elevation=_cut_profile(road.elevation, a, b),
        superelevation=None
        if road.superelevation is None
        else _cut_profile(road.superelevation, a, b),
        lane_offset=_cut_profile(road.lane_offset, a, b),
        predecessor=None,
        successor=None,
    )
