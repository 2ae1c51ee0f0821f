"""A lane hidden beside a broken outermost line in an occlusion gap of the outer edge
(:mod:`roadtwin.mainline.dashed_lanes`): soderleden-s2 with a noisier sensor, whose
acceleration lane lay wholly inside a 146 m gap, its outer line unpainted."""

from dataclasses import replace

import numpy as np
import pytest

from roadtwin.mainline.dashed_lanes import (
    broken_stretches,
    dashed_lane_gores,
    dashed_lanes_in_gaps,
    widen_beside_dashed,
)
from roadtwin.mainline.markings import _Track

GRID = np.arange(0.0, 601.0, 1.0)
LANE_M = 3.5
LINE_M = 7.0  # the outermost line: the edge line, broken beside the acceleration lane
SOLID_END = 240.0  # the entry's gore: the solid edge line turns broken ...
LANE_END = 340.0  # ... up to the end of the lane's taper
GAP = (212.0, 358.0)  # the outer edge unseen


def _samples(rng: np.random.Generator, *, dashed: bool = True, period: float = 12.0) -> np.ndarray:
    """Stations (metres) of the outermost line's samples, 0.5 m apart with 10 % missed:
    solid to ``SOLID_END``, then 6 m dashes every ``period`` (a gap first) to ``LANE_END``
    (solid if not ``dashed``), none from there to 360 m, solid after."""
    s = np.arange(0.0, 600.0, 0.5)
    keep = s < SOLID_END
    if dashed:
        keep |= (s >= SOLID_END) & (s < LANE_END) & ((s - SOLID_END) % period >= period - 6.0)
    else:
        keep |= (s >= SOLID_END) & (s < LANE_END)
    keep |= s >= 360.0
    keep &= rng.random(s.size) > 0.1
    return s[keep] + rng.normal(0.0, 0.05, np.count_nonzero(keep))


def _line(s_samples: np.ndarray, d: float = LINE_M) -> _Track:
    s = GRID[(s_samples.min() <= GRID) & (s_samples.max() >= GRID)]
    return _Track(
        0,
        float(s[0]),
        float(s[-1]),
        s,
        np.full(s.size, d),
        "broken",
        s_samples.size,
        np.sort(s_samples),
        np.full(s_samples.size, d),
    )


def _covered() -> np.ndarray:
    return ~((GAP[0] < GRID) & (GAP[1] > GRID))


