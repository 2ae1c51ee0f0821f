"""Default method: the lane structure of the mainline from lane-marking samples and
outer-edge points (:func:`fit_lanes`), stage by stage: outer edge (:mod:`.outer_edge`),
marking tracks (:mod:`.markings`) without other roads' lines seen through an occlusion
of the edge (:mod:`.beyond_edge`), hidden gores (:mod:`.hidden_gores`), lanes hidden
beside a broken outermost line (:mod:`.dashed_lanes`), gores moved to the paint
(:mod:`.painted_gores`), edge lines that go on as lane lines (:mod:`.edge_lines`), lane
sections and events (:mod:`.sections`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from ..model import (
    LaneSection,
)
from ._common import (
    BoundaryTrack,
    LaneEvent,
    _grid,
    true_runs,
)
from .beyond_edge import without_other_roads_lines
from .dashed_lanes import dashed_lane_gores, dashed_lanes_in_gaps, widen_beside_dashed
from .edge_levels import EdgeSteps
from .edge_lines import split_edge_lines_at_steps
from .hidden_gores import (
    _gores_at_lane_wide_strips,
    _place_hidden_gores,
    _replace_line_gores,
    _seen_steps,
    _snap_to_hidden_gores,
    _visible_taper_length,
)
from .hidden_lanes import _add_hidden_lanes
from .markings import _merge_collinear, _tracks_from_samples, typical_lane_width
from .outer_edge import _bridge_edge_gaps, _outer_edge_with_levels, fit_outer_edge
from .painted_gores import move_gores_to_paint
from .sections import _sections_from_tracks
from .shoulder_line import continue_median_shoulder_line, continue_shoulder_line
from .unpainted import follow_edge_across_unpainted

FloatArray = NDArray[np.float64]

__all__ = ["fit_lanes", "fit_outer_edge"]


def _car_offset(car: tuple[FloatArray, FloatArray] | None, grid: FloatArray) -> FloatArray | None:
    """The car's offset (metres, same frame) at each grid station, None without it."""
    if car is None or car[0].size < 2:
        return None
    return np.interp(grid, car[0], car[1])


def _edge_bound(d_edge: FloatArray, covered: NDArray[np.bool_]) -> FloatArray:
    """The outer edge as a bound for the lane markings: the edge where it was seen, and in
    an occlusion gap the widest of the edge at the gap's ends and the fit across it.

    The smoother bridging a gap carries a taper's slope on past the last point (a hard
    shoulder narrowing into the gap of a9-10959882-s1 with a noisier sensor: 1.6 m inside
    the outermost line, whose 107 m of samples were cut off as beyond the edge and its lane
    ended); the markings that were seen in a gap decide where the lanes are, and a ramp's
    lines there are the evidence of its gore (:func:`_snap_to_hidden_gores`).
    """
    bound = d_edge.copy()
    for a, b in true_runs(~covered):
        ends = d_edge[[max(a - 1, 0), min(b, d_edge.size - 1)]]
        bound[a:b] = np.maximum(d_edge[a:b], float(np.max(ends)))
    return bound


_BEYOND_BIN_M = 10.0  # lane samples beyond the bound in a gap, binned this long (metres) ...
_BEYOND_MAX_M = 5.0  # ... up to this far beyond it (metres) ...
_BEYOND_STEP_M = 0.5  # ... one line where neighbouring bins' levels differ by at most this ...
_BEYOND_MIN_M = 50.0  # ... over at least this long (metres) ...
_BEYOND_SLOPE = 0.02  # ... running parallel (m/m from its first bins to its last) ...
_BEYOND_LANE_M = (2.5, 4.5)  # ... a lane width out from a line inside it ...
_BEYOND_INSIDE_SHARE = 0.5  # ... seen in this share of its bins


