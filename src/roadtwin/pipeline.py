"""The whole build, wired in one place: mainline -> ramps -> topology -> network.

:func:`build_map` only calls the stages in order and collects their results and timings;
every stage is a pure function of plain data (DESIGN.md section 2). Loading the inputs and
writing files are the caller's job (``roadtwin build`` in :mod:`roadtwin.cli`).
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field, replace

import networkx as nx
from threadpoolctl import threadpool_limits

from . import __version__
from .config import PipelineConfig
from .evaluation import self_consistency
from .heading_bias import remove_heading_bias
from .io import MappingRun, reduce_run
from .mainline import Mainline, build_mainline
from .model import Header, Road, RoadNetwork
from .progress import progress
from .ramps import Ramp, RampSet, build_ramps, gores_from_lane_events
from .topology import Topology, build_topology

log = logging.getLogger(__name__)

__all__ = ["BuildResult", "build_map"]


@dataclass(frozen=True)
class BuildResult:
    """Everything :func:`build_map` produced.

    Attributes
    ----------
    network : the built map (mainline roads, ramp roads, connecting roads, junctions).
    ramps : the ramps integrated into ``network`` (with their decisions and warnings).
    ramp_set : the whole ramp stage result (candidates, chains, rejected, skipped).
    topology : the topology stage result (road ids of the ramps, skipped ramps).
    mainline : the mainline stage result (lane events, residuals).
    timings_s : seconds per stage (``mainline``, ``ramps``, ``topology``).
    warnings : every stage's notes (fallback rules, disagreements, skipped ramps).
    """

    network: RoadNetwork
    ramps: tuple[Ramp, ...]
    ramp_set: RampSet
    topology: Topology
    mainline: Mainline
    timings_s: dict[str, float] = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def summary(self) -> dict[str, float | int]:
        """Counts and lengths: roads, ramps by type, kilometres, seconds."""
        roads = self.network.roads
        return {
            "roads": len(roads),
            "mainline_roads": sum(r.name == "mainline" for r in roads),
            "connecting_roads": sum(r.junction != "-1" for r in roads),
            "junctions": len(self.network.junctions),
            "exits": sum(r.type == "exit" for r in self.ramps),
            "entries": sum(r.type == "entry" for r in self.ramps),
            "mainline_km": sum(r.length for r in roads if r.name == "mainline") / 1000.0,
            "ramp_km": sum(r.length for r in roads if r.name in ("exit", "entry")) / 1000.0,
            "total_km": sum(r.length for r in roads) / 1000.0,
            "seconds": sum(self.timings_s.values()),
        }


def with_osm_way_ids(topology: Topology) -> tuple[Road, ...]:
    """The topology's roads, each ramp road carrying the OSM way ids it was built from."""
    ways = {
        rid: tuple(int(w) for w in ramp.osm_way_ids)
        for rid, ramp in zip(topology.ramp_road_ids, topology.ramps, strict=True)
    }
    return tuple(
        replace(road, osm_way_ids=ways[road.id]) if road.id in ways else road
        for road in topology.roads
    )


def build_map(
    run: MappingRun,
    osm_graph: nx.MultiDiGraph | None,
    *,
    config: PipelineConfig | None = None,
) -> BuildResult:
    """Build the georeferenced road network of a mapping run.

    Parameters
    ----------
    run
        The mapping run (``roadtwin.io.load_run``), mapping frame.
    osm_graph
        OSM graph in the same mapping frame (``roadtwin.osm.load_osm``), or ``None``
        (then the map has the mainline only).
    config
        Stage settings.

    Returns
    -------
    BuildResult
        The network (header with the run's geoReference, OpenDRIVE 1.8) and every stage's
        result. A ramp that cannot be built or integrated is skipped with a warning.
    """
    # the stages solve many small dense problems: BLAS threads only contend for the cores
    with threadpool_limits(limits=1, user_api="blas"):
        return _build_map(run, osm_graph, config or PipelineConfig())


