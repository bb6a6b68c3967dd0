"""Readers of the ACFR Victoria Park data set (trees as point features) and of landmark
logs in plain text (:func:`read_landmark_log`: one's own data, with ground truth).

The three text files of the data set (see ``data/README.md`` of the shared data):

* ``measurements.dat``: ``time range bearing diameter``, one row per detected tree; rows
  with the same time are one batch observation. The bearing is in [0, pi] with 0 on the
  scanner's right, so the vehicle-frame bearing (counter-clockwise from the vehicle's
  heading) is ``bearing - pi/2``.
* ``inputs.dat``: ``time speed steering`` (m/s at the rear-left wheel encoder, rad).
* ``gps.dat``: ``time x y`` (m), intermittent GPS fixes, the only ground truth.

:func:`read_victoria_park` merges the controls and the observations into one time-ordered
sequence of :class:`Step` records, the input of :func:`scanclique.slam.ekf_slam`.
"""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._records import readonly as _ro
from ..errors import ArgumentError, ConfigError, DataNotFoundError, ParseError, StepError
from ..geometry import interpolate_poses
from ..io.table import read_table
from ..io.table import table_line as _line_of
from ..scan import MAX_ANGLE_SPAN

__all__ = [
    "LandmarkLog",
    "Step",
    "VictoriaPark",
    "interpolate_poses",
    "is_landmark_log",
    "read_landmark_log",
    "read_victoria_park",
    "read_table",
    "resolve_victoria_park",
    "steps_from_arrays",
]

log = logging.getLogger(__name__)

#: The registered name of the data set, resolved in the shared data directory.
DATASET_NAME = "victoria-park"
FILES = ("measurements.dat", "inputs.dat", "gps.dat")
SOURCE = (
    "the ACFR Victoria Park data set (E. Nebot, J. Guivant; "
    "www-personal.acfr.usyd.edu.au/nebot/victoria_park.htm)"
)


def as_numbers(values, where: str, field: str) -> np.ndarray:
    """``values`` as a float array, or a :class:`StepError` saying ``where`` (``"Step at
    t=0.5"``) ``field`` must be numbers (the slam inputs' one conversion)."""
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError) as e:
        raise StepError(f"{where}: {field} must be numbers ({e})") from None


def as_observations(values, where: str, field: str) -> np.ndarray:
    """``values`` as a ``(k, 2)`` float array of range (m) and bearing (rad), or a
    :class:`StepError` saying ``where`` which of ``field``'s observations is not finite,
    has a range that is not above 0 (a landmark at the sensor has no bearing, and the
    filter's observation Jacobian divides by its range) or a bearing beyond two turns
    (:data:`scanclique.scan.MAX_ANGLE_SPAN`: degrees given for radians) (the one check of a
    step's and ``associate``'s observations)."""
    obs = as_numbers(values, where, field)
    if obs.size % 2:
        raise StepError(f"{where}: {field} must be (k, 2) range and bearing, got shape {obs.shape}")
    obs = obs.reshape(-1, 2)
    if not obs.size or (
        np.isfinite(obs).all()
        and obs[:, 0].min() > 0.0
        and np.abs(obs[:, 1]).max() <= MAX_ANGLE_SPAN
    ):
        return obs
    if np.isfinite(obs).all() and obs[:, 0].min() > 0.0:
        i = int(np.flatnonzero(np.abs(obs[:, 1]) > MAX_ANGLE_SPAN)[0])
        b = float(obs[i, 1])
        raise StepError(
            f"{where}: {field}: observation {i} has bearing {b} rad, more than two turns: "
            f"bearings are radians (degrees? {b} deg is {math.radians(b):.6g} rad; or are "
            "the observations x, y and not range, bearing?)"
        )
    i = int(np.flatnonzero(~np.isfinite(obs).all(axis=1) | ~(obs[:, 0] > 0.0))[0])
    says = "is not finite" if not np.isfinite(obs[i]).all() else "has a range not above 0"
    raise StepError(
        f"{where}: {field}: observation {i} (range, bearing) = {obs[i].tolist()} {says}"
    )


