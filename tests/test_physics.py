"""Physics the study depends on (native MuJoCo backend)."""

import dataclasses
import math

import mujoco
import numpy as np
import pytest

from smarticle_mjx import configs as C
from smarticle_mjx import presets
from smarticle_mjx import scene as S
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx import gait as G
from smarticle_mjx.gait import GaitSpec

P = S.SceneParams()
W = P.robot.body_length
SPEED = P.robot.servo_speed
GAIT = GaitSpec(90.0)
A0 = GAIT.setpoints(0.0, SPEED)
# a pair that touches from the first period on (found by a small scan)
PAIR = (1.16, 6.026, 4.451)


def _pair(cfg=PAIR):
    return C.pair_poses(*cfg, A0[0], A0[1])


def _rotate(poses, ang, shift=(0.0, 0.0)):
    out = np.array(poses, dtype=float)
    c, s = math.cos(ang), math.sin(ang)
    out[:, 0] = c * poses[:, 0] - s * poses[:, 1] + shift[0]
    out[:, 1] = s * poses[:, 0] + c * poses[:, 1] + shift[1]
    out[:, 2] = poses[:, 2] + ang
    return out


def _circ(a, b):
    return np.abs(np.angle(np.exp(1j * (a - b))))


def test_plate_friction_is_coulomb_and_isotropic():
    """A body sliding at v0 stops after ~v0^2 / (2 mu g); rotating the robot
    together with its velocity changes nothing (the plate has no axes)."""
    m = S.compile_model(S.build_mjcf(P, [(0, 0, 0, 0.0, 0.0)]))  # symmetric shape: no yaw torque
    d = mujoco.MjData(m)

    def slide(heading, ang):
        mujoco.mj_resetDataKeyframe(m, d, 0)
        d.qpos[3], d.qpos[6] = math.cos(heading / 2), math.sin(heading / 2)
        for _ in range(200):  # settle on the plate
            mujoco.mj_step(m, d)
        d.qvel[:] = 0
        d.qvel[0], d.qvel[1] = 0.2 * math.cos(ang), 0.2 * math.sin(ang)
        x0 = d.qpos[:2].copy()
        for _ in range(500):
            mujoco.mj_step(m, d)
        assert np.linalg.norm(d.qvel[:2]) < 1e-3
        return d.qpos[:2] - x0

    expected = 0.2 ** 2 / (2 * P.plate_friction * 9.81)
    for rel in (0.0, 0.7, 2.0):
        base = slide(0.0, rel)
        # Coulomb: about mu g deceleration (dt = 1 ms shortens it by up to
        # 8 % through small hops of the box; see docs/timestep.md)
        assert 0.9 * expected < np.linalg.norm(base) < 1.05 * expected
        for turn in (0.6, 2.2):
            moved = slide(turn, rel + turn)
            c, s = math.cos(-turn), math.sin(-turn)
            back = np.array([c * moved[0] - s * moved[1], s * moved[0] + c * moved[1]])
            np.testing.assert_allclose(back, base, atol=1e-9)


def _relative_after(poses, periods=1, gait=GAIT):
    return np.array(simulate(P, poses, gait, periods=periods).relative())


def test_rotating_the_scene_leaves_the_relative_history_unchanged():
    """Isotropic friction: a rigid rotation of a colliding pair's initial
    scene leaves (|r|, theta, phi) after the first period unchanged to 1e-6.

    One period only: collisions amplify round-off (measured: a 1 nm shift
    changes |r| by ~0.1 W within 3 periods), so later periods are compared
    in distribution, not point by point. A pyramidal friction cone fails
    this test by ~0.3 W."""
    poses = _pair()
    ref = simulate(P, poses, GAIT, periods=1)
    assert ref.touched.any(), "test pair must collide"
    for ang in (0.9, 2.5):
        got = _relative_after(_rotate(poses, ang, (0.05, -0.02)))
        want = np.array(ref.relative())
        np.testing.assert_allclose(got[0], want[0], atol=1e-6)
        assert _circ(got[1:], want[1:]).max() < 1e-6


