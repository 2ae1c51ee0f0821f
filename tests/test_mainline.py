"""Mainline reconstruction: accuracy against a known truth road, continuity, lanes, cut_road."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from roadtwin.config import MainlineConfig
from roadtwin.evaluation.mainline_truth import compare_mainline_road, geometry_continuity, rmse
from roadtwin.frames import MappingFrame, Origin
from roadtwin.io import MappingRun, Trajectory
from roadtwin.mainline import build_mainline, cut_road
from roadtwin.model import (
    Arc,
    CubicPiece,
    CubicProfile,
    Lane,
    LaneSection,
    Line,
    ParamPoly3,
    Road,
    RoadMark,
    Spiral,
    chain_geometry,
)


def _flat_lane(lid: int, w: float, kind: str = "driving") -> Lane:
    """A lane of constant width ``w`` (metres) for the section-link tests."""
    return Lane(lid, kind, CubicProfile((CubicPiece(0.0, w),)))


# ---------------------------------------------------------------------------
# fixture: a known truth road sampled like a mapping run
# ---------------------------------------------------------------------------


def _lanes(widths, types, marks, sign):
    out = []
    for i, (w, ty, mk) in enumerate(zip(widths, types, marks, strict=True)):
        prof = w if isinstance(w, CubicProfile) else CubicProfile.constant(w)
        lid = -(i + 1) if sign > 0 else i + 1
        out.append(Lane(lid, ty, prof, (RoadMark(0.0, mk),)))
    return tuple(out)


def _section(s0, widths, types, marks, sign):
    lanes = _lanes(widths, types, marks, sign)
    return LaneSection(s0, right=lanes) if sign > 0 else LaneSection(s0, left=lanes)


def truth_road(*, sign: float = 1.0, aux_lane: bool = True, length_scale: float = 1.0) -> Road:
    """A 1.5 km mainline: line, clothoid, arc, clothoid, line; 3 lanes; a tapering
    deceleration lane from 900 m (80 m taper) to 1200 m."""
    k = 1.0 / 800.0 * sign
    L = length_scale
    geo = chain_geometry(
        [
            Line(0, 100.0, 200.0, 0.3, 400.0 * L),
            Spiral(0, 0, 0, 0, 150.0 * L, curv_start=0.0, curv_end=k),
            Arc(0, 0, 0, 0, 400.0 * L, curvature_per_m=k),
            Spiral(0, 0, 0, 0, 150.0 * L, curv_start=k, curv_end=0.0),
            Line(0, 0, 0, 0, 400.0 * L),
        ]
    )
    # place pieces end to end
    placed = []
    x, y, h = 100.0, 200.0, 0.3
    for g in geo:
        g2 = replace(g, x0=x, y0=y, hdg=h)
        placed.append(g2)
        x, y, h = g2.end_pose()
    base_w = [0.75, 3.75, 3.75, 3.75, 2.5]
    base_t = ["shoulder", "driving", "driving", "driving", "shoulder"]
    base_m = ["solid", "broken", "broken", "solid", "none"]
    sections = [_section(0.0, base_w, base_t, base_m, sign)]
    if aux_lane:
        taper = 80.0
        # smooth 0 -> 3.5 over the taper, then constant
        c3 = -2 * 3.5 / taper**3
        c2 = 3 * 3.5 / taper**2
        aux = CubicProfile((CubicPiece(0.0, 0.0, 0.0, c2, c3), CubicPiece(taper, 3.5)))
        sections.append(
            _section(
                900.0 * L,
                [0.75, 3.75, 3.75, 3.75, aux, 2.5],
                [*base_t[:4], "driving", "shoulder"],
                ["solid", "broken", "broken", "broken", "solid", "none"],
                sign,
            )
        )
        sections.append(_section(1200.0 * L, base_w, base_t, base_m, sign))
    elevation = CubicProfile((CubicPiece(0.0, 5.0, 0.01, 2e-5, -1e-8),))
    return Road("1", tuple(placed), tuple(sections), name="mainline", elevation=elevation)


def _lane_ids(sec: LaneSection) -> list[int]:
    return [ln.id for ln in (sec.right or sec.left)]


def sample_run(
    road: Road,
    *,
    noise_m: float = 0.03,
    seed: int = 0,
    outliers: float = 0.0,
    gap: tuple[float, float] | None = None,
    traffic_side: str = "right",
    cross_slope: float = 0.0,
) -> MappingRun:
    """Edge points, lane samples and poses of ``road`` with Gaussian noise.

    ``outliers``: fraction of edge points pushed 0.5-3 m outward (guardrails);
    ``gap``: station range without edge points (occlusion); ``cross_slope``: the surface
    height changes by this much per metre of t (z = elevation + t * cross_slope)."""
    rng = np.random.default_rng(seed)
    sign = 1.0 if traffic_side == "right" else -1.0
    length = road.length
    s_e = np.arange(0.0, length, 0.2)
    edges, sides = [], []
    for side_val in (1, -1):
        t = np.zeros_like(s_e)
        if side_val == -sign:  # outer edge
            for k, sec in enumerate(road.lane_sections):
                hi = road.lane_sections[k + 1].s0 if k + 1 < len(road.lane_sections) else length
                sel = (s_e >= sec.s0) & (s_e < hi)
                t[sel] = road.lane_border_t(s_e[sel], _lane_ids(sec)[-1])
        keep = np.ones(s_e.size, bool)
        if gap is not None:
            keep &= ~((s_e > gap[0]) & (s_e < gap[1]))
        xy = road.to_xy(s_e[keep], t[keep])
        z = road.height(s_e[keep]) + cross_slope * t[keep]
        pts = np.column_stack([xy, z]) + rng.normal(0.0, noise_m, (xy.shape[0], 3))
        if outliers > 0:  # guardrail-like points offset outward
            n_out = int(outliers * pts.shape[0])
            idx = rng.choice(pts.shape[0], n_out, replace=False)
            h = road.heading(road.project(pts[idx])[0])
            out_dir = side_val * np.stack([-np.sin(h), np.cos(h)], axis=1)
            pts[idx, :2] += out_dir * rng.uniform(0.5, 3.0, (n_out, 1))
        edges.append(pts)
        sides.append(np.full(pts.shape[0], side_val, np.int8))
    # lane samples on markings
    lane_pts = []
    s_l = np.arange(0.0, length, 0.5)
    for k, sec in enumerate(road.lane_sections):
        hi = road.lane_sections[k + 1].s0 if k + 1 < len(road.lane_sections) else length
        side = sec.right or sec.left
        sel_s = s_l[(s_l >= sec.s0) & (s_l < hi)]
        for ln in side[:-1]:
            mark = ln.road_marks[0].type
            ss = sel_s
            if mark == "broken":
                ss = ss[np.mod(ss, 18.0) < 6.0]
            t = road.lane_border_t(ss, ln.id)
            # no samples where the lane has (near) zero width (same line)
            w = ln.width.value(ss - sec.s0)
            ss, t = ss[w > 0.05], t[w > 0.05]
            xy = road.to_xy(ss, t)
            lane_pts.append(np.column_stack([xy, road.height(ss) + cross_slope * t]))
    lanes = np.vstack(lane_pts)
    lanes = lanes + rng.normal(0.0, noise_m, lanes.shape)
    # trajectory: centre of the second driving lane, with a gentle weave
    s_p = np.arange(0.0, length, 1.0)
    t_p = road.lane_border_t(s_p, int(-3 * sign)) + sign * 1.875 + 0.3 * np.sin(s_p / 90.0)
    xy_p = road.to_xy(s_p, t_p)
    z_p = road.height(s_p) + cross_slope * t_p
    traj = Trajectory(
        frame=np.arange(s_p.size, dtype=np.int64),
        t=s_p / 25.0,
        xyz=np.column_stack([xy_p, z_p]),
        yaw=np.unwrap(road.heading(s_p)),
        pitch=np.zeros(s_p.size),
        roll=np.zeros(s_p.size),
    )
    return MappingRun(
        root=Path("."),
        frame=MappingFrame(Origin(47.0, 15.0, 300.0)),
        trajectory=traj,
        pose_height_m=0.0,
        edges=np.vstack(edges),
        edge_side=np.concatenate(sides),
        lane_samples=lanes,
        lane_sample_frame=np.zeros(lanes.shape[0], np.int64),
        osm_path=None,
        traffic_side=traffic_side,  # type: ignore[arg-type]
    )


# ---------------------------------------------------------------------------
# comparison against the truth road (every 1 m along the true boundaries)
# ---------------------------------------------------------------------------


def compare_to_truth(built: Road, truth: Road, *, trim_m: float = 30.0) -> dict:
    """Errors (metres) of the built road against the truth road, ``trim_m`` kept off both
    ends, plus the fraction of stations where the lane count agrees."""
    res = compare_mainline_road(built, truth, s_lo=trim_m, s_hi=truth.length - trim_m)
    res["lane_count_agreement"] = float(np.mean(res["lane_count"]))
    return res


# ---------------------------------------------------------------------------
# tests
# ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def right_case():
    truth = truth_road()
    run = sample_run(truth, seed=1)
    return truth, run, build_mainline(run)


def test_default_method_matches_truth(right_case):
    truth, _run, ml = right_case
    road = ml.road
    assert road.name == "mainline"
    assert road.id == "1"
    res = compare_to_truth(road, truth)
    assert rmse(res["ref_edge"]) < 0.02
    assert rmse(res["outer_edge"]) < 0.05
    assert rmse(res["lane_boundary"]) < 0.03
    assert rmse(res["elevation"]) < 0.01
    assert res["lane_count_agreement"] > 0.98
    gap, kink = geometry_continuity(road)
    assert gap < 1e-3
    assert kink < 0.01
    assert road.length == pytest.approx(truth.length, abs=0.5)
    assert road.superelevation is None  # flat cross section
    assert ml.residuals["road_edge"] < 0.06
    assert ml.residuals["lane_boundary"] < 0.06
    assert set(ml.timings_s) >= {"reference_line", "elevation", "lanes", "total"}


def test_default_lane_layout_and_events(right_case):
    _, _, ml = right_case
    secs = ml.road.lane_sections
    assert [len(sec.right) for sec in secs] == [5, 6, 5]
    assert secs[1].s0 == pytest.approx(900.0, abs=3.0)
    assert secs[2].s0 == pytest.approx(1200.0, abs=3.0)
    for sec in secs:
        assert not sec.left
        types = [ln.type for ln in sec.right]
        assert types[0] == "shoulder"
        assert types[-1] == "shoulder"
        assert set(types[1:-1]) == {"driving"}
        assert [ln.id for ln in sec.right] == list(range(-1, -len(sec.right) - 1, -1))
        assert sec.right[-1].road_marks[0].type == "none"
        assert sec.right[0].road_marks[0].type == "solid"
    marks = [ln.road_marks[0].type for ln in secs[0].right]
    assert marks == ["solid", "broken", "broken", "solid", "none"]
    aux = secs[1].right[4]
    assert aux.width.value(0.0) < 0.1  # tapers from zero
    assert aux.width.value(150.0) == pytest.approx(3.5, abs=0.1)
    assert aux.predecessor is None
    # hard shoulder continues across sections
    assert secs[1].right[-1].predecessor == -5
    assert secs[0].right[-1].successor == -6
    births = [e for e in ml.lane_events if e.kind == "birth"]
    ends = [e for e in ml.lane_events if e.kind == "end"]
    assert len(births) == 1
    assert len(ends) == 1
    assert births[0].s_m == pytest.approx(900.0, abs=5.0)
    assert births[0].taper_m == pytest.approx(80.0, abs=15.0)
    assert births[0].lane_id == -5
    assert births[0].position == "outer"
    assert ends[0].s_m == pytest.approx(1200.0, abs=3.0)
    assert ends[0].taper_m == 0.0
    # widths are never negative
    for sec, nxt in zip(secs, [*secs[1:], None], strict=True):
        hi = (nxt.s0 if nxt else ml.road.length) - sec.s0
        ds = np.linspace(0.0, hi, 50)
        for ln in sec.right:
            assert np.all(ln.width.value(ds) >= -1e-6)


def test_left_hand_traffic_is_mirrored():
    truth = truth_road(sign=-1.0)
    run = sample_run(truth, seed=2, traffic_side="left")
    ml = build_mainline(run)
    secs = ml.road.lane_sections
    assert all(not sec.right for sec in secs)
    assert [len(sec.left) for sec in secs] == [5, 6, 5]
    assert [ln.id for ln in secs[0].left] == [1, 2, 3, 4, 5]
    res = compare_to_truth(ml.road, truth)
    assert rmse(res["ref_edge"]) < 0.02
    assert rmse(res["lane_boundary"]) < 0.03
    assert ml.lane_events[0].side == "left"
    assert ml.lane_events[0].lane_id == 5


def test_robust_to_outliers_occlusion_and_cross_slope():
    truth = truth_road(aux_lane=False)
    run = sample_run(truth, seed=3, outliers=0.08, gap=(600.0, 700.0), cross_slope=0.025)
    ml = build_mainline(run)
    res = compare_to_truth(ml.road, truth)
    assert rmse(res["ref_edge"]) < 0.03
    assert rmse(res["outer_edge"]) < 0.06
    assert res["lane_count_agreement"] > 0.99
    assert len(ml.road.lane_sections) == 1
    # surface falls to the right (t < 0 lower): superelevation = atan(0.025) > 0
    assert ml.road.superelevation is not None
    sup = ml.road.superelevation.value(np.linspace(100, 1400, 20))
    np.testing.assert_allclose(sup, np.arctan(0.025), atol=0.003)
    assert rmse(res["elevation"]) < 0.02


def test_paper_method_is_windowed():
    truth = truth_road(length_scale=0.4)  # 600 m: six windows (K-means per window is slow)
    run = sample_run(truth, seed=4)
    paper = build_mainline(run, config=MainlineConfig(method="paper"))
    assert paper.method == "paper"
    road = paper.road
    # one piece and one lane section per 100 m window
    assert len(road.geometry) == pytest.approx(6, abs=1)
    assert len(road.lane_sections) == len(road.geometry)
    gap, _ = geometry_continuity(road)
    assert gap > 1e-3  # independent windows do not meet exactly
    res = compare_to_truth(road, truth)
    assert rmse(res["ref_edge"]) < 0.2
    assert np.isfinite(paper.residuals["overall"])
    # the default method is better on the lanes
    default = build_mainline(run)
    assert rmse(compare_to_truth(default.road, truth)["lane_boundary"]) < rmse(res["lane_boundary"])


def test_unknown_method_is_an_input_error(right_case):
    from roadtwin._errors import InputError

    _, run, _ = right_case
    with pytest.raises(InputError):
        build_mainline(run, config=MainlineConfig(method="magic"))  # type: ignore[arg-type]


def test_cut_road_is_exact(right_case):
    _, _, ml = right_case
    road = ml.road
    a, b = 850.3, 1250.7
    sub = cut_road(road, a, b, road_id="7")
    assert sub.id == "7"
    assert sub.predecessor is None
    assert sub.successor is None
    # cut normalized ParamPoly3 pieces declare their true arc length (the ASAM checker
    # allows 1 mm), so stations inside the sub-road may move by micrometres
    assert sub.length == pytest.approx(b - a, abs=1e-3)
    assert sub.geometry[0].s0 == 0.0
    assert sub.lane_sections[0].s0 == 0.0
    for g in sub.geometry:
        if isinstance(g, ParamPoly3) and g.p_range == "normalized":
            p = np.linspace(0.0, 1.0, 20001)
            du = g.bU + p * (2 * g.cU + 3 * g.dU * p)
            dv = g.bV + p * (2 * g.cV + 3 * g.dV * p)
            speed = np.hypot(du, dv)
            true_len = float(np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(p)))
            assert g.length == pytest.approx(true_len, abs=1e-6)
    np.testing.assert_allclose(sub.xy(np.array([0.0])), road.xy(np.array([a])), atol=1e-9)
    np.testing.assert_allclose(sub.xy(np.array([sub.length])), road.xy(np.array([b])), atol=1e-7)
    s = np.linspace(0.0, sub.length, 300)
    # the same curve: every point of the sub-road lies on the road's reference line
    s_on, t_on = road.project(sub.xy(s))
    np.testing.assert_allclose(t_on, 0.0, atol=1e-6)
    np.testing.assert_allclose(s_on, s + a, atol=1e-3)
    np.testing.assert_allclose(sub.heading(s), road.heading(s_on), atol=1e-6)
    s = np.linspace(0.0, b - a, 300)
    np.testing.assert_allclose(sub.height(s), road.height(s + a), atol=1e-9)
    for lid in (-1, -3, -5):
        np.testing.assert_allclose(
            sub.lane_border_t(s, lid), road.lane_border_t(s + a, lid), atol=1e-9, equal_nan=True
        )
    assert [sc.s0 + a for sc in sub.lane_sections[1:]] == pytest.approx(
        [sc.s0 for sc in road.lane_sections if a < sc.s0 < b]
    )
    gap, kink = geometry_continuity(sub)
    assert gap < 1e-6
    assert kink < 1e-6
    first = sub.lane_sections[0].right
    assert all(ln.predecessor is None for ln in first)
    assert all(ln.successor is None for ln in sub.lane_sections[-1].right)


def test_simulated_run_end_to_end(tmp_path):
    simulate = pytest.importorskip("roadtwin.simulate")
    from roadtwin.io import load_run
    from roadtwin.xodr import read_xodr

    out = simulate.simulate_run("straight_curve_2km", tmp_path / "run")
    run = load_run(out)
    ml = build_mainline(run)
    truth = read_xodr(out / "truth.xodr")
    mains = sorted((r for r in truth.roads if r.name == "mainline"), key=lambda r: int(r.id))
    errs = {"ref_edge": [], "outer_edge": [], "lane_boundary": []}
    for r in mains:
        res = compare_to_truth(ml.road, r, trim_m=0.5)
        for k in errs:
            errs[k].append(res[k])
    assert rmse(np.concatenate(errs["ref_edge"])) < 0.05
    assert rmse(np.concatenate(errs["lane_boundary"])) < 0.05
    # exit and entry: a deceleration lane ends at the exit gore, an acceleration lane
    # starts at the entry gore
    road = ml.road
    for k, sec in enumerate(road.lane_sections):
        hi = road.lane_sections[k + 1].s0 if k + 1 < len(road.lane_sections) else road.length
        ds = np.linspace(0.0, hi - sec.s0, 400)
        for ln in sec.right:
            assert np.min(ln.width.value(ds)) >= -1e-6
    kinds = [(e.kind, round(e.s_m / 50.0) * 50) for e in ml.lane_events]
    assert ("end", 650) in kinds
    assert ("birth", 1250) in kinds


def test_without_lane_samples_the_road_is_one_driving_lane():
    from dataclasses import replace as dc_replace

    truth = truth_road(aux_lane=False, length_scale=0.4)
    run = sample_run(truth, seed=7)
    run = dc_replace(
        run, lane_samples=np.zeros((0, 3)), lane_sample_frame=np.zeros(0, dtype=np.int64)
    )
    ml = build_mainline(run)
    (sec,) = ml.road.lane_sections
    assert [ln.type for ln in sec.right] == ["driving"]
    width = sec.right[0].width.value(np.linspace(0.0, ml.road.length, 20))
    np.testing.assert_allclose(width, 14.5, atol=0.05)
    assert np.isnan(ml.residuals["lane_boundary"])


def test_outer_edge_steps_are_located_to_the_metre_at_half_point_density():
    from roadtwin.mainline import fit_outer_edge

    rng = np.random.default_rng(11)
    grid = np.arange(0.0, 1201.0)
    # exit gore at 400 m (deceleration lane ends: the edge steps 6 m inwards, the ramp's
    # edge goes on outside), entry gore at 800 m (the edge steps outwards); two points per
    # metre with random spacing (half the simulator's density), 3 cm noise
    s = np.arange(0.0, 1200.0, 0.5) + rng.uniform(0.0, 0.5, 2400)
    low = (s >= 400.0) & (s < 800.0)
    d = np.where(low, 12.0, 18.0) + rng.normal(0.0, 0.03, s.size)
    s_r = s[low & (rng.uniform(size=s.size) < 0.5)]
    s = np.concatenate([s, s_r])
    d = np.concatenate([d, 18.0 + 0.02 * np.minimum(s_r - 400.0, 800.0 - s_r)])
    edge, breaks, _, _ = fit_outer_edge(s, d, grid)
    np.testing.assert_allclose(breaks, [400.0, 800.0], atol=0.5)
    np.testing.assert_allclose(edge[410:790], 12.0, atol=0.03)
    np.testing.assert_allclose(edge[:390], 18.0, atol=0.03)


def test_points_of_another_level_give_no_superelevation():
    """Edge points of a ramp passing 5 m under the road beside it (same xy band) are not
    road surface: no superelevation appears and the elevation stays within centimetres."""
    road = truth_road(aux_lane=False)
    run = sample_run(road)
    s, t = road.project(run.edges)
    # a stretch of the outer side seen 5 m lower (an underpass beside the carriageway)
    low = (s > 600.0) & (s < 700.0) & (t < -8.0)
    edges = run.edges.copy()
    edges[low, 2] -= 5.0
    built = build_mainline(replace(run, edges=edges))
    assert built.road.superelevation is None
    s_chk = np.arange(50.0, built.road.length - 50.0, 5.0)
    xy = built.road.xy(s_chk)
    s_true, _ = road.project(xy)
    dz = built.road.height(s_chk) - road.height(s_true)
    assert float(np.max(np.abs(dz))) < 0.05


def test_points_beyond_the_median_edge_at_another_level_give_no_superelevation():
    """melbourne-408-opp-s4: median-side edge points 2.5 m beyond the road's edge lay
    0.8-2 m lower (an inner ramp falling away beside the road), close enough to the car's
    level to pass the height gate; fitted as road surface they made a 0.1 rad cross slope
    out of a flat road. Only points on the fitted median edge give the road's heights."""
    road = truth_road(aux_lane=False)
    run = sample_run(road)
    s, _ = road.project(run.edges)
    median = run.edge_side == 1  # right-hand traffic: the median side is left (t > 0)
    take = median & (s > 500.0) & (s < 800.0)
    extra = run.edges[take].copy()
    beyond = road.xy(s[take]) + 2.5 * np.column_stack(
        [-np.sin(road.heading(s[take])), np.cos(road.heading(s[take]))]
    )
    extra[:, :2] = beyond
    extra[:, 2] -= 0.8 + 1.2 * (s[take] - 500.0) / 300.0
    edges = np.vstack([run.edges, extra])
    sides = np.concatenate([run.edge_side, run.edge_side[take]])
    built = build_mainline(replace(run, edges=edges, edge_side=sides))
    assert built.road.superelevation is None
    s_chk = np.arange(50.0, built.road.length - 50.0, 5.0)
    s_true, _ = road.project(built.road.xy(s_chk))
    dz = built.road.height(s_chk) - road.height(s_true)
    assert float(np.max(np.abs(dz))) < 0.05


