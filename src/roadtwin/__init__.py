"""roadtwin: georeferenced ASAM OpenDRIVE digital twins of highways.

Fuses a mobile-mapping run (poses, road-edge points, lane-marking samples) with the
OpenStreetMap road graph into one connected OpenDRIVE map::

    import roadtwin

    run = roadtwin.load_run("run/")
    osm_graph = roadtwin.load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    result = roadtwin.build_map(run, osm_graph)
    roadtwin.write_xodr(result.network, "out/map.xodr")
    report = roadtwin.check_file("out/map.xodr")

The names below are imported on first use, so ``import roadtwin`` (and ``roadtwin --help``)
stays fast: the heavy dependencies (OSMnx, SciPy, matplotlib) load only when needed.
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

_LAZY = {
    # loading inputs
    "load_run": "io",
    "MappingRun": "io",
    "load_osm": "osm",
    "load_osm_online": "osm",
    # building and configuring
    "build_map": "pipeline",
    "BuildResult": "pipeline",
    "PipelineConfig": "config",
    # the model
    "RoadNetwork": "model",
    "Road": "model",
    "Junction": "model",
    # writing and reading maps
    "write_xodr": "xodr",
    "read_xodr": "xodr",
    "write_kml": "export",
    "write_geojson": "export",
    "plot_network": "export",
    "plot_overview": "plots",
    # checking and evaluating
    "check_file": "check",
    "check_network": "check",
    "evaluate": "evaluation",
    "evaluate_paths": "evaluation",
    "self_consistency": "evaluation",
    "write_report": "report",
    # simulating
    "simulate_run": "simulate",
    "load_scenario": "simulate",
    # errors
    "RoadtwinError": "_errors",
    "InputError": "_errors",
    "FitError": "_errors",
    "InputWarning": "_errors",
}

__all__ = [
    "BuildResult",
    "FitError",
    "InputError",
    "InputWarning",
    "Junction",
    "MappingRun",
    "PipelineConfig",
    "Road",
    "RoadNetwork",
    "RoadtwinError",
    "__version__",
    "build_map",
    "check_file",
    "check_network",
    "evaluate",
    "evaluate_paths",
    "load_osm",
    "load_osm_online",
    "load_run",
    "load_scenario",
    "plot_network",
    "plot_overview",
    "read_xodr",
    "self_consistency",
    "simulate_run",
    "write_geojson",
    "write_kml",
    "write_report",
    "write_xodr",
]

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from ._errors import FitError, InputError, InputWarning, RoadtwinError
    from .check import check_file, check_network
    from .config import PipelineConfig
    from .evaluation import evaluate, evaluate_paths, self_consistency
    from .export import plot_network, write_geojson, write_kml
    from .io import MappingRun, load_run
    from .model import Junction, Road, RoadNetwork
    from .osm import load_osm, load_osm_online
    from .pipeline import BuildResult, build_map
    from .plots import plot_overview
    from .report import write_report
    from .simulate import load_scenario, simulate_run
    from .xodr import read_xodr, write_xodr


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'roadtwin' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # cache: the next access is a plain attribute
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
