"""Scenarios that follow real OSM geometry: fitting clothoid chains and cropping OSM.

Used to make the ``real_a9`` scenario (``examples/make_real_a9.py``): a real motorway
carriageway and its link ways become a smooth chain of clothoids (curvature linear
between knots, fitted to the smoothed polyline's heading), so the ground truth stays an
exact Line/Arc/Spiral model while following the real road within a metre or so.
"""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
from lxml import etree
from numpy.typing import NDArray
from scipy.signal import savgol_filter

from .._xml import parse_xml
from .alignment import build_pieces


def resample(xy: NDArray, step_m: float = 1.0) -> tuple[NDArray, NDArray]:
    """Polyline ``(N, 2)`` resampled every ``step_m`` metres; returns points and stations."""
    seg = np.hypot(*np.diff(xy, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    keep = np.concatenate([[True], seg > 1e-6])
    s, xy = s[keep], xy[keep]
    grid = np.arange(0.0, s[-1], step_m)
    return np.column_stack([np.interp(grid, s, xy[:, 0]), np.interp(grid, s, xy[:, 1])]), grid


def smooth_polyline(xy: NDArray, *, window_m: float, step_m: float = 1.0):
    """Savitzky-Golay smoothed points and headings (radians, unwrapped) every ``step_m``."""
    pts, s = resample(xy, step_m)
    win = int(window_m / step_m) | 1
    win = min(win, (pts.shape[0] - 1) | 1 if pts.shape[0] % 2 == 0 else pts.shape[0])
    win = max(win, 5)
    sm = savgol_filter(pts, win, 3, axis=0, mode="interp")
    d = savgol_filter(pts, win, 3, deriv=1, axis=0, mode="interp")
    return sm, np.unwrap(np.arctan2(d[:, 1], d[:, 0])), s


def fit_clothoids(
    s: NDArray,
    heading: NDArray,
    *,
    knot_spacing_m: float,
    start_heading: float | None = None,
    weight: NDArray | None = None,
    smoothness: float = 1e3,
) -> list[tuple[float, float, float]]:
    """Clothoids ``(length, k_start, k_end)`` whose heading best matches ``heading(s)``.

    Curvature is piecewise linear between knots every ``knot_spacing_m``; the heading at
    s = 0 is ``start_heading`` (default the first sample). Least squares with a
    second-difference penalty (``smoothness``) on the knot curvatures.
    """
    length = float(s[-1])
    n_int = max(1, round(length / knot_spacing_m))
    knots = np.linspace(0.0, length, n_int + 1)
    theta0 = heading[0] if start_heading is None else start_heading
    # basis: integral from 0 to s of the hat function of each knot
    fine = np.linspace(0.0, length, max(2, int(length / 0.5) + 1))
    hats = np.clip(1.0 - np.abs(fine[:, None] - knots[None, :]) / np.diff(knots).mean(), 0, None)
    cum = np.vstack(
        [
            np.zeros(len(knots)),
            np.cumsum(0.5 * (hats[1:] + hats[:-1]) * np.diff(fine)[:, None], axis=0),
        ]
    )
    A = np.column_stack([np.interp(s, fine, cum[:, j]) for j in range(len(knots))])
    b = heading - theta0
    w = np.ones_like(s) if weight is None else weight
    D = np.diff(np.eye(len(knots)), 2, axis=0) * smoothness
    lhs = np.vstack([A * w[:, None], D])
    rhs = np.concatenate([b * w, np.zeros(D.shape[0])])
    kappa, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
    return [
        (float(knots[i + 1] - knots[i]), float(kappa[i]), float(kappa[i + 1])) for i in range(n_int)
    ]


def chain_xy(elements, *, x0: float, y0: float, hdg: float, step_m: float = 1.0) -> NDArray:
    """Points every ``step_m`` along a clothoid chain (for checking a fit)."""
    pieces = build_pieces([("clothoid", *e) for e in elements], x0=x0, y0=y0, hdg=hdg)
    out = []
    for p in pieces:
        ds = np.arange(0.0, p.length, step_m)
        out.append(p.xy(p.s0 + ds))
    return np.vstack(out)


def crop_osm(src: str | Path, dst: str | Path, *, bbox: tuple[float, float, float, float]) -> dict:
    """Copy the highway ways of an OSM XML file (``.osm``/``.osm.gz``) having a node inside
    ``bbox = (min_lon, min_lat, max_lon, max_lat)``, with all their nodes, to ``dst``
    (gzip if it ends in ``.gz``). Ids, versions and tags are kept. Returns counts."""
    src = Path(src)
    opener = gzip.open if src.suffix == ".gz" else open
    with opener(src, "rb") as fh:
        root = parse_xml(fh, name=src).getroot()
    nodes = {n.get("id"): n for n in root.iter("node")}
    lo_lon, lo_lat, hi_lon, hi_lat = bbox

    def inside(nid: str) -> bool:
        n = nodes.get(nid)
        if n is None:
            return False
        lon, lat = float(n.get("lon")), float(n.get("lat"))
        return lo_lon <= lon <= hi_lon and lo_lat <= lat <= hi_lat

    keep_ways, keep_nodes = [], set()
    for w in root.iter("way"):
        tags = {t.get("k"): t.get("v") for t in w.iter("tag")}
        if "highway" not in tags:
            continue
        refs = [nd.get("ref") for nd in w.iter("nd")]
        if any(inside(r) for r in refs) and all(r in nodes for r in refs):
            keep_ways.append(w)
            keep_nodes.update(refs)
    out = etree.Element("osm", version="0.6", generator="roadtwin crop_osm")
    out.append(etree.Comment(" (c) OpenStreetMap contributors, ODbL 1.0. Cropped from "
                             f"{src.name} (graphhopper test data) "))  # fmt: skip
    out.append(
        etree.Element(
            "bounds",
            minlat=f"{lo_lat:.7f}",
            minlon=f"{lo_lon:.7f}",
            maxlat=f"{hi_lat:.7f}",
            maxlon=f"{hi_lon:.7f}",
        )
    )
    for nid in sorted(keep_nodes, key=int):
        out.append(nodes[nid])
    for w in sorted(keep_ways, key=lambda e: int(e.get("id"))):
        out.append(w)
    etree.indent(out, space=" ")
    data = etree.tostring(out, xml_declaration=True, encoding="UTF-8")
    dst = Path(dst)
    if dst.suffix == ".gz":
        dst.write_bytes(gzip.compress(data, mtime=0))
    else:
        dst.write_bytes(data)
    return {"ways": len(keep_ways), "nodes": len(keep_nodes)}
