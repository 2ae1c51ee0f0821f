"""A gore on the median side hidden in an occlusion of the median edge: where the edge's
own line, seen through the gap, leaves the edge's level for the ramp, the step is there.

melbourne-1019-lane1-s21 with a noisier sensor (bench_real, ``--noisy --seed-offset 20``):
the median edge was unseen for 156 m across an inner exit whose lane leaves at full width
(a 4.1 m step); the step was bridged as a taper over the whole gap, the reference line cut
across the exiting lane and the edge was 3 m off (edge 0.41 m, lanes 0.40 m RMSE). The
line 0.9 m inside the edge was seen holding its course up to the gore (602 m) and
bending away with the ramp after it."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.config import MainlineConfig
from roadtwin.mainline.edge_levels import edge_level_path, edge_steps
from roadtwin.mainline.gap_evidence import edge_line_departure

GAP = (500.0, 656.0)
GORE_M = 602.0
RADIUS_M = 250.0  # the ramp's line curves away from the gore on this radius


def _samples(
    *, tilt: float = 0.0, leaves: bool = True, seed: int = 3, seen_to: float = 800.0
) -> tuple[np.ndarray, np.ndarray]:
    """Lane samples every 0.5 m (stations, offsets towards the median, metres): the edge's
    line 0.9 m inside an edge at 0 (leaving for the ramp at ``GORE_M`` when ``leaves``)
    and the next line 4.5 m inside, both seen up to ``seen_to``; ``tilt`` (m/m) a frame
    drifting against them; 5 cm noise."""
    rng = np.random.default_rng(seed)
    s = np.arange(300.0, 800.0, 0.5)
    edge_line = np.full(s.size, -0.9)
    if leaves:
        past = np.clip(s - GORE_M, 0.0, None)
        edge_line += past**2 / (2.0 * RADIUS_M)
    s_all = np.concatenate([s, s])
    u_all = np.concatenate([edge_line, np.full(s.size, -4.5)]) + tilt * (s_all - 300.0)
    u_all += rng.normal(0.0, 0.05, s_all.size)
    keep = s_all <= seen_to
    return s_all[keep], u_all[keep]


@pytest.mark.parametrize("tilt", [0.0, 0.004, -0.004])
def test_the_gore_is_where_the_edge_line_leaves(tilt):
    s, u = _samples(tilt=tilt)
    outer = tilt * (GAP[0] - 300.0)  # the edge's level where last seen
    departure = edge_line_departure(s, u, GAP, outer, forward=True)
    assert departure is not None
    # the ramp's line is 0.1 m off 22 m after the gore (and the first bin 0.3 m off its
    # course lies 11 m after it): the bend's start is fitted back to within 4 m
    assert GORE_M - 4.0 <= departure <= GORE_M + 4.0


def test_an_entry_is_walked_back_from_the_gap_end():
    s, u = _samples()
    # mirrored: the entry's line joins at 2 * 578 - 602 = 554 m, walked back from 656 m
    departure = edge_line_departure(1156.0 - s, u, (500.0, 656.0), 0.0, forward=False)
    assert departure is not None
    assert 1156.0 - GORE_M - 4.0 <= departure <= 1156.0 - GORE_M + 4.0


def test_a_line_holding_its_course_gives_no_gore():
    s, u = _samples(leaves=False)
    assert edge_line_departure(s, u, GAP, 0.0, forward=True) is None


def test_a_line_moving_in_with_a_lane_dropped_gives_no_gore():
    """town06-auto-lane2-s22 with a noisier sensor (seed offset 140): the median edge
    tapers in by a lane (325-365 m) inside a gap (318-486 m) and its line with it. In a
    frame bridged straight across the gap the line bends back outward where the taper
    ends (an S), 0.3 m off its course within metres; it never lies beyond where it was
    held (taken for a gore, the step made the lane end at full width: a dead end)."""
    rng = np.random.default_rng(7)
    s = np.arange(250.0, 600.0, 0.5)
    x = np.clip((s - 325.0) / 40.0, 0.0, 1.0)
    world = -0.9 - 3.5 * x * x * (3.0 - 2.0 * x)
    bridge = -3.5 * np.clip((s - 318.0) / 168.0, 0.0, 1.0)
    u = world - bridge + rng.normal(0.0, 0.05, s.size)
    assert edge_line_departure(s, u, (318.0, 486.0), 0.0, forward=True) is None


def test_a_line_lost_before_it_leaves_gives_no_gore():
    s, u = _samples(seen_to=560.0)
    assert edge_line_departure(s, u, GAP, 0.0, forward=True) is None


def test_no_line_near_the_edge_gives_no_gore():
    s, u = _samples()
    far = u < -2.0  # only the line 4.5 m inside the edge
    assert edge_line_departure(s[far], u[far], GAP, 0.0, forward=True) is None


def _edge(gore_seen: bool) -> tuple[np.ndarray, np.ndarray]:
    """Median edge points (stations, offsets, metres): the edge at 0 up to the gap, the
    new edge 4.1 m nearer the carriageway after it, none in the gap."""
    rng = np.random.default_rng(5)
    s = np.arange(300.0, 800.0, 0.25)
    u = np.where(s < GORE_M, 0.0, -4.1) + rng.normal(0.0, 0.04, s.size)
    seen = (s < GAP[0]) | (s > GAP[1]) if not gore_seen else np.ones(s.size, dtype=bool)
    return s[seen], u[seen]


def test_edge_steps_puts_the_hidden_gore_where_the_line_leaves():
    s, u = _edge(gore_seen=False)
    s_l, u_l = _samples()
    edges = np.arange(299.0, 803.0, 2.0)
    cfg = MainlineConfig()
    level = edge_level_path(s, u, edges, config=cfg)
    s_o = np.arange(300.0, 800.0, 0.5)
    other = (s_o, np.full(s_o.size, 12.0))
    without = edge_steps(s, u, edges, level, config=cfg, across=lambda: other)
    # without the lines: a 4.1 m change over 156 m is bridged as a taper, no step
    assert without.stations.size == 0
    steps = edge_steps(
        s, u, edges, level, config=cfg, across=lambda: other, lines=lambda: (s_l, u_l)
    )
    assert steps.stations.size == 1
    assert GORE_M - 4.0 <= steps.stations[0] <= GORE_M + 4.0
    assert steps.offsets[1] - steps.offsets[0] == pytest.approx(-4.1, abs=0.1)
