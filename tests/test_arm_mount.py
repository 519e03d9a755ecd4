"""Arms with a mount near the hinge (RobotParams.arm_mount_length / arm_mount_width), as the lab's CAD arm
part has one: the planar overlap test, the scene's geoms, the collision record and the refusals."""

import math

import mujoco
import numpy as np
import pytest
from mjgap import mujoco_gap

from smarticle_mjx import configs as C
from smarticle_mjx import presets
from smarticle_mjx import scene as S

# the lab CAD part's mount (docs/relax.md): 6.75 mm wide, reaching 26.6 mm from the hinge
CAD = dict(arm_mount_length=0.0266, arm_mount_width=0.00675)


def _params(**robot):
    p = presets.params("lab")
    return p.replace(robot=S.dataclasses.replace(p.robot, **robot))


def test_the_planar_gap_with_mounts_is_mujocos_own_distance():
    """configs.pair_separation with mounts equals MuJoCo's distance between the compiled geoms (an
    independent computation: its own box-box query) for random pairs near contact, to 1e-6 m where
    they are apart; and the mounts matter: on those poses the gap without them differs somewhere."""
    params = _params(**CAD)
    bare = _params()
    rng = np.random.default_rng(7)
    differs = 0
    for _ in range(40):
        a = rng.uniform(-math.pi / 2, math.pi / 2, 4)
        r = rng.uniform(0.04, 0.09)
        ang = rng.uniform(0, 2 * math.pi)
        p1 = (0.0, 0.0, rng.uniform(0, 2 * math.pi), a[0], a[1])
        p2 = (r * math.cos(ang), r * math.sin(ang), rng.uniform(0, 2 * math.pi), a[2], a[3])
        ours = float(C.pair_separation(np.array(p1), np.array(p2), params.robot))
        theirs = mujoco_gap(params, [p1, p2])
        if theirs > 1e-4:
            assert ours == pytest.approx(theirs, abs=1e-6)
        else:
            assert ours <= 1e-6  # touching or overlapping in both
        differs += abs(ours - float(C.pair_separation(np.array(p1), np.array(p2), bare.robot))) > 1e-4
    assert differs >= 3


def test_a_mount_is_a_massless_box_of_the_arm_at_the_hinge():
    """The scene adds one box per arm on the arm's body, from the hinge to arm_mount_length, as tall as
    the arm; the robot's mass and the hinges' inertia are unchanged (the part's mass is the arm's)."""
    with_m, bare = _params(**CAD), _params()
    pose = [(0.0, 0.0, 0.0, 0.3, -0.4)]
    m = S.compile_model(S.build_mjcf(with_m, pose))
    m0 = S.compile_model(S.build_mjcf(bare, pose))
    assert m.ngeom == m0.ngeom + 2
    for k in (1, 2):
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"r0_arm{k}_mount")
        arm = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"r0_arm{k}")
        assert m.geom_bodyid[g] == m.geom_bodyid[arm]
        assert m.geom_size[g] == pytest.approx([0.0133, 0.003375, with_m.robot.arm_extent_z / 2])
        assert abs(m.geom_pos[g][0]) == pytest.approx(0.0133)
    assert m.body_subtreemass[1] == pytest.approx(m0.body_subtreemass[1])
    assert np.allclose(m.body_inertia, m0.body_inertia)
    assert S.SceneLayout.of(m).geom_robot.tolist().count(0) == 5


