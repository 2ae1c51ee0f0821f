"""``truth_from_osm``: one real OSM carriageway chain -> a lane-level ground-truth map.

Pipeline (each step in its own module): choose the chain and its window (``chain``),
find its ramps (``links``), move OSM by a seeded offset field and fit the mainline's
reference line (``geometry``), lay out the lanes along it (``layout``), shape and fit the
ramps (``geometry``), give everything heights (``elevation``) and assemble roads,
junctions and lane links (``network``).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ...fitting import arc_length
from ...frames import Origin
from ...model import Connection, Header, Junction, Road, RoadLink, RoadNetwork
from ..route_truth import LeftOutRamp
from .chain import OsmRoads, read_osm_roads, resolve_selection, select_chain, window_chain
from .elevation import mainline_profile, ramp_profile
from .geometry import (
    curvature,
    fit_line,
    normals,
    offset_field,
    ramp_polyline,
    road_with_geometry,
    self_intersects,
    smooth_line,
)
from .layout import Layout, RampEvent, Strip, build_layout, tag_segments_from_chain
from .links import OsmRamp, find_ramps, tagged_lanes
from .network import BuiltRoad, Source, build_road, lane_pairs, set_end_links
from .settings import OsmTruthSettings, RampShape
from .style import RoadStyle, road_style

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RampTruth:
    """Metadata of one ramp of the truth (for truth.json)."""

    road_id: str
    type: str
    side: str
    station_m: float  # gore station along the route (mainline stations, metres)
    lanes: int
    osm_way_ids: tuple[int, ...]
    length_m: float
    min_radius_m: float
    crossings: tuple[float, ...] = ()  # clearance (metres) reached where it crosses the mainline

    def to_dict(self) -> dict:
        return {
            "road_id": self.road_id,
            "type": self.type,
            "side": self.side,
            "station_m": round(self.station_m, 3),
            "lanes": self.lanes,
            "osm_way_ids": list(self.osm_way_ids),
            "length_m": round(self.length_m, 3),
            "min_radius_m": round(self.min_radius_m, 2),
            "crossing_clearance_m": [round(c, 2) for c in self.crossings],
        }


@dataclass(frozen=True)
class OsmTruth:
    """The ground truth built from one OSM chain.

    Attributes
    ----------
    network : the map (mapping frame of ``origin``, OpenDRIVE 1.8, with geoReference).
    route : road ids a car drives along the carriageway, in order (mainline roads and the
        junctions' through connecting roads).
    mainline_ids : the roads named ``mainline`` in driving order.
    osm_path : the real extract the run should use as its map input (unchanged).
    ramps : per ramp its road, type, gore station along the route, lanes, OSM way ids.
    style : country, traffic side, widths and marking patterns used.
    origin : GPS origin of the mapping frame.
    chain_way_ids : the OSM ways of the mainline window.
    mainline : the whole mainline as one road (all lane sections), for sampling.
    layout : the lane strips along the mainline (truth stations).
    osm_offset_m : ``(N, 3)`` station and the truth-minus-OSM displacement (x, y) applied
        along the mainline every 10 m.
    tagged_lanes : ``(s0, s1, lanes)`` of the OSM ``lanes`` tags along the mainline
        (truth stations).
    skipped : the OSM ramps left out, where they meet the truth's mainline.
    notes : what the layout did (weaving lanes, missing shoulders, ...).
    """

    network: RoadNetwork
    route: tuple[str, ...]
    mainline_ids: tuple[str, ...]
    osm_path: Path
    ramps: tuple[RampTruth, ...]
    style: RoadStyle
    origin: Origin
    chain_way_ids: tuple[int, ...]
    mainline: Road
    layout: Layout
    osm_offset_m: NDArray[np.float64]
    tagged_lanes: tuple[tuple[float, float, int], ...]
    seed: int
    skipped: tuple[LeftOutRamp, ...] = ()
    notes: tuple[str, ...] = field(default_factory=tuple)
    offset_centre_xy: tuple[float, float] = (0.0, 0.0)
    """Centre (mapping frame, metres) of the OSM offset field's waves: a truth of the other
    carriageway built with the same seed, origin and centre is moved off OSM by the same
    field, so the two carriageways keep OSM's relative placement."""

    def metadata(self) -> dict:
        """What truth.json needs about the map."""
        return {
            "source": "osm",
            "osm_file": str(self.osm_path),
            "osm_attribution": "(c) OpenStreetMap contributors, ODbL",
            "chain_way_ids": list(self.chain_way_ids),
            "origin": {
                "lat": self.origin.lat_deg,
                "lon": self.origin.lon_deg,
                "alt": self.origin.alt_m,
            },
            "route": list(self.route),
            "mainline_length_m": round(self.mainline.length, 3),
            "ramps": [r.to_dict() for r in self.ramps],
            "style": self.style.to_dict(),
            "seed": self.seed,
            "skipped": [[x.what, x.why] for x in self.skipped],
            "notes": list(self.notes),
        }


def _moved(xy: tuple[float, float], fld) -> tuple[float, float]:
    """An OSM point moved by the offset field ``fld`` onto the truth (mapping frame)."""
    p = np.array([xy])
    q = (p + fld(p))[0]
    return (float(q[0]), float(q[1]))


def _gore_point(r: OsmRamp, fld) -> tuple[float, float]:
    """Where an OSM ramp meets the truth's mainline (its gore node, moved by ``fld``)."""
    xy = r.xy[0] if r.kind == "exit" else r.xy[-1]
    return _moved((float(xy[0]), float(xy[1])), fld)


def _rng(seed: int, k: int) -> np.random.Generator:
    return np.random.default_rng([seed, k])


def _moving_mean(x: NDArray, n: int) -> NDArray:
    n = max(1, min(n, len(x)) | 1)
    pad = np.pad(x, n // 2, mode="edge")
    return np.convolve(pad, np.ones(n) / n, mode="valid")


def truth_from_osm(
    osm_path: str | Path,
    *,
    chain: int | str | None = None,
    origin: Origin | None = None,
    settings: OsmTruthSettings | None = None,
    seed: int = 0,
    offset_centre_xy: tuple[float, float] | None = None,
    roads: OsmRoads | None = None,
) -> OsmTruth:
    """Lane-level ground truth of one real motorway/trunk carriageway of an OSM extract.

    Parameters
    ----------
    osm_path
        ``.osm``, ``.osm.gz``, ``.osm.bz2`` or ``.osm.pbf`` extract (used unchanged).
    chain
        Shortcut for ``settings.chain``: an OSM way id (int) or a ``ref`` (str, e.g.
        ``"A 70"``); None keeps ``settings.chain`` (default: the longest chain).
    origin
        GPS origin of the mapping frame (``local`` tmerc); default the window's start.
    settings
        :class:`OsmTruthSettings`; defaults are realistic.
    seed
        Seed of every random choice (offset field, widths, grades, shoulders): the same
        seed gives the same map, byte for byte.
    offset_centre_xy
        Centre of the offset field's waves (mapping frame, metres); default the chain's
        mean point. Give the other carriageway's ``OsmTruth.offset_centre_xy`` (with the
        same seed and origin) to move both carriageways off OSM by the same field.
    roads
        The extract already read (:func:`~.chain.read_osm_roads` of ``osm_path``), so
        that several truths of one extract read it once.
    """
    cfg = settings or OsmTruthSettings()
    sel = resolve_selection(cfg.chain, chain)
    if roads is None:
        roads = read_osm_roads(osm_path)
    ids = select_chain(roads, sel)
    ch = window_chain(roads, ids, sel, origin)
    frame = ch.frame
    style = road_style(
        frame.origin.lon_deg, frame.origin.lat_deg, country=cfg.country, traffic=cfg.traffic
    )
    sign = -1 if style.traffic == "right" else 1
    cs = cfg.cross_section
    lane_w = cs.lane_width_m or style.lane_width_m
    ramp_w = cs.ramp_lane_width_m or style.ramp_lane_width_m
    w_in = cs.inner_shoulder_m if cs.inner_shoulder_m is not None else style.inner_shoulder_m
    w_hard = cs.hard_shoulder_m if cs.hard_shoulder_m is not None else style.hard_shoulder_m
    osm_ramps, skipped = find_ramps(
        roads, ch, shape=cfg.ramps, cross_section=cs, traffic=style.traffic
    )
    seg_lanes = tagged_lanes(roads, ch, cs.default_lanes)

    # ---- mainline reference line ---------------------------------------------------
    centre_xy = ch.xy.mean(axis=0) if offset_centre_xy is None else np.asarray(offset_centre_xy)
    fld = offset_field(_rng(seed, 1), cfg.offset, centre=centre_xy)
    skipped = [replace(x, xy=_moved(x.xy, fld)) for x in skipped]
    centre = smooth_line(ch.xy + fld(ch.xy), window_m=cfg.mainline_smooth_window_m)
    s_c = arc_length(centre)
    # tagged lanes along the smoothed line (by the OSM stations, scaled)
    frac = s_c / s_c[-1]
    seg_mid = 0.5 * (ch.s[1:] + ch.s[:-1]) / ch.s[-1]
    n_tag = seg_lanes[np.clip(np.searchsorted(seg_mid, frac), 0, len(seg_lanes) - 1)]
    n_sm = _moving_mean(n_tag.astype(float), 401)
    u_c = w_in + n_sm * lane_w / 2.0
    edge = centre - sign * u_c[:, None] * normals(centre)
    edge = smooth_line(edge, window_m=41.0)
    main_geo = road_with_geometry("main", fit_line(edge, tolerance_m=cfg.fit_tolerance_m))
    L = main_geo.length

    # ---- truth stations of the OSM features -----------------------------------------
    s_nodes, _ = main_geo.project(ch.xy + fld(ch.xy))
    segments = tag_segments_from_chain(s_nodes, seg_lanes, L)
    gore_xy = np.array([r.xy[0] if r.kind == "exit" else r.xy[-1] for r in osm_ramps]).reshape(
        -1, 2
    )
    gore_s = main_geo.project(gore_xy + fld(gore_xy))[0] if len(osm_ramps) else np.zeros(0)
    # one junction zone per ramp, zones apart and inside the mainline
    lz = 0.0 if cfg.junctions == "direct" else cfg.junction_length_m
    min_gap = 5.0
    accepted: list[tuple[OsmRamp, float]] = []
    last_b = -math.inf
    for r, g in sorted(zip(osm_ramps, gore_s.tolist(), strict=True), key=lambda p: p[1]):
        a, b = (g, g + lz) if r.kind == "exit" else (g - lz, g)
        what = f"{r.kind} way {r.way_ids[0]} at {g:.0f} m"
        if a < last_b + min_gap or a < min_gap or b > L - min_gap:
            why = "its junction would overlap another ramp's or the end"
            skipped.append(LeftOutRamp(r.kind, what, why, _gore_point(r, fld)))
            continue
        accepted.append((r, g))
        last_b = b
    # a link that cannot be drawn as a ramp (a U-turn across the median, a crossing road
    # meeting the chain at a node: its path knots) is left out before the lanes are laid
    # out, so that no lane opens or ends for it
    while True:
        events = [RampEvent(i, r.kind, r.side, g, r.lanes) for i, (r, g) in enumerate(accepted)]
        layout = build_layout(
            L,
            segments,
            events,
            lane_width_m=lane_w,
            ramp_lane_width_m=ramp_w,
            inner_shoulder_m=w_in,
            hard_shoulder_m=w_hard,
            cross=cs,
            events=cfg.lanes,
            rng=_rng(seed, 2),
        )
        paths = [
            _ramp_path(
                r, g, layout.attachments[ev.index], layout, main_geo, fld, cfg, sign, ramp_w, w_hard
            )
            for ev, (r, g) in zip(events, accepted, strict=True)
        ]
        bad = [k for k, (xy, _) in enumerate(paths) if _unbuildable(xy, cfg.ramps)]
        if not bad:
            break
        for k in bad:
            r, g = accepted[k]
            what = f"{r.kind} way {r.way_ids[0]} at {g:.0f} m"
            why = "its path bends tighter than a ramp can (a knot)"
            skipped.append(LeftOutRamp(r.kind, what, why, _gore_point(r, fld)))
        accepted = [a for k, a in enumerate(accepted) if k not in bad]
    z_main = mainline_profile(L, cfg.elevation, _rng(seed, 3))
    main_src = Source(main_geo, z_main, layout)

    # ---- ramps ---------------------------------------------------------------------
    ramp_srcs: list[Source] = []
    ramp_meta: list[dict] = []
    for ev, (r, g), (xy, pose) in zip(events, accepted, paths, strict=True):
        att = layout.attachments[ev.index]
        pieces = (
            fit_line(xy, tolerance_m=cfg.fit_tolerance_m, start_pose=pose)
            if r.kind == "exit"
            else fit_line(xy, tolerance_m=cfg.fit_tolerance_m, end_pose=pose)
        )
        rgeo = road_with_geometry("ramp", pieces)
        Lr = rgeo.length
        rl = _ramp_layout(att.lane_keys, att.shoulder_key, layout, g, Lr, r, ramp_w, cfg, ev.index)
        # heights: crossings of the mainline carriageway
        sig = np.linspace(0.0, Lr, max(2, int(Lr) + 1))
        pts = rgeo.xy(sig)
        s_m, t_m = main_geo.project(pts)
        u_m = sign * t_m
        u_out = layout.u_border(s_m, 1e9)
        on = (u_m > -2.0) & (u_m < u_out + 2.0) & (s_m > 0.5) & (s_m < L - 0.5)
        d_gore = sig if r.kind == "exit" else Lr - sig
        free = np.flatnonzero(~on & (d_gore > 5.0))
        crossings = []
        if free.size:
            first_free = d_gore[free].min()
            cross = on & (d_gore > first_free)
            idx = np.flatnonzero(cross)
            if idx.size:
                for run in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
                    zc = float(np.max(z_main.value(s_m[run])))
                    over = -1 if r.layer < 0 else 1
                    crossings.append(
                        (float(sig[run[0]]) - 4.0, float(sig[run[-1]]) + 4.0, zc, over)
                    )
        z_g = float(z_main.value(g))
        grade_g = float(z_main.derivative(g))
        zprof, reached = ramp_profile(
            sig,
            kind=r.kind,
            z_gore=z_g,
            grade_gore=grade_g,
            crossings=crossings,
            cfg=cfg.elevation,
            rng=_rng(seed, 100 + ev.index),
        )
        kap = np.abs(curvature(rgeo.xy(np.linspace(0, Lr, max(4, int(Lr * 2))))))
        ramp_srcs.append(Source(rgeo, zprof, rl))
        ramp_meta.append(
            {
                "min_radius_m": float(1.0 / max(kap.max(), 1e-9)),
                "crossings": tuple(reached),
                "self_intersects": self_intersects(pts),
            }
        )

    # ---- roads and junctions -------------------------------------------------------
    network, route, main_ids, ramp_ids = _assemble(
        main_src, ramp_srcs, events, accepted, cfg, style, sign
    )
    network = replace(network, header=replace(network.header, geo_reference=frame.geo_reference))
    ramps = tuple(
        RampTruth(
            ramp_ids[k],
            ev.kind,
            ev.side,
            ev.station_m,
            ev.lanes,
            r.way_ids,
            ramp_srcs[k].road.length,
            ramp_meta[k]["min_radius_m"],
            ramp_meta[k]["crossings"],
        )
        for k, (ev, (r, _)) in enumerate(zip(events, accepted, strict=True))
    )
    s10 = np.arange(0.0, ch.length, 10.0)
    pts10 = np.column_stack([np.interp(s10, ch.s, ch.xy[:, 0]), np.interp(s10, ch.s, ch.xy[:, 1])])
    disp = fld(pts10)
    full = build_road(
        main_src, 0.0, L, road_id="0", name="mainline", sign=sign, markings=style.markings
    )
    log.info(
        "osm truth %s: chain %.0f m (%d ways), %d ramps (%d exits), %d roads",
        Path(osm_path).name,
        L,
        len(ch.way_ids),
        len(ramps),
        sum(r.type == "exit" for r in ramps),
        len(network.roads),
    )
    return OsmTruth(
        network=network,
        route=route,
        mainline_ids=main_ids,
        osm_path=Path(osm_path),
        ramps=ramps,
        style=style,
        origin=frame.origin,
        chain_way_ids=ch.way_ids,
        mainline=full.road,
        layout=layout,
        osm_offset_m=np.column_stack([s10, disp]),
        tagged_lanes=tuple(segments),
        seed=seed,
        skipped=tuple(skipped),
        notes=tuple(layout.notes),
        offset_centre_xy=(float(centre_xy[0]), float(centre_xy[1])),
    )


def _ramp_path(
    r: OsmRamp,
    g: float,
    att,
    layout: Layout,
    main_geo: Road,
    fld,
    cfg: OsmTruthSettings,
    sign: int,
    ramp_w: float,
    w_hard: float,
) -> tuple[NDArray, tuple[float, float, float]]:
    """The reference line of ramp ``r`` attached at station ``g`` (dense polyline, driving
    order) and its pose at the gore (:func:`~.geometry.ramp_polyline`); ``ramp_w`` and
    ``w_hard`` are the ramp lane's and the hard shoulder's widths (metres)."""
    cs = cfg.cross_section
    sg = np.array([g + (1e-3 if r.kind == "entry" else -1e-3)])
    if r.side == "outer":
        first = min((x for x in layout.strips if x.key in att.lane_keys), key=lambda x: x.rank)
        u = float(layout.u_border(sg, first.rank)[0])
    else:
        u = float(layout.u_inner_edge(sg)[0])
    tc = smooth_line(r.xy + fld(r.xy), window_m=cfg.ramps.smooth_window_m)
    u_rc = cs.ramp_inner_shoulder_m + r.lanes * ramp_w / 2.0
    target = tc - sign * u_rc * normals(tc)
    sh = next((x for x in layout.strips if x.key == att.shoulder_key), None)
    w_sh = float(sh.full(sg)[0]) if sh is not None else w_hard
    gore_sh = cs.ramp_inner_shoulder_m if r.side == "outer" else cs.ramp_hard_shoulder_m
    return ramp_polyline(
        main_geo,
        g,
        sign * u,
        target,
        kind=r.kind,
        away_sign=float(sign if r.side == "outer" else -sign),
        separation_m=w_sh + gore_sh + cfg.ramps.gore_gap_m,
        cfg=cfg.ramps,
    )


def _unbuildable(xy: NDArray, shape: RampShape) -> bool:
    """A ramp path that crosses itself or bends tighter than half the design radius."""
    kap = np.abs(curvature(xy))
    return bool(self_intersects(xy) or kap.max(initial=0.0) * 0.5 * shape.min_radius_m > 1.0)


def _ramp_layout(
    lane_keys: tuple[str, ...],
    shoulder_key: str,
    main: Layout,
    g: float,
    length: float,
    r: OsmRamp,
    ramp_w: float,
    cfg: OsmTruthSettings,
    index: int,
) -> Layout:
    """Lanes of a ramp road (stations 0..length in driving order): its driving lanes and
    the shoulder it shares with the mainline keep their widths at the gore and change to
    the ramp's widths over 80 m; the shoulder on the gore side opens (exit) or closes
    (entry) over up to 100 m."""
    exit_ = r.kind == "exit"
    by_key = {x.key: x for x in main.strips}
    cs = cfg.cross_section
    open_m = min(cfg.lanes.gore_shoulder_taper_m, 0.4 * length)

    def blended(w_gore: float, w_ramp: float):
        def fn(s):
            d = np.asarray(s, float) if exit_ else length - np.asarray(s, float)
            f = np.clip(d / 80.0, 0.0, 1.0)
            f = f * f * (3 - 2 * f)
            return (1 - f) * w_gore + f * w_ramp

        return fn

    def const(w: float):
        return lambda s: np.full(np.shape(s), w, dtype=float)

    strips: list[Strip] = []
    for j, key in enumerate(lane_keys):
        src = by_key.get(key)
        w0 = float(src.full(np.array([g]))[0]) if src is not None else ramp_w
        strips.append(Strip(key, "through", float(j), 0.0, length, blended(w0, ramp_w)))
    sh = by_key.get(shoulder_key)
    outer = r.side == "outer"
    cont_w = cs.ramp_hard_shoulder_m if outer else cs.ramp_inner_shoulder_m
    w_sh = float(sh.full(np.array([g]))[0]) if sh is not None else cont_w
    cont = Strip(
        shoulder_key or f"R{index}.sh",
        "hard" if outer else "inner",
        1e6 if outer else -1e6,
        0.0,
        length,
        blended(w_sh, cont_w),
    )
    new_w = cs.ramp_inner_shoulder_m if outer else cs.ramp_hard_shoulder_m
    new = Strip(
        f"R{index}.gore",
        "inner" if outer else "hard",
        -1e6 if outer else 1e6,
        0.0,
        length,
        const(new_w),
        open_m=open_m if exit_ else 0.0,
        close_m=0.0 if exit_ else open_m,
    )
    strips += [cont, new]
    return Layout(length, strips, {}, 0.0, -1e9)


def _assemble(
    main_src: Source,
    ramp_srcs: list[Source],
    events: list[RampEvent],
    accepted: list[tuple[OsmRamp, float]],
    cfg: OsmTruthSettings,
    style: RoadStyle,
    sign: int,
) -> tuple[RoadNetwork, tuple[str, ...], tuple[str, ...], list[str]]:
    """Mainline roads between junction zones, through and ramp connecting roads, ramp
    roads, junctions with lane links; returns the network, route, mainline ids, ramp ids."""
    direct = cfg.junctions == "direct"
    lz = 0.0 if direct else cfg.junction_length_m
    L = main_src.road.length
    mk = style.markings
    zones = [
        (g - lz, g) if ev.kind == "entry" else (g, g + lz)
        for ev, (_, g) in zip(events, accepted, strict=True)
    ]
    bounds = [0.0] + [x for z in zones for x in z] + [L]
    mains = [
        build_road(
            main_src,
            bounds[2 * i],
            bounds[2 * i + 1],
            road_id=str(i + 1),
            name="mainline",
            sign=sign,
            markings=mk,
        )
        for i in range(len(zones) + 1)
    ]
    roads_out: list[BuiltRoad] = []
    junctions: list[Junction] = []
    route: list[str] = [mains[0].road.id]
    ramp_ids: list[str] = []
    conn_id = 301
    for k, (ev, src) in enumerate(zip(events, ramp_srcs, strict=True)):
        jid = str(1001 + k)
        rid = str(101 + k)
        ramp_ids.append(rid)
        up, down = mains[k], mains[k + 1]
        J = RoadLink("junction", jid)
        up = BuiltRoad(replace_road(up.road, successor=J), up.keys)
        down = BuiltRoad(replace_road(down.road, predecessor=J), down.keys)
        Lr = src.road.length
        conns: list[Connection] = []
        if direct:
            ramp = build_road(src, 0.0, Lr, road_id=rid, name=ev.kind, sign=sign, markings=mk)
            ramp = BuiltRoad(
                replace_road(
                    ramp.road, **({"predecessor": J} if ev.kind == "exit" else {"successor": J})
                ),
                ramp.keys,
            )
            conns.append(_conn("0", up, down))
            conns.append(_conn("1", up, ramp) if ev.kind == "exit" else _conn("1", ramp, down))
            roads_out.append(ramp)
        else:
            a, b = zones[k]
            t_id = str(conn_id)
            c_id = str(conn_id + 1)
            conn_id += 2
            through = build_road(
                main_src, a, b, road_id=t_id, name="connector", sign=sign, markings=mk, junction=jid
            )
            through = _link_connector(through, up, down)
            lzr = min(lz, 0.3 * Lr)
            if ev.kind == "exit":
                rconn = build_road(
                    src,
                    0.0,
                    lzr,
                    road_id=c_id,
                    name="connector",
                    sign=sign,
                    markings=mk,
                    junction=jid,
                )
                ramp = build_road(src, lzr, Lr, road_id=rid, name="exit", sign=sign, markings=mk)
                ramp = BuiltRoad(replace_road(ramp.road, predecessor=J), ramp.keys)
                rconn = _link_connector(rconn, up, ramp, down_contact="start")
                conns += [_conn("0", up, through), _conn("1", up, rconn)]
            else:
                ramp = build_road(
                    src, 0.0, Lr - lzr, road_id=rid, name="entry", sign=sign, markings=mk
                )
                ramp = BuiltRoad(replace_road(ramp.road, successor=J), ramp.keys)
                rconn = build_road(
                    src,
                    Lr - lzr,
                    Lr,
                    road_id=c_id,
                    name="connector",
                    sign=sign,
                    markings=mk,
                    junction=jid,
                )
                rconn = _link_connector(rconn, ramp, down)
                conns += [_conn("0", up, through), _conn("1", ramp, rconn)]
            roads_out += [through, rconn, ramp]
            route.append(t_id)
        mains[k], mains[k + 1] = up, down
        route.append(mains[k + 1].road.id)
        name = f"{ev.kind} ({ev.side}) at {ev.station_m:.0f} m"
        junctions.append(
            Junction(jid, tuple(conns), name=name, type="direct" if direct else "default")
        )
    header = Header(
        name="roadtwin osm truth",
        geo_reference="",
        vendor="roadtwin-simulate",
    )
    net = RoadNetwork(header, tuple(b.road for b in (*mains, *roads_out)), tuple(junctions))
    return net, tuple(route), tuple(m.road.id for m in mains), ramp_ids


def replace_road(road: Road, **kw) -> Road:
    from dataclasses import replace

    return replace(road, **kw)


def _conn(cid: str, incoming: BuiltRoad, target: BuiltRoad) -> Connection:
    from ...model import LaneLink

    links = tuple(LaneLink(a, b) for a, b in lane_pairs(incoming, target))
    return Connection(cid, incoming.road.id, target.road.id, "start", links)


def _link_connector(
    conn: BuiltRoad, up: BuiltRoad, down: BuiltRoad, *, down_contact: str = "start"
) -> BuiltRoad:
    """Road and lane links of a connecting road from the end of ``up`` to ``down``."""
    pred = {b: a for a, b in lane_pairs(up, conn)}
    succ = dict(lane_pairs(conn, down))
    out = set_end_links(conn, predecessors=pred, successors=succ)
    road = replace_road(
        out.road,
        predecessor=RoadLink("road", up.road.id, "end"),
        successor=RoadLink("road", down.road.id, down_contact),  # type: ignore[arg-type]
    )
    return BuiltRoad(road, out.keys)