def test_cut_at_a_lane_offset_step_leaves_no_sliver_of_the_old_offset(right_case):
    # a median-side step of 3.5 m a hair (0.1 micrometre) after the cut, as at an inner
    # gore where the junction starts: the road after the cut starts on the new offset
    # (a sliver of the old one made esmini's car jump 3.5 m into the connecting road)
    _, _, ml = right_case
    road = replace(
        ml.road,
        lane_offset=CubicProfile((CubicPiece(0.0, 3.5), CubicPiece(600.0 + 1.3e-7, 0.0))),
    )
    before = cut_road(road, 10.0, 600.0, road_id="1")
    after = cut_road(road, 600.0, 900.0, road_id="2")
    assert [p.a for p in before.lane_offset.pieces] == [3.5]
    assert [p.a for p in after.lane_offset.pieces] == [0.0]
    assert after.lane_offset.pieces[0].s0 == 0.0
    # a step well inside a cut road stays where it is
    inside = cut_road(road, 500.0, 700.0, road_id="3")
    assert [(round(p.s0, 6), p.a) for p in inside.lane_offset.pieces] == [(0.0, 3.5), (100.0, 0.0)]


def _road_with_a_lane_beginning_at_a_step(offset_m: float, length_m: float) -> Road:
    """A straight road whose median-side edge steps out by ``offset_m`` at 200 m, where
    an inner lane (3.50 m) and a narrower inner shoulder begin on the median side."""
    before = _section(0.0, [0.78, 3.5, 3.5], ["shoulder", "driving", "driving"], ["solid"] * 3, 1)
    after = _section(
        200.0,
        [0.79, 3.5, 3.5, 3.5],
        ["shoulder", "driving", "driving", "driving"],
        ["solid"] * 4,
        1,
    )
    after = replace(
        after,
        right=tuple(
            replace(ln, predecessor=ln.id + 1 if ln.id <= -3 else None) for ln in after.right
        ),
    )
    return Road(
        "1",
        chain_geometry([Line(0, 0.0, 0.0, 0.0, length_m)]),
        (before, after),
        lane_offset=CubicProfile((CubicPiece(0.0, 0.0), CubicPiece(200.0, offset_m))),
    )


