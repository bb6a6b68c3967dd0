"""Mapping with the laser scanners people use today (benchmarks/mapping_sensors.py): a
40 Hz 270-degree scanner, a 360-degree triangulation scanner, ROS no-return conventions,
and the cost of the front end's motion model on long logs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_mapping import _aligned_errors as _ate

from scanclique.geometry import Pose2
from scanclique.mapping import map_scans
from scanclique.mapping.config import FrontEndConfig
from scanclique.mapping.frontend import VelocityModel
from scanclique.match import pose_score, prepare_scan
from scanclique.scan import Scan
from scanclique.sim import World, office_world, room_world, simulate_scan, simulate_sensor_drive

HOKUYO = dict(
    n_beams=1081, fov=math.radians(270.0), angle_min=math.radians(-135.0), max_range=30.0,
    range_sigma=0.02, scan_rate=40.0, speed=1.0,
)  # fmt: skip
RPLIDAR = dict(
    n_beams=360, fov=2 * math.pi * 359 / 360, angle_min=-math.pi, max_range=10.0,
    range_sigma=0.0, range_sigma_per_m=0.015, dropout=0.07, scan_rate=7.0, speed=0.5,
)  # fmt: skip


def test_sensor_drive_steps_as_the_scanner_sees_them():
    rng = np.random.default_rng(4)
    world = office_world(rng)
    turn_rate = math.radians(90.0)
    scans = simulate_sensor_drive(
        rng, world, 12, 0.25, scan_rate=40.0, speed=1.0, turn_rate=turn_rate, n_beams=61
    )
    assert len(scans) >= 11 * 10 + 1  # at least ten scans per 0.25 m at 1 m/s and 40 Hz
    assert [s.timestamp for s in scans[:3]] == [0.0, 0.025, 0.05]
    for a, b in zip(scans[:-1], scans[1:], strict=True):
        u = a.reference.inverse() @ b.reference
        assert math.hypot(u.x, u.y) <= 0.025 + 1e-9
        assert abs(u.theta) <= turn_rate / 40.0 + 1e-9
        o = a.odometry.inverse() @ b.odometry
        assert math.hypot(o.x, o.y) < 0.05  # odometry interpolated too, not jumping
    assert all(world.is_free(s.reference.translation, 0.2)[0] for s in scans)


def test_range_noise_can_grow_with_the_range():
    walls = np.array([[[-2.0, -9.0], [-2.0, 9.0]], [[8.0, -9.0], [8.0, 9.0]]])
    world = World(walls)
    kw = dict(n_beams=2000, fov=math.radians(20.0), angle_min=math.radians(-10.0))
    exact = simulate_scan(world, Pose2.identity(), range_sigma=0.0, **kw)
    noisy = simulate_scan(
        world, Pose2.identity(), range_sigma=0.0, range_sigma_per_m=0.01,
        rng=np.random.default_rng(0), **kw,
    )  # fmt: skip
    err = (noisy.ranges - exact.ranges) / exact.ranges  # a wall 8 m ahead: sigma 8 cm
    assert np.std(err) == pytest.approx(0.01, rel=0.1)


@pytest.mark.parametrize("odometry", [True, False])
def test_a_40_hz_270_degree_scanner(odometry):
    # Hokuyo UTM-30LX class: 1081 beams over 270 degrees, 2.5 cm between scans; the
    # keyframes, not the scans, carry the loop search
    rng = np.random.default_rng(2)
    scans = simulate_sensor_drive(rng, office_world(rng), 8, 0.25, **HOKUYO)
    r = map_scans(scans, use_odometry=odometry)
    assert _ate(r, scans).max() < 0.03
    assert set(r.placed_by[1:]) <= {"match", "icp"}
    assert len(r.keyframes) < len(scans) / 5


def test_a_360_degree_scanner_with_dropouts():
    # RPLIDAR A1 class: beams from -pi all the way round, noise 1.5 % of the range, 7 %
    # of the beams without a return
    rng = np.random.default_rng(0)
    scans = simulate_sensor_drive(rng, office_world(rng), 16, 0.25, **RPLIDAR)
    assert scans[0].angles[0] == -math.pi and scans[0].angles[-1] < math.pi
    r = map_scans(scans, use_odometry=False)
    assert _ate(r, scans).max() < 0.1
    assert set(r.placed_by[1:]) <= {"match", "icp"}


def test_a_scanner_that_loses_returns_has_them_bridged():
    """map_scans fits the clustering to the scanner (features.for_scanner): it reads one
    lost beam inside a surface as a lost return when the scanner loses returns, and
    widens the range term to a noise of 1.5 % of the range, and says so in the
    configuration it used; not when told not to, not the bridging for a scanner that
    loses no returns, nor when the clustering already bridges; the online mapper decides
    on the first scan."""
    import dataclasses

    from scanclique.mapping import MapConfig, map_online

    rng = np.random.default_rng(0)
    scans = simulate_sensor_drive(rng, office_world(rng), 6, 0.25, **RPLIDAR)
    gap = lambda r: r.config.match.clustering.max_gap_beams  # noqa: E731
    fitted = map_scans(scans, use_odometry=False).config.match.clustering
    assert fitted.max_gap_beams == 1 and fitted.c2 > 0.06
    off = MapConfig(front_end=FrontEndConfig(fit_scanner=False))
    assert map_scans(scans, use_odometry=False, config=off).config.match == off.match
    m = MapConfig().match
    m = dataclasses.replace(m, clustering=dataclasses.replace(m.clustering, max_gap_beams=2))
    two = MapConfig(match=m)
    assert gap(map_scans(scans, use_odometry=False, config=two)) == 2
    clean = simulate_sensor_drive(rng, office_world(rng), 6, 0.25, **{**RPLIDAR, "dropout": 0.0})
    assert gap(map_scans(clean, use_odometry=False)) == 0
    assert gap(map_online(scans, use_odometry=False).result) == 1
    assert gap(map_online(clean[:1] + scans, use_odometry=False).result) == 0
    # the command's table says so
    from scanclique.mapping.run import MapRun

    said = {m: v for m, v, _ in MapRun("x", map_scans(scans), {}, None).rows()}
    assert said["lost returns bridged inside a surface"] == "up to 1"
    assert float(said["clustering's range term (c2)"]) == fitted.c2
    said = {m: v for m, v, _ in MapRun("x", map_scans(clean), {}, None).rows()}
    assert "lost returns bridged inside a surface" not in said
    assert "clustering's range term (c2)" in said  # its noise is the same


LDS01 = dict(RPLIDAR, angle_min=0.0, max_range=3.5, dropout=0.05, scan_rate=5.0, speed=0.2)


def test_loop_closures_of_a_short_reach_are_verified_without_its_edges():
    """map_scans verifies loop closures (not local matches) on the keyframes prepared
    again without the edges where a wall only leaves the reach, for a scanner that meets
    its reach (LoopConfig.reach_edges off, features.meets_reach), and says so; not for
    one that does not, nor when told not to fit the scanner; the local jobs keep the
    front end's features; on one worker beside the front end the map is the same."""
    import dataclasses

    from scanclique.mapping import MapConfig
    from scanclique.mapping.parallel import _verify_jobs
    from scanclique.mapping.pipeline import loop_match
    from scanclique.mapping.run import MapRun

    rng = np.random.default_rng(4)
    world = office_world(rng)
    short = simulate_sensor_drive(rng, world, 24, 0.25, **LDS01)
    far = simulate_sensor_drive(rng, world, 4, 0.25, **{**LDS01, "max_range": 30.0})
    r = map_scans(short, use_odometry=False)
    assert not r.config.loops.reach_edges and not loop_match(r.config).features.reach_edges
    assert map_scans(far, use_odometry=False).config.loops.reach_edges
    from scanclique.mapping import map_online  # the online mapper: from its first scan

    assert not map_online(short, use_odometry=False).result.config.loops.reach_edges
    off = MapConfig(front_end=FrontEndConfig(fit_scanner=False))
    assert map_scans(short, use_odometry=False, config=off).config.loops.reach_edges
    said = {m: v for m, v, _ in MapRun("x", r, {}, None).rows()}
    assert said["edges where a wall leaves the reach"] == "left out of loop closures"
    two = map_scans(short, use_odometry=False, workers=2)
    assert [p.as_array().tolist() for p in two.poses] == [p.as_array().tolist() for p in r.poses]
    # the verifier: a loop job on the loops' scans and configuration, a local one not
    from scanclique.mapping.parallel import Verifier

    cfg = r.config
    a, b = (prepare_scan(short[k], cfg.match) for k in (0, 3))
    la, lb = (dataclasses.replace(p, config=loop_match(cfg)) for p in (a, b))
    seen = []
    import scanclique.mapping.loops as loops

    orig = loops.verify

    def spy(pa, pb, *args, **kw):
        seen.append((pa is la, args[3].features.reach_edges, kw["quick"]))
        return orig(pa, pb, *args, **kw)

    v = Verifier(cfg.match, cfg.front_end, (0.01, 0.005), 1, loop_match(cfg))
    try:
        loops.verify = spy
        job = (0, 3, Pose2.identity(), Pose2(0.25, 0.0, 0.0), (0.1, 0.05))
        _verify_jobs(v.token, [(*job, True, False), (*job, False, False)], {0: a, 3: b},
                     {0: la, 3: lb})  # fmt: skip
    finally:
        loops.verify = orig
        v.close()
    assert seen == [(False, True, True), (True, False, False)]


