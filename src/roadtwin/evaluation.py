"""Accuracy of a built map (DESIGN.md section 5).

Three families of metrics, all lateral distances in metres measured in the Frenet frame
(s along, t left positive) of the road a point projects onto:

* **Self-consistency** (the seed paper's Table 4): every road-edge point and lane sample of
  the run against the nearest road-edge / lane boundary of the mainline road it projects onto,
  ``e_i = |t_m,i - t_b(s_m,i)|``; RMSE for road edge, lane boundary and both pooled (overall).
* **Against truth** (simulated runs): every ``truth_step_m`` along each true boundary of the
  true mainline, the lateral distance to the nearest reconstructed boundary of the same kind;
  elevation; ramps separately; driving-lane count per station.
* **Topology against truth**: ramps matched / missed / spurious by the proximity of their
  attachment (gore) points, merge/exit type, and lane-level reachability through lane links.

Boundary kinds follow the shared lane layout: road edges are the centre-lane border (the
reference line plus lane offset) and the outer border of the outermost lane; lane
boundaries are the outer borders of every other lane. Functions here are pure; plots and
files live in :mod:`roadtwin.report`.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from .config import EvaluationConfig
from .model import LaneSection, Road, RoadNetwork

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

EDGE = "road_edge"
LANE = "lane_boundary"
RAMP_ROLES = ("exit", "entry")

# status codes of a projection
_OK, _BEYOND_ENDS, _NO_ROAD = 0, 1, 2


# ---------------------------------------------------------------------------
# small numeric helpers
# ---------------------------------------------------------------------------


def error_stats(errors: Sequence[float] | FloatArray) -> dict[str, float | int | None]:
    """Summary of absolute errors (metres): ``n``, ``rmse_m``, ``mean_abs_m``, ``p95_m``,
    ``max_m``. Empty input gives ``n = 0`` and ``None`` for the rest (JSON ``null``)."""
    e = np.abs(np.asarray(errors, dtype=float))
    e = e[np.isfinite(e)]
    if e.size == 0:
        return {"n": 0, "rmse_m": None, "mean_abs_m": None, "p95_m": None, "max_m": None}
    return {
        "n": int(e.size),
        "rmse_m": float(np.sqrt(np.mean(e * e))),
        "mean_abs_m": float(np.mean(e)),
        "p95_m": float(np.percentile(e, 95.0)),
        "max_m": float(np.max(e)),
    }


def _rmse(errors: FloatArray) -> float:
    e = errors[np.isfinite(errors)]
    return float(np.sqrt(np.mean(e * e))) if e.size else math.nan


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


def _height(road: Road, s: FloatArray, t: FloatArray) -> FloatArray:
    """Surface height z (metres) at Frenet ``(s, t)``: elevation plus superelevation."""
    z = road.elevation.value(s)
    if road.superelevation is not None:
        z = z + t * np.tan(road.superelevation.value(s))
    return z


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


def project_points(
    roads: Sequence[Road],
    points: FloatArray,
    *,
    max_lateral_m: float = 40.0,
    end_tolerance_m: float = 0.1,
) -> Projection:
    """Project mapping-frame points onto the best of several (possibly overlapping) roads.

    Every point is projected onto every road whose bounding box (grown by
    ``max_lateral_m``) holds it; the loop runs over roads, vectorised over points. Among
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
        ``(N, 2+)`` mapping-frame points, metres.
    """
    pts = np.asarray(points, dtype=float)[:, :2]
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
    tried_beyond = np.zeros(n, dtype=bool)
    tol = 0.05

    for ri, road in enumerate(roads):  # loop over roads, vectorised over points
        grid = np.linspace(0.0, road.length, max(2, math.ceil(road.length / 2.0) + 1))
        xy = road.xy(grid)
        lo_grid, hi_grid = road_band(road, grid)
        grow = max_lateral_m + float(np.nanmax(np.abs(np.concatenate([lo_grid, hi_grid]))))
        box_lo = xy.min(axis=0) - grow
        box_hi = xy.max(axis=0) + grow
        idx = np.nonzero(np.all((pts >= box_lo) & (pts <= box_hi), axis=1))[0]
        if idx.size == 0:
            continue
        s, t, beyond = _project_one(road, pts[idx], end_tolerance_m)
        lo, hi = road_band(road, s)
        out_d = np.maximum(np.maximum(lo - t, t - hi), 0.0)
        centre = np.abs(t - 0.5 * (lo + hi))
        margin = np.minimum(s, road.length - s)
        near = margin < 1.0
        reach = out_d <= max_lateral_m
        tried_beyond[idx[beyond & reach]] = True
        inside = ~beyond & reach
        o_out, o_near, o_c, o_m = best_out[idx], best_near[idx], best_centre[idx], best_margin[idx]
        better = out_d < o_out - tol
        eq = np.abs(out_d - o_out) <= tol
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
    status[road_index >= 0] = _OK
    status[(road_index < 0) & tried_beyond] = _BEYOND_ENDS
    station = np.full(n, np.nan)
    okm = road_index >= 0
    station[okm] = offsets[road_index[okm]] + s_out[okm]
    return Projection(road_index, s_out, t_out, status, station)


# ---------------------------------------------------------------------------
# per-point errors
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class PointErrors:
    """Per-point lateral errors of one metric, for plots (not written to JSON).

    Attributes
    ----------
    name : metric name, e.g. ``"self/road_edge"`` or ``"truth/lane_boundary"``.
    xy : (N, 2) mapping-frame positions of the points, metres.
    station_m : (N,) station along the mainline chain (metres).
    error_m : (N,) signed error (measured/true minus reconstructed), metres.
    boundary : (N,) lane id whose outer border the matched boundary is.
    """

    name: str
    xy: FloatArray
    station_m: FloatArray
    error_m: FloatArray
    boundary: NDArray[np.int64]

    @property
    def rmse_m(self) -> float:
        """RMSE of ``error_m`` (metres; NaN if empty)."""
        return _rmse(self.error_m)


def _empty_errors(name: str) -> PointErrors:
    return PointErrors(
        name, np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64)
    )


def _errors_full(
    roads: Sequence[Road], proj: Projection, kind: str | None
) -> tuple[FloatArray, NDArray[np.int64]]:
    """Signed ``t - t_b`` (NaN where not projected) and the matched lane id, per point."""
    n = proj.s.size
    err = np.full(n, np.nan)
    lane = np.zeros(n, dtype=np.int64)
    keep = np.nonzero(proj.ok)[0]
    ri = proj.road_index[keep]
    for r in np.unique(ri):  # grouped by road
        idx = keep[ri == r]
        t_b, lid = nearest_boundary(roads[int(r)], proj.s[idx], proj.t[idx], kind)
        err[idx] = proj.t[idx] - t_b
        lane[idx] = lid
    return err, lane


def _lateral_errors(
    roads: Sequence[Road], pts: FloatArray, proj: Projection, kind: str | None, name: str
) -> PointErrors:
    """Signed ``t - t_b`` of projected points against the nearest boundary of ``kind``."""
    err, lane = _errors_full(roads, proj, kind)
    good = np.isfinite(err)
    return PointErrors(name, pts[good, :2], proj.station_m[good], err[good], lane[good])


def self_consistency_errors(
    network: RoadNetwork, run: Any, *, config: EvaluationConfig | None = None
) -> tuple[PointErrors, PointErrors, dict[str, int]]:
    """Per-point self-consistency errors of a run's measurements against a map.

    Each point is projected onto the mainline roads and, with
    ``config.self_consistency_scope == "all"`` (default), also onto the ramp roads (and
    their connecting roads); its error is the one against the nearest boundary of its kind
    among the roads it projects onto. Road-edge points and lane samples the car measured on
    a ramp's gore and first metres belong to the ramp, not to the mainline; with
    ``"mainline"`` they are compared with the mainline only (the literal reading of the
    paper, which inflates the RMSE near every ramp even for a perfect map).

    Parameters
    ----------
    network
        The built map.
    run
        A :class:`~roadtwin.io.MappingRun` (uses ``edges`` and ``lane_samples``, mapping
        frame, metres).

    Returns
    -------
    edge_errors, lane_errors, counts
        Errors of road-edge points against the nearest road edge and of lane samples
        against the nearest lane boundary, and extras: ``excluded_beyond_ends``,
        ``excluded_no_road`` (points on no road), ``ramp_points`` (points whose nearest
        boundary is on a ramp road), ``height_rmse_m`` (RMS of measured z minus the map's
        surface height at the points on mainline roads, metres).
    """
    cfg = config or EvaluationConfig()
    main = mainline_roads(network)
    ramps = ramp_roads(network) if cfg.self_consistency_scope == "all" else []
    counts: dict[str, Any] = {"excluded_beyond_ends": 0, "excluded_no_road": 0, "ramp_points": 0}
    out = []
    dz_all = []
    for pts, kind in ((run.edges, EDGE), (run.lane_samples, LANE)):
        pts = np.asarray(pts, dtype=float).reshape(-1, 3)
        kw = {"max_lateral_m": cfg.max_lateral_m, "end_tolerance_m": cfg.end_tolerance_m}
        proj = project_points(main, pts, **kw)
        err, lane = _errors_full(main, proj, kind)
        status = proj.status
        use_r = np.zeros(err.size, dtype=bool)
        if ramps:
            proj_r = project_points(ramps, pts, **kw)
            err_r, lane_r = _errors_full(ramps, proj_r, kind)
            use_r = np.isfinite(err_r) & ~(np.abs(err) <= np.abs(err_r))
            err = np.where(use_r, err_r, err)
            lane = np.where(use_r, lane_r, lane)
            counts["ramp_points"] += int(use_r.sum())
            status = np.where(proj_r.ok, _OK, np.minimum(status, proj_r.status))
        counts["excluded_beyond_ends"] += int(np.sum(status == _BEYOND_ENDS))
        counts["excluded_no_road"] += int(np.sum(status == _NO_ROAD))
        good = np.isfinite(err)
        out.append(
            PointErrors(f"self/{kind}", pts[good, :2], proj.station_m[good], err[good], lane[good])
        )
        on_main = proj.ok & ~use_r
        for r in np.unique(proj.road_index[on_main]):  # measured height - map surface
            sel = on_main & (proj.road_index == r)
            dz_all.append(pts[sel, 2] - _height(main[int(r)], proj.s[sel], proj.t[sel]))
    counts["height_rmse_m"] = _rmse(np.concatenate(dz_all)) if dz_all else math.nan
    return out[0], out[1], counts


def _self_summary(edge: PointErrors, lane: PointErrors, counts: dict[str, Any]) -> dict:
    both = np.concatenate([edge.error_m, lane.error_m])
    return {
        "road_edge_rmse_m": _rmse(edge.error_m),
        "lane_boundary_rmse_m": _rmse(lane.error_m),
        "overall_rmse_m": _rmse(both),
        "road_edge_points": int(edge.error_m.size),
        "lane_samples": int(lane.error_m.size),
        **counts,
    }


def data_quality(
    network: RoadNetwork, run: Any, *, config: EvaluationConfig | None = None
) -> dict[str, float]:
    """Relative accuracy of a map for the OpenDRIVE header's ``<dataQuality><error>``.

    Returns
    -------
    dict
        ``xy_relative`` (overall self-consistency RMSE) and ``z_relative`` (height RMSE of
        the measured points against the map surface), metres; keys of
        :class:`~roadtwin.model.Header` ``data_quality``. The absolute errors need the
        GNSS accuracy of the run, which a run folder does not state, so they are absent.
    """
    sc = self_consistency(network, run, config=config)
    return {"xy_relative": sc["overall_rmse_m"], "z_relative": sc["height_rmse_m"]}


def self_consistency(
    network: RoadNetwork, run: Any, *, config: EvaluationConfig | None = None
) -> dict[str, float]:
    """The seed paper's self-consistency RMSE of a map against its own run.

    ``e_i = |t_m,i - t_b(s_m,i)|`` in the Frenet frame of the mainline road each point
    projects onto; road-edge points against the nearest road edge, lane samples against
    the nearest lane boundary.

    Returns
    -------
    dict
        ``road_edge_rmse_m``, ``lane_boundary_rmse_m``, ``overall_rmse_m`` (all points
        pooled), metres (NaN where no point was evaluated); ``road_edge_points``,
        ``lane_samples`` (evaluated counts), ``excluded_beyond_ends``, ``excluded_no_road``,
        ``ramp_points`` (see :func:`self_consistency_errors` for which roads count),
        ``height_rmse_m`` (measured z against the map surface, metres).
    """
    edge, lane, counts = self_consistency_errors(network, run, config=config)
    return _self_summary(edge, lane, counts)


# ---------------------------------------------------------------------------
# against truth
# ---------------------------------------------------------------------------


def _stations(length_m: float, step_m: float) -> FloatArray:
    """Stations every ``step_m`` at the middle of each step (never exactly on a road end,
    where consecutive roads meet and lane layouts may change)."""
    return np.arange(0.5 * step_m, length_m, step_m)


def _sample_boundaries(
    road: Road, step_m: float
) -> tuple[FloatArray, FloatArray, list[str], NDArray[np.int64], FloatArray]:
    """Points every ``step_m`` along every boundary of a road.

    Returns ``s, t, kinds, lane_ids, z`` (flat arrays over boundaries and stations).
    """
    s_all = _stations(road.length, step_m)
    s_list, t_list, kinds, ids = [], [], [], []
    sec_idx = road.section_index(s_all)
    for k in np.unique(sec_idx):
        s = s_all[sec_idx == k]
        for kind, lid in section_boundaries(road.lane_sections[int(k)]):
            s_list.append(s)
            t_list.append(road.lane_border_t(s, lid))
            kinds += [kind] * s.size
            ids.append(np.full(s.size, lid, dtype=np.int64))
    s = np.concatenate(s_list) if s_list else np.zeros(0)
    t = np.concatenate(t_list) if t_list else np.zeros(0)
    lane_ids = np.concatenate(ids) if ids else np.zeros(0, dtype=np.int64)
    return s, t, kinds, lane_ids, _height(road, s, t)


def _truth_mainline(
    network: RoadNetwork, truth: RoadNetwork, cfg: EvaluationConfig
) -> tuple[dict[str, Any], dict[str, PointErrors]]:
    true_roads = mainline_roads(truth)
    built = mainline_roads(network)
    offsets = np.concatenate([[0.0], np.cumsum([r.length for r in true_roads])])
    xy_l, st_l, kind_l, z_l = [], [], [], []
    for i, road in enumerate(true_roads):
        s, t, kinds, _, z = _sample_boundaries(road, cfg.truth_step_m)
        xy_l.append(road.to_xy(s, t).reshape(-1, 2))
        st_l.append(offsets[i] + s)
        kind_l += kinds
        z_l.append(z)
    if not xy_l:
        return {"mainline_roads": 0}, {}
    xy = np.vstack(xy_l)
    station = np.concatenate(st_l)
    z_true = np.concatenate(z_l)
    kinds_arr = np.asarray(kind_l)
    proj = project_points(
        built, xy, max_lateral_m=cfg.max_lateral_m, end_tolerance_m=cfg.end_tolerance_m
    )
    details: dict[str, PointErrors] = {}
    result: dict[str, Any] = {
        "mainline_roads": len(true_roads),
        "true_points": int(xy.shape[0]),
        "covered_fraction": float(np.mean(proj.ok)) if proj.ok.size else 0.0,
    }
    for kind in (EDGE, LANE):
        mask = kinds_arr == kind
        sub = Projection(
            np.where(mask, proj.road_index, -1),
            proj.s,
            proj.t,
            np.where(mask, proj.status, _NO_ROAD),
            station,  # plots along the TRUE mainline station
        )
        pe = _lateral_errors(built, xy, sub, kind, f"truth/{kind}")
        details[f"truth/{kind}"] = pe
        result[kind] = error_stats(pe.error_m)
    # elevation at every covered true boundary point
    ok = np.nonzero(proj.ok)[0]
    dz = np.full(ok.size, np.nan)
    for r in np.unique(proj.road_index[ok]):
        sel = ok[proj.road_index[ok] == r]
        dz[np.searchsorted(ok, sel)] = (
            _height(built[int(r)], proj.s[sel], proj.t[sel]) - z_true[sel]
        )
    details["truth/elevation"] = PointErrors(
        "truth/elevation", xy[ok], station[ok], dz, np.zeros(ok.size, dtype=np.int64)
    )
    result["elevation"] = error_stats(dz)
    result["lane_count"] = _lane_count(true_roads, built, offsets, cfg)
    return result, details


def _lane_count(
    true_roads: Sequence[Road], built: Sequence[Road], offsets: FloatArray, cfg: EvaluationConfig
) -> dict[str, Any]:
    """Driving-lane count of the built map against truth at every station."""
    sections = []
    all_match: list[NDArray[np.bool_]] = []
    for i, road in enumerate(true_roads):
        s = _stations(road.length, cfg.truth_step_m)
        sec_idx = road.section_index(s)
        centre = np.empty(s.size)
        for k in np.unique(sec_idx):
            sel = sec_idx == k
            centre[sel] = _section_centre_t(road, s[sel], road.lane_sections[int(k)])
        true_n = driving_lane_count(road, s, min_width_m=cfg.lane_count_min_width_m)
        proj = project_points(
            built,
            road.to_xy(s, centre).reshape(-1, 2),
            max_lateral_m=cfg.max_lateral_m,
            end_tolerance_m=cfg.end_tolerance_m,
        )
        built_n = np.full(s.size, -1, dtype=np.int64)
        for r in np.unique(proj.road_index[proj.ok]):
            sel = proj.road_index == r
            built_n[sel] = driving_lane_count(
                built[int(r)], proj.s[sel], min_width_m=cfg.lane_count_min_width_m
            )
        match = (built_n == true_n) & proj.ok
        for k in np.unique(sec_idx):
            sel = (sec_idx == k) & proj.ok
            sec = road.lane_sections[int(k)]
            end = (
                road.lane_sections[int(k) + 1].s0
                if int(k) + 1 < len(road.lane_sections)
                else road.length
            )
            counts = true_n[sec_idx == k]
            sections.append(
                {
                    "road_id": road.id,
                    "s0_m": float(sec.s0),
                    "s1_m": float(end),
                    "station0_m": float(offsets[i] + sec.s0),
                    "true_driving_lanes": int(np.bincount(counts).argmax()),
                    "built_driving_lanes": (
                        int(np.bincount(built_n[sel]).argmax()) if sel.any() else None
                    ),
                    "covered_stations": int(sel.sum()),
                    "matched_fraction": float(np.mean(match[sel])) if sel.any() else None,
                }
            )
        all_match.append(match[proj.ok])
    flat = np.concatenate(all_match) if all_match else np.zeros(0, dtype=bool)
    return {
        "stations": int(flat.size),
        "matched_fraction": float(np.mean(flat)) if flat.size else None,
        "sections": sections,
    }


def _truth_ramps(
    network: RoadNetwork, truth: RoadNetwork, cfg: EvaluationConfig
) -> tuple[dict[str, Any], dict[str, PointErrors]]:
    """True ramp centre lines and boundaries against the nearest built ramp road.

    Centre: the middle between a section's road edges, against the same on the built road
    the centre point projects onto (:func:`project_points`). Boundaries: against the
    nearest boundary of the same kind on the built road their station's centre point went
    to (so a boundary point where two ramps overlap stays with its own ramp).
    """
    true_roads = ramp_roads(truth)
    built = ramp_roads(network)
    centre_err, bound_err = [], []
    xy_c, xy_b, st_c, st_b = [], [], [], []
    n_true = 0
    n_centre_points = 0
    for road in true_roads:
        s = _stations(road.length, cfg.truth_step_m)
        sec_idx = road.section_index(s)
        t_c = np.empty(s.size)
        for k in np.unique(sec_idx):
            sel = sec_idx == k
            t_c[sel] = _section_centre_t(road, s[sel], road.lane_sections[int(k)])
        pts_c = road.to_xy(s, t_c).reshape(-1, 2)
        n_centre_points += s.size
        sb, tb, kinds_b, _, _ = _sample_boundaries(road, cfg.truth_step_m)
        kinds_b_arr = np.asarray(kinds_b)
        pts_b = road.to_xy(sb, tb).reshape(-1, 2)
        n_true += sb.size
        if not built:
            continue
        kw = {"max_lateral_m": cfg.max_lateral_m, "end_tolerance_m": cfg.end_tolerance_m}
        proj_c = project_points(built, pts_c, **kw)
        # a boundary point goes to the built road its station's centre point went to
        station_idx = np.clip(
            np.rint((sb - 0.5 * cfg.truth_step_m) / cfg.truth_step_m), 0, s.size - 1
        )
        owner_b = proj_c.road_index[station_idx.astype(np.int64)]
        for r in np.unique(proj_c.road_index[proj_c.ok]):
            broad = built[int(r)]
            sel = np.nonzero(proj_c.road_index == r)[0]
            sc_, tc_ = proj_c.s[sel], proj_c.t[sel]
            t_ref = np.empty(sel.size)
            sidx = broad.section_index(sc_)
            for k in np.unique(sidx):
                m = sidx == k
                t_ref[m] = _section_centre_t(broad, sc_[m], broad.lane_sections[int(k)])
            centre_err.append(tc_ - t_ref)
            xy_c.append(pts_c[sel])
            st_c.append(s[sel])
            selb = np.nonzero(owner_b == r)[0]
            s_b, t_b, beyond = _project_one(broad, pts_b[selb], cfg.end_tolerance_m)
            selb, s_b, t_b = selb[~beyond], s_b[~beyond], t_b[~beyond]
            t_ref = np.full(selb.size, np.nan)
            for kind in (EDGE, LANE):
                m = kinds_b_arr[selb] == kind
                t_ref[m], _ = nearest_boundary(broad, s_b[m], t_b[m], kind)
            bound_err.append(t_b - t_ref)
            xy_b.append(pts_b[selb])
            st_b.append(sb[selb])
    details = {}
    result: dict[str, Any] = {"true_ramp_roads": len(true_roads), "built_ramp_roads": len(built)}
    for key, errs, xys, sts, total in (
        ("ramp_centre", centre_err, xy_c, st_c, n_centre_points),
        ("ramp_boundary", bound_err, xy_b, st_b, n_true),
    ):
        e = np.concatenate(errs) if errs else np.zeros(0)
        result[key] = error_stats(e)
        covered = int(np.isfinite(e).sum())  # NaN: the built ramp has no such boundary
        result[key]["covered_fraction"] = float(covered / total) if total else None
        details[f"truth/{key}"] = PointErrors(
            f"truth/{key}",
            np.vstack(xys) if xys else np.zeros((0, 2)),
            np.concatenate(sts) if sts else np.zeros(0),
            e,
            np.zeros(e.size, dtype=np.int64),
        )
    return result, details


# ---------------------------------------------------------------------------
# topology
# ---------------------------------------------------------------------------


def _attachment_point(road: Road, mainline: Sequence[Road]) -> FloatArray:
    """End of a ramp road (centre of its lanes) nearer to the mainline reference lines."""
    ends = np.array([0.0, road.length])
    sec = [road.lane_sections[int(i)] for i in road.section_index(ends)]
    t = np.array([_section_centre_t(road, ends[i : i + 1], sec[i])[0] for i in range(2)])
    pts = road.to_xy(ends, t).reshape(2, 2)
    if not mainline:
        return pts[0]
    grid = np.vstack(
        [r.xy(np.linspace(0.0, r.length, max(2, math.ceil(r.length) + 1))) for r in mainline]
    )
    d, _ = cKDTree(grid).query(pts)
    return pts[int(np.argmin(d))]


def lane_graph(network: RoadNetwork, *, traffic_side: str = "right"):
    """Directed lane graph in the direction of travel.

    Nodes are ``(road_id, section_index, lane_id)``; edges follow lane successor /
    predecessor links inside a road, road links, and junction connection lane links.
    With right-hand traffic, right lanes (negative ids) drive towards +s; with left-hand
    traffic, left lanes do.
    """
    import networkx as nx

    graph = nx.DiGraph()
    roads = network.id_to_road

    def forward(lane_id: int) -> bool:
        return (lane_id < 0) == (traffic_side == "right")

    def target_node(road_id: str, contact: str | None, lane_id: int):
        road = roads.get(road_id)
        if road is None:
            return None
        sec = 0 if contact in (None, "start") else len(road.lane_sections) - 1
        return (road_id, sec, lane_id)

    for road in network.roads:
        nsec = len(road.lane_sections)
        for k, section in enumerate(road.lane_sections):
            for lane in (*section.left, *section.right):
                node = (road.id, k, lane.id)
                graph.add_node(node, type=lane.type)
                fwd = forward(lane.id)
                nxt_lane = lane.successor if fwd else lane.predecessor
                inside = k + 1 < nsec if fwd else k > 0
                if inside:
                    if nxt_lane is not None:
                        graph.add_edge(node, (road.id, k + 1 if fwd else k - 1, nxt_lane))
                    continue
                link = road.successor if fwd else road.predecessor
                if link is None:
                    continue
                if link.element_type == "road":
                    if nxt_lane is not None:
                        tgt = target_node(link.element_id, link.contact_point, nxt_lane)
                        if tgt is not None:
                            graph.add_edge(node, tgt)
                    continue
                junction = network.id_to_junction.get(link.element_id)
                if junction is None:
                    continue
                for conn in junction.connections:
                    if conn.incoming_road != road.id:
                        continue
                    for ll in conn.lane_links:
                        if ll.from_lane == lane.id:
                            tgt = target_node(conn.connecting_road, conn.contact_point, ll.to_lane)
                            if tgt is not None:
                                graph.add_edge(node, tgt)
    return graph


def ramp_connectivity(network: RoadNetwork, *, traffic_side: str = "right") -> list[dict]:
    """For every ramp road: can a car reach it from a mainline driving lane (exit) or reach
    a mainline lane from it (entry) by following lane links?"""
    import networkx as nx

    graph = lane_graph(network, traffic_side=traffic_side)
    main_ids = {r.id for r in network.roads if r.name == "mainline"}
    main_driving = [
        n for n, d in graph.nodes(data=True) if n[0] in main_ids and d.get("type") == "driving"
    ]
    main_all = [n for n in graph.nodes if n[0] in main_ids]
    # one multi-source search each way instead of one search per node
    graph.add_node("_from_main")
    graph.add_edges_from(("_from_main", n) for n in main_driving)
    from_main = nx.descendants(graph, "_from_main")
    graph.add_node("_to_main")
    graph.add_edges_from((n, "_to_main") for n in main_all)
    to_main = nx.ancestors(graph, "_to_main")
    out = []
    for road in ramp_roads(network, with_connectors=False):
        nodes = [n for n in graph.nodes if isinstance(n, tuple) and n[0] == road.id]
        reach = from_main if road.name == "exit" else to_main
        out.append(
            {"road_id": road.id, "type": road.name, "connected": any(n in reach for n in nodes)}
        )
    return out


def topology_against_truth(
    network: RoadNetwork,
    truth: RoadNetwork,
    *,
    truth_info: dict | None = None,
    traffic_side: str = "right",
    config: EvaluationConfig | None = None,
) -> dict[str, Any]:
    """Ramps matched / missed / spurious, merge-exit type and lane-level connectivity.

    Ramps are matched one-to-one (Hungarian assignment) by the distance between their
    attachment points (the ramp end nearer the mainline), up to
    ``config.ramp_match_distance_m``. True ramps come from ``truth_info["ramps"]`` (the
    simulator's truth.json) when given, else from the truth network's ``exit``/``entry``
    roads.
    """
    cfg = config or EvaluationConfig()
    true_main = mainline_roads(truth)
    built_main = mainline_roads(network)
    if truth_info and truth_info.get("ramps") is not None:
        true_list = [
            (str(r["road_id"]), str(r["type"]), r.get("station_m"))
            for r in truth_info["ramps"]
            if str(r["road_id"]) in truth.id_to_road
        ]
    else:
        true_list = [(r.id, r.name, None) for r in ramp_roads(truth, with_connectors=False)]
    built_list = [(r.id, r.name) for r in ramp_roads(network, with_connectors=False)]
    true_pts = np.array(
        [_attachment_point(truth.road(i), true_main) for i, _, _ in true_list]
    ).reshape(-1, 2)
    built_pts = np.array(
        [_attachment_point(network.road(i), built_main) for i, _ in built_list]
    ).reshape(-1, 2)
    pairs = []
    matched_true: set[int] = set()
    matched_built: set[int] = set()
    if len(true_list) and len(built_list):
        cost = np.linalg.norm(true_pts[:, None, :] - built_pts[None, :, :], axis=2)
        rows, cols = linear_sum_assignment(cost)
        for i, j in zip(rows, cols, strict=True):
            if cost[i, j] <= cfg.ramp_match_distance_m:
                matched_true.add(int(i))
                matched_built.add(int(j))
                pairs.append(
                    {
                        "truth_road_id": true_list[i][0],
                        "built_road_id": built_list[j][0],
                        "truth_type": true_list[i][1],
                        "built_type": built_list[j][1],
                        "type_correct": true_list[i][1] == built_list[j][1],
                        "truth_station_m": true_list[i][2],
                        "attachment_distance_m": float(cost[i, j]),
                    }
                )
    connectivity = ramp_connectivity(network, traffic_side=traffic_side)
    conn_by_id = {c["road_id"]: c["connected"] for c in connectivity}
    for p in pairs:
        p["connected"] = conn_by_id.get(p["built_road_id"], False)
    return {
        "true_ramps": len(true_list),
        "built_ramps": len(built_list),
        "matched": len(pairs),
        "missed": [true_list[i][0] for i in range(len(true_list)) if i not in matched_true],
        "spurious": [built_list[j][0] for j in range(len(built_list)) if j not in matched_built],
        "type_correct": sum(p["type_correct"] for p in pairs),
        "connected": sum(c["connected"] for c in connectivity),
        "all_connected": all(c["connected"] for c in connectivity),
        "pairs": pairs,
        "ramps": connectivity,
    }


# ---------------------------------------------------------------------------
# report objects
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RunEvaluation:
    """Evaluation of one map against one run (and its truth, if any).

    Attributes
    ----------
    label : display name (run folder name, plus the method where several are compared).
    run_dir : run folder.
    map_name : name of the map file (or ``""``).
    method : mainline method that built the map (``"default"``, ``"paper"`` or ``""``).
    self_consistency : see :func:`self_consistency`.
    truth : accuracy against truth (``None`` without truth): ``road_edge``,
        ``lane_boundary``, ``elevation``, ``ramp_centre``, ``ramp_boundary`` (each
        :func:`error_stats`), ``lane_count``, coverage.
    topology : :func:`topology_against_truth` (``None`` without truth), or the built map's
        ramp connectivity alone under ``{"ramps": [...]}``.
    details : per-point errors for plots (not serialised).
    map_lines : reconstructed boundary polylines for the map plot (not serialised).
    """

    label: str
    run_dir: str
    map_name: str
    method: str
    self_consistency: dict[str, float]
    truth: dict[str, Any] | None = None
    topology: dict[str, Any] | None = None
    details: dict[str, PointErrors] = field(default_factory=dict, repr=False, compare=False)
    map_lines: tuple[FloatArray, ...] = field(default=(), repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (NaN -> ``None``)."""
        return _json_clean(
            {
                "label": self.label,
                "run_dir": self.run_dir,
                "map": self.map_name,
                "method": self.method,
                "self_consistency": self.self_consistency,
                "truth": self.truth,
                "topology": self.topology,
            }
        )


TABLE_TARGETS = (
    ("road_edge", "Road edge"),
    ("lane_boundary", "Lane boundary"),
    ("overall", "Overall"),
)


@dataclass(frozen=True)
class EvaluationReport:
    """Evaluations of one or several runs (and methods); see :func:`evaluate`."""

    runs: tuple[RunEvaluation, ...]

    def table(self) -> dict[str, dict[str, dict[str, float | int | None]]]:
        """The seed paper's Table 4 per method: ``{method: {target: stats}}``.

        Targets ``road_edge``, ``lane_boundary``, ``overall``; stats ``runs``,
        ``mean_rmse_m``, ``median_rmse_m``, ``min_rmse_m``, ``max_rmse_m`` over the runs'
        self-consistency RMSE (``self_consistency[f"{target}_rmse_m"]``). The method key
        is ``"map"`` where the method is unknown.
        """
        out: dict[str, dict[str, dict[str, float | int | None]]] = {}
        methods = list(dict.fromkeys(r.method or "map" for r in self.runs))
        for m in methods:
            out[m] = {}
            for key, _ in TABLE_TARGETS:
                vals = np.array(
                    [
                        r.self_consistency.get(f"{key}_rmse_m", math.nan)
                        for r in self.runs
                        if (r.method or "map") == m
                    ],
                    dtype=float,
                )
                vals = vals[np.isfinite(vals)]
                out[m][key] = {
                    "runs": int(vals.size),
                    "mean_rmse_m": float(np.mean(vals)) if vals.size else None,
                    "median_rmse_m": float(np.median(vals)) if vals.size else None,
                    "min_rmse_m": float(np.min(vals)) if vals.size else None,
                    "max_rmse_m": float(np.max(vals)) if vals.size else None,
                }
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``report.json`` document (schema documented in the README)."""
        return _json_clean(
            {
                "schema": "roadtwin-evaluation/1",
                "runs": [r.to_dict() for r in self.runs],
                "table": self.table(),
            }
        )


def combine_reports(reports: Iterable[EvaluationReport]) -> EvaluationReport:
    """One report holding the runs of several (for multi-run and multi-method tables)."""
    return EvaluationReport(tuple(r for rep in reports for r in rep.runs))


def format_table(report: EvaluationReport) -> str:
    """The seed paper's Table 4 layout as plain text, one block per method."""
    lines = []
    for method, targets in report.table().items():
        n = max(v["runs"] or 0 for v in targets.values())
        lines.append(f"Self-consistency ({method}, {n} run{'s' if n != 1 else ''})")
        lines.append(f"{'Target':<15}{'Mean RMSE (m)':>15}{'Median RMSE (m)':>17}{'Range (m)':>17}")
        for key, title in TABLE_TARGETS:
            st = targets[key]
            if st["runs"]:
                rng = f"{st['min_rmse_m']:.3f}-{st['max_rmse_m']:.3f}"
                lines.append(
                    f"{title:<15}{st['mean_rmse_m']:>15.3f}{st['median_rmse_m']:>17.3f}{rng:>17}"
                )
            else:
                lines.append(f"{title:<15}{'-':>15}{'-':>17}{'-':>17}")
    return "\n".join(lines)


def _json_clean(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _json_clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_clean(v) for v in obj]
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj


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


def evaluate(
    network: RoadNetwork,
    run: Any,
    *,
    truth: RoadNetwork | None = None,
    truth_info: dict | None = None,
    label: str | None = None,
    method: str = "",
    map_name: str = "",
    config: EvaluationConfig | None = None,
) -> EvaluationReport:
    """Evaluate a built map against its run and, if given, against ground truth.

    Parameters
    ----------
    network
        The built map.
    run
        The :class:`~roadtwin.io.MappingRun` the map was built from.
    truth
        The true network (simulator's ``truth.xodr``), or ``None``.
    truth_info
        The simulator's ``truth.json`` (true ramps with type and station), optional.
    label, method, map_name
        Labels for the report (label defaults to the run folder name).

    Returns
    -------
    EvaluationReport
        With one :class:`RunEvaluation`.
    """
    cfg = config or EvaluationConfig()
    traffic_side = getattr(run, "traffic_side", "right")
    edge, lane, counts = self_consistency_errors(network, run, config=cfg)
    details = {edge.name: edge, lane.name: lane}
    truth_result = None
    if truth is not None:
        truth_result, d1 = _truth_mainline(network, truth, cfg)
        ramps, d2 = _truth_ramps(network, truth, cfg)
        truth_result.update(ramps)
        details.update(d1)
        details.update(d2)
        topology = topology_against_truth(
            network, truth, truth_info=truth_info, traffic_side=traffic_side, config=cfg
        )
    else:
        topology = {"ramps": ramp_connectivity(network, traffic_side=traffic_side)}
    root = getattr(run, "root", "")
    summary = _self_summary(edge, lane, counts)
    log.info(
        "evaluated %s: self-consistency RMSE edge %.3f m, lane %.3f m, overall %.3f m",
        label or root,
        summary["road_edge_rmse_m"],
        summary["lane_boundary_rmse_m"],
        summary["overall_rmse_m"],
    )
    result = RunEvaluation(
        label=label or (getattr(root, "name", "") or str(root)),
        run_dir=str(root),
        map_name=map_name,
        method=method,
        self_consistency=summary,
        truth=truth_result,
        topology=topology,
        details=details,
        map_lines=boundary_polylines(network),
    )
    return EvaluationReport((result,))


# ---------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------


def load_truth(path: str | Path) -> tuple[RoadNetwork, dict | None]:
    """Read a truth network and the ``truth.json`` beside it (``None`` if absent).

    Raises
    ------
    InputError
        The xodr cannot be read or truth.json is not valid JSON.
    """
    from ._errors import InputError
    from .xodr import read_xodr

    path = Path(path)
    network = read_xodr(path)
    info_path = path.with_name("truth.json")
    if not info_path.is_file():
        return network, None
    try:
        info = json.loads(info_path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        msg = f"{info_path}: not valid JSON: {exc}"
        raise InputError(msg) from None
    return network, info


def evaluate_paths(
    map_path: str | Path,
    run_dirs: Sequence[str | Path],
    *,
    truth_path: str | Path | None = None,
    method: str = "",
    config: EvaluationConfig | None = None,
    progress: Callable[[Iterable], Iterable] | None = None,
) -> EvaluationReport:
    """Evaluate a map file against one or several run folders.

    Parameters
    ----------
    map_path
        The built ``.xodr``.
    run_dirs
        Mapping-run folders.
    truth_path
        Ground-truth ``.xodr`` for every run; if ``None``, each run's own
        ``RUN_DIR/truth.xodr`` is used where it exists.
    progress
        Optional wrapper of the run iterable (e.g. ``tqdm``).
    """
    from .io import load_run
    from .xodr import read_xodr

    network = read_xodr(map_path)
    shared = load_truth(truth_path) if truth_path is not None else None
    reports = []
    dirs = [Path(d) for d in run_dirs]
    for run_dir in progress(dirs) if progress else dirs:
        run = load_run(run_dir)
        truth, info = shared if shared is not None else (None, None)
        if shared is None and (run_dir / "truth.xodr").is_file():
            truth, info = load_truth(run_dir / "truth.xodr")
        reports.append(
            evaluate(
                network,
                run,
                truth=truth,
                truth_info=info,
                method=method,
                map_name=Path(map_path).name,
                config=config,
            )
        )
    return combine_reports(reports)


def compare_methods(
    run: Any,
    osm_graph: Any = None,
    *,
    truth: RoadNetwork | None = None,
    truth_info: dict | None = None,
    methods: Sequence[str] = ("default", "paper"),
    config: Any = None,
    eval_config: EvaluationConfig | None = None,
    include_truth: bool = True,
) -> EvaluationReport:
    """Build a run's map with each mainline method and evaluate them side by side.

    Parameters
    ----------
    run
        The :class:`~roadtwin.io.MappingRun`.
    osm_graph
        OSM graph for the ramps (``roadtwin.osm.load_osm``); loaded from ``run.osm_path``
        when ``None`` and the run names one.
    methods
        Values of ``MainlineConfig.method`` to build with.
    config
        :class:`~roadtwin.config.PipelineConfig` (defaults if ``None``); only the mainline
        method is changed per build.

    include_truth
        With a truth network, also evaluate the truth itself against the run (method
        ``"truth"``): the floor of the self-consistency metric set by the measurement noise.

    Returns
    -------
    EvaluationReport
        One :class:`RunEvaluation` per method (``method`` set), in the order given, then
        the truth's.
    """
    from dataclasses import replace

    from .config import PipelineConfig
    from .pipeline import build_map

    cfg = config if config is not None else PipelineConfig()
    if osm_graph is None and getattr(run, "osm_path", None) is not None:
        from .osm import load_osm

        osm_graph = load_osm(
            run.osm_path, frame=run.frame, around_xy=run.trajectory.xy, config=cfg.load
        )
    reports = []
    for method in methods:
        build_cfg = replace(cfg, mainline=replace(cfg.mainline, method=method))
        result = build_map(run, osm_graph, config=build_cfg)
        reports.append(
            evaluate(
                result.network,
                run,
                truth=truth,
                truth_info=truth_info,
                method=method,
                map_name=f"{method} build",
                config=eval_config,
            )
        )
    if truth is not None and include_truth:
        reports.append(
            evaluate(
                truth,
                run,
                truth=truth,
                truth_info=truth_info,
                method="truth",
                map_name="truth",
                config=eval_config,
            )
        )
    return combine_reports(reports)
