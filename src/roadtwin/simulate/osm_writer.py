"""OSM XML of the simulated place, drawn the way a mapper draws it.

Each carriageway and ramp is a centreline way with sparse nodes (every 20-80 m on
curves, a few hundred metres on straights), shifted by a per-way offset of about a metre
plus per-node noise. Motorway ways are split at every gore and lane drop; the link way of
an exit starts at a node it shares with the motorway way (tagged
``highway=motorway_junction``), the link way of an entry ends on one. The opposite
carriageway (drawn in its own driving direction, with mirrored ramps: our exit is its
entry) and the unrelated roads are included. Tags: ``highway`` (motorway,
motorway_link, primary, residential), ``oneway``, ``ref``; ``lanes`` on most ways only,
and on ramps one of ``lanes``, ``lanes:forward``, ``turn:lanes`` or nothing (for one-lane
ramps), cycling with the ramp index. Node and way ids are sequential, so the file is
deterministic.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
from numpy.typing import NDArray

from ..frames import MappingFrame
from ..model import Road
from .alignment import ramp_pieces
from .route import TRAFFIC_LANE_TYPES
from .route_truth import RouteTruth
from .scenario import OsmStyle
from .truth import Truth

NODE_ID0 = 1_000_001
WAY_ID0 = 5_001


@dataclass
class _Osm:
    """Nodes and ways being collected (ids assigned in creation order)."""

    nodes: list[tuple[int, float, float, dict[str, str]]] = field(default_factory=list)
    ways: list[tuple[int, list[int], dict[str, str]]] = field(default_factory=list)

    def add_nodes(self, xy: NDArray) -> list[int]:
        first = NODE_ID0 + len(self.nodes)
        ids = list(range(first, first + len(xy)))
        self.nodes.extend((i, float(p[0]), float(p[1]), {}) for i, p in zip(ids, xy, strict=False))
        return ids

    def add_way(self, node_ids: list[int], tags: dict[str, str]) -> int:
        way_id = WAY_ID0 + len(self.ways)
        self.ways.append((way_id, list(node_ids), tags))
        return way_id

    def tag_node(self, node_id: int, tags: dict[str, str]) -> None:
        i = node_id - NODE_ID0
        self.nodes[i][3].update(tags)


def node_stations(
    road: Road, s_a: float, s_b: float, style: OsmStyle, *, forced: tuple[float, ...] = ()
) -> NDArray[np.float64]:
    """Stations of a mapper's nodes on ``road`` between ``s_a`` and ``s_b`` (metres):
    spacing from the chord error on curves (clipped to the curve range), long on
    straights, plus the ``forced`` stations (gores, lane drops)."""
    s = np.linspace(s_a, s_b, max(2, math.ceil((s_b - s_a) / 1.0) + 1))
    kappa = np.abs(road.curvature(s))
    lo, hi = style.curve_spacing_m
    spacing = np.where(
        kappa < 1.0 / 5000.0,
        style.straight_spacing_m,
        np.clip(np.sqrt(8.0 * style.chord_error_m / np.maximum(kappa, 1e-9)), lo, hi),
    )
    count = np.concatenate([[0.0], np.cumsum(np.diff(s) / spacing[:-1])])
    crossing = np.nonzero(np.diff(np.floor(count)) > 0)[0] + 1
    out = np.concatenate([[s_a], s[crossing], [s_b], np.asarray(forced, float)])
    out = np.unique(np.round(out, 3))
    # drop sampled nodes crowding a forced one or an end (mappers do not place them 2 m apart)
    keep = np.ones(out.size, bool)
    anchors = np.concatenate([[s_a, s_b], np.asarray(forced, float)])
    for a in anchors:
        near = (np.abs(out - a) < 0.4 * lo) & (np.abs(out - a) > 1e-6)
        keep &= ~near
    return out[keep]


def mapper_xy(xy: NDArray, rng: np.random.Generator, style: OsmStyle) -> NDArray:
    """Points as a mapper draws them: one offset of up to ``way_offset_m`` for the whole
    way plus per-node noise (metres)."""
    ang = rng.uniform(0.0, 2.0 * math.pi)
    mag = rng.uniform(0.0, style.way_offset_m)
    offset = mag * np.array([math.cos(ang), math.sin(ang)])
    return xy + offset + rng.normal(0.0, style.node_noise_m, size=xy.shape)


def _lane_tags(k: int, index: int) -> dict[str, str]:
    mode = ("lanes", "none", "turn:lanes", "lanes:forward")[index % 4]
    if mode == "none" and k > 1:
        mode = "lanes"
    if mode == "lanes":
        return {"lanes": str(k)}
    if mode == "lanes:forward":
        return {"lanes": str(k), "lanes:forward": str(k)}
    if mode == "turn:lanes":
        return {"turn:lanes": "|".join(["through"] * k)}
    return {}


def _carriageway(
    osm: _Osm,
    road: Road,
    t_centre: float,
    cuts: list[tuple[float, int]],
    rng: np.random.Generator,
    truth: Truth,
) -> tuple[list[int], NDArray]:
    """Motorway ways of one carriageway split at ``cuts`` ((station, lanes after it));
    returns the node ids and their stations."""
    sc = truth.scenario
    forced = tuple(c[0] for c in cuts)
    s = node_stations(road, 0.0, road.length, sc.osm, forced=forced)
    xy = mapper_xy(road.to_xy(s, np.full_like(s, t_centre)), rng, sc.osm)
    ids = osm.add_nodes(xy)
    bounds = [0.0, *forced, road.length]
    lanes = [sc.lanes.count, *[c[1] for c in cuts]]
    for j, (a, b) in enumerate(itertools.pairwise(bounds)):
        sel = [i for i, v in enumerate(s) if a - 1e-6 <= v <= b + 1e-6]
        tags = {"highway": "motorway", "oneway": "yes", "ref": sc.osm.motorway_ref}
        if j == 0 or rng.random() >= sc.osm.missing_lanes_fraction:
            tags["lanes"] = str(lanes[j])
        osm.add_way([ids[i] for i in sel], tags)
    return ids, s


def _ramp_way(
    osm: _Osm,
    kind: str,
    centre_xy: NDArray,
    gore_node: int,
    lanes: int,
    index: int,
    rng: np.random.Generator,
    style: OsmStyle,
    *,
    name: str,
) -> int:
    xy = mapper_xy(centre_xy, rng, style)
    ids = osm.add_nodes(xy)
    node_ids = [gore_node, *ids] if kind == "exit" else [*ids, gore_node]
    tags = {"highway": "motorway_link", "oneway": "yes", **_lane_tags(lanes, index)}
    if name:
        tags["destination"] = name
    return osm.add_way(node_ids, tags)


def _ramp_centre(
    road: Road, lanes: int, lane_w: float, ris: float, sign: float, truth: Truth, kind: str
):
    """Sparse centreline points of a ramp road, leaving out ~30 m next to the gore."""
    gap = 30.0
    a, b = (gap, road.length) if kind == "exit" else (0.0, road.length - gap)
    s = node_stations(road, a, b, truth.scenario.osm)
    t = np.full_like(s, sign * (ris + lanes * lane_w / 2.0))
    return road.to_xy(s, t)


def build_osm(truth: Truth, rng: np.random.Generator) -> tuple[_Osm, dict[int, list[int]]]:
    """Collect the OSM nodes and ways; returns them and the link way ids per ramp index."""
    sc = truth.scenario
    sign = truth.sign
    ln = sc.lanes
    osm = _Osm()
    t_c = sign * (ln.inner_shoulder_m + ln.count * ln.width_m / 2.0)
    cuts: list[tuple[float, int]] = []
    for r in sc.ramps:
        cuts.append((r.station_m, ln.count - sum(d.station_m <= r.station_m for d in ln.drops)))
    for d in ln.drops:
        cuts.append((d.station_m, ln.count - sum(e.station_m <= d.station_m for e in ln.drops)))
    cuts.sort()
    ids, stations = _carriageway(osm, truth.mainline, t_c, cuts, rng, truth)
    ramp_ways: dict[int, list[int]] = {}
    for i, rt in enumerate(truth.ramps):
        r = rt.ramp
        gore = ids[int(np.argmin(np.abs(stations - r.station_m)))]
        if r.type == "exit":
            osm.tag_node(gore, {"highway": "motorway_junction", "ref": str(i + 1)})
        centre = _ramp_centre(
            rt.road, r.lanes, r.lane_width_m, r.inner_shoulder_m, sign, truth, r.type
        )
        way = _ramp_way(osm, r.type, centre, gore, r.lanes, i, rng, sc.osm, name=r.name)
        ramp_ways[i] = [way]
    if truth.opposite is not None:
        opp = truth.opposite
        opp_cuts = []
        mirrored = []
        if sc.opposite.ramps:
            for r in sc.ramps:
                u = opp.length - r.station_m
                kind = "entry" if r.type == "exit" else "exit"
                mirrored.append((u, kind, r))
                opp_cuts.append((u, ln.count))
        opp_cuts.sort()
        o_ids, o_st = _carriageway(osm, opp, t_c, opp_cuts, rng, truth)
        for j, (u, kind, r) in enumerate(sorted(mirrored, key=lambda m: m[0])):
            t_b = sign * (ln.inner_shoulder_m + ln.count * ln.width_m)
            _x, _y, h, k = (float(v[0]) for v in opp.evaluate(np.array([u])))
            p = opp.to_xy(np.array([u]), np.array([t_b]))[0]
            pieces = ramp_pieces(
                x=float(p[0]), y=float(p[1]), hdg=h, curvature_start=k / (1.0 - t_b * k),
                turn_sign=sign, radius_m=r.radius_m, clothoid_length_m=r.clothoid_length_m,
                curve_length_m=r.curve_length_m, tail_length_m=r.tail_length_m, kind=kind,
            )  # fmt: skip
            ramp_road = Road("opp-ramp", pieces, truth.ramps[0].road.lane_sections)
            centre = _ramp_centre(
                ramp_road, r.lanes, r.lane_width_m, r.inner_shoulder_m, sign, truth, kind
            )
            gore = o_ids[int(np.argmin(np.abs(o_st - u)))]
            if kind == "exit":
                osm.tag_node(gore, {"highway": "motorway_junction"})
            _ramp_way(osm, kind, centre, gore, r.lanes, j + 1, rng, sc.osm, name="")
    for road, o in zip(
        truth.others[1 if truth.opposite is not None else 0 :], sc.other_roads, strict=False
    ):
        s = np.linspace(0.0, road.length, 3 if o.length_m < 400 else 5)
        xy = mapper_xy(road.xy(s), rng, truth.scenario.osm)
        tags = {"highway": o.highway, "lanes": "2"}
        if o.name:
            tags["name"] = o.name
        if o.kind == "overpass":
            tags |= {"bridge": "yes", "layer": "1"}
        osm.add_way(osm.add_nodes(xy), tags)
    return osm, ramp_ways


def osm_xml(osm: _Osm, frame: MappingFrame, what: str) -> bytes:
    """Serialise to OSM XML 0.6 with WGS84 coordinates via the mapping frame; ``what``
    names the simulated place in the file's comment."""
    xy = np.array([[n[1], n[2]] for n in osm.nodes])
    lon, lat = frame.to_lonlat(xy[:, 0], xy[:, 1])
    lines = [
        "<?xml version='1.0' encoding='UTF-8'?>",
        '<osm version="0.6" generator="roadtwin simulate">',
        f"  <!-- simulated map: {what}; not real OpenStreetMap data -->",
        f'  <bounds minlat="{lat.min():.7f}" minlon="{lon.min():.7f}" '
        f'maxlat="{lat.max():.7f}" maxlon="{lon.max():.7f}"/>',
    ]
    for (node_id, _, _, tags), la, lo in zip(osm.nodes, lat, lon, strict=False):
        head = f'  <node id="{node_id}" version="1" lat="{la:.7f}" lon="{lo:.7f}"'
        if not tags:
            lines.append(head + "/>")
            continue
        lines.append(head + ">")
        lines += [f"    <tag k={quoteattr(k)} v={quoteattr(v)}/>" for k, v in tags.items()]
        lines.append("  </node>")
    for way_id, nodes, tags in osm.ways:
        lines.append(f'  <way id="{way_id}" version="1">')
        lines += [f'    <nd ref="{n}"/>' for n in nodes]
        lines += [f"    <tag k={quoteattr(k)} v={quoteattr(v)}/>" for k, v in tags.items()]
        lines.append("  </way>")
    lines.append("</osm>")
    return ("\n".join(lines) + "\n").encode("utf-8")


