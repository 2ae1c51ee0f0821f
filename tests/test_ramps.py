"""Ramps from real OSM extracts (tests/data/osm, © OpenStreetMap contributors, ODbL).

A fake mapping run drives along a real motorway way (the OSM carriageway centreline); the
"measured" mainline road is that line offset to its median-side edge with the shared lane
layout. Checked with numbers: candidates (Algorithm 1), directions and sides, Algorithm 2
per tag combination, the highway-class fallback on the Kotka extract (no lane tags), left-
hand candidates on the Melbourne extract, the LiDAR gore deciding the station, and the
attachment of every ramp to the mainline (gap <= 1 cm, heading <= 0.5 deg).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
from shapely.geometry import LineString

from roadtwin.config import PipelineConfig, RampConfig
from roadtwin.fitting import PolylineFrame, fit_parampoly3_chain, resample_polyline, savgol_smooth
from roadtwin.frames import MappingFrame, Origin
from roadtwin.model import (
    CubicPiece,
    CubicProfile,
    LaneSection,
    Road,
    chain_geometry,
    constant_lane,
)
from roadtwin.osm import load_osm
from roadtwin.ramps import (
    build_ramps,
    extract_ramp_chains,
    find_candidates,
    infer_lane_count,
)
from roadtwin.ramps.candidates import _mainline_nodes, _Track

DATA = Path(__file__).parent / "data" / "osm"


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------


def _load(name: str, lat: float, lon: float) -> nx.MultiDiGraph:
    return load_osm(DATA / name, frame=MappingFrame(Origin(lat, lon)), around_xy=None)


def _is_motorway(graph, e) -> bool:
    return graph.edges[e].get("highway") == "motorway"


def _edge_len(graph, e) -> float:
    return float(graph.edges[e]["geometry"].length)


def motorway_path(graph: nx.MultiDiGraph, node, *, back_m: float, ahead_m: float) -> np.ndarray:
    """Polyline along motorway edges through ``node``: ``back_m`` upstream, ``ahead_m``
    downstream (first edge in sorted order at forks)."""
    back, length, n = [], 0.0, node
    while length < back_m:
        ins = sorted(e for e in graph.in_edges(n, keys=True) if _is_motorway(graph, e))
        if not ins or any(ins[0] == b for b in back):
            break
        back.append(ins[0])
        length += _edge_len(graph, ins[0])
        n = ins[0][0]
    ahead, length, n = [], 0.0, node
    while length < ahead_m:
        outs = sorted(e for e in graph.out_edges(n, keys=True) if _is_motorway(graph, e))
        if not outs or any(outs[0] == a for a in ahead):
            break
        ahead.append(outs[0])
        length += _edge_len(graph, outs[0])
        n = outs[0][1]
    edges = back[::-1] + ahead
    parts = [np.asarray(graph.edges[e]["geometry"].coords) for e in edges]
    xy = np.vstack([parts[0], *[p[1:] for p in parts[1:]]])
    return xy[np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > 1e-6])]


def fake_run(centre_xy: np.ndarray, side: str = "right") -> tuple[np.ndarray, Road]:
    """Trajectory (1 m, smoothed OSM centreline) and a mainline road whose reference line
    is the median-side edge: inner shoulder 1 m, three 3.5 m lanes, hard shoulder 2.5 m."""
    dense = savgol_smooth(resample_polyline(centre_xy, 1.0), window=61, polyorder=2)
    frame = PolylineFrame.from_points(dense)
    sign = 1.0 if side == "right" else -1.0
    edge = frame.offset_points(np.full(frame.s.shape, sign * (1.0 + 1.5 * 3.5)))
    geometry = chain_geometry(fit_parampoly3_chain(edge))
    k = -1 if side == "right" else 1
    lanes = (
        constant_lane(k * 1, 1.0, lane_type="shoulder"),
        constant_lane(k * 2, 3.5, mark="broken"),
        constant_lane(k * 3, 3.5, mark="broken"),
        constant_lane(k * 4, 3.5),
        constant_lane(k * 5, 2.5, lane_type="shoulder", mark="none"),
    )
    section = LaneSection(0.0, right=lanes) if side == "right" else LaneSection(0.0, left=lanes)
    return dense, Road("1", geometry, (section,), name="mainline")


def _attach_nodes(graph, kind: str = "motorway_link") -> list:
    """Nodes where a link meets a motorway edge."""
    out = set()
    for u, v, _k, d in graph.edges(keys=True, data=True):
        if d.get("highway") != kind:
            continue
        for n in (u, v):
            inc = list(graph.in_edges(n, keys=True)) + list(graph.out_edges(n, keys=True))
            if any(_is_motorway(graph, e) for e in inc):
                out.add(n)
    return sorted(out)


def _check_attached(ramp, road: Road, side: str) -> None:
    assert ramp.attach_gap_m <= 0.01
    assert ramp.attach_heading_deg <= 0.5
    s_end = 0.0 if ramp.type == "exit" else ramp.road.length
    x, y, h, _ = ramp.road.evaluate(np.array([s_end]))
    s, t = road.project(np.array([[x[0], y[0]]]))
    assert s[0] == pytest.approx(ramp.station_m, abs=0.05)
    source = ramp.mainline_lane_ids[0]
    inner = source + (1 if source < 0 else -1)
    t_inner = road.lane_border_t(np.array([ramp.station_m]), inner)[0]
    assert t[0] == pytest.approx(t_inner, abs=0.01)
    dh = (h[0] - road.heading(np.array([ramp.station_m]))[0] + math.pi) % (2 * math.pi) - math.pi
    assert abs(math.degrees(dh)) <= 0.5
    # 150 m away from the mainline the ramp lies on its side: the traffic side for an
    # outer ramp, the median side for an inner one
    sign = (-1.0 if side == "right" else 1.0) * (1.0 if ramp.side == "outer" else -1.0)
    s_far = min(150.0, ramp.road.length)
    s_far = s_far if ramp.type == "exit" else ramp.road.length - s_far
    _, t_far = road.project(ramp.road.xy(np.array([s_far])))
    assert t_far[0] * sign > 0.0


# ---------------------------------------------------------------------------
# Algorithm 2
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("tags", "lanes", "rule"),
    [
        ({"lanes:forward": "2", "lanes": "4", "highway": "motorway_link"}, 2, "lanes:forward"),
        ({"lanes": "3", "turn:lanes": "left|right", "highway": "motorway_link"}, 3, "lanes"),
        ({"lanes": ["2", "3"], "highway": "trunk_link"}, 2, "lanes"),
        ({"lanes": "x", "turn:lanes": "left|through|through;right"}, 3, "turn:lanes"),
        ({"lanes": "0", "turn:lanes": "through|right", "highway": "primary"}, 2, "turn:lanes"),
        ({"lanes:forward": "1;2"}, 1, "lanes:forward"),
        ({"highway": "motorway_link"}, 1, "highway class"),
        ({"highway": "motorway"}, 3, "highway class"),
        ({"highway": "trunk_link"}, 1, "highway class"),
        ({"highway": "primary_link"}, 1, "highway class"),
        ({"highway": "secondary_link"}, 1, "highway class"),
        ({"lanes": float("nan"), "highway": "tertiary_link"}, 1, "highway class"),
        ({}, 1, "highway class"),
    ],
)
def test_algorithm2_priority(tags, lanes, rule):
    assert infer_lane_count(tags) == (lanes, rule)


@pytest.mark.parametrize(
    ("highway", "osm", "paper"),
    [("motorway_link", 1, 3), ("trunk_link", 1, 2), ("primary_link", 1, 2), ("motorway", 3, 3)],
)
def test_untagged_link_lanes_osm_convention_vs_paper(highway, osm, paper):
    """OSM's convention: an untagged *_link is one lane; the paper's class default is kept
    for --method paper (PipelineConfig.with_method)."""
    assert infer_lane_count({"highway": highway}) == (osm, "highway class")
    assert infer_lane_count({"highway": highway}, link_rule="paper") == (paper, "highway class")
    cfg = PipelineConfig().with_method("paper")
    assert (cfg.mainline.method, cfg.ramps.link_lane_rule) == ("paper", "paper")
    assert PipelineConfig().ramps.link_lane_rule == "osm"


# ---------------------------------------------------------------------------
# West Oakland (I-880): candidates, entry, direction check
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def oakland():
    graph = _load("west-oakland-i880.osm.bz2", 37.81, -122.297)
    # I-880 carriageway through the node where the link of way 28413786 joins it
    node = next(
        v
        for u, v, d in graph.edges(data=True)
        if d.get("highway") == "motorway_link" and d.get("osmid") == 28413786
    )
    centre = motorway_path(graph, node, back_m=900.0, ahead_m=900.0)
    traj, road = fake_run(centre)
    return graph, traj, road


def test_candidates_algorithm1(oakland):
    graph, traj, _ = oakland
    cands = find_candidates(graph, traj)
    assert len(cands) >= 3
    traj_line = LineString(traj)
    for c in cands:
        assert c.highway.endswith("_link")
        geom = graph.edges[c.u, c.v, c.key]["geometry"]
        assert geom.distance(traj_line) == pytest.approx(c.distance_m, abs=1e-6)
        assert c.distance_m <= RampConfig().candidate_distance_m
    # every link edge within d_r is a candidate, and only those
    near = {
        (u, v, k)
        for u, v, k, d in graph.edges(keys=True, data=True)
        if "_link" in str(d.get("highway")) and d["geometry"].distance(traj_line) <= 30.0
    }
    assert {(c.u, c.v, c.key) for c in cands} == near
    wider = find_candidates(graph, traj, config=RampConfig(candidate_distance_m=200.0))
    assert len(wider) > len(cands)


def test_oakland_entry_found_and_attached(oakland):
    graph, traj, road = oakland
    result = build_ramps(graph, road, trajectory_xy=traj)
    by_way = {w: r for r in result.ramps for w in r.osm_way_ids}
    assert 28413786 in by_way
    ramp = by_way[28413786]
    assert ramp.type == "entry"
    assert ramp.type_geometry == "entry"
    # its OSM lane tags decide (no mainline lane change on this fake mainline)
    assert ramp.lane_rule in ("lanes:forward", "lanes", "turn:lanes")
    assert (
        ramp.lanes
        == infer_lane_count(
            graph.edges[
                next(
                    (u, v, k)
                    for u, v, k, d in graph.edges(keys=True, data=True)
                    if d.get("osmid") == 28413786
                )
            ]
        )[0]
    )
    assert ramp.station_source == "osm"
    for r in result.ramps:
        _check_attached(r, road, "right")
    # candidates not used are all listed with a reason
    used = {e for ch in result.chains for e in ch.edges}
    listed = {c for c in result.candidates if (c.u, c.v, c.key) not in used}
    assert len(result.rejected) >= len(listed)


def test_direction_check_rejects_the_opposite_direction(oakland):
    graph, traj, road = oakland
    forward = build_ramps(graph, road, trajectory_xy=traj)
    assert forward.ramps
    # drive the same line the other way: the carriageway's nodes no longer match the
    # driven direction, so none of its links may be taken as ramps of this drive
    chains, rejected = extract_ramp_chains(graph, traj[::-1])
    fwd_ways = {w for r in forward.ramps for w in r.osm_way_ids}
    assert not fwd_ways & {w for c in chains for w in c.osm_way_ids}
    assert rejected


def test_ramp_side_outer_or_median(oakland):
    """A link on the traffic side of the drive is an outer ramp; the same link seen from a
    left-hand-traffic drive lies on the median side: an inner ramp (a left exit/entry), not
    rejected."""
    graph, traj, _ = oakland
    chains_r, _ = extract_ramp_chains(graph, traj, traffic_side="right")
    chains_l, _ = extract_ramp_chains(graph, traj, traffic_side="left")
    side_r = {w: c.side for c in chains_r for w in c.osm_way_ids}
    side_l = {w: c.side for c in chains_l for w in c.osm_way_ids}
    assert side_r[28413786] == "outer"
    assert side_l[28413786] == "inner"  # it lies right of the drive


# ---------------------------------------------------------------------------
# Kotka (E18): no lane tags on some links -> the class fallback (1 lane), reported
# ---------------------------------------------------------------------------


def test_kotka_fallback_reported():
    graph = _load("kotka-e18.osm.pbf", 60.528, 26.95)
    found = []
    for node in _attach_nodes(graph):
        centre = motorway_path(graph, node, back_m=700.0, ahead_m=700.0)
        if LineString(centre).length < 600.0:
            continue
        traj, road = fake_run(centre)
        result = build_ramps(graph, road, trajectory_xy=traj)
        for r in result.ramps:
            _check_attached(r, road, "right")
        found.extend((r, result) for r in result.ramps)
    assert found
    fallback = [(r, res) for r, res in found if r.osm_lane_rule == "highway class"]
    assert fallback, "Kotka has links without lanes tags"
    for r, res in fallback:
        assert r.lanes == 1  # an untagged motorway_link: OSM's one-lane convention
        assert r.lane_rule == "highway class"
        assert any("highway class" in w for w in r.warnings)
        assert any("highway class" in w for w in res.warnings)
    tagged = [r for r, _ in found if r.osm_lane_rule == "lanes"]
    assert tagged
    assert all(r.lanes >= 1 for r in tagged)


# ---------------------------------------------------------------------------
# Melbourne: left-hand traffic
# ---------------------------------------------------------------------------


def test_melbourne_left_hand_candidates():
    graph = _load("melbourne-lht.osm.pbf", -37.63, 145.37)
    n_chains = n_runs = n_outer = 0
    for node in _attach_nodes(graph):
        centre = motorway_path(graph, node, back_m=600.0, ahead_m=600.0)
        if LineString(centre).length < 400.0 or n_runs == 3:
            continue
        n_runs += 1
        traj, road = fake_run(centre, side="left")
        cands = find_candidates(graph, traj)
        assert cands
        chains, _ = extract_ramp_chains(graph, traj, traffic_side="left", candidates=cands)
        result = build_ramps(graph, road, trajectory_xy=traj, traffic_side="left")
        for r in result.ramps:
            assert r.road.lane_sections[0].left
            assert not r.road.lane_sections[0].right
            _check_attached(r, road, "left")
        # left-hand traffic: they are outer ramps; seen as right-hand traffic the same
        # links lie on the median side (branches drawn over the carriageway's nodes come
        # on both sides: the LiDAR decides theirs)
        chains = [c for c in chains if not c.shared]
        chains_rht, _ = extract_ramp_chains(graph, traj, traffic_side="right", candidates=cands)
        sides = {c.edges: c.side for c in chains_rht if not c.shared}
        flip = {"outer": "inner", "inner": "outer"}
        assert all(sides[c.edges] == flip[c.side] for c in chains if c.edges in sides)
        n_outer += sum(c.side == "outer" for c in chains)
        n_chains += len(chains)
    assert n_chains >= 2
    assert n_outer >= 2


# ---------------------------------------------------------------------------
# LiDAR evidence: a measured deceleration lane decides the station and lane count
# ---------------------------------------------------------------------------


def _gore_scene():
    """A mainline with a measured exit gore at s=520 and an OSM exit leaving at s~470."""
    x = np.linspace(0.0, 1200.0, 601)
    centre = np.stack([x, 0.002 * (x - 600.0) ** 2 / 10.0], axis=1)
    traj, road = fake_run(centre)
    # add a 3.5 m deceleration lane from s=300 (60 m taper) to the gore at s=520
    base = road.lane_sections[0].right
    decel = constant_lane(-5, 3.5)
    taper = CubicProfile(
        (CubicPiece(0.0, 0.0, 0.0, 3 * 3.5 / 60**2, -2 * 3.5 / 60**3), CubicPiece(60.0, 3.5))
    )
    decel = type(decel)(-5, "driving", taper, decel.road_marks)
    hard = constant_lane(-6, 2.5, lane_type="shoulder", mark="none")
    sections = (
        LaneSection(0.0, right=base),
        LaneSection(300.0, right=(*base[:4], decel, hard)),
        LaneSection(520.0, right=base),
    )
    road = Road("1", road.geometry, sections, name="mainline")
    # an OSM graph: the carriageway centreline and one 2-lane exit leaving at s~470
    graph = nx.MultiDiGraph(crs="local")
    frame = PolylineFrame.from_points(traj)
    s_nodes = [0.0, 470.0, frame.length]
    for i, s in enumerate(s_nodes):
        p, _ = frame.at(np.array([s]))
        graph.add_node(i, x=float(p[0, 0]), y=float(p[0, 1]))
    for i in range(2):
        s = np.linspace(s_nodes[i], s_nodes[i + 1], 30)
        p, _ = frame.at(s)
        graph.add_edge(i, i + 1, highway="motorway", osmid=1, geometry=LineString(p))
    s_ramp = np.linspace(470.0, 800.0, 15)
    t_ramp = -0.0004 * (s_ramp - 470.0) ** 2
    p, tg = frame.at(s_ramp)
    normal = np.stack([-tg[:, 1], tg[:, 0]], axis=1)
    ramp_xy = p + t_ramp[:, None] * normal
    graph.add_node(9, x=float(ramp_xy[-1, 0]), y=float(ramp_xy[-1, 1]))
    graph.add_edge(1, 9, highway="motorway_link", lanes="2", osmid=2, geometry=LineString(ramp_xy))
    return traj, road, sections, graph


def test_measured_gore_decides_station():
    traj, road, sections, graph = _gore_scene()
    result = build_ramps(graph, road, trajectory_xy=traj)
    assert len(result.ramps) == 1
    ramp = result.ramps[0]
    assert ramp.type == "exit"
    assert ramp.station_source == "lidar gore"
    assert ramp.station_m == pytest.approx(520.0)
    assert ramp.lanes == 1
    assert ramp.lane_rule == "mainline lane change"
    assert ramp.osm_lanes == 2
    assert ramp.mainline_lane_ids == (-5,)
    assert any("mainline lane change says 1" in w for w in ramp.warnings)
    _check_attached(ramp, road, "right")
    # mainline layout: inner shoulder opening from zero width, the driving lane taking the
    # deceleration lane's width at the gore, the hard shoulder the mainline's (2.5 m)
    lanes = ramp.road.lane_sections[0].right
    assert [(x.id, x.type) for x in lanes] == [(-1, "shoulder"), (-2, "driving"), (-3, "shoulder")]
    assert [x.road_marks[0].type for x in lanes] == ["solid", "solid", "none"]
    w0 = [float(x.width.value(np.array([0.0]))[0]) for x in lanes]
    assert w0 == pytest.approx([0.0, 3.5, 2.5], abs=1e-3)
    assert ramp.shoulder_lane_id == -6
    far = np.linspace(0.0, ramp.road.length, 200)
    for x in lanes:
        assert float(np.min(x.width.value(far))) >= -1e-9
    cfg = RampConfig()
    w_far = [float(x.width.value(np.array([ramp.road.length]))[0]) for x in lanes]
    assert w_far == pytest.approx(
        [cfg.inner_shoulder_width_m, cfg.lane_width_m, cfg.hard_shoulder_width_m], abs=1e-3
    )
    # without the LiDAR evidence the OSM attachment and tags decide
    plain = Road("1", road.geometry, (sections[0],), name="mainline")
    osm_only = build_ramps(graph, plain, trajectory_xy=traj).ramps[0]
    assert osm_only.station_source == "osm"
    # the OSM node at trajectory station 470 lies at ~469 m on the offset reference line
    assert osm_only.station_m == pytest.approx(470.0, abs=3.0)
    assert (osm_only.lanes, osm_only.lane_rule) == (2, "lanes")
    _check_attached(osm_only, plain, "right")


# ---------------------------------------------------------------------------
# measured points past the gore shape the ramp and give its widths
# ---------------------------------------------------------------------------


def _true_ramp_points(mainline: Road, *, gore_m: float = 520.0, seed: int = 3):
    """Points the LiDAR would see on an exit leaving the outer border of through lane -4
    at ``gore_m`` with ``d(a) = 0.0004 a^2`` (6.8 m at a = 130 m; inner shoulder 0.6 m
    opening over the default taper, lane 3.5 m, hard shoulder 2.2 m), seen up to 130 m
    past the gore with 3 cm noise and 5 % outliers. Returns (edges, lanes, true reference
    line xy)."""
    rng = np.random.default_rng(seed)
    taper = RampConfig().shoulder_taper_m
    a = np.arange(5.0, 130.0, 0.5)
    s = gore_m + a
    t_border = mainline.lane_border_t(s, -4)
    d = 0.0004 * a**2
    xg = np.clip(a / taper, 0.0, 1.0)
    w_in = 0.6 * xg * xg * (3.0 - 2.0 * xg)

    def pts(tau):
        return mainline.to_xy(s, t_border - tau - rng.normal(0.0, 0.03, a.size)).reshape(-1, 2)

    edges = np.vstack([pts(d), pts(d + w_in + 3.5 + 2.2)])
    lanes = np.vstack([pts(d + w_in), pts(d + w_in + 3.5)])
    box_lo, box_hi = edges.min(axis=0), edges.max(axis=0)
    edges = np.vstack([edges, rng.uniform(box_lo, box_hi, (len(edges) // 20, 2))])
    lanes = np.vstack([lanes, rng.uniform(box_lo, box_hi, (len(lanes) // 20, 2))])
    return edges, lanes, mainline.to_xy(s, t_border - d).reshape(-1, 2)


def test_ramp_evidence_shapes_first_part_and_widths():
    traj, road, _sections, graph = _gore_scene()
    plain = build_ramps(graph, road, trajectory_xy=traj).ramps[0]
    assert plain.evidence is None
    edges, lanes, true_ref = _true_ramp_points(road)
    # OSM alone is metres off the true ramp over its first 130 m
    _, t0 = plain.road.project(true_ref)
    assert float(np.max(np.abs(t0))) > 2.0
    fitted = build_ramps(graph, road, trajectory_xy=traj, edge_xy=edges, lane_xy=lanes).ramps[0]
    ev = fitted.evidence
    assert ev is not None
    assert ev.points > 900  # of 1000 true points (a few near the gore are the mainline's)
    assert ev.rmse_m < 0.05
    assert ev.span_m == pytest.approx(130.5, abs=1.5)  # arc length along the ramp
    assert ev.widths == pytest.approx((0.6, 3.5, 2.2), abs=0.03)
    # the reference line now follows the measured ramp within 3 cm (measured: 7 mm) ...
    _, t1 = fitted.road.project(true_ref)
    assert float(np.max(np.abs(t1))) < 0.03
    # ... and still attaches exactly at the gore
    _check_attached(fitted, road, "right")
    lanes_ = fitted.road.lane_sections[0].right
    s_far = np.array([fitted.road.length])
    assert [float(x.width.value(s_far)[0]) for x in lanes_] == pytest.approx(
        [0.6, 3.5, 2.2], abs=0.03
    )
    far = np.linspace(0.0, fitted.road.length, 400)
    assert all(float(np.min(x.width.value(far))) >= -1e-9 for x in lanes_)


def test_ramp_evidence_absent_or_disabled():
    traj, road, _sections, graph = _gore_scene()
    plain = build_ramps(graph, road, trajectory_xy=traj).ramps[0]
    empty = np.zeros((0, 3))
    none = build_ramps(graph, road, trajectory_xy=traj, edge_xy=empty, lane_xy=empty).ramps[0]
    assert none.evidence is None
    s = np.linspace(0.0, plain.road.length, 50)
    assert np.max(np.hypot(*(none.road.xy(s) - plain.road.xy(s)).T)) < 1e-9
    edges, lanes, _ = _true_ramp_points(road)
    off = build_ramps(
        graph,
        road,
        trajectory_xy=traj,
        edge_xy=edges,
        lane_xy=lanes,
        config=RampConfig(use_evidence=False),
    ).ramps[0]
    assert off.evidence is None
    # default widths where nothing was measured (AASHTO mid-range)
    w = [
        float(x.width.value(np.array([off.road.length]))[0])
        for x in off.road.lane_sections[0].right
    ]
    assert w == pytest.approx([0.9, 3.5, 2.4], abs=1e-6)


def test_zero_width_mainline_shoulder_is_not_continued():
    """A mainline hard shoulder that closes to zero width at the gore is not linked to
    the ramp's (OpenDRIVE: no link at a zero-width end); the ramp's opens from zero."""
    from roadtwin.model import Lane
    from roadtwin.ramps import width_transition

    traj, road, sections, graph = _gore_scene()
    gore = sections[1]
    closing = Lane(-6, "shoulder", CubicProfile(width_transition(2.5, 0.0, 220.0)))
    sec = LaneSection(gore.s0, right=(*gore.right[:5], closing))
    road = Road("1", road.geometry, (sections[0], sec, sections[2]), name="mainline")
    ramp = build_ramps(graph, road, trajectory_xy=traj).ramps[0]
    assert ramp.station_source == "lidar gore"
    assert ramp.shoulder_lane_id is None
    lanes = ramp.road.lane_sections[0].right
    w0 = [float(x.width.value(np.array([0.0]))[0]) for x in lanes]
    assert w0 == pytest.approx([0.0, 3.5, 0.0], abs=1e-6)


# ---------------------------------------------------------------------------
# a flyover: another motorway crosses the carriageway and joins it as a link
# ---------------------------------------------------------------------------


def _straight_motorway(node_x: float) -> tuple[nx.MultiDiGraph, np.ndarray]:
    """A 1 km straight motorway along x (way 1, nodes 0, 1, 2 at x = 0, ``node_x``,
    1000 m) and a drive along it."""
    graph = nx.MultiDiGraph(crs="local")
    traj = np.stack([np.linspace(0.0, 1000.0, 1001), np.zeros(1001)], axis=1)
    for i, x in enumerate((0.0, node_x, 1000.0)):
        graph.add_node(i, x=x, y=0.0)
    for a, b in ((0, 1), (1, 2)):
        xa, xb = graph.nodes[a]["x"], graph.nodes[b]["x"]
        graph.add_edge(a, b, highway="motorway", osmid=1, geometry=LineString([(xa, 0), (xb, 0)]))
    return graph, traj


def _flyover_graph():
    """A straight carriageway (x east, RHT) and a motorway branch that comes from the
    median side, crosses over the carriageway and ends 5 m off it on the traffic side,
    aligned with it, at x=400, where a 90 m link goes on to join it at x=490."""
    graph, traj = _straight_motorway(490.0)
    # the branch: from 60 m left of the carriageway (the median side), across it
    xs = np.linspace(150.0, 400.0, 26)
    ys = 60.0 - 65.0 * np.clip((xs - 150.0) / 200.0, 0.0, 1.0)
    graph.add_node(10, x=150.0, y=60.0)
    graph.add_node(11, x=400.0, y=-5.0)
    graph.add_edge(10, 11, highway="motorway", osmid=7, geometry=LineString(np.c_[xs, ys]))
    xl = np.linspace(400.0, 490.0, 10)
    graph.add_edge(11, 1, highway="motorway_link", osmid=8,
                   geometry=LineString(np.c_[xl, -5.0 + 5.0 * (xl - 400.0) / 90.0]))  # fmt: skip
    return graph, traj


def test_flyover_joining_as_a_link_is_one_outer_entry():
    graph, traj = _flyover_graph()
    chains, rejected = extract_ramp_chains(graph, traj)
    # the branch's last node lies near the drive with its heading, but the carriageway
    # does not run through it: the link is no part of the carriageway
    assert not any("both ends" in why for _, why in rejected)
    assert len(chains) == 1
    chain = chains[0]
    assert chain.type == "entry"
    assert chain.osm_way_ids == (7, 8)  # the branch and its link: one ramp
    assert chain.attach_node == 1
    # it joins on the traffic side (right), where it first clears the carriageway line,
    # though most of it lies on the median side
    assert chain.side == "outer"
    chains_lht, _ = extract_ramp_chains(graph, traj, traffic_side="left")
    assert chains_lht[0].side == "inner"


def test_an_exit_onto_a_frontage_road_is_an_exit():
    """melbourne-1019 (seed 11): a tertiary frontage road runs 15 m beside the motorway
    and the exit's link ends on it. Its nodes lay near the drive with the driven heading,
    so the link had "both ends on the driven carriageway" and the exit was missed (its lane
    was closed by a taper instead)."""
    graph, traj = _straight_motorway(300.0)
    # the frontage road, 15 m right of the carriageway, same direction
    for i, x in enumerate((0.0, 450.0, 1000.0)):
        graph.add_node(20 + i, x=x, y=-15.0)
    for a, b in ((20, 21), (21, 22)):
        xa, xb = graph.nodes[a]["x"], graph.nodes[b]["x"]
        graph.add_edge(a, b, highway="tertiary", osmid=5,
                       geometry=LineString([(xa, -15.0), (xb, -15.0)]))  # fmt: skip
    xl = np.linspace(300.0, 450.0, 16)
    graph.add_edge(1, 21, highway="motorway_link", osmid=9,
                   geometry=LineString(np.c_[xl, -15.0 * (xl - 300.0) / 150.0]))  # fmt: skip
    chains, rejected = extract_ramp_chains(graph, traj)
    assert not any("both ends" in why for _, why in rejected)
    assert [(c.type, c.osm_way_ids, c.attach_node, c.side) for c in chains] == [
        ("exit", (9,), 1, "outer")
    ]
    # without a motorway or trunk along the drive, a road of any class is its carriageway
    graph.remove_edges_from([(0, 1, 0), (1, 2, 0)])
    on_road = _mainline_nodes(graph, _Track(traj + np.array([0.0, -15.0])), RampConfig())
    assert 21 in on_road


def test_ramp_evidence_ignores_a_crossing_road():
    """A flyover's edges and markings crossing the measured ramp at 60 deg are another
    road's: the reference line still follows the measured ramp."""
    traj, road, _sections, graph = _gore_scene()
    edges, lanes, true_ref = _true_ramp_points(road)
    # a 20 m wide road crossing the ramp's measured stretch at a = 60 m, at 60 deg
    s0 = 520.0 + 60.0
    c, tg = PolylineFrame.from_points(traj).at(np.array([s0]))
    h = math.atan2(tg[0, 1], tg[0, 0]) + math.radians(60.0)
    along = np.arange(-40.0, 40.0, 0.25)
    u = np.array([math.cos(h), math.sin(h)])
    n = np.array([-u[1], u[0]])
    cross = [c[0] - 9.0 * n + along[:, None] * u, c[0] + 9.0 * n + along[:, None] * u]
    marks = [c[0] + k * n + along[::4, None] * u for k in (-5.0, 0.0, 5.0)]
    fitted = build_ramps(
        graph,
        road,
        trajectory_xy=traj,
        edge_xy=np.vstack([edges, *cross]),
        lane_xy=np.vstack([lanes, *marks]),
    ).ramps[0]
    ev = fitted.evidence
    assert ev is not None
    assert ev.span_m == pytest.approx(130.5, abs=1.5)
    assert ev.widths == pytest.approx((0.6, 3.5, 2.2), abs=0.05)
    _, t1 = fitted.road.project(true_ref)
    assert float(np.max(np.abs(t1))) < 0.05


