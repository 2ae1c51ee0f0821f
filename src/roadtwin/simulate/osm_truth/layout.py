"""Lane layout of the mainline along s: which lanes exist where, how wide, which paint.

Everything here is in truth stations ``s`` (metres along the mainline reference line)
and in the side-free lateral coordinate ``u`` (metres from the reference line towards
the outer side: right in right-hand traffic, left in left-hand traffic).

A lane is a *strip*: it exists over ``[s0, s1]``, opens from zero width over ``open_m``
and closes over ``close_m`` (0 = starts/ends at full width, at a gore or the window's
ends), and has a slowly varying full width. Strips are ordered across the road by
``rank``: the inner shoulder, auxiliary lanes of inner-side ramps, the through lanes of
the ``lanes`` tags, auxiliary lanes of outer-side ramps, the hard shoulder. A strip's
``key`` names it wherever it continues (ramp lanes at a gore carry the key of the
mainline lane they continue), so lane links follow from keys.

Lane events (brief): the ``lanes`` tags give the through lanes; a tag drop at an exit is an
exit-only lane (it ends at the gore into the ramp), a gain at an entry a lane that
continues; other tag changes taper (drop) or open (gain). Ramps with more lanes than
that get deceleration / acceleration lanes; an entry followed by an exit on the same
side within ``weave_max_m`` shares one continuous weaving lane.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from .settings import CrossSection, LaneEvents

WidthFn = Callable[[NDArray[np.float64]], NDArray[np.float64]]


@dataclass
class Strip:
    """One lane over ``[s0, s1]`` (see the module docstring)."""

    key: str
    kind: str  # inner | through | aux | hard
    rank: float
    s0: float
    s1: float
    full: WidthFn
    open_m: float = 0.0
    close_m: float = 0.0

    def width(self, s: NDArray[np.float64]) -> NDArray[np.float64]:
        """Width (metres) at stations ``s``; 0 outside ``[s0, s1]``."""
        s = np.asarray(s, dtype=float)
        f = np.ones_like(s)
        if self.open_m > 0:
            f *= _smoothstep((s - self.s0) / self.open_m)
        if self.close_m > 0:
            f *= _smoothstep((self.s1 - s) / self.close_m)
        inside = (s >= self.s0 - 1e-9) & (s <= self.s1 + 1e-9)
        return np.where(inside, f * self.full(s), 0.0)

    @property
    def breaks(self) -> tuple[float, ...]:
        out = [self.s0, self.s1]
        if self.open_m > 0:
            out.append(self.s0 + self.open_m)
        if self.close_m > 0:
            out.append(self.s1 - self.close_m)
        return tuple(out)


def _smoothstep(x: NDArray) -> NDArray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


@dataclass(frozen=True)
class RampEvent:
    """A ramp as the layout sees it: gore station, side, lanes and the OSM tag change it
    explains (``delta`` lanes dropped at an exit / gained at an entry)."""

    index: int
    kind: str  # exit | entry
    side: str  # outer | inner
    station_m: float
    lanes: int


@dataclass(frozen=True)
class RampAttachment:
    """What the ramp road continues at its gore: the mainline strip keys of its driving
    lanes (inner to outer in the mainline's u), the shoulder strip it continues, and the
    key of the shoulder that opens (exit) / closes (entry) on the ramp's other side."""

    event: RampEvent
    lane_keys: tuple[str, ...]
    shoulder_key: str


@dataclass
class Layout:
    """All strips of the mainline, the section breaks and the ramps' attachments."""

    length_m: float
    strips: list[Strip]
    attachments: dict[int, RampAttachment]
    inner_shoulder_m: float
    anchor_rank: float
    """Strips ranked below this are stacked from the median edge inwards: inner-side lane
    events move the median edge (OpenDRIVE lane offset), never the lanes beyond it."""
    notes: list[str] = field(default_factory=list)

    def alive(self, a: float, b: float) -> list[Strip]:
        """Strips present (with width) inside ``(a, b)``, ordered inner to outer."""
        m = 0.5 * (a + b)
        return sorted(
            (x for x in self.strips if x.s0 <= m <= x.s1 and x.s0 < b - 1e-9 and x.s1 > a + 1e-9),
            key=lambda x: x.rank,
        )

    def breaks(self, extra: tuple[float, ...] = ()) -> list[float]:
        """Sorted section breaks in ``[0, length]`` (merged within 1 mm)."""
        raw = sorted({round(b, 6) for x in self.strips for b in x.breaks} | set(extra))
        out: list[float] = []
        for b in raw:
            b = min(max(b, 0.0), self.length_m)
            if not out or b - out[-1] > 1e-3:
                out.append(b)
        if out[0] > 0.0:
            out.insert(0, 0.0)
        if self.length_m - out[-1] > 1e-3:
            out.append(self.length_m)
        else:
            out[-1] = self.length_m
        return out

    def u_inner_edge(self, s: NDArray, strips: list[Strip] | None = None) -> NDArray:
        """u of the median-side road edge (0 where the inner shoulder is nominal).

        ``strips`` restricts the sum to the lanes of one section (at a gore a lane that
        ends there and one that starts there share the station)."""
        s = np.asarray(s, dtype=float)
        pool = self.strips if strips is None else strips
        left = sum((x.width(s) for x in pool if x.rank < self.anchor_rank), np.zeros_like(s))
        return self.inner_shoulder_m - left

    def u_border(self, s: NDArray, rank_below: float) -> NDArray:
        """u of the border below which lie the strips ranked under ``rank_below``."""
        s = np.asarray(s, dtype=float)
        acc = sum((x.width(s) for x in self.strips if x.rank < rank_below), np.zeros_like(s))
        return self.u_inner_edge(s) + acc


def wander(rng: np.random.Generator, amplitude: float, wavelengths: tuple[float, float]) -> WidthFn:
    """A smooth random function of s with zero mean and about ``amplitude`` peak: three
    sines of random wavelength and phase."""
    lam = rng.uniform(*wavelengths, size=3)
    ph = rng.uniform(0.0, 2 * math.pi, size=3)
    amp = amplitude * rng.uniform(0.5, 1.0, size=3) / 2.0

    def fn(s: NDArray) -> NDArray:
        s = np.asarray(s, dtype=float)
        return sum(
            a * np.sin(2 * math.pi * s / w + p) for a, w, p in zip(amp, lam, ph, strict=True)
        )

    return fn


def _width_fn(base: float, var: WidthFn, lo: float, hi: float) -> WidthFn:
    def fn(s: NDArray) -> NDArray:
        return np.clip(base + var(s), lo, hi)

    return fn


def build_layout(
    length_m: float,
    tag_segments: list[tuple[float, float, int]],
    ramps: list[RampEvent],
    *,
    lane_width_m: float,
    ramp_lane_width_m: float,
    inner_shoulder_m: float,
    hard_shoulder_m: float,
    cross: CrossSection,
    events: LaneEvents,
    rng: np.random.Generator,
) -> Layout:
    """Strips of the whole mainline from the tagged lane counts and the ramps.

    ``tag_segments`` are ``(s_start, s_end, lanes)`` in truth stations covering
    ``[0, length_m]``; ``ramps`` sorted by station.
    """
    L = length_m
    lo_w, hi_w = cross.min_lane_width_m, cross.max_lane_width_m
    counter = itertools.count()
    strips: list[Strip] = []
    notes: list[str] = []

    def lane_fn() -> WidthFn:
        base = float(np.clip(lane_width_m - rng.uniform(0.0, 0.15), lo_w, hi_w))
        return _width_fn(
            base, wander(rng, cross.width_wander_m, cross.wander_wavelength_m), lo_w, hi_w
        )

    def aux_fn() -> WidthFn:
        base = float(np.clip(ramp_lane_width_m, lo_w, hi_w))
        return _width_fn(
            base, wander(rng, cross.width_wander_m, cross.wander_wavelength_m), lo_w, hi_w
        )

    segs = _merged_segments(
        tag_segments,
        events.min_tag_segment_m,
        gores=[r.station_m for r in ramps],
        snap_m=events.event_snap_m,
    )

    # ----- through lanes from the tags -------------------------------------------------
    n0 = int(segs[0][2])
    active: list[Strip] = []
    for k in range(n0):
        st = Strip(f"T{next(counter)}", "through", float(k), 0.0, L, lane_fn())
        active.append(st)
        strips.append(st)
    used_ramps: dict[int, int] = {}  # ramp index -> lanes it dropped/gained
    inner_touched: set[str] = set()
    for seg_prev, seg in itertools.pairwise(segs):
        c = float(seg[0])
        n1, n2 = int(seg_prev[2]), int(seg[2])
        delta = n2 - n1
        kind = "entry" if delta > 0 else "exit"
        near = [
            r
            for r in ramps
            if r.kind == kind
            and abs(r.station_m - c) <= events.event_snap_m
            and r.index not in used_ramps
        ]
        ramp = min(near, key=lambda r: abs(r.station_m - c)) if near else None
        side = ramp.side if ramp is not None else "outer"
        active.sort(key=lambda x: x.rank)
        if delta < 0:
            k = -delta
            gone = active[-k:] if side == "outer" else active[:k]
            if ramp is not None:
                used_ramps[ramp.index] = k
                n_taper = max(k - ramp.lanes, 0)
                for j, st in enumerate(gone):
                    inner_most = j < n_taper if side == "outer" else j >= k - n_taper
                    if inner_most:  # more lanes end than the ramp has: they merge first
                        st.s1 = max(ramp.station_m - 10.0, st.s0 + 1.0)
                        st.close_m = min(events.drop_taper_m, st.s1 - st.s0)
                    else:
                        st.s1 = ramp.station_m
                        st.close_m = 0.0
            else:
                for st in gone:
                    st.s1 = c
                    st.close_m = min(events.drop_taper_m, c - st.s0)
            for st in gone:
                active.remove(st)
                if side == "inner":
                    inner_touched.add(st.key)
        else:
            ranks = [x.rank for x in active]
            start = ramp.station_m if ramp is not None else c
            for j in range(delta):
                rank = (max(ranks) + 1 + j) if side == "outer" else (min(ranks) - 1 - j)
                st = Strip(f"T{next(counter)}", "through", rank, start, L, lane_fn())
                if ramp is None or j >= ramp.lanes:
                    st.open_m = min(events.gain_taper_m, L - start)
                active.append(st)
                strips.append(st)
                if side == "inner":
                    inner_touched.add(st.key)
            if ramp is not None:
                used_ramps[ramp.index] = delta

    # ----- auxiliary lanes -------------------------------------------------------------
    attachments: dict[int, RampAttachment] = {}
    exit_lanes: dict[int, list[Strip]] = {}
    entry_lanes: dict[int, list[Strip]] = {}
    for r in ramps:
        taken = used_ramps.get(r.index, 0)
        extra = r.lanes - taken
        if extra <= 0:
            continue
        sgn = 1.0 if r.side == "outer" else -1.0
        new = []
        for j in range(extra):
            rank = sgn * (1000.0 + r.station_m / 1e5 + (j if r.kind == "exit" else -j) * 1e-3)
            if r.kind == "exit":
                s0 = max(r.station_m - events.decel_length_m, 0.0)
                st = Strip(
                    f"X{r.index}.{j}",
                    "aux",
                    rank,
                    s0,
                    r.station_m,
                    aux_fn(),
                    open_m=min(events.decel_taper_m, r.station_m - s0) if s0 > 0 else 0.0,
                )
            else:
                s1 = min(r.station_m + events.accel_length_m, L)
                st = Strip(
                    f"E{r.index}.{j}",
                    "aux",
                    rank,
                    r.station_m,
                    s1,
                    aux_fn(),
                    close_m=min(events.accel_taper_m, s1 - r.station_m) if s1 < L else 0.0,
                )
            new.append(st)
            strips.append(st)
        (exit_lanes if r.kind == "exit" else entry_lanes)[r.index] = new
    # weaving: an entry and the next ramp on its side, an exit within weave_max_m
    for side in ("outer", "inner"):
        seq = [r for r in ramps if r.side == side]
        for e, x in itertools.pairwise(seq):
            if e.kind != "entry" or x.kind != "exit":
                continue
            if x.station_m - e.station_m > events.weave_max_m:
                continue
            acc, dec = entry_lanes.get(e.index, []), exit_lanes.get(x.index, [])
            for a_st, d_st in zip(acc, dec, strict=False):
                # one lane from the entry gore to the exit gore
                a_st.s1, a_st.close_m = x.station_m, 0.0
                d_st.s0 = a_st.s1  # degenerate: removed below
                a_st.key = f"W{e.index}-{x.index}"
                d_st.key = a_st.key
                strips.remove(d_st)
                dec[dec.index(d_st)] = a_st
            exit_lanes[x.index] = dec
            if acc and dec:
                notes.append(f"weaving lane {e.station_m:.0f}-{x.station_m:.0f} m ({side})")

    # ----- shoulders -------------------------------------------------------------------
    inner_var = _width_fn(inner_shoulder_m, lambda s: np.zeros_like(s), 0.0, 10.0)
    hard_var = wander(rng, cross.shoulder_wander_m, cross.wander_wavelength_m)
    hard_fn = _width_fn(hard_shoulder_m, hard_var, 0.5, hard_shoulder_m + 1.0)
    gst = events.gore_shoulder_taper_m
    shoulder_breaks: dict[str, list[tuple[float, str]]] = {"inner": [], "hard": []}
    for r in ramps:
        which = "hard" if r.side == "outer" else "inner"
        shoulder_breaks[which].append((r.station_m, r.kind))
    # hard shoulder missing on a few stretches away from the ramps
    busy = sorted({r.station_m for r in ramps})
    n_gaps = int(rng.integers(cross.shoulder_gaps[0], cross.shoulder_gaps[1] + 1))
    gaps: list[tuple[float, float]] = []
    for _ in range(n_gaps):
        glen = float(rng.uniform(*cross.shoulder_gap_length_m))
        a = float(rng.uniform(150.0, max(L - glen - 150.0, 151.0)))
        b = a + glen
        clear = all(x < a - 500.0 or x > b + 400.0 for x in busy)
        overlap = any(not (b + 200 < g0 or a - 200 > g1) for g0, g1 in gaps)
        if clear and not overlap and b < L - 150.0:
            gaps.append((a, b))
    keys_at: dict[str, dict[float, str]] = {"inner": {}, "hard": {}}
    for which, rank, fn in (("inner", -1e6, inner_var), ("hard", 1e6, hard_fn)):
        cuts = sorted(shoulder_breaks[which])
        pieces: list[Strip] = []
        cur = Strip(f"{which}0", which, rank, 0.0, L, fn)
        pieces.append(cur)
        for g, kind in cuts:
            nxt = Strip(f"{which}{len(pieces)}", which, rank, g, L, fn)
            cur.s1 = g
            if kind == "entry":  # closes before the gore; the ramp's shoulder continues
                cur.close_m = min(gst, g - cur.s0) if g - cur.s0 > 1.0 else 0.0
                keys_at[which][g] = nxt.key
            else:  # continues into the ramp; a new one opens after the gore
                nxt.open_m = min(gst, L - g)
                keys_at[which][g] = cur.key
            pieces.append(nxt)
            cur = nxt
        if which == "hard":
            for a, b in gaps:
                for p in pieces:
                    if p.s0 + 1 < a and b < p.s1 - 1:
                        tail = Strip(
                            f"hard{len(pieces)}",
                            "hard",
                            rank,
                            b,
                            p.s1,
                            fn,
                            open_m=cross.shoulder_taper_m,
                            close_m=p.close_m,
                        )
                        p.s1, p.close_m = a, cross.shoulder_taper_m
                        pieces.append(tail)
                        break
            if gaps:
                notes.append(
                    "hard shoulder missing at " + ", ".join(f"{a:.0f}-{b:.0f} m" for a, b in gaps)
                )
        strips.extend(p for p in pieces if p.s1 - p.s0 > 1e-3)
        # keys of shoulders whose stretch was renamed by a gap stay valid (keys are unique)

    # ----- attachments -----------------------------------------------------------------
    for r in ramps:
        g = r.station_m
        side_strips = [x for x in strips if x.kind in ("through", "aux")]
        if r.kind == "exit":
            ending = [x for x in side_strips if abs(x.s1 - g) < 1e-6 and x.close_m == 0.0]
        else:
            ending = [x for x in side_strips if abs(x.s0 - g) < 1e-6 and x.open_m == 0.0]
        ending.sort(key=lambda x: x.rank)
        which = "hard" if r.side == "outer" else "inner"
        keys = tuple(dict.fromkeys(x.key for x in ending))
        if len(keys) != r.lanes:
            notes.append(f"{r.kind} at {g:.0f} m: {len(keys)} lanes attach, ramp has {r.lanes}")
        attachments[r.index] = RampAttachment(r, keys, keys_at[which].get(g, ""))
    through = [x for x in strips if x.kind == "through"]
    kept = [x.rank for x in through if x.key not in inner_touched]
    anchor = min(kept) if kept else max(x.rank for x in through) + 0.5
    return Layout(L, strips, attachments, inner_shoulder_m, anchor, notes)


def _merged_segments(
    tag_segments: list[tuple[float, float, int]],
    min_length_m: float,
    *,
    gores: Sequence[float] = (),
    snap_m: float = 0.0,
) -> list[list[float]]:
    """``[s0, s1, lanes]`` runs of equal lane counts; an inner run shorter than
    ``min_length_m`` takes the count of its longer neighbour (shortest first), unless one
    of its ends lies within ``snap_m`` of a ramp's gore station (``gores``): a lane added
    just before an exit that takes it is real."""
    g = np.asarray(sorted(gores), dtype=float)

    def at_gore(x: float) -> bool:
        return bool(g.size) and float(np.min(np.abs(g - x))) <= snap_m

    def merge(segments) -> list[list[float]]:
        out: list[list[float]] = []
        for a, b, n in segments:
            if out and out[-1][2] == n:
                out[-1][1] = b
            else:
                out.append([a, b, n])
        return out

    segs = merge(tag_segments)
    while len(segs) > 2:
        inner = [
            i
            for i in range(1, len(segs) - 1)
            if segs[i][1] - segs[i][0] < min_length_m
            and not (at_gore(segs[i][0]) or at_gore(segs[i][1]))
        ]
        if not inner:
            break
        k = min(inner, key=lambda i: segs[i][1] - segs[i][0])
        before, after = segs[k - 1], segs[k + 1]
        longer = before if before[1] - before[0] >= after[1] - after[0] else after
        segs[k][2] = longer[2]
        segs = merge(segs)
    return segs


def tag_segments_from_chain(
    s_nodes: NDArray[np.float64], seg_lanes: NDArray[np.int64], length_m: float
) -> list[tuple[float, float, int]]:
    """``(s0, s1, lanes)`` segments in truth stations from the chain vertices' truth
    stations (monotone) and each segment's tagged lane count."""
    out: list[tuple[float, float, int]] = []
    s = np.clip(np.maximum.accumulate(s_nodes), 0.0, length_m)
    s[0], s[-1] = 0.0, length_m
    for a, b, n in zip(s[:-1], s[1:], seg_lanes, strict=True):
        if b - a <= 1e-6:
            continue
        out.append((float(a), float(b), int(n)))
    return out


def lane_count_at(
    layout: Layout,
    s: NDArray,
    *,
    min_width_m: float = 2.5,
    kinds: tuple[str, ...] = ("through", "aux"),
) -> NDArray[np.int64]:
    """Number of lanes of ``kinds`` wider than ``min_width_m`` at each station."""
    s = np.asarray(s, dtype=float)
    out = np.zeros(s.shape, np.int64)
    for x in layout.strips:
        if x.kind in kinds:
            out += (x.width(s) > min_width_m).astype(np.int64)
    return out
