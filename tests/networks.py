"""Hand-built RoadNetworks for tests: a 300 m mainline with an exit ramp.

Right-hand traffic, the shared lane convention: reference line = left (median-side) road
edge, lanes -1 inner shoulder (1.0 m), -2/-3 driving (3.5 m), then a deceleration lane
and the hard shoulder (2.5 m). The mainline runs along +x from the origin.

``mainline_exit_network("default")``:

* road ``"1"`` (mainline, 0..150 m): section at 0 with -1, -2, -3, -4 hard shoulder;
  section at 100 m where the deceleration lane -4 tapers in from 0 to 3.5 m (cubic, no
  predecessor) and the hard shoulder becomes -5. Successor: junction ``"100"``.
* junction ``"100"`` (default) at x = 150 m with two connecting roads (``name="connector"``):
  ``"101"`` straight 20 m (lanes -1..-3 continue; the hard shoulder -4 re-appears from
  zero width) and ``"102"`` a normalized ParamPoly3 (cubic Hermite) starting on the
  border between lanes -3 and -4 of road 1 (t = -8 m), carrying the deceleration lane as
  its lane -1 and the hard shoulder as -2. Lane links in both directions on the connectors,
  and in the junction's ``laneLink`` elements.
* road ``"2"`` (mainline, 130 m) from the end of ``"101"``; road ``"3"`` (exit, one
  driving lane + shoulder), an arc from the end of ``"102"``.

``mainline_exit_network("direct")``: the same without connecting roads: road ``"2"``
starts at x = 150 m (150 m long, hard shoulder re-appearing over its first 20 m) and road
``"3"`` starts with the Hermite piece; junction ``"200"`` is ``direct`` with
``linkedRoad`` connections.

Every joint is computed so that positions and headings meet exactly.
"""

from __future__ import annotations

import math
from dataclasses import replace

from scipy.integrate import quad

from roadtwin.model import (
    Arc,
    Connection,
    CubicPiece,
    CubicProfile,
    Header,
    Junction,
    Lane,
    LaneLink,
    LaneSection,
    Line,
    ParamPoly3,
    Road,
    RoadLink,
    RoadMark,
    RoadNetwork,
    constant_lane,
)

GEO_REFERENCE = "+proj=tmerc +lat_0=59.3293 +lon_0=18.0686 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m"
SHOULDER_IN_M = 1.0
LANE_M = 3.5
SHOULDER_OUT_M = 2.5
GORE_X_M = 150.0
CONNECTOR_M = 20.0
RAMP_T_M = -(SHOULDER_IN_M + 2 * LANE_M)  # border between lanes -3 and -4 of road 1


def taper(width_m: float, length_m: float, *, grow: bool = True) -> CubicProfile:
    """Cubic width taper from 0 to ``width_m`` (or back) over ``length_m``, then constant."""
    c = 3.0 * width_m / length_m**2
    d = -2.0 * width_m / length_m**3
    if grow:
        return CubicProfile((CubicPiece(0.0, 0.0, 0.0, c, d), CubicPiece(length_m, width_m)))
    return CubicProfile((CubicPiece(0.0, width_m, 0.0, -c, -d), CubicPiece(length_m, 0.0)))


def _lane(lane_id, width, lane_type="driving", mark="broken", pred=None, succ=None) -> Lane:
    prof = width if isinstance(width, CubicProfile) else CubicProfile.constant(width)
    return Lane(lane_id, lane_type, prof, (RoadMark(0.0, mark),), pred, succ)


def _center() -> Lane:
    return Lane(0, "none", CubicProfile(), (RoadMark(0.0, "none"),))


def hermite_parampoly3(
    x0: float,
    y0: float,
    hdg: float,
    end_u: float,
    end_v: float,
    end_hdg_local: float,
    *,
    s0: float = 0.0,
) -> ParamPoly3:
    """Normalized ParamPoly3 from the local origin (heading 0) to ``(end_u, end_v)`` with
    local end heading ``end_hdg_local``; tangent lengths = chord length. Its length is the
    true arc length (adaptive quadrature)."""
    chord = math.hypot(end_u, end_v)
    m0 = (chord, 0.0)
    m1 = (chord * math.cos(end_hdg_local), chord * math.sin(end_hdg_local))
    coef = []
    for p1, t0, t1 in ((end_u, m0[0], m1[0]), (end_v, m0[1], m1[1])):
        coef.append((0.0, t0, 3.0 * p1 - 2.0 * t0 - t1, -2.0 * p1 + t0 + t1))
    (au, bu, cu, du), (av, bv, cv, dv) = coef

    def speed(p: float) -> float:
        return math.hypot(bu + 2 * cu * p + 3 * du * p * p, bv + 2 * cv * p + 3 * dv * p * p)

    length = quad(speed, 0.0, 1.0, epsabs=1e-13, epsrel=1e-13, limit=200)[0]
    return ParamPoly3(s0, x0, y0, hdg, length, au, bu, cu, du, av, bv, cv, dv, "normalized")