def test_lanes_linked_across_a_lane_offset_step_stay_joined():
    from roadtwin.mainline.reference import _join_lanes_across_offset_steps

    # an inner lane (3.50 m) and a narrower inner shoulder join at 200 m on the median
    # side; the measured offset step (3.49 m) disagrees with the lane widths by 1 cm +
    # the shoulders' difference: the through lanes would jump sideways at the step
    road = _road_with_a_lane_beginning_at_a_step(3.49, 400.0)
    joined = _join_lanes_across_offset_steps(road, np.array([200.0]))
    for lid_before, lid_after in ((-2, -3), (-3, -4)):
        t0 = joined.lane_border_t(np.array([200.0 - 1e-6]), lid_before)[0]
        t1 = joined.lane_border_t(np.array([200.0]), lid_after)[0]
        assert abs(t1 - t0) < 1e-6
    # the raw offsets left a 2 cm jump
    gap = (
        road.lane_border_t(np.array([200.0]), -3)[0]
        - road.lane_border_t(np.array([200.0 - 1e-6]), -2)[0]
    )
    assert abs(gap) > 0.015
    assert joined.lane_offset.pieces[0].a == 0.0


def test_an_offset_step_that_disagrees_with_the_lanes_by_decimetres_stays_measured():
    """oakland-28393854-s7: the median edge steps out by 12.24 m, the lane widths said
    12.43 m. Re-levelling moved the 800 m after the step 0.18 m off the measured median
    edge, and every lane border with it (lane RMSE 0.110 -> 0.034 m without). The offset
    stays as measured; the lanes beginning at the step take up the difference."""
    from roadtwin.mainline.reference import _join_lanes_across_offset_steps
    from roadtwin.mainline.seal import seal_lane_borders

    # as in the test above, but the measured step is 3.67 m: 0.18 m more than the lanes
    road = _road_with_a_lane_beginning_at_a_step(3.67, 800.0)
    before = road.lane_sections[0]
    joined = _join_lanes_across_offset_steps(road, np.array([200.0]))
    assert [p.a for p in joined.lane_offset.pieces] == [0.0, 3.67]
    sealed = seal_lane_borders(joined)
    for lid_before, lid_after in ((-2, -3), (-3, -4)):
        t0 = sealed.lane_border_t(np.array([200.0 - 1e-6]), lid_before)[0]
        t1 = sealed.lane_border_t(np.array([200.0]), lid_after)[0]
        assert abs(t1 - t0) < 1e-6
    # the median edge and, 100 m past the step, every border lie where they were measured
    s = np.array([200.0, 300.0])
    assert np.allclose(sealed.lane_border_t(s, 0), road.lane_border_t(s, 0), atol=1e-9)
    far = np.array([300.0])
    for lid in (-1, -2, -3, -4):
        assert sealed.lane_border_t(far, lid)[0] == pytest.approx(
            road.lane_border_t(far, lid)[0], abs=1e-6
        )
    # where every lane goes on across the border, none can take the difference up: the
    # segment moves (krems-30799129 +80: else a 0.16 m gap across a road link)
    same = _section(200.0, [0.78, 3.5, 3.5], ["shoulder", "driving", "driving"], ["solid"] * 3, 1)
    same = replace(same, right=tuple(replace(ln, predecessor=ln.id) for ln in same.right))
    through = replace(
        road,
        lane_sections=(before, same),
        lane_offset=CubicProfile((CubicPiece(0.0, 0.0), CubicPiece(200.0, 0.16))),
    )
    moved = _join_lanes_across_offset_steps(through, np.array([200.0]))
    assert moved.lane_offset.pieces[1].a == pytest.approx(0.0, abs=1e-9)


def _const_track(tid, grid, d, lo, hi, n=100):
    from roadtwin.mainline.markings import _Track

    s = grid[(grid >= lo) & (grid <= hi)]
    dd = d(s) if callable(d) else np.full(s.size, d)
    return _Track(tid, lo, hi, s, dd, "broken", n, s)


def test_inferred_median_side_lanes_end_where_the_innermost_marking_does():
    """Oakland-like: the two innermost markings end and the median-side edge steps 3 m
    later (the carriageway splits on the median side); the line inferred from the
    innermost one must not jump a lane inwards with the next marking for its last metres
    (it bent every lane by 1.5-1.9 m there)."""
    from roadtwin.mainline.hidden_lanes import _add_hidden_lanes

    cfg = MainlineConfig()
    grid = np.arange(0.0, 400.5, cfg.grid_step_m)

    def track(tid: int, d: float, hi: float):
        return _const_track(tid, grid, d, 0.0, hi)

    observed = [track(0, 4.8, 370.0), track(1, 8.5, 371.0), track(2, 12.0, 400.0)]
    observed += [track(3, 15.6, 400.0)]
    # the median-side edge steps to the through lanes where the split is complete
    d_median = np.where(grid < 373.9, 0.0, 11.66)
    out = _add_hidden_lanes(observed, grid, np.full(grid.size, 18.5), d_median, cfg)
    inferred = [tr for tr in out if tr.n == 0 and float(np.median(tr.d)) < 4.8]
    assert inferred, "the inner shoulder's edge line between median edge and 4.8 m"
    for tr in inferred:
        assert float(np.max(np.abs(np.diff(tr.d)))) < 0.1
        assert tr.hi <= 371.0
        assert float(np.max(tr.d)) < 4.8 - 2.5


def _shifting_pattern(offsets, seen=None):
    """Lines at ``offsets`` (metres) over 0-600 m that shift 3.4 m outwards over 290-340 m
    (a lane opening on the median side), the outer edge beside them, the grid and config;
    ``seen`` maps an offset to the stretches ``(lo, hi)`` where that line was seen."""
    cfg = MainlineConfig()
    grid = np.arange(0.0, 600.5, cfg.grid_step_m)

    def shift(s):
        x = np.clip((s - 290.0) / 50.0, 0.0, 1.0)
        return 3.4 * x * x * (3.0 - 2.0 * x)

    tracks = []
    for d in offsets:
        for lo, hi in (seen or {}).get(d, [(0.0, 600.0)]):
            tracks.append(_const_track(len(tracks), grid, lambda s, d=d: d + shift(s), lo, hi))
    return tracks, 13.8 + shift(grid), grid, cfg


def test_a_lane_opening_on_the_median_side_as_the_lanes_shift_keeps_the_shoulder():
    """The whole marking pattern shifts 3.4 m outwards over 290-340 m while a lane opens
    on the median side; the inner shoulder's solid line at 1.0 m is out of the sensor's
    reach from there, and the innermost marking seen is the line that moves away from it.
    The shoulder's line is inferred at 1.0 m from where the marking starts to move, and
    the lane beside it opens from zero width there (melbourne-1226-s11: the shoulder grew
    with the marking and was split into shoulder and lane only 45 m later, where the
    strip had become a lane wide: lines 0.3-0.6 m off, lane count wrong over 17 m)."""
    from roadtwin.mainline.hidden_lanes import _add_hidden_lanes

    tracks, d_edge, grid, cfg = _shifting_pattern((1.0, 4.4, 7.8, 11.2))
    out = _add_hidden_lanes(tracks, grid, d_edge, np.zeros(grid.size), cfg)
    added = [tr for tr in out if tr.n == 0]
    assert len(added) == 1
    (line,) = added
    assert line.lo == pytest.approx(290.0, abs=5.0)
    at = np.interp([300.0, 315.0, 330.0, 345.0, 400.0], line.s, line.d)
    assert np.max(np.abs(at - 1.0)) < 0.05
    # the lane between it and the moving marking opens from zero width
    lane_at_start = float(np.interp(line.lo, tracks[0].s, tracks[0].d)) - float(line.d[0])
    assert lane_at_start < 0.3


def test_no_shoulder_is_held_where_a_line_is_first_seen_as_the_lanes_shift():
    """As above, but a line is first seen (seen again) where the pattern shifts: the
    lanes there are what the sensor saw, and no shoulder line is held from where the shift
    began; the hidden lane is inferred where the strip is a lane wide, as before
    (melbourne-408-opp-s4: two lanes opening one after the other, first seen as they
    opened, were cut into tapers by a held shoulder and jumped by a metre at a section
    border)."""
    from roadtwin.mainline.hidden_lanes import _add_hidden_lanes

    # the line between the second and the third lane: seen up to 295 m, then from 315 m
    tracks, d_edge, grid, cfg = _shifting_pattern(
        (1.0, 4.4, 7.8, 11.2), seen={7.8: [(0.0, 295.0), (315.0, 600.0)]}
    )
    out = _add_hidden_lanes(tracks, grid, d_edge, np.zeros(grid.size), cfg)
    added = [tr for tr in out if tr.n == 0]
    assert added
    assert all(tr.lo > 325.0 for tr in added)


def test_an_inferred_line_continues_the_observed_one_it_takes_over_from():
    """The inner edge line is seen for 300 m, then the car moves out and only the markings
    near it are seen: the line inferred on from there is the same line, not a new one (a
    new track started a lane there that opened over 100 m, copying a neighbour's taper)."""
    from roadtwin.mainline.hidden_lanes import _add_hidden_lanes

    cfg = MainlineConfig()
    grid = np.arange(0.0, 600.5, cfg.grid_step_m)

    def track(tid: int, d: float, hi: float):
        return _const_track(tid, grid, d, 0.0, hi)

    observed = [track(0, 1.2, 300.0), track(1, 4.8, 600.0), track(2, 8.4, 600.0)]
    out = _add_hidden_lanes(observed, grid, np.full(grid.size, 14.5), np.zeros(grid.size), cfg)
    assert len(out) == 3
    inner = out[0]
    assert inner.n > 0
    assert inner.hi == pytest.approx(600.0, abs=1.0)
    assert float(np.max(np.abs(inner.d - 1.2))) < 0.05


def _line_ending_at_300(outer_offsets):
    """Lines at 4.8 m (on), 8.3 m (ends at s=300) and one beyond whose offset follows
    ``outer_offsets`` at s = 0, 300, 330/400, 600; returns the tracks and the result of
    continuing ended lines."""
    from roadtwin.mainline.markings import _continue_to_convergence

    cfg = MainlineConfig()
    grid = np.arange(0.0, 600.5, cfg.grid_step_m)
    stations, offsets = outer_offsets

    def outer(s):
        return np.interp(s, stations, offsets)

    tracks = [
        _const_track(0, grid, 4.8, 0.0, 600.0),
        _const_track(1, grid, 8.3, 0.0, 300.0),
        _const_track(2, grid, outer, 0.0, 600.0),
    ]
    return tracks, _continue_to_convergence(tracks, grid, cfg)


def test_a_line_ending_where_a_lane_drop_taper_begins_runs_on_to_where_the_lane_closes():
    """Town06: the broken line between the lane that goes on and the one that drops ends
    where the taper begins; the edge line beyond converges onto it over 30 m. Without the
    line the two lanes were one lane 7 m wide; continued, the outer lane closes to zero."""
    tracks, out = _line_ending_at_300(([0.0, 300.0, 330.0, 600.0], [11.8, 11.8, 8.3, 8.3]))
    ended = out[1]
    assert ended.hi == pytest.approx(330.0, abs=2.0)
    assert float(np.max(np.abs(ended.d - 8.3))) < 1e-9
    # the lane between the continued line and the edge line closes to zero at its end
    assert abs(float(np.interp(ended.hi, out[2].s, out[2].d)) - 8.3) < 0.3
    # the others are unchanged
    assert out[0] is tracks[0]
    assert out[2] is tracks[2]


