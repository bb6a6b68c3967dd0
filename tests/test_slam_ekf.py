"""EKF-SLAM end to end on the simulated tree park; the update against a dense reference;
outputs and the ``scanclique slam`` command on a small simulated data directory."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from scanclique import slam
from scanclique.slam import ekf as E
from scanclique.slam.metrics import align_se2, duplicate_pairs, gps_error, gps_outliers, nees
from scanclique.slam.models import inverse_observe, observe
from scanclique.slam.sim import simulate_park

#: The slip these tests were written for: per second while moving (the defaults before
#: session 22), the same in the simulated truth and the filter.
SLIP = dict(
    sigma_xy_rate=0.05, sigma_theta_rate=math.radians(0.5), sigma_xy_distance=0.0,
    sigma_theta_distance=0.0, sigma_theta_turn=0.0,
)  # fmt: skip
CFG = slam.SlamConfig(max_range=20.0, **SLIP)


@pytest.fixture(scope="module")
def park():
    return simulate_park(1, laps=1, length=50.0, width=30.0, n_trees=70, config=CFG)


@pytest.mark.parametrize("method", slam.METHODS)
def test_simulated_park_end_to_end(park, method):
    r = slam.ekf_slam(park.steps, slam.Ackermann(), association=method, config=CFG)
    assert r.poses.shape == (len(park.steps), 3)
    e = r.poses - park.poses
    e[:, 2] = slam.wrap(e[:, 2])
    assert np.sqrt(np.mean(np.sum(e[:, :2] ** 2, 1))) < 1.5
    # every landmark is one tree: the map's landmarks lie near distinct trees
    d = np.hypot(*(r.landmarks[:, None, :] - park.trees[None]).transpose(2, 0, 1))
    near = d.argmin(1)
    assert np.median(d.min(1)) < 1.0
    assert len(set(near.tolist())) >= 0.95 * len(near)
    # associations agree with the truth for nearly every pair
    votes = {}
    for a, tr in zip(r.associations, park.truth, strict=False):
        for lid, tree in zip(a.tolist(), tr.tolist(), strict=False):
            if lid >= 0:
                votes.setdefault(lid, []).append(tree)
    agree = sum(max(v.count(t) for t in set(v)) for v in votes.values())
    total = sum(len(v) for v in votes.values())
    assert agree / total > 0.98
    # the joint distance of each step passes its own gate (the validation record); NN
    # gates pairs one by one only, so its joint distance passes on nearly every step
    from scanclique.slam.association import chi2_bound

    passed = [
        d2 <= chi2_bound(int(dof), CFG.association.gate_probability) + 1e-9
        for d2, dof in zip(r.joint_d2, r.dof, strict=False)
        if dof
    ]
    assert np.mean(passed) >= (0.98 if method == "nn" else 1.0)
    assert np.all(np.linalg.eigvalsh(r.pose_covariances[-1]) > 0)


def test_nees_is_plausible(park):
    r = slam.ekf_slam(park.steps, slam.Ackermann(), association="jcbb", config=CFG)
    e = r.poses - park.poses
    e[:, 2] = slam.wrap(e[:, 2])
    n = nees(e[200:], r.pose_covariances[200:])
    assert 0.3 < n.mean() < 12.0


def _dense_update(x, P, z, glob, R, sx, sy):
    """Textbook EKF update with the full H and the Joseph form (slow reference)."""
    d = len(x)
    m = len(glob)
    H = np.zeros((2 * m, d))
    lm = np.array([x[3 + 2 * g : 5 + 2 * g] for g in glob])
    zhat, Hx, Hm = observe(x[:3], lm, sx, sy)
    for q, g in enumerate(glob):
        H[2 * q : 2 * q + 2, :3] = Hx[q]
        H[2 * q : 2 * q + 2, 3 + 2 * g : 5 + 2 * g] = Hm[q]
    Rb = np.kron(np.eye(m), R)
    S = H @ P @ H.T + Rb
    K = P @ H.T @ np.linalg.inv(S)
    nu = z - zhat
    nu[:, 1] = slam.wrap(nu[:, 1])
    xn = x + K @ nu.reshape(-1)
    xn[2] = slam.wrap(xn[2])
    I_KH = np.eye(d) - K @ H
    return xn, I_KH @ P @ I_KH.T + K @ Rb @ K.T


def test_update_matches_dense_joseph_form():
    rng = np.random.default_rng(4)
    f = E._Filter(np.array([1.0, 2.0, 0.3]), np.diag([0.2, 0.3, 0.01]), cap=2)
    R = np.diag([0.3, 0.02]) ** 2
    for _ in range(5):  # grows past the capacity
        z = np.array([[rng.uniform(5, 20), rng.uniform(-1.2, 1.2)]])
        m, Gx, Gz = inverse_observe(f.x[:3], z, 3.78, 0.5)
        f.add(m[0], Gx[0], Gz[0], R, 0.0)
    d = f.dim
    x0, P0 = f.x[:d].copy(), f.P[:d, :d].copy()
    glob = np.array([3, 0, 4])
    lm = np.array([x0[3 + 2 * g : 5 + 2 * g] for g in glob])
    z = observe(x0[:3], lm, 3.78, 0.5)[0] + rng.normal(0, [0.3, 0.02], (3, 2))
    xr, Pr = _dense_update(x0, P0, z, glob, R, 3.78, 0.5)
    E._update(f, z, glob, R, 3.78, 0.5)
    np.testing.assert_allclose(f.x[:d], xr, atol=1e-9)
    np.testing.assert_allclose(f.P[:d, :d], Pr, atol=1e-9)
    assert np.allclose(f.P[:d, :d], f.P[:d, :d].T)
    # removing a landmark keeps the others' blocks
    keep = [0, 1, 3, 4]
    blocks = [f.P[3 + 2 * j : 5 + 2 * j, 3 + 2 * j : 5 + 2 * j].copy() for j in keep]
    ids = f.ids[keep].copy()
    f.remove([2])
    assert f.n == 4 and f.ids[:4].tolist() == ids.tolist()
    for q, b in enumerate(blocks):
        np.testing.assert_allclose(f.P[3 + 2 * q : 5 + 2 * q, 3 + 2 * q : 5 + 2 * q], b)


def test_landmarks_seen_once_are_removed():
    """A spurious detection seen once never enters the final map."""
    steps = [slam.Step(0.0, np.array([0.0, 0.0]), np.zeros((0, 2)))]
    lm = np.array([[10.0, 3.0], [12.0, -4.0], [15.0, 1.0]])
    for k in range(1, 20):
        z = observe(np.zeros(3), lm)[0]
        if k == 5:
            z = np.vstack([z, [[7.0, 0.5]]])
        steps.append(slam.Step(0.2 * k, None, z))
    r = slam.ekf_slam(steps, slam.Unicycle(), association="clique", config=CFG)
    assert len(r.landmarks) == 3
    np.testing.assert_allclose(np.sort(r.landmarks[:, 0]), [10.0, 12.0, 15.0], atol=0.05)
    assert r.associations[4].tolist()[-1] == slam.NEW


def test_metrics():
    t = np.linspace(0, 100, 501)
    pos = np.column_stack([t, np.sin(t / 10)])
    ang = 0.3
    Rm = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    g = np.column_stack([t[::5], pos[::5] @ Rm.T + [5.0, -2.0]])
    g[40, 1:] += 200.0  # a receiver jump
    assert np.flatnonzero(gps_outliers(g)).tolist() == [40]
    e = gps_error(t, pos, g)
    assert e.rmse_best < 1e-9 and e.rmse_start < 1e-6 and e.fixes == len(g) - 1
    R2, t2, a2 = align_se2(pos, pos @ Rm.T + [5.0, -2.0])
    assert abs(a2 - ang) < 1e-12
    assert duplicate_pairs(np.array([[0, 0], [0.5, 0], [5, 5]])) == (1, 2)


def _write_vp(d, run, gps_every=5):
    d.mkdir(parents=True, exist_ok=True)
    with open(d / "inputs.dat", "w") as fi, open(d / "measurements.dat", "w") as fm:
        for s in run.steps:
            if s.control is not None:
                fi.write(f"{s.time:.3f} {s.control[0]:.5f} {s.control[1]:.5f}\n")
            for r, b in s.observations:
                fm.write(f"{s.time:.3f} {r:.5f} {b + math.pi / 2:.5f} 0.3\n")
    laser = slam.Ackermann()
    pos = np.array([laser.sensor_pose(p)[:2] for p in run.poses[:: gps_every * 8]])
    with open(d / "gps.dat", "w") as fg:
        for t, (x, y) in zip(run.times[:: gps_every * 8], pos, strict=False):
            fg.write(f"{t:.3f} {x:.4f} {y:.4f}\n")


def test_cli_slam_on_simulated_directory(tmp_path, park):
    from scanclique.cli import app

    d = tmp_path / "vp"
    _write_vp(d, park)
    out = tmp_path / "out"
    # the command: --out alone writes map.png too
    res = CliRunner().invoke(app, ["slam", str(d), "--association", "clique", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert (out / "map.png").is_file()
    res = CliRunner().invoke(
        app, ["slam", str(d), "-a", "nn", "--out", str(tmp_path / "np"), "--json", "--no-plot"]
    )
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "np" / "map.png").exists()
    assert (tmp_path / "np" / "report.json").is_file()
    # --no-plot into the first run's directory: its map.png (another run's map) is removed,
    # with a note; a map.png that no run listed is left alone
    res = CliRunner().invoke(app, ["slam", str(d), "-a", "nn", "--out", str(out), "--no-plot"])
    assert res.exit_code == 0, res.output
    assert not (out / "map.png").exists() and "removed" in res.output
    assert json.loads((out / "report.json").read_text())["removed"] == [str(out / "map.png")]
    (out / "map.png").write_bytes(b"mine")
    res = CliRunner().invoke(app, ["slam", str(d), "-a", "nn", "--out", str(out), "--no-plot"])
    assert res.exit_code == 0 and (out / "map.png").read_bytes() == b"mine"
    res = CliRunner().invoke(app, ["slam", str(d), "--plot"])
    assert res.exit_code == 2 and "give --out" in res.output
    res = CliRunner().invoke(
        app, ["slam", str(d), "--association", "clique", "--out", str(out), "--json", "--plot"]
    )
    assert res.exit_code == 0, res.output
    rep = json.loads(res.stdout)
    assert rep["method"] == "clique"
    assert rep["metrics"]["GPS RMSE (best SE(2) alignment)"]["value"] < 1.5
    # what the filter leaves out by its max_range is counted, not lost silently
    z = np.concatenate([s.observations for s in park.steps if s.n_observations])
    assert rep["metrics"]["observations"]["value"] == len(z)
    assert rep["metrics"]["observations beyond max_range (not used)"]["value"] == 0
    (tmp_path / "near.toml").write_text("max_range = 15.0\n")
    res = CliRunner().invoke(
        app, ["slam", str(d), "-a", "nn", "-c", str(tmp_path / "near.toml"), "--json"]
    )
    assert res.exit_code == 0, res.output
    far = json.loads(res.stdout)["metrics"]["observations beyond max_range (not used)"]
    assert far["value"] == np.count_nonzero(z[:, 0] > 15.0) > 0
    for f in ("trajectory.tum", "landmarks.csv", "report.json", "map.png"):
        assert (out / f).is_file()
    tum = np.loadtxt(out / "trajectory.tum")
    assert tum.shape[1] == 8
    res = CliRunner().invoke(app, ["slam", str(tmp_path / "missing")])
    assert res.exit_code == 2 and "error:" in res.output
    res = CliRunner().invoke(app, ["slam", str(d), "--association", "magic"])
    assert res.exit_code == 2


def test_steering_bias_is_estimated(park):
    """A zero offset of the logged steering: the augmented filter finds it (within three of
    its standard deviations) and tracks the vehicle better than the filter without it."""
    offset = 0.01  # rad, added to every logged steering angle
    steps = [
        s if s.control is None else slam.Step(s.time, s.control + (0.0, offset), s.observations)
        for s in park.steps
    ]
    cfg = slam.SlamConfig(max_range=20.0, **SLIP, control_bias_sigma=0.05, control_bias_rate=1e-5)
    r = slam.ekf_slam(steps, slam.Ackermann(), association="jcbb", config=cfg)
    b, sb = r.control_bias
    assert abs(b + offset) < 3 * sb and sb < 0.005
    plain = slam.ekf_slam(steps, slam.Ackermann(), association="jcbb", config=CFG)
    assert plain.control_bias is None

    def rmse(res):
        return np.sqrt(np.mean(np.sum((res.poses[:, :2] - park.poses[:, :2]) ** 2, 1)))

    assert rmse(r) < rmse(plain)


def test_speed_scale_is_estimated(park):
    """A wheel radius 5 % off (every logged speed times 0.95): the filter estimates the
    speed's relative error (1 / 0.95 - 1) within three of its standard deviations and
    tracks the vehicle better than the filter that takes the speed as logged."""
    factor = 0.95
    steps = [
        s if s.control is None else slam.Step(s.time, s.control * (factor, 1.0), s.observations)
        for s in park.steps
    ]
    r = slam.ekf_slam(steps, slam.Ackermann(), association="jcbb", config=CFG)
    assert CFG.speed_scale_sigma is not None  # on by default
    sc, ssc = r.speed_scale
    assert abs(sc - (1.0 / factor - 1.0)) < 3 * ssc and ssc < 0.01
    plain_cfg = dataclasses.replace(CFG, speed_scale_sigma=None)
    plain = slam.ekf_slam(steps, slam.Ackermann(), association="jcbb", config=plain_cfg)
    assert plain.speed_scale is None

    def rmse(res):
        return np.sqrt(np.mean(np.sum((res.poses[:, :2] - park.poses[:, :2]) ** 2, 1)))

    assert rmse(r) < rmse(plain)


def test_init_range_limits_new_landmarks(park):
    """No landmark starts beyond the initialisation range: every NEW observation is within."""
    cfg = slam.SlamConfig(max_range=20.0, **SLIP, init_range=(0.0, 12.0))
    r = slam.ekf_slam(park.steps, slam.Ackermann(), association="nn", config=cfg)
    obs = [s for s in park.steps if s.n_observations]
    new_r = np.concatenate(
        [s.observations[a == slam.NEW, 0] for s, a in zip(obs, r.associations, strict=True)]
    )
    assert len(new_r) and new_r.max() <= 12.0
    full = slam.ekf_slam(park.steps, slam.Ackermann(), association="nn", config=CFG)
    new_full = np.concatenate(
        [s.observations[a == slam.NEW, 0] for s, a in zip(obs, full.associations, strict=True)]
    )
    assert new_full.max() > 12.0


def test_bearing_bias_is_estimated(park):
    """A yaw misalignment of the sensor (every bearing offset): the augmented filter finds
    it within three standard deviations and tracks the vehicle better than without."""
    offset = 0.01
    steps = [
        s if not s.n_observations else slam.Step(s.time, s.control, s.observations + (0.0, offset))
        for s in park.steps
    ]
    cfg = slam.SlamConfig(max_range=20.0, **SLIP, bearing_bias_sigma=0.03)
    r = slam.ekf_slam(steps, slam.Ackermann(), association="jcbb", config=cfg)
    b, sb = r.bearing_bias
    assert abs(b - offset) < 3 * sb and sb < 0.005
    plain = slam.ekf_slam(steps, slam.Ackermann(), association="jcbb", config=CFG)

    def rmse(res):
        return np.sqrt(np.mean(np.sum((res.poses[:, :2] - park.poses[:, :2]) ** 2, 1)))

    assert rmse(r) < rmse(plain)


def test_confirm_range_keeps_far_only_trees_out_of_the_map():
    """A tree seen often but never within the confirmation range stays tentative and is
    not in the final map; without the condition it is."""
    lm = np.array([[10.0, 3.0], [12.0, -4.0], [24.0, 2.0]])
    steps = [slam.Step(0.0, np.array([0.0, 0.0]), np.zeros((0, 2)))]
    for k in range(1, 20):
        steps.append(slam.Step(0.2 * k, None, observe(np.zeros(3), lm)[0]))
    cfg = slam.SlamConfig(max_range=30.0, confirm_range=20.0, tentative_scans=100)
    r = slam.ekf_slam(steps, slam.Unicycle(), association="jcbb", config=cfg)
    assert len(r.landmarks) == 2 and r.landmarks[:, 0].max() < 20.0
    cfg = slam.SlamConfig(max_range=30.0, confirm_range=None, tentative_scans=100)
    r = slam.ekf_slam(steps, slam.Unicycle(), association="jcbb", config=cfg)
    assert len(r.landmarks) == 3


def _map_cost(x, x0, P0, z, glob, R, sx, sy):
    """The iterated EKF's objective: prior plus observations, Mahalanobis (squared)."""
    dx = x - x0
    dx[2] = slam.wrap(dx[2])
    lm = np.array([x[3 + 2 * g : 5 + 2 * g] for g in glob])
    nu = z - observe(x[:3], lm, sx, sy)[0]
    nu[:, 1] = slam.wrap(nu[:, 1])
    Ri = np.linalg.inv(R)
    return dx @ np.linalg.solve(P0, dx) + np.einsum("ka,ab,kb->", nu, Ri, nu)


