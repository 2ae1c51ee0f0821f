"""Drive every route of a map in esmini: the proof that a map is usable in a simulator.

``drive_map(MAP, OUT)`` finds the routes a driver can take (:mod:`.routes`: the mainline
end to end, into every exit, from every entry, through every junction connection of a
driving lane), writes one OpenSCENARIO file per route into ``OUT/scenarios``
(:mod:`.scenario`), runs each in esmini headless when esmini is found (:mod:`.esmini`),
judges the recording (:mod:`.judge`) and writes ``OUT/drive.json`` (:mod:`.results`).
Recordings of failed routes stay in ``OUT/runs`` (``.csv`` from ``dat2csv --extended``,
``.dat``, esmini's ``.log``); of passed routes only the log is kept.

The modules depend one way: routes <- scenario, judge <- results <- this orchestrator.
"""

from __future__ import annotations

import logging
import os
import re
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ..config import DriveConfig
from ..model import RoadNetwork
from .esmini import Esmini, find_esmini, read_recording, run_esmini
from .judge import Fault, Judgement, judge_recording
from .results import DriveReport, RouteResult, write_drive_json
from .routes import LanePoint, Route, find_routes, traffic_side
from .scenario import write_scenario

log = logging.getLogger(__name__)

__all__ = [
    "DriveReport",
    "Esmini",
    "Fault",
    "Judgement",
    "LanePoint",
    "Route",
    "RouteResult",
    "drive_map",
    "find_esmini",
    "find_routes",
    "judge_recording",
    "read_recording",
    "run_esmini",
    "traffic_side",
    "write_drive_json",
    "write_scenario",
]


def _file_name(index: int, route: Route) -> str:
    slug = re.sub(r"[^A-Za-z0-9]+", "_", route.name.replace("->", "to")).strip("_")
    return f"{index:03d}_{slug}.xosc"


def _drive_one(
    route: Route,
    scenario: Path,
    runs: Path,
    network: RoadNetwork,
    tools: Esmini,
    cfg: DriveConfig,
) -> RouteResult:
    run = run_esmini(tools, scenario, runs, timestep_s=cfg.timestep_s, timeout_s=cfg.timeout_s)
    if run.csv is None:
        tail = "; ".join(run.log_tail) or "no log"
        fault = Fault("esmini", f"esmini wrote no recording (exit {run.returncode}): {tail}")
        return RouteResult(route, "failed", (fault,), None, run.messages, scenario, run.wall_s)
    judgement = judge_recording(read_recording(run.csv), route, network, config=cfg)
    faults = judgement.faults
    if run.returncode != 0:
        faults = (Fault("esmini", f"esmini exited with code {run.returncode}"), *faults)
    status = "failed" if faults else "passed"
    if status == "passed":  # keep the log only: recordings of long routes are megabytes
        for ext in (".dat", ".csv"):
            (runs / f"{scenario.stem}{ext}").unlink(missing_ok=True)
    return RouteResult(route, status, faults, judgement, run.messages, scenario, run.wall_s)


def drive_map(
    map_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    esmini: Esmini | None = None,
    config: DriveConfig | None = None,
    network: RoadNetwork | None = None,
    progress: Callable[[Iterable, int], Iterable] | None = None,
) -> DriveReport:
    """Find, write and (with ``esmini``) drive every route of the map at ``map_path``.

    Parameters
    ----------
    map_path
        The OpenDRIVE map (the scenarios reference it by a relative path).
    out_dir
        Folder for ``scenarios/``, ``runs/`` and ``drive.json``.
    esmini
        From :func:`find_esmini`; None writes the scenarios without driving them.
    config
        Speed, time step and the pass criteria (:class:`roadtwin.config.DriveConfig`).
    network
        The map already read (else it is read from ``map_path``).
    progress
        ``progress(iterable, total)`` wraps the drives as they finish (e.g. a tqdm bar);
        the library never prints.

    Returns
    -------
    DriveReport
        Routes without a lane path fail without being run; without esmini the others are
        ``not run``.
    """
    from ..xodr import read_xodr

    started = time.perf_counter()
    cfg = config or DriveConfig()
    map_path = Path(map_path)
    network = network if network is not None else read_xodr(map_path)
    out = Path(out_dir)
    scenarios, runs = out / "scenarios", out / "runs"
    scenarios.mkdir(parents=True, exist_ok=True)
    if esmini is not None:
        runs.mkdir(parents=True, exist_ok=True)
    routes = find_routes(network, config=cfg)
    results: list[RouteResult | None] = [None] * len(routes)
    todo = []
    for index, route in enumerate(routes):
        if route.problem:
            results[index] = RouteResult(route, "failed", (Fault("no_lane_path", route.problem),))
            continue
        path = scenarios / _file_name(index + 1, route)
        scenario = write_scenario(route, map_path, path, config=cfg)
        if esmini is None:
            results[index] = RouteResult(route, "not run", scenario=scenario)
        else:
            todo.append((index, route, scenario))
    written = {r.scenario.name for r in results if r is not None and r.scenario is not None}
    written |= {scenario.name for _, _, scenario in todo}
    if todo:
        with ThreadPoolExecutor(max_workers=max(1, cfg.workers)) as pool:
            done: Iterable = pool.map(
                lambda item: (item[0], _drive_one(item[1], item[2], runs, network, esmini, cfg)),
                todo,
            )
            if progress is not None:
                done = progress(done, len(todo))
            for index, result in done:
                results[index] = result
    # files of an earlier drive (another map, or routes this one does not have)
    stems = {Path(name).stem for name in written}
    for stale in (*scenarios.glob("*.xosc"), *(runs.glob("*.*") if runs.is_dir() else ())):
        if stale.stem not in stems or (stale.parent == runs and esmini is None):
            stale.unlink()
    report = DriveReport(
        str(map_path),
        tuple(r for r in results if r is not None),
        cfg,
        esmini,
        scenarios,
        time.perf_counter() - started,
    )
    write_drive_json(report, out / "drive.json")
    log.info("drive %s: %s", map_path, report.summary())
    return report
