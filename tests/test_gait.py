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


def _draws(rng, n):
    """Gait arguments shaped as the replay's follower passes them: per lane and robot ([U, N]), times per lane
    and robot or [K, U, N] (each segment's end), phases on eighths of a period half the time, both
    chiralities, both kinds, arms of unequal speed."""
    for k in range(n):
        shp = ((1, 1), (3, 2))[k % 2]  # two shapes only: JAX compiles each operation anew for each shape
        a = rng.uniform(0.2, 1.6, shp)
        per = a / math.radians(90) * 1.6 * rng.uniform(0.9, 1.1, shp)
        chi = rng.choice([-1.0, 1.0], shp)
        kind = rng.choice([0.0, 1.0], shp) * (rng.random() < 0.3)
        ph = rng.uniform(-1, 1, shp)
        if k % 4 > 1:
            ph = np.round(ph * 8) / 8
        w1, w2 = rng.uniform(5, 12, shp), rng.uniform(5, 12, shp)
        ends = (np.arange(1, 6)[:, None, None] / 4 - np.mod(ph, 1)) * per - 1e-9 * per
        for t in (np.zeros(shp), rng.uniform(0, 2, shp), ends):
            yield t, a, per, 1.0, chi, kind, ph, w1, w2


def test_the_host_gait_is_the_jax_gait_bit_for_bit():
    """The replay's servo reference (engine.core.follow_corners) asks ``host_setpoints`` for the gait's
    corners, which the JAX gait gave before: a model robot rattling in its backlash turns a last-bit change
    of a setpoint into another run, so the two must be the same numbers, not close ones. JAX divides by a
    divisor broadcast to the quotient's shape as a product with its inverse, which differs from a division
    in the last bit in about one case in five; the host function has to do the same."""
    rng = np.random.default_rng(20261202)
    n = 0
    for args in _draws(rng, 40):
        want = np.asarray(G.setpoints(*args))
        got = G.host_setpoints(*args)
        assert got.dtype == want.dtype and got.shape == want.shape
        assert np.array_equal(got, want), np.abs(got.astype(float) - want).max()
        n += 1
    spec = G.GaitSpec(60.0, chirality="cw")
    # numpy scalars are not weakly typed: JAX rounds them to its float type first, numpy would not
    for t in (0.0, 0.37, np.linspace(0, 3, 97), np.float64(1.1)):
        for phase in (0.0, 0.3, -0.2, np.float64(0.3), np.array([0.61, 0.2])[0]):
            for speed in (SPEED, np.float64(SPEED) * 1.01):
                want = np.asarray(G.setpoints(t, spec.amplitude, spec.period(), speed, -1, 0, phase))
                got = spec.setpoints(t, speed, phase=phase)
                assert got.dtype == want.dtype and np.array_equal(got, want), (t, phase, speed)
    assert n == 120


def test_the_replays_controls_are_those_of_the_jax_gait(monkeypatch):
    """Controls of lanes whose servo references start at tracked arms (``Lanes.start_ref``) are computed with
    the host gait; with the JAX gait put back they are the same array."""
    import dataclasses

    from smarticle_mjx.engine import Lanes, Scene
    from smarticle_mjx.engine.core import lane_controls, on_step_grid
    from smarticle_mjx.scene import SceneParams

    scene = Scene.build(SceneParams(), 2)
    specs = [G.GaitSpec(40.0), G.GaitSpec(75.0, chirality="cw")]
    lanes = Lanes.from_robot_gaits(np.zeros((3, 2, 5)), specs, phase=np.array([[0.1, 0.62], [0.4, 0.0], [0.9, 0.33]]))
    start = np.radians([[[40.0, 12.0], [-75.0, 75.0]], [[3.0, -40.0], [np.nan, 70.0]], [[-38.0, -40.0], [0.0, 0.0]]])
    lanes = on_step_grid(dataclasses.replace(lanes, start_ref=start), scene.params.timestep)
    t = scene.params.timestep * np.arange(int(round(lanes.period / scene.params.timestep)))
    host = lane_controls(scene, lanes, t)
    monkeypatch.setattr(G, "host_setpoints", lambda *a, **k: np.asarray(G.setpoints(*a, **k)))
    jax_gait = lane_controls(scene, lanes, t)
    assert np.array_equal(host, jax_gait)
    assert not np.array_equal(host, lane_controls(scene, dataclasses.replace(lanes, start_ref=None), t))
