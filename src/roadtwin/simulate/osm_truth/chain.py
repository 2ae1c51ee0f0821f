"""The OSM side: motorway/trunk ways of an extract and the carriageway chain to simulate.

A *chain* is a sequence of one-way ``motorway`` (or ``trunk``) ways, each starting where
the previous one ends: one carriageway in its driving direction. It is chosen by way id,
by ``ref`` (and direction), or as the longest chain of the extract; at every node where
the carriageway splits it continues on the way with the same ``ref`` and the smallest
turn, so the choice is deterministic. Coordinates stay WGS84 here; :func:`chain_in_frame`
projects a chain into a mapping frame.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..._errors import InputError
from ...fitting import arc_length
from ...frames import MappingFrame, Origin
from ...osm import _read_highway_ways
from .settings import ChainSelection

CARRIAGEWAY = frozenset({"motorway", "trunk"})
# every link class: a ramp between a motorway and a secondary road is often tagged with
# the lower road's class (Krems: a secondary_link exit off the B37 trunk)
LINKS = frozenset(
    {"motorway_link", "trunk_link", "primary_link", "secondary_link", "tertiary_link"}
)
EXTRA_TAGS = ("layer", "bridge", "tunnel", "destination")
_COMPASS = {
    "N": 0.0,
    "NE": 45.0,
    "E": 90.0,
    "SE": 135.0,
    "S": 180.0,
    "SW": 225.0,
    "W": 270.0,
    "NW": 315.0,
}


@dataclass(frozen=True)
class OsmWay:
    """One one-way OSM way in its driving direction: node ids and ``(N, 2)`` lon/lat."""

    id: int
    tags: dict[str, str]
    nodes: tuple[int, ...]
    lonlat: NDArray[np.float64]

    @property
    def highway(self) -> str:
        return self.tags.get("highway", "")

    @property
    def refs(self) -> frozenset[str]:
        """The ``ref`` values (``"A 9;E 51"`` -> two), spaces removed, upper case."""
        raw = self.tags.get("ref", "")
        return frozenset(r.replace(" ", "").upper() for r in raw.split(";") if r.strip())

    def lanes(self, defaults: dict[str, int]) -> int:
        """Lanes in the driving direction: ``lanes`` (``lanes:forward`` on a two-way way),
        else the class default."""
        for key in ("lanes:forward", "lanes") if "lanes:forward" in self.tags else ("lanes",):
            try:
                n = int(float(self.tags[key].split(";")[0]))
            except (KeyError, ValueError):
                continue
            if n > 0:
                return n
        return defaults.get(self.highway, 1)


@dataclass(frozen=True)
class OsmRoads:
    """The one-way motorway/trunk (and link) ways of an extract, indexed by end nodes."""

    ways: dict[int, OsmWay]
    starting: dict[int, tuple[int, ...]]  # node id -> ids of ways starting there
    ending: dict[int, tuple[int, ...]]  # node id -> ids of ways ending there
    node_lonlat: dict[int, tuple[float, float]]
    source: str


def _oneway(tags: dict[str, str]) -> int:
    """+1 one-way as drawn, -1 one-way against the drawing, 0 two-way."""
    v = tags.get("oneway", "")
    if v in ("yes", "true", "1"):
        return 1
    if v == "-1":
        return -1
    return 0


def resolve_selection(sel: ChainSelection, chain: int | str | None) -> ChainSelection:
    """``sel`` with the ``chain`` shortcut applied: an OSM way id (int) or a ``ref``
    (str); None keeps ``sel``."""
    if isinstance(chain, int):
        return replace(sel, way_id=chain, ref=None)
    if isinstance(chain, str):
        return replace(sel, ref=chain, way_id=None)
    return sel


def read_osm_roads(path: str | Path) -> OsmRoads:
    """Every one-way ``motorway``, ``trunk`` and ``*_link`` way of an OSM extract.

    ``motorway`` and ``motorway_link`` without ``oneway`` are one-way (OSM's convention,
    as :func:`roadtwin.osm.load_osm`); ``oneway=-1`` ways are reversed; two-way ways are
    left out (they are not one carriageway).
    """
    path = Path(path)
    if not path.is_file():
        msg = f"{path}: OSM file not found"
        raise InputError(msg)
    raw = _read_highway_ways(path, extra_tags=EXTRA_TAGS)
    starts = np.searchsorted(raw.way_index, np.arange(len(raw.ids) + 1))
    ways: dict[int, OsmWay] = {}
    node_lonlat: dict[int, tuple[float, float]] = {}
    for i, wid in enumerate(raw.ids):
        tags = raw.tags[i]
        if tags.get("highway") not in CARRIAGEWAY | LINKS:
            continue
        direction = _oneway(tags)
        if direction == 0:
            continue
        sl = slice(starts[i], starts[i + 1])
        nodes = raw.ref[sl]
        ll = np.column_stack([raw.lon[sl], raw.lat[sl]])
        if direction < 0:
            nodes, ll = nodes[::-1], ll[::-1]
        ways[wid] = OsmWay(wid, tags, tuple(int(n) for n in nodes), ll.copy())
        for n, (lo, la) in zip(nodes.tolist(), ll.tolist(), strict=True):
            node_lonlat[n] = (lo, la)
    starting: dict[int, list[int]] = defaultdict(list)
    ending: dict[int, list[int]] = defaultdict(list)
    for wid in sorted(ways):
        w = ways[wid]
        starting[w.nodes[0]].append(wid)
        ending[w.nodes[-1]].append(wid)
    if not any(w.highway in CARRIAGEWAY for w in ways.values()):
        msg = f"{path}: no one-way motorway or trunk way in the extract"
        raise InputError(msg)
    return OsmRoads(
        ways,
        {k: tuple(v) for k, v in starting.items()},
        {k: tuple(v) for k, v in ending.items()},
        node_lonlat,
        str(path),
    )


# ---------------------------------------------------------------------------
# geometry on the sphere (lengths and bearings; metres, degrees)
# ---------------------------------------------------------------------------

_EARTH_R = 6_371_000.0


def _local_xy(lonlat: NDArray, lat0: float) -> NDArray:
    """Equirectangular metres around latitude ``lat0`` (lengths and angles only)."""
    k = math.pi / 180.0 * _EARTH_R
    return np.column_stack([lonlat[:, 0] * k * math.cos(math.radians(lat0)), lonlat[:, 1] * k])


def _way_length(w: OsmWay) -> float:
    xy = _local_xy(w.lonlat, float(w.lonlat[0, 1]))
    return float(np.hypot(*np.diff(xy, axis=0).T).sum())


def _end_heading(w: OsmWay, *, at_end: bool) -> float:
    """Heading (radians, CCW from east) of the way's first or last ~30 m."""
    xy = _local_xy(w.lonlat, float(w.lonlat[0, 1]))
    if at_end:
        xy = xy[::-1]
    d = np.hypot(*(xy - xy[0]).T)
    j = int(np.searchsorted(d, 30.0))
    j = min(max(j, 1), len(xy) - 1)
    v = xy[j] - xy[0]
    h = math.atan2(v[1], v[0])
    return h + math.pi if at_end else h


