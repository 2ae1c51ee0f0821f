"""Evaluation metrics on model-level networks with known errors."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from roadtwin.config import EvaluationConfig
from roadtwin.evaluation import (
    EvaluationReport,
    combine_reports,
    evaluate,
    format_table,
    lane_graph,
    mainline_roads,
    project_points,
    ramp_connectivity,
    section_boundaries,
    self_consistency,
    topology_against_truth,
)
from roadtwin.evaluation.topology import _attachment_point
from roadtwin.frames import MappingFrame, Origin
from roadtwin.io import MappingRun, Trajectory
from roadtwin.model import (
    Arc,
    Connection,
    CubicProfile,
    Header,
    Junction,
    Lane,
    LaneLink,
    LaneSection,
    Line,
    Road,
    RoadLink,
    RoadMark,
    RoadNetwork,
    chain_geometry,
)

MAIN_WIDTHS = (
    (-1, "shoulder", 0.75),
    (-2, "driving", 3.75),
    (-3, "driving", 3.75),
    (-4, "shoulder", 2.5),
)
RAMP_WIDTHS = ((-1, "shoulder", 0.5), (-2, "driving", 3.5), (-3, "shoulder", 1.0))


def _lanes(widths, *, succ=None, pred=None) -> tuple[Lane, ...]:
    succ = succ or {}
    pred = pred or {}
    return tuple(
        Lane(
            lid,
            typ,
            CubicProfile.constant(w),
            (RoadMark(0.0, "solid"),),
            predecessor=pred.get(lid),
            successor=succ.get(lid),
        )
        for lid, typ, w in widths
    )


def _same(widths) -> dict[int, int]:
    return {lid: lid for lid, _, _ in widths}


def _end_pose(road: Road) -> tuple[float, float, float]:
    return road.geometry[-1].end_pose()


def make_truth() -> RoadNetwork:
    """Mainline 1 -> J100 -> 2 (line + arc) -> J300 -> 3, exit 10 at J100, entry 20 at J300."""
    road1 = Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, 400.0),),
        (LaneSection(0.0, right=_lanes(MAIN_WIDTHS)),),
        name="mainline",
        successor=RoadLink("junction", "100"),
    )
    c101 = Road(
        "101",
        (Line(0.0, 400.0, 0.0, 0.0, 40.0),),
        (
            LaneSection(
                0.0, right=_lanes(MAIN_WIDTHS, succ=_same(MAIN_WIDTHS), pred=_same(MAIN_WIDTHS))
            ),
        ),
        name="connector",
        predecessor=RoadLink("road", "1", "end"),
        successor=RoadLink("road", "2", "start"),
        junction="100",
    )
    road2 = Road(
        "2",
        chain_geometry(
            [Line(0, 440.0, 0.0, 0.0, 200.0), Arc(0, 640.0, 0.0, 0.0, 300.0, curvature_per_m=0.002)]
        ),
        (LaneSection(0.0, right=_lanes(MAIN_WIDTHS)),),
        name="mainline",
        predecessor=RoadLink("junction", "100"),
        successor=RoadLink("junction", "300"),
    )
    c102 = Road(
        "102",
        (Line(0.0, 400.0, -8.25, -0.15, 40.0),),
        (LaneSection(0.0, right=_lanes(RAMP_WIDTHS, succ=_same(RAMP_WIDTHS))),),
        name="connector",
        predecessor=RoadLink("road", "1", "end"),
        successor=RoadLink("road", "10", "start"),
        junction="100",
    )
    x, y, h = _end_pose(c102)
    road10 = Road(
        "10",
        (Line(0.0, x, y, h, 200.0),),
        (LaneSection(0.0, right=_lanes(RAMP_WIDTHS, pred=_same(RAMP_WIDTHS))),),
        name="exit",
        predecessor=RoadLink("junction", "100"),
    )
    x2, y2, h2 = _end_pose(road2)
    c301 = Road(
        "301",
        (Line(0.0, x2, y2, h2, 40.0),),
        (
            LaneSection(
                0.0, right=_lanes(MAIN_WIDTHS, succ=_same(MAIN_WIDTHS), pred=_same(MAIN_WIDTHS))
            ),
        ),
        name="connector",
        predecessor=RoadLink("road", "2", "end"),
        successor=RoadLink("road", "3", "start"),
        junction="300",
    )
    x3, y3, h3 = _end_pose(c301)
    road3 = Road(
        "3",
        (Line(0.0, x3, y3, h3, 300.0),),
        (LaneSection(0.0, right=_lanes(MAIN_WIDTHS)),),
        name="mainline",
        predecessor=RoadLink("junction", "300"),
    )
    ex, ey = road3.to_xy(np.array([0.0]), np.array([-8.25]))[0]
    he = h3 + 0.15
    c303 = Road(
        "303",
        (Line(0.0, ex - 40.0 * math.cos(he), ey - 40.0 * math.sin(he), he, 40.0),),
        (LaneSection(0.0, right=_lanes(RAMP_WIDTHS, succ={-2: -3}, pred=_same(RAMP_WIDTHS))),),
        name="connector",
        predecessor=RoadLink("road", "20", "end"),
        successor=RoadLink("road", "3", "start"),
        junction="300",
    )
    sx, sy = c303.geometry[0].x0, c303.geometry[0].y0
    road20 = Road(
        "20",
        (Line(0.0, sx - 200.0 * math.cos(he), sy - 200.0 * math.sin(he), he, 200.0),),
        (LaneSection(0.0, right=_lanes(RAMP_WIDTHS)),),
        name="entry",
        successor=RoadLink("junction", "300"),
    )
    main_links = tuple(LaneLink(i, i) for i in (-1, -2, -3, -4))
    j100 = Junction(
        "100",
        (
            Connection("0", "1", "101", "start", main_links),
            Connection("1", "1", "102", "start", (LaneLink(-3, -2), LaneLink(-4, -3))),
        ),
    )
    j300 = Junction(
        "300",
        (
            Connection("0", "2", "301", "start", main_links),
            Connection("1", "20", "303", "start", (LaneLink(-2, -2),)),
        ),
    )
    return RoadNetwork(
        Header(), (road1, road2, road3, c101, c301, c102, road10, c303, road20), (j100, j300)
    )


TRUTH_INFO = {
    "traffic_side": "right",
    "ramps": [
        {"road_id": "10", "type": "exit", "station_m": 400.0},
        {"road_id": "20", "type": "entry", "station_m": 980.0},
    ],
}


def shifted(network: RoadNetwork, shift_m: float, *, roles=("mainline",)) -> RoadNetwork:
    """Every boundary of the roles' roads (and their through connectors) moved left."""
    keep = {r.id for r in mainline_roads(network)} if "mainline" in roles else set()
    keep |= {r.id for r in network.roads if r.name in roles}
    roads = tuple(
        replace(r, lane_offset=CubicProfile.constant(shift_m)) if r.id in keep else r
        for r in network.roads
    )
    return replace(network, roads=roads)


