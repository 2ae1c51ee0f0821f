"""Ramps from OpenStreetMap: candidates, lane count, merge/exit, geometry re-anchored on the
measured mainline.

The mapping car never drives the ramps; the OSM graph supplies them (paper, "Ramp
Reconstruction"). This module follows the paper's steps and adds what makes a ramp really
attach to the measured road (DESIGN.md section 4):

1. :func:`find_candidates` -- Algorithm 1: directed ``*_link`` edges within ``d_r`` of the
   trajectory.
2. :func:`extract_ramp_chains` -- consecutive link edges merged into one chain from the
   attachment on the driven carriageway up to ``max_ramp_length_m`` or the next OSM
   junction; links of the opposite carriageway and of unrelated roads are rejected by a
   direction check (heading at the attachment vs the driven direction) and a side check
   (the ramp lies on the traffic side of the trajectory). Merge/exit from directed
   connectivity (the paper's rule), cross-checked with geometry.
3. :func:`infer_lane_count` -- Algorithm 2 (``lanes:forward`` > ``lanes`` > ``turn:lanes``
   > highway class); the measured mainline lane-count change at the gore
   (:func:`gores_from_lane_events`, :func:`gore_events`) overrides it when present, and
   the measured gore decides the station where the ramp leaves or joins.
4. :func:`build_ramp_road` -- OSM polyline resampled at 0.5 m, Savitzky-Golay smoothed,
   offset by half the ramp width to its median-side boundary (the reference line), kept
   outside the measured carriageway, trimmed or extended to the gore, and re-anchored:
   its mainline end is moved exactly onto the inner border of the mainline lane it
   continues (the deceleration/acceleration lane: i.e. the outer border of the outermost
   through lane; without a measured gore the outermost lane, which the ramp splits off)
   with the mainline's heading, blended into the OSM shape over ``blend_length_m``, the
   attachment piece made an exact Hermite ParamPoly3; the rest fitted with
   :func:`roadtwin.fitting.fit_parampoly3_chain`.
5. :func:`fit_ramp_evidence` -- the road edges and lane markings the LiDAR measured past
   the gore (not explained by the mainline) are tracked outward from the gore and give
   the ramp's first part (a spline offset from the through lane's outer border, tangent
   at the gore) and its shoulder and lane widths; beyond the last measured point the
   fitted line blends into the OSM shape. No or too little evidence: OSM shape and the
   documented default widths (``RampConfig``).

Ramp cross-section = the mainline's layout: inner shoulder (opening from zero width at
the gore), driving lanes (the first ones starting with the widths of the mainline lanes
they continue, blending to the ramp's lane width), hard shoulder (continuing the
mainline's hard shoulder at a measured gore, else opening from zero width).

All coordinates are in the mapping frame (metres, radians CCW from +x). Lane layout
conventions (right-hand traffic; left-hand traffic mirrors): ramp reference line = the
ramp's left edge, ramp lanes ``-1`` (inner shoulder), ``-2 .. -(n+1)`` (driving),
``-(n+2)`` (hard shoulder) to its right.
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import networkx as nx
import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ._errors import FitError, InputError
from .config import RampConfig
from .fitting import (
    PolylineFrame,
    arc_length,
    fit_parampoly3_chain,
    resample_polyline,
    savgol_smooth,
)
from .model import (
    CubicPiece,
    CubicProfile,
    Lane,
    LaneSection,
    ParamPoly3,
    Road,
    RoadMark,
    chain_geometry,
)

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
RampType = Literal["exit", "entry"]
TrafficSide = Literal["right", "left"]
EdgeKey = tuple[Any, Any, int]

__all__ = [
    "GoreEvent",
    "Ramp",
    "RampCandidate",
    "RampChain",
    "RampEvidence",
    "RampSet",
    "build_ramp_road",
    "build_ramps",
    "extract_ramp_chains",
    "find_candidates",
    "fit_ramp_evidence",
    "gore_events",
    "gores_from_lane_events",
    "hermite_piece",
    "infer_lane_count",
]

_MIN_GORE_WIDTH_M = 1.0  # a lane ending/starting wider than this ends/starts at a gore
_MIN_BOUNDARY_POINTS = 20  # measured points on a road edge needed to measure its shoulder
_MIN_LINK_WIDTH_M = 0.05  # a lane narrower than this at a junction opens/closes there
_MIN_FIT_POINTS = 10  # points within the association gate needed to go on fitting
_EVIDENCE_LATERAL_M = 30.0  # measured points this far from the gore's base line count


# ---------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class RampCandidate:
    """One directed OSM link edge within ``d_r`` of the trajectory (Algorithm 1).

    ``u, v, key`` identify the edge in the OSM graph; ``distance_m`` is its smallest
    distance to the trajectory (metres).
    """

    u: Any
    v: Any
    key: int
    highway: str
    osm_way_id: Any
    distance_m: float


@dataclass(frozen=True)
class RampChain:
    """Consecutive OSM link edges forming one ramp, in driving order.

    Attributes
    ----------
    edges : ``(u, v, key)`` of each link edge, in driving order.
    osm_way_ids : OSM way ids of the edges (unique, in order).
    attach_node : OSM node where the chain meets the driven carriageway.
    mainline_edge : the OSM carriageway edge at ``attach_node`` (``E_m`` of the paper).
    type : ``"exit"`` or ``"entry"`` from directed connectivity (the paper's rule).
    type_geometry : the same decided from geometry (which end lies nearer the trajectory).
    xy : ``(N, 2)`` chain polyline in driving order, mapping frame, metres.
    tags : OSM tags of the link edge at the attachment.
    """

    edges: tuple[EdgeKey, ...]
    osm_way_ids: tuple[Any, ...]
    attach_node: Any
    mainline_edge: EdgeKey
    type: RampType
    type_geometry: RampType
    xy: FloatArray = field(repr=False, compare=False)
    tags: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass(frozen=True)
class GoreEvent:
    """A measured gore on the mainline: driving lanes ending (exit) or starting (entry)
    at full width at a lane-section boundary.

    Attributes
    ----------
    station_m : mainline station of the section boundary, metres.
    kind : ``"exit"`` (lanes end: deceleration lanes) or ``"entry"`` (lanes start:
        acceleration lanes).
    lane_ids : mainline lane ids of the ending/starting lanes, inner to outer (in the
        section before the gore for exits, after it for entries).
    through_lane_id : the outermost driving lane that continues through the gore.
    """

    station_m: float
    kind: RampType
    lane_ids: tuple[int, ...]
    through_lane_id: int


@dataclass(frozen=True)
class RampEvidence:
    """The measured points past a gore fitted to a ramp (:func:`fit_ramp_evidence`).

    Attributes
    ----------
    xy : ``(N, 2)`` corrected reference line (driving order, mapping frame, metres).
    widths : ``(inner shoulder, driving lane, hard shoulder)`` widths, metres (measured
        where the points saw the boundary, else the defaults given).
    points : measured points matched to a ramp boundary.
    counts : matched points per boundary ``(left edge, markings, right edge)``.
    span_m : extent along the ramp of the matched points (metres from the gore).
    max_shift_m : distance between the fitted line and the OSM shape where the blend
        into the OSM shape begins, metres.
    rmse_m : residual RMSE of the matched points against the fitted boundaries, metres.
    """

    xy: FloatArray = field(repr=False)
    widths: tuple[float, float, float]
    points: int
    counts: tuple[int, int, int]
    span_m: float
    max_shift_m: float
    rmse_m: float


@dataclass(frozen=True)
class Ramp:
    """One reconstructed ramp and every decision taken for it.

    Attributes
    ----------
    type : ``"exit"`` or ``"entry"``.
    road : the ramp road in driving direction (``name`` = type, a provisional id;
        topology assigns the final id). Its reference line starts (exit) or ends (entry)
        exactly on the inner border of ``mainline_lane_ids[0]`` at ``station_m``.
    station_m : mainline station of the attachment (gore), metres.
    lanes : ramp lane count.
    lane_rule : which rule decided ``lanes`` (``"lanes:forward"``, ``"lanes"``,
        ``"turn:lanes"``, ``"highway class"`` or ``"mainline lane change"``).
    osm_lanes, osm_lane_rule : Algorithm 2's result and rule on the OSM tags.
    station_source : ``"lidar gore"`` (a measured lane event decided the station) or
        ``"osm"`` (the OSM attachment node projected on the mainline).
    mainline_lane_ids : mainline lanes the ramp lanes link to, inner to outer (the
        deceleration/acceleration lanes at a measured gore; else the outermost driving
        lane, which the ramp then splits off). Driving lane ``k`` of the ramp (lane
        ``-(k+1)`` for right-hand traffic; ``-1`` is the inner shoulder) continues/feeds
        ``mainline_lane_ids[k - 1]``; further ramp driving lanes open from zero width.
    type_connectivity, type_geometry : the two merge/exit decisions.
    osm_way_ids : OSM ways of the chain.
    attach_gap_m, attach_heading_deg : position and heading mismatch of the fitted ramp
        end against the anchor on the mainline (metres, degrees).
    warnings : human-readable notes (disagreements, fallbacks).
    shoulder_lane_id : mainline hard shoulder the ramp's hard shoulder continues/feeds at
        a measured gore (``None``: it opens from zero width).
    evidence : the measured points past the gore fitted to the ramp (``None``: none or
        too few; OSM shape and default widths).
    """

    type: RampType
    road: Road = field(repr=False)
    station_m: float
    lanes: int
    lane_rule: str
    osm_lanes: int
    osm_lane_rule: str
    station_source: str
    mainline_lane_ids: tuple[int, ...]
    type_connectivity: RampType
    type_geometry: RampType
    osm_way_ids: tuple[Any, ...]
    attach_gap_m: float
    attach_heading_deg: float
    warnings: tuple[str, ...] = ()
    shoulder_lane_id: int | None = None
    evidence: RampEvidence | None = field(default=None, repr=False)


@dataclass(frozen=True)
class RampSet:
    """Result of :func:`build_ramps`.

    ``candidates`` are Algorithm 1's edges; ``rejected`` lists ``(what, reason)`` for
    candidate edges/chains not used; ``skipped`` lists ramps that could not be built;
    ``warnings`` collects every ramp's notes.
    """

    ramps: tuple[Ramp, ...]
    candidates: tuple[RampCandidate, ...]
    chains: tuple[RampChain, ...] = ()
    rejected: tuple[tuple[str, str], ...] = ()
    skipped: tuple[tuple[str, str], ...] = ()
    warnings: tuple[str, ...] = ()


# ---------------------------------------------------------------------------
# Algorithm 2: lane count from tags
# ---------------------------------------------------------------------------


def _first_value(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return value[0] if value else None
    return value


def _parse_int(value: Any) -> int | None:
    value = _first_value(value)
    if value is None:
        return None
    if isinstance(value, float) and not math.isfinite(value):
        return None
    try:
        n = int(str(value).split(";")[0].strip())
    except ValueError:
        return None
    return n if n > 0 else None


def infer_lane_count(tags: dict[str, Any]) -> tuple[int, str]:
    """Lane count of one OSM edge by the paper's Algorithm 2, and the rule that decided.

    Priority: ``lanes:forward`` > ``lanes`` > ``turn:lanes`` (number of ``|`` + 1) >
    highway class (``motorway*`` 3, ``trunk*``/``primary*`` 2, else 1).

    Parameters
    ----------
    tags
        OSM edge attributes (values may be strings, numbers or lists, as OSMnx gives them).

    Returns
    -------
    (lanes, rule)
        ``rule`` is one of ``"lanes:forward"``, ``"lanes"``, ``"turn:lanes"``,
        ``"highway class"``.
    """
    forward = _parse_int(tags.get("lanes:forward"))
    if forward is not None:
        return forward, "lanes:forward"
    lanes = _parse_int(tags.get("lanes"))
    if lanes is not None:
        return lanes, "lanes"
    turn = _first_value(tags.get("turn:lanes"))
    if isinstance(turn, str) and turn != "":
        return turn.count("|") + 1, "turn:lanes"
    highway = tags.get("highway", "")
    highway = " ".join(highway) if isinstance(highway, (list, tuple)) else str(highway)
    if "motorway" in highway:
        return 3, "highway class"
    if "trunk" in highway or "primary" in highway:
        return 2, "highway class"
    return 1, "highway class"


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


def _edge_xy(graph: nx.MultiDiGraph, u: Any, v: Any, key: int) -> FloatArray:
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
        xy = _edge_xy(osm_graph, u, v, k)
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


def _mainline_nodes(
    osm_graph: nx.MultiDiGraph, track: _Track, cfg: RampConfig
) -> dict[Any, EdgeKey]:
    """OSM nodes on the driven carriageway -> one aligned non-link edge at that node."""
    max_dh = math.radians(cfg.max_heading_diff_deg)
    node_ids = list(osm_graph.nodes)
    if not node_ids:
        return {}
    pts = np.array([[osm_graph.nodes[n]["x"], osm_graph.nodes[n]["y"]] for n in node_ids])
    s, t = track.project(pts)
    near = (np.abs(t) <= cfg.mainline_match_m) & (s >= -cfg.mainline_match_m)
    near &= s <= track.length + cfg.mainline_match_m
    near_nodes = {n: float(si) for n, si, ok in zip(node_ids, s, near, strict=False) if ok}
    out: dict[Any, EdgeKey] = {}
    for n, sn in near_nodes.items():
        h_track = float(track.heading(np.array([sn]))[0])
        edges = [(u, v, k, True) for u, v, k in osm_graph.out_edges(n, keys=True)]
        edges += [(u, v, k, False) for u, v, k in osm_graph.in_edges(n, keys=True)]
        for u, v, k, outgoing in sorted(edges, key=lambda e: (str(e[0]), str(e[1]), e[2])):
            data = osm_graph.edges[u, v, k]
            if _is_link(data):
                continue
            xy = _edge_xy(osm_graph, u, v, k)
            h = _end_heading(xy, at_start=outgoing)
            if abs(float(_wrap(h - h_track))) <= max_dh:
                out[n] = (u, v, k)
                break
    return out


def _follow(
    osm_graph: nx.MultiDiGraph,
    first: EdgeKey,
    *,
    forward: bool,
    stop_nodes: dict[Any, EdgeKey],
    max_length_m: float,
) -> list[EdgeKey]:
    """Link edges from ``first`` onward (or backward) until a junction, the carriageway or
    ``max_length_m``."""
    chain = [first]
    length = float(arc_length(_edge_xy(osm_graph, *first))[-1])
    seen = {first[0], first[1]}
    while length < max_length_m:
        node = chain[-1][1] if forward else chain[-1][0]
        if node in stop_nodes:
            break
        outs = [e for e in osm_graph.out_edges(node, keys=True) if _is_link(osm_graph.edges[e])]
        ins = [e for e in osm_graph.in_edges(node, keys=True) if _is_link(osm_graph.edges[e])]
        # a junction: any non-link road meets here, or the link forks/joins
        others = [
            e
            for e in (*osm_graph.out_edges(node, keys=True), *osm_graph.in_edges(node, keys=True))
            if not _is_link(osm_graph.edges[e])
        ]
        if others or len(outs) != 1 or len(ins) != 1:
            break
        nxt = outs[0] if forward else ins[0]
        far = nxt[1] if forward else nxt[0]
        if far in seen:
            break
        seen.add(far)
        chain.append(nxt)
        length += float(arc_length(_edge_xy(osm_graph, *nxt))[-1])
    return chain if forward else chain[::-1]


def _chain_xy(osm_graph: nx.MultiDiGraph, edges: list[EdgeKey]) -> FloatArray:
    parts = [_edge_xy(osm_graph, *e) for e in edges]
    xy = np.vstack([parts[0], *[p[1:] for p in parts[1:]]])
    keep = np.concatenate([[True], np.hypot(*np.diff(xy, axis=0).T) > 1e-6])
    return xy[keep]


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
    ``max_heading_diff_deg`` or when the ramp lies on the wrong side of the trajectory
    (left for right-hand traffic).

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
        )
        covered.update(edges)
        xy = _chain_xy(osm_graph, edges)
        ways = tuple(dict.fromkeys(_first_value(osm_graph.edges[x].get("osmid")) for x in edges))
        what = f"ways {', '.join(str(w) for w in ways)} ({ramp_type})"
        # direction check at the attachment
        node_xy = np.array([[osm_graph.nodes[attach]["x"], osm_graph.nodes[attach]["y"]]])
        s_att, _ = track.project(node_xy)
        h_track = float(track.heading(s_att)[0])
        h_ramp = _end_heading(xy, at_start=ramp_type == "exit")
        dh = abs(float(_wrap(h_ramp - h_track)))
        if dh > max_dh:
            rejected.append(
                (what, f"heading at the attachment {math.degrees(dh):.0f} deg off the drive")
            )
            continue
        # side check on the part away from the attachment
        s_pts, t_pts = track.project(xy)
        along = arc_length(xy)
        dist_from_attach = along if ramp_type == "exit" else along[-1] - along
        away = dist_from_attach > min(20.0, 0.5 * along[-1])
        t_away = t_pts[away] if np.any(away) else t_pts
        if float(np.median(t_away)) * side_sign <= 0.0:
            side = "left" if side_sign < 0 else "right"
            rejected.append((what, f"lies {side} of the drive (opposite carriageway side)"))
            continue
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
        )
        chains.append((float(s_att[0]), chain))
    for cand in candidates:
        if (cand.u, cand.v, cand.key) not in covered:
            rejected.append((f"way {cand.osm_way_id}", "not attached to the driven carriageway"))
    chains.sort(key=lambda c: (c[0], c[1].type))
    log.info(
        "ramp chains: %d from %d candidates (%d rejected)",
        len(chains),
        len(candidates),
        len(rejected),
    )
    return tuple(c for _, c in chains), tuple(rejected)


# ---------------------------------------------------------------------------
# measured gores
# ---------------------------------------------------------------------------


def _traffic_lanes(section: LaneSection, traffic_side: TrafficSide) -> tuple[Lane, ...]:
    return section.right if traffic_side == "right" else section.left


def _driving(lanes: tuple[Lane, ...]) -> list[Lane]:
    return [lane for lane in lanes if lane.type == "driving"]


def gore_events(road: Road, *, traffic_side: TrafficSide = "right") -> tuple[GoreEvent, ...]:
    """Gores the LiDAR saw: driving lanes that end or start at full width.

    Scans the mainline's lane sections (DESIGN.md lane layout: deceleration and
    acceleration lanes are the outermost driving lanes of their sections). Where the
    driving-lane count drops and the ending lanes are wider than 1 m at the boundary,
    lanes leave through an exit; where it rises with lanes starting wider than 1 m,
    lanes enter from a merge (the paper's lane-count-change rule). Tapers (width from or
    to zero) are not gores.
    """
    out: list[GoreEvent] = []
    sections = road.lane_sections
    for prev, nxt in itertools.pairwise(sections):
        dp = _driving(_traffic_lanes(prev, traffic_side))
        dn = _driving(_traffic_lanes(nxt, traffic_side))
        s_b = nxt.s0
        if len(dp) > len(dn) and dn:
            k = len(dp) - len(dn)
            ending = dp[-k:]
            widths = [float(lane.width.value(s_b - prev.s0)) for lane in ending]
            if min(widths) > _MIN_GORE_WIDTH_M:
                out.append(GoreEvent(s_b, "exit", tuple(x.id for x in ending), dp[-k - 1].id))
        elif len(dn) > len(dp) and dp:
            k = len(dn) - len(dp)
            starting = dn[-k:]
            widths = [float(lane.width.value(0.0)) for lane in starting]
            if min(widths) > _MIN_GORE_WIDTH_M:
                out.append(GoreEvent(s_b, "entry", tuple(x.id for x in starting), dn[-k - 1].id))
    return tuple(out)


def gores_from_lane_events(
    lane_events, road: Road, *, traffic_side: TrafficSide = "right", max_taper_m: float = 1.0
) -> tuple[GoreEvent, ...]:
    """Measured gores from the mainline stage's lane events.

    A lane that ends without a taper (``kind="end"``, ``taper_m`` below ``max_taper_m``)
    ends at an exit gore; one that is born without a taper starts at an entry gore.
    Events at the same station and kind are one gore with several lanes.

    Parameters
    ----------
    lane_events
        :class:`roadtwin.mainline.LaneEvent` records (``s_m``, ``kind``, ``lane_id``,
        ``taper_m``).
    road
        The mainline road they refer to.
    """
    groups: dict[tuple[float, str], list[int]] = {}
    for ev in lane_events:
        if ev.taper_m > max_taper_m:
            continue
        kind = "exit" if ev.kind == "end" else "entry"
        groups.setdefault((round(float(ev.s_m), 6), kind), []).append(int(ev.lane_id))
    out = []
    for (s, kind), ids in sorted(groups.items()):
        ids = sorted(ids, key=abs)
        s_sec = s - 1e-6 if kind == "exit" else s + 1e-6
        section = road.lane_sections[int(road.section_index(np.array([s_sec]))[0])]
        inner = [
            lane.id
            for lane in _driving(_traffic_lanes(section, traffic_side))
            if abs(lane.id) < abs(ids[0])
        ]
        if not inner:
            continue
        out.append(GoreEvent(s, kind, tuple(ids), inner[-1]))  # type: ignore[arg-type]
    return tuple(out)


def outer_driving_lane(road: Road, s: float, *, traffic_side: TrafficSide = "right") -> int:
    """Id of the outermost driving lane of the section containing station ``s``."""
    section = road.lane_sections[int(road.section_index(np.array([s]))[0])]
    driving = _driving(_traffic_lanes(section, traffic_side))
    if not driving:
        msg = f"mainline road {road.id}: no driving lane at s={s:.1f} m"
        raise FitError(msg)
    return driving[-1].id


def _outer_shoulder(
    road: Road,
    station: float,
    ramp_type: RampType,
    source_lane_ids: tuple[int, ...],
    traffic_side: TrafficSide,
) -> int | None:
    """The mainline hard shoulder just outside the gore's ending (exit) / starting (entry)
    lanes, or ``None``."""
    s = station - 1e-6 if ramp_type == "exit" else station + 1e-6
    section = road.lane_sections[int(road.section_index(np.array([s]))[0])]
    lanes_ = _traffic_lanes(section, traffic_side)
    ids = [lane.id for lane in lanes_]
    if not source_lane_ids or source_lane_ids[-1] not in ids:
        return None
    k = ids.index(source_lane_ids[-1])
    if k + 1 < len(lanes_) and lanes_[k + 1].type == "shoulder":
        lane_id = lanes_[k + 1].id
        s_arr = np.array([s])
        w = abs(
            float(road.lane_border_t(s_arr, lane_id)[0])
            - float(road.lane_border_t(s_arr, lane_id + (1 if lane_id < 0 else -1))[0])
        )
        # a shoulder of (near) zero width at the gore is opening/closing there: no link
        return lane_id if math.isfinite(w) and w > _MIN_LINK_WIDTH_M else None
    return None


def _outer_border_t(road: Road, s: FloatArray, traffic_side: TrafficSide) -> FloatArray:
    """Lateral offset of the outer border of the outermost driving lane at each station."""
    out = np.full(s.shape, np.nan)
    idx = road.section_index(s)
    for k in np.unique(idx):
        sel = idx == k
        driving = _driving(_traffic_lanes(road.lane_sections[int(k)], traffic_side))
        if driving:
            out[sel] = road.lane_border_t(s[sel], driving[-1].id)
    return out


# ---------------------------------------------------------------------------
# geometry
# ---------------------------------------------------------------------------


_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(16)


def hermite_piece(
    start: tuple[float, float, float], end: tuple[float, float, float], *, s0: float = 0.0
) -> ParamPoly3:
    """One ParamPoly3 (``pRange="normalized"``) from pose ``start`` to pose ``end``.

    Poses are ``(x, y, heading)`` (mapping frame, metres, radians). The cubic Hermite
    curve meets both exactly in position and heading; the tangent length is the chord;
    ``length`` is the true arc length (Gauss-Legendre).
    """
    x0, y0, h0 = start
    x1, y1, h1 = end
    c, s = math.cos(h0), math.sin(h0)
    dx, dy = x1 - x0, y1 - y0
    p1 = np.array([c * dx + s * dy, -s * dx + c * dy])
    dh = (h1 - h0 + math.pi) % (2 * math.pi) - math.pi
    chord = math.hypot(dx, dy)
    m0 = np.array([chord, 0.0])
    m1 = chord * np.array([math.cos(dh), math.sin(dh)])
    coef = np.stack([np.zeros(2), m0, 3.0 * p1 - 2.0 * m0 - m1, -2.0 * p1 + m0 + m1])
    length = 0.0
    for k in range(4):
        p = 0.125 * (2 * k + 1) + 0.125 * _GL_NODES
        d = coef[1] + p[:, None] * (2.0 * coef[2] + 3.0 * p[:, None] * coef[3])
        length += 0.125 * float(np.hypot(d[:, 0], d[:, 1]) @ _GL_WEIGHTS)
    return ParamPoly3(
        s0,
        float(x0),
        float(y0),
        float(h0),
        length,
        aU=0.0,
        bU=float(coef[1, 0]),
        cU=float(coef[2, 0]),
        dU=float(coef[3, 0]),
        aV=0.0,
        bV=float(coef[1, 1]),
        cV=float(coef[2, 1]),
        dV=float(coef[3, 1]),
        p_range="normalized",
    )


def _smootherstep(x: FloatArray) -> FloatArray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def _smooth_polyline(xy: FloatArray, cfg: RampConfig) -> FloatArray:
    dense = resample_polyline(xy, cfg.resample_step_m)
    window = max(5, round(cfg.savgol_window_m / cfg.resample_step_m))
    smooth = savgol_smooth(dense, window=window, polyorder=cfg.savgol_polyorder)
    return smooth


def _anchor_start(
    xy: FloatArray, target_xy: FloatArray, target_hdg: float, blend_m: float
) -> FloatArray:
    """Move the start of a dense polyline onto ``target_xy`` with heading ``target_hdg``,
    blending the correction out over ``blend_m`` (C2 smootherstep)."""
    sigma = arc_length(xy)
    frame = PolylineFrame.from_points(xy)
    u0 = frame.tangent[0]
    u_star = np.array([math.cos(target_hdg), math.sin(target_hdg)])
    delta = target_xy - xy[0]
    fade = 1.0 - _smootherstep(sigma / max(blend_m, 1e-6))
    out = xy + fade[:, None] * (delta[None, :] + sigma[:, None] * (u_star - u0)[None, :])
    out[0] = target_xy
    return out


def _mainline_boundary_distance(
    road: Road, pts: FloatArray, *, kind: str, traffic_side: TrafficSide
) -> FloatArray:
    """Distance (metres) of points to the nearest mainline boundary of ``kind``
    (``"edge"``: road edges; ``"lane"``: lane markings) at their station; ``inf`` off the
    road's ends."""
    s, t = road.project(pts)
    out = np.full(s.shape, np.inf)
    on = (s > 0.0) & (s < road.length)
    if not np.any(on):
        return out
    idx = road.section_index(np.clip(s, 0.0, road.length))
    for k in np.unique(idx[on]):
        sel = on & (idx == k)
        lanes_ = _traffic_lanes(road.lane_sections[int(k)], traffic_side)
        if not lanes_:
            continue
        ids = [lane.id for lane in lanes_]
        border_ids = [0, ids[-1]] if kind == "edge" else ids[:-1]
        best = np.full(int(sel.sum()), np.inf)
        for lane_id in border_ids:
            tb = road.lane_border_t(s[sel], lane_id)
            best = np.minimum(best, np.abs(t[sel] - tb))
        out[sel] = best
    return out


