"""Point reduction: dense road-edge points and lane samples -> what the fits need.

Our simulator writes ~10 k road-edge points per km; a real mobile mapper gives 0.1-5 M. The
fits downstream (mainline, ramp evidence, self-consistency) need a few points per metre of
each line, and were tuned at that density. This stage makes their input the same kind at
any density, in one linear pass over the points and with bounded memory:

1. **Cells.** Every point is placed in the Frenet frame of the trajectory (station ``s``
   along the trajectory densified to 2 m, lateral offset ``t``, left positive) and counted
   in a cell of ``cell_station_m`` x ``cell_lateral_m`` (default 0.25 m x 0.05 m) of its
   group (road-edge side, or all lane samples). Per cell the sufficient statistics are
   summed: count, sum of x, y, z and of the lateral offset and its square (relative to the
   cell's lower border, for precision). The sums are additive, so chunks of a file are
   reduced one at a time and merged, in any order; nothing is sorted per point.
2. **Line density.** Per station bin the densest 0.3 m wide lateral window holds one line
   (an edge, a marking); the median of those counts over the run is the run's density of a
   line, points per metre, per group.
3. **Rows.** Where that density exceeds ``reduce_factor`` times the target
   (``edge_points_per_m`` / ``lane_samples_per_m``), each cell is written as copies of
   its mean point, as many as its count divided by ``q = density / target``; the fractions
   are carried from cell to cell in station order (error diffusion), so the result is
   deterministic and every cell keeps its share of the points to within one row. Lines
   come out at the target density, and a stray point keeps the weight it had among the raw
   points (1 % outliers stay 1 % of the rows): the robust fits see the same statistics as
   on a sparse run, with cell means that are more precise than single points. Below the
   threshold the points pass unchanged (the bundled runs are not touched).

Each row keeps the lateral variance of the points inside its cell (``spread_m2``), so
self-consistency against the map can be computed over all points from the rows
(``e^2`` of the cell mean plus that variance).

Frames: input and output points are in the mapping frame (metres); ``s``/``t`` are only
used to place points in cells.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

__all__ = [
    "CellAccumulator",
    "ReducedPoints",
    "Reduction",
    "TrajectoryLine",
    "trajectory_line",
]

_LINE_WINDOW_M = 0.3
"""Lateral width of the window that holds one line (an edge or a marking), metres."""
_VALLEY = 0.5
"""A cell with fewer points than this share of the largest count on both sides of it
separates two lines (metres-free: a ratio of counts)."""
_TAIL = 0.05
"""Cells with fewer points than this share of their run's largest count are its tails."""
_DENSITY_BLOCK_M = 25.0
"""Length of the stretches over which the local line density is measured, metres."""
_COARSE_M = 1.0
"""Cell size of the coarse grid whose centres are looked up in the KD-tree, metres."""
_STATS = 6  # count, sum x, sum y, sum z, sum u, sum u^2


@dataclass(frozen=True)
class TrajectoryLine:
    """The trajectory densified to a polyline: the frame points are placed in.

    Attributes
    ----------
    xy : (V, 2) vertices, mapping frame, metres (every ``step_m`` and every pose).
    s : (V,) station of each vertex, metres from the first pose.
    tree : KD-tree of the vertices (distance checks, nearest vertex).
    """

    xy: FloatArray
    s: FloatArray
    tree: cKDTree

    @property
    def length(self) -> float:
        return float(self.s[-1])

    @cached_property
    def seg_len(self) -> FloatArray:
        """(V - 1,) segment lengths, metres."""
        return np.diff(self.s)

    @cached_property
    def seg_u(self) -> FloatArray:
        """(V - 1, 2) unit direction of every segment."""
        return np.diff(self.xy, axis=0) / np.maximum(self.seg_len, 1e-12)[:, None]

    @cached_property
    def seg_ux(self) -> FloatArray:
        return np.ascontiguousarray(self.seg_u[:, 0])

    @cached_property
    def seg_uy(self) -> FloatArray:
        return np.ascontiguousarray(self.seg_u[:, 1])

    @cached_property
    def tangent_x(self) -> FloatArray:
        return np.ascontiguousarray(self.tangent[:, 0])

    @cached_property
    def tangent_y(self) -> FloatArray:
        return np.ascontiguousarray(self.tangent[:, 1])

    @cached_property
    def rel_x(self) -> FloatArray:
        """(V,) vertex x relative to the first vertex (metres)."""
        return self.xy[:, 0] - self.xy[0, 0]

    @cached_property
    def rel_y(self) -> FloatArray:
        return self.xy[:, 1] - self.xy[0, 1]

    @cached_property
    def tangent(self) -> FloatArray:
        """(V, 2) unit tangent at every vertex (mean of the adjacent segments)."""
        u = self.seg_u
        if u.shape[0] == 0:
            return np.array([[1.0, 0.0]])
        tg = np.vstack([u[:1], u[:-1] + u[1:], u[-1:]])
        return tg / np.maximum(np.hypot(tg[:, 0], tg[:, 1]), 1e-12)[:, None]


