"""Accuracy of a built map (DESIGN.md section 5).

Three families of metrics, all lateral distances in metres measured in the Frenet frame
(s along, t left positive) of the road a point projects onto:

* **Self-consistency** (the seed paper's Table 4): every road-edge point and lane sample of
  the run against the nearest road-edge / lane boundary of the mainline road (or, for the
  points the car measured on a ramp's gore, the ramp road) it projects onto,
  ``e_i = |t_m,i - t_b(s_m,i)|``; RMSE for road edge, lane boundary and both pooled (overall).
* **Against truth** (simulated runs): every ``truth_step_m`` along each true boundary of the
  true mainline, the lateral distance to the nearest reconstructed boundary of the same kind;
  elevation; ramps separately; driving-lane count per station.
* **Topology against truth**: ramps matched / missed / spurious by the proximity of their
  attachment (gore) points, merge/exit type, and lane-level reachability through lane links.

Boundary kinds follow the shared lane layout: road edges are the centre-lane border (the
reference line plus lane offset) and the outer border of the outermost lane; lane
boundaries are the outer borders of every other lane. Functions here are pure; plots and
files live in :mod:`roadtwin.report`.

A subpackage because the metrics outgrew one ~800-line module; one module per concern:

- ``frenet.py``    road roles, boundaries, projection of points onto overlapping roads
- ``metrics.py``   self-consistency and accuracy against truth
- ``topology.py``  ramps matched / missed / spurious, lane-level reachability
- ``results.py``   :class:`RunEvaluation`, :class:`EvaluationReport`, Table 4
- ``__init__.py``  :func:`evaluate`, :func:`evaluate_paths`, :func:`compare_methods`
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from .._perf import gc_paused
from ..config import EvaluationConfig
from ..model import RoadNetwork
from .frenet import (
    EDGE,
    LANE,
    Projection,
    boundary_polylines,
    driving_lane_count,
    mainline_roads,
    nearest_boundary,
    project_points,
    ramp_roads,
    road_band,
    section_boundaries,
)
from .metrics import (
    PointErrors,
    _self_summary,
    _truth_mainline,
    _truth_ramps,
    error_stats,
    self_consistency,
    self_consistency_errors,
)
from .results import (
    TABLE_TARGETS,
    EvaluationReport,
    RunEvaluation,
    combine_reports,
    format_table,
)
from .topology import lane_graph, ramp_connectivity, topology_against_truth

__all__ = [
    "EDGE",
    "LANE",
    "TABLE_TARGETS",
    "EvaluationReport",
    "PointErrors",
    "Projection",
    "RunEvaluation",
    "boundary_polylines",
    "combine_reports",
    "compare_methods",
    "driving_lane_count",
    "error_stats",
    "evaluate",
    "evaluate_paths",
    "format_table",
    "lane_graph",
    "load_truth",
    "mainline_roads",
    "nearest_boundary",
    "project_points",
    "ramp_connectivity",
    "ramp_roads",
    "road_band",
    "section_boundaries",
    "self_consistency",
    "self_consistency_errors",
    "topology_against_truth",
]

log = logging.getLogger(__name__)


def evaluate(
    network: RoadNetwork,
    run: Any,
    *,
    truth: RoadNetwork | None = None,
    truth_info: dict | None = None,
    label: str | None = None,
    method: str = "",
    map_name: str = "",
    config: EvaluationConfig | None = None,
) -> EvaluationReport:
    """Evaluate a built map against its run and, if given, against ground truth.

    Parameters
    ----------
    network
        The built map.
    run
        The :class:`~roadtwin.io.MappingRun` the map was built from.
    truth
        The true network (simulator's ``truth.xodr``), or ``None``.
    truth_info
        The simulator's ``truth.json`` (true ramps with type and station), optional.
    label, method, map_name
        Labels for the report (label defaults to the run folder name).

    Returns
    -------
    EvaluationReport
        With one :class:`RunEvaluation`.
    """
    cfg = config or EvaluationConfig()
    traffic_side = getattr(run, "traffic_side", "right")
    if not mainline_roads(network):
        log.warning("the map has no road named 'mainline': self-consistency is undefined")
    edge, lane, counts = self_consistency_errors(network, run, config=cfg)
    details = {edge.name: edge, lane.name: lane}
    truth_result = None
    if truth is not None:
        from ..highway.evaluate import carriageways_of_truth

        # a map of the whole highway is measured on the carriageways the truth holds
        measured = carriageways_of_truth(network, truth)
        truth_result, d1 = _truth_mainline(measured, truth, cfg, getattr(run, "lane_samples", None))
        ramps, d2 = _truth_ramps(measured, truth, cfg)
        truth_result.update(ramps)
        details.update(d1)
        details.update(d2)
        topology = topology_against_truth(
            measured, truth, truth_info=truth_info, traffic_side=traffic_side, config=cfg
        )
    else:
        topology = {"ramps": ramp_connectivity(network, traffic_side=traffic_side)}
    root = getattr(run, "root", "")
    summary = _self_summary(edge, lane, counts)
    log.info(
        "evaluated %s: self-consistency RMSE edge %.3f m, lane %.3f m, overall %.3f m",
        label or root,
        summary["road_edge_rmse_m"],
        summary["lane_boundary_rmse_m"],
        summary["overall_rmse_m"],
    )
    result = RunEvaluation(
        label=label or (getattr(root, "name", "") or str(root)),
        run_dir=str(root),
        map_name=map_name,
        method=method,
        self_consistency=summary,
        truth=truth_result,
        topology=topology,
        details=details,
        map_lines=boundary_polylines(network),
    )
    return EvaluationReport((result,))


# ---------------------------------------------------------------------------
# files
# ---------------------------------------------------------------------------


# ---------------------------------------------------------------------------
# files and method comparison
# ---------------------------------------------------------------------------


def load_truth(path: str | Path) -> tuple[RoadNetwork, dict | None]:
    """Read a truth network and the ``truth.json`` beside it (``None`` if absent).

    Raises
    ------
    InputError
        The xodr cannot be read or truth.json is not valid JSON.
    """
    from .._errors import InputError, reason
    from ..xodr import read_xodr

    path = Path(path)
    network = read_xodr(path)
    info_path = path.with_name("truth.json")
    if not info_path.is_file():
        return network, None
    try:
        info = json.loads(info_path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        msg = f"{info_path}: not valid JSON ({reason(exc)})"
        raise InputError(msg) from None
    _check_truth_info(info, info_path)
    return network, info


def _check_truth_info(info: Any, path: Path) -> None:
    """``truth.json`` must be an object whose ``ramps`` (if any) is a list of objects with
    ``road_id``, ``type`` (``exit``/``entry``) and an optional numeric ``station_m``."""
    from .._errors import InputError

    if not isinstance(info, dict):
        kind = type(info).__name__
        msg = f"{path}: expected a JSON object (the simulator's truth.json), not a {kind}"
        raise InputError(msg)
    ramps = info.get("ramps")
    if ramps is None:
        return
    if not isinstance(ramps, list):
        msg = f"{path}: 'ramps' must be a list of ramp objects"
        raise InputError(msg)
    for i, ramp in enumerate(ramps):
        where = f"{path}: ramps[{i}]"
        if not isinstance(ramp, dict):
            raise InputError(f"{where}: expected an object")
        for key in ("road_id", "type"):
            if not isinstance(ramp.get(key), (str, int)) or isinstance(ramp.get(key), bool):
                raise InputError(f"{where}: missing or invalid '{key}'")
        if ramp["type"] not in ("exit", "entry"):
            raise InputError(f"{where}: 'type' must be 'exit' or 'entry'")
        station = ramp.get("station_m")
        if station is not None and (
            isinstance(station, bool)
            or not isinstance(station, (int, float))
            or not math.isfinite(station)
        ):
            raise InputError(f"{where}: 'station_m' must be a finite number (metres) or null")


def evaluate_paths(
    map_path: str | Path,
    run_dirs: Sequence[str | Path],
    *,
    truth_path: str | Path | None = None,
    method: str = "",
    config: EvaluationConfig | None = None,
    progress: Callable[[Iterable], Iterable] | None = None,
) -> EvaluationReport:
    """Evaluate a map file against one or several run folders.

    Parameters
    ----------
    map_path
        The built ``.xodr``.
    run_dirs
        Mapping-run folders.
    truth_path
        Ground-truth ``.xodr`` for every run; if ``None``, each run's own
        ``RUN_DIR/truth.xodr`` is used where it exists.
    progress
        Optional wrapper of the run iterable (e.g. ``tqdm``).
    """
    from ..io import load_run
    from ..xodr import read_xodr

    with gc_paused():  # linear on maps of 10^4 roads (see roadtwin._perf)
        network = read_xodr(map_path)
        shared = load_truth(truth_path) if truth_path is not None else None
        reports = []
        dirs = [Path(d) for d in run_dirs]
        for run_dir in progress(dirs) if progress else dirs:
            run = load_run(run_dir)
            truth, info = shared if shared is not None else (None, None)
            if shared is None and (run_dir / "truth.xodr").is_file():
                truth, info = load_truth(run_dir / "truth.xodr")
            reports.append(
                evaluate(
                    network,
                    run,
                    truth=truth,
                    truth_info=info,
                    method=method,
                    map_name=Path(map_path).name,
                    config=config,
                )
            )
    return combine_reports(reports)


def compare_methods(
    run: Any,
    osm_graph: Any = None,
    *,
    truth: RoadNetwork | None = None,
    truth_info: dict | None = None,
    methods: Sequence[str] = ("default", "paper"),
    config: Any = None,
    eval_config: EvaluationConfig | None = None,
    include_truth: bool = True,
) -> EvaluationReport:
    """Build a run's map with each mainline method and evaluate them side by side.

    Parameters
    ----------
    run
        The :class:`~roadtwin.io.MappingRun`.
    osm_graph
        OSM graph for the ramps (``roadtwin.osm.load_osm``); loaded from ``run.osm_path``
        when ``None`` and the run names one.
    methods
        Values of ``MainlineConfig.method`` to build with.
    config
        :class:`~roadtwin.config.PipelineConfig` (defaults if ``None``); only the mainline
        method is changed per build.

    include_truth
        With a truth network, also evaluate the truth itself against the run (method
        ``"truth"``): the floor of the self-consistency metric set by the measurement noise.

    Returns
    -------
    EvaluationReport
        One :class:`RunEvaluation` per method (``method`` set), in the order given, then
        the truth's.
    """
    from ..config import PipelineConfig
    from ..pipeline import build_map

    cfg = config if config is not None else PipelineConfig()
    if osm_graph is None and getattr(run, "osm_path", None) is not None:
        from ..osm import load_osm

        osm_graph = load_osm(
            run.osm_path, frame=run.frame, around_xy=run.trajectory.xy, config=cfg.load
        )
    reports = []
    for method in methods:
        build_cfg = cfg.with_method(method)
        result = build_map(run, osm_graph, config=build_cfg)
        reports.append(
            evaluate(
                result.network,
                run,
                truth=truth,
                truth_info=truth_info,
                method=method,
                map_name=f"{method} build",
                config=eval_config,
            )
        )
    if truth is not None and include_truth:
        reports.append(
            evaluate(
                truth,
                run,
                truth=truth,
                truth_info=truth_info,
                method="truth",
                map_name="truth",
                config=eval_config,
            )
        )
    return combine_reports(reports)