def _base_line(
    road: Road, station_m: float, through_lane_id: int, ramp_type: RampType, reach_m: float
) -> PolylineFrame | None:
    """The outer border of the through lane from the gore ``reach_m`` along the ramp's
    direction (exit: downstream, entry: upstream), in driving order, as a Frenet frame."""
    direction = 1.0 if ramp_type == "exit" else -1.0
    far = float(np.clip(station_m + direction * reach_m, 0.0, road.length))
    n = int(abs(far - station_m) / 0.5) + 1
    if n < 8:
        return None
    s = np.linspace(station_m, far, n)
    s = np.clip(s, 1e-6, road.length - 1e-6)
    t = road.lane_border_t(s, through_lane_id)
    if not np.all(np.isfinite(t)):
        return None
    xy = road.to_xy(s, t).reshape(-1, 2)
    return PolylineFrame.from_points(xy if ramp_type == "exit" else xy[::-1])


_KNOTS_U = np.arange(0.15, 0.95, 0.15)  # spline knots, in units of evidence_length_m
_N_SHAPE = 2 + _KNOTS_U.size  # shape parameters of e(a) before the three widths


def _shape_basis(u: FloatArray) -> FloatArray:
    """``(N, _N_SHAPE)`` cubic-spline basis with ``e(0) = e'(0) = 0``: ``u^2``, ``u^3``
    and truncated cubes ``(u - k)_+^3`` at the knots."""
    u = np.asarray(u, dtype=float)
    cols = [u * u, u**3, *(np.maximum(u - k, 0.0) ** 3 for k in _KNOTS_U)]
    return np.stack(cols, axis=-1)


