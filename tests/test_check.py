"""``roadtwin check``: own checks in numbers, external consumers on real files, the CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from roadtwin.check import CheckConfig, check_file, check_network, find_tool, network_stats
from roadtwin.cli import main
from roadtwin.model import (
    Connection,
    CubicPiece,
    CubicProfile,
    Header,
    Junction,
    Lane,
    LaneSection,
    Line,
    Road,
    RoadLink,
    RoadNetwork,
)
from roadtwin.xodr import read_xodr, write_xodr

sys.path.insert(0, str(Path(__file__).parent))
from networks import mainline_exit_network, straight_road

DATA = Path(__file__).parent / "data" / "xodr"
HAVE_SUMO = find_tool("netconvert") is not None
HAVE_ASAM = find_tool("qc_opendrive") is not None


@pytest.fixture(scope="module")
def checked(tmp_path_factory):
    """Both fixture networks written and checked once with both external consumers."""
    tmp = tmp_path_factory.mktemp("check")
    out = {}
    for jt in ("default", "direct"):
        path = write_xodr(mainline_exit_network(jt), tmp / f"{jt}.xodr")
        out[jt] = (path, check_file(path, external=True))
    return out


def _codes(findings, severity="error"):
    return [f.code for f in findings if f.severity == severity]


# ---------------------------------------------------------------------------
# clean networks
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("junction_type", ["default", "direct"])
def test_fixture_networks_have_no_own_findings(junction_type):
    net = mainline_exit_network(junction_type)
    assert check_network(net) == []
    stats = network_stats(net)
    assert stats["max_gap_mm"] < 1e-6
    assert stats["max_link_gap_mm"] < 1e-6
    assert stats["max_link_heading_jump_deg"] < 1e-6
    # default: 1->101, 1->102, 101->2, 102->3; direct: 1->2, 1->3
    assert stats["links_checked"] == (4 if junction_type == "default" else 2)


def test_default_junction_passes_both_external_checkers(checked):
    _, report = checked["default"]
    consumers = {c.name: c for c in report.consumers}
    if not HAVE_SUMO or not HAVE_ASAM:
        pytest.skip("external checkers not installed")
    assert consumers["sumo netconvert"].status == "passed"
    assert consumers["sumo netconvert"].errors == 0
    assert consumers["asam qc_opendrive"].status == "passed"
    assert consumers["asam qc_opendrive"].issues_per_rule == {}
    assert report.errors == 0
    assert report.ok


def test_direct_junction_passes_asam_and_skips_sumo(checked):
    _, report = checked["direct"]
    consumers = {c.name: c for c in report.consumers}
    assert consumers["sumo netconvert"].status == "skipped"
    assert "SUMO cannot read direct junctions" in consumers["sumo netconvert"].messages[0]
    if not HAVE_ASAM:
        pytest.skip("qc_opendrive not installed")
    assert consumers["asam qc_opendrive"].status == "passed"
    assert consumers["asam qc_opendrive"].errors == 0
    assert report.errors == 0
    assert "SUMO cannot read direct junctions" in report.format_text()


def test_asam_checker_counts_issues_per_rule(tmp_path):
    if not HAVE_ASAM:
        pytest.skip("qc_opendrive not installed")
    # a connection lane link from a lane that does not exist: the ASAM checker and our
    # own check both see it; and esmini's soderleden sample has known issues
    report = check_file(DATA / "soderleden.xodr", external=True)
    asam = {c.name: c for c in report.consumers}["asam qc_opendrive"]
    assert asam.status == "failed"
    assert (
        asam.issues_per_rule["asam.net:xodr:1.4.0:road.lane.link.lanes_across_lane_sections"] >= 1
    )
    assert sum(asam.issues_per_rule.values()) >= asam.errors > 0
    # an error says where it is, by the ids the user looks up (from the XML locations)
    assert any(
        "lanes_across_lane_sections" in m and m.endswith("(road 7 lane -1)") for m in asam.messages
    ), asam.messages
    assert any(m.endswith("(road 0 lane -3 -> road 0 lane -2)") for m in asam.messages)
    # our own checks find the road the file links one-sidedly, 66 m away
    gaps = [f for f in report.findings if f.code == "link_gap" and f.road == "7"]
    assert gaps
    assert gaps[0].value > 60_000.0
    assert "one_sided_link" in _codes(report.findings)


# ---------------------------------------------------------------------------
# deliberately broken files
# ---------------------------------------------------------------------------


def _broken(tmp_path, network, name="broken.xodr"):
    path = write_xodr(network, tmp_path / name)
    return check_file(path, external=False)


def test_gap_between_geometries_is_caught(tmp_path):
    road = straight_road("1", 100.0)
    pieces = (Line(0.0, 0.0, 0.0, 0.0, 50.0), Line(50.0, 50.0, 0.05, 0.0, 50.0))
    net = replace(
        mainline_exit_network("direct"), roads=(replace(road, geometry=pieces),), junctions=()
    )
    report = _broken(tmp_path, net)
    (gap,) = [f for f in report.findings if f.code == "geometry_gap"]
    assert gap.severity == "error"
    assert gap.value == pytest.approx(50.0, abs=1e-6)
    assert gap.s == pytest.approx(50.0)
    assert "50.0 mm" in gap.message
    assert report.stats["max_gap_mm"] == pytest.approx(50.0, abs=1e-6)
    # a 0.5 mm gap and a 0.05 deg kink: a warning, not an error
    pieces = (Line(0.0, 0.0, 0.0, 0.0, 50.0), Line(50.0, 50.0, 0.0005, np.radians(0.05), 50.0))
    net2 = replace(net, roads=(replace(road, geometry=pieces),))
    findings = check_network(net2)
    assert _codes(findings) == []
    assert _codes(findings, "warning") == ["geometry_kink"]
    assert network_stats(net2)["max_heading_jump_deg"] == pytest.approx(0.05)


def test_negative_width_is_caught(tmp_path):
    road = straight_road("1", 100.0)
    sec = road.lane_sections[0]
    bad_lane = replace(sec.right[2], width=CubicProfile((CubicPiece(0.0, 3.5, -0.05),)))
    road = replace(
        road, lane_sections=(replace(sec, right=(*sec.right[:2], bad_lane, sec.right[3])),)
    )
    net = replace(mainline_exit_network("direct"), roads=(road,), junctions=())
    report = _broken(tmp_path, net)
    neg = [f for f in report.findings if f.code == "negative_width"]
    assert len(neg) == 1
    assert neg[0].severity == "error"
    assert neg[0].value == pytest.approx(3.5 - 0.05 * 100.0)
    assert "lane -3" in neg[0].message
    assert not report.ok


def test_width_jump_between_sections_is_caught():
    net = mainline_exit_network("default")
    road1 = net.road("1")
    sec0, sec1 = road1.lane_sections
    lane = replace(sec1.right[1], width=CubicProfile.constant(3.2))  # lane -2: 3.5 -> 3.2
    road1 = replace(
        road1, lane_sections=(sec0, replace(sec1, right=(sec1.right[0], lane, *sec1.right[2:])))
    )
    net = replace(net, roads=(road1, *net.roads[1:]))
    jumps = [f for f in check_network(net) if f.code == "width_jump"]
    assert len(jumps) == 1
    assert jumps[0].value == pytest.approx(300.0)
    assert jumps[0].s == pytest.approx(100.0)


def _second_lane_findings(pieces, code, config=None):
    """The findings ``code`` on a straight road whose second right lane has the width
    records ``pieces``: exactly one (returned) or none (None)."""
    road = _with_second_lane_width(straight_road(), pieces)
    net = RoadNetwork(Header(), (road,))
    found = [f for f in check_network(net, config=config) if f.code == code]
    assert len(found) <= 1
    return found[0] if found else None


def _with_second_lane_width(road, pieces):
    """``road`` (one lane section) with its second right lane's width records ``pieces``
    (``(s0, a, b)`` tuples, metres)."""
    sec = road.lane_sections[0]
    lane = replace(sec.right[1], width=CubicProfile(tuple(CubicPiece(*p) for p in pieces)))
    return replace(road, lane_sections=(replace(sec, right=(sec.right[0], lane, *sec.right[2:])),))


@pytest.mark.parametrize(
    ("offset", "width", "jump_mm"),
    [
        # krems-30799129-s11 with a noisier sensor: the lane offset stepped 3 m a metre
        # past a gore, inside the lane section the gore began (esmini's car jumped 1.3 m)
        (((0.0, -0.94, 0.0), (1.0, -3.93, 0.0)), None, 2990.0),
        # a width record that does not continue the one before it
        (None, ((0.0, 3.5, 0.0), (40.0, 3.1, 0.0)), 400.0),
        # the same records, continuous: nothing
        (((0.0, -0.94, 0.0), (1.0, -0.94, 0.0)), ((0.0, 3.5, 0.0), (40.0, 3.5, 0.0)), None),
    ],
)
def test_a_lane_border_jump_inside_a_lane_section_is_caught(offset, width, jump_mm):
    """``lane_jump``: a lane offset or width record inside a lane section whose value does
    not continue the one before it moves lane borders sideways there; the section and link
    rules look only at section borders and road ends, and such a map passed every check."""
    road = straight_road()
    if offset is not None:
        road = replace(road, lane_offset=CubicProfile(tuple(CubicPiece(*p) for p in offset)))
    if width is not None:
        road = _with_second_lane_width(road, width)
    net = RoadNetwork(Header(), (road,))
    jumps = [f for f in check_network(net) if f.code == "lane_jump"]
    if jump_mm is None:
        assert jumps == []
        return
    assert len(jumps) == 1
    assert jumps[0].severity == "error"
    assert jumps[0].value == pytest.approx(jump_mm, abs=1.0)
    assert jumps[0].s == pytest.approx(1.0 if offset is not None else 40.0)


@pytest.mark.parametrize(
    ("offset", "step_mm"),
    [
        (((0.0, 0.0, 0.0), (100.0, -0.5, 0.0)), 500.0),  # a step at the section border
        (((0.0, 0.0, 0.0), (100.0, 0.0, 0.0)), None),  # a record that continues
        (((0.0, 0.0, 0.0), (60.0, -0.5, 0.0)), None),  # inside a section: lane_jump's
    ],
)
def test_a_lane_offset_step_at_a_section_border_is_told(offset, step_mm):
    """``lane_offset_step`` (a warning): the ASAM checker reads a section's end with the
    lane offset record that begins at the next section, so a step there reads as a gap of
    every lane linked across it, even where a lane beside the centre widens by as much
    and the borders meet (melbourne-1019-s11 with a noisier sensor: a 0.5 m step,
    ``contact_point_no_horizontal_gaps`` on two lanes, our own rules all passed)."""
    net = mainline_exit_network("default")
    road1 = net.road("1")
    assert [sec.s0 for sec in road1.lane_sections] == [0.0, 100.0]
    road1 = replace(road1, lane_offset=CubicProfile(tuple(CubicPiece(*p) for p in offset)))
    net = replace(net, roads=(road1, *net.roads[1:]))
    found = [f for f in check_network(net) if f.code == "lane_offset_step"]
    if step_mm is None:
        assert found == []
        return
    assert len(found) == 1
    assert found[0].severity == "warning"
    assert found[0].value == pytest.approx(step_mm, abs=0.5)
    assert found[0].s == pytest.approx(100.0)


@pytest.mark.parametrize(
    ("pieces", "pinched_at"),
    [
        # melbourne-18-s11 with a noisier sensor: 3.66 m to 0 within 6 m and back to 3.5 m
        # 10 m on (esmini's car jumped 1.6 m into the next lane and stuck)
        (((0.0, 3.66, -0.6), (6.0, 0.06, 0.0), (8.0, 0.06, 0.85), (12.0, 3.46, 0.0)), 6.0),
        # a lane closing by a 60 m taper and opening again 40 m later: no pinch
        (((0.0, 3.5, -3.5 / 60.0), (60.0, 0.0, 0.0), (100.0, 0.0, 3.5 / 60.0)), None),
        # a lane that opens by a taper (narrow at the start only): nothing
        (((0.0, 0.0, 0.1), (35.0, 3.5, 0.0)), None),
    ],
)
def test_a_driving_lane_pinched_inside_a_section_is_caught(pieces, pinched_at):
    """``lane_pinch``: a driving lane that narrows to almost nothing and widens back within
    30 m: two lanes swapping their space. Width records that continue each other pass
    every other rule."""
    found = _second_lane_findings(pieces, "lane_pinch")
    if pinched_at is None:
        assert found is None
        return
    assert found.severity == "error"
    assert found.s == pytest.approx(pinched_at, abs=2.0)
    assert found.value < 0.5


def test_dangling_link_is_caught(tmp_path):
    net = mainline_exit_network("default")
    road3 = replace(net.road("3"), successor=RoadLink("road", "99", "start"))
    net = replace(net, roads=(*net.roads[:4], road3))
    report = _broken(tmp_path, net)
    dangling = [f for f in report.findings if f.code == "dangling_link"]
    assert len(dangling) == 1
    assert dangling[0].road == "3"
    assert "road 99" in dangling[0].message
    assert "does not exist" in dangling[0].message


def test_missing_lane_link_is_caught(tmp_path):
    net = mainline_exit_network("default")
    (j,) = net.junctions
    cons = (j.connections[0], replace(j.connections[1], lane_links=()))
    net = replace(net, junctions=(replace(j, connections=cons),))
    report = _broken(tmp_path, net)
    missing = [f for f in report.findings if f.code == "missing_lane_link"]
    assert len(missing) == 1
    assert missing[0].severity == "error"
    assert missing[0].junction == "100"
    assert missing[0].road == "102"
    assert "has no laneLink" in missing[0].message


def test_one_sided_link_is_caught():
    net = mainline_exit_network("default")
    c101 = replace(net.road("101"), successor=None)  # 2 says predecessor junction 100 ...
    road2 = replace(net.road("2"), predecessor=RoadLink("road", "101", "end"))
    road2 = replace(road2, predecessor=RoadLink("road", "101", "end"))
    net = replace(net, roads=(net.roads[0], c101, net.roads[2], road2, net.roads[4]))
    one_sided = [f for f in check_network(net) if f.code == "one_sided_link"]
    assert [f.road for f in one_sided] == ["2"]
    assert "does not link back to road 2" in one_sided[0].message


def test_gap_across_link_is_caught():
    net = mainline_exit_network("default")
    road2 = net.road("2")

    def with_road2(**change):
        geometry = tuple(
            replace(g, **{k: getattr(g, k) + v for k, v in change.items()}) for g in road2.geometry
        )
        return replace(net, roads=(*net.roads[:3], replace(road2, geometry=geometry), net.roads[4]))

    findings = check_network(with_road2(y0=0.02))  # road 2 shifted 2 cm sideways
    gap = [f for f in findings if f.code == "link_gap"]
    assert len(gap) == 1
    assert gap[0].severity == "error"
    assert gap[0].value == pytest.approx(20.0, abs=1e-6)
    assert "road 101 end -> road 2 start" in gap[0].message
    assert not [f for f in findings if f.code == "link_kink"]

    findings = check_network(with_road2(hdg=np.radians(0.5)))  # turned by 0.5 deg
    (kink,) = [f for f in findings if f.code == "link_kink"]
    assert kink.value == pytest.approx(0.5)
    # the lane borders 10.5 m from the reference line move by 10.5 m * 0.5 deg
    (gap,) = [f for f in findings if f.code == "link_gap"]
    assert gap.value == pytest.approx(10500.0 * np.radians(0.5), rel=1e-3)


def test_bad_geo_reference_and_junction_target(tmp_path):
    net = mainline_exit_network("direct")
    net = replace(net, header=replace(net.header, geo_reference="+proj=nonsense +foo"))
    (j,) = net.junctions
    extra = Connection("9", "1", "77", "start", ())
    net = replace(net, junctions=(replace(j, connections=(*j.connections, extra)),))
    codes = _codes(check_network(net))
    assert "geo_reference" in codes
    assert codes.count("dangling_link") == 1
    assert codes.count("missing_lane_link") == 1
    assert isinstance(net.junctions[0], Junction)


def test_thresholds_are_configurable():
    road = straight_road("1", 100.0)
    pieces = (Line(0.0, 0.0, 0.0, 0.0, 50.0), Line(50.0, 50.0, 0.005, 0.0, 50.0))
    net = replace(
        mainline_exit_network("direct"), roads=(replace(road, geometry=pieces),), junctions=()
    )
    assert _codes(check_network(net), "warning") == ["geometry_gap"]
    strict = CheckConfig(gap_warning_mm=0.1, gap_error_mm=1.0)
    assert _codes(check_network(net, config=strict)) == ["geometry_gap"]


@pytest.mark.parametrize(
    ("pieces", "widest"),
    [
        # town06-auto-lane2-s22 with a noisier sensor: a lane line continued 4 m out to
        # the shoulder's place over the run's last metres, a lane widening to 7.5 m
        (((0.0, 3.5, 0.0), (90.0, 3.5, 0.4)), 7.5),
        # a lane 4.5 m wide (a wide lane on a bend): nothing
        (((0.0, 4.5, 0.0),), None),
    ],
)
def test_a_driving_lane_wider_than_any_real_lane_is_reported(pieces, widest):
    """``lane_wide``: a driving lane wider than 6 m anywhere (a warning: valid OpenDRIVE,
    but two lanes' space in one or a shoulder taken for a lane; the maps that had one
    passed every check)."""
    found = _second_lane_findings(pieces, "lane_wide")
    if widest is None:
        assert found is None
        return
    assert found.severity == "warning"
    assert found.value == pytest.approx(widest, abs=0.05)
    assert found.s == pytest.approx(100.0, abs=1.0)
    assert _second_lane_findings(pieces, "lane_wide", CheckConfig(wide_lane_m=8.0)) is None


def test_other_tools_clean_map_has_no_errors():
    report = check_file(DATA / "e6mini.xodr", external=False)
    assert report.errors == 0
    assert report.stats["max_gap_mm"] < 5.0
    assert report.stats["geometries"] == 17


# ---------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------


def test_cli_exit_codes_and_json(checked, tmp_path, capsys):
    path, _ = checked["default"]
    assert main(["check", str(path), "--no-external"]) == 0
    text = capsys.readouterr().out
    assert "max gap between pieces 0.000 mm" in text
    assert "OK: 0 errors" in text

    net = mainline_exit_network("default")
    road3 = replace(net.road("3"), successor=RoadLink("road", "99", "start"))
    bad = write_xodr(replace(net, roads=(*net.roads[:4], road3)), tmp_path / "bad.xodr")
    assert main(["check", str(bad), "--no-external", "--json"]) == 1
    data = json.loads(capsys.readouterr().out)
    assert list(data) == ["file", "ok", "errors", "warnings", "stats", "findings", "consumers"]
    assert data["ok"] is False
    assert data["errors"] == 1
    assert list(data["findings"][0]) == [
        "severity",
        "code",
        "road",
        "junction",
        "s",
        "value",
        "message",
    ]
    assert data["findings"][0]["code"] == "dangling_link"
    assert data["consumers"] == []

    broken = tmp_path / "garbage.xodr"
    broken.write_text("<OpenDRIVE><road")
    assert main(["check", str(broken)]) == 2
    assert "not well-formed XML" in capsys.readouterr().err


def test_cli_subprocess_json(checked):
    path, _ = checked["direct"]
    exe = find_tool("roadtwin")
    cmd = [exe] if exe else [sys.executable, "-m", "roadtwin"]
    proc = subprocess.run(
        [*cmd, "check", str(path), "--json", "--no-external"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["stats"]["direct_junctions"] == 1
    assert data["stats"]["max_link_gap_mm"] < 1e-6
    assert read_xodr(path).junctions[0].type == "direct"


def test_missing_consumers_are_reported_and_own_checks_still_run(checked, monkeypatch):
    import roadtwin.consumers as consumers_module

    monkeypatch.setattr(consumers_module, "find_tool", lambda name: None)
    path, _ = checked["default"]
    report = check_file(path, external=True)
    assert [c.status for c in report.consumers] == ["not installed", "not installed"]
    assert report.ok
    assert report.stats["links_checked"] == 4
    assert "sumo netconvert: not installed" in report.format_text()


def test_zero_width_lane_end_with_link_is_an_error():
    """A lane tapering to zero width that still names a successor is caught (ASAM rule)."""
    from dataclasses import replace

    from roadtwin.check import check_network
    from roadtwin.model import (
        CubicPiece,
        CubicProfile,
        Header,
        Lane,
        LaneSection,
        Line,
        Road,
        RoadNetwork,
        constant_lane,
    )

    taper = CubicProfile((CubicPiece(0.0, 3.5, -3.5 / 100.0),))  # 3.5 m -> 0 m over 100 m
    first = LaneSection(
        0.0, right=(constant_lane(-1, 3.5), Lane(-2, "driving", taper, successor=-2))
    )
    second = LaneSection(100.0, right=(constant_lane(-1, 3.5), constant_lane(-2, 3.5)))
    road = Road("1", (Line(0.0, 0.0, 0.0, 0.0, 200.0),), (first, second))
    network = RoadNetwork(Header(geo_reference="+proj=tmerc +lat_0=47 +lon_0=15"), (road,))
    found = [f for f in check_network(network) if f.code == "zero_width_link"]
    assert len(found) == 1
    assert found[0].severity == "error"
    assert found[0].s == pytest.approx(100.0)
    unlinked = replace(
        road,
        lane_sections=(
            replace(first, right=(first.right[0], replace(first.right[1], successor=None))),
            second,
        ),
    )
    assert not [
        f for f in check_network(replace(network, roads=(unlinked,))) if f.code == "zero_width_link"
    ]


def test_a_width_record_starting_after_the_section_start_is_an_error():
    lane = Lane(-1, "driving", CubicProfile((CubicPiece(0.733, 3.5),)))
    road = Road("1", (Line(0.0, 0.0, 0.0, 0.0, 100.0),), (LaneSection(0.0, right=(lane,)),))
    findings = check_network(RoadNetwork(Header(), (road,)))
    found = [f for f in findings if f.code == "width_start"]
    assert len(found) == 1
    assert found[0].severity == "error"
    assert found[0].value == pytest.approx(0.733)


def test_a_linked_lane_moving_sideways_at_a_section_border_is_an_error():
    def lane(lid, w, pred=None, succ=None, kind="driving"):
        return Lane(
            lid, kind, CubicProfile((CubicPiece(0.0, w),)), predecessor=pred, successor=succ
        )

    # lane -2 continues as lane -2, but the unlinked shoulder inside it grows 0.29 m at
    # the border (a lane born 0.29 m wide): lane -2 moves sideways by 290 mm
    first = LaneSection(0.0, right=(lane(-1, 1.0, kind="shoulder"), lane(-2, 3.5, succ=-2)))
    second = LaneSection(50.0, right=(lane(-1, 1.29, kind="shoulder"), lane(-2, 3.5, pred=-2)))
    road = Road("1", (Line(0.0, 0.0, 0.0, 0.0, 100.0),), (first, second))
    found = [f for f in check_network(RoadNetwork(Header(), (road,))) if f.code == "lane_shift"]
    assert len(found) == 1
    assert found[0].severity == "error"
    assert found[0].value == pytest.approx(290.0, abs=0.5)
    # the shoulder continuing with its width: no shift
    second_ok = LaneSection(50.0, right=(lane(-1, 1.0, kind="shoulder"), lane(-2, 3.5, pred=-2)))
    road_ok = Road("1", (Line(0.0, 0.0, 0.0, 0.0, 100.0),), (first, second_ok))
    assert not [
        f for f in check_network(RoadNetwork(Header(), (road_ok,))) if f.code == "lane_shift"
    ]


def test_a_driving_lane_ending_at_full_width_inside_a_road_is_a_dead_end():
    def lane(lid, w, slope=0.0, pred=None, succ=None, kind="driving"):
        return Lane(
            lid,
            kind,
            CubicProfile((CubicPiece(0.0, w, slope),)),
            predecessor=pred,
            successor=succ,
        )

    line = (Line(0.0, 0.0, 0.0, 0.0, 100.0),)
    second = LaneSection(50.0, right=(lane(-1, 3.5, pred=-1),))
    # lane -2 ends 3.5 m wide: a car in it has nowhere to go
    first = LaneSection(0.0, right=(lane(-1, 3.5, succ=-1), lane(-2, 3.5)))
    road = Road("1", line, (first, second))
    found = [f for f in check_network(RoadNetwork(Header(), (road,))) if f.code == "lane_dead_end"]
    assert len(found) == 1
    assert found[0].severity == "warning"
    assert found[0].value == pytest.approx(3.5)
    # closing to zero width over the section (a taper) is no dead end
    tapering = LaneSection(0.0, right=(lane(-1, 3.5, succ=-1), lane(-2, 3.5, -3.5 / 50.0)))
    road_ok = Road("1", line, (tapering, second))
    assert not [
        f for f in check_network(RoadNetwork(Header(), (road_ok,))) if f.code == "lane_dead_end"
    ]


def test_a_ctrl_c_while_a_checkers_scratch_folder_is_removed_waits_until_it_is_gone(
    monkeypatch,
):
    """A Ctrl-C that lands while an external checker's scratch folder is being removed
    (the checker just done) stopped the removal half-way and left the folder in TMPDIR
    (once in CI). It is delivered once the folder is gone."""
    import os
    import shutil
    import signal
    from pathlib import Path

    import roadtwin.consumers as consumers

    real = shutil.rmtree

    def rmtree(path, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C right now
        real(path, **kwargs)

    monkeypatch.setattr(consumers.shutil, "rmtree", rmtree)
    # Python's own Ctrl-C handler (a CI job run in the background starts with SIGINT ignored)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt), consumers._scratch_dir("roadtwin-test-") as tmp:
            Path(tmp, "result.xqar").write_text("x", encoding="utf-8")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert not Path(tmp).exists()
