"""Default method: lane markings as tracks, outer edge, lane sections and events."""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from ..fitting import (
    binned_quantile,
    fit_cubic_profile,
    moving_median,
)
from ..model import (
    Lane,
    LaneSection,
    RoadMark,
    continue_width,
)
from ._common import (
    BoundaryTrack,
    LaneEvent,
    _fill_nan,
    _grid,
    robust_offset_fit,
)
from .gores import (
    ShoulderTaper,
    fit_shoulder_taper,
    fuse_gore_estimates,
    marking_gore_interval,
    smoothstep,
    taper_width,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


@dataclass
class _RawTrack:
    cols: list[int]
    d: list[float]
    slope: float = 0.0

    def add(self, col: int, value: float) -> None:
        """Append a column and update the slope (least squares over the last 4 columns,
        clipped to +-0.5 m per column)."""
        self.cols.append(col)
        self.d.append(value)
        if len(self.d) < 3:
            return
        c = self.cols[-4:]
        v = self.d[-4:]
        n = len(c)
        cm, vm = sum(c) / n, sum(v) / n
        var = 0.0
        cov = 0.0
        for ci, vi in zip(c, v, strict=True):
            var += (ci - cm) * (ci - cm)
            cov += (ci - cm) * (vi - vm)
        self.slope = min(max(cov / var, -0.5), 0.5)

    def predict(self, col: int) -> float:
        """Offset extrapolated linearly from the last few columns to column ``col``."""
        return self.d[-1] + self.slope * (col - self.cols[-1])


def _find_track_peaks(
    s: FloatArray, d: FloatArray, length: float, cfg: MainlineConfig
) -> tuple[FloatArray, list[FloatArray]]:
    """Marking peaks per histogram column: column centres and the peak offsets in each.

    All columns are searched in one ``find_peaks`` call: the columns are laid end to end,
    separated by zero padding at least as wide as the peak distance, so that neither the
    distance nor the prominence test reaches across columns.
    """
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
    bin_c = d_lo + (np.arange(n_bin) + 0.5) * cfg.lane_bin_m
    pad = min_dist + 1
    stride = n_bin + pad
    flat = np.zeros((n_col, stride))
    flat[:, :n_bin] = hist
    idx, _ = find_peaks(flat.ravel(), height=thr, distance=min_dist, prominence=0.5 * thr)
    row, j = np.divmod(idx, stride)
    # a column's first/last bin is never a peak (as for a search per column)
    inner = (j > 0) & (j < n_bin - 1)
    row, j = row[inner], j[inner]
    ks = np.arange(-2, 3)
    jj = np.clip(j[:, None] + ks[None, :], 0, n_bin - 1)
    wts = hist[row[:, None], jj]
    # centroid refinement over +-2 bins
    ref = (wts * bin_c[jj]).sum(axis=1) / np.maximum(wts.sum(axis=1), 1e-12)
    split = np.searchsorted(row, np.arange(1, n_col))
    peaks = np.split(ref, split)
    return centres, peaks


def _link_tracks(peaks: list[FloatArray], cfg: MainlineConfig) -> list[_RawTrack]:
    """Greedy nearest-neighbour linking of column peaks into tracks."""
    max_gap = max(1, round(cfg.lane_max_gap_m / cfg.lane_column_m))
    tracks: list[_RawTrack] = []
    active: list[int] = []
    for c, pk in enumerate(peaks):
        active = [i for i in active if c - tracks[i].cols[-1] <= max_gap]
        used_p: set[int] = set()
        if active and pk.size:
            used_t: set[int] = set()
            pred = np.array([tracks[i].predict(c) for i in active])
            cost = np.abs(pk[:, None] - pred[None, :])
            n_ok = int(np.count_nonzero(cost <= cfg.lane_link_m))
            if n_ok:
                order = np.argsort(cost, axis=None, kind="stable")[:n_ok]
                for flat in order.tolist():
                    pi, ti = divmod(flat, len(active))
                    if pi in used_p or ti in used_t:
                        continue
                    used_p.add(pi)
                    used_t.add(ti)
                    tracks[active[ti]].add(c, float(pk[pi]))
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


def _refine_step(s: FloatArray, d: FloatArray, s_step: float, low: float, *, starts: bool) -> float:
    """Station (metres, sub-metre) where the low level of an outer-edge step starts
    (``starts``: exit gore) or ends (entry gore), from the points within 10 m.

    The step lies half a mean point spacing before the first (after the last) point of
    the low level; an isolated first (last) point more than 5 m from the next one is an
    outlier.
    """
    win = (np.abs(s - s_step) < 10.0) & (np.abs(d - low) < 0.5)
    if np.count_nonzero(win) < 4:
        return s_step
    ss = np.sort(s[win])
    if not starts:
        ss = -ss[::-1]  # mirror: the last point of the low level becomes the first
    if ss[1] - ss[0] > 5.0:
        ss = ss[1:]
    spacing = (ss[-1] - ss[0]) / (ss.size - 1)
    edge = float(ss[0] - 0.5 * spacing)
    return edge if starts else -edge


def fit_outer_edge(
    s: FloatArray,
    d: FloatArray,
    grid: FloatArray,
    *,
    config: MainlineConfig | None = None,
    hidden_steps: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.bool_]]:
    """Outer road edge ``d_E(s)`` on ``grid`` from the outer-side edge points.

    The outer side also holds ramp edges beyond a gore and outward outliers (guardrails,
    vegetation), so the mainline edge is taken as the LOWEST cluster of offsets (near the
    first quartile of each bin). Steps (gores, where the edge jumps by a lane) split the
    fit into independent segments.

    ``hidden_steps`` (metres) are steps that an occlusion hid (gores placed from other
    evidence); the fit is split there too, so that it does not bend across them.

    Returns
    -------
    d_edge : (G,) offsets, metres (NaN only if there are no points at all).
    breaks : stations of the steps, metres.
    used : (N,) mask of the points that belong to the mainline edge.
    covered : (G,) grid stations with edge points within 3 m (False in occlusion gaps).
    """
    cfg = config or MainlineConfig()
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
    # or ends (step up, an entry gore) where the edge jumps (the high level goes on as
    # the ramp's edge, so only the low level tells)
    sv, dv = s[ok], d[ok]
    for n, j in enumerate(jumps):
        q0, q1 = q[qi[j]], q[qi[j + 1]]
        breaks[n] = _refine_step(sv, dv, float(breaks[n]), min(q0, q1), starts=q1 < q0)
    # a real step has edge points right before and after it; an occlusion gap has none
    real = [
        np.count_nonzero((sv >= b - 5.0) & (sv < b)) >= 3
        and np.count_nonzero((sv > b) & (sv <= b + 5.0)) >= 3
        for b in breaks
    ]
    breaks = breaks[np.asarray(real, dtype=bool)] if breaks.size else breaks
    if hidden_steps is not None and len(hidden_steps):
        breaks = np.sort(np.concatenate([breaks, np.asarray(hidden_steps, dtype=float)]))
    # kept off the grid: a lane section starts exactly at a step (the first grid station of
    # its segment is the first one at or after it), as its edge segment does
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
    tracks, evidence = _tracks_from_samples(
        s_l, d_l, grid, length, cfg, d_edge if np.all(np.isfinite(d_edge)) else None
    )
    if not np.all(np.isfinite(d_edge)):
        last = max((float(np.max(tr.d)) for tr in tracks), default=3.0)
        d_edge = np.full(grid.size, last + 2.5)
        breaks = np.zeros(0)
    else:
        tracks, gores = _snap_to_hidden_gores(tracks, evidence, covered, grid, cfg)
        taper_length = _visible_taper_length(
            breaks, d_edge, tracks, s_outer[used], d_outer[used], grid
        )
        tracks, placed, tapers = _place_hidden_gores(
            tracks, s_outer[used], d_outer[used], covered, grid, taper_length
        )
        # a placed gore replaces the ramp-line estimate of the same gore
        hidden = [g for g in gores if all(abs(g - p) > 40.0 for p in placed)] + placed
        if hidden:
            d_edge, breaks, used, covered = fit_outer_edge(
                s_outer, d_outer, grid, config=cfg, hidden_steps=np.asarray(hidden)
            )
        d_edge = _bridge_edge_gaps(d_edge, covered, tracks, grid, tapers)
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
    s_samples: FloatArray  # stations of the inlier samples, sorted
    d_samples: FloatArray = field(default_factory=lambda: np.zeros(0))  # their offsets


