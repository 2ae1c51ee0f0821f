"""Plan geometry of the truth: where OSM is off, smoothing, reference lines and their fits.

All in the mapping frame (metres, radians CCW from +x). The truth is the OSM geometry
moved by a smooth seeded displacement field (:func:`offset_field`), smoothed like a
designed road (Savitzky-Golay over a window, curvature kept below ``1 / min_radius_m``),
and fitted by chains of ParamPoly3 pieces (:func:`roadtwin.fitting.fit_parampoly3_chain`)
whose joints share position and heading. A ramp leaves its gore tangentially to the
lane border it starts on (:func:`ramp_polyline`) and blends into the OSM link's shape.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_interp_spline

from ...fitting import arc_length, fit_parampoly3_chain, resample_polyline, savgol_smooth
from ...model import Geometry, Road, chain_geometry
from ...ramps import hermite_piece
from .settings import OsmOffset, RampShape

FloatArray = NDArray[np.float64]
Field = Callable[[FloatArray], FloatArray]


def offset_field(rng: np.random.Generator, cfg: OsmOffset, *, centre: FloatArray) -> Field:
    """Displacement ``(N, 2)`` (metres) of the truth from OSM at points ``(N, 2)``.

    A regional shift of random direction and ``cfg.shift_m`` magnitude plus, per axis,
    three plane waves of random direction, wavelength and phase (``cfg.wander_m`` peak),
    with the magnitude limited to ``[cfg.min_m, cfg.max_m]``. ``centre`` (2,) keeps the
    waves' phases local to the area (numbers stay small).
    """
    ang = rng.uniform(0.0, 2 * math.pi)
    mag = rng.uniform(*cfg.shift_m)
    shift = mag * np.array([math.cos(ang), math.sin(ang)])
    dirs = rng.uniform(0.0, 2 * math.pi, size=(2, 3))
    lam = rng.uniform(*cfg.wander_wavelength_m, size=(2, 3))
    ph = rng.uniform(0.0, 2 * math.pi, size=(2, 3))
    amp = cfg.wander_m / 3.0 * rng.uniform(0.6, 1.0, size=(2, 3))
    kx = np.cos(dirs) * 2 * math.pi / lam
    ky = np.sin(dirs) * 2 * math.pi / lam
    c = np.asarray(centre, dtype=float)

    def field(p: FloatArray) -> FloatArray:
        q = np.atleast_2d(np.asarray(p, dtype=float)) - c
        arg = q[:, 0, None, None] * kx + q[:, 1, None, None] * ky + ph  # (N, 2, 3)
        d = shift + (amp * np.sin(arg)).sum(axis=2)
        m = np.linalg.norm(d, axis=1, keepdims=True)
        scale = np.clip(m, cfg.min_m, cfg.max_m) / np.maximum(m, 1e-9)
        return d * scale

    return field


def smooth_line(xy: FloatArray, *, window_m: float, step_m: float = 1.0) -> FloatArray:
    """Resampled (``step_m``) and Savitzky-Golay smoothed polyline; ends kept in place."""
    dense = resample_polyline(xy, step_m)
    n = dense.shape[0]
    win = int(window_m / step_m) | 1
    win = min(win, n - 1 if n % 2 == 0 else n)
    if win < 5:
        return dense
    return savgol_smooth(dense, window=win, polyorder=3)


def curvature(xy: FloatArray) -> FloatArray:
    """Signed curvature (1/m) of a dense polyline from a cubic spline in arc length."""
    s = arc_length(xy)
    keep = np.concatenate([[True], np.diff(s) > 1e-9])
    s, pts = s[keep], xy[keep]
    if pts.shape[0] < 4:
        return np.zeros(pts.shape[0])
    sp = make_interp_spline(s, pts, k=3)
    d1, d2 = sp(s, 1), sp(s, 2)
    num = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    return num / np.maximum(np.hypot(d1[:, 0], d1[:, 1]) ** 3, 1e-12)


def normals(xy: FloatArray) -> FloatArray:
    """Unit left normals ``(N, 2)`` of a dense polyline."""
    d = np.gradient(xy, axis=0)
    t = d / np.linalg.norm(d, axis=1, keepdims=True)
    return np.column_stack([-t[:, 1], t[:, 0]])


def fit_line(
    xy: FloatArray,
    *,
    tolerance_m: float,
    start_pose: tuple[float, float, float] | None = None,
    end_pose: tuple[float, float, float] | None = None,
) -> tuple[Geometry, ...]:
    """ParamPoly3 chain through a dense smooth polyline; the first (last) piece is
    rebuilt as an exact Hermite piece from ``start_pose`` (to ``end_pose``) so a road
    meets the lane border it leaves from to floating-point precision."""
    pieces = list(fit_parampoly3_chain(xy, tolerance_m=tolerance_m, max_piece_m=150.0))
    if start_pose is not None:
        first = pieces[0]
        if len(pieces) > 1:
            pieces[0] = hermite_piece(start_pose, first.end_pose())
        else:
            pieces[0] = hermite_piece(start_pose, first.end_pose())
    if end_pose is not None:
        last = pieces[-1]
        pieces[-1] = hermite_piece((last.x0, last.y0, last.hdg), end_pose)
    return chain_geometry(pieces)


def ramp_polyline(
    main: Road,
    gore_s: float,
    attach_t: float,
    target: FloatArray,
    *,
    kind: str,
    away_sign: float,
    separation_m: float,
    cfg: RampShape,
) -> tuple[FloatArray, tuple[float, float, float]]:
    """Dense reference line of a ramp (driving order) and its exact gore pose.

    ``attach_t`` is the lateral offset (metres, left positive) on ``main`` where the ramp's
    reference line starts (exit) or ends (entry) at station ``gore_s``; ``target`` the
    ramp's reference line from the displaced OSM link, in driving order. Near the gore the
    ramp is described in the mainline's Frenet frame: its separation from that border
    (``away_sign`` +1 = to the left) is the larger (a soft maximum) of the target's and a
    minimum that leaves the border tangentially on a circle of ``cfg.diverge_radius_m`` and
    levels off at ``separation_m`` (room for the shoulders that open in the gore). Once
    the target is ``cfg.switch_m`` away from the mainline (or turns away) the ramp follows
    the target itself. Curvature is limited to ``1 / cfg.min_radius_m``.
    """
    exit_ = kind == "exit"
    d = 1.0 if exit_ else -1.0
    tgt = target if exit_ else target[::-1]  # from the gore away
    tgt = smooth_line(tgt, window_m=cfg.smooth_window_m, step_m=1.0)
    s_t, t_t = main.project(tgt)
    sig_t = d * (s_t - gore_s)
    e_t = away_sign * (t_t - attach_t)
    hd = np.abs(_wrap(_headings(tgt) - main.heading(s_t) - (0.0 if exit_ else math.pi)))
    near = (
        (np.concatenate([[True], np.diff(sig_t) > 0.05]))
        & (e_t < cfg.switch_m)
        & (hd < math.radians(35.0))
        & (s_t > 0.5)
        & (s_t < main.length - 0.5)
    )
    near &= np.cumprod(near).astype(bool)  # the prefix only
    j = int(near.sum())
    sig_switch = float(sig_t[j - 1]) if j >= 2 else 0.0
    sig_switch = float(np.clip(sig_switch, 0.0, d * ((main.length if exit_ else 0.0) - gore_s)))
    pieces = []
    if sig_switch > 1.0:
        sig = np.linspace(0.0, sig_switch, max(2, math.ceil(sig_switch) + 1))
        cap = separation_m
        e_min = cap * (1.0 - np.exp(-(sig * sig) / (2.0 * cfg.diverge_radius_m * cap)))
        e_tgt = np.interp(sig, sig_t[:j], e_t[:j]) if j >= 2 else e_min
        k = cfg.softmax_m
        e = e_min + k * np.logaddexp(0.0, (e_tgt - e_min) / k)
        e -= e[0] * np.exp(-0.5 * (sig / 15.0) ** 2)  # starts on the border, tangentially
        pieces.append(main.to_xy(gore_s + d * sig, attach_t + away_sign * e))
    far = tgt[j:] if sig_switch > 1.0 else tgt
    if sig_switch > 1.0 and len(far):
        far = far[np.hypot(*(far - pieces[0][-1]).T).argmin() :]
        far = far[1:] if len(far) > 1 else far
    if len(far):
        pieces.append(far)
    xy = np.vstack(pieces)
    gore_xy = main.to_xy(np.array([gore_s]), np.array([attach_t]))[0]
    if sig_switch <= 1.0:
        xy = np.vstack([gore_xy, xy[np.hypot(*(xy - gore_xy).T) > 1.0]])
    xy = resample_polyline(xy, 1.0)
    xy = limit_curvature(xy, min_radius_m=cfg.min_radius_m, keep_start_m=2.0)
    h0 = float(main.heading(np.array([gore_s]))[0])
    pose = (float(gore_xy[0]), float(gore_xy[1]), h0)
    if not exit_:
        xy = xy[::-1]
    return xy, pose


def _headings(xy: FloatArray) -> FloatArray:
    d = np.gradient(xy, axis=0)
    return np.arctan2(d[:, 1], d[:, 0])


def _wrap(a: FloatArray) -> FloatArray:
    return (a + math.pi) % (2 * math.pi) - math.pi


def limit_curvature(
    xy: FloatArray, *, min_radius_m: float, keep_start_m: float = 0.0, max_rounds: int = 8
) -> FloatArray:
    """Smooth the parts of a dense polyline that bend tighter than ``min_radius_m`` (a
    widening Savitzky-Golay window there), keeping the first ``keep_start_m`` as they are."""
    out = xy.copy()
    s = arc_length(out)
    for k in range(max_rounds):
        kap = np.abs(curvature(out))
        bad = kap > 1.0 / (1.05 * min_radius_m)
        if not bad.any():
            break
        win = 9 + 8 * k
        sm = savgol_smooth(out, window=win, polyorder=3)
        # blend the smoothed version in around the bad samples (soft mask over ~2 windows)
        mask = np.convolve(bad.astype(float), np.ones(2 * win + 1), mode="same") > 0
        soft = np.convolve(mask.astype(float), np.ones(win) / win, mode="same")
        soft[s < keep_start_m] = 0.0
        out = out + soft[:, None] * (sm - out)
    return out


def self_intersects(xy: FloatArray) -> bool:
    """True when a polyline crosses itself."""
    from shapely.geometry import LineString

    return not LineString(xy).is_simple


def road_with_geometry(road_id: str, pieces: tuple[Geometry, ...]) -> Road:
    """A bare road (one empty lane section) to evaluate and cut a reference line."""
    from ...model import LaneSection

    return Road(road_id, pieces, (LaneSection(0.0),))


def shifted(pieces: tuple[Geometry, ...], ds: float) -> tuple[Geometry, ...]:
    """Pieces with stations moved by ``ds``."""
    return tuple(replace(p, s0=p.s0 + ds) for p in pieces)
