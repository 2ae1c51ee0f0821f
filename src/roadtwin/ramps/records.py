"""Data records of the ramp stage: candidates, chains, gore events, evidence, ramps.

Also the type aliases and the thresholds shared by the other ``roadtwin.ramps`` modules.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ..model import Road

FloatArray = NDArray[np.float64]
RampType = Literal["exit", "entry"]
TrafficSide = Literal["right", "left"]
RampSide = Literal["outer", "inner"]
"""Side of the carriageway a ramp leaves or joins: ``outer`` (the traffic side: right for
right-hand traffic) or ``inner`` (the median side: a left exit on a right-hand road)."""
EdgeKey = tuple[Any, Any, int]


_MIN_GORE_WIDTH_M = 1.0  # a lane ending/starting wider than this ends/starts at a gore
_MIN_BOUNDARY_POINTS = 20  # measured points on a road edge needed to measure its shoulder
_MIN_LINK_WIDTH_M = 0.05  # a lane narrower than this at a junction opens/closes there
_MIN_FIT_POINTS = 10  # points within the association gate needed to go on fitting
_EVIDENCE_LATERAL_M = 30.0  # measured points this far from the gore's base line count


# ---------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RampCandidate:
    """One directed OSM link edge within ``d_r`` of the trajectory (Algorithm 1).

    ``u, v, key`` identify the edge in the OSM graph; ``distance_m`` is its smallest
    distance to the trajectory (metres).
    """

    u: Any
    v: Any
    key: int
    highway: str
    osm_way_id: Any
    distance_m: float


@dataclass(frozen=True)
class RampChain:
    """Consecutive OSM link edges forming one ramp, in driving order.

    Attributes
    ----------
    edges : ``(u, v, key)`` of each link edge, in driving order.
    osm_way_ids : OSM way ids of the edges (unique, in order).
    attach_node : OSM node where the chain meets the driven carriageway.
    mainline_edge : the OSM carriageway edge at ``attach_node`` (``E_m`` of the paper).
    type : ``"exit"`` or ``"entry"`` from directed connectivity (the paper's rule).
    type_geometry : the same decided from geometry (which end lies nearer the trajectory).
    xy : ``(N, 2)`` chain polyline in driving order, mapping frame, metres.
    tags : OSM tags of the link edge at the attachment.
    side : ``outer`` or ``inner`` (the median side) of the driven carriageway.
    shared : drawn over the carriageway's own nodes (a branch OSM puts on the same nodes
        as the carriageway until it parts): it has no geometry or side of its own, and is
        built only where a measured gore on that side says where its lanes leave or join.
    """

    edges: tuple[EdgeKey, ...]
    osm_way_ids: tuple[Any, ...]
    attach_node: Any
    mainline_edge: EdgeKey
    type: RampType
    type_geometry: RampType
    xy: FloatArray = field(repr=False, compare=False)
    tags: dict[str, Any] = field(default_factory=dict, repr=False)
    side: RampSide = "outer"
    shared: bool = False


@dataclass(frozen=True)
class GoreEvent:
    """A measured gore on the mainline: driving lanes ending (exit) or starting (entry)
    at full width at a lane-section boundary.

    Attributes
    ----------
    station_m : mainline station of the section boundary, metres.
    kind : ``"exit"`` (lanes end: deceleration lanes) or ``"entry"`` (lanes start:
        acceleration lanes).
    lane_ids : mainline lane ids of the ending/starting lanes, inner to outer (in the
        section before the gore for exits, after it for entries).
    through_lane_id : the driving lane that continues through the gore next to them (the
        outermost one for an outer gore, the innermost for a gore on the median side).
    side : ``outer`` or ``inner``: the side of the carriageway the lanes leave or join.
    """

    station_m: float
    kind: RampType
    lane_ids: tuple[int, ...]
    through_lane_id: int
    side: RampSide = "outer"


@dataclass(frozen=True)
class RampEvidence:
    """The measured points past a gore fitted to a ramp (:func:`.shape.fit_ramp_shape`).

    Attributes
    ----------
    xy : ``(N, 2)`` fitted reference line (driving order, mapping frame, metres).
    widths : ``(inner shoulder, driving lane, hard shoulder)`` widths, metres (measured
        where the points saw the boundary, else the defaults given).
    points : measured points matched to a ramp boundary.
    counts : matched points per boundary ``(left edge, markings, right edge)``.
    span_m : extent along the ramp of the matched points (metres from the gore).
    max_shift_m : largest distance between the fitted line and the line fitted to the
        OSM shape alone, metres.
    rmse_m : residual RMSE of the matched points against the fitted boundaries, metres.
    """

    xy: FloatArray = field(repr=False)
    widths: tuple[float, float, float]
    points: int
    counts: tuple[int, int, int]
    span_m: float
    max_shift_m: float
    rmse_m: float


@dataclass(frozen=True)
class Ramp:
    """One reconstructed ramp and every decision taken for it.

    Attributes
    ----------
    type : ``"exit"`` or ``"entry"``.
    road : the ramp road in driving direction (``name`` = type, a provisional id;
        topology assigns the final id). Its reference line starts (exit) or ends (entry)
        exactly on the inner border of ``mainline_lane_ids[0]`` at ``station_m``.
    station_m : mainline station of the attachment (gore), metres.
    lanes : ramp lane count.
    lane_rule : which rule decided ``lanes`` (``"lanes:forward"``, ``"lanes"``,
        ``"turn:lanes"``, ``"highway class"`` or ``"mainline lane change"``).
    osm_lanes, osm_lane_rule : Algorithm 2's result and rule on the OSM tags.
    station_source : ``"lidar gore"`` (a measured lane event decided the station) or
        ``"osm"`` (the OSM attachment node projected on the mainline).
    mainline_lane_ids : mainline lanes the ramp lanes link to, inner to outer (the
        deceleration/acceleration lanes at a measured gore; else the outermost driving
        lane, which the ramp then splits off). Driving lane ``k`` of the ramp (lane
        ``-(k+1)`` for right-hand traffic; ``-1`` is the inner shoulder) continues/feeds
        ``mainline_lane_ids[k - 1]``; further ramp driving lanes open from zero width.
    type_connectivity, type_geometry : the two merge/exit decisions.
    osm_way_ids : OSM ways of the chain.
    attach_gap_m, attach_heading_deg : position and heading mismatch of the fitted ramp
        end against the anchor on the mainline (metres, degrees).
    warnings : human-readable notes (disagreements, fallbacks).
    shoulder_lane_id : mainline hard shoulder the ramp's hard shoulder continues/feeds at
        a measured gore (``None``: it opens from zero width).
    side : ``outer`` or ``inner`` (a ramp on the median side of the carriageway).
    evidence : the measured points past the gore fitted to the ramp (``None``: none or
        too few; OSM shape and default widths).
    """

    type: RampType
    road: Road = field(repr=False)
    station_m: float
    lanes: int
    lane_rule: str
    osm_lanes: int
    osm_lane_rule: str
    station_source: str
    mainline_lane_ids: tuple[int, ...]
    type_connectivity: RampType
    type_geometry: RampType
    osm_way_ids: tuple[Any, ...]
    attach_gap_m: float
    attach_heading_deg: float
    warnings: tuple[str, ...] = ()
    shoulder_lane_id: int | None = None
    evidence: RampEvidence | None = field(default=None, repr=False)
    side: RampSide = "outer"


@dataclass(frozen=True)
class RampSet:
    """Result of :func:`build_ramps`.

    ``candidates`` are Algorithm 1's edges; ``rejected`` lists ``(what, reason)`` for
    candidate edges/chains not used; ``skipped`` lists ramps that could not be built;
    ``warnings`` collects every ramp's notes.
    """

    ramps: tuple[Ramp, ...]
    candidates: tuple[RampCandidate, ...]
    chains: tuple[RampChain, ...] = ()
    rejected: tuple[tuple[str, str], ...] = ()
    skipped: tuple[tuple[str, str], ...] = ()
    warnings: tuple[str, ...] = ()