def _ramp_points(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The entry's outer edge coming in from 19 m to 11.5 m before the gap."""
    s = rng.uniform(150.0, 210.0, 200)
    return s, 19.0 - 7.5 * (s - 150.0) / 60.0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_broken_stretch_runs_from_the_solid_line_s_end_to_the_last_dash(seed):
    stretches = broken_stretches(_samples(np.random.default_rng(seed)))
    assert len(stretches) == 1
    lo, hi = stretches[0]
    # the solid line may have run on into the first dash: half a dash before its end
    assert SOLID_END - 4.0 < lo < SOLID_END + 1.0
    assert LANE_END - 8.0 < hi < LANE_END + 1.0  # the last dash ends 6 m into its period


def test_a_solid_line_with_holes_is_no_broken_stretch():
    rng = np.random.default_rng(4)
    s = _samples(rng, dashed=False)
    holes = ((s > 250.0) & (s < 254.0)) | ((s > 280.0) & (s < 290.0)) | ((s > 300.0) & (s < 303.0))
    assert broken_stretches(s[~holes]) == []


def test_the_lane_beside_the_broken_line_is_put_in_the_gap_with_its_gore():
    rng = np.random.default_rng(5)
    line = _line(_samples(rng))
    d_edge = np.full(GRID.size, LINE_M)  # seen at the line on both sides of the gap
    lanes = dashed_lanes_in_gaps([line], GRID, d_edge, _covered(), LANE_M, 60.0, _ramp_points(rng))
    assert len(lanes) == 1
    lane = lanes[0]
    assert lane.gore_at_start is True  # the ramp was seen beside the stretch's start
    assert abs(lane.start - SOLID_END) < 4.0
    assert lane.width_m == LANE_M
    gores = dashed_lane_gores(lanes, _covered(), GRID, np.zeros(0))
    assert gores == [lane.start]
    edge = widen_beside_dashed(d_edge, _covered(), GRID, lanes)
    at = lambda s: float(np.interp(s, GRID, edge))  # noqa: E731
    assert at(220.0) == LINE_M  # before the gore: the line is the edge line
    assert abs(at(260.0) - (LINE_M + LANE_M)) < 1e-9  # the lane at full width
    assert at(300.0) > LINE_M + 0.5 * LANE_M  # its taper ends at the last dash
    assert at(LANE_END - 1.0) < LINE_M + 0.2
    assert at(350.0) == LINE_M
    # seen stations keep the edge they had
    assert np.array_equal(edge[_covered()], d_edge[_covered()])


def test_without_a_ramp_seen_the_lane_tapers_at_both_ends_and_no_gore_is_placed():
    rng = np.random.default_rng(6)
    line = _line(_samples(rng))
    d_edge = np.full(GRID.size, LINE_M)
    nothing = (np.zeros(0), np.zeros(0))
    lanes = dashed_lanes_in_gaps([line], GRID, d_edge, _covered(), LANE_M, 30.0, nothing)
    assert len(lanes) == 1
    assert lanes[0].gore_at_start is None
    assert dashed_lane_gores(lanes, _covered(), GRID, np.zeros(0)) == []
    w = lanes[0].width(np.array([lanes[0].start + 1.0, 290.0, lanes[0].end - 1.0]))
    assert w[0] < 0.1
    assert w[1] == LANE_M
    assert w[2] < 0.1


def test_a_gore_already_placed_in_the_gap_is_not_placed_twice():
    rng = np.random.default_rng(7)
    line = _line(_samples(rng))
    d_edge = np.full(GRID.size, LINE_M)
    lanes = dashed_lanes_in_gaps([line], GRID, d_edge, _covered(), LANE_M, 60.0, _ramp_points(rng))
    assert dashed_lane_gores(lanes, _covered(), GRID, np.array([300.0])) == []


def test_the_lane_s_end_taper_passes_through_the_width_seen_after_the_gap():
    """soderleden-s2 +320: the gap ends inside the lane's end taper, the strip seen 2.8 m
    wide 18 m before the last dash: the taper is fitted through it (25 m long)."""
    rng = np.random.default_rng(8)
    line = _line(_samples(rng))
    covered = ~((GRID > 228.0) & (GRID < 322.0))
    d_edge = np.full(GRID.size, LINE_M)
    end = broken_stretches(line.s_samples)[0][1]
    d_edge[322] = LINE_M + 2.8
    lanes = dashed_lanes_in_gaps([line], GRID, d_edge, covered, LANE_M, 60.0, _ramp_points(rng))
    assert len(lanes) == 1
    assert abs(float(lanes[0].width(np.array([322.0]))[0]) - 2.8) < 0.05
    assert 15.0 < lanes[0].taper_m < 40.0
    assert abs(lanes[0].end - end) < 1e-9


def test_a_broken_line_with_no_lane_beside_it_where_seen_is_left_alone():
    # the edge seen 1 m beyond the broken line at the gap's start: a shoulder, no lane
    rng = np.random.default_rng(9)
    line = _line(_samples(rng))
    covered = ~((GRID > 260.0) & (GRID < 358.0))
    d_edge = np.full(GRID.size, LINE_M)
    d_edge[:261] = LINE_M + 1.0
    lanes = dashed_lanes_in_gaps([line], GRID, d_edge, covered, LANE_M, 60.0, _ramp_points(rng))
    assert lanes == []


def test_the_edge_is_widened_only_in_the_gap_the_lane_was_found_in():
    """kotka-37952515-opp-s4+200: a 700 m broken stretch ending at a gap; in another gap
    500 m before, inside the stretch, a line farther out was the outermost one, and the
    edge widened there beside the broken line lay 0.4 m off."""
    rng = np.random.default_rng(10)
    line = _line(_samples(rng))
    covered = ~(((GRID > 212.0) & (GRID < 250.0)) | ((GRID > 270.0) & (GRID < 290.0)))
    d_edge = np.full(GRID.size, LINE_M)
    d_edge[250:330] = LINE_M + LANE_M  # the lane seen from the first gap's end on
    lanes = dashed_lanes_in_gaps([line], GRID, d_edge, covered, LANE_M, 60.0, _ramp_points(rng))
    assert len(lanes) == 1  # the second gap has no end of the stretch near it
    assert lanes[0].gap == (212.0, 250.0)
    other = replace(lanes[0], gap=(270.0, 290.0))
    d_edge[271:290] = LINE_M  # bridged beside a line farther out (here: at the line)
    edge = widen_beside_dashed(d_edge, covered, GRID, lanes)
    assert edge[245] == LINE_M + LANE_M  # past the gore, in the gap it was found in
    np.testing.assert_array_equal(edge[251:], d_edge[251:])
    # the same lane found in the second gap widens that one
    assert widen_beside_dashed(d_edge, covered, GRID, [other])[280] == LINE_M + LANE_M
