"""OpenDRIVE writer and reader: round trips, schema validity, determinism, other tools' maps."""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from lxml import etree

from roadtwin._errors import InputError, InputWarning
from roadtwin.model import (
    Arc,
    CubicPiece,
    CubicProfile,
    Header,
    Lane,
    LaneSection,
    Line,
    ParamPoly3,
    Poly3,
    Road,
    RoadMark,
    RoadNetwork,
    Spiral,
)
from roadtwin.xodr import read_xodr, schema_errors, to_xodr_bytes, write_xodr

sys.path.insert(0, str(Path(__file__).parent))
from networks import GEO_REFERENCE, mainline_exit_network

HAVE_SCHEMA = importlib.util.find_spec("qc_opendrive") is not None
NEEDS_SCHEMA = pytest.mark.skipif(
    not HAVE_SCHEMA, reason="the 1.8 XSD ships with asam-qc-opendrive (roadtwin[validate])"
)

DATA = Path(__file__).parent / "data" / "xodr"
SHARED_TOWN06 = Path("/work/shared/data/xodr/Town06.xodr")


def _find(name: str) -> str | None:
    here = Path(sys.executable).parent / name
    return str(here) if here.is_file() else shutil.which(name)


# ---------------------------------------------------------------------------
# a network with every geometry type and every s-profile
# ---------------------------------------------------------------------------

GEOMETRIES = {
    "line": Line(0.0, 10.0, -5.0, 0.3, 120.0),
    "arc": Arc(0.0, -20.0, 40.0, 1.2, 150.0, curvature_per_m=-1.0 / 180.0),
    "spiral": Spiral(0.0, 100.0, 200.0, -0.7, 90.0, curv_start=0.002, curv_end=-0.011),
    "poly3": Poly3(0.0, 5.0, 5.0, 2.0, 80.0, a=0.0, b=0.0, c=0.002, d=-1.5e-5),
    "pp3_arclength": ParamPoly3(
        0.0, 300.0, 10.0, 0.1, 60.0, 0.0, 1.0, -1e-4, 2e-7, 0.0, 0.0, 0.003, -2e-5, "arcLength"
    ),
    "pp3_normalized": ParamPoly3(
        0.0, -300.0, 10.0, 3.0, 75.0, 0.0, 74.0, 1.5, -0.5, 0.0, 0.0, 6.0, -2.0, "normalized"
    ),
}


def _rich_road(road_id: str, geometry) -> Road:
    length = geometry.length
    half = round(length / 2.0, 3)
    sec0 = LaneSection(
        0.0,
        left=(
            Lane(
                1,
                "shoulder",
                CubicProfile((CubicPiece(0.0, 1.0, 0.001), CubicPiece(10.0, 1.01, 0.0, 1e-5))),
                (RoadMark(0.0, "solid"),),
                successor=1,
            ),
        ),
        center=Lane(0, "none", CubicProfile(), (RoadMark(0.0, "none"),)),
        right=(
            Lane(-1, "driving", CubicProfile.constant(3.5), (RoadMark(0.0, "broken"),), None, -1),
            Lane(
                -2,
                "driving",
                CubicProfile((CubicPiece(0.0, 3.4, 0.0, 1e-4, -1e-6),)),
                (RoadMark(0.0, "solid", 0.2, "white"),),
                None,
                -2,
            ),
        ),
    )
    sec1 = LaneSection(
        half,
        left=(Lane(1, "shoulder", CubicProfile.constant(1.1), (), predecessor=1),),
        center=Lane(0, "none", CubicProfile(), ()),
        right=(
            Lane(-1, "driving", CubicProfile.constant(3.5), (), -1, None),
            Lane(-2, "driving", CubicProfile.constant(3.6), (RoadMark(5.0, "broken"),), -2),
            Lane(-3, "exit", CubicProfile((CubicPiece(0.0, 0.0, 0.0, 0.01, -1e-4),))),
        ),
    )
    return Road(
        road_id,
        (geometry,),
        (sec0, sec1),
        name="other",
        elevation=CubicProfile(
            (CubicPiece(0.0, 12.0, 0.01, 1e-5, -1e-8), CubicPiece(half, 12.5, -0.004))
        ),
        superelevation=CubicProfile((CubicPiece(0.0, 0.02, 1e-4),)),
        lane_offset=CubicProfile((CubicPiece(0.0, 0.0, 0.0, 1e-4, -1e-6), CubicPiece(half, 0.3))),
        speed_limit_mps=25.0,
    )