def test_a_line_is_not_run_back_to_a_split_where_the_lanes_shift_sideways():
    """Town06 after an inner exit: the lanes shift 3 m sideways over 80 m. The outer edge
    line is seen from 170 m on, 0.5 m inside the shoulder line; before that both moved in
    from 3 m farther out. Run back flat to where the shifting line beside it was at its
    offset (a lane "opening" there), it cut the narrowing outer lane into a sliver under
    1 m, a shoulder opened from zero between two driving lanes, and esmini warned of a lane
    without a connecting lane (town06-auto-s2)."""
    from roadtwin.mainline.markings import _continue_to_convergence

    cfg = MainlineConfig()
    grid = np.arange(0.0, 300.5, cfg.grid_step_m)

    def shifting(before, after, end=180.0):
        return lambda s: np.interp(s, [0.0, 100.0, end, 300.0], [before, before, after, after])

    tracks = [
        _const_track(0, grid, shifting(11.65, 8.1), 0.0, 300.0),
        _const_track(1, grid, shifting(15.15, 11.6), 0.0, 300.0),
        _const_track(2, grid, 15.13, 170.0, 300.0),
        _const_track(3, grid, shifting(18.6, 15.7, end=170.0), 0.0, 300.0),
    ]
    out = _continue_to_convergence(tracks, grid, cfg)
    assert out[2].lo == pytest.approx(170.0, abs=1e-9)
    # a real lane opening (nothing converging beside the line) is still run back
    tracks[3] = _const_track(3, grid, 18.6, 0.0, 300.0)
    assert _continue_to_convergence(tracks, grid, cfg)[2].lo < 120.0


def test_a_line_ending_at_an_exit_is_not_continued():
    """At an exit the line beyond the ended one leaves (diverges): no taper to continue."""
    _, out = _line_ending_at_300(([0.0, 300.0, 400.0, 600.0], [11.8, 11.8, 20.0, 30.0]))
    assert out[1].hi == 300.0


def test_a_driving_lane_refitted_up_to_1_m_wider_or_narrower_after_a_section_border_goes_on():
    """Town06 inner entry: the outer driving lane is 3.42 m wide before the border and
    3.83 m after it (its outer line seen again). Its outer borders differ by 0.41 m, more
    than the border tolerance, yet it is the same lane: linked, it continues with the
    width it had; unlinked, a car in it had nowhere to go."""
    from roadtwin.mainline.section_links import _link_sections
    from roadtwin.model import LaneSection

    lane = _flat_lane

    first = LaneSection(
        0.0, right=(lane(-1, 1.0, "shoulder"), lane(-2, 3.5), lane(-3, 3.42), lane(-4, 0.5))
    )
    second = LaneSection(
        100.0, right=(lane(-1, 1.0, "shoulder"), lane(-2, 3.5), lane(-3, 3.83), lane(-4, 0.5))
    )
    linked = _link_sections([first, second], [[], []], at_step=[False, False])
    after = linked[1].right
    assert after[2].predecessor == -3
    assert linked[0].right[2].successor == -3
    assert float(after[2].width.value(np.array([0.0]))[0]) == pytest.approx(3.42, abs=1e-9)
    # a shoulder is no driving lane: a hard shoulder starting beside a gore stays unlinked
    third = LaneSection(
        100.0, right=(lane(-1, 1.0, "shoulder"), lane(-2, 3.5), lane(-3, 3.83, "shoulder"))
    )
    assert (
        _link_sections([first, third], [[], []], at_step=[False, False])[1].right[2].predecessor
        is None
    )
    # 0.9 m narrower (a9 opposite carriageway past an exit: 4.59 -> 3.69 m): the same
    # lane; 1.2 m: another one
    narrower = LaneSection(
        100.0, right=(lane(-1, 1.0, "shoulder"), lane(-2, 3.5), lane(-3, 2.52), lane(-4, 0.5))
    )
    assert (
        _link_sections([first, narrower], [[], []], at_step=[False, False])[1].right[2].predecessor
        == -3
    )
    much = LaneSection(
        100.0, right=(lane(-1, 1.0, "shoulder"), lane(-2, 3.5), lane(-3, 2.22), lane(-4, 0.5))
    )
    assert (
        _link_sections([first, much], [[], []], at_step=[False, False])[1].right[2].predecessor
        is None
    )


def test_a_lane_split_by_a_line_first_seen_inside_it_goes_on_as_the_widest():
    """melbourne-408-opp-s4 with a noisier sensor (seed offset 260): where two lanes are
    added beside the median a new line was first seen 1.34 m inside the innermost lane,
    and the lanes after the border (1.34, 0 and 2.08 m) spanned it exactly; no border met
    another within 0.3 m, the lane led nowhere (a route failed) and two lanes began at
    full width from nothing. The lane goes on as the widest of them, the others open from
    zero: every border stays where it was."""
    from roadtwin.mainline.section_links import _link_sections
    from roadtwin.model import LaneSection

    lane = _flat_lane

    first = LaneSection(
        0.0,
        right=(lane(-1, 1.0, "shoulder"), lane(-2, 3.42), lane(-3, 3.4), lane(-4, 1.0, "shoulder")),
    )
    second = LaneSection(
        100.0,
        right=(
            lane(-1, 1.0, "shoulder"),
            lane(-2, 1.34),
            lane(-3, 0.0),
            lane(-4, 2.08),
            lane(-5, 3.4),
            lane(-6, 1.0, "shoulder"),
        ),
    )
    linked = _link_sections([first, second], [[], []], at_step=[False, False])
    after = linked[1].right
    assert after[3].predecessor == -2
    assert linked[0].right[1].successor == -4
    widths = [float(ln.width.value(np.array([0.0]))[0]) for ln in after]
    assert widths == pytest.approx([1.0, 0.0, 0.0, 3.42, 3.4, 1.0], abs=1e-9)
    # a lane that goes on at its borders is not split
    plain = LaneSection(
        100.0,
        right=(lane(-1, 1.0, "shoulder"), lane(-2, 3.42), lane(-3, 3.4), lane(-4, 1.0, "shoulder")),
    )
    again = _link_sections([first, plain], [[], []], at_step=[False, False])[1].right
    assert [ln.predecessor for ln in again] == [-1, -2, -3, -4]


def test_a_driving_lane_goes_on_where_the_inner_shoulders_line_is_first_seen():
    """melbourne-921-s2 past its inner exit: the innermost lane is 3.74 m wide from the
    median-side edge (its shoulder's line not seen) and from 647 m a 0.57 m shoulder and a
    3.41 m lane span it. No border met within 0.3 m (the inner ones are the shoulder's
    width apart), the lane led nowhere and a route failed. The lane goes on; the shoulder
    opens from zero width."""
    from roadtwin.mainline.section_links import _link_sections
    from roadtwin.model import LaneSection

    lane = _flat_lane

    first = LaneSection(0.0, left=(lane(1, 3.74), lane(2, 3.33), lane(3, 2.55, "shoulder")))
    second = LaneSection(
        42.0,
        left=(lane(1, 0.57, "shoulder"), lane(2, 3.41), lane(3, 3.28), lane(4, 2.55, "shoulder")),
    )
    linked = _link_sections([first, second], [[], []], at_step=[False, False])
    before, after = linked[0].left, linked[1].left
    assert (before[0].successor, after[1].predecessor) == (2, 1)
    assert (before[1].successor, after[2].predecessor) == (3, 2)
    assert after[0].predecessor is None
    # the shoulder opens from zero and the lane goes on with the width it had
    assert float(after[0].width.value(np.array([0.0]))[0]) == pytest.approx(0.0, abs=1e-9)
    assert float(after[1].width.value(np.array([0.0]))[0]) == pytest.approx(3.74, abs=1e-9)
    # a lane beginning beside it that is a lane wide is a new lane, not this one's rest
    wide = LaneSection(
        42.0,
        left=(lane(1, 3.4, "driving"), lane(2, 3.41), lane(3, 3.28), lane(4, 2.55, "shoulder")),
    )
    relinked = _link_sections([first, wide], [[], []], at_step=[False, False])
    assert relinked[1].left[1].predecessor != 1


def test_a_line_is_continued_to_where_the_converging_line_settles_beside_it():
    """The line beyond converges and settles 0.7 m outside the ended line's offset (the
    lane that goes on is a little wider after the drop): it met it where it came nearest,
    within a quarter lane."""
    _, out = _line_ending_at_300(([0.0, 300.0, 330.0, 600.0], [11.8, 11.8, 9.0, 9.0]))
    assert out[1].hi == pytest.approx(330.0, abs=2.0)
    # settling a lane away is no meeting
    _, apart = _line_ending_at_300(([0.0, 300.0, 330.0, 600.0], [11.8, 11.8, 10.0, 10.0]))
    assert apart[1].hi == 300.0


def _line_track(k: int, grid: np.ndarray, d: np.ndarray):
    from roadtwin.mainline.markings import _Track

    return _Track(k, float(grid[0]), float(grid[-1]), grid, d, "broken", grid.size, grid)


def test_a_lane_too_wide_between_observed_markings_gets_its_missed_line():
    """A lane added by a 100 m taper beside the through lane: the car saw the diverging
    line but not the new straight one. Where the two observed lines lie more than a lane
    plus 1.5 m apart over 30 m, the missed line is inferred a lane from the steady one
    (the through lane's); three lanes wide: two lines evenly spaced; a short wide stretch
    (20 m) is left alone."""
    from roadtwin.mainline.hidden_lanes import _wide_lane_lines

    grid = np.arange(0.0, 401.0, 1.0)
    x = np.clip((grid - 100.0) / 100.0, 0.0, 1.0)
    steady = _line_track(0, grid, np.full(grid.size, 3.6))
    diverging = _line_track(1, grid, 7.2 + 3.6 * x * x * (3.0 - 2.0 * x))
    lines = _wide_lane_lines([steady, diverging], grid, 3.6, 1.5)
    assert len(lines) == 1
    a, b, d = lines[0]
    # the gap exceeds 5.1 m from s = 144.4 m (the smoothstep reaches 1.5 of 3.6) to the end
    assert grid[a] == pytest.approx(145.0, abs=1.0)
    assert grid[b - 1] == 400.0
    assert np.allclose(d, 7.2)
    # three lanes between steady lines 10.8 m apart: lines at 3.6 and 7.2
    wide = _line_track(1, grid, np.full(grid.size, 10.8))
    flat = _line_track(0, grid, np.zeros(grid.size))
    got = sorted(float(np.median(d)) for _, _, d in _wide_lane_lines([flat, wide], grid, 3.6, 1.5))
    assert got == pytest.approx([3.6, 7.2])
    # wide over 20 m only: a gore's diverging lines before they end, not a lane
    bump = np.where((grid > 200.0) & (grid < 220.0), 9.0, 7.2)
    assert _wide_lane_lines([steady, _line_track(1, grid, bump)], grid, 3.6, 1.5) == []


def test_a_median_side_step_is_sized_so_that_the_edge_line_runs_on_smoothly():
    """The median-side edge steps 9 m towards the carriageway at s=500 (a 3-lane left exit
    leaves); the first estimate of the step, measured in a frame that already bent, is
    1.5 m short. Sized by the smoothest line through both sides it is 9 m (within 0.1 m);
    a step measured right stays as it was."""
    from roadtwin.fitting import PolylineFrame
    from roadtwin.mainline.edge_levels import EdgeSteps
    from roadtwin.mainline.reference import _smoothest_steps

    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 1000.0, 1001)
    frame = PolylineFrame.from_points(np.stack([x, 0.002 * x], axis=1))
    s = np.sort(rng.uniform(0.0, 1000.0, 6000))
    t = np.where(s < 500.0, 0.0, -9.0) + rng.normal(0.0, 0.03, s.size)
    cfg = MainlineConfig()
    off = _smoothest_steps(
        frame, s, t, 1.0, EdgeSteps(np.array([500.0]), np.array([0.0, -7.5])), cfg
    )
    assert off.offsets[1] == pytest.approx(-9.0, abs=0.1)
    right = _smoothest_steps(
        frame, s, t, 1.0, EdgeSteps(np.array([500.0]), np.array([0.0, -9.0])), cfg
    )
    assert right.offsets[1] == pytest.approx(-9.0, abs=0.05)