def _turn(a: float, b: float) -> float:
    return abs((b - a + math.pi) % (2 * math.pi) - math.pi)


# ---------------------------------------------------------------------------
# chains
# ---------------------------------------------------------------------------


def _continuation(
    roads: OsmRoads, way: OsmWay, used: set[int], *, forward: bool, refs: frozenset[str] | None
) -> int | None:
    """The carriageway way continuing ``way`` forward (or backward), or None."""
    node = way.nodes[-1] if forward else way.nodes[0]
    pool = roads.starting.get(node, ()) if forward else roads.ending.get(node, ())
    h = _end_heading(way, at_end=forward)
    best: tuple[float, int] | None = None
    want = refs if refs is not None else way.refs
    for wid in pool:
        cand = roads.ways[wid]
        if wid in used or cand.highway not in CARRIAGEWAY:
            continue
        if refs is not None and not (cand.refs & refs):
            continue
        turn = _turn(h, _end_heading(cand, at_end=not forward))
        if turn > math.radians(60.0):
            continue
        score = turn + (0.0 if (cand.refs & want or not want) else 1.0)
        if best is None or (score, wid) < best:
            best = (score, wid)
    return None if best is None else best[1]


def grow_chain(roads: OsmRoads, seed: int, *, refs: frozenset[str] | None = None) -> list[int]:
    """Way ids of the carriageway through ``seed``, in driving order."""
    chain = [seed]
    used = {seed}
    while (
        nxt := _continuation(roads, roads.ways[chain[-1]], used, forward=True, refs=refs)
    ) is not None:
        chain.append(nxt)
        used.add(nxt)
    while (
        prv := _continuation(roads, roads.ways[chain[0]], used, forward=False, refs=refs)
    ) is not None:
        chain.insert(0, prv)
        used.add(prv)
    return chain


