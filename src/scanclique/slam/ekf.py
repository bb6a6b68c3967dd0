"""EKF-SLAM with point landmarks and batch data association.

The joint state is ``[x, y, theta, m1x, m1y, m2x, m2y, ...]``: the vehicle pose (see
:mod:`scanclique.slam.models`) and world landmark positions, with their full covariance.
The recipe of :func:`ekf_slam`, per step of the log:

1. **predict** the vehicle with the step's control held since the previous step (the
   vehicle block of the covariance every step; the vehicle-map cross-covariance is
   multiplied by the accumulated motion Jacobian only when an observation needs it);
2. **select** the landmarks the sensor may see (predicted range and bearing within the
   sensor's limits plus a margin) and predict their measurements and covariance;
3. **associate** the batch (:func:`scanclique.slam.association.associate_predicted`);
4. **update** with all pairs at once, in Joseph form (expanded in the gain and the
   innovation covariance so that it costs O(n^2 m), symmetric by construction);
5. **initialise** new landmarks (inverse observation, covariance augmentation) as
   *tentative*; a landmark becomes permanent after ``confirm_hits`` sightings (one of
   them within ``confirm_range``), and a
   tentative landmark expected in view but unseen ``max_misses`` times is removed.

Angles are wrapped after every operation that changes them (heading, bearing
innovations), so associations behind the vehicle at +-pi are handled.

References
----------
H. Durrant-Whyte and T. Bailey, "Simultaneous localization and mapping: part I", IEEE
Robotics and Automation Magazine 13(2), 2006. J. Guivant and E. Nebot (2001), the
Victoria Park vehicle model (see :class:`~scanclique.slam.models.Ackermann`).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from .._records import readonly as _ro
from ..config import (
    check_choice,
    check_nonneg,
    check_positive,
    check_types,
    require_callable,
    require_config,
)
from ..errors import ArgumentError, ConfigError, StepError
from .association import (
    METHODS,
    NEW,
    REJECTED,
    AssociationConfig,
    Predicted,
    _individual_d2,
    _innovations,
    associate_predicted,
    chi2_bound,
)
from .checks import bearing_turns, far_between, mirrored
from .models import MotionModel, inverse_observe, observe, require_model, wrap
from .reader import Step

__all__ = ["SlamConfig", "SlamResult", "ekf_slam", "held_controls", "slip_variance"]

log = logging.getLogger(__name__)

#: bearing margin (rad) beyond each edge of ``SlamConfig.sensor_fov`` within which the map's
#: landmarks are still candidates for pairing (about 20 deg)
_FOV_MARGIN = 0.35

#: the largest :attr:`SlamConfig.noise_window` (pairs): a policy limit, so that a mistyped
#: window is an error and not a memory allocation of terabytes
MAX_NOISE_WINDOW = 1_000_000


@dataclass(frozen=True, slots=True)
class SlamConfig:
    """Parameters of :func:`ekf_slam` (defaults for the Victoria Park tree detector).

    **The defaults are Victoria Park's**: the sensor's noise (``sigma_range`` 0.5 m,
    ``sigma_bearing`` 1.5 deg) and limits (``max_range`` 25 m, ``sensor_fov`` 180 deg),
    the vehicle's slip (per metre travelled and per radian turned, see below), the
    detector's range-dependent reliability
    (``confirm_range`` 20 m) and its trunk diameters' spread
    (:attr:`AssociationConfig.attribute_sigma`, used only with attributes). For another
    sensor, give its noise and limits in one place with :meth:`for_sensor`, and the robot's
    slip (``sigma_xy_rate``, ``sigma_theta_rate``: the odometry's systematic error, which
    the motion model's white control noise does not cover at a high control rate).

    Attributes
    ----------
    sigma_range : float
        Standard deviation of a tree centre's range (m): the laser's range noise plus the
        centre estimate from a trunk's arc. On Victoria Park the range innovations of
        landmarks seen 20 times or more have a robust standard deviation of 0.06-0.10 m
        (map and pose uncertainty included; 0.13 m beyond 20 m with outliers), but with
        0.15 m the filter is overconfident on the simulated park, where this noise is the
        truth (ANEES about 7.5 over 5 parks, band [1.25, 5.5]; 3.96 with 0.5 m): the
        linearised heading makes a precise sensor's updates too strong, and an inflated
        range noise keeps the filter consistent. The iterated update
        (``update_iterations=3``) removes that overconfidence on the simulated park
        (ANEES 2.78 over 3 parks at 0.15 m and 0.5 deg, 98.8 % of steps in the band) but
        not on Victoria Park, where the same noises give a GPS RMSE of 5.3 m (SE(2)) and
        322 landmarks, 24 % in duplicate pairs (clique): there the inflation covers
        unmodelled error (see ``sigma_bearing``), not the linearisation. Hence 0.5 m.
    sigma_bearing : float
        Standard deviation of the bearing (rad): about the angular resolution of the
        laser (0.5 deg) plus the centre estimate. Victoria Park's bearing innovations
        spread less (0.5 deg) but carry a bias of -0.24 deg whenever the car moves (none
        at rest; larger in left turns): an unmodelled heading error that neither a
        steering-offset nor a bearing-offset state removes (both measured worse against
        GPS). With 0.5 deg the filter grows overconfident and duplicates trees, so 1.5.
    max_range : float or None
        Observations farther than this are not used (m).
    sensor_fov : float
        Field of view of the sensor (rad), centred on the heading (180 deg for the SICK).
        Landmarks within it and 20 deg beyond each edge are candidates for pairing, and
        those within it are expected to be seen. An observation farther outside proves
        the sensor sees there: the run widens its field of view to the bearings it has
        seen and warns at the end (a 360 deg sensor under the default: 15 landmarks
        mapped as 42 to 59 with NN, 18 to 25 with the clique, before it did; 15 after).
    sigma_xy_rate, sigma_theta_rate : float
        Additive process noise (m, rad per square root of second) added while the
        vehicle moves (:meth:`MotionModel.moving
        <scanclique.slam.models.MotionModel.moving>`: a unicycle turning on the spot
        moves, a car at rest with its wheel turned does not). 0 by default: slip grows
        with the path and the turns, not with the clock (below); a noise per second tuned
        for a car at 3 m/s is 40 % of the path of a robot at 0.25 m/s.
    sigma_xy_distance, sigma_theta_distance : float
        Additive process noise per square root of metre travelled (m, rad): the
        variance of x and of y grows by ``sigma_xy_distance**2`` per metre, the
        heading's by ``sigma_theta_distance**2`` (wheel radii, slip along the path).
    sigma_theta_turn : float
        Additive heading noise per square root of radian turned (rad): a wheel base,
        steering or gyro scale off by a little turns every rotation by a little more or
        less. The three forms add up to one step's additive noise, :attr:`slip` (rows
        per second, per metre, per radian; columns x, y, heading); 0 leaves a form out.
        **Defaults**: the slip that Victoria Park's filter used per second (0.1 m and
        0.5 deg per square root of second, while moving) put per metre and per radian
        with that log's own motion (2.73 m per second moving, 0.088 rad turned per
        second moving): 0.06 m per square root of metre, and the heading's variance half
        per metre (0.21 deg) and half per radian turned (1.2 deg). Measured on Victoria
        Park against the per-second noise (GPS RMSE start / SE(2) alignment, m): clique
        3.58 / 1.54 -> 3.53 / 1.52, nn 3.47 / 1.55 -> 3.40 / 1.53, jcbb the same as nn;
        with 5 clutter detections per scan clique 3.47 / 1.59 -> 3.37 / 1.51, nn 3.46 /
        2.28 -> 3.39 / 2.12, jcbb 3.49 / 2.12 -> 3.42 / 2.00. On the simulated room
        (a robot at 0.25 m/s; truth 0.02 m and 1 deg per square root of second) given
        the sensor by :meth:`for_sensor` but not the slip, pose RMSE 0.29 -> 0.14 m
        (clique) and 0.22 -> 0.14 m (nn), as good as the room's true slip. Either form
        scaled by 0.7 breaks Victoria Park (a loop not closed, 8 m). On 40
        simulated parks (whose truth follows these defaults) 6 runs end with an ANEES
        above 50 for NN and for the clique, against 3 with the per-second slip; the
        others are as consistent (mean ANEES 3.50 against 3.72, clique).
    initial_sigma : (3,) float
        Standard deviations of the initial pose (m, m, rad).
    confirm_hits : int
        Sightings after which a tentative landmark becomes permanent.
    max_misses : int
        A tentative landmark expected in view (within ``visible_range``) and not seen this
        many times is removed.
    tentative_scans : int
        A landmark still tentative this many scans after its first sighting is removed.
    visible_range : float
        Range (m) within which a landmark in the field of view is expected to be seen
        (misses count only there); never beyond ``max_range``, whatever its value: the
        default 20 m is Victoria Park's, and with a 5 m sensor it counted landmarks
        beyond the sensor's reach as missed.
    init_range : (2,) float
        Range interval (m) in which an unpaired observation may start a landmark; outside
        it the observation is rejected. (Default: no limit. A limit leaves the trees seen
        only beyond it out of the map while their observations still seek partners among
        the mapped trees: on the simulated park, a limit of 20 m with a 25 m sensor range
        puts JCBB's ANEES above 200 on 2 of 5 parks; :attr:`confirm_range` is the safe form.)
    confirm_range : float or None
        A tentative landmark becomes permanent only when, besides ``confirm_hits``
        sightings, at least one of them was within this range (m); until then it stays
        tentative (removed when missed or expired, see below). Far detections still
        start and update landmarks, so they find their own tree, but a tree the sensor
        never sees near is not trusted into the map: on Victoria Park the detector's
        range and diameter spread grow beyond 20 m (robust standard deviations of the
        range innovations 0.066 m at 15-20 m, 0.082 at 20-25, 0.095 at 25-30; of the
        diameters 0.07, 0.11, 0.15 m at 10-20, 20-30, 30-40 m), hence 20 m. None: no
        condition. A property of that detector: without effect for a sensor whose range
        is 20 m or less; :meth:`for_sensor` leaves it out.
    control_bias_sigma : float or None
        When set, the filter estimates a constant additive bias of the second control
        (the steering angle of :class:`~scanclique.slam.Ackermann`, rad; the turn rate of
        :class:`~scanclique.slam.Unicycle`, rad/s) as a fourth vehicle state, with this
        prior standard deviation: a steering sensor's zero offset is a calibration error
        that additive heading noise can only cover, and the landmarks make it observable.
    control_bias_rate : float or None
        Random-walk standard deviation of that bias (per square root of second).
    speed_scale_sigma : float or None
        When set (the default, 0.05), the filter estimates a constant relative error of
        the first control (the speed of both models) as a vehicle state, with this prior
        standard deviation: the logged speed is taken as ``v (1 + s)``. A wheel radius or
        encoder scale off by a few percent is a calibration error that additive speed
        noise can only cover; the landmarks make it observable. On Victoria Park with
        every logged speed scaled by 0.97 the filter without it breaks (GPS RMSE after
        SE(2) alignment 8.6 m, clique; 8.2 m, JCBB; 218 and 224 landmarks), and by 0.95
        worse (24.8 m, 7.8 m); with it 0.95, 0.97, 1.0 and 1.03 all give 1.54 m (clique),
        and the logged speeds 1.571 -> 1.540 m (clique), 1.58 -> 1.551 m (NN, JCBB), the
        drift from the start (RMSE under the alignment of the first 50 m) 3.46 -> 3.58 m
        (clique), 3.38 -> 3.47 m (NN, JCBB); these with the per-second slip of session
        19. With the default slip per metre and per radian, speeds scaled by 0.95, 0.97
        and 1.03 give 1.523, 1.523 and 1.522 m (clique). None: the speed is taken as
        logged (the compiled prediction then runs when no other calibration state is
        set).
    bearing_bias_sigma : float or None
        When set, the filter estimates a constant offset of the sensor's bearings (rad;
        a yaw misalignment of its mounting) as a vehicle state, with this prior standard
        deviation. Observations fix only heading plus offset; the motion separates them.
    update_iterations : int
        Linearisations of the observation model per update: 1 is the EKF; more is the
        iterated EKF (Bell and Cathey 1993), which re-linearises at the updated estimate.
    tentative_update : {"full", "landmark"}
        What a tentative landmark's pair updates: ``"full"``, the whole state (the EKF);
        ``"landmark"``, that landmark alone (a Schmidt update: the gain's other rows set
        to zero, the covariance exact in Joseph form), after the permanent landmarks'
        pairs have updated the state: a spurious detection that started a landmark does
        not move the vehicle. Measured against ``"full"`` (the clique with
        ``AssociationConfig(ambiguity="conflict")``): on Victoria Park, without clutter
        3.35 / 1.59, 3.36 / 1.59, 3.43 / 1.57 m (nn, jcbb, clique; start / SE(2))
        against 3.38 / 1.58, 3.38 / 1.58, 3.46 / 1.57; with 5 clutter detections per
        scan 3.08 / 1.57, 3.05 / 1.57, 3.38 / 1.49 m against 11.57 / 8.58, 3.56 / 2.24,
        3.53 / 1.62; the clique's SE(2) error over 3 clutter seeds at 5 and 10 per scan
        1.49-1.70 m against 1.61-7.20 m. On 5 simulated rooms with one spurious
        detection per frame ANEES 5.48, 5.02, 4.19 (nn, jcbb, clique; 66, 70, 84 % of
        the frames in the band) against 6.83, 6.06, 5.96 (41, 55, 54 %). But on the 5
        simulated parks (150 trees, 25 m) nn, jcbb and clique-jcbb close the loop
        wrongly on one park (ANEES 109, 74, 57 against 4.0, 4.0, 3.7; the clique 3.05
        against 2.99), and the clique's start-aligned error on Victoria Park at 5 clutter
        detections is no longer below JCBB's. Hence ``"full"`` by default; ``"landmark"``
        is worth trying for a sensor with frequent false detections.
    noise_window : int or None
        When set (the default, 200), the filter checks the configured sensor noise
        (``sigma_range``, ``sigma_bearing``) against its innovations: those of its last
        ``noise_window`` pairs with established landmarks, before their update, range and
        bearing apart. When the median of a component's normalised innovations squared,
        ``nu**2 / (S_pred + sigma**2)`` (``S_pred`` the vehicle's and the map's part), is
        above ``noise_trigger`` times the median of a chi-square of 1 degree of freedom
        (0.455, what a right noise gives), that component's variance is raised to the one
        that brings the median back to 0.455 (covariance matching, Mehra 1972; the median
        holds against a minority of wrong pairs); checked every quarter window (the first
        check over the first 50 pairs, until the window fills over the pairs so far), the
        raised noise then following the innovations, never below the configured one. A
        sensor noisier than configured otherwise narrows every gate: re-observations fall
        outside and start duplicates. On 5 simulated rooms (a 3 deg bearing sensor) with
        the filter not told the sensor (``SlamConfig()``: 1.5 deg) the pose RMSE falls
        0.411 -> 0.202 m (nn), 0.383 -> 0.171 m (jcbb), 0.334 -> 0.158 m (clique),
        duplicate landmarks 11.0 / 11.4 / 6.6 -> 0.6 / 0.4 / 0.4 per room (with a 180
        deg field of view 0.193 -> 0.134 m, nn); a first check only once the window is
        full gave 0.236 / 0.210 / 0.200 m. Victoria Park is unchanged at 0, 5 and 10
        clutter detections per scan (its configured noise is larger than its innovations
        on purpose, see ``sigma_range``), and so are the rooms whose filter is told the
        sensor; on the 5 simulated parks (whose noise is the configured one) NN's and
        JCBB's ANEES move 3.52 / 3.53 -> 3.54 / 3.56, their pose RMSE 1.29 / 1.28 ->
        1.31 / 1.30 m, and the 40 parks keep their failures (runs above ANEES 10: 2 / 1 /
        1 / 0). Window 100 (with trigger 1.5 and the first check at a full window) let one
        JCBB room with a spurious detection per frame diverge (0.235 -> 0.492 m over 5
        rooms); 300 warms up too slowly for a room's 15 landmarks. None: the configured
        noise throughout.
        :attr:`SlamResult.observation_noise` reports what the run ended with, and a run
        that raised it in most checks logs a warning naming the noise it found. With
        attributes, the clique methods' attribute gate
        (:attr:`AssociationConfig.attribute_sigma`) is checked likewise against the
        attributes' spread about their landmarks' and widened when they spread more
        (attributes in centimetres, or not a tree's diameter; see
        :attr:`SlamResult.attribute_scale`, and a warning says so).
    noise_trigger : float
        How far (a ratio >= 1 of the median normalised innovation squared to 0.455) the
        innovations must say the sensor is noisier before the noise is raised: 2, so that
        a right noise is left as it is. With 1.5 one check of about a hundred raised it
        on one of the 5 simulated parks (NN), as the vehicle came back with its drift,
        and the wider gates closed that loop on a neighbouring tree (ANEES 2.5 -> 54):
        the innovations of consecutive scans share the map's and the vehicle's errors, so
        a window of 200 pairs holds far fewer independent ones. A sensor twice as noisy
        as configured (four times the variance) is well beyond 2.
    association : AssociationConfig

    Every field is checked when the record is built: a value of the wrong type, NaN, a
    noise or count out of range (sigmas of the sensor, ``sensor_fov``, ``confirm_hits``,
    ``max_misses``, ``tentative_scans``, ``update_iterations`` and ``noise_window`` > 0;
    ``sensor_fov`` at most 2 pi and ``sigma_bearing`` at most pi / 4, so that degrees
    given for radians are refused, with the value converted in the message;
    ``max_range``, ``visible_range`` and ``confirm_range`` > 0, +inf meaning no limit;
    the rates and the calibration sigmas >= 0; ``noise_window`` at most
    :data:`MAX_NOISE_WINDOW`; ``noise_trigger`` >= 1), or a
    ``tentative_update`` that is not one of its choices is a
    :class:`~scanclique.errors.ConfigError` naming the field.
    """

    sigma_range: float = 0.5
    sigma_bearing: float = math.radians(1.5)
    max_range: float | None = 25.0
    sensor_fov: float = math.pi
    sigma_xy_rate: float = 0.0
    sigma_theta_rate: float = 0.0
    sigma_xy_distance: float = 0.06
    sigma_theta_distance: float = math.radians(0.21)
    sigma_theta_turn: float = math.radians(1.2)
    initial_sigma: tuple[float, float, float] = (0.01, 0.01, math.radians(0.1))
    confirm_hits: int = 5
    max_misses: int = 3
    tentative_scans: int = 25
    visible_range: float = 20.0
    init_range: tuple[float, float] = (0.0, math.inf)
    confirm_range: float | None = 20.0
    control_bias_sigma: float | None = None
    control_bias_rate: float | None = None
    speed_scale_sigma: float | None = 0.05
    bearing_bias_sigma: float | None = None
    update_iterations: int = 1
    tentative_update: str = "full"
    noise_window: int | None = 200
    noise_trigger: float = 2.0
    association: AssociationConfig = field(default_factory=AssociationConfig)

    def __post_init__(self) -> None:
        check_types(self)
        check_positive(
            self, "sigma_range", "sigma_bearing", "sensor_fov", "confirm_hits", "max_misses",
            "tentative_scans", "update_iterations", "noise_window",
        )  # fmt: skip
        check_positive(self, "max_range", "visible_range", "confirm_range", infinite=True)
        check_nonneg(
            self, "sigma_xy_rate", "sigma_theta_rate", "sigma_xy_distance",
            "sigma_theta_distance", "sigma_theta_turn", "control_bias_sigma",
            "control_bias_rate", "speed_scale_sigma", "bearing_bias_sigma",
        )  # fmt: skip
        # radians: a value that no field of view or bearing noise can have in radians is
        # refused as degrees given for radians
        for name, top, what in (
            ("sensor_fov", 2.0 * math.pi, "2 pi rad (360 deg)"),
            ("sigma_bearing", math.pi / 4.0, "pi / 4 rad (45 deg)"),
        ):
            v = getattr(self, name)
            if v > top * (1.0 + 1e-12):
                raise ConfigError(
                    f"SlamConfig.{name} is in radians and at most {what}, got {v!r}; if that "
                    f"is degrees, give math.radians({v!r}) = {math.radians(v):.6g}"
                )
        if not all(math.isfinite(s) and s >= 0 for s in self.initial_sigma):
            raise ConfigError(
                f"SlamConfig.initial_sigma must be three numbers >= 0, got {self.initial_sigma!r}"
            )
        lo, hi = self.init_range
        if not (math.isfinite(lo) and 0 <= lo <= hi):
            raise ConfigError(
                "SlamConfig.init_range must be (low, high) with 0 <= low <= high (high may be "
                f"inf), got {self.init_range!r}"
            )
        check_choice(self, "tentative_update", ("full", "landmark"))
        if self.noise_window is not None and self.noise_window > MAX_NOISE_WINDOW:
            raise ConfigError(
                f"SlamConfig.noise_window must be at most {MAX_NOISE_WINDOW} pairs (its ring "
                f"holds two numbers per pair and component), got {self.noise_window!r}"
            )
        if not (math.isfinite(self.noise_trigger) and self.noise_trigger >= 1.0):
            raise ConfigError(
                f"SlamConfig.noise_trigger must be a number >= 1, got {self.noise_trigger!r}"
            )

    @classmethod
    def for_sensor(
        cls,
        sigma_range: float,
        sigma_bearing: float,
        max_range: float | None,
        fov: float = math.pi,
        *,
        attribute_sigma: tuple[float, float] | None = None,
        **fields,
    ) -> SlamConfig:
        """A configuration for a range-bearing sensor, given in one place: its noise and
        its limits, with the settings that depend on them following it.

        ``visible_range`` becomes ``max_range`` (a landmark within the sensor's range and
        field of view is expected to be seen), ``confirm_range`` None (Victoria Park's
        detector grows unreliable beyond 20 m; a sensor whose noise is given as one range
        sigma does not), and the association's attribute gate ``attribute_sigma`` the
        given one (None: no gate on attributes; the default is Victoria Park's trunk
        diameters). Everything else keeps its default unless given in ``fields``
        (notably the robot's slip: ``sigma_xy_distance``, ``sigma_theta_distance``,
        ``sigma_theta_turn`` per metre and per radian, whose defaults carry over between
        vehicles; ``sigma_xy_rate`` and ``sigma_theta_rate`` per second add to them).

        Parameters
        ----------
        sigma_range : float
            Standard deviation of the range (m).
        sigma_bearing : float
            Standard deviation of the bearing (rad).
        max_range : float or None
            Farthest range the sensor reports (m).
        fov : float
            Field of view (rad), centred on the sensor's heading.
        attribute_sigma : (2,) float or None
            Spread of an observation's scalar attribute about its landmark's, ``a + b *
            range`` (see :class:`AssociationConfig`).
        **fields
            Any other field of :class:`SlamConfig`.

        Examples
        --------
        >>> cfg = SlamConfig.for_sensor(0.15, math.radians(3.0), 5.0, math.radians(60.0),
        ...                             sigma_xy_rate=0.02)
        >>> cfg.visible_range, cfg.confirm_range, cfg.association.attribute_sigma
        (5.0, None, None)
        """
        from dataclasses import replace

        def num(name, v) -> float:  # float('0.5') would take a string, float('x') fail
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.number)):
                raise ConfigError(f"SlamConfig.for_sensor: {name} must be a number, got {v!r}")
            return float(v)

        assoc = fields.pop("association", None) or AssociationConfig()
        if not isinstance(assoc, AssociationConfig):
            raise ConfigError(
                f"SlamConfig.association must be a AssociationConfig, got {type(assoc).__name__}"
            )
        base = dict(
            sigma_range=num("sigma_range", sigma_range),
            sigma_bearing=num("sigma_bearing", sigma_bearing),
            max_range=None if max_range is None else num("max_range", max_range),
            sensor_fov=num("fov", fov),
            visible_range=math.inf if max_range is None else num("max_range", max_range),
            confirm_range=None,
            association=replace(assoc, attribute_sigma=attribute_sigma),
        )
        base.update(fields)
        return cls(**base)

    @property
    def R(self) -> np.ndarray:
        return np.diag([self.sigma_range**2, self.sigma_bearing**2])

    @property
    def slip(self) -> np.ndarray:
        """The additive process noise as a (3, 3) array of variances: row 0 per second
        (while moving), row 1 per metre travelled, row 2 per radian turned; columns x, y,
        heading. A step from pose ``x0`` to ``x1`` over ``dt`` seconds adds
        ``slip_variance(self.slip, x0, x1, dt)``."""
        xy_t, th_t = self.sigma_xy_rate**2, self.sigma_theta_rate**2
        xy_d, th_d = self.sigma_xy_distance**2, self.sigma_theta_distance**2
        return np.array(
            [[xy_t, xy_t, th_t], [xy_d, xy_d, th_d], [0.0, 0.0, self.sigma_theta_turn**2]]
        )


def slip_variance(slip: np.ndarray, x0, x1, dt: float) -> np.ndarray:
    """The additive variances (3,) of x, y and heading for one step of a moving vehicle
    from pose ``x0`` to ``x1`` (``(x, y, theta)``) over ``dt`` seconds, given
    :attr:`SlamConfig.slip`: per second, per metre of the straight path between the two
    poses and per radian of heading change."""
    dist = math.hypot(x1[0] - x0[0], x1[1] - x0[1])
    turn = abs(wrap(x1[2] - x0[2]))
    return slip[0] * dt + slip[1] * dist + slip[2] * turn


@dataclass(frozen=True, slots=True, eq=False)
class SlamResult:
    """The run of :func:`ekf_slam`.

    Attributes
    ----------
    times : (N,) ndarray
        Time of each step (s).
    poses : (N, 3) ndarray
        Vehicle pose ``(x, y, theta)`` after each step (world frame; rad).
    pose_covariances : (N, 3, 3) ndarray
    landmarks : (n, 2) ndarray
        Final map: permanent landmarks' world positions (m).
    landmark_covariances : (n, 2, 2) ndarray
    landmark_ids : (n,) int64 ndarray
        Stable id of each landmark (the ids of :attr:`associations`).
    landmark_hits : (n,) int64 ndarray
        Sightings of each landmark.
    observation_times : (S,) ndarray
        Times of the steps with observations.
    associations : tuple of (k,) int64 ndarrays
        Per observation step: landmark id of each observation, or ``NEW`` (-1, started a
        landmark) or ``REJECTED`` (-2).
    association_seconds : (S,) ndarray
        Time of each association.
    joint_d2, dof : (S,) ndarrays
        Joint Mahalanobis distance (squared) of each step's pairs and its degrees of
        freedom (paper section 7: validation of each association).
    ambiguous : (S,) bool ndarray
        Steps whose best association was ambiguous (handled conservatively).
    method : str
    seconds : float
        Wall-clock time of the whole run.
    cpu_seconds : float
        CPU time of the whole run (the process's; one core: the filter is single-threaded
        except for any BLAS threads).
    config : SlamConfig
    control_bias : (float, float) or None
        The estimated bias of the second control at the end of the run and its standard
        deviation, when :attr:`SlamConfig.control_bias_sigma` is set.
    speed_scale : (float, float) or None
        The estimated relative error ``s`` of the speed (logged speed times ``1 + s``) at
        the end of the run and its standard deviation, when
        :attr:`SlamConfig.speed_scale_sigma` is set.
    bearing_bias : (float, float) or None
        The same for the sensor's bearing offset (rad), when
        :attr:`SlamConfig.bearing_bias_sigma` is set.
    observation_noise : (float, float) or None
        The sensor noise the run ended with, standard deviations of range (m) and bearing
        (rad), when :attr:`SlamConfig.noise_window` is set: the configured one, or larger
        where the innovations said the sensor is noisier.
    noise_raised : float
        The fraction of the noise checks (one per quarter :attr:`SlamConfig.noise_window`
        of pairs) that raised the noise above the configured one; NaN without a check
        (no ``noise_window``, or fewer pairs than a quarter window).
    attribute_scale : float
        The factor by which the run ended up widening the clique methods' attribute gate
        (:attr:`AssociationConfig.attribute_sigma`) to the spread of the observations'
        attributes about their landmarks': 1 when the configured spread held (it is
        never narrowed), larger for attributes noisier than configured or in other units.
        NaN when not checked (no attributes, no ``attribute_sigma``, no ``noise_window``,
        the ``nn`` and ``jcbb`` methods, which do not use attributes, or fewer pairs than
        a quarter window).
    beyond_max_range : (int, int)
        The observations farther than :attr:`SlamConfig.max_range`, which the filter did
        not use, and all observations (Victoria Park under the default 25 m: 24518 of
        52974); a run with more than half beyond warns.
    """

    times: np.ndarray
    poses: np.ndarray
    pose_covariances: np.ndarray
    landmarks: np.ndarray
    landmark_covariances: np.ndarray
    landmark_ids: np.ndarray
    landmark_hits: np.ndarray
    observation_times: np.ndarray
    associations: tuple
    association_seconds: np.ndarray
    joint_d2: np.ndarray
    dof: np.ndarray
    ambiguous: np.ndarray
    method: str
    seconds: float
    config: SlamConfig
    cpu_seconds: float = float("nan")
    control_bias: tuple[float, float] | None = None
    bearing_bias: tuple[float, float] | None = None
    speed_scale: tuple[float, float] | None = None
    observation_noise: tuple[float, float] | None = None
    noise_raised: float = float("nan")
    attribute_scale: float = float("nan")
    beyond_max_range: tuple[int, int] = (0, 0)

    def __post_init__(self) -> None:
        for name in (
            "times",
            "poses",
            "pose_covariances",
            "landmarks",
            "landmark_covariances",
            "landmark_ids",
            "landmark_hits",
            "observation_times",
            "association_seconds",
            "joint_d2",
            "dof",
            "ambiguous",
        ):
            object.__setattr__(self, name, _ro(getattr(self, name)))

    def positions_at(self, t) -> np.ndarray:
        """Vehicle positions (len(t), 2) linearly interpolated at times ``t``."""
        t = np.asarray(t, float)
        return np.column_stack(
            [np.interp(t, self.times, self.poses[:, 0]), np.interp(t, self.times, self.poses[:, 1])]
        )


class _Filter:
    """The joint state and covariance, with room to grow (internal)."""

    def __init__(self, pose, pose_cov, cap=256, confirm_hits=5):
        self.confirm_hits = confirm_hits
        nv = len(pose)  # vehicle states: the pose, then any calibration states
        self.nv = nv
        self.ib = None  # index of the sensor's bearing bias, when estimated
        self.x = np.zeros(nv + 2 * cap)
        self.P = np.zeros((nv + 2 * cap, nv + 2 * cap))
        self.x[:nv] = pose
        self.P[:nv, :nv] = pose_cov
        self.n = 0  # landmarks
        self.ids = np.zeros(cap, np.int64)
        self.hits = np.zeros(cap, np.int64)
        self.misses = np.zeros(cap, np.int64)
        self.att = np.zeros(cap)
        self.born = np.zeros(cap, np.int64)  # scan index of the first sighting
        self.near = np.zeros(cap, bool)  # seen within the confirmation range
        self.scan = 0
        self.next_id = 0

    def permanent(self) -> np.ndarray:
        """(n,) bool: the landmarks past their tentative stage: seen ``confirm_hits``
        times, once within ``confirm_range``."""
        return (self.hits[: self.n] >= self.confirm_hits) & self.near[: self.n]

    @property
    def obs_cols(self):
        return [0, 1, 2] if self.ib is None else [0, 1, 2, self.ib]

    def observe(self, lm, sx, sy):
        """Predicted range/bearing of world points ``lm`` with Jacobians: ``Hx`` over
        :attr:`obs_cols` (the pose and the bearing bias) and ``Hm``."""
        z, Hx, Hm = observe(self.x[:3], lm, sx, sy)
        if self.ib is None:
            return z, Hx, Hm
        z[:, 1] = wrap(z[:, 1] + self.x[self.ib])
        Ha = np.zeros((len(z), 2, 4))
        Ha[:, :, :3] = Hx
        Ha[:, 1, 3] = 1.0
        return z, Ha, Hm

    def inverse(self, z, sx, sy):
        """World points of observations ``z`` with Jacobians over :attr:`obs_cols`."""
        if self.ib is None:
            return inverse_observe(self.x[:3], z, sx, sy)
        zc = np.array(z, float).reshape(-1, 2)
        zc[:, 1] -= self.x[self.ib]
        m, Gx, Gz = inverse_observe(self.x[:3], zc, sx, sy)
        Ga = np.zeros((len(zc), 2, 4))
        Ga[:, :, :3] = Gx
        Ga[:, :, 3] = -Gz[:, :, 1]
        return m, Ga, Gz

    @property
    def dim(self):
        return self.nv + 2 * self.n

    def _grow(self):
        cap = len(self.ids)
        new = cap * 2
        x = np.zeros(self.nv + 2 * new)
        x[: len(self.x)] = self.x
        P = np.zeros((self.nv + 2 * new, self.nv + 2 * new))
        d = self.dim
        P[:d, :d] = self.P[:d, :d]
        self.x, self.P = x, P
        for name in ("ids", "hits", "misses", "att", "born", "near"):
            a = getattr(self, name)
            b = np.zeros(new, a.dtype)
            b[:cap] = a
            setattr(self, name, b)

    def add(self, m, Gx, Gz, R, attribute, near=True):
        """Append a landmark at ``m`` with Jacobians of the inverse observation."""
        if self.n == len(self.ids):
            self._grow()
        d = self.dim
        P = self.P
        o = self.obs_cols  # the vehicle states the observation depends on
        rows = Gx @ P[o, :d]  # (2, d)
        Pmm = Gx @ P[np.ix_(o, o)] @ Gx.T + Gz @ R @ Gz.T
        P[d : d + 2, :d] = rows
        P[:d, d : d + 2] = rows.T
        P[d : d + 2, d : d + 2] = 0.5 * (Pmm + Pmm.T)
        self.x[d : d + 2] = m
        j = self.n
        self.ids[j] = self.next_id
        self.next_id += 1
        self.hits[j] = 1
        self.misses[j] = 0
        self.att[j] = attribute
        self.born[j] = self.scan
        self.near[j] = near
        self.n += 1
        return self.ids[j]

    def remove(self, js):
        """Remove landmarks (local indices ``js``)."""
        js = np.asarray(sorted(set(int(j) for j in js)), int)
        if len(js) == 0:
            return
        d = self.dim
        keep_l = np.setdiff1d(np.arange(self.n), js)
        nv = self.nv
        keep = np.r_[np.arange(nv), (nv + 2 * keep_l[:, None] + np.arange(2)).reshape(-1)]
        keep = keep.astype(int)
        x = self.x[keep].copy()
        P = self.P[np.ix_(keep, keep)].copy()
        m = len(keep)
        self.x[:m] = x
        self.P[:m, :m] = P
        self.x[m:d] = 0
        for name in ("ids", "hits", "misses", "att", "born", "near"):
            a = getattr(self, name)
            a[: len(keep_l)] = a[keep_l]
        self.n = len(keep_l)


def _check_log(steps, model, cfg: SlamConfig, held, dts, obs_steps) -> None:
    """Warn, before the filter runs, of what the log's units or conventions make
    impossible (:mod:`scanclique.slam.checks`): controls that carry the vehicle beyond
    the sensor's reach between consecutive observations, and bearings that turn against
    the controls' turns."""
    far = far_between(held, dts, obs_steps)
    if cfg.max_range is not None and far > cfg.max_range:
        log.warning(
            "the controls move the vehicle %.4g m between consecutive observations (median), "
            "farther than the sensor reaches (max_range %.4g m): no landmark of one batch "
            "can be in view at the next. Are the step times in seconds (not milliseconds or "
            "nanoseconds) and the speeds in m/s?",
            far,
            cfg.max_range,
        )
    counts = bearing_turns(steps, model, (cfg.sigma_range, cfg.sigma_bearing), cfg.max_range)
    if mirrored(counts):
        log.warning(
            "the observations' bearings turn against the controls: carried through the "
            "vehicle's turns, %d of them are explained with their bearings mirrored and %d "
            "as given. Bearings are counter-clockwise from the heading (a clockwise sensor's "
            "need their sign changed), and the second control turns the vehicle to the left "
            "when positive (steering angle, turn rate); the map will not hold together.",
            counts[1],
            counts[0],
        )


