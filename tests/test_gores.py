"""Gore stations from the marking's solid/broken change and the hard-shoulder taper."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.mainline.gores import (
    ShoulderTaper,
    fit_shoulder_taper,
    fuse_gore_estimates,
    marking_gore_interval,
)

SPACING_M = 0.3  # lane-sample spacing along a marking, metres


def _marking(
    solid: tuple[float, float],
    dashes_from: float,
    dashes_to: float,
    *,
    dash=6.0,
    period=12.0,
    rng=None,
) -> np.ndarray:
    """Sample stations of a marking: solid over ``solid``, dashes of ``dash`` metres every
    ``period`` metres from ``dashes_from`` (a dash starts there) to ``dashes_to``."""
    rng = rng or np.random.default_rng(0)
    parts = [np.arange(solid[0], solid[1], SPACING_M)]
    for start in np.arange(dashes_from, dashes_to, period):
        parts.append(np.arange(start, start + dash, SPACING_M))
    s = np.concatenate(parts)
    return np.sort(s + rng.normal(0.0, 0.03, s.size))


def test_entry_solid_ending_in_a_dash_gap_pins_the_gore():
    # solid to the gore at 1000 m, the first dash 3 m later (the pattern's phase is global)
    s = _marking((850.0, 1000.0), 1003.0, 1100.0)
    lo, hi = marking_gore_interval(s, 995.0, entry=True)
    assert lo == hi
    assert abs(lo - 1000.0) < 0.3


def test_entry_solid_running_into_a_dash_gives_the_dash_as_interval():
    # a dash starts 2 m before the gore at 1000 m: the solid line seems to run to 1004 m
    s = _marking((850.0, 1004.0), 1010.0, 1100.0)
    lo, hi = marking_gore_interval(s, 990.0, entry=True)
    assert hi - lo == pytest.approx(6.0, abs=0.5)
    assert lo - 0.3 <= 1000.0 <= hi + 0.3
    assert abs(hi - 1004.0) < 0.3


def test_exit_mirrors_entry():
    # broken upstream of the exit gore at 2000 m, solid after it; last dash ends 2 m before
    s = _marking((2000.0, 2150.0), 1884.0, 1993.0)
    lo, hi = marking_gore_interval(s, 2005.0, entry=False)
    assert lo == hi
    assert abs(lo - 2000.0) < 0.3


def test_no_type_change_gives_no_interval():
    solid = np.arange(0.0, 300.0, SPACING_M)
    assert marking_gore_interval(solid, 150.0, entry=True) is None
    broken = _marking((0.0, 0.0), 0.0, 300.0)
    assert marking_gore_interval(broken, 150.0, entry=True) is None


def test_stray_samples_in_the_gap_do_not_pin_the_gore():
    s = _marking((850.0, 1004.0), 1010.0, 1100.0)
    s = np.sort(np.concatenate([s, [1007.0]]))  # one stray detection inside the gap
    lo, hi = marking_gore_interval(s, 990.0, entry=True)
    assert hi - lo > 5.0


def _shoulder(s: np.ndarray, *, gore: float, length: float, width: float, entry: bool):
    x = np.clip((gore - s) / length if entry else (s - gore) / length, 0.0, 1.0)
    return width * x * x * (3.0 - 2.0 * x)


@pytest.mark.parametrize("entry", [True, False])
def test_shoulder_taper_seen_halfway_places_the_gore(entry):
    rng = np.random.default_rng(3)
    gore, length, width = 1250.0, 80.0, 3.0
    # seen up to 37 m short of the gore (the shoulder has narrowed to about half)
    s = np.arange(1050.0, 1213.0, 0.2) if entry else np.arange(1287.0, 1450.0, 0.2)
    w = _shoulder(s, gore=gore, length=length, width=width, entry=entry)
    w += rng.normal(0.0, 0.03, s.size)
    taper = fit_shoulder_taper(s, w, entry=entry)
    assert taper is not None
    assert abs(taper.s_gore - gore) < 1.0
    assert abs(taper.length_m - length) < 3.0
    assert abs(taper.width_m - width) < 0.05
    s_check = np.array([gore - 20.0, gore - 60.0]) if entry else np.array([gore + 20.0])
    truth = _shoulder(s_check, gore=gore, length=length, width=width, entry=entry)
    assert np.max(np.abs(taper.width(s_check) - truth)) < 0.05


def test_shoulder_seen_only_at_full_width_gives_no_taper():
    s = np.arange(1000.0, 1160.0, 0.2)
    w = 3.0 + np.random.default_rng(1).normal(0.0, 0.03, s.size)
    assert fit_shoulder_taper(s, w, entry=True) is None


def test_fusion_keeps_the_taper_inside_the_marking_interval():
    taper = ShoulderTaper(1249.6, 80.0, 3.0, True, 0.03)
    assert fuse_gore_estimates((1248.0, 1253.5), taper, 1253.0) == pytest.approx(1249.6)
    far = ShoulderTaper(1241.0, 80.0, 3.0, True, 0.03)
    assert fuse_gore_estimates((1248.0, 1253.5), far, 1253.0) == pytest.approx(1248.0)
    assert fuse_gore_estimates((1248.0, 1253.5), None, 1260.0) == pytest.approx(1250.75)
    assert fuse_gore_estimates(None, taper, 1260.0) == pytest.approx(1249.6)
    assert fuse_gore_estimates(None, None, 1260.0) == pytest.approx(1260.0)


def test_a_hole_in_the_solid_line_does_not_pin_the_gore():
    # samples missing over 1243.7-1246.9 m: the solid line's tail (1246.9-1248) runs into
    # the dash at 1248-1254 and looks like a long, early dash
    s = _marking((850.0, 1254.0), 1260.0, 1340.0)
    s = s[(s < 1243.7) | (s > 1246.9)]
    assert marking_gore_interval(s, 1245.0, entry=True) is None


def test_a_gap_of_every_marking_is_missing_frames_not_a_dash_gap():
    s = _marking((850.0, 1000.0), 1003.0, 1100.0)
    s = s[(s < 990.0) | (s > 994.0)]  # frames missing over 990-994 m
    # another marking seen everywhere except in the same hole
    seen = np.sort(np.concatenate([s, np.arange(850.0, 990.0, 0.3), np.arange(994.0, 1100.0, 0.3)]))
    lo, hi = marking_gore_interval(s, 995.0, entry=True, seen_s=seen)
    assert lo == hi
    assert abs(lo - 1000.0) < 0.3
    # without knowing the hole is everywhere, the solid line seems to end at 990 m
    assert marking_gore_interval(s, 995.0, entry=True) != (lo, hi)


@pytest.mark.parametrize("linked", [True, False])
def test_a_line_that_begins_beside_a_lane_going_on_is_no_gore(linked):
    """soderleden-s2 with a noisier sensor (seed offset 260): the outer lane's edge line
    was first painted (seen) 75 m before an entry's nose, where the outer lane goes on
    (linked across the section border there). Its start was an abrupt birth of that
    lane, a measured entry gore, and the ramp joined 75 m early (missed, spurious). A
    lane born there (not linked) still is one."""
    from roadtwin.mainline.sections import _events
    from roadtwin.model import Lane, LaneSection, constant_lane

    grid = np.arange(0.0, 400.5, 0.5)
    before = LaneSection(0.0, right=(constant_lane(-1, 3.5), constant_lane(-2, 3.5)))
    after = LaneSection(
        165.0,
        right=(
            Lane(-1, "driving", constant_lane(-1, 3.5).width, predecessor=-1),
            Lane(-2, "driving", constant_lane(-2, 3.5).width, predecessor=-2 if linked else None),
            constant_lane(-3, 1.2, lane_type="shoulder"),
        ),
    )
    dmat = np.full((3, grid.size), np.nan)
    dmat[0] = 3.5
    dmat[1, grid >= 165.0] = 7.0
    dmat[2] = 8.2
    events = _events(
        [(1, "start", 165.0, 0.0, None)], [before, after], [[0, 2], [0, 1, 2]], dmat, grid,
        "right", 1.0,
    )  # fmt: skip
    assert [(e.kind, e.lane_id, e.s_m) for e in events] == (
        [] if linked else [("birth", -2, 165.0)]
    )