def make_run(
    network: RoadNetwork, *, edge_sigma: float, lane_sigma: float, seed: int, step_m: float = 0.5
) -> MappingRun:
    """Measurements on the boundaries of the mainline roads plus Gaussian lateral noise."""
    rng = np.random.default_rng(seed)
    edges, lanes = [], []
    for road in mainline_roads(network):
        s = np.arange(0.0, road.length, step_m)
        for kind, lid in section_boundaries(road.lane_sections[0]):
            sigma = edge_sigma if kind == "road_edge" else lane_sigma
            t = road.lane_border_t(s, lid) + rng.normal(0.0, sigma, s.size)
            xy = road.to_xy(s, t)
            pts = np.column_stack([xy, np.zeros(s.size)])
            (edges if kind == "road_edge" else lanes).append(pts)
    edges_arr = np.vstack(edges)
    lanes_arr = np.vstack(lanes)
    n = 10
    traj = Trajectory(
        frame=np.arange(n, dtype=np.int64),
        t=np.arange(n, dtype=float),
        xyz=np.column_stack([np.linspace(0, 400, n), np.full(n, -5.0), np.zeros(n)]),
        yaw=np.zeros(n),
        pitch=np.zeros(n),
        roll=np.zeros(n),
    )
    return MappingRun(
        root=Path(f"/runs/run{seed}"),
        frame=MappingFrame(Origin(47.07, 15.44, 350.0)),
        trajectory=traj,
        pose_height_m=0.0,
        edges=edges_arr,
        edge_side=np.zeros(edges_arr.shape[0], dtype=np.int8),
        lane_samples=lanes_arr,
        lane_sample_frame=np.zeros(lanes_arr.shape[0], dtype=np.int64),
        osm_path=None,
    )