def held_controls(steps: Sequence[Step]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The motion between consecutive steps, as the filter integrates it.

    Returns ``(times, held, dts)``: the step times ``(N,)`` (s); ``held[k]`` ``(N, 2)``, the
    control holding over ``(t[k-1], t[k]]``, which is the last one given at or before
    ``t[k-1]`` (NaN before the first control, and for ``k = 0``); ``dts[k] = t[k] - t[k-1]``
    (0 for ``k = 0``).

    Examples
    --------
    >>> steps = [Step(0.0, (1.0, 0.0), []), Step(0.5, None, []), Step(1.5, (2.0, 0.1), [])]
    >>> t, held, dt = held_controls(steps)
    >>> held[1].tolist(), held[2].tolist(), dt.tolist()
    ([1.0, 0.0], [1.0, 0.0], [0.0, 0.5, 1.0])
    """
    N = len(steps)
    times = np.array([s.time for s in steps], float)
    ctrl = np.full((N, 2), np.nan)
    last = np.full(2, np.nan)
    for k, s in enumerate(steps):
        if s.control is not None:
            last = s.control
        ctrl[k] = last
    held = np.vstack([np.full((1, 2), np.nan), ctrl[:-1]]) if N else ctrl
    dts = np.diff(times, prepend=times[0] if N else 0.0)
    return times, held, dts


def ekf_slam(
    steps: Sequence[Step],
    motion_model: MotionModel,
    *,
    association: str = "clique",
    config: SlamConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    initial_pose=(0.0, 0.0, 0.0),
) -> SlamResult:
    """EKF-SLAM over a log of :class:`~scanclique.slam.Step` records.

    Parameters
    ----------
    steps : sequence of Step
        Time-ordered controls and batch observations (range, bearing in the sensor frame).
    motion_model : Ackermann or Unicycle
        The vehicle model, with the sensor's position on the vehicle.
    association : {"clique", "jcbb", "nn"}
        The data association method (:mod:`scanclique.slam.association`).
    config : SlamConfig, optional
    progress : callable(done, total), optional
        Called every few hundred steps.
    initial_pose : (3,) float
        The vehicle's pose at the first step.

    Returns
    -------
    SlamResult
        No steps give an empty result.

    Raises
    ------
    ArgumentError
        ``steps`` is not a sequence of :class:`~scanclique.slam.Step`, ``motion_model``
        not a :class:`~scanclique.slam.models.MotionModel`, ``progress`` not callable, or
        ``initial_pose`` not three finite numbers.
    StepError
        The steps are not in time order (equal times are allowed), or a control's angle
        cannot be radians for ``motion_model``
        (:attr:`~scanclique.slam.models.MotionModel.control_bound`: degrees given for
        radians). A step's own values are checked when it is made
        (:class:`~scanclique.slam.Step`).
    ConfigError
        ``association`` is not one of the methods, or ``config`` not a
        :class:`~scanclique.slam.SlamConfig` (checked before the first step, so a log
        without observations does not hide it).
    """
    if isinstance(steps, (str, bytes)) or not isinstance(steps, Iterable):
        raise ArgumentError(
            f"ekf_slam: steps must be a sequence of Step, got {type(steps).__name__}"
        )
    if not isinstance(steps, Sequence):
        steps = list(steps)
    for k, s in enumerate(steps):
        if not isinstance(s, Step):
            raise ArgumentError(f"ekf_slam: steps[{k}] is a {type(s).__name__}, not a Step")
        if k and s.time < steps[k - 1].time:
            raise StepError(
                f"ekf_slam: steps[{k}] at t={s.time} comes before steps[{k - 1}] at "
                f"t={steps[k - 1].time}: steps must be in time order"
            )
    try:
        pose0 = np.array(initial_pose, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise ArgumentError(
            f"ekf_slam: initial_pose must be 3 numbers (x, y, theta), got {initial_pose!r}"
        ) from None
    if not np.isfinite(pose0).all():
        raise ArgumentError(f"ekf_slam: initial_pose {pose0.tolist()} is not finite")
    require_model("ekf_slam: ", "motion_model", motion_model)
    given = [k for k, s in enumerate(steps) if s.control is not None]
    bad = motion_model.implausible_control(np.array([steps[k].control for k in given]))
    if bad is not None:
        k = given[bad[0]]
        raise StepError(
            f"ekf_slam: steps[{k}] at t={steps[k].time}: control {steps[k].control.tolist()} "
            f"for {type(motion_model).__name__}: {bad[1]}"
        )
    if association not in METHODS:
        raise ConfigError(
            f"association method must be one of {', '.join(METHODS)}, got {association!r}"
        )
    require_config("ekf_slam: ", config, SlamConfig)
    require_callable("ekf_slam: ", progress=progress)
    cfg = config or SlamConfig()
    acfg = (
        cfg.association if isinstance(cfg.association, AssociationConfig) else AssociationConfig()
    )
    t_start = time.perf_counter()
    c_start = time.process_time()
    R = cfg.R
    noise = (
        None if cfg.noise_window is None else _MatchedNoise(R, cfg.noise_window, cfg.noise_trigger)
    )
    # the clique's attribute gate checked against the attributes' spread about their landmarks
    attr = None
    if (
        cfg.noise_window is not None
        and acfg.attribute_sigma is not None
        and association in ("clique", "clique-jcbb")
    ):
        attr = _MatchedAttribute(
            acfg.attribute_sigma, cfg.noise_window, cfg.noise_trigger, acfg.gate_probability
        )
    attr_scale = 1.0  # the factor applied to acfg's attribute_sigma
    bias = cfg.control_bias_sigma is not None
    bbias = cfg.bearing_bias_sigma is not None
    # vehicle state [x, y, theta, (beta), (s), (psi)]: beta the bias of the second control,
    # s the relative error of the first (the speed), psi the bias of the sensor's bearings
    prior = list(np.square(cfg.initial_sigma))
    if bias:
        prior.append(cfg.control_bias_sigma**2)
    sscale = cfg.speed_scale_sigma is not None
    i_s = 3 + int(bias)  # index of the speed's scale error, when estimated
    if sscale:
        prior.append(cfg.speed_scale_sigma**2)
    if bbias:
        prior.append(cfg.bearing_bias_sigma**2)
    x0 = np.r_[pose0, np.zeros(len(prior) - 3)]
    f = _Filter(x0, np.diag(prior), confirm_hits=cfg.confirm_hits)
    nv = f.nv
    if bbias:
        f.ib = nv - 1
    sx, sy = motion_model.sensor_x, motion_model.sensor_y
    N = len(steps)
    times, held, dts = held_controls(steps)
    poses = np.empty((N, 3))
    pcovs = np.empty((N, 3, 3))
    obs_steps = [k for k, s in enumerate(steps) if s.n_observations]
    _check_log(steps, motion_model, cfg, held, dts, obs_steps)
    obs_t, assoc_out, assoc_sec, jd2, jdof, amb = [], [], [], [], [], []
    Pvv = f.P[:nv, :nv].copy()
    Fcum = np.eye(nv)
    half_fov = configured_half = 0.5 * cfg.sensor_fov
    # an observation beyond the candidates' window proves the sensor sees there: the
    # field of view widens to the bearings seen (a 360 deg sensor under the 180 deg default
    # otherwise starts a new landmark for every sighting behind the vehicle)
    n_outside = n_bearings = 0
    n_far = n_all_obs = 0  # observations beyond max_range (not used), and all
    far_ranges = []  # a sample of the ranges beyond it, for the warning
    slip = cfg.slip
    kern = None if nv > 3 else motion_model.kernel()
    q_bias = (cfg.control_bias_rate or 0.0) ** 2
    confirm_r = math.inf if cfg.confirm_range is None else cfg.confirm_range
    # a landmark beyond the sensor's range is not expected to be seen, whatever visible_range
    visible_r = min(cfg.visible_range, cfg.max_range or math.inf)
    done = 0  # steps [0, done) predicted
    every = max(1, len(obs_steps) // 200)

    def predict_to(k_end):
        """1. predict the vehicle through steps [done, k_end]."""
        nonlocal done, Pvv, Fcum
        a, b = done, k_end + 1
        if b <= a:
            return
        xv = f.x[:nv].copy()
        if kern is not None:
            from ._kernels import predict_segment

            predict_segment(
                kern[0], kern[1], xv, Pvv, Fcum, dts[a:b], held[a:b], slip, poses, pcovs, a
            )
        elif nv > 3:
            Fa = np.eye(nv)
            Ga = np.zeros((nv, 2))
            for k in range(a, b):
                if dts[k] > 0 and not np.isnan(held[k, 0]):
                    u = held[k] + (0.0, xv[3]) if bias else held[k]
                    if sscale:
                        u = np.array([u[0] * (1.0 + xv[i_s]), u[1]])
                    x_was = xv[:3].copy()
                    xv[:3], F, G = motion_model.predict(xv[:3], u, dts[k])
                    Fa[:3, :3] = F
                    if bias:
                        Fa[:3, 3] = G[:, 1]  # d pose / d beta
                    if sscale:
                        Fa[:3, i_s] = G[:, 0] * held[k, 0]  # d pose / d scale
                    Ga[:3] = G
                    Pvv = Fa @ Pvv @ Fa.T + Ga @ motion_model.control_covariance(u) @ Ga.T
                    if motion_model.moving(held[k]):
                        Pvv[np.diag_indices(3)] += slip_variance(slip, x_was, xv, dts[k])
                    if bias:
                        Pvv[3, 3] += q_bias * dts[k]
                    Fcum = Fa @ Fcum
                poses[k] = xv[:3]
                pcovs[k] = Pvv[:3, :3]
        else:
            for k in range(a, b):
                if dts[k] > 0 and not np.isnan(held[k, 0]):
                    x_was = xv
                    xv, F, G = motion_model.predict(xv, held[k], dts[k])
                    Pvv = F @ Pvv @ F.T + G @ motion_model.control_covariance(held[k]) @ G.T
                    if motion_model.moving(held[k]):
                        Pvv[np.diag_indices(3)] += slip_variance(slip, x_was, xv, dts[k])
                    Fcum = F @ Fcum
                poses[k] = xv
                pcovs[k] = Pvv
        f.x[:nv] = xv
        done = b

    for o_i, s_i in enumerate(obs_steps):
        step = steps[s_i]
        predict_to(s_i)
        z = step.observations
        if len(z):
            att = step.attributes
            n_all = len(z)
            keep = np.arange(n_all)
            if cfg.max_range is not None:
                keep = np.flatnonzero(z[:, 0] <= cfg.max_range)
                if len(keep) < n_all:
                    n_far += n_all - len(keep)
                    if len(far_ranges) < 1000:
                        far_ranges.extend(np.delete(z[:, 0], keep).tolist())
                z = z[keep]
                att = None if att is None else att[keep]
            n_all_obs += n_all
            if len(z):
                b_abs = np.abs(wrap(z[:, 1]))
                n_bearings += len(z)
                n_outside += int(np.count_nonzero(b_abs > configured_half + _FOV_MARGIN))
                if n_outside:
                    half_fov = max(half_fov, float(b_abs.max()))
            # bring the cross-covariance up to date
            d = f.dim
            P = f.P
            if f.n:
                P[:nv, nv:d] = Fcum @ P[:nv, nv:d]
                P[nv:d, :nv] = P[:nv, nv:d].T
            P[:nv, :nv] = Pvv
            Fcum = np.eye(nv)
            a_used = np.full(len(z), REJECTED, np.int64)
            sec = 0.0
            D2, dof, ambiguous = 0.0, 0, False
            if len(z):
                # 2. landmarks the sensor may see
                lm_all = f.x[nv:d].reshape(-1, 2)
                if f.n:
                    zall, _, _ = f.observe(lm_all, sx, sy)
                    lim = (cfg.max_range or np.inf) + 5.0
                    J = np.flatnonzero(
                        (zall[:, 0] <= lim) & (np.abs(zall[:, 1]) <= half_fov + _FOV_MARGIN)
                    )
                else:
                    zall = np.zeros((0, 2))
                    J = np.zeros(0, int)
                idx = np.r_[f.obs_cols, (nv + 2 * J[:, None] + np.arange(2)).reshape(-1)]
                idx = idx.astype(int)
                Psub = P[np.ix_(idx, idx)]  # pose (and bearing bias), selected landmarks
                zJ, Hx, Hm = f.observe(lm_all[J], sx, sy)
                pred = _predicted(
                    zJ,
                    Hx,
                    Hm,
                    Psub,
                    lm_all[J],
                    f.att[J] if att is not None else None,
                    f.permanent()[J],
                )
                if attr is not None and att is not None and len(J) and not attr.settled:
                    scale = attr.add(z, att, zJ, pred.Sz, R, f.att[J], f.hits[J])
                    if scale != attr_scale:
                        attr_scale = scale
                        a0, b0 = attr.sigma
                        acfg = replace(acfg, attribute_sigma=(scale * a0, scale * b0))
                # 3. associate
                a = associate_predicted(z, R, pred, association, acfg, att)
                sec = a.seconds
                D2, dof, ambiguous = a.joint_d2, a.dof, a.ambiguous
                loc = a.landmarks
                paired = np.flatnonzero(loc >= 0)
                glob = J[loc[paired]]
                if noise is not None and len(paired):
                    # the sensor's noise as the innovations of established landmarks say
                    est = pred.established[loc[paired]]
                    R = noise.add(z[paired[est]], zJ, pred.Sz, loc[paired[est]])
                # 4. update with all pairs
                if len(paired):
                    if cfg.tentative_update == "full":
                        _update(f, z[paired], glob, R, sx, sy, cfg.update_iterations)
                    else:
                        # the permanent landmarks' pairs first, then the tentative ones'
                        # (which move only their own landmark)
                        t = ~f.permanent()[glob]
                        for part, own in ((~t, False), (t, True)):
                            if part.any():
                                zz, gg = z[paired][part], glob[part]
                                own_q = np.full(len(gg), own)
                                _update(f, zz, gg, R, sx, sy, cfg.update_iterations, own_q)
                    f.hits[glob] += 1
                    f.near[glob] |= z[paired, 0] <= confirm_r
                    f.misses[glob] = 0
                    if att is not None:
                        f.att[glob] += (att[paired] - f.att[glob]) / np.minimum(f.hits[glob], 20)
                    a_used[paired] = f.ids[glob]
                # tentative landmarks expected in view but unseen
                if len(J):
                    seen = np.zeros(len(J), bool)
                    seen[loc[paired]] = True
                    vis = (zall[J, 0] <= visible_r) & (np.abs(zall[J, 1]) <= half_fov - 0.1)
                    missed = J[vis & ~seen]
                    f.misses[missed] += 1
                # 5. new landmarks
                new = np.flatnonzero(loc == NEW)
                lo, hi = cfg.init_range
                far = (z[new, 0] < lo) | (z[new, 0] > hi)
                a_used[new[far]] = REJECTED
                new = new[~far]
                if len(new):
                    m, Gx, Gz = f.inverse(z[new], sx, sy)
                    for q, i in enumerate(new):
                        lid = f.add(
                            m[q],
                            Gx[q],
                            Gz[q],
                            R,
                            att[i] if att is not None else 0.0,
                            z[i, 0] <= confirm_r,
                        )
                        a_used[i] = NEW
                        _ = lid
                tentative = ~f.permanent()
                drop = np.flatnonzero(
                    tentative
                    & (
                        (f.misses[: f.n] >= cfg.max_misses)
                        | (f.scan - f.born[: f.n] >= cfg.tentative_scans)
                    )
                )
                if len(drop):
                    f.remove(drop)
            Pvv = f.P[:nv, :nv].copy()
            f.scan += 1
            obs_t.append(step.time)
            a_out = np.full(n_all, REJECTED, np.int64)  # beyond max_range: rejected
            a_out[keep] = a_used
            assoc_out.append(_ro(a_out))
            assoc_sec.append(sec)
            jd2.append(D2)
            jdof.append(dof)
            amb.append(ambiguous)
        poses[s_i] = f.x[:3]
        pcovs[s_i] = Pvv[:3, :3]
        if progress is not None and (o_i % every == 0):
            progress(s_i + 1, N)
    predict_to(N - 1)
    if progress is not None:
        progress(N, N)
    if n_outside:
        log.warning(
            "%d of %d observations lay outside the configured field of view (sensor_fov %.0f "
            "deg, and %.0f deg beyond each edge), at bearings up to +-%.0f deg: the filter "
            "widened its field of view to the bearings it saw, so that they pair with the "
            "landmarks there. Give it the sensor's field of view (SlamConfig(sensor_fov=...) "
            "or SlamConfig.for_sensor(fov=...)) to start from it.",
            n_outside,
            n_bearings,
            math.degrees(cfg.sensor_fov),
            math.degrees(_FOV_MARGIN),
            math.degrees(half_fov),
        )
    if n_far > 0.5 * n_all_obs:
        log.warning(
            "%d of %d observations (%.0f %%) lay beyond SlamConfig.max_range (%.4g m), at a "
            "median range of %.4g m: the filter did not use them. Are the ranges in metres "
            "(not millimetres or centimetres)? A sensor that reaches further: give its "
            "range (SlamConfig(max_range=...) or SlamConfig.for_sensor(max_range=...)).",
            n_far,
            n_all_obs,
            100.0 * n_far / n_all_obs,
            cfg.max_range,
            float(np.median(far_ranges)),
        )
    if noise is not None and noise.checks and noise.raised_checks >= 0.5 * noise.checks:
        log.warning(
            "the sensor is noisier than configured: the innovations asked for more noise in "
            "%d of %d checks; the run ended with range sigma %.3g m and bearing sigma %.3g "
            "deg (configured %.3g m, %.3g deg). Give the filter its sensor "
            "(SlamConfig.for_sensor) to start from the right noise.",
            noise.raised_checks,
            noise.checks,
            math.sqrt(R[0, 0]),
            math.degrees(math.sqrt(R[1, 1])),
            cfg.sigma_range,
            math.degrees(cfg.sigma_bearing),
        )
    if attr is not None and attr.scale > 1.0:
        a0, b0 = attr.sigma
        log.warning(
            "the observations' attributes spread %.3g times more about their landmarks' "
            "than AssociationConfig.attribute_sigma (%.3g m + %.3g * range) says, over %d "
            "pairs that only one landmark's gate held: the run widened the clique's "
            "attribute gate by that factor. Are the attributes a tree's diameter in metres? "
            "Give their spread (SlamConfig.for_sensor(..., attribute_sigma=...)), or None to "
            "associate without them.",
            attr.scale,
            a0,
            b0,
            attr.count,
        )
    # the final map: permanent landmarks only
    f.remove(np.flatnonzero(~f.permanent()))
    d = f.dim
    lms = f.x[nv:d].reshape(-1, 2).copy()
    idx = np.arange(f.n)
    lcov = f.P[nv:d, nv:d].reshape(f.n, 2, f.n, 2)[idx, :, idx, :].copy()
    return SlamResult(
        times,
        poses,
        pcovs,
        lms,
        lcov,
        f.ids[: f.n].copy(),
        f.hits[: f.n].copy(),
        np.asarray(obs_t),
        tuple(assoc_out),
        np.asarray(assoc_sec),
        np.asarray(jd2),
        np.asarray(jdof, np.int64),
        np.asarray(amb, bool),
        association,
        time.perf_counter() - t_start,
        cfg,
        time.process_time() - c_start,
        (float(f.x[3]), float(math.sqrt(f.P[3, 3]))) if bias else None,
        (float(f.x[f.ib]), float(math.sqrt(f.P[f.ib, f.ib]))) if bbias else None,
        (float(f.x[i_s]), float(math.sqrt(f.P[i_s, i_s]))) if sscale else None,
        None if noise is None else tuple(float(v) for v in np.sqrt(np.diag(R))),
        noise.raised_checks / noise.checks if noise is not None and noise.checks else math.nan,
        math.nan if attr is None or not attr.checks else attr.scale,
        (n_far, n_all_obs),
    )


class _MatchedAttribute:
    """The clique's attribute gate matched to the attributes' spread (with
    :attr:`SlamConfig.noise_window`).

    The configured spread of an observation's attribute about its landmark's,
    ``sigma(r) = a + b * r`` (:attr:`AssociationConfig.attribute_sigma`, Victoria Park's
    trunk diameters in metres by default), is checked against the pairs that position
    alone decides: an observation inside the individual gate (``probability``) of exactly
    one predicted landmark, that landmark's gate holding no other observation (the gate
    on attributes plays no part, so a gate too narrow to pair anything is still checked).
    Each pair's ``u**2 = (attribute - landmark's)**2 / (sigma(r)**2 * (1 + 1 /
    min(hits, 20)))`` (the landmark's attribute is the running mean of its sightings, at
    most 20 deep) is a chi-square of 1 degree of freedom when the spread is right. When
    the median of all pairs so far exceeds ``trigger`` times 0.455 (its median), the
    gate is widened by ``sqrt(median / 0.455)``, then follows the median, never below
    the configured spread. All pairs so far, not a window: a spread is the detector's, and
    a stationary vehicle's repeated sightings (Victoria Park's stops) would empty a
    window's median. Checked every quarter ``window`` of pairs until ``window``, then
    every quarter of the pairs so far, until ten windows of pairs (2000 by default) have
    settled it: a detector's spread does not change within a run, and the check costs
    about 0.1 ms a scan. Attributes in centimetres widen the gate about a
    hundredfold (Victoria Park, clique: 121.3 / 90.4 m of GPS error start / SE(2) aligned
    and 29 landmarks without the check, 2.00 / 1.52 m and 155 with it; 3.54 / 1.53 m and
    160 in metres; a simulated park's 70 trees: no landmark at all without it, 65 with
    it); an attribute unrelated to the landmark (uniform in [0, 1]) about fourfold
    (70.5 / 30.7 -> 3.39 / 1.55 m). Victoria Park's diameters in metres never trigger it
    (the median is at most 0.63, 0.79 and 1.13 times the right one with 0, 5 and 10
    clutter detections per scan), and a narrower gate is not taken: 0.6 of the configured spread
    loses Victoria Park (12.4 / 7.9 m).
    """

    def __init__(self, sigma, window: int, trigger: float, probability: float):
        self.sigma = (float(sigma[0]), float(sigma[1]))
        self.window, self.trigger = int(window), float(trigger)
        self.gate = chi2_bound(2, probability)
        self.u2 = np.zeros(max(self.window, 1))
        self.count = 0  # pairs seen
        self.fresh = 0  # pairs since the last check
        self.scale = 1.0
        self.checks = 0

    @property
    def settled(self) -> bool:
        """Ten windows of pairs are in: the spread is known (:meth:`add` is not needed)."""
        return self.count >= 10 * self.window

    def add(self, z, att, zhat, Sz, R, latt, hits) -> float:
        """Record the position-decided pairs of observations ``z`` (k, 2) with attributes
        ``att`` (k,) and the predicted landmarks ``zhat`` (n, 2) (joint covariance ``Sz``
        (2n, 2n), sensor noise ``R`` (2, 2)) with attributes ``latt`` (n,) and sightings
        ``hits`` (n,); return the factor on ``attribute_sigma`` to use from now on."""
        Rk = np.broadcast_to(R, (len(z), 2, 2))
        inside = _individual_d2(_innovations(z, zhat), Sz, Rk) <= self.gate
        i = np.flatnonzero(inside.sum(axis=1) == 1)
        j = inside[i].argmax(axis=1)
        mutual = inside[:, j].sum(axis=0) == 1
        i, j = i[mutual], j[mutual]
        m = len(i)
        if m:
            if self.count + m > len(self.u2):
                self.u2 = np.r_[self.u2, np.zeros(len(self.u2) + m)]
            a, b = self.sigma
            s2 = (a + b * z[i, 0]) ** 2 * (1.0 + 1.0 / np.minimum(hits[j], 20))
            self.u2[self.count : self.count + m] = (att[i] - latt[j]) ** 2 / s2
            self.count += m
            self.fresh += m
        if m and 4 * self.fresh >= max(self.window, self.count):
            self.fresh = 0
            self.checks += 1
            ratio = float(np.median(self.u2[: self.count])) / chi2_bound(1, 0.5)
            if ratio > self.trigger or self.scale > 1.0:
                self.scale = max(1.0, math.sqrt(ratio))
        return self.scale


class _MatchedNoise:
    """The sensor noise matched to the filter's innovations (:attr:`SlamConfig.noise_window`).

    A ring of the last ``window`` pairs with established landmarks: each component's
    squared innovation (range, bearing wrapped) and the predicted measurement's variance
    without the sensor (``S_pred``: the vehicle's and the map's part). Every quarter
    window (over the pairs so far until the ring is full), each component's variance is
    set to the ``R`` (found by
    bisection; the median falls as ``R`` grows) at which the median of ``nu**2 / (S_pred
    + R)`` is 0.455, the median of a chi-square of 1 degree of freedom (what a right
    noise gives), never below the configured one; while the noise is the configured one,
    only when that median at the configured ``R`` exceeds ``trigger`` times 0.455. Once
    raised, the noise follows the innovations, down to the configured one: the narrow
    gates of a noise too small cut the innovations' tails, which makes the median read
    low.
    """

    def __init__(self, R, window: int, trigger: float):
        self.R0 = np.diag(np.asarray(R, float)).copy()
        self.R = np.diag(self.R0)
        self.window, self.trigger = int(window), float(trigger)
        self.nu2 = np.zeros((self.window, 2))
        self.spred = np.zeros((self.window, 2))
        self.count = 0  # pairs seen
        self.fresh = 0  # pairs since the last check
        self.raised_checks = 0
        self.checks = 0

    def add(self, z, zhat, Sz, j) -> np.ndarray:
        """Record the pairs of observations ``z`` (m, 2) with predicted landmarks ``j``
        (m,) (their predictions ``zhat[j]``, joint covariance ``Sz`` (2n, 2n)); return
        the noise (2, 2) to use from now on."""
        m = len(j)
        if m:
            nu = np.asarray(z, float) - zhat[j]
            nu[:, 1] = wrap(nu[:, 1])
            slots = (self.count + np.arange(m)) % self.window
            self.nu2[slots] = nu**2
            self.spred[slots, 0] = Sz[2 * j, 2 * j]
            self.spred[slots, 1] = Sz[2 * j + 1, 2 * j + 1]
            self.count += m
            self.fresh += m
        if 4 * self.fresh >= self.window:  # every quarter window, from the first
            self.fresh = 0
            self.checks += 1
            var = np.array([self._matched(c) for c in range(2)])
            self.raised_checks += bool(np.any(var > self.R0))
            self.R = np.diag(var)
        return self.R

    def _matched(self, c: int) -> float:
        k = min(self.count, self.window)  # the pairs so far, until the ring is full
        nu2, sp, r0 = self.nu2[:k, c], self.spred[:k, c], self.R0[c]

        def median_nis(r):
            return float(np.median(nu2 / (sp + r)))

        right = chi2_bound(1, 0.5)  # the median of a chi-square of 1 dof, 0.455
        m0 = median_nis(r0)
        if m0 <= right or (self.R[c, c] <= r0 and m0 <= self.trigger * right):
            return r0
        lo, hi = r0, 2.0 * r0
        while median_nis(hi) > right:
            lo, hi = hi, 2.0 * hi
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if median_nis(mid) > right:
                lo = mid
            else:
                hi = mid
        return hi


def _predicted(zJ, Hx, Hm, Psub, positions, attributes, established) -> Predicted:
    """:class:`Predicted` for the selected landmarks (Psub over [vehicle, m_J]);
    ``established`` their permanent flags."""
    n = len(zJ)
    if n == 0:
        return Predicted(zJ, np.zeros((0, 0)), positions, np.zeros((0, 0)), attributes, established)
    no = Hx.shape[2]  # vehicle states the observation depends on
    Hx2 = Hx.reshape(2 * n, no)
    Pvv = Psub[:no, :no]
    Pvm = Psub[:no, no:]
    Pmm = Psub[no:, no:]

    # block-diagonal Hm applied without forming it: (HmB M)[2j+a] = sum_b Hm[j,a,b] M[2j+b]
    def hm_left(M):  # HmB @ M, M (2n, c)
        Mr = M.reshape(n, 2, M.shape[1])
        return np.einsum("jab,jbc->jac", Hm, Mr).reshape(2 * n, -1)

    A = Hx2 @ hm_left(Pvm.T).T  # Hx Pvm HmB^T
    B = hm_left(hm_left(Pmm).T).T  # HmB Pmm HmB^T
    Sz = Hx2 @ Pvv @ Hx2.T + A + A.T + B
    return Predicted(zJ, Sz, positions, Pmm, attributes, established)


def _update(f: _Filter, z, glob, R, sx, sy, iterations: int = 1, own=None):
    """Batch EKF update with observations ``z`` paired with landmarks ``glob`` (local
    indices), Joseph form expanded: P - K H P - P H^T K^T + K S K^T.

    With ``iterations`` > 1, the iterated EKF (Bell and Cathey 1993): the observation
    model is re-linearised at the updated estimate ``x_i`` and the update recomputed from
    the prior ``x_0``, ``x_{i+1} = x_0 + K_i (z - h(x_i) - H_i (x_0 - x_i))`` (Gauss-Newton
    on the prior and the observations); the covariance uses the last linearisation."""
    d = f.dim
    x, P = f.x, f.P
    nv = f.nv
    m = len(glob)
    cols = np.r_[np.arange(nv), (nv + 2 * glob[:, None] + np.arange(2)).reshape(-1)].astype(int)
    Rm = np.kron(np.eye(m), R)
    x0 = x[:d].copy()
    for it in range(max(1, iterations)):
        lm = x[nv + 2 * glob[:, None] + np.arange(2)]
        zhat, Hx, Hm = f.observe(lm, sx, sy)
        Hs = np.zeros((2 * m, nv + 2 * m))
        Hs[:, f.obs_cols] = Hx.reshape(2 * m, -1)
        for q in range(m):
            Hs[2 * q : 2 * q + 2, nv + 2 * q : nv + 2 + 2 * q] = Hm[q]
        PHt = P[:d, cols] @ Hs.T  # (d, 2m)
        S = Hs @ PHt[cols] + Rm
        S = 0.5 * (S + S.T)
        K = np.linalg.solve(S, PHt.T).T  # (d, 2m)
        if own is not None and own.any():
            # a Schmidt (consider) update: pairs flagged ``own`` move only their own
            # landmark; the Joseph form below stays exact for this suboptimal gain
            for q in np.flatnonzero(own):
                rows = nv + 2 * glob[q] + np.arange(2)
                keep = K[rows, 2 * q : 2 * q + 2].copy()
                K[:, 2 * q : 2 * q + 2] = 0.0
                K[rows, 2 * q : 2 * q + 2] = keep
        nu = z - zhat
        nu[:, 1] = wrap(nu[:, 1])
        nu = nu.reshape(-1)
        if it:
            dx = x0[cols] - x[cols]
            dx[2] = wrap(dx[2])
            nu = nu - Hs @ dx
        x[:d] = x0 + K @ nu
        x[2] = wrap(x[2])
    # K S K^T - K PHt^T - PHt K^T = K M^T + M K^T with M = 0.5 K S - PHt
    from ._kernels import sym_update

    Mt = 0.5 * (K @ S) - PHt
    sym_update(P, d, np.ascontiguousarray(K), np.ascontiguousarray(Mt))
