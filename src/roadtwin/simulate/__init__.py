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

Runs along a route through any road network (``roadtwin simulate --xodr``; the network
is the ground truth):

- ``route.py``        through-routes: roads, driving directions, junction passages
- ``carriageway.py``  the carriageway leg by leg: source lanes, bridging in junctions
- ``leg_samples.py``  dense cross-sections of a leg (borders, road marks, breakpoints)
- ``canonical.py``    fitted re-expression of a chain of legs as one road (<= 1 mm)
- ``route_truth.py``  the canonical truth: mainline roads, ramps, direct junctions, gores
- ``markings.py``     national marking styles (de/at/us/uk/fr), painted road-mark types
- ``route_sensor.py`` the car's path along a lane, paved-area edges, paint points
- ``network_run.py``  :func:`simulate_network_run` / :func:`simulate_xodr_run`: the run
- ``osm_truth/``      a lane-level truth from any real OSM motorway / trunk chain
- ``osm_run.py``      :func:`simulate_osm_run`: that truth driven, the real extract as map
"""

from __future__ import annotations

from .scenario import Scenario, bundled_scenarios, load_scenario

__all__ = [
    "NetworkRunSettings",
    "Scenario",
    "bundled_scenarios",
    "load_scenario",
    "noisy_settings",
    "simulate_network_run",
    "simulate_osm_run",
    "simulate_run",
    "simulate_xodr_run",
]

_LAZY = {
    "simulate_run": "writer",
    "simulate_network_run": "network_run",
    "simulate_osm_run": "osm_run",
    "simulate_xodr_run": "network_run",
    "NetworkRunSettings": "network_run",
    "noisy_settings": "network_run",
}


def __getattr__(name: str):
    if name in _LAZY:
        from importlib import import_module

        return getattr(import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(name)