def test_an_icp_step_is_not_confirmed_by_the_chain_it_turned():
    """With odometry, a scan the feature match cannot place is placed by ICP when its pose
    agrees with the odometry, or with the chain's constant-velocity prediction only when
    the scan before was matched: after an ICP step the prediction carries that step's
    error. A 3.5 m scanner on a campus (drive 2 of benchmarks/mapping_sensors.py, its
    first 100 scans, loops off): steps turned up to 33 degrees wrong, each agreeing with
    the one before, while the odometry was right to half a degree; now at most 9."""
    import dataclasses

    from scanclique.mapping import MapConfig
    from scanclique.sim import campus_world

    rng = np.random.default_rng(2)
    scans = simulate_sensor_drive(rng, campus_world(rng), 300, 0.25, **LDS01)[:100]
    cfg = MapConfig()
    cfg = dataclasses.replace(cfg, loops=dataclasses.replace(cfg.loops, enabled=False))
    r = map_scans(scans, use_odometry=True, config=cfg)
    turn = [
        abs(math.remainder((a.inverse() @ b).theta - (sa.reference.inverse() @ sb.reference).theta,
                           2 * math.pi))
        for a, b, sa, sb in zip(r.poses[:-1], r.poses[1:], scans[:-1], scans[1:], strict=True)
    ]  # fmt: skip
    assert "icp" in r.placed_by
    assert math.degrees(max(turn)) < 15.0
    assert _ate(r, scans).mean() < 0.15


