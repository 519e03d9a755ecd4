"""Native backend: MuJoCo's C engine through its multi-threaded ``rollout``.

Each call advances a batch of lanes by whole gait periods. ``rollout`` returns
every step's state, so lanes are processed in slices whose per-period output
stays under ``memory_budget`` bytes; only per-period records leave this module
(plus a strided track when asked for).
"""

from __future__ import annotations

import os

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from .core import (BackendBase, collision_bin_of, COLLISION_WIDTH, CONTACT_KINDS, SENSOR_WIDTH, Lanes, PeriodRecords, Record, Scene, Status,
                   blank_collisions, lane_controls, on_step_grid, steps_per_period)

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS.value


def state_offsets(model: mujoco.MjModel) -> tuple[int, int]:
    """Index of qpos and qvel inside a FULLPHYSICS state vector."""
    t = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME.value)
    nq = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_QPOS.value)
    return t, t + nq


class NativeBackend(BackendBase):
    """Batched native MuJoCo rollouts on ``nthread`` threads (default: all cores)."""

    name = "native"
    batching = "occupied"  # see engine.core.BATCHING

    def __init__(self, scene: Scene, nthread: int | None = None, memory_budget: float = 256e6,
                 penetration_limit: float = 0.002):
        self.scene = scene
        self.model = scene.model
        self.nthread = max(1, nthread if nthread is not None else (os.cpu_count() or 1))
        self.datas = [mujoco.MjData(self.model) for _ in range(self.nthread)]
        self.pool = mj_rollout.Rollout(nthread=self.nthread if self.nthread > 1 else 0)
        self.nstate = mujoco.mj_stateSize(self.model, _FULL)
        self.qpos_at, self.qvel_at = state_offsets(self.model)
        self.memory_budget = memory_budget
        self.penetration_limit = penetration_limit

    def close(self):
        if self.pool is not None:
            self.pool.close()
            self.pool = None

    def initial_state(self, lanes: Lanes) -> np.ndarray:
        """FULLPHYSICS states [B, nstate] at t = 0 with the lanes' poses at rest."""
        m = self.model
        d = self.datas[0]
        mujoco.mj_resetData(m, d)
        base = np.empty(self.nstate)
        mujoco.mj_getState(m, d, base, _FULL)
        state = np.tile(base, (lanes.size, 1))
        state[:, self.qpos_at:self.qpos_at + m.nq] = self.scene.qpos_from_poses(lanes.poses)
        if m.na:
            act_at = self.qvel_at + m.nv
            state[:, act_at:act_at + m.na] = self.scene.initial_act(lanes)
        state[:, 0] = 0.0
        return state

    def advance(self, state: np.ndarray, lanes: Lanes, n_periods: int, *, t0: float = 0.0,
                record: Record | None = None):
        """Advance ``state`` [B, nstate] by ``n_periods`` whole gait periods.

        Every lane must be at gait phase 0 (a whole number of periods into its
        run); lanes need not share a clock. ``t0`` labels track times and, for
        robots with their own gait period (``lanes.robot_period``), is the
        time since the run's start that sets their phase (:meth:`Lanes.at_time`);
        [B] when the lanes started at different times (no track then).
        ``record`` says what to keep beyond the per-period records.

        Returns:
          (new_state, PeriodRecords, track) where track is None or a dict with
          ``t`` [S] and ``qpos`` [B, S, nq] sampled every ``record.track_stride`` steps.
        """
        record = record or Record()
        record.validate()
        track_stride = record.track_stride
        if track_stride and np.ndim(t0):
            raise ValueError("a full-rate track needs one start time t0 for every lane")
        if record.collisions and not self.scene.collisions:
            raise ValueError("the collision record needs a scene built with Scene.build(..., collisions=True)")
        m = self.model
        dt = m.opt.timestep
        lanes = on_step_grid(lanes, dt)
        nstep = steps_per_period(lanes.period, dt)
        b, n_pairs = lanes.size, self.scene.n_pairs
        per_lane = nstep * (self.nstate + m.nsensordata + m.nu) * 8
        slice_size = max(1, min(b, int(self.memory_budget // per_lane)))
        poses = np.empty((b, n_periods, self.scene.n_robots, 5))
        touched = np.zeros((b, n_periods, n_pairs), dtype=bool)
        min_dist = np.full((b, n_periods, n_pairs), np.inf)
        status = np.zeros(b, dtype=np.int32)
        coll = blank_collisions(b, n_periods, n_pairs, record.collision_bins) if record.collisions else None
        state = np.array(state, dtype=np.float64, copy=True)
        track_t, track_q = [], []
        # every call starts at gait phase 0 and the gait is periodic, so the
        # controls of one period serve every period and every lane's clock
        # (robots with their own period: recomputed each period at their phase then)
        t_rel = dt * np.arange(nstep)
        ctrl_all = None
        for k in range(n_periods):
            t_start = t0 + k * lanes.period
            lanes_k = lanes.at_time(t_start)
            if b <= slice_size and (k == 0 or lanes.varies):
                ctrl_all = lane_controls(self.scene, lanes_k, t_rel)
            out_q = []
            for lo in range(0, b, slice_size):
                sl = slice(lo, min(b, lo + slice_size))
                ctrl = ctrl_all[sl] if ctrl_all is not None else lane_controls(self.scene, lanes_k.take(sl), t_rel)
                init = state[sl].copy()
                states, sens = self.pool.rollout(
                    m, self.datas, init, ctrl, nstep=nstep)
                if coll is not None:
                    self._collisions(coll, sl, k, init, states, sens, nstep, record.collision_bins)
                sens = sens[..., :n_pairs * SENSOR_WIDTH].reshape(sens.shape[0], nstep, n_pairs, SENSOR_WIDTH)
                found = sens[..., 0] > 0
                touched[sl, k] = found.any(1)
                dist = np.where(found, sens[..., 1], np.inf).min(1)
                min_dist[sl, k] = dist
                final = states[:, -1]
                bad = ~np.isfinite(states).all(axis=(1, 2))
                # MuJoCo answers a NaN, Inf or huge acceleration by resetting the data to the model's
                # rest state (a warning, then finite numbers: robots jump to the placeholder poses).
                # The reset sets the clock back to 0, so a step whose time does not advance marks it.
                clock = np.concatenate([init[:, :1], states[:, :, 0]], axis=1)
                bad |= (np.diff(clock, axis=1) <= 0).any(1)
                status[sl] |= np.where(bad, int(Status.NONFINITE), 0)
                status[sl] |= np.where((dist < -self.penetration_limit).any(-1), int(Status.PENETRATION), 0)
                state[sl] = final
                poses[sl, k] = self.scene.poses_from_qpos(final[:, self.qpos_at:self.qpos_at + m.nq])
                if track_stride:
                    out_q.append(states[:, track_stride - 1::track_stride, self.qpos_at:self.qpos_at + m.nq])
            if track_stride:
                track_q.append(np.concatenate(out_q, 0))
                track_t.append(t_start + t_rel[track_stride - 1::track_stride] + dt)
        track = None
        if track_stride:
            track = {"t": np.concatenate(track_t), "qpos": np.concatenate(track_q, 1)}
        return state, PeriodRecords(poses, touched, min_dist, status, coll), track

    def _collisions(self, coll: dict, sl: slice, k: int, init, states, sens, nstep: int, bins: int):
        """Fold one period's contact-force sensors into the collision record."""
        m, lay = self.model, self.scene.layout
        n_pairs, n_kinds = self.scene.n_pairs, len(CONTACT_KINDS)
        cs = sens[..., n_pairs * SENSOR_WIDTH:].reshape(sens.shape[0], nstep, n_pairs, n_kinds, COLLISION_WIDTH)
        # the sensors of step s read the forces that acted during step s, on the
        # state the step started from: the previous row of ``states`` (or the
        # period's initial state for the first step)
        qa = slice(self.qpos_at, self.qpos_at + m.nq)
        q = np.concatenate([init[:, None, qa], states[:, :-1, qa]], 1)
        dt = m.opt.timestep
        bin_of = collision_bin_of(nstep, bins)
        for p, (i, j) in enumerate(lay.pairs):
            ci, cj = q[..., lay.free_qpos[i]:lay.free_qpos[i] + 2], q[..., lay.free_qpos[j]:lay.free_qpos[j] + 2]
            rvec = cj - ci
            rhat = rvec / np.maximum(np.linalg.norm(rvec, axis=-1, keepdims=True), 1e-12)  # [b, nstep, 2]
            found = cs[:, :, p, :, 0] > 0  # [b, nstep, kinds]
            imp = cs[:, :, p, :, 1:3] * dt  # [b, nstep, kinds, 2]
            imp_r = (imp * rhat[:, :, None, :]).sum(-1)
            for g in range(bins):
                at = bin_of == g
                coll["steps"][sl, k, p, :, g] = found[:, at].sum(1)
                coll["impulse"][sl, k, p, :, g] = imp[:, at].sum(1)
                coll["impulse_r"][sl, k, p, :, g] = imp_r[:, at].sum(1)

    def step_qpos(self, lanes: Lanes, nsteps: int) -> np.ndarray:
        """qpos [B, nsteps, nq] of the first ``nsteps`` steps from rest."""
        dt = self.model.opt.timestep
        lanes = on_step_grid(lanes, dt)
        ctrl = lane_controls(self.scene, lanes, dt * np.arange(nsteps))
        states, _ = self.pool.rollout(self.model, self.datas, self.initial_state(lanes), ctrl, nstep=nsteps)
        return states[:, :, self.qpos_at:self.qpos_at + self.model.nq]