def _chain_length(roads: OsmRoads, chain: list[int]) -> float:
    return sum(_way_length(roads.ways[w]) for w in chain)


def _bearing_deg(roads: OsmRoads, chain: list[int]) -> float:
    a = roads.ways[chain[0]].lonlat[0]
    b = roads.ways[chain[-1]].lonlat[-1]
    xy = _local_xy(np.array([a, b]), float(a[1]))
    v = xy[1] - xy[0]
    return math.degrees(math.atan2(v[0], v[1])) % 360.0


def all_chains(roads: OsmRoads, *, refs: frozenset[str] | None = None) -> list[list[int]]:
    """Every distinct maximal chain (optionally only of ways carrying one of ``refs``),
    longest first (ties: smallest first way id)."""
    seen: set[frozenset[int]] = set()
    out: list[list[int]] = []
    for wid in sorted(roads.ways):
        w = roads.ways[wid]
        if w.highway not in CARRIAGEWAY or (refs is not None and not (w.refs & refs)):
            continue
        if any(wid in s for s in seen):
            continue
        chain = grow_chain(roads, wid, refs=refs)
        key = frozenset(chain)
        if key not in seen:
            seen.add(key)
            out.append(chain)
    out.sort(key=lambda c: (-_chain_length(roads, c), c[0]))
    return out


def select_chain(roads: OsmRoads, selection: ChainSelection) -> list[int]:
    """Way ids of the chosen carriageway (see :class:`ChainSelection`)."""
    if selection.way_id is not None:
        if selection.way_id not in roads.ways:
            msg = f"{roads.source}: way {selection.way_id} is not a one-way motorway/trunk way"
            raise InputError(msg)
        if roads.ways[selection.way_id].highway not in CARRIAGEWAY:
            msg = f"{roads.source}: way {selection.way_id} is a link, not a carriageway"
            raise InputError(msg)
        return grow_chain(roads, selection.way_id)
    refs = None
    if selection.ref is not None:
        refs = frozenset(r.replace(" ", "").upper() for r in selection.ref.split(";"))
    chains = all_chains(roads, refs=refs)
    if not chains:
        msg = f"{roads.source}: no one-way motorway/trunk chain with ref {selection.ref!r}"
        raise InputError(msg)
    if selection.direction is None:
        return chains[0]
    d = selection.direction
    want = _COMPASS.get(str(d).upper()) if isinstance(d, str) else float(d)
    if want is None:
        msg = f"direction must be a bearing in degrees or one of {', '.join(_COMPASS)}, got {d!r}"
        raise InputError(msg)
    long_enough = [c for c in chains if _chain_length(roads, c) >= selection.min_length_m]
    pool = long_enough or chains

    def off(c: list[int]) -> float:
        return abs((_bearing_deg(roads, c) - want + 180.0) % 360.0 - 180.0)

    return min(pool, key=lambda c: (round(off(c) / 45.0), -_chain_length(roads, c), c[0]))