def _tracks_from_samples(
    s: FloatArray,
    d: FloatArray,
    grid: FloatArray,
    length: float,
    cfg: MainlineConfig,
    d_edge: FloatArray | None = None,
) -> tuple[list[_Track], list[tuple[float, float]]]:
    """Marking tracks: histogram peaks linked along s, false positives removed, samples
    assigned exclusively to the nearest track, each track smoothed robustly.

    Also returns ``(s, d)`` where ramp lines crossing the corridor were cut off (they meet
    or leave a mainline marking there: gore evidence)."""
    if s.size < 10:
        return [], []
    centres, peaks = _find_track_peaks(s, d, length, cfg)
    raw = _link_tracks(peaks, cfg)
    col = cfg.lane_column_m
    s_first, s_last = float(np.min(s)), float(np.max(s))

    def too_short(lo: float, hi: float) -> bool:
        """Shorter than ``lane_min_track_m``, unless the run's start or end cuts it (then
        it only has to be ``lane_min_cut_track_m`` long)."""
        if hi - lo >= cfg.lane_min_track_m:
            return False
        cut = lo <= s_first + 2.0 * col or hi >= s_last - 2.0 * col
        return not (cut and hi - lo >= cfg.lane_min_cut_track_m)

    cand: list[_Track] = []
    for tr in raw:
        lo = centres[tr.cols[0]] - 0.5 * col
        hi = centres[tr.cols[-1]] + 0.5 * col
        if too_short(lo, hi):
            continue
        cand.append(
            _Track(len(cand), lo, hi, centres[tr.cols], np.asarray(tr.d), "solid", 0, s[:0])
        )
    if not cand:
        return [], []
    # each sample belongs to the nearest candidate track (the first one on ties); the
    # samples are sorted by station so that a track only looks at its own window
    order = np.argsort(s, kind="stable")
    s, d = s[order], d[order]
    best = np.full(s.size, np.inf)
    owner = np.full(s.size, -1, dtype=np.int64)
    windows: list[tuple[int, int]] = []
    for k, tr in enumerate(cand):
        i0 = int(np.searchsorted(s, tr.lo - col, side="left"))
        i1 = int(np.searchsorted(s, tr.hi + col, side="right"))
        windows.append((i0, i1))
        dk = np.abs(d[i0:i1] - np.interp(s[i0:i1], tr.s, tr.d))
        better = dk < best[i0:i1]
        best[i0:i1][better] = dk[better]
        owner[i0:i1][better] = k
    final: list[_Track] = []
    evidence: list[tuple[float, float]] = []
    for k, (i0, i1) in enumerate(windows):
        sel = i0 + np.flatnonzero((owner[i0:i1] == k) & (best[i0:i1] < cfg.lane_assign_m))
        if sel.size < 10:
            continue
        ss_all = s[sel]
        lo, hi = float(np.min(ss_all)), float(np.max(ss_all))
        if too_short(lo, hi):
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
            local_sigma_ends_m=2.0 * cfg.lane_smoothing_m,
        )
        keep_g = _trim_ramp_lines(g, fit, cfg)
        if not keep_g[-1] or not keep_g[0]:
            # a ramp line: where it meets / leaves the corridor's marking is a gore
            if keep_g.any():
                i_in = np.flatnonzero(keep_g)
                i_g = i_in[0] - 1 if not keep_g[0] else i_in[-1] + 1
            else:
                i_g = g.size - 1 if fit[-1] < fit[0] else 0
            evidence.append((float(g[i_g]), float(fit[i_g])))
        if not keep_g.any():
            continue
        g_in = g[keep_g]
        if too_short(float(g_in[0]), float(g_in[-1]) + cfg.grid_step_m):
            continue
        g, fit = g[keep_g], fit[keep_g]
        lo, hi = float(g[0]), float(g[-1])
        ss, dd = ss_all[inl], d[sel][inl]
        within = (ss >= lo - 1.0) & (ss <= hi + 1.0)
        ss, dd = ss[within], dd[within]  # sorted by station already
        mark = _mark_type(ss, lo, hi, cfg)
        final.append(_Track(len(final), lo, hi, g, fit, mark, int(ss.size), ss, dd))
    return _merge_collinear(final, cfg, grid, d_edge), evidence


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


