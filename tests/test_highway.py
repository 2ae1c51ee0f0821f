"""The whole highway: several runs fused, both carriageways, the other carriageway and the
roads beyond the ramps from OSM, the OSM-only mode, multi-run simulation.

Runs are simulated (bundled ``straight_curve_2km``: passes 1 and 2 of the forward
carriageway, the opposite carriageway) and built; every map is checked by ``roadtwin
check``'s own checks, and accuracy is measured against the simulator's truth.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from roadtwin.check import check_network
from roadtwin.cli import main
from roadtwin.config import HighwayConfig
from roadtwin.evaluation import evaluate, ramp_connectivity
from roadtwin.frames import MappingFrame
from roadtwin.highway import (
    build_highway,
    build_osm_only,
    check_consistency,
    fuse_runs,
    group_runs,
    merge_parts,
    run_in_frame,
)
from roadtwin.highway.area import area_from_bbox, load_area_graph
from roadtwin.highway.evaluate import carriageway_network, evaluate_carriageway
from roadtwin.highway.merge import NetworkPart, carriageway_of
from roadtwin.io import load_run
from roadtwin.model import Connection, Junction, Road, RoadLink
from roadtwin.osm import load_osm
from roadtwin.osm_roads import CrossSection, lane_sections, maxspeed_mps
from roadtwin.pipeline import build_map
from roadtwin.simulate import simulate_run
from roadtwin.simulate.opposite import simulate_opposite_run
from roadtwin.xodr import read_xodr, write_xodr

OSM_DIR = Path(__file__).parent / "data" / "osm"
SCENARIO = "straight_curve_2km"
NORD = OSM_DIR / "a9-bayreuth-nord.osm.gz"  # an A9 interchange: both carriageways, 4 ramps
NORD_BOX = (11.486, 50.0345, 11.501, 50.0425)


def _errors(network) -> list[str]:
    return [
        f"{f.code} road {f.road}: {f.message}"
        for f in check_network(network)
        if f.severity == "error"
    ]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("highway")
    dirs = {
        "pass1": simulate_run(SCENARIO, base / "pass1"),
        "pass2": simulate_run(SCENARIO, base / "pass2", pass_index=2),
        "opposite": simulate_opposite_run(SCENARIO, base / "opposite"),
    }
    return {k: load_run(v) for k, v in dirs.items()} | {"dirs": dirs}


@pytest.fixture(scope="module")
def osm_graph(runs):
    run = runs["pass1"]
    return load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)


def _truth_rmse(network, run, truth_dir) -> dict:
    truth = read_xodr(truth_dir / "truth.xodr")
    t = evaluate(network, run, truth=truth).runs[0].truth
    return {k: t[k]["rmse_m"] for k in ("road_edge", "lane_boundary")}


# ---------------------------------------------------------------------------
# simulation of several runs
# ---------------------------------------------------------------------------


def test_passes_share_truth_and_osm_but_not_the_sensor(runs):
    a, b = runs["dirs"]["pass1"], runs["dirs"]["pass2"]
    for name in ("truth.xodr", "map.osm", "truth_trajectory.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    for name in ("trajectory.csv", "road_edges.laz", "lane_samples.csv"):
        assert (a / name).read_bytes() != (b / name).read_bytes(), name
    assert json.loads((b / "truth.json").read_text())["pass"] == 2
    assert "pass" not in json.loads((a / "truth.json").read_text())


def test_opposite_run_drives_the_other_carriageway_in_the_same_frame(runs):
    fwd, opp = runs["pass1"], runs["opposite"]
    assert opp.frame.geo_reference == fwd.frame.geo_reference
    assert opp.frame.z_offset_m == fwd.frame.z_offset_m
    # it drives the other way, a median and a few lanes to the left
    d = np.gradient(fwd.trajectory.xy, axis=0)
    near = np.argmin(
        np.hypot(*(fwd.trajectory.xy[:, None] - opp.trajectory.xy[None, ::40]).T), axis=1
    )
    heading_f = np.arctan2(d[near, 1], d[near, 0])
    heading_o = opp.trajectory.yaw[::40]
    turn = np.abs((heading_o - heading_f + np.pi) % (2 * np.pi) - np.pi)
    assert np.all(turn > np.radians(170))
    truth = read_xodr(runs["dirs"]["opposite"] / "truth.xodr")
    assert [r.name for r in truth.roads] == ["mainline"]
    assert (runs["dirs"]["opposite"] / "map.osm").read_bytes() == (
        runs["dirs"]["pass1"] / "map.osm"
    ).read_bytes()


def test_simulate_cli_pass_and_direction(tmp_path, capsys):
    assert main(["-q", "simulate", SCENARIO, "--pass", "3", "-o", str(tmp_path / "p3")]) == 0
    assert "pass 3" in capsys.readouterr().out
    assert main(["-q", "simulate", SCENARIO, "--pass", "0", "-o", str(tmp_path / "p0")]) == 2
    code = main(
        ["-q", "simulate", "--xodr", "x.xodr", "--direction", "opposite", "-o", str(tmp_path / "x")]
    )
    assert code == 2


def test_osm_chain_opposite_direction(tmp_path):
    """``--from-osm --direction opposite``: the other carriageway of a real A9 stretch, in
    the forward truth's frame, running the other way beside it."""
    from roadtwin.simulate import simulate_osm_run

    osm = OSM_DIR / "a9-bindlacher-berg.osm"
    fwd = simulate_osm_run(osm, tmp_path / "f", chain=239192816, seed=1)
    opp = simulate_osm_run(osm, tmp_path / "o", chain=239192816, seed=1, direction="opposite")
    a, b = load_run(fwd), load_run(opp)
    assert a.frame.geo_reference == b.frame.geo_reference
    ma = next(r for r in read_xodr(fwd / "truth.xodr").roads if r.name == "mainline")
    s, t = ma.project(b.trajectory.xy)
    inside = (s > 1.0) & (s < ma.length - 1.0)
    assert inside.mean() > 0.3
    # the car of the other direction drives beside the forward carriageway on its median
    # side (left for right-hand traffic), the other way
    assert np.median(t[inside]) > 3.0
    assert np.all(np.abs(t[inside]) < 80.0)
    turn = (b.trajectory.yaw[inside] - ma.heading(s[inside]) + np.pi) % (2 * np.pi) - np.pi
    assert np.all(np.abs(turn) > np.radians(150))
    assert json.loads((opp / "truth.json").read_text())["traffic_side"] == "right"


