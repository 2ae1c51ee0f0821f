"""The ramp stage: :func:`build_ramps` wires candidates, chains, lane counts, measured
gores and ramp roads into a :class:`RampSet`.
"""

from __future__ import annotations

import logging

import networkx as nx
import numpy as np
from scipy.spatial import cKDTree

from .._errors import FitError
from ..config import RampConfig
from ..model import Road
from .candidates import extract_ramp_chains, find_candidates
from .gores import _outer_shoulder, edge_driving_lane, gore_events
from .lanes import infer_lane_count
from .records import (
    _EVIDENCE_LATERAL_M,
    FloatArray,
    GoreEvent,
    Ramp,
    RampChain,
    RampSet,
    TrafficSide,
)
from .road import _build_ramp_road

log = logging.getLogger(__name__)

_SCANNED_GORE_M = 75.0  # an OSM attachment this close to an unlinked lane birth / end
# of the mainline (no measured gore) is attached there (metres; OSM is drawn tens of
# metres off at most)

# ---------------------------------------------------------------------------
# the stage
# ---------------------------------------------------------------------------


def _match_gores(
    chains: tuple[RampChain, ...],
    stations: list[float],
    events: tuple[GoreEvent, ...],
    cfg: RampConfig,
    max_m: float = float("inf"),
) -> dict[int, GoreEvent]:
    """Greedy one-to-one matching of chains to measured gores of their type, within the
    configured search window and at most ``max_m`` (metres) from the OSM attachment."""
    up = min(cfg.gore_search_upstream_m, max_m)
    down = min(cfg.gore_search_downstream_m, max_m)
    pairs = []
    for i, (chain, s_osm) in enumerate(zip(chains, stations, strict=False)):
        for j, ev in enumerate(events):
            if ev.kind != chain.type or ev.side != chain.side:
                continue
            d = ev.station_m - s_osm
            if chain.type == "entry":
                d = -d
            if -up <= d <= down:
                pairs.append((abs(d), i, j))
    out: dict[int, GoreEvent] = {}
    used: set[int] = set()
    for _, i, j in sorted(pairs):
        if i in out or j in used:
            continue
        out[i] = events[j]
        used.add(j)
    return out


