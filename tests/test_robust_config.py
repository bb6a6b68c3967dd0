"""Robustness audit (s13): configuration values, CLI numeric options, output paths.

A configuration value that is NaN, infinite where no limit is meant, negative, zero
where zero means nothing, of the wrong type, or not one of a field's choices is a
:class:`~scanclique.errors.ConfigError` naming the record and the field, raised when the
record is built (so before any work), and a TOML file's naming the file too. The CLI
exits 2 with one ``error:`` line. The matcher's own records (``MatchConfig`` and its
sections) are covered by ``test_config``; these are the mapper's and the filter's.
"""

from __future__ import annotations

import dataclasses
import math

import pytest
from conftest import assert_clean_error
from typer.testing import CliRunner

from scanclique import cli
from scanclique.config import MatchConfig, a_or_an
from scanclique.errors import ConfigError, ScanCliqueError
from scanclique.io.config import loads_config
from scanclique.mapping import MapConfig
from scanclique.mapping.config import (
    BackEndConfig,
    FrontEndConfig,
    LoopConfig,
    OccupancyConfig,
)
from scanclique.match import match_scans
from scanclique.slam import SlamConfig
from scanclique.slam.association import AssociationConfig
from scanclique.uncertainty import OdometryNoise

runner = CliRunner()
NAN, INF = math.nan, math.inf


def invoke(*args):
    return runner.invoke(cli.app, [str(a) for a in args])


# ---------------------------------------------------------------------------------------
# the mapper's and the filter's records had no type check and few range checks: NaN,
# strings and negative counts went into the run (a NaN gate or score silently changed
# the map, a wrong-typed section was used or replaced by the defaults, a typo of a
# choice ran the other choice, a negative margin or clique_limit ended in a traceback)
# ---------------------------------------------------------------------------------------
BAD_FIELDS = [
    (FrontEndConfig, "icp_gate", NAN),
    (FrontEndConfig, "icp_gate", 0.0),
    (FrontEndConfig, "refine_iterations", -1),
    (FrontEndConfig, "refine_max_correspondence", NAN),
    (FrontEndConfig, "refine_min_correspondence", 0.0),
    (FrontEndConfig, "refine_max_shift", -0.1),
    (FrontEndConfig, "icp_min_fitness", -INF),
    (FrontEndConfig, "icp_score_tie", INF),
    (FrontEndConfig, "scan_min_score", NAN),
    (FrontEndConfig, "refine", "no"),
    (FrontEndConfig, "max_seeds", 2.5),
    (FrontEndConfig, "refine_max_turn", "0.1"),
    (FrontEndConfig, "odometry_noise", None),
    (FrontEndConfig, "velocity_noise", (0.1, 0.1)),
    (LoopConfig, "enabled", "false"),
    (LoopConfig, "growth", NAN),
    (LoopConfig, "heading_growth", -0.1),
    (LoopConfig, "local", -1),
    (LoopConfig, "per_keyframe", -2),
    (LoopConfig, "separation", -1),
    (LoopConfig, "pcm_anchor_batches", -1),
    (LoopConfig, "min_score", NAN),
    (LoopConfig, "pcm_gate", "0.99"),  # a TypeError from the comparison before
    (LoopConfig, "every", 10**30),
    (LoopConfig, "max_turn", 45.0),  # degrees: larger than any turn, the rule off silently
    (LoopConfig, "max_turn", 0.0),
    (LoopConfig, "max_shift", 0.0),  # every closure beyond the drift radius refused
    (LoopConfig, "max_shift", NAN),  # silently the drift radius alone (max() skips NaN)
    (LoopConfig, "max_shift", -INF),
    (LoopConfig, "max_conflict", NAN),  # "conflict > NaN" is never true: the rule off silently
    (LoopConfig, "max_conflict", -0.05),  # every twin test refused
    (FrontEndConfig, "keyframe_angle", 10.0),  # degrees: keyframes by distance alone, silently
    (FrontEndConfig, "refine_max_turn", 5.0),
    (BackEndConfig, "max_iterations", 2.5),
    (OccupancyConfig, "margin", -100.0),  # negative dimensions (ValueError) before
    (OccupancyConfig, "margin", NAN),  # cannot convert NaN to integer before
    (OccupancyConfig, "log_odds_miss", NAN),  # an all-unknown grid before
    (OccupancyConfig, "log_odds_miss", 0.5),  # passes marked cells occupied
    (OccupancyConfig, "free_on_no_return", 1),
    (MapConfig, "loops", "x"),
    (MapConfig, "match", {}),
    (MapConfig, "occupancy", LoopConfig()),
    (SlamConfig, "sigma_range", 0.0),
    (SlamConfig, "sigma_range", -0.5),  # squared: silently 0.5 before
    (SlamConfig, "sigma_range", NAN),  # an empty map before
    (SlamConfig, "sigma_bearing", INF),
    (SlamConfig, "sigma_xy_rate", "0.1"),  # a TypeError at the first prediction before
    (SlamConfig, "sigma_xy_distance", -0.05),
    (SlamConfig, "sigma_theta_distance", NAN),
    (SlamConfig, "sigma_theta_turn", INF),
    (SlamConfig, "sensor_fov", -1.0),
    (SlamConfig, "max_range", -1.0),
    (SlamConfig, "max_range", NAN),
    (SlamConfig, "visible_range", NAN),
    (SlamConfig, "confirm_range", NAN),
    (SlamConfig, "confirm_hits", 0),
    (SlamConfig, "confirm_hits", 2.5),
    (SlamConfig, "max_misses", -1),
    (SlamConfig, "tentative_scans", 0),
    (SlamConfig, "update_iterations", 0),
    (SlamConfig, "control_bias_sigma", -1.0),
    (SlamConfig, "speed_scale_sigma", -0.05),
    (SlamConfig, "bearing_bias_sigma", NAN),
    (SlamConfig, "initial_sigma", (1.0, 2.0)),  # negative dimensions (ValueError) before
    (SlamConfig, "initial_sigma", (0.1, 0.1, NAN)),
    (SlamConfig, "initial_sigma", [0.1, 0.1, 0.1]),
    (SlamConfig, "init_range", (5.0, 1.0)),
    (SlamConfig, "init_range", (-1.0, INF)),
    (SlamConfig, "tentative_update", "Full"),  # ran the "landmark" update before
    (SlamConfig, "association", "x"),  # replaced by the defaults before
    (AssociationConfig, "gate_probability", 1.0),
    (AssociationConfig, "gate_probability", NAN),
    (AssociationConfig, "new_probability", 0.0),
    (AssociationConfig, "ambiguity_probability", 2.0),
    (AssociationConfig, "invariant_sigmas", -1.0),
    (AssociationConfig, "attribute_tolerance", -1.0),
    (AssociationConfig, "attribute_sigma", (0.0, 0.0)),
    (AssociationConfig, "attribute_sigma", (NAN, 0.1)),
    (AssociationConfig, "ambiguity", "Distinct"),  # ran "conflict" before
    (AssociationConfig, "clique_limit", -1),  # max() of an empty sequence before
    (AssociationConfig, "node_limit", 0),
    (AssociationConfig, "clique_individual_gate", "yes"),
]