def _shape_dbasis(u: FloatArray) -> FloatArray:
    u = np.asarray(u, dtype=float)
    cols = [2.0 * u, 3.0 * u * u, *(3.0 * np.maximum(u - k, 0.0) ** 2 for k in _KNOTS_U)]
    return np.stack(cols, axis=-1)


def _poly_e(p: FloatArray, u: FloatArray) -> FloatArray:
    return _shape_basis(u) @ p[:_N_SHAPE]


def _poly_de(p: FloatArray, u: FloatArray) -> FloatArray:
    return _shape_dbasis(u) @ p[:_N_SHAPE]


def _fit_boundaries(
    a_scale: float,
    a_p: FloatArray,
    g_in: FloatArray,
    tau: FloatArray,
    is_edge: NDArray[np.bool_],
    coef_b: FloatArray,
    edge_b: NDArray[np.bool_],
    prior: FloatArray,
    prior_val: FloatArray,
    windows: tuple[float, ...],
) -> tuple[FloatArray, NDArray[np.int64] | None, FloatArray, NDArray[np.bool_]]:
    """Track the ramp outward from the gore: IRLS (Huber, 0.1 m) of
    ``[c2, c3, c4, w_in, w, w_hs]`` on the points up to each window in turn, each point
    re-associated with the nearest boundary of its kind predicted by the previous fit.
    Returns ``(p, assoc, resid, used)``; ``assoc`` is ``None`` when the first window has
    fewer than ``_MIN_FIT_POINTS`` points within the gate."""
    p = prior_val.copy()
    u = a_p / a_scale
    assoc = np.zeros(u.size, dtype=np.int64)
    resid = np.full(u.size, np.inf)
    used = np.zeros(u.size, dtype=bool)
    good = None
    u_lim = np.inf  # beyond the last window the prediction continues linearly
    for k, window in enumerate(windows):
        sel = a_p <= window
        gates = (1.5, 1.0, 0.7, 0.5, 0.4) if k == 0 else (1.0, 0.7, 0.5, 0.4)
        p_try = p.copy()
        failed = False
        for g_i, gate in enumerate(gates):
            if g_i == 0 and np.isfinite(u_lim):
                ul = np.array([u_lim])
                e = np.where(
                    u <= u_lim,
                    _poly_e(p_try, u),
                    _poly_e(p_try, ul)[0] + _poly_de(p_try, ul)[0] * (u - u_lim),
                )
            else:
                e = _poly_e(p_try, u)
            pred = e[:, None] + g_in[:, None] * (coef_b[:, 0] * p_try[_N_SHAPE])[None, :]
            pred += (coef_b[:, 1:] @ p_try[_N_SHAPE + 1 :])[None, :]
            r_all = tau[:, None] - pred
            r_all[is_edge[:, None] != edge_b[None, :]] = np.inf
            a_k = np.argmin(np.abs(r_all), axis=1)
            r_k = r_all[np.arange(u.size), a_k]
            ok = sel & (np.abs(r_k) <= gate)
            if np.count_nonzero(ok) < _MIN_FIT_POINTS:
                failed = True
                break
            w = np.where(np.abs(r_k) <= 0.1, 1.0, 0.1 / np.maximum(np.abs(r_k), 1e-9))[ok]
            cb = coef_b[a_k[ok]]
            cb[:, 0] *= g_in[ok]
            uo = u[ok]
            design = np.column_stack([_shape_basis(uo), cb])
            sw = np.sqrt(w)
            a_mat = np.vstack([design * sw[:, None], np.diag(np.sqrt(prior))])
            b_vec = np.concatenate([tau[ok] * sw, np.sqrt(prior) * prior_val])
            p_try = np.linalg.lstsq(a_mat, b_vec, rcond=None)[0]
        if failed:
            break
        p, assoc, resid, used = p_try, a_k, r_k, sel
        good = True
        u_lim = window / a_scale
        if window >= float(a_p.max()):
            break
    if good is None:
        return p, None, resid, used
    return p, assoc, resid, used