@dataclass(frozen=True, slots=True, eq=False)
class Step:
    """One event of a SLAM log: a control that holds from ``time`` on, and a batch
    observation taken at ``time``.

    Attributes
    ----------
    time : float
        Seconds.
    control : (2,) float64 ndarray, read-only, or None
        The control applied from ``time`` until the next step: ``(speed m/s, steering rad)``
        for :class:`~scanclique.slam.Ackermann`, ``(v m/s, omega rad/s)`` for
        :class:`~scanclique.slam.Unicycle`. None: the previous control still holds.
    observations : (k, 2) float64 ndarray, read-only
        Range (m) and bearing (rad, counter-clockwise from the vehicle's heading, in
        (-pi, pi]) of each detected feature, in the sensor frame. ``k`` may be 0.
    attributes : (k,) float64 ndarray, read-only, or None
        A scalar attribute per observation (a tree's diameter, m), or None.

    Raises
    ------
    StepError
        A time, control, observation or attribute that is not a finite number, a negative
        range, a bearing beyond two turns (4 pi: degrees given for radians), a control
        that is not two numbers, observations that are not pairs, or attributes that do
        not match the observations one to one.
    """

    time: float
    control: np.ndarray | None
    observations: np.ndarray
    attributes: np.ndarray | None = None

    def __post_init__(self) -> None:
        try:
            t = float(self.time)
        except (TypeError, ValueError):
            raise StepError(f"Step: time must be a number of seconds, got {self.time!r}") from None
        if not math.isfinite(t):
            raise StepError(f"Step: time must be finite, got {t}")
        object.__setattr__(self, "time", t)
        if self.control is not None:
            c = as_numbers(self.control, f"Step at t={t}", "control")
            if c.size != 2:
                raise StepError(f"Step at t={t}: control must be 2 numbers, got {c.size}")
            c = c.reshape(2)
            if not (math.isfinite(c[0]) and math.isfinite(c[1])):
                raise StepError(f"Step at t={t}: control {c.tolist()} is not finite")
            object.__setattr__(self, "control", _ro(c))
        obs = as_observations(self.observations, f"Step at t={t}", "observations")
        object.__setattr__(self, "observations", _ro(obs))
        if self.attributes is not None:
            att = as_numbers(self.attributes, f"Step at t={t}", "attributes").reshape(-1)
            if len(att) != len(obs):
                raise StepError(f"Step at t={t}: {len(att)} attributes for {len(obs)} observations")
            if att.size and not np.isfinite(att).all():
                bad = int(np.flatnonzero(~np.isfinite(att))[0])
                raise StepError(f"Step at t={t}: attribute {bad} is {att[bad]}, not finite")
            object.__setattr__(self, "attributes", _ro(att))

    @property
    def n_observations(self) -> int:
        return len(self.observations)


@dataclass(frozen=True, slots=True, eq=False)
class VictoriaPark:
    """The raw tables of the data set (each row as in its file; read-only arrays).

    Attributes
    ----------
    measurements : (M, 4) float64 ndarray
        ``time range bearing diameter`` with the file's bearing (0 on the right).
    inputs : (U, 3) float64 ndarray
        ``time speed steering``.
    gps : (G, 3) float64 ndarray
        ``time x y``.
    directory : Path
    """

    measurements: np.ndarray
    inputs: np.ndarray
    gps: np.ndarray
    directory: Path

    def __post_init__(self) -> None:
        for name in ("measurements", "inputs", "gps"):
            object.__setattr__(self, name, _ro(getattr(self, name)))


def resolve_victoria_park(source: str | os.PathLike = DATASET_NAME) -> Path:
    """The directory of the data set: the name ``"victoria-park"`` (looked for in
    :func:`scanclique.datasets.data_dir`) or a directory path.

    Raises
    ------
    DataNotFoundError
        The directory or one of its three files is missing; the message names what was
        looked for and where.
    ArgumentError
        ``source`` is neither a string nor a path.
    """
    from .. import datasets

    if not isinstance(source, (str, os.PathLike)):
        raise ArgumentError(
            f"expected the name {DATASET_NAME!r} or a directory path, got {type(source).__name__}"
        )
    s = os.fspath(source)
    if s == DATASET_NAME:
        d = datasets.data_dir() / DATASET_NAME
        looked = f"{DATASET_NAME}/ in " + ", ".join(str(c) for c in datasets.data_dir_candidates())
    else:
        d = Path(s).expanduser()
        looked = str(d)
    _require_files(
        d,
        FILES,
        "Victoria Park data",
        f"looked for the directory {looked} (holding {', '.join(FILES)}). Set "
        f"{datasets.ENV_VAR} to the shared data directory or give the directory; the data "
        f"are public: {SOURCE}.",
        f"(expected {', '.join(FILES)}); the data are public: {SOURCE}.",
    )
    return d


