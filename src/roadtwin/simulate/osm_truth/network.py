"""Assembly: lane sections from the layouts, roads cut at the junctions, links by key.

A road covers ``[a, b]`` of a *source* (the mainline or one ramp: a reference line, an
elevation profile and a :class:`~.layout.Layout`). Its lane sections are the layout's
sections clipped to ``[a, b]``; lane widths (and the lane offset, where inner-side lane
events move the median edge) are fitted from the layout's width functions, so a lane that
continues across a section or road boundary has the same width on both sides. Lane ids
are ``sign * 1, 2, ...`` inner to outer (``sign = -1`` right-hand traffic). Two lanes are
linked where they carry the same strip key and both have width at the joint (no link at
a zero-width end).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from ...fitting import fit_cubic_profile
from ...mainline import cut_road
from ...model import CubicPiece, CubicProfile, Lane, LaneSection, Road, RoadMark
from ...topology import true_lengths
from ..alignment import cut_profile
from ..route import side_lanes
from ..scenario import Markings
from .layout import Layout, Strip

ZERO_WIDTH_M = 1e-3
"""A lane end narrower than this is a zero-width end: never linked."""


@dataclass(frozen=True)
class Source:
    """A reference line with its heights and lanes (stations 0..length)."""

    road: Road  # geometry only
    elevation: CubicProfile
    layout: Layout


@dataclass
class BuiltRoad:
    """A model road plus the strip key of every lane: ``keys[section][lane_id]``."""

    road: Road
    keys: list[dict[int, str]]

    def end_lanes(self, at_end: bool) -> dict[str, tuple[int, float]]:
        """key -> (lane id, width at that end) of the first/last section."""
        k = len(self.road.lane_sections) - 1 if at_end else 0
        sec = self.road.lane_sections[k]
        length = (self.road.length - sec.s0) if at_end else 0.0
        out = {}
        for lane in (*sec.left, *sec.right):
            w = float(lane.width.value(np.array([length]))[0])
            out[self.keys[k][lane.id]] = (lane.id, w)
        return out


def _marks(strips: list[Strip], markings: Markings) -> list[RoadMark]:
    """Paint on the outer border of each lane (inner to outer), from its neighbours."""
    out = []
    for i, x in enumerate(strips):
        nxt = strips[i + 1] if i + 1 < len(strips) else None
        if x.kind == "hard" or (x.kind == "inner" and nxt is None):
            out.append(RoadMark(0.0, "none", 0.0))
        elif nxt is None or nxt.kind in ("hard", "inner") or x.kind == "inner":
            out.append(RoadMark(0.0, "solid", markings.edge_line_width_m))
        elif "aux" in (x.kind, nxt.kind):
            out.append(RoadMark(0.0, "broken", markings.edge_line_width_m))
        else:
            out.append(RoadMark(0.0, "broken", markings.lane_line_width_m))
    return out


def _fit(s_local: np.ndarray, values: np.ndarray, *, shape_preserving: bool) -> CubicProfile:
    if float(np.ptp(values)) < 1e-6:
        return CubicProfile((CubicPiece(0.0, float(values[0])),))
    return fit_cubic_profile(
        s_local, values, tolerance=0.002, max_piece_m=250.0, shape_preserving=shape_preserving
    )


def _samples(a: float, b: float, step_m: float = 4.0) -> np.ndarray:
    n = max(4, int(np.ceil((b - a) / step_m)) + 1)
    return np.linspace(a, b, n)


def build_road(
    source: Source,
    a: float,
    b: float,
    *,
    road_id: str,
    name: str,
    sign: int,
    markings: Markings,
    junction: str = "-1",
) -> BuiltRoad:
    """The road over ``[a, b]`` of ``source`` with lane sections, widths and inner lane
    links (road links and the links at its two ends are set later)."""
    geo = true_lengths(cut_road(source.road, a, b, road_id=road_id))
    breaks = [x for x in source.layout.breaks() if a + 1e-3 < x < b - 1e-3]
    edges = [a, *breaks, b]
    sections: list[LaneSection] = []
    keys: list[dict[int, str]] = []
    offset_pieces: list[CubicPiece] = []
    any_offset = False
    for s0, s1 in itertools.pairwise(edges):
        strips = list(source.layout.alive(s0, s1))
        s = _samples(s0, s1)
        marks = _marks(strips, markings)
        lanes = []
        kmap: dict[int, str] = {}
        for i, (x, mark) in enumerate(zip(strips, marks, strict=True), start=1):
            w = x.width(s)
            prof = _fit(s - s0, w, shape_preserving=bool(w.min() < 0.5))
            lanes.append(
                Lane(
                    sign * i,
                    "shoulder" if x.kind in ("inner", "hard") else "driving",
                    prof,
                    (mark,),
                )
            )
            kmap[sign * i] = x.key
        u_edge = source.layout.u_inner_edge(s, strips)
        if np.abs(u_edge).max() > 1e-9:
            any_offset = True
        off = _fit(s - s0, sign * u_edge, shape_preserving=False)
        offset_pieces += [replace(p, s0=p.s0 + s0 - a) for p in off.pieces]
        centre = Lane(0, "none", road_marks=(RoadMark(0.0, "none", 0.0),))
        side = tuple(lanes)
        sections.append(
            LaneSection(
                s0 - a,
                left=side if sign > 0 else (),
                center=centre,
                right=side if sign < 0 else (),
            )
        )
        keys.append(kmap)
    # inner lane links by key
    for k in range(len(sections) - 1):
        sa, sb = sections[k], sections[k + 1]
        la, lb = side_lanes(sa, sign), side_lanes(sb, sign)
        end_a = sb.s0 - sa.s0
        ids_b = {keys[k + 1][x.id]: x for x in lb}
        new_a, new_b = list(la), list(lb)
        for i, x in enumerate(la):
            y = ids_b.get(keys[k][x.id])
            if y is None:
                continue
            wa = float(x.width.value(np.array([end_a]))[0])
            wb = float(y.width.value(np.array([0.0]))[0])
            if min(wa, wb) <= ZERO_WIDTH_M:
                continue
            new_a[i] = replace(new_a[i], successor=y.id)
            j = lb.index(y)
            new_b[j] = replace(new_b[j], predecessor=x.id)
        sections[k] = _with_side(sections[k], new_a, sign)
        sections[k + 1] = _with_side(sections[k + 1], new_b, sign)
    road = replace(
        geo,
        name=name,
        junction=junction,
        lane_sections=tuple(sections),
        elevation=cut_profile(source.elevation, a, b),
        lane_offset=CubicProfile(tuple(offset_pieces)) if any_offset else CubicProfile(),
    )
    return BuiltRoad(road, keys)


def _with_side(sec: LaneSection, lanes: list[Lane], sign: int) -> LaneSection:
    return replace(sec, left=tuple(lanes)) if sign > 0 else replace(sec, right=tuple(lanes))


def lane_pairs(up: BuiltRoad, down: BuiltRoad) -> list[tuple[int, int]]:
    """(lane id at the end of ``up``, lane id at the start of ``down``) with equal keys and
    width on both sides."""
    a, b = up.end_lanes(True), down.end_lanes(False)
    out = []
    for key, (ia, wa) in a.items():
        if key in b and min(wa, b[key][1]) > ZERO_WIDTH_M:
            out.append((ia, b[key][0]))
    return sorted(out, key=lambda p: abs(p[0]))


def set_end_links(
    road: BuiltRoad,
    *,
    predecessors: dict[int, int] | None = None,
    successors: dict[int, int] | None = None,
) -> BuiltRoad:
    """Lane predecessors of the first section / successors of the last one."""
    secs = list(road.road.lane_sections)
    sign = -1 if secs[0].right else 1

    def apply(sec: LaneSection, links: dict[int, int], attr: str) -> LaneSection:
        lanes = [replace(x, **{attr: links.get(x.id)}) for x in side_lanes(sec, sign)]
        return _with_side(sec, lanes, sign)

    if predecessors is not None:
        secs[0] = apply(secs[0], predecessors, "predecessor")
    if successors is not None:
        secs[-1] = apply(secs[-1], successors, "successor")
    return BuiltRoad(replace(road.road, lane_sections=tuple(secs)), road.keys)
