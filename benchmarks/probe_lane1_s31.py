"""Probe of the mapping car in an inner lane on chains the lane probes never drove.

Session 13 (RESULTS, "Session 13"): twelve runs with the car next to the median-side lane
at 110 km/h, seed 31, on OSM chains (and opposite carriageways) that the lane-1 and lane-2
runs of ``bench_real.py`` do not drive. Measured once as a fresh holdout; not part of the
benchmark. Takes the same options as ``bench_real.py``::

    python benchmarks/probe_lane1_s31.py --split all --methods default --external --drive \\
        --workdir /tmp/probe-lane1-s31 [--json FILE]
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_real

_CAR = {"lane": 1, "speed_kmh": 110.0}

_CHAINS = (  # name, extract, chain, direction
    ("a9-10959882", "north-bayreuth-a9.osm.gz", 10959882, "forward"),
    ("a9-8081560", "north-bayreuth-a9.osm.gz", 8081560, "forward"),
    ("a9-206615404-opp", "north-bayreuth-a9.osm.gz", 206615404, "opposite"),
    ("oakland-11197879", "west-oakland-i880.osm.bz2", 11197879, "forward"),
    ("oakland-11197879-opp", "west-oakland-i880.osm.bz2", 11197879, "opposite"),
    ("kotka-33042885", "kotka-e18.osm.pbf", 33042885, "forward"),
    ("krems-46762523", "krems-s5-trunk.osm.gz", 46762523, "forward"),
    ("krems-24980555", "krems-s5-trunk.osm.gz", 24980555, "forward"),
    ("krems-24746399", "krems-s5-trunk.osm.gz", 24746399, "forward"),
    ("melbourne-921", "melbourne-lht.osm.pbf", 921, "forward"),
    ("melbourne-14", "melbourne-lht.osm.pbf", 14, "forward"),
    ("melbourne-18", "melbourne-lht.osm.pbf", 18, "forward"),
)

RUNS = tuple(
    bench_real.RealRun(
        f"{name}-lane1-s31",
        "osm",
        path,
        31,
        chain,
        holdout=True,
        settings=_CAR,
        direction=direction,
    )
    for name, path, chain, direction in _CHAINS
)

if __name__ == "__main__":
    bench_real.RUNS = RUNS
    sys.exit(bench_real.main(sys.argv[1:]))
