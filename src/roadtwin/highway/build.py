"""The whole highway from several runs (or from OSM alone), wired in one place.

:func:`build_highway` -- runs of any frames and directions:

1. every run into the first run's frame; runs grouped by carriageway
   (:func:`~.runs.group_runs`);
2. per carriageway the runs fused (:func:`~.runs.fuse_runs`) and built by the single-run
   pipeline (:func:`roadtwin.pipeline.build_map`: mainline, ramps, topology);
3. per carriageway that no run drove beside a measured one, the OSM carriageway of the
   other direction (:func:`roadtwin.osm_roads.opposite_carriageway`) with its ramps
   (:func:`roadtwin.ramps.build_ramps`, :func:`roadtwin.topology.build_topology`);
4. the road beyond every ramp (:func:`roadtwin.osm_roads.beyond_roads`), linked to it;
5. everything merged into one network (:func:`~.merge.merge_parts`), every road tagged
   with its carriageway and source.

:func:`build_osm_only` -- every one-way motorway/trunk carriageway of an OSM graph from OSM
alone (:func:`roadtwin.osm_roads.carriageway_from_osm`), with its ramps and the roads
beyond them.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import networkx as nx
import numpy as np
from threadpoolctl import threadpool_limits

from .. import __version__
from .._errors import FitError, InputError
from ..config import PipelineConfig
from ..evaluation import self_consistency
from ..frames import MappingFrame
from ..heading_bias import remove_heading_bias
from ..io import MappingRun
from ..model import Header, Junction, Road, RoadNetwork
from ..osm_roads import (
    BeyondRoad,
    CrossSection,
    OsmRoad,
    beyond_roads,
    carriageway_chains,
    carriageway_from_osm,
    link_beyond,
    measured_cross_section,
    opposite_carriageway,
)
from ..osm_roads.chains import shared_length_m
from ..pipeline import BuildResult, build_map, with_osm_way_ids
from ..ramps import RampSet, build_ramps
from ..topology import Topology, build_topology
from .merge import NetworkPart, merge_parts
from .runs import FusedRun, RunGroups, fuse_runs, group_runs, run_in_frame, run_name

log = logging.getLogger(__name__)

__all__ = ["Carriageway", "HighwayResult", "build_highway", "build_osm_only"]

_ATTRIBUTION = "(c) OpenStreetMap contributors, ODbL 1.0"


@dataclass(frozen=True)
class Carriageway:
    """One carriageway of the built highway.

    Attributes
    ----------
    number : 1, 2, ... (the ``roadtwin:carriageway`` of its roads).
    source : ``"lidar"`` (built from runs) or ``"osm"`` (from OSM alone).
    runs : names of the runs fused into it (empty for ``osm``).
    fused : the fused run (``lidar``).
    build : the single-run pipeline's result on the fused run (``lidar``).
    osm_road : the carriageway built from OSM (``osm``).
    ramp_set, topology : its ramp and topology stage results.
    road_ids : ids of its roads in the merged network.
    ramp_road_ids : ids of its ramp roads in the merged network (order of
        ``topology.ramps``).
    partner : the number of the carriageway of the other direction, or None.
    """

    number: int
    source: str
    runs: tuple[str, ...]
    ramp_set: RampSet
    topology: Topology
    fused: FusedRun | None = None
    build: BuildResult | None = None
    osm_road: OsmRoad | None = None
    road_ids: tuple[str, ...] = ()
    ramp_road_ids: tuple[str, ...] = ()
    partner: int | None = None
    run_self_consistency: tuple[tuple[str, dict[str, float]], ...] = ()
    """Per fused run, the self-consistency RMSE (metres) of its own points against the
    carriageway built from all runs (``road_edge_rmse_m``, ``lane_boundary_rmse_m``, ...):
    every run, not only their union, should be explained by the map."""


@dataclass(frozen=True)
class HighwayResult:
    """Everything :func:`build_highway` / :func:`build_osm_only` produced.

    Attributes
    ----------
    network : the merged map.
    carriageways : each carriageway's stages and its road ids in ``network``.
    beyond : the roads beyond the ramps (ids in ``network``).
    groups : how the runs were grouped (``None`` in the OSM-only mode).
    frame : the mapping frame of everything.
    timings_s, warnings : per stage seconds, every stage's notes.
    """

    network: RoadNetwork
    carriageways: tuple[Carriageway, ...]
    beyond: tuple[BeyondRoad, ...]
    groups: RunGroups | None
    frame: MappingFrame
    timings_s: dict[str, float] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def summary(self) -> dict[str, float | int]:
        """Counts and lengths: carriageways by source, roads, ramps, kilometres."""
        roads = self.network.roads
        ramps = [r for r in roads if r.name in ("exit", "entry")]
        return {
            "carriageways": len(self.carriageways),
            "lidar_carriageways": sum(c.source == "lidar" for c in self.carriageways),
            "osm_carriageways": sum(c.source == "osm" for c in self.carriageways),
            "runs": sum(len(c.runs) for c in self.carriageways),
            "roads": len(roads),
            "mainline_roads": sum(r.name == "mainline" for r in roads),
            "connecting_roads": sum(r.junction != "-1" for r in roads),
            "junctions": len(self.network.junctions),
            "exits": sum(r.name == "exit" for r in ramps),
            "entries": sum(r.name == "entry" for r in ramps),
            "beyond_roads": len(self.beyond),
            "mainline_km": sum(r.length for r in roads if r.name == "mainline") / 1000.0,
            "ramp_km": sum(r.length for r in ramps) / 1000.0,
            "total_km": sum(r.length for r in roads) / 1000.0,
            "seconds": sum(self.timings_s.values()),
        }


@dataclass
class _Part:
    """A carriageway before merging (roads with their part-local ids)."""

    carriageway: Carriageway
    roads: list[Road]
    junctions: tuple[Junction, ...]
    beyond: list[BeyondRoad] = field(default_factory=list)


def _osm_part(
    number: int,
    osm_road: OsmRoad,
    osm_graph: nx.MultiDiGraph,
    *,
    traffic_side: str,
    cfg: PipelineConfig,
    partner: int | None,
) -> _Part:
    """Ramps and topology of a carriageway built from OSM: a ramp attaches at the gore of
    its lanes where OSM's lane count changes next to it (found in the road's lane
    sections), else at its OSM node."""
    ramp_set = build_ramps(
        osm_graph,
        osm_road.road,
        trajectory_xy=osm_road.path_xy,
        traffic_side=traffic_side,  # type: ignore[arg-type]
        config=cfg.ramps,
    )
    topology = build_topology(
        osm_road.road,
        ramp_set.ramps,
        traffic_side=traffic_side,  # type: ignore[arg-type]
        config=cfg.topology,
    )
    # the gores of an OSM-built road come from OSM's lane counts, not from a run
    osm_words = {"lidar gore": "osm lane change", "mainline lane change": "osm lane change"}
    topology = replace(
        topology,
        ramps=tuple(
            replace(
                r,
                station_source=osm_words.get(r.station_source, r.station_source),
                lane_rule=osm_words.get(r.lane_rule, r.lane_rule),
            )
            for r in topology.ramps
        ),
    )
    roads = list(with_osm_way_ids(topology))
    cw = Carriageway(number, "osm", (), ramp_set, topology, osm_road=osm_road, partner=partner)
    return _Part(cw, roads, topology.junctions)


def _add_beyond(
    part: _Part, osm_graph: nx.MultiDiGraph, *, traffic_side: str, lane_width_m: float, cfg
) -> list[str]:
    """Build and link the road beyond every ramp of a part (in place)."""
    topo = part.carriageway.topology
    by_id = {r.id: r for r in part.roads}
    found, notes = beyond_roads(
        osm_graph,
        by_id,
        list(zip(topo.ramp_road_ids, topo.ramps, strict=True)),
        part.carriageway.ramp_set.chains,
        traffic_side=traffic_side,
        lane_width_m=lane_width_m,
        config=cfg.highway,
        ramp_config=cfg.ramps,
    )
    next_id = 1 + max((int(r.id) for r in part.roads if r.id.isdigit()), default=0)
    next_id = max(
        next_id, 1 + max((int(j.id) for j in part.junctions if j.id.isdigit()), default=0)
    )
    for b in found:
        new_id = str(next_id)
        next_id += 1
        ramp, road = link_beyond(
            by_id[b.ramp_road_id],
            replace(b.road, id=new_id),
            exit_=b.ramp_type == "exit",
            traffic_side=traffic_side,
        )
        by_id[ramp.id] = ramp
        part.beyond.append(replace(b, road=road))
    part.roads = [by_id[r.id] for r in part.roads] + [b.road for b in part.beyond]
    return [f"carriageway {part.carriageway.number}: {n}" for n in notes]


def _header(name: str, frame: MappingFrame, user_data: list[tuple[str, str]]) -> Header:
    return Header(
        name=name,
        rev_major=1,
        rev_minor=8,
        geo_reference=frame.geo_reference,
        offset=(0.0, 0.0, frame.z_offset_m, 0.0) if frame.z_offset_m else None,
        user_data=tuple(user_data),
    )


def _finish(
    parts: list[_Part],
    *,
    name: str,
    frame: MappingFrame,
    user_data: list[tuple[str, str]],
    groups: RunGroups | None,
    timings: dict[str, float],
    warnings: list[str],
) -> HighwayResult:
    """Merge the parts, give the carriageways their final road ids."""
    merged_parts = [
        NetworkPart(tuple(p.roads), p.junctions, p.carriageway.number, p.carriageway.source)
        for p in parts
    ]
    roads, junctions, maps = merge_parts(merged_parts)
    carriageways = []
    beyond: list[BeyondRoad] = []
    for p, m in zip(parts, maps, strict=True):
        cw = p.carriageway
        carriageways.append(
            replace(
                cw,
                road_ids=tuple(m[r.id] for r in p.roads),
                ramp_road_ids=tuple(m[i] for i in cw.topology.ramp_road_ids),
            )
        )
        beyond.extend(
            replace(
                b,
                road=next(r for r in roads if r.id == m[b.road.id]),
                ramp_road_id=m[b.ramp_road_id],
            )
            for b in p.beyond
        )
    if any(r.osm_way_ids for r in roads):
        user_data.append(("roadtwin:attribution", f"OpenStreetMap data: {_ATTRIBUTION}"))
    user_data.append(
        (
            "roadtwin:carriageways",
            "; ".join(
                f"{c.number}: {c.source}"
                + (f" (runs {', '.join(c.runs)})" if c.runs else "")
                + (f", other direction of {c.partner}" if c.partner else "")
                for c in carriageways
            ),
        )
    )
    network = RoadNetwork(_header(name, frame, user_data), roads, junctions)
    log.info(
        "highway: %d carriageways, %d roads, %d junctions, %d roads beyond ramps",
        len(carriageways),
        len(roads),
        len(junctions),
        len(beyond),
    )
    return HighwayResult(
        network, tuple(carriageways), tuple(beyond), groups, frame, timings, tuple(warnings)
    )


def build_highway(
    runs: Sequence[MappingRun],
    osm_graph: nx.MultiDiGraph | None,
    *,
    config: PipelineConfig | None = None,
) -> HighwayResult:
    """Build the whole highway from one or several mapping runs and OSM.

    Parameters
    ----------
    runs
        Mapping runs of any frames, directions and extents (``roadtwin.io.load_run``);
        everything goes into the first run's frame.
    osm_graph
        OSM graph in the first run's frame around all runs (``roadtwin.osm.load_osm``), or
        None (then: the measured carriageways without ramps, nothing from OSM).
    config
        Stage settings; ``config.highway`` for grouping, fusion and the OSM-built roads.

    Returns
    -------
    HighwayResult

    Raises
    ------
    InputError
        No runs, or runs of different traffic sides.
    """
    if not runs:
        raise InputError("build: no mapping run given")
    cfg = config or PipelineConfig()
    with threadpool_limits(limits=1, user_api="blas"):
        return _build_highway(list(runs), osm_graph, cfg)


def _build_highway(
    runs: list[MappingRun], osm_graph: nx.MultiDiGraph | None, cfg: PipelineConfig
) -> HighwayResult:
    timings: dict[str, float] = {}
    warnings: list[str] = []
    hw = cfg.highway
    t0 = time.perf_counter()
    frame = runs[0].frame
    if len({r.traffic_side for r in runs}) > 1:
        raise InputError("build: the runs have different [traffic] sides")
    side = runs[0].traffic_side
    runs = [run_in_frame(r, frame) for r in runs]
    if cfg.mainline.method == "default" and cfg.mainline.heading_bias:
        # each run's own poses: the fused run's poses are its carriageway's spine
        runs = [remove_heading_bias(r) for r in runs]
    groups = group_runs(runs, config=hw)
    timings["group runs"] = time.perf_counter() - t0

    parts: list[_Part] = []
    for k, members in enumerate(groups.carriageways):
        t0 = time.perf_counter()
        fused = fuse_runs([runs[i] for i in members], config=hw)
        warnings.extend(fused.warnings)
        timings[f"fuse {k + 1}"] = time.perf_counter() - t0
        result = build_map(fused.run, osm_graph, config=cfg)
        for key, value in result.timings_s.items():
            timings[f"{key} {k + 1}"] = value
        warnings.extend(result.warnings)
        partner = groups.partner(k)
        per_run: tuple[tuple[str, dict[str, float]], ...] = ()
        if len(members) > 1:
            per_run = tuple(
                (run_name(r, i), self_consistency(result.network, r, config=cfg.evaluation))
                for i, r in zip(members, fused.runs, strict=True)
            )
        cw = Carriageway(
            k + 1,
            "lidar",
            tuple(run_name(runs[i], i) for i in members),
            result.ramp_set,
            result.topology,
            fused=fused,
            build=result,
            partner=None if partner is None else partner + 1,
            run_self_consistency=per_run,
        )
        parts.append(_Part(cw, list(result.network.roads), result.network.junctions))

    has_osm = osm_graph is not None and osm_graph.number_of_edges() > 0
    if hw.opposite and has_osm:
        t0 = time.perf_counter()
        for k, part in enumerate(list(parts)):
            if groups.partner(k) is not None:
                continue
            build = part.carriageway.build
            assert build is not None  # a measured carriageway
            xs = measured_cross_section(
                build.mainline.road,
                traffic_side=side,
                default=CrossSection(hw.lane_width_m, hw.inner_shoulder_m, hw.hard_shoulder_m),
            )
            fused = part.carriageway.fused
            assert fused is not None
            try:
                osm_road = opposite_carriageway(
                    build.mainline.road,
                    osm_graph,
                    path_xy=fused.run.trajectory.xy,
                    traffic_side=side,
                    cross=xs,
                    config=hw,
                )
            except FitError as exc:
                warnings.append(f"other carriageway of {k + 1} not built: {exc}")
                continue
            if osm_road is None:
                warnings.append(f"carriageway {k + 1}: OSM has no other direction beside it")
                continue
            number = len(parts) + 1
            parts.append(
                _osm_part(number, osm_road, osm_graph, traffic_side=side, cfg=cfg, partner=k + 1)
            )
            parts[k].carriageway = replace(part.carriageway, partner=number)
            warnings.extend(osm_road.notes)
            warnings.extend(parts[-1].carriageway.ramp_set.warnings)
        timings["other carriageway"] = time.perf_counter() - t0

    if hw.beyond and has_osm:
        t0 = time.perf_counter()
        for part in parts:
            build = part.carriageway.build
            lane_w = (
                hw.lane_width_m
                if build is None
                else measured_cross_section(build.mainline.road, traffic_side=side).lane_width_m
            )
            warnings.extend(
                _add_beyond(part, osm_graph, traffic_side=side, lane_width_m=lane_w, cfg=cfg)
            )
        timings["roads beyond ramps"] = time.perf_counter() - t0

    user_data = [("roadtwin:generator", f"roadtwin {__version__}")]
    for part in parts:
        build = part.carriageway.build
        if build is None:  # built from OSM
            continue
        for code, value in build.network.header.user_data:
            if code.startswith("roadtwin:self_consistency") or code in (
                "roadtwin:method",
                "roadtwin:junctions",
            ):
                suffix = "" if part.carriageway.number == 1 else f":{part.carriageway.number}"
                if code in ("roadtwin:method", "roadtwin:junctions") and suffix:
                    continue
                user_data.append((code + suffix, value))
    name = runs[0].root.name if runs[0].root is not None else "roadtwin"
    return _finish(
        parts,
        name=name,
        frame=frame,
        user_data=user_data,
        groups=groups,
        timings=timings,
        warnings=warnings,
    )


def build_osm_only(
    osm_graph: nx.MultiDiGraph,
    frame: MappingFrame,
    *,
    traffic_side: str = "right",
    name: str = "osm",
    box_xy: tuple[float, float, float, float] | None = None,
    config: PipelineConfig | None = None,
) -> HighwayResult:
    """Every one-way motorway/trunk carriageway of an OSM graph from OSM alone, with its
    ramps and the roads beyond them (OSM accuracy; lanes from the tags, widths from
    ``config.highway``). ``box_xy = (xmin, ymin, xmax, ymax)`` (mapping frame, metres)
    keeps the carriageways' longest parts inside that box.

    Raises
    ------
    InputError
        The graph has no carriageway of at least ``min_carriageway_m``.
    """
    cfg = config or PipelineConfig()
    with threadpool_limits(limits=1, user_api="blas"):
        return _build_osm_only(osm_graph, frame, traffic_side, name, box_xy, cfg)


def _build_osm_only(
    osm_graph: nx.MultiDiGraph,
    frame: MappingFrame,
    traffic_side: str,
    name: str,
    box_xy: tuple[float, float, float, float] | None,
    cfg: PipelineConfig,
) -> HighwayResult:
    hw = cfg.highway
    timings: dict[str, float] = {}
    warnings: list[str] = []
    t0 = time.perf_counter()
    chains = carriageway_chains(osm_graph, min_length_m=hw.min_carriageway_m)
    if box_xy is not None:
        chains = [c for c in (c.inside(box_xy) for c in chains) if c is not None]
        chains = [c for c in chains if c.length >= hw.min_carriageway_m]
    if not chains:
        msg = (
            f"OSM-only build: no one-way motorway/trunk carriageway of at least "
            f"{hw.min_carriageway_m:.0f} m in the area"
        )
        raise InputError(msg)
    timings["carriageways"] = time.perf_counter() - t0
    parts: list[_Part] = []
    t0 = time.perf_counter()
    for chain in chains:
        try:
            osm_road = carriageway_from_osm(chain, osm_graph, traffic_side=traffic_side, config=hw)
        except FitError as exc:
            warnings.append(f"carriageway {chain.way_ids[0]} not built: {exc}")
            continue
        parts.append(
            _osm_part(
                len(parts) + 1,
                osm_road,
                osm_graph,
                traffic_side=traffic_side,
                cfg=cfg,
                partner=None,
            )
        )
        warnings.extend(osm_road.notes)
        warnings.extend(parts[-1].carriageway.ramp_set.warnings)
    timings["build carriageways"] = time.perf_counter() - t0
    paths = [p.carriageway.osm_road.path_xy for p in parts]
    for a in range(len(parts)):
        for b in range(a + 1, len(parts)):
            if _opposite_paths(paths[a], paths[b], cfg):
                parts[a].carriageway = replace(parts[a].carriageway, partner=b + 1)
                parts[b].carriageway = replace(parts[b].carriageway, partner=a + 1)
    if hw.beyond:
        t0 = time.perf_counter()
        for part in parts:
            warnings.extend(
                _add_beyond(
                    part,
                    osm_graph,
                    traffic_side=traffic_side,
                    lane_width_m=hw.lane_width_m,
                    cfg=cfg,
                )
            )
        timings["roads beyond ramps"] = time.perf_counter() - t0
    user_data = [
        ("roadtwin:generator", f"roadtwin {__version__}"),
        ("roadtwin:method", "osm-only"),
        ("roadtwin:junctions", cfg.topology.junctions),
    ]
    return _finish(
        parts,
        name=name,
        frame=frame,
        user_data=user_data,
        groups=None,
        timings=timings,
        warnings=warnings,
    )


def _opposite_paths(a: np.ndarray, b: np.ndarray, cfg: PipelineConfig) -> bool:
    """Two carriageway paths are the two directions of one road."""
    shared = shared_length_m(a, b, distance_m=cfg.highway.opposite_carriageway_m, opposite=True)
    return shared >= cfg.highway.min_overlap_m
