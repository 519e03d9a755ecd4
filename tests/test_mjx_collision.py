"""smarticle_mjx's capsule–box (arm against body) and capsule–capsule (arm against arm) colliders for MJX."""

import jax
import mujoco
import numpy as np
import pytest

from smarticle_mjx.engine import mjx_collision as mc
from smarticle_mjx.engine.core import Scene
from smarticle_mjx.scene import SceneParams

BOX = np.array([0.025, 0.011, 0.0125])  # the robot body's half-sizes
R, H = 0.0015, 0.02625                  # arm radius and half-length
contacts = jax.jit(mc.capsule_box_contacts)


def _capsule_along(direction, centre):
    """Capsule frame whose z axis (the capsule axis) is ``direction``."""
    z = np.asarray(direction, float) / np.linalg.norm(direction)
    x = np.cross([0.0, 0.0, 1.0], z) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    mat = np.stack([x, np.cross(z, x), z], axis=1)
    return np.asarray(centre, float), mat, np.array([R, H, 0.0])


def _run(centre, direction, box_pos=np.zeros(3), box_mat=np.eye(3)):
    pos, mat, size = _capsule_along(direction, centre)
    d, p, n = contacts(pos, mat, size, box_pos, box_mat, BOX)
    return np.asarray(d), np.asarray(p), np.asarray(n)


def test_arm_lying_along_a_face_gets_two_separate_contacts_at_the_true_depth():
    """An arm parallel to the +y face, 0.4 mm into it, presses along its
    length: two contacts far apart, each 0.4 mm deep, pushing along +y
    (normal from capsule to box is -y, to 1 mrad: the depth is flat along the
    face, so in float32 a contact may sit at the face's end, where the
    52.5 mm arm overhangs the 50 mm body)."""
    d, p, n = _run([0.0, BOX[1] + R - 0.0004, 0.0], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(d, -0.0004, atol=1e-7)
    assert abs(p[0, 0] - p[1, 0]) > 0.02 and np.abs(p[:, 0]).max() <= BOX[0] + 1e-6
    np.testing.assert_allclose(n, [[0, -1, 0], [0, -1, 0]], atol=1e-3)


def test_corner_touch_is_one_contact_at_the_distance_to_the_edge():
    """An arm crossing the body's vertical edge at (+x, +y) diagonally, its
    axis 1.0 mm from the edge: the nearest body point is on the edge, so the
    contact is 0.5 mm deep (radius 1.5 mm minus 1.0 mm), pushes along the
    diagonal, and there is no second one."""
    gap = R - 0.0005                                  # axis 1.0 mm from the edge: 0.5 mm deep
    corner = np.array([BOX[0], BOX[1], 0.0])
    out = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    d, p, n = _run(corner + out * gap, [1.0, -1.0, 0.0])
    assert d[0] == pytest.approx(gap - R, abs=1e-7)
    assert d[1] > 0, "a corner touch is counted once"
    np.testing.assert_allclose(n[0], -out, atol=1e-5)


def test_separated_arm_reports_its_gap_and_no_contact():
    d, _, _ = _run([0.0, BOX[1] + R + 0.002, 0.0], [1.0, 0.0, 0.0])
    assert d.min() == pytest.approx(0.002, abs=1e-7)


def _brute(cap_pos, cap_mat, box_pos, box_mat):
    t = np.linspace(-1, 1, 20001)[:, None]
    x = (cap_pos + t * H * cap_mat[:, 2] - box_pos) @ box_mat
    q = np.abs(x) - BOX
    return (np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(1), 0)).min() - R


def _random_pair_poses(rng, r_min: float, r_max: float) -> np.ndarray:
    """Robot 1 at the origin, robot 2 at a random distance in [r_min, r_max] (m)
    and direction; random headings and arm angles within +-90 deg."""
    poses = np.zeros((2, 5))
    ang = rng.uniform(-np.pi, np.pi)
    poses[1, :2] = rng.uniform(r_min, r_max) * np.array([np.cos(ang), np.sin(ang)])
    poses[:, 2] = rng.uniform(-np.pi, np.pi, 2)
    poses[:, 3:] = rng.uniform(-np.pi / 2, np.pi / 2, (2, 2))
    return poses


