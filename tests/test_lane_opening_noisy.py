"""A lane opening on the outer side seen by a noisier sensor (melbourne-18, seed 91).

The Melbourne chain 18 (``tests/data/osm/melbourne-lht.osm.pbf``, left-hand traffic)
gains a third lane from s = 17 m, opening over 100 m: the hard shoulder's solid line moves
out by a lane width while the new lane's inner (broken) line keeps the old offset. With
the noisier sensor (``noisy_settings``) that broken line is first seen at 61 m, and the
same solid line is the edge line further on, where the truth has no hard shoulder. The
build had dropped the solid line all along and let the lane beside it take the opening
lane and the shoulder: a driving lane 7.2 m wide, lane RMSE 1.08 m, a route that
ended nowhere. Now the solid line is the shoulder's line where a shoulder lies beyond it
(``sections.shoulder_line_in``) and the late broken line begins where the solid one left
its offset (``tapers._lines_from_splits``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from roadtwin.evaluation import evaluate_paths
from roadtwin.io import load_run
from roadtwin.osm import load_osm
from roadtwin.pipeline import build_map
from roadtwin.simulate import noisy_settings
from roadtwin.simulate.osm_run import simulate_osm_run
from roadtwin.xodr import write_xodr

MELBOURNE = Path(__file__).parent / "data" / "osm" / "melbourne-lht.osm.pbf"


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("m18")
    run_dir = simulate_osm_run(
        MELBOURNE, root / "run", chain=18, seed=91, settings=noisy_settings()
    )
    run = load_run(run_dir)
    osm = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    result = build_map(run, osm)
    path = root / "map.xodr"
    write_xodr(result.network, path)
    return run_dir, path, result.network


def test_no_lane_takes_the_opening_lane_and_the_shoulder(built):
    _, _, network = built
    widest = 0.0
    for road in network.roads:
        for k, sec in enumerate(road.lane_sections):
            hi = road.lane_sections[k + 1].s0 if k + 1 < len(road.lane_sections) else road.length
            ds = np.linspace(0.0, hi - sec.s0, 50)
            for lane in sec.lanes:
                if lane.type == "driving":
                    widest = max(widest, float(np.max(lane.width.value(ds))))
    assert widest < 6.0  # 7.2 m before


def test_lane_boundaries_follow_the_opening(built):
    run_dir, path, _ = built
    rep = evaluate_paths(path, [run_dir]).runs[0]
    err = rep.details["truth/lane_boundary"].error_m
    assert float(np.sqrt(np.mean(err**2))) < 0.6  # 1.08 m before
