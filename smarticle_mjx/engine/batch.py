"""Run many lanes through a fixed-size batch: chunks, early exit, refill.

The batch holds ``batch_size`` slots. Every chunk advances all occupied
slots by ``chunk_periods`` gait periods. A lane is finished when it has run
all its periods or the :class:`RetireRule` decides its outcome; its records
go to the ``on_lanes`` callback at once and its slot takes the next queued
lane, so the batch stays full. Memory is O(batch_size x periods), never
lanes x steps.

Why retiring quiet lanes is sound (and measured in benchmarks/early_exit.py):
a lone robot does not drift (converged drift ~1e-5 W per period, see
docs/timestep.md) and friction stops any coasting within ~0.05 s, so a pair
that went ``quiet_periods`` whole periods without touching starts every
later period from the same relative pose and would stay apart forever.
"""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from .. import configs
from .core import Lanes, Record, Status, blank_collisions


@dataclasses.dataclass(frozen=True)
class RetireRule:
    """When a lane's outcome is decided before its last period.

    Attributes:
      quiet_periods: retire after this many consecutive periods in which no
        pair touched (0 disables early exit).
      min_separation_W: and only if every pair's |r| (in W) at the last
        period boundary exceeds this.
      on_bad_status: retire lanes whose status turned non-finite,
        penetrating or overflowing.
    """

    quiet_periods: int = 2
    min_separation_W: float = 0.0
    on_bad_status: bool = True

    def validate(self):
        if self.quiet_periods < 0 or self.min_separation_W < 0:
            raise ValueError("retire rule values must be >= 0")


@dataclasses.dataclass
class LaneResults:
    """Records of finished lanes (host numpy), as handed to ``on_lanes``.

    Attributes:
      index: [b] lane indices into the queue.
      poses: [b, K, N, 5] poses at the end of each period; NaN after retiring.
      touched: [b, K, P]; False after retiring.
      min_dist: [b, K, P]; inf after retiring or where no touch.
      status: [b] Status bits.
      periods_run: [b] periods actually simulated.
      collisions: the collision record (see ``PeriodRecords``; zero after
        retiring), or None when not asked for.
    """

    index: np.ndarray
    poses: np.ndarray
    touched: np.ndarray
    min_dist: np.ndarray
    status: np.ndarray
    periods_run: np.ndarray
    collisions: dict | None = None


def _take_state(state, idx):
    if isinstance(state, np.ndarray):
        return state[idx]
    import jax
    return jax.tree_util.tree_map(lambda x: x[idx], state)


def _put_state(state, idx, new):
    if isinstance(state, np.ndarray):
        state[idx] = new
        return state
    import jax
    return jax.tree_util.tree_map(lambda x, y: x.at[idx].set(y), state, new)


def _blank(b, k, n, p):
    """Records of lanes that did not run: poses NaN, no touch, no contact."""
    return np.full((b, k, n, 5), np.nan), np.zeros((b, k, p), bool), np.full((b, k, p), np.inf)


def _pad_to_bucket(idx: np.ndarray, b: int, smallest: int = 16) -> np.ndarray:
    """``idx`` (occupied slots) padded with idle ones to the next power of two
    (at least ``smallest``, at most ``b``): few distinct sub-batch sizes."""
    size = min(b, max(smallest, 1 << int(np.ceil(np.log2(max(1, len(idx)))))))
    if size <= len(idx):
        return idx
    idle = np.setdiff1d(np.arange(b), idx)[:size - len(idx)]
    return np.sort(np.concatenate([idx, idle]))


def _scatter_records(rec, idx, b):
    from .core import PeriodRecords
    out = PeriodRecords(*_blank(b, rec.poses.shape[1], rec.poses.shape[2], rec.touched.shape[2]),
                        np.zeros(b, np.int32))
    out.poses[idx], out.touched[idx], out.min_dist[idx], out.status[idx] = rec.poses, rec.touched, rec.min_dist, rec.status
    if rec.collisions is not None:
        k, p, _, bins = rec.collisions["steps"].shape[1:]
        out.collisions = blank_collisions(b, k, p, bins)
        for name, v in rec.collisions.items():
            out.collisions[name][idx] = v
    return out


