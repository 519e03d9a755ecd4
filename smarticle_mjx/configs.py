"""Pair coordinates (|r|, theta, phi) <-> poses, sampling, and validity.

Definitions (smarticle.md, paper Fig. 2A), with the frame of ``scene``:

* r = c2 - c1, the vector between body centres; |r| in units of W.
* theta: polar angle of r in robot 1's body frame, from robot 1's body axis,
  counter-clockwise, in [0, 2 pi). theta = 3 pi / 2 is robot 1's normal (-y).
* phi: angle from robot 1's normal to robot 2's normal, counter-clockwise, in
  [0, 2 pi); since both normals are the body's -y, phi = heading2 - heading1.
  phi = pi is the anti-aligned C1 glider, phi = 0 the aligned C2.

Validity is decided in the plane without simulating: arms are capsules and
bodies rectangles at the arms' height (``scene`` puts every arm inside the
body's height), so a 2D separation test is exact. ``tests/test_configs.py``
checks it against MuJoCo's own collision detection.
"""

from __future__ import annotations

import numpy as np

from .scene import RobotParams

TWO_PI = 2 * np.pi


def pose_from_relative(r_W, theta, phi, body_length: float = RobotParams().body_length):
    """Robot 2's (x, y, heading) for robot 1 at the origin with heading 0.

    Args:
      r_W: |r| in units of W, any shape.
      theta, phi: radians, broadcastable with ``r_W``.
      body_length: W in metres.

    Returns:
      Tuple ``(x, y, heading)`` of arrays in m and rad.
    """
    r = np.asarray(r_W, dtype=float) * body_length
    theta = np.asarray(theta, dtype=float)
    return r * np.cos(theta), r * np.sin(theta), np.mod(np.asarray(phi, dtype=float), TWO_PI)


def relative_coordinates(pose1, pose2, body_length: float = RobotParams().body_length):
    """(|r| in W, theta, phi) from two arrays of poses ``[..., >=3]`` (x, y, heading)."""
    p1 = np.asarray(pose1, dtype=float)
    p2 = np.asarray(pose2, dtype=float)
    dx = p2[..., 0] - p1[..., 0]
    dy = p2[..., 1] - p1[..., 1]
    h1 = p1[..., 2]
    c, s = np.cos(h1), np.sin(h1)
    bx, by = c * dx + s * dy, -s * dx + c * dy  # r in robot 1's frame
    r = np.hypot(dx, dy) / body_length
    theta = np.mod(np.arctan2(by, bx), TWO_PI)
    phi = np.mod(p2[..., 2] - h1, TWO_PI)
    return r, theta, phi


# ---------------------------------------------------------------- geometry

