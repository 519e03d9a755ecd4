"""Generated scenes: parameters, collision filtering, stored reference models."""

import pathlib

import mujoco
import numpy as np
import pytest

from smarticle_mjx import presets
from smarticle_mjx import scene as S

MODELS = pathlib.Path(__file__).resolve().parents[1] / "models"


def test_reference_models_are_up_to_date():
    """models/*.xml are generated; a change to the generator must regenerate them (smx models)."""
    for name, xml in S.reference_models(presets.params()).items():
        stored = (MODELS / name).read_text()
        assert stored == xml, f"models/{name} is stale: run `smx models`"


def test_default_robot_mass_and_geometry():
    """models/ holds the default preset: the paper's measured mass, the lab
    code's 5.4 cm body (D 2.2 cm from the paper, 2.5 cm tall, chosen)."""
    m = S.compile_model((MODELS / "single.xml").read_text())
    total = sum(m.body_mass[1:])
    assert total == pytest.approx(0.0348, rel=1e-9)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "r0_body")
    np.testing.assert_allclose(2 * m.geom_size[body], [0.054, 0.022, 0.025])
    assert m.nu == 4 and m.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC  # per arm: setpoint + rate


def _can_collide(m, g1, g2):
    return bool((m.geom_contype[g1] & m.geom_conaffinity[g2]) or (m.geom_contype[g2] & m.geom_conaffinity[g1]))


def test_collision_filter_arms_never_touch_plate_robots_touch_each_other():
    m = S.compile_model((MODELS / "pair.xml").read_text())
    gid = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g): g for g in range(m.ngeom)}
    plate = gid["plate"]
    for i in (0, 1):
        assert _can_collide(m, plate, gid[f"r{i}_body"])
        for k in (1, 2):
            assert not _can_collide(m, plate, gid[f"r{i}_arm{k}"]), "arms must never touch the plate"
    for a in ("body", "arm1", "arm2"):
        for b in ("body", "arm1", "arm2"):
            assert _can_collide(m, gid[f"r0_{a}"], gid[f"r1_{b}"]), (a, b)
    # arms rest above the plate
    assert m.geom_pos[gid["r0_arm1"]][2] == 0  # in the arm frame; height from the body:
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    assert d.geom_xpos[gid["r0_arm1"]][2] - S.RobotParams().arm_radius >= S.RobotParams().arm_clearance - 1e-9


def test_bad_parameters_are_refused_with_a_clear_message():
    with pytest.raises(ValueError, match="timestep"):
        S.SceneParams(timestep=-1).validate()
    with pytest.raises(ValueError, match="contact_timeconst"):
        S.SceneParams(timestep=0.01).validate()
    with pytest.raises(ValueError, match="arms must start below the body's top"):
        S.SceneParams(robot=S.RobotParams(arm_clearance=0.03)).validate()
    with pytest.raises(ValueError, match="pose"):
        S.build_mjcf(S.SceneParams(), [(0, 0, 0, 0)])
    with pytest.raises(ValueError, match="hinge limit"):
        S.build_mjcf(S.SceneParams(), [(0, 0, 0, 3.0, 0)])
    with pytest.raises(ValueError, match="integrator must be one of"):
        S.SceneParams(integrator="verlet").validate()


def test_arm_plates_may_reach_above_the_body_as_the_lab_arms_do():
    """The lab's arm plates (about 31 mm) are taller than its body (about 26 mm): a plate arm of 31 mm on a
    25 mm body stands from its clearance to above the body's top, and its mass and its inertia about the
    vertical hinge are the shorter plate's (height does not enter a rotation about the hinge axis)."""
    import dataclasses
    lab = dataclasses.replace(S.RobotParams(), arm_shape="plate", arm_thickness=0.0029, arm_clearance=0.0005)
    out = {}
    for h in (0.024, 0.031):
        p = S.SceneParams(robot=dataclasses.replace(lab, arm_height=h))
        m = S.compile_model(S.build_mjcf(p, [(0, 0, 0, 0, 0)]))
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        mujoco.mj_forward(m, d)
        arm = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "r0_arm1")
        bottom, top = d.geom_xpos[arm][2] - m.geom_size[arm][2], d.geom_xpos[arm][2] + m.geom_size[arm][2]
        assert bottom == pytest.approx(0.0005, abs=1e-9) and top == pytest.approx(0.0005 + h, abs=1e-9)
        hinge = m.geom_bodyid[arm]
        out[h] = (m.body_mass[hinge], m.body_inertia[hinge][2])
    assert 0.0005 + 0.031 > S.RobotParams().body_height
    assert out[0.031] == pytest.approx(out[0.024], rel=1e-12)


