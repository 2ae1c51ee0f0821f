"""Algorithm 1 of the paper and ramp chains: directed OSM ``*_link`` edges near the
trajectory, merged into chains, with the direction check and the side they lie on.

All coordinates are in the mapping frame (metres, radians CCW from +x).
"""

from __future__ import annotations

import logging
import math
from typing import Any

import networkx as nx
import numpy as np
import shapely
from scipy.spatial import cKDTree

from .._errors import InputError
from ..config import RampConfig
from ..fitting import PolylineFrame, arc_length, resample_polyline, savgol_smooth
from .lanes import _first_value
from .records import EdgeKey, FloatArray, RampCandidate, RampChain, RampType, TrafficSide

log = logging.getLogger(__name__)

# ---------------------------------------------------------------------------
# the trajectory as a Frenet frame
# ---------------------------------------------------------------------------


class _Track:
    """The driven path as a smooth 1 m Frenet frame with a KD-tree built once."""

    def __init__(self, trajectory_xy: FloatArray) -> None:
        xy = _dedupe_xy(np.asarray(trajectory_xy, dtype=float)[:, :2])
        dense = resample_polyline(xy, 1.0)
        smooth = savgol_smooth(dense, window=21, polyorder=2)
        smooth[0], smooth[-1] = dense[0], dense[-1]
        self.frame = PolylineFrame.from_points(smooth)
        self.tree = cKDTree(self.frame.xy)
        self.length = self.frame.length

    def project(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Frenet ``(s, t)`` of ``(N, 2)`` points (metres; t left positive)."""
        pts = np.asarray(points, dtype=float)[:, :2]
        _, idx = self.tree.query(pts)
        f = self.frame
        s = f.s[idx] + np.einsum("ij,ij->i", pts - f.xy[idx], f.tangent[idx])
        xy_r, tg_r = f.at(np.clip(s, 0.0, f.length))
        s = np.where((s >= 0.0) & (s <= f.length), s + np.einsum("ij,ij->i", pts - xy_r, tg_r), s)
        xy_r, tg_r = f.at(np.clip(s, 0.0, f.length))
        d = pts - xy_r
        return s, tg_r[:, 0] * d[:, 1] - tg_r[:, 1] * d[:, 0]

    def heading(self, s: FloatArray) -> FloatArray:
        """Heading (radians) of the driven path at stations ``s``."""
        _, tg = self.frame.at(np.clip(s, 0.0, self.length))
        return np.arctan2(tg[..., 1], tg[..., 0])


def _wrap(angle: FloatArray | float) -> FloatArray | float:
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def edge_xy(graph: nx.MultiDiGraph, u: Any, v: Any, key: int) -> FloatArray:
    """``(N, 2)`` polyline of an OSM edge from ``u`` to ``v`` (mapping frame, metres)."""
    data = graph.edges[u, v, key]
    geom = data.get("geometry")
    if geom is not None:
        return np.asarray(geom.coords, dtype=float)[:, :2]
    nu, nv = graph.nodes[u], graph.nodes[v]
    return np.array([[nu["x"], nu["y"]], [nv["x"], nv["y"]]], dtype=float)


def _end_heading(xy: FloatArray, *, at_start: bool, reach_m: float = 8.0) -> float:
    """Heading of a polyline at its start (pointing forward) or end, over ``reach_m``."""
    s = arc_length(xy)
    if at_start:
        j = int(min(np.searchsorted(s, min(reach_m, s[-1])), len(s) - 1))
        d = xy[j] - xy[0]
    else:
        j = int(max(np.searchsorted(s, max(s[-1] - reach_m, 0.0), side="right") - 1, 0))
        d = xy[-1] - xy[j]
    return math.atan2(d[1], d[0])


def _dedupe_xy(xy: FloatArray) -> FloatArray:
    keep = np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > 1e-9])
    out = xy[keep]
    if out.shape[0] < 2:
        msg = "ramps: the trajectory needs at least two distinct poses"
        raise InputError(msg)
    return out


def _is_link(data: dict[str, Any]) -> bool:
    hw = data.get("highway", "")
    hw = " ".join(hw) if isinstance(hw, (list, tuple)) else str(hw)
    return "_link" in hw


# ---------------------------------------------------------------------------
# Algorithm 1 and chains
# ---------------------------------------------------------------------------


def find_candidates(
    osm_graph: nx.MultiDiGraph, trajectory_xy: FloatArray, *, config: RampConfig | None = None
) -> tuple[RampCandidate, ...]:
    """Algorithm 1: directed ``*_link`` edges within ``d_r`` of the trajectory.

    Parameters
    ----------
    osm_graph
        OSM graph projected into the mapping frame (``roadtwin.osm.load_osm``).
    trajectory_xy
        ``(N, 2)`` vehicle positions, mapping frame, metres.
    config
        ``candidate_distance_m`` is ``d_r``.

    Returns
    -------
    Candidates sorted by (distance, way id) -- deterministic.
    """
    cfg = config or RampConfig()
    traj_xy = _dedupe_xy(np.asarray(trajectory_xy, dtype=float)[:, :2])
    # coarse distances from a KD-tree of the trajectory resampled at 1 m (error < 0.5 m),
    # exact ones (shapely) only near d_r, against the stretch of trajectory concerned
    traj_s = arc_length(traj_xy)
    step = 1.0
    n = max(2, math.ceil(traj_s[-1] / step) + 1)
    dense_s = np.linspace(0.0, traj_s[-1], n)
    dense = np.stack([np.interp(dense_s, traj_s, traj_xy[:, j]) for j in range(2)], axis=1)
    tree = cKDTree(dense)
    out = []
    for u, v, k, data in osm_graph.edges(keys=True, data=True):
        if not _is_link(data):
            continue
        xy = edge_xy(osm_graph, u, v, k)
        coarse, idx = tree.query(resample_polyline(xy, step))
        if float(coarse.min()) > cfg.candidate_distance_m + step:
            continue
        s_lo, s_hi = dense_s[max(int(idx.min()) - 2, 0)], dense_s[min(int(idx.max()) + 2, n - 1)]
        a = max(int(np.searchsorted(traj_s, s_lo, side="right")) - 2, 0)
        b = min(int(np.searchsorted(traj_s, s_hi)) + 2, len(traj_s))
        d = shapely.distance(shapely.LineString(xy), shapely.LineString(traj_xy[a:b]))
        if d <= cfg.candidate_distance_m:
            data = osm_graph.edges[u, v, k]
            hw = data.get("highway", "")
            out.append(
                RampCandidate(
                    u,
                    v,
                    k,
                    " ".join(hw) if isinstance(hw, list) else str(hw),
                    _first_value(data.get("osmid")),
                    float(d),
                )
            )
    out.sort(key=lambda c: (round(c.distance_m, 6), str(c.osm_way_id), str(c.u), str(c.v)))
    return tuple(out)


_TRACK_END_M = 100.0  # near the drive's ends a carriageway node may show one side only


def _mainline_nodes(
    osm_graph: nx.MultiDiGraph, track: _Track, cfg: RampConfig
) -> dict[Any, EdgeKey]:
    """OSM nodes on the driven carriageway -> one aligned non-link edge at that node.

    A node is on the carriageway when the carriageway runs through it: a non-link edge
    arrives and one leaves, each with the driven heading at the node and each lying along
    the drive (median offset within ``mainline_match_m``). Where a motorway branch ends
    next to the drive and goes on as a link (a flyover joining from the far side), its
    last node is near the drive and aligned with it, but nothing of the carriageway
    leaves it, so the link is a ramp, not part of the carriageway. Within
    ``_TRACK_END_M`` of the drive's ends one side is enough (the extract is cut there).
    Where the drive has motorway or trunk edges along it, only those make the carriageway:
    a frontage road running beside it (a tertiary road 15 m off, with the exit's link
    ending on it) is not the carriageway.
    """
    max_dh = math.radians(cfg.max_heading_diff_deg)
    node_ids = list(osm_graph.nodes)
    if not node_ids:
        return {}
    pts = np.array([[osm_graph.nodes[n]["x"], osm_graph.nodes[n]["y"]] for n in node_ids])
    s, t = track.project(pts)
    near = (np.abs(t) <= cfg.mainline_match_m) & (s >= -cfg.mainline_match_m)
    near &= s <= track.length + cfg.mainline_match_m
    near_nodes = {n: float(si) for n, si, ok in zip(node_ids, s, near, strict=False) if ok}

    def along_drive(xy: FloatArray) -> bool:
        s_e, t_e = track.project(resample_polyline(xy, 2.0))
        inside = (s_e >= 0.0) & (s_e <= track.length)
        return bool(np.median(np.abs(t_e[inside] if inside.any() else t_e)) <= cfg.mainline_match_m)

    # per node: the aligned edges of each direction, motorway/trunk ones first
    found: dict[Any, tuple[dict[bool, EdgeKey], dict[bool, EdgeKey]]] = {}
    for n, sn in near_nodes.items():
        h_track = float(track.heading(np.array([sn]))[0])
        edges = [(u, v, k, True) for u, v, k in osm_graph.out_edges(n, keys=True)]
        edges += [(u, v, k, False) for u, v, k in osm_graph.in_edges(n, keys=True)]
        aligned: dict[bool, EdgeKey] = {}
        major: dict[bool, EdgeKey] = {}
        for u, v, k, outgoing in sorted(edges, key=lambda e: (str(e[0]), str(e[1]), e[2])):
            data = osm_graph.edges[u, v, k]
            if outgoing in major or _is_link(data):
                continue
            xy = edge_xy(osm_graph, u, v, k)
            h = _end_heading(xy, at_start=outgoing)
            if abs(float(_wrap(h - h_track))) <= max_dh and along_drive(xy):
                aligned.setdefault(outgoing, (u, v, k))
                if _carriageway_class(data):
                    major[outgoing] = (u, v, k)
        found[n] = (aligned, major)
    strict = any(major for _, major in found.values())
    out: dict[Any, EdgeKey] = {}
    for n, (aligned, major) in found.items():
        use = major if strict else aligned
        sn = near_nodes[n]
        at_end = sn <= _TRACK_END_M or sn >= track.length - _TRACK_END_M
        if len(use) == 2 or (use and at_end):
            out[n] = use.get(True, use.get(False))
    return out


def _follow(
    osm_graph: nx.MultiDiGraph,
    first: EdgeKey,
    *,
    forward: bool,
    stop_nodes: dict[Any, EdgeKey],
    max_length_m: float,
    any_class: bool = False,
) -> list[EdgeKey]:
    """Link edges from ``first`` onward (or backward) until a junction, the carriageway or
    ``max_length_m``; with ``any_class`` (a carriageway branch) edges of its own class.

    A node where only two edges meet, the link and a motorway or trunk edge, is no
    junction: a branch of another carriageway that ends as a link (or a link that goes on
    as a carriageway) is one ramp, followed on along that carriageway's class."""
    same = _highway(osm_graph.edges[first]) if any_class else None

    def ramp_edge(data: dict[str, Any]) -> bool:
        return _is_link(data) or (same is not None and _highway(data) == same)

    chain = [first]
    length = float(arc_length(edge_xy(osm_graph, *first))[-1])
    seen = {first[0], first[1]}
    while length < max_length_m:
        node = chain[-1][1] if forward else chain[-1][0]
        if node in stop_nodes:
            break
        out_all = list(osm_graph.out_edges(node, keys=True))
        in_all = list(osm_graph.in_edges(node, keys=True))
        onward = out_all if forward else in_all
        if (
            same is None
            and len(out_all) == 1
            and len(in_all) == 1
            and _carriageway_class(osm_graph.edges[onward[0]])
        ):
            same = _highway(osm_graph.edges[onward[0]])
        outs = [e for e in out_all if ramp_edge(osm_graph.edges[e])]
        ins = [e for e in in_all if ramp_edge(osm_graph.edges[e])]
        # a junction: any non-link road meets here, or the link forks/joins
        others = [e for e in (*out_all, *in_all) if not ramp_edge(osm_graph.edges[e])]
        if others or len(outs) != 1 or len(ins) != 1:
            break
        nxt = outs[0] if forward else ins[0]
        far = nxt[1] if forward else nxt[0]
        if far in seen:
            break
        seen.add(far)
        chain.append(nxt)
        length += float(arc_length(edge_xy(osm_graph, *nxt))[-1])
    return chain if forward else chain[::-1]


def chain_xy(osm_graph: nx.MultiDiGraph, edges: list[EdgeKey]) -> FloatArray:
    """One polyline along consecutive edges (mapping frame, metres; repeated points
    dropped)."""
    parts = [edge_xy(osm_graph, *e) for e in edges]
    xy = np.vstack([parts[0], *[p[1:] for p in parts[1:]]])
    keep = np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > 1e-6])
    return xy[keep]


