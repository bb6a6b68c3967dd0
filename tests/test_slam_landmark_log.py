"""Landmark logs in plain text: one's own range-bearing data with ground truth, read by
``slam.read_landmark_log`` and run by ``run_slam`` / ``scanclique slam DIR``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import assert_clean_error
from typer.testing import CliRunner

from scanclique import cli, slam
from scanclique.errors import ArgumentError, ConfigError, DataNotFoundError, ParseError
from scanclique.slam.metrics import truth_error
from scanclique.slam.outputs import write_landmark_log
from scanclique.slam.run import run_slam, victoria_park_model
from scanclique.slam.sim import room_config, simulate_room


@pytest.fixture(scope="module")
def room():
    return simulate_room(0, duration=90.0, config=room_config())


@pytest.fixture(scope="module")
def room_log(room, tmp_path_factory):
    truth = np.column_stack([room.times, room.poses])
    d = tmp_path_factory.mktemp("room")
    return write_landmark_log(
        d, room.steps, model=slam.Unicycle(), truth=truth, landmarks=room.landmarks
    )


def _events(steps):
    """The steps that carry something (frames that saw nothing have no row in the files)."""
    return [s for s in steps if s.control is not None or s.n_observations]


def test_a_written_log_reads_back_the_same_steps(room, room_log):
    log = slam.read_landmark_log(room_log)
    want = _events(room.steps)
    assert len(log.steps) == len(want)
    for a, b in zip(log.steps, want, strict=True):
        assert a.time == b.time
        assert (a.control is None) == (b.control is None)
        if a.control is not None:
            assert np.array_equal(a.control, b.control)
        assert np.array_equal(a.observations, b.observations)
        assert a.attributes is None and b.attributes is None
    assert log.model == slam.Unicycle()
    assert log.truth.shape == (len(room.times), 4) and not log.truth.flags.writeable
    assert np.array_equal(log.landmarks, room.landmarks)
    assert np.allclose(log.true_pose(room.times[5]), room.poses[5])
    assert log.true_pose(room.times[-1] + 1.0) is None


def test_run_slam_on_a_landmark_log_measures_against_the_truth(room, room_log, tmp_path):
    cfg = room_config()
    run = run_slam(room_log, config=cfg, out=tmp_path / "out", plot=True)
    te = run.truth
    assert te is not None and te.poses == len(_events(room.steps))
    # the same run as the filter on the read steps, started from the true pose
    log = slam.read_landmark_log(room_log)
    direct = slam.ekf_slam(log.steps, log.model, config=cfg, initial_pose=room.poses[0])
    assert np.array_equal(direct.poses, run.result.poses)
    e = direct.poses[:, :2] - slam.reader.interpolate_poses(log.truth, direct.times)[:, :2]
    assert te.rmse_start == pytest.approx(math.sqrt(np.mean(np.sum(e**2, 1))))
    assert te.rmse_start < 0.3 and te.rmse_best <= te.rmse_start
    assert 1.0 < te.anees < 6.0
    assert te.landmarks_true == 15 and te.landmarks_mapped >= 12 and te.landmark_rmse < 0.4
    assert run.gps is None and "GPS RMSE (start alignment)" not in run.metrics
    assert run.metrics["true landmarks mapped (within 1 m)"] == (te.landmarks_mapped, "of 15")
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["truth"]["rmse_start"] == pytest.approx(te.rmse_start)
    assert (tmp_path / "out" / "map.png").stat().st_size > 1000


def test_truth_error_moves_the_estimate_onto_the_first_true_pose():
    """A filter started at the origin is compared in the truth's frame (start alignment);
    a turned and shifted copy of the truth has no error."""
    t = np.linspace(0.0, 10.0, 50)
    truth = np.column_stack([t, 3.0 + t, 2.0 + np.sin(t), 0.1 * t])
    c, s = math.cos(0.7), math.sin(0.7)
    xy = (truth[:, 1:3] - truth[0, 1:3]) @ np.array([[c, -s], [s, c]]).T
    est = np.column_stack([xy, slam.wrap(truth[:, 3] - truth[0, 3] + 0.7)])
    covs = np.broadcast_to(np.eye(3) * 0.01, (len(t), 3, 3))
    te = truth_error(t, est, covs, truth, est[:, :2][:3], np.array([[50.0, 50.0]]))
    assert te.rmse_start < 1e-9 and te.rmse_best < 1e-9 and te.heading_rmse < 1e-9
    assert te.landmarks_true == 1 and te.landmarks_mapped == 0 and te.landmarks_spurious == 3
    assert truth_error(t + 100.0, est, covs, truth) is None
    bare = truth_error(t, est, None, truth)  # no covariances (a smoothed run): no ANEES
    assert math.isnan(bare.anees) and bare.rmse_start == te.rmse_start


def test_the_command_runs_a_landmark_log(room_log, tmp_path):
    out = tmp_path / "cli"
    r = CliRunner().invoke(cli.app, ["slam", str(room_log), "--out", str(out), "--json"])
    assert r.exit_code == 0, r.output
    report = json.loads(r.stdout)
    assert report["truth"]["landmarks_true"] == 15
    assert "pose RMSE (start alignment)" in report["metrics"]
    assert (out / "map.png").exists() and (out / "trajectory.tum").exists()


def test_an_ackermann_model_reads_back(tmp_path):
    m = slam.Ackermann(wheelbase=2.5, encoder_offset=0.5, laser_a=1.0, laser_b=0.2, sigma_speed=0.1)
    step = slam.Step(0.0, np.array([1.0, 0.1]), np.array([[5.0, 0.3]]), np.array([0.4]))
    d = write_landmark_log(tmp_path, [step], model=m)
    log = slam.read_landmark_log(d)
    assert log.model == m and log.truth is None and log.landmarks is None
    assert np.array_equal(log.steps[0].attributes, [0.4])
    (d / "model.toml").write_text('kind = "ackermann"\n')  # the defaults: Victoria Park's car
    assert slam.read_landmark_log(d).model == victoria_park_model()


def _log(tmp_path, observations="0.1 4.0 0.2\n", **files):
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "controls.txt").write_text("0.0 0.5 0.0\n")
    (tmp_path / "observations.txt").write_text(observations)
    for name, text in files.items():
        (tmp_path / name.replace("_", ".")).write_text(text)
    return tmp_path


@pytest.mark.parametrize(
    ("observations", "files", "words"),
    [
        ("0.1 4.0 45.0\n", {}, ("observations.txt:1", "bearing", "radians", "0.785398")),
        ("0.1 -4.0 0.2\n", {}, ("observations.txt:1", "range must be above 0")),
        ("0.1 4 0.2\n0.2 0 0.2\n", {}, ("observations.txt:2", "range must be above 0", "0.0")),
        ("# t r b a\n0.1 4 0.2 0.3\n0.2 4 0.2\n", {}, ("observations.txt:3", "expected 4")),
        ("0.1 4 nan\n", {}, ("observations.txt:1", "bearing", "not finite")),
        ("0.2 4 0.1\n0.1 4 0.1\n", {}, ("observations.txt:2", "time goes back")),
        ("0.1 4 0.2\n", {"landmarks_txt": "1 2\n3 x\n"}, ("landmarks.txt:2", "y", "not a number")),
        ("0.1 4 0.2\n", {"truth_txt": "0 1 2\n"}, ("truth.txt:1", "expected 4")),
        ("0.1 4 0.2\n", {"model_toml": "kind = \n"}, ("model.toml", "not TOML")),
    ],
)
def test_malformed_files_name_the_file_line_and_field(tmp_path, observations, files, words):
    d = _log(tmp_path, observations, **files)
    with pytest.raises(ParseError) as e:
        slam.read_landmark_log(d)
    for w in words:
        assert w in str(e.value)


@pytest.mark.parametrize(
    ("model", "words"),
    [
        ('kind = "bicycle"\n', ("model.toml", "kind must be one of unicycle, ackermann")),
        ("kind = [1]\n", ("model.toml", "kind must be one of")),
        ("sigma_speed = 0.1\n", ("model.toml", "unknown unicycle parameter 'sigma_speed'")),
        ("sigma_v = -1.0\n", ("model.toml", "sigma_v must be >= 0")),
        ('kind = "ackermann"\nwheelbase = 0\n', ("model.toml", "wheelbase must be > 0")),
    ],
)
def test_a_wrong_model_names_the_file_and_the_key(tmp_path, model, words):
    d = _log(tmp_path, model_toml=model)
    with pytest.raises(ConfigError) as e:
        slam.read_landmark_log(d)
    for w in words:
        assert w in str(e.value)


def test_a_missing_file_says_what_a_landmark_log_holds(tmp_path):
    (tmp_path / "controls.txt").write_text("0 0 0\n")
    with pytest.raises(DataNotFoundError, match="lacks observations.txt"):
        slam.read_landmark_log(tmp_path)
    with pytest.raises(DataNotFoundError, match="not a directory"):
        slam.read_landmark_log(tmp_path / "nope")
    assert not slam.reader.is_landmark_log(tmp_path) and not slam.reader.is_landmark_log(3)
    # the command: a landmark log's file and none of Victoria Park's: read as a landmark
    # log, which says what it lacks; a directory holding neither's files names both
    r = CliRunner().invoke(cli.app, ["slam", str(tmp_path)])
    assert_clean_error(r, "lacks observations.txt")
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.md").write_text("not data\n")
    r = CliRunner().invoke(cli.app, ["slam", str(tmp_path / "empty")])
    assert_clean_error(r, "neither a landmark log (controls.txt")
    assert "measurements.dat" in r.output
    with pytest.raises(DataNotFoundError, match="holds neither"):
        run_slam(tmp_path / "empty", out=tmp_path / "o")


def test_a_log_with_no_rows_and_truth_beside_the_run(tmp_path, caplog):
    d = _log(tmp_path, "# nothing\n")
    (d / "controls.txt").write_text("# nothing\n")
    with pytest.raises(ParseError, match="controls.txt and observations.txt have no rows"):
        run_slam(d)
    d = _log(tmp_path, "0.1 4.0 0.2\n0.2 4.0 0.2\n", truth_txt="50 0 0 0\n60 1 0 0\n")
    with caplog.at_level("WARNING", logger="scanclique"):
        run = run_slam(d)
    assert run.truth is None and "no step falls within truth.txt" in caplog.text


def test_gps_fixes_of_a_landmark_log_are_measured_as_victoria_parks(room, tmp_path):
    """A log with ``gps.txt`` and no truth: the filter starts at the origin and the GPS
    rows measure it in the GPS's frame (the start and the best SE(2) alignment)."""
    keep = np.flatnonzero(np.diff(np.floor(room.times), prepend=-1.0) > 0)  # 1 Hz fixes
    fixes = np.column_stack([room.times[keep], room.poses[keep, :2]])
    d = write_landmark_log(tmp_path, room.steps)
    np.savetxt(d / "gps.txt", fixes)
    run = run_slam(d, config=room_config(), out=tmp_path / "out", plot=True)
    assert run.truth is None and run.gps is not None and run.gps.fixes == len(keep)
    assert run.gps.rmse_best < 0.3 and run.gps.rmse_start < 0.5
    assert "GPS RMSE (best SE(2) alignment)" in run.metrics


