"""The shoulder's own line goes on where it lies beyond the sensor's reach.

Town06 paints a solid line 0.6 m inside the outer edge (its hard shoulder split in two).
Driven in an inner lane, that line lay beyond the sensor's lateral reach over most of
town06-auto-lane1-s21 and was seen over 350 m only: wherever it was missing, the
boundary was 0.5 m off (lanes 0.146 m). Unseen out of reach is not absent."""

from __future__ import annotations

import numpy as np

from roadtwin.mainline.markings import _Track
from roadtwin.mainline.shoulder_line import continue_median_shoulder_line, continue_shoulder_line

GRID = np.arange(0.0, 1001.0, 1.0)


def _track(k: int, lo: float, hi: float, d: float, mark: str = "solid", n: int = 100) -> _Track:
    s = GRID[(lo <= GRID) & (hi >= GRID)]
    return _Track(k, lo, hi, s, np.full(s.size, d), mark, n, s.copy())


def _run(car_d: np.ndarray) -> list[_Track]:
    """Lane lines at 4.6, 8.1, 11.6 (broken) and 15.1 m (the lane's outer line), the
    shoulder's line at 15.6 m seen over 400-700 m only, the edge at 16.25 m seen all along;
    lane samples up to 12 m either side of the car (the sensor's reach)."""
    tracks = [
        _track(0, 0.0, 1000.0, 4.6, "broken"),
        _track(1, 0.0, 1000.0, 8.1, "broken"),
        _track(2, 0.0, 1000.0, 11.6, "broken"),
        _track(3, 0.0, 1000.0, 15.1),
        _track(4, 400.0, 700.0, 15.6),
    ]
    s_lane = np.repeat(GRID, 5)
    d_lane = np.interp(s_lane, GRID, car_d) + np.tile(np.linspace(-12.0, 12.0, 5), GRID.size)
    d_edge = np.full(GRID.size, 16.25)
    covered = np.ones(GRID.size, dtype=bool)
    return continue_shoulder_line(tracks, GRID, d_edge, covered, (s_lane, d_lane), (GRID, car_d))


def test_the_shoulders_line_goes_on_out_of_reach():
    out = _run(np.full(GRID.size, 3.0))  # 12.6 m from the shoulder's line: out of reach
    line = out[4]
    assert line.lo == 0.0
    assert line.hi == 1000.0
    np.testing.assert_allclose(np.interp([100.0, 550.0, 900.0], line.s, line.d), 15.6, atol=0.01)
    assert len(out) == 5


def test_not_where_the_car_would_have_seen_it():
    """Where the car drove within reach of the line's place (800-1000 m) and saw no line
    there, the line is absent: it stops where the car came near."""
    car = np.where(GRID < 800.0, 3.0, 8.0)
    line = _run(car)[4]
    assert line.lo == 0.0
    assert 798.0 <= line.hi <= 800.0


def test_no_pattern_seen_long_enough_no_line():
    """A line seen over less than 100 m beside the edge is no pattern to go on with."""
    car = np.full(GRID.size, 3.0)
    tracks = [_track(0, 0.0, 1000.0, 15.1), _track(1, 400.0, 460.0, 15.6)]
    s_lane = np.repeat(GRID, 5)
    d_lane = 3.0 + np.tile(np.linspace(-12.0, 12.0, 5), GRID.size)
    out = continue_shoulder_line(
        tracks,
        GRID,
        np.full(GRID.size, 16.25),
        np.ones(GRID.size, dtype=bool),
        (s_lane, d_lane),
        (GRID, car),
    )
    assert out[1].lo == 400.0
    assert out[1].hi == 460.0


