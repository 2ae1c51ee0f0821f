"""Report files, the ``roadtwin evaluate`` command, and rendering in headless Chromium."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread
from scipy.spatial import cKDTree

from roadtwin.cli import main
from roadtwin.evaluation import combine_reports, evaluate, mainline_roads
from roadtwin.report import write_report
from roadtwin.xodr import write_xodr
from test_evaluation import TRUTH_INFO, make_run, make_truth, shifted

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory) -> Path:
    truth = make_truth()
    reports = [
        evaluate(
            shifted(truth, 0.3),
            make_run(truth, edge_sigma=0.05, lane_sigma=0.08, seed=seed),
            truth=truth,
            truth_info=TRUTH_INFO,
            method=method,
        )
        for seed, method in ((11, "default"), (12, "paper"))
    ]
    out = tmp_path_factory.mktemp("report")
    write_report(combine_reports(reports), out)
    return out


def test_report_files(report_dir):
    doc = json.loads((report_dir / "report.json").read_text())
    assert doc["schema"] == "roadtwin-evaluation/1"
    assert sorted(doc) == ["runs", "schema", "table"]
    assert list(doc["table"]) == ["default", "paper"]
    run = doc["runs"][0]
    assert sorted(run) == [
        "label",
        "map",
        "method",
        "run_dir",
        "self_consistency",
        "topology",
        "truth",
    ]
    assert run["truth"]["road_edge"]["rmse_m"] == pytest.approx(0.3, abs=0.01)
    pngs = sorted(p.name for p in report_dir.glob("*.png"))
    assert len(pngs) == 6  # 3 plots x 2 runs
    for name in pngs:
        data = (report_dir / name).read_bytes()
        assert data.startswith(PNG_MAGIC)
        assert len(data) > 10_000
    html = (report_dir / "report.html").read_text()
    # self-contained: no scripts, no external resources, every plot embedded
    assert "<script" not in html
    assert not re.search(r'(src|href)="(?!data:)', html)
    assert html.count('src="data:image/png;base64,') == 6
    paper_row = re.search(r"<td[^>]*>Road edge</td>(.*?)</tr>", html).group(1)
    mean = doc["table"]["default"]["road_edge"]["mean_rmse_m"]
    assert f"{mean:.3f}" in paper_row


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _run_chromium(exe: str, url: str, tmp: Path, *extra: str) -> subprocess.CompletedProcess:
    cmd = [
        exe,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp / 'profile'}",
        "--enable-logging=stderr",
        "--v=0",
        *extra,
        url,
    ]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)


def _console_errors(stderr: str) -> list[str]:
    """Console messages (our page has no script, so any is an error) and load failures."""
    return [
        line
        for line in stderr.splitlines()
        if ":CONSOLE" in line or "Uncaught" in line or "Failed to load resource" in line
    ]


def test_html_renders_in_headless_chromium(report_dir, tmp_path):
    exe = _chromium()
    if exe is None:
        pytest.skip("no chromium binary on PATH (Debian: apt-get install -y chromium)")
    url = (report_dir / "report.html").as_uri()
    shot = tmp_path / "shot.png"
    res = _run_chromium(exe, url, tmp_path, f"--screenshot={shot}", "--window-size=1280,2000")
    assert res.returncode == 0, res.stderr[-2000:]
    assert _console_errors(res.stderr) == []
    img = imread(shot)[..., :3]
    assert img.shape[:2] == (2000, 1280)
    assert float(img.std()) > 0.05  # not a blank page
    assert float(np.mean(img < 0.5)) > 0.01  # dark pixels: text, plot lines
    dom = _run_chromium(exe, url, tmp_path, "--dump-dom")
    assert dom.returncode == 0
    assert _console_errors(dom.stderr) == []
    doc = json.loads((report_dir / "report.json").read_text())
    for target in ("Road edge", "Lane boundary", "Overall"):
        assert f">{target}</td>" in dom.stdout
    overall = doc["table"]["paper"]["overall"]["median_rmse_m"]
    assert f"{overall:.3f}" in dom.stdout
    assert dom.stdout.count("data:image/png;base64,") == 6

    # the console check itself catches a failing script
    bad = tmp_path / "bad.html"
    bad.write_text("<html><body><script>undefinedFn();</script><p>x</p></body></html>")
    res_bad = _run_chromium(exe, bad.as_uri(), tmp_path, "--dump-dom")
    assert any("Uncaught" in line for line in _console_errors(res_bad.stderr))


def _write_run_folder(truth, run, root: Path) -> None:
    """A mapping-run folder (DESIGN.md section 3) holding the given measurements."""
    root.mkdir(parents=True)
    xy, yaw = [], []
    for road in mainline_roads(truth):
        s = np.arange(0.0, road.length, 2.0)
        xy.append(road.to_xy(s, np.full(s.size, -5.0)))
        yaw.append(road.heading(s))
    pose_xy = np.vstack(xy)
    pose_yaw = np.concatenate(yaw)
    n = pose_xy.shape[0]
    frames = np.arange(n)
    lines = ["frame,t,x,y,z,yaw"] + [
        f"{i},{0.1 * i:.1f},{x:.4f},{y:.4f},0.0,{h:.8f}"
        for i, (x, y), h in zip(frames, pose_xy, pose_yaw, strict=True)
    ]
    (root / "trajectory.csv").write_text("\n".join(lines) + "\n")
    lines = ["x,y,z"] + [f"{x:.4f},{y:.4f},{z:.4f}" for x, y, z in run.edges]
    (root / "road_edges.csv").write_text("\n".join(lines) + "\n")
    _, near = cKDTree(pose_xy).query(run.lane_samples[:, :2])
    d = run.lane_samples[:, :2] - pose_xy[near]
    c, s = np.cos(pose_yaw[near]), np.sin(pose_yaw[near])
    ego = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    lines = ["frame,x,y,z"] + [
        f"{f},{x:.4f},{y:.4f},0.0" for f, (x, y) in zip(frames[near], ego, strict=True)
    ]
    (root / "lane_samples.csv").write_text("\n".join(lines) + "\n")
    (root / "run.toml").write_text(
        "[origin]\nlat = 47.0707\nlon = 15.4395\nalt = 350.0\n"
        '[frame]\ncrs = "local"\n'
        '[files]\ntrajectory = "trajectory.csv"\nroad_edges = "road_edges.csv"\n'
        'lane_samples = "lane_samples.csv"\n'
        '[traffic]\nside = "right"\n'
    )
    write_xodr(truth, root / "truth.xodr")
    (root / "truth.json").write_text(json.dumps(TRUTH_INFO))


def test_cli_evaluate_shifted_map_against_truth(tmp_path, capsys):
    truth = make_truth()
    run_a = tmp_path / "run_a"
    run_b = tmp_path / "run_b"
    _write_run_folder(truth, make_run(truth, edge_sigma=0.03, lane_sigma=0.05, seed=21), run_a)
    _write_run_folder(truth, make_run(truth, edge_sigma=0.06, lane_sigma=0.10, seed=22), run_b)
    map_path = tmp_path / "map.xodr"
    write_xodr(shifted(truth, 0.3), map_path)
    out = tmp_path / "report"
    code = main(["-q", "evaluate", str(map_path), str(run_a), str(run_b), "-o", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    doc = json.loads((out / "report.json").read_text())
    assert [r["label"] for r in doc["runs"]] == ["run_a", "run_b"]
    for r in doc["runs"]:
        assert r["truth"]["road_edge"]["rmse_m"] == pytest.approx(0.3, abs=0.01)
        assert r["truth"]["lane_boundary"]["rmse_m"] == pytest.approx(0.3, abs=0.01)
        assert r["topology"]["matched"] == 2
        assert r["topology"]["all_connected"] is True
        # self-consistency: 0.3 m shift plus the injected noise, in quadrature
        assert 0.3 < r["self_consistency"]["overall_rmse_m"] < 0.32
    # the printed Table 4 reproduces from report.json
    vals = [r["self_consistency"]["overall_rmse_m"] for r in doc["runs"]]
    row = next(line for line in text.splitlines() if line.startswith("Overall"))
    assert f"{np.mean(vals):.3f}" in row
    assert f"{min(vals):.3f}-{max(vals):.3f}" in row
    assert "ramps 2/2 matched" in text
    assert (out / "report.html").is_file()


def test_cli_evaluate_bad_input(tmp_path, capsys):
    map_path = tmp_path / "map.xodr"
    write_xodr(make_truth(), map_path)
    code = main(["evaluate", str(map_path), str(tmp_path / "nope")])
    assert code == 2
    assert "no run.toml" in capsys.readouterr().err
