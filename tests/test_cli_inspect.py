"""``roadtwin inspect``: every format end to end, and every bad input -> exit 2 + message."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from _run_factory import EDGE_FORMATS, write_run, write_run_on_osm
from roadtwin.cli import main

OSM_DIR = Path(__file__).parent / "data" / "osm"


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


@pytest.mark.parametrize("edge_format", EDGE_FORMATS)
def test_inspect_every_format(tmp_path, capsys, edge_format):
    truth = write_run(tmp_path / "run", edge_format=edge_format, n_frames=80)
    out = tmp_path / "png" / "o.png"
    assert main(["inspect", str(truth.root), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    n_edges = truth.edges.shape[0]
    assert f"{n_edges:,} road-edge points ({n_edges // 2:,} left, {n_edges // 2:,} right)" in text
    assert f"{truth.lane_world.shape[0]:,} lane samples" in text
    assert re.search(r"driven     0\.19[78] km in 7\.9 s, 80 frames", text)
    assert "crs        local (+proj=tmerc +lat_0=49.97 +lon_0=11.61" in text
    w, h = _png_size(out)
    assert w > 600
    assert h > 300
    assert not list(out.parent.glob(".*"))  # no temporary file left behind


@pytest.mark.parametrize(
    "osm_name",
    [
        "a9-bindlacher-berg.osm",
        "a9-dreieck-bayreuth-kulmbach.osm.gz",
        "west-oakland-i880.osm.bz2",
        "kotka-e18.osm.pbf",
    ],
)
def test_inspect_with_real_osm(tmp_path, capsys, osm_name):
    truth = write_run_on_osm(tmp_path / "run", OSM_DIR / osm_name, edge_format="laz")
    assert main(["inspect", str(truth.root)]) == 0
    text = capsys.readouterr().out
    line = next(li for li in text.splitlines() if li.startswith("osm "))
    assert osm_name in line
    assert "motorway " in line  # the motorway we drive on is near
    assert (truth.root / "overview.png").is_file()


def _csv_edit(name: str, edit):
    def apply(root: Path) -> None:
        df = pd.read_csv(root / name)
        edit(df).to_csv(root / name, index=False)

    return apply


def _set(name, row, col, value):
    def edit(df):
        df[col] = df[col].astype(object) if isinstance(value, str) else df[col]
        df.loc[row, col] = value
        return df

    return _csv_edit(name, edit)


def _write(name: str, content: bytes):
    def apply(root: Path) -> None:
        (root / name).write_bytes(content)

    return apply


def _toml(old: str, new: str):
    def apply(root: Path) -> None:
        p = root / "run.toml"
        text = p.read_text()
        assert old in text
        p.write_text(text.replace(old, new))

    return apply


def _remove(name: str):
    return lambda root: (root / name).unlink()


def _degrees(df):
    df["yaw"] = np.degrees(np.unwrap(df["yaw"].to_numpy()))
    return df


def _compass(df):
    df["yaw"] = np.pi / 2 - df["yaw"]
    return df


def _dup_frame(df):
    df.loc[7, "frame"] = df.loc[6, "frame"]
    return df


def _t_back(df):
    df.loc[12, "t"] = df.loc[10, "t"]
    return df


def _jump(df):
    df.loc[40:, "x"] += 250.0
    return df


def _lane_frame_missing(df):
    df.loc[5, "frame"] = 99999
    return df


def _far_lane_samples(df):
    df.loc[[3, 4], "x"] = 900.0
    return df


def _osm_far_away(root: Path) -> None:
    shutil.copyfile(OSM_DIR / "kotka-e18.osm.pbf", root / "map.osm.pbf")
    _toml(
        'lane_samples = "lane_samples.csv"',
        'lane_samples = "lane_samples.csv"\nosm = "map.osm.pbf"',
    )(root)


def _osm(content: bytes, name: str = "map.osm"):
    def apply(root: Path) -> None:
        (root / name).write_bytes(content)
        _toml(
            'lane_samples = "lane_samples.csv"',
            f'lane_samples = "lane_samples.csv"\nosm = "{name}"',
        )(root)

    return apply


def _lane_t_outside(root: Path) -> None:
    traj = pd.read_csv(root / "trajectory.csv")
    lanes = pd.read_csv(root / "lane_samples.csv").rename(columns={"frame": "t"})
    lanes["t"] = traj["t"].iloc[0] + 0.05 * np.arange(len(lanes))
    lanes.loc[len(lanes) - 1, "t"] = traj["t"].iloc[-1] + 30.0
    lanes.to_csv(root / "lane_samples.csv", index=False)


BAD = {
    # id: (mutation, exit code, regex on stderr)
    "no run.toml": (_remove("run.toml"), 2, r"run\.toml: file not found"),
    "bad toml": (_write("run.toml", b"[origin\nlat=1"), 2, r"run\.toml: not valid TOML"),
    "no origin lat": (_toml("lat = 49.97\n", ""), 2, r"\[origin\] lat is missing"),
    "no [files] key": (
        _toml('lane_samples = "lane_samples.csv"', ""),
        2,
        r"\[files\] lane_samples is missing",
    ),
    "missing trajectory": (
        _remove("trajectory.csv"),
        2,
        r"trajectory\.csv: file not found \(named by \[files\] trajectory",
    ),
    "missing edges file": (_remove("road_edges.csv"), 2, r"road_edges\.csv: file not found"),
    "unknown edge format": (
        _toml('road_edges = "road_edges.csv"', 'road_edges = "run.toml"'),
        2,
        r"unsupported road-edge format",
    ),
    "missing column yaw": (
        _csv_edit("trajectory.csv", lambda df: df.drop(columns="yaw")),
        2,
        r"trajectory\.csv: missing column 'yaw' \(expected columns frame,t,x,y,z,yaw",
    ),
    "missing column z in edges": (
        _csv_edit("road_edges.csv", lambda df: df.drop(columns="z")),
        2,
        r"road_edges\.csv: missing column 'z'",
    ),
    "empty trajectory": (_write("trajectory.csv", b""), 2, r"trajectory\.csv: file is empty"),
    "empty edges": (_write("road_edges.csv", b"x,y,z\n"), 2, r"road_edges\.csv: .*no data rows"),
    "empty lane samples": (
        _write("lane_samples.csv", b"frame,x,y,z\n"),
        2,
        r"lane_samples\.csv: file has a header but no data rows",
    ),
    "NaN in trajectory": (
        _set("trajectory.csv", 4, "x", np.nan),
        2,
        r"trajectory\.csv: data row 5, column 'x': nan is not a finite number",
    ),
    "inf in edges": (
        _set("road_edges.csv", 9, "z", np.inf),
        2,
        r"road_edges\.csv: data row 10, column 'z': inf is not a finite number",
    ),
    "text in lane samples": (
        _set("lane_samples.csv", 2, "y", "abc"),
        2,
        r"lane_samples\.csv: data row 3, column 'y': not a number",
    ),
    "bad side": (
        _set("road_edges.csv", 3, "side", "middle"),
        2,
        r"road_edges\.csv: data row 4, column 'side': 'middle' is not a side",
    ),
    "yaw in degrees": (
        _csv_edit("trajectory.csv", _degrees),
        2,
        r"trajectory\.csv: column 'yaw' is in degrees",
    ),
    "yaw as compass heading": (
        _csv_edit("trajectory.csv", _compass),
        2,
        r"column 'yaw' does not match the direction of travel .*compass heading",
    ),
    "lane frame without pose": (
        _csv_edit("lane_samples.csv", _lane_frame_missing),
        2,
        r"lane_samples\.csv: data row 6, column 'frame': frame 99999 has no pose",
    ),
    "lane t outside the trajectory": (
        _lane_t_outside,
        2,
        r"lane_samples\.csv: data row \d+, column 't': .* outside the trajectory's time span",
    ),
    "duplicate frames": (
        _csv_edit("trajectory.csv", _dup_frame),
        2,
        r"trajectory\.csv: duplicate frame 1006 in data rows 7 and 8",
    ),
    "duplicate t": (
        _csv_edit("trajectory.csv", _t_back),
        2,
        r"trajectory\.csv: data rows 11 and 13, column 't': both at .* one pose per time stamp",
    ),
    "trajectory jump": (
        _csv_edit("trajectory.csv", _jump),
        2,
        r"trajectory\.csv: trajectory jumps 2\d\d\.\d m between data rows 40 and 41",
    ),
    "points far away (warn, drop)": (
        _csv_edit("lane_samples.csv", _far_lane_samples),
        0,
        r"warning: .*lane_samples\.csv: dropped 2 of \d+ lane samples farther than 60 m",
    ),
    "all points far (wrong frame)": (
        _csv_edit("road_edges.csv", lambda df: df.assign(x=df["x"] + 680000.0)),
        2,
        r"road_edges\.csv: all \d+ road-edge points are farther than 60 m",
    ),
    "unknown CRS": (
        _toml('crs = "local"', 'crs = "EPSG:999999"'),
        2,
        r"\[frame\] crs: unknown CRS 'EPSG:999999'",
    ),
    "geographic CRS": (
        _toml('crs = "local"', 'crs = "EPSG:4326"'),
        2,
        r"not a projected \(metric\) CRS",
    ),
    "missing OSM file": (
        _toml(
            'lane_samples = "lane_samples.csv"', 'lane_samples = "lane_samples.csv"\nosm = "x.osm"'
        ),
        2,
        r"x\.osm: file not found",
    ),
    "empty OSM file": (_osm(b""), 2, r"map\.osm: OSM file is empty"),
    "unreadable OSM file": (_osm(b"not xml at all"), 2, r"map\.osm: not a readable OSM file"),
    "OSM without data": (
        _osm(b'<?xml version="1.0"?><osm version="0.6"></osm>'),
        2,
        r"map\.osm: OSM file has no data",
    ),
    "OSM far from the trajectory (warn)": (
        _osm_far_away,
        0,
        r"warning: .*no drivable OSM ways near the trajectory .*no ramps will be built",
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input(tmp_path, capsys, case):
    mutate, code, pattern = BAD[case]
    write_run(tmp_path, n_frames=60)
    mutate(tmp_path)
    out_png = tmp_path / "out" / "overview.png"
    assert main(["inspect", str(tmp_path), "-o", str(out_png)]) == code
    err = capsys.readouterr().err
    lines = [li for li in err.splitlines() if li.strip()]
    assert any(re.search(pattern, li) for li in lines), err
    if code == 2:
        assert len(lines) == 1
        assert lines[0].startswith("roadtwin: error: ")
        assert not out_png.parent.exists()  # no partial output
    else:
        assert out_png.is_file()


def test_console_script_exit_code(tmp_path):
    write_run(tmp_path, n_frames=40)
    _csv_edit("trajectory.csv", _degrees)(tmp_path)
    exe = Path(sys.executable).parent / "roadtwin"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "roadtwin"]
    proc = subprocess.run(
        [*cmd, "inspect", str(tmp_path)], capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().startswith("roadtwin: error: ")
    assert "column 'yaw' is in degrees" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "overview.png").exists()
