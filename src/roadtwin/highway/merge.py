"""Several road networks -> one: ids renumbered, every road tagged with its carriageway.

Each carriageway is built on its own (mainline roads ``"1", "2", ...``, ramps, connecting
roads, junctions, each numbered from 1). Merging them renumbers every road and junction
of a part with fresh numbers (one counter for both, so ids stay unique across the two
kinds as every stage assumes) and rewrites every reference: road links, a connecting
road's junction, junction connections. Lane links name lane ids and stay as they are.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

from ..model import Connection, Junction, Road, RoadLink

__all__ = ["NetworkPart", "merge_parts"]

CARRIAGEWAY_CODE = "roadtwin:carriageway"
"""Road ``<userData>``: the carriageway (1, 2, ...) a road belongs to."""
SOURCE_CODE = "roadtwin:source"
"""Road ``<userData>``: ``lidar`` (built from runs) or ``osm`` (from OSM alone)."""


@dataclass(frozen=True)
class NetworkPart:
    """Roads and junctions of one carriageway (ids unique within the part).

    ``carriageway`` is its number (1, 2, ...), ``source`` ``"lidar"`` or ``"osm"``."""

    roads: tuple[Road, ...]
    junctions: tuple[Junction, ...]
    carriageway: int
    source: str


def _link(link: RoadLink | None, roads: dict[str, str], junctions: dict[str, str]):
    if link is None:
        return None
    table = roads if link.element_type == "road" else junctions
    return replace(link, element_id=table.get(link.element_id, link.element_id))


def merge_parts(
    parts: Sequence[NetworkPart], *, first_id: int = 1
) -> tuple[tuple[Road, ...], tuple[Junction, ...], list[dict[str, str]]]:
    """Merge parts into one set of roads and junctions with unique numeric ids (the first
    part keeps its own numeric ids; the others are numbered on after them, in order).

    Returns
    -------
    roads, junctions, id_maps
        ``id_maps[k]`` maps part ``k``'s old road ids to the new ones.
    """
    next_id = first_id
    roads_out: list[Road] = []
    junctions_out: list[Junction] = []
    maps: list[dict[str, str]] = []
    for k, part in enumerate(parts):
        road_map: dict[str, str] = {}
        junction_map: dict[str, str] = {}
        ids = [r.id for r in part.roads] + [j.id for j in part.junctions]
        if k == 0 and all(i.isdigit() for i in ids) and len(set(ids)) == len(ids):
            # the first part keeps its ids: a map of one carriageway is the single-run map
            road_map = {r.id: r.id for r in part.roads}
            junction_map = {j.id: j.id for j in part.junctions}
            next_id = max([first_id - 1, *(int(i) for i in ids)]) + 1
        else:
            for road in part.roads:
                road_map[road.id] = str(next_id)
                next_id += 1
            for junction in part.junctions:
                junction_map[junction.id] = str(next_id)
                next_id += 1
        tags = ((CARRIAGEWAY_CODE, str(part.carriageway)), (SOURCE_CODE, part.source))
        for road in part.roads:
            own = tuple((c, v) for c, v in road.user_data if c not in dict(tags))
            roads_out.append(
                replace(
                    road,
                    id=road_map[road.id],
                    predecessor=_link(road.predecessor, road_map, junction_map),
                    successor=_link(road.successor, road_map, junction_map),
                    junction=junction_map.get(road.junction, road.junction),
                    user_data=(*tags, *own),
                )
            )
        for junction in part.junctions:
            junctions_out.append(
                replace(
                    junction,
                    id=junction_map[junction.id],
                    connections=tuple(
                        Connection(
                            c.id,
                            road_map.get(c.incoming_road, c.incoming_road),
                            road_map.get(c.connecting_road, c.connecting_road),
                            c.contact_point,
                            c.lane_links,
                        )
                        for c in junction.connections
                    ),
                )
            )
        maps.append(road_map)
    return tuple(roads_out), tuple(junctions_out), maps


def carriageway_of(road: Road) -> int | None:
    """The carriageway number a merged road carries (None if untagged)."""
    value = dict(road.user_data).get(CARRIAGEWAY_CODE)
    return int(value) if value is not None and value.isdigit() else None
