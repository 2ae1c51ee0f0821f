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

_WINDOW_ENTRIES = 1 << 22  # samples looked at in one go when measuring prominence


def _local_maxima(x: FloatArray) -> IntArray:
    """Indices of local maxima; a flat top counts once, at its middle (rounded down)."""
    n = x.size
    if n < 3:
        return np.zeros(0, dtype=np.intp)
    d = np.diff(x)
    peaks = np.flatnonzero((d[:-1] > 0.0) & (d[1:] < 0.0)) + 1
    flat = d == 0.0
    if flat.any():
        # runs d[a..b] == 0: x is flat over a..b+1; a top if it rises into it and falls after
        edges = np.diff(np.concatenate([[0], flat.astype(np.int8), [0]]))
        a, b = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
        ok = (a >= 1) & (b + 1 <= n - 2)
        a, b = a[ok], b[ok]
        top = (d[a - 1] > 0.0) & (d[b + 1] < 0.0)
        peaks = np.sort(np.concatenate([peaks, (a[top] + b[top] + 1) // 2]))
    return peaks.astype(np.intp)


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


def _prominent(x: FloatArray, peaks: IntArray, minimum: float) -> NDArray[np.bool_]:
    """Whether each peak's prominence (its height above the higher of its two bases; a
    base is the lowest point between the peak and the nearest higher point on that side,
    or the array's end) is at least ``minimum``."""
    if minimum <= 0.0:
        return np.ones(peaks.size, dtype=bool)
    return _side_reaches(x, peaks, minimum, left=True) & _side_reaches(
        x, peaks, minimum, left=False
    )


def _side_reaches(x: FloatArray, p: IntArray, minimum: float, *, left: bool) -> NDArray[np.bool_]:
    """Whether, walking from each peak ``p`` to one side, the values come down to ``minimum``
    below the peak before any rises above it; searched in windows growing fourfold."""
    n = x.size
    result = np.zeros(p.size, dtype=bool)
    todo = np.arange(p.size)
    width = 16
    while todo.size:
        # at most ~4 M window entries at once (memory bound)
        step = max(1, _WINDOW_ENTRIES // (width + 1))
        undecided = []
        for c in range(0, todo.size, step):
            rows = todo[c : c + step]
            pp = p[rows]
            v = x[pp]
            offs = np.arange(1, width + 1)
            idx = pp[:, None] - offs[None, :] if left else pp[:, None] + offs[None, :]
            inside = (idx >= 0) & (idx < n)
            vals = x[np.clip(idx, 0, n - 1)]
            low = inside & (vals <= (v - minimum)[:, None])
            high = inside & (vals > v[:, None])
            first_low = np.where(low.any(axis=1), np.argmax(low, axis=1), width)
            first_high = np.where(high.any(axis=1), np.argmax(high, axis=1), width)
            decided = (first_low < width) | (first_high < width) | ~inside[:, -1]
            result[rows[decided]] = (first_low < first_high)[decided]
            undecided.append(rows[~decided])
        todo = np.concatenate(undecided) if undecided else todo[:0]
        width *= 4
    return result


def find_peaks(x: ArrayLike, *, height: float, distance: float, prominence: float) -> IntArray:
    """Indices (ascending) of the peaks of ``x`` that :func:`scipy.signal.find_peaks` finds
    with ``height``, ``distance`` (samples) and ``prominence`` (minimum values), filtered
    in that order."""
    arr = np.ascontiguousarray(x, dtype=np.float64)
    peaks = _local_maxima(arr)
    peaks = peaks[arr[peaks] >= height]
    if distance > 1 and peaks.size > 1:
        peaks = _select_by_distance(peaks, arr[peaks], math.ceil(distance))
    if peaks.size:
        peaks = peaks[_prominent(arr, peaks, prominence)]
    return peaks


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
        flat[a:b] = np.polyval(coeffs, t)
    return flat.reshape(x.shape)


__all__ = ["find_peaks", "savgol_filter"]
