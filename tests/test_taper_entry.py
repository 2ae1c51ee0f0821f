"""An entry whose acceleration lane closes by a taper from the nose on (a taper-type entry).

Past the nose the acceleration lane's outer line converges onto the through lanes with the
hard shoulder (and the road's edge) beside it. It is a line of the mainline, not a ramp's
line crossing the corridor: cut off as one, the acceleration lane and the shoulder were
built as one 5.9 m shoulder (a9 chain 206615404, seed 41: lane RMSE 0.145 m, lines 3.6 m
off over 100 m). A painted gore's line past the nose (the ramp's inner line converging
onto the through lanes while the acceleration lane runs on beyond it) and the ramp's own
shoulder line coming in with the ramp's edge at the ramp's angle are still cut."""

from __future__ import annotations

import numpy as np

from roadtwin.mainline.markings import _mainline_ends_inside_edge

GRID = np.arange(0.0, 400.0, 1.0)
NOSE_M = 200.0


def _edge(after_nose: np.ndarray) -> np.ndarray:
    """The outer edge (metres from the reference edge): 10.5 m up to the nose, then
    ``after_nose`` (evaluated on the grid stations past it)."""
    return np.where(GRID < NOSE_M, 10.5, after_nose)


def _converging(d0: float, d1: float, length_m: float) -> tuple[np.ndarray, np.ndarray]:
    g = np.arange(NOSE_M, NOSE_M + length_m, 1.0)
    return g, d0 + (d1 - d0) * (g - NOSE_M) / (length_m - 1.0)


def _kept(g: np.ndarray, d: np.ndarray, d_edge: np.ndarray, inner_d: float = 8.1) -> np.ndarray:
    """What of a line the ramp-line trim cut whole (it converges all along) is kept;
    ``inner_d``: the next line inward (the through lanes' outer line)."""
    cut = np.zeros(g.size, dtype=bool)
    return _mainline_ends_inside_edge(
        g, d, cut, GRID, d_edge, float(GRID[-1]), 10.0, inner_d=inner_d
    )


def test_a_taper_type_acceleration_lane_line_is_the_mainlines():
    """The line closes from 11.7 to 8.1 m over 110 m, the edge 2.3 m beyond it all along."""
    g, d = _converging(11.7, 8.1, 110.0)
    edge = _edge(np.clip(14.0 - 3.5 * (GRID - NOSE_M) / 110.0, 10.5, 14.0))
    assert _kept(g, d, edge).all()


def test_a_painted_gore_line_past_the_nose_is_cut():
    """The same line, but the edge stays a lane and a shoulder out: the acceleration lane
    runs on beyond the line, which is the ramp's inner line closing the painted gore."""
    g, d = _converging(11.7, 8.1, 110.0)
    edge = _edge(np.full(GRID.size, 14.0 + 3.5))
    assert not _kept(g, d, edge).any()


def test_the_ramps_outer_line_past_a_painted_gore_is_cut():
    """The ramp's outer line comes in with the edge, a shoulder inside it, but the gore
    and the ramp's lane lie between it and the through lanes: more than one lane."""
    g, d = _converging(15.2, 11.6, 110.0)
    edge = _edge(np.clip(17.5 - 3.5 * (GRID - NOSE_M) / 110.0, 14.0, 17.5))
    assert not _kept(g, d, edge).any()
    assert _kept(g, d, edge, inner_d=11.6).all()  # were the gore's line the next inward


def test_the_ramps_shoulder_line_coming_in_with_the_ramp_is_cut():
    """Edge and line come in together, but at the ramp's angle (3.3 m in 35 m), as on
    krems-24746399-s11: the ramp's own shoulder line, not a lane's taper."""
    g, d = _converging(14.8, 11.5, 35.0)
    edge = _edge(np.clip(16.6 - 2.4 * (GRID - NOSE_M) / 35.0, 14.2, 16.6))
    assert not _kept(g, d, edge).any()


