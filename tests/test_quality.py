"""Stretch warnings: where the run's own points disagree with the built mainline."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from roadtwin.mainline import poorly_determined
from roadtwin.model import CubicPiece, CubicProfile
from test_mainline import sample_run, truth_road


def _widen(road, section_index: int, lane_index: int, extra_m: float):
    """``road`` with one lane of one section ``extra_m`` wider (its outer borders move)."""
    secs = list(road.lane_sections)
    sec = secs[section_index]
    lanes = list(sec.right)
    lane = lanes[lane_index]
    p0 = lane.width.pieces[0]
    lanes[lane_index] = replace(
        lane, width=CubicProfile((replace(p0, a=p0.a + extra_m), *lane.width.pieces[1:]))
    )
    secs[section_index] = replace(sec, right=tuple(lanes))
    return replace(road, lane_sections=tuple(secs))


def test_true_road_explains_its_points():
    road = truth_road()
    run = sample_run(road, outliers=0.02)
    assert poorly_determined(road, run) == ()


def test_outer_edge_off_is_reported_with_its_stations():
    road = truth_road()
    run = sample_run(road)
    # the hard shoulder of the last section 1.2 m too wide: the built outer edge lies
    # 1.2 m outside the measured one from 1200 m to the end
    bad = _widen(road, 2, 4, 1.2)
    found = [st for st in poorly_determined(bad, run) if st.kind == "outer edge"]
    assert len(found) == 1
    st = found[0]
    assert st.s0_m <= 1200.0 + 25.0
    assert st.s1_m >= road.length - 25.0
    assert st.value_m == np.clip(st.value_m, 1.1, 1.3)  # points lie 1.2 m inside it
    assert "s=1200" in st.message() or "s=1175" in st.message()


def test_missed_marking_gives_a_wide_lane_and_unexplained_samples():
    road = truth_road()
    run = sample_run(road)
    # merge driving lanes 2 and 3 of the first section into one 7.5 m lane
    sec = road.lane_sections[0]
    lanes = list(sec.right)
    merged = replace(lanes[2], width=CubicProfile((CubicPiece(0.0, 7.5),)))
    lanes = [*lanes[:2], merged, *lanes[4:]]
    lanes = [replace(ln, id=-(i + 1)) for i, ln in enumerate(lanes)]
    secs = (replace(sec, right=tuple(lanes)), *road.lane_sections[1:])
    bad = replace(road, lane_sections=secs)
    kinds = {st.kind: st for st in poorly_determined(bad, run)}
    assert kinds["lane width"].value_m == np.clip(kinds["lane width"].value_m, 7.4, 7.6)
    assert kinds["lane width"].s1_m <= 925.0
    # the lane line between them was measured all along: its samples line up off the map
    missed = kinds["lane markings"]
    t_line = float(road.lane_border_t(np.array([400.0]), -3)[0])
    assert abs(missed.value_m - t_line) < 0.3
    assert missed.s0_m < 100.0
    assert 800.0 < missed.s1_m <= 925.0