def test_opposite_chirality_gives_the_mirror_image_pair():
    """Mirror x -> -x maps a robot (x, y, h, a1, a2) to (-x, y, -h, a2, a1) and
    a CCW gait to a CW one: the mirrored pair traces the mirrored path
    (first period, to round-off; see the rotation test for why one)."""
    poses = _pair()
    ccw = simulate(P, poses, GaitSpec(90.0, "ccw"), periods=1)
    mirror = np.stack([-poses[:, 0], poses[:, 1], -poses[:, 2], poses[:, 4], poses[:, 3]], -1)
    cw = simulate(P, mirror, GaitSpec(90.0, "cw"), periods=1)
    np.testing.assert_allclose(cw.poses[:, :, 0], -ccw.poses[:, :, 0], atol=1e-7)
    np.testing.assert_allclose(cw.poses[:, :, 1], ccw.poses[:, :, 1], atol=1e-7)
    assert _circ(cw.poses[:, :, 2], -ccw.poses[:, :, 2]).max() < 1e-6
    np.testing.assert_array_equal(cw.touched, ccw.touched)
    # the pair moved, so the check is not trivial; the same chirality does not mirror
    assert np.abs(ccw.poses[-1, :, :2] - ccw.poses[0, :, :2]).max() > 1e-3
    same = simulate(P, mirror, GaitSpec(90.0, "ccw"), periods=1)
    assert np.abs(same.poses[-1, :, 0] + ccw.poses[-1, :, 0]).max() > 1e-3


def test_single_robot_barely_drifts_at_90_degrees():
    """Paper: about 0.0015 W per gait cycle. The converged model drifts
    ~1e-5 W per cycle (docs/timestep.md): it lacks the servo noise and gait
    jitter of the lab robot, so the paper's figure is an upper bound here.
    Friction is what holds it: on a nearly frictionless plate (mu = 0.02) the
    same gait moves it far more."""
    res = simulate(P, [(0, 0, 0, A0[0], A0[1])], GAIT, periods=8)
    drift = np.linalg.norm(np.diff(res.poses[2:, 0, :2], axis=0), axis=1).mean() / W
    assert drift < 0.0015, drift
    slippery = simulate(P.replace(plate_friction=0.02), [(0, 0, 0, A0[0], A0[1])], GAIT, periods=4)
    slip = np.linalg.norm(np.diff(slippery.poses[2:, 0, :2], axis=0), axis=1).mean() / W
    assert slip > 10 * drift and slip > 1e-3, (slip, drift)


@pytest.mark.parametrize("amplitude", [90.0, 10.0])
def test_a_lone_robot_moves_the_same_at_the_default_step_and_a_quarter_of_it(amplitude):
    """The lone robot's drift per cycle is what the model is compared with
    (the lab's 1.5e-3 W per cycle), so the default step's error in it must
    be small against that: the drift at the default numerics differs from
    dt/4's by less than 1 % of the lab's value. A step that is too large
    fails this: at 4 dt the 10-degree robot creeps 2.6e-4 W per cycle where
    dt/4 gives 5e-6 (the arms' reaction impulses make the box slip on its
    soft contacts, docs/timestep.md), which the test checks as well so that
    its bound is known to tell a converged step from one that is not."""
    gait = GaitSpec(amplitude)
    a0 = gait.setpoints(0.0, SPEED)

    def drift(params):
        xy = simulate(params, [(0, 0, 0, a0[0], a0[1])], gait, periods=12).poses[2:, 0, :2]
        return np.linalg.norm(xy[-1] - xy[0]) / (len(xy) - 1) / params.robot.body_length

    model = presets.params()  # the default model's numerics
    bound = 0.01 * 1.5e-3
    d_fine = drift(model.replace(timestep=model.timestep / 4))
    assert abs(drift(model) - d_fine) < bound, (drift(model), d_fine)
    if amplitude == 10.0:
        assert abs(drift(model.replace(timestep=4 * model.timestep)) - d_fine) > bound


def test_arms_follow_the_gait_and_reach_the_corners():
    """At 90 deg the arms reach each commanded corner within 0.5 deg before
    the next move, and lag the moving setpoint by < 5 deg."""
    res = simulate(P, [(0, 0, 0, A0[0], A0[1])], GAIT, periods=2, track_stride=1)
    t = res.track_t
    want = GAIT.setpoints(t - P.timestep, SPEED)  # setpoint applied during the step
    got = res.track[:, 0, 3:5]
    err = np.degrees(np.abs(got - want))
    assert err.max() < 5.0
    T = GAIT.period()
    for q in range(8):
        k = np.argmin(np.abs(t - ((q + 1) * T / 4 - 2 * P.timestep)))
        assert err[k].max() < 0.5, (q, err[k])


