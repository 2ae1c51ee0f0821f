"""Several mapping runs -> carriageways: common frame, grouping, fusion with a
consistency check.

A campaign drives each direction of a highway, often more than once, sometimes in parts
that continue each other. This module

1. moves every run into one mapping frame (:func:`run_in_frame`: pyproj through WGS84,
   heights through each frame's altitude offset, yaw turned with the grid);
2. groups the runs (:func:`group_runs`): runs whose paths share a stretch in the same
   direction, or whose one starts where another ends, drive the same carriageway; a
   group that shares a stretch with another in the opposite direction is the other
   carriageway of the same highway;
3. fuses each group into one :class:`~roadtwin.io.MappingRun` (:func:`fuse_runs`): every
   run's edge points and lane samples; one path for the Frenet frame (the first run's
   poses, extended by the poses of the runs that continue it); before that, overlapping
   runs are compared stretch by stretch (:func:`check_consistency`): where their road
   edges disagree by more than their noise, the disagreement is reported with its station
   and only one run's points are kept there (averaging two positions of one edge would
   invent a road in between, or a second marking).

The fused run goes through the single-run pipeline unchanged (one reference line and one
lane structure from all points). Each run's own poses stay in :attr:`FusedRun.runs`.

All coordinates are in the first run's mapping frame (metres); stations are metres along
the fused path.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .._errors import InputError
from ..config import HighwayConfig
from ..fitting import (
    PolylineFrame,
    binned_statistics,
    resample_polyline,
    savgol_smooth,
    whittaker_smooth,
)
from ..inputs import run_in_frame
from ..io import MappingRun, Trajectory
from ..osm_roads.chains import shared_length_m

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

__all__ = [
    "Disagreement",
    "FusedRun",
    "RunGroups",
    "check_consistency",
    "fuse_runs",
    "group_runs",
    "run_in_frame",
]

_SAMPLE_STEP_M = 5.0  # path samples used to relate runs
_MAX_RESIDUAL_M = 0.5  # edge points farther off the common fit are other levels/outliers


# ---------------------------------------------------------------------------
# one frame
# ---------------------------------------------------------------------------


# ---------------------------------------------------------------------------
# grouping
# ---------------------------------------------------------------------------


def _continues(a: FloatArray, b: FloatArray, *, gap_m: float) -> bool:
    """Path ``b`` starts within ``gap_m`` of path ``a``'s end in ``a``'s direction."""
    if a.shape[0] < 2 or b.shape[0] < 2:
        return False
    ha = np.arctan2(*(a[-1] - a[-2])[::-1])
    hb = np.arctan2(*(b[1] - b[0])[::-1])
    turn = abs((hb - ha + np.pi) % (2 * np.pi) - np.pi)
    return bool(np.hypot(*(b[0] - a[-1])) <= gap_m and turn < 0.25 * np.pi)


@dataclass(frozen=True)
class RunGroups:
    """Runs grouped by carriageway.

    Attributes
    ----------
    carriageways : per carriageway the indices of its runs (into the given runs), the
        first run first, then the others in input order.
    opposite : ``(i, j)`` pairs of carriageway indices that are the two directions of one
        highway (``i < j``).
    """

    carriageways: tuple[tuple[int, ...], ...]
    opposite: tuple[tuple[int, int], ...] = ()

    def partner(self, k: int) -> int | None:
        """The carriageway of the other direction of carriageway ``k``, or None."""
        for i, j in self.opposite:
            if k in (i, j):
                return j if k == i else i
        return None


def group_runs(runs: list[MappingRun], *, config: HighwayConfig | None = None) -> RunGroups:
    """Group runs (all in one frame) by the carriageway they drove.

    Two runs share a carriageway where at least ``min_overlap_m`` of their paths lie
    within ``same_carriageway_m`` with the same heading, or where one starts within
    ``join_gap_m`` of the other's end (it continues it). Carriageways whose paths share
    ``min_overlap_m`` within ``opposite_carriageway_m`` in opposite directions are the two
    directions of one highway.
    """
    cfg = config or HighwayConfig()
    paths = [resample_polyline(r.trajectory.xy, _SAMPLE_STEP_M) for r in runs]
    n = len(runs)
    parent = list(range(n))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            if runs[i].traffic_side != runs[j].traffic_side:
                continue
            same = max(
                shared_length_m(
                    paths[i], paths[j], distance_m=cfg.same_carriageway_m, opposite=False
                ),
                shared_length_m(
                    paths[j], paths[i], distance_m=cfg.same_carriageway_m, opposite=False
                ),
            )
            joined = _continues(paths[i], paths[j], gap_m=cfg.join_gap_m) or _continues(
                paths[j], paths[i], gap_m=cfg.join_gap_m
            )
            if same >= cfg.min_overlap_m or joined:
                parent[root(j)] = root(i)
    members: dict[int, list[int]] = {}
    for i in range(n):
        members.setdefault(root(i), []).append(i)
    groups = tuple(tuple(sorted(m)) for m in sorted(members.values(), key=min))
    pairs = []
    for a in range(len(groups)):
        for b in range(a + 1, len(groups)):
            shared = max(
                shared_length_m(
                    paths[i], paths[j], distance_m=cfg.opposite_carriageway_m, opposite=True
                )
                for i in groups[a]
                for j in groups[b]
            )
            if shared >= cfg.min_overlap_m:
                pairs.append((a, b))
    return RunGroups(groups, tuple(pairs))


# ---------------------------------------------------------------------------
# the fused path
# ---------------------------------------------------------------------------


def _spine(runs: list[MappingRun]) -> tuple[FloatArray, list[tuple[int, int, int]]]:
    """One path through the runs of a carriageway: the first run's poses, extended at its
    ends by the poses of the runs that reach beyond them. Returns ``(N, 3)`` poses and,
    per piece, ``(run index, first pose, stop pose)``."""
    pieces: list[tuple[int, int, int]] = [(0, 0, runs[0].trajectory.xyz.shape[0])]
    xyz = runs[0].trajectory.xyz
    for k in range(1, len(runs)):
        frame = PolylineFrame.from_points(resample_polyline(xyz[:, :2], 1.0))
        s, _ = frame.project(runs[k].trajectory.xy)
        after = np.flatnonzero(s > frame.length + 1.0)
        before = np.flatnonzero(s < -1.0)
        own = runs[k].trajectory.xyz
        if after.size:  # a contiguous tail of run k lies beyond the end
            first = int(after[0])
            tail = np.arange(first, own.shape[0])
            tail = tail[s[tail] > frame.length + 1.0]
            if tail.size:
                xyz = np.vstack([xyz, own[tail]])
                pieces.append((k, int(tail[0]), int(tail[-1]) + 1))
        if before.size:
            head = np.arange(0, int(before[-1]) + 1)
            head = head[s[head] < -1.0]
            if head.size:
                xyz = np.vstack([own[head], xyz])
                pieces.insert(0, (k, int(head[0]), int(head[-1]) + 1))
    return xyz, pieces


def _frame_of(xyz: FloatArray) -> PolylineFrame:
    """Frenet frame of a smoothed path (1 m resampling, 31 m Savitzky-Golay)."""
    xy = resample_polyline(xyz[:, :2], 1.0)
    if xy.shape[0] >= 31:
        xy = savgol_smooth(xy, window=31, polyorder=3)
    return PolylineFrame.from_points(xy)


# ---------------------------------------------------------------------------
# consistency of overlapping runs
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Disagreement:
    """Overlapping runs that disagree on a stretch.

    Attributes
    ----------
    runs : names of the two runs (folder names).
    edge : ``"median-side edge"`` or ``"outer edge"``.
    s0_m, s1_m : the stretch, metres along the fused path.
    offset_m : how far their edges lie apart there (median over the stretch, metres).
    noise_m : the difference their noise explains (standard error, metres).
    kept : the run whose points build the stretch (the others' are left out there).
    """

    runs: tuple[str, str]
    edge: str
    s0_m: float
    s1_m: float
    offset_m: float
    noise_m: float
    kept: str

    def message(self) -> str:
        a, b = self.runs
        return (
            f"runs {a} and {b} disagree on the {self.edge} at s={self.s0_m:.0f}-"
            f"{self.s1_m:.0f} m by {self.offset_m:.2f} m (their noise explains "
            f"{self.noise_m:.2f} m): built from run {self.kept} alone there"
        )


def _edge_residuals(
    frame: PolylineFrame, runs: list[MappingRun], side: int
) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """Stations, residuals against a common smooth fit, and run index of the edge points
    of one side (+1 left, -1 right) of every run."""
    s_l, t_l, k_l = [], [], []
    for k, run in enumerate(runs):
        pts = run.edges[run.edge_side == side]
        s, t = frame.project(pts)
        ok = (s >= 0.0) & (s <= frame.length)
        s_l.append(s[ok])
        t_l.append(t[ok])
        k_l.append(np.full(int(ok.sum()), k))
    s = np.concatenate(s_l)
    t = np.concatenate(t_l)
    k = np.concatenate(k_l).astype(np.int64)
    if s.size < 10:
        return s, np.full(s.size, np.nan), k
    edges = np.arange(0.0, frame.length + 1.0, 1.0)
    med, _, count = binned_statistics(s, t, edges)
    fit = whittaker_smooth(np.nan_to_num(med), (count > 0).astype(float), lam=1e4)
    b = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, fit.size - 1)
    return s, t - fit[b], k


def check_consistency(
    frame: PolylineFrame,
    runs: list[MappingRun],
    *,
    traffic_side: str = "right",
    config: HighwayConfig | None = None,
) -> list[Disagreement]:
    """Compare overlapping runs stretch by stretch on both road edges.

    Per stretch of ``consistency_bin_m`` along ``frame`` and per run: the median residual
    of its edge points against a smooth fit of all runs' points (points more than 0.5 m
    off are other levels or outliers), its robust spread and count. Two runs disagree
    where their medians differ by more than ``disagree_sigmas`` standard errors (points'
    spread over their count, plus ``pose_sigma_m`` per run) and by more than
    ``min_disagreement_m``; consecutive stretches merge. The run kept there is the one
    nearest to the median of all runs present there; of two runs alone, the earlier one.
    """
    cfg = config or HighwayConfig()
    out: list[Disagreement] = []
    names = [run_name(r, i) for i, r in enumerate(runs)]
    bins = np.arange(0.0, frame.length + cfg.consistency_bin_m, cfg.consistency_bin_m)
    nb = bins.size - 1
    median_side = 1 if traffic_side == "right" else -1
    for side, label in ((median_side, "median-side edge"), (-median_side, "outer edge")):
        s, r, k = _edge_residuals(frame, runs, side)
        good = np.isfinite(r) & (np.abs(r) <= _MAX_RESIDUAL_M)
        if not np.any(good):
            continue
        med = np.full((len(runs), nb), np.nan)
        se = np.full((len(runs), nb), np.inf)
        for j in range(len(runs)):
            sel = good & (k == j)
            m, _, n = binned_statistics(s[sel], r[sel], bins)
            mad, _, _ = binned_statistics(
                s[sel], np.abs(r[sel] - m[np.clip(np.searchsorted(bins, s[sel]) - 1, 0, nb - 1)]),
                bins,
            )  # fmt: skip
            enough = n >= cfg.min_bin_points
            med[j, enough] = m[enough]
            se[j, enough] = 1.4826 * mad[enough] / np.sqrt(n[enough])
        seen = np.isfinite(med)
        centre = np.full(nb, np.nan)
        some = seen.any(axis=0)
        centre[some] = np.nanmedian(med[:, some], axis=0)
        for a in range(len(runs)):
            for b in range(a + 1, len(runs)):
                both = np.isfinite(med[a]) & np.isfinite(med[b])
                diff = np.abs(med[a] - med[b])
                noise = np.sqrt(se[a] ** 2 + se[b] ** 2 + 2.0 * cfg.pose_sigma_m**2)
                limit = np.maximum(cfg.disagree_sigmas * noise, cfg.min_disagreement_m)
                bad = both & (diff > limit)
                for lo, hi in _stretches(bad):
                    sel = slice(lo, hi)
                    present = int(np.count_nonzero(np.isfinite(med[:, sel]).any(axis=1)))
                    da = np.nanmedian(np.abs(med[a, sel] - centre[sel]))
                    db = np.nanmedian(np.abs(med[b, sel] - centre[sel]))
                    # two runs alone cannot say which is right: the earlier one (the
                    # reference frame's run) is kept; with more, the one nearer the rest
                    kept = names[a] if present <= 2 or da <= db else names[b]
                    out.append(
                        Disagreement(
                            (names[a], names[b]),
                            label,
                            float(bins[lo]),
                            float(bins[hi]),
                            float(np.nanmedian(diff[sel])),
                            float(np.nanmedian(noise[sel])),
                            kept,
                        )
                    )
    return out


def _stretches(flags: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """``[lo, hi)`` index ranges of runs of True (a single False between two merges)."""
    idx = np.flatnonzero(flags)
    if idx.size == 0:
        return []
    out = []
    lo = prev = int(idx[0])
    for i in idx[1:].tolist():
        if i > prev + 2:
            out.append((lo, prev + 1))
            lo = i
        prev = i
    out.append((lo, prev + 1))
    return out


# ---------------------------------------------------------------------------
# fusion
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class FusedRun:
    """Runs of one carriageway fused into one run.

    Attributes
    ----------
    run : the fused run (first run's frame, root and OSM file; every run's points; one
        path for the Frenet frame: the first run's poses extended by the runs continuing
        it).
    runs : every run in that frame, with its own poses.
    path_pieces : ``(run name, first pose, stop pose)`` of the pieces of the fused path.
    disagreements : stretches where overlapping runs disagreed.
    dropped_points : edge points and lane samples left out because of a disagreement.
    """

    run: MappingRun
    runs: tuple[MappingRun, ...]
    path_pieces: tuple[tuple[str, int, int], ...] = ()
    disagreements: tuple[Disagreement, ...] = ()
    dropped_points: int = 0

    @property
    def warnings(self) -> tuple[str, ...]:
        """One line per disagreement."""
        return tuple(d.message() for d in self.disagreements)


def _points_outside(
    frame: PolylineFrame, pts: FloatArray, stretches: list[tuple[float, float]]
) -> NDArray[np.bool_]:
    """True for points whose station lies outside every ``(s0, s1)`` stretch."""
    keep = np.ones(pts.shape[0], dtype=bool)
    if not stretches or pts.shape[0] == 0:
        return keep
    s, _ = frame.project(pts)
    for s0, s1 in stretches:
        keep &= ~((s >= s0) & (s <= s1))
    return keep


def fuse_runs(runs: list[MappingRun], *, config: HighwayConfig | None = None) -> FusedRun:
    """Fuse the runs of one carriageway (same frame, same direction; the first is the
    reference) into one run.

    Raises
    ------
    InputError
        Runs of different traffic sides, or no run.
    """
    cfg = config or HighwayConfig()
    if not runs:
        raise InputError("fuse_runs: no run given")
    if len({r.traffic_side for r in runs}) > 1:
        msg = "runs of one carriageway have different [traffic] sides"
        raise InputError(msg)
    if len(runs) == 1:
        return FusedRun(runs[0], (runs[0],))
    xyz, pieces = _spine(runs)
    frame = _frame_of(xyz)
    disagreements = check_consistency(frame, runs, traffic_side=runs[0].traffic_side, config=cfg)
    names = [run_name(r, i) for i, r in enumerate(runs)]
    edges, sides, lanes, lane_frames = [], [], [], []
    dropped = 0
    frame_offset = 0
    for j, run in enumerate(runs):
        away = [
            (d.s0_m, d.s1_m) for d in disagreements if names[j] in d.runs and d.kept != names[j]
        ]
        keep_e = _points_outside(frame, run.edges, away)
        keep_l = _points_outside(frame, run.lane_samples, away)
        dropped += int((~keep_e).sum() + (~keep_l).sum())
        edges.append(run.edges[keep_e])
        sides.append(run.edge_side[keep_e])
        lanes.append(run.lane_samples[keep_l])
        # frame numbers of later runs are shifted so they stay unique
        lane_frames.append(run.lane_sample_frame[keep_l] + frame_offset)
        frame_offset += int(run.trajectory.frame.max()) + 1
    n = xyz.shape[0]
    d = np.gradient(xyz[:, :2], axis=0) if n > 1 else np.zeros((n, 2))
    trajectory = Trajectory(
        frame=np.arange(n, dtype=np.int64),
        t=np.arange(n, dtype=float) * 0.1,
        xyz=xyz,
        yaw=np.unwrap(np.arctan2(d[:, 1], d[:, 0])),
        pitch=np.zeros(n),
        roll=np.zeros(n),
    )
    first = runs[0]
    fused = replace(
        first,
        trajectory=trajectory,
        edges=np.vstack(edges),
        edge_side=np.concatenate(sides),
        lane_samples=np.vstack(lanes),
        lane_sample_frame=np.concatenate(lane_frames),
        osm_path=next((r.osm_path for r in runs if r.osm_path is not None), None),
        dropped_edge_points=sum(r.dropped_edge_points for r in runs),
        dropped_lane_samples=sum(r.dropped_lane_samples for r in runs),
        input_files=tuple(dict.fromkeys(f for r in runs for f in r.input_files)),
    )
    log.info(
        "fused %d runs (%s): %d edge points, %d lane samples, %d disagreements",
        len(runs),
        ", ".join(names),
        fused.edges.shape[0],
        fused.lane_samples.shape[0],
        len(disagreements),
    )
    return FusedRun(
        fused,
        tuple(runs),
        tuple((names[k], a, b) for k, a, b in pieces),
        tuple(disagreements),
        dropped,
    )


def run_name(run: MappingRun, index: int = 0) -> str:
    """A run's name for messages: its folder name."""
    return run.root.name if isinstance(run.root, Path) else f"run {index}"