# ---------------------------------------------------------------------------
# runs: frames, grouping, fusion
# ---------------------------------------------------------------------------


def test_run_in_frame_round_trip(runs):
    run = runs["pass1"]
    utm = MappingFrame(run.frame.origin, "+proj=utm +zone=32 +datum=WGS84 +units=m")
    there = run_in_frame(run, utm)
    assert abs(there.trajectory.xy[0, 0] - run.trajectory.xy[0, 0]) > 1e4  # really moved
    # heights keep their altitude: local z is above the origin's altitude
    assert np.allclose(there.edges[:, 2], run.edges[:, 2] + run.frame.z_offset_m)
    back = run_in_frame(there, run.frame)
    assert np.abs(back.trajectory.xyz - run.trajectory.xyz).max() < 1e-3
    assert np.abs(back.edges - run.edges).max() < 1e-3
    assert np.abs(back.lane_samples - run.lane_samples).max() < 1e-3
    assert np.abs(back.trajectory.yaw - run.trajectory.yaw).max() < 1e-5
    assert run_in_frame(run, run.frame) is run


def _split(run, at: int, name: str):
    """The run's poses ``[at:]`` (or ``[:at]`` for negative ``at``) and their points."""
    traj = run.trajectory
    sel = slice(at, None) if at >= 0 else slice(None, -at)
    frames = set(traj.frame[sel].tolist())
    keep_l = np.isin(run.lane_sample_frame, list(frames))
    part = {k: getattr(traj, k)[sel] for k in ("frame", "t", "xyz", "yaw", "pitch", "roll")}
    xy = traj.xy[sel]
    tree_d, _ = cKDTree(xy).query(run.edges[:, :2])
    keep_e = tree_d < 30.0
    return replace(
        run,
        root=run.root.with_name(name),
        trajectory=replace(traj, **part),
        edges=run.edges[keep_e],
        edge_side=run.edge_side[keep_e],
        lane_samples=run.lane_samples[keep_l],
        lane_sample_frame=run.lane_sample_frame[keep_l],
    )


