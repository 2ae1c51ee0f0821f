"""The whole highway: several runs fused, both carriageways, the roads beyond the ramps,
and the OSM-only mode.

One module per concern:

- :mod:`.runs` -- runs into one frame, grouped by carriageway, fused with a consistency
  check of their overlaps.
- :mod:`.merge` -- several carriageways' roads and junctions into one network.
- :mod:`.build` -- :func:`build_highway` (runs and OSM) and :func:`build_osm_only`.
"""

from .build import Carriageway, HighwayResult, build_highway, build_osm_only
from .merge import carriageway_of, merge_parts
from .runs import (
    Disagreement,
    FusedRun,
    RunGroups,
    check_consistency,
    fuse_runs,
    group_runs,
    run_in_frame,
)

__all__ = [
    "Carriageway",
    "Disagreement",
    "FusedRun",
    "HighwayResult",
    "RunGroups",
    "build_highway",
    "build_osm_only",
    "carriageway_of",
    "check_consistency",
    "fuse_runs",
    "group_runs",
    "merge_parts",
    "run_in_frame",
]
