"""The ramp's reference line as a curvature-bounded clothoid spline anchored at the gore.

OSM ramps are drawn metres off, with corners and sparse nodes; smoothing and offsetting
such a polyline knots it where the ramp is a tight loop, and blending it onto an anchor
bends it sharply. Real ramps are designed as clothoids and arcs, so the reference line is
modelled as one: it starts exactly at the anchor pose on the mainline (position, heading,
curvature), its curvature is piecewise linear in arc length between knots and bounded
(:attr:`RampConfig.min_radius_m`, tighter on the side of its lanes so that no lane border
folds), and the knot curvatures are fitted by robust least squares:

* to the OSM shape (target points, metres of uncertainty), and
* where the LiDAR saw the ramp past the gore, to the measured road edges and lane
  markings: each point is associated with the nearest predicted ramp boundary of its kind
  and its lateral offset from the curve is fitted, together with the ramp's inner
  shoulder, lane and hard shoulder widths. The association is grown outward from the
  gore (where the anchored curve is right by construction) window by window, with a
  shrinking gate, so a ramp that OSM places metres off is still picked up correctly.

A curve of bounded curvature integrated from one pose cannot kink or fold locally, what
ever the targets do. The Jacobian is analytic: a change of curvature at ``u`` turns the
rest of the curve about the point at ``u``.

All coordinates are in the mapping frame (metres, radians CCW from +x); ``a`` is the arc
length along the ramp from its attachment (metres); lateral offsets ``lat`` are measured
from the reference line towards the ramp's lanes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from threadpoolctl import threadpool_limits

from ..config import RampConfig
from ..fitting import arc_length
from .records import FloatArray

_POINT_SIGMA_M = 0.05  # a measured edge point / lane sample about its boundary
_WIDTH_PRIOR_SIGMA_M = 0.6  # the default widths as weak priors
_MIN_GROUP_POINTS = 20  # an edge seen by fewer points cannot give its shoulder's width
_MAX_POINTS = 600  # measured points used per ramp (evenly thinned beyond)
_OSM_LOOKAHEAD_M = 40.0  # OSM is ignored up to this far beyond the measured window
_MEASURED_REACH_M = 10.0  # ... and where associated points lie this close along the ramp
_LOOKAHEAD_WEIGHT = 0.1  # OSM's weight in the look-ahead (enough to stop a swing there)
_DIRECTION_NEIGHBOURS = 10  # points whose spread gives a measured point's line direction
_LINE_LINK_M = 15.0  # points of one line: this close along it (a dash and a gap) ...
_LINE_LATERAL_M = 0.4  # ... this close across it ...
_LINE_TURN_RAD = math.radians(15.0)  # ... and directions this close
_LINE_OUTLIER_M = 3.0  # a point of a known line this far off its boundary is an outlier
_MAX_CROSSING_RAD = math.radians(30.0)  # a point on a line crossing the ramp at more than
# this is another road's (a flyover's edge), never the ramp's


@dataclass(frozen=True)
class RampCrossSection:
    """Boundaries of a ramp as offsets from its reference line towards its lanes.

    Road edges at ``0`` and ``g(a) w_in + n w + w_hs``; markings at ``g(a) w_in + j w``
    (``j = 0..n``), with ``g`` the inner shoulder opening from zero width at the gore over
    ``taper_m`` (C1 cubic), as the ramp road is built.
    """

    lanes: int
    taper_m: float

    def offsets(self, a: FloatArray, widths: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(B, N)`` boundary offsets at ``a`` and their ``(B, N, 3)`` derivatives by the
        widths ``(w_in, w, w_hs)``."""
        x = np.clip(a / max(self.taper_m, 1e-6), 0.0, 1.0)
        g = x * x * (3.0 - 2.0 * x)
        coef = self.coefficients()  # (B, 3) on (g w_in, w, w_hs)
        d = np.empty((coef.shape[0], a.size, 3))
        d[:, :, 0] = coef[:, 0, None] * g[None, :]
        d[:, :, 1] = coef[:, 1, None]
        d[:, :, 2] = coef[:, 2, None]
        return d @ widths, d

    def coefficients(self) -> FloatArray:
        rows = [(0.0, 0.0, 0.0)]
        rows += [(1.0, float(j), 0.0) for j in range(self.lanes + 1)]
        rows.append((1.0, float(self.lanes), 1.0))
        return np.array(rows)

    def is_edge(self) -> NDArrayBool:
        return np.array([True] + [False] * (self.lanes + 1) + [True])

    def group(self) -> NDArrayInt:
        """0 reference edge, 1 markings, 2 outer edge (for counting what was seen)."""
        return np.array([0] + [1] * (self.lanes + 1) + [2])


