"""Any map's driving lanes against the true carriageway, whatever its road structure.

The metrics of :mod:`roadtwin.evaluation` need roadtwin's road roles (``mainline``, ramps).
To compare maps of other tools (SUMO netconvert's OSM to OpenDRIVE, an HD map) with ours
on the same truth, this module looks only at lanes: the centre line of every driving lane
(every metre, in its direction of travel) of the map against those of the true mainline:

* every few metres along the truth, the candidate lanes crossing the true cross-section
  (same direction) are paired with the true lanes by their order from the median side
  (:func:`compare_lane_centres`): lateral error of the paired lane centres, true lanes
  without a partner, and whether the lane count is right.

Mapping-frame metres. Maps in other frames are moved into the truth's first with
:func:`network_points_to_frame`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..drive.routes import traffic_side
from ..model import LaneSection, Road, RoadNetwork

FloatArray = NDArray[np.float64]

__all__ = [
    "LaneCentres",
    "carriageway_edges",
    "compare_edges",
    "compare_lane_centres",
    "lane_centres",
]

DRIVING = frozenset({"driving", "entry", "exit", "onRamp", "offRamp"})
"""Lane types of driving lanes (the drive's ``DRIVABLE`` without ``bidirectional``)."""


@dataclass(frozen=True)
class LaneCentres:
    """Points on the centre lines of driving lanes.

    Attributes
    ----------
    xy : ``(N, 2)`` points (mapping frame, metres).
    heading : ``(N,)`` direction of travel (radians).
    lane : ``(N,)`` index of the lane (a road's lane in one lane section) of each point.
    half_width : ``(N,)`` half the lane's width (metres).
    road : ``(N,)`` index of the road in the network.
    station : ``(N,)`` road station (metres).
    """

    xy: FloatArray
    heading: FloatArray
    lane: NDArray[np.int64]
    half_width: FloatArray
    road: NDArray[np.int64]
    station: FloatArray


def _section_grid(
    network: RoadNetwork, keep: Callable[[Any], bool] | None, step_m: float
) -> Iterator[tuple[int, Road, LaneSection, FloatArray, FloatArray]]:
    """``(road index, road, lane section, stations, headings)`` every ``step_m`` (half a
    step off the section's ends) of every lane section of the roads ``keep`` accepts."""
    for ri, road in enumerate(network.roads):
        if keep is not None and not keep(road):
            continue
        bounds = [sec.s0 for sec in road.lane_sections] + [road.length]
        for k, sec in enumerate(road.lane_sections):
            s = np.arange(bounds[k] + 0.5 * step_m, bounds[k + 1], step_m)
            if s.size:
                yield ri, road, sec, s, road.heading(s)


def _moved(
    xy: FloatArray, heading: FloatArray, transform: Callable[[FloatArray], FloatArray] | None
) -> tuple[FloatArray, FloatArray]:
    """Points and headings in another frame (headings through a point 1 m ahead)."""
    if transform is None:
        return xy, heading
    ahead = transform(xy + np.column_stack([np.cos(heading), np.sin(heading)]))
    xy = transform(xy)
    d = ahead - xy
    return xy, np.arctan2(d[:, 1], d[:, 0])


def lane_centres(
    network: RoadNetwork,
    *,
    step_m: float = 1.0,
    keep: Callable[[Any], bool] | None = None,
    min_width_m: float = 1.5,
    transform: Callable[[FloatArray], FloatArray] | None = None,
) -> LaneCentres:
    """Centre points of every driving lane (at least ``min_width_m`` wide) of the roads
    ``keep`` accepts (default all), every ``step_m``; ``transform`` maps ``(N, 2)`` points
    into another frame (headings follow)."""
    side = traffic_side(network)
    xy_l, h_l, lane_l, w_l, road_l, s_l = [], [], [], [], [], []
    n_lane = 0
    for ri, road, sec, s, h in _section_grid(network, keep, step_m):
        for lane in (*sec.left, *sec.right):
            if lane.type not in DRIVING:
                continue
            outer = road.lane_border_t(s, lane.id)
            inner = road.lane_border_t(s, lane.id + (1 if lane.id < 0 else -1))
            width = np.abs(outer - inner)
            ok = np.isfinite(width) & (width >= min_width_m)
            if not ok.any():
                continue
            pts = road.to_xy(s[ok], 0.5 * (outer + inner)[ok])
            fwd = (lane.id < 0) == (side == "right")
            xy_l.append(pts)
            h_l.append(h[ok] if fwd else h[ok] + math.pi)
            lane_l.append(np.full(pts.shape[0], n_lane))
            w_l.append(0.5 * width[ok])
            road_l.append(np.full(pts.shape[0], ri))
            s_l.append(s[ok])
            n_lane += 1
    if not xy_l:
        z = np.zeros(0)
        return LaneCentres(np.zeros((0, 2)), z, z.astype(np.int64), z, z.astype(np.int64), z)
    xy, heading = _moved(np.vstack(xy_l), np.concatenate(h_l), transform)
    return LaneCentres(
        xy,
        heading,
        np.concatenate(lane_l),
        np.concatenate(w_l),
        np.concatenate(road_l),
        np.concatenate(s_l),
    )


def _turn(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)


def compare_lane_centres(
    candidate: LaneCentres,
    truth: LaneCentres,
    *,
    search_m: float = 6.0,
    max_heading_deg: float = 30.0,
    step_m: float = 2.0,
    side: str = "right",
) -> dict[str, float | int | None]:
    """The candidate's driving lanes against the true ones, cross-section by cross-section.

    Every ``step_m`` along each true road: the true lanes crossing there (their centres,
    sorted from the median side: left for right-hand traffic) and the candidate lanes
    crossing the same line (centre points within 0.75 m of it, running the same way, up to
    ``search_m`` beyond the outermost true lanes; centres closer than 1.5 m are one lane:
    overlapping roads of a junction). Lanes are paired by their order from the median side
    (a map drawn metres off is then still compared lane with lane, not with the nearest
    lane of another); the error is the lateral distance of the paired centres.

    Returns
    -------
    dict
        ``rmse_m``, ``mean_abs_m``, ``p95_m``, ``max_m`` of the paired lanes;
        ``covered_fraction`` (true lanes with a partner); ``lane_count_right`` (fraction of
        cross-sections with as many candidate lanes as true ones); ``cross_sections``;
        ``true_points``.
    """
    out: dict[str, float | int | None] = {"true_points": int(truth.xy.shape[0])}
    empty = {
        "covered_fraction": 0.0, "rmse_m": None, "p95_m": None, "max_m": None,
        "mean_abs_m": None, "lane_count_right": 0.0, "cross_sections": 0,
    }  # fmt: skip
    if candidate.xy.shape[0] == 0 or truth.xy.shape[0] == 0:
        return out | empty
    tree = cKDTree(candidate.xy)
    key_s = np.round(truth.station / step_m).astype(np.int64)
    pick = np.abs(truth.station - key_s * step_m) <= 0.51
    groups: dict[tuple[int, int], list[int]] = {}
    for i in np.flatnonzero(pick):
        groups.setdefault((int(truth.road[i]), int(key_s[i])), []).append(int(i))
    median_first = 1.0 if side == "right" else -1.0  # sort by -lat: left first
    errors: list[float] = []
    paired = total = right = 0
    for members in groups.values():
        m = np.asarray(members)
        centre = truth.xy[m].mean(axis=0)
        h = float(np.angle(np.exp(1j * truth.heading[m]).mean()))
        ux, uy = math.cos(h), math.sin(h)
        lat_t = -(truth.xy[m, 0] - centre[0]) * uy + (truth.xy[m, 1] - centre[1]) * ux
        lo = float(np.min(lat_t - truth.half_width[m])) - search_m
        hi = float(np.max(lat_t + truth.half_width[m])) + search_m
        near = np.asarray(tree.query_ball_point(centre, r=max(-lo, hi) + 1.0), dtype=np.int64)
        lats = np.zeros(0)
        if near.size:
            dx = candidate.xy[near] - centre
            along = dx[:, 0] * ux + dx[:, 1] * uy
            lat = -dx[:, 0] * uy + dx[:, 1] * ux
            same = _turn(candidate.heading[near], np.full(near.size, h))
            ok = (np.abs(along) <= 0.75) & (lat >= lo) & (lat <= hi)
            ok &= same < math.radians(max_heading_deg)
            lats = np.sort(lat[ok])
            if lats.size:
                # one value per lane: overlapping roads' lanes within 1.5 m are one
                split = np.flatnonzero(np.diff(lats) > 1.5) + 1
                lats = np.array([g.mean() for g in np.split(lats, split)])
        lat_t = np.sort(lat_t)
        lat_t = np.array(
            [g.mean() for g in np.split(lat_t, np.flatnonzero(np.diff(lat_t) > 1.5) + 1)]
        )
        true_sorted = np.sort(lat_t * -median_first) * -median_first
        cand_sorted = np.sort(lats * -median_first) * -median_first
        n = min(true_sorted.size, cand_sorted.size)
        errors.extend(np.abs(true_sorted[:n] - cand_sorted[:n]).tolist())
        paired += n
        total += true_sorted.size
        right += cand_sorted.size == true_sorted.size
    e = np.asarray(errors)
    return out | {
        "covered_fraction": paired / total if total else 0.0,
        "rmse_m": float(np.sqrt(np.mean(e * e))) if e.size else None,
        "mean_abs_m": float(np.mean(e)) if e.size else None,
        "p95_m": float(np.percentile(e, 95)) if e.size else None,
        "max_m": float(np.max(e)) if e.size else None,
        "lane_count_right": right / len(groups) if groups else None,
        "cross_sections": len(groups),
    }


PAVED = DRIVING | {"shoulder", "stop", "parking", "restricted", "bidirectional"}
"""Lane types inside a carriageway's edges."""


def carriageway_edges(
    network: RoadNetwork,
    *,
    step_m: float = 1.0,
    keep: Callable[[Any], bool] | None = None,
    transform: Callable[[FloatArray], FloatArray] | None = None,
) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """Points on the edges of every road's paved lanes, per driving direction: the
    median-side edge (kind 0: the inner border of the lane nearest the road's centre) and
    the outer edge (kind 1: the outer border of the outermost paved lane). Returns
    ``(N, 2)`` points, headings of travel (radians) and kinds."""
    side = traffic_side(network)
    xy_l, h_l, k_l = [], [], []
    for _, road, sec, s, h in _section_grid(network, keep, step_m):
        for lanes in (sec.left, sec.right):
            paved = [ln for ln in lanes if ln.type in PAVED]
            if not any(ln.type in DRIVING for ln in paved):
                continue
            inner_id = min(paved, key=lambda ln: abs(ln.id)).id
            outer_id = max(paved, key=lambda ln: abs(ln.id)).id
            fwd = (inner_id < 0) == (side == "right")
            t_in = road.lane_border_t(s, inner_id + (1 if inner_id < 0 else -1))
            t_out = road.lane_border_t(s, outer_id)
            for kind, t in ((0, t_in), (1, t_out)):
                ok = np.isfinite(t)
                xy_l.append(road.to_xy(s[ok], t[ok]))
                h_l.append(h[ok] if fwd else h[ok] + math.pi)
                k_l.append(np.full(int(ok.sum()), kind))
    if not xy_l:
        return np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.int64)
    xy, heading = _moved(np.vstack(xy_l), np.concatenate(h_l), transform)
    return xy, heading, np.concatenate(k_l)


