"""Lane borders that meet at every lane-section border of a road.

Sections are fitted one by one and linked by geometry (:mod:`.sections`); where lanes
that are *not* linked begin or end beside linked ones, their widths on the two sides of
the border need not add up to the same. Every linked lane outside them then moves
sideways at the border (a 17 mm sliver of a closing lane, a shoulder and a lane replaced
by one lane 37 mm narrower, a lane re-fitted 0.35 m narrower after a gap in its marking),
which consumers see as gaps (``roadtwin check`` rule ``lane_shift``, the ASAM rule
``contact_point_no_horizontal_gaps``) and a car driving across sees as a jump.

:func:`seal_lane_borders` closes these gaps on the final road: between two linked lanes
(and between the centre lane and the first linked lane), the unlinked lanes of the section
after the border start with widths scaled so that they fill what the unlinked lanes before
it leave; where nothing begins there, the lanes that end close to what the next section
needs (zero when they leave). The correction fades over the first (last) width piece, so
the lanes keep their fitted widths away from the border.

Offsets are metres; stations are metres along the road's reference line; widths are
evaluated at the border from the sections' own starts.
"""

from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ..fitting import cubic_min
from ..model import CubicPiece, CubicProfile, Lane, LaneSection, Road

log = logging.getLogger(__name__)

_SEAL_TOLERANCE_M = 1e-6  # a mismatch below this is left alone (metres)
_SAME_ROOM_M = 0.01  # unlinked lanes this close in width at a sealed border are one (metres)
_ZERO_WIDTH_M = 1e-3  # narrower than this a lane has closed (metres)
_FADE_M = 20.0  # a correction fades out over this distance from the border (metres)
_REDRAWN_LINE_M = 1.5  # a line between driving lanes re-fitted this far aside is the same line
_REDRAWN_MIN_WIDTH_M = 2.0  # ... between lanes at least this wide on both sides (metres)
_FADES_M = (_FADE_M, 10.0, 5.0, 2.0, 1.0, 0.5)  # shorter where a long one goes negative


def _width_at(lane: Lane, ds: float) -> float:
    return float(lane.width.value(np.array([ds]))[0])


def reexpanded(piece: CubicPiece, x0: float) -> CubicPiece:
    """The same cubic written from ``x0`` on (section-local metres)."""
    h = x0 - piece.s0
    a, b, c, d = piece.a, piece.b, piece.c, piece.d
    return CubicPiece(
        x0, a + b * h + c * h**2 + d * h**3, b + 2 * c * h + 3 * d * h**2, c + 3 * d * h, d
    )


def add_linear_ramp(
    profile: CubicProfile, x_from: float, x_to: float, v_from: float, v_to: float, length_m: float
) -> CubicProfile:
    """``profile`` plus a linear correction from ``v_from`` at ``x_from`` to ``v_to`` at
    ``x_to`` (metres; zero outside), pieces split at both ends inside the section
    (``length_m`` long)."""
    pieces = list(profile.pieces) or [CubicPiece(0.0, 0.0)]
    cuts = sorted({x for x in (x_from, x_to) if x < length_m} - {p.s0 for p in pieces})
    for x in cuts:
        k = max(i for i, p in enumerate(pieces) if p.s0 <= x) if x >= pieces[0].s0 else 0
        if x > pieces[k].s0:
            pieces.insert(k + 1, reexpanded(pieces[k], x))
    slope = (v_to - v_from) / (x_to - x_from)
    out = []
    for p in pieces:
        if x_from - 1e-12 <= p.s0 < x_to - 1e-12:
            p = replace(p, a=p.a + v_from + slope * (p.s0 - x_from), b=p.b + slope)
        out.append(p)
    return CubicProfile(tuple(out))


def _with_start_width(lane: Lane, w_new: float, length_m: float, fade_m: float = _FADE_M) -> Lane:
    delta = w_new - _width_at(lane, 0.0)
    fade = min(fade_m, length_m)
    if abs(delta) < 1e-12 or fade <= 0.0:
        return lane
    return replace(lane, width=add_linear_ramp(lane.width, 0.0, fade, delta, 0.0, length_m))