_BRANCH_CLASSES = ("motorway", "trunk")
_BRANCH_PROBE_M = 120.0  # how far along a fork it is looked at
_BRANCH_AWAY_M = 12.0  # ... and how far from the drive it must be there to be a branch


def _highway(data: dict[str, Any]) -> str:
    hw = data.get("highway", "")
    return " ".join(hw) if isinstance(hw, (list, tuple)) else str(hw)


def _carriageway_class(data: dict[str, Any]) -> bool:
    """A motorway or trunk edge (or one of their links)."""
    return any(c in _highway(data) for c in _BRANCH_CLASSES)


def _node_xy(osm_graph: nx.MultiDiGraph, node: Any) -> FloatArray:
    """``(1, 2)`` position of an OSM node (mapping frame, metres)."""
    return np.array([[osm_graph.nodes[node]["x"], osm_graph.nodes[node]["y"]]])


def _reach_xy(osm_graph: nx.MultiDiGraph, edge: EdgeKey, *, forward: bool) -> FloatArray:
    """The polyline of ``edge`` continued along single successors (forward) or
    predecessors up to ``_BRANCH_PROBE_M``, starting at the fork node."""
    parts = [edge_xy(osm_graph, *edge)]
    if not forward:
        parts = [parts[0][::-1]]
    length = float(arc_length(parts[0])[-1])
    node = edge[1] if forward else edge[0]
    seen = {edge[0], edge[1]}
    while length < _BRANCH_PROBE_M:
        nxt = list(
            osm_graph.out_edges(node, keys=True) if forward else osm_graph.in_edges(node, keys=True)
        )
        if len(nxt) != 1:
            break
        e = nxt[0]
        far = e[1] if forward else e[0]
        if far in seen:
            break
        seen.add(far)
        xy = edge_xy(osm_graph, *e)
        parts.append(xy if forward else xy[::-1])
        length += float(arc_length(xy)[-1])
        node = far
    return np.vstack(parts)


