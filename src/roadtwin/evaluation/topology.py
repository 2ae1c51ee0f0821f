"""Topology against truth: ramps matched / missed / spurious, merge-exit type, and
lane-level reachability through lane links."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

from ..config import EvaluationConfig
from ..model import Road, RoadNetwork
from ..topology import lane_graph
from .frenet import FloatArray, _section_centre_t, mainline_roads, ramp_roads


def _road_ends(road: Road) -> FloatArray:
    """``(2, 2)`` centre points of a road's lanes at its start and end (mapping frame)."""
    ends = np.array([0.0, road.length])
    sec = [road.lane_sections[int(i)] for i in road.section_index(ends)]
    t = np.array([_section_centre_t(road, ends[i : i + 1], sec[i])[0] for i in range(2)])
    return road.to_xy(ends, t).reshape(2, 2)


def _attachment_point(network: RoadNetwork, road: Road, mainline: Sequence[Road]) -> FloatArray:
    """Where a ramp meets the mainline (mapping frame, metres).

    Follows the links: the end of a junction connecting road between the ramp road and a
    mainline road, on the mainline side; else the ramp road's end that links to a junction
    or a mainline road. Without such links: the ramp road's end nearer the mainline
    reference lines.
    """
    main_ids = {r.id for r in mainline}
    ends = _road_ends(road)
    linked = []  # (ramp end index, link)
    for i, link in ((0, road.predecessor), (1, road.successor)):
        if link is not None and (link.element_type == "junction" or link.element_id in main_ids):
            linked.append(i)
    for conn in network.roads:
        if conn.junction == "-1":
            continue
        for j, (here, there) in enumerate(
            ((conn.predecessor, conn.successor), (conn.successor, conn.predecessor))
        ):
            if (
                here is not None
                and there is not None
                and here.element_type == "road"
                and there.element_type == "road"
                and here.element_id in main_ids
                and there.element_id == road.id
            ):
                return _road_ends(conn)[j]  # j = 0: the connector starts on the mainline
    if len(linked) == 1:
        return ends[linked[0]]
    if not mainline:
        return ends[0]
    grid = np.vstack(
        [r.xy(np.linspace(0.0, r.length, max(2, math.ceil(r.length) + 1))) for r in mainline]
    )
    d, _ = cKDTree(grid).query(ends)
    return ends[int(np.argmin(d))]


def ramp_connectivity(network: RoadNetwork, *, traffic_side: str = "right") -> list[dict]:
    """For every ramp road: can a car reach it from a mainline driving lane (exit) or reach
    a mainline lane from it (entry) by following lane links?"""
    import networkx as nx

    graph = lane_graph(network, traffic_side=traffic_side)
    main_ids = {r.id for r in network.roads if r.name == "mainline"}
    main_driving = [
        n for n, d in graph.nodes(data=True) if n[0] in main_ids and d.get("type") == "driving"
    ]
    main_all = [n for n in graph.nodes if n[0] in main_ids]
    # one multi-source search each way instead of one search per node
    graph.add_node("_from_main")
    graph.add_edges_from(("_from_main", n) for n in main_driving)
    from_main = nx.descendants(graph, "_from_main")
    graph.add_node("_to_main")
    graph.add_edges_from((n, "_to_main") for n in main_all)
    to_main = nx.ancestors(graph, "_to_main")
    out = []
    for road in ramp_roads(network, with_connectors=False):
        nodes = [n for n in graph.nodes if isinstance(n, tuple) and n[0] == road.id]
        reach = from_main if road.name == "exit" else to_main
        out.append(
            {"road_id": road.id, "type": road.name, "connected": any(n in reach for n in nodes)}
        )
    return out