def test_group_runs_by_carriageway(runs):
    first = _split(runs["pass1"], -450, "first")
    second = _split(runs["pass2"], 420, "second")
    groups = group_runs([runs["pass1"], runs["opposite"], first, second, runs["pass2"]])
    assert groups.carriageways == ((0, 2, 3, 4), (1,))
    assert groups.opposite == ((0, 1),)
    assert groups.partner(1) == 0
    # two halves that continue each other are one carriageway and one path
    cont = group_runs([first, second])
    assert cont.carriageways == ((0, 1),)
    fused = fuse_runs([first, second])
    assert [p[0] for p in fused.path_pieces] == ["first", "second"]
    length = np.hypot(*np.diff(fused.run.trajectory.xy, axis=0).T).sum()
    assert length > 0.95 * runs["pass1"].trajectory.length_m


def test_two_passes_fused_beat_each_pass(runs, osm_graph):
    """Passes 1 and 2 fused: the lane boundaries closer to the truth than either pass, the
    edges closer than the passes' mean, and the occlusions of one filled by the other."""
    truth_dir = runs["dirs"]["pass1"]
    single = [
        _truth_rmse(build_map(runs[k], osm_graph).network, runs[k], truth_dir)
        for k in ("pass1", "pass2")
    ]
    fused = fuse_runs([runs["pass1"], runs["pass2"]])
    assert fused.disagreements == ()
    assert fused.run.edges.shape[0] == runs["pass1"].edges.shape[0] + runs["pass2"].edges.shape[0]
    both = _truth_rmse(build_map(fused.run, osm_graph).network, fused.run, truth_dir)
    assert both["lane_boundary"] < min(s["lane_boundary"] for s in single)
    assert both["road_edge"] < np.mean([s["road_edge"] for s in single])
    assert both["road_edge"] < 0.03
    assert both["lane_boundary"] < 0.03
    # occlusions (trucks, dropouts): metres of the true median-side edge without an edge
    # point within 1 m, per pass and fused
    truth = read_xodr(truth_dir / "truth.xodr")
    mains = [r for r in truth.roads if r.name == "mainline"]
    ref = np.vstack(
        [
            r.to_xy(np.arange(0.0, r.length), r.lane_border_t(np.arange(0.0, r.length), 0))
            for r in mains
        ]
    )

    def unseen(run) -> int:
        d, _ = cKDTree(run.edges[:, :2]).query(ref)
        return int(np.count_nonzero(d > 1.0))

    gaps = [unseen(runs["pass1"]), unseen(runs["pass2"])]
    assert min(gaps) > 20  # each pass has occlusions ...
    assert unseen(fused.run) < 0.5 * min(gaps)  # ... the other fills most of them


def test_disagreeing_runs_are_reported_not_averaged(runs, osm_graph):
    """A run shifted 0.6 m sideways on 300 m (a GNSS fault) is reported with its station,
    and the map follows the other run there."""
    a, b = runs["pass1"], runs["pass2"]
    mainline = build_map(a, osm_graph).mainline.road
    s_e, _ = mainline.project(b.edges[:, :2])
    s_l, _ = mainline.project(b.lane_samples[:, :2])
    h_e = mainline.heading(s_e)
    h_l = mainline.heading(s_l)
    shift = 0.6
    bad_e = (s_e > 300.0) & (s_e < 600.0)
    bad_l = (s_l > 300.0) & (s_l < 600.0)
    edges = b.edges.copy()
    lanes = b.lane_samples.copy()
    edges[bad_e, 0] -= shift * np.sin(h_e[bad_e])
    edges[bad_e, 1] += shift * np.cos(h_e[bad_e])
    lanes[bad_l, 0] -= shift * np.sin(h_l[bad_l])
    lanes[bad_l, 1] += shift * np.cos(h_l[bad_l])
    faulty = replace(b, edges=edges, lane_samples=lanes)
    fused = fuse_runs([a, faulty])
    found = [d for d in fused.disagreements if d.edge == "median-side edge"]
    assert found, fused.disagreements
    d = found[0]
    assert 250.0 <= d.s0_m <= 350.0
    assert 550.0 <= d.s1_m <= 650.0
    assert abs(d.offset_m - shift) < 0.15
    assert d.kept == "pass1"
    assert fused.dropped_points > 1000
    assert any("disagree" in w and "s=" in w for w in fused.warnings)
    rmse = _truth_rmse(build_map(fused.run, osm_graph).network, fused.run, runs["dirs"]["pass1"])
    assert rmse["road_edge"] < 0.05