def branch_candidates(
    osm_graph: nx.MultiDiGraph,
    track: _Track,
    on_carriageway: dict[Any, EdgeKey],
) -> tuple[RampCandidate, ...]:
    """Carriageway forks that are not ``*_link`` ways: a motorway or trunk way leaving
    (or joining) the driven carriageway at one of its nodes and ``_BRANCH_AWAY_M`` away
    from the drive ``_BRANCH_PROBE_M`` further on (a motorway splitting in two, a
    motorway merging into another). Links cover ordinary ramps (Algorithm 1); these are
    the interchanges' carriageway branches, which OSM tags as the road class itself.
    Forks within ``_BRANCH_PROBE_M`` of the drive's ends are left out (the carriageway
    itself runs on beyond them)."""
    out = []
    for n in on_carriageway:
        xy_n = _node_xy(osm_graph, n)
        s_n, _ = track.project(xy_n)
        if not _BRANCH_PROBE_M <= float(s_n[0]) <= track.length - _BRANCH_PROBE_M:
            continue
        edges = [(e, True) for e in osm_graph.out_edges(n, keys=True)]
        edges += [(e, False) for e in osm_graph.in_edges(n, keys=True)]
        for e, forward in edges:
            data = osm_graph.edges[e]
            if _is_link(data) or not _carriageway_class(data):
                continue
            xy = _reach_xy(osm_graph, e, forward=forward)
            a = arc_length(xy)
            if a[-1] < 0.5 * _BRANCH_PROBE_M:
                continue
            probe = xy[min(int(np.searchsorted(a, _BRANCH_PROBE_M)), len(xy) - 1)]
            _, t = track.project(probe[None, :])
            if abs(float(t[0])) < _BRANCH_AWAY_M:
                continue  # the carriageway itself (or a parallel one close by)
            d = float(shapely.distance(shapely.LineString(edge_xy(osm_graph, *e)),
                                       shapely.Point(xy_n[0])))  # fmt: skip
            out.append(
                RampCandidate(e[0], e[1], e[2], _highway(data), _first_value(data.get("osmid")), d)
            )
    return tuple(sorted(out, key=lambda c: (str(c.osm_way_id), str(c.u), str(c.v))))


