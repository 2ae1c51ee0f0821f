"""Default method: reference edge, elevation, and the assembly of the road."""

from __future__ import annotations

import functools
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import median_filter, percentile_filter

from .._errors import InputError
from ..config import MainlineConfig
from ..fitting import (
    PolylineFrame,
    arc_length,
    fit_cubic_profile,
    fit_parampoly3_chain,
    resample_polyline,
    whittaker_smooth,
)
from ..io import MappingRun
from ..model import (
    CubicPiece,
    CubicProfile,
    LaneSection,
    Road,
)
from ._common import (
    TURN_WINDOW_M,
    BoundaryTrack,
    _grid,
    _lam,
    _Partial,
    _road_frame,
    _sign,
    _split_edges,
    _trajectory_frame,
    inner_line_points,
    road_surface_poses,
    robust_offset_fit,
    tight_turn_runs,
    true_runs,
)
from .edge_levels import EdgeSteps, edge_level_path, edge_steps
from .lanes import fit_lanes
from .median_gaps import edge_along_shoulder_line
from .median_moves import (
    edge_moves,
    moves_beside_steps,
    shoulder_moves,
    unseen_stretches,
    with_edge_moves,
)
from .seal import nonnegative_widths, seal_lane_borders

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


def _build_default(run: MappingRun, cfg: MainlineConfig, timings: dict[str, float]) -> _Partial:
    sign = _sign(run)
    t0 = time.perf_counter()
    traj = _trajectory_frame(run)
    ref_pts, outer_pts = _split_edges(run, traj)
    if ref_pts.shape[0] < 10:
        side = "left" if sign > 0 else "right"
        msg = f"mainline: only {ref_pts.shape[0]} {side} (median-side) road-edge points"
        raise InputError(msg)
    timings["frame"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    median = fit_median_edge(
        ref_pts, traj, config=cfg, outer_pts=outer_pts, lane_pts=run.lane_samples
    )
    median = _without_knots(median, ref_pts, traj, cfg, outer_pts, run.lane_samples)
    geometry = fit_parampoly3_chain(median.xy, tolerance_m=cfg.fit_tolerance_m)
    timings["reference_line"] = time.perf_counter() - t0

    base = Road("1", geometry, (LaneSection(0.0),), name="mainline")
    # heights from the trajectory: points of a road the run passes over or under go to
    # the stations at their own level
    heights = None if median.z is None else (arc_length(median.xy), median.z)
    frame = _road_frame(base, heights=heights)
    length = base.length

    t0 = time.perf_counter()
    poses = road_surface_poses(run)
    s_out, t_out = frame.project(outer_pts)
    s_lane, t_lane = frame.project(run.lane_samples)
    s_car, t_car = frame.project(poses)
    order = np.argsort(s_car)

    def lanes(
        surface_scale: Callable[[FloatArray], FloatArray | float],
        move: tuple[FloatArray, FloatArray] | None = None,
    ):
        return fit_lanes(
            s_lane,
            -sign * t_lane * surface_scale(s_lane),
            s_out,
            -sign * t_out * surface_scale(s_out),
            length=length,
            sign=sign,
            config=cfg,
            car=(s_car[order], -sign * t_car[order] * surface_scale(s_car[order])),
            median=median.steps,
            median_move=move,
        )

    sections, events, tracks, used = lanes(lambda s: 1.0)
    # where the median-side edge is unseen it moves with the lines seen there (beside a
    # gore, along the inner shoulder's line): the lanes again, with the edge moved
    grid = np.minimum(_grid(0.0, length, cfg.grid_step_m), length)
    s_ref, t_ref = frame.project(ref_pts)
    move = _median_moves(s_ref, -sign * t_ref, median, tracks, grid, s_lane, -sign * t_lane)
    if move is not None:
        sections, events, tracks, used = lanes(lambda s: 1.0, move)
    timings["lanes"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    on_edge = _on_median_edge(ref_pts, s_ref, t_ref, median.steps, sign)
    surface_pts = np.vstack([on_edge, outer_pts[used]])
    elevation, superelevation = fit_elevation(frame, surface_pts, poses=poses, config=cfg)
    timings["elevation"] = time.perf_counter() - t0
    if superelevation is not None:
        # OpenDRIVE measures t along the rolled surface (t cos(roll) in plan): the lanes
        # are fitted again to the plan offsets divided by cos(roll), so that consumers
        # place every border where it was seen
        t0 = time.perf_counter()
        sections, events, tracks, _ = lanes(lambda s: 1.0 / np.cos(superelevation.value(s)), move)
        timings["lanes"] += time.perf_counter() - t0
    road = replace(
        base,
        elevation=elevation,
        superelevation=superelevation,
        lane_sections=sections,
        lane_offset=_lane_offset(median.steps, sign),
    )
    if move is not None:
        offset = with_edge_moves(road.lane_offset, grid, move[0], sign, move[1])
        road = replace(road, lane_offset=offset)
    road = _join_lanes_across_offset_steps(road, median.steps.stations)
    road = nonnegative_widths(seal_lane_borders(road))
    return _Partial(road, events, "default", tracks, _seen_stretches(np.sort(s_out[used])))


_SEEN_SPACING_M = 6.0  # edge points closer than this along the road are one seen stretch


def _seen_stretches(s_sorted: FloatArray) -> tuple[tuple[float, float], ...]:
    """Stretches (first and last station, metres) of sorted stations ``s_sorted`` of the
    outer-edge points used, split where consecutive points lie ``_SEEN_SPACING_M`` or
    more apart (an occlusion gap)."""
    if s_sorted.size == 0:
        return ()
    cut = np.flatnonzero(np.diff(s_sorted) >= _SEEN_SPACING_M)
    first = np.r_[0, cut + 1]
    last = np.r_[cut, s_sorted.size - 1]
    return tuple((float(s_sorted[a]), float(s_sorted[b])) for a, b in zip(first, last, strict=True))


def _median_moves(
    s_edge: FloatArray,
    d_edge: FloatArray,
    median: MedianEdge,
    tracks: tuple[BoundaryTrack, ...],
    grid: FloatArray,
    s_lane: FloatArray,
    d_lane: FloatArray,
) -> tuple[FloatArray, FloatArray] | None:
    """Where the median-side edge is unseen, how far it moves with the lines a first lane
    fit (``tracks``) found (:mod:`.median_moves`): beside a gore, across a stretch
    where the inner shoulder's line is seen through (away from gores and steps), and
    between a step and where the edge was seen along the lines seen there. The move
    on ``grid`` (metres towards the carriageway) and the gore stations where it begins or
    ends at full size; None where it moves nowhere. ``s_edge``, ``d_edge`` and ``s_lane``,
    ``d_lane``: the median-side edge points and the lane samples in the lanes' frame
    (metres)."""
    at_gores, gores = edge_moves(median.unseen_beside_gores, tracks, grid)
    d_median = -median.steps.at(grid) + at_gores
    step = float(grid[1] - grid[0])
    near_step = np.zeros(grid.size, dtype=bool)
    for st in median.steps.stations:
        near_step |= np.abs(grid - st) <= 10.0 * step
    unseen = [
        (a, b)
        for a, b in unseen_stretches(s_edge, d_edge, grid, d_median, _ON_EDGE_M)
        if not np.any(at_gores[a - 1 : b + 1])
    ]
    gaps = [(a, b) for a, b in unseen if not np.any(near_step[a - 1 : b + 1])]
    beside, ends = moves_beside_steps(
        [(a, b) for a, b in unseen if np.any(near_step[a - 1 : b + 1])],
        median.steps.stations,
        tracks,
        s_lane,
        d_lane,
        grid,
        d_median,
    )
    move = at_gores + beside + shoulder_moves(gaps, tracks, s_lane, d_lane, grid, d_median)
    gores = np.union1d(gores, ends)
    move = _from_gores(move, grid, gores)
    return (move, gores) if np.any(move) else None


def _from_gores(move: FloatArray, grid: FloatArray, gores: FloatArray) -> FloatArray:
    """``move`` (on ``grid``, metres) begun at the gore it begins next to and ended at the
    one it ends next to (within 1.5 grid steps): the unseen stretch it covers starts a
    station past the gore, where the lane sections change. Begun there, the lanes of the
    new section were fitted to the edge as it was for a metre and the lane offset stepped
    inside the section: every lane jumped 3.0 m sideways a metre past an inner exit's gore
    (krems-30799129-s11 with a noisier sensor, seed offset 380; esmini's car jumped
    1.3 m; the check's ``lane_jump``)."""
    if not gores.size or not np.any(move):
        return move
    step = float(grid[1] - grid[0]) if grid.size > 1 else 1.0
    out = move.copy()
    for a, b in true_runs(move != 0.0):
        near = gores[(gores < grid[a]) & (gores >= grid[a] - 1.5 * step)]
        if a > 0 and near.size:
            i = int(np.searchsorted(grid, float(near[0]) - 1e-9))
            out[i:a] = move[a]
        near = gores[(gores > grid[b - 1]) & (gores <= grid[b - 1] + 1.5 * step)]
        if b < grid.size and near.size:
            i = int(np.searchsorted(grid, float(near[-1]) - 1e-9))
            out[b:i] = move[b - 1]
    return out


_ON_EDGE_M = 0.8  # a median-side edge point this close to the fitted edge is the road's


def _on_median_edge(
    points: FloatArray, s: FloatArray, t: FloatArray, steps: EdgeSteps, sign: float
) -> FloatArray:
    """The median-side edge points (mapping frame, ``(N, 3)``) that lie on the fitted
    median-side edge (within ``_ON_EDGE_M`` of it sideways, the reference line moved by
    the edge's offset between its steps): the road's own edge, whose heights are the
    road's. Points beyond it (a ramp's or the other carriageway's edge, a median barrier)
    may lie metres higher or lower: their heights made a 0.1 rad cross slope out of a
    flat road (melbourne-408-opp-s4: the median-side points 2.5 m beyond the edge lay
    0.8-2 m lower, where an inner ramp fell away beside it). ``sign``: +1 right-hand
    traffic (the median on the left, t > 0), -1 left-hand traffic. ``s``, ``t``: the
    points' stations and offsets on the road (metres)."""
    return points[np.abs(sign * t - steps.at(s)) < _ON_EDGE_M]


@dataclass(frozen=True)
class MedianEdge:
    """The median-side road edge: a smooth reference line and the steps of the edge.

    Attributes
    ----------
    xy : ``(G, 2)`` the reference line (mapping frame, ~1 m spacing): the median-side edge
        at the level the longest stretch of the road has, continued smoothly through
        stretches where the edge lies elsewhere.
    steps : stations (along ``xy``) where the median-side edge steps (a gore on the median
        side: lanes beginning or ending at full width there) and, per segment, how far
        the edge lies from the reference line (metres, towards the median): the lane
        offset of the centre lane.
    z : ``(G,)`` height of the road surface under the car beside each point of ``xy``
        (mapping frame, metres; from the trajectory), or None.
    unseen_beside_gores : ``(k, 2)`` rows of (gore station, station where the edge is
        seen again), metres along ``xy``: a ramp's edge peeled off (joined) on the median
        side and the road's own edge is unseen after (before) the gore for at least
        ``_UNSEEN_GORE_M`` (:mod:`.median_moves`).
    """

    xy: FloatArray
    steps: EdgeSteps
    z: FloatArray | None = None
    unseen_beside_gores: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))