def _with_end_width(lane: Lane, w_new: float, length_m: float, fade_m: float = _FADE_M) -> Lane:
    delta = w_new - _width_at(lane, length_m)
    fade = min(fade_m, length_m)
    if abs(delta) < 1e-12 or fade <= 0.0:
        return lane
    return replace(
        lane, width=add_linear_ramp(lane.width, length_m - fade, length_m, 0.0, delta, length_m)
    )


def _min_width(lane: Lane, length_m: float) -> float:
    ds = np.linspace(0.0, max(length_m, 0.0), 801)
    return float(np.min(lane.width.value(ds)))


def _scaled(
    lanes: list[Lane], widths: list[float], target: float, *, at_start: bool, length_m: float
) -> list[Lane] | None:
    """``lanes`` with their widths at one end scaled to sum to ``target`` (metres); None
    if that would make one negative anywhere in the section."""
    total = sum(widths)
    if total <= 0.0 or target < 0.0:
        return None
    out = []
    for lane, w in zip(lanes, widths, strict=True):
        fixed = faded_width(lane, w * target / total, length_m, at_start=at_start)
        if fixed is None:
            return None
        out.append(fixed)
    return out


def faded_width(
    lane: Lane,
    w_new: float,
    length_m: float,
    *,
    at_start: bool,
    fades_m: tuple[float, ...] = _FADES_M,
) -> Lane | None:
    """``lane`` (in a section ``length_m`` long) with its width at the section's start
    (``at_start``) or end set to ``w_new`` (metres) by a linear correction that fades out
    over the longest of ``fades_m`` (metres, longest first, at most the section) that keeps
    the width non-negative; None if none does.

    A lane that has (nearly) closed before the border would dip below zero under a long
    correction, hence the shorter ones.
    """
    for fade in fades_m:
        fixed = (
            _with_start_width(lane, w_new, length_m, fade)
            if at_start
            else _with_end_width(lane, w_new, length_m, fade)
        )
        if _min_width(fixed, length_m) >= -1e-9:
            return fixed
    return None


def _seal_side(
    prev: tuple[Lane, ...],
    cur: tuple[Lane, ...],
    prev_len: float,
    cur_len: float,
    offset_jump: float,
) -> tuple[tuple[Lane, ...], tuple[Lane, ...], float]:
    """One side of one border: ``(prev lanes, cur lanes, largest shift sealed)``.

    ``offset_jump`` is the centre lane's offset after minus before the border, outwards
    positive (metres)."""
    prev_l, cur_l = list(prev), list(cur)
    index_prev = {ln.id: j for j, ln in enumerate(prev_l)}
    pairs = sorted(
        (i, index_prev[ln.predecessor])
        for i, ln in enumerate(cur_l)
        if ln.predecessor is not None and ln.predecessor in index_prev
    )
    worst = 0.0
    i_last, j_last = -1, -1
    for i, j in pairs:
        if j <= j_last:  # links that cross each other: nothing consistent to seal
            continue
        # linked lanes continue with the width they had
        cur_l[i] = _with_start_width(cur_l[i], _width_at(prev_l[j], prev_len), cur_len)
        run_cur = list(range(i_last + 1, i))
        run_prev = list(range(j_last + 1, j))
        w_cur = [_width_at(cur_l[k], 0.0) for k in run_cur]
        w_prev = [_width_at(prev_l[k], prev_len) for k in run_prev]
        inner_cur = (offset_jump if i_last < 0 else 0.0) + sum(w_cur)
        inner_prev = sum(w_prev)
        mismatch = inner_cur - inner_prev
        if abs(mismatch) > _SEAL_TOLERANCE_M:
            # the lanes that begin take it up; where none can, the ones that end
            options = (
                (cur_l, run_cur, w_cur, sum(w_cur) - mismatch, True, cur_len),
                (prev_l, run_prev, w_prev, sum(w_prev) + mismatch, False, prev_len),
            )
            for lanes, run, widths, target, at_start, span in options:
                fixed = _scaled(
                    [lanes[k] for k in run], widths, target, at_start=at_start, length_m=span
                )
                if fixed is not None:
                    for k, ln in zip(run, fixed, strict=True):
                        lanes[k] = ln
                    worst = max(worst, abs(mismatch))
                    break
        _link_same_room(prev_l, cur_l, run_prev, run_cur, prev_len, cur_len)
        i_last, j_last = i, j
    return tuple(prev_l), tuple(cur_l), worst