def _require_files(d: Path, files, what: str, not_found: str, expected: str) -> None:
    """A :class:`DataNotFoundError` ("``what`` not found: ``not_found``") when ``d`` is not
    a directory, or ("``what`` incomplete: ``d`` lacks ... ``expected``") when it lacks
    one of ``files``."""
    if not d.is_dir():
        raise DataNotFoundError(f"{what} not found: {not_found}")
    missing = [f for f in files if not (d / f).is_file()]
    if missing:
        raise DataNotFoundError(f"{what} incomplete: {d} lacks {', '.join(missing)} {expected}")


def load_victoria_park(source: str | os.PathLike = DATASET_NAME) -> VictoriaPark:
    """The three raw tables of the data set (see :class:`VictoriaPark`)."""
    d = resolve_victoria_park(source)
    meas = read_table(d / "measurements.dat", ("time", "range", "bearing", "diameter"))
    inputs = read_table(d / "inputs.dat", ("time", "speed", "steering"))
    gps = read_table(d / "gps.dat", ("time", "x", "y"))
    bad = np.flatnonzero(meas[:, 1] <= 0)
    if len(bad):
        raise ParseError(
            str(d / "measurements.dat"),
            _line_of(d / "measurements.dat", int(bad[0])),
            f"range must be positive, found {meas[bad[0], 1]}",
            field="range",
        )
    return VictoriaPark(meas, inputs, gps, d)


def steps_from_arrays(
    controls: np.ndarray,
    measurements: np.ndarray,
    *,
    bearing_offset: float = 0.0,
    max_range: float | None = None,
) -> list[Step]:
    """Merge controls and observations into one time-ordered list of :class:`Step`.

    Parameters
    ----------
    controls : (U, 3) array
        ``time c1 c2`` rows; each control holds from its time until the next. Of several
        controls at one time the last holds (the others hold for no time at all).
    measurements : (M, 3) or (M, 4) array
        ``time range bearing [attribute]`` rows; rows with equal times are one batch.
    bearing_offset : float
        Added to every bearing (``-pi/2`` for Victoria Park's scanner); the result is
        wrapped to (-pi, pi].
    max_range : float, optional
        Observations farther than this are dropped; it must be a positive number (NaN
        would drop every observation without a word, so it is a ``ConfigError``).

    Returns
    -------
    list of Step
        One step per distinct time; a time with both a control and a batch gives one
        step carrying both.
    """
    from .models import wrap

    controls = np.asarray(controls, float).reshape(-1, 3)
    measurements = np.asarray(measurements, float)
    if measurements.ndim != 2 or measurements.shape[1] not in (3, 4):
        raise ValueError(f"measurements must be (M, 3) or (M, 4), got {measurements.shape}")
    if max_range is not None:
        if not max_range > 0:
            raise ConfigError(f"max_range must be a positive number of metres, got {max_range}")
        measurements = measurements[measurements[:, 1] <= max_range]
    has_att = measurements.shape[1] == 4
    t_m = measurements[:, 0]
    # batches: runs of equal times
    if len(t_m):
        starts = np.flatnonzero(np.r_[True, t_m[1:] != t_m[:-1]])
        ends = np.r_[starts[1:], len(t_m)]
    else:
        starts = ends = np.zeros(0, int)
    batch_t = t_m[starts]
    ctrl_t = controls[:, 0]
    times = np.union1d(ctrl_t, batch_t)
    ci = np.searchsorted(ctrl_t, times, side="right") - 1  # the last control at that time
    bi = np.searchsorted(batch_t, times)
    empty = np.zeros((0, 2))
    steps: list[Step] = []
    for k, t in enumerate(times):
        c = controls[ci[k], 1:] if ci[k] >= 0 and ctrl_t[ci[k]] == t else None
        if bi[k] < len(batch_t) and batch_t[bi[k]] == t:
            rows = measurements[starts[bi[k]] : ends[bi[k]]]
            obs = np.column_stack([rows[:, 1], wrap(rows[:, 2] + bearing_offset)])
            att = rows[:, 3] if has_att else None
        else:
            obs, att = empty, None
        steps.append(Step(float(t), c, obs, att))
    return steps