def fit_ramp_evidence(
    ref_xy: FloatArray,
    mainline_road: Road,
    *,
    ramp_type: RampType,
    lanes: int,
    widths: tuple[float, float, float],
    station_m: float,
    through_lane_id: int,
    edge_xy: FloatArray | None,
    lane_xy: FloatArray | None,
    traffic_side: TrafficSide = "right",
    config: RampConfig | None = None,
) -> RampEvidence | None:
    """Fit a ramp's first part to the road edges and lane markings the car measured.

    Past an exit's gore (before an entry's) the LiDAR sees the ramp's diverging edges and
    markings within its lateral range. They are modelled in the Frenet frame of the base
    line -- the outer border of the through lane ``through_lane_id`` from the gore at
    ``station_m`` -- with ``a`` the distance from the gore and ``tau`` the lateral offset
    towards the ramp's lanes:

    ``tau = e(a) + b_k(a)``, ``e`` a cubic spline in ``u = a / evidence_length_m`` (knots
    every 0.15, ``e(0) = e'(0) = 0``: the ramp leaves the gore exactly, tangent to the
    mainline),

    with ``b_k`` the boundary offsets: road edges at ``0`` and ``g(a) w_in + n w + w_hs``,
    markings at ``g(a) w_in + j w`` (``j = 0..n``), ``g`` the inner shoulder's opening
    over ``shoulder_taper_m`` (as built). The ramp is tracked outward from the gore
    (windows of 30, 60, ... m; in each, Huber-weighted least squares with every point
    re-associated with the nearest boundary of its kind, gate shrinking to 0.4 m), so
    the fit does not depend on the OSM shape. Points within ``evidence_exclude_m`` of a
    mainline boundary of their kind are the mainline's and not used. A shoulder whose road
    edge fewer than 20 points saw keeps its default width (weak priors hold every width
    where nothing saw it). Beyond the last matched point (``A``) the fitted line,
    extrapolated linearly, blends into the OSM shape ``ref_xy`` over
    ``evidence_blend_m`` (smootherstep).

    Parameters
    ----------
    ref_xy
        ``(N, 2)`` dense provisional reference line (re-anchored OSM) in driving order,
        mapping frame, metres; exits start, entries end at the gore.
    mainline_road
        The measured mainline.
    widths
        Default ``(inner shoulder, lane, hard shoulder)`` widths, metres.
    station_m, through_lane_id
        Mainline station of the gore and the through lane whose outer border the ramp's
        reference line leaves from.
    edge_xy, lane_xy
        Measured road-edge points and lane samples, ``(N, 2+)`` mapping frame, metres.

    Returns
    -------
    RampEvidence or None
        ``None`` when too few points match (``evidence_min_points``,
        ``evidence_min_span_m``) or the fitted line ends implausibly far from the OSM
        shape (``evidence_max_shift_m`` where the blend begins) or crosses into the
        mainline.
    """
    cfg = config or RampConfig()
    ref = np.asarray(ref_xy, dtype=float)[:, :2]
    w_in0, w0, w_hs0 = (float(x) for x in widths)
    side = -1.0 if traffic_side == "right" else 1.0  # tau = side * t
    reach = cfg.evidence_length_m + cfg.evidence_blend_m
    base = _base_line(mainline_road, station_m, through_lane_id, ramp_type, reach)
    if base is None:
        return None
    a_base = base.s if ramp_type == "exit" else base.length - base.s
    near = a_base <= cfg.evidence_length_m
    if np.count_nonzero(near) < 2:
        return None
    lateral = _EVIDENCE_LATERAL_M
    kinds, pts_all = [], []
    probe = resample_polyline(base.xy[near], 2.0)
    for kind, pts in (("edge", edge_xy), ("lane", lane_xy)):
        if pts is None or len(pts) == 0:
            continue
        pts = np.asarray(pts, dtype=float)[:, :2]
        hits = cKDTree(pts).query_ball_point(probe, r=lateral)
        idx = np.unique(np.fromiter(itertools.chain.from_iterable(hits), dtype=np.int64))
        if idx.size == 0:
            continue
        sub = pts[idx]
        d_main = _mainline_boundary_distance(
            mainline_road, sub, kind=kind, traffic_side=traffic_side
        )
        sub = sub[d_main > cfg.evidence_exclude_m]
        pts_all.append(sub)
        kinds.append(np.full(sub.shape[0], kind == "edge"))
    if not pts_all:
        return None
    pts = np.vstack(pts_all)
    is_edge = np.concatenate(kinds)
    s_p, t_p = base.project(pts)
    a_p = s_p if ramp_type == "exit" else base.length - s_p
    tau = side * t_p
    keep = (s_p > 0.0) & (s_p < base.length) & (a_p > 0.0) & (a_p <= cfg.evidence_length_m)
    keep &= (tau > -3.0) & (tau < lateral)
    a_p, tau, is_edge = a_p[keep], tau[keep], is_edge[keep]
    if a_p.size < cfg.evidence_min_points:
        return None
    # the inner shoulder opens over shoulder_taper_m from the gore (as built, C1 cubic)
    xg = np.clip(a_p / max(cfg.shoulder_taper_m, 1e-6), 0.0, 1.0)
    g_in = xg * xg * (3.0 - 2.0 * xg)
    # boundary table: (is_edge, coef of w_in, coef of w, coef of w_hs, group)
    table = [(True, 0.0, 0.0, 0.0, 0)]
    table += [(False, 1.0, float(j), 0.0, 1) for j in range(lanes + 1)]
    table += [(True, 1.0, float(lanes), 1.0, 2)]
    coef_b = np.array([[c[1], c[2], c[3]] for c in table])
    edge_b = np.array([c[0] for c in table])
    group_b = np.array([c[4] for c in table])
    prior_val = np.array([0.0] * _N_SHAPE + [w_in0, w0, w_hs0])
    prior = np.array([1e-3] * _N_SHAPE + [3.0, 3.0, 3.0])  # pseudo-points of weight 1 each
    a_scale = cfg.evidence_length_m
    windows = tuple(
        float(w)
        for w in np.arange(30.0, cfg.evidence_length_m + 14.9, 15.0).clip(max=cfg.evidence_length_m)
    )
    for _ in range(2):
        p, assoc, resid, used = _fit_boundaries(
            a_scale, a_p, g_in, tau, is_edge, coef_b, edge_b, prior, prior_val, windows
        )
        if assoc is None:
            return None
        ok = used & (np.abs(resid) <= 0.4)
        counts = tuple(int(np.count_nonzero(ok & (group_b[assoc] == g))) for g in range(3))
        # an edge nobody saw cannot give its shoulder's width: hold the default
        weak = [
            k
            for k, c in ((_N_SHAPE, counts[0]), (_N_SHAPE + 2, counts[2]))
            if c < _MIN_BOUNDARY_POINTS
        ]
        if all(prior[k] > 1e5 for k in weak):
            break
        for k in weak:
            prior[k] = 1e6
    n_ok = int(np.count_nonzero(ok))
    if n_ok < cfg.evidence_min_points:
        return None
    span = float(np.max(a_p[ok]))
    if span < cfg.evidence_min_span_m:
        return None
    w_in = float(np.clip(p[_N_SHAPE], 0.3, 3.0))  # narrower is an edge line, not a shoulder
    w_lane = float(np.clip(p[_N_SHAPE + 1], 2.5, 5.0))
    w_hs = float(np.clip(p[_N_SHAPE + 2], 0.3, 4.0))
    # the fitted line up to the span, extrapolated linearly beyond it along the base line
    step = cfg.resample_step_m
    blend = cfg.evidence_blend_m
    a_max = float(a_base.max())
    a_f = np.arange(0.0, min(span + blend, a_max) + 1e-9, step)
    u_f = np.minimum(a_f, span) / a_scale
    e_f = _poly_e(p, u_f)
    e_span = float(_poly_e(p, np.array([span / a_scale]))[0])
    de_span = float(_poly_de(p, np.array([span / a_scale]))[0]) / a_scale
    e_f = np.where(a_f > span, e_span + de_span * (a_f - span), e_f)
    if float(np.min(e_f[a_f <= span])) < -1.0:
        log.warning("ramp evidence: fitted line crosses into the mainline; not used")
        return None
    s_f = a_f if ramp_type == "exit" else base.length - a_f
    xy_b, tg_b = base.at(s_f)
    normal = np.stack([-tg_b[:, 1], tg_b[:, 0]], axis=1)
    fit_xy = xy_b + (side * e_f)[:, None] * normal  # attachment-first order
    # the OSM shape, attachment-first, at the same distances from the gore
    osm = ref if ramp_type == "exit" else ref[::-1]
    a_osm = arc_length(osm)
    osm_at = np.stack([np.interp(a_f, a_osm, osm[:, j]) for j in range(2)], axis=1)
    join = a_f >= span
    gap = float(np.hypot(*(fit_xy[join][0] - osm_at[join][0]))) if np.any(join) else 0.0
    if gap > cfg.evidence_max_shift_m:
        log.warning("ramp evidence: fitted line ends %.1f m from the OSM shape; not used", gap)
        return None
    wgt = _smootherstep((a_f - span) / max(blend, 1e-6))[:, None]
    mixed = (1.0 - wgt) * fit_xy + wgt * osm_at
    rest = osm[a_osm > a_f[-1] + 0.5 * step]
    out = np.vstack([mixed, rest])
    out = out if ramp_type == "exit" else out[::-1]
    rmse = float(np.sqrt(np.mean(resid[ok] ** 2)))
    return RampEvidence(
        xy=out,
        widths=(w_in, w_lane, w_hs),
        points=n_ok,
        counts=counts,  # type: ignore[arg-type]
        span_m=span,
        max_shift_m=gap,
        rmse_m=rmse,
    )


