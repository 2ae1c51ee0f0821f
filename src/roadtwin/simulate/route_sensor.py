"""The mapping car on a route truth: its path, the paved area's edges and the paint.

* **Path**: the car drives the centre of a lane (``lane`` counted from the median side;
  0 = the outermost through lane) at constant station steps (``speed / rate``) along the
  mainline. A lane that ends within ``lookahead_m`` (a lane drop, an exit lane) or an
  auxiliary lane is not chosen; when the chosen lane changes the car moves over along a
  smoothstep over ``lane_change_m`` per lane crossed, ending a lane change's length after
  the decision (a change across several lanes starts early), as a driver does. The path
  never falls back to the reference line and its lateral rate is limited (1:10), so the
  car never runs backwards where lane centres jump (a lane ending at full width).
* **Road edges**: points along both edges of every true road (the mainline and the
  ramps), minus those inside another road's paved area at the same height: so at a gore
  the edge follows the ramp's outer edge and the nose's inner edges, and where roads
  overlap in a junction the interior borders are not edges. Left/right is relative to
  the observing pose. Range, dropouts, trucks, guardrail outliers and noise as in
  :func:`roadtwin.simulate.sensor.observe_edges`.
* **Lane markings**: every painted border (:data:`~roadtwin.simulate.markings.PAINTED`
  road marks of the true roads, median edge included) with the national dash pattern,
  worn stretches, seen by :func:`roadtwin.simulate.sensor.observe_markings`.

Frames: mapping frame, metres, radians; stations are metres along the whole mainline.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ..evaluation.mainline_truth import lane_borders
from ..fitting import arc_length
from ..model import Road, RoadNetwork
from .markings import PAINTED, MarkingStyle, dash_pattern
from .route import TRAFFIC_LANE_TYPES
from .route_truth import RouteTruth
from .scenario import Car
from .sensor import SIDE_LEFT, SIDE_RIGHT, Poses, observing_frame

FloatArray = NDArray[np.float64]

MIN_LANE_WIDTH_M = 2.5
"""A lane narrower than this (tapering in or out) is not driven."""
INTERIOR_TOLERANCE_M = 0.005
"""An edge point this close to another road's paved area is inside the paved area."""
SAME_LEVEL_M = 2.5
"""Paved areas whose heights differ by more than this do not hide each other's edges."""


# ---------------------------------------------------------------------------
# the car's path
# ---------------------------------------------------------------------------


def _key_ends(truth: RouteTruth) -> dict[int, float]:
    """Mainline station where each lane key stops being drivable: where it gets narrower
    than :data:`MIN_LANE_WIDTH_M` before its last lane section ends (the start of its
    taper), else that end (inf: the lane runs to the route's end)."""
    road = truth.mainline
    keys = truth.mainline_fit.section_keys
    out: dict[int, float] = {}
    last: dict[int, int] = {}
    for k, ks in enumerate(keys):
        for key in ks:
            last[key] = k
    for key, k in last.items():
        if k + 1 == len(keys):
            out[key] = math.inf
            continue
        end = road.lane_sections[k + 1].s0
        # walk back over the lane's sections until it is wide again
        u = np.arange(end - 1e-6, max(end - 600.0, 0.0), -0.5)
        w = _key_width(truth, u, key)
        wide = np.nonzero(w >= MIN_LANE_WIDTH_M)[0]
        out[key] = float(u[wide[0]]) if wide.size else end
    return out


def _key_width(truth: RouteTruth, u: FloatArray, key: int) -> FloatArray:
    """Width of lane ``key`` at stations u (0 where it does not run)."""
    road = truth.mainline
    sec_idx = road.section_index(u)
    out = np.zeros(u.size)
    for k in np.unique(sec_idx):
        lane_id = truth.mainline_fit.lane_id(int(k), key)
        if lane_id is None:
            continue
        sel = sec_idx == k
        sec = road.lane_sections[int(k)]
        out[sel] = sec.lane(lane_id).width.value(u[sel] - sec.s0)
    return out


