"""Driving lanes across a carriageway, whichever roads carry them.

Where a ramp leaves or joins, maps split the same pavement between roads differently: one
keeps a deceleration lane on the mainline road up to the nose, another hands it to a
junction's connecting road at the painted gore, a third keeps a closing lane on the mainline
under the ramp road's first metres. Counted on the mainline road alone, the same
carriageway has a lane more or less there. :func:`carriageway_lane_count` counts the
driving lanes a line across the carriageway passes through, on every road at the line's
level, a lane that two roads overlap once.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from ..model import SAME_LEVEL_M, Road
from .frenet import FloatArray, project_points

HALF_WIDTH_M = 30.0
"""Reach of the line across the carriageway on each side of its centre point (metres)."""
STEP_M = 0.25
"""Spacing of the samples along the line (metres)."""
ALONG_RAD = math.radians(20.0)
"""A road whose heading differs from the carriageway's by more than this (radians) crosses
it (a ramp on a bridge, a knotted ramp): its lanes are no lanes of the carriageway."""
GAP_M = 0.6
"""Pavement interrupted by at most this much (metres; the seam between two roads, a
painted gore's first centimetres) is the same carriageway."""


def _lane_at(road: Road, s: FloatArray, t: FloatArray) -> NDArray[np.int64]:
    """Id of the ``driving`` lane holding Frenet points ``s, t`` of ``road`` (0: none)."""
    out = np.zeros(s.shape, dtype=np.int64)
    sec_idx = road.section_index(s)
    for k in np.unique(sec_idx):
        section = road.lane_sections[int(k)]
        sel = np.nonzero(sec_idx == k)[0]
        for lanes in (section.left, section.right):
            inner = road.lane_border_t(s[sel], 0)
            for lane in sorted(lanes, key=lambda x: abs(x.id)):  # centre outwards
                outer = road.lane_border_t(s[sel], lane.id)
                lo, hi = np.minimum(inner, outer), np.maximum(inner, outer)
                if lane.type == "driving":
                    hit = (t[sel] >= lo) & (t[sel] < hi) & (out[sel] == 0)
                    out[sel[hit]] = lane.id
                inner = outer
    return out


def carriageway_lane_count(
    roads: Sequence[Road],
    centres: FloatArray,
    normals: FloatArray,
    *,
    min_width_m: float,
) -> NDArray[np.int64]:
    """Driving lanes at least ``min_width_m`` wide on a line across the carriageway.

    Parameters
    ----------
    roads
        Every road that may carry the carriageway's lanes (mainline, ramp and connecting
        roads of one map).
    centres
        ``(M, 3)`` mapping-frame points on the carriageway (metres, with the surface
        height: roads passing over or under are not the same pavement).
    normals
        ``(M, 2)`` unit vectors across the carriageway at ``centres`` (pointing left of its
        driving direction: lanes of roads heading more than ``ALONG_RAD`` off it cross it
        and are not counted).
    min_width_m
        A lane counts where the line runs at least this far through it (metres).

    Returns
    -------
    (M,) int
        Per point: the driving lanes of the stretch of pavement the line runs through
        without a gap over ``GAP_M`` around the point; lanes of different roads whose
        middles along the line are less than ``min_width_m`` apart are one lane.
    """
    centres = np.asarray(centres, dtype=float)
    normals = np.asarray(normals, dtype=float)
    m = centres.shape[0]
    counts = np.zeros(m, dtype=np.int64)
    if m == 0 or not roads:
        return counts
    offsets = np.arange(-HALF_WIDTH_M, HALF_WIDTH_M + 0.5 * STEP_M, STEP_M)
    k = offsets.size
    k0 = int(np.argmin(np.abs(offsets)))
    xy = centres[:, None, :2] + offsets[None, :, None] * normals[:, None, :]
    pts = np.column_stack([xy.reshape(-1, 2), np.repeat(centres[:, 2], k)])
    # the carriageway's heading per point: the normal turned right by 90 degrees
    heading = np.arctan2(-normals[:, 0], normals[:, 1])
    paved = np.zeros(m * k, dtype=bool)
    hits: list[tuple[NDArray[np.intp], NDArray[np.int64], int]] = []
    for r, road in enumerate(roads):  # loop over roads, vectorised over samples
        proj = project_points([road], pts, max_lateral_m=0.0, end_tolerance_m=0.0)
        idx = np.nonzero(proj.ok)[0]
        level = np.abs(road.surface_height(proj.s[idx], proj.t[idx]) - pts[idx, 2])
        along = np.abs(np.angle(np.exp(1j * (road.heading(proj.s[idx]) - heading[idx // k]))))
        idx = idx[(level <= SAME_LEVEL_M) & (along <= ALONG_RAD)]
        paved[idx] = True
        lane = _lane_at(road, proj.s[idx], proj.t[idx])
        hits.append((idx[lane != 0], lane[lane != 0], r))
    # the stretch of pavement through each centre point, seams closed
    grid = ndimage.binary_closing(
        paved.reshape(m, k), structure=np.ones((1, round(GAP_M / STEP_M) + 1), bool)
    )
    labels, _ = ndimage.label(grid, structure=np.array([[0, 0, 0], [1, 1, 1], [0, 0, 0]]))
    own = labels == labels[:, k0 : k0 + 1]
    own &= labels[:, k0 : k0 + 1] > 0
    # per point and lane (road, id): samples on the line and their mean offset
    rows, keys, where = [], [], []
    for idx, lane, r in hits:
        keep = own.reshape(-1)[idx]
        rows.append(idx[keep] // k)
        where.append(offsets[idx[keep] % k])
        keys.append(r * 100_000 + lane[keep] + 50_000)
    if not rows:
        return counts
    row = np.concatenate(rows)
    key = np.concatenate(keys)
    off = np.concatenate(where)
    pair, inverse = np.unique(np.column_stack([row, key]), axis=0, return_inverse=True)
    n = np.bincount(inverse.ravel())
    middle = np.bincount(inverse.ravel(), weights=off) / n
    wide = n * STEP_M >= min_width_m
    pair, middle = pair[wide], middle[wide]
    order = np.lexsort((middle, pair[:, 0]))
    pair, middle = pair[order], middle[order]
    # a new lane where the point changes or the middle moves on by min_width_m
    new = np.ones(pair.shape[0], dtype=bool)
    same_row = pair[1:, 0] == pair[:-1, 0]
    new[1:] = ~same_row | (np.diff(middle) >= min_width_m)
    np.add.at(counts, pair[new, 0], 1)
    return counts
