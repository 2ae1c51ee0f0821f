"""The heading error of the poses, seen in the lane samples, and removed from them.

A lane marking is sampled from every frame that sees it, 3-30 m ahead. A pose whose
heading is off by a small angle ``psi`` (radians) places every sample of its frame
``psi * x`` to the side, ``x`` metres ahead: the same line seen far ahead lies beside
where it lies seen near. An inertial system's heading error drifts slowly (tens of
seconds), so the lines fitted from all ranges carry its mean lever arm (about 16 m):
1-3 cm on every lane border of the real-layout benchmark's runs (a heading error of
0.05-0.1 degrees). The offset between near and far samples of the same line says how
large it is at each moment: per time window, the samples' lateral offsets from their
line's local median against their forward range have slope ``psi``
(:func:`estimate_heading_bias`); each sample is turned back by it about its pose
(:func:`remove_heading_bias`). A lateral error of the pose position moves near and far
samples alike: it stays (no run can see it).

Frames: samples and poses in the mapping frame (metres, yaw counter-clockwise from +x);
the ego frame of a pose has x forward, y to the left (DESIGN.md section 3).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from .fitting import PolylineFrame, project_to_polyline, resample_polyline

FloatArray = NDArray[np.float64]

log = logging.getLogger(__name__)

__all__ = ["HeadingBias", "estimate_heading_bias", "remove_heading_bias"]

_BIN_M = 2.0  # samples of one line within this station bin share its local median ...
_SPLIT_M = 0.4  # ... lines are told apart by a lateral gap wider than this (metres)
_INLIER_M = 0.25  # a sample farther than this from its line's median is left out (metres)
_WINDOW_S = 10.0  # the heading error is estimated over windows this long (seconds) ...
_SMOOTH_S = 5.0  # ... smoothed with a Gaussian of this sigma (seconds)
_PRIOR_M2 = 2000.0  # sum of squared range spreads (m^2) that weighs like no error
_MIN_SPREAD_M2 = 20000.0  # a run with less range spread in its samples is left alone
_VIEW_M = 80.0  # samples farther than this from their pose were not seen from it (metres)
_IN_VIEW_SHARE = 0.9  # ... and if fewer than this share are nearer, the frames are not theirs
_MAX_RAD = 0.01  # a larger estimated error is no heading error (radians, 0.57 degrees)


@dataclass(frozen=True)
class HeadingBias:
    """The poses' heading error as seen in the lane samples.

    Attributes
    ----------
    t : (N,) pose times (seconds, the trajectory's).
    rad : (N,) heading error per pose (radians; positive: the pose's yaw is
        counter-clockwise of the true heading, samples ahead lie to the left).
    """

    t: FloatArray
    rad: FloatArray

    @property
    def max_abs_deg(self) -> float:
        """Largest error along the run (degrees)."""
        return float(np.degrees(np.max(np.abs(self.rad)))) if self.rad.size else 0.0


def _ego(run, pose: NDArray[np.int64]) -> tuple[FloatArray, FloatArray]:
    """Forward and leftward ego coordinates (metres) of every lane sample."""
    tr = run.trajectory
    d = run.lane_samples[:, :2] - tr.xy[pose]
    c, s = np.cos(tr.yaw[pose]), np.sin(tr.yaw[pose])
    return d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c


def _in_view(x: FloatArray, y: FloatArray) -> NDArray[np.bool_]:
    """Samples where a lane camera or scanner sees markings from its pose (ego metres)."""
    return (x > -_VIEW_M) & (x < _VIEW_M) & (np.abs(y) < _VIEW_M)


def _too_few(run) -> bool:
    """Too few lane samples or poses to read a heading error from."""
    return run.lane_samples.shape[0] < 100 or run.trajectory.frame.size < 10


def _pose_index(run) -> NDArray[np.int64]:
    """Index into the trajectory of every lane sample's frame."""
    frames = run.trajectory.frame
    order = np.argsort(frames)
    pos = np.clip(np.searchsorted(frames[order], run.lane_sample_frame), 0, frames.size - 1)
    return order[pos]


def _line_residuals(s: FloatArray, t: FloatArray) -> tuple[FloatArray, NDArray[np.int64]]:
    """Each sample's lateral offset from the median of its line in its station bin
    (``s``, ``t``: metres along and left of the trajectory) and the line's group id."""
    b = np.floor(s / _BIN_M).astype(np.int64)
    order = np.lexsort((t, b))
    bs, ts = b[order], t[order]
    new = np.ones(order.size, dtype=bool)
    new[1:] = (bs[1:] != bs[:-1]) | (np.diff(ts) > _SPLIT_M)
    group_sorted = np.cumsum(new) - 1
    group = np.empty_like(group_sorted)
    group[order] = group_sorted
    # medians per group: samples are sorted by t within each group already
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, order.size))
    mid_lo = ts[starts + (counts - 1) // 2]
    mid_hi = ts[starts + counts // 2]
    median = 0.5 * (mid_lo + mid_hi)
    return t - median[group], group


@dataclass(frozen=True)
class _SampleView:
    """Each lane sample's pose (index into the trajectory), its ego coordinates (metres:
    forward, left) and whether its pose could have seen it (:func:`_in_view`)."""

    pose: NDArray[np.int64]
    x: FloatArray
    y: FloatArray
    near: NDArray[np.bool_]

    @classmethod
    def of(cls, run) -> _SampleView:
        pose = _pose_index(run)
        x, y = _ego(run, pose)
        return cls(pose, x, y, _in_view(x, y))


def estimate_heading_bias(run) -> HeadingBias | None:
    """The heading error of every pose of ``run`` (:class:`~roadtwin.io.MappingRun`) from
    its lane samples; None where the samples cannot tell (too few, or too little spread
    in range).

    Per window of ``_WINDOW_S`` the slope of the samples' offsets from their lines'
    local medians against their forward range (each line's mean range subtracted), shrunk
    towards 0 by ``_PRIOR_M2``, then smoothed along time.
    """
    return None if _too_few(run) else _estimate(run, _SampleView.of(run))


def _estimate(run, view: _SampleView) -> HeadingBias | None:
    """:func:`estimate_heading_bias` with the samples' poses and ego coordinates given."""
    tr = run.trajectory
    pose, x, near = view.pose, view.x, view.near
    if np.mean(near) < _IN_VIEW_SHARE:
        # samples placed by frames that did not see them (a run made in memory with one
        # frame for all): no lever arm to read
        return None
    path = resample_polyline(tr.xy, 1.0)
    if path.shape[0] < 3:
        return None
    s, t = project_to_polyline(PolylineFrame.from_points(path), run.lane_samples[:, :2])
    r, group = _line_residuals(s, t)
    ok = (np.abs(r) < _INLIER_M) & near
    # the line's mean range: the lever arm its median carries
    n_g = int(group.max()) + 1
    cnt = np.bincount(group[ok], minlength=n_g)
    mean_x = np.bincount(group[ok], weights=x[ok], minlength=n_g) / np.maximum(cnt, 1)
    dx = x - mean_x[group]
    ok &= cnt[group] >= 3
    if float(np.sum(dx[ok] ** 2)) < _MIN_SPREAD_M2:
        return None
    t_pose = tr.t - tr.t[0]
    w = np.floor(t_pose[pose] / _WINDOW_S).astype(np.int64)
    n_w = int(np.floor(t_pose[-1] / _WINDOW_S)) + 1
    sxy = np.bincount(w[ok], weights=(r * dx)[ok], minlength=n_w)
    sxx = np.bincount(w[ok], weights=(dx * dx)[ok], minlength=n_w)
    psi_w = sxy / (sxx + _PRIOR_M2)
    weight_w = sxx / (sxx + _PRIOR_M2)
    centre = (np.arange(n_w) + 0.5) * _WINDOW_S
    # a Gaussian-weighted mean of the windows' estimates at every pose
    k = np.exp(-0.5 * ((t_pose[:, None] - centre[None, :]) / _SMOOTH_S) ** 2) * weight_w[None, :]
    rad = (k @ psi_w) / np.maximum(k.sum(axis=1), 1e-12)
    if float(np.max(np.abs(rad))) > _MAX_RAD:
        log.warning(
            "heading bias: the lane samples say the poses' heading is off by up to %.2f deg;"
            " that is no slow heading error, left uncorrected",
            float(np.degrees(np.max(np.abs(rad)))),
        )
        return None
    return HeadingBias(tr.t.copy(), rad)


def remove_heading_bias(run, bias: HeadingBias | None = None):
    """``run`` with its lane samples turned back about their poses by the heading error
    (:func:`estimate_heading_bias` unless ``bias`` is given), marked
    ``heading_bias_removed`` (then returned as it is: fused runs of a highway were turned
    back one by one before). Heights are kept."""
    if run.heading_bias_removed:
        return run
    if bias is None and _too_few(run):
        return replace(run, heading_bias_removed=True)
    view = _SampleView.of(run)
    bias = _estimate(run, view) if bias is None else bias
    if bias is None:
        return replace(run, heading_bias_removed=True)
    pose, x, y = view.pose, view.x, view.y
    tr = run.trajectory
    yaw = tr.yaw[pose] - np.where(view.near, bias.rad[pose], 0.0)
    c, s = np.cos(yaw), np.sin(yaw)
    out = run.lane_samples.copy()
    out[:, 0] = tr.xy[pose, 0] + x * c - y * s
    out[:, 1] = tr.xy[pose, 1] + x * s + y * c
    log.info("heading bias: lane samples turned back by up to %.3f deg", bias.max_abs_deg)
    return replace(run, lane_samples=out, heading_bias_removed=True)