def topology_against_truth(
    network: RoadNetwork,
    truth: RoadNetwork,
    *,
    truth_info: dict | None = None,
    traffic_side: str = "right",
    config: EvaluationConfig | None = None,
) -> dict[str, Any]:
    """Ramps matched / missed / spurious, merge-exit type and lane-level connectivity.

    Ramps are matched one-to-one (Hungarian assignment) by the distance between their
    attachment points (the ramp end nearer the mainline), up to
    ``config.ramp_match_distance_m``. True ramps come from ``truth_info["ramps"]`` (the
    simulator's truth.json) when given, else from the truth network's ``exit``/``entry``
    roads.

    A built ramp left unmatched within that distance of a ramp the truth left out
    (``truth_info["ramps_left_out"]``: a ramp of the source map the simulator could not
    draw, which the run's OSM still has) is ``unjudged``, not spurious: the run holds no
    truth of it.
    """
    cfg = config or EvaluationConfig()
    true_main = mainline_roads(truth)
    built_main = mainline_roads(network)
    if truth_info and truth_info.get("ramps") is not None:
        true_list = [
            (str(r["road_id"]), str(r["type"]), r.get("station_m"))
            for r in truth_info["ramps"]
            if str(r["road_id"]) in truth.id_to_road
        ]
    else:
        true_list = [(r.id, r.name, None) for r in ramp_roads(truth, with_connectors=False)]
    built_list = [(r.id, r.name) for r in ramp_roads(network, with_connectors=False)]
    true_pts = np.array(
        [_attachment_point(truth, truth.road(i), true_main) for i, _, _ in true_list]
    ).reshape(-1, 2)
    built_pts = np.array(
        [_attachment_point(network, network.road(i), built_main) for i, _ in built_list]
    ).reshape(-1, 2)
    pairs = []
    matched_true: set[int] = set()
    matched_built: set[int] = set()
    if len(true_list) and len(built_list):
        cost = np.linalg.norm(true_pts[:, None, :] - built_pts[None, :, :], axis=2)
        rows, cols = linear_sum_assignment(cost)
        for i, j in zip(rows, cols, strict=True):
            if cost[i, j] <= cfg.ramp_match_distance_m:
                matched_true.add(int(i))
                matched_built.add(int(j))
                pairs.append(
                    {
                        "truth_road_id": true_list[i][0],
                        "built_road_id": built_list[j][0],
                        "truth_type": true_list[i][1],
                        "built_type": built_list[j][1],
                        "type_correct": true_list[i][1] == built_list[j][1],
                        "truth_station_m": true_list[i][2],
                        "attachment_distance_m": float(cost[i, j]),
                    }
                )
    unmatched = [j for j in range(len(built_list)) if j not in matched_built]
    left_out = [(r["x"], r["y"]) for r in (truth_info or {}).get("ramps_left_out") or []]
    unjudged: set[int] = set()
    if unmatched and left_out:
        d, _ = cKDTree(np.array(left_out, dtype=float)).query(built_pts[unmatched])
        unjudged = {
            j for j, dj in zip(unmatched, d, strict=True) if dj <= cfg.ramp_match_distance_m
        }
    connectivity = ramp_connectivity(network, traffic_side=traffic_side)
    conn_by_id = {c["road_id"]: c["connected"] for c in connectivity}
    for p in pairs:
        p["connected"] = conn_by_id.get(p["built_road_id"], False)
    return {
        "true_ramps": len(true_list),
        "built_ramps": len(built_list),
        "matched": len(pairs),
        "missed": [true_list[i][0] for i in range(len(true_list)) if i not in matched_true],
        "spurious": [built_list[j][0] for j in unmatched if j not in unjudged],
        "unjudged": [built_list[j][0] for j in sorted(unjudged)],
        "type_correct": sum(p["type_correct"] for p in pairs),
        "connected": sum(c["connected"] for c in connectivity),
        "all_connected": all(c["connected"] for c in connectivity),
        "pairs": pairs,
        "ramps": connectivity,
    }


# ---------------------------------------------------------------------------
# report objects
# ---------------------------------------------------------------------------
