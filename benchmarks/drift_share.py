"""How much of a batch's lateral error against truth is a slow common offset (pose drift).

For every built run of a ``bench_real.py`` work directory (``RUN/default/map.xodr`` beside
``RUN/run``): the lateral errors of the road edges and of the lane boundaries against truth
(:func:`roadtwin.evaluation.evaluate_paths`), their mean over the boundaries at each metre
of station (the offset all borders share there), smoothed over 101 m (what a drifting pose
moves: the whole cross-section, slowly). Printed per kind: the median RMSE, the median RMS
of that slow common offset, the median share of the squared error it carries and the
median RMSE left without it.

A mapping car's pose drift moves everything it measures together; a build from one run
cannot take it out (OSM is metres off), so a batch whose error is mostly this share is at
the floor its poses set.

Usage: ``python benchmarks/drift_share.py WORKDIR [--json OUT]``
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

import numpy as np
from scipy.ndimage import uniform_filter1d

from roadtwin.evaluation import evaluate_paths

WINDOW_M = 101
"""Stations (metres, one per metre) over which the common offset is averaged."""


def drift_share(run_root: Path) -> dict[str, tuple[float, float]]:
    """``{kind: (rmse_m, slow_common_rms_m)}`` of one built run folder (metres)."""
    rep = evaluate_paths(run_root / "default" / "map.xodr", [run_root / "run"]).runs[0]
    out = {}
    for kind in ("road_edge", "lane_boundary"):
        d = rep.details["truth/" + kind]
        ok = np.isfinite(d.error_m)
        err = d.error_m[ok]
        _, inv = np.unique(np.round(d.station_m[ok]).astype(int), return_inverse=True)
        common = np.bincount(inv, err) / np.bincount(inv)
        slow = uniform_filter1d(common, WINDOW_M)
        out[kind] = (float(np.sqrt(np.mean(err**2))), float(np.sqrt(np.mean(slow[inv] ** 2))))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("workdir", type=Path, help="a bench_real.py --workdir")
    ap.add_argument("--json", type=Path, help="write the per-run figures here")
    args = ap.parse_args(argv)
    logging.disable(logging.WARNING)
    runs = sorted(p for p in args.workdir.iterdir() if (p / "default" / "map.xodr").exists())
    rows = {p.name: drift_share(p) for p in runs}
    print(f"{len(rows)} runs of {args.workdir}")
    for kind in ("road_edge", "lane_boundary"):
        rmse = np.array([r[kind][0] for r in rows.values()])
        slow = np.array([r[kind][1] for r in rows.values()])
        share = slow**2 / np.maximum(rmse**2, 1e-12)
        rest = np.sqrt(np.maximum(rmse**2 - slow**2, 0.0))
        print(
            f"{kind}: RMSE median {np.median(rmse):.3f} m, slow common offset median "
            f"{np.median(slow):.3f} m ({100 * np.median(share):.0f} % of the squared error), "
            f"without it {np.median(rest):.3f} m"
        )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
