"""Mapping runs along a route through any OpenDRIVE road network (``roadtwin simulate
--xodr``): the map is the ground truth.

:func:`simulate_network_run` takes an in-memory :class:`~roadtwin.model.RoadNetwork`
(read from a file, or made by another generator), finds or follows a route, builds the
canonical truth (:mod:`roadtwin.simulate.route_truth`), drives the car
(:mod:`roadtwin.simulate.route_sensor`) and writes the run folder exactly like the
parametric scenarios do (``run.toml``, ``trajectory.csv``, ``road_edges.<ext>``,
``lane_samples.csv``, ``map.osm``, ``truth.xodr``, ``truth.json``,
``truth_trajectory.csv``). Same network, route, settings and seed give the same bytes.

The run's mapping frame is the network's: its ``geoReference`` when pyproj reads it as a
projected CRS (vertical grids dropped), else a ``local`` frame on ``settings.origin``
whose coordinates are the network's.
"""

from __future__ import annotations

import dataclasses
import gzip
import logging
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from pyproj.exceptions import CRSError

from .._errors import InputError
from .._xml import parse_xml
from ..frames import MappingFrame, Origin
from ..model import RoadNetwork
from ..xodr import read_xodr
from .canonical import FitSettings
from .markings import MarkingStyle
from .osm_writer import through_lane_counts, write_route_osm
from .route import Route, TrafficSide, find_through_route, route_from_ids, route_length_m
from .route_sensor import (
    drive,
    edge_sides,
    opposite_painted_points,
    painted_points,
    resolved_lane,
    sensor_view,
    true_edges,
)
from .route_truth import LeftOutRamp, RouteTruth, build_route_truth
from .scenario import Car, Noise, OsmStyle, Sensor
from .sensor import noisy_poses, observe_edges, observe_markings
from .writer import (
    _rng,
    copy_osm,
    run_toml_text,
    section_record,
    write_run_folder,
    write_sensor_files,
    write_truth_files,
)

log = logging.getLogger(__name__)

_VERTICAL_TOKENS = ("+geoidgrids", "+vunits", "+no_defs", "+type=crs", "+nadgrids")


@dataclass(frozen=True)
class NetworkRunSettings:
    """Everything of a network run except the network, route and seed.

    ``car.lane`` counts from the median side (0 = the outermost through lane); ``style``
    is the national marking style; ``ramp_length_m`` how far a ramp is followed beyond its
    junction (or to its next junction); ``origin`` the GPS origin used when the network has
    no usable geoReference; ``osm_file`` an existing OSM file copied instead of drawing
    one; ``fit`` the tolerances of the canonical truth.
    """

    traffic_side: TrafficSide = "right"
    car: Car = field(default_factory=Car)
    noise: Noise = field(default_factory=Noise)
    sensor: Sensor = field(default_factory=Sensor)
    style: MarkingStyle = field(default_factory=MarkingStyle)
    osm: OsmStyle = field(default_factory=OsmStyle)
    ramp_length_m: float = 300.0
    origin: Origin = field(default_factory=lambda: Origin(49.98, 11.62, 400.0))
    osm_file: str = ""
    road_edges_format: str = "laz"
    fit: FitSettings = field(default_factory=FitSettings)
    lookahead_m: float = 200.0
    """A lane ending within this distance ahead is left early (metres)."""
    lane_change_m: float = 120.0
    """Length of a lane change (metres)."""
    opposite_markings: bool = False
    """Also sample the paint of the opposite carriageway (lanes of the source map whose
    traffic runs against the route) within the sensor's lateral range."""
    pass_index: int = 1
    """Which drive of the same route this is: pass N > 1 keeps the truth and the OSM of
    pass 1 and draws new pose errors, edge points, occlusions and lane samples."""

    def __post_init__(self) -> None:
        if self.traffic_side not in ("right", "left"):
            raise InputError(f"traffic side: expected right or left, got {self.traffic_side!r}")
        if self.road_edges_format not in ("laz", "las", "csv", "ply", "npy", "parquet"):
            raise InputError(f"road edges format {self.road_edges_format!r} is not supported")
        if not 10.0 <= self.car.speed_kmh <= 200.0 or not 1.0 <= self.car.rate_hz <= 100.0:
            raise InputError("car: speed_kmh must be 10..200 and rate_hz 1..100")
        if self.car.lane < 0:
            raise InputError(f"car lane {self.car.lane}: expected 0 (outermost) or 1, 2, ...")
        if isinstance(self.pass_index, bool) or not (
            isinstance(self.pass_index, int) and self.pass_index >= 1
        ):
            raise InputError(f"pass {self.pass_index!r}: expected 1, 2, ...")


