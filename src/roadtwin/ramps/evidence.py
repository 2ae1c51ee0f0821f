"""LiDAR evidence of a ramp past its gore: the measured road edges and lane markings not
explained by the mainline, fitted as a spline offset from the through lane's outer border
(:func:`fit_ramp_evidence`).

All coordinates are in the mapping frame (metres, radians CCW from +x).
"""

from __future__ import annotations

import itertools
import logging

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..config import RampConfig
from ..fitting import arc_length, resample_polyline
from ..model import Road
from .geometry import _base_line, _mainline_boundary_distance, _smootherstep
from .records import (
    _EVIDENCE_LATERAL_M,
    _MIN_BOUNDARY_POINTS,
    _MIN_FIT_POINTS,
    FloatArray,
    RampEvidence,
    RampType,
    TrafficSide,
)

log = logging.getLogger(__name__)

_KNOTS_U = np.arange(0.15, 0.95, 0.15)  # spline knots, in units of evidence_length_m
_N_SHAPE = 2 + _KNOTS_U.size  # shape parameters of e(a) before the three widths


def _shape_basis(u: FloatArray) -> FloatArray:
    """``(N, _N_SHAPE)`` cubic-spline basis with ``e(0) = e'(0) = 0``: ``u^2``, ``u^3``
    and truncated cubes ``(u - k)_+^3`` at the knots."""
    u = np.asarray(u, dtype=float)
    cols = [u * u, u**3, *(np.maximum(u - k, 0.0) ** 3 for k in _KNOTS_U)]
    return np.stack(cols, axis=-1)


def _shape_dbasis(u: FloatArray) -> FloatArray:
    u = np.asarray(u, dtype=float)
    cols = [2.0 * u, 3.0 * u * u, *(3.0 * np.maximum(u - k, 0.0) ** 2 for k in _KNOTS_U)]
    return np.stack(cols, axis=-1)


def _poly_e(p: FloatArray, u: FloatArray) -> FloatArray:
    return _shape_basis(u) @ p[:_N_SHAPE]


def _poly_de(p: FloatArray, u: FloatArray) -> FloatArray:
    return _shape_dbasis(u) @ p[:_N_SHAPE]


def _fit_boundaries(
    a_scale: float,
    a_p: FloatArray,
    g_in: FloatArray,
    tau: FloatArray,
    is_edge: NDArray[np.bool_],
    coef_b: FloatArray,
    edge_b: NDArray[np.bool_],
    prior: FloatArray,
    prior_val: FloatArray,
    windows: tuple[float, ...],
) -> tuple[FloatArray, NDArray[np.int64] | None, FloatArray, NDArray[np.bool_]]:
    """Track the ramp outward from the gore: IRLS (Huber, 0.1 m) of
    ``[c2, c3, c4, w_in, w, w_hs]`` on the points up to each window in turn, each point
    re-associated with the nearest boundary of its kind predicted by the previous fit.
    Returns ``(p, assoc, resid, used)``; ``assoc`` is ``None`` when the first window has
    fewer than ``_MIN_FIT_POINTS`` points within the gate."""
    p = prior_val.copy()
    u = a_p / a_scale
    assoc = np.zeros(u.size, dtype=np.int64)
    resid = np.full(u.size, np.inf)
    used = np.zeros(u.size, dtype=bool)
    good = None
    u_lim = np.inf  # beyond the last window the prediction continues linearly
    for k, window in enumerate(windows):
        sel = a_p <= window
        gates = (1.5, 1.0, 0.7, 0.5, 0.4) if k == 0 else (1.0, 0.7, 0.5, 0.4)
        p_try = p.copy()
        failed = False
        for g_i, gate in enumerate(gates):
            if g_i == 0 and np.isfinite(u_lim):
                ul = np.array([u_lim])
                e = np.where(
                    u <= u_lim,
                    _poly_e(p_try, u),
                    _poly_e(p_try, ul)[0] + _poly_de(p_try, ul)[0] * (u - u_lim),
                )
            else:
                e = _poly_e(p_try, u)
            pred = e[:, None] + g_in[:, None] * (coef_b[:, 0] * p_try[_N_SHAPE])[None, :]
            pred += (coef_b[:, 1:] @ p_try[_N_SHAPE + 1 :])[None, :]
            r_all = tau[:, None] - pred
            r_all[is_edge[:, None] != edge_b[None, :]] = np.inf
            a_k = np.argmin(np.abs(r_all), axis=1)
            r_k = r_all[np.arange(u.size), a_k]
            ok = sel & (np.abs(r_k) <= gate)
            if np.count_nonzero(ok) < _MIN_FIT_POINTS:
                failed = True
                break
            w = np.where(np.abs(r_k) <= 0.1, 1.0, 0.1 / np.maximum(np.abs(r_k), 1e-9))[ok]
            cb = coef_b[a_k[ok]]
            cb[:, 0] *= g_in[ok]
            uo = u[ok]
            design = np.column_stack([_shape_basis(uo), cb])
            sw = np.sqrt(w)
            a_mat = np.vstack([design * sw[:, None], np.diag(np.sqrt(prior))])
            b_vec = np.concatenate([tau[ok] * sw, np.sqrt(prior) * prior_val])
            p_try = np.linalg.lstsq(a_mat, b_vec, rcond=None)[0]
        if failed:
            break
        p, assoc, resid, used = p_try, a_k, r_k, sel
        good = True
        u_lim = window / a_scale
        if window >= float(a_p.max()):
            break
    if good is None:
        return p, None, resid, used
    return p, assoc, resid, used


