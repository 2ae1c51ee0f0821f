"""Peak finding and Savitzky-Golay smoothing without importing ``scipy.signal``.

``scipy.signal`` imports ``scipy.stats`` (its peak finding uses a percentile function),
which costs about 0.5 s on every ``roadtwin`` process that builds a map. The two functions
the build needs are small; these follow SciPy's algorithms step by step, so that they
return the same results (the tests compare them with SciPy on random and real input).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

_PROMINENCE_CHUNK = 4096  # peaks whose prominence is measured at once (memory bound)


def _local_maxima(x: FloatArray) -> IntArray:
    """Indices of local maxima; a flat top counts once, at its middle (rounded down)."""
    n = x.size
    if n < 3:
        return np.zeros(0, dtype=np.intp)
    # runs of equal values: [start, end] inclusive
    change = np.flatnonzero(np.diff(x) != 0.0) + 1
    start = np.concatenate([[0], change])
    end = np.concatenate([change - 1, [n - 1]])
    inner = (start > 0) & (end < n - 1)
    start, end = start[inner], end[inner]
    top = (x[start - 1] < x[start]) & (x[end + 1] < x[start])
    return ((start[top] + end[top]) // 2).astype(np.intp)


def _select_by_distance(peaks: IntArray, priority: FloatArray, distance: float) -> IntArray:
    """Keep the highest peaks first, dropping any closer than ``distance`` to a kept one."""
    keep = np.ones(peaks.size, dtype=bool)
    order = np.argsort(priority)
    pos = peaks.tolist()
    for i in range(peaks.size - 1, -1, -1):
        j = int(order[i])
        if not keep[j]:
            continue
        k = j - 1
        while k >= 0 and pos[j] - pos[k] < distance:
            keep[k] = False
            k -= 1
        k = j + 1
        while k < peaks.size and pos[k] - pos[j] < distance:
            keep[k] = False
            k += 1
    return peaks[keep]


def _prominences(x: FloatArray, peaks: IntArray) -> FloatArray:
    """Each peak's height above the higher of its two bases; a base is the lowest point
    between the peak and the nearest higher point on that side (or the array's end)."""
    out = np.empty(peaks.size)
    for a in range(0, peaks.size, _PROMINENCE_CHUNK):
        p = peaks[a : a + _PROMINENCE_CHUNK]
        v = x[p]
        out[a : a + p.size] = v - np.maximum(
            _side_min(x, p, v, left=True), _side_min(x, p, v, left=False)
        )
    return out


def _side_min(x: FloatArray, p: IntArray, v: FloatArray, *, left: bool) -> FloatArray:
    """Lowest value between each peak ``p`` (value ``v``) and its nearest higher point on
    one side, or the array's end; searched outwards in windows growing fourfold."""
    n = x.size
    result = np.full(p.size, np.nan)
    todo = np.arange(p.size)
    width = 64
    while todo.size:
        pp, vv = p[todo], v[todo]
        offs = np.arange(width + 1)
        idx = pp[:, None] - offs[None, :] if left else pp[:, None] + offs[None, :]
        inside = (idx >= 0) & (idx < n)
        vals = np.where(inside, x[np.clip(idx, 0, n - 1)], -np.inf)
        higher = inside & (vals > vv[:, None])
        found = higher.any(axis=1)
        first = np.where(found, np.argmax(higher, axis=1), width + 1)
        span = offs[None, :] < first[:, None]
        low = np.where(span & inside, vals, np.inf).min(axis=1)
        reached_end = ~found & ~inside.all(axis=1)
        done = found | reached_end
        result[todo[done]] = low[done]
        todo = todo[~done]
        width *= 4
    return result


def find_peaks(
    x: ArrayLike, *, height: float, distance: float, prominence: float
) -> tuple[IntArray, dict]:
    """Peaks of ``x`` as :func:`scipy.signal.find_peaks` with ``height``, ``distance``
    (samples) and ``prominence`` (minimum values) finds them, in that order of filters.

    Returns the peak indices (ascending) and an empty properties dict."""
    arr = np.ascontiguousarray(x, dtype=np.float64)
    peaks = _local_maxima(arr)
    peaks = peaks[arr[peaks] >= height]
    if distance > 1 and peaks.size > 1:
        peaks = _select_by_distance(peaks, arr[peaks], math.ceil(distance))
    if peaks.size:
        peaks = peaks[_prominences(arr, peaks) >= prominence]
    return peaks, {}


def _savgol_coeffs(window: int, polyorder: int) -> FloatArray:
    from scipy.linalg import lstsq

    half = window // 2
    pos = np.arange(-half, window - half, dtype=np.float64)[::-1]  # for a convolution
    design = pos ** np.arange(polyorder + 1, dtype=np.float64).reshape(-1, 1)
    target = np.zeros(polyorder + 1)
    target[0] = 1.0
    rcond = np.finfo(np.float64).eps * max(design.shape)
    coeffs, *_ = lstsq(design, target, cond=rcond)
    return coeffs


def _polyfit(t: FloatArray, y: FloatArray, deg: int) -> FloatArray:
    from scipy.linalg import lstsq

    powers = np.arange(deg + 1, dtype=np.float64)[::-1]
    lhs = t[:, None] ** powers[None, :]
    scale = np.sqrt(np.sum(lhs * lhs, axis=0))
    lhs /= scale
    rcond = t.shape[0] * np.finfo(np.float64).eps
    c, *_ = lstsq(lhs, y, cond=rcond)
    return (c.T / scale).T


def _polyval(p: FloatArray, t: FloatArray) -> FloatArray:
    y = np.zeros_like(t)
    for j in range(p.shape[0]):
        y = y * t + p[j, ...]
    return y


def savgol_filter(y: ArrayLike, window: int, polyorder: int) -> FloatArray:
    """Savitzky-Golay smoothing along axis 0 with polynomial fits at both ends, as
    :func:`scipy.signal.savgol_filter` with ``mode="interp"`` (odd ``window`` samples,
    at most the length of ``y``)."""
    from scipy.ndimage import convolve1d

    x = np.asarray(y, dtype=np.float64)
    if window > x.shape[0]:
        msg = "window must not be longer than the data"
        raise ValueError(msg)
    out = convolve1d(x, _savgol_coeffs(window, polyorder), axis=0, mode="constant")
    half = window // 2
    n = x.shape[0]
    flat = out.reshape(n, -1)
    for lo, hi, a, b in ((0, window, 0, half), (n - window, n, n - half, n)):
        edge = x[lo:hi].reshape(window, -1)
        coeffs = _polyfit(np.arange(0, hi - lo, dtype=np.float64), edge, polyorder)
        t = np.arange(a - lo, b - lo, dtype=np.float64).reshape(-1, 1)
        flat[a:b] = _polyval(coeffs, t)
    return flat.reshape(x.shape)


__all__ = ["find_peaks", "savgol_filter"]
