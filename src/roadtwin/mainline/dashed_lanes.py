"""A lane hidden beside a broken outermost line: where the outer edge goes unseen and the
outermost marking seen through the gap turns from the solid edge line into a broken line
and back, a lane lies beyond it over that broken stretch.

An entry's acceleration lane (an exit's deceleration lane) can lie wholly inside an
occlusion gap of the outer edge with its own outer line unpainted or unseen: the edge is
at the same level on both sides of the gap and nothing steps. What was seen is the line
between the through lanes and that lane: beside the lane it is broken (a lane line), next
to it the solid edge line. Bridged straight across, the edge ran along that line and the
lane was missing over 100 m (soderleden-s2 with a noisier sensor: 3.5 m off); bridged
linearly from the lane seen before the gap to the line the edge meets after it, the lane
narrowed over the whole gap instead of at its end taper (soderleden-s2 +440: 2.4 m off).

The stretch's end where a ramp's edge or lines were seen beyond the line is the gore (the
lane begins there at full width after an entry's, ends there at full width before an
exit's); the other end is the lane's taper, which ends where the broken line ends. Stations
``s`` and offsets ``d`` are metres in the reference line's frame (``d`` from the reference
edge towards the carriageway, :func:`~.lanes.fit_lanes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ._common import true_runs
from .gores import _runs, taper_width
from .markings import _last_marking, _Track

FloatArray = NDArray[np.float64]

__all__ = ["DashedLane", "dashed_lane_gores", "dashed_lanes_in_gaps", "widen_beside_dashed"]

_GAP_MIN_M = 30.0  # occlusion gaps of the edge at least this long are looked at (metres)
_END_NEAR_M = 20.0  # ... with an end of a broken stretch inside or this near them (metres)
_OUTERMOST_M = 0.3  # a track this near the outermost marking is the outermost one
_OUTERMOST_SHARE = 0.8  # ... at this share of the gap's stations where it runs
_DASH_MAX_M = 15.0  # a run of samples at most this long is a dash (metres) ...
_DASH_MIN_M = 0.5  # ... and at least this long
_SOLID_MIN_M = 20.0  # a run at least this long is a solid line (metres)
_MIN_DASHES = 3  # a broken stretch has this many dashes at least
_PERIOD_RANGE_M = (4.0, 40.0)  # a dash period (dash plus gap) lies in this range (metres)
_PERIOD_SPREAD = 0.3  # the periods of a stretch lie this near their median (fraction) ...
_MISSED_DASHES = 2  # ... or at a whole multiple of it up to this (dashes not seen)
_JOIN_PERIODS = 1.5  # a solid line ending this near the first dash (periods) ends the stretch
_LANE_SEEN_SLACK_M = 0.5  # beside a broken line seen at a gap's end the strip is this near a lane
_EVIDENCE_M = 100.0  # a ramp's points this far outside the stretch's end tell the gore (m)
_EVIDENCE_BEYOND_M = (1.0, 30.0)  # ... lying this far beyond the line (metres)
_EVIDENCE_MIN = 10  # ... this many at least
_EVIDENCE_RATIO = 3.0  # ... and this many times those at the other end
_TAPER_RANGE_M = (10.0, 150.0)  # a lane's end taper fitted to the seen width: its range


@dataclass(frozen=True, eq=False)
class DashedLane:
    """A lane beside the outermost marking over a broken stretch of it.

    Attributes
    ----------
    start, end : the broken stretch (stations, metres): from the end of the solid line
        before it (or its first dash) to the end of its last dash.
    gore_at_start : True for an entry's lane (it begins at full width at ``start``), False
        for an exit's (it ends at full width at ``end``), None when no ramp was seen at
        either end (it tapers at both).
    width_m : the lane's width (metres).
    taper_m : length of its taper(s) (metres).
    line_s, line_d : the broken line's course (stations and offsets, metres).
    gap : the occlusion gap of the edge it was found in (first and last unseen station,
        metres): the edge is widened there only.
    """

    start: float
    end: float
    gore_at_start: bool | None
    width_m: float
    taper_m: float
    line_s: FloatArray
    line_d: FloatArray
    gap: tuple[float, float]

    @property
    def gore(self) -> float | None:
        """The gore's station (metres), None if no end is one."""
        if self.gore_at_start is None:
            return None
        return self.start if self.gore_at_start else self.end

    def width(self, s: FloatArray) -> FloatArray:
        """The lane's width (metres) at stations ``s`` (metres): zero outside the stretch,
        tapering at the end(s) that are not the gore."""
        s = np.asarray(s, dtype=float)
        w = np.where((s >= self.start) & (s <= self.end), self.width_m, 0.0)
        if self.gore_at_start is not True:  # tapers open from the stretch's start
            w = np.minimum(w, taper_width(s, self.width_m, self.start, self.taper_m, entry=False))
        if self.gore_at_start is not False:  # ... and close to its end
            w = np.minimum(w, taper_width(s, self.width_m, self.end, self.taper_m, entry=True))
        return w


