"""Evaluation results: one run's evaluation, the report over runs and methods, the seed
paper's Table 4."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .frenet import FloatArray
from .metrics import PointErrors


@dataclass(frozen=True)
class RunEvaluation:
    """Evaluation of one map against one run (and its truth, if any).

    Attributes
    ----------
    label : display name (run folder name, plus the method where several are compared).
    run_dir : run folder.
    map_name : name of the map file (or ``""``).
    method : mainline method that built the map (``"default"``, ``"paper"`` or ``""``).
    self_consistency : see :func:`self_consistency`.
    truth : accuracy against truth (``None`` without truth): ``road_edge``,
        ``lane_boundary``, ``elevation``, ``ramp_centre``, ``ramp_boundary`` (each
        :func:`error_stats`), ``lane_count``, coverage.
    topology : :func:`topology_against_truth` (``None`` without truth), or the built map's
        ramp connectivity alone under ``{"ramps": [...]}``.
    details : per-point errors for plots (not serialised).
    map_lines : reconstructed boundary polylines for the map plot (not serialised).
    """

    label: str
    run_dir: str
    map_name: str
    method: str
    self_consistency: dict[str, float]
    truth: dict[str, Any] | None = None
    topology: dict[str, Any] | None = None
    details: dict[str, PointErrors] = field(default_factory=dict, repr=False, compare=False)
    map_lines: tuple[FloatArray, ...] = field(default=(), repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (NaN -> ``None``)."""
        return _json_clean(
            {
                "label": self.label,
                "run_dir": self.run_dir,
                "map": self.map_name,
                "method": self.method,
                "self_consistency": self.self_consistency,
                "truth": self.truth,
                "topology": self.topology,
            }
        )


TABLE_TARGETS = (
    ("road_edge", "Road edge"),
    ("lane_boundary", "Lane boundary"),
    ("overall", "Overall"),
)


@dataclass(frozen=True)
class EvaluationReport:
    """Evaluations of one or several runs (and methods); see :func:`evaluate`."""

    runs: tuple[RunEvaluation, ...]

    def table(self) -> dict[str, dict[str, dict[str, float | int | None]]]:
        """The seed paper's Table 4 per method: ``{method: {target: stats}}``.

        Targets ``road_edge``, ``lane_boundary``, ``overall``; stats ``runs``,
        ``mean_rmse_m``, ``median_rmse_m``, ``min_rmse_m``, ``max_rmse_m`` over the runs'
        self-consistency RMSE (``self_consistency[f"{target}_rmse_m"]``). The method key
        is ``"map"`` where the method is unknown.
        """
        out: dict[str, dict[str, dict[str, float | int | None]]] = {}
        methods = list(dict.fromkeys(r.method or "map" for r in self.runs))
        for m in methods:
            out[m] = {}
            for key, _ in TABLE_TARGETS:
                vals = np.array(
                    [
                        r.self_consistency.get(f"{key}_rmse_m", math.nan)
                        for r in self.runs
                        if (r.method or "map") == m
                    ],
                    dtype=float,
                )
                vals = vals[np.isfinite(vals)]
                out[m][key] = {
                    "runs": int(vals.size),
                    "mean_rmse_m": float(np.mean(vals)) if vals.size else None,
                    "median_rmse_m": float(np.median(vals)) if vals.size else None,
                    "min_rmse_m": float(np.min(vals)) if vals.size else None,
                    "max_rmse_m": float(np.max(vals)) if vals.size else None,
                }
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ``report.json`` document (schema documented in the README)."""
        return _json_clean(
            {
                "schema": "roadtwin-evaluation/1",
                "runs": [r.to_dict() for r in self.runs],
                "table": self.table(),
            }
        )


def combine_reports(reports: Iterable[EvaluationReport]) -> EvaluationReport:
    """One report holding the runs of several (for multi-run and multi-method tables)."""
    return EvaluationReport(tuple(r for rep in reports for r in rep.runs))


def format_table(report: EvaluationReport) -> str:
    """The seed paper's Table 4 layout as plain text, one block per method."""
    lines = []
    for method, targets in report.table().items():
        n = max(v["runs"] or 0 for v in targets.values())
        lines.append(f"Self-consistency ({method}, {n} run{'s' if n != 1 else ''})")
        lines.append(f"{'Target':<15}{'Mean RMSE (m)':>15}{'Median RMSE (m)':>17}{'Range (m)':>17}")
        for key, title in TABLE_TARGETS:
            st = targets[key]
            if st["runs"]:
                rng = f"{st['min_rmse_m']:.3f}-{st['max_rmse_m']:.3f}"
                lines.append(
                    f"{title:<15}{st['mean_rmse_m']:>15.3f}{st['median_rmse_m']:>17.3f}{rng:>17}"
                )
            else:
                lines.append(f"{title:<15}{'-':>15}{'-':>17}{'-':>17}")
    return "\n".join(lines)


def _json_clean(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _json_clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_json_clean(v) for v in obj]
    if isinstance(obj, bool | np.bool_):
        return bool(obj)
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj
