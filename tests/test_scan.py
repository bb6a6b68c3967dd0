"""The Scan record: validity masking, read-only ranges, shape checks, beam convention."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scanclique.errors import ScanError
from scanclique.geometry import Pose2
from scanclique.scan import Scan, beam_angles


def scan_of(ranges, **kw):
    r = np.asarray(ranges, dtype=float)
    return Scan(r, np.linspace(-1.0, 1.0, r.size), **kw)


# -- validity ------------------------------------------------------------------------------
def test_valid_mask_known_answer():
    ranges = [1.0, np.nan, np.inf, -np.inf, -1.0, 0.0, 0.5, 0.50001, 9.99, 10.0, 12.0, 3.0]
    s = scan_of(ranges, range_min=0.5, range_max=10.0)
    expected = [True, False, False, False, False, False, False, True, True, False, False, True]
    assert s.valid.tolist() == expected
    assert s.n_valid == 4
    assert s.n_beams == 12


def test_ranges_kept_unaltered():
    ranges = np.array([1.0, np.nan, np.inf, -2.0, 80.0, 100.0])
    s = scan_of(ranges)
    np.testing.assert_array_equal(s.ranges, ranges)  # NaN == NaN for assert_array_equal
    assert s.ranges.dtype == np.float64


def test_arrays_are_read_only_copies():
    ranges = np.array([1.0, 2.0, 3.0])
    angles = np.array([-0.1, 0.0, 0.1])
    s = Scan(ranges, angles)
    ranges[0] = 99.0  # caller's array changes; the scan's does not
    angles[0] = -5.0
    assert s.ranges[0] == 1.0
    assert s.angles[0] == -0.1
    for a in (s.ranges, s.angles, s.valid):
        with pytest.raises(ValueError):
            a[0] = 0


def test_defaults():
    s = scan_of([1.0, 2.0])
    assert s.range_min == 0.0 and s.range_max == 80.0
    assert s.timestamp is None and s.odometry is None and s.reference is None


def test_zero_beams_is_fine():
    s = Scan(np.zeros(0), np.zeros(0))
    assert s.n_beams == 0 and s.n_valid == 0
    assert s.points().shape == (0, 2)
    assert s.xy().shape == (0, 2)


def test_single_beam_is_fine():
    s = Scan([2.0], [0.3])
    np.testing.assert_allclose(s.points(), [[2 * math.cos(0.3), 2 * math.sin(0.3)]])


# -- errors --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("ranges", "angles"),
    [
        (np.zeros(3), np.zeros(4)),  # sizes differ
        (np.zeros((2, 2)), np.zeros(4)),  # not 1-D
        (np.zeros(3), np.zeros((3, 1))),
        (["a", "b"], [0.0, 1.0]),  # not numeric
    ],
)
def test_shape_errors(ranges, angles):
    with pytest.raises(ScanError):
        Scan(ranges, angles)


@pytest.mark.parametrize(
    "angles",
    [[0.0, 0.0, 0.1], [0.0, 0.2, 0.1], [0.3, 0.2, 0.1], [0.0, np.nan, 0.2], [0.0, 0.1, np.inf]],
)
def test_angles_must_increase_and_be_finite(angles):
    with pytest.raises(ScanError):
        Scan([1.0, 1.0, 1.0], angles)


@pytest.mark.parametrize(
    ("rmin", "rmax"),
    [(-0.1, 10.0), (5.0, 5.0), (6.0, 5.0), (np.nan, 5.0), (0.0, np.nan)],
)
def test_range_limits_checked(rmin, rmax):
    with pytest.raises(ScanError):
        scan_of([1.0, 2.0], range_min=rmin, range_max=rmax)


@pytest.mark.parametrize("field", ["odometry", "reference"])
def test_pose_fields_must_be_pose2(field):
    with pytest.raises(ScanError):
        scan_of([1.0], **{field: (0.0, 0.0, 0.0)})
    s = scan_of([1.0], **{field: Pose2(1.0, 2.0, 0.0)})
    assert getattr(s, field) == Pose2(1.0, 2.0, 0.0)


@pytest.mark.parametrize("t", [np.nan, np.inf])
def test_timestamp_must_be_finite(t):
    with pytest.raises(ScanError):
        scan_of([1.0], timestamp=t)


def test_error_message_names_source():
    with pytest.raises(ScanError, match="mylog:7"):
        Scan([1.0, 2.0], [0.0], source="mylog:7")


# -- beams and points ----------------------------------------------------------------------
def test_beam_angles():
    np.testing.assert_allclose(beam_angles(3, -1.0, 0.5), [-1.0, -0.5, 0.0])
    assert beam_angles(0, 0.0, 1.0).shape == (0,)


@pytest.mark.parametrize("n", [181, 361])
def test_from_ranges_carmen_convention(n):
    s = Scan.from_ranges(np.ones(n))
    assert s.angles[0] == pytest.approx(-math.pi / 2)
    assert s.angles[-1] == pytest.approx(math.pi / 2)
    assert s.angles[(n - 1) // 2] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(np.diff(s.angles), math.pi / (n - 1))


def test_from_ranges_explicit_increment_and_kwargs():
    s = Scan.from_ranges(
        [1.0, 2.0, 3.0], angle_min=0.0, angle_increment=0.1, range_max=2.5, timestamp=4.0
    )
    np.testing.assert_allclose(s.angles, [0.0, 0.1, 0.2])
    assert s.valid.tolist() == [True, True, False]
    assert s.timestamp == 4.0


def test_from_ranges_fov():
    s = Scan.from_ranges(np.ones(5), angle_min=-1.0, fov=2.0)
    np.testing.assert_allclose(s.angles, [-1.0, -0.5, 0.0, 0.5, 1.0])


def test_points_and_xy_known_answer():
    # beams at -90, 0, +90 degrees: right, forward, left
    s = Scan.from_ranges(
        [1.0, np.nan, 3.0, 100.0, 2.0], angle_min=-math.pi / 2, fov=math.pi, range_max=50.0
    )
    # angles: -90, -45, 0, 45, 90 degrees
    pts = s.points()
    np.testing.assert_allclose(pts, [[0.0, -1.0], [3.0, 0.0], [0.0, 2.0]], atol=1e-12)
    xy = s.xy()
    assert xy.shape == (5, 2)
    assert np.isnan(xy[1]).all() and np.isnan(xy[3]).all()
    np.testing.assert_allclose(xy[[0, 2, 4]], pts, atol=1e-12)
    # the points lie at the measured ranges
    np.testing.assert_allclose(np.hypot(pts[:, 0], pts[:, 1]), [1.0, 3.0, 2.0])