@pytest.mark.parametrize(
    "cls, name, value", BAD_FIELDS, ids=[f"{c.__name__}.{n}={v!r}" for c, n, v in BAD_FIELDS]
)
def test_a_bad_field_is_a_config_error_naming_it(cls, name, value):
    with pytest.raises(ConfigError, match=rf"{cls.__name__}\.{name} must "):
        dataclasses.replace(cls(), **{name: value})


GOOD_FIELDS = [  # the documented meanings of the edge values
    (SlamConfig, "max_range", None),  # no limit
    (SlamConfig, "max_range", INF),
    (SlamConfig, "visible_range", INF),
    (SlamConfig, "confirm_range", None),
    (SlamConfig, "init_range", (0.0, INF)),
    (SlamConfig, "initial_sigma", (0.0, 0.0, 0.0)),  # a known start
    (SlamConfig, "sigma_xy_rate", 0.0),
    (SlamConfig, "sigma_xy_distance", 0.0),
    (SlamConfig, "sigma_theta_turn", 0.0),
    (SlamConfig, "control_bias_sigma", 0.1),
    (SlamConfig, "speed_scale_sigma", None),  # the speed as logged
    (SlamConfig, "tentative_update", "landmark"),
    (AssociationConfig, "attribute_sigma", None),
    (AssociationConfig, "attribute_sigma", (0.1, 0.0)),
    (AssociationConfig, "ambiguity", "conflict"),
    (LoopConfig, "per_keyframe", 0),  # no loop candidates
    (LoopConfig, "min_score", -INF),
    (FrontEndConfig, "icp_min_score", -0.5),  # raw-scan scores can be negative
    (OccupancyConfig, "log_odds_miss", 0.0),  # passes leave cells alone
    (OccupancyConfig, "margin", 0.0),
]