def test_an_icp_step_is_gated_by_the_odometry_as_good_as_it_has_proved():
    """With odometry, the ICP fallback gates its poses by the odometry noise model scaled
    to what the accepted matches have shown (:class:`OdometryFit`). A 3.5 m scanner on a
    campus (drive 1 of benchmarks/mapping_sensors.py, its first 620 scans, loops off):
    the model's 4 sigma let ICP steps turn 6-9 degrees from odometry right to half a
    degree (scans 586-599); now the odometry places them."""
    import dataclasses

    from scanclique.mapping import MapConfig
    from scanclique.sim import campus_world

    rng = np.random.default_rng(1)
    scans = simulate_sensor_drive(rng, campus_world(rng), 300, 0.25, **LDS01)[:620]
    cfg = MapConfig()
    cfg = dataclasses.replace(cfg, loops=dataclasses.replace(cfg.loops, enabled=False))
    worst = {}
    for fit in (False, True):
        fe = dataclasses.replace(cfg.front_end, odometry_fit=fit)
        r = map_scans(scans, use_odometry=True, config=dataclasses.replace(cfg, front_end=fe))
        worst[fit] = max(
            abs(math.remainder((a.inverse() @ b).theta
                               - (sa.reference.inverse() @ sb.reference).theta, 2 * math.pi))
            for a, b, sa, sb in zip(r.poses[:-1], r.poses[1:], scans[:-1], scans[1:],
                                    strict=True)
        )  # fmt: skip
    assert math.degrees(worst[False]) > 5.0  # the model's gate: the wrong turns pass
    assert math.degrees(worst[True]) < 3.0
    # the map says how good the odometry proved (measured either way), and so does its table
    from scanclique.mapping.run import MapRun

    m_xy, m_th = r.odometry_fit
    assert 0.1 <= m_xy < 0.5 and m_th == pytest.approx(0.1)  # right to a tenth in heading
    assert r.counts()["odometry_fit"] == [m_xy, m_th]
    said = {m: (v, u) for m, v, u in MapRun("x", r, {}, None).rows()}
    row = "odometry's error / its noise model"
    assert said[row] == (f"{m_xy:.2f} / {m_th:.2f}", "translation / heading")
    assert map_scans(scans[:30], use_odometry=False).odometry_fit is None


def test_odometry_fit_scales_the_model_to_the_residuals_it_has_seen():
    from scanclique.mapping.frontend import OdometryFit

    fe = FrontEndConfig()
    fit = OdometryFit(fe)
    cov = np.diag([0.1**2, 0.1**2, math.radians(4.0) ** 2])
    prior = (Pose2(0.1, 0.0, 0.0), cov)
    for k in range(fe.odometry_fit_min - 1):
        fit.observe(Pose2(0.1 + 0.01 * (k % 3 - 1), 0.0, math.radians(2.0) * (k % 2)), *prior)
    assert fit.scales() is None and fit.fitted(prior)[1] is cov  # not yet measured
    fit.observe(Pose2(0.1, 0.0, 0.0), *prior)
    m_xy, m_th = fit.scales()
    assert m_xy == fe.odometry_fit_floor  # residuals of 0.1 sigma: the floor
    assert m_th == pytest.approx(0.5 / 1.960)  # half a sigma at the 95th percentile
    np.testing.assert_allclose(np.sqrt(np.diag(fit.fitted(prior)[1])),
                               np.sqrt(np.diag(cov)) * [m_xy, m_xy, m_th])  # fmt: skip
    for _ in range(200):  # an odometry worse than its model is never loosened beyond it
        fit.observe(Pose2(1.0, 1.0, 1.0), *prior)
    assert fit.scales() == (1.0, 1.0)
    import dataclasses

    never = OdometryFit(dataclasses.replace(fe, odometry_fit_min=0))
    assert never.scales() is None  # nothing measured yet: the model, whatever the minimum


