"""One-off script that cut ``town06-35-38.xodr.gz`` from CARLA's Town06.xodr (3 MB).

Keeps, unchanged (elements copied as they are), the header, the roads of one route, every
connecting road of the junctions on it, the roads its ramps are built from
(``roadtwin.simulate`` follows them up to 300 m or their next junction), and those
junctions with the connections whose roads are kept. Links to roads or junctions that
were left out stay in the file (they dangle; the route does not use them).
Run: ``python tests/data/xodr/crop_xodr.py /work/shared/data/xodr/Town06.xodr``
"""

from __future__ import annotations

import gzip
import sys
from pathlib import Path

from lxml import etree

from roadtwin.frames import MappingFrame, Origin
from roadtwin.simulate.route import route_from_ids
from roadtwin.simulate.route_truth import build_route_truth
from roadtwin.xodr import read_xodr

ROUTE = ["35", "36", "37", "38"]
TARGET = Path(__file__).with_name("town06-35-38.xodr.gz")


def kept_ids(source: Path) -> tuple[set[str], set[str]]:
    network = read_xodr(source)
    route = route_from_ids(network, ROUTE)
    truth = build_route_truth(network, route, frame=MappingFrame(Origin(0.0, 0.0)))
    junctions = {p.junction_id for p in route.passages if p.junction_id}
    roads = set(route.road_ids)
    for jid in junctions:
        for con in network.id_to_junction[jid].connections:
            roads |= {con.incoming_road, con.connecting_road}
    for ramp in truth.ramps:
        roads |= set(ramp.source_roads)
    return roads, junctions


def main(source: Path) -> None:
    roads, junctions = kept_ids(source)
    root = etree.parse(str(source)).getroot()
    for el in list(root):
        if el.tag == "road" and el.get("id") not in roads:
            root.remove(el)
        elif el.tag == "junction":
            if el.get("id") not in junctions:
                root.remove(el)
                continue
            for con in el.findall("connection"):
                if con.get("incomingRoad") not in roads or con.get("connectingRoad") not in roads:
                    el.remove(con)
    root.insert(
        1,
        etree.Comment(
            f" Cropped from CARLA Town06.xodr (MIT, via the Scenic repository) by "
            f"tests/data/xodr/crop_xodr.py: route {','.join(ROUTE)}, {len(roads)} roads, "
            f"{len(junctions)} junctions "
        ),
    )
    data = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    TARGET.write_bytes(gzip.compress(data, mtime=0))
    print(
        f"{TARGET.name}: {len(roads)} roads, {len(junctions)} junctions, {TARGET.stat().st_size} B"
    )


if __name__ == "__main__":
    main(Path(sys.argv[1]))