def test_contacts_robot_robot_yes_arm_plate_and_self_never():
    """Step a colliding pair and inspect every contact MuJoCo makes."""
    poses = _pair()
    m = S.compile_model(S.build_mjcf(P, poses))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    lay = S.SceneLayout.of(m)
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(m.ngeom)]
    kinds = set()
    nsteps = int(2 * GAIT.period() / P.timestep)
    ctrl = np.asarray(G.setpoints_and_rates(P.timestep * np.arange(nsteps), GAIT.amplitude, GAIT.period(), SPEED))
    for k in range(nsteps):
        d.ctrl[:] = np.tile(ctrl[k], 2)
        mujoco.mj_step(m, d)
        for c in d.contact[:d.ncon]:
            g1, g2 = c.geom
            r1, r2 = lay.geom_robot[g1], lay.geom_robot[g2]
            assert not ("arm" in names[g1] and names[g2] == "plate") and not ("arm" in names[g2] and names[g1] == "plate")
            assert not (r1 >= 0 and r1 == r2), f"self-contact {names[g1]} {names[g2]}"
            if r1 >= 0 and r2 >= 0:
                kinds.add(tuple(sorted((names[g1].split("_")[1][:3], names[g2].split("_")[1][:3]))))
    assert ("arm", "arm") in kinds


@pytest.mark.parametrize("kind,poses", [
    ("body-body", [(0, 0, 0, 0, 0), (0, -(0.022 - 0.0005), 0, 0, 0)]),
    ("arm-arm", [(0, 0, 0, 0, 0), (0.050 + 2 * 0.054 - 0.0005, 0, 0, 0, 0)]),
    ("arm-body", [(0, 0, 0, 0, 0), (0.025 + 0.054 + 0.011 - 0.0005, 0, math.pi / 2, 0, 0)]),
])
def test_each_kind_of_robot_robot_contact_is_detected(kind, poses):
    m = S.compile_model(S.build_mjcf(P, poses))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(m.ngeom)]
    found = {tuple(sorted((names[c.geom[0]].split("_")[1][:3], names[c.geom[1]].split("_")[1][:3])))
             for c in d.contact[:d.ncon] if c.dist < 0 and "plate" not in (names[c.geom[0]], names[c.geom[1]])}
    a, b = kind.split("-")
    assert found == {tuple(sorted((a[:3], b[:3])))}


def test_records_touch_matches_contacts_and_separation():
    """Per-period touch flags agree with whether the pair ever came close."""
    res = simulate(P, _pair(), GAIT, periods=3)
    far = simulate(P, C.pair_poses(3.0, 0.5, 1.0, A0[0], A0[1]), GAIT, periods=2)
    assert res.touched.any() and np.isfinite(res.min_dist[res.touched]).all()
    assert not far.touched.any() and np.isinf(far.min_dist).all()


def test_overlapping_start_is_refused():
    with pytest.raises(ValueError, match="overlap"):
        simulate(P, C.pair_poses(0.2, 0.0, 0.0, A0[0], A0[1]), GAIT, periods=1)


def test_contact_forces_come_from_a_converged_solve():
    """An arm striking its neighbour's body is the stiffest event a pair sees:
    MuJoCo's Newton solver then needs up to ~25 line-search evaluations. With
    the scene's solver settings, every step of two colliding pairs' first
    period has the accelerations of a solve that cannot stop early (within
    0.1 % of the largest). The same census does catch a solver that stops
    early: capped at 10 evaluations (the setting before) the line search
    ends short, the solver takes the small improvement for convergence and
    some impacts come out wrong."""
    from smarticle_mjx.engine import Lanes, Scene
    from smarticle_mjx.engine.solver_check import solver_census

    poses = C.sample_valid_pairs(2, np.random.default_rng(7), (0.8, 2.0), A0[0], A0[1])
    lanes = Lanes.from_gait(poses, GAIT)
    nsteps = int(round(GAIT.period() / P.timestep))
    got = solver_census(Scene.build(P, 2), lanes, nsteps)
    assert got.multi_iteration_solves > 50, "the pairs must collide"
    assert got.unconverged == 0, got
    capped = solver_census(Scene.build(dataclasses.replace(P, ls_iterations=10), 2), lanes, nsteps)
    assert capped.unconverged > 0, capped


