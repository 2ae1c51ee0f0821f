"""Where the built mainline disagrees with its own evidence: stretch warnings.

A map can pass every validity check and still be metres off where its inference went
wrong (a marking bridged across a narrowing road, an edge pulled by a ramp). The points
the map was built from say so: along such a stretch the road-edge points lie off the
built edge on one side, or many lane samples lie far from every built lane boundary. This
module bins the residuals of the points (:func:`~._common.point_residuals`) along the
station and reports every stretch where they disagree, every driving lane wider than a
lane can be, and every stretch where a road edge was not seen and the line next to it
does not pin it either (:func:`unseen_edges`), so that the build warns with the station
instead of saying "OK".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import maximum_filter1d

from ..config import MainlineConfig
from ..io import MappingRun
from ..model import Road
from ._common import (
    TURN_WINDOW_M,
    FloatArray,
    PointResiduals,
    _border_matrix,
    point_residuals,
    tight_turn_runs,
    true_runs,
)


@dataclass(frozen=True)
class Stretch:
    """A stretch of the mainline whose evidence disagrees with the map.

    Attributes
    ----------
    s0_m, s1_m : station range (metres along the mainline road).
    kind : ``"reference edge"``, ``"outer edge"``, ``"lane markings"``, ``"lane width"``,
        ``"reference edge unseen"``, ``"outer edge unseen"`` (an edge not seen over 50 m
        or more where the line next to it was not measured or its distance to the edge
        changes by 1 m or more) or ``"reference line"`` (turning tighter than a radius
        of ``quality_min_radius_m``).
    value_m : the worst bin's figure: median signed edge offset of the points from the
        built edge (edges), lateral offset t where unexplained lane samples line up
        (markings), the widest lane (lane width) or how much the distance from an unseen
        edge to the line next to it changes (unseen edges; NaN: that line not measured)
        or the tightest radius (reference line), metres.
    fraction : share of the points in the worst bin that the map does not explain.
    """

    s0_m: float
    s1_m: float
    kind: str
    value_m: float
    fraction: float

    def message(self) -> str:
        where = f"mainline s={self.s0_m:.0f}..{self.s1_m:.0f} m"
        if self.kind == "reference edge unseen":
            return (
                f"{where}: the median-side road edge was not seen (out of the sensor's "
                "reach or hidden); the road's place there is bridged from where it was seen, "
                "or at a run's end held at the offset from the trajectory it had there"
                + self._width_note()
            )
        if self.kind == "outer edge unseen":
            return (
                f"{where}: the outer road edge was not seen (out of the sensor's reach or "
                "hidden); it is bridged from where it was seen" + self._width_note()
            )
        if self.kind == "reference line":
            return (
                f"{where}: the mainline turns with a {self.value_m:.0f} m radius, tighter "
                "than a motorway or trunk road can: its reference line is poorly determined "
                "(the median-side edge points there were another road's, or too few)"
            )
        if self.kind == "lane width":
            return f"{where}: a driving lane is {self.value_m:.1f} m wide (a lane missed?)"
        if self.kind == "lane markings":
            return (
                f"{where}: {100 * self.fraction:.0f} % of the lane samples lie along "
                f"t={self.value_m:+.1f} m, off every lane boundary of the map (a marking "
                "missed?)"
            )
        return (
            f"{where}: the {self.kind} is poorly determined (the measured edge lies "
            f"{self.value_m:+.2f} m from it)"
        )

    def _width_note(self) -> str:
        if np.isnan(self.value_m):
            return (
                "; the marking next to it was not measured either: a lane there may be "
                "missed or the road's width there is a guess"
            )
        if self.value_m < _UNSEEN_WIDTH_M:
            return ""
        return (
            f"; its distance to the marking next to it changes by {self.value_m:.1f} m "
            "there, so where the lanes begin, end or taper is inferred, not measured"
        )


# unseen edges (:func:`unseen_edges`); metres unless said otherwise
_SEEN_RADIUS_M = 2.5  # a station is seen with _SEEN_POINTS edge points this near it: stray
_SEEN_POINTS = 3  # points (outliers, a ramp's edge crossing) do not end an unseen stretch
_UNSEEN_CHANGE_M = 50.0  # an edge unseen over this long is reported where the line next to
_UNSEEN_WIDTH_M = 1.0  # it moves this much closer or farther, or was not measured:
_ADJACENT_MEASURED = 0.9  # near less than this share of the stretch's stations
_UNSEEN_END_M = 100.0  # a median-side edge unseen this long at a run's end is reported
_SHOULDER_BIN_M = 10.0  # a line is measured near a station with _SHOULDER_NTH samples on
_SHOULDER_NTH = 3  # it in a bin of this length within _SHOULDER_REACH bins (a dash cycle
_SHOULDER_REACH = 3  # and a worn stretch)
_SAME_LINE_M = 0.05  # a boundary this near the edge is the edge (a lane of zero width)


def _bins(length: float, step: float) -> FloatArray:
    return np.arange(0.0, length + step, step)


def poorly_determined(
    road: Road, run: MappingRun, *, config: MainlineConfig | None = None
) -> tuple[Stretch, ...]:
    """Stretches of ``road`` where the run's points disagree with it.

    Per bin of ``quality_bin_m`` along the station: the median signed offset of the
    road-edge points from the reference edge and from the outer edge they are nearest to
    (flagged beyond ``quality_edge_bias_m``), and lane samples farther than
    ``quality_marking_m`` from every lane boundary that line up at one offset over two
    bins or more (a marking the map lacks, at least ``quality_min_marking_samples`` per
    bin); edge bins need ``quality_min_points`` points.
    Driving lanes wider than ``quality_max_lane_m`` are flagged too, edges unseen where
    the line next to them does not pin them (:func:`unseen_edges`) and a reference line
    turning tighter than ``quality_min_radius_m`` (:func:`tight_turns`). Neighbouring
    flagged bins merge into one stretch.
    """
    cfg = config or MainlineConfig()
    edges = _bins(road.length, cfg.quality_bin_m)
    res = point_residuals(road, run)
    out: list[Stretch] = []

    def add(flags: np.ndarray, values: np.ndarray, fractions: np.ndarray, kind: str) -> None:
        for a, b in true_runs(flags):
            k = a + int(np.argmax(np.abs(np.nan_to_num(values[a:b]))))
            s0, s1 = float(edges[a]), float(min(edges[b], road.length))
            out.append(Stretch(s0, s1, kind, float(values[k]), float(fractions[k])))

    n_bins = edges.size - 1
    edge = res["road_edge"]
    for row, kind in ((0, "reference edge"), (1, "outer edge")):
        sel = edge.boundary == row
        idx = np.clip(np.searchsorted(edges, edge.s[sel], side="right") - 1, 0, n_bins - 1)
        err = edge.error[sel]
        med = np.full(n_bins, np.nan)
        frac = np.zeros(n_bins)
        order = np.argsort(idx, kind="stable")
        bounds = np.searchsorted(idx[order], np.arange(n_bins + 1))
        for j in np.flatnonzero(np.diff(bounds) >= cfg.quality_min_points):
            e = err[order[bounds[j] : bounds[j + 1]]]
            med[j] = float(np.median(e))
            frac[j] = float(np.mean(np.abs(e) > cfg.quality_edge_bias_m))
        add(np.abs(np.nan_to_num(med)) > cfg.quality_edge_bias_m, med, frac, kind)
    out += unseen_edges(road, edge, res["lane_boundary"], marking_m=cfg.quality_marking_m)
    lane = res["lane_boundary"]
    if lane.s.size:
        conc, share = _unexplained_markings(lane, edges, cfg)
        # one bin can be a ramp line crossing the corridor near a gore; a missed marking
        # runs on (two bins or more)
        flags = np.isfinite(conc)
        runs = [(a, b) for a, b in true_runs(flags) if b - a >= 2]
        keep = np.zeros(n_bins, dtype=bool)
        for a, b in runs:
            keep[a:b] = True
        add(keep, conc, share, "lane markings")
    widest = _widest_driving_lane(road, edges)
    add(widest > cfg.quality_max_lane_m, widest, np.zeros(n_bins), "lane width")
    out += tight_turns(road, cfg.quality_min_radius_m)
    return tuple(sorted(out, key=lambda x: (x.s0_m, x.kind)))


def unseen_edges(
    road: Road,
    edge_points: PointResiduals,
    lane_samples: PointResiduals,
    *,
    marking_m: float = 0.3,
) -> list[Stretch]:
    """Stretches where a road edge was not seen and the map there is a guess.

    Over such a stretch nothing measured the edge: the reference line is bridged from
    where the median-side edge was seen (placed by the trajectory alone), the outer edge
    from its seen ends. Where the lane boundary next to the edge was measured and the edge
    keeps its distance to it (a shoulder of steady width beside its line; a lane opening
    at the edge with its line seen) the bridge follows a measured line. Reported are the
    stretches of 50 m or more where that distance changes by 1 m or more (a lane ending
    or beginning at the edge, a gore, unseen) or the line next to the edge was not
    measured either (out of reach: a lane may hide between the edge and the nearest line
    that was); and a median-side edge unseen over 100 m or more at a run's end, where the
    reference line is held at the trajectory's offset, not bridged.

    Parameters
    ----------
    road
        The built mainline road.
    edge_points, lane_samples
        Residuals of the road-edge points and the lane samples inside the corridor
        (:func:`~._common.point_residuals`): stations, offsets t (metres, road frame),
        and for edge points the edge each is nearest to (0 reference, 1 outer).
    marking_m
        Lane samples nearer than this (metres) to a built lane boundary are measurements
        of it.

    Returns
    -------
    Stretches of kind ``"reference edge unseen"`` / ``"outer edge unseen"``, their value
    the change (metres) of the distance from the edge to the line next to it over the
    stretch (NaN where that line was not measured).
    """
    grid = np.arange(0.0, road.length + 1.0, 1.0)
    grid[-1] = min(grid[-1], road.length)
    lines = _border_matrix(road, grid, edges=False)
    # the two edges: the reference line (row 0) and the outermost lane's border (the last
    # row each station has; none on a section without lanes)
    n_rows = np.count_nonzero(np.isfinite(lines), axis=0)
    outer = lines[np.maximum(n_rows - 1, 0), np.arange(grid.size)]
    both = np.stack([lines[0], np.where(n_rows > 1, outer, np.nan)])
    measured = np.abs(lane_samples.error) < marking_m
    s_lane, row_lane = lane_samples.s[measured], lane_samples.boundary[measured]
    out: list[Stretch] = []
    for k, kind in ((0, "reference edge unseen"), (1, "outer edge unseen")):
        s_k = np.sort(edge_points.s[edge_points.boundary == k])
        near = np.searchsorted(s_k, grid + _SEEN_RADIUS_M, side="right") - np.searchsorted(
            s_k, grid - _SEEN_RADIUS_M, side="left"
        )
        for a, b in true_runs(near < _SEEN_POINTS):
            s0, s1 = float(grid[a]), float(grid[b - 1])
            if s1 - s0 < _UNSEEN_CHANGE_M:
                continue
            change = _adjacent_line_change(both[k, a:b], lines[:, a:b], s_lane, row_lane, (s0, s1))
            # at a run's end the reference line is held at the offset from the trajectory
            # it had where the edge was last seen, not bridged between two seen ends
            held = k == 0 and (a == 0 or b == grid.size) and s1 - s0 >= _UNSEEN_END_M
            if held or not change < _UNSEEN_WIDTH_M:  # NaN: the line next to it unmeasured
                out.append(Stretch(s0, s1, kind, change, 1.0))
    return out


def tight_turns(road: Road, min_radius_m: float) -> list[Stretch]:
    """Stretches where the road's reference line turns tighter than ``min_radius_m``
    (metres; :func:`~._common.tight_turn_runs`). Kind ``"reference line"``, value the
    tightest radius (metres)."""
    if road.length < 2.0 * TURN_WINDOW_M:
        return []
    s = np.arange(0.0, road.length, 1.0)
    runs, radius = tight_turn_runs(np.unwrap(road.heading(s)), min_radius_m)
    out = []
    for a, b in runs:
        worst = float(np.min(radius[a : max(min(b, radius.size), a + 1)]))
        out.append(Stretch(float(s[a]), float(s[b - 1]), "reference line", worst, 1.0))
    return out


def _adjacent_line_change(
    edge_t: FloatArray,
    lines_t: FloatArray,
    s_lane: FloatArray,
    row_lane: NDArray[np.int64],
    span: tuple[float, float],
) -> float:
    """Over an unseen stretch of an edge: how much (metres) the distance from the edge to
    the lane boundary next to it changes where that boundary was measured; NaN where it
    was not measured at ``_ADJACENT_MEASURED`` of the stretch's stations (then a lane may
    hide between the edge and the nearest line that was).

    A boundary is measured near a station with ``_SHOULDER_NTH`` lane samples on it in a
    bin of ``_SHOULDER_BIN_M`` within ``_SHOULDER_REACH`` bins of the station's (a lane
    opening at the edge with its line seen hands the adjacent line over to the new one
    without a jump). ``edge_t`` are the edge's offsets (metres) on the stretch's 1 m
    grid, ``lines_t`` every boundary's (rows of :func:`~._common._border_matrix`, NaN
    where a row is no lane's); ``s_lane``, ``row_lane`` the stations and nearest rows of
    the measured lane samples.
    """
    s0, s1 = span
    n_bins = max(round((s1 - s0) / _SHOULDER_BIN_M), 1)

    def bin_of(s: FloatArray) -> NDArray[np.int64]:
        return np.clip(((s - s0) / (s1 - s0 + 1e-9) * n_bins).astype(int), 0, n_bins - 1)

    inside = (s_lane >= s0) & (s_lane <= s1)
    counts = np.zeros((lines_t.shape[0], n_bins))
    np.add.at(counts, (row_lane[inside], bin_of(s_lane[inside])), 1.0)
    # a line measured within _SHOULDER_REACH bins of a station (its dashes, a worn
    # stretch) is followed there
    on = maximum_filter1d(counts >= _SHOULDER_NTH, size=2 * _SHOULDER_REACH + 1, axis=1)
    on = on[:, bin_of(np.linspace(s0, s1, edge_t.size))]
    # the line next to the edge (a lane of zero width, the edge's own row left out): with
    # it measured nothing can hide between it and the edge
    apart = np.abs(edge_t[None, :] - lines_t)
    apart[~(apart > _SAME_LINE_M)] = np.inf
    adjacent = np.argmin(apart, axis=0)
    cols = np.arange(edge_t.size)
    ok = np.isfinite(apart[adjacent, cols]) & on[adjacent, cols]
    if np.mean(ok) < _ADJACENT_MEASURED:
        return math.nan
    return float(np.ptp(apart[adjacent, cols][ok]))


def _unexplained_markings(lane, edges: FloatArray, cfg: MainlineConfig):
    """Per bin: the lateral offset (metres) where the lane samples that lie off every lane
    boundary concentrate (NaN where they do not: scattered false positives, a ramp line
    crossing at an angle), and their share of the bin's samples."""
    n_bins = edges.size - 1
    idx = np.clip(np.searchsorted(edges, lane.s, side="right") - 1, 0, n_bins - 1)
    far = np.abs(lane.error) > cfg.quality_marking_m
    count = np.bincount(idx, minlength=n_bins)
    conc = np.full(n_bins, np.nan)
    share = np.zeros(n_bins)
    fi, ft = idx[far], lane.t[far]
    if fi.size == 0:
        return conc, share
    # 0.25 m lateral cells of the far samples, counted per bin
    cell = np.floor(ft / 0.25).astype(np.int64)
    cell -= cell.min()
    n_cell = int(cell.max()) + 2
    grid = np.zeros((n_bins, n_cell))
    np.add.at(grid, (fi, cell), 1.0)
    pair = grid[:, :-1] + grid[:, 1:]  # a marking's samples spread over two cells
    best = pair.max(axis=1)
    n_far = np.bincount(fi, minlength=n_bins)
    ok = (best >= cfg.quality_min_marking_samples) & (best >= 0.5 * n_far)
    t_best = (np.argmax(pair, axis=1) + 1) * 0.25 + np.floor(ft.min() / 0.25) * 0.25
    conc[ok] = t_best[ok]
    share[ok] = best[ok] / np.maximum(count[ok], 1)
    return conc, share


def _widest_driving_lane(road: Road, edges: FloatArray) -> FloatArray:
    """Width of the widest driving lane in each bin (metres, sampled every metre)."""
    s = np.arange(0.0, road.length, 1.0)
    widest = np.zeros(s.size)
    sec_idx = road.section_index(s)
    for k in np.unique(sec_idx):
        sec = road.lane_sections[int(k)]
        sel = sec_idx == k
        for lane in (*sec.left, *sec.right):
            if lane.type == "driving":
                widest[sel] = np.maximum(widest[sel], lane.width.value(s[sel] - sec.s0))
    n_bins = edges.size - 1
    idx = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, n_bins - 1)
    out = np.zeros(n_bins)
    np.maximum.at(out, idx, widest)
    return out
