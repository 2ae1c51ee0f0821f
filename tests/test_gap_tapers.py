"""A lane closing or opening at the outer edge inside an occlusion gap of the edge: its
taper is placed by the part of it the sensor saw (roadtwin.mainline.gap_tapers).

a9-239192816-lane1-s21 with a noisier sensor: an auxiliary lane 2.4 m wide closed over
1280-1330 m while the edge was hidden from 1213 to 1319 m; only the taper's last 10 m were
seen. Bridged linearly, the lane closed over the whole 106 m gap (edge 1.2 m off over
50 m, edge RMSE 0.174 m). oakland-11197879-s3 (seed 20): a lane opening over 1880-1920 m,
edge hidden 1820-1912 m, opened over 92 m (edge RMSE 0.139 m).
"""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline import fit_lanes
from roadtwin.mainline.gap_tapers import fitted_gap_taper, taper_widths


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _edge_at(sections, station):
    """Outer road edge offset (metres from the reference) of right-hand lane sections."""
    sc = sections[max(i for i, sc in enumerate(sections) if sc.s0 <= station)]
    return sum(float(ln.width.value(np.array([station - sc.s0]))[0]) for ln in sc.right)


def _closing_run(rng, taper_start, gap=(540.0, 640.0), length=55.0):
    """Lines at 1, 4.5 and 8 m over 1000 m; the edge 3 m outside the last line closes
    to 0.3 m over ``length`` metres from ``taper_start``; edge points every 0.2 m, hidden
    over ``gap``. Returns the lane samples, the seen edge points and the true edge."""
    s_l = np.arange(0.0, 1000.0, 0.5)
    s_lane = np.tile(s_l, 3)
    d_lane = np.repeat([1.0, 4.5, 8.0], s_l.size) + rng.normal(0.0, 0.02, 3 * s_l.size)

    def edge(s):
        return 11.0 - 2.7 * _smoothstep((np.asarray(s) - taper_start) / length)

    s_out = np.arange(0.0, 1000.0, 0.2)
    s_out = s_out[(s_out < gap[0]) | (s_out > gap[1])]
    d_out = edge(s_out) + rng.normal(0.0, 0.05, s_out.size)
    return s_lane, d_lane, s_out, d_out, edge


def test_a_lane_closing_late_in_a_gap_closes_where_its_tail_was_seen():
    rng = np.random.default_rng(7)
    # the last 13 m of the taper seen, 0.3 m of its 2.7 m
    s_lane, d_lane, s_out, d_out, edge = _closing_run(rng, taper_start=598.0)
    sections, _, _, _ = fit_lanes(
        s_lane, d_lane, s_out, d_out, length=1000.0, sign=1.0, config=MainlineConfig()
    )
    for station in (560.0, 580.0, 600.0, 620.0, 635.0, 660.0):
        built, true = _edge_at(sections, station), float(edge(station))
        # linear over the gap: 1.1 m off at 580 m, 1.6 m at 600 m
        assert abs(built - true) < 0.25, (station, built, true)


def test_a_lane_closing_wholly_inside_a_gap_stays_bridged_linearly():
    """Nothing of the taper seen: where in the gap it lies is unknown, and the linear
    bridge (the least-squares guess) stays."""
    rng = np.random.default_rng(8)
    s_lane, d_lane, s_out, d_out, _ = _closing_run(rng, taper_start=565.0)
    sections, _, _, _ = fit_lanes(
        s_lane, d_lane, s_out, d_out, length=1000.0, sign=1.0, config=MainlineConfig()
    )
    for station in (560.0, 590.0, 620.0):
        linear = 11.0 - 2.7 * (station - 540.0) / 100.0
        assert abs(_edge_at(sections, station) - linear) < 0.15, station


