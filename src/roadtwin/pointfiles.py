"""Point and table files of a mapping run: CSV tables and road-edge point clouds.

Vectorised readers for the road-edge formats of DESIGN.md section 3 -- LAS/LAZ (laspy with
lazrs), PLY (ascii and binary, own header parser + ``np.fromfile``), CSV, NPY and Parquet
(pyarrow) -- and the column checks shared with :mod:`roadtwin.io`. Point files and CSV tables
are read in chunks (:func:`iter_road_edges`, :func:`iter_table`) so that a run of tens of
millions of points never sits in memory at once; the checks are the same. Every problem raises
:class:`~roadtwin._errors.InputError` naming the file, the data row (1 = first row after the
header) or field, and what was expected.

Side encoding of road-edge points: text ``left`` / ``right`` (``l`` / ``r``; empty or
``unknown`` = unknown), or integers ``1`` = left, ``2`` = right, ``0`` = unknown (``-1`` is
read as right). The result uses :data:`SIDE_LEFT` (+1) / :data:`SIDE_RIGHT` (-1) / 0.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ._errors import InputError, InputWarning, one_line, reason

__all__ = [
    "DEFAULT_CHUNK_POINTS",
    "EDGE_SUFFIXES",
    "MAX_COORDINATE_M",
    "SIDE_LEFT",
    "SIDE_RIGHT",
    "EdgeChunk",
    "check_coordinates",
    "count_road_edges",
    "float_column",
    "int_column",
    "iter_road_edges",
    "iter_table",
    "one_line",
    "read_road_edges",
    "read_table",
    "require_columns",
    "stack_columns",
]

MAX_COORDINATE_M = 1.0e8
"""Largest absolute coordinate (metres) of any point or pose. No place on earth lies farther
than ~2e7 m from a projected CRS's origin; beyond this the data are corrupt or not metres
(and squares of such numbers overflow)."""

EDGE_SUFFIXES = (".las", ".laz", ".ply", ".csv", ".npy", ".parquet")
SIDE_LEFT = 1
"""Edge side code of a left road-edge point (``MappingRun.edge_side``)."""
SIDE_RIGHT = -1
"""Edge side code of a right road-edge point."""


# ---------------------------------------------------------------------------
# tables (CSV / Parquet) -> validated float columns
# ---------------------------------------------------------------------------


def read_table(path: Path, what: str, *, max_rows: int | None = None) -> pd.DataFrame:
    """Read a CSV file with a header row.

    Parameters
    ----------
    path
        CSV file (comma separated, UTF-8 with or without BOM).
    what
        What the file should hold, for error messages (``"columns x,y,z[,side]"``).
    max_rows
        Refuse files with more data rows (``None``: no limit).

    Returns
    -------
    pandas.DataFrame
        At least one row; column names stripped and lower-cased.
    """
    _check_text_file(path, what)
    with _csv_errors(path, what):
        df = pd.read_csv(
            path,
            skipinitialspace=True,
            low_memory=False,
            encoding="utf-8-sig",
            nrows=None if max_rows is None else max_rows + 1,
        )
    df.columns = [str(c).strip().lower() for c in df.columns]
    if df.shape[0] == 0:
        msg = f"{path}: file has a header but no data rows (expected {what})"
        raise InputError(msg)
    _check_row_count(path, df.shape[0], max_rows)
    return df


def _check_text_file(path: Path, what: str) -> None:
    """Refuse an empty file, or one with NUL bytes (pandas would silently cut the field at
    the NUL)."""
    if path.stat().st_size == 0:
        msg = f"{path}: file is empty (expected {what})"
        raise InputError(msg)
    nul = _first_nul(path)
    if nul is not None:
        msg = f"{path}: NUL byte at offset {nul}: not a text CSV file (expected {what})"
        raise InputError(msg)


@contextmanager
def _csv_errors(path: Path, what: str) -> Iterator[None]:
    """pandas' parse errors as one-line :class:`InputError` that quote no file content."""
    try:
        yield
    except InputError:
        raise
    except pd.errors.EmptyDataError:
        msg = f"{path}: file is empty (expected {what})"
        raise InputError(msg) from None
    except UnicodeDecodeError:
        msg = f"{path}: not a UTF-8 text file; expected a CSV table with {what}"
        raise InputError(msg) from None
    except (pd.errors.ParserError, ValueError) as exc:
        msg = f"{path}: not a readable CSV file ({reason(exc)}); expected {what}"
        raise InputError(msg) from None


