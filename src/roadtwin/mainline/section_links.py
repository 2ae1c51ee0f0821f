"""Lanes linked across lane sections by the geometry of their borders: a lane goes on
where its borders meet, lanes beginning or ending between linked ones open from or close
to zero width, refitted outer lanes keep their links.

Widths and offsets are metres, stations metres along the mainline.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..model import (
    Lane,
    LaneSection,
    close_width,
    continue_width,
)
from .seal import add_linear_ramp
from .tapers import _RESIDUAL_WIDTH_M

FloatArray = NDArray[np.float64]

_ZERO_FADE_M = 20.0  # a taper's rest (narrower than _RESIDUAL_WIDTH_M) fades out over
# this where a whole piece cannot

_LINK_TOLERANCE_M = 0.3  # lanes whose borders meet this closely continue across sections
_WIDTH_JUMP_M = 1.0  # a driving lane this much narrower/wider beyond a border is the same


def _side_lanes(sec: LaneSection) -> tuple[Lane, ...]:
    return sec.right if sec.right else sec.left


def _nonnegative(candidates: tuple[Lane, ...], original: Lane, ds: FloatArray) -> Lane:
    """The first of ``candidates`` whose width does not dip below zero on ``ds``
    (metres), else ``original``."""
    for fixed in candidates:
        if float(np.min(fixed.width.value(ds))) >= 0.0:
            return fixed
    return original


def _between_linked(lanes: tuple[Lane, ...], i: int, link: str) -> bool:
    """Whether lanes inside and outside lane ``i`` are linked (``link``: the attribute,
    ``"predecessor"`` or ``"successor"``)."""
    return any(getattr(o, link) is not None for o in lanes[:i]) and any(
        getattr(o, link) is not None for o in lanes[i + 1 :]
    )


def _open_from_zero(lane: Lane, sec_len: float) -> tuple[Lane, ...]:
    """``lane`` corrected to start at zero width: over its first piece, or if that makes
    it negative, over ``_ZERO_FADE_M`` (:func:`.seal.add_linear_ramp`; ``sec_len`` metres,
    inf for the road's last section)."""
    w0 = float(lane.width.value(np.array([0.0]))[0])
    fade = min(_ZERO_FADE_M, sec_len)
    faded = add_linear_ramp(lane.width, 0.0, fade, -w0, 0.0, sec_len)
    return continue_width(lane, 0.0), replace(lane, width=faded)


def _close_to_zero(lane: Lane, sec_len: float) -> tuple[Lane, ...]:
    """``lane`` corrected to end at zero width at ``sec_len`` (see :func:`_open_from_zero`)."""
    w1 = float(lane.width.value(np.array([sec_len]))[0])
    fade = min(_ZERO_FADE_M, sec_len)
    faded = add_linear_ramp(lane.width, sec_len - fade, sec_len, 0.0, -w1, sec_len)
    return close_width(lane, sec_len), replace(lane, width=faded)


def _link_first_free(
    i: int, candidates: NDArray[np.bool_], mapping: dict[int, int], used: set[int]
) -> None:
    """Link lane ``i`` after a border to the first lane before it among ``candidates``
    that is not linked yet (``mapping``: after -> before; ``used``: linked befores)."""
    for j in np.flatnonzero(candidates).tolist():
        if j not in used:
            mapping[i] = j
            used.add(j)
            return


def _link_refitted_outer_lanes(
    prev_lanes: tuple[Lane, ...],
    cur_lanes: tuple[Lane, ...],
    b_prev: FloatArray,
    b_cur: FloatArray,
    mapping: dict[int, int],
    used: set[int],
) -> None:
    """Link the driving lanes of the outermost unlinked lanes on both sides of a border
    pairwise when they are the same lanes fitted anew: as many of them, of the same types,
    between an inner border and an outer edge that meet (``_LINK_TOLERANCE_M``; borders
    in metres from the median-side edge). A line between them that the two fits place
    more than ``_WIDTH_JUMP_M`` apart left a driving lane ending at full width where the
    same lane began at full width, a dead end (melbourne-1019-lane1-s21 with a noisier
    sensor: 2.67 m before the border, 4.08 m after it, the edge in place); linked, it
    continues with the width it had (:func:`_link_sections`)."""
    free_prev = [j for j in range(len(prev_lanes)) if j not in used]
    free_cur = [i for i in range(len(cur_lanes)) if i not in mapping]
    if not free_prev or not free_cur:
        return
    j0, i0 = free_prev[0], free_cur[0]
    if free_prev != list(range(j0, len(prev_lanes))) or free_cur != list(range(i0, len(cur_lanes))):
        return
    if len(free_prev) != len(free_cur):
        return
    if abs(b_prev[j0] - b_cur[i0]) > _LINK_TOLERANCE_M or abs(b_prev[-1] - b_cur[-1]) > (
        _LINK_TOLERANCE_M
    ):
        return
    if any(
        prev_lanes[j].type != cur_lanes[i].type for j, i in zip(free_prev, free_cur, strict=True)
    ):
        return
    for j, i in zip(free_prev, free_cur, strict=True):
        if cur_lanes[i].type == "driving":
            mapping[i] = j
            used.add(j)


def _link_split_lanes(
    prev_lanes: tuple[Lane, ...],
    cur_lanes: tuple[Lane, ...],
    b_prev: FloatArray,
    b_cur: FloatArray,
    w_prev: FloatArray,
    mapping: dict[int, int],
    used: set[int],
) -> set[int]:
    """Link a driving lane that ends unlinked at a border where two or more unlinked
    lanes after it span it exactly (its borders met within ``_LINK_TOLERANCE_M``): a line
    first seen inside it there, a new lane's that leaves its inner border (lanes added
    beside the median, the new line's dashes found late). The lane goes on as the widest
    driving one of them; the others open from zero width (returned: their indices), so
    that no border moves at the border. Left as it was, the lane led nowhere and the
    lanes after it began from nothing at 1.3 and 2.1 m (melbourne-408-opp-s4 with a
    noisier sensor, a route failed)."""
    opens: set[int] = set()
    for j in range(len(prev_lanes)):
        if j in used or prev_lanes[j].type != "driving" or w_prev[j] < 0.3:
            continue
        i0 = np.flatnonzero(np.abs(b_cur[:-1] - b_prev[j]) <= _LINK_TOLERANCE_M)
        i1 = np.flatnonzero(np.abs(b_cur[1:] - b_prev[j + 1]) <= _LINK_TOLERANCE_M)
        if not i0.size or not i1.size or i1[0] <= i0[0]:
            continue
        run = range(int(i0[0]), int(i1[0]) + 1)
        if any(i in mapping for i in run):
            continue
        driving = [i for i in run if cur_lanes[i].type == "driving"]
        if not driving:
            continue
        widest = max(driving, key=lambda i: float(b_cur[i + 1] - b_cur[i]))
        mapping[widest] = j
        used.add(j)
        opens.update(i for i in run if i != widest)
    return opens


def _link_sections(
    sections: list[LaneSection],
    bounds_per: list[list[tuple[object, object]]],
    medians: list[tuple[float, float]] | None = None,
    at_step: list[bool] | None = None,
) -> list[LaneSection]:
    """Lane predecessor/successor ids between consecutive sections of the road.

    Chosen by geometry: a lane continues into the lane of the next section whose inner
    and outer borders lie where its own end (within ``_LINK_TOLERANCE_M``, offsets from
    the reference line: the median-side edge ``medians`` (section start, end) plus the
    widths), both wider than 0.3 m there; counting lanes or matching border labels fails
    where a lane begins or ends beside the others, on either side. A shoulder whose width
    jumps at a boundary on an edge step (``at_step``: the hard shoulder at a gore, where
    the old one leaves with the ramp and the new one starts narrow) ends there; a lane that
    begins or ends there other than at a gore opens from (closes to) zero width; every
    other lane whose borders met continues with the width it had (sections are fitted
    one by one: an unlinked shoulder whose width differs by centimetres would move every
    lane beyond it sideways at the boundary).
    """
    if medians is None:
        medians = [(0.0, 0.0)] * len(sections)
    if at_step is None:
        at_step = [True] * len(sections)
    preds: list[dict[int, int]] = [{} for _ in sections]
    succs: list[dict[int, int]] = [{} for _ in sections]
    opens: list[set[int]] = [set() for _ in sections]  # lanes that must open from zero
    for n in range(1, len(sections)):
        prev_lanes, cur_lanes = _side_lanes(sections[n - 1]), _side_lanes(sections[n])
        prev_len = sections[n].s0 - sections[n - 1].s0
        w_prev = np.array([float(ln.width.value(prev_len)) for ln in prev_lanes])
        w_cur = np.array([float(ln.width.value(0.0)) for ln in cur_lanes])
        b_prev = medians[n - 1][1] + np.concatenate([[0.0], np.cumsum(w_prev)])
        b_cur = medians[n][0] + np.concatenate([[0.0], np.cumsum(w_cur)])
        pairs = []
        for i in range(len(cur_lanes)):
            for j in range(len(prev_lanes)):
                if min(w_cur[i], w_prev[j]) < 0.3:
                    continue
                d = max(abs(b_cur[i] - b_prev[j]), abs(b_cur[i + 1] - b_prev[j + 1]))
                if d <= _LINK_TOLERANCE_M:
                    pairs.append((d, i, j))
        mapping: dict[int, int] = {}
        used: set[int] = set()
        for _, i, j in sorted(pairs):
            if i not in mapping and j not in used:
                mapping[i] = j
                used.add(j)
        # driving lanes before the border wide enough to go on
        open_prev = np.array([ln.type == "driving" for ln in prev_lanes]) & (w_prev >= 0.3)
        # a driving lane whose inner border meets one that ends there and whose width
        # differs by less than _WIDTH_JUMP_M is that lane fitted anew (the outer border
        # is a marking seen again after a gap, a gore's section border): it goes on, with
        # the width it had; left unlinked, a car in it had nowhere to go
        for i in range(len(cur_lanes)):
            if i in mapping or cur_lanes[i].type != "driving" or w_cur[i] < 0.3:
                continue
            meets = (np.abs(b_cur[i] - b_prev[:-1]) <= _LINK_TOLERANCE_M) & (
                np.abs(w_cur[i] - w_prev) <= _WIDTH_JUMP_M
            )
            _link_first_free(i, open_prev & meets, mapping, used)
        # ... or whose outer border does, beside a linked lane inside it that took the
        # difference (their common line fitted anew; town06-auto-s3, noisier sensor) or
        # beside shoulders only (the innermost driving lane, whose inner shoulder took it:
        # town06-auto-lane2-s22 with a noisier sensor, an inner shoulder 0 m wide before
        # the border and 0.97 m after it, and the inner lane led nowhere)
        for i in range(1, len(cur_lanes)):
            inside_taken = i - 1 in mapping or all(ln.type != "driving" for ln in cur_lanes[:i])
            if i in mapping or not inside_taken or cur_lanes[i].type != "driving" or w_cur[i] < 0.3:
                continue
            meets = (np.abs(b_cur[i + 1] - b_prev[1:]) <= _LINK_TOLERANCE_M) & (
                np.abs(w_cur[i] - w_prev) <= _WIDTH_JUMP_M
            )
            _link_first_free(i, open_prev & meets, mapping, used)
        # the same where a narrow lane begins on a driving lane's inner side and the two
        # together span the lane that ends there (the median-side shoulder's line first
        # seen there): the lane goes on, and the narrow one opens from zero width below;
        # left unlinked, the innermost lane led nowhere (melbourne-921-s2)
        for i in range(1, len(cur_lanes)):
            if (
                i in mapping
                or i - 1 in mapping
                or cur_lanes[i].type != "driving"
                or w_cur[i] < 0.3
                or w_cur[i - 1] >= _RESIDUAL_WIDTH_M
            ):
                continue
            meets = (np.abs(b_cur[i - 1] - b_prev[:-1]) <= _LINK_TOLERANCE_M) & (
                np.abs(b_cur[i + 1] - b_prev[1:]) <= _LINK_TOLERANCE_M
            )
            _link_first_free(i, open_prev & meets, mapping, used)
        _link_refitted_outer_lanes(prev_lanes, cur_lanes, b_prev, b_cur, mapping, used)
        opens[n] = _link_split_lanes(prev_lanes, cur_lanes, b_prev, b_cur, w_prev, mapping, used)
        for i, j in mapping.items():
            hard_shoulder = (prev_lanes[j].type == "shoulder" and j == len(prev_lanes) - 1) or (
                cur_lanes[i].type == "shoulder" and i == len(cur_lanes) - 1
            )
            if hard_shoulder and at_step[n] and abs(w_prev[j] - w_cur[i]) > 0.05:
                continue
            preds[n][i] = prev_lanes[j].id
            succs[n - 1][j] = cur_lanes[i].id
    out = []
    for n, sec in enumerate(sections):
        lanes = tuple(
            replace(ln, predecessor=preds[n].get(i), successor=succs[n].get(i))
            for i, ln in enumerate(_side_lanes(sec))
        )
        # a lane that begins / ends beside linked ones away from a gore opens from / closes
        # to zero width, so that the lanes beyond it keep their place (a lane born 0.3 m
        # wide moved every lane outside it sideways by 0.3 m at the section border)
        sec_len = (sections[n + 1].s0 if n + 1 < len(sections) else np.inf) - sec.s0
        # the last section: its start (where a lane opening from zero fades in) is checked
        end = sec_len if np.isfinite(sec_len) else _ZERO_FADE_M
        span = np.concatenate(  # densest near the ends, where a closed taper dips
            [
                np.linspace(0.0, end, 400),
                np.linspace(0.0, min(20.0, end), 400),
                np.linspace(max(end - 20.0, 0.0), end, 400),
            ]
        )
        # at a gore too between lanes linked there (a median-side step: a shoulder 34 mm
        # wide began unlinked between linked lanes and moved the outer ones by that,
        # town06-auto-s2 with a noisier sensor); the innermost / outermost lanes at a gore
        # begin and end at full width
        lanes = tuple(
            _nonnegative(_open_from_zero(ln, sec_len), ln, span)
            if n > 0
            and (
                i in opens[n]
                or (
                    (not at_step[n] or _between_linked(lanes, i, "predecessor"))
                    and ln.predecessor is None
                    and preds[n]
                    and abs(float(ln.width.value(np.array([0.0]))[0])) < _RESIDUAL_WIDTH_M
                )
            )
            else ln
            for i, ln in enumerate(lanes)
        )
        if n + 1 < len(sections) and succs[n]:
            lanes = tuple(
                _nonnegative(_close_to_zero(ln, sec_len), ln, span)
                if (not at_step[n + 1] or _between_linked(lanes, i, "successor"))
                and ln.successor is None
                and abs(float(ln.width.value(np.array([sec_len]))[0])) < _RESIDUAL_WIDTH_M
                else ln
                for i, ln in enumerate(lanes)
            )
        if n > 0:
            # linked lanes continue with the width they had (sections are fitted one by
            # one to 1 cm; the checker flags jumps above 1 mm)
            prev_len = sec.s0 - sections[n - 1].s0
            by_id = {ln.id: ln for ln in _side_lanes(out[n - 1])}
            lanes = tuple(
                continue_width(ln, float(by_id[ln.predecessor].width.value(prev_len)))
                if ln.predecessor in by_id
                else ln
                for ln in lanes
            )
        out.append(replace(sec, right=lanes) if sec.right else replace(sec, left=lanes))
    return out