@pytest.mark.parametrize(
    "cls, name, value", GOOD_FIELDS, ids=[f"{c.__name__}.{n}={v!r}" for c, n, v in GOOD_FIELDS]
)
def test_edge_values_with_a_documented_meaning_are_kept(cls, name, value):
    cfg = dataclasses.replace(cls(), **{name: value})
    assert getattr(cfg, name) == value


def test_the_defaults_and_the_sensor_configurations_are_valid():
    from scanclique.slam.sim import room_config

    assert MapConfig() == MapConfig() and SlamConfig() == SlamConfig()
    cfg = SlamConfig.for_sensor(0.2, 0.03, None, attribute_sigma=(0.1, 0.0))
    assert cfg.max_range is None and cfg.visible_range == INF
    assert room_config().max_range == 5.0


# --- the same through a TOML file given with -c: the error names the file and the field --
TOML_CASES = [
    ("map", "[front_end]\nicp_gate = nan\n", "FrontEndConfig.icp_gate"),
    ("map", "[occupancy]\nmargin = -1.0\n", "OccupancyConfig.margin"),
    ("map", "[occupancy]\nlog_odds_miss = inf\n", "OccupancyConfig.log_odds_miss"),
    ("map", "[loops]\nlocal = -1\n", "LoopConfig.local"),
    ("slam", "sigma_range = nan\n", "SlamConfig.sigma_range"),
    ("slam", "max_range = -inf\n", "SlamConfig.max_range"),
    ("slam", "initial_sigma = [nan, 0, 0]\n", "SlamConfig.initial_sigma"),
    ("slam", 'tentative_update = "Full"\n', "SlamConfig.tentative_update"),
    ("slam", "[association]\ngate_probability = 1\n", "AssociationConfig.gate_probability"),
    ("slam", '[association]\nambiguity = "x"\n', "AssociationConfig.ambiguity"),
]


@pytest.mark.parametrize("command, text, field", TOML_CASES)
def test_a_bad_value_in_a_configuration_file_stops_the_command_first(
    tmp_path, command, text, field
):
    conf = tmp_path / "bad.toml"
    conf.write_text(text)
    out = tmp_path / "out"
    data = tmp_path / "no-such-log"  # the configuration is read before the data
    r = invoke(command, data, "--out", out, "-c", conf)
    assert_clean_error(r, "bad.toml", field)
    assert not out.exists()


# ---------------------------------------------------------------------------------------
# CLI numeric options: typer's range checks where the option is declared, the library's
# check (one ConfigError line) where the bound depends on the machine
# ---------------------------------------------------------------------------------------
def _scan_text(tmp_path):
    import numpy as np

    import scanclique as sc
    from scanclique.io import write_scans_text

    rng = np.random.default_rng(0)
    scans = sc.sim.simulate_trajectory(rng, sc.sim.office_world(np.random.default_rng(0)), 3)
    path = tmp_path / "s.txt"
    write_scans_text(path, scans)
    return path


def _tiny_victoria_park(d):
    d.mkdir()
    (d / "measurements.dat").write_text("0.5 10.0 1.0 0.3\n1.0 10.0 1.0 0.3\n")
    (d / "inputs.dat").write_text("0.0 1.0 0.0\n")
    (d / "gps.dat").write_text("0.0 0.0 0.0\n")
    return d


# a worker count beyond the machine forked every process at once (--workers 100000 forked
# thousands on a 2-core machine until the system refused), or 10**12 ended in a traceback
@pytest.mark.parametrize("command", ["map", "loops"])
def test_a_worker_count_beyond_the_machine_is_refused_before_any_fork(tmp_path, command):
    from scanclique._workers import max_workers

    log = _scan_text(tmp_path)
    out = tmp_path / "out"
    extra = ["--out", out] if command == "map" else []
    for n in (10**12, max_workers() + 1):
        assert_clean_error(invoke(command, log, *extra, "--workers", n), "--workers", str(n))
    assert not out.exists()


