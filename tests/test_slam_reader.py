"""Victoria Park reader: steps, frames, missing files and malformed rows; a step, the
filter and ``associate`` refusing what is not finite or not in order."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from scanclique import datasets, slam
from scanclique.errors import ArgumentError, ConfigError, DataNotFoundError, ParseError, StepError
from scanclique.slam import Step
from scanclique.slam.reader import read_table


def _write(d: Path, meas: str, inputs: str, gps: str = "0.0 0.0 0.0\n") -> Path:
    d.mkdir(parents=True, exist_ok=True)
    (d / "measurements.dat").write_text(meas)
    (d / "inputs.dat").write_text(inputs)
    (d / "gps.dat").write_text(gps)
    return d


def test_steps_merge_and_bearing_frame(tmp_path):
    d = _write(
        tmp_path / "vp",
        "0.5 10.0 1.5707963 0.3\n0.5 20.0 0.0 0.2\n1.0 5.0 3.1415926 0.1\n",
        "0.0 1.0 0.0\n0.5 1.5 0.1\n0.75 1.5 0.1\n",
    )
    steps = slam.read_victoria_park(d)
    assert [s.time for s in steps] == [0.0, 0.5, 0.75, 1.0]
    s = steps[1]
    assert s.control is not None and s.control.tolist() == [1.5, 0.1]
    assert s.observations.shape == (2, 2)
    # file bearing pi/2 (straight ahead) -> 0; 0 (scanner's right) -> -pi/2
    np.testing.assert_allclose(s.observations[:, 1], [0.0, -math.pi / 2], atol=1e-6)
    np.testing.assert_allclose(s.attributes, [0.3, 0.2])
    assert steps[3].control is None and abs(steps[3].observations[0, 1] - math.pi / 2) < 1e-6
    assert steps[2].n_observations == 0
    with pytest.raises(ValueError):
        s.observations[0, 0] = 1.0  # read-only


@pytest.mark.parametrize(
    "text, line, field",
    [
        ("0.5 10.0 1.0 0.3\n0.6 10.0 abc 0.3\n", 2, "bearing"),
        ("0.5 10.0 1.0 0.3\n\n0.6 10.0 1.0\n", 3, None),
        ("0.5 10.0 1.0 0.3\n0.4 10.0 1.0 0.3\n", 2, "time"),
        ("0.5 nan 1.0 0.3\n", 1, "range"),
    ],
)
def test_malformed_rows_name_file_and_line(tmp_path, text, line, field):
    d = _write(tmp_path / "vp", text, "0.0 1.0 0.0\n")
    with pytest.raises(ParseError) as ei:
        slam.read_victoria_park(d)
    e = ei.value
    assert e.path.endswith("measurements.dat") and e.line == line and e.field == field
    assert f"measurements.dat:{line}:" in str(e)


def test_negative_range_is_named(tmp_path):
    d = _write(tmp_path / "vp", "0.5 10.0 1.0 0.3\n# c\n0.6 -1.0 1.0 0.3\n", "0.0 1.0 0.0\n")
    with pytest.raises(ParseError) as ei:
        slam.read_victoria_park(d)
    assert ei.value.line == 3 and ei.value.field == "range"


def test_missing_files(tmp_path, monkeypatch):
    with pytest.raises(DataNotFoundError, match="nowhere"):
        slam.read_victoria_park(tmp_path / "nowhere")
    d = tmp_path / "half"
    d.mkdir()
    (d / "inputs.dat").write_text("0 0 0\n")
    with pytest.raises(DataNotFoundError, match="measurements.dat"):
        slam.read_victoria_park(d)
    monkeypatch.setenv(datasets.ENV_VAR, str(tmp_path / "empty"))
    with pytest.raises(DataNotFoundError, match="victoria-park"):
        slam.read_victoria_park("victoria-park")


def test_read_table_skips_comments(tmp_path):
    p = tmp_path / "t.dat"
    p.write_text("# time x y\n0 1 2\n\n1 2 3\n")
    np.testing.assert_array_equal(read_table(p, ("time", "x", "y")), [[0, 1, 2], [1, 2, 3]])


@pytest.mark.realdata
def test_real_victoria_park(data_dir):
    if not (data_dir / "victoria-park").is_dir():
        pytest.skip(f"real data not found: {data_dir / 'victoria-park'}")
    steps = slam.read_victoria_park("victoria-park")
    obs = [s for s in steps if s.n_observations]
    assert len(obs) == 7230
    assert max(s.n_observations for s in obs) == 18 or max(s.n_observations for s in obs) > 10
    b = np.concatenate([s.observations[:, 1] for s in obs])
    assert b.min() >= -math.pi / 2 - 1e-6 and b.max() <= math.pi / 2 + 1e-6


@pytest.mark.parametrize(
    "kwargs, says",
    [
        (dict(time=float("nan"), control=None, observations=[]), "time must be finite"),
        (dict(time="soon", control=None, observations=[]), "time must be a number"),
        (dict(time=0.0, control=(1.0, float("inf")), observations=[]), "control"),
        (dict(time=0.0, control=(1.0, 0.0, 2.0), observations=[]), "2 numbers"),
        (dict(time=0.0, control=None, observations=[[float("nan"), 0.1]]), "observation 0"),
        (dict(time=0.0, control=None, observations=[[2.0, 0.1], [-0.5, 0.2]]), "observation 1"),
        (dict(time=0.0, control=None, observations=[[2.0, float("inf")]]), "observation 0"),
        (dict(time=0.0, control=None, observations=[1.0, 2.0, 3.0]), "(k, 2)"),
        (dict(time=0.0, control=None, observations=[["a", 1.0]]), "observations must be numbers"),
        (
            dict(time=0.0, control=None, observations=[[2.0, 0.1]], attributes=[0.3, 0.4]),
            "2 attributes",
        ),
        (
            dict(time=0.0, control=None, observations=[[2.0, 0.1]], attributes=[np.nan]),
            "attribute 0",
        ),
    ],
)
def test_a_bad_step_is_refused_by_name(kwargs, says):
    with pytest.raises(StepError, match=re.escape(says)):
        Step(**kwargs)


def test_the_filter_refuses_steps_out_of_order_and_a_bad_initial_pose():
    u = (0.5, 0.0)
    steps = [Step(1.0, u, []), Step(1.0, None, [[2.0, 0.1]]), Step(0.5, u, [])]
    with pytest.raises(StepError, match=r"steps\[2\] at t=0.5 comes before steps\[1\]"):
        slam.ekf_slam(steps, slam.Unicycle())
    # equal times are in order
    assert len(slam.ekf_slam(steps[:2], slam.Unicycle()).times) == 2
    for bad in [(0.0, float("nan"), 0.0), (0.0, 0.0), "origin"]:
        with pytest.raises(ArgumentError, match="initial_pose"):
            slam.ekf_slam(steps[:2], slam.Unicycle(), initial_pose=bad)


def test_associate_refuses_what_is_not_finite():
    lm = np.array([[10.0, 0.0], [10.0, 5.0]])
    cov = np.tile(np.eye(2) * 0.01, (2, 1, 1))
    R = np.diag([0.1, 0.01]) ** 2
    z = np.array([[10.0, 0.0]])
    assert slam.associate(z, R, lm, cov, np.zeros(3), np.eye(3) * 1e-4).landmarks.tolist() == [0]
    bad = dict(
        z=np.array([[np.nan, 0.0]]),
        R=np.full((2, 2), np.inf),
        map_mean=lm + np.nan,
        pose=(0.0, np.nan, 0.0),
    )
    for name, value in bad.items():
        args = dict(z=z, R=R, map_mean=lm, map_cov=cov, pose=np.zeros(3), pose_cov=np.eye(3))
        args[name] = value
        says = "associate: z: observation 0" if name == "z" else f"associate: {name} is not finite"
        with pytest.raises(StepError, match=says):
            slam.associate(**args)
    with pytest.raises(StepError, match="range not above 0"):
        slam.associate(-z, R, lm, cov, np.zeros(3), np.eye(3) * 1e-4)
    # a landmark at the sensor (range 0) has no bearing: the filter's Jacobian divides by it
    at_sensor = np.array(z)
    at_sensor[0, 0] = 0.0
    with pytest.raises(StepError, match=r"observation 0 .* has a range not above 0"):
        slam.associate(at_sensor, R, lm, cov, np.zeros(3), np.eye(3) * 1e-4)
    with pytest.raises(StepError, match="range not above 0"):
        slam.Step(1.0, (1.0, 0.0), [[0.0, 0.3]])


@pytest.mark.parametrize(
    ("model", "turn", "says"),
    [
        (slam.Ackermann(), 5.0, r"steering angle \(rad\) 5.0 is at or beyond 1.5708.*0.0872665"),
        (slam.Unicycle(), 30.0, r"turn rate \(rad/s\) 30.0 is at or beyond 12.566.*0.523599"),
    ],
)
def test_controls_in_degrees_are_refused(model, turn, says):
    """A steering angle at or beyond pi/2 (tan infinite: wheels sideways) or a turn rate
    of two turns a second or more is degrees given for radians: refused before the first
    step, naming the step; a plausible control runs."""
    steps = [Step(0.0, (1.0, 0.1), []), Step(0.1, (1.0, turn), []), Step(0.2, None, [])]
    with pytest.raises(StepError, match=r"steps\[1\] at t=0.1: control \[1.0, " + f"{turn}\\]"):
        slam.ekf_slam(steps, model)
    with pytest.raises(StepError, match=says):
        slam.ekf_slam(steps, model)
    ok = [Step(0.0, (1.0, 0.1), []), Step(0.1, (1.0, -1.5), []), Step(0.2, None, [])]
    assert slam.ekf_slam(ok, model).poses.shape == (3, 3)


def test_bearings_in_degrees_are_refused():
    """A bearing beyond two turns cannot be radians (a tree at 45 deg given as 45 was
    wrapped to 45 rad = 2.0 rad, silently): refused, with its value in radians; bearings
    in (-pi, pi], in [0, 2 pi) and up to two turns are accepted."""
    with pytest.raises(StepError, match=r"observation 1 has bearing 45.0 rad.*0.785398 rad"):
        Step(1.0, None, [[10.0, 0.1], [8.0, 45.0]])
    with pytest.raises(StepError, match="associate: z: observation 0 has bearing -90.0 rad"):
        slam.associate([[10.0, -90.0]], np.eye(2), np.zeros((0, 2)), np.zeros((0, 2, 2)),
                       np.zeros(3), np.eye(3))  # fmt: skip
    ok = Step(1.0, None, [[10.0, -math.pi], [8.0, 2 * math.pi - 0.1], [5.0, 4 * math.pi]])
    assert ok.observations[:, 1].tolist() == [-math.pi, 2 * math.pi - 0.1, 4 * math.pi]


@pytest.mark.parametrize(
    "make, says",
    [
        (lambda: slam.Ackermann(wheelbase=0.0), "Ackermann: wheelbase must be > 0 m"),
        (lambda: slam.Ackermann(wheelbase=-2.83), "Ackermann: wheelbase must be > 0 m"),
        (lambda: slam.Ackermann(wheelbase=float("nan")), "wheelbase must be a finite number"),
        (lambda: slam.Ackermann(laser_a="front"), "Ackermann: laser_a must be a finite number"),
        (lambda: slam.Ackermann(sigma_steering=-0.1), "sigma_steering must be >= 0"),
        (lambda: slam.Unicycle(sigma_v=-0.05), "Unicycle: sigma_v must be >= 0"),
        (lambda: slam.Unicycle(sigma_omega=math.inf), "sigma_omega must be a finite number"),
        (lambda: slam.Unicycle(sensor_x=True), "Unicycle: sensor_x must be a finite number"),
    ],
)
def test_a_bad_motion_model_is_refused_by_name(make, says):
    with pytest.raises(ConfigError, match=re.escape(says)):
        make()


def test_the_filter_refuses_a_bad_model_config_or_progress():
    steps = [Step(0.1 * k, (1.0, 0.0), [[5.0, 0.1]] if k % 2 else []) for k in range(6)]
    good = slam.Unicycle(sigma_v=np.float32(0.1), sensor_x=1)  # numbers of any kind: floats
    assert type(good.sigma_v) is float and type(good.sensor_x) is float
    assert slam.ekf_slam(steps, good).poses.shape == (6, 3)
    with pytest.raises(ArgumentError, match="ekf_slam: motion_model must be a slam.MotionModel"):
        slam.ekf_slam(steps, "unicycle")
    with pytest.raises(
        ConfigError, match="ekf_slam: config must be a SlamConfig or None, got dict"
    ):
        slam.ekf_slam(steps, good, config={"R": 1})
    with pytest.raises(ArgumentError, match="ekf_slam: progress must be a function or None"):
        slam.ekf_slam(steps, good, progress=10)


def test_associate_refuses_arrays_of_the_wrong_shape():
    lm = np.array([[10.0, 0.0], [10.0, 5.0]])
    cov = np.tile(np.eye(2) * 0.01, (2, 1, 1))
    R = np.diag([0.1, 0.01]) ** 2
    z = np.array([[10.0, 0.0]])
    args = dict(z=z, R=R, map_mean=lm, map_cov=cov, pose=np.zeros(3), pose_cov=np.eye(3) * 1e-4)
    assert slam.associate(**{**args, "map_cov": np.eye(4) * 0.01}).landmarks.tolist() == [0]
    for name, value, says in [
        ("R", np.eye(3), "R must be of shape (2, 2) or (1, 2, 2), got (3, 3)"),
        ("pose", np.zeros(2), "pose must be of shape (3,), got (2,)"),
        ("pose_cov", np.eye(2), "pose_cov must be of shape (3, 3)"),
        ("map_cov", np.eye(3), "map_cov must be of shape (2, 2, 2) or (4, 4), got (3, 3)"),
        ("map_mean", np.zeros(5), "map_mean must be (n, 2) positions"),
        ("cross_cov", np.zeros((3, 3)), "cross_cov must be of shape (3, 4)"),
        ("attributes", np.ones(2), "attributes must be of shape (1,)"),
        ("sensor", (0.0, 0.0, 0.0), "sensor must be of shape (2,)"),
    ]:
        with pytest.raises(StepError, match=re.escape(f"associate: {says}")):
            slam.associate(**{**args, name: value})


@pytest.mark.parametrize(
    "kwargs, says",
    [
        (dict(laps=0), "simulate_park: laps must be an integer >= 1"),
        (dict(n_trees=-1), "simulate_park: n_trees must be an integer >= 0"),
        (dict(length=float("nan")), "simulate_park: length must be a positive number"),
        (dict(p_detect=1.2), "simulate_park: p_detect must be a probability in [0, 1]"),
    ],
)
def test_the_park_simulator_refuses_bad_parameters(kwargs, says):
    from scanclique.slam.sim import simulate_park

    with pytest.raises(ConfigError, match=re.escape(says)):
        simulate_park(0, **kwargs)


@pytest.mark.parametrize(
    "kwargs, says",
    [
        (dict(duration=-1.0), "simulate_room: duration must be a positive number"),
        (dict(room=(5.0,)), "simulate_room: room must be (width, depth)"),
        (dict(room=(5.0, 0.0)), "simulate_room: room_depth must be a positive number"),
        (dict(clutter=-0.5), "simulate_room: clutter must be a number >= 0"),
        (dict(n_landmarks=2.5), "simulate_room: n_landmarks must be an integer >= 0"),
    ],
)
def test_the_room_simulator_refuses_bad_parameters(kwargs, says):
    from scanclique.slam.sim import simulate_room

    with pytest.raises(ConfigError, match=re.escape(says)):
        simulate_room(0, **kwargs)