def test_random_near_contact_poses_match_brute_force_and_mujoco():
    """Over random arm-vs-body poses of the pair scene near contact, the
    deepest distance equals a brute-force one (20001 points along the axis)
    within 0.01 mm, and MuJoCo's own collision within 0.01 mm."""
    scene = Scene.build(SceneParams(), 2)
    m = scene.model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    box = next(g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX)
    root = m.body_rootid
    caps = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE
            and root[m.geom_bodyid[g]] != root[m.geom_bodyid[box]]]
    assert len(caps) == 2
    checked = 0
    for _ in range(4000):
        d.qpos[:] = scene.qpos_from_poses(_random_pair_poses(rng, 0.02, 0.07)[None])[0]
        mujoco.mj_kinematics(m, d)
        for cap in caps:
            args = (d.geom_xpos[cap], d.geom_xmat[cap].reshape(3, 3), d.geom_xpos[box], d.geom_xmat[box].reshape(3, 3))
            truth = _brute(*args)
            if abs(truth) > 0.001:
                continue
            dist = float(np.asarray(contacts(args[0], args[1], m.geom_size[cap], args[2], args[3], BOX)[0]).min())
            assert dist == pytest.approx(truth, abs=1e-5)
            ft = np.zeros(6)
            assert mujoco.mj_geomDistance(m, d, cap, box, 0.01, ft) == pytest.approx(truth, abs=1e-5)
            checked += 1
    assert checked >= 20


def _arm_arm_contacts(n_poses: int, seed: int):
    """MuJoCo C's arm-arm contacts of the pair scene over random poses:
    (capsule 1 pos, mat, size, capsule 2 pos, mat, size, C's dist, C's normal)."""
    scene = Scene.build(SceneParams(), 2)
    m = scene.model
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    capsule = m.geom_type == mujoco.mjtGeom.mjGEOM_CAPSULE
    out = []
    for _ in range(n_poses):
        d.qpos[:] = scene.qpos_from_poses(_random_pair_poses(rng, 0.03, 0.08)[None])[0]
        mujoco.mj_forward(m, d)
        for c in d.contact[:d.ncon]:
            g1, g2 = c.geom
            if capsule[g1] and capsule[g2]:
                out.append((d.geom_xpos[g1].copy(), d.geom_xmat[g1].reshape(3, 3).copy(), m.geom_size[g1].copy(),
                            d.geom_xpos[g2].copy(), d.geom_xmat[g2].reshape(3, 3).copy(), m.geom_size[g2].copy(),
                            float(c.dist), c.frame[:3].copy()))
    return out


def test_arm_arm_contacts_match_mujoco_where_mjx_tilts_the_normal():
    """Two arms (capsules, 1.5 mm radius, 52.5 mm axis) touching: smarticle_mjx's
    contact has MuJoCo's depth (within 1 µm) and MuJoCo's normal (within
    0.1 mrad), so the contact force points the same way. MJX's own closest-
    point routine divides by |ab|^2 + 1e-6 with |ab|^2 = 2.8e-3, which shifts
    the closest point along the arm by up to ~20 µm and, beside a 3 mm centre
    distance, tilts the normal by milliradians on the same contacts."""
    from mujoco.mjx._src import math as mjx_math
    # arms whose axes cross (overlap deeper than 2.9 mm of 3) have no
    # meaningful normal; both libraries then use the axes' cross product
    found = [c for c in _arm_arm_contacts(3000, seed=5) if c[6] > -0.0029]
    assert len(found) >= 20, "the sample must contain arm-arm contacts"
    ours = jax.jit(mc.capsule_capsule_contact)
    theirs = jax.jit(mjx_math.closest_segment_to_segment_points)
    worst_ours = worst_theirs = 0.0
    for p1, m1, s1, p2, m2, s2, c_dist, c_normal in found:
        dist, _, n = (np.asarray(x, float) for x in ours(p1, m1, s1, p2, m2, s2))
        assert dist == pytest.approx(c_dist, abs=1e-6)
        worst_ours = max(worst_ours, np.linalg.norm(n - c_normal))  # angle (rad), small-angle
        h1, h2 = s1[1] * m1[:, 2], s2[1] * m2[:, 2]
        a, b = (np.asarray(x, float) for x in theirs(p1 - h1, p1 + h1, p2 - h2, p2 + h2))
        worst_theirs = max(worst_theirs, np.linalg.norm((b - a) / np.linalg.norm(b - a) - c_normal))
    assert worst_ours < 1e-4, worst_ours
    assert worst_theirs > 1e-3, worst_theirs


