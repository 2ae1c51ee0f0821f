"""Report files, the ``roadtwin evaluate`` command, and rendering in headless Chromium."""

from __future__ import annotations

import contextlib
import io
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
from roadtwin.evaluation import evaluate, mainline_roads
from roadtwin.report import render_html
from roadtwin.xodr import write_xodr
from test_evaluation import TRUTH_INFO, make_run, make_truth, shifted

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def cli_report(tmp_path_factory) -> tuple[Path, str]:
    """``roadtwin evaluate`` on a map shifted 0.3 m, over two run folders with truth."""
    tmp = tmp_path_factory.mktemp("cli")
    truth = make_truth()
    runs = [tmp / "run_a", tmp / "run_b"]
    _write_run_folder(truth, make_run(truth, edge_sigma=0.03, lane_sigma=0.05, seed=21), runs[0])
    _write_run_folder(truth, make_run(truth, edge_sigma=0.06, lane_sigma=0.10, seed=22), runs[1])
    map_path = tmp / "map.xodr"
    write_xodr(shifted(truth, 0.3), map_path)
    out = tmp / "report"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(["-q", "evaluate", str(map_path), *map(str, runs), "-o", str(out)])
    assert code == 0
    return out, buf.getvalue()


@pytest.fixture(scope="module")
def report_dir(cli_report) -> Path:
    return cli_report[0]


def test_report_files(report_dir):
    doc = json.loads((report_dir / "report.json").read_text())
    assert doc["schema"] == "roadtwin-evaluation/1"
    assert sorted(doc) == ["runs", "schema", "table"]
    assert list(doc["table"]) == ["map"]
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
    mean = doc["table"]["map"]["road_edge"]["mean_rmse_m"]
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
    overall = doc["table"]["map"]["overall"]["median_rmse_m"]
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


def test_cli_evaluate_shifted_map_against_truth(cli_report):
    out, text = cli_report
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


SHORT_SCENARIO = """
name = "short_exit"
seed = 3
[origin]
lat = 49.98
lon = 11.62
alt = 420.0
[traffic]
side = "right"
[[alignment]]
type = "straight"
length = 400
[[alignment]]
type = "arc"
radius = 1500
length = 500
direction = "left"
[lanes]
count = 2
width = 3.75
inner_shoulder = 0.75
hard_shoulder = 2.5
[[ramps]]
type = "exit"
station = 450
lanes = 1
parallel_length = 150
taper_length = 60
radius = 300
curve_length = 140
[output]
road_edges_format = "csv"
"""


@pytest.mark.slow
def test_simulated_run_truth_and_both_methods(tmp_path):
    """Simulator files end to end: the truth scores perfectly against itself, and both
    build methods are reported side by side."""
    from roadtwin.evaluation import compare_methods, load_truth
    from roadtwin.io import load_run
    from roadtwin.simulate import load_scenario, simulate_run

    scenario_path = tmp_path / "short.toml"
    scenario_path.write_text(SHORT_SCENARIO)
    run_dir = simulate_run(load_scenario(scenario_path), tmp_path / "run", seed=3)
    run = load_run(run_dir)
    truth, info = load_truth(run_dir / "truth.xodr")

    own = evaluate(truth, run, truth=truth, truth_info=info).runs[0]
    for key in ("road_edge", "lane_boundary", "elevation", "ramp_centre", "ramp_boundary"):
        assert own.truth[key]["max_m"] == pytest.approx(0.0, abs=1e-6), key
    assert own.truth["covered_fraction"] == 1.0
    assert own.truth["lane_count"]["matched_fraction"] == 1.0
    assert own.topology["matched"] == len(info["ramps"]) == 1
    assert own.topology["type_correct"] == 1
    assert own.topology["all_connected"] is True  # direct junction lane links, as written
    # the run's own noise and outliers against the true map: well under the paper's 0.74 m
    assert own.self_consistency["overall_rmse_m"] < 0.4

    report = compare_methods(run, truth=truth, truth_info=info)
    assert [r.method for r in report.runs] == ["default", "paper", "truth"]
    assert list(report.table()) == ["default", "paper", "truth"]
    assert report.runs[2].self_consistency == own.self_consistency
    for r in report.runs:
        assert r.truth["lane_boundary"]["rmse_m"] < 1.0
        assert r.topology["true_ramps"] == 1
    html = render_html(report, {})
    head = html[html.index('<table class="paper">') : html.index("</thead>")]
    assert re.findall(r'<th colspan="3">(\w+)</th>', head) == ["default", "paper", "truth"]
