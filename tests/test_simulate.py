"""Tests of the simulator: noise levels against the truth, paint, ego frames, OSM ramps,
determinism, bundled scenarios and the CLI."""

from __future__ import annotations

import dataclasses
import itertools
import json
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from roadtwin._errors import InputError
from roadtwin.simulate import bundled_scenarios, load_scenario, simulate_run
from roadtwin.simulate.scenario import Noise, scenario_from_dict

pd = pytest.importorskip("pandas")


def _quiet_pose(scenario):
    """The scenario with a perfect GNSS/INS (so point errors are the sensor's alone)."""
    return dataclasses.replace(
        scenario,
        noise=Noise(position_std_m=0.0, height_std_m=0.0, yaw_std_deg=0.0, jitter_m=0.0),
    )


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    return simulate_run("straight_curve_2km", tmp_path_factory.mktemp("sim") / "run")


@pytest.fixture(scope="module")
def truth(run_dir):
    from roadtwin.xodr import read_xodr

    return read_xodr(run_dir / "truth.xodr"), json.loads((run_dir / "truth.json").read_text())


def _dense_borders(network, *, markings: bool, step: float = 0.05):
    """Dense points on true lane borders of mainline and ramp roads, read back from the
    written truth.xodr: markings (outer border of every lane but the outermost) or road
    edges (reference line and outer border of the outermost lane). Returns points,
    unit normals, road mark type/width and road station of each point."""
    pts, normals, kinds, widths, stations, roads = [], [], [], [], [], []
    for road in network.roads:
        if road.name not in ("mainline", "exit", "entry"):
            continue
        bounds = [ls.s0 for ls in road.lane_sections] + [road.length]
        for k, ls in enumerate(road.lane_sections):
            s = np.arange(bounds[k], bounds[k + 1], step)
            lanes = ls.right or ls.left
            h = road.heading(s)
            n = np.column_stack([-np.sin(h), np.cos(h)])
            if markings:
                chosen = [(lane.id, lane.road_marks[0]) for lane in lanes[:-1]]
            else:
                chosen = [(0, None), (lanes[-1].id, None)]
            for lane_id, mark in chosen:
                t = road.lane_border_t(s, lane_id)
                pts.append(road.to_xy(s, t))
                normals.append(n)
                kinds.append(np.full(s.size, mark.type if mark else "edge"))
                widths.append(np.full(s.size, mark.width_m if mark else 0.0))
                stations.append(s)
                roads.append(np.full(s.size, road.id))
    cat = np.concatenate
    return (
        np.vstack(pts), np.vstack(normals), cat(kinds), cat(widths), cat(stations), cat(roads),
    )  # fmt: skip


def _read_edges(path: Path) -> tuple[np.ndarray, np.ndarray]:
    import laspy

    las = laspy.read(path)
    return np.column_stack([las.x, las.y, las.z]), np.asarray(las.side)


def test_truth_network_is_valid_and_links_ramps(truth):
    from roadtwin.check import check_network

    network, info = truth
    errors = [f for f in check_network(network) if f.severity == "error"]
    assert errors == []
    names = sorted(r.name for r in network.roads)
    assert names.count("mainline") == 3
    assert names.count("exit") == 1
    assert names.count("entry") == 1
    assert [r["type"] for r in info["ramps"]] == ["exit", "entry"]
    # the exit ramp starts exactly on the outer border of the last driving lane at its gore
    exit_info = info["ramps"][0]
    before = network.road(exit_info["mainline_road_before"])
    ramp = network.road(exit_info["road_id"])
    t_edge = before.lane_border_t([before.length], -4)  # inner shoulder + 3 driving lanes
    gore = before.to_xy([before.length], t_edge)[0]
    assert np.hypot(*(ramp.xy([0.0])[0] - gore)) < 1e-6
    assert abs(before.lane_border_t([before.length], -4)[0] + (0.75 + 3 * 3.75)) < 1e-9
    # junction lane links: deceleration lane -> ramp driving lane
    junction = network.id_to_junction[exit_info["junction_id"]]
    to_ramp = next(c for c in junction.connections if c.connecting_road == ramp.id)
    assert (exit_info["aux_lane_ids"][0], -2) in {
        (ll.from_lane, ll.to_lane) for ll in to_ramp.lane_links
    }
    # deceleration lane tapers from zero width
    first = before.lane_sections[1]
    assert first.lane(-5).width.value(0.0) == pytest.approx(0.0, abs=1e-12)
    assert first.lane(-5).width.value(60.0) == pytest.approx(3.5, abs=1e-9)


