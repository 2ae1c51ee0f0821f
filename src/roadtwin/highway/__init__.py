"""The whole highway: several runs fused, both carriageways, the roads beyond the ramps,
and the OSM-only mode.

One module per concern:

- :mod:`.runs` -- runs into one frame, grouped by carriageway, fused with a consistency
  check of their overlaps.
- :mod:`.merge` -- several carriageways' roads and junctions into one network.
- :mod:`.build` -- :func:`build_highway` (runs and OSM) and :func:`build_osm_only`.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

# the names load on first use: ``roadtwin build`` imports :mod:`.command` before it reads
# the runs, and the building modules (evaluation, OSM roads) only when it builds
_LAZY = {
    "Carriageway": "build",
    "HighwayResult": "build",
    "build_highway": "build",
    "build_osm_only": "build",
    "carriageway_of": "merge",
    "merge_parts": "merge",
    "Disagreement": "runs",
    "FusedRun": "runs",
    "RunGroups": "runs",
    "check_consistency": "runs",
    "fuse_runs": "runs",
    "group_runs": "runs",
    "run_in_frame": "runs",
}

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
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


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})


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
