"""The command line (scanclique.cli) through typer's CliRunner, on simulated scans.

Real-data runs are marked ``realdata`` and skipped when the shared logs are absent.
"""

from __future__ import annotations

import json
import math
import runpy
import sys

import numpy as np
import pytest
from conftest import assert_clean_error, require_log
from typer.testing import CliRunner

import scanclique as sc
from scanclique import cli
from scanclique.config import paper_config
from scanclique.io import write_scans_text
from scanclique.io.config import loads_config, read_config
from scanclique.io.dimacs import write_dimacs

runner = CliRunner()
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def invoke(*args: str):
    return runner.invoke(cli.app, [str(a) for a in args])


@pytest.fixture(scope="module")
def pair():
    return sc.sim.simulate_pair(np.random.default_rng(7))


@pytest.fixture(scope="module")
def files(pair, tmp_path_factory):
    """a.txt and b.txt (one scan each), ab.txt (a log of both), bb.txt (two scans)."""
    d = tmp_path_factory.mktemp("scans")
    write_scans_text(d / "a.txt", [pair.scan_a])
    write_scans_text(d / "b.txt", [pair.scan_b])
    write_scans_text(d / "ab.txt", [pair.scan_a, pair.scan_b])
    write_scans_text(d / "bb.txt", [pair.scan_b, pair.scan_a])
    write_scans_text(d / "empty.txt", [])
    return d


# ---------------------------------------------------------------------------------------
# match
# ---------------------------------------------------------------------------------------
def test_match_two_files_prints_the_table(files, pair):
    r = invoke("match", files / "a.txt", files / "b.txt")
    assert r.exit_code == 0, r.output
    for metric in (
        "pose x",
        "pose theta",
        "std x",
        "clique size",
        "mapped line",
        "score",
        "ambiguous",
        "optimal",
        "correspondence graph",
        "time clique",
        "error rotation",
    ):
        assert metric in r.stdout
    assert "Metric" in r.stdout and "Units" in r.stdout


def test_match_log_and_indices_json(files, pair):
    r = invoke("match", files / "ab.txt", 0, 1, "--json")
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert out["scan_a"]["name"] == "ab.txt:0" and out["scan_b"]["name"] == "ab.txt:1"
    assert out["clique_size"] == len(out["pairs"]) > 0
    ref = out["reference"]
    assert ref["x"] == pytest.approx(pair.pose_a_b.x)
    assert out["error"]["translation_m"] < 0.1
    assert out["error"]["rotation_deg"] < 1.0
    assert set(out["std"]) == {"x", "y", "theta"}
    assert out["config"]["pose"]["method"] == "lsq"


def test_match_paper_config_and_save_config(files, tmp_path):
    used = tmp_path / "used.toml"
    r = invoke("match", files / "ab.txt", 0, 1, "--paper", "--json", "--save-config", used)
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["config"]["pose"]["method"] == "median"
    assert read_config(used) == paper_config()
    assert "configuration written" in r.stderr


def test_match_config_file_overrides(files, tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[pose]\nmin_pairs = 3\n")
    r = invoke("match", files / "ab.txt", 0, 1, "--config", cfg, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["config"]["pose"]["min_pairs"] == 3


def test_match_file_with_several_scans_uses_the_first(files):
    r = invoke("match", files / "a.txt", files / "bb.txt", "--json")
    assert r.exit_code == 0, r.output
    assert "bb.txt holds 2 scans; using the first" in r.stderr
    assert json.loads(r.stdout)["notes"] == [
        f"{files / 'bb.txt'} holds 2 scans; using the first (index 0)"
    ]


def test_match_plot(files, tmp_path):
    out = tmp_path / "m.png"
    r = invoke("match", files / "ab.txt", 0, 1, "--plot", out)
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:8] == PNG_MAGIC


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("nofile.log", 1, 2), ["nofile.log", "neither an existing file"]),
        (("{d}/a.txt", "{d}/missing.txt"), ["missing.txt"]),
        (("{d}/ab.txt", 0, 5), ["scan index 5 out of range", "2 scans (0..1)"]),
        (("{d}/ab.txt", "x", 1), ["integer scan index", "'x'"]),
        (("{d}/ab.txt", 3), ["'3' is not a file"]),
        (("{d}/ab.txt",), ["need two scans"]),
        (("{d}/empty.txt", "{d}/a.txt"), ["holds no scan"]),
    ],
)
def test_match_bad_input_is_one_line_exit_2(files, args, words):
    r = invoke("match", *(str(a).format(d=files) for a in args))
    assert_clean_error(r, *words)