def test_the_fit_places_a_seen_head_or_tail_and_ignores_outliers():
    rng = np.random.default_rng(1)
    gap = (1213.0, 1319.0)
    s = np.sort(rng.uniform(1150.0, 1380.0, 20_000))  # a dense sensor: binned to 1 m
    s = s[(s < gap[0]) | (s > gap[1])]

    def ends(start):
        return tuple(2.45 - 2.45 * _smoothstep((np.array(gap) - start) / 50.0))

    for start in (1195.0, 1283.0):  # head seen before the gap, tail seen after it
        true = 2.45 - 2.45 * _smoothstep((s - start) / 50.0)
        w = true + rng.normal(0.0, 0.05, s.size)
        w[::50] += 3.0  # guardrail points
        found = fitted_gap_taper(s, w, gap, ends(start))
        assert found is not None
        s_start, length, wa, wb = found
        assert abs(s_start - start) < 6.0
        assert abs(length - 50.0) < 12.0
        assert abs(wa - 2.45) < 0.05
        assert abs(wb) < 0.05
        stations = np.arange(gap[0], gap[1])
        expected = 2.45 - 2.45 * _smoothstep((stations - start) / 50.0)
        assert np.max(np.abs(taper_widths(found, stations) - expected)) < 0.25
    # a shoulder that changes by less than a lane is no lane's taper
    w = 0.5 + 0.4 * _smoothstep((s - 1300.0) / 40.0)
    assert fitted_gap_taper(s, w, gap, (0.5, 0.7)) is None


def test_widths_of_another_road_beyond_the_taper_do_not_pull_its_levels():
    """oakland-11197879-s3 (seed 80): an acceleration lane closing over 840-905 m, the edge
    hidden from 801 to 879 m; 45 m after the gap a ramp's edge takes over the outer points
    (widths of 6-10 m). Solved with them, no taper's levels stayed near the gap's widths
    and the lane closed linearly over the gap (edge 0.110 m); they are left out."""
    rng = np.random.default_rng(4)
    gap = (801.0, 879.0)
    s = np.arange(740.0, 940.0, 2.5)
    s = s[(s < gap[0]) | (s > gap[1])]
    true = 3.1 - 2.8 * _smoothstep((s - 840.0) / 65.0)
    w = true + rng.normal(0.0, 0.05, s.size)
    w[s > 925.0] = rng.uniform(6.0, 10.0, np.count_nonzero(s > 925.0))
    ends = tuple(3.1 - 2.8 * _smoothstep((np.array(gap) - 840.0) / 65.0))
    found = fitted_gap_taper(s, w, gap, ends)
    assert found is not None
    stations = np.arange(gap[0], gap[1])
    expected = 3.1 - 2.8 * _smoothstep((stations - 840.0) / 65.0)
    assert np.max(np.abs(taper_widths(found, stations) - expected)) < 0.25


def test_a_lane_gained_in_a_gap_widens_the_edge_with_its_line_seen_late():
    """oakland-28393854-s7 (seed 80): a lane gained beside the edge over 580-670 m, the
    edge hidden over 565-748 m and the new lane's line first seen at 626 m, 1.9 m out
    from the line it left. The outermost marking stepped there and the gap was bridged
    as at a gore: the edge kept its width to 626 m and jumped (1.8 m off over 40 m). The
    line is carried back along its slope to where it left its neighbour."""
    rng = np.random.default_rng(11)

    def move(s):
        return 3.5 * _smoothstep((np.asarray(s) - 580.0) / 90.0)

    s_l = np.arange(0.0, 1000.0, 0.5)
    lines = [(s_l, np.full(s_l.size, d)) for d in (1.0, 4.5, 8.0)]
    s_new = s_l[s_l >= 626.0]
    lines.append((s_new, 8.0 + move(s_new)))
    s_lane = np.concatenate([a for a, _ in lines])
    d_lane = np.concatenate([b for _, b in lines]) + rng.normal(0.0, 0.02, s_lane.size)
    s_out = np.arange(0.0, 1000.0, 0.2)
    s_out = s_out[(s_out < 565.0) | (s_out > 748.0)]
    d_out = 11.0 + move(s_out) + rng.normal(0.0, 0.05, s_out.size)
    sections, _, _, _ = fit_lanes(
        s_lane, d_lane, s_out, d_out, length=1000.0, sign=1.0, config=MainlineConfig()
    )
    for station in (570.0, 600.0, 615.0, 625.0, 640.0, 660.0, 700.0, 740.0):
        built, true = _edge_at(sections, station), 11.0 + float(move(station))
        # bridged as at a gore: 0.42 m off at 600 m, 1.75 m at 625 m
        assert abs(built - true) < 0.25, (station, built, true)
