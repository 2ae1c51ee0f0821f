"""Write a simulated mapping run: the DESIGN.md section 3 folder plus ground truth.

Files: ``run.toml``, ``trajectory.csv`` (measured poses), ``road_edges.<ext>``,
``lane_samples.csv`` (ego frame), ``map.osm`` -- exactly the run contract -- and
``truth.xodr`` (the true RoadNetwork), ``truth.json`` (ramps, lane sections, noise) and
``truth_trajectory.csv`` (noise-free poses). Everything is first written into a temporary
folder next to ``out_dir`` and then moved in, so a failure leaves no partial run.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import logging
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .._errors import InputError
from ..frames import Origin
from ..xodr import write_xodr
from .osm_writer import write_osm
from .scenario import Scenario, load_scenario
from .sensor import (
    SIDE_LEFT,
    Poses,
    edge_points,
    lane_samples,
    measured_poses,
    true_poses,
)
from .truth import Truth, _lane_ids, build_truth, section_at

log = logging.getLogger(__name__)

_STREAMS = {"poses": 1, "edges": 2, "lanes": 3, "osm": 4}
"""Independent random streams per component: ``default_rng([seed, stream])``."""


def _rng(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng([seed, _STREAMS[name]])


def _write_csv(path: Path, columns: dict[str, np.ndarray], *, decimals: int = 4) -> None:
    """Fast deterministic CSV: floats rounded to ``decimals`` (shortest repr), via pyarrow."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    data = {
        k: np.round(v, decimals) if np.asarray(v).dtype.kind == "f" else v
        for k, v in columns.items()
    }
    with path.open("wb") as fh:
        fh.write((",".join(columns) + "\n").encode("ascii"))
        pcsv.write_csv(
            pa.table(data), fh, pcsv.WriteOptions(include_header=False, quoting_style="none")
        )


def _write_poses(poses: Poses, path: Path) -> None:
    yaw = (poses.yaw + np.pi) % (2.0 * np.pi) - np.pi
    _write_csv(
        path,
        {
            "frame": poses.frame,
            "t": np.round(poses.t, 3),
            "x": poses.xyz[:, 0],
            "y": poses.xyz[:, 1],
            "z": poses.xyz[:, 2],
            "yaw": yaw,
        },
        decimals=6,
    )


def _write_edges(xyz: np.ndarray, side: np.ndarray, path: Path, fmt: str) -> None:
    text_side = np.where(side == SIDE_LEFT, "left", "right")
    if fmt in ("laz", "las"):
        import laspy

        header = laspy.LasHeader(point_format=0, version="1.2")
        header.add_extra_dim(laspy.ExtraBytesParams(name="side", type=np.uint8))
        header.scales = np.array([0.001, 0.001, 0.001])
        header.offsets = np.floor(xyz.min(axis=0)) if xyz.size else np.zeros(3)
        header.creation_date = datetime.date(2024, 1, 1)  # fixed: same input -> same bytes
        header.generating_software = "roadtwin simulate"
        las = laspy.LasData(header)
        las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        las.side = side.astype(np.uint8)
        las.write(str(path))
    elif fmt == "csv":
        _write_csv(path, {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "side": text_side})
    elif fmt == "parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        table = pa.table({"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "side": text_side})
        pq.write_table(table, path)
    elif fmt in ("npy", "ply"):
        arr = np.empty(side.size, dtype=[("x", "<f8"), ("y", "<f8"), ("z", "<f8"), ("side", "u1")])
        arr["x"], arr["y"], arr["z"], arr["side"] = xyz[:, 0], xyz[:, 1], xyz[:, 2], side
        if fmt == "npy":
            np.save(path, arr)
        else:
            head = (
                "ply\nformat binary_little_endian 1.0\ncomment roadtwin simulate road edges\n"
                f"element vertex {side.size}\nproperty double x\nproperty double y\n"
                "property double z\nproperty uchar side\nend_header\n"
            )
            path.write_bytes(head.encode("ascii") + arr.tobytes())
    else:  # pragma: no cover - validated in the scenario
        raise InputError(f"unknown road-edge format {fmt!r}")


