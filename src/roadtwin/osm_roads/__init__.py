"""Roads built from OpenStreetMap alone, at OSM accuracy.

What no run measured but the highway has: the carriageway of the other direction
(:func:`opposite_carriageway`, placed beside the measured one), every carriageway of an
area for the OSM-only mode (:func:`carriageway_from_osm`), and the roads the ramps lead to
(:func:`beyond_roads`), so that no ramp ends in a dead end where OSM continues. One module
per concern:

- :mod:`.chains` -- one-way motorway/trunk carriageways of the OSM graph, tags
  (lane counts per direction, ``maxspeed``).
- :mod:`.lanes` -- cross-sections (widths measured or default) and lane sections from the
  OSM lane counts.
- :mod:`.carriageway` -- the carriageway roads.
- :mod:`.beyond` -- the roads beyond the ramps and their links.

OSM data: (c) OpenStreetMap contributors, ODbL.
"""

from .beyond import BeyondRoad, beyond_road, beyond_roads, link_beyond
from .carriageway import OsmRoad, carriageway_from_osm, opposite_carriageway, osm_road_tags
from .chains import OsmCarriageway, carriageway_chains, maxspeed_mps
from .lanes import CrossSection, lane_sections, measured_cross_section

__all__ = [
    "BeyondRoad",
    "CrossSection",
    "OsmCarriageway",
    "OsmRoad",
    "beyond_road",
    "beyond_roads",
    "carriageway_chains",
    "carriageway_from_osm",
    "lane_sections",
    "link_beyond",
    "maxspeed_mps",
    "measured_cross_section",
    "opposite_carriageway",
    "osm_road_tags",
]