def _check_row_count(path: Path, rows: int, max_rows: int | None) -> None:
    if max_rows is not None and rows > max_rows:
        msg = (
            f"{path}: more than {max_rows:,} data rows; larger files are refused "
            "([load] max_poses / max_points): thin or split them"
        )
        raise InputError(msg)


def _first_nul(path: Path, chunk: int = 1 << 22) -> int | None:
    """Byte offset of the first NUL byte in a file, or None (read in 4 MiB chunks)."""
    offset = 0
    with path.open("rb") as fh:
        while block := fh.read(chunk):
            at = block.find(b"\0")
            if at >= 0:
                return offset + at
            offset += len(block)
    return None


def iter_table(
    path: Path, what: str, *, chunk_rows: int, max_rows: int | None = None
) -> Iterator[pd.DataFrame]:
    """:func:`read_table` in chunks of ``chunk_rows`` rows (file order).

    Same checks and messages (empty file, NUL bytes, not UTF-8, not a CSV, header without
    rows, more than ``max_rows`` data rows); column names stripped and lower-cased in every
    chunk. Yields at least one chunk.
    """
    _check_text_file(path, what)
    rows = 0
    with _csv_errors(path, what):
        reader = pd.read_csv(
            path, skipinitialspace=True, encoding="utf-8-sig", chunksize=max(1, chunk_rows)
        )
        with reader:
            for df in reader:
                df.columns = [str(c).strip().lower() for c in df.columns]
                if rows == 0 and df.shape[0] == 0:
                    break
                rows += df.shape[0]
                _check_row_count(path, rows, max_rows)
                yield df
    if rows == 0:
        msg = f"{path}: file has a header but no data rows (expected {what})"
        raise InputError(msg)


def _column_names(columns: Iterable[str]) -> str:
    """The found column names when they look like names; never other file content."""
    names = [str(c) for c in columns]
    plain = all(len(n) <= 32 and n.replace("_", "").replace(" ", "").isalnum() for n in names)
    if plain and len(names) <= 20:
        return "found: " + ", ".join(names)
    return f"found {len(names)} column(s) that are not such names"


def require_columns(columns: Iterable[str], needed: Iterable[str], path: Path, what: str) -> None:
    """Raise an InputError naming the first of ``needed`` missing from ``columns``."""
    columns = list(columns)
    have = set(columns)
    for name in needed:
        if name not in have:
            msg = f"{path}: missing column '{name}' (expected {what}; {_column_names(columns)})"
            raise InputError(msg)


def float_column(values: Any, path: Path, name: str, *, first_row: int = 0) -> NDArray[np.float64]:
    """A column as float64; non-numbers, NaN and inf name the first bad data row
    (``first_row``: data row of the column's first value, 0-based, for chunks)."""
    series = values if isinstance(values, pd.Series) else pd.Series(np.asarray(values))
    if series.dtype.kind in "fiub":
        arr = series.to_numpy(dtype=np.float64)
    else:
        arr = pd.to_numeric(series, errors="coerce").to_numpy(dtype=np.float64)
        bad_text = np.isnan(arr) & series.notna().to_numpy()
        if bad_text.any():
            row = int(np.argmax(bad_text))
            count = int(np.count_nonzero(bad_text))
            msg = (
                f"{path}: data row {first_row + row + 1}, column '{name}': not a number "
                f"({count} such value(s) in this column; expected numbers)"
            )
            raise InputError(msg)
    finite = np.isfinite(arr)
    if not finite.all():
        row = int(np.argmin(finite))
        count = int(finite.size - np.count_nonzero(finite))
        msg = (
            f"{path}: data row {first_row + row + 1}, column '{name}': {arr[row]} is not a "
            f"finite number ({count} NaN/inf value(s) in this column; expected finite numbers)"
        )
        raise InputError(msg)
    return arr


def check_coordinates(xyz: NDArray[np.float64], path: Path, *, first_row: int = 0) -> None:
    """Refuse coordinates beyond :data:`MAX_COORDINATE_M` (corrupt, or not metres);
    ``first_row``: data row of ``xyz[0]`` (0-based, for chunks)."""
    if xyz.size == 0:
        return
    big = np.abs(xyz) > MAX_COORDINATE_M
    if big.any():
        row, col = np.unravel_index(int(np.argmax(big)), big.shape)
        msg = (
            f"{path}: data row {first_row + row + 1}: coordinate {xyz[row, col]:.3g} is beyond "
            f"{MAX_COORDINATE_M:.0e} m ({int(big.any(axis=1).sum())} row(s)); expected "
            "metres in the mapping frame"
        )
        raise InputError(msg)


