"""Ramp geometry helpers: exact Hermite ParamPoly3 pieces, smoothing of the OSM polyline
and distances to the mainline's boundaries.

All coordinates are in the mapping frame (metres, radians CCW from +x).
"""

from __future__ import annotations

import math

import numpy as np

from ..config import RampConfig
from ..fitting import resample_polyline, savgol_smooth
from ..model import ParamPoly3, Road
from .gores import _traffic_lanes
from .records import FloatArray, TrafficSide

# ---------------------------------------------------------------------------
# geometry
# ---------------------------------------------------------------------------


_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)


def hermite_piece(
    start: tuple[float, float, float], end: tuple[float, float, float], *, s0: float = 0.0
) -> ParamPoly3:
    """One ParamPoly3 (``pRange="normalized"``) from pose ``start`` to pose ``end``.

    Poses are ``(x, y, heading)`` (mapping frame, metres, radians). The cubic Hermite
    curve meets both exactly in position and heading; the tangent length is the chord;
    ``length`` is the true arc length (Gauss-Legendre).
    """
    x0, y0, h0 = start
    x1, y1, h1 = end
    c, s = math.cos(h0), math.sin(h0)
    dx, dy = x1 - x0, y1 - y0
    p1 = np.array([c * dx + s * dy, -s * dx + c * dy])
    dh = (h1 - h0 + math.pi) % (2 * math.pi) - math.pi
    chord = math.hypot(dx, dy)
    m0 = np.array([chord, 0.0])
    m1 = chord * np.array([math.cos(dh), math.sin(dh)])
    coef = np.stack([np.zeros(2), m0, 3.0 * p1 - 2.0 * m0 - m1, -2.0 * p1 + m0 + m1])
    length = 0.0
    for k in range(4):
        p = 0.125 * (2 * k + 1) + 0.125 * _GL_NODES
        d = coef[1] + p[:, None] * (2.0 * coef[2] + 3.0 * p[:, None] * coef[3])
        length += 0.125 * float(np.hypot(d[:, 0], d[:, 1]) @ _GL_WEIGHTS)
    return ParamPoly3(
        s0,
        float(x0),
        float(y0),
        float(h0),
        length,
        aU=0.0,
        bU=float(coef[1, 0]),
        cU=float(coef[2, 0]),
        dU=float(coef[3, 0]),
        aV=0.0,
        bV=float(coef[1, 1]),
        cV=float(coef[2, 1]),
        dV=float(coef[3, 1]),
        p_range="normalized",
    )


def _smooth_polyline(xy: FloatArray, cfg: RampConfig) -> FloatArray:
    dense = resample_polyline(xy, cfg.resample_step_m)
    window = max(5, round(cfg.savgol_window_m / cfg.resample_step_m))
    smooth = savgol_smooth(dense, window=window, polyorder=cfg.savgol_polyorder)
    return smooth


def _mainline_boundary_distance(
    road: Road, pts: FloatArray, *, kind: str, traffic_side: TrafficSide
) -> FloatArray:
    """Distance (metres) of points to the nearest mainline boundary of ``kind``
    (``"edge"``: road edges; ``"lane"``: lane markings) at their station; ``inf`` off the
    road's ends."""
    s, t = road.project(pts)
    out = np.full(s.shape, np.inf)
    on = (s > 0.0) & (s < road.length)
    if not np.any(on):
        return out
    idx = road.section_index(np.clip(s, 0.0, road.length))
    for k in np.unique(idx[on]):
        sel = on & (idx == k)
        lanes_ = _traffic_lanes(road.lane_sections[int(k)], traffic_side)
        if not lanes_:
            continue
        ids = [lane.id for lane in lanes_]
        border_ids = [0, ids[-1]] if kind == "edge" else ids[:-1]
        best = np.full(int(sel.sum()), np.inf)
        for lane_id in border_ids:
            tb = road.lane_border_t(s[sel], lane_id)
            best = np.minimum(best, np.abs(t[sel] - tb))
        out[sel] = best
    return out