def test_closest_points_of_crossing_parallel_nearly_parallel_and_end_to_end_segments():
    """The exact closest points where shortcuts go wrong: segments crossing
    at a gap (interior points), parallel segments overlapping (the middle of
    the overlap, at the true gap), segments 1 mrad from parallel (the end of
    the overlap where they are closest, not its middle: for two 52.5 mm arms
    that is tens of micrometres deeper), and segments meeting end to end at
    an angle (the two near ends)."""
    f = jax.jit(mc.segment_closest_points)
    a, b = f(np.array([-1.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.3, -1, 0.2]), np.array([0.3, 1, 0.2]))
    np.testing.assert_allclose(np.stack([a, b]), [[0.3, 0, 0], [0.3, 0, 0.2]], atol=1e-6)
    a, b = f(np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.5, 0.1, 0]), np.array([1.5, 0.1, 0]))
    np.testing.assert_allclose(np.stack([a, b]), [[0.75, 0, 0], [0.75, 0.1, 0]], atol=1e-6)
    a, b = f(np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 0.1, 0]), np.array([1.0, 0.101, 0]))
    np.testing.assert_allclose(np.stack([a, b]), [[0.0, 0, 0], [0.0, 0.1, 0]], atol=1e-6)
    a, b = f(np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([1.2, 0.1, 0]), np.array([2.0, 1.0, 0]))
    np.testing.assert_allclose(np.stack([a, b]), [[1.0, 0, 0], [1.2, 0.1, 0]], atol=1e-6)


def test_install_replaces_mjx_routines_once_and_uninstall_restores_them():
    from mujoco.mjx._src import collision_driver as cd
    from mujoco.mjx._src.collision_convex import capsule_convex
    from mujoco.mjx._src.collision_primitive import capsule_capsule
    from mujoco.mjx._src.types import GeomType
    box_key, cap_key = (GeomType.CAPSULE, GeomType.BOX), (GeomType.CAPSULE, GeomType.CAPSULE)
    try:
        mc.uninstall()
        assert cd._COLLISION_FUNC[box_key] is capsule_convex and cd._COLLISION_FUNC[cap_key] is capsule_capsule
        mc.install()
        ours = cd._COLLISION_FUNC[box_key], cd._COLLISION_FUNC[cap_key]
        assert all(getattr(f, "smarticle_mjx", False) for f in ours)
        assert (ours[0].ncon, ours[1].ncon) == (2, 1)
        mc.install()
        assert (cd._COLLISION_FUNC[box_key], cd._COLLISION_FUNC[cap_key]) == ours
        # an MJX whose entry is not the routine replaced: refused, and nothing is changed
        mc.uninstall()
        cd._COLLISION_FUNC[cap_key] = cd._COLLISION_FUNC[(GeomType.SPHERE, GeomType.CAPSULE)]
        with pytest.raises(RuntimeError, match="capsule-capsule collision entry is not the one smarticle_mjx"):
            mc.install()
        assert cd._COLLISION_FUNC[box_key] is capsule_convex
    finally:
        mc.uninstall()
        mc.install()


def test_the_mjx_backend_runs_with_this_collider():
    from mujoco.mjx._src import collision_driver as cd
    from mujoco.mjx._src.types import GeomType
    from smarticle_mjx.engine import make_backend
    mc.uninstall()
    make_backend("mjx", Scene.build(SceneParams(), 2))
    assert getattr(cd._COLLISION_FUNC[(GeomType.CAPSULE, GeomType.BOX)], "smarticle_mjx", False)
    assert getattr(cd._COLLISION_FUNC[(GeomType.CAPSULE, GeomType.CAPSULE)], "smarticle_mjx", False)
