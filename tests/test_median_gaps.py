"""The median-side edge across an unseen stretch follows the inner shoulder's line.

town06-auto-lane1-s21 (the benchmark's Town06 route with the car in the inner lane, seed
offset 320): the innermost lane is dropped by a taper on the median side at 325-362 m,
and the edge is unseen over 310-365 m. The reference line bridged the gap smoothly from
300 m on, the marking tracks measured from it kinked and lost the dropped lane's line,
the lane ended 2.7 m wide and its lane chain led onto the shoulder (a failed route). The
shoulder's line, seen along the taper, keeps its 1.1 m from the edge on both sides of
the gap, so the edge is carried along it.
"""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.config import MainlineConfig
from roadtwin.fitting import PolylineFrame
from roadtwin.mainline.median_gaps import edge_along_shoulder_line
from roadtwin.mainline.reference import fit_median_edge

RNG_SEED = 42
TAPER = (325.0, 362.0)
UNSEEN = (310.0, 365.0)


def _smoothstep(x: np.ndarray, a: float, b: float, v0: float, v1: float) -> np.ndarray:
    u = np.clip((x - a) / (b - a), 0.0, 1.0)
    return v0 + (v1 - v0) * u * u * (3.0 - 2.0 * u)


def _edge(x: np.ndarray) -> np.ndarray:
    """The median-side edge (metres left of the trajectory): 6.3 m, 2.9 m after the taper."""
    return _smoothstep(x, *TAPER, 6.3, 2.9)


def _samples(rng: np.random.Generator, x: np.ndarray, y: np.ndarray, sd: float) -> np.ndarray:
    return np.column_stack([x, y + rng.normal(0.0, sd, x.size)])


def _scene(*, shoulder_line_seen: bool = True, unseen: tuple[float, float] = UNSEEN):
    """Edge points (unseen in ``unseen``), lane samples and a straight trajectory along x."""
    rng = np.random.default_rng(RNG_SEED)
    x = np.arange(0.0, 700.0, 0.2)
    seen = (x < unseen[0]) | (x > unseen[1])
    edge_pts = _samples(rng, x[seen], _edge(x[seen]), 0.05)
    xl = np.arange(0.0, 700.0, 0.5)
    lines = [
        _samples(rng, xl, np.full(xl.size, 1.7), 0.03),  # the through line
        _samples(rng, xl, np.full(xl.size, -1.8), 0.03),
    ]
    if shoulder_line_seen:
        # the dropped lane's line beside the shoulder: 1.2 m inside the edge, along the
        # taper into the through line
        on = xl < TAPER[1]
        lines.append(_samples(rng, xl[on], _edge(xl[on]) - 1.2, 0.03))
    traj = PolylineFrame.from_points(np.column_stack([np.arange(0.0, 700.5, 1.0), np.zeros(701)]))
    return edge_pts, np.vstack(lines), traj


def _reference_offset(xy: np.ndarray, x: np.ndarray) -> np.ndarray:
    order = np.argsort(xy[:, 0])
    return np.interp(x, xy[order, 0], xy[order, 1])


# the edge seen again after the taper, or 7 m before its end (town06-auto-lane2-s22+800)
@pytest.mark.parametrize("unseen", [UNSEEN, (310.0, 355.0)])
def test_the_reference_line_follows_the_taper_the_shoulder_line_takes(unseen):
    edge_pts, lane_pts, traj = _scene(unseen=unseen)
    x = np.arange(*unseen, 1.0)
    with_line = fit_median_edge(edge_pts, traj, config=MainlineConfig(), lane_pts=lane_pts)
    bridged = fit_median_edge(edge_pts, traj, config=MainlineConfig())
    err_line = _reference_offset(with_line.xy, x) - _edge(x)
    err_bridge = _reference_offset(bridged.xy, x) - _edge(x)
    # the smooth bridge begins its taper where the edge is last seen, 15 m early
    assert np.max(np.abs(err_bridge)) > 0.5
    assert np.sqrt(np.mean(err_line**2)) < 0.1
    assert np.max(np.abs(err_line)) < 0.25
    # seen stretches unchanged: the line only fills the gap
    away = np.r_[np.arange(100.0, 280.0), np.arange(400.0, 600.0)]
    assert np.max(np.abs(_reference_offset(with_line.xy, away) - _edge(away))) < 0.05