NDArrayBool = np.ndarray
NDArrayInt = np.ndarray


@dataclass(frozen=True)
class RampShape:
    """A fitted ramp reference line.

    Attributes
    ----------
    xy : ``(M, 2)`` dense reference line every ``shape_step_m`` from the anchor,
        attachment-first (mapping frame, metres).
    widths : ``(inner shoulder, lane, hard shoulder)`` widths (metres).
    points : measured points matched to a ramp boundary (0 without evidence).
    counts : matched points per boundary group ``(reference edge, markings, outer edge)``.
    span_m : the farthest matched point from the gore along the ramp (metres).
    rmse_m : residual RMSE of the matched points (metres).
    """

    xy: FloatArray
    widths: tuple[float, float, float]
    points: int = 0
    counts: tuple[int, int, int] = (0, 0, 0)
    span_m: float = 0.0
    rmse_m: float = math.nan


def _knot_basis(a: FloatArray, knots: FloatArray) -> FloatArray:
    """``(len(a), len(knots))`` hat functions: curvature linear between knots."""
    width = np.diff(knots)
    left = np.concatenate([[1.0], width])
    right = np.concatenate([width, [1.0]])
    d = a[:, None] - knots[None, :]
    up = np.clip(1.0 + d / left[None, :], 0.0, 1.0)
    down = np.clip(1.0 - d / right[None, :], 0.0, 1.0)
    return np.where(d <= 0.0, up, down)


def _cumtrapz(values: FloatArray, step: float) -> FloatArray:
    """Cumulative trapezoid integral along axis 0 from 0 (same length)."""
    out = np.zeros_like(values)
    out[1:] = np.cumsum(0.5 * (values[1:] + values[:-1]) * step, axis=0)
    return out


def curvature_bounds(lane_side: float, width_m: float, config: RampConfig) -> tuple[float, float]:
    """Curvature limits ``(lo, hi)`` (1/m, left positive) of a reference line whose lanes
    lie on ``lane_side`` (+1 left of its direction, -1 right) and span ``width_m``: at
    most ``1 / min_radius_m`` either way, and the outer lane border keeps that radius too
    (it lies ``width_m`` inside a turn towards the lanes)."""
    k_max = 1.0 / config.min_radius_m
    k_towards = 1.0 / (config.min_radius_m + width_m)
    return (-k_towards, k_max) if lane_side < 0 else (-k_max, k_towards)


