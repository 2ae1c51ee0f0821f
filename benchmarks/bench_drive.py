"""Drive benchmark: ``roadtwin drive`` on the bundled scenarios' maps and on other tools' maps.

Run: ``python benchmarks/bench_drive.py [MAP ...] [--workdir DIR] [--esmini DIR] [--json FILE]``.
A MAP is a bundled scenario name (simulated with its seed and built with the default method
into ``--workdir``, cached) or an ``.xodr`` file. Without MAP: every bundled scenario, the
two esmini samples in ``tests/data/xodr`` and CARLA's Town06 from ``../shared/data/xodr``
when it is there. esmini is found as ``roadtwin drive`` finds it (``--esmini``,
``ESMINI_BIN``, ``PATH``).

Per map: routes by kind, passed / failed, esmini's distinct warnings, the drive's wall time
and CPU time (this process + the esmini and dat2csv child processes), then every fault.
Results: ``benchmarks/RESULTS.md``, section "Drive".
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import sys
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
FOREIGN = (
    ROOT / "tests/data/xodr/e6mini.xodr",
    ROOT / "tests/data/xodr/soderleden.xodr",
    ROOT.parent / "shared/data/xodr/Town06.xodr",
)


def _built_map(name: str, workdir: Path) -> Path:
    """Simulate and build a bundled scenario (cached in ``workdir/name``)."""
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map
    from roadtwin.simulate import simulate_run
    from roadtwin.xodr import write_xodr

    path = workdir / name / "map.xodr"
    if path.is_file():
        return path
    run_dir = simulate_run(name, workdir / name / "run")
    run = load_run(run_dir)
    osm = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
    return write_xodr(build_map(run, osm).network, path)


def _cpu(who: int) -> float:
    r = resource.getrusage(who)
    return r.ru_utime + r.ru_stime


def main(argv: list[str] | None = None) -> int:
    from roadtwin.drive import drive_map, find_esmini
    from roadtwin.simulate import bundled_scenarios

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("maps", nargs="*", help="bundled scenario names or .xodr files")
    p.add_argument("--workdir", type=Path, default=Path("/tmp/roadtwin-bench-drive"))
    p.add_argument("--esmini", type=Path, default=None)
    p.add_argument("--json", type=Path, default=None)
    args = p.parse_args(argv)
    tools = find_esmini(args.esmini)
    if tools is None:
        print("esmini not found (--esmini DIR, ESMINI_BIN or PATH)", file=sys.stderr)
        return 2
    maps = args.maps or [*bundled_scenarios(), *(str(f) for f in FOREIGN if f.is_file())]
    print(f"esmini: {tools.version}; {platform.node()} {platform.processor() or ''}".strip())
    print(
        f"python {platform.python_version()}, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}"
    )
    head = "| map | routes (kinds) | passed | failed | esmini warnings | wall s | CPU s |"
    print(head)
    print("|---|---|---:|---:|---|---:|---:|")
    rows, details = [], []
    for name in maps:
        path = Path(name) if name.endswith(".xodr") else _built_map(name, args.workdir)
        label = path.stem if name.endswith(".xodr") else name
        cpu0 = _cpu(resource.RUSAGE_SELF) + _cpu(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        report = drive_map(path, args.workdir / "drive" / label, esmini=tools)
        wall = time.perf_counter() - t0
        cpu = _cpu(resource.RUSAGE_SELF) + _cpu(resource.RUSAGE_CHILDREN) - cpu0
        kinds = Counter(r.route.kind for r in report.results)
        kind_text = ", ".join(f"{k} {n}" for k, n in kinds.items())
        warns = "; ".join(f"{m} ({n})" for m, n in report.warnings.items()) or "none"
        row = {
            "map": label,
            "routes": len(report.results),
            "kinds": dict(kinds),
            "passed": report.count("passed"),
            "failed": report.count("failed"),
            "esmini_warnings": report.warnings,
            "wall_s": round(wall, 2),
            "cpu_s": round(cpu, 2),
        }
        rows.append(row)
        print(
            f"| {label} | {len(report.results)} ({kind_text}) | {row['passed']} | "
            f"{row['failed']} | {warns} | {wall:.1f} | {cpu:.1f} |",
            flush=True,
        )
        details += [
            f"{label}: {r.route.name}: {f.code}: {f.message}"
            for r in report.results
            for f in r.faults
        ]
    if details:
        print("\nfaults:")
        print("\n".join(details))
    if args.json is not None:
        args.json.write_text(json.dumps(rows, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