def test_check_consistency_quiet_on_agreeing_runs(runs):
    from roadtwin.highway.runs import _frame_of

    frame = _frame_of(runs["pass1"].trajectory.xyz)
    assert check_consistency(frame, [runs["pass1"], runs["pass2"]]) == []


# ---------------------------------------------------------------------------
# both carriageways
# ---------------------------------------------------------------------------


def test_a_run_in_each_direction_gives_both_carriageways(runs, osm_graph):
    res = build_highway([runs["pass1"], runs["opposite"]], osm_graph)
    assert [c.source for c in res.carriageways] == ["lidar", "lidar"]
    assert res.carriageways[0].partner == 2
    assert res.carriageways[1].partner == 1
    assert not _errors(res.network)
    for number, key in ((1, "pass1"), (2, "opposite")):
        truth_dir = runs["dirs"][key]
        r = evaluate_carriageway(
            res.network,
            number,
            runs[key],
            read_xodr(truth_dir / "truth.xodr"),
            truth_info=json.loads((truth_dir / "truth.json").read_text()),
        )
        assert r["truth"]["road_edge"]["rmse_m"] <= 0.05, (number, r["truth"]["road_edge"])
        assert r["truth"]["lane_boundary"]["rmse_m"] <= 0.05
        assert r["truth"]["lane_count"]["matched_fraction"] > 0.99
        assert r["topology"]["missed"] == []
    # ids unique, every road tagged with its carriageway
    ids = [r.id for r in res.network.roads] + [j.id for j in res.network.junctions]
    assert len(ids) == len(set(ids))
    assert {carriageway_of(r) for r in res.network.roads} == {1, 2}


def test_one_run_gets_the_other_carriageway_from_osm(runs, osm_graph, tmp_path):
    res = build_highway([runs["pass1"]], osm_graph)
    assert [c.source for c in res.carriageways] == ["lidar", "osm"]
    other = res.carriageways[1]
    assert other.partner == 1
    assert res.carriageways[0].partner == 2
    assert not _errors(res.network)
    # in the right place (within OSM accuracy: the simulated OSM is drawn up to 1.5 m off
    # plus 0.5 m node noise) and with the right lanes
    opp_dir = runs["dirs"]["opposite"]
    r = evaluate_carriageway(res.network, 2, runs["opposite"], read_xodr(opp_dir / "truth.xodr"))
    assert r["truth"]["covered_fraction"] > 0.95
    assert r["truth"]["road_edge"]["rmse_m"] < 2.0
    assert r["truth"]["lane_boundary"]["rmse_m"] < 2.0
    assert r["truth"]["lane_count"]["matched_fraction"] > 0.95
    # in the right direction: the opposite run's poses head along it
    part = carriageway_network(res.network, 2)
    main = [x for x in part.roads if x.name == "mainline"]
    traj = runs["opposite"].trajectory
    for road in main:
        s, t = road.project(traj.xy[::25])
        on = (s > 1.0) & (s < road.length - 1.0) & (np.abs(t) < 20.0)
        turn = (traj.yaw[::25][on] - road.heading(s[on]) + np.pi) % (2 * np.pi) - np.pi
        assert on.any(), road.id
        assert np.all(np.abs(turn) < np.radians(10)), road.id
    # with its own ramps, linked to it by lane links
    assert len(other.topology.ramps) == 2
    conn = ramp_connectivity(part)
    assert conn
    assert all(c["connected"] for c in conn)
    # evaluated against the run's truth, the map is measured on the carriageway the truth
    # holds: the other carriageway's ramps are not spurious ones
    rep = evaluate(
        res.network,
        runs["pass1"],
        truth=read_xodr(runs["dirs"]["pass1"] / "truth.xodr"),
        truth_info=json.loads((runs["dirs"]["pass1"] / "truth.json").read_text()),
    ).runs[0]
    assert rep.topology["spurious"] == []
    assert rep.topology["matched"] == 2
    # the file keeps the tags
    path = write_xodr(res.network, tmp_path / "map.xodr")
    back = read_xodr(path)
    assert {carriageway_of(r) for r in back.roads} == {1, 2}
    assert any(dict(r.user_data).get("roadtwin:source") == "osm" for r in back.roads)


