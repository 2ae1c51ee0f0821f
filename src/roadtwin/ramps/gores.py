"""Measured gores: where a mainline lane ends or begins wide enough to be a ramp's gore,
and the mainline lane/shoulder borders a ramp attaches to.

Stations in metres along the mainline road; lateral offsets ``t`` in metres, left positive.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from .._errors import FitError
from ..model import Lane, LaneSection, Road
from .records import (
    _MIN_GORE_WIDTH_M,
    _MIN_LINK_WIDTH_M,
    FloatArray,
    GoreEvent,
    RampType,
    TrafficSide,
)

# ---------------------------------------------------------------------------
# measured gores
# ---------------------------------------------------------------------------


def _traffic_lanes(section: LaneSection, traffic_side: TrafficSide) -> tuple[Lane, ...]:
    return section.right if traffic_side == "right" else section.left


def _driving(lanes: tuple[Lane, ...]) -> list[Lane]:
    return [lane for lane in lanes if lane.type == "driving"]


def gore_events(road: Road, *, traffic_side: TrafficSide = "right") -> tuple[GoreEvent, ...]:
    """Gores the LiDAR saw: driving lanes that end or start at full width.

    Scans the mainline's lane sections (DESIGN.md lane layout: deceleration and
    acceleration lanes are the outermost driving lanes of their sections). Where the
    driving-lane count drops and the ending lanes are wider than 1 m at the boundary,
    lanes leave through an exit; where it rises with lanes starting wider than 1 m,
    lanes enter from a merge (the paper's lane-count-change rule). Tapers (width from or
    to zero) are not gores.
    """
    out: list[GoreEvent] = []
    sections = road.lane_sections
    for prev, nxt in itertools.pairwise(sections):
        dp = _driving(_traffic_lanes(prev, traffic_side))
        dn = _driving(_traffic_lanes(nxt, traffic_side))
        s_b = nxt.s0
        if len(dp) > len(dn) and dn:
            k = len(dp) - len(dn)
            ending = dp[-k:]
            widths = [float(lane.width.value(s_b - prev.s0)) for lane in ending]
            if min(widths) > _MIN_GORE_WIDTH_M:
                out.append(GoreEvent(s_b, "exit", tuple(x.id for x in ending), dp[-k - 1].id))
        elif len(dn) > len(dp) and dp:
            k = len(dn) - len(dp)
            starting = dn[-k:]
            widths = [float(lane.width.value(0.0)) for lane in starting]
            if min(widths) > _MIN_GORE_WIDTH_M:
                out.append(GoreEvent(s_b, "entry", tuple(x.id for x in starting), dn[-k - 1].id))
    return tuple(out)


def gores_from_lane_events(
    lane_events, road: Road, *, traffic_side: TrafficSide = "right", max_taper_m: float = 1.0
) -> tuple[GoreEvent, ...]:
    """Measured gores from the mainline stage's lane events.

    A lane that ends without a taper (``kind="end"``, ``taper_m`` below ``max_taper_m``)
    ends at an exit gore; one that is born without a taper starts at an entry gore.
    Events at the same station and kind are one gore with several lanes.

    Parameters
    ----------
    lane_events
        :class:`roadtwin.mainline.LaneEvent` records (``s_m``, ``kind``, ``lane_id``,
        ``taper_m``).
    road
        The mainline road they refer to.
    """
    groups: dict[tuple[float, str], list[int]] = {}
    for ev in lane_events:
        if ev.taper_m > max_taper_m:
            continue
        kind = "exit" if ev.kind == "end" else "entry"
        groups.setdefault((round(float(ev.s_m), 6), kind), []).append(int(ev.lane_id))
    out = []
    for (s, kind), ids in sorted(groups.items()):
        ids = sorted(ids, key=abs)
        s_sec = s - 1e-6 if kind == "exit" else s + 1e-6
        section = road.lane_sections[int(road.section_index(np.array([s_sec]))[0])]
        inner = [
            lane.id
            for lane in _driving(_traffic_lanes(section, traffic_side))
            if abs(lane.id) < abs(ids[0])
        ]
        if not inner:
            continue
        out.append(GoreEvent(s, kind, tuple(ids), inner[-1]))  # type: ignore[arg-type]
    return tuple(out)


def outer_driving_lane(road: Road, s: float, *, traffic_side: TrafficSide = "right") -> int:
    """Id of the outermost driving lane of the section containing station ``s``."""
    section = road.lane_sections[int(road.section_index(np.array([s]))[0])]
    driving = _driving(_traffic_lanes(section, traffic_side))
    if not driving:
        msg = f"mainline road {road.id}: no driving lane at s={s:.1f} m"
        raise FitError(msg)
    return driving[-1].id


def _outer_shoulder(
    road: Road,
    station: float,
    ramp_type: RampType,
    source_lane_ids: tuple[int, ...],
    traffic_side: TrafficSide,
) -> int | None:
    """The mainline hard shoulder just outside the gore's ending (exit) / starting (entry)
    lanes, or ``None``."""
    s = station - 1e-6 if ramp_type == "exit" else station + 1e-6
    section = road.lane_sections[int(road.section_index(np.array([s]))[0])]
    lanes_ = _traffic_lanes(section, traffic_side)
    ids = [lane.id for lane in lanes_]
    if not source_lane_ids or source_lane_ids[-1] not in ids:
        return None
    k = ids.index(source_lane_ids[-1])
    if k + 1 < len(lanes_) and lanes_[k + 1].type == "shoulder":
        lane_id = lanes_[k + 1].id
        s_arr = np.array([s])
        w = abs(
            float(road.lane_border_t(s_arr, lane_id)[0])
            - float(road.lane_border_t(s_arr, lane_id + (1 if lane_id < 0 else -1))[0])
        )
        # a shoulder of (near) zero width at the gore is opening/closing there: no link
        return lane_id if math.isfinite(w) and w > _MIN_LINK_WIDTH_M else None
    return None


def _outer_border_t(road: Road, s: FloatArray, traffic_side: TrafficSide) -> FloatArray:
    """Lateral offset of the outer border of the outermost driving lane at each station."""
    out = np.full(s.shape, np.nan)
    idx = road.section_index(s)
    for k in np.unique(idx):
        sel = idx == k
        driving = _driving(_traffic_lanes(road.lane_sections[int(k)], traffic_side))
        if driving:
            out[sel] = road.lane_border_t(s[sel], driving[-1].id)
    return out