def compare_edges(
    candidate: tuple[FloatArray, FloatArray, NDArray[np.int64]],
    truth: tuple[FloatArray, FloatArray, NDArray[np.int64]],
    *,
    search_m: float = 8.0,
    max_heading_deg: float = 30.0,
) -> dict[str, float | None]:
    """Each true carriageway edge point against the nearest candidate edge of the same
    kind (median-side / outer) running the same way, measured across the candidate edge,
    within ``search_m``: ``rmse_m``, ``p95_m``, ``covered_fraction``."""
    c_xy, c_h, c_k = candidate
    t_xy, t_h, t_k = truth
    errors: list[FloatArray] = []
    covered = 0
    for kind in (0, 1):
        cm, tm = c_k == kind, t_k == kind
        if not cm.any() or not tm.any():
            continue
        cx, ch = c_xy[cm], c_h[cm]
        dist, idx = cKDTree(cx).query(
            t_xy[tm], k=min(8, cx.shape[0]), distance_upper_bound=search_m
        )
        dist = dist.reshape(int(tm.sum()), -1)
        idx = idx.reshape(int(tm.sum()), -1)
        valid = np.isfinite(dist)
        safe = np.where(valid, idx, 0)
        same = valid & (_turn(ch[safe], t_h[tm][:, None]) < math.radians(max_heading_deg))
        d = t_xy[tm][:, None, :] - cx[safe]
        lat = np.abs(-d[..., 0] * np.sin(ch[safe]) + d[..., 1] * np.cos(ch[safe]))
        best = np.where(same, lat, np.inf).min(axis=1)
        ok = np.isfinite(best)
        covered += int(ok.sum())
        errors.append(best[ok])
    e = np.concatenate(errors) if errors else np.zeros(0)
    return {
        "rmse_m": float(np.sqrt(np.mean(e * e))) if e.size else None,
        "p95_m": float(np.percentile(e, 95)) if e.size else None,
        "covered_fraction": covered / t_xy.shape[0] if t_xy.shape[0] else 0.0,
    }