def test_writing_attributes_for_some_batches_only_is_refused(tmp_path):
    from scanclique.errors import ArgumentError

    a = slam.Step(0.0, None, np.array([[5.0, 0.3]]), np.array([0.4]))
    b = slam.Step(1.0, None, np.array([[5.0, 0.3]]))
    with pytest.raises(ArgumentError, match="t=1.0 have no attributes"):
        write_landmark_log(tmp_path / "x", [a, b])
    assert not (tmp_path / "x").exists()


def test_csv_files_with_a_header_read_as_the_whitespace_ones(tmp_path):
    """Comma-separated files, with or without a first row of column names, read as the
    whitespace-separated ones; a malformed CSV row still names its line and field."""
    plain = _log(tmp_path / "plain", "0.1 4.0 0.2 0.3\n0.1 6.0 -0.3 0.5\n")
    csv = _log(
        tmp_path / "csv",
        "time,range,bearing,diameter\n0.1, 4.0, 0.2, 0.3\n0.1,6.0,-0.3,0.5\n",
        truth_txt="t,x,y,theta\n0,1,2,0.5\n",
        landmarks_txt="x,y\n1,2\n",
    )
    a, b = slam.read_landmark_log(plain), slam.read_landmark_log(csv)
    assert np.array_equal(a.steps[1].observations, b.steps[1].observations)
    assert np.array_equal(a.steps[1].attributes, b.steps[1].attributes)
    assert b.truth.tolist() == [[0.0, 1.0, 2.0, 0.5]] and b.landmarks.tolist() == [[1.0, 2.0]]
    (csv / "observations.txt").write_text("time,range,bearing\n0.1,4.0,\n")
    with pytest.raises(ParseError, match=r"observations.txt:2: bearing: not a number: ''"):
        slam.read_landmark_log(csv)
    (csv / "observations.txt").write_text("# a comment\nt,r,b\n0.1,4.0,45.0\n")
    with pytest.raises(ParseError, match=r"observations.txt:3: bearing: bearing 45.0"):
        slam.read_landmark_log(csv)  # the line counted past the comment and the header
    (csv / "observations.txt").write_text("0.1 4.0 abc\n")  # not a header: one is a number
    with pytest.raises(ParseError, match=r"observations.txt:1: bearing: not a number"):
        slam.read_landmark_log(csv)
    # the attribute column is there when the first data row has it, whatever the header
    (csv / "observations.txt").write_text("# c\ntime,range,bearing\n0.1,4.0,0.2,0.3\n")
    assert slam.read_landmark_log(csv).steps[1].attributes.tolist() == [0.3]
    (csv / "observations.txt").write_text("time,range,bearing,d\n0.1,4.0,0.2\n0.2,4,0,1\n")
    with pytest.raises(ParseError, match=r"observations.txt:3: expected 3 numbers"):
        slam.read_landmark_log(csv)  # the first data row sets the width


