"""Exports of a built map besides OpenDRIVE: KML (Google Earth), GeoJSON and a PNG.

* :func:`write_kml` -- every road's reference line and lane borders as KML 2.2
  LineStrings in WGS84, one folder per road; mainline green and ramps red as in the
  paper's Google Earth overlays, connecting roads orange.
* :func:`write_geojson` -- lane polygons and lane borders in WGS84 (RFC 7946 order
  lon, lat), with road id, road name, lane id and type as properties.
* :func:`plot_network` -- a figure of the built map over the run's inputs (road-edge points,
  lane samples, trajectory), in the mapping frame; written as PNG only when a path is given.

All writers are atomic: they write a temporary file next to the target and rename it.
Coordinates come from the model in the mapping frame and are transformed with
:meth:`roadtwin.frames.MappingFrame.to_lonlat`.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from lxml import etree
from numpy.typing import NDArray

if TYPE_CHECKING:
    from matplotlib.figure import Figure

from ._errors import FitError
from ._files import atomic_write_bytes
from .frames import MappingFrame
from .model import LaneSection, Road, RoadNetwork

__all__ = ["figure_png", "network_lines", "plot_network", "write_geojson", "write_kml"]

KML_NS = "http://www.opengis.net/kml/2.2"
# KML colours are aabbggrr
_KML_STYLES = {
    "mainline": ("ff00ff00", 3.0),
    "ramp": ("ff0000ff", 3.0),
    "connector": ("ff00a5ff", 2.0),
    "other": ("ffb0b0b0", 1.5),
}
_PLOT_COLORS = {"mainline": "tab:green", "ramp": "tab:red", "connector": "tab:orange"}


def _role(road: Road) -> str:
    if road.name == "mainline":
        return "mainline"
    if road.name in ("exit", "entry"):
        return "ramp"
    if road.name == "connector" or road.junction != "-1":
        return "connector"
    return "other"


def _section_stations(road: Road, k: int, step_m: float) -> NDArray[np.float64]:
    sec = road.lane_sections[k]
    end = road.section_end(k)
    n = max(2, math.ceil((end - sec.s0) / step_m) + 1)
    s = np.linspace(sec.s0, end, n)
    # stay inside this section at its end (the next section starts there)
    s[-1] = max(sec.s0, end - 1e-6)
    return s


def _side_ids(section: LaneSection) -> list[int]:
    return [lane.id for lane in (*section.left, *section.right)]


def network_lines(
    network: RoadNetwork, *, step_m: float = 2.0
) -> Iterator[tuple[Road, int, int, NDArray[np.float64]]]:
    """Every lane border of every lane section as a polyline.

    Yields ``(road, section_index, lane_id, xy)``: ``xy`` is ``(N, 2)`` in the mapping
    frame (metres), the *outer* border of ``lane_id``; lane 0 is the centre line (lane
    offset; the reference line where there is no offset). Sampled every ``step_m``.
    """
    for road in network.roads:
        for k, sec in enumerate(road.lane_sections):
            s = _section_stations(road, k, step_m)
            for lane_id in [0, *_side_ids(sec)]:
                t = road.lane_border_t(s, lane_id)
                if np.all(np.isfinite(t)):
                    yield road, k, lane_id, road.to_xy(s, t)


def _lonlat(frame: MappingFrame, xy: NDArray[np.float64]) -> NDArray[np.float64]:
    lon, lat = frame.to_lonlat(xy[:, 0], xy[:, 1])
    ll = np.stack([lon, lat], axis=1)
    if not np.isfinite(ll).all():  # never write Infinity/NaN into KML or GeoJSON
        msg = (
            f"map coordinates (up to {np.nanmax(np.abs(xy)):.3g} m) have no WGS84 position in "
            f"the frame {frame.crs!r}: cannot write KML/GeoJSON"
        )
        raise FitError(msg)
    return ll


def kml_bytes(network: RoadNetwork, frame: MappingFrame, *, step_m: float = 2.0) -> bytes:
    """The KML 2.2 document of :func:`write_kml` as bytes."""
    kml = etree.Element(f"{{{KML_NS}}}kml", nsmap={None: KML_NS})
    doc = etree.SubElement(kml, "Document")
    etree.SubElement(doc, "name").text = network.header.name or "roadtwin"
    etree.SubElement(doc, "description").text = (
        "roadtwin map: mainline (green, measured), ramps (red, from OpenStreetMap), "
        "connecting roads (orange)"
    )
    for style_id, (color, width) in _KML_STYLES.items():
        style = etree.SubElement(doc, "Style", id=style_id)
        line = etree.SubElement(style, "LineStyle")
        etree.SubElement(line, "color").text = color
        etree.SubElement(line, "width").text = f"{width:g}"
    folders: dict[str, etree._Element] = {}
    for road, k, lane_id, xy in network_lines(network, step_m=step_m):
        folder = folders.get(road.id)
        if folder is None:
            folder = etree.SubElement(doc, "Folder")
            etree.SubElement(folder, "name").text = f"{road.name or 'road'} {road.id}"
            folders[road.id] = folder
        pm = etree.SubElement(folder, "Placemark")
        what = "reference line" if lane_id == 0 else f"lane {lane_id} outer border"
        etree.SubElement(pm, "name").text = f"road {road.id} section {k} {what}"
        etree.SubElement(pm, "styleUrl").text = f"#{_role(road)}"
        ls = etree.SubElement(pm, "LineString")
        etree.SubElement(ls, "tessellate").text = "1"
        etree.SubElement(ls, "altitudeMode").text = "clampToGround"
        ll = _lonlat(frame, xy)
        # one C-level %-format over all points (same text as f"{lon:.8f},{lat:.8f},0")
        etree.SubElement(ls, "coordinates").text = " ".join(["%.8f,%.8f,0"] * ll.shape[0]) % tuple(
            ll.ravel().tolist()
        )
    return etree.tostring(kml, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def write_kml(
    network: RoadNetwork, frame: MappingFrame, path: str | os.PathLike, *, step_m: float = 2.0
) -> Path:
    """Write the map as Google Earth KML 2.2 (atomic).

    Parameters
    ----------
    network
        The built map (mapping frame).
    frame
        The run's mapping frame (for the WGS84 transform).
    path
        Output file (``.kml``).
    step_m
        Sampling step along each road (metres).

    Returns
    -------
    Path of the written file.
    """
    return atomic_write_bytes(path, kml_bytes(network, frame, step_m=step_m))


def _round(ll: NDArray[np.float64]) -> list[list[float]]:
    """``(N, 2)`` lon/lat rounded to 8 decimals (~1 mm) as nested lists for JSON."""
    return np.round(ll, 8).tolist()


class _Borders:
    """Lane borders of one lane section at stations ``s``: offsets t (metres) and WGS84
    lon/lat lists rounded by :func:`_round`, each computed once (a border is the ring of
    two lanes and a boundary line)."""

    def __init__(self, road: Road, s: NDArray[np.float64], frame: MappingFrame) -> None:
        self._road, self._s, self._frame = road, s, frame
        self._t: dict[int, NDArray[np.float64]] = {}
        self._ll: dict[int, list[list[float]]] = {}

    def t(self, lane_id: int) -> NDArray[np.float64]:
        if lane_id not in self._t:
            self._t[lane_id] = self._road.lane_border_t(self._s, lane_id)
        return self._t[lane_id]

    def lonlat(self, lane_id: int) -> list[list[float]]:
        if lane_id not in self._ll:
            xy = self._road.to_xy(self._s, self.t(lane_id))
            self._ll[lane_id] = _round(_lonlat(self._frame, xy))
        return self._ll[lane_id]


def geojson_dict(network: RoadNetwork, frame: MappingFrame, *, step_m: float = 2.0) -> dict:
    """The GeoJSON FeatureCollection of :func:`write_geojson` as a dict."""
    features = []
    for road in network.roads:
        for k, sec in enumerate(road.lane_sections):
            s = _section_stations(road, k, step_m)
            borders = _Borders(road, s, frame)
            for lane in (*reversed(sec.left), *sec.right):
                inner_id = lane.id - 1 if lane.id > 0 else lane.id + 1
                outer = borders.t(lane.id)
                inner = borders.t(inner_id)
                if not (np.all(np.isfinite(outer)) and np.all(np.isfinite(inner))):
                    continue
                props = {
                    "road_id": road.id,
                    "road_name": road.name,
                    "section": k,
                    "lane_id": lane.id,
                    "type": lane.type,
                }
                if np.max(np.abs(outer - inner)) > 1e-3:
                    ring = [*borders.lonlat(inner_id), *borders.lonlat(lane.id)[::-1]]
                    ring.append(ring[0])
                    features.append(
                        {
                            "type": "Feature",
                            "properties": {"kind": "lane", **props},
                            "geometry": {"type": "Polygon", "coordinates": [ring]},
                        }
                    )
                mark = lane.road_marks[0].type if lane.road_marks else "none"
                features.append(
                    {
                        "type": "Feature",
                        "properties": {"kind": "boundary", **props, "mark": mark},
                        "geometry": {
                            "type": "LineString",
                            "coordinates": borders.lonlat(lane.id),
                        },
                    }
                )
            features.append(
                {
                    "type": "Feature",
                    "properties": {
                        "kind": "boundary",
                        "road_id": road.id,
                        "road_name": road.name,
                        "section": k,
                        "lane_id": 0,
                        "type": "center",
                        "mark": sec.center.road_marks[0].type if sec.center.road_marks else "none",
                    },
                    "geometry": {
                        "type": "LineString",
                        "coordinates": borders.lonlat(0),
                    },
                }
            )
    return {
        "type": "FeatureCollection",
        "name": network.header.name or "roadtwin",
        "features": features,
    }


def write_geojson(
    network: RoadNetwork, frame: MappingFrame, path: str | os.PathLike, *, step_m: float = 2.0
) -> Path:
    """Write lane polygons and lane borders as GeoJSON in WGS84 (atomic).

    Features have ``properties``: ``kind`` (``"lane"`` polygon or ``"boundary"``
    LineString), ``road_id``, ``road_name``, ``section``, ``lane_id``, ``type`` (lane
    type; ``"center"`` for lane 0) and, for boundaries, ``mark`` (road mark type).
    """
    data = json.dumps(
        geojson_dict(network, frame, step_m=step_m), separators=(",", ":"), allow_nan=False
    )
    return atomic_write_bytes(path, data.encode("utf-8"))


def plot_network(network: RoadNetwork, run=None, path: str | os.PathLike | None = None) -> Figure:
    """Figure of the built map (lane borders by role) over the run's inputs.

    Parameters
    ----------
    network
        The built map, mapping frame.
    run
        The :class:`~roadtwin.io.MappingRun` it was built from (road-edge points, lane
        samples and trajectory are drawn underneath), or ``None``.
    path
        If given, the figure is also written there as PNG (atomically); nothing is
        written otherwise.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (object API with an Agg canvas: no pyplot state, no backend change).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pts = [xy for _, _, lane_id, xy in network_lines(network, step_m=25.0) if lane_id == 0]
    if run is not None:
        pts.append(np.asarray(run.trajectory.xy))
    allxy = np.vstack(pts) if pts else np.zeros((2, 2))
    span = np.ptp(allxy, axis=0) + 40.0
    aspect = float(np.clip(span[1] / span[0], 0.3, 1.5))
    fig = Figure(figsize=(12, 1.5 + 10.5 * aspect), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    if run is not None:
        edges = np.asarray(run.edges)
        if edges.size:
            step = max(1, edges.shape[0] // 20000)
            ax.scatter(edges[::step, 0], edges[::step, 1], s=0.3, c="0.55", label="road edges")
        lanes = np.asarray(run.lane_samples)
        if lanes.size:
            step = max(1, lanes.shape[0] // 20000)
            ax.scatter(
                lanes[::step, 0], lanes[::step, 1], s=0.3, c="tab:blue", label="lane samples"
            )
        xy = run.trajectory.xy
        ax.plot(xy[:, 0], xy[:, 1], "k--", lw=0.6, label="trajectory")
    labelled: set[str] = set()
    for road, _, lane_id, xy in network_lines(network, step_m=2.0):
        role = _role(road)
        color = _PLOT_COLORS.get(role, "0.3")
        label = None if role in labelled else role
        labelled.add(role)
        ax.plot(xy[:, 0], xy[:, 1], color=color, lw=1.2 if lane_id == 0 else 0.7, label=label)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east (m, mapping frame)")
    ax.set_ylabel("y north (m, mapping frame)")
    ax.set_title(
        f"{network.header.name}: {len(network.roads)} roads, {len(network.junctions)} junctions"
    )
    ax.legend(loc="best", markerscale=10, fontsize=8)
    fig.tight_layout()
    if path is not None:
        atomic_write_bytes(path, figure_png(fig))
    return fig


def figure_png(fig: Figure, **savefig) -> bytes:
    """A matplotlib figure as PNG bytes (no ``Software`` metadata: same figure, same bytes)."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None}, **savefig)
    return buf.getvalue()