def broken_stretches(s_samples: FloatArray) -> list[tuple[float, float]]:
    """The broken stretches of one marking (stations, metres).

    A stretch is a chain of at least ``_MIN_DASHES`` dashes (sample runs
    ``_DASH_MIN_M``-``_DASH_MAX_M`` long) at a regular period (dashes the sensor missed
    leave a whole multiple of it). It begins at the end of a solid run (``_SOLID_MIN_M``)
    that stops within ``_JOIN_PERIODS`` periods before its first dash, less half a dash
    (the solid line may have run on into a dash), else at that dash; it ends at the end of
    its last dash, or half a dash into a solid run that begins right after it. Frames the
    sensor missed are not told from dash gaps (the other lines are broken too, and sparse):
    they break a pattern's regularity.
    """
    ss = np.sort(np.asarray(s_samples, dtype=float))
    if ss.size < 10:
        return []
    start, end, count = _runs(ss)
    keep = count >= 3
    start, end = start[keep], end[keep]
    length = end - start
    dash = (length >= _DASH_MIN_M) & (length <= _DASH_MAX_M)
    out: list[tuple[float, float]] = []
    for a, b in true_runs(dash):
        if b - a < _MIN_DASHES:
            continue
        period = np.diff(start[a:b])
        p0 = float(np.median(period))
        if not (_PERIOD_RANGE_M[0] <= p0 <= _PERIOD_RANGE_M[1]):
            continue
        multiple = np.round(period / p0)
        regular = (multiple >= 1) & (multiple <= _MISSED_DASHES)
        regular &= np.abs(period - multiple * p0) <= _PERIOD_SPREAD * p0
        if not np.all(regular):
            continue
        lo, hi = float(start[a]), float(end[b - 1])
        # a solid line that stops a dash gap before the first dash may have run into a
        # dash of the pattern (painted without a gap): the change lies within that dash
        half_dash = 0.5 * float(np.median(length[a:b]))
        if a > 0 and length[a - 1] >= _SOLID_MIN_M and lo - end[a - 1] <= _JOIN_PERIODS * p0:
            lo = float(end[a - 1]) - half_dash
        solid_after = b < length.size and length[b] >= _SOLID_MIN_M
        if solid_after and start[b] - hi <= _JOIN_PERIODS * p0:
            hi = float(start[b]) + half_dash
        out.append((lo, hi))
    return out


def _outermost_tracks(
    tracks: list[_Track], grid: FloatArray, d_last: FloatArray, a: int, b: int
) -> list[int]:
    """Indices of the tracks that are the outermost marking (``d_last`` on ``grid``,
    :func:`~.markings._last_marking`) over the gap ``a:b`` where they run there."""
    out = []
    for k, tr in enumerate(tracks):
        g = grid[a:b]
        sel = (g >= tr.lo) & (g <= tr.hi)
        if np.count_nonzero(sel) < 10:
            continue
        near = np.interp(g[sel], tr.s, tr.d) >= d_last[a:b][sel] - _OUTERMOST_M
        if np.mean(near) >= _OUTERMOST_SHARE:
            out.append(k)
    return out


