"""Topology: a hand-built mainline road with a deceleration and an acceleration lane plus
two ramp polylines -> cut roads, junctions (default and direct), lane links.

Numbers checked: attachment gap <= 1 cm and heading jump <= 0.5 deg at every link, lane
routes from the mainline into the exit and from the entry onto the mainline, mutual links
(``roadtwin.check.check_network`` finds no link problem), lane sections where the lane
count changes.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import replace

import networkx as nx
import numpy as np
import pytest

from roadtwin.check import check_network
from roadtwin.config import PipelineConfig, RampConfig, TopologyConfig
from roadtwin.model import (
    Arc,
    CubicPiece,
    CubicProfile,
    Header,
    Lane,
    LaneSection,
    Line,
    Road,
    RoadMark,
    RoadNetwork,
)
from roadtwin.ramps import Ramp, build_ramp_road, gore_events
from roadtwin.topology import build_topology, hermite_road, lane_graph, match_lanes_at

W = 3.75
LINK_CODES = {
    "link_gap",
    "link_kink",
    "one_sided_link",
    "dangling_link",
    "missing_lane_link",
    "geometry_gap",
    "geometry_kink",
}


def _taper(w0: float, w1: float, s0: float, length: float) -> CubicPiece:
    dw = w1 - w0
    return CubicPiece(s0, w0, 0.0, 3 * dw / length**2, -2 * dw / length**3)


def _lane(lane_id, width, lane_type="driving", mark="broken", pred=None, succ=None):
    if not isinstance(width, CubicProfile):
        width = CubicProfile.constant(width)
    return Lane(lane_id, lane_type, width, (RoadMark(0.0, mark),), pred, succ)


def _mirror(section: LaneSection, side: str) -> LaneSection:
    if side == "right":
        return section

    def flip(lane: Lane) -> Lane:
        return Lane(
            -lane.id,
            lane.type,
            lane.width,
            lane.road_marks,
            None if lane.predecessor is None else -lane.predecessor,
            None if lane.successor is None else -lane.successor,
        )

    return LaneSection(section.s0, left=tuple(flip(x) for x in section.right))


def mainline_road(side: str = "right") -> Road:
    """1200 m: line then a left arc; decel lane 300..500 (gore at 500), accel lane
    800..1000 (gore at 800); shared lane layout (inner shoulder, 3 lanes, hard shoulder)."""
    line = Line(0.0, 100.0, 50.0, 0.3, 400.0)
    geometry = (line, Arc(400.0, *line.end_pose(), 800.0, curvature_per_m=1 / 1500))

    def base(decel=None, extra_succ=None, extra_pred=None, s_pred=True, s_succ=True):
        lanes = [
            _lane(-1, 0.75, "shoulder", "solid", -1 if s_pred else None, -1 if s_succ else None),
            _lane(-2, W, pred=-2 if s_pred else None, succ=-2 if s_succ else None),
            _lane(-3, W, pred=-3 if s_pred else None, succ=-3 if s_succ else None),
            _lane(-4, W, mark="solid", pred=-4 if s_pred else None, succ=-4 if s_succ else None),
        ]
        if decel is not None:
            lanes.append(_lane(-5, decel, mark="solid", pred=extra_pred, succ=extra_succ))
        hs = -6 if decel is not None else -5
        lanes.append(_lane(hs, 2.5, "shoulder", "none"))
        return lanes

    s0 = base(s_pred=False)
    s0[-1] = _lane(-5, 2.5, "shoulder", "none", None, -6)
    s1 = base(CubicProfile((_taper(0.0, W, 0.0, 60.0), CubicPiece(60.0, W))))
    s1[-1] = _lane(-6, 2.5, "shoulder", "none", -5, None)
    s2 = base()
    s2[-1] = _lane(-5, 2.5, "shoulder", "none", None, -6)
    s3 = base(CubicProfile((CubicPiece(0.0, W), _taper(W, 0.0, 140.0, 60.0))))
    s3[-1] = _lane(-6, 2.5, "shoulder", "none", None, -5)
    s4 = base(s_succ=False)
    s4[-1] = _lane(-5, 2.5, "shoulder", "none", -6, None)
    center = Lane(0, "none", road_marks=(RoadMark(0.0, "none"),))
    sections = tuple(
        _mirror(LaneSection(s, center=center, right=tuple(lanes)), side)
        for s, lanes in ((0.0, s0), (300.0, s1), (500.0, s2), (800.0, s3), (1000.0, s4))
    )
    return Road(
        "1",
        geometry,
        sections,
        name="mainline",
        elevation=CubicProfile((CubicPiece(0.0, 10.0, 0.01),)),
    )


def ramp_polylines(road: Road, side: str = "right") -> dict[str, np.ndarray]:
    """OSM-like sparse centrelines: the exit leaves the carriageway centre near s=430 and
    bends away; the entry comes in and joins the centre near s=900."""
    sign = -1.0 if side == "right" else 1.0
    centre_t = sign * (0.75 + 1.5 * W)
    s_exit = np.arange(430.0, 800.0, 20.0)
    t_exit = centre_t + sign * 0.0012 * (s_exit - 430.0) ** 2
    s_entry = np.arange(560.0, 901.0, 20.0)
    t_entry = centre_t + sign * 0.0012 * (900.0 - s_entry) ** 2
    return {
        "exit": road.to_xy(s_exit, t_exit),
        "entry": road.to_xy(s_entry, t_entry),
    }


def make_ramps(road: Road, side: str = "right") -> list[Ramp]:
    cfg = RampConfig()
    events = {e.kind: e for e in gore_events(road, traffic_side=side)}
    out = []
    for kind, xy in ramp_polylines(road, side).items():
        ev = events[kind]
        ramp_road, gap, dh = build_ramp_road(
            xy,
            road,
            ramp_type=kind,
            lanes=len(ev.lane_ids),
            station_m=ev.station_m,
            source_lane_ids=ev.lane_ids,
            traffic_side=side,
            road_id=f"r{kind}",
            config=cfg,
        )
        out.append(
            Ramp(
                type=kind,
                road=ramp_road,
                station_m=ev.station_m,
                lanes=len(ev.lane_ids),
                lane_rule="mainline lane change",
                osm_lanes=1,
                osm_lane_rule="highway class",
                station_source="lidar gore",
                mainline_lane_ids=ev.lane_ids,
                type_connectivity=kind,
                type_geometry=kind,
                osm_way_ids=(),
                attach_gap_m=gap,
                attach_heading_deg=dh,
            )
        )
    return out


def _network(topo) -> RoadNetwork:
    return RoadNetwork(
        Header(geo_reference="+proj=tmerc +lat_0=50 +lon_0=11"), topo.roads, topo.junctions
    )


def _pose(road: Road, s: float):
    x, y, h, _ = road.evaluate(np.array([s]))
    return float(x[0]), float(y[0]), float(h[0])


def _lane_border_xy(road: Road, s: float, lane_id: int) -> np.ndarray:
    """Inner and outer border points of a lane at station s."""
    inner = lane_id + (1 if lane_id < 0 else -1)
    t = [road.lane_border_t(np.array([s]), i)[0] for i in (inner, lane_id)]
    return road.to_xy(np.array([s, s]), np.array(t))


@pytest.fixture(scope="module", params=["right", "left"])
def side(request):
    return request.param


@pytest.fixture(scope="module")
def mainline(side):
    return mainline_road(side)


@pytest.fixture(scope="module")
def ramps(mainline, side):
    return make_ramps(mainline, side)


def test_gore_events_from_lane_sections(mainline, side):
    events = gore_events(mainline, traffic_side=side)
    sign = -1 if side == "right" else 1
    assert [(e.kind, e.station_m, e.lane_ids, e.through_lane_id) for e in events] == [
        ("exit", 500.0, (sign * 5,), sign * 4),
        ("entry", 800.0, (sign * 5,), sign * 4),
    ]


def test_ramp_roads_attach_exactly(mainline, ramps, side):
    sign = -1 if side == "right" else 1
    for ramp in ramps:
        assert ramp.attach_gap_m <= 0.01
        assert ramp.attach_heading_deg <= 0.5
        s_ramp = 0.0 if ramp.type == "exit" else ramp.road.length
        # the ramp's reference line lies on the outer border of the outermost through lane
        t_border = mainline.lane_border_t(np.array([ramp.station_m]), sign * 4)[0]
        target = mainline.to_xy(np.array([ramp.station_m]), np.array([t_border]))[0]
        x, y, h = _pose(ramp.road, s_ramp)
        assert math.hypot(x - target[0], y - target[1]) <= 0.01
        h_main = float(mainline.heading(np.array([ramp.station_m]))[0])
        assert abs(math.degrees((h - h_main + math.pi) % (2 * math.pi) - math.pi)) <= 0.5
        # the ramp lies on the traffic side, outside the carriageway, 100 m away
        s_far = 100.0 if ramp.type == "exit" else ramp.road.length - 100.0
        _, t_far = mainline.project(ramp.road.xy(np.array([s_far])))
        edge = mainline.lane_border_t(np.array([ramp.station_m]), sign * 4)[0]
        assert t_far[0] * sign > abs(edge)


@pytest.mark.parametrize("junctions", ["default", "direct"])
def test_topology_links_and_routes(mainline, ramps, side, junctions):
    topo = build_topology(
        mainline, ramps, traffic_side=side, config=TopologyConfig(junctions=junctions)
    )
    assert not topo.skipped
    net = _network(topo)
    names = [r.name for r in net.roads]
    assert names.count("mainline") == 3
    assert names.count("exit") == 1
    assert names.count("entry") == 1
    assert names.count("connector") == (4 if junctions == "default" else 0)
    assert [r.id for r in net.roads if r.name == "mainline"] == ["1", "2", "3"]
    assert len(net.junctions) == 2
    assert {j.type for j in net.junctions} == {junctions}
    # mainline lengths add up (default: plus the through connectors)
    total = sum(r.length for r in net.roads if r.name == "mainline")
    total += sum(
        r.length
        for r in net.roads
        if r.name == "connector"
        and {r.predecessor.element_id, r.successor.element_id} <= {"1", "2", "3"}
    )
    assert total == pytest.approx(mainline.length, abs=0.01)

    findings = check_network(net)
    bad = [f for f in findings if f.code in LINK_CODES and f.severity == "error"]
    assert not bad, [f.message for f in bad]
    errors = [f for f in findings if f.severity == "error"]
    assert not errors, [f.message for f in errors]

    # every road link is mutual and geometrically continuous within 1 cm / 0.5 deg
    ids = net.id_to_road
    for road in net.roads:
        for contact, link in (("start", road.predecessor), ("end", road.successor)):
            if link is None or link.element_type != "road":
                continue
            other = ids[link.element_id]
            back = other.predecessor if link.contact_point == "start" else other.successor
            assert back is not None
            assert back.element_id in (road.id, road.junction)
            s_a = 0.0 if contact == "start" else road.length
            s_b = 0.0 if link.contact_point == "start" else other.length
            _xa, _ya, ha = _pose(road, s_a)
            _xb, _yb, hb = _pose(other, s_b)
            pairs = [
                (ln.id, ln.predecessor if contact == "start" else ln.successor)
                for sec in (road.lane_sections[0 if contact == "start" else -1],)
                for ln in (*sec.left, *sec.right)
            ]
            pairs = [(a, b) for a, b in pairs if b is not None]
            assert pairs, f"road {road.id} {contact}: no lane links"
            for a, b in pairs:
                pa = _lane_border_xy(road, s_a, a)
                pb = _lane_border_xy(other, s_b, b)
                assert np.max(np.hypot(*(pa - pb).T)) <= 0.01
            dh = math.degrees((hb - ha + math.pi) % (2 * math.pi) - math.pi)
            assert abs(dh) <= 0.5
    # routes over the lane graph (lane changes allowed inside a lane section)
    g = lane_graph(net, traffic_side=side, lane_changes=True)
    sign = -1 if side == "right" else 1
    first, last = ids["1"], ids["3"]
    start = ("1", 0, sign * 2)
    end = ("3", len(last.lane_sections) - 1, sign * 2)
    exit_id = next(r.id for r in net.roads if r.name == "exit")
    entry_id = next(r.id for r in net.roads if r.name == "entry")
    exit_road, _entry_road = ids[exit_id], ids[entry_id]
    assert nx.has_path(g, start, (exit_id, len(exit_road.lane_sections) - 1, sign * 2))
    assert nx.has_path(g, (entry_id, 0, sign * 2), end)
    assert nx.has_path(g, start, end)
    # without lane changes: the deceleration lane leads into the exit, the entry into the
    # acceleration lane
    g0 = lane_graph(net, traffic_side=side)
    assert nx.has_path(g0, ("1", len(first.lane_sections) - 1, sign * 5), (exit_id, 0, sign * 2))
    assert nx.has_path(g0, (entry_id, 0, sign * 2), ("3", 0, sign * 5))


@pytest.mark.parametrize("junctions", ["default", "direct"])
def test_junction_lane_links_join_driving_lanes(mainline, ramps, side, junctions):
    """Between mainline and ramp a junction lane link joins two driving lanes (esmini warns
    "target lane not driving" on one into a shoulder); lanes of the same road continuing
    (through lanes, the ramp into its connecting road) link shoulders with shoulders. The
    exit's connecting road keeps the hard shoulder's width at the gore without the link. A
    ramp whose source lanes name the hard shoulder is still fed by driving lanes only."""
    sign = -1 if side == "right" else 1
    # the hard shoulder beside both gores is lane 6 (after the deceleration/acceleration lane)
    ramps = [replace(r, shoulder_lane_id=sign * 6) for r in ramps]
    bad_sources = [
        replace(r, mainline_lane_ids=(sign * 6, *r.mainline_lane_ids)) if r.type == "exit" else r
        for r in ramps
    ]
    for ramp_set in (ramps, bad_sources):
        topo = build_topology(
            mainline, ramp_set, traffic_side=side, config=TopologyConfig(junctions=junctions)
        )
        net = _network(topo)
        ids = net.id_to_road
        n_ramp_links = 0
        for junction in net.junctions:
            for conn in junction.connections:
                inc, tgt = ids[conn.incoming_road], ids[conn.connecting_road]
                end_in = inc.successor is not None and inc.successor.element_id == junction.id
                inc_sec = inc.lane_sections[-1 if end_in else 0]
                tgt_sec = tgt.lane_sections[0 if conn.contact_point == "start" else -1]
                types_in = {ln.id: ln.type for ln in (*inc_sec.left, *inc_sec.right)}
                types_to = {ln.id: ln.type for ln in (*tgt_sec.left, *tgt_sec.right)}
                ramp_side = {inc.name, tgt.name} & {"exit", "entry"} or (
                    tgt.name == "connector"
                    and any(ids[x].name in ("exit", "entry") for x in _ends(tgt))
                )
                for ll in conn.lane_links:
                    pair = (types_in[ll.from_lane], types_to[ll.to_lane])
                    assert pair[0] == pair[1], (junction.id, conn.id, ll, pair)
                    if ramp_side and inc.name == "mainline":
                        assert pair == ("driving", "driving"), (junction.id, conn.id, ll)
                        n_ramp_links += 1
        assert n_ramp_links >= 1
        findings = [f for f in check_network(net) if f.severity == "error"]
        assert not findings, [f.message for f in findings]
    if junctions == "default":
        exit_id = next(r.id for r in net.roads if r.name == "exit")
        conn = next(r for r in net.roads if r.junction != "-1" and exit_id in _ends(r))
        hard = (
            conn.lane_sections[0].right[-1] if side == "right" else conn.lane_sections[0].left[-1]
        )
        assert hard.type == "shoulder"
        assert hard.predecessor is None
        width = float(hard.width.value(np.array([0.0]))[0])
        assert width == pytest.approx(2.5, abs=0.01)  # the mainline's hard shoulder


def _ends(road: Road) -> set[str]:
    return {
        link.element_id
        for link in (road.predecessor, road.successor)
        if link is not None and link.element_type == "road"
    }


def test_lane_sections_follow_lane_count(mainline, ramps, side):
    topo = build_topology(mainline, ramps, traffic_side=side)
    for road in topo.roads:
        counts = [len(s.left) + len(s.right) for s in road.lane_sections]
        assert all(a != b for a, b in itertools.pairwise(counts)) or len(counts) == 1


def test_too_close_ramps_are_skipped(mainline, ramps, side):
    moved = [ramps[0], Ramp(**{**ramps[1].__dict__, "station_m": ramps[0].station_m + 10.0})]
    topo = build_topology(mainline, moved, traffic_side=side)
    assert len(topo.skipped) == 1
    assert len(topo.junctions) == 1


def test_match_lanes_by_geometry(mainline, side):
    """Across a gore the lanes whose borders meet continue: shoulders and through lanes;
    not the deceleration lane, not the hard shoulder beside the gore."""
    sign = -1 if side == "right" else 1
    m = match_lanes_at(mainline, 500.0 - 1e-9, mainline, 500.0, traffic_side=side)
    assert m == {sign * i: sign * i for i in (1, 2, 3, 4)}
    # where the acceleration lane has closed to zero width the hard shoulder goes on
    closed = match_lanes_at(mainline, 1000.0 - 1e-9, mainline, 1000.0, traffic_side=side)
    assert closed == {**{sign * i: sign * i for i in (1, 2, 3, 4)}, sign * 6: sign * 5}


def test_match_lanes_by_geometry_when_lanes_leave_on_the_median_side():
    """A left exit (right-hand traffic): the innermost driving lane ends at the gore and
    the centre lane moves out by its width (lane offset); counting would link lane 2 to
    lane 2 -- geometry links each through lane to the one it really continues as."""
    from roadtwin.model import Line

    line = (Line(0.0, 0.0, 0.0, 0.0, 1000.0),)
    before = LaneSection(
        0.0,
        right=(
            _lane(-1, 0.75, "shoulder", "solid"),
            _lane(-2, W),
            _lane(-3, W),
            _lane(-4, W),
            _lane(-5, 2.5, "shoulder", "none"),
        ),
    )
    after = LaneSection(
        500.0,
        right=(
            _lane(-1, 0.75, "shoulder", "solid"),
            _lane(-2, W),
            _lane(-3, W),
            _lane(-4, 2.5, "shoulder", "none"),
        ),
    )
    offset = CubicProfile((CubicPiece(0.0, 0.0), CubicPiece(500.0, -W)))
    road = Road("1", line, (before, after), lane_offset=offset)
    m = match_lanes_at(road, 500.0 - 1e-9, road, 500.0)
    assert m == {-3: -2, -4: -3, -5: -4}


def test_hermite_road_meets_both_poses():
    start = (10.0, -5.0, 0.2)
    end = (60.0, 3.0, 0.45)
    road = hermite_road(start, end, road_id="c", widths_start=[3.5, 0.0], widths_end=[3.6, 3.6])
    x0, y0, h0 = _pose(road, 0.0)
    x1, y1, h1 = _pose(road, road.length)
    assert math.hypot(x0 - start[0], y0 - start[1]) < 1e-9
    assert math.hypot(x1 - end[0], y1 - end[1]) < 1e-6
    assert abs(h0 - start[2]) < 1e-9
    assert abs(h1 - end[2]) < 1e-9
    # declared length is the true arc length (1 mm ASAM tolerance)
    s = np.linspace(0, road.length, 20001)
    true_len = float(np.sum(np.hypot(*np.diff(road.xy(s), axis=0).T)))
    assert road.length == pytest.approx(true_len, abs=1e-4)
    w = road.lane_sections[0].right[1].width
    assert float(w.value(0.0)) == pytest.approx(0.0)
    assert float(w.value(road.length)) == pytest.approx(3.6)


def test_gores_from_lane_events_match_section_scan(mainline, side):
    from roadtwin.mainline import LaneEvent
    from roadtwin.ramps import gores_from_lane_events

    k = -5 if side == "right" else 5
    events = [
        LaneEvent(300.0, "birth", side, k, "outer", 60.0, W),
        LaneEvent(500.0, "end", side, k, "outer", 0.0, W),
        LaneEvent(800.0, "birth", side, k, "outer", 0.0, W),
        LaneEvent(1000.0, "end", side, k, "outer", 60.0, W),
    ]
    got = gores_from_lane_events(events, mainline, traffic_side=side)
    assert got == gore_events(mainline, traffic_side=side)
    assert [g.station_m for g in got] == [500.0, 800.0]


def test_a_lane_ending_and_one_beginning_at_one_station_is_no_pair_of_gores(mainline, side):
    """Lanes that end at full width where lanes begin at full width at the same station,
    on the same side, are a carriageway whose lane links broke, not an exit and an entry
    at one point (melbourne-1019-lane1-s21 with a noisier sensor: such a pair drew the
    entry 90 m past its gore). The other gores stay."""
    from roadtwin.mainline import LaneEvent
    from roadtwin.ramps import gores_from_lane_events

    k = -5 if side == "right" else 5
    events = [
        LaneEvent(400.0, "end", side, k, "outer", 0.0, W),
        LaneEvent(400.0, "birth", side, k, "outer", 0.0, W),
        LaneEvent(500.0, "end", side, k, "outer", 0.0, W),
    ]
    paired = gores_from_lane_events(events, mainline, traffic_side=side)
    assert [(g.station_m, g.kind) for g in paired] == [(500.0, "exit")]
    alone = gores_from_lane_events(events[1:], mainline, traffic_side=side)
    assert [(g.station_m, g.kind) for g in alone] == [(400.0, "entry"), (500.0, "exit")]


def test_unlink_width_jumps_drops_only_jumping_links():
    """A lane whose width jumps at a section boundary is unlinked on both sides; a lane
    that continues smoothly keeps its links."""
    from roadtwin.model import CubicProfile, Lane, LaneSection, Line, Road
    from roadtwin.topology import unlink_width_jumps

    a = LaneSection(
        0.0,
        right=(
            Lane(-1, "driving", CubicProfile.constant(3.5), successor=-1),
            Lane(-2, "shoulder", CubicProfile.constant(2.5), successor=-2),
        ),
    )
    b = LaneSection(
        50.0,
        right=(
            Lane(-1, "driving", CubicProfile.constant(3.5), predecessor=-1),
            Lane(-2, "shoulder", CubicProfile.constant(0.0), predecessor=-2),
        ),
    )
    road = Road("1", (Line(0.0, 0.0, 0.0, 0.0, 100.0),), (a, b))
    out = unlink_width_jumps(road)
    first, second = out.lane_sections
    assert (first.right[0].successor, second.right[0].predecessor) == (-1, -1)
    assert (first.right[1].successor, second.right[1].predecessor) == (None, None)
    assert unlink_width_jumps(out) is out


def test_prune_zero_width_links_everywhere():
    """A lane of zero width at a contact keeps no link there: between lane sections, across
    a road link and in a junction (ASAM zero_width_at_start/end, new_lane_appear); lanes of
    width keep theirs, and what remains is mutual."""
    from roadtwin.model import (
        Connection,
        CubicPiece,
        CubicProfile,
        Junction,
        Lane,
        LaneLink,
        LaneSection,
        Line,
        Road,
        RoadLink,
    )
    from roadtwin.topology import prune_zero_width_links

    opening = CubicProfile((CubicPiece(0.0, 0.0, 0.0, 3 * 3.5 / 50**2, -2 * 3.5 / 50**3),))
    a = Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, 100.0),),
        (
            LaneSection(
                0.0, right=(Lane(-1, "driving", CubicProfile.constant(3.5), successor=-1),)
            ),
            LaneSection(
                50.0,
                right=(
                    Lane(-1, "driving", CubicProfile.constant(3.5), predecessor=-1, successor=-1),
                    Lane(-2, "driving", opening, predecessor=-1, successor=-2),
                ),
            ),
        ),
        successor=RoadLink("road", "2", "start"),
    )
    b = Road(
        "2",
        (Line(0.0, 100.0, 0.0, 0.0, 50.0),),
        (
            LaneSection(
                0.0,
                right=(
                    Lane(-1, "driving", CubicProfile.constant(3.5), predecessor=-1),
                    Lane(-2, "driving", CubicProfile.constant(0.0), predecessor=-2, successor=-1),
                ),
            ),
        ),
        predecessor=RoadLink("road", "1", "end"),
        successor=RoadLink("junction", "9"),
    )
    c = Road(
        "3",
        (Line(0.0, 150.0, 0.0, 0.0, 20.0),),
        (LaneSection(0.0, right=(Lane(-1, "driving", CubicProfile.constant(3.5)),)),),
        junction="9",
    )
    j = Junction("9", (Connection("0", "2", "3", "start", (LaneLink(-1, -1), LaneLink(-2, -1))),))
    roads, junctions = prune_zero_width_links([a, b, c], [j])
    ra, rb, _ = roads
    s0, s1 = ra.lane_sections
    # the lane opening from zero width in section 2 of road 1 has no predecessor
    assert s1.right[1].predecessor is None
    assert s1.right[0].predecessor == -1
    assert s0.right[0].successor == -1
    # road 1 -> road 2: lane -2 reaches road 2's zero-width lane -2: unlinked both ways
    assert s1.right[1].successor is None
    assert rb.lane_sections[0].right[1].predecessor is None
    assert (s1.right[0].successor, rb.lane_sections[0].right[0].predecessor) == (-1, -1)
    # junction: only the lane with width is linked
    assert junctions[0].connections[0].lane_links == (LaneLink(-1, -1),)


def _road_with_median_step() -> Road:
    """1000 m straight; the median-side lane -2 leaves at s=500 (no junction): the lane
    offset steps in by a lane there and the lanes beyond are linked by geometry."""
    return _straight_two_sections(
        (
            _lane(-1, 0.75, "shoulder", "solid", succ=-1),
            _lane(-2, W),
            _lane(-3, W, succ=-2),
            _lane(-4, W, succ=-3),
            _lane(-5, 2.5, "shoulder", "none", succ=-4),
        ),
        (
            _lane(-1, 0.75, "shoulder", "solid", pred=-1),
            _lane(-2, W, pred=-3),
            _lane(-3, W, pred=-4),
            _lane(-4, 2.5, "shoulder", "none", pred=-5),
        ),
        lane_offset=CubicProfile((CubicPiece(0.0, 0.0), CubicPiece(500.0, -W))),
    )


def test_the_lane_an_exit_leaves_from_is_not_linked_on_into_the_shoulder_beside_the_gore():
    """Past an exit's gore the mainline's hard shoulder begins as wide as the lane that
    left: the lanes' borders meet, so the driving lane was linked both into the ramp and
    on into that shoulder, and esmini drove a car bound along the mainline onto the
    shoulder (melbourne-408-lane1-s21 with a noisier sensor). The lane goes on as the
    ramp's lane only."""
    road = mainline_road()
    secs = list(road.lane_sections)
    k = next(i for i, sc in enumerate(secs) if sc.s0 == 500.0)
    right = list(secs[k].right)
    wide = CubicProfile((_taper(W, 2.5, 0.0, 60.0), CubicPiece(60.0, 2.5)))
    right[-1] = _lane(-5, wide, "shoulder", "none", None, -6)
    secs[k] = replace(secs[k], right=tuple(right))
    road = replace(road, lane_sections=tuple(secs))
    ramps = [r for r in make_ramps(road) if r.type == "exit"]
    topo = build_topology(road, ramps, traffic_side="right")
    (junction,) = topo.junctions
    # the through connecting road ends on a mainline road
    mains = {r.id for r in topo.roads if r.name == "mainline"}
    through = next(
        r for r in topo.roads
        if r.junction == junction.id and r.successor is not None
        and r.successor.element_id in mains
    )  # fmt: skip
    up = next(r for r in topo.roads if r.id == through.predecessor.element_id)
    up_types = {ln.id: ln.type for ln in up.lane_sections[-1].right}
    for ln in through.lane_sections[0].right:
        if ln.predecessor is not None:
            assert (up_types[ln.predecessor] == "driving") == (ln.type == "driving"), ln
    assert through.lane_sections[0].right[-1].predecessor is None
    conn = next(c for c in junction.connections if c.connecting_road == through.id)
    assert all(link.to_lane != through.lane_sections[0].right[-1].id for link in conn.lane_links)


