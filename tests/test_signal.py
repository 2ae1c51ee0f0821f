"""roadtwin._signal: peak finding and Savitzky-Golay smoothing without scipy.signal, equal
to SciPy's results (the build no longer pays scipy.signal's import of scipy.stats)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.signal

from roadtwin._signal import find_peaks, savgol_filter


def _signals(rng):
    n = int(rng.integers(3, 3000))
    yield rng.random(n)  # noise: peaks everywhere
    yield np.round(rng.random(n) * 5.0)  # flat tops
    spikes = np.zeros(n)
    spikes[rng.integers(0, n, 20)] = rng.random(20) * 10.0  # isolated peaks on zeros
    yield spikes
    counts = rng.poisson(0.3, n).astype(float)  # a smoothed histogram, as the markings'
    yield np.convolve(counts, np.exp(-(np.linspace(-3.0, 3.0, 15) ** 2)), "same")


@pytest.mark.parametrize("seed", range(40))
def test_find_peaks_equals_scipy(seed):
    rng = np.random.default_rng(seed)
    for x in _signals(rng):
        height = float(rng.random() * max(x.max(), 1e-9) * 0.5)
        distance = int(rng.integers(1, 20))
        prominence = float(rng.random() * height)
        want, _ = scipy.signal.find_peaks(
            x, height=height, distance=distance, prominence=prominence
        )
        got = find_peaks(x, height=height, distance=distance, prominence=prominence)
        np.testing.assert_array_equal(got, want)


def test_find_peaks_prominence_across_a_long_search():
    # the nearest higher point lies 5,000 samples away: the growing search window finds
    # it, and the base between is the lowest point on the way (-2 at 3000, against -3
    # all along the right: prominence 7 of the peak at 6000; 9 of the one at 1000)
    x = np.zeros(12000)
    x[6000] = 5.0
    x[1000] = 9.0
    x[3000] = -2.0
    x[6001:] = -3.0
    want, _ = scipy.signal.find_peaks(x, height=0.0, distance=1, prominence=6.9)
    got = find_peaks(x, height=0.0, distance=1, prominence=6.9)
    np.testing.assert_array_equal(got, want)
    assert got.tolist() == [1000, 6000]
    got = find_peaks(x, height=0.0, distance=1, prominence=7.1)
    assert got.tolist() == [1000]


def test_find_peaks_on_marking_histogram_columns_equals_scipy():
    # the layout markings._find_track_peaks searches: smoothed lateral histograms of 2,000
    # columns laid end to end with zero padding, five lines each over sparse noise
    from scipy.ndimage import gaussian_filter1d

    rng = np.random.default_rng(7)
    n_col, n_bin, pad = 2000, 380, 20
    hist = rng.poisson(0.2, (n_col, n_bin)).astype(float)
    for _ in range(5):
        hist[np.arange(n_col), rng.integers(20, n_bin - 20, n_col)] += rng.poisson(30, n_col)
    hist = gaussian_filter1d(hist, 1.5, axis=1, mode="constant")
    flat = np.zeros((n_col, n_bin + pad))
    flat[:, :n_bin] = hist
    thr = 0.15 * float(np.percentile(hist.max(axis=1), 75))
    args = {"height": thr, "distance": 16, "prominence": 0.5 * thr}
    want, _ = scipy.signal.find_peaks(flat.ravel(), **args)
    got = find_peaks(flat.ravel(), **args)
    assert want.size > 8000
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("seed", range(20))
def test_savgol_filter_equals_scipy(seed):
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(10, 500))
    window = min(int(rng.integers(1, n // 2)) * 2 + 1, n if n % 2 else n - 1)
    polyorder = int(rng.integers(1, 4))
    if window <= polyorder:
        window = polyorder + 1 + (polyorder % 2 == 1)
    y = rng.random((n, 2)) if seed % 2 else rng.random(n)
    want = scipy.signal.savgol_filter(y, window, polyorder, axis=0, mode="interp")
    np.testing.assert_array_equal(savgol_filter(y, window, polyorder), want)


def test_a_build_does_not_import_scipy_signal(tmp_path):
    code = (
        "import sys\n"
        "from roadtwin.pipeline import build_map\n"
        "from roadtwin.io import load_run\n"
        "from roadtwin.osm import load_osm\n"
        f"run = load_run({str(tmp_path / 'run')!r})\n"
        "g = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)\n"
        "build_map(run, g)\n"
        "print('scipy.signal' in sys.modules, 'scipy.stats' in sys.modules)\n"
    )
    from roadtwin.simulate import simulate_run

    simulate_run("straight_curve_2km", tmp_path / "run")
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=300
    )
    assert out.stdout.split()[-2:] == ["False", "False"]
