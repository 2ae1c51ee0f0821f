"""Gores where the paint splits the lanes, not where the kerb does.

At an exit the lanes split where the markings do: the through lanes' outer marking turns
from broken (beside the deceleration lane) to the solid edge line at the painted gore's
tip, and from there the exit lane belongs to the ramp. The physical nose, where the
outer-edge points step back to the mainline (:func:`~.outer_edge.fit_outer_edge`), lies
metres to a hundred metres further on; between the two lies the hatched gore area. An
entry mirrors it (nose, then the painted tip where the acceleration lane begins beside
the through lanes).

:func:`move_gores_to_paint` moves each measured edge step (the nose) to the painted tip
found by :func:`~.gores.marking_gore_interval` on the through lanes' outer marking: the
lanes beyond that marking end (begin) at the tip, and between tip and nose the mainline's
outer edge is that marking plus the shoulder the nose opens with, rising linearly from
zero. Where the marking does not show the change (no markings, a solid line all along, a
worn stretch), the step stays at the nose.

Stations ``s`` are metres along the reference line, offsets ``d`` metres from the
reference (median-side) edge towards the carriageway and beyond (larger: farther out).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from .gores import marking_gore_interval
from .hidden_gores import _move_track_end
from .markings import _Track

FloatArray = NDArray[np.float64]

_PROBE_M = 3.0  # stations this far either side of a step tell its direction and lanes
_THROUGH_M = 10.0  # the through marking runs at least this far past the nose both ways
_MIN_PAINTED_M = 3.0  # a tip nearer the nose than this is the nose (nothing to move)


def _at(tr: _Track, s: float) -> float:
    return float(np.interp(s, tr.s, tr.d))


def move_gores_to_paint(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    breaks: FloatArray,
    seen_s: FloatArray,
    config: MainlineConfig | None = None,
) -> tuple[list[_Track], FloatArray, FloatArray, list[tuple[float, float]]]:
    """Outer-edge steps (gore noses) moved to the painted gore tips.

    Parameters
    ----------
    tracks
        Marking tracks (offsets on their own stations).
    grid, d_edge
        Stations (metres) and the outer edge's offset on them (metres).
    breaks
        Stations of the outer edge's steps (metres).
    seen_s
        Sorted stations of every lane sample (metres): stretches without any are not dash
        gaps.

    Returns
    -------
    tracks (those beyond the through marking cut at the tips), the outer edge, the steps,
    and the painted stretches ``(lo, hi)`` (metres; the edge points there are the ramp's).
    """
    cfg = config or MainlineConfig()
    if breaks.size == 0 or not tracks:
        return tracks, d_edge, breaks, []
    d_edge = d_edge.copy()
    out_breaks: list[float] = []
    painted: list[tuple[float, float]] = []
    for b in np.sort(breaks):
        before = float(np.interp(b - _PROBE_M, grid, d_edge))
        after = float(np.interp(b + _PROBE_M, grid, d_edge))
        moved = _paint_tip(tracks, grid, d_edge, float(b), before, after, seen_s, cfg)
        if moved is None:
            out_breaks.append(float(b))
            continue
        tracks, tip = moved
        out_breaks.append(tip)
        painted.append((min(tip, float(b)), max(tip, float(b))))
    # track ids are their positions (the lane-section stage indexes by them)
    tracks = [replace(tr, id=i) for i, tr in enumerate(tracks)]
    return tracks, d_edge, np.sort(np.asarray(out_breaks)), painted


def _paint_tip(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    nose: float,
    before: float,
    after: float,
    seen_s: FloatArray,
    cfg: MainlineConfig,
) -> tuple[list[_Track], float] | None:
    """Move one step; ``d_edge`` is changed in place. None when the paint shows no tip."""
    if abs(after - before) < cfg.edge_step_m:
        return None
    exit_ = after < before  # the edge moves in: a lane leaves
    inner_edge = min(before, after)
    # the through lanes' outer marking: the outermost marking that runs on past the nose
    # on both sides and lies inside the edge where the road is narrow (after an exit's
    # nose, before an entry's; right at the nose it may be the edge line)
    probe = nose + _PROBE_M if exit_ else nose - _PROBE_M
    through = [
        tr
        for tr in tracks
        if tr.n > 0
        and tr.lo <= nose - _THROUGH_M
        and tr.hi >= nose + _THROUGH_M
        and _at(tr, probe) < inner_edge + 0.3
    ]
    if not through:
        return None
    mark = max(through, key=lambda tr: _at(tr, probe))
    interval = marking_gore_interval(
        mark.s_samples,
        nose,
        entry=not exit_,
        search_m=cfg.painted_gore_max_m,
        seen_s=seen_s,
    )
    if interval is None:
        return None
    # within a dash the line may turn solid anywhere: the end nearer the nose keeps the
    # painted stretch as short as the paint allows
    tip = interval[1] if exit_ else interval[0]
    painted = nose - tip if exit_ else tip - nose
    if not (_MIN_PAINTED_M <= painted <= cfg.painted_gore_max_m):
        return None
    lo, hi = (tip, nose) if exit_ else (nose, tip)
    # the markings beyond the through marking in the painted stretch are the ramp's: they
    # end (begin) at the tip; one that lies there only is dropped
    mid = 0.5 * (lo + hi)
    d_mark = _at(mark, mid)
    kept: list[_Track] = []
    for tr in tracks:
        overlaps = tr.lo < hi and tr.hi > lo
        if tr is mark or not overlaps:
            kept.append(tr)
            continue
        inside = tr.s[(tr.s >= lo) & (tr.s <= hi)]
        at = float(inside[inside.size // 2]) if inside.size else mid
        if _at(tr, at) <= d_mark + 0.5 * cfg.lane_split_m:
            kept.append(tr)
            continue
        if exit_ and tr.lo < tip - 1.0:
            kept.append(_move_track_end(tr, tip, grid, start=False))
        elif not exit_ and tr.hi > tip + 1.0:
            kept.append(_move_track_end(tr, tip, grid, start=True))
        # else: it lies in the painted stretch (or on the ramp beyond it) only
    # the outer edge between tip and nose: the through marking plus the shoulder the
    # nose opens with, from zero at the tip
    zone = (grid > lo) & (grid < hi)
    if zone.any():
        shoulder = max((after if exit_ else before) - _at(mark, probe), 0.0)
        frac = (grid[zone] - tip) / (nose - tip)
        d_mark_zone = np.interp(grid[zone], mark.s, mark.d)
        d_edge[zone] = d_mark_zone + shoulder * np.clip(frac, 0.0, 1.0)
    return kept, float(tip)


__all__ = ["move_gores_to_paint"]