def int_column(values: Any, path: Path, name: str, *, first_row: int = 0) -> NDArray[np.int64]:
    """A column of integer values (``1000`` or ``1000.0``) as int64, checked like floats."""
    arr = float_column(values, path, name, first_row=first_row)
    rounded = np.round(arr)
    bad = np.abs(arr - rounded) > 1e-9
    if bad.any():
        row = int(np.argmax(bad))
        msg = (
            f"{path}: data row {first_row + row + 1}, column '{name}': {arr[row]} is not an integer"
        )
        raise InputError(msg)
    return rounded.astype(np.int64)


# ---------------------------------------------------------------------------
# road edges
# ---------------------------------------------------------------------------


@dataclass(frozen=True)
class EdgeChunk:
    """Consecutive road-edge points of a file.

    Attributes
    ----------
    xyz : (n, 3) float64 points, mapping frame, metres.
    side : (n,) int8, +1 left, -1 right, 0 unknown.
    first_row : data row of the first point (0-based; error messages add 1).
    """

    xyz: NDArray[np.float64]
    side: NDArray[np.int8]
    first_row: int


DEFAULT_CHUNK_POINTS = 1_000_000
"""Points per chunk of :func:`iter_road_edges` (about 40 MB of working memory)."""


def read_road_edges(
    path: str | Path, *, max_points: int | None = None
) -> tuple[NDArray[np.float64], NDArray[np.int8]]:
    """Read all road-edge points of a LAS/LAZ, PLY, CSV, NPY or Parquet file.

    Parameters
    ----------
    path
        Point file; ``x, y, z`` in the mapping frame (metres), optional ``side``
        (strings ``left``/``right``, or integers 1 = left, 2 = right, 0 = unknown;
        -1 is accepted for right).
    max_points
        Refuse files with more points (``None``: no limit); LAS/LAZ, PLY, NPY and Parquet
        are refused from their headers, before the points are read.

    Returns
    -------
    edges : (N, 3) float64 points, mapping frame, metres.
    edge_side : (N,) int8, +1 left, -1 right, 0 unknown.
    """
    chunks = list(iter_road_edges(path, max_points=max_points))
    return (
        np.vstack([c.xyz for c in chunks]),
        np.concatenate([c.side for c in chunks]),
    )


def iter_road_edges(
    path: str | Path, *, chunk_points: int = DEFAULT_CHUNK_POINTS, max_points: int | None = None
) -> Iterator[EdgeChunk]:
    """Read road-edge points in chunks of at most ``chunk_points`` (file order).

    Same formats, checks and messages as :func:`read_road_edges` (a bad value names its
    data row in the whole file); LAS/LAZ are read with laspy's chunk iterator, PLY and NPY
    through memory maps, Parquet by record batches, CSV by pandas chunks. Yields at least
    one chunk, or raises :class:`~roadtwin._errors.InputError`.
    """
    path = Path(path)
    name = path.name.lower()
    if path.stat().st_size == 0:
        msg = f"{path}: file is empty (expected road-edge points x,y,z)"
        raise InputError(msg)
    n = max(1, int(chunk_points))
    limit = max_points if max_points is not None else np.iinfo(np.int64).max
    if name.endswith((".las", ".laz")):
        parts = _las_chunks(path, n, limit)
    elif name.endswith(".ply"):
        parts = _ply_chunks(path, n, limit)
    elif name.endswith(".csv"):
        parts = _csv_chunks(path, n, max_points)
    elif name.endswith(".npy"):
        parts = _npy_chunks(path, n, limit)
    elif name.endswith(".parquet"):
        parts = _parquet_chunks(path, n, limit)
    else:
        msg = f"{path}: unsupported road-edge format (expected one of {', '.join(EDGE_SUFFIXES)})"
        raise InputError(msg)
    row = 0
    for cols, side in parts:
        xyz = stack_columns([float_column(cols[c], path, c, first_row=row) for c in "xyz"])
        if xyz.shape[0] == 0:
            continue
        check_coordinates(xyz, path, first_row=row)
        codes = _side_codes(side, path, xyz.shape[0], first_row=row)
        yield EdgeChunk(xyz, codes, row)
        row += xyz.shape[0]
    if row == 0:
        msg = f"{path}: no points (expected road-edge points x,y,z)"
        raise InputError(msg)