@pytest.fixture(scope="module")
def truth() -> RoadNetwork:
    return make_truth()


def test_mainline_chain_order_and_boundaries(truth):
    assert [r.id for r in mainline_roads(truth)] == ["1", "101", "2", "301", "3"]
    kinds = section_boundaries(truth.road("1").lane_sections[0])
    assert kinds == [
        ("road_edge", 0),
        ("lane_boundary", -1),
        ("lane_boundary", -2),
        ("lane_boundary", -3),
        ("road_edge", -4),
    ]


def test_projection_excludes_points_beyond_ends_and_far_away(truth):
    roads = mainline_roads(truth)
    pts = np.array([[-30.0, -5.0], [200.0, 200.0], [420.0, -5.0], [100.0, -5.0]])
    proj = project_points(roads, pts)
    assert proj.status.tolist() == [1, 2, 0, 0]
    assert roads[int(proj.road_index[2])].id == "101"
    assert proj.station_m[2] == pytest.approx(420.0, abs=1e-6)
    assert proj.t[3] == pytest.approx(-5.0, abs=1e-9)


def test_self_consistency_equals_injected_noise(truth):
    run = make_run(truth, edge_sigma=0.05, lane_sigma=0.10, seed=1)
    far = np.array([[-20.0, -3.0, 0.0], [-30.0, -6.0, 0.0], [300.0, 300.0, 0.0]])
    run = replace(run, edges=np.vstack([run.edges, far]))
    sc = self_consistency(truth, run)
    # measured RMS of the injected noise itself (n ~ 5000 edge, 7700 lane points)
    assert sc["road_edge_rmse_m"] == pytest.approx(0.05, rel=0.05)
    assert sc["lane_boundary_rmse_m"] == pytest.approx(0.10, rel=0.05)
    n_e, n_l = sc["road_edge_points"], sc["lane_samples"]
    pooled = math.sqrt(
        (n_e * sc["road_edge_rmse_m"] ** 2 + n_l * sc["lane_boundary_rmse_m"] ** 2) / (n_e + n_l)
    )
    assert sc["overall_rmse_m"] == pytest.approx(pooled, rel=1e-9)
    assert sc["excluded_beyond_ends"] == 2
    assert sc["excluded_no_road"] == 1
    assert n_e == run.edges.shape[0] - 3


def test_self_consistency_of_shifted_map(truth):
    run = make_run(truth, edge_sigma=0.0, lane_sigma=0.0, seed=2)
    cfg = EvaluationConfig(self_consistency_scope="mainline")
    sc = self_consistency(shifted(truth, 0.3), run, config=cfg)
    for key in ("road_edge_rmse_m", "lane_boundary_rmse_m", "overall_rmse_m"):
        assert sc[key] == pytest.approx(0.3, abs=1e-6)
    # with ramps in scope, the unshifted ramp connectors explain a few junction points
    sc_all = self_consistency(shifted(truth, 0.3), run)
    assert 0 < sc_all["ramp_points"] < 0.02 * (sc_all["road_edge_points"] + sc_all["lane_samples"])
    assert 0.29 < sc_all["overall_rmse_m"] <= 0.3


def test_self_consistency_points_on_ramps(truth):
    """Edge points measured along a ramp belong to the ramp road, not to the mainline."""
    ramp = truth.road("10")
    s = np.arange(0.0, 60.0, 0.5)
    ramp_edges = np.column_stack([ramp.to_xy(s, ramp.lane_border_t(s, -3)), np.zeros(s.size)])
    run = make_run(truth, edge_sigma=0.0, lane_sigma=0.0, seed=6)
    run = replace(run, edges=np.vstack([run.edges, ramp_edges]))
    sc_all = self_consistency(truth, run)
    assert sc_all["road_edge_rmse_m"] == pytest.approx(0.0, abs=1e-6)
    assert sc_all["ramp_points"] >= s.size
    sc_main = self_consistency(
        truth, run, config=EvaluationConfig(self_consistency_scope="mainline")
    )
    assert sc_main["road_edge_rmse_m"] > 0.5


