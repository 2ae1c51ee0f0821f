"""The broken-input corpus (``tests/corpus.py``) as tests: every case through the CLI.

Each case runs ``roadtwin.cli.main`` in-process on its own copy of the simulated run with a
fresh temporary folder, and is held to the corpus contract (:func:`corpus.judge`): the
expected exit code, one ``roadtwin: error:`` line naming the file, no traceback, nothing
left behind or clobbered, the secret never leaked. Signals and a full disk need a real
process and run as subprocesses.
"""

from __future__ import annotations

import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

import corpus
from roadtwin.cli import main

CASES = corpus.all_cases()
HANG_S = 90.0


class Hang(BaseException):
    """Raised by the alarm when a command runs longer than ``HANG_S``."""


@pytest.fixture(scope="session")
def base(tmp_path_factory):
    return corpus.make_base(tmp_path_factory.mktemp("corpus-base"))


def _alarm(signum, frame):
    raise Hang()


def _params():
    for case in CASES:
        marks = []
        if case.subprocess_only:
            marks.append(pytest.mark.skip(reason="runs as a subprocess (test below)"))
        if "nonroot" in case.tags and os.geteuid() == 0:
            marks.append(pytest.mark.skip(reason="root ignores folder permissions"))
        yield pytest.param(case, id=case.name, marks=marks)


@pytest.mark.parametrize("case", list(_params()))
def test_corpus_case(case, base, tmp_path, capsys, monkeypatch):
    base_run, base_map = base
    d = corpus.prepare(case, base_run, base_map, tmp_path / "case")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    was = corpus.before(d)
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, HANG_S)
    t0 = time.perf_counter()
    hung = False
    try:
        code = main(case.argv(d))
    except Hang:
        code, hung = None, True
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    captured = capsys.readouterr()
    outcome = corpus.Outcome(code, captured.out, captured.err, time.perf_counter() - t0, hung)
    problems = corpus.judge(case, d, outcome, was, tmp)
    assert not problems, f"{problems}\nstderr:\n{captured.err[-2000:]}"


def _roadtwin() -> list[str]:
    exe = Path(sys.executable).parent / "roadtwin"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "roadtwin"]


def test_disk_full_leaves_nothing(base, tmp_path):
    """A disk that fills while writing (every write past 300 kB fails with EFBIG): one line,
    exit 2, no partial output and no temporary file."""
    (case,) = [c for c in CASES if c.name == "output/disk_full"]
    d = corpus.prepare(case, *base, tmp_path / "case")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    was = corpus.before(d)

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (300_000, 300_000))

    proc = subprocess.run(
        [*_roadtwin(), *case.argv(d)],
        capture_output=True,
        text=True,
        timeout=300,
        preexec_fn=limit,
        env={**os.environ, "TMPDIR": str(tmp)},
        check=False,
    )
    outcome = corpus.Outcome(proc.returncode, proc.stdout, proc.stderr, 0.0)
    assert corpus.judge(case, d, outcome, was, tmp) == {}, proc.stderr
    assert "File too large" in proc.stderr


def _descendants(pid: int) -> set[int]:
    """Process ids whose parent chain leads to ``pid`` (from /proc)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found: set[int] = set()
    frontier = {pid}
    while frontier:
        children = {p for p, pp in parents.items() if pp in frontier} - found
        found |= children
        frontier = children
    return found


@pytest.mark.parametrize(
    ("signum", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["ctrl-c", "sigterm"]
)
def test_signal_during_check_cleans_up(base, tmp_path, signum, code):
    """A signal while ``build`` runs the external checkers: exit 130/143, one line, no
    temporary folder left, and no checker process outlives roadtwin."""
    from roadtwin.consumers import find_tool

    if find_tool("qc_opendrive") is None and find_tool("netconvert") is None:
        pytest.skip("no external checker installed (roadtwin[validate])")
    case = corpus.Case("signal", corpus._seq(), corpus._build)
    d = corpus.prepare(case, *base, tmp_path / "case")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    proc = subprocess.Popen(
        [*_roadtwin(), "build", str(d.run), "-o", str(d.out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "TMPDIR": str(tmp)},
    )
    children: set[int] = set()
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        children = _descendants(proc.pid)
        if children:  # netconvert or qc_opendrive is running
            break
        time.sleep(0.05)
    assert children, "the build finished before an external checker started"
    time.sleep(0.3)
    children |= _descendants(proc.pid)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines, err
    assert lines[-1].startswith("roadtwin: error: "), err
    assert "Traceback" not in err
    time.sleep(0.2)
    alive = {p for p in children if Path(f"/proc/{p}").exists()}
    zombies = {
        p for p in alive if (Path(f"/proc/{p}/stat").read_text().split(")")[1].split()[0] == "Z")
    }
    assert alive <= zombies, f"checker processes left running: {alive - zombies}"
    assert list(tmp.iterdir()) == [], list(tmp.iterdir())
    assert not [p for p in d.root.rglob("*") if ".tmp" in p.name]


def _terminate_mid_build(cmd: list[str], out: Path, tmp: Path) -> subprocess.Popen | None:
    """Start ``cmd`` and send SIGTERM once the build is visibly under way.

    Two signs, both short-lived on a fast machine: the OSM stage's temporary folder in
    ``tmp`` (tens of milliseconds) and the output's staging folder in ``out`` (the write
    stage, a few hundred milliseconds). Returns None when the build ended before either
    was seen, so the caller can try again.
    """
    proc = subprocess.Popen(
        cmd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "TMPDIR": str(tmp)},
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if any(tmp.iterdir()) or out.exists():
            proc.send_signal(signal.SIGTERM)
            return proc
        time.sleep(0.005)
    proc.communicate(timeout=60)
    return None


def test_signal_during_build_leaves_no_partial_output(base, tmp_path):
    """SIGTERM while the map is built: exit 143 and the output folder is not created."""
    case = corpus.Case("signal", corpus._seq(), corpus._build)
    d = corpus.prepare(case, *base, tmp_path / "case")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    cmd = [*_roadtwin(), "build", str(d.run), "-o", str(d.out), "--no-check"]
    for _ in range(3):  # a build that ended before the signal could land says nothing
        proc = _terminate_mid_build(cmd, d.out, tmp)
        if proc is not None:
            break
        shutil.rmtree(d.out, ignore_errors=True)
    assert proc is not None, "the build ended three times before a sign of it was seen"
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1] == "roadtwin: error: terminated by SIGTERM"
    assert not d.out.exists()
    assert list(tmp.iterdir()) == []


@pytest.mark.parametrize(
    ("signum", "code", "text"),
    [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated by SIGTERM")],
)
def test_signal_turned_into_another_error_still_ends_as_interrupted(signum, code, text, capsys):
    """A signal that lands while a C extension initialises surfaces as an ImportError
    ("initialization failed"; seen once in 10 runs of the check test above, then reported
    as an internal error, exit 3): the command still ends as interrupted."""
    import argparse

    from roadtwin import cli

    def command(_args) -> int:
        try:
            os.kill(os.getpid(), signum)
            time.sleep(1.0)
        except BaseException as exc:  # what an extension's initialisation does
            raise ImportError("initialization failed") from exc
        return 0

    with cli._signals_as_exceptions():
        got = cli.run_command(argparse.Namespace(func=command, verbose=False))
    assert got == code
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"roadtwin: error: {text}"
