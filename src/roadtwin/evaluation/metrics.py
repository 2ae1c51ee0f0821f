"""Lateral error metrics: self-consistency (the seed paper's Table 4) and accuracy against
truth, in metres."""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..config import EvaluationConfig
from ..model import SAME_LEVEL_M, Road, RoadNetwork
from .cross_section import ALONG_RAD, carriageway_lane_count
from .frenet import (
    _BEYOND_ENDS,
    _NO_ROAD,
    _OK,
    EDGE,
    LANE,
    FloatArray,
    Projection,
    _project_one,
    _section_centre_t,
    _stations,
    driving_lane_count,
    mainline_roads,
    nearest_boundary,
    on_pavement_of,
    project_points,
    ramp_roads,
    section_boundaries,
    split_border,
    unseen_boundary,
)

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------
# statistics
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


def _rmse(errors: FloatArray, spread_m2: FloatArray | None = None) -> float:
    ok = np.isfinite(errors)
    e = errors[ok]
    if not e.size:
        return math.nan
    sq = e * e if spread_m2 is None else e * e + spread_m2[ok]
    return float(np.sqrt(np.mean(sq)))


def _row_spread(run: Any, kind: str) -> FloatArray | None:
    """Lateral variance behind each row of a reduced run (``None``: rows are points)."""
    info = getattr(run, "edge_reduction" if kind == EDGE else "lane_reduction", None)
    if info is None or not info.reduced:
        return None
    return np.asarray(info.spread_m2, dtype=float)


