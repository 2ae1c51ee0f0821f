"""KML, GeoJSON and PNG exports of a built network (hand-built mainline + two ramps)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from lxml import etree
from pyproj import Geod
from shapely.geometry import Polygon

from roadtwin.export import network_lines, plot_network, write_geojson, write_kml
from roadtwin.frames import MappingFrame, Origin
from roadtwin.model import Header, RoadNetwork
from roadtwin.topology import build_topology
from test_topology import mainline_road, make_ramps

KML = "{http://www.opengis.net/kml/2.2}"
FRAME = MappingFrame(Origin(49.98, 11.62, 420.0))


@pytest.fixture(scope="module")
def network() -> RoadNetwork:
    road = mainline_road("right")
    topo = build_topology(road, make_ramps(road, "right"))
    return RoadNetwork(
        Header(name="export", geo_reference=FRAME.geo_reference), topo.roads, topo.junctions
    )


def test_kml_parses_and_lies_at_the_right_place(network, tmp_path):
    path = write_kml(network, FRAME, tmp_path / "map.kml")
    root = etree.parse(str(path)).getroot()
    assert root.tag == f"{KML}kml"
    doc = root.find(f"{KML}Document")
    styles = {
        s.get("id"): s.findtext(f"{KML}LineStyle/{KML}color") for s in doc.iter(f"{KML}Style")
    }
    assert styles["mainline"] == "ff00ff00"  # green (aabbggrr)
    assert styles["ramp"] == "ff0000ff"  # red
    placemarks = list(doc.iter(f"{KML}Placemark"))
    lines = list(network_lines(network))
    assert len(placemarks) == len(lines)
    folders = [f.findtext(f"{KML}name") for f in doc.iter(f"{KML}Folder")]
    assert len(folders) == len(network.roads)
    role = {"mainline": "#mainline", "exit": "#ramp", "entry": "#ramp", "connector": "#connector"}
    geod = Geod(ellps="WGS84")
    for pm, (road, _, _, xy) in zip(placemarks, lines, strict=True):
        assert pm.findtext(f"{KML}styleUrl") == role[road.name]
        text = pm.findtext(f"{KML}LineString/{KML}coordinates")
        coords = np.array([[float(v) for v in c.split(",")] for c in text.split()])
        assert coords.shape == (xy.shape[0], 3)
        # every point where the mapping frame says, measured on the ellipsoid from the
        # origin (local frame: the origin is (0, 0))
        az, _, dist = geod.inv(
            np.full(len(coords), FRAME.origin.lon_deg),
            np.full(len(coords), FRAME.origin.lat_deg),
            coords[:, 0],
            coords[:, 1],
        )
        expected = np.hypot(xy[:, 0], xy[:, 1])
        assert np.max(np.abs(dist - expected)) < 0.05 + 1e-6 * expected.max()
        bearing = np.degrees(np.arctan2(xy[:, 0], xy[:, 1]))  # clockwise from north
        ok = expected > 1.0
        diff = (az[ok] - bearing[ok] + 180.0) % 360.0 - 180.0
        assert np.max(np.abs(diff)) < 0.01
    # the map sits next to the origin: the mainline starts 100 m E / 50 m N of it
    first = placemarks[0].findtext(f"{KML}LineString/{KML}coordinates").split()[0]
    lon, lat, _ = (float(v) for v in first.split(","))
    _, _, d = geod.inv(FRAME.origin.lon_deg, FRAME.origin.lat_deg, lon, lat)
    assert d == pytest.approx(math.hypot(100.0, 50.0), abs=0.05)


def test_geojson_lanes_and_boundaries(network, tmp_path):
    path = write_geojson(network, FRAME, tmp_path / "map.geojson")
    data = json.loads(path.read_text(encoding="utf-8"))
    assert data["type"] == "FeatureCollection"
    lanes = [f for f in data["features"] if f["properties"]["kind"] == "lane"]
    bounds = [f for f in data["features"] if f["properties"]["kind"] == "boundary"]
    assert lanes
    assert bounds
    for f in lanes:
        assert f["geometry"]["type"] == "Polygon"
        ring = f["geometry"]["coordinates"][0]
        assert ring[0] == ring[-1]
        assert {"road_id", "lane_id", "type", "road_name"} <= set(f["properties"])
    # lane area in the mapping frame: road 1 section 0 lane -2 is 3.75 m x 300 m
    f = next(
        f
        for f in lanes
        if f["properties"]["road_id"] == "1"
        and f["properties"]["section"] == 0
        and f["properties"]["lane_id"] == -2
    )
    ring = np.array(f["geometry"]["coordinates"][0])
    x, y = FRAME.from_lonlat(ring[:, 0], ring[:, 1])
    assert Polygon(np.stack([x, y], axis=1)).area == pytest.approx(3.75 * 300.0, rel=0.005)
    # one boundary per lane border and section, plus the centre line
    n_sections = sum(len(r.lane_sections) for r in network.roads)
    n_lanes = sum(len(s.left) + len(s.right) for r in network.roads for s in r.lane_sections)
    assert len(bounds) == n_lanes + n_sections
    ramp_lanes = [f for f in lanes if f["properties"]["road_name"] in ("exit", "entry")]
    # ramps have the mainline layout: inner shoulder, driving lane(s), hard shoulder
    assert {f["properties"]["type"] for f in ramp_lanes} == {"driving", "shoulder"}


def test_png_and_atomic_write(network, tmp_path):
    path = tmp_path / "map.png"
    plot_network(network, None, path)
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 10_000
    (tmp_path / "busy.kml").mkdir()
    with pytest.raises(IsADirectoryError):
        write_kml(network, FRAME, tmp_path / "busy.kml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["busy.kml", "map.png"]


def test_vectorised_coordinates_equal_per_point_formatting(network, tmp_path):
    """The writers format all coordinates at once; the text equals per-point formatting
    (Python ``round(v, 8)`` in GeoJSON, ``f"{lon:.8f},{lat:.8f},0"`` in KML)."""
    geo = json.loads(write_geojson(network, FRAME, tmp_path / "m.geojson").read_text("utf-8"))
    kml = etree.parse(str(write_kml(network, FRAME, tmp_path / "m.kml"))).getroot()
    texts = [pm.findtext(f"{KML}LineString/{KML}coordinates") for pm in kml.iter(f"{KML}Placemark")]
    lines = list(network_lines(network))
    for text, (road, k, lane_id, xy) in zip(texts, lines, strict=True):
        lon, lat = FRAME.to_lonlat(xy[:, 0], xy[:, 1])
        assert text == " ".join(f"{a:.8f},{b:.8f},0" for a, b in zip(lon, lat, strict=True))
        feature = next(
            f
            for f in geo["features"]
            if f["properties"]["kind"] == "boundary"
            and f["properties"]["road_id"] == road.id
            and f["properties"]["section"] == k
            and f["properties"]["lane_id"] == lane_id
        )
        expected = [[round(float(a), 8), round(float(b), 8)] for a, b in zip(lon, lat, strict=True)]
        assert feature["geometry"]["coordinates"] == expected
    # and on 200 000 random coordinates: numpy rounding == Python round
    rng = np.random.default_rng(5)
    vals = np.column_stack([rng.uniform(-180, 180, 100_000), rng.uniform(-90, 90, 100_000)])
    assert np.round(vals, 8).tolist() == [[round(a, 8), round(b, 8)] for a, b in vals.tolist()]