class _Spline:
    """The clothoid spline: curvature at the anchor fixed, free knot curvatures."""

    def __init__(self, length: float, anchor, curvature0: float, cfg: RampConfig) -> None:
        n_grid = max(3, math.ceil(length / cfg.shape_step_m) + 1)
        self.a = np.linspace(0.0, length, n_grid)
        self.step = float(self.a[1] - self.a[0])
        n_knots = max(2, math.ceil(length / cfg.shape_knot_m) + 1)
        self.knots = np.linspace(0.0, length, n_knots)
        self.basis = _knot_basis(self.a, self.knots)  # (G, K)
        self.cum_basis = _cumtrapz(self.basis, self.step)  # heading change per knot
        self.anchor = anchor
        self.k0 = curvature0
        self.n_free = n_knots - 1

    def evaluate(self, p: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Points ``(G, 2)`` and headings ``(G,)`` on the grid."""
        x0, y0, h0 = self.anchor
        kappa = np.interp(self.a, self.knots, np.concatenate([[self.k0], p]))
        heading = h0 + _cumtrapz(kappa, self.step)
        mid = 0.5 * (heading[1:] + heading[:-1])
        # the chord of a circular arc turning by dh is step * sinc(dh / 2)
        chord = self.step * np.sinc((heading[1:] - heading[:-1]) / (2.0 * np.pi))
        xy = np.empty((self.a.size, 2))
        xy[0] = (x0, y0)
        xy[1:, 0] = x0 + np.cumsum(chord * np.cos(mid))
        xy[1:, 1] = y0 + np.cumsum(chord * np.sin(mid))
        return xy, heading

    def position_jacobian(self, xy: FloatArray) -> FloatArray:
        """``(G, 2, K-1)``: d position / d free knot curvature. A curvature change at u
        turns the curve beyond u about P(u): dP(a) = R90 (P(a) - P(u)) dtheta(u), and
        dtheta(u)/dkappa_j = C_j(u), so dP(a)/dkappa_j = R90 (P(a) C_j(a) - D_j(a)) with
        D_j(a) = int_0^a B_j(u) P(u) du (B_j the knot's hat function)."""
        b = self.basis[:, 1:]  # (G, K-1)
        c = self.cum_basis[:, 1:]
        # int_0^a C_j P' = C_j(a) P(a) - int_0^a B_j P (by parts, C_j(0) = 0)
        d = _cumtrapz(b[:, :, None] * xy[:, None, :], self.step)  # (G, K-1, 2)
        v = xy[:, None, :] * c[:, :, None] - d
        return np.stack([-v[:, :, 1], v[:, :, 0]], axis=1)  # R90 (x, y) = (-y, x)


def _project_on_grid(
    xy_curve: FloatArray, heading: FloatArray, step: float, pts: FloatArray, tree: cKDTree
) -> tuple[FloatArray, FloatArray, NDArrayInt]:
    """Foot stations (metres), left-positive lateral offsets and nearest grid index of
    points on the dense curve (linear refinement within one grid step)."""
    _, idx = tree.query(pts)
    d = pts - xy_curve[idx]
    c, s = np.cos(heading[idx]), np.sin(heading[idx])
    along = np.clip(d[:, 0] * c + d[:, 1] * s, -step, step)
    lateral = -d[:, 0] * s + d[:, 1] * c
    return idx * step + along, lateral, idx


def line_directions(xy: FloatArray, group: NDArrayBool) -> FloatArray:
    """Direction (radians, modulo pi) of the line each measured point lies on: the main
    axis of its ``_DIRECTION_NEIGHBOURS`` nearest points of the same group (edges or lane
    samples), mapping frame. Points of a boundary lie on a line; this tells a boundary
    that runs along the ramp from one that crosses it."""
    out = np.zeros(xy.shape[0])
    for g in (False, True):
        sel = np.flatnonzero(group == g)
        if sel.size < 3:
            continue
        k = min(_DIRECTION_NEIGHBOURS, sel.size)
        _, nb = cKDTree(xy[sel]).query(xy[sel], k=k)
        d = xy[sel][nb] - xy[sel][nb].mean(axis=1, keepdims=True)  # (n, k, 2)
        cxx = np.einsum("nk,nk->n", d[..., 0], d[..., 0])
        cyy = np.einsum("nk,nk->n", d[..., 1], d[..., 1])
        cxy = np.einsum("nk,nk->n", d[..., 0], d[..., 1])
        out[sel] = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)
    return out


def _line_angle(a: FloatArray, b: FloatArray) -> FloatArray:
    """Angle (radians, 0..pi/2) between undirected lines of directions ``a`` and ``b``."""
    return np.abs(np.angle(np.exp(2j * (a - b)))) / 2.0


def _along_curve(direction: FloatArray, heading: FloatArray) -> NDArrayBool:
    """Whether lines of ``direction`` (modulo pi) run within ``_MAX_CROSSING_RAD`` of the
    curve headings."""
    return _line_angle(direction, heading) <= _MAX_CROSSING_RAD


def boundary_lines(xy: FloatArray, group: NDArrayBool, direction: FloatArray) -> NDArrayInt:
    """Label measured points by the line they lie on (connected components).

    Two points of the same group (edges or lane samples) belong to one line when they lie
    within ``_LINE_LINK_M`` of each other along the line (a marking's dashes and gaps
    included), within ``_LINE_LATERAL_M`` across it, and their line directions agree.
    A crossing road's edges and a parallel boundary a lane away are other lines.
    """
    n = xy.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    pairs = cKDTree(xy).query_pairs(_LINE_LINK_M, output_type="ndarray")
    if pairs.size == 0:
        return np.arange(n, dtype=np.int64)
    i, j = pairs[:, 0], pairs[:, 1]
    d = xy[j] - xy[i]
    u = np.stack([np.cos(direction[i]), np.sin(direction[i])], axis=1)
    across = np.abs(d[:, 0] * u[:, 1] - d[:, 1] * u[:, 0])
    same_dir = _line_angle(direction[i], direction[j]) <= _LINE_TURN_RAD
    keep = (group[i] == group[j]) & (across <= _LINE_LATERAL_M) & same_dir
    graph = coo_matrix((np.ones(int(keep.sum())), (i[keep], j[keep])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return labels.astype(np.int64)


def _associate_lines(
    r: FloatArray, in_window: NDArrayBool, lines: NDArrayInt, known: dict[int, int], gate: float
) -> tuple[NDArrayBool, NDArrayInt, dict[int, int]]:
    """Points matched to a ramp boundary, line by line.

    ``r`` ``(B, P)``: residuals of every point against every boundary (``inf`` where the
    kind differs). A line keeps the boundary it was matched to in an earlier window
    (``known``), so a curve that swings beyond the measured stretch is pulled back by the
    lines it already follows instead of losing them; a new line takes the boundary its
    points lie nearest to by median, if within ``gate`` (metres). Points farther than
    ``_LINE_OUTLIER_M`` from their line's boundary are left out (``gate`` for new lines).
    Returns the mask of matched points, every point's boundary and each matched line's.
    """
    ok = np.zeros(r.shape[1], dtype=bool)
    kind = np.argmin(np.abs(r), axis=0)
    matched: dict[int, int] = {}
    for line in (int(x) for x in np.unique(lines[in_window])):
        idx = np.flatnonzero(in_window & (lines == line))
        med = np.median(np.abs(r[:, idx]), axis=1)
        seen = line in known
        k = known[line] if seen else int(np.argmin(med))
        if not seen and not med[k] <= gate:
            continue
        kind[idx] = k
        ok[idx] = np.abs(r[k, idx]) <= (max(gate, _LINE_OUTLIER_M) if seen else gate)
        if ok[idx].any():
            matched[line] = k
    return ok, kind, matched


# the solves are small dense problems: BLAS threads only contend (a loaded 2-core machine
# took 20x longer with them)
@threadpool_limits.wrap(limits=1, user_api="blas")
def fit_ramp_shape(
    target_xy: FloatArray,
    sigma_m: FloatArray,
    *,
    anchor: tuple[float, float, float],
    curvature0: float,
    lane_side: float,
    lanes: int,
    widths: tuple[float, float, float],
    points: tuple[FloatArray, NDArrayBool] | None = None,
    config: RampConfig | None = None,
) -> RampShape:
    """Fit the ramp's reference line to target points (and measured points), anchored.

    Parameters
    ----------
    target_xy
        ``(N, 2)`` target points of the reference line, attachment-first (mapping frame,
        metres); each is compared with the curve at its own arc length from the first
        point (mostly across the curve). The curve is as long as the target polyline.
    sigma_m
        ``(N,)`` standard deviation of each target point (metres).
    anchor
        ``(x, y, heading)`` where the reference line leaves the mainline, pointing away
        from it (an entry is fitted from its end backwards: heading reversed).
    curvature0
        Curvature at the anchor (1/m, left positive): the ramp leaves the mainline border
        without a curvature jump.
    lane_side
        +1 if the ramp's lanes lie left of the attachment-first direction, -1 right.
    lanes
        Ramp driving lanes.
    widths
        Default ``(inner shoulder, lane, hard shoulder)`` widths (metres); fitted where
        measured points saw the boundaries.
    points
        Measured points ``((P, 2) xy, (P,) is_edge)`` near the ramp past the gore (the
        mainline's own boundaries already removed), or ``None``.
    config
        ``min_radius_m``, ``shape_knot_m``, ``shape_step_m``, ``shape_smoothness``,
        ``evidence_length_m``, ``shoulder_taper_m``.

    Returns
    -------
    RampShape
    """
    cfg = config or RampConfig()
    target = np.asarray(target_xy, dtype=float)[:, :2]
    sigma = np.asarray(sigma_m, dtype=float)
    a_target = arc_length(target)
    spline = _Spline(float(a_target[-1]), anchor, curvature0, cfg)
    # targets every ~2 m are plenty for a shape known to metres (keeps the solves small)
    thin = np.unique(np.searchsorted(a_target, np.arange(0.0, a_target[-1], 2.0)))
    thin = np.unique(np.concatenate([thin, [a_target.size - 1]]))
    target_all, a_all = target, a_target
    target, a_target, sigma = target[thin], a_target[thin], sigma[thin]
    step = spline.step
    w_default = np.asarray(widths, dtype=float)
    lo, hi = curvature_bounds(lane_side, float(w_default.sum() + (lanes - 1) * w_default[1]), cfg)
    k0 = float(np.clip(curvature0, lo + 1e-9, hi - 1e-9))
    spline.k0 = k0
    idx_t = np.clip(np.rint(a_target / step).astype(np.int64), 0, spline.a.size - 1)
    w_target = 1.0 / np.maximum(sigma, 1e-3)
    n_k = spline.n_free
    dd = np.diff(np.eye(n_k + 1), 2, axis=0) / cfg.shape_knot_m**2 * cfg.shape_smoothness
    section = RampCrossSection(lanes, cfg.shoulder_taper_m)
    coef_edge = section.is_edge()

    # initial curvature: the target's heading changes
    h_t = np.unwrap(np.arctan2(*np.gradient(target_all, a_all, axis=0).T[::-1]))
    k_t = np.gradient(h_t, a_all)
    p = np.concatenate([np.clip(np.interp(spline.knots[1:], a_all, k_t), lo, hi), w_default])

    def solve(
        p0: FloatArray,
        assoc: tuple | None,
        w_row: FloatArray,
        osm_from: float = 0.0,
        measured_a: FloatArray | None = None,
    ) -> FloatArray:
        """Least squares over (knot curvatures, widths) with a fixed association;
        ``w_row`` weights the width priors (large: held at the defaults); targets before
        ``osm_from`` (metres from the gore) are ignored where associated points
        (``measured_a``: their arc lengths) lie within ``_MEASURED_REACH_M``: where the
        ramp was measured the measurement decides, and OSM drawn metres off must not bend
        the prediction of the next stretch; a hole inside the measured stretch (no
        associated point within that reach) keeps its OSM targets (else nothing holds the
        curve there and it swings into an S-bend)."""
        if assoc is not None:
            pts, kind_row = assoc
        if measured_a is not None and measured_a.size:
            a_sorted = np.sort(measured_a)
            j = np.clip(np.searchsorted(a_sorted, a_target), 1, a_sorted.size - 1)
            gap = np.minimum(np.abs(a_target - a_sorted[j - 1]), np.abs(a_target - a_sorted[j]))
            if a_sorted.size == 1:
                gap = np.abs(a_target - a_sorted[0])
            # holes inside the measured stretch only: beyond it the look-ahead applies
            # inside the measured stretch a hole is held by OSM; beyond it (the look-ahead)
            # OSM only damps the curve, so that the next window's points still find it
            unmeasured = np.where(
                a_target < a_sorted[-1], gap > _MEASURED_REACH_M, _LOOKAHEAD_WEIGHT
            )
        else:
            unmeasured = np.zeros(a_target.size, dtype=bool)
        w_t = w_target * np.maximum(a_target >= osm_from, unmeasured)

        def parts(p: FloatArray):
            xy, heading = spline.evaluate(p[:n_k])
            return xy, heading

        def residuals(p: FloatArray) -> FloatArray:
            xy, heading = parts(p)
            d = target - xy[idx_t]
            h = heading[idx_t]
            c, s = np.cos(h), np.sin(h)
            cross = (-d[:, 0] * s + d[:, 1] * c) * w_t
            along = 0.1 * (d[:, 0] * c + d[:, 1] * s) * w_t
            out = [cross, along, dd @ np.concatenate([[k0], p[:n_k]])]
            out.append((p[n_k:] - w_default) / _WIDTH_PRIOR_SIGMA_M * w_row)
            if assoc is not None:
                tree = cKDTree(xy)
                a_p, lat, _ = _project_on_grid(xy, heading, step, pts, tree)
                offs, _ = section.offsets(a_p, p[n_k:])
                pred = offs[kind_row, np.arange(pts.shape[0])]
                out.append((lane_side * lat - pred) / _POINT_SIGMA_M)
            return np.concatenate(out)

        def jacobian(p: FloatArray) -> FloatArray:
            xy, heading = parts(p)
            dpos = spline.position_jacobian(xy)  # (G, 2, K)
            h = heading[idx_t]
            c, s = np.cos(h), np.sin(h)
            d = target - xy[idx_t]
            cross = -d[:, 0] * s + d[:, 1] * c
            along = d[:, 0] * c + d[:, 1] * s
            dth = spline.cum_basis[idx_t, 1:]  # d heading / d kappa_j
            dp_t = dpos[idx_t]
            j_cross = -(-s[:, None] * dp_t[:, 0] + c[:, None] * dp_t[:, 1]) - along[:, None] * dth
            j_along = -(c[:, None] * dp_t[:, 0] + s[:, None] * dp_t[:, 1]) + cross[:, None] * dth
            rows = [
                np.hstack([j_cross * w_t[:, None], np.zeros((idx_t.size, 3))]),
                np.hstack([0.1 * j_along * w_t[:, None], np.zeros((idx_t.size, 3))]),
                np.hstack([dd[:, 1:], np.zeros((dd.shape[0], 3))]),
                np.hstack([np.zeros((3, n_k)), np.diag(w_row / _WIDTH_PRIOR_SIGMA_M)]),
            ]
            if assoc is not None:
                tree = cKDTree(xy)
                a_p, _, gi = _project_on_grid(xy, heading, step, pts, tree)
                hp = heading[gi]
                normal = np.stack([-np.sin(hp), np.cos(hp)], axis=1)
                # the foot point moves along the curve: only the normal part counts
                j_lat = -np.einsum("pk,pkj->pj", normal, dpos[gi])
                _, doffs = section.offsets(a_p, p[n_k:])
                j_w = -doffs[kind_row, np.arange(pts.shape[0])]
                rows.append(np.hstack([lane_side * j_lat, j_w]) / _POINT_SIGMA_M)
            return np.vstack(rows)

        # narrower than 0.3 m is an edge line, not a shoulder (and no lane of zero width)
        lower = np.concatenate([np.full(n_k, lo), [0.3, 2.5, 0.3]])
        upper = np.concatenate([np.full(n_k, hi), [3.0, 5.0, 4.0]])
        res = least_squares(
            residuals,
            np.clip(p0, lower + 1e-9, upper - 1e-9),
            jac=jacobian,
            bounds=(lower, upper),
            loss="soft_l1",
            f_scale=2.0,
            x_scale=np.concatenate([np.full(n_k, 0.01), np.ones(3)]),
            max_nfev=40,
        )
        return res.x

    p = solve(p, None, np.full(3, 1e3))  # widths held at their defaults until measured
    xy, heading = spline.evaluate(p[:n_k])
    if points is None or len(points[0]) == 0:
        return RampShape(xy, tuple(float(w) for w in w_default))

    pts_every = np.asarray(points[0], dtype=float)[:, :2]
    edge_every = np.asarray(points[1], dtype=bool)
    dir_every = line_directions(pts_every, edge_every)
    pts_all, edge_all, dir_all = pts_every, edge_every, dir_every
    if pts_all.shape[0] > _MAX_POINTS:  # a deterministic even thinning keeps solves small
        keep = np.linspace(0, pts_all.shape[0] - 1, _MAX_POINTS).astype(np.int64)
        pts_all, edge_all, dir_all = pts_all[keep], edge_all[keep], dir_all[keep]
    reach = min(cfg.evidence_length_m, float(spline.a[-1]))
    # windows growing by half their length: a fit predicts well about that far ahead
    windows = [w for w in (30.0, 45.0, 70.0, 105.0, 160.0, 240.0, 360.0) if w < reach]
    windows.append(reach)
    lines = boundary_lines(pts_all, edge_all, dir_all)
    known: dict[int, int] = {}  # line -> boundary, from the windows before
    assoc = None
    best = None
    for k, window in enumerate(windows):
        # the new part of a window may lie a metre or two off the prediction (OSM drawn
        # off, a ramp bending away): start wide, shrink once it is followed
        gates = (1.5, 1.0, 0.7, 0.4) if k == 0 else (1.5, 0.6)
        for gate in gates:
            tree = cKDTree(xy)
            a_p, lat, gi = _project_on_grid(xy, heading, step, pts_all, tree)
            offs, _ = section.offsets(a_p, p[n_k:])
            r = lane_side * lat[None, :] - offs
            r[coef_edge[:, None] != edge_all[None, :]] = np.inf
            in_window = (a_p > 0.5) & (a_p <= window) & _along_curve(dir_all, heading[gi])
            ok, kind, matched = _associate_lines(r, in_window, lines, known, gate)
            if np.count_nonzero(ok) < cfg.evidence_min_points // 4:
                break
            groups = section.group()[kind[ok]]
            counts = np.bincount(groups, minlength=3)
            # a width is measured only where the boundaries that bound it were seen: the
            # inner shoulder needs the reference edge (else shifting the line and the
            # shoulder fit the same points), the hard shoulder the outer edge
            w_row = np.where(counts >= _MIN_GROUP_POINTS, 1.0, 1e3)
            assoc = (pts_all[ok], kind[ok])
            measured_a = a_p[ok]
            span = float(np.max(measured_a))
            p = solve(p, assoc, w_row, osm_from=span + _OSM_LOOKAHEAD_M, measured_a=measured_a)
            xy, heading = spline.evaluate(p[:n_k])
            best = (ok, kind)
        else:
            known.update(matched)
            continue
        break
    if assoc is None or best is None:
        return RampShape(xy, tuple(float(w) for w in w_default))
    # beyond the measured stretch the OSM shape decides again
    p = solve(p, assoc, w_row, osm_from=span, measured_a=measured_a)
    xy, heading = spline.evaluate(p[:n_k])
    # every measured point (not only the thinned ones) against the final boundaries
    tree = cKDTree(xy)
    a_p, lat, gi = _project_on_grid(xy, heading, step, pts_every, tree)
    offs, _ = section.offsets(a_p, p[n_k:])
    r = lane_side * lat[None, :] - offs
    r[coef_edge[:, None] != edge_every[None, :]] = np.inf
    kind = np.argmin(np.abs(r), axis=0)
    resid = r[kind, np.arange(a_p.size)]
    good = (np.abs(resid) <= 0.4) & (a_p > 0.5) & (a_p <= float(spline.a[-1]))
    good &= _along_curve(dir_every, heading[gi])
    groups = section.group()[kind[good]]
    counts = np.bincount(groups, minlength=3)
    widths_out = tuple(float(w) for w in p[n_k:])
    return RampShape(
        xy,
        widths_out,  # type: ignore[arg-type]
        points=int(np.count_nonzero(good)),
        counts=(int(counts[0]), int(counts[1]), int(counts[2])),
        span_m=float(np.max(a_p[good])) if np.any(good) else 0.0,
        rmse_m=float(np.sqrt(np.mean(resid[good] ** 2))) if np.any(good) else math.nan,
    )
