"""Command-line interface: ``roadtwin inspect|simulate|build|check|evaluate|demo``.

A thin layer: it parses arguments, reads TOML config, shows progress and turns every
failure into one line on stderr (all work happens in library functions, which never print).

Exit codes: 0 ok; 1 the map has errors (``check``, ``build``); 2 bad input, or a file that
cannot be read or written (every :class:`~roadtwin._errors.RoadtwinError` and ``OSError``:
missing, not a folder, permission denied, disk full, read-only file system), one line
``roadtwin: error: ...``; 3 an internal error (a bug: ``-v`` shows the traceback); 130
interrupted (Ctrl-C); 143 terminated (SIGTERM). Interrupted or failed commands remove
their temporary files and stop the external tools they started. ``-q``/``-v`` are
accepted before or after the command; progress bars are drawn only on a terminal.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

from . import __version__
from ._errors import InputError, RoadtwinError, one_line

log = logging.getLogger("roadtwin")

EXIT_BAD_INPUT = 2
EXIT_INTERNAL = 3


def _load_config(path: Path | None):
    """Read a ``--config`` TOML file into a :class:`PipelineConfig`."""
    from .config import PipelineConfig

    if path is None:
        return PipelineConfig()
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]
    if not path.is_file():
        what = "not a file" if path.exists() else "config file not found"
        raise InputError(f"{path}: {what} (--config expects a TOML file)")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a UTF-8 text file (--config expects TOML)") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {one_line(exc)}") from None
    return PipelineConfig.from_dict(data, source=str(path))


def progress(args: argparse.Namespace, iterable: Iterable | None = None, **kwargs):
    """A tqdm bar on stderr, drawn only on a terminal and without ``-q`` (log files and
    pipes get no carriage-return garbage)."""
    from tqdm import tqdm

    disable = bool(getattr(args, "quiet", False)) or not _stderr_is_terminal()
    return tqdm(iterable, file=sys.stderr, disable=disable, **kwargs)


def _stderr_is_terminal() -> bool:
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


# ---------------------------------------------------------------------------
# inspect  (foundation issue)
# ---------------------------------------------------------------------------


def _add_inspect(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("inspect", help="summarise a mapping run and plot an overview PNG")
    p.add_argument("run_dir", type=Path, help="mapping-run folder with run.toml")
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="overview PNG path (default: RUN_DIR/overview.png)",
    )
    p.add_argument(
        "--osm-online",
        action="store_true",
        help="fetch OSM around the trajectory through OSMnx instead of a local file",
    )
    p.add_argument("--config", type=Path, default=None, help="TOML file with stage settings")
    p.set_defaults(func=_cmd_inspect)


def _cmd_inspect(args: argparse.Namespace) -> int:
    import time

    from ._files import check_output_dir
    from .io import load_run
    from .osm import highway_counts, load_osm, load_osm_online
    from .plots import plot_overview

    started = time.perf_counter()
    cfg = _load_config(args.config).load
    run = load_run(args.run_dir, config=cfg)
    osm_graph = None
    if args.osm_online:
        osm_graph = load_osm_online(frame=run.frame, around_xy=run.trajectory.xy, config=cfg)
        osm_source = "OSM online (Overpass via OSMnx)"
    elif run.osm_path is not None:
        osm_graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy, config=cfg)
        osm_source = run.osm_path.name
    out = args.output if args.output is not None else run.root / "overview.png"
    check_output_dir(out.parent, inputs=run.input_files, names=[out.name])
    plot_overview(run, osm_graph, out)

    s = run.summary()
    n_left = int((run.edge_side == 1).sum())
    n_right = int((run.edge_side == -1).sum())
    rows = "rows: " if run.edge_reduction is not None and run.edge_reduction.reduced else ""
    sides = f" ({rows}{n_left:,} left, {n_right:,} right)" if n_left + n_right else " (no side)"
    xmin, ymin, xmax, ymax = s.bbox_m
    crs = s.crs if s.crs != "local" else f"local ({run.frame.geo_reference})"
    lines = [
        f"run        {run.root}",
        f"driven     {s.driven_length_m / 1000:.3f} km in {s.duration_s:.1f} s, "
        f"{s.frames:,} frames",
        f"points     {s.edge_points:,} road-edge points{sides}, {s.lane_samples:,} lane samples",
        f"dropped    {s.dropped_edge_points:,} road-edge points, {s.dropped_lane_samples:,} "
        f"lane samples (farther than {cfg.max_point_distance_m:g} m from the trajectory)",
        *(
            f"reduced    {what}: {red.describe()}"
            for what, red in (("edges", run.edge_reduction), ("lanes", run.lane_reduction))
            if red is not None and red.reduced
        ),
        f"bbox       x {xmin:.1f} .. {xmax:.1f} m, y {ymin:.1f} .. {ymax:.1f} m "
        f"({xmax - xmin:.0f} m x {ymax - ymin:.0f} m, mapping frame)",
        f"crs        {crs}",
        f"traffic    {s.traffic_side}-hand, pose height {run.pose_height_m:g} m",
    ]
    if osm_graph is None:
        lines.append("osm        none (no OSM file in run.toml: no ramps will be built)")
    else:
        counts = highway_counts(osm_graph)
        by_class = ", ".join(f"{k} {v}" for k, v in counts.items()) or "none"
        lines.append(
            f"osm        {osm_source}: {sum(counts.values())} ways within "
            f"{cfg.osm_buffer_m:g} m ({by_class})"
        )
    lines.append(f"overview   {out}")
    lines.append(f"time       {time.perf_counter() - started:.2f} s")
    print("\n".join(lines))
    return 0


# ---------------------------------------------------------------------------
# simulate  (simulator issue)
# ---------------------------------------------------------------------------


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate a mapping run with ground truth from a scenario or an OpenDRIVE map",
    )
    p.add_argument(
        "scenario", nargs="?", help="scenario TOML file, or the name of a bundled example"
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="run folder to write")
    p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    p.add_argument(
        "--pass",
        dest="pass_index",
        type=int,
        default=1,
        metavar="N",
        help="drive N of the same road: the same truth and OSM, new pose errors, points, "
        "occlusions and lane samples (default 1)",
    )
    p.add_argument(
        "--direction",
        choices=["forward", "opposite"],
        default="forward",
        help="the carriageway to drive: the scenario's / chain's own (forward) or the one "
        "running the other way beside it (opposite), in the same frame",
    )
    p.add_argument(
        "--noisy",
        action="store_true",
        help="with --xodr or --from-osm: a noisier mapping system (twice the sensor noise, "
        "5%% outliers, missed markings, trucks, 2.5x the pose drift) to test robustness",
    )
    g = p.add_argument_group("runs along a route through an OpenDRIVE map (the map is the truth)")
    g.add_argument("--xodr", type=Path, default=None, help="OpenDRIVE map to drive through")
    g.add_argument(
        "--route",
        default=None,
        help="road ids in driving order, comma separated (default: the longest through-route)",
    )
    g.add_argument(
        "--lane",
        type=int,
        default=0,
        help="lane to drive, counted from the median side (default 0: the outermost through lane)",
    )
    g.add_argument(
        "--style", default="de", help="national marking style: de, at, us, uk, fr (default de)"
    )
    g.add_argument(
        "--traffic",
        choices=["right", "left"],
        default=None,
        help="traffic side (default: from the map's road rule, else right)",
    )
    g.add_argument(
        "--osm",
        type=Path,
        default=None,
        help="copy this OSM file into the run instead of drawing one",
    )
    h = p.add_argument_group(
        "runs along a real OSM carriageway (a lane-level truth is built from the OSM chain)"
    )
    h.add_argument(
        "--from-osm",
        type=Path,
        default=None,
        metavar="EXTRACT",
        help="OSM extract (.osm, .osm.gz, .osm.bz2, .osm.pbf); it is the run's map input",
    )
    h.add_argument(
        "--chain",
        default=None,
        help="the carriageway: an OSM way id or a ref such as 'A 70' (default: the longest "
        "one-way motorway/trunk chain)",
    )
    p.set_defaults(func=_cmd_simulate)


def _cmd_simulate_network(args: argparse.Namespace) -> int:
    """``simulate --xodr MAP`` or ``simulate --from-osm EXTRACT``: a run along a route."""
    import time

    from .simulate import NetworkRunSettings, noisy_settings, simulate_osm_run, simulate_xodr_run
    from .simulate.markings import marking_style
    from .simulate.scenario import Car

    make_settings = noisy_settings if args.noisy else NetworkRunSettings
    started = time.perf_counter()
    if args.from_osm is not None:
        if not args.from_osm.is_file():
            raise InputError(f"{args.from_osm}: OSM extract not found")
        chain = args.chain
        if chain is not None and chain.strip().isdigit():
            chain = int(chain)
        source = f"{args.from_osm} chain {args.chain or '(longest)'}"
        out = simulate_osm_run(
            args.from_osm,
            args.output,
            chain=chain,
            seed=args.seed or 0,
            settings=make_settings(car=Car(lane=args.lane), pass_index=args.pass_index),
            direction=args.direction,
        )
    else:
        if args.osm is not None and not args.osm.is_file():
            raise InputError(f"{args.osm}: OSM file not found")
        if args.direction != "forward":
            raise InputError("simulate --xodr: choose the other direction with --route")
        settings = make_settings(
            car=Car(lane=args.lane),
            style=marking_style(args.style),
            osm_file=str(args.osm) if args.osm is not None else "",
            pass_index=args.pass_index,
        )
        route = [r for r in args.route.split(",") if r.strip()] if args.route else None
        source = str(args.xodr)
        out = simulate_xodr_run(
            args.xodr,
            args.output,
            route=route,
            settings=settings,
            seed=args.seed or 0,
            traffic_side=args.traffic,
        )
    _print_network_run(out, source, args, started)
    return 0


def _cmd_simulate_opposite(args: argparse.Namespace) -> int:
    """``simulate SCENARIO --direction opposite``: the scenario's other carriageway."""
    import time

    from .simulate.opposite import simulate_opposite_run

    started = time.perf_counter()
    out = simulate_opposite_run(
        args.scenario, args.output, seed=args.seed, pass_index=args.pass_index
    )
    _print_network_run(out, f"{args.scenario} (opposite carriageway)", args, started)
    return 0