def test_odometry_fit_takes_out_a_steady_heading_drift_it_can_show_and_no_other():
    """OdometryFit.drift: the heading the odometry loses per metre and per radian turned,
    by least squares over the accepted matches, each term only when it stands DRIFT_T
    standard errors from zero; corrected() takes it out of an odometry edge and scales
    the covariance to the residuals left."""
    from scanclique.mapping.frontend import DRIFT_T, OdometryFit

    fe = FrontEndConfig()
    rng = np.random.default_rng(0)
    per_metre, noise = 0.003, math.radians(0.03)  # a steady drift as large as the noise
    fit = OdometryFit(fe)
    for k in range(400):
        turn = math.radians(90.0) if k % 40 == 0 else 0.0
        odo = Pose2(0.25, 0.0, turn)
        cov = np.diag([0.1**2, 0.1**2, math.radians(4.0) ** 2])
        seen = Pose2(0.25, 0.0, turn + per_metre * 0.25 + rng.normal(0.0, noise))
        fit.observe(seen, odo, cov)
    m, r = fit.drift()
    assert m == pytest.approx(per_metre, rel=0.1) and r == 0.0  # no per-radian error shown
    (dm, dr), (s_xy, s_th) = fit.calibration()
    assert (dm, dr) == (m, r) and s_xy == fit.scales()[0]
    assert s_th <= fit.scales()[1]  # the residuals left are no larger
    z, P = OdometryFit.corrected((Pose2(100.0, 0.0, 0.0), np.eye(3)), 100.0, fit.calibration())
    assert z.theta == pytest.approx(100.0 * m) and z.y == pytest.approx(100.0 * math.sin(50.0 * m))
    np.testing.assert_allclose(np.diag(P), [s_xy**2, s_xy**2, s_th**2])
    # the same residuals without the drift: nothing shown, nothing taken out
    blind = OdometryFit(fe)
    for _ in range(400):
        blind.observe(Pose2(0.25, 0.0, rng.normal(0.0, noise)), Pose2(0.25, 0.0, 0.0), cov)
    assert blind.drift() == (0.0, 0.0) and DRIFT_T >= 3.0
    # steps steadily 2 % longer than the odometry's: read, not taken out
    assert fit.steps_off() == 0.0 and blind.steps_off() == 0.0
    long = OdometryFit(fe)
    for _ in range(400):
        seen = Pose2(0.25 * 1.02 + rng.normal(0.0, 0.002), 0.0, 0.0)
        long.observe(seen, Pose2(0.25, 0.0, 0.0), cov)
    assert long.steps_off() == pytest.approx(0.02, rel=0.1) and long.drift() == (0.0, 0.0)
    assert OdometryFit(fe).drift() is None and OdometryFit(fe).calibration() is None


def test_odometry_fit_reads_a_steady_scale_error_from_the_matches_fixed_along_the_step():
    """OdometryFit.scale: the odometry distance's steady relative error, each match
    weighed by its own sigma along the step, only when shown; matches a corridor leaves
    loose (large sigma along the step) that stay where the odometry put them count for
    little, so the wheels' 2 % is read where the unweighted steps_off reads far less."""
    from scanclique.mapping.frontend import SCALE_REFIT, OdometryFit

    fe = FrontEndConfig()
    rng = np.random.default_rng(1)
    cov = np.diag([0.1**2, 0.1**2, math.radians(4.0) ** 2])
    fixed = np.diag([0.003**2, 0.003**2, 1e-6])  # features fix the step
    loose = np.diag([0.5**2, 0.003**2, 1e-6])  # a corridor: nothing fixes it along x
    fit, blind = OdometryFit(fe), OdometryFit(fe)
    for k in range(600):
        odo = Pose2(0.25 * 1.02, 0.0, 0.0)  # wheels measuring 2 % long
        if k % 3:  # two of three matches in corridors, left where the odometry put them
            fit.observe(Pose2(odo.x + rng.normal(0.0, 0.001), 0.0, 0.0), odo, cov, loose)
        else:
            fit.observe(Pose2(0.25 + rng.normal(0.0, 0.003), 0.0, 0.0), odo, cov, fixed)
        blind.observe(Pose2(0.25 + rng.normal(0.0, 0.003), 0.0, 0.0), Pose2(0.25, 0, 0), cov, fixed)
    assert fit.scale() == pytest.approx(1 / 1.02 - 1, rel=0.05)
    assert abs(fit.steps_off()) < 0.5 * abs(fit.scale())  # unweighted: mostly the corridors
    assert blind.scale() == 0.0  # exact wheels: nothing shown
    assert OdometryFit.scaled(Pose2(1.0, 2.0, 0.5), -0.5) == Pose2(0.5, 1.0, 0.5)
    # without the matches' covariances nothing is read; refitted only as matches come
    bare = OdometryFit(fe)
    for _ in range(100):
        bare.observe(Pose2(0.3, 0.0, 0.0), Pose2(0.25, 0.0, 0.0), cov)
    assert bare.scale() == 0.0 and SCALE_REFIT >= 1