def test_shifted_map_against_truth_reports_shift(truth):
    run = make_run(truth, edge_sigma=0.03, lane_sigma=0.03, seed=3)
    report = evaluate(shifted(truth, 0.3), run, truth=truth, truth_info=TRUTH_INFO)
    res = report.runs[0].truth
    for kind in ("road_edge", "lane_boundary"):
        strict = res[f"{kind}_strict"]
        assert strict["rmse_m"] == pytest.approx(0.3, abs=0.01)
        assert strict["p95_m"] == pytest.approx(0.3, abs=0.01)
        assert strict["max_m"] == pytest.approx(0.3, abs=0.01)
        # beside the ramps' (unshifted) connecting roads a few points match their borders
        assert res[kind]["rmse_m"] == pytest.approx(0.3, abs=0.01)
        assert res[kind]["max_m"] <= 0.3 + 1e-6
    # every 1 m along 1280 m of mainline, 2 edges and 3 markings; where the entry's
    # connecting road converges across the through connector's hard shoulder (J300), 30 m
    # of the outer edge lie on the entry's pavement and are no edge
    assert res["road_edge"]["n"] == 2 * 1280 - 30
    assert res["on_ramp_points"] == 30
    assert res["lane_boundary"]["n"] == 3 * 1280
    assert res["covered_fraction"] == pytest.approx(1.0)
    assert res["elevation"]["max_m"] == pytest.approx(0.0, abs=1e-9)
    assert res["ramp_centre"]["max_m"] == pytest.approx(0.0, abs=1e-6)
    assert res["lane_count"]["matched_fraction"] == pytest.approx(1.0)
    signed = report.runs[0].details["truth/road_edge"].error_m
    shifted_by = np.isclose(signed, -0.3, atol=1e-6)  # truth lies 0.3 m right of the map
    assert np.count_nonzero(~shifted_by) <= 10 <= res["junction_points"]


def test_ramp_shift_and_elevation_against_truth(truth):
    run = make_run(truth, edge_sigma=0.0, lane_sigma=0.0, seed=4)
    built = shifted(truth, 0.5, roles=("exit", "entry", "connector"))
    built = replace(
        built,
        roads=tuple(
            replace(r, elevation=CubicProfile.constant(0.2)) if r.name == "mainline" else r
            for r in built.roads
        ),
    )
    res = evaluate(built, run, truth=truth).runs[0].truth
    assert res["ramp_centre"]["rmse_m"] == pytest.approx(0.5, abs=0.01)
    assert res["ramp_boundary"]["rmse_m"] == pytest.approx(0.5, abs=0.01)
    assert res["ramp_centre"]["covered_fraction"] > 0.95
    # connectors 101 and 301 were shifted too (role "connector") but named roads not
    assert res["road_edge_strict"]["max_m"] == pytest.approx(0.5, abs=1e-6)
    # 2 x 80 connector points of 2 x 1280, less the 30 of connector 301's outer edge on
    # the entry connector's pavement
    strict = 0.5 * math.sqrt(130 / 2530)
    assert res["road_edge_strict"]["rmse_m"] == pytest.approx(strict, abs=1e-3)
    # beside the ramps' connecting roads (shifted alike) some match their borders
    assert 0.8 * strict < res["road_edge"]["rmse_m"] < strict
    # the three named mainline roads are 0.2 m high, the through connectors are not
    assert res["elevation"]["rmse_m"] == pytest.approx(0.2 * math.sqrt(1200 / 1280), abs=1e-3)


def test_lane_count_against_truth(truth):
    run = make_run(truth, edge_sigma=0.0, lane_sigma=0.0, seed=5)
    road2 = truth.road("2")
    sec = road2.lane_sections[0]
    right = (*sec.right[:2], replace(sec.right[2], type="shoulder"), sec.right[3])
    built = replace(
        truth,
        roads=tuple(
            replace(r, lane_sections=(replace(sec, right=right),)) if r.id == "2" else r
            for r in truth.roads
        ),
    )
    lc = evaluate(built, run, truth=truth).runs[0].truth["lane_count"]
    assert lc["stations"] == 1280
    assert lc["matched_fraction"] == pytest.approx((1280 - 500) / 1280)
    by_road = {s["road_id"]: s for s in lc["sections"]}
    assert by_road["2"]["true_driving_lanes"] == 2
    assert by_road["2"]["built_driving_lanes"] == 1
    assert by_road["2"]["matched_fraction"] == 0.0
    assert by_road["1"]["matched_fraction"] == 1.0