def _print_network_run(out: Path, source: str, args: argparse.Namespace, started: float) -> None:
    """The summary of a run along a route (``truth.json`` of a network run)."""
    import json
    import time

    truth = json.loads((out / "truth.json").read_text(encoding="utf-8"))
    counts = truth["counts"]
    ramps = ", ".join(
        f"{r['type']} at {r['station_m']:.0f} m ({r['lanes']} lane)" for r in truth["ramps"]
    )
    route_txt = ",".join(
        f"{r['road_id']}{'' if r['direction'] == '+s' else '(-s)'}"
        for r in truth["source"]["route"]
    )
    fit = truth["source"]["fit_max_error_mm"]
    files = ", ".join(sorted(p.name for p in out.iterdir() if p.is_file()))
    style = truth["noise"].get("markings", {}).get("name", args.style)
    drive_no = f", pass {truth['pass']}" if truth.get("pass", 1) > 1 else ""
    print(
        "\n".join(
            [
                f"map        {source} (seed {truth['seed']}{drive_no}, "
                f"{truth['traffic_side']}-hand traffic, {style} markings)",
                f"route      roads {route_txt}",
                f"mainline   {truth['mainline_length_m'] / 1000:.3f} km, "
                f"{len(truth['mainline_roads'])} roads, car in lane {truth['car_lane']}",
                f"ramps      {ramps or 'none'}",
                f"truth fit  max {fit['median_edge']:.2f} mm (median edge), "
                f"{fit['lane_borders']:.2f} mm (lane borders) from the map",
                f"run        {counts['frames']:,} frames, {counts['edge_points']:,} road-edge "
                f"points, {counts['lane_samples']:,} lane samples",
                f"wrote      {out}: {files}",
                f"time       {time.perf_counter() - started:.2f} s",
            ]
        )
    )


