"""Lane sections from marking tracks and the outer edge: section borders at track ends
and edge steps, lane widths as cubic pieces (tapers at gores: :mod:`.tapers`), lane types
from width and the car, links across sections by border geometry (:mod:`.section_links`),
and the lane events.
"""

from __future__ import annotations

import itertools
from dataclasses import replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from ..fitting import (
    fit_cubic_profile,
)
from ..model import (
    Lane,
    LaneSection,
    RoadMark,
)
from ._common import (
    BoundaryTrack,
    LaneEvent,
    _fill_nan,
    edge_move_at,
    true_runs,
)
from .mark_changes import pattern_changes
from .markings import _dashed, _mark_type, _Track
from .section_links import _link_sections, _side_lanes
from .tapers import (
    _close_strip,
    _lines_from_splits,
    _lines_to_gores,
    _lines_with_median_edge,
    _taper,
)

FloatArray = NDArray[np.float64]

_GORE_MATCH_M = 20.0  # a marking ending this close to an edge step ends at that gore

_SHOULDER_LINE_M = 20.0  # an edge line is a shoulder's line over at least this length ...
_SHOULDER_MIN_M = 1.8  # ... where its shoulder is at least this wide (metres)
# the shoulder opens (closes) where its line is this far from the edge (metres): the truth's
# shoulder tapers to zero, and at edge_line_m it ended 15 m early (melbourne-18-s11+80)
_SHOULDER_MEET_M = 0.1
# a marking's change between solid and broken starts a section this far (metres) from any
# other start only
_PATTERN_ALONE_M = 50.0


def _lane_types(
    borders: FloatArray,
    gs: FloatArray,
    car: tuple[FloatArray, FloatArray] | None,
    cfg: MainlineConfig,
    dashed: tuple[bool, bool] = (False, False),
) -> list[str]:
    """Lane types of one section from its borders (rows inner to outer, on ``gs``).

    The lanes between a road edge and the nearest marking are shoulders when they are
    narrower than ``shoulder_max_m``, driving lanes when the car drove in them
    (``car``: stations and offsets of the poses), when that marking is dashed (``dashed``:
    the innermost and the outermost marking; a line between a lane and a shoulder is
    solid) or when they are at least ``edge_lane_min_m`` wide (a road without shoulders,
    whose edge lines run along its edges), all up to ``edge_lane_max_m`` (wider: paved
    area beside the lanes, a gore); in between (2.2-3.3 m: a hard shoulder or a narrow
    lane) a shoulder where the section has three lanes or more. Lanes between two
    markings are driving lanes unless they are nowhere ``shoulder_max_m`` wide (a strip
    between an edge line and a second line beside it).
    """
    n_l = borders.shape[0] - 1
    if n_l < 2:
        return ["driving"] * n_l
    all_widths = np.diff(borders, axis=0)
    widths = np.median(all_widths, axis=1)
    types = [
        "shoulder" if w < cfg.shoulder_max_m else "driving" for w in np.max(all_widths, axis=1)
    ]
    share = np.zeros(n_l)
    if car is not None and car[0].size:
        s_car, d_car = car
        on = (s_car >= gs[0]) & (s_car <= gs[-1])
        if np.any(on):
            i_g = np.clip(np.searchsorted(gs, s_car[on]), 0, gs.size - 1)
            inside = (d_car[on][None, :] > borders[:-1, i_g]) & (
                d_car[on][None, :] <= borders[1:, i_g]
            )
            share = inside.mean(axis=1)
    for i, beside_dashes in ((0, dashed[0]), (n_l - 1, dashed[1])):
        if widths[i] < cfg.shoulder_max_m:
            types[i] = "shoulder"
        elif share[i] > 0.3:
            types[i] = "driving"
        elif widths[i] > cfg.edge_lane_max_m:
            types[i] = "shoulder"
        elif widths[i] >= cfg.edge_lane_min_m or beside_dashes:
            types[i] = "driving"
        elif n_l >= 3:
            types[i] = "shoulder"
    return types


