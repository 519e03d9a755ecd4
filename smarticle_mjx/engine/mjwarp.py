"""Warp backend: MuJoCo Warp (``mujoco_warp``) on a GPU, or on Warp's CPU device.

One MuJoCo Warp ``Data`` holds the batch, one world per lane. A lane's state
travels between calls as a host vector (:meth:`WarpBackend.initial_state`),
as the native backend's does, so early exit and refill (``engine.batch``)
work unchanged: a refilled lane is a new row written into the next upload.

Per step, on the device: a kernel copies each world's controls from a table
of one gait period (built by the same pure gait function as the other
backends, one row per distinct gait of the batch), ``mujoco_warp.step``
advances every world, and a kernel folds the scene's touch sensors (the same
``found dist`` contact sensors the native backend reads) into per-period
touch and deepest-contact records. On CUDA the three are captured once as a
graph and replayed, so Python pays one launch per step whatever the batch.

Warp computes in float32. Contact and constraint buffers are sized from the
scene (:func:`buffer_sizes`) for the worst case every geom pair allows; if
MuJoCo Warp still reports an overflow, every lane of that step carries
``Status.OVERFLOW`` (MuJoCo Warp's contact pool is shared by all worlds, so
an overflow cannot be pinned on one lane).
"""

from __future__ import annotations

import copy
import dataclasses
import time

import mujoco
import numpy as np

from .core import (BackendBase, Lanes, check_records, check_solver, check_start_delays, check_timing, PeriodRecords,
                   Record, Scene, Status, refuse_mounts, distinct_gaits, lane_controls, on_step_grid, steps_per_period)

MISSING = "the warp backend needs MuJoCo Warp: pip install -e '.[gpu]'"


def available() -> bool:
    """True when ``mujoco_warp`` and ``warp`` can be imported."""
    import importlib.util
    return all(importlib.util.find_spec(m) is not None for m in ("warp", "mujoco_warp"))


# Most contacts MuJoCo (and MuJoCo Warp) reports for one geom pair, by geom
# types (sorted mjtGeom codes). Pairs not listed use mjMAXCONPAIR, the bound
# of the general convex collider.
_G = mujoco.mjtGeom
MAX_CONTACTS = {
    (int(_G.mjGEOM_PLANE), int(_G.mjGEOM_SPHERE)): 1,
    (int(_G.mjGEOM_PLANE), int(_G.mjGEOM_CAPSULE)): 2,
    (int(_G.mjGEOM_PLANE), int(_G.mjGEOM_BOX)): 4,
    (int(_G.mjGEOM_SPHERE), int(_G.mjGEOM_SPHERE)): 1,
    (int(_G.mjGEOM_SPHERE), int(_G.mjGEOM_CAPSULE)): 1,
    (int(_G.mjGEOM_SPHERE), int(_G.mjGEOM_BOX)): 1,
    (int(_G.mjGEOM_CAPSULE), int(_G.mjGEOM_CAPSULE)): 2,
    (int(_G.mjGEOM_CAPSULE), int(_G.mjGEOM_BOX)): 2,
    (int(_G.mjGEOM_BOX), int(_G.mjGEOM_BOX)): 8,
}


