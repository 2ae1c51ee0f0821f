"""Ground truth from real OSM: any motorway/trunk carriageway chain -> a lane-level map.

A subpackage split by concern, in pipeline order:

- ``settings.py``  frozen settings with realistic defaults (chain, widths, lane events,
  ramps, OSM offset, heights, junction style)
- ``style.py``     national style by the origin's country: traffic side, widths, markings
- ``chain.py``     one-way motorway/trunk ways of the extract, chain selection and window
- ``links.py``     the chain's ramps as OSM draws them (exits, entries, side, lanes)
- ``geometry.py``  offset field (OSM drawn 1-5 m off), smoothing, ramp shapes, ParamPoly3
- ``layout.py``    lane strips along the mainline: lane gains/drops, auxiliary lanes,
  weaving, shoulders
- ``elevation.py`` grades and ramp profiles that clear the mainline where they cross it
- ``network.py``   lane sections, roads cut at junctions, lane links by strip key
- ``build.py``     :func:`truth_from_osm`, wiring the stages

OSM data: (c) OpenStreetMap contributors, ODbL.
"""

from __future__ import annotations

from .build import OsmTruth, RampTruth, truth_from_osm
from .settings import (
    ChainSelection,
    CrossSection,
    Elevation,
    LaneEvents,
    OsmOffset,
    OsmTruthSettings,
    RampShape,
)
from .style import RoadStyle, road_style

__all__ = [
    "ChainSelection",
    "CrossSection",
    "Elevation",
    "LaneEvents",
    "OsmOffset",
    "OsmTruth",
    "OsmTruthSettings",
    "RampShape",
    "RampTruth",
    "RoadStyle",
    "road_style",
    "truth_from_osm",
]