def _straight_two_sections(before, after, lane_offset=None) -> Road:
    """A 1000 m straight mainline whose lanes are ``before`` up to s=500, ``after`` on."""
    sections = (LaneSection(0.0, right=tuple(before)), LaneSection(500.0, right=tuple(after)))
    line = (Line(0.0, 0.0, 0.0, 0.0, 1000.0),)
    if lane_offset is None:
        return Road("1", line, sections, name="mainline")
    return Road("1", line, sections, name="mainline", lane_offset=lane_offset)


def test_mainline_is_split_into_linked_roads_where_its_lane_offset_steps():
    """A left exit without a junction (OSM has no ramp there): the lane offset steps by a
    lane width at s=500. The ASAM checker evaluates a section's end with the offset record
    starting there and saw a 3.75 m gap; two roads linked end to start say the same with
    every linked lane border meeting exactly."""
    road = _road_with_median_step()
    topo = build_topology(road, [])
    mains = [r for r in topo.roads if r.name == "mainline"]
    assert len(mains) == 2
    first, second = mains
    assert first.length == pytest.approx(500.0)
    assert second.length == pytest.approx(500.0)
    assert first.successor.element_type == "road"
    assert first.successor.element_id == second.id
    assert second.predecessor.element_id == first.id
    # each road's lane offset is one level: no step inside a road
    for r in mains:
        values = r.lane_offset.value(np.linspace(0.0, r.length, 101))
        assert float(np.ptp(values)) < 1e-9
    # the through lanes are linked by geometry and their borders meet at the link
    links = {ln.id: ln.successor for ln in first.lane_sections[-1].right}
    assert links[-3] == -2
    assert links[-4] == -3
    assert links[-2] is None  # the lane that leaves on the median side
    for a, b in ((-3, -2), (-4, -3)):
        end = _lane_border_xy(first, first.length, a)
        start = _lane_border_xy(second, 0.0, b)
        assert float(np.max(np.abs(end - start))) < 1e-6
    findings = check_network(_network(topo))
    assert not [f for f in findings if f.severity == "error"]