def _lane_offset(steps: EdgeSteps, sign: float) -> CubicProfile:
    """The centre lane's offset (metres, t left positive): zero where the median-side edge
    is the reference line, the edge's offset (towards the median) on segments between its
    steps; it changes exactly at the steps, where lane sections change too."""
    towards_median = 1.0 if sign > 0 else -1.0  # the median is left for right-hand traffic
    starts = np.concatenate([[0.0], steps.stations])
    return CubicProfile(
        tuple(
            CubicPiece(float(s0), float(towards_median * off))
            for s0, off in zip(starts, steps.offsets, strict=True)
        )
    )


_STEP_SECTION_M = 0.5  # a lane section starting this close to an offset step starts there
_RELEVEL_MAX_M = 0.05  # a lane border this far off across an offset step is noise: the
# segment moves; farther, the markings and the median edge disagree for real and the
# seal fades the lanes beginning or ending there instead of moving the whole segment
_RELEVEL_ANY_M = 0.5  # ... unless no such lane is there to take it up


def _join_lanes_across_offset_steps(road: Road, stations: FloatArray) -> Road:
    """Lane offsets re-levelled so that the lanes linked across each step stay joined.

    The offset of each segment is measured from the median-side edge points, the lane
    widths from the markings; at a step the two need not agree to the millimetre, and a
    through lane would jump sideways by the difference where the road is cut into a
    junction (14 mm at Town06's inner entry: a link-gap error). Step by step along the
    road, the segment after a step is moved so that the innermost lane linked across the
    section border there keeps its outer border (metres, t), if that moves it by at most
    ``_RELEVEL_MAX_M``, with the records that continue it up to the next step (a
    median-side move's after a gore). A larger difference is no noise: moving the segment
    by it moved 800 m of oakland-28393854-s7 0.18 m off its measured median edge (every
    lane border with it); :func:`~.seal.seal_lane_borders` joins the lanes there instead,
    by the widths of the lanes inside that begin or end at the border. Where there are none, the
    segment still moves (up to ``_RELEVEL_ANY_M``): the border would be a 0.16 m gap."""
    pieces = list(road.lane_offset.pieces)
    if len(pieces) < 2 or not len(stations):
        return road
    s0s = np.array([sec.s0 for sec in road.lane_sections])
    for k in range(1, len(pieces)):
        s_step = pieces[k].s0
        n = int(np.argmin(np.abs(s0s - s_step)))
        if n == 0 or abs(s0s[n] - s_step) > _STEP_SECTION_M:
            continue
        prev_sec, sec = road.lane_sections[n - 1], road.lane_sections[n]
        # linked lanes already continue with the width they had (section_links._link_sections)
        linked = [ln for ln in (sec.right or sec.left) if ln.predecessor is not None]
        if not linked:
            continue
        lane = min(linked, key=lambda ln: abs(ln.id))
        # lanes inside it on either side of the border (beginning or ending there) can
        # take up a difference (the seal); without them the segment moves
        takes_up = any(abs(ln.id) < abs(lane.id) for ln in (sec.right or sec.left)) or any(
            abs(ln.id) < abs(int(lane.predecessor)) for ln in (prev_sec.right or prev_sec.left)
        )
        probe = replace(road, lane_offset=CubicProfile(tuple(pieces)))
        s_before = np.array([s0s[n] - 1e-6])
        if s_before[0] < prev_sec.s0:
            continue
        t_before = probe.lane_border_t(s_before, int(lane.predecessor))[0]
        t_after = probe.lane_border_t(np.array([s0s[n]]), lane.id)[0]
        shift = float(t_before - t_after)
        limit = _RELEVEL_MAX_M if takes_up else _RELEVEL_ANY_M
        if np.isfinite(shift) and abs(shift) <= limit:
            # the whole segment moves: the records that continue this one up to the next
            # step (a median-side move's after a gore), so that they stay continuous
            j = k
            while True:
                goes_on = j + 1 < len(pieces) and _continues(pieces[j], pieces[j + 1])
                pieces[j] = replace(pieces[j], a=pieces[j].a + shift)
                if not goes_on:
                    break
                j += 1
    return replace(road, lane_offset=CubicProfile(tuple(pieces)))