def _smoothstep(s, s0: float, length: float):
    x = np.clip((s - s0) / length, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _tracks_600(ss, dd, seed: int, edge_of):
    """Marking tracks of a 600 m run from lane samples ``(ss, dd)`` (2 cm noise added)
    and the outer edge ``edge_of(grid)``."""
    from roadtwin.mainline.markings import _tracks_from_samples

    cfg = MainlineConfig()
    dd = dd + np.random.default_rng(seed).normal(0.0, 0.02, dd.size)
    grid = np.arange(0.0, 600.0 + 0.5 * cfg.grid_step_m, cfg.grid_step_m)
    return _tracks_from_samples(ss, dd, grid, 600.0, cfg, edge_of(grid))


def _diverging_at_run_end(edge_offset_m: float | None):
    """Marking tracks of a 600 m run whose outer solid line (7.2 m) starts to diverge at
    s = 500 m (smoothstep, 3.6 m over 150 m: still diverging where the run ends), while a
    broken line goes on at 7.2 m from 520 m; the outer edge runs ``edge_offset_m`` outside
    the diverging line (None: straight at 8.5 m, so the line leaves the corridor)."""
    s = np.arange(0.0, 600.0, 0.25)
    diverging = 7.2 + 3.6 * _smoothstep(s, 500.0, 150.0)
    dashes = (s % 12.0) < 3.0
    straight = s >= 520.0
    ss = np.concatenate([s[dashes], s, s[dashes & straight]])
    dd = np.concatenate(
        [np.full(int(dashes.sum()), 3.6), diverging, np.full(int((dashes & straight).sum()), 7.2)]
    )

    def edge_of(grid):
        if edge_offset_m is None:
            return np.full(grid.size, 8.5)
        return 7.2 + 3.6 * _smoothstep(grid, 500.0, 150.0) + edge_offset_m

    return _tracks_600(ss, dd, 3, edge_of)


def test_a_line_diverging_inside_the_edge_where_the_run_ends_is_the_mainlines_own():
    """Oakland I-880: a lane opens on the outside by a taper that the run ends in (the
    edge moves out with the line, no ramp). The diverging line had been cut off as a ramp
    line leaving the corridor: the lane was never built and its outer line was 3.6 m off.
    Inside the measured edge to the run's end, it is kept; a line that runs out of the
    corridor is still cut (gore evidence)."""
    tracks, evidence = _diverging_at_run_end(3.0)
    outer = max(tracks, key=lambda tr: float(tr.d[-1]))
    assert outer.hi == pytest.approx(600.0, abs=2.0)
    assert float(outer.d[-1]) == pytest.approx(7.2 + 3.6 * 0.74, abs=0.15)
    assert evidence == []
    # the straight broken line goes on beside it: one lane more at the end
    assert sum(1 for tr in tracks if tr.hi >= 585.0) == 3
    tracks, evidence = _diverging_at_run_end(None)
    assert max(float(tr.d[-1]) for tr in tracks) < 7.5
    assert len(evidence) == 1


def _converging_edge_line(edge_offset_m: float | None, *, nose: bool = False):
    """Marking tracks of a 600 m run with broken lines at 3.6 and 7.2 m and a solid line
    that comes in from 10.8 m to 7.2 m between s = 250 and 350 m (smoothstep) and runs on
    there; before s = 270 m it was not seen (worn or occluded). The outer edge runs
    ``edge_offset_m`` outside the solid line (None: straight at 9.5 m, so the line comes
    in from outside the corridor, as an entry's line does before its gore); with ``nose``
    it is ``edge_offset_m`` outside the 7.2 m line up to s = 265 m and steps out there (an
    entry's nose: the ramp's inner line converges onward inside the edge)."""
    s = np.arange(0.0, 600.0, 0.25)
    solid = 10.8 - 3.6 * _smoothstep(s, 250.0, 100.0)
    dashes = (s % 12.0) < 3.0
    seen = s >= 270.0
    through = s < 350.0
    ss = np.concatenate([s[dashes], s[dashes & through], s[seen]])
    dd = np.concatenate(
        [
            np.full(int(dashes.sum()), 3.6),
            np.full(int((dashes & through).sum()), 7.2),
            solid[seen],
        ]
    )

    def edge_of(grid):
        if edge_offset_m is None:
            return np.full(grid.size, 9.5)
        edge = 10.8 - 3.6 * _smoothstep(grid, 250.0, 100.0) + edge_offset_m
        if nose:  # the edge steps out by the ramp's width where the line is first seen
            edge = np.where(grid < 265.0, 7.2 + edge_offset_m, edge)
        return edge

    return _tracks_600(ss, dd, 4, edge_of)


def test_a_lane_drops_edge_line_converging_inside_the_edge_is_the_mainlines_own():
    """The edge line of a lane drop converges onto the next line over 100 m (0.054 m/m,
    steeper than a ramp line's 0.012) with the measured edge closing in beside it. It had
    been cut off as an entry's line: the lane then ended where the cut line began. Inside
    the edge all along it is kept from where it was first seen (mid-taper); a line coming
    in from outside the edge, or from an entry's nose, is still cut (gore evidence)."""
    tracks, evidence = _converging_edge_line(2.5)
    solid = max(tracks, key=lambda tr: float(tr.d[0]))
    assert solid.lo == pytest.approx(270.0, abs=3.0)
    assert float(np.interp(300.0, solid.s, solid.d)) == pytest.approx(9.0, abs=0.15)
    assert evidence == []
    tracks, evidence = _converging_edge_line(None)
    assert all(float(tr.d[0]) < 7.5 for tr in tracks)
    assert len(evidence) == 1
    # past an entry's nose the ramp's inner line converges inside the edge too, with the
    # ramp's lane and shoulder beyond it: still cut (the painted gore is not a lane of the
    # mainline)
    tracks, evidence = _converging_edge_line(6.0, nose=True)
    assert all(float(tr.d[0]) < 7.5 for tr in tracks)
    assert len(evidence) == 1
    # with only a shoulder beyond it the line is an acceleration lane's, closing by a taper
    # from the nose on (a taper-type entry): kept from where it is first seen
    tracks, evidence = _converging_edge_line(2.5, nose=True)
    solid = max(tracks, key=lambda tr: float(tr.d[0]))
    assert solid.lo == pytest.approx(270.0, abs=3.0)
    assert evidence == []


def test_median_side_lanes_between_an_inner_exits_paint_tip_and_nose_are_inferred():
    """town06-auto-s3: an inner exit's two lanes leave 56 m before the median-side edge
    steps at the nose; their lines diverge there and are cut as ramp lines, so between
    tip and nose the strip from the median edge to the first through line was one lane
    8.1 m wide, the exit was attached at its OSM station 40 m early and a route failed.
    Hidden median-side lanes are inferred over 30 m or more (they were over 60 m only):
    the two lanes run on to the nose, where they end at the step (a gore the ramp stage
    matches)."""
    from roadtwin.mainline.hidden_lanes import _add_hidden_lanes

    cfg = MainlineConfig()
    grid = np.arange(0.0, 600.5, cfg.grid_step_m)
    tracks = [
        _const_track(0, grid, 1.1, 0.0, 300.0),
        _const_track(1, grid, 4.6, 0.0, 300.0),
        _const_track(2, grid, 8.1, 0.0, 600.0),
        _const_track(3, grid, 11.6, 0.0, 600.0),
    ]
    d_median = np.where(grid < 345.0, 0.0, 7.0)  # the median edge steps in at the nose
    d_edge = np.full(grid.size, 14.6)
    out = _add_hidden_lanes(tracks, grid, d_edge, d_median, cfg)
    inner = sorted((tr for tr in out if float(tr.d[0]) < 6.0), key=lambda tr: float(tr.d[0]))
    # the two innermost lines go on from 300 m to the step, continuing the observed ones
    assert [round(float(np.median(tr.d)), 1) for tr in inner] == [1.1, 4.6]
    for tr in inner:
        assert tr.lo == 0.0
        assert tr.hi == pytest.approx(345.0, abs=2.0)


def test_a_line_ending_where_the_edge_closes_the_lane_beyond_it_runs_on_to_the_edge():
    """No hard shoulder: the outer lane closes with the edge itself converging onto the
    line between it and the through lane, and that line ends where the taper begins. The
    edge is then the neighbour that meets it (krems-102561705-s2: the two lanes were one
    over 100 m): the line runs on to where the edge reaches it and the lane closes there.
    Not where the edge was not seen (a truck beside the car), not where it drifts onto the
    line over hundreds of metres (an exit's edge past the gore: the bundled
    left_hand_2km), and not with a hard shoulder (the edge settles beyond the line)."""
    from roadtwin.mainline.markings import _continue_to_convergence

    cfg = MainlineConfig()
    grid = np.arange(0.0, 600.5, cfg.grid_step_m)
    tracks = [_const_track(0, grid, 3.6, 0.0, 600.0), _const_track(1, grid, 7.2, 0.0, 300.0)]
    d_edge = 10.8 - 3.6 * _smoothstep(grid, 300.0, 40.0)
    out = _continue_to_convergence(tracks, grid, cfg, d_edge)
    # the edge comes within 0.3 m of the line at s = 333 m (smoothstep over 300-340 m)
    assert out[1].hi == pytest.approx(333.0, abs=1.0)
    assert float(np.max(np.abs(out[1].d - 7.2))) < 1e-9
    assert out[0] is tracks[0]
    assert _continue_to_convergence(tracks, grid, cfg)[1].hi == 300.0
    unseen = np.where((grid > 310.0) & (grid < 330.0), np.nan, d_edge)
    assert _continue_to_convergence(tracks, grid, cfg, unseen)[1].hi == 300.0
    drifting = 10.8 - 3.6 * _smoothstep(grid, 300.0, 200.0)
    assert _continue_to_convergence(tracks, grid, cfg, drifting)[1].hi == 300.0
    assert _continue_to_convergence(tracks, grid, cfg, d_edge + 2.5)[1].hi == 300.0


def test_an_edge_line_going_on_as_a_lane_line_at_an_entry_is_split_where_it_parts():
    """soderleden, seed 7 (no hard shoulder): the line along the outer edge (7.0 m) goes
    on as the line between the through lanes and the acceleration lane where the entry
    widens the road at 240 m (the edge step was placed at 249 m). One track along the edge
    for 127 m and apart for 75 m was taken for the edge's line all along: the acceleration
    lane was one lane with the through lane, 7 m wide. Split where it parts from the edge,
    with the step moved there; a track mostly apart from the edge (a lane line already,
    with a hard shoulder beyond) is left whole."""
    from roadtwin.mainline.edge_lines import split_edge_lines_at_steps

    cfg = MainlineConfig()
    grid = np.arange(0.0, 400.5, cfg.grid_step_m)
    d_edge = np.where(grid < 240.0, 7.0, 10.5)
    line = _const_track(0, grid, 7.0, 113.0, 315.0)
    out, steps = split_edge_lines_at_steps([line], grid, d_edge, np.array([249.0]), 0.35)
    assert [(tr.lo, tr.hi) for tr in out] == [(113.0, 239.0), (240.0, 315.0)]
    assert steps.tolist() == [240.0]
    # the same line with a 2.5 m hard shoulder beyond it up to the step: left whole
    apart = np.where(grid < 240.0, 9.5, 10.5)
    out, steps = split_edge_lines_at_steps([line], grid, apart, np.array([249.0]), 0.35)
    assert out == [line]
    assert steps.tolist() == [249.0]


def test_markings_unseen_over_a_short_gap_join_where_the_lanes_shift_sideways():
    """town06-auto-s3, noisier sensor (seed 23): every lane line went unseen for 14 m
    while the lanes began to shift sideways (0.64 m by the end of the gap); the lines
    after the gap were new tracks, and the 21 m section between had one lane 13.9 m wide.
    A line may drift by 0.04 m per metre of gap when its pair is unambiguous."""
    from roadtwin.mainline.markings import _merge_collinear

    cfg = MainlineConfig()
    grid = np.arange(0.0, 600.5, cfg.grid_step_m)
    before = _const_track(0, grid, 9.7, 0.0, 300.0)
    after = _const_track(1, grid, 9.06, 314.0, 600.0)
    beside = _const_track(2, grid, 6.2, 0.0, 600.0)
    out = _merge_collinear([before, after, beside], cfg, grid)
    assert sorted((tr.lo, tr.hi) for tr in out) == [(0.0, 600.0), (0.0, 600.0)]
    # over a 4 m gap a line moves 0.16 m at most: 0.9 m is another line
    near = _const_track(1, grid, 9.7 - 0.9, 304.0, 600.0)
    assert len(_merge_collinear([before, near, beside], cfg, grid)) == 3
    # two lines starting 0.64 and 1.0 m off: which one continues is not clear
    other = _const_track(3, grid, 10.7, 314.0, 600.0)
    assert len(_merge_collinear([before, after, other], cfg, grid)) == 3


def test_an_edge_lane_wider_than_any_lane_is_a_shoulder_unless_the_car_drove_in_it():
    """melbourne-408-s1, noisier sensor (seed 21): the paved strip beside an entry's gore,
    6.1-9.7 m wide, was a driving lane from the mainline into the junction that led
    nowhere (the drive failed on it)."""
    from roadtwin.mainline.sections import _lane_types

    cfg = MainlineConfig()
    gs = np.arange(0.0, 50.5, 1.0)
    borders = np.array([0.0, 1.0, 4.5, 8.0, 14.5])[:, None] + np.zeros(gs.size)
    assert _lane_types(borders, gs, None, cfg) == ["shoulder", "driving", "driving", "shoulder"]
    car = (gs, np.full(gs.size, 11.0))
    assert _lane_types(borders, gs, car, cfg)[-1] == "driving"
    lane = borders.copy()
    lane[-1] = 11.8  # 3.8 m: a lane without a shoulder
    assert _lane_types(lane, gs, None, cfg)[-1] == "driving"


def test_a_lane_beyond_a_dashed_line_is_a_lane_however_narrow():
    """melbourne-18 (seed 11): five lanes, the outermost 3.2-3.4 m between a dashed line
    and the edge (no hard shoulder). Its width alone (2.2-3.3 m: a hard shoulder or a
    narrow lane) made it a shoulder over 265 m; the line beside it is dashed, and a line
    between a lane and a hard shoulder is solid."""
    from roadtwin.mainline.markings import _dashed
    from roadtwin.mainline.sections import _lane_types

    cfg = MainlineConfig()
    gs = np.arange(0.0, 300.5, 1.0)
    borders = np.array([0.0, 1.0, 4.4, 7.8, 11.1, 14.3, 17.5])[:, None] + np.zeros(gs.size)
    assert _lane_types(borders, gs, None, cfg)[-1] == "shoulder"
    assert _lane_types(borders, gs, None, cfg, (False, True))[-1] == "driving"
    assert _lane_types(borders, gs, None, cfg, (True, False))[0] == "shoulder"  # 1 m
    # dashes 6 m long every 18 m, sampled every 0.5 m, some samples missed
    rng = np.random.default_rng(3)
    s = np.arange(0.0, 300.0, 0.5)
    dashes = s[(s % 18.0) < 6.0]
    dashes = dashes[rng.random(dashes.size) > 0.1]
    assert _dashed(dashes, 0.0, 300.0, cfg)
    # US paint: 3 m dashes every 12 m
    assert _dashed(s[(s % 12.0) < 3.0], 0.0, 300.0, cfg)
    # a solid line hidden by trucks over 40 and 90 m, or worn for 30 m: not a pattern
    hidden = s[((s < 100.0) | (s > 140.0)) & ((s < 180.0) | (s > 270.0))]
    assert not _dashed(hidden, 0.0, 300.0, cfg)
    assert not _dashed(s[(s < 200.0) | (s > 230.0)], 0.0, 300.0, cfg)
    assert not _dashed(s, 0.0, 300.0, cfg)


def test_no_lane_width_dips_below_zero_between_samples():
    """oakland-11197879-s9, noisier sensor (seed 49): a shoulder opening from zero had a
    width piece 0 at both ends of 22.5 m and -2 mm between (own check: negative_width).
    Such a piece is replaced by a non-negative one between the same end values; others
    stay exactly as they were."""
    from roadtwin.mainline.seal import nonnegative_widths
    from roadtwin.model import CubicPiece, CubicProfile, Lane, LaneSection, Line, Road

    dip = CubicProfile(
        (
            CubicPiece(0.0, 0.0, 0.002507, -0.00027928, 7.460158e-06),
            CubicPiece(22.5, 0.0, 0.0, 0.0, 0.0),
            CubicPiece(40.0, 0.0, 0.05, 0.0, 0.0),
        )
    )
    lanes = (Lane(-1, "driving", CubicProfile.constant(3.5)), Lane(-2, "shoulder", dip))
    road = Road("1", (Line(0.0, 0.0, 0.0, 0.0, 60.0),), (LaneSection(0.0, right=lanes),))
    ds = np.linspace(0.0, 60.0, 6001)
    assert float(np.min(dip.value(ds))) < -1.5e-3
    fixed = nonnegative_widths(road).lane_sections[0].right
    width = fixed[1].width
    assert float(np.min(width.value(ds))) >= -1e-9
    for s in (0.0, 22.5, 40.0, 60.0):
        assert float(width.value(np.array([s]))[0]) == pytest.approx(
            float(dip.value(np.array([s]))[0]), abs=1e-6
        )
    assert fixed[0] is lanes[0]
    assert width.pieces[1:] == dip.pieces[1:]


def test_a_driving_lane_goes_on_where_only_its_outer_border_meets():
    """town06-auto-s3, noisier sensor (seed 23), at a lane-offset step: the line inside
    the outermost lane was fitted 0.88 m further in after the border, so the lane inside it
    (linked: its inner border met) was 0.85 m narrower and the outermost lane 0.86 m wider;
    the outermost lane's inner border met nothing, it was left unlinked and led nowhere
    (a route failed). Its outer border meets and its width differs by less than a metre:
    it goes on with the width it had."""
    from roadtwin.mainline.section_links import _link_sections
    from roadtwin.model import LaneSection

    lane = _flat_lane

    first = LaneSection(
        0.0,
        right=(lane(-1, 1.0, "shoulder"), lane(-2, 3.98), lane(-3, 3.5), lane(-4, 0.6, "shoulder")),
    )
    second = LaneSection(
        60.0,
        right=(
            lane(-1, 1.0, "shoulder"),
            lane(-2, 3.13),
            lane(-3, 4.36),
            lane(-4, 0.6, "shoulder"),
        ),
    )
    linked = _link_sections([first, second], [[], []], at_step=[False, False])
    before, after = linked[0].right, linked[1].right
    assert (before[1].successor, after[1].predecessor) == (-2, -2)
    assert (before[2].successor, after[2].predecessor) == (-3, -3)
    assert float(after[2].width.value(np.array([0.0]))[0]) == pytest.approx(3.5, abs=1e-9)
    # a lane a lane and a half wide beyond the border is not this one fitted anew
    wider = replace(second, right=(*second.right[:2], lane(-3, 4.8), second.right[3]))
    relinked = _link_sections([first, wider], [[], []], at_step=[False, False])
    assert relinked[1].right[2].predecessor is None


def test_a_lane_wide_shoulder_between_two_driving_lanes_it_links_is_a_driving_lane():
    """melbourne-921-s2, noisier sensor (seed 62): where two lanes were added on the median
    side, a 20 m section typed its 2.9-3.2 m innermost lane a shoulder (four lanes, the car
    not in it) between the driving lanes it linked before and after; esmini's car in that
    lane jumped 3.1 m to the next one. A narrow shoulder, or one that links a shoulder,
    stays a shoulder."""
    from roadtwin.mainline.sections import _drive_on_through_sections

    cfg = MainlineConfig()

    def section(s0, types, widths, pred=True, succ=True):
        lanes = tuple(
            Lane(
                -(i + 1),
                ty,
                CubicProfile.constant(w),
                (RoadMark(0.0, "broken"),),
                -(i + 1) if pred else None,
                -(i + 1) if succ else None,
            )
            for i, (ty, w) in enumerate(zip(types, widths, strict=True))
        )
        return LaneSection(s0, right=lanes)

    widths = [3.0, 3.5, 3.5, 1.0]
    drv = ["driving", "driving", "driving", "shoulder"]
    mid = ["shoulder", "driving", "driving", "shoulder"]
    secs = [
        section(0.0, drv, widths, pred=False),
        section(100.0, mid, widths),
        section(120.0, mid, widths),
        section(140.0, drv, widths, succ=False),
    ]
    out = _drive_on_through_sections(secs, cfg)
    assert [[ln.type for ln in sc.right] for sc in out] == [drv, drv, drv, drv]
    assert out[0] is secs[0]
    assert out[3] is secs[3]
    narrow = [
        section(s, ty, [1.5, 3.5, 3.5, 1.0]) for s, ty in ((0.0, drv), (100, mid), (120, drv))
    ]
    assert [ln.type for ln in _drive_on_through_sections(narrow, cfg)[1].right] == mid
    one_sided = [
        section(0.0, drv, widths),
        section(100.0, mid, widths),
        section(120.0, mid, widths),
    ]
    assert [ln.type for ln in _drive_on_through_sections(one_sided, cfg)[1].right] == mid


def test_a_median_step_close_before_an_outer_edge_step_keeps_its_lane_section():
    """town06-auto-s9, noisier sensor (seed 49): the median-side edge stepped out by a lane
    12.8 m before the outer edge stepped. The outer step's section start swept the median
    step's away, so the lane offset stepped inside a section: over 12.8 m every lane lay a
    lane width off, and four routes failed in esmini. Both steps start a section."""
    from roadtwin.mainline.markings import _Track
    from roadtwin.mainline.sections import _sections_from_tracks

    cfg = MainlineConfig()
    grid = np.arange(0.0, 600.0 + 0.5 * cfg.grid_step_m, cfg.grid_step_m)
    tracks = [
        _Track(
            k, 0.0, 600.0, grid, np.full(grid.size, d), "broken", 500, grid, np.full(grid.size, d)
        )
        for k, d in enumerate((1.0, 4.5, 8.0))
    ]
    d_edge = np.where(grid < 312.8, 12.0, 11.0)
    d_median = np.where(grid < 300.0, 0.0, -3.5)
    sections, _, _ = _sections_from_tracks(
        tracks, grid, d_edge, np.array([312.8]), 1.0, cfg, None, d_median, np.array([300.0])
    )
    starts = [round(sc.s0, 1) for sc in sections]
    assert 300.0 in starts
    assert 312.8 in starts
    inner = {round(sc.s0, 1): sc.right[0] for sc in sections}
    assert float(inner[300.0].width.value(np.array([1.0]))[0]) == pytest.approx(4.5, abs=0.05)


def test_lines_unseen_just_before_a_median_step_go_on_to_the_lines_inferred_after_it():
    """town06-auto-s3, noisier sensor (seed 83): the inner lines were last seen 27 m
    before a median-side step and inferred (not seen) after it; the 27 m between were
    too short to infer lanes, and the mainline had one shoulder 11.6 m wide there. The
    inferred lines go on from the observed ones."""
    from roadtwin.mainline import fit_lanes
    from roadtwin.mainline.edge_levels import EdgeSteps

    rng = np.random.default_rng(5)

    def line(s0, s1, d, step=0.5):
        s = np.arange(s0, s1, step)
        return s, d + rng.normal(0.0, 0.02, s.size)

    parts = [line(0, 645, 1.0), line(0, 645, 4.5), line(0, 645, 8.0), line(0, 1000, 11.5)]
    s_lane = np.concatenate([p[0] for p in parts])
    d_lane = np.concatenate([p[1] for p in parts])
    s_out, d_out = line(0, 1000, 13.0, 0.2)
    median = EdgeSteps(np.array([672.0]), np.array([0.0, 2.0]))
    sections, _, _, _ = fit_lanes(
        s_lane, d_lane, s_out, d_out, length=1000.0, sign=1.0, config=MainlineConfig(),
        median=median,
    )  # fmt: skip
    for k, sc in enumerate(sections):
        end = sections[k + 1].s0 if k + 1 < len(sections) else 1000.0
        ds = np.linspace(0.0, end - sc.s0 - 1e-6, 20)
        widest = max(float(np.max(ln.width.value(ds))) for ln in sc.right)
        assert widest < 4.0, (sc.s0, widest)
        assert sum(ln.type == "driving" for ln in sc.right) == 3, sc.s0


def _four_lines_800(seed: int):
    """Lane samples of four lines at 1.0, 4.5, 8.0 and 11.5 m over 800 m (2 cm noise) and
    the function that samples a line (offset, step) with the same generator."""
    rng = np.random.default_rng(seed)

    def line(d, step=0.5):
        s = np.arange(0.0, 800.0, step)
        return s, d + rng.normal(0.0, 0.02, s.size)

    parts = [line(1.0), line(4.5), line(8.0), line(11.5)]
    return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]), line