def _steps_beside(
    tracks: list[_Track],
    k: int,
    station: float,
    outer_steps: FloatArray,
    median_steps: FloatArray,
) -> FloatArray:
    """The edge steps that may end or start track ``k`` at ``station`` (metres): the outer
    edge's where no other track lies farther out there, the median-side edge's where none
    lies farther in. A step of one edge opens or closes the lanes beside that edge; a line
    with lines on both sides starts or ends for another reason (town06-auto-lane2-s22 with
    a noisier sensor: a line between two lanes first seen 33 m into the run, where the
    outer edge stepped, left the two lanes one 6.9 m lane there, and no lane led on).
    """
    d_k = float(np.interp(station, tracks[k].s, tracks[k].d))
    others = [
        float(np.interp(station, tr.s, tr.d))
        for j, tr in enumerate(tracks)
        if j != k and tr.lo - 5.0 <= station <= tr.hi + 5.0
    ]
    parts = []
    if not any(d > d_k + 0.5 for d in others):
        parts.append(outer_steps)
    if not any(d < d_k - 0.5 for d in others):
        parts.append(median_steps)
    return np.concatenate(parts) if parts else np.zeros(0)


def _shoulder_stretches(
    dmat: FloatArray, d_edge: FloatArray, d_median: FloatArray, cfg: MainlineConfig
) -> tuple[set[int], dict[int, NDArray[np.bool_]]]:
    """The edge lines among the tracks and where each is a shoulder's line instead.

    A marking within ``edge_line_m`` of a road edge (median over its length; ``dmat``
    rows on the grid, ``d_edge`` / ``d_median`` the outer and median-side edges, all
    metres from the reference edge towards the carriageway) is that edge's line, not the
    border of a lane a few centimetres wide. Where it runs at least ``_SHOULDER_MIN_M``
    inside that edge over ``_SHOULDER_LINE_M`` or more, a hard shoulder lies beside it:
    the stretch, widened to where the line meets the edge again (within
    ``_SHOULDER_MEET_M``), is a shoulder stretch (``True`` on the grid), and the shoulder opens
    and closes at its ends. A hard shoulder beginning where a lane drops, or ending
    beyond an exit, moves the edge away from its line within a section: judged over the
    whole section, the line was dropped and the lane beside it took the shoulder
    (melbourne-18-s11+80: a lane 5.5 m wide over 45 m, a shoulder 2.4 m wide missed over
    60 m).
    """
    n_min = max(1, round(_SHOULDER_LINE_M / cfg.grid_step_m))
    edge_lines: set[int] = set()
    shoulder_of: dict[int, NDArray[np.bool_]] = {}
    for k in range(dmat.shape[0]):
        on = np.isfinite(dmat[k])
        if np.count_nonzero(on) < 10:
            continue
        to_edge = d_edge - dmat[k]
        to_median = dmat[k] - d_median
        m_edge, m_median = float(np.median(to_edge[on])), float(np.median(to_median[on]))
        if min(m_edge, m_median) >= cfg.edge_line_m:
            continue
        edge_lines.add(k)
        side = to_edge if m_edge <= m_median else to_median
        gap = np.where(on, side, np.nan)
        wide = gap >= _SHOULDER_MIN_M
        apart = gap > _SHOULDER_MEET_M
        stretch = np.zeros(gap.size, dtype=bool)
        for a, b in true_runs(wide):
            if b - a < n_min:
                continue
            while a > 0 and apart[a - 1]:
                a -= 1
            while b < gap.size and apart[b]:
                b += 1
            stretch[a:b] = True
        shoulder_of[k] = stretch
    return edge_lines, shoulder_of


_TAKES_OVER_M = 1.0  # the median-side edge this close to a line beyond its step goes on as it


def _edge_takes_over(
    d_line: float,
    s_step: float,
    end: Literal["start", "end"],
    grid: FloatArray,
    d_median: FloatArray,
    median_steps: FloatArray,
) -> bool:
    """Whether a line that ends (``end`` "end") or begins ("start") at ``s_step`` (metres),
    at offset ``d_line`` (metres), does so because the median-side edge steps onto it
    there: beyond an exit's gore on the median side the edge goes on where the mainline's
    innermost line was, and the lane outward of that line goes on too (it was counted
    with the exit's lanes: melbourne-921-s2, a 2-lane exit built with 3). The edge's
    offset is taken 5 m on the far side of the step (``d_median`` on ``grid``)."""
    if not median_steps.size or np.min(np.abs(median_steps - s_step)) >= _GORE_MATCH_M:
        return False
    probe = s_step + (5.0 if end == "end" else -5.0)
    i = int(np.clip(np.searchsorted(grid, probe), 0, grid.size - 1))
    return bool(abs(d_median[i] - d_line) < _TAKES_OVER_M)