def stack_columns(columns: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """``(n, k)`` array with contiguous columns (Fortran order: no copy to take a column)."""
    out = np.empty((columns[0].size, len(columns)), order="F")
    for k, col in enumerate(columns):
        out[:, k] = col
    return out


def count_road_edges(path: str | Path) -> int | None:
    """Number of points a road-edge file says it holds (LAS/LAZ, PLY, NPY and Parquet
    headers), or ``None`` (CSV, unreadable header): for progress bars only."""
    path = Path(path)
    name = path.name.lower()
    try:
        if name.endswith((".las", ".laz")):
            import laspy

            with laspy.open(path) as reader:
                return int(reader.header.point_count)
        if name.endswith(".npy"):
            return int(np.load(path, mmap_mode="r", allow_pickle=False).shape[0])
        if name.endswith(".parquet"):
            import pyarrow.parquet as pq

            return int(pq.ParquetFile(path).metadata.num_rows)
        if name.endswith(".ply"):
            return int(_ply_header(path).count)
    except Exception:  # only a hint: the reader reports what is wrong
        return None
    return None


def _side_codes(side: Any, path: Path, n: int, *, first_row: int = 0) -> NDArray[np.int8]:
    """Map a ``side`` column (strings or integer codes) to +1 left / -1 right / 0."""
    if side is None:
        return np.zeros(n, np.int8)
    series = side if isinstance(side, pd.Series) else pd.Series(np.asarray(side))
    out = np.zeros(n, np.int8)
    if series.dtype.kind in "iuf":
        vals = series.to_numpy(dtype=np.float64)
        vals = np.where(np.isnan(vals), 0.0, vals)
        ok = np.isin(vals, (0.0, 1.0, 2.0, -1.0))
        if not ok.all():
            row = int(np.argmin(ok))
            msg = (
                f"{path}: data row {first_row + row + 1}, field 'side': {vals[row]:g} is not a "
                "side code "
                "(expected 1 = left, 2 = right, 0 = unknown)"
            )
            raise InputError(msg)
        out[vals == 1.0] = SIDE_LEFT
        out[(vals == 2.0) | (vals == -1.0)] = SIDE_RIGHT
        return out
    text = series.astype("string").str.strip().str.lower().fillna("")
    left = text.isin(["left", "l"]).to_numpy(dtype=bool)
    right = text.isin(["right", "r"]).to_numpy(dtype=bool)
    unknown = text.isin(["", "unknown", "none"]).to_numpy(dtype=bool)
    ok = left | right | unknown
    if not ok.all():
        row = int(np.argmin(ok))
        msg = (
            f"{path}: data row {first_row + row + 1}, column 'side': {series.iloc[row]!r} is "
            "not a side "
            "(expected 'left' or 'right')"
        )
        raise InputError(msg)
    out[left] = SIDE_LEFT
    out[right] = SIDE_RIGHT
    return out


def _too_many(path: Path, count: int, limit: int) -> None:
    if count > limit:
        msg = (
            f"{path}: {count:,} points; files with more than {limit:,} are refused "
            "([load] max_points): thin or split them"
        )
        raise InputError(msg)


def _las_chunks(path: Path, n: int, limit: int) -> Iterator[tuple[dict[str, Any], Any]]:
    import laspy

    try:
        reader = laspy.open(path)
    except Exception as exc:  # laspy raises many kinds on corrupt files
        msg = f"{path}: not a readable LAS/LAZ file ({reason(exc)})"
        raise InputError(msg) from None
    with reader:
        _too_many(path, int(reader.header.point_count), limit)
        names = {d.lower(): d for d in reader.header.point_format.dimension_names}
        side_name = names.get("side")
        chunks = reader.chunk_iterator(n)
        while True:
            try:
                points = next(chunks)
            except StopIteration:
                break
            except Exception as exc:
                msg = f"{path}: not a readable LAS/LAZ file ({reason(exc)})"
                raise InputError(msg) from None
            cols = {"x": np.asarray(points.x), "y": np.asarray(points.y), "z": np.asarray(points.z)}
            yield cols, (np.asarray(points[side_name]) if side_name else None)


def _csv_chunks(path: Path, n: int, limit: int | None) -> Iterator[tuple[dict[str, Any], Any]]:
    what = "columns x,y,z[,side]"
    for df in iter_table(path, what, chunk_rows=n, max_rows=limit):
        require_columns(df.columns, "xyz", path, what)
        yield {c: df[c] for c in "xyz"}, df.get("side")


def _npy_chunks(path: Path, n: int, limit: int) -> Iterator[tuple[dict[str, Any], Any]]:
    try:  # memory-mapped: the header's shape is checked against the file's size
        arr = np.load(path, allow_pickle=False, mmap_mode="r")
    except (ValueError, OSError, EOFError) as exc:
        msg = f"{path}: not a readable .npy array ({reason(exc)})"
        raise InputError(msg) from None
    if arr.ndim >= 1:
        _too_many(path, int(arr.shape[0]), limit)
    if arr.dtype.kind not in "fiub" and not arr.dtype.names:
        msg = f"{path}: array of dtype {arr.dtype}; expected numbers (x,y,z[,side])"
        raise InputError(msg)
    if arr.dtype.names:
        names = {name.lower(): name for name in arr.dtype.names}
        require_columns(names, "xyz", path, "fields x,y,z[,side]")
        for i in range(0, arr.shape[0], n):
            part = arr[i : i + n]
            side = part[names["side"]] if "side" in names else None
            yield {c: np.asarray(part[names[c]]) for c in "xyz"}, side
        return
    if arr.ndim != 2 or arr.shape[1] not in (3, 4):
        msg = (
            f"{path}: array of shape {arr.shape}; expected (N, 3) x,y,z, (N, 4) x,y,z,side "
            "or a structured array with fields x,y,z[,side]"
        )
        raise InputError(msg)
    with_side = arr.shape[1] == 4
    if with_side and not np.isin(np.asarray(arr[:, 3], dtype=float), (0.0, 1.0, 2.0, -1.0)).all():
        warnings.warn(
            f"{path}: 4th column is not a side code (expected 1 = left, 2 = right, "
            "0 = unknown); ignored, sides unknown",
            InputWarning,
            stacklevel=5,
        )
        with_side = False
    for i in range(0, arr.shape[0], n):
        part = np.asarray(arr[i : i + n])
        yield {c: part[:, k] for k, c in enumerate("xyz")}, (part[:, 3] if with_side else None)


def _parquet_chunks(path: Path, n: int, limit: int) -> Iterator[tuple[dict[str, Any], Any]]:
    import pyarrow.parquet as pq

    try:
        file = pq.ParquetFile(path)
        schema = file.schema_arrow
        rows = int(file.metadata.num_rows)
    except Exception as exc:  # pyarrow raises ArrowInvalid/OSError on bad files
        msg = f"{path}: not a readable Parquet file ({reason(exc)})"
        raise InputError(msg) from None
    _too_many(path, rows, limit)
    names = {name.lower(): name for name in schema.names}
    require_columns(names, "xyz", path, "columns x,y,z[,side]")
    wanted = [names[c] for c in ("x", "y", "z", "side") if c in names]
    batches = file.iter_batches(batch_size=n, columns=wanted)
    while True:
        try:
            batch = next(batches)
        except StopIteration:
            break
        except Exception as exc:  # corrupt pages surface only when the data is read
            msg = f"{path}: Parquet data not readable ({reason(exc)})"
            raise InputError(msg) from None
        try:
            cols = {c: batch.column(names[c]).to_numpy(zero_copy_only=False) for c in "xyz"}
            side = batch.column(names["side"]).to_pandas() if "side" in names else None
        except Exception as exc:
            msg = f"{path}: Parquet data not readable ({reason(exc)})"
            raise InputError(msg) from None
        yield cols, side


_PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}