def collision_pairs(model: mujoco.MjModel) -> list[tuple[int, int]]:
    """Geom pairs MuJoCo's collision filter lets through (dynamic pairs only).

    MuJoCo's rules: geoms on different bodies, not both on the world body,
    contype/conaffinity compatible, bodies not parent and child (unless the
    parent is the world), body pairs not excluded; plus explicit ``<pair>``s.
    """
    excluded = {int(s) for s in model.exclude_signature[:model.nexclude]}
    filterparent = not (model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)
    out = set()
    for g1 in range(model.ngeom):
        for g2 in range(g1 + 1, model.ngeom):
            b1, b2 = int(model.geom_bodyid[g1]), int(model.geom_bodyid[g2])
            if b1 == b2 or (model.body_weldid[b1] == 0 and model.body_weldid[b2] == 0):
                continue
            if not ((model.geom_contype[g1] & model.geom_conaffinity[g2]) or
                    (model.geom_contype[g2] & model.geom_conaffinity[g1])):
                continue
            w1, w2 = int(model.body_weldid[b1]), int(model.body_weldid[b2])
            if filterparent and w1 and w2 and (model.body_parentid[w1] == w2 or model.body_parentid[w2] == w1):
                continue
            lo, hi = min(b1, b2), max(b1, b2)
            if (lo << 16) + hi in excluded:
                continue
            out.add((g1, g2))
    for p in range(model.npair):
        g1, g2 = int(model.pair_geom1[p]), int(model.pair_geom2[p])
        out.add((min(g1, g2), max(g1, g2)))
    return sorted(out)


def buffer_sizes(model: mujoco.MjModel) -> tuple[int, int]:
    """(nconmax, njmax) per world: the most contacts and constraint rows the scene can produce.

    Contacts: the sum over colliding geom pairs of :data:`MAX_CONTACTS`
    (at least the number of pairs, the broadphase's candidate count).
    Rows: per contact the larger of an elliptic (condim) and a pyramidal
    (2 (condim - 1)) cone, plus two per limited joint, one per dof with
    friction loss, and six per equality constraint.
    """
    pairs = collision_pairs(model)
    ncon = 0
    rows = 0
    for g1, g2 in pairs:
        key = tuple(sorted((int(model.geom_type[g1]), int(model.geom_type[g2]))))
        n = MAX_CONTACTS.get(key, mujoco.mjMAXCONPAIR)
        condim = max(int(model.geom_condim[g1]), int(model.geom_condim[g2]))
        ncon += n
        rows += n * max(condim, 2 * (condim - 1), 1)
    rows += 2 * int(np.sum(model.jnt_limited)) + int(np.sum(model.dof_frictionloss > 0)) + 6 * model.neq
    return max(ncon, len(pairs), 1), max(rows, 1)


# MuJoCo Warp's buffer overflows (OverflowType): results of that step are not trustworthy.
_BUFFER_BITS = (1 << 0) | (1 << 1) | (1 << 2) | (1 << 3) | (1 << 4) | (1 << 6)  # NEFC NNZ BROAD NARROW CCD MATCH


def _kernels():
    """The backend's three small kernels (their module imports Warp, which is optional)."""
    from . import warp_kernels as k
    return k.set_ctrl, k.record, k.tick


# constraint solvers MuJoCo Warp implements (no PGS)
WARP_SOLVERS = ("Newton", "CG")

# how MuJoCo Warp collides box pairs (WarpBackend's box_collider)
BOX_COLLIDERS = ("analytic", "convex")
BOX_COLLIDER = "analytic"  # the default (since 0.4.2; "convex" before), which benchmarks record

@dataclasses.dataclass
class _Batch:
    """Device buffers of one batch size (MuJoCo Warp data, records, control table)."""

    nworld: int
    data: object
    row: object
    step: object
    touched: object
    mind: object
    finite: object
    table: object = None
    graph: object = None