def run_toml_text(
    *,
    comment: str,
    origin: Origin,
    crs: str,
    traffic_side: str,
    edges_name: str,
    osm_name: str,
) -> str:
    """The run manifest (DESIGN.md section 3); ``comment`` is its first line's text."""
    o = origin
    return (
        f"# {comment}\n"
        "# Ground truth (not part of the run contract): truth.xodr, truth.json,\n"
        "# truth_trajectory.csv.\n"
        "[origin]\n"
        f"lat = {o.lat_deg:.9f}\nlon = {o.lon_deg:.9f}\nalt = {o.alt_m:.3f}\n"
        f"[frame]\ncrs = {json.dumps(crs)}\n"
        "[vehicle]\npose_height = 0.0\n"
        "[files]\n"
        'trajectory = "trajectory.csv"\n'
        f'road_edges = "{edges_name}"\n'
        'lane_samples = "lane_samples.csv"\n'
        f'osm = "{osm_name}"\n'
        f'[traffic]\nside = "{traffic_side}"\n'
    )


def _run_toml(sc: Scenario, edges_name: str, osm_name: str) -> str:
    return run_toml_text(
        comment=f"Simulated mapping run: roadtwin scenario {sc.name!r}, seed {sc.seed}.",
        origin=sc.origin,
        crs="local",
        traffic_side=sc.traffic_side,
        edges_name=edges_name,
        osm_name=osm_name,
    )


def copy_osm(src: str | os.PathLike, folder: Path) -> str:
    """Copy an OSM file into ``folder`` as ``map`` plus its (compound) suffix, which
    :func:`roadtwin.io.load_run` needs (``.osm.gz``, ``.osm.bz2``, ``.osm.pbf``, ``.osm``);
    returns the new file name."""
    real = Path(src)
    name = real.name.lower()
    osm_name = "map" + next(
        (ext for ext in (".osm.gz", ".osm.bz2", ".osm.pbf", ".osm") if name.endswith(ext)),
        ".osm.pbf" if name.endswith(".pbf") else ".osm",
    )
    shutil.copyfile(real, folder / osm_name)
    return osm_name


def write_sensor_files(
    folder: Path,
    meas: Poses,
    poses: Poses,
    edges: np.ndarray,
    side: np.ndarray,
    edges_name: str,
    frames: np.ndarray,
    ego: np.ndarray,
) -> None:
    """Write the measured and true poses, the road-edge points (format from the suffix of
    ``edges_name``) and the lane samples (ego frame) of a run into ``folder``."""
    _write_poses(meas, folder / "trajectory.csv")
    _write_poses(poses, folder / "truth_trajectory.csv")
    _write_edges(edges, side, folder / edges_name, edges_name.rsplit(".", 1)[-1])
    _write_csv(
        folder / "lane_samples.csv",
        {"frame": frames, "x": ego[:, 0], "y": ego[:, 1], "z": ego[:, 2]},
    )


def write_truth_files(folder: Path, doc: dict, network) -> None:
    """Write ``truth.json`` (``doc``) and ``truth.xodr`` (the true ``network``)."""
    (folder / "truth.json").write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    write_xodr(network, folder / "truth.xodr")