def _lane_centre(road: Road, u: FloatArray, lane_id: int) -> FloatArray:
    inner = 0 if abs(lane_id) == 1 else lane_id - int(math.copysign(1, lane_id))
    return 0.5 * (road.lane_border_t(u, inner) + road.lane_border_t(u, lane_id))


def chosen_lane_keys(
    truth: RouteTruth, u: FloatArray, lane: int, *, lookahead_m: float
) -> NDArray[np.int64]:
    """The lane key the car aims for at each station (``lane`` 1 = innermost through
    lane, 0 = outermost)."""
    road = truth.mainline
    ends = _key_ends(truth)
    sec_idx = road.section_index(u)
    out = np.zeros(u.size, np.int64)
    for k in np.unique(sec_idx):
        sel = np.nonzero(sec_idx == k)[0]
        sec = road.lane_sections[int(k)]
        lanes = sec.right or sec.left
        keys = truth.mainline_fit.section_keys[int(k)]
        uu = u[sel]
        widths = np.stack([lane_.width.value(uu - sec.s0) for lane_ in lanes])
        traffic = np.array([ln.type in TRAFFIC_LANE_TYPES for ln in lanes])
        aux = np.array([key in truth.aux_keys for key in keys])
        remaining = np.array([ends[key] for key in keys])[:, None] - uu[None, :]
        wide = widths >= MIN_LANE_WIDTH_M
        tiers = [
            traffic[:, None] & ~aux[:, None] & wide & (remaining > lookahead_m),
            traffic[:, None] & ~aux[:, None] & wide,
            traffic[:, None] & wide,
            np.broadcast_to(traffic[:, None], wide.shape),
        ]
        choice = np.full(uu.size, -1)
        for ok in tiers:
            todo = choice < 0
            if not np.any(todo):
                break
            count = ok.sum(axis=0)
            has = todo & (count > 0)
            if not np.any(has):
                continue
            order = np.cumsum(ok, axis=0)  # 1-based rank of each candidate lane
            want = count if lane <= 0 else np.minimum(lane, count)
            pick = np.argmax(ok & (order == want[None, :]), axis=0)
            choice[has] = pick[has]
        choice[choice < 0] = 0
        out[sel] = np.asarray(keys)[choice]
    return out


def _key_centre(truth: RouteTruth, u: FloatArray, key: int) -> FloatArray:
    """Centre offset t of lane ``key`` at stations u (NaN where it does not run)."""
    road = truth.mainline
    sec_idx = road.section_index(u)
    out = np.full(u.size, np.nan)
    for k in np.unique(sec_idx):
        keys = truth.mainline_fit.section_keys[int(k)]
        if key not in keys:
            continue
        sel = sec_idx == k
        lane_id = truth.mainline_fit.lane_id(int(k), key)
        out[sel] = _lane_centre(road, u[sel], lane_id)  # type: ignore[arg-type]
    return out


PATH_STEP_M = 0.25
"""Spacing of the stations on which the car's path is laid out before it is sampled."""