def _continues(piece: CubicPiece, nxt: CubicPiece) -> bool:
    """Whether ``nxt`` begins where ``piece`` ends: one continuous profile, no step."""
    h = nxt.s0 - piece.s0
    return abs(piece.a + piece.b * h + piece.c * h**2 + piece.d * h**3 - nxt.a) < 1e-6


def fit_reference_edge(
    ref_pts: FloatArray, traj: PolylineFrame, *, config: MainlineConfig | None = None
) -> FloatArray:
    """Smooth reference-edge polyline ``(G, 2)`` (mapping frame, ~1 m spacing); see
    :func:`fit_median_edge` (this is its ``xy``)."""
    return fit_median_edge(ref_pts, traj, config=config).xy


_SIZE_SEARCH_M = 2.5  # a step's size is searched this far around its first estimate
_SIZE_WINDOW_M = 120.0  # ... judged by the line this far either side of the step


def _roughness(frame: PolylineFrame, grid: FloatArray, off: FloatArray) -> float:
    """Sum of squared curvature changes (1/m^2 per m) of the line ``off`` beside ``frame``
    on ``grid`` (mapping frame): a jog of the line shows as an S of curvature."""
    xy, tg = frame.at(np.clip(grid, 0.0, frame.length))
    nrm = np.stack([-tg[:, 1], tg[:, 0]], axis=1)
    pts = xy + off[:, None] * nrm
    d = np.diff(pts, axis=0)
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    step = float(grid[1] - grid[0])
    kappa = np.diff(heading) / step
    return float(np.sum(np.diff(kappa) ** 2))