def _cmd_simulate(args: argparse.Namespace) -> int:
    import json
    import time

    from .simulate import load_scenario, simulate_run

    given = [x for x in (args.scenario, args.xodr, args.from_osm) if x is not None]
    if len(given) != 1:
        raise InputError("simulate: give one of SCENARIO, --xodr MAP or --from-osm EXTRACT")
    if args.pass_index < 1:
        raise InputError(f"simulate --pass {args.pass_index}: expected 1, 2, ...")
    if args.xodr is not None or args.from_osm is not None:
        return _cmd_simulate_network(args)
    if args.noisy:
        raise InputError("simulate --noisy: only with --xodr MAP or --from-osm EXTRACT")
    if args.direction == "opposite":
        return _cmd_simulate_opposite(args)
    started = time.perf_counter()
    scenario = load_scenario(args.scenario)
    out = simulate_run(scenario, args.output, seed=args.seed, pass_index=args.pass_index)
    truth = json.loads((out / "truth.json").read_text(encoding="utf-8"))
    counts = truth["counts"]
    ramps = ", ".join(
        f"{r['type']} at {r['station_m']:.0f} m ({r['lanes']} lane)" for r in truth["ramps"]
    )
    files = ", ".join(sorted(p.name for p in out.iterdir() if p.is_file()))
    print(
        "\n".join(
            [
                f"scenario   {scenario.name} (seed {truth['seed']}"
                f"{f', pass {args.pass_index}' if args.pass_index > 1 else ''}, "
                f"{scenario.traffic_side}-hand traffic)",
                f"mainline   {truth['mainline_length_m'] / 1000:.3f} km, "
                f"{scenario.lanes.count} lanes, car in lane {truth['car_lane']}",
                f"ramps      {ramps or 'none'}",
                f"run        {counts['frames']:,} frames, {counts['edge_points']:,} road-edge "
                f"points, {counts['lane_samples']:,} lane samples",
                f"wrote      {out}: {files}",
                f"time       {time.perf_counter() - started:.2f} s",
            ]
        )
    )
    return 0


# ---------------------------------------------------------------------------
# build  (ramps / integration issue)
# ---------------------------------------------------------------------------


def _add_build(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "build", help="build map.xodr (+ kml, geojson, png) from mapping runs and/or OSM"
    )
    p.add_argument(
        "run_dirs",
        type=Path,
        nargs="*",
        metavar="RUN_DIR",
        help="mapping-run folder(s) with run.toml (several: fused per carriageway; a folder "
        "whose run.toml names only an OSM file: the OSM-only mode)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="output folder (default: the first RUN_DIR/out)",
    )
    h = p.add_argument_group("the whole highway (issue on several runs and OSM roads)")
    h.add_argument(
        "--carriageway-only",
        action="store_true",
        help="only what one run drove (and its ramps): no other carriageway and no roads "
        "beyond the ramps from OSM",
    )
    h.add_argument(
        "--osm",
        type=Path,
        default=None,
        metavar="FILE",
        help="OSM extract: with RUN_DIRs instead of their run.toml's; alone (with --bbox) the "
        "OSM-only mode, every motorway/trunk carriageway of the box from OSM",
    )
    h.add_argument(
        "--bbox",
        default=None,
        metavar="MINLON,MINLAT,MAXLON,MAXLAT",
        help="area of the OSM-only mode (WGS84 degrees)",
    )
    h.add_argument(
        "--traffic",
        choices=["right", "left"],
        default="right",
        help="traffic side of the OSM-only mode with --osm (default right)",
    )
    p.add_argument(
        "--method",
        choices=["default", "paper"],
        default=None,
        help="mainline method (default: the improved one)",
    )
    p.add_argument(
        "--junctions",
        choices=["default", "direct"],
        default=None,
        help="junctions with connecting roads (default) or OpenDRIVE 1.7 direct",
    )
    p.add_argument(
        "--osm-online",
        action="store_true",
        help="fetch OSM around the trajectory through OSMnx instead of a local file",
    )
    p.add_argument("--no-check", action="store_true", help="skip roadtwin check on the result")
    p.add_argument(
        "--no-drive", action="store_true", help="skip driving the map in esmini (roadtwin drive)"
    )
    _add_esmini_option(p)
    p.add_argument("--config", type=Path, default=None, help="TOML file with stage settings")
    p.set_defaults(func=_cmd_build)


def _cmd_build(args: argparse.Namespace) -> int:
    if args.osm is not None or len(args.run_dirs) != 1 or not args.carriageway_only:
        from .highway.command import cmd_build_highway

        return cmd_build_highway(args)
    args.run_dir = args.run_dirs[0]
    return _cmd_build_run(args)


def _build_config(args: argparse.Namespace):
    """The stage settings of ``build``: ``--config`` with ``--method``, ``--junctions``."""
    import dataclasses

    cfg = _load_config(args.config)
    if args.method is not None:
        cfg = cfg.with_method(args.method)
    if args.junctions is not None:
        cfg = dataclasses.replace(
            cfg, topology=dataclasses.replace(cfg.topology, junctions=args.junctions)
        )
    return cfg


def _ramp_info(road_id: str, r) -> dict:
    """``build.json`` record of one ramp (its decisions)."""
    return {
        "road_id": road_id,
        "type": r.type,
        "station_m": round(r.station_m, 3),
        "station_source": r.station_source,
        "lanes": r.lanes,
        "lane_rule": r.lane_rule,
        "osm_lanes": r.osm_lanes,
        "osm_lane_rule": r.osm_lane_rule,
        "type_geometry": r.type_geometry,
        "osm_way_ids": [str(w) for w in r.osm_way_ids],
        "attach_gap_m": r.attach_gap_m,
        "attach_heading_deg": r.attach_heading_deg,
        "warnings": list(r.warnings),
    }