def test_a_scan_placed_by_the_odometry_is_as_unsure_as_it_has_proved_unless_it_slipped():
    """A scan the scans could not place is placed by the odometry with the covariance the
    odometry has proved (OdometryFit.placing), not the model's; one whose match was
    rejected for disagreeing with the odometry keeps the model's (a slip)."""
    from scanclique.mapping.frontend import OdometryFit, Step, prior_step

    fe = FrontEndConfig()
    fit = OdometryFit(fe)
    a, b = Pose2(0.0, 0.0, 0.0), Pose2(0.1, 0.0, 0.01)
    step = prior_step(a, b, fe.odometry_noise, "odometry", "few", "too_few_features", 0.0)
    assert fit.placing(step).covariance is step.covariance  # not yet measured: the model
    for _ in range(fe.odometry_fit_min):
        fit.observe(step.pose, step.pose, step.covariance)  # the odometry exactly right
    placed = fit.placing(step)
    assert isinstance(placed, Step) and placed.pose == step.pose and placed.kind == step.kind
    np.testing.assert_allclose(placed.covariance, step.covariance * fe.odometry_fit_floor**2)
    slipped = prior_step(a, b, fe.odometry_noise, "odometry", "4.7 sigma", "rejected_odometry",
                         0.0)  # fmt: skip
    assert fit.placing(slipped).covariance is slipped.covariance


def test_odometry_that_proved_good_enters_the_batch_graph_but_not_across_a_slip():
    """The batch back end takes the odometry between consecutive keyframes as edges
    (kind "odometry_factor", in MapResult.edges and graph.g2o) when it proved at least
    BackEndConfig.odometry_max_fit times better than its model in heading, scaled as it
    proved; none across a scan whose match was rejected for disagreeing with it, or
    matched against it reversed; none for odometry that proved worse, or when off."""
    import dataclasses

    from scanclique.mapping import MapConfig
    from scanclique.mapping.pipeline import _Mapper
    from scanclique.sim import campus_world

    rng = np.random.default_rng(1)
    scans = simulate_sensor_drive(rng, campus_world(rng), 300, 0.25, **LDS01)[:240]
    cfg = MapConfig()
    cfg = dataclasses.replace(cfg, loops=dataclasses.replace(cfg.loops, enabled=False))
    m = _Mapper(True, False, cfg, 1)
    try:
        m.run(scans)
    finally:
        m.verifier.close()
    assert m.odo_fit.scales()[1] <= cfg.back_end.odometry_max_fit  # right to a tenth
    assert m.odometry_factors() == []  # chained only: the front end's chain alone
    cfg = MapConfig()  # as if the loops had run (none would have closed so short a drive)
    m.cfg = cfg
    factors = m.odometry_factors()
    assert len(factors) == len(m.kf) - 1  # every pair of consecutive keyframes
    i, j, Z, P = factors[3]
    a, b = m.kf[i], m.kf[j]
    assert Z.distance_to(scans[a].odometry.inverse() @ scans[b].odometry)[0] < 1e-12
    assert P[2, 2] < (math.radians(4.0) * 0.5) ** 2  # scaled as proved, not the model's
    # a slip between keyframes 3 and 4, and a scan matched against the odometry reversed
    m.odometry_doubted.update((m.kf[4], m.kf[7]))
    pairs = {(i, j) for i, j, _, _ in m.odometry_factors()}
    assert (3, 4) not in pairs and (6, 7) not in pairs and (4, 5) in pairs
    r = m.result(0.0)
    assert sum(e.kind == "odometry_factor" for e in r.edges) == len(pairs)
    for be in (dataclasses.replace(cfg.back_end, odometry_max_fit=0.05),
               dataclasses.replace(cfg.back_end, odometry_factors=False)):  # fmt: skip
        m.cfg = dataclasses.replace(cfg, back_end=be)
        assert m.odometry_factors() == []


def _mapped_ring(**odometry_errors):
    """Half a loop of the simulated ring (seed 0) mapped with its odometry, whose errors
    ``simulate_ring_drive`` takes (``heading_bias_per_m``, ``scale_error``): the scans and
    the batch mapper after the run, for its odometry fit and edges."""
    from scanclique.mapping import MapConfig
    from scanclique.mapping.pipeline import _Mapper
    from scanclique.sim import simulate_ring_drive

    scans = simulate_ring_drive(np.random.default_rng(0), loops=0.5, **odometry_errors)
    m = _Mapper(True, False, MapConfig(), 1)
    try:
        m.run(scans)
    finally:
        m.verifier.close()
    return scans, m


