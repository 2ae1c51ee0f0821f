"""``roadtwin build`` of the whole highway: several runs, one run with the OSM roads around
it, or OSM alone.

Reads the inputs (runs, or the OSM-only area), builds (:func:`~.build.build_highway`,
:func:`~.build.build_osm_only`), writes ``map.xodr``, ``map.kml``, ``map.geojson``,
``map.png`` and ``build.json`` atomically, then checks and drives the map like the
single-run build (:mod:`roadtwin.cli`).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .._errors import InputError

if TYPE_CHECKING:  # pragma: no cover
    from .build import HighwayResult

NAMES = ("map.xodr", "map.kml", "map.geojson", "map.png", "build.json")


def _round(value: float, digits: int = 3) -> float:
    return round(float(value), digits)


def build_info(result: HighwayResult) -> dict[str, Any]:
    """``build.json`` of a highway build: the single-run keys (``summary``, ``timings_s``,
    ``ramps`` of the measured carriageways, ``rejected``, ``skipped``, ``warnings``) plus
    ``carriageways`` and ``beyond``."""
    from ..cli import _ramp_info

    carriageways = []
    ramps = []
    rejected: list[list[str]] = []
    skipped: list[list[str]] = []
    for cw in result.carriageways:
        cw_ramps = []
        for rid, ramp in zip(cw.ramp_road_ids, cw.topology.ramps, strict=True):
            info = _ramp_info(rid, ramp) | {"carriageway": cw.number}
            cw_ramps.append(info)
            if cw.source == "lidar":
                ramps.append(info)
        rejected += [list(x) for x in cw.ramp_set.rejected]
        skipped += [list(x) for x in (*cw.ramp_set.skipped, *cw.topology.skipped)]
        entry: dict[str, Any] = {
            "number": cw.number,
            "source": cw.source,
            "runs": list(cw.runs),
            "partner": cw.partner,
            "road_ids": list(cw.road_ids),
            "ramps": cw_ramps,
        }
        if cw.fused is not None:
            entry["disagreements"] = [
                {
                    "runs": list(d.runs),
                    "edge": d.edge,
                    "s0_m": _round(d.s0_m),
                    "s1_m": _round(d.s1_m),
                    "offset_m": _round(d.offset_m),
                    "noise_m": _round(d.noise_m),
                    "kept": d.kept,
                }
                for d in cw.fused.disagreements
            ]
            entry["path_pieces"] = [list(p) for p in cw.fused.path_pieces]
            entry["dropped_points"] = cw.fused.dropped_points
            entry["run_self_consistency_rmse_m"] = {
                name: {
                    k: None if v is None else _round(v, 4)
                    for k, v in sc.items()
                    if k.endswith("_rmse_m")
                }
                for name, sc in cw.run_self_consistency
            }
        if cw.osm_road is not None:
            entry["osm_way_ids"] = [str(w) for w in cw.osm_road.chain.way_ids]
            med = cw.osm_road.median_m
            if med.size:
                entry["median_m"] = {
                    "min": _round(med[:, 1].min()),
                    "median": _round(np.median(med[:, 1])),
                    "max": _round(med[:, 1].max()),
                }
            entry["notes"] = list(cw.osm_road.notes)
        carriageways.append(entry)
    beyond = [
        {
            "road_id": b.road.id,
            "ramp_road_id": b.ramp_road_id,
            "ramp_type": b.ramp_type,
            "name": b.road.name,
            "length_m": _round(b.road.length),
            "stop": b.stop,
            "speed_limit_mps": None
            if b.road.speed_limit_mps is None
            else _round(b.road.speed_limit_mps),
            "osm_way_ids": [str(w) for w in b.road.osm_way_ids],
        }
        for b in result.beyond
    ]
    return {
        "summary": result.summary(),
        "timings_s": result.timings_s,
        "ramps": ramps,
        "rejected": rejected,
        "skipped": skipped,
        "warnings": list(result.warnings),
        "carriageways": carriageways,
        "beyond": beyond,
    }


def _inputs(args: argparse.Namespace, cfg):
    """(runs, area): the mapping runs (in the first run's frame), or the OSM-only area."""
    from .area import area_from_bbox, is_osm_only_run, load_osm_area, parse_bbox

    if args.bbox is not None and args.osm is None and not args.run_dirs:
        raise InputError("build --bbox: give the OSM file with --osm FILE")
    if not args.run_dirs:
        if args.osm is None:
            raise InputError("build: give RUN_DIR(s), or --osm FILE --bbox ... for OSM alone")
        if args.bbox is None:
            raise InputError("build --osm FILE without RUN_DIR: give the area with --bbox")
        return [], area_from_bbox(args.osm, parse_bbox(args.bbox), traffic_side=args.traffic)
    if len(args.run_dirs) == 1 and is_osm_only_run(args.run_dirs[0]):
        area = load_osm_area(args.run_dirs[0])
        if args.bbox is not None:
            from dataclasses import replace

            area = replace(area, bbox=parse_bbox(args.bbox))
        return [], area
    if args.bbox is not None:
        raise InputError("build --bbox is for the OSM-only mode (no run with a trajectory)")
    from ..inputs import load_runs

    return load_runs(args.run_dirs, cfg.load), None


def cmd_build_highway(args: argparse.Namespace) -> int:
    """``roadtwin build`` of the whole highway (see the module docstring)."""
    from dataclasses import replace

    from .._files import check_output_dir, staged_output
    from ..cli import (
        _build_config,
        _check_and_drive,
        _drive_lines,
        _print_build,
        progress,
    )
    from .area import load_area_graph

    started = time.perf_counter()
    cfg = _build_config(args)
    if args.carriageway_only:
        cfg = replace(cfg, highway=replace(cfg.highway, opposite=False, beyond=False))
    tools = None
    if not args.no_drive:
        from ..drive import find_esmini

        tools = find_esmini(args.esmini)
    steps = ["load", "build map", "write files", *(["check"] if not args.no_check else [])]
    if tools is not None:
        steps.append("drive")
    bar = progress(args, total=len(steps), unit="step")
    times: dict[str, float] = {}

    t0 = time.perf_counter()
    bar.set_description("load")
    runs, area = _inputs(args, cfg)
    if area is not None:
        out = args.output if args.output is not None else (area.root or Path(".")) / "out"
        if args.output is None and area.root is None:
            raise InputError("build --osm: give the output folder with -o")
        check_output_dir(
            out,
            inputs=area.input_files,
            input_dirs=[area.root] if area.root else [],
            names=NAMES,
        )
        graph = load_area_graph(area, config=cfg.load)
    else:
        out = args.output if args.output is not None else runs[0].root / "out"
        check_output_dir(
            out,
            inputs=[f for r in runs for f in r.input_files],
            input_dirs=[r.root for r in runs],
            names=NAMES,
        )
        from ..inputs import load_osm_around

        graph = load_osm_around(runs, cfg.load, osm=args.osm, osm_online=args.osm_online)
    times["load"] = time.perf_counter() - t0
    bar.update()

    bar.set_description("build map")
    # the building and writing modules load when their stage begins (start-up time)
    from ..export import plot_network, write_geojson, write_kml
    from ..xodr import write_xodr
    from .build import build_highway, build_osm_only

    if area is not None:
        result = build_osm_only(
            graph,
            area.frame,
            traffic_side=area.traffic_side,
            name=area.name,
            box_xy=area.box_xy,
            config=cfg,
        )
    else:
        result = build_highway(runs, graph, config=cfg)
    times["build map"] = sum(result.timings_s.values())
    bar.update()

    t0 = time.perf_counter()
    bar.set_description("write files")
    frame = result.frame
    fused = [c.fused.run for c in result.carriageways if c.fused is not None]
    plot_run = None
    if fused:  # every carriageway's points under the map (the first run's path)
        plot_run = replace(
            fused[0],
            edges=np.vstack([r.edges for r in fused]),
            edge_side=np.concatenate([r.edge_side for r in fused]),
            lane_samples=np.vstack([r.lane_samples for r in fused]),
        )
    with staged_output(out) as tmp:
        write_xodr(result.network, tmp / "map.xodr")
        write_kml(result.network, frame, tmp / "map.kml")
        write_geojson(result.network, frame, tmp / "map.geojson")
        plot_network(result.network, plot_run, tmp / "map.png")
        text = json.dumps(build_info(result), indent=2) + "\n"
        (tmp / "build.json").write_bytes(text.encode("utf-8"))
    times["write files"] = time.perf_counter() - t0
    bar.update()

    report, drive_report = _check_and_drive(out, args, cfg, tools, bar, times)
    lines = summary_lines(result, out, times, started)
    lines += _drive_lines(drive_report, skipped=args.no_drive, out=out)
    return _print_build(lines, report, drive_report)


def summary_lines(
    result: HighwayResult, out: Path, times: dict[str, float], started: float
) -> list[str]:
    """The printed summary of a highway build."""
    s = result.summary()
    lines = []
    for cw in result.carriageways:
        what = f"runs {', '.join(cw.runs)}" if cw.runs else "OSM"
        if cw.osm_road is not None:
            what = f"OSM ways {', '.join(str(w) for w in cw.osm_road.chain.way_ids[:3])}"
            if len(cw.osm_road.chain.way_ids) > 3:
                what += ", ..."
        other = f", other direction of {cw.partner}" if cw.partner else ""
        n_exit = sum(r.type == "exit" for r in cw.topology.ramps)
        n_entry = len(cw.topology.ramps) - n_exit
        km = sum(
            r.length
            for r in result.network.roads
            if r.id in set(cw.road_ids) and r.name == "mainline"
        )
        lines.append(
            f"carriageway {cw.number}: {cw.source} ({what}{other}), {km / 1000:.3f} km, "
            f"{n_exit} exit, {n_entry} entry"
        )
        for rid, r in zip(cw.ramp_road_ids, cw.topology.ramps, strict=True):
            lines.append(
                f"  road {rid:>4}  {r.type:<5} at s={r.station_m:8.1f} m ({r.station_source}), "
                f"{r.lanes} lane(s) by {r.lane_rule}"
            )
        if cw.fused is not None:
            for d in cw.fused.disagreements:
                lines.append(f"  {d.message()}")
    for b in result.beyond:
        name = f" {b.road.name!r}" if b.road.name else ""
        lines.append(
            f"beyond     road {b.road.id}{name} after {b.ramp_type} road {b.ramp_road_id}, "
            f"{b.road.length:.0f} m (ends: {b.stop})"
        )
    lines += [
        f"roads      {s['roads']} ({s['mainline_roads']} mainline, {s['connecting_roads']} "
        f"connecting, {s['beyond_roads']} beyond the ramps), {s['junctions']} junctions",
        f"length     {s['total_km']:.3f} km ({s['mainline_km']:.3f} km mainline, "
        f"{s['ramp_km']:.3f} km ramps)",
        "time       " + ", ".join(f"{k} {v:.2f} s" for k, v in times.items()),
        f"total      {time.perf_counter() - started:.2f} s",
        f"written    {', '.join(str(out / n) for n in NAMES[:4])}",
    ]
    lines += [f"note       {w}" for w in result.warnings]
    return lines