def _sections_from_tracks(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    breaks: FloatArray,
    sign: float,
    cfg: MainlineConfig,
    car: tuple[FloatArray, FloatArray] | None = None,
    d_median: FloatArray | None = None,
    median_steps: FloatArray | None = None,
) -> tuple[tuple[LaneSection, ...], tuple[LaneEvent, ...], tuple[BoundaryTrack, ...]]:
    """Lane sections (constant set of tracks), lane links, road marks and lane events.

    ``d_median`` (on ``grid``) is the innermost border (the median-side edge); its steps
    (``median_steps``) start sections like the outer edge's steps (``breaks``)."""
    if d_median is None:
        d_median = np.zeros(grid.size)
    if median_steps is None:
        median_steps = np.zeros(0)
    outer_steps = np.asarray(breaks, dtype=float)
    breaks = np.sort(np.concatenate([breaks, median_steps]))
    length = float(grid[-1])
    side: Literal["right", "left"] = "right" if sign > 0 else "left"
    n_g = grid.size
    dmat = np.full((len(tracks), n_g), np.nan)
    for k, tr in enumerate(tracks):
        # a track that stops short of the run's start/end was cut by it (the car saw no
        # more of it), unless an edge step (a gore) on its side lies in between: there it
        # really ends
        near_start = _steps_beside(tracks, k, tr.lo, outer_steps, median_steps)
        near_end = _steps_beside(tracks, k, tr.hi, outer_steps, median_steps)
        cut_start = not np.any((near_start >= grid[0]) & (near_start <= tr.lo + 5.0))
        cut_end = not np.any((near_end >= tr.hi - 5.0) & (near_end <= length))
        lo = grid[0] if tr.lo - grid[0] < cfg.lane_max_gap_m and cut_start else tr.lo
        hi = length if length - tr.hi < cfg.lane_max_gap_m and cut_end else tr.hi
        sel = (grid >= lo) & (grid <= hi)
        dmat[k, sel] = np.interp(grid[sel], tr.s, tr.d)
    at_entry_gore = _lines_to_gores(dmat, grid, d_edge, outer_steps)
    _lines_from_splits(dmat, grid)
    _lines_with_median_edge(dmat, grid, d_median, median_steps)
    # births / ends inside the run
    raw_events: list[tuple[int, str, float, float, int | None]] = []
    # observed markings first: an inferred (unobserved) one opens/closes like its sibling
    order = sorted(range(len(tracks)), key=lambda k: tracks[k].n == 0)
    for k in order:
        for end in ("start", "end"):
            idx = np.nonzero(np.isfinite(dmat[k]))[0]
            if idx.size == 0:
                continue
            i_edge = idx[0] if end == "start" else idx[-1]
            if (end == "start" and i_edge == 0) or (end == "end" and i_edge == n_g - 1):
                continue
            fixed = None
            if tracks[k].n == 0:
                # a sibling opens (closes) near it, and not a taper's half or more after
                # it begins (before it ends): an inferred line with a taper of its own
                # (an exit lane opening out of sight) kept 96 m of it when it borrowed
                # the taper of a median-side lane opening there (town06-auto-lane1-s21)
                sign_end = 1.0 if end == "start" else -1.0
                sib = [
                    (s_z, tp)
                    for _, e2, s_z, tp, _ in raw_events
                    if e2 == end
                    and tp > 0.0
                    and abs(s_z - grid[i_edge]) < 100.0
                    and sign_end * (grid[i_edge] - s_z) > -0.5 * tp
                ]
                fixed = sib[0] if sib else None
            raw = (tracks[k].s_samples, tracks[k].d_samples)
            beside = _steps_beside(tracks, k, float(grid[i_edge]), outer_steps, median_steps)
            at_gore = bool(
                tracks[k].n == 0
                and beside.size
                and np.min(np.abs(beside - grid[i_edge])) < _GORE_MATCH_M
            )
            # an inferred marking that ends at a gore of the edge beside it ends there with
            # its lane (no taper borrowed from a marking elsewhere: an exit lane's unseen
            # outer line took the taper of the lane dropped after the exit and ran on 75 m
            # past the gore, beyond the edge, melbourne-408-lane1-s21)
            at_gore = at_gore or (end == "start" and k in at_entry_gore)
            info = None if at_gore else _taper(dmat, k, grid, end, cfg, fixed, raw)
            if info is None and not at_gore and tracks[k].n > 0:
                near_break = breaks.size and np.min(np.abs(breaks - grid[i_edge])) < _GORE_MATCH_M
                if not near_break and _close_strip(dmat, k, grid, end):
                    continue
            if info is None:
                # a lane that begins/ends at full width does so at a gore, where an edge
                # steps; a marking that merely starts/ends (paint beginning at a road
                # edge, a worn stretch) without one is no lane event
                s_ev = float(grid[i_edge])
                if breaks.size and np.min(np.abs(breaks - s_ev)) < _GORE_MATCH_M:
                    s_ev = float(breaks[np.argmin(np.abs(breaks - s_ev))])
                    if _edge_takes_over(dmat[k, i_edge], s_ev, end, grid, d_median, median_steps):
                        continue
                    raw_events.append((k, end, s_ev, 0.0, None))
            else:
                raw_events.append((k, end, info[0], info[1], info[2]))
    # sections: runs of a constant set of tracks
    present = np.isfinite(dmat)
    change = np.flatnonzero(np.any(present[:, 1:] != present[:, :-1], axis=0)) + 1
    starts = [0, *change.tolist()]
    edge_lines, shoulder_of = _shoulder_stretches(dmat, d_edge, d_median, cfg)
    # a hard shoulder opening (closing) beside an edge line starts a section where the
    # line leaves (meets) the edge
    for k in edge_lines:
        edges = np.flatnonzero(np.diff(shoulder_of[k].astype(np.int8))) + 1
        starts.extend(int(i) for i in edges)
    # so does a marking beside an edge strip turning from solid to broken (a lane gained
    # beyond it) or back, where no other change of the lanes explains it: next to a lane
    # opening or ending, the aux lane's line turns solid a dash or two before the taper's
    # end, and that change moved the lane's own section start by 2-15 m (7 runs of the
    # quiet seed-offset-860 batch)
    known = np.asarray([*starts, *(_grid_index(b, grid, cfg) for b in breaks)], dtype=float)
    alone = round(_PATTERN_ALONE_M / cfg.grid_step_m)
    starts.extend(
        i for i in pattern_changes(tracks, dmat, grid, cfg) if np.min(np.abs(known - i)) > alone
    )
    # edge steps start a section too
    forced: set[int] = set()
    s0_at: dict[int, float] = {}  # a section that starts at an edge step starts exactly there
    # the lane offset steps at a median step: a section must start exactly there
    offset_steps = {_grid_index(b, grid, cfg) for b in median_steps}
    for b in breaks:
        i_b = _grid_index(b, grid, cfg)
        s0_at[i_b] = float(min(b, grid[i_b]))
        # track changes next to an edge step belong to the gore: move them onto the step
        # (not a median step's start: town06-auto-s9 with a noisier sensor lost one 12.8 m
        # before an outer step, and four lanes lay a lane width off over those metres)
        starts = [
            i
            for i in starts
            if i == 0 or i in offset_steps or i in forced or abs(i - i_b) * cfg.grid_step_m >= 20.0
        ]
        starts.append(i_b)
        forced.add(i_b)
    starts = sorted(set(starts))
    min_n = max(1, int(cfg.min_section_m / cfg.grid_step_m))
    merged_starts = [starts[0]]
    for i in starts[1:]:
        # an edge step (a gore) starts a section even close to the run's end: the lane
        # that leaves there must not run on to the end
        min_tail = max(1, int(2.0 / cfg.grid_step_m)) if i in forced else min_n
        if n_g - i < min_tail:
            continue
        if i - merged_starts[-1] >= min_n:
            merged_starts.append(i)
        elif i in forced and merged_starts[-1] != 0 and merged_starts[-1] not in forced:
            merged_starts[-1] = i
        elif (
            i in forced
            and merged_starts[-1] in forced
            and not offset_steps & {i, merged_starts[-1]}
            and abs(edge_move_at(d_edge, i)) > abs(edge_move_at(d_edge, merged_starts[-1]))
        ):
            # two edge steps closer than a section: the larger one is the gore (an exit's
            # step 12 m before a small one the ramp's peeling edge made: kotka-37952515-s1
            # with a noisier sensor, seed offset 200, where the later one won and the exit
            # lane ran on 12 m past the nose, 3.5 m off)
            merged_starts[-1] = i
        elif (
            i in forced
            and merged_starts[-1] in forced
            and offset_steps & {i, merged_starts[-1]}
            and i - merged_starts[-1] >= min_tail
        ):
            merged_starts.append(i)  # a median step and another step: each starts a section
    starts = [*merged_starts, n_g]
    sections: list[LaneSection] = []
    bounds_per: list[list[tuple[object, object]]] = []
    medians: list[tuple[float, float]] = []  # the median-side edge at section start, end

    def shoulder_line_in(k: int, lo: int, hi: int) -> bool:
        """An edge line is the shoulder's line in the section ``lo:hi`` (at least
        ``_SHOULDER_LINE_M`` long) where it lies in one of its shoulder stretches
        (:func:`_shoulder_stretches`) over most of the section: the same solid line is
        the edge line where the hard shoulder is missing (melbourne-18-s11+80: dropped
        all along, the lane beside it took a 2.4 m shoulder, 7.3 m wide)."""
        on = np.isfinite(dmat[k, lo:hi])
        if (hi - lo) * cfg.grid_step_m < _SHOULDER_LINE_M or not on.all():
            return False
        return bool(np.mean(shoulder_of[k][lo:hi]) >= 0.5)

    members_per: list[list[int]] = []
    for a, b in itertools.pairwise(starts):
        b_inc = min(b + 1, n_g)
        votes = present[:, a:b].mean(axis=1)
        members = [k for k in range(len(tracks)) if votes[k] > 0.5]
        members.sort(key=lambda k: float(np.nanmedian(dmat[k, a:b])))
        members = [k for k in members if k not in edge_lines or shoulder_line_in(k, a, b)]
        gs = grid[a:b_inc]
        s0 = s0_at.get(a, float(grid[a]))
        rel = gs - s0
        # a section that starts at an edge step starts between grid stations: its width
        # profiles start at the section's start (the first record at sOffset 0), not at
        # the first grid station after it
        rel[0] = 0.0
        m = d_median[a:b_inc].copy()
        if b_inc > b and b < n_g and abs(d_median[b] - d_median[b - 1]) > 0.5:
            m[-1] = m[-2] if m.size >= 2 else m[-1]  # the next segment's level is not inside
        rows = [m]
        labels: list[object] = ["ref"]
        for k in members:
            rows.append(_fill_nan(gs, dmat[k, a:b_inc]))
            labels.append(k)
        e = d_edge[a:b_inc].copy()
        if b_inc > b and b < n_g and abs(d_edge[b] - d_edge[b - 1]) > 0.5:
            e[-1] = 2 * e[-2] - e[-3] if e.size >= 3 else e[-2]  # no step inside
        rows.append(e)
        labels.append("edge")
        stack = np.maximum.accumulate(np.vstack(rows), axis=0)
        n_l = len(stack) - 1
        dashed = (False, False)
        if members:
            lo, hi = float(gs[0]), float(gs[-1])
            dashed = (
                _dashed(tracks[members[0]].s_samples, lo, hi, cfg),
                _dashed(tracks[members[-1]].s_samples, lo, hi, cfg),
            )
        types = _lane_types(stack, gs, car, cfg, dashed)
        lanes: list[Lane] = []
        bounds: list[tuple[object, object]] = []
        for i in range(n_l):
            width = np.clip(stack[i + 1] - stack[i], 0.0, None)
            lane_type = types[i]
            if i == n_l - 1:
                mark = "none"
            else:
                tr = tracks[labels[i + 1]]  # type: ignore[index]
                mark = (
                    _mark_type(tr.s_samples, float(gs[0]), float(gs[-1]), cfg)
                    if gs[-1] - gs[0] >= 4 * cfg.broken_gap_m
                    else tr.mark
                )
            prof = fit_cubic_profile(
                rel, width, tolerance=cfg.lane_width_tolerance_m, shape_preserving=True
            )
            lid = -(i + 1) if sign > 0 else i + 1
            lanes.append(Lane(lid, lane_type, prof, (RoadMark(0.0, mark),)))  # type: ignore[arg-type]
            bounds.append((labels[i], labels[i + 1]))
        sections.append(_make_section(s0, lanes, sign))
        bounds_per.append(bounds)
        medians.append((float(m[0]), float(m[min(b - a, m.size - 1)])))
        members_per.append(members)
    at_step = [a in forced for a in starts[:-1]]
    sections = _link_sections(sections, bounds_per, medians, at_step)
    sections = _drive_on_through_sections(sections, cfg)
    events = _events(raw_events, sections, members_per, dmat, grid, side, sign, median_steps)
    out_tracks = tuple(
        BoundaryTrack(
            tr.id,
            grid[np.isfinite(dmat[tr.id])],
            dmat[tr.id][np.isfinite(dmat[tr.id])],
            tr.mark,  # type: ignore[arg-type]
            tr.n,
        )
        for tr in tracks
    )
    return tuple(sections), events, out_tracks