def drive(
    truth: RouteTruth, car: Car, *, lookahead_m: float = 200.0, lane_change_m: float = 120.0
) -> Poses:
    """Noise-free poses of the car: ``speed / rate`` metres apart along its own path
    (constant speed), ``station`` the mainline station of each pose (metres)."""
    road = truth.mainline
    u = np.arange(0.0, road.length - 1e-6, PATH_STEP_M)
    keys = chosen_lane_keys(truth, u, car.lane, lookahead_m=lookahead_m)
    t = np.full(u.size, np.nan)
    for key in np.unique(keys):
        sel = keys == key
        t[sel] = _key_centre(truth, u[sel], int(key))
    n_w = max(1, round(lane_change_m / PATH_STEP_M))
    changes = np.nonzero(keys[1:] != keys[:-1])[0] + 1
    done = 0  # where the previous lane change ended (path index)
    for j, i in enumerate(changes):
        # a change across n lanes takes n lane changes' length and ends where a single one
        # would: the driver starts early enough (not before the previous change ended)
        n = _lanes_crossed(truth, float(u[i - 1]), int(keys[i - 1]), int(keys[i]))
        start = max(i - (n - 1) * n_w, done, 1)
        end = i + n_w
        stop = min(end, u.size, changes[j + 1] if j + 1 < changes.size else u.size)
        seg = np.arange(start, stop)
        w = (seg - start + 1) / (end - start)
        w = w * w * (3.0 - 2.0 * w)
        old = _key_centre(truth, u[seg], int(keys[i - 1]))
        new = _key_centre(truth, u[seg], int(keys[i]))
        old = np.where(np.isfinite(old), old, t[seg])
        new = np.where(np.isfinite(new), new, t[seg])
        t[seg] = (1.0 - w) * old + w * new
        done = stop
    # where the chosen lane has no centre (a section without it) the car holds its line:
    # interpolate, never fall back to the reference line (a jump of several metres made
    # the arc-length resampling run the car backwards)
    ok = np.isfinite(t)
    t = np.interp(u, u[ok], t[ok]) if np.any(ok) else np.zeros_like(u)
    # a driver steers: no lateral rate above ~1:10 even where lane centres jump (a lane
    # ending at full width at a gore)
    t = _limit_lateral_rate(t, PATH_STEP_M, max_slope=0.1)
    path = road.to_xy(u, t)
    arc = arc_length(path)
    step = car.speed_kmh / 3.6 / car.rate_hz
    s_pose = np.arange(0.0, arc[-1], step)
    u_pose = np.interp(s_pose, arc, u)
    t_pose = np.interp(s_pose, arc, t)
    xy = road.to_xy(u_pose, t_pose)
    heading = np.unwrap(np.arctan2(*np.gradient(path, axis=0)[:, ::-1].T))
    yaw = np.interp(s_pose, arc, heading)
    z = road.surface_height(u_pose, t_pose)
    frame = np.arange(u_pose.size, dtype=np.int64)
    return Poses(frame, car.t0_s + frame / car.rate_hz, np.column_stack([xy, z]), yaw, u_pose)


def _lanes_crossed(truth: RouteTruth, u: float, key_from: int, key_to: int) -> int:
    """How many lanes apart lanes ``key_from`` and ``key_to`` lie at station ``u`` (1 when
    one of them does not run there)."""
    keys = truth.mainline_fit.section_keys[int(truth.mainline.section_index(np.array([u]))[0])]
    if key_from not in keys or key_to not in keys:
        return 1
    return max(1, abs(keys.index(key_to) - keys.index(key_from)))


def _limit_lateral_rate(t: FloatArray, step_m: float, *, max_slope: float) -> FloatArray:
    """``t`` (metres on a regular grid ``step_m`` apart) with its slope limited to
    ``max_slope``: forward and backward passes that keep each value within the slope of
    its neighbour, averaged (a jump becomes a ramp centred on it)."""
    lim = max_slope * step_m
    fwd = t.copy()
    for i in range(1, fwd.size):  # a running clamp; loops over path samples, not points
        fwd[i] = min(max(fwd[i], fwd[i - 1] - lim), fwd[i - 1] + lim)
    bwd = t.copy()
    for i in range(bwd.size - 2, -1, -1):
        bwd[i] = min(max(bwd[i], bwd[i + 1] - lim), bwd[i + 1] + lim)
    return 0.5 * (fwd + bwd)