# ---------------------------------------------------------------------------
# roles of roads and boundaries
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
    spread_m2 : (N,) lateral variance of the measured points each row stands for (m^2) when
        the run's points were reduced to rows (:mod:`roadtwin.reduction`), else None: the
        RMSE over all points is ``sqrt(mean(error^2 + spread))``.
    """

    name: str
    xy: FloatArray
    station_m: FloatArray
    error_m: FloatArray
    boundary: NDArray[np.int64]
    spread_m2: FloatArray | None = None

    @property
    def rmse_m(self) -> float:
        """RMSE over the points (metres; NaN if empty): of ``error_m``, plus the spread of
        the points behind each row for a reduced run."""
        return _rmse(self.error_m, self.spread_m2)


# ---------------------------------------------------------------------------
# self-consistency
# ---------------------------------------------------------------------------


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
    roads: Sequence[Road],
    pts: FloatArray,
    proj: Projection,
    kind: str | None,
    name: str,
    *,
    either: NDArray[np.bool_] | None = None,
) -> PointErrors:
    """Signed ``t - t_b`` of projected points against the nearest boundary of ``kind``;
    the points of the mask ``either`` against the nearest boundary of any kind."""
    err, lane, err_any, lane_any = _errors_and_any(roads, proj, kind, either)
    if either is not None:
        err = np.where(either, err_any, err)
        lane = np.where(either, lane_any, lane)
    good = np.isfinite(err)
    return PointErrors(name, pts[good, :2], proj.station_m[good], err[good], lane[good])


def _errors_and_any(
    roads: Sequence[Road], proj: Projection, kind: str | None, need_any: NDArray[np.bool_] | None
) -> tuple[FloatArray, NDArray[np.int64], FloatArray, NDArray[np.int64]]:
    """:func:`_errors_full` against boundaries of ``kind`` and against boundaries of any
    kind; the second pass only where a point of the mask ``need_any`` was projected (else
    the first pass's arrays are returned twice)."""
    err, lane = _errors_full(roads, proj, kind)
    if need_any is None or kind is None or not np.any(need_any & proj.ok):
        return err, lane, err, lane
    err_any, lane_any = _errors_full(roads, proj, None)
    return err, lane, err_any, lane_any


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
        against the nearest lane border (road edges included), and extras: ``excluded_beyond_ends``,
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
        spread = _row_spread(run, kind)
        kw = {"max_lateral_m": cfg.max_lateral_m, "end_tolerance_m": cfg.end_tolerance_m}
        proj = project_points(main, pts, **kw)
        # a marking may be painted on a road edge (a two-way road's centre line on its
        # reference line, an edge line without a shoulder): lane samples match any border
        match = EDGE if kind == EDGE else None
        err, lane = _errors_full(main, proj, match)
        status = proj.status
        use_r = np.zeros(err.size, dtype=bool)
        if ramps:
            proj_r = project_points(ramps, pts, **kw)
            err_r, lane_r = _errors_full(ramps, proj_r, match)
            use_r = np.isfinite(err_r) & ~(np.abs(err) <= np.abs(err_r))
            err = np.where(use_r, err_r, err)
            lane = np.where(use_r, lane_r, lane)
            counts["ramp_points"] += int(use_r.sum())
            status = np.where(proj_r.ok, _OK, np.minimum(status, proj_r.status))
        counts["excluded_beyond_ends"] += int(np.sum(status == _BEYOND_ENDS))
        counts["excluded_no_road"] += int(np.sum(status == _NO_ROAD))
        good = np.isfinite(err)
        out.append(
            PointErrors(
                f"self/{kind}",
                pts[good, :2],
                proj.station_m[good],
                err[good],
                lane[good],
                None if spread is None else spread[good],
            )
        )
        on_main = proj.ok & ~use_r
        for r in np.unique(proj.road_index[on_main]):  # measured height - map surface
            sel = on_main & (proj.road_index == r)
            dz_all.append(pts[sel, 2] - main[int(r)].surface_height(proj.s[sel], proj.t[sel]))
    counts["height_rmse_m"] = _rmse(np.concatenate(dz_all)) if dz_all else math.nan
    return out[0], out[1], counts


def _self_summary(edge: PointErrors, lane: PointErrors, counts: dict[str, Any]) -> dict:
    both = np.concatenate([edge.error_m, lane.error_m])
    spread = None
    if edge.spread_m2 is not None or lane.spread_m2 is not None:
        spread = np.concatenate(
            [
                np.zeros(pe.error_m.size) if pe.spread_m2 is None else pe.spread_m2
                for pe in (edge, lane)
            ]
        )
    return {
        "road_edge_rmse_m": edge.rmse_m,
        "lane_boundary_rmse_m": lane.rmse_m,
        "overall_rmse_m": _rmse(both, spread),
        "road_edge_points": int(edge.error_m.size),
        "lane_samples": int(lane.error_m.size),
        **counts,
    }


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


# ---------------------------------------------------------------------------
# against truth
# ---------------------------------------------------------------------------


_SPLIT_PAINT_M = 0.25
"""A lane sample within this distance (metres) of a split's line is paint seen on it; the
line beside a split lies 0.5 m or more away."""

_SPLIT_SEEN_ALONG_M = 20.0
"""A split's line counts this far (metres, along the road) from paint seen on it: over
the gaps of a dashed or worn line, never over a stretch the sensor did not reach."""


def _split_seen(road: Road, s: FloatArray, lane_id: int, paint: cKDTree) -> NDArray[np.bool_]:
    """Which stations ``s`` (metres) of the border split off by lane ``lane_id`` lie within
    ``_SPLIT_SEEN_ALONG_M`` of lane samples (``paint``: their mapping-frame xy) on it."""
    if s.size == 0:
        return np.zeros(0, dtype=bool)
    dense = np.arange(s.min(), s.max() + _SPLIT_PAINT_M, _SPLIT_PAINT_M)
    xy = road.to_xy(dense, road.lane_border_t(dense, lane_id)).reshape(-1, 2)
    dist, _ = paint.query(xy, distance_upper_bound=_SPLIT_PAINT_M)
    hits = dense[np.isfinite(dist)]
    if hits.size == 0:
        return np.zeros(s.shape, dtype=bool)
    i = np.searchsorted(hits, s)
    before = hits[np.clip(i - 1, 0, hits.size - 1)]
    after = hits[np.clip(i, 0, hits.size - 1)]
    return np.minimum(np.abs(s - before), np.abs(s - after)) <= _SPLIT_SEEN_ALONG_M


def _sample_boundaries(
    road: Road, step_m: float, *, seen_only: bool = False, paint: cKDTree | None = None
) -> tuple[FloatArray, FloatArray, list[str], NDArray[np.int64], FloatArray]:
    """Points every ``step_m`` along every boundary of a road.

    ``seen_only``: without the unmarked borders between two non-driving lanes
    (:func:`~.frenet.unseen_boundary`); with ``paint`` (a KD-tree of the run's lane
    samples, mapping-frame xy) also without the painted stretches of such a split that no
    lane sample shows: a split beyond the sensor's reach is a line no build can place (a
    driving lane's border out of reach stays measured: lane widths infer it).

    Returns ``s, t, kinds, lane_ids, z`` (flat arrays over boundaries and stations).
    """
    s_all = _stations(road.length, step_m)
    s_list, t_list, kinds, ids = [], [], [], []
    sec_idx = road.section_index(s_all)
    for k in np.unique(sec_idx):
        s = s_all[sec_idx == k]
        section = road.lane_sections[int(k)]
        for kind, lid in section_boundaries(section):
            at = s
            if seen_only and kind == LANE:
                at = s[~unseen_boundary(section, lid, s - section.s0)]
                if paint is not None and split_border(section, lid) is not None:
                    at = at[_split_seen(road, at, lid, paint)]
            s_list.append(at)
            t_list.append(road.lane_border_t(at, lid))
            kinds += [kind] * at.size
            ids.append(np.full(at.size, lid, dtype=np.int64))
    s = np.concatenate(s_list) if s_list else np.zeros(0)
    t = np.concatenate(t_list) if t_list else np.zeros(0)
    lane_ids = np.concatenate(ids) if ids else np.zeros(0, dtype=np.int64)
    return s, t, kinds, lane_ids, road.surface_height(s, t)


_TWIN_M = 0.1
"""A true boundary within this distance (metres) of a true boundary of the other kind at the
same station is both: a lane border where the lane beside it has closed to zero width
is the road edge there, and is matched with the nearest built boundary of either kind."""


def _twins(s: FloatArray, t: FloatArray, kinds: NDArray[np.str_]) -> NDArray[np.bool_]:
    """Mask of boundary points (one road's, flat) that lie within ``_TWIN_M`` of a point of
    the other kind at the same station."""
    out = np.zeros(s.size, dtype=bool)
    if s.size < 2:
        return out
    order = np.lexsort((t, s))
    a, b = order[:-1], order[1:]
    pair = (s[a] == s[b]) & (np.abs(t[a] - t[b]) < _TWIN_M) & (kinds[a] != kinds[b])
    out[a[pair]] = True
    out[b[pair]] = True
    return out


_ON_RAMP_MARGIN_M = 0.3
"""A true mainline boundary point this far inside a true ramp's road edges (metres) lies on
the ramp's pavement and is left out of the mainline's truth."""


def _at_junction(
    true_ramps: Sequence[Road],
    built_ramps: Sequence[Road],
    pts: FloatArray,
    on_ramp: NDArray[np.bool_],
) -> NDArray[np.bool_]:
    """Mask of true mainline boundary points (``(N, 3)``, mapping frame, metres) on or
    within ``_ON_RAMP_MARGIN_M`` of the pavement of a true or built ramp road (with the
    connecting roads joining it: :func:`~.frenet.ramp_roads`), not on a true ramp's
    pavement (those are left out)."""
    near = np.zeros(pts.shape[0], dtype=bool)
    for ramps in (true_ramps, built_ramps):
        near |= on_pavement_of(ramps, pts, margin_m=-_ON_RAMP_MARGIN_M)
    return near & ~on_ramp


def _junction_errors(
    ramps: Sequence[Road],
    pts: FloatArray,
    heading: FloatArray,
    mainline_err: FloatArray,
    mainline_any: FloatArray,
    at_junction: NDArray[np.bool_],
) -> FloatArray:
    """Errors of true mainline boundary points where a ramp leaves or joins (metres): the
    smallest in magnitude against any boundary of the built mainline or of a built ramp road
    (or its connecting road; ``ramps``) the point is on or beside, running along the true mainline
    (``heading``: its heading at each point, radians; within ``ALONG_RAD``);
    ``mainline_err`` elsewhere.

    Where a ramp lane stops being a mainline lane is a convention of each map (a junction
    starting at the painted gore, at the nose, a connecting road of 12 or 20 m): the same
    pavement edge is the mainline's edge in one map and a ramp connecting road's edge, or a
    lane border between through and ramp lanes, in another, a few metres along. A true
    boundary there is matched with the nearest built boundary of the carriageway, whichever
    road carries it; away from ramps the kinds and roads must agree.
    """
    err = mainline_err.copy()
    idx = np.nonzero(at_junction)[0]
    if not idx.size:
        return err
    best = np.where(np.isfinite(mainline_any[idx]), mainline_any[idx], np.inf)
    proj = project_points(ramps, pts[idx], max_lateral_m=_ON_RAMP_MARGIN_M, end_tolerance_m=0.0)
    for r in np.unique(proj.road_index[proj.ok]):
        sel = np.nonzero(proj.ok & (proj.road_index == r))[0]
        road = ramps[int(r)]
        level = np.abs(road.surface_height(proj.s[sel], proj.t[sel]) - pts[idx[sel], 2])
        # a ramp crossing the mainline (a knotted or misplaced one) is no lane beside it
        along = np.abs(np.angle(np.exp(1j * (road.heading(proj.s[sel]) - heading[idx[sel]]))))
        t_b, _ = nearest_boundary(road, proj.s[sel], proj.t[sel], None)
        cand = np.where((level <= SAME_LEVEL_M) & (along <= ALONG_RAD), proj.t[sel] - t_b, np.nan)
        better = np.isfinite(cand) & (np.abs(cand) < np.abs(best[sel]))
        best[sel[better]] = cand[better]
    err[idx] = np.where(np.isfinite(best), best, err[idx])
    return err


def _truth_mainline(
    network: RoadNetwork,
    truth: RoadNetwork,
    cfg: EvaluationConfig,
    lane_samples: FloatArray | None = None,
) -> tuple[dict[str, Any], dict[str, PointErrors]]:
    """Every true mainline boundary against the built map (``lane_samples``: the run's,
    ``(M, >=2)`` mapping frame, to leave out the splits it never saw)."""
    paint = None
    if lane_samples is not None and len(lane_samples):
        paint = cKDTree(np.asarray(lane_samples, dtype=float)[:, :2])
    true_roads = mainline_roads(truth)
    built = mainline_roads(network)
    offsets = np.concatenate([[0.0], np.cumsum([r.length for r in true_roads])])
    xy_l, st_l, kind_l, z_l, id_l, twin_l, h_l = [], [], [], [], [], [], []
    for i, road in enumerate(true_roads):
        s, t, kinds, lane_ids, z = _sample_boundaries(
            road, cfg.truth_step_m, seen_only=True, paint=paint
        )
        twin_l.append(_twins(s, t, np.asarray(kinds)))
        h_l.append(road.heading(s))
        xy_l.append(road.to_xy(s, t).reshape(-1, 2))
        st_l.append(offsets[i] + s)
        kind_l += kinds
        z_l.append(z)
        id_l.append(lane_ids)
    if not xy_l:
        empty = error_stats(np.zeros(0))
        return {
            "mainline_roads": 0,
            "true_points": 0,
            "covered_fraction": None,
            EDGE: empty,
            LANE: dict(empty),
            "elevation": dict(empty),
            "lane_count": {"stations": 0, "matched_fraction": None, "sections": []},
        }, {}
    xy = np.vstack(xy_l)
    station = np.concatenate(st_l)
    z_true = np.concatenate(z_l)
    kinds_arr = np.asarray(kind_l)
    pts3 = np.column_stack([xy, z_true])
    # a true boundary on the pavement of a true ramp is no border of anything: truths that
    # keep a diverging lane on the mainline while the ramp road already covers it (or grow
    # an entry's lanes under the ramp's end) sweep their "edge" across the ramp there
    true_ramps, built_ramps = ramp_roads(truth), ramp_roads(network)
    on_ramp = on_pavement_of(true_ramps, pts3, margin_m=_ON_RAMP_MARGIN_M)
    kinds_arr = np.where(on_ramp, "", kinds_arr)
    # with their heights: a run that passes over itself has two levels of boundaries
    proj = project_points(
        built, pts3, max_lateral_m=cfg.max_lateral_m, end_tolerance_m=cfg.end_tolerance_m
    )
    details: dict[str, PointErrors] = {}
    result: dict[str, Any] = {
        "mainline_roads": len(true_roads),
        "true_points": int(xy.shape[0]),
        "on_ramp_points": int(np.count_nonzero(on_ramp)),
        "covered_fraction": float(np.mean(proj.ok)) if proj.ok.size else 0.0,
    }
    twin = np.concatenate(twin_l)
    heading = np.concatenate(h_l)
    at_junction = _at_junction(true_ramps, built_ramps, pts3, on_ramp)
    for kind in (EDGE, LANE):
        mask = kinds_arr == kind
        sub = Projection(
            np.where(mask, proj.road_index, -1),
            proj.s,
            proj.t,
            np.where(mask, proj.status, _NO_ROAD),
            station,  # plots along the TRUE mainline station
        )
        err, lane, err_any, lane_any = _errors_and_any(built, sub, kind, twin | at_junction)
        strict = np.where(twin, err_any, err)
        lane = np.where(twin, lane_any, lane)
        good = np.isfinite(strict)
        err = _junction_errors(built_ramps, pts3, heading, strict, err_any, at_junction & good)
        pe = PointErrors(f"truth/{kind}", xy[good], station[good], err[good], lane[good])
        details[f"truth/{kind}"] = pe
        result[kind] = error_stats(pe.error_m)
        # the same points with kinds and roads that must agree at junctions too
        result[f"{kind}_strict"] = error_stats(strict[good])
    result["junction_points"] = int(np.count_nonzero(at_junction))
    # elevation at every covered true boundary point
    ok = np.nonzero(proj.ok)[0]
    dz = np.full(ok.size, np.nan)
    for r in np.unique(proj.road_index[ok]):
        sel = ok[proj.road_index[ok] == r]
        dz[np.searchsorted(ok, sel)] = (
            built[int(r)].surface_height(proj.s[sel], proj.t[sel]) - z_true[sel]
        )
    details["truth/elevation"] = PointErrors(
        "truth/elevation", xy[ok], station[ok], dz, np.concatenate(id_l)[ok]
    )
    result["elevation"] = error_stats(dz)
    result["lane_count"] = _lane_count(
        true_roads,
        built,
        offsets,
        cfg,
        true_ramps=true_ramps,
        built_ramps=built_ramps,
    )
    return result, details


def _slice_projection(proj: Projection, start: int, stop: int) -> Projection:
    """Points ``start:stop`` of a projection."""
    return Projection(
        proj.road_index[start:stop],
        proj.s[start:stop],
        proj.t[start:stop],
        proj.status[start:stop],
        proj.station_m[start:stop],
    )


def _centre_points(
    roads: Sequence[Road], step_m: float
) -> tuple[list[FloatArray], list[FloatArray]]:
    """Per road: stations every ``step_m`` metres and the (N, 3) mapping-frame points on the
    centre of its lanes (between the road edges of the section there) with the height of
    the road surface there (metres)."""
    stations, centres = [], []
    for road in roads:
        s = _stations(road.length, step_m)
        sec_idx = road.section_index(s)
        t_c = np.empty(s.size)
        for k in np.unique(sec_idx):
            sel = sec_idx == k
            t_c[sel] = _section_centre_t(road, s[sel], road.lane_sections[int(k)])
        stations.append(s)
        xy = road.to_xy(s, t_c).reshape(-1, 2)
        centres.append(np.column_stack([xy, road.surface_height(s, t_c)]))
    return stations, centres


_NEAR_RAMP_M = 15.0
"""Stations whose centre point lies within this distance (metres) of a true or built ramp's
pavement are counted across the carriageway (:mod:`.cross_section`)."""


def _lane_count(
    true_roads: Sequence[Road],
    built: Sequence[Road],
    offsets: FloatArray,
    cfg: EvaluationConfig,
    *,
    true_ramps: Sequence[Road] = (),
    built_ramps: Sequence[Road] = (),
) -> dict[str, Any]:
    """Driving-lane count of the built map against truth at every station: of the mainline
    roads, and near a ramp (``true_ramps``, ``built_ramps``: ramp and connecting roads) of
    every road across the carriageway in each map."""
    sections = []
    all_match: list[NDArray[np.bool_]] = []
    stations, centres = _centre_points(true_roads, cfg.truth_step_m)
    # one projection of all roads' points (per-point results do not depend on the batch)
    proj_all = project_points(
        built,
        np.vstack(centres) if centres else np.zeros((0, 3)),
        max_lateral_m=cfg.max_lateral_m,
        end_tolerance_m=cfg.end_tolerance_m,
    )
    bounds = np.concatenate([[0], np.cumsum([s.size for s in stations])])
    min_w = cfg.lane_count_min_width_m
    for i, road in enumerate(true_roads):
        s = stations[i]
        sec_idx = road.section_index(s)
        true_n = driving_lane_count(road, s, min_width_m=cfg.lane_count_min_width_m)
        proj = _slice_projection(proj_all, int(bounds[i]), int(bounds[i + 1]))
        built_n = np.full(s.size, -1, dtype=np.int64)
        for r in np.unique(proj.road_index[proj.ok]):
            sel = proj.road_index == r
            built_n[sel] = driving_lane_count(
                built[int(r)], proj.s[sel], min_width_m=cfg.lane_count_min_width_m
            )
        near = proj.ok & on_pavement_of(
            [*true_ramps, *built_ramps], centres[i], margin_m=-_NEAR_RAMP_M
        )
        match = (built_n == true_n) & proj.ok
        # near a ramp, a count that differs on the mainline roads may agree across the
        # carriageway: the maps put the ramp's lanes on different roads there
        near &= ~match
        if near.any():
            h = road.heading(s[near])
            normals = np.column_stack([-np.sin(h), np.cos(h)])
            true_cw = carriageway_lane_count(
                [*true_roads, *true_ramps], centres[i][near], normals, min_width_m=min_w
            )
            built_cw = carriageway_lane_count(
                [*built, *built_ramps], centres[i][near], normals, min_width_m=min_w
            )
            match[near] = built_cw == true_cw
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
    stations, centres = _centre_points(true_roads, cfg.truth_step_m)
    kw = {"max_lateral_m": cfg.max_lateral_m, "end_tolerance_m": cfg.end_tolerance_m}
    # one projection of all ramps' centre points (per-point results do not depend on it);
    # in plan only: a built ramp's heights come from OSM's layers, metres off on a bridge,
    # so its level would send true points to another road
    proj_all = project_points(built, np.vstack(centres)[:, :2], **kw) if built and centres else None
    bounds = np.concatenate([[0], np.cumsum([s.size for s in stations])])
    for i, road in enumerate(true_roads):
        s, pts_c = stations[i], centres[i]
        n_centre_points += s.size
        sb, tb, kinds_b, _, _ = _sample_boundaries(road, cfg.truth_step_m)
        kinds_b_arr = np.asarray(kinds_b)
        pts_b = road.to_xy(sb, tb).reshape(-1, 2)
        n_true += sb.size
        if proj_all is None:
            continue
        proj_c = _slice_projection(proj_all, int(bounds[i]), int(bounds[i + 1]))
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
            xy_c.append(pts_c[sel, :2])
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
        keep = np.isfinite(e)
        result[key] = error_stats(e)
        covered = int(keep.sum())  # NaN: the built ramp has no such boundary
        result[key]["covered_fraction"] = float(covered / total) if total else None
        details[f"truth/{key}"] = PointErrors(
            f"truth/{key}",
            (np.vstack(xys) if xys else np.zeros((0, 2)))[keep],
            (np.concatenate(sts) if sts else np.zeros(0))[keep],
            e[keep],
            np.zeros(int(keep.sum()), dtype=np.int64),
        )
    return result, details


# ---------------------------------------------------------------------------
# topology
# ---------------------------------------------------------------------------