def _rich_network() -> RoadNetwork:
    roads = tuple(_rich_road(str(i + 1), g) for i, g in enumerate(GEOMETRIES.values()))
    # one road made of chained pieces of every type
    pieces = []
    s, pose = 0.0, (0.0, -500.0, 0.0)
    for g in GEOMETRIES.values():
        piece = replace(g, s0=s, x0=pose[0], y0=pose[1], hdg=pose[2])
        pieces.append(piece)
        s += piece.length
        pose = piece.end_pose()
    chained = replace(_rich_road("100", GEOMETRIES["line"]), geometry=tuple(pieces))
    header = Header(
        name="all geometry",
        geo_reference=GEO_REFERENCE + " +no_defs",
        offset=(1000.0, 2000.0, 30.0, 0.1),
        data_quality={
            "xy_absolute": 0.05,
            "xy_relative": 0.01,
            "z_absolute": 0.1,
            "z_relative": 0.02,
        },
    )
    return RoadNetwork(header, (*roads, chained))


@pytest.fixture(scope="module")
def rich(tmp_path_factory):
    net = _rich_network()
    path = write_xodr(net, tmp_path_factory.mktemp("rich") / "rich.xodr")
    return net, path, read_xodr(path)


def _samples(road: Road) -> np.ndarray:
    return np.linspace(0.0, road.length, 301)


@pytest.mark.parametrize("road_index", range(len(GEOMETRIES) + 1))
def test_round_trip_sampled_points_agree(rich, road_index):
    net, _, back = rich
    a, b = net.roads[road_index], back.roads[road_index]
    s = _samples(a)
    xa, ya, ha, _ = a.evaluate(s)
    xb, yb, hb, _ = b.evaluate(s)
    assert np.max(np.hypot(xa - xb, ya - yb)) < 1e-6
    assert np.max(np.abs(np.angle(np.exp(1j * (ha - hb))))) < 1e-9
    assert np.max(np.abs(a.height(s) - b.height(s))) < 1e-6
    assert np.max(np.abs(a.superelevation.value(s) - b.superelevation.value(s))) < 1e-9
    for lane_id in (2, 1, 0, -1, -2, -3):
        ta, tb = a.lane_border_t(s, lane_id), b.lane_border_t(s, lane_id)
        np.testing.assert_array_equal(np.isnan(ta), np.isnan(tb))
        ok = ~np.isnan(ta)
        pa = a.to_xy(s[ok], ta[ok])
        pb = b.to_xy(s[ok], tb[ok])
        assert np.max(np.hypot(*(pa - pb).T), initial=0.0) < 1e-6


def test_round_trip_model_is_identical(rich):
    net, _, back = rich
    assert back.roads == net.roads
    assert back.junctions == net.junctions
    assert back.header.geo_reference == GEO_REFERENCE  # +no_defs removed
    assert back.header.offset == net.header.offset
    assert back.header.data_quality == net.header.data_quality
    assert (back.header.rev_major, back.header.rev_minor) == (1, 8)


def test_every_geometry_type_is_written(rich):
    _, path, _ = rich
    root = etree.parse(str(path)).getroot()
    tags = {etree.QName(c).localname for g in root.iter("geometry") for c in g}
    assert tags == {"line", "arc", "spiral", "poly3", "paramPoly3"}
    p_ranges = {e.get("pRange") for e in root.iter("paramPoly3")}
    assert p_ranges == {"arcLength", "normalized"}
    # the chained road's pieces meet exactly in the written file
    back = read_xodr(path)
    chained = back.road("100")
    for g0, g1 in zip(chained.geometry[:-1], chained.geometry[1:], strict=False):
        x, y, h = g0.end_pose()
        assert np.hypot(g1.x0 - x, g1.y0 - y) < 1e-9
        assert abs(g1.hdg - h) < 1e-12