def test_map_scans_checks_its_worker_count_before_the_scans():
    from scanclique.mapping import map_scans

    for bad in (0, -1, 2.0, 10**6):  # an empty log hid them (the check was the verifier's)
        with pytest.raises(ConfigError, match="map_scans: workers must be an integer from 1"):
            map_scans([], workers=bad)
    assert map_scans([], workers=2).poses == ()


# --clutter 10**5 ran out of memory in the association (10**12 at once), a negative --seed
# with clutter ended in numpy's ValueError traceback
@pytest.mark.parametrize(
    "args, word",
    [
        (["--clutter", "101"], "--clutter"),
        (["--clutter", "1000000000000"], "--clutter"),
        (["--clutter", "1", "--seed", "-1"], "--seed"),
    ],
)
def test_slam_clutter_and_seed_are_bounded(tmp_path, args, word):
    d = _tiny_victoria_park(tmp_path / "vp")
    assert_clean_error(invoke("slam", d, *args), word)


def test_run_slam_checks_clutter_and_seed_before_reading(tmp_path):
    from scanclique.slam.run import MAX_CLUTTER, run_slam

    missing = tmp_path / "no-such-dir"
    for kw in ({"clutter": MAX_CLUTTER + 1}, {"clutter": -1}, {"clutter": 2.5}, {"seed": -1}):
        with pytest.raises(ConfigError, match=f"run_slam: {next(iter(kw))} must be"):
            run_slam(missing, **kw)
    r = invoke("slam", _tiny_victoria_park(tmp_path / "vp"), "--clutter", MAX_CLUTTER, "--json")
    assert r.exit_code == 0, r.output


# ---------------------------------------------------------------------------------------
# output paths: refused before the run, not when the results are written
# ---------------------------------------------------------------------------------------
def test_output_directories_under_a_file_or_that_are_a_file(tmp_path):
    log = _scan_text(tmp_path)
    vp = _tiny_victoria_park(tmp_path / "vp")
    f = tmp_path / "file"
    f.write_text("kept")
    for args in (["map", log, "--out"], ["slam", vp, "--out"]):
        assert_clean_error(invoke(*args, f / "sub"), "is not a directory")
        assert_clean_error(invoke(*args, f), "exists and is not a directory")
        # a name longer than the file system allows (an OSError escaped: session 46)
        assert_clean_error(invoke(*args, tmp_path / ("x" * 300)), "File name too long")
    assert f.read_text() == "kept"


# a directory in the way of one of the command's files failed after the whole run, with
# the files before it written and those after it not
@pytest.mark.parametrize(
    "command, name",
    [
        ("map", "report.json"),
        ("map", "map.pgm"),
        ("map", "trajectory.tum"),
        ("slam", "landmarks.csv"),
        ("slam", "report.json"),
    ],
)
def test_a_directory_in_the_way_of_an_output_file_is_refused_first(tmp_path, command, name):
    out = tmp_path / "out"
    (out / name).mkdir(parents=True)
    missing = tmp_path / "no-such-data"  # refused before the data are even looked for
    assert_clean_error(invoke(command, missing, "--out", out), name, "is a directory")
    if name == "report.json":  # the last file: every other one was written before
        source = _scan_text(tmp_path) if command == "map" else _tiny_victoria_park(tmp_path / "vp")
        assert_clean_error(invoke(command, source, "--out", out), name, "is a directory")
        assert sorted(p.name for p in out.iterdir()) == [name]


def test_the_output_names_are_the_files_written(tmp_path):
    from scanclique.mapping.run import output_names as map_names
    from scanclique.slam.run import output_names as slam_names

    r = invoke("map", _scan_text(tmp_path), "--out", tmp_path / "m", "--json")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "m").iterdir()) == sorted(map_names(plot=False))
    r = invoke("map", _scan_text(tmp_path), "--out", tmp_path / "o", "--json", "--online")
    assert r.exit_code == 0, r.output
    written = sorted(p.name for p in (tmp_path / "o").iterdir())
    assert written == sorted(map_names(plot=False, online=True))
    vp = _tiny_victoria_park(tmp_path / "vp")
    r = invoke("slam", vp, "--out", tmp_path / "s", "--json")  # map.png with --out
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "s").iterdir()) == sorted(slam_names(plot=True))
    r = invoke("slam", vp, "--out", tmp_path / "s2", "--json", "--no-plot")
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "s2").iterdir()) == sorted(slam_names())


def test_an_empty_out_is_not_the_current_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # '' wrote the map's five files here, replacing any
    log = _scan_text(tmp_path)
    assert_clean_error(invoke("map", log, "--out", ""), "--out is empty")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.txt"]