def test_a_lane_line_where_the_road_widened_is_not_continued_as_the_shoulders():
    """A track that is the shoulder's line over 0-600 m (0.65 m inside the edge) goes on
    as a lane's line where the road is a lane wider (the edge 3.5 m farther out from
    600 m, the added lane's outer line 0.5 m inside the shoulder line's place): its end
    10 m before the run's end lies 3.5 m inside the shoulder line's place. It is not
    continued there (continued, it jumped 4 m out over the run's last metres,
    town06-auto-lane2-s22 with a noisier sensor, and a lane 7.5 m wide)."""
    grid = GRID
    car = np.full(grid.size, 3.0)
    edge = np.where(grid < 600.0, 16.25, 19.75)
    s = grid[grid <= 990.0]
    widened = _Track(3, 0.0, 990.0, s, np.full(s.size, 15.6), "solid", 300, s.copy())
    tracks = [
        _track(0, 0.0, 1000.0, 4.6, "broken"),
        _track(1, 0.0, 1000.0, 8.1, "broken"),
        _track(2, 0.0, 1000.0, 15.1, "broken"),
        widened,
        _track(4, 600.0, 1000.0, 18.6),  # the added lane's outer line
    ]
    s_lane = np.repeat(grid, 5)
    d_lane = 3.0 + np.tile(np.linspace(-12.0, 12.0, 5), grid.size)
    out = continue_shoulder_line(
        tracks, grid, edge, np.ones(grid.size, dtype=bool), (s_lane, d_lane), (grid, car)
    )
    line = out[3]
    assert line.hi == 990.0
    assert float(np.max(np.abs(np.diff(line.d)))) < 0.01


def _median_side(car_d: np.ndarray, innermost: list[_Track] | None = None) -> list[_Track]:
    """The median side of a road widened by an entry, driven in its outermost lane: the
    inner shoulder's line 0.7 m from the median edge (d = 0) seen over 0-600 m only, the
    innermost lane line 3.7 m beyond it and the lane lines beyond that seen all along;
    lane samples up to 12 m either side of the car."""
    tracks = [
        _track(0, 0.0, 600.0, 0.7),
        *(innermost or [_track(1, 0.0, 1000.0, 4.4, "broken")]),
        _track(2, 0.0, 1000.0, 8.1, "broken"),
        _track(3, 0.0, 1000.0, 11.8, "broken"),
    ]
    s_lane = np.repeat(GRID, 5)
    d_lane = np.interp(s_lane, GRID, car_d) + np.tile(np.linspace(-12.0, 12.0, 5), GRID.size)
    return continue_median_shoulder_line(
        tracks, GRID, np.zeros(GRID.size), (s_lane, d_lane), (GRID, car_d)
    )


def test_the_inner_shoulders_line_goes_on_out_of_reach():
    """Unseen beyond the sensor's reach is not absent on the median side either
    (a9-239192816-opp-s12 at seed offset 860: the strip from the median edge to the
    innermost line seen, 0.7 + 3.7 m, was built as a 4.3 m lane over its last 230 m)."""
    out = _median_side(np.full(GRID.size, 13.7))  # 13 m from the line: out of reach
    line = out[0]
    assert line.lo == 0.0
    assert line.hi == 1000.0
    np.testing.assert_allclose(np.interp([300.0, 700.0, 990.0], line.s, line.d), 0.7, atol=0.01)
    assert [tr.hi for tr in out[1:]] == [1000.0, 1000.0, 1000.0]


def test_the_inner_shoulders_line_stops_where_the_car_came_near():
    car = np.where(GRID < 800.0, 13.7, 6.0)
    line = _median_side(car)[0]
    assert 798.0 <= line.hi <= 800.0


def test_the_inner_shoulders_line_stops_where_the_pattern_ends():
    """Where the innermost lane line is no longer a lane width beyond the shoulder's
    place (the lanes move a lane away from the median from 750 m), the strip is no
    longer a shoulder and a lane: the line is not continued there."""
    moved = [_track(1, 0.0, 749.0, 4.4, "broken"), _track(4, 750.0, 1000.0, 8.1, "solid")]
    line = _median_side(np.full(GRID.size, 13.7), moved)[0]
    assert 748.0 <= line.hi <= 750.0
