"""A generated corpus of broken and hostile inputs for the ``roadtwin`` CLI (issue 13).

Every case starts from the same simulated run (the bundled ``straight_curve_2km``) and a map
built from it, copied into the case's own folder, and breaks one thing: a table truncated,
corrupted, with swapped or missing columns, NaN or huge values, the run in the wrong CRS or
units, hostile XML (billion laughs, external and parameter entities, XInclude) in every XML
reader, files named outside the run folder, bad ``--config`` values, output folders that
cannot or must not be written. Cases are generated as the cross product of mutation
families and the files or keys they apply to, not written one by one.

A :class:`Case` says which command runs on the broken input, the exit code expected, and a
piece of text the one-line error must contain (the file, table or key at fault). The
contract every case is held to (``tests/test_corpus.py``, ``benchmarks/corpus.py``):

* the exit code is the expected one (2 for bad input) and no traceback is printed;
* bad input ends with exactly one ``roadtwin: error: ...`` line on stderr naming the file;
  every other stderr line is a ``roadtwin: warning: ...`` line (no progress-bar garbage);
* nothing is left behind: no temporary files, no partial outputs, the input folder is
  unchanged (no clobbered input);
* the content of the secret file :data:`CANARY` never appears in stdout, stderr or any
  written file, whatever the hostile input points at.
"""

from __future__ import annotations

import bz2
import gzip
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

CANARY = "ROADTWIN-CANARY-7f3a9c"
"""Content of ``secret.txt`` beside every case's run folder; must never leak."""


@dataclass(frozen=True)
class Dirs:
    """Paths of one case: ``root/run`` (the run), ``root/out``, ``root/map.xodr``,
    ``root/secret.txt`` (outside the run folder)."""

    root: Path

    @property
    def run(self) -> Path:
        return self.root / "run"

    @property
    def out(self) -> Path:
        return self.root / "out"

    @property
    def map(self) -> Path:
        return self.root / "map.xodr"

    @property
    def secret(self) -> Path:
        return self.root / "secret.txt"

    @property
    def config(self) -> Path:
        return self.root / "config.toml"


Mutate = Callable[[Dirs], None]
Argv = Callable[[Dirs], list[str]]


@dataclass(frozen=True)
class Case:
    """One broken input and the command run on it.

    ``expect`` is the text the error line must contain (usually the name of the file at
    fault); ``exit_code`` 2 means "bad input, one error line", 0 or 1 a command that runs
    (a warning is allowed). ``writes`` lists output files that must exist after an exit 0/1.
    """

    name: str
    mutate: Mutate
    argv: Argv
    exit_code: int = 2
    expect: str | Callable[[Dirs], str] = ""
    writes: tuple[str, ...] = ()
    subprocess_only: bool = False
    tags: frozenset[str] = field(default_factory=frozenset)

    def expected_text(self, d: Dirs) -> str:
        return self.expect(d) if callable(self.expect) else self.expect


# ---------------------------------------------------------------------------
# building blocks
# ---------------------------------------------------------------------------


def _seed(name: str) -> int:
    return int.from_bytes(name.encode()[:8].ljust(8, b"\0"), "little") % (2**32)


def _edit_toml(old: str, new: str) -> Mutate:
    def apply(d: Dirs) -> None:
        p = d.run / "run.toml"
        text = p.read_text(encoding="utf-8")
        assert old in text, (old, text)
        p.write_text(text.replace(old, new, 1), encoding="utf-8")

    return apply


def _set_file(key: str, value: str | Callable[[Dirs], str]) -> Mutate:
    """Point ``[files] key`` at ``value`` (a TOML value, e.g. ``'"x.csv"'``)."""

    def apply(d: Dirs) -> None:
        text = (d.run / "run.toml").read_text(encoding="utf-8")
        lines = []
        for line in text.splitlines():
            if line.split("=")[0].strip() == key:
                v = value(d) if callable(value) else value
                line = f"{key} = {v}"
            lines.append(line)
        (d.run / "run.toml").write_text("\n".join(lines) + "\n", encoding="utf-8")

    return apply


def _csv(name: str, edit: Callable[[pd.DataFrame], pd.DataFrame]) -> Mutate:
    def apply(d: Dirs) -> None:
        path = d.run / name
        df = pd.read_csv(path)
        edit(df).to_csv(path, index=False)

    return apply


def _bytes(name: str, make: Callable[[bytes], bytes]) -> Mutate:
    def apply(d: Dirs) -> None:
        path = d.run / name
        path.write_bytes(make(path.read_bytes()))

    return apply


def _seq(*steps: Mutate) -> Mutate:
    def apply(d: Dirs) -> None:
        for step in steps:
            step(d)

    return apply


def _garbage(n: int, seed: int) -> bytes:
    return np.random.default_rng(seed).integers(0, 256, n, dtype=np.uint8).tobytes()


def _truncate_mid_row(data: bytes) -> bytes:
    """Cut inside the first field of a row past 60 % of the file (a copy that stopped)."""
    cut = data.index(b"\n", int(len(data) * 0.6)) + 2
    return data[:cut]


def _header_only(data: bytes) -> bytes:
    return data.split(b"\n", 1)[0] + b"\n"


# edge file conversions: the simulated run has LAZ edges; other formats are made from it


def _edges_xyz_side(d: Dirs) -> tuple[np.ndarray, np.ndarray]:
    import laspy

    las = laspy.read(d.run / "road_edges.laz")
    xyz = np.column_stack([las.x, las.y, las.z]).astype(float)
    names = {n.lower(): n for n in las.point_format.dimension_names}
    side = np.asarray(las[names["side"]]) if "side" in names else np.zeros(len(xyz))
    return xyz, side


