"""The ramp road: OSM shape (or measured evidence) re-anchored on the mainline, fitted as
ParamPoly3 pieces, with the ramp's cross-section (:func:`build_ramp_road`).

All coordinates are in the mapping frame (metres, radians CCW from +x).
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from .._errors import FitError
from ..config import RampConfig
from ..fitting import PolylineFrame, arc_length, fit_parampoly3_chain, resample_polyline
from ..mainline._common import true_runs
from ..model import CubicPiece, CubicProfile, Lane, LaneSection, Road, RoadMark, chain_geometry
from .candidates import _wrap
from .geometry import _mainline_boundary_distance, _smooth_polyline, hermite_piece
from .gores import _carriageway_border_t
from .records import FloatArray, RampEvidence, RampSide, RampType, TrafficSide
from .shape import fit_ramp_shape

log = logging.getLogger(__name__)


def _refuse_folded(ref: FloatArray, centre: FloatArray, road_id: str) -> None:
    """Raise :class:`FitError` if the reference line ``ref`` (``(N, 2)``, metres) is more
    than twice as long as the OSM centre line ``centre`` it was offset from, plus 100 m.

    Points moved onto the carriageway's border near the gore can alternate with points
    left where they were: a zigzag 70 times the ramp's length, whose fit then asked for
    24 GB (oakland-11197879-s9, paper method, where the border jumps at its gores)."""
    if arc_length(ref)[-1] > 2.0 * arc_length(centre)[-1] + 100.0:
        msg = f"{road_id}: the ramp's reference line folds onto the mainline border"
        raise FitError(msg)


_KNOT_DEG = 100.0  # a fitted line heading this far from the OSM line beside it turned back
_KNOT_RUN_M = 5.0  # ... over at least this length (metres)
_KNOT_KEEP_M = 100.0  # a fit turning back this far from the gore (metres) ends before it ...
_KNOT_MARGIN_M = 10.0  # ... by this much (metres)


def _turn_back_start(fitted: FloatArray, target: FloatArray) -> float | None:
    """Where (metres along ``fitted`` from its first point) the fitted reference line
    first turns back against the OSM line ``target`` it was fitted to (both ``(N, 2)``,
    metres, in the same order): over ``_KNOT_RUN_M`` its heading differs by more than
    ``_KNOT_DEG`` from the heading of the nearest stretch of ``target``. None where it
    does not.

    The clothoid spline compares each target point with the curve at the same arc length;
    where the OSM line turns more sharply than the curvature bound allows (Town06's exit
    5011 bends 70 degrees within metres) or starts metres beside the gore (a fork drawn
    from the branch's centre, melbourne-1226), its best fit is a loop 20-30 m across that
    a car would drive. A loop ramp's OSM line loops too, so its fit follows it and passes."""
    fit = resample_polyline(fitted, 1.0)
    line = resample_polyline(target, 1.0)
    if fit.shape[0] < 3 or line.shape[0] < 3:
        return None
    h_fit = np.arctan2(*np.gradient(fit, axis=0)[:, ::-1].T)
    h_line = np.arctan2(*np.gradient(line, axis=0)[:, ::-1].T)
    _, nearest = cKDTree(line).query(fit)
    back = np.degrees(np.abs(_wrap(h_fit - h_line[nearest]))) > _KNOT_DEG
    along = arc_length(fit)
    runs = [a for a, b in true_runs(back) if along[b - 1] - along[a] >= _KNOT_RUN_M - 1.0]
    return float(along[runs[0]]) if runs else None


def _build_ramp_road(
    chain_xy: FloatArray,
    mainline_road: Road,
    *,
    ramp_type: RampType,
    lanes: int,
    station_m: float,
    source_lane_ids: tuple[int, ...],
    traffic_side: TrafficSide = "right",
    side: RampSide = "outer",
    road_id: str = "ramp",
    shoulder_lane_id: int | None = None,
    edge_xy: FloatArray | None = None,
    lane_xy: FloatArray | None = None,
    config: RampConfig | None = None,
) -> tuple[Road, float, float, RampEvidence | None]:
    """Ramp road from an OSM chain polyline, re-anchored on the measured mainline and
    corrected by the measured points past the gore.

    Parameters
    ----------
    chain_xy
        ``(N, 2)`` OSM polyline in driving order, mapping frame, metres.
    mainline_road
        The measured mainline (one road over the run).
    ramp_type
        ``"exit"`` (the ramp starts at the mainline) or ``"entry"`` (it ends there).
    lanes
        Ramp lane count (>= 1).
    station_m
        Mainline station of the attachment (gore), metres.
    source_lane_ids
        Mainline lanes the ramp lanes continue (exit) or feed (entry), inner to outer:
        the deceleration/acceleration lanes at a measured gore, else the outermost driving
        lane. The ramp's reference line meets the inner border of the first of them (at a
        gore: the outer border of the outermost through lane), and the first ramp lanes
        take their widths there, blending to ``lane_width_m`` over ``blend_length_m``;
        further ramp lanes open from zero width.
    traffic_side
        ``"right"``: reference line = ramp's left edge, lanes ``-1`` (inner shoulder),
        ``-2 .. -(n+1)`` (driving), ``-(n+2)`` (hard shoulder); ``"left"`` mirrored.
    side
        ``"outer"`` (the ramp leaves/joins on the traffic side) or ``"inner"`` (on the
        median side): which carriageway border it must stay clear of near the gore.
    shoulder_lane_id
        Mainline hard shoulder the ramp's hard shoulder continues (exit) or feeds (entry)
        at a measured gore; its width there is the ramp hard shoulder's start width.
        ``None``: the ramp's hard shoulder opens from zero width.
    edge_xy, lane_xy
        Measured road-edge points and lane samples (``(N, 2+)``, mapping frame, metres).
        Those past the gore on the ramp (:func:`.shape.fit_ramp_shape`) shape the
        ramp's first part and give its shoulder and lane widths; ``None``: OSM and
        defaults decide.

    Returns
    -------
    (road, gap_m, heading_deg)
        The ramp road and the position / heading mismatch (metres, degrees) of its fitted
        attachment end against the anchor on the mainline.

    Raises
    ------
    FitError
        Too little of the ramp remains after trimming, or the fit fails.
    """
    cfg = config or RampConfig()
    lanes = max(1, int(lanes))
    width = cfg.lane_width_m
    left = 1.0 if traffic_side == "right" else -1.0  # reference line side of the centre
    # lateral direction in which the ramp leaves the carriageway: away from the median on
    # the outer side, towards it on the median side
    outward = -left if side == "outer" else left
    pts = np.asarray(chain_xy, dtype=float)[:, :2]
    if ramp_type == "entry":
        pts = pts[::-1]  # work attachment-first
    dense = resample_polyline(pts, cfg.resample_step_m)
    keep = arc_length(dense) <= cfg.max_ramp_length_m
    dense = dense[keep]
    if dense.shape[0] < 4:
        msg = f"{road_id}: ramp polyline too short"
        raise FitError(msg)
    centre = _smooth_polyline(dense, cfg)
    # reference line: median-side boundary (offset towards the mainline side)
    frame = PolylineFrame.from_points(centre if ramp_type == "exit" else centre[::-1])
    # the OSM way runs along the middle of the driving lanes (an assumption: mappers draw
    # the carriageway's centre); the reference line is the inner road edge
    w_in = cfg.inner_shoulder_width_m
    ref = frame.offset_points(np.full(frame.s.shape, left * (w_in + 0.5 * lanes * width)))
    if ramp_type == "entry":
        ref = ref[::-1]

    # anchor on the mainline
    s_att = float(np.clip(station_m, 0.0, mainline_road.length))
    s_eval = np.array([s_att - 1e-6 if ramp_type == "exit" else s_att + 1e-6])
    src_widths = []
    for lane_id in source_lane_ids:
        outer = mainline_road.lane_border_t(s_eval, lane_id)[0]
        inner = mainline_road.lane_border_t(s_eval, lane_id + (1 if lane_id < 0 else -1))[0]
        src_widths.append(abs(float(outer - inner)))
        if not math.isfinite(src_widths[-1]):
            msg = f"{road_id}: mainline lane {lane_id} missing at s={s_att:.1f} m"
            raise FitError(msg)
    first_id = source_lane_ids[0]
    t_att = float(mainline_road.lane_border_t(s_eval, first_id + (1 if first_id < 0 else -1))[0])
    target = mainline_road.to_xy(np.array([s_att]), np.array([t_att]))[0]
    h_main = float(mainline_road.heading(np.array([s_att]))[0])
    direction = 1.0 if ramp_type == "exit" else -1.0  # attachment-first stations run ...

    s_i, t_i = mainline_road.project(ref)
    # trim to the gore: drop the part on the wrong side of the attachment station
    beyond = (s_i - s_att) * direction >= 0.0
    first = int(np.argmax(beyond)) if np.any(beyond) else len(s_i)
    ref, s_i, t_i = ref[first:], s_i[first:], t_i[first:]
    if ref.shape[0] < 4:
        msg = f"{road_id}: nothing of the OSM ramp lies beyond the gore at s={s_att:.1f} m"
        raise FitError(msg)
    # extend along the mainline edge if the gore lies before the OSM attachment
    gap_s = (s_i[0] - s_att) * direction
    if gap_s > cfg.resample_step_m:
        n = max(2, math.ceil(gap_s / cfg.resample_step_m))
        s_ext = s_att + direction * np.linspace(0.0, gap_s, n, endpoint=False)
        t_ext = _carriageway_border_t(mainline_road, s_ext, traffic_side, side)
        ref = np.vstack([mainline_road.to_xy(s_ext, t_ext), ref])
        s_i = np.concatenate([s_ext, s_i])
        t_i = np.concatenate([t_ext, t_i])
    # keep the ramp outside the measured carriageway until it has clearly left it
    t_edge = _carriageway_border_t(
        mainline_road, np.clip(s_i, 0.0, mainline_road.length), traffic_side, side
    )
    t_edge = np.where(np.isfinite(t_edge), t_edge, t_i)
    # past the gore the border of the lanes that stay behind lies inside the border the
    # ramp leaves from (the median-side edge steps in a few metres past an inner exit's
    # gore): the ramp does not come back inside the line it leaves from at the gore
    past_gore = (s_i - s_att) * direction > 0.0
    t_edge = np.where(past_gore & ((t_att - t_edge) * outward > 0.0), t_att, t_edge)
    separation = (t_i - t_edge) * outward
    # points near the carriageway on the wrong side of the gore before the ramp has left
    # it (OSM drawn across the gore, an offset curve folding) are dropped; later ones are
    # the ramp itself (a loop coming back across the mainline on a bridge)
    away = separation > 2.0 * lanes * width
    leaving = np.arange(len(ref)) < (int(np.argmax(away)) if np.any(away) else len(ref))
    wrong = leaving & ((s_i - s_att) * direction < -1e-6) & (separation < 2.0 * lanes * width)
    if np.any(wrong):
        ref, s_i, t_i = ref[~wrong], s_i[~wrong], t_i[~wrong]
        t_edge, separation = t_edge[~wrong], separation[~wrong]
    if ref.shape[0] < 4:
        msg = f"{road_id}: nothing of the OSM ramp lies beyond the gore at s={s_att:.1f} m"
        raise FitError(msg)
    inside_road = (s_i > 0.0) & (s_i < mainline_road.length)
    clear = separation > lanes * width
    stop = int(np.argmax(clear)) if np.any(clear) else len(ref)
    clamp = inside_road & (np.arange(len(ref)) < stop) & (separation < 0.0)
    if np.any(clamp):
        ref = ref.copy()
        ref[clamp] = mainline_road.to_xy(s_i[clamp], t_edge[clamp])
    _refuse_folded(ref, centre, road_id)
    ref = _smooth_polyline(ref, cfg)
    length = float(arc_length(ref)[-1])
    if length < cfg.min_ramp_length_m:
        msg = f"{road_id}: only {length:.1f} m of ramp remain after trimming"
        raise FitError(msg)
    # the reference line as a clothoid spline from the anchor pose (attachment-first:
    # an entry is fitted from its end, heading reversed, lanes on the other side)
    backwards = ramp_type == "entry"
    hdg = h_main + (math.pi if backwards else 0.0)
    k_main = float(mainline_road.curvature(np.array([s_att]))[0])
    k_border = k_main / max(1.0 - t_att * k_main, 0.1)
    lane_side = -left * (-1.0 if backwards else 1.0)  # the ramp's lanes: right of it (RHT)
    w_hs = cfg.hard_shoulder_width_m

    anchor = (float(target[0]), float(target[1]), hdg)
    k_start = -k_border if backwards else k_border
    sigma_osm = np.full(len(ref), cfg.osm_sigma_m)
    fit_shape = functools.partial(
        fit_ramp_shape,
        ref,
        sigma_osm,
        anchor=anchor,
        curvature0=k_start,
        lane_side=lane_side,
        lanes=lanes,
        widths=(w_in, width, w_hs),
        config=cfg,
    )
    target_line = ref
    osm_fit = fit_shape()
    fit = None
    measured = _measured_near_ramp(
        osm_fit.xy, mainline_road, edge_xy, lane_xy, lanes * width + 8.0, traffic_side, cfg
    )
    if measured is not None:
        shape = fit_shape(points=measured)
        shift = float(np.max(np.hypot(*(shape.xy - osm_fit.xy).T)))
        if shape.points < cfg.evidence_min_points or shape.span_m < cfg.evidence_min_span_m:
            shape = None
        elif shift > cfg.evidence_max_shift_m:
            log.warning(
                "%s: measured points pull the ramp %.1f m off the OSM shape; not used",
                road_id,
                shift,
            )
            shape = None
        if shape is not None:
            w_in, width, w_hs = shape.widths
            fit = RampEvidence(
                xy=shape.xy[::-1] if backwards else shape.xy,
                widths=shape.widths,
                points=shape.points,
                counts=shape.counts,
                span_m=shape.span_m,
                max_shift_m=shift,
                rmse_m=shape.rmse_m,
            )
            log.info(
                "%s: %d measured points past the gore up to %.0f m (max correction %.2f m, "
                "residual RMSE %.3f m); widths %.2f / %.2f / %.2f m",
                road_id,
                fit.points,
                fit.span_m,
                fit.max_shift_m,
                fit.rmse_m,
                w_in,
                width,
                w_hs,
            )
    fitted = osm_fit.xy if fit is None else shape.xy
    knot = _turn_back_start(fitted, target_line)
    if knot is not None and knot >= _KNOT_KEEP_M:
        # far from the gore (where the ramp meets the local roads, whose corners OSM
        # draws as sharp as they are): the ramp ends before it. The OSM line as drawn
        # kept a 4 m radius hook at an entry's start, where esmini's car jumped 4.3 m
        # (melbourne-408-lane1-s21 with a noisier sensor, seed offset 80)
        log.warning(
            "%s: the fitted ramp turns back against its OSM line %.0f m from the gore; "
            "it ends %.0f m before there",
            road_id,
            knot,
            _KNOT_MARGIN_M,
        )
        fitted = fitted[arc_length(fitted) <= knot - _KNOT_MARGIN_M]
        if fit is not None:
            fit = replace(fit, xy=fitted[::-1] if backwards else fitted)
    elif knot is not None:
        log.warning(
            "%s: the fitted ramp turns back against its OSM line (a loop); the OSM line "
            "is used as drawn",
            road_id,
        )
        fit, fitted = None, target_line
    ref = fitted[::-1] if backwards else fitted
    w_hs_src = 0.0
    if shoulder_lane_id is not None:
        inner_id = shoulder_lane_id + (1 if shoulder_lane_id < 0 else -1)
        w = abs(
            float(mainline_road.lane_border_t(s_eval, shoulder_lane_id)[0])
            - float(mainline_road.lane_border_t(s_eval, inner_id)[0])
        )
        w_hs_src = w if math.isfinite(w) else 0.0
    pieces = list(fit_parampoly3_chain(ref, tolerance_m=cfg.fit_tolerance_m))
    # the attachment piece again as an exact Hermite piece: anchor pose to its far pose
    anchor = (float(target[0]), float(target[1]), h_main)
    if ramp_type == "exit":
        pieces[0] = hermite_piece(anchor, pieces[0].end_pose())
    else:
        last = pieces[-1]
        pieces[-1] = hermite_piece((last.x0, last.y0, last.hdg), anchor)
    geometry = chain_geometry(pieces)

    road = Road(
        id=road_id,
        geometry=geometry,
        lane_sections=(
            _ramp_section(
                lanes,
                width,
                ramp_type,
                traffic_side,
                cfg,
                source_widths=tuple(src_widths),
                road_length=float(sum(g.length for g in geometry)),
                inner_shoulder_m=w_in,
                hard_shoulder_m=w_hs,
                hard_shoulder_source_m=w_hs_src,
            ),
        ),
        name=ramp_type,
        elevation=CubicProfile.constant(
            float(mainline_road.surface_height(np.array([s_att]), np.array([t_att]))[0])
        ),
    )
    road = replace(
        road,
        superelevation=_roll_from_attachment(
            float(mainline_road.roll(np.array([s_att]))[0]),
            road.length,
            at_start=ramp_type == "exit",
        ),
    )
    s_end = 0.0 if ramp_type == "exit" else road.length
    x, y, h, _ = road.evaluate(np.array([s_end]))
    gap = float(math.hypot(float(x[0]) - target[0], float(y[0]) - target[1]))
    dh = abs(float(_wrap(float(h[0]) - h_main)))
    return road, gap, math.degrees(dh), fit


_ROLL_BLEND_M = 60.0
"""Length (metres) over which a ramp leaves the mainline's superelevation for a flat
cross section (at most half the ramp)."""


def _roll_from_attachment(roll: float, length: float, *, at_start: bool) -> CubicProfile | None:
    """Superelevation of a ramp road (radians): the mainline's ``roll`` at the attached
    end, blended C1 to zero over ``_ROLL_BLEND_M``; None where the mainline is flat there.

    OpenDRIVE rotates ``t`` by the roll, so only a ramp that carries the roll of the road
    it joins has its lane borders meet that road's in plan and in height."""
    if roll == 0.0:
        return None
    blend = min(_ROLL_BLEND_M, 0.5 * length)
    if at_start:
        return CubicProfile(width_transition(roll, 0.0, blend))
    return CubicProfile(
        (CubicPiece(0.0, 0.0), width_transition(0.0, roll, blend, s0=length - blend)[0])
    )


def _measured_near_ramp(
    ramp_xy: FloatArray,
    mainline_road: Road,
    edge_xy: FloatArray | None,
    lane_xy: FloatArray | None,
    lateral_m: float,
    traffic_side: TrafficSide,
    cfg: RampConfig,
) -> tuple[FloatArray, NDArray[np.bool_]] | None:
    """Measured edge points and lane samples within ``lateral_m`` of the first
    ``evidence_length_m`` of a provisional ramp line (attachment-first), without those
    the mainline explains (within ``evidence_exclude_m`` of a mainline boundary of their
    kind): ``(xy, is_edge)`` or None."""
    a = arc_length(ramp_xy)
    probe = ramp_xy[a <= cfg.evidence_length_m + 1.0][:: max(1, round(2.0 / cfg.shape_step_m))]
    parts, kinds = [], []
    for is_edge, pts in ((True, edge_xy), (False, lane_xy)):
        if pts is None or len(pts) == 0 or probe.shape[0] == 0:
            continue
        xy = np.asarray(pts, dtype=float)[:, :2]
        near = cKDTree(probe).query(xy, distance_upper_bound=lateral_m)[0] < np.inf
        sub = xy[near]
        if sub.shape[0] == 0:
            continue
        kind = "edge" if is_edge else "lane"
        d_main = _mainline_boundary_distance(
            mainline_road, sub, kind=kind, traffic_side=traffic_side
        )
        sub = sub[d_main > cfg.evidence_exclude_m]
        parts.append(sub)
        kinds.append(np.full(sub.shape[0], is_edge))
    if not parts or sum(p.shape[0] for p in parts) < cfg.evidence_min_points:
        return None
    return np.vstack(parts), np.concatenate(kinds)


def build_ramp_road(*args: Any, **kwargs: Any) -> tuple[Road, float, float]:
    road, gap, dh, _ = _build_ramp_road(*args, **kwargs)
    return road, gap, dh


build_ramp_road.__doc__ = _build_ramp_road.__doc__


def width_transition(
    w_from: float, w_to: float, length_m: float, *, s0: float = 0.0
) -> tuple[CubicPiece, CubicPiece]:
    """Two cubic pieces: a C1 transition from ``w_from`` (at ``s0``) to ``w_to`` (at
    ``s0 + length_m``), then constant ``w_to`` (metres)."""
    dw = w_to - w_from
    length = max(length_m, 1e-6)
    return (
        CubicPiece(s0, w_from, 0.0, 3.0 * dw / length**2, -2.0 * dw / length**3),
        CubicPiece(s0 + length, w_to),
    )


def _ramp_width(
    w_src: float, width: float, ramp_type: RampType, blend_m: float, road_length: float
) -> CubicProfile:
    if abs(w_src - width) < 1e-9:
        return CubicProfile.constant(width)
    if ramp_type == "exit":
        return CubicProfile(width_transition(w_src, width, blend_m))
    start = road_length - blend_m
    first, second = width_transition(width, w_src, blend_m, s0=start)
    return CubicProfile((CubicPiece(0.0, width), first, replace(second, s0=road_length)))


def _opening(w_to: float, ramp_type: RampType, taper_m: float, road_length: float) -> CubicProfile:
    """Width opening from zero at the gore (exit: road start; entry: closing to zero at
    the road end) over ``taper_m`` (metres)."""
    return _ramp_width(0.0, w_to, ramp_type, taper_m, road_length)


def _ramp_section(
    lanes: int,
    width: float,
    ramp_type: RampType,
    traffic_side: TrafficSide,
    cfg: RampConfig,
    *,
    source_widths: tuple[float, ...] = (),
    road_length: float = 0.0,
    inner_shoulder_m: float | None = None,
    hard_shoulder_m: float | None = None,
    hard_shoulder_source_m: float = 0.0,
) -> LaneSection:
    """The ramp's cross-section, the mainline's layout (DESIGN.md conventions): inner
    shoulder (opening from zero width at the gore), ``lanes`` driving lanes (the first
    ones starting with ``source_widths``, the others from zero), hard shoulder (starting
    with ``hard_shoulder_source_m``, the width of the mainline hard shoulder it
    continues, or zero)."""
    sign = -1 if traffic_side == "right" else 1
    lane_type = "driving"
    if cfg.lane_type == "spec":
        lane_type = "offRamp" if ramp_type == "exit" else "onRamp"
    blend = min(cfg.blend_length_m, 0.5 * road_length) if road_length > 0 else cfg.blend_length_m
    taper = min(cfg.shoulder_taper_m, 0.5 * road_length) if road_length > 0 else blend
    w_in = cfg.inner_shoulder_width_m if inner_shoulder_m is None else inner_shoulder_m
    w_hs = cfg.hard_shoulder_width_m if hard_shoulder_m is None else hard_shoulder_m
    out = [
        Lane(
            sign * 1,
            "shoulder",
            _opening(w_in, ramp_type, taper, road_length),
            (RoadMark(0.0, "solid"),),
        )
    ]
    for k in range(1, lanes + 1):
        mark = "solid" if k == lanes else "broken"
        w_src = source_widths[k - 1] if k <= len(source_widths) else 0.0
        out.append(
            Lane(
                sign * (k + 1),
                lane_type,  # type: ignore[arg-type]
                _ramp_width(w_src, width, ramp_type, blend, road_length),
                (RoadMark(0.0, mark),),  # type: ignore[arg-type]
            )
        )
    out.append(
        Lane(
            sign * (lanes + 2),
            "shoulder",
            _ramp_width(hard_shoulder_source_m, w_hs, ramp_type, blend, road_length),
            (RoadMark(0.0, "none"),),
        )
    )
    center = Lane(0, "none", road_marks=(RoadMark(0.0, "none"),))
    if traffic_side == "right":
        return LaneSection(0.0, center=center, right=tuple(out))
    return LaneSection(0.0, left=tuple(out), center=center)