def trajectory_line(xy: FloatArray, *, step_m: float = 2.0) -> TrajectoryLine:
    """The trajectory ``(N, 2)`` (mapping frame, metres) densified to ``step_m``.

    The vertices are the poses plus points every ``step_m`` along the chords between them;
    the distance of a point to the trajectory is its distance to the nearest vertex.
    """
    xy = np.asarray(xy, dtype=float)[:, :2]
    seg = np.hypot(*np.diff(xy, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return TrajectoryLine(xy[:1].copy(), np.zeros(1), cKDTree(xy[:1]))
    n = max(math.ceil(s[-1] / step_m) + 1, 2)
    grid = np.unique(np.concatenate([np.linspace(0.0, s[-1], n), s]))
    keep = np.concatenate([[True], np.diff(s) > 0])
    dense = np.column_stack(
        [np.interp(grid, s[keep], xy[keep, 0]), np.interp(grid, s[keep], xy[keep, 1])]
    )
    return TrajectoryLine(dense, grid, cKDTree(dense))


def _coarse_cells(x: FloatArray, y: FloatArray) -> tuple[IntArray, FloatArray]:
    """Occupied 1 m grid cells of points (``x``, ``y``: metres from the line's first vertex):
    the cell index of every point and the centre of every cell (so that what a point is
    matched with depends on the point alone, not on the chunk it came in). A dense raster
    over the points' bounding box where that is small (points of a file come in driving
    order), else hashing."""
    gx = np.floor(x * (1.0 / _COARSE_M)).astype(np.int64)
    gy = np.floor(y * (1.0 / _COARSE_M)).astype(np.int64)
    x0, y0 = int(gx.min()), int(gy.min())
    nx, ny = int(gx.max()) - x0 + 1, int(gy.max()) - y0 + 1
    if nx * ny <= 4 * x.size + 1024:
        flat = (gx - x0) * ny + (gy - y0)
        occupied = np.flatnonzero(np.bincount(flat, minlength=nx * ny))
        index = np.zeros(nx * ny, np.int64)
        index[occupied] = np.arange(occupied.size)
        cx, cy = x0 + occupied // ny, y0 + occupied % ny
        return index[flat], (np.column_stack([cx, cy]) + 0.5) * _COARSE_M
    import pandas as pd  # hash factorisation: linear, no sort

    off = np.int64(1 << 30)  # cells within +-1e9 m; (gx + off) << 32 stays below 2**63
    codes, uniq = pd.factorize(((gx + off) << 32) | (gy + off))
    uniq = np.asarray(uniq, dtype=np.int64)
    cx, cy = (uniq >> 32) - off, (uniq & 0xFFFFFFFF) - off
    return codes.astype(np.int64), (np.column_stack([cx, cy]) + 0.5) * _COARSE_M


def _cell_codes(
    group: IntArray, i_s: IntArray, i_t: IntArray, *, n_s: int, n_t: int
) -> tuple[IntArray, IntArray]:
    """Index of every point's cell among the chunk's occupied cells, and their keys
    ``(group * n_s + i_s) * n_t + i_t``: counted in a raster over the chunk's range of
    groups, stations and offsets where that is small (a chunk of a file in driving order
    covers a few hundred metres), else by hashing the keys."""
    lo = [int(a.min()) for a in (group, i_s, i_t)]
    span = [int(a.max()) - b + 1 for a, b in zip((group, i_s, i_t), lo, strict=True)]
    size = span[0] * span[1] * span[2]
    if size <= 4 * group.size + 1024:
        local = ((group - lo[0]) * span[1] + (i_s - lo[1])) * span[2] + (i_t - lo[2])
        occupied = np.flatnonzero(np.bincount(local, minlength=size))
        index = np.zeros(size, np.int64)
        index[occupied] = np.arange(occupied.size)
        g, rest = np.divmod(occupied, span[1] * span[2])
        s_, t_ = np.divmod(rest, span[2])
        keys = ((g + lo[0]) * n_s + (s_ + lo[1])) * n_t + (t_ + lo[2])
        return index[local], keys
    import pandas as pd  # hash factorisation: linear, no sort

    codes, uniq = pd.factorize((group * n_s + i_s) * n_t + i_t)
    return codes.astype(np.int64), np.asarray(uniq, dtype=np.int64)


def _project(
    line: TrajectoryLine, x: FloatArray, y: FloatArray, limit_m: float
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], FloatArray, FloatArray]:
    """Station, lateral offset and the distance test of points (mapping frame, metres).

    Per occupied 1 m grid cell (dense points share cells, so the KD-tree sees a fraction of
    them): the vertex nearest to the cell's centre, the segment before or after it by the
    side of the vertex tangent the centre lies on, and that segment's projection as an
    affine map ``(x, y) -> (s, t)``; every point of the cell goes through its cell's map
    (a projection extended a metre past a 2 m segment's end is off by ~(1 m)^2 x
    curvature / 2: 0.5 mm at a 1000 m radius). The result depends on the point alone, not
    on the chunk it came in. ``near`` is exactly the test "distance to the nearest vertex
    <= limit_m": cells that straddle the limit are decided point by point in the KD-tree.
    Also returns x and y relative to the line's first vertex.
    """
    n_v = line.xy.shape[0]
    if x.size == 0:
        return np.zeros(0), np.zeros(0), np.zeros(0, dtype=bool), np.zeros(0), np.zeros(0)
    ref_x, ref_y = float(line.xy[0, 0]), float(line.xy[0, 1])
    rx = x - ref_x
    ry = y - ref_y
    cell, centre = _coarse_cells(rx, ry)
    half_diagonal = math.sqrt(0.5) * _COARSE_M
    reach = limit_m + 2.0 * _COARSE_M
    d_c, v_c = line.tree.query(
        centre + np.array([ref_x, ref_y]), distance_upper_bound=reach, workers=-1
    )
    found = v_c < n_v
    v = np.where(found, v_c, 0)
    if n_v == 1:
        ux, uy = np.ones(v.size), np.zeros(v.size)
        s0, t0 = np.zeros(v.size), np.zeros(v.size)
    else:
        vx, vy = line.rel_x, line.rel_y
        ahead = (centre[:, 0] - vx[v]) * line.tangent_x[v]
        ahead += (centre[:, 1] - vy[v]) * line.tangent_y[v]
        k = np.clip(np.where(ahead >= 0.0, v, v - 1), 0, n_v - 2)
        ux, uy = line.seg_ux[k], line.seg_uy[k]
        s0 = line.s[k] - vx[k] * ux - vy[k] * uy
        t0 = uy * vx[k] - ux * vy[k]
    s = s0[cell] + ux[cell] * rx + uy[cell] * ry
    t = t0[cell] + ux[cell] * ry - uy[cell] * rx
    # a point lies within half a diagonal of its cell's centre
    all_near = found & (d_c + half_diagonal <= limit_m)
    unsure_c = found & ~all_near & (d_c - half_diagonal <= limit_m)
    near = all_near[cell]
    if unsure_c.any():
        unsure = np.flatnonzero(unsure_c[cell])
        pts = np.column_stack([x[unsure], y[unsure]])
        d_exact, _ = line.tree.query(pts, distance_upper_bound=limit_m, workers=-1)
        near[unsure] = np.isfinite(d_exact)
    return s, t, near, rx, ry


@dataclass(frozen=True)
class Reduction:
    """How one kind of points (road edges or lane samples) was reduced.

    Attributes
    ----------
    points : points read and kept (within the distance limit of the trajectory).
    rows : rows in the run after the reduction (``points`` if not reduced).
    cells : occupied cells.
    line_density_per_m : measured density of one line (edge, marking), points per metre
        (the largest over the groups).
    points_per_row : ``q``, points a row stands for (1.0 if not reduced).
    reduced : whether the rows are cell means (else the raw points, unchanged).
    spread_m2 : ``(rows,)`` lateral variance of the points in each row's cell (m^2;
        zeros for raw points).
    """

    points: int
    rows: int
    cells: int
    line_density_per_m: float
    points_per_row: float
    reduced: bool
    spread_m2: FloatArray

    def describe(self) -> str:
        """One line for logs: ``1,000,000 points -> 40,123 rows (q 25, 180 /m per line)``."""
        if not self.reduced:
            return (
                f"{self.points:,} points (not reduced, {self.line_density_per_m:.0f} /m per line)"
            )
        return (
            f"{self.points:,} points -> {self.rows:,} rows in {self.cells:,} cells "
            f"({self.points_per_row:.3g} points per row, {self.line_density_per_m:.0f} /m "
            "per line)"
        )


@dataclass(frozen=True)
class ReducedPoints:
    """Rows of one kind of points after :meth:`CellAccumulator.finish`.

    Attributes
    ----------
    xyz : (M, 3) points (raw) or cell means, mapping frame, metres.
    group : (M,) int64 group of each row (as passed to :meth:`CellAccumulator.add`).
    payload : (M,) int64 per-point payload of raw points (e.g. the lane sample's frame);
        for cell means the payload of the trajectory vertex nearest in station
        (see :meth:`CellAccumulator.finish`).
    info : the :class:`Reduction` summary (counts, density, spread).
    """

    xyz: FloatArray
    group: IntArray
    payload: IntArray
    info: Reduction


class CellAccumulator:
    """Per-cell sufficient statistics of a stream of points (see the module docstring).

    Parameters
    ----------
    line
        The trajectory line (:func:`trajectory_line`).
    n_groups
        Number of point groups (groups are ``0 .. n_groups - 1``).
    station_bin_m, lateral_bin_m
        Cell size along and across the trajectory, metres.
    max_lateral_m
        Points farther than this from the trajectory are dropped by :meth:`add`, metres.
    keep_raw_points
        Raw points are kept (to be returned unchanged if the run is not dense) until more
        than this many were added; then only the cells are kept.
    """

    def __init__(
        self,
        line: TrajectoryLine,
        *,
        n_groups: int,
        station_bin_m: float,
        lateral_bin_m: float,
        max_lateral_m: float,
        keep_raw_points: float,
    ) -> None:
        self.line = line
        self.n_groups = int(n_groups)
        self.ds = float(station_bin_m)
        self.dt = float(lateral_bin_m)
        self.limit = float(max_lateral_m)
        # cell borders on multiples of the cell size (the same cells whatever the limit)
        self.s0 = -(math.ceil(self.limit / self.ds) + 1) * self.ds
        self.t0 = -math.ceil(self.limit / self.dt) * self.dt
        self.n_s = math.ceil((line.length - 2.0 * self.s0) / self.ds) + 1
        self.n_t = math.ceil(-2.0 * self.t0 / self.dt) + 1
        self.ref = line.xy[0]
        self.keep_raw_points = float(keep_raw_points)
        self.points = 0
        self._parts: list[tuple[IntArray, FloatArray]] = []
        self._pending = 0
        self._merged = 0
        self._raw: list[tuple[FloatArray, IntArray, IntArray]] | None = []

    def add(
        self, xyz: FloatArray, group: IntArray, payload: IntArray | None = None
    ) -> NDArray[np.bool_]:
        """Count a chunk of points ``(N, 3)`` (mapping frame, metres) of groups ``(N,)``.

        Returns the mask of the points kept (within ``max_lateral_m`` of the trajectory).
        """
        xyz = np.asarray(xyz, dtype=float)
        x, y, z = (np.ascontiguousarray(xyz[:, k]) for k in range(3))
        group = np.asarray(group, dtype=np.int64)
        s, t, near, rx, ry = _project(self.line, x, y, self.limit)
        all_near = bool(near.all())
        if not all_near:
            rx, ry, z, group, s, t = rx[near], ry[near], z[near], group[near], s[near], t[near]
        n = rx.size
        self.points += n
        if self._raw is not None:
            if self.points <= self.keep_raw_points:
                kept = xyz if all_near else xyz[near]
                pay = np.zeros(n, np.int64) if payload is None else np.asarray(payload, np.int64)
                if payload is not None and not all_near:
                    pay = pay[near]
                self._raw.append((kept.copy(), group.copy(), pay.copy()))
            else:
                self._raw = None
        if n == 0:
            return near
        # kept points lie within the limit of the line, so s - s0 > 0 and t + limit >= 0:
        # truncation is the floor (the clip only guards rounding at the far borders)
        i_s = ((s - self.s0) * (1.0 / self.ds)).astype(np.int64)
        np.clip(i_s, 0, self.n_s - 1, out=i_s)
        t_lo = self.t0
        i_t = ((t - t_lo) * (1.0 / self.dt)).astype(np.int64)
        np.clip(i_t, 0, self.n_t - 1, out=i_t)
        u = t - (t_lo + i_t * self.dt)  # offset inside the cell, [0, dt)
        codes, uniq = _cell_codes(group, i_s, i_t, n_s=self.n_s, n_t=self.n_t)
        sums = np.column_stack(
            [np.bincount(codes, w, minlength=uniq.size) for w in (None, rx, ry, z, u, u * u)]
        )
        self._parts.append((uniq, sums.astype(np.float64, copy=False)))
        self._pending += uniq.size
        # merge when the pending partial tables outgrow the merged one (amortised linear)
        if self._pending > max(2 * self._merged, 2_000_000):
            self._merge()
        return near

    def _merge(self) -> None:
        import pandas as pd

        if len(self._parts) > 1:
            keys = np.concatenate([k for k, _ in self._parts])
            sums = np.vstack([v for _, v in self._parts])
            codes, uniq = pd.factorize(keys)
            merged = np.column_stack(
                [np.bincount(codes, sums[:, j], minlength=uniq.size) for j in range(_STATS)]
            )
            self._parts = [(np.asarray(uniq, dtype=np.int64), merged)]
        self._merged = self._parts[0][0].size if self._parts else 0
        self._pending = 0

    def _cells(self) -> tuple[IntArray, FloatArray]:
        self._merge()
        if not self._parts:
            return np.zeros(0, np.int64), np.zeros((0, _STATS))
        keys, sums = self._parts[0]
        order = np.argsort(keys, kind="stable")
        return keys[order], sums[order]

    def finish(
        self,
        *,
        target_per_m: float,
        reduce_factor: float,
        payload_of_vertex: IntArray | None = None,
    ) -> ReducedPoints:
        """Rows: the raw points if the lines are not denser than ``reduce_factor`` times
        ``target_per_m`` (points per metre of one line), else copies of the cell means
        (module docstring).

        Parameters
        ----------
        payload_of_vertex
            ``(V,)`` payload of each trajectory-line vertex; a cell mean gets the payload of
            the vertex nearest to its station (e.g. the frame of the nearest pose).
        """
        keys, sums = self._cells()
        n_cells = keys.size
        grp, i_s = np.divmod(keys // self.n_t, self.n_s)
        count = sums[:, 0]
        density, local = _line_density(
            keys,
            count,
            n_t=self.n_t,
            n_s=self.n_s,
            n_groups=self.n_groups,
            ds=self.ds,
            w=max(1, round(_LINE_WINDOW_M / self.dt)),
            block=max(1, round(_DENSITY_BLOCK_M / self.ds)),
            first_bin=round(self.s0 / self.ds),
        )
        peak = float(np.nanmax(density)) if np.isfinite(density).any() else 0.0
        reduce = peak > reduce_factor * target_per_m or self._raw is None
        if not reduce:
            assert self._raw is not None
            if self._raw:
                xyz = np.vstack([r[0] for r in self._raw])
                group = np.concatenate([r[1] for r in self._raw])
                payload = np.concatenate([r[2] for r in self._raw])
            else:
                xyz, group, payload = np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)
            info = Reduction(
                self.points, int(xyz.shape[0]), n_cells, peak, 1.0, False, np.zeros(xyz.shape[0])
            )
            return ReducedPoints(xyz, group, payload, info)
        self._raw = None
        # a line crosses a station bin as a run of adjacent occupied cells: its points are
        # summed into one row value (cells merely sample the line's spread)
        starts, run = _line_runs(keys, count, n_t=self.n_t)
        i_t = keys % self.n_t
        # lateral sums relative to the run's first cell (precision), then per run
        shift = (i_t - i_t[starts][run]) * self.dt
        su = sums[:, 4] + count * shift
        suu = sums[:, 5] + 2.0 * shift * sums[:, 4] + count * shift * shift
        run_sums = np.add.reduceat(np.column_stack([sums[:, :4], su, suu]), starts, axis=0)
        n_runs = starts.size
        r_count = run_sums[:, 0]
        r_grp, r_is = grp[starts], i_s[starts]
        # copies per run: count / q of its group and stretch, fractions carried in station
        # order; q follows the local density (a mapper that slows down, a far line), so
        # every stretch gets the target density, never more rows than points
        q = np.maximum(local(r_grp, r_is) / target_per_m, 1.0)
        share = r_count / q
        copies = np.zeros(n_runs, np.int64)
        for g in range(self.n_groups):
            sel = np.flatnonzero(r_grp == g)
            if sel.size:
                carried = np.floor(np.cumsum(share[sel]) + 0.5).astype(np.int64)
                copies[sel] = np.diff(carried, prepend=0)
        mean = run_sums[:, 1:4] / r_count[:, None]
        mean[:, :2] += self.ref
        mu = run_sums[:, 4] / r_count
        spread = np.maximum(run_sums[:, 5] / r_count - mu * mu, 0.0)
        rows = np.repeat(np.arange(n_runs), copies)
        station = self.s0 + (r_is + 0.5) * self.ds
        payload = np.zeros(rows.size, np.int64)
        if payload_of_vertex is not None and rows.size:
            k = np.clip(np.searchsorted(self.line.s, station[rows]), 1, self.line.s.size - 1)
            if self.line.s.size == 1:
                k = np.zeros(rows.size, np.int64)
            else:
                prev_closer = station[rows] - self.line.s[k - 1] <= self.line.s[k] - station[rows]
                k = np.where(prev_closer, k - 1, k)
            payload = np.asarray(payload_of_vertex, dtype=np.int64)[k]
        q_all = float(np.sum(count) / max(rows.size, 1))
        info = Reduction(
            self.points, int(rows.size), n_cells, peak, q_all, True, spread[rows].copy()
        )
        return ReducedPoints(mean[rows], r_grp[rows], payload, info)


def _line_runs(keys: IntArray, count: FloatArray, *, n_t: int) -> tuple[IntArray, IntArray]:
    """Split sorted cells into lines: runs of adjacent occupied cells of one station bin,
    cut where the count has a valley (a cell below ``_VALLEY`` of the largest count on
    either side of it: two lines side by side) and between a run's core and its tails
    (cells below ``_TAIL`` of the run's largest count, e.g. a stray point touching a line).

    Both cuts compare counts within a run, so they do not depend on the density. Returns
    the first cell of every run and the run of every cell.
    """
    n = keys.size
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    per_t = keys // n_t
    i_t = keys - per_t * n_t
    new = np.concatenate([[True], (per_t[1:] != per_t[:-1]) | (np.diff(i_t) != 1)])
    run = np.cumsum(new) - 1
    first = np.flatnonzero(new)
    # running maxima from either end of each run (runs stacked by an offset per run)
    top = float(count.max()) + 1.0
    stacked = count + run * top
    left = np.maximum.accumulate(stacked) - run * top
    right = _reverse_running_max(count, run, top)
    left_before = np.concatenate([[0.0], left[:-1]])
    right_after = np.concatenate([right[1:], [0.0]])
    left_before[first] = 0.0
    last = np.concatenate([first[1:] - 1, [n - 1]])
    right_after[last] = 0.0
    valley = count < _VALLEY * np.minimum(left_before, right_after)
    peak = np.maximum.reduceat(count, first)[run]
    weak = count < _TAIL * peak
    cut = new | valley | np.concatenate([[False], valley[:-1]])
    cut |= np.concatenate([[False], weak[1:] != weak[:-1]])
    starts = np.flatnonzero(cut)
    return starts, np.cumsum(cut) - 1


def _reverse_running_max(count: FloatArray, run: IntArray, top: float) -> FloatArray:
    """Running maximum of ``count`` from the end of each run (``run``: sorted run ids)."""
    rev = count[::-1] + (run.max() - run[::-1]) * top
    acc = np.maximum.accumulate(rev)
    return (acc - (run.max() - run[::-1]) * top)[::-1]


def _line_density(
    keys: IntArray,
    count: FloatArray,
    *,
    n_t: int,
    n_s: int,
    n_groups: int,
    ds: float,
    w: int,
    block: int,
    first_bin: int = 0,
) -> tuple[FloatArray, Callable[[IntArray, IntArray], FloatArray]]:
    """Points per metre of one line: per group (NaN for an empty group), and a function
    ``(group, station bin) -> density`` of the stretch around an occupied bin.

    The count of a line in a station bin is the count in the densest window of ``w``
    lateral cells; a density is the median of those counts over occupied bins: of the
    group, and of stretches of ``block`` bins on two grids offset by half a stretch. A bin
    takes the stretch (of the two that hold it) whose median is nearer its own count (on
    a log scale), so that where the density changes (a mapper that slows down) each side
    keeps its own, and a bin of stray points inside a dense stretch still takes the
    stretch's. ``keys`` are sorted cell keys ``(group * n_s + station bin) * n_t + lateral
    bin``.
    """
    out = np.full(n_groups, np.nan)
    if keys.size == 0:
        return out, lambda g, i: np.ones(np.shape(g))
    per_t = keys // n_t
    csum = np.concatenate([[0.0], np.cumsum(count)])
    # the window [i_t, i_t + w) stays inside its (group, station bin)
    end = np.searchsorted(keys, np.minimum(keys + w, (per_t + 1) * n_t), side="left")
    window = csum[end] - csum[np.arange(keys.size)]
    first = np.flatnonzero(np.concatenate([[True], per_t[1:] != per_t[:-1]]))
    peak = np.maximum.reduceat(window, first)
    bins = per_t[first]  # occupied (group, station bin) keys, sorted
    group, i_s = np.divmod(bins, n_s)
    for g in range(n_groups):
        sel = group == g
        if sel.any():
            out[g] = float(np.median(peak[sel])) / ds
    fallback = np.nan_to_num(out, nan=1.0)[group]
    log_peak = np.log(np.maximum(peak / ds, 1e-9))
    best = fallback
    best_gap = np.full(bins.size, np.inf)
    # stretches start at multiples of ``block`` bins from station 0 (``first_bin``: the
    # absolute index of bin 0), whatever the accumulator's margins
    at = i_s + first_bin
    for shift in (0, block // 2):
        part = (at + shift) // block
        stretch = group * (n_s // block + 3) + (part - part.min())
        order = np.lexsort((peak, stretch))
        st, pk = stretch[order], peak[order]
        starts = np.flatnonzero(np.concatenate([[True], st[1:] != st[:-1]]))
        sizes = np.diff(np.concatenate([starts, [st.size]]))
        med = 0.5 * (pk[starts + (sizes - 1) // 2] + pk[starts + sizes // 2]) / ds
        med = np.where(sizes >= 3, med, np.nan)  # too few bins: the group's density
        of_bin = np.empty(bins.size)
        of_bin[order] = np.repeat(med, sizes)
        of_bin = np.where(np.isfinite(of_bin), of_bin, fallback)
        gap = np.abs(np.log(of_bin) - log_peak)
        take = gap < best_gap
        best = np.where(take, of_bin, best)
        best_gap = np.where(take, gap, best_gap)

    def local(g: IntArray, i: IntArray) -> FloatArray:
        at = np.searchsorted(bins, np.asarray(g) * n_s + np.asarray(i))
        return best[np.minimum(at, bins.size - 1)]

    return out, local
