"""Format-neutral road model mirroring ASAM OpenDRIVE.

Everything is in the mapping frame (x east, y north, metres; headings in radians,
counter-clockwise from +x). Lateral offsets ``t`` are positive to the left of the
reference line, as in OpenDRIVE. Every s-profile (elevation, lane offset, lane width,
superelevation) is one :class:`CubicProfile`. Geometry pieces evaluate vectorised over
arrays of s. Serialisation lives in :mod:`roadtwin.xodr`, never here.

All classes are frozen dataclasses holding tuples, so a built network is a value:
stages return new networks (``dataclasses.replace``) instead of mutating.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree
from scipy.special import fresnel

FloatArray = NDArray[np.float64]

LaneType = Literal[
    "driving", "shoulder", "border", "entry", "exit", "onRamp", "offRamp", "median", "none"
]
RoadMarkType = Literal["solid", "broken", "none", "solid solid", "broken broken"]
ContactPoint = Literal["start", "end"]

# ---------------------------------------------------------------------------
# s-profiles
# ---------------------------------------------------------------------------


HEIGHT_WEIGHT = 4.0
"""Where a point lies more than ``SAME_LEVEL_M`` above or below the line sample nearest to
it in plan, its nearest sample is looked up in 3-D with a metre of height difference
counting as this many metres of horizontal distance: a road stacked 5 m over or under
another (a bridge, a run that passes over itself) is then farther than a point 20 m beside
it, while the height of a point on the line's own road (cross slope, a few decimetres)
moves the nearest sample by well under a metre, which the projection's tangent or Newton
steps take back."""

SAME_LEVEL_M = 3.0
"""A point this far (metres) above or below a road surface lies on another level: more than
any cross slope times a carriageway's width, less than the clearance under a bridge."""


LEVEL_REACH_M = 50.0
"""Another pass of a line is a sample within this distance in plan (metres) and more than
this along the line from a point's nearest sample in plan."""


def nearest_at_level(
    tree: cKDTree,
    s: FloatArray,
    z: FloatArray,
    tree_3d: Callable[[], cKDTree],
    points: FloatArray,
) -> NDArray[np.intp]:
    """Index of the line sample nearest to each point ``(N, 3)``, at the point's level.

    ``tree`` holds the samples in plan, ``s`` their stations and ``z`` their heights
    (metres), ``tree_3d`` builds the samples' 3-D tree (heights scaled by
    ``HEIGHT_WEIGHT``). A point within ``SAME_LEVEL_M`` of its nearest sample in plan keeps
    that sample. The others are looked up in 3-D and take the sample found there if it is
    another pass of the line at their level: within ``SAME_LEVEL_M`` in height, within
    ``LEVEL_REACH_M`` in plan and more than that along the line. A point at no level of
    the line (a ramp passing under it) keeps its sample in plan. If most points are off
    their nearest sample's level, the heights do not describe the same surface (points
    without real heights): plan distance decides.
    """
    _, idx = tree.query(points[:, :2])
    off = np.flatnonzero(np.abs(points[:, 2] - z[idx]) > SAME_LEVEL_M)
    if not off.size or off.size > 0.5 * idx.size:
        return idx
    pts = points[off]
    _, idx_3d = tree_3d().query(np.column_stack([pts[:, :2], HEIGHT_WEIGHT * pts[:, 2]]))
    xy_3d = tree.data[idx_3d]
    other_pass = (
        (np.abs(pts[:, 2] - z[idx_3d]) <= SAME_LEVEL_M)
        & (np.hypot(pts[:, 0] - xy_3d[:, 0], pts[:, 1] - xy_3d[:, 1]) <= LEVEL_REACH_M)
        & (np.abs(s[idx_3d] - s[idx[off]]) > LEVEL_REACH_M)
    )
    idx[off[other_pass]] = idx_3d[other_pass]
    return idx


@dataclass(frozen=True)
class CubicPiece:
    """One cubic ``a + b ds + c ds^2 + d ds^3`` valid from ``s0`` (metres) on."""

    s0: float
    a: float
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0