def test_a_lane_out_of_the_sensors_reach_beyond_the_last_marking_is_inferred():
    """Town06 driven in its inner lane (seed 21): the line between the outer lane and the
    shoulders lay 12.2 m from the car, out of the sensor's reach, over the whole run; the
    run's "typical shoulder" was then the outer lane and the shoulders together, 4.7 m,
    and the outer lane was never inferred (lane RMSE 1.77 m). Driven more than two lanes
    and that strip away from the edge, the strip is whole lanes and the rest shoulder."""
    from roadtwin.mainline import fit_lanes

    s_lane, d_lane, line = _four_lines_800(11)
    s_out, d_out = line(16.2, 0.2)

    def outer_lanes(car_d):
        car = (np.arange(0.0, 800.0, 1.0), np.full(800, car_d))
        sections, _, _, _ = fit_lanes(
            s_lane, d_lane, s_out, d_out, length=800.0, sign=1.0, config=MainlineConfig(),
            car=car,
        )  # fmt: skip
        return [
            (ln.type, round(float(ln.width.value(np.array([100.0]))[0]), 1))
            for ln in sections[0].right
        ]

    # in the inner lane: a 3.5 m lane and a 1.2 m shoulder beyond the last marking
    assert outer_lanes(2.75)[-2:] == [("driving", 3.5), ("shoulder", 1.2)]
    # in the lane beside the strip the sensor would have seen that line: the strip stays
    assert outer_lanes(9.75)[-1] == ("driving", 4.7)


