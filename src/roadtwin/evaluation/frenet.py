"""Frenet geometry of a road network for the metrics: road roles, boundaries, projection.

Boundary kinds follow the shared lane layout: road edges are the centre-lane border (the
reference line plus lane offset) and the outer border of the outermost lane; lane
boundaries are the outer borders of every other lane. Lateral offsets t are metres, left
positive, in the Frenet frame of the road; positions are mapping-frame metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..model import SAME_LEVEL_M, Lane, LaneSection, Road, RoadNetwork

FloatArray = NDArray[np.float64]

EDGE = "road_edge"
LANE = "lane_boundary"
RAMP_ROLES = ("exit", "entry")

# status codes of a projection
_OK, _BEYOND_ENDS, _NO_ROAD = 0, 1, 2


# ---------------------------------------------------------------------------
# roles of roads and boundaries
# ---------------------------------------------------------------------------


def _linked_road_ids(road: Road) -> list[str]:
    return [
        link.element_id
        for link in (road.predecessor, road.successor)
        if link is not None and link.element_type == "road"
    ]


def mainline_roads(network: RoadNetwork) -> list[Road]:
    """Mainline roads in driving order: roads named ``mainline`` plus connecting roads of
    junctions that join two mainline roads (the through lanes of a junction).

    The order follows successor links from the first road without a mainline predecessor;
    roads not reached that way are appended in id order.
    """
    named = {r.id: r for r in network.roads if r.name == "mainline"}
    through = {
        r.id: r
        for r in network.roads
        if r.junction != "-1"
        and len(_linked_road_ids(r)) == 2
        and all(i in named for i in _linked_road_ids(r))
    }
    members = {**named, **through}
    # successor relation between members (road links and junction connections)
    nxt: dict[str, str] = {}
    for road in members.values():
        link = road.successor
        if link is None:
            continue
        if link.element_type == "road" and link.element_id in members:
            nxt[road.id] = link.element_id
        elif link.element_type == "junction" and link.element_id in network.id_to_junction:
            for conn in network.id_to_junction[link.element_id].connections:
                if conn.incoming_road == road.id and conn.connecting_road in members:
                    nxt[road.id] = conn.connecting_road
                    break
    has_pred = set(nxt.values())
    order: list[str] = []
    for start in sorted(members, key=_id_key):
        if start in has_pred or start in order:
            continue
        cur: str | None = start
        while cur is not None and cur not in order:
            order.append(cur)
            cur = nxt.get(cur)
    order += [i for i in sorted(members, key=_id_key) if i not in order]
    return [members[i] for i in order]


def ramp_roads(network: RoadNetwork, *, with_connectors: bool = True) -> list[Road]:
    """Ramp roads (named ``exit``/``entry``), optionally with the junction connecting roads
    that join a ramp road to anything."""
    named = [r for r in network.roads if r.name in RAMP_ROLES]
    if not with_connectors:
        return named
    ids = {r.id for r in named}
    conns = [
        r
        for r in network.roads
        if r.junction != "-1" and r.id not in ids and any(i in ids for i in _linked_road_ids(r))
    ]
    return named + conns


def _id_key(road_id: str) -> tuple[int, float, str]:
    try:
        return (0, float(road_id), road_id)
    except ValueError:
        return (1, 0.0, road_id)


def section_boundaries(section: LaneSection) -> list[tuple[str, int]]:
    """``(kind, lane_id)`` of every lateral boundary of a lane section.

    ``lane_id`` names the lane whose *outer* border the boundary is (0: the centre lane,
    i.e. reference line plus lane offset). Kind is ``"road_edge"`` for the centre border of
    a one-sided section and the outer border of each side's outermost lane, else
    ``"lane_boundary"``.
    """
    sides = [side for side in (section.right, section.left) if side]
    out: list[tuple[str, int]] = [(EDGE if len(sides) <= 1 else LANE, 0)]
    for side in sides:
        for i, lane in enumerate(side):
            out.append((EDGE if i == len(side) - 1 else LANE, lane.id))
    return out


def unseen_boundary(
    section: LaneSection, lane_id: int, ds: FloatArray | None = None
) -> NDArray[np.bool_]:
    """Where the outer border of lane ``lane_id`` is a border no sensor can see: it
    divides two lanes of which neither is a driving lane (two shoulder or border strips of
    one paved area, e.g. CARLA's inner shoulder split 0.64 + 0.5 m) and the marking in
    effect there is ``none``. Such a border marks nothing on the road; the truth's lane
    boundaries leave it out (:func:`roadtwin.evaluation.metrics`), as a built map cannot
    place it but by chance. Town06 paints the split over parts of a section only: the
    painted stretches are measured, the rest is not.

    Parameters
    ----------
    section, lane_id
        The lane section and the lane whose outer border is asked about.
    ds
        Section-relative stations (metres); ``None``: the section's start only.

    Returns
    -------
    Boolean per station of ``ds`` (one element for ``None``).
    """
    ds = np.zeros(1) if ds is None else np.asarray(ds, dtype=float)
    unseen = np.zeros(ds.shape, dtype=bool)
    lane = split_border(section, lane_id)
    if lane is None:
        return unseen
    marks = sorted(lane.road_marks, key=lambda mark: mark.s_offset)
    if not marks:
        return ~unseen
    starts = np.array([mark.s_offset for mark in marks])
    painted = np.array([mark.type != "none" for mark in marks])
    # before the first mark's offset nothing is painted either (OpenDRIVE: no mark)
    k = np.searchsorted(starts, ds, side="right") - 1
    return np.where(k >= 0, ~painted[np.clip(k, 0, None)], True)


def split_border(section: LaneSection, lane_id: int) -> Lane | None:
    """Lane ``lane_id`` if its outer border divides two lanes of which neither is a driving
    lane (a split of one paved strip, e.g. CARLA's inner shoulder 0.64 + 0.5 m), else
    ``None`` (a border of a driving lane, the road edge, or no such lane)."""
    for side in (section.right, section.left):
        ids = [lane.id for lane in side]
        if lane_id not in ids:
            continue
        i = ids.index(lane_id)
        if i + 1 >= len(side):
            return None  # the road edge
        lane, outer = side[i], side[i + 1]
        return None if "driving" in (lane.type, outer.type) else lane
    return None


def _section_centre_t(road: Road, s: FloatArray, section: LaneSection) -> FloatArray:
    """Lateral offset of the middle between the two road edges of a section."""
    edges = [lid for kind, lid in section_boundaries(section) if kind == EDGE]
    ts = np.stack([road.lane_border_t(s, lid) for lid in edges])
    return 0.5 * (ts.min(axis=0) + ts.max(axis=0))


def nearest_boundary(
    road: Road, s: FloatArray, t: FloatArray, kind: str | None
) -> tuple[FloatArray, NDArray[np.int64]]:
    """Nearest boundary of ``kind`` (``None``: any kind) to Frenet points of one road.

    Parameters
    ----------
    road
        The road whose Frenet frame ``s, t`` are in.
    s, t
        ``(N,)`` stations and lateral offsets (metres).
    kind
        ``"road_edge"``, ``"lane_boundary"`` or ``None``.

    Returns
    -------
    t_b, lane_id
        Lateral offset of the nearest boundary at ``s`` (NaN where the section has no
        boundary of that kind) and the id of the lane whose outer border it is.
    """
    s = np.asarray(s, dtype=float)
    t = np.asarray(t, dtype=float)
    t_b = np.full(s.shape, np.nan)
    lane_id = np.zeros(s.shape, dtype=np.int64)
    sec_idx = road.section_index(s)
    for k in np.unique(sec_idx):  # loop over sections and boundaries, vectorised over points
        section = road.lane_sections[int(k)]
        ids = [lid for knd, lid in section_boundaries(section) if kind is None or knd == kind]
        if not ids:
            continue
        sel = np.nonzero(sec_idx == k)[0]
        cand = np.stack([road.lane_border_t(s[sel], lid) for lid in ids], axis=1)
        dist = np.abs(cand - t[sel, None])
        dist = np.where(np.isfinite(dist), dist, np.inf)
        best = np.argmin(dist, axis=1)
        t_b[sel] = cand[np.arange(sel.size), best]
        lane_id[sel] = np.asarray(ids)[best]
    return t_b, lane_id


def driving_lane_count(road: Road, s: FloatArray, *, min_width_m: float) -> NDArray[np.int64]:
    """Number of ``driving`` lanes at least ``min_width_m`` wide at stations ``s``."""
    s = np.asarray(s, dtype=float)
    out = np.zeros(s.shape, dtype=np.int64)
    sec_idx = road.section_index(s)
    for k in np.unique(sec_idx):
        section = road.lane_sections[int(k)]
        sel = sec_idx == k
        ds = s[sel] - section.s0
        for lane in (*section.left, *section.right):
            if lane.type == "driving":
                out[sel] += (lane.width.value(ds) >= min_width_m).astype(np.int64)
    return out


# ---------------------------------------------------------------------------
# projection of points onto a set of roads
# ---------------------------------------------------------------------------


def _stations(length_m: float, step_m: float) -> FloatArray:
    """Stations every ``step_m`` at the middle of each step (never exactly on a road end,
    where consecutive roads meet and lane layouts may change)."""
    return np.arange(0.5 * step_m, length_m, step_m)


def boundary_polylines(network: RoadNetwork, *, step_m: float = 2.0) -> tuple[FloatArray, ...]:
    """Every boundary of every road as ``(N, 2)`` mapping-frame polylines (for plots)."""
    lines = []
    for road in network.roads:
        s_all = np.append(np.arange(0.0, road.length, step_m), road.length)
        sec_idx = road.section_index(s_all)
        for k in np.unique(sec_idx):
            s = s_all[sec_idx == k]
            for _, lid in section_boundaries(road.lane_sections[int(k)]):
                lines.append(road.to_xy(s, road.lane_border_t(s, lid)).reshape(-1, 2))
    return tuple(lines)


# ---------------------------------------------------------------------------
# projection of points onto a set of roads
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Projection:
    """Points projected onto a set of roads.

    Attributes
    ----------
    road_index : (N,) int, index into the road list, -1 where excluded.
    s, t : (N,) Frenet station and lateral offset (metres) on that road (NaN if excluded).
    status : (N,) int, 0 projected, 1 beyond the road ends, 2 no road within reach.
    station_m : (N,) station along the chain of roads (cumulative length before the road
        plus s), NaN if excluded.
    """

    road_index: NDArray[np.int64]
    s: FloatArray
    t: FloatArray
    status: NDArray[np.int64]
    station_m: FloatArray

    @property
    def ok(self) -> NDArray[np.bool_]:
        """Mask of points that were projected."""
        return self.status == _OK


def _project_one(road: Road, pts: FloatArray, end_tol: float):
    s, t = road.project(pts)
    x, y, h, _ = road.evaluate(s)
    along = (pts[:, 0] - x) * np.cos(h) + (pts[:, 1] - y) * np.sin(h)
    beyond = ((s <= 1e-9) & (along < -end_tol)) | ((s >= road.length - 1e-9) & (along > end_tol))
    return s, t, beyond


def on_pavement_of(
    roads: Sequence[Road], points: FloatArray, *, margin_m: float
) -> NDArray[np.bool_]:
    """Mask of points that lie on the pavement of one of ``roads``: at least ``margin_m``
    inside its road edges (metres; negative: at most ``-margin_m`` outside them) and, for
    ``(N, 3)`` points, within ``SAME_LEVEL_M`` of its surface (a road passing over or under
    is not the same pavement)."""
    raw = np.asarray(points, dtype=float)
    out = np.zeros(raw.shape[0], dtype=bool)
    if not roads or raw.shape[0] == 0:
        return out
    # a negative margin reaches outside the edges: the projection must too
    proj = project_points(roads, raw, max_lateral_m=max(0.0, -margin_m), end_tolerance_m=0.0)
    for r in np.unique(proj.road_index[proj.ok]):
        sel = np.nonzero(proj.ok & (proj.road_index == r))[0]
        road = roads[int(r)]
        s, t = proj.s[sel], proj.t[sel]
        lo, hi = road_band(road, s)
        inside = (t > lo + margin_m) & (t < hi - margin_m)
        if raw.shape[1] > 2:
            inside &= np.abs(road.surface_height(s, t) - raw[sel, 2]) <= SAME_LEVEL_M
        out[sel] = inside
    return out


def road_band(road: Road, s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Lateral extent ``(t_low, t_high)`` (metres) between the road edges at stations ``s``."""
    s = np.asarray(s, dtype=float)
    lo = np.zeros(s.shape)
    hi = np.zeros(s.shape)
    sec_idx = road.section_index(s)
    for k in np.unique(sec_idx):
        sel = sec_idx == k
        edges = [
            lid for kind, lid in section_boundaries(road.lane_sections[int(k)]) if kind == EDGE
        ]
        ts = np.stack([road.lane_border_t(s[sel], lid) for lid in edges])
        lo[sel] = np.nanmin(ts, axis=0)
        hi[sel] = np.nanmax(ts, axis=0)
    return lo, hi


def _ray_box_exit(origin: FloatArray, direction: FloatArray, lo: FloatArray, hi: FloatArray):
    """Distance along the unit ``direction`` from ``origin`` (inside the box) to where the
    ray leaves the axis-aligned box ``[lo, hi]`` (metres)."""
    exits = []
    for i in range(2):
        if direction[i] > 1e-12:
            exits.append((hi[i] - origin[i]) / direction[i])
        elif direction[i] < -1e-12:
            exits.append((lo[i] - origin[i]) / direction[i])
    return max(0.0, min(exits)) if exits else 0.0


@dataclass(frozen=True)
class _PointGrid:
    """Points bucketed into square cells of ``cell_m`` (mapping frame): ``order`` sorts
    the point indices by cell; cell ``keys[i]`` holds ``order[start[i]:start[i] + count[i]]``."""

    origin: FloatArray
    cell_m: float
    ny: int
    keys: NDArray[np.int64]
    start: NDArray[np.int64]
    count: NDArray[np.int64]
    order: NDArray[np.intp]

    @classmethod
    def build(cls, pts: FloatArray, cell_m: float) -> _PointGrid:
        """Bucket the finite points of ``(N, 2)`` ``pts`` (others are in no cell)."""
        finite = np.nonzero(np.all(np.isfinite(pts), axis=1))[0]
        if finite.size == 0:
            empty = np.zeros(0, dtype=np.int64)
            return cls(np.zeros(2), cell_m, 1, empty, empty, empty, empty.astype(np.intp))
        fpts = pts[finite]
        origin = fpts.min(axis=0)
        cell = np.floor((fpts - origin) / cell_m).astype(np.int64)
        ny = int(cell[:, 1].max()) + 1
        key = cell[:, 0] * ny + cell[:, 1]
        order = np.argsort(key, kind="stable")
        keys, start, count = np.unique(key[order], return_index=True, return_counts=True)
        return cls(origin, cell_m, ny, keys, start, count, finite[order])

    def near(self, centres: FloatArray, radius_m: float) -> NDArray[np.intp]:
        """Sorted indices of the points in every cell that meets a square of half-side
        ``radius_m`` around a centre (a superset of the points within ``radius_m``)."""
        lo = np.floor((centres - radius_m - self.origin) / self.cell_m).astype(np.int64)
        hi = np.floor((centres + radius_m - self.origin) / self.cell_m).astype(np.int64)
        lo = np.maximum(lo, 0)
        hi[:, 1] = np.minimum(hi[:, 1], self.ny - 1)
        span = int(np.max(hi - lo, initial=0)) + 1
        d = np.arange(span)
        cx = lo[:, 0, None, None] + d[None, :, None]
        cy = lo[:, 1, None, None] + d[None, None, :]
        ok = (cx <= hi[:, 0, None, None]) & (cy <= hi[:, 1, None, None])
        cells = np.unique((cx * self.ny + cy)[ok])
        if self.keys.size == 0:
            return np.zeros(0, dtype=np.intp)
        pos = np.minimum(np.searchsorted(self.keys, cells), self.keys.size - 1)
        pos = pos[self.keys[pos] == cells]  # cells that hold points
        start, count = self.start[pos], self.count[pos]
        total = int(count.sum())
        if total == 0:
            return np.zeros(0, dtype=np.intp)
        rel = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
        return np.sort(self.order[np.repeat(start, count) + rel])


def _candidate_points(
    grid: _PointGrid,
    road: Road,
    box_lo: FloatArray,
    box_hi: FloatArray,
    reach_m: float,
) -> NDArray[np.intp]:
    """Sorted indices of the bucketed points that lie within ``reach_m`` of the road's
    reference line or of its straight extensions beyond both ends (inside the box), plus
    some more near them (a superset: callers still apply their own tests).

    The reference line is sampled every ``step = reach_m``; a point within ``reach_m`` of
    the line is within ``reach_m + step / 2`` of a sample. The extensions run along the
    end headings until they leave the box grown by ``reach_m`` (a point in the box within
    ``reach_m`` of an extension has its foot there).
    """
    step = max(reach_m, 1.0)
    n = max(2, math.ceil(road.length / step) + 1)
    x, y, h, _ = road.evaluate(np.linspace(0.0, road.length, n))
    centres = [np.column_stack([x, y])]
    for j, sign in ((0, -1.0), (-1, 1.0)):  # start runs backwards, end forwards
        origin = np.array([x[j], y[j]])
        direction = sign * np.array([math.cos(h[j]), math.sin(h[j])])
        u_max = _ray_box_exit(origin, direction, box_lo - reach_m, box_hi + reach_m)
        u = np.arange(step, u_max + step, step)
        centres.append(origin + u[:, None] * direction)
    return grid.near(np.vstack(centres), reach_m + 0.5 * step)


def project_points(
    roads: Sequence[Road],
    points: FloatArray,
    *,
    max_lateral_m: float = 40.0,
    end_tolerance_m: float = 0.1,
    preselect: bool = True,
) -> Projection:
    """Project mapping-frame points onto the best of several (possibly overlapping) roads.

    Every point is projected onto every road whose bounding box (grown by
    ``max_lateral_m`` plus the road's widest edge offset) holds it and that it can be
    within reach of; the loop runs over roads, vectorised over points. Among
    the roads a point projects inside (not beyond an end by more than ``end_tolerance_m``)
    the best is, in order: the smallest distance outside the road's edges (0 inside); a
    road the point is not within 1 m of an end of; the smallest distance from the middle
    between the edges; the largest distance from the road ends (ties: 5 cm). Points beyond
    every road's ends or farther than ``max_lateral_m`` outside every road are excluded
    (status 1 where the point lies beyond a road's end, within ``max_lateral_m`` of its
    edges and inside its grown bounding box, else 2).

    Parameters
    ----------
    roads
        Roads in chain order (for ``station_m``).
    points
        ``(N, 2)`` mapping-frame points, metres, or ``(N, 3)`` with their heights: then a
        road whose surface there lies within ``SAME_LEVEL_M`` of the point's height
        comes before every other (a run passing over itself, a ramp on a bridge).
    max_lateral_m
        Largest distance outside a road's edges that still counts as on the road (metres).
    end_tolerance_m
        How far beyond a road end a point may lie and still project onto it (metres).
    preselect
        ``True`` (default): per road, only the points in grid cells (points bucketed
        once) near the sampled reference line and its extensions beyond the ends are
        projected, so
        the cost grows linearly with the number of roads and points. ``False``: every
        point in a road's grown bounding box is projected (the reference implementation;
        cost roads x points). Both give the same result.
    """
    raw = np.asarray(points, dtype=float)
    pts = raw[:, :2]
    z_pts = raw[:, 2] if raw.ndim == 2 and raw.shape[1] > 2 else None
    n = pts.shape[0]
    road_index = np.full(n, -1, dtype=np.int64)
    s_out = np.full(n, np.nan)
    t_out = np.full(n, np.nan)
    status = np.full(n, _NO_ROAD, dtype=np.int64)
    if n == 0 or not roads:
        return Projection(road_index, s_out, t_out, status, np.full(n, np.nan))
    offsets = np.concatenate([[0.0], np.cumsum([r.length for r in roads])])
    best_out = np.full(n, np.inf)
    best_near = np.ones(n, dtype=bool)
    best_centre = np.full(n, np.inf)
    best_margin = np.full(n, -np.inf)
    best_level = np.zeros(n, dtype=bool)
    tried_beyond = np.zeros(n, dtype=bool)
    tol = 0.05
    # buckets of about the reach of a road (max_lateral_m plus its edge offsets)
    buckets = _PointGrid.build(pts, max(max_lateral_m, 5.0) + 20.0) if preselect else None

    for ri, road in enumerate(roads):  # loop over roads, vectorised over points
        grid = np.linspace(0.0, road.length, max(2, math.ceil(road.length / 2.0) + 1))
        xy = road.xy(grid)
        lo_grid, hi_grid = road_band(road, grid)
        grow = max_lateral_m + float(np.nanmax(np.abs(np.concatenate([lo_grid, hi_grid]))))
        box_lo = xy.min(axis=0) - grow
        box_hi = xy.max(axis=0) + grow
        if buckets is None:
            idx = np.nonzero(np.all((pts >= box_lo) & (pts <= box_hi), axis=1))[0]
        else:
            # points that can end up within reach: |t| <= grow (plus 2 m for the band
            # between grid stations and the Newton steps), inside the box
            idx = _candidate_points(buckets, road, box_lo, box_hi, grow + 2.0)
            idx = idx[np.all((pts[idx] >= box_lo) & (pts[idx] <= box_hi), axis=1)]
        if idx.size == 0:
            continue
        s, t, beyond = _project_one(
            road, raw[idx, :3] if z_pts is not None else pts[idx], end_tolerance_m
        )
        lo, hi = road_band(road, s)
        out_d = np.maximum(np.maximum(lo - t, t - hi), 0.0)
        centre = np.abs(t - 0.5 * (lo + hi))
        margin = np.minimum(s, road.length - s)
        near = margin < 1.0
        reach = out_d <= max_lateral_m
        tried_beyond[idx[beyond & reach]] = True
        inside = ~beyond & reach
        o_out, o_near, o_c, o_m = best_out[idx], best_near[idx], best_centre[idx], best_margin[idx]
        # a road at the point's own level first (a road stacked over or under it is not
        # the point's road however close in plan); without heights every road is level
        if z_pts is None:
            level = np.ones(idx.size, dtype=bool)
        else:
            level = np.abs(road.surface_height(s, t) - z_pts[idx]) <= SAME_LEVEL_M
        o_level = best_level[idx]
        better = level & ~o_level
        same = level == o_level
        better |= same & (out_d < o_out - tol)
        eq = same & (np.abs(out_d - o_out) <= tol)
        better |= eq & (~near & o_near)
        eq &= near == o_near
        better |= eq & (centre < o_c - tol)
        eq &= np.abs(centre - o_c) <= tol
        better |= eq & (margin > o_m)
        better &= inside
        tgt = idx[better]
        road_index[tgt] = ri
        s_out[tgt] = s[better]
        t_out[tgt] = t[better]
        best_out[tgt] = out_d[better]
        best_near[tgt] = near[better]
        best_centre[tgt] = centre[better]
        best_margin[tgt] = margin[better]
        best_level[tgt] = level[better]
    status[road_index >= 0] = _OK
    status[(road_index < 0) & tried_beyond] = _BEYOND_ENDS
    station = np.full(n, np.nan)
    okm = road_index >= 0
    station[okm] = offsets[road_index[okm]] + s_out[okm]
    return Projection(road_index, s_out, t_out, status, station)


# ---------------------------------------------------------------------------
# per-point errors
# ---------------------------------------------------------------------------
