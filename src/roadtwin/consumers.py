"""External OpenDRIVE consumers run by ``roadtwin check``.

* SUMO ``netconvert --opendrive-files MAP.xodr -o net.net.xml`` (eclipse-sumo wheel): its
  ``Error:`` lines and a non-zero exit code count as errors, ``Warning:`` lines as
  warnings. SUMO cannot read ``direct`` junctions: such maps are skipped with that reason.
* The ASAM quality checker's OpenDRIVE bundle ``qc_opendrive -c config.xml``
  (asam-qc-opendrive): it exits 0 even when it finds issues, so its XQAR result is loaded
  with ``qc_baselib.Result`` and the issues are counted per rule (level ERROR as errors,
  WARNING and crashed checkers as warnings). A schema failure skips all later rules.

Each tool is looked up next to ``sys.executable`` first, then on ``PATH``
(:func:`find_tool`); a missing one gives status ``not installed``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from .model import RoadNetwork

__all__ = ["ConsumerResult", "find_tool", "run_asam", "run_sumo", "run_tool"]


@dataclass(frozen=True)
class ConsumerResult:
    """Outcome of one external consumer.

    ``status`` is ``passed``, ``failed``, ``skipped`` or ``not installed``; ``errors`` and
    ``warnings`` count its messages; ``issues_per_rule`` (ASAM checker) maps rule UIDs to
    issue counts; ``messages`` are one line each.
    """

    name: str
    status: Literal["passed", "failed", "skipped", "not installed"]
    errors: int = 0
    warnings: int = 0
    messages: tuple[str, ...] = ()
    issues_per_rule: dict[str, int] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "status": self.status,
            "errors": self.errors,
            "warnings": self.warnings,
            "issues_per_rule": dict(sorted(self.issues_per_rule.items())),
            "messages": list(self.messages),
        }


def find_tool(name: str) -> str | None:
    """Path of a console script: next to ``sys.executable`` first, then ``PATH``."""
    here = Path(sys.executable).parent / name
    if here.is_file() and os.access(here, os.X_OK):
        return str(here)
    return shutil.which(name)


def run_tool(
    cmd: list[str], *, timeout_s: float, cwd: str | os.PathLike | None = None
) -> subprocess.CompletedProcess[str]:
    """Run an external tool in its own process group and collect its output.

    The console scripts of the eclipse-sumo wheel are Python wrappers that start the real
    binary as their own child, so killing the direct child is not enough: on a timeout, an
    interrupt (Ctrl-C), SIGTERM or any other exception the whole group is killed before
    the exception goes on, and no tool outlives roadtwin.

    Raises
    ------
    subprocess.TimeoutExpired
        The tool ran longer than ``timeout_s`` (it has been killed).
    """
    with _signals_deferred() as pending:
        proc = subprocess.Popen(
            cmd,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            stdin=subprocess.DEVNULL,
            text=True,
            errors="replace",
            cwd=cwd,
            start_new_session=True,  # own process group; a terminal's Ctrl-C reaches only us
        )
    try:
        for signum in pending:  # delivered again here, where the tool is stopped with us
            os.kill(os.getpid(), signum)
        out, err = proc.communicate(timeout=timeout_s)
    except BaseException:
        _kill_group(proc)
        raise
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


_DEFERRED = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


@contextlib.contextmanager
def _signals_deferred() -> Iterator[list[int]]:
    """Signals that arrive while a tool is being started are recorded, not handled: one
    that raised inside ``Popen`` after the fork (the exec handshake, slow on a loaded
    machine) lost the tool's ``Popen``, and the tool ran on after roadtwin had exited
    ("subprocess ... is still running"). Yields the list of signals received; only in the
    main thread (where Python handles signals), and only for Python-level handlers."""
    pending: list[int] = []
    previous: dict[int, object] = {}
    if threading.current_thread() is threading.main_thread():
        for signum in _DEFERRED:
            handler = signal.getsignal(signum)
            if callable(handler):
                previous[signum] = signal.signal(signum, lambda n, _f: pending.append(n))
    try:
        yield pending
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)  # type: ignore[arg-type]


_SCRATCH_REMOVE_S = 5.0  # how long a scratch folder's removal is retried (seconds)


@contextlib.contextmanager
def _scratch_dir(prefix: str) -> Iterator[str]:
    """A temporary folder for a tool's files, removed on the way out, also after a signal.

    A Ctrl-C that arrives while the folder is being removed (the tool done, its files being
    deleted) stopped the removal half-way: the folder stayed in TMPDIR (once in CI,
    ``test_signal_during_check_cleans_up``). Signals wait until the folder is gone (then
    delivered again), and the removal is retried for a while (a killed tool's last write
    may land while the folder is being removed)."""
    tmp = tempfile.mkdtemp(prefix=prefix)
    try:
        yield tmp
    finally:
        # a signal arriving while the folder is removed waits until it is gone
        with _signals_deferred() as pending:
            deadline = time.monotonic() + _SCRATCH_REMOVE_S
            while True:
                shutil.rmtree(tmp, ignore_errors=True)
                if not os.path.exists(tmp) or time.monotonic() > deadline:
                    break
                time.sleep(0.05)
        for signum in pending:
            os.kill(os.getpid(), signum)


def _kill_group(proc: subprocess.Popen) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.kill()
    proc.communicate()


def run_sumo(path: Path, network: RoadNetwork, *, timeout_s: float = 600.0) -> ConsumerResult:
    """Load the map with SUMO ``netconvert --opendrive-files`` and collect its messages."""
    name = "sumo netconvert"
    if any(j.type == "direct" for j in network.junctions):
        return ConsumerResult(
            name, "skipped", messages=("skipped: SUMO cannot read direct junctions",)
        )
    exe = find_tool("netconvert")
    if exe is None:
        return ConsumerResult(name, "not installed", messages=("netconvert not found",))
    with _scratch_dir("roadtwin-sumo-") as tmp:
        cmd = [
            exe,
            "--opendrive-files",
            str(path.resolve()),
            "-o",
            str(Path(tmp) / "net.net.xml"),
        ]
        try:
            proc = run_tool(cmd, timeout_s=timeout_s)
        except subprocess.TimeoutExpired:
            return ConsumerResult(
                name, "failed", errors=1, messages=(f"timed out after {timeout_s} s",)
            )
        produced = (Path(tmp) / "net.net.xml").is_file()
    lines = [ln.strip() for ln in (proc.stderr + "\n" + proc.stdout).splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("Error")]
    warns = [ln for ln in lines if ln.startswith("Warning")]
    n_err = len(errors)
    if proc.returncode != 0 and n_err == 0:
        errors.append(f"netconvert exited with code {proc.returncode}")
        n_err = 1
    if proc.returncode == 0 and not produced:
        errors.append("netconvert wrote no network")
        n_err += 1
    status = "passed" if n_err == 0 else "failed"
    return ConsumerResult(name, status, n_err, len(warns), tuple(errors + warns))


_QC_CONFIG = """<?xml version="1.0" encoding="UTF-8"?>
<Config>
  <Param name="InputFile" value="{input}"/>
  <CheckerBundle application="xodrBundle">
    <Param name="resultFile" value="{result}"/>
  </CheckerBundle>
