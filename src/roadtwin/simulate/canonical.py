"""Canonical re-expression of a carriageway chain: one fitted road per chain of legs.

The reference line is the median-side edge of the carriageway, FITTED as ParamPoly3 pieces
(:func:`roadtwin.fitting.fit_parampoly3_chain`) through dense samples of that edge,
whatever geometry types the source map used and whichever way its roads are driven.
Where that edge steps sideways between two legs (lanes ending or starting at full width
on the median side: a gore of a left exit or entry with right-hand traffic), the samples
beyond the step are shifted back by the step's size along their own normals before the
fit, so the reference line stays smooth (it runs parallel to the edge, at the level of the
longest stretch), and the step becomes the road's lane offset: piecewise constant,
changing exactly where a lane section starts. Tapering changes of the edge stay in the
reference line. Every lane border is projected into the fitted road's Frenet frame and
each lane width, measured from the median-side edge (reference line + lane offset), is
fitted as a cubic profile (:func:`roadtwin.fitting.fit_cubic_profile`), leg by leg, so the
canonical borders are the source borders to within the fit tolerance. Lanes keep their
source types and road marks; lanes sit on the traffic side (right lanes, ids -1, -2, ...
for right-hand traffic; left lanes for left-hand traffic), inner to outer. A new lane
section starts wherever the set of lanes changes; lanes are linked across sections.

Frames: mapping-frame metres; ``u`` is the station along the canonical road (metres).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import CubicSpline

from ..fitting import arc_length, fit_cubic_profile, fit_parampoly3_chain
from ..model import (
    CubicPiece,
    CubicProfile,
    Lane,
    LaneSection,
    Road,
    RoadMark,
    RoadNetwork,
    chain_geometry,
)
from .carriageway import Leg, next_lane
from .leg_samples import LegSamples, sample_leg
from .route import Passage, TrafficSide

FloatArray = NDArray[np.float64]

JOIN_TOLERANCE_M = 0.05
"""Consecutive legs whose median edges meet closer than this share their joint sample."""

SMOOTH_KINK_RAD = 0.01
"""A change of direction of the median edge at a leg joint below this is smoothed over by
the reference-line fit (:func:`roadtwin.fitting.fit_parampoly3_chain` does the same)."""


@dataclass(frozen=True)
class FitSettings:
    """Tolerances of the canonical re-expression (metres)."""

    sample_step_m: float = 0.5
    """Spacing of the cross-sections sampled along each leg."""
    geometry_tolerance_m: float = 0.0005
    """Reference-line fit tolerance against the sampled median edge."""
    min_piece_m: float = 0.25
    """Shortest reference-line piece: short enough to hold the tolerance next to a slight
    kink of the source edge at a leg joint (the fitted line keeps its heading there)."""
    width_min_piece_m: float = 0.25
    """Shortest lane-width piece: short enough to hold the tolerance where a source width
    changes quickly between close breakpoints."""
    width_tolerance_m: float = 0.0002
    """Lane-width and elevation fit tolerance."""


@dataclass(frozen=True)
class ChainFit:
    """A chain of legs re-expressed as one road.

    ``road`` is the whole chain (reference line, elevation, all lane sections);
    ``leg_u`` the station range ``(u_start, u_end)`` of each leg; ``keys`` the lane keys
    of each leg (median side first; equal keys = the same lane continuing);
    ``section_keys`` the keys of each lane section of ``road``; ``samples`` the sampled
    cross-sections of each leg and ``sample_u`` the station of each of their samples.
    """

    road: Road
    legs: tuple[Leg, ...]
    leg_u: tuple[tuple[float, float], ...]
    keys: tuple[tuple[int, ...], ...]
    section_keys: tuple[tuple[int, ...], ...]
    samples: tuple[LegSamples, ...]
    sample_u: tuple[FloatArray, ...]

    def key_of(self, section: int, lane_id: int) -> int:
        """Lane key of canonical lane ``lane_id`` in lane section ``section``."""
        return self.section_keys[section][abs(lane_id) - 1]

    def lane_id(self, section: int, key: int) -> int | None:
        """Canonical lane id of lane ``key`` in lane section ``section`` (None: absent)."""
        keys = self.section_keys[section]
        if key not in keys:
            return None
        sec = self.road.lane_sections[section]
        side = sec.right or sec.left
        return side[keys.index(key)].id


def lane_keys(
    network: RoadNetwork,
    legs: list[Leg],
    passages: list[Passage | None],
    *,
    first_keys: tuple[int, ...] | None = None,
    counter: list[int] | None = None,
) -> list[tuple[int, ...]]:
    """Lane identity along a chain: a key per lane of every leg; a lane that continues
    (by lane links, or through a junction leg's up/down lanes) keeps its key.

    ``counter`` is a one-element list holding the next free key (shared between chains).
    """
    counter = counter if counter is not None else [0]

    def fresh() -> int:
        counter[0] += 1
        return counter[0]

    keys: list[tuple[int, ...]] = []
    for i, leg in enumerate(legs):
        if i == 0:
            if first_keys is not None and len(first_keys) == len(leg.lanes):
                keys.append(tuple(first_keys))
            else:
                keys.append(tuple(fresh() for _ in leg.lanes))
            continue
        prev = legs[i - 1]
        targets: dict[tuple[str, int], int] = {}
        for lane, key in zip(prev.lanes, keys[-1], strict=True):
            nxt = next_lane(network, prev, lane, leg, passages[i - 1])
            if nxt is not None and nxt not in targets:
                targets[nxt] = key
        used: set[int] = set()
        row = []
        for lane in leg.lanes:
            key = targets.get(lane.up) if lane.up is not None else None
            if key is None or key in used:
                key = fresh()
            used.add(key)
            row.append(key)
        keys.append(tuple(row))
    return keys


def _merge_pieces(
    pieces: list[CubicPiece], end: float, tol: float = 1e-6
) -> tuple[CubicPiece, ...]:
    """Drop pieces that only continue the cubic before them: where the kept cubic,
    extended, stays within ``tol`` (metres) of the piece over its whole extent (fits
    split at breakpoints where the source profile does not change). ``end`` is where the
    last piece ends (same station frame)."""
    out: list[CubicPiece] = []
    for i, p in enumerate(pieces):
        if out:
            stop = pieces[i + 1].s0 if i + 1 < len(pieces) else end
            x = np.linspace(p.s0, max(stop, p.s0), 5)
            kept = CubicProfile((out[-1],)).value(x)
            mine = CubicProfile((p,)).value(x)
            if float(np.max(np.abs(kept - mine))) <= tol:
                continue
        out.append(p)
    return tuple(out)


def _intervals(sm: LegSamples) -> list[tuple[int, int]]:
    """Sample index ranges ``[a, b]`` between a leg's ends and its breakpoints."""
    bounds = [0, *sm.breaks, sm.p.size - 1]
    return [(a, b) for a, b in itertools.pairwise(bounds) if b > a]


def _left_normals(xy: FloatArray, *, half_window_m: float = 0.25) -> FloatArray:
    """Unit normals (N, 2) to the left of a polyline's direction (N >= 2 points), from the
    chord between the points about ``half_window_m`` behind and ahead: points only
    micrometres apart (samples at nearly coinciding breakpoints) get the same normal, so
    shifting along the normals keeps their order."""
    arc = arc_length(xy)
    n = xy.shape[0]
    ahead = np.clip(np.searchsorted(arc, arc + half_window_m), 1, n - 1)
    behind = np.clip(np.searchsorted(arc, arc - half_window_m, side="right") - 1, 0, n - 2)
    d = xy[ahead] - xy[behind]
    d = d / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    return np.column_stack([-d[:, 1], d[:, 0]])


def median_levels(samples: list[LegSamples]) -> FloatArray:
    """Level of each leg's median-side edge (metres, left of the direction of travel): the
    sum of the sideways steps of the edge at the leg joints before it, relative to the
    level the longest stretch of the chain has (so that stretch gets no lane offset).

    A step is where consecutive legs' edges do not meet (farther apart than
    :data:`JOIN_TOLERANCE_M`) and the gap has a sideways part of at least that much,
    measured in the normal at the end of the earlier leg.
    """
    levels = [0.0]
    for prev, sm in itertools.pairwise(samples):
        gap = sm.median[0, :2] - prev.median[-1, :2]
        step = 0.0
        if np.hypot(*gap) >= JOIN_TOLERANCE_M:
            sideways = float(_left_normals(prev.median[-2:, :2])[-1] @ gap)
            step = sideways if abs(sideways) >= JOIN_TOLERANCE_M else 0.0
        levels.append(levels[-1] + step)
    level = np.asarray(levels)
    lengths = np.array(
        [float(np.hypot(*np.diff(sm.median[:, :2], axis=0).T).sum()) for sm in samples]
    )
    key = np.round(level, 3)
    totals = {k: float(lengths[key == k].sum()) for k in np.unique(key)}
    base = max(totals, key=lambda k: (totals[k], -abs(k)))
    return np.where(key == base, 0.0, level - level[key == base][0])


def _corner(a: FloatArray, b: FloatArray, *, chord_m: float = 0.25) -> FloatArray:
    """Where the line along the end of polyline ``a`` meets the line along the start of
    ``b`` (directions over about ``chord_m``, not over micrometre-short end segments;
    (2,) metres; the midpoint of their ends when the lines are parallel or meet more than
    a metre away)."""
    da = a[-1] - a[::-1][_chord_index(a[::-1], chord_m)]
    db = b[_chord_index(b, chord_m)] - b[0]
    cross = da[0] * db[1] - da[1] * db[0]
    mid = 0.5 * (a[-1] + b[0])
    if abs(cross) < 1e-12:
        return mid
    w = b[0] - a[-1]
    x = a[-1] + da * (w[0] * db[1] - w[1] * db[0]) / cross
    return x if max(np.hypot(*(x - a[-1])), np.hypot(*(x - b[0]))) <= 1.0 else mid


def _chord_index(xy: FloatArray, chord_m: float) -> int:
    """Index of the first point of ``xy`` at least ``chord_m`` from its first point (the
    last point if none is)."""
    far = np.flatnonzero(np.hypot(*(xy - xy[0]).T) >= chord_m)
    return int(far[0]) if far.size else len(xy) - 1


def _join(samples: list[LegSamples], levels: FloatArray) -> tuple[FloatArray, list[int]]:
    """Concatenated median-edge points (M, 3), each leg's shifted back by its level along
    its own normals (:func:`median_levels`), and the index of each leg's first point in it
    (a leg that starts where the previous ended shares that point).

    Where a shifted leg meets its neighbour, the edge's slight kink at the joint (the
    source roads' headings differ a little) makes the two parallel lines overlap or part
    by the shift times the kink angle: both end points move to where the lines meet, as an
    offset of a kinked line does (the fit keeps a piece boundary at every joint).
    """
    meds = []
    for sm, level in zip(samples, levels, strict=True):
        med = sm.median
        if level != 0.0:
            med = med.copy()
            med[:, :2] -= level * _left_normals(med[:, :2])
        meds.append(med)
    for i in range(1, len(meds)):
        a, b = meds[i - 1], meds[i]
        if (levels[i - 1] == 0.0 and levels[i] == 0.0) or a.shape[0] < 2 or b.shape[0] < 2:
            continue
        if np.hypot(*(b[0, :2] - a[-1, :2])) < 1.0:
            da = a[-1, :2] - a[::-1][_chord_index(a[::-1, :2], 0.25), :2]
            db = b[_chord_index(b[:, :2], 0.25), :2] - b[0, :2]
            cos = float(da @ db) / max(float(np.hypot(*da) * np.hypot(*db)), 1e-12)
            # a kink the fit keeps (SMOOTH_KINK_RAD): the lines meet at a corner; else the
            # edge is smooth there and the ends meet halfway
            if cos < math.cos(SMOOTH_KINK_RAD):
                x = _corner(a[:, :2], b[:, :2])
            else:
                x = 0.5 * (a[-1, :2] + b[0, :2])
            # points of either leg beyond the meeting point (micrometre-spaced samples
            # next to a joint) collapse onto it: the line never runs backwards
            a[((a[:, :2] - x) @ da >= 0.0), :2] = x
            b[((b[:, :2] - x) @ db <= 0.0), :2] = x
    pts: list[FloatArray] = []
    first: list[int] = []
    count = 0
    for med in meds:
        if pts and np.hypot(*(med[0, :2] - pts[-1][-1, :2])) < JOIN_TOLERANCE_M:
            first.append(count - 1)
            med = med[1:]
        else:
            first.append(count)
        pts.append(med)
        count += med.shape[0]
    return np.vstack(pts), first


def _monotone_interp(u: FloatArray, t: FloatArray, u_new: FloatArray) -> FloatArray:
    """Cubic interpolation of t(u) at u_new (linear where u is not increasing)."""
    order = np.argsort(u, kind="stable")
    u_s, t_s = u[order], t[order]
    keep = np.concatenate([[True], np.diff(u_s) > 1e-9])
    u_s, t_s = u_s[keep], t_s[keep]
    if u_s.size >= 4:  # extrapolates a little past a chain's ends (oblique end sections)
        return CubicSpline(u_s, t_s)(u_new)
    return np.interp(u_new, u_s, t_s)


def _marks_to_u(
    marks, p: FloatArray, u: FloatArray, u_section: float, lo: float, hi: float
) -> list[RoadMark]:
    out = []
    for p_from, m in marks:
        uf = float(np.interp(p_from, p, u))
        if uf >= hi - 1e-6:
            continue
        out.append(replace(m, s_offset=max(uf, lo) - u_section))
    return out


def _merge_marks(marks: list[RoadMark]) -> tuple[RoadMark, ...]:
    out: list[RoadMark] = []
    for m in sorted(marks, key=lambda m: m.s_offset):
        if out and (out[-1].type, out[-1].width_m, out[-1].color) == (m.type, m.width_m, m.color):
            continue
        if out and abs(out[-1].s_offset - m.s_offset) < 1e-6:
            out[-1] = m
            continue
        out.append(m)
    return tuple(out) or (RoadMark(0.0, "none", 0.0),)


def fit_chain(
    network: RoadNetwork,
    legs: list[Leg],
    keys: list[tuple[int, ...]],
    traffic_side: TrafficSide,
    *,
    road_id: str,
    name: str,
    breaks: tuple[int, ...] = (),
    settings: FitSettings | None = None,
    median_steps: bool = True,
) -> ChainFit:
    """Fit one canonical road through a chain of legs.

    Parameters
    ----------
    legs, keys
        Legs in driving order and their lane keys (:func:`lane_keys`).
    breaks
        Indices of legs that must start a geometry piece and a lane section (where the
        road will be cut, e.g. at a ramp's junction).
    median_steps
        Sideways steps of the median-side edge between legs become lane offset steps
        (:func:`median_levels`); False: the reference line follows the edge through them.

    Raises
    ------
    FitError
        A leg's lane border does not advance along the fitted reference line.
    """
    cfg = settings or FitSettings()
    side_sign = -1.0 if traffic_side == "right" else 1.0
    samples = [sample_leg(network, leg, traffic_side, step_m=cfg.sample_step_m) for leg in legs]
    levels = median_levels(samples) if median_steps else np.zeros(len(samples))
    median, first = _join(samples, levels)
    chord = arc_length(median[:, :2])
    # the median edge may kink or jump in curvature at every leg joint and source
    # breakpoint: the fit keeps a piece boundary there (and the cuts must be ones)
    joints = [first[i] for i in range(1, len(legs))]
    joints += [first[i] + j for i, sm in enumerate(samples) for j in sm.breaks]
    pieces = fit_parampoly3_chain(
        median[:, :2],
        tolerance_m=cfg.geometry_tolerance_m,
        min_piece_m=cfg.min_piece_m,
        breaks_m=chord[np.unique(np.asarray(joints, dtype=int))] if joints else (),
    )
    ref = Road(road_id, chain_geometry(pieces), (LaneSection(0.0),), name=name)
    total = ref.length
    s_guess = chord * (total / max(chord[-1], 1e-9))
    u_med, _ = ref.project(median[:, :2], s_init=s_guess)
    u_med = np.maximum.accumulate(u_med)
    u_med[0], u_med[-1] = 0.0, total
    piece_s0 = np.array([g.s0 for g in ref.geometry])
    for i in breaks:  # snap cut stations onto the piece boundary the fit placed there
        if 0 < i < len(legs):
            j = int(np.argmin(np.abs(piece_s0 - u_med[first[i]])))
            u_med[first[i]] = piece_s0[j]
    sample_u = []
    leg_u = []
    for i, sm in enumerate(samples):
        u = u_med[first[i] : first[i] + sm.p.size]
        sample_u.append(u)
        leg_u.append((float(u[0]), float(u[-1])))
    z_pieces: list[CubicPiece] = []
    for sm, u in zip(samples, sample_u, strict=True):
        for a, b in _intervals(sm):
            if u[b] - u[a] > 1e-6:
                z_pieces += fit_cubic_profile(
                    u[a : b + 1], sm.median[a : b + 1, 2], tolerance=cfg.width_tolerance_m
                ).pieces
    elevation = CubicProfile(_merge_pieces(z_pieces, total))
    if any(sm.roll is not None for sm in samples):
        roll_pieces: list[CubicPiece] = []
        for sm, u in zip(samples, sample_u, strict=True):
            roll = np.zeros(sm.p.size) if sm.roll is None else sm.roll
            for a, b in _intervals(sm):
                if u[b] - u[a] > 1e-6:
                    roll_pieces += fit_cubic_profile(
                        u[a : b + 1], roll[a : b + 1], tolerance=1e-4
                    ).pieces
        # before the lane widths: t runs along the rolled surface (projection divides the
        # plan offsets by cos(roll)), as in the source
        ref = replace(ref, superelevation=CubicProfile(_merge_pieces(roll_pieces, total)))

    # lane sections: a new one wherever the keys change or a break is forced
    groups: list[list[int]] = []
    # (the median-side edge steps only where a lane section starts)
    for i in range(len(legs)):
        same = groups and keys[i] == keys[groups[-1][-1]] and levels[i] == levels[i - 1]
        if same and i not in breaks:
            groups[-1].append(i)
        else:
            groups.append([i])
    sections: list[LaneSection] = []
    section_keys: list[tuple[int, ...]] = []
    for g, members in enumerate(groups):
        u0 = leg_u[members[0]][0]
        u_end = leg_u[members[-1]][1]
        gkeys = keys[members[0]]
        widths: list[list[CubicPiece]] = [[] for _ in gkeys]
        marks: list[list[RoadMark]] = [[] for _ in gkeys]
        centre_marks: list[RoadMark] = []
        for i in members:
            sm, u = samples[i], sample_u[i]
            lo, hi = leg_u[i]
            if hi - lo < 1e-6:
                continue
            t_prev = np.full(u.size, levels[i])  # lanes are measured from the median edge
            n_k = len(gkeys)
            u_all, t_all = ref.project(
                sm.borders[:, :, :2].reshape(-1, 2), s_init=np.tile(u, n_k), iterations=8
            )
            for k in range(n_k):
                uk, tk = u_all[k * u.size : (k + 1) * u.size], t_all[k * u.size : (k + 1) * u.size]
                # a border point before the chain's start or past its end projects onto
                # the end (clipped): it says nothing about the border there
                on = (uk > 1e-9) & (uk < total - 1e-9)
                on |= ~np.any(on)
                t_k = _monotone_interp(uk[on], tk[on], u)
                w = np.maximum(side_sign * (t_k - t_prev), 0.0)
                for a, b in _intervals(sm):
                    if u[b] - u[a] > 1e-6:
                        widths[k] += fit_cubic_profile(
                            u[a : b + 1] - u0,
                            w[a : b + 1],
                            tolerance=cfg.width_tolerance_m,
                            min_piece_m=cfg.width_min_piece_m,
                            # no overshoot below zero where a lane opens or closes
                            shape_preserving=bool(np.min(w[a : b + 1]) < 0.5),
                        ).pieces
                marks[k] += _marks_to_u(sm.marks[k], sm.p, u, u0, lo, hi)
                t_prev = t_k
            centre_marks += _marks_to_u(sm.median_marks, sm.p, u, u0, lo, hi)
        ids = [int(side_sign * (k + 1)) for k in range(len(gkeys))]
        prev_keys = section_keys[-1] if section_keys else ()
        next_keys = keys[groups[g + 1][0]] if g + 1 < len(groups) else ()
        lanes = []
        for k, key in enumerate(gkeys):
            pred = prev_keys.index(key) if key in prev_keys else None
            succ = next_keys.index(key) if key in next_keys else None
            lane_type = legs[members[0]].lanes[k].type
            lanes.append(
                Lane(
                    ids[k],
                    lane_type,  # type: ignore[arg-type]
                    CubicProfile(_merge_pieces(widths[k], u_end - u0) or (CubicPiece(0.0, 0.0),)),
                    _merge_marks(marks[k]),
                    predecessor=None if pred is None else int(side_sign * (pred + 1)),
                    successor=None if succ is None else int(side_sign * (succ + 1)),
                )
            )
        centre = Lane(0, "none", road_marks=_merge_marks(centre_marks))
        sections.append(
            LaneSection(
                u0,
                left=tuple(lanes) if side_sign > 0 else (),
                center=centre,
                right=tuple(lanes) if side_sign < 0 else (),
            )
        )
        section_keys.append(gkeys)
    offset = [
        CubicPiece(sec.s0, float(levels[g[0]]))
        for k, (sec, g) in enumerate(zip(sections, groups, strict=True))
        if k == 0 or levels[g[0]] != levels[groups[k - 1][0]]
    ]
    lane_offset = CubicProfile(tuple(offset)) if np.any(levels != 0.0) else CubicProfile()
    road = replace(ref, lane_sections=tuple(sections), elevation=elevation, lane_offset=lane_offset)
    return ChainFit(
        road,
        tuple(legs),
        tuple(leg_u),
        tuple(keys),
        tuple(section_keys),
        tuple(samples),
        tuple(sample_u),
    )


def max_border_error_m(
    fit: ChainFit, *, network: RoadNetwork | None = None, step_m: float | None = None
) -> dict[str, float]:
    """Largest lateral deviation (metres) of the canonical road from the source borders:
    ``median_edge`` (against the reference line plus the lane offset) and ``lane_borders``
    (source borders only, not bridged ones), measured in the canonical road's Frenet frame.

    By default at the samples the fit used; with ``network`` and ``step_m`` the source
    map is sampled afresh every ``step_m`` metres (an independent check).
    """
    road = fit.road
    samples, sample_u = fit.samples, fit.sample_u
    if network is not None and step_m is not None:
        side: TrafficSide = "right" if road.lane_sections[0].right else "left"
        samples = tuple(sample_leg(network, leg, side, step_m=step_m) for leg in fit.legs)
        sample_u = tuple(
            np.interp(sm.p, old.p, u)
            for sm, old, u in zip(samples, fit.samples, fit.sample_u, strict=True)
        )
    worst_med, worst_lane = 0.0, 0.0
    for sm, u, (lo, hi), leg in zip(samples, sample_u, fit.leg_u, fit.legs, strict=True):
        if hi - lo < 1e-6:
            continue
        sec_idx = road.section_index(np.array([0.5 * (lo + hi)]))[0]
        inside = np.clip(u, lo + 1e-7, hi - 1e-7)
        if leg.lanes[0].source is not None:
            um, t = road.project(sm.median[:, :2], s_init=u, iterations=10)
            on = (um > 1e-7) & (um < road.length - 1e-7)
            edge = road.lane_border_t(np.clip(um, lo + 1e-7, hi - 1e-7), 0)
            worst_med = max(worst_med, float(np.max(np.abs(t - edge)[on], initial=0.0)))
        sec = road.lane_sections[sec_idx]
        side = sec.right or sec.left
        exact = [k for k, ex in enumerate(sm.exact) if ex]
        if not exact:
            continue
        u_all, t_all = road.project(
            sm.borders[exact, :, :2].reshape(-1, 2),
            s_init=np.tile(inside, len(exact)),
            iterations=8,
        )
        for j, k in enumerate(exact):
            uk, tk = u_all[j * u.size : (j + 1) * u.size], t_all[j * u.size : (j + 1) * u.size]
            on = (uk > lo + 1e-7) & (uk < hi - 1e-7)  # points beyond a chain end: no border
            if not np.any(on):
                continue
            t_c = road.lane_border_t(uk[on], side[k].id)
            worst_lane = max(worst_lane, float(np.nanmax(np.abs(tk[on] - t_c))))
    return {"median_edge": worst_med, "lane_borders": worst_lane}
