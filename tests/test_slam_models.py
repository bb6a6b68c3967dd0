"""Models of scanclique.slam: Jacobians against finite differences, angle wrapping."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scanclique.slam import Ackermann, Unicycle, wrap
from scanclique.slam.models import inverse_observe, observe

EPS = 1e-6


def _num_jac(f, x, eps=EPS):
    cols = []
    for e in np.eye(len(x)):
        d = f(x + eps * e) - f(x - eps * e)
        if d.ndim:
            d = d.copy()
        cols.append(d / (2 * eps))
    return np.stack(cols, axis=-1)


MODELS = [
    Ackermann(wheelbase=2.83, encoder_offset=0.76, laser_a=3.78, laser_b=0.5),
    Unicycle(sensor_x=0.3, sensor_y=-0.1),
]


@pytest.mark.parametrize("model", MODELS, ids=["ackermann", "unicycle"])
@given(
    x=st.floats(-50, 50),
    y=st.floats(-50, 50),
    th=st.floats(-3.1, 3.1),
    v=st.floats(-3, 8),
    c=st.floats(-0.5, 0.5),
    dt=st.floats(0.01, 0.5),
)
@settings(max_examples=40, deadline=None)
def test_motion_jacobians(model, x, y, th, v, c, dt):
    s0 = np.array([x, y, th])
    u = np.array([v, c])
    _, F, G = model.predict(s0, u, dt)

    def fs(s):
        out = model.predict(s, u, dt)[0].copy()
        out[2] = s0[2] + wrap(out[2] - s0[2])
        return out

    def fu(uu):
        out = model.predict(s0, uu, dt)[0].copy()
        out[2] = s0[2] + wrap(out[2] - s0[2])
        return out

    np.testing.assert_allclose(F, _num_jac(fs, s0), atol=1e-6)
    np.testing.assert_allclose(G, _num_jac(fu, u), atol=1e-6)


@pytest.mark.parametrize("offset", [(0.0, 0.0), (3.78, 0.5)])
# ruff: noqa: B023 (the closures are called at once, inside their loop iteration)
def test_observation_jacobians(offset):
    rng = np.random.default_rng(3)
    for _ in range(20):
        s0 = np.r_[rng.uniform(-20, 20, 2), rng.uniform(-math.pi, math.pi)]
        lm = s0[:2] + rng.uniform(-30, 30, (4, 2))
        z, Hx, Hm = observe(s0, lm, *offset)

        def fx(s):
            zz = observe(s, lm, *offset)[0].copy()
            zz[:, 1] = z[:, 1] + wrap(zz[:, 1] - z[:, 1])
            return zz

        np.testing.assert_allclose(Hx, _num_jac(fx, s0), atol=1e-5)
        for j in range(len(lm)):

            def fm(m, j=j):
                zz = observe(s0, m[None], *offset)[0][0].copy()
                zz[1] = z[j, 1] + wrap(zz[1] - z[j, 1])
                return zz

            np.testing.assert_allclose(Hm[j], _num_jac(fm, lm[j]), atol=1e-5)
        # inverse observation: round trip and Jacobians
        m, Gx, Gz = inverse_observe(s0, z, *offset)
        np.testing.assert_allclose(m, lm, atol=1e-9)
        np.testing.assert_allclose(
            Gx, _num_jac(lambda s: inverse_observe(s, z, *offset)[0], s0), atol=1e-5
        )
        for j in range(len(lm)):
            np.testing.assert_allclose(
                Gz[j],
                _num_jac(lambda zz: inverse_observe(s0, zz[None], *offset)[0][0], z[j]),
                atol=1e-5,
            )


def test_wrap_range_and_pi():
    a = np.array([math.pi, -math.pi, 3 * math.pi, -3 * math.pi + 1e-9, 0.0, 7.0, -7.0])
    w = wrap(a)
    assert np.all(w >= -math.pi) and np.all(w < math.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-12)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-9)


def test_bearing_behind_vehicle_at_pi():
    """A landmark straight behind: the bearing is +-pi, and a tiny move of the landmark
    across the axis changes the bearing by a tiny angle after wrapping, not by 2 pi."""
    s0 = np.array([0.0, 0.0, 0.0])
    z1 = observe(s0, np.array([[-10.0, 1e-6]]))[0][0]
    z2 = observe(s0, np.array([[-10.0, -1e-6]]))[0][0]
    assert abs(abs(z1[1]) - math.pi) < 1e-6 and abs(abs(z2[1]) - math.pi) < 1e-6
    assert abs(wrap(z1[1] - z2[1])) < 1e-6
    # heading across +-pi: prediction wraps
    m = Unicycle()
    x, _, _ = m.predict(np.array([0.0, 0.0, math.pi - 0.01]), np.array([1.0, 1.0]), 0.1)
    assert -math.pi <= x[2] < math.pi and abs(wrap(x[2] - (math.pi + 0.09))) < 1e-12


def test_ackermann_straight_and_turn():
    m = Ackermann()
    x, _, _ = m.predict(np.zeros(3), np.array([2.0, 0.0]), 0.5)
    np.testing.assert_allclose(x, [1.0, 0.0, 0.0], atol=1e-12)
    # the encoder is off-centre: vc = ve / (1 - tan(a) H / L)
    a = 0.2
    x, _, _ = m.predict(np.zeros(3), np.array([1.0, a]), 1.0)
    vc = 1.0 / (1 - math.tan(a) * 0.76 / 2.83)
    np.testing.assert_allclose(x, [vc, 0.0, vc * math.tan(a) / 2.83], atol=1e-12)