@NEEDS_SCHEMA
def test_written_files_are_schema_valid_1_8(rich, tmp_path):
    _, path, _ = rich
    assert schema_errors(path) == []
    for jt in ("default", "direct"):
        data = to_xodr_bytes(mainline_exit_network(jt))
        assert schema_errors(data) == []
    # the validator does catch a broken file
    bad = Path(path).read_bytes().replace(b'revMajor="1"', b'revMajor="1" bogus="x"', 1)
    assert schema_errors(bad)


def test_header_and_determinism(rich):
    net, path, back = rich
    data = Path(path).read_bytes()
    assert data == to_xodr_bytes(net)
    assert to_xodr_bytes(back) == data  # read -> write reproduces the bytes
    root = etree.fromstring(data)
    header = root.find("header")
    assert header.get("revMajor") == "1"
    assert header.get("revMinor") == "8"
    assert header.get("date") is None  # no timestamp unless the model has one
    assert b"<geoReference><![CDATA[+proj=tmerc" in data
    assert b"+no_defs" not in data
    assert header.find("offset").get("hdg") == "0.1"
    assert header.find("dataQuality/error").get("xyAbsolute") == "0.05"
    dated = replace(net, header=replace(net.header, date="2024-05-01T12:00:00"))
    assert etree.fromstring(to_xodr_bytes(dated)).find("header").get("date") == (
        "2024-05-01T12:00:00"
    )


def test_write_is_atomic_and_overwrites(tmp_path):
    net = mainline_exit_network("default")
    target = tmp_path / "map.xodr"
    target.write_text("old")
    write_xodr(net, target)
    assert target.read_bytes() == to_xodr_bytes(net)
    assert sorted(os.listdir(tmp_path)) == ["map.xodr"]  # no temp file left behind


def test_lane_links_both_directions_on_connecting_roads():
    net = mainline_exit_network("default")
    root = etree.fromstring(to_xodr_bytes(net))
    connectors = [r for r in root.iter("road") if r.get("junction") != "-1"]
    assert len(connectors) == 2
    for road in connectors:
        for lane in road.iter("lane"):
            if lane.get("type") != "driving":
                continue
            assert lane.find("link/predecessor") is not None
            assert lane.find("link/successor") is not None
    links = {
        (c.get("incomingRoad"), c.get("connectingRoad")): [
            (int(ll.get("from")), int(ll.get("to"))) for ll in c.iter("laneLink")
        ]
        for c in root.iter("connection")
    }
    assert sorted(links[("1", "102")]) == [(-5, -2), (-4, -1)]
    assert sorted(links[("1", "101")]) == [(-3, -3), (-2, -2), (-1, -1)]


def test_direct_junction_uses_linked_road():
    root = etree.fromstring(to_xodr_bytes(mainline_exit_network("direct")))
    junction = root.find("junction")
    assert junction.get("type") == "direct"
    cons = junction.findall("connection")
    assert [c.get("linkedRoad") for c in cons] == ["2", "3"]
    assert all(c.get("connectingRoad") is None for c in cons)
    back = read_xodr_bytes(to_xodr_bytes(mainline_exit_network("direct")))
    assert back.junctions == mainline_exit_network("direct").junctions


def read_xodr_bytes(data: bytes, tmp_dir: Path | None = None) -> RoadNetwork:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "x.xodr"
        p.write_bytes(data)
        return read_xodr(p)


# ---------------------------------------------------------------------------
# other tools' maps
# ---------------------------------------------------------------------------


def _max_piece_gap_m(road: Road) -> float:
    gaps = [0.0]
    for g0, g1 in zip(road.geometry[:-1], road.geometry[1:], strict=False):
        x, y, _ = g0.end_pose()
        gaps.append(float(np.hypot(g1.x0 - x, g1.y0 - y)))
    return max(gaps)