def _exit_at_493(road: Road) -> Ramp:
    """A 1-lane outer exit leaving lane -4 of a straight mainline at s=493."""
    s_osm = np.arange(480.0, 800.0, 20.0)
    xy = road.to_xy(s_osm, -(0.75 + 2.5 * W) - 0.0012 * np.clip(s_osm - 480.0, 0, None) ** 2)
    ramp_road, gap, dh = build_ramp_road(
        xy, road, ramp_type="exit", lanes=1, station_m=493.0, source_lane_ids=(-4,),
        road_id="rexit", config=RampConfig(),
    )  # fmt: skip
    return Ramp(
        type="exit", road=ramp_road, station_m=493.0, lanes=1, lane_rule="lanes",
        osm_lanes=1, osm_lane_rule="lanes", station_source="osm", mainline_lane_ids=(-4,),
        type_connectivity="exit", type_geometry="exit", osm_way_ids=(), attach_gap_m=gap,
        attach_heading_deg=dh,
    )  # fmt: skip


def _through_connector(road: Road, ramp: Ramp):
    """The topology of ``road`` with ``ramp`` and its one through connecting road."""
    topo = build_topology(road, [ramp])
    roads = {r.id: r for r in topo.roads}
    through = [r for r in topo.roads if r.name == "connector" and r.successor.element_id != "rexit"]
    through = [r for r in through if roads[r.successor.element_id].name == "mainline"]
    assert len(through) == 1
    return topo, through[0]