@dataclass(frozen=True)
class CubicProfile:
    """Piecewise cubic function of s, as OpenDRIVE elevation/width/laneOffset records.

    Parameters
    ----------
    pieces
        Pieces sorted by ``s0``; each is valid until the next one starts. Before the
        first piece the first piece is extrapolated. An empty profile is zero.
    """

    pieces: tuple[CubicPiece, ...] = ()

    def __repr__(self) -> str:
        return f"CubicProfile({len(self.pieces)} pieces)"

    @staticmethod
    def constant(value: float, s0: float = 0.0) -> CubicProfile:
        """A profile equal to ``value`` everywhere."""
        return CubicProfile((CubicPiece(s0, float(value)),))

    @cached_property
    def _coefficients(self) -> tuple[FloatArray, FloatArray]:
        s0 = np.array([p.s0 for p in self.pieces], dtype=float)
        coef = np.array([[p.a, p.b, p.c, p.d] for p in self.pieces], dtype=float).reshape(-1, 4)
        return s0, coef

    def _locate(self, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
        s_arr = np.asarray(s, dtype=float)
        s0, coef = self._coefficients
        idx = np.clip(np.searchsorted(s0, s_arr, side="right") - 1, 0, len(s0) - 1)
        return s_arr - s0[idx], coef[idx]

    def value(self, s: ArrayLike) -> FloatArray:
        """Profile value at ``s`` (vectorised)."""
        if not self.pieces:
            return np.zeros_like(np.asarray(s, dtype=float))
        ds, k = self._locate(s)
        return k[..., 0] + ds * (k[..., 1] + ds * (k[..., 2] + ds * k[..., 3]))

    def derivative(self, s: ArrayLike) -> FloatArray:
        """First derivative d(value)/ds at ``s`` (vectorised)."""
        if not self.pieces:
            return np.zeros_like(np.asarray(s, dtype=float))
        ds, k = self._locate(s)
        return k[..., 1] + ds * (2.0 * k[..., 2] + 3.0 * ds * k[..., 3])

    def shifted(self, ds: float) -> CubicProfile:
        """The same profile with every ``s0`` moved by ``ds`` (coefficients unchanged)."""
        return CubicProfile(tuple(CubicPiece(p.s0 + ds, p.a, p.b, p.c, p.d) for p in self.pieces))


# ---------------------------------------------------------------------------
# reference-line geometry
# ---------------------------------------------------------------------------


def _rotate(u: FloatArray, v: FloatArray, hdg: float) -> tuple[FloatArray, FloatArray]:
    c, s = math.cos(hdg), math.sin(hdg)
    return c * u - s * v, s * u + c * v


@dataclass(frozen=True)
class Geometry:
    """Base of all planView pieces: start station ``s0``, start pose and length (metres).

    Subclasses implement :meth:`local`, returning ``(u, v, theta, kappa)`` in the piece's
    local frame (origin at the start, u along the start heading) for ``ds`` in
    ``[0, length]``.
    """

    s0: float
    x0: float
    y0: float
    hdg: float
    length: float

    def local(self, ds: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        raise NotImplementedError

    def evaluate(self, s: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Return ``x, y, heading, curvature`` at road stations ``s`` (mapping frame)."""
        ds = np.asarray(s, dtype=float) - self.s0
        u, v, theta, kappa = self.local(ds)
        x, y = _rotate(u, v, self.hdg)
        return x + self.x0, y + self.y0, theta + self.hdg, kappa

    def xy(self, s: ArrayLike) -> FloatArray:
        """Positions ``(N, 2)`` at stations ``s``, mapping frame, metres."""
        x, y, _, _ = self.evaluate(s)
        return np.stack([x, y], axis=-1)

    def heading(self, s: ArrayLike) -> FloatArray:
        """Heading (radians, CCW from +x) at stations ``s``."""
        return self.evaluate(s)[2]

    def curvature(self, s: ArrayLike) -> FloatArray:
        """Curvature (1/m, positive turning left) at stations ``s``."""
        return self.evaluate(s)[3]

    def end_pose(self) -> tuple[float, float, float]:
        """``(x, y, heading)`` at the end of the piece."""
        x, y, h, _ = self.evaluate(np.array([self.s0 + self.length]))
        return float(x[0]), float(y[0]), float(h[0])


@dataclass(frozen=True)
class Line(Geometry):
    """Straight line."""

    def local(self, ds):
        z = np.zeros_like(ds)
        return ds, z, z.copy(), z.copy()


@dataclass(frozen=True)
class Arc(Geometry):
    """Circular arc of constant ``curvature`` (1/m, positive = left)."""

    curvature_per_m: float = 0.0

    def local(self, ds):
        k = self.curvature_per_m
        theta = k * ds
        if abs(k) < 1e-15:
            z = np.zeros_like(ds)
            return ds, z, z.copy(), z.copy()
        u = np.sin(theta) / k
        v = (1.0 - np.cos(theta)) / k
        return u, v, theta, np.full_like(ds, k)


def _integrate_heading_gauss(
    theta_fn, ds: FloatArray, n_nodes: int = 24, max_step_m: float = 25.0
) -> tuple[FloatArray, FloatArray]:
    """Integrate ``(cos theta, sin theta)`` from 0 to ``ds`` by composite Gauss-Legendre."""
    ds = np.asarray(ds, dtype=float)
    out_u = np.zeros_like(ds)
    out_v = np.zeros_like(ds)
    if ds.size == 0:
        return out_u, out_v
    nodes, weights = np.polynomial.legendre.leggauss(n_nodes)
    n_sub = max(1, math.ceil(float(np.max(np.abs(ds))) / max_step_m))
    flat = ds.reshape(-1)
    for k in range(n_sub):  # loop over sub-intervals, vectorised over points
        a = flat * (k / n_sub)
        b = flat * ((k + 1) / n_sub)
        half = 0.5 * (b - a)
        t = (0.5 * (a + b))[:, None] + half[:, None] * nodes[None, :]
        th = theta_fn(t)
        out_u.reshape(-1)[:] += half * (np.cos(th) @ weights)
        out_v.reshape(-1)[:] += half * (np.sin(th) @ weights)
    return out_u, out_v


@dataclass(frozen=True)
class Spiral(Geometry):
    """Clothoid whose curvature changes linearly from ``curv_start`` to ``curv_end`` (1/m).

    Evaluated with Fresnel integrals; where the clothoid is nearly an arc (tiny curvature
    rate) or far from its inflection point (Fresnel differences lose precision) a
    Gauss-Legendre quadrature of the heading is used instead.
    """

    curv_start: float = 0.0
    curv_end: float = 0.0

    @property
    def curv_rate(self) -> float:
        return (self.curv_end - self.curv_start) / self.length if self.length > 0 else 0.0

    def _theta(self, t: FloatArray) -> FloatArray:
        return self.curv_start * t + 0.5 * self.curv_rate * t * t

    def local(self, ds):
        ds = np.asarray(ds, dtype=float)
        k0, c = self.curv_start, self.curv_rate
        theta = self._theta(ds)
        kappa = k0 + c * ds
        tau0 = k0 / c if abs(c) > 1e-12 else np.inf
        scale = math.sqrt(abs(c) / math.pi) if abs(c) > 1e-12 else 0.0
        if not np.isfinite(tau0) or abs(tau0) * scale > 50.0:
            u, v = _integrate_heading_gauss(self._theta, ds)
            return u, v, theta, kappa
        sigma = 1.0 if c > 0 else -1.0
        phi = k0 * k0 / (2.0 * c)
        w0 = tau0 * scale
        w = (ds + tau0) * scale
        s_w, c_w = fresnel(w)
        s_0, c_0 = fresnel(w0)
        dc, dsn = c_w - c_0, s_w - s_0
        u = (math.cos(phi) * dc + sigma * math.sin(phi) * dsn) / scale
        v = (sigma * math.cos(phi) * dsn - math.sin(phi) * dc) / scale
        return u, v, theta, kappa


@dataclass(frozen=True)
class Poly3(Geometry):
    """Cubic ``v(u) = a + b u + c u^2 + d u^3`` in the local frame (deprecated in 1.6+).

    Station s is arc length along the curve; u(s) is found from a dense arc-length table.
    """

    a: float = 0.0
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0

    @cached_property
    def _arc_table(self) -> tuple[FloatArray, FloatArray]:
        # u extends a little past the end so stations up to `length` are covered
        u = np.linspace(0.0, self.length * 1.2 + 1.0, 4001)
        dv = self.b + 2 * self.c * u + 3 * self.d * u * u
        speed = np.sqrt(1.0 + dv * dv)
        s = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(u))])
        return s, u

    def local(self, ds):
        s_tab, u_tab = self._arc_table
        u = np.interp(ds, s_tab, u_tab)
        v = self.a + u * (self.b + u * (self.c + u * self.d))
        dv = self.b + 2 * self.c * u + 3 * self.d * u * u
        ddv = 2 * self.c + 6 * self.d * u
        theta = np.arctan(dv)
        kappa = ddv / (1.0 + dv * dv) ** 1.5
        return u, v, theta, kappa


@dataclass(frozen=True)
class ParamPoly3(Geometry):
    """Parametric cubic ``u(p), v(p)`` in the local frame.

    ``p_range`` is ``"arcLength"`` (p runs over ``[0, length]`` and is assumed to be arc
    length) or ``"normalized"`` (p runs over ``[0, 1]``; p = ds / length).
    """

    aU: float = 0.0
    bU: float = 1.0
    cU: float = 0.0
    dU: float = 0.0
    aV: float = 0.0
    bV: float = 0.0
    cV: float = 0.0
    dV: float = 0.0
    p_range: Literal["arcLength", "normalized"] = "arcLength"

    def local(self, ds):
        ds = np.asarray(ds, dtype=float)
        p = ds / self.length if self.p_range == "normalized" else ds
        u = self.aU + p * (self.bU + p * (self.cU + p * self.dU))
        v = self.aV + p * (self.bV + p * (self.cV + p * self.dV))
        du = self.bU + p * (2 * self.cU + 3 * self.dU * p)
        dv = self.bV + p * (2 * self.cV + 3 * self.dV * p)
        ddu = 2 * self.cU + 6 * self.dU * p
        ddv = 2 * self.cV + 6 * self.dV * p
        theta = np.arctan2(dv, du)
        kappa = (du * ddv - dv * ddu) / np.maximum((du * du + dv * dv) ** 1.5, 1e-300)
        return u, v, theta, kappa


# ---------------------------------------------------------------------------
# lanes
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RoadMark:
    """Road marking of a lane's outer border from ``s_offset`` (metres, section-relative)."""

    s_offset: float = 0.0
    type: RoadMarkType = "solid"
    width_m: float = 0.15
    color: str = "standard"


@dataclass(frozen=True)
class Lane:
    """One lane of a lane section.

    ``id`` > 0 left of the reference line, < 0 right, 0 the centre lane (no width).
    ``width`` has section-relative ``s0`` (OpenDRIVE's ``sOffset``). ``predecessor`` /
    ``successor`` are lane ids in the neighbouring section or linked road, or ``None``.
    """

    id: int
    type: LaneType = "driving"
    width: CubicProfile = field(default_factory=CubicProfile)
    road_marks: tuple[RoadMark, ...] = ()
    predecessor: int | None = None
    successor: int | None = None
    level: bool = False

    def __repr__(self) -> str:
        return (
            f"Lane({self.id}, {self.type!r}, width={self.width!r}, "
            f"predecessor={self.predecessor}, successor={self.successor})"
        )


@dataclass(frozen=True)
class LaneSection:
    """Lanes valid from road station ``s0`` until the next section.

    ``left`` holds lanes with positive ids ordered 1, 2, ...; ``right`` lanes with negative
    ids ordered -1, -2, ... (inner to outer); ``center`` is lane 0.
    """

    s0: float
    left: tuple[Lane, ...] = ()
    center: Lane = field(default_factory=lambda: Lane(0, "none"))
    right: tuple[Lane, ...] = ()
    single_side: bool = False

    def __repr__(self) -> str:
        ids = [lane.id for lane in self.lanes if lane.id != 0]
        return f"LaneSection(s0={self.s0:.3f}, lanes={ids})"

    @property
    def lanes(self) -> tuple[Lane, ...]:
        """All lanes: left (outer to inner), centre, right (inner to outer)."""
        return (*reversed(self.left), self.center, *self.right)

    def lane(self, lane_id: int) -> Lane:
        """The lane with ``lane_id``; ``KeyError`` if it does not exist."""
        for lane in self.lanes:
            if lane.id == lane_id:
                return lane
        raise KeyError(f"lane {lane_id} not in section at s={self.s0}")


# ---------------------------------------------------------------------------
# roads, links, junctions, network
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RoadLink:
    """Predecessor/successor of a road: another road (with contact point) or a junction."""

    element_type: Literal["road", "junction"]
    element_id: str
    contact_point: ContactPoint | None = None


@dataclass(frozen=True)
class Road:
    """One OpenDRIVE road.

    Parameters
    ----------
    id
        Road id (string, unique in the network).
    geometry
        Reference-line pieces in order; ``geometry[i].s0`` is the road station where the
        piece starts (the first is 0).
    elevation, superelevation, lane_offset
        s-profiles: height z (metres, mapping frame), cross slope (radians), offset of the
        centre lane from the reference line (metres, left positive).
    lane_sections
        Sorted by ``s0``; the first starts at 0.
    junction
        Id of the junction this road is a connecting road of, ``"-1"`` for none.
    """

    id: str
    geometry: tuple[Geometry, ...]
    lane_sections: tuple[LaneSection, ...]
    name: str = ""
    elevation: CubicProfile = field(default_factory=CubicProfile)
    superelevation: CubicProfile | None = None
    lane_offset: CubicProfile = field(default_factory=CubicProfile)
    predecessor: RoadLink | None = None
    successor: RoadLink | None = None
    junction: str = "-1"
    road_type: str = "motorway"
    speed_limit_mps: float | None = None
    osm_way_ids: tuple[int, ...] = ()
    """OSM ways the road was built from (ramps; empty for roads from the LiDAR run).
    Written to the map as ``<userData code="roadtwin:osm_way_ids">``."""
    user_data: tuple[tuple[str, str], ...] = ()
    """``(code, value)`` pairs written as the road's ``<userData>`` (e.g.
    ``roadtwin:carriageway``, ``roadtwin:source``, the OSM ``name`` and ``ref``)."""

    def __repr__(self) -> str:
        links = [
            f"{which}={link.element_type}:{link.element_id}"
            for which, link in (("predecessor", self.predecessor), ("successor", self.successor))
            if link is not None
        ]
        extra = "".join(", " + x for x in links)
        return (
            f"Road({self.id!r}, name={self.name!r}, length={self.length:.3f} m, "
            f"{len(self.geometry)} pieces, {len(self.lane_sections)} lane sections, "
            f"junction={self.junction!r}{extra})"
        )

    @property
    def length(self) -> float:
        """Total reference-line length (metres)."""
        g = self.geometry[-1]
        return g.s0 + g.length

    @cached_property
    def _geometry_s0(self) -> FloatArray:
        return np.array([g.s0 for g in self.geometry], dtype=float)

    def evaluate(self, s: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``x, y, heading, curvature`` of the reference line at stations ``s``.

        Vectorised over ``s``; the loop runs over geometry pieces, not points. Stations
        outside ``[0, length]`` extrapolate the first/last piece.
        """
        s_arr = np.atleast_1d(np.asarray(s, dtype=float))
        idx = np.clip(
            np.searchsorted(self._geometry_s0, s_arr, side="right") - 1, 0, len(self.geometry) - 1
        )
        out = np.empty((4, s_arr.size))
        flat_s = s_arr.reshape(-1)
        flat_idx = idx.reshape(-1)
        order = np.argsort(flat_idx, kind="stable")
        bounds = np.searchsorted(flat_idx[order], np.arange(len(self.geometry) + 1))
        for gi in np.nonzero(np.diff(bounds))[0]:
            sel = order[bounds[gi] : bounds[gi + 1]]
            out[:, sel] = self.geometry[gi].evaluate(flat_s[sel])
        shape = s_arr.shape
        return tuple(o.reshape(shape) for o in out)  # type: ignore[return-value]

    def xy(self, s: ArrayLike) -> FloatArray:
        """Reference-line positions ``(N, 2)`` (mapping frame, metres)."""
        x, y, _, _ = self.evaluate(s)
        return np.stack([x, y], axis=-1)

    def heading(self, s: ArrayLike) -> FloatArray:
        """Reference-line heading (radians) at stations ``s``."""
        return self.evaluate(s)[2]

    def curvature(self, s: ArrayLike) -> FloatArray:
        """Reference-line curvature (1/m) at stations ``s``."""
        return self.evaluate(s)[3]

    def height(self, s: ArrayLike) -> FloatArray:
        """Reference-line height z (metres) at stations ``s``."""
        return self.elevation.value(s)

    def roll(self, s: ArrayLike) -> FloatArray:
        """Superelevation (radians, positive = falling to the right) at stations ``s``;
        zeros where the road has none."""
        if self.superelevation is None or not self.superelevation.pieces:
            return np.zeros(np.shape(np.asarray(s, dtype=float)))
        return self.superelevation.value(s)

    def _plan_scale(self, s: ArrayLike) -> FloatArray | float:
        """Horizontal length of one metre of ``t`` at stations ``s``: ``cos(roll)``.

        OpenDRIVE rotates the lateral axis about the reference line by the
        superelevation, so a point at ``t`` lies ``t cos(roll)`` from the reference line
        in plan and ``t sin(roll)`` above it (the ASAM checker places borders so)."""
        if self.superelevation is None or not self.superelevation.pieces:
            return 1.0  # the common flat road: no array to build
        return np.cos(self.roll(s))

    def to_xy(self, s: ArrayLike, t: ArrayLike) -> FloatArray:
        """Frenet ``(s, t)`` -> mapping-frame ``(N, 2)`` points (t left positive).

        On a superelevated road ``t`` runs along the rolled surface: the point lies
        ``t cos(roll)`` from the reference line in plan (see :meth:`surface_height`)."""
        x, y, h, _ = self.evaluate(s)
        t_arr = np.asarray(t, dtype=float) * self._plan_scale(s)
        return np.stack([x - t_arr * np.sin(h), y + t_arr * np.cos(h)], axis=-1)

    def surface_height(self, s: ArrayLike, t: ArrayLike) -> FloatArray:
        """Height z (metres, mapping frame) of the road surface at Frenet ``(s, t)``:
        elevation plus ``t sin(roll)``."""
        return self.elevation.value(s) + np.asarray(t, dtype=float) * np.sin(self.roll(s))

    # -- lanes --------------------------------------------------------------

    @cached_property
    def _section_s0(self) -> FloatArray:
        return np.array([ls.s0 for ls in self.lane_sections], dtype=float)

    def sections_with_ends(self) -> list[tuple[LaneSection, float]]:
        """Each lane section with the station (metres) where it ends: the next section's
        start, the road's length for the last."""
        return [(sec, self.section_end(k)) for k, sec in enumerate(self.lane_sections)]

    def section_end(self, k: int) -> float:
        """Station (metres) where lane section ``k`` ends: the next section's start, the
        road's length for the last."""
        return self.lane_sections[k + 1].s0 if k + 1 < len(self.lane_sections) else self.length

    def section_index(self, s: ArrayLike) -> NDArray[np.int64]:
        """Index of the lane section containing each station."""
        idx = np.searchsorted(self._section_s0, np.asarray(s, dtype=float), side="right") - 1
        return np.clip(idx, 0, len(self.lane_sections) - 1)

    def lane_border_t(self, s: ArrayLike, lane_id: int) -> FloatArray:
        """Lateral offset t (metres, left positive) of the *outer* border of ``lane_id``.

        Lane 0 gives the lane offset (the centre line). Where the lane does not exist in
        the section containing s, the result is NaN.
        """
        s_arr = np.atleast_1d(np.asarray(s, dtype=float))
        out = np.full(s_arr.shape, np.nan)
        base = self.lane_offset.value(s_arr)
        sec_idx = self.section_index(s_arr)
        for k in np.unique(sec_idx):
            section = self.lane_sections[int(k)]
            sel = sec_idx == k
            ds = s_arr[sel] - section.s0
            if lane_id == 0:
                out[sel] = base[sel]
                continue
            side = section.left if lane_id > 0 else section.right
            if abs(lane_id) > len(side):
                continue
            acc = np.zeros_like(ds)
            for lane in side[: abs(lane_id)]:
                acc += lane.width.value(ds)
            out[sel] = base[sel] + (acc if lane_id > 0 else -acc)
        return out

    # -- Frenet projection --------------------------------------------------

    @cached_property
    def _projection_index(self) -> tuple[FloatArray, cKDTree]:
        n = max(2, math.ceil(self.length / 0.5) + 1)
        s = np.linspace(0.0, self.length, n)
        return s, cKDTree(self.xy(s))

    @cached_property
    def _projection_heights(self) -> FloatArray:
        return self.elevation.value(self._projection_index[0])

    @cached_property
    def _projection_index_3d(self) -> cKDTree:
        tree = self._projection_index[1]
        return cKDTree(np.column_stack([tree.data, HEIGHT_WEIGHT * self._projection_heights]))

    def project(
        self, points: ArrayLike, *, iterations: int = 4, s_init: ArrayLike | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Frenet projection of mapping-frame points onto the reference line.

        Parameters
        ----------
        points
            ``(N, 2)`` or ``(N, 3)`` array, mapping frame, metres. With z (and a road with
            an elevation profile) the first guess is the nearest sample at the point's
            level (:func:`nearest_at_level`): a point of a road that passes over or under
            this one's other part goes to its own level.
        s_init
            Optional ``(N,)`` first guesses of the stations (metres) instead of the
            nearest sampled point, for a road that comes back near itself (a loop).

        Returns
        -------
        s, t
            Station (clipped to ``[0, length]``) and signed lateral offset (left positive),
            metres, along the rolled surface of a superelevated road (the inverse of
            :meth:`to_xy`). Points beyond the ends get the offset at the end station.
        """
        raw = np.asarray(points, dtype=float)
        pts = raw[:, :2]
        if s_init is None:
            with_z = (
                raw.ndim == 2
                and raw.shape[1] > 2
                and bool(self.elevation.pieces)
                and bool(np.isfinite(raw[:, 2]).all())
            )
            s_tab, tree = self._projection_index
            if with_z:
                nearest = nearest_at_level(
                    tree,
                    s_tab,
                    self._projection_heights,
                    lambda: self._projection_index_3d,
                    raw[:, :3],
                )
            else:
                _, nearest = tree.query(pts)
            s = s_tab[nearest]
        else:
            s = np.clip(np.asarray(s_init, dtype=float), 0.0, self.length)
        for _ in range(iterations):  # Newton steps on d/ds |P - C(s)|^2 = 0
            x, y, h, k = self.evaluate(s)
            dx, dy = pts[:, 0] - x, pts[:, 1] - y
            along = dx * np.cos(h) + dy * np.sin(h)
            lateral = -dx * np.sin(h) + dy * np.cos(h)
            denom = np.maximum(1.0 - k * lateral, 0.1)
            s = np.clip(s + along / denom, 0.0, self.length)
        x, y, h, _ = self.evaluate(s)
        t = -(pts[:, 0] - x) * np.sin(h) + (pts[:, 1] - y) * np.cos(h)
        return s, t / self._plan_scale(s)


@dataclass(frozen=True)
class LaneLink:
    """Lane ``from_lane`` of the incoming road connects to ``to_lane`` of the connecting
    (or, in a direct junction, linked) road."""

    from_lane: int
    to_lane: int


@dataclass(frozen=True)
class Connection:
    """A junction connection.

    For a ``default`` junction ``connecting_road`` is the connecting road inside the
    junction; for a ``direct`` junction it is the linked road (OpenDRIVE ``linkedRoad``).
    ``contact_point`` is where the connecting/linked road is entered.
    """

    id: str
    incoming_road: str
    connecting_road: str
    contact_point: ContactPoint
    lane_links: tuple[LaneLink, ...] = ()


@dataclass(frozen=True)
class Junction:
    """An OpenDRIVE junction: ``type`` is ``"default"`` or ``"direct"``."""

    id: str
    connections: tuple[Connection, ...]
    name: str = ""
    type: Literal["default", "direct"] = "default"

    def __repr__(self) -> str:
        return f"Junction({self.id!r}, {self.type!r}, {len(self.connections)} connections)"


@dataclass(frozen=True)
class Header:
    """OpenDRIVE header.

    ``geo_reference`` is the PROJ string of the mapping frame (no ``+no_defs``);
    ``offset`` an optional ``(x, y, z, hdg)`` of the OpenDRIVE ``<offset>`` element;
    ``data_quality`` optional absolute/relative errors in metres
    (``{"xy_absolute": .., "z_absolute": .., "xy_relative": .., "z_relative": ..}``) of the
    measurement data, as OpenDRIVE's ``<dataQuality><error>`` defines them (absolute error,
    and relative error between adjacent entries; not a fit residual);
    ``user_data`` ``(code, value)`` pairs written as ``<userData>`` (generator, version,
    method, measured self-consistency).
    """

    name: str = "roadtwin"
    rev_major: int = 1
    rev_minor: int = 8
    geo_reference: str = ""
    offset: tuple[float, float, float, float] | None = None
    vendor: str = "roadtwin"
    date: str = ""
    data_quality: dict[str, float] | None = None
    user_data: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class RoadNetwork:
    """The whole map: header, roads and junctions."""

    header: Header
    roads: tuple[Road, ...]
    junctions: tuple[Junction, ...] = ()

    def __repr__(self) -> str:
        km = sum(r.length for r in self.roads) / 1000.0
        return (
            f"RoadNetwork({self.header.name!r}, {len(self.roads)} roads, "
            f"{len(self.junctions)} junctions, {km:.3f} km)"
        )

    @cached_property
    def id_to_road(self) -> dict[str, Road]:
        """Roads by id."""
        return {r.id: r for r in self.roads}

    @cached_property
    def id_to_junction(self) -> dict[str, Junction]:
        """Junctions by id."""
        return {j.id: j for j in self.junctions}

    def road(self, road_id: str) -> Road:
        """The road with ``road_id``; ``KeyError`` if absent."""
        return self.id_to_road[road_id]


# ---------------------------------------------------------------------------
# small constructors used by several stages
# ---------------------------------------------------------------------------


def chain_geometry(pieces: Sequence[Geometry]) -> tuple[Geometry, ...]:
    """Re-number ``s0`` of consecutive pieces so each starts where the previous ends."""
    out: list[Geometry] = []
    s = 0.0
    for piece in pieces:
        out.append(replace(piece, s0=s))
        s += piece.length
    return tuple(out)


def constant_lane(
    lane_id: int,
    width_m: float,
    *,
    lane_type: LaneType = "driving",
    mark: RoadMarkType = "solid",
) -> Lane:
    """A lane of constant width with one road mark on its outer border."""
    return Lane(
        lane_id,
        lane_type,
        CubicProfile.constant(width_m),
        (RoadMark(0.0, mark),),
    )


def close_width(lane: Lane, length_m: float) -> Lane:
    """``lane`` with its last width piece corrected to end at zero width at ``length_m``
    (metres from the section start); the correction grows linearly over that piece (a
    lane that ends beside others away from a gore closes to zero width)."""
    pieces = lane.width.pieces
    if not pieces:
        return lane
    last = pieces[-1]
    span = length_m - last.s0
    if span <= 0.0:
        return lane
    w_end = float(lane.width.value(np.array([length_m]))[0])
    if abs(w_end) < 1e-7:
        return lane
    fixed = replace(last, b=last.b - w_end / span)
    return replace(lane, width=replace(lane.width, pieces=(*pieces[:-1], fixed)))


def continue_width(lane: Lane, w_start: float) -> Lane:
    """``lane`` with its first width piece corrected to start at ``w_start`` (metres); the
    correction fades out linearly over that piece (a lane that continues across a section
    boundary or a link keeps its width there: fits of neighbouring sections differ by
    millimetres)."""
    pieces = lane.width.pieces
    if not pieces:
        return lane
    p0 = pieces[0]
    delta = w_start - p0.a
    if abs(delta) < 1e-7:
        return lane
    span = (pieces[1].s0 if len(pieces) > 1 else p0.s0 + 1e9) - p0.s0
    slope = -delta / span if len(pieces) > 1 else 0.0
    first = replace(p0, a=p0.a + delta, b=p0.b + slope)
    return replace(lane, width=replace(lane.width, pieces=(first, *pieces[1:])))