def test_edge_points_have_the_configured_noise(tmp_path):
    from roadtwin.xodr import read_xodr

    sc = _quiet_pose(load_scenario("straight_curve_2km"))
    out = simulate_run(sc, tmp_path / "run")
    xyz, side = _read_edges(out / "road_edges.laz")
    network = read_xodr(out / "truth.xodr")
    pts, normals, *_ = _dense_borders(network, markings=False)
    _, idx = cKDTree(pts).query(xyz[:, :2])
    residual = np.einsum("ij,ij->i", xyz[:, :2] - pts[idx], normals[idx])
    inliers = np.abs(residual) < 0.25  # outliers are 0.3..3 m outside the edge
    assert inliers.mean() > 0.98
    assert np.std(residual[inliers]) == pytest.approx(sc.sensor.edge_noise_m, rel=0.10)
    assert abs(np.mean(residual[inliers])) < 0.005
    assert set(np.unique(side)) == {1, 2}
    # dropouts and truck occlusions: fewer points than the dense truth would give
    counts = json.loads((out / "truth.json").read_text())["counts"]["edges"]
    assert counts["dropouts"] > 0
    assert counts["outliers"] == pytest.approx(0.01 * xyz.shape[0], rel=0.3)


def test_lane_samples_lie_on_paint_with_true_poses(run_dir, truth):
    network, info = truth
    samples = pd.read_csv(run_dir / "lane_samples.csv")
    poses = {
        n: pd.read_csv(run_dir / n).set_index("frame")
        for n in ("truth_trajectory.csv", "trajectory.csv")
    }
    pts, _normals, kinds, widths, stations, roads = _dense_borders(network, markings=True)
    tree = cKDTree(pts)
    rms = {}
    for name, pose in poses.items():
        p = pose.loc[samples["frame"]]
        c, s = np.cos(p["yaw"].to_numpy()), np.sin(p["yaw"].to_numpy())
        x = p["x"].to_numpy() + c * samples["x"].to_numpy() - s * samples["y"].to_numpy()
        y = p["y"].to_numpy() + s * samples["x"].to_numpy() + c * samples["y"].to_numpy()
        dist, idx = tree.query(np.column_stack([x, y]))
        rms[name] = (dist, idx)
    dist, idx = rms["truth_trajectory.csv"]
    fp = json.loads((run_dir / "truth.json").read_text())["counts"]["lanes"]["false_positives"]
    near = dist < 0.15
    # everything but the false positives lands on a true marking, at the sensor noise
    assert (~near).sum() <= fp + 0.001 * dist.size
    assert np.sqrt(np.mean(dist[near] ** 2)) == pytest.approx(0.03, rel=0.15)
    # with the recorded (noisy) poses they are farther off: the pose error is inherited
    dist_m, _ = rms["trajectory.csv"]
    assert np.sqrt(np.mean(dist_m[near] ** 2)) > np.sqrt(np.mean(dist[near] ** 2))
    # paint only: on broken lines every sample is inside a dash (6 m of 18, or 6 of 12)
    starts = {r["road_id"]: r["station_m"] for r in info["mainline_roads"]}
    on_main = np.isin(roads[idx], list(starts))
    broken = near & on_main & (kinds[idx] == "broken")
    global_s = stations[idx] + np.array([starts.get(r, 0.0) for r in roads[idx]])
    period = np.where(widths[idx] > 0.2, 12.0, 18.0)
    phase = np.mod(global_s, period)
    inside = (phase < 6.0 + 0.1) | (phase > period - 0.1)
    assert broken.sum() > 1000
    assert inside[broken].mean() > 0.998
    # and solid lines are seen along their whole length (no gaps longer than a frame step)
    solid = near & on_main & (kinds[idx] == "solid") & (roads[idx] == "3")
    sol_s = np.sort(global_s[solid])
    assert sol_s.size > 500
    assert np.diff(sol_s).max() < 5.0


def test_exit_start_is_seen_up_to_sensor_range(run_dir, truth):
    network, info = truth
    xyz, side = _read_edges(run_dir / "road_edges.laz")
    ramp = network.road(info["ramps"][0]["road_id"])
    s, t = ramp.project(xyz[side == 2])
    outer = ramp.lane_border_t(s, -len(ramp.lane_sections[-1].right))
    on_ramp = (np.abs(t - outer) < 0.2) & (s > 5.0) & (s < ramp.length - 1)
    assert on_ramp.sum() > 100  # the diverging edge after the gore was seen
    traj = pd.read_csv(run_dir / "truth_trajectory.csv")[["x", "y"]].to_numpy()
    far, _ = cKDTree(traj).query(ramp.to_xy(s[on_ramp], t[on_ramp]))
    assert far.max() <= 25.0 + 0.5  # ... but only as far as the sensor reaches


