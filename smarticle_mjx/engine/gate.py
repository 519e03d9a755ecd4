"""Where two robots may touch within the next few steps: the gate of near-contact sub-stepping.

The native backend can split a lane's time steps while its robots are close
(``SceneParams.contact_substeps``; ``docs/timestep.md`` says why: the glider
quantities need about 20 contact-force evaluations per contact time constant,
and a glider's robots are within a few millimetres of each other for only a
third of the time). Every few steps it asks :func:`gap_lower_bound` how far
apart each lane's robots are at least, from their planar poses alone.

Each robot is covered by three capsules: the body by one along its long axis
whose ends reach the body's corners (axis half-length L/2 - D/2, radius
D/sqrt(2)), each arm by its hinge-to-tip segment widened by half its
thickness (a plate arm's rectangle and a capsule arm lie inside it). The gap
between two such covers is never more than the robots' planar gap
(:func:`smarticle_mjx.configs.pair_separation`), and is less by at most the
body cover's bulge, (sqrt(2) - 1) D/2 per body (4.6 mm for the lab's robot),
where two bodies are the nearest parts. Jitted: one call for a whole slice of
lanes costs tens of microseconds, not the milliseconds of the same numpy.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from ..scene import RobotParams

# The fastest that two robots' nearest points approach each other (m/s): arm tips at the servo's
# speed (8.7 rad/s x 54 mm = 0.47 m/s) striking head-on, plus what collisions give the bodies; the
# crowd's hardest strikes measured 1.18-1.30 m/s along the contact normal (docs/relax.md).
APPROACH_SPEED_MAX = 1.5


def _seg_dist(p1, q1, p2, q2):
    """Distance between 2D segments [p1, q1] and [p2, q2] (arrays [..., 2]); 0 where they cross."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = jnp.sum(d1 * d1, -1)
    e = jnp.sum(d2 * d2, -1)
    f = jnp.sum(d2 * r, -1)
    c = jnp.sum(d1 * r, -1)
    b = jnp.sum(d1 * d2, -1)
    denom = a * e - b * b
    s = jnp.where(denom > 1e-18, jnp.clip((b * f - c * e) / jnp.where(denom > 1e-18, denom, 1.0), 0, 1), 0.0)
    t = (b * s + f) / e
    s = jnp.where(t < 0, jnp.clip(-c / a, 0, 1), jnp.where(t > 1, jnp.clip((b - c) / a, 0, 1), s))
    t = jnp.clip(t, 0, 1)
    return jnp.linalg.norm(p1 + d1 * s[..., None] - p2 - d2 * t[..., None], axis=-1)


@functools.partial(jax.jit, static_argnums=(2,))
def _bound(pose1, pose2, dims):
    half_axis, body_r, arm_r, hinge_x, length = dims

    def segments(pose):
        x, y, h, a1, a2 = (pose[..., k] for k in range(5))
        c, s = jnp.cos(h), jnp.sin(h)

        def world(bx, by):
            return jnp.stack([x + c * bx - s * by, y + s * bx + c * by], -1)

        zero = 0 * x
        starts = [world(-half_axis + zero, zero)]
        ends = [world(half_axis + zero, zero)]
        for sign, alpha in ((-1, a1), (1, a2)):
            starts.append(world(sign * hinge_x + zero, zero))
            ends.append(world(sign * hinge_x + sign * length * jnp.cos(alpha), length * jnp.sin(alpha)))
        return jnp.stack(starts, -2), jnp.stack(ends, -2)  # [..., 3, 2]

    p1, q1 = segments(pose1)
    p2, q2 = segments(pose2)
    radius = jnp.array([body_r, arm_r, arm_r])
    i = np.repeat(np.arange(3), 3)
    j = np.tile(np.arange(3), 3)
    d = _seg_dist(p1[..., i, :], q1[..., i, :], p2[..., j, :], q2[..., j, :]) - radius[i] - radius[j]
    return d.min(-1)


def _cover(robot: RobotParams) -> tuple[float, ...]:
    """The capsule cover's sizes (m): body axis half-length and radius, arm radius, hinge offset, arm length."""
    hw, hd = robot.body_length / 2, robot.body_thickness / 2
    return (float(hw - hd), float(hd * np.sqrt(2.0)), float(robot.arm_thickness / 2), float(robot.hinge_x),
            float(max(robot.arm_lengths)))


def gap_lower_bound(pose1, pose2, robot: RobotParams) -> np.ndarray:
    """A lower bound (m) on the planar gap between robots at ``pose1`` and ``pose2`` ([..., 5] each:
    x, y, heading, alpha1, alpha2); negative where the covers overlap."""
    return np.asarray(_bound(jnp.asarray(pose1), jnp.asarray(pose2), _cover(robot)))


def chunk_steps(timestep: float, gate: float) -> int:
    """Steps between two asks of the gate: robots ``gate`` m apart cannot close the gap in fewer
    (at :data:`APPROACH_SPEED_MAX`)."""
    return max(1, int(gate / (APPROACH_SPEED_MAX * timestep)))


def make_gate(layout, robot: RobotParams, gate: float):
    """A jitted ``near(qpos [B, nq]) -> bool [B]``: whether any pair of a lane's robots may be closer than
    ``gate`` m (:func:`gap_lower_bound` on poses read straight from MuJoCo's qpos, as
    ``Scene.poses_from_qpos`` reads them)."""
    dims = _cover(robot)
    free = np.asarray(layout.free_qpos)
    arm = np.asarray(layout.arm_qpos)
    play = None if layout.play_qpos is None else np.asarray(layout.play_qpos)
    pi, pj = (np.asarray(v) for v in np.asarray(layout.pairs).T)

    @jax.jit
    def near(qpos):
        w, x, y, z = (qpos[:, free + 3 + k] for k in range(4))  # [B, N]
        heading = jnp.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        angles = []
        for k in (0, 1):
            a = qpos[:, arm[:, k]]
            if play is not None:
                a = a + jnp.where(play[:, k] >= 0, qpos[:, np.maximum(play[:, k], 0)], 0.0)
            angles.append(a)
        poses = jnp.stack([qpos[:, free], qpos[:, free + 1], heading, *angles], -1)  # [B, N, 5]
        return (_bound(poses[:, pi], poses[:, pj], dims).min(-1) < gate)

    return lambda qpos: np.asarray(near(jnp.asarray(qpos)))
