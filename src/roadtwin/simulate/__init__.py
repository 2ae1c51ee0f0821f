"""Synthetic mapping runs with ground truth (``roadtwin simulate``).

A subpackage rather than one ``simulate.py`` because it outgrows ~800 lines; one module
per concern, in pipeline order:

- ``scenario.py``   TOML schema, validation (clear InputErrors) and realistic defaults
- ``alignment.py``  exact straights/arcs/clothoids, cutting/offsetting, vertical profiles
- ``truth.py``      the ground-truth RoadNetwork (mainline roads, ramps, direct junctions)
- ``sensor.py``     the mapping car: noisy poses, road-edge points, lane-marking samples
- ``osm_writer.py`` OSM XML as a mapper would draw the same place
- ``writer.py``     the run folder (DESIGN.md section 3) plus truth.xodr/json/trajectory
- ``from_osm.py``   clothoid-chain fits of real OSM ways and OSM cropping (``real_a9``)
"""

from __future__ import annotations

from .scenario import Scenario, bundled_scenarios, load_scenario

__all__ = ["Scenario", "bundled_scenarios", "load_scenario", "simulate_run"]


def __getattr__(name: str):
    if name == "simulate_run":
        from .writer import simulate_run

        return simulate_run
    raise AttributeError(name)
