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
        return (repr(self.params), self.config.backend, self.config.collisions, nthread,
                self.config.robot_draws, self.config.robot_seed)

    def pair_params(self, k: int) -> SceneParams:
        """The scene of robot pair ``k`` (its gear play and centres of mass; pair 0's is ``params``)."""
        return self.config.robots(k).scene(self.params)

    def open_backend(self, nthread: int | None = None):
        if self.config.robot_draws == 1:
            return self._open(self.params, nthread)
        return PairBackends(self, nthread)

    def _open(self, params: SceneParams, nthread: int | None):
        return open_backend(self.config.backend, params, 2, collisions=self.config.collisions, nthread=nthread,
                            **self.config.backend_options())

    def rows(self, backend, run: str, lo: int, hi: int, on_rows: Callable[[np.ndarray, dict], None]) -> dict:
        """Simulate rows ``lo .. hi-1`` of ``run``; ``on_rows(rows index, rows)`` as lanes finish (any order).
        Returns the engine's summary (``run_lanes``: lane-periods run, seconds inside the backend; summed
        over the robot pairs of a scan that draws several, each pair's lanes run on its own scene)."""
        config = self.config
        inputs = RunInputs.of(config, self.params, self.amplitudes[run])
        record = Record(collisions=config.collisions, collision_bins=config.collision_bins)
        idx_all = np.arange(lo, hi)
        draws = config.lane_draw(idx_all)
        total: dict = {}
        for k in np.unique(draws):
            idx = idx_all[draws == k]
            lanes = config.robots(int(k)).lanes(Lanes.from_gait(inputs.poses[idx], inputs.gait), idx)

            def on_lanes(res, idx=idx):
                rows = idx[res.index]
                on_rows(rows, _rows(inputs.cfg[rows], inputs.valid[rows], res, self.params.robot.body_length))

            b = backend if config.robot_draws == 1 else backend.get(int(k))
            ran = run_lanes(b, lanes, config.periods, batch_size=config.batch_size,
                            chunk_periods=config.chunk_periods, rule=RetireRule(quiet_periods=config.quiet_periods),
                            valid=inputs.valid[idx], on_lanes=on_lanes, record=record)
            for key, v in ran.items():
                total[key] = total.get(key, 0) + v
        return total


class PairBackends:
    """The backends of a scan that runs several robot pairs: one per distinct scene (pairs whose drawn
    robots change no scene field, only servo speeds, clocks and phases, share one), opened when first
    asked for and closed together."""

    def __init__(self, job: ScanJob, nthread: int | None):
        self.job, self.nthread = job, nthread
        self._open: dict[str, object] = {}

    def get(self, k: int):
        params = self.job.pair_params(k)
        key = repr(params)
        if key not in self._open:
            self._open[key] = self.job._open(params, self.nthread)
        return self._open[key]

    def close(self) -> None:
        for b in self._open.values():
            b.close()
        self._open.clear()


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
