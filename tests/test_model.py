"""Road model: geometry evaluation, profiles, lanes and Frenet projection, in numbers."""

from __future__ import annotations

import numpy as np
import pytest

from roadtwin.model import (
    Arc,
    CubicPiece,
    CubicProfile,
    LaneSection,
    Line,
    ParamPoly3,
    Road,
    Spiral,
    _integrate_heading_gauss,
    chain_geometry,
    constant_lane,
)


@pytest.mark.parametrize(("k0", "k1"), [(0.001, 0.01), (-0.005, 0.005), (0.0, 1e-13), (0.02, 0.0)])
def test_spiral_fresnel_matches_quadrature(k0, k1):
    spiral = Spiral(0.0, 10.0, -5.0, 0.3, 200.0, curv_start=k0, curv_end=k1)
    s = np.linspace(0.0, 200.0, 41)
    u, v = _integrate_heading_gauss(spiral._theta, s)
    x = 10.0 + np.cos(0.3) * u - np.sin(0.3) * v
    y = -5.0 + np.sin(0.3) * u + np.cos(0.3) * v
    np.testing.assert_allclose(spiral.xy(s), np.stack([x, y], axis=1), atol=1e-9)
    np.testing.assert_allclose(spiral.curvature(s), k0 + (k1 - k0) * s / 200.0, atol=1e-15)


def test_arc_end_point_on_circle():
    arc = Arc(0.0, 0.0, 0.0, 0.0, 50.0 * np.pi, curvature_per_m=0.01)  # quarter circle r=100
    x, y, h = arc.end_pose()
    assert (x, y) == pytest.approx((100.0, 100.0), abs=1e-9)
    assert h == pytest.approx(np.pi / 2, abs=1e-12)


def test_parampoly3_normalized_equals_arclength_for_line():
    a = ParamPoly3(0, 1, 2, 0.5, 80.0, bU=1.0, p_range="arcLength")
    b = ParamPoly3(0, 1, 2, 0.5, 80.0, bU=80.0, p_range="normalized")
    s = np.linspace(0, 80, 9)
    np.testing.assert_allclose(a.xy(s), b.xy(s), atol=1e-12)
    np.testing.assert_allclose(a.heading(s), 0.5, atol=1e-12)


def test_cubic_profile_value_and_derivative():
    prof = CubicProfile((CubicPiece(0.0, 1.0, 0.1), CubicPiece(10.0, 2.0, 0.0, 0.01)))
    np.testing.assert_allclose(prof.value([0.0, 5.0, 10.0, 20.0]), [1.0, 1.5, 2.0, 3.0])
    np.testing.assert_allclose(prof.derivative([5.0, 20.0]), [0.1, 0.2])


def _test_road() -> Road:
    pieces = chain_geometry(
        [Line(0, 0, 0, 0, 100.0), Arc(0, 100.0, 0, 0, 100.0, curvature_per_m=0.01)]
    )
    section = LaneSection(0.0, right=(constant_lane(-1, 3.5), constant_lane(-2, 3.75)))
    return Road("1", pieces, (section,))


def test_road_projection_round_trip():
    road = _test_road()
    rng = np.random.default_rng(0)
    s_true = rng.uniform(1.0, road.length - 1.0, 500)
    t_true = rng.uniform(-12.0, 12.0, 500)
    s, t = road.project(road.to_xy(s_true, t_true))
    assert np.max(np.abs(s - s_true)) < 1e-6
    assert np.max(np.abs(t - t_true)) < 1e-6


def test_lane_border_offsets():
    road = _test_road()
    np.testing.assert_allclose(road.lane_border_t([10.0, 150.0], -1), -3.5)
    np.testing.assert_allclose(road.lane_border_t([10.0, 150.0], -2), -7.25)
    assert np.all(np.isnan(road.lane_border_t([10.0], 1)))


def test_close_width_ends_a_lane_at_zero_width():
    from roadtwin.model import CubicPiece, CubicProfile, Lane, close_width

    # a taper that stopped 0.22 m short of zero over its last piece (40..100 m)
    lane = Lane(
        -3,
        "driving",
        CubicProfile((CubicPiece(0.0, 3.5), CubicPiece(40.0, 3.5, -0.0547))),
    )
    closed = close_width(lane, 100.0)
    s = np.linspace(0.0, 100.0, 1001)
    w = closed.width.value(s)
    assert w[-1] == pytest.approx(0.0, abs=1e-9)
    assert w.min() >= 0.0
    # untouched before the last piece, and the correction grows linearly over it
    np.testing.assert_allclose(w[s < 40.0], 3.5)
    assert closed.width.value(np.array([40.0]))[0] == pytest.approx(3.5)
