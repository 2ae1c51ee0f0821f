"""Runs along real OSM carriageways: an OSM chain's lane-level truth driven by the car.

The glue of two parts: :func:`~roadtwin.simulate.osm_truth.truth_from_osm` turns a real
motorway or trunk chain of any extract into a lane-level truth (lane gains and drops,
weaving lanes, ramps, loops, national widths and paint, drawn metres off OSM), and
:func:`~roadtwin.simulate.network_run.simulate_network_run` drives the mapping car along
it. The run's map input is the real extract, unchanged (``roadtwin simulate --from-osm``;
generalises what the bundled ``real_a9`` scenario does for one stretch).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from .markings import MarkingStyle
from .network_run import NetworkRunSettings, simulate_network_run
from .osm_truth import OsmTruthSettings, truth_from_osm


def simulate_osm_run(
    osm_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    chain: int | str | None = None,
    seed: int = 0,
    truth_settings: OsmTruthSettings | None = None,
    settings: NetworkRunSettings | None = None,
) -> Path:
    """Simulate a mapping run along a real OSM carriageway, with its lane-level truth.

    Parameters
    ----------
    osm_path
        An OSM extract (``.osm``, ``.osm.gz``, ``.osm.bz2``, ``.osm.pbf``); it becomes the
        run's map input unchanged (© OpenStreetMap contributors, ODbL).
    out_dir
        Run folder to write (with ``truth.xodr``, ``truth.json``).
    chain
        The carriageway: an OSM way id, a ``ref`` (e.g. ``"A 70"``) or None for the
        extract's longest one-way motorway/trunk chain.
    seed
        Seed of the truth (offsets, widths, grades) and of the sensor.
    truth_settings
        :class:`~roadtwin.simulate.osm_truth.OsmTruthSettings` (realistic defaults).
    settings
        Car, noise, sensor settings; the traffic side, frame origin, marking pattern and
        OSM file always come from the truth (the chain's country).

    Returns
    -------
    Path
        ``out_dir``.
    """
    truth = truth_from_osm(osm_path, chain=chain, settings=truth_settings, seed=seed)
    paint = truth.style.markings
    base = settings or NetworkRunSettings()
    style = replace(
        base.style if isinstance(base.style, MarkingStyle) else MarkingStyle(),
        name=truth.style.country,
        dash_m=paint.dash_m,
        gap_m=paint.gap_m,
        aux_dash_m=paint.aux_dash_m,
        aux_gap_m=paint.aux_gap_m,
    )
    cfg = replace(
        base,
        traffic_side=truth.style.traffic,
        origin=truth.origin,
        osm_file=str(truth.osm_path),
        style=style,
    )
    stem = Path(osm_path).name.split(".")[0]
    name = f"{stem} chain {truth.chain_way_ids[0] if truth.chain_way_ids else chain}"
    return simulate_network_run(
        truth.network, out_dir, route=list(truth.route), settings=cfg, seed=seed, name=name
    )
