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

from .core import SENSOR_WIDTH, Lanes, PeriodRecords, Scene, Status, lane_controls, on_step_grid, steps_per_period

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS.value


def state_offsets(model: mujoco.MjModel) -> tuple[int, int]:
    """Index of qpos and qvel inside a FULLPHYSICS state vector."""
    t = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME.value)
    nq = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_QPOS.value)
    return t, t + nq


class NativeBackend:
    """Batched native MuJoCo rollouts on ``nthread`` threads (default: all cores)."""

    name = "native"

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
        state[:, 0] = 0.0
        return state

    def advance(self, state: np.ndarray, lanes: Lanes, n_periods: int, *, t0: float = 0.0,
                track_stride: int | None = None):
        """Advance ``state`` [B, nstate] by ``n_periods`` whole gait periods.

        Every lane must be at gait phase 0 (a whole number of periods into its
        run); lanes need not share a clock. ``t0`` only labels track times.

        Returns:
          (new_state, PeriodRecords, track) where track is None or a dict with
          ``t`` [S] and ``qpos`` [B, S, nq] sampled every ``track_stride`` steps.
        """
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
        state = np.array(state, dtype=np.float64, copy=True)
        track_t, track_q = [], []
        # every call starts at gait phase 0 and the gait is periodic, so the
        # controls of one period serve every period and every lane's clock
        t_rel = dt * np.arange(nstep)
        ctrl_all = lane_controls(self.scene, lanes, t_rel) if b <= slice_size else None
        for k in range(n_periods):
            t_start = t0 + k * lanes.period
            out_q = []
            for lo in range(0, b, slice_size):
                sl = slice(lo, min(b, lo + slice_size))
                ctrl = ctrl_all[sl] if ctrl_all is not None else lane_controls(self.scene, lanes.take(sl), t_rel)
                init = state[sl].copy()
                states, sens = self.pool.rollout(
                    m, self.datas, init, ctrl, nstep=nstep)
                sens = sens.reshape(sens.shape[0], nstep, n_pairs, SENSOR_WIDTH)
                found = sens[..., 0] > 0
                touched[sl, k] = found.any(1)
                dist = np.where(found, sens[..., 1], np.inf).min(1)
                min_dist[sl, k] = dist
                final = states[:, -1]
                bad = ~np.isfinite(states).all(axis=(1, 2))
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
        return state, PeriodRecords(poses, touched, min_dist, status), track

    def step_qpos(self, lanes: Lanes, nsteps: int) -> np.ndarray:
        """qpos [B, nsteps, nq] of the first ``nsteps`` steps from rest."""
        dt = self.model.opt.timestep
        lanes = on_step_grid(lanes, dt)
        ctrl = lane_controls(self.scene, lanes, dt * np.arange(nsteps))
        states, _ = self.pool.rollout(self.model, self.datas, self.initial_state(lanes), ctrl, nstep=nsteps)
        return states[:, :, self.qpos_at:self.qpos_at + self.model.nq]