@dataclass(frozen=True)
class _PlyHeader:
    fmt: str
    count: int
    props: list[tuple[str, str | None]]
    body_offset: int
    header_lines: int
    skip_rows: int
    skip_bytes: int


def _ply_header(path: Path) -> _PlyHeader:
    """Parse a PLY header up to the ``vertex`` element (ascii, binary little/big endian)."""
    with path.open("rb") as fh:
        head = fh.read(65536)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        msg = f"{path}: not a PLY file (expected a 'ply' header ending in 'end_header')"
        raise InputError(msg)
    nl = head.find(b"\n", end)
    body_offset = nl + 1
    lines = head[:end].decode("ascii", errors="replace").splitlines()
    fmt = None
    elements: list[tuple[str, int, list[tuple[str, str | None]]]] = []
    for raw in lines[1:]:
        tok = raw.split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        if tok[0] == "format" and len(tok) >= 2:
            fmt = tok[1]
        elif tok[0] == "element" and len(tok) == 3:
            if not tok[2].isdigit():
                msg = f"{path}: PLY header: element count is not a number"
                raise InputError(msg)
            elements.append((tok[1], int(tok[2]), []))
        elif tok[0] == "property" and elements:
            if tok[1] == "list":
                elements[-1][2].append((tok[-1], None))
            elif len(tok) == 3 and tok[1] in _PLY_TYPES:
                elements[-1][2].append((tok[2], _PLY_TYPES[tok[1]]))
            else:
                msg = (
                    f"{path}: PLY header: a property of unknown type "
                    f"(expected {', '.join(_PLY_TYPES)})"
                )
                raise InputError(msg)
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        msg = f"{path}: PLY format {fmt!r}; expected ascii or binary_little/big_endian"
        raise InputError(msg)
    skip_rows = 0
    skip_bytes = 0
    vertex = None
    for name, count, props in elements:
        if name == "vertex":
            vertex = (count, props)
            break
        if any(t is None for _, t in props) and fmt != "ascii":
            msg = f"{path}: PLY element {name!r} with list properties before 'vertex'"
            raise InputError(msg)
        skip_rows += count
        skip_bytes += count * sum(np.dtype(t).itemsize for _, t in props if t is not None)
    if vertex is None:
        msg = f"{path}: PLY file has no 'vertex' element (expected x,y,z vertices)"
        raise InputError(msg)
    count, props = vertex
    return _PlyHeader(
        fmt,
        count,
        props,
        body_offset,
        len(head[:body_offset].splitlines()),
        skip_rows,
        skip_bytes,
    )