def test_odometry_edges_of_a_drifting_odometry_have_the_drift_taken_out():
    """Odometry whose heading drifts steadily (a wheel a little larger than the other)
    enters the batch graph with that drift taken out (OdometryFit.calibration): edges
    are independent in a graph, so a drift within their noise on every edge would bend
    a long corridor (the 200 x 120 m ring, seeds 0-3: 0.879 / 0.713 / 0.565 / 1.047 m
    with the drift in its edges)."""

    bias = 0.01  # rad/m
    scans, m = _mapped_ring(heading_bias_per_m=bias)
    per_metre, _ = m.odo_fit.drift()
    assert per_metre == pytest.approx(-bias, rel=0.2)  # the scans turn less than the wheels
    factors = m.odometry_factors()
    assert len(factors) > len(m.kf) // 2
    raw, fixed = [], []
    for i, j, Z, _ in factors:
        a, b = m.kf[i], m.kf[j]
        truth = scans[a].reference.inverse() @ scans[b].reference
        odo = scans[a].odometry.inverse() @ scans[b].odometry
        raw.append(odo.theta - truth.theta)
        fixed.append(Z.theta - truth.theta)
    assert abs(np.mean(raw)) > 3 * abs(np.mean(fixed))  # the steady part is gone
    assert m.odo_fit.steps_off() == 0.0
    # the map says it, and so does its table
    from scanclique.mapping.run import MapRun

    r = m.result(0.0)
    assert r.odometry_drift == m.odo_fit.drift()
    assert r.counts()["odometry_drift"] == list(r.odometry_drift)
    said = {m: (v, u) for m, v, u in MapRun("x", r, {}, None).rows()}
    value, unit = said["odometry's steady heading drift"]
    assert unit == "deg/m / % of turn" and float(value.split(" / ")[0]) == pytest.approx(
        math.degrees(per_metre), abs=0.006)  # fmt: skip


def test_odometry_of_a_wrong_radius_has_its_scale_read_and_taken_out_of_its_edges():
    """Wheels measuring 5 % short or long: the matches the features fix along the step
    read the steady scale error (OdometryFit.scale, within a fifth of it; the unweighted
    steps_off reads less), and the batch graph's odometry edges carry the odometry with it
    taken out. Without a scale read, matches stepping steadily further than the odometry
    (steps_off > 0) keep its edges out, as before."""
    from scanclique.mapping import MapConfig

    for error in (-0.05, 0.05):
        scans, m = _mapped_ring(scale_error=error)
        scale = m.odo_fit.scale()
        assert scale == pytest.approx(1.0 / (1.0 + error) - 1.0, rel=0.2)
        assert abs(m.odo_fit.steps_off()) < abs(scale)  # corridors' matches follow the seed
        assert m.odo_fit.calibration()[1][1] <= MapConfig().back_end.odometry_max_fit
        factors = m.odometry_factors()
        assert len(factors) > len(m.kf) // 2
        ratios = []
        for i, j, Z, _ in factors:
            odo = scans[m.kf[i]].odometry.inverse() @ scans[m.kf[j]].odometry
            if math.hypot(odo.x, odo.y) > 0.1:
                ratios.append(math.hypot(Z.x, Z.y) / math.hypot(odo.x, odo.y))
        assert np.median(ratios) == pytest.approx(1.0 + scale, abs=1e-6)
        assert m.result(0.0).odometry_steps == scale
        if error < 0:  # short wheels, their scale not read: no edges
            m.odo_fit._scale = (len(m.odo_fit.rows), 0.0)  # as if none were shown
            assert m.odo_fit.steps_off() > 0.02 and m.odometry_factors() == []


def test_ros_no_returns_are_never_walls():
    # ROS LaserScan marks a beam without a return by +inf (REP 117), NaN, 0, -inf or a
    # value below range_min, depending on the driver: each is masked and none becomes a
    # point. +inf is a no-return like a reading at range_max (open space beyond reach: a
    # cluster beside it ends in an edge), the others are unknown readings; each group
    # gives one map, and both map the drive
    rng = np.random.default_rng(1)
    kw = dict(RPLIDAR, dropout=0.15, scan_rate=3.5)
    scans = simulate_sensor_drive(rng, office_world(rng), 8, 0.25, **kw)
    maps = {}
    for value in ("max", math.inf, math.nan, 0.0, -math.inf, 0.05):
        out = []
        for s in scans:
            v = s.range_max if value == "max" else value
            r = np.where(s.ranges >= s.range_max, v, s.ranges)
            out.append(
                Scan(r, s.angles, range_min=0.1, range_max=s.range_max, timestamp=s.timestamp,
                     reference=s.reference)
            )  # fmt: skip
        valid = [int(np.sum(s.ranges < s.range_max)) for s in scans]
        assert [o.n_valid for o in out] == valid
        m = map_scans(out, use_odometry=False)
        maps[value] = np.array([p.as_array() for p in m.poses])
        assert _ate(m, scans).max() < 0.1
    assert np.array_equal(maps[math.inf], maps["max"])
    for value in (0.0, -math.inf, 0.05):
        assert np.array_equal(maps[value], maps[math.nan])


