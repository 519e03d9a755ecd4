"""Basin scans and amplitude sweeps: configurations -> engine -> store."""

from __future__ import annotations

import dataclasses
import time
from typing import Callable

import numpy as np

from . import configs as C
from .engine import Lanes, open_backend, steps_per_period
from .engine.batch import RetireRule, run_lanes
from .engine.core import Record
from .executors import LocalExecutor
from .gait import GaitSpec
from .scene import SceneParams
from .specs import ScanConfig, config_from_json, params_from_json, params_json, run_name
from .store import Writer, longest_run


def _rows(cfg: np.ndarray, valid: np.ndarray, res, body_length: float) -> dict:
    """Store rows from engine LaneResults (pair scenes)."""
    extra = {}
    if res.collisions is not None:
        extra = {"coll_steps": res.collisions["steps"], "coll_impulse": res.collisions["impulse"],
                 "coll_impulse_r": res.collisions["impulse_r"]}
    poses = res.poses
    p1, p2 = poses[:, :, 0], poses[:, :, 1]
    r, th, ph = C.relative_coordinates(p1, p2, body_length)
    com = np.stack([(p1[..., 0] + p2[..., 0]) / 2, (p1[..., 1] + p2[..., 1]) / 2,
                    np.angle(np.exp(1j * p1[..., 2]) + np.exp(1j * p2[..., 2]))], -1)
    return {
        "config": cfg.astype(np.float64), "valid": valid, "status": res.status.astype(np.int32),
        "periods_run": res.periods_run.astype(np.int32), "touched": res.touched,
        "min_dist": res.min_dist.astype(np.float32), "poses": poses.astype(np.float32),
        "rel": np.stack([r, th, ph], -1).astype(np.float32), "com": com.astype(np.float32),
        "lifetime": longest_run(res.touched[:, :, 0]),
        **extra,
    }


@dataclasses.dataclass(frozen=True)
class RunInputs:
    """One run's configurations, initial poses and validity (the same on every worker)."""

    cfg: np.ndarray
    poses: np.ndarray
    valid: np.ndarray
    gait: GaitSpec

    @staticmethod
    def of(config: ScanConfig, params: SceneParams, amplitude_deg: float) -> "RunInputs":
        cfg = config.initial_configs()
        g = config.gait_spec(amplitude_deg)
        a0 = g.setpoints(0.0, params.robot.servo_speed)
        poses = C.pair_poses(cfg[:, 0], cfg[:, 1], cfg[:, 2], a0[0], a0[1], params.robot)
        return RunInputs(cfg, poses, C.poses_valid(poses, params.robot), g)


def simulate_rows(backend, config: ScanConfig, params: SceneParams, inputs: RunInputs, lo: int, hi: int,
                  on_rows: Callable[[np.ndarray, dict], None],
                  on_progress: Callable[[int], None] | None = None) -> dict:
    """Simulate rows ``lo .. hi-1`` of one run; ``on_rows(rows index, rows)`` as lanes finish (any order).

    Returns the engine's summary (``run_lanes``): lane-periods run and the
    seconds spent inside the backend.

    Every executor runs configurations through this one function, so a row's
    content does not depend on which executor, shard or batch computed it.
    """
    record = Record(collisions=config.collisions, collision_bins=config.collision_bins)
    lanes = config.robots().lanes(Lanes.from_gait(inputs.poses[lo:hi], inputs.gait), np.arange(lo, hi))

    def on_lanes(res):
        idx = lo + res.index
        on_rows(idx, _rows(inputs.cfg[idx], inputs.valid[idx], res, params.robot.body_length))

    return run_lanes(backend, lanes, config.periods, batch_size=config.batch_size, chunk_periods=config.chunk_periods,
              rule=RetireRule(quiet_periods=config.quiet_periods), valid=inputs.valid[lo:hi], on_lanes=on_lanes,
              on_progress=(lambda done, total, lp: on_progress(done)) if on_progress else None, record=record)


@dataclasses.dataclass(frozen=True)
class ScanJob:
    """A scan's row job (``executors.RowJob``): simulates any range of one run's configurations."""

    config: ScanConfig
    params: SceneParams
    amplitudes: dict  # run name -> amplitude (deg)

    def backend_key(self, nthread: int | None) -> tuple:
        return (repr(self.params), self.config.backend, self.config.collisions, nthread)

    def open_backend(self, nthread: int | None = None):
        return open_backend(self.config.backend, self.params, 2, collisions=self.config.collisions,
                            nthread=nthread,
                            **self.config.backend_options())

    def rows(self, backend, run: str, lo: int, hi: int, on_rows) -> dict:
        inputs = RunInputs.of(self.config, self.params, self.amplitudes[run])
        return simulate_rows(backend, self.config, self.params, inputs, lo, hi, on_rows)