def read_victoria_park(
    source: str | os.PathLike = DATASET_NAME, *, max_range: float | None = None
) -> list[Step]:
    """The Victoria Park log as a time-ordered list of :class:`Step`.

    Controls are ``(speed m/s, steering rad)`` of :class:`~scanclique.slam.Ackermann`;
    observations are (range m, bearing rad) of the tree centres in the laser's frame,
    bearing counter-clockwise from the vehicle's heading (the file's bearing - pi/2);
    attributes are the trees' diameters (m).

    Parameters
    ----------
    source : str or path
        ``"victoria-park"`` (looked for in the shared data directory) or the directory
        holding ``measurements.dat``, ``inputs.dat`` and ``gps.dat``.
    max_range : float, optional
        Drop detections farther than this (m).

    Raises
    ------
    DataNotFoundError
        A file is missing (the message says where it was looked for).
    ParseError
        A malformed row (file and line named).

    Examples
    --------
    >>> steps = read_victoria_park()          # doctest: +SKIP
    >>> sum(s.n_observations > 0 for s in steps)  # doctest: +SKIP
    7230
    """
    vp = load_victoria_park(source)
    return steps_from_arrays(
        vp.inputs, vp.measurements, bearing_offset=-math.pi / 2, max_range=max_range
    )


def read_gps(source: str | os.PathLike = DATASET_NAME) -> np.ndarray:
    """The GPS fixes ``(G, 3)``: time (s), x, y (m)."""
    d = resolve_victoria_park(source)
    return _ro(read_table(d / "gps.dat", ("time", "x", "y")))


#: The files of a landmark log in plain text (:func:`read_landmark_log`): the two it
#: needs, then the optional ones.
LOG_FILES = ("controls.txt", "observations.txt")
LOG_OPTIONAL = ("truth.txt", "landmarks.txt", "gps.txt", "model.toml")
#: the file a landmark log may hold instead of ``controls.txt``: wheel odometry as poses
LOG_ODOMETRY = "odometry.txt"
#: what a landmark log's directory holds, in words (the errors that miss one say it)
LOG_HOLDS = (
    f"{', '.join(LOG_FILES)} (or {LOG_ODOMETRY} for controls.txt), and optionally "
    f"{', '.join(LOG_OPTIONAL)}"
)


@dataclass(frozen=True, slots=True, eq=False)
class LandmarkLog:
    """A landmark log read from its directory (:func:`read_landmark_log`).

    Attributes
    ----------
    steps : list of Step
        Controls and observations merged in time order (:func:`steps_from_arrays`).
    model : MotionModel
        From ``model.toml``; :class:`~scanclique.slam.Unicycle` with its defaults when the
        directory has none.
    truth : (T, 4) float64 ndarray, read-only, or None
        ``time x y theta`` of the vehicle's true pose (s, m, rad), from ``truth.txt``.
    landmarks : (L, 2) float64 ndarray, read-only, or None
        True landmark positions ``x y`` (m, the truth's frame), from ``landmarks.txt``.
    directory : Path
    gps : (G, 3) float64 ndarray, read-only, or None
        ``time x y`` position fixes of the sensor (s, m), from ``gps.txt``.
    """

    steps: list
    model: object
    truth: np.ndarray | None
    landmarks: np.ndarray | None
    directory: Path
    gps: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("truth", "landmarks", "gps"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _ro(getattr(self, name)))

    def true_pose(self, t: float) -> np.ndarray | None:
        """The true pose ``(x, y, theta)`` at time ``t`` (s), interpolated (the heading
        along the shorter arc), or None without truth or outside its time span."""
        if self.truth is None or not len(self.truth):
            return None
        tt = self.truth[:, 0]
        if not tt[0] <= t <= tt[-1]:
            return None
        return interpolate_poses(self.truth, np.array([t]))[0]


