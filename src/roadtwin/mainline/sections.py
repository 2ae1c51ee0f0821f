"""Lane sections from marking tracks and the outer edge: section borders at track ends
and edge steps, lane widths as cubic pieces (tapers at gores), lane types from width
and the car, links across sections by border geometry, and the lane events.
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
    close_width,
    continue_width,
)
from ._common import (
    BoundaryTrack,
    LaneEvent,
    _fill_nan,
)
from .gores import (
    smoothstep,
    taper_width,
)
from .markings import _dashed, _mark_type, _Track
from .seal import add_linear_ramp

FloatArray = NDArray[np.float64]


_GORE_MATCH_M = 20.0  # a marking ending this close to an edge step ends at that gore

_RESIDUAL_WIDTH_M = 1.0  # a lane beginning/ending narrower than this is a taper's rest
_ZERO_FADE_M = 20.0  # ... and its rest fades out over this where a whole piece cannot

_LINK_TOLERANCE_M = 0.3  # lanes whose borders meet this closely continue across sections
_WIDTH_JUMP_M = 1.0  # a driving lane this much narrower/wider beyond a border is the same


_LATE_LINE_M = 60.0  # a line first seen this soon after an entry's gore ...
_LATE_LINE_LANE_M = 1.5  # ... this far from its neighbour (a lane, not a taper's tip)
_SPLIT_SAME_M = 0.3  # a neighbour this close to a line's offset was at the line
_SPLIT_MIN_M = 1.0  # ... and this far from it at the line's first station has left it


_STRIP_CLOSE_M = 20.0  # a line this near its neighbour that ends meets it over this (m)
_STRIP_SEEN_M = 50.0  # ... if it ran beside it this long (metres) ...
_STRIP_STEADY_M = 0.3  # ... at a separation varying by no more than this (metres)

_SHOULDER_LINE_M = 20.0  # shortest section in which an edge line can be a shoulder's line
_SHOULDER_MIN_M = 1.8  # ... whose shoulder is at least this wide all through it (metres)


def _first_seen(
    dmat: FloatArray, grid: FloatArray
) -> tuple[NDArray[np.bool_], NDArray[np.intp], int]:
    """Where each track of ``dmat`` is seen, its first grid index, and how many grid steps
    ``_LATE_LINE_M`` spans (a late-seen line is first seen that soon after its cause)."""
    seen = np.isfinite(dmat)
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    return seen, np.argmax(seen, axis=1), round(_LATE_LINE_M / max(step, 1e-9))


def _lines_to_gores(
    dmat: FloatArray, grid: FloatArray, d_edge: FloatArray, steps: FloatArray
) -> None:
    """Lines first seen soon after an entry's gore begin at the gore: ``dmat`` (tracks x
    ``grid``, offsets in metres, NaN where absent) is filled in place from the line's
    first offset back to the step.

    At an entry's step the outer edge (``d_edge``) moves out and the entry's lanes begin
    at full width; a line between them that the sensor first saw ``_LATE_LINE_M`` or less
    later, already at least ``_LATE_LINE_LANE_M`` from its neighbour, was there from the
    gore. a9-8081560 driven in its third lane: an acceleration lane's outer line was first
    seen 48 m after the gore, and over those metres the lane was a shoulder 6.4 m wide. A
    line that would leave the road (beyond the edge) is left as it is. Not at an exit: the
    line between the through and the exit lane ends at the painted gore's tip, tens of
    metres before the step (extended, two exits were attached 10-24 m late)."""
    n_g = grid.size
    for b in steps:
        i_b = int(np.searchsorted(grid, b))
        if i_b <= 0 or i_b >= n_g - 1:
            continue
        if d_edge[min(i_b + 5, n_g - 1)] <= d_edge[max(i_b - 5, 0)]:
            continue  # the edge moves in: an exit
        seen, first, span = _first_seen(dmat, grid)  # again: earlier steps filled dmat
        late = (seen.sum(axis=1) >= 10) & (first > i_b) & (first - i_b <= span)
        for k in np.flatnonzero(late):
            i0 = int(first[k])
            d_k = float(dmat[k, i0])
            sep = np.abs(np.delete(dmat[:, i0], k) - d_k)
            sep = sep[np.isfinite(sep)]
            if sep.size == 0 or sep.min() < _LATE_LINE_LANE_M:
                continue
            if np.any(d_edge[i_b:i0] - d_k < 0.3):
                continue
            dmat[k, i_b:i0] = d_k


def _lines_from_splits(dmat: FloatArray, grid: FloatArray) -> None:
    """Lines first seen soon after a neighbouring line left their offset begin where it
    left: ``dmat`` (tracks x ``grid``, offsets in metres, NaN where absent) is filled in
    place back to the station where the neighbour was last within ``_SPLIT_SAME_M``.

    A lane opens between the two: the old line's position is kept by the new lane's inner
    (outer) line, which a noisier sensor may see only later (a broken line, markings
    missed), while the line that moves away is the new lane's other border. Without it the
    lane beside the old position widened to 5 m (melbourne-18-s11+80: the third lane
    opening over 100 m from s = 17 m, its inner line first seen at 61 m). The neighbour
    must have moved at least ``_SPLIT_MIN_M`` away by the line's first station, within
    ``_LATE_LINE_M`` of it, with no line between them."""
    seen, first, span = _first_seen(dmat, grid)
    for k in np.flatnonzero((seen.sum(axis=1) >= 10) & (first > 0)):
        i0 = int(first[k])
        d_k = float(dmat[k, i0])
        lo = max(i0 - span, 0)
        best: tuple[int, int] | None = None
        for j in range(dmat.shape[0]):
            if j == k or not seen[j, lo : i0 + 1].all():
                continue
            gap = np.abs(dmat[j, lo : i0 + 1] - d_k)
            if gap[-1] < _SPLIT_MIN_M:
                continue
            close = np.flatnonzero(gap < _SPLIT_SAME_M)
            if close.size == 0:
                continue
            i_s = lo + int(close[-1])
            between = [
                m
                for m in range(dmat.shape[0])
                if m not in (j, k)
                and seen[m, i_s:i0].any()
                and np.any((dmat[m, i_s:i0] - d_k) * (dmat[j, i_s:i0] - dmat[m, i_s:i0]) > 0.0)
            ]
            if not between and (best is None or i_s > best[0]):
                best = (i_s, j)
        if best is not None:
            dmat[k, best[0] : i0] = d_k


def _taper(
    dmat: FloatArray,
    k: int,
    grid: FloatArray,
    end: str,
    cfg: MainlineConfig,
    fixed: tuple[float, float] | None = None,
    samples: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[float, float, int] | None:
    """Extend track ``k`` at its start/end to where it meets its nearest neighbour.

    The separation from the neighbour is modelled as a smoothstep (cubic) taper whose
    mid-point and slope are measured where the separation passes half the full width.
    ``dmat`` is filled in place over the unobserved part of the taper. Returns
    ``(s_zero, taper_length, neighbour)`` or None if the track starts/ends at full width.
    ``fixed = (s_zero, taper)`` imposes the taper (an inferred marking that opens with
    an observed one) and overwrites the track over it. With the track's raw ``samples``
    (stations, offsets) the taper's zero station and length are refined by a least-squares
    fit of the cubic taper to them (:func:`_fit_taper`).
    """
    n_g = grid.size
    idx = np.nonzero(np.isfinite(dmat[k]))[0]
    i_edge = int(idx[0] if end == "start" else idx[-1])
    others = [j for j in range(dmat.shape[0]) if j != k and np.isfinite(dmat[j, i_edge])]
    if not others:
        return None
    jn = min(others, key=lambda j: abs(dmat[k, i_edge] - dmat[j, i_edge]))
    span = int(300.0 / cfg.grid_step_m)
    sl = (
        slice(i_edge, min(i_edge + span, n_g))
        if end == "start"
        else slice(max(i_edge - span, 0), i_edge + 1)
    )
    both = np.isfinite(dmat[k, sl]) & np.isfinite(dmat[jn, sl])
    gs = grid[sl][both]
    sep = np.abs(dmat[k, sl] - dmat[jn, sl])[both]
    if gs.size < 10:
        return None
    w_full = float(np.percentile(sep, 90))
    # the side of the neighbour the track runs on where it is open (at its very end the
    # two may have met)
    sgn = float(np.sign(np.median((dmat[k, sl] - dmat[jn, sl])[both])))
    if fixed is not None and w_full >= 1.0:
        s_zero, taper = fixed
        if end == "start":
            dmat[k, grid < s_zero] = np.nan
            fill = (grid >= s_zero) & (grid < s_zero + taper)
            x = (grid[fill] - s_zero) / taper
        else:
            dmat[k, grid > s_zero] = np.nan
            fill = (grid > s_zero - taper) & (grid <= s_zero)
            x = (s_zero - grid[fill]) / taper
        ok = fill & np.isfinite(dmat[jn])
        dmat[k, ok] = dmat[jn, ok] + sgn * w_full * smoothstep(x[ok[fill]])
        return s_zero, taper, jn
    sep0 = float(np.abs(dmat[k, i_edge] - dmat[jn, i_edge]))
    if w_full < 1.0 or sep0 > 0.7 * w_full:
        return None
    mid = (sep > 0.3 * w_full) & (sep < 0.7 * w_full)
    if np.count_nonzero(mid) < 3:
        return None
    slope, icpt = np.polyfit(gs[mid], sep[mid], 1)
    if abs(slope) < 1e-4:
        return None
    s50 = (0.5 * w_full - icpt) / slope
    taper = float(min(1.5 * w_full / abs(slope), cfg.lane_taper_max_m))
    s_edge = float(grid[i_edge])
    if end == "start":
        s_zero = float(np.clip(s50 - 0.5 * taper, grid[0], s_edge))
    else:
        s_zero = float(np.clip(s50 + 0.5 * taper, s_edge, grid[-1]))
    refined = _fit_taper(samples, dmat[jn], grid, s_zero, taper, w_full, end, cfg)
    if refined is not None:
        # the taper model replaces the smoothed track over the whole taper: the smoother
        # rounds a taper's steep start off
        s_zero, taper = refined
        if end == "start":
            dmat[k, grid < s_zero] = np.nan
            fill = (grid >= s_zero) & (grid < s_zero + taper)
        else:
            dmat[k, grid > s_zero] = np.nan
            fill = (grid > s_zero - taper) & (grid <= s_zero)
    elif end == "start":
        fill = (grid >= s_zero) & (grid < s_edge)
    else:
        fill = (grid > s_edge) & (grid <= s_zero)
    x = (grid[fill] - s_zero) / taper if end == "start" else (s_zero - grid[fill]) / taper
    ok = fill & np.isfinite(dmat[jn])
    dmat[k, ok] = dmat[jn, ok] + sgn * w_full * smoothstep(x[ok[fill]])
    return s_zero, taper, jn


def _close_strip(dmat: FloatArray, k: int, grid: FloatArray, end: str) -> bool:
    """Let line ``k``, whose paint starts/ends beside another line closer than a lane's
    rest (``_RESIDUAL_WIDTH_M``), meet that line over ``_STRIP_CLOSE_M`` beyond its end.

    The strip between them is no lane (a shoulder split by a painted line, Town06's
    0.64 + 0.5 m): where the paint stops, the two strips become one shoulder. Left open,
    both strips ended unlinked at the section border, closed to zero width there, and
    every lane outside them stepped 1.15 m towards the median for 40 m
    (town06-auto-lane1-s21). Only a strip of steady width (within ``_STRIP_STEADY_M``
    over the ``_STRIP_SEEN_M`` next to the end) beside a line that runs on past the
    closing: a ramp's line starting near a mainline line at an entry converges with it
    and is no split shoulder (melbourne-921-s9 with a noisier sensor). ``dmat`` is filled
    in place. Returns whether the line met a neighbour."""
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    idx = np.flatnonzero(np.isfinite(dmat[k]))
    i_edge = int(idx[0] if end == "start" else idx[-1])
    n_seen = round(_STRIP_SEEN_M / step)
    n_close = round(_STRIP_CLOSE_M / step)
    if end == "start":
        seen, closing = slice(i_edge, i_edge + n_seen), slice(i_edge - n_close, i_edge)
    else:
        seen, closing = (
            slice(i_edge - n_seen + 1, i_edge + 1),
            slice(i_edge + 1, i_edge + n_close + 1),
        )
    if seen.start < 0 or closing.start < 0 or max(seen.stop, closing.stop) > grid.size:
        return False
    if not np.all(np.isfinite(dmat[k, seen])):
        return False
    others = [
        j
        for j in range(dmat.shape[0])
        if j != k and np.all(np.isfinite(dmat[j, seen])) and np.all(np.isfinite(dmat[j, closing]))
    ]
    if not others:
        return False
    jn = min(others, key=lambda j: abs(float(dmat[j, i_edge] - dmat[k, i_edge])))
    gaps = dmat[k, seen] - dmat[jn, seen]
    gap = float(dmat[k, i_edge] - dmat[jn, i_edge])
    if abs(gap) >= _RESIDUAL_WIDTH_M or float(np.ptp(gaps)) > _STRIP_STEADY_M:
        return False
    x = (
        np.linspace(0.0, 1.0, n_close + 1)[1:]
        if end == "start"
        else np.linspace(1.0, 0.0, n_close + 1)[:-1]
    )
    dmat[k, closing] = dmat[jn, closing] + gap * smoothstep(x)
    return True


def _fit_taper(
    samples: tuple[FloatArray, FloatArray] | None,
    d_neighbour: FloatArray,
    grid: FloatArray,
    s_zero: float,
    taper: float,
    w_full: float,
    end: str,
    cfg: MainlineConfig,
) -> tuple[float, float] | None:
    """Zero-width station and length (metres) of a cubic lane taper fitted to the raw
    samples of the opening (``end == "start"``) or closing marking, as separations from
    its neighbour (offsets ``d_neighbour`` on ``grid``, NaN where it is absent), starting
    from ``(s_zero, taper)``. None if there are too few samples in the taper or the fit
    leaves the plausible range."""
    from scipy.optimize import least_squares

    if samples is None or samples[0].size < 15:
        return None
    s_raw, d_raw = samples
    lo, hi = (s_zero, s_zero + taper) if end == "start" else (s_zero - taper, s_zero)
    have = np.isfinite(d_neighbour)
    if np.count_nonzero(have) < 2:
        return None
    win = (s_raw >= lo - 0.25 * taper) & (s_raw <= hi + 0.25 * taper)
    s_w = s_raw[win]
    sep = np.abs(d_raw[win] - np.interp(s_w, grid[have], d_neighbour[have]))
    # the taper itself must be seen, not only the full-width lane beside it
    if np.count_nonzero((sep > 0.2 * w_full) & (sep < 0.8 * w_full)) < 10:
        return None

    def residual(p: FloatArray) -> FloatArray:
        return sep - taper_width(s_w, w_full, p[0], max(p[1], 1.0), entry=end == "end")

    res = least_squares(
        residual, np.array([s_zero, taper]), loss="soft_l1", f_scale=0.1, x_scale=10.0
    )
    s_fit, l_fit = float(res.x[0]), float(res.x[1])
    if not (5.0 <= l_fit <= cfg.lane_taper_max_m) or abs(s_fit - s_zero) > taper:
        return None
    return s_fit, l_fit


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
    _lines_to_gores(dmat, grid, d_edge, outer_steps)
    _lines_from_splits(dmat, grid)
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
                    raw_events.append((k, end, s_ev, 0.0, None))
            else:
                raw_events.append((k, end, info[0], info[1], info[2]))
    # sections: runs of a constant set of tracks
    present = np.isfinite(dmat)
    change = np.flatnonzero(np.any(present[:, 1:] != present[:, :-1], axis=0)) + 1
    starts = [0, *change.tolist()]
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
            if i == 0 or i in offset_steps or abs(i - i_b) * cfg.grid_step_m >= 20.0
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
            and offset_steps & {i, merged_starts[-1]}
            and i - merged_starts[-1] >= min_tail
        ):
            merged_starts.append(i)  # a median step and another step: each starts a section
    starts = [*merged_starts, n_g]
    sections: list[LaneSection] = []
    bounds_per: list[list[tuple[object, object]]] = []
    medians: list[tuple[float, float]] = []  # the median-side edge at section start, end
    # an edge line painted along a road edge all its length (no shoulder there) is that
    # edge, not the border of a lane a few centimetres wide (a shoulder opening from zero
    # beside a gore separates from the edge: its line stays)
    edge_lines = set()
    for k in range(len(tracks)):
        on = np.isfinite(dmat[k])
        if np.count_nonzero(on) < 10:
            continue
        to_edge = float(np.median(d_edge[on] - dmat[k, on]))
        to_median = float(np.median(dmat[k, on] - d_median[on]))
        if min(to_edge, to_median) < cfg.edge_line_m:
            edge_lines.add(k)

    def shoulder_line_in(k: int, lo: int, hi: int) -> bool:
        """An edge line that runs a whole shoulder's width inside the outer edge all
        through the section ``lo:hi`` (at least ``_SHOULDER_LINE_M`` long) is the
        shoulder's line there: the same solid line is the edge line where the hard
        shoulder is missing (melbourne-18-s11+80: dropped all along, the lane beside it
        took a 2.4 m shoulder, 7.3 m wide)."""
        on = np.isfinite(dmat[k, lo:hi])
        if (hi - lo) * cfg.grid_step_m < _SHOULDER_LINE_M or not on.all():
            return False
        gap = d_edge[lo:hi] - dmat[k, lo:hi]
        return bool(np.min(gap) >= _SHOULDER_MIN_M)

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
    and esmini's car in the inner lane jumped 3.1 m to the next lane."""
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