def test_lane_graph_follows_junction_links(truth):
    graph = lane_graph(truth)
    assert graph.has_edge(("1", 0, -3), ("102", 0, -2))
    assert graph.has_edge(("102", 0, -2), ("10", 0, -2))
    assert graph.has_edge(("303", 0, -2), ("3", 0, -3))
    assert not graph.has_edge(("1", 0, -2), ("102", 0, -2))
    conn = {c["road_id"]: c["connected"] for c in ramp_connectivity(truth)}
    assert conn == {"10": True, "20": True}


def test_topology_against_truth(truth):
    topo = topology_against_truth(truth, truth, truth_info=TRUTH_INFO)
    assert (topo["matched"], topo["missed"], topo["spurious"]) == (2, [], [])
    assert topo["type_correct"] == 2
    assert topo["all_connected"] is True
    assert all(p["attachment_distance_m"] < 1e-9 for p in topo["pairs"])

    # built map: entry missing, exit typed as entry, exit's lane link cut
    j100 = truth.id_to_junction["100"]
    j100_cut = replace(
        j100, connections=(j100.connections[0], replace(j100.connections[1], lane_links=()))
    )
    built = replace(
        truth,
        roads=tuple(
            replace(r, name="entry") if r.id == "10" else r
            for r in truth.roads
            if r.id not in ("20", "303")
        ),
        junctions=(
            j100_cut,
            replace(
                truth.id_to_junction["300"], connections=truth.id_to_junction["300"].connections[:1]
            ),
        ),
    )
    topo = topology_against_truth(built, truth, truth_info=TRUTH_INFO)
    assert topo["matched"] == 1
    assert topo["missed"] == ["20"]
    assert topo["spurious"] == []
    assert topo["type_correct"] == 0
    assert topo["pairs"][0]["connected"] is False  # an "entry" that leads nowhere

    # a far-away extra ramp is spurious
    extra = replace(truth.road("10"), id="99", geometry=(Line(0.0, 0.0, 500.0, 0.0, 100.0),))
    topo = topology_against_truth(
        replace(truth, roads=(*truth.roads, extra)), truth, truth_info=TRUTH_INFO
    )
    assert topo["spurious"] == ["99"]
    assert topo["matched"] == 2

    # ... unless the truth left a ramp of its source out there: then it is unjudged
    with_extra = replace(truth, roads=(*truth.roads, extra))
    at = _attachment_point(with_extra, extra, mainline_roads(with_extra))
    for dist, spurious, unjudged in ((5.0, [], ["99"]), (65.0, ["99"], [])):
        left_out = {"type": "exit", "what": "exit way 1", "why": "link only 40 m long"}
        info = TRUTH_INFO | {
            "ramps_left_out": [left_out | {"x": at[0] + dist, "y": at[1]}],
        }
        topo = topology_against_truth(with_extra, truth, truth_info=info)
        assert (topo["spurious"], topo["unjudged"], topo["matched"]) == (spurious, unjudged, 2)


def test_multi_run_table_reproducible_from_json(truth, tmp_path):
    reports = [
        evaluate(truth, make_run(truth, edge_sigma=s, lane_sigma=2 * s, seed=i), method="default")
        for i, s in enumerate((0.02, 0.05, 0.08))
    ]
    combined = combine_reports(reports)
    path = tmp_path / "report.json"
    path.write_text(json.dumps(combined.to_dict(), sort_keys=True))
    doc = json.loads(path.read_text())
    for target in ("road_edge", "lane_boundary", "overall"):
        vals = [r["self_consistency"][f"{target}_rmse_m"] for r in doc["runs"]]
        row = doc["table"]["default"][target]
        assert row["runs"] == 3
        assert row["mean_rmse_m"] == pytest.approx(float(np.mean(vals)), abs=1e-12)
        assert row["median_rmse_m"] == pytest.approx(float(np.median(vals)), abs=1e-12)
        assert row["min_rmse_m"] == min(vals)
        assert row["max_rmse_m"] == max(vals)
    assert doc["table"]["default"]["road_edge"]["median_rmse_m"] == pytest.approx(0.05, rel=0.1)
    text = format_table(combined)
    assert "Road edge" in text
    assert "Overall" in text
    assert f"{doc['table']['default']['overall']['mean_rmse_m']:.3f}" in text
    # deterministic: same input, same bytes
    again = combine_reports(
        [
            evaluate(
                truth, make_run(truth, edge_sigma=s, lane_sigma=2 * s, seed=i), method="default"
            )
            for i, s in enumerate((0.02, 0.05, 0.08))
        ]
    )
    assert json.dumps(again.to_dict(), sort_keys=True) == path.read_text()
    assert isinstance(combined, EvaluationReport)