def write_osm(truth: Truth, path: Path, rng: np.random.Generator) -> dict[int, list[int]]:
    """Write ``map.osm``; returns the link way ids of each of our ramps (by index)."""
    osm, ramp_ways = build_osm(truth, rng)
    Path(path).write_bytes(osm_xml(osm, truth.frame, f"roadtwin scenario {truth.scenario.name}"))
    return ramp_ways


# ---------------------------------------------------------------------------
# routes through any road network (roadtwin.simulate.route_truth)
# ---------------------------------------------------------------------------


def _through_band(truth: RouteTruth, road: Road, s: NDArray, *, keys=None) -> NDArray:
    """Centre offset t of the through traffic lanes (not auxiliary) of ``road`` at s."""
    out = np.zeros(s.size)
    sec_idx = road.section_index(s)
    for k in np.unique(sec_idx):
        sel = sec_idx == k
        sec = road.lane_sections[int(k)]
        lanes = sec.right or sec.left
        sec_keys = keys[int(k)] if keys is not None else [None] * len(lanes)
        ids = [
            ln.id
            for ln, key in zip(lanes, sec_keys, strict=True)
            if ln.type in TRAFFIC_LANE_TYPES and key not in truth.aux_keys
        ] or [ln.id for ln in lanes]
        first, last = ids[0], ids[-1]
        inner = 0 if abs(first) == 1 else first - int(np.sign(first))
        out[sel] = 0.5 * (road.lane_border_t(s[sel], inner) + road.lane_border_t(s[sel], last))
    return out