def _snap_to_hidden_gores(
    tracks: list[_Track],
    evidence: list[tuple[float, float]],
    covered: NDArray[np.bool_],
    grid: FloatArray,
    cfg: MainlineConfig,
) -> tuple[list[_Track], FloatArray]:
    """Place gores that an occlusion of the outer edge hid.

    A ramp line that meets (entry) or leaves (exit) the outermost mainline marking inside
    an occlusion gap marks the gore; an outer marking that starts or ends abruptly in the
    same gap is cut or extended to that station (ramp markings upstream of an entry gore
    otherwise make the lane start early). Returns the tracks and the gore stations.
    """
    gores: list[float] = []
    out = list(tracks)
    step = cfg.grid_step_m

    def hidden(s_at: float) -> bool:
        i = int(np.clip(np.rint((s_at - grid[0]) / step), 0, grid.size - 1))
        return not covered[max(i - 10, 0) : i + 11].all()

    # a marking that starts (ends) inside such a gap while still converging (diverging)
    # is a ramp line until it runs parallel: the gore is where it does
    for k, tr in enumerate(out):
        if tr.s.size < 20:
            continue
        slope = np.gradient(tr.d, tr.s)
        if tr.lo > grid[0] + step and hidden(tr.lo):
            par = np.flatnonzero(slope > -cfg.hidden_gore_slope)
            if par.size and par[0] > 0 and tr.s[par[0]] - tr.lo >= 5.0:
                i0 = par[0]
                tr = replace(tr, lo=float(tr.s[i0]), s=tr.s[i0:], d=tr.d[i0:])
                gores.append(tr.lo)
        if tr.hi < grid[-1] - step and hidden(tr.hi):
            slope = np.gradient(tr.d, tr.s)
            par = np.flatnonzero(slope < cfg.hidden_gore_slope)
            if par.size and par[-1] < tr.s.size - 1 and tr.hi - tr.s[par[-1]] >= 5.0:
                i1 = par[-1] + 1
                tr = replace(tr, hi=float(tr.s[i1 - 1]), s=tr.s[:i1], d=tr.d[:i1])
                gores.append(tr.hi)
        out[k] = tr
    for s_g, d_g in evidence:
        i_g = int(np.clip(np.rint((s_g - grid[0]) / step), 0, grid.size - 1))
        # inside (or within 10 m of) a gap of the outer-edge points
        lo_i, hi_i = max(i_g - 10, 0), min(i_g + 11, grid.size)
        if covered[lo_i:hi_i].all():
            continue
        # it must touch a mainline marking there
        near = [
            tr
            for tr in out
            if tr.lo - 1 <= s_g <= tr.hi + 1 and abs(np.interp(s_g, tr.s, tr.d) - d_g) < 1.0
        ]
        if not near:
            continue
        s_gore = float(grid[i_g])
        if any(abs(g - s_gore) < 30.0 for g in gores):
            continue
        gores.append(s_gore)
        for k, tr in enumerate(out):
            if abs(tr.lo - s_gore) < 60.0 and tr.lo < s_gore - step and tr.hi > s_gore + 60.0:
                sel = tr.s >= s_gore
                out[k] = replace(tr, lo=s_gore, s=tr.s[sel], d=tr.d[sel])
            elif abs(tr.hi - s_gore) < 60.0 and tr.hi > s_gore + step and tr.lo < s_gore - 60.0:
                sel = tr.s <= s_gore
                out[k] = replace(tr, hi=s_gore, s=tr.s[sel], d=tr.d[sel])
    return out, np.asarray(gores, dtype=float)


