"""Results of a drive: one line per route, ``drive.json`` (schema ``roadtwin-drive/1``)."""

from __future__ import annotations

import json
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from ..config import DriveConfig
from .esmini import Esmini
from .judge import Fault, Judgement
from .routes import Route

__all__ = ["DriveReport", "RouteResult", "write_drive_json"]

SCHEMA = "roadtwin-drive/1"


@dataclass(frozen=True)
class RouteResult:
    """One route: ``passed``, ``failed`` or ``not run`` (no esmini), its faults, the
    measured numbers (None when not run), esmini's warnings and errors, the scenario file
    and the wall time of its esmini run (seconds)."""

    route: Route
    status: Literal["passed", "failed", "not run"]
    faults: tuple[Fault, ...] = ()
    judgement: Judgement | None = None
    messages: tuple[str, ...] = ()
    scenario: Path | None = None
    wall_s: float = 0.0

    def to_dict(self) -> dict:
        r, j = self.route, self.judgement
        return {
            "name": r.name,
            "kind": r.kind,
            "status": self.status,
            "roads": list(r.roads),
            "waypoints": [
                {"road": p.road_id, "lane": p.lane_id, "s_m": round(p.s_m, 3)} for p in r.waypoints
            ],
            "planned_m": round(r.length_m, 3),
            "planned_on_target_m": round(r.on_target_m, 3),
            "driven_m": None if j is None else round(j.driven_m, 3),
            "on_target_m": None if j is None else round(j.on_target_m, 3),
            "max_jump_m": None if j is None else round(j.max_jump_m, 4),
            "max_step_m": None if j is None else round(j.max_step_m, 4),
            "sim_time_s": None if j is None else round(j.sim_time_s, 3),
            "faults": [f.to_dict() for f in self.faults],
            "esmini_messages": list(self.messages),
            "scenario": None if self.scenario is None else self.scenario.name,
            "wall_s": round(self.wall_s, 3),
        }


@dataclass(frozen=True)
class DriveReport:
    """Every route of one map and how its drive went."""

    map_path: str
    results: tuple[RouteResult, ...]
    config: DriveConfig
    esmini: Esmini | None
    scenario_dir: Path
    wall_s: float

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.results)

    @property
    def ok(self) -> bool:
        """esmini ran and every route passed."""
        return self.esmini is not None and all(r.status == "passed" for r in self.results)

    @property
    def warnings(self) -> dict[str, int]:
        """esmini's warnings and errors over all routes: message -> routes that logged it."""
        return dict(Counter(m for r in self.results for m in dict.fromkeys(r.messages)))

    def to_dict(self) -> dict:
        return {
            "schema": SCHEMA,
            "map": self.map_path,
            "esmini": None
            if self.esmini is None
            else {"path": str(self.esmini.esmini), "version": self.esmini.version},
            "ok": self.ok,
            "routes_total": len(self.results),
            "passed": self.count("passed"),
            "failed": self.count("failed"),
            "not_run": self.count("not run"),
            "speed_m_s": self.config.speed_m_s,
            "timestep_s": self.config.timestep_s,
            "esmini_warnings": self.warnings,
            "wall_s": round(self.wall_s, 3),
            "routes": [r.to_dict() for r in self.results],
        }

    def summary(self) -> str:
        """One line: routes, passed/failed, esmini warnings, time."""
        n = len(self.results)
        if self.esmini is None:
            failed = self.count("failed")
            extra = f", {failed} without a lane path" if failed else ""
            return f"{n} routes, not driven: esmini not found{extra}"
        warn = len(self.warnings)
        return (
            f"{n} routes: {self.count('passed')} passed, {self.count('failed')} failed; "
            f"esmini {str(warn) + ' distinct warnings' if warn else 'logged no warning'}"
        )

    def format_text(self) -> str:
        """The table printed by ``roadtwin drive``, faults under their route."""
        lines = [
            f"{'route':<44} {'roads':<22} {'result':<8} {'driven':>8} {'on target':>9} "
            f"{'max jump':>9}"
        ]
        for r in self.results:
            roads = " ".join(r.route.roads)
            roads = roads if len(roads) <= 22 else roads[:19] + "..."
            j = r.judgement
            nums = (
                f"{j.driven_m:7.0f}m {j.on_target_m:8.0f}m {j.max_jump_m:8.3f}m"
                if j is not None
                else f"{'-':>8} {'-':>9} {'-':>9}"
            )
            status = "FAILED" if r.status == "failed" else r.status
            lines.append(f"{r.route.name[:44]:<44} {roads:<22} {status:<8} {nums}")
            lines += [f"    {f.code}: {f.message}" for f in r.faults]
        for message, routes in self.warnings.items():
            lines.append(f"esmini {message} ({routes} route(s))")
        lines.append(f"drive: {self.summary()} ({self.wall_s:.1f} s)")
        return "\n".join(lines)


def write_drive_json(report: DriveReport, path: str | os.PathLike) -> Path:
    """Write ``report`` as JSON (atomically)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(report.to_dict(), indent=2) + "\n", encoding="utf-8")
    tmp.replace(path)
    return path
