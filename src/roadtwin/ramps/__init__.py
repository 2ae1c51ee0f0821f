"""Ramps from OpenStreetMap: candidates, lane count, merge/exit, geometry re-anchored on the
measured mainline.

The mapping car never drives the ramps; the OSM graph supplies them (paper, "Ramp
Reconstruction"). This module follows the paper's steps and adds what makes a ramp really
attach to the measured road (DESIGN.md section 4):

1. :func:`find_candidates` -- Algorithm 1: directed ``*_link`` edges within ``d_r`` of the
   trajectory.
2. :func:`extract_ramp_chains` -- consecutive link edges merged into one chain from the
   attachment on the driven carriageway up to ``max_ramp_length_m`` or the next OSM
   junction; links of the opposite carriageway and of unrelated roads are rejected by a
   direction check (heading at the attachment vs the driven direction); a chain on the
   median side is an inner ramp (a left exit on a right-hand road). Merge/exit from directed
   connectivity (the paper's rule), cross-checked with geometry.
3. :func:`infer_lane_count` -- Algorithm 2 (``lanes:forward`` > ``lanes`` > ``turn:lanes``
   > highway class); the measured mainline lane-count change at the gore
   (:func:`gores_from_lane_events`, :func:`gore_events`) overrides it when present, and
   the measured gore decides the station where the ramp leaves or joins.
4. :func:`build_ramp_road` -- the reference line (the ramp's median-side edge, offset from
   the smoothed OSM centreline, trimmed or extended to the gore) is a curvature-bounded
   clothoid spline anchored exactly on the inner border of the mainline lane it continues
   (the deceleration/acceleration lane: i.e. the outer border of the outermost through
   lane; without a measured gore the outermost lane, which the ramp splits off) with the
   mainline's heading and curvature (:func:`fit_ramp_shape`): no knots on tight loops,
   radius >= ``min_radius_m``; the attachment piece is an exact Hermite ParamPoly3, the
   rest fitted with :func:`roadtwin.fitting.fit_parampoly3_chain`.
5. LiDAR evidence: the road edges and lane markings measured past the gore (not explained
   by the mainline) are tracked outward from the gore in the same fit: each point is
   associated with the nearest predicted ramp boundary of its kind and gives the ramp's
   first part and its shoulder and lane widths; beyond the last measured point the OSM
   shape decides again. No or too little evidence: OSM shape and the documented default
   widths (``RampConfig``).

Ramp cross-section = the mainline's layout: inner shoulder (opening from zero width at
the gore), driving lanes (the first ones starting with the widths of the mainline lanes
they continue, blending to the ramp's lane width), hard shoulder (continuing the
mainline's hard shoulder at a measured gore, else opening from zero width).

All coordinates are in the mapping frame (metres, radians CCW from +x). Lane layout
conventions (right-hand traffic; left-hand traffic mirrors): ramp reference line = the
ramp's left edge, ramp lanes ``-1`` (inner shoulder), ``-2 .. -(n+1)`` (driving),
``-(n+2)`` (hard shoulder) to its right.

Why a package: the ramp stage grew past the ~800 lines STYLE.md allows one module, so it is
split with one concern per module; everything is imported from ``roadtwin.ramps`` as before:

- :mod:`.records` -- data records (``RampCandidate``, ``RampChain``, ``GoreEvent``,
  ``RampEvidence``, ``Ramp``, ``RampSet``), type aliases and shared thresholds.
- :mod:`.lanes` -- Algorithm 2, lane count from OSM tags.
- :mod:`.candidates` -- Algorithm 1, ramp chains, direction check and side.
- :mod:`.gores` -- measured gores and the mainline borders a ramp attaches to.
- :mod:`.geometry` -- Hermite pieces, smoothing, mainline boundary distances.
- :mod:`.shape` -- the curvature-bounded reference line and the evidence fit
  (:func:`fit_ramp_shape`).
- :mod:`.road` -- the ramp road and its cross-section (:func:`build_ramp_road`).
- :mod:`.build` -- the stage, :func:`build_ramps`.
"""

# Names after "as" are kept importable from roadtwin.ramps as before but stay out of __all__.
from .build import build_ramps
from .candidates import extract_ramp_chains, find_candidates
from .geometry import hermite_piece
from .gores import gore_events, gores_from_lane_events
from .gores import outer_driving_lane as outer_driving_lane
from .lanes import infer_lane_count
from .records import EdgeKey as EdgeKey
from .records import FloatArray as FloatArray
from .records import GoreEvent, Ramp, RampCandidate, RampChain, RampEvidence, RampSet
from .records import RampType as RampType
from .records import TrafficSide as TrafficSide
from .road import build_ramp_road
from .road import width_transition as width_transition
from .shape import fit_ramp_shape

__all__ = [
    "GoreEvent",
    "Ramp",
    "RampCandidate",
    "RampChain",
    "RampEvidence",
    "RampSet",
    "build_ramp_road",
    "build_ramps",
    "extract_ramp_chains",
    "find_candidates",
    "fit_ramp_shape",
    "gore_events",
    "gores_from_lane_events",
    "hermite_piece",
    "infer_lane_count",
]
