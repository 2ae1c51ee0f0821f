"""Carriageways built from OSM at OSM accuracy: the one no run drove, or all of them.

Two ways to place a carriageway that no run measured:

* :func:`opposite_carriageway` -- beside a measured carriageway: its median-side edge lies
  at the measured median-side edge plus the OSM median width. OSM draws each carriageway
  along the middle of its driving lanes, so the OSM median width is the distance between
  the two OSM ways minus the half widths of both carriageways (inner shoulder plus half
  the driving lanes, with OSM's lane counts and the measured widths), smoothed along the
  road and never below ``min_median_m``. What OSM gets wrong in common (a regional shift,
  a few metres) cancels; only its relative error remains.
* :func:`carriageway_from_osm` -- from OSM alone: the OSM way offset by the half width
  towards the median, fitted as a curvature-bounded clothoid spline
  (:func:`roadtwin.ramps.fit_ramp_shape`, window by window, each anchored on the last).

Both give one road (``name="mainline"``, reference line on the median-side edge, lanes
from the OSM lane counts: :mod:`.lanes`) and the line along the middle of its driving
lanes, which stands in for the trajectory in the ramp stage. Coordinates in the mapping
frame (metres, radians CCW from +x).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import networkx as nx
import numpy as np
from numpy.typing import NDArray

from ..config import HighwayConfig, RampConfig
from ..fitting import (
    PolylineFrame,
    arc_length,
    fit_cubic_profile,
    fit_parampoly3_chain,
    resample_polyline,
    savgol_smooth,
    whittaker_smooth,
)
from ..model import CubicProfile, Road
from ..ramps import fit_ramp_shape
from .chains import (
    OsmCarriageway,
    carriageway_chains,
    link_attachments,
    maxspeed_mps,
    shared_length_m,
)
from .lanes import CrossSection, lane_sections

FloatArray = NDArray[np.float64]

__all__ = ["OsmRoad", "carriageway_from_osm", "opposite_carriageway", "osm_road_tags"]

_STEP_M = 2.0  # sampling of the measured road and of the median width
_OWN_CHAIN_M = 30.0  # the OSM way of the measured carriageway lies this close to the run
_GORE_MATCH_M = 60.0  # a lane-count change this close to a ramp's node is its gore


@dataclass(frozen=True)
class OsmRoad:
    """A carriageway built from OSM.

    Attributes
    ----------
    road : the road (``name="mainline"``, provisional id ``"osm"``), driving direction.
    path_xy : ``(N, 2)`` the middle of its driving lanes (mapping frame), the trajectory
        a car would have driven (for the ramp stage).
    chain : the OSM carriageway it was built from.
    median_m : ``(M, 2)`` stations along the measured road and the median width used
        there (metres; empty for an OSM-only carriageway).
    notes : what was decided (median width, lane counts).
    """

    road: Road
    path_xy: FloatArray
    chain: OsmCarriageway
    median_m: FloatArray
    notes: tuple[str, ...] = ()


def osm_road_tags(chain: OsmCarriageway) -> tuple[tuple[str, str], ...]:
    """The OSM ``name`` and ``ref`` of a chain as road ``userData`` pairs."""
    out = []
    for key in ("name", "ref"):
        value = chain.tag(key)
        if value:
            out.append((f"roadtwin:osm_{key}", value))
    return tuple(out)


def _lane_counts(
    chain: OsmCarriageway,
    chain_s: FloatArray,
    road_s: FloatArray,
    attachments: list[tuple[float, str, int]],
) -> list[tuple[float, int, bool]]:
    """``(road station, lanes, gore)`` change points, from the chain stations ``chain_s``
    seen at the road stations ``road_s`` (both increasing together). A gain next to an
    entry (a drop next to an exit) within ``_GORE_MATCH_M`` is a gore: the entry's lanes
    join (the exit's leave) at full width, at the ramp's station."""
    n = chain.lanes_at(chain_s)
    out = [(0.0, int(n[0]), False)]
    order = np.argsort(chain_s)
    for k in np.flatnonzero(np.diff(n)) + 1:
        s_road = float(road_s[k])
        kind = "entry" if n[k] > n[k - 1] else "exit"
        near = [
            float(np.interp(s_att, chain_s[order], road_s[order]))
            for s_att, what, _ in attachments
            if what == kind
        ]
        near = [x for x in near if abs(x - s_road) <= _GORE_MATCH_M]
        if near:
            s_road = min(near, key=lambda x: abs(x - s_road))
        out.append((s_road, int(n[k]), bool(near)))
    return out


def _lam(length_m: float, step_m: float) -> float:
    """Whittaker smoothing strength whose cut-off wavelength is ``length_m``."""
    return float((length_m / step_m / (2.0 * math.pi)) ** 4)


def _road(
    ref_xy: FloatArray,
    *,
    counts: list,
    cross: CrossSection,
    traffic_side: str,
    elevation: CubicProfile,
    chain: OsmCarriageway,
    config: HighwayConfig,
) -> tuple[Road, FloatArray]:
    """The road on a reference polyline (driving order) and its driving path."""
    geometry = fit_parampoly3_chain(ref_xy, tolerance_m=0.02)
    length = float(sum(g.length for g in geometry))
    sections = lane_sections(
        length, counts, cross, traffic_side=traffic_side, taper_m=config.lane_taper_m
    )
    speed = maxspeed_mps(chain.tag("maxspeed"))
    road = Road(
        id="osm",
        geometry=geometry,
        lane_sections=sections,
        name="mainline",
        elevation=elevation,
        road_type="motorway",
        speed_limit_mps=speed,
        osm_way_ids=chain.way_ids,
        user_data=osm_road_tags(chain),
    )
    s = np.linspace(0.0, length, max(2, math.ceil(length / _STEP_M) + 1))
    t = np.zeros_like(s)
    for k, sec in enumerate(road.lane_sections):
        end = road.lane_sections[k + 1].s0 if k + 1 < len(road.lane_sections) else length + 1
        sel = (s >= sec.s0) & (s < end)
        lanes = sec.right if traffic_side == "right" else sec.left
        n = sum(ln.type == "driving" for ln in lanes)
        t[sel] = cross.half_width_m(n)
    side = -1.0 if traffic_side == "right" else 1.0
    return road, road.to_xy(s, side * t)


def _sample_chain(chain: OsmCarriageway, step_m: float = 1.0) -> tuple[FloatArray, FloatArray]:
    """Points every ``step_m`` along a chain and their chain stations."""
    s = np.arange(0.0, chain.length, step_m)
    xy = np.column_stack([np.interp(s, chain.s, chain.xy[:, k]) for k in range(2)])
    return xy, s


def _lateral_along(
    road: Road, chain: OsmCarriageway, s_grid: FloatArray, *, max_m: float, opposite: bool
) -> tuple[FloatArray, FloatArray]:
    """Lateral offset (metres, left positive) of an OSM chain from ``road`` at stations
    ``s_grid``, and the chain station there (NaN where the chain is not beside it)."""
    pts, cs = _sample_chain(chain)
    s, t = road.project(pts)
    hdg = road.heading(s)
    h_chain = chain.heading_at(cs)
    turn = np.abs((h_chain - hdg + np.pi) % (2 * np.pi) - np.pi)
    ok = (
        (s > 0.5)
        & (s < road.length - 0.5)
        & (np.abs(t) < max_m)
        & ((turn > 0.75 * np.pi) if opposite else (turn < 0.25 * np.pi))
    )
    t_out = np.full(s_grid.shape, np.nan)
    c_out = np.full(s_grid.shape, np.nan)
    if np.count_nonzero(ok) < 2:
        return t_out, c_out
    order = np.argsort(s[ok])
    s_ok, t_ok, c_ok = s[ok][order], t[ok][order], cs[ok][order]
    # stations more than 5 m from any chain point are not covered
    near = np.abs(s_ok[np.clip(np.searchsorted(s_ok, s_grid), 0, s_ok.size - 1)] - s_grid) < 5.0
    near |= (
        np.abs(s_ok[np.clip(np.searchsorted(s_ok, s_grid) - 1, 0, s_ok.size - 1)] - s_grid) < 5.0
    )
    inside = near & (s_grid >= s_ok[0]) & (s_grid <= s_ok[-1])
    t_out[inside] = np.interp(s_grid[inside], s_ok, t_ok)
    c_out[inside] = np.interp(s_grid[inside], s_ok, c_ok)
    return t_out, c_out


def _longest_run(mask: NDArray[np.bool_]) -> slice:
    """The longest run of True in ``mask`` (empty slice if none)."""
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return slice(0, 0)
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    stops = np.concatenate([idx[breaks], [idx[-1]]]) + 1
    k = int(np.argmax(stops - starts))
    return slice(int(starts[k]), int(stops[k]))


def opposite_carriageway(
    measured: Road,
    osm_graph: nx.MultiDiGraph,
    *,
    path_xy: FloatArray,
    traffic_side: str = "right",
    cross: CrossSection | None = None,
    config: HighwayConfig | None = None,
) -> OsmRoad | None:
    """The carriageway of the other direction beside a measured one, from OSM.

    Parameters
    ----------
    measured
        The measured carriageway as one road (driving direction, reference line on its
        median-side edge), mapping frame.
    osm_graph
        OSM graph in the same frame (:func:`roadtwin.osm.load_osm`).
    path_xy
        ``(N, 2)`` the measured carriageway's trajectory (to find its own OSM way).
    traffic_side
        ``"right"`` or ``"left"``.
    cross
        Widths of the new carriageway (default: the measured one's,
        :func:`~.lanes.measured_cross_section`).
    config
        ``opposite_carriageway_m``, ``min_overlap_m``, ``median_smooth_m``,
        ``min_median_m``, ``lane_taper_m``.

    Returns
    -------
    OsmRoad or None
        None when OSM has no carriageway running the other way beside the measured one.
    """
    cfg = config or HighwayConfig()
    xs = cross or CrossSection()
    chains = carriageway_chains(osm_graph)
    if not chains:
        return None
    shared = [
        shared_length_m(c.xy, path_xy, distance_m=cfg.opposite_carriageway_m, opposite=True)
        for c in chains
    ]
    k = int(np.argmax(shared))
    if shared[k] < cfg.min_overlap_m:
        return None
    other = chains[k]
    own_shared = [
        shared_length_m(c.xy, path_xy, distance_m=_OWN_CHAIN_M, opposite=False) for c in chains
    ]
    j = int(np.argmax(own_shared))
    own = chains[j] if own_shared[j] >= cfg.min_overlap_m else None

    s_grid = np.arange(0.0, measured.length, _STEP_M)
    side = 1.0 if traffic_side == "right" else -1.0  # the median lies on this side (t sign)
    t_b, c_b = _lateral_along(
        measured, other, s_grid, max_m=cfg.opposite_carriageway_m, opposite=True
    )
    ok = np.isfinite(t_b) & (side * t_b > 0.0)
    keep = _longest_run(ok)
    if (keep.stop - keep.start) * _STEP_M < cfg.min_overlap_m:
        return None
    s_k, t_bk, c_bk = s_grid[keep], t_b[keep], c_b[keep]
    h_b = xs.half_width_m(np.asarray(other.lanes_at(c_bk), dtype=float))
    notes = []
    if own is not None:
        t_a, c_a = _lateral_along(measured, own, s_k, max_m=_OWN_CHAIN_M * 2, opposite=False)
        has_a = np.isfinite(t_a)
        h_a = np.full(s_k.shape, np.nan)
        h_a[has_a] = xs.half_width_m(np.asarray(own.lanes_at(c_a[has_a]), dtype=float))
        # OSM's own median (both ways as OSM draws them) where both are there; else the
        # OSM way of the other direction against the measured median-side edge
        median = np.where(has_a, side * (t_bk - t_a) - h_a - h_b, side * t_bk - h_b)
        notes.append(
            f"median from the OSM ways of both directions on {100 * has_a.mean():.0f} % of "
            f"the stretch (ways {own.way_ids[0]} and {other.way_ids[0]})"
        )
    else:
        median = side * t_bk - h_b
        notes.append("median from the OSM way of the other direction and the measured edge")
    median = whittaker_smooth(median, lam=_lam(cfg.median_smooth_m, _STEP_M))
    median = np.maximum(median, cfg.min_median_m)
    edge = measured.to_xy(s_k, side * median)
    ref = resample_polyline(edge[::-1], 1.0)
    u = s_k[-1] - s_k[::-1]  # stations of the new road at the reversed grid
    counts = _lane_counts(other, c_bk[::-1], u, link_attachments(osm_graph, other))
    z = measured.height(s_k[::-1])
    elevation = fit_cubic_profile(u, z, tolerance=0.02)
    road, path = _road(
        ref,
        counts=counts,
        cross=xs,
        traffic_side=traffic_side,
        elevation=elevation,
        chain=other,
        config=cfg,
    )
    notes.append(
        f"other carriageway from OSM way(s) {', '.join(str(w) for w in other.way_ids[:4])}: "
        f"{road.length:.0f} m, median {np.median(median):.1f} m "
        f"({median.min():.1f}-{median.max():.1f} m), lanes "
        f"{'/'.join(str(c[1]) for c in counts)}"
    )
    return OsmRoad(road, path, other, np.column_stack([s_k, median]), tuple(notes))


def _fit_windows(
    target: FloatArray, *, lanes: int, cross: CrossSection, traffic_side: str, cfg: HighwayConfig
) -> FloatArray:
    """A curvature-bounded clothoid spline through a dense target line (driving order, 1 m
    spacing), fitted window by window (:func:`roadtwin.ramps.fit_ramp_shape`); each window
    starts at the pose and curvature where the last kept part ended, and its targets start
    at the target point nearest to that pose (the fitted and the target lines differ in
    length by metres)."""
    # a motorway's curvature changes over hundreds of metres: coarse knots and grid keep
    # the windows' solves small
    rcfg = RampConfig(shape_knot_m=50.0, shape_step_m=2.0)
    smooth = savgol_smooth(target, window=min(41, target.shape[0] // 2 * 2 - 1), polyorder=2)
    a = arc_length(smooth)
    window = cfg.osm_fit_window_m
    keep_m = 0.6 * window
    d = np.gradient(smooth, axis=0)
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    anchor = (float(smooth[0, 0]), float(smooth[0, 1]), float(heading[0]))
    k0 = 0.0
    lane_side = -1.0 if traffic_side == "right" else 1.0
    widths = (cross.inner_shoulder_m, cross.lane_width_m, max(cross.hard_shoulder_m, 0.3))
    parts: list[FloatArray] = []
    i0 = 0
    while True:
        stop = int(np.searchsorted(a, a[i0] + window, side="right"))
        piece = np.vstack([anchor[:2], smooth[i0 + 1 : stop]])
        if piece.shape[0] < 4:
            break
        shape = fit_ramp_shape(
            piece,
            np.full(piece.shape[0], rcfg.osm_sigma_m),
            anchor=anchor,
            curvature0=k0,
            lane_side=lane_side,
            lanes=lanes,
            widths=widths,
            config=rcfg,
        )
        xy = shape.xy
        if stop >= a.size:
            parts.append(xy)
            break
        ax = arc_length(xy)
        n_keep = int(np.searchsorted(ax, keep_m))
        parts.append(xy[:n_keep])
        dd = np.gradient(xy, axis=0)
        hh = np.unwrap(np.arctan2(dd[:, 1], dd[:, 0]))
        kk = np.gradient(hh, ax)
        anchor = (float(xy[n_keep, 0]), float(xy[n_keep, 1]), float(hh[n_keep]))
        k0 = float(np.mean(kk[max(0, n_keep - 5) : n_keep + 5]))
        near = np.hypot(*(smooth[i0:stop] - xy[n_keep]).T)
        i0 = i0 + max(1, int(np.argmin(near)))
    return np.vstack(parts)


def carriageway_from_osm(
    chain: OsmCarriageway,
    osm_graph: nx.MultiDiGraph,
    *,
    traffic_side: str = "right",
    cross: CrossSection | None = None,
    config: HighwayConfig | None = None,
) -> OsmRoad:
    """A carriageway from its OSM way alone (OSM accuracy; ``osm_graph`` holds its ramps):
    the way offset by the half width (inner shoulder and half the driving lanes, lane
    counts smoothed over 400 m) towards the median, fitted as a curvature-bounded clothoid
    spline; lanes from the OSM lane counts (gores where they change at a ramp); elevation
    0 (OSM has no heights)."""
    cfg = config or HighwayConfig()
    xs = cross or CrossSection(cfg.lane_width_m, cfg.inner_shoulder_m, cfg.hard_shoulder_m)
    pts, cs = _sample_chain(chain)
    pts = np.vstack([pts, chain.xy[-1]])
    cs = np.concatenate([cs, [chain.length]])
    n = chain.lanes_at(cs).astype(float)
    win = int(min(401, (pts.shape[0] // 2) * 2 - 1))
    n_smooth = np.convolve(np.pad(n, win // 2, mode="edge"), np.ones(win) / win, mode="valid")
    frame = PolylineFrame.from_points(pts)
    side = 1.0 if traffic_side == "right" else -1.0
    target = frame.offset_points(side * xs.half_width_m(np.asarray(n_smooth, dtype=float)))
    ref = _fit_windows(
        resample_polyline(target, 1.0),
        lanes=int(np.median(n)),
        cross=xs,
        traffic_side=traffic_side,
        cfg=cfg,
    )
    ref = resample_polyline(ref, 1.0)
    u = arc_length(ref)
    counts = _lane_counts(
        chain,
        np.interp(u, [0.0, u[-1]], [0.0, chain.length]),
        u,
        link_attachments(osm_graph, chain),
    )
    road, path = _road(
        ref,
        counts=counts,
        cross=xs,
        traffic_side=traffic_side,
        elevation=CubicProfile.constant(0.0),
        chain=chain,
        config=cfg,
    )
    note = (
        f"carriageway from OSM way(s) {', '.join(str(w) for w in chain.way_ids[:4])}: "
        f"{road.length:.0f} m, lanes {'/'.join(str(c[1]) for c in counts)}"
    )
    return OsmRoad(road, path, chain, np.zeros((0, 2)), (note,))
