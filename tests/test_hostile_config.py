"""Fuzzing findings: configuration numbers the records accepted but a run could not use,
and beam times a timing candidate moved beyond a sweep.

A number that would overflow a square, an array size, a solver's integer count or run
without end is a :class:`~scanclique.errors.ConfigError` naming the record and the field
when the record is built; each bound is documented on its field and lies far above the
defaults. Ints given for float fields are kept as floats. A reading of the beam times
(:func:`scanclique.scan.retime`) that would put a beam beyond
:data:`~scanclique.scan.MAX_SWEEP` is no possible reading of the scan.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scanclique as sc
from scanclique.scan import MAX_SWEEP, Scan, retime


# -- finding 1: retime's candidates beyond MAX_SWEEP ----------------------------------------
def test_a_timing_that_would_move_a_beam_beyond_the_sweep_reads_as_its_direction_does():
    late = Scan(np.ones(4), np.linspace(0.0, 0.3, 4), beam_times=np.linspace(-0.9, 0.0, 4))
    # shifted (t - T) would put the first beam 1.8 s before the stamp: read as given
    assert retime(late, "shifted").beam_times.tolist() == late.beam_times.tolist()
    # reversed (T - t) would put it 1.8 s after: read as negated
    reversed_ = retime(late, "reversed").beam_times
    assert reversed_.tolist() == retime(late, "negated").beam_times.tolist()
    assert float(np.max(np.abs(reversed_))) <= MAX_SWEEP


def test_a_possible_timing_is_read_as_before():
    s = Scan(np.ones(3), [0.0, 0.1, 0.2], beam_times=[0.0, 0.4, 0.8])
    assert retime(s, "shifted").beam_times.tolist() == pytest.approx([-0.8, -0.4, 0.0])
    assert retime(s, "reversed").beam_times.tolist() == pytest.approx([0.8, 0.4, 0.0])
    mid = Scan(np.ones(3), [0.0, 0.1, 0.2], beam_times=[-0.2, 0.0, 0.2])
    assert retime(mid, "shifted").beam_times.tolist() == pytest.approx([-0.6, -0.4, -0.2])


def test_map_scans_takes_beam_times_measured_before_the_stamp():
    world = sc.sim.office_world(np.random.default_rng(1))
    base = sc.sim.simulate_trajectory(np.random.default_rng(2), world, 12, n_beams=181)
    scans = [dataclasses.replace(s, beam_times=np.linspace(-0.9, 0.0, s.n_beams)) for s in base]
    result = sc.map_scans(scans, use_odometry=False)  # a ScanError (1.8 s) before
    assert len(result.poses) == len(scans)