def _grid_index(s: float, grid: FloatArray, cfg: MainlineConfig) -> int:
    """Index of the first grid station at or after ``s`` (metres), within the grid's
    inner stations."""
    return int(np.clip(np.ceil((s - grid[0]) / cfg.grid_step_m - 1e-9), 1, grid.size - 1))


def _make_section(s0: float, lanes: list[Lane], sign: float) -> LaneSection:
    return LaneSection(s0, right=tuple(lanes)) if sign > 0 else LaneSection(s0, left=tuple(lanes))


def _side_lanes(sec: LaneSection) -> tuple[Lane, ...]:
    return sec.right if sec.right else sec.left


def _nonnegative(candidates: tuple[Lane, ...], original: Lane, ds: FloatArray) -> Lane:
    """The first of ``candidates`` whose width does not dip below zero on ``ds``
    (metres), else ``original``."""
    for fixed in candidates:
        if float(np.min(fixed.width.value(ds))) >= 0.0:
            return fixed
    return original


def _between_linked(lanes: tuple[Lane, ...], i: int, link: str) -> bool:
    """Whether lanes inside and outside lane ``i`` are linked (``link``: the attribute,
    ``"predecessor"`` or ``"successor"``)."""
    return any(getattr(o, link) is not None for o in lanes[:i]) and any(
        getattr(o, link) is not None for o in lanes[i + 1 :]
    )


