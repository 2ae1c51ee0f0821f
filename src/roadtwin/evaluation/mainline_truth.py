"""The built mainline road against one true mainline road, boundary by boundary.

Where :mod:`roadtwin.evaluation.metrics` measures a whole map against the true network
(every boundary against the nearest reconstructed one of its kind), this compares lane
borders BY INDEX: a true marking against the built marking with the same index where the
lane counts agree (else the nearest one). That is what the mainline stage's tests and
``benchmarks/bench_mainline.py`` need to see a lane that opens at the wrong station. All
errors are lateral distances in metres in the built road's Frenet frame (s along, t left
positive); stations are metres along the true road.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..model import LaneSection, Road

FloatArray = NDArray[np.float64]


def _side_lanes(sec: LaneSection):
    return sec.right or sec.left


def lane_borders(road: Road, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, NDArray]:
    """Reference-edge t, outer-edge t, lane-marking t (K, N; NaN where a section has fewer
    markings) and the lane count at stations ``s`` (metres) of ``road``."""
    sec_idx = road.section_index(s)
    kmax = max(len(_side_lanes(sec)) for sec in road.lane_sections)
    marks = np.full((kmax, s.size), np.nan)
    outer = np.full(s.size, np.nan)
    count = np.zeros(s.size, int)
    for k in np.unique(sec_idx):
        sec = road.lane_sections[int(k)]
        sel = sec_idx == k
        ids = [ln.id for ln in _side_lanes(sec)]
        count[sel] = len(ids)
        outer[sel] = road.lane_border_t(s[sel], ids[-1])
        for j, lid in enumerate(ids[:-1]):
            marks[j, sel] = road.lane_border_t(s[sel], lid)
    return road.lane_border_t(s, 0), outer, marks, count


def compare_mainline_road(
    built: Road,
    truth: Road,
    *,
    step_m: float = 1.0,
    s_lo: float = 0.0,
    s_hi: float | None = None,
) -> dict[str, FloatArray] | None:
    """Errors of ``built`` against ``truth`` every ``step_m`` metres over ``[s_lo, s_hi]``
    of the true road (stations half a step off section boundaries).

    Returns
    -------
    ``ref_edge``, ``outer_edge``, ``lane_boundary``, ``elevation``: errors in metres;
    ``lane_count``: 1.0 where the built lane count at the station is right;
    ``section_count``: the same at the middle of every true lane section longer than 20 m.
    None if the range holds no station.
    """
    s_hi = truth.length if s_hi is None else s_hi
    s_t = np.arange(s_lo + 0.5 * step_m, s_hi, step_m)
    if s_t.size == 0:
        return None
    ref_t, out_t, marks_t, count_t = lane_borders(truth, s_t)
    out: dict[str, FloatArray] = {}
    pts_ref = truth.to_xy(s_t, ref_t)
    s_b, t_b = built.project(pts_ref)
    ref_b, _, _, count_b = lane_borders(built, s_b)
    out["ref_edge"] = t_b - ref_b
    out["lane_count"] = (count_b == count_t).astype(float)
    out["elevation"] = built.height(s_b) - truth.height(s_t)
    s_b, t_b = built.project(truth.to_xy(s_t, out_t))
    out["outer_edge"] = t_b - lane_borders(built, s_b)[1]
    errs = []
    for j in range(marks_t.shape[0]):
        ok = np.isfinite(marks_t[j])
        if not np.any(ok):
            continue
        s_b, t_b = built.project(truth.to_xy(s_t[ok], marks_t[j, ok]))
        _, _, marks_b, cnt_b = lane_borders(built, s_b)
        same = cnt_b == count_t[ok]
        by_index = marks_b[j] if j < marks_b.shape[0] else np.full(s_b.size, np.nan)
        nearest = np.nanmin(np.abs(marks_b - t_b[None, :]), axis=0)
        errs.append(np.where(same & np.isfinite(by_index), np.abs(t_b - by_index), nearest))
    out["lane_boundary"] = np.concatenate(errs) if errs else np.zeros(0)
    mids = []
    for k, sec in enumerate(truth.lane_sections):
        hi = truth.section_end(k)
        if hi - sec.s0 > 20.0 and s_lo <= 0.5 * (sec.s0 + hi) <= s_hi:
            mids.append(0.5 * (sec.s0 + hi))
    if mids:
        s_m = np.asarray(mids)
        s_b, _ = built.project(truth.to_xy(s_m, lane_borders(truth, s_m)[0]))
        out["section_count"] = (lane_borders(built, s_b)[3] == lane_borders(truth, s_m)[3]).astype(
            float
        )
    else:
        out["section_count"] = np.zeros(0)
    return out


def geometry_continuity(road: Road) -> tuple[float, float]:
    """Largest position gap (metres) and heading kink (degrees) between consecutive
    geometry pieces of ``road``."""
    gap, kink = 0.0, 0.0
    for a, b in zip(road.geometry[:-1], road.geometry[1:], strict=True):
        x, y, h = a.end_pose()
        gap = max(gap, math.hypot(x - b.x0, y - b.y0))
        dh = (h - b.hdg + math.pi) % (2 * math.pi) - math.pi
        kink = max(kink, abs(math.degrees(dh)))
    return gap, kink


def rmse(errors) -> float:
    """Root mean square of the finite errors (NaN if there are none)."""
    e = np.asarray(errors, float)
    e = e[np.isfinite(e)]
    return float(np.sqrt(np.mean(e * e))) if e.size else math.nan