def _ply_chunks(path: Path, n: int, limit: int) -> Iterator[tuple[dict[str, Any], Any]]:
    """Vectorised PLY reader (ascii, binary little/big endian) for the ``vertex`` element."""
    hdr = _ply_header(path)
    count, props = hdr.count, hdr.props
    if any(t is None for _, t in props):
        msg = f"{path}: PLY 'vertex' element has list properties; expected scalar x,y,z[,side]"
        raise InputError(msg)
    names = [p.lower() for p, _ in props]
    require_columns(names, "xyz", path, "vertex properties x,y,z[,side]")
    if count == 0:
        msg = f"{path}: PLY file has 0 vertices (expected road-edge points)"
        raise InputError(msg)
    _too_many(path, count, limit)
    if hdr.fmt == "ascii":
        seen = 0
        try:
            reader = pd.read_csv(
                path,
                sep=r"\s+",
                header=None,
                skiprows=hdr.header_lines + hdr.skip_rows,
                nrows=count,
                names=names,
                usecols=range(len(names)),
                engine="c",
                chunksize=n,
            )
            with reader:
                for df in reader:
                    seen += df.shape[0]
                    yield {c: df[c] for c in "xyz"}, df.get("side")
        except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
            msg = f"{path}: PLY ascii body not readable ({reason(exc)})"
            raise InputError(msg) from None
        if seen != count:
            msg = f"{path}: PLY header says {count} vertices, body has {seen}"
            raise InputError(msg)
        return
    endian = "<" if hdr.fmt == "binary_little_endian" else ">"
    dtype = np.dtype([(p.lower(), endian + t) for p, t in props])  # type: ignore[operator]
    size = path.stat().st_size
    need = hdr.body_offset + hdr.skip_bytes + count * dtype.itemsize
    if size < need:
        msg = (
            f"{path}: PLY body too short: header says {count} vertices of {dtype.itemsize} "
            f"bytes, file has {size - hdr.body_offset - hdr.skip_bytes} bytes of vertex data"
        )
        raise InputError(msg)
    data = np.memmap(
        path, dtype=dtype, mode="r", offset=hdr.body_offset + hdr.skip_bytes, shape=(count,)
    )
    for i in range(0, count, n):
        part = np.asarray(data[i : i + n])
        cols = {c: part[c].astype(np.float64) for c in "xyz"}
        yield cols, (part["side"] if "side" in names else None)