def test_carriageway_only_is_the_single_run_build(runs, osm_graph):
    cfg_off = HighwayConfig(opposite=False, beyond=False)
    from roadtwin.config import PipelineConfig

    res = build_highway([runs["pass1"]], osm_graph, config=PipelineConfig(highway=cfg_off))
    single = build_map(runs["pass1"], osm_graph)
    assert [r.id for r in res.network.roads] == [r.id for r in single.network.roads]
    assert [j.id for j in res.network.junctions] == [j.id for j in single.network.junctions]


# ---------------------------------------------------------------------------
# OSM roads: lanes, beyond the ramps, OSM-only
# ---------------------------------------------------------------------------


def test_lane_sections_from_osm_counts():
    xs = CrossSection(3.5, 0.75, 2.5)
    secs = lane_sections(1000.0, [(0.0, 2), (300.0, 3), (600.0, 2, True)], xs, taper_m=80.0)
    assert [round(s.s0) for s in secs] == [0, 300, 600]
    gain = secs[1].right
    assert [ln.type for ln in gain] == ["shoulder", "driving", "driving", "driving", "shoulder"]
    w = gain[3].width
    assert float(w.value(0.0)) == pytest.approx(0.0, abs=1e-9)  # a lane gain opens ...
    assert float(w.value(80.0)) == pytest.approx(3.5)  # ... over the taper
    assert gain[3].predecessor is None
    assert gain[3].successor is None  # ... and ends at full width at the exit's gore
    assert secs[0].right[-1].successor == gain[-1].id  # the hard shoulder continues
    assert float(secs[2].right[0].width.value(0.0)) == pytest.approx(0.75)
    left = lane_sections(500.0, [(0.0, 2)], xs, traffic_side="left")
    assert [ln.id for ln in left[0].left] == [1, 2, 3, 4]


def test_maxspeed():
    assert maxspeed_mps("130") == pytest.approx(130 / 3.6)
    assert maxspeed_mps("60 mph") == pytest.approx(26.8224)
    assert maxspeed_mps("none") is None
    assert maxspeed_mps("DE:motorway") is None
    assert maxspeed_mps(None) is None


def test_merge_renumbers_and_keeps_links():
    from roadtwin.model import LaneSection, Line

    def road(rid, **kw):
        return Road(rid, (Line(0.0, 0.0, 0.0, 0.0, 10.0),), (LaneSection(0.0),), **kw)

    a = NetworkPart(
        (road("1", successor=RoadLink("junction", "3")), road("2", junction="3")),
        (Junction("3", (Connection("0", "1", "2", "start"),)),),
        1,
        "lidar",
    )
    b = NetworkPart(
        (
            road("1", successor=RoadLink("road", "2", "start")),
            road("2", predecessor=RoadLink("road", "1", "end")),
        ),
        (),
        2,
        "osm",
    )
    roads, junctions, maps = merge_parts([a, b])
    assert [r.id for r in roads] == ["1", "2", "4", "5"]
    assert [j.id for j in junctions] == ["3"]
    assert roads[2].successor == RoadLink("road", "5", "start")
    assert roads[1].junction == "3"
    assert maps[1] == {"1": "4", "2": "5"}
    assert [carriageway_of(r) for r in roads] == [1, 1, 2, 2]


@pytest.fixture(scope="module")
def osm_only(tmp_path_factory):
    area = area_from_bbox(NORD, NORD_BOX)
    graph = load_area_graph(area)
    res = build_osm_only(graph, area.frame, box_xy=area.box_xy)
    path = write_xodr(res.network, tmp_path_factory.mktemp("osm_only") / "map.xodr")
    return res, graph, read_xodr(path)


def test_osm_only_builds_both_carriageways_with_ramps(osm_only):
    res, _, back = osm_only
    assert len(res.carriageways) == 2
    assert res.carriageways[0].partner == 2
    assert not _errors(back)
    ramps = [r for r in back.roads if r.name in ("exit", "entry")]
    assert ramps
    assert all(c["connected"] for c in ramp_connectivity(back))
    # OSM's name / ref and maxspeed are in the file
    main = [r for r in back.roads if r.name == "mainline"]
    assert all(dict(r.user_data).get("roadtwin:osm_ref") == "A 70" for r in main)
    assert any(r.speed_limit_mps is not None for r in back.roads)


