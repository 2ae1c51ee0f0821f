"""A shoulder split by a painted line over part of the road (CARLA Town06: 0.64 + 0.5 m
beside the median, the split painted over a few hundred metres only).

Where the split's paint stops, the two narrow strips become one shoulder. Built before as
two strips that ended unlinked at a section border, both closed to zero width there and
every lane outside them stepped 1.15 m towards the median for 40 m
(town06-auto-lane1-s21: lane boundaries 0.24 m RMSE, the outer edge 1.1 m off)."""

from __future__ import annotations

import numpy as np

from roadtwin.check import check_network
from roadtwin.config import MainlineConfig
from roadtwin.mainline import fit_lanes
from roadtwin.model import Line, Road
from test_occluded_lane_changes import _line


def _borders_at(sections, station):
    """Offsets (metres from the reference) of every lane border of right-hand sections."""
    sc = sections[max(i for i, sc in enumerate(sections) if sc.s0 <= station)]
    ds = np.array([station - sc.s0])
    widths = [float(ln.width.value(ds)[0]) for ln in sc.right]
    return np.cumsum(widths), [ln.type for ln in sc.right]


def _split_shoulder_run(seed: int):
    """Lines at 1.14 m (the inner shoulder's line), 4.64 and 8.14 m over 1000 m; the split
    line at 0.64 m painted from 300 to 600 m only; the outer edge at 9.3 m."""
    rng = np.random.default_rng(seed)
    parts = [_line(rng, 0, 1000, d) for d in (1.14, 4.64, 8.14)]
    parts.append(_line(rng, 300, 600, 0.64))
    s_out, d_out = _line(rng, 0, 1000, 9.3, 0.2)
    s_lane = np.concatenate([p[0] for p in parts])
    d_lane = np.concatenate([p[1] for p in parts])
    return fit_lanes(s_lane, d_lane, s_out, d_out, length=1000.0, sign=1.0, config=MainlineConfig())


def test_the_lanes_keep_their_place_where_a_split_shoulders_paint_ends():
    sections, _, _, _ = _split_shoulder_run(seed=4)
    for station in np.arange(5.0, 995.0, 1.0):
        borders, types = _borders_at(sections, station)
        driving = [i for i, t in enumerate(types) if t == "driving"]
        assert len(driving) == 2, station
        inner = borders[driving[0] - 1]  # the driving lanes' inner border
        # within 5 cm of the shoulder's line everywhere (1.15 m off next to the paint's
        # ends before)
        assert abs(inner - 1.14) < 0.05, (station, inner)
        assert abs(borders[driving[1]] - 8.14) < 0.05, station
        assert abs(borders[-1] - 9.3) < 0.08, station


def test_the_split_is_built_where_it_is_painted_and_merges_into_the_line_beside_it():
    sections, _, _, _ = _split_shoulder_run(seed=5)
    borders, types = _borders_at(sections, 450.0)
    assert types[:2] == ["shoulder", "shoulder"]
    np.testing.assert_allclose(borders[:2], [0.64, 1.14], atol=0.05)
    # 20 m past the paint's end the split has met the shoulder's line: one shoulder
    borders, types = _borders_at(sections, 625.0)
    assert types[:2] == ["shoulder", "driving"]
    assert abs(borders[0] - 1.14) < 0.05
    borders, types = _borders_at(sections, 275.0)
    assert types[:2] == ["shoulder", "driving"]


def test_the_merged_split_is_a_valid_road():
    """The own checker on the road built: no width jump at a link, no negative width, no
    lane linked at its zero-width end (the strips close within the section)."""
    from dataclasses import replace

    from test_evaluation import make_truth

    sections, _, _, _ = _split_shoulder_run(seed=6)
    base = make_truth()
    road = Road("1", (Line(0.0, 0.0, 0.0, 0.0, 1000.0),), tuple(sections), name="mainline")
    findings = check_network(replace(base, roads=(road,), junctions=()))
    bad = {"width_jump", "negative_width", "zero_width_link", "lane_shift"}
    assert [f for f in findings if f.severity == "error" and f.code in bad] == []


def _peak_offsets(lines, length=300.0, seed=7):
    """Column peaks (metres) of lane samples along ``lines`` (functions of the station)."""
    from roadtwin.mainline.markings import _find_track_peaks

    rng = np.random.default_rng(seed)
    s = np.arange(0.0, length, 0.5)
    d = np.concatenate([f(s) + rng.normal(0.0, 0.02, s.size) for f in lines])
    _, peaks = _find_track_peaks(np.tile(s, len(lines)), d, length, MainlineConfig())
    return peaks


def test_a_parallel_double_line_is_two_markings_a_ramp_line_leaving_is_not_doubled():
    """Two lines 0.5 m apart all along: two peaks in (nearly) every column. A ramp's line
    leaving a marking at 1:50 from 100 m on lies 0.35-0.8 m from it over 80-140 m, moving
    0.1 m per column: one peak there (closer than ``lane_min_separation_m``, it is left to
    the tracks' linking as before)."""
    parallel = _peak_offsets([lambda s: np.full(s.size, 1.14), lambda s: np.full(s.size, 0.64)])
    doubled = [
        np.count_nonzero(np.abs(np.sort(p)[:2] - [0.64, 1.14]) < 0.05) == 2 for p in parallel
    ]
    assert np.mean(doubled) > 0.9
    leaving = _peak_offsets(
        [lambda s: np.full(s.size, 1.14), lambda s: 1.14 + 0.02 * np.clip(s - 100.0, 0.0, None)]
    )
    cfg = MainlineConfig()
    for col, p in enumerate(leaving):
        sep = 0.02 * max(col * cfg.lane_column_m + 2.5 - 100.0, 0.0)
        if 0.4 < sep < 0.7:
            assert p.size == 1, (col, p)


def test_a_pair_of_lines_moving_sideways_together_is_not_doubled():
    """Two lines 0.5 m apart moving sideways at 0.05 m/m (a shifting pattern, lines lost
    where they cross): one peak per column as before. Doubled, Town06 seen by a narrow
    sensor broke into pieces too short to keep and left one lane 15 m wide."""
    moving = _peak_offsets([lambda s: 1.14 + 0.05 * s, lambda s: 1.64 + 0.05 * s], length=200.0)
    assert np.mean([p.size == 1 for p in moving]) > 0.9
