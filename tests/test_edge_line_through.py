"""The edge's own line seen through an unseen stretch of the edge holds the edge there.

melbourne-1019-lane1-s21 with the quiet sensor (bench_real ``--seed-offset 860``): the
median-side edge was unseen over 106 m before an inner exit's nose; its 4.5 m step was
bridged as a taper over the whole stretch (the edge up to 4.2 m off, lanes 0.323 m RMSE),
though the inner shoulder's line, 1 m inside the edge, was seen all through it. The edge
cannot cross its own line: the step lies at the stretch's far end.
"""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.mainline.gap_evidence import edge_line_through

GAP = (500.0, 606.0)
OUTER, INNER = 6.24, 1.77  # the edge's level before the exit and after it (m, towards it)


def _line(leaves_at: float | None = None, lost_at: float | None = None, seed: int = 2):
    """Lane samples (s, u) of the inner shoulder's line at 5.2 m, solid, every 0.25 m from
    400 to 650 m; leaving outward (towards the edge) at 0.1 m/m from ``leaves_at``, or not
    seen after ``lost_at``; and a lane line at 1.8 m."""
    rng = np.random.default_rng(seed)
    s = np.arange(400.0, 650.0, 0.25)
    u = np.full(s.size, 5.2)
    if leaves_at is not None:
        u += 0.1 * np.clip(s - leaves_at, 0.0, None)
    keep = s < lost_at if lost_at is not None else np.ones(s.size, bool)
    s, u = s[keep], u[keep]
    s_lane = np.arange(400.0, 650.0, 0.25)
    s_lane = s_lane[(s_lane % 12.0) < 3.0]
    s_all = np.concatenate([s, s_lane])
    u_all = np.concatenate([u, np.full(s_lane.size, 1.8)]) + rng.normal(0.0, 0.03, s_all.size)
    order = np.argsort(s_all, kind="stable")
    return s_all[order], u_all[order]


def test_a_line_seen_through_the_gap_holds_the_edge_to_its_far_end():
    assert edge_line_through(*_line(), GAP, OUTER, INNER, forward=True)


@pytest.mark.parametrize(
    ("case", "inner"),
    [("leaves", INNER), ("lost", INNER), ("none", 5.0)],
)
def test_no_hold_where_the_line_leaves_is_lost_or_the_edge_stays_outside_it(case, inner):
    """A line leaving in the gap tells the gore itself (edge_line_departure); one lost
    halfway tells nothing of the rest; an edge whose level on the other side stays
    outside the line may have tapered beside it."""
    pts = (
        _line(leaves_at=550.0)
        if case == "leaves"
        else _line(lost_at=540.0)
        if case == "lost"
        else _line()
    )
    assert not edge_line_through(*pts, GAP, OUTER, inner, forward=True)


def test_an_entry_is_walked_back_from_the_gaps_end():
    s, u = _line()
    # mirrored: the stretch walked back from its end, the line seen through it
    assert edge_line_through(1050.0 - s[::-1], u[::-1], (444.0, 550.0), OUTER, INNER, forward=False)
