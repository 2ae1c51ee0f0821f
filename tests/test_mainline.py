"""Mainline reconstruction: accuracy against a known truth road, continuity, lanes, cut_road."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from roadtwin.config import MainlineConfig
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
    Road,
    RoadMark,
    Spiral,
    chain_geometry,
)

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


def sample_run(road: Road, *, noise_m: float = 0.03, seed: int = 0, outliers: float = 0.0,
               gap: tuple[float, float] | None = None, traffic_side: str = "right") -> MappingRun:
    """Edge points, lane samples and poses of ``road`` with Gaussian noise."""
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
        z = road.height(s_e[keep])
        pts = np.column_stack([xy, z]) + rng.normal(0.0, noise_m, (xy.shape[0], 3))
        if outliers > 0:  # guardrail-like points offset outward
            n_out = int(outliers * pts.shape[0])
            idx = rng.choice(pts.shape[0], n_out, replace=False)
            _, h = road.project(pts[idx])[0], road.heading(road.project(pts[idx])[0])
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
            lane_pts.append(np.column_stack([xy, road.height(ss)]))
    lanes = np.vstack(lane_pts)
    lanes = lanes + rng.normal(0.0, noise_m, lanes.shape)
    # trajectory: centre of the second driving lane, with a gentle weave
    s_p = np.arange(0.0, length, 1.0)
    t_p = road.lane_border_t(s_p, int(-3 * sign)) + sign * 1.875 + 0.3 * np.sin(s_p / 90.0)
    xy_p = road.to_xy(s_p, t_p)
    z_p = road.height(s_p)
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


def _borders(road: Road, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per station: reference edge t, outer edge t, and a (K, N) matrix of lane-marking t
    (NaN where a section has fewer markings); also the lane count per station."""
    sec_idx = road.section_index(s)
    kmax = max(len(sec.right or sec.left) for sec in road.lane_sections)
    marks = np.full((kmax, s.size), np.nan)
    outer = np.full(s.size, np.nan)
    count = np.zeros(s.size, int)
    for k in np.unique(sec_idx):
        sec = road.lane_sections[int(k)]
        sel = sec_idx == k
        ids = _lane_ids(sec)
        count[sel] = len(ids)
        outer[sel] = road.lane_border_t(s[sel], ids[-1])
        for j, lid in enumerate(ids[:-1]):
            marks[j, sel] = road.lane_border_t(s[sel], lid)
    return road.lane_border_t(s, 0), outer, marks, count


def compare_to_truth(built: Road, truth: Road, *, step_m: float = 1.0, trim_m: float = 30.0):
    """Lateral errors (metres) of the built road against the truth road: road edges, lane
    markings (same index where the lane counts agree, else the nearest marking), elevation,
    and the fraction of stations where the lane count agrees."""
    s_t = np.arange(trim_m, truth.length - trim_m, step_m)
    ref_t, out_t, marks_t, count_t = _borders(truth, s_t)
    res = {}
    pts_ref = truth.to_xy(s_t, ref_t)
    s_b, t_b = built.project(pts_ref)
    res["ref_edge"] = t_b - _borders(built, s_b)[0]
    pts_out = truth.to_xy(s_t, out_t)
    s_b, t_b = built.project(pts_out)
    res["outer_edge"] = t_b - _borders(built, s_b)[1]
    errs = []
    for j in range(marks_t.shape[0]):
        ok = np.isfinite(marks_t[j])
        if not np.any(ok):
            continue
        pts = truth.to_xy(s_t[ok], marks_t[j, ok])
        s_b, t_b = built.project(pts)
        _, _, marks_b, count_b = _borders(built, s_b)
        same = count_b == count_t[ok]
        by_index = marks_b[j] if j < marks_b.shape[0] else np.full(s_b.size, np.nan)
        nearest = np.nanmin(np.abs(marks_b - t_b[None, :]), axis=0)
        e = np.where(same & np.isfinite(by_index), np.abs(t_b - by_index), nearest)
        errs.append(e)
    res["lane_boundary"] = np.concatenate(errs)
    s_b, _ = built.project(pts_ref)
    res["elevation"] = built.height(s_b) - truth.height(s_t)
    count_b = _borders(built, s_b)[3]
    res["lane_count_agreement"] = float(np.mean(count_b == count_t))
    return res


def rmse(e) -> float:
    e = np.asarray(e, float)
    return float(np.sqrt(np.mean(e * e)))
