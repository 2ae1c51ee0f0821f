"""Gore stations hidden from the outer-edge points, from two independent cues.

Where a vehicle hides the outer road edge at an entry or exit gore, the edge step that
normally pins the gore (:func:`roadtwin.mainline.outer_edge.fit_outer_edge`) is not seen, and a
ramp line that joins or leaves the mainline tangentially only bounds it from one side. Two
other observations place it:

1. **The mainline's outer marking changes type at the gore.** Beside an acceleration
   (deceleration) lane the outer marking of the through lanes is broken; upstream of an
   entry (downstream of an exit) gore it is the solid edge line. Where the solid line ends
   inside a dash gap the gore is exactly there; where it runs on into a dash, the gore lies
   within that dash. :func:`marking_gore_interval` returns that interval from the lane
   samples of the through marking (metres along the reference line).
2. **The hard shoulder tapers to zero width at the gore.** Upstream of an entry gore the
   shoulder narrows from its full width to zero at the gore (downstream of an exit gore it
   widens from zero). :func:`fit_shoulder_taper` fits a cubic taper (the shape of an
   OpenDRIVE width polynomial with zero slope at both ends) to the shoulder widths that
   were seen before the occlusion.

:func:`fuse_gore_estimates` combines them: the marking interval bounds the gore, the taper
fit (or the interval's middle) chooses inside it. All stations and offsets are in the
reference line's frame: ``s`` metres along it, ``d`` metres from the reference edge
towards the carriageway.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

_MIN_RUN_SAMPLES = 3
"""Runs of fewer marking samples are stray detections, not dashes."""


@dataclass(frozen=True)
class ShoulderTaper:
    """A hard shoulder that tapers between zero and full width at a gore.

    Attributes
    ----------
    s_gore : station where the shoulder has zero width (the gore), metres.
    length_m : taper length, metres (the full width is reached ``length_m`` upstream of an
        entry gore, downstream of an exit gore).
    width_m : full shoulder width, metres.
    entry : True upstream of an entry gore (narrowing), False downstream of an exit gore.
    rms_m : RMS residual of the fit, metres.
    """

    s_gore: float
    length_m: float
    width_m: float
    entry: bool
    rms_m: float

    def width(self, s: FloatArray) -> FloatArray:
        """Shoulder width (metres) at stations ``s`` (metres)."""
        s = np.asarray(s, dtype=float)
        return taper_width(s, self.width_m, self.s_gore, self.length_m, self.entry)


def smoothstep(x: FloatArray) -> FloatArray:
    """Cubic 0 -> 1 over ``x`` in [0, 1] with zero slope at both ends (clipped outside)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def taper_width(
    s: FloatArray, width: float, s_gore: float, length: float, entry: bool
) -> FloatArray:
    """Width (metres) of a cubic taper at stations ``s``: 0 at ``s_gore``, ``width`` from
    ``length`` upstream (``entry``: it closes at ``s_gore``) or downstream (it opens)."""
    x = (s_gore - s) / length if entry else (s - s_gore) / length
    return width * smoothstep(x)


def _runs(
    s_sorted: FloatArray, seen_s: FloatArray | None = None
) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """Runs of consecutive samples along a marking: starts, ends (half a sample spacing
    beyond the first/last sample) and sample counts.

    With ``seen_s`` (sorted stations of every lane sample of the run, all markings), a gap
    where the sensor saw no marking at all (missing frames) does not split a run: only a
    gap in this marking while others were seen is a gap of the marking.
    """
    spacing = float(np.median(np.diff(s_sorted)))
    gap = np.diff(s_sorted) > max(1.5, 5.0 * spacing)
    if seen_s is not None and seen_s.size:
        i_gap = np.flatnonzero(gap)
        lo = np.searchsorted(seen_s, s_sorted[i_gap] + 0.5 * spacing, side="right")
        hi = np.searchsorted(seen_s, s_sorted[i_gap + 1] - 0.5 * spacing, side="left")
        gap[i_gap[hi - lo < _MIN_RUN_SAMPLES]] = False
    split = np.flatnonzero(gap)
    first = np.concatenate([[0], split + 1])
    last = np.concatenate([split, [s_sorted.size - 1]])
    return (
        s_sorted[first] - 0.5 * spacing,
        s_sorted[last] + 0.5 * spacing,
        (last - first + 1).astype(np.int64),
    )