def test_junction_zone_ends_at_a_lane_section_border_inside_it():
    """A lane section border 7 m past an exit's gore (the hard shoulder narrows there):
    the through connecting road ends at it and holds one lane section (lanes renumbered
    inside a connecting road made esmini take a through lane's link into a shoulder)."""
    line = (Line(0.0, 0.0, 0.0, 0.0, 1000.0),)
    lanes = [
        _lane(-1, 0.75, "shoulder", "solid", succ=-1),
        _lane(-2, W, succ=-2),
        _lane(-3, W, succ=-3),
        _lane(-4, W, succ=-4),
        _lane(-5, 2.5, "shoulder", "none", succ=-5),
    ]
    after = [replace(ln, predecessor=ln.id, successor=None) for ln in lanes]
    after[-1] = replace(after[-1], width=CubicProfile((CubicPiece(0.0, 2.0),)))
    road = Road(
        "1",
        line,
        (LaneSection(0.0, right=tuple(lanes)), LaneSection(500.0, right=tuple(after))),
        name="mainline",
    )
    topo, conn = _through_connector(road, _exit_at_493(road))
    assert conn.length == pytest.approx(7.0, abs=1e-6)
    assert len(conn.lane_sections) == 1
    findings = check_network(_network(topo))
    assert not [f for f in findings if f.severity == "error"]


