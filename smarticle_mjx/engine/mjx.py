"""MJX backend: ``jax.vmap`` of ``mjx.step`` inside a ``lax.scan`` over a period.

The core, :func:`_period`, is written for one lane; :class:`MjxBackend` adds
``vmap`` over lanes and ``jit``. What forces a recompile (static): the model,
the batch size, steps per period (gait period / timestep) and the dtype.
Amplitude, chirality, gait kind and phase offsets are traced per lane.

MJX has no subtree contact sensor, so touches are read from the contact list
directly: MJX's contact slots are fixed per model, so each slot's robot pair
is known ahead of time (``_pair_matrix``).

Capsule–box (arm–body) contacts use smarticle_mjx's own collider
(:mod:`.mjx_collision`): MJX's misses contacts at the robots' millimetre scale.
"""

from __future__ import annotations


import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

from .. import gait as gait_mod
from . import mjx_collision
from ..capabilities import require
from .core import (BackendBase, Lanes, check_records, check_solver, check_start_delays, PeriodRecords, Record, Scene,
                   Status, refuse_mounts, on_step_grid, steps_per_period)


def strip_sensors(xml: str) -> str:
    a, b = xml.index("<sensor>"), xml.index("</sensor>") + len("</sensor>")
    return xml[:a] + xml[b:]


def _contact_slots(scene: Scene, model: mujoco.MjModel, mx) -> np.ndarray:
    """One-hot [ncon_slots, P]: which robot pair each MJX contact slot belongs to."""
    d = mjx.make_data(model)
    d = jax.jit(mjx.forward)(mx, d)
    geom = np.asarray(d._impl.contact.geom)
    lay = scene.layout
    pair_index = {tuple(p): k for k, p in enumerate(lay.pairs.tolist())}
    out = np.zeros((geom.shape[0], max(1, len(lay.pairs))), dtype=bool)
    for s, (g1, g2) in enumerate(geom):
        r1, r2 = lay.geom_robot[g1], lay.geom_robot[g2]
        if r1 >= 0 and r2 >= 0 and r1 != r2:
            out[s, pair_index[(min(r1, r2), max(r1, r2))]] = True
    return out[:, :len(lay.pairs)]


# MJX's line search is a fixed-length scan: under vmap every step pays for
# all ls_iterations evaluations whether a lane needs them or not, so the cap
# is MJX's cost. The scene's cap (50) is for MuJoCo C, whose search stops
# when done. At all 14 055 hard solves of 8 colliding pairs' first period
# (contact onsets, impacts) MJX's solve with 6 or 10 evaluations is within
# 0.03 % of its own converged one, with 2 it is off at 1112; 20 costs 1.57x
# of 10 (benchmarks/solver_convergence.py).
LS_ITERATIONS = 10

# JAX's default matmul precision on recent GPUs is TF32 (10-bit mantissa):
# contact Jacobians and inertia products at millimetre scale lose digits the
# solver needs. The backend runs every trace at full float32 precision.
MATMUL_PRECISION = "highest"


# integrators MJX (JAX) implements in mjx.step
MJX_INTEGRATORS = ("Euler", "RK4", "implicitfast")
# constraint solvers MJX implements (no PGS)
MJX_SOLVERS = ("Newton", "CG")

