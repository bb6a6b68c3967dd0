"""Loop-candidate verification on local processes (scanclique.mapping.parallel, issue 12
part 7): the map with ``workers=2`` or ``3`` is the serial map, closure for closure, pose
for pose."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import circle_drive

from scanclique.errors import ScanCliqueError
from scanclique.mapping import map_scans


def _closure_key(c):
    p = None if c.pose is None else tuple(c.pose.as_array().tolist())
    return (c.i, c.j, c.verdict, c.accepted, c.local, c.source, c.score, p)


@pytest.mark.parametrize("workers", [2, 3])  # one forked worker; two, finishing out of order
def test_workers_give_the_serial_map(workers):
    scans = circle_drive(np.random.default_rng(5), n_per_lap=30)
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
    scans = circle_drive(np.random.default_rng(1), n_per_lap=6)[:3]
    with pytest.raises(ScanCliqueError, match="workers"):
        map_scans(scans, workers=bad)