def write_run_folder(out_dir: Path, fill: Callable[[Path], None]) -> None:
    """Let ``fill`` write every file into a temporary folder next to ``out_dir``, then
    move them in (so a failure leaves no partial run); files become mode 644."""
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", dir=out_dir.parent))
    try:
        fill(tmp)
        out_dir.mkdir(parents=True, exist_ok=True)
        for f in sorted(tmp.iterdir()):
            f.chmod(0o644)
            os.replace(f, out_dir / f.name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _aux_lane_ids(truth: Truth, station_m: float, kind: str) -> list[int]:
    """Lane ids of a ramp's deceleration (before the gore) / acceleration (after) lanes."""
    probe = station_m - 1e-3 if kind == "exit" else station_m + 1e-3
    spec = section_at(truth.sections, probe)
    return [v for k, v in _lane_ids(spec, truth.sign).items() if k[0] == "aux"]


def section_record(road_id: str, s0: float, start: float, lanes, kinds: list[str]) -> dict:
    """truth.json entry of a mainline lane section: ``kinds`` are ``inner``, ``driving``,
    ``aux``, ``hard`` (or a lane type) per lane, median side first."""
    return {
        "road_id": road_id,
        "s0_m": round(s0, 6),
        "station_m": round(start + s0, 6),
        "driving_lanes": kinds.count("driving"),
        "aux_lanes": kinds.count("aux"),
        "lane_ids": [lane.id for lane in lanes],
        "lane_kinds": kinds,
    }


def _truth_json(truth: Truth, ramp_ways: dict[int, list[int]], counts: dict) -> dict:
    sc = truth.scenario
    roads = [r for r in truth.network.roads if r.name == "mainline"]
    starts = truth.mainline_road_starts
    sections = []
    for road, start in zip(roads, starts, strict=False):
        for ls in road.lane_sections:
            lanes = ls.right if truth.sign < 0 else ls.left
            spec = next(x for x in truth.sections if abs(x.s0 - (start + ls.s0)) < 1e-6)
            kinds = [lane.kind for lane in spec.lanes]
            sections.append(section_record(road.id, ls.s0, start, lanes, kinds))
    ramps = []
    for i, rt in enumerate(truth.ramps):
        ramps.append(
            {
                "road_id": rt.road.id,
                "type": rt.ramp.type,
                "station_m": rt.station_m,
                "lanes": rt.ramp.lanes,
                "osm_way_ids": ramp_ways.get(i, []),
                "junction_id": str(1001 + i),
                "mainline_road_before": roads[i].id,
                "mainline_road_after": roads[i + 1].id,
                "aux_lane_ids": _aux_lane_ids(truth, rt.station_m, rt.ramp.type),
                "length_m": round(rt.road.length, 6),
                "name": rt.ramp.name,
            }
        )
    return {
        "scenario": sc.name,
        "seed": sc.seed,
        "traffic_side": sc.traffic_side,
        "mainline_length_m": round(truth.mainline.length, 6),
        "car_lane": sc.car_lane,
        "lane_width_m": sc.lanes.width_m,
        "mainline_roads": [
            {"road_id": r.id, "station_m": s, "length_m": round(r.length, 6)}
            for r, s in zip(roads, starts, strict=False)
        ],
        "ramps": ramps,
        "lane_drops": [dataclasses.asdict(d) for d in sc.lanes.drops],
        "lane_sections": sections,
        "noise": {
            "pose": dataclasses.asdict(sc.noise),
            "sensor": dataclasses.asdict(sc.sensor),
            "osm": dataclasses.asdict(sc.osm),
        },
        "counts": counts,
    }


def simulate_run(
    scenario: Scenario | str | os.PathLike, out_dir: str | os.PathLike, *, seed: int | None = None
) -> Path:
    """Simulate a mapping run with ground truth into ``out_dir``.

    Parameters
    ----------
    scenario
        A :class:`Scenario`, a scenario TOML path or a bundled scenario name.
    out_dir
        Run folder to write (created; existing files of the same names are replaced).
    seed
        Overrides the scenario's seed. Same scenario and seed give the same bytes.

    Returns
    -------
    Path
        ``out_dir``.
    """
    sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario)
    if seed is not None:
        sc = dataclasses.replace(sc, seed=int(seed))
    out = Path(out_dir)
    truth = build_truth(sc)
    poses = true_poses(truth)
    meas = measured_poses(poses, truth, _rng(sc.seed, "poses"))
    edges, side, edge_counts = edge_points(truth, poses, meas, _rng(sc.seed, "edges"))
    frames, ego, lane_counts = lane_samples(truth, poses, _rng(sc.seed, "lanes"))
    edges_name = f"road_edges.{sc.road_edges_format}"

    def fill(tmp: Path) -> None:
        write_sensor_files(tmp, meas, poses, edges, side, edges_name, frames, ego)
        if sc.real_osm:
            osm_name = copy_osm(sc.real_osm, tmp)
            ramp_ways = {i: list(r.osm_way_ids) for i, r in enumerate(sc.ramps)}
        else:
            osm_name = "map.osm"
            ramp_ways = write_osm(truth, tmp / osm_name, _rng(sc.seed, "osm"))
        (tmp / "run.toml").write_text(_run_toml(sc, edges_name, osm_name), encoding="utf-8")
        counts = {
            "frames": int(poses.frame.size),
            "edge_points": int(side.size),
            "lane_samples": int(frames.size),
            "edges": edge_counts,
            "lanes": lane_counts,
        }
        write_truth_files(tmp, _truth_json(truth, ramp_ways, counts), truth.network)

    write_run_folder(out, fill)
    log.info(
        "simulated %s (seed %d): %.0f m, %d frames, %d edge points, %d lane samples, "
        "%d ramps -> %s",
        sc.name, sc.seed, truth.mainline.length, poses.frame.size, side.size, frames.size,
        len(truth.ramps), out,
    )  # fmt: skip
    return out