def noisy_settings(**overrides) -> NetworkRunSettings:
    """Settings of a noisier mapping system than the default, for robustness tests: twice
    the sensor noise (0.06 m on edges and markings), five times the outliers (5 %), 15 %
    of the edge points dropped, 5 trucks per km occluding the edge, 15 % of the marking
    samples missed, 2 % false marking samples and 2.5x the pose drift (0.05 m, 0.06 m
    height, 0.1 deg yaw). ``overrides``: other :class:`NetworkRunSettings` fields."""
    return NetworkRunSettings(
        sensor=Sensor(
            edge_noise_m=0.06,
            outlier_fraction=0.05,
            edge_dropout=0.15,
            trucks_per_km=5.0,
            lane_noise_m=0.06,
            lane_miss=0.15,
            lane_false_positive=0.02,
        ),
        noise=Noise(position_std_m=0.05, height_std_m=0.06, yaw_std_deg=0.1),
        **overrides,
    )


def network_frame(network: RoadNetwork, origin: Origin, start_xy) -> MappingFrame:
    """The run's mapping frame: the network's geoReference if it is a usable projected
    CRS (with the GPS origin at the route start), else ``local`` on ``origin``."""
    text = network.header.geo_reference.strip()
    if text:
        clean = " ".join(t for t in text.split() if not t.startswith(_VERTICAL_TOKENS))
        try:
            probe = MappingFrame(origin, crs=clean)
            lon, lat = (float(v) for v in probe.to_lonlat(float(start_xy[0]), float(start_xy[1])))
            if np.isfinite(lon) and np.isfinite(lat):
                return MappingFrame(Origin(lat, lon, 0.0), crs=clean)
        except (InputError, CRSError, ValueError) as exc:
            log.info("geoReference %r not usable (%s): local frame on the origin", text, exc)
    return MappingFrame(origin, "local")


def _resolve_route(
    network: RoadNetwork, route: Route | Sequence[str] | None, side: TrafficSide
) -> Route:
    if route is None:
        return find_through_route(network, traffic_side=side)
    if isinstance(route, Route):
        return route
    return route_from_ids(network, [str(r) for r in route], traffic_side=side)


def _lane_kinds(truth: RouteTruth, section: int) -> list[str]:
    """``inner`` / ``driving`` / ``aux`` / ``hard`` (non-traffic lanes inside / outside the
    traffic lanes) or the lane type, per lane of a whole-mainline lane section."""
    sec = truth.mainline.lane_sections[section]
    lanes = sec.right or sec.left
    keys = truth.mainline_fit.section_keys[section]
    traffic = [i for i, ln in enumerate(lanes) if ln.type in ("driving", "entry", "exit")]
    first, last = (traffic[0], traffic[-1]) if traffic else (len(lanes), -1)
    out = []
    for i, (ln, key) in enumerate(zip(lanes, keys, strict=True)):
        if i in traffic:
            out.append("aux" if key in truth.aux_keys else "driving")
        elif ln.type == "shoulder" and i < first:
            out.append("inner")
        elif ln.type == "shoulder" and i > last:
            out.append("hard")
        else:
            out.append(ln.type)
    return out


