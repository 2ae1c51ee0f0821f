"""``roadtwin drive``: routes on the lane graph, one OpenSCENARIO per route, esmini drives.

Without esmini (``ESMINI_BIN`` or ``PATH``) the tests that drive skip with that reason;
route finding, scenario writing and judging recordings are tested without it. The drives
use a map built from the bundled ``straight_curve_2km`` run and four broken copies of it
(a connection removed, a ramp linked to the wrong road, a lane link to a lane metres away,
a 1.5 m gap): each must fail with a reason that names the road and the lane.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os

import numpy as np
import pytest
from lxml import etree

from networks import LANE_M, SHOULDER_IN_M, mainline_exit_network, straight_road
from roadtwin._errors import InputError
from roadtwin.cli import main
from roadtwin.config import DriveConfig
from roadtwin.drive import (
    Route,
    drive_map,
    find_esmini,
    find_routes,
    judge_recording,
    write_scenario,
)
from roadtwin.drive.esmini import Recording
from roadtwin.drive.routes import lane_type_at
from roadtwin.model import Arc, CubicPiece, CubicProfile, RoadLink, RoadNetwork
from roadtwin.xodr import read_xodr, write_xodr

ESMINI = find_esmini()
needs_esmini = pytest.mark.skipif(
    ESMINI is None,
    reason="esmini not found: set ESMINI_BIN to a folder with esmini and dat2csv "
    "(../shared/tools/esmini-headless-linux-x86_64.tar.gz; .ci/run unpacks it)",
)


# ---------------------------------------------------------------------------
# routes (no esmini)
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("junctions", ["default", "direct"])
def test_routes_of_a_mainline_with_an_exit(junctions):
    net = mainline_exit_network(junctions)
    routes = find_routes(net)
    assert [(r.kind, r.name) for r in routes] == [
        ("mainline", "mainline lane -2"),
        ("mainline", "mainline lane -3"),
        ("exit", "exit road 3"),
    ]
    through = "101" if junctions == "default" else None
    for r in routes[:2]:
        assert r.roads == (("1", through, "2") if through else ("1", "2"))
        # from 2 m after the start of road 1 to 2 m before the end of road 2: 296 m
        assert r.length_m == pytest.approx(296.0, abs=1e-6)
        assert (r.start.road_id, r.start.s_m) == ("1", pytest.approx(2.0))
        assert r.target.road_id == "2"
    exit_route = routes[2]
    assert exit_route.lanes[0] == ("1", 1, -4)  # the deceleration lane feeds the exit
    assert exit_route.roads[-1] == "3"
    # the start waits until the tapering deceleration lane is 2 m wide (cubic 0 -> 3.5 m
    # over 100..150 m reaches 2 m at 127.5 m), plus the 2 m margin
    assert exit_route.start.s_m == pytest.approx(129.5, abs=0.5)
    assert exit_route.on_target_m == pytest.approx(exit_route.target.s_m, abs=1e-6)
    for r in routes:
        for p in r.waypoints:
            assert lane_type_at(net, p.road_id, p.lane_id, np.array([p.s_m]))[0] == "driving"


def test_a_lane_narrower_than_a_car_through_a_junction_is_no_connection_route():
    """A lane that opens from zero width just before a junction is 0.1-0.4 m wide all
    through it (melbourne-14-s11 with a noisier sensor): no driver takes that connection,
    the car changes into the lane where it is open. It is no route, not a failed one."""
    net = mainline_exit_network()

    def opening(road_id: str, section: int, w0: float, w1: float, length: float, **links):
        road = net.road(road_id)
        sec = road.lane_sections[section]
        width = CubicProfile((CubicPiece(0.0, w0, (w1 - w0) / length),))
        lane = dataclasses.replace(sec.right[0], type="driving", width=width, **links)
        secs = list(road.lane_sections)
        secs[section] = dataclasses.replace(sec, right=(lane, *sec.right[1:]))
        return dataclasses.replace(road, lane_sections=tuple(secs))

    road1 = net.road("1")
    roads = {
        "1": opening("1", 1, 0.0, 0.1, road1.length - 100.0, predecessor=None),
        "101": opening("101", 0, 0.1, 0.4, net.road("101").length),
        "2": opening("2", 0, 0.4, 0.4, net.road("2").length),
    }
    net = dataclasses.replace(net, roads=tuple(roads.get(r.id, r) for r in net.roads))
    routes = find_routes(net)
    assert [(r.kind, r.name) for r in routes] == [
        ("mainline", "mainline lane -2"),
        ("mainline", "mainline lane -3"),
        ("exit", "exit road 3"),
    ]
    assert not any(r.problem for r in routes)


def _drop_connection(net: RoadNetwork, junction_id: str, connection_id: str) -> RoadNetwork:
    junctions = tuple(
        dataclasses.replace(j, connections=tuple(c for c in j.connections if c.id != connection_id))
        if j.id == junction_id
        else j
        for j in net.junctions
    )
    return dataclasses.replace(net, junctions=junctions)


def _replace_road(net: RoadNetwork, road_id: str, **changes) -> RoadNetwork:
    roads = tuple(dataclasses.replace(r, **changes) if r.id == road_id else r for r in net.roads)
    return dataclasses.replace(net, roads=roads)


def test_a_mainline_lane_narrower_than_a_car_over_its_last_road_ends_where_it_was_wide():
    """A through lane that closes by a taper from 1.8 m at the start of the last mainline
    road: the route along it targets where it was last 2 m wide, not the end of that road
    (0.05 m wide, where esmini moved the car into the next lane: melbourne-921-s2)."""
    net = mainline_exit_network("default")
    road = net.road("2")
    sec = road.lane_sections[0]
    taper = CubicProfile((CubicPiece(0.0, 1.8, -1.8 / road.length),))
    right = tuple(dataclasses.replace(ln, width=taper) if ln.id == -2 else ln for ln in sec.right)
    net = _replace_road(net, "2", lane_sections=(dataclasses.replace(sec, right=right),))
    route = next(r for r in find_routes(net) if r.name == "mainline lane -2")
    assert not route.problem
    assert route.target.road_id != "2"
    assert route.on_target_m > 0.0
    tr = net.road(route.target.road_id)
    s_t = np.array([route.target.s_m])
    lid = route.target.lane_id
    width = abs(tr.lane_border_t(s_t, lid) - tr.lane_border_t(s_t, lid + (1 if lid < 0 else -1)))
    assert width[0] >= 2.0


def test_a_removed_connection_is_a_route_without_lane_path():
    net = _drop_connection(mainline_exit_network(), "100", "1")
    route = next(r for r in find_routes(net) if r.kind == "exit")
    assert route.waypoints == ()
    assert "road 3 lane -1" in route.problem
    assert "road 102 lane -1" in route.problem
    assert "junction 100 has no connection onto road 102" in route.problem


def test_a_ramp_linked_to_the_wrong_road_names_the_lane_it_reaches():
    # the exit's connecting road leads onto the mainline road after the junction: its
    # driving lane -1 continues as road 2's lane -1, the inner shoulder
    net = _replace_road(mainline_exit_network(), "102", successor=RoadLink("road", "2", "start"))
    routes = find_routes(net)
    exit_route = next(r for r in routes if r.kind == "exit")
    assert "leads into road 3 lane -1" in exit_route.problem
    assert "road 3 links to junction 100, but no road of that junction leads onto it" in (
        exit_route.problem
    )
    # the junction lane link into road 102 becomes a route of its own, onto the shoulder
    link = next(r for r in routes if r.kind == "connection")
    assert link.name == "junction 100: road 1 lane -4 -> road 102 lane -1"
    assert link.lanes[-1] == ("2", 0, -1)
    assert lane_type_at(net, "2", -1, np.array([0.0]))[0] == "shoulder"


# ---------------------------------------------------------------------------
# scenarios (no esmini)
# ---------------------------------------------------------------------------


def test_scenario_files_reference_the_map_and_the_route(tmp_path):
    net = mainline_exit_network()
    map_path = write_xodr(net, tmp_path / "map.xodr")
    cfg = DriveConfig()
    for i, route in enumerate(find_routes(net)):
        path = write_scenario(route, map_path, tmp_path / "scenarios" / f"{i}.xosc", config=cfg)
        first = path.read_bytes()
        write_scenario(route, map_path, path, config=cfg)
        assert path.read_bytes() == first  # same route, same bytes
        doc = etree.parse(str(path))
        logic = doc.find(".//RoadNetwork/LogicFile").get("filepath")
        assert logic == "../map.xodr"
        assert (path.parent / logic).resolve() == map_path.resolve()
        teleport = doc.find(".//TeleportAction//LanePosition")
        assert (teleport.get("roadId"), int(teleport.get("laneId"))) == (
            route.start.road_id,
            route.start.lane_id,
        )
        waypoints = doc.findall(".//AssignRouteAction//Waypoint/Position/LanePosition")
        assert [(w.get("roadId"), int(w.get("laneId")), float(w.get("s"))) for w in waypoints] == [
            (p.road_id, p.lane_id, pytest.approx(p.s_m, abs=1e-3)) for p in route.waypoints
        ]
        speed = doc.find(".//AbsoluteTargetSpeed").get("value")
        assert float(speed) == cfg.speed_m_s
        assert doc.find(".//CatalogLocations") is not None
        assert not doc.findall(".//CatalogReference")


def test_a_route_without_lane_path_has_no_scenario(tmp_path):
    route = Route("exit road 9", "exit", problem="no lane")
    with pytest.raises(ValueError, match="cannot be driven"):
        write_scenario(route, tmp_path / "map.xodr", tmp_path / "x.xosc", config=DriveConfig())


# ---------------------------------------------------------------------------
# judging recordings (no esmini)
# ---------------------------------------------------------------------------


@pytest.fixture
def straight():
    """A 300 m straight mainline along +x and its route in lane -2 (centre y = -2.75 m)."""
    net = RoadNetwork(mainline_exit_network().header, (straight_road("1", 300.0),))
    route = next(r for r in find_routes(net) if r.name == "mainline lane -2")
    return net, route


def _drive(route: Route, cfg: DriveConfig, *, until_s: float | None = None) -> dict:
    """States of a car driving lane -2 of the straight road at the configured speed."""
    end = route.target.s_m if until_s is None else until_s
    s = np.arange(route.start.s_m, end + 1e-9, cfg.speed_m_s * cfg.timestep_s)
    n = s.size
    return {
        "time": np.arange(n) * cfg.timestep_s,
        "x": s.copy(),
        "y": np.full(n, -2.75),
        "h": np.zeros(n),
        "road": np.full(n, "1", dtype=object),
        "lane": np.full(n, -2),
        "s": s,
        "speed": np.full(n, cfg.speed_m_s),
    }


def _judge(states: dict, route: Route, net: RoadNetwork, cfg: DriveConfig):
    rec = Recording(**{k: np.asarray(v) for k, v in states.items()})
    return judge_recording(rec, route, net, config=cfg)


def test_a_clean_drive_passes(straight):
    net, route = straight
    cfg = DriveConfig()
    j = _judge(_drive(route, cfg), route, net, cfg)
    assert j.faults == ()
    assert j.reached
    assert j.max_jump_m < 1e-9
    assert j.driven_m == pytest.approx(296.0, abs=1.3)
    assert j.on_target_m == pytest.approx(j.driven_m)


@pytest.mark.parametrize(("dx", "dy"), [(0.0, 1.5), (1.5, 0.0), (-1.06, 1.06)])
def test_a_gap_of_1_5_m_is_a_jump_in_any_direction(straight, dx, dy):
    net, route = straight
    cfg = DriveConfig()
    states = _drive(route, cfg)
    k = 100
    states["x"][k:] += dx
    states["y"][k:] += dy
    states["s"][k:] += dx
    j = _judge(states, route, net, cfg)
    jumps = [f for f in j.faults if f.code == "jump"]
    assert len(jumps) == 1
    assert j.max_jump_m == pytest.approx(1.5, abs=0.01)
    # the raw step across the gap stays under 2 m when the gap is sideways
    if dx == 0.0:
        assert j.max_step_m < 2.0
    f = jumps[0]
    assert (f.road_id, f.lane_id) == ("1", -2)
    assert f.s_m == pytest.approx(states["s"][k])
    assert "road 1 lane -2" in f.message


def test_a_car_on_a_shoulder_off_the_route_or_standing_still_fails(straight):
    net, route = straight
    cfg = DriveConfig()
    states = _drive(route, cfg)
    states["lane"][50:60] = -1  # the inner shoulder
    j = _judge(states, route, net, cfg)
    assert [f.code for f in j.faults] == ["non_driving_lane"]
    assert j.faults[0].lane_id == -1
    assert "a shoulder lane" in j.faults[0].message

    states = _drive(route, cfg)
    states["lane"][70] = -7  # a lane the road does not have
    j = _judge(states, route, net, cfg)
    assert "a lane the road does not have" in j.faults[0].message

    states = _drive(route, cfg)
    states["road"][80:90] = "99"  # not on the route (and not in the map)
    j = _judge(states, route, net, cfg)
    assert [f.code for f in j.faults] == ["non_driving_lane", "off_route"]
    assert j.faults[1].road_id == "99"
    assert "left the route (roads 1): road 99 lane -2" in j.faults[1].message

    states = _drive(route, cfg, until_s=150.0)  # stops at s=150 and stands for 3 s
    n_still = int(3.0 / cfg.timestep_s)
    for key in ("x", "y", "h", "road", "lane", "s"):
        states[key] = np.concatenate([states[key], np.repeat(states[key][-1:], n_still)])
    t_end = states["time"][-1]
    states["time"] = np.concatenate(
        [states["time"], t_end + cfg.timestep_s * np.arange(1, n_still + 1)]
    )
    states["speed"] = np.concatenate([states["speed"], np.zeros(n_still)])
    j = _judge(states, route, net, cfg)
    assert [f.code for f in j.faults] == ["stuck", "not_reached"]
    assert j.faults[0].s_m == pytest.approx(states["s"][-1], abs=1.3)
    assert "stood still" in j.faults[0].message


def test_too_short_a_drive_on_the_target_road_fails(straight):
    net, route = straight
    cfg = DriveConfig()
    states = _drive(route, cfg)
    # the car only appears on the target road 20 m before the target
    k = int(np.searchsorted(states["s"], route.target.s_m - 20.0))
    states["road"][:k] = "0"
    route0 = dataclasses.replace(route, lanes=(("0", 0, -2), *route.lanes))
    j = _judge(states, route0, net, cfg)
    assert [f.code for f in j.faults] == ["non_driving_lane", "short_on_target"]
    assert j.on_target_m == pytest.approx(20.0, abs=1.3)


def test_a_lane_on_the_inside_of_a_tight_curve_is_judged_along_the_road():
    """A 45 m ramp bending right at a 15 m radius: its lane -2 (centre 2.75 m right of the
    reference line) is 18 % shorter than the reference line, along which the route plans
    its distance; the car that drives it to the end has driven far enough."""
    arc = Arc(0.0, 0.0, 0.0, 0.0, 45.0, curvature_per_m=-1.0 / 15.0)
    road = dataclasses.replace(straight_road("1", 45.0), geometry=(arc,))
    net = RoadNetwork(mainline_exit_network().header, (road,))
    cfg = DriveConfig()
    route = next(r for r in find_routes(net, config=cfg) if r.name == "mainline lane -2")
    centre = -(SHOULDER_IN_M + 0.5 * LANE_M)
    # s advances by the car's step divided by (1 - k t) = 1 - 2.75 / 15
    step = cfg.speed_m_s * cfg.timestep_s
    s = np.arange(route.start.s_m, route.target.s_m + 1e-9, step / (1.0 - 2.75 / 15.0))
    xy = road.to_xy(s, np.full(s.size, centre))
    states = {
        "time": np.arange(s.size) * cfg.timestep_s,
        "x": xy[:, 0],
        "y": xy[:, 1],
        "h": road.heading(s),
        "road": np.full(s.size, "1", dtype=object),
        "lane": np.full(s.size, -2),
        "s": s,
        "speed": np.full(s.size, cfg.speed_m_s),
    }
    j = _judge(states, route, net, cfg)
    assert j.reached
    assert j.max_jump_m < 0.01
    # 43 m of reference line, 35 m driven: short in metres, far enough along the road
    assert j.on_target_m == pytest.approx(0.817 * (s[-1] - s[0]), abs=0.1)
    assert j.faults == ()
    # a car that leaves the lane 10 m early is still too short, however it is measured
    short = {k: v[: s.size - 8] for k, v in states.items()}
    j = _judge(short, route, net, cfg)
    assert "short_on_target" in [f.code for f in j.faults] or "not_reached" in [
        f.code for f in j.faults
    ]


# ---------------------------------------------------------------------------
# CLI without esmini
# ---------------------------------------------------------------------------


def test_drive_without_esmini_writes_scenarios_and_exits_2(tmp_path, monkeypatch, capsys):
    map_path = write_xodr(mainline_exit_network(), tmp_path / "map.xodr")
    monkeypatch.setenv("ESMINI_BIN", str(tmp_path / "nowhere"))
    monkeypatch.setenv("PATH", os.defpath)
    code = main(["-q", "drive", str(map_path), "-o", str(tmp_path / "d")])
    assert code == 2
    err = capsys.readouterr().err
    assert "esmini not found" in err
    assert "--esmini DIR" in err
    assert "esmini --headless --osc" in err
    assert sorted(p.name for p in (tmp_path / "d" / "scenarios").iterdir()) == [
        "001_mainline_lane_2.xosc",
        "002_mainline_lane_3.xosc",
        "003_exit_road_3.xosc",
    ]
    doc = (tmp_path / "d" / "drive.json").read_text(encoding="utf-8")
    assert '"not_run": 3' in doc
    # check --drive cannot drive either: the check's report, then exit 2
    assert main(["-q", "check", str(map_path), "--no-external", "--drive"]) == 2
    captured = capsys.readouterr()
    assert "roadtwin check" in captured.out
    assert "esmini not found" in captured.err


def test_a_wrong_esmini_folder_is_bad_input(tmp_path, capsys):
    map_path = write_xodr(mainline_exit_network(), tmp_path / "map.xodr")
    with pytest.raises(InputError, match="no runnable esmini"):
        find_esmini(tmp_path)
    assert main(["-q", "drive", str(map_path), "--esmini", str(tmp_path)]) == 2
    assert "no runnable esmini and dat2csv" in capsys.readouterr().err
    assert main(["-q", "drive", str(tmp_path / "missing.xodr")]) == 2


# ---------------------------------------------------------------------------
# esmini drives of a built map and of broken copies of it
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """``straight_curve_2km`` simulated and built (default junctions), read back."""
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map
    from roadtwin.simulate import simulate_run

    base = tmp_path_factory.mktemp("drive")
    simulate_run("straight_curve_2km", base / "run")
    run = load_run(base / "run")
    osm = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    path = write_xodr(build_map(run, osm).network, base / "map.xodr")
    return path, read_xodr(path)


def _ramp_ids(net: RoadNetwork, kind: str) -> tuple[str, str, str]:
    """(ramp road, its connecting road, the mainline road on the junction's other side)."""
    ramp = next(r for r in net.roads if r.name == kind)
    conn = next(
        r
        for r in net.roads
        if r.junction != "-1" and ramp.id in {r.predecessor.element_id, r.successor.element_id}
    )
    main_id = conn.predecessor.element_id if kind == "exit" else conn.successor.element_id
    return ramp.id, conn.id, main_id


@needs_esmini
def test_every_route_of_a_built_map_drives(built, tmp_path):
    path, net = built
    report = drive_map(path, tmp_path, esmini=ESMINI, network=net)
    kinds = [r.route.kind for r in report.results]
    assert kinds == ["mainline"] * 3 + ["exit", "entry"]
    assert report.ok, report.format_text()
    assert report.warnings == {}
    for r in report.results:
        j = r.judgement
        assert j.reached
        assert j.max_jump_m < 0.05
        assert j.on_target_m >= DriveConfig().min_on_target_m
    exit_result = next(r for r in report.results if r.route.kind == "exit")
    ramp_id, _, _ = _ramp_ids(net, "exit")
    assert exit_result.judgement.on_target_m >= 0.95 * (net.road(ramp_id).length - 4.0)
    # passed routes keep their esmini log only
    assert sorted(p.suffix for p in (tmp_path / "runs").iterdir()) == [".log"] * 5


def _lane_centre(road, s: float, lane_id: int) -> np.ndarray:
    inner = lane_id + 1 if lane_id < 0 else lane_id - 1
    t = 0.5 * (
        road.lane_border_t(np.array([s]), lane_id) + road.lane_border_t(np.array([s]), inner)
    )
    return road.to_xy(np.array([s]), t)[0]


def _set_last_successor(net: RoadNetwork, road_id: str, lane_id: int, new: int) -> RoadNetwork:
    road = net.road(road_id)
    sec = road.lane_sections[-1]
    right = tuple(
        dataclasses.replace(ln, successor=new) if ln.id == lane_id else ln for ln in sec.right
    )
    sections = (*road.lane_sections[:-1], dataclasses.replace(sec, right=right))
    return _replace_road(net, road_id, lane_sections=sections)


def _driving_lane(net: RoadNetwork, road_id: str):
    """The (first) driving lane of the last lane section of a road."""
    return next(ln for ln in net.road(road_id).lane_sections[-1].right if ln.type == "driving")


def _plant(kind: str, net: RoadNetwork):
    """A broken copy of ``net`` and a check of the failed drive."""
    exit_id, exit_conn, _ = _ramp_ids(net, "exit")
    _, entry_conn, down_id = _ramp_ids(net, "entry")
    if kind == "connection removed":
        junction = net.road(exit_conn).junction
        conn = next(
            c for c in net.id_to_junction[junction].connections if c.connecting_road == exit_conn
        )
        broken = _drop_connection(net, junction, conn.id)

        def verify(report):
            r = next(x for x in report.results if x.route.kind == "exit")
            assert r.status == "failed"
            assert [f.code for f in r.faults] == ["no_lane_path"]
            lane = _driving_lane(net, exit_conn).id
            assert f"road {exit_conn} lane {lane}" in r.faults[0].message
            assert f"junction {junction} has no connection onto road {exit_conn}" in (
                r.faults[0].message
            )

    elif kind == "ramp linked to the wrong road":
        # the entry's connecting road leads onto the first mainline road instead
        first = next(r for r in net.roads if r.name == "mainline" and r.predecessor is None)
        broken = _replace_road(net, entry_conn, successor=RoadLink("road", first.id, "start"))

        def verify(report):
            r = next(x for x in report.results if x.route.kind == "entry")
            assert r.status == "failed"
            assert f"road {first.id} lane" in r.faults[0].message
            driven = [x for x in report.results if x.route.kind == "connection"]
            assert driven, "the junction lane link into the wrong road is driven"
            jump = next(f for f in driven[0].faults if f.code == "jump")
            assert jump.road_id == first.id
            assert jump.message.startswith("jump of")

    elif kind == "lane link to a lane metres away":
        # the entry lane continues as the mainline lane whose centre is nearest 9 m away
        road = net.road(down_id)
        entry_lane = _driving_lane(net, entry_conn)
        here = _lane_centre(road, 0.0, entry_lane.successor)
        lanes = [ln.id for ln in road.lane_sections[0].right if ln.type == "driving"]
        far = min(lanes, key=lambda i: abs(np.hypot(*(_lane_centre(road, 0.0, i) - here)) - 9.0))
        distance = float(np.hypot(*(_lane_centre(road, 0.0, far) - here)))
        assert distance > 5.0
        broken = _set_last_successor(net, entry_conn, entry_lane.id, far)

        def verify(report):
            r = next(x for x in report.results if x.route.kind == "entry")
            jump = next(f for f in r.faults if f.code == "jump")
            assert (jump.road_id, jump.lane_id) == (down_id, far)
            assert r.judgement.max_jump_m == pytest.approx(distance, abs=0.5)

    else:  # a 1.5 m gap: the exit road moved sideways by 1.5 m
        road = net.road(exit_id)
        h = road.geometry[0].hdg
        dx, dy = -1.5 * math.sin(h), 1.5 * math.cos(h)
        geometry = tuple(dataclasses.replace(g, x0=g.x0 + dx, y0=g.y0 + dy) for g in road.geometry)
        broken = _replace_road(net, exit_id, geometry=geometry)

        def verify(report):
            r = next(x for x in report.results if x.route.kind == "exit")
            assert [f.code for f in r.faults] == ["jump"]
            f = r.faults[0]
            assert (f.road_id, f.lane_id) == (exit_id, _driving_lane(net, exit_id).id)
            assert f.s_m < 2.0
            assert r.judgement.max_jump_m == pytest.approx(1.5, abs=0.05)

    return broken, verify


@needs_esmini
@pytest.mark.parametrize(
    "kind",
    [
        "connection removed",
        "ramp linked to the wrong road",
        "lane link to a lane metres away",
        "gap of 1.5 m",
    ],
)
def test_a_broken_map_fails_the_drive_naming_road_and_lane(built, tmp_path, kind):
    _, net = built
    broken, verify = _plant(kind, net)
    path = write_xodr(broken, tmp_path / "broken.xodr")
    report = drive_map(path, tmp_path / "d", esmini=ESMINI)
    assert not report.ok
    verify(report)
    # the routes the plant does not touch still pass
    assert report.count("passed") >= 3


@needs_esmini
def test_drive_cli_exit_codes(built, tmp_path, capsys):
    path, net = built
    esmini_dir = str(ESMINI.esmini.parent)
    assert main(["-q", "drive", str(path), "-o", str(tmp_path / "ok"), "--esmini", esmini_dir]) == 0
    out = capsys.readouterr().out
    assert "5 routes: 5 passed, 0 failed; esmini logged no warning" in out
    broken, _ = _plant("gap of 1.5 m", net)
    bad = write_xodr(broken, tmp_path / "broken.xodr")
    code = main(["-q", "drive", str(bad), "-o", str(tmp_path / "bad"), "--esmini", esmini_dir])
    assert code == 1
    out = capsys.readouterr().out
    assert "FAILED" in out
    assert "jump of 1.5" in out
    assert (tmp_path / "bad" / "drive.json").is_file()
    # the failed route keeps its recording for a look
    assert any(p.suffix == ".csv" for p in (tmp_path / "bad" / "runs").iterdir())


def test_the_html_report_shows_the_drive(tmp_path, monkeypatch):
    from roadtwin.evaluation import EvaluationReport
    from roadtwin.report import render_html

    map_path = write_xodr(mainline_exit_network(), tmp_path / "map.xodr")
    doc = drive_map(map_path, tmp_path / "d", esmini=None).to_dict()
    doc["routes"][2]["faults"] = [{"code": "jump", "message": "jump of 1.50 m <at> road 3"}]
    page = render_html(EvaluationReport(()), {}, drive=doc)
    assert "<h2>Drive-throughs (esmini)</h2>" in page
    for name in ("mainline lane -2", "mainline lane -3", "exit road 3"):
        assert f'<td class="s">{name}</td>' in page
    assert page.count('<td class="s">not run</td>') == 3
    assert "jump of 1.50 m &lt;at&gt; road 3" in page
    assert "Drive-throughs" not in render_html(EvaluationReport(()), {})


@needs_esmini
def test_check_drive(built, capsys):
    path, _ = built
    esmini_dir = str(ESMINI.esmini.parent)
    code = main(["-q", "check", str(path), "--no-external", "--drive", "--esmini", esmini_dir])
    out = capsys.readouterr().out
    assert code == 0, out
    assert out.index("OK: 0 errors") < out.index("drive: 5 routes: 5 passed, 0 failed")
    code = main(
        ["-q", "check", str(path), "--no-external", "--json", "--drive", "--esmini", esmini_dir]
    )
    doc = json.loads(capsys.readouterr().out)
    assert doc["drive"]["schema"] == "roadtwin-drive/1"
    assert doc["drive"]["passed"] == 5