def _gore_at_start(
    start: float, end: float, line: _Track, points: tuple[FloatArray, FloatArray]
) -> bool | None:
    """Which end of the stretch is the gore: the one with a ramp's points (outer-edge
    points not the mainline's, lane samples beyond the mainline's edge) seen beyond the
    line just outside it; None if neither clearly."""
    s, d = points
    d_line = np.interp(s, line.s, line.d)
    beyond = (d > d_line + _EVIDENCE_BEYOND_M[0]) & (d < d_line + _EVIDENCE_BEYOND_M[1])
    before = int(np.count_nonzero(beyond & (s > start - _EVIDENCE_M) & (s < start)))
    after = int(np.count_nonzero(beyond & (s > end) & (s < end + _EVIDENCE_M)))
    if before >= _EVIDENCE_MIN and before >= _EVIDENCE_RATIO * after:
        return True
    if after >= _EVIDENCE_MIN and after >= _EVIDENCE_RATIO * before:
        return False
    return None


def _taper_through(width: float, distance: float, seen: float, default: float) -> float:
    """Length (metres) of a cubic taper of a lane ``width`` wide (metres) that has ``seen``
    width (metres) ``distance`` metres from its zero end; ``default`` if that says nothing
    (the seen width full or none)."""
    if not (0.05 * width < seen < 0.95 * width) or distance <= 0.0:
        return default
    # the cubic 3x^2 - 2x^3 = seen / width solved on [0, 1]
    x = 0.5 - math.sin(math.asin(1.0 - 2.0 * seen / width) / 3.0)
    return float(np.clip(distance / x, *_TAPER_RANGE_M))


def dashed_lanes_in_gaps(
    tracks: list[_Track],
    grid: FloatArray,
    d_edge: FloatArray,
    covered: NDArray[np.bool_],
    lane_m: float,
    taper_m: float,
    ramp_points: tuple[FloatArray, FloatArray],
) -> list[DashedLane]:
    """The lanes beside a broken outermost marking in occlusion gaps of the outer edge.

    Parameters
    ----------
    tracks, grid
        Marking tracks and the station grid (metres).
    d_edge, covered
        The outer edge on the grid (metres) and where it was seen.
    lane_m
        The run's typical lane width (metres): the lane's width unless it was seen beside
        the broken line at a gap's end.
    taper_m
        Length (metres) of the lane's end taper where nothing seen shapes it.
    ramp_points
        Stations and offsets (metres) of the points that may be a ramp's: the outer-edge
        points not on the mainline's edge and the lane samples beyond it.

    Returns
    -------
    One :class:`DashedLane` per broken stretch of the outermost marking with an end inside
    a gap or within ``_END_NEAR_M`` of it, beside which the strip seen at the gap's ends is
    a lane wide (where the stretch reaches them).
    """
    out: list[DashedLane] = []
    d_last = _last_marking(tracks, grid)
    for a, b in true_runs(~covered):
        if a == 0 or b >= grid.size or grid[b] - grid[a - 1] < _GAP_MIN_M:
            continue
        s_a, s_b = float(grid[a - 1]), float(grid[b])
        for k in _outermost_tracks(tracks, grid, d_last, a, b):
            line = tracks[k]
            for lo, hi in broken_stretches(line.s_samples):
                # a lane beginning or ending in the gap (or just past it, its taper seen
                # only in part): one seen beside the line at both ends of a gap inside a
                # long broken stretch is bridged between the widths seen (kotka-37952515-
                # opp-s4+200: a 6.3 m strip held over a 700 m stretch, 0.047 -> 0.061 m)
                near = (s_a - _END_NEAR_M < lo < s_b + _END_NEAR_M) or (
                    s_a - _END_NEAR_M < hi < s_b + _END_NEAR_M
                )
                if not near or hi - lo < 2 * _SOLID_MIN_M:
                    continue
                lane = _lane_seen(line, grid, d_edge, (a - 1, b), (lo, hi), lane_m)
                if lane is None:
                    continue
                width, seen_width, distance = lane
                gore_at_start = _gore_at_start(lo, hi, line, ramp_points)
                taper = min(taper_m, 0.5 * (hi - lo))
                if seen_width is not None:
                    taper = _taper_through(width, distance, seen_width, taper)
                out.append(
                    DashedLane(lo, hi, gore_at_start, width, taper, line.s, line.d, (s_a, s_b))
                )
    return out


