"""Lane borders joined at lane-section borders (mainline.seal)."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.check import check_network
from roadtwin.mainline.seal import seal_lane_borders
from roadtwin.model import (
    CubicPiece,
    CubicProfile,
    Header,
    Lane,
    LaneSection,
    Line,
    Road,
    RoadNetwork,
)


def _lane(lid, w, pred=None, succ=None, kind="driving", slope=0.0):
    return Lane(
        lid, kind, CubicProfile((CubicPiece(0.0, w, slope),)), predecessor=pred, successor=succ
    )


def _road(first: LaneSection, second: LaneSection, offset: float = 0.0) -> Road:
    return Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, 200.0),),
        (first, second),
        lane_offset=CubicProfile((CubicPiece(0.0, offset),)),
    )


def _shift_mm(road: Road) -> float:
    found = [f for f in check_network(RoadNetwork(Header(), (road,))) if f.code == "lane_shift"]
    return max((f.value for f in found), default=0.0)


def _jump_mm(road: Road, lane_before: int, lane_after: int, s: float) -> float:
    before = road.lane_border_t(np.array([s - 1e-9]), lane_before)[0]
    after = road.lane_border_t(np.array([s]), lane_after)[0]
    return 1000.0 * abs(after - before)


def _sealed_checked(
    first: LaneSection, second: LaneSection, shift_mm: float, before: int, after: int
) -> Road:
    """Seal the two-section road; the check finds ``shift_mm`` before and nothing after,
    and lane ``before`` meets lane ``after`` at the border."""
    road = _road(first, second)
    assert _shift_mm(road) == pytest.approx(shift_mm, abs=0.1)
    sealed = seal_lane_borders(road)
    assert _shift_mm(sealed) == 0.0
    assert _jump_mm(sealed, before, after, second.s0) < 1e-6
    return sealed


def test_a_closing_lane_left_17_mm_wide_closes_to_zero():
    # lane -2 tapers out but its fit ends 17 mm wide; lane -3 continues as lane -2
    first = LaneSection(
        0.0,
        right=(
            _lane(-1, 1.0, succ=-1, kind="shoulder"),
            _lane(-2, 3.5, slope=-(3.5 - 0.0172) / 100.0),
            _lane(-3, 3.5, succ=-2),
        ),
    )
    second = LaneSection(
        100.0, right=(_lane(-1, 1.0, pred=-1, kind="shoulder"), _lane(-2, 3.5, pred=-3))
    )
    sealed = _sealed_checked(first, second, 17.2, -3, -2)
    closing = sealed.lane_sections[0].right[1]
    assert float(closing.width.value(np.array([100.0]))[0]) == pytest.approx(0.0, abs=1e-9)
    # 20 m before the border the lane is as fitted
    for ds in (10.0, 50.0, 79.9):
        assert float(closing.width.value(np.array([ds]))[0]) == pytest.approx(
            3.5 - (3.5 - 0.0172) * ds / 100.0, abs=1e-9
        )


def test_a_shoulder_and_lane_replaced_by_one_lane_keep_the_outer_lanes_in_place():
    # Town06-like: shoulder 0.386 m + lane 3.027 m end, one lane 3.376 m begins; the
    # hard shoulder beyond continues: it moved 37 mm sideways
    first = LaneSection(
        0.0,
        right=(
            _lane(-1, 3.5, succ=-1),
            _lane(-2, 0.386, kind="shoulder"),
            _lane(-3, 3.027),
            _lane(-4, 0.66, succ=-3, kind="shoulder"),
        ),
    )
    second = LaneSection(
        100.0,
        right=(
            _lane(-1, 3.5, pred=-1),
            _lane(-2, 3.376),
            _lane(-3, 0.66, pred=-4, kind="shoulder"),
        ),
    )
    sealed = _sealed_checked(first, second, 37.0, -4, -3)
    new_lane = sealed.lane_sections[1].right[1]
    assert float(new_lane.width.value(np.array([0.0]))[0]) == pytest.approx(3.413, abs=1e-9)
    # the correction fades out within 20 m of the border
    for ds in (20.0, 50.0, 99.0):
        assert float(new_lane.width.value(np.array([ds]))[0]) == pytest.approx(3.376, abs=1e-9)


def test_a_step_of_the_lane_offset_is_taken_up_by_the_lanes_that_begin():
    # the centre lane's offset steps 0.2 m to the left (a median-side edge step); an
    # inner shoulder begins there and lane -1 continues as lane -2
    first = LaneSection(0.0, right=(_lane(-1, 3.5, succ=-2),))
    second = LaneSection(100.0, right=(_lane(-1, 0.5, kind="shoulder"), _lane(-2, 3.5, pred=-1)))
    road = Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, 200.0),),
        (first, second),
        lane_offset=CubicProfile((CubicPiece(0.0, 0.0), CubicPiece(100.0, 0.2))),
    )
    assert _jump_mm(road, -1, -2, 100.0) == pytest.approx(300.0, abs=1e-6)
    sealed = seal_lane_borders(road)
    assert _jump_mm(sealed, -1, -2, 100.0) < 1e-6
    assert float(sealed.lane_sections[1].right[0].width.value(np.array([0.0]))[0]) == (
        pytest.approx(0.2, abs=1e-9)
    )


def test_nothing_changes_where_the_borders_already_meet():
    first = LaneSection(0.0, right=(_lane(-1, 1.0, succ=-1), _lane(-2, 3.5, succ=-2)))
    second = LaneSection(100.0, right=(_lane(-1, 1.0, pred=-1), _lane(-2, 3.5, pred=-2)))
    road = _road(first, second)
    assert seal_lane_borders(road) == road


def test_a_lane_refitted_narrower_after_its_marking_reappears_is_linked_to_itself():
    """Melbourne: inner lane 2 ends 3.74 m wide and a lane 2 begins 3.39 m wide at the same
    border (its marking seen again after a gap; the borders met too loosely to link).
    Sealed, it fills the same room and is the same lane: linked, so that a car in it goes
    on (``lane_dead_end`` had it end and begin at full width)."""
    first = LaneSection(
        0.0,
        left=(
            _lane(1, 0.0, kind="shoulder"),
            _lane(2, 3.7447),
            _lane(3, 3.349, succ=3),
        ),
    )
    second = LaneSection(
        100.0,
        left=(
            _lane(1, 0.0, kind="shoulder"),
            _lane(2, 3.3916),
            _lane(3, 3.349, pred=3),
        ),
    )
    road = _road(first, second)
    dead = [f for f in check_network(RoadNetwork(Header(), (road,))) if f.code == "lane_dead_end"]
    assert len(dead) == 2  # ends and begins
    sealed = seal_lane_borders(road)
    before, after = sealed.lane_sections[0].left, sealed.lane_sections[1].left
    assert before[1].successor == 2
    assert after[1].predecessor == 2
    # the closed shoulder stays unlinked (zero width)
    assert before[0].successor is None
    assert after[0].predecessor is None
    assert _jump_mm(sealed, 2, 2, 100.0) < 1e-6
    assert _jump_mm(sealed, 3, 3, 100.0) < 1e-6
    findings = check_network(RoadNetwork(Header(), (sealed,)))
    assert not [f for f in findings if f.code in ("lane_dead_end", "lane_shift", "width_jump")]


def test_two_driving_lanes_sharing_the_same_room_differently_are_linked_in_order():
    """melbourne-408-opp: inner lanes 2 and 3 end 4.39 and 2.66 m wide where lanes 2 and 4
    begin 3.12 and 3.93 m wide with a zero-width shoulder 3 opening between them: the
    same two lanes, the line between them re-fitted 1.27 m aside. Linked in order, they
    continue with the widths they had and the line moves over the fade (both lanes of
    the run ended at full width: two routes led nowhere); a line 1.8 m aside is another
    lane structure and stays unlinked."""

    def sections(w2_after: float):
        first = LaneSection(
            0.0,
            left=(
                _lane(1, 0.96, succ=1, kind="shoulder"),
                _lane(2, 4.39),
                _lane(3, 2.66),
                _lane(4, 3.5, succ=5),
            ),
        )
        second = LaneSection(
            100.0,
            left=(
                _lane(1, 0.96, pred=1, kind="shoulder"),
                _lane(2, w2_after),
                _lane(3, 0.0, kind="shoulder"),
                _lane(4, 7.05 - w2_after),
                _lane(5, 3.5, pred=4),
            ),
        )
        return _road(first, second)

    sealed = seal_lane_borders(sections(3.12))
    before, after = sealed.lane_sections[0].left, sealed.lane_sections[1].left
    assert (before[1].successor, before[2].successor) == (2, 4)
    assert (after[1].predecessor, after[3].predecessor) == (2, 3)
    assert after[2].predecessor is None  # the shoulder opening from zero width
    assert _jump_mm(sealed, 2, 2, 100.0) < 1e-6
    assert _jump_mm(sealed, 3, 4, 100.0) < 1e-6
    assert _jump_mm(sealed, 4, 5, 100.0) < 1e-6
    # 20 m on, the lanes have the widths they were fitted with
    s = np.array([20.0])
    assert float(after[1].width.value(s)[0]) == pytest.approx(3.12, abs=1e-9)
    assert float(after[3].width.value(s)[0]) == pytest.approx(3.93, abs=1e-9)
    findings = check_network(RoadNetwork(Header(), (sealed,)))
    assert not [f for f in findings if f.code in ("lane_dead_end", "lane_shift", "width_jump")]
    far = seal_lane_borders(sections(2.59)).lane_sections[1].left
    assert far[1].predecessor is None


@pytest.mark.parametrize(("shoulder_after", "linked"), [(1.06, True), (0.2, False)])
def test_a_shoulder_and_driving_lanes_sharing_the_room_differently_are_linked(
    shoulder_after, linked
):
    """town06-auto-s7 with a noisier sensor (seed offset 320): the median-side shoulder
    ends 1.91 m wide at a border and begins 1.06 m wide after it, the two driving lanes
    beside it sharing the rest (3.50 + 2.67 m before, 3.50 + 3.52 m after); the outer lanes
    linked. Only driving lanes counted as re-fitted, so the three ended and began at full
    width and two of the mainline's routes led nowhere in esmini. Now they are the same
    lanes, the lines moved over the fade; a shoulder moved 1.7 m (more than a re-fitted
    line's 1.5 m) is another structure and stays unlinked."""
    rest = 1.91 + 3.50 + 2.67 - shoulder_after
    first = LaneSection(
        0.0,
        right=(
            _lane(-1, 1.91, kind="shoulder"),
            _lane(-2, 3.50),
            _lane(-3, 2.67),
            _lane(-4, 3.5, succ=-4),
        ),
    )
    second = LaneSection(
        100.0,
        right=(
            _lane(-1, shoulder_after, kind="shoulder"),
            _lane(-2, 3.50),
            _lane(-3, rest - 3.50),
            _lane(-4, 3.5, pred=-4),
        ),
    )
    sealed = seal_lane_borders(_road(first, second))
    before, after = sealed.lane_sections[0].right, sealed.lane_sections[1].right
    if not linked:
        assert [ln.predecessor for ln in after[:3]] == [None, None, None]
        return
    assert [ln.successor for ln in before[:3]] == [-1, -2, -3]
    assert [ln.predecessor for ln in after[:3]] == [-1, -2, -3]
    for lane in (-1, -2, -3, -4):
        assert _jump_mm(sealed, lane, lane, 100.0) < 1e-6
    # 20 m on, the lanes have the widths they were fitted with
    s = np.array([20.0])
    assert float(after[0].width.value(s)[0]) == pytest.approx(shoulder_after, abs=1e-9)
    assert float(after[2].width.value(s)[0]) == pytest.approx(rest - 3.50, abs=1e-9)
    findings = check_network(RoadNetwork(Header(), (sealed,)))
    assert not [f for f in findings if f.code in ("lane_dead_end", "lane_shift", "width_jump")]
