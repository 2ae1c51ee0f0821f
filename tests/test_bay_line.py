"""A line that a bay's line bulges out of and back into goes on straight across the bay.

A lay-by (or bus bay) opens beside the outer lane: its line leaves the lane's line,
bulges 1.4 m out and comes back over 130 m, and the lane's own line goes on straight,
dashed. The two share one histogram peak wherever they lie closer than
``lane_min_separation_m``; the dashed line is a peak of its own over 60 m only, and with a
dash or two lost (krems-24980555-s11 with a noisier sensor) it was too short for a track:
the lane's boundary followed the bay, 1.3 m off."""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.linking import _RawTrack
from roadtwin.mainline.markings import _tracks_from_samples
from roadtwin.mainline.raw_joins import _into_merging_peaks

LENGTH_M = 1200.0
BAY = (500.0, 630.0)  # stations (metres) where the bay's line leaves and rejoins
BULGE_M = 1.4


def _bay_line(s: np.ndarray) -> np.ndarray:
    u = np.clip((s - BAY[0]) / (BAY[1] - BAY[0]), 0.0, 1.0)
    return 8.0 + BULGE_M * 0.5 * (1.0 - np.cos(2.0 * np.pi * u))


def _samples(lost_dashes: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Lane samples (stations, offsets in metres) every 0.5 m along: a solid line at
    0.6 m, a dashed one at 4.3 m (6 m dash, 12 m gap), the outer lane's solid line at 8 m
    that bulges into the bay, and inside the bay the lane's own dashed line at 8 m, its
    dashes numbered from the bay's start ``lost_dashes`` left out. Noise 3 cm, seeded."""
    rng = np.random.default_rng(7)
    s = np.arange(0.0, LENGTH_M, 0.5)
    dashed = np.mod(s, 18.0) < 6.0
    parts = [(s, np.full(s.size, 0.6)), (s[dashed], np.full(int(dashed.sum()), 4.3))]
    parts.append((s, _bay_line(s)))
    inside = (s > BAY[0] + 5.0) & (s < BAY[1] - 5.0) & dashed
    dash_no = np.floor((s - BAY[0]) / 18.0).astype(int)
    inside &= ~np.isin(dash_no, lost_dashes)
    parts.append((s[inside], np.full(int(inside.sum()), 8.0)))
    ss = np.concatenate([p[0] for p in parts])
    dd = np.concatenate([p[1] for p in parts]) + rng.normal(0.0, 0.03, ss.size)
    return ss, dd


def _straight_line_across_bay(tracks) -> float:
    """Metres of the bay (its middle 80 m) where some track lies within 0.15 m of 8 m."""
    grid = np.arange(BAY[0] + 25.0, BAY[1] - 25.0, 1.0)
    covered = np.zeros(grid.size, dtype=bool)
    for tr in tracks:
        inside = (grid >= tr.s[0]) & (grid <= tr.s[-1])
        covered |= inside & (np.abs(np.interp(grid, tr.s, tr.d) - 8.0) < 0.15)
    return float(covered.sum())


# column peaks (5 m columns) of krems-24980555-s11+80 at its lay-by: the bay's line from
# column 318 on, and the lane's straight dashed line where it was a peak of its own
BAY_LINE = [
    8.02,
    8.06,
    7.98,
    8.07,
    8.08,
    8.12,
    8.26,
    8.41,
    8.56,
    8.71,
    8.88,
    9.02,
    9.13,
    9.23,
    9.33,
    9.38,
    9.38,
    9.33,
    9.28,
    9.16,
    9.02,
    8.83,
    8.73,
    8.53,
    8.37,
    8.23,
    8.18,
    8.07,
    8.07,
    8.06,
    8.03,
    8.03,
]
STRAIGHT = {328: 8.07, 331: 8.06, 332: 8.03, 334: 8.09, 335: 8.08, 338: 8.03, 339: 8.04}


def _peaks(raw: list[_RawTrack]):
    col = np.concatenate([np.asarray(tr.cols) for tr in raw])
    d = np.concatenate([np.asarray(tr.d, dtype=float) for tr in raw])
    owner = np.repeat(np.arange(len(raw)), [len(tr.cols) for tr in raw])
    return col, d, owner


def test_a_short_line_goes_on_where_the_bay_line_closes_on_it():
    cfg = MainlineConfig()
    bay = _RawTrack(list(range(318, 318 + len(BAY_LINE))), list(BAY_LINE))
    straight = _RawTrack(list(STRAIGHT), list(STRAIGHT.values()))
    out = _into_merging_peaks([bay, straight], cfg, _peaks([bay, straight]))
    assert out[0].cols == bay.cols  # the bay's line is long: left as it is
    # carried on over the columns where the bay's line lay 0.1-0.8 m from it and closing:
    # 12 columns (60 m, as short as a track may be) become 21 (105 m)
    assert out[1].cols[0] == 324
    assert out[1].cols[-1] == 344
    level = float(np.median(list(STRAIGHT.values())))
    assert out[1].d[0] == level
    assert out[1].d[-1] == level
    assert len(out[1].cols) == len(STRAIGHT) + 4 + 5


def test_a_short_line_beside_a_parallel_one_is_not_carried_on():
    """A line 0.3 m beside it that does not close on it (paint beside a line) carries a
    short line on by one column at most; a line as long as two tracks is not touched."""
    cfg = MainlineConfig()
    line = _RawTrack(list(range(40)), [8.3] * 40)
    short = _RawTrack(list(range(15, 25)), [8.0] * 10)
    out = _into_merging_peaks([line, short], cfg, _peaks([line, short]))
    assert out[1].cols[0] >= 14
    assert out[1].cols[-1] <= 25
    n_long = int(2 * cfg.lane_min_track_m / cfg.lane_column_m)
    closing = _RawTrack(list(range(60)), [8.0 + 0.1 * max(0, 30 - c) for c in range(60)])
    long_line = _RawTrack(list(range(30, 30 + n_long)), [8.0] * n_long)
    out = _into_merging_peaks([closing, long_line], cfg, _peaks([closing, long_line]))
    assert out[1].cols == long_line.cols


def test_the_lane_line_goes_on_straight_across_a_bay_with_dashes_lost():
    cfg = MainlineConfig()
    s, d = _samples(lost_dashes=(1, 5))
    grid = np.arange(0.0, LENGTH_M + 1.0, cfg.grid_step_m)
    tracks, _ = _tracks_from_samples(s, d, grid, LENGTH_M, cfg)
    assert _straight_line_across_bay(tracks) >= 79.0
    # the bay's own line is kept too: 1.4 m out at the bay's middle
    mid = 0.5 * (BAY[0] + BAY[1])
    out = [float(np.interp(mid, tr.s, tr.d)) for tr in tracks if tr.s[0] <= mid <= tr.s[-1]]
    assert any(abs(v - 9.4) < 0.15 for v in out)


def test_a_line_beside_another_that_does_not_close_on_it_is_not_carried_on():
    """Paint 0.5 m beside a line for 40 m (a patch, a repair) stays too short for a
    track: the line beside it does not close on it."""
    cfg = MainlineConfig()
    rng = np.random.default_rng(3)
    s = np.arange(0.0, LENGTH_M, 0.5)
    patch = (s > 500.0) & (s < 540.0)
    ss = np.concatenate([s, s, s[patch]])
    dd = np.concatenate(
        [np.full(s.size, 0.6), np.full(s.size, 8.0), np.full(int(patch.sum()), 7.4)]
    )
    dd = dd + rng.normal(0.0, 0.03, ss.size)
    grid = np.arange(0.0, LENGTH_M + 1.0, cfg.grid_step_m)
    tracks, _ = _tracks_from_samples(ss, dd, grid, LENGTH_M, cfg)
    assert len(tracks) == 2
