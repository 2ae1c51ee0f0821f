"""Where the built mainline disagrees with its own evidence: stretch warnings.

A map can pass every validity check and still be metres off where its inference went
wrong (a marking bridged across a narrowing road, an edge pulled by a ramp). The points
the map was built from say so: along such a stretch the road-edge points lie off the
built edge on one side, or many lane samples lie far from every built lane boundary. This
module bins the residuals of the points (:func:`~._common.point_residuals`) along the
station and reports every stretch where they disagree, and every driving lane wider than
a lane can be, so that the build warns with the station instead of saying "OK".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import MainlineConfig
from ..io import MappingRun
from ..model import Road
from ._common import FloatArray, point_residuals, true_runs


@dataclass(frozen=True)
class Stretch:
    """A stretch of the mainline whose evidence disagrees with the map.

    Attributes
    ----------
    s0_m, s1_m : station range (metres along the mainline road).
    kind : ``"reference edge"``, ``"outer edge"``, ``"lane markings"``, ``"lane width"`` or
        ``"reference edge unseen"`` (no median-side edge point over 100 m or more).
    value_m : the worst bin's figure: median signed edge offset of the points from the
        built edge (edges), lateral offset t where unexplained lane samples line up
        (markings) or the widest lane (lane width), metres.
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


_UNSEEN_M = 100.0  # a stretch this long without median-side edge points is reported


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
    Driving lanes wider than ``quality_max_lane_m`` are flagged too. Neighbouring flagged
    bins merge into one stretch.
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
        if row == 0:
            # the reference line is the median-side edge: where none of it was seen over
            # 100 m or more, nothing but the trajectory placed the road
            unseen = np.bincount(idx, minlength=n_bins) == 0
            long = np.zeros(n_bins, dtype=bool)
            for a, b in true_runs(unseen):
                long[a:b] = (b - a) * cfg.quality_bin_m >= _UNSEEN_M
            add(long, np.full(n_bins, np.nan), np.ones(n_bins), "reference edge unseen")
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
    return tuple(sorted(out, key=lambda x: (x.s0_m, x.kind)))


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