def test_a_lane_opening_out_of_the_sensors_reach_opens_beside_the_through_lane():
    """Town06 driven in its inner lane (seed 21): beyond the sensor's reach an exit lane
    opened over 50 m beside the inferred outer lane. The strip was split evenly into its
    whole lanes, so the inferred lane grew from 3.5 to 6.6 m and became two lanes 3.3 m
    wide at a section border, linked to neither: esmini found no lane path to the end.
    The through lane keeps its width and the new lane opens from zero width beside it."""
    from roadtwin.mainline import fit_lanes

    s_lane, d_lane, line = _four_lines_800(12)
    s_out, d_out = line(16.2, 0.2)
    d_out = d_out + 3.5 * _smoothstep(s_out, 400.0, 50.0)
    car = (np.arange(0.0, 800.0, 1.0), np.full(800, 2.75))
    sections, _, _, _ = fit_lanes(
        s_lane, d_lane, s_out, d_out, length=800.0, sign=1.0, config=MainlineConfig(), car=car
    )

    def lanes_at(s):
        k = max(i for i, sc in enumerate(sections) if sc.s0 <= s)
        sc = sections[k]
        return [(ln, float(ln.width.value(np.array([s - sc.s0]))[0])) for ln in sc.right]

    for s in np.arange(5.0, 800.0, 5.0):
        assert max(w for _, w in lanes_at(s)) < 4.3, s
    # through the taper the outer through lane keeps its 3.5 m
    for s in (420.0, 430.0, 440.0):
        driving = [w for ln, w in lanes_at(s) if ln.type == "driving"]
        assert driving[3] == pytest.approx(3.5, abs=0.15), (s, driving)
    after = [(ln.type, round(w, 1)) for ln, w in lanes_at(600.0)]
    assert after[-3:] == [("driving", 3.5), ("driving", 3.5), ("shoulder", 1.2)]
    # the new lane opens from (almost) zero width where its section starts
    k_new = next(
        i for i, sc in enumerate(sections)
        if sum(ln.type == "driving" for ln in sc.right) == 5
    )  # fmt: skip
    born = [ln for ln in sections[k_new].right if ln.predecessor is None and ln.type == "driving"]
    assert len(born) == 1
    assert float(born[0].width.value(np.array([0.0]))[0]) < 0.3
    assert 380.0 < sections[k_new].s0 < 420.0


def test_a_strip_out_of_reach_too_wide_for_its_whole_lanes_holds_one_lane_more():
    """a9-8081560 driven in its inner lane with a noisier sensor: a 2-lane entry joined out
    of the sensor's reach, its lanes 3.4 m wide beside observed lanes of 3.7 m. Counted in
    whole lanes of 3.7 m with a 0.4 m tolerance, the 6.8 m they make were one lane (a lane
    6.8 m wide, lane count 95 %). Lanes wider than 4.5 m are split while they stay 2.5 m
    wide (the lane-width prior), here and in the count helper."""
    from roadtwin.mainline import fit_lanes
    from roadtwin.mainline.hidden_lanes import _hidden_lane_count

    def count(gap_m: float, lanes_only: bool = True) -> int:
        gap = np.full(200, gap_m)
        return int(_hidden_lane_count(gap, 3.7, -1.7, 1.0, lanes_only=lanes_only)[100])

    assert [count(g) for g in (4.4, 4.6, 6.8, 10.5)] == [1, 1, 2, 3]
    assert count(6.8, lanes_only=False) == 1  # a strip with a shoulder in it: as before

    rng = np.random.default_rng(13)

    def line(d, step=0.5):
        s = np.arange(0.0, 1000.0, step)
        return s, d + rng.normal(0.0, 0.02, s.size)

    parts = [line(d) for d in (1.0, 4.7, 8.4, 12.1)]
    s_lane = np.concatenate([p[0] for p in parts])
    d_lane = np.concatenate([p[1] for p in parts])
    # the edge: a lane of 3.7 m and a 2.5 m shoulder beyond the last line; from 700 m two
    # more lanes of 3.4 m, the outer one closing over 750-850 m
    s_out, d_out = line(18.3, 0.2)
    d_out = d_out + np.where(s_out >= 700.0, 6.8, 0.0) - 3.4 * _smoothstep(s_out, 750.0, 100.0)
    car = (np.arange(0.0, 1000.0, 1.0), np.full(1000, 2.85))
    sections, _, _, _ = fit_lanes(
        s_lane, d_lane, s_out, d_out, length=1000.0, sign=1.0, config=MainlineConfig(), car=car
    )

    def driving_at(s):
        sc = sections[max(i for i, x in enumerate(sections) if x.s0 <= s)]
        ds = np.array([s - sc.s0])
        return [float(ln.width.value(ds)[0]) for ln in sc.right if ln.type == "driving"]

    for s in np.arange(5.0, 1000.0, 5.0):
        assert max(driving_at(s)) < 4.5, (s, driving_at(s))
    assert len(driving_at(720.0)) == 6  # three observed, the one beyond, two that joined
    assert len(driving_at(950.0)) == 5


def test_a_line_first_seen_soon_after_an_entry_gore_begins_at_the_gore():
    """a9-8081560 driven in its third lane: a 2-lane entry joined at s = 722 m; the outer
    line of its acceleration lane was first seen 48 m later, already closing, and over
    those metres the lane was a hard shoulder 6.4 m wide. A line first seen within 60 m
    after an entry's step, a lane's width from its neighbour, begins at the step; not a
    taper's tip, not one seen too late, not one beyond the edge, and not at an exit (the
    line between the through and the exit lane ends at the painted gore's tip)."""
    from roadtwin.mainline.tapers import _lines_to_gores

    grid = np.arange(0.0, 800.5, 1.0)
    d_edge = np.where(grid < 400.0, 12.0, 19.5)  # an entry at 400 m (two lanes)
    d_edge = np.where(grid > 650.0, 12.0, d_edge)  # an exit at 650 m

    def row(lo, hi, d):
        out = np.full(grid.size, np.nan)
        out[(grid >= lo) & (grid <= hi)] = d
        return out

    dmat = np.vstack(
        [
            row(0.0, 800.0, 8.0),  # through line
            row(400.0, 650.0, 11.5),  # the entry's inner lane's line, seen from the gore
            row(448.0, 600.0, 14.5),  # first seen 48 m after the gore, last 50 m before
            row(448.0, 640.0, 11.9),  # 0.4 m from its neighbour: a taper's tip
            row(480.0, 640.0, 17.0),  # first seen 80 m after the gore
            row(420.0, 640.0, 19.4),  # 0.1 m inside the edge: not a lane's line
        ]
    )
    _lines_to_gores(dmat, grid, d_edge, np.array([400.0, 650.0]))
    first = [int(grid[np.flatnonzero(np.isfinite(r))[0]]) for r in dmat]
    last = [int(grid[np.flatnonzero(np.isfinite(r))[-1]]) for r in dmat]
    assert first == [0, 400, 400, 448, 480, 420]
    assert last == [800, 650, 600, 640, 640, 640]  # nothing moves up to the exit's step
    assert np.nanmax(np.abs(dmat[2] - 14.5)) == 0.0  # extended at its first offset


def test_a_late_seen_entry_line_makes_its_lane_from_the_gore():
    """The same through the sections stage: from the gore on there are two new lanes,
    not one lane and a shoulder 8 m wide."""
    from roadtwin.mainline.markings import _Track
    from roadtwin.mainline.sections import _sections_from_tracks

    cfg = MainlineConfig()
    grid = np.arange(0.0, 800.0 + 0.5 * cfg.grid_step_m, cfg.grid_step_m)

    def track(k, lo, d):
        g = grid[grid >= lo]
        return _Track(k, lo, 800.0, g, np.full(g.size, d), "broken", 400, g, np.full(g.size, d))

    tracks = [track(0, 0.0, 1.0), track(1, 0.0, 4.5), track(2, 0.0, 8.0)]
    tracks += [track(3, 400.0, 11.5), track(4, 448.0, 15.0)]
    d_edge = np.where(grid < 400.0, 9.0, 17.5)
    sections, events, _ = _sections_from_tracks(
        tracks, grid, d_edge, np.array([400.0]), 1.0, cfg, None, np.zeros(grid.size)
    )
    sc = sections[max(i for i, x in enumerate(sections) if x.s0 <= 420.0)]
    ds = np.array([420.0 - sc.s0])
    lanes = [(ln.type, round(float(ln.width.value(ds)[0]), 1)) for ln in sc.right]
    assert lanes[-3:] == [("driving", 3.5), ("driving", 3.5), ("shoulder", 2.5)]
    births = sorted(round(ev.s_m) for ev in events if ev.kind == "birth")
    assert births == [400, 400]


def test_a_line_extended_to_an_entry_gore_does_not_open_its_lane_before_it():
    """melbourne-921-s2: an acceleration lane's outer line was first seen 5 m after the
    gore, 1.7 m from its neighbour, which later swung 4 m away; the taper fitted to the
    separation opened the lane 25 m before the gore (lane RMSE 0.191 m, lane count 96.6 %;
    0.110 m, 99.0 % beginning at the gore)."""
    from roadtwin.mainline.markings import _Track
    from roadtwin.mainline.sections import _sections_from_tracks

    cfg = MainlineConfig()
    grid = np.arange(0.0, 800.0 + 0.5 * cfg.grid_step_m, cfg.grid_step_m)

    def track(k, lo, hi, d_of):
        g = grid[(grid >= lo) & (grid <= hi)]
        d = d_of(g)
        return _Track(k, lo, hi, g, d, "broken", 400, g, d)

    tracks = [
        track(0, 0.0, 800.0, lambda g: np.full(g.size, 1.0)),
        track(1, 0.0, 800.0, lambda g: np.full(g.size, 4.5)),
        track(2, 0.0, 800.0, lambda g: np.full(g.size, 8.0)),
        # the entry's inner line from the gore, swinging in onto the through line
        track(3, 400.0, 580.0, lambda g: 11.5 - 3.5 * _smoothstep(g, 480.0, 100.0)),
        # its outer line, first seen 5 m after the gore
        track(4, 405.0, 800.0, lambda g: np.full(g.size, 13.2)),
    ]
    d_edge = np.where(grid < 400.0, 9.0, 15.7)
    sections, events, _ = _sections_from_tracks(
        tracks, grid, d_edge, np.array([400.0]), 1.0, cfg, None, np.zeros(grid.size)
    )
    births = sorted(round(ev.s_m, 1) for ev in events if ev.kind == "birth")
    assert births
    assert min(births) >= 400.0, births
    before = sections[max(i for i, x in enumerate(sections) if x.s0 <= 390.0)]
    assert sum(ln.type == "driving" for ln in before.right) == 2


def test_an_inferred_line_with_its_own_taper_does_not_borrow_a_later_one():
    """An inferred line opens (closes) like an observed sibling near it (two lanes of a
    2-lane exit, one line seen), but not one whose taper begins only after the inferred
    line is already half open: town06-auto-lane1-s21 borrowed the taper of a median-side
    lane opening 96 m on, and the exit lane opening out of sight lost those 96 m."""
    from roadtwin.mainline.markings import _Track
    from roadtwin.mainline.sections import _sections_from_tracks

    cfg = MainlineConfig()
    grid = np.arange(0.0, 800.0 + 0.5 * cfg.grid_step_m, cfg.grid_step_m)

    def track(k, lo, d_of, n):
        g = grid[grid >= lo]
        d = d_of(g)
        samples = g if n else g[:0]
        return _Track(k, lo, 800.0, g, d, "broken", n, samples, d_of(samples))

    def flat(d):
        return lambda g: np.full(g.size, d)

    tracks = [
        track(0, 0.0, flat(1.0), 800),
        track(1, 0.0, flat(4.5), 800),
        track(2, 0.0, flat(8.0), 800),
        track(3, 0.0, flat(11.5), 800),
        # observed: a median-side lane opening over 480-540 m
        track(4, 490.0, lambda g: 1.0 - 3.5 * _smoothstep(g, 480.0, 60.0), 600),
        # inferred: an outer lane opening over 400-450 m
        track(5, 404.0, lambda g: 11.5 + 3.5 * _smoothstep(g, 400.0, 50.0), 0),
    ]
    _, events, _ = _sections_from_tracks(
        tracks, grid, np.full(grid.size, 16.2), np.zeros(0), 1.0, cfg, None,
        np.full(grid.size, -3.5),
    )  # fmt: skip
    births = sorted((round(ev.s_m), ev.position) for ev in events if ev.kind == "birth")
    assert len(births) == 2
    (s_outer,) = [s for s, pos in births if pos == "outer"]
    assert s_outer == pytest.approx(400.0, abs=10.0)


