"""Near-contact sub-stepping: the gate never misses a contact, and a sub-stepped lane is MuJoCo's own
stepping at the sub-step."""

import dataclasses

import numpy as np
import pytest

from smarticle_mjx import configs as C
from smarticle_mjx import presets
from smarticle_mjx import scene as S
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.core import Record
from smarticle_mjx.engine.gate import APPROACH_SPEED_MAX, chunk_steps, gap_lower_bound, make_gate
from smarticle_mjx.gait import GaitSpec

LAB = presets.params("lab-lag")
DISCRETE = LAB.replace(integrator="discrete")
GAIT = GaitSpec(90.0)


def _random_poses(n, n_robots, seed, spread=0.09):
    rng = np.random.default_rng(seed)
    return np.concatenate([rng.uniform(-spread, spread, (n, n_robots, 2)), rng.uniform(-np.pi, np.pi, (n, n_robots, 1)),
                           rng.uniform(-1.6, 1.6, (n, n_robots, 2))], -1)


@pytest.mark.parametrize("preset", ["lab-lag", "paper"])
def test_gate_bound_is_never_above_the_robots_gap(preset):
    """The gate's capsule covers contain the robots, so their gap is a lower bound of the planar gap that
    the start-validity check computes from the exact outlines (configs.pair_separation, written for that
    check): never above it, and below it by no more than the two body covers' bulge, (sqrt(2) - 1) D/2 each,
    plus each end cap's overhang past the body's end, (sqrt(2) - 1) D/2 again."""
    robot = presets.params(preset).robot
    poses = _random_poses(6000, 2, 1)
    exact = C.pair_separation(poses[:, 0], poses[:, 1], robot)
    bound = gap_lower_bound(poses[:, 0], poses[:, 1], robot)
    apart = exact > 0
    assert apart.sum() > 2000
    assert np.all(bound <= exact + 1e-6)
    bulge = (np.sqrt(2) - 1) * robot.body_thickness / 2
    assert np.max(exact[apart] - bound[apart]) <= 4 * bulge + 1e-6
    # where an arm is nearest on both sides the bound is close: most pairs within a millimetre
    assert np.median(exact[apart] - bound[apart]) < 0.005


def test_gate_reads_poses_from_qpos_as_the_scene_does():
    """make_gate reads x, y, heading and arm angles (driven hinge plus free play) from qpos; near is exactly
    'the bound of some pair < gate', on three robots with gear play."""
    params = LAB.replace(robot=dataclasses.replace(LAB.robot, backlash_deg=2.0))
    scene = Scene.build(params, 3)
    assert scene.layout.play_qpos is not None
    poses = _random_poses(800, 3, 2, spread=0.12)
    qpos = scene.qpos_from_poses(poses)
    rng = np.random.default_rng(3)
    qpos[:, scene.layout.play_qpos.ravel()] = rng.uniform(-0.03, 0.03, (800, scene.layout.play_qpos.size))
    back = scene.poses_from_qpos(qpos)
    i, j = np.triu_indices(3, 1)
    want = gap_lower_bound(back[:, i], back[:, j], params.robot).min(-1) < 0.004
    got = make_gate(scene.layout, params.robot, 0.004)(qpos)
    assert 0.1 < want.mean() < 0.9
    assert np.array_equal(got, want)


def test_chunk_is_short_enough_for_the_fastest_approach():
    """Between two asks of the gate, robots a gate apart cannot meet: chunk x dt x v_max <= gate."""
    for dt, gate in ((5e-4, 0.004), (2.5e-4, 0.004), (5e-4, 0.0005), (1e-3, 0.01)):
        n = chunk_steps(dt, gate)
        assert n >= 1 and (n == 1 or n * dt * APPROACH_SPEED_MAX <= gate)


def _pair_lanes(n, seed=0):
    a0 = GAIT.setpoints(0.0, LAB.robot.servo_speed)
    return Lanes.from_gait(C.sample_valid_pairs(n, np.random.default_rng(seed), (0.8, 1.2), a0[0], a0[1], LAB.robot),
                           GAIT)