def _edges_as(fmt: str) -> Mutate:
    def apply(d: Dirs) -> None:
        xyz, side = _edges_xyz_side(d)
        name = f"road_edges.{fmt}"
        path = d.run / name
        if fmt == "csv":
            pd.DataFrame({"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "side": side}).to_csv(
                path, index=False
            )
        elif fmt == "npy":
            np.save(path, np.column_stack([xyz, side]))
        elif fmt == "parquet":
            pd.DataFrame({"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}).to_parquet(
                path, row_group_size=2000
            )
        elif fmt == "ply":
            head = (
                f"ply\nformat binary_little_endian 1.0\nelement vertex {len(xyz)}\n"
                "property double x\nproperty double y\nproperty double z\nend_header\n"
            )
            path.write_bytes(head.encode() + xyz.astype("<f8").tobytes())
        (d.run / "road_edges.laz").unlink()
        _set_file("road_edges", f'"{name}"')(d)

    return apply


# ---------------------------------------------------------------------------
# hostile XML
# ---------------------------------------------------------------------------


def _dtd_external(d: Dirs) -> str:
    return f'<!ENTITY leak SYSTEM "file://{d.secret}">'


def _dtd_parameter(d: Dirs) -> str:
    # the classic out-of-band trick: an external parameter entity defines an internal
    # entity holding the secret file's content
    evil = d.root / "evil.dtd"
    evil.write_text(
        f'<!ENTITY % file SYSTEM "file://{d.secret}">\n'
        "<!ENTITY % all \"<!ENTITY leak '%file;'>\">\n%all;\n",
        encoding="utf-8",
    )
    return f'<!ENTITY % pe SYSTEM "file://{evil}"> %pe;'


def _dtd_laughs(d: Dirs) -> str:
    ents = ['<!ENTITY l0 "LOL-LOL-LOL-LOL-LOL-LOL-LOL-LOL">']
    for i in range(1, 10):
        ents.append(f'<!ENTITY l{i} "{f"&l{i - 1};" * 10}">')
    ents.append('<!ENTITY leak "&l9;">')
    return "".join(ents)


XML_ATTACKS: dict[str, Callable[[Dirs], str] | None] = {
    "billion_laughs": _dtd_laughs,
    "external_entity": _dtd_external,
    "parameter_entity": _dtd_parameter,
    "xinclude": None,  # no DTD: an XInclude element pulling the secret in as text
}


def _hostile_xml(xml: str, root_tag: str, attack: str, d: Dirs, *, target: str) -> str:
    """Insert ``attack`` into an XML document: a DTD before ``root_tag`` and a reference
    to ``&leak;`` (or an ``xi:include`` of the secret) inside the element ``target``
    (``<target>`` text)."""
    make = XML_ATTACKS[attack]
    body = xml.split("?>", 1)[1] if xml.lstrip().startswith("<?xml") else xml
    decl = '<?xml version="1.0" encoding="UTF-8"?>\n'
    if make is not None:
        head = f"{decl}<!DOCTYPE {root_tag} [{make(d)}]>"
        ref = "&leak;"
    else:
        head = decl
        xi = 'xmlns:xi="http://www.w3.org/2001/XInclude"'
        ref = f'<xi:include {xi} href="file://{d.secret}" parse="text"/>'
    if "@" in target and make is not None:  # an attribute value (internal entities only)
        tag, attr = target.split("@")
        i = body.index(f"<{tag} ")
        a = body.index(f'{attr}="', i) + len(attr) + 2
        b = body.index('"', a)
        return head + body[:a] + ref + body[b:]
    target = target.split("@")[0] if "@" in target else target
    i = body.index(f"<{target}")
    j = body.index(">", i) + 1
    if body[j - 2] == "/":  # <target .../> -> <target ...>ref</target>
        body = body[: j - 2] + ">" + ref + f"</{target}>" + body[j:]
    else:
        body = body[:j] + ref + body[j:]
    return head + body


# ---------------------------------------------------------------------------
# the families
# ---------------------------------------------------------------------------


def _build(d: Dirs, *extra: str) -> list[str]:
    return ["build", str(d.run), "-o", str(d.out), "--no-check", *extra]


def _table_cases() -> list[Case]:
    """Corruptions of the CSV tables (and of CSV road edges)."""
    cases: list[Case] = []

    def nan_row(col: str, value) -> Callable[[pd.DataFrame], pd.DataFrame]:
        def edit(df: pd.DataFrame) -> pd.DataFrame:
            df[col] = df[col].astype(object)
            df.loc[len(df) // 2, col] = value
            return df

        return edit

    def swap(a: str, b: str) -> Callable[[pd.DataFrame], pd.DataFrame]:
        return lambda df: df.rename(columns={a: b, b: a})

    def drop(col: str) -> Callable[[pd.DataFrame], pd.DataFrame]:
        return lambda df: df.drop(columns=[col])

    tables = {
        "trajectory.csv": ("x", "yaw"),
        "lane_samples.csv": ("x", "frame"),
        "road_edges.csv": ("x", "z"),
    }
    for table, (num_col, other_col) in tables.items():
        prep: Mutate = _edges_as("csv") if table == "road_edges.csv" else _seq()
        raw = {
            "empty": lambda b: b"",
            "header_only": _header_only,
            "truncated_mid_row": _truncate_mid_row,
            "garbage": lambda b, t=table: _garbage(4096, _seed(t)),
            "not_utf8": lambda b: b"\xff\xfe\xfa" + b.replace(b",", b"\xe9,", 2),
            "nul_bytes": lambda b: b[:200] + b"\0" * 64 + b[200:],
        }
        for kind, make in raw.items():
            cases.append(
                Case(
                    f"table/{table}/{kind}",
                    _seq(prep, _bytes(table, make)),
                    _build,
                    expect=table,
                )
            )
        edits = {
            "nan": nan_row(num_col, float("nan")),
            "inf": nan_row(num_col, float("inf")),
            "huge_1e308": nan_row(num_col, 1e308),
            "text": nan_row(num_col, "twelve"),
            f"missing_{other_col}": drop(other_col),
            "duplicate_header_row": lambda df: pd.concat(
                [df.iloc[:10], pd.DataFrame([df.columns], columns=df.columns), df.iloc[10:]]
            ),
        }
        for kind, edit in edits.items():
            cases.append(
                Case(f"table/{table}/{kind}", _seq(prep, _csv(table, edit)), _build, expect=table)
            )
    cases.append(
        Case(
            "table/trajectory.csv/swapped_x_y",
            _csv("trajectory.csv", swap("x", "y")),
            _build,
            expect="trajectory.csv",
        )
    )
    cases.append(
        Case(
            "table/trajectory.csv/swapped_t_frame",
            _csv("trajectory.csv", swap("t", "frame")),
            _build,
            expect="trajectory.csv",
        )
    )
    return cases


def _plausibility_cases() -> list[Case]:
    """Data in the wrong frame, units or convention."""

    def traj(edit: Callable[[pd.DataFrame], pd.DataFrame]) -> Mutate:
        return _csv("trajectory.csv", edit)

    def scale_all(factor: float) -> Mutate:
        def apply(d: Dirs) -> None:
            for name in ("trajectory.csv",):
                df = pd.read_csv(d.run / name)
                df[["x", "y", "z"]] *= factor
                df.to_csv(d.run / name, index=False)
            _edges_as("csv")(d)
            df = pd.read_csv(d.run / "road_edges.csv")
            df[["x", "y", "z"]] *= factor
            df.to_csv(d.run / "road_edges.csv", index=False)

        return apply

    def shift_all(offset: float) -> Mutate:
        def apply(d: Dirs) -> None:
            df = pd.read_csv(d.run / "trajectory.csv")
            df[["x", "y"]] += offset
            df.to_csv(d.run / "trajectory.csv", index=False)
            _edges_as("csv")(d)
            df = pd.read_csv(d.run / "road_edges.csv")
            df[["x", "y"]] += offset
            df.to_csv(d.run / "road_edges.csv", index=False)

        return apply

    def lonlat_in_xy(d: Dirs) -> None:
        from roadtwin.frames import MappingFrame, Origin

        frame = MappingFrame(Origin(49.98, 11.62, 420.0))
        df = pd.read_csv(d.run / "trajectory.csv")
        lon, lat = frame.to_lonlat(df["x"], df["y"])
        df["x"], df["y"] = lon, lat
        df.to_csv(d.run / "trajectory.csv", index=False)

    def compass(df: pd.DataFrame) -> pd.DataFrame:
        df["yaw"] = np.pi / 2 - df["yaw"]
        return df

    def degrees(df: pd.DataFrame) -> pd.DataFrame:
        df["yaw"] = np.degrees(df["yaw"])
        return df

    def standing(df: pd.DataFrame) -> pd.DataFrame:
        df["x"], df["y"] = df["x"].iloc[0], df["y"].iloc[0]
        return df

    def same_edges(d: Dirs) -> None:
        _edges_as("csv")(d)
        df = pd.read_csv(d.run / "road_edges.csv")
        df[["x", "y", "z"]] = df[["x", "y", "z"]].iloc[0].to_numpy()
        df.to_csv(d.run / "road_edges.csv", index=False)

    def yaw_reversed(df: pd.DataFrame) -> pd.DataFrame:
        df["yaw"] = df["yaw"] + np.pi
        return df

    T = "trajectory.csv"
    return [
        Case("plausible/compass_heading", traj(compass), _build, expect=T),
        Case("plausible/yaw_degrees", traj(degrees), _build, expect=T),
        Case("plausible/yaw_reversed", traj(yaw_reversed), _build, expect=T),
        Case("plausible/standing_vehicle", traj(standing), _build, expect=T),
        Case("plausible/lonlat_in_xy", lonlat_in_xy, _build, expect=T),
        Case("plausible/scaled_1e300", scale_all(1e300), _build, expect=T),
        Case("plausible/far_from_origin_1e15", shift_all(1e15), _build, expect=T),
        Case("plausible/far_from_origin_1e7", shift_all(1e7), _build, expect=T),
        Case("plausible/all_edges_identical", same_edges, _build, expect="road_edges.csv"),
        Case(
            "plausible/latlon_swapped",
            _seq(
                _edit_toml("lat = 49.98", "lat = 11.62"), _edit_toml("lon = 11.62", "lon = 49.98")
            ),
            _build,
            expect="run.toml",
        ),
        Case(
            "plausible/wrong_crs_utm",
            _edit_toml('crs = "local"', 'crs = "EPSG:32633"'),
            _build,
            expect="run.toml",
        ),
    ]


def _edge_format_cases() -> list[Case]:
    """Corrupt road-edge files of every binary format."""
    cases = [
        Case(
            "edges/laz/truncated",
            _bytes("road_edges.laz", lambda b: b[: len(b) // 2]),
            _build,
            expect="road_edges.laz",
        ),
        Case(
            "edges/laz/garbage",
            _bytes("road_edges.laz", lambda b: _garbage(len(b), 11)),
            _build,
            expect="road_edges.laz",
        ),
        Case(
            "edges/laz/header_count_huge",
            _bytes("road_edges.laz", lambda b: b[:107] + (2**40).to_bytes(8, "little") + b[115:]),
            _build,
            expect="road_edges.laz",
        ),
        Case(
            "edges/laz/body_corrupt",
            _bytes("road_edges.laz", lambda b: b[:2000] + _garbage(len(b) - 4000, 12) + b[-2000:]),
            _build,
            expect="road_edges.laz",
        ),
    ]

    def ply_count(n: int) -> Mutate:
        def apply(d: Dirs) -> None:
            p = d.run / "road_edges.ply"
            data = p.read_bytes()
            head, body = data.split(b"end_header\n", 1)
            lines = [
                f"element vertex {n}".encode() if ln.startswith(b"element vertex") else ln
                for ln in head.split(b"\n")
            ]
            p.write_bytes(b"\n".join(lines) + b"end_header\n" + body)

        return apply

    def npy_object(d: Dirs) -> None:
        np.save(d.run / "road_edges.npy", np.array([{"x": 1}] * 10, dtype=object))

    def npy_huge_shape(d: Dirs) -> None:
        p = d.run / "road_edges.npy"
        data = p.read_bytes()
        hlen = int.from_bytes(data[8:10], "little")
        header = data[10 : 10 + hlen].decode("latin1")
        import re

        new = re.sub(r"\(\d+, 4\)", "(4000000000000, 4)", header)
        new = new.rstrip("\n").ljust(hlen - 1) + "\n"
        p.write_bytes(data[:10] + new.encode("latin1") + data[10 + hlen :])

    def npy_strings(d: Dirs) -> None:
        np.save(d.run / "road_edges.npy", np.array([["a", "b", "c"]] * 10))

    def parquet_scramble(d: Dirs) -> None:
        p = d.run / "road_edges.parquet"
        data = bytearray(p.read_bytes())
        rng = np.random.default_rng(5)
        start, stop = 64, len(data) - 2048
        idx = rng.integers(start, stop, size=(stop - start) // 8)
        for i in idx.tolist():
            data[i] = (data[i] + 97) % 256
        p.write_bytes(bytes(data))

    cases += [
        Case(
            "edges/ply/count_huge",
            _seq(_edges_as("ply"), ply_count(10**12)),
            _build,
            expect="road_edges.ply",
        ),
        Case(
            "edges/ply/count_short",
            _seq(_edges_as("ply"), ply_count(10**7)),
            _build,
            expect="road_edges.ply",
        ),
        Case(
            "edges/ply/garbage",
            _seq(_edges_as("ply"), _bytes("road_edges.ply", lambda b: _garbage(2000, 3))),
            _build,
            expect="road_edges.ply",
        ),
        Case(
            "edges/npy/object_array",
            _seq(_edges_as("npy"), npy_object),
            _build,
            expect="road_edges.npy",
        ),
        Case(
            "edges/npy/huge_shape",
            _seq(_edges_as("npy"), npy_huge_shape),
            _build,
            expect="road_edges.npy",
        ),
        Case(
            "edges/npy/strings",
            _seq(_edges_as("npy"), npy_strings),
            _build,
            expect="road_edges.npy",
        ),
        Case(
            "edges/npy/truncated",
            _seq(_edges_as("npy"), _bytes("road_edges.npy", lambda b: b[: len(b) // 2])),
            _build,
            expect="road_edges.npy",
        ),
        Case(
            "edges/parquet/scrambled_pages",
            _seq(_edges_as("parquet"), parquet_scramble),
            _build,
            expect="road_edges.parquet",
        ),
        Case(
            "edges/parquet/truncated",
            _seq(_edges_as("parquet"), _bytes("road_edges.parquet", lambda b: b[: len(b) // 2])),
            _build,
            expect="road_edges.parquet",
        ),
    ]
    return cases


def _manifest_cases() -> list[Case]:
    """run.toml: broken syntax, values and file references (inside/outside the run)."""
    M = "run.toml"
    cases = [
        Case("manifest/missing", lambda d: (d.run / M).unlink(), _build, expect=M),
        Case("manifest/empty", _bytes(M, lambda b: b""), _build, expect=M),
        Case("manifest/garbage", _bytes(M, lambda b: _garbage(300, 1)), _build, expect=M),
        Case("manifest/not_utf8", _bytes(M, lambda b: b"\xff" + b), _build, expect=M),
        Case("manifest/truncated", _bytes(M, lambda b: b[: len(b) // 2]), _build, expect=M),
        Case(
            "manifest/is_directory",
            _seq(lambda d: (d.run / M).unlink(), lambda d: (d.run / M).mkdir()),
            _build,
            expect=M,
        ),
        Case(
            "manifest/given_as_file",
            _seq(),
            lambda d: ["build", str(d.run / M), "-o", str(d.out), "--no-check"],
            exit_code=0,
            writes=("map.xodr",),
        ),
        Case("manifest/run_dir_missing", lambda d: shutil.rmtree(d.run), _build, expect="run"),
        Case(
            "manifest/run_dir_is_file",
            _seq(lambda d: shutil.rmtree(d.run), lambda d: d.run.write_text("x")),
            _build,
            expect="run",
        ),
    ]
    values = {
        "lat_nan": ("lat = 49.98", "lat = nan"),
        "lat_text": ("lat = 49.98", 'lat = "north"'),
        "lat_1e308": ("lat = 49.98", "lat = 1e308"),
        "lon_inf": ("lon = 11.62", "lon = inf"),
        "alt_text": ("alt = 420.0", 'alt = "high"'),
        "crs_geographic": ('crs = "local"', 'crs = "EPSG:4326"'),
        "crs_garbage": ('crs = "local"', 'crs = "no such crs"'),
        "crs_number": ('crs = "local"', "crs = 4326"),
        "pose_height_text": ("pose_height = 0.0", 'pose_height = "x"'),
        "pose_height_nan": ("pose_height = 0.0", "pose_height = nan"),
        "pose_height_1e308": ("pose_height = 0.0", "pose_height = 1e308"),
        "side_middle": ('side = "right"', 'side = "middle"'),
        "files_not_table": ("[files]", "files = 3\n[files2]"),
    }
    for kind, (old, new) in values.items():
        cases.append(Case(f"manifest/{kind}", _edit_toml(old, new), _build, expect=M))

    outside = {
        "absolute_secret": lambda d: f'"{d.secret}"',
        "dotdot_secret": lambda d: '"../secret.txt"',
        "etc_passwd": lambda d: '"/etc/passwd"',
        "dev_zero": lambda d: '"/dev/zero"',
        "dev_urandom": lambda d: '"/dev/urandom"',
        "nonexistent": lambda d: '"nope.csv"',
        "directory": lambda d: '"."',
        "list_value": lambda d: '["a.csv", "b.csv"]',
        "the_manifest": lambda d: '"run.toml"',
    }
    for key in ("trajectory", "lane_samples", "road_edges", "osm"):
        for kind, value in outside.items():
            if key == "osm" and kind in ("list_value", "the_manifest"):
                continue
            cases.append(
                Case(f"files/{key}/{kind}", _set_file(key, value), _build, expect="run.toml")
            )

    def symlink_out(d: Dirs) -> None:
        (d.run / "lane_samples.csv").unlink()
        (d.run / "lane_samples.csv").symlink_to(d.secret)

    def fifo(d: Dirs) -> None:
        import os

        (d.run / "lane_samples.csv").unlink()
        os.mkfifo(d.run / "lane_samples.csv")

    cases.append(Case("files/lane_samples/symlink_outside", symlink_out, _build, expect="run.toml"))
    cases.append(Case("files/lane_samples/fifo", fifo, _build, expect="lane_samples.csv"))
    return cases


def _osm_cases() -> list[Case]:
    """OSM extracts: hostile XML in every compression, corrupt files."""
    cases: list[Case] = []
    compress = {
        ".osm": lambda b: b,
        ".osm.gz": lambda b: gzip.compress(b, mtime=0),
        ".osm.bz2": bz2.compress,
    }

    def hostile(attack: str, suffix: str) -> Mutate:
        def apply(d: Dirs) -> None:
            xml = (d.run / "map.osm").read_text(encoding="utf-8")
            bad = _hostile_xml(xml, "osm", attack, d, target="tag")
            name = f"map{suffix}"
            (d.run / "map.osm").unlink()
            (d.run / name).write_bytes(compress[suffix](bad.encode("utf-8")))
            _set_file("osm", f'"{name}"')(d)

        return apply

    for attack in XML_ATTACKS:
        for suffix in compress:
            # libosmium refuses entity declarations, and an element inside <tag>
            cases.append(
                Case(
                    f"osm/{attack}{suffix}", hostile(attack, suffix), _build, expect=f"map{suffix}"
                )
            )

    def rename_osm(suffix: str, make: Callable[[bytes], bytes]) -> Mutate:
        def apply(d: Dirs) -> None:
            data = (d.run / "map.osm").read_bytes()
            (d.run / "map.osm").unlink()
            (d.run / f"map{suffix}").write_bytes(make(data))
            _set_file("osm", f'"map{suffix}"')(d)

        return apply

    corrupt = {
        "truncated.osm": (".osm", lambda b: b[: len(b) // 2]),
        "garbage.osm": (".osm", lambda b: _garbage(3000, 21)),
        "garbage.osm.gz": (".osm.gz", lambda b: _garbage(3000, 22)),
        "truncated.osm.gz": (".osm.gz", lambda b: gzip.compress(b, mtime=0)[:300]),
        "garbage.osm.bz2": (".osm.bz2", lambda b: _garbage(3000, 23)),
        "garbage.osm.pbf": (".osm.pbf", lambda b: _garbage(3000, 24)),
        "xml_named_pbf.osm.pbf": (".osm.pbf", lambda b: b),
        "no_data.osm": (".osm", lambda b: b'<?xml version="1.0"?>\n<osm version="0.6"></osm>\n'),
        "lat_out_of_range.osm": (
            ".osm",
            lambda b: b.replace(b'lat="49.9799489"', b'lat="1000.0"'),
        ),
    }
    for kind, (suffix, make) in corrupt.items():
        cases.append(Case(f"osm/{kind}", rename_osm(suffix, make), _build, expect=f"map{suffix}"))
    return cases


def _config_cases() -> list[Case]:
    """``--config`` files: wrong types, non-finite and out-of-range values, bad tables."""

    def config(text: str | bytes) -> Mutate:
        def apply(d: Dirs) -> None:
            data = text.encode() if isinstance(text, str) else text
            d.config.write_bytes(data)

        return apply

    def argv(d: Dirs) -> list[str]:
        return [*_build(d), "--config", str(d.config)]

    keys = {
        "load.osm_buffer_m": ("load", "osm_buffer_m"),
        "load.max_point_distance_m": ("load", "max_point_distance_m"),
        "mainline.grid_step_m": ("mainline", "grid_step_m"),
        "mainline.paper_max_clusters": ("mainline", "paper_max_clusters"),
        "ramps.lane_width_m": ("ramps", "lane_width_m"),
        "topology.junction_length_m": ("topology", "junction_length_m"),
        "evaluation.truth_step_m": ("evaluation", "truth_step_m"),
    }
    bad_values = {
        "nan": "nan",
        "inf": "inf",
        "negative": "-1.0",
        "zero": "0",
        "string": '"x"',
        "bool": "true",
        "list": "[1, 2]",
    }
    cases = []
    for label, (table, key) in keys.items():
        for kind, value in bad_values.items():
            cases.append(
                Case(
                    f"config/{label}/{kind}",
                    config(f"[{table}]\n{key} = {value}\n"),
                    argv,
                    expect=f"[{table}] {key}",
                )
            )
    others = {
        "method_unknown": ('[mainline]\nmethod = "magic"\n', "[mainline] method"),
        "junctions_number": ("[topology]\njunctions = 3\n", "[topology] junctions"),
        "seed_float": ("[mainline]\nseed = 1.5\n", "[mainline] seed"),
        "use_evidence_string": ('[ramps]\nuse_evidence = "yes"\n', "[ramps] use_evidence"),
        "unknown_key": ("[load]\nbuffer = 3\n", "buffer"),
        "unknown_table": ("[loading]\nx = 1\n", "loading"),
        "table_not_table": ("load = 3\n", "[load]"),
        "garbage": (_garbage(200, 31), "config.toml"),
        "not_utf8": (b"[load]\nosm_buffer_m = 400 # \xff\n", "config.toml"),
    }
    for kind, (text, expect) in others.items():
        cases.append(Case(f"config/{kind}", config(text), argv, expect=expect))
    cases.append(Case("config/missing", _seq(), argv, expect="config.toml"))
    cases.append(
        Case("config/is_directory", lambda d: d.config.mkdir(), argv, expect="config.toml")
    )
    return cases


def _output_cases() -> list[Case]:
    """Output folders that must not or cannot be written."""

    def out_is_file(d: Dirs) -> None:
        d.out.write_text("I am a file")

    def lanes_in_out(d: Dirs) -> None:
        # the clobbering case: an input named like an output, in the default
        # output folder RUN_DIR/out
        (d.run / "out").mkdir()
        shutil.move(d.run / "lane_samples.csv", d.run / "out" / "map.geojson")
        _set_file("lane_samples", '"out/map.geojson"')(d)

    def readonly(d: Dirs) -> None:
        d.out.mkdir()
        d.out.chmod(0o555)

    cases = [
        Case(
            "output/is_input_folder",
            _seq(),
            lambda d: ["build", str(d.run), "-o", str(d.run), "--no-check"],
            expect="run",
        ),
        Case(
            "output/contains_an_input",
            lanes_in_out,
            lambda d: ["build", str(d.run), "--no-check"],
            expect="map.geojson",
        ),
        Case("output/is_a_file", out_is_file, _build, expect="out"),
        Case(
            "output/parent_is_a_file",
            out_is_file,
            lambda d: ["build", str(d.run), "-o", str(d.out / "sub"), "--no-check"],
            expect="out",
        ),
        Case(
            "output/read_only_filesystem",
            _seq(),
            lambda d: ["build", str(d.run), "-o", "/proc/roadtwin-out", "--no-check"],
            expect="/proc/roadtwin-out",
        ),
        Case(
            "output/read_only_folder", readonly, _build, expect="out", tags=frozenset({"nonroot"})
        ),
        Case(
            "output/inspect_png_is_input",
            _seq(),
            lambda d: ["inspect", str(d.run), "-o", str(d.run / "trajectory.csv")],
            expect="trajectory.csv",
        ),
        Case(
            "output/inspect_png_parent_is_file",
            out_is_file,
            lambda d: ["inspect", str(d.run), "-o", str(d.out / "overview.png")],
            expect="out",
        ),
        Case(
            "output/evaluate_into_run_folder",
            _seq(),
            lambda d: ["evaluate", str(d.map), str(d.run), "-o", str(d.run)],
            expect="run",
        ),
        Case(
            "output/evaluate_report_is_file",
            out_is_file,
            lambda d: ["evaluate", str(d.map), str(d.run), "-o", str(d.out)],
            expect="out",
        ),
        Case(
            "output/disk_full",
            _seq(),
            _build,
            expect="out",
            subprocess_only=True,
            tags=frozenset({"fsize"}),
        ),
    ]
    return cases


def _xodr_cases() -> list[Case]:
    """Maps read by ``check`` and ``evaluate`` (and truth files read by ``evaluate``)."""

    def edit_map(edit: Callable[[str], str]) -> Mutate:
        def apply(d: Dirs) -> None:
            d.map.write_text(edit(d.map.read_text(encoding="utf-8")), encoding="utf-8")

        return apply

    def hostile_map(attack: str, path: Callable[[Dirs], Path]) -> Mutate:
        def apply(d: Dirs) -> None:
            p = path(d)
            xml = p.read_text(encoding="utf-8")
            # the secret as a link target: a dangling link is printed by check (the issue's
            # leak); XInclude cannot sit in an attribute and goes into <geoReference>
            target = "geoReference" if attack == "xinclude" else "successor@elementId"
            p.write_text(_hostile_xml(xml, "OpenDRIVE", attack, d, target=target), encoding="utf-8")

        return apply

    def first_attr(tag: str, attr: str, value: str) -> Callable[[str], str]:
        import re

        def edit(text: str) -> str:
            pattern = re.compile(rf'(<{tag}\b[^>]*?\s{attr}=")[^"]*(")')
            new, n = pattern.subn(rf"\g<1>{value}\g<2>", text, count=1)
            assert n == 1, (tag, attr)
            return new

        return edit

    def check(d: Dirs) -> list[str]:
        return ["check", str(d.map), "--no-external"]

    def evaluate(d: Dirs) -> list[str]:
        return ["evaluate", str(d.map), str(d.run), "-o", str(d.out)]

    cases: list[Case] = []
    for attack in XML_ATTACKS:
        for cmd_name, argv in (("check", check), ("evaluate", evaluate)):
            cases.append(
                Case(
                    f"xodr/{cmd_name}/{attack}",
                    hostile_map(attack, lambda d: d.map),
                    argv,
                    # an xi:include element inside <geoReference> is not expanded: the
                    # geoReference is then empty, which is only a warning
                    exit_code=0 if attack == "xinclude" else 2,
                    expect="map.xodr",
                    writes=("report.json",)
                    if cmd_name == "evaluate" and attack == "xinclude"
                    else (),
                )
            )
        cases.append(
            Case(
                f"truth/xodr/{attack}",
                hostile_map(attack, lambda d: d.run / "truth.xodr"),
                evaluate,
                exit_code=0 if attack == "xinclude" else 2,
                expect="truth.xodr",
                writes=("report.json",) if attack == "xinclude" else (),
            )
        )
    edits = {
        "empty": lambda t: "",
        "truncated": lambda t: t[: len(t) // 2],
        "not_opendrive": lambda t: '<?xml version="1.0"?><kml/>',
        "no_roads": lambda t: t[: t.index("<road ")] + "</OpenDRIVE>\n",
        "length_inf": first_attr("geometry", "length", "inf"),
        "length_1e308": first_attr("geometry", "length", "1e308"),
        "length_nan": first_attr("geometry", "length", "NaN"),
        "length_negative": first_attr("geometry", "length", "-5"),
        "length_text": first_attr("geometry", "length", "long"),
        "x_1e300": first_attr("geometry", "x", "1e300"),
        "hdg_inf": first_attr("geometry", "hdg", "INF"),
        "road_length_1e308": first_attr("road", "length", "1e308"),
        "width_1e308": first_attr("width", "a", "1e308"),
        "lane_id_text": first_attr("lane", "id", "minus-one"),
        "deep_nesting": lambda t: t.replace(
            "</header>", "<a>" * 5000 + "</a>" * 5000 + "</header>"
        ),
        "garbage": lambda t: _garbage(5000, 41).decode("latin1"),
    }
    for kind, edit in edits.items():
        for cmd_name, argv in (("check", check), ("evaluate", evaluate)):
            if cmd_name == "evaluate" and kind in ("deep_nesting", "garbage", "lane_id_text"):
                continue
            cases.append(Case(f"xodr/{cmd_name}/{kind}", edit_map(edit), argv, expect="map.xodr"))

    def oversized(d: Dirs) -> None:  # sparse: 40 MiB on paper, nothing on disk
        with d.map.open("r+b") as fh:
            fh.truncate(40 * 2**20)

    def many_pieces(d: Dirs) -> None:
        text = d.map.read_text(encoding="utf-8")
        i = text.index("</planView>")
        d.map.write_text(text[:i] + "<geometry/>" * 500_001 + text[i:], encoding="utf-8")

    cases.append(Case("xodr/check/over_32MiB", oversized, check, expect="map.xodr"))
    cases.append(Case("xodr/evaluate/over_32MiB", oversized, evaluate, expect="map.xodr"))
    cases.append(Case("xodr/check/over_500k_pieces", many_pieces, check, expect="map.xodr"))
    cases.append(Case("xodr/check/missing", lambda d: d.map.unlink(), check, expect="map.xodr"))
    cases.append(
        Case(
            "xodr/check/directory",
            _seq(lambda d: d.map.unlink(), lambda d: d.map.mkdir()),
            check,
            expect="map.xodr",
        )
    )

    def truth_json(text: str) -> Mutate:
        return lambda d: (d.run / "truth.json").write_text(text, encoding="utf-8")

    cases.append(  # no "ramps": the true ramps come from the truth network's ramp roads
        Case(
            "truth/json/no_ramps_key",
            truth_json("{}"),
            evaluate,
            exit_code=0,
            writes=("report.json", "report.html"),
        )
    )
    for kind, text in {
        "garbage": "{{{ not json",
        "list": "[1, 2, 3]",
        "ramps_not_list": '{"ramps": 5}',
        "ramp_missing_keys": '{"ramps": [{"type": "exit"}]}',
        "ramp_station_text": '{"ramps": [{"type": "exit", "station_m": "x", "road_id": "1"}]}',
    }.items():
        cases.append(Case(f"truth/json/{kind}", truth_json(text), evaluate, expect="truth.json"))
    cases.append(
        Case(
            "truth/missing_file",
            _seq(),
            lambda d: [*evaluate(d), "--truth", str(d.root / "nope.xodr")],
            expect="nope.xodr",
        )
    )
    cases.append(
        Case(
            "truth/is_directory",
            lambda d: (d.root / "t.xodr").mkdir(),
            lambda d: [*evaluate(d), "--truth", str(d.root / "t.xodr")],
            expect="t.xodr",
        )
    )
    return cases


def _limit_cases() -> list[Case]:
    """Size limits, lowered through ``--config`` so that the run stays small: the same code
    refuses a 5 M-pose trajectory or a 10^9-point LAZ (from its header) at the defaults."""

    def limited(table: str, key: str, value: str) -> tuple[Mutate, Argv]:
        def mutate(d: Dirs) -> None:
            d.config.write_text(f"[{table}]\n{key} = {value}\n", encoding="utf-8")

        return mutate, lambda d: [*_build(d), "--config", str(d.config)]

    cases = []
    for name, (key, value, fmt, expect) in {
        "poses": ("max_poses", "500", None, "trajectory.csv"),
        "driven_km": ("max_driven_km", "1.0", None, "trajectory.csv"),
        "points_laz": ("max_points", "1000", None, "road_edges.laz"),
        "points_csv": ("max_points", "1000", "csv", "road_edges.csv"),
        "points_ply": ("max_points", "1000", "ply", "road_edges.ply"),
        "points_npy": ("max_points", "1000", "npy", "road_edges.npy"),
        "points_parquet": ("max_points", "1000", "parquet", "road_edges.parquet"),
        "origin_distance": ("max_origin_distance_km", "0.5", None, "trajectory.csv"),
    }.items():
        mutate, argv = limited("load", key, value)
        if fmt is not None:
            mutate = _seq(_edges_as(fmt), mutate)
        cases.append(Case(f"limits/{name}", mutate, argv, expect=expect))
    return cases


def all_cases() -> list[Case]:
    """Every case of the corpus, in a stable order."""
    cases = [
        *_table_cases(),
        *_plausibility_cases(),
        *_edge_format_cases(),
        *_manifest_cases(),
        *_osm_cases(),
        *_config_cases(),
        *_output_cases(),
        *_xodr_cases(),
        *_limit_cases(),
    ]
    names = [c.name for c in cases]
    assert len(names) == len(set(names)), "case names must be unique"
    return cases


# ---------------------------------------------------------------------------
# preparing a case folder
# ---------------------------------------------------------------------------


def make_base(root: Path) -> tuple[Path, Path]:
    """Simulate the bundled run and build its map once: ``root/run``, ``root/map.xodr``."""
    from roadtwin.io import load_run
    from roadtwin.osm import load_osm
    from roadtwin.pipeline import build_map
    from roadtwin.simulate import load_scenario, simulate_run
    from roadtwin.xodr import write_xodr

    run_dir = root / "run"
    if not (run_dir / "run.toml").is_file():
        simulate_run(load_scenario("straight_curve_2km"), run_dir)
    map_path = root / "map.xodr"
    if not map_path.is_file():
        run = load_run(run_dir)
        osm = load_osm(run.osm_path, frame=run.frame, around_xy=run.trajectory.xy)
        write_xodr(build_map(run, osm).network, map_path)
    return run_dir, map_path


def prepare(case: Case, base_run: Path, base_map: Path, root: Path) -> Dirs:
    """Copy the base run and map into ``root`` and apply the case's mutation."""
    d = Dirs(root)
    root.mkdir(parents=True, exist_ok=True)
    shutil.copytree(base_run, d.run)
    shutil.copyfile(base_map, d.map)
    d.secret.write_text(CANARY + "\n", encoding="utf-8")
    case.mutate(d)
    return d


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Relative path -> content (None for folders) of everything under ``folder``."""
    out: dict[str, bytes | None] = {}
    if not folder.exists():
        return out
    for p in sorted(folder.rglob("*")):
        rel = str(p.relative_to(folder))
        if p.is_symlink() or p.is_fifo():
            out[rel] = b"<special>"
        elif p.is_dir():
            out[rel] = None
        else:
            out[rel] = p.read_bytes()
    return out


@dataclass
class Outcome:
    """What one command did: exit code, output streams, seconds, and whether it hung."""

    exit_code: int | None
    stdout: str
    stderr: str
    seconds: float
    hung: bool = False


@dataclass(frozen=True)
class Before:
    """The case folder before the command ran."""

    run: dict[str, bytes | None]
    out: dict[str, bytes | None]


def before(d: Dirs) -> Before:
    return Before(snapshot(d.run), snapshot(d.out))


SECRETS = (CANARY.lower(), "root:x:0:0:")
"""Text that must never appear in any output: the canary, and the first line of
``/etc/passwd`` (cases name it directly); compared case-insensitively."""


def _has_secret(text: str) -> bool:
    low = text.lower()
    return any(secret in low for secret in SECRETS)


PROBLEMS = ("hang", "traceback", "exit", "message", "noise", "leak", "leftover", "clobbered")
"""Kinds of failure :func:`judge` reports."""


def judge(case: Case, d: Dirs, outcome: Outcome, was: Before, tmp: Path) -> dict[str, str]:
    """Problems of one outcome against the corpus contract, by kind (empty: all good).

    ``tmp`` is the TMPDIR the command ran with; it must be empty afterwards.
    """
    problems: dict[str, str] = {}
    err_lines = [ln for ln in outcome.stderr.splitlines() if ln.strip()]
    if outcome.hung:
        problems["hang"] = f"no exit within {outcome.seconds:.0f} s"
        return problems
    if "Traceback (most recent call last)" in outcome.stderr + outcome.stdout:
        problems["traceback"] = next(
            (ln for ln in reversed(err_lines) if ln and not ln.startswith(" ")), "?"
        )
    if outcome.exit_code != case.exit_code:
        problems["exit"] = f"exit {outcome.exit_code}, expected {case.exit_code}"
    errors = [ln for ln in err_lines if ln.startswith("roadtwin: error: ")]
    if case.exit_code == 2:
        want = case.expected_text(d)
        if len(errors) != 1:
            problems["message"] = f"{len(errors)} error lines"
        elif want not in errors[0]:
            problems["message"] = f"error line does not name {want!r}: {errors[0][:300]}"
    noise = [
        ln for ln in err_lines if not ln.startswith(("roadtwin: error: ", "roadtwin: warning: "))
    ]
    if noise and "traceback" not in problems:
        problems["noise"] = noise[0][:200]
    written: list[Path] = []
    for folder in (d.out, d.run, tmp):
        if folder.exists():
            written.extend(p for p in folder.rglob("*") if p.is_file() and not p.is_symlink())
    leaked = [
        str(p)
        for p in written
        if p.stat().st_size < 50_000_000 and _has_secret(p.read_bytes().decode("latin1"))
    ]
    if _has_secret(outcome.stdout + outcome.stderr):
        leaked.insert(0, "stdout/stderr")
    if leaked:
        problems["leak"] = ", ".join(leaked[:3])
    left = [str(p) for p in tmp.rglob("*")] if tmp.exists() else []
    for folder in (d.out, d.run, d.root):
        if folder.exists():
            left += [
                str(p)
                for p in folder.rglob("*")
                if p.name.startswith(".") and (".tmp" in p.name or ".build." in p.name)
            ]
    now_out = snapshot(d.out)
    if outcome.exit_code == 2 and now_out != was.out:
        new = sorted(set(now_out) - set(was.out)) or ["(changed content)"]
        left.append(f"output changed on error: {new[:3]}" if d.out.exists() else "out removed")
    if left:
        problems["leftover"] = ", ".join(sorted(set(left))[:3])
    now_run = snapshot(d.run)
    changed = [k for k in was.run if was.run[k] != now_run.get(k)]
    if changed:
        problems["clobbered"] = ", ".join(changed[:3])
    if outcome.exit_code in (0, 1) and outcome.exit_code == case.exit_code:
        missing = [n for n in case.writes if not (d.out / n).is_file()]
        if missing:
            problems["exit"] = f"did not write {missing}"
    return problems