def _open_from_zero(lane: Lane, sec_len: float) -> tuple[Lane, ...]:
    """``lane`` corrected to start at zero width: over its first piece, or if that makes
    it negative, over ``_ZERO_FADE_M`` (:func:`.seal.add_linear_ramp`; ``sec_len`` metres,
    inf for the road's last section)."""
    w0 = float(lane.width.value(np.array([0.0]))[0])
    fade = min(_ZERO_FADE_M, sec_len)
    faded = add_linear_ramp(lane.width, 0.0, fade, -w0, 0.0, sec_len)
    return continue_width(lane, 0.0), replace(lane, width=faded)


def _close_to_zero(lane: Lane, sec_len: float) -> tuple[Lane, ...]:
    """``lane`` corrected to end at zero width at ``sec_len`` (see :func:`_open_from_zero`)."""
    w1 = float(lane.width.value(np.array([sec_len]))[0])
    fade = min(_ZERO_FADE_M, sec_len)
    faded = add_linear_ramp(lane.width, sec_len - fade, sec_len, 0.0, -w1, sec_len)
    return close_width(lane, sec_len), replace(lane, width=faded)


def _link_first_free(
    i: int, candidates: NDArray[np.bool_], mapping: dict[int, int], used: set[int]
) -> None:
    """Link lane ``i`` after a border to the first lane before it among ``candidates``
    that is not linked yet (``mapping``: after -> before; ``used``: linked befores)."""
    for j in np.flatnonzero(candidates).tolist():
        if j not in used:
            mapping[i] = j
            used.add(j)
            return


