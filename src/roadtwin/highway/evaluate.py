"""Accuracy of a whole-highway map, carriageway by carriageway.

The metrics of :mod:`roadtwin.evaluation` compare a map's mainline with one true
mainline. A highway map holds several carriageways (``roadtwin:carriageway`` on every
road), each with its own truth (the run that drove it, or, for a carriageway built from
OSM, the truth of the other direction): :func:`carriageway_network` cuts one carriageway
out of the map, and :func:`evaluate_carriageway` measures it against its truth.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from ..config import EvaluationConfig
from ..evaluation import evaluate
from ..model import RoadNetwork
from .merge import carriageway_of

__all__ = [
    "carriageway_network",
    "carriageway_numbers",
    "carriageways_of_truth",
    "evaluate_carriageway",
]


def carriageway_numbers(network: RoadNetwork) -> list[int]:
    """The carriageway numbers of a highway map (sorted)."""
    return sorted({n for r in network.roads if (n := carriageway_of(r)) is not None})


def carriageway_network(
    network: RoadNetwork, number: int, *, with_beyond: bool = False
) -> RoadNetwork:
    """The roads and junctions of one carriageway of a highway map.

    Roads beyond the ramps (roads not named ``mainline``, ``exit``, ``entry`` or
    ``connector``) are left out unless ``with_beyond``; links to roads that are not kept
    are dropped so the part stands alone.
    """
    roles = ("mainline", "exit", "entry", "connector")
    keep = {
        r.id
        for r in network.roads
        if carriageway_of(r) == number and (with_beyond or r.name in roles)
    }
    roads = []
    for r in network.roads:
        if r.id not in keep:
            continue
        pred = r.predecessor
        succ = r.successor
        if pred is not None and pred.element_type == "road" and pred.element_id not in keep:
            pred = None
        if succ is not None and succ.element_type == "road" and succ.element_id not in keep:
            succ = None
        roads.append(replace(r, predecessor=pred, successor=succ))
    junctions = tuple(
        j
        for j in network.junctions
        if all(c.incoming_road in keep and c.connecting_road in keep for c in j.connections)
    )
    return RoadNetwork(network.header, tuple(roads), junctions)


def evaluate_carriageway(
    network: RoadNetwork,
    number: int,
    run: Any,
    truth: RoadNetwork,
    *,
    truth_info: dict | None = None,
    config: EvaluationConfig | None = None,
) -> dict[str, Any]:
    """One carriageway of a highway map against its truth.

    Parameters
    ----------
    network
        The highway map.
    number
        The carriageway (``roadtwin:carriageway``).
    run
        A run of that carriageway (for self-consistency; any run in the map's frame).
    truth
        The true network of that carriageway (mainline roads named ``mainline``).
    truth_info
        The truth's ``truth.json`` (true ramps), optional.

    Returns
    -------
    dict
        ``truth`` (edge, lane boundary, elevation, ramp errors, lane count, as
        :func:`roadtwin.evaluation.evaluate`), ``topology`` (ramps matched, missed,
        spurious, connected) and ``self_consistency``.
    """
    part = carriageway_network(network, number)
    report = evaluate(part, run, truth=truth, truth_info=truth_info, config=config).runs[0]
    return {
        "truth": report.truth,
        "topology": report.topology,
        "self_consistency": report.self_consistency,
    }


def carriageways_of_truth(network: RoadNetwork, truth: RoadNetwork) -> RoadNetwork:
    """The part of a highway map whose carriageways the truth holds: those whose mainline
    runs along the truth's mainline (at least 30 % of it within 10 m of a true lane centre,
    heading the same way). A map without carriageway tags, or of one carriageway, is
    returned as it is; so is a map none of whose carriageways the truth holds."""
    import numpy as np
    from scipy.spatial import cKDTree

    from .compare import lane_centres

    numbers = carriageway_numbers(network)
    if len(numbers) < 2:
        return network
    true = lane_centres(truth, keep=lambda r: r.name == "mainline", step_m=5.0)
    if true.xy.shape[0] == 0:
        return network
    tree = cKDTree(true.xy)
    keep = []
    for n in numbers:
        built = lane_centres(
            network,
            keep=lambda r, n=n: r.name == "mainline" and carriageway_of(r) == n,
            step_m=10.0,
        )
        if built.xy.shape[0] == 0:
            continue
        d, i = tree.query(built.xy, distance_upper_bound=10.0)
        ok = np.isfinite(d)
        turn = np.abs((built.heading[ok] - true.heading[i[ok]] + np.pi) % (2 * np.pi) - np.pi)
        if np.count_nonzero(turn < np.pi / 4) >= 0.3 * built.xy.shape[0]:
            keep.append(n)
    if not keep:
        return network
    parts = [carriageway_network(network, n, with_beyond=True) for n in keep]
    roads = tuple(r for part in parts for r in part.roads)
    junctions = tuple(j for part in parts for j in part.junctions)
    return RoadNetwork(network.header, roads, junctions)
