"""Tests of scanclique.io.dimacs: reading, writing and the errors on malformed files."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from scanclique.errors import DataNotFoundError, ParseError
from scanclique.io.dimacs import DimacsGraph, read_dimacs, write_dimacs


def write(tmp_path, text: str) -> Path:
    p = tmp_path / "g.clq"
    p.write_text(text)
    return p


def test_read_basic(tmp_path):
    p = write(
        tmp_path,
        "c a comment\nc   another\n\np edge 4 4\ne 1 2\ne 2 3\ne 3 1\ne 2 1\ne 4 3\n",
    )
    g = read_dimacs(p)
    assert isinstance(g, DimacsGraph)
    assert g.n == 4 and g.m == 4 and g.weights is None
    assert g.edges.tolist() == [[0, 1], [0, 2], [1, 2], [2, 3]]
    assert g.comments == ("a comment", "another")
    adj = g.adjacency()
    assert adj.dtype == bool and np.array_equal(adj, adj.T) and adj.sum() == 8
    with pytest.raises(ValueError):
        g.edges[0, 0] = 3


def test_weights_and_col_header(tmp_path):
    g = read_dimacs(write(tmp_path, "p col 3 1\nn 2 5\nn 3 2.5\ne 1 2\n"))
    assert g.weights.tolist() == [1.0, 5.0, 2.5]


def test_empty_graph(tmp_path):
    g = read_dimacs(write(tmp_path, "p edge 0 0\n"))
    assert g.n == 0 and g.edges.shape == (0, 2) and g.adjacency().shape == (0, 0)


@pytest.mark.parametrize("n", [0, 1, 5, 70])
def test_round_trip(tmp_path, n):
    rng = np.random.default_rng(n)
    adj = np.triu(rng.random((n, n)) < 0.4, 1)
    adj = adj | adj.T
    w = rng.integers(1, 9, n).astype(float)
    p = tmp_path / "rt.clq"
    write_dimacs(p, adj, comments=["round trip"], weights=w)
    g = read_dimacs(p)
    assert np.array_equal(g.adjacency(), adj)
    assert g.comments == ("round trip",)
    assert n == 0 or np.array_equal(g.weights, w)
    write_dimacs(p, g)
    assert np.array_equal(read_dimacs(p).adjacency(), adj)
    write_dimacs(p, (g.edges, g.n))
    assert np.array_equal(read_dimacs(p).adjacency(), adj)


@pytest.mark.parametrize(
    ("text", "line", "field", "match"),
    [
        ("e 1 2\np edge 2 1\n", 1, "e", "before"),
        ("p edge 2 1\ne 1\n", 2, "e", "fields"),
        ("p edge 2 1\ne 1 x\n", 2, "v", "integer"),
        ("p edge 2 1\ne 1 3\n", 2, "v", "1..2"),
        ("p edge 2 1\ne 0 1\n", 2, "u", "1..2"),
        ("p edge 2 1\ne 2 2\n", 2, "v", "self loop"),
        ("p edge 2\n", 1, "p", "p edge N M"),
        ("p graph 2 1\n", 1, "p", "p edge N M"),
        ("p edge two 1\n", 1, "N", "integer"),
        ("p edge 2 1\np edge 2 1\n", 2, "p", "second"),
        ("c ok\np edge 2 1\nx 1 2\n", 3, "type", "unknown"),
        ("p edge 2 1\nn 1 heavy\n", 2, "w", "number"),
        ("p edge 2 1\nn 3 1\n", 2, "v", "1..2"),
    ],
)
def test_malformed(tmp_path, text, line, field, match):
    p = write(tmp_path, text)
    with pytest.raises(ParseError, match=match) as ei:
        read_dimacs(p)
    assert ei.value.line == line and ei.value.field == field and ei.value.path == str(p)
    assert str(ei.value).startswith(f"{p}:{line}: {field}: ")


def test_missing_p_line_and_missing_file(tmp_path):
    with pytest.raises(ParseError, match="no 'p edge") as ei:
        read_dimacs(write(tmp_path, "c nothing\n"))
    assert ei.value.line is None
    with pytest.raises(DataNotFoundError):
        read_dimacs(tmp_path / "absent.clq")


def _dimacs_dir() -> Path:
    root = Path(__file__).resolve().parents[1]
    return Path(os.environ.get("SCANCLIQUE_DATA", root.parent / "shared" / "data")) / "dimacs"


@pytest.mark.realdata
def test_shared_files_parse():
    d = _dimacs_dir()
    if not (d / "omega.txt").exists():
        pytest.skip(f"DIMACS data not found in {d} (set SCANCLIQUE_DATA)")
    table = [
        ln.split()
        for ln in (d / "omega.txt").read_text().splitlines()
        if ln.strip() and not ln.startswith("#")
    ]
    assert len(table) == 27
    for name, n, _ in table:
        g = read_dimacs(d / f"{name}.clq")
        assert g.n == int(n) and g.m > 0
