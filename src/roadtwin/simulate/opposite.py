"""Runs along the other carriageway: the opposite direction of a scenario or an OSM chain.

A mapping campaign drives each direction of a highway. These runs share the frame (and,
for OSM chains, the OSM offset field) of the forward run, so a run in each direction
describes one consistent highway:

* bundled / TOML scenarios: the car drives the opposite carriageway that every scenario's
  truth already holds (road ``"201"``, ``name="other"``) through
  :func:`~roadtwin.simulate.network_run.simulate_network_run`, in the scenario's ``local``
  frame (same origin and altitude as the forward run), with the scenario's noise, sensor,
  markings and OSM file (the same ``map.osm`` as the forward run);
* OSM chains: :func:`opposite_chain` finds the carriageway running the other way beside a
  chain (same ``ref``, opposite bearing, nearest), cropped to the forward window; its
  truth is built in the forward truth's frame with the same seed and offset field.

OSM data: (c) OpenStreetMap contributors, ODbL.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .._errors import InputError
from ..fitting import arc_length
from .markings import MarkingStyle, style_from_markings
from .network_run import NetworkRunSettings, simulate_network_run
from .osm_truth import OsmTruth, OsmTruthSettings, truth_from_osm
from .osm_truth.chain import (
    CARRIAGEWAY,
    OsmRoads,
    _local_xy,
    chain_polyline,
    grow_chain,
    read_osm_roads,
    resolve_selection,
    select_chain,
)
from .osm_truth.settings import ChainSelection
from .osm_writer import write_osm
from .scenario import Scenario, load_scenario
from .truth import build_truth
from .writer import _rng, copy_osm

OPPOSITE_ROAD_ID = "201"
"""Road id of the opposite carriageway in a scenario's truth (:mod:`.truth`)."""

_NEAR_M = 120.0  # OSM centrelines of the two carriageways lie within this distance
_OPPOSITE_TURN_DEG = 135.0  # heading difference that makes a way run the other way