def _smoothest_steps(
    frame: PolylineFrame,
    s: FloatArray,
    t: FloatArray,
    side: float,
    steps: EdgeSteps,
    cfg: MainlineConfig,
) -> EdgeSteps:
    """Each step's size chosen so that the edge line fitted through it is smoothest.

    A segment's offset is measured from its points in the previous iteration's line (the
    frame); where that line bends across the step because the first estimate was off, the
    bend is self-consistent and stays (oakland's 3-lane left exit: 1.5 m, and the through
    lanes before and after the step did not meet). The reference line runs on smoothly at
    the level it had: within ``_SIZE_WINDOW_M`` either side, up to the neighbouring steps
    (at least 40 m each way), sizes within ``_SIZE_SEARCH_M`` of the estimate are tried,
    and the one whose fitted line changes curvature least is taken if it halves that
    change. ``s``, ``t``: the edge points on their levels in the frame (metres)."""
    offsets = steps.offsets.copy()
    step = cfg.grid_step_m
    stations = steps.stations
    for k, st in enumerate(stations):
        # the stretch between the neighbouring steps: one step judged at a time
        lo = max(st - _SIZE_WINDOW_M, stations[k - 1] + 5.0 if k > 0 else -np.inf)
        hi = min(st + _SIZE_WINDOW_M, stations[k + 1] - 5.0 if k + 1 < stations.size else np.inf)
        if st - lo < 40.0 or hi - st < 40.0:
            continue
        sel = (s >= lo) & (s <= hi)
        if np.count_nonzero(sel & (s < st)) < 20 or np.count_nonzero(sel & (s > st)) < 20:
            continue
        grid = np.arange(lo, hi + 0.5 * step, step)

        def score(delta: float, k=k, s_k=s[sel], t_k=t[sel], grid=grid) -> float:
            trial = offsets.copy()
            trial[k + 1 :] += delta
            shifted = t_k - side * EdgeSteps(stations, trial).at(s_k)
            off, _, _ = robust_offset_fit(
                s_k, shifted, grid, cutoff_m=cfg.edge_smoothing_m, mad_k=cfg.edge_outlier_mad,
                min_threshold_m=cfg.edge_outlier_min_m,
            )  # fmt: skip
            return _roughness(frame, grid, off)

        coarse = np.linspace(-_SIZE_SEARCH_M, _SIZE_SEARCH_M, 26)
        best = float(coarse[int(np.argmin([score(d) for d in coarse]))])
        fine = np.linspace(best - 0.2, best + 0.2, 21)
        scores = [score(d) for d in fine]
        # only a clear improvement moves the step: a line that bends there anyway (a
        # curve, a ramp edge converging at a merge) keeps the measured size
        if min(scores) < 0.5 * score(0.0):
            offsets[k + 1 :] += float(fine[int(np.argmin(scores))])
    return EdgeSteps(steps.stations, offsets, steps.areas)