def _cmd_build_run(args: argparse.Namespace) -> int:
    """``build RUN_DIR --carriageway-only``: one run, the carriageway it drove."""
    import json
    import time

    from ._files import check_output_dir, staged_output

    # only what the first stage needs is imported before it starts (start-up time); the
    # later stages import their modules when they begin
    from .inputs import load_osm_around, load_runs

    started = time.perf_counter()
    cfg = _build_config(args)
    names = ("map.xodr", "map.kml", "map.geojson", "map.png", "build.json")
    tools = None
    if not args.no_drive:
        from .drive import find_esmini

        tools = find_esmini(args.esmini)
    steps = ["load run", "load OSM", "build map", "write files"]
    if not args.no_check:
        steps.append("check")
    if tools is not None:
        steps.append("drive")
    bar = progress(args, total=len(steps), unit="step")
    times: dict[str, float] = {}

    def step(name: str) -> None:
        bar.set_description(name)

    t0 = time.perf_counter()
    step("load run")
    (run,) = load_runs([args.run_dir], cfg.load)
    out = args.output if args.output is not None else run.root / "out"
    check_output_dir(out, inputs=run.input_files, input_dirs=[run.root], names=names)
    times["load run"] = time.perf_counter() - t0
    bar.update()

    t0 = time.perf_counter()
    step("load OSM")
    osm_graph = load_osm_around([run], cfg.load, osm_online=args.osm_online)
    times["load OSM"] = time.perf_counter() - t0
    bar.update()

    from .pipeline import build_map

    step("build map")
    result = build_map(run, osm_graph, config=cfg)
    times.update(result.timings_s)
    bar.update()

    from .export import plot_network, write_geojson, write_kml
    from .xodr import write_xodr

    t0 = time.perf_counter()
    step("write files")
    with staged_output(out) as tmp:
        write_xodr(result.network, tmp / "map.xodr")
        write_kml(result.network, run.frame, tmp / "map.kml")
        write_geojson(result.network, run.frame, tmp / "map.geojson")
        plot_network(result.network, run, tmp / "map.png")
        ramps_info = [
            _ramp_info(rid, r)
            for rid, r in zip(result.topology.ramp_road_ids, result.ramps, strict=True)
        ]
        info = {
            "summary": result.summary(),
            "timings_s": result.timings_s,
            "ramps": ramps_info,
            "rejected": [list(x) for x in result.ramp_set.rejected],
            "skipped": [list(x) for x in (*result.ramp_set.skipped, *result.topology.skipped)],
            "warnings": list(result.warnings),
        }
        atomic_json = (json.dumps(info, indent=2) + "\n").encode("utf-8")
        (tmp / "build.json").write_bytes(atomic_json)
    times["write files"] = time.perf_counter() - t0
    bar.update()

    report, drive_report = _check_and_drive(out, args, cfg, tools, bar, times)

    s = result.summary()
    lines = [
        f"run        {run.root}",
        f"roads      {s['roads']} ({s['mainline_roads']} mainline, {s['connecting_roads']} "
        f"connecting), {s['junctions']} {cfg.topology.junctions} junctions",
        f"ramps      {s['exits']} exit, {s['entries']} entry "
        f"({len(result.ramp_set.candidates)} OSM candidates, "
        f"{len(result.ramp_set.rejected)} rejected, "
        f"{len(result.ramp_set.skipped) + len(result.topology.skipped)} skipped)",
    ]
    for rid, r in zip(result.topology.ramp_road_ids, result.ramps, strict=True):
        lines.append(
            f"  road {rid:>4}  {r.type:<5} at s={r.station_m:8.1f} m ({r.station_source}), "
            f"{r.lanes} lane(s) by {r.lane_rule}"
        )
    lines.append(
        f"length     {s['total_km']:.3f} km ({s['mainline_km']:.3f} km mainline, "
        f"{s['ramp_km']:.3f} km ramps)"
    )
    lines.append("time       " + ", ".join(f"{k} {v:.2f} s" for k, v in times.items()))
    lines.append(f"total      {time.perf_counter() - started:.2f} s")
    lines.append(f"written    {', '.join(str(out / n) for n in names[:4])}")
    for w in result.warnings:
        lines.append(f"note       {w}")
    lines += _drive_lines(drive_report, skipped=args.no_drive, out=out)
    return _print_build(lines, report, drive_report)


def _print_build(lines: list[str], report, drive_report) -> int:
    """Print a build's summary lines and its check report; exit code 1 when the check
    found errors or a route failed its drive."""
    print("\n".join(lines))
    failed = drive_report is not None and not drive_report.ok
    if report is not None:
        print(report.format_text())
        failed = failed or report.errors > 0
    return 1 if failed else 0


def _check_and_drive(out: Path, args: argparse.Namespace, cfg, tools, bar, times: dict):
    """``roadtwin check`` of ``out/map.xodr`` (unless ``--no-check``) and, with esmini
    (``tools``), ``roadtwin drive`` into ``out/drive`` (recorded in ``build.json``);
    returns both reports (None where skipped) and closes the progress bar."""
    import time

    report = None
    if not args.no_check:
        from .check import check_file

        t0 = time.perf_counter()
        bar.set_description("check")
        report = check_file(out / "map.xodr", external=True)
        times["check"] = time.perf_counter() - t0
        bar.update()
    drive_report = None
    if tools is not None:
        t0 = time.perf_counter()
        bar.set_description("drive")
        drive_report = _drive(out / "map.xodr", out / "drive", args, cfg.drive, tools=tools)
        _add_drive_to_build_json(out / "build.json", drive_report)
        times["drive"] = time.perf_counter() - t0
        bar.update()
    bar.close()
    return report, drive_report


def _drive_lines(drive_report, *, skipped: bool, out: Path | None = None) -> list[str]:
    """Summary lines of a drive for ``build`` (one line, then each failed route)."""
    if skipped:
        return []
    if drive_report is None:
        return ["drive      skipped: esmini not found (--esmini DIR, ESMINI_BIN or PATH)"]
    lines = [f"drive      {drive_report.summary()}"]
    for r in drive_report.results:
        lines += [f"  {r.route.name}: {f.code}: {f.message}" for f in r.faults]
    lines += [f"  esmini {m} ({n} route(s))" for m, n in drive_report.warnings.items()]
    if out is not None:
        lines.append(f"           {out / 'drive' / 'drive.json'}, {out / 'drive' / 'scenarios'}/")
    return lines


