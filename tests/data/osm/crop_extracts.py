"""One-off script that cut the small OSM test extracts from /work/shared/data/osm.

Keeps every way with a ``highway`` tag that has a node inside a lon/lat box, with all of
its nodes (so ways are complete) and their tags. Data: © OpenStreetMap contributors, ODbL.
Run: ``python tests/data/osm/crop_extracts.py /work/shared/data/osm/north-bayreuth-a9.osm.gz
[NAME ...]`` (the Krems crop from ``krems-s5-trunk.osm.gz``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import osmium

CROPS = {
    # name: (lon_min, lat_min, lon_max, lat_max) around an A9 junction
    "a9-bindlacher-berg.osm": (11.598, 50.0095, 11.613, 50.0205),
    "a9-dreieck-bayreuth-kulmbach.osm.gz": (11.594, 50.0195, 11.614, 50.0305),
    # an A9 interchange with both carriageways, their ramps and the roads beyond them
    "a9-bayreuth-nord.osm.gz": (11.486, 50.0345, 11.501, 50.0425),
    # the S5 near Krems where it is one carriageway: links of both directions meet it, on
    # both sides (from krems-s5-trunk.osm.gz)
    "krems-s5-links.osm.gz": (15.612, 48.4035, 15.634, 48.4115),
}


def crop(source: Path, target: Path, box: tuple[float, float, float, float]) -> None:
    lon0, lat0, lon1, lat1 = box
    keep_ways: set[int] = set()
    keep_nodes: set[int] = set()
    processor = osmium.FileProcessor(str(source)).with_locations()
    for obj in processor.with_filter(osmium.filter.KeyFilter("highway")):
        if not obj.is_way():
            continue
        inside = any(
            n.location.valid() and lon0 <= n.lon <= lon1 and lat0 <= n.lat <= lat1
            for n in obj.nodes
        )
        if inside:
            keep_ways.add(obj.id)
            keep_nodes.update(n.ref for n in obj.nodes)
    target.unlink(missing_ok=True)
    with osmium.SimpleWriter(str(target)) as writer:
        for obj in osmium.FileProcessor(str(source)):
            if (obj.is_node() and obj.id in keep_nodes) or (obj.is_way() and obj.id in keep_ways):
                writer.add(obj)


if __name__ == "__main__":
    src = Path(sys.argv[1])
    here = Path(__file__).parent
    only = sys.argv[2:]  # optional: the names to (re)cut
    for name, box in CROPS.items():
        if only and name not in only:
            continue
        crop(src, here / name, box)
        print(name, (here / name).stat().st_size, "bytes")
