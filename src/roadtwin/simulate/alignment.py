"""Horizontal and vertical alignment: exact Line/Arc/Spiral pieces and cubic profiles.

Everything is in the mapping frame (metres, radians). Pieces are chained so each starts
exactly at the end pose of the previous one; the mainline starts at the origin heading
along ``start_heading_rad``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..model import (
    Arc,
    CubicPiece,
    CubicProfile,
    Geometry,
    Line,
    Spiral,
    chain_geometry,
)
from .scenario import AlignmentElement, GradeChange


def _piece(kind: str, s0, x, y, hdg, length, k0, k1) -> Geometry:
    if kind == "straight" or (abs(k0) < 1e-12 and abs(k1) < 1e-12):
        return Line(s0, x, y, hdg, length)
    if kind == "arc" or abs(k1 - k0) < 1e-12:
        return Arc(s0, x, y, hdg, length, curvature_per_m=k0)
    return Spiral(s0, x, y, hdg, length, curv_start=k0, curv_end=k1)


def _curvatures(piece: Geometry) -> tuple[float, float]:
    if isinstance(piece, Spiral):
        return piece.curv_start, piece.curv_end
    if isinstance(piece, Arc):
        return piece.curvature_per_m, piece.curvature_per_m
    return 0.0, 0.0


def _kind(piece: Geometry) -> str:
    return (
        "clothoid" if isinstance(piece, Spiral) else "arc" if isinstance(piece, Arc) else "straight"
    )


def build_pieces(
    elements: Sequence[tuple[str, float, float, float]],
    *,
    x0: float = 0.0,
    y0: float = 0.0,
    hdg: float = 0.0,
) -> tuple[Geometry, ...]:
    """Chain ``(kind, length_m, curvature_start, curvature_end)`` elements from a pose."""
    pieces: list[Geometry] = []
    s = 0.0
    x, y, h = x0, y0, hdg
    for kind, length, k0, k1 in elements:
        piece = _piece(kind, s, x, y, h, length, k0, k1)
        pieces.append(piece)
        x, y, h = piece.end_pose()
        s += length
    return tuple(pieces)


def mainline_pieces(
    alignment: Sequence[AlignmentElement],
    *,
    start_heading_rad: float = 0.0,
    start_xy_m: tuple[float, float] = (0.0, 0.0),
) -> tuple[Geometry, ...]:
    """The driven carriageway's reference line (its median-side edge) from its start."""
    return build_pieces(
        [(e.kind, e.length_m, e.curvature_start, e.curvature_end) for e in alignment],
        x0=start_xy_m[0],
        y0=start_xy_m[1],
        hdg=start_heading_rad,
    )


def cut_pieces(pieces: Sequence[Geometry], s_a: float, s_b: float) -> tuple[Geometry, ...]:
    """Exact sub-curve ``[s_a, s_b]`` of chained pieces, re-based to start at s = 0."""
    out: list[Geometry] = []
    for p in pieces:
        a = max(s_a, p.s0)
        b = min(s_b, p.s0 + p.length)
        if b - a <= 1e-9:
            continue
        x, y, h, k = (float(v[0]) for v in p.evaluate(np.array([a])))
        k_end = float(p.evaluate(np.array([b]))[3][0])
        out.append(_piece(_kind(p), 0.0, x, y, h, b - a, k, k_end))
    return chain_geometry(out)


def reverse_pieces(pieces: Sequence[Geometry]) -> tuple[Geometry, ...]:
    """The same curve driven the other way (heading + pi, curvatures negated, reversed)."""
    out: list[Geometry] = []
    for p in reversed(pieces):
        x, y, h = p.end_pose()
        k0, k1 = _curvatures(p)
        hdg = (h + 2.0 * math.pi) % (2.0 * math.pi) - math.pi  # h + pi wrapped to [-pi, pi)
        out.append(_piece(_kind(p), 0.0, x, y, hdg, p.length, -k1, -k0))
    return chain_geometry(out)


def offset_pieces(pieces: Sequence[Geometry], t_m: float) -> tuple[Geometry, ...]:
    """Approximate parallel curve at lateral offset ``t_m`` (left positive).

    Lines and arcs are exact; a clothoid becomes a clothoid between the offset end
    curvatures (close to the true offset for |t| much smaller than the radius). Used only
    for roads outside the ground-truth mainline (the opposite carriageway).
    """
    first = pieces[0]
    x0 = first.x0 - t_m * math.sin(first.hdg)
    y0 = first.y0 + t_m * math.cos(first.hdg)
    elements = []
    for p in pieces:
        k0, k1 = _curvatures(p)
        k0o, k1o = k0 / (1.0 - t_m * k0), k1 / (1.0 - t_m * k1)
        length = p.length * (1.0 - t_m * 0.5 * (k0 + k1))
        elements.append((_kind(p), length, k0o, k1o))
    return build_pieces(elements, x0=x0, y0=y0, hdg=first.hdg)