def _median_levels(
    s: FloatArray, t: FloatArray, side: float, lo: float, hi: float, cfg: MainlineConfig
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Level path of the median-side edge points (``t`` signed, left positive; ``side`` +1
    when the median lies left): ``u`` = offset towards the median, the 2 m station bin
    edges and the level per bin (:func:`~.edge_levels.edge_level_path`)."""
    u = side * t
    edges = np.arange(lo - 1.0, hi + 3.0, 2.0)
    return u, edges, edge_level_path(s, u, edges, config=cfg)


_KNOT_MARGIN_M = 30.0  # edge points this near a knot of the median line are left out


def _without_knots(
    median: MedianEdge,
    ref_pts: FloatArray,
    traj: PolylineFrame,
    cfg: MainlineConfig,
    outer_pts: FloatArray,
    lane_pts: FloatArray,
) -> MedianEdge:
    """``median`` fitted again without its edge points (mapping frame, metres) within
    ``_KNOT_MARGIN_M`` of where it turns tighter than ``cfg.quality_min_radius_m``: no
    carriageway does, the points there are another road's (a diverging ramp's edge beside
    an unseen median edge) and the fit bridges them. Unchanged without knots, or where
    fewer than 10 points would be left."""
    knots = _tight_turns(median.xy, traj, cfg.quality_min_radius_m)
    if not knots:
        return median
    s_ref, _ = traj.project(ref_pts[:, :2])
    drop = np.zeros(s_ref.size, dtype=bool)
    for lo, hi in knots:
        drop |= (s_ref > lo - _KNOT_MARGIN_M) & (s_ref < hi + _KNOT_MARGIN_M)
    if np.count_nonzero(~drop) < 10:
        return median
    log.warning(
        "mainline: the median-side edge turned tighter than a %.0f m radius at "
        "s=%s m of the trajectory; its %d points there are left out",
        cfg.quality_min_radius_m,
        ", ".join(f"{lo:.0f}..{hi:.0f}" for lo, hi in knots),
        int(np.count_nonzero(drop)),
    )
    return fit_median_edge(ref_pts[~drop], traj, config=cfg, outer_pts=outer_pts, lane_pts=lane_pts)


def _tight_turns(
    xy: FloatArray, traj: PolylineFrame, min_radius_m: float
) -> list[tuple[float, float]]:
    """Stretches (trajectory stations, metres) where the polyline ``xy`` (mapping frame,
    metres) turns tighter than ``min_radius_m`` (:func:`~._common.tight_turn_runs`)."""
    s = arc_length(xy)
    if s[-1] < 2.0 * TURN_WINDOW_M:
        return []
    grid = np.arange(0.0, s[-1], 1.0)
    heading = np.unwrap(np.arctan2(np.diff(xy[:, 1]), np.diff(xy[:, 0])))
    runs, _ = tight_turn_runs(np.interp(grid, s[:-1], heading), min_radius_m)
    out = []
    for a, b in runs:
        ends = np.interp([grid[a], grid[b - 1]], s, np.arange(s.size))
        st, _ = traj.project(xy[np.clip(np.rint(ends).astype(int), 0, len(xy) - 1)])
        out.append((float(np.min(st)), float(np.max(st))))
    return out


_UNSEEN_END_M = 150.0  # a run end this long without median-side edge points is still road


_EXCURSION_OUT_M = 0.5  # a median-side edge level this far outward of its base ...
_EXCURSION_SLOPE = 0.02  # ... moving away from (towards) the road by this (m/m) at least ...
_EXCURSION_MAX_M = 80.0  # ... over at most this many metres of station (an auxiliary
# lane beside the median runs 100 m and more) ...
_EXCURSION_AGREE_M = 0.6  # ... with the levels either side this close: a ramp's edge
_EXCURSION_ONSET_M = 0.1  # it runs from where it is this far out of the base to where it
# is back (the bins in between that are unseen included)
_EXCURSION_JOIN_M = 10.0  # outward bins this close along belong to one excursion
_EXCURSION_BASE_M = 80.0  # the base: a low percentile of the level over this (metres)
_EXCURSION_BASE_PERCENT = 20
_EXCURSION_SIDE_BINS = 3  # bins either side that tell the levels before and after
_EXCURSION_POINT_M = 0.6  # a point inside an excursion this far outward of its base is
# the ramp's


def median_excursions(
    centres: FloatArray, level: FloatArray, *, drifting: bool = False
) -> tuple[FloatArray, FloatArray]:
    """Stretches where the median-side edge's level path leaves outward and comes back.

    A ramp leaving (joining) on the median side without a lane ending (beginning) at full
    width: its edge peels off the mainline's (the level path follows it outward for a
    few tens of metres), and beyond the gore the mainline's own edge goes on at the level
    it had. Those points are the ramp's; fitted into the reference line they bent the
    whole road up to 3 m towards the ramp over 40 m (Town06's inner exits, every lane
    with it).
    A step or a taper to a new level is no excursion: the levels either side differ.

    Parameters
    ----------
    centres, level
        Station bin centres (metres) and the level path (metres towards the median, NaN
        where unseen) of :func:`~.edge_levels.edge_level_path`.
    drifting
        The level path is measured in a frame that may drift away from the edge (the
        trajectory's: town06-auto-s3's car moved 4 m sideways with its lane over the
        100 m before an inner exit, and no excursion was found against a level base).
        In a frame that follows the edge (a fit of the edge itself) it does not.

    Returns
    -------
    ``(k, 2)`` station intervals (metres) of the excursions and ``(k,)`` the base level
    (metres) in each, the mean of the levels either side.
    """
    ok = np.isfinite(level)
    if np.count_nonzero(ok) < 2 * _EXCURSION_SIDE_BINS + 1:
        return np.zeros((0, 2)), np.zeros(0)
    step = float(np.median(np.diff(centres)))
    window = max(3, round(_EXCURSION_BASE_M / step) | 1)
    filled = np.interp(centres, centres[ok], level[ok])
    # a low percentile: an excursion is outward, and the base must not rise with it (or
    # with a step to a farther level beside it); in a frame that drifts away from the
    # edge, about the course the edge keeps there (a running median, which follows the
    # drift and not an excursion shorter than half its window)
    course = median_filter(filled, size=window, mode="nearest") if drifting else 0.0
    base = course + percentile_filter(
        filled - course, _EXCURSION_BASE_PERCENT, size=window, mode="nearest"
    )
    out = ok & (level - base > _EXCURSION_OUT_M)
    # runs of outward bins, unseen bins inside a run included (the gore's nose)
    idx = np.flatnonzero(out)
    spans: list[tuple[float, float]] = []
    bases: list[float] = []
    last_b = -1
    if idx.size:
        for run in np.split(
            idx, np.flatnonzero(np.diff(idx) > 1 + round(_EXCURSION_JOIN_M / step)) + 1
        ):
            a, b = int(run[0]), int(run[-1])
            # from where the edge starts to leave its base to where it is back on it (the
            # gore's nose unseen in between)
            while a > 0 and (not ok[a - 1] or level[a - 1] - base[a - 1] > _EXCURSION_ONSET_M):
                a -= 1
            while b + 1 < level.size and (
                not ok[b + 1] or level[b + 1] - base[b + 1] > _EXCURSION_ONSET_M
            ):
                b += 1
            if a <= last_b:  # extended into the previous run: one stretch, judged once
                continue
            last_b = b
            if (b - a + 1) * step > _EXCURSION_MAX_M:
                continue
            # a ramp's edge keeps moving away (towards the join); an auxiliary lane on the
            # median side (an entry's lane to the next exit) steps out and stays: no ramp
            # (town06-auto-s3 +20: the weaving lane between its inner ramps was dropped)
            span = np.arange(a, b + 1)
            sel = span[ok[span]]
            if sel.size < 2 or abs(np.polyfit(centres[sel], level[sel], 1)[0]) < _EXCURSION_SLOPE:
                continue
            before = level[:a][ok[:a]][-_EXCURSION_SIDE_BINS:]
            after = level[b + 1 :][ok[b + 1 :]][:_EXCURSION_SIDE_BINS]
            if before.size < _EXCURSION_SIDE_BINS or after.size < _EXCURSION_SIDE_BINS:
                continue
            m_before, m_after = float(np.mean(before)), float(np.mean(after))
            if abs(m_before - m_after) > _EXCURSION_AGREE_M:
                continue
            spans.append((centres[a] - 0.5 * step, centres[b] + 0.5 * step))
            bases.append(0.5 * (m_before + m_after))
    return np.asarray(spans, dtype=float).reshape(-1, 2), np.asarray(bases, dtype=float)


_UNSEEN_GORE_M = 20.0  # an excursion's unseen end this long hides the edge beside a gore


def _unseen_beside_gores(centres: FloatArray, level: FloatArray, spans: FloatArray) -> FloatArray:
    """(gore station, station where the edge is seen again) of each excursion (``spans``,
    :func:`median_excursions`) whose end (an exit's) or beginning (an entry's) is unseen
    over at least ``_UNSEEN_GORE_M``: the last (first) station where the ramp's edge is
    seen is the gore; stations and ``level`` on the bin ``centres``, metres."""
    rows = []
    ok = np.isfinite(level)
    for a, b in spans:
        idx = np.flatnonzero((centres >= a) & (centres <= b))
        seen = np.flatnonzero(ok[idx])
        if seen.size == 0:
            continue
        half = 0.5 * float(np.median(np.diff(centres)))
        first, last = centres[idx[seen[0]]] - half, centres[idx[seen[-1]]] + half
        if b - last >= _UNSEEN_GORE_M:
            rows.append((last, b))  # an exit: the edge unseen after its gore
        if first - a >= _UNSEEN_GORE_M:
            rows.append((first, a))  # an entry: unseen before its gore
    return np.asarray(rows, dtype=float).reshape(-1, 2)


def fit_median_edge(
    ref_pts: FloatArray,
    traj: PolylineFrame,
    *,
    config: MainlineConfig | None = None,
    outer_pts: FloatArray | None = None,
    lane_pts: FloatArray | None = None,
) -> MedianEdge:
    """The median-side road edge: a smooth reference line and the edge's steps.

    Edge points are fitted as a robust smooth offset from a frame, first the smoothed
    trajectory, then twice the previous fit itself (so the final smoothing acts on small
    residuals only and does not flatten lane changes of the vehicle). On the median side
    the edge steps where lanes leave or join there (a left exit on a right-hand road): the
    points form levels (:func:`~.edge_levels.edge_level_path`, the level nearest the
    carriageway is the road's edge, ramp edges and the median lie beyond it); segments
    between steps are shifted onto the level of the longest stretch before the fit, so
    the reference line stays smooth and the steps become the centre lane's offset. Where
    a ramp's edge peels off (joins) on the median side and the edge goes on at its level
    beyond the gore (:func:`median_excursions`), the ramp's points are left out.
    ``outer_pts`` (the other edge's points) tell a step hidden in an occlusion gap from
    the car's own lane change there, and ``lane_pts`` (the lane samples) where in the gap
    the edge's own line leaves for a ramp (:func:`~.edge_levels.edge_steps`), and where
    the edge went across a stretch it is unseen: along the inner shoulder's line, where
    that line is followed through the stretch and keeps its distance from the edge
    (:func:`~.median_gaps.edge_along_shoulder_line`).
    """
    cfg = config or MainlineConfig()
    step = cfg.grid_step_m
    frame = traj
    side, has_steps = 1.0, False
    filled = np.zeros((0, 2))  # stretches filled along the inner shoulder's line
    for it in range(3):
        s_all, t_all = frame.project(ref_pts)
        inside = (s_all >= -5.0) & (s_all <= frame.length + 5.0)
        s, t = s_all[inside], t_all[inside]
        if s.size < 10:
            raise InputError("mainline: the median-side road edge is not beside the trajectory")
        if it == 0:
            # edge points beyond an end of the trajectory (the car stopped recording inside
            # an occlusion of the edge) still say the edge goes on to that end; where the
            # edge was not seen over a long stretch at an end (out of the sensor's reach
            # across a wide road) the road still runs to that end, the reference keeping
            # the offset it had where last seen
            lo = max(float(np.min(s_all)), 0.0)
            hi = min(float(np.max(s_all)), frame.length)
            lo = 0.0 if lo > _UNSEEN_END_M else lo
            hi = frame.length if frame.length - hi > _UNSEEN_END_M else hi
        else:
            # at least the extent of the first pass: an occlusion of the edge at the end of
            # the run is bridged by the fit, not cut off with the road
            lo, hi = min(float(np.min(s)), 0.0), max(float(np.max(s)), frame.length)
        if it == 0:
            # the median lies on the side of the trajectory the points are on; later frames
            # are the edge itself, with points on both sides of it
            side = 1.0 if np.median(t) >= 0.0 else -1.0
        u, edges, level = _median_levels(s, t, side, lo, hi, cfg)
        centres = 0.5 * (edges[1:] + edges[:-1])
        # a ramp's edge peeling off on the median side is not the road's edge (in every
        # pass: the first one's bend would stay in the frames of the others), nor is its
        # nose, where the path drops back to the road's edge, a step of the road's edge
        # (the first pass's trajectory frame drifting beside it, a 1.8 m step sized
        # there bent town06-auto-s3's reference 0.6 m at an inner exit)
        road, level_road, spans = _without_excursions(s, u, centres, level, drifting=it == 0)
        s, t, u = s[road], t[road], u[road]
        if it == 0 or has_steps:
            steps = edge_steps(
                s,
                u,
                edges,
                level_road,
                config=cfg,
                across=functools.partial(_in_frame, frame, outer_pts, -side),
                lines=functools.partial(_in_frame, frame, lane_pts, side),
            )
            has_steps = bool(steps.stations.size)
        if has_steps or spans.size:
            # points on the edge's own level (the path bridged across excursions: a
            # ramp's edge runs on beyond its nose, and beyond an excursion found in the
            # first pass no zero-sized step at its nose leaves it out any more)
            seen = np.isfinite(level_road)
            if seen.any():
                near = np.abs(u - np.interp(s, centres[seen], level_road[seen])) < 0.8
                s, t, u = s[near], t[near], u[near]
        else:
            # nor, without them, points beyond the level path, where it was seen (left
            # in, a ramp's dense curb line ending beside the edge pulled the first pass)
            fit = ~_beyond_level(s, u, edges, level_road)
            s, t, u = s[fit], t[fit], u[fit]
        if has_steps:
            # each segment moved onto the base level
            near = ~steps.ramp_points(s, u)
            if it > 0:
                steps = _smoothest_steps(frame, s[near], t[near], side, steps, cfg)
            shift = steps.from_base(lo, hi)
            s, t = s[near], t[near] - side * shift.at(s[near])
        # where the edge is unseen the inner shoulder's line, followed through, says
        # where it went (a taper the smooth bridge would begin too early); in a frame
        # that follows the edge (the trajectory's moves with the car's lane changes),
        # and in the last pass where the one before found it
        lines = _in_frame(frame, lane_pts, side) if it > 0 else None
        if lines is not None and (it == 1 or filled.size):
            s_add, u_add, filled = edge_along_shoulder_line(
                centres, level_road, *lines, again=filled if it > 1 else None
            )
            if s_add.size:
                if has_steps:
                    u_add = u_add - shift.at(s_add)
                s, t = np.r_[s, s_add], np.r_[t, side * u_add]
        if it > 0:
            # the frame is the previous fit (on the base level): t is each point's residual
            # from it; a second line of points beyond the edge (the other carriageway's,
            # across a narrow median) is not averaged in
            inner = inner_line_points(s, side * t)
            s, t = s[inner], t[inner]
        grid = _grid(lo, hi, step)
        grid = grid[grid <= hi + 1e-9] if grid[-1] > hi + 0.5 * step else grid
        cutoff = cfg.edge_smoothing_m if it > 0 else max(cfg.edge_smoothing_m, 60.0)
        off, _, _ = robust_offset_fit(
            s,
            t,
            grid,
            cutoff_m=cutoff,
            mad_k=cfg.edge_outlier_mad,
            min_threshold_m=cfg.edge_outlier_min_m if it > 0 else 0.5,
        )
        # over a long unseen run end the offset is held, not extrapolated by the smoother
        held = ((grid < s.min()) & (s.min() - grid[0] > _UNSEEN_END_M)) | (
            (grid > s.max()) & (grid[-1] - s.max() > _UNSEEN_END_M)
        )
        if np.any(held) and not np.all(held):
            off = np.where(held, np.interp(grid, grid[~held], off[~held]), off)
        xy, tg = frame.at(np.clip(grid, 0.0, frame.length))
        # beyond the frame ends extrapolate along the end tangents
        xy = xy + (grid - np.clip(grid, 0.0, frame.length))[:, None] * tg
        nrm = np.stack([-tg[:, 1], tg[:, 0]], axis=1)
        pts = xy + off[:, None] * nrm
        z = frame.height_at(np.clip(grid, 0.0, frame.length))
        if z is not None:
            pts = np.column_stack([pts, z])
        frame = PolylineFrame.from_points(resample_polyline(pts, step))
    unseen = _unseen_beside_gores(centres, level, spans)  # of the last pass
    if not has_steps:
        return MedianEdge(frame.xy, EdgeSteps(np.zeros(0), np.zeros(1)), frame.z, unseen)
    # the steps in the final line's own stations
    s_f, t_f = frame.project(ref_pts)
    ok = (s_f >= 0.0) & (s_f <= frame.length)
    s_f, t_f = s_f[ok], t_f[ok]
    u, edges, level = _median_levels(s_f, t_f, side, 0.0, frame.length, cfg)
    road, level_road, _ = _without_excursions(s_f, u, 0.5 * (edges[1:] + edges[:-1]), level)
    steps = edge_steps(
        s_f[road],
        u[road],
        edges,
        level_road,
        config=cfg,
        across=functools.partial(_in_frame, frame, outer_pts, -side),
        lines=functools.partial(_in_frame, frame, lane_pts, side),
    )
    return MedianEdge(frame.xy, steps, frame.z, unseen)


_BEYOND_LEVEL_M = 0.8
"""An edge point this far (metres) beyond the level its bin's path is on, away from the
road, is another road's edge or the median's: the road's own edge is the level nearest
the carriageway. Left in, the robust fit of a pass may follow a dense line of them."""


def _beyond_level(
    s: FloatArray, u: FloatArray, edges: FloatArray, level: FloatArray
) -> NDArray[np.bool_]:
    """Mask of edge points (stations ``s``, offsets ``u`` towards the median, metres)
    lying more than ``_BEYOND_LEVEL_M`` beyond the level path (per bin of ``edges``,
    NaN where unseen: no point is dropped there). Only for a fit without steps or
    excursions: with them the points off the bridged level path are left out both ways,
    and the step and excursion logic needs the ramp's edge beyond (melbourne-921-s9+860,
    an inner exit: dropped before the steps were found, the edge was built 7.5 m off).

    A ramp whose edge line ends 7 m beside the median edge (krems-30799129-s11+920: 670
    points over 60 m, denser than the edge's own) pulled the first pass's fit 7 m
    outward though the level path stayed on the edge; the knot it tied was then cut out
    and bridged 0.9 m off over 100 m."""
    b = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, level.size - 1)
    at = level[b]
    return np.isfinite(at) & (u > at + _BEYOND_LEVEL_M)


def _without_excursions(
    s: FloatArray, u: FloatArray, centres: FloatArray, level: FloatArray, *, drifting: bool = False
) -> tuple[NDArray[np.bool_], FloatArray, FloatArray]:
    """The road's own edge without the excursions of its level path
    (:func:`median_excursions`; ``drifting`` as there).

    Returns the mask of the edge points (stations ``s``, offsets ``u`` towards the median,
    metres) that are not a ramp's (inside an excursion and more than
    ``_EXCURSION_POINT_M`` outward of its base), the level path (on bin ``centres``,
    metres) unseen (NaN) over the excursions, and the excursions' ``(k, 2)`` station
    intervals."""
    spans, bases = median_excursions(centres, level, drifting=drifting)
    if not spans.size:
        return np.ones(s.size, dtype=bool), level, spans
    k = np.clip(np.searchsorted(spans[:, 0], s, side="right") - 1, 0, None)
    inside = (s >= spans[k, 0]) & (s <= spans[k, 1])
    level_road = level.copy()
    for a, b in spans:
        level_road[(centres >= a) & (centres <= b)] = np.nan
    return ~(inside & (u > bases[k] + _EXCURSION_POINT_M)), level_road, spans


def _in_frame(
    frame: PolylineFrame, points: FloatArray | None, sign: float
) -> tuple[FloatArray, FloatArray] | None:
    """Stations and ``sign`` times the offsets (metres) of ``points`` in ``frame`` (the
    other edge's points away from the median with ``-side``, the lane samples towards it
    with ``side``), or None without points."""
    if points is None or points.shape[0] == 0:
        return None
    s, t = frame.project(points)
    return s, sign * t


def _bin_sums(
    b: NDArray[np.int64], w: FloatArray, t: FloatArray, z: FloatArray, n: int
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Weighted sums per bin ``b`` (of ``n``): ``w``, ``w t``, ``w z``, ``w t^2``, ``w t z``
    (the moments of a per-bin line z = e + g t; t lateral and z height, metres)."""
    return (
        np.bincount(b, w, n),
        np.bincount(b, w * t, n),
        np.bincount(b, w * z, n),
        np.bincount(b, w * t * t, n),
        np.bincount(b, w * t * z, n),
    )


def fit_elevation(
    frame: PolylineFrame,
    points: FloatArray,
    *,
    poses: FloatArray | None = None,
    config: MainlineConfig | None = None,
) -> tuple[CubicProfile, CubicProfile | None]:
    """Elevation and (if significant) superelevation of the reference line.

    Per station bin a weighted plane ``z = e + g t`` is fitted to the height points
    (road-edge points and the road surface under the car: ``poses`` minus the pose
    height; mapping frame z), with one round of robust (MAD) rejection; ``e`` and ``g``
    are smoothed along s and bridged over gaps. With ``poses``, edge points that cannot
    lie on the driven road's surface are left out first: farther above or below the
    surface under the car than ``elevation_gate_m`` plus the largest plausible cross slope
    (``superelevation_max_rad``) over their lateral distance from the car (a ramp passing
    over or under, a bridge beside the road).

    Returns
    -------
    elevation : C1 cubic profile of z at the reference line (metres).
    superelevation : profile of ``atan(g)`` (radians; positive = falling to the right),
        or None if ``|g|`` stays below ``config.superelevation_min_rad``.
    """
    cfg = config or MainlineConfig()
    if poses is not None and len(poses):
        points = np.vstack([_on_driven_surface(frame, points, poses, cfg), poses])
    s, t = frame.project(points)
    z = points[:, 2]
    ok = (s >= 0) & (s <= frame.length) & np.isfinite(z)
    s, t, z = s[ok], t[ok], z[ok]
    step = cfg.elevation_bin_m
    grid = _grid(0.0, frame.length, step)
    n = grid.size
    b = np.clip(np.rint(s / step).astype(np.int64), 0, n - 1)
    keep = np.ones(s.size, dtype=bool)
    e = g = np.zeros(n)
    lam = _lam(cfg.elevation_smoothing_m, step)
    for _ in range(2):
        sw, st, sz, stt, stz = _bin_sums(b, keep.astype(float), t, z, n)
        with np.errstate(invalid="ignore", divide="ignore"):
            mt, mz = st / sw, sz / sw
            vt = stt / sw - mt * mt
            ctz = stz / sw - mt * mz
            g_bin = np.where(vt > 1.0, ctz / vt, np.nan)
        gw = np.where(np.isfinite(g_bin), sw * np.nan_to_num(vt), 0.0)
        g = whittaker_smooth(g_bin, gw, lam=lam) if np.any(gw > 0) else np.zeros(n)
        e_bin = np.where(sw > 0, mz - g * mt, np.nan)
        e = whittaker_smooth(e_bin, sw / max(float(np.median(sw[sw > 0])), 1e-12), lam=lam)
        res = z - (np.interp(s, grid, e) + np.interp(s, grid, g) * t)
        mad = float(np.median(np.abs(res))) * 1.4826
        keep = np.abs(res) <= max(4.0 * mad, 0.05)
    elevation = fit_cubic_profile(grid, e, tolerance=cfg.elevation_tolerance_m)
    # cross slope per bin and its weight sum_w (t - mean t)^2 (kept points only)
    sw, st, sz, stt, stz = _bin_sums(b, keep.astype(float), t, z, n)
    with np.errstate(invalid="ignore", divide="ignore"):
        mt, mz = st / sw, sz / sw
        sxx = np.where(sw > 0, stt - sw * mt * mt, 0.0)
        g_bin = np.where(sxx > sw, (stz - sw * mt * mz) / sxx, 0.0)
    sxx = np.where(sxx > sw, sxx, 0.0)
    sigma_z = max(float(np.median(np.abs(res[keep]))) * 1.4826, 1e-4) if np.any(keep) else 1.0
    superelevation = _significant_cross_slope(grid, g, g_bin, sxx, sigma_z, cfg)
    return elevation, superelevation


def _on_driven_surface(
    frame: PolylineFrame, points: FloatArray, poses: FloatArray, cfg: MainlineConfig
) -> FloatArray:
    """The points whose height fits the surface under the car (see :func:`fit_elevation`)."""
    if points.shape[0] == 0:
        return points
    s_p, t_p = frame.project(poses)
    order = np.argsort(s_p)
    s_p, t_p, z_p = s_p[order], t_p[order], poses[order, 2]
    s, t = frame.project(points)
    z_car = np.interp(s, s_p, z_p)
    lateral = np.abs(t - np.interp(s, s_p, t_p))
    bound = cfg.elevation_gate_m + np.tan(cfg.superelevation_max_rad) * lateral
    return points[np.abs(points[:, 2] - z_car) <= bound]


def _significant_cross_slope(
    grid: FloatArray,
    g_smooth: FloatArray,
    g_bin: FloatArray,
    sxx: FloatArray,
    sigma_z: float,
    cfg: MainlineConfig,
) -> CubicProfile | None:
    """Superelevation profile (radians) where the cross slope is real, else None.

    Over every window of ``superelevation_min_length_m`` the least-squares cross slope
    (``sum sxx_i g_i / sum sxx_i``) is compared with its standard error
    ``sigma_z / sqrt(sum sxx_i)`` (``sigma_z``: robust height noise, metres). A stretch
    counts where ``|mean| > superelevation_k_sigma * se`` and
    ``|mean| > superelevation_min_rad`` for at least that length; elsewhere the slope is 0
    (the height noise alone gives ~1e-4 rad wobble, not superelevation). Inside a stretch
    the smoothed slope is kept; the profile eases in and out over half a window and is
    fitted to ``superelevation_tolerance_rad`` (a few smooth cubic pieces).
    """
    step = float(grid[1] - grid[0])
    n_win = max(3, round(cfg.superelevation_min_length_m / step))
    if grid.size < n_win:
        return None
    cw = np.concatenate([[0.0], np.cumsum(sxx)])
    cg = np.concatenate([[0.0], np.cumsum(sxx * g_bin)])
    tot = cw[n_win:] - cw[:-n_win]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(tot > 0, (cg[n_win:] - cg[:-n_win]) / tot, 0.0)
        se = np.where(tot > 0, sigma_z / np.sqrt(tot), np.inf)
    sig_win = (np.abs(mean) > cfg.superelevation_k_sigma * se) & (
        np.abs(mean) > cfg.superelevation_min_rad
    )
    if not np.any(sig_win):
        return None
    # bins covered by a significant window
    cover = np.convolve(sig_win.astype(float), np.ones(n_win))[: grid.size] > 0
    weight = np.convolve(cover.astype(float), np.ones(n_win) / n_win, mode="same")
    weight = np.clip(weight, 0.0, 1.0)
    value = np.arctan(g_smooth) * weight
    log.info(
        "mainline: superelevation over %.0f m (max |%.4f| rad)",
        float(np.count_nonzero(cover)) * step,
        float(np.max(np.abs(value))),
    )
    value = np.clip(value, -cfg.superelevation_max_rad, cfg.superelevation_max_rad)
    return fit_cubic_profile(grid, value, tolerance=cfg.superelevation_tolerance_rad)