@pytest.mark.slow  # a solver census of ~3200 steps (90 s); benchmarks/solver_convergence.py measures it at scale
def test_mjx_contact_forces_are_converged_and_match_mujoco_at_impacts():
    """MJX's line search is a fixed-length scan, so the MJX backend caps it
    lower than MuJoCo C (it pays for every evaluation under vmap). At every
    state of a colliding pair's first half period where MuJoCo C needed more
    than one solver iteration (contact onsets, impacts), MJX with the
    backend's cap gives the accelerations of its own fully converged solve
    (within 0.1 % of the largest); a cap of 2 does not, so the census can
    fail. And MJX's converged accelerations are MuJoCo's: the two libraries'
    contact forces differ by more than 0.1 % at no more than 1 % of those
    states (float32 contacts within ~0.1 um of touching may switch)."""
    from smarticle_mjx.engine import Lanes, Scene
    from smarticle_mjx.engine.mjx import LS_ITERATIONS
    from smarticle_mjx.engine.solver_check import mjx_solver_census

    poses = C.sample_valid_pairs(1, np.random.default_rng(7), (0.8, 2.0), A0[0], A0[1])
    nsteps = int(round(GAIT.period() / P.timestep)) // 2
    got = mjx_solver_census(Scene.build(P, 2), Lanes.from_gait(poses, GAIT), nsteps, [LS_ITERATIONS, 2])
    assert got[LS_ITERATIONS].multi_iteration_solves > 50, "the pair must collide"
    assert got[LS_ITERATIONS].unconverged == 0, got[LS_ITERATIONS]
    assert got[2].unconverged > 0, got[2]
    assert got["vs_c"].unconverged <= 0.01 * got["vs_c"].multi_iteration_solves, got["vs_c"]


def _slip_per_arm_move(params, periods=4):
    """Mean displacement of a lone robot's body per quarter period (one arm move and its dwell), in W,
    after the first period."""
    from smarticle_mjx.reduce import transport
    res = simulate(params, [(0, 0, 0, A0[0], A0[1])], GAIT, periods=periods, track_stride=1)
    t = np.concatenate([[0.0], res.track_t])
    xy = np.concatenate([[[0.0, 0.0]], res.track[:, 0, :2]])
    T = res.track_t[-1] / periods
    idx = [int(np.argmin(np.abs(t - q * T / 4))) for q in range(4 * periods + 1)]
    return transport.lone_robot(xy[idx], samples_per_cycle=4, skip_cycles=1,
                                unit=params.robot.body_length).slip_per_edge_W


def test_an_implicit_step_slips_a_lone_robot_in_proportion_to_dt_times_the_servo_gain():
    """MuJoCo's implicit integrators solve the contacts with the mass matrix M, then advance the
    velocities with M + dt * kv on the arms' hinges (the servo's velocity gain, linearised): friction
    computed to hold the body no longer does, and each arm move slips the body by an amount that grows
    with dt * kv. RK4 takes the servo explicitly and has no such term. Facts checked: RK4's slip per arm
    move is the same at 1 ms and 0.25 ms (within 3 %); implicitfast at 0.5 ms slips more than 3x as
    much, and its excess over RK4 roughly doubles with kv doubled (1.6x to 2.5x)."""
    base = presets.params("lab-lag")
    rk4 = _slip_per_arm_move(base.replace(integrator="RK4", timestep=1e-3))
    rk4_fine = _slip_per_arm_move(base.replace(integrator="RK4", timestep=2.5e-4))
    assert abs(rk4 / rk4_fine - 1) < 0.03, (rk4, rk4_fine)
    implicit = _slip_per_arm_move(base.replace(integrator="implicitfast", timestep=5e-4))
    assert implicit > 3 * rk4_fine, (implicit, rk4_fine)
    stiffer = base.replace(integrator="implicitfast", timestep=5e-4,
                           robot=dataclasses.replace(base.robot, servo_kv=2 * base.robot.kv))
    ratio = (_slip_per_arm_move(stiffer) - rk4_fine) / (implicit - rk4_fine)
    assert 1.6 < ratio < 2.5, ratio