def _link_refitted_outer_lanes(
    prev_lanes: tuple[Lane, ...],
    cur_lanes: tuple[Lane, ...],
    b_prev: FloatArray,
    b_cur: FloatArray,
    mapping: dict[int, int],
    used: set[int],
) -> None:
    """Link the driving lanes of the outermost unlinked lanes on both sides of a border
    pairwise when they are the same lanes fitted anew: as many of them, of the same types,
    between an inner border and an outer edge that meet (``_LINK_TOLERANCE_M``; borders
    in metres from the median-side edge). A line between them that the two fits place
    more than ``_WIDTH_JUMP_M`` apart left a driving lane ending at full width where the
    same lane began at full width, a dead end (melbourne-1019-lane1-s21 with a noisier
    sensor: 2.67 m before the border, 4.08 m after it, the edge in place); linked, it
    continues with the width it had (:func:`_link_sections`)."""
    free_prev = [j for j in range(len(prev_lanes)) if j not in used]
    free_cur = [i for i in range(len(cur_lanes)) if i not in mapping]
    if not free_prev or not free_cur:
        return
    j0, i0 = free_prev[0], free_cur[0]
    if free_prev != list(range(j0, len(prev_lanes))) or free_cur != list(range(i0, len(cur_lanes))):
        return
    if len(free_prev) != len(free_cur):
        return
    if abs(b_prev[j0] - b_cur[i0]) > _LINK_TOLERANCE_M or abs(b_prev[-1] - b_cur[-1]) > (
        _LINK_TOLERANCE_M
    ):
        return
    if any(
        prev_lanes[j].type != cur_lanes[i].type for j, i in zip(free_prev, free_cur, strict=True)
    ):
        return
    for j, i in zip(free_prev, free_cur, strict=True):
        if cur_lanes[i].type == "driving":
            mapping[i] = j
            used.add(j)