_SIDE_CLEAR_M = 3.0  # a ramp's side is read where it is this far off the carriageway line


def _ramp_side(
    track: _Track, xy: FloatArray, attach_xy: FloatArray, *, exit_: bool, sign: float
) -> str:
    """``"outer"`` (traffic side) or ``"inner"`` (median side): the side of the carriageway
    on which the ramp first lies clear of the carriageway's OSM line, going away from the
    attachment.

    The offset is measured from the carriageway's line through the attachment, not from
    the drive: the car keeps to one lane, and a link drawn close to the carriageway can lie
    on the far side of the car's lane. The side where the ramp first clears the line is
    the side on which it joins: a flyover crosses the carriageway further away.
    ``sign`` is -1 for right-hand traffic (outer = right = negative offset), else +1."""
    dense = resample_polyline(xy, 1.0)
    if not exit_:
        dense = dense[::-1]
    _, t = track.project(dense)
    _, t_attach = track.project(attach_xy)
    t_rel = t - float(t_attach[0])
    along = arc_length(dense)
    away = along > min(20.0, 0.5 * along[-1])
    clear = away & (np.abs(t_rel) >= _SIDE_CLEAR_M)
    if np.any(clear):
        side_t = float(t_rel[int(np.argmax(clear))])
    else:
        side_t = float(np.median(t_rel[away] if np.any(away) else t_rel))
    return "outer" if side_t * sign > 0.0 else "inner"