def test_no_ramp_is_a_dead_end_where_osm_continues(osm_only):
    res, graph, back = osm_only
    assert res.beyond
    by_id = back.id_to_road
    linked = set()
    for b in res.beyond:
        ramp, road = by_id[b.ramp_road_id], by_id[b.road.id]
        if b.ramp_type == "exit":
            assert ramp.successor == RoadLink("road", road.id, "start")
            assert road.predecessor == RoadLink("road", ramp.id, "end")
            lanes = [ln for ln in ramp.lane_sections[-1].right if ln.type == "driving"]
            assert all(ln.successor is not None for ln in lanes)
            gap = np.hypot(*(ramp.xy([ramp.length])[0] - road.xy([0.0])[0]))
        else:
            assert ramp.predecessor == RoadLink("road", road.id, "end")
            lanes = [ln for ln in ramp.lane_sections[0].right if ln.type == "driving"]
            assert all(ln.predecessor is not None for ln in lanes)
            gap = np.hypot(*(ramp.xy([0.0])[0] - road.xy([road.length])[0]))
        assert gap < 1e-6
        assert road.length > 15.0
        linked.add(b.ramp_road_id)
    # every ramp whose far OSM node leads on has its road beyond
    for cw in res.carriageways:
        for rid, ramp in zip(cw.ramp_road_ids, cw.topology.ramps, strict=True):
            chain = next(
                c for c in cw.ramp_set.chains if tuple(c.osm_way_ids) == tuple(ramp.osm_way_ids)
            )
            node = chain.edges[-1][1] if ramp.type == "exit" else chain.edges[0][0]
            more = graph.out_degree(node) if ramp.type == "exit" else graph.in_degree(node)
            if more:
                assert rid in linked, f"{ramp.type} road {rid} ends where OSM continues"


def test_build_cli_several_runs_and_osm_only(runs, tmp_path, capsys):
    d = runs["dirs"]
    out = tmp_path / "both"
    code = main(
        [
            "-q",
            "build",
            str(d["pass1"]),
            str(d["pass2"]),
            str(d["opposite"]),
            "-o",
            str(out),
            "--no-drive",
            "--no-check",
        ]
    )
    assert code == 0
    info = json.loads((out / "build.json").read_text())
    assert [c["source"] for c in info["carriageways"]] == ["lidar", "lidar"]
    assert info["carriageways"][0]["runs"] == ["pass1", "pass2"]
    assert info["carriageways"][0]["disagreements"] == []
    per_run = info["carriageways"][0]["run_self_consistency_rmse_m"]
    assert set(per_run) == {"pass1", "pass2"}
    assert all(v["road_edge_rmse_m"] < 0.3 for v in per_run.values())
    assert len(info["ramps"]) == 4
    text = capsys.readouterr().out
    assert "carriageway 1: lidar (runs pass1, pass2, other direction of 2)" in text
    out = tmp_path / "osm"
    osm = NORD
    code = main(
        [
            "-q",
            "build",
            "--osm",
            str(osm),
            "--bbox",
            ",".join(str(v) for v in NORD_BOX),
            "-o",
            str(out),
            "--no-drive",
            "--no-check",
        ]
    )
    assert code == 0
    info = json.loads((out / "build.json").read_text())
    assert {c["source"] for c in info["carriageways"]} == {"osm"}
    assert info["beyond"]
    for f in ("map.xodr", "map.kml", "map.geojson", "map.png"):
        assert (out / f).is_file()
    # bad input: one line, exit 2
    assert main(["-q", "build", "--bbox", "1,2,3,4", "-o", str(tmp_path / "x")]) == 2
    assert (
        main(["-q", "build", "--osm", str(osm), "--bbox", "5,5,4,4", "-o", str(tmp_path / "y")])
        == 2
    )
    assert not (tmp_path / "y").exists()


def test_osm_only_run_folder(tmp_path):
    """A run folder with only run.toml and an OSM file builds from OSM alone."""
    run = tmp_path / "run"
    run.mkdir()
    (run / "map.osm.gz").write_bytes(NORD.read_bytes())
    (run / "run.toml").write_text(
        '[origin]\nlat = 50.0385\nlon = 11.4935\n[files]\nosm = "map.osm.gz"\n'
        "[area]\nbbox = [11.486, 50.0345, 11.501, 50.0425]\n",
        encoding="utf-8",
    )
    assert main(["-q", "build", str(run), "--no-drive", "--no-check"]) == 0
    net = read_xodr(run / "out" / "map.xodr")
    assert {carriageway_of(r) for r in net.roads} == {1, 2}
    assert "+lat_0=50.0385" in net.header.geo_reference


