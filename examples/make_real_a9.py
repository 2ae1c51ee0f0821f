"""Make the ``real_a9`` scenario from the real OSM extract around Bayreuth.

Run from the repository root (needs /work/shared/data or pass the extract's path):

    python examples/make_real_a9.py [/path/to/north-bayreuth-a9.osm.gz]

It picks the eastbound A 70 carriageway towards the A 9 junction (Bayreuth area), a 3.5 km
window with its exit and entry, fits the smoothed real geometry with clothoid chains
(mainline reference line = left road edge, 4.5 m left of the OSM centreline for two
3.75 m lanes and a 0.75 m inner shoulder; ramps fitted to the link ways' shape from the
gore on), writes ``src/roadtwin/data/scenarios/real_a9.toml`` and crops the OSM of the
area to ``src/roadtwin/data/osm/real_a9.osm.gz`` (the real map input of that scenario).
OSM data (c) OpenStreetMap contributors, ODbL 1.0. Heights are synthetic (OSM has none).
"""

from __future__ import annotations

import gzip
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
from lxml import etree
from pyproj import Transformer

from roadtwin.model import LaneSection, Road
from roadtwin.simulate.alignment import build_pieces
from roadtwin.simulate.from_osm import chain_xy, crop_osm, fit_clothoids, smooth_polyline

SRC = Path(sys.argv[1] if len(sys.argv) > 1 else "/work/shared/data/osm/north-bayreuth-a9.osm.gz")
ROOT = Path(__file__).resolve().parents[1] / "src" / "roadtwin" / "data"
WINDOW = (200.0, 3700.0)  # stations along the OSM carriageway (metres)
LANES, WIDTH, INNER, HARD = 2, 3.75, 0.75, 2.5
EDGE_OFFSET = INNER + LANES * WIDTH / 2.0


def _length(node_ids, lonlat, fwd) -> float:
    p = np.array([fwd.transform(*lonlat[i]) for i in node_ids])
    return float(np.hypot(*np.diff(p, axis=0).T).sum())


def _next_link(ways, motorway_nodes, used, chain_ids, kind):
    """The one-way link way continuing a ramp away from the motorway: (way id, its nodes),
    or None. Stops at two-way links (shared by an exit and an entry)."""
    node = chain_ids[-1] if kind == "exit" else chain_ids[0]
    for k, (t, nds) in sorted(ways.items()):
        if k in used or t["highway"] != "motorway_link":
            continue
        two_way = False  # a two-way link is shared by both directions: the ramps end there
        if t.get("oneway", "yes") == "no":
            continue
        if kind == "exit":
            oriented = nds if nds[0] == node else nds[::-1] if two_way and nds[-1] == node else None
            far = oriented[-1] if oriented else None
        else:
            oriented = nds if nds[-1] == node else nds[::-1] if two_way and nds[0] == node else None
            far = oriented[0] if oriented else None
        if oriented is not None and far not in motorway_nodes:
            return k, oriented
    return None


