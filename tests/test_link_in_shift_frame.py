"""Linking marking peaks in a frame that moves with the marking pattern.

Where two lanes are added on the median side, every line beyond moves out by two lanes
and the linking runs in a frame that moves with them (:mod:`roadtwin.mainline.shift`).
The median-side line stays where it is in the road: in that frame it moves by minus the
frame's move, while the outer of the two new lines, leaving it, is flat in the frame.
Following its own lagging trend, the median line's track took the new line
(melbourne-408-opp-s9: 2.3 m off over 100 m, lane count 96.1 %)."""

from __future__ import annotations

import numpy as np

from roadtwin.config import MainlineConfig
from roadtwin.mainline.markings import _link_tracks

N_COL = 40


def _frame_offset() -> np.ndarray:
    """The frame's offset per column (metres): 0, then out by 7 m over columns 10-26."""
    u = np.clip((np.arange(N_COL) - 10) / 16.0, 0.0, 1.0)
    return 7.0 * 0.5 * (1.0 - np.cos(np.pi * u))


def _peaks(offset: np.ndarray) -> list[np.ndarray]:
    """Per column, in the frame: the median line (1 m in the road; its paint worn over
    columns 13-15, where the shift gets going), the two new lines leaving it (to 4.5 and
    8 m in the road), and a through line at 4.5 m; lines within 0.8 m of one another are
    one peak."""
    out = []
    for c, off in enumerate(offset):
        cand = [1.0 - 0.5 * off, 1.0, 4.5]
        if not 13 <= c <= 15:
            cand.insert(0, 1.0 - off)
        kept: list[float] = []
        for v in cand:
            if all(abs(v - k) > 0.8 for k in kept):
                kept.append(v)
        out.append(np.sort(np.array(kept)))
    return out


def test_the_line_that_stays_in_the_road_is_one_track_through_the_shift():
    """After the worn stretch the median line's peaks (1 m in the road) are one track to
    the end, and no track joins them to another line (the old linking left them as
    single peaks and linked one of them to the new line at 4.5 m, 7 columns on)."""
    offset = _frame_offset()
    tracks = _link_tracks(_peaks(offset), MainlineConfig(), offset)
    road = [np.asarray(tr.d) + offset[tr.cols] for tr in tracks]
    late = [
        (tr, r)
        for tr, r in zip(tracks, road, strict=True)
        if tr.cols[0] >= 16 and abs(r[0] - 1.0) < 0.1
    ]
    assert len(late) == 1
    tr, r = late[0]
    assert tr.cols == list(range(16, N_COL))
    assert np.max(np.abs(r - 1.0)) < 0.05
    # every track past the shift follows one line of the road
    for tr, r in zip(tracks, road, strict=True):
        after = np.asarray(tr.cols) >= 26
        if np.count_nonzero(after) >= 2:
            assert np.ptp(r[after]) < 0.05
