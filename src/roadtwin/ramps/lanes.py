"""Algorithm 2 of the paper: the lane count of an OSM link from its tags."""

from __future__ import annotations

import math
from typing import Any, Literal

# ---------------------------------------------------------------------------
# Algorithm 2: lane count from tags
# ---------------------------------------------------------------------------


def _first_value(value: Any) -> Any:
    if isinstance(value, (list, tuple)):
        return value[0] if value else None
    return value


def _parse_int(value: Any) -> int | None:
    value = _first_value(value)
    if value is None:
        return None
    if isinstance(value, float) and not math.isfinite(value):
        return None
    try:
        n = int(str(value).split(";")[0].strip())
    except ValueError:
        return None
    return n if n > 0 else None


def infer_lane_count(
    tags: dict[str, Any], *, link_rule: Literal["osm", "paper"] = "osm"
) -> tuple[int, str]:
    """Lane count of one OSM edge by the paper's Algorithm 2, and the rule that decided.

    Priority: ``lanes:forward`` > ``lanes`` > ``turn:lanes`` (number of ``|`` + 1) >
    highway class. The class default follows OSM's own convention with ``link_rule="osm"``
    (the default method): a ``*_link`` way without lane tags is 1 lane (the OSM wiki's
    ``lanes`` default for link roads; the paper's class default built real one-lane ramps
    3 lanes wide); ``motorway`` 3, ``trunk``/``primary`` 2, else 1. ``link_rule="paper"``
    is the paper's Algorithm 2 as written (``motorway*`` 3, ``trunk*``/``primary*`` 2, else
    1, links included).

    Parameters
    ----------
    tags
        OSM edge attributes (values may be strings, numbers or lists, as OSMnx gives them).
    link_rule
        ``"osm"`` or ``"paper"``: the class default for ``*_link`` ways (see above).

    Returns
    -------
    (lanes, rule)
        ``rule`` is one of ``"lanes:forward"``, ``"lanes"``, ``"turn:lanes"``,
        ``"highway class"``.
    """
    forward = _parse_int(tags.get("lanes:forward"))
    if forward is not None:
        return forward, "lanes:forward"
    lanes = _parse_int(tags.get("lanes"))
    if lanes is not None:
        return lanes, "lanes"
    turn = _first_value(tags.get("turn:lanes"))
    if isinstance(turn, str) and turn != "":
        return turn.count("|") + 1, "turn:lanes"
    highway = tags.get("highway", "")
    highway = " ".join(highway) if isinstance(highway, (list, tuple)) else str(highway)
    if link_rule == "osm" and "_link" in highway:
        return 1, "highway class"
    if "motorway" in highway:
        return 3, "highway class"
    if "trunk" in highway or "primary" in highway:
        return 2, "highway class"
    return 1, "highway class"