def _parallel_ramp_scene(osm_inward_m: float, *, seed: int = 3):
    """An entry-style parallel ramp: it leaves the border of through lane -4 at the gore
    (s=520), lies 4 m out after 60 m and runs parallel, measured for 200 m (edges and
    markings, 3 cm noise). OSM draws its centre ``osm_inward_m`` towards the mainline,
    leaving at s=470, and bends away beyond s=720. Returns (traj, road, graph, edges,
    lanes, true reference line xy)."""
    traj, road, _sections, _graph = _gore_scene()
    frame = PolylineFrame.from_points(traj)
    rng = np.random.default_rng(seed)
    a = np.arange(5.0, 200.0, 0.5)
    s = 520.0 + a
    x = np.clip(a / 60.0, 0.0, 1.0)
    d = 4.0 * x * x * (3.0 - 2.0 * x)
    t_border = road.lane_border_t(s, -4)

    def pts(tau):
        return road.to_xy(s, t_border - tau - rng.normal(0.0, 0.03, a.size)).reshape(-1, 2)

    xg = np.clip(a / RampConfig().shoulder_taper_m, 0.0, 1.0)
    w_in = 0.6 * xg * xg * (3.0 - 2.0 * xg)  # the inner shoulder opens past the gore
    edges = np.vstack([pts(d), pts(d + w_in + 3.5 + 2.2)])
    lanes = np.vstack([pts(d + w_in), pts(d + w_in + 3.5)])
    graph = nx.MultiDiGraph(crs="local")
    s_nodes = [0.0, 470.0, frame.length]
    for i, sn in enumerate(s_nodes):
        p, _ = frame.at(np.array([sn]))
        graph.add_node(i, x=float(p[0, 0]), y=float(p[0, 1]))
    for i in range(2):
        p, _ = frame.at(np.linspace(s_nodes[i], s_nodes[i + 1], 30))
        graph.add_edge(i, i + 1, highway="motorway", osmid=1, geometry=LineString(p))
    s_osm = np.linspace(470.0, 900.0, 40)
    x = np.clip((s_osm - 470.0) / 100.0, 0.0, 1.0)
    t_osm = (
        road.lane_border_t(s_osm, -4)
        - (4.0 + 0.6 + 1.75 - osm_inward_m) * x * x * (3.0 - 2.0 * x)
        - 0.0006 * np.clip(s_osm - 720.0, 0.0, None) ** 2
    )
    osm_xy = road.to_xy(s_osm, t_osm).reshape(-1, 2)
    graph.add_node(9, x=float(osm_xy[-1, 0]), y=float(osm_xy[-1, 1]))
    graph.add_edge(1, 9, highway="motorway_link", lanes="1", osmid=2, geometry=LineString(osm_xy))
    return traj, road, graph, edges, lanes, road.to_xy(s, t_border - d).reshape(-1, 2)


