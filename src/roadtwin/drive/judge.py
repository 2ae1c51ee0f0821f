"""Judging one recorded drive against its route.

A route passes when the car

* reached the target (within ``reach_tolerance_m``) and drove at least ``min_on_target_m``
  on the target road (or as far as the route plans there, when that is shorter), measured
  as driven or along the road's reference line (the route's plan: a lane on the inside
  of a tight curve is shorter than its stretch of reference line);
* never jumped: after each step the car is within ``max_jump_m`` of where its own speed
  and heading would have put it (a continuous map gives millimetres; a gap across a link,
  or a lane link to a lane metres away, gives the size of the gap);
* was never on a lane that is not a driving lane, nor on a lane the road does not have;
* never left the roads of the route;
* never stood still (moved less than 0.1 m during ``stuck_s``) before reaching the target.

Each fault names the road, lane, station and time where it first happened.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import DriveConfig
from ..model import RoadNetwork
from .esmini import Recording
from .routes import DRIVABLE, Route, lane_type_at

__all__ = ["Fault", "Judgement", "judge_recording"]


@dataclass(frozen=True)
class Fault:
    """Why a route failed: ``code`` (``jump``, ``non_driving_lane``, ``off_route``,
    ``stuck``, ``not_reached``, ``short_on_target``, ``no_lane_path``, ``esmini``), a
    message, and where (road, lane, station in metres, simulation time in seconds)."""

    code: str
    message: str
    road_id: str | None = None
    lane_id: int | None = None
    s_m: float | None = None
    time_s: float | None = None

    def to_dict(self) -> dict:
        return {
            "code": self.code,
            "message": self.message,
            "road": self.road_id,
            "lane": self.lane_id,
            "s_m": None if self.s_m is None else round(self.s_m, 3),
            "time_s": None if self.time_s is None else round(self.time_s, 3),
        }


@dataclass(frozen=True)
class Judgement:
    """Faults and measured numbers of one drive (metres, seconds)."""

    faults: tuple[Fault, ...]
    driven_m: float
    on_target_m: float
    max_jump_m: float
    max_step_m: float
    sim_time_s: float
    reached: bool


def _where(rec: Recording, i: int) -> str:
    return f"road {rec.road[i]} lane {rec.lane[i]} s={rec.s[i]:.1f} m (t={rec.time[i]:.2f} s)"


def _fault(code: str, message: str, rec: Recording, i: int) -> Fault:
    return Fault(
        code, message, str(rec.road[i]), int(rec.lane[i]), float(rec.s[i]), float(rec.time[i])
    )


def _target_xy(network: RoadNetwork, route: Route) -> np.ndarray:
    """Centre of the target lane at the target station (mapping frame, metres)."""
    t = route.target
    road = network.road(t.road_id)
    inner = t.lane_id + 1 if t.lane_id < 0 else t.lane_id - 1
    s = np.array([t.s_m])
    centre = 0.5 * (road.lane_border_t(s, t.lane_id) + road.lane_border_t(s, inner))
    return road.to_xy(s, centre)[0]


def _jumps(rec: Recording) -> tuple[np.ndarray, np.ndarray]:
    """Step lengths and jumps (metres) between consecutive samples: a jump is the distance
    between the new position and the old one moved by the mean speed along the mean
    heading over the step."""
    dxy = np.column_stack([np.diff(rec.x), np.diff(rec.y)])
    step = np.hypot(dxy[:, 0], dxy[:, 1])
    dt = np.diff(rec.time)
    v = 0.5 * (rec.speed[1:] + rec.speed[:-1])
    h = rec.h[:-1] + 0.5 * (np.angle(np.exp(1j * (rec.h[1:] - rec.h[:-1]))))
    expected = np.column_stack([np.cos(h), np.sin(h)]) * (v * dt)[:, None]
    return step, np.hypot(*(dxy - expected).T)


def judge_recording(
    rec: Recording, route: Route, network: RoadNetwork, *, config: DriveConfig
) -> Judgement:
    """Faults of one recorded drive of ``route`` (see the module docstring)."""
    cfg = config
    faults: list[Fault] = []
    if len(rec) < 2:
        return Judgement(
            (Fault("esmini", "esmini recorded fewer than two states"),),
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            False,
        )
    step, jump = _jumps(rec)
    big = np.nonzero(jump > cfg.max_jump_m)[0]
    if big.size:
        i = int(big[0])
        faults.append(
            _fault(
                "jump",
                f"jump of {jump[i]:.2f} m (step {step[i]:.2f} m) from {_where(rec, i)} to "
                f"{_where(rec, i + 1)}",
                rec,
                i + 1,
            )
        )
    types = np.empty(len(rec), dtype=object)
    for road_id, lane_id in sorted(
        {(r, int(ln)) for r, ln in zip(rec.road, rec.lane, strict=True)}
    ):
        sel = (rec.road == road_id) & (rec.lane == lane_id)
        types[sel] = lane_type_at(network, road_id, lane_id, rec.s[sel])
    bad = np.nonzero([t not in DRIVABLE for t in types])[0]
    if bad.size:
        i = int(bad[0])
        what = "a lane the road does not have" if types[i] == "missing" else f"a {types[i]} lane"
        faults.append(_fault("non_driving_lane", f"on {what}: {_where(rec, i)}", rec, i))
    off = np.nonzero(~np.isin(rec.road, list(route.roads)))[0]
    if off.size:
        i = int(off[0])
        roads = ", ".join(route.roads)
        faults.append(
            _fault("off_route", f"left the route (roads {roads}): {_where(rec, i)}", rec, i)
        )

    ok_step = np.where(jump > cfg.max_jump_m, 0.0, step)
    on_target = (rec.road[1:] == route.target.road_id) & (rec.road[:-1] == route.target.road_id)
    driven_on_target = float(ok_step[on_target].sum())
    # the route plans its distance along the target road's reference line: in a lane on
    # the inside of a curve the car advances further in s than it drives (1 / (1 - k t))
    advanced_on_target = float(np.abs(np.diff(rec.s))[on_target & (jump <= cfg.max_jump_m)].sum())
    goal = _target_xy(network, route)
    dist = np.hypot(rec.x - goal[0], rec.y - goal[1])
    reached = bool(dist.min() <= cfg.reach_tolerance_m + 0.5 * cfg.speed_m_s * cfg.timestep_s)
    cum = np.concatenate([[0.0], np.cumsum(step)])
    later = np.searchsorted(rec.time, rec.time + cfg.stuck_s)
    valid = later < len(rec)
    still = np.nonzero(valid & (cum[np.minimum(later, len(rec) - 1)] - cum < 0.1))[0]
    if still.size and not (reached and still[0] >= int(np.argmin(dist))):
        i = int(still[0])
        faults.append(
            _fault("stuck", f"stood still for {cfg.stuck_s:g} s at {_where(rec, i)}", rec, i)
        )
    if not reached:
        faults.append(
            _fault(
                "not_reached",
                f"never reached the target road {route.target.road_id} lane "
                f"{route.target.lane_id} s={route.target.s_m:.1f} m (closest "
                f"{dist.min():.1f} m); the drive ended on {_where(rec, len(rec) - 1)}",
                rec,
                len(rec) - 1,
            )
        )
    # the car stops within reach_tolerance_m of the target, and the step that enters the
    # target road counts for neither road
    step_m = cfg.speed_m_s * cfg.timestep_s
    needed = min(cfg.min_on_target_m, route.on_target_m) - cfg.reach_tolerance_m - 2.0 * step_m
    if reached and max(driven_on_target, advanced_on_target) < needed:
        faults.append(
            _fault(
                "short_on_target",
                f"drove only {driven_on_target:.1f} m ({advanced_on_target:.1f} m along the "
                f"road) on the target road {route.target.road_id} (needed {needed:.1f} m)",
                rec,
                len(rec) - 1,
            )
        )
    return Judgement(
        tuple(faults),
        float(ok_step.sum()),
        driven_on_target,
        float(jump.max()),
        float(step.max()),
        float(rec.time[-1] - rec.time[0]),
        reached,
    )