def _ramp_lanes(pred_drive=None, pred_sh=None, succ_drive=None, succ_sh=None):
    return (
        _lane(-1, LANE_M, mark="solid", pred=pred_drive, succ=succ_drive),
        _lane(-2, SHOULDER_OUT_M, "shoulder", "none", pred_sh, succ_sh),
    )


def _road1(successor: RoadLink) -> Road:
    sec0 = LaneSection(
        0.0,
        center=_center(),
        right=(
            _lane(-1, SHOULDER_IN_M, "shoulder", "solid", succ=-1),
            _lane(-2, LANE_M, pred=None, succ=-2),
            _lane(-3, LANE_M, mark="solid", succ=-3),
            _lane(-4, SHOULDER_OUT_M, "shoulder", "none", succ=-5),
        ),
    )
    sec1 = LaneSection(
        100.0,
        center=_center(),
        right=(
            _lane(-1, SHOULDER_IN_M, "shoulder", "solid", pred=-1),
            _lane(-2, LANE_M, pred=-2),
            _lane(-3, LANE_M, mark="broken", pred=-3),
            _lane(-4, taper(LANE_M, 50.0), mark="solid"),
            _lane(-5, SHOULDER_OUT_M, "shoulder", "none", pred=-4),
        ),
    )
    return Road(
        "1",
        (Line(0.0, 0.0, 0.0, 0.0, GORE_X_M),),
        (sec0, sec1),
        name="mainline",
        elevation=CubicProfile((CubicPiece(0.0, 10.0, 0.001),)),
        successor=successor,
        speed_limit_mps=120 / 3.6,
    )


def _road2(x0: float, length: float, predecessor: RoadLink, *, shoulder_taper: bool) -> Road:
    lanes = (
        _lane(-1, SHOULDER_IN_M, "shoulder", "solid"),
        _lane(-2, LANE_M),
        _lane(-3, LANE_M, mark="solid"),
    )
    if shoulder_taper:
        sec0 = LaneSection(
            0.0,
            center=_center(),
            right=(
                *(Lane(ln.id, ln.type, ln.width, ln.road_marks, None, ln.id) for ln in lanes),
                _lane(-4, taper(SHOULDER_OUT_M, CONNECTOR_M), "shoulder", "none", succ=-4),
            ),
        )
        sec1 = LaneSection(
            CONNECTOR_M,
            center=_center(),
            right=(
                *(Lane(ln.id, ln.type, ln.width, ln.road_marks, ln.id, None) for ln in lanes),
                _lane(-4, SHOULDER_OUT_M, "shoulder", "none", pred=-4),
            ),
        )
        sections = (sec0, sec1)
    else:
        sections = (
            LaneSection(
                0.0,
                center=_center(),
                right=(*lanes, _lane(-4, SHOULDER_OUT_M, "shoulder", "none")),
            ),
        )
    z0 = 10.0 + 0.001 * x0
    return Road(
        "2",
        (Line(0.0, x0, 0.0, 0.0, length),),
        sections,
        name="mainline",
        elevation=CubicProfile((CubicPiece(0.0, z0, 0.001),)),
        predecessor=predecessor,
        speed_limit_mps=120 / 3.6,
    )


def _header() -> Header:
    return Header(
        name="mainline_exit",
        geo_reference=GEO_REFERENCE,
        data_quality={
            "xy_absolute": 0.1,
            "xy_relative": 0.02,
            "z_absolute": 0.2,
            "z_relative": 0.05,
        },
    )


def _diverge() -> ParamPoly3:
    return hermite_parampoly3(GORE_X_M, RAMP_T_M, 0.0, 40.0, -4.0, -0.18)


