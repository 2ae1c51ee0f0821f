"""The poses' heading error read from near and far lane samples of the same lines.

A straight road along x with lines at y = 0, 3.5 and 7 m, seen from poses every 1 m
(25 m/s) 3-30 m ahead; the poses' yaw is off by +1.5 mrad over the first 40 s and by
-1.0 mrad after (a slow heading error of an inertial system, 0.09 / 0.06 degrees).
Far samples lie 4.5 cm aside; fitted from all ranges, every line lies 2.5 cm off.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from roadtwin.frames import MappingFrame, Origin
from roadtwin.heading_bias import estimate_heading_bias, remove_heading_bias
from roadtwin.io import MappingRun, Trajectory

LINES_M = (0.0, 3.5, 7.0)


def _run(psi_first: float, psi_after: float, *, one_frame: bool = False) -> MappingRun:
    rng = np.random.default_rng(7)
    x_pose = np.arange(0.0, 2000.0, 1.0)
    t = x_pose / 25.0
    psi = np.where(t < 40.0, psi_first, psi_after)
    frames, pts = [], []
    ahead = np.arange(3.0, 30.0, 1.5)
    for i, x0 in enumerate(x_pose[:-30]):
        for y_line in LINES_M:
            # the marking ahead in the true ego frame (pose on y = 1.75, heading +x)
            ex, ey = ahead, np.full(ahead.size, y_line - 1.75)
            # placed with the measured yaw psi: turned by psi about the pose
            c, s = np.cos(psi[i]), np.sin(psi[i])
            pts.append(np.column_stack([x0 + ex * c - ey * s, 1.75 + ex * s + ey * c]))
            frames.append(np.full(ahead.size, i))
    lanes = np.vstack(pts)
    lanes = lanes + rng.normal(0.0, 0.03, lanes.shape)
    n = x_pose.size
    trajectory = Trajectory(
        frame=np.arange(n, dtype=np.int64),
        t=t,
        xyz=np.column_stack([x_pose, np.full(n, 1.75), np.zeros(n)]),
        yaw=psi.copy(),  # the measured yaw: the true heading (0) plus the error
        pitch=np.zeros(n),
        roll=np.zeros(n),
    )
    frame_of = np.concatenate(frames)
    return MappingRun(
        root=Path("."),
        frame=MappingFrame(Origin(47.0, 15.0, 300.0)),
        trajectory=trajectory,
        pose_height_m=0.0,
        edges=np.zeros((0, 3)),
        edge_side=np.zeros(0, np.int8),
        lane_samples=np.column_stack([lanes, np.zeros(lanes.shape[0])]),
        lane_sample_frame=np.zeros_like(frame_of) if one_frame else frame_of,
        osm_path=None,
    )


def _line_offsets(run: MappingRun) -> np.ndarray:
    """Mean lateral offset (metres) of each line's samples from where it truly is."""
    y = run.lane_samples[:, 1]
    nearest = np.array(LINES_M)[np.argmin(np.abs(y[:, None] - np.array(LINES_M)), axis=1)]
    return np.array([np.mean((y - nearest)[nearest == v]) for v in LINES_M])


def test_the_heading_error_is_read_from_the_range_spread_of_each_lines_samples():
    run = _run(1.5e-3, -1.0e-3)
    bias = estimate_heading_bias(run)
    assert bias is not None
    t = run.trajectory.t
    # away from the change (smoothed over 5 s) within 0.15 mrad
    assert np.max(np.abs(bias.rad[t < 30.0] - 1.5e-3)) < 1.5e-4
    assert np.max(np.abs(bias.rad[(t > 50.0) & (t < 75.0)] + 1.0e-3)) < 1.5e-4


def test_removing_it_puts_the_lines_back_and_far_samples_beside_near_ones():
    run = _run(1.5e-3, 1.5e-3)
    before = _line_offsets(run)
    assert np.all(before > 0.02)  # 1.5 mrad at 16 m on average
    fixed = remove_heading_bias(run)
    assert fixed.heading_bias_removed
    assert np.max(np.abs(_line_offsets(fixed))) < 0.003
    # heights, frames and the poses are untouched
    assert np.array_equal(fixed.lane_samples[:, 2], run.lane_samples[:, 2])
    assert fixed.trajectory is run.trajectory
    # done once: a second call leaves the run as it is
    assert remove_heading_bias(fixed) is fixed


def test_no_error_is_read_where_there_is_none_or_the_frames_did_not_see_the_samples():
    bias = estimate_heading_bias(_run(0.0, 0.0))
    assert bias is not None
    assert bias.max_abs_deg < 0.01
    # one frame for all samples (a run made in memory): kilometres of "range"
    one = _run(1.5e-3, 1.5e-3, one_frame=True)
    assert estimate_heading_bias(one) is None
    assert remove_heading_bias(one).lane_samples is one.lane_samples


@pytest.mark.parametrize("psi", [2.0e-3, -2.0e-3])
def test_the_sign_follows_the_error(psi):
    bias = estimate_heading_bias(_run(psi, psi))
    assert bias is not None
    assert float(np.median(bias.rad)) == pytest.approx(psi, abs=1.5e-4)


def test_it_is_asked_for_in_the_mainline_config():
    from roadtwin.config import MainlineConfig, PipelineConfig

    assert MainlineConfig().heading_bias is False
    cfg = PipelineConfig.from_dict({"mainline": {"heading_bias": True}}, source="test")
    assert cfg.mainline.heading_bias is True