def _build_map(
    run: MappingRun, osm_graph: nx.MultiDiGraph | None, cfg: PipelineConfig
) -> BuildResult:
    timings: dict[str, float] = {}
    warnings: list[str] = []

    # dense points -> a few rows per metre of each line (a no-op for a run from load_run,
    # which reduced while reading): every stage below sees the same kind of input at any
    # density
    run = reduce_run(run, config=cfg.load)
    if cfg.mainline.method == "default" and cfg.mainline.heading_bias:
        run = remove_heading_bias(run)

    t0 = time.perf_counter()
    with progress("mainline"):
        mainline = build_mainline(run, config=cfg.mainline)
    timings["mainline"] = time.perf_counter() - t0
    warnings.extend(st.message() for st in mainline.stretches)

    t0 = time.perf_counter()
    with progress("ramps"):
        if osm_graph is not None and osm_graph.number_of_edges() > 0:
            ramp_set = build_ramps(
                osm_graph,
                mainline.road,
                trajectory_xy=run.trajectory.xy,
                traffic_side=run.traffic_side,
                gores=gores_from_lane_events(
                    mainline.lane_events, mainline.road, traffic_side=run.traffic_side
                ),
                edge_xy=run.edges,
                lane_xy=run.lane_samples,
                config=cfg.ramps,
            )
        else:
            ramp_set = RampSet(ramps=(), candidates=())
            warnings.append("no OSM graph: the map has the mainline only")
    warnings.extend(ramp_set.warnings)
    timings["ramps"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    with progress("topology"):
        topology = build_topology(
            mainline.road,
            ramp_set.ramps,
            traffic_side=run.traffic_side,
            config=cfg.topology,
            outer_edge_seen=mainline.outer_edge_seen,
        )
    warnings.extend(f"skipped {what}: {why}" for what, why in topology.skipped)
    timings["topology"] = time.perf_counter() - t0

    roads = with_osm_way_ids(topology)
    header = Header(
        name=run.root.name if run.root is not None else "roadtwin",
        rev_major=1,
        rev_minor=8,
        geo_reference=run.frame.geo_reference,
        # local frame: z is metres above the origin's altitude; <offset z> restores it
        offset=(0.0, 0.0, run.frame.z_offset_m, 0.0) if run.frame.z_offset_m else None,
    )
    network = RoadNetwork(header, roads, topology.junctions)

    # The self-consistency RMSE is how far the run's own points lie from the map: a fit
    # residual, not the "error range of the measurement data" (absolute, or relative
    # between adjacent entries) that OpenDRIVE's <dataQuality><error> records, so it goes
    # into <userData>; <dataQuality> stays empty until a run states its GNSS accuracy.
    t0 = time.perf_counter()
    with progress("self-consistency"):
        sc = self_consistency(network, run, config=cfg.evaluation)
    user_data = [
        ("roadtwin:generator", f"roadtwin {__version__}"),
        ("roadtwin:method", cfg.mainline.method),
        ("roadtwin:junctions", cfg.topology.junctions),
        (
            "roadtwin:self_consistency_rmse_m",
            " ".join(
                f"{key}={sc[key + '_rmse_m']:.4f}"
                for key in ("road_edge", "lane_boundary", "overall", "height")
            ),
        ),
    ]
    if any(r.osm_way_ids for r in roads):
        user_data.append(
            (
                "roadtwin:attribution",
                "ramps from OpenStreetMap: (c) OpenStreetMap contributors, ODbL 1.0",
            )
        )
    network = replace(network, header=replace(header, user_data=tuple(user_data)))
    timings["self-consistency"] = time.perf_counter() - t0
    log.info(
        "built %d roads, %d junctions (%d ramps) in %.2f s",
        len(network.roads),
        len(network.junctions),
        len(topology.ramps),
        sum(timings.values()),
    )
    return BuildResult(
        network=network,
        ramps=topology.ramps,
        ramp_set=ramp_set,
        topology=topology,
        mainline=mainline,
        timings_s=timings,
        warnings=tuple(warnings),
    )
