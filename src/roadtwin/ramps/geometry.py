"""Ramp shape helpers: exact Hermite ParamPoly3 pieces, smoothing of the OSM polyline,
re-anchoring on the mainline and the base line of the ramp's first part.

All coordinates are in the mapping frame (metres, radians CCW from +x).
"""

from __future__ import annotations

import math

import numpy as np

from ..config import RampConfig
from ..fitting import PolylineFrame, arc_length, resample_polyline, savgol_smooth
from ..model import ParamPoly3, Road
from .gores import _traffic_lanes
from .records import FloatArray, RampType, TrafficSide

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


def _smootherstep(x: FloatArray) -> FloatArray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def _smooth_polyline(xy: FloatArray, cfg: RampConfig) -> FloatArray:
    dense = resample_polyline(xy, cfg.resample_step_m)
    window = max(5, round(cfg.savgol_window_m / cfg.resample_step_m))
    smooth = savgol_smooth(dense, window=window, polyorder=cfg.savgol_polyorder)
    return smooth


def _anchor_start(
    xy: FloatArray, target_xy: FloatArray, target_hdg: float, blend_m: float
) -> FloatArray:
    """Move the start of a dense polyline onto ``target_xy`` with heading ``target_hdg``,
    blending the correction out over ``blend_m`` (C2 smootherstep)."""
    sigma = arc_length(xy)
    frame = PolylineFrame.from_points(xy)
    u0 = frame.tangent[0]
    u_star = np.array([math.cos(target_hdg), math.sin(target_hdg)])
    delta = target_xy - xy[0]
    fade = 1.0 - _smootherstep(sigma / max(blend_m, 1e-6))
    out = xy + fade[:, None] * (delta[None, :] + sigma[:, None] * (u_star - u0)[None, :])
    out[0] = target_xy
    return out


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


def _base_line(
    road: Road, station_m: float, through_lane_id: int, ramp_type: RampType, reach_m: float
) -> PolylineFrame | None:
    """The outer border of the through lane from the gore ``reach_m`` along the ramp's
    direction (exit: downstream, entry: upstream), in driving order, as a Frenet frame."""
    direction = 1.0 if ramp_type == "exit" else -1.0
    far = float(np.clip(station_m + direction * reach_m, 0.0, road.length))
    n = int(abs(far - station_m) / 0.5) + 1
    if n < 8:
        return None
    s = np.linspace(station_m, far, n)
    s = np.clip(s, 1e-6, road.length - 1e-6)
    t = road.lane_border_t(s, through_lane_id)
    if not np.all(np.isfinite(t)):
        return None
    xy = road.to_xy(s, t).reshape(-1, 2)
    return PolylineFrame.from_points(xy if ramp_type == "exit" else xy[::-1])