@pytest.mark.parametrize("osm_inward_m", [2.0, 5.0])
def test_ramp_evidence_follows_a_parallel_ramp_osm_draws_inside(osm_inward_m):
    """OSM drawn metres inside a ramp that runs parallel to the mainline must not swing
    the fit off the measured lines beyond each window (it did by 3.7-9.4 m): boundary
    lines matched once keep their boundary."""
    traj, road, graph, edges, lanes, true_ref = _parallel_ramp_scene(osm_inward_m)
    ramp = build_ramps(graph, road, trajectory_xy=traj, edge_xy=edges, lane_xy=lanes).ramps[0]
    ev = ramp.evidence
    assert ev is not None
    assert ev.span_m == pytest.approx(200.0, abs=2.0)
    assert ev.widths == pytest.approx((0.6, 3.5, 2.2), abs=0.05)
    _, t = ramp.road.project(true_ref)
    # measured: max 0.24 m, in the S-bend of the first 30 m (the spline's knots are 15 m
    # apart); beyond it p95 0.05 m
    assert float(np.max(np.abs(t))) < 0.4
    assert float(np.percentile(np.abs(t[50:]), 95)) < 0.1


# ---------------------------------------------------------------------------
# Melbourne: branches drawn over the carriageway's own nodes
# ---------------------------------------------------------------------------


