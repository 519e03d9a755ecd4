"""Native backend: MuJoCo's C engine through its multi-threaded ``rollout``.

Each call advances a batch of lanes by whole gait periods. ``rollout`` returns
every step's state, so lanes are processed in slices whose per-period output
stays under ``memory_budget`` bytes; only per-period records leave this module
(plus a strided track when asked for).
"""

from __future__ import annotations

import copy
import os

import mujoco
import numpy as np
from mujoco import rollout as mj_rollout

from .gate import chunk_steps, make_gate
from .core import (BackendBase, collision_bin_of, COLLISION_WIDTH, CONTACT_KINDS, SENSOR_WIDTH, Lanes, PeriodRecords, Record, Scene, Status,
                   blank_collisions, lane_controls, on_step_grid, steps_per_period)

_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS.value


def state_offsets(model: mujoco.MjModel) -> tuple[int, int]:
    """Index of qpos and qvel inside a FULLPHYSICS state vector."""
    t = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_TIME.value)
    nq = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_QPOS.value)
    return t, t + nq


def _joined_track(track_t: list, track_q: list) -> dict | None:
    """The periods' strided track pieces as one track (None when no track was asked for)."""
    if not track_t:
        return None
    return {"t": np.concatenate(track_t), "qpos": np.concatenate(track_q, 1)}


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
        self.substeps = scene.params.contact_substeps
        if self.substeps > 1:  # the same compiled model at the sub-step: every solref stays in seconds
            self.fine_model = copy.deepcopy(self.model)
            self.fine_model.opt.timestep = scene.params.sub_timestep
            self.fine_datas = [mujoco.MjData(self.fine_model) for _ in range(self.nthread)]
            self.gate = make_gate(scene.layout, scene.params.robot, scene.params.substep_gate)
            self.substep_stats = [0, 0]  # coarse steps run whole, and split, since the backend was made

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
        if self.substeps > 1 and self.scene.n_robots > 1:
            return self._advance_gated(state, lanes, n_periods, t0, record)
        m = self.model
        dt = m.opt.timestep
        lanes = on_step_grid(lanes, dt)
        nstep = steps_per_period(lanes.period, dt)
        b, n_pairs = lanes.size, self.scene.n_pairs
        per_lane = nstep * (self.nstate + m.nsensordata + m.nu) * 8
        slice_size = max(1, min(b, int(self.memory_budget // per_lane)))
        poses, touched, min_dist, status, coll = self._blank_records(b, n_periods, record)
        bin_of = collision_bin_of(nstep, record.collision_bins) if record.collisions else None
        state = np.array(state, dtype=np.float64, copy=True)
        track_t, track_q = [], []
        # every call starts at gait phase 0 and the gait is periodic, so the
        # controls of one period serve every period and every lane's clock
        # (robots with their own period: recomputed each period at their phase then)
        t_rel = dt * np.arange(nstep)
        ctrl_all = None
        for k in range(n_periods):
            t_start = t0 + k * lanes.period
            lanes_k = lanes.at_time(t_start).started(t_start)
            if b <= slice_size and (k == 0 or lanes.varies or (k == 1 and lanes.starts_apart)):
                ctrl_all = lane_controls(self.scene, lanes_k, t_rel)
            out_q = []
            for lo in range(0, b, slice_size):
                sl = slice(lo, min(b, lo + slice_size))
                ctrl = ctrl_all[sl] if ctrl_all is not None else lane_controls(self.scene, lanes_k.take(sl), t_rel)
                init = state[sl].copy()
                states, sens = self.pool.rollout(
                    m, self.datas, init, ctrl, nstep=nstep)
                if coll is not None:
                    self._collisions(coll, sl, k, init, states, sens, bin_of, 1, dt)
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
                status[sl] |= self._status_bits(bad, dist)
                state[sl] = final
                poses[sl, k] = self.scene.poses_from_qpos(final[:, self.qpos_at:self.qpos_at + m.nq])
                if track_stride:
                    out_q.append(states[:, track_stride - 1::track_stride, self.qpos_at:self.qpos_at + m.nq])
            if track_stride:
                track_q.append(np.concatenate(out_q, 0))
                track_t.append(t_start + t_rel[track_stride - 1::track_stride] + dt)
        return state, PeriodRecords(poses, touched, min_dist, status, coll), _joined_track(track_t, track_q)

    def _advance_gated(self, state: np.ndarray, lanes: Lanes, n_periods: int, t0, record: Record):
        """:meth:`advance` with near-contact sub-stepping (``SceneParams.contact_substeps`` = K > 1).

        Every ``C`` steps (:func:`gate.chunk_steps`: robots ``substep_gate`` apart cannot meet in fewer)
        each lane's robots are asked how far apart they are at least (:func:`gate.gap_lower_bound`
        over every pair); lanes with a pair nearer than the gate run the next C steps as C x K steps of
        timestep / K, the others as C steps. The records are those of :meth:`advance`: touches,
        deepest contacts and penetration from every (sub-)step, the collision record's step counts on
        the full step's grid (a step counts when any of its sub-steps touched), impulses of every
        sub-step, tracks on the full step's grid. Each chunk starts the solver cold, as each period
        of :meth:`advance` does.
        """
        m, mf, k_sub = self.model, self.fine_model, self.substeps
        dt = m.opt.timestep
        track_stride = record.track_stride
        lanes = on_step_grid(lanes, dt)
        nstep = steps_per_period(lanes.period, dt)
        chunk = chunk_steps(dt, self.scene.params.substep_gate)
        near_of = self.gate
        b, n_pairs = lanes.size, self.scene.n_pairs
        per_lane = nstep * (1 + k_sub) * m.nu * 8 + (nstep * m.nq * 8 if track_stride else 0)
        slice_size = max(1, min(b, int(self.memory_budget // per_lane)))
        poses, touched, min_dist, status, coll = self._blank_records(b, n_periods, record)
        bin_of = collision_bin_of(nstep, record.collision_bins) if record.collisions else None
        state = np.array(state, dtype=np.float64, copy=True)
        qa = slice(self.qpos_at, self.qpos_at + m.nq)
        track_t, track_q = [], []
        t_rel = dt * np.arange(nstep)
        t_fine = (dt / k_sub) * np.arange(nstep * k_sub)
        ctrl_all = None
        for k in range(n_periods):
            t_start = t0 + k * lanes.period
            lanes_k = lanes.at_time(t_start).started(t_start)
            # one period's controls serve every period (after a first one with start delays)
            if b <= slice_size and (k == 0 or lanes.varies or (k == 1 and lanes.starts_apart)):
                ctrl_all = lane_controls(self.scene, lanes_k, t_rel), lane_controls(self.scene, lanes_k, t_fine)
            out_q = []
            for lo in range(0, b, slice_size):
                sl = slice(lo, min(b, lo + slice_size))
                if ctrl_all is not None:
                    ctrl_c, ctrl_f = ctrl_all
                else:
                    ctrl_c, ctrl_f = (lane_controls(self.scene, lanes_k.take(sl), t) for t in (t_rel, t_fine))
                st = state[sl].copy()
                nb = st.shape[0]
                found = np.zeros((nb, n_pairs), bool)
                dist = np.full((nb, n_pairs), np.inf)
                bad = np.zeros(nb, bool)
                q_grid = np.empty((nb, nstep, m.nq)) if track_stride else None
                for c0 in range(0, nstep, chunk):
                    n = min(chunk, nstep - c0)
                    near = near_of(st[:, qa])
                    for fine in (False, True):
                        idx = np.flatnonzero(near == fine)
                        if not idx.size:
                            continue
                        kk = k_sub if fine else 1
                        ctrl = (ctrl_f[idx, c0 * k_sub:(c0 + n) * k_sub] if fine else ctrl_c[idx, c0:c0 + n])
                        init = st[idx]
                        states, sens = self.pool.rollout(mf if fine else m, self.fine_datas if fine else self.datas,
                                                         init, ctrl, nstep=n * kk)
                        self.substep_stats[int(fine)] += idx.size * n
                        if coll is not None:
                            self._collisions(coll, lo + idx, k, init, states, sens, bin_of[c0:c0 + n], kk, dt / kk)
                        ps = sens[..., :n_pairs * SENSOR_WIDTH].reshape(idx.size, n * kk, n_pairs, SENSOR_WIDTH)
                        f = ps[..., 0] > 0
                        found[idx] |= f.any(1)
                        dist[idx] = np.minimum(dist[idx], np.where(f, ps[..., 1], np.inf).min(1))
                        clock = np.concatenate([init[:, :1], states[:, :, 0]], axis=1)
                        bad[idx] |= ~np.isfinite(states).all(axis=(1, 2)) | (np.diff(clock, axis=1) <= 0).any(1)
                        if q_grid is not None:
                            q_grid[idx, c0:c0 + n] = states[:, kk - 1::kk, qa]
                        st[idx] = states[:, -1]
                touched[sl, k] = found
                min_dist[sl, k] = dist
                status[sl] |= self._status_bits(bad, dist)
                state[sl] = st
                poses[sl, k] = self.scene.poses_from_qpos(st[:, qa])
                if track_stride:
                    out_q.append(q_grid[:, track_stride - 1::track_stride])
            if track_stride:
                track_q.append(np.concatenate(out_q, 0))
                track_t.append(t_start + t_rel[track_stride - 1::track_stride] + dt)
        return state, PeriodRecords(poses, touched, min_dist, status, coll), _joined_track(track_t, track_q)

    def _blank_records(self, b: int, n_periods: int, record: Record):
        """Empty per-period records of ``b`` lanes: poses, touches, deepest contacts, status, collisions."""
        n_pairs = self.scene.n_pairs
        return (np.empty((b, n_periods, self.scene.n_robots, 5)), np.zeros((b, n_periods, n_pairs), dtype=bool),
                np.full((b, n_periods, n_pairs), np.inf), np.zeros(b, dtype=np.int32),
                blank_collisions(b, n_periods, n_pairs, record.collision_bins) if record.collisions else None)

    def _status_bits(self, bad: np.ndarray, dist: np.ndarray) -> np.ndarray:
        """Status bits of a slice's period: non-finite (or reset) states, and contacts past the penetration limit."""
        return (np.where(bad, int(Status.NONFINITE), 0)
                | np.where((dist < -self.penetration_limit).any(-1), int(Status.PENETRATION), 0))

    def _collisions(self, coll: dict, lanes_at, k: int, init, states, sens, bins_of_steps, kk: int, dt_row: float):
        """Fold the contact-force sensors of ``len(bins_of_steps)`` full steps of period ``k``, run as ``kk``
        sub-steps each (rows of ``dt_row`` s; kk = 1: whole steps), into the collision record of lanes
        ``lanes_at``: impulses of every row, a full step counted in contact when any of its sub-steps was.
        The sensors of a row read the forces that acted during it, on the state it started from: the
        previous row of ``states`` (or ``init`` for the first)."""
        m, lay = self.model, self.scene.layout
        n_pairs, n_kinds = self.scene.n_pairs, len(CONTACT_KINDS)
        nb, rows = states.shape[0], states.shape[1]
        cs = sens[..., n_pairs * SENSOR_WIDTH:].reshape(nb, rows, n_pairs, n_kinds, COLLISION_WIDTH)
        qa = slice(self.qpos_at, self.qpos_at + m.nq)
        q = np.concatenate([init[:, None, qa], states[:, :-1, qa]], 1)
        row_bin = np.repeat(bins_of_steps, kk)
        for p, (i, j) in enumerate(lay.pairs):
            ci, cj = q[..., lay.free_qpos[i]:lay.free_qpos[i] + 2], q[..., lay.free_qpos[j]:lay.free_qpos[j] + 2]
            rvec = cj - ci
            rhat = rvec / np.maximum(np.linalg.norm(rvec, axis=-1, keepdims=True), 1e-12)
            found = cs[:, :, p, :, 0] > 0  # [nb, rows, kinds]
            step_found = found.reshape(nb, rows // kk, kk, n_kinds).any(2)
            imp = cs[:, :, p, :, 1:3] * dt_row
            imp_r = (imp * rhat[:, :, None, :]).sum(-1)
            for g in np.unique(bins_of_steps):
                at, at_row = bins_of_steps == g, row_bin == g
                coll["steps"][lanes_at, k, p, :, g] += step_found[:, at].sum(1).astype(np.int32)
                coll["impulse"][lanes_at, k, p, :, g] += imp[:, at_row].sum(1).astype(np.float32)
                coll["impulse_r"][lanes_at, k, p, :, g] += imp_r[:, at_row].sum(1).astype(np.float32)

    def step_qpos(self, lanes: Lanes, nsteps: int) -> np.ndarray:
        """qpos [B, nsteps, nq] of the first ``nsteps`` steps from rest."""
        dt = self.model.opt.timestep
        lanes = on_step_grid(lanes, dt)
        ctrl = lane_controls(self.scene, lanes, dt * np.arange(nsteps))
        states, _ = self.pool.rollout(self.model, self.datas, self.initial_state(lanes), ctrl, nstep=nsteps)
        return states[:, :, self.qpos_at:self.qpos_at + self.model.nq]


def step_lane(scene: Scene, lanes: Lanes, periods: int):
    """Step the one lane of ``lanes`` (already on the step grid) with ``mj_step``, one step at a time, as
    :class:`NativeBackend` runs it: its initial state, each period's controls at that period's phase, and
    each period started from a zero warm start as the backend's rollout does (a replay of a stored lane
    crosses its stored flags). Yields (period, step, MjData) after every step; the MjData is reused."""
    be = NativeBackend(scene, nthread=1)
    state = be.initial_state(lanes)
    be.close()
    m = scene.model
    d = mujoco.MjData(m)
    mujoco.mj_setState(m, d, np.asarray(state[0]), mujoco.mjtState.mjSTATE_FULLPHYSICS)
    dt = m.opt.timestep
    nstep = int(round(lanes.period / dt))
    for p in range(periods):
        ctrl = lane_controls(scene, lanes.at_time(p * lanes.period).started(p * lanes.period),
                             dt * np.arange(nstep))[0]
        d.qacc_warmstart[:] = 0.0
        for k in range(nstep):
            d.ctrl[:] = ctrl[k]
            mujoco.mj_step(m, d)
            yield p, k, d
