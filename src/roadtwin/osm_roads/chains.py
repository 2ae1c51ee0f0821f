"""Carriageways of the OSM graph: one-way motorway/trunk edges chained in driving order.

OSM draws a dual carriageway as two one-way ways, one per direction, along the middle of
each carriageway's driving lanes. A *carriageway* here is a maximal chain of such edges
of the projected OSMnx graph (:func:`roadtwin.osm.load_osm`), each starting where the
previous one ends: at every node the chain continues on the carriageway edge with the
smallest turn (at most 60 deg; the same ``ref`` first), so the choice is deterministic.
Links (``*_link``) are ramps, not carriageways.

All coordinates are in the mapping frame (metres); stations are metres along the chain.
OSM data: (c) OpenStreetMap contributors, ODbL.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import networkx as nx
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from ..fitting import arc_length, resample_polyline
from ..ramps import infer_lane_count
from ..ramps.candidates import chain_xy, edge_xy

FloatArray = NDArray[np.float64]
EdgeKey = tuple[Any, Any, int]

CARRIAGEWAY_HIGHWAYS = frozenset({"motorway", "trunk"})
"""``highway`` values of carriageways (their ``*_link`` ways are ramps)."""

_MAX_TURN_RAD = math.radians(60.0)
_END_HEADING_M = 30.0  # the heading of an edge end is taken over this length


def end_heading(xy: FloatArray, *, at_end: bool) -> float:
    """Heading (radians, CCW from +x) of a polyline's first or last ~30 m, in its own
    direction."""
    pts = xy[::-1] if at_end else xy
    d = np.hypot(*(pts - pts[0]).T)
    j = min(max(int(np.searchsorted(d, _END_HEADING_M)), 1), len(pts) - 1)
    v = pts[j] - pts[0]
    h = math.atan2(v[1], v[0])
    return h + math.pi if at_end else h


def turn_rad(a: float, b: float) -> float:
    """Absolute heading change (radians, 0..pi) from ``a`` to ``b``."""
    return abs((b - a + math.pi) % (2.0 * math.pi) - math.pi)


def maxspeed_mps(value: Any) -> float | None:
    """An OSM ``maxspeed`` value in metres per second (km/h unless it says ``mph``);
    None for ``none``, ``signals``, country codes (``DE:motorway``) and unreadable
    values."""
    if isinstance(value, (list, tuple)):
        value = value[0] if value else None
    if value is None:
        return None
    text = str(value).split(";")[0].strip().lower()
    factor = 1.0 / 3.6
    if text.endswith("mph"):
        text, factor = text[:-3].strip(), 0.44704
    elif text.endswith("km/h"):
        text = text[:-4].strip()
    try:
        speed = float(text)
    except ValueError:
        return None
    return speed * factor if speed > 0 and math.isfinite(speed) else None


def directional_lanes(data: dict[str, Any]) -> int:
    """Lanes in the direction of an edge: ``lanes:forward`` / ``lanes:backward`` of a
    two-way way (by the edge's ``reversed`` flag), half of its ``lanes``, or
    Algorithm 2 (:func:`roadtwin.ramps.infer_lane_count`) for one-way ways."""
    if data.get("oneway") is False:
        key = "lanes:backward" if data.get("reversed") else "lanes:forward"
        n, _ = infer_lane_count({"lanes": data.get(key)})
        if data.get(key) is not None:
            return n
        total, rule = infer_lane_count({"lanes": data.get("lanes")})
        return max(1, total // 2) if rule == "lanes" else 1
    n, _ = infer_lane_count(data)
    return n


@dataclass(frozen=True)
class OsmCarriageway:
    """One carriageway of the OSM graph in driving order.

    Attributes
    ----------
    edges : ``(u, v, key)`` of its edges in driving order.
    xy : ``(N, 2)`` polyline (mapping frame, metres).
    s : ``(N,)`` stations of the vertices (metres).
    edge_s : ``(E + 1,)`` station where each edge starts, and the chain's length.
    tags : per edge its OSM attributes (``highway``, ``lanes``, ``ref``, ``name``,
        ``maxspeed``, ``osmid``, ...).
    """

    edges: tuple[EdgeKey, ...]
    xy: FloatArray = field(repr=False)
    s: FloatArray = field(repr=False)
    edge_s: FloatArray = field(repr=False)
    tags: tuple[dict[str, Any], ...] = field(repr=False)

    @property
    def length(self) -> float:
        return float(self.s[-1])

    @property
    def way_ids(self) -> tuple[int, ...]:
        """OSM way ids, in order, each once."""
        out: dict[int, None] = {}
        for t in self.tags:
            w = t.get("osmid")
            if isinstance(w, (list, tuple)):
                w = w[0]
            if w is not None:
                out[int(w)] = None
        return tuple(out)

    def edge_index(self, s: ArrayLike) -> NDArray[np.int64]:
        """Index of the edge at each station."""
        idx = np.searchsorted(self.edge_s, np.asarray(s, dtype=float), side="right") - 1
        return np.clip(idx, 0, len(self.edges) - 1)

    def lanes_at(self, s: ArrayLike) -> NDArray[np.int64]:
        """Lane count (Algorithm 2 on each edge's tags) at stations ``s``."""
        counts = np.array([infer_lane_count(t)[0] for t in self.tags], dtype=np.int64)
        return counts[self.edge_index(s)]

    def tag(self, key: str) -> str | None:
        """The most common value of ``key`` over the chain's length (None if untagged)."""
        lengths: dict[str, float] = {}
        for t, a, b in zip(self.tags, self.edge_s[:-1], self.edge_s[1:], strict=True):
            v = t.get(key)
            if isinstance(v, (list, tuple)):
                v = v[0] if v else None
            if v is not None:
                lengths[str(v)] = lengths.get(str(v), 0.0) + float(b - a)
        return max(sorted(lengths), key=lambda k: lengths[k]) if lengths else None

    def crop(self, s0: float, s1: float) -> OsmCarriageway:
        """The part between stations ``s0`` and ``s1`` (metres), stations from 0 again."""
        s0, s1 = max(0.0, s0), min(self.length, s1)
        inside = (self.s > s0) & (self.s < s1)
        ends = [np.interp(v, self.s, self.xy[:, k]) for v in (s0, s1) for k in range(2)]
        xy = np.vstack([ends[:2], self.xy[inside], ends[2:]])
        s = np.concatenate([[s0], self.s[inside], [s1]]) - s0
        keep = [
            i for i in range(len(self.edges)) if self.edge_s[i + 1] > s0 and self.edge_s[i] < s1
        ]
        edge_s = (
            np.clip(np.concatenate([self.edge_s[keep], [self.edge_s[keep[-1] + 1]]]), s0, s1) - s0
        )
        return OsmCarriageway(
            tuple(self.edges[i] for i in keep), xy, s, edge_s, tuple(self.tags[i] for i in keep)
        )

    def inside(self, box: tuple[float, float, float, float]) -> OsmCarriageway | None:
        """The longest part inside ``box = (xmin, ymin, xmax, ymax)`` (mapping frame,
        metres), or None."""
        grid = np.arange(0.0, self.length, 2.0)
        pts = np.column_stack([np.interp(grid, self.s, self.xy[:, k]) for k in range(2)])
        ok = (
            (pts[:, 0] >= box[0]) & (pts[:, 0] <= box[2]) & (pts[:, 1] >= box[1])
            & (pts[:, 1] <= box[3])
        )  # fmt: skip
        idx = np.flatnonzero(ok)
        if idx.size < 2:
            return None
        breaks = np.flatnonzero(np.diff(idx) > 1)
        starts = np.concatenate([[idx[0]], idx[breaks + 1]])
        stops = np.concatenate([idx[breaks], [idx[-1]]])
        k = int(np.argmax(stops - starts))
        if ok.all():
            return self
        return self.crop(float(grid[starts[k]]), float(grid[stops[k]]))

    def heading_at(self, s: ArrayLike) -> FloatArray:
        """Heading (radians) of the polyline segment at stations ``s``."""
        d = np.diff(self.xy, axis=0)
        h = np.arctan2(d[:, 1], d[:, 0])
        idx = np.searchsorted(self.s, np.asarray(s, float), side="right") - 1
        return h[np.clip(idx, 0, h.size - 1)]


def _carriageway_edges(graph: nx.MultiDiGraph) -> list[EdgeKey]:
    out = []
    for u, v, k, d in graph.edges(keys=True, data=True):
        hw = d.get("highway")
        if isinstance(hw, (list, tuple)):
            hw = hw[0]
        if hw in CARRIAGEWAY_HIGHWAYS and d.get("oneway") is True:
            out.append((u, v, k))
    return sorted(out, key=lambda e: (str(e[0]), str(e[1]), e[2]))


def _refs(data: dict[str, Any]) -> frozenset[str]:
    raw = data.get("ref") or ""
    if isinstance(raw, (list, tuple)):
        raw = ";".join(str(r) for r in raw)
    return frozenset(r.replace(" ", "").upper() for r in str(raw).split(";") if r.strip())


def carriageway_chains(
    graph: nx.MultiDiGraph, *, min_length_m: float = 0.0
) -> list[OsmCarriageway]:
    """Every carriageway chain of the graph, longest first (ties: first edge).

    Each carriageway edge belongs to one chain; a chain continues at a node on the edge
    with the smallest turn (at most 60 deg; an edge sharing the ``ref`` first).
    """
    edges = _carriageway_edges(graph)
    if not edges:
        return []
    xy = {e: edge_xy(graph, *e) for e in edges}
    out_of: dict[Any, list[EdgeKey]] = {}
    into: dict[Any, list[EdgeKey]] = {}
    for e in edges:
        out_of.setdefault(e[0], []).append(e)
        into.setdefault(e[1], []).append(e)

    def best(e: EdgeKey, pool: list[EdgeKey], forward: bool, used: set) -> EdgeKey | None:
        h = end_heading(xy[e], at_end=forward)
        refs = _refs(graph.edges[e])
        ranked = []
        for c in pool:
            if c in used or c == e:
                continue
            turn = turn_rad(h, end_heading(xy[c], at_end=not forward))
            if turn > _MAX_TURN_RAD:
                continue
            same = bool(refs & _refs(graph.edges[c])) or not refs
            ranked.append((0 if same else 1, turn, str(c[0]), str(c[1]), c[2], c))
        return min(ranked)[-1] if ranked else None

    used: set[EdgeKey] = set()
    chains: list[list[EdgeKey]] = []
    for seed in edges:
        if seed in used:
            continue
        chain = [seed]
        used.add(seed)
        while (nxt := best(chain[-1], out_of.get(chain[-1][1], []), True, used)) is not None:
            chain.append(nxt)
            used.add(nxt)
        while (prv := best(chain[0], into.get(chain[0][0], []), False, used)) is not None:
            chain.insert(0, prv)
            used.add(prv)
        chains.append(chain)
    out = []
    for chain in chains:
        pts = chain_xy(graph, chain)
        lengths = [float(np.hypot(*np.diff(xy[e], axis=0).T).sum()) for e in chain]
        s = arc_length(pts)
        if s[-1] < min_length_m or pts.shape[0] < 2:
            continue
        edge_s = np.concatenate([[0.0], np.cumsum(lengths)])
        edge_s *= s[-1] / edge_s[-1]
        tags = tuple(
            {k: v for k, v in graph.edges[e].items() if k not in ("geometry",)} for e in chain
        )
        out.append(OsmCarriageway(tuple(chain), pts, s, edge_s, tags))
    out.sort(key=lambda c: (-c.length, str(c.edges[0])))
    return out


def _is_link(data: dict[str, Any]) -> bool:
    hw = data.get("highway")
    if isinstance(hw, (list, tuple)):
        hw = hw[0]
    return isinstance(hw, str) and hw.endswith("_link")


def link_attachments(graph: nx.MultiDiGraph, chain: OsmCarriageway) -> list[tuple[float, str, int]]:
    """Where OSM ramps meet a carriageway: ``(chain station, "exit" | "entry", lanes)``
    for every ``*_link`` edge leaving (exit) or arriving at (entry) one of its nodes."""
    nodes = [e[0] for e in chain.edges] + [chain.edges[-1][1]]
    out = []
    for k, node in enumerate(nodes):
        s = float(chain.edge_s[k])
        for _, _, d in graph.out_edges(node, data=True):
            if _is_link(d):
                out.append((s, "exit", infer_lane_count(d)[0]))
        for _, _, d in graph.in_edges(node, data=True):
            if _is_link(d):
                out.append((s, "entry", infer_lane_count(d)[0]))
    return out


def shared_length_m(
    xy: ArrayLike,
    other_xy: ArrayLike,
    *,
    distance_m: float,
    opposite: bool,
    step_m: float = 5.0,
) -> float:
    """Metres of the polyline ``xy`` that run within ``distance_m`` of the polyline
    ``other_xy`` the same way (or, with ``opposite``, the other way), headings within
    45 deg; points abreast of ``other_xy``'s ends do not count."""
    a = np.asarray(xy, dtype=float)[:, :2]
    b = np.asarray(other_xy, dtype=float)[:, :2]
    if a.shape[0] < 2 or b.shape[0] < 2:
        return 0.0
    pts = resample_polyline(a, step_m)
    d_a = np.gradient(pts, axis=0)
    h_a = np.arctan2(d_a[:, 1], d_a[:, 0])
    d_b = np.gradient(b, axis=0)
    h_b = np.arctan2(d_b[:, 1], d_b[:, 0])
    dist, idx = cKDTree(b).query(pts)
    turn = np.abs((h_a - h_b[idx] + np.pi) % (2 * np.pi) - np.pi)
    aligned = turn > 0.75 * np.pi if opposite else turn < 0.25 * np.pi
    inside = (idx > 0) & (idx < b.shape[0] - 1)
    return float(np.count_nonzero((dist < distance_m) & aligned & inside)) * step_m
