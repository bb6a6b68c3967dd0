"""Loop-candidate verification on local processes (scanclique.mapping.parallel, issue 12
part 7): the map with ``workers=2`` or ``3`` is the serial map, closure for closure, pose
for pose."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scanclique.errors import ScanCliqueError
from scanclique.geometry import Pose2
from scanclique.mapping import map_scans
from scanclique.sim import room_world, simulate_scan


def _two_laps(rng, n_per_lap=30):
    """Two laps of a 1.5 m circle in a room with drifting odometry: the second lap closes
    loops with the first."""
    world = room_world(8.0, 7.0, rng=rng, pillars=0, clutter=6)
    scans, odo, prev = [], Pose2.identity(), None
    for k in range(2 * n_per_lap):
        a = 2 * math.pi * k / n_per_lap
        ref = Pose2(4.0 + 1.5 * math.cos(a), 3.5 + 1.5 * math.sin(a), a + math.pi / 2)
        if prev is not None:
            u = prev.inverse() @ ref
            odo = odo @ Pose2(u.x * 1.03, u.y + 0.01, u.theta * 1.04 + 0.003)
        prev = ref
        scans.append(simulate_scan(world, ref, rng=rng, timestamp=0.2 * k, odometry=odo))
    return scans


def _closure_key(c):
    p = None if c.pose is None else tuple(c.pose.as_array().tolist())
    return (c.i, c.j, c.verdict, c.accepted, c.local, c.source, c.score, p)


@pytest.mark.parametrize("workers", [2, 3])  # one forked worker; two, finishing out of order
def test_workers_give_the_serial_map(workers):
    scans = _two_laps(np.random.default_rng(5))
    serial = map_scans(scans)
    parallel = map_scans(scans, workers=workers)
    assert len(serial.accepted_closures) >= 3  # the test has closures to agree on
    assert [_closure_key(c) for c in serial.loop_closures] == [
        _closure_key(c) for c in parallel.loop_closures
    ]
    a = np.array([p.as_array() for p in serial.poses])
    b = np.array([p.as_array() for p in parallel.poses])
    np.testing.assert_array_equal(a, b)
    assert serial.keyframes == parallel.keyframes
    assert [(e.i, e.j, e.kind) for e in serial.edges] == [
        (e.i, e.j, e.kind) for e in parallel.edges
    ]


@pytest.mark.parametrize("bad", [0, -1, 1.5, True])
def test_workers_must_be_a_positive_integer(bad):
    scans = _two_laps(np.random.default_rng(1), n_per_lap=6)[:3]
    with pytest.raises(ScanCliqueError, match="workers"):
        map_scans(scans, workers=bad)
