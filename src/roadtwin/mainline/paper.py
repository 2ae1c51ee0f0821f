"""The seed paper's method (baseline): 100 m windows, K-means lanes."""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .._errors import InputError
from ..config import MainlineConfig
from ..fitting import (
    PolylineFrame,
    binned_quantile,
    local_cubic_piece,
    resample_polyline,
    savgol_smooth,
)
from ..io import MappingRun
from ..model import (
    CubicPiece,
    CubicProfile,
    Geometry,
    Lane,
    LaneSection,
    Road,
    RoadMark,
)
from ._common import (
    _fill_nan,
    _Partial,
    _sign,
    _split_edges,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


def _build_paper(run: MappingRun, cfg: MainlineConfig, timings: dict[str, float]) -> _Partial:
    from sklearn.cluster import KMeans
    from sklearn.metrics import silhouette_score
    from threadpoolctl import threadpool_limits

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
        from ..fitting import _cubic_arc_length

        coef_g = np.stack([UVr[:, 0], UVr[:, 1]], axis=1)
        length = _cubic_arc_length(coef_g)
        pieces.append(local_cubic_piece(s0, x0, ang + hdg_loc, UVr, length))
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
    # K-means on a few hundred 1-D points: OpenMP threads only add overhead (40x slower
    # on a busy 2-core machine), so one thread
    with threadpool_limits(limits=1):
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
            d_max = (
                30.0 if edge_cf is None else float(np.polyval(edge_cf[::-1], 0.5 * (hi - lo))) + 0.3
            )
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
                lane_type = "shoulder" if n_l >= 3 and i in (0, n_l - 1) else "driving"
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
                LaneSection(lo, right=tuple(lanes))
                if sign > 0
                else LaneSection(lo, left=tuple(lanes))
            )
    timings["lanes"] = time.perf_counter() - t0
    road = replace(
        base,
        elevation=elevation,
        lane_sections=tuple(sections),
        lane_offset=CubicProfile.constant(0.0),
    )
    return _Partial(road, (), "paper")
