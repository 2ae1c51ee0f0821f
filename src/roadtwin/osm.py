"""OpenStreetMap road graph around a trajectory, in the mapping frame.

:func:`load_osm` streams a local extract (``.osm``, ``.osm.gz``, ``.osm.bz2``, ``.osm.pbf``)
with pyosmium, keeps only drivable ``highway`` ways that have a node within
``LoadConfig.osm_buffer_m`` of the trajectory, writes them to a small temporary OSM XML
file and builds the graph with OSMnx. A country-sized extract therefore costs one
streaming pass, never a graph of the whole file. :func:`load_osm_online` fetches the same
area through OSMnx (Overpass). Both return the same projected graph:

* nodes: ``x, y`` (mapping frame, metres), ``lon, lat`` (WGS84 degrees), OSM node tags;
* edges: ``highway, lanes, lanes:forward, lanes:backward, turn:lanes, oneway (bool),
  reversed (bool), ref, name, maxspeed, osmid, length`` (metres, in the mapping frame) and
  ``geometry`` (shapely LineString in the mapping frame from ``u`` to ``v``) on every edge;
* ``graph.graph["crs"]``: the mapping frame's CRS (a PROJ string for ``local``).

Tag values stay OSM strings (``lanes="3"``, ``turn:lanes="through|through;right"``); only
``oneway`` is OSMnx's bool. A key missing from an edge's attributes means the way has no such tag.

Edge direction is the direction of travel: OSMnx reverses ``oneway=-1`` ways, and adds a
reverse edge (``reversed=True``) only for two-way ways. ``highway=motorway`` and
``motorway_link`` without an ``oneway`` tag are one-way by OSM convention, so they get
``oneway=yes`` before the graph is built (online, where OSMnx has already decided, every
motorway edge is made one-way, so an explicit ``oneway=no`` motorway is lost). Edges never
span two OSM ways (simplification keeps way boundaries), so every tag is a single value.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import sys
import tempfile
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any
from xml.sax.saxutils import quoteattr

import networkx as nx
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree
from shapely.geometry import LineString

from ._errors import InputError, InputWarning, reason
from .config import LoadConfig
from .frames import MappingFrame

log = logging.getLogger(__name__)


WAY_TAGS = (
    "highway",
    "lanes",
    "lanes:forward",
    "lanes:backward",
    "turn:lanes",
    "oneway",
    "ref",
    "name",
    "maxspeed",
)
"""OSM way tags kept as edge attributes (plus ``junction``, which OSMnx needs for oneway)."""

DRIVABLE_HIGHWAYS = frozenset(
    {
        "motorway",
        "motorway_link",
        "trunk",
        "trunk_link",
        "primary",
        "primary_link",
        "secondary",
        "secondary_link",
        "tertiary",
        "tertiary_link",
        "unclassified",
        "residential",
        "living_street",
        "service",
        "road",
    }
)
"""``highway`` values kept from an extract (roads a car may drive on)."""

IMPLIED_ONEWAY = frozenset({"motorway", "motorway_link"})
OSM_SUFFIXES = (".osm", ".osm.gz", ".osm.bz2", ".osm.pbf")
_EXTRA_TAGS = ("junction",)


def load_osm(
    path: str | Path,
    *,
    frame: MappingFrame,
    around_xy: ArrayLike | None,
    config: LoadConfig | None = None,
) -> nx.MultiDiGraph:
    """Load the drivable OSM ways near a trajectory into a graph in the mapping frame.

    Parameters
    ----------
    path
        Local OSM extract: ``.osm``, ``.osm.gz``, ``.osm.bz2`` or ``.osm.pbf``.
    frame
        Mapping frame to project into.
    around_xy
        (N, 2) trajectory positions, mapping frame, metres. Ways with no node within
        ``config.osm_buffer_m`` of them are left out. ``None`` keeps every drivable way.
    config
        Loading settings; :class:`~roadtwin.config.LoadConfig` defaults if None.

    Returns
    -------
    networkx.MultiDiGraph
        Projected OSMnx graph (see the module docstring for attributes). Empty, with an
        :class:`~roadtwin._errors.InputWarning`, when no drivable way is near the trajectory.

    Raises
    ------
    InputError
        Missing, unreadable or empty file, or an unsupported suffix.
    """
    cfg = config if config is not None else LoadConfig()
    path = Path(path)
    if not path.is_file():
        msg = f"{path}: OSM file not found"
        raise InputError(msg)
    if not path.name.lower().endswith(OSM_SUFFIXES):
        msg = f"{path}: unsupported OSM format (expected one of {', '.join(OSM_SUFFIXES)})"
        raise InputError(msg)
    if path.stat().st_size == 0:
        msg = f"{path}: OSM file is empty (expected OSM XML or PBF data)"
        raise InputError(msg)

    ways = _read_highway_ways(path)
    if not ways.ids:
        if _is_empty(path):
            msg = f"{path}: OSM file has no data (expected nodes and highway ways)"
            raise InputError(msg)
        return _no_ways(path, frame, "the file has no drivable highway ways")

    x, y = frame.from_lonlat(ways.lon, ways.lat)
    keep_way = _ways_near(np.column_stack([x, y]), ways.way_index, len(ways.ids), around_xy, cfg)
    if not keep_way.any():
        _check_swapped_origin(path, ways, frame)
        return _no_ways(
            path,
            frame,
            f"none of its {len(ways.ids)} drivable ways is within {cfg.osm_buffer_m:g} m of "
            "the trajectory",
        )
    with tempfile.TemporaryDirectory(prefix="roadtwin-osm-") as tmp:
        xml_path = Path(tmp) / "cropped.osm"
        _write_xml(xml_path, ways, keep_way)
        graph = _graph_from_xml(xml_path)
    graph = _project_graph(graph, frame)
    graph.graph["source"] = str(path)
    if graph.number_of_edges() == 0:
        return _no_ways(path, frame, "the ways near it form no road graph")
    log.info(
        "OSM %s: kept %d of %d drivable ways within %.0f m -> %d nodes, %d edges",
        path.name,
        int(keep_way.sum()),
        len(ways.ids),
        cfg.osm_buffer_m,
        graph.number_of_nodes(),
        graph.number_of_edges(),
    )
    return graph


def load_osm_online(
    *,
    frame: MappingFrame,
    around_xy: ArrayLike,
    config: LoadConfig | None = None,
) -> nx.MultiDiGraph:
    """Fetch the drivable OSM graph around a trajectory through OSMnx (Overpass).

    Same area (``config.osm_buffer_m`` around ``around_xy``) and the same projected result
    as :func:`load_osm`. Needs network access.
    """
    import shapely

    ox = _osmnx()

    cfg = config if config is not None else LoadConfig()
    xy = np.atleast_2d(np.asarray(around_xy, dtype=float))[:, :2]
    line = LineString(xy) if len(xy) > 1 else LineString([xy[0], xy[0] + 1e-3])
    area = line.simplify(1.0).buffer(cfg.osm_buffer_m)
    area_lonlat = shapely.transform(
        area, lambda c: np.column_stack(frame.to_lonlat(c[:, 0], c[:, 1]))
    )
    with _osmnx_tags():
        try:
            graph = ox.graph_from_polygon(
                area_lonlat,
                network_type="drive",
                simplify=False,
                retain_all=True,
                truncate_by_edge=True,
            )
        except Exception as exc:  # osmnx raises InsufficientResponseError, HTTP errors
            msg = f"OSM online query around the trajectory failed: {reason(exc)}"
            raise InputError(msg) from None
        # Overpass data has lost whether motorway oneway was implied: drop reverse copies
        drop = [
            (u, v, k)
            for u, v, k, d in graph.edges(keys=True, data=True)
            if d.get("reversed") and d.get("highway") in IMPLIED_ONEWAY
        ]
        graph.remove_edges_from(drop)
        for _, _, d in graph.edges(data=True):
            if d.get("highway") in IMPLIED_ONEWAY:
                d["oneway"] = True
        graph = ox.simplify_graph(graph, edge_attrs_differ=["osmid"])
    graph = _project_graph(graph, frame)
    graph.graph["source"] = "overpass"
    return graph


# ---------------------------------------------------------------------------
# streaming and cropping
# ---------------------------------------------------------------------------


class _Ways:
    """Drivable ways of an extract as flat arrays (one row per way node)."""

    def __init__(self) -> None:
        self.ids: list[int] = []
        self.tags: list[dict[str, str]] = []
        self.ref: NDArray[np.int64] = np.zeros(0, np.int64)
        self.lon: NDArray[np.float64] = np.zeros(0)
        self.lat: NDArray[np.float64] = np.zeros(0)
        self.way_index: NDArray[np.int64] = np.zeros(0, np.int64)
        self.node_tags: dict[int, dict[str, str]] = {}


def _read_highway_ways(path: Path, *, extra_tags: tuple[str, ...] = ()) -> _Ways:
    """Every drivable way of an extract (``WAY_TAGS`` plus ``extra_tags`` kept)."""
    import osmium

    out = _Ways()
    refs: list[list[int]] = []
    lons: list[list[float]] = []
    lats: list[list[float]] = []
    keep = (*WAY_TAGS, *_EXTRA_TAGS, *extra_tags)
    try:
        processor = (
            osmium.FileProcessor(str(path))
            .with_locations()
            .with_filter(osmium.filter.KeyFilter("highway"))
        )
        for obj in processor:
            if obj.is_node():
                highway = obj.tags.get("highway")
                if highway is not None:
                    out.node_tags[obj.id] = {"highway": highway}
                continue
            if not obj.is_way():
                continue
            tags = obj.tags
            highway = tags.get("highway")
            if highway not in DRIVABLE_HIGHWAYS or tags.get("area") == "yes":
                continue
            r, lo, la = [], [], []
            for node in obj.nodes:
                loc = node.location
                if loc.valid():
                    r.append(node.ref)
                    lo.append(loc.lon)
                    la.append(loc.lat)
            if len(r) < 2:
                continue
            kept = {k: tags.get(k) for k in keep if k in tags}
            if highway in IMPLIED_ONEWAY and "oneway" not in kept:
                kept["oneway"] = "yes"
            out.ids.append(obj.id)
            out.tags.append(kept)
            refs.append(r)
            lons.append(lo)
            lats.append(la)
    except (RuntimeError, ValueError, OSError, osmium.InvalidLocationError) as exc:
        msg = f"{path}: not a readable OSM file ({reason(exc)})"
        raise InputError(msg) from None
    if out.ids:
        sizes = np.fromiter((len(r) for r in refs), np.int64, len(refs))
        out.way_index = np.repeat(np.arange(len(refs)), sizes)
        out.ref = np.fromiter((n for r in refs for n in r), np.int64, int(sizes.sum()))
        out.lon = np.fromiter((v for r in lons for v in r), np.float64, int(sizes.sum()))
        out.lat = np.fromiter((v for r in lats for v in r), np.float64, int(sizes.sum()))
    return out


def _is_empty(path: Path) -> bool:
    import osmium

    try:
        return next(iter(osmium.FileProcessor(str(path))), None) is None
    except (RuntimeError, ValueError, OSError) as exc:
        msg = f"{path}: not a readable OSM file ({reason(exc)})"
        raise InputError(msg) from None


def _km_between(lat1: float, lon1: float, lat2, lon2):
    """Great-circle distance (km) on a sphere of the earth's mean radius."""
    p1, p2 = np.radians(lat1), np.radians(lat2)
    dlat, dlon = p2 - p1, np.radians(np.asarray(lon2) - lon1)
    h = np.sin(dlat / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin(dlon / 2) ** 2
    return 2.0 * 6371.0 * np.arcsin(np.sqrt(np.clip(h, 0.0, 1.0)))


_SWAP_NEAR_KM = 50.0


def _check_swapped_origin(path: Path, ways: _Ways, frame: MappingFrame) -> None:
    """Refuse a run whose OSM data lie where the origin would be with lat and lon swapped.

    Only for the ``local`` frame, where the origin places the whole run: a swapped origin
    moves the run to another continent, and the map would be built there without an error.
    """
    o = frame.origin
    if frame.crs != "local" or abs(o.lon_deg) > 90.0:
        return
    lat_c, lon_c = float(np.median(ways.lat)), float(np.median(ways.lon))
    here = float(_km_between(o.lat_deg, o.lon_deg, lat_c, lon_c))
    swapped = float(_km_between(o.lon_deg, o.lat_deg, lat_c, lon_c))
    if here > _SWAP_NEAR_KM and swapped < _SWAP_NEAR_KM:
        msg = (
            f"{path}: the OSM data lie {here:.0f} km from the run's origin (lat "
            f"{o.lat_deg:g}, lon {o.lon_deg:g}) but {swapped:.0f} km from lat {o.lon_deg:g}, "
            f"lon {o.lat_deg:g}: are [origin] lat and lon swapped in run.toml?"
        )
        raise InputError(msg)


def _ways_near(
    node_xy: NDArray[np.float64],
    way_index: NDArray[np.int64],
    n_ways: int,
    around_xy: ArrayLike | None,
    cfg: LoadConfig,
) -> NDArray[np.bool_]:
    """Ways with at least one node within ``osm_buffer_m`` of the trajectory."""
    if around_xy is None:
        return np.ones(n_ways, bool)
    traj = np.atleast_2d(np.asarray(around_xy, dtype=float))[:, :2]
    dense = _densify(traj, max(cfg.osm_buffer_m / 8.0, 1.0))
    dist, _ = cKDTree(dense).query(node_xy, k=1, distance_upper_bound=cfg.osm_buffer_m)
    near = np.isfinite(dist)
    return np.bincount(way_index[near], minlength=n_ways) > 0


def _densify(xy: NDArray[np.float64], step_m: float) -> NDArray[np.float64]:
    if len(xy) < 2:
        return xy
    seg = np.hypot(*np.diff(xy, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    keep = np.concatenate([[True], seg > 0])
    if s[-1] <= 0:
        return xy[:1]
    grid = np.linspace(0.0, s[-1], int(np.ceil(s[-1] / step_m)) + 1)
    return np.column_stack(
        [np.interp(grid, s[keep], xy[keep, 0]), np.interp(grid, s[keep], xy[keep, 1])]
    )


def _write_xml(path: Path, ways: _Ways, keep_way: NDArray[np.bool_]) -> None:
    """Write the kept ways and their nodes as OSM XML for OSMnx."""
    rows = keep_way[ways.way_index]
    refs, first = np.unique(ways.ref[rows], return_index=True)
    lon = ways.lon[rows][first]
    lat = ways.lat[rows][first]
    parts = ['<?xml version="1.0" encoding="UTF-8"?>\n<osm version="0.6" generator="roadtwin">\n']
    for ref, lo, la in zip(refs.tolist(), lon.tolist(), lat.tolist(), strict=True):
        tags = ways.node_tags.get(ref)
        if tags:
            inner = "".join(f"<tag k={quoteattr(k)} v={quoteattr(v)}/>" for k, v in tags.items())
            parts.append(f'<node id="{ref}" lat="{la:.7f}" lon="{lo:.7f}">{inner}</node>\n')
        else:
            parts.append(f'<node id="{ref}" lat="{la:.7f}" lon="{lo:.7f}"/>\n')
    starts = np.searchsorted(ways.way_index, np.arange(len(ways.ids) + 1))
    for i in np.flatnonzero(keep_way).tolist():
        nds = "".join(f'<nd ref="{r}"/>' for r in ways.ref[starts[i] : starts[i + 1]].tolist())
        tags = "".join(f"<tag k={quoteattr(k)} v={quoteattr(v)}/>" for k, v in ways.tags[i].items())
        parts.append(f'<way id="{ways.ids[i]}">{nds}{tags}</way>\n')
    parts.append("</osm>\n")
    path.write_text("".join(parts), encoding="utf-8")


# ---------------------------------------------------------------------------
# OSMnx graph and projection
# ---------------------------------------------------------------------------


class _LazyBallTree:
    """Stands in for scikit-learn's ``BallTree`` in ``osmnx.distance``: imports it on
    first use."""

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        from sklearn.neighbors import BallTree

        return BallTree(*args, **kwargs)


class _LazyMatplotlib:
    """Stands in for one of the matplotlib modules ``osmnx.plot`` binds at import
    (``pyplot``, ``cm``, ``colormaps``, ``colors``): imports it on first use."""

    def __init__(self, module: str, attribute: str | None = None) -> None:
        self._module = module
        self._attribute = attribute

    def _target(self) -> Any:
        target = importlib.import_module(self._module)
        return getattr(target, self._attribute) if self._attribute else target

    def __getattr__(self, name: str) -> Any:
        return getattr(self._target(), name)

    def __getitem__(self, key: Any) -> Any:
        return self._target()[key]


# the names osmnx.plot binds from matplotlib, and what each one is
_OSMNX_MATPLOTLIB = {
    "plt": ("matplotlib.pyplot", None),
    "cm": ("matplotlib.cm", None),
    "colormaps": ("matplotlib", "colormaps"),
    "colors": ("matplotlib.colors", None),
}


def _osmnx() -> ModuleType:
    """OSMnx, imported without importing scikit-learn or ``matplotlib.pyplot``.

    ``osmnx.distance`` imports scikit-learn's ``BallTree`` at import time (0.6-0.8 s, a
    third of every build's fixed cost) for nearest-node searches on unprojected graphs,
    which roadtwin never runs; ``osmnx.plot`` imports ``matplotlib.pyplot`` (0.35 s) for
    plotting, which roadtwin never calls (its own plots use ``matplotlib.figure``). Both
    imports are held off while OSMnx loads and the names are bound to stand-ins that
    import the module when used, so OSMnx behaves as usual for anyone else in the same
    process (a notebook).
    """
    if "osmnx" in sys.modules:
        return sys.modules["osmnx"]
    held = [name for name in ("sklearn", "matplotlib.pyplot") if name not in sys.modules]
    for name in held:
        sys.modules[name] = None  # type: ignore[assignment]  # import -> ImportError
    try:
        import osmnx
        import osmnx.distance
        import osmnx.plot
    finally:
        for name in held:
            if name in sys.modules and sys.modules[name] is None:
                del sys.modules[name]
    if osmnx.distance.BallTree is None:
        osmnx.distance.BallTree = _LazyBallTree
    if not osmnx.plot.mpl_available and importlib.util.find_spec("matplotlib") is not None:
        for name, (module, attribute) in _OSMNX_MATPLOTLIB.items():
            setattr(osmnx.plot, name, _LazyMatplotlib(module, attribute))
        osmnx.plot.mpl_available = True
    return osmnx


@contextmanager
def _osmnx_tags() -> Iterator[None]:
    """Temporarily make OSMnx keep exactly the way tags the method needs."""
    ox = _osmnx()

    previous = list(ox.settings.useful_tags_way)
    ox.settings.useful_tags_way = [*WAY_TAGS, *_EXTRA_TAGS]
    try:
        yield
    finally:
        ox.settings.useful_tags_way = previous


def _graph_from_xml(xml_path: Path) -> nx.MultiDiGraph:
    ox = _osmnx()

    with _osmnx_tags():
        graph = ox.graph_from_xml(xml_path, simplify=False, retain_all=True)
        return ox.simplify_graph(graph, edge_attrs_differ=["osmid"])


def _project_graph(graph: nx.MultiDiGraph, frame: MappingFrame) -> nx.MultiDiGraph:
    """Nodes and edge geometries from WGS84 (OSMnx x=lon, y=lat) into the mapping frame."""
    nodes = list(graph.nodes)
    lon = np.array([graph.nodes[n]["x"] for n in nodes], dtype=float)
    lat = np.array([graph.nodes[n]["y"] for n in nodes], dtype=float)
    x, y = frame.from_lonlat(lon, lat) if nodes else (lon, lat)
    for n, lo, la, xx, yy in zip(
        nodes, lon.tolist(), lat.tolist(), x.tolist(), y.tolist(), strict=True
    ):
        data = graph.nodes[n]
        data["lon"], data["lat"], data["x"], data["y"] = lo, la, xx, yy
    node_xy = {n: (graph.nodes[n]["x"], graph.nodes[n]["y"]) for n in nodes}
    # project all interior geometry coordinates in one pyproj call
    edges = list(graph.edges(keys=True, data=True))
    geo: list[NDArray[np.float64]] = []
    for _, _, _, d in edges:
        g = d.get("geometry")
        geo.append(np.asarray(g.coords, float) if g is not None else np.zeros((0, 2)))
    sizes = np.array([len(g) for g in geo], dtype=np.int64)
    if sizes.sum():
        allc = np.vstack([g for g in geo if len(g)])
        px, py = frame.from_lonlat(allc[:, 0], allc[:, 1])
        proj = np.column_stack([px, py])
    else:
        proj = np.zeros((0, 2))
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    for i, (u, v, _, d) in enumerate(edges):
        if sizes[i] >= 2:
            coords = proj[offsets[i] : offsets[i + 1]].copy()
            coords[0], coords[-1] = node_xy[u], node_xy[v]  # exact node positions at the ends
        else:
            coords = np.array([node_xy[u], node_xy[v]])
        line = LineString(coords)
        d["geometry"] = line
        d["length"] = float(line.length)
        for key in ("osmid", *WAY_TAGS):
            if isinstance(d.get(key), list):  # defensive: never expected with osmid splits
                d[key] = d[key][0]
    graph.graph["crs"] = _graph_crs(frame)
    graph.graph["frame_crs"] = frame.crs
    return graph


def _graph_crs(frame: MappingFrame) -> str:
    return frame.geo_reference if frame.crs == "local" else frame.crs


def _no_ways(path: Path, frame: MappingFrame, why: str) -> nx.MultiDiGraph:
    warnings.warn(
        f"{path}: no drivable OSM ways near the trajectory ({why}); no ramps will be built",
        InputWarning,
        stacklevel=3,
    )
    graph = nx.MultiDiGraph(crs=_graph_crs(frame), frame_crs=frame.crs, source=str(path))
    return graph


def highway_counts(graph: nx.MultiDiGraph) -> dict[str, int]:
    """Number of distinct OSM ways per ``highway`` class in a graph."""
    seen: dict[str, set[Any]] = {}
    for _, _, d in graph.edges(data=True):
        seen.setdefault(str(d.get("highway")), set()).add(d.get("osmid"))
    return {k: len(v) for k, v in sorted(seen.items(), key=lambda kv: -len(kv[1]))}