def test_osm_has_ramps_with_the_right_directions(run_dir, truth):
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm

    _, info = truth
    run = load_run(run_dir)
    graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    hw = {}
    for u, v, d in graph.edges(data=True):
        hw.setdefault(u, set()).add(d["highway"])
        hw.setdefault(v, set()).add(d["highway"])
    links = [(u, v, d) for u, v, d in graph.edges(data=True) if d["highway"] == "motorway_link"]
    assert len(links) == 4  # ours and the opposite carriageway's
    for ramp in info["ramps"]:
        (way_id,) = ramp["osm_way_ids"]
        (u, v, d) = next(e for e in links if e[2]["osmid"] == way_id)
        assert d["oneway"] in (True, "yes")
        if ramp["type"] == "exit":
            assert "motorway" in hw[u]
            assert "motorway" not in hw[v]
        else:
            assert "motorway" in hw[v]
            assert "motorway" not in hw[u]
        # the link way's far end lies near the true ramp's far end (metres of mapper noise)
        far = np.asarray(d["geometry"].coords)[-1 if ramp["type"] == "exit" else 0]
        road = truth[0].road(ramp["road_id"])
        true_end = road.xy([road.length if ramp["type"] == "exit" else 0.0])[0]
        assert np.hypot(*(far - true_end)) < 10.0
    classes = {d["highway"] for _, _, d in graph.edges(data=True)}
    assert {"motorway", "motorway_link", "primary", "residential"} <= classes


def test_same_seed_same_bytes_other_seed_differs(tmp_path):
    sc = load_scenario("straight_curve_2km")
    a = simulate_run(sc, tmp_path / "a")
    b = simulate_run(sc, tmp_path / "b")
    c = simulate_run(sc, tmp_path / "c", seed=99)
    files = sorted(p.name for p in a.iterdir())
    assert files == sorted(p.name for p in b.iterdir())
    for name in files:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert (a / "trajectory.csv").read_bytes() != (c / "trajectory.csv").read_bytes()
    assert (a / "truth.xodr").read_bytes() == (c / "truth.xodr").read_bytes()


@pytest.mark.parametrize("name", ["interchange_5km", "left_hand_2km", "long_20km", "real_a9"])
def test_bundled_scenarios_simulate_in_seconds(name, tmp_path):
    from roadtwin.check import check_network
    from roadtwin.io import load_run
    from roadtwin.xodr import read_xodr

    start = time.perf_counter()
    out = simulate_run(name, tmp_path / name)
    elapsed = time.perf_counter() - start
    assert elapsed < (15.0 if name == "long_20km" else 8.0)
    run = load_run(out)
    sc = load_scenario(name)
    assert run.traffic_side == sc.traffic_side
    assert run.trajectory.length_m == pytest.approx(sc.length_m, rel=0.02)
    network = read_xodr(out / "truth.xodr")
    assert [f for f in check_network(network) if f.severity == "error"] == []
    info = json.loads((out / "truth.json").read_text())
    assert len(info["ramps"]) == len(sc.ramps)
    if sc.traffic_side == "left":  # lanes on the left, positive ids
        assert all(
            ls.right == () and ls.left
            for r in network.roads
            if r.name == "mainline"
            for ls in r.lane_sections
        )


def test_every_bundled_scenario_is_tested():
    tested = {"straight_curve_2km", "interchange_5km", "left_hand_2km", "long_20km", "real_a9"}
    assert set(bundled_scenarios()) == tested


def _densify(xy: np.ndarray) -> np.ndarray:
    """Points every ~0.5 m along a polyline (OSM ways have sparse nodes)."""
    return np.vstack([np.linspace(a, b, 200) for a, b in itertools.pairwise(xy)])