def _build_ramp_road(
    chain_xy: FloatArray,
    mainline_road: Road,
    *,
    ramp_type: RampType,
    lanes: int,
    station_m: float,
    source_lane_ids: tuple[int, ...],
    traffic_side: TrafficSide = "right",
    road_id: str = "ramp",
    shoulder_lane_id: int | None = None,
    edge_xy: FloatArray | None = None,
    lane_xy: FloatArray | None = None,
    config: RampConfig | None = None,
) -> tuple[Road, float, float, RampEvidence | None]:
    """Ramp road from an OSM chain polyline, re-anchored on the measured mainline and
    corrected by the measured points past the gore.

    Parameters
    ----------
    chain_xy
        ``(N, 2)`` OSM polyline in driving order, mapping frame, metres.
    mainline_road
        The measured mainline (one road over the run).
    ramp_type
        ``"exit"`` (the ramp starts at the mainline) or ``"entry"`` (it ends there).
    lanes
        Ramp lane count (>= 1).
    station_m
        Mainline station of the attachment (gore), metres.
    source_lane_ids
        Mainline lanes the ramp lanes continue (exit) or feed (entry), inner to outer:
        the deceleration/acceleration lanes at a measured gore, else the outermost driving
        lane. The ramp's reference line meets the inner border of the first of them (at a
        gore: the outer border of the outermost through lane), and the first ramp lanes
        take their widths there, blending to ``lane_width_m`` over ``blend_length_m``;
        further ramp lanes open from zero width.
    traffic_side
        ``"right"``: reference line = ramp's left edge, lanes ``-1`` (inner shoulder),
        ``-2 .. -(n+1)`` (driving), ``-(n+2)`` (hard shoulder); ``"left"`` mirrored.
    shoulder_lane_id
        Mainline hard shoulder the ramp's hard shoulder continues (exit) or feeds (entry)
        at a measured gore; its width there is the ramp hard shoulder's start width.
        ``None``: the ramp's hard shoulder opens from zero width.
    edge_xy, lane_xy
        Measured road-edge points and lane samples (``(N, 2+)``, mapping frame, metres).
        Those past the gore on the ramp (:func:`fit_ramp_evidence`) shape the ramp's first
        part and give its shoulder and lane widths; ``None``: OSM and defaults decide.

    Returns
    -------
    (road, gap_m, heading_deg)
        The ramp road and the position / heading mismatch (metres, degrees) of its fitted
        attachment end against the anchor on the mainline.

    Raises
    ------
    FitError
        Too little of the ramp remains after trimming, or the fit fails.
    """
    cfg = config or RampConfig()
    lanes = max(1, int(lanes))
    width = cfg.lane_width_m
    left = 1.0 if traffic_side == "right" else -1.0  # reference line side of the centre
    outward = -left  # lateral direction away from the mainline's reference line
    pts = np.asarray(chain_xy, dtype=float)[:, :2]
    if ramp_type == "entry":
        pts = pts[::-1]  # work attachment-first
    dense = resample_polyline(pts, cfg.resample_step_m)
    keep = arc_length(dense) <= cfg.max_ramp_length_m
    dense = dense[keep]
    if dense.shape[0] < 4:
        msg = f"{road_id}: ramp polyline too short"
        raise FitError(msg)
    centre = _smooth_polyline(dense, cfg)
    # reference line: median-side boundary (offset towards the mainline side)
    frame = PolylineFrame.from_points(centre if ramp_type == "exit" else centre[::-1])
    # the OSM way runs along the middle of the driving lanes (an assumption: mappers draw
    # the carriageway's centre); the reference line is the inner road edge
    w_in = cfg.inner_shoulder_width_m
    ref = frame.offset_points(np.full(frame.s.shape, left * (w_in + 0.5 * lanes * width)))
    if ramp_type == "entry":
        ref = ref[::-1]

    # anchor on the mainline
    s_att = float(np.clip(station_m, 0.0, mainline_road.length))
    s_eval = np.array([s_att - 1e-6 if ramp_type == "exit" else s_att + 1e-6])
    src_widths = []
    for lane_id in source_lane_ids:
        outer = mainline_road.lane_border_t(s_eval, lane_id)[0]
        inner = mainline_road.lane_border_t(s_eval, lane_id + (1 if lane_id < 0 else -1))[0]
        src_widths.append(abs(float(outer - inner)))
        if not math.isfinite(src_widths[-1]):
            msg = f"{road_id}: mainline lane {lane_id} missing at s={s_att:.1f} m"
            raise FitError(msg)
    first_id = source_lane_ids[0]
    t_att = float(mainline_road.lane_border_t(s_eval, first_id + (1 if first_id < 0 else -1))[0])
    target = mainline_road.to_xy(np.array([s_att]), np.array([t_att]))[0]
    h_main = float(mainline_road.heading(np.array([s_att]))[0])
    direction = 1.0 if ramp_type == "exit" else -1.0  # attachment-first stations run ...

    s_i, t_i = mainline_road.project(ref)
    # trim to the gore: drop the part on the wrong side of the attachment station
    beyond = (s_i - s_att) * direction >= 0.0
    first = int(np.argmax(beyond)) if np.any(beyond) else len(s_i)
    ref, s_i, t_i = ref[first:], s_i[first:], t_i[first:]
    if ref.shape[0] < 4:
        msg = f"{road_id}: nothing of the OSM ramp lies beyond the gore at s={s_att:.1f} m"
        raise FitError(msg)
    # extend along the mainline edge if the gore lies before the OSM attachment
    gap_s = (s_i[0] - s_att) * direction
    if gap_s > cfg.resample_step_m:
        n = max(2, math.ceil(gap_s / cfg.resample_step_m))
        s_ext = s_att + direction * np.linspace(0.0, gap_s, n, endpoint=False)
        t_ext = _outer_border_t(mainline_road, s_ext, traffic_side)
        ref = np.vstack([mainline_road.to_xy(s_ext, t_ext), ref])
        s_i = np.concatenate([s_ext, s_i])
        t_i = np.concatenate([t_ext, t_i])
    # keep the ramp outside the measured carriageway until it has clearly left it
    t_edge = _outer_border_t(mainline_road, np.clip(s_i, 0.0, mainline_road.length), traffic_side)
    t_edge = np.where(np.isfinite(t_edge), t_edge, t_i)
    separation = (t_i - t_edge) * outward
    # points near the carriageway on the wrong side of the gore (a ramp folding back
    # across the mainline, or an offset curve folding) are dropped
    wrong = ((s_i - s_att) * direction < -1e-6) & (separation < 2.0 * lanes * width)
    if np.any(wrong):
        ref, s_i, t_i = ref[~wrong], s_i[~wrong], t_i[~wrong]
        t_edge, separation = t_edge[~wrong], separation[~wrong]
    if ref.shape[0] < 4:
        msg = f"{road_id}: nothing of the OSM ramp lies beyond the gore at s={s_att:.1f} m"
        raise FitError(msg)
    inside_road = (s_i > 0.0) & (s_i < mainline_road.length)
    clear = separation > lanes * width
    stop = int(np.argmax(clear)) if np.any(clear) else len(ref)
    clamp = inside_road & (np.arange(len(ref)) < stop) & (separation < 0.0)
    if np.any(clamp):
        ref = ref.copy()
        ref[clamp] = mainline_road.to_xy(s_i[clamp], t_edge[clamp])
    ref = _smooth_polyline(ref, cfg)
    length = float(arc_length(ref)[-1])
    if length < cfg.min_ramp_length_m:
        msg = f"{road_id}: only {length:.1f} m of ramp remain after trimming"
        raise FitError(msg)
    hdg = h_main if ramp_type == "exit" else h_main + math.pi
    ref = _anchor_start(ref, target, hdg, min(cfg.blend_length_m, 0.6 * length))
    if ramp_type == "entry":
        ref = ref[::-1]
    w_hs = cfg.hard_shoulder_width_m
    fit = None
    if edge_xy is not None or lane_xy is not None:
        fit = fit_ramp_evidence(
            ref,
            mainline_road,
            ramp_type=ramp_type,
            lanes=lanes,
            widths=(w_in, width, w_hs),
            station_m=s_att,
            through_lane_id=first_id + (1 if first_id < 0 else -1),
            edge_xy=edge_xy,
            lane_xy=lane_xy,
            traffic_side=traffic_side,
            config=cfg,
        )
        if fit is not None:
            ref = fit.xy
            w_in, width, w_hs = fit.widths
            log.info(
                "%s: %d measured points past the gore (max correction %.2f m, residual "
                "RMSE %.3f m); widths %.2f / %.2f / %.2f m",
                road_id,
                fit.points,
                fit.max_shift_m,
                fit.rmse_m,
                w_in,
                width,
                w_hs,
            )
    w_hs_src = 0.0
    if shoulder_lane_id is not None:
        inner_id = shoulder_lane_id + (1 if shoulder_lane_id < 0 else -1)
        w = abs(
            float(mainline_road.lane_border_t(s_eval, shoulder_lane_id)[0])
            - float(mainline_road.lane_border_t(s_eval, inner_id)[0])
        )
        w_hs_src = w if math.isfinite(w) else 0.0
    pieces = list(fit_parampoly3_chain(ref, tolerance_m=cfg.fit_tolerance_m))
    # the attachment piece again as an exact Hermite piece: anchor pose to its far pose
    anchor = (float(target[0]), float(target[1]), h_main)
    if ramp_type == "exit":
        pieces[0] = hermite_piece(anchor, pieces[0].end_pose())
    else:
        last = pieces[-1]
        pieces[-1] = hermite_piece((last.x0, last.y0, last.hdg), anchor)
    geometry = chain_geometry(pieces)

    road = Road(
        id=road_id,
        geometry=geometry,
        lane_sections=(
            _ramp_section(
                lanes,
                width,
                ramp_type,
                traffic_side,
                cfg,
                source_widths=tuple(src_widths),
                road_length=float(sum(g.length for g in geometry)),
                inner_shoulder_m=w_in,
                hard_shoulder_m=w_hs,
                hard_shoulder_source_m=w_hs_src,
            ),
        ),
        name=ramp_type,
        elevation=CubicProfile.constant(float(mainline_road.height(np.array([s_att]))[0])),
    )
    s_end = 0.0 if ramp_type == "exit" else road.length
    x, y, h, _ = road.evaluate(np.array([s_end]))
    gap = float(math.hypot(float(x[0]) - target[0], float(y[0]) - target[1]))
    dh = abs(float(_wrap(float(h[0]) - h_main)))
    return road, gap, math.degrees(dh), fit