def test_junction_zone_ends_at_a_lane_offset_step_inside_it():
    """An outer exit at s=493 and a median-side lane leaving at s=500 (the lane offset
    steps there), 7 m into the exit's 20 m junction: the through connecting road ends at
    the step, so that no offset step lies inside it (its lanes could not be linked across
    one), and every through lane is linked on through the junction to the next road with
    its borders meeting."""
    road = _road_with_median_step()
    topo, conn = _through_connector(road, _exit_at_493(road))
    roads = {r.id: r for r in topo.roads}
    assert conn.length == pytest.approx(7.0, abs=1e-6)
    assert float(np.ptp(conn.lane_offset.value(np.linspace(0.0, conn.length, 21)))) < 1e-9
    down = roads[conn.successor.element_id]
    links = {ln.id: ln.successor for ln in conn.lane_sections[-1].right}
    assert links[-3] == -2
    assert links[-4] == -3
    assert links[-2] is None
    for a, b in ((-3, -2), (-4, -3)):
        end = _lane_border_xy(conn, conn.length, a)
        start = _lane_border_xy(down, 0.0, b)
        assert float(np.max(np.abs(end - start))) < 1e-6
    findings = check_network(_network(topo))
    assert not [f for f in findings if f.severity == "error"]


def test_inner_exit_stays_outside_the_border_it_leaves_from_past_an_offset_step():
    """A left exit at s=493 takes the median-side lane; the lane offset steps in by a lane
    at s=500 (the lanes that stay). OSM draws the exit from the carriageway centre. Past
    the step the carriageway's median-side border lies a lane inside the line the exit
    leaves from: the exit's reference line must not come back inside that line (it did,
    by 3.5 m, where OSM runs inside the carriageway)."""
    road = _road_with_median_step()
    s_osm = np.arange(480.0, 900.0, 20.0)
    # from the carriageway centre, bending left (to the median side) slowly
    xy = road.to_xy(s_osm, -(0.75 + 1.5 * W) + 0.0004 * np.clip(s_osm - 480.0, 0, None) ** 2)
    ramp_road, gap, _dh = build_ramp_road(
        xy, road, ramp_type="exit", lanes=1, station_m=493.0, source_lane_ids=(-2,),
        side="inner", road_id="rexit", config=RampConfig(),
    )  # fmt: skip
    assert gap < 0.01
    # the line the exit leaves from: the inner border of lane -2 at the gore (t = -0.75)
    a = np.linspace(0.0, 80.0, 161)
    _, t = road.project(ramp_road.xy(a))
    assert float(np.min(t)) > -0.75 - 0.05


