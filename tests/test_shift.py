"""The marking pattern's sideways shift (roadtwin.mainline.shift) and the tracks found in
the frame that moves with it (roadtwin.mainline.markings)."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.config import MainlineConfig
from roadtwin.mainline.hidden_lanes import _inner_shoulder_line
from roadtwin.mainline.markings import (
    _edge_in_frame,
    _find_track_peaks,
    _link_tracks,
    _shift_frame,
    _tracks_from_samples,
)
from roadtwin.mainline.shift import (
    OuterEdge,
    ShiftFrame,
    _lines_follow,
    _pattern_shift,
    _straightest,
)

LENGTH = 700.0
LANE = 3.5


def _smoothstep(s: np.ndarray, s0: float, s1: float) -> np.ndarray:
    x = np.clip((s - s0) / (s1 - s0), 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _line(rng, offset, s0=0.0, s1=LENGTH, dashed=True):
    """Samples (s, d) of one marking: every 0.25 m, 3 m dashes every 12 m (or solid),
    3 cm noise; ``offset(s)`` its offset (metres)."""
    s = np.arange(s0, s1, 0.25)
    if dashed:
        s = s[(s % 12.0) < 3.0]
    return s, offset(s) + rng.normal(0.0, 0.03, s.size)


def _samples(lines):
    s = np.concatenate([a for a, _ in lines])
    d = np.concatenate([b for _, b in lines])
    order = np.argsort(s, kind="stable")
    return s[order], d[order]


def _median_side_lanes_added(rng, lanes=1, s0=300.0, s1=380.0):
    """``lanes`` lanes added beside the median over s0..s1: the median-side edge line
    stays at 1.0 m, the three lines beyond it move out by as many lane widths, and the
    new lanes' lines leave the edge line (reference frame: the median-side edge)."""
    move = lambda s: lanes * LANE * _smoothstep(s, s0, s1)  # noqa: E731
    lines = [
        _line(rng, lambda s: np.full(s.size, 1.0), dashed=False),
        _line(rng, lambda s: 1.0 + LANE + move(s)),
        _line(rng, lambda s: 1.0 + 2 * LANE + move(s)),
        _line(rng, lambda s: 1.0 + 3 * LANE + move(s), dashed=False),
    ]
    for k in range(1, lanes + 1):  # the new lines, each reaching its place with the others
        lines.append(_line(rng, lambda s, k=k: 1.0 + k / lanes * move(s), s0=s0 + 10.0))
    return _samples(lines), move


def _frame(s, d, cfg, edge=None):
    centres, peaks = _find_track_peaks(s, d, LENGTH, cfg)
    return _shift_frame(s, d, LENGTH, centres, _link_tracks(peaks, cfg), cfg, edge)


def _outer_edge(rng, offset, unseen=None):
    """The outer edge as the shift sees it: a smooth fit on a 1 m grid (2 cm noise),
    NaN over ``unseen`` (s0, s1)."""
    grid = np.arange(0.0, LENGTH + 0.5, 1.0)
    d = offset(grid) + rng.normal(0.0, 0.02, grid.size)
    if unseen is not None:
        d[(grid >= unseen[0]) & (grid <= unseen[1])] = np.nan
    return OuterEdge(grid, d)


def _fast_swing(rng, dash, period, s0=300.0, s1=345.0):
    """Every line but the innermost swings out by a lane over 45 m (town06-auto-s1 after
    its inner exit: broken lines sampled every metre, a few dashes through the swing);
    a new line leaves the innermost one (a lane added beside the median)."""
    move = lambda s: LANE * _smoothstep(s, s0, s1)  # noqa: E731

    def line(offset, start=0.0, phase=0.0):
        s = np.arange(start, LENGTH, 1.0)
        s = s[((s + phase) % period) < dash]
        return s, offset(s) + rng.normal(0.0, 0.05, s.size)

    lines = [_line(rng, lambda s: np.full(s.size, 1.0), dashed=False)]
    lines += [line(lambda s, k=k: 1.0 + k * LANE + move(s), phase=5.0 * k) for k in (1, 2, 3)]
    lines.append(line(lambda s: 1.0 + move(s), start=s0 + 10.0))
    edge = _outer_edge(rng, lambda s: 1.0 + 3 * LANE + 1.0 + move(s))
    return _samples(lines), edge, move


