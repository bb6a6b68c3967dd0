"""Hostile arguments to the simulator (found by fuzzing): each is a named ConfigError at
once, not a raw NumPy error, a silently wrong world or a run of minutes."""

import math

import numpy as np
import pytest

from scanclique import sim
from scanclique.errors import ConfigError


def rng():
    return np.random.default_rng(0)


@pytest.fixture(scope="module")
def room():
    return sim.room_world(4.0, 4.0, rng=rng(), doorways=0, pillars=0, clutter=0)


# -- n_scans = 0 ---------------------------------------------------------------------


def test_a_drive_of_no_scans_is_refused(room):
    with pytest.raises(ConfigError, match="n_scans must be >= 1"):
        sim.simulate_trajectory(rng(), room, 0)
    with pytest.raises(ConfigError, match="n_steps must be >= 1"):
        sim.simulate_sensor_drive(rng(), room, 0)


# -- unvalidated arguments -----------------------------------------------------------


@pytest.mark.parametrize("origin", [(math.nan, 0.0), "ab", (1e300, 0.0), (1.0,), None])
def test_room_world_refuses_a_bad_origin(origin):
    with pytest.raises(ConfigError, match="origin"):
        sim.room_world(5.0, 5.0, rng=rng(), origin=origin)


def test_room_world_refuses_a_room_too_small_to_have_walls():
    with pytest.raises(ConfigError, match="width"):
        sim.room_world(1e-9, 1e-9, rng=rng())


def test_office_world_refuses_an_endless_corridor():
    with pytest.raises(ConfigError, match="length"):
        sim.office_world(rng(), length=1e300)


@pytest.mark.parametrize("blocks", [("a", 2), 3, (2.5, 2), (2, 2, 2), (True, 2)])
def test_campus_world_refuses_blocks_that_are_not_two_integers(blocks):
    with pytest.raises(ConfigError, match="blocks"):
        sim.campus_world(rng(), blocks=blocks)


def test_cast_rays_refuses_a_bad_origin_angle_or_range(room):
    with pytest.raises(ConfigError, match="origin"):
        sim.cast_rays(room, (0.0,), [0.0])
    with pytest.raises(ConfigError, match="finite"):
        sim.cast_rays(room, (math.nan, 1.0), [0.0])
    with pytest.raises(ConfigError, match="finite"):
        sim.cast_rays(room, (1.0, 1.0), [math.nan])
    for bad in (-1.0, math.nan, 0.0):
        with pytest.raises(ConfigError, match="max_range"):
            sim.cast_rays(room, (1.0, 1.0), [0.0], max_range=bad)
    assert sim.cast_rays(room, (1.0, 2.0), [0.0], max_range=np.inf).tolist() == [3.0]


def test_is_free_refuses_a_negative_clearance(room):
    with pytest.raises(ConfigError, match="clearance"):
        room.is_free([[2.0, 2.0]], clearance=-1.0)


# -- counts and sizes with no bound --------------------------------------------------


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: sim.room_world(5, 5, rng=rng(), pillars=10**6), "pillars"),
        (lambda: sim.room_world(5, 5, rng=rng(), clutter=10**5), "clutter"),
        (lambda: sim.room_world(5, 5, rng=rng(), doorways=10**6), "doorways"),
        (lambda: sim.corridor_world(20, 3, rng=rng(), doorways=10**6), "doorways"),
        (lambda: sim.office_world(rng(), pillars=10**6), "pillars"),
        (lambda: sim.ring_world(rng(), door_every=1e-6), "door_every"),
        (lambda: sim.campus_world(rng(), blocks=(1000, 1000)), "blocks"),
        (lambda: sim.campus_world(rng(), tree_spacing=1e-6), "tree_spacing"),
        (lambda: sim.campus_world(rng(), street=1e6), "street"),
    ],
)
def test_world_builders_bound_what_they_make(call, name):
    with pytest.raises(ConfigError, match=name):
        call()


def test_corridor_doorways_that_do_not_fit_are_refused_as_side_rooms_are():
    with pytest.raises(ConfigError, match="do not fit"):
        sim.corridor_world(20, 3, rng=rng(), doorways=60)


def test_simulators_bound_beams_people_and_scans(room):
    with pytest.raises(ConfigError, match="n_beams"):
        sim.simulate_scan(room, sim.Pose2(2.0, 2.0, 0.0), n_beams=10**7)
    with pytest.raises(ConfigError, match="moving_people"):
        sim.simulate_pair(rng(), world=room, moving_people=10**5)
    with pytest.raises(ConfigError, match="n_scans"):
        sim.simulate_trajectory(rng(), room, 10**9)
    with pytest.raises(ConfigError, match="scan_rate"):
        sim.simulate_sensor_drive(rng(), room, 3, 0.25, n_beams=31, scan_rate=1e6)
    for kw in ({"speed": 1e-9}, {"turn_rate": 1e-9}, {"scan_rate": 1e3, "speed": 1e-3}):
        with pytest.raises(ConfigError, match="more than"):
            sim.simulate_sensor_drive(rng(), room, 3, 0.25, n_beams=31, **kw)
    for kw in ({"loops": 1e6}, {"step": 1e-6}):
        with pytest.raises(ConfigError, match="scans"):
            sim.simulate_ring_drive(rng(), n_beams=31, **kw)