def _link_same_room(
    prev_l: list[Lane],
    cur_l: list[Lane],
    run_prev: list[int],
    run_cur: list[int],
    prev_len: float,
    cur_len: float,
) -> None:
    """Link (in place) the unlinked lanes of a sealed run that fill the same room: as many
    on both sides, of the same types, each as wide as its partner (a lane re-fitted after
    a gap in its marking is the lane it was; left unlinked, a car in it had nowhere to go),
    or lanes of the same types, driving lanes among them each at least
    ``_REDRAWN_MIN_WIDTH_M`` wide, whose widths differ by up to ``_REDRAWN_LINE_M`` (the
    lines between them re-fitted aside: they move over the fade).
    Lanes of zero width stay unlinked (OpenDRIVE: a lane that closes has no successor)."""
    # lanes of zero width at the border (a gore's shoulder opening there) take no room
    run_prev = [k for k in run_prev if _width_at(prev_l[k], prev_len) >= _ZERO_WIDTH_M]
    run_cur = [k for k in run_cur if _width_at(cur_l[k], 0.0) >= _ZERO_WIDTH_M]
    if not run_cur or len(run_cur) != len(run_prev):
        return
    w_prev = [_width_at(prev_l[k], prev_len) for k in run_prev]
    w_cur = [_width_at(cur_l[k], 0.0) for k in run_cur]
    same = all(
        prev_l[b].type == cur_l[a].type and abs(wp - wc) <= _SAME_ROOM_M
        for a, b, wp, wc in zip(run_cur, run_prev, w_prev, w_cur, strict=True)
    )
    # lanes as many on both sides, of the same types, that share the room differently
    # (the lines between them re-fitted up to _REDRAWN_LINE_M aside), driving lanes among
    # them and each at least _REDRAWN_MIN_WIDTH_M wide: the same lanes, the lines moved
    # over the fade. A shoulder among them is such a lane too (town06-auto-s7 with a
    # noisier sensor: the inner shoulder 1.91 m before a border and 1.06 m after it, the
    # two driving lanes beside it sharing the rest; left unlinked, two of the mainline's
    # lanes led nowhere)
    redrawn = (
        abs(sum(w_prev) - sum(w_cur)) <= _SAME_ROOM_M
        and any(cur_l[a].type == "driving" for a in run_cur)
        and all(
            prev_l[b].type == cur_l[a].type
            and (cur_l[a].type != "driving" or min(wp, wc) >= _REDRAWN_MIN_WIDTH_M)
            and abs(wp - wc) <= _REDRAWN_LINE_M
            for a, b, wp, wc in zip(run_cur, run_prev, w_prev, w_cur, strict=True)
        )
    )
    if not (same or redrawn):
        return
    for a, b, wp in zip(run_cur, run_prev, w_prev, strict=True):
        if wp < _ZERO_WIDTH_M:
            continue
        cur_l[a] = replace(_with_start_width(cur_l[a], wp, cur_len), predecessor=prev_l[b].id)
        prev_l[b] = replace(prev_l[b], successor=cur_l[a].id)