def test_an_explicit_integrator_is_refused_for_a_servo_it_would_misintegrate():
    """RK4 at 0.5 ms slips a lone robot with the stiff servo 0.1 W per arm move (implicitfast: 3.5e-3):
    timestep * kv / hinge inertia above 1 is refused in one line, below it accepted."""
    stiff = presets.params("lab-stiff")
    with pytest.raises(ValueError, match="takes the servo's velocity gain explicitly"):
        stiff.replace(integrator="RK4", timestep=1e-3).validate()
    stiff.replace(integrator="RK4", timestep=1e-4).validate()
    presets.params("lab-lag").replace(integrator="RK4", timestep=1e-3).validate()


@pytest.mark.parametrize("timeconst, speed", [(0.005, 0.05), (0.005, 1.2), (0.002, 1.2)])
def test_a_contacts_deepest_penetration_is_its_approach_speed_times_tau_over_e(timeconst, speed):
    """A critically damped linear contact (MuJoCo's solref with damping ratio 1, impedance held at its
    maximum) stopping a body that meets it at speed v penetrates v tau / e at its deepest, whatever the
    mass: the closed form the flag diagnosis (benchmarks/flag_diagnosis.py) reads impacts by."""
    h = timeconst / 80
    xml = f"""<mujoco><option timestep="{h}" gravity="0 0 0" integrator="implicitfast"/>
    <worldbody><geom type="plane" size="1 1 .1" solref="{timeconst} 1" solimp="0.99 0.99 0.001"/>
    <body pos="0 0 0.01"><freejoint/><geom type="sphere" size="0.01" mass="0.05" solref="{timeconst} 1"
    solimp="0.99 0.99 0.001"/></body></worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    d.qvel[2] = -speed
    deepest = 0.0
    for _ in range(int(3 * timeconst / h)):
        mujoco.mj_step(m, d)
        deepest = min(deepest, d.qpos[2] - 0.01)
    assert -deepest == pytest.approx(speed * timeconst / math.e, rel=0.02)


def test_a_crowd_with_gear_play_is_solved_without_kicks():
    """Seven robots with gear play (the `backlash` set), crowded from the relaxation's compressed start
    and out of step by s.d. 0.02 period, the combination that turned robots over. An arm in its play is
    driven by a servo turning at 8.7 rad/s and pushed by neighbours whose arms move as fast: it never
    crosses its play at 50 rad/s, and no robot leans 2 deg from upright, when the scene is solved as its
    default solver ("auto") solves it. With MuJoCo's Newton solver these three trials (seed 0) each
    tipped a robot within three periods on an unconverged solve of tens of newtons, an arm kicked through
    its play at 100-2000 rad/s (benchmarks/play_probe.py; docs/relax.md, "The solver, not the play")."""
    from smarticle_mjx.engine import Scene
    from smarticle_mjx.engine.core import SceneLayout, on_step_grid
    from smarticle_mjx.engine.native import step_lane
    from smarticle_mjx.relax import start_poses, trial_lanes
    from smarticle_mjx.specs import RelaxConfig

    config = RelaxConfig(trials=16, periods=3, imperfections="backlash", phase_jitter=0.02)
    params = config.robots().scene(presets.params("lab-lag"))
    assert params.solver == "auto" and params.constraint_solver(config.n_robots) == ("CG", 100)
    starts, phase = start_poses(config, params)
    xml = Scene.mjcf(params, config.n_robots, False)
    m = S.compile_model(xml)
    scene = Scene(params, m, SceneLayout.of(m), xml, False)
    bodies = [m.geom(f"r{i}_body").bodyid[0] for i in range(config.n_robots)]
    play = [m.jnt_dofadr[j] for j in range(m.njnt) if m.joint(j).name.endswith(("_k1", "_k2"))]
    assert len(play) == 2 * config.n_robots
    for trial in (1, 3, 15):
        # as the Newton tips were measured: clocks started at t = 0 at their offsets (up to version 0.4.0)
        lanes = on_step_grid(trial_lanes(config, starts[trial], phase[trial], [trial], start_delays=False),
                             m.opt.timestep)
        tilt, speed = 0.0, 0.0
        for _, _, d in step_lane(scene, lanes, 3):
            speed = max(speed, float(np.abs(d.qvel[play]).max()))
            tilt = max(tilt, float(np.degrees(np.arccos(np.clip(d.xmat[bodies, 8].min(), -1, 1)))))
        assert speed < 50.0, (trial, speed)
        assert tilt < 2.0, (trial, tilt)


def _robot_bounce(robot_dampratio, drop=False):
    """Two lab-lag robots, arms straight, side by side 24.5 mm apart: robot 1 thrown at robot 0 at
    0.3 m/s (returns the largest separating speed after the hit, over the approach speed), or both
    dropped 2 mm onto the plate, apart (returns the largest upward speed after landing)."""
    from smarticle_mjx.engine import Scene
    params = presets.params()
    if robot_dampratio is not None:
        params = dataclasses.replace(params, robot_dampratio=robot_dampratio)
    scene = Scene.build(params, 2)
    m, d = scene.model, mujoco.MjData(scene.model)
    d.qpos[:] = scene.qpos_from_poses(np.array([[0, 0, 0, 0, 0], [0, 0.0245, 0, 0, 0]], float))
    a0, a1 = scene.layout.free_qpos
    dof = {int(m.jnt_qposadr[j]): int(m.jnt_dofadr[j]) for j in range(m.njnt)}
    if drop:
        d.qpos[a1 + 1] = 0.3
        d.qpos[[a0 + 2, a1 + 2]] += 0.002
    else:
        d.qvel[dof[a1] + 1] = -0.3
    out = []
    for _ in range(int(0.05 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        out.append(d.qvel[dof[a0] + 2] if drop else d.qvel[dof[a1] + 1] - d.qvel[dof[a0] + 1])
    return max(out) if drop else max(out) / 0.3


def test_robots_bounce_off_each_other_by_their_damping_ratio_and_not_off_the_plate():
    """Contacts between robots take robot_dampratio and bounce more the less they are damped: a linear
    contact of damping ratio z returns e = exp(-pi z / sqrt(1 - z^2)) of the approach speed (0.73 at
    z = 0.1; the robots' servo-held arms add a little of their own). Contacts with the plate keep
    contact_dampratio: MuJoCo's own contact parameters say so, and a robot dropped onto the plate
    lands the same whatever the robots' damping ratio."""
    from smarticle_mjx.engine import Scene
    scene = Scene.build(dataclasses.replace(presets.params(), robot_dampratio=0.1), 2)
    m, d = scene.model, mujoco.MjData(scene.model)
    d.qpos[:] = scene.qpos_from_poses(np.array([[0, 0, 0, 0, 0], [0, 0.0215, 0, 0, 0]], float))
    mujoco.mj_forward(m, d)
    kinds = {}
    for c in d.contact[:d.ncon]:
        plate = m.geom(c.geom1).name == "plate" or m.geom(c.geom2).name == "plate"
        kinds.setdefault(plate, set()).add(tuple(np.round(c.solref, 9)))
    assert kinds == {True: {(0.005, 1.0)}, False: {(0.005, 0.1)}}, kinds
    e = {z: _robot_bounce(z) for z in (None, 0.3, 0.1, 0.05)}
    assert e[None] < e[0.3] < e[0.1] < e[0.05], e
    assert e[0.1] == pytest.approx(math.exp(-math.pi * 0.1 / math.sqrt(1 - 0.01)), abs=0.1), e
    assert _robot_bounce(0.05, drop=True) == pytest.approx(_robot_bounce(None, drop=True), abs=1e-9)
    with pytest.raises(ValueError, match="robot_dampratio must be a positive number"):
        dataclasses.replace(presets.params(), robot_dampratio=0.0).validate()


def test_the_discrete_integrator_slips_a_lone_robot_as_the_explicit_servo_does_at_the_default_step():
    """MuJoCo's discrete integrator solves the constraints together with the implicit velocity update, so
    the friction that holds the body holds it through the servo's damping too: its slip per arm move at
    the default step is RK4's (whose servo is explicit, with no such term) within 5 %, where implicitfast at
    the same step slips more than twice as much. The calibration's model runs it (calibrate.data.NUMERICS)."""
    base = presets.params("lab-lag")
    dt = base.timestep
    rk4 = _slip_per_arm_move(base.replace(integrator="RK4", timestep=dt))
    discrete = _slip_per_arm_move(base.replace(integrator="discrete", timestep=dt))
    implicit = _slip_per_arm_move(base.replace(integrator="implicitfast", timestep=dt))
    assert abs(discrete / rk4 - 1) < 0.05, (discrete, rk4)
    assert implicit > 2 * rk4, (implicit, rk4)