def _add_drive_to_build_json(path: Path, drive_report) -> None:
    """Record the drive's summary in ``build.json`` (rewritten atomically)."""
    import json

    info = json.loads(path.read_text(encoding="utf-8"))
    doc = drive_report.to_dict()
    info["drive"] = {
        k: doc[k] for k in ("ok", "routes_total", "passed", "failed", "esmini_warnings", "wall_s")
    }
    info["drive"]["report"] = "drive/drive.json"
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(info, indent=2) + "\n", encoding="utf-8")
    tmp.replace(path)


# ---------------------------------------------------------------------------
# check  (road model / OpenDRIVE I/O issue)
# ---------------------------------------------------------------------------


def _add_check(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("check", help="check an OpenDRIVE file for gaps, links, widths, consumers")
    p.add_argument("xodr", type=Path, help="OpenDRIVE file")
    p.add_argument("--json", action="store_true", help="print findings as JSON")
    p.add_argument(
        "--no-external",
        action="store_true",
        help="skip SUMO netconvert and the ASAM quality checker",
    )
    p.add_argument(
        "--drive",
        action="store_true",
        help="also drive every route in esmini (as roadtwin drive, in a temporary folder)",
    )
    _add_esmini_option(p)
    p.set_defaults(func=_cmd_check)


def _cmd_check(args: argparse.Namespace) -> int:
    import json
    import tempfile

    from .check import check_file

    report = check_file(args.xodr, external=not args.no_external)
    drive_report = tools = None
    if args.drive:
        from .drive import find_esmini

        tools = find_esmini(args.esmini)
        with tempfile.TemporaryDirectory(prefix="roadtwin-drive-") as tmp:
            drive_report = _drive(args.xodr, Path(tmp), args, _drive_config(args), tools=tools)
    if args.json:
        doc = report.to_dict()
        if drive_report is not None:
            doc["drive"] = drive_report.to_dict()
        print(json.dumps(doc, indent=2))
    else:
        print(report.format_text())
        if drive_report is not None:
            print(drive_report.format_text())
    if args.drive and tools is None:
        print(
            "roadtwin: esmini not found: give --esmini DIR, set ESMINI_BIN to its folder or "
            "put it on PATH (releases: https://github.com/esmini/esmini/releases)",
            file=sys.stderr,
        )
        return 2
    return 0 if report.ok and (drive_report is None or drive_report.ok) else 1


# ---------------------------------------------------------------------------
# evaluate  (evaluation issue)
# ---------------------------------------------------------------------------


def _add_evaluate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("evaluate", help="accuracy report of a map against its run (and truth)")
    p.add_argument("xodr", type=Path, help="map to evaluate")
    p.add_argument("run_dirs", type=Path, nargs="+", help="mapping-run folder(s)")
    p.add_argument("--truth", type=Path, default=None, help="ground-truth OpenDRIVE file")
    p.add_argument("-o", "--output", type=Path, default=None, help="report folder")
    p.add_argument(
        "--compare-methods",
        action="store_true",
        help="also build each run with the default and the paper method and report both",
    )
    p.add_argument("--config", type=Path, default=None, help="TOML file with stage settings")
    p.set_defaults(func=_cmd_evaluate)


def _cmd_evaluate(args: argparse.Namespace) -> int:
    import time

    from ._files import check_output_dir, staged_output
    from .evaluation import evaluate_paths, format_table
    from .report import write_report

    def _fmt_m(value) -> str:
        return "-" if value is None or value != value else f"{value:.3f} m"

    def _fmt_pct(value) -> str:
        return "-" if value is None else f"{100.0 * value:.1f} %"

    start = time.perf_counter()

    def runs_bar(items):
        return progress(args, items, desc="evaluate", unit="run")

    for run_dir in args.run_dirs:
        if not (run_dir / "run.toml").is_file():
            raise InputError(f"{run_dir}: not a mapping-run folder (no run.toml)")
    if args.truth is not None and not args.truth.is_file():
        what = "not a file" if args.truth.exists() else "truth file not found"
        raise InputError(f"{args.truth}: {what}")
    out_dir = args.output if args.output is not None else args.xodr.parent / "report"
    inputs = [args.xodr, *([args.truth] if args.truth is not None else [])]
    for run_dir in args.run_dirs:
        inputs += [p for p in run_dir.iterdir() if p.is_file()]
    check_output_dir(
        out_dir, inputs=inputs, input_dirs=args.run_dirs, names=["report.json", "report.html"]
    )
    report = evaluate_paths(
        args.xodr,
        args.run_dirs,
        truth_path=args.truth,
        progress=runs_bar if len(args.run_dirs) > 1 else None,
    )
    if args.compare_methods:
        from .evaluation import combine_reports, compare_methods, load_truth
        from .io import load_run

        config = _load_config(args.config)
        extra = []
        for run_dir in args.run_dirs:
            truth_path = args.truth
            if truth_path is None and (run_dir / "truth.xodr").is_file():
                truth_path = run_dir / "truth.xodr"
            truth, info = load_truth(truth_path) if truth_path is not None else (None, None)
            run = load_run(run_dir, config=config.load)
            extra.append(compare_methods(run, truth=truth, truth_info=info, config=config))
        report = combine_reports([report, *extra])
    with staged_output(out_dir) as tmp:
        written = write_report(report, tmp)
    paths = {role: out_dir / p.name for role, p in written.items()}
    print(format_table(report))
    for run in report.runs:
        line = f"{run.label} [{run.method or 'map'}]:"
        if run.truth:
            t = run.truth
            line += (
                f" vs truth edge RMSE {_fmt_m(t['road_edge']['rmse_m'])},"
                f" lane boundary RMSE {_fmt_m(t['lane_boundary']['rmse_m'])},"
                f" elevation RMSE {_fmt_m(t['elevation']['rmse_m'])},"
                f" ramp centre RMSE {_fmt_m(t['ramp_centre']['rmse_m'])},"
                f" lane count right {_fmt_pct(t['lane_count']['matched_fraction'])}"
            )
        topo = run.topology or {}
        ramps = topo.get("ramps", [])
        if "true_ramps" in topo:
            unjudged = len(topo.get("unjudged") or [])
            line += (
                f"; ramps {topo['matched']}/{topo['true_ramps']} matched,"
                f" {len(topo['missed'])} missed, {len(topo['spurious'])} spurious,"
                + (f" {unjudged} unjudged (left out of the truth)," if unjudged else "")
                + f" {topo['type_correct']} typed right"
            )
        line += f"; {sum(r['connected'] for r in ramps)}/{len(ramps)} ramps connected by lane links"
        print(line)
    print(
        f"report: {paths['html']} (+ report.json, {len(paths) - 2} PNG) "
        f"in {time.perf_counter() - start:.1f} s"
    )
    return 0


# ---------------------------------------------------------------------------
# drive  (issue: drive every ramp in esmini)
# ---------------------------------------------------------------------------

_ESMINI_HELP = "folder with esmini and dat2csv (default: the folder in $ESMINI_BIN, then PATH)"


def _add_esmini_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--esmini", type=Path, default=None, metavar="DIR", help=_ESMINI_HELP)


def _add_drive(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "drive", help="drive every route of a map in esmini (one OpenSCENARIO file per route)"
    )
    p.add_argument("xodr", type=Path, help="OpenDRIVE map")
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="folder for scenarios/, runs/ and drive.json (default: MAP_DIR/drive)",
    )
    _add_esmini_option(p)
    p.add_argument("--speed", type=float, default=None, metavar="M_S", help="car speed (m/s)")
    p.add_argument("--config", type=Path, default=None, help="TOML file with stage settings")
    p.set_defaults(func=_cmd_drive)