def test_a_marking_ending_where_the_edge_is_not_seen_again_before_the_run_ends_is_no_gore():
    """A marking that ends diverging inside an occlusion gap of the outer edge is an exit
    line leaving at a hidden gore, when the edge is seen again after the gap. In a gap that
    runs to the end of the run nothing shows a gore: with a noisier sensor the line between
    two lanes of krems-102561705-lane1-s21 seemed to diverge over its last metres and
    ended 12 m before the run's end; a gore was placed there, and the two lanes became one
    lane 7.4 m wide with no lane path to the end."""
    from roadtwin.mainline.hidden_gores import _snap_to_hidden_gores

    cfg = MainlineConfig()

    def gores(length: float) -> list[float]:
        grid = np.arange(0.0, length + 0.5, cfg.grid_step_m)
        through = _const_track(0, grid, 3.5, 0.0, length)
        # parallel up to 580 m, then diverging by 0.1 m per metre up to its end at 592 m
        ending = _const_track(
            1, grid, lambda s: 7.0 + 0.1 * np.clip(s - 580.0, 0.0, None), 0.0, 592.0
        )
        covered = (grid < 585.0) | (grid > 620.0)
        _, found = _snap_to_hidden_gores([through, ending], [], covered, grid, cfg)
        return [round(float(g)) for g in found]

    assert gores(800.0) == [579]  # the edge is seen again at 620 m: a hidden exit gore
    assert gores(600.0) == []  # the gap runs to the run's end: no evidence


def test_a_hidden_gore_cuts_only_the_markings_beside_it():
    """A ramp line meeting the outermost marking in an occlusion gap places a gore there,
    and the outer markings that begin just before it are cut back to it (they are the
    ramp's lines upstream). A through line nearer the median that happens to begin within
    60 m of it is not: on melbourne-921-s2 the inner shoulder's line, beginning after an
    inner exit, was cut back 51 m to an outer lane drop's gore, and the shoulder became
    part of a driving lane 3.9 m wide."""
    from roadtwin.mainline.hidden_gores import _snap_to_hidden_gores

    cfg = MainlineConfig()
    grid = np.arange(0.0, 1000.5, cfg.grid_step_m)
    inner = _const_track(0, grid, 0.7, 596.0, 1000.0)  # begins after an inner exit
    through = _const_track(1, grid, 15.2, 0.0, 1000.0)
    outer = _const_track(2, grid, 18.7, 610.0, 1000.0)  # the ramp's line upstream of the gore
    covered = (grid < 630.0) | (grid > 660.0)
    out, gores = _snap_to_hidden_gores(
        [inner, through, outer], [(647.0, 15.2, False)], covered, grid, cfg
    )
    assert [round(float(g)) for g in gores] == [647]
    assert out[0].lo == pytest.approx(596.0)  # the inner line keeps its start
    assert out[1].lo == pytest.approx(0.0)
    assert out[2].lo == pytest.approx(647.0, abs=cfg.grid_step_m)  # cut back to the gore


def test_the_second_join_pass_only_joins_inferred_lines_to_observed_ones():
    """After the hidden lanes are inferred, an inferred line is joined to the observed one
    it continues; two observed tracks still apart then were split at a gore on purpose
    (a9-10959882-s9 with a noisier sensor: joined again, a lane 6.1 m wide)."""
    from roadtwin.mainline.markings import _merge_collinear, _Track

    cfg = MainlineConfig()

    def track(lo, hi, d, n):
        g = np.arange(lo, hi + 0.5, 1.0)
        samples = g if n else g[:0]
        return _Track(
            0, lo, hi, g, np.full(g.size, d), "broken", n, samples, np.full(samples.size, d)
        )

    observed = [track(0.0, 500.0, 8.2, 400), track(501.0, 900.0, 8.1, 300)]
    assert len(_merge_collinear(observed, cfg, with_inferred_only=True)) == 2
    assert len(_merge_collinear(observed, cfg)) == 1
    inferred = [track(0.0, 500.0, 8.2, 400), track(530.0, 900.0, 7.7, 0)]
    joined = _merge_collinear(inferred, cfg, with_inferred_only=True)
    assert len(joined) == 1
    assert (joined[0].lo, joined[0].hi) == (0.0, 900.0)


def test_an_edge_line_is_the_shoulders_line_where_a_shoulder_lies_beyond_it():
    """The same solid line runs 2.4 m inside the edge (the hard shoulder's line) up to an
    edge step at 250 m and at the edge (no hard shoulder) for the remaining 550 m: it is
    the edge line only there. Judged for the whole run it was dropped everywhere and the
    lane beside it took the shoulder: a lane 5.9 m wide (melbourne-18-s11+80, 7.3 m)."""
    from roadtwin.mainline.markings import _Track
    from roadtwin.mainline.sections import _sections_from_tracks

    cfg = MainlineConfig()
    grid = np.arange(0.0, 800.0 + 0.5 * cfg.grid_step_m, cfg.grid_step_m)

    def track(k, d, mark):
        return _Track(k, 0.0, 800.0, grid, np.full(grid.size, d), mark, 600, grid, grid)

    tracks = [track(0, 1.0, "solid"), track(1, 4.5, "broken"), track(2, 8.0, "solid")]
    d_edge = np.where(grid < 250.0, 10.4, 8.1)
    sections, _, _ = _sections_from_tracks(
        tracks, grid, d_edge, np.array([250.0]), 1.0, cfg, None, np.zeros(grid.size)
    )

    def lanes_at(s):
        sc = sections[max(i for i, x in enumerate(sections) if x.s0 <= s)]
        ds = np.array([s - sc.s0])
        return [(ln.type, round(float(ln.width.value(ds)[0]), 1)) for ln in sc.right]

    assert lanes_at(100.0)[-3:] == [("driving", 3.5), ("driving", 3.5), ("shoulder", 2.4)]
    assert max(w for _, w in lanes_at(600.0)) <= 3.6  # the edge line is no lane border


def test_lines_from_splits_fills_back_to_where_the_neighbour_left():
    """``_lines_from_splits``: a line first seen at 150 m at the offset a neighbouring
    line left between 100 and 200 m begins where that line was last within 0.3 m of it;
    not if another line lies between them, nor if the neighbour never was at its offset."""
    from roadtwin.mainline.tapers import _lines_from_splits

    grid = np.arange(0.0, 400.0 + 0.5, 1.0)
    moving = np.interp(grid, [0.0, 100.0, 200.0, 400.0], [8.0, 8.0, 11.5, 11.5])
    late = np.where(grid >= 150.0, 8.0, np.nan)

    def first(row):
        return float(grid[np.flatnonzero(np.isfinite(row))[0]])

    dmat = np.vstack([np.full(grid.size, 4.5), moving, late])
    _lines_from_splits(dmat, grid)
    assert 100.0 <= first(dmat[2]) <= 112.0
    # a line between the late one and the one that left: that one is not its neighbour
    between = np.interp(grid, [0.0, 100.0, 200.0, 400.0], [8.0, 8.0, 9.5, 9.5]) + 0.6
    dmat = np.vstack([np.full(grid.size, 4.5), moving, between, late])
    _lines_from_splits(dmat, grid)
    assert first(dmat[3]) == 150.0
    # the neighbour was never at the late line's offset
    dmat = np.vstack([np.full(grid.size, 4.5), moving + 1.0, late])
    _lines_from_splits(dmat, grid)
    assert first(dmat[2]) == 150.0


def test_markings_beside_a_median_edge_below_the_reference_line_are_measured():
    """Between median-side gores the median edge lies below the reference line (here
    3.5 m), and so does the inner shoulder's line. It is measured, not inferred a lane
    from the next line: a 4.0 m inner lane stays 4.0 m wide (it was built 3.5 m, the
    typical width, with its measured line never searched for)."""
    from roadtwin.mainline.edge_levels import EdgeSteps
    from roadtwin.mainline.lanes import fit_lanes

    cfg = MainlineConfig()
    rng = np.random.default_rng(5)
    s = np.arange(0.0, 600.0, 0.25)
    dashes = (s % 12.0) < 3.0
    lines = [(-2.9, s), (1.1, s[dashes]), (4.6, s[dashes]), (8.1, s[dashes]), (11.6, s)]
    s_lane = np.concatenate([ss for _, ss in lines])
    d_lane = np.concatenate([np.full(ss.size, d) for d, ss in lines])
    d_lane = d_lane + rng.normal(0.0, 0.02, d_lane.size)
    s_out = np.arange(0.0, 600.0, 0.5)
    d_out = 12.6 + rng.normal(0.0, 0.02, s_out.size)
    sections, _, tracks, _ = fit_lanes(
        s_lane,
        d_lane,
        s_out,
        d_out,
        length=600.0,
        sign=1.0,
        config=cfg,
        median=EdgeSteps(np.zeros(0), np.array([3.5])),
    )
    inner_line = [tr for tr in tracks if abs(float(np.median(tr.d_m)) + 2.9) < 0.1]
    assert inner_line
    assert inner_line[0].n_samples > 1000
    sec = sections[len(sections) // 2]
    driving = [ln for ln in sec.right if ln.type == "driving"]
    assert len(driving) == 4
    innermost = min(driving, key=lambda ln: abs(ln.id))
    assert float(innermost.width.value(np.array([100.0]))[0]) == pytest.approx(4.0, abs=0.05)


def test_extreme_markings_are_held_over_the_half_window_at_the_run_ends():
    """The innermost marking's moving median at a run's start, where the inner lines are
    seen only from 19 m on (the outer line alone before), flips between lines over the
    cut-short windows; held at the first full window's value it does not (town06-auto-s2:
    inferred inner lanes 1.7 m aside over the first 10 m, a step esmini's car met)."""
    from roadtwin.fitting import moving_median
    from roadtwin.mainline.hidden_lanes import _held_at_ends

    raw = np.concatenate([np.full(8, np.nan), np.full(10, 18.62), [11.62], np.full(200, 8.11)])
    window = 41
    smooth = np.where(np.isfinite(raw), moving_median(raw, window=window), np.nan)
    assert np.nanmax(np.abs(smooth[8:30] - 8.11)) > 1.0  # the flip
    held = _held_at_ends(smooth, window)
    np.testing.assert_allclose(held[8:], 8.11, atol=1e-9)
    assert np.all(np.isnan(held[:8]))


def test_a_broken_line_whose_next_dash_lies_past_the_runs_end_is_cut_by_it():
    """A lane gain's broken line (6 m dashes, 12 m gaps) begins 53 m before the run's
    end; its last dash ends 11 m before it, the next would lie past it. Too short for a
    marking (60 m) unless the run's end cuts it: within two columns (10 m) it did not
    count as cut, and the line was dropped (oakland-28393854-lane2-s22 with a noisier
    sensor: the new lane made one 6.4 m wide with the next). Within its own longest gap
    it does."""
    from roadtwin.mainline.markings import _tracks_from_samples

    cfg = MainlineConfig()
    rng = np.random.default_rng(3)
    end = 593.0
    parts = [(np.arange(0.0, end, 0.25), off) for off in (1.0, 4.5, 8.0)]
    s_new = np.arange(540.0, 582.0, 0.25)
    parts.append((s_new[(s_new - 540.0) % 18.0 < 6.0], 11.5))
    ss = np.concatenate([s for s, _ in parts])
    dd = np.concatenate([np.full(s.size, off) for s, off in parts])
    order = np.argsort(ss, kind="stable")
    ss, dd = ss[order], dd[order] + rng.normal(0.0, 0.02, ss.size)
    tracks, _ = _tracks_from_samples(ss, dd, np.arange(0.0, end + 0.5, 1.0), end, cfg)
    new = [tr for tr in tracks if abs(float(np.median(tr.d)) - 11.5) < 0.2]
    assert len(tracks) == 4
    assert len(new) == 1
    assert new[0].lo == pytest.approx(540.0, abs=1.0)
    assert new[0].hi == pytest.approx(581.75, abs=1.0)