def main() -> None:
    with gzip.open(SRC) as fh:
        root = etree.parse(fh).getroot()
    lonlat = {n.get("id"): (float(n.get("lon")), float(n.get("lat"))) for n in root.iter("node")}
    ways = {}
    for w in root.iter("way"):
        tags = {t.get("k"): t.get("v") for t in w.iter("tag")}
        if tags.get("highway") in ("motorway", "motorway_link"):
            ways[int(w.get("id"))] = (tags, [nd.get("ref") for nd in w.iter("nd")])
    motorway = {k: v for k, v in ways.items() if v[0]["highway"] == "motorway"}
    motorway_nodes = {n for _, nds in motorway.values() for n in nds}
    starts = defaultdict(list)
    for k, (_, nds) in motorway.items():
        starts[nds[0]].append(k)
    ends = {nds[-1] for _, nds in motorway.values()}
    # the eastbound A 70: the chain that starts at the western edge of the extract
    heads = [k for k, (t, nds) in motorway.items() if nds[0] not in ends and t.get("ref") == "A 70"]
    head = min(heads, key=lambda k: lonlat[motorway[k][1][0]][0])
    chain = [head]
    while nxt := [w for w in starts[motorway[chain[-1]][1][-1]] if w not in chain]:
        chain.append(nxt[0])
    ids: list[str] = []
    for w in chain:
        ids += motorway[w][1] if not ids else motorway[w][1][1:]
    ll = np.array([lonlat[i] for i in ids])
    lon0, lat0 = float(ll[0, 0]), float(ll[0, 1])
    fwd = Transformer.from_crs(
        "EPSG:4326",
        f"+proj=tmerc +lat_0={lat0} +lon_0={lon0} +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m",
        always_xy=True,
    )
    xy = np.column_stack(fwd.transform(ll[:, 0], ll[:, 1]))
    seg = np.hypot(*np.diff(xy, axis=0).T)
    s_node = np.concatenate([[0.0], np.cumsum(seg)])
    # window of the carriageway, smoothed; left road edge = centreline + EDGE_OFFSET to the left
    sm, hdg, s = smooth_polyline(xy, window_m=150.0)
    sel = (s >= WINDOW[0]) & (s <= WINDOW[1])
    centre, hdg_c = sm[sel], hdg[sel]
    left = centre + EDGE_OFFSET * np.column_stack([-np.sin(hdg_c), np.cos(hdg_c)])
    left_sm, left_hdg, left_s = smooth_polyline(left, window_m=31.0)
    elements = fit_clothoids(left_s, left_hdg, knot_spacing_m=60.0, smoothness=300.0)
    x0, y0, h0 = float(left_sm[0, 0]), float(left_sm[0, 1]), float(left_hdg[0])
    fitted = chain_xy(elements, x0=x0, y0=y0, hdg=h0)
    from scipy.spatial import cKDTree

    dev, _ = cKDTree(left_sm).query(fitted)
    print(
        f"mainline fit: {sum(e[0] for e in elements):.0f} m, {len(elements)} clothoids, "
        f"max dev {dev.max():.2f} m, rms {np.sqrt(np.mean(dev**2)):.2f} m"
    )
    pieces = build_pieces([("clothoid", *e) for e in elements], x0=x0, y0=y0, hdg=h0)
    road = Road("0", pieces, (LaneSection(0.0),))
    # ramps attached to the window
    pos = {n: s_node[i] for i, n in enumerate(ids)}
    link_start, link_end = defaultdict(list), defaultdict(list)
    for k, (t, nds) in ways.items():
        if t["highway"] == "motorway_link":
            link_start[nds[0]].append(k)
            link_end[nds[-1]].append(k)
    ramps = []
    for k, (t, nds) in ways.items():
        if t["highway"] != "motorway_link":
            continue
        for kind, node in (("exit", nds[0]), ("entry", nds[-1])):
            if node not in pos or not WINDOW[0] + 300 < pos[node] < WINDOW[1] - 400:
                continue
            # follow one-way link ways away from the motorway, up to ~450 m
            chain_ids, way_ids = list(nds), [k]
            while _length(chain_ids, lonlat, fwd) < 450.0:
                step = _next_link(ways, motorway_nodes, way_ids, chain_ids, kind)
                if step is None:
                    break
                way_ids.append(step[0])
                more = step[1]
                chain_ids = chain_ids + more[1:] if kind == "exit" else more[:-1] + chain_ids
            p = np.array([fwd.transform(*lonlat[i]) for i in chain_ids])
            if kind == "entry":
                p = p[::-1]  # from the gore backwards
            gore_xy = np.array(fwd.transform(*lonlat[node]))
            station = float(road.project(gore_xy[None, :])[0][0])
            h_gore = float(road.heading([station])[0])
            _, rh, rs = smooth_polyline(p, window_m=41.0)
            keep = rs <= 450.0
            rh, rs = rh[keep], rs[keep]
            start = h_gore if kind == "exit" else h_gore + np.pi
            rh = rh + 2 * np.pi * np.round((start - rh[0]) / (2 * np.pi))
            weight = (rs > 40.0).astype(float)
            el = fit_clothoids(
                rs, rh, knot_spacing_m=30.0, start_heading=start, weight=weight, smoothness=30.0
            )
            if kind == "entry":  # backward fit -> driving order
                el = [(length, -k1, -k0) for length, k0, k1 in reversed(el)]
            lanes = int(t.get("lanes", "1"))
            ramps.append((station, kind, lanes, el, way_ids, t.get("destination", "")))
            print(
                f"{kind} at {station:.0f} m, {lanes} lane(s), ways {way_ids}, "
                f"{sum(e[0] for e in el):.0f} m"
            )
    ramps.sort()
    lat_o, lon_o = lat0, lon0
    lines = [
        "# Generated by examples/make_real_a9.py -- do not edit by hand.",
        "# The eastbound A 70 towards the A 9 junction near Bayreuth, 3.5 km with one exit",
        "# and one entry: mainline and ramps follow the smoothed real OSM geometry (clothoid",
        "# chains); lane widths are realistic (2 x 3.75 m); heights are synthetic. The map input",
        "# is the real OSM crop ../osm/real_a9.osm.gz: (c) OpenStreetMap contributors, ODbL 1.0.",
        'name = "real_a9"',
        'description = "real geometry: A 70 eastbound near Bayreuth (OSM extract north-bayreuth-a9), 3.5 km, exit + entry"',  # noqa: E501
        "seed = 9",
        "",
        "[origin]",
        f"lat = {lat_o:.7f}",
        f"lon = {lon_o:.7f}",
        "alt = 420.0",
        "",
        "[traffic]",
        'side = "right"',
        "",
        "[start]",
        f"x = {x0:.4f}",
        f"y = {y0:.4f}",
        f"heading_deg = {np.degrees(h0):.6f}",
        "",
    ]
    for length, k0, k1 in elements:
        lines += ["[[alignment]]", 'type = "clothoid"', f"length = {length:.4f}",
                  f"curvature_start = {k0:.9f}", f"curvature_end = {k1:.9f}"]  # fmt: skip
    lines += ["", "[vertical]", "start_z = 0.0", "[[vertical.grades]]", "station = 0",
              "grade_pct = 1.2", "[[vertical.grades]]", "station = 1800", "grade_pct = -0.8",
              "curve_length = 600", "", "[lanes]", f"count = {LANES}", f"width = {WIDTH}",
              f"inner_shoulder = {INNER}", f"hard_shoulder = {HARD}", ""]  # fmt: skip
    for station, kind, lanes, el, way_ids, dest in ramps:
        lines += ["[[ramps]]", f'type = "{kind}"', f"station = {station:.3f}", f"lanes = {lanes}"]
        if dest:
            lines.append(f'name = "{dest}"')
        lines.append(f"osm_way_ids = {way_ids}")
        lines.append("elements = [")
        lines += [f"  [{length:.4f}, {k0:.9f}, {k1:.9f}]," for length, k0, k1 in el]
        lines += ["]", ""]
    lines += ["[opposite]", "enabled = false  # the real OSM has it", "",
              "[car]", "speed_kmh = 100", "", "[output]",
              'road_edges_format = "laz"', 'real_osm = "../osm/real_a9.osm.gz"']  # fmt: skip
    (ROOT / "scenarios" / "real_a9.toml").write_text("\n".join(lines) + "\n", encoding="utf-8")
    # crop: the window's bounding box plus ~500 m
    inv = Transformer.from_crs(fwd.target_crs, "EPSG:4326", always_xy=True)
    lo = left_sm.min(axis=0) - 500.0
    hi = left_sm.max(axis=0) + 500.0
    lon_a, lat_a = inv.transform(lo[0], lo[1])
    lon_b, lat_b = inv.transform(hi[0], hi[1])
    (ROOT / "osm").mkdir(exist_ok=True)
    counts = crop_osm(SRC, ROOT / "osm" / "real_a9.osm.gz", bbox=(lon_a, lat_a, lon_b, lat_b))
    print("cropped OSM:", counts)


if __name__ == "__main__":
    main()