def test_motion_model_does_not_sort_the_whole_history_per_scan(monkeypatch):
    # without odometry the front end asks the motion model for the 90th percentile of the
    # steps on every scan: np.quantile of the whole history made it quadratic in the log's
    # length (17 ms per scan after 100000 scans, 42 minutes of a 40 Hz scanner)
    fe = FrontEndConfig()
    m = VelocityModel(fe)
    rng = np.random.default_rng(0)
    prev2, prev = Pose2.identity(), Pose2(0.02, 0.0, 0.0)
    steps, turns = [], []
    for _ in range(3000):
        placed = prev @ Pose2(float(rng.uniform(0.0, 0.05)), 0.0, float(rng.normal(0.0, 0.01)))
        rel = prev.inverse() @ placed
        steps.append(math.hypot(rel.x, rel.y))
        turns.append(m.predict(prev2, prev).distance_to(placed)[1])
        m.observe(prev2, prev, (None, None, None), placed, rel, 1)
        prev2, prev = prev, placed
    expect = (
        fe.jump_factor * float(np.quantile(steps, 0.9)) * 3 + fe.jump_floor,
        min(float(np.quantile(turns, 0.95)), fe.guess_sigma_radians),
    )
    sizes = []
    quantile = np.quantile

    def counting(a, *args, **kw):
        sizes.append(np.size(a))
        return quantile(a, *args, **kw)

    monkeypatch.setattr(np, "quantile", counting)
    assert (m.max_translation(3), m.heading_sigma()) == expect  # to the bit
    assert max(sizes) <= 2


def test_a_bag_of_a_360_degree_scanner_published_from_0_to_2_pi(tmp_path):
    # the TurtleBot3's LDS-01 driver publishes angle_min 0, angle_max 2 pi; the matcher
    # measures bearings in [-pi, pi) (atan2), so the raw-scan score saw no free space
    # behind the robot: a pose 0.5 m off scored 0.03, and -0.42 from the same scans
    # published from -pi. The reader rolls a full circle to start at -pi
    pytest.importorskip("rosbags")
    from test_rosbag import write_ros1

    from scanclique.io.rosbag import read_bag

    rng = np.random.default_rng(3)
    world = room_world(8.0, 6.0, rng=rng, doorways=1, pillars=1, clutter=3)
    kw = dict(n_beams=360, fov=2 * math.pi * 359 / 360, angle_min=0.0, max_range=10.0, rng=rng)
    poses = (Pose2(4.0, 3.0, 0.0), Pose2(4.3, 3.1, 0.3))
    scans = [
        simulate_scan(world, p, timestamp=0.2 * k, odometry=p, **kw) for k, p in enumerate(poses)
    ]
    write_ros1(tmp_path / "lds.bag", scans)
    back = read_bag(tmp_path / "lds.bag")
    for b, s in zip(back, scans, strict=True):
        assert -math.pi <= b.angles[0] < -3.1 and b.angles[-1] < math.pi
        assert np.all(np.diff(b.angles) > 0)
        # the same beams, each with its range, only relabelled by a whole turn (the beam
        # at pi may land on either side)

        def turn(x):
            x = np.mod(x, 2 * math.pi)
            return np.where(x > 2 * math.pi - 1e-5, 0.0, x)

        ob, os_ = np.argsort(turn(b.angles)), np.argsort(turn(s.angles))
        np.testing.assert_allclose(turn(b.angles)[ob], turn(s.angles)[os_], atol=1e-5)
        np.testing.assert_allclose(b.ranges[ob], s.ranges[os_], atol=1e-5)
    pa, pb = prepare_scan(back[0]), prepare_scan(back[1])
    true = poses[0].inverse() @ poses[1]
    assert pose_score(pa, pb, true) > 0.8
    assert pose_score(pa, pb, true @ Pose2(0.5, 0.0, 0.0)) < -0.2


def test_a_scan_made_with_angles_from_0_to_2_pi_scores_as_if_rolled():
    # a Scan built directly from such a driver's message (not through the bag reader,
    # which rolls it): the raw-scan score and the free-space conflicts look a bearing up
    # a whole turn on, so the blind side behind the robot is gone there too
    from scanclique.refine import free_space_conflicts

    rng = np.random.default_rng(3)
    world = room_world(8.0, 6.0, rng=rng, doorways=1, pillars=1, clutter=3)
    kw = dict(n_beams=360, fov=2 * math.pi * 359 / 360, angle_min=0.0, max_range=10.0, rng=rng)
    poses = (Pose2(4.0, 3.0, 0.0), Pose2(4.3, 3.1, 0.3))
    scans = [simulate_scan(world, p, **kw) for p in poses]

    def rolled(s):
        a = np.where(s.angles >= math.pi, s.angles - 2 * math.pi, s.angles)
        o = np.argsort(a, kind="stable")
        return Scan(s.ranges[o], a[o], range_min=s.range_min, range_max=s.range_max)

    true = poses[0].inverse() @ poses[1]
    off = true @ Pose2(0.5, 0.0, 0.0)
    direct = [prepare_scan(s) for s in scans]
    turned = [prepare_scan(rolled(s)) for s in scans]
    for pose in (true, off):
        assert pose_score(*direct, pose) == pytest.approx(pose_score(*turned, pose), abs=0.02)
    assert pose_score(*direct, off) < -0.2
    pts = scans[1].points()
    for pose in (true, off):
        assert free_space_conflicts(scans[0], pts, pose=pose) == pytest.approx(
            free_space_conflicts(rolled(scans[0]), pts, pose=pose), abs=0.01
        )


