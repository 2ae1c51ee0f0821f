"""Exact sub-roads: :func:`cut_road`."""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from .._errors import FitError, InputError
from ..fitting import (
    _cubic_arc_length,
    shift_cubic_piece,
)
from ..model import (
    Arc,
    CubicProfile,
    Geometry,
    Lane,
    LaneSection,
    Line,
    ParamPoly3,
    Road,
    Spiral,
    chain_geometry,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


def _shift_cubic(c: tuple[float, float, float, float], p0: float, scale: float) -> FloatArray:
    """Coefficients of ``c(p0 + scale * q)`` in q (Taylor shift, then scaling)."""
    a, b, cc, d = c
    return np.array(
        [
            a + p0 * (b + p0 * (cc + p0 * d)),
            (b + p0 * (2.0 * cc + 3.0 * p0 * d)) * scale,
            (cc + 3.0 * d * p0) * scale * scale,
            d * scale * scale * scale,
        ]
    )


def _cut_geometry(g: Geometry, a: float, b: float, s_new: float) -> Geometry:
    """The part of piece ``g`` between road stations ``a`` and ``b`` (exact).

    A cut ``normalized`` ParamPoly3 declares the true arc length of its curve as its
    length (the station span ``b - a`` differs from it by up to millimetres where p is
    not exactly proportional to arc length).
    """
    length = b - a
    if isinstance(g, ParamPoly3):
        x, y, h, _ = g.evaluate(np.array([a]))
        if g.p_range == "normalized":
            pa, scale = (a - g.s0) / g.length, length / g.length
        else:
            pa, scale = a - g.s0, 1.0
        Uc = _shift_cubic((g.aU, g.bU, g.cU, g.dU), pa, scale)
        Vc = _shift_cubic((g.aV, g.bV, g.cV, g.dV), pa, scale)
        # rotate the old local frame to the tangent at the cut: new hdg = h[0]
        rel = float(h[0]) - g.hdg
        c, sn = math.cos(rel), math.sin(rel)
        U = c * Uc + sn * Vc
        V = -sn * Uc + c * Vc
        if g.p_range == "normalized":
            length = _cubic_arc_length(np.stack([U, V], axis=1))
        return ParamPoly3(
            s_new,
            float(x[0]),
            float(y[0]),
            float(h[0]),
            length,
            aU=0.0,
            bU=float(U[1]),
            cU=float(U[2]),
            dU=float(U[3]),
            aV=0.0,
            bV=float(V[1]),
            cV=float(V[2]),
            dV=float(V[3]),
            p_range=g.p_range,
        )
    x, y, h, k = g.evaluate(np.array([a, b]))
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


_SECTION_TOL_M = 1e-3
"""Lane sections and profile pieces shorter than this (metres) are not cut off at a road's
ends."""


def _cut_profile(prof: CubicProfile, a: float, b: float) -> CubicProfile:
    """Profile restricted to [a, b] and re-based so that station a becomes 0.

    A piece that starts within ``_SECTION_TOL_M`` of a cut belongs to the side it starts
    on, like a lane section: a step of the lane offset at a gore, where the road is cut,
    must not leave a sliver of the old offset at the start of the next road (a 3.5 m jump
    0.1 micrometre into a junction's connecting road)."""
    if not prof.pieces:
        return prof
    s0s = np.array([p.s0 for p in prof.pieces])
    i0 = max(int(np.searchsorted(s0s, a + _SECTION_TOL_M, side="right")) - 1, 0)
    out = [shift_cubic_piece(prof.pieces[i0], a)]
    out.extend(p for p in prof.pieces[i0 + 1 :] if p.s0 < b - _SECTION_TOL_M)
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
    # true arc lengths of cut normalized pieces: later pieces start where these end
    geo = list(chain_geometry(geo))
    # a section that starts within a millimetre of a cut (a cut at a gore, where a section
    # starts too) belongs to the side it starts on: no zero-length sections
    sec_s0 = np.array([sc.s0 for sc in road.lane_sections])
    i0 = max(int(np.searchsorted(sec_s0, a + _SECTION_TOL_M, side="right")) - 1, 0)
    secs = [road.lane_sections[i0]] + [
        sc for sc in road.lane_sections[i0 + 1 :] if sc.s0 < b - _SECTION_TOL_M
    ]
    new_secs: list[LaneSection] = []
    for j, sc in enumerate(secs):
        sa = a if j == 0 else sc.s0
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
