"""A servo reference that starts at the arms (``Lanes.start_ref``, since version 0.4.4): a robot at rest
whose gait is part of a move ahead makes that move from where its arms are, at the servo's speed.

The reference is checked against a rate-limited follower written here step by step toward the corner
the independent simulator's clock names (``calibrate.independent.corner``), not against the closed form
it is computed with."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from smarticle_mjx import gait as G
from smarticle_mjx import presets
from smarticle_mjx.calibrate.independent import corner
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.core import Record, check_start_delays, lane_controls, on_step_grid


def _lanes(amp_deg, phase, chirality="ccw", kind="square", start=None, n=1):
    spec = G.GaitSpec(amplitude_deg=amp_deg, chirality=chirality, kind=kind)
    poses = np.zeros((1, n, 5))
    lanes = Lanes.from_robot_gaits(poses, [spec] * n, phase=np.full((1, n), phase))
    if start is not None:
        lanes = dataclasses.replace(lanes, start_ref=np.broadcast_to(np.asarray(start, float), (1, n, 2)).copy())
    return lanes


def _slewed(t, a, period, speed, start, target_of):
    """Step by step: the reference moves at most speed * dt toward the target in force at each step."""
    dt = t[1] - t[0]
    ref, out = np.array(start, float), []
    for tk in t:
        out.append(ref.copy())
        ref = ref + np.clip(target_of(tk) - ref, -speed * dt, speed * dt)
    return np.array(out)


@pytest.mark.parametrize("amp_deg,phase,chirality", [(40.0, 0.149, "ccw"), (90.0, 0.40, "ccw"),
                                                     (60.0, -0.10, "cw"), (25.0, 0.73, "ccw")])
def test_a_reference_started_in_the_first_corner_is_the_rate_limited_follower_of_the_gaits_corners(
        amp_deg, phase, chirality):
    """A robot at rest in its first corner (+a, +a) whose clock is ``phase`` periods on: its reference moves
    from the corner toward the corner in force at the servo's speed, reverses when the target changes
    (the 90 deg, 0.4 case changes target mid-catch-up), and is the steady gait from where it meets it on,
    within one step's slew of the step-by-step follower."""
    params = presets.params()
    scene, speed = Scene.build(params, 1), params.robot.servo_speed
    a = math.radians(amp_deg)
    lanes = on_step_grid(_lanes(amp_deg, phase, chirality, start=[a, a]), params.timestep)
    dt, period = params.timestep, lanes.period
    t = dt * np.arange(int(round(period / dt)))
    ctrl = lane_controls(scene, lanes, t)[0]
    steady = lane_controls(scene, dataclasses.replace(lanes, start_ref=None), t)[0]
    brute = _slewed(t, a, period, speed, [a, a], lambda tk: corner(tk + 1e-12, a, period, chirality, phase))
    assert np.abs(ctrl[:, :2] - brute).max() <= speed * dt * 1.01
    assert np.abs(ctrl[0, :2] - [a, a]).max() < 1e-6  # (float32 gait where it is the gait) it starts at the arms, not at the gait's setpoint
    own = np.abs(ctrl[:, :2] - steady[:, :2]) > 1e-5  # where it is not (yet) the gait
    assert own.any()
    moving = own & (np.abs(ctrl[:, 2:]) > 0)
    np.testing.assert_allclose(np.abs(ctrl[:, 2:][moving]), speed, rtol=1e-6)  # it moves at the servo's speed
    late = t > 0.8 * period  # it has met the gait by then (a move fits in a quarter)
    np.testing.assert_allclose(ctrl[late], steady[late], atol=1e-5)


def test_a_diagonal_reference_follows_its_half_period_targets():
    """Diagonal gait: both arms head for -a in the first half and +a in the second; started at (-a, +a)
    a quarter into the period, arm 1 waits (it is at its target) and arm 2 moves down, each then joins
    the gait."""
    params = presets.params()
    scene, speed = Scene.build(params, 1), params.robot.servo_speed
    a = math.radians(60.0)
    lanes = on_step_grid(_lanes(60.0, 0.25, kind="diagonal", start=[-a, a]), params.timestep)
    dt, period = params.timestep, lanes.period
    t = dt * np.arange(int(round(period / dt)))
    ctrl = lane_controls(scene, lanes, t)[0]

    def target(tk):
        u = (tk / period + 0.25) % 1.0
        return np.full(2, -a if u < 0.5 else a)
    brute = _slewed(t, a, period, speed, [-a, a], target)
    assert np.abs(ctrl[:, :2] - brute).max() <= speed * dt * 1.01


def test_a_reference_started_at_the_gaits_own_setpoint_is_the_gait():
    """The steady gait is the same follower, so starting it where the gait is at t = 0 (or NaN, which
    means that) changes no control."""
    params = presets.params()
    scene = Scene.build(params, 2)
    lanes = on_step_grid(_lanes(40.0, 0.149, n=2), params.timestep)
    t = params.timestep * np.arange(int(round(lanes.period / params.timestep)))
    steady = lane_controls(scene, lanes, t)
    at0 = steady[:, 0].reshape(1, 2, 4)[..., :2]
    same = lane_controls(scene, dataclasses.replace(lanes, start_ref=at0.copy()), t)
    nan = lane_controls(scene, dataclasses.replace(lanes, start_ref=np.full((1, 2, 2), np.nan)), t)
    np.testing.assert_allclose(same, steady, atol=1e-5)
    np.testing.assert_allclose(nan, steady, atol=1e-5)