def test_branches_drawn_over_the_carriageways_nodes_are_built_where_the_lidar_saw_them(
    tmp_path,
):
    """In the Melbourne extract an inner exit (ways 327/328) and, on the other carriageway,
    a 2-lane entry (ways 408/409) share the carriageway's nodes for hundreds of metres: no
    geometry of their own, no side. They are ramps where a measured gore on one side shows
    lanes leaving or joining (melbourne-921: 2 of 3 ramps were found; the inner exit's two
    lanes ended at full width, a dead end for a car). A simulated run of chain 921: every
    true ramp is built, of its type, on its side, within 30 m, and nothing else."""
    import json

    from roadtwin import build_map, load_osm, load_run
    from roadtwin.simulate import simulate_osm_run

    run_dir = simulate_osm_run(DATA / "melbourne-lht.osm.pbf", tmp_path / "run", chain=921, seed=2)
    run = load_run(run_dir)
    graph = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    built = build_map(run, graph).ramps
    truth = json.loads((Path(run_dir) / "truth.json").read_text())["ramps"]
    assert len(built) == len(truth) == 3
    for t in truth:
        near = [r for r in built if r.type == t["type"] and r.side == t["side"]]
        assert near, t
        assert min(abs(r.station_m - t["station_m"]) for r in near) < 30.0, t
    shared = [r for r in built if 327 in r.osm_way_ids or 328 in r.osm_way_ids]
    assert len(shared) == 1
    exit_ = shared[0]
    assert (exit_.type, exit_.side, exit_.lanes) == ("exit", "inner", 2)
    assert exit_.station_source == "lidar gore"