def test_iterated_update_reaches_the_map_estimate():
    """With a large heading uncertainty and a precise sensor, the EKF's one
    linearisation stops short of the minimum of prior + observations; the iterated
    update (Bell and Cathey 1993) reaches it (against scipy's minimiser), and its first
    iteration is the EKF's update."""
    from scipy.optimize import minimize

    rng = np.random.default_rng(7)
    sx, sy = 3.78, 0.5
    R = np.diag([0.05, math.radians(0.3)]) ** 2
    lm = np.array([[15.0, 4.0], [12.0, -6.0], [20.0, 1.0]])
    f0 = E._Filter(np.zeros(3), np.diag([0.05, 0.05, 0.01]), cap=4)
    for m in lm:  # landmarks known to 0.3 m, independent of the pose
        f0.add(m, np.zeros((2, 3)), np.eye(2), np.eye(2) * 0.09, 0.0)
    f0.P[:3, :3] = np.diag([1.0, 1.0, math.radians(15.0) ** 2])
    truth = f0.x[: f0.dim].copy()
    truth[:3] = [0.6, -0.5, math.radians(20.0)]  # a 20 deg heading error: strongly nonlinear
    glob = np.arange(3)
    z = observe(truth[:3], lm, sx, sy)[0] + rng.normal(0, np.sqrt(np.diag(R)), (3, 2))
    d = f0.dim
    x0, P0 = f0.x[:d].copy(), f0.P[:d, :d].copy()
    ref = minimize(_map_cost, x0, args=(x0, P0, z, glob, R, sx, sy), method="BFGS", tol=1e-12)
    out = {}
    for iters in (1, 8):
        f = E._Filter(np.zeros(3), np.eye(3), cap=4)
        f.x, f.P, f.n = f0.x.copy(), f0.P.copy(), f0.n
        E._update(f, z, glob, R, sx, sy, iters)
        out[iters] = f
    ekf = E._Filter(np.zeros(3), np.eye(3), cap=4)
    ekf.x, ekf.P, ekf.n = f0.x.copy(), f0.P.copy(), f0.n
    E._update(ekf, z, glob, R, sx, sy)
    np.testing.assert_array_equal(out[1].x, ekf.x)
    np.testing.assert_array_equal(out[1].P, ekf.P)
    err_ekf = np.abs(out[1].x[:d] - ref.x).max()
    err_iekf = np.abs(out[8].x[:d] - ref.x).max()
    assert err_iekf < 1e-4 < 0.05 < err_ekf
    c8 = _map_cost(out[8].x[:d], x0, P0, z, glob, R, sx, sy)
    assert c8 <= ref.fun + 1e-6 < _map_cost(out[1].x[:d], x0, P0, z, glob, R, sx, sy)
    P = out[8].P[:d, :d]
    assert np.allclose(P, P.T) and np.all(np.linalg.eigvalsh(P) > 0)