def _parallel_groups(osm_graph: nx.MultiDiGraph, node: Any, *, forward: bool) -> list[list]:
    """Groups of two or more carriageway/link edges leaving (``forward``) or reaching
    ``node`` along the same neighbouring node: ways drawn over the same nodes."""
    edges = osm_graph.out_edges(node, keys=True) if forward else osm_graph.in_edges(node, keys=True)
    groups: dict[Any, list[EdgeKey]] = {}
    for e in edges:
        data = osm_graph.edges[e]
        if _is_link(data) or _carriageway_class(data):
            groups.setdefault(e[1] if forward else e[0], []).append(e)
    return [g for g in groups.values() if len(g) >= 2]


def _shared_branches(
    osm_graph: nx.MultiDiGraph,
    track: _Track,
    on_carriageway: dict[Any, EdgeKey],
    cfg: RampConfig,
) -> list[tuple[float, RampChain]]:
    """Branches that OSM draws over the carriageway's own nodes: two carriageway (or
    link) ways leave a node of the drive along the same next node (an exit that parts
    later), or arrive at one from the same previous node (an entry). For each, a chain
    along the shared edges of the other way, up to ``max_ramp_length_m``, once per side
    (``shared``; only one that a measured gore confirms is built), with the station of
    its attachment along the drive (metres)."""
    out: list[tuple[float, RampChain]] = []
    for n in on_carriageway:
        s_n = float(track.project(_node_xy(osm_graph, n))[0][0])
        if not 0.0 < s_n < track.length:
            continue
        for forward in (True, False):
            onward = _parallel_groups(osm_graph, n, forward=forward)
            # where the sharing begins (an exit) or ends (an entry): not shared behind
            if not onward or _parallel_groups(osm_graph, n, forward=not forward):
                continue
            for parallel in onward:
                # the carriageway's own way is the first in key order; the branch is the
                # other one, followed while it stays on shared edges
                branch = sorted(parallel, key=lambda e: e[2])[1]
                chain, length = [branch], float(arc_length(edge_xy(osm_graph, *branch))[-1])
                while length < cfg.max_ramp_length_m:
                    node = chain[-1][1] if forward else chain[-1][0]
                    nxt = (
                        osm_graph.out_edges(node, keys=True)
                        if forward
                        else osm_graph.in_edges(node, keys=True)
                    )
                    same = [e for e in nxt if e[2] == branch[2]]
                    if len(same) != 1 or same[0] in chain:
                        break
                    chain.append(same[0])
                    length += float(arc_length(edge_xy(osm_graph, *same[0]))[-1])
                edges_ = chain if forward else chain[::-1]
                xy = chain_xy(osm_graph, edges_)
                ways = tuple(
                    dict.fromkeys(_first_value(osm_graph.edges[x].get("osmid")) for x in edges_)
                )
                tags = dict(osm_graph.edges[branch])
                tags.pop("geometry", None)
                kind: RampType = "exit" if forward else "entry"
                for side in ("outer", "inner"):
                    out.append(
                        (
                            s_n,
                            RampChain(
                                edges=tuple(edges_),
                                osm_way_ids=ways,
                                attach_node=n,
                                mainline_edge=on_carriageway[n],
                                type=kind,
                                type_geometry=kind,
                                xy=xy,
                                tags=tags,
                                side=side,  # type: ignore[arg-type]
                                shared=True,
                            ),
                        )
                    )
    return out