class WarpBackend(BackendBase):
    """Batched MuJoCo Warp rollouts on one Warp device (default: the first GPU, else the CPU).

    Args:
      scene: the compiled scene (its touch sensors are read as the native backend reads them).
      device: a Warp device name ("cuda:0", "cpu"); None picks the first GPU, else the CPU.
      penetration_limit: deeper inter-robot contact than this (m) sets ``Status.PENETRATION``.
      deterministic: MuJoCo Warp's deterministic mode (stable contact order,
        invariant reductions), so a lane's result does not depend on the rest
        of its batch; it costs some speed (measured in benchmarks/engine.py).
      graph: capture each step as a CUDA graph (ignored on the CPU).
      box_collider: "analytic" (default): box pairs through MuJoCo Warp's port
        of the analytic box-box collider, the one MuJoCo C uses (set with
        MuJoCo's NATIVECCD disable flag on the backend's copy of the model);
        "convex": MuJoCo Warp's own default for box pairs, GJK/EPA, which on a
        GPU reports rare phantom contacts a box's thickness deep (3.2 mm for
        an arm plate; docs/engine.md) and so flags about 3 % of a paper scan's
        lanes. Kept to reproduce stores made before version 0.4.2.
    """

    name = "warp"
    batching = "pow2"  # see engine.core.BATCHING

    def __init__(self, scene: Scene, device: str | None = None, penetration_limit: float = 0.002,
                 deterministic: bool = False, graph: bool = True, box_collider: str = BOX_COLLIDER):
        check_solver(scene, "warp", WARP_SOLVERS)
        if box_collider not in BOX_COLLIDERS:
            raise ValueError(f"box_collider must be one of {', '.join(BOX_COLLIDERS)}, got {box_collider!r}")
        refuse_mounts(scene.params, "warp")
        if not available():
            raise ValueError(MISSING)
        import warp as wp
        wp.config.quiet = True
        import mujoco_warp as mjw
        self._wp, self._mjw = wp, mjw
        self.scene = scene
        self.model = scene.model
        if scene.params.contact_substeps > 1:
            # near-contact sub-stepping (SceneParams.contact_substeps): the GPU's lanes run in lock-step, so
            # a lane that skips sub-steps saves nothing; every step is split (the gate always open)
            self.model = copy.deepcopy(scene.model)
            self.model.opt.timestep = scene.params.sub_timestep
        self.box_collider = box_collider
        if box_collider == "analytic":
            if self.model is scene.model:
                self.model = copy.deepcopy(scene.model)
            self.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_NATIVECCD  # read by MuJoCo Warp only
        self.device = wp.get_device(device if device is not None else
                                    ("cuda:0" if wp.is_cuda_available() else "cpu"))
        self.penetration_limit = penetration_limit
        self.nconmax, self.njmax = buffer_sizes(self.model)
        with wp.ScopedDevice(self.device):
            self.mw = mjw.put_model(self.model)
        self.mw.opt.warn_overflow = 0  # overflows are reported per lane in the status instead
        self.mw.opt.deterministic = bool(deterministic)
        self.graph = bool(graph) and self.device.is_cuda
        m = self.model
        # state vector: qpos, qvel, act, qacc_warmstart
        self.cuts = np.cumsum([0, m.nq, m.nv, m.na, m.nv])  # state layout: qpos | qvel | act | warm start
        self.nstate = int(self.cuts[-1])
        self._adr = wp.array(np.asarray(m.sensor_adr[:scene.n_pairs], np.int32), dtype=wp.int32, device=self.device)
        self._kern = _kernels()
        self._batch: _Batch | None = None
        self._batches: dict[int, _Batch] = {}
        self.keep_batches = 4
        self.capture_s = 0.0  # time of the last CUDA graph capture

    def close(self):
        self._batch = None
        self._batches.clear()

    # ---- state ----------------------------------------------------------
    def initial_state(self, lanes: Lanes) -> np.ndarray:
        """States [B, nstate] at t = 0: the lanes' poses at rest, no warm start."""
        m = self.model
        s = np.zeros((lanes.size, self.nstate))
        c = self.cuts
        s[:, c[0]:c[1]] = self.scene.qpos_from_poses(lanes.poses)
        if m.na:
            s[:, c[2]:c[3]] = self.scene.initial_act(lanes)
        return s

    def _fields(self, d):
        return (d.qpos, d.qvel, d.act, d.qacc_warmstart)

    def _upload(self, b: _Batch, state: np.ndarray):
        wp = self._wp
        c = self.cuts
        for k, arr in enumerate(self._fields(b.data)):
            if c[k + 1] > c[k]:
                arr.assign(wp.array(np.ascontiguousarray(state[:, c[k]:c[k + 1]], np.float32), device=self.device))
        b.data.time.zero_()
        b.data.overflow.zero_()

    def _download(self, b: _Batch) -> np.ndarray:
        c = self.cuts
        out = np.zeros((b.nworld, self.nstate))
        for k, arr in enumerate(self._fields(b.data)):
            if c[k + 1] > c[k]:
                out[:, c[k]:c[k + 1]] = arr.numpy()
        return out

    # ---- buffers --------------------------------------------------------
    def _batch_for(self, nworld: int) -> _Batch:
        """Buffers for ``nworld`` worlds; the few most recent sizes are kept
        (early exit runs power-of-two sub-batches, engine.batch)."""
        if nworld in self._batches:
            self._batch = self._batches.pop(nworld)
            self._batches[nworld] = self._batch
            return self._batch
        while len(self._batches) >= self.keep_batches:
            self._batches.pop(next(iter(self._batches)))
        wp, mjw = self._wp, self._mjw
        p = max(1, self.scene.n_pairs)
        with wp.ScopedDevice(self.device):
            d = mjw.make_data(self.model, nworld=nworld, nconmax=self.nconmax, njmax=self.njmax)
            self._batch = _Batch(nworld, d, wp.zeros(nworld, dtype=wp.int32), wp.zeros(1, dtype=wp.int32),
                                 wp.zeros((nworld, p), dtype=wp.int32), wp.zeros((nworld, p), dtype=wp.float32),
                                 wp.ones(nworld, dtype=wp.int32))
        self._batches[nworld] = self._batch
        return self._batch

    def _set_table(self, b: _Batch, lanes: Lanes, nstep: int):
        """Controls of one period, one row per distinct gait among the lanes."""
        check_timing(lanes, "warp")  # its control table holds one period
        wp = self._wp
        first, row = distinct_gaits(lanes)  # lanes with one gait share a row
        dt = float(self.model.opt.timestep)
        ctrl = lane_controls(self.scene, lanes.take(first), dt * np.arange(nstep)).astype(np.float32)
        shape = (max(len(first), 1), nstep, self.model.nu)
        if b.table is None or b.table.shape[1] != nstep or b.table.shape[0] < len(first):
            cap = max(len(first), 4)
            b.table = wp.zeros((cap, nstep, self.model.nu), dtype=wp.float32, device=self.device)
            b.graph = None  # captured with the old table's address
        full = np.zeros(b.table.shape, np.float32)
        full[:shape[0]] = ctrl
        b.table.assign(wp.array(full, device=self.device))
        b.row.assign(wp.array(row.astype(np.int32), device=self.device))

    # ---- stepping -------------------------------------------------------
    def _one_step(self, b: _Batch):
        wp = self._wp
        set_ctrl, record, tick = self._kern
        d = b.data
        wp.launch(set_ctrl, dim=(b.nworld, self.model.nu), inputs=[b.table, b.row, b.step, d.ctrl],
                  device=self.device)
        self._mjw.step(self.mw, d)
        wp.launch(record, dim=b.nworld, inputs=[d.sensordata, self._adr, d.qpos, d.qvel, b.touched, b.mind,
                                                b.finite], device=self.device)
        wp.launch(tick, dim=1, inputs=[b.step, b.table.shape[1]], device=self.device)

    def _run_steps(self, b: _Batch, nstep: int):
        wp = self._wp
        if not self.graph:
            for _ in range(nstep):
                self._one_step(b)
            return
        if b.graph is None:
            # kernels are loaded by the uncaptured step of _warm before this
            t = time.perf_counter()
            with wp.ScopedCapture(device=self.device) as cap:
                self._one_step(b)
            b.graph = cap.graph
            self.capture_s = time.perf_counter() - t
        for _ in range(nstep):
            wp.capture_launch(b.graph)

    def _warm(self, b: _Batch, state: np.ndarray):
        """Compile every kernel (first use) without a capture, then restore the state."""
        if self.graph and b.graph is None:
            b.step.zero_()
            self._one_step(b)
            self._wp.synchronize_device(self.device)
            self._upload(b, state)

    def advance(self, state, lanes: Lanes, n_periods: int, *, t0: float = 0.0, record: Record | None = None):
        """Advance ``state`` [B, nstate] by ``n_periods`` gait periods; same contract as the native backend."""
        check_start_delays(lanes, "warp")
        check_records(record, "warp")
        wp = self._wp
        dt = float(self.model.opt.timestep)
        lanes = on_step_grid(lanes, dt)
        nstep = steps_per_period(lanes.period, dt)
        state = np.asarray(state, dtype=np.float64)
        bsz, n_pairs = lanes.size, self.scene.n_pairs
        b = self._batch_for(bsz)
        self._set_table(b, lanes, nstep)
        self._upload(b, state)
        self._warm(b, state)
        poses = np.empty((bsz, n_periods, self.scene.n_robots, 5))
        touched = np.zeros((bsz, n_periods, n_pairs), dtype=bool)
        min_dist = np.full((bsz, n_periods, n_pairs), np.inf)
        status = np.zeros(bsz, dtype=np.int32)
        b.finite.fill_(1)
        for k in range(n_periods):
            b.step.zero_()
            b.touched.zero_()
            b.mind.fill_(np.inf)
            self._run_steps(b, nstep)
            wp.synchronize_device(self.device)
            touched[:, k] = b.touched.numpy()[:, :n_pairs] > 0
            md = b.mind.numpy()[:, :n_pairs].astype(np.float64)
            min_dist[:, k] = np.where(touched[:, k], md, np.inf)
            poses[:, k] = self.scene.poses_from_qpos(b.data.qpos.numpy().astype(np.float64))
            status |= np.where((min_dist[:, k] < -self.penetration_limit).any(-1), int(Status.PENETRATION), 0)
        status |= np.where(b.finite.numpy() > 0, 0, int(Status.NONFINITE))
        status |= np.where((b.data.overflow.numpy() & _BUFFER_BITS) != 0, int(Status.OVERFLOW), 0)
        return self._download(b), PeriodRecords(poses, touched, min_dist, status), None

    def step_qpos(self, lanes: Lanes, nsteps: int) -> np.ndarray:
        """qpos [B, nsteps, nq] of the first ``nsteps`` steps from rest (step-by-step comparisons)."""
        dt = float(self.model.opt.timestep)
        lanes = on_step_grid(lanes, dt)
        nstep_period = steps_per_period(lanes.period, dt)
        b = self._batch_for(lanes.size)
        self._set_table(b, lanes, nstep_period)
        state = self.initial_state(lanes)
        self._upload(b, state)
        self._warm(b, state)
        b.step.zero_()
        out = np.empty((lanes.size, nsteps, self.model.nq))
        for i in range(nsteps):
            self._run_steps(b, 1)
            out[:, i] = b.data.qpos.numpy()
        return out

    def run_from_rest(self, lanes: Lanes, nsteps: int) -> np.ndarray:
        """State [B, nstate] after ``nsteps`` steps of the lanes' gait from rest,
        nothing read back on the way (throughput benchmarks)."""
        dt = float(self.model.opt.timestep)
        lanes = on_step_grid(lanes, dt)
        b = self._batch_for(lanes.size)
        self._set_table(b, lanes, steps_per_period(lanes.period, dt))
        state = self.initial_state(lanes)
        self._upload(b, state)
        self._warm(b, state)
        b.step.zero_()
        self._run_steps(b, nsteps)
        self._wp.synchronize_device(self.device)
        return self._download(b)

    def overflowed(self) -> bool:
        """Whether the last call's batch reported a buffer overflow."""
        return self._batch is not None and bool((self._batch.data.overflow.numpy() & _BUFFER_BITS).any())