class MjxBackend(BackendBase):
    """Batched MJX rollouts; runs on whatever device JAX chose (CPU or GPU)."""

    name = "mjx"
    batching = "fixed"  # see engine.core.BATCHING

    def __init__(self, scene: Scene, penetration_limit: float = 0.002, ls_iterations: int = LS_ITERATIONS):
        self.scene = scene
        jax.config.update("jax_default_matmul_precision", MATMUL_PRECISION)
        mjx_collision.install()  # before any trace: MJX's capsule-box misses contacts at this scale
        if scene.params.integrator not in MJX_INTEGRATORS:
            raise ValueError(f"the mjx backend integrates with {', '.join(MJX_INTEGRATORS)}, not "
                             f"{scene.params.integrator!r}; use the native or warp backend")
        check_solver(scene, "mjx", MJX_SOLVERS)
        refuse_mounts(scene.params, "mjx")
        self.model = mujoco.MjModel.from_xml_string(Scene.mjcf(scene.params, scene.n_robots, sensors="none"))
        # near-contact sub-stepping (SceneParams.contact_substeps): lanes here run in lock-step, so a lane
        # that skips sub-steps saves nothing; every step is split (the gate always open)
        self.model.opt.timestep = scene.params.sub_timestep
        if ls_iterations < 1:
            raise ValueError(f"ls_iterations must be >= 1, got {ls_iterations}")
        self.model.opt.ls_iterations = min(int(ls_iterations), scene.params.ls_iterations)
        self.mx = mjx.put_model(self.model)
        self.slots = jnp.asarray(_contact_slots(scene, self.model, self.mx))
        self.penetration_limit = penetration_limit
        self._compiled = {}
        cpus = [d for d in jax.local_devices() if d.platform == "cpu"]
        self.devices = cpus if len(cpus) == len(jax.local_devices()) else jax.local_devices()[:1]

    def _shard(self, tree, b: int):
        """Split the lane axis across devices (host cores) when it divides evenly."""
        n = len(self.devices)
        if n < 2 or b % n:
            return tree
        from jax.sharding import Mesh, NamedSharding, PartitionSpec
        sharding = NamedSharding(Mesh(np.array(self.devices), ("lanes",)), PartitionSpec("lanes"))
        return jax.device_put(tree, sharding)

    def initial_state(self, lanes: Lanes):
        """Batched mjx.Data at t = 0 with the lanes' poses at rest."""
        qpos = jnp.asarray(self.scene.qpos_from_poses(lanes.poses), dtype=jnp.float32)
        d0 = mjx.make_data(self.model)
        b = lanes.size
        d = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (b,) + x.shape), d0)
        d = d.replace(qpos=qpos)
        if self.model.na:
            d = d.replace(act=jnp.asarray(self.scene.initial_act(lanes), dtype=d.act.dtype))
        return self._shard(d, b)

    def _lane_args(self, lanes: Lanes):
        """Traced per-lane gait inputs (amplitude, chirality, kind, phase, period).

        The period is one scalar for the batch, or [B, N] when robots run
        their own gaits (then amplitude, chirality and kind are [B, N] too).
        """
        if lanes.arm_speed is not None:
            require("mjx", "per_arm_speeds")  # its controls are traced at the model's servo speed
        if lanes.per_robot:
            amp, chi, kind, period = lanes.robot_gait()
            period = jnp.asarray(period, jnp.float32)
        else:
            amp, chi, kind, period = lanes.amplitude, lanes.chirality, lanes.kind, None
        args = (jnp.asarray(amp, jnp.float32), jnp.asarray(chi, jnp.int32), jnp.asarray(kind, jnp.int32),
                jnp.asarray(lanes.phase, jnp.float32))
        if period is not None:
            return self._shard(args + (period,), lanes.size), True
        return self._shard(args, lanes.size) + (jnp.float32(lanes.period),), False

    def _gait_step(self, d, t, amplitude, chirality, kind, phase, period):
        """One mjx.step of one lane with the gait's controls at time ``t``."""
        ctrl = gait_mod.setpoints_and_rates(t, amplitude, period, self.scene.params.robot.servo_speed,
                                            chirality, kind, phase).reshape(-1)
        return mjx.step(self.mx, d.replace(ctrl=ctrl.astype(d.ctrl.dtype)))

    def _period_fn(self, nstep: int, per_robot: bool = False):
        """jit(vmap(one lane, one period)) for ``nstep`` steps per period
        (``per_robot``: the period is per lane and robot, not one scalar)."""
        if (nstep, per_robot) in self._compiled:
            return self._compiled[(nstep, per_robot)]
        slots = self.slots
        dt = float(self.model.opt.timestep)
        n_pairs = self.scene.n_pairs

        def one_lane(d, amplitude, chirality, kind, phase, period):
            def body(carry, i):
                d, touched, mind, finite = carry
                # gait time is period-relative: lanes may have different clocks
                d = self._gait_step(d, dt * i, amplitude, chirality, kind, phase, period)
                # contacts of this step's forward pass (state at time t)
                dist = d._impl.contact.dist
                hit = (dist < 0)[:, None] & slots
                touched = touched | hit.any(0)
                mind = jnp.minimum(mind, jnp.where(hit, dist[:, None], jnp.inf).min(0))
                finite = finite & jnp.isfinite(d.qpos).all() & jnp.isfinite(d.qvel).all()
                return (d, touched, mind, finite), None

            init = (d, jnp.zeros(n_pairs, bool), jnp.full(n_pairs, jnp.inf), jnp.asarray(True))
            (d, touched, mind, finite), _ = jax.lax.scan(body, init, jnp.arange(nstep))
            return d, touched, mind, finite

        fn = jax.jit(jax.vmap(one_lane, in_axes=(0, 0, 0, 0, 0, 0 if per_robot else None)))
        self._compiled[(nstep, per_robot)] = fn
        return fn

    def advance(self, state, lanes: Lanes, n_periods: int, *, t0: float = 0.0, record: Record | None = None):
        """Advance batched ``state`` by ``n_periods``; same contract as the native backend."""
        check_start_delays(lanes, "mjx")
        check_records(record, "mjx")
        lanes = on_step_grid(lanes, float(self.model.opt.timestep))
        nstep = steps_per_period(lanes.period, float(self.model.opt.timestep))
        b = lanes.size
        args, per_robot = self._lane_args(lanes.at_time(t0))
        fn = self._period_fn(nstep, per_robot)
        poses = np.empty((b, n_periods, self.scene.n_robots, 5))
        touched = np.zeros((b, n_periods, self.scene.n_pairs), dtype=bool)
        min_dist = np.full((b, n_periods, self.scene.n_pairs), np.inf)
        status = np.zeros(b, dtype=np.int32)
        for k in range(n_periods):
            if k and lanes.varies:  # own clocks or per-cycle retriggering: the phases move on
                args, _ = self._lane_args(lanes.at_time(t0 + k * lanes.period))
            state, tch, mind, finite = fn(state, *args)
            touched[:, k] = np.asarray(tch)
            min_dist[:, k] = np.asarray(mind)
            poses[:, k] = self.scene.poses_from_qpos(np.asarray(state.qpos, dtype=np.float64))
            status |= np.where(np.asarray(finite), 0, int(Status.NONFINITE))
            status |= np.where((min_dist[:, k] < -self.penetration_limit).any(-1), int(Status.PENETRATION), 0)
        return state, PeriodRecords(poses, touched, min_dist, status), None

    def step_qpos(self, lanes: Lanes, nsteps: int) -> np.ndarray:
        """qpos [B, nsteps, nq] of the first ``nsteps`` steps from rest (for
        step-by-step comparison with the native backend, and benchmarks).
        The period is traced here, so only ``nsteps`` and B recompile."""
        lanes = on_step_grid(lanes, float(self.model.opt.timestep))
        args, per_robot = self._lane_args(lanes)
        key = ("steps", nsteps, per_robot)
        if key not in self._compiled:
            dt = float(self.model.opt.timestep)

            def one_lane(d, amplitude, chirality, kind, phase, period):
                def body(d, i):
                    d = self._gait_step(d, dt * i, amplitude, chirality, kind, phase, period)
                    return d, d.qpos
                return jax.lax.scan(body, d, jnp.arange(nsteps))[1]

            self._compiled[key] = jax.jit(jax.vmap(one_lane, in_axes=(0, 0, 0, 0, 0, 0 if per_robot else None)))
        out = self._compiled[key](self.initial_state(lanes), *args)
        return np.asarray(jax.block_until_ready(out), dtype=np.float64)