def build_ramp_road(*args: Any, **kwargs: Any) -> tuple[Road, float, float]:
    road, gap, dh, _ = _build_ramp_road(*args, **kwargs)
    return road, gap, dh


build_ramp_road.__doc__ = _build_ramp_road.__doc__


def width_transition(
    w_from: float, w_to: float, length_m: float, *, s0: float = 0.0
) -> tuple[CubicPiece, CubicPiece]:
    """Two cubic pieces: a C1 transition from ``w_from`` (at ``s0``) to ``w_to`` (at
    ``s0 + length_m``), then constant ``w_to`` (metres)."""
    dw = w_to - w_from
    length = max(length_m, 1e-6)
    return (
        CubicPiece(s0, w_from, 0.0, 3.0 * dw / length**2, -2.0 * dw / length**3),
        CubicPiece(s0 + length, w_to),
    )


def _ramp_width(
    w_src: float, width: float, ramp_type: RampType, blend_m: float, road_length: float
) -> CubicProfile:
    if abs(w_src - width) < 1e-9:
        return CubicProfile.constant(width)
    if ramp_type == "exit":
        return CubicProfile(width_transition(w_src, width, blend_m))
    start = road_length - blend_m
    first, second = width_transition(width, w_src, blend_m, s0=start)
    return CubicProfile((CubicPiece(0.0, width), first, replace(second, s0=road_length)))