def _link_sections(
    sections: list[LaneSection],
    bounds_per: list[list[tuple[object, object]]],
    medians: list[tuple[float, float]] | None = None,
    at_step: list[bool] | None = None,
) -> list[LaneSection]:
    """Lane predecessor/successor ids between consecutive sections of the road.

    Chosen by geometry: a lane continues into the lane of the next section whose inner
    and outer borders lie where its own end (within ``_LINK_TOLERANCE_M``, offsets from
    the reference line: the median-side edge ``medians`` (section start, end) plus the
    widths), both wider than 0.3 m there; counting lanes or matching border labels fails
    where a lane begins or ends beside the others, on either side. A shoulder whose width
    jumps at a boundary on an edge step (``at_step``: the hard shoulder at a gore, where
    the old one leaves with the ramp and the new one starts narrow) ends there; a lane that
    begins or ends there other than at a gore opens from (closes to) zero width; every
    other lane whose borders met continues with the width it had (sections are fitted
    one by one: an unlinked shoulder whose width differs by centimetres would move every
    lane beyond it sideways at the boundary).
    """
    if medians is None:
        medians = [(0.0, 0.0)] * len(sections)
    if at_step is None:
        at_step = [True] * len(sections)
    preds: list[dict[int, int]] = [{} for _ in sections]
    succs: list[dict[int, int]] = [{} for _ in sections]
    for n in range(1, len(sections)):
        prev_lanes, cur_lanes = _side_lanes(sections[n - 1]), _side_lanes(sections[n])
        prev_len = sections[n].s0 - sections[n - 1].s0
        w_prev = np.array([float(ln.width.value(prev_len)) for ln in prev_lanes])
        w_cur = np.array([float(ln.width.value(0.0)) for ln in cur_lanes])
        b_prev = medians[n - 1][1] + np.concatenate([[0.0], np.cumsum(w_prev)])
        b_cur = medians[n][0] + np.concatenate([[0.0], np.cumsum(w_cur)])
        pairs = []
        for i in range(len(cur_lanes)):
            for j in range(len(prev_lanes)):
                if min(w_cur[i], w_prev[j]) < 0.3:
                    continue
                d = max(abs(b_cur[i] - b_prev[j]), abs(b_cur[i + 1] - b_prev[j + 1]))
                if d <= _LINK_TOLERANCE_M:
                    pairs.append((d, i, j))
        mapping: dict[int, int] = {}
        used: set[int] = set()
        for _, i, j in sorted(pairs):
            if i not in mapping and j not in used:
                mapping[i] = j
                used.add(j)
        # driving lanes before the border wide enough to go on
        open_prev = np.array([ln.type == "driving" for ln in prev_lanes]) & (w_prev >= 0.3)
        # a driving lane whose inner border meets one that ends there and whose width
        # differs by less than _WIDTH_JUMP_M is that lane fitted anew (the outer border
        # is a marking seen again after a gap, a gore's section border): it goes on, with
        # the width it had; left unlinked, a car in it had nowhere to go
        for i in range(len(cur_lanes)):
            if i in mapping or cur_lanes[i].type != "driving" or w_cur[i] < 0.3:
                continue
            meets = (np.abs(b_cur[i] - b_prev[:-1]) <= _LINK_TOLERANCE_M) & (
                np.abs(w_cur[i] - w_prev) <= _WIDTH_JUMP_M
            )
            _link_first_free(i, open_prev & meets, mapping, used)
        # ... or whose outer border does, beside a linked lane inside it that took the
        # difference (their common line fitted anew; town06-auto-s3, noisier sensor) or
        # beside shoulders only (the innermost driving lane, whose inner shoulder took it:
        # town06-auto-lane2-s22 with a noisier sensor, an inner shoulder 0 m wide before
        # the border and 0.97 m after it, and the inner lane led nowhere)
        for i in range(1, len(cur_lanes)):
            inside_taken = i - 1 in mapping or all(ln.type != "driving" for ln in cur_lanes[:i])
            if i in mapping or not inside_taken or cur_lanes[i].type != "driving" or w_cur[i] < 0.3:
                continue
            meets = (np.abs(b_cur[i + 1] - b_prev[1:]) <= _LINK_TOLERANCE_M) & (
                np.abs(w_cur[i] - w_prev) <= _WIDTH_JUMP_M
            )
            _link_first_free(i, open_prev & meets, mapping, used)
        # the same where a narrow lane begins on a driving lane's inner side and the two
        # together span the lane that ends there (the median-side shoulder's line first
        # seen there): the lane goes on, and the narrow one opens from zero width below;
        # left unlinked, the innermost lane led nowhere (melbourne-921-s2)
        for i in range(1, len(cur_lanes)):
            if (
                i in mapping
                or i - 1 in mapping
                or cur_lanes[i].type != "driving"
                or w_cur[i] < 0.3
                or w_cur[i - 1] >= _RESIDUAL_WIDTH_M
            ):
                continue
            meets = (np.abs(b_cur[i - 1] - b_prev[:-1]) <= _LINK_TOLERANCE_M) & (
                np.abs(b_cur[i + 1] - b_prev[1:]) <= _LINK_TOLERANCE_M
            )
            _link_first_free(i, open_prev & meets, mapping, used)
        _link_refitted_outer_lanes(prev_lanes, cur_lanes, b_prev, b_cur, mapping, used)
        for i, j in mapping.items():
            hard_shoulder = (prev_lanes[j].type == "shoulder" and j == len(prev_lanes) - 1) or (
                cur_lanes[i].type == "shoulder" and i == len(cur_lanes) - 1
            )
            if hard_shoulder and at_step[n] and abs(w_prev[j] - w_cur[i]) > 0.05:
                continue
            preds[n][i] = prev_lanes[j].id
            succs[n - 1][j] = cur_lanes[i].id
    out = []
    for n, sec in enumerate(sections):
        lanes = tuple(
            replace(ln, predecessor=preds[n].get(i), successor=succs[n].get(i))
            for i, ln in enumerate(_side_lanes(sec))
        )
        # a lane that begins / ends beside linked ones away from a gore opens from / closes
        # to zero width, so that the lanes beyond it keep their place (a lane born 0.3 m
        # wide moved every lane outside it sideways by 0.3 m at the section border)
        sec_len = (sections[n + 1].s0 if n + 1 < len(sections) else np.inf) - sec.s0
        # the last section: its start (where a lane opening from zero fades in) is checked
        end = sec_len if np.isfinite(sec_len) else _ZERO_FADE_M
        span = np.concatenate(  # densest near the ends, where a closed taper dips
            [
                np.linspace(0.0, end, 400),
                np.linspace(0.0, min(20.0, end), 400),
                np.linspace(max(end - 20.0, 0.0), end, 400),
            ]
        )
        # at a gore too between lanes linked there (a median-side step: a shoulder 34 mm
        # wide began unlinked between linked lanes and moved the outer ones by that,
        # town06-auto-s2 with a noisier sensor); the innermost / outermost lanes at a gore
        # begin and end at full width
        lanes = tuple(
            _nonnegative(_open_from_zero(ln, sec_len), ln, span)
            if n > 0
            and (not at_step[n] or _between_linked(lanes, i, "predecessor"))
            and ln.predecessor is None
            and preds[n]
            and abs(float(ln.width.value(np.array([0.0]))[0])) < _RESIDUAL_WIDTH_M
            else ln
            for i, ln in enumerate(lanes)
        )
        if n + 1 < len(sections) and succs[n]:
            lanes = tuple(
                _nonnegative(_close_to_zero(ln, sec_len), ln, span)
                if (not at_step[n + 1] or _between_linked(lanes, i, "successor"))
                and ln.successor is None
                and abs(float(ln.width.value(np.array([sec_len]))[0])) < _RESIDUAL_WIDTH_M
                else ln
                for i, ln in enumerate(lanes)
            )
        if n > 0:
            # linked lanes continue with the width they had (sections are fitted one by
            # one to 1 cm; the checker flags jumps above 1 mm)
            prev_len = sec.s0 - sections[n - 1].s0
            by_id = {ln.id: ln for ln in _side_lanes(out[n - 1])}
            lanes = tuple(
                continue_width(ln, float(by_id[ln.predecessor].width.value(prev_len)))
                if ln.predecessor in by_id
                else ln
                for ln in lanes
            )
        out.append(replace(sec, right=lanes) if sec.right else replace(sec, left=lanes))
    return out


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
