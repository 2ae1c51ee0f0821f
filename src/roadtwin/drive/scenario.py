"""One OpenSCENARIO file per route (scenariogeneration's ``xosc``).

Each scenario has one car and no catalogs: the car is placed on the route's start lane at
the route's speed, gets the route (``AssignRouteAction`` with a waypoint on every road of
the route, the last one on the target road) and the story ends when the car is within
``reach_tolerance_m`` of the target, when it stands still for ``stuck_s``, or after 1.5x
the planned driving time plus 10 s. Any OpenSCENARIO 1.1+ player can run the files; the
map is referenced by a path relative to the scenario.
"""

from __future__ import annotations

import os
from pathlib import Path

from scenariogeneration import xosc

from ..config import DriveConfig
from .routes import LanePoint, Route

__all__ = ["scenario_time_limit_s", "write_scenario"]

EGO = "ego"


def _position(point: LanePoint) -> xosc.LanePosition:
    return xosc.LanePosition(round(point.s_m, 3), 0.0, point.lane_id, point.road_id)


def _car() -> xosc.Vehicle:
    """A mid-size passenger car (metres, radians, m/s, m/s^2)."""
    box = xosc.BoundingBox(1.8, 4.6, 1.5, 1.4, 0.0, 0.75)
    front = xosc.Axle(0.5, 0.65, 1.6, 2.8, 0.33)
    rear = xosc.Axle(0.0, 0.65, 1.6, 0.0, 0.33)
    return xosc.Vehicle("car", xosc.VehicleCategory.car, box, front, rear, 70.0, 10.0, 10.0)


def scenario_time_limit_s(route: Route, *, config: DriveConfig) -> float:
    """Simulated time (seconds) after which the scenario stops: 1.5x the planned driving
    time plus 10 s."""
    return 1.5 * route.length_m / config.speed_m_s + 10.0


def _stop_trigger(route: Route, config: DriveConfig) -> xosc.Trigger:
    stop = xosc.Trigger("stop")
    conditions = [
        xosc.ValueTrigger(
            "time_limit",
            0.0,
            xosc.ConditionEdge.none,
            xosc.SimulationTimeCondition(
                round(scenario_time_limit_s(route, config=config), 2), xosc.Rule.greaterThan
            ),
            "stop",
        ),
        xosc.EntityTrigger(
            "target_reached",
            0.0,
            xosc.ConditionEdge.none,
            xosc.DistanceCondition(
                config.reach_tolerance_m,
                xosc.Rule.lessThan,
                _position(route.target),
                alongroute=False,
                freespace=False,
                distance_type=xosc.RelativeDistanceType.euclidianDistance,
                coordinate_system=xosc.CoordinateSystem.entity,
            ),
            EGO,
            triggeringpoint="stop",
        ),
        xosc.EntityTrigger(
            "standing_still",
            0.0,
            xosc.ConditionEdge.none,
            xosc.StandStillCondition(config.stuck_s),
            EGO,
            triggeringpoint="stop",
        ),
    ]
    for condition in conditions:  # one group each: any of them stops the scenario
        group = xosc.ConditionGroup("stop")
        group.add_condition(condition)
        stop.add_conditiongroup(group)
    return stop


def write_scenario(
    route: Route, map_path: str | os.PathLike, path: str | os.PathLike, *, config: DriveConfig
) -> Path:
    """Write the OpenSCENARIO file of ``route`` on the map ``map_path`` to ``path``.

    Raises
    ------
    ValueError
        The route has no waypoints (it has a ``problem``).
    """
    if len(route.waypoints) < 2:
        msg = f"route {route.name!r} cannot be driven: {route.problem}"
        raise ValueError(msg)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    map_ref = Path(os.path.relpath(Path(map_path).resolve(), path.parent.resolve())).as_posix()

    entities = xosc.Entities()
    entities.add_scenario_object(EGO, _car())
    init = xosc.Init()
    init.add_init_action(EGO, xosc.TeleportAction(_position(route.start)))
    init.add_init_action(
        EGO,
        xosc.AbsoluteSpeedAction(
            config.speed_m_s,
            xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0.0),
        ),
    )
    osc_route = xosc.Route(route.name)
    for point in route.waypoints:
        osc_route.add_waypoint(_position(point), xosc.RouteStrategy.shortest)
    init.add_init_action(EGO, xosc.AssignRouteAction(osc_route))

    storyboard = xosc.StoryBoard(init, _stop_trigger(route, config))
    scenario = xosc.Scenario(
        f"roadtwin drive: {route.name}",
        "roadtwin",
        xosc.ParameterDeclarations(),
        entities,
        storyboard,
        xosc.RoadNetwork(roadfile=map_ref),
        xosc.Catalog(),
    )
    tmp = path.with_name(f".{path.name}.tmp")
    scenario.write_xml(str(tmp))
    _strip_date(tmp)
    tmp.replace(path)
    return path


def _strip_date(path: Path) -> None:
    """Same route, same bytes: drop the write time scenariogeneration puts in the header."""
    import re

    text = path.read_text(encoding="utf-8")
    text = re.sub(r'date="[^"]*"', 'date="2000-01-01T00:00:00"', text, count=1)
    path.write_text(text, encoding="utf-8")