def _opening(w_to: float, ramp_type: RampType, taper_m: float, road_length: float) -> CubicProfile:
    """Width opening from zero at the gore (exit: road start; entry: closing to zero at
    the road end) over ``taper_m`` (metres)."""
    return _ramp_width(0.0, w_to, ramp_type, taper_m, road_length)


def _ramp_section(
    lanes: int,
    width: float,
    ramp_type: RampType,
    traffic_side: TrafficSide,
    cfg: RampConfig,
    *,
    source_widths: tuple[float, ...] = (),
    road_length: float = 0.0,
    inner_shoulder_m: float | None = None,
    hard_shoulder_m: float | None = None,
    hard_shoulder_source_m: float = 0.0,
) -> LaneSection:
    """The ramp's cross-section, the mainline's layout (DESIGN.md conventions): inner
    shoulder (opening from zero width at the gore), ``lanes`` driving lanes (the first
    ones starting with ``source_widths``, the others from zero), hard shoulder (starting
    with ``hard_shoulder_source_m``, the width of the mainline hard shoulder it
    continues, or zero)."""
    sign = -1 if traffic_side == "right" else 1
    lane_type = "driving"
    if cfg.lane_type == "spec":
        lane_type = "offRamp" if ramp_type == "exit" else "onRamp"
    blend = min(cfg.blend_length_m, 0.5 * road_length) if road_length > 0 else cfg.blend_length_m
    taper = min(cfg.shoulder_taper_m, 0.5 * road_length) if road_length > 0 else blend
    w_in = cfg.inner_shoulder_width_m if inner_shoulder_m is None else inner_shoulder_m
    w_hs = cfg.hard_shoulder_width_m if hard_shoulder_m is None else hard_shoulder_m
    out = [
        Lane(
            sign * 1,
            "shoulder",
            _opening(w_in, ramp_type, taper, road_length),
            (RoadMark(0.0, "solid"),),
        )
    ]
    for k in range(1, lanes + 1):
        mark = "solid" if k == lanes else "broken"
        w_src = source_widths[k - 1] if k <= len(source_widths) else 0.0
        out.append(
            Lane(
                sign * (k + 1),
                lane_type,  # type: ignore[arg-type]
                _ramp_width(w_src, width, ramp_type, blend, road_length),
                (RoadMark(0.0, mark),),  # type: ignore[arg-type]
            )
        )
    out.append(
        Lane(
            sign * (lanes + 2),
            "shoulder",
            _ramp_width(hard_shoulder_source_m, w_hs, ramp_type, blend, road_length),
            (RoadMark(0.0, "none"),),
        )
    )
    center = Lane(0, "none", road_marks=(RoadMark(0.0, "none"),))
    if traffic_side == "right":
        return LaneSection(0.0, center=center, right=tuple(out))
    return LaneSection(0.0, left=tuple(out), center=center)