def _with_lane_lines_beyond(
    bound: FloatArray,
    covered: NDArray[np.bool_],
    grid: FloatArray,
    s_lane: FloatArray,
    d_lane: FloatArray,
) -> FloatArray:
    """``bound`` (:func:`_edge_bound`, metres on ``grid``) raised over an occlusion gap of
    the outer edge to a lane line seen beyond it there: lane samples 0.3-5 m beyond the
    bound that run as one line parallel to the road over 50 m or more, a lane width out
    from a line inside the bound. An auxiliary lane opened by a long taper while the edge
    beyond it was unseen (a9-10959882-opp-s7 with a noisier sensor, seed offset 800: its
    outer line seen over 95 m 11.1-11.9 m out, the bound held at 10.9 m, the line cut and
    the lane typed a shoulder); a ramp's line leaves the road, it does not run along it.
    Stations and offsets ``d`` (towards the carriageway) in metres."""
    out = bound.copy()
    for a, b in true_runs(~covered):
        lo, hi = float(grid[a]), float(grid[b - 1])
        if hi - lo < _BEYOND_MIN_M:
            continue
        at = (s_lane >= lo) & (s_lane <= hi)
        s_in, d_in = s_lane[at], d_lane[at]
        over = d_in - np.interp(s_in, grid, bound)
        beyond = (over > 0.3) & (over < _BEYOND_MAX_M)
        if np.count_nonzero(beyond) < 10:
            continue
        edges = np.arange(lo, hi + _BEYOND_BIN_M, _BEYOND_BIN_M)
        d_beyond = d_in[beyond]
        k = np.clip(np.searchsorted(edges, s_in[beyond], side="right") - 1, 0, edges.size - 2)
        n = np.bincount(k, minlength=edges.size - 1)
        level = np.full(edges.size - 1, np.nan)
        for j in np.flatnonzero(n >= 2):
            level[j] = float(np.median(d_beyond[k == j]))
        line = _longest_line(level)
        if line is None:
            continue
        i, j = line
        centres = 0.5 * (edges[:-1] + edges[1:])
        seen = np.flatnonzero(np.isfinite(level[i:j])) + i
        span = float(centres[seen[-1]] - centres[seen[0]])
        if span < _BEYOND_MIN_M:
            continue
        if abs(float(level[seen[-1]] - level[seen[0]])) > _BEYOND_SLOPE * span:
            continue
        # a line a lane width inside it, seen beside it
        k_all = np.searchsorted(edges, s_in, side="right") - 1
        in_seen = np.isin(k_all, seen)
        w = level[k_all[in_seen]] - d_in[in_seen]
        lane_wide = (w >= _BEYOND_LANE_M[0]) & (w <= _BEYOND_LANE_M[1])
        if np.unique(k_all[in_seen][lane_wide]).size < _BEYOND_INSIDE_SHARE * seen.size:
            continue
        g = (grid >= lo) & (grid <= hi)
        out[g] = np.maximum(out[g], np.interp(grid[g], centres[seen], level[seen]))
    return out


def _longest_line(level: FloatArray) -> tuple[int, int] | None:
    """Index range ``[i, j)`` of the longest run of bins whose seen levels (NaN: unseen,
    at most two in a row) step by at most ``_BEYOND_STEP_M`` from one to the next."""
    best: tuple[int, int] | None = None
    start, last, miss = -1, -1, 0
    for m, v in enumerate(level.tolist()):
        if not np.isfinite(v):
            miss += 1
            if start >= 0 and miss > 2:
                if best is None or last + 1 - start > best[1] - best[0]:
                    best = (start, last + 1)
                start = -1
            continue
        if start >= 0 and abs(v - level[last]) <= _BEYOND_STEP_M:
            last, miss = m, 0
            continue
        if start >= 0 and (best is None or last + 1 - start > best[1] - best[0]):
            best = (start, last + 1)
        start, last, miss = m, m, 0
    if start >= 0 and (best is None or last + 1 - start > best[1] - best[0]):
        best = (start, last + 1)
    return best


