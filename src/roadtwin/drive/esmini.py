"""Finding and running esmini (headless) and reading its recording.

esmini is found in a folder given explicitly (``--esmini DIR``), in the folder named by the
environment variable ``ESMINI_BIN``, or on ``PATH``; the folder must hold ``esmini`` and
``dat2csv``. A run is ``esmini --headless --osc SCENARIO --fixed_timestep DT --record
DAT``, then ``dat2csv DAT --extended`` turns the recording into a CSV with one row per
step: time, position, heading, road id, lane id, s, t and speed.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._errors import InputError

__all__ = [
    "HARMLESS",
    "Esmini",
    "EsminiRun",
    "Recording",
    "find_esmini",
    "read_recording",
    "run_esmini",
]

HARMLESS = (
    re.compile(r"3D model .* not located"),
    re.compile(r"Ignoring missing default config"),
)
"""Log lines that say nothing about the map: a headless run has no 3D models and no
config file."""

_LEVEL = re.compile(r"\[(warn|error)\]\s*(.*)")


@dataclass(frozen=True)
class Esmini:
    """The esmini executables and their version line."""

    esmini: Path
    dat2csv: Path
    version: str


def _tools_in(folder: Path) -> Esmini | None:
    exe, conv = folder / "esmini", folder / "dat2csv"
    if not (exe.is_file() and os.access(exe, os.X_OK) and conv.is_file()):
        return None
    try:
        proc = subprocess.run(
            [str(exe), "--version"], capture_output=True, text=True, timeout=30, check=False
        )
        lines = [ln for ln in (proc.stdout + proc.stderr).splitlines() if "version" in ln.lower()]
        version = lines[0].strip() if lines else "unknown version"
    except (OSError, subprocess.TimeoutExpired):
        return None
    return Esmini(exe.resolve(), conv.resolve(), version)


def find_esmini(folder: str | os.PathLike | None = None) -> Esmini | None:
    """esmini from ``folder``, else from ``$ESMINI_BIN``, else from ``PATH``; None if absent.

    Raises
    ------
    InputError
        ``folder`` was given but holds no runnable ``esmini`` and ``dat2csv``.
    """
    if folder is not None:
        tools = _tools_in(Path(folder))
        if tools is None:
            msg = f"{folder}: no runnable esmini and dat2csv in this folder"
            raise InputError(msg)
        return tools
    env = os.environ.get("ESMINI_BIN")
    if env:
        tools = _tools_in(Path(env))
        if tools is not None:
            return tools
    found = shutil.which("esmini")
    return _tools_in(Path(found).parent) if found else None


@dataclass(frozen=True)
class EsminiRun:
    """What one esmini run left: exit code, recording CSV (None if none was written), the
    map-related warnings and errors of its log, and the wall time."""

    returncode: int
    csv: Path | None
    messages: tuple[str, ...]
    log_tail: tuple[str, ...]
    wall_s: float


def run_esmini(
    tools: Esmini, scenario: Path, work_dir: Path, *, timestep_s: float, timeout_s: float
) -> EsminiRun:
    """Run ``scenario`` headless, record it into ``work_dir`` and convert the recording."""
    import time

    work_dir.mkdir(parents=True, exist_ok=True)
    stem = scenario.stem
    dat, log, csv = (work_dir / f"{stem}{ext}" for ext in (".dat", ".log", ".csv"))
    for f in (dat, log, csv):
        f.unlink(missing_ok=True)
    cmd = [
        str(tools.esmini),
        "--headless",
        "--osc",
        str(scenario.resolve()),
        "--fixed_timestep",
        f"{timestep_s:g}",
        "--record",
        str(dat.resolve()),
        "--logfile_path",
        str(log.resolve()),
        "--disable_stdout",
    ]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, capture_output=True, text=True, timeout=timeout_s, check=False, cwd=work_dir
        )
        code = proc.returncode
    except subprocess.TimeoutExpired:
        code = -1
    lines = log.read_text(encoding="utf-8", errors="replace").splitlines() if log.exists() else []
    if code == -1:
        lines.append(f"[error] esmini did not finish within {timeout_s:g} s")
    if dat.exists():
        subprocess.run(
            [str(tools.dat2csv), str(dat.resolve()), "--extended", "--csv", str(csv.resolve())],
            capture_output=True,
            text=True,
            timeout=timeout_s,
            check=False,
            cwd=work_dir,
        )
    messages = []
    for line in lines:
        m = _LEVEL.search(line)
        if m and not any(h.search(m.group(2)) for h in HARMLESS):
            messages.append(f"{m.group(1)}: {m.group(2).strip()}")
    return EsminiRun(
        code,
        csv if csv.exists() else None,
        tuple(messages),
        tuple(lines[-5:]),
        time.perf_counter() - t0,
    )


@dataclass(frozen=True)
class Recording:
    """One car's recorded states, one entry per simulation step (arrays of equal length).

    ``x``, ``y`` mapping frame (metres), ``h`` heading (radians), ``road`` road id (str),
    ``lane`` lane id, ``s`` station on that road (metres), ``speed`` (m/s).
    """

    time: np.ndarray
    x: np.ndarray
    y: np.ndarray
    h: np.ndarray
    road: np.ndarray
    lane: np.ndarray
    s: np.ndarray
    speed: np.ndarray

    def __len__(self) -> int:
        return int(self.time.size)


def read_recording(csv: Path) -> Recording:
    """Read ``dat2csv --extended`` output (first object only).

    Raises
    ------
    InputError
        The file lacks a column this reader needs.
    """
    import pandas as pd

    df = pd.read_csv(csv, skipinitialspace=True)
    df.columns = [c.strip() for c in df.columns]
    need = ("time", "id", "x", "y", "h", "roadId", "laneId", "s", "speed")
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise InputError(f"{csv}: recording lacks columns {missing}")
    df = df[df["id"] == df["id"].iloc[0]] if len(df) else df
    return Recording(
        df["time"].to_numpy(float),
        df["x"].to_numpy(float),
        df["y"].to_numpy(float),
        df["h"].to_numpy(float),
        df["roadId"].astype(str).str.strip().to_numpy(),
        df["laneId"].to_numpy(int),
        df["s"].to_numpy(float),
        df["speed"].to_numpy(float),
    )