# ---------------------------------------------------------------------------
# the stage
# ---------------------------------------------------------------------------


def _match_gores(
    chains: tuple[RampChain, ...],
    stations: list[float],
    events: tuple[GoreEvent, ...],
    cfg: RampConfig,
) -> dict[int, GoreEvent]:
    """Greedy one-to-one matching of chains to measured gores of their type."""
    pairs = []
    for i, (chain, s_osm) in enumerate(zip(chains, stations, strict=False)):
        for j, ev in enumerate(events):
            if ev.kind != chain.type:
                continue
            d = ev.station_m - s_osm
            if chain.type == "entry":
                d = -d
            if -cfg.gore_search_upstream_m <= d <= cfg.gore_search_downstream_m:
                pairs.append((abs(d), i, j))
    out: dict[int, GoreEvent] = {}
    used: set[int] = set()
    for _, i, j in sorted(pairs):
        if i in out or j in used:
            continue
        out[i] = events[j]
        used.add(j)
    return out


def build_ramps(
    osm_graph: nx.MultiDiGraph,
    mainline_road: Road,
    *,
    trajectory_xy: FloatArray,
    traffic_side: TrafficSide = "right",
    gores: tuple[GoreEvent, ...] | None = None,
    edge_xy: FloatArray | None = None,
    lane_xy: FloatArray | None = None,
    config: RampConfig | None = None,
) -> RampSet:
    """The ramp stage: OSM graph + measured mainline -> ramp roads with their decisions.

    Parameters
    ----------
    osm_graph
        OSM graph in the mapping frame (``roadtwin.osm.load_osm``).
    mainline_road
        The measured mainline (one road over the run, driving direction).
    trajectory_xy
        ``(N, 2)`` vehicle positions, mapping frame, metres.
    traffic_side
        ``"right"`` or ``"left"``.
    gores
        Measured gores (:func:`gores_from_lane_events` on the mainline stage's lane
        events); ``None`` scans the road's lane sections (:func:`gore_events`); ``()``
        uses none (OSM decides every station).
    edge_xy, lane_xy
        The run's measured road-edge points and lane samples (``(N, 2+)``, mapping frame,
        metres): those past each gore shape the ramp's first part and give its widths
        (:func:`fit_ramp_evidence`). ``None``: OSM shape and default widths.
    config
        Ramp settings.

    Returns
    -------
    RampSet
        Ramps sorted by station. A ramp that cannot be built is listed in ``skipped``
        with its reason (and a warning), never raised.
    """
    cfg = config or RampConfig()
    if not cfg.use_evidence:
        edge_xy = lane_xy = None
    candidates = find_candidates(osm_graph, trajectory_xy, config=cfg)
    chains, rejected = extract_ramp_chains(
        osm_graph, trajectory_xy, traffic_side=traffic_side, candidates=candidates, config=cfg
    )
    events = gore_events(mainline_road, traffic_side=traffic_side) if gores is None else gores
    stations = []
    for chain in chains:
        node = osm_graph.nodes[chain.attach_node]
        s, _ = mainline_road.project(np.array([[node["x"], node["y"]]]))
        stations.append(float(s[0]))
    matched = _match_gores(chains, stations, events, cfg)
    # KD-trees of the measured points, built once; each ramp gets the points near its gore
    measured = {}
    for key, pts in (("edge", edge_xy), ("lane", lane_xy)):
        if pts is not None and len(pts):
            xy = np.asarray(pts, dtype=float)[:, :2]
            measured[key] = (xy, cKDTree(xy))

    def near_gore(key: str, station: float) -> FloatArray | None:
        if key not in measured:
            return None
        xy, tree = measured[key]
        s_c = float(np.clip(station, 0.0, mainline_road.length))
        centre = mainline_road.to_xy(np.array([s_c]), np.array([0.0])).reshape(2)
        idx = tree.query_ball_point(centre, r=cfg.evidence_length_m + 2.0 * _EVIDENCE_LATERAL_M)
        return xy[np.sort(np.asarray(idx, dtype=np.int64))]

    ramps: list[Ramp] = []
    skipped: list[tuple[str, str]] = []
    warnings: list[str] = []
    for i, (chain, s_osm) in enumerate(zip(chains, stations, strict=False)):
        what = f"{chain.type} ways {', '.join(str(w) for w in chain.osm_way_ids)}"
        notes: list[str] = []
        osm_lanes, osm_rule = infer_lane_count(chain.tags)
        if osm_rule == "highway class":
            notes.append(f"{what}: no lane tags, lane count {osm_lanes} from the highway class")
        if chain.type != chain.type_geometry:
            notes.append(
                f"{what}: connectivity says {chain.type}, geometry says {chain.type_geometry}"
                f" (kept {chain.type})"
            )
        event = matched.get(i)
        if event is not None:
            station, source = event.station_m, "lidar gore"
            lanes, rule = max(1, len(event.lane_ids)), "mainline lane change"
            mainline_lanes = event.lane_ids
            if lanes != osm_lanes:
                notes.append(
                    f"{what}: OSM says {osm_lanes} lane(s) ({osm_rule}), the mainline lane "
                    f"change says {lanes}; using {lanes}"
                )
        else:
            station, source = s_osm, "osm"
            bounds = np.array([sec.s0 for sec in mainline_road.lane_sections[1:]])
            if bounds.size:
                near = bounds[np.argmin(np.abs(bounds - station))]
                if abs(near - station) <= cfg.snap_to_section_m:
                    station = float(near)
            if not cfg.min_ramp_length_m < station < mainline_road.length - 1.0:
                reason = f"attachment at s={station:.0f} m is outside the measured mainline"
                skipped.append((what, reason))
                warnings.append(f"skipped {what}: {reason}")
                continue
            lanes, rule = max(1, osm_lanes), osm_rule
            s_src = station - 1e-6 if chain.type == "exit" else station + 1e-6
            try:
                through = outer_driving_lane(mainline_road, s_src, traffic_side=traffic_side)
            except FitError as exc:
                skipped.append((what, str(exc)))
                warnings.append(f"skipped {what}: {exc}")
                continue
            mainline_lanes = (through,)
        shoulder = None
        if source == "lidar gore":
            shoulder = _outer_shoulder(
                mainline_road, station, chain.type, mainline_lanes, traffic_side
            )
        try:
            road, gap, dh, evidence = _build_ramp_road(
                chain.xy,
                mainline_road,
                ramp_type=chain.type,
                lanes=lanes,
                station_m=station,
                source_lane_ids=tuple(mainline_lanes),
                traffic_side=traffic_side,
                road_id=f"ramp{i}",
                shoulder_lane_id=shoulder,
                edge_xy=near_gore("edge", station),
                lane_xy=near_gore("lane", station),
                config=cfg,
            )
        except (FitError, ValueError) as exc:
            skipped.append((what, str(exc)))
            warnings.append(f"skipped {what}: {exc}")
            log.warning("skipped %s: %s", what, exc)
            continue
        warnings.extend(notes)
        ramps.append(
            Ramp(
                type=chain.type,
                road=road,
                station_m=station,
                lanes=lanes,
                lane_rule=rule,
                osm_lanes=osm_lanes,
                osm_lane_rule=osm_rule,
                station_source=source,
                mainline_lane_ids=tuple(mainline_lanes),
                type_connectivity=chain.type,
                type_geometry=chain.type_geometry,
                osm_way_ids=chain.osm_way_ids,
                attach_gap_m=gap,
                attach_heading_deg=dh,
                warnings=tuple(notes),
                shoulder_lane_id=shoulder,
                evidence=evidence,
            )
        )
    ramps.sort(key=lambda r: (r.station_m, r.type))
    log.info(
        "ramps: %d built (%d exit, %d entry), %d skipped, %d candidates",
        len(ramps),
        sum(r.type == "exit" for r in ramps),
        sum(r.type == "entry" for r in ramps),
        len(skipped),
        len(candidates),
    )
    return RampSet(
        ramps=tuple(ramps),
        candidates=candidates,
        chains=chains,
        rejected=rejected,
        skipped=tuple(skipped),
        warnings=tuple(warnings),
    )
