"""The mapping car: true and measured poses, road-edge points and lane-marking samples.

Frames: poses and road-edge points are in the mapping frame (metres, yaw radians CCW
from +x). Lane samples are in the ego frame of their LiDAR frame (x forward along the
yaw, y left, z up; level), measured relative to the TRUE vehicle pose, as a sensor sees
them; the run records the MEASURED pose for that frame, so a consumer that places the
samples with the recorded poses inherits the GNSS/INS error, exactly as in a real run.
Road-edge points were placed by the (simulated) extraction pipeline with the measured
poses, so they carry the pose error plus the sensor noise.

Everything is vectorised over points; loops run over marking lines, ramps and truck
occlusion events only. All randomness comes from one ``numpy.random.Generator``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal import lfilter
from scipy.spatial import cKDTree

from ..model import Road
from .scenario import Noise, Sensor
from .truth import Truth, marking_lines, outer_edge_id

SIDE_LEFT = 1
SIDE_RIGHT = 2
"""Integer side codes of road-edge points (LAS/PLY/NPY ``side``: 1 left, 2 right)."""


@dataclass(frozen=True)
class Poses:
    """Vehicle poses, one per frame: mapping frame, metres, radians.

    ``station`` is the mainline station of each pose (metres).
    """

    frame: NDArray[np.int64]
    t: NDArray[np.float64]
    xyz: NDArray[np.float64]
    yaw: NDArray[np.float64]
    station: NDArray[np.float64]


def true_poses(truth: Truth) -> Poses:
    """Noise-free poses of the car driving the centre of its lane at constant speed."""
    sc = truth.scenario
    speed = sc.car.speed_kmh / 3.6
    step = speed / sc.car.rate_hz
    s = np.arange(0.0, truth.mainline.length - 1e-6, step)
    ln = sc.lanes
    t_car = truth.sign * (ln.inner_shoulder_m + (sc.car_lane - 0.5) * ln.width_m)
    xy = truth.mainline.to_xy(s, np.full_like(s, t_car))
    z = truth.mainline.elevation.value(s)
    yaw = truth.mainline.heading(s)
    frame = np.arange(s.size, dtype=np.int64)
    t = sc.car.t0_s + frame / sc.car.rate_hz
    return Poses(frame, t, np.column_stack([xy, z]), yaw, s)


def _gauss_markov(rng: np.random.Generator, n: int, std: float, corr_steps: float) -> NDArray:
    """Stationary first-order Gauss-Markov sequence (smooth drift) of length n."""
    if std <= 0.0:
        return np.zeros(n)
    a = float(np.exp(-1.0 / max(corr_steps, 1e-9)))
    e = rng.standard_normal(n + 1)
    b = std * np.sqrt(1.0 - a * a)
    out, _ = lfilter([b], [1.0, -a], e[1:], zi=[a * std * e[0]])
    return out


def measured_poses(poses: Poses, truth: Truth, rng: np.random.Generator) -> Poses:
    """Poses with GNSS/INS errors: correlated drift plus white jitter (scenario [noise])."""
    return noisy_poses(poses, truth.scenario.noise, truth.scenario.car.rate_hz, rng)


def noisy_poses(poses: Poses, noise: Noise, rate_hz: float, rng: np.random.Generator) -> Poses:
    """Poses with GNSS/INS errors ``noise`` at a pose rate of ``rate_hz`` (Gauss-Markov
    drift of position, height and yaw plus white position jitter)."""
    n = poses.frame.size
    corr = noise.correlation_s * rate_hz
    err = np.column_stack(
        [
            _gauss_markov(rng, n, noise.position_std_m, corr),
            _gauss_markov(rng, n, noise.position_std_m, corr),
            _gauss_markov(rng, n, noise.height_std_m, corr),
        ]
    )
    err += rng.normal(0.0, noise.jitter_m, size=(n, 3)) if noise.jitter_m > 0 else 0.0
    yaw_err = _gauss_markov(rng, n, np.radians(noise.yaw_std_deg), corr)
    return Poses(poses.frame, poses.t, poses.xyz + err, poses.yaw + yaw_err, poses.station)


def _to_measured(pts: NDArray, frame_idx: NDArray, true: Poses, meas: Poses) -> NDArray:
    """Re-place mapping-frame points seen from the true pose with the measured pose."""
    d = pts - true.xyz[frame_idx]
    dyaw = meas.yaw[frame_idx] - true.yaw[frame_idx]
    c, s = np.cos(dyaw), np.sin(dyaw)
    out = np.empty_like(pts)
    out[:, 0] = c * d[:, 0] - s * d[:, 1]
    out[:, 1] = s * d[:, 0] + c * d[:, 1]
    out[:, 2] = d[:, 2]
    return out + meas.xyz[frame_idx]


def _edge_curve(road: Road, s: NDArray, t: NDArray) -> tuple[NDArray, NDArray]:
    xy = road.to_xy(s, t)
    return np.column_stack([xy, road.elevation.value(s)]), road.heading(s)


def true_edges(truth: Truth, spacing_m: float, rng: np.random.Generator):
    """Dense points on the true road edges of the driven carriageway and its ramps.

    Returns ``xyz (N, 3)``, ``side`` codes, outward unit normals ``(N, 2)`` and the
    mainline station used to pick the observing frame (NaN for ramp points).
    """
    sign = truth.sign
    road = truth.mainline
    s = np.arange(0.0, road.length, spacing_m)
    s = np.clip(s + rng.uniform(0.0, spacing_m, s.size), 0.0, road.length)
    parts = []
    # median-side edge: the reference line; outer edge: border of the outermost lane
    inner_side = SIDE_LEFT if sign < 0 else SIDE_RIGHT
    outer_side = SIDE_RIGHT if sign < 0 else SIDE_LEFT
    outer_t = np.empty_like(s)
    ids = outer_edge_id(truth.sections, s, sign)
    for lane_id in np.unique(ids):
        sel = ids == lane_id
        outer_t[sel] = road.lane_border_t(s[sel], int(lane_id))
    for t, side, out_dir in ((np.zeros_like(s), inner_side, -sign), (outer_t, outer_side, sign)):
        xyz, h = _edge_curve(road, s, t)
        normal = out_dir * np.column_stack([-np.sin(h), np.cos(h)])
        parts.append((xyz, np.full(s.size, side, np.uint8), normal, s))
    for rt in truth.ramps:
        r = rt.road
        rs = np.arange(0.0, r.length, spacing_m)
        n_lanes = len(rt.sections[0].lanes)
        t = r.lane_border_t(rs, int(sign * n_lanes))
        xyz, h = _edge_curve(r, rs, t)
        normal = sign * np.column_stack([-np.sin(h), np.cos(h)])
        parts.append(
            (xyz, np.full(rs.size, outer_side, np.uint8), normal, np.full(rs.size, np.nan))
        )
    xyz = np.vstack([p[0] for p in parts])
    side = np.concatenate([p[1] for p in parts])
    normal = np.vstack([p[2] for p in parts])
    station = np.concatenate([p[3] for p in parts])
    return xyz, side, normal, station


def observing_frame(
    station: NDArray, xyz: NDArray, true: Poses, tree: cKDTree
) -> NDArray[np.int64]:
    """Frame whose true pose is nearest: by station on the mainline, by distance elsewhere."""
    step = true.station[1] - true.station[0] if true.station.size > 1 else 1.0
    idx = np.empty(station.size, np.int64)
    on_main = np.isfinite(station)
    idx[on_main] = np.clip(np.rint(station[on_main] / step), 0, true.frame.size - 1)
    if (~on_main).any():
        _, idx[~on_main] = tree.query(xyz[~on_main, :2])
    return idx


def edge_points(
    truth: Truth, true: Poses, meas: Poses, rng: np.random.Generator
) -> tuple[NDArray[np.float64], NDArray[np.uint8], dict[str, int]]:
    """Extracted road-edge points of the driven carriageway (mapping frame).

    Returns ``xyz (N, 3)``, ``side`` (1 left, 2 right) and counts of what was removed or
    corrupted (out of range, dropouts, occluded, outliers), sorted by frame.
    """
    sensor = truth.scenario.sensor
    xyz, side, normal, station = true_edges(truth, sensor.edge_spacing_m, rng)
    return observe_edges(
        xyz, side, normal, station, true, meas, sensor, rng, length_m=truth.mainline.length
    )


def observe_edges(
    xyz: NDArray,
    side: NDArray,
    normal: NDArray,
    station: NDArray,
    true: Poses,
    meas: Poses,
    sensor: Sensor,
    rng: np.random.Generator,
    *,
    length_m: float,
) -> tuple[NDArray[np.float64], NDArray[np.uint8], dict[str, int]]:
    """The extraction pipeline's view of true road-edge points.

    Parameters
    ----------
    xyz, side, normal, station
        True edge points ``(N, 3)`` (mapping frame), side codes, outward unit normals
        ``(N, 2)`` and the mainline station of each point (NaN off the mainline: the
        observing frame is then the nearest pose).
    true, meas
        True and measured poses (stations uniformly spaced from 0).
    length_m
        Mainline length (metres), for the number of trucks.

    Returns
    -------
    Measured points ``(M, 3)`` and side codes sorted by frame, and counts of what was
    out of range, dropped, occluded by trucks or turned into outliers.
    """
    tree = cKDTree(true.xyz[:, :2])
    frame_idx = observing_frame(station, xyz, true, tree)
    dist = np.hypot(*(xyz[:, :2] - true.xyz[frame_idx, :2]).T)
    keep = dist <= sensor.edge_range_m
    counts = {"out_of_range": int((~keep).sum())}
    drop = rng.random(side.size) < sensor.edge_dropout
    counts["dropouts"] = int((drop & keep).sum())
    keep &= ~drop
    # trucks passing on one side hide that side's edge for a few seconds
    duration = float(true.t[-1] - true.t[0]) if true.t.size > 1 else 0.0
    n_trucks = rng.poisson(sensor.trucks_per_km * length_m / 1000.0)
    starts = rng.uniform(true.t[0], true.t[0] + duration, n_trucks)
    lengths = rng.uniform(*sensor.truck_duration_s, n_trucks)
    sides = rng.choice(np.array([SIDE_LEFT, SIDE_RIGHT], np.uint8), n_trucks)
    occluded = np.zeros(side.size, bool)
    t_pt = true.t[frame_idx]
    for t0, dt, sd in zip(starts, lengths, sides, strict=False):
        occluded |= (t_pt >= t0) & (t_pt < t0 + dt) & (side == sd)
    counts["occluded"] = int((occluded & keep).sum())
    counts["truck_events"] = int(n_trucks)
    keep &= ~occluded
    xyz, side, normal, frame_idx = xyz[keep], side[keep], normal[keep], frame_idx[keep]
    station = station[keep]
    # outliers: guardrail posts, vegetation, kerbs outside the edge
    outlier = rng.random(side.size) < sensor.outlier_fraction
    n_out = int(outlier.sum())
    offset = rng.uniform(*sensor.outlier_offset_m, n_out)
    xyz = xyz.copy()
    xyz[outlier, :2] += normal[outlier] * offset[:, None]
    xyz[outlier, 2] += rng.uniform(0.0, 1.0, n_out)
    counts["outliers"] = n_out
    meas_xyz = _to_measured(xyz, frame_idx, true, meas)
    meas_xyz[:, :2] += rng.normal(0.0, sensor.edge_noise_m, size=(side.size, 2))
    meas_xyz[:, 2] += rng.normal(0.0, sensor.edge_height_noise_m, size=side.size)
    order = np.lexsort((np.nan_to_num(station, nan=np.inf), side, frame_idx))
    return meas_xyz[order], side[order], counts


def _paint_mask(s: NDArray, style: str, truth: Truth) -> NDArray[np.bool_]:
    m = truth.scenario.markings
    if style == "solid":
        return np.ones(s.size, bool)
    dash, gap = (m.dash_m, m.gap_m) if style == "lane" else (m.aux_dash_m, m.aux_gap_m)
    return np.mod(s, dash + gap) < dash


def painted_points(truth: Truth, spacing_m: float, rng: np.random.Generator):
    """True lane-marking paint: ``xyz (N, 3)`` (mapping frame) and the mainline station
    of each point (NaN on ramps), only where paint is."""
    pts, stations = [], []
    for line in marking_lines(truth):
        if line.style == "none" or line.s1 - line.s0 < spacing_m:
            continue
        s = np.arange(line.s0, line.s1, spacing_m)
        s = s + rng.uniform(0.0, spacing_m, s.size)
        s = s[(s < line.s1) & _paint_mask(s + line.phase_m, line.style, truth)]
        if s.size == 0:
            continue
        t = line.road.lane_border_t(s, line.lane_id)
        xy = line.road.to_xy(s, t)
        pts.append(np.column_stack([xy, line.road.elevation.value(s)]))
        on_main = line.road is truth.mainline
        stations.append(s if on_main else np.full(s.size, np.nan))
    return np.vstack(pts), np.concatenate(stations)


def lane_samples(
    truth: Truth, true: Poses, rng: np.random.Generator
) -> tuple[NDArray[np.int64], NDArray[np.float64], dict[str, int]]:
    """Lane-marking samples per frame in the ego frame (relative to the TRUE pose).

    Returns the frame index of each sample, ``(M, 3)`` ego coordinates (x forward, y left,
    z up, metres) and counts; sorted by frame, then x.
    """
    sensor = truth.scenario.sensor
    xyz, station = painted_points(truth, sensor.lane_spacing_m, rng)
    return observe_markings(xyz, station, true, sensor, rng)


def observe_markings(
    xyz: NDArray, station: NDArray, true: Poses, sensor: Sensor, rng: np.random.Generator
) -> tuple[NDArray[np.int64], NDArray[np.float64], dict[str, int]]:
    """The lane-marking detector's view of true paint points.

    ``xyz`` (N, 3) are paint points (mapping frame) and ``station`` their mainline
    station (NaN off the mainline). Each point is seen from a frame a random look-ahead
    (``sensor.lane_range_m``) before it, within the lateral range, unless missed; noise and
    false positives are added. Returns the frame index of each sample, ``(M, 3)`` ego
    coordinates (relative to the TRUE pose) and counts, sorted by frame, then x.
    """
    tree = cKDTree(true.xyz[:, :2])
    nearest = observing_frame(station, xyz, true, tree)
    step = true.station[1] - true.station[0] if true.station.size > 1 else 1.0
    lo, hi = sensor.lane_range_m
    look = rng.uniform(lo, hi, station.size)
    k = nearest - np.rint(look / step).astype(np.int64)
    valid = k >= 0
    k = np.clip(k, 0, true.frame.size - 1)
    d = xyz - true.xyz[k]
    c, s = np.cos(true.yaw[k]), np.sin(true.yaw[k])
    ego = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])
    valid &= (ego[:, 0] >= lo - step) & (ego[:, 0] <= hi + step)
    valid &= np.abs(ego[:, 1]) <= sensor.lane_lateral_range_m
    counts = {"painted_not_seen": int((~valid).sum())}
    miss = rng.random(station.size) < sensor.lane_miss
    counts["missed"] = int((miss & valid).sum())
    valid &= ~miss
    ego, k = ego[valid], k[valid]
    ego += rng.normal(0.0, sensor.lane_noise_m, size=ego.shape)
    n_fp = int(rng.binomial(ego.shape[0], sensor.lane_false_positive)) if ego.shape[0] else 0
    fp = np.column_stack(
        [
            rng.uniform(lo, hi, n_fp),
            rng.uniform(-sensor.lane_lateral_range_m, sensor.lane_lateral_range_m, n_fp),
            rng.normal(0.0, sensor.lane_noise_m, n_fp),
        ]
    )
    fp_frame = rng.integers(0, true.frame.size, n_fp)
    counts["false_positives"] = n_fp
    frames = np.concatenate([true.frame[k], true.frame[fp_frame]])
    ego = np.vstack([ego, fp])
    order = np.lexsort((ego[:, 0], frames))
    return frames[order], ego[order], counts
