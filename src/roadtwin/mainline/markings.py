"""Lane-marking tracks: histogram peaks along the station linked into tracks
(:mod:`.linking`, pieces joined by :mod:`.raw_joins`), samples assigned to their nearest
track, ramp lines cut off at the corridor and collinear pieces merged (lanes hidden
beyond the sensor's reach: :mod:`.hidden_lanes`).

Stations ``s`` and offsets ``d`` are metres in the reference line's frame (``d`` from the
reference edge towards the carriageway).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from ._common import (
    robust_offset_fit,
    true_runs,
)
from .linking import _find_track_peaks, _link_tracks, _RawTrack
from .raw_joins import _into_merging_peaks, _join_late_pieces, _join_taper_pieces, _join_tapers
from .shift import MIN_TOTAL_M, OuterEdge, ShiftFrame, common_shift

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


def _mark_type(s_samples: FloatArray, lo: float, hi: float, cfg: MainlineConfig) -> str:
    """``broken`` if long gaps between samples cover a large part of [lo, hi]."""
    ss = np.sort(s_samples[(s_samples >= lo) & (s_samples <= hi)])
    if ss.size < 3 or hi - lo <= 0:
        return "solid"
    gaps = np.diff(np.concatenate([[lo], ss, [hi]]))
    limit = _long_gap_m(ss, cfg)
    frac = float(np.sum(gaps[gaps > limit])) / (hi - lo)
    return "broken" if frac > cfg.broken_gap_fraction else "solid"


def _long_gap_m(ss: FloatArray, cfg: MainlineConfig) -> float:
    """A gap between sorted sample stations ``ss`` longer than this (metres) is a gap in
    the paint, not in the sampling: ``broken_gap_m`` or three sample spacings."""
    spacing = float(np.median(np.diff(ss))) if ss.size > 1 else 0.0
    return max(cfg.broken_gap_m, 3.0 * spacing)


def _dashed(s_samples: FloatArray, lo: float, hi: float, cfg: MainlineConfig) -> bool:
    """True if the samples in [lo, hi] (stations, metres) show a dash pattern: at least
    three gaps longer than ``broken_gap_m`` covering more than ``broken_gap_fraction`` of
    the interval, of regular length (their spread under half their median) and separated
    by dashes no longer than 15 m. A solid line hidden by a truck or worn for a stretch
    leaves one or two gaps of any length, not a pattern."""
    ss = np.sort(s_samples[(s_samples >= lo) & (s_samples <= hi)])
    if ss.size < 4 or hi - lo <= 0:
        return False
    gaps = np.diff(ss)
    long_gap = gaps > _long_gap_m(ss, cfg)
    n_long = int(np.count_nonzero(long_gap))
    if n_long < 3 or float(np.sum(gaps[long_gap])) <= cfg.broken_gap_fraction * (hi - lo):
        return False
    lengths = gaps[long_gap]
    spread = float(np.subtract(*np.percentile(lengths, [75, 25])))
    i_long = np.nonzero(long_gap)[0]
    dashes = ss[i_long[1:]] - ss[i_long[:-1] + 1]
    return spread < 0.5 * float(np.median(lengths)) and float(np.median(dashes)) <= 15.0


@dataclass
class _Track:
    id: int
    lo: float
    hi: float
    s: FloatArray  # stations of d (grid or column centres)
    d: FloatArray
    mark: str
    n: int
    s_samples: FloatArray  # stations of the inlier samples, sorted
    d_samples: FloatArray = field(default_factory=lambda: np.zeros(0))  # their offsets


def track_part(tr: _Track, a: int, b: int) -> _Track:
    """Track ``tr`` over its stations ``tr.s[a:b]``, with the samples that lie there."""
    lo, hi = float(tr.s[a]), float(tr.s[b - 1])
    keep = (tr.s_samples >= lo) & (tr.s_samples <= hi)
    same = tr.d_samples.size == tr.s_samples.size
    return replace(
        tr,
        lo=lo,
        hi=hi,
        s=tr.s[a:b],
        d=tr.d[a:b],
        n=int(np.count_nonzero(keep)),
        s_samples=tr.s_samples[keep],
        d_samples=tr.d_samples[keep] if same else tr.d_samples,
    )


def _tracks_from_samples(
    s: FloatArray,
    d: FloatArray,
    grid: FloatArray,
    length: float,
    cfg: MainlineConfig,
    d_edge: FloatArray | None = None,
    covered: NDArray[np.bool_] | None = None,
    below_m: float = 0.0,
) -> tuple[list[_Track], list[tuple[float, float]]]:
    """Marking tracks: histogram peaks linked along s, false positives removed, samples
    assigned exclusively to the nearest track, each track smoothed robustly; where the
    marking pattern shifts sideways as a whole (:mod:`.shift`), found in the frame that
    moves with it and returned in the reference line's.

    ``below_m`` (metres, >= 0): how far the median-side edge lies below the reference
    line somewhere (on a segment between median-side gores the lanes begin beyond it); the
    markings there are searched for too.

    Also returns ``(s, d, leaves)`` where ramp lines crossing the corridor were cut off
    (they meet, or leave (``leaves``), a mainline marking there: gore evidence)."""
    if s.size < 10:
        return [], []
    centres, peaks = _find_track_peaks(s, d, length, cfg, below_m)
    # the outer edge where it was seen (bridged across a gap it is no evidence: of where
    # the lines beside it go, of a lane it closes)
    if d_edge is not None and covered is not None:
        seen_edge = np.where(covered, d_edge, np.nan)
    else:
        seen_edge = None
    witness = None
    if d_edge is not None:
        witness = OuterEdge(grid, d_edge if seen_edge is None else seen_edge)
    # the pattern's shift from the lines linked without the edge (lines that follow the
    # edge as it moves with the whole pattern would hide the shift: melbourne-921-s9+20)
    raw = _link_tracks(peaks, cfg)
    frame = _shift_frame(s, d, length, centres, raw, cfg, witness)
    if frame is None:
        if seen_edge is not None:
            raw = _link_tracks(peaks, cfg, edge=_at_columns(seen_edge, grid, centres))
        tracks, evidence = _tracks_in_frame(
            s, d, grid, length, cfg, d_edge, centres, raw, edge_seen=covered
        )
    else:
        edge = None if d_edge is None else _edge_in_frame(d_edge, covered, grid, frame)
        d_frame = d - frame.offset(s)
        centres, peaks = _find_track_peaks(s, d_frame, length, cfg, frame.deepest_m + below_m)
        raw = _link_tracks(
            peaks,
            cfg,
            frame.offset(centres),
            _at_columns(
                None if seen_edge is None else seen_edge - frame.offset(grid), grid, centres
            ),
        )
        tracks, evidence = _tracks_in_frame(
            s, d_frame, grid, length, cfg, edge, centres, raw, frame, edge_seen=covered
        )
        tracks = [_out_of_frame(tr, grid, frame) for tr in tracks]
        moved = frame.offset(np.array([g for g, _, _ in evidence], dtype=float))
        evidence = [
            (g, v + float(m), leaves) for (g, v, leaves), m in zip(evidence, moved, strict=True)
        ]
    return _continue_to_convergence(tracks, grid, cfg, seen_edge), evidence


def _edge_in_frame(
    d_edge: FloatArray,
    covered: NDArray[np.bool_] | None,
    grid: FloatArray,
    frame: ShiftFrame,
) -> FloatArray:
    """The outer edge ``d_edge`` (metres, on ``grid``) in the shift ``frame``, linear in
    the frame across every gap (``covered`` False) in which the frame moves by
    :data:`.shift.MIN_TOTAL_M` (half a lane: a shift, not the refinement of one) or more:
    the edge moves with the whole marking pattern, so unseen it keeps its place in the
    pattern. Bridged in the reference line's frame, it cut through the lanes wherever the
    pattern swung out and back inside a gap (town06-auto-lane2-s22 with a noisier sensor:
    the outer edge unseen over 150 m across a 3.5 m swing, the outermost lane left out
    over 80 m); bridged in a frame that moved 0.6 m, the lines beside a 100 m gap of
    town06-auto-s3 (noisier) bulged by up to 1.5 m."""
    offset = frame.offset(grid)
    edge = d_edge - offset
    if covered is None:
        return edge
    for a, b in true_runs(~covered):
        if a == 0 or b >= grid.size:
            continue
        inside = offset[a - 1 : b + 1]
        if float(np.max(inside) - np.min(inside)) < MIN_TOTAL_M:
            continue
        x = (grid[a:b] - grid[a - 1]) / (grid[b] - grid[a - 1])
        edge[a:b] = (1.0 - x) * edge[a - 1] + x * edge[b]
    return edge


def _at_columns(
    values: FloatArray | None, grid: FloatArray, centres: FloatArray
) -> FloatArray | None:
    """``values`` on ``grid`` (metres, NaN where unknown) at the column ``centres``
    (metres): each the value of the first grid station at or after the centre."""
    if values is None:
        return None
    return values[np.clip(np.searchsorted(grid, centres), 0, grid.size - 1)]


def _out_of_frame(track: _Track, grid: FloatArray, frame: ShiftFrame) -> _Track:
    """``track`` (offsets in the frame moving with the marking pattern) in the reference
    line's frame, on every ``grid`` station of its extent: where it was not seen (two
    tracks joined across an occlusion) it keeps its offset in the moving frame, so it
    moves with the pattern there. Only its own stations shifted, the gap was bridged
    straight in the reference frame (melbourne-1226-s11 with a noisier sensor: a line
    unseen over 290-390 m while the pattern shifted 3.6 m cut across its lane, 1.1 m off)."""
    # joined tracks may overlap by a metre: their stations sorted, each once
    s_own, first = np.unique(track.s, return_index=True)
    s = np.union1d(grid[(grid >= s_own[0]) & (grid <= s_own[-1])], s_own)
    d = np.interp(s, s_own, track.d[first])
    return replace(
        track,
        s=s,
        d=d + frame.offset(s),
        d_samples=track.d_samples + frame.offset(track.s_samples),
    )


def _shift_frame(
    s: FloatArray,
    d: FloatArray,
    length: float,
    centres: FloatArray,
    raw: list[_RawTrack],
    cfg: MainlineConfig,
    edge: OuterEdge | None = None,
) -> ShiftFrame | None:
    """The marking pattern's sideways shift (:func:`.shift.common_shift`) from the linked
    column peaks ``raw`` (tracks of two columns or more), with the outer edge ``edge`` as
    a witness where it was seen."""
    raw = [tr for tr in raw if len(tr.cols) >= 2]
    if not raw:
        return None
    return common_shift(
        s,
        d,
        length,
        np.concatenate([centres[tr.cols] for tr in raw]),
        np.concatenate([np.asarray(tr.d) for tr in raw]),
        np.repeat(np.arange(len(raw)), [len(tr.cols) for tr in raw]),
        cfg.lane_column_m,
        edge,
    )


def _tracks_in_frame(
    s: FloatArray,
    d: FloatArray,
    grid: FloatArray,
    length: float,
    cfg: MainlineConfig,
    d_edge: FloatArray | None,
    centres: FloatArray,
    raw: list[_RawTrack],
    frame: ShiftFrame | None = None,
    *,
    edge_seen: NDArray[np.bool_] | None = None,
) -> tuple[list[_Track], list[tuple[float, float]]]:
    """:func:`_tracks_from_samples` in one frame: ``d`` and ``d_edge`` are offsets in it,
    ``raw`` the column peaks at ``centres`` linked into tracks, ``frame`` the shift the
    frame moves with (None: the reference line's own frame), ``edge_seen`` where on
    ``grid`` the edge was seen (None: everywhere). Tracks are returned merged but not yet
    continued to convergence."""
    col = cfg.lane_column_m
    s_first, s_last = float(np.min(s)), float(np.max(s))

    def too_short(lo: float, hi: float, gap: float = 0.0) -> bool:
        """Shorter than ``lane_min_track_m``, unless the run's start or end cuts it (then
        it only has to be ``lane_min_cut_track_m`` long): it lies within two columns of
        it, or within ``gap`` (metres; the longest the line went unseen between its
        samples, at most ``lane_min_cut_track_m``)."""
        if hi - lo >= cfg.lane_min_track_m:
            return False
        reach = max(2.0 * col, min(gap, cfg.lane_min_cut_track_m))
        cut = lo <= s_first + reach or hi >= s_last - reach
        return not (cut and hi - lo >= cfg.lane_min_cut_track_m)

    cand: list[_Track] = []
    evidence: list[tuple[float, float, bool]] = []
    # every column peak once (column, offset, track), for the short ramp lines below
    raw = _join_taper_pieces(_join_late_pieces(_join_tapers(raw, cfg), cfg), cfg)
    peak_col = np.concatenate([np.asarray(tr.cols, dtype=np.int64) for tr in raw])
    peak_d = np.concatenate([np.asarray(tr.d, dtype=float) for tr in raw])
    peak_tr = np.repeat(np.arange(len(raw)), [len(tr.cols) for tr in raw])
    raw = _into_merging_peaks(raw, cfg, (peak_col, peak_d, peak_tr))
    for i_raw, tr in enumerate(raw):
        lo = centres[tr.cols[0]] - 0.5 * col
        hi = centres[tr.cols[-1]] + 0.5 * col
        if too_short(lo, hi):
            peaks = (peak_col, peak_d, peak_tr != i_raw)
            meeting = _short_ramp_line_meeting(tr, peaks, centres, cfg)
            if meeting is not None:
                evidence.append(meeting)
            continue
        cand.append(
            _Track(len(cand), lo, hi, centres[tr.cols], np.asarray(tr.d), "solid", 0, s[:0])
        )
    if not cand:
        return [], evidence
    # each sample belongs to the nearest candidate track (the first one on ties); the
    # samples are sorted by station so that a track only looks at its own window
    order = np.argsort(s, kind="stable")
    s, d = s[order], d[order]
    best = np.full(s.size, np.inf)
    owner = np.full(s.size, -1, dtype=np.int64)
    windows: list[tuple[int, int]] = []
    for k, tr in enumerate(cand):
        i0 = int(np.searchsorted(s, tr.lo - col, side="left"))
        i1 = int(np.searchsorted(s, tr.hi + col, side="right"))
        windows.append((i0, i1))
        dk = np.abs(d[i0:i1] - np.interp(s[i0:i1], tr.s, tr.d))
        better = dk < best[i0:i1]
        best[i0:i1][better] = dk[better]
        owner[i0:i1][better] = k
    final: list[_Track] = []
    for k, (i0, i1) in enumerate(windows):
        sel = i0 + np.flatnonzero((owner[i0:i1] == k) & (best[i0:i1] < cfg.lane_assign_m))
        if sel.size < 10:
            continue
        ss_all = s[sel]
        lo, hi = float(np.min(ss_all)), float(np.max(ss_all))
        # a broken line's next dash may lie past the run's end: its own gaps tell how far
        # (oakland-28393854-lane2-s22 with a noisier sensor: a lane gain's line seen for
        # 42 m up to 10.1 m before the end, with longer gaps between its dashes, was
        # dropped and the new lane made one 6.4 m wide with the next)
        unseen = float(np.max(np.diff(ss_all)))
        if too_short(lo, hi, unseen):
            continue
        g = grid[(grid >= lo) & (grid <= hi)]
        if g.size < 4:
            continue
        fit, inl, _ = robust_offset_fit(
            ss_all,
            d[sel],
            g,
            cutoff_m=cfg.lane_smoothing_m,
            mad_k=cfg.edge_outlier_mad,
            min_threshold_m=cfg.edge_outlier_min_m,
            local_sigma_ends_m=2.0 * cfg.lane_smoothing_m,
        )
        keep_g = _trim_ramp_lines(g, fit, cfg, None if frame is None else frame.rate(g))
        if d_edge is not None:
            # the line inward matters only for a cut end (a nose's taper line)
            inner = None if keep_g.all() else _next_line_inward(cand, k, g, fit)
            meets = not keep_g[-1] and _ends_on_converging_line(
                cand, k, float(g[-1]), float(fit[-1])
            )
            # the run's end cuts a broken line within its own dash gaps there
            tail = ss_all[ss_all >= hi - _END_GAPS_OVER_M]
            tail_gap = float(np.max(np.diff(tail))) if tail.size > 1 else 0.0
            keep_g |= _mainline_ends_inside_edge(
                g,
                fit,
                keep_g,
                grid,
                d_edge,
                s_last,
                max(2.0 * col, min(tail_gap, cfg.lane_min_cut_track_m)),
                inner_d=inner,
                meets_line=meets,
                settle_slope=cfg.ramp_line_slope,
                edge_seen=edge_seen,
            )
        if not keep_g[-1] or not keep_g[0]:
            # a ramp line: where it meets / leaves the corridor's marking is a gore
            if keep_g.any():
                i_in = np.flatnonzero(keep_g)
                leaves = bool(keep_g[0])
                i_g = i_in[-1] + 1 if leaves else i_in[0] - 1
            else:
                leaves = bool(fit[-1] >= fit[0])
                i_g = _ramp_line_meeting(g, fit, [c for j, c in enumerate(cand) if j != k])
            evidence.append((float(g[i_g]), float(fit[i_g]), leaves))
        if not keep_g.any():
            continue
        g_in = g[keep_g]
        if too_short(float(g_in[0]), float(g_in[-1]) + cfg.grid_step_m, unseen):
            continue
        g, fit = g[keep_g], fit[keep_g]
        lo, hi = float(g[0]), float(g[-1])
        ss, dd = ss_all[inl], d[sel][inl]
        within = (ss >= lo - 1.0) & (ss <= hi + 1.0)
        ss, dd = ss[within], dd[within]  # sorted by station already
        mark = _mark_type(ss, lo, hi, cfg)
        final.append(_Track(len(final), lo, hi, g, fit, mark, int(ss.size), ss, dd))
    return _merge_collinear(final, cfg, grid, d_edge), evidence


_SHORT_RAMP_LINE_M = 20.0  # a line too short for a track still shows a gore if this long ...
_SHORT_RAMP_MOVE_M = 1.5  # ... and crossing this far sideways (metres) ...
_SHORT_RAMP_STEADY = 0.8  # ... moving one way on this share of its column steps
_SHORT_RAMP_REACH_M = 20.0  # its slope carries it on at most this far onto a line (metres)


def _short_ramp_line_meeting(
    tr: _RawTrack,
    peaks: tuple[NDArray[np.int64], FloatArray, NDArray[np.bool_]],
    centres: FloatArray,
    cfg: MainlineConfig,
) -> tuple[float, float, bool] | None:
    """Where a line too short to be a marking track meets (converging inward) or leaves
    (diverging outward) the corridor's markings, if it crosses the corridor steadily over
    ``_SHORT_RAMP_LINE_M`` or more: a ramp line, the evidence of a gore. Its peaks merge
    with the line it joins for the last metre or so; the meeting is where its slope
    carries it onto the nearest other line (``peaks``: every track's column indices and
    offsets, and the mask of the other tracks' ones, applied only when the line qualifies;
    columns centred at ``centres``) within ``_SHORT_RAMP_REACH_M``, else its last (first)
    column; and whether it leaves them. A ramp line converging through an occlusion gap of
    the outer edge is cut by the edge's bound there and may be left too short for a track
    (soderleden-s2, noisier sensor: then nothing placed the gore, and the acceleration lane
    began where the line beside it did, 54 m early)."""
    s_cols, d_cols = centres[tr.cols], np.asarray(tr.d)
    if s_cols.size < 4 or s_cols[-1] - s_cols[0] < _SHORT_RAMP_LINE_M:
        return None
    rate = np.diff(d_cols) / np.diff(s_cols)
    if d_cols[0] - d_cols[-1] >= _SHORT_RAMP_MOVE_M:
        if np.mean(rate < -cfg.ramp_line_slope) < _SHORT_RAMP_STEADY:
            return None
        end, col, toward = -1, tr.cols[-1], 1
    elif d_cols[-1] - d_cols[0] >= _SHORT_RAMP_MOVE_M:
        if np.mean(rate > cfg.ramp_line_slope) < _SHORT_RAMP_STEADY:
            return None
        end, col, toward = 0, tr.cols[0], -1
    else:
        return None
    s_end, d_end = float(s_cols[end]), float(d_cols[end])
    slope = abs(float(np.median(rate[-3:] if end == -1 else rate[:3])))
    # the other lines inward of its end, in the columns it would cross next
    reach = round(_SHORT_RAMP_REACH_M / float(centres[1] - centres[0])) if centres.size > 1 else 0
    cols, offsets, other = peaks
    cols, offsets = cols[other], offsets[other]
    ahead = (cols - col) * toward
    inward = offsets[
        (ahead >= 0)
        & (ahead <= reach)
        & (offsets >= d_end - _SHORT_RAMP_REACH_M * slope)
        & (offsets < d_end)
    ]
    leaves = toward < 0
    if inward.size == 0:
        return s_end, d_end, leaves
    d_meet = float(np.max(inward))
    return s_end + toward * (d_end - d_meet) / max(slope, 1e-6), d_meet, leaves


_MEET_M = 0.3  # a neighbouring line this close to an ended line's offset has met it (metres)
_TAPER_TAIL_M = 0.8  # a neighbour at least this far from a line that ended may close onto it
# (closer, the two are a double line or a shoulder split: the tracker separates lines from 0.8 m)
_SETTLE_RUN_M = 50.0  # a neighbour whose gap shrinks by less than _SETTLE_DROP_M over this
_SETTLE_DROP_M = 0.1  # ... (metres) has settled
_EDGE_TAPER_MAX_M = 60.0  # the outer edge closes a lane over at most this (metres)
# another line this close to a continued line's offset along the continuation takes its
# place, or is converging onto it from the far side: the lanes shift sideways there and
# the continuation would cut the lane beyond into a sliver (town06-auto-s2: 0.51 m)
_OCCUPIED_M = 1.0
_MEET_LANE_SHARE = 0.25  # ... or settles this share of a lane beside it


def _ramp_line_meeting(g: FloatArray, fit: FloatArray, others: list[_Track]) -> int:
    """Index (on ``g``) where a ramp line that crosses the corridor all along meets the
    marking it joins (converging: the first station within ``_MEET_M`` of another track)
    or leaves it (diverging: the last such station); its far end if it meets none. Its
    trend may carry it past the line it met, across an occlusion gap, onto the next one
    (soderleden-s2, noisier sensor: the entry's line "met" the through line 60 m late and
    3.5 m inward, and the acceleration lane began 65 m early)."""
    converging = fit[-1] < fit[0]
    near = np.zeros(g.size, dtype=bool)
    for tr in others:
        on = (g >= tr.lo) & (g <= tr.hi)
        near[on] |= np.abs(fit[on] - np.interp(g[on], tr.s, tr.d)) < _MEET_M
    hits = np.flatnonzero(near)
    if hits.size == 0:
        return g.size - 1 if converging else 0
    return int(hits[0]) if converging else int(hits[-1])


_MOVING_SLOPE = 0.015  # a line whose end moves sideways this fast (m/m) ...
_MOVING_OVER_M = 10.0  # ... over its last (first) this many metres is a taper's line ...
_CARRY_MAX_M = 60.0  # ... carried on along that slope at most this far (metres)
_OUTSIDE_EDGE_M = 0.3  # a carried line lies no farther than this beyond the seen edge


def _along_its_slope(
    tr: _Track,
    tracks: list[_Track],
    k: int,
    grid: FloatArray,
    *,
    forward: bool,
    lane_m: float,
    d_edge: FloatArray | None = None,
) -> _Track | None:
    """Track ``k`` (``tr``) carried on along its slope to the line it meets, where it was
    seen moving sideways at a taper's rate where it ends (``forward``) or begins; None if
    it was not, or no line within a lane (``lane_m``, metres) of its end runs where its
    slope carries it within ``_CARRY_MAX_M``, or the carried part would lie beyond the
    outer edge ``d_edge`` (on ``grid``, NaN where it was not seen).

    A lane's line seen only from the middle of its taper on (worn paint where it leaves
    the line it splits from) is no line that stays where it is: held at the offset it was
    first seen at back to where the edge moving out with it reached that offset, the lane
    opened at once 2.2 m wide there, 30 m before its taper reached that width
    (melbourne-14-s11+80: lane count 96.6 %). Carried on along its slope, it opens from
    the line it leaves, as a taper. Stations and offsets in metres."""
    n_slope = max(round(_MOVING_OVER_M / float(grid[1] - grid[0])), 2)
    s_part, d_part = (
        (tr.s[-n_slope:], tr.d[-n_slope:]) if forward else (tr.s[:n_slope], tr.d[:n_slope])
    )
    if s_part.size < 2 or tr.n == 0:
        return None
    slope = float(np.polyfit(s_part, d_part, 1)[0])
    if abs(slope) < _MOVING_SLOPE:
        return None
    s_end, d_end = float(s_part[-1 if forward else 0]), float(d_part[-1 if forward else 0])
    if forward:
        probe = grid[(grid > s_end) & (grid <= s_end + _CARRY_MAX_M)]
    else:
        probe = grid[(grid < s_end) & (grid >= s_end - _CARRY_MAX_M)][::-1]
    d_probe = d_end + slope * (probe - s_end)
    meet = None
    for j, nb in enumerate(tracks):
        if j == k:
            continue
        inside = (probe >= nb.lo) & (probe <= nb.hi)
        if not inside.any():
            continue
        # the side of the neighbour the line is on flips (or comes within _MEET_M) where
        # they meet
        side = np.where(inside, d_probe - np.interp(probe, nb.s, nb.d), np.nan)
        at_end = side[np.flatnonzero(inside)[0]]
        if abs(at_end) > lane_m:
            continue
        hit = np.flatnonzero(inside & ((np.abs(side) <= _MEET_M) | (side * at_end < 0.0)))
        if hit.size and (meet is None or hit[0] < meet):
            meet = int(hit[0])
    if meet is None or meet == 0:
        return None
    g, d_new = probe[: meet + 1], d_probe[: meet + 1]
    if d_edge is not None and np.any(d_new > np.interp(g, grid, d_edge) + _OUTSIDE_EDGE_M):
        return None  # beyond the seen edge: not where the line went
    if forward:
        return replace(
            tr, hi=float(g[-1]), s=np.concatenate([tr.s, g]), d=np.concatenate([tr.d, d_new])
        )
    return replace(
        tr,
        lo=float(g[-1]),
        s=np.concatenate([g[::-1], tr.s]),
        d=np.concatenate([d_new[::-1], tr.d]),
    )


def _meeting_station(
    tr: _Track,
    nb: _Track,
    grid: FloatArray,
    cfg: MainlineConfig,
    *,
    forward: bool,
    lane_m: float,
) -> float | None:
    """Where ``nb`` reaches the offset ``tr`` ends (starts) with, converging onto it after
    ``tr`` ends (diverging from it before ``tr`` starts) within ``lane_taper_max_m``;
    None if it does not."""
    s_end = tr.hi if forward else tr.lo
    d_end = float(tr.d[-1] if forward else tr.d[0])
    if forward:
        probe = grid[(grid > s_end) & (grid <= min(s_end + cfg.lane_taper_max_m, nb.hi))]
    else:
        probe = grid[(grid < s_end) & (grid >= max(s_end - cfg.lane_taper_max_m, nb.lo))][::-1]
    if probe.size < 2:
        return None
    gap = np.abs(np.interp(probe, nb.s, nb.d) - d_end)
    met = np.flatnonzero(gap <= _MEET_M)
    # where the neighbour stops converging (the gap shrinks by less than _SETTLE_DROP_M over
    # the next _SETTLE_RUN_M) it has settled; a meeting farther on is another line's
    # business (melbourne-408-opp-s4: a lane line ended 0.7 m short of where the lane
    # beside it closed, was carried on 250 m to where the line bent towards it, and a lane
    # 0.7 m wide ran along 200 m)
    step = float(abs(probe[1] - probe[0]))
    w = max(1, round(_SETTLE_RUN_M / step))
    ahead = np.concatenate([gap[w:], np.full(min(w, gap.size), gap[-1])])
    settled = np.flatnonzero((gap - ahead < _SETTLE_DROP_M) & (gap > _MEET_M))
    settled = settled[settled < gap.size - w]  # a whole run ahead to judge by
    if settled.size and (not met.size or settled[0] < met[0]):
        met = np.zeros(0, dtype=np.int64)
        gap = gap[: settled[0] + 1]
    if met.size:
        i = int(met[0])
    else:
        # the neighbour settles beside the ended line's offset, not on it (the lane that
        # goes on is a little narrower or wider after the drop): it met it where it came
        # nearest, if that is within a quarter lane (the rest closes as a taper's rest)
        i = int(np.argmin(gap))
        if gap[i] > _MEET_LANE_SHARE * lane_m:
            return None
    # converging all the way: the gap shrinks from the end to the meeting point
    if i > 0 and float(np.max(np.diff(gap[: i + 1]))) > 0.05:
        return None
    return float(probe[i])


def _continue_to_convergence(
    tracks: list[_Track],
    grid: FloatArray,
    cfg: MainlineConfig,
    d_edge: FloatArray | None = None,
) -> list[_Track]:
    """Lane lines that end where a lane's taper begins, continued to where it closes.

    Where a lane ends by a taper (an acceleration lane, a lane drop), the broken line
    between it and the lane that goes on often ends where the taper begins, and the line
    beyond it converges onto that position over the taper; a lane that begins mirrors it.
    Without the ended line the taper's two lanes are built as one lane up to twice as wide
    (7 m on Town06). A line that ends (begins) is continued at the offset it ended with to
    where its neighbour meets that offset, if that neighbour converges onto it (diverges
    from it) all the way within ``lane_taper_max_m`` and no other line lies there: the
    lane between them then closes (opens) to zero width there, a taper.

    With the outer edge ``d_edge`` (on ``grid``; NaN where it was not seen), the edge is
    such a neighbour too where it was seen all the way to the meeting: on a road without a
    hard shoulder the edge itself closes the outer lane onto the line that ended, with no
    line beyond it (krems-102561705-s2: the two lanes were one over 100 m).

    Stations and offsets are metres (offsets from the reference edge towards the
    carriageway); the continued part has no samples of its own.
    """
    if len(tracks) < 2:
        return tracks
    lane_m = typical_lane_width(tracks, grid)
    out = list(tracks)
    neighbours = list(tracks)
    edge_seen = np.zeros(grid.size, dtype=bool) if d_edge is None else np.isfinite(d_edge)
    if edge_seen.any():
        neighbours.append(
            _Track(
                -1,
                float(grid[0]),
                float(grid[-1]),
                grid[edge_seen],
                d_edge[edge_seen],  # type: ignore[index]
                "solid",
                0,
                grid[:0],
            )
        )
    for k, tr in enumerate(tracks):
        if tr.n == 0:
            continue
        for forward in (True, False):
            s_end = tr.hi if forward else tr.lo
            if (forward and s_end >= grid[-1] - 1.0) or (not forward and s_end <= grid[0] + 1.0):
                continue
            d_end = float(tr.d[-1] if forward else tr.d[0])
            along = _along_its_slope(
                out[k], tracks, k, grid, forward=forward, lane_m=lane_m, d_edge=d_edge
            )
            if along is not None:
                out[k] = along
                continue
            # the adjacent lines either side that run on past the end
            beside = []
            for j, nb in enumerate(neighbours):
                if j == k or nb.lo > s_end - 1.0 or nb.hi < s_end + 1.0:
                    continue
                gap = abs(float(np.interp(s_end, nb.s, nb.d)) - d_end)
                # a neighbour already closer than a lane at the end is the taper's last
                # metres (melbourne-18-s11+80: the line between a dropped lane and the
                # one beside it lost 1.0 m from the converging line, 50 m before they met)
                if _TAPER_TAIL_M <= gap <= 1.5 * lane_m:
                    beside.append((gap, j))
            for _, j in sorted(beside):
                s_meet = _meeting_station(
                    tr, neighbours[j], grid, cfg, forward=forward, lane_m=lane_m
                )
                if s_meet is None:
                    continue
                lo, hi = (s_end, s_meet) if forward else (s_meet, s_end)
                if j == len(tracks):
                    # the edge closes a lane where it was seen, meeting the line within a
                    # taper's length (an exit's edge stepping in beyond the gore drifts
                    # onto its line over hundreds of metres)
                    edge = neighbours[j]
                    meets = abs(float(np.interp(s_meet, edge.s, edge.d)) - d_end)
                    span = (grid >= lo) & (grid <= hi)
                    if hi - lo > _EDGE_TAPER_MAX_M or meets > _MEET_M or not edge_seen[span].all():
                        continue
                occupied = any(
                    other.lo < hi
                    and other.hi > lo
                    and np.any(
                        np.abs(other.d[(other.s > lo) & (other.s < hi)] - d_end) < _OCCUPIED_M
                    )
                    for i2, other in enumerate(tracks)
                    if i2 not in (k, j)
                )
                if occupied:
                    continue
                cur = out[k]
                if forward:
                    g = grid[(grid > cur.hi) & (grid <= s_meet)]
                    out[k] = replace(
                        cur,
                        hi=float(g[-1]),
                        s=np.concatenate([cur.s, g]),
                        d=np.concatenate([cur.d, np.full(g.size, d_end)]),
                    )
                else:
                    g = grid[(grid < cur.lo) & (grid >= s_meet)]
                    out[k] = replace(
                        cur,
                        lo=float(g[0]),
                        s=np.concatenate([g, cur.s]),
                        d=np.concatenate([np.full(g.size, d_end), cur.d]),
                    )
                log.debug(
                    "mainline: line at %.1f m continued %s to s=%.0f m (a taper)",
                    d_end,
                    "on" if forward else "back",
                    s_meet,
                )
                break
    return out


_FRAME_RATE_SHARE = 0.3  # share of the frame's rate a line moving with it may keep in it


def _trim_ramp_lines(
    g: FloatArray, d: FloatArray, cfg: MainlineConfig, frame_rate: FloatArray | None = None
) -> NDArray[np.bool_]:
    """Mask of the part of a marking track that belongs to the mainline.

    Ramp markings cross the mainline corridor near a gore: before an entry gore they come
    in from outside, converging steeply (d decreasing), after an exit gore they leave
    (d increasing). A track's leading part that converges steeply and its trailing part
    that diverges steeply are cut off. (Lane tapers of the mainline itself open outward at
    their start and close inward at their end, so they are kept.)

    In a frame that moves with the marking pattern (``frame_rate``: its sideways rate at
    ``g``, m/m; ``d`` in that frame) a part is steep only where it is steep in the
    reference line's frame too: a line that stays where it is while the pattern shifts
    (the median-side edge line) is no ramp line.
    """
    keep = np.ones(g.size, dtype=bool)
    if g.size < 5:
        return keep
    slope = np.gradient(d, g)
    steep = cfg.ramp_line_slope
    if frame_rate is None:
        road_slope, steep_here = slope, steep
    else:
        # the frame follows the pattern to within a few tenths of its rate halfway
        # through a shift: a line that moves with it is that steep in the frame
        road_slope, steep_here = slope + frame_rate, steep + _FRAME_RATE_SHARE * np.abs(frame_rate)
    # leading part: converging inward steeply
    flat = np.flatnonzero((slope > -steep_here) | (road_slope > -steep))
    if flat.size == 0:
        return np.zeros(g.size, dtype=bool)  # converging all along: a ramp line
    if flat[0] > 0 and (g[flat[0]] - g[0]) >= 10.0:
        keep[: flat[0]] = False
    flat = np.flatnonzero((slope < steep_here) | (road_slope < steep))
    if flat.size == 0:
        return np.zeros(g.size, dtype=bool)
    if flat[-1] < g.size - 1 and (g[-1] - g[flat[-1]]) >= 10.0:
        keep[flat[-1] + 1 :] = False
    return keep


_NOSE_WINDOW_M = 15.0  # an edge step this close before or after a line's start ... (metres)
_NOSE_STEP_M = 1.5  # ... outward by more than this is an entry's nose (metres)


_END_GAPS_OVER_M = 60.0  # the dash gaps over a line's last metres tell where a run end cut it
_INWARD_AHEAD_M = 15.0  # the next line inward may be first seen this far after a line's start


def _next_line_inward(cand: list[_Track], k: int, g: FloatArray, d: FloatArray) -> float | None:
    """Offset (metres) of the nearest other candidate track inward of track ``k`` (more
    than half a metre inside) where ``k`` is first seen (its fit ``d`` at stations ``g``):
    the narrowest strip between them over ``k``'s first ``_INWARD_AHEAD_M``, as an offset
    at ``g[0]``; None if there is none. A broken line seen a dash late counts (a9-8081560-
    s11 with a noisier sensor: two lanes gained at once, the inner one's line first seen
    9 m after the outer one's, which then had two lanes inside it and was cut as a ramp's
    line: the lane closing by a taper over 125 m was missing)."""
    ahead = g <= g[0] + _INWARD_AHEAD_M
    g_a, d_a = g[ahead], d[ahead]
    # per station the nearest line inward (-inf where none)
    nearest = np.full(g_a.size, -np.inf)
    for j, tr in enumerate(cand):
        if j == k:
            continue
        v = np.interp(g_a, tr.s, tr.d)
        ok = (g_a >= tr.lo) & (g_a <= tr.hi) & (v < d_a - 0.5)
        nearest = np.where(ok, np.maximum(nearest, v), nearest)
    seen = np.isfinite(nearest)
    return float(d[0]) - float(np.min(d_a[seen] - nearest[seen])) if seen.any() else None


def _mainline_ends_inside_edge(
    g: FloatArray,
    d: FloatArray,
    keep: NDArray[np.bool_],
    grid: FloatArray,
    d_edge: FloatArray,
    s_last: float,
    end_reach_m: float,
    *,
    inner_d: float | None = None,
    meets_line: bool = False,
    settle_slope: float | None = None,
    edge_seen: NDArray[np.bool_] | None = None,
) -> NDArray[np.bool_]:
    """The trimmed ends of a marking track (``~keep``, see :func:`_trim_ramp_lines`) that
    are the mainline's own lines after all: they stay inside the outer edge ``d_edge``
    (metres, same frame as ``d``) all along. A line ending within ``end_reach_m`` of the
    run's last sample (``s_last``, metres) is cut by the run's end: two columns, or the
    line's own dash gaps there (oakland-28393854-lane1-s21 with a noisier sensor: a lane
    gained by a taper over the run's last 80 m, its broken line's last dash seen 12 m
    before the end, was cut as an exit's line and the lane was missing).

    A steeply converging or diverging part is a ramp line because it comes in from, or
    leaves to, outside the corridor. The edge line of a lane drop converges as steeply
    (a 3.5 m taper over 100-200 m) but inside the edge, which closes in with it: kept, the
    lane closes where its line meets the next one instead of ending at full width. Past an
    entry's nose the ramp's line converges inside the edge too, but it starts where the
    edge steps out by the ramp's width: that one is still cut (the painted gore is no lane
    of the mainline; kept, it split the acceleration lane and esmini warned of lanes
    without a connecting lane on melbourne-408-opp). A diverging part is kept only where
    the run's end cuts it off before it could leave: a lane that opens by a taper the run
    ends in. Elsewhere a diverging line inside the edge may still be about to leave (the
    edge follows an exit's ramp up to the nose), and kept whole, the lines that shift a
    lane sideways where lanes are added on the median side gave lane sections whose
    through lanes were not linked (melbourne-408-opp). Past a nose, the outer line of an
    acceleration lane that closes by a taper is kept (:func:`_closes_with_edge`;
    ``inner_d``: the next line inward where the line is first seen, metres). A diverging
    tail that ends on a line converging towards it (``meets_line``,
    :func:`_ends_on_converging_line`) is kept too: the lane between them closes from both
    sides (melbourne-408-opp-s4: the inner line of a dropped lane moved 0.8 m out to meet
    the outer one; cut, it went on flat and the lane ended 0.7 m wide, 10 m late).
    """
    back = np.zeros(g.size, dtype=bool)
    if keep.all():
        return back
    edge = np.interp(g, grid, d_edge)
    inside = np.isfinite(edge) & (d < edge)
    if not keep.any():  # converging (diverging) all along: all head (tail)
        kept = np.array([g.size]) if d[-1] < d[0] else np.array([-1])
    else:
        kept = np.flatnonzero(keep)
    head = np.arange(0, kept[0])
    # an entry's line comes in past the nose, where the edge steps out by the ramp's width
    near = np.interp(g[0] + np.array([-_NOSE_WINDOW_M, 0.0, _NOSE_WINDOW_M]), grid, d_edge)
    at_nose = near[1:].max() - near[0] > _NOSE_STEP_M
    if (
        head.size
        and inside[head].all()
        and (not at_nose or _closes_with_edge(g[head], d[head], edge[head], inner_d))
    ):
        back[head] = True
    tail = np.arange(kept[-1] + 1, g.size)
    at_end = g[-1] >= s_last - end_reach_m
    if tail.size and (at_end or meets_line) and inside[tail].all():
        back[tail] = True
    elif tail.size and at_end and settle_slope is not None and edge_seen is not None:
        seen = np.interp(g[tail], grid, edge_seen.astype(float)) > 0.5
        back[tail] = _settles_unseen(g[tail], d[tail], inside[tail] | ~seen, settle_slope)
    return back


_SETTLED_OVER_M = 10.0  # a run-end tail that runs parallel over its last metres ...
_SETTLED_MOVE_M = (2.5, 4.5)  # ... after moving out by a lane's width (metres): its
_SETTLED_SHARE = 0.5  # slope there at most this share of its steepest (a taper's S)


def _settles_unseen(
    g: FloatArray, d: FloatArray, allowed: NDArray[np.bool_], slope_max: float
) -> bool:
    """Whether the diverging tail of a line that the run's end cuts off (stations ``g``,
    offsets ``d``, metres) is a new lane's line though the edge beside it was not seen:
    it lies inside the edge wherever that was seen (``allowed``: inside it or beside its
    occlusion), moved out by a lane's width (``_SETTLED_MOVE_M``) and levelled off over
    its last ``_SETTLED_OVER_M`` (slope under ``slope_max``, m/m, or ``_SETTLED_SHARE`` of
    its steepest: a taper's S, smoothed by the fit), where a ramp's line keeps leaving
    (oakland-28393854-lane1-s21 with a noisier sensor, seed offset 320: a lane gained by a
    taper over the last 80 m of the run, the edge hidden there; cut as an exit's line,
    the lane was missing)."""
    if not allowed.all():
        return False
    last = g >= g[-1] - _SETTLED_OVER_M
    if np.count_nonzero(last) < 3:
        return False
    slope = float(np.polyfit(g[last], d[last], 1)[0])
    moved = float(d[-1] - d[0])
    steepest = float(np.max(np.abs(np.gradient(d, g)))) if g.size >= 2 else 0.0
    flat = abs(slope) < max(slope_max, _SETTLED_SHARE * steepest)
    return flat and _SETTLED_MOVE_M[0] <= moved <= _SETTLED_MOVE_M[1]


_CLOSING_OVER_M = 30.0  # a line ends on another whose gap to it shrank over this ...
_CLOSING_BY_M = 0.5  # ... by this much (metres), the other coming in by as much ...
_CLOSING_AHEAD_M = 50.0  # ... and, closing at that rate, meets it within this (metres) ...
_CLOSING_AFTER_M = 20.0  # ... while the other goes on at least this far beyond the meeting


def _ends_on_converging_line(cand: list[_Track], k: int, s_end: float, d_end: float) -> bool:
    """Whether track ``k``, whose end at station ``s_end`` (offset ``d_end``, metres)
    moves outward, ends on another candidate track farther out that converges towards
    it: the gap between the two shrank by ``_CLOSING_BY_M`` or more over the last
    ``_CLOSING_OVER_M``, the other line came in, closing at that rate they meet within
    ``_CLOSING_AHEAD_M``, and the other line goes on ``_CLOSING_AFTER_M`` beyond the meeting.

    A lane closing from both sides: its inner line moves out while its outer line comes
    in, and only the outer line goes on (the inner one's samples end where the two become
    one marking). An exit's diverging line leaves past every line instead (the line
    beyond it, the exit lane's outer line, leaves with it)."""
    tr_k = cand[k]
    before = s_end - _CLOSING_OVER_M
    if tr_k.lo > before:
        return False
    d_k_before = float(np.interp(before, tr_k.s, tr_k.d))
    for j, tr in enumerate(cand):
        if j == k or tr.lo > before:
            continue
        d_there, d_before = np.interp([s_end, before], tr.s, tr.d)
        gap, gap_before = d_there - d_end, d_before - d_k_before
        closing = gap_before - gap
        if gap <= -_CLOSING_BY_M or closing < _CLOSING_BY_M or d_before - d_there < _CLOSING_BY_M:
            continue
        meet = s_end + max(gap, 0.0) / closing * _CLOSING_OVER_M
        if meet - s_end <= _CLOSING_AHEAD_M and tr.hi >= meet + _CLOSING_AFTER_M:
            return True
    return False


_WITH_EDGE_SHARE = 0.5  # a line whose gap to the edge changes by less than this share ...
_WITH_EDGE_MIN_M = 1.5  # ... of its own sideways move (at least this, metres) moves with it
_TAPER_MAX_SLOPE = 0.06  # a lane closes by a taper no steeper than this (m/m): 3.5 m in 60 m
_SHOULDER_MAX_M = 3.25  # narrower than a lane (2.75 m) and a ramp's shoulder (0.5 m)
_ONE_LANE_MAX_M = 4.75  # the widest strip that is one lane


def _closes_with_edge(
    g: FloatArray, d: FloatArray, edge: FloatArray, inner_d: float | None
) -> bool:
    """Whether a converging line (``d`` at stations ``g``) is the outer line of an
    acceleration lane that closes by a taper from the nose on (metres towards the outer
    side; ``edge`` the outer edge, ``inner_d`` the next line inward at ``g[0]``).

    Such a line closes one lane (the strip to the next line inward is a lane wide where it
    is first seen), at a lane taper's rate (3.5 m in 60 m or slower), with the hard
    shoulder beside it: its gap to the edge stays about a shoulder's width while it moves
    in. Past the nose of a painted gore, the ramp's inner line has the ramp's lane and
    shoulder beyond it (the gap is wider than a shoulder), its outer line the gore and the
    ramp's lane inside it (more than a lane to the next line inward); the ramp's shoulder
    line comes in as steeply as the ramp (0.1 m/m on krems-24746399-s11). Kept, the line
    makes the acceleration lane that tapers (a9 chain 206615404, seed 41: it and the
    shoulder had been one 5.9 m shoulder, lines 3.6 m off over 100 m)."""
    if d.size < 2 or inner_d is None:
        return False
    moved = float(np.max(d) - np.min(d))
    gap = edge - d
    span = float(g[-1] - g[0])
    return (
        moved >= _WITH_EDGE_MIN_M
        and moved <= _TAPER_MAX_SLOPE * span
        and float(np.ptp(gap)) < _WITH_EDGE_SHARE * moved
        and float(np.median(gap)) < _SHOULDER_MAX_M
        and float(d[0]) - inner_d <= _ONE_LANE_MAX_M
    )


_DRIFT_PER_M = 0.04  # a hidden line may have moved sideways this much per metre of gap
_DRIFT_MAX_LANE = 0.4  # ... and at most this share of a lane (lines are a lane apart)
_HOLD_MARGIN_M = 0.5  # a bridged line this near the edge (metres) was no line there ...
_HOLD_SEEN_M = 10.0  # ... unless as near where it was seen this far (metres) beside the gap
_HOLD_STEP_M = 1.0  # ... at a gore in the gap: the edge moves this much (metres) per station


def _merge_collinear(
    tracks: list[_Track],
    cfg: MainlineConfig,
    grid: FloatArray | None = None,
    d_edge: FloatArray | None = None,
    *,
    with_inferred_only: bool = False,
) -> list[_Track]:
    """Join a track that ends and another that starts at the same offset (occlusion).

    The same offset: within ``lane_link_m``, plus a drift of ``_DRIFT_PER_M`` per metre
    of the gap (the lanes shift sideways where the markings were not seen; a line moves
    by less than a lane) for a pair that is each other's nearest by twice the margin
    of any other: the lines beside it are a lane away, so the pair is unambiguous.

    With the outer edge ``d_edge`` on ``grid``: never across a stretch where the road is
    too narrow to hold the marking (the edge comes within ``_HOLD_MARGIN_M`` of the
    bridged line): there the marking really ended and another began (an exit and a later
    entry at the same offset), it was not hidden; an edge line leaving the edge where a
    lane opens beside it by a taper is a lane's border from there (a section starts). Where
    the edge steps in the stretch (a gore), a line running on beside the new level as near
    as where it was seen (half the least distance between edge and line over the
    ``_HOLD_SEEN_M`` beside the stretch) over most of it is the line inward of the ramp's
    lanes going on as the edge line.

    ``with_inferred_only``: only pairs of which one is an inferred line (no samples): two
    observed tracks that were left apart after the first pass were split on purpose (at a
    gore).
    """
    lane_m = typical_lane_width(tracks, grid) if grid is not None else 3.5

    def road_holds(a: _Track, b: _Track) -> bool:
        if grid is None or d_edge is None:
            return True
        inside = (grid > a.hi) & (grid < b.lo)
        if not np.any(inside):
            return True
        x = (grid[inside] - a.hi) / max(b.lo - a.hi, 1e-9)
        line = (1.0 - x) * a.d[-1] + x * b.d[0]
        edge = d_edge[inside]
        known = np.isfinite(edge)
        if not np.any(np.abs(np.diff(edge[known])) > _HOLD_STEP_M):
            return not np.any(known & (edge < line + _HOLD_MARGIN_M))
        # the edge steps in the gap (a gore): the line inward of the ramp's lanes goes on
        # as the edge line beside the new level, over most of the gap (the edge bends
        # into the step over a few metres)
        narrow = known & (edge < line + holds_margin(a, b))
        return not (np.any(narrow) and np.count_nonzero(narrow) >= 0.5 * np.count_nonzero(known))

    def holds_margin(a: _Track, b: _Track) -> float:
        # an edge line runs this near the edge where it was seen: the edge as near
        # in the gap is no narrowing (krems-46762523-opp-s4 with a noisier sensor: the
        # line left as the edge line by a two-lane exit, broken at the gore, was not
        # joined across it and a lane opened over 220 m to reach it); a line seen beyond
        # the edge is no edge line (krems-24746399-opp-s12: a lane line ending at an exit
        # joined to one beginning at an entry 290 m on, across a one-lane stretch)
        near = []
        for tr, part in ((a, a.s >= a.hi - _HOLD_SEEN_M), (b, b.s <= b.lo + _HOLD_SEEN_M)):
            e = np.interp(tr.s[part], grid, d_edge)
            ok = np.isfinite(e)
            if np.any(ok):
                near.append(float(np.min(e[ok] - tr.d[part][ok])))
        return min(_HOLD_MARGIN_M, 0.5 * max(min(near), 0.0)) if near else _HOLD_MARGIN_M

    def follows(a: _Track, b: _Track) -> bool:
        return b.lo > a.hi - 1.0 and b.lo - a.hi <= 5.0 * cfg.lane_max_gap_m

    def allowed(a: _Track, b: _Track) -> float:
        gap = max(b.lo - a.hi, 0.0)  # tracks may overlap by up to a metre
        return cfg.lane_link_m + min(_DRIFT_PER_M * gap, _DRIFT_MAX_LANE * lane_m)

    def clear_pair(tracks: list[_Track], i: int, j: int) -> bool:
        a, b = tracks[i], tracks[j]
        jump = abs(a.d[-1] - b.d[0])
        if jump <= cfg.lane_link_m:
            return True
        others_b = [
            abs(t.d[-1] - b.d[0]) for k, t in enumerate(tracks) if k not in (i, j) and follows(t, b)
        ]
        others_a = [
            abs(a.d[-1] - t.d[0]) for k, t in enumerate(tracks) if k not in (i, j) and follows(a, t)
        ]
        return all(o > 2.0 * jump for o in others_a + others_b)

    tracks = sorted(tracks, key=lambda tr: tr.lo)
    merged = True
    while merged:
        merged = False
        for i, a in enumerate(tracks):
            for j, b in enumerate(tracks):
                if i == j or not follows(a, b):
                    continue
                if with_inferred_only and a.n > 0 and b.n > 0:
                    continue
                if abs(a.d[-1] - b.d[0]) > allowed(a, b) or not road_holds(a, b):
                    continue
                if not clear_pair(tracks, i, j):
                    continue
                tracks[i] = _Track(
                    a.id,
                    a.lo,
                    b.hi,
                    np.concatenate([a.s, b.s]),
                    np.concatenate([a.d, b.d]),
                    a.mark if a.n >= b.n else b.mark,
                    a.n + b.n,
                    np.concatenate([a.s_samples, b.s_samples]),
                    np.concatenate([a.d_samples, b.d_samples]),
                )
                del tracks[j]
                merged = True
                break
            if merged:
                break
    return [replace(tr, id=k) for k, tr in enumerate(tracks)]


def _marking_matrix(tracks: list[_Track], grid: FloatArray) -> FloatArray:
    """``(n_tracks, grid)`` offsets of every marking track, NaN outside its extent."""
    out = np.full((len(tracks), grid.size), np.nan)
    for i, tr in enumerate(tracks):
        sel = (grid >= tr.lo) & (grid <= tr.hi)
        out[i, sel] = np.interp(grid[sel], tr.s, tr.d)
    return out


def typical_lane_width(tracks: list[_Track], grid: FloatArray, default_m: float = 3.5) -> float:
    """Median width (metres) of the lanes between adjacent observed markings that are
    2.5-4.5 m apart (the run's own lane width; ``default_m`` if none)."""
    if len(tracks) < 2:
        return default_m
    d = np.sort(_marking_matrix(tracks, grid), axis=0)  # NaN sort last
    w = np.diff(d, axis=0)
    w = w[np.isfinite(w) & (w >= 2.5) & (w <= 4.5)]
    return float(np.median(w)) if w.size else default_m


def _last_marking(tracks: list[_Track], grid: FloatArray) -> FloatArray:
    """Offset of the outermost marking track at each grid station (-inf where none)."""
    d_last = np.full(grid.size, -np.inf)
    for tr in tracks:
        sel = (grid >= tr.lo) & (grid <= tr.hi)
        d_last[sel] = np.maximum(d_last[sel], np.interp(grid[sel], tr.s, tr.d))
    return d_last