def test_a_body_pressed_on_a_mount_alone_is_an_arm_contact_in_the_collision_record():
    """Robot 1's body pushed into robot 0's arm-1 mount where the arm's plate is not: MuJoCo finds the
    contact, and the collision record's sensors count it as body-on-arm1 (they match the arm's body,
    so its mount counts as the arm), with the force pushing robot 0 away from robot 1."""
    from smarticle_mjx.engine.core import Scene
    params = _params(**CAD)
    rp = params.robot
    # robot 0 at the origin, arm 1 straight out along -x; robot 1 across it (heading 90 deg, its arms
    # folded away along -x), the end of its body beside the mount, sunk 0.5 mm into the mount's side (the
    # plate is 3.2 mm thick, the mount 6.75: the plate's side lies 1.3 mm from robot 1)
    hx = rp.hinge_x
    y1 = rp.arm_mount_width / 2 + rp.body_length / 2 - 0.0005
    half_pi = math.pi / 2
    poses = [(0.0, 0.0, 0.0, 0.0, 0.0), (-hx - 0.020, y1, half_pi, half_pi, half_pi)]
    assert float(C.pair_separation(np.array(poses[0]), np.array(poses[1]), _params().robot)) > 0.0005
    assert float(C.pair_separation(np.array(poses[0]), np.array(poses[1]), rp)) <= 0
    xml = Scene.mjcf(params, 2, collisions=True)
    m = S.compile_model(xml)
    d = mujoco.MjData(m)
    mujoco.mj_resetData(m, d)
    lay = S.SceneLayout.of(m)
    for i, (x, y, h, a1, a2) in enumerate(poses):
        q = lay.free_qpos[i]
        d.qpos[q:q + 7] = [x, y, rp.body_height / 2, math.cos(h / 2), 0, 0, math.sin(h / 2)]
        d.qpos[lay.arm_qpos[i]] = [a1, a2]
    mujoco.mj_forward(m, d)

    def sensor(name):
        s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SENSOR, name)
        return d.sensordata[m.sensor_adr[s]:m.sensor_adr[s] + m.sensor_dim[s]]

    hit = sensor("coll_0_1_arm1_body")
    assert hit[0] > 0 and hit[2] < 0  # found; robot 1 (at +y) pushes robot 0's arm toward -y
    for other in ("coll_0_1_body_body", "coll_0_1_arm2_body", "coll_0_1_arm1_arm1"):
        assert sensor(other)[0] == 0


@pytest.mark.parametrize("fields, message", [
    (dict(arm_mount_length=0.06, arm_mount_width=0.007), "must not exceed the arm"),
    (dict(arm_mount_length=0.02, arm_mount_width=0.003), "must exceed the arm's thickness"),
    (dict(arm_mount_width=0.007), "needs robot.arm_mount_length"),
    (dict(arm_mount_length=-0.01), ">= 0"),
])
def test_a_bad_mount_is_refused_in_one_line(fields, message):
    with pytest.raises(ValueError, match=message):
        _params(**fields).validate()


def test_backends_without_mounts_refuse_them_in_one_line():
    """The MJX, Warp and DART backends do not build mounts: one line each, before any model is built."""
    from smarticle_mjx.engine.core import refuse_mounts
    from smarticle_mjx.engine.dart import DartNumerics, check_model
    params = _params(**CAD).replace(robot=S.dataclasses.replace(_params(**CAD).robot, servo_armature=0.0))
    for backend in ("mjx", "warp"):
        with pytest.raises(ValueError, match=f"run on the native backend, not {backend}"):
            refuse_mounts(params, backend)
    refuse_mounts(_params(), "mjx")  # no mount: nothing to refuse
    with pytest.raises(ValueError, match="arms with mounts"):
        check_model(params, DartNumerics())


def test_a_store_made_before_mounts_reads_back_without_them():
    """A recorded scene that predates the mount fields (no keys for them) reads back with no mount, and a
    recorded mount reads back as recorded."""
    import json
    d = json.loads(json.dumps(S.params_json(_params())))
    for k in ("arm_mount_length", "arm_mount_width"):
        del d["robot"][k]
    assert not S.params_from_json(d).robot.has_mount
    back = S.params_from_json(json.loads(json.dumps(S.params_json(_params(**CAD)))))
    assert back.robot.arm_mount_length == CAD["arm_mount_length"] and back.robot.has_mount
