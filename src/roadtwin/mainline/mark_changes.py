"""Where the marking beside a road-edge strip changes between solid and broken.

The line between the outermost lane and the hard shoulder is solid; where a lane is
gained beside it (the shoulder becomes a lane, an added lane opens beyond the sensor's
reach) the same line runs on as a broken lane line, and where the lane is dropped again
it turns solid. Seen from an inner lane, the new lane's own outer line may lie out of
reach: the marking's pattern is then the only sign, along one track, that the strip
beyond it changed from a shoulder to a lane. A section judged as a whole read the strip
by its majority (oakland-28393854-lane1-s21 at seed offset 860: the 3.0 m shoulder over
the run's first 573 m typed a driving lane with the lane that follows it, lane count
71 %). Such a change starts a section, so that each part is typed by its own pattern.

Stations are metres along the reference line; offsets ``d`` metres from the reference
edge towards the carriageway (the lanes' frame, :func:`~.lanes.fit_lanes`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..config import MainlineConfig
from .markings import _long_gap_m, _Track

FloatArray = NDArray[np.float64]

_SIDE_M = 100.0  # each pattern holds over this much of the track on its side (metres)
_DASHED_GAPS = 4  # a broken stretch has at least this many gaps in the paint ...
_DASHED_SHARE = 0.3  # ... covering at least this share of it
_SOLID_GAPS = 2  # a solid stretch has at most this many (a missed or worn piece) ...
_SOLID_SHARE = 0.45  # ... covering at most this share (a worn stretch is 5-40 m long)
_BESIDE_M = 0.3  # no other marking farther out (in) than this: the strip is the edge's


def pattern_changes(
    tracks: list[_Track], dmat: FloatArray, grid: FloatArray, cfg: MainlineConfig
) -> list[int]:
    """Grid indices where a marking that borders an edge strip (no other marking beyond it
    there, on either side) turns from solid to broken (at the first gap of the broken
    stretch) or from broken to solid (at the end of its last gap), each pattern held over
    ``_SIDE_M`` on its side. ``dmat``: the tracks' offsets on ``grid`` (rows as
    ``tracks``, NaN where absent)."""
    out: list[int] = []
    for k, tr in enumerate(tracks):
        for c in _changes_along(tr, cfg):
            i = int(np.clip(np.searchsorted(grid, c), 0, grid.size - 1))
            if _borders_edge_strip(dmat, k, i):
                out.append(i)
    return sorted(set(out))


def _changes_along(tr: _Track, cfg: MainlineConfig) -> FloatArray:
    """Stations (metres) where track ``tr``'s paint turns from solid to broken or back."""
    ss = np.sort(tr.s_samples)
    if ss.size < 20 or tr.hi - tr.lo < 2.0 * _SIDE_M:
        return np.zeros(0)
    gaps = np.diff(ss)
    long_gap = gaps > _long_gap_m(ss, cfg)
    g_lo, g_hi = ss[:-1][long_gap], ss[1:][long_gap]
    if g_lo.size < _DASHED_GAPS:
        return np.zeros(0)
    paint = _Paint(ss, g_lo, g_hi, np.concatenate([[0.0], np.cumsum(g_hi - g_lo)]))
    # solid to broken at a gap's start, broken to solid at a gap's end; the gaps next to a
    # change qualify too (a gap or two on the solid side): the first of each cluster where
    # the line turns broken, the last where it turns solid
    inside_lo = (g_lo - _SIDE_M >= tr.lo) & (g_lo + _SIDE_M <= tr.hi)
    inside_hi = (g_hi - _SIDE_M >= tr.lo) & (g_hi + _SIDE_M <= tr.hi)
    to_broken = g_lo[
        inside_lo & paint.solid(g_lo - _SIDE_M, g_lo) & paint.dashed(g_lo, g_lo + _SIDE_M)
    ]
    to_solid = g_hi[
        inside_hi & paint.dashed(g_hi - _SIDE_M, g_hi) & paint.solid(g_hi, g_hi + _SIDE_M)
    ]
    firsts = to_broken[np.diff(to_broken, prepend=-np.inf) > _SIDE_M]
    lasts = to_solid[np.diff(to_solid, append=np.inf) > _SIDE_M]
    return np.sort(np.concatenate([firsts, lasts]))


@dataclass(frozen=True)
class _Paint:
    """A marking's sample stations (sorted) and the gaps in its paint (metres)."""

    ss: FloatArray
    g_lo: FloatArray
    g_hi: FloatArray
    gap_length_before: FloatArray  # total length of the gaps before each gap

    def _count_and_share(self, a: FloatArray, b: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Gaps lying wholly inside ``[a, b]``: how many, and the share of it they cover."""
        i = np.searchsorted(self.g_lo, a, "left")
        j = np.maximum(np.searchsorted(self.g_hi, b, "right"), i)
        covered = self.gap_length_before[j] - self.gap_length_before[i]
        return j - i, covered / (b - a)

    def solid(self, a: FloatArray, b: FloatArray) -> NDArray[np.bool_]:
        """Whether the paint is solid over each ``[a, b]``, seen up to both ends (a
        stretch out of the sensor's reach is no solid line)."""
        n, share = self._count_and_share(a, b)
        first = self.ss[np.minimum(np.searchsorted(self.ss, a), self.ss.size - 1)]
        last = self.ss[np.maximum(np.searchsorted(self.ss, b, "right") - 1, 0)]
        seen = (first - a < _SIDE_M / 4) & (b - last < _SIDE_M / 4)
        return (n <= _SOLID_GAPS) & (share <= _SOLID_SHARE) & seen

    def dashed(self, a: FloatArray, b: FloatArray) -> NDArray[np.bool_]:
        """Whether the paint is broken over each ``[a, b]``."""
        n, share = self._count_and_share(a, b)
        return (n >= _DASHED_GAPS) & (share >= _DASHED_SHARE)


def _borders_edge_strip(dmat: FloatArray, k: int, i: int) -> bool:
    """Whether no other marking lies beyond track ``k`` at grid index ``i``, on the
    outer side or on the median side."""
    d = dmat[:, i]
    if not np.isfinite(d[k]):
        return False
    others = np.delete(d, k)
    others = others[np.isfinite(others)]
    return bool(not np.any(others > d[k] + _BESIDE_M) or not np.any(others < d[k] - _BESIDE_M))