def _drive_on_through_sections(
    sections: list[LaneSection], cfg: MainlineConfig
) -> list[LaneSection]:
    """Shoulders at least ``shoulder_max_m`` wide (metres) all along their sections, linked
    from a driving lane before them to a driving lane after them, are driving lanes: the
    lane goes on.

    An edge lane 2.2-3.3 m wide that the car did not drive is typed by its section alone
    (:func:`_lane_types`), and a short section of many lanes makes it a shoulder. Between
    two driving lanes it linked, that makes a lane stop and start again for 20 m:
    melbourne-921-s2 with a noisier sensor, where two lanes were added on the median side,
    and esmini's car in the inner lane jumped 3.1 m to the next lane.

    A shoulder between two markings that goes on from a driving lane at its width and
    narrows to less than half of it is that lane's taper (:func:`_closing_taper`)."""
    lanes = [{ln.id: ln for ln in _side_lanes(sc)} for sc in sections]
    ends = [
        np.array([0.0, max(nxt.s0 - sc.s0 - 1e-6, 0.0)]) for sc, nxt in itertools.pairwise(sections)
    ]

    def lane_wide_shoulder(n: int, lane: Lane) -> bool:
        return lane.type == "shoulder" and float(np.min(lane.width.value(ends[n]))) >= (
            cfg.shoulder_max_m
        )

    turn: set[tuple[int, int]] = set()
    for n in range(1, len(sections) - 1):
        for lane in lanes[n].values():
            before = lanes[n - 1].get(lane.predecessor)  # type: ignore[arg-type]
            if before is None or before.type != "driving":
                continue
            # follow the lane on while it is a lane-wide shoulder (the last section has
            # no lane after it to end the chain on)
            chain: list[tuple[int, int]] = []
            k, cur = n, lane
            while cur is not None and k < len(ends) and lane_wide_shoulder(k, cur):
                chain.append((k, cur.id))
                k, cur = k + 1, lanes[k + 1].get(cur.successor)  # type: ignore[arg-type]
            if cur is not None and cur.type == "driving":
                turn.update(chain)
            elif not chain and _closing_taper(sections[n], lane, before, ends[n - 1], ends[n]):
                turn.add((n, lane.id))
    if not turn:
        return list(sections)
    out = []
    for n, sc in enumerate(sections):
        side = "right" if sc.right else "left"
        new = tuple(
            replace(ln, type="driving") if (n, ln.id) in turn else ln for ln in _side_lanes(sc)
        )
        out.append(replace(sc, **{side: new}) if new != _side_lanes(sc) else sc)
    return out


