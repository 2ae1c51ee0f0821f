"""Probe of the mapping car in an inner lane on chains the lane probes never drove.

Session 13 (RESULTS, "Session 13"): twelve runs on OSM chains (and opposite carriageways)
that the lane-1 and lane-2 runs of ``bench_real.py`` do not drive, with the car next to
the median-side lane at 110 km/h (seed 31) or, with ``--car-lane 2``, in the third lane
from the median at 90 km/h (seed 32). Measured once as fresh holdouts; not part of the
benchmark. Takes the options of ``bench_real.py``::

    python benchmarks/probe_lane1_s31.py [--car-lane 2] --split all --methods default \
        --external --drive --workdir /tmp/probe-lane1-s31 [--json FILE]
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_real

_CARS = {1: ({"lane": 1, "speed_kmh": 110.0}, 31), 2: ({"lane": 2, "speed_kmh": 90.0}, 32)}

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


def probe_runs(car_lane: int = 1) -> tuple[bench_real.RealRun, ...]:
    """The probe's runs with the car in lane ``car_lane`` (1 or 2) from the median side."""
    car, seed = _CARS[car_lane]
    return tuple(
        bench_real.RealRun(
            f"{name}-lane{car_lane}-s{seed}",
            "osm",
            path,
            seed,
            chain,
            holdout=True,
            settings=car,
            direction=direction,
        )
        for name, path, chain, direction in _CHAINS
    )


RUNS = probe_runs(1)

if __name__ == "__main__":
    argv = sys.argv[1:]
    lane = 1
    if "--car-lane" in argv:
        k = argv.index("--car-lane")
        lane = int(argv[k + 1])
        del argv[k : k + 2]
    bench_real.RUNS = probe_runs(lane)
    sys.exit(bench_real.main(argv))
