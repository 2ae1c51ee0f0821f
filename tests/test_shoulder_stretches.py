"""A hard shoulder that opens or closes beside its edge line, away from any edge step.

melbourne-18-s11+80 (the real-layout benchmark, Melbourne's OSM, a noisier sensor): the
hard shoulder beside a lane gain widens to 2.3 m and closes again 120 m later; later a
lane drops by a 107 m taper into the line of a hard shoulder that opens beside it. The
shoulder's line runs along the edge elsewhere, so it was judged an edge line section by
section: dropped, and the lane beside it took the shoulder (5.5 m wide over 45 m); the
2.3 m strip was taken for a hidden lane; the dropping lane, narrower than a lane in its
own section, was typed a shoulder; and the line between it and the lane that goes on,
lost 1 m before the converging line met it, ended the lane 50 m early. Lanes 0.436 m
(94.9 % of stations with the right lane count) -> 0.058 m (99.7 %).
"""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.config import MainlineConfig
from roadtwin.mainline.hidden_lanes import _hidden_lane_count
from roadtwin.mainline.markings import _continue_to_convergence, _Track
from roadtwin.mainline.sections import _sections_from_tracks

CFG = MainlineConfig()
GRID = np.arange(0.0, 800.0 + 0.5 * CFG.grid_step_m, CFG.grid_step_m)


def _track(k, d, lo=0.0, hi=800.0, mark="broken"):
    s = GRID[(lo <= GRID) & (hi >= GRID)]
    dd = np.interp(s, GRID, d) if np.ndim(d) else np.full(s.size, float(d))
    return _Track(k, lo, hi, s, dd, mark, s.size, s, dd)


def _edge_with_shoulder(s):
    """The outer edge 2.4 m beyond the line at 8.0 m up to 300 m, closing onto it by 350 m
    and 0.1 m beyond it from there (no edge step anywhere)."""
    return np.interp(s, [0.0, 300.0, 350.0, 800.0], [10.4, 10.4, 8.1, 8.1])


def _lanes_at(sections, s):
    sc = sections[max(i for i, x in enumerate(sections) if x.s0 <= s)]
    ds = np.array([s - sc.s0])
    return [(ln.type, round(float(ln.width.value(ds)[0]), 1)) for ln in sc.right]


def test_a_shoulder_closing_onto_its_line_ends_where_they_meet():
    tracks = [_track(0, 1.0, mark="solid"), _track(1, 4.5), _track(2, 8.0, mark="solid")]
    d_edge = _edge_with_shoulder(GRID)
    sections, _, _ = _sections_from_tracks(
        tracks, GRID, d_edge, np.zeros(0), 1.0, CFG, None, np.zeros(GRID.size)
    )
    # the shoulder keeps its 2.4 m beside the line; before, the outer lane took it (5.9 m)
    assert _lanes_at(sections, 100.0)[-3:] == [
        ("driving", 3.5),
        ("driving", 3.5),
        ("shoulder", 2.4),
    ]
    # ... and ends where the edge meets the line (gap 0.1 m at 350 m), not earlier
    ends = [sc.s0 for sc in sections[1:]]
    assert len(ends) == 1
    assert 335.0 <= ends[0] <= 352.0
    assert max(w for _, w in _lanes_at(sections, 600.0)) <= 3.6


def test_shoulder_stretches_reach_from_where_the_line_leaves_the_edge_to_where_it_meets_it():
    from roadtwin.mainline.sections import _shoulder_stretches

    d_edge = _edge_with_shoulder(GRID)
    line = np.full(GRID.size, 8.0)
    inner = np.full(GRID.size, 4.5)
    edge_lines, stretch = _shoulder_stretches(
        np.vstack([inner, line]), d_edge, np.zeros(GRID.size), CFG
    )
    assert edge_lines == {1}
    on = GRID[stretch[1]]
    assert on[0] == 0.0
    assert 340.0 <= on[-1] <= 352.0
    # a shoulder wider than 1.8 m over less than 20 m (a bulge at a gore's nose) is none
    bump = 8.1 + 2.0 * np.exp(-(((GRID - 500.0) / 6.0) ** 2))
    _, stretch = _shoulder_stretches(np.vstack([inner, line]), bump, np.zeros(GRID.size), CFG)
    assert not stretch[1].any()