def _closing_taper(
    section: LaneSection, lane: Lane, before: Lane, ends_before: FloatArray, ends: FloatArray
) -> bool:
    """Whether ``lane``, a shoulder between two markings of ``section``, is the closing
    taper of the driving lane ``before`` (its predecessor): it starts within 0.5 m of that
    lane's width at its end and narrows to less than half its own start width
    (``ends_before``, ``ends``: section-relative start and end stations, metres). A lane
    dropped by a taper narrows below ``shoulder_max_m`` within a section of its own once
    the hard shoulder beside it opens on its line (melbourne-18-s11+80: typed a shoulder
    over 45 m, the lane count one short)."""
    side = _side_lanes(section)
    if lane.type != "shoulder" or lane.id in (side[0].id, side[-1].id):
        return False
    w_prev = float(before.width.value(ends_before[1:])[0])
    w0, w1 = (float(w) for w in lane.width.value(ends))
    return abs(w0 - w_prev) <= 0.5 and w1 < 0.5 * w0


def _grid_index(s: float, grid: FloatArray, cfg: MainlineConfig) -> int:
    """Index of the first grid station at or after ``s`` (metres), within the grid's
    inner stations."""
    return int(np.clip(np.ceil((s - grid[0]) / cfg.grid_step_m - 1e-9), 1, grid.size - 1))