def test_every_integrator_reaches_the_compiled_model():
    """The integrator is a numerics choice (docs/timestep.md): each MJCF name must compile to MuJoCo's enum."""
    want = {"implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST, "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
            "Euler": mujoco.mjtIntegrator.mjINT_EULER, "RK4": mujoco.mjtIntegrator.mjINT_RK4,
            "discrete": mujoco.mjtIntegrator.mjINT_DISCRETE}
    assert set(want) == set(S.INTEGRATORS)
    for name, enum in want.items():
        p = S.SceneParams(integrator=name)
        m = mujoco.MjModel.from_xml_string(S.build_mjcf(p, [(0, 0, 0, 1.0, 1.0)]))
        assert m.opt.integrator == enum, name


def test_boundary_wall_is_optional_and_collides_with_robots():
    m = S.compile_model(S.build_mjcf(S.SceneParams(boundary_radius=0.3), S.standard_poses("single")))
    walls = [g for g in range(m.ngeom) if (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "").startswith("wall")]
    assert len(walls) == 48
    arm = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "r0_arm1")
    assert _can_collide(m, walls[0], arm)


# ------------------------------------------------------------ plate departures (calibration effects)

def _rest(params, steps=2000):
    import mujoco
    from smarticle_mjx.scene import build_mjcf, compile_model
    m = compile_model(build_mjcf(params, [(0, 0, 0, 1.5708, 1.5708)]))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    d.ctrl[:] = m.key_ctrl[0]
    for _ in range(steps):
        mujoco.mj_step(m, d)
    return m, d


def test_tilted_plate_holds_below_the_friction_angle_and_slides_above():
    from smarticle_mjx.scene import SceneParams
    # friction angle atan(0.37) = 20.3 deg
    _, d = _rest(SceneParams(plate_tilt_deg=(10.0, 0.0)))
    assert abs(d.qpos[0]) < 1e-4
    _, d = _rest(SceneParams(plate_tilt_deg=(30.0, 0.0)))
    assert d.qpos[0] > 0.01 and abs(d.qpos[1]) < 0.1 * d.qpos[0]   # downhill is +x


def test_anisotropic_plate_slides_only_along_its_slippery_axis():
    from smarticle_mjx.scene import SceneParams
    # mu_x = 0.37 holds a 10 deg slope; mu_y = 0.37 * 0.2 = 0.074 < tan(10 deg) = 0.176 does not.
    # (MuJoCo's soft friction lets a held body creep; anisotropic cones creep more, ~3 mm in 0.5 s here.)
    _, d = _rest(SceneParams(plate_friction_y_ratio=0.2, plate_tilt_deg=(10.0, 0.0)))
    held = abs(d.qpos[0])
    _, d = _rest(SceneParams(plate_friction_y_ratio=0.2, plate_tilt_deg=(0.0, 10.0)))
    assert d.qpos[1] > 0.05 and d.qpos[1] > 10 * held


def test_arms_on_the_plate_touch_it_only_when_asked():
    import dataclasses
    from smarticle_mjx.scene import RobotParams, SceneParams
    on = SceneParams(robot=dataclasses.replace(RobotParams(), arm_clearance=0.0), arm_plate_friction=0.3)
    m, d = _rest(on, 200)
    arm_geoms = {m.geom(f"r0_arm{k}").id for k in (1, 2)}
    plate = m.geom("plate").id
    touching = [c for c in d.contact[:d.ncon] if {c.geom1, c.geom2} & arm_geoms and plate in (c.geom1, c.geom2)]
    assert touching
    m, d = _rest(SceneParams(), 200)
    assert not any({c.geom1, c.geom2} & arm_geoms and plate in (c.geom1, c.geom2) for c in d.contact[:d.ncon])