# ---------------------------------------------------------------------------------------
# the occupancy grid: max_range=1e300 with free_on_no_return walked without end (the cell
# index of the beam's end was not an integer), resolution=1e-7 or margin=1e9 asked numpy
# for petabytes (a MemoryError traceback after the whole mapping run)
# ---------------------------------------------------------------------------------------
def _no_return_scan():
    import numpy as np

    import scanclique as sc

    angles = np.linspace(-math.pi / 2, math.pi / 2, 61)
    r = np.full(61, 3.0)
    r[::6] = 80.0  # no return
    return sc.Scan(r, angles, 0.0, 80.0)


@pytest.mark.parametrize(
    "kw, field",
    [
        ({"max_range": 1e300}, "max_range"),
        ({"max_range": 1e7}, "max_range"),
        ({"resolution": 1e-7}, "resolution"),
    ],
)
def test_occupancy_limits_that_keep_cell_indices_integers(kw, field):
    with pytest.raises(ConfigError, match=rf"OccupancyConfig\.{field} must be"):
        OccupancyConfig(**kw)


def test_an_occupancy_grid_beyond_the_cell_limit_names_the_resolution():
    from scanclique.geometry import Pose2
    from scanclique.mapping.occupancy import occupancy_grid

    for kw in ({"margin": 1e9}, {"resolution": 1e-4}):
        with pytest.raises(ConfigError, match=r"cells .*OccupancyConfig\.resolution="):
            occupancy_grid([_no_return_scan()], [Pose2.identity()], OccupancyConfig(**kw))


def test_a_long_free_beam_stops_where_it_leaves_the_grid():
    from scanclique.geometry import Pose2
    from scanclique.mapping.occupancy import occupancy_grid

    scan, pose = _no_return_scan(), [Pose2.identity()]
    near = occupancy_grid([scan], pose, OccupancyConfig(max_range=30.0, free_on_no_return=True))
    far = occupancy_grid([scan], pose, OccupancyConfig(max_range=1e6, free_on_no_return=True))
    assert far.shape == near.shape  # the grid is sized on the hits
    assert abs(int((far.log_odds < 0).sum()) - int((near.log_odds < 0).sum())) < 10


# --max-range of a log that is not CARMEN was ignored whatever its value (-1, 0, nan: the
# command ran); the CARMEN reader refused them. Now every format refuses them.
@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf"])
def test_a_bad_max_range_is_refused_whatever_the_log_format(tmp_path, value):
    from scanclique.io import read_scans

    log = _scan_text(tmp_path)
    assert_clean_error(invoke("features", log, 0, "--max-range", value), "max_range")
    with pytest.raises(ConfigError, match="max_range must be a positive number"):
        read_scans(log, max_range=float(value))
    assert len(read_scans(log, max_range=30.0)) == 3  # a good one is still ignored here


def test_an_unknown_top_level_key_of_a_slam_file_lists_keys_and_tables(tmp_path):
    conf = tmp_path / "slam.toml"
    conf.write_text("[associaton]\nnode_limit = 1\n")  # 'known tables: sigma_range, ...'
    r = invoke("slam", tmp_path / "vp", "-c", conf)
    assert_clean_error(r, "slam.toml", "unknown key 'associaton'", "known keys and tables")
    conf.write_text("[refine]\ncandidates = 1\n")
    r = invoke("map", tmp_path / "log", "--out", tmp_path / "out", "-c", conf)
    assert_clean_error(r, "unknown key 'refine'", "known tables: match, front_end")


def test_an_empty_slam_out_is_not_the_current_directory(tmp_path, monkeypatch):
    vp = _tiny_victoria_park(tmp_path / "vp")
    monkeypatch.chdir(tmp_path)  # '' wrote trajectory.tum, landmarks.csv... here
    assert_clean_error(invoke("slam", vp, "--out", ""), "--out is empty")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["vp"]
    r = invoke("slam", vp, "--out", "runs", "--json")  # a relative --out still works
    assert r.exit_code == 0, r.output
    assert (tmp_path / "runs" / "report.json").is_file()