def mainline_exit_network(junction_type: str = "default") -> RoadNetwork:
    """Mainline (roads 1, 2) + exit ramp (road 3); ``junction_type`` default or direct."""
    if junction_type not in ("default", "direct"):
        raise ValueError(junction_type)
    diverge = _diverge()
    if junction_type == "default":
        jid = "100"
        road1 = _road1(RoadLink("junction", jid))
        c101 = Road(
            "101",
            (Line(0.0, GORE_X_M, 0.0, 0.0, CONNECTOR_M),),
            (
                LaneSection(
                    0.0,
                    center=_center(),
                    right=(
                        _lane(-1, SHOULDER_IN_M, "shoulder", "solid", pred=-1, succ=-1),
                        _lane(-2, LANE_M, pred=-2, succ=-2),
                        _lane(-3, LANE_M, mark="solid", pred=-3, succ=-3),
                        _lane(-4, taper(SHOULDER_OUT_M, CONNECTOR_M), "shoulder", "none", succ=-4),
                    ),
                ),
            ),
            name="connector",
            elevation=CubicProfile((CubicPiece(0.0, 10.0 + 0.001 * GORE_X_M, 0.001),)),
            predecessor=RoadLink("road", "1", "end"),
            successor=RoadLink("road", "2", "start"),
            junction=jid,
        )
        x_end, y_end, h_end = diverge.end_pose()
        z_gore = 10.0 + 0.001 * GORE_X_M
        c102 = Road(
            "102",
            (diverge,),
            (
                LaneSection(
                    0.0,
                    center=_center(),
                    right=_ramp_lanes(-4, -5, -1, -2),
                ),
            ),
            name="connector",
            elevation=CubicProfile((CubicPiece(0.0, z_gore, 0.001),)),
            predecessor=RoadLink("road", "1", "end"),
            successor=RoadLink("road", "3", "start"),
            junction=jid,
        )
        # road 2 starts in the junction: its lanes name the lanes of connector 101
        road2 = _road2(
            GORE_X_M + CONNECTOR_M,
            300.0 - GORE_X_M - CONNECTOR_M,
            RoadLink("junction", jid),
            shoulder_taper=False,
        )
        sec = road2.lane_sections[0]
        right = tuple(replace(ln, predecessor=ln.id) for ln in sec.right)
        road2 = replace(road2, lane_sections=(replace(sec, right=right),))
        road3 = Road(
            "3",
            (Arc(0.0, x_end, y_end, h_end, 100.0, -1.0 / 250.0),),
            (LaneSection(0.0, center=_center(), right=_ramp_lanes(-1, -2)),),
            name="exit",
            elevation=CubicProfile((CubicPiece(0.0, z_gore + 0.001 * diverge.length, 0.001),)),
            predecessor=RoadLink("junction", jid),
            speed_limit_mps=80 / 3.6,
        )
        junction = Junction(
            jid,
            (
                Connection("0", "1", "101", "start", tuple(LaneLink(i, i) for i in (-1, -2, -3))),
                Connection("1", "1", "102", "start", (LaneLink(-4, -1), LaneLink(-5, -2))),
            ),
            name="exit junction",
        )
        return RoadNetwork(_header(), (road1, c101, c102, road2, road3), (junction,))

    jid = "200"
    road1 = _road1(RoadLink("junction", jid))
    road2 = _road2(GORE_X_M, 300.0 - GORE_X_M, RoadLink("junction", jid), shoulder_taper=True)
    arc = Arc(diverge.length, *diverge.end_pose(), 100.0, -1.0 / 250.0)
    road3 = Road(
        "3",
        (diverge, arc),
        (LaneSection(0.0, center=_center(), right=_ramp_lanes()),),
        name="exit",
        elevation=CubicProfile((CubicPiece(0.0, 10.0 + 0.001 * GORE_X_M, 0.001),)),
        predecessor=RoadLink("junction", jid),
        speed_limit_mps=80 / 3.6,
    )
    junction = Junction(
        jid,
        (
            Connection("0", "1", "2", "start", tuple(LaneLink(i, i) for i in (-1, -2, -3))),
            Connection("1", "1", "3", "start", (LaneLink(-4, -1), LaneLink(-5, -2))),
        ),
        name="exit junction",
        type="direct",
    )
    return RoadNetwork(_header(), (road1, road2, road3), (junction,))


