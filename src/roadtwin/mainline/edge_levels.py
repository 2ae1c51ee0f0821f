"""The outer road edge as one path through the levels the edge points form.

On the outer side the LiDAR's edge extraction returns more than the mainline's edge:
ramps leaving and joining (their edges run on beside and beyond it), guardrails and
vegetation (outward outliers), other roads seen through a gap. Per station bin the points
form a few levels (dense clusters of lateral offset). The mainline's edge is the
continuous path through them that stays on the innermost supported level, changes level
only at a few steps (gores, where a lane begins or ends at full width), and may go on
unseen through bins where its own edge was hidden (a truck beside the car) rather than
jump to another road's edge and back. That is a shortest path over (bin, level) states,
found by a beam Viterbi pass along the bins with costs for:

* support: ``-log`` of the level's share of the bin's points, relative to the bin's best
  supported level (so two equally supported levels both cost nothing);
* rank: each level inside the chosen one (nearer the carriageway) costs
  ``edge_rank_cost``;
* continuity: a level change between bins costs ``(change / sigma)^2`` (``sigma`` grows
  with the bins since the state was last seen), a change beyond ``edge_step_m`` costs
  ``edge_step_cost`` (a gore step);
* unseen: a state that carries its level through a bin holding points but none at its
  level costs ``edge_skip_cost`` per bin, twice that beyond the first ``_SKIP_CHEAP_BINS``
  such bins since it was last seen (empty bins cost nothing). A vehicle beside the car
  hides the road's edge and what lies beyond alike; the edge unseen under another
  road's for long is more likely not there: an entry's new lane, whose edge seen for
  24 m after the nose was gone around at the shoulder's level (a9-206615404-s1+380).

Offsets ``d`` are metres from the reference edge towards the carriageway (positive).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d, uniform_filter1d

from ..config import MainlineConfig
from .gap_evidence import (
    edge_line_departure,
    edge_line_through,
    lines_held_to,
    ramp_edge_meets,
)

FloatArray = NDArray[np.float64]

_CELL_M = 0.25  # lateral cell of the level histogram
_MAX_LEVELS = 6  # observed levels kept per bin (innermost first)
_MAX_CARRIED = 6  # unseen (carried) states kept per bin
_AFTER_STEP_AGE = 3.0  # a state that just stepped is as uncertain as one unseen for 3 bins
_MIN_LEVEL_POINTS = 3.0  # points (over three bins) that make a level: fewer are noise
_SKIP_CHEAP_BINS = 5  # an edge unseen under another road's for this many bins costs ...
_SKIP_LONG_FACTOR = 2.0  # ... edge_skip_cost each, every bin after that this many times it


def bin_levels(
    s: FloatArray, d: FloatArray, edges_s: FloatArray, *, config: MainlineConfig | None = None
) -> list[tuple[FloatArray, FloatArray]]:
    """Per station bin: the levels of the edge points (metres, innermost first) and their
    emission costs (support and rank); empty arrays for bins without points."""
    cfg = config or MainlineConfig()
    n_bins = edges_s.size - 1
    empty = (np.zeros(0), np.zeros(0))
    if s.size == 0 or n_bins < 1:
        return [empty] * max(n_bins, 0)
    b = np.clip(np.searchsorted(edges_s, s, side="right") - 1, 0, n_bins - 1)
    d_lo = float(np.min(d)) - _CELL_M
    d_hi = float(np.percentile(d, 99.5)) + 1.0
    n_cell = max(3, math.ceil((d_hi - d_lo) / _CELL_M))
    c = np.clip(((d - d_lo) / _CELL_M).astype(np.int64), 0, n_cell - 1)
    hist = np.zeros((n_bins, n_cell), dtype=np.float32)
    np.add.at(hist, (b, c), 1.0)
    count = hist.sum(axis=1)
    dens = gaussian_filter1d(hist, 1.0, axis=1, mode="constant")
    dens = uniform_filter1d(dens, 3, axis=0, mode="nearest")
    left = np.concatenate([np.full((n_bins, 1), -1.0), dens[:, :-1]], axis=1)
    right = np.concatenate([dens[:, 1:], np.full((n_bins, 1), -1.0)], axis=1)
    floor = np.maximum(_MIN_LEVEL_POINTS * 0.4, 0.08 * dens.max(axis=1, keepdims=True))
    peak = (dens >= left) & (dens > right) & (dens >= floor)
    # sub-cell level: centroid of the raw points within +-2 cells of each peak, for all
    # peaks at once (box sums along d); the first _MAX_LEVELS peaks of a bin, innermost first
    mass_all = 5.0 * uniform_filter1d(hist, 5, axis=1, mode="constant")
    first_all = 5.0 * uniform_filter1d(
        hist * np.arange(n_cell, dtype=np.float32), 5, axis=1, mode="constant"
    )
    peak &= (count > 0)[:, None]
    rank_all = np.cumsum(peak, axis=1) - 1
    peak &= rank_all < _MAX_LEVELS
    rows, cols = np.nonzero(peak)
    mass = np.maximum(mass_all[rows, cols].astype(float), 0.5)
    level = d_lo + (first_all[rows, cols] / mass + 0.5) * _CELL_M
    best = np.zeros(n_bins)
    np.maximum.at(best, rows, mass)
    emit = -np.log(mass / best[rows]) + cfg.edge_rank_cost * rank_all[rows, cols]
    split = np.searchsorted(rows, np.arange(1, n_bins))
    return list(zip(np.split(level, split), np.split(emit, split), strict=True))


def edge_level_path(
    s: FloatArray, d: FloatArray, edges_s: FloatArray, *, config: MainlineConfig | None = None
) -> FloatArray:
    """Level (metres) of the mainline's outer edge in each station bin, NaN where unseen.

    Parameters
    ----------
    s, d
        Stations and offsets of the outer-side edge points (metres).
    edges_s
        Bin edges along the station (``n + 1`` values, metres).

    Returns
    -------
    FloatArray
        ``(n,)`` offsets of the chosen level per bin (NaN: no points there, or the path
        went on unseen).
    """
    cfg = config or MainlineConfig()
    bins = bin_levels(s, d, edges_s, config=cfg)
    sigma = level_sigma(bins, cfg)
    return _beam_viterbi(bins, replace(cfg, edge_level_sigma_m=sigma))


def level_sigma(bins: list[tuple[FloatArray, FloatArray]], cfg: MainlineConfig) -> float:
    """Lateral change between neighbouring bins that costs 1 (metres): the configured
    ``edge_level_sigma_m`` widened by the scatter of the levels themselves.

    A level is the centroid of a bin's points; a noisier sensor scatters it from bin to
    bin. Where following the scattered level cost more per bin than ``edge_skip_cost``,
    the path went on unseen beside its own edge instead (soderleden-s9, noisier sensor: a
    new acceleration lane's edge, 0.15 m scatter, left unseen for 40 m). The scatter is
    the robust spread (MAD) of the change of the innermost level between neighbouring
    bins; with sigma twice that the seen path costs about a quarter per bin.
    """
    inner = np.array([lv[0] if lv.size else np.nan for lv, _ in bins])
    change = np.diff(inner)
    change = change[np.isfinite(change) & (np.abs(change) < 0.5 * cfg.edge_step_m)]
    if change.size < 10:
        return cfg.edge_level_sigma_m
    scatter = 1.4826 * float(np.median(np.abs(change - np.median(change))))
    return float(math.hypot(cfg.edge_level_sigma_m, 2.0 * scatter))


def _beam_viterbi(bins: list[tuple[FloatArray, FloatArray]], cfg: MainlineConfig) -> FloatArray:
    """Shortest path over the bins' observed and carried states (module docstring).

    A state also carries its slope (level change per bin, smoothed along the path), so a
    tapering edge (a shoulder opening over 80 m) is predicted, not penalised: the
    continuity cost applies to the change against the predicted level.
    """
    n_bins = len(bins)
    out = np.full(n_bins, np.nan)
    hist_level: list[FloatArray] = []
    hist_seen: list[NDArray[np.bool_]] = []
    hist_back: list[NDArray[np.int64]] = []
    level = np.zeros(0)
    slope = np.zeros(0)
    cost = np.zeros(0)
    age = np.zeros(0)
    skipped = np.zeros(0)  # bins holding points the state went on unseen through
    for i in range(n_bins):
        obs, emit = bins[i]
        has_points = obs.size > 0
        if obs.size and level.size:
            pred = level + slope
            change = np.abs(obs[None, :] - pred[:, None])
            sigma = cfg.edge_level_sigma_m * (1.0 + 0.25 * age[:, None])
            trans = np.where(change > cfg.edge_step_m, cfg.edge_step_cost, (change / sigma) ** 2)
            total = cost[:, None] + trans
            k = np.argmin(total, axis=0)
            o_cost = total[k, np.arange(obs.size)] + emit
            o_back = k.astype(np.int64)
            stepped = np.abs(obs - level[k]) > cfg.edge_step_m
            new_slope = (obs - level[k]) / (age[k] + 1.0)
            o_slope = np.where(stepped, 0.0, 0.5 * slope[k] + 0.5 * new_slope)
            # where a step lands is known to a metre, not to centimetres
            o_age = np.where(stepped, _AFTER_STEP_AGE, 0.0)
            o_skipped = np.zeros(obs.size)
        elif obs.size:
            o_cost = emit + cfg.edge_skip_cost * i
            o_back = np.full(obs.size, -1, dtype=np.int64)
            o_slope = np.zeros(obs.size)
            o_age = np.zeros(obs.size)
            o_skipped = np.zeros(obs.size)
        else:
            o_cost, o_back, o_slope = np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0)
            o_age = np.zeros(0)
            o_skipped = np.zeros(0)
        # carried states: every previous state going on unseen (not onto an observed level)
        c_level = level + slope
        c_slope = 0.9 * slope
        c_skipped = skipped + has_points
        c_cost = cost + has_points * cfg.edge_skip_cost * np.where(
            c_skipped > _SKIP_CHEAP_BINS, _SKIP_LONG_FACTOR, 1.0
        )
        c_age = age + 1
        c_back = np.arange(level.size, dtype=np.int64)
        if obs.size and level.size:
            # a state passing within three of its sigmas of a seen level takes that level
            near = 3.0 * cfg.edge_level_sigma_m * (1.0 + 0.25 * c_age)
            keep = np.min(np.abs(c_level[:, None] - obs[None, :]), axis=1) >= near
            c_level, c_slope, c_cost = c_level[keep], c_slope[keep], c_cost[keep]
            c_age, c_back, c_skipped = c_age[keep], c_back[keep], c_skipped[keep]
        if c_level.size > _MAX_CARRIED:
            best = np.argsort(c_cost, kind="stable")[:_MAX_CARRIED]
            c_level, c_slope, c_cost = c_level[best], c_slope[best], c_cost[best]
            c_age, c_back, c_skipped = c_age[best], c_back[best], c_skipped[best]
        level = np.concatenate([obs, c_level])
        slope = np.concatenate([o_slope, c_slope])
        cost = np.concatenate([o_cost, c_cost])
        age = np.concatenate([o_age, c_age])
        skipped = np.concatenate([o_skipped, c_skipped])
        hist_level.append(level)
        hist_seen.append(np.concatenate([np.ones(obs.size, bool), np.zeros(c_level.size, bool)]))
        hist_back.append(np.concatenate([o_back, c_back]))
    if not level.size:
        return out
    k = int(np.argmin(cost))
    for i in range(n_bins - 1, -1, -1):
        if k < 0 or k >= hist_level[i].size:
            break
        if hist_seen[i][k]:
            out[i] = hist_level[i][k]
        k = int(hist_back[i][k])
    return out


def refine_step(s: FloatArray, d: FloatArray, s_step: float, low: float, *, starts: bool) -> float:
    """Station (metres, sub-metre) where the low level of an edge step starts
    (``starts``: exit gore) or ends (entry gore), from the points within 10 m; ``d`` is
    measured so that the low level lies nearer the carriageway.

    The step lies half a mean point spacing before the first (after the last) point of
    the low level; an isolated first (last) point more than 5 m from the next one is an
    outlier.
    """
    win = (np.abs(s - s_step) < 10.0) & (np.abs(d - low) < 0.5)
    if np.count_nonzero(win) < 4:
        return s_step
    ss = np.sort(s[win])
    if not starts:
        ss = -ss[::-1]  # mirror: the last point of the low level becomes the first
    if ss[1] - ss[0] > 5.0:
        ss = ss[1:]
    spacing = (ss[-1] - ss[0]) / (ss.size - 1)
    edge = float(ss[0] - 0.5 * spacing)
    return edge if starts else -edge


_STEADY_SPREAD_M = 0.25  # a segment whose quarters' offsets agree this well is one level
_STEP_MERGE_M = 5.0  # jumps that refine to stations this close are one step
_HELD_BINS = 3  # a level held for fewer seen bins between two jumps is not a segment


@dataclass(frozen=True)
class EdgeSteps:
    """Steps of an edge level path (gores where lanes begin or end at full width).

    Attributes
    ----------
    stations : ``(n,)`` refined step stations, metres, increasing.
    offsets : ``(n + 1,)`` offset of each segment's edge points from the line they were
        measured from (their median), metres, in the offsets' own direction (positive:
        farther from the carriageway).
    """

    stations: FloatArray
    offsets: FloatArray
    areas: FloatArray = field(default_factory=lambda: np.zeros((0, 3)))
    """``(m, 3)``: per gore area (stations between a ramp's edge leaving the road's level
    and the nose, metres), its start, its end and the level nearer the carriageway there
    (metres, in the offsets' direction): points farther out inside it are the ramp's. A
    step hidden in an occlusion gap has the gap as its area (level ``inf``)."""

    def at(self, s: FloatArray) -> FloatArray:
        """Offset (metres) of the segment each station lies in (a step's own station
        lies in the segment it begins: the lane section starting there)."""
        return self.offsets[np.searchsorted(self.stations, np.asarray(s, dtype=float), "right")]

    def from_base(self, start_m: float, end_m: float) -> EdgeSteps:
        """The same steps with offsets relative to the base level: the level the longest
        stretch of ``[start_m, end_m]`` has (offsets within 0.5 m count as one level)."""
        bounds = np.concatenate([[start_m], self.stations, [end_m]])
        lengths = np.diff(bounds)
        rounded = np.round(self.offsets / 0.5)
        totals = {r: float(lengths[rounded == r].sum()) for r in np.unique(rounded)}
        base_key = max(totals, key=lambda r: (totals[r], -abs(r)))
        base = float(np.median(self.offsets[rounded == base_key]))
        return EdgeSteps(self.stations, self.offsets - base, self.areas)

    def ramp_points(self, s: FloatArray, u: FloatArray) -> NDArray[np.bool_]:
        """Mask of points (stations, offsets, metres) of a ramp's edge inside a gore area
        (:func:`_ramp_points`)."""
        return _ramp_points(self.areas, s, u)


def _ramp_points(areas: FloatArray, s: FloatArray, u: FloatArray) -> NDArray[np.bool_]:
    """Mask of points (stations, offsets, metres) of a ramp's edge inside a gore area
    (rows of :attr:`EdgeSteps.areas`): more than 0.8 m farther out than the level nearer
    the carriageway there."""
    out = np.zeros(np.shape(s), dtype=bool)
    for a, b, low in areas:
        out |= (s > a) & (s < b) & (u > low + 0.8)
    return out


def edge_steps(
    s: FloatArray,
    u: FloatArray,
    edges_s: FloatArray,
    level: FloatArray,
    *,
    config: MainlineConfig | None = None,
    across: Callable[[], tuple[FloatArray, FloatArray] | None] | None = None,
    lines: Callable[[], tuple[FloatArray, FloatArray] | None] | None = None,
) -> EdgeSteps:
    """The steps of a level path (:func:`edge_level_path`) and each segment's offset.

    ``s``, ``u``: the edge points (stations, offsets, metres, larger ``u`` farther from the
    carriageway); ``level`` the path on the bins ``edges_s``. A step is a change of more
    than ``edge_step_m`` between neighbouring seen bins with points right before and after
    it, its station where the level nearer the carriageway starts or ends
    (:func:`refine_step`). Across an occlusion gap (no points right before or after the
    change) the level also moves where the car changed lanes unseen; it is a step only
    where ``across`` (called only then: the other edge's points, stations and offsets away
    from this edge, metres, same frame) says the carriageway's width changed with it
    (:func:`_width_changes`), at the gap's middle (:func:`_step_across_gap`); where
    ``lines`` (called only then: the lane samples, stations and offsets towards this edge,
    metres, same frame) show the edge's own line held at the old level across part of the
    gap and then leaving it outward, the step is there, a ramp's line peeling off
    (:func:`~.gap_evidence.edge_line_departure`).
    Each segment's offset is the median
    ``u`` of its points on the path, 10 m clear of its steps where it has enough of them.
    """
    cfg = config or MainlineConfig()
    centres = 0.5 * (edges_s[1:] + edges_s[:-1])
    seen = np.flatnonzero(np.isfinite(level))
    if seen.size < 2:
        return EdgeSteps(np.zeros(0), np.zeros(1))
    jumps = np.flatnonzero(np.abs(np.diff(level[seen])) > cfg.edge_step_m)
    # [station, level before, level after, gore area or None] per step
    found: list[list] = []
    across_bins: FloatArray | None = None
    line_pts: tuple[FloatArray, FloatArray] | None = None
    for j_first, j in _jump_groups(jumps):
        before = float(np.median(level[seen[max(j_first - 4, 0) : j_first + 1]]))
        after = float(np.median(level[seen[j + 1 : j + 6]]))
        guess = 0.5 * (centres[seen[j_first]] + centres[seen[j_first + 1]])
        station = refine_step(s, u, guess, min(before, after), starts=after < before)
        seen_both_sides = (
            np.count_nonzero((s >= station - 5.0) & (s < station)) >= 3
            and np.count_nonzero((s > station) & (s <= station + 5.0)) >= 3
        )
        area = None
        if seen_both_sides:
            # an exit's step lies where the ramp's edge leaves the road's level; an
            # entry's at its nose, where the new lane begins (an entry's edge coming in
            # after the nose is the new lane's: Town06's inner entries, whose maps begin
            # the lane at the nose, put 17 m after it 3.7 m off)
            start = _gore_area_start(centres, level, station, after) if after < before else None
            if start is not None:
                area = (start, station, after)
                station = start
        else:
            gap = (centres[seen[j_first]], centres[seen[j_first + 1]])
            if across is not None and across_bins is None:
                other = across()
                if other is not None:
                    across_bins = _bin_medians(other[0], other[1], edges_s)
            change = after - before
            station = None
            if _width_changes(gap, change, centres, level, across_bins, cfg):
                # the edge's own line, seen in the gap, says where the gore is; else its
                # size and what was seen at the gap's ends
                if lines is not None and line_pts is None:
                    line_pts = lines()
                held = None
                if line_pts is not None:
                    outer, exit_ = max(before, after), after < before
                    inner = min(before, after)
                    station = edge_line_departure(*line_pts, gap, outer, forward=exit_)
                    # an exit's only: on four entries it changed no measure by more than
                    # 6 mm, but one map had the lane offset step 0.5 m at a section border
                    # 38 m into a road, the inner shoulder widening by as much (borders
                    # continuous), which the ASAM checker reports as horizontal gaps of
                    # the lanes beyond (melbourne-1019-s11+860; not understood further)
                    if (
                        station is None
                        and exit_
                        and abs(change) >= _GAP_STEP_RAMP_MIN_M
                        and edge_line_through(*line_pts, gap, outer, inner, forward=True)
                    ):
                        station = float(gap[1])
                    if station is None:
                        held = lines_held_to(*line_pts, gap, outer, inner, forward=exit_)
                if station is None:
                    # an entry's ramp edge coming in onto the old level just before the
                    # gap, an exit's leaving the new one just after it: the nose is there
                    at = gap[0] if change > 0.0 else gap[1]
                    meets = abs(change) >= _GAP_STEP_RAMP_MIN_M and ramp_edge_meets(
                        s, u, at, min(before, after), -np.sign(change)
                    )
                    station = _step_across_gap(
                        gap, change, centres, level, held=held, ramp_at=at if meets else None
                    )
            if station is None:
                continue
            # sized from either side of the gap (nothing of the step was seen in it)
            area = (float(gap[0]), float(gap[1]), np.inf)
        if found and abs(station - found[-1][0]) < _STEP_MERGE_M:
            # a level held for a bin or two at a step (a stray point, a ramp edge
            # crossing) makes two jumps that refine to one station; counted twice, the
            # step's size doubles and every later segment moves (town06-auto-s7: 3.7 m)
            found[-1][2] = after
            continue
        found.append([station, before, after, area])
    found = sorted((f for f in found if abs(f[2] - f[1]) > cfg.edge_step_m), key=lambda f: f[0])
    if not found:
        return EdgeSteps(np.zeros(0), np.zeros(1))
    st = np.array([f[0] for f in found])
    areas = np.array([f[3] for f in found if f[3] is not None], dtype=float).reshape(-1, 3)
    # per step the stretch its size is measured clear of: its gore area, or its station
    clear = np.array([(f[0], f[0]) if f[3] is None else f[3][:2] for f in found], dtype=float)
    # Offsets sum the step sizes. A step between two segments whose points lie on one
    # level each (``u`` steady: the line it is measured from runs parallel to the edge)
    # is the difference of their medians, 10 m clear of the steps; the level bins next
    # to a step are biased by a converging ramp edge near a merge, and a sum would carry
    # that bias into every later segment (Town06: 1.3 m after an inner entry). Where a
    # segment's ``u`` wanders (the car changed lanes, the edge diverges at a split) its
    # median means nothing, and the step is measured from the points 10-50 m either side.
    path = np.interp(s, centres[seen], level[seen])
    on_level = (np.abs(u - path) < 0.8) & ~_ramp_points(areas, s, u)
    bounds = np.concatenate([[float(edges_s[0])], st, [float(edges_s[-1])]])
    seg = np.searchsorted(st, s)
    median = np.full(st.size + 1, np.nan)
    for k in range(st.size + 1):
        mine = on_level & (seg == k)
        away = mine & (s > bounds[k] + 10.0) & (s < bounds[k + 1] - 10.0)
        pick = away if np.count_nonzero(away) >= 10 else mine
        if np.count_nonzero(pick) >= 40:
            # steady: the medians of its quarters (along s) agree
            s_pick, u_pick = s[pick], u[pick]
            quarter = np.minimum(
                (4.0 * (s_pick - s_pick.min()) / max(np.ptp(s_pick), 1e-9)).astype(int), 3
            )
            q_med = [np.median(u_pick[quarter == q]) for q in range(4) if np.any(quarter == q)]
            if np.ptp(q_med) < _STEADY_SPREAD_M:
                median[k] = float(np.median(u_pick))
    sized = np.array([f[2] - f[1] for f in found])
    for k in range(st.size):
        if np.isfinite(median[k]) and np.isfinite(median[k + 1]):
            sized[k] = median[k + 1] - median[k]
            continue
        # 10 m clear of the step and of its gore area (the new edge next to a nose may
        # still be coming in)
        a0, a1 = clear[k]
        lo = max(bounds[k], a0 - 50.0)
        hi = min(bounds[k + 2], a1 + 50.0)
        before = on_level & (s >= lo) & (s < a0 - 10.0)
        after = on_level & (s > a1 + 10.0) & (s <= hi)
        if np.count_nonzero(before) >= 10 and np.count_nonzero(after) >= 10:
            sized[k] = float(np.median(u[after]) - np.median(u[before]))
    offsets = np.concatenate([[0.0], np.cumsum(sized)])
    # anchored on the line the offsets were measured from: steady segments keep their
    # own median, so the line's own level has offset 0 (a level the line does not follow
    # exactly keeps its remainder); without one, the level of the longest stretch
    steady = np.isfinite(median)
    if steady.any():
        lengths = np.diff(bounds)[steady]
        anchor = _weighted_median(median[steady] - offsets[steady], lengths)
        return EdgeSteps(st, offsets + anchor, areas)
    return EdgeSteps(st, offsets, areas).from_base(float(edges_s[0]), float(edges_s[-1]))


_AREA_MAX_M = 60.0  # a ramp's edge leaves the road's level at most this far from the nose
_AREA_SLOPE_M = 0.04  # it moves out by this much per 2 m bin at least ...
_AREA_RISE_M = 0.5  # ... and this much in all by the nose
_AREA_NEAR_M = 10.0  # seen this near the nose (the last metres of a gore may be unseen)


def _gore_area_start(
    centres: FloatArray, level: FloatArray, nose: float, low: float
) -> float | None:
    """Where a ramp's edge leaves the road's level before an exit's nose (metres): the
    start of the gore area, or None where the level holds up to the nose.

    At an exit the ramp's edge peels off the edge the road had before the gore and the
    level path follows it outward up to the nose, where the new edge nearer the
    carriageway begins. Between the two the lanes that leave already belong to the ramp:
    the road's edge there is the new one (HD maps split the road where the lanes' borders
    part; a map cut at the nose keeps the leaving lanes straight on the road while the
    ramp's pavement bends away, 11 m at CARLA Town06's first inner exit). Walking back
    from the nose, the gore area goes on while the level keeps coming in by
    ``_AREA_SLOPE_M`` per bin or more; ``low`` is the level after the nose, nearer the
    carriageway (metres), whose bins next to the nose are not the ramp's.
    """
    dist = nose - centres  # from the nose back into the higher level's side
    high = np.isfinite(level) & (level > low + 1.0)
    idx = np.flatnonzero((dist > -2.0) & (dist <= _AREA_MAX_M) & high)
    if idx.size < 2:
        return None
    idx = idx[np.argsort(dist[idx])]  # nearest the nose first
    if dist[idx[0]] > _AREA_NEAR_M:
        return None  # the ramp's edge was not seen near the nose
    gaps = np.diff(dist[idx]) > 2.5  # an unseen bin ends the walk
    falls = -np.diff(level[idx]) >= _AREA_SLOPE_M
    walk = falls & ~gaps
    k = int(np.argmin(walk)) if not walk.all() else walk.size
    if k == 0 or float(level[idx[0]] - level[idx[k]]) < _AREA_RISE_M:
        return None
    return nose - (float(dist[idx[k]]) + 1.0)


_GAP_MIN_M = 10.0  # an unseen stretch this long (metres) may hide a step ...
_GAP_REACH_M = 150.0  # ... told by the width where both edges are seen this near it ...
_GAP_WIDTH_BINS = 5  # ... in this many bins either side ...
_GAP_WIDTH_SHARE = 0.5  # ... changing with the level by this share of its change at least
_GAP_TAPER_RATE = 0.06  # a change no faster than a taper (m/m) over the gap is bridged
_GAP_HELD_M = 30.0  # both levels seen over this much next to the gap ...
_GAP_HELD_BINS = 10  # ... in this many bins at least
_GAP_STEP_MIN_M = 7.5  # a smaller change (two lanes and a shoulder) is bridged: the car's
# own lane change while the other edge moved in the same gap (oakland-28393854-opp, an
# outer entry hidden in it), or two lanes fanning out on the median side over the gap
# (melbourne-921-s2 and -408-opp, noisier: a step there put the edge 0.2-0.4 m off);
# a fork of three or more lanes cannot be bridged (oakland-28393854-lane1: 1.5 m off)
_GAP_STEP_HELD_MIN_M = 5.0  # ... where a line between the levels is seen leaving in the
# gap, a change of one and a half lanes or more is a step
_GAP_STEP_RAMP_MIN_M = 2.5  # ... where a ramp's edge meets the edge at the gap, most of a lane


def _bin_medians(s: FloatArray, u: FloatArray, edges_s: FloatArray) -> FloatArray:
    """Median ``u`` per station bin (NaN where a bin has no point)."""
    b = np.searchsorted(edges_s, s, side="right") - 1
    ok = (b >= 0) & (b < edges_s.size - 1)
    b, v = b[ok], u[ok]
    order = np.lexsort((v, b))
    b, v = b[order], v[order]
    first = np.searchsorted(b, np.arange(edges_s.size - 1), side="left")
    last = np.searchsorted(b, np.arange(edges_s.size - 1), side="right")
    out = np.full(edges_s.size - 1, np.nan)
    has = last > first
    out[has] = v[(first[has] + last[has] - 1) // 2]
    return out


def _step_across_gap(
    gap: tuple[float, float],
    level_change: float,
    centres: FloatArray,
    level: FloatArray,
    *,
    held: tuple[float, bool] | None = None,
    ramp_at: float | None = None,
) -> float | None:
    """Station (metres) of a step whose level change (``level_change``, metres, between
    the levels either side) falls in the unseen stretch ``gap`` (the centres of the seen
    bins either side) where the carriageway's width changed with it
    (:func:`_width_changes`), or None where it is bridged as a taper.

    The step lies at the end of the gap where a ramp's edge was seen peeling off the
    higher level; else where a line between the levels seen into the gap left outward
    (``held``, :func:`~.gap_evidence.lines_held_to`: a ramp's line leaving, or joining
    for an entry), or at the middle of what is left of the gap beyond where such lines
    were seen going on (after it for an exit, before it for an entry: the lanes were
    there, oakland-28393854-s7 with a noisier sensor put a 3-lane inner exit's step 35 m
    before its nose), or of the whole gap (nothing seen tells where in it the gore is).
    A change under ``_GAP_STEP_MIN_M`` is a step only where such a line was seen leaving
    in the gap and it is ``_GAP_STEP_HELD_MIN_M`` at least (a 2-lane inner exit whose
    line left in the gap, melbourne-921-s2+260 with a noisier sensor: bridged, the edge
    was 4 m off; lines seen running on alone are no such evidence: two lanes fanning out
    beside the median, melbourne-921-s2+20, were taken for a step, a lane 6.8 m wide).
    At ``ramp_at`` (an end of the gap where a ramp's edge was seen meeting the lower
    level, :func:`~.gap_evidence.ramp_edge_meets`) a change of ``_GAP_STEP_RAMP_MIN_M``
    or more is a step there: the ramp's nose (town06-auto-s1 with a noisier sensor, a
    1-lane inner entry bridged as a taper over the 86 m gap after it: the edge 3.9 m
    off).
    """
    lo, hi = gap
    if ramp_at is not None and abs(level_change) >= _GAP_STEP_RAMP_MIN_M:
        return ramp_at
    departed = held is not None and held[1]
    small = abs(level_change) < (_GAP_STEP_HELD_MIN_M if departed else _GAP_STEP_MIN_M)
    if small or abs(level_change) <= _GAP_TAPER_RATE * (hi - lo):
        # bridged, the edge closes (opens) no faster than a lane's taper: a lane ending
        # unseen is mapped as one that tapers over the gap, and the lane structure
        # around stays as seen
        return None
    # a ramp's edge seen peeling off the higher level right at the gap (before it for an
    # exit, after it for an entry) puts the gore at that end of the gap
    if level_change < 0.0 and _peels_off(centres, level, lo, -1.0):
        return lo
    if level_change > 0.0 and _peels_off(centres, level, hi, 1.0):
        return hi
    if held is not None:
        at = min(max(held[0], lo), hi)
        if held[1]:
            return at
        lo, hi = (at, hi) if level_change < 0.0 else (lo, at)
    return 0.5 * (lo + hi)


def _width_changes(
    gap: tuple[float, float],
    level_change: float,
    centres: FloatArray,
    level: FloatArray,
    across: FloatArray | None,
    cfg: MainlineConfig,
) -> bool:
    """Whether the carriageway's width (this edge's level plus ``across``, the other
    edge's median offset per bin) changes across the unseen stretch ``gap`` with this
    edge's level (``level_change``, metres): a step, not the car's own lane change (which
    moves both edges by the same amount in opposite directions): by ``edge_step_m`` or
    ``_GAP_WIDTH_SHARE`` of the level's change, whichever is less. The width is taken where
    both edges were seen nearest the gap on each side, both levels held next to it."""
    lo, hi = gap
    if across is None or hi - lo < _GAP_MIN_M:
        return False
    seen = np.isfinite(level)
    held_before = seen & (centres <= lo) & (centres > lo - _GAP_HELD_M)
    held_after = seen & (centres >= hi) & (centres < hi + _GAP_HELD_M)
    if min(np.count_nonzero(held_before), np.count_nonzero(held_after)) < _GAP_HELD_BINS:
        return False  # a level seen only briefly next to the gap may be a bend's
    width = level + across
    ok = np.isfinite(width)
    before = np.flatnonzero(ok & (centres <= lo) & (centres > lo - _GAP_REACH_M))[-_GAP_WIDTH_BINS:]
    after = np.flatnonzero(ok & (centres >= hi) & (centres < hi + _GAP_REACH_M))[:_GAP_WIDTH_BINS]
    if before.size < _GAP_WIDTH_BINS or after.size < _GAP_WIDTH_BINS:
        return False
    width_change = float(np.median(width[after]) - np.median(width[before]))
    # most of the level's change, not all of it: the other edge may have its own gore
    # next to the gap (melbourne-1019-lane1-s21 with a noisier sensor: an outer exit's
    # nose at the far end of a 96 m gap hiding an inner exit's step of 3.4 m, the width
    # changed by 1.9 m; judged against a lane's step the inner one was bridged as a lane
    # change over the gap, the edge 3 m off and a car driven onto the shoulder)
    needed = min(cfg.edge_step_m, _GAP_WIDTH_SHARE * abs(level_change))
    return abs(width_change) > needed and width_change * level_change > 0.0


_PEEL_NEAR_M = 10.0  # the level this near a gap's end ...
_PEEL_BASE_M = (12.0, 40.0)  # ... against its median this far from it ...
_PEEL_OUT_M = 0.5  # ... lies this much farther out: a ramp's edge leaving it


def _peels_off(centres: FloatArray, level: FloatArray, end: float, direction: float) -> bool:
    """Whether the level path, going from the gap's ``end`` away from the gap
    (``direction`` -1: backwards from its start, +1: onwards from its end), starts
    more than ``_PEEL_OUT_M`` outward of the steady level beyond: the edge of a ramp that
    leaves (joins) there."""
    dist = direction * (centres - end)
    near = np.isfinite(level) & (dist >= 0.0) & (dist <= _PEEL_NEAR_M)
    base = np.isfinite(level) & (dist >= _PEEL_BASE_M[0]) & (dist <= _PEEL_BASE_M[1])
    if not near.any() or np.count_nonzero(base) < 5:
        return False
    return float(np.max(level[near]) - np.median(level[base])) > _PEEL_OUT_M


def _jump_groups(jumps: NDArray[np.int64]) -> list[tuple[int, int]]:
    """Jumps of a level path (indices into its seen bins) grouped into steps: ``(first,
    last)`` jump of each group. A level held for fewer than ``_HELD_BINS`` seen bins
    between two jumps is a stray cluster (outliers, a ramp edge crossing), not a segment:
    the jumps either side are one step, from the level before the first to the level
    after the last (a spike beyond the new level refined its two jumps 5.8 m apart and
    the step counted twice: melbourne-408-opp-s4 with a noisier sensor, a 15.8 m offset)."""
    groups: list[tuple[int, int]] = []
    for j in jumps.tolist():
        if groups and j - groups[-1][1] < _HELD_BINS:
            groups[-1] = (groups[-1][0], j)
        else:
            groups.append((j, j))
    return groups


def _weighted_median(values: FloatArray, weights: FloatArray) -> float:
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return float(values[order][np.searchsorted(cum, 0.5 * cum[-1])])