def seal_lane_borders(road: Road) -> Road:
    """``road`` with the lanes linked across each lane-section border joined there.

    Parameters
    ----------
    road
        A road whose lanes are linked between its sections (predecessor / successor ids).

    Returns
    -------
    Road
        The same road; only width pieces next to section borders change (see module
        docstring). Borders inside a road are then continuous to floating-point precision
        for every pair of linked lanes whose links do not cross.
    """
    sections = list(road.lane_sections)
    if len(sections) < 2:
        return road
    for n in range(1, len(sections)):
        prev, cur = sections[n - 1], sections[n]
        s_b = cur.s0
        prev_len = s_b - prev.s0
        nxt = sections[n + 1].s0 if n + 1 < len(sections) else road.length
        cur_len = nxt - s_b
        off = road.lane_offset.value(np.array([s_b - 1e-9, s_b]))
        jump = float(off[1] - off[0])  # left positive
        p_r, c_r, worst_r = _seal_side(prev.right, cur.right, prev_len, cur_len, -jump)
        p_l, c_l, worst_l = _seal_side(prev.left, cur.left, prev_len, cur_len, jump)
        worst = max(worst_r, worst_l)
        if worst > 1e-3:
            log.debug("road %s: lanes joined at s=%.2f m (shift %.3f m)", road.id, s_b, worst)
        sections[n - 1] = replace(prev, right=p_r, left=p_l)
        sections[n] = replace(cur, right=c_r, left=c_l)
    return replace(road, lane_sections=tuple(sections))


def _nonnegative_piece(p: CubicPiece, h: float) -> CubicPiece:
    """``p`` over ``0 <= t <= h`` (metres) if it stays non-negative; else the cubic Hermite
    between its end values (clipped at zero) with the end slopes zeroed where they would
    let it dip: a lane that closes to (opens from) zero with a noisy width wiggles a few
    millimetres below zero otherwise."""
    if h <= 0.0 or cubic_min(p.a, p.b, p.c, p.d, h) >= -1e-9:
        return p
    va = max(p.a, 0.0)
    vb = max(p.a + h * (p.b + h * (p.c + h * p.d)), 0.0)
    db_end = p.b + 2.0 * p.c * h + 3.0 * p.d * h * h
    # the last pair (flat ends) is monotone between two non-negative values: it holds
    for da, db in ((p.b, db_end), (max(p.b, 0.0), min(db_end, 0.0)), (0.0, 0.0)):
        c2 = (3.0 * (vb - va) / h - 2.0 * da - db) / h
        c3 = (2.0 * (va - vb) / h + da + db) / (h * h)
        if (da, db) == (0.0, 0.0) or cubic_min(va, da, c2, c3, h) >= -1e-9:
            break
    return CubicPiece(p.s0, va, da, c2, c3)


def _nonnegative_lanes(lanes: tuple[Lane, ...], length_m: float) -> tuple[Lane, ...]:
    out = []
    for lane in lanes:
        pieces = lane.width.pieces
        ends = [p.s0 for p in pieces[1:]] + [length_m]
        fixed = tuple(_nonnegative_piece(p, e - p.s0) for p, e in zip(pieces, ends, strict=True))
        out.append(lane if fixed == pieces else replace(lane, width=CubicProfile(fixed)))
    return tuple(out)


def nonnegative_widths(road: Road) -> Road:
    """``road`` with every lane-width piece that dips below zero inside its section
    replaced by a non-negative one between the same end values (ASAM and ``roadtwin
    check``: no negative lane width anywhere)."""
    sections: list[LaneSection] = []
    for k, sec in enumerate(road.lane_sections):
        end = road.section_end(k)
        length = end - sec.s0
        sections.append(
            replace(
                sec,
                right=_nonnegative_lanes(sec.right, length),
                left=_nonnegative_lanes(sec.left, length),
            )
        )
    return replace(road, lane_sections=tuple(sections))


__all__ = [
    "add_linear_ramp",
    "faded_width",
    "nonnegative_widths",
    "reexpanded",
    "seal_lane_borders",
]