def straight_road(road_id: str = "1", length_m: float = 100.0) -> Road:
    """A single straight road with the mainline lane layout (for small unit tests)."""
    return Road(
        road_id,
        (Line(0.0, 0.0, 0.0, 0.0, length_m),),
        (
            LaneSection(
                0.0,
                right=(
                    constant_lane(-1, SHOULDER_IN_M, lane_type="shoulder"),
                    constant_lane(-2, LANE_M, mark="broken"),
                    constant_lane(-3, LANE_M),
                    constant_lane(-4, SHOULDER_OUT_M, lane_type="shoulder", mark="none"),
                ),
            ),
        ),
        name="mainline",
    )


# ---------------------------------------------------------------------------
# ramps on the median side
# ---------------------------------------------------------------------------

MEDIAN_RADIUS_M = 1000.0
"""Radius of the mainline's median-side edge where it runs at its base level."""


def _on_circle(radius_m: float, theta: float) -> tuple[float, float]:
    """A point of the circle centred at (0, MEDIAN_RADIUS_M) (a left curve starting at the
    origin heading +x) at angle ``theta`` and radius ``radius_m``."""
    return radius_m * math.sin(theta), MEDIAN_RADIUS_M - radius_m * math.cos(theta)


def _arc_road(road_id: str, radius_m: float, theta0: float, length_m: float, lanes, **kw) -> Road:
    x0, y0 = _on_circle(radius_m, theta0)
    geo = (Arc(0.0, x0, y0, theta0, length_m, curvature_per_m=1.0 / radius_m),)
    return Road(road_id, geo, (LaneSection(0.0, center=_center(), right=tuple(lanes)),), **kw)


def _hermite_to(x1: float, y1: float, hdg1: float, back_m: float, side_m: float, turn: float):
    """A ParamPoly3 ending at (x1, y1) with heading ``hdg1``, starting ``back_m`` before and
    ``side_m`` left of it with heading ``hdg1 - turn``."""
    c, s = math.cos(hdg1), math.sin(hdg1)
    x0, y0 = x1 - back_m * c - side_m * s, y1 - back_m * s + side_m * c
    hdg0 = hdg1 - turn
    dx, dy = x1 - x0, y1 - y0
    u = dx * math.cos(hdg0) + dy * math.sin(hdg0)
    v = -dx * math.sin(hdg0) + dy * math.cos(hdg0)
    return hermite_parampoly3(x0, y0, hdg0, u, v, turn)


def median_ramps_network() -> RoadNetwork:
    """A left entry and a left exit on a right-hand motorway curving left (R ~ 1 km), both
    at full width on the median side, joined by ``direct`` junctions.

    * road ``"1"`` (300 m along the edge): inner shoulder -1, driving -2 -3, hard shoulder
      -4; its median edge is the circle of radius ``MEDIAN_RADIUS_M``.
    * junction ``"100"``: the entry ``"3"`` (shoulder -1, driving -2) joins at the median
      side: road ``"2"`` has the entry's two lanes inside the through lanes -3 -4 (road 1's
      inner shoulder ends there), so its median edge steps 3.5 m towards the median.
    * road ``"2"`` (250 m) ends at junction ``"200"``: the exit ``"5"`` takes its lanes -1
      -2 away at full width, road ``"4"`` (400 m) goes on with the through lanes and the
      hard shoulder, its median edge 4.5 m farther out than road 2's.

    Every road is exact: the through lanes' borders are concentric circles throughout.
    """
    r1, r2, r4 = MEDIAN_RADIUS_M, MEDIAN_RADIUS_M - 3.5, MEDIAN_RADIUS_M + 1.0
    th1 = 300.0 / r1
    th2 = th1 + 250.0 / r2
    j100, j200 = RoadLink("junction", "100"), RoadLink("junction", "200")
    road1 = _arc_road(
        "1", r1, 0.0, 300.0,
        (
            _lane(-1, SHOULDER_IN_M, "shoulder", "solid"),
            _lane(-2, LANE_M),
            _lane(-3, LANE_M, mark="solid"),
            _lane(-4, SHOULDER_OUT_M, "shoulder", "none"),
        ),
        name="mainline", successor=j100,
    )  # fmt: skip
    road2 = _arc_road(
        "2", r2, th1, 250.0,
        (
            _lane(-1, SHOULDER_IN_M, "shoulder", "solid"),
            _lane(-2, LANE_M),
            _lane(-3, LANE_M),
            _lane(-4, LANE_M, mark="solid"),
            _lane(-5, SHOULDER_OUT_M, "shoulder", "none"),
        ),
        name="mainline", predecessor=j100, successor=j200,
    )  # fmt: skip
    road4 = _arc_road(
        "4", r4, th2, 400.0,
        (
            _lane(-1, LANE_M),
            _lane(-2, LANE_M, mark="solid"),
            _lane(-3, SHOULDER_OUT_M, "shoulder", "none"),
        ),
        name="mainline", predecessor=j200,
    )  # fmt: skip
    ramp_lanes = (_lane(-1, SHOULDER_IN_M, "shoulder", "solid"), _lane(-2, LANE_M, mark="solid"))
    x2, y2 = _on_circle(r2, th1)
    entry_geo = _hermite_to(x2, y2, th1, 120.0, 25.0, 0.25)
    entry = Road(
        "3", (entry_geo,), (LaneSection(0.0, center=_center(), right=ramp_lanes),),
        name="entry", successor=j100,
    )  # fmt: skip
    x5, y5 = _on_circle(r2, th2)
    exit_geo = hermite_parampoly3(x5, y5, th2, 120.0, 25.0, 0.3)
    exit_ = Road(
        "5", (exit_geo,), (LaneSection(0.0, center=_center(), right=ramp_lanes),),
        name="exit", predecessor=j200,
    )  # fmt: skip
    junctions = (
        Junction(
            "100",
            (
                Connection("1", "1", "2", "start", tuple(LaneLink(a, a - 1) for a in (-2, -3, -4))),
                Connection("2", "3", "2", "start", (LaneLink(-1, -1), LaneLink(-2, -2))),
            ),
            type="direct",
        ),
        Junction(
            "200",
            (
                Connection("1", "2", "4", "start", tuple(LaneLink(a, a + 2) for a in (-3, -4, -5))),
                Connection("2", "2", "5", "start", (LaneLink(-1, -1), LaneLink(-2, -2))),
            ),
            type="direct",
        ),
    )
    return RoadNetwork(_header(), (road1, road2, road4, entry, exit_), junctions)