def _seg_seg_dist(p1, q1, p2, q2):
    """Distance between 2D segments [p1, q1] and [p2, q2]; arrays [..., 2]."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.sum(d1 * d1, -1)
    e = np.sum(d2 * d2, -1)
    f = np.sum(d2 * r, -1)
    c = np.sum(d1 * r, -1)
    b = np.sum(d1 * d2, -1)
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(denom > 1e-18, np.clip((b * f - c * e) / denom, 0, 1), 0.0)
        t = (b * s + f) / e
        t_c = np.clip(t, 0, 1)
        s = np.where(t < 0, np.clip(-c / a, 0, 1), np.where(t > 1, np.clip((b - c) / a, 0, 1), s))
    c1 = p1 + d1 * s[..., None]
    c2 = p2 + d2 * t_c[..., None]
    dist = np.linalg.norm(c1 - c2, axis=-1)
    # segments that properly cross have distance 0
    cross = _segments_cross(p1, q1, p2, q2)
    return np.where(cross, 0.0, dist)


def _segments_cross(p1, q1, p2, q2):
    def orient(a, b, c):
        return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])
    o1, o2 = orient(p1, q1, p2), orient(p1, q1, q2)
    o3, o4 = orient(p2, q2, p1), orient(p2, q2, q1)
    return (o1 * o2 < 0) & (o3 * o4 < 0)


def _body_to_world(pose):
    """(pose's arm angles a1, a2, and a map of body-frame points (bx, by) to world points [..., 2]) of
    robots at ``pose`` [..., 5]."""
    pose = np.asarray(pose, dtype=float)
    x, y, h, a1, a2 = (pose[..., k] for k in range(5))
    c, s = np.cos(h), np.sin(h)
    zero = 0 * x

    def world(bx, by):
        bx, by = bx + zero, by + zero
        return np.stack([x + c * bx - s * by, y + s * bx + c * by], -1)
    return a1, a2, world


def _arm_rectangle(world, sign, hx, alpha, length, half_width):
    """[..., 4, 2] counter-clockwise rectangle from an arm's hinge (``sign`` -1: arm 1 at -``hx``, pointing
    along -x at angle 0 and folding toward +y; +1: arm 2, mirrored) ``length`` along the arm at ``alpha``,
    ``half_width`` either side of its axis."""
    ux, uy = sign * np.cos(alpha), np.sin(alpha)  # along the arm, body frame
    nx, ny = -uy, ux  # across the arm, to its left: the corners run counter-clockwise
    return np.stack([world(sign * hx + u * length * ux + v * half_width * nx, u * length * uy + v * half_width * ny)
                     for u, v in ((0, -1), (1, -1), (1, 1), (0, 1))], -2)


def robot_outline(pose, robot: RobotParams = RobotParams()):
    """Planar outline of robots at ``pose`` [..., 5].

    Returns:
      ``corners`` [..., 4, 2] of the body rectangle (counter-clockwise) and
      ``arms`` [..., 2, V, 2]: arm k's convex outline. A capsule arm is its
      axis segment (V = 2: hinge, end of the axis) to be widened by
      ``arm_piece_radius(robot)``; a plate arm is its rectangle (V = 4,
      counter-clockwise, radius 0). Hinges sit ``robot.hinge_x`` from the
      body centre.
    """
    a1, a2, world = _body_to_world(pose)
    hw, hd = robot.body_length / 2, robot.body_thickness / 2
    hx = robot.hinge_x
    corners = np.stack([world(-hw, -hd), world(hw, -hd), world(hw, hd), world(-hw, hd)], -2)
    arms = []
    len1, len2 = robot.arm_lengths
    for sign, alpha, length in ((-1, a1, len1), (1, a2, len2)):
        if robot.arm_shape == "plate":
            arms.append(_arm_rectangle(world, sign, hx, alpha, length, robot.arm_thickness / 2))
        else:
            reach = length - robot.arm_radius
            ux, uy = sign * np.cos(alpha), np.sin(alpha)
            arms.append(np.stack([world(sign * hx, 0.0), world(sign * hx + reach * ux, reach * uy)], -2))
    return corners, np.stack(arms, -3)


def mount_outline(pose, robot: RobotParams = RobotParams()):
    """Rectangles [..., 2, 4, 2] (counter-clockwise) of the arms' mounts
    (``RobotParams.arm_mount_length``) of robots at ``pose`` [..., 5]: from the
    hinge to ``arm_mount_length`` along each arm, ``arm_mount_width`` across;
    None for robots without mounts."""
    if not robot.has_mount:
        return None
    a1, a2, world = _body_to_world(pose)
    return np.stack([_arm_rectangle(world, sign, robot.hinge_x, alpha, robot.arm_mount_length,
                                    robot.arm_mount_width / 2) for sign, alpha in ((-1, a1), (1, a2))], -3)


def arm_piece_radius(robot: RobotParams) -> float:
    """Radius by which an arm outline of :func:`robot_outline` is widened."""
    return 0.0 if robot.arm_shape == "plate" else robot.arm_radius


def _point_in_convex(pt, poly):
    """pt [..., 2] strictly inside the convex counter-clockwise polygon poly [..., V >= 3, 2]."""
    inside = np.ones(pt.shape[:-1], dtype=bool)
    v = poly.shape[-2]
    for k in range(v):
        a, b = poly[..., k, :], poly[..., (k + 1) % v, :]
        cross = (b[..., 0] - a[..., 0]) * (pt[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (pt[..., 0] - a[..., 0])
        inside &= cross > 0
    return inside


def _edges(poly):
    v = poly.shape[-2]
    if v == 2:
        return [(poly[..., 0, :], poly[..., 1, :])]
    return [(poly[..., k, :], poly[..., (k + 1) % v, :]) for k in range(v)]


def _convex_dist(p, q):
    """Distance between convex polygons (or segments, V = 2) p [..., V, 2] and
    q [..., U, 2]; 0 where they overlap."""
    d = np.min(np.stack([_seg_seg_dist(a, b, c, e) for a, b in _edges(p) for c, e in _edges(q)]), 0)
    inside = np.zeros(d.shape, dtype=bool)
    if q.shape[-2] >= 3:
        for k in range(p.shape[-2]):
            inside |= _point_in_convex(p[..., k, :], q)
    if p.shape[-2] >= 3:
        for k in range(q.shape[-2]):
            inside |= _point_in_convex(q[..., k, :], p)
    return np.where(inside, 0.0, d)


def pair_separation(pose1, pose2, robot: RobotParams = RobotParams()):
    """Smallest planar gap (m) between two robots; <= 0 means they overlap.

    Body-body, arm-body and arm-arm gaps are all considered; a capsule's gap is
    its axis segment's distance minus its radius, a plate's its rectangle's.
    Vectorised over leading axes.
    """
    c1, arms1 = robot_outline(pose1, robot)
    c2, arms2 = robot_outline(pose2, robot)
    r = arm_piece_radius(robot)
    # each robot's pieces beside its body: its arms (widened by r) and their mounts (radius 0)
    pieces1 = [(arms1[..., k, :, :], r) for k in range(2)]
    pieces2 = [(arms2[..., k, :, :], r) for k in range(2)]
    if robot.has_mount:
        m1, m2 = mount_outline(pose1, robot), mount_outline(pose2, robot)
        pieces1 += [(m1[..., k, :, :], 0.0) for k in range(2)]
        pieces2 += [(m2[..., k, :, :], 0.0) for k in range(2)]
    gaps = [_convex_dist(c1, c2)]
    for p, rp in pieces1:
        gaps.append(_convex_dist(p, c2) - rp)
    for q, rq in pieces2:
        gaps.append(_convex_dist(q, c1) - rq)
    for p, rp in pieces1:
        for q, rq in pieces2:
            gaps.append(_convex_dist(p, q) - rp - rq)
    return np.min(np.stack(gaps), 0)


def poses_valid(poses, robot: RobotParams = RobotParams(), clearance: float = 0.0):
    """True where no two of the N robots in ``poses`` [..., N, 5] overlap.

    ``clearance`` (m) demands a positive gap; 0 accepts touching robots.
    """
    poses = np.asarray(poses, dtype=float)
    i, j = np.triu_indices(poses.shape[-2], 1)
    if len(i) == 0:
        return np.ones(poses.shape[:-2], dtype=bool)
    # every pair at once: one vectorised call instead of one per pair
    return (pair_separation(poses[..., i, :], poses[..., j, :], robot) > clearance).all(-1)


# ---------------------------------------------------------------- sampling

def pair_poses(r_W, theta, phi, alpha1, alpha2, robot: RobotParams = RobotParams()):
    """Poses [..., 2, 5] of a pair from relative coordinates and arm angles.

    Robot 1 sits at the origin with heading 0; both robots start with arm
    angles ``(alpha1, alpha2)`` (all robots start in phase).
    """
    x, y, h = pose_from_relative(r_W, theta, phi, robot.body_length)
    a1 = np.broadcast_to(np.asarray(alpha1, dtype=float), x.shape)
    a2 = np.broadcast_to(np.asarray(alpha2, dtype=float), x.shape)
    z = np.zeros_like(x)
    p1 = np.stack([z, z, z, a1, a2], -1)
    p2 = np.stack([x, y, h, a1, a2], -1)
    return np.stack([p1, p2], -2)


def random_configs(n: int, rng: np.random.Generator, r_range_W=(0.5, 2.5)):
    """``n`` uniform random (|r|, theta, phi): |r| uniform in ``r_range_W``
    (units of W), angles uniform on [0, 2 pi). Returns array [n, 3]."""
    if n <= 0:
        raise ValueError(f"number of configurations must be positive, got {n}")
    lo, hi = r_range_W
    if not 0 <= lo < hi:
        raise ValueError(f"bad |r| range {r_range_W}")
    return np.stack([rng.uniform(lo, hi, n), rng.uniform(0, TWO_PI, n), rng.uniform(0, TWO_PI, n)], -1)


def polar_configs(radius_W: float, positions: int, orientations: int):
    """The paper's polar grid: ``positions`` evenly spaced theta at fixed
    |r| = ``radius_W``, each with ``orientations`` evenly spaced phi.
    Returns array [positions * orientations, 3]."""
    if positions <= 0 or orientations <= 0:
        raise ValueError("positions and orientations must be positive")
    if radius_W <= 0:
        raise ValueError("radius must be positive")
    th = np.arange(positions) * TWO_PI / positions
    ph = np.arange(orientations) * TWO_PI / orientations
    T, P = np.meshgrid(th, ph, indexing="ij")
    return np.stack([np.full(T.size, radius_W), T.ravel(), P.ravel()], -1)


def sample_valid_pairs(n: int, rng: np.random.Generator, r_range_W, alpha1, alpha2,
                       robot: RobotParams = RobotParams()) -> np.ndarray:
    """Poses [n, 2, 5] of ``n`` random non-overlapping pairs (uniform
    (|r|, theta, phi) with |r| in ``r_range_W``, rejection of overlaps)."""
    out, have = [], 0
    while have < n:
        cf = random_configs(4 * n, rng, r_range_W)
        p = pair_poses(cf[:, 0], cf[:, 1], cf[:, 2], alpha1, alpha2, robot)
        p = p[poses_valid(p, robot)]
        out.append(p)
        have += len(p)
    return np.concatenate(out)[:n]