def run_lanes(backend, lanes: Lanes, periods: int, *, batch_size: int = 256, chunk_periods: int = 5,
              rule: RetireRule = RetireRule(), valid: np.ndarray | None = None,
              on_lanes: Callable[[LaneResults], None] | None = None,
              on_progress: Callable[[int, int, int], None] | None = None,
              record: Record | None = None) -> dict:
    """Run every lane of ``lanes`` for ``periods`` periods (or until retired).

    Args:
      backend: any backend (engine.make_backend: native, mjx, warp, dart) built for the lanes' scene.
      lanes: all lanes, queued in order.
      periods: periods per lane.
      batch_size: slots advanced together.
      chunk_periods: periods per chunk (retirement is checked between chunks).
      rule: early-exit rule.
      valid: [M] bool; invalid lanes are reported with Status.INVALID and
        never simulated.
      on_lanes: receives each group of finished lanes (any order).
      on_progress: called as (lanes_done, lanes_total, lane_periods_run).
      record: what to record beyond poses and touches (full-rate tracks are
        not kept here; the collision record is).

    Returns:
      Summary dict: lanes, simulated lane-periods, full lane-periods, wall
      seconds spent in the backend.
    """
    import time

    rule.validate()
    record = record or Record()
    record.validate()
    if record.track_stride:
        raise ValueError("run_lanes keeps per-period records only; record full-rate tracks with advance()")
    if periods < 1 or batch_size < 1 or chunk_periods < 1:
        raise ValueError("periods, batch_size and chunk_periods must be positive")
    m = lanes.size
    n, p = lanes.poses.shape[1], backend.scene.n_pairs
    valid = np.ones(m, bool) if valid is None else np.asarray(valid, bool)
    W = backend.scene.params.robot.body_length
    done = 0
    lane_periods = 0

    def emit(res: LaneResults):
        nonlocal done
        done += len(res.index)
        if on_lanes is not None:
            on_lanes(res)
        if on_progress is not None:
            on_progress(done, m, lane_periods)

    bad = np.flatnonzero(~valid)
    if len(bad):
        emit(LaneResults(bad, *_blank(len(bad), periods, n, p), np.full(len(bad), int(Status.INVALID), np.int32),
                         np.zeros(len(bad), np.int32),
                         blank_collisions(len(bad), periods, p, record.collision_bins) if record.collisions else None))
    queue = list(np.flatnonzero(valid))
    b = min(batch_size, len(queue))
    if b == 0:
        return dict(lanes=m, lane_periods=0, full_lane_periods=0, backend_seconds=0.0)

    # the backend's batching policy (engine.core.BATCHING)
    shrink = backend.batching if backend.batching != "fixed" else None
    slot_lane = np.array(queue[:b])
    qpos = b
    slot_lanes = lanes.take(slot_lane)
    state = backend.initial_state(slot_lanes)
    slot_done = np.zeros(b, np.int32)
    active = np.ones(b, bool)
    buf_poses, buf_touch, buf_dist = _blank(b, periods, n, p)
    buf_status = np.zeros(b, np.int32)
    buf_coll = blank_collisions(b, periods, p, record.collision_bins) if record.collisions else None
    wall = 0.0

    # robots with their own gait period (clock drift) keep their phase across chunks, retriggered
    # robots their cycle count, and robots started at different times wait only in their lane's first
    # chunk: each chunk starts at the time its lane has run, not at 0 (backends without such robots
    # take no start time)
    if lanes.timed:
        from .core import on_step_grid
        grid = on_step_grid(lanes, backend.scene.params.timestep).period

        def start(idx):
            return {"t0": slot_done[idx] * grid}
    else:
        def start(idx):
            return {}

    while active.any():
        # a slot with fewer periods left than the chunk still runs the
        # chunk (the surplus records are dropped); no chunk runs past the
        # longest remaining lane
        n_adv = int(min(chunk_periods, (periods - slot_done[active]).max()))
        t = time.perf_counter()
        if shrink and not active.all():
            idx = np.flatnonzero(active)
            if shrink == "pow2":
                idx = _pad_to_bucket(idx, b)
            sub_state, sub_rec, _ = backend.advance(_take_state(state, idx), slot_lanes.take(idx), n_adv,
                                                    record=record, **start(idx))
            state = _put_state(state, idx, sub_state)
            rec = _scatter_records(sub_rec, idx, b)
        else:
            state, rec, _ = backend.advance(state, slot_lanes, n_adv, record=record, **start(np.arange(b)))
        wall += time.perf_counter() - t
        finished = []
        for s in np.flatnonzero(active):
            k0 = slot_done[s]
            k1 = min(periods, k0 + n_adv)
            used = k1 - k0
            buf_poses[s, k0:k1] = rec.poses[s, :used]
            buf_touch[s, k0:k1] = rec.touched[s, :used]
            buf_dist[s, k0:k1] = rec.min_dist[s, :used]
            buf_status[s] |= rec.status[s]
            if buf_coll is not None:
                for name, v in rec.collisions.items():
                    buf_coll[name][s, k0:k1] = v[s, :used]
            slot_done[s] = k1
            lane_periods += used
            if k1 >= periods:
                finished.append(s)
            elif rule.on_bad_status and buf_status[s] & (Status.NONFINITE | Status.PENETRATION | Status.OVERFLOW):
                buf_status[s] |= int(Status.RETIRED)
                finished.append(s)
            elif rule.quiet_periods and k1 >= rule.quiet_periods and \
                    not buf_touch[s, k1 - rule.quiet_periods:k1].any():
                last = buf_poses[s, k1 - 1]
                sep_ok = True
                if rule.min_separation_W > 0:
                    i, j = backend.scene.layout.pairs.T
                    r, _, _ = configs.relative_coordinates(last[i], last[j], W)
                    sep_ok = bool((r > rule.min_separation_W).all())
                if sep_ok:
                    buf_status[s] |= int(Status.RETIRED)
                    finished.append(s)
        if finished:
            f = np.array(finished)
            emit(LaneResults(slot_lane[f].copy(), buf_poses[f].copy(), buf_touch[f].copy(), buf_dist[f].copy(),
                             buf_status[f].copy(), slot_done[f].copy(),
                             {k: v[f].copy() for k, v in buf_coll.items()} if buf_coll is not None else None))
            # refill
            refill = []
            for s in f:
                if qpos < len(queue):
                    slot_lane[s] = queue[qpos]
                    qpos += 1
                    refill.append(s)
                else:
                    active[s] = False
            if refill:
                r_idx = np.array(refill)
                new_lanes = lanes.take(slot_lane[r_idx])
                state = _put_state(state, r_idx, backend.initial_state(new_lanes))
                slot_lanes = lanes.take(slot_lane)
                slot_done[r_idx] = 0
                buf_poses[r_idx] = np.nan
                buf_touch[r_idx] = False
                buf_dist[r_idx] = np.inf
                buf_status[r_idx] = 0
                if buf_coll is not None:
                    for v in buf_coll.values():
                        v[r_idx] = 0
            if not active.any():
                break
            # mjx: idle slots keep running a finished lane (discarded) so the
            # batch shape, and so the compiled function, stays the same
    return dict(lanes=m, lane_periods=int(lane_periods), full_lane_periods=int(valid.sum()) * periods,
                backend_seconds=wall)