def test_a_ramp_is_not_fed_by_a_lane_that_has_not_opened_at_the_junction():
    """The measured lane an entry joins may still be of zero width where the junction
    ends (its opening fitted a few metres late): linked there the ramp's lanes were pruned
    (a zero-width link) and closed, the entry a dead end with a 9 m gap at its link. The
    outermost driving lane that is open there feeds it instead."""
    from roadtwin.topology import _valid_sources

    road = mainline_road()
    opening = CubicProfile((_taper(0.0, W, 0.0, 60.0), CubicPiece(60.0, W)))
    sec = road.lane_sections[1]  # s = 300..500: lane -5 opens from zero width at 300
    lanes = tuple(replace(ln, width=opening) if ln.id == -5 else ln for ln in sec.right)
    road = replace(road, lane_sections=(*road.lane_sections[:1], replace(sec, right=lanes),
                                        *road.lane_sections[2:]))  # fmt: skip
    section = road.lane_sections[1]
    assert _valid_sources(section, (-5,), "right") == [-5]  # by type alone
    assert _valid_sources(section, (-5,), "right", main=road, s_main=300.0) == [-4]
    assert _valid_sources(section, (-5,), "right", main=road, s_main=400.0) == [-5]


def _drop_road(after_widths, *, succ=None):
    """A 300 m road: lanes -1 shoulder 1.0 m, -2 / -3 driving 3.5 m and -4 shoulder 2.5 m
    up to s = 200 m; beyond it the lanes ``after_widths`` (types driving ... shoulder)."""
    from roadtwin.model import Line

    before = LaneSection(
        0.0,
        right=(
            _lane(-1, 1.0, "shoulder", succ=-1),
            _lane(-2, 3.5, succ=-2),
            _lane(-3, 3.5, succ=succ),
            _lane(-4, 2.5, "shoulder"),
        ),
    )
    types = ["shoulder", *["driving"] * (len(after_widths) - 2), "shoulder"]
    after = LaneSection(
        200.0,
        right=tuple(
            _lane(-(i + 1), w, t, pred=-(i + 1) if i < 2 else None)
            for i, (w, t) in enumerate(zip(after_widths, types, strict=True))
        ),
    )
    return Road("1", (Line(0.0, 0.0, 0.0, 0.0, 300.0),), (before, after))


def test_a_driving_lane_ending_at_full_width_where_the_road_narrows_closes_by_a_taper():
    """town06-auto-s3: where the outer edge was not seen over a lane drop, the lane ended
    at full width beside the edge's step: a dead end (``roadtwin drive``: "leads nowhere").
    Closed to zero over the last 60 m of its section, the road narrows smoothly into the
    next section (outer border continuous to the millimetre). A lane whose room goes on
    (lanes redrawn, the side as wide) or that is linked is left alone."""
    from roadtwin.lane_drops import taper_lane_drops

    road = _drop_road([1.0, 3.5, 2.5])
    out, closed = taper_lane_drops(road, "right")
    assert closed == [(200.0, -3)]
    lane = out.lane_sections[0].right[2]
    w = lane.width.value(np.array([0.0, 139.9, 170.0, 200.0]))
    assert w[:2] == pytest.approx([3.5, 3.5], abs=1e-9)
    assert w[2] == pytest.approx(1.75, abs=1e-9)
    assert w[3] == pytest.approx(0.0, abs=1e-9)
    before = out.lane_border_t(np.array([199.999]), -4)[0]
    after = out.lane_border_t(np.array([200.0]), -3)[0]
    assert abs(before - after) < 1e-3
    # the side as wide beyond the border: another lane took the room, nothing closes
    same_room = _drop_road([1.0, 3.5, 3.5, 2.5])
    assert taper_lane_drops(same_room, "right") == (same_room, [])
    # linked on: not a drop
    linked = _drop_road([1.0, 3.5, 3.5, 2.5], succ=-3)
    assert taper_lane_drops(linked, "right")[1] == []
    # the paper method leaves it: its lanes end where its clusters do
    paper = PipelineConfig().with_method("paper").topology.lane_drop_taper_m
    assert paper == 0.0
    assert taper_lane_drops(road, "right", max_taper_m=paper) == (road, [])
    assert PipelineConfig().with_method("default").topology.lane_drop_taper_m == 60.0