def build_ramps(
    osm_graph: nx.MultiDiGraph,
    mainline_road: Road,
    *,
    trajectory_xy: FloatArray,
    traffic_side: TrafficSide = "right",
    gores: tuple[GoreEvent, ...] | None = None,
    edge_xy: FloatArray | None = None,
    lane_xy: FloatArray | None = None,
    config: RampConfig | None = None,
) -> RampSet:
    """The ramp stage: OSM graph + measured mainline -> ramp roads with their decisions.

    Parameters
    ----------
    osm_graph
        OSM graph in the mapping frame (``roadtwin.osm.load_osm``).
    mainline_road
        The measured mainline (one road over the run, driving direction).
    trajectory_xy
        ``(N, 2)`` vehicle positions, mapping frame, metres.
    traffic_side
        ``"right"`` or ``"left"``.
    gores
        Measured gores (:func:`gores_from_lane_events` on the mainline stage's lane
        events); ``None`` scans the road's lane sections (:func:`gore_events`). An OSM
        attachment that matches none of ``gores`` still goes to a driving lane of the road
        that begins (entry) / ends (exit) at full width without a link within
        ``_SCANNED_GORE_M`` of it (the edge step there was not measured); else OSM decides.
    edge_xy, lane_xy
        The run's measured road-edge points and lane samples (``(N, 2+)``, mapping frame,
        metres): those past each gore shape the ramp's first part and give its widths
        (:func:`~roadtwin.ramps.shape.fit_ramp_shape`). ``None``: OSM shape and default widths.
    config
        Ramp settings.

    Returns
    -------
    RampSet
        Ramps sorted by station. A ramp that cannot be built is listed in ``skipped``
        with its reason (and a warning), never raised.
    """
    cfg = config or RampConfig()
    if not cfg.use_evidence:
        edge_xy = lane_xy = None
    candidates = find_candidates(osm_graph, trajectory_xy, config=cfg)
    chains, rejected = extract_ramp_chains(
        osm_graph, trajectory_xy, traffic_side=traffic_side, candidates=candidates, config=cfg
    )
    events = gore_events(mainline_road, traffic_side=traffic_side) if gores is None else gores
    stations = []
    for chain in chains:
        node = osm_graph.nodes[chain.attach_node]
        s, _ = mainline_road.project(np.array([[node["x"], node["y"]]]))
        stations.append(float(s[0]))
    matched = _match_gores(chains, stations, events, cfg)
    if gores is not None:
        # a driving lane of the mainline that begins (ends) at full width without a
        # measured gore (the edge step unseen: noise, a truck) is where a ramp joins
        # (leaves); an OSM attachment near one without a measured gore goes there
        scanned = tuple(
            g
            for g in gore_events(mainline_road, traffic_side=traffic_side)
            if all(g.kind != e.kind or abs(g.station_m - e.station_m) > 1.0 for e in events)
        )
        todo = [i for i in range(len(chains)) if i not in matched]
        if scanned and todo:
            more = _match_gores(
                tuple(chains[i] for i in todo),
                [stations[i] for i in todo],
                scanned,
                cfg,
                _SCANNED_GORE_M,
            )
            matched.update({todo[k]: ev for k, ev in more.items()})
    # KD-trees of the measured points, built once; each ramp gets the points near its gore
    measured = {}
    for key, pts in (("edge", edge_xy), ("lane", lane_xy)):
        if pts is not None and len(pts):
            xy = np.asarray(pts, dtype=float)[:, :2]
            measured[key] = (xy, cKDTree(xy))

    def near_gore(key: str, station: float) -> FloatArray | None:
        if key not in measured:
            return None
        xy, tree = measured[key]
        s_c = float(np.clip(station, 0.0, mainline_road.length))
        centre = mainline_road.to_xy(np.array([s_c]), np.array([0.0])).reshape(2)
        idx = tree.query_ball_point(centre, r=cfg.evidence_length_m + 2.0 * _EVIDENCE_LATERAL_M)
        return xy[np.sort(np.asarray(idx, dtype=np.int64))]

    ramps: list[Ramp] = []
    skipped: list[tuple[str, str]] = []
    warnings: list[str] = []
    # a branch drawn over the carriageway's nodes is built only on the side where a
    # measured gore shows its lanes leave or join
    confirmed = {chains[i].edges for i in matched if chains[i].shared}
    for i, (chain, s_osm) in enumerate(zip(chains, stations, strict=False)):
        what = f"{chain.type} ways {', '.join(str(w) for w in chain.osm_way_ids)}"
        if chain.shared and i not in matched:
            if chain.edges not in confirmed and chain.side == "outer":
                skipped.append((what, "drawn over the carriageway's nodes, no measured gore"))
            continue
        notes: list[str] = []
        osm_lanes, osm_rule = infer_lane_count(chain.tags, link_rule=cfg.link_lane_rule)
        if osm_rule == "highway class":
            notes.append(f"{what}: no lane tags, lane count {osm_lanes} from the highway class")
        if chain.type != chain.type_geometry:
            notes.append(
                f"{what}: connectivity says {chain.type}, geometry says {chain.type_geometry}"
                f" (kept {chain.type})"
            )
        event = matched.get(i)
        if event is not None:
            station, source = event.station_m, "lidar gore"
            lanes, rule = max(1, len(event.lane_ids)), "mainline lane change"
            mainline_lanes = event.lane_ids
            if lanes != osm_lanes:
                notes.append(
                    f"{what}: OSM says {osm_lanes} lane(s) ({osm_rule}), the mainline lane "
                    f"change says {lanes}; using {lanes}"
                )
        else:
            station, source = s_osm, "osm"
            bounds = np.array([sec.s0 for sec in mainline_road.lane_sections[1:]])
            if bounds.size:
                near = bounds[np.argmin(np.abs(bounds - station))]
                if abs(near - station) <= cfg.snap_to_section_m:
                    station = float(near)
            if not cfg.min_ramp_length_m < station < mainline_road.length - 1.0:
                reason = f"attachment at s={station:.0f} m is outside the measured mainline"
                skipped.append((what, reason))
                warnings.append(f"skipped {what}: {reason}")
                continue
            lanes, rule = max(1, osm_lanes), osm_rule
            s_src = station - 1e-6 if chain.type == "exit" else station + 1e-6
            try:
                through = edge_driving_lane(
                    mainline_road, s_src, traffic_side=traffic_side, side=chain.side
                )
            except FitError as exc:
                skipped.append((what, str(exc)))
                warnings.append(f"skipped {what}: {exc}")
                continue
            mainline_lanes = (through,)
        shoulder = None
        if source == "lidar gore" and chain.side == "outer":
            shoulder = _outer_shoulder(
                mainline_road, station, chain.type, mainline_lanes, traffic_side
            )
        try:
            road, gap, dh, evidence = _build_ramp_road(
                chain.xy,
                mainline_road,
                ramp_type=chain.type,
                lanes=lanes,
                station_m=station,
                source_lane_ids=tuple(mainline_lanes),
                traffic_side=traffic_side,
                side=chain.side,
                road_id=f"ramp{i}",
                shoulder_lane_id=shoulder,
                edge_xy=near_gore("edge", station),
                lane_xy=near_gore("lane", station),
                config=cfg,
            )
        except (FitError, ValueError) as exc:
            skipped.append((what, str(exc)))
            warnings.append(f"skipped {what}: {exc}")
            log.warning("skipped %s: %s", what, exc)
            continue
        warnings.extend(notes)
        ramps.append(
            Ramp(
                type=chain.type,
                road=road,
                station_m=station,
                lanes=lanes,
                lane_rule=rule,
                osm_lanes=osm_lanes,
                osm_lane_rule=osm_rule,
                station_source=source,
                mainline_lane_ids=tuple(mainline_lanes),
                type_connectivity=chain.type,
                type_geometry=chain.type_geometry,
                osm_way_ids=chain.osm_way_ids,
                attach_gap_m=gap,
                attach_heading_deg=dh,
                warnings=tuple(notes),
                shoulder_lane_id=shoulder,
                evidence=evidence,
                side=chain.side,
            )
        )
    ramps.sort(key=lambda r: (r.station_m, r.type))
    log.info(
        "ramps: %d built (%d exit, %d entry), %d skipped, %d candidates",
        len(ramps),
        sum(r.type == "exit" for r in ramps),
        sum(r.type == "entry" for r in ramps),
        len(skipped),
        len(candidates),
    )
    return RampSet(
        ramps=tuple(ramps),
        candidates=candidates,
        chains=chains,
        rejected=rejected,
        skipped=tuple(skipped),
        warnings=tuple(warnings),
    )