def _make_section(s0: float, lanes: list[Lane], sign: float) -> LaneSection:
    return LaneSection(s0, right=tuple(lanes)) if sign > 0 else LaneSection(s0, left=tuple(lanes))


def _events(
    raw_events: list[tuple[int, str, float, float, int | None]],
    sections: list[LaneSection],
    members_per: list[list[int]],
    dmat: FloatArray,
    grid: FloatArray,
    side: Literal["right", "left"],
    sign: float,
    median_steps: FloatArray | None = None,
) -> tuple[LaneEvent, ...]:
    """Lane events: the lane between a track that starts/ends and its nearest neighbour.

    A track that starts/ends abruptly (a gore) bounds the lane that begins/ends on its
    outer side, or, at a step of the median-side edge (a gore on the median side), on its
    carriageway side."""
    if median_steps is None:
        median_steps = np.zeros(0)
    s0s = np.array([sec.s0 for sec in sections])
    events = []
    for k, end, s_zero, taper, jn in raw_events:
        # the section where the lane exists: just after a birth, just before an end
        probe = s_zero + (1.0 + taper if end == "start" else -(1.0 + taper))
        probe = float(np.clip(probe, grid[0], grid[-1]))
        n = int(np.clip(np.searchsorted(s0s, probe, side="right") - 1, 0, len(sections) - 1))
        members = members_per[n]
        if k not in members:
            continue
        pos = members.index(k)
        i_p = int(np.clip(np.searchsorted(grid, probe), 0, grid.size - 1))
        # neighbour: the adjacent member nearer in offset
        cand = [p for p in (pos - 1, pos + 1) if 0 <= p < len(members)]
        at_median_step = bool(
            median_steps.size and np.min(np.abs(median_steps - s_zero)) < _GORE_MATCH_M
        )
        if taper == 0.0:  # abrupt (gore): the lane whose outer border is the track
            outer_pos = pos + 1 if at_median_step else pos
        elif jn is not None and jn in members:
            outer_pos = max(pos, members.index(jn))
        elif cand:
            p_nb = min(cand, key=lambda p: abs(dmat[members[p], i_p] - dmat[k, i_p]))
            outer_pos = max(pos, p_nb)
        else:
            outer_pos = pos
        lanes = _side_lanes(sections[n])
        lane_idx = outer_pos  # lane index whose outer border is member outer_pos
        if lane_idx == 0 and not cand:
            lane_idx = 1
        if lane_idx >= len(lanes) - 1:
            continue
        lane = lanes[lane_idx]
        if taper == 0.0 and (lane.predecessor if end == "start" else lane.successor) is not None:
            # the lane goes on across the border (its line merely begins or ends there: an
            # edge line first painted 75 m before an entry's nose, soderleden-s2 with a
            # noisier sensor, was an entry's gore there, and the ramp joined 75 m early)
            continue
        driving = [ln for ln in lanes if ln.type == "driving"]
        position = (
            "outer" if driving and lane.id == driving[-1].id and len(driving) > 1 else "inner"
        )
        ds = probe - sections[n].s0
        if taper == 0.0:
            # an abrupt end/birth is where the lane's section ends/begins (two edge steps
            # close together can leave the track end and the section border metres apart;
            # the junction must start where the lane really leaves)
            border = (
                sections[n].s0
                if end == "start"
                else (sections[n + 1].s0 if n + 1 < len(sections) else s_zero)
            )
            if abs(border - s_zero) < _GORE_MATCH_M:
                s_zero = float(border)
        events.append(
            LaneEvent(
                s_m=float(s_zero),
                kind="birth" if end == "start" else "end",
                side=side,
                lane_id=int(lane.id),
                position=position,  # type: ignore[arg-type]
                taper_m=float(taper),
                width_m=float(lane.width.value(ds)),
            )
        )
    return tuple(sorted(events, key=lambda e: e.s_m))