def _run_end_tail(
    d_gain: float, *, seen_to_end: bool = False, s_end: float = 399.0, reach: float = 10.0
):
    """A line at 20.3 m that leaves it by a taper over 80 m from 300 m (cut there as a
    ramp's diverging line) up to the run's end at ``s_end``, moving out by ``d_gain``; the
    edge seen at 23.5 m up to 270 m (or ``seen_to_end``) and held there beyond."""
    g = np.arange(250.0, s_end + 0.5, 1.0)
    x = np.clip((g - 300.0) / 80.0, 0.0, 1.0)
    d = 20.3 + d_gain * x * x * (3.0 - 2.0 * x)
    keep = g <= 302.0
    seen = np.ones(GRID.size, dtype=bool) if seen_to_end else GRID < 270.0
    return _mainline_ends_inside_edge(
        g,
        d,
        keep,
        GRID,
        np.full(GRID.size, 23.5),
        float(GRID[-1]),
        reach,  # two columns: the run's end cuts the line
        settle_slope=0.012,
        edge_seen=seen,
    )


def test_a_run_end_line_levelling_off_a_lane_out_is_a_new_lanes():
    """oakland-28393854-lane1-s21 with a noisier sensor (seed offset 320): a lane gained
    by a taper over the run's last 80 m, the edge hidden there (held at its last seen
    offset, the line ends 0.2 m beyond it). The diverging tail levels off a lane's width
    out: the new lane's line, kept (cut as an exit's, the lane was missing: lane RMSE
    0.264 -> 0.149 m)."""
    assert _run_end_tail(3.7)[~(np.arange(250.0, 399.5) <= 302.0)].all()
    # still leaving at the run's end (a ramp's line), or moved out by more than a lane
    assert not _run_end_tail(3.7, s_end=340.0).any()
    assert not _run_end_tail(6.0).any()
    # where the edge was seen beside it and the line crossed it: a ramp's
    assert not _run_end_tail(3.7, seen_to_end=True).any()


def test_a_broken_line_s_last_dash_a_dash_gap_before_the_run_s_end_is_cut_by_it():
    """oakland-28393854-lane1-s21 with a noisier sensor (seed offset 500): the new lane's
    broken line last seen 12 m before the run's end, its dashes up to 15 m apart there."""
    tail = ~(np.arange(250.0, 387.5) <= 302.0)
    assert not _run_end_tail(3.7, s_end=387.0).any()  # two columns: not the run's end
    assert _run_end_tail(3.7, s_end=387.0, reach=15.0)[tail].all()


def test_the_next_line_inward_may_be_first_seen_a_dash_late():
    """a9-8081560-s11 with a noisier sensor: two lanes gained at once, the outer one
    closing by a taper from 19.4 m; the inner one's line (15.65 m) first seen 9 m after
    the outer one's start. Taken where the outer line starts, the next line inward was
    the through lanes' (11.9 m): two lanes inside it, and the closing line was cut as a
    ramp's."""
    from roadtwin.mainline.markings import _next_line_inward, _Track

    def track(lo, hi, d):
        s = np.arange(lo, hi + 1.0)
        return _Track(0, lo, hi, s, np.full(s.size, d), "broken", s.size, s, np.full(s.size, d))

    g = np.arange(735.0, 861.0)
    fit = 19.4 - 3.7 * (g - 735.0) / 125.0
    cand = [track(0.0, 2000.0, 11.9), track(744.0, 2000.0, 15.65), track(735.0, 860.0, 0.0)]
    inner = _next_line_inward(cand, 2, g, fit)
    assert inner is not None
    # the narrowest strip over the first 15 m where both are seen
    assert abs((fit[0] - inner) - (fit[15] - 15.65)) < 1e-9
    assert fit[0] - inner < 4.75  # one lane: the closing line is the mainline's
    # an inner line first seen farther on does not count
    late = [track(0.0, 2000.0, 11.9), track(760.0, 2000.0, 15.65), track(735.0, 860.0, 0.0)]
    assert fit[0] - _next_line_inward(late, 2, g, fit) > 4.75
