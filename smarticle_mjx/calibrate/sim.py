"""Replay measured trials in the model: same start, same gait, same frame times.

Trials that share a robot count, gaits (one per robot) and scene are run
together as lanes of one native batch (``mujoco.rollout`` on all cores). Gait time is measured
time: a trial whose first frame is at t0 starts robot i at gait phase
t0 / T_i. A robot whose arms are tracked starts with them where the first
frame has them, and its servo reference starts there too (``Lanes.start_ref``),
moving to the corner its gait is heading for at the servo's speed: a robot
measured at rest in a corner while its gait is part of a move ahead makes the
move from its corner, as it did, not from the middle of the steady gait's move.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..engine import Lanes, Scene, make_backend
from ..engine.core import Record, on_step_grid
from .data import Trial

SIM_SAMPLE_S = 0.004  # the model is sampled every 4 ms and interpolated to the frames
_local = threading.local()


def in_pool() -> bool:
    """Whether this thread is one of :func:`pmap`'s workers (its rollouts then run on one thread each)."""
    return bool(getattr(_local, "worker", False))


def _mark_worker() -> None:
    _local.worker = True


# Model runs made by pmap's workers take one of these slots, one per core, for the whole run (scene, backend,
# rollout). The workers themselves are cheap: every item of a pmap, nested or not, gets its own thread, and the
# slots keep the cores busy with whatever run is ready, whichever fit or Jacobian column asked for it. Each run
# is the same computation either way, so the results are too. NESTED = False restores the earlier schedule
# (a pmap inside a worker runs its items one after another), for benchmarks/calibration_schedule.py.
_SLOTS = threading.BoundedSemaphore(max(1, os.cpu_count() or 1))
NESTED = True
MAX_THREADS = 64  # threads of one pmap (its items beyond that wait for one)


def slot():
    """The context a model run holds: one core's slot inside a pmap worker, nothing outside one (the caller's
    run then has every core to itself)."""
    return _SLOTS if in_pool() else contextlib.nullcontext()


def pmap(fn, items: list, workers: int | None = None) -> list:
    """``[fn(x) for x in items]``, side by side: model runs release the GIL in MuJoCo's rollout, so
    independent runs (a Jacobian's columns, a grid's points, a scene's gait groups, joint fits) go on every
    core (2 cores: 2.0x measured on the calibration's runs). Nested calls spread too; ``slot`` keeps the runs
    to one per core. ``workers``: at most that many threads (1: in order, here)."""
    items = list(items)
    cores = os.cpu_count() or 1
    if NESTED:
        n = min(len(items), workers or MAX_THREADS)
        if cores <= 1:
            n = 1
    else:  # the earlier schedule: one thread per core, and in order inside a worker
        n = 1 if in_pool() else min(len(items), workers or cores)
    if n <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(n, initializer=_mark_worker) as ex:
        return list(ex.map(fn, items))


def _interp_track(t_sim, track, t_frames):
    """Linear interpolation of [S, N, 5] samples to frame times (headings unwrapped)."""
    out = np.empty((len(t_frames),) + track.shape[1:])
    tr = track.copy()
    tr[:, :, 2] = np.unwrap(tr[:, :, 2], axis=0)
    for i in range(tr.shape[1]):
        for j in range(tr.shape[2]):
            out[:, i, j] = np.interp(t_frames, t_sim, tr[:, i, j])
    return out


SNAP_DEG = 3.0  # a tracked arm this close to one of its gait's two angles is taken to rest there


def start_reference(arms0: np.ndarray, amplitudes) -> np.ndarray:
    """[N, 2] where each robot's servo reference starts (rad; NaN where the arm is not tracked).

    A robot at rest holds its arms where its servo's reference is: at one of its gait's two angles
    (+-amplitude) for a robot started in a corner. A tracked arm within ``SNAP_DEG`` of one is taken to
    be exactly there, the rest being tracking noise (a reference started a noise's width off the gait's
    corner and caught up in a step would shake a lagging servo's filter for nothing); an arm further
    from both starts its reference where it was tracked.
    """
    arms0 = np.asarray(arms0, float)
    amp = np.asarray(amplitudes, float)[:, None]
    corner = np.where(arms0 >= 0, amp, -amp)
    near = np.abs(arms0 - corner) <= np.radians(SNAP_DEG)
    return np.where(np.isfinite(arms0), np.where(near, corner, arms0), np.nan)


def simulate_trials(trials: list[Trial], scene_for, phase_for=None, nthread: int | None = None) -> list[np.ndarray]:
    """Model tracks [F, N, 5] at every trial's frame times.

    Args:
      trials: measured trials.
      scene_for: trial -> SceneParams to simulate it with (effects applied).
      phase_for: trial -> [N] extra per-robot gait phase offsets (fractions
        of a period), or None.

    Returns:
      one [F, N, 5] array (x, y, heading unwrapped, alpha1, alpha2) per trial.
    """
    groups: dict = {}
    for k, tr in enumerate(trials):
        groups.setdefault((tr.robots, tr.gaits, scene_for(tr)), []).append(k)
    out: list[np.ndarray | None] = [None] * len(trials)
    # groups run side by side, one thread and one core's slot each (rollout releases the GIL)
    if nthread is None:
        nthread = 1 if (in_pool() or len(groups) > 1) else None

    def run_group(item):
        with slot():
            _run_group(item)

    def _run_group(item):
        (n, gaits, params), idx = item
        scene = Scene.build(params, n)
        be = make_backend("native", scene, nthread=nthread)
        try:
            poses, phases, t0s, refs = [], [], [], []
            for k in idx:
                tr = trials[k]
                t0 = float(tr.t[0])
                ph = t0 / tr.periods
                if phase_for is not None:
                    ph = ph + np.asarray(phase_for(tr), float)
                p = np.zeros((n, 5))
                p[:, :3] = tr.pose[0]
                for i in range(n):
                    cmd = gaits[i].setpoints(0.0, params.robot.servo_speed, phase=ph[i])
                    meas = tr.arms[0, i] if tr.arms is not None else np.full(2, np.nan)
                    p[i, 3:] = np.where(np.isfinite(meas), meas, cmd)
                poses.append(p)
                # the servo reference starts at the tracked arms (NaN: untracked, at the gait's setpoint)
                refs.append(start_reference(tr.arms[0], [g.amplitude for g in gaits]) if tr.arms is not None
                            else np.full((n, 2), np.nan))
                phases.append(np.mod(ph, 1.0))
                t0s.append(t0)
            lanes = Lanes.from_robot_gaits(np.stack(poses), gaits, phase=np.stack(phases))
            ref = np.stack(refs)
            if np.isfinite(ref).any():
                lanes = dataclasses.replace(lanes, start_ref=ref)
            lanes = on_step_grid(lanes, params.timestep)
            dur = max(trials[k].duration for k in idx)
            periods = max(1, math.ceil(dur / lanes.period + 1e-9))
            stride = max(1, int(round(SIM_SAMPLE_S / params.timestep)))
            state = be.initial_state(lanes)
            _, _, track = be.advance(state, lanes, periods, record=Record(track_stride=stride))
            t_sim = np.concatenate([[0.0], np.asarray(track["t"], float)])
            for j, k in enumerate(idx):
                tr = trials[k]
                q = scene.poses_from_qpos(track["qpos"][j])
                q = np.concatenate([poses[j][None], q], 0)
                out[k] = _interp_track(t_sim, q, tr.t - t0s[j])
        finally:
            be.close()

    pmap(run_group, list(groups.items()))
    return out  # type: ignore[return-value]
