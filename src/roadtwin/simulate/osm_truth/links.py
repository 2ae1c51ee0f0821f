"""Ramps of a chain as OSM draws them: link ways leaving or joining the carriageway.

An *exit* is a link way (or, with ``include_motorway_branches``, another motorway/trunk
way) whose first node is a node of the chain; an *entry* one whose last node is. Each is
followed away from the chain over further link ways (the smallest turn at every fork)
up to ``RampShape.max_length_m``. Its side is where it goes relative to the driving
direction: ``outer`` (right in right-hand traffic, left in left-hand) or ``inner`` (the
median side).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ...fitting import arc_length
from ..route_truth import LeftOutRamp
from .chain import CARRIAGEWAY, LINKS, Chain, OsmRoads, _end_heading, _turn
from .settings import CrossSection, RampShape


@dataclass(frozen=True)
class OsmRamp:
    """One ramp of the chain as drawn in OSM.

    ``xy`` ``(M, 2)`` is the OSM polyline in the mapping frame in driving order (an exit
    starts at the gore node, an entry ends there); ``station_m`` is the gore node's station
    along the OSM chain; ``lanes`` the lane count of the way at the gore.
    """

    kind: Literal["exit", "entry"]
    gore_node: int
    station_m: float
    way_ids: tuple[int, ...]
    lanes: int
    highway: str
    side: Literal["outer", "inner"]
    xy: NDArray[np.float64]
    layer: int = 0


def _follow(
    roads: OsmRoads, first: int, *, forward: bool, chain_nodes: set[int], max_length_m: float
) -> list[int]:
    """Way ids from ``first`` away from the chain, in the order they are followed."""
    out = [first]
    length = 0.0
    cls = LINKS | CARRIAGEWAY
    while True:
        w = roads.ways[out[-1]]
        ll = w.lonlat
        lat = math.radians(float(ll[0, 1]))
        d = np.diff(ll, axis=0) * np.array([math.cos(lat), 1.0]) * (math.pi / 180 * 6_371_000.0)
        length += float(np.hypot(*d.T).sum())
        node = w.nodes[-1] if forward else w.nodes[0]
        if length >= max_length_m or node in chain_nodes:
            return out
        pool = roads.starting.get(node, ()) if forward else roads.ending.get(node, ())
        h = _end_heading(w, at_end=forward)
        best: tuple[float, int] | None = None
        for wid in pool:
            if wid in out or roads.ways[wid].highway not in cls:
                continue
            turn = _turn(h, _end_heading(roads.ways[wid], at_end=not forward))
            if turn < math.radians(75.0) and (best is None or (turn, wid) < best):
                best = (turn, wid)
        if best is None:
            return out
        out.append(best[1])


def _side(chain: Chain, k: int, xy: NDArray, *, exit_: bool, traffic: str) -> str:
    """``outer`` or ``inner`` from the ramp's lateral offsets 15-120 m from the gore."""
    g = chain.xy[k]
    j0, j1 = max(k - 1, 0), min(k + 1, len(chain.xy) - 1)
    tangent = chain.xy[j1] - chain.xy[j0]
    tangent = tangent / np.linalg.norm(tangent)
    pts = xy if exit_ else xy[::-1]
    d = arc_length(pts)
    sel = (d >= 15.0) & (d <= 120.0)
    if not sel.any():
        sel = d > 0
    v = pts[sel] - g
    left = tangent[0] * v[:, 1] - tangent[1] * v[:, 0]
    is_left = float(np.sum(left * np.abs(left))) > 0
    outer_is_left = traffic == "left"
    return "outer" if is_left == outer_is_left else "inner"


def _cap(xy: NDArray, length_m: float, *, from_start: bool) -> NDArray:
    """The first (or last) ``length_m`` of a polyline."""
    pts = xy if from_start else xy[::-1]
    d = arc_length(pts)
    if d[-1] > length_m:
        k = int(np.searchsorted(d, length_m))
        f = (length_m - d[k - 1]) / max(d[k] - d[k - 1], 1e-9)
        end = pts[k - 1] + f * (pts[k] - pts[k - 1])
        pts = np.vstack([pts[:k], end])
    return pts if from_start else pts[::-1]


def _point(xy: NDArray[np.float64]) -> tuple[float, float]:
    return (float(xy[0]), float(xy[1]))


def _layer(tags: dict[str, str]) -> int:
    try:
        return int(float(tags.get("layer", "0")))
    except ValueError:
        return 0


def find_ramps(
    roads: OsmRoads,
    chain: Chain,
    *,
    shape: RampShape,
    cross_section: CrossSection,
    traffic: str,
) -> tuple[list[OsmRamp], list[LeftOutRamp]]:
    """Ramps along the chain's window, sorted by station, and the links left out (too
    close to the window's ends, too short; placed at their chain node, OSM as drawn)."""
    chain_ways = set(chain.way_ids)
    index = {int(n): k for k, n in enumerate(chain.node_ids) if n >= 0}
    chain_nodes = set(index)
    ramps: list[OsmRamp] = []
    skipped: list[LeftOutRamp] = []
    allowed = LINKS | (CARRIAGEWAY if shape.include_motorway_branches else frozenset())
    for wid in sorted(roads.ways):
        w = roads.ways[wid]
        if wid in chain_ways or w.highway not in allowed:
            continue
        for kind, node in (("exit", w.nodes[0]), ("entry", w.nodes[-1])):
            k = index.get(node)
            if k is None:
                continue
            what = f"{kind} way {wid} at {chain.s[k]:.0f} m"
            if not shape.end_margin_m <= chain.s[k] <= chain.length - shape.end_margin_m:
                why = "gore too close to the end of the chain window"
                skipped.append(LeftOutRamp(kind, what, why, _point(chain.xy[k])))
                continue
            ids = _follow(
                roads,
                wid,
                forward=kind == "exit",
                chain_nodes=chain_nodes,
                max_length_m=shape.max_length_m,
            )
            ll = [roads.ways[i].lonlat for i in ids]
            if kind == "exit":
                pts = np.vstack([ll[0]] + [x[1:] for x in ll[1:]])
            else:
                pts = np.vstack([x[:-1] for x in reversed(ll[1:])] + [ll[0]])
            x, y = chain.frame.from_lonlat(pts[:, 0], pts[:, 1])
            xy = _cap(np.column_stack([x, y]), shape.max_length_m, from_start=kind == "exit")
            length = float(np.hypot(*np.diff(xy, axis=0).T).sum())
            if length < shape.min_length_m:
                why = f"link only {length:.0f} m long"
                skipped.append(LeftOutRamp(kind, what, why, _point(chain.xy[k])))
                continue
            ramps.append(
                OsmRamp(
                    kind,  # type: ignore[arg-type]
                    int(node),
                    float(chain.s[k]),
                    tuple(ids),
                    w.lanes(cross_section.default_lanes),
                    w.highway,
                    _side(chain, k, xy, exit_=kind == "exit", traffic=traffic),  # type: ignore[arg-type]
                    xy,
                    max((_layer(roads.ways[i].tags) for i in ids), key=abs, default=0),
                )
            )
    ramps.sort(key=lambda r: (r.station_m, r.kind, r.way_ids))
    return ramps, skipped


def tagged_lanes(roads: OsmRoads, chain: Chain, defaults: dict[str, int]) -> NDArray[np.int64]:
    """Lane count of every chain segment from its way's tags ``(N - 1,)``."""
    per_way = {w: roads.ways[w].lanes(defaults) for w in chain.way_ids}
    return np.array([per_way[int(w)] for w in chain.seg_way], np.int64)
