"""Evaluation report files: ``report.json``, a self-contained ``report.html`` and PNG plots.

The HTML page needs no network and no JavaScript: inline CSS, tables, and the plots
embedded as base64 PNG. The same PNGs are written beside it. Plots use matplotlib's
object API (no global pyplot state) with the Agg backend.
"""

from __future__ import annotations

import base64
import html
import json
import logging
import re
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from ._files import atomic_write_bytes
from .evaluation import TABLE_TARGETS, EvaluationReport, PointErrors, RunEvaluation
from .export import figure_png

log = logging.getLogger(__name__)

MAX_PLOT_POINTS = 8000
"""Largest number of points drawn per series (evenly strided, deterministic)."""


def _stride(n: int, limit: int = MAX_PLOT_POINTS) -> slice:
    return slice(None, None, max(1, -(-n // limit)))


# ---------------------------------------------------------------------------
# plots
# ---------------------------------------------------------------------------


def plot_map(run: RunEvaluation) -> Figure:
    """Map plot (figure): built boundaries over the measurements coloured by |error|."""
    panels = [("self", "Measurements vs map (self-consistency)")]
    if any(k.startswith("truth/") for k in run.details):
        panels.append(("truth", "Truth boundaries vs map"))
    height = 4.2 * len(panels)
    fig = Figure(figsize=(11, height))
    axes = fig.subplots(len(panels), 1, squeeze=False)[:, 0]
    fig.subplots_adjust(
        left=0.08, right=0.98, bottom=0.6 / height, top=1 - 0.4 / height, hspace=0.35
    )
    for ax, (prefix, title) in zip(axes, panels, strict=True):
        if run.map_lines:
            ax.add_collection(LineCollection(run.map_lines, colors="0.65", lw=0.6, zorder=1))
            ax.autoscale_view()
        series = [
            d
            for k, d in run.details.items()
            if k.startswith(prefix + "/") and k != "truth/elevation" and d.error_m.size
        ]
        if series:
            xy = np.vstack([d.xy for d in series])
            err = np.abs(np.concatenate([d.error_m for d in series]))
            finite = np.isfinite(err)
            xy, err = xy[finite], err[finite]
            order = np.arange(err.size)[_stride(err.size)]
            order = order[np.argsort(err[order], kind="stable")]  # large errors drawn on top
            vmax = max(float(np.percentile(err, 99.0)), 1e-3)
            sc = ax.scatter(
                xy[order, 0],
                xy[order, 1],
                c=err[order],
                s=3,
                cmap="viridis",
                vmin=0.0,
                vmax=vmax,
                zorder=2,
                linewidths=0,
            )
            fig.colorbar(sc, ax=ax, label="|lateral error| (m)", shrink=0.9)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(f"{run.label}: {title}")
        ax.set_xlabel("x (m, mapping frame)")
        ax.set_ylabel("y (m)")
    return fig


def plot_error_along_s(run: RunEvaluation) -> Figure:
    """Signed lateral error along the mainline station for each boundary (figure)."""
    keys = [
        k
        for k in (
            "self/road_edge",
            "self/lane_boundary",
            "truth/road_edge",
            "truth/lane_boundary",
            "truth/elevation",
        )
        if k in run.details and run.details[k].error_m.size
    ]
    height = 2.6 * max(1, len(keys))
    fig = Figure(figsize=(11, height))
    axes = fig.subplots(max(1, len(keys)), 1, squeeze=False, sharex=True)[:, 0]
    fig.subplots_adjust(
        left=0.08, right=0.98, bottom=0.6 / height, top=1 - 0.35 / height, hspace=0.45
    )
    for ax, key in zip(axes, keys, strict=False):
        d: PointErrors = run.details[key]
        for lane_id in np.unique(d.boundary):
            m = d.boundary == lane_id
            order = np.argsort(d.station_m[m], kind="stable")
            st = d.station_m[m][order][_stride(int(m.sum()))]
            er = d.error_m[m][order][_stride(int(m.sum()))]
            if key.startswith("truth/") and st.size > 1:  # break lines where a lane is absent
                gap = np.nonzero(np.diff(st) > 5.0)[0] + 1
                st = np.insert(st, gap, np.nan)
                er = np.insert(er, gap, np.nan)
            if lane_id == 0:
                label = "inner edge (lane 0 border)"
            else:
                label = f"outer border of lane {lane_id}"
            style = (
                {"lw": 0.8} if key.startswith("truth/") else {"ls": "", "marker": ".", "ms": 1.5}
            )
            ax.plot(st, er, label=label, **style)
        ax.axhline(0.0, color="0.3", lw=0.5)
        unit = "dz (m)" if key.endswith("elevation") else "error (m)"
        ax.set_ylabel(unit)
        ax.set_title(f"{key}  (RMSE {d.rmse_m:.3f} m)", fontsize=10)
        ax.legend(fontsize=7, loc="upper right", ncol=3, markerscale=4)
    if not keys:
        axes[0].text(0.5, 0.5, "no evaluated points", ha="center", transform=axes[0].transAxes)
    axes[-1].set_xlabel("station along the mainline (m)")
    return fig


def plot_histogram(run: RunEvaluation) -> Figure:
    """Histograms of |lateral error|: self-consistency and (if any) against truth (figure)."""
    groups = [("self", "self-consistency")]
    if any(k.startswith("truth/") for k in run.details):
        groups.append(("truth", "against truth"))
    fig = Figure(figsize=(11, 3.8))
    axes = fig.subplots(1, len(groups), squeeze=False)[0]
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.14, top=0.9, wspace=0.2)
    for ax, (prefix, title) in zip(axes, groups, strict=True):
        series = [
            (k, np.abs(d.error_m[np.isfinite(d.error_m)]))
            for k, d in run.details.items()
            if k.startswith(prefix + "/") and k != "truth/elevation" and d.error_m.size
        ]
        if series:
            top = max(float(np.percentile(e, 99.5)) for _, e in series)
            bins = np.linspace(0.0, max(top * 1.05, 1e-2), 50)
            for key, e in series:
                ax.hist(np.clip(e, 0, bins[-1]), bins=bins, histtype="step", lw=1.4, label=key)
            ax.legend(fontsize=8)
        ax.set_xlabel("|lateral error| (m)")
        ax.set_ylabel("points")
        ax.set_title(f"{run.label}: {title}")
    return fig


PLOTS = (
    ("map_errors", plot_map),
    ("error_along_s", plot_error_along_s),
    ("error_histogram", plot_histogram),
)


# ---------------------------------------------------------------------------
# HTML
# ---------------------------------------------------------------------------

_CSS = """
body{font-family:DejaVu Sans,Arial,sans-serif;margin:24px;color:#222;max-width:1200px}
h1{font-size:22px}h2{font-size:18px;margin-top:28px;border-bottom:1px solid #ccc}
h3{font-size:15px}
table{border-collapse:collapse;margin:8px 0 16px 0;font-size:13px}
th,td{border:1px solid #bbb;padding:4px 8px;text-align:right}
th{background:#eef2f6;text-align:center}td.s,th:first-child{text-align:left}
.ok{color:#17702b;font-weight:bold}.bad{color:#b3261e;font-weight:bold}
img{max-width:100%;border:1px solid #ddd;margin:6px 0}
.note{color:#555;font-size:12px}
"""


def _f(value: Any, digits: int = 3) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return "–" if not np.isfinite(value) else f"{value:.{digits}f}"
    return html.escape(str(value))


def _table(head: list[str], rows: list[list[Any]], cls: str = "") -> str:
    out = [f'<table class="{cls}"><thead><tr>']
    out += [f"<th>{html.escape(h)}</th>" for h in head]
    out.append("</tr></thead><tbody>")
    for row in rows:
        cells = (
            f'<td class="s">{_f(v)}</td>' if isinstance(v, str) else f"<td>{_f(v)}</td>"
            for v in row
        )
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


_METHOD_NOTES = {
    "default": "roadtwin's default method",
    "paper": "the seed paper's method",
    "truth": "the true map: the floor set by the measurement noise",
    "map": "the given map",
}


def _paper_table(doc: dict) -> str:
    """Table 4 of the seed paper, one column group (mean, median, range) per method."""
    table = doc["table"]
    methods = list(table)
    out = ['<table class="paper"><thead><tr><th rowspan="2">Evaluation target</th>']
    out += [f'<th colspan="3">{html.escape(m)}</th>' for m in methods]
    out.append("</tr><tr>")
    out += ["<th>Mean RMSE (m)</th><th>Median RMSE (m)</th><th>RMSE range (m)</th>"] * len(methods)
    out.append("</tr></thead><tbody>")
    for key, title in TABLE_TARGETS:
        cells = [f'<td class="s">{html.escape(title)}</td>']
        for m in methods:
            st = table[m][key]
            rng = f"{st['min_rmse_m']:.3f}–{st['max_rmse_m']:.3f}" if st["runs"] else None
            cells += [f"<td>{_f(v)}</td>" for v in (st["mean_rmse_m"], st["median_rmse_m"])]
            cells.append(f"<td>{_f(rng)}</td>")
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    notes = "; ".join(
        f"{html.escape(m)}: {table[m]['overall']['runs']} run(s)"
        + (f", {_METHOD_NOTES[m]}" if m in _METHOD_NOTES else "")
        for m in methods
    )
    return "".join(out) + (
        '<p class="note">Frenet lateral RMSE of the run\'s own road-edge points and lane '
        "samples against the nearest boundary of the map (the seed paper's Table 4 layout; "
        f"overall pools all points of a run). {notes}.</p>"
    )


def _runs_table(doc: dict) -> str:
    head = [
        "Run",
        "Method",
        "Edge RMSE (m)",
        "Lane RMSE (m)",
        "Overall RMSE (m)",
        "Height RMSE (m)",
        "Edge points",
        "Lane samples",
        "On ramps",
        "Excluded",
    ]
    rows = []
    for r in doc["runs"]:
        sc = r["self_consistency"]
        rows.append(
            [
                r["label"],
                r["method"] or "map",
                sc["road_edge_rmse_m"],
                sc["lane_boundary_rmse_m"],
                sc["overall_rmse_m"],
                sc.get("height_rmse_m"),
                sc["road_edge_points"],
                sc["lane_samples"],
                sc.get("ramp_points"),
                sc["excluded_beyond_ends"] + sc["excluded_no_road"],
            ]
        )
    return _table(head, rows)


def _truth_tables(doc: dict) -> str:
    runs = [r for r in doc["runs"] if r["truth"]]
    if not runs:
        return '<p class="note">No ground truth given: accuracy against truth not evaluated.</p>'
    head = ["Run", "Method", "Metric", "n", "RMSE (m)", "p95 (m)", "max (m)", "Covered"]
    rows = []
    for r in runs:
        tr = r["truth"]
        for key, title in (
            ("road_edge", "Road edge"),
            ("lane_boundary", "Lane boundary"),
            ("elevation", "Elevation"),
            ("ramp_centre", "Ramp centre line"),
            ("ramp_boundary", "Ramp boundary"),
        ):
            st = tr.get(key) or {}
            cov = st.get("covered_fraction", tr.get("covered_fraction"))
            rows.append(
                [
                    r["label"],
                    r["method"] or "map",
                    title,
                    st.get("n"),
                    st.get("rmse_m"),
                    st.get("p95_m"),
                    st.get("max_m"),
                    cov,
                ]
            )
    out = _table(head, rows)
    head = ["Run", "Method", "Stations", "Lane count right", "Sections (true → built lanes)"]
    rows = []
    for r in runs:
        lc = r["truth"]["lane_count"]
        secs = "; ".join(
            f"{s['road_id']}@{s['s0_m']:.0f}: {s['true_driving_lanes']}→"
            f"{s['built_driving_lanes'] if s['built_driving_lanes'] is not None else '–'}"
            for s in lc["sections"]
        )
        rows.append(
            [r["label"], r["method"] or "map", lc["stations"], lc["matched_fraction"], secs]
        )
    return out + _table(head, rows)


def _topology_tables(doc: dict) -> str:
    head = [
        "Run",
        "Method",
        "True ramps",
        "Built ramps",
        "Matched",
        "Missed",
        "Spurious",
        "Type right",
        "Connected by lane links",
    ]
    rows = []
    for r in doc["runs"]:
        tp = r["topology"] or {}
        ramps = tp.get("ramps", [])
        conn = f"{sum(x['connected'] for x in ramps)}/{len(ramps)}"
        rows.append(
            [
                r["label"],
                r["method"] or "map",
                tp.get("true_ramps"),
                tp.get("built_ramps", len(ramps)),
                tp.get("matched"),
                ", ".join(tp.get("missed", [])) or "–",
                (", ".join(tp.get("spurious", [])) or "–")
                + (
                    f" (left out of the truth: {', '.join(tp['unjudged'])})"
                    if tp.get("unjudged")
                    else ""
                ),
                tp.get("type_correct"),
                conn,
            ]
        )
    return _table(head, rows)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "run"


def _drive_tables(drive: dict | None) -> str:
    """The drive-throughs in esmini (``roadtwin drive``'s ``drive.json``): one row per
    route, its faults, and esmini's warnings about the map."""
    if drive is None:
        return '<p class="note">Not driven: esmini not found (roadtwin drive --esmini DIR).</p>'
    head = ["Route", "Kind", "Roads", "Result", "Driven (m)", "On target (m)", "Max jump (m)"]
    rows = []
    for r in drive["routes"]:
        rows.append(
            [
                r["name"],
                r["kind"],
                " ".join(r["roads"]),
                r["status"],
                r["driven_m"],
                r["on_target_m"],
                r["max_jump_m"],
            ]
        )
    verdict = "ok" if drive["ok"] else "bad"
    out = [
        f'<p class="{verdict}">{drive["passed"]} of {drive["routes_total"]} routes passed, '
        f"{drive['failed']} failed, {drive['not_run']} not run; speed "
        f"{drive['speed_m_s']:g} m/s, step {drive['timestep_s']:g} s.</p>",
        _table(head, rows),
    ]
    faults = [(r["name"], f["message"]) for r in drive["routes"] for f in r["faults"]]
    if faults:
        out.append(_table(["Route", "Fault"], [list(x) for x in faults]))
    warnings = drive.get("esmini_warnings") or {}
    if warnings:
        out.append(
            _table(["esmini warning or error", "Routes"], [[m, n] for m, n in warnings.items()])
        )
    else:
        out.append('<p class="note">esmini logged no warning or error about the map.</p>')
    esmini = drive.get("esmini") or {}
    out.append(
        '<p class="note">A car driven in esmini ('
        + html.escape(esmini.get("version", "not found"))
        + ") along every route: it must reach the target road and drive on it, never jump "
        "(position off by more than its own motion), never use a lane that is not a driving "
        "lane, never leave the route and never get stuck.</p>"
    )
    return "".join(out)


def render_html(
    report: EvaluationReport, images: dict[str, bytes], *, drive: dict | None = None
) -> str:
    """The report page: tables and the given PNGs (name -> bytes) embedded as base64;
    with ``drive`` (a ``drive.json`` document) also the drive-throughs in esmini."""
    doc = report.to_dict()
    parts = [
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
        "<title>roadtwin evaluation report</title>",
        f"<style>{_CSS}</style></head><body>",
        "<h1>roadtwin evaluation report</h1>",
        "<h2>Self-consistency (paper Table 4)</h2>",
        _paper_table(doc),
        "<h3>Per run</h3>",
        _runs_table(doc),
        "<h2>Accuracy against truth</h2>",
        _truth_tables(doc),
        "<h2>Topology</h2>",
        _topology_tables(doc),
    ]
    if drive is not None:
        parts += ["<h2>Drive-throughs (esmini)</h2>", _drive_tables(drive)]
    parts.append("<h2>Plots</h2>")
    for name, png in images.items():
        b64 = base64.b64encode(png).decode("ascii")
        parts.append(f"<h3>{html.escape(name)}</h3>")
        parts.append(f'<img alt="{html.escape(name)}" src="data:image/png;base64,{b64}">')
    parts.append("</body></html>\n")
    return "\n".join(parts)


def write_report(
    report: EvaluationReport, out_dir: str | Path, *, drive: dict | None = None
) -> dict[str, Path]:
    """Write ``report.json``, ``report.html`` and the PNG plots into ``out_dir``.

    ``drive`` (the ``drive.json`` document of ``roadtwin drive``) adds the drive-throughs
    to the HTML page.

    Each file is written to a temporary name and renamed. PNG names are
    ``map_errors.png``, ``error_along_s.png``, ``error_histogram.png`` for a single run,
    prefixed with ``NN_<label>_`` per run when the report holds several.

    Returns
    -------
    dict
        File role (``"json"``, ``"html"``, PNG stem) -> path.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths: dict[str, Path] = {}
    images: dict[str, bytes] = {}
    multi = len(report.runs) > 1
    for i, run in enumerate(report.runs):
        prefix = f"{i + 1:02d}_{_slug(run.label)}_" if multi else ""
        for stem, plot in PLOTS:
            name = f"{prefix}{stem}"
            png = figure_png(plot(run), dpi=100)
            path = out / f"{name}.png"
            atomic_write_bytes(path, png)
            paths[name] = path
            images[name] = png
    doc = report.to_dict()
    paths["json"] = out / "report.json"
    atomic_write_bytes(
        paths["json"], (json.dumps(doc, indent=2, sort_keys=True) + "\n").encode("utf-8")
    )
    paths["html"] = out / "report.html"
    atomic_write_bytes(paths["html"], render_html(report, images, drive=drive).encode("utf-8"))
    log.info("wrote evaluation report (%d run(s)) to %s", len(report.runs), out)
    return paths