def _gap_runs(covered: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """Index ranges ``[a, b)`` of the grid stations without outer-edge points."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (~covered).astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def _place_hidden_gores(
    tracks: list[_Track],
    s_out: FloatArray,
    d_out: FloatArray,
    covered: NDArray[np.bool_],
    grid: FloatArray,
    taper_length_m: float | None = None,
) -> tuple[list[_Track], list[float], list[ShoulderTaper]]:
    """Gore stations inside occlusion gaps of the outer edge.

    For an outer marking that starts (entry) or ends (exit) inside a gap while the through
    lanes' outer marking runs on, the gore is placed by the marking's solid/broken change
    and the hard-shoulder taper seen before (entry) / after (exit) the gap
    (:mod:`roadtwin.mainline.gores`), and the marking is cut or extended to it. ``s_out``,
    ``d_out``: the outer-edge points of the mainline edge (metres, reference frame).
    Where the taper was not seen at all, the run's own taper length at gores that were
    seen (``taper_length_m``) shapes it, if the shoulder was seen at full width up to
    where that taper would begin.
    Returns the tracks, the gore stations placed and the shoulder tapers.
    """
    out = list(tracks)
    placed: list[float] = []
    tapers: list[ShoulderTaper] = []
    step = float(grid[1] - grid[0])
    # where the sensor saw any marking (a gap of all of them is missing frames)
    seen = np.sort(np.concatenate([t.s_samples for t in tracks])) if tracks else None
    for a, b in _gap_runs(covered):
        if a == 0 or b >= grid.size:
            continue
        s_a, s_b = float(grid[a]), float(grid[b - 1])
        for k in range(len(out)):
            for entry in (True, False):
                tr = out[k]
                s_tip = tr.lo if entry else tr.hi
                beyond = tr.hi - s_b if entry else s_a - tr.lo
                if not (s_a - step <= s_tip <= s_b + step) or tr.s.size < 20 or beyond < 20.0:
                    continue
                d_tip = float(tr.d[0] if entry else tr.d[-1])
                through = [
                    t
                    for t in out
                    if t is not tr
                    and t.lo <= s_tip - 40.0
                    and t.hi >= s_tip + 40.0
                    and np.interp(s_tip, t.s, t.d) < d_tip - 1.0
                ]
                if not through:
                    continue
                nb = max(through, key=lambda t: float(np.interp(s_tip, t.s, t.d)))
                interval = marking_gore_interval(nb.s_samples, s_tip, entry=entry, seen_s=seen)
                if entry:
                    sel = (s_out > max(s_a - 200.0, nb.lo)) & (s_out < s_a)
                else:
                    sel = (s_out > s_b) & (s_out < min(s_b + 200.0, nb.hi))
                width = d_out[sel] - np.interp(s_out[sel], nb.s, nb.d)
                taper = fit_shoulder_taper(s_out[sel], width, entry=entry)
                if interval is None and taper is None:
                    continue
                s_gore = fuse_gore_estimates(interval, taper, s_tip)
                if abs(s_gore - s_tip) > 40.0:
                    continue
                out[k] = _move_track_end(tr, s_gore, grid, start=entry)
                placed.append(s_gore)
                if taper is not None:
                    tapers.append(replace(taper, s_gore=s_gore))
                elif taper_length_m is not None and width.size >= 10:
                    s_w = s_out[sel]
                    near = np.abs(s_w - (s_a if entry else s_b)) < 30.0
                    begins = s_gore - taper_length_m if entry else s_gore + taper_length_m
                    seen_flat = begins >= s_a - 10.0 if entry else begins <= s_b + 10.0
                    if np.count_nonzero(near) >= 10 and seen_flat:
                        full = float(np.median(width[near]))
                        tapers.append(ShoulderTaper(s_gore, taper_length_m, full, entry, math.nan))
                log.info(
                    "mainline: %s gore in an occlusion gap at s=%.1f m (marking interval %s, "
                    "shoulder taper %s)",
                    "entry" if entry else "exit",
                    s_gore,
                    "none" if interval is None else f"{interval[0]:.1f}..{interval[1]:.1f}",
                    "none" if taper is None else f"{taper.s_gore:.1f}",
                )
    return out, placed, tapers


def _visible_taper_length(
    steps: FloatArray,
    d_edge: FloatArray,
    tracks: list[_Track],
    s_out: FloatArray,
    d_out: FloatArray,
    grid: FloatArray,
) -> float | None:
    """Median length (metres) of the hard-shoulder tapers fitted at the seen edge steps
    (gores), or None if none could be fitted."""
    d_last = _last_marking(tracks, grid)
    lengths = []
    for b in steps:
        i = int(np.searchsorted(grid, b))
        if i < 5 or i + 5 >= grid.size:
            continue
        entry = bool(d_edge[i + 3] > d_edge[i - 3])  # the edge steps out: a lane begins
        sel = (s_out > b - 200.0) & (s_out < b) if entry else (s_out > b) & (s_out < b + 200.0)
        mark = np.interp(s_out[sel], grid, d_last)
        ok = np.isfinite(mark)
        fit = fit_shoulder_taper(s_out[sel][ok], d_out[sel][ok] - mark[ok], entry=entry)
        if fit is not None and abs(fit.s_gore - b) < 5.0:
            lengths.append(fit.length_m)
    return float(np.median(lengths)) if lengths else None


def _move_track_end(tr: _Track, s_new: float, grid: FloatArray, *, start: bool) -> _Track:
    """``tr`` cut or extended (at its end offset) so that it starts/ends at ``s_new``."""
    if start:
        if s_new >= tr.lo:
            sel = tr.s >= s_new
            new_s, new_d = tr.s[sel], tr.d[sel]
            if new_s.size == 0 or new_s[0] > s_new:
                new_s = np.concatenate([[s_new], new_s])
                new_d = np.concatenate([[np.interp(s_new, tr.s, tr.d)], new_d])
        else:
            ext = np.concatenate([[s_new], grid[(grid > s_new) & (grid < tr.s[0])]])
            new_s = np.concatenate([ext, tr.s])
            new_d = np.concatenate([np.full(ext.size, tr.d[0]), tr.d])
        return replace(tr, lo=s_new, s=new_s, d=new_d)
    if s_new <= tr.hi:
        sel = tr.s <= s_new
        new_s, new_d = tr.s[sel], tr.d[sel]
        if new_s.size == 0 or new_s[-1] < s_new:
            new_s = np.concatenate([new_s, [s_new]])
            new_d = np.concatenate([new_d, [np.interp(s_new, tr.s, tr.d)]])
    else:
        ext = np.concatenate([grid[(grid < s_new) & (grid > tr.s[-1])], [s_new]])
        new_s = np.concatenate([tr.s, ext])
        new_d = np.concatenate([tr.d, np.full(ext.size, tr.d[-1])])
    return replace(tr, hi=s_new, s=new_s, d=new_d)


def _hermite01(x: FloatArray, v0: float, m0: float) -> FloatArray:
    """Cubic from value ``v0`` with slope ``m0`` (per unit x) at x = 0 to value 0 with
    slope 0 at x = 1."""
    return v0 * (1.0 - x * x * (3.0 - 2.0 * x)) + m0 * x * (1.0 - x) ** 2


def _last_marking(tracks: list[_Track], grid: FloatArray) -> FloatArray:
    """Offset of the outermost marking track at each grid station (-inf where none)."""
    d_last = np.full(grid.size, -np.inf)
    for tr in tracks:
        sel = (grid >= tr.lo) & (grid <= tr.hi)
        d_last[sel] = np.maximum(d_last[sel], np.interp(grid[sel], tr.s, tr.d))
    return d_last


def _bridge_edge_gaps(
    d_edge: FloatArray,
    covered: NDArray[np.bool_],
    tracks: list[_Track],
    grid: FloatArray,
    tapers: list[ShoulderTaper] | None = None,
) -> FloatArray:
    """Across occlusion gaps of the outer edge, keep the outer-shoulder width (edge minus
    outermost marking) linear between the gap ends instead of the edge offset itself, so
    the edge follows markings that were seen (tapers, gores inside the gap). A shoulder
    taper fitted at a gore in the gap (``tapers``) gives the width on its side."""
    d_last = _last_marking(tracks, grid)
    out = d_edge.copy()
    for a, b in _gap_runs(covered):
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
        # a lane that starts/ends inside the gap (a gore): each side keeps its own width,
        # unless the shoulder was seen narrowing towards the gore (entry) / widening from
        # it (exit): then it tapers linearly from / to zero width at the gore
        jump = np.flatnonzero(np.abs(np.diff(d_last[i0 : i1 + 1])) > 1.5)
        if jump.size == 1:
            j = int(jump[0])  # grid[a + j] is the first station after the gore
            k = np.arange(b - a)
            hw = np.where(k < j, hw0, hw1)
            s_jump = 0.5 * (grid[i0 + j] + grid[i0 + j + 1])
            fitted = [tp for tp in tapers or () if abs(tp.s_gore - s_jump) <= grid[1] - grid[0]]
            for tp in fitted:
                side = k < j if tp.entry else k >= j
                hw[side] = tp.width(grid[a:b][side])
            if fitted:
                out[a:b][ok] = inner[ok] + hw[ok]
                continue
            # the trend over 20 m, 5 m away from the gap (the fit bends at its ends); the
            # taper continues with the observed slope and reaches zero width flat (cubic)
            i_a, i_b = i0 - 25, i0 - 5
            if i_a >= 0 and np.all(np.isfinite(d_last[[i_a, i_b]])) and j > 0:
                narrowing = (d_edge[i_a] - d_last[i_a]) - (d_edge[i_b] - d_last[i_b])
                if narrowing > 0.5:
                    before = k <= j
                    x = (k[before] + 1) / (j + 1)
                    m0 = -narrowing / 20.0 * (grid[a + j] - grid[i0])
                    hw[before] = np.maximum(_hermite01(x, hw0, m0), 0.0)
            i_a, i_b = i1 + 5, i1 + 25
            n_after = b - a - (j + 1)
            if i_b < grid.size and np.all(np.isfinite(d_last[[i_a, i_b]])) and n_after > 0:
                widening = (d_edge[i_b] - d_last[i_b]) - (d_edge[i_a] - d_last[i_a])
                if widening > 0.5:
                    after = k > j
                    x = (n_after - (k[after] - j - 1)) / (n_after + 1)  # 1 at the gore
                    m1 = -widening / 20.0 * (grid[i1] - grid[a + j + 1])
                    hw[after] = np.maximum(_hermite01(x, hw1, m1), 0.0)
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


def _merge_collinear(
    tracks: list[_Track],
    cfg: MainlineConfig,
    grid: FloatArray | None = None,
    d_edge: FloatArray | None = None,
) -> list[_Track]:
    """Join a track that ends and another that starts at the same offset (occlusion).

    With the outer edge ``d_edge`` on ``grid``: never across a stretch where the road is
    too narrow to hold the marking (the edge comes within half a metre of the bridged
    line): there the marking really ended and another began (an exit and a later entry at
    the same offset), it was not hidden.
    """

    def road_holds(a: _Track, b: _Track) -> bool:
        if grid is None or d_edge is None:
            return True
        inside = (grid > a.hi) & (grid < b.lo)
        if not np.any(inside):
            return True
        x = (grid[inside] - a.hi) / max(b.lo - a.hi, 1e-9)
        line = (1.0 - x) * a.d[-1] + x * b.d[0]
        edge = d_edge[inside]
        return not np.any(np.isfinite(edge) & (edge < line + 0.5))

    tracks = sorted(tracks, key=lambda tr: tr.lo)
    merged = True
    while merged:
        merged = False
        for i, a in enumerate(tracks):
            for j, b in enumerate(tracks):
                if i == j or b.lo <= a.hi - 1.0 or b.lo - a.hi > 5.0 * cfg.lane_max_gap_m:
                    continue
                if abs(a.d[-1] - b.d[0]) > cfg.lane_link_m or not road_holds(a, b):
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
                    np.concatenate([a.d_samples, b.d_samples]),
                )
                del tracks[j]
                merged = True
                break
            if merged:
                break
    return [replace(tr, id=k) for k, tr in enumerate(tracks)]


def _taper(
    dmat: FloatArray,
    k: int,
    grid: FloatArray,
    end: str,
    cfg: MainlineConfig,
    fixed: tuple[float, float] | None = None,
    samples: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[float, float, int] | None:
    """Extend track ``k`` at its start/end to where it meets its nearest neighbour.

    The separation from the neighbour is modelled as a smoothstep (cubic) taper whose
    mid-point and slope are measured where the separation passes half the full width.
    ``dmat`` is filled in place over the unobserved part of the taper. Returns
    ``(s_zero, taper_length, neighbour)`` or None if the track starts/ends at full width.
    ``fixed = (s_zero, taper)`` imposes the taper (an inferred marking that opens with
    an observed one) and overwrites the track over it. With the track's raw ``samples``
    (stations, offsets) the taper's zero station and length are refined by a least-squares
    fit of the cubic taper to them (:func:`_fit_taper`).
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
    # the side of the neighbour the track runs on where it is open (at its very end the
    # two may have met)
    sgn = float(np.sign(np.median((dmat[k, sl] - dmat[jn, sl])[both])))
    if fixed is not None and w_full >= 1.0:
        s_zero, taper = fixed
        if end == "start":
            dmat[k, grid < s_zero] = np.nan
            fill = (grid >= s_zero) & (grid < s_zero + taper)
            x = (grid[fill] - s_zero) / taper
        else:
            dmat[k, grid > s_zero] = np.nan
            fill = (grid > s_zero - taper) & (grid <= s_zero)
            x = (s_zero - grid[fill]) / taper
        ok = fill & np.isfinite(dmat[jn])
        dmat[k, ok] = dmat[jn, ok] + sgn * w_full * smoothstep(x[ok[fill]])
        return s_zero, taper, jn
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
    s_edge = float(grid[i_edge])
    if end == "start":
        s_zero = float(np.clip(s50 - 0.5 * taper, grid[0], s_edge))
    else:
        s_zero = float(np.clip(s50 + 0.5 * taper, s_edge, grid[-1]))
    refined = _fit_taper(samples, dmat[jn], grid, s_zero, taper, w_full, end, cfg)
    if refined is not None:
        # the taper model replaces the smoothed track over the whole taper: the smoother
        # rounds a taper's steep start off
        s_zero, taper = refined
        if end == "start":
            dmat[k, grid < s_zero] = np.nan
            fill = (grid >= s_zero) & (grid < s_zero + taper)
        else:
            dmat[k, grid > s_zero] = np.nan
            fill = (grid > s_zero - taper) & (grid <= s_zero)
    elif end == "start":
        fill = (grid >= s_zero) & (grid < s_edge)
    else:
        fill = (grid > s_edge) & (grid <= s_zero)
    x = (grid[fill] - s_zero) / taper if end == "start" else (s_zero - grid[fill]) / taper
    ok = fill & np.isfinite(dmat[jn])
    dmat[k, ok] = dmat[jn, ok] + sgn * w_full * smoothstep(x[ok[fill]])
    return s_zero, taper, jn


def _fit_taper(
    samples: tuple[FloatArray, FloatArray] | None,
    d_neighbour: FloatArray,
    grid: FloatArray,
    s_zero: float,
    taper: float,
    w_full: float,
    end: str,
    cfg: MainlineConfig,
) -> tuple[float, float] | None:
    """Zero-width station and length (metres) of a cubic lane taper fitted to the raw
    samples of the opening (``end == "start"``) or closing marking, as separations from
    its neighbour (offsets ``d_neighbour`` on ``grid``, NaN where it is absent), starting
    from ``(s_zero, taper)``. None if there are too few samples in the taper or the fit
    leaves the plausible range."""
    from scipy.optimize import least_squares

    if samples is None or samples[0].size < 15:
        return None
    s_raw, d_raw = samples
    lo, hi = (s_zero, s_zero + taper) if end == "start" else (s_zero - taper, s_zero)
    have = np.isfinite(d_neighbour)
    if np.count_nonzero(have) < 2:
        return None
    win = (s_raw >= lo - 0.25 * taper) & (s_raw <= hi + 0.25 * taper)
    s_w = s_raw[win]
    sep = np.abs(d_raw[win] - np.interp(s_w, grid[have], d_neighbour[have]))
    # the taper itself must be seen, not only the full-width lane beside it
    if np.count_nonzero((sep > 0.2 * w_full) & (sep < 0.8 * w_full)) < 10:
        return None

    def residual(p: FloatArray) -> FloatArray:
        return sep - taper_width(s_w, w_full, p[0], max(p[1], 1.0), entry=end == "end")

    res = least_squares(
        residual, np.array([s_zero, taper]), loss="soft_l1", f_scale=0.1, x_scale=10.0
    )
    s_fit, l_fit = float(res.x[0]), float(res.x[1])
    if not (5.0 <= l_fit <= cfg.lane_taper_max_m) or abs(s_fit - s_zero) > taper:
        return None
    return s_fit, l_fit


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
        # a track that stops short of the run's start/end was cut by it (the car saw no
        # more of it), unless an edge step (a gore) lies in between: there it really ends
        cut_start = not np.any((breaks >= grid[0]) & (breaks <= tr.lo + 5.0))
        cut_end = not np.any((breaks >= tr.hi - 5.0) & (breaks <= length))
        lo = grid[0] if tr.lo - grid[0] < cfg.lane_max_gap_m and cut_start else tr.lo
        hi = length if length - tr.hi < cfg.lane_max_gap_m and cut_end else tr.hi
        sel = (grid >= lo) & (grid <= hi)
        dmat[k, sel] = np.interp(grid[sel], tr.s, tr.d)
    # births / ends inside the run
    raw_events: list[tuple[int, str, float, float, int | None]] = []
    # observed markings first: an inferred (unobserved) one opens/closes like its sibling
    order = sorted(range(len(tracks)), key=lambda k: tracks[k].n == 0)
    for k in order:
        for end in ("start", "end"):
            idx = np.nonzero(np.isfinite(dmat[k]))[0]
            if idx.size == 0:
                continue
            i_edge = idx[0] if end == "start" else idx[-1]
            if (end == "start" and i_edge == 0) or (end == "end" and i_edge == n_g - 1):
                continue
            fixed = None
            if tracks[k].n == 0:
                sib = [
                    (s_z, tp)
                    for _, e2, s_z, tp, _ in raw_events
                    if e2 == end and tp > 0.0 and abs(s_z - grid[i_edge]) < 100.0
                ]
                fixed = sib[0] if sib else None
            raw = (tracks[k].s_samples, tracks[k].d_samples)
            info = _taper(dmat, k, grid, end, cfg, fixed, raw)
            if info is None:
                s_ev = float(grid[i_edge])
                if breaks.size and np.min(np.abs(breaks - s_ev)) < 20.0:
                    s_ev = float(breaks[np.argmin(np.abs(breaks - s_ev))])
                raw_events.append((k, end, s_ev, 0.0, None))
            else:
                raw_events.append((k, end, info[0], info[1], info[2]))
    # sections: runs of a constant set of tracks
    present = np.isfinite(dmat)
    change = np.flatnonzero(np.any(present[:, 1:] != present[:, :-1], axis=0)) + 1
    starts = [0, *change.tolist()]
    # edge steps start a section too
    forced: set[int] = set()
    s0_at: dict[int, float] = {}  # a section that starts at an edge step starts exactly there
    for b in breaks:
        i_b = int(np.clip(np.ceil((b - grid[0]) / cfg.grid_step_m - 1e-9), 1, n_g - 1))
        s0_at[i_b] = float(min(b, grid[i_b]))
        # track changes next to an edge step belong to the gore: move them onto the step
        starts = [i for i in starts if i == 0 or abs(i - i_b) * cfg.grid_step_m >= 20.0]
        starts.append(i_b)
        forced.add(i_b)
    starts = sorted(set(starts))
    min_n = max(1, int(cfg.min_section_m / cfg.grid_step_m))
    merged_starts = [starts[0]]
    for i in starts[1:]:
        # an edge step (a gore) starts a section even close to the run's end: the lane
        # that leaves there must not run on to the end
        min_tail = max(1, int(2.0 / cfg.grid_step_m)) if i in forced else min_n
        if n_g - i < min_tail:
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
        s0 = s0_at.get(a, float(grid[a]))
        rel = gs - s0
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
            lane_type = "shoulder" if n_l >= 3 and i in (0, n_l - 1) else "driving"
            if i == n_l - 1:
                mark = "none"
            else:
                tr = tracks[labels[i + 1]]  # type: ignore[index]
                mark = (
                    _mark_type(tr.s_samples, float(gs[0]), float(gs[-1]), cfg)
                    if gs[-1] - gs[0] >= 4 * cfg.broken_gap_m
                    else tr.mark
                )
            prof = fit_cubic_profile(
                rel, width, tolerance=cfg.lane_width_tolerance_m, shape_preserving=True
            )
            lid = -(i + 1) if sign > 0 else i + 1
            lanes.append(Lane(lid, lane_type, prof, (RoadMark(0.0, mark),)))  # type: ignore[arg-type]
            bounds.append((labels[i], labels[i + 1]))
        sections.append(_make_section(s0, lanes, sign))
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
            # a lane whose width jumps at the boundary (the hard shoulder at a gore: the
            # old one leaves with the ramp, the new one starts narrow) ends there
            w_prev = float(prev_lanes[j].width.value(prev_len))
            w_cur = float(cur_lanes[i].width.value(0.0))
            if abs(w_prev - w_cur) > 0.05:
                continue
            preds[n][i] = prev_lanes[j].id
            succs[n - 1][j] = cur_lanes[i].id
    out = []
    for n, sec in enumerate(sections):
        lanes = tuple(
            replace(ln, predecessor=preds[n].get(i), successor=succs[n].get(i))
            for i, ln in enumerate(_side_lanes(sec))
        )
        if n > 0:
            # linked lanes continue with the width they had (sections are fitted one by
            # one to 1 cm; the checker flags jumps above 1 mm)
            prev_len = sec.s0 - sections[n - 1].s0
            by_id = {ln.id: ln for ln in _side_lanes(out[n - 1])}
            lanes = tuple(
                continue_width(ln, float(by_id[ln.predecessor].width.value(prev_len)))
                if ln.predecessor in by_id
                else ln
                for ln in lanes
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