def is_landmark_log(source) -> bool:
    """Whether ``source`` is a directory holding a landmark log's ``controls.txt`` and
    ``observations.txt`` (:func:`read_landmark_log`)."""
    if not isinstance(source, (str, os.PathLike)):
        return False
    d = Path(os.fspath(source)).expanduser()
    return d.is_dir() and all((d / f).is_file() for f in log_files(d))


def log_files(d: Path) -> tuple[str, str]:
    """The two files a landmark log in ``d`` needs: :data:`LOG_FILES`, with
    :data:`LOG_ODOMETRY` for ``controls.txt`` when ``d`` holds that and not the other."""
    if (d / LOG_ODOMETRY).exists() and not (d / LOG_FILES[0]).exists():
        return LOG_ODOMETRY, LOG_FILES[1]
    return LOG_FILES


def read_landmark_log(directory: str | os.PathLike) -> LandmarkLog:
    """A landmark log in plain text: the way to bring one's own range-bearing data (a
    robot's wheel odometry and a detector's landmarks, with ground truth when there is
    some) to :func:`~scanclique.slam.ekf_slam` and ``scanclique slam DIR``.

    The directory holds (numbers separated by whitespace or commas, one row per line,
    ``#`` comments, a first row of column names skipped, times in seconds and not
    decreasing; :func:`read_table`):

    * ``controls.txt``: ``time c1 c2``, each control holding until the next: ``(v m/s,
      omega rad/s)`` of a :class:`~scanclique.slam.Unicycle` (the default model), or
      ``(speed m/s, steering rad)`` of an :class:`~scanclique.slam.Ackermann`;
    * or, instead of ``controls.txt``, ``odometry.txt``: ``time x y theta``, the wheel
      odometry as poses (metres, radians), made into a :class:`~scanclique.slam.Unicycle`'s
      controls by :func:`~scanclique.slam.controls_from_odometry`;
    * ``observations.txt``: ``time range bearing [attribute]``, range in metres, bearing
      in radians counter-clockwise from the vehicle's heading, in the sensor's frame
      (where ``model.toml`` puts it on the vehicle); rows with the same time are one
      batch observation (the clique associates a batch as a whole); the optional fourth
      column a scalar per landmark (a tree's diameter);
    * ``truth.txt`` (optional): ``time x y theta``, the vehicle's true pose (the pose the
      model moves: a unicycle's centre, an Ackermann's rear axle);
    * ``landmarks.txt`` (optional): ``x y``, the true landmark positions, in the truth's
      frame;
    * ``gps.txt`` (optional): ``time x y``, position fixes of the sensor, measured as
      Victoria Park's (:mod:`scanclique.slam.metrics`: the start and the best SE(2)
      alignment) where there is no ``truth.txt``;
    * ``model.toml`` (optional): ``kind = "unicycle"`` or ``"ackermann"`` and the
      model's parameters by name (``sensor_x``, ``sensor_y``, ``sigma_v``, ... for a
      unicycle; ``wheelbase``, ``encoder_offset``, ``laser_a``, ``laser_b``,
      ``sigma_speed``, ... for an Ackermann).

    Raises
    ------
    DataNotFoundError
        The directory, ``controls.txt`` or ``observations.txt`` is missing.
    ParseError
        A malformed row (file, line and field named), a range not above 0, a bearing beyond
        two turns (degrees given for radians), observation rows of three and four numbers
        mixed, or a ``model.toml`` that is not TOML.
    ConfigError
        ``model.toml`` names an unknown kind or parameter, or a parameter out of range
        (the file and the key named).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "controls.txt").write_text("0.0 0.5 0.0\\n")
    >>> _ = (d / "observations.txt").write_text("0.1 4.0 0.2\\n0.1 6.0 -0.3\\n")
    >>> log = read_landmark_log(d)
    >>> [s.n_observations for s in log.steps], type(log.model).__name__, log.truth
    ([0, 2], 'Unicycle', None)
    """
    if not isinstance(directory, (str, os.PathLike)):
        raise ArgumentError(f"expected a directory path, got {type(directory).__name__}")
    d = Path(os.fspath(directory)).expanduser()
    files = log_files(d)
    _require_files(
        d,
        files,
        "landmark log",
        f"{d} is not a directory (expected one holding {LOG_HOLDS})",
        f"(expected {LOG_HOLDS})",
    )
    if files[0] == LOG_ODOMETRY:
        controls = None  # from the odometry, once the model is known
    elif (d / LOG_ODOMETRY).exists():
        raise ParseError(
            str(d / LOG_ODOMETRY),
            None,
            "is beside controls.txt: the motion comes from one of them (remove one)",
        )
    else:
        controls = read_table(d / "controls.txt", ("time", "c1", "c2"))
    obs_path = d / "observations.txt"
    meas = read_table(obs_path, ("time", "range", "bearing"), optional=("attribute",))
    bad = np.flatnonzero((meas[:, 1] <= 0) | (np.abs(meas[:, 2]) > MAX_ANGLE_SPAN))
    if len(bad):
        i = int(bad[0])
        r, b = meas[i, 1], meas[i, 2]
        what = (
            f"range must be above 0 m, found {r}"
            if r <= 0
            else f"bearing {b} is more than two turns: radians? ({b} deg is "
            f"{math.radians(b):.6g} rad)"
        )
        raise ParseError(
            str(obs_path), _line_of(obs_path, i), what, field="range" if r < 0 else "bearing"
        )
    optional = {
        "truth.txt": (("time", "x", "y", "theta"), True),
        "landmarks.txt": (("x", "y"), False),
        "gps.txt": (("time", "x", "y"), True),
    }
    tables = {}
    for name, (columns, ordered) in optional.items():
        path = d / name
        if path.exists():
            _regular(path)
            tables[name] = read_table(path, columns, ordered=ordered)
    model = _read_model(d / "model.toml")
    if controls is None:
        controls = _odometry_controls(d / LOG_ODOMETRY, model)
    return LandmarkLog(
        steps_from_arrays(controls, meas),
        model,
        tables.get("truth.txt"),
        tables.get("landmarks.txt"),
        d,
        tables.get("gps.txt"),
    )