def test_height_residual(truth):
    run = make_run(truth, edge_sigma=0.0, lane_sigma=0.0, seed=7)
    main_ids = {r.id for r in mainline_roads(truth)}
    raised = replace(
        truth,
        roads=tuple(
            replace(r, elevation=CubicProfile.constant(0.25)) if r.id in main_ids else r
            for r in truth.roads
        ),
    )
    sc = self_consistency(raised, run)
    assert sc["height_rmse_m"] == pytest.approx(0.25, abs=1e-9)
    assert sc["overall_rmse_m"] == pytest.approx(0.0, abs=1e-6)


def test_projection_prefers_the_road_a_point_lies_in_the_middle_of():
    lanes = (LaneSection(0.0, right=_lanes(((-1, "driving", 3.5),))),)
    road_a = Road("a", (Line(0.0, 0.0, 0.0, 0.0, 100.0),), lanes, name="exit")
    road_b = Road("b", (Line(0.0, 48.25, -50.0, math.pi / 2, 100.0),), lanes, name="entry")
    x = np.arange(1.0, 100.0, 1.0)
    pts = np.column_stack([x, np.full(x.size, -1.75)])  # centre line of a, crossing b
    proj = project_points([road_b, road_a], pts)
    assert np.all(proj.road_index == 1)
    np.testing.assert_allclose(proj.t, -1.75, atol=1e-9)
    # a point on b's centre line at the crossing goes to b
    proj_b = project_points([road_a, road_b], np.array([[50.0, -1.0], [50.0, 30.0]]))
    assert proj_b.road_index.tolist() == [1, 1]


def test_preselected_projection_equals_brute_force(truth):
    """The KD-tree pre-selection of candidate points per road changes nothing: same road,
    station, offset and status as projecting every point in each road's bounding box."""
    rng = np.random.default_rng(3)
    run = make_run(truth, edge_sigma=0.05, lane_sigma=0.10, seed=2)
    lo = np.min(run.edges[:, :2], axis=0) - 150.0
    hi = np.max(run.edges[:, :2], axis=0) + 150.0
    scatter = rng.uniform(lo, hi, size=(4000, 2))
    bad = np.array([[np.nan, 0.0], [100.0, np.inf]])  # invalid points are on no road
    pts = np.vstack([run.edges[:, :2], run.lane_samples[:, :2], scatter, bad])
    for roads in (mainline_roads(truth), list(truth.roads)):
        fast = project_points(roads, pts, max_lateral_m=20.0)
        slow = project_points(roads, pts, max_lateral_m=20.0, preselect=False)
        np.testing.assert_array_equal(fast.road_index, slow.road_index)
        np.testing.assert_array_equal(fast.status, slow.status)
        np.testing.assert_allclose(fast.s, slow.s, rtol=0, atol=1e-9)
        np.testing.assert_allclose(fast.t, slow.t, rtol=0, atol=1e-9)
        np.testing.assert_allclose(fast.station_m, slow.station_m, rtol=0, atol=1e-9)
        # every status occurs, so the test covers points beyond the ends and far away
        assert set(np.unique(fast.status).tolist()) == {0, 1, 2}
        assert fast.status[-2:].tolist() == [2, 2]
        assert project_points(roads, bad).status.tolist() == [2, 2]


def test_markings_painted_on_a_road_edge_are_on_a_boundary(truth):
    """A two-way road's centre line lies on the reference line (e6mini): its samples are
    on the map's border there, not 'off every lane boundary' (self-consistency 2.26 m)."""
    run = make_run(truth, edge_sigma=0.0, lane_sigma=0.0, seed=3)
    on_edge = run.edges[: run.edges.shape[0] // 2]
    run = replace(
        run,
        lane_samples=np.vstack([run.lane_samples, on_edge]),
        lane_sample_frame=np.concatenate(
            [run.lane_sample_frame, np.zeros(on_edge.shape[0], dtype=np.int64)]
        ),
    )
    sc = self_consistency(truth, run, config=EvaluationConfig(self_consistency_scope="mainline"))
    assert sc["lane_boundary_rmse_m"] < 0.01
