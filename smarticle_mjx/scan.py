"""Basin scans and amplitude sweeps: configurations -> engine -> store."""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from . import configs as C
from .engine import Lanes, open_backend
from .engine.batch import RetireRule, run_lanes
from .engine.core import Record
from .executors import LocalExecutor
from .gait import GaitSpec
from .scene import SceneParams
from .runner import RunCount, ScanSummary, prepare, run_attrs, write_rows
from .specs import ScanConfig, run_name
from .reduce.binding import longest_run
from .store import Store


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


@dataclasses.dataclass(frozen=True)
class ScanJob:
    """A scan's row job (``executors.RowJob``): simulates any range of one run's configurations.

    Every executor runs configurations through :meth:`rows`, so a row's content does not depend on
    which executor, shard or batch computed it.
    """

    config: ScanConfig
    params: SceneParams
    amplitudes: dict  # run name -> amplitude (deg)

    def backend_key(self, nthread: int | None) -> tuple:
        return (repr(self.params), self.config.backend, self.config.collisions, nthread)

    def open_backend(self, nthread: int | None = None):
        return open_backend(self.config.backend, self.params, 2, collisions=self.config.collisions, nthread=nthread,
                            **self.config.backend_options())

    def rows(self, backend, run: str, lo: int, hi: int, on_rows: Callable[[np.ndarray, dict], None]) -> dict:
        """Simulate rows ``lo .. hi-1`` of ``run``; ``on_rows(rows index, rows)`` as lanes finish (any order).
        Returns the engine's summary (``run_lanes``: lane-periods run, seconds inside the backend)."""
        config = self.config
        inputs = RunInputs.of(config, self.params, self.amplitudes[run])
        record = Record(collisions=config.collisions, collision_bins=config.collision_bins)
        lanes = config.robots().lanes(Lanes.from_gait(inputs.poses[lo:hi], inputs.gait), np.arange(lo, hi))

        def on_lanes(res):
            idx = lo + res.index
            on_rows(idx, _rows(inputs.cfg[idx], inputs.valid[idx], res, self.params.robot.body_length))

        return run_lanes(backend, lanes, config.periods, batch_size=config.batch_size,
                         chunk_periods=config.chunk_periods, rule=RetireRule(quiet_periods=config.quiet_periods),
                         valid=inputs.valid[lo:hi], on_lanes=on_lanes, record=record)


def run_scan(config: ScanConfig, out, mode: str = "new", params: SceneParams | None = None,
             flush_rows: int = 64, on_progress: Callable[[dict], None] | None = None, executor=None) -> ScanSummary:
    """Run a scan or sweep into the store ``out`` (``runner``: the path every study takes).

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
      :class:`runner.ScanSummary`: configurations, valid starts and bound-at-end fraction per run,
      wall time, simulated steps and steps per second; with the local executor also
      ``backend_s``, the seconds spent inside the engine's advance (else None).
    """
    prep = prepare(config, "scan", params, executor)
    n = len(config.initial_configs())
    runs = {run_name(a): run_attrs(config.gait_spec(a), prep.dt, config.periods, n) for a in config.amplitudes_deg}
    job = ScanJob(config, prep.params, {name: a["amplitude_deg"] for name, a in runs.items()})
    timing = write_rows(job, out, prep, runs, n, mode, executor, LocalExecutor(flush_rows), on_progress)
    st = Store(out)
    counts = {}
    for name in st.runs:
        d = st.run(name, fields=("valid", "touched"))
        v, touched = d["valid"], d["touched"]
        counts[name] = RunCount(int(v.sum()), float(touched[v, -1, 0].mean()) if v.any() else 0.0)
    return ScanSummary(**dataclasses.asdict(timing), configs=n, runs=counts)
