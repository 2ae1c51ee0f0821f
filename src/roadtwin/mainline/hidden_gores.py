"""Gores the outer-edge points did not see: snapped to ramp-line evidence or placed from
the through marking's type change and the shoulder taper (:mod:`.gores`), with the
marking tracks moved to end there.
"""

from __future__ import annotations

import logging
import math
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from ._common import edge_move_at, true_runs
from .gores import (
    ShoulderTaper,
    fit_shoulder_taper,
    fuse_gore_estimates,
    marking_gore_interval,
)
from .markings import (
    _SHOULDER_MAX_M,
    _WITH_EDGE_SHARE,
    _ends_on_converging_line,
    _last_marking,
    _Track,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


_BESIDE_GORE_M = 1.0
"""A marking more than this (metres) inside the mainline marking a ramp line meets at a
hidden gore is a through line: the gore does not cut it."""


_THROUGH_M = 60.0
"""A line that runs on this far (metres) on both sides of a station goes through it."""


def _outermost_at(tracks: list[_Track], k: int, station: float) -> bool:
    """Whether no line that goes through ``station`` (metres along the reference line; it
    runs on ``_THROUGH_M`` before and after it) lies more than 0.5 m farther out than track
    ``k`` there. Lines beginning or ending nearer are a gore's own (a ramp's lines)."""
    d_k = float(np.interp(station, tracks[k].s, tracks[k].d))
    return not any(
        float(np.interp(station, tr.s, tr.d)) > d_k + 0.5
        for j, tr in enumerate(tracks)
        if j != k and tr.lo <= station - _THROUGH_M and tr.hi >= station + _THROUGH_M
    )


def _other_lines_at(tracks: list[_Track], k: int, station: float) -> FloatArray:
    """Offsets (metres) at ``station`` of the tracks other than ``k`` that run there."""
    return np.array(
        [
            float(np.interp(station, tr.s, tr.d))
            for j, tr in enumerate(tracks)
            if j != k and tr.lo <= station <= tr.hi
        ]
    )


def _beside_inner_line(tracks: list[_Track], k: int, tr: _Track) -> tuple[FloatArray, FloatArray]:
    """Offsets (metres) of ``tr`` (track ``k`` of ``tracks``, maybe cut already) from the
    nearest line inward at each of its stations (lines of ``tracks`` nearer the median),
    and their rate of change along s (m/m), or its own offsets and slope where some
    station has none: a ramp line converges onto (diverges from) the mainline's lines,
    which may shift sideways as a whole meanwhile (a lane gained on the median side:
    melbourne-921-s9 with a noisier sensor, an entry's line moving out with the shift read
    as diverging, its gore hidden in a gap not placed and the edge 4 m off).

    The rate is the line's slope less that of the line inward at each station, so a line
    inward that begins or ends beside ``tr`` is no convergence (krems-46762523-opp-s4 with
    a noisier sensor: the line between two lanes first seen 10 m after the one beside the
    shoulder, whose offset from the nearest line inward so "fell" by 3.7 m: it was cut back
    as a ramp line, the lanes merged into one 10 m wide and a route led nowhere)."""
    own = (tr.d, np.gradient(tr.d, tr.s) if tr.s.size > 1 else np.zeros(tr.s.size))
    others = [t for j, t in enumerate(tracks) if j != k]
    if not others:
        return own
    d = np.stack(
        [
            np.where((tr.s >= t.lo) & (tr.s <= t.hi), np.interp(tr.s, t.s, t.d), np.nan)
            for t in others
        ]
    )
    d[~(d < tr.d)] = -np.inf
    nearest = d.argmax(axis=0)
    inner = d[nearest, np.arange(tr.s.size)]
    if not np.isfinite(inner).all():
        return own
    slopes = np.stack(
        [
            np.interp(tr.s, t.s, np.gradient(t.d, t.s)) if t.s.size > 1 else np.zeros(tr.s.size)
            for t in others
        ]
    )
    return tr.d - inner, own[1] - slopes[nearest, np.arange(tr.s.size)]


def _turn(rel_slope: FloatArray, s: FloatArray, i0: int, i1: int) -> float:
    """How much (metres) the offset from the line inward grew from station index ``i0`` to
    ``i1`` (>= ``i0``) of ``s``: the integral of ``rel_slope`` (m/m,
    :func:`_beside_inner_line`)."""
    part = slice(i0, i1 + 1)
    return float(np.sum(np.diff(s[part]) * 0.5 * (rel_slope[part][1:] + rel_slope[part][:-1])))


_MET_M = 0.3  # a ramp line this near the line inward has met it (metres)
_RAMP_LINE_TURN_M = 0.3
"""A ramp line converges (diverges) by at least this much (metres) over the stretch cut
from it; a line whose offset drifts by centimetres there is the mainline's (a noisier
sensor's smoothed line starting 2 cm "converging" made an exit's deceleration lane start
75 m late, a9-10959882-s9+80)."""


_AT_GAP_M = 5.0  # a line first (last) seen this near a gap's start (end) ...
_BEYOND_EDGE_M = 0.5  # ... this far beyond the edge seen next to it lies beside the road


def _beside_road_in_gap(
    tr: _Track,
    first: bool,
    gap: NDArray[np.bool_],
    grid: FloatArray,
    d_edge: FloatArray | None,
    others: tuple[list[_Track], int],
) -> tuple[float, float] | None:
    """The occlusion gap of the outer edge (``gap`` on ``grid``; its first and last
    stations, metres) whose start (end) track ``tr`` begins (``first``; else ends) within
    ``_AT_GAP_M`` of, more than ``_BEYOND_EDGE_M`` beyond the edge ``d_edge`` seen just
    before (after) the gap; None where it does not, or where that edge lies on a line
    (``others``: the tracks and ``tr``'s index among them, :func:`_other_lines_at`), within
    ``_NO_SHOULDER_M``: there it is a nose, the ramp's pavement joins the road right
    beside it, and a line going on from the nose is the road's (a9-206615404-s7+920: an
    entry's nose seen 3 m before a 100 m gap, the acceleration lane's line beginning at
    the nose cut back to its last 8 m as a ramp's line; the lane was built 3.7 m wide
    over the taper, 1.8 m off). The line was there beside the road,
    its samples left out as beyond the edge where the edge was seen. A ramp's line running
    beside the carriageway before its nose is the mainline's nowhere up to where it meets
    the line inward in that gap (melbourne-1019-lane1-s21 with a noisier sensor: an
    entry's line, parallel 3 m beyond the edge before bending in, made the edge bridged
    across the 110 m gap a shoulder's width beyond it, 5.9 m off). A line meeting the line
    inward outside the gap, where the edge was seen beyond it, is the road's own
    (krems-102561705-opp-s7 with a noisier sensor: a lane opened by a new line and dropped
    150 m on, its line cut back to its first metre).
    """
    if d_edge is None:
        return None
    tip = tr.lo if first else tr.hi
    i = int(np.clip(np.searchsorted(grid, tip), 0, grid.size - 1))
    if not gap[i]:
        return None
    a, b = next((a, b) for a, b in true_runs(gap) if a <= i < b)
    seen_at = a - 1 if first else b
    near = tip - grid[a] if first else grid[b - 1] - tip
    if seen_at < 0 or seen_at >= grid.size or near > _AT_GAP_M or not np.isfinite(d_edge[seen_at]):
        return None
    if float(tr.d[0] if first else tr.d[-1]) <= float(d_edge[seen_at]) + _BEYOND_EDGE_M:
        return None
    if np.any(
        np.abs(_other_lines_at(*others, float(grid[seen_at])) - d_edge[seen_at]) < _NO_SHOULDER_M
    ):
        return None
    return float(grid[a]), float(grid[b - 1])


def _grid_index(s: FloatArray | float, grid: FloatArray, step: float) -> NDArray[np.int64]:
    """Index of the station of ``grid`` (spaced ``step``, metres) nearest to each of ``s``
    (metres), clipped to the grid."""
    return np.clip(np.rint((np.asarray(s) - grid[0]) / step).astype(np.int64), 0, grid.size - 1)


def _snap_to_hidden_gores(
    tracks: list[_Track],
    evidence: list[tuple[float, float, bool]],
    covered: NDArray[np.bool_],
    grid: FloatArray,
    cfg: MainlineConfig,
    d_edge: FloatArray | None = None,
) -> tuple[list[_Track], FloatArray]:
    """Place gores that an occlusion of the outer edge hid.

    A ramp line that meets (entry) or leaves (exit) the outermost mainline marking inside
    an occlusion gap marks the gore; an outer marking that starts or ends abruptly in the
    same gap is cut or extended to that station (ramp markings upstream of an entry gore
    otherwise make the lane start early). A converging (diverging) line beside which the
    outer edge ``d_edge`` (metres on ``grid``, same frame) was seen moving with it a
    shoulder's width away is the outer line of a lane closing (opening) by a taper, no
    ramp line (:func:`_moves_with_seen_edge`). Returns the tracks and the gore stations.
    """
    gores: list[float] = []
    at_lines: list[tuple[float, float, bool]] = []  # (gore, offset, exit) of the ramp lines cut
    out = list(tracks)
    step = cfg.grid_step_m
    # gaps inside the run only: where the edge is not seen again up to the run's end (its
    # start), a marking ending (starting) there is no evidence of a gore (a noisier sensor
    # at the end of krems-102561705-lane1-s21: a "gore" 12 m before the end, where the
    # line between two lanes ended, made them one lane 7.4 m wide)
    gap = ~covered
    for a, b in true_runs(gap):
        if a == 0 or b >= grid.size:
            gap[a:b] = False

    def hidden(s_at: float) -> bool:
        i = int(_grid_index(s_at, grid, step))
        return bool(gap[max(i - 10, 0) : i + 11].any())

    # a marking that starts (ends) inside such a gap while still converging (diverging)
    # is a ramp line until it runs parallel or meets the line inward: the gore is where it
    # does, hidden too (a9-10959882-opp-s7 with a noisier sensor: an acceleration lane's
    # line beginning at a nose in a gap and closing onto the line inward 100 m on, where
    # the edge was seen, was cut back to that meeting, its lane 6.3 m wide). Only the
    # outermost line there can be an outer ramp's: a line with lines farther out is the
    # mainline's (melbourne-1019-lane1-s21: the inner shoulder's line, bending towards an
    # inner exit where the outer edge was hidden, was cut back 11 m and made a "gore" 22 m
    # before it)
    for k, tr in enumerate(out):
        if tr.s.size < 20:
            continue
        if tr.lo > grid[0] + step and hidden(tr.lo) and _outermost_at(out, k, tr.lo):
            rel, rel_slope = _beside_inner_line(tracks, k, tr)
            par = np.flatnonzero((rel_slope > -cfg.hidden_gore_slope) | (rel < _MET_M))
            met = np.flatnonzero(rel < _MET_M)
            beside = _beside_road_in_gap(tr, True, gap, grid, d_edge, (out, k))
            if beside is not None and met.size and tr.s[met[0]] <= beside[1]:
                # a ramp's line up to where it meets the line inward, however it ran
                i0 = min(int(met[0]), tr.s.size - 2)
                tr = replace(tr, lo=float(tr.s[i0]), s=tr.s[i0:], d=tr.d[i0:])
                gores.append(tr.lo)
                at_lines.append((tr.lo, float(tr.d[0]), False))
            elif (
                par.size
                and par[0] > 0
                and tr.s[par[0]] - tr.lo >= 5.0
                and -_turn(rel_slope, tr.s, 0, int(par[0])) >= _RAMP_LINE_TURN_M
                and hidden(float(tr.s[par[0]]))
                and not _moves_with_seen_edge(tr, slice(0, par[0] + 1), covered, grid, d_edge)
            ):
                i0 = par[0]
                tr = replace(tr, lo=float(tr.s[i0]), s=tr.s[i0:], d=tr.d[i0:])
                gores.append(tr.lo)
                at_lines.append((tr.lo, float(tr.d[0]), False))
        # a line ending on a line that converges onto it is a lane closing from both
        # sides, no ramp line (melbourne-921-s2: cut back 70 m to where it began to bend)
        if (
            tr.hi < grid[-1] - step
            and hidden(tr.hi)
            and _outermost_at(out, k, tr.hi)
            and not _ends_on_converging_line(out, k, tr.hi, float(tr.d[-1]))
        ):
            rel, rel_slope = _beside_inner_line(tracks, k, tr)
            par = np.flatnonzero((rel_slope < cfg.hidden_gore_slope) | (rel < _MET_M))
            met = np.flatnonzero(rel < _MET_M)
            beside = _beside_road_in_gap(tr, False, gap, grid, d_edge, (out, k))
            if beside is not None and met.size and tr.s[met[-1]] >= beside[0]:
                i1 = max(int(met[-1]), 1) + 1
                tr = replace(tr, hi=float(tr.s[i1 - 1]), s=tr.s[:i1], d=tr.d[:i1])
                gores.append(tr.hi)
                at_lines.append((tr.hi, float(tr.d[-1]), True))
            elif (
                par.size
                and par[-1] < tr.s.size - 1
                and tr.hi - tr.s[par[-1]] >= 5.0
                and _turn(rel_slope, tr.s, int(par[-1]), tr.s.size - 1) >= _RAMP_LINE_TURN_M
                and hidden(float(tr.s[par[-1]]))
                and not _moves_with_seen_edge(tr, slice(par[-1], None), covered, grid, d_edge)
            ):
                i1 = par[-1] + 1
                tr = replace(tr, hi=float(tr.s[i1 - 1]), s=tr.s[:i1], d=tr.d[:i1])
                gores.append(tr.hi)
                at_lines.append((tr.hi, float(tr.d[-1]), True))
        out[k] = tr
    # the ramp's other lines beside such a gore begin (end) there too (melbourne-921-s9
    # with a noisier sensor: an entry's outer line, first seen 32 m before its gore, made
    # the ramp's lane the mainline's there and the edge 4 m off)
    for s_gore, d_g, leaves in at_lines:
        out = _cut_beside_gore(out, s_gore, d_g, step, _gap_around(gap, grid, s_gore), leaves)
    for s_g, d_g, leaves in evidence:
        i_g = int(_grid_index(s_g, grid, step))
        # inside (or within 10 m of) a gap of the outer-edge points
        lo_i, hi_i = max(i_g - 10, 0), min(i_g + 11, grid.size)
        if not gap[lo_i:hi_i].any():
            continue
        if _edge_moves_against(leaves, gap, lo_i, hi_i, d_edge):
            continue
        # it must touch the outermost mainline marking there (a line meeting one with
        # through lines farther out is an inner ramp's, whose gore does not step the outer
        # edge); its tip is where it was last kept, up to 1.5 m short of the line it meets
        # as it still converges (a9-206615404-opp-s9 with a noisier sensor: 1.3 m, the gore
        # was not placed and the edge widened linearly across its gap, 5 m off)
        near = [
            tr
            for j, tr in enumerate(out)
            if tr.lo - 1 <= s_g <= tr.hi + 1
            and abs(np.interp(s_g, tr.s, tr.d) - d_g) < _TIP_NEAR_M
            and _outermost_at(out, j, s_g)
        ]
        if not near:
            continue
        s_gore = float(grid[i_g])
        if any(abs(g - s_gore) < 30.0 for g in gores):
            continue
        gores.append(s_gore)
        out = _cut_beside_gore(out, s_gore, d_g, step, _gap_around(gap, grid, s_gore), leaves)
    return out, np.asarray(gores, dtype=float)


_AGAINST_EDGE_M = 1.5  # the edge widening (narrowing) across a gap by a lane's share


def _edge_moves_against(
    leaves: bool,
    gap: NDArray[np.bool_],
    lo_i: int,
    hi_i: int,
    d_edge: FloatArray | None,
) -> bool:
    """Whether the outer edge (``d_edge``, metres outward on the grid) seen at the ends of
    the occlusion gap (``gap``) that overlaps the grid stations ``lo_i:hi_i`` moved against
    a gore there: wider after the gap by ``_AGAINST_EDGE_M`` where the line cut off leaves
    the markings (``leaves``, an exit's), narrower where it meets them (an entry's). Such a
    line opens (closes) a lane by a taper: a lane gain whose new edge line left the old one
    inside a 143 m gap (oakland-28393854-lane1-s21+380 with a noisier sensor) was cut off
    as an exit's ramp line, and the gore placed where it left stepped the edge out there,
    the shoulder before it closing to the gore: 3.6 m off."""
    if d_edge is None:
        return False
    runs = [(a, b) for a, b in true_runs(gap) if a < hi_i and b > lo_i]
    if not runs:
        return False
    a, b = runs[0][0], runs[-1][1]
    if a == 0 or b >= gap.size:
        return False
    widens = float(d_edge[b] - d_edge[a - 1])
    return widens > _AGAINST_EDGE_M if leaves else widens < -_AGAINST_EDGE_M


_WITH_EDGE_SEEN_M = 10.0  # the edge seen beside this much of a moving line (metres) ...
_WITH_EDGE_MOVE_M = 0.5  # ... while it moved sideways by this much (metres) ...


def _moves_with_seen_edge(
    tr: _Track,
    part: slice,
    covered: NDArray[np.bool_],
    grid: FloatArray,
    d_edge: FloatArray | None,
) -> bool:
    """Whether the outer edge (``d_edge``, metres on ``grid``; seen where ``covered``)
    was seen beside the ``part`` of track ``tr`` that converges (diverges) over at least
    ``_WITH_EDGE_SEEN_M``, a shoulder's width (0-``_SHOULDER_MAX_M``) beyond it and moving
    with it: its gap to the line changed by less than ``_WITH_EDGE_SHARE`` of the line's
    own move there (``_WITH_EDGE_MOVE_M`` at least). That line closes (opens) a lane by a
    taper: an acceleration lane's outer line meeting the line inward, where a ramp's line
    meeting it at a gore has the mainline's edge inside it and the ramp's lane beyond it
    (a9-206615404-s1 with a noisier sensor: an acceleration lane's line, its start hidden,
    seen for 32 m beside an edge 2.4 m out, was taken for the ramp's; a gore made where it
    met the line inward dropped the lane over 100 m, lane count 2 for 3, edge 0.133 m)."""
    if d_edge is None:
        return False
    s, d = tr.s[part], tr.d[part]
    i = _grid_index(s, grid, float(grid[1] - grid[0]))
    seen = covered[i] & np.isfinite(d_edge[i])
    if np.count_nonzero(seen) * float(grid[1] - grid[0]) < _WITH_EDGE_SEEN_M:
        return False
    gap = d_edge[i][seen] - d[seen]
    moved = float(np.ptp(d[seen]))
    return bool(
        moved >= _WITH_EDGE_MOVE_M
        and np.all((gap > 0.0) & (gap < _SHOULDER_MAX_M))
        and float(np.ptp(gap)) < _WITH_EDGE_SHARE * moved
    )


def _gap_around(gap: NDArray[np.bool_], grid: FloatArray, s_at: float) -> tuple[float, float]:
    """The stations (metres) where the occlusion gap of the outer edge around ``s_at``
    (within 10 grid stations of it) begins and ends; an empty span where there is none."""
    i = int(np.clip(np.searchsorted(grid, s_at), 0, grid.size - 1))
    for a, b in true_runs(gap):
        if a - 10 <= i < b + 10:
            return float(grid[a]), float(grid[b - 1])
    return s_at, s_at


_CUT_NEAR_M = 60.0  # a line beginning (ending) this close to a gore is the ramp's ...
_GAP_SLACK_M = 5.0  # ... or beginning (ending) in the same occlusion gap, within this
_RUNS_ON_M = 10.0  # a line cut at a gore of known kind runs on this far past it (metres)


def _cut_beside_gore(
    tracks: list[_Track],
    s_gore: float,
    d_gore: float,
    step: float,
    gap: tuple[float, float] | None = None,
    leaves: bool | None = None,
) -> list[_Track]:
    """Lines beside a gore at ``s_gore`` (metres; its ramp line at ``d_gore`` metres) that
    begin less than 60 m before it (end less than 60 m after it), or anywhere in the
    occlusion gap of the outer edge the gore lies in (``gap``: its first and last
    stations, metres), and run on 60 m beyond it, cut to begin (end) at the gore: the
    ramp's lines. An entry's lines seen 66 m before its nose, from where the edge became
    unseen, were the mainline's and its acceleration lane began there, 5.7 m wide beside
    three shoulders (a9-10959882-opp-s7 with a noisier sensor, seed offset 620). Only the
    lines beside the gore: a through line nearer the median that happens to begin within
    60 m (after an inner exit) has nothing to do with it (melbourne-921-s2: the inner
    shoulder's line was cut back 51 m to an outer lane drop's gore, the shoulder became
    part of a lane 3.9 m wide).

    ``leaves``: the gore is an exit's (True: only lines that end after it are cut) or an
    entry's (False: only lines that begin before it); None: either. At an entry the line
    of the ramp seen from the gap on had been cut to end at the gore instead, as if an
    exit's (it ran on only 37 m past the nose)."""
    lo_gap, hi_gap = gap if gap is not None else (s_gore, s_gore)
    beyond = _CUT_NEAR_M if leaves is None else _RUNS_ON_M  # a line left after the cut
    out = list(tracks)
    for k, tr in enumerate(out):
        if float(np.interp(s_gore, tr.s, tr.d)) < d_gore - _BESIDE_GORE_M:
            continue
        near_lo = abs(tr.lo - s_gore) < _CUT_NEAR_M or lo_gap - _GAP_SLACK_M <= tr.lo < s_gore
        near_hi = abs(tr.hi - s_gore) < _CUT_NEAR_M or s_gore < tr.hi <= hi_gap + _GAP_SLACK_M
        if leaves is not True and near_lo and tr.lo < s_gore - step and tr.hi > s_gore + beyond:
            sel = tr.s >= s_gore
            out[k] = replace(tr, lo=s_gore, s=tr.s[sel], d=tr.d[sel])
        elif leaves is not False and near_hi and tr.hi > s_gore + step and tr.lo < s_gore - beyond:
            sel = tr.s <= s_gore
            out[k] = replace(tr, hi=s_gore, s=tr.s[sel], d=tr.d[sel])
    return out


_TIP_NEAR_M = 1.5  # a ramp line's tip this near the outermost line meets it (metres)
_SEEN_STEP_M = 100.0  # a lane whose edge was seen to begin (end) this close after (before)
# its marking's tip in an occlusion gap has its gore there, not in the gap (metres)


def _seen_steps(
    steps: FloatArray, d_edge: FloatArray, grid: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Stations of the outer edge's seen steps and whether each steps outwards (a lane
    begins: the edge moves away from the reference line)."""
    steps = np.asarray(steps, dtype=float)
    i = np.clip(np.searchsorted(grid, steps), 0, grid.size - 1)
    move = edge_move_at(d_edge, i)
    return steps, np.isfinite(move) & (move > 0.0)


def _place_hidden_gores(
    tracks: list[_Track],
    s_out: FloatArray,
    d_out: FloatArray,
    covered: NDArray[np.bool_],
    grid: FloatArray,
    taper_length_m: float | None = None,
    seen_steps: tuple[FloatArray, NDArray[np.bool_]] | None = None,
    line_gores: FloatArray | None = None,
) -> tuple[list[_Track], list[float], list[ShoulderTaper]]:
    """Gore stations inside occlusion gaps of the outer edge.

    For an outer marking that starts (entry) or ends (exit) inside a gap while the through
    lanes' outer marking runs on, the gore is placed by the marking's solid/broken change
    and the hard-shoulder taper seen before (entry) / after (exit) the gap
    (:mod:`roadtwin.mainline.gores`), and the marking is cut or extended to it. ``s_out``,
    ``d_out``: the outer-edge points of the mainline edge (metres, reference frame).
    Where the taper was not seen at all, the run's own taper length at gores that were
    seen (``taper_length_m``) shapes it, if the shoulder was seen at full width up to
    where that taper would begin. ``seen_steps`` (:func:`_seen_steps`): where the edge
    was seen to step outwards within ``_SEEN_STEP_M`` after an entry marking's tip
    (inwards before an exit marking's end), the lane's pavement begins (ends) there: that
    is its gore (a parallel entry's line starts far upstream of it), none is placed.
    A marking first (last) seen just after (before) a gap is asked about too
    (:func:`_lane_at_gap_end`), unless a ramp's line already showed a gore in the gap
    (``line_gores``, stations from :func:`_snap_to_hidden_gores`, metres) or the edge was
    seen stepping between the marking's tip and the gap.
    Returns the tracks, the gore stations placed and the shoulder tapers.
    """
    out = list(tracks)
    placed: list[float] = []
    tapers: list[ShoulderTaper] = []
    step = float(grid[1] - grid[0])
    # where the sensor saw any marking (a gap of all of them is missing frames)
    seen = np.sort(np.concatenate([t.s_samples for t in tracks])) if tracks else None
    for a, b in true_runs(~covered):
        if a == 0 or b >= grid.size:
            continue
        s_a, s_b = float(grid[a]), float(grid[b - 1])
        for k in range(len(out)):
            for entry in (True, False):
                tr = out[k]
                s_tip = tr.lo if entry else tr.hi
                beyond = tr.hi - s_b if entry else s_a - tr.lo
                if tr.s.size < 20 or beyond < 20.0:
                    continue
                late = not (s_a - step <= s_tip <= s_b + step)
                if late and not _lane_at_gap_end(
                    tr,
                    entry,
                    (s_a, s_b),
                    (s_out, d_out),
                    line_gores,
                    None if seen_steps is None else seen_steps[0],
                ):
                    continue
                if seen_steps is not None:
                    st, outward = seen_steps
                    ahead = (st > s_tip) & (st <= s_tip + _SEEN_STEP_M) & outward
                    behind = (st < s_tip) & (st >= s_tip - _SEEN_STEP_M) & ~outward
                    if (ahead if entry else behind).any():
                        continue
                d_tip = float(tr.d[0] if entry else tr.d[-1])
                through = [
                    t
                    for t in out
                    if t is not tr
                    and t.lo <= s_tip - 40.0
                    and t.hi >= s_tip + 40.0
                    and np.interp(s_tip, t.s, t.d) < d_tip - 1.0
                ]
                if not through:
                    continue
                nb = max(through, key=lambda t: float(np.interp(s_tip, t.s, t.d)))
                interval = marking_gore_interval(nb.s_samples, s_tip, entry=entry, seen_s=seen)
                if entry:
                    sel = (s_out > max(s_a - 200.0, nb.lo)) & (s_out < s_a)
                else:
                    sel = (s_out > s_b) & (s_out < min(s_b + 200.0, nb.hi))
                width = d_out[sel] - np.interp(s_out[sel], nb.s, nb.d)
                taper = fit_shoulder_taper(s_out[sel], width, entry=entry)
                if interval is None and taper is None:
                    continue
                s_gore = fuse_gore_estimates(interval, taper, s_tip)
                if late:  # its lane was there where the gap ends (begins)
                    s_gore = min(max(s_gore, s_a), s_b)
                elif _edge_beyond_line_at_gap_end(tr, entry, (s_a, s_b), (s_out, d_out)):
                    # a shoulder taper extrapolated past the gap's far end, where the
                    # lane's edge was seen already (krems-102561705-lane1-s21+440: 11 m
                    # past it, and the edge was bridged as a taper across the gap)
                    s_gore = min(s_gore, s_b) if entry else max(s_gore, s_a)
                if abs(s_gore - s_tip) > 40.0:
                    continue
                out[k] = _move_track_end(tr, s_gore, grid, start=entry)
                placed.append(s_gore)
                if taper is not None:
                    tapers.append(replace(taper, s_gore=s_gore))
                elif taper_length_m is not None and width.size >= 10:
                    s_w = s_out[sel]
                    near = np.abs(s_w - (s_a if entry else s_b)) < 30.0
                    begins = s_gore - taper_length_m if entry else s_gore + taper_length_m
                    seen_flat = begins >= s_a - 10.0 if entry else begins <= s_b + 10.0
                    if np.count_nonzero(near) >= 10 and seen_flat:
                        full = float(np.median(width[near]))
                        tapers.append(ShoulderTaper(s_gore, taper_length_m, full, entry, math.nan))
                log.info(
                    "mainline: %s gore in an occlusion gap at s=%.1f m (marking interval %s, "
                    "shoulder taper %s)",
                    "entry" if entry else "exit",
                    s_gore,
                    "none" if interval is None else f"{interval[0]:.1f}..{interval[1]:.1f}",
                    "none" if taper is None else f"{taper.s_gore:.1f}",
                )
    return out, placed, tapers


_LATE_TIP_M = 20.0  # a line first (last) seen this far after (before) a gap ...
_AT_END_M = 10.0  # ... beside the edge seen this far past the gap's end (before its start)


def _lane_at_gap_end(
    tr: _Track,
    entry: bool,
    gap: tuple[float, float],
    points: tuple[FloatArray, FloatArray],
    line_gores: FloatArray | None = None,
    seen_steps: FloatArray | None = None,
) -> bool:
    """Whether track ``tr``, first seen (``entry``; else last seen) within ``_LATE_TIP_M``
    after the end (before the start) of the occlusion gap ``gap`` (first and last
    station) of the outer edge (metres), has its lane there already: the edge points
    (``points``: stations and offsets) within ``_AT_END_M`` past that end lie beyond the
    line by more than
    ``_NO_SHOULDER_M``. The lane began (ended) at a gore in the gap, its line's paint
    starting later (melbourne-408-opp-s4 with a noisier sensor: an entry's line first seen
    14 m after the gap that hid the nose, the lane was opened by a taper across the gap
    and the edge bridged 4-5 m off; an exit's, krems-46762523-s2: its lane closed by a
    250 m taper, edge 0.229 -> 0.056 m). Only where the gap is an occlusion
    (``_STRIP_GAP_M`` long: melbourne-1019-s11 with a noisier sensor, seed
    offset 200, an exit's step seen 9 m past its line's end, then a 1 m gap; a gore put
    in that gap, edge 0.093 -> 0.115 m), no ramp's line showed a gore in it
    (``line_gores``, stations in metres) and no step of the edge (``seen_steps``) was
    seen between the line's tip and the gap: that step is the gore (a9-206615404-s2, seed
    offset 200: one seen where the line ended, 6 m before the gap; moved into it, 0.054
    -> 0.068 m)."""
    s_a, s_b = gap
    s_tip = tr.lo if entry else tr.hi
    late = (s_tip - s_b) if entry else (s_a - s_tip)
    if not 0.0 < late <= _LATE_TIP_M or s_b - s_a < _STRIP_GAP_M:
        return False
    if _any_between(line_gores, s_a, s_b) or _any_between(seen_steps, s_tip, s_b if entry else s_a):
        return False
    return _edge_beyond_line_at_gap_end(tr, entry, gap, points)


def _edge_beyond_line_at_gap_end(
    tr: _Track, entry: bool, gap: tuple[float, float], points: tuple[FloatArray, FloatArray]
) -> bool:
    """Whether the edge points (``points``: stations and offsets, metres) within
    ``_AT_END_M`` past the end (``entry``; else before the start) of the occlusion gap
    ``gap`` (first and last station, metres) lie beyond track ``tr``'s line at its tip by
    more than ``_NO_SHOULDER_M``: its lane is there already, so its gore lies in the gap."""
    s_a, s_b = gap
    s_out, d_out = points
    near = (
        (s_out > s_b) & (s_out <= s_b + _AT_END_M)
        if entry
        else (s_out < s_a) & (s_out >= s_a - _AT_END_M)
    )
    if np.count_nonzero(near) < 5:
        return False
    d_tip = float(tr.d[0] if entry else tr.d[-1])
    return float(np.median(d_out[near])) > d_tip + _NO_SHOULDER_M


def _any_between(stations: FloatArray | None, s0: float, s1: float) -> bool:
    """Whether any of ``stations`` (metres; None: none) lies between ``s0`` and ``s1``
    (metres, either order)."""
    if stations is None:
        return False
    st = np.asarray(stations, dtype=float)
    return bool(np.any((st >= min(s0, s1)) & (st <= max(s0, s1))))


_NO_SHOULDER_M = 0.5  # an edge this near the outermost line has no shoulder (metres)
_STRIP_GAP_M = 10.0  # an occlusion gap of the outer edge at least this long (metres; as
# outer_edge._SPLIT_GAP_M, which this module cannot import: outer_edge imports it)
_FLAT_STATIONS = 20  # grid stations either side of a gap over which the edge is flat


def _gores_at_lane_wide_strips(
    d_edge: FloatArray,
    covered: NDArray[np.bool_],
    tracks: list[_Track],
    grid: FloatArray,
    lane_m: float,
    gores: FloatArray,
) -> list[float]:
    """Gores (stations, metres) in occlusion gaps of the outer edge (``d_edge`` on
    ``grid``, seen where ``covered``; gaps of ``_STRIP_GAP_M`` or more inside the run)
    across which the outermost marking goes on while the strip beyond it goes from no
    shoulder (under ``_NO_SHOULDER_M``) to a lane (``lane_m`` less 0.4 m, metres) or back,
    the edge flat on the shoulderless side and not going on to widen (narrow) on the other
    (an entry's acceleration lane, an exit's deceleration lane, their own outer line unseen
    or unpainted; one that closes again just after the gap is still one: soderleden-
    lane1-s21 with a noisier sensor, a 70 m gap up to the acceleration lane's end taper).
    None where a gore is already placed in the gap (``gores``). The lane begins (ends) at
    full width at a gore somewhere in the gap; nothing seen says where: its middle.
    Bridged as a widening strip instead, the lane was a shoulder over the gap and beyond
    (soderleden-s7 with a noisier sensor: an entry hidden over 65 m, lane count 94.9 %,
    edge 2.6 m off)."""
    d_last = _last_marking(tracks, grid)
    out: list[float] = []
    for a, b in true_runs(~covered):
        i0, i1 = a - 1, b
        if a == 0 or b >= grid.size or grid[i1] - grid[i0] < _STRIP_GAP_M:
            continue
        if np.any((gores >= grid[i0]) & (gores <= grid[i1])):
            continue
        if not (np.isfinite(d_last[i0]) and np.isfinite(d_last[i1])):
            continue
        if abs(d_last[i1] - d_last[i0]) > _NO_SHOULDER_M:
            continue
        hw0, hw1 = d_edge[i0] - d_last[i0], d_edge[i1] - d_last[i1]
        # how far the edge moved outward over the stations before / after the gap
        out0 = d_edge[i0] - d_edge[max(i0 - _FLAT_STATIONS, 0)]
        out1 = d_edge[min(i1 + _FLAT_STATIONS, grid.size - 1)] - d_edge[i1]
        # the lane opens: no shoulder, flat, before the gap; after it the strip is a lane
        # wide and does not go on widening (a taper) -- it may close again (its end)
        opens = hw0 < _NO_SHOULDER_M and hw1 > lane_m - 0.4
        opens &= abs(out0) < _NO_SHOULDER_M and out1 < _NO_SHOULDER_M
        closes = hw1 < _NO_SHOULDER_M and hw0 > lane_m - 0.4
        closes &= abs(out1) < _NO_SHOULDER_M and out0 > -_NO_SHOULDER_M
        if opens or closes:
            out.append(float(0.5 * (grid[a] + grid[b - 1])))
    return out


def _visible_taper_length(
    steps: FloatArray,
    d_edge: FloatArray,
    tracks: list[_Track],
    s_out: FloatArray,
    d_out: FloatArray,
    grid: FloatArray,
) -> float | None:
    """Median length (metres) of the hard-shoulder tapers fitted at the seen edge steps
    (gores), or None if none could be fitted."""
    d_last = _last_marking(tracks, grid)
    lengths = []
    for b in steps:
        i = int(np.searchsorted(grid, b))
        if i < 5 or i + 5 >= grid.size:
            continue
        entry = bool(edge_move_at(d_edge, i) > 0.0)  # the edge steps out: a lane begins
        sel = (s_out > b - 200.0) & (s_out < b) if entry else (s_out > b) & (s_out < b + 200.0)
        mark = np.interp(s_out[sel], grid, d_last)
        ok = np.isfinite(mark)
        fit = fit_shoulder_taper(s_out[sel][ok], d_out[sel][ok] - mark[ok], entry=entry)
        if fit is not None and abs(fit.s_gore - b) < 5.0:
            lengths.append(fit.length_m)
    return float(np.median(lengths)) if lengths else None


_SAME_GORE_M = 60.0  # a ramp-line gore estimate this close to a placed gore is that gore


def _replace_line_gores(
    tracks: list[_Track], gores: FloatArray, placed: list[float], grid: FloatArray
) -> tuple[list[_Track], list[float]]:
    """The ramp-line gore estimates (:func:`_snap_to_hidden_gores`) that a gore placed by
    the edge's shoulder taper (:func:`_place_hidden_gores`) replaces, and the tracks they
    cut moved to the placed one: a line that began (ended) at the estimate begins (ends)
    at the first (last) grid station after (before) the placed gore where that lies after
    (before) it. A two-lane entry's middle line converging in a gap runs parallel 40 m
    before the nose, where its estimate cut it: its lane began there (krems-30799129-s11
    with a noisier sensor, edge 0.17 -> 0.54 m when the markings in the gap were bounded
    by the wider end of the gap). Returns the tracks and the estimates kept (metres)."""
    step_m = float(grid[1] - grid[0])
    kept: list[float] = []
    out = list(tracks)
    for g in np.asarray(gores, dtype=float).tolist():
        near = [p for p in placed if abs(g - p) <= _SAME_GORE_M]
        if not near:
            kept.append(g)
            continue
        p = min(near, key=lambda v: abs(v - g))
        for k, tr in enumerate(out):
            if abs(tr.lo - g) <= step_m and p > g and tr.hi > p + _SAME_GORE_M:
                out[k] = _move_track_end(tr, float(tr.s[tr.s >= p][0]), grid, start=True)
            elif abs(tr.hi - g) <= step_m and p < g and tr.lo < p - _SAME_GORE_M:
                out[k] = _move_track_end(tr, float(tr.s[tr.s <= p][-1]), grid, start=False)
    return out, kept


def _move_track_end(tr: _Track, s_new: float, grid: FloatArray, *, start: bool) -> _Track:
    """``tr`` cut or extended (at its end offset) so that it starts/ends at ``s_new``."""
    if start:
        if s_new >= tr.lo:
            sel = tr.s >= s_new
            new_s, new_d = tr.s[sel], tr.d[sel]
            if new_s.size == 0 or new_s[0] > s_new:
                new_s = np.concatenate([[s_new], new_s])
                new_d = np.concatenate([[np.interp(s_new, tr.s, tr.d)], new_d])
        else:
            ext = np.concatenate([[s_new], grid[(grid > s_new) & (grid < tr.s[0])]])
            new_s = np.concatenate([ext, tr.s])
            new_d = np.concatenate([np.full(ext.size, tr.d[0]), tr.d])
        return replace(tr, lo=s_new, s=new_s, d=new_d)
    if s_new <= tr.hi:
        sel = tr.s <= s_new
        new_s, new_d = tr.s[sel], tr.d[sel]
        if new_s.size == 0 or new_s[-1] < s_new:
            new_s = np.concatenate([new_s, [s_new]])
            new_d = np.concatenate([new_d, [np.interp(s_new, tr.s, tr.d)]])
    else:
        ext = np.concatenate([grid[(grid < s_new) & (grid > tr.s[-1])], [s_new]])
        new_s = np.concatenate([tr.s, ext])
        new_d = np.concatenate([tr.d, np.full(ext.size, tr.d[-1])])
    return replace(tr, hi=s_new, s=new_s, d=new_d)


def _hermite01(x: FloatArray, v0: float, m0: float) -> FloatArray:
    """Cubic from value ``v0`` with slope ``m0`` (per unit x) at x = 0 to value 0 with
    slope 0 at x = 1."""
    return v0 * (1.0 - x * x * (3.0 - 2.0 * x)) + m0 * x * (1.0 - x) ** 2