def test_a_dropped_lane_closes_after_the_outer_edge_was_last_seen_at_full_width():
    """soderleden-s9 with a noisier sensor: the outer edge was seen at full width up to
    25 m before the lane's end, then hidden; closed over the last 60 m, the lane narrowed
    35 m where it was seen wide (edge 2 m off). The taper begins where the edge was last
    seen, and is 10 m long at least where it was seen to the end."""
    from roadtwin.lane_drops import taper_lane_drops

    road = _drop_road([1.0, 3.5, 2.5])
    out, closed = taper_lane_drops(road, "right", edge_seen_until=lambda s: min(s, 175.0))
    assert closed == [(200.0, -3)]
    w = out.lane_sections[0].right[2].width.value(np.array([150.0, 175.0, 187.5, 200.0]))
    assert w[:2] == pytest.approx([3.5, 3.5], abs=1e-9)
    assert w[2] == pytest.approx(1.75, abs=1e-9)
    assert w[3] == pytest.approx(0.0, abs=1e-9)
    out, _ = taper_lane_drops(road, "right", edge_seen_until=lambda s: s)
    w = out.lane_sections[0].right[2].width.value(np.array([189.9, 195.0, 200.0]))
    assert w == pytest.approx([3.5, 1.75, 0.0], abs=1e-9)
    # seen last before the longest taper: the longest taper
    out, _ = taper_lane_drops(road, "right", edge_seen_until=lambda s: 100.0)
    w = out.lane_sections[0].right[2].width.value(np.array([139.9, 170.0]))
    assert w == pytest.approx([3.5, 1.75], abs=1e-9)


def _road_with_median_side_lane_opening() -> Road:
    """1000 m straight; a lane opens beside the median shoulder at s=500 (a taper from
    zero width over 60 m): every driving lane beyond it goes on under the next id."""
    return _straight_two_sections(
        (
            _lane(-1, 0.75, "shoulder", "solid", succ=-1),
            _lane(-2, W, succ=-3),
            _lane(-3, W, succ=-4),
            _lane(-4, 2.5, "shoulder", "none", succ=-5),
        ),
        (
            _lane(-1, 0.75, "shoulder", "solid", pred=-1),
            _lane(-2, CubicProfile((_taper(0.0, W, 0.0, 60.0), CubicPiece(60.0, W)))),
            _lane(-3, W, pred=-2),
            _lane(-4, W, pred=-3),
            _lane(-5, 2.5, "shoulder", "none", pred=-4),
        ),
    )


def test_mainline_is_split_where_its_driving_lanes_are_renumbered():
    """Players plan routes by lane id along a road: esmini's planner logged "Lane id 6
    not available in lane section" on the Melbourne maps, where lanes open beside the
    median and the driving lanes beyond go on under new ids. Split there, the renumbering
    is in the road links; a shoulder renumbered beside an outer lane is left alone."""
    topo = build_topology(_road_with_median_side_lane_opening(), [])
    mains = [r for r in topo.roads if r.name == "mainline"]
    assert [round(r.length, 6) for r in mains] == [500.0, 500.0]
    first, second = mains
    assert (first.successor.element_id, second.predecessor.element_id) == (second.id, first.id)
    links = {ln.id: ln.successor for ln in first.lane_sections[-1].right}
    assert (links[-2], links[-3]) == (-3, -4)
    for a, b in ((-2, -3), (-3, -4)):
        end = _lane_border_xy(first, first.length, a)
        start = _lane_border_xy(second, 0.0, b)
        assert float(np.max(np.abs(end - start))) < 1e-6
    findings = check_network(_network(topo))
    assert not [f for f in findings if f.severity == "error"]
    # the shared layout's decel lane renumbers only the hard shoulder: one road
    assert len([r for r in build_topology(mainline_road(), []).roads if r.name == "mainline"]) == 1


def test_linked_borders_meet_at_a_junction_cut_at_a_lane_offset_step():
    """town06-auto-s9, noisier sensor (seed 49): the through connecting road starts at a
    lane-offset step where two inner lanes begin; their widths and the step differ by
    14.7 mm in total, so every linked border was 14.7 mm off at the joint (ASAM and own
    check: link_gap). The through road's offset is corrected there, fading out."""
    from roadtwin.model import CubicProfile, LaneSection
    from roadtwin.topology import _align_linked_borders

    up = Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, 100.0),),
        (LaneSection(0.0, right=(_lane(-1, 1.6, "shoulder"), _lane(-2, 3.5), _lane(-3, 3.5))),),
    )
    through = Road(
        "2",
        (Line(0.0, 100.0, 0.0, 0.0, 20.0),),
        (
            LaneSection(
                0.0,
                right=(
                    _lane(-1, 1.6, "shoulder"),
                    _lane(-2, 3.4853),  # 14.7 mm narrower than the step
                    _lane(-3, 3.5),
                    _lane(-4, 3.5),
                ),
            ),
        ),
        lane_offset=CubicProfile.constant(3.5),
    )
    links = {-2: -3, -3: -4}
    gap = float(up.lane_border_t(np.array([100.0]), -2)[0]) - float(
        through.lane_border_t(np.array([0.0]), -3)[0]
    )
    assert gap == pytest.approx(-0.0147, abs=1e-9)
    fixed = _align_linked_borders(through, up, links)
    for a, b in links.items():
        t_up = float(up.lane_border_t(np.array([100.0]), a)[0])
        assert float(fixed.lane_border_t(np.array([0.0]), b)[0]) == pytest.approx(t_up, abs=1e-9)
    # the far end is unchanged, and a gap of more than 5 cm is another lane, not a cut
    assert float(fixed.lane_offset.value(np.array([20.0]))[0]) == pytest.approx(3.5)
    wide = replace(through, lane_offset=CubicProfile.constant(3.6))
    assert _align_linked_borders(wide, up, links) is wide