def test_a_partial_landmark_log_says_what_it_lacks(tmp_path):
    (tmp_path / "observations.txt").write_text("0.1 4.0 0.2\n")
    with pytest.raises(DataNotFoundError, match="landmark log incomplete: .* lacks controls.txt"):
        run_slam(tmp_path)
    r = CliRunner().invoke(cli.app, ["slam", str(tmp_path)])
    assert_clean_error(r, "lacks controls.txt")


@pytest.mark.parametrize("name", ["truth.txt", "landmarks.txt", "gps.txt", "model.toml"])
def test_an_optional_file_that_is_not_a_regular_file_is_named(tmp_path, name):
    import os

    d = _log(tmp_path)
    (d / name).mkdir()
    with pytest.raises(ParseError, match=f"{name}: is not a regular file"):
        slam.read_landmark_log(d)
    (d / name).rmdir()
    os.mkfifo(d / name)  # a pipe would block the reader: refused, not read
    with pytest.raises(ParseError, match=f"{name}: is not a regular file"):
        slam.read_landmark_log(d)


def test_write_landmark_log_refuses_what_would_not_read_back(tmp_path):
    from dataclasses import dataclass

    from scanclique.errors import ArgumentError

    @dataclass(frozen=True, slots=True)
    class Tracked(slam.Unicycle):
        track: float = 0.4

    step = slam.Step(0.0, None, np.array([[5.0, 0.3]]))
    with pytest.raises(ArgumentError, match="got Tracked"):
        write_landmark_log(tmp_path / "a", [step], model=Tracked())
    with pytest.raises(ArgumentError, match=r"steps\[1\] is a tuple"):
        write_landmark_log(tmp_path / "b", [step, (1.0, None)])