def test_reads_esmini_soderleden():
    net = read_xodr(DATA / "soderleden.xodr")
    assert (net.header.rev_major, net.header.rev_minor) == (1, 7)
    assert [r.id for r in net.roads] == ["0", "1", "2", "5", "7"]
    (junction,) = net.junctions
    assert junction.type == "direct"
    con = {c.incoming_road: c for c in junction.connections}
    assert con["2"].connecting_road == "0"  # linkedRoad
    assert [(ll.from_lane, ll.to_lane) for ll in con["5"].lane_links] == [
        (-1, -3),
        (-2, -4),
        (-3, -5),
    ]
    assert any(isinstance(g, ParamPoly3) for r in net.roads for g in r.geometry)
    # the paramPoly3 pieces evaluate to a continuous reference line
    assert max(_max_piece_gap_m(r) for r in net.roads) < 0.005
    road0 = net.road("0")
    assert len(road0.lane_sections) >= 2
    # laneOffset 3.5 m shifts the centre lane left: lane -1 ends on the reference line
    assert road0.lane_border_t(np.array([1.0]), -1)[0] == pytest.approx(0.0)
    assert road0.lane_border_t(np.array([1.0]), -3)[0] == pytest.approx(-7.0)
    assert road0.lane_border_t(np.array([1.0]), 2)[0] == pytest.approx(5.8)


def test_reads_esmini_e6mini():
    net = read_xodr(DATA / "e6mini.xodr")
    (road,) = net.roads
    assert len(road.geometry) == 17
    assert road.length == pytest.approx(1460, abs=10)
    assert _max_piece_gap_m(road) < 0.005
    assert road.elevation.pieces
    sec = road.lane_sections[0]
    assert [ln.id for ln in sec.right] == [-1, -2, -3, -4, -5, -6, -7]
    assert sum(ln.type == "driving" for ln in (*sec.left, *sec.right)) == 6


@pytest.mark.parametrize("name", ["soderleden.xodr", "e6mini.xodr"])
def test_other_tools_maps_survive_write_read(tmp_path, name):
    net = read_xodr(DATA / name)
    data = to_xodr_bytes(net)
    if HAVE_SCHEMA:
        assert schema_errors(data) == []
    (tmp_path / name).write_bytes(data)
    back = read_xodr(tmp_path / name)
    assert back.roads == net.roads
    assert back.junctions == net.junctions


def test_road_without_lane_sections_is_refused():
    net = mainline_exit_network("direct")
    bare = replace(net, roads=(replace(net.roads[0], lane_sections=()),))
    with pytest.raises(InputError, match="lane section"):
        to_xodr_bytes(bare)


@pytest.mark.skipif(not SHARED_TOWN06.is_file(), reason="Town06.xodr not available")
def test_reads_carla_town06():
    net = read_xodr(SHARED_TOWN06)
    assert (net.header.rev_major, net.header.rev_minor) == (1, 4)
    assert len(net.roads) == 200
    assert len(net.junctions) == 23
    kinds = {type(g).__name__ for r in net.roads for g in r.geometry}
    assert {"Line", "Arc"} <= kinds
    assert max(_max_piece_gap_m(r) for r in net.roads) < 0.005
    ids = set(net.id_to_road)
    back = read_xodr_bytes(to_xodr_bytes(net))
    assert back.roads == net.roads
    assert back.junctions == net.junctions
    for j in net.junctions:
        for c in j.connections:
            assert c.incoming_road in ids
            assert c.connecting_road in ids


@pytest.fixture(scope="module")
def netconvert_xodr(tmp_path_factory):
    exe = _find("netconvert")
    if exe is None:
        pytest.skip("netconvert not installed")
    tmp = tmp_path_factory.mktemp("sumo")
    ours = write_xodr(mainline_exit_network("default"), tmp / "ours.xodr")
    net_xml = tmp / "net.net.xml"
    back = tmp / "back.xodr"
    subprocess.run(
        [exe, "--opendrive-files", str(ours), "-o", str(net_xml)], check=True, capture_output=True
    )
    subprocess.run(
        [exe, "--sumo-net-file", str(net_xml), "--opendrive-output", str(back)],
        check=True,
        capture_output=True,
    )
    return back