def _esmini_missing_note(report) -> str:
    """How to get esmini, and how to run the written scenarios without roadtwin."""
    first = next(iter(sorted(report.scenario_dir.glob("*.xosc"))), None)
    lines = [
        "roadtwin: esmini not found: give --esmini DIR, set ESMINI_BIN to its folder or put it "
        "on PATH (releases: https://github.com/esmini/esmini/releases)",
        f"roadtwin: the scenarios are in {report.scenario_dir}",
    ]
    if first is not None:
        lines.append(
            f"roadtwin: run one with: esmini --headless --osc {first} --fixed_timestep "
            f"{report.config.timestep_s:g} --record sim.dat && dat2csv sim.dat --extended"
        )
    return "\n".join(lines)


def _drive(map_path: Path, out_dir: Path, args: argparse.Namespace, drive_cfg, *, tools=None):
    """Drive ``map_path`` (the shared step of ``drive``, ``build``, ``demo``, ``check``)."""
    from .drive import drive_map

    def routes(items, total):
        return progress(args, items, total=total, desc="drive", unit="route", leave=False)

    return drive_map(map_path, out_dir, esmini=tools, config=drive_cfg, progress=routes)


def _drive_config(args: argparse.Namespace):
    import dataclasses

    cfg = _load_config(getattr(args, "config", None)).drive
    if getattr(args, "speed", None) is not None:
        if not args.speed > 0:
            raise InputError(f"--speed must be > 0 m/s, got {args.speed}")
        cfg = dataclasses.replace(cfg, speed_m_s=args.speed)
    return cfg


def _cmd_drive(args: argparse.Namespace) -> int:
    from .drive import find_esmini

    if not args.xodr.is_file():
        raise InputError(f"{args.xodr}: map not found")
    cfg = _drive_config(args)
    tools = find_esmini(args.esmini)
    out = args.output if args.output is not None else args.xodr.parent / "drive"
    report = _drive(args.xodr, out, args, cfg, tools=tools)
    print(report.format_text())
    print(f"wrote      {out / 'drive.json'}, {report.scenario_dir}/ ({len(report.results)} routes)")
    if tools is None:
        print(_esmini_missing_note(report), file=sys.stderr)
        return 2
    return 0 if report.ok else 1


# ---------------------------------------------------------------------------
# demo  (simulator issue; grows as stages land)
# ---------------------------------------------------------------------------