@pytest.mark.realdata
def test_victoria_park_written_as_a_landmark_log_runs_the_same(data_dir, tmp_path):
    """Victoria Park through the landmark-log path (an Ackermann model.toml, attributes,
    gps.txt): the same steps, and the filter gives the same poses. The whole run gives
    3.5427 / 1.5253 m and 160 landmarks either way (measured in session 30)."""
    if not (data_dir / "victoria-park").is_dir():
        pytest.skip(f"real data not found: {data_dir / 'victoria-park'}")
    steps = slam.read_victoria_park("victoria-park")
    d = write_landmark_log(tmp_path / "vp", steps, model=victoria_park_model())
    np.savetxt(d / "gps.txt", slam.read_gps("victoria-park"), fmt="%.17g")
    log = slam.read_landmark_log(d)
    assert log.model == victoria_park_model() and len(log.steps) == len(steps)
    assert np.array_equal(log.gps, slam.read_gps("victoria-park"))
    for a, b in zip(log.steps, steps, strict=True):
        assert a.time == b.time and np.array_equal(a.observations, b.observations)
        assert np.array_equal(a.attributes, b.attributes) or a.attributes is b.attributes
        assert (a.control is None and b.control is None) or np.array_equal(a.control, b.control)
    first = steps[:4000]
    want = slam.ekf_slam(first, victoria_park_model())
    got = slam.ekf_slam(log.steps[:4000], log.model)
    assert np.array_equal(want.poses, got.poses) and np.array_equal(want.landmarks, got.landmarks)


def test_controls_from_odometry_inverts_the_unicycle_step():
    rng = np.random.default_rng(3)
    t = np.r_[0.0, np.cumsum(rng.uniform(0.01, 0.05, 299))]
    u = np.column_stack([rng.uniform(-0.5, 1.0, 300), rng.uniform(-1.5, 1.5, 300)])
    poses = [np.array([1.0, -2.0, 3.0])]  # near +-pi: the turns wrap across it
    for k in range(299):
        poses.append(slam.Unicycle().predict(poses[-1], u[k], t[k + 1] - t[k])[0])
    c = slam.controls_from_odometry(t, np.array(poses))
    assert np.array_equal(c[:, 0], t) and c[-1, 1:].tolist() == [0.0, 0.0]
    assert np.allclose(c[:-1, 1:], u[:-1], atol=1e-9)
    # an arc of a quarter turn in one interval: as far as the chord, turning as much
    c = slam.controls_from_odometry([0.0, 1.0], [[0, 0, 0], [1, 1, math.pi / 2]])
    assert c[0, 1:] == pytest.approx([math.sqrt(2.0), math.pi / 2])
    # standing still twice at one time is taken; turning on the spot has no speed
    c = slam.controls_from_odometry([0, 1, 1, 2], [[0, 0, 0], [0, 0, 1], [0, 0, 1], [0, 0, 0]])
    assert c[:, 1].tolist() == [0.0, 0.0, 0.0, 0.0] and c[0, 2] == pytest.approx(1.0)


