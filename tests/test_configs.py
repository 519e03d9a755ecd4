"""Pair coordinates and validity of initial configurations."""

import math

import mujoco
import numpy as np
import pytest

from smarticle_mjx import configs as C
from smarticle_mjx import scene as S

W = S.RobotParams().body_length


def test_pose_relative_round_trip():
    rng = np.random.default_rng(1)
    cf = C.random_configs(500, rng)
    x, y, h = C.pose_from_relative(cf[:, 0], cf[:, 1], cf[:, 2], W)
    p1 = np.zeros((500, 3))
    p2 = np.stack([x, y, h], -1)
    r, th, ph = C.relative_coordinates(p1, p2, W)
    np.testing.assert_allclose(r, cf[:, 0], atol=1e-12)
    np.testing.assert_allclose(np.exp(1j * th), np.exp(1j * cf[:, 1]), atol=1e-12)
    np.testing.assert_allclose(np.exp(1j * ph), np.exp(1j * cf[:, 2]), atol=1e-12)


def test_relative_coordinates_invariant_under_rigid_motion():
    """(|r|, theta, phi) describe the pair only: moving and rotating both robots changes nothing."""
    rng = np.random.default_rng(2)
    p1 = np.stack([rng.normal(size=50), rng.normal(size=50), rng.uniform(0, 6.3, 50)], -1)
    p2 = np.stack([rng.normal(size=50), rng.normal(size=50), rng.uniform(0, 6.3, 50)], -1)
    ang, shift = 1.234, np.array([0.3, -0.7])
    R = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])

    def move(p):
        q = p.copy()
        q[:, :2] = p[:, :2] @ R.T + shift
        q[:, 2] = p[:, 2] + ang
        return q

    a = C.relative_coordinates(p1, p2, W)
    b = C.relative_coordinates(move(p1), move(p2), W)
    for u, v in zip(a, b):
        np.testing.assert_allclose(np.exp(1j * u), np.exp(1j * v), atol=1e-9)


def test_theta_270_is_robot1_normal_and_phi_180_is_antialigned():
    x, y, h = C.pose_from_relative(1.3, math.radians(270), math.pi, W)
    assert x == pytest.approx(0, abs=1e-12) and y == pytest.approx(-1.3 * W)
    assert h == pytest.approx(math.pi)


def _mujoco_depth(poses):
    """Deepest inter-robot penetration MuJoCo's collider finds (0 if none)."""
    m = S.compile_model(S.build_mjcf(S.SceneParams(), poses))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    lay = S.SceneLayout.of(m)
    depth = 0.0
    for c in d.contact[:d.ncon]:
        r1, r2 = lay.geom_robot[c.geom[0]], lay.geom_robot[c.geom[1]]
        if r1 >= 0 and r2 >= 0 and r1 != r2:
            depth = min(depth, c.dist)
    return depth


def _sampled_overlap(pose1, pose2, h=2.5e-4):
    """Independent reference: sample points on a grid inside robot 2's
    outline and test containment in robot 1's outline (rectangle, capsules)."""
    rp = S.RobotParams()
    r = rp.arm_radius

    def inside(pts, pose):
        corners, arms = C.robot_outline(pose, rp)
        x, y, hd = pose[0], pose[1], pose[2]
        c, s = math.cos(hd), math.sin(hd)
        lx = c * (pts[:, 0] - x) + s * (pts[:, 1] - y)
        ly = -s * (pts[:, 0] - x) + c * (pts[:, 1] - y)
        hit = (np.abs(lx) <= rp.body_length / 2) & (np.abs(ly) <= rp.body_thickness / 2)
        for a, b in arms:
            ab = b - a
            t = np.clip(((pts - a) @ ab) / (ab @ ab), 0, 1)
            hit |= np.linalg.norm(pts - (a + t[:, None] * ab), axis=1) <= r
        return hit

    corners, arms = C.robot_outline(pose2, rp)
    lo = np.minimum(corners.min(0), arms.reshape(-1, 2).min(0)) - r
    hi = np.maximum(corners.max(0), arms.reshape(-1, 2).max(0)) + r
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0], h), np.arange(lo[1], hi[1], h))
    pts = np.stack([gx.ravel(), gy.ravel()], -1)
    pts = pts[inside(pts, pose2)]
    return bool(inside(pts, pose1).any())


def _sample(n, seed):
    rng = np.random.default_rng(seed)
    cf = C.random_configs(n, rng, r_range_W=(0.3, 2.2))
    arms = rng.uniform(-math.pi / 2, math.pi / 2, (n, 2))
    return C.pair_poses(cf[:, 0], cf[:, 1], cf[:, 2], arms[:, 0], arms[:, 1])


def test_validity_agrees_with_sampled_reference():
    """Overlap is decided exactly: a brute-force point-sampling test agrees
    except within its grid spacing of grazing contact."""
    poses = _sample(200, 3)
    gap = C.pair_separation(poses[:, 0], poses[:, 1])
    ref = np.array([_sampled_overlap(p[0], p[1]) for p in poses])
    ours = gap <= 0
    assert 0.2 < ours.mean() < 0.9, "sample should contain both outcomes"
    disagree = ours != ref
    assert np.all(np.abs(gap[disagree]) < 5e-4), gap[disagree]
    assert disagree.mean() <= 0.02


def test_every_penetration_mujoco_finds_is_invalid():
    """MuJoCo's collider never invents contacts: whatever it finds penetrating
    (deeper than 0.1 mm) must be invalid here. (It can miss an arm that passes
    right through a body, so the converse is checked by the sampled reference.)"""
    poses = _sample(200, 4)
    gap = C.pair_separation(poses[:, 0], poses[:, 1])
    depth = np.array([_mujoco_depth(p) for p in poses])
    assert (depth < -1e-4).sum() > 20
    assert np.all(gap[depth < -1e-4] <= 0)
    # and robots we call clearly apart are apart for MuJoCo too
    assert np.all(depth[gap > 1e-4] == 0)


def test_obvious_cases():
    a = math.pi / 2
    same_place = C.pair_poses(0.0, 0.0, 0.3, a, a)
    far = C.pair_poses(10.0, 1.0, 2.0, a, a)
    assert not C.poses_valid(same_place)
    assert C.poses_valid(far)
    # two U's facing away at the paper's 1.3 W: valid; facing each other overlapping arms: invalid
    assert C.poses_valid(C.pair_poses(1.3, math.radians(270), math.pi, a, a))
    assert not C.poses_valid(C.pair_poses(1.3, math.radians(90), math.pi, a, a))


def test_reference_scenes_are_valid():
    for kind in S.REFERENCE_SCENES:
        poses = np.array(S.standard_poses(kind))
        assert C.poses_valid(poses), kind


def test_samplers_reject_bad_counts():
    with pytest.raises(ValueError):
        C.random_configs(0, np.random.default_rng(0))
    with pytest.raises(ValueError):
        C.polar_configs(1.3, 0, 10)
    g = C.polar_configs(1.3, 40, 25)
    assert g.shape == (1000, 3) and np.all(g[:, 0] == 1.3)