def test_a_reference_line_folded_onto_the_mainline_border_is_refused():
    # 600 m of ramp whose points alternate between the OSM line and the carriageway's
    # border 6 m away (a clamp that flips sign): 7 km of polyline, refused before the
    # clothoid fit builds a (length / 0.5 m) x (length / 15 m) basis (24 GB on a real one)
    from roadtwin._errors import FitError
    from roadtwin.ramps.road import _refuse_folded

    s = np.arange(0.0, 600.0, 0.5)
    centre = np.column_stack([s, np.full(s.size, 10.0)])
    zigzag = centre.copy()
    zigzag[::2, 1] -= 6.0
    with pytest.raises(FitError, match="folds"):
        _refuse_folded(zigzag, centre, "7")
    # a reference line offset from its centre line, even round a tight loop, is kept
    angle = np.linspace(0.0, 1.5 * np.pi, 400)
    loop = np.column_stack([40.0 * np.cos(angle), 40.0 * np.sin(angle)])
    inner = np.column_stack([35.0 * np.cos(angle), 35.0 * np.sin(angle)])
    _refuse_folded(inner, loop, "7")
    _refuse_folded(centre + np.array([0.0, 5.0]), centre, "7")


def test_an_unmeasured_gore_is_where_the_mainline_lane_ends():
    """krems-46762523-s1, noisier sensor (seed 21): the edge step at an entry's gore was not
    seen, so no gore was measured; the ramp went to its OSM node 21 m upstream of where
    the acceleration lane begins at full width, and the ramp's lane was linked into a
    through lane while the acceleration lane began from nothing (esmini: "Lane id -5 not
    available"). An attachment that matches no measured gore goes to a driving lane
    that ends (begins) at full width without a link within 75 m."""
    traj, road, _sections, graph = _gore_scene()
    ramp = build_ramps(graph, road, trajectory_xy=traj, gores=()).ramps[0]
    assert ramp.station_source == "lidar gore"
    assert ramp.station_m == pytest.approx(520.0)
    assert ramp.mainline_lane_ids == (-5,)
    # a lane ending 110 m from the OSM node is another one's gore: OSM decides
    moved = replace(
        road, lane_sections=(*road.lane_sections[:2], replace(road.lane_sections[2], s0=580.0))
    )
    far = build_ramps(graph, moved, trajectory_xy=traj, gores=()).ramps[0]
    assert far.station_source == "osm"
    assert far.station_m == pytest.approx(470.0, abs=3.0)


