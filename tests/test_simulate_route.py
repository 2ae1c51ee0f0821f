"""Runs along a route through real OpenDRIVE maps (``roadtwin simulate --xodr``).

The maps are other tools' files (tests/data/xodr): esmini's soderleden (a direct-junction
entry, paramPoly3) and e6mini (one road, lanes both ways, paramPoly3 + elevation), and a
crop of CARLA's Town06 (default junctions whose lanes are separate connecting roads, left
exits, a right entry, roads driven against s).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from roadtwin._errors import InputError
from roadtwin.frames import MappingFrame, Origin
from roadtwin.io import load_run
from roadtwin.model import RoadNetwork
from roadtwin.simulate import NetworkRunSettings, simulate_network_run, simulate_xodr_run
from roadtwin.simulate.canonical import max_border_error_m
from roadtwin.simulate.markings import PAINTED, marking_style
from roadtwin.simulate.route import find_through_route, route_from_ids
from roadtwin.simulate.route_truth import build_route_truth
from roadtwin.simulate.scenario import Car, Noise, Sensor
from roadtwin.xodr import read_xodr

DATA = Path(__file__).parent / "data" / "xodr"
SODERLEDEN = DATA / "soderleden.xodr"
E6MINI = DATA / "e6mini.xodr"
TOWN06 = DATA / "town06-35-38.xodr.gz"
SHARED_TOWN06 = Path("/work/shared/data/xodr/Town06.xodr")

NOISE_FREE = NetworkRunSettings(
    noise=Noise(position_std_m=0.0, height_std_m=0.0, yaw_std_deg=0.0, jitter_m=0.0),
    sensor=Sensor(
        edge_noise_m=0.0,
        edge_height_noise_m=0.0,
        edge_dropout=0.0,
        trucks_per_km=0.0,
        outlier_fraction=0.0,
        lane_noise_m=0.0,
        lane_miss=0.0,
        lane_false_positive=0.0,
    ),
    style=marking_style("us", worn_fraction=0.0),
)


@pytest.fixture(scope="module")
def town06_truth():
    return _truth(TOWN06, ["35", "36", "37", "38"])


def _truth(path: Path, ids=None, side="right"):
    network = read_xodr(path)
    route = (
        route_from_ids(network, ids, traffic_side=side)
        if ids
        else find_through_route(network, traffic_side=side)
    )
    truth = build_route_truth(
        network, route, frame=MappingFrame(Origin(0.0, 0.0)), traffic_side=side
    )
    return network, truth


class _Polylines:
    """Distance from points to a set of polylines (exact point-to-segment distance)."""

    def __init__(self, lines: list[np.ndarray]) -> None:
        lines = [ln for ln in lines if len(ln) >= 2]
        self.xy = np.vstack(lines)
        ends = np.cumsum([len(ln) for ln in lines])
        self.valid = np.ones(len(self.xy) - 1, bool)  # segment i joins vertex i and i + 1
        self.valid[ends[:-1] - 1] = False
        self.tree = cKDTree(self.xy)

    def distance(self, pts: np.ndarray) -> np.ndarray:
        _, i = self.tree.query(pts[:, :2])
        best = np.full(len(pts), np.inf)
        for seg in (i - 1, i):
            ok = (seg >= 0) & (seg < len(self.valid))
            seg = np.clip(seg, 0, len(self.valid) - 1)
            ok &= self.valid[seg]
            a, b = self.xy[seg], self.xy[seg + 1]
            ab = b - a
            f = np.clip(
                np.einsum("ij,ij->i", pts[:, :2] - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1
            )
            d = np.hypot(*(pts[:, :2] - (a + f[:, None] * ab)).T)
            best = np.where(ok, np.minimum(best, d), best)
        return best


def _edge_polylines(truth: RoadNetwork, step_m: float = 0.05) -> _Polylines:
    """Both edges of every true road (mapping frame)."""
    from roadtwin.evaluation.mainline_truth import lane_borders

    pts = []
    for road in truth.roads:
        s = np.arange(0.0, road.length, step_m)
        ref_t, out_t, _, _ = lane_borders(road, s)
        pts += [road.to_xy(s, ref_t), road.to_xy(s, out_t)]
    return _Polylines(pts)


def _painted_polylines(truth: RoadNetwork, step_m: float = 0.05) -> _Polylines:
    """Every painted line of the true roads (both lines of double ones)."""
    pts = []
    for road in truth.roads:
        for k, sec in enumerate(road.lane_sections):
            s1 = road.lane_sections[k + 1].s0 if k + 1 < len(road.lane_sections) else road.length
            for border, marks in [(0, sec.center.road_marks)] + [
                (ln.id, ln.road_marks) for ln in (sec.right or sec.left)
            ]:
                for i, m in enumerate(marks):
                    if m.type not in PAINTED:
                        continue
                    a = sec.s0 + m.s_offset
                    b = sec.s0 + marks[i + 1].s_offset if i + 1 < len(marks) else s1
                    s = np.arange(a, b, step_m)
                    half = 0.5 * (max(m.width_m, 0.1) + 0.12)
                    for dt in (0.0,) if len(PAINTED[m.type]) == 1 else (half, -half):
                        pts.append(road.to_xy(s, road.lane_border_t(s, border) + dt))
    return _Polylines(pts)


def _rmse(d: np.ndarray) -> float:
    return float(np.sqrt(np.mean(d * d)))


# ---------------------------------------------------------------------------
# routes
# ---------------------------------------------------------------------------


def test_routes_follow_the_links_in_either_direction():
    network = read_xodr(TOWN06)
    # road 8 is entered at its start, road 2 at its end (driven against s), then 45
    route = route_from_ids(network, ["8", "2", "45"])
    assert [(t.road_id, t.direction) for t in route.traversals] == [("8", 1), ("2", -1), ("45", -1)]
    # the mainline passes three default junctions, each through its connecting road(s)
    route = route_from_ids(network, ["35", "36", "37", "38"])
    assert [p.junction_id for p in route.passages] == ["565", "1146", "1034"]
    assert [p.connectors[0].road_id for p in route.passages] == ["575", "1149", "1037"]
    # naming the connecting road instead of leaving it out gives the same route
    assert route_from_ids(network, ["35", "575", "36", "37", "38"]) == route
    with pytest.raises(InputError, match="road 35 does not continue into road 38"):
        route_from_ids(network, ["35", "38"])
    with pytest.raises(InputError, match="'999' is not in the map"):
        route_from_ids(network, ["35", "999"])


def test_automatic_routes_are_the_main_carriageways():
    assert [
        (t.road_id, t.direction) for t in find_through_route(read_xodr(SODERLEDEN)).traversals
    ] == [("2", 1), ("0", 1)]  # not the ramp 1 -> 5
    assert [(t.road_id, t.direction) for t in find_through_route(read_xodr(E6MINI)).traversals] == [
        ("0", 1)
    ]
    assert find_through_route(read_xodr(TOWN06)).road_ids == ("35", "36", "37", "38")


@pytest.mark.skipif(not SHARED_TOWN06.is_file(), reason="full Town06.xodr not available")
def test_automatic_route_through_the_whole_town06():
    network = read_xodr(SHARED_TOWN06)
    route = find_through_route(network)
    assert route == find_through_route(network)  # deterministic
    from roadtwin.simulate.route import route_length_m

    assert route_length_m(network, route) > 2000.0
    assert route.traversals[0] == route_from_ids(network, ["4", "47"]).traversals[0]  # not a ramp
    assert {t.direction for t in route.traversals} == {1, -1}


# ---------------------------------------------------------------------------
# canonical truth against the source map
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "ids"),
    [
        (SODERLEDEN, None),
        (E6MINI, None),
        (TOWN06, ["35", "36", "37", "38"]),
        (TOWN06, ["8", "2", "45"]),  # one road driven along s, two against it
    ],
)
def test_canonical_truth_is_the_map_within_a_millimetre(path, ids, request):
    if ids == ["35", "36", "37", "38"]:
        network, truth = request.getfixturevalue("town06_truth")
    else:
        network, truth = _truth(path, ids)
    # the source borders sampled afresh at another step than the fit used
    for fit in [truth.mainline_fit, *(r.fit for r in truth.ramps)]:
        err = max_border_error_m(fit, network=network, step_m=0.37)
        assert err["median_edge"] <= 0.001, (fit.road.id, err)
        assert err["lane_borders"] <= 0.001, (fit.road.id, err)
    # the written mainline roads are exact cuts of the whole mainline
    main = [r for r in truth.network.roads if r.name == "mainline"]
    for road, start in zip(main, truth.mainline_road_starts, strict=True):
        s = np.linspace(0.0, road.length, 50)
        assert np.allclose(road.xy(s), truth.mainline.xy(start + s), atol=1e-9)


def test_ramps_of_town06_match_the_map(town06_truth):
    _, truth = town06_truth
    ramps = [(r.type, r.source_roads[:2], r.main_before, r.main_after) for r in truth.ramps]
    assert ramps == [
        ("exit", ("570", "8"), "1", "2"),  # left exit: road 35's lane -3 through connector 570
        ("entry", ("32", "63"), "2", "3"),  # right entry from road 68 through connector 1159
        ("exit", ("1043", "70"), "3", "4"),  # left exit of lanes -1..-3 through connector 1043
    ]
    cuts = [r.cut_station_m for r in truth.ramps]
    gores = [r.station_m for r in truth.ramps]
    # exits cut at the junction's start, the entry at its end; gores where the bands part
    assert gores[0] > cuts[0] + 10.0
    assert gores[2] > cuts[2] + 10.0
    assert gores[1] < cuts[1] - 10.0
    net = truth.network
    for r in truth.ramps:
        junction = net.id_to_junction[r.junction_id]
        conn = next(
            c for c in junction.connections if r.road.id in (c.incoming_road, c.connecting_road)
        )
        assert conn.lane_links, r.road.id
        # the ramp's traffic lane is linked to a mainline driving lane
        ramp_sec = r.road.lane_sections[0 if r.type == "exit" else -1]
        ramp_driving = {ln.id for ln in ramp_sec.right if ln.type == "driving"}
        linked = {ll.to_lane if r.type == "exit" else ll.from_lane for ll in conn.lane_links}
        assert ramp_driving & linked


def test_soderleden_entry_feeds_the_acceleration_lane():
    _, truth = _truth(SODERLEDEN)
    (ramp,) = truth.ramps
    assert (ramp.type, ramp.source_roads, ramp.lanes) == ("entry", ("1", "5"), 1)
    assert ramp.aux_lane_ids == (-3,)  # road 0's lane -3, which ends 100 m later
    main_after = truth.network.road(ramp.main_after)
    assert [ln.type for ln in main_after.lane_sections[0].right] == ["driving"] * 3
    assert len(main_after.lane_sections[-1].right) == 2
    width_end = (
        main_after.lane_sections[0].right[2].width.value(main_after.lane_sections[1].s0 - 1e-6)
    )
    assert abs(float(width_end)) < 0.01  # the lane tapers out as in the map


# ---------------------------------------------------------------------------
# the simulated run
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def town06_clean(tmp_path_factory):
    """A noise-free run along Town06 35-38, through the in-memory network API."""
    out = tmp_path_factory.mktemp("t6") / "run"
    network = read_xodr(TOWN06)
    route = ["35", "36", "37", "38"]
    simulate_network_run(network, out, route=route, settings=NOISE_FREE, seed=2, name="town06")
    return out


def test_noise_free_run_lies_on_the_truth(town06_clean):
    run = load_run(town06_clean)
    truth = read_xodr(town06_clean / "truth.xodr")
    info = json.loads((town06_clean / "truth.json").read_text())
    assert run.traffic_side == "right"
    assert len(info["ramps"]) == 3
    # road edges: on the boundary of the paved area of the mainline and its ramps
    d_edge = _edge_polylines(truth).distance(run.edges)
    assert _rmse(d_edge) < 0.005, _rmse(d_edge)
    assert set(np.unique(run.edge_side)) == {-1, 1}
    # lane samples (placed with the recorded, here exact, poses): on painted lines
    d_lane = _painted_polylines(truth).distance(run.lane_samples)
    assert _rmse(d_lane) < 0.005, _rmse(d_lane)
    # ramp markings near the gores are seen too
    ramps = RoadNetwork(truth.header, tuple(r for r in truth.roads if r.name != "mainline"))
    d_ramp = _painted_polylines(ramps).distance(run.lane_samples)
    assert np.count_nonzero(d_ramp < 0.005) > 100


def test_broken_lines_have_the_style_dash_pattern(town06_clean):
    run = load_run(town06_clean)
    truth = read_xodr(town06_clean / "truth.xodr")
    info = json.loads((town06_clean / "truth.json").read_text())
    starts = {r["road_id"]: r["station_m"] for r in info["mainline_roads"]}
    road = truth.road("3")  # 200 m of road 37: broken lines between the five lanes
    s, t = road.project(run.lane_samples[:, :2])
    on_road = (s > 5.0) & (s < road.length - 5.0)
    border = road.lane_border_t(s, -4)  # between the 2nd and 3rd driving lane (US style)
    near = on_road & (np.abs(t - border) < 0.01)
    phase = np.mod(starts["3"] + s[near], 3.05 + 9.15)
    assert near.sum() > 50
    assert np.all(phase < 3.05 + 0.01), phase.max()  # 3.05 m dashes ...
    assert np.ptp(phase) > 2.5  # ... that are painted along their whole length


def test_noisy_run_has_sensor_noise(tmp_path):
    out = simulate_xodr_run(SODERLEDEN, tmp_path / "run", seed=4)
    run = load_run(out)
    truth = read_xodr(out / "truth.xodr")
    d = _edge_polylines(truth).distance(run.edges)
    inliers = d[d < 0.25]  # guardrail outliers are 0.3-3 m off
    # edge noise 0.03 m and pose drift 0.02 m per axis
    assert 0.025 < _rmse(inliers) < 0.08, _rmse(inliers)
    assert inliers.size > 0.95 * d.size
    info = json.loads((out / "truth.json").read_text())
    assert info["counts"]["lanes"]["worn_m"] > 0.0  # de style: 2 % of the paint worn off
    assert info["source"]["fit_max_error_mm"]["lane_borders"] < 1.0


def test_same_seed_same_bytes(tmp_path):
    def digest(folder: Path) -> dict[str, str]:
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.iterdir()}

    a = digest(simulate_xodr_run(E6MINI, tmp_path / "a", seed=7))
    b = digest(simulate_xodr_run(E6MINI, tmp_path / "b", seed=7))
    c = digest(simulate_xodr_run(E6MINI, tmp_path / "c", seed=8))
    assert a == b
    assert a["lane_samples.csv"] != c["lane_samples.csv"]
    assert a["truth.xodr"] == c["truth.xodr"]


def test_car_leaves_a_dropped_lane_before_its_taper():
    from roadtwin.simulate import load_scenario
    from roadtwin.simulate.route_sensor import drive
    from roadtwin.simulate.truth import build_truth

    # a network made by another generator: our parametric scenario's truth
    parametric = build_truth(load_scenario("interchange_5km"))
    (drop,) = parametric.scenario.lanes.drops  # lane 3 tapers to zero 4200 -> 4400 m
    route = find_through_route(parametric.network)
    truth = build_route_truth(parametric.network, route, frame=parametric.frame)
    poses = drive(truth, Car(lane=0))  # the outermost through lane
    u = poses.station
    _, t = truth.mainline.project(poses.xyz[:, :2], s_init=u)
    lane3 = -(0.75 + 2.5 * 3.75)  # centres of lanes 3 and 2 (3.75 m lanes, 0.75 m shoulder)
    lane2 = lane3 + 3.75
    taper_start = drop.station_m - drop.taper_m
    assert np.all(np.abs(t[u < taper_start - 150.0] - lane3) < 0.01)
    assert np.all(np.abs(t[u > taper_start] - lane2) < 0.01)  # moved over before the taper
    change = (u > taper_start - 150.0) & (u < taper_start)
    assert np.all(np.diff(t[change]) >= -1e-9)  # one smooth move to the left
    assert np.degrees(np.max(np.abs(np.diff(poses.yaw)))) < 1.0


def test_parametric_network_through_the_generic_path(tmp_path):
    from roadtwin.simulate import load_scenario
    from roadtwin.simulate.truth import build_truth

    parametric = build_truth(load_scenario("left_hand_2km"))
    settings = NetworkRunSettings(traffic_side="left")
    out = simulate_network_run(parametric.network, tmp_path / "run", settings=settings, seed=3)
    info = json.loads((out / "truth.json").read_text())
    assert info["traffic_side"] == "left"
    assert [r["type"] for r in info["ramps"]] == [r.ramp.type for r in parametric.ramps]
    for got, want in zip(info["ramps"], parametric.ramps, strict=True):
        assert abs(got["junction_station_m"] - want.station_m) < 1e-3
        assert abs(got["station_m"] - want.station_m) <= 1.5  # gore found on a 1 m scan
    assert info["source"]["fit_max_error_mm"]["median_edge"] < 1.0
    assert info["source"]["fit_max_error_mm"]["lane_borders"] < 1.0
    assert info["car_lane"] == parametric.scenario.car_lane == 3  # the outermost lane


def test_left_hand_traffic(tmp_path):
    out = simulate_xodr_run(E6MINI, tmp_path / "lht", settings=NOISE_FREE, traffic_side="left")
    run = load_run(out)
    truth = read_xodr(out / "truth.xodr")
    assert run.traffic_side == "left"
    (road,) = truth.roads
    assert all(ln.id > 0 for ls in road.lane_sections for ln in ls.left)
    assert not any(ls.right for ls in road.lane_sections)
    d = _edge_polylines(truth).distance(run.edges)
    assert _rmse(d) < 0.005
    # driving the left lanes along s: the car keeps left of the truth's reference line
    _s, t = road.project(run.trajectory.xy)
    assert np.all(t > 0.0)


def test_route_osm_links_join_the_motorway(town06_clean):
    from roadtwin.osm import load_osm

    out = town06_clean

    run = load_run(out)
    graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    kinds = {d["highway"] for _, _, d in graph.edges(data=True)}
    assert kinds == {"motorway", "motorway_link"}
    info = json.loads((out / "truth.json").read_text())
    link_ways = {w for r in info["ramps"] for w in r["osm_way_ids"]}
    assert len(link_ways) == 3
    # each link way starts (exit) or ends (entry) on a node of the motorway
    motorway_nodes = {
        n for u, v, d in graph.edges(data=True) if d["highway"] == "motorway" for n in (u, v)
    }
    for ramp in info["ramps"]:
        ends = [
            (u, v)
            for u, v, d in graph.edges(data=True)
            if d["highway"] == "motorway_link" and d["osmid"] in ramp["osm_way_ids"]
        ]
        assert ends
        first = {u for u, _ in ends} - {v for _, v in ends}
        last = {v for _, v in ends} - {u for u, _ in ends}
        assert (first if ramp["type"] == "exit" else last) & motorway_nodes


def test_cli_simulates_a_map(tmp_path, capsys):
    from roadtwin.cli import main

    assert (
        main(["simulate", "--xodr", str(E6MINI), "--style", "uk", "-o", str(tmp_path / "r")]) == 0
    )
    text = capsys.readouterr().out
    assert "route      roads 0" in text
    assert "uk markings" in text
    assert main(["simulate", "--xodr", str(E6MINI), "--route", "7", "-o", str(tmp_path / "x")]) == 2
    assert main(["simulate", "-o", str(tmp_path / "y")]) == 2


def test_build_and_evaluate_end_to_end(tmp_path):
    from roadtwin.evaluation import evaluate
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map

    out = simulate_xodr_run(SODERLEDEN, tmp_path / "run", seed=1)
    run = load_run(out)
    graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    network = build_map(run, graph).network
    truth = read_xodr(out / "truth.xodr")
    info = json.loads((out / "truth.json").read_text())
    rep = evaluate(network, run, truth=truth, truth_info=info).runs[0]
    assert rep.truth["mainline_roads"] == 2
    assert rep.topology["true_ramps"] == 1
    # the numbers are the method's business; here only: the frames agree (a run in the
    # wrong place would be metres off) and nothing is undefined
    assert math.isfinite(rep.truth["road_edge"]["rmse_m"])
    assert rep.truth["road_edge"]["rmse_m"] < 1.0


def test_cli_simulates_a_real_osm_carriageway(tmp_path, capsys):
    """``simulate --from-osm``: the chain's lane-level truth driven by the car; the real
    extract is the run's map input, the run loads and its truth lies on the OSM chain."""
    from roadtwin.cli import main

    osm = Path(__file__).parent / "data" / "osm" / "kotka-e18.osm.pbf"
    out = tmp_path / "run"
    assert main(["simulate", "--from-osm", str(osm), "--seed", "2", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "kotka-e18.osm.pbf chain (longest)" in text
    run = load_run(out)
    assert run.osm_path is not None
    assert run.osm_path.read_bytes() == osm.read_bytes()
    truth = json.loads((out / "truth.json").read_text())
    assert truth["mainline_length_m"] > 1000.0
    assert truth["ramps"], "the Kotka chain has link ways"
    # a link meeting the chain at its first node cannot be drawn; it is recorded where it
    # meets the run (the evaluation does not count a ramp built there as spurious)
    (left_out,) = truth["ramps_left_out"]
    assert left_out["why"] == "gore too close to the end of the chain window"
    start = np.loadtxt(out / "truth_trajectory.csv", delimiter=",", skiprows=1, max_rows=1)
    assert math.hypot(left_out["x"] - start[2], left_out["y"] - start[3]) < 15.0
    assert main(["simulate", "--from-osm", str(tmp_path / "none.osm"), "-o", str(out)]) == 2
    assert main(["simulate", "straight_curve_2km", "--from-osm", str(osm), "-o", str(out)]) == 2


def test_a_parallel_entry_whose_line_starts_in_an_occlusion_is_attached_where_it_joins(
    tmp_path,
):
    """soderleden with a noisier sensor (seed 22): the entry's lane runs beside the mainline
    behind a line from 165 m and joins it at 240 m, where the outer edge was seen to step
    out. A truck hid the edge where the line starts, and a gore was placed there from the
    line's tip alone: the ramp was attached 73 m early (one ramp missed, one spurious)."""
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map
    from roadtwin.simulate import noisy_settings

    run_dir = simulate_xodr_run(
        DATA / "soderleden.xodr", tmp_path / "run", seed=22, settings=noisy_settings()
    )
    run = load_run(run_dir)
    graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    result = build_map(run, graph)
    entries = [r for r in result.ramps if r.type == "entry"]
    assert len(entries) == 1
    assert entries[0].station_m == pytest.approx(238.0, abs=6.0)


def test_simulate_noisy_flag_gives_a_worse_sensor_on_the_same_route(tmp_path):
    """``roadtwin simulate --xodr MAP --noisy``: the same route and truth, with markings
    missed (15 %), outliers and trucks; refused for a bundled scenario."""
    from roadtwin.cli import main

    args = ["simulate", "--xodr", str(DATA / "soderleden.xodr"), "--seed", "3", "-q"]
    assert main([*args, "-o", str(tmp_path / "plain")]) == 0
    assert main([*args, "--noisy", "-o", str(tmp_path / "noisy")]) == 0
    plain, noisy = load_run(tmp_path / "plain"), load_run(tmp_path / "noisy")
    assert (tmp_path / "plain" / "truth.xodr").read_bytes() == (
        tmp_path / "noisy" / "truth.xodr"
    ).read_bytes()
    assert noisy.lane_samples.shape[0] < 0.9 * plain.lane_samples.shape[0]
    assert noisy.edges.shape[0] < 0.9 * plain.edges.shape[0]
    assert main(["simulate", "demo", "--noisy", "-o", str(tmp_path / "demo")]) == 2


def test_branches_left_out_of_the_truth_are_recorded_where_they_leave():
    """A branch the route truth cannot represent is left out and recorded where it leaves
    (joins) the route, so that the evaluation does not call a ramp built there spurious."""
    network = read_xodr(TOWN06)
    route = route_from_ids(network, ["35", "36", "37", "38"], traffic_side="right")
    frame = MappingFrame(Origin(0.0, 0.0))
    kept = build_route_truth(network, route, frame=frame, traffic_side="right")
    # no branch fits within a nanometre: every one is left out
    none = build_route_truth(
        network, route, frame=frame, traffic_side="right", max_branch_error_m=1e-9
    )
    assert not none.ramps
    assert not kept.left_out
    assert sorted(x.type for x in none.left_out) == sorted(r.type for r in kept.ramps)
    for ramp in kept.ramps:
        at = kept.mainline.xy(np.array([ramp.cut_station_m]))[0]
        d = [math.dist(at, x.xy) for x in none.left_out if x.type == ramp.type]
        assert min(d) < 25.0, (ramp.type, d)
    assert {x.why for x in none.left_out} == {"one road cannot represent it"}
