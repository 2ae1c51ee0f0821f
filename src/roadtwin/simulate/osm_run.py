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
from typing import Literal

from .._errors import InputError
from .markings import style_from_markings
from .network_run import NetworkRunSettings, simulate_network_run
from .osm_truth import OsmTruthSettings, truth_from_osm
from .osm_truth.chain import read_osm_roads


def simulate_osm_run(
    osm_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    chain: int | str | None = None,
    seed: int = 0,
    truth_settings: OsmTruthSettings | None = None,
    settings: NetworkRunSettings | None = None,
    direction: Literal["forward", "opposite"] = "forward",
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
        Car, noise, sensor settings (``pass_index`` for another drive of the same truth);
        the traffic side, frame origin, marking pattern and OSM file always come from the
        truth (the chain's country).
    direction
        ``"forward"``: the chain itself; ``"opposite"``: the carriageway running the other
        way beside it (:func:`~roadtwin.simulate.opposite.opposite_chain`), its truth in
        the forward truth's frame with the same seed and OSM offset field, so a run in
        each direction describes one highway.

    Returns
    -------
    Path
        ``out_dir``.
    """
    if direction not in ("forward", "opposite"):
        msg = f"direction {direction!r}: expected 'forward' or 'opposite'"
        raise InputError(msg)
    roads = read_osm_roads(osm_path)  # once for both directions' truths
    truth = truth_from_osm(osm_path, chain=chain, settings=truth_settings, seed=seed, roads=roads)
    if direction == "opposite":
        from .opposite import opposite_truth

        truth = opposite_truth(osm_path, truth, chain=chain, settings=truth_settings, roads=roads)
    base = settings or NetworkRunSettings()
    style = style_from_markings(truth.style.markings, name=truth.style.country, base=base.style)
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
        truth.network,
        out_dir,
        route=list(truth.route),
        settings=cfg,
        seed=seed,
        name=name,
        left_out=truth.skipped,
    )