def _add_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="simulate the bundled example and run every stage on it")
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="folder to write into (default: a new temporary folder)",
    )
    p.add_argument(
        "--scenario",
        default="straight_curve_2km",
        help="bundled scenario name or scenario TOML file",
    )
    _add_esmini_option(p)
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args: argparse.Namespace) -> int:
    import importlib
    import json
    import tempfile
    import time

    from .simulate import load_scenario, simulate_run

    started = time.perf_counter()
    root = args.output or Path(tempfile.mkdtemp(prefix="roadtwin-demo-"))
    run_dir, out_dir = root / "run", root / "out"
    scenario = load_scenario(args.scenario)
    lines: list[str] = []
    wrote: list[Path] = []
    state: dict = {}

    def has(module: str, name: str) -> bool:
        try:
            return hasattr(importlib.import_module(f"roadtwin.{module}"), name)
        except ImportError:
            return False

    def simulate() -> str:
        simulate_run(scenario, run_dir)
        truth = json.loads((run_dir / "truth.json").read_text(encoding="utf-8"))
        state["truth_info"] = truth
        wrote.extend([run_dir / "run.toml", run_dir / "truth.xodr"])
        c = truth["counts"]
        return (
            f"{scenario.name}: {truth['mainline_length_m'] / 1000:.1f} km, "
            f"{len(truth['ramps'])} ramps, {c['frames']:,} frames, "
            f"{c['edge_points']:,} edge points, {c['lane_samples']:,} lane samples"
        )

    def inspect() -> str:
        from .io import load_run
        from .osm import load_osm
        from .plots import plot_overview

        run = load_run(run_dir)
        osm_graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
        state["run"], state["osm_graph"] = run, osm_graph
        plot_overview(run, osm_graph, run_dir / "overview.png")
        wrote.append(run_dir / "overview.png")
        return f"loaded, {osm_graph.number_of_edges()} OSM edges, overview plotted"

    def build() -> str:
        from .pipeline import build_map
        from .xodr import write_xodr

        result = build_map(state["run"], state["osm_graph"])
        state["network"] = result.network
        path = write_xodr(result.network, out_dir / "map.xodr")
        wrote.append(path)
        if has("export", "write_kml"):
            from .export import write_geojson, write_kml

            frame = state["run"].frame
            wrote.append(write_kml(result.network, frame, out_dir / "map.kml"))
            wrote.append(write_geojson(result.network, frame, out_dir / "map.geojson"))
        n_main = sum(r.name == "mainline" for r in result.network.roads)
        return f"{len(result.network.roads)} roads ({n_main} mainline), {len(result.ramps)} ramps"

    def check() -> str:
        from .check import check_file

        target = out_dir / "map.xodr" if "network" in state else run_dir / "truth.xodr"
        report = check_file(target, external=True)
        consumers = ", ".join(f"{c.name} {c.status}" for c in report.consumers)
        verdict = "ok" if report.ok else f"{report.errors} errors"
        return f"{target.name}: {verdict}, {len(report.findings)} own findings; {consumers}"

    def drive() -> str:
        from .drive import find_esmini

        tools = find_esmini(args.esmini)
        if tools is None:
            return "skipped: esmini not found (--esmini DIR, ESMINI_BIN or PATH)"
        report = _drive(
            out_dir / "map.xodr", out_dir / "drive", args, _drive_config(args), tools=tools
        )
        state["drive"] = report.to_dict()
        wrote.append(out_dir / "drive" / "drive.json")
        lines = [report.summary()]
        lines += [f"  {r.route.name}: {f.message}" for r in report.results for f in r.faults]
        return "\n".join(lines)

    def evaluate() -> str:
        from .evaluation import evaluate_paths
        from .report import write_report

        report = evaluate_paths(out_dir / "map.xodr", [run_dir], truth_path=run_dir / "truth.xodr")
        paths = write_report(report, out_dir / "report", drive=state.get("drive"))
        wrote.append(Path(paths["html"]))
        t = report.runs[0].truth or {}
        edge = (t.get("road_edge") or {}).get("rmse_m")
        lane = (t.get("lane_boundary") or {}).get("rmse_m")
        if edge is None:
            return "report written"
        return f"vs truth: road edge RMSE {edge:.3f} m, lane boundary RMSE {lane:.3f} m"

    stages = [("simulate", simulate, True), ("inspect", inspect, has("io", "load_run"))]
    stages.append(("build", build, has("pipeline", "build_map")))
    stages.append(("check", check, has("check", "check_file")))
    stages.append(("drive", drive, has("pipeline", "build_map")))
    can_evaluate = has("pipeline", "build_map") and has("evaluation", "evaluate_paths")
    stages.append(("evaluate", evaluate, can_evaluate))
    bar = progress(args, stages, desc="demo", unit="stage", leave=False)
    for name, stage, available in bar:
        bar.set_postfix_str(name)
        if not available:
            lines.append(f"{name:<10} not available yet")
            continue
        t0 = time.perf_counter()
        try:
            text = stage()
        except NotImplementedError:
            lines.append(f"{name:<10} not available yet")
            continue
        first, *details = text.split("\n")
        lines.append(f"{name:<10} {first} ({time.perf_counter() - t0:.1f} s)")
        lines += [f"{'':<10} {d}" for d in details]
    bar.close()
    lines.append(f"{'folder':<10} {root}")
    lines += [f"{'':<10} {p}" for p in wrote if p.exists()]
    lines.append(f"{'time':<10} {time.perf_counter() - started:.1f} s")
    print("\n".join(lines))
    return 0


# ---------------------------------------------------------------------------


def _verbosity_options(parser: argparse.ArgumentParser, *, default) -> None:
    parser.add_argument(
        "-v", "--verbose", action="store_true", default=default, help="log every stage"
    )
    parser.add_argument(
        "-q", "--quiet", action="store_true", default=default, help="no progress bars, no info"
    )


def build_parser() -> argparse.ArgumentParser:
    """The ``roadtwin`` argument parser (``-q``/``-v`` before or after the command)."""
    parser = argparse.ArgumentParser(
        prog="roadtwin",
        description="Georeferenced OpenDRIVE digital twins of highways from LiDAR + OSM.",
    )
    parser.add_argument("--version", action="version", version=f"roadtwin {__version__}")
    _verbosity_options(parser, default=False)
    # the same options after the command; SUPPRESS keeps a value given before it
    common = argparse.ArgumentParser(add_help=False)
    _verbosity_options(common, default=argparse.SUPPRESS)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    original_add = sub.add_parser

    def add_parser(name: str, **kwargs) -> argparse.ArgumentParser:
        return original_add(name, parents=[common, *kwargs.pop("parents", [])], **kwargs)

    sub.add_parser = add_parser  # type: ignore[method-assign]
    for add in (
        _add_inspect,
        _add_simulate,
        _add_build,
        _add_check,
        _add_evaluate,
        _add_drive,
        _add_demo,
    ):
        add(sub)
    return parser


# ---------------------------------------------------------------------------
# one error path: messages, logging, warnings, signals
# ---------------------------------------------------------------------------


class Terminated(BaseException):
    """Raised in the main thread when SIGTERM (or SIGHUP) arrives, so that ``finally``
    blocks remove temporary files and external tools are stopped, as on Ctrl-C."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


class _LineFormatter(logging.Formatter):
    """Every log record as ``roadtwin: <level>: <message>`` on one line, the same format as
    warnings and errors."""

    def format(self, record: logging.LogRecord) -> str:
        return f"roadtwin: {record.levelname.lower()}: {one_line(record.getMessage())}"


class _StderrHandler(logging.Handler):
    """Writes to the *current* ``sys.stderr`` (tests swap it between commands)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            _print_line(self.format(record))
        except Exception:  # pragma: no cover - logging must never raise
            self.handleError(record)


def _print_line(line: str) -> None:
    _close_bars()
    print(line, file=sys.stderr, flush=True)


def _close_bars() -> None:
    """Close open progress bars so a message never glues onto a bar line."""
    tqdm = sys.modules.get("tqdm")
    if tqdm is None:
        return
    for bar in list(getattr(tqdm.tqdm, "_instances", ())):
        with contextlib.suppress(Exception):
            bar.close()


@contextlib.contextmanager
def _logging(verbose: bool, quiet: bool) -> Iterator[None]:
    root = logging.getLogger()
    handler = _StderrHandler()
    handler.setFormatter(_LineFormatter())
    level = logging.INFO if verbose and not quiet else logging.WARNING
    old_level, old_root_level = log.level, root.level
    if not verbose:  # libraries log what they then raise (laspy): the error line says it
        handler.addFilter(lambda record: record.name.split(".")[0] == "roadtwin")
    root.addHandler(handler)
    root.setLevel(logging.WARNING)
    log.setLevel(level)
    try:
        yield
    finally:
        root.removeHandler(handler)
        root.setLevel(old_root_level)
        log.setLevel(old_level)


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    _print_line(f"roadtwin: warning: {one_line(message)}")