def fit_ramp_evidence(
    ref_xy: FloatArray,
    mainline_road: Road,
    *,
    ramp_type: RampType,
    lanes: int,
    widths: tuple[float, float, float],
    station_m: float,
    through_lane_id: int,
    edge_xy: FloatArray | None,
    lane_xy: FloatArray | None,
    traffic_side: TrafficSide = "right",
    config: RampConfig | None = None,
) -> RampEvidence | None:
    """Fit a ramp's first part to the road edges and lane markings the car measured.

    Past an exit's gore (before an entry's) the LiDAR sees the ramp's diverging edges and
    markings within its lateral range. They are modelled in the Frenet frame of the base
    line -- the outer border of the through lane ``through_lane_id`` from the gore at
    ``station_m`` -- with ``a`` the distance from the gore and ``tau`` the lateral offset
    towards the ramp's lanes:

    ``tau = e(a) + b_k(a)``, ``e`` a cubic spline in ``u = a / evidence_length_m`` (knots
    every 0.15, ``e(0) = e'(0) = 0``: the ramp leaves the gore exactly, tangent to the
    mainline),

    with ``b_k`` the boundary offsets: road edges at ``0`` and ``g(a) w_in + n w + w_hs``,
    markings at ``g(a) w_in + j w`` (``j = 0..n``), ``g`` the inner shoulder's opening
    over ``shoulder_taper_m`` (as built). The ramp is tracked outward from the gore
    (windows of 30, 60, ... m; in each, Huber-weighted least squares with every point
    re-associated with the nearest boundary of its kind, gate shrinking to 0.4 m), so
    the fit does not depend on the OSM shape. Points within ``evidence_exclude_m`` of a
    mainline boundary of their kind are the mainline's and not used. A shoulder whose road
    edge fewer than 20 points saw keeps its default width (weak priors hold every width
    where nothing saw it). Beyond the last matched point (``A``) the fitted line,
    extrapolated linearly, blends into the OSM shape ``ref_xy`` over
    ``evidence_blend_m`` (smootherstep).

    Parameters
    ----------
    ref_xy
        ``(N, 2)`` dense provisional reference line (re-anchored OSM) in driving order,
        mapping frame, metres; exits start, entries end at the gore.
    mainline_road
        The measured mainline.
    widths
        Default ``(inner shoulder, lane, hard shoulder)`` widths, metres.
    station_m, through_lane_id
        Mainline station of the gore and the through lane whose outer border the ramp's
        reference line leaves from.
    edge_xy, lane_xy
        Measured road-edge points and lane samples, ``(N, 2+)`` mapping frame, metres.

    Returns
    -------
    RampEvidence or None
        ``None`` when too few points match (``evidence_min_points``,
        ``evidence_min_span_m``) or the fitted line ends implausibly far from the OSM
        shape (``evidence_max_shift_m`` where the blend begins) or crosses into the
        mainline.
    """
    cfg = config or RampConfig()
    ref = np.asarray(ref_xy, dtype=float)[:, :2]
    w_in0, w0, w_hs0 = (float(x) for x in widths)
    side = -1.0 if traffic_side == "right" else 1.0  # tau = side * t
    reach = cfg.evidence_length_m + cfg.evidence_blend_m
    base = _base_line(mainline_road, station_m, through_lane_id, ramp_type, reach)
    if base is None:
        return None
    a_base = base.s if ramp_type == "exit" else base.length - base.s
    near = a_base <= cfg.evidence_length_m
    if np.count_nonzero(near) < 2:
        return None
    lateral = _EVIDENCE_LATERAL_M
    kinds, pts_all = [], []
    probe = resample_polyline(base.xy[near], 2.0)
    for kind, pts in (("edge", edge_xy), ("lane", lane_xy)):
        if pts is None or len(pts) == 0:
            continue
        pts = np.asarray(pts, dtype=float)[:, :2]
        hits = cKDTree(pts).query_ball_point(probe, r=lateral)
        idx = np.unique(np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64))
        if idx.size == 0:
            continue
        sub = pts[idx]
        d_main = _mainline_boundary_distance(
            mainline_road, sub, kind=kind, traffic_side=traffic_side
        )
        sub = sub[d_main > cfg.evidence_exclude_m]
        pts_all.append(sub)
        kinds.append(np.full(sub.shape[0], kind == "edge"))
    if not pts_all:
        return None
    pts = np.vstack(pts_all)
    is_edge = np.concatenate(kinds)
    s_p, t_p = base.project(pts)
    a_p = s_p if ramp_type == "exit" else base.length - s_p
    tau = side * t_p
    keep = (s_p > 0.0) & (s_p < base.length) & (a_p > 0.0) & (a_p <= cfg.evidence_length_m)
    keep &= (tau > -3.0) & (tau < lateral)
    a_p, tau, is_edge = a_p[keep], tau[keep], is_edge[keep]
    if a_p.size < cfg.evidence_min_points:
        return None
    # the inner shoulder opens over shoulder_taper_m from the gore (as built, C1 cubic)
    xg = np.clip(a_p / max(cfg.shoulder_taper_m, 1e-6), 0.0, 1.0)
    g_in = xg * xg * (3.0 - 2.0 * xg)
    # boundary table: (is_edge, coef of w_in, coef of w, coef of w_hs, group)
    table = [(True, 0.0, 0.0, 0.0, 0)]
    table += [(False, 1.0, float(j), 0.0, 1) for j in range(lanes + 1)]
    table += [(True, 1.0, float(lanes), 1.0, 2)]
    coef_b = np.array([[c[1], c[2], c[3]] for c in table])
    edge_b = np.array([c[0] for c in table])
    group_b = np.array([c[4] for c in table])
    prior_val = np.array([0.0] * _N_SHAPE + [w_in0, w0, w_hs0])
    prior = np.array([1e-3] * _N_SHAPE + [3.0, 3.0, 3.0])  # pseudo-points of weight 1 each
    a_scale = cfg.evidence_length_m
    windows = tuple(
        float(w)
        for w in np.arange(30.0, cfg.evidence_length_m + 14.9, 15.0).clip(max=cfg.evidence_length_m)
    )
    for _ in range(2):
        p, assoc, resid, used = _fit_boundaries(
            a_scale, a_p, g_in, tau, is_edge, coef_b, edge_b, prior, prior_val, windows
        )
        if assoc is None:
            return None
        ok = used & (np.abs(resid) <= 0.4)
        counts = tuple(int(np.count_nonzero(ok & (group_b[assoc] == g))) for g in range(3))
        # an edge nobody saw cannot give its shoulder's width: hold the default
        weak = [
            k
            for k, c in ((_N_SHAPE, counts[0]), (_N_SHAPE + 2, counts[2]))
            if c < _MIN_BOUNDARY_POINTS
        ]
        if all(prior[k] > 1e5 for k in weak):
            break
        for k in weak:
            prior[k] = 1e6
    n_ok = int(np.count_nonzero(ok))
    if n_ok < cfg.evidence_min_points:
        return None
    span = float(np.max(a_p[ok]))
    if span < cfg.evidence_min_span_m:
        return None
    w_in = float(np.clip(p[_N_SHAPE], 0.3, 3.0))  # narrower is an edge line, not a shoulder
    w_lane = float(np.clip(p[_N_SHAPE + 1], 2.5, 5.0))
    w_hs = float(np.clip(p[_N_SHAPE + 2], 0.3, 4.0))
    # the fitted line up to the span, extrapolated linearly beyond it along the base line
    step = cfg.resample_step_m
    blend = cfg.evidence_blend_m
    a_max = float(a_base.max())
    a_f = np.arange(0.0, min(span + blend, a_max) + 1e-9, step)
    u_f = np.minimum(a_f, span) / a_scale
    e_f = _poly_e(p, u_f)
    e_span = float(_poly_e(p, np.array([span / a_scale]))[0])
    de_span = float(_poly_de(p, np.array([span / a_scale]))[0]) / a_scale
    e_f = np.where(a_f > span, e_span + de_span * (a_f - span), e_f)
    if float(np.min(e_f[a_f <= span])) < -1.0:
        log.warning("ramp evidence: fitted line crosses into the mainline; not used")
        return None
    s_f = a_f if ramp_type == "exit" else base.length - a_f
    xy_b, tg_b = base.at(s_f)
    normal = np.stack([-tg_b[:, 1], tg_b[:, 0]], axis=1)
    fit_xy = xy_b + (side * e_f)[:, None] * normal  # attachment-first order
    # the OSM shape, attachment-first, at the same distances from the gore
    osm = ref if ramp_type == "exit" else ref[::-1]
    a_osm = arc_length(osm)
    osm_at = np.stack([np.interp(a_f, a_osm, osm[:, j]) for j in range(2)], axis=1)
    join = a_f >= span
    gap = float(np.hypot(*(fit_xy[join][0] - osm_at[join][0]))) if np.any(join) else 0.0
    if gap > cfg.evidence_max_shift_m:
        log.warning("ramp evidence: fitted line ends %.1f m from the OSM shape; not used", gap)
        return None
    wgt = _smootherstep((a_f - span) / max(blend, 1e-6))[:, None]
    mixed = (1.0 - wgt) * fit_xy + wgt * osm_at
    rest = osm[a_osm > a_f[-1] + 0.5 * step]
    out = np.vstack([mixed, rest])
    out = out if ramp_type == "exit" else out[::-1]
    rmse = float(np.sqrt(np.mean(resid[ok] ** 2)))
    return RampEvidence(
        xy=out,
        widths=(w_in, w_lane, w_hs),
        points=n_ok,
        counts=counts,  # type: ignore[arg-type]
        span_m=span,
        max_shift_m=gap,
        rmse_m=rmse,
    )
