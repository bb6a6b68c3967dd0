"""The stable contracts other tools call, as the issues state them: names, parameters
(their order, kind and defaults) and the meaning of the results. A change that breaks
one of these breaks a caller; this file says which and why.

- issue 2: ``read_scans(path) -> list[Scan]``, ``match_scans(a, b, config=None) ->
  ScanMatch`` whose ``.pose`` (``x``, ``y``, ``theta``) maps points of b into a's frame;
- issue 12: ``map_scans(scans, *, use_odometry=None, config=None, progress=None) ->
  MapResult``, ``MapResult.poses`` one per scan in the frame of scan 0;
- issue 13: ``slam.ekf_slam(steps, motion_model, *, association=..., config=None,
  progress=None)``, ``slam.Step(time, control, observations, attributes)``,
  ``slam.Ackermann(wheelbase=, encoder_offset=, laser_a=, laser_b=)``, ``slam.Unicycle``
  (controls ``(v, omega)``), ``slam.associate(z, R, map_mean, map_cov, pose, pose_cov,
  method="clique")``, ``slam.read_victoria_park(path)``;
- issue 14: ``places.PlaceDB(path)``, ``.add(scan, name=None) -> int``, ``.query(scan,
  k=5) -> list[PlaceHit]`` with ``place_id``, ``name``, ``pose``, ``score``, ``verdict``.

Parameters beyond these may be added (keyword-only, with defaults); these may not move.
"""

from __future__ import annotations

import dataclasses
import inspect
import math

import numpy as np

import scanclique as sc
from scanclique import slam
from scanclique.geometry import Pose2

P = inspect.Parameter
POS = (P.POSITIONAL_ONLY, P.POSITIONAL_OR_KEYWORD)
NONE = object()  # "no default"


def _check(fn, positional=(), keyword=()):
    """``positional``: (name, default) pairs that must open the signature in this order,
    each callable by position; ``keyword``: (name, default) pairs that must be accepted
    by keyword. Every parameter after them must have a default."""
    params = list(inspect.signature(fn).parameters.values())
    if params and params[0].name == "self":
        params = params[1:]
    for (name, default), p in zip(positional, params, strict=False):
        assert p.name == name and p.kind in POS, f"{fn.__qualname__}: {p} for {name}"
        want = P.empty if default is NONE else default
        assert p.default == want, f"{fn.__qualname__}: {name}'s default is {p.default!r}"
    assert len(params) >= len(positional), f"{fn.__qualname__}: too few parameters"
    by_name = {p.name: p for p in params}
    for name, default in keyword:
        assert name in by_name, f"{fn.__qualname__} has no parameter {name!r}"
        p = by_name[name]
        assert p.kind != P.POSITIONAL_ONLY, f"{fn.__qualname__}: {name} is positional-only"
        assert p.default == default, f"{fn.__qualname__}: {name}'s default is {p.default!r}"
    named = {n for n, _ in positional} | {n for n, _ in keyword}
    for p in params:
        if p.name not in named and p.kind not in (P.VAR_POSITIONAL, P.VAR_KEYWORD):
            assert p.default is not P.empty, f"{fn.__qualname__}: new {p.name} has no default"


def _fields(record):
    return [f.name for f in dataclasses.fields(record)]


def test_core_signatures():
    _check(sc.read_scans, [("path", NONE)])
    _check(sc.match_scans, [("a", NONE), ("b", NONE), ("config", None)])


def test_application_signatures():
    _check(
        sc.map_scans,
        [("scans", NONE)],
        [("use_odometry", None), ("config", None), ("progress", None)],
    )
    _check(
        slam.ekf_slam,
        [("steps", NONE), ("motion_model", NONE)],
        [("association", "clique"), ("config", None), ("progress", None)],
    )
    _check(
        slam.associate,
        [(n, NONE) for n in ("z", "R", "map_mean", "map_cov", "pose", "pose_cov")]
        + [("method", "clique")],
    )
    _check(slam.read_victoria_park, [("source", "victoria-park")])
    _check(sc.places.PlaceDB, [("path", NONE)])
    _check(sc.places.PlaceDB.add, [("scan", NONE), ("name", None)])
    _check(sc.places.PlaceDB.query, [("scan", NONE), ("k", 5)])


def test_records_keep_their_fields():
    assert _fields(slam.Step)[:4] == ["time", "control", "observations", "attributes"]
    assert _fields(sc.places.PlaceHit)[:5] == ["place_id", "name", "pose", "score", "verdict"]
    r = set(_fields(slam.SlamResult))
    assert {"times", "poses", "landmarks", "landmark_covariances", "associations"} <= r
    m = set(_fields(sc.MapResult))
    assert {"poses", "loop_closures", "edges", "seconds"} <= m
    model = slam.Ackermann(wheelbase=2.83, encoder_offset=0.76, laser_a=3.78, laser_b=0.5)
    assert (model.wheelbase, model.encoder_offset, model.laser_a, model.laser_b) == (
        2.83, 0.76, 3.78, 0.5,
    )  # fmt: skip
    assert isinstance(slam.Unicycle(), slam.MotionModel)


def test_match_scans_pose_maps_b_into_a():
    pair = sc.sim.simulate_pair(np.random.default_rng(3))
    a, b = pair.scan_a, pair.scan_b
    m = sc.match_scans(a, b)
    truth = pair.pose_a_b
    assert isinstance(m.pose, Pose2)
    t, r = m.pose.distance_to(truth)
    assert t < 0.05 and r < math.radians(1)
    # R(theta) p_b + (x, y): the points of b in a's frame
    pts = b.points()[:5]
    c, s = math.cos(m.pose.theta), math.sin(m.pose.theta)
    want = pts @ np.array([[c, s], [-s, c]]) + (m.pose.x, m.pose.y)
    np.testing.assert_allclose(m.pose.transform(pts), want)
    # no pose: None, and the result says why
    empty = sc.Scan([np.nan] * 5, np.linspace(-1, 1, 5))
    none = sc.match_scans(empty, b)
    assert none.pose is None and none.reason


def test_application_results_mean_what_they_say(tmp_path):
    from conftest import circle_drive

    scans = circle_drive(np.random.default_rng(0), laps=1, n_per_lap=12)
    r = sc.map_scans(scans)
    assert len(r.poses) == len(scans) and all(isinstance(p, Pose2) for p in r.poses)
    assert max(r.poses[0].distance_to(Pose2.identity())) < 1e-9  # the frame of scan 0
    truth = scans[0].reference.inverse() @ scans[6].reference
    assert r.poses[6].distance_to(truth)[0] < 0.1

    from scanclique.slam.sim import simulate_room

    run = simulate_room(seed=0, duration=20.0)
    res = slam.ekf_slam(run.steps, slam.Unicycle(), association="clique")
    n_obs = sum(len(s.observations) > 0 for s in run.steps)
    assert res.poses.shape == (len(res.times), 3) and len(res.associations) == n_obs
    assert res.landmarks.shape[1:] == (2,) and res.landmark_covariances.shape[1:] == (2, 2)

    with sc.places.PlaceDB(tmp_path / "p.db") as db:
        pid = db.add(scans[0], name="start")
        assert isinstance(pid, int)
        hits = db.query(scans[1], k=5)
    assert isinstance(hits, list) and hits[0].place_id == pid and hits[0].name == "start"
    assert hits[0].verdict in (sc.places.ACCEPTED, sc.places.AMBIGUOUS, sc.places.REJECTED)
    if hits[0].pose is not None:  # the query's frame in the place's
        truth = scans[0].reference.inverse() @ scans[1].reference
        assert hits[0].pose.distance_to(truth)[0] < 0.1