def _lane_seen(
    line: _Track,
    grid: FloatArray,
    d_edge: FloatArray,
    ends: tuple[int, int],
    stretch: tuple[float, float],
    lane_m: float,
) -> tuple[float, float | None, float] | None:
    """The lane's width (metres) from the strip beyond the line at the gap's seen ends
    (indices ``ends``) that lie inside the broken ``stretch``; with the strip seen at an
    end inside the stretch's end taper (narrower than the lane) and its distance to the
    stretch's end (metres). None where a seen end inside the stretch has no lane beside
    the broken line (it is no lane line)."""
    lo, hi = stretch
    widths = []
    narrow: tuple[float, float] | None = None
    for i in ends:
        s = float(grid[i])
        if not (lo < s < hi):
            continue
        strip = float(d_edge[i] - np.interp(s, line.s, line.d))
        if strip >= lane_m - _LANE_SEEN_SLACK_M:
            widths.append(strip)
        elif i == ends[1] and hi - s < 0.5 * (hi - lo):
            narrow = (strip, hi - s)  # seen inside the lane's end taper
        else:
            return None
    width = float(np.median(widths)) if widths else lane_m
    if narrow is None:
        return width, None, 0.0
    return width, narrow[0], narrow[1]


def dashed_lane_gores(
    lanes: list[DashedLane], covered: NDArray[np.bool_], grid: FloatArray, gores: FloatArray
) -> list[float]:
    """The gores (stations, metres) of ``lanes`` that lie inside an occlusion gap of the
    outer edge (``covered`` on ``grid``) with no gore in it yet (``gores``, metres): the
    edge steps there (:func:`~.outer_edge.fit_outer_edge`)."""
    out: list[float] = []
    for lane in lanes:
        s = lane.gore
        if s is None:
            continue
        i = int(np.searchsorted(grid, s))
        if not (0 < i < grid.size) or covered[i] or covered[i - 1]:
            continue
        run = [(a, b) for a, b in true_runs(~covered) if a <= i < b]
        a, b = run[0]
        taken = np.asarray([*gores, *out], dtype=float)
        if np.any((taken >= grid[a - 1]) & (taken <= grid[min(b, grid.size - 1)])):
            continue
        out.append(float(s))
    return out


def widen_beside_dashed(
    d_edge: FloatArray,
    covered: NDArray[np.bool_],
    grid: FloatArray,
    lanes: list[DashedLane],
) -> FloatArray:
    """The outer edge (metres, on ``grid``) across the gap each of ``lanes`` was found in
    at least the lane's width beyond its broken line; seen stations keep theirs. (In
    another gap of the same stretch another line may be the outermost: kotka-37952515-opp-
    s4+200, a line farther out seen in a gap 500 m before the stretch's end.)"""
    out = d_edge.copy()
    gap = ~covered
    for lane in lanes:
        inside = (grid > lane.gap[0]) & (grid < lane.gap[1])
        sel = gap & inside & (grid >= lane.start) & (grid <= lane.end)
        if not sel.any():
            continue
        g = grid[sel]
        out[sel] = np.maximum(out[sel], np.interp(g, lane.line_s, lane.line_d) + lane.width(g))
    return out