def _run(params, lanes, periods=1, collisions=False, track=None):
    be = make_backend("native", Scene.build(params, 2, collisions=collisions), nthread=1)
    try:
        st, rec, tr = be.advance(be.initial_state(lanes), lanes, periods,
                                 record=Record(track_stride=track, collisions=collisions))
        return st, rec, tr, getattr(be, "substep_stats", None)
    finally:
        be.close()


def test_a_lane_always_near_runs_as_mujoco_at_the_sub_step():
    """With the gate wide open every chunk is sub-stepped: the run is a plain run at timestep / K, with the
    same touches and collision record and poses equal to the solver's tolerance (each chunk starts Newton
    cold where the plain run warm-starts it: differences of ~1e-8 m after a period of contacts)."""
    lanes = _pair_lanes(3)
    gated = DISCRETE.replace(contact_substeps=2, substep_gate=1.0)
    plain = DISCRETE.replace(timestep=LAB.timestep / 2)
    s1, r1, t1, stats = _run(gated, lanes, collisions=True, track=400)
    s2, r2, t2, _ = _run(plain, lanes, collisions=True, track=800)
    assert stats[0] == 0 and stats[1] > 0
    np.testing.assert_allclose(r1.poses, r2.poses, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(r1.touched, r2.touched)
    np.testing.assert_allclose(r1.min_dist, r2.min_dist, rtol=0, atol=1e-6)
    # tracks on the full step's grid: the plain run's every other row
    np.testing.assert_allclose(t1["qpos"], t2["qpos"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(t1["t"], t2["t"])
    np.testing.assert_allclose(r1.collisions["impulse"], r2.collisions["impulse"], rtol=1e-4, atol=1e-7)
    # a full step is in contact when either of its two sub-steps was: between half and all the sub-steps
    steps1, steps2 = r1.collisions["steps"], r2.collisions["steps"]
    assert np.all(steps1 * 2 >= steps2) and np.all(steps1 <= steps2)
    assert steps1.sum() > 0


def test_lanes_apart_run_at_the_full_step_and_near_ones_split():
    """Pairs started 0.8-1.2 W apart touch within a period; sub-stepped only while near, they run some
    chunks whole and some split, and end where neither the full nor the sub-step run ends (a third
    numerics), with the same touches in this first period."""
    lanes = _pair_lanes(4, seed=1)
    _, r_gate, _, stats = _run(DISCRETE.replace(contact_substeps=2), lanes)
    _, r_full, _, _ = _run(DISCRETE, lanes)
    assert stats[0] > 0 and stats[1] > 0
    assert r_full.touched.any()
    np.testing.assert_array_equal(r_gate.touched, r_full.touched)
    assert not np.array_equal(r_gate.poses, r_full.poses)


@pytest.mark.slow  # 20 s: building an MJX backend
def test_lock_step_backends_split_every_step():
    """MJX runs its lanes in lock-step, where skipping sub-steps for some lanes saves nothing: it honours
    sub-stepping by splitting every step (the gate always open), not by ignoring it."""
    be = make_backend("mjx", Scene.build(LAB.replace(integrator="RK4", contact_substeps=2), 2))
    assert be.model.opt.timestep == LAB.timestep / 2


def test_bad_sub_stepping_is_refused():
    for bad in (dict(contact_substeps=0), dict(contact_substeps=1.5), dict(substep_gate=0.0)):
        with pytest.raises(ValueError, match="contact_substeps|substep_gate"):
            S.SceneParams(**bad).validate()
    # implicitfast slips a body per arm move by an amount that grows with the step: a step that changes with
    # the robots' distance would make that a drift (docs/timestep.md), so it is refused
    with pytest.raises(ValueError, match="per-step error does not depend on the step"):
        S.SceneParams(contact_substeps=2).validate()
    S.SceneParams(contact_substeps=2, integrator="discrete").validate()