@pytest.mark.parametrize(
    "times, poses, words",
    [
        ([0, 1], [[0, 0, 0]], "times must be (N,) and poses (N, 3)"),
        ([0, 1, 0.5], [[0, 0, 0]] * 3, "row 2: time goes back"),
        ([0, 1, 1], [[0, 0, 0], [1, 0, 0], [2, 0, 0]], "row 2: the pose moves in no time"),
        ([0, np.nan], [[0, 0, 0]] * 2, "row 1: not finite"),
    ],
)
def test_controls_from_odometry_refuses_what_it_cannot_take(times, poses, words):
    with pytest.raises(ArgumentError) as e:
        slam.controls_from_odometry(times, poses)
    assert words in str(e.value)


def test_sideways_odometry_is_told(caplog):
    t = np.arange(20.0)
    sideways = np.column_stack([np.zeros(20), 0.1 * t, np.zeros(20)])  # heading x, moving y
    with caplog.at_level("WARNING", logger="scanclique"):
        c = slam.controls_from_odometry(t, sideways)
    assert "100% of the odometry's path runs across its heading" in caplog.text
    assert np.allclose(np.abs(c[:-1, 1]), 0.1)
    caplog.clear()
    with caplog.at_level("WARNING", logger="scanclique"):
        slam.controls_from_odometry(t, np.column_stack([0.1 * t, np.zeros(20), np.zeros(20)]))
    assert "across its heading" not in caplog.text


def _odometry_of(steps):
    """Odometry poses (time x y theta) that the steps' controls move a unicycle through
    (one Euler step per control), ending at the last step's time."""
    ctrl = [(s.time, s.control) for s in steps if s.control is not None]
    rows, pose = [], np.zeros(3)
    ends = [t for t, _ in ctrl[1:]] + [steps[-1].time]
    for (t, u), end in zip(ctrl, ends, strict=True):
        rows.append([t, *pose])
        pose = slam.Unicycle().predict(pose, u, end - t)[0]
    rows.append([steps[-1].time, *pose])
    return np.array(rows)


def test_a_landmark_log_of_odometry_poses_runs_as_its_controls(room, room_log, tmp_path):
    """odometry.txt for controls.txt: the controls it gives are the log's (one Euler step
    per control), and the run the same."""
    import shutil

    d = tmp_path / "odo"
    shutil.copytree(room_log, d)
    (d / "controls.txt").unlink()
    odo = _odometry_of(room.steps)
    np.savetxt(d / "odometry.txt", odo, fmt="%.17g", header="time x y theta", comments="")
    a, b = slam.read_landmark_log(room_log), slam.read_landmark_log(d)
    assert len(a.steps) == len(b.steps)
    for s, u in zip(a.steps[:-1], b.steps[:-1], strict=True):  # the last: after the odometry
        assert s.time == u.time and np.array_equal(s.observations, u.observations)
        if s.control is not None:
            assert np.allclose(s.control, u.control, atol=1e-9)
    cfg = room_config()
    ra = slam.ekf_slam(a.steps[:-1], a.model, config=cfg)
    rb = slam.ekf_slam(b.steps[:-1], b.model, config=cfg)
    assert np.allclose(ra.poses, rb.poses, atol=1e-6)
    r = CliRunner().invoke(cli.app, ["slam", str(d), "--out", str(tmp_path / "o"), "--json"])
    assert r.exit_code == 0, r.output
    # both files: which one moves the robot is not guessed
    (d / "controls.txt").write_text("0 0 0\n")
    with pytest.raises(ParseError, match="odometry.txt: is beside controls.txt"):
        slam.read_landmark_log(d)
    (d / "controls.txt").unlink()
    (d / "odometry.txt").write_text("time x y theta\n0 0 0 0\n1 1 0 0\n1 2 0 0\n")
    with pytest.raises(ParseError, match=r"odometry.txt:4: the pose moves in no time"):
        slam.read_landmark_log(d)
    (d / "model.toml").write_text('kind = "ackermann"\n')
    with pytest.raises(ConfigError, match="odometry.txt gives a unicycle's controls"):
        slam.read_landmark_log(d)