def test_a_driving_lane_ending_at_full_width_into_a_wider_shoulder_closes_by_a_taper():
    """town06-auto-s2, noisier sensor (seed 22): the outer lane's line went unseen for 72 m,
    so the lane ended at full width where the shoulder beyond the border is as wide as the
    lane and the shoulder together: the road does not narrow, and the lane led nowhere
    (``roadtwin drive`` failed). It closes over the shoulder's widening, the outer edge
    stays where it was; a lane that a driving lane beyond the border covers stays."""
    from roadtwin.lane_drops import taper_lane_drops

    road = _drop_road([1.0, 3.5, 6.0])
    out, closed = taper_lane_drops(road, "right")
    assert closed == [(200.0, -3)]
    lanes = out.lane_sections[0].right
    w = lanes[2].width.value(np.array([0.0, 139.9, 200.0]))
    assert w == pytest.approx([3.5, 3.5, 0.0], abs=1e-9)
    assert float(lanes[3].width.value(np.array([200.0]))[0]) == pytest.approx(6.0, abs=1e-9)
    ds = np.linspace(0.0, 199.999, 500)
    edge = out.lane_border_t(ds, -4)
    assert float(np.max(np.abs(edge + 10.5))) < 1e-9
    # beyond the border a driving lane covers it (a lane redrawn): left alone
    covered = _drop_road([1.0, 3.5, 3.5, 2.5])
    assert taper_lane_drops(covered, "right") == (covered, [])


def test_a_section_border_next_to_a_zone_end_does_not_leave_a_sliver():
    # The mainline's section border lies 4 cm inside where the entry's junction zone would
    # start. Cut there, the through connecting road began with a section 4 cm long, which
    # esmini read past ("target lane not driving", melbourne-921-s2 with a noisier
    # sensor); the zone now starts on the border.
    road = mainline_road("right")
    ramps = make_ramps(road, "right")
    entry = next(r for r in ramps if r.type == "entry")
    zone_start = entry.station_m - TopologyConfig().junction_length_m
    border = zone_start + 0.04
    secs = list(road.lane_sections)
    k = max(i for i, sc in enumerate(secs) if sc.s0 < border)
    before = replace(secs[k], right=tuple(replace(ln, successor=ln.id) for ln in secs[k].right))
    after = replace(
        secs[k], s0=border, right=tuple(replace(ln, predecessor=ln.id) for ln in secs[k].right)
    )
    road = replace(road, lane_sections=(*secs[:k], before, after, *secs[k + 1 :]))
    topo = build_topology(road, ramps, traffic_side="right")
    assert not topo.skipped
    net = _network(topo)
    for r in net.roads:
        ends = [sc.s0 for sc in r.lane_sections] + [r.length]
        assert min(np.diff(ends)) > 0.5, (r.id, r.name, ends)
    through = [
        r
        for r in net.roads
        if r.name == "connector" and r.successor is not None and r.successor.element_id == "3"
    ]
    assert through
    assert through[0].length == pytest.approx(20.0 - 0.04, abs=1e-6)
    findings = check_network(net)
    assert not [f for f in findings if f.severity == "error"]


def test_a_driving_lane_that_narrowed_is_not_linked_on_into_a_shoulder():
    """town06-auto-s3 with a noisier sensor: a driving lane narrowed to 0.5 m at a
    junction cut and was linked by its borders into the next road's 0.5 m shoulder;
    esmini's car in that lane ended on the shoulder. Narrowed below 2 m, it has closed: no
    link. The lanes that go on are linked as before."""
    from roadtwin.topology import _end_to_start_links

    line = (Line(0.0, 0.0, 0.0, 0.0, 100.0),)
    narrowing = CubicProfile((_taper(W, 0.5, 0.0, 100.0),))
    up = Road(
        "1",
        line,
        (
            LaneSection(
                0.0,
                right=(
                    _lane(-1, 0.75, "shoulder", "solid"),
                    _lane(-2, W),
                    _lane(-3, narrowing),
                    _lane(-4, 0.6, "shoulder", "none"),
                ),
            ),
        ),
        name="mainline",
    )
    down_lanes = (
        _lane(-1, 0.75, "shoulder", "solid"),
        _lane(-2, W),
        _lane(-3, 0.5, "shoulder", "none"),
        _lane(-4, 0.6, "shoulder", "none"),
    )
    down = Road(
        "2", (Line(0.0, 100.0, 0.0, 0.0, 100.0),), (LaneSection(0.0, right=down_lanes),),
        name="mainline",
    )  # fmt: skip
    assert _end_to_start_links(up, down, "right") == {-1: -1, -2: -2, -4: -4}
    wide = replace(down, lane_sections=(LaneSection(0.0, right=(*down_lanes[:2],
        _lane(-3, 0.5), down_lanes[3])),))  # fmt: skip
    assert _end_to_start_links(up, wide, "right")[-3] == -3  # driving on: still linked


def test_no_lane_of_the_built_roads_ends_below_zero_width():
    """melbourne-1226 (seed 11): a lane closing at a road's end reached -1.7 mm there (an
    error for ASAM and roadtwin check). Every width piece of every built road is kept at
    or above zero; a lane that stays positive is left exactly as it was."""
    drop = 3.5 + 0.002  # from 3.5 m to -2 mm over the last 150 m, flat at both ends
    closing = CubicProfile(
        (
            CubicPiece(0.0, 3.5, 0.0, 0.0, 0.0),
            CubicPiece(150.0, 3.5, 0.0, -3.0 * drop / 150.0**2, 2.0 * drop / 150.0**3),
        )
    )
    end = closing.value(np.array([300.0]))[0]
    assert -0.005 < end < 0.0  # the fitted closing lane overshoots zero at the end
    road = Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, 300.0),),
        (
            LaneSection(
                0.0,
                right=(
                    Lane(-1, "shoulder", CubicProfile.constant(1.0), (RoadMark(0.0, "solid"),)),
                    Lane(-2, "driving", CubicProfile.constant(3.5), (RoadMark(0.0, "broken"),)),
                    Lane(-3, "driving", closing, (RoadMark(0.0, "solid"),)),
                ),
            ),
        ),
        name="mainline",
    )
    topo = build_topology(road, [])
    (built,) = [r for r in topo.roads if r.name == "mainline"]
    lanes = {ln.id: ln for ln in built.lane_sections[0].right}
    s = np.linspace(0.0, 300.0, 3001)
    assert lanes[-3].width.value(s).min() > -1e-9
    assert lanes[-3].width.value(np.array([300.0]))[0] == pytest.approx(0.0, abs=1e-9)
    assert lanes[-2].width == road.lane_sections[0].right[1].width


def test_a_mainline_piece_is_never_split_into_a_sliver():
    """Offset steps and renumbering borders split the mainline between junctions, but a
    step within ``min_road_length_m`` of a piece's end (or of the previous split) stays
    inside the road: a step 1.9 m past an exit's junction made a road no car could drive a
    lane of (oakland-28393854-lane1-s21)."""
    from roadtwin.topology import _split_stations

    assert _split_stations([1396.0, 1700.0, 1702.0, 2163.0], 1394.1, 2165.0, 5.0) == [1700.0]
    assert _split_stations([10.0, 20.0], 0.0, 100.0, 5.0) == [10.0, 20.0]
    assert _split_stations([3.0, 97.0], 0.0, 100.0, 5.0) == []
