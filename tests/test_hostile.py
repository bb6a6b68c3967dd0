"""Hostile input (issue 15): every case gets a named ScanCliqueError (one ``error:`` line
and exit code 2 from the CLI) or a documented bounded result, within a stated memory bound
and never hanging.

Memory bounds are checked in a subprocess under an address-space limit
(``resource.setrlimit(RLIMIT_AS)``): :data:`LIMIT_MB` is what a Python process that has
imported scanclique (about 300 MB of address space) plus the readers' buffers needs, far
below what the inputs would take if they were decompressed or allocated whole (2 GiB and
more). Special files (FIFOs, devices) are refused before they are opened; those tests run
in a subprocess with a timeout so that a regression fails instead of hanging the suite.
"""

from __future__ import annotations

import bz2
import gzip
import math
import os
import subprocess
import sys
import textwrap
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error, require_log
from typer.testing import CliRunner

import scanclique as sc
from scanclique import cli, tools
from scanclique.errors import (
    ArgumentError,
    ConfigError,
    GraphError,
    ParseError,
    ScanCliqueError,
    ScanIndexError,
)
from scanclique.io import config as io_config
from scanclique.io import dimacs, read_scans, read_scans_at, write_scans_npz, write_scans_text
from scanclique.io.carmen import detect_no_return, read_carmen