@dataclass(frozen=True)
class Chain:
    """A carriageway chain cut to its window, in a mapping frame.

    ``xy`` ``(N, 2)`` metres, ``s`` stations along the OSM polyline (0 at the window
    start), ``node_ids`` the OSM node of each vertex (-1 for the interpolated window
    ends), ``seg_way`` the way id of each of the ``N - 1`` segments.
    """

    way_ids: tuple[int, ...]
    node_ids: NDArray[np.int64]
    xy: NDArray[np.float64]
    s: NDArray[np.float64]
    seg_way: NDArray[np.int64]
    frame: MappingFrame
    osm_start_m: float  # station of the window start along the whole chain

    @property
    def length(self) -> float:
        return float(self.s[-1])


def chain_polyline(roads: OsmRoads, chain: list[int]) -> tuple[NDArray, NDArray, NDArray]:
    """Node ids ``(N,)``, lon/lat ``(N, 2)`` and segment way ids ``(N-1,)`` of a chain."""
    nodes: list[int] = []
    ll: list[NDArray] = []
    seg: list[int] = []
    for k, wid in enumerate(chain):
        w = roads.ways[wid]
        skip = 0 if k == 0 else 1
        nodes.extend(w.nodes[skip:])
        ll.append(w.lonlat[skip:])
        seg.extend([wid] * (len(w.nodes) - 1))
    return np.array(nodes, np.int64), np.vstack(ll), np.array(seg, np.int64)


def window_chain(
    roads: OsmRoads, chain: list[int], selection: ChainSelection, origin: Origin | None
) -> Chain:
    """Cut the chain to its window and project it into the ``local`` frame of ``origin``
    (default: the window's first point, rounded to 1e-6 degrees, altitude 0)."""
    nodes, ll, seg = chain_polyline(roads, chain)
    lat0 = float(ll[0, 1])
    xy0 = _local_xy(ll, lat0)
    s_all = arc_length(xy0)
    total = float(s_all[-1])
    a = min(selection.start_m, max(total - selection.min_length_m, 0.0))
    length = selection.length_m if selection.length_m is not None else total - a
    b = min(a + min(length, selection.max_length_m), total)
    if b - a < selection.min_length_m:
        msg = (
            f"{roads.source}: the chosen chain is {total:.0f} m long; the window "
            f"[{a:.0f}, {b:.0f}] m is shorter than min_length_m={selection.min_length_m:.0f} m"
        )
        raise InputError(msg)
    inside = np.flatnonzero((s_all > a + 1e-6) & (s_all < b - 1e-6))
    lon_a, lat_a = (np.interp(a, s_all, ll[:, k]) for k in range(2))
    lon_b, lat_b = (np.interp(b, s_all, ll[:, k]) for k in range(2))
    w_ll = np.vstack([[lon_a, lat_a], ll[inside], [lon_b, lat_b]])
    w_nodes = np.concatenate([[-1], nodes[inside], [-1]])
    # an end that falls on a node keeps its id
    for end, at in ((0, a), (-1, b)):
        hit = np.flatnonzero(np.abs(s_all - at) <= 1e-6)
        if hit.size:
            w_nodes[end] = nodes[hit[0]]
    seg_idx = np.clip(
        np.searchsorted(s_all, np.concatenate([[a], s_all[inside]]), "right") - 1, 0, len(seg) - 1
    )
    if origin is None:
        origin = Origin(round(float(w_ll[0, 1]), 6), round(float(w_ll[0, 0]), 6), 0.0)
    frame = MappingFrame(origin, "local")
    x, y = frame.from_lonlat(w_ll[:, 0], w_ll[:, 1])
    xy = np.column_stack([x, y])
    s = arc_length(xy)
    used = tuple(dict.fromkeys(int(w) for w in seg[seg_idx]))
    return Chain(used, w_nodes, xy, s, seg[seg_idx], frame, a)
