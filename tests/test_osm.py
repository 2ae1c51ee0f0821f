"""OSM loader on real extracts: formats, tags, edge direction, cropping, projection."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import osmium
import pytest
from pyproj import CRS, Transformer
from shapely.geometry import LineString

from _run_factory import motorway_start
from roadtwin._errors import InputError, InputWarning
from roadtwin.config import LoadConfig
from roadtwin.frames import MappingFrame, Origin
from roadtwin.osm import DRIVABLE_HIGHWAYS, WAY_TAGS, load_osm

OSM_DIR = Path(__file__).parent / "data" / "osm"
FILES = {
    "osm": OSM_DIR / "a9-bindlacher-berg.osm",
    "osm.gz": OSM_DIR / "a9-dreieck-bayreuth-kulmbach.osm.gz",
    "osm.bz2": OSM_DIR / "west-oakland-i880.osm.bz2",
    "osm.pbf": OSM_DIR / "kotka-e18.osm.pbf",
    "osm.pbf-lht": OSM_DIR / "melbourne-lht.osm.pbf",
}


def _raw_ways(path: Path) -> dict[int, tuple[dict[str, str], list[int], np.ndarray]]:
    """Drivable highway ways with >= 2 nodes in the file, read directly with pyosmium:
    tags, node refs, lon/lat."""
    out = {}
    proc = osmium.FileProcessor(str(path)).with_locations()
    for obj in proc.with_filter(osmium.filter.KeyFilter("highway")):
        if obj.is_way() and obj.tags.get("highway") in DRIVABLE_HIGHWAYS:
            nodes = [n for n in obj.nodes if n.location.valid()]
            if len(nodes) < 2:  # way outside the extract
                continue
            out[obj.id] = (
                dict(obj.tags),
                [n.ref for n in nodes],
                np.array([(n.lon, n.lat) for n in nodes]),
            )
    return out


@functools.cache
def raw_ways(path: Path):
    return _raw_ways(path)


@functools.cache
def frame_for(path: Path) -> tuple[MappingFrame, float]:
    lat, lon, heading = motorway_start(path)
    return MappingFrame(Origin(lat, lon, 0.0)), heading


@functools.cache
def full_graph(path: Path):
    """Uncropped graph of a test file (cached: the tests only read it)."""
    frame, _ = frame_for(path)
    return load_osm(path, frame=frame, around_xy=None)


@pytest.mark.parametrize("kind", list(FILES))
def test_each_format_loads_projected_with_geometry_on_every_edge(kind):
    path = FILES[kind]
    graph = full_graph(path)
    raw = raw_ways(path)
    assert graph.number_of_edges() > 20
    assert CRS.from_user_input(graph.graph["crs"]).is_projected
    # node x/y are the projected lon/lat (check against an independent pyproj transformer)
    to_xy = Transformer.from_crs("EPSG:4326", graph.graph["crs"], always_xy=True)
    lon = np.array([d["lon"] for _, d in graph.nodes(data=True)])
    lat = np.array([d["lat"] for _, d in graph.nodes(data=True)])
    x, y = to_xy.transform(lon, lat)
    np.testing.assert_allclose(x, [d["x"] for _, d in graph.nodes(data=True)], atol=1e-6)
    np.testing.assert_allclose(y, [d["y"] for _, d in graph.nodes(data=True)], atol=1e-6)
    assert np.abs(x).max() < 20_000  # metres around the origin, not degrees or UTM
    for u, v, d in graph.edges(data=True):
        geom = d["geometry"]
        assert isinstance(geom, LineString)
        coords = np.asarray(geom.coords)
        np.testing.assert_allclose(coords[0], (graph.nodes[u]["x"], graph.nodes[u]["y"]))
        np.testing.assert_allclose(coords[-1], (graph.nodes[v]["x"], graph.nodes[v]["y"]))
        assert d["length"] == pytest.approx(geom.length)
        assert d["length"] > 0
        assert d["highway"] in DRIVABLE_HIGHWAYS
        assert d["osmid"] in raw  # one edge never spans two OSM ways
    # every drivable way of the file is in the graph (no crop)
    assert {d["osmid"] for *_, d in graph.edges(data=True)} == set(raw)


def test_tags_kept_exactly():
    path = FILES["osm"]
    graph = full_graph(path)
    raw = raw_ways(path)
    n_turn = 0
    for _, _, d in graph.edges(data=True):
        tags = raw[d["osmid"]][0]
        for key in WAY_TAGS:
            if key == "oneway":
                continue
            assert d.get(key) == tags.get(key), (d["osmid"], key)
        n_turn += "turn:lanes" in d
        assert isinstance(d["oneway"], bool)
    assert n_turn > 0
    lanes = {d.get("lanes") for *_, d in graph.edges(data=True) if d["highway"] == "motorway"}
    assert lanes - {None}  # motorway lane counts are there


@pytest.mark.parametrize("kind", ["osm", "osm.gz", "osm.bz2", "osm.pbf", "osm.pbf-lht"])
def test_link_edges_follow_the_direction_of_travel(kind):
    """Motorway (links) are one-way unless tagged oneway=no: one edge per piece, from the
    earlier to the later way node (reversed for oneway=-1), geometry along the node order."""
    path = FILES[kind]
    frame, _ = frame_for(path)
    graph = full_graph(path)
    raw = raw_ways(path)
    n_links = 0
    for u, v, d in graph.edges(data=True):
        if d["highway"] not in ("motorway", "motorway_link"):
            continue
        tags, refs, lonlat = raw[d["osmid"]]
        if tags.get("oneway") == "no":  # explicitly two-way (exists on a real A9 link)
            assert d["oneway"] is False
            forward = not d["reversed"]
        else:  # tagged or implied one-way: a single edge per piece
            assert d["oneway"] is True
            assert d["reversed"] is False
            back = graph[v][u].values() if graph.has_edge(v, u) else []
            assert all(e["osmid"] != d["osmid"] for e in back)
            forward = tags.get("oneway") not in ("-1", "reverse")
        iu, iv = refs.index(u), refs.index(v)
        assert (iu < iv) if forward else (iu > iv)
        # the edge geometry runs through the way's nodes in the same order
        piece = lonlat[min(iu, iv) : max(iu, iv) + 1]
        if not forward:
            piece = piece[::-1]
        px, py = frame.from_lonlat(piece[:, 0], piece[:, 1])
        np.testing.assert_allclose(np.asarray(d["geometry"].coords), np.c_[px, py], atol=1e-6)
        n_links += d["highway"] == "motorway_link"
    assert n_links >= 2


def test_two_way_roads_get_both_directions():
    graph = full_graph(FILES["osm.bz2"])
    two_way = [(u, v, d) for u, v, d in graph.edges(data=True) if not d["oneway"]]
    assert two_way
    for u, v, d in two_way:
        coords = np.asarray(d["geometry"].coords)
        back = [
            e
            for e in graph[v][u].values()
            if e["osmid"] == d["osmid"]
            and e["reversed"] != d["reversed"]
            and np.allclose(np.asarray(e["geometry"].coords)[::-1], coords)
        ]
        assert len(back) == 1


def test_crop_keeps_exactly_the_ways_near_the_trajectory():
    path = FILES["osm"]
    frame, heading = frame_for(path)
    s = np.linspace(0.0, 300.0, 61)
    traj = np.c_[s * np.cos(heading), s * np.sin(heading)]
    cfg = LoadConfig(osm_buffer_m=120.0)
    graph = load_osm(path, frame=frame, around_xy=traj, config=cfg)
    raw = raw_ways(path)
    expected = set()
    for way_id, (_, _, lonlat) in raw.items():
        x, y = frame.from_lonlat(lonlat[:, 0], lonlat[:, 1])
        # distance of each node to the trajectory segment (exact, brute force)
        d = np.abs(np.c_[x, y] @ np.array([-np.sin(heading), np.cos(heading)]))
        along = np.c_[x, y] @ np.array([np.cos(heading), np.sin(heading)])
        d = np.where(along < 0, np.hypot(x, y), d)
        d = np.where(along > 300, np.hypot(x - traj[-1, 0], y - traj[-1, 1]), d)
        if (d <= 120.0 - 0.1).any():
            expected.add(way_id)
        elif (d <= 120.0 + 0.1).any():
            pytest.skip("a node sits on the buffer border")
    kept = {d["osmid"] for *_, d in graph.edges(data=True)}
    assert kept == expected
    assert 0 < len(kept) < len(raw)
    assert any(d["highway"] == "motorway" for *_, d in graph.edges(data=True))


def test_no_drivable_ways_near_the_trajectory_warns_and_returns_empty():
    path = FILES["osm.pbf"]
    frame, _ = frame_for(path)
    far = np.array([[50_000.0, 50_000.0], [50_100.0, 50_000.0]])
    with pytest.warns(InputWarning, match="no ramps will be built"):
        graph = load_osm(path, frame=frame, around_xy=far)
    assert graph.number_of_edges() == 0
    assert graph.graph["crs"] == frame.geo_reference


@pytest.mark.parametrize(
    ("content", "name", "message"),
    [
        (b"", "e.osm", "OSM file is empty"),
        (b"this is not xml", "bad.osm", "not a readable OSM file"),
        (b"\x00\x01garbage", "bad.osm.pbf", "not a readable OSM file"),
        (b'<?xml version="1.0"?>\n<osm version="0.6"></osm>\n', "none.osm", "has no data"),
        (b"<osm/>", "map.txt", "unsupported OSM format"),
    ],
)
def test_bad_osm_files(tmp_path, content, name, message):
    (tmp_path / name).write_bytes(content)
    frame = MappingFrame(Origin(50.0, 11.6, 0.0))
    with pytest.raises(InputError, match=message):
        load_osm(tmp_path / name, frame=frame, around_xy=None)


def test_missing_osm_file(tmp_path):
    frame = MappingFrame(Origin(50.0, 11.6, 0.0))
    with pytest.raises(InputError, match="OSM file not found"):
        load_osm(tmp_path / "nope.osm.pbf", frame=frame, around_xy=None)


def test_online_path_postprocessing_without_network(monkeypatch):
    """``load_osm_online`` with OSMnx's Overpass download replaced by the same data from a
    file (no network): area polygon around the trajectory in lon/lat, motorways one-way,
    projection identical to the file loader."""
    import osmnx as ox
    from shapely.geometry import MultiPoint

    from roadtwin.osm import load_osm_online

    path = FILES["osm"]
    frame, heading = frame_for(path)
    traj = np.c_[
        np.linspace(0, 300, 31) * np.cos(heading), np.linspace(0, 300, 31) * np.sin(heading)
    ]
    seen = {}

    def overpass_from_file(polygon, **kwargs):
        seen.update(kwargs, polygon=polygon)
        return ox.graph_from_xml(path, simplify=False, retain_all=True)

    monkeypatch.setattr(ox, "graph_from_polygon", overpass_from_file)
    graph = load_osm_online(frame=frame, around_xy=traj, config=LoadConfig(osm_buffer_m=200.0))
    lon, lat = frame.to_lonlat(traj[:, 0], traj[:, 1])
    assert seen["polygon"].contains(MultiPoint(np.c_[lon, lat]))
    assert seen["network_type"] == "drive"
    assert graph.graph["crs"] == frame.geo_reference

    def motorway_edges(g):
        raw = raw_ways(path)
        return {
            (u, v, d["osmid"])
            for u, v, d in g.edges(data=True)
            if d["highway"] in ("motorway", "motorway_link")
            and raw[d["osmid"]][0].get("oneway") != "no"
        }

    online = motorway_edges(graph)
    assert online
    assert online == motorway_edges(full_graph(path))
    for u, v, d in graph.edges(data=True):
        np.testing.assert_allclose(
            d["geometry"].coords[0], (graph.nodes[u]["x"], graph.nodes[u]["y"])
        )
        np.testing.assert_allclose(
            d["geometry"].coords[-1], (graph.nodes[v]["x"], graph.nodes[v]["y"])
        )


def test_loading_osm_does_not_import_scikit_learn_or_pyplot_yet_osmnx_still_can():
    """OSMnx imports scikit-learn (0.6-0.8 s) for nearest-node searches on unprojected
    graphs and ``matplotlib.pyplot`` (0.35 s) for its plots, neither of which a build
    runs: a build's OSM load leaves both unimported. Later in the same process (a
    notebook) OSMnx's unprojected search and its plots still work and import them."""
    import subprocess
    import sys

    code = f"""
import sys
from roadtwin.frames import MappingFrame, Origin
from roadtwin.osm import load_osm
frame = MappingFrame(Origin(49.99, 11.6, 0.0))
graph = load_osm({str(FILES["osm"])!r}, frame=frame, around_xy=None)
print(graph.number_of_edges() > 0, "sklearn" in sys.modules, "matplotlib.pyplot" in sys.modules)
import networkx as nx
import osmnx as ox
g = nx.MultiDiGraph(crs="epsg:4326")
g.add_node(1, x=11.5, y=50.0)
g.add_node(2, x=11.6, y=50.1)
g.add_edge(1, 2, length=14000.0)
print(ox.distance.nearest_nodes(g, [11.59], [50.09]).tolist(), "sklearn" in sys.modules)
print(ox.plot.get_colors(2))
fig, ax = ox.plot_graph(g, show=False, close=True)
drawn = len(ax.lines) + len(ax.collections) > 0
print(type(fig).__name__, drawn, "matplotlib.pyplot" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split("\n")[:4] == [
        "True False False",
        "[2] True",
        "['#440154', '#fde725']",
        "Figure True True",
    ]