def test_a_ramp_fit_that_turns_back_against_its_osm_line_is_not_used():
    """Town06 exit 5011 (every seed): its OSM line bends 70 degrees within metres, and the
    clothoid spline, which compares each OSM point with the curve at the same arc length,
    looped round 25 m across (ramp centre RMSE 9.7 m; esmini drove the loop). At a fork of
    melbourne-1226 the gore lay 8.5 m beside the branch's OSM line: a U-turn 30 m across.
    Such a fit is detected and the OSM line is used as drawn; a fit beside its line, and a
    loop ramp's fit along its looping OSM line, are kept."""
    from roadtwin.ramps.road import _turn_back_start

    x = np.linspace(0.0, 60.0, 61)
    line = np.c_[x, -20.0 - 0.2 * x]
    theta = np.linspace(0.0, np.pi, 50)  # a half circle of 15 m radius, then back
    u_turn = np.r_[np.c_[15.0 * np.sin(theta), -15.0 + 15.0 * np.cos(theta)],
                   np.c_[-np.linspace(1.0, 10.0, 10), np.full(10, -30.0)]]  # fmt: skip
    assert _turn_back_start(u_turn, line) is not None
    assert _turn_back_start(line + np.array([0.0, 1.5]), line) is None
    # a 270 degree loop ramp fitted 1 m inside its OSM line
    phi = np.linspace(0.0, 1.5 * np.pi, 120)
    loop = np.c_[40.0 * np.sin(phi), 40.0 - 40.0 * np.cos(phi)]
    fitted = np.c_[39.0 * np.sin(phi), 40.0 - 39.0 * np.cos(phi)]
    assert _turn_back_start(fitted, loop) is None