def _lane_drops(truth: RouteTruth) -> list[dict]:
    """Traffic lanes of the mainline that end before the route's end other than into a
    ramp: station where they end and the length over which they taper (metres)."""
    road = truth.mainline
    fit = truth.mainline_fit
    ramp_keys = set()
    for ramp in truth.ramps:
        sec = fit.road.section_index(np.array([ramp.cut_station_m - 1e-6]))[0]
        for lid in ramp.aux_lane_ids if ramp.type == "exit" else ():
            ramp_keys.add(fit.key_of(int(sec), lid))
    out = []
    for k in range(len(fit.section_keys) - 1):
        nxt = set(fit.section_keys[k + 1])
        sec = road.lane_sections[k]
        end = road.lane_sections[k + 1].s0
        for lane, key in zip(sec.right or sec.left, fit.section_keys[k], strict=True):
            if key in nxt or key in ramp_keys or lane.type != "driving":
                continue
            w_end = float(lane.width.value(end - sec.s0))
            taper = end - sec.s0 if w_end < 0.05 else 0.0
            out.append({"station_m": round(end, 6), "taper_m": round(taper, 3)})
    return out


def route_truth_json(
    truth: RouteTruth,
    settings: NetworkRunSettings,
    *,
    seed: int,
    car_lane: int,
    ramp_ways: dict[int, list[int]],
    counts: dict,
    left_out: Sequence[LeftOutRamp] = (),
) -> dict:
    """``truth.json`` of a network run: the keys of the parametric runs' truth.json plus
    the source, route and fit accuracy, and ``ramps_left_out``: the ramps of the source
    that the truth has not (``left_out`` and those the route truth left out)."""
    roads = truth.mainline_roads
    starts = truth.mainline_road_starts
    sections = []
    main = truth.mainline
    for road, start in zip(roads, starts, strict=True):
        for ls in road.lane_sections:
            k = int(main.section_index(np.array([start + ls.s0 + 1e-6]))[0])
            kinds = _lane_kinds(truth, k)
            lanes = ls.right or ls.left
            record = section_record(road.id, ls.s0, start, lanes, kinds)
            sections.append(record | {"lane_types": [lane.type for lane in lanes]})
    ramps = []
    for i, r in enumerate(truth.ramps):
        ramps.append(
            {
                "road_id": r.road.id,
                "type": r.type,
                "station_m": round(r.station_m, 6),
                "lanes": r.lanes,
                "osm_way_ids": ramp_ways.get(i, []),
                "junction_id": r.junction_id,
                "mainline_road_before": r.main_before,
                "mainline_road_after": r.main_after,
                "aux_lane_ids": list(r.aux_lane_ids),
                "length_m": round(r.road.length, 6),
                "name": r.name,
                "junction_station_m": round(r.cut_station_m, 6),
                "source_roads": list(r.source_roads),
                "side": r.side,
            }
        )
    widths = [
        float(np.median(ln.width.value(np.linspace(0.0, 10.0, 3))))
        for ls in main.lane_sections
        for ln in (ls.right or ls.left)
        if ln.type == "driving"
    ]
    route = truth.route
    return {
        "scenario": f"route:{truth.source_name}",
        "seed": seed,
        "traffic_side": truth.traffic_side,
        "mainline_length_m": round(main.length, 6),
        "car_lane": car_lane,
        "lane_width_m": round(float(np.median(widths)), 3) if widths else None,
        "mainline_roads": [
            {"road_id": r.id, "station_m": round(s, 6), "length_m": round(r.length, 6)}
            for r, s in zip(roads, starts, strict=True)
        ],
        "ramps": ramps,
        "ramps_left_out": [r.to_dict() for r in (*left_out, *truth.left_out)],
        "lane_drops": _lane_drops(truth),
        "lane_sections": sections,
        "through_lanes": [
            {"station_m": round(s, 6), "lanes": n} for s, n in through_lane_counts(truth)
        ],
        "source": {
            "map": truth.source_name,
            "route": [
                {"road_id": t.road_id, "direction": "+s" if t.direction > 0 else "-s"}
                for t in route.traversals
            ],
            "junctions": [p.junction_id for p in route.passages if p.junction_id],
            "fit_max_error_mm": {k: round(v * 1000.0, 4) for k, v in truth.fit_error_m.items()},
        },
        "noise": {
            "pose": dataclasses.asdict(settings.noise),
            "sensor": dataclasses.asdict(settings.sensor),
            "osm": dataclasses.asdict(settings.osm),
            "markings": dataclasses.asdict(settings.style),
            "car": dataclasses.asdict(settings.car),
        },
        "counts": counts,
    }