def ramp_pieces(
    *,
    x: float,
    y: float,
    hdg: float,
    curvature_start: float,
    turn_sign: float,
    radius_m: float,
    clothoid_length_m: float,
    curve_length_m: float,
    tail_length_m: float,
    kind: str,
    elements: Sequence[tuple[float, float, float]] = (),
) -> tuple[Geometry, ...]:
    """Ramp reference line through the gore pose ``(x, y, hdg)``.

    An exit starts there: clothoid from ``curvature_start`` to ``turn_sign / radius``,
    arc, straight tail. An entry ends there with heading ``hdg``: built backwards from the
    gore (turning the other way) and reversed, so its last piece meets the gore exactly.
    ``elements`` (``(length, k_start, k_end)`` clothoids in driving order) replace the
    clothoid/arc/tail shape.
    """
    k = turn_sign / radius_m
    if elements:  # a given shape, in driving order
        forward = [("clothoid", length, k0, k1) for length, k0, k1 in elements]
    else:
        forward = [
            ("clothoid", clothoid_length_m, curvature_start, k),
            ("arc", curve_length_m, k, k),
            ("straight", tail_length_m, 0.0, 0.0),
        ]
        if kind == "entry":  # mirrored in time: arrive along the tail, leave along the clothoid
            forward = [
                ("straight", tail_length_m, 0.0, 0.0),
                ("arc", curve_length_m, k, k),
                ("clothoid", clothoid_length_m, k, curvature_start),
            ]
    if kind == "exit":
        return build_pieces(forward, x0=x, y0=y, hdg=hdg)
    backward = [(kd, length, -k1, -k0) for kd, length, k0, k1 in reversed(forward)]
    return reverse_pieces(build_pieces(backward, x0=x, y0=y, hdg=hdg + math.pi))


def shift_cubic(piece: CubicPiece, s_new: float) -> CubicPiece:
    """The same cubic re-expanded about station ``s_new`` (exact)."""
    h = s_new - piece.s0
    a, b, c, d = piece.a, piece.b, piece.c, piece.d
    return CubicPiece(
        s_new,
        a + h * (b + h * (c + h * d)),
        b + h * (2 * c + 3 * d * h),
        c + 3 * d * h,
        d,
    )


def cut_profile(profile: CubicProfile, s_a: float, s_b: float) -> CubicProfile:
    """Exact restriction of a profile to ``[s_a, s_b]``, stations re-based to 0."""
    pieces = profile.pieces
    out = []
    for i, p in enumerate(pieces):
        end = pieces[i + 1].s0 if i + 1 < len(pieces) else math.inf
        if end <= s_a + 1e-9 or p.s0 >= s_b - 1e-9:
            continue
        q = shift_cubic(p, max(p.s0, s_a)) if p.s0 < s_a else p
        out.append(replace(q, s0=q.s0 - s_a))
    if not out:  # before the first piece: extrapolate it
        q = shift_cubic(pieces[0], s_a)
        out.append(replace(q, s0=0.0))
    return CubicProfile(tuple(out))


def elevation_profile(
    grades: Sequence[GradeChange], *, start_z_m: float, length_m: float
) -> CubicProfile:
    """Road height (metres) along the mainline: straight grades joined by parabolic
    vertical curves, as exact cubic pieces (c != 0 only inside vertical curves)."""
    pieces: list[CubicPiece] = []
    z = start_z_m
    g = grades[0].grade_pct / 100.0
    s = 0.0
    for change in grades[1:]:
        g_new = change.grade_pct / 100.0
        half = change.curve_length_m / 2.0
        a = change.station_m - half
        pieces.append(CubicPiece(s, z, g))
        z += g * (a - s)
        if half > 0:
            c = (g_new - g) / (2.0 * change.curve_length_m)
            pieces.append(CubicPiece(a, z, g, c))
            z += g * change.curve_length_m + c * change.curve_length_m**2
        s = change.station_m + half
        g = g_new
    pieces.append(CubicPiece(s, z, g))
    merged = [p for p in pieces if p.s0 < length_m or p is pieces[0]]
    # drop zero-length pieces (a curve starting at the previous piece's start)
    out: list[CubicPiece] = []
    for p in merged:
        if out and abs(out[-1].s0 - p.s0) < 1e-9:
            out[-1] = p
        else:
            out.append(p)
    return CubicProfile(tuple(out))


def smoothstep_cubic(s0: float, length_m: float, w0: float, w1: float) -> CubicPiece:
    """Cubic from ``w0`` to ``w1`` over ``length_m`` with zero slope at both ends."""
    dw = w1 - w0
    return CubicPiece(s0, w0, 0.0, 3.0 * dw / length_m**2, -2.0 * dw / length_m**3)
