"""Generated scenes: parameters, collision filtering, stored reference models."""

import pathlib

import mujoco
import numpy as np
import pytest

from smarticle_mjx import scene as S

MODELS = pathlib.Path(__file__).resolve().parents[1] / "models"


def test_reference_models_are_up_to_date():
    """models/*.xml are generated; a change to the generator must regenerate them (smx models)."""
    for name, xml in S.reference_models().items():
        stored = (MODELS / name).read_text()
        assert stored == xml, f"models/{name} is stale: run `smx models`"


def test_paper_robot_mass_and_geometry():
    m = S.compile_model((MODELS / "single.xml").read_text())
    total = sum(m.body_mass[1:])
    assert total == pytest.approx(0.0348, rel=1e-9)
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "r0_body")
    np.testing.assert_allclose(2 * m.geom_size[body], [0.050, 0.022, 0.025])
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
    with pytest.raises(ValueError, match="arms must lie within"):
        S.SceneParams(robot=S.RobotParams(arm_clearance=0.03)).validate()
    with pytest.raises(ValueError, match="pose"):
        S.build_mjcf(S.SceneParams(), [(0, 0, 0, 0)])
    with pytest.raises(ValueError, match="hinge limit"):
        S.build_mjcf(S.SceneParams(), [(0, 0, 0, 3.0, 0)])


def test_boundary_wall_is_optional_and_collides_with_robots():
    m = S.compile_model(S.build_mjcf(S.SceneParams(boundary_radius=0.3), S.standard_poses("single")))
    walls = [g for g in range(m.ngeom) if (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "").startswith("wall")]
    assert len(walls) == 48
    arm = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "r0_arm1")
    assert _can_collide(m, walls[0], arm)