def test_raised_arms_meet_the_plate_only_when_their_robot_leans():
    """With arm-plate contacts and the arms' 5 mm clearance (the default robot), an upright robot's arms
    never touch the plate; a robot leaning 8 deg about its long axis toward its arms, held out sideways
    (90 deg, a U, reaching 1-5 cm from that axis), brings them below the plate's surface and they meet it.
    Without arm-plate contacts the arms pass through it."""
    import math
    from smarticle_mjx.scene import SceneParams
    for mu, expect in ((0.37, True), (0.0, False)):
        p = SceneParams(arm_plate_friction=mu)
        m = S.compile_model(S.build_mjcf(p, [(0, 0, 0, math.pi / 2, math.pi / 2)]))
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        arm_geoms = {m.geom(f"r0_arm{k}").id for k in (1, 2)}
        plate = m.geom("plate").id

        def arm_plate(d):
            return [c for c in d.contact[:d.ncon] if {c.geom1, c.geom2} & arm_geoms and plate in (c.geom1, c.geom2)]
        mujoco.mj_forward(m, d)
        assert not arm_plate(d)  # upright
        lean = -math.radians(8.0)  # about the body's long axis (x), toward +y where both arms point (a U)
        d.qpos[3:7] = [math.cos(lean / 2), math.sin(lean / 2), 0, 0]
        d.qpos[2] = S.RobotParams().body_thickness / 2 * math.sin(-lean) + S.RobotParams().body_height / 2 * math.cos(lean)
        mujoco.mj_forward(m, d)
        assert bool(arm_plate(d)) == expect


def test_friction_inside_the_gears_play_holds_an_arm_against_a_smaller_torque():
    """Coulomb friction in the free play (robot.backlash_friction): a lone robot's arm in +-2 deg of play,
    its servo holding, pushed for 50 ms by a torque on the play alone. Without friction (the presets) half
    of 5 mN m swings it to the stop (2 deg); with 5 mN m of friction the same push moves it by under
    0.01 deg, and twice the friction still swings it to the stop. Off (0) writes no friction at all."""
    import dataclasses

    def swing(friction, torque):
        p = presets.params(None)
        p = dataclasses.replace(p, robot=dataclasses.replace(p.robot, backlash_deg=2.0, backlash_friction=friction))
        m = S.compile_model(S.build_mjcf(p, S.standard_poses("single")))
        d = mujoco.MjData(m)
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "r0_k2")
        for _ in range(int(0.05 / m.opt.timestep)):
            d.qfrc_applied[m.jnt_dofadr[j]] = torque
            mujoco.mj_step(m, d)
        return float(np.degrees(d.qpos[m.jnt_qposadr[j]])), float(m.dof_frictionloss[m.jnt_dofadr[j]])

    assert swing(0.0, 0.0025) == (pytest.approx(2.0, abs=0.02), 0.0)
    held, loss = swing(0.005, 0.0025)
    assert abs(held) < 0.01 and loss == 0.005
    assert swing(0.005, 0.01)[0] == pytest.approx(2.0, abs=0.02)
    with pytest.raises(ValueError, match="backlash_friction"):
        S.RobotParams(backlash_friction=-0.001).validate()


def test_compliant_gear_teeth_let_a_pushed_arm_past_its_stop_and_none_keeps_rigid_teeth():
    """robot.backlash_stop_timeconst: the gear stops at the ends of the play as a soft constraint of that
    time constant. An arm in +-2 deg of play, its servo holding, pushed against its stop for 50 ms by a
    constant torque on the play: a soft constraint's static deflection grows with the square of its time
    constant, so 5 ms teeth let it go well past the stop (more than 10x as far as the presets' rigid
    teeth, 2 dt), yet under 0.1 deg for 2.5 mN m. None (the presets) writes exactly the scene it did."""
    import dataclasses

    def scene(stop):
        p = presets.params(None)
        return dataclasses.replace(p, robot=dataclasses.replace(p.robot, backlash_deg=2.0,
                                                                backlash_stop_timeconst=stop))

    def past(stop, torque=0.0025):
        m = S.compile_model(S.build_mjcf(scene(stop), S.standard_poses("single")))
        d = mujoco.MjData(m)
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "r0_k2")
        for _ in range(int(0.05 / m.opt.timestep)):
            d.qfrc_applied[m.jnt_dofadr[j]] = torque
            mujoco.mj_step(m, d)
        return float(np.degrees(d.qpos[m.jnt_qposadr[j]])) - 2.0

    rigid, soft = past(None), past(0.005)
    assert 0 < soft < 0.1
    assert soft > 10 * max(rigid, 1e-9)
    p0 = presets.params(None)
    p0 = dataclasses.replace(p0, robot=dataclasses.replace(p0.robot, backlash_deg=2.0))
    assert S.build_mjcf(scene(None), S.standard_poses("single")) == S.build_mjcf(p0, S.standard_poses("single"))
    for bad in (0.0, -0.001, 0.5):
        with pytest.raises(ValueError, match="backlash_stop_timeconst"):
            S.RobotParams(backlash_stop_timeconst=bad).validate()