@contextlib.contextmanager
def _warnings_as_lines() -> Iterator[None]:
    with warnings.catch_warnings():
        warnings.simplefilter("default")
        previous = warnings.showwarning
        warnings.showwarning = _show_warning
        try:
            yield
        finally:
            warnings.showwarning = previous


_signals_received: list[int] = []  # signals delivered while a command runs, in order


def _raise_terminated(signum, frame) -> None:
    _signals_received.append(signum)
    raise Terminated(signum)


def _raise_interrupt(signum, frame) -> None:
    _signals_received.append(signum)
    raise KeyboardInterrupt


@contextlib.contextmanager
def _signals_as_exceptions() -> Iterator[None]:
    """SIGTERM and SIGHUP raise :class:`Terminated`; SIGINT raises KeyboardInterrupt (as
    Python's default handler does, restored if something replaced it). Each signal is also
    recorded, so that one that an import or a C extension turned into another error still
    ends the command as interrupted (:func:`run_command`)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _signals_received.clear()
    wanted = {signal.SIGINT: _raise_interrupt, signal.SIGTERM: _raise_terminated}
    if hasattr(signal, "SIGHUP"):
        wanted[signal.SIGHUP] = _raise_terminated
    previous = {}
    for signum, handler in wanted.items():
        with contextlib.suppress(ValueError, OSError):
            previous[signum] = signal.signal(signum, handler)
    old_hook = sys.unraisablehook

    def redeliver(unraisable) -> None:
        # A signal that lands in a destructor or weakref callback raises there, and Python
        # only prints it ("Exception ignored"): send it again a moment later, when the main
        # thread has left the callback, so that it reaches the command.
        exc = unraisable.exc_value
        if isinstance(exc, (Terminated, KeyboardInterrupt)):
            signum = exc.signum if isinstance(exc, Terminated) else signal.SIGINT
            timer = threading.Timer(0.01, os.kill, (os.getpid(), signum))
            timer.daemon = True
            timer.start()
        else:
            old_hook(unraisable)

    sys.unraisablehook = redeliver
    try:
        yield
    finally:
        sys.unraisablehook = old_hook
        for signum, handler in previous.items():
            with contextlib.suppress(ValueError, OSError, TypeError):
                signal.signal(signum, handler)


def _os_error_text(exc: OSError) -> str:
    """``path: reason`` for an OS error (permission denied, disk full, read-only, ...)."""
    reason = exc.strerror or one_line(exc) or type(exc).__name__
    names = [str(f) for f in (exc.filename, exc.filename2) if f is not None]
    return f"{' -> '.join(names)}: {reason}" if names else reason


def _signal_exit(signum: int) -> int:
    """Say that a signal ended the command; the exit code for it (128 + signal number)."""
    if signum == signal.SIGINT:
        _print_line("roadtwin: error: interrupted")
    else:
        _print_line(f"roadtwin: error: terminated by {signal.Signals(signum).name}")
    return 128 + signum


def run_command(args: argparse.Namespace) -> int:
    """Run a parsed command through the one error path; returns the exit code."""
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return _signal_exit(signal.SIGINT)
    except Terminated as exc:
        return _signal_exit(exc.signum)
    except RoadtwinError as exc:
        _print_line(f"roadtwin: error: {one_line(exc)}")
        return EXIT_BAD_INPUT
    except OSError as exc:
        _print_line(f"roadtwin: error: {_os_error_text(exc)}")
        return EXIT_BAD_INPUT
    except MemoryError:
        _print_line(
            "roadtwin: error: out of memory: the input is larger than this machine can "
            "process (see the limits in the README)"
        )
        return EXIT_BAD_INPUT
    except Exception as exc:  # a bug: one line, the traceback only with -v
        if _signals_received:
            # the signal landed inside an import or a C extension, which turned it into
            # another error (an interrupted module initialisation is an ImportError)
            return _signal_exit(_signals_received[-1])
        if getattr(args, "verbose", False):
            import traceback

            _close_bars()
            traceback.print_exc(file=sys.stderr)
        _print_line(
            f"roadtwin: error: internal error ({type(exc).__name__}: {one_line(exc)[:200]}); "
            "please report it with the output of -v"
        )
        return EXIT_INTERNAL
    finally:
        _close_bars()


class _StageBar:
    """A stage of :mod:`roadtwin.progress`: a tqdm bar (see :func:`progress`) and, when the
    stage ends, one log line with its seconds and count (shown with ``-v``). A message
    printed meanwhile may close the tqdm bar early (:func:`_close_bars`); the stage still
    ends, and logs, when the library says so."""

    def __init__(self, args: argparse.Namespace, name: str, total: float | None, unit: str):
        import time

        self.name, self.unit, self.count = name, unit, 0.0
        self.started = time.perf_counter()
        self.bar = progress(args, total=total, desc=name, unit=unit, unit_scale=True, leave=False)

    def update(self, n: float = 1) -> None:
        self.count += n
        self.bar.update(n)

    def close(self) -> None:
        import time

        self.bar.close()
        done = f" ({self.count:,.0f} {self.unit})" if self.count else ""
        log.info("stage %s: %.2f s%s", self.name, time.perf_counter() - self.started, done)


def _progress_listener(args: argparse.Namespace):
    """Listener for :mod:`roadtwin.progress`: a :class:`_StageBar` per long stage."""

    def listener(name: str, total: float | None, unit: str) -> _StageBar:
        return _StageBar(args, name, total, unit)

    return listener


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``roadtwin`` console script; returns the exit code."""
    from .progress import listening

    parser = build_parser()
    args = parser.parse_args(argv)
    with (
        _signals_as_exceptions(),
        _logging(args.verbose, args.quiet),
        _warnings_as_lines(),
        listening(_progress_listener(args)),
    ):
        return run_command(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