def test_a_fit_turning_back_far_from_the_gore_ends_before_it():
    """melbourne-408-lane1-s21 with a noisier sensor (seed offset 80): an entry's OSM line
    turns 95 degrees within 10 m where it meets the local roads, 371 m from the gore; the
    fit turned back there, and the OSM line used as drawn instead kept that 4 m radius
    hook, where esmini's car jumped 4.3 m. Where the knot lies is known: the ramp ends
    before it (``_KNOT_KEEP_M`` from the gore or more), else the OSM line is used."""
    from roadtwin.ramps.road import _KNOT_KEEP_M, _turn_back_start

    x = np.linspace(0.0, 400.0, 401)
    line = np.c_[x, np.zeros(x.size)]
    theta = np.linspace(0.0, np.pi, 50)
    hook = np.r_[np.c_[x[:301], np.zeros(301)],
                 np.c_[300.0 + 15.0 * np.sin(theta), 15.0 - 15.0 * np.cos(theta)][1:],
                 np.c_[300.0 - np.linspace(1.0, 30.0, 30), np.full(30, 30.0)]]  # fmt: skip
    knot = _turn_back_start(hook, line)
    assert knot is not None
    assert knot >= _KNOT_KEEP_M
    assert 300.0 < knot < 300.0 + 15.0 * np.pi  # in the half circle
    assert _turn_back_start(line + np.array([0.0, 1.5]), line) is None