def test_iterated_filter_runs_on_the_park(park):
    cfg = slam.SlamConfig(max_range=20.0, **SLIP, update_iterations=3)
    r = slam.ekf_slam(park.steps, slam.Ackermann(), association="nn", config=cfg)
    e = r.poses - park.poses
    assert np.sqrt(np.mean(np.sum(e[:, :2] ** 2, 1))) < 1.5


def test_gps_fix_errors_and_jumps():
    from scanclique.slam.metrics import gps_fix_errors, gps_jumps

    t = np.linspace(0, 100, 501)
    pos = np.column_stack([3.0 * t, 20 * np.sin(t / 20)])
    g = np.column_stack([t, pos])
    g[200:260, 1] += 5.0  # the receiver steps 5 m off and back
    fixes, e_start, e_best, est_best, _ = gps_fix_errors(t, pos, g)
    agg = gps_error(t, pos, g)
    assert abs(np.sqrt(np.mean(e_best**2)) - agg.rmse_best) < 1e-12
    assert abs(e_start.max() - agg.max_start) < 1e-12
    assert np.flatnonzero(gps_jumps(fixes, est_best)).tolist() == [200, 260]
    # a step after a gap longer than max_dt is not called a jump
    assert not gps_jumps(fixes, est_best, max_dt=0.1).any()