# ---------------------------------------------------------------------------
# a run that passes over itself
# ---------------------------------------------------------------------------

LOOP_RADIUS_M = 150.0
LOOP_TURN_DEG = 350.0
LOOP_RISE_M = 9.0


def self_crossing_network() -> RoadNetwork:
    """One right-hand motorway road that loops over itself: 250 m east along y = 0, a left
    arc of ``LOOP_RADIUS_M`` through ``LOOP_TURN_DEG`` degrees rising ``LOOP_RISE_M`` m,
    then 350 m straight, which crosses the first straight 13 m before the loop at 10
    degrees, ``LOOP_RISE_M`` above it (the two passes run within 20 m of each other in plan
    for about 120 m). Lanes: inner shoulder, three driving lanes, hard shoulder.
    """
    turn = math.radians(LOOP_TURN_DEG)
    arc_len = LOOP_RADIUS_M * turn
    x1 = 250.0 + LOOP_RADIUS_M * math.sin(turn)
    y1 = LOOP_RADIUS_M * (1.0 - math.cos(turn))
    geometry = (
        Line(0.0, 0.0, 0.0, 0.0, 250.0),
        Arc(250.0, 250.0, 0.0, 0.0, arc_len, curvature_per_m=1.0 / LOOP_RADIUS_M),
        Line(250.0 + arc_len, x1, y1, turn, 350.0),
    )
    # flat to s = 300 m, a cubic rise to s = 800 m, flat again
    rise_m = 500.0
    c = 3.0 * LOOP_RISE_M / rise_m**2
    d = -2.0 * LOOP_RISE_M / rise_m**3
    elevation = CubicProfile(
        (CubicPiece(0.0, 0.0), CubicPiece(300.0, 0.0, 0.0, c, d), CubicPiece(800.0, LOOP_RISE_M))
    )
    lanes = (
        _lane(-1, 1.0, "shoulder", "solid"),
        _lane(-2, LANE_M),
        _lane(-3, LANE_M),
        _lane(-4, LANE_M, mark="solid"),
        _lane(-5, SHOULDER_OUT_M, "shoulder", "none"),
    )
    road = Road(
        "1",
        geometry,
        (LaneSection(0.0, center=_center(), right=lanes),),
        name="mainline",
        elevation=elevation,
        speed_limit_mps=100 / 3.6,
    )
    return RoadNetwork(replace(_header(), name="self_crossing"), (road,))
