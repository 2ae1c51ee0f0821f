"""Mainline reconstruction from a mapping run: reference line, elevation and lanes.

Two methods build the same :class:`Mainline` (one :class:`~roadtwin.model.Road` named
``"mainline"`` over the whole run, laid out as the shared lane layout says):

``default`` (DESIGN.md section 4)
    The median-side road edge (left for right-hand traffic, right for left-hand traffic)
    is fitted as ONE smooth curve along the whole run: edge points are projected into the
    Frenet frame of the smoothed trajectory, outliers are rejected by a local median/MAD
    test, per-metre bin means are smoothed by a penalised least-squares (Whittaker)
    smoother that bridges gaps, and the frame is replaced by the fitted edge and the fit
    repeated. The result is cut into ParamPoly3 pieces that share end points and headings
    (:func:`roadtwin.fitting.fit_parampoly3_chain`). Heights and cross slope are fitted per
    bin (edge points and poses) and smoothed; elevation becomes C1 cubic pieces.
    Lane-marking samples are followed as tracks along s in a station/offset histogram;
    short tracks are rejected; a marking that starts or ends next to a neighbour opens or
    closes a tapering lane (lane birth / end), extrapolated to zero width; one that starts
    or ends at full width is a gore. Ramp markings crossing the corridor near a gore are
    cut off by their steep convergence/divergence. The outer road edge is the lowest
    cluster of the outer-side edge points (ramp edges lie farther out), fitted piecewise
    between edge steps (gores); across occlusion gaps the outer-shoulder width is bridged.
    Lane sections follow the set of tracks; the inner shoulder (edge to first marking) and
    the hard shoulder (last marking to the outer edge) are shoulder lanes; road marks are
    solid or broken from the gap statistics of the samples along each track.

``paper`` (the seed paper, kept as the baseline)
    100 m trajectory windows; a cubic per window fitted to the median-side edge points and
    turned into a ParamPoly3 (windows are independent, joints are not continuous);
    elevation = median height within radius r of stations, smoothed, one cubic per
    window; lane samples clustered per window by K-means on the lateral offset with
    k <= 6 chosen by silhouette; one cubic t(s) per cluster.

Frames: all input and output coordinates are in the mapping frame (metres). Internally
lateral offsets are handled as ``d`` = distance from the reference edge towards the
carriageway (``d = -t`` for right-hand traffic, ``d = t`` for left-hand traffic), so the
method is written once and mirrored by the sign.

Implementation, one concern per module: ``_common`` (results, helpers,
self-consistency); ``reference`` (default method: median-side reference edge, its steps
and excursions, elevation); ``median_moves`` (the median-side edge unseen beside a
gore); ``edge_levels`` (level paths and steps of an edge); ``lanes`` (the lane fit's
driver); ``linking`` (marking peaks per column linked into raw tracks); ``raw_joins``
(raw tracks joined where a line went to pieces); ``markings`` (marking tracks: samples,
ramp lines, collinear pieces);
``hidden_lanes`` (lanes and lines beyond the sensor's reach); ``unpainted`` (the
outermost line where it is not seen); ``shift`` (the marking
pattern's sideways shift); ``outer_edge`` (the outer edge and its bridging across gaps);
``gores``, ``hidden_gores``, ``painted_gores`` (where gores are); ``edge_lines`` (lines
painted on an edge); ``sections`` (lane sections, lane types, events); ``tapers`` (where
a line begins or ends); ``section_links`` (lanes linked across sections); ``seal``
(joined borders, non-negative widths); ``quality`` (poorly determined stretches);
``paper`` (the seed paper's method); ``cut`` (:func:`cut_road`).
"""

from __future__ import annotations

import logging
import math
import time

from .._errors import InputError
from ..config import MainlineConfig
from ..io import MappingRun
from ._common import BoundaryTrack, LaneEvent, Mainline, self_consistency
from .cut import cut_road
from .lanes import fit_lanes, fit_outer_edge
from .paper import _build_paper
from .quality import Stretch, poorly_determined
from .reference import _build_default, fit_elevation, fit_reference_edge

log = logging.getLogger(__name__)

__all__ = [
    "BoundaryTrack",
    "LaneEvent",
    "Mainline",
    "Stretch",
    "build_mainline",
    "cut_road",
    "fit_elevation",
    "fit_lanes",
    "fit_outer_edge",
    "fit_reference_edge",
    "poorly_determined",
    "self_consistency",
]


def build_mainline(run: MappingRun, *, config: MainlineConfig | None = None) -> Mainline:
    """Reconstruct the driven mainline of a mapping run as one OpenDRIVE road.

    Parameters
    ----------
    run
        The mapping run (mapping frame, metres).
    config
        Stage settings; ``config.method`` selects ``"default"`` or ``"paper"``.

    Returns
    -------
    Mainline
        ``.road`` (reference line = median-side road edge, elevation, optional
        superelevation, lane sections per the shared lane layout) and lane events.

    Raises
    ------
    InputError
        Too few edge points on the median side to fit a reference line.
    """
    cfg = config or MainlineConfig()
    if cfg.method not in ("default", "paper"):
        msg = f"mainline: unknown method {cfg.method!r}; expected 'default' or 'paper'"
        raise InputError(msg)
    timings: dict[str, float] = {}
    t_all = time.perf_counter()
    if cfg.method == "paper":
        result = _build_paper(run, cfg, timings)
    else:
        result = _build_default(run, cfg, timings)
    t0 = time.perf_counter()
    residuals = self_consistency(result.road, run)
    stretches = poorly_determined(result.road, run, config=cfg)
    for stretch in stretches:
        log.warning("%s", stretch.message())
    timings["self_consistency"] = time.perf_counter() - t0
    timings["total"] = time.perf_counter() - t_all
    road = result.road
    log.info(
        "mainline (%s): %.0f m, %d pieces, %d lane sections, %d lane events, "
        "edge RMSE %.3f m, lane RMSE %.3f m, %.2f s",
        cfg.method,
        road.length,
        len(road.geometry),
        len(road.lane_sections),
        len(result.lane_events),
        residuals.get("road_edge", math.nan),
        residuals.get("lane_boundary", math.nan),
        timings["total"],
    )
    return Mainline(
        road=road,
        lane_events=result.lane_events,
        method=result.method,
        tracks=result.tracks,
        timings_s=timings,
        residuals=residuals,
        stretches=stretches,
        outer_edge_seen=result.outer_edge_seen,
    )