def run_scan(config: ScanConfig, out, mode: str = "new", params: SceneParams | None = None,
             flush_rows: int = 64, on_progress: Callable[[dict], None] | None = None, executor=None) -> dict:
    """Run a scan or sweep into the store ``out``.

    Args:
      config: what to scan.
      out: store path (.h5).
      mode: "new", "resume" or "overwrite" (see store.Writer). A resumed
        scan simulates only the rows its journal lacks.
      params: scene parameters; default: those of ``config.model``. Given
        explicitly, the store records the model as "custom" (with every
        parameter, as always).
      flush_rows: journal finished rows in blocks of at least this many.
      on_progress: receives dicts with run, done, total, steps, elapsed.
      executor: an ``executors.Executor``; None: ``LocalExecutor(flush_rows)`` (this machine, all
        cores). ``DaskExecutor`` runs shards elsewhere and hands their rows back; this process stays
        the only writer.

    Returns:
      Summary: configurations, valid, bound-at-end fraction per run, wall
      time, simulated steps and steps per second; with the local executor
      also ``backend_s``, the seconds spent inside the engine's advance.
    """
    model = config.model if params is None else "custom"
    params = config.scene_params() if params is None else params
    config.validate(params)
    robots = config.robots()
    params = robots.scene(params)  # the drawn robots' backlash and centres of mass, recorded with the scene
    params.validate()
    cfg = config.initial_configs()
    from .engine.dart import study_timestep
    dt = study_timestep(config.backend, config.dart_numerics, params.timestep)  # the engine's own step
    runs = {}
    for a in config.amplitudes_deg:
        g = config.gait_spec(a)
        period = steps_per_period(g.period(), dt) * dt
        runs[run_name(a)] = {"amplitude_deg": float(a), "period_s": period, "chirality": g.chirality,
                             "gait": g.kind, "periods": config.periods, "n_configs": len(cfg)}
    full = {"model": model, "scan": config.to_json(), "scene": params_json(params)}
    if not robots.set.ideal:
        full["imperfections"] = robots.to_json()
    if executor is not None:
        full["executor"] = executor.describe()
    t0 = time.perf_counter()
    summary = {"configs": len(cfg), "runs": {}, "steps": 0}
    nsteps = {name: steps_per_period(config.gait_spec(a["amplitude_deg"]).period(), dt) for name, a in runs.items()}
    with Writer(out, full, runs, mode=mode) as w:
        done = {name: len(cfg) - sum(b - a for a, b in w.missing(name, len(cfg))) for name in runs}

        def progress(name):
            if on_progress:
                on_progress({"run": name, "done": done[name], "total": len(cfg),
                             "elapsed": time.perf_counter() - t0, "steps": summary["steps"]})

        for name in runs:
            progress(name)

        def on_rows(name, lo, rows):
            w.append(name, lo, rows)
            done[name] += len(rows["config"])
            summary["steps"] += int(rows["periods_run"].sum()) * nsteps[name]
            progress(name)

        job = ScanJob(config, params, {name: a["amplitude_deg"] for name, a in runs.items()})
        ran = (executor or LocalExecutor(flush_rows)).run(job, {name: w.missing(name, len(cfg)) for name in runs},
                                                           on_rows)
        if "backend_s" in ran:
            summary["backend_s"] = ran["backend_s"]
        w.finalize()
    from .store import Store
    st = Store(out)
    for name in st.runs:
        d = st.run(name, fields=("valid", "touched"))
        v = d["valid"]
        summary["runs"][name] = {"valid": int(v.sum()),
                                 "bound_end_fraction": float(d["touched"][v, -1, 0].mean()) if v.any() else 0.0}
    summary["wall_s"] = time.perf_counter() - t0
    summary["steps_per_s"] = summary["steps"] / max(summary["wall_s"], 1e-9)
    return summary


def resimulate_lane(store_path, run: str | None, lane: int, track_stride: int = 40,
                    frame_interval: float | None = None):
    """Simulate lane ``lane`` of a scan store again, from its stored start, amplitude, gait and model.

    ``frame_interval`` (s), when given, sets the track stride from the stored
    model's own time step instead of ``track_stride``.

    Returns (times [S], poses [S, N, 5]: the start, then the full-rate track
    every ``track_stride`` steps; the period records ``SimResult``, params, gait,
    the stored rows of that lane). Raises ValueError for a lane out of
    range or one that was never simulated (overlapping start).
    """
    from .engine.simulate import simulate
    from .store import Store
    st = Store(store_path)
    run = run or st.runs[0]
    if run not in st.runs:
        raise ValueError(f"{store_path} has no run {run!r} (runs: {', '.join(st.runs)})")
    config = config_from_json(st.config["scan"])
    params = params_from_json(st.config["scene"])
    m = int(st.run_attrs[run]["n_configs"])
    if not 0 <= lane < m:
        raise ValueError(f"lane {lane} is out of range: run {run} has lanes 0..{m - 1}")
    rows = st.run(run, fields=("config", "valid", "touched", "poses", "periods_run", "status"))
    rows = {k: v[lane] for k, v in rows.items()}
    if not rows["valid"]:
        raise ValueError(f"lane {lane} of run {run} starts with the robots overlapping; it was never simulated")
    inputs = RunInputs.of(config, params, float(st.run_attrs[run]["amplitude_deg"]))
    if frame_interval is not None:
        track_stride = max(1, int(round(frame_interval / params.timestep)))
    res = simulate(params, inputs.poses[lane], inputs.gait, int(config.periods), track_stride=track_stride,
                   imperfections=config.robots(), row=lane)
    # the track starts after its first stride: put the start in front
    t = np.concatenate([[0.0], res.track_t])
    track = np.concatenate([inputs.poses[lane][None], res.track], 0)
    return t, track, res, params, inputs.gait, rows


