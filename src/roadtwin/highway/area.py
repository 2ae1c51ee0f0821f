"""The area of an OSM-only build: an OSM extract, a bounding box, a frame.

Without LiDAR a user gives an OSM file and a bounding box (``roadtwin build --osm FILE
--bbox MINLON,MINLAT,MAXLON,MAXLAT``), or a run folder whose ``run.toml`` names only an
OSM file (``[origin]``, ``[frame]``, ``[traffic]`` as for any run; ``[area] bbox =
[min_lon, min_lat, max_lon, max_lat]`` optional, else the whole extract). The mapping
frame is the run's, or ``local`` on the box's centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import networkx as nx
import numpy as np

from .._errors import InputError
from ..config import LoadConfig
from ..frames import MappingFrame, Origin
from ..io import _frame_from_manifest, _read_manifest, _table, _traffic_side
from ..osm import OSM_SUFFIXES, load_osm

__all__ = [
    "OsmArea",
    "area_from_bbox",
    "is_osm_only_run",
    "load_area_graph",
    "load_osm_area",
    "parse_bbox",
]


@dataclass(frozen=True)
class OsmArea:
    """What an OSM-only build reads.

    Attributes
    ----------
    osm_path : the OSM extract.
    frame : the mapping frame of the map.
    traffic_side : ``"right"`` or ``"left"``.
    bbox : ``(min_lon, min_lat, max_lon, max_lat)`` WGS84 degrees, or None (whole extract).
    name : the map's name.
    box_xy : the box in the mapping frame ``(xmin, ymin, xmax, ymax)``, metres.
    root : the run folder (None for ``--osm --bbox``).
    input_files : files an output must never replace.
    """

    osm_path: Path
    frame: MappingFrame
    traffic_side: str = "right"
    bbox: tuple[float, float, float, float] | None = None
    name: str = "osm"
    root: Path | None = None
    input_files: tuple[Path, ...] = ()

    @property
    def box_xy(self) -> tuple[float, float, float, float] | None:
        if self.bbox is None:
            return None
        lo_lon, lo_lat, hi_lon, hi_lat = self.bbox
        lon = np.array([lo_lon, hi_lon, lo_lon, hi_lon])
        lat = np.array([lo_lat, lo_lat, hi_lat, hi_lat])
        x, y = self.frame.from_lonlat(lon, lat)
        return float(x.min()), float(y.min()), float(x.max()), float(y.max())


def parse_bbox(text: str) -> tuple[float, float, float, float]:
    """``"MINLON,MINLAT,MAXLON,MAXLAT"`` -> floats (WGS84 degrees), checked."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 4 or not all(math.isfinite(v) for v in values):
        msg = f"--bbox {text!r}: expected MINLON,MINLAT,MAXLON,MAXLAT in degrees"
        raise InputError(msg)
    lo_lon, lo_lat, hi_lon, hi_lat = values
    if not (-180 <= lo_lon < hi_lon <= 180 and -90 <= lo_lat < hi_lat <= 90):
        msg = (
            f"--bbox {text!r}: expected min < max, longitudes in [-180, 180] and latitudes "
            "in [-90, 90] (MINLON,MINLAT,MAXLON,MAXLAT)"
        )
        raise InputError(msg)
    return values  # type: ignore[return-value]


def _check_osm(path: Path) -> None:
    if not path.is_file():
        raise InputError(f"{path}: OSM file not found")
    if not path.name.lower().endswith(OSM_SUFFIXES):
        msg = f"{path}: unsupported OSM format (expected one of {', '.join(OSM_SUFFIXES)})"
        raise InputError(msg)


def area_from_bbox(
    osm_path: str | Path, bbox: tuple[float, float, float, float], *, traffic_side: str = "right"
) -> OsmArea:
    """An OSM-only area: the extract, the box and a ``local`` frame on the box's centre."""
    path = Path(osm_path)
    _check_osm(path)
    lo_lon, lo_lat, hi_lon, hi_lat = bbox
    origin = Origin(round(0.5 * (lo_lat + hi_lat), 7), round(0.5 * (lo_lon + hi_lon), 7), 0.0)
    stem = path.name.split(".")[0]
    return OsmArea(path, MappingFrame(origin, "local"), traffic_side, bbox, stem, None, (path,))


def is_osm_only_run(run_dir: str | Path) -> bool:
    """A run folder whose ``run.toml`` names an OSM file and no trajectory."""
    manifest_path = Path(run_dir) / "run.toml"
    if not manifest_path.is_file():
        return False
    manifest = _read_manifest(manifest_path)
    files = manifest.get("files")
    return isinstance(files, dict) and "osm" in files and "trajectory" not in files


def load_osm_area(run_dir: str | Path) -> OsmArea:
    """The area of a run folder with only ``run.toml`` and an OSM file."""
    root = Path(run_dir)
    manifest_path = root / "run.toml"
    manifest = _read_manifest(manifest_path)
    frame = _frame_from_manifest(manifest, manifest_path)
    side = _traffic_side(manifest, manifest_path)
    name = _table(manifest, "files", manifest_path, required=True).get("osm")
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"{manifest_path}: [files] osm: expected a file name (a string)")
    path = root / name
    _check_osm(path)
    bbox = None
    raw = _table(manifest, "area", manifest_path, required=False).get("bbox")
    if raw is not None:
        if not isinstance(raw, list):
            msg = f"{manifest_path}: [area] bbox: expected [min_lon, min_lat, max_lon, max_lat]"
            raise InputError(msg)
        try:
            bbox = parse_bbox(",".join(str(v) for v in raw))
        except InputError as exc:
            raise InputError(f"{manifest_path}: [area] {str(exc).lstrip('-')}") from None
    return OsmArea(path, frame, side, bbox, root.name, root, (manifest_path, path))


def load_area_graph(area: OsmArea, *, config: LoadConfig | None = None) -> nx.MultiDiGraph:
    """The drivable OSM graph of the area in its frame: ways with a node in the box (and
    within ``osm_buffer_m`` of it), or every way of the extract without a box."""
    cfg = config or LoadConfig()
    if area.bbox is None:
        return load_osm(area.osm_path, frame=area.frame, around_xy=None, config=cfg)
    lo_lon, lo_lat, hi_lon, hi_lat = area.bbox
    # probe points covering the box every osm_buffer_m: a way near any of them is kept
    x, y = area.frame.from_lonlat(
        np.array([lo_lon, hi_lon, lo_lon, hi_lon]), np.array([lo_lat, lo_lat, hi_lat, hi_lat])
    )
    step = cfg.osm_buffer_m
    gx = np.arange(float(np.min(x)), float(np.max(x)) + step, step)
    gy = np.arange(float(np.min(y)), float(np.max(y)) + step, step)
    grid = np.column_stack([g.ravel() for g in np.meshgrid(gx, gy)])
    return load_osm(area.osm_path, frame=area.frame, around_xy=grid, config=cfg)