def _odometry_controls(path: Path, model) -> np.ndarray:
    """The controls table (``time c1 c2``) of a landmark log's ``odometry.txt`` (``time
    x y theta``) for ``model``, which must be a :class:`~scanclique.slam.Unicycle`."""
    from .models import Unicycle, odometry_fault, unicycle_controls

    if not isinstance(model, Unicycle):
        raise ConfigError(
            f"{path.parent / 'model.toml'}: {LOG_ODOMETRY} gives a unicycle's controls; a "
            f"{type(model).__name__} takes controls.txt (its own controls)"
        )
    _regular(path)
    odo = read_table(path, ("time", "x", "y", "theta"))
    fault = odometry_fault(odo[:, 0], odo[:, 1:])
    if fault is not None:
        raise ParseError(str(path), _line_of(path, fault[0]), fault[1])
    return unicycle_controls(odo[:, 0], odo[:, 1:])


def _regular(path: Path) -> None:
    """A :class:`ParseError` when ``path`` (which exists) is not a regular file: a
    directory, or a pipe, which could block the reader."""
    if not path.is_file():
        raise ParseError(str(path), None, "is not a regular file")


def _read_model(path: Path):
    """The motion model ``path`` (``model.toml``) describes; a default
    :class:`~scanclique.slam.Unicycle` when there is no such file."""
    import inspect

    try:
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10
        import tomli as tomllib

    from .models import Ackermann, Unicycle

    if not path.exists():
        return Unicycle()
    _regular(path)
    try:
        table = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ParseError(str(path), None, f"not TOML ({exc})") from None
    except OSError as exc:  # no permission, an I/O error
        raise ParseError(str(path), None, f"cannot be read ({exc.strerror or exc})") from None
    kinds = {"unicycle": Unicycle, "ackermann": Ackermann}
    kind = table.pop("kind", "unicycle")
    if not isinstance(kind, str) or kind not in kinds:
        raise ConfigError(f"{path}: kind must be one of {', '.join(kinds)}, got {kind!r}")
    cls = kinds[kind]
    known = set(inspect.signature(cls).parameters)
    unknown = sorted(set(table) - known)
    if unknown:
        raise ConfigError(
            f"{path}: unknown {kind} parameter {unknown[0]!r} (known: {', '.join(sorted(known))})"
        )
    try:
        return cls(**table)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