def test_real_log_degradations_do_what_they_say():
    """benchmarks/mapping_sensors.py --real: each variant of a scan is what its name says,
    and the scan given is never altered."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import mapping_sensors as bench  # noqa: PLC0415

    rng = np.random.default_rng(3)
    r = rng.uniform(0.5, 12.0, 181)
    r[[5, 9]] = 80.0  # no returns
    r[7] = np.nan
    s = Scan(r, np.linspace(-math.pi / 2, math.pi / 2, 181), range_max=80.0, timestamp=1.0)
    scans = [s, Scan(r, s.angles, range_max=80.0, timestamp=2.0)]
    before = s.ranges.copy()
    assert bench.degrade(scans, "as-is") == scans
    assert bench.degrade(scans, "every-2nd-scan") == scans[:1]
    cap = bench.degrade(scans, "range-5.6")[0]
    assert cap.range_max == 5.6 and np.array_equal(cap.ranges, s.ranges, equal_nan=True)
    assert not cap.valid[s.ranges >= 5.6].any() and cap.valid[s.valid & (s.ranges < 5.6)].all()
    half = bench.degrade(scans, "half-beams")[0]
    assert half.ranges.size == 91 and np.array_equal(half.angles, s.angles[::2])
    noisy = bench.degrade(scans, "noise-3cm")[0]
    moved = noisy.ranges[s.valid] - s.ranges[s.valid]
    assert 0.02 < moved.std() < 0.04
    assert np.array_equal(noisy.ranges[~s.valid], s.ranges[~s.valid], equal_nan=True)
    assert np.array_equal(s.ranges, before, equal_nan=True)
    with pytest.raises(ValueError, match="unknown variant"):
        bench.degrade(scans, "range-3")


def test_a_coarse_scanner_with_odometry_keeps_its_loop_closures():
    # Intel's first 2500 scans with every second beam (2 degrees apart) and its odometry:
    # the matches verify few features, so the front end drifts faster than the loops' drift
    # model allows. The loops widen their gates to the front end's own summed uncertainty
    # with odometry as without it; when they did so without odometry only, the drift model
    # refused every closure once the estimate had drifted (5 closures, 1.06 m mean
    # relation error, 5.8 m max; 76 closures and 0.026 m since)
    import dataclasses

    from conftest import require_log

    from scanclique import datasets
    from scanclique.eval import frame_mounting, read_relations, relation_metrics

    require_log("intel-raw")
    scans = [
        dataclasses.replace(s, ranges=s.ranges[::2], angles=s.angles[::2])
        for s in datasets.load_log("intel-raw")[:2500]
    ]
    r = map_scans(scans, use_odometry=True)
    assert r.used_odometry
    rels = read_relations(datasets.data_dir() / datasets.DATASETS["intel-raw"].relations)
    m = relation_metrics(
        rels, list(r.poses), [s.timestamp for s in scans], mounting=frame_mounting(scans)
    ).to_dict()["all"]
    assert m["n"] > 300
    assert m["translation_mean"] < 0.05 and m["translation_max"] < 0.5
    assert len(r.accepted_closures) >= 30


@pytest.mark.slow
def test_a_twin_room_is_not_taken_for_the_room_it_looks_like():
    """Drive 3 of the office with the RPLIDAR-class scanner and odometry: coming back past
    the start, the robot sees a room 3.6 m from the first that looks like it (the office's
    rooms are alike). The front end knows its way there to 0.1-0.5 m, the drift model
    allows 1.8 m, and the match to the first room is 3.6 m off; the raw scans conflict on
    8-17 % of their points (furniture where the other room is free). With
    ``loops.max_conflict`` off, two such closures are corroborated by each other and
    enter the graph; with it they are refused as ``"conflicting"`` and every accepted
    closure is right."""
    from dataclasses import replace  # noqa: PLC0415

    from scanclique.mapping import MapConfig  # noqa: PLC0415
    from scanclique.mapping.run import MapRun  # noqa: PLC0415

    rng = np.random.default_rng(3)
    scans = simulate_sensor_drive(rng, office_world(rng), 110, 0.25, **RPLIDAR)

    def wrong_closures(cfg):
        res = map_scans(scans, use_odometry=True, config=cfg)
        wrong = 0
        for c in res.accepted_closures:
            truth = scans[c.i].reference.inverse() @ scans[c.j].reference
            wrong += c.pose.distance_to(truth)[0] > 0.3
        return wrong, [c for c in res.loop_closures if c.verdict == "conflicting"], res

    cfg = MapConfig()
    off = replace(cfg, loops=replace(cfg.loops, max_conflict=1.0))
    wrong_off, refused_off, _ = wrong_closures(off)
    assert wrong_off >= 1 and not refused_off  # the twin room, taken without the rule
    wrong_on, refused, res = wrong_closures(cfg)
    assert wrong_on == 0
    assert refused and all("twin place" in c.reason and c.pose is None for c in refused)
    # and ``scanclique map``'s table says so
    rows = {m: v for m, v, _ in MapRun("drive 3", res, {}, None).rows()}
    assert f"{len(refused)} conflicting" in rows["loop closures refused as look-alikes"]