def test_a_dropping_lane_narrower_than_a_lane_in_its_section_is_still_driving():
    """Lane 3 (8.0-11.5 m) drops: its outer line converges onto 8.0 m from 400 to 560 m,
    and the hard shoulder (2.4 m) opens beside that line from 420 m on."""
    converging = np.interp(GRID, [0.0, 400.0, 560.0, 800.0], [11.5, 11.5, 8.0, 8.0])
    tracks = [
        _track(0, 1.0, mark="solid"),
        _track(1, 4.5),
        _track(2, 8.0, hi=560.0),
        _track(3, converging, mark="solid"),
    ]
    d_edge = np.interp(GRID, [0.0, 420.0, 520.0, 800.0], [11.6, 11.6, 10.4, 10.4])
    sections, _, _ = _sections_from_tracks(
        tracks, GRID, d_edge, np.zeros(0), 1.0, CFG, None, np.zeros(GRID.size)
    )
    at_500 = _lanes_at(sections, 500.0)
    # the dropping lane is 1.3 m wide there and the shoulder 1.3 m
    assert [t for t, _ in at_500[-2:]] == ["driving", "shoulder"]
    assert at_500[-2][1] == pytest.approx(1.3, abs=0.15)
    assert sum(t == "driving" for t, _ in _lanes_at(sections, 700.0)) == 2


def test_a_line_lost_near_the_end_of_a_taper_runs_on_to_where_the_neighbour_meets_it():
    """The line between a dropping lane and the one that goes on (8.0 m) ends at 500 m,
    where the converging line beyond is still 1.0 m away; that line meets 8.0 m at 560 m.
    A neighbour closer than 0.6 of a lane was never continued onto: the lane ended 60 m
    early, at 1.0 m wide."""
    converging = np.interp(GRID, [0.0, 400.0, 560.0, 800.0], [11.5, 11.5, 8.0, 8.0])
    tracks = [_track(0, 4.5), _track(1, 8.0, hi=500.0), _track(2, converging)]
    out = _continue_to_convergence(tracks, GRID, CFG)
    assert out[1].hi == pytest.approx(553.0, abs=6.0)
    # a neighbour within 0.5 m when the line ends has met it: nothing to continue
    tracks[1] = _track(1, 8.0, hi=545.0)
    assert _continue_to_convergence(tracks, GRID, CFG)[1].hi == 545.0


def test_a_strip_narrower_than_any_lane_beyond_the_outermost_line_is_no_hidden_lane():
    """With no shoulder over most of the run, a 2.3 m strip beyond the outermost line was
    taken for a hidden lane (wider than the usual shoulder by more than 2.0 m); no lane is
    2.3 m wide: it is a shoulder. A 3.4 m strip still hides one."""
    gap = np.full(GRID.size, 2.3)
    lane_m = 3.4
    count = _hidden_lane_count(
        gap, lane_m, CFG.hidden_lane_min_m - lane_m, CFG.grid_step_m, lanes_only=True
    )
    assert not count.any()
    count = _hidden_lane_count(
        gap + 1.1, lane_m, CFG.hidden_lane_min_m - lane_m, CFG.grid_step_m, lanes_only=True
    )
    assert (count == 1).all()


def test_a_shoulder_that_narrows_on_from_a_driving_lane_is_that_lanes_taper():
    """Section 2 (40 m) holds the dropping lane between two markings, 2.1 -> 0.4 m wide,
    linked from a 2.1 m driving lane: nowhere 2.2 m wide, it was typed a shoulder. A strip
    that keeps its width (a hatched area beside an edge line) stays a shoulder, and so
    does the outermost lane."""
    from dataclasses import replace

    from roadtwin.mainline.sections import _drive_on_through_sections
    from roadtwin.model import CubicPiece, CubicProfile, LaneSection, constant_lane

    def lane(lane_id, width, lane_type="driving", pred=None):
        return replace(
            constant_lane(lane_id, 0.0, lane_type=lane_type), width=width, predecessor=pred
        )

    def sections(middle_width):
        first = LaneSection(
            0.0,
            right=(
                lane(-1, CubicProfile.constant(3.5)),
                lane(-2, CubicProfile((CubicPiece(0.0, 3.3, -0.006),))),  # 2.1 m at 200 m
            ),
        )
        middle = LaneSection(
            200.0,
            right=(
                lane(-1, CubicProfile.constant(3.5), pred=-1),
                lane(-2, middle_width, "shoulder", pred=-2),
                lane(-3, CubicProfile((CubicPiece(0.0, 0.2, 0.03),)), "shoulder", pred=None),
            ),
        )
        last = LaneSection(
            240.0,
            right=(
                lane(-1, CubicProfile.constant(3.5), pred=-1),
                lane(-2, CubicProfile.constant(2.4), "shoulder", pred=None),
            ),
        )
        return [first, middle, last]

    closing = CubicProfile((CubicPiece(0.0, 2.1, -0.0425),))  # 2.1 -> 0.4 m over 40 m
    out = _drive_on_through_sections(sections(closing), CFG)
    assert [ln.type for ln in out[1].right] == ["driving", "driving", "shoulder"]
    out = _drive_on_through_sections(sections(CubicProfile.constant(2.1)), CFG)
    assert [ln.type for ln in out[1].right] == ["driving", "shoulder", "shoulder"]
