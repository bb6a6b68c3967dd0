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
import math

import numpy as np
import pytest

import scanclique as sc
from scanclique.config import (
    MAX_ITERATIONS,
    MAX_QUICK_EXACT,
    MAX_REFINE_CANDIDATES,
    MAX_SEARCH_BINS,
    MAX_SEARCH_SEEDS,
    MAX_SIGMA_METRES,
    FeatureConfig,
    MatchConfig,
    RefineConfig,
    ValidationConfig,
)
from scanclique.errors import ConfigError
from scanclique.io.config import loads_config
from scanclique.mapping import MapConfig
from scanclique.mapping.config import (
    MAX_SIGMA_FLOOR_RADIANS,
    BackEndConfig,
    FrontEndConfig,
    LoopConfig,
)
from scanclique.scan import MAX_SWEEP, Scan, retime

INF = math.inf


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


# -- findings 2 and 3: numbers beyond what a run can use ------------------------------------
BEYOND = [
    (FrontEndConfig, "sigma_floor_metres", 1e200),  # OverflowError squaring it
    (FrontEndConfig, "sigma_floor_radians", 1e200),
    (FrontEndConfig, "sigma_floor_metres", 2**32),  # an int: object arrays of its square
    (FrontEndConfig, "refine_iterations", 2**62),  # ran without end
    (BackEndConfig, "max_iterations", 2**40),  # GTSAM's 32-bit count: a TypeError
    (FeatureConfig, "range_sigma", 1e200),  # LinAlgError
    (RefineConfig, "search_bins", 2**40),  # MemoryError
    (RefineConfig, "search_bins", 2**62),  # array too big
    (RefineConfig, "search_peaks", 2**62),
    (RefineConfig, "search_top", 2**62),
    (RefineConfig, "quick_exact", 2**62),  # OverflowError in the kernel
    (RefineConfig, "candidates", 2**62),  # its product with quick_exact overflowed
    (RefineConfig, "iterations", 2**62),  # ran without end
]


@pytest.mark.parametrize(
    "cls, name, value", BEYOND, ids=[f"{c.__name__}.{n}={v!r}" for c, n, v in BEYOND]
)
def test_numbers_beyond_their_documented_bound_are_refused_when_built(cls, name, value):
    with pytest.raises(ConfigError, match=rf"{cls.__name__}\.{name} must be at most"):
        cls(**{name: value})


AT_BOUND = [
    (FrontEndConfig, "sigma_floor_metres", MAX_SIGMA_METRES),
    (FrontEndConfig, "sigma_floor_radians", MAX_SIGMA_FLOOR_RADIANS),
    (FrontEndConfig, "refine_iterations", MAX_ITERATIONS),
    (BackEndConfig, "max_iterations", MAX_ITERATIONS),
    (FeatureConfig, "range_sigma", MAX_SIGMA_METRES),
    (RefineConfig, "iterations", MAX_ITERATIONS),
    (RefineConfig, "search_bins", MAX_SEARCH_BINS),
    (RefineConfig, "search_peaks", MAX_SEARCH_SEEDS),
    (RefineConfig, "search_top", MAX_SEARCH_SEEDS),
    (RefineConfig, "quick_exact", MAX_QUICK_EXACT),
    (RefineConfig, "candidates", MAX_REFINE_CANDIDATES),
]


@pytest.mark.parametrize(
    "cls, name, value", AT_BOUND, ids=[f"{c.__name__}.{n}" for c, n, _ in AT_BOUND]
)
def test_the_bounds_lie_far_above_the_defaults_and_are_accepted(cls, name, value):
    assert getattr(cls(), name) * 10 <= value
    assert getattr(cls(**{name: value}), name) == value


def test_the_bounds_are_named_in_a_toml_file_too():
    with pytest.raises(ConfigError, match="BackEndConfig.max_iterations"):
        loads_config("[back_end]\nmax_iterations = 1099511627776\n", base=MapConfig())
    with pytest.raises(ConfigError, match="RefineConfig.search_bins"):
        loads_config("[refine]\nsearch_bins = 4611686018427387904\n")


def test_a_map_at_the_sigma_floors_bounds_is_made():
    scans = sc.sim.simulate_trajectory(
        np.random.default_rng(2), sc.sim.office_world(np.random.default_rng(1)), 6, n_beams=91
    )
    fe = FrontEndConfig(sigma_floor_metres=1000, sigma_floor_radians=MAX_SIGMA_FLOOR_RADIANS)
    match = MatchConfig(features=FeatureConfig(range_sigma=MAX_SIGMA_METRES))
    result = sc.map_scans(scans, config=MapConfig(match=match, front_end=fe))
    assert np.all(np.isfinite([p.as_array() for p in result.poses]))


def test_ints_given_for_float_fields_are_kept_as_floats():
    fe = FrontEndConfig(sigma_floor_metres=2, icp_min_score=1)
    assert type(fe.sigma_floor_metres) is float and fe.sigma_floor_metres == 2.0
    assert type(fe.icp_min_score) is float
    assert type(FeatureConfig(range_sigma=1).range_sigma) is float
    assert type(RefineConfig(min_score=0).min_score) is float
    assert type(RefineConfig(iterations=3).iterations) is int  # int fields stay ints
    assert np.asarray([fe.sigma_floor_metres**2]).dtype == np.float64


# -- finding 10: score floors of +inf, refused as RefineConfig.min_score is ------------------
FLOORS = [
    (RefineConfig, "min_score"),
    (FrontEndConfig, "scan_min_score"),
    (FrontEndConfig, "icp_min_score"),
    (LoopConfig, "min_score"),
    (ValidationConfig, "rival_min_score"),
]


@pytest.mark.parametrize("cls, name", FLOORS, ids=[f"{c.__name__}.{n}" for c, n in FLOORS])
def test_a_score_floor_of_inf_is_refused_and_minus_inf_means_none(cls, name):
    with pytest.raises(ConfigError, match=rf"{cls.__name__}\.{name} must be below inf"):
        cls(**{name: INF})
    assert getattr(cls(**{name: -INF}), name) == -INF