LIMIT_MB = 1024
runner = CliRunner()


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------
def limited(code: str, *args: str, limit_mb: int = LIMIT_MB, timeout: float = 120):
    """Run ``code`` in a fresh Python under an address-space limit; returns the process."""
    prelude = textwrap.dedent(
        f"""
        import resource, sys
        lim = {limit_mb} * 2**20
        resource.setrlimit(resource.RLIMIT_AS, (lim, lim))
        """
    )
    return subprocess.run(
        [sys.executable, "-c", prelude + textwrap.dedent(code), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


READ = """
import scanclique as sc
try:
    scans = sc.read_scans(sys.argv[1])
    print("scans", len(scans))
except sc.ScanCliqueError as exc:
    print("ScanCliqueError", type(exc).__name__, exc)
"""


def assert_refused(proc, *words: str) -> str:
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout.strip()
    assert out.startswith("ScanCliqueError"), out + proc.stderr[-2000:]
    assert "MemoryError" not in proc.stderr
    for w in words:
        assert w in out, out
    return out


def bomb(path: Path, unit: bytes, mib: int, kind: str = "gzip") -> Path:
    """A small file that expands to ``mib`` MiB of ``unit`` repeated (concatenated gzip or
    bzip2 members, built without compressing it all)."""
    block = unit * (2**20 // len(unit))
    member = gzip.compress(block, 9) if kind == "gzip" else bz2.compress(block, 9)
    path.write_bytes(member * mib)
    return path


def cli_run(*args):
    return runner.invoke(cli.app, [str(a) for a in args])


def flaser_line(ranges, t=0.0, pose=(0.0, 0.0, 0.0), odom=(0.0, 0.0, 0.0)) -> str:
    r = " ".join(f"{v:.3f}" for v in ranges)
    p = " ".join(f"{v:.6f}" for v in (*pose, *odom))
    return f"FLASER {len(ranges)} {r} {p} {t:.3f} host {t:.3f}"


# ---------------------------------------------------------------------------------------
# item 1: small files must not take gigabytes
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "unit, kind, words",
    [
        (b"\n", "gzip", ["expands more than"]),
        (b"#\n", "gzip", ["expands more than"]),
        (b"# comment\n", "bzip2", ["expands more than"]),
        (b"\x00", "gzip", []),
        (b"   \n", "bzip2", ["expands more than"]),
    ],
)
def test_decompression_bombs_are_refused_in_bounded_memory(tmp_path, unit, kind, words):
    """2 GiB of newlines, comments, blanks or NUL bytes in a file of at most a few MB:
    refused under a 1 GiB address-space limit (the old readers took 8-11 GB)."""
    path = bomb(tmp_path / f"bomb.{'gz' if kind == 'gzip' else 'bz2'}", unit, 2048, kind)
    assert path.stat().st_size < 5 * 2**20
    assert_refused(limited(READ, str(path)), str(path), *words)


def test_a_line_without_end_is_refused_at_the_line_bound(tmp_path):
    path = tmp_path / "long.log"
    path.write_bytes(b"FLASER 3 " + b"1.0 " * (5 * 2**20))  # 20 MiB, no newline
    out = assert_refused(limited(READ, str(path)), "line longer than 16.0 MiB")
    assert ":1:" in out


def test_a_large_plain_log_reads_in_bounded_memory(tmp_path):
    """30 000 scans of 181 beams (38 MB of text): read under a 700 MB address-space
    limit, building two scans (the old reader held every line and every scan)."""
    line = flaser_line(np.linspace(1.0, 20.0, 181)) + "\n"
    path = tmp_path / "big.log"
    with open(path, "w") as fh:
        for _ in range(30):
            fh.write(line * 1000)
    assert path.stat().st_size > 30 * 2**20
    proc = limited(
        """
        import scanclique as sc
        from scanclique.io import read_scans_at
        sel = read_scans_at(sys.argv[1], [5, 29999], count=True)
        print(sorted(sel.scans), sel.n_scans)
        """,
        str(path),
        limit_mb=700,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["[5,", "29999]", "30000"]


def test_match_reads_only_the_scans_it_needs(tmp_path):
    """``match LOG i j`` builds two scans and stops reading after the later one (and
    the 200 laser messages of the no-return probe): a malformed line further on is never
    reached (a full read refuses it)."""
    lines = [flaser_line(np.full(20, 2.0 + k * 0.01), t=k) for k in range(300)]
    lines.append("FLASER 20 this line is broken")
    path = tmp_path / "log"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ParseError, match=":301:"):
        read_scans(path)
    sel = read_scans_at(path, [3, 7])
    assert sorted(sel.scans) == [3, 7] and sel.n_scans is None
    assert sel.scans[7].source == "log:8"
    a, b, names, _ = tools.load_scan_pair(path, 3, 7)
    assert names == ("log:3", "log:7") and a.timestamp == 3.0 and b.timestamp == 7.0


def test_an_index_beyond_the_end_reads_to_the_end_and_says_how_many(tmp_path):
    path = tmp_path / "log"
    path.write_text("\n".join(flaser_line(np.full(10, 3.0), t=k) for k in range(4)) + "\n")
    with pytest.raises(ScanIndexError, match=r"index 9 out of range: the log has 4 scans"):
        tools.load_scan(path, 9)
    with pytest.raises(ScanIndexError, match=r"index -1 out of range: the log has 4 scans"):
        tools.load_scan(path, -1)


def _npy_header(shape, dtype="<f8") -> bytes:
    import io as _io

    buf = _io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": dtype, "fortran_order": False, "shape": shape}
    )
    return buf.getvalue()


def test_npz_with_a_ten_million_row_empty_array_is_refused(tmp_path):
    """510 bytes whose ``ranges`` has shape (10**7, 0): refused from the header (it took
    9 GB and 176 s)."""
    path = tmp_path / "rows.npz"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("ranges.npy", _npy_header((10**7, 0)))
        z.writestr("angles.npy", _npy_header((0,)))
    assert path.stat().st_size < 1000
    assert_refused(limited(READ, str(path)), "ranges", "more than 1000000 scans")


def test_npz_header_that_lies_about_its_size_is_refused(tmp_path):
    path = tmp_path / "lie.npz"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("ranges.npy", _npy_header((10**6, 10**4)) + b"\0" * 80)
        z.writestr("angles.npy", _npy_header((0,)))
    out = assert_refused(limited(READ, str(path)), "ranges")
    assert "header says shape" in out


def test_npz_member_above_the_size_bound_is_not_decompressed(tmp_path):
    scans = [sc.Scan.from_ranges(np.full(1000, 2.0)) for _ in range(10)]
    write_scans_npz(tmp_path / "s.npz", scans)
    with pytest.raises(ParseError, match="exceeds the limit of 4000 bytes"):
        sc.io.npz.read_scans_npz(tmp_path / "s.npz", max_bytes=4000)


def test_npz_members_the_reader_does_not_use_are_never_read(tmp_path, monkeypatch):
    """A 4 GB array under an unknown key was decompressed anyway; now only the layout's
    members are opened."""
    path = tmp_path / "extra.npz"
    write_scans_npz(path, [sc.Scan.from_ranges([1.0, 2.0])])
    with zipfile.ZipFile(path, "a") as z:
        z.writestr("huge.npy", _npy_header((2**29,)) + b"\0" * 1024)
    opened: list[str] = []
    real_open = zipfile.ZipFile.open

    def spy(self, name, *a, **k):
        opened.append(getattr(name, "filename", name))
        return real_open(self, name, *a, **k)

    monkeypatch.setattr(zipfile.ZipFile, "open", spy)
    scans = read_scans(path)
    assert len(scans) == 1 and "huge.npy" not in opened and "ranges.npy" in opened


def test_a_large_dimacs_edge_file_reads_in_bounded_memory(tmp_path):
    n = 3000
    rng = np.random.default_rng(0)
    u = rng.integers(1, n, 400_000)
    v = np.minimum(u + rng.integers(1, 50, u.size), n)
    keep = u != v
    path = tmp_path / "g.clq"
    with open(path, "w") as fh:
        fh.write(f"p edge {n} {int(keep.sum())}\n")
        fh.writelines(f"e {a} {b}\n" for a, b in zip(u[keep], v[keep], strict=True))
    proc = limited(
        """
        from scanclique.io.dimacs import read_dimacs
        g = read_dimacs(sys.argv[1])
        print(g.n, g.m > 0)
        """,
        str(path),
        limit_mb=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["3000", "True"]


# ---------------------------------------------------------------------------------------
# item 2: DIMACS vertex count
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("n", [100_000_000, 100_000])
def test_dimacs_vertex_count_is_bounded_before_allocating(tmp_path, n):
    path = tmp_path / "p.clq"
    path.write_text(f"p edge {n} 1\ne 1 2\n")
    proc = limited(
        """
        from scanclique.io.dimacs import read_dimacs
        from scanclique.errors import ScanCliqueError
        try:
            read_dimacs(sys.argv[1])
        except ScanCliqueError as exc:
            print("ScanCliqueError", exc)
        """,
        str(path),
        limit_mb=600,
    )
    out = assert_refused(proc, f"{path}:1", str(n))
    assert "PiB" in out or "GiB" in out or "TiB" in out
    r = cli_run("clique", path)
    assert_clean_error(r, "vertices")


def test_dimacs_more_edge_lines_than_a_graph_can_hold(tmp_path):
    path = tmp_path / "dup.clq"
    path.write_text("p edge 3 1\n" + "e 1 2\n" * 7)
    with pytest.raises(ParseError, match="more edge lines than"):
        dimacs.read_dimacs(path)


def test_dimacs_comments_are_kept_bounded(tmp_path):
    path = tmp_path / "c.clq"
    path.write_text("c x\n" * 5000 + "p edge 2 1\ne 1 2\n")
    g = dimacs.read_dimacs(path)
    assert len(g.comments) == 1000 and g.m == 1


def test_max_clique_edge_list_naming_a_huge_vertex_is_a_graph_error():
    from scanclique.clique import max_clique

    with pytest.raises(GraphError):
        max_clique(np.array([[0, 10**8]]))


# ---------------------------------------------------------------------------------------
# items 6 and 1: FIFOs and devices are refused, never read
# ---------------------------------------------------------------------------------------
@pytest.fixture
def fifo(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this platform")
    p = tmp_path / "fifo"
    os.mkfifo(p)
    return p


SPECIAL = """
import scanclique as sc
from scanclique.io.config import read_config
from scanclique.io.dimacs import read_dimacs
for f in (sc.read_scans, sc.io.read_carmen, sc.io.read_scans_text, sc.io.read_scans_npz,
          read_dimacs, read_config, sc.io.detect_format):
    try:
        f(sys.argv[1])
        print("read", f.__name__)
    except sc.ScanCliqueError as exc:
        print("refused", f.__name__, "|", exc)
"""


@pytest.mark.parametrize("which", ["fifo", "/dev/zero"])
def test_special_files_are_refused_by_every_reader(fifo, which):
    target = str(fifo) if which == "fifo" else which
    if not os.path.exists(target):
        pytest.skip(f"{target} does not exist here")
    proc = limited(SPECIAL, target, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    assert len(lines) == 7, proc.stdout
    kind = "FIFO" if which == "fifo" else "character device"
    for line in lines:
        assert line.startswith("refused") and kind in line, line


@pytest.mark.parametrize("which", ["fifo", "/dev/zero"])
def test_special_files_on_the_command_line(fifo, which):
    target = str(fifo) if which == "fifo" else which
    if not os.path.exists(target):
        pytest.skip(f"{target} does not exist here")
    for args in (
        ["clique", target],
        ["match", target, "0", "1"],
        ["features", target],
        ["features", "x", "--config", target],
    ):
        proc = subprocess.run(
            [sys.executable, "-m", "scanclique", *args], capture_output=True, text=True, timeout=60
        )
        assert proc.returncode == 2, (args, proc.stderr)
        err = proc.stderr.strip()
        assert err.startswith("error:") and len(err.splitlines()) == 1, err
        assert target in err, err


# ---------------------------------------------------------------------------------------
# item 4: no-return readings below 80 m
# ---------------------------------------------------------------------------------------
def _open_room():
    walls = [
        [[0, 0], [14, 0]], [[14, 0], [14, 9]], [[0, 9], [0, 0]], [[0, 9], [4, 9]],
        [[10, 9], [14, 9]], [[5, 3], [6, 3]], [[6, 3], [6, 4]], [[6, 4], [5, 4]],
        [[5, 4], [5, 3]], [[9, 5], [11, 5]],
    ]  # fmt: skip
    return sc.sim.World(
        np.array(walls, float),
        circle_centres=[[3.0, 5.0], [11.0, 2.0]],
        circle_radii=[0.25, 0.3],
        free_regions=[[1.0, 1.0, 13.0, 8.0]],
    )


@pytest.fixture(scope="module")
def log50(tmp_path_factory):
    """A simulated CARMEN log of a room open on one side that marks no return with 50 m."""
    rng = np.random.default_rng(3)
    scans = sc.sim.simulate_trajectory(
        rng, _open_room(), 30, n_beams=181, fov=math.pi, angle_min=-math.pi / 2, max_range=50.0
    )
    lines = ["# simulated: no return is logged as 50 m"]
    for k, s in enumerate(scans):
        r = np.where(s.valid, s.ranges, 50.0)
        ref, od = s.reference, s.odometry
        lines.append(
            flaser_line(r, t=0.5 * k, pose=(ref.x, ref.y, ref.theta), odom=(od.x, od.y, od.theta))
        )
    path = tmp_path_factory.mktemp("nr") / "room50.log"
    path.write_text("\n".join(lines) + "\n")
    return path, scans


def test_a_log_marking_no_return_with_50_m_is_detected_and_masked(log50, caplog):
    path, truth = log50
    with caplog.at_level("WARNING", logger="scanclique.io.carmen"):
        log = read_carmen(path)
    assert dict(log.no_return) == {"FLASER": 50.0}
    assert "marks no return with 50 m" in caplog.text
    for s, t in zip(log.scans, truth, strict=True):
        assert s.range_max == 50.0
        assert np.array_equal(s.valid, t.valid)  # exactly the simulator's no-returns
    n_masked = sum(int((~s.valid).sum()) for s in log.scans)
    assert n_masked > 100
    # a selective read decides the same way (it parses the same probe)
    sel = read_scans_at(path, [2])
    assert sel.scans[2].range_max == 50.0 and sel.no_return == {"FLASER": 50.0}


def test_without_masking_the_50_m_readings_become_phantom_features(log50):
    path, _ = log50
    masked = read_scans(path)
    raw = read_scans(path, max_range=80.0)  # an explicit max_range turns detection off
    assert raw[0].range_max == 80.0
    far = [
        int(np.sum(np.hypot(*sc.extract_features(s).points_xy.T) > 40.0))
        + int(np.sum(np.abs(sc.extract_features(s).lines_rho_alpha[:, 0]) > 40.0))
        for s in raw
    ]
    far_masked = [
        int(np.sum(np.hypot(*sc.extract_features(s).points_xy.T) > 40.0))
        + int(np.sum(np.abs(sc.extract_features(s).lines_rho_alpha[:, 0]) > 40.0))
        for s in masked
    ]
    assert sum(far) > 0, "the test log should make phantom features without masking"
    assert sum(far_masked) == 0


def test_features_command_says_so(log50):
    path, _ = log50
    r = cli_run("features", path, "3")
    assert r.exit_code == 0, r.output
    assert "marks no return with 50 m" in r.stderr
    assert "no return at or beyond" in r.stdout and "50 m" in r.stdout
    r = cli_run("features", path, "3", "--max-range", "80")
    assert "marks no return" not in r.stderr and "80 m" in r.stdout


def test_detection_leaves_genuine_ranges_alone():
    rng = np.random.default_rng(1)
    rows = [rng.uniform(0.3, 30.0, 361).round(2) for _ in range(200)]  # cm-quantised
    assert detect_no_return(rows) is None
    # a value repeated a lot but inside the distribution (a wall seen from a still robot)
    rows = [np.concatenate([rng.uniform(0.3, 30.0, 300).round(2), np.full(20, 12.34)])] * 50
    assert detect_no_return(rows) is None
    # marks at or beyond max_range are the reader's default already
    rows = [np.where(rng.random(180) < 0.3, 81.83, rng.uniform(0.5, 25, 180)) for _ in range(50)]
    assert detect_no_return(rows) is None


@pytest.mark.realdata
@pytest.mark.parametrize("name", ["intel", "csail"])
def test_shared_logs_mark_no_return_at_80_m_or_more_and_nothing_changes(name):
    log = read_carmen(require_log(name))
    assert dict(log.no_return) == {}
    assert {s.range_max for s in log.scans} == {80.0}


# ---------------------------------------------------------------------------------------
# item 5: one error line instead of tracebacks
# ---------------------------------------------------------------------------------------
def test_npy_named_npz_and_text_named_npz(tmp_path):
    np.save(tmp_path / "a.npy", np.zeros(3))
    os.rename(tmp_path / "a.npy", tmp_path / "a.npz")
    with pytest.raises(ParseError, match="single .npy array"):
        read_scans(tmp_path / "a.npz")
    (tmp_path / "t.npz").write_text(flaser_line([1.0, 2.0]) + "\n")
    with pytest.raises(ParseError, match="found text starting 'FLASER") as e:
        read_scans(tmp_path / "t.npz")
    assert "unpickl" not in str(e.value)
    assert_clean_error(cli_run("features", tmp_path / "a.npz"), "a.npz")


def test_plot_with_an_unknown_suffix_fails_before_any_work(tmp_path):
    scans = [sc.Scan.from_ranges(np.full(50, 2.0))]
    write_scans_text(tmp_path / "a.txt", scans)
    r = cli_run("features", tmp_path / "a.txt", "--plot", tmp_path / "x.xyz")
    assert_clean_error(r, "x.xyz", ".png")
    assert r.stdout == ""  # refused before the table


def test_toml_integer_above_int64(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text("[correspondence]\nmax_nodes = 99999999999999999999\n")
    with pytest.raises(ConfigError, match="64-bit integer"):
        io_config.read_config(p)
    assert_clean_error(cli_run("features", "x", "--config", p), "max_nodes")


def test_oversized_config_file(tmp_path):
    p = tmp_path / "big.toml"
    p.write_text("# x\n" * 400_000)
    with pytest.raises(ConfigError, match="larger than 1024 KiB"):
        io_config.read_config(p)


# ---------------------------------------------------------------------------------------
# item 8: --plot paths
# ---------------------------------------------------------------------------------------
@pytest.fixture
def scan_file(tmp_path):
    rng = np.random.default_rng(2)
    pair = sc.sim.simulate_pair(rng)
    write_scans_text(tmp_path / "a.txt", [pair.scan_a])
    write_scans_text(tmp_path / "b.txt", [pair.scan_b])
    return tmp_path


def test_plot_into_a_missing_directory_is_refused_and_nothing_is_created(scan_file):
    target = scan_file / "no" / "such" / "dir" / "m.png"
    r = cli_run("features", scan_file / "a.txt", "--plot", target)
    assert_clean_error(r, "does not exist")
    assert not (scan_file / "no").exists()


def test_plot_onto_an_existing_directory_is_refused(scan_file):
    d = scan_file / "somedir"
    d.mkdir()
    r = cli_run("features", scan_file / "a.txt", "--plot", d)
    assert_clean_error(r, "is a directory")
    assert not (scan_file / "somedir.png").exists()


# ---------------------------------------------------------------------------------------
# item 9 (readers and writers): wrong argument types, writer argument order
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [None, 3, 2.5, ["a.log"], {"path": 1}])
def test_read_scans_wrong_path_type(bad):
    with pytest.raises(ArgumentError, match="must be a file path"):
        read_scans(bad)


def test_read_scans_wrong_option_types(tmp_path):
    p = tmp_path / "a.log"
    p.write_text(flaser_line([1.0, 2.0]) + "\n")
    with pytest.raises(ArgumentError, match="strict"):
        read_scans(p, strict="yes")
    with pytest.raises(ArgumentError, match="max_beams"):
        read_scans(p, max_beams=0)
    with pytest.raises(ArgumentError, match="max_range"):
        read_scans(p, max_range="80")
    with pytest.raises(ArgumentError, match="non-negative"):
        read_scans_at(p, [-1])
    with pytest.raises(ArgumentError):
        tools.load_scan(None, 0)


def test_writers_take_the_path_first_and_the_old_config_order_warns(tmp_path):
    cfg = sc.MatchConfig()
    new = io_config.write_config(tmp_path / "new.toml", cfg)
    with pytest.warns(DeprecationWarning, match="write_config\\(path, config\\)"):
        old = io_config.write_config(cfg, tmp_path / "old.toml")
    assert new.read_text() == old.read_text()
    with pytest.raises(ArgumentError):
        io_config.write_config(tmp_path / "x.toml", {"clique": {}})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_scans_text(tmp_path / "s.txt", [sc.Scan.from_ranges([1.0])])


# ---------------------------------------------------------------------------------------
# item 10: odometry that is the reference pose
# ---------------------------------------------------------------------------------------
def test_odometry_equal_to_reference_is_said(scan_file, caplog):
    pair = sc.sim.simulate_pair(np.random.default_rng(5))
    same = [
        sc.Scan(s.ranges, s.angles, s.range_min, s.range_max, 0.0, s.reference, s.reference)
        for s in (pair.scan_a, pair.scan_b)
    ]
    write_scans_text(scan_file / "same.txt", same)
    assert sc.io.odometry_is_reference(same)
    assert sc.io.poses_carried(same).startswith("reference only")
    with caplog.at_level("WARNING"):
        run = tools.run_match(scan_file / "same.txt", 0, 1, odometry=True)
    assert any("ground truth" in n for n in run.notes)
    rows = dict((m, v) for m, v, _ in tools.match_rows(run))
    assert rows["poses in the log"].startswith("reference only")
    r = cli_run("match", scan_file / "same.txt", "0", "1", "--odometry")
    assert r.exit_code == 0, r.output
    assert "ground truth" in r.stderr


def test_distinct_odometry_is_not_flagged():
    pair = sc.sim.simulate_pair(np.random.default_rng(5))
    drift = sc.Pose2(0.05, -0.02, 0.01)
    scans = [
        sc.Scan(s.ranges, s.angles, s.range_min, s.range_max, 0.0, s.reference @ drift, s.reference)
        for s in (pair.scan_a, pair.scan_b)
    ]
    assert not sc.io.odometry_is_reference(scans)
    assert sc.io.poses_carried(scans) == "reference and odometry"
    assert sc.io.poses_carried(scans, has_reference=False) == "odometry only"


@pytest.mark.realdata
def test_raw_logs_carry_odometry_only():
    require_log("intel-raw")
    assert sc.datasets.DATASETS["intel-raw"].has_reference is False
    run = tools.run_match("intel-raw", 100, 101)
    assert run.reference is None and run.errors() is None
    assert run.poses == "odometry only"
    assert any("odometry only" in n for n in run.notes)
    with pytest.raises(ScanCliqueError, match="no reference pose"):
        tools.run_validate("intel-raw", cap=1)


# ---------------------------------------------------------------------------------------
# item 13: usage errors, clique table, --help
# ---------------------------------------------------------------------------------------
def test_negative_index_is_one_line(scan_file):
    r = cli_run("match", scan_file / "a.txt", "-1", "2")
    assert_clean_error(r, "-1", "indices start at 0")


def test_out_of_range_option_is_one_line(scan_file):
    assert_clean_error(cli_run("validate", scan_file / "a.txt", "--cap", "-3"), "--cap")
    assert_clean_error(cli_run("features", scan_file / "a.txt", "x"), "index")
    assert_clean_error(cli_run("nosuchcommand"), "nosuchcommand")


def test_help_shows_no_bool_after_plain_flags():
    for args in ([], ["match"], ["validate"], ["clique"]):
        r = cli_run(*args, "--help")
        assert r.exit_code == 0
        assert "<bool>" not in r.stdout, args


def test_clique_table_of_an_unfinished_search_does_not_claim_omega(tmp_path):
    n = 60
    adj = ~np.eye(n, dtype=bool)
    adj[np.random.default_rng(0).random((n, n)) < 0.1] = False
    adj &= adj.T
    dimacs.write_dimacs(tmp_path / "g.clq", adj)
    r = cli_run("clique", tmp_path / "g.clq", "--node-limit", "1")
    assert r.exit_code == 0, r.output
    assert "clique number" not in r.stdout and "largest clique found" in r.stdout
    r = cli_run("clique", tmp_path / "g.clq")
    assert "clique number" in r.stdout


def test_clique_command_uses_vertex_weights(tmp_path):
    # a triangle 1-2-3 of weight 3 and an edge 4-5 of weight 10
    (tmp_path / "w.clq").write_text(
        "p edge 5 4\nn 1 1\nn 2 1\nn 3 1\nn 4 5\nn 5 5\ne 1 2\ne 2 3\ne 1 3\ne 4 5\n"
    )
    r = cli_run("clique", tmp_path / "w.clq")
    assert r.exit_code == 0, r.output
    assert "maximum-weight clique" in r.stdout and "weight 10" in r.stdout
    r = cli_run("clique", tmp_path / "w.clq", "--no-weights")
    assert "ω (clique number)" in r.stdout