def sensor_view(poses: Poses, station: FloatArray, step_m: float) -> tuple[Poses, FloatArray]:
    """Poses and point stations in the form the shared sensor code expects: poses
    ``step_m`` apart in station, so a point's station is its observing frame times the
    step (mainline stations mapped through the poses'; NaN stays NaN)."""
    even = poses.frame * step_m
    mapped = np.full(station.shape, np.nan)
    ok = np.isfinite(station)
    mapped[ok] = np.interp(station[ok], poses.station, even)
    return replace(poses, station=even), mapped


def resolved_lane(truth: RouteTruth, poses: Poses) -> int:
    """The car's lane at its first pose among the traffic lanes, counted from the median
    side (1 = innermost)."""
    road = truth.mainline
    s, t = road.project(poses.xyz[:1, :2], s_init=poses.station[:1])
    sec = road.lane_sections[int(road.section_index(s)[0])]
    traffic = [ln for ln in (sec.right or sec.left) if ln.type in TRAFFIC_LANE_TYPES]
    for rank, lane in enumerate(traffic, start=1):
        centre = _lane_centre(road, s, lane.id)[0]
        half = 0.5 * float(lane.width.value(s - sec.s0)[0])
        if abs(t[0] - centre) <= half + 1e-6:
            return rank
    return len(traffic)


# ---------------------------------------------------------------------------
# road edges
# ---------------------------------------------------------------------------


def _truth_roads(truth: RouteTruth) -> list[tuple[Road, bool]]:
    """The whole mainline road and the ramp roads, with a flag for the mainline."""
    return [(truth.mainline, True), *((r.road, False) for r in truth.ramps)]


def _paved_chunks(
    roads: list[tuple[Road, bool]], chunk_m: float = 25.0, step_m: float = 0.5
) -> tuple[list, NDArray, NDArray, NDArray, NDArray]:
    """Polygons of each road's paved band in chunks (split at lane sections), with their
    road index, station range and mean height."""
    polys, owner, lo, hi, z = [], [], [], [], []
    for r_idx, (road, _) in enumerate(roads):
        bounds = sorted({*(ls.s0 for ls in road.lane_sections), road.length})
        for a, b in itertools.pairwise(bounds):
            n_chunks = max(1, math.ceil((b - a) / chunk_m))
            edges = np.linspace(a, b, n_chunks + 1)
            for ca, cb in itertools.pairwise(edges):
                s = np.linspace(ca, cb - 1e-7, max(2, math.ceil((cb - ca) / step_m) + 1))
                ref_t, out_t, _, _ = lane_borders(road, s)
                ring = np.vstack([road.to_xy(s, ref_t), road.to_xy(s[::-1], out_t[::-1])])
                poly = shapely.make_valid(shapely.Polygon(ring))
                if poly.is_empty or poly.area < 1e-6:
                    continue
                polys.append(poly.buffer(INTERIOR_TOLERANCE_M))
                owner.append(r_idx)
                lo.append(ca)
                hi.append(cb)
                z.append(float(np.mean(road.elevation.value(s))))
    return polys, np.array(owner), np.array(lo), np.array(hi), np.array(z)