def fit_lanes(
    s_lane: FloatArray,
    d_lane: FloatArray,
    s_outer: FloatArray,
    d_outer: FloatArray,
    *,
    length: float,
    sign: float,
    config: MainlineConfig | None = None,
    car: tuple[FloatArray, FloatArray] | None = None,
    median: EdgeSteps | None = None,
    median_move: tuple[FloatArray, FloatArray] | None = None,
) -> tuple[tuple[LaneSection, ...], tuple[LaneEvent, ...], tuple[BoundaryTrack, ...], FloatArray]:
    """Lane sections from lane samples and outer-edge points in the reference frame.

    Parameters
    ----------
    s_lane, d_lane
        Stations and offsets from the reference edge towards the carriageway (metres)
        of the lane-marking samples.
    s_outer, d_outer
        The same for the outer road-edge points.
    length
        Road length (metres).
    sign
        +1 right-hand traffic (lanes get negative ids), -1 left-hand traffic.
    car
        Stations (sorted) and offsets (same frame) of the vehicle poses: the lane the car
        drove in is a driving lane (:func:`_lane_types`). None: not used.
    median
        Steps of the median-side edge (gores on the median side) and its offset from the
        reference line per segment (metres towards the median): the innermost border of
        the lanes. None: the median-side edge is the reference line everywhere.
    median_move
        Where the median-side edge is unseen and moves with the lines seen there
        (:mod:`.median_moves`): the move on this function's grid (metres towards the
        carriageway) and the gore stations where it begins or ends at full size
        (metres). None: no such move.

    Returns
    -------
    lane sections, lane events, marking tracks, mask of the outer-edge points used.
    """
    cfg = config or MainlineConfig()
    grid = np.minimum(_grid(0.0, length, cfg.grid_step_m), length)
    d_edge, breaks, used, covered, levels = _outer_edge_with_levels(s_outer, d_outer, grid, cfg)
    # the median-side edge in this frame (d towards the carriageway): 0 where it is the
    # reference line, negative where lanes were added on the median side
    d_median = -median.at(grid) if median is not None else np.zeros(grid.size)
    median_steps = median.stations if median is not None else np.zeros(0)
    if median_move is not None:
        d_median = d_median + median_move[0]
        median_steps = np.sort(np.concatenate([median_steps, median_move[1]]))
    keep = (s_lane >= 0) & (s_lane <= length)
    keep &= d_lane > np.interp(s_lane, grid, d_median) - 0.5
    if np.all(np.isfinite(d_edge)):
        bound = _with_lane_lines_beyond(_edge_bound(d_edge, covered), covered, grid, s_lane, d_lane)
        keep &= d_lane < np.interp(s_lane, grid, bound) + 0.3
    s_l, d_l = s_lane[keep], d_lane[keep]
    # on a segment between median-side gores the median edge lies below the reference
    # line, and so do its lanes' markings (Town06's inner shoulder line, 2.4 m below: never
    # searched for, it was inferred, and a lane drop beside it became a dead end)
    tracks, evidence = _tracks_from_samples(
        s_l,
        d_l,
        grid,
        length,
        cfg,
        d_edge if np.all(np.isfinite(d_edge)) else None,
        covered,
        below_m=max(0.0, -float(np.min(d_median))),
    )
    if not np.all(np.isfinite(d_edge)):
        last = max((float(np.max(tr.d)) for tr in tracks), default=3.0)
        d_edge = np.full(grid.size, last + 2.5)
        breaks = np.zeros(0)
    else:
        tracks = without_other_roads_lines(tracks, grid, d_edge, covered, (s_lane, d_lane))
        tracks, gores = _snap_to_hidden_gores(tracks, evidence, covered, grid, cfg, d_edge)
        taper_length = _visible_taper_length(
            breaks, d_edge, tracks, s_outer[used], d_outer[used], grid
        )
        if taper_length is None:
            # the shoulder still ends at an entry's gore (begins at an exit's): the
            # acceleration lane takes its place (oakland-28393854-opp-s9+80: kept 2.7 m
            # wide up to a gore hidden 85 m into a gap, 2.4 m off over 70 m)
            taper_length = cfg.gore_shoulder_taper_m
        dashed = dashed_lanes_in_gaps(
            tracks,
            grid,
            d_edge,
            covered,
            typical_lane_width(tracks, grid),
            taper_length,
            (np.concatenate([s_outer[~used], s_lane]), np.concatenate([d_outer[~used], d_lane])),
        )
        tracks, placed, tapers = _place_hidden_gores(
            tracks,
            s_outer[used],
            d_outer[used],
            covered,
            grid,
            taper_length,
            _seen_steps(breaks, d_edge, grid),
            gores,
        )
        placed += dashed_lane_gores(dashed, covered, grid, np.asarray([*gores, *placed]))
        placed += _gores_at_lane_wide_strips(
            d_edge,
            covered,
            tracks,
            grid,
            typical_lane_width(tracks, grid),
            np.asarray([*gores, *placed]),
        )
        # a placed gore replaces the ramp-line estimate of the same gore
        tracks, gores = _replace_line_gores(tracks, gores, placed, grid)
        hidden = [*gores, *placed]
        if hidden:
            d_edge, breaks, used, covered = fit_outer_edge(
                s_outer, d_outer, grid, config=cfg, hidden_steps=np.asarray(hidden), levels=levels
            )
        d_edge = _bridge_edge_gaps(
            d_edge,
            covered,
            tracks,
            grid,
            tapers,
            np.asarray(hidden),
            breaks,
            taper_length,
            (s_outer[used], d_outer[used]),
        )
        d_edge = widen_beside_dashed(d_edge, covered, grid, dashed)
        if cfg.painted_gore_max_m > 0.0:
            tracks, d_edge, breaks, painted = move_gores_to_paint(
                tracks, grid, d_edge, breaks, np.sort(s_l), cfg
            )
            for lo, hi in painted:  # the outer-edge points there are the ramp's
                used = used & ~((s_outer > lo) & (s_outer < hi))
        tracks = follow_edge_across_unpainted(tracks, grid, d_edge, covered, breaks)
    tracks = _add_hidden_lanes(tracks, grid, d_edge, d_median, cfg, _car_offset(car, grid))
    # an inferred line may go on where an observed one stopped a few tens of metres before
    # (lines unseen for 27 m before a median-side step: town06-auto-s3 with a noisier
    # sensor had the inner lanes missing there, one shoulder 11.6 m wide); observed tracks
    # still apart were split at a gore on purpose (a9-10959882-s9 +60)
    tracks = _merge_collinear(tracks, cfg, grid, d_edge, with_inferred_only=True)
    if np.all(np.isfinite(d_edge)):
        tracks = continue_shoulder_line(tracks, grid, d_edge, covered, (s_l, d_l), car)
    tracks = continue_median_shoulder_line(tracks, grid, d_median, (s_l, d_l), car)
    tracks, breaks = split_edge_lines_at_steps(tracks, grid, d_edge, breaks, cfg.edge_line_m)
    sections, events, out_tracks = _sections_from_tracks(
        tracks, grid, d_edge, breaks, sign, cfg, car, d_median, median_steps
    )
    return sections, events, out_tracks, used