def simulate_network_run(
    network: RoadNetwork,
    out_dir: str | os.PathLike,
    *,
    route: Route | Sequence[str] | None = None,
    settings: NetworkRunSettings | None = None,
    seed: int = 0,
    name: str = "network",
    left_out: Sequence[LeftOutRamp] = (),
) -> Path:
    """Simulate a mapping run along a route through ``network`` (the ground truth).

    Parameters
    ----------
    network
        Any road network (mapping-frame metres): read from OpenDRIVE
        (:func:`roadtwin.xodr.read_xodr`) or built by another generator.
    out_dir
        Run folder to write (created; files of the same names are replaced).
    route
        Road ids in driving order (directions follow from the links; connecting roads may
        be omitted), a :class:`~roadtwin.simulate.route.Route`, or None for the longest
        plausible through-route (:func:`~roadtwin.simulate.route.find_through_route`).
    settings
        Car, noise, sensor, marking style, OSM style, frame origin (defaults if None).
    seed
        Seed of every random stream; same inputs and seed give the same bytes.
    name
        Name of the source (for truth.json and comments).
    left_out
        Ramps of the source that ``network`` leaves out (e.g. OSM links the OSM truth
        could not draw), recorded in truth.json's ``ramps_left_out``.

    Returns
    -------
    Path
        ``out_dir``.

    Raises
    ------
    InputError
        An unknown or undrivable route, or a network without traffic lanes.
    """
    cfg = settings or NetworkRunSettings()
    side = cfg.traffic_side
    rt = _resolve_route(network, route, side)
    first = network.road(rt.traversals[0].road_id)
    start_xy = first.xy([0.0 if rt.traversals[0].direction > 0 else first.length])[0]
    frame = network_frame(network, cfg.origin, start_xy)
    truth = build_route_truth(
        network,
        rt,
        frame=frame,
        traffic_side=side,
        ramp_length_m=cfg.ramp_length_m,
        fit=cfg.fit,
        name=name,
    )
    poses = drive(truth, cfg.car, lookahead_m=cfg.lookahead_m, lane_change_m=cfg.lane_change_m)
    if poses.frame.size < 2:
        raise InputError(f"route {','.join(rt.road_ids)}: too short to drive")
    meas = noisy_poses(poses, cfg.noise, cfg.car.rate_hz, _rng(seed, "poses", cfg.pass_index))
    step = cfg.car.speed_kmh / 3.6 / cfg.car.rate_hz
    edge_rng = _rng(seed, "edges", cfg.pass_index)
    xyz, normal, station = true_edges(truth, cfg.sensor.edge_spacing_m, edge_rng)
    view, view_station = sensor_view(poses, station, step)
    side_code = edge_sides(xyz, view_station, view)
    edges, edge_side, edge_counts = observe_edges(
        xyz, side_code, normal, view_station, view, replace(meas, station=view.station),
        cfg.sensor, edge_rng, length_m=truth.mainline.length,
    )  # fmt: skip
    lane_rng = _rng(seed, "lanes", cfg.pass_index)
    paint, paint_station, paint_counts = painted_points(
        truth, cfg.style, cfg.sensor.lane_spacing_m, lane_rng
    )
    if cfg.opposite_markings:
        other = opposite_painted_points(
            network, truth, cfg.style, cfg.sensor.lane_spacing_m, lane_rng
        )
        paint_counts["opposite_paint_points"] = int(other.shape[0])
        paint = np.vstack([paint, other])
        paint_station = np.concatenate([paint_station, np.full(other.shape[0], np.nan)])
    view, view_station = sensor_view(poses, paint_station, step)
    frames, ego, lane_counts = observe_markings(paint, view_station, view, cfg.sensor, lane_rng)
    lane_counts.update(paint_counts)
    car_lane = cfg.car.lane or resolved_lane(truth, poses)
    edges_name = f"road_edges.{cfg.road_edges_format}"
    out = Path(out_dir)

    def fill(tmp: Path) -> None:
        write_sensor_files(tmp, meas, poses, edges, edge_side, edges_name, frames, ego)
        if cfg.osm_file:
            osm_name = copy_osm(cfg.osm_file, tmp)
            ramp_ways: dict[int, list[int]] = {}
        else:
            osm_name = "map.osm"
            ramp_ways = write_route_osm(truth, tmp / osm_name, cfg.osm, _rng(seed, "osm"))
        drive_no = f", pass {cfg.pass_index}" if cfg.pass_index > 1 else ""
        comment = (
            f"Simulated mapping run along roads {','.join(rt.road_ids)} of {name}, "
            f"seed {seed}{drive_no}."
        )
        (tmp / "run.toml").write_text(
            run_toml_text(
                comment=comment,
                origin=frame.origin,
                crs=frame.crs,
                traffic_side=side,
                edges_name=edges_name,
                osm_name=osm_name,
            ),
            encoding="utf-8",
        )
        counts = {
            "frames": int(poses.frame.size),
            "edge_points": int(edge_side.size),
            "lane_samples": int(frames.size),
            "edges": edge_counts,
            "lanes": lane_counts,
        }
        doc = route_truth_json(
            truth,
            cfg,
            seed=seed,
            car_lane=car_lane,
            ramp_ways=ramp_ways,
            counts=counts,
            left_out=left_out,
        )
        if cfg.pass_index > 1:
            doc["pass"] = cfg.pass_index
        write_truth_files(tmp, doc, truth.network)

    write_run_folder(out, fill)
    log.info(
        "simulated route %s of %s (seed %d): %.0f m (source roads %.0f m), %d frames, "
        "%d edge points, %d lane samples, %d ramps -> %s",
        ",".join(rt.road_ids), name, seed, truth.mainline.length,
        route_length_m(network, rt), poses.frame.size, edge_side.size, frames.size,
        len(truth.ramps), out,
    )  # fmt: skip
    return out