def simulate_opposite_run(
    scenario: Scenario | str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    seed: int | None = None,
    pass_index: int = 1,
) -> Path:
    """Simulate a run along the opposite carriageway of a scenario (the other direction).

    Parameters
    ----------
    scenario
        A :class:`Scenario`, a scenario TOML path or a bundled scenario name; its
        ``[opposite]`` carriageway must be enabled.
    out_dir
        Run folder to write. ``truth.xodr`` holds the opposite carriageway as mainline
        road ``"1"`` (the route truth), in the scenario's ``local`` frame.
    seed
        Overrides the scenario's seed (the same truth and OSM as the forward run with it).
    pass_index
        Which drive of this carriageway (1, 2, ...; see :func:`~.writer.simulate_run`).

    Returns
    -------
    Path
        ``out_dir``.
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if seed is not None:
        sc = dataclasses.replace(sc, seed=int(seed))
    if not sc.opposite.enabled:
        msg = f"scenario {sc.name}: [opposite] enabled = false, there is no other carriageway"
        raise InputError(msg)
    truth = build_truth(sc)
    # no geoReference: the run's frame is then `local` on the scenario's origin, exactly
    # the forward run's frame (the same coordinates and altitude)
    network = dataclasses.replace(
        truth.network, header=dataclasses.replace(truth.network.header, geo_reference="")
    )
    m = sc.markings
    settings = NetworkRunSettings(
        traffic_side=sc.traffic_side,
        car=sc.car,
        noise=sc.noise,
        sensor=sc.sensor,
        style=style_from_markings(m, name="scenario", base=MarkingStyle(worn_fraction=0.0)),
        origin=sc.origin,
        road_edges_format=sc.road_edges_format,
        pass_index=pass_index,
    )
    with tempfile.TemporaryDirectory(prefix="roadtwin-opposite-") as tmp:
        if sc.real_osm:
            osm_file = Path(tmp) / copy_osm(sc.real_osm, Path(tmp))
        else:
            osm_file = Path(tmp) / "map.osm"
            write_osm(truth, osm_file, _rng(sc.seed, "osm"))
        return simulate_network_run(
            network,
            out_dir,
            route=[OPPOSITE_ROAD_ID],
            settings=dataclasses.replace(settings, osm_file=str(osm_file)),
            seed=sc.seed,
            name=f"{sc.name} opposite carriageway",
        )


def _bearings(xy: np.ndarray) -> np.ndarray:
    """Heading (radians, CCW from east) of each segment of a polyline ``(N, 2)``."""
    d = np.diff(xy, axis=0)
    return np.arctan2(d[:, 1], d[:, 0])


def opposite_chain(
    roads: OsmRoads, chain: list[int], *, start_m: float = 0.0, length_m: float | None = None
) -> ChainSelection:
    """The carriageway running the other way beside ``chain``, cropped to its window.

    Parameters
    ----------
    roads
        The extract's one-way motorway/trunk ways (:func:`~.osm_truth.chain.read_osm_roads`).
    chain
        Way ids of the forward carriageway in driving order.
    start_m, length_m
        The forward window along ``chain`` (metres of its OSM polyline; ``None``: to its
        end).

    Returns
    -------
    ChainSelection
        ``way_id`` of a way of the opposite chain and the window along it that lies beside
        the forward window.

    Raises
    ------
    InputError
        No carriageway way runs the other way within ~120 m of the window.
    """
    _, ll_a, _ = chain_polyline(roads, chain)
    lat0 = float(ll_a[0, 1])
    xy_a = _local_xy(ll_a, lat0)
    s_a = arc_length(xy_a)
    end = s_a[-1] if length_m is None else min(s_a[-1], start_m + length_m)
    grid = np.arange(start_m, end, 5.0)
    win = np.column_stack([np.interp(grid, s_a, xy_a[:, 0]), np.interp(grid, s_a, xy_a[:, 1])])
    hdg_a = np.interp(grid, 0.5 * (s_a[1:] + s_a[:-1]), np.unwrap(_bearings(xy_a)))
    tree = cKDTree(win)
    used = set(chain)
    best: tuple[float, int] | None = None
    for wid in sorted(roads.ways):
        way = roads.ways[wid]
        if wid in used or way.highway not in CARRIAGEWAY or len(way.nodes) < 2:
            continue
        if roads.ways[chain[0]].refs and not (way.refs & roads.ways[chain[0]].refs):
            continue
        xy = _local_xy(way.lonlat, lat0)
        mid = 0.5 * (xy[1:] + xy[:-1])
        seg = np.hypot(*np.diff(xy, axis=0).T)
        dist, idx = tree.query(mid)
        turn = np.abs((_bearings(xy) - hdg_a[idx] + math.pi) % (2 * math.pi) - math.pi)
        near = (dist < _NEAR_M) & (turn > math.radians(_OPPOSITE_TURN_DEG))
        score = float(seg[near].sum())
        if score > 0 and (best is None or (-score, wid) < (-best[0], best[1])):
            best = (score, wid)
    if best is None:
        msg = f"{roads.source}: no carriageway runs the other way beside chain {chain[0]}"
        raise InputError(msg)
    ids = grow_chain(roads, best[1])
    _, ll_b, _ = chain_polyline(roads, ids)
    xy_b = _local_xy(ll_b, lat0)
    # stations as window_chain measures them (its own first latitude)
    own = _local_xy(ll_b, float(ll_b[0, 1]))
    s_b = arc_length(own)
    dense_s = np.arange(0.0, s_b[-1], 2.0)
    dense = np.column_stack(
        [np.interp(dense_s, s_b, xy_b[:, 0]), np.interp(dense_s, s_b, xy_b[:, 1])]
    )
    dist, idx = cKDTree(dense).query(win[[0, -1]])
    if np.any(dist > _NEAR_M):
        # the forward window reaches beyond the other carriageway: keep what lies beside it
        near = cKDTree(win).query(dense)[0] < _NEAR_M
        a, b = float(dense_s[near].min()), float(dense_s[near].max())
    else:
        a, b = sorted((float(dense_s[idx[0]]), float(dense_s[idx[1]])))
    # the window of the opposite chain runs from the forward window's end to its start
    return ChainSelection(way_id=ids[0], start_m=a, length_m=max(b - a, 1.0))


def opposite_truth(
    osm_path: str | os.PathLike,
    forward: OsmTruth,
    *,
    chain: int | str | None = None,
    settings: OsmTruthSettings | None = None,
    roads: OsmRoads | None = None,
) -> OsmTruth:
    """The truth of the carriageway running the other way beside ``forward``'s chain:
    the window beside the forward window, built with the forward truth's seed, origin and
    OSM offset field (:func:`~.osm_truth.truth_from_osm`); ``roads``: the extract already
    read (:func:`~.osm_truth.chain.read_osm_roads`)."""
    cfg = settings or OsmTruthSettings()
    sel = resolve_selection(cfg.chain, chain)
    if roads is None:
        roads = read_osm_roads(osm_path)
    ids = select_chain(roads, sel)
    _, ll, _ = chain_polyline(roads, ids)
    own = _local_xy(ll, float(ll[0, 1]))
    total = float(np.hypot(*np.diff(own, axis=0).T).sum())
    a = min(sel.start_m, max(total - sel.min_length_m, 0.0))
    length = min(sel.length_m if sel.length_m is not None else total - a, sel.max_length_m)
    other = opposite_chain(roads, ids, start_m=a, length_m=length)
    other = dataclasses.replace(
        other, max_length_m=sel.max_length_m, min_length_m=min(sel.min_length_m, other.length_m)
    )
    return truth_from_osm(
        osm_path,
        origin=forward.origin,
        settings=dataclasses.replace(cfg, chain=other),
        seed=forward.seed,
        offset_centre_xy=forward.offset_centre_xy,
        roads=roads,
    )