def test_match_malformed_scan_file(tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("SCAN 0 -1.5 0.1 0 30 3 1.0 2.0\n")
    r = invoke("match", bad, bad)
    assert_clean_error(r, "bad.txt:1")


@pytest.mark.parametrize(
    ("toml", "words"),
    [
        ("[pose\n", ["bad.toml", "not valid TOML"]),
        ("[features]\nfoo = 1\n", ["bad.toml", "'features.foo'"]),
        ("[pose]\nmin_pairs = 1\n", ["bad.toml", "min_pairs"]),
    ],
)
def test_match_malformed_config(files, tmp_path, toml, words):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(toml)
    assert_clean_error(invoke("match", files / "ab.txt", 0, 1, "-c", cfg), *words)


def test_match_missing_config(files, tmp_path):
    assert_clean_error(
        invoke("match", files / "ab.txt", 0, 1, "-c", tmp_path / "no.toml"), "no.toml"
    )


# ---------------------------------------------------------------------------------------
# features, clique, config, demo, global options
# ---------------------------------------------------------------------------------------
def test_features_table_json_and_plot(files, pair, tmp_path):
    r = invoke("features", files / "ab.txt", 1)
    assert r.exit_code == 0, r.output
    assert "features of ab.txt:1" in r.stdout and "total" in r.stdout
    r = invoke("features", files / "ab.txt", 1, "--json")
    out = json.loads(r.stdout)
    feats = sc.extract_features(pair.scan_b)
    assert out["counts"] == feats.counts()
    assert len(out["points"]) == feats.n_points and len(out["lines"]) == feats.n_lines
    png = tmp_path / "f.png"
    r = invoke("features", files / "a.txt", "--plot", png)
    assert r.exit_code == 0, r.output
    assert png.read_bytes()[:8] == PNG_MAGIC


def test_features_bad_index(files):
    assert_clean_error(invoke("features", files / "ab.txt", 9), "out of range")


@pytest.fixture
def clq(tmp_path):
    # two triangles sharing vertex 2, plus a 4-clique {3, 4, 5, 6}
    edges = [(0, 1), (0, 2), (1, 2), (2, 3), (3, 4), (3, 5), (3, 6), (4, 5), (4, 6), (5, 6)]
    p = tmp_path / "g.clq"
    write_dimacs(p, (np.array(edges), 7))
    return p


def test_clique_table_and_json(clq):
    r = invoke("clique", clq)
    assert r.exit_code == 0, r.output
    assert "4 5 6 7" in r.stdout and "ω" in r.stdout
    r = invoke("clique", clq, "--all", "--json", "--time-limit", 5)
    out = json.loads(r.stdout)
    assert out["omega"] == 4 and out["optimal"] and out["cliques"] == [[4, 5, 6, 7]]


def test_validate_stderr_without_a_terminal_has_no_empty_line(files, tmp_path):
    r = invoke("validate", tmp_path / "nope.log")
    assert_clean_error(r, "nope.log")
    assert r.stderr.endswith(")\n") and "\n\n" not in r.stderr, repr(r.stderr)
    r = invoke("validate", files / "ab.txt", "--cap", "1", "--set", "consecutive", "--no-odometry")
    assert r.exit_code == 0, r.output
    assert r.stderr == "", repr(r.stderr)


def test_clique_too_large_names_the_variable_not_the_library_argument(tmp_path):
    big = tmp_path / "big.clq"
    big.write_text("p edge 100000000 1\n")
    r = invoke("clique", big)
    assert_clean_error(r, "big.clq:1", "PiB", "set SCANCLIQUE_MAX_VERTICES")
    assert "max_vertices=" not in r.stderr


def test_clique_bad_files(tmp_path):
    assert_clean_error(invoke("clique", tmp_path / "none.clq"), "none.clq")
    bad = tmp_path / "bad.clq"
    bad.write_text("p edge 3 1\ne 1 9\n")
    assert_clean_error(invoke("clique", bad), "bad.clq")


@pytest.mark.parametrize("flag", ["--paper", "--default"])
def test_config_prints_toml(flag, tmp_path):
    r = invoke("config", flag)
    assert r.exit_code == 0, r.output
    want = paper_config() if flag == "--paper" else sc.MatchConfig()
    assert loads_config(r.stdout) == want
    r = invoke("config", flag, "-o", tmp_path / "c.toml")
    assert read_config(tmp_path / "c.toml") == want


def test_demo_without_data_simulates(tmp_path, monkeypatch):
    monkeypatch.setenv("SCANCLIQUE_DATA", str(tmp_path / "nonexistent"))
    png = tmp_path / "match.png"
    r = invoke("demo", "--plot", png)
    assert r.exit_code == 0, r.output
    assert "no real data found" in r.stdout and "simulated pair" in r.stdout
    last = r.stdout.strip().splitlines()[-1]
    assert last.startswith("error ") and "vs known pose: success" in last
    assert png.read_bytes()[:8] == PNG_MAGIC


def test_demo_without_data_names_each_place_looked_in_once(tmp_path, monkeypatch):
    # run from the checkout, ../shared/data by the checkout and by the cwd are one directory
    missing = tmp_path / "shared" / "data"
    monkeypatch.delenv("SCANCLIQUE_DATA", raising=False)
    (tmp_path / "repo").mkdir()
    monkeypatch.setattr(sc.datasets, "_repo_root", lambda: tmp_path / "repo")
    monkeypatch.chdir(tmp_path / "repo")
    r = invoke("demo", "--plot", tmp_path / "match.png")
    assert r.exit_code == 0, r.output
    first = r.stdout.splitlines()[0]
    assert first.startswith(f"no real data found in {missing} (set SCANCLIQUE_DATA)"), first
    assert first.count(str(missing)) == 1, first


def test_version_help_and_verbose():
    r = invoke("--version")
    assert r.exit_code == 0 and r.stdout.strip() == f"scanclique {sc.__version__}"
    commands = ("match", "features", "clique", "demo", "validate", "config", "slam", "map")
    for cmd in (*commands, "loops", "places", "places add", "places query", "places info"):
        r = invoke(*cmd.split(), "--help")
        assert r.exit_code == 0 and "Examples" in r.stdout, cmd
    r = invoke("-vv", "config")
    assert r.exit_code == 0


@pytest.mark.parametrize("flag", ["-v", "-vv", "--verbose"])
def test_verbose_after_the_command_says_where_it_goes(files, flag):
    r = invoke("match", files / "a.txt", files / "b.txt", flag)
    assert_clean_error(r, "goes before the command: scanclique", "match ...")
    r = invoke("places", "info", files / "x.db", flag)
    assert_clean_error(r, "goes before the command: scanclique", "places info ...")


def test_python_dash_m(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["scanclique", "--version"])
    with pytest.raises(SystemExit) as exc:
        runpy.run_module("scanclique", run_name="__main__")
    assert exc.value.code in (0, None)
    assert capsys.readouterr().out.strip() == f"scanclique {sc.__version__}"


# ---------------------------------------------------------------------------------------
# output paths: refused before the run (a map of a long log takes minutes), not after it
# ---------------------------------------------------------------------------------------
def test_out_directory_that_is_a_file_is_refused_before_the_run(files, tmp_path):
    a_file = tmp_path / "taken"
    a_file.write_text("")
    # a log that does not exist: the output path is checked first, nothing is read
    for cmd in (("map", tmp_path / "nope.log"), ("slam", tmp_path / "nope")):
        r = invoke(*cmd, "--out", a_file)
        assert_clean_error(r, str(a_file), "not a directory")
        r = invoke(*cmd, "--out", a_file / "sub")
        assert_clean_error(r, "cannot be created", "is not a directory")
        assert not (a_file / "sub").exists()


def test_out_directory_that_exists_or_not_is_accepted(files, tmp_path):
    # the check lets the run go on: the error is then the log's, not the directory's
    for out in (tmp_path / "empty", tmp_path / "new" / "dir"):
        (tmp_path / "empty").mkdir(exist_ok=True)
        r = invoke("map", tmp_path / "nope.log", "--out", out)
        assert_clean_error(r, "nope.log")
        assert "--out" not in r.stderr
    # a directory with files in it: said in a note, then the run goes on
    (tmp_path / "used").mkdir()
    (tmp_path / "used" / "map.pgm").write_text("")
    r = invoke("map", tmp_path / "nope.log", "--out", tmp_path / "used")
    assert r.exit_code == 2
    note, err = r.stderr.strip().splitlines()
    assert note.startswith("note:") and "not empty" in note and "replaced" in note, note
    assert err.startswith("error:") and "nope.log" in err, err


def test_match_save_config_path_checked_before_the_match(files, tmp_path):
    ab = (files / "a.txt", files / "b.txt")
    r = invoke("match", *ab, "--save-config", tmp_path / "nodir" / "used.toml")
    assert_clean_error(r, "nodir", "does not exist")
    r = invoke("match", *ab, "--save-config", tmp_path)
    assert_clean_error(r, "is a directory")
    assert r.stdout == ""


def test_loops_out_and_new_place_database_checked_before_the_run(files, tmp_path):
    r = invoke("loops", files / "ab.txt", "--out", tmp_path / "nodir" / "loops.json")
    assert_clean_error(r, "nodir", "does not exist")
    r = invoke("loops", files / "ab.txt", "--out", tmp_path)
    assert_clean_error(r, "is a directory")
    r = invoke("places", "add", tmp_path / "nodir" / "places.db", files / "ab.txt")
    assert_clean_error(r, "nodir", "does not exist")
    assert not (tmp_path / "nodir").exists()


# ---------------------------------------------------------------------------------------
# the plain functions behind the commands
# ---------------------------------------------------------------------------------------
def test_run_match_and_rows(files, pair):
    run = cli.run_match(files / "ab.txt", 0, 1)
    assert run.reference is not None
    t, r = run.errors()
    assert t < 0.1 and math.degrees(r) < 1.0
    rows = dict((m, v) for m, v, _ in cli.match_rows(run))
    assert rows["clique size"] == str(run.match.clique_size)
    assert run.verdict().startswith("error ")


def test_load_scan_pair_errors(files):
    with pytest.raises(cli.ScanIndexError, match="out of range"):
        cli.load_scan_pair(files / "ab.txt", 0, 2)
    with pytest.raises(IndexError):
        cli.load_scan(files / "ab.txt", -1)
    with pytest.raises(sc.ScanCliqueError):
        cli.load_scan_pair(files / "nope.txt", files / "a.txt")


def test_run_without_pose_has_a_reason_row():
    empty = sc.Scan.from_ranges(np.full(181, np.nan))
    m = sc.match_scans(empty, empty)
    run = cli.MatchRun(empty, empty, m, ("e:0", "e:1"), sc.MatchConfig())
    rows = cli.match_rows(run)
    assert rows[2][0] == "pose" and rows[2][1].startswith("none: ")
    assert run.verdict().startswith("no pose")
    assert run.to_dict()["error"] is None


# ---------------------------------------------------------------------------------------
# real data
# ---------------------------------------------------------------------------------------
@pytest.mark.realdata
def test_match_intel_consecutive_pair():
    require_log("intel")
    r = invoke("match", "intel", 120, 121, "--json")
    assert r.exit_code == 0, r.output
    err = json.loads(r.stdout)["error"]
    assert err["translation_m"] < 0.2 and err["rotation_deg"] < 2.0


@pytest.mark.realdata
def test_match_intel_index_out_of_range():
    require_log("intel")
    assert_clean_error(
        invoke("match", "intel", 120, 910), "scan index 910 out of range", "910 scans"
    )


@pytest.mark.realdata
def test_demo_with_real_data(tmp_path):
    require_log("intel")
    png = tmp_path / "match.png"
    r = invoke("demo", "--plot", png)
    assert r.exit_code == 0, r.output
    assert "Intel Research Lab log, scans 120 and 121" in r.stdout
    assert "vs reference: success" in r.stdout.strip().splitlines()[-1]
    assert png.read_bytes()[:8] == PNG_MAGIC


# ---------------------------------------------------------------------------------------
# The split: library layer in scanclique.tools, light command modules
# ---------------------------------------------------------------------------------------
_HEAVY = ("numpy", "scipy", "numba", "matplotlib")


def _new_modules_of(stmt: str, after: str = "import scanclique") -> list[str]:
    import subprocess

    code = (
        f"import sys\n{after}\nbefore = set(sys.modules)\n{stmt}\n"
        "print('\\n'.join(sorted(set(sys.modules) - before)))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    ).stdout
    return out.split()


def test_cli_package_imports_nothing_heavy_beyond_the_core():
    """The app and every command module load only typer, rich and the standard library:
    what ``import scanclique.cli`` adds to ``import scanclique`` holds no NumPy, SciPy,
    numba or matplotlib module and none of the core's stage modules."""
    new = _new_modules_of("import scanclique.cli")
    assert "scanclique.cli.match" in new  # the command modules were registered
    heavy = [m for m in new if m.split(".")[0] in _HEAVY]
    light = {"scanclique.errors"}  # the exception hierarchy: standard library only
    core = [
        m
        for m in new
        if m.startswith("scanclique.") and not m.startswith("scanclique.cli") and m not in light
    ]
    assert not heavy, heavy
    assert not core, core


def test_tools_import_neither_typer_nor_rich():
    new = _new_modules_of(
        "import scanclique.tools as t\nfor n in t.__all__: getattr(t, n)", after="pass"
    )
    assert "scanclique.tools.runs" in new
    assert not [m for m in new if m.split(".")[0] in ("typer", "rich", "click")]


def test_version_does_not_load_numba():
    """``scanclique --version`` must not import numba (issue 11 item 8). The CLI side is
    held by the test above; this one needs ``import scanclique`` itself to be light."""
    import subprocess

    base = subprocess.run(
        [sys.executable, "-c", "import sys, scanclique; print('numba' in sys.modules)"],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    ).stdout.strip()
    if base == "True":
        pytest.skip("`import scanclique` itself loads numba (the core's package init)")
    r = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "scanclique", "--version"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0 and r.stdout.startswith("scanclique ")
    assert "numba" not in r.stderr


def test_old_names_still_resolve_from_cli():
    from scanclique import tools

    for name in (
        "run_match",
        "run_demo",
        "run_validate",
        "load_scan",
        "load_scan_pair",
        "load_config",
        "MatchRun",
        "ValidateRun",
        "odometry_path",
        "match_rows",
        "validation_rows",
        "feature_rows",
        "features_to_dict",
        "confusion_rows",
    ):
        assert getattr(cli, name) is getattr(tools, name)
    with pytest.raises(AttributeError):
        cli.no_such_name  # noqa: B018


# ---------------------------------------------------------------------------------------
# configurations of map and slam: --config, --save-config, scanclique config --for
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("which", ["map", "slam"])
def test_config_for_map_and_slam_round_trips(which, tmp_path):
    from scanclique.mapping import MapConfig
    from scanclique.slam import SlamConfig

    cls = MapConfig if which == "map" else SlamConfig
    r = invoke("config", "--for", which)
    assert r.exit_code == 0, r.output
    assert f"({cls.__name__})" in r.stdout.splitlines()[0]
    assert loads_config(r.stdout, cls=cls) == cls()
    r = invoke("config", "--for", which, "-o", tmp_path / "c.toml")
    assert read_config(tmp_path / "c.toml", cls=cls) == cls()


def test_config_flags_that_exclude_each_other():
    assert_clean_error(invoke("config", "--default", "--paper"), "--paper and --default")
    assert_clean_error(invoke("config", "--for", "slam", "--paper"), "--paper", "--for slam")
    assert_clean_error(invoke("config", "--for", "places"), "--for must be one of")


@pytest.fixture(scope="module")
def drive(drive_log):
    return drive_log


def test_map_config_and_save_config(drive, tmp_path):
    from scanclique.mapping import MapConfig

    cfg_file = tmp_path / "map.toml"
    cfg_file.write_text("[loops]\nenabled = false\n\n[occupancy]\nresolution = 0.1\n")
    out, used = tmp_path / "run", tmp_path / "used.toml"
    r = invoke("map", drive, "--out", out, "-c", cfg_file, "--save-config", used, "--json")
    assert r.exit_code == 0, r.output
    saved = read_config(used, cls=MapConfig)
    assert not saved.loops.enabled and saved.occupancy.resolution == 0.1
    assert saved.front_end == MapConfig().front_end
    report = json.loads((out / "report.json").read_text())
    assert report["config"]["loops"]["enabled"] is False
    assert "resolution: 0.1" in (out / "map.yaml").read_text()


def test_map_bad_config_is_refused_before_the_run(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[loops]\nradius_per_km = 1\n")
    # the log does not exist: the configuration is read first
    r = invoke("map", tmp_path / "nope.log", "--out", tmp_path / "o", "-c", bad)
    assert_clean_error(r, "bad.toml", "loops.radius_per_km")
    r = invoke("map", tmp_path / "nope.log", "--out", tmp_path / "o", "--save-config", tmp_path)
    assert_clean_error(r, "is a directory")


def test_save_config_may_go_into_the_new_out_directory(drive, tmp_path):
    from scanclique.mapping import MapConfig

    out = tmp_path / "runs" / "new"  # neither runs/ nor runs/new exists yet
    r = invoke("map", drive, "--out", out, "--save-config", out / "used.toml", "--json")
    assert r.exit_code == 0, r.output
    assert read_config(out / "used.toml", cls=MapConfig) == MapConfig()
    # any other missing directory is still refused, before the run
    for cmd in (
        ("map", tmp_path / "nope.log", "--out", tmp_path / "o2"),
        ("slam", tmp_path / "nope"),
    ):
        r = invoke(*cmd, "--save-config", tmp_path / "missing" / "used.toml")
        assert_clean_error(r, "missing", "does not exist")
    vp = tmp_path / "vp"
    r = invoke("slam", tmp_path / "nope", "--out", vp, "--save-config", vp / "used.toml")
    assert_clean_error(r, "nope")  # past the path checks: the data set is what is missing


def test_map_removes_its_own_stale_figure_only(drive, tmp_path):
    out = tmp_path / "run"
    r = invoke("map", drive, "--out", out, "--plot")
    assert r.exit_code == 0, r.output
    assert (out / "map.png").read_bytes()[:8] == PNG_MAGIC
    r = invoke("map", drive, "--out", out)  # no --plot: the old figure would mislead
    assert r.exit_code == 0, r.output
    assert not (out / "map.png").exists()
    assert "removed" in r.stderr and "map.png" in r.stderr
    assert json.loads((out / "report.json").read_text())["removed"] == [str(out / "map.png")]
    # a map.png that no run of scanclique listed stays
    (out / "map.png").write_bytes(b"mine")
    r = invoke("map", drive, "--out", out)
    assert r.exit_code == 0, r.output
    assert (out / "map.png").read_bytes() == b"mine"
    # --json says what it removed too
    assert invoke("map", drive, "--out", out, "--plot").exit_code == 0
    r = invoke("map", drive, "--out", out, "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["removed"] == [str(out / "map.png")]
    assert not (out / "map.png").exists()


def test_workers_has_both_short_forms(tmp_path):
    # accepted as options: the error is then the log's
    for flag in ("-w", "-j"):
        r = invoke("map", tmp_path / "nope.log", "--out", tmp_path / "o", flag, "1")
        assert_clean_error(r, "nope.log")
        r = invoke("loops", tmp_path / "nope.log", flag, "1")
        assert_clean_error(r, "nope.log")


@pytest.mark.realdata
def test_slam_config_and_save_config(tmp_path, data_dir):
    """A short stretch of Victoria Park (its first rows) run with a configuration file."""
    from scanclique.slam import SlamConfig

    src = data_dir / "victoria-park"
    if not (src / "measurements.dat").is_file():
        pytest.skip(f"Victoria Park not found in {data_dir}")
    vp = tmp_path / "vp"
    vp.mkdir()
    for name, rows in (("measurements.dat", 1500), ("inputs.dat", 2000), ("gps.dat", 200)):
        lines = (src / name).read_text().splitlines(keepends=True)[:rows]
        (vp / name).write_text("".join(lines))
    cfg_file = tmp_path / "slam.toml"
    cfg_file.write_text('max_range = 20.0\n\n[association]\nattribute_sigma = "none"\n')
    used, out = tmp_path / "used.toml", tmp_path / "out"
    r = invoke("slam", vp, "-a", "nn", "--out", out, "-c", cfg_file, "--save-config", used)
    assert r.exit_code == 0, r.output
    saved = read_config(used, cls=SlamConfig)
    assert saved.max_range == 20.0 and saved.association.attribute_sigma is None
    assert saved.sigma_range == SlamConfig().sigma_range
    report = json.loads((out / "report.json").read_text())
    assert report["config"]["max_range"] == 20.0


@pytest.mark.realdata
def test_clique_finds_a_shared_graph_by_its_bare_name(data_dir, tmp_path, monkeypatch):
    if not (data_dir / "dimacs" / "hamming6-2.clq").is_file():
        pytest.skip(f"the DIMACS graphs are not in {data_dir}")
    monkeypatch.chdir(tmp_path)  # not the dimacs directory: the help's example works anyway
    r = invoke("clique", "hamming6-2.clq", "--json")
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["omega"] == 32
    assert_clean_error(invoke("clique", "no-such-graph.clq"), "no-such-graph.clq")
    assert_clean_error(invoke("clique", tmp_path / "hamming6-2.clq"), "hamming6-2.clq")


def test_map_odometry_is_checked_by_default_and_forced_by_the_flag(tmp_path):
    """``scanclique map`` without a flag sets a zero odometry aside (the sample of matched
    pairs says it does not move), in the batch and the online mode alike; ``--odometry``
    maps with it as it is (before, the flag was the automatic choice and nothing could
    force the odometry); ``--no-odometry`` maps from the scans alone."""
    import dataclasses

    from scanclique.mapping.run import run_map

    rng = np.random.default_rng(11)
    scans = sc.sim.simulate_trajectory(rng, sc.sim.office_world(rng, length=16.0), 40, step=0.25)
    zero = sc.Pose2(0.0, 0.0, 0.0)
    log = tmp_path / "zeros.txt"
    write_scans_text(log, [dataclasses.replace(s, odometry=zero) for s in scans])

    def report(*flags):
        out = tmp_path / f"run{len(list(tmp_path.iterdir()))}"
        r = invoke("map", log, "--out", out, "--json", *flags)
        assert r.exit_code == 0, r.output
        return json.loads((out / "report.json").read_text())

    auto = report()
    assert auto["used_odometry"] is False
    assert auto["odometry_scale"]["median_scale"] < 0.5 and auto["odometry_scale"]["steps"] >= 20
    forced = report("--odometry")
    assert forced["used_odometry"] is True
    none = report("--no-odometry")
    assert none["used_odometry"] is False and none["odometry_scale"] is None
    online = run_map(log, tmp_path / "online", plot=False, online=True)
    assert not online.result.used_odometry and online.result.odometry_scale.scaled