def through_lane_counts(truth: RouteTruth) -> list[tuple[float, int]]:
    """``(station, lanes)`` where the number of through traffic lanes of the mainline (not
    auxiliary, at least 2.5 m wide in the middle of the section) changes; the first entry
    is at station 0."""
    road = truth.mainline
    out: list[tuple[float, int]] = []
    for k, sec in enumerate(road.lane_sections):
        s1 = road.section_end(k)
        mid = 0.5 * (sec.s0 + s1) - sec.s0
        n = sum(
            1
            for ln, key in zip(
                sec.right or sec.left, truth.mainline_fit.section_keys[k], strict=True
            )
            if ln.type in TRAFFIC_LANE_TYPES
            and key not in truth.aux_keys
            and float(ln.width.value(mid)) >= 2.5
        )
        if not out or out[-1][1] != n:
            out.append((sec.s0, max(n, 1)))
    return out


MAX_LINK_ANGLE_DEG = 15.0
"""Mappers join a link way to the motorway way at a shallow angle: the shared node is
placed where the link's first (exit) / last (entry) segment meets the motorway
centreline at no more than this angle."""


def _link_nodes(truth: RouteTruth, ramp, style: OsmStyle, gap_m: float = 30.0):
    """Stations and centre points of a ramp's link-way nodes (from ``gap_m`` beyond the
    gore to the ramp road's far end) and the mainline station of the node it shares."""
    r = ramp.road
    if ramp.type == "exit":
        a = min(max(ramp.station_m - ramp.cut_station_m, 0.0) + gap_m, 0.5 * r.length)
        rs = node_stations(r, round(a, 3), round(r.length, 3), style)
        near = rs[0]
    else:
        b = r.length - max(ramp.cut_station_m - ramp.station_m, 0.0) - gap_m
        rs = node_stations(r, 0.0, round(max(b, 0.5 * r.length), 3), style)
        near = rs[-1]
    centre = r.to_xy(rs, _through_band(truth, r, rs))
    main = truth.mainline
    p_near = r.to_xy(np.array([near]), _through_band(truth, r, np.array([near])))
    u, t = main.project(p_near, s_init=np.array([ramp.station_m]))
    off = abs(float(t[0] - _through_band(truth, main, u, keys=truth.mainline_fit.section_keys)[0]))
    run = max(gap_m, off / math.tan(math.radians(MAX_LINK_ANGLE_DEG)))
    u_att = float(u[0]) - run if ramp.type == "exit" else float(u[0]) + run
    return centre, round(float(np.clip(u_att, 0.0, main.length)), 3)