def _loop_back_graph(leave_x: float, way: int = 5) -> tuple[nx.MultiDiGraph, np.ndarray]:
    """A straight 1 km carriageway (x east, nodes at 0, 300, ``leave_x``, 1000 m) and a
    link that leaves it at ``leave_x``, swings out 80 m to the right and back west, and
    joins it at 300 m with the driven heading."""
    graph = nx.MultiDiGraph(crs="local")
    traj = np.stack([np.linspace(0.0, 1000.0, 1001), np.zeros(1001)], axis=1)
    xs = (0.0, 300.0, leave_x, 1000.0)
    for i, x in enumerate(xs):
        graph.add_node(i, x=x, y=0.0)
    for a in range(3):
        graph.add_edge(a, a + 1, highway="trunk", osmid=1,
                       geometry=LineString([(xs[a], 0.0), (xs[a + 1], 0.0)]))  # fmt: skip
    path = [(leave_x, 0.0), (leave_x + 10.0, -30.0), (leave_x - 80.0, -80.0), (200.0, -80.0),
            (200.0, -40.0), (250.0, -8.0), (300.0, 0.0)]  # fmt: skip
    graph.add_edge(2, 1, highway="trunk", osmid=way, geometry=LineString(path))
    return graph, traj


def test_a_branch_leaving_at_the_runs_end_is_an_entry_where_it_joins():
    """krems chain 30799129: a two-lane trunk joins the driven one at 337 m and left it
    9 m before the run's end (the route loops). Both its ends lie on the driven
    carriageway, so it was rejected as a bypass and the entry was missing from every
    build. An end at the run's start or end is where the map ends: the branch is a ramp
    at its other end. One leaving in the middle of the run is still a bypass."""
    graph, traj = _loop_back_graph(975.0)
    chains, rejected = extract_ramp_chains(graph, traj)
    assert [c.type for c in chains] == ["entry"]
    assert chains[0].attach_node == 1
    assert chains[0].osm_way_ids == (5,)
    assert not any("both ends" in why for _, why in rejected)
    graph, traj = _loop_back_graph(700.0)
    chains, rejected = extract_ramp_chains(graph, traj)
    assert chains == ()
    assert any("both ends" in why for _, why in rejected)
    # a piece of the driven way itself (oakland chain 28393854 driven in its inner lane)
    graph, traj = _loop_back_graph(975.0, way=1)
    chains, rejected = extract_ramp_chains(graph, traj)
    assert chains == ()