def test_runs_in_other_frames_fuse_in_the_first_runs_frame(runs, tmp_path):
    """Pass 2 written in UTM (another CRS and origin) fuses with pass 1 (local frame) as
    if it were in pass 1's frame: everything goes to the first run's frame."""
    src = runs["dirs"]["pass2"]
    b = runs["pass2"]
    utm = MappingFrame(b.frame.origin, "+proj=utm +zone=32 +datum=WGS84 +units=m")
    moved = run_in_frame(b, utm)
    out = tmp_path / "pass2-utm"
    out.mkdir()
    traj = moved.trajectory
    np.savetxt(
        out / "trajectory.csv",
        np.column_stack([traj.frame, traj.t, traj.xyz, np.angle(np.exp(1j * traj.yaw))]),
        delimiter=",",
        header="frame,t,x,y,z,yaw",
        comments="",
        fmt=["%d", "%.3f", "%.4f", "%.4f", "%.4f", "%.8f"],
    )
    side = np.where(moved.edge_side > 0, 1, 2)
    np.savetxt(
        out / "road_edges.csv",
        np.column_stack([moved.edges, side]),
        delimiter=",",
        header="x,y,z,side",
        comments="",
        fmt=["%.4f", "%.4f", "%.4f", "%d"],
    )
    (out / "lane_samples.csv").write_bytes((src / "lane_samples.csv").read_bytes())
    (out / "map.osm").write_bytes((src / "map.osm").read_bytes())
    o = utm.origin
    (out / "run.toml").write_text(
        f"[origin]\nlat = {o.lat_deg}\nlon = {o.lon_deg}\nalt = 0.0\n"
        '[frame]\ncrs = "+proj=utm +zone=32 +datum=WGS84 +units=m"\n'
        '[files]\ntrajectory = "trajectory.csv"\nroad_edges = "road_edges.csv"\n'
        'lane_samples = "lane_samples.csv"\nosm = "map.osm"\n',
        encoding="utf-8",
    )
    there = load_run(out)
    assert abs(there.trajectory.xy[0, 0] - b.trajectory.xy[0, 0]) > 1e4
    groups = group_runs([runs["pass1"], run_in_frame(there, runs["pass1"].frame)])
    assert groups.carriageways == ((0, 1),)
    a = fuse_runs([runs["pass1"], b]).run
    c = fuse_runs([runs["pass1"], run_in_frame(there, runs["pass1"].frame)]).run
    assert c.frame is runs["pass1"].frame
    assert np.abs(a.edges - c.edges).max() < 2e-3  # rounding of the written CSV
    assert np.abs(a.lane_samples[:, :2] - c.lane_samples[:, :2]).max() < 2e-3
    # heights: the UTM run's z is absolute, the local frame's relative to its altitude
    assert np.abs(a.edges[:, 2] - c.edges[:, 2]).max() < 2e-3


def test_load_runs_and_osm_equals_loading_each(runs):
    """The runs and the OSM graph of load_runs_and_osm are those of load_run, run_in_frame
    and load_osm (two passes: the graph lies around both trajectories, in the first run's
    frame); read_run_header gives the run's frame, trajectory and OSM file alone."""
    from roadtwin.config import LoadConfig
    from roadtwin.inputs import load_runs_and_osm
    from roadtwin.io import read_run_header

    dirs = [runs["dirs"]["pass1"], runs["dirs"]["pass2"]]
    header = read_run_header(dirs[0])
    assert header.frame == runs["pass1"].frame
    np.testing.assert_array_equal(header.trajectory.xyz, runs["pass1"].trajectory.xyz)
    assert header.osm_path == runs["pass1"].osm_path
    loaded, graph = load_runs_and_osm(dirs, LoadConfig())
    for got, want in zip(loaded, (runs["pass1"], runs["pass2"]), strict=True):
        np.testing.assert_array_equal(got.edges, want.edges)
        np.testing.assert_array_equal(got.lane_samples, want.lane_samples)
    sequential = load_osm(
        runs["pass1"].osm_path,
        frame=runs["pass1"].frame,
        around_xy=np.vstack([runs["pass1"].trajectory.xy, runs["pass2"].trajectory.xy]),
    )
    assert sorted(graph.nodes) == sorted(sequential.nodes)
    assert graph.number_of_edges() == sequential.number_of_edges()
    assert graph.number_of_nodes() > 0
