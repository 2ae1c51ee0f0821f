"""Curve math: arc length, resampling, smoothing, projection, ParamPoly3 chains, profiles."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from roadtwin._errors import FitError
from roadtwin.fitting import (
    PolylineFrame,
    arc_length,
    binned_quantile,
    binned_statistics,
    fit_cubic_profile,
    fit_parampoly3_chain,
    moving_median,
    resample_polyline,
    shift_cubic_piece,
    whittaker_smooth,
)
from roadtwin.model import Arc, CubicPiece, LaneSection, Line, Road, Spiral, chain_geometry


def _place(pieces):
    out, x, y, h = [], 0.0, 0.0, 0.4
    for g in chain_geometry(pieces):
        g = type(g)(**{**g.__dict__, "x0": x, "y0": y, "hdg": h})
        out.append(g)
        x, y, h = g.end_pose()
    return tuple(out)


@pytest.fixture(scope="module")
def curve_road() -> Road:
    """Line, clothoid, arc (R=600 m), clothoid back, line: 1.5 km."""
    k = 1.0 / 600.0
    geo = _place(
        [
            Line(0, 0, 0, 0, 300.0),
            Spiral(0, 0, 0, 0, 200.0, curv_start=0.0, curv_end=k),
            Arc(0, 0, 0, 0, 500.0, curvature_per_m=k),
            Spiral(0, 0, 0, 0, 200.0, curv_start=k, curv_end=0.0),
            Line(0, 0, 0, 0, 300.0),
        ]
    )
    return Road("t", geo, (LaneSection(0.0),))


def _joints(pieces):
    gaps, kinks = [], []
    for a, b in itertools.pairwise(pieces):
        x, y, h = a.end_pose()
        gaps.append(math.hypot(x - b.x0, y - b.y0))
        kinks.append(abs(math.degrees((h - b.hdg + math.pi) % (2 * math.pi) - math.pi)))
    return max(gaps, default=0.0), max(kinks, default=0.0)


def test_arc_length_and_resampling():
    xy = np.array([[0.0, 0.0], [3.0, 4.0], [3.0, 10.0]])
    np.testing.assert_allclose(arc_length(xy), [0.0, 5.0, 11.0])
    out = resample_polyline(xy, 0.5)
    assert out.shape == (23, 2)
    np.testing.assert_allclose(out[[0, -1]], xy[[0, -1]])
    np.testing.assert_allclose(np.diff(arc_length(out)), 0.5, atol=1e-9)


def test_parampoly3_chain_tracks_curve_continuously(curve_road):
    s = np.linspace(0.0, curve_road.length, 1501)
    xy = curve_road.xy(s)
    chain = fit_parampoly3_chain(xy, tolerance_m=0.02)
    gap, kink = _joints(chain)
    assert gap < 1e-6
    assert kink < 1e-6
    assert chain[0].s0 == 0.0
    for a, b in itertools.pairwise(chain):
        assert b.s0 == pytest.approx(a.s0 + a.length, abs=1e-9)
    assert all(p.p_range == "normalized" for p in chain)
    road = Road("f", chain, (LaneSection(0.0),))
    assert road.length == pytest.approx(curve_road.length, rel=1e-4)
    # lateral deviation from the true curve and station accuracy
    _, t = road.project(xy)
    assert np.max(np.abs(t)) < 0.02
    np.testing.assert_allclose(road.xy(s), xy, atol=0.03)
    # declared lengths are true arc lengths of each cubic
    for p in chain:
        q = np.linspace(0.0, p.length, 2001)
        pts = p.xy(q + p.s0)
        assert arc_length(pts)[-1] == pytest.approx(p.length, rel=1e-6)
    assert len(chain) < 40


def test_parampoly3_chain_straight_line_is_one_piece():
    xy = np.column_stack([np.linspace(0, 300, 301), 0.5 * np.linspace(0, 300, 301)])
    chain = fit_parampoly3_chain(xy)
    assert len(chain) == 1
    assert chain[0].length == pytest.approx(math.hypot(300, 150), rel=1e-9)
    assert chain[0].hdg == pytest.approx(math.atan2(150, 300))


def test_parampoly3_chain_rejects_degenerate_input():
    with pytest.raises(FitError):
        fit_parampoly3_chain(np.zeros((5, 2)))


def test_cubic_profile_is_c1_and_within_tolerance():
    s = np.linspace(0.0, 2000.0, 2001)
    z = 10.0 + 0.01 * s + 4.0 * np.sin(s / 250.0)
    prof = fit_cubic_profile(s, z, tolerance=0.002)
    assert np.max(np.abs(prof.value(s) - z)) < 0.003
    for p, q in zip(prof.pieces[:-1], prof.pieces[1:], strict=True):
        ds = q.s0 - p.s0
        end_v = p.a + ds * (p.b + ds * (p.c + ds * p.d))
        end_d = p.b + ds * (2 * p.c + 3 * p.d * ds)
        assert end_v == pytest.approx(q.a, abs=1e-9)
        assert end_d == pytest.approx(q.b, abs=1e-9)
    assert prof.pieces[0].s0 == 0.0


def test_cubic_profile_smoothing_of_noisy_samples():
    rng = np.random.default_rng(3)
    s = np.sort(rng.uniform(0.0, 500.0, 600))
    truth = 2.0 + 0.02 * s - 3e-5 * s**2
    prof = fit_cubic_profile(s, truth + rng.normal(0, 0.05, s.size), smooth=True, tolerance=0.005)
    grid = np.linspace(5.0, 495.0, 200)
    err = prof.value(grid) - (2.0 + 0.02 * grid - 3e-5 * grid**2)
    assert np.sqrt(np.mean(err**2)) < 0.01


def test_shift_cubic_piece_keeps_values():
    p = CubicPiece(10.0, 1.0, 0.2, -0.01, 3e-4)
    q = shift_cubic_piece(p, 17.5)
    for x in (17.5, 20.0, 30.0):
        dp, dq = x - p.s0, x - q.s0
        assert p.a + dp * (p.b + dp * (p.c + dp * p.d)) == pytest.approx(
            q.a + dq * (q.b + dq * (q.c + dq * q.d)), abs=1e-12
        )


def test_whittaker_bridges_gaps_and_keeps_lines():
    x = np.arange(200.0)
    y = 0.5 + 0.01 * x
    w = np.ones_like(x)
    w[80:120] = 0.0
    yy = y.copy()
    yy[80:120] = np.nan
    out = whittaker_smooth(yy, w, lam=1000.0)
    np.testing.assert_allclose(out, y, atol=1e-6)


def test_binned_statistics_match_numpy():
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 10, 500)
    y = rng.normal(size=500)
    edges = np.arange(0.0, 11.0, 1.0)
    med, mean, count = binned_statistics(x, y, edges)
    q = binned_quantile(x, y, edges, 0.25)
    for k in range(10):
        sel = (x >= edges[k]) & (x < edges[k + 1])
        assert count[k] == sel.sum()
        assert med[k] == pytest.approx(np.median(y[sel]))
        assert mean[k] == pytest.approx(np.mean(y[sel]))
        ys = np.sort(y[sel])
        assert q[k] == ys[int(np.floor(0.25 * (ys.size - 1) + 0.5))]


def test_polyline_frame_projection_on_arc():
    r = 500.0
    th = np.linspace(0.0, 0.8, 401)
    xy = np.column_stack([r * np.sin(th), r - r * np.cos(th)])
    frame = PolylineFrame.from_points(xy)
    pts_th = np.linspace(0.05, 0.75, 50)
    for off in (-7.0, 3.0):
        rr = r - off
        pts = np.column_stack([rr * np.sin(pts_th), r - rr * np.cos(pts_th)])
        s, t = frame.project(pts)
        np.testing.assert_allclose(t, off, atol=2e-3)
        np.testing.assert_allclose(s, r * pts_th, atol=2e-2)


def test_whittaker_banded_solve_matches_the_sparse_normal_equations():
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    rng = np.random.default_rng(5)
    n = 400
    y = np.sin(np.arange(n) / 30.0) + rng.normal(0.0, 0.1, n)
    w = rng.uniform(0.2, 2.0, n)
    w[150:220] = 0.0  # a gap bridged by the penalty
    for order in (1, 2):
        f = whittaker_smooth(y, w, lam=500.0, order=order)
        coef = np.diff(np.eye(order + 1), order, axis=0)[0]
        D = sparse.diags(
            [np.full(n, c) for c in coef], list(range(order + 1)), shape=(n - order, n)
        )
        ref = spsolve((sparse.diags(w) + 500.0 * (D.T @ D)).tocsc(), w * y)
        np.testing.assert_allclose(f, ref, atol=1e-9)


def test_moving_median_equals_nanmedian_of_the_windows():
    from numpy.lib.stride_tricks import sliding_window_view

    rng = np.random.default_rng(6)
    v = rng.normal(size=500)
    v[rng.uniform(size=500) < 0.3] = np.nan
    v[100:140] = np.nan  # windows with no value at all
    for window in (5, 11, 21):
        half = window // 2
        view = sliding_window_view(np.pad(v, half, constant_values=np.nan), 2 * half + 1)
        with np.errstate(all="ignore"), pytest.warns(RuntimeWarning):
            ref = np.nanmedian(view, axis=1)
        np.testing.assert_array_equal(moving_median(v, window=window), ref)


def test_cubic_profile_ignores_a_station_a_hair_after_the_last_node():
    """A 1 m grid clipped at a road's end (length 419.0001 m) ends with two stations
    0.1 mm apart; the profile of a flat lane width must stay flat there (it swung 0.73 m
    before the near-duplicate station was dropped), and still reach the end station."""
    s = np.r_[np.arange(0.0, 420.0), 419.00010299]
    width = 2.5223 + 0.001 * np.sin(s / 30.0)
    width[-2:] += (3e-4, 1e-4)  # the two samples at the end differ a little
    prof = fit_cubic_profile(s, width, tolerance=0.01)
    x = np.linspace(0.0, s[-1], 8001)
    assert np.max(np.abs(prof.value(x) - (2.5223 + 0.001 * np.sin(x / 30.0)))) < 0.01
    assert prof.value(np.array([s[-1]]))[0] == pytest.approx(width[-1], abs=1e-3)
    # samples spaced normally are untouched: the same profile as before for a clean grid
    clean = fit_cubic_profile(s[:-1], width[:-1], tolerance=0.01)
    np.testing.assert_allclose(clean.value(x[:-1]), prof.value(x[:-1]), atol=0.01)