def build_route_osm(
    truth: RouteTruth, style: OsmStyle, rng: np.random.Generator
) -> tuple[_Osm, dict[int, list[int]]]:
    """A mapper's OSM of a route truth: the carriageway as oneway ``motorway`` ways split
    at every link's node and lane-count change (``lanes`` = through lanes, sometimes
    missing), each ramp a ``motorway_link`` way from a node shared with the motorway (where
    the link meets it at a shallow angle, near the gore) to the ramp road's far end.
    Returns the ways and the link way ids per ramp."""
    osm = _Osm()
    road = truth.mainline
    counts = through_lane_counts(truth)
    links = [_link_nodes(truth, ramp, style) for ramp in truth.ramps]
    forced = tuple(sorted({u for _, u in links} | {round(c[0], 3) for c in counts[1:]} - {0.0}))
    # node_stations compares millimetre-rounded nodes with its end stations: give it
    # millimetre ends, or it drops them as crowding themselves
    s = node_stations(road, 0.0, round(road.length, 3), style, forced=forced)
    t_c = _through_band(truth, road, s, keys=truth.mainline_fit.section_keys)
    ids = osm.add_nodes(mapper_xy(road.to_xy(s, t_c), rng, style))
    bounds = [0.0, *forced, road.length]
    starts = np.array([c[0] for c in counts])
    for j, (a, b) in enumerate(itertools.pairwise(bounds)):
        sel = [i for i, v in enumerate(s) if a - 1e-6 <= v <= b + 1e-6]
        if len(sel) < 2:
            continue
        tags = {"highway": "motorway", "oneway": "yes", "ref": style.motorway_ref}
        lanes = counts[int(np.searchsorted(starts, 0.5 * (a + b), side="right") - 1)][1]
        if j == 0 or rng.random() >= style.missing_lanes_fraction:
            tags["lanes"] = str(lanes)
        osm.add_way([ids[i] for i in sel], tags)
    ramp_ways: dict[int, list[int]] = {}
    for i, (ramp, (centre, u_att)) in enumerate(zip(truth.ramps, links, strict=True)):
        shared = ids[int(np.argmin(np.abs(s - u_att)))]
        if ramp.type == "exit":
            osm.tag_node(shared, {"highway": "motorway_junction", "ref": str(i + 1)})
        way = _ramp_way(osm, ramp.type, centre, shared, ramp.lanes, i, rng, style, name=ramp.name)
        ramp_ways[i] = [way]
    return osm, ramp_ways


def write_route_osm(
    truth: RouteTruth, path: Path, style: OsmStyle, rng: np.random.Generator
) -> dict[int, list[int]]:
    """Write the ``map.osm`` of a route truth; returns the link way ids per ramp index."""
    osm, ramp_ways = build_route_osm(truth, style, rng)
    what = f"roadtwin route through {truth.source_name}"
    Path(path).write_bytes(osm_xml(osm, truth.frame, what))
    return ramp_ways