def _levels(edge_pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A level path on 2 m bins: the edge points' mean per bin, NaN where unseen."""
    edges = np.arange(0.0, 702.0, 2.0)
    b = np.digitize(edge_pts[:, 0], edges) - 1
    n = np.bincount(b, minlength=edges.size - 1)[: edges.size - 1]
    total = np.bincount(b, edge_pts[:, 1], minlength=edges.size - 1)[: edges.size - 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        level = np.where(n > 0, total / np.maximum(n, 1), np.nan)
    return 0.5 * (edges[1:] + edges[:-1]), level


def test_added_points_lie_on_the_edge_inside_the_gap_only():
    edge_pts, lane_pts, _ = _scene()
    centres, level = _levels(edge_pts)
    s_add, u_add, _ = edge_along_shoulder_line(centres, level, lane_pts[:, 0], lane_pts[:, 1])
    assert s_add.size > 50
    assert np.all((s_add >= UNSEEN[0] - 2.0) & (s_add <= UNSEEN[1] + 2.0))
    err = u_add - _edge(s_add)
    # on the edge but where the line meets the through line (both lines' samples taken)
    assert np.median(np.abs(err)) < 0.03
    assert np.sqrt(np.mean(err**2)) < 0.1


def test_nothing_is_added_without_the_shoulder_line():
    edge_pts, lane_pts, _ = _scene(shoulder_line_seen=False)
    centres, level = _levels(edge_pts)
    s_add, _, _ = edge_along_shoulder_line(centres, level, lane_pts[:, 0], lane_pts[:, 1])
    assert s_add.size == 0


def test_nothing_is_added_where_the_line_goes_where_the_bridge_does():
    # an occlusion of a straight edge: the shoulder's line runs straight through
    rng = np.random.default_rng(RNG_SEED)
    x = np.arange(0.0, 700.0, 0.2)
    seen = (x < UNSEEN[0]) | (x > UNSEEN[1])
    edge_pts = _samples(rng, x[seen], np.full(np.count_nonzero(seen), 6.3), 0.05)
    xl = np.arange(0.0, 700.0, 0.5)
    lane_pts = _samples(rng, xl, np.full(xl.size, 5.2), 0.05)
    centres, level = _levels(edge_pts)
    s_add, _, _ = edge_along_shoulder_line(centres, level, lane_pts[:, 0], lane_pts[:, 1])
    assert s_add.size == 0


@pytest.mark.parametrize("distance_after", [0.4, 2.6])
def test_nothing_is_added_where_the_line_does_not_keep_its_distance(distance_after):
    # after the gap the line nearest inside the edge is 0.4 m or 2.6 m from it (another
    # line, or a lane begun between them): it did not run beside the edge through the gap
    rng = np.random.default_rng(RNG_SEED)
    x = np.arange(0.0, 700.0, 0.2)
    seen = (x < UNSEEN[0]) | (x > UNSEEN[1])
    edge_pts = _samples(rng, x[seen], _edge(x[seen]), 0.05)
    xl = np.arange(0.0, 700.0, 0.5)
    line = _smoothstep(xl, TAPER[0], TAPER[1], 5.2, 2.9 - distance_after)
    lane_pts = _samples(rng, xl, line, 0.03)
    centres, level = _levels(edge_pts)
    s_add, _, _ = edge_along_shoulder_line(centres, level, lane_pts[:, 0], lane_pts[:, 1])
    assert s_add.size == 0
