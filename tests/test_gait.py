"""The gait: corners, speed, chirality, period policy, traceability."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from smarticle_mjx import gait as G

SPEED = 8.727


def _corners(spec):
    T = spec.period()
    # end of each quarter (just before the next move starts)
    t = (np.arange(4) + 1) * T / 4 - 1e-6
    return np.degrees(spec.setpoints(t, SPEED))


def test_square_ccw_visits_corners_in_order():
    c = _corners(G.GaitSpec(90.0, "ccw"))
    np.testing.assert_allclose(c, [[-90, 90], [-90, -90], [90, -90], [90, 90]], atol=1e-3)


def test_square_cw_visits_corners_in_opposite_order():
    c = _corners(G.GaitSpec(90.0, "cw"))
    np.testing.assert_allclose(c, [[90, -90], [-90, -90], [-90, 90], [90, 90]], atol=1e-3)


def test_cw_is_ccw_with_arms_swapped():
    """Mirror symmetry of the robot maps arm 1 to arm 2; CW must be CCW mirrored."""
    t = np.linspace(0, 3.2, 997)
    ccw = G.GaitSpec(60.0, "ccw").setpoints(t, SPEED)
    cw = G.GaitSpec(60.0, "cw").setpoints(t, SPEED)
    np.testing.assert_allclose(cw, ccw[:, ::-1], atol=1e-6)


@pytest.mark.parametrize("amp", [10.0, 45.0, 90.0])
def test_square_moves_one_arm_at_servo_speed(amp):
    spec = G.GaitSpec(amp)
    t = np.linspace(0, spec.period(), 2001)
    sp = spec.setpoints(t, SPEED).astype(np.float64)
    v = np.diff(sp, axis=0) / np.diff(t)[:, None]
    moving = np.abs(v) > 1e-3
    assert not (moving[:, 0] & moving[:, 1]).any(), "square gait moves one arm per edge"
    # no faster than the servo; interior samples of a move are at full speed
    assert np.abs(v).max() <= SPEED * 1.001
    assert np.median(np.abs(v[moving])) == pytest.approx(SPEED, rel=1e-3)
    # total travel per period: 4 edges of 2a
    travel = np.abs(np.diff(sp, axis=0)).sum()
    assert travel == pytest.approx(8 * math.radians(amp), rel=1e-3)


def test_diagonal_gait_moves_both_arms_together_and_is_time_symmetric():
    spec = G.GaitSpec(90.0, kind="diagonal")
    T = spec.period()
    t = np.linspace(0, T, 4001)
    sp = spec.setpoints(t, SPEED)
    np.testing.assert_allclose(sp[:, 0], sp[:, 1], atol=1e-6)
    # visits the opposite corner (-a, -a) at half period
    np.testing.assert_allclose(np.degrees(spec.setpoints(T / 2 - 1e-6, SPEED)), [-90, -90], atol=1e-3)
    # time-symmetric: the move back is the move out played backwards
    tm = 2 * math.pi / 2 / SPEED
    tau = np.linspace(0, tm, 101)
    np.testing.assert_allclose(spec.setpoints(T / 2 + tau, SPEED), spec.setpoints(tm - tau, SPEED), atol=1e-4)


def test_period_policy():
    assert G.GaitSpec(90.0).period() == pytest.approx(1.6)
    assert G.GaitSpec(45.0).period() == pytest.approx(0.8)
    assert G.GaitSpec(45.0, period_s=1.6).period() == pytest.approx(1.6)
    with pytest.raises(ValueError, match="shorter than"):
        G.GaitSpec(90.0, period_s=1.0).validate(SPEED)
    with pytest.raises(ValueError, match="amplitude"):
        G.GaitSpec(120.0).validate(SPEED)
    with pytest.raises(ValueError, match="chirality"):
        G.GaitSpec(90.0, chirality="left").validate(SPEED)


def test_phase_offset_shifts_time():
    spec = G.GaitSpec(90.0)
    t = np.linspace(0, 1.6, 321)
    a = spec.setpoints(t, SPEED, phase=0.25)
    b = spec.setpoints(t + 0.4, SPEED)
    np.testing.assert_allclose(a, b, atol=1e-4)


def test_traceable_amplitude_chirality_kind_under_jit_and_vmap():
    f = jax.jit(jax.vmap(G.setpoints, in_axes=(None, 0, None, None, 0, 0, None)))
    amps = jnp.radians(jnp.array([30.0, 60.0, 90.0]))
    out = f(0.39, amps, 1.6, SPEED, jnp.array([1, -1, 1]), jnp.array([0, 0, 1]), 0.0)
    ref = [G.setpoints(0.39, a, 1.6, SPEED, c, k) for a, c, k in zip(amps, [1, -1, 1], [0, 0, 1])]
    np.testing.assert_allclose(np.asarray(out), np.stack(ref), atol=1e-6)