def test_real_a9_follows_the_real_osm_ways(tmp_path):
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm
    from roadtwin.xodr import read_xodr

    out = simulate_run("real_a9", tmp_path / "a9")
    assert (out / "map.osm.gz").is_file()
    run = load_run(out)
    graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    network = read_xodr(out / "truth.xodr")
    info = json.loads((out / "truth.json").read_text())
    assert [r["type"] for r in info["ramps"]] == ["exit", "entry"]
    motorway = [d["geometry"] for _, _, d in graph.edges(data=True) if d["highway"] == "motorway"]
    for ramp in info["ramps"]:
        edges = [
            (u, v, d)
            for u, v, d in graph.edges(data=True)
            if d["highway"] == "motorway_link" and d["osmid"] in ramp["osm_way_ids"]
        ]
        assert edges, ramp
        road = network.road(ramp["road_id"])
        # the true ramp's centre stays within a few metres of the real link way
        lanes = road.lane_sections[-1].right
        s = (
            np.linspace(30.0, road.length - 5.0, 50)
            if ramp["type"] == "exit"
            else np.linspace(5.0, road.length - 30.0, 50)
        )
        t = 0.5 * (road.lane_border_t(s, lanes[0].id) + road.lane_border_t(s, lanes[-2].id))
        centre = road.to_xy(s, t)
        link = np.vstack([np.asarray(d["geometry"].coords) for _, _, d in edges])
        dense = _densify(link)
        dist, _ = cKDTree(dense).query(centre)
        assert np.median(dist) < 4.0
    # and the mainline's carriageway centre stays within ~2 m of the real motorway way
    main = [r for r in network.roads if r.name == "mainline"]
    pts = np.vstack(
        [
            r.to_xy(np.arange(0, r.length, 10.0), np.full(int(np.ceil(r.length / 10)), -4.5))
            for r in main
        ]
    )
    dense = np.vstack([_densify(np.asarray(g.coords)) for g in motorway])
    dist, _ = cKDTree(dense).query(pts)
    assert np.median(dist) < 2.0


def test_interchange_has_lane_drop_and_two_lane_exit():
    from roadtwin.simulate.truth import build_truth

    truth = build_truth(load_scenario("interchange_5km"))
    last = [r for r in truth.network.roads if r.name == "mainline"][-1]
    counts = [sum(lane.type == "driving" for lane in ls.right) for ls in last.lane_sections]
    assert counts[-1] == 2
    assert max(counts) >= 3
    two = next(rt for rt in truth.ramps if rt.ramp.lanes == 2)
    assert sum(lane.type == "driving" for lane in two.road.lane_sections[0].right) == 2


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"ramps": [{"type": "exit", "station": 650, "side": "left"}]}, "outer"),
        (
            {"ramps": [{"type": "exit", "station": 650}, {"type": "entry", "station": 700}]},
            "overlaps",
        ),
        ({"lanes": {"count": 3, "widht": 3.5}}, "widht"),
        ({"alignment": [{"type": "spiral", "length": 100}]}, "straight, arc or clothoid"),
        ({"car": {"lane": 5}}, "[car] lane"),
    ],
)
def test_bad_scenarios_raise_clear_input_errors(patch, message):
    base = {"alignment": [{"type": "straight", "length": 2000}]}
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        scenario_from_dict(base | patch)


def test_cli_simulate_and_unknown_scenario(tmp_path, capsys):
    from roadtwin.cli import main

    assert main(["simulate", "straight_curve_2km", "-o", str(tmp_path / "run")]) == 0
    assert (tmp_path / "run" / "run.toml").is_file()
    assert "exit at 650 m" in capsys.readouterr().out
    assert main(["simulate", "no_such_scenario", "-o", str(tmp_path / "x")]) == 2
    assert "bundled" in capsys.readouterr().err


@pytest.mark.parametrize("fmt", ["laz", "las", "csv", "ply", "npy", "parquet"])
def test_every_road_edge_format_loads_with_the_run_loader(fmt, tmp_path):
    from roadtwin.io import load_run

    doc = {
        "seed": 3,
        "alignment": [
            {"type": "straight", "length": 300},
            {"type": "arc", "radius": 600, "length": 200, "direction": "right"},
        ],
        "opposite": {"enabled": False},
        "output": {"road_edges_format": fmt},
    }
    out = simulate_run(scenario_from_dict(doc, name=f"fmt_{fmt}"), tmp_path / fmt)
    run = load_run(out)
    counts = json.loads((out / "truth.json").read_text())["counts"]
    assert run.edges.shape == (counts["edge_points"], 3)
    assert run.dropped_edge_points == 0
    # left edge (median side, t = 0) and right edge (3 lanes + shoulders = 14.5 m away)
    left, right = run.edges[run.edge_side == 1], run.edges[run.edge_side == -1]
    assert left.shape[0] > 1000
    assert right.shape[0] > 1000
    traj = run.trajectory.xy
    d_left = cKDTree(traj).query(left[:, :2])[0]
    d_right = cKDTree(traj).query(right[:, :2])[0]
    # car in lane 3 (centre 0.75 + 2.5 * 3.75 = 10.125 m from the left edge)
    assert np.median(d_left) == pytest.approx(10.125, abs=0.1)
    assert np.median(d_right) == pytest.approx(0.75 + 3 * 3.75 + 2.5 - 10.125, abs=0.1)
