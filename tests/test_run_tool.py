"""External tools started by ``roadtwin.consumers.run_tool`` never outlive a signal.

A signal that arrived while ``Popen`` waited for the tool's exec (slow on a loaded
machine) raised inside ``Popen``: its object was lost, the tool ran on after roadtwin had
exited and Python warned "subprocess ... is still running" after the error line (a CI
run of ``test_signal_during_check_cleans_up`` while benchmarks loaded the machine)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from roadtwin import consumers


class _Stop(BaseException):
    pass


def _raise_stop(signum, frame):
    raise _Stop(signum)


def _state(pid: int) -> str:
    """Process state letter (``Z`` zombie), or ``-`` if the process is gone."""
    stat = Path(f"/proc/{pid}/stat")
    return stat.read_text().split(")")[1].split()[0] if stat.exists() else "-"


@pytest.mark.skipif(sys.platform != "linux", reason="reads /proc")
def test_a_signal_while_the_tool_starts_stops_it(monkeypatch):
    assert threading.current_thread() is threading.main_thread()
    started: list[int] = []
    real_popen = subprocess.Popen

    def popen_then_signal(*args, **kwargs):
        proc = real_popen(*args, **kwargs)
        started.append(proc.pid)
        os.kill(os.getpid(), signal.SIGTERM)  # lands before Popen has returned
        return proc

    monkeypatch.setattr(consumers.subprocess, "Popen", popen_then_signal)
    previous = signal.signal(signal.SIGTERM, _raise_stop)
    try:
        with pytest.raises(_Stop):
            consumers.run_tool(["sleep", "30"], timeout_s=60.0)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert started
    assert _state(started[0]) in ("-", "Z")  # killed and reaped, not running on
    # the handler in place before is back
    assert signal.getsignal(signal.SIGTERM) is previous


def test_a_tool_runs_and_returns_its_output():
    proc = consumers.run_tool([sys.executable, "-c", "print('ok')"], timeout_s=60.0)
    assert proc.returncode == 0
    assert proc.stdout.strip() == "ok"