@pytest.mark.parametrize(
    "args, kw",
    [
        (("x", 0.03, 5.0), {}),  # a ValueError from float('x') before
        (("0.2", 0.03, 5.0), {}),  # taken as 0.2 before
        ((0.2, 0.03, "5"), {}),
        ((0.2, 0.03, 5.0, True), {}),  # fov=True was 1.0 rad
        ((0.2, 0.03, 5.0), {"association": "x"}),  # an AttributeError before
    ],
)
def test_for_sensor_takes_numbers_only(args, kw):
    with pytest.raises(ConfigError, match="SlamConfig"):
        SlamConfig.for_sensor(*args, **kw)


@pytest.mark.parametrize(
    "kw, converted",
    [
        ({"sensor_fov": 180.0}, "3.14159"),  # half of it was 90 rad before: everything in view
        ({"sigma_bearing": 3.0}, "0.0523599"),  # a bearing sigma of 172 deg before
        ({"sensor_fov": 360.0}, "6.28319"),
    ],
)
def test_degrees_given_for_radians_are_refused(kw, converted):
    """sensor_fov above 2 pi and sigma_bearing above pi / 4 cannot be radians: refused,
    with the value in radians in the message; the limits themselves are accepted."""
    with pytest.raises(ConfigError, match=f"is in radians.*math.radians.*{converted}"):
        SlamConfig(**kw)
    with pytest.raises(ConfigError, match="in radians"):
        SlamConfig.for_sensor(0.2, kw.get("sigma_bearing", 0.05), 5.0, kw.get("sensor_fov", 1.0))
    assert SlamConfig(sensor_fov=2 * math.pi, sigma_bearing=math.pi / 4).sensor_fov == 2 * math.pi


# --- s14: "must be a AssociationConfig": the article before a vowel ---------------------
@pytest.mark.parametrize(
    "build, words",
    [
        (lambda: SlamConfig(association={}), "SlamConfig.association must be an AssociationConfig"),
        (lambda: MapConfig(occupancy=1), "MapConfig.occupancy must be an OccupancyConfig"),
        (
            lambda: FrontEndConfig(odometry_noise=None),
            "FrontEndConfig.odometry_noise must be an OdometryNoise",
        ),
        (lambda: MatchConfig(clique={}), "MatchConfig.clique must be a CliqueConfig"),
        (lambda: match_scans(None, None), "match_scans: a must be a Scan"),
        (
            lambda: loads_config("", base=SlamConfig(), cls=AssociationConfig),
            "base is a SlamConfig, not an AssociationConfig",
        ),
    ],
)
def test_a_record_of_the_wrong_class_is_named_with_its_article(build, words):
    with pytest.raises(ScanCliqueError) as info:
        build()
    assert words in str(info.value)


def test_a_or_an():
    assert [a_or_an(n) for n in ("AssociationConfig", "OdometryNoise", "Unicycle", "Scan")] == [
        "an AssociationConfig",
        "an OdometryNoise",
        "a Unicycle",
        "a Scan",
    ]


# --- s14: OdometryNoise names the field at fault; scaled() checks its factor ------------
@pytest.mark.parametrize("name", ["floor_metres", "floor_radians"])
def test_a_zero_odometry_floor_is_named_alone(name):
    with pytest.raises(ConfigError, match=rf"^OdometryNoise\.{name} must be a positive") as info:
        OdometryNoise(**{name: 0.0})
    other = {"floor_metres", "floor_radians"} - {name}
    assert other.pop() not in str(info.value)


@pytest.mark.parametrize("factor", ["2", None, True, -1.0, NAN, INF])
def test_odometry_noise_scaled_refuses_a_bad_factor(factor):
    with pytest.raises(ConfigError, match="OdometryNoise.scaled: factor must be a positive"):
        OdometryNoise().scaled(factor)


@pytest.mark.parametrize(
    "section, name, value",
    [("features", "merge_angle", 5.0), ("features", "corner_min_angle", 35.0),
     ("refine", "distinct_radians", 5.0)],
)  # fmt: skip
def test_an_angle_in_degrees_is_refused_saying_so(section, name, value):
    """Angles are radians; one above pi (no turn is larger) is degrees given for radians,
    which silently changed what it bounds (a 5-degree merge angle read as 5 rad merged
    every pair of lines)."""
    sub = getattr(MatchConfig(), section)
    with pytest.raises(ConfigError, match=rf"{type(sub).__name__}\.{name} must be at most pi") as e:
        dataclasses.replace(sub, **{name: value})
    assert "degrees?" in str(e.value)
    dataclasses.replace(sub, **{name: math.pi})  # pi itself is an angle
