"""Point files read in chunks: the same points and the same checks as a whole-file read."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from _run_factory import EDGE_FORMATS, write_run
from roadtwin._errors import InputError
from roadtwin.pointfiles import count_road_edges, iter_road_edges, read_road_edges


def _edge_file(root):
    return next(p for p in root.iterdir() if p.name.startswith("road_edges"))


@pytest.mark.parametrize("edge_format", EDGE_FORMATS)
def test_chunks_hold_the_whole_file_in_order(tmp_path, edge_format):
    truth = write_run(tmp_path, edge_format=edge_format, n_frames=40)
    path = _edge_file(tmp_path)
    chunks = list(iter_road_edges(path, chunk_points=7))
    assert [c.first_row for c in chunks] == list(range(0, truth.edges.shape[0], 7))
    assert all(c.xyz.shape[0] == 7 for c in chunks[:-1])
    np.testing.assert_allclose(np.vstack([c.xyz for c in chunks]), truth.edges, atol=1e-6)
    np.testing.assert_array_equal(np.concatenate([c.side for c in chunks]), truth.edge_side)
    whole, side = read_road_edges(path)
    np.testing.assert_array_equal(whole, np.vstack([c.xyz for c in chunks]))
    np.testing.assert_array_equal(side, truth.edge_side)
    if edge_format != "csv":  # CSV has no header count
        assert count_road_edges(path) == truth.edges.shape[0]


@pytest.mark.parametrize(
    ("column", "value", "message"),
    [
        ("x", np.nan, r"data row 26, column 'x': nan is not a finite number"),
        ("y", "abc", r"data row 26, column 'y': not a number"),
        ("side", "up", r"data row 26, column 'side': 'up' is not a side"),
    ],
)
def test_bad_value_in_a_later_chunk_names_its_row_in_the_file(tmp_path, column, value, message):
    write_run(tmp_path, edge_format="csv", n_frames=40)
    path = tmp_path / "road_edges.csv"
    df = pd.read_csv(path)
    df[column] = df[column].astype(object)
    df.loc[25, column] = value
    df.to_csv(path, index=False)
    with pytest.raises(InputError, match=message):
        list(iter_road_edges(path, chunk_points=10))


def test_empty_and_header_only_files(tmp_path):
    (tmp_path / "e.csv").write_text("")
    with pytest.raises(InputError, match="file is empty"):
        list(iter_road_edges(tmp_path / "e.csv"))
    (tmp_path / "h.csv").write_text("x,y,z\n")
    with pytest.raises(InputError, match="header but no data rows"):
        list(iter_road_edges(tmp_path / "h.csv", chunk_points=3))


def test_truncated_laz_is_an_input_error(tmp_path):
    write_run(tmp_path, edge_format="laz", n_frames=200)
    path = tmp_path / "road_edges.laz"
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="not a readable LAS/LAZ file"):
        list(iter_road_edges(path, chunk_points=100))
