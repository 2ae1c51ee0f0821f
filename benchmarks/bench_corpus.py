"""Run the broken-input corpus (``tests/corpus.py``) through the real console script.

Every case runs as its own ``roadtwin`` process with a fresh TMPDIR and a time limit, and
is judged against the corpus contract (exit code, one error line naming the file, no
traceback, no leftover or partial file, no clobbered input, no leaked secret). Prints one
line per failing case and a count per kind of problem; ``--json FILE`` writes them all.

    python benchmarks/corpus.py [--timeout 120] [--only SUBSTRING] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import corpus


def _limit_file_size() -> None:
    # a disk that fills up: any write past 2 MB fails with EFBIG (Python ignores SIGXFSZ)
    resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))


def run_case(case: corpus.Case, base_run: Path, base_map: Path, work: Path, timeout: float):
    d = corpus.prepare(case, base_run, base_map, work / "case")
    tmp = work / "tmp"
    tmp.mkdir()
    was = corpus.before(d)
    exe = Path(sys.executable).parent / "roadtwin"
    env = {**os.environ, "TMPDIR": str(tmp), "PYTHONWARNINGS": ""}
    preexec = _limit_file_size if "fsize" in case.tags else None
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            [str(exe), *case.argv(d)],
            capture_output=True,
            text=True,
            timeout=timeout,
            env=env,
            preexec_fn=preexec,
            check=False,
        )
        outcome = corpus.Outcome(
            proc.returncode, proc.stdout, proc.stderr, time.perf_counter() - t0
        )
    except subprocess.TimeoutExpired as exc:
        outcome = corpus.Outcome(
            None,
            (exc.stdout or b"").decode(errors="replace")
            if isinstance(exc.stdout, bytes)
            else exc.stdout or "",
            (exc.stderr or b"").decode(errors="replace")
            if isinstance(exc.stderr, bytes)
            else exc.stderr or "",
            timeout,
            hung=True,
        )
    problems = corpus.judge(case, d, outcome, was, tmp)
    return outcome, problems


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timeout", type=float, default=120.0)
    parser.add_argument("--only", default="")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--keep", type=Path, default=None, help="keep case folders here")
    args = parser.parse_args()
    base = Path(tempfile.mkdtemp(prefix="roadtwin-corpus-"))
    base_run, base_map = corpus.make_base(base / "base")
    cases = [c for c in corpus.all_cases() if args.only in c.name]
    if os.geteuid() == 0:
        cases = [c for c in cases if "nonroot" not in c.tags]
    counts: Counter[str] = Counter()
    rows = []
    started = time.perf_counter()
    for i, case in enumerate(cases):
        work = base / f"{i:03d}"
        work.mkdir()
        outcome, problems = run_case(case, base_run, base_map, work, args.timeout)
        counts.update(problems.keys())
        rows.append(
            {
                "case": case.name,
                "exit": outcome.exit_code,
                "seconds": round(outcome.seconds, 2),
                "problems": problems,
                "stderr_tail": outcome.stderr.strip().splitlines()[-3:],
            }
        )
        if problems:
            print(f"{case.name}: " + "; ".join(f"{k}: {v}" for k, v in problems.items()))
            sys.stdout.flush()
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)
    bad = sum(1 for r in rows if r["problems"])
    print(
        f"\n{len(cases)} cases, {bad} with problems, {time.perf_counter() - started:.0f} s; "
        + ", ".join(f"{k} {counts.get(k, 0)}" for k in corpus.PROBLEMS)
    )
    if args.json:
        args.json.write_text(json.dumps({"counts": counts, "rows": rows}, indent=1))
    if args.keep is not None:
        shutil.copytree(base, args.keep, dirs_exist_ok=True)
    shutil.rmtree(base, ignore_errors=True)
    return 0 if bad == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