def _near_run_end(track: _Track, xy: FloatArray, margin_m: float) -> bool:
    """Whether the point (mapping frame, metres) projects within ``margin_m`` of the
    trajectory's start or end (or beyond them)."""
    s, _ = track.project(np.asarray(xy, dtype=float).reshape(1, 2))
    return bool(s[0] < margin_m or s[0] > track.length - margin_m)


def extract_ramp_chains(
    osm_graph: nx.MultiDiGraph,
    trajectory_xy: FloatArray,
    *,
    traffic_side: TrafficSide = "right",
    candidates: tuple[RampCandidate, ...] | None = None,
    config: RampConfig | None = None,
) -> tuple[tuple[RampChain, ...], tuple[tuple[str, str], ...]]:
    """Merge candidate link edges into ramp chains attached to the driven carriageway.

    A candidate attaches where one of its nodes is on the driven carriageway (an OSM node
    near the trajectory with a non-link edge in the driven direction). Paper's rule: the
    ramp is a merge (``"entry"``) if its edge ends on the carriageway (``v_r`` in
    ``{u_m, v_m}``), else an exit. The chain is followed away from the carriageway along
    link edges up to ``max_ramp_length_m`` or the next junction. Chains are rejected when
    the ramp's heading at the attachment differs from the driven direction by more than
    ``max_heading_diff_deg``. A chain on the median side of the trajectory (left for
    right-hand traffic) is an inner ramp (``side="inner"``): a left exit or entry.

    Returns
    -------
    (chains, rejected)
        Chains sorted by attachment station; ``rejected`` lists ``(what, reason)``.
    """
    cfg = config or RampConfig()
    if candidates is None:
        candidates = find_candidates(osm_graph, trajectory_xy, config=cfg)
    track = _Track(trajectory_xy)
    on_carriageway = _mainline_nodes(osm_graph, track, cfg)
    branches = branch_candidates(osm_graph, track, on_carriageway)
    branch_edges = {(c.u, c.v, c.key) for c in branches}
    known = {(x.u, x.v, x.key) for x in candidates}
    candidates = (*candidates, *(c for c in branches if (c.u, c.v, c.key) not in known))
    side_sign = -1.0 if traffic_side == "right" else 1.0
    max_dh = math.radians(cfg.max_heading_diff_deg)

    chains: list[tuple[float, RampChain]] = []
    rejected: list[tuple[str, str]] = []
    covered: set[EdgeKey] = set()
    attached = []
    for cand in candidates:
        e = (cand.u, cand.v, cand.key)
        u_on, v_on = cand.u in on_carriageway, cand.v in on_carriageway
        if u_on and v_on:
            # an end at the run's start or end lies where the map ends: the branch is a
            # ramp at its other end (krems chain 30799129: a two-lane trunk merging at
            # 337 m left the carriageway 9 m before the run's end; rejected as a bypass,
            # the entry was missing from every build of the run)
            u_end, v_end = (
                _near_run_end(track, _node_xy(osm_graph, n), cfg.run_end_margin_m)
                for n in (cand.u, cand.v)
            )
            # (not a piece of a driven way: oakland chain 28393854, driven in its inner
            # lane, had one between a node at the run's start and one 440 m on)
            driven = {
                _first_value(osm_graph.edges[on_carriageway[n]].get("osmid"))
                for n in (cand.u, cand.v)
            }
            if u_end != v_end and cand.osm_way_id not in driven:
                u_on, v_on = not u_end, not v_end
        if u_on and v_on:
            rejected.append((f"way {cand.osm_way_id}", "both ends on the driven carriageway"))
            covered.add(e)
        elif u_on or v_on:
            attached.append((cand, "entry" if v_on else "exit"))
    for cand, ramp_type in attached:
        e = (cand.u, cand.v, cand.key)
        if e in covered:
            continue
        attach = cand.v if ramp_type == "entry" else cand.u
        edges = _follow(
            osm_graph,
            e,
            forward=ramp_type == "exit",
            stop_nodes=on_carriageway,
            max_length_m=cfg.max_ramp_length_m,
            any_class=e in branch_edges,
        )
        covered.update(edges)
        xy = chain_xy(osm_graph, edges)
        ways = tuple(dict.fromkeys(_first_value(osm_graph.edges[x].get("osmid")) for x in edges))
        what = f"ways {', '.join(str(w) for w in ways)} ({ramp_type})"
        # direction check at the attachment
        node_xy = _node_xy(osm_graph, attach)
        s_att, _ = track.project(node_xy)
        h_track = float(track.heading(s_att)[0])
        h_ramp = _end_heading(xy, at_start=ramp_type == "exit")
        dh = abs(float(_wrap(h_ramp - h_track)))
        if dh > max_dh:
            rejected.append(
                (what, f"heading at the attachment {math.degrees(dh):.0f} deg off the drive")
            )
            continue
        # which side of the drive the ramp lies on, away from the attachment
        s_pts, t_pts = track.project(xy)
        ramp_side = _ramp_side(track, xy, node_xy, exit_=ramp_type == "exit", sign=side_sign)
        # geometry cross-check: which end lies nearer the trajectory
        d_start, d_end = abs(float(t_pts[0])), abs(float(t_pts[-1]))
        in_start = -5.0 <= s_pts[0] <= track.length + 5.0
        in_end = -5.0 <= s_pts[-1] <= track.length + 5.0
        if in_start and not in_end:
            d_end = math.inf
        elif in_end and not in_start:
            d_start = math.inf
        type_geometry: RampType = "exit" if d_start <= d_end else "entry"
        tags = dict(osm_graph.edges[edges[0] if ramp_type == "exit" else edges[-1]])
        tags.pop("geometry", None)
        chain = RampChain(
            edges=tuple(edges),
            osm_way_ids=ways,
            attach_node=attach,
            mainline_edge=on_carriageway[attach],
            type=ramp_type,  # type: ignore[arg-type]
            type_geometry=type_geometry,
            xy=xy,
            tags=tags,
            side=ramp_side,  # type: ignore[arg-type]
        )
        chains.append((float(s_att[0]), chain))
    for cand in candidates:
        if (cand.u, cand.v, cand.key) not in covered:
            rejected.append((f"way {cand.osm_way_id}", "not attached to the driven carriageway"))
    chains += [
        (s_n, chain)
        for s_n, chain in _shared_branches(osm_graph, track, on_carriageway, cfg)
        if not set(chain.edges) & covered
    ]
    chains.sort(key=lambda c: (c[0], c[1].type))
    log.info(
        "ramp chains: %d from %d candidates (%d rejected)",
        len(chains),
        len(candidates),
        len(rejected),
    )
    return tuple(c for _, c in chains), tuple(rejected)