</Config>
"""


class _IssuePlaces:
    """Where in the map an ASAM issue is: its XML locations (``/OpenDRIVE/road[13]/lanes/
    laneSection/left/lane[2]``, positions in document order) named by the ids of the road,
    lane section and lane they point at, as a user looks them up."""

    def __init__(self, path: Path) -> None:
        self._path = path
        self._tree = None

    def _element(self, xpath: str):
        from lxml import etree

        if self._tree is None:
            from ._xml import safe_parser

            try:
                self._tree = etree.parse(str(self._path), safe_parser())
            except (OSError, etree.XMLSyntaxError):
                self._tree = False
        if not self._tree or not xpath.startswith("/OpenDRIVE"):
            return None
        try:
            found = self._tree.xpath(xpath)
        except etree.XPathError:
            return None
        return found[0] if found and isinstance(found[0], etree._Element) else None

    def of(self, issue) -> str:
        """`` (road 13 lane 2 -> road 4 lane 4)``: the roads and lanes of an issue's
        XML locations, or ``""``."""
        names = []
        for loc in issue.locations:
            for xml_loc in getattr(loc, "xml_location", None) or ():
                el = self._element(getattr(xml_loc, "xpath", "") or "")
                if el is None:
                    continue
                road = next((a for a in el.iterancestors("road")), el if el.tag == "road" else None)
                text = f"road {road.get('id')}" if road is not None else el.tag
                if el.tag == "lane":
                    text += f" lane {el.get('id')}"
                names.append(text)
        return f" ({' -> '.join(names[:2])})" if names else ""


def run_asam(path: Path, *, timeout_s: float = 600.0) -> ConsumerResult:
    """Run the ASAM quality checker's OpenDRIVE bundle and count its issues per rule."""
    from xml.sax.saxutils import quoteattr

    name = "asam qc_opendrive"
    exe = find_tool("qc_opendrive")
    try:
        from qc_baselib import IssueSeverity, Result, StatusType
    except ImportError:
        exe = None
    if exe is None:
        return ConsumerResult(name, "not installed", messages=("qc_opendrive not found",))
    with _scratch_dir("roadtwin-qc-") as tmp:
        result_file = Path(tmp) / "result.xqar"
        config_file = Path(tmp) / "config.xml"
        config_file.write_text(
            _QC_CONFIG.format(
                input=quoteattr(str(path.resolve()))[1:-1],
                result=quoteattr(str(result_file))[1:-1],
            ),
            encoding="utf-8",
        )
        try:
            proc = run_tool([exe, "-c", str(config_file)], timeout_s=timeout_s, cwd=tmp)
        except subprocess.TimeoutExpired:
            return ConsumerResult(
                name, "failed", errors=1, messages=(f"timed out after {timeout_s} s",)
            )
        if not result_file.is_file():
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
            return ConsumerResult(
                name,
                "failed",
                errors=1,
                messages=(f"qc_opendrive wrote no result (exit {proc.returncode})", *tail),
            )
        result = Result()
        result.load_from_file(str(result_file))
    per_rule: Counter[str] = Counter()
    messages: list[str] = []
    n_err = n_warn = 0
    skipped = []
    where = _IssuePlaces(path)
    for bundle in result.get_checker_bundle_results():
        for checker in bundle.checkers:
            if checker.status == StatusType.SKIPPED:
                skipped.append(checker.checker_id)
            if checker.status == StatusType.ERROR:  # the checker crashed: a tool problem
                n_warn += 1
                messages.append(f"WARNING checker {checker.checker_id} failed to run")
            for issue in checker.issues:
                per_rule[issue.rule_uid] += 1
                if issue.level == IssueSeverity.ERROR:
                    n_err += 1
                elif issue.level == IssueSeverity.WARNING:
                    n_warn += 1
                rule = issue.rule_uid.split(":")[-1]
                place = where.of(issue) if issue.level == IssueSeverity.ERROR else ""
                messages.append(f"{issue.level.name} {rule}: {issue.description}{place}")
    if any("valid_schema" in c for c in skipped) or per_rule.get(
        "asam.net:xodr:1.0.0:xml.valid_schema"
    ):
        messages.append("schema check failed or skipped: later rules were skipped")
    status = "passed" if n_err == 0 else "failed"
    return ConsumerResult(name, status, n_err, n_warn, tuple(messages), dict(per_rule))