def true_edges(
    truth: RouteTruth, spacing_m: float, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Dense points on the boundary of the paved area of the true roads.

    Returns ``xyz (N, 3)``, outward unit normals ``(N, 2)`` and the mainline station of
    each point (NaN on ramps).
    """
    roads = _truth_roads(truth)
    sign = truth.sign
    pts, normals, stations, owner, s_all = [], [], [], [], []
    for r_idx, (road, is_main) in enumerate(roads):
        s = np.arange(0.0, road.length, spacing_m)
        s = np.clip(s + rng.uniform(0.0, spacing_m, s.size), 0.0, road.length - 1e-7)
        ref_t, out_t, _, _ = lane_borders(road, s)
        h = road.heading(s)
        left = np.column_stack([-np.sin(h), np.cos(h)])
        for t, out_dir in ((ref_t, -sign), (out_t, sign)):
            xy = road.to_xy(s, t)
            pts.append(np.column_stack([xy, road.surface_height(s, t)]))
            normals.append(out_dir * left)
            stations.append(s if is_main else np.full(s.size, np.nan))
            owner.append(np.full(s.size, r_idx))
            s_all.append(s)
    xyz = np.vstack(pts)
    normal = np.vstack(normals)
    station = np.concatenate(stations)
    own = np.concatenate(owner)
    s_own = np.concatenate(s_all)
    polys, p_owner, p_lo, p_hi, p_z = _paved_chunks(roads)
    tree = shapely.STRtree(polys)
    pi, ci = tree.query(shapely.points(xyz[:, :2]), predicate="intersects")
    same = p_owner[ci] == own[pi]
    near = (s_own[pi] >= p_lo[ci] - 1.0) & (s_own[pi] <= p_hi[ci] + 1.0)
    level = np.abs(xyz[pi, 2] - p_z[ci]) <= SAME_LEVEL_M
    hides = ~(same & near) & level
    inside = np.zeros(xyz.shape[0], bool)
    inside[pi[hides]] = True
    return xyz[~inside], normal[~inside], station[~inside]


def edge_sides(xyz: FloatArray, station: FloatArray, true: Poses) -> NDArray[np.uint8]:
    """Side codes (left/right of the observing pose's heading) of edge points."""
    idx = observing_frame(station, xyz, true, cKDTree(true.xyz[:, :2]))
    d = xyz[:, :2] - true.xyz[idx, :2]
    ego_y = -np.sin(true.yaw[idx]) * d[:, 0] + np.cos(true.yaw[idx]) * d[:, 1]
    return np.where(ego_y > 0.0, SIDE_LEFT, SIDE_RIGHT).astype(np.uint8)


# ---------------------------------------------------------------------------
# paint
# ---------------------------------------------------------------------------


def _aux_borders(truth: RouteTruth, road: Road, k: int) -> set[int]:
    """Border indices of lane section k of the whole mainline that touch an aux lane."""
    if road is not truth.mainline:
        return set()
    sec = road.lane_sections[k]
    lanes = sec.right or sec.left
    out: set[int] = set()
    for j, lane in enumerate(lanes):
        if truth.mainline_fit.section_keys[k][j] in truth.aux_keys:
            out.add(lane.id)  # its outer border
            out.add(lanes[j - 1].id if j > 0 else 0)  # its median-side border
    return out


def _worn(s: FloatArray, a: float, b: float, style: MarkingStyle, rng) -> NDArray[np.bool_]:
    """Mask of samples in random worn stretches of a painted line over ``[a, b)``."""
    lo, hi = style.worn_length_m
    n = rng.poisson(style.worn_fraction * (b - a) / (0.5 * (lo + hi)))
    worn = np.zeros(s.size, bool)
    if n == 0:
        return worn
    starts = rng.uniform(a, b, n)
    lengths = rng.uniform(lo, hi, n)
    for x0, length in zip(starts, lengths, strict=True):
        worn |= (s >= x0) & (s < x0 + length)
    return worn


def painted_points(
    truth: RouteTruth, style: MarkingStyle, spacing_m: float, rng: np.random.Generator
) -> tuple[FloatArray, FloatArray, dict[str, float]]:
    """Paint points of every painted lane border of the true roads: ``xyz (N, 3)``, the
    mainline station of each (NaN on ramps) and painted / worn lengths (metres)."""
    pts, stations = [], []
    painted_m = worn_m = 0.0
    for road, is_main in _truth_roads(truth):
        for k, sec in enumerate(road.lane_sections):
            s1 = road.section_end(k)
            aux = _aux_borders(truth, road, k)
            borders = [(0, sec.center.road_marks)]
            borders += [(ln.id, ln.road_marks) for ln in (sec.right or sec.left)]
            for border, marks in borders:
                for i, mark in enumerate(marks):
                    kinds = PAINTED.get(mark.type)
                    a = sec.s0 + mark.s_offset
                    b = sec.s0 + marks[i + 1].s_offset if i + 1 < len(marks) else s1
                    if kinds is None or b - a < spacing_m:
                        continue
                    half = 0.5 * (max(mark.width_m, 0.1) + style.double_gap_m)
                    offsets = (0.0,) if len(kinds) == 1 else (half, -half)
                    for kind, dt in zip(kinds, offsets, strict=True):
                        s = np.arange(a, b, spacing_m)
                        s = s + rng.uniform(0.0, spacing_m, s.size)
                        s = s[s < b]
                        pattern = dash_pattern(kind, style, aux=border in aux)
                        if pattern is not None:
                            s = s[np.mod(s, pattern[0] + pattern[1]) < pattern[0]]
                        worn = _worn(s, a, b, style, rng)
                        painted_m += s.size * spacing_m
                        worn_m += float(worn.sum()) * spacing_m
                        s = s[~worn]
                        if s.size == 0:
                            continue
                        t = road.lane_border_t(s, border) + dt
                        xy = road.to_xy(s, t)
                        pts.append(np.column_stack([xy, road.surface_height(s, t)]))
                        stations.append(s if is_main else np.full(s.size, np.nan))
    if not pts:
        return np.zeros((0, 3)), np.zeros(0), {"painted_m": 0.0, "worn_m": 0.0}
    counts = {"painted_m": round(painted_m, 1), "worn_m": round(worn_m, 1)}
    return np.vstack(pts), np.concatenate(stations), counts


def opposite_painted_points(
    network: RoadNetwork,
    truth: RouteTruth,
    style: MarkingStyle,
    spacing_m: float,
    rng: np.random.Generator,
    *,
    lateral_m: float = 40.0,
) -> FloatArray:
    """Paint points ``(N, 3)`` of the source map's lanes whose traffic runs against the
    route (heading more than 120 degrees off the mainline's) within ``lateral_m`` of it:
    the opposite carriageway. These lanes are not part of the truth (station NaN)."""
    side_travel = {-1: 1, 1: -1} if truth.traffic_side == "right" else {-1: -1, 1: 1}
    main = truth.mainline
    out = []
    for road in network.roads:
        if road.junction != "-1":
            continue
        for k, sec in enumerate(road.lane_sections):
            s1 = road.section_end(k)
            for sign, lanes in ((-1, sec.right), (1, sec.left)):
                if not any(ln.type in TRAFFIC_LANE_TYPES for ln in lanes):
                    continue
                for lane in lanes:
                    for i, mark in enumerate(lane.road_marks):
                        kinds = PAINTED.get(mark.type)
                        a = sec.s0 + mark.s_offset
                        b = (
                            sec.s0 + lane.road_marks[i + 1].s_offset
                            if i + 1 < len(lane.road_marks)
                            else s1
                        )
                        if kinds is None or b - a < spacing_m:
                            continue
                        s = np.arange(a, b, spacing_m) + rng.uniform(0.0, spacing_m)
                        s = s[s < b]
                        pattern = dash_pattern(kinds[0], style, aux=False)
                        if pattern is not None:
                            s = s[np.mod(s, pattern[0] + pattern[1]) < pattern[0]]
                        if s.size == 0:
                            continue
                        t_border = road.lane_border_t(s, lane.id)
                        xy = road.to_xy(s, t_border)
                        heading = road.heading(s) + (0.0 if side_travel[sign] > 0 else np.pi)
                        u, t = main.project(xy)
                        against = np.cos(heading - main.heading(u)) < -0.5
                        keep = against & (np.abs(t) <= lateral_m) & (u > 0.0) & (u < main.length)
                        if np.any(keep):
                            z = road.surface_height(s[keep], t_border[keep])
                            out.append(np.column_stack([xy[keep], z]))
    return np.vstack(out) if out else np.zeros((0, 3))
