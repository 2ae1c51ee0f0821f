"""Command-line interface: ``roadtwin inspect|simulate|build|check|evaluate|demo``.

A thin layer: it parses arguments, reads TOML config, shows progress and turns
:class:`~roadtwin._errors.InputError` into one line on stderr and exit code 2.
All work happens in library functions, which never print.
"""

from __future__ import annotations

import argparse
import logging
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

from . import __version__
from ._errors import FitError, InputError, InputWarning

log = logging.getLogger("roadtwin")


def _load_config(path: Path | None):
    """Read a ``--config`` TOML file into a :class:`PipelineConfig`."""
    from .config import PipelineConfig

    if path is None:
        return PipelineConfig()
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]
    if not path.is_file():
        raise InputError(f"{path}: config file not found")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML: {exc}") from None
    return PipelineConfig.from_dict(data)


# ---------------------------------------------------------------------------
# inspect  (foundation issue)
# ---------------------------------------------------------------------------


def _add_inspect(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("inspect", help="summarise a mapping run and plot an overview PNG")
    p.add_argument("run_dir", type=Path, help="mapping-run folder with run.toml")
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="overview PNG path (default: RUN_DIR/overview.png)",
    )
    p.add_argument(
        "--osm-online",
        action="store_true",
        help="fetch OSM around the trajectory through OSMnx instead of a local file",
    )
    p.add_argument("--config", type=Path, default=None, help="TOML file with stage settings")
    p.set_defaults(func=_cmd_inspect)


def _cmd_inspect(args: argparse.Namespace) -> int:
    raise NotImplementedError


# ---------------------------------------------------------------------------
# simulate  (simulator issue)
# ---------------------------------------------------------------------------


def _add_simulate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="simulate a mapping run with ground truth from a scenario")
    p.add_argument("scenario", help="scenario TOML file, or the name of a bundled example")
    p.add_argument("-o", "--output", type=Path, required=True, help="run folder to write")
    p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    p.set_defaults(func=_cmd_simulate)


def _cmd_simulate(args: argparse.Namespace) -> int:
    raise NotImplementedError


# ---------------------------------------------------------------------------
# build  (ramps / integration issue)
# ---------------------------------------------------------------------------


def _add_build(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("build", help="build map.xodr (+ kml, geojson, png) from a mapping run")
    p.add_argument("run_dir", type=Path, help="mapping-run folder with run.toml")
    p.add_argument(
        "-o", "--output", type=Path, default=None, help="output folder (default: RUN_DIR/out)"
    )
    p.add_argument(
        "--method",
        choices=["default", "paper"],
        default=None,
        help="mainline method (default: the improved one)",
    )
    p.add_argument(
        "--junctions",
        choices=["default", "direct"],
        default=None,
        help="junctions with connecting roads (default) or OpenDRIVE 1.7 direct",
    )
    p.add_argument(
        "--osm-online",
        action="store_true",
        help="fetch OSM around the trajectory through OSMnx instead of a local file",
    )
    p.add_argument("--no-check", action="store_true", help="skip roadtwin check on the result")
    p.add_argument("--config", type=Path, default=None, help="TOML file with stage settings")
    p.set_defaults(func=_cmd_build)


def _cmd_build(args: argparse.Namespace) -> int:
    raise NotImplementedError


# ---------------------------------------------------------------------------
# check  (road model / OpenDRIVE I/O issue)
# ---------------------------------------------------------------------------


def _add_check(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("check", help="check an OpenDRIVE file for gaps, links, widths, consumers")
    p.add_argument("xodr", type=Path, help="OpenDRIVE file")
    p.add_argument("--json", action="store_true", help="print findings as JSON")
    p.add_argument(
        "--no-external",
        action="store_true",
        help="skip SUMO netconvert and the ASAM quality checker",
    )
    p.set_defaults(func=_cmd_check)


def _cmd_check(args: argparse.Namespace) -> int:
    raise NotImplementedError


# ---------------------------------------------------------------------------
# evaluate  (evaluation issue)
# ---------------------------------------------------------------------------


def _add_evaluate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("evaluate", help="accuracy report of a map against its run (and truth)")
    p.add_argument("xodr", type=Path, help="map to evaluate")
    p.add_argument("run_dirs", type=Path, nargs="+", help="mapping-run folder(s)")
    p.add_argument("--truth", type=Path, default=None, help="ground-truth OpenDRIVE file")
    p.add_argument("-o", "--output", type=Path, default=None, help="report folder")
    p.set_defaults(func=_cmd_evaluate)


def _cmd_evaluate(args: argparse.Namespace) -> int:
    raise NotImplementedError


# ---------------------------------------------------------------------------
# demo  (simulator issue; grows as stages land)
# ---------------------------------------------------------------------------


def _add_demo(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="simulate the bundled example and run every stage on it")
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="folder to write into (default: a new temporary folder)",
    )
    p.add_argument(
        "--scenario",
        default="straight_curve_2km",
        help="bundled scenario name or scenario TOML file",
    )
    p.set_defaults(func=_cmd_demo)


def _cmd_demo(args: argparse.Namespace) -> int:
    raise NotImplementedError


# ---------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    """The ``roadtwin`` argument parser."""
    parser = argparse.ArgumentParser(
        prog="roadtwin",
        description="Georeferenced OpenDRIVE digital twins of highways from LiDAR + OSM.",
    )
    parser.add_argument("--version", action="version", version=f"roadtwin {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log every stage")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (_add_inspect, _add_simulate, _add_build, _add_check, _add_evaluate, _add_demo):
        add(sub)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    print(f"roadtwin: warning: {message}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``roadtwin`` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    with warnings.catch_warnings():
        warnings.simplefilter("always", InputWarning)
        previous = warnings.showwarning
        warnings.showwarning = _show_warning
        try:
            return int(args.func(args) or 0)
        except (InputError, FitError) as exc:
            print(f"roadtwin: error: {exc}", file=sys.stderr)
            return 2
        finally:
            warnings.showwarning = previous


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
