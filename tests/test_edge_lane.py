"""A lane the outer edge borders goes on where a hard shoulder opens beyond it.

oakland-28393854-lane1-s21 with a noisier sensor (seed offsets 320 and 560): a lane added
on the outer side, the edge its outer border (no shoulder), then the edge moving out by a
shoulder's width; the lane's line, 13-14 m from the car, was never seen. Read afresh from
the run's typical shoulder, the wider strip was a lane opening by a taper from the line
inward where the edge moved out (lanes 0.149 m, lane count 98.2 %), or (where the lane's
own 3.6 m strip had been taken for a shoulder) the lane was missing over 280 m (lane
count 87.4 %). ``hidden_lanes._add_hidden_lanes`` keeps the lane at its width.
"""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.hidden_lanes import _add_hidden_lanes
from roadtwin.mainline.markings import _Track

CFG = MainlineConfig()
GRID = np.arange(0.0, 2000.5, 1.0)


def _line(k: int, lo: float, hi: float, d: float) -> _Track:
    g = GRID[(lo <= GRID) & (hi >= GRID)]
    return _Track(k, lo, hi, g, np.full(g.size, d), "broken", g.size, g)


def _ramp(lo: float, hi: float, a: float, b: float) -> np.ndarray:
    return a + (b - a) * np.clip((GRID - lo) / (hi - lo), 0.0, 1.0)


def _layout(opens_from_zero: bool) -> tuple[list[_Track], np.ndarray]:
    """Four lanes seen (lines at 1.2, 4.8, 8.4, 12.0 m), the fourth lane's outer line
    seen only from 1200 m (15.6 m) with a 3 m shoulder beyond; before that the edge
    borders that lane from 460 m (15.6 m), and moves out by the shoulder over 800-860 m.
    Before 400 m the strip beyond 12.0 m is a 3 m shoulder (``opens_from_zero``: no
    shoulder, the lane opening by the edge's taper over 400-460 m)."""
    tracks = [_line(k, 0.0, 2000.0, d) for k, d in enumerate((1.2, 4.8, 8.4, 12.0))]
    tracks.append(_line(4, 1200.0, 2000.0, 15.6))
    before = 12.0 if opens_from_zero else 15.0
    d_edge = _ramp(400.0, 460.0, before, 15.6) + _ramp(800.0, 860.0, 0.0, 3.0)
    return tracks, d_edge


def _offset_at(tracks: list[_Track], s: float, near: float) -> float:
    """The offset (metres) of the track nearest ``near`` at station ``s`` (inf if none)."""
    here = [float(np.interp(s, t.s, t.d)) for t in tracks if t.lo <= s <= t.hi]
    return min(here, key=lambda d: abs(d - near), default=np.inf)


def test_the_line_stays_where_the_edge_was_as_a_shoulder_opens():
    tracks, d_edge = _layout(opens_from_zero=True)
    out = _add_hidden_lanes(tracks, GRID, d_edge, np.zeros(GRID.size), CFG)
    # the lane's outer line runs on at 15.6 m through the shoulder's opening (the edge
    # moved 1.5 m out by 830 m: read afresh, the line tapered in from 12.0 m there)
    for s in (820.0, 830.0, 850.0, 900.0, 1100.0):
        d = _offset_at(out, s, 15.6)
        assert abs(d - 15.6) < 0.15, (s, d)
    # ... and back to where the edge's taper opened the lane (it borders the lane there)
    assert abs(_offset_at(out, 600.0, 15.6) - 15.6) < 0.15
    # on the edge, halfway through its taper
    assert abs(_offset_at(out, 430.0, 13.8) - 13.8) < 0.2


def test_a_lane_wide_strip_after_a_shoulder_is_the_lane_not_a_wider_shoulder():
    tracks, d_edge = _layout(opens_from_zero=False)
    out = _add_hidden_lanes(tracks, GRID, d_edge, np.zeros(GRID.size), CFG)
    # 3.6 m from the last line to the edge over 460-800 m: the lane goes on there
    for s in (500.0, 700.0, 830.0):
        d = _offset_at(out, s, 15.6)
        assert abs(d - 15.6) < 0.15, (s, d)
    # the 3 m strip before it stays a shoulder: no line beyond 12.0 m there
    assert _offset_at(out, 300.0, 15.0) == 12.0