def test_the_arm_makes_its_first_move_at_the_servos_speed_instead_of_catching_up():
    """Physics: a lone robot at rest in its first corner, its clock 0.149 period ahead at 40 deg (mid-move).
    Sent the steady gait's setpoint, the servo meets a jump of most of a move and the arm catches up at
    its stall torque, faster than the servo's rated speed; with its reference started at its arms, the
    arm moves no faster than the rated speed (plus the tracking's overshoot) and ends the period where the
    steady gait does."""
    params = presets.params()
    scene, speed = Scene.build(params, 1), params.robot.servo_speed
    a = math.radians(40.0)
    poses = np.array([[[0.0, 0.0, 0.0, a, a]]])
    spec = G.GaitSpec(amplitude_deg=40.0)
    runs = {}
    for name, start in (("steady", None), ("at arms", np.array([[[a, a]]]))):
        lanes = Lanes.from_robot_gaits(poses, [spec], phase=np.array([[0.149]]))
        lanes = dataclasses.replace(lanes, start_ref=start)
        be = make_backend("native", scene)
        try:
            state = be.initial_state(lanes)
            _, _, track = be.advance(state, lanes, 2, record=Record(track_stride=1))
        finally:
            be.close()
        q = scene.poses_from_qpos(track["qpos"][0])  # [S, 1, 5]
        runs[name] = q[:, 0, 3:]
    dt = params.timestep
    rate = {k: np.abs(np.diff(v, axis=0)).max() / dt for k, v in runs.items()}
    assert rate["steady"] > 1.3 * speed
    assert rate["at arms"] < 1.15 * speed
    np.testing.assert_allclose(runs["at arms"][-1], runs["steady"][-1], atol=math.radians(1.0))


def test_start_ref_is_checked_and_only_the_native_backend_runs_it():
    """Shape and non-finite angles are refused; it cannot be combined with start delays; the backends
    that start every reference at the gait's setpoint say so in one line."""
    lanes = _lanes(40.0, 0.1)
    with pytest.raises(ValueError, match="start_ref"):
        dataclasses.replace(lanes, start_ref=np.zeros((1, 2, 2)))
    with pytest.raises(ValueError, match="start_ref"):
        dataclasses.replace(lanes, start_ref=np.full((1, 1, 2), np.inf))
    with pytest.raises(ValueError, match="not both"):
        dataclasses.replace(lanes, start_ref=np.zeros((1, 1, 2)), hold=np.full((1, 1), 0.1))
    with pytest.raises(ValueError, match="native backend"):
        check_start_delays(dataclasses.replace(lanes, start_ref=np.zeros((1, 1, 2))), "mjx")
    started = dataclasses.replace(lanes, start_ref=np.zeros((1, 1, 2))).started(1.0)
    assert started.start_ref is None  # past the run's start the gait runs


def test_the_replay_takes_an_arm_tracked_near_its_gaits_corner_as_resting_there():
    """calibrate.sim.start_reference: a tracked arm within SNAP_DEG of +-amplitude starts its reference
    exactly there (tracking noise is not a start), one further off starts where it was tracked, and an
    untracked arm is left to the gait (NaN)."""
    from smarticle_mjx.calibrate.sim import SNAP_DEG, start_reference
    a = math.radians(40.0)
    noise = math.radians(0.5 * SNAP_DEG)
    far = math.radians(2.0 * SNAP_DEG)
    arms0 = np.array([[a + noise, -a - noise], [a - far, np.nan]])
    ref = start_reference(arms0, [a, a])
    np.testing.assert_allclose(ref[0], [a, -a], atol=0)
    assert ref[1, 0] == arms0[1, 0] and np.isnan(ref[1, 1])


def test_a_replayed_trial_of_robots_at_rest_in_their_corner_is_the_gait_where_the_clock_is_at_a_corner():
    """A two-robot trial tracked from rest in the first corner (with tracking noise): robot 0 is at gait
    phase 0, where the steady gait is at that corner too, so its replay is the steady gait's, to the
    last digit; robot 1, 0.149 period ahead (mid-move), makes its first move from the corner."""
    from smarticle_mjx.calibrate import sim
    from smarticle_mjx.calibrate.data import Trial
    params = presets.params()
    spec = G.GaitSpec(amplitude_deg=40.0)
    a = spec.amplitude
    t = np.arange(0.0, 2 * spec.period(), 1 / 60)
    rng = np.random.default_rng(1)
    pose = np.zeros((len(t), 2, 3))
    pose[:, 1, 0] = 0.3
    arms = np.full((len(t), 2, 2), a) + rng.normal(0, math.radians(0.3), (len(t), 2, 2))
    tr = Trial("t", t, pose, arms, spec, params, 60.0)
    [with_start] = sim.simulate_trials([tr], lambda _: params, phase_for=lambda _: np.array([0.0, 0.149]))
    steady_ref = sim.start_reference
    try:
        sim.start_reference = lambda arms0, amps: np.full(arms0.shape, np.nan)  # every reference at its gait
        [steady] = sim.simulate_trials([tr], lambda _: params, phase_for=lambda _: np.array([0.0, 0.149]))
    finally:
        sim.start_reference = steady_ref
    np.testing.assert_array_equal(with_start[:, 0], steady[:, 0])
    early = t < 0.1 * spec.period()
    # steady: robot 1's servo is sent mid-move and its arm 1 is well on its way at once; started at its
    # arms it has moved at most the servo's speed times the time
    assert np.degrees(a - steady[early, 1, 3]).max() > 20.0
    assert (a - with_start[early, 1, 3] <= params.robot.servo_speed * t[early] * 1.1 + 1e-3).all()