def traffic_rule_of_xodr(path: str | os.PathLike) -> TrafficSide | None:
    """``"left"`` / ``"right"`` from the ``rule`` attribute of an OpenDRIVE file's roads
    (the majority of those that have one), None when no road says."""
    path = Path(path)
    if path.name.lower().endswith(".gz"):
        with gzip.open(path, "rb") as fh:
            root = parse_xml(fh, name=path).getroot()
    else:
        root = parse_xml(path).getroot()
    rules = [el.get("rule") for el in root.iter("{*}road") if el.get("rule") in ("LHT", "RHT")]
    if not rules:
        return None
    return "left" if rules.count("LHT") > rules.count("RHT") else "right"


def simulate_xodr_run(
    xodr_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    route: Sequence[str] | None = None,
    settings: NetworkRunSettings | None = None,
    seed: int = 0,
    traffic_side: TrafficSide | None = None,
) -> Path:
    """:func:`simulate_network_run` on an OpenDRIVE file; the traffic side is
    ``traffic_side``, else the file's road ``rule``, else the settings' (right)."""
    path = Path(xodr_path)
    network = read_xodr(path)
    cfg = settings or NetworkRunSettings()
    side = traffic_side or traffic_rule_of_xodr(path) or cfg.traffic_side
    cfg = dataclasses.replace(cfg, traffic_side=side)
    return simulate_network_run(
        network, out_dir, route=route, settings=cfg, seed=seed, name=path.name
    )
