"""Overview plot of a mapping run (and its OSM graph) in the mapping frame."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ._files import atomic_write_bytes

if TYPE_CHECKING:
    import networkx as nx
    from matplotlib.figure import Figure

    from .io import MappingRun

HIGHWAY_COLORS = {
    "motorway": "#e8384f",
    "motorway_link": "#fd817d",
    "trunk": "#fdae33",
    "trunk_link": "#fdd18c",
    "primary": "#ecd500",
    "primary_link": "#f5e77a",
    "secondary": "#8fd14f",
    "secondary_link": "#bde59a",
    "tertiary": "#4ecbc4",
    "tertiary_link": "#9fe2de",
}
"""Colour per OSM ``highway`` class; every other class is grey."""
_OTHER_COLOR = "#b0b0b0"


def plot_overview(
    run: MappingRun,
    osm_graph: nx.MultiDiGraph | None,
    path: str | Path | None = None,
    *,
    max_points: int = 200_000,
    seed: int = 0,
) -> Figure:
    """Overview figure of a run in the mapping frame; written as PNG when ``path`` is given.

    Parameters
    ----------
    run
        The loaded mapping run.
    osm_graph
        Projected OSM graph from :func:`roadtwin.osm.load_osm`, or None.
    path
        PNG file to write (atomically), or None to write nothing.
    max_points
        Road-edge points and lane samples are randomly subsampled (seeded) to at most this.
    seed
        Seed of the subsampling (same input -> same picture).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (object API, Agg canvas, no pyplot state).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    rng = np.random.default_rng(seed)
    summary = run.summary()
    xmin, ymin, xmax, ymax = summary.bbox_m
    pad = max(0.12 * max(xmax - xmin, ymax - ymin), 120.0)  # metres of OSM context
    xmin, ymin, xmax, ymax = xmin - pad, ymin - pad, xmax + pad, ymax + pad
    aspect = (ymax - ymin) / (xmax - xmin)
    if aspect >= 1.0:
        size = (float(np.clip(9.0 / aspect + 1.5, 5.0, 11.0)), 10.0)
    else:
        size = (11.0, float(np.clip(9.5 * aspect + 1.5, 5.0, 10.0)))
    fig = Figure(figsize=size, dpi=110)  # Agg canvas, no pyplot state
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    if osm_graph is not None and osm_graph.number_of_edges():
        by_class: dict[str, list[np.ndarray]] = {}
        for _, _, d in osm_graph.edges(data=True):
            hw = str(d.get("highway"))
            key = hw if hw in HIGHWAY_COLORS else "other"
            by_class.setdefault(key, []).append(np.asarray(d["geometry"].coords))
        order = [k for k in HIGHWAY_COLORS if k in by_class]
        if "other" in by_class:
            order.append("other")
        for key in reversed(order):
            lw = 2.2 if key.startswith(("motorway", "trunk")) else 1.0
            ax.add_collection(
                LineCollection(
                    by_class[key],
                    colors=HIGHWAY_COLORS.get(key, _OTHER_COLOR),
                    linewidths=lw,
                    alpha=0.8,
                    label=f"OSM {key} ({len(by_class[key])} edges)",
                    zorder=1,
                )
            )
    idx = _pick(len(run.edges), max_points, rng)
    edges, side = run.edges[idx], run.edge_side[idx]
    for code, name, color in ((1, "left", "#1f3a93"), (-1, "right", "#6c3483"), (0, "", "k")):
        sel = side == code
        if sel.any():
            label = f"road edge {name}".strip() + f" ({np.count_nonzero(run.edge_side == code):,})"
            ax.scatter(*edges[sel, :2].T, s=0.6, color=color, label=label, zorder=2, lw=0)
    lanes = run.lane_samples[_pick(len(run.lane_samples), max_points, rng)]
    ax.scatter(
        *lanes[:, :2].T,
        s=0.6,
        color="#27ae60",
        label=f"lane samples ({summary.lane_samples:,})",
        zorder=3,
        lw=0,
    )
    xy = run.trajectory.xy
    ax.plot(
        *xy.T, color="#111111", lw=1.2, label=f"trajectory ({summary.frames:,} poses)", zorder=4
    )
    ax.plot(*xy[0], marker="o", color="#111111", ms=5, zorder=5)
    ax.annotate("start", xy[0], xytext=(4, 4), textcoords="offset points", fontsize=8)
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x east (m, mapping frame)")
    ax.set_ylabel("y north (m, mapping frame)")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.set_title(
        f"{run.root.name}: {summary.driven_length_m / 1000:.2f} km, "
        f"{summary.duration_s:.0f} s, {summary.frames:,} frames, "
        f"{summary.edge_points:,} edge pts, {summary.lane_samples:,} lane samples\n"
        f"CRS {summary.crs}, {summary.traffic_side}-hand traffic",
        fontsize=9,
    )
    ax.legend(
        loc=_emptiest_corner(xy, (xmin, ymin, xmax, ymax)),
        fontsize=7,
        markerscale=8,
        framealpha=0.85,
    )
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.07, top=0.92)
    if path is not None:
        from .export import figure_png

        atomic_write_bytes(path, figure_png(fig))
    return fig


def _emptiest_corner(xy: np.ndarray, bbox: tuple[float, float, float, float]) -> str:
    """Legend location: the plot corner with the fewest trajectory poses (cheaper than
    matplotlib's ``"best"``, which scans every plotted point)."""
    xmin, ymin, xmax, ymax = bbox
    fx = (xy[:, 0] - xmin) / max(xmax - xmin, 1e-9)
    fy = (xy[:, 1] - ymin) / max(ymax - ymin, 1e-9)
    corners = {
        "upper left": (fx < 0.4) & (fy > 0.6),
        "upper right": (fx > 0.6) & (fy > 0.6),
        "lower left": (fx < 0.4) & (fy < 0.4),
        "lower right": (fx > 0.6) & (fy < 0.4),
    }
    return min(corners, key=lambda k: int(np.count_nonzero(corners[k])))


def _pick(size: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted indices of a seeded random subsample of at most ``n`` of ``size`` items."""
    if size <= n:
        return np.arange(size)
    return np.sort(rng.choice(size, size=n, replace=False))