def marking_gore_interval(
    s_samples: FloatArray,
    s_guess: float,
    *,
    entry: bool,
    search_m: float = 30.0,
    min_solid_m: float = 20.0,
    max_dash_m: float = 15.0,
    seen_s: FloatArray | None = None,
) -> tuple[float, float] | None:
    """Interval of gore stations allowed by the solid/broken change of a through marking.

    Parameters
    ----------
    s_samples
        Stations (metres) of the lane samples of the through lanes' outer marking.
    s_guess
        Approximate gore station (metres); the solid line must end (entry) or start (exit)
        within ``search_m`` of it.
    entry
        True for an entry gore (solid upstream, broken downstream), False for an exit.
    min_solid_m, max_dash_m
        Shortest solid run and longest dash (metres).
    seen_s
        Sorted stations (metres) of all lane samples of the run: gaps where no marking was
        seen (frames missing) are not dash gaps.

    Returns
    -------
    ``(lo, hi)`` in metres, ``lo == hi`` when the gore is pinned (the solid line ends in a
    dash gap), or None when the marking does not show the change (solid or broken on both
    sides, too few dashes, an irregular pattern).
    """
    ss = np.sort(np.asarray(s_samples, dtype=float))
    ss = ss[np.abs(ss - s_guess) < 120.0]
    if ss.size < 20:
        return None
    seen = None
    if seen_s is not None:
        seen_s = np.asarray(seen_s, dtype=float)
        seen = seen_s[np.abs(seen_s - s_guess) < 130.0]
    start, end, count = _runs(ss, seen)
    keep = count >= _MIN_RUN_SAMPLES
    start, end = start[keep], end[keep]
    length = end - start
    # the solid line's end (entry) / start (exit) next to the guess
    tip = end if entry else start
    solid = np.flatnonzero((length >= min_solid_m) & (np.abs(tip - s_guess) < search_m))
    if solid.size == 0:
        return None
    i = int(solid[np.argmin(np.abs(tip[solid] - s_guess))])
    # the dashes on the broken side, nearest first, up to the next long run
    side = np.arange(i + 1, start.size) if entry else np.arange(i - 1, -1, -1)
    long_run = np.flatnonzero(length[side] > max_dash_m)
    dashes = side[: long_run[0]] if long_run.size else side
    dashes = dashes[:6]
    if dashes.size < 3:
        return None
    dash = float(np.median(length[dashes]))
    period = float(np.median(np.abs(np.diff(start[dashes]))))
    if not (0.1 * period < dash < 0.9 * period) or np.ptp(length[dashes]) > 0.5 * dash:
        return None
    # the dash next to the solid line must fit the pattern: a hole in the solid line
    # (samples missing there) makes a "dash" of its tail, longer or out of phase
    first, second = int(dashes[0]), int(dashes[1])
    phase = start[second] - period if entry else start[second] + period
    if abs(length[first] - dash) > max(0.6, 0.15 * dash) or abs(start[first] - phase) > max(
        0.6, 0.1 * period
    ):
        return None
    gap = period - dash
    tol = max(1.0, 0.3 * gap)
    if entry:
        seen_gap = float(start[dashes[0]] - end[i])
        if seen_gap < gap - tol:  # the solid line stops inside a gap: the gore
            return float(end[i]), float(end[i])
        return float(start[dashes[0]] - period), float(end[i])
    seen_gap = float(start[i] - end[dashes[0]])
    if seen_gap < gap - tol:
        return float(start[i]), float(start[i])
    return float(start[i]), float(end[dashes[0]] + period)


def fit_shoulder_taper(
    s: FloatArray, width: FloatArray, *, entry: bool, max_rms_m: float = 0.15
) -> ShoulderTaper | None:
    """Fit a cubic shoulder taper to shoulder widths seen on one side of a gore.

    Parameters
    ----------
    s, width
        Stations and hard-shoulder widths (outer edge minus outermost marking), metres,
        upstream of an entry gore (``entry``) or downstream of an exit gore.
    max_rms_m
        Fits with a larger RMS residual are rejected.

    Returns
    -------
    The taper, or None unless the shoulder was seen narrowing to at most 85 % of its full
    width (a taper seen only at its flat start does not say where it ends).
    """
    from scipy.optimize import least_squares

    s = np.asarray(s, dtype=float)
    width = np.asarray(width, dtype=float)
    ok = np.isfinite(s) & np.isfinite(width)
    s, width = s[ok], width[ok]
    if s.size < 30:
        return None
    order = np.argsort(s)
    s, width = s[order], width[order]
    far = width[: max(10, s.size // 5)] if entry else width[-max(10, s.size // 5) :]
    full = float(np.median(far))
    near = width[-10:] if entry else width[:10]
    if full < 0.5 or float(np.median(near)) > 0.85 * full:
        return None
    low = np.flatnonzero(width < 0.85 * full)
    s_low = float(s[low[0]] if entry else s[low[-1]])
    tip = float(s[-1] if entry else s[0])
    # start: the taper's full-width end at the first narrowing point, gore beyond the last
    # point seen
    length0 = max(2.0 * abs(tip - s_low), 20.0)
    gore0 = s_low + length0 if entry else s_low - length0

    def residual(p: FloatArray) -> FloatArray:
        return width - taper_width(s, p[0], p[1], max(p[2], 1.0), entry)

    res = least_squares(
        residual,
        np.array([full, gore0, length0]),
        loss="soft_l1",
        f_scale=0.05,
        x_scale=np.array([1.0, 10.0, 10.0]),
    )
    w_fit, s_gore, length = (float(v) for v in res.x)
    rms = float(np.sqrt(np.mean(residual(res.x) ** 2)))
    beyond = s_gore >= tip - 1.0 if entry else s_gore <= tip + 1.0
    if not (0.5 < w_fit < 8.0 and 5.0 <= length <= 400.0 and rms <= max_rms_m and beyond):
        return None
    return ShoulderTaper(s_gore, length, w_fit, entry, rms)


def fuse_gore_estimates(
    interval: tuple[float, float] | None, taper: ShoulderTaper | None, s_guess: float
) -> float:
    """Gore station (metres) from the marking interval and the shoulder taper.

    The marking interval bounds the gore; inside it the taper decides, else the middle of
    the interval (the least worst case). Without an interval the taper decides, else the
    guess stands.
    """
    if interval is not None:
        lo, hi = interval
        inside = taper.s_gore if taper is not None else 0.5 * (lo + hi)
        return float(np.clip(inside, lo, hi))
    if taper is not None:
        return taper.s_gore
    return s_guess