def test_reads_netconvert_output(netconvert_xodr):
    ours = mainline_exit_network("default")
    net = read_xodr(netconvert_xodr)
    assert net.header.rev_minor == 4
    assert net.header.geo_reference.startswith("+proj=tmerc +lat_0=59.3293")
    normal = [r for r in net.roads if r.junction == "-1"]
    connecting = [r for r in net.roads if r.junction != "-1"]
    assert len(connecting) >= 2
    assert len(normal) >= 3
    ids = set(net.id_to_road)
    for r in connecting:
        assert r.predecessor.element_id in ids
        assert r.successor.element_id in ids
    # SUMO's reference lines run along our lanes: every sampled point lies within 15 m of
    # our mainline or ramp reference lines (offset by the header offset SUMO applies)
    dx, dy = net.header.offset[:2] if net.header.offset else (0.0, 0.0)
    ours_pts = np.concatenate([r.xy(np.linspace(0, r.length, 400)) for r in ours.roads])
    for r in net.roads:
        pts = r.xy(np.linspace(0, r.length, 50)) + np.array([dx, dy])
        d = np.min(np.hypot(*(pts[:, None, :] - ours_pts[None, :, :]).transpose(2, 0, 1)), axis=1)
        assert d.max() < 15.0
    total = sum(r.length for r in normal)
    assert 250.0 < total < 420.0


# ---------------------------------------------------------------------------
# reader details and errors
# ---------------------------------------------------------------------------

BORDER_XODR = """<?xml version="1.0"?>
<OpenDRIVE xmlns="http://code.asam.net/simulation/standard/opendrive_schema">
 <header revMajor="1" revMinor="6" name="b"/>
 <road id="7" junction="-1" length="50">
  <planView><geometry s="0" x="0" y="0" hdg="0" length="50"><line/></geometry></planView>
  <lanes><laneSection s="0">
   <center><lane id="0" type="none"/></center>
   <right>
    <lane id="-2" type="driving"><border sOffset="0" a="-7" b="0" c="0" d="0"/>
      <border sOffset="20" a="-7" b="-0.01" c="0" d="0"/></lane>
    <lane id="-1" type="driving"><border sOffset="0" a="-3.5" b="0" c="0" d="0"/></lane>
   </right>
  </laneSection></lanes>
 </road>
</OpenDRIVE>
"""


def test_border_records_become_widths(tmp_path):
    p = tmp_path / "border.xodr"
    p.write_text(BORDER_XODR)
    net = read_xodr(p)
    sec = net.road("7").lane_sections[0]
    assert [ln.id for ln in sec.right] == [-1, -2]  # sorted inner to outer
    assert sec.right[0].width.value(np.array([10.0]))[0] == pytest.approx(3.5)
    assert sec.right[1].width.value(np.array([10.0, 40.0])) == pytest.approx([3.5, 3.7])
    assert net.road("7").lane_border_t(np.array([40.0]), -2)[0] == pytest.approx(-7.2)


def test_mixed_border_and_width_warns(tmp_path):
    p = tmp_path / "mixed.xodr"
    p.write_text(
        BORDER_XODR.replace(
            '<border sOffset="0" a="-3.5" b="0" c="0" d="0"/>',
            '<width sOffset="0" a="3.5" b="0" c="0" d="0"/>',
        )
    )
    with pytest.warns(InputWarning, match="border"):
        read_xodr(p)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("<OpenDRIVE><header", "not well-formed"),
        ("<foo/>", "expected <OpenDRIVE>"),
        ('<OpenDRIVE><header revMajor="1" revMinor="8"/></OpenDRIVE>', "no <road>"),
        (
            '<OpenDRIVE><header/><road id="1" length="1"><planView><geometry s="0" x="a" '
            'y="0" hdg="0" length="1"><line/></geometry></planView></road></OpenDRIVE>',
            "not a number",
        ),
        (
            '<OpenDRIVE><header/><road id="1" length="1"><planView><geometry s="0" x="0" '
            'y="0" hdg="0" length="1"><clothoid/></geometry></planView></road></OpenDRIVE>',
            "unknown geometry",
        ),
    ],
)
def test_malformed_files_raise_input_error(tmp_path, content, match):
    p = tmp_path / "bad.xodr"
    p.write_text(content)
    with pytest.raises(InputError, match=match):
        read_xodr(p)


def test_missing_file_raises_input_error(tmp_path):
    with pytest.raises(InputError, match="not found"):
        read_xodr(tmp_path / "nope.xodr")