@pytest.mark.parametrize(("dash", "period"), [(3.0, 12.0), (6.0, 18.0)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_fast_swing_of_broken_lines_is_found_with_the_outer_edge_as_witness(dash, period, seed):
    """A broken line has a dash or two in a 20 m window: sheared, its samples pile up
    little better than straight, and the rates caught none or part of a 45 m swing
    (town06-auto-s1: 0.5 of 3.5 m with the heading bias removed, 4 routes lost; the same
    run without it 2.2 m, snapped). The outer edge is seen all through and moves with
    the lines: the whole swing is found, shaped like the edge's move."""
    cfg = MainlineConfig()
    (s, d), edge, move = _fast_swing(np.random.default_rng(seed), dash, period)
    frame = _frame(s, d, cfg, edge)
    assert frame is not None
    at = np.array([100.0, 290.0, 310.0, 322.5, 335.0, 355.0, 600.0])
    err = np.abs(frame.offset(at) - move(at))
    # none before the swing, the lane after it (the lines' pattern says how far, within
    # a bin or two); within 0.6 m halfway (the rates the few dashes show refine the
    # edge's shape, and a dash or two sway it)
    mid = (at > 300.0) & (at < 345.0)
    assert float(np.max(err[~mid])) < 0.2, err
    assert float(np.max(err[mid])) < 0.6, err
    assert frame.deepest_m == pytest.approx(LANE, abs=0.15)


@pytest.mark.parametrize("lanes", [1, 2])
def test_the_shift_of_lines_moving_out_by_lanes_is_found_where_and_how_far_it_goes(lanes):
    cfg = MainlineConfig()
    (s, d), move = _median_side_lanes_added(np.random.default_rng(1), lanes)
    frame = _frame(s, d, cfg)
    assert frame is not None
    at = np.array([0.0, 250.0, 290.0, 340.0, 390.0, 450.0, 650.0])
    made = np.interp(at, frame.stations, frame.shift) - float(frame.shift[0])
    # none before the lanes move, the lanes' widths after them (within 0.15 m), about half
    # of it halfway (within 0.4 m: the path's steps are a window long)
    err = np.abs(made - move(at))
    assert float(np.max(err[at != 340.0])) < 0.15, made
    assert float(err[at == 340.0][0]) < 0.4, made
    assert float(np.max(np.abs(frame.rate(np.array([100.0, 600.0]))))) < 1e-9
    # the frame is the reference line's until the lines move (the same histogram bins,
    # peaks and tracks there), and the histogram reaches as far below as it moves them
    assert float(np.max(np.abs(frame.offset(np.linspace(0.0, 250.0, 20))))) == 0.0
    assert frame.deepest_m == pytest.approx(lanes * LANE, abs=0.15)


def test_an_edge_moved_a_lane_farther_than_the_lines_does_not_set_the_shift():
    """melbourne-408-opp-s4: two lanes are added beside the median (the lines move 7 m)
    where an entry joins at the outer edge (the edge moves 10.5 m). The lines matched
    best within half a metre of the edge's move at 10.4 m, a lane too far (lanes 0.33 m,
    one 13 m wide); the lines' own best match is 7 m: the edge tells no lane there, and
    the shift is the one the rates and patterns find without it."""
    cfg = MainlineConfig()
    rng = np.random.default_rng(4)
    (s, d), move = _median_side_lanes_added(rng, lanes=2)
    edge = _outer_edge(rng, lambda x: 2.0 + 3 * LANE + 1.5 * move(x))
    frame = _frame(s, d, cfg, edge)
    assert frame is not None
    assert float(frame.shift[-1]) == pytest.approx(2 * LANE, abs=0.15)
    # the patterns alone: before the stretch four lines, after it the same moved by two
    # lanes and the innermost's two new ones; near the edge's 10.5 m the pattern matches
    # three lines, at 7 m four
    from roadtwin.mainline.shift import _pattern_shift

    before = [1.0 + k * LANE for k in range(4)]
    after = [1.0, 1.0 + LANE, *(1.0 + (k + 2) * LANE for k in range(4))]
    st = np.arange(0.0, 30.0, 0.5)
    s2 = np.concatenate([st for _ in before] + [st + 130.0 for _ in after])
    d2 = np.concatenate([np.full(st.size, v) for v in before + after])
    owner = np.repeat(np.arange(len(before) + len(after)), st.size)
    near = {"near_m": 0.5}
    assert _pattern_shift(s2, d2, owner, 30.0, 130.0, 10.5, **near) is None
    assert _pattern_shift(s2, d2, owner, 30.0, 130.0, 7.1, **near) == pytest.approx(7.0)


@pytest.mark.parametrize(
    "what",
    [
        "straight",
        "a bump of a metre",
        "an exit's lines leaving",
        "an outer lane opening",
        "an outer lane opening fast beside a double edge line",
        "an outer lane closing",
    ],
)
def test_no_shift_where_the_pattern_does_not_move_as_a_whole(what):
    """Straight lines; every line swinging out by 1 m and back (the linking follows
    that itself); a ramp's two lines leaving the others; the edge line moving out (in)
    by a lane where a lane opens (closes) on the outside: the frame stays the reference
    line's, with or without the outer edge as a witness."""
    rng = np.random.default_rng(2)
    flat = [
        _line(rng, lambda s, k=k: np.full(s.size, 1.0 + k * LANE), dashed=0 < k < 3)
        for k in range(4)
    ]
    bump = lambda s: np.exp(-(((s - 350.0) / 40.0) ** 2))  # noqa: E731
    leave = lambda s: 0.08 * np.clip(s - 300.0, 0.0, None)  # noqa: E731
    if what == "straight":
        lines = flat
    elif what == "a bump of a metre":
        lines = [_line(rng, lambda s, k=k: 1.0 + k * LANE + bump(s)) for k in range(4)]
    elif what == "an exit's lines leaving":
        lines = [
            *flat,
            _line(rng, lambda s: 1.0 + 3 * LANE + leave(s), s0=300.0, s1=420.0, dashed=False),
            _line(rng, lambda s: 1.0 + 4 * LANE + leave(s), s0=300.0, s1=420.0, dashed=False),
        ]
    elif what == "an outer lane opening":
        opening = lambda s: 1.0 + 3 * LANE + LANE * _smoothstep(s, 300.0, 380.0)  # noqa: E731
        lines = [*flat[:3], _line(rng, opening, dashed=False)]
    elif what == "an outer lane closing":
        # soderleden-s7: the solid edge line moves in onto the broken line beside it
        opening = lambda s: 1.0 + 3 * LANE - LANE * _smoothstep(s, 300.0, 345.0)  # noqa: E731
        lines = [*flat[:3], _line(rng, opening, dashed=False)]
    else:
        # Town06's entries: the edge line and the shoulder's split line 0.5 m beyond it
        # swing out by a lane over 45 m, a broken line goes on where the edge line was
        opening = lambda s: 1.0 + 3 * LANE + LANE * _smoothstep(s, 300.0, 345.0)  # noqa: E731
        lines = [
            *flat[:3],
            _line(rng, opening, dashed=False),
            _line(rng, lambda s: opening(s) + 0.5, dashed=False),
            _line(rng, lambda s: np.full(s.size, 1.0 + 3 * LANE), s0=305.0),
        ]
    s, d = _samples(lines)
    assert _frame(s, d, MainlineConfig()) is None
    # the outer edge 1 m beyond the outermost line, moving with it where a lane opens:
    # it moves alone, or not at all, and witnesses no shift
    if what in ("straight", "a bump of a metre", "an exit's lines leaving"):
        d_edge = lambda s: np.full(s.size, 2.0 + 3 * LANE)  # noqa: E731
    else:
        d_edge = lambda s: opening(s) + 1.0  # noqa: E731
    edge = _outer_edge(rng, d_edge)
    assert _frame(s, d, MainlineConfig(), edge) is None


def test_lines_that_move_out_by_two_lanes_are_whole_tracks_that_follow_them():
    """Two lanes added beside the median, every line beyond moving out by 7 m over 80 m
    (melbourne-921-s9). Found line by line, the moving lines were cut where they are
    steep (ramp lines) and the pieces joined to other lines: lanes up to 7.5 m wide. In
    the moving frame each is one track from end to end, on the line within 0.15 m."""
    cfg = MainlineConfig()
    (s, d), move = _median_side_lanes_added(np.random.default_rng(3), lanes=2)
    grid = np.arange(0.0, LENGTH + 0.5, cfg.grid_step_m)
    tracks, _ = _tracks_from_samples(s, d, grid, LENGTH, cfg)
    for k in (1, 2, 3):
        truth = lambda x, k=k: 1.0 + k * LANE + move(x)  # noqa: E731
        on = [
            tr
            for tr in tracks
            if tr.lo < 20.0
            and tr.hi > LENGTH - 20.0
            and float(np.max(np.abs(tr.d - truth(tr.s)))) < 0.15
        ]
        assert len(on) == 1, f"line {k}: {[(tr.lo, tr.hi) for tr in tracks]}"
    # the median-side edge line stays a whole straight line too
    edge = [tr for tr in tracks if tr.lo < 20.0 and tr.hi > LENGTH - 20.0 and np.ptp(tr.d) < 0.2]
    assert len(edge) == 1


def test_the_inner_shoulder_line_is_held_where_the_lanes_shift_onto_the_shoulder():
    """Hidden median-side lanes are counted from the innermost marking. Where that
    marking moves a lane towards the median (a lane dropped beside the shoulder), the
    count drops by one halfway and the shoulder's line, whole lanes from the marking,
    jumped by a lane there: the lane beside it went on into the shoulder. It stays."""
    step_m = 1.0
    s = np.arange(0.0, 400.0, step_m)
    first = 8.1 - LANE * _smoothstep(s, 170.0, 230.0)
    n = np.where(first - 1.1 >= 1.5 * LANE, 2, 1)
    raw = first - n * LANE
    assert float(np.ptp(raw)) > 1.5  # the line counted from the marking jumps
    held = _inner_shoulder_line(raw, n, step_m)
    np.testing.assert_allclose(held, 1.1, atol=0.05)


def test_a_jump_of_the_innermost_marking_spread_over_two_grid_steps_is_a_jump():
    """The innermost marking's moving median split a 3.5 m jump (another line became the
    innermost 20 m before the run's end) into two steps of 1.74 m, under half a lane
    each: the median-side run went on across it and a lane 7 m wide was built (Town06).
    A shift moves the marking a few tenths of a metre per grid step: no jump."""
    from roadtwin.mainline.hidden_lanes import _extreme_jumps, _two_step_jumps

    jump = np.concatenate([np.full(50, 8.13), [9.875], np.full(20, 11.62)])
    assert not _extreme_jumps(jump, LANE).any()
    assert np.flatnonzero(_two_step_jumps(jump, LANE)).tolist() in ([49], [50])
    shift = 8.1 - LANE * _smoothstep(np.arange(100.0), 20.0, 80.0)
    assert not _two_step_jumps(shift, LANE).any()


def _peaks(tracks):
    """Peak stations, offsets and track ids from ``{track: [(s, d), ...]}``."""
    rows = [(s, d, k) for k, pts in tracks.items() for s, d in pts]
    s, d, k = (np.array(v) for v in zip(*rows, strict=True))
    return s.astype(float), d.astype(float), k.astype(np.int64)


def test_a_stretch_where_lines_stay_and_only_outer_ones_move_is_no_common_shift():
    """town06-auto-s1: over 1562-1588 m the edge line and the shoulder's split line swing
    out by a lane (a lane opens at the outer edge) while the lane lines at 4.6 (the
    innermost seen), 8.2, 11.7 and 15.2 m go on: the stretch moves only lines beyond the
    pattern. Lanes added beside the median (melbourne-921-s2): one line linked across
    at 7.9 m hops between moving lines, and the moving lines cross the stretch inside
    it: a common shift."""
    from roadtwin.mainline.shift import _a_line_stays

    def flat(d, stations):
        return [(s, d) for s in stations]

    outer = {
        0: flat(4.63, [1540, 1550, 1600, 1610]),
        1: flat(8.16, [1535, 1545, 1595, 1605]),
        2: flat(11.67, [1540, 1555, 1570, 1580, 1600]),
        3: flat(15.17, [1535, 1545, 1555, 1565, 1575, 1585, 1595]),
        4: [(1570, 16.6), (1575, 17.0), (1580, 18.0), (1585, 18.6), (1600, 18.6)],
    }
    assert _a_line_stays(*_peaks(outer), 1562.0, 1588.0)
    median = {
        0: flat(0.96, [350, 360, 380, 400, 420, 440, 450]),
        1: flat(7.94, [350, 365, 390, 415, 440, 455]),
        2: [(380, 3.4), (390, 4.2), (400, 5.0), (410, 5.9)],
        3: [(385, 6.4), (395, 7.2)],
    }
    assert not _a_line_stays(*_peaks(median), 372.0, 432.0)
    # nothing stays but the innermost line: a common shift
    inner_only = {0: median[0], 2: median[2]}
    assert not _a_line_stays(*_peaks(inner_only), 372.0, 432.0)


def test_a_line_unseen_while_the_pattern_shifts_moves_with_it_across_the_gap():
    """melbourne-1226-s11 with a noisier sensor: a lane added beside the median moves
    every line out by 3.6 m over 60 m; one line was seen before the shift and after it,
    not in between. Its two pieces were joined in the moving frame, but only their own
    stations were shifted back: the 100 m gap was bridged straight in the reference
    frame, 1.1 m off the line. Now the joined track follows the line (within 0.2 m) all
    through the gap."""
    cfg = MainlineConfig()
    rng = np.random.default_rng(5)
    (s, d), move = _median_side_lanes_added(rng, lanes=1, s0=300.0, s1=360.0)
    line = lambda x: 1.0 + 2 * LANE + move(x)  # noqa: E731
    unseen = (np.abs(d - line(s)) < 0.3) & (s > 295.0) & (s < 395.0)
    s, d = s[~unseen], d[~unseen]
    grid = np.arange(0.0, LENGTH + 0.5, cfg.grid_step_m)
    tracks, _ = _tracks_from_samples(s, d, grid, LENGTH, cfg)
    on = [tr for tr in tracks if tr.lo < 20.0 and abs(float(tr.d[0]) - line(0.0)) < 0.2]
    assert len(on) == 1, [(tr.lo, tr.hi, tr.d[0], tr.d[-1]) for tr in tracks]
    assert on[0].hi > LENGTH - 20.0
    at = np.arange(295.0, 400.0, 5.0)
    err = np.abs(np.interp(at, on[0].s, on[0].d) - line(at))
    # bridged straight in the reference frame: up to 1.3 m off
    assert float(np.max(err)) < 0.2, err


def _swing_all_lines_seen_sparsely(rng, dash, period, keep, noise, s0=300.0, s1=345.0):
    """Every seen line swings out by a lane over 45 m (a lane added beside the median
    whose line there is not seen, and no outer edge: town06-auto-s3 with a noisier
    sensor): broken lines sampled every metre, a share ``keep`` of the samples kept,
    ``noise`` (metres) on each; a new line leaves the inner side."""
    move = lambda s: LANE * _smoothstep(s, s0, s1)  # noqa: E731

    def line(offset, start=0.0, phase=0.0):
        s = np.arange(start, LENGTH, 1.0)
        s = s[((s + phase) % period) < dash]
        s = s[rng.random(s.size) < keep]
        return s, offset(s) + rng.normal(0.0, noise, s.size)

    lines = [line(lambda s, k=k: 1.0 + k * LANE + move(s), phase=5.0 * k) for k in (1, 2, 3)]
    lines.append(line(lambda s: 1.0 + move(s), start=s0 + 10.0))
    return _samples(lines), move


@pytest.mark.parametrize(
    ("keep", "noise", "dash", "period", "seed"),
    [(0.7, 0.08, 6.0, 18.0, 0), (0.7, 0.08, 6.0, 18.0, 1), (0.5, 0.05, 3.0, 12.0, 3)],
)
def test_a_steady_lean_of_the_windows_the_rate_path_missed_is_a_shift(
    keep, noise, dash, period, seed
):
    """Few dashes per window gain little sharpness at any rate: the rate path stays at 0
    (its prior per window off 0, its cost for following an S), though window after window
    piles up best at rates of one sign. Such a steady stretch is a shift when the line
    patterns either side match and the lines are found moved inside it (town06-auto-s3
    with a noisier sensor: nine windows at 0.015-0.145 m/m; the tracks swapped lines, lanes
    3.5 m off over 40 m, edge 0.214 -> 0.049 m)."""
    cfg = MainlineConfig()
    (s, d), move = _swing_all_lines_seen_sparsely(
        np.random.default_rng(seed), dash, period, keep, noise
    )
    frame = _frame(s, d, cfg)
    assert frame is not None
    at = np.array([100.0, 290.0, 355.0, 600.0])
    np.testing.assert_allclose(frame.offset(at), move(at), atol=0.3)


def test_a_lean_of_sparse_windows_by_chance_is_no_shift():
    """The same lines with a third of the samples and 8 cm of noise: after the swing seven
    windows lean the other way by chance (-0.02 to -0.2 m/m, 3.5 m in all) and a pattern
    shifted by a lane matches itself; the lines seen before the stretch are not found
    moved inside it, so no shift back is made there."""
    cfg = MainlineConfig()
    (s, d), move = _swing_all_lines_seen_sparsely(np.random.default_rng(1), 3.0, 12.0, 0.35, 0.08)
    frame = _frame(s, d, cfg)
    if frame is not None:
        at = np.array([100.0, 600.0])
        np.testing.assert_allclose(frame.offset(at), move(at), atol=0.3)


@pytest.mark.parametrize("moves", [True, False])
def test_the_innermost_line_seen_by_two_samples_before_a_swing_does_not_vote(moves):
    """town06-auto-s2 with a noisier sensor (seed offset 260): in the 60 m before a lane
    added beside the median the inner shoulder's line and the next line out were seen
    by two samples each. The innermost line with three samples, a lane line, was taken
    for the innermost and left out of the vote, the lines beyond lay beside the edge:
    no line voted, the swing the outer edge witnessed was not taken and the new lane was
    built at the outer edge (a route ending in a dead end)."""
    rng = np.random.default_rng(4)
    move = lambda s: LANE * _smoothstep(s, 300.0, 345.0)  # noqa: E731
    parts = []
    for k, (offset, n_before) in enumerate([(1.0, 2), (1.0 + LANE, 2), (1.0 + 2 * LANE, 20)]):
        before = np.sort(rng.uniform(240.0, 300.0, n_before))
        inside = np.arange(300.0, 346.0, 1.0)[k::2]  # a dash every other metre
        shift = move(inside) if (moves and k > 0) else np.zeros(inside.size)
        s_k = np.concatenate([before, inside])
        d_k = offset + np.concatenate([np.zeros(before.size), shift])
        parts.append((s_k, d_k + rng.normal(0.0, 0.03, s_k.size), np.full(s_k.size, k)))
    s, d, owner = (np.concatenate([p[i] for p in parts]) for i in range(3))
    # the edge 1 m beyond the third lane line; lines within 2.5 m of it do not vote
    follows = _lines_follow(s, d, owner.astype(np.int64), 300.0, 345.0, move, 1.0 + 3 * LANE - 1.5)
    assert follows is moves


def _lines_beside_a_median_opening(rng, *, fork: bool, outer_moves: bool):
    """Samples (s, d, owner) around a stretch 300-345 m where the pattern moves out by a
    lane: the innermost line stays at 1.0 m (solid), the next line (4.5 m) is worn over
    the stretch (seen before it only), the third (8.0 m) moves with the pattern when
    ``outer_moves``; with ``fork`` a new line leaves the innermost one with the move."""
    move = lambda s: LANE * _smoothstep(s, 300.0, 345.0)  # noqa: E731
    before = np.arange(240.0, 300.0, 1.0)
    inside = np.arange(300.0, 346.0, 1.0)
    parts = [
        (np.concatenate([before, inside]), np.full(before.size + inside.size, 1.0)),
        (before, np.full(before.size, 1.0 + LANE)),
        (
            np.concatenate([before, inside]),
            1.0 + 2 * LANE + np.concatenate([np.zeros(before.size), move(inside) * outer_moves]),
        ),
    ]
    if fork:
        parts.append((inside, 1.0 + move(inside)))
    s = np.concatenate([p[0] for p in parts])
    d = np.concatenate([p[1] for p in parts]) + rng.normal(0.0, 0.03, s.size)
    owner = np.concatenate([np.full(p[0].size, k) for k, p in enumerate(parts)])
    return s, d, owner.astype(np.int64), move


@pytest.mark.parametrize(
    ("fork", "outer_moves", "follows"),
    [(True, True, True), (False, True, False), (True, False, False)],
)
def test_a_line_forking_off_the_innermost_one_votes_for_a_lane_opened_beside_the_median(
    fork, outer_moves, follows
):
    """melbourne-1019-s11 with a noisier sensor (seed offset 920): a lane added beside the
    median, the only lane line between the innermost line and the moving ones worn over
    the 60 m the pattern moved. One line voted for the move and none against, not more
    than half of the two: no shift was found, and the lanes beyond lay a lane off (lane
    RMSE 0.189 m, a 4.6 m lane). The new lane's line leaving the innermost one with the
    move is what a lane opening at the outer edge never makes: it votes for the move
    (lanes 0.079 m). Without it, or where the other lines stay, there is no shift."""
    s, d, owner, move = _lines_beside_a_median_opening(
        np.random.default_rng(5), fork=fork, outer_moves=outer_moves
    )
    # the edge 1 m beyond the third lane line; lines within 2.5 m of it do not vote
    assert _lines_follow(s, d, owner, 300.0, 345.0, move, 1.0 + 3 * LANE - 1.5) is follows


@pytest.mark.parametrize(("dash", "period"), [(3.0, 12.0), (6.0, 18.0)])
@pytest.mark.parametrize("seed", [1, 2])
def test_a_swing_is_found_where_the_edge_is_hidden_just_after_it(dash, period, seed):
    """The fast swing with the outer edge unseen over 349-368 m, just after it: seen on 12
    of the 30 m after the move, the edge still witnesses it (melbourne-1019-lane1-s21 with
    a noisier sensor, seed offset 200: seen on 14 of 30 m, no shift was found, the lines
    moving out by a lane were linked across to the next ones and two lane borders lay
    1-1.8 m off; lanes 0.163 -> 0.062 m)."""
    cfg = MainlineConfig()
    (s, d), edge, move = _fast_swing(np.random.default_rng(seed), dash, period)
    hidden = edge.d.copy()
    hidden[(edge.stations >= 349.0) & (edge.stations <= 368.0)] = np.nan
    frame = _frame(s, d, cfg, OuterEdge(edge.stations, hidden))
    assert frame is not None
    at = np.array([100.0, 290.0, 322.5, 355.0, 600.0])
    err = np.abs(frame.offset(at) - move(at))
    assert float(np.max(err[at != 322.5])) < 0.2, err
    assert float(err[at == 322.5][0]) < 0.6, err


def test_the_innermost_line_staying_does_not_make_an_exit_a_common_shift():
    """a9-206615404-opp-s4 with a noisier sensor: an exit's lane line diverges (11.5 ->
    14.4 m) over a 30 m gap of the outer edge while the lines at 0.7 (the innermost), 4.4
    and 8.0 m go on. The innermost line's peaks inside the stretch were counted as moving
    lines inside the pattern, the stretch taken for a shift of the whole pattern, and in
    its frame the exit's line was no ramp line: the edge followed the ramp 30 m on."""
    from roadtwin.mainline.shift import _a_line_stays

    def flat(d, stations):
        return [(s, d) for s in stations]

    stations = list(range(7648, 7740, 5))
    exit_ = {
        0: flat(0.72, stations),
        2: flat(4.4, stations[1::2]),
        4: flat(8.05, stations),
        3: [(7648, 11.53), (7668, 11.7), (7678, 12.3), (7688, 13.3), (7698, 14.0), (7702, 14.4)],
    }
    assert _a_line_stays(*_peaks(exit_), 7677.5, 7707.5)


def test_a_shift_the_rates_caught_too_little_of_takes_the_lane_the_lines_moved_by():
    """melbourne-921-s9 with a noisier sensor (seed offset 500): two lanes added beside the
    median, every line beyond moving out by 7.0 m; the rate path caught 5.1 m of it over
    a stretch shorter than the move, and the line patterns either side, which repeat
    every lane, matched best at 3.6 m within reach of that: the lines were linked a lane
    apart from their own (edge RMSE 0.18 m). Of the pattern's matches a lane apart, the
    one that leaves the lines inside the stretch straightest is the shift."""
    rng = np.random.default_rng(4)
    move = lambda s: 2 * LANE * _smoothstep(s, 300.0, 380.0)  # noqa: E731
    # the median-side edge line stays, three lines move out, two new ones fan out
    offsets = [lambda s: np.full(s.size, 1.0)]
    offsets += [lambda s, k=k: 1.0 + k * LANE + move(s) for k in (1, 2, 3)]
    offsets += [lambda s, k=k: 1.0 + k / 2 * move(s) for k in (1, 2)]
    lines = [_line(rng, f, s0=0.0 if i < 4 else 310.0) for i, f in enumerate(offsets)]
    s = np.concatenate([a for a, _ in lines])
    d = np.concatenate([b for _, b in lines])
    owner = np.repeat(np.arange(len(lines)), [a.size for a, _ in lines])
    # the rates of the windows over 300-380 m (one per 5 m), a bump adding up to 5.1 m
    bump = np.bartlett(18)[1:-1]
    rates = bump / bump.sum() * 5.1 / 5.0
    s_a, s_b = 300.0, 380.0
    assert _pattern_shift(s, d, owner, s_a, s_b, 5.1) == pytest.approx(3.5, abs=0.15)
    assert _straightest(s, d, owner, rates, s_a, s_b, 3.5) == pytest.approx(7.0, abs=0.15)
    # where the rates caught the move whole, the match they snap to stays
    rates_whole = rates * 7.0 / 5.1
    assert _straightest(s, d, owner, rates_whole, s_a, s_b, 7.0) == pytest.approx(7.0, abs=0.15)
    # a lane's shift is not taken for two
    one = [_line(rng, lambda x, k=k: 1.0 + k * LANE + 0.5 * move(x)) for k in (1, 2, 3)]
    s1 = np.concatenate([a for a, _ in one])
    d1 = np.concatenate([b for _, b in one])
    owner1 = np.repeat(np.arange(len(one)), [a.size for a, _ in one])
    rates_one = rates * 3.5 / 5.1
    assert _straightest(s1, d1, owner1, rates_one, s_a, s_b, 3.5) == pytest.approx(3.5, abs=0.15)


def _swing_out_and_back(rng, back_at, back_m=45.0):
    """Every line but the innermost swings out by a lane over 300-345 m and back over
    ``back_at`` .. + ``back_m`` (a lane added beside the median by a taper and dropped at an inner
    exit soon after, the reference frame following the median-side edge): solid and 3 m
    dashes every 12 m, 4 cm noise; the innermost line stays."""

    def out(s):
        return LANE * (_smoothstep(s, 300.0, 345.0) - _smoothstep(s, back_at, back_at + back_m))

    lines = [
        _line(rng, lambda s: np.full(s.size, 1.0), dashed=False),
        _line(rng, lambda s: 1.0 + LANE + out(s)),
        _line(rng, lambda s: 1.0 + 2 * LANE + out(s)),
        _line(rng, lambda s: 1.0 + 3 * LANE + out(s), dashed=False),
    ]
    return _samples(lines), out


@pytest.mark.parametrize(
    ("back_at", "back_m", "seed"),
    [(345.0, 45.0, 0), (345.0, 45.0, 2), (345.0, 60.0, 1), (350.0, 80.0, 0), (360.0, 80.0, 3)],
)
def test_a_swing_out_and_back_is_two_shifts_each_a_lane(back_at, back_m, seed):
    """town06-auto-lane2-s22 with a noisier sensor: the lines swung out by a lane and back
    within 130 m. The rate path's stretch went out and came back; scaled as one shift to
    the total its ends agree on (about 0), its rates were multiplied: the frame swung out
    by 7.6 m, every line a lane off (here: no shift at all, or one of up to 17 m). Each way
    is a shift of its own: the frame follows the lines out and back."""
    cfg = MainlineConfig()
    (s, d), out = _swing_out_and_back(np.random.default_rng(seed), back_at, back_m)
    frame = _frame(s, d, cfg)
    assert frame is not None
    at = np.arange(100.0, 650.0, 5.0)
    made = frame.offset(at) - frame.offset(np.array([100.0]))
    err = np.abs(made - out(at))
    swinging = ((at > 295.0) & (at < 350.0)) | (
        (at > back_at - 5.0) & (at < back_at + back_m + 5.0)
    )
    # a lane out between the swings and none before and after them (within 0.25 m); the
    # path's steps are a window long, so inside the swings within 1 m
    assert float(np.max(err[~swinging])) < 0.25, at[err >= 0.25]
    assert float(np.max(err[swinging])) < 1.0, at[err >= 1.0]


@pytest.mark.parametrize(("swing_m", "moves"), [(3.5, True), (0.6, False)])
def test_the_outer_edge_unseen_across_a_swing_is_bridged_in_the_shifting_frame(swing_m, moves):
    """town06-auto-lane2-s22 with a noisier sensor: the outer edge unseen over 150 m while
    the lines swung out by a lane and back. Bridged straight in the reference line's frame
    the edge cut through the outermost lane (its line was left out over 80 m); in the frame
    that moves with the lines it keeps its place beside them (within 1 cm here). A frame
    that moves less than half a lane in the gap (a shift's refinement, town06-auto-s3 with
    a noisier sensor) leaves the edge as bridged."""
    grid = np.arange(0.0, LENGTH + 0.5, 1.0)
    out = swing_m * (_smoothstep(grid, 300.0, 345.0) - _smoothstep(grid, 360.0, 420.0))
    frame = ShiftFrame(grid, out)
    true_edge = 12.5 + out
    covered = (grid < 260.0) | (grid > 460.0)
    bridged = true_edge.copy()
    bridged[~covered] = 12.5  # straight across the gap in the reference line's frame
    in_frame = _edge_in_frame(bridged, covered, grid, frame)
    back = in_frame + frame.offset(grid)
    if moves:
        np.testing.assert_allclose(back, true_edge, atol=0.01)
    else:
        np.testing.assert_allclose(back, bridged, atol=1e-9)
