"""The package as a user meets it: top-level API, reprs, figures, files, CLI conventions."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import roadtwin
from roadtwin.cli import build_parser, main
from roadtwin.config import PipelineConfig
from roadtwin.xodr import read_xodr

DATA = Path(__file__).parent / "data"


def test_import_is_lazy_and_fast():
    """``import roadtwin`` loads none of the heavy dependencies; names resolve on use."""
    code = (
        "import sys, roadtwin; "
        "heavy = [m for m in ('numpy', 'scipy', 'osmnx', 'matplotlib', 'pandas', 'lxml') "
        "if m in sys.modules]; print(heavy)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    for name in roadtwin.__all__:
        assert getattr(roadtwin, name) is not None, name
    assert roadtwin.read_xodr is read_xodr
    with pytest.raises(AttributeError):
        _ = roadtwin.no_such_name


def test_help_does_not_import_the_pipeline():
    code = (
        "import sys; from roadtwin.cli import build_parser; build_parser(); "
        "print([m for m in ('numpy', 'osmnx', 'matplotlib') if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_short_reprs():
    network = read_xodr(DATA / "xodr" / "soderleden.xodr")
    text = repr(network)
    assert text.startswith("RoadNetwork(")
    assert len(text) < 120
    for road in network.roads[:20]:
        assert len(repr(road)) < 250
        for section in road.lane_sections:
            assert len(repr(section)) < 200
    for junction in network.junctions:
        assert len(repr(junction)) < 120
    assert len(repr(PipelineConfig())) > 0


def test_plots_return_figures_and_write_only_when_told(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    from roadtwin.export import plot_network

    monkeypatch.chdir(tmp_path)
    network = read_xodr(DATA / "xodr" / "e6mini.xodr")
    fig = plot_network(network)
    assert isinstance(fig, Figure)
    assert list(tmp_path.iterdir()) == []  # nothing written into the working folder
    out = tmp_path / "sub" / "m.png"
    assert isinstance(plot_network(network, None, out), Figure)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_outputs_are_readable_by_others(tmp_path):
    """Files get 0o666 minus the umask (0644 under umask 022), not mkstemp's 0600."""
    from roadtwin.xodr import write_xodr

    network = read_xodr(DATA / "xodr" / "e6mini.xodr")
    old = os.umask(0o022)
    try:
        path = write_xodr(network, tmp_path / "a.xodr")
        assert path.stat().st_mode & 0o777 == 0o644
        os.umask(0o002)
        path = write_xodr(network, tmp_path / "b.xodr")
        assert path.stat().st_mode & 0o777 == 0o664
    finally:
        os.umask(old)


@pytest.mark.parametrize(
    "argv",
    [
        ["-q", "check", "X", "--no-external"],
        ["check", "-q", "X", "--no-external"],
        ["check", "X", "--no-external", "-q"],
        ["-v", "check", "X", "-q"],
    ],
)
def test_quiet_and_verbose_anywhere(argv):
    args = build_parser().parse_args(argv)
    assert args.quiet is True
    assert args.verbose is ("-v" in argv)


def test_verbose_default_false():
    args = build_parser().parse_args(["check", "X"])
    assert (args.quiet, args.verbose) == (False, False)


def test_one_line_format_for_errors_warnings_and_logs(tmp_path, capsys):
    """Every stderr line of a failing command is ``roadtwin: <level>: ...``."""
    bad = tmp_path / "m.xodr"
    bad.write_text("<OpenDRIVE><header/></OpenDRIVE>")
    assert main(["-v", "check", str(bad), "--no-external"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err
    assert all(line.startswith(("roadtwin: info: ", "roadtwin: error: ")) for line in err), err
    assert err[-1] == f"roadtwin: error: {bad}: OpenDRIVE file has no <road>"


def test_no_progress_bars_when_not_a_terminal(tmp_path):
    """Piped stderr (a log file, CI) gets no carriage-return bar lines."""
    run = tmp_path / "run"
    from roadtwin.simulate import load_scenario, simulate_run

    simulate_run(load_scenario("straight_curve_2km"), run)
    exe = Path(sys.executable).parent / "roadtwin"
    proc = subprocess.run(
        [str(exe), "build", str(run), "-o", str(tmp_path / "out"), "--no-check", "--no-drive"],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert "\r" not in proc.stderr
    assert "it/s" not in proc.stderr
    assert "step/s" not in proc.stderr
    assert all(line.startswith("roadtwin: ") for line in proc.stderr.splitlines()), proc.stderr
    modes = {p.name: p.stat().st_mode & 0o777 for p in (tmp_path / "out").iterdir()}
    assert set(modes) == {"map.xodr", "map.kml", "map.geojson", "map.png", "build.json"}
    umask = os.umask(0)
    os.umask(umask)
    assert set(modes.values()) == {0o666 & ~umask}, modes
