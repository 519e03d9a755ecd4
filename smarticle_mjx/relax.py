"""The relaxation experiment (paper, Fig. 1): N robots started compressed and
in phase on an open plate; do gliders emerge?

``run_relax`` simulates ``trials`` perturbed copies of the compressed start
for ``periods`` gait periods and writes one row per trial into an HDF5
store (the scan store's writer: journaled, resumable, atomic; schema in
docs/store.md). The analysis (glider detection, emergence fraction,
distances, lifetimes) is in :mod:`smarticle_mjx.reduce.relaxation`.

The compressed start. The paper's Fig. 1C shows seven robots "in a densely
packed configuration" that "began their shape-changing motions at the same
time and in phase"; its text gives no coordinates. Here every robot starts
at the gait's first corner (a U at 90 deg), all with the same heading, on a
staggered lattice whose spacing is the robot's bounding box at that shape
plus ``gap_mm``; the N lattice sites nearest the centre are used (for N = 7:
three side by side, two above and two below, offset by half a robot, the
``seven`` scene of ``models/``). Each trial perturbs every robot's position
(Gaussian, ``jitter_mm`` per axis) and heading (``jitter_deg``) from the
trial's own random stream (seed, trial index), so trials 0..T-1 are the same
whichever stage or batch runs them; a draw that makes robots overlap is
drawn again.

The plate is open: MuJoCo's plane is unbounded, and the lab's 60 x 60 cm
plate (centred on the packing) is a record, not a wall: ``left_plate`` holds
the first period at whose end a robot's centre lay outside it (0: never).
The analysis ends a robot's track there, as the lab's camera would.

Early exit: a trial in which no two robots touched for ``quiet_periods``
whole periods is stopped (status bit 8, ``periods_run`` < ``periods``). A
lone robot of the default model does not drift (docs/validation.md: ~1e-6 W
per period) and friction stops any coasting within a period, so from then on
every period repeats the last: no contact, no pair, no glider can form.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

from . import configs as C
from .engine import Lanes, open_backend
from .engine.batch import RetireRule, run_lanes
from .scene import RobotParams, SceneParams
from .specs import RelaxConfig
from .executors import LocalExecutor
from .runner import RelaxSummary, prepare, run_attrs, write_rows
from .store import RELAX_FIELDS, Store

RUN = "trials"  # the one run group of a relaxation store


def packing(n: int, robot: RobotParams, alpha: tuple[float, float], gap: float) -> np.ndarray:
    """Poses [n, 5] of the compressed start: the n sites of a staggered lattice
    nearest its centre, spaced by the robot's bounding box at arm angles
    ``alpha`` plus ``gap`` (m), all headings 0, centred on the origin."""
    pose0 = np.array([0.0, 0.0, 0.0, alpha[0], alpha[1]])
    body, arms = C.robot_outline(pose0, robot)
    pad = C.arm_piece_radius(robot) if robot.arm_shape != "plate" else 0.0
    pts = np.concatenate([body.reshape(-1, 2), arms.reshape(-1, 2)])
    lo, hi = pts.min(0) - pad, pts.max(0) + pad
    if robot.has_mount:  # the mounts (unwidened) may reach past the arms' sides
        mounts = C.mount_outline(pose0, robot).reshape(-1, 2)
        lo, hi = np.minimum(lo, mounts.min(0)), np.maximum(hi, mounts.max(0))
    w, d = hi - lo + gap
    rows = int(math.ceil(math.sqrt(n))) + 2
    sites = [((c + 0.5 * (r % 2)) * w, r * d) for r in range(-rows, rows + 1) for c in range(-rows, rows + 1)]
    sites = np.array(sites)
    # nearest first, in units of the cell (ties: by row, then column, so the
    # choice does not depend on floating-point noise)
    key = np.round(np.hypot(sites[:, 0] / w, sites[:, 1] / d), 9)
    order = np.lexsort((sites[:, 0], sites[:, 1], key))
    xy = sites[order[:n]]
    # the bounding box centre sits at the body centre's offset (lo + hi) / 2
    xy = xy - xy.mean(0) - (lo + hi) / 2
    poses = np.zeros((n, 5))
    poses[:, :2] = xy
    poses[:, 3], poses[:, 4] = alpha
    return poses


def hex_pack(n: int, robot: RobotParams, alpha: tuple[float, float], spacing: float | None,
             gap: float) -> np.ndarray:
    """Poses [n, 5] of a hexagonal pack: the n sites of a triangular lattice nearest its centre (for 7: a
    robot ringed by six, the packing Savoie's cloud analysis takes as the densest), all headings 0.
    ``spacing`` (m) between neighbouring centres; None: the closest at which robots of heading 0 do not
    overlap, plus ``gap``."""
    rows = int(math.ceil(math.sqrt(n))) + 2
    sites = np.array([(i + 0.5 * j, j * math.sqrt(3) / 2) for j in range(-rows, rows + 1)
                      for i in range(-rows, rows + 1)])
    key = np.round(np.hypot(sites[:, 0], sites[:, 1]), 9)
    unit = sites[np.lexsort((sites[:, 0], sites[:, 1], key))[:n]]
    unit = unit - unit.mean(0)
    poses = np.zeros((n, 5))
    poses[:, 3], poses[:, 4] = alpha
    if spacing is None:
        lo, hi = robot.body_length * 0.5, 4 * (robot.body_length + robot.arm_length)
        for _ in range(60):  # bisection on the spacing at which the aligned pack stops overlapping
            mid = 0.5 * (lo + hi)
            poses[:, :2] = unit * mid
            lo, hi = (mid, hi) if not C.poses_valid(poses, robot) else (lo, mid)
        spacing = hi + gap
    poses[:, :2] = unit * spacing
    return poses


def area_fraction_of(poses: np.ndarray, robot: RobotParams) -> float:
    """n W D / (hull area of the body centres) of one set of poses [n, >=2] (reduce.relaxation's phi)."""
    from .reduce.relaxation import area_fraction_at
    return area_fraction_at(poses, robot.body_length, robot.body_thickness)


def base_start(config: RelaxConfig, robot: RobotParams, alpha: tuple[float, float]) -> np.ndarray:
    """The unperturbed start [n, 5] of ``config``: its family (``start``: lattice or hex) spaced by
    ``gap_mm``, or scaled about its centre to the area fraction ``start_phi``; ValueError if the
    robots would overlap."""
    gap = config.gap_mm * 1e-3
    if config.start == "hex":
        base = hex_pack(config.n_robots, robot, alpha, None, gap)
    else:
        base = packing(config.n_robots, robot, alpha, gap)
    if config.start_phi is not None:
        centre = base[:, :2].mean(0)
        k = math.sqrt(area_fraction_of(base, robot) / config.start_phi)
        base[:, :2] = centre + (base[:, :2] - centre) * k
    if not C.poses_valid(base, robot):
        what = f"area fraction {config.start_phi:g}" if config.start_phi is not None else f"gap {config.gap_mm:g} mm"
        raise ValueError(f"the {config.start} start at {what} overlaps; "
                         f"{'lower --start-phi' if config.start_phi is not None else 'raise --gap-mm'}")
    return base


def trial_rng(seed: int, trial: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), int(trial), 0x52454C58])  # "RELX": apart from other streams


def start_poses(config: RelaxConfig, params: SceneParams) -> tuple[np.ndarray, np.ndarray]:
    """Perturbed starts [T, N, 5] and per-robot phases [T, N] of the config's trials."""
    g = config.gait_spec()
    a0 = g.setpoints(0.0, params.robot.servo_speed)
    base = base_start(config, params.robot, (float(a0[0]), float(a0[1])))
    out = np.empty((config.trials,) + base.shape)
    phase = np.zeros((config.trials, config.n_robots))
    for t in range(config.trials):
        rng = trial_rng(config.seed, config.first_trial + t)
        for _ in range(1000):
            p = base.copy()
            p[:, :2] += rng.normal(0.0, config.jitter_mm * 1e-3, (config.n_robots, 2))
            p[:, 2] += rng.normal(0.0, math.radians(config.jitter_deg), config.n_robots)
            if config.headings == "drawn":  # after the aligned draws, so aligned trials keep their stream
                p[:, 2] += rng.uniform(0.0, 2 * math.pi, config.n_robots)
            if C.poses_valid(p, params.robot):
                break
        else:
            raise ValueError(f"no overlap-free start for trial {config.first_trial + t} in 1000 draws; "
                             "lower --jitter-mm or --start-phi, or raise --gap-mm")
        out[t] = p
        if config.phase_jitter > 0:
            phase[t] = rng.normal(0.0, config.phase_jitter, config.n_robots)
    return out, phase


def retrigger_of(config: RelaxConfig, trials) -> np.ndarray:
    """[T, 3] the engine's per-cycle retrigger of ``trials`` (s.d., the study's seed, the trial), or [T, 4] its
    lasting offsets that set in (s.d., seed, trial, onset cycle: ``Lanes.retrigger``)."""
    trials = np.atleast_1d(np.asarray(trials))
    if config.onset_offset_sd > 0:
        return np.stack([np.full(len(trials), config.onset_offset_sd), np.full(len(trials), config.seed), trials,
                         np.full(len(trials), config.onset_cycle)], 1).astype(float)
    return np.stack([np.full(len(trials), config.retrigger_sd), np.full(len(trials), config.seed), trials], 1
                    ).astype(float)


def retriggered(config: RelaxConfig) -> bool:
    """Whether the study's robots change their timing after the start (a per-cycle re-trigger or lasting
    offsets that set in)."""
    return config.retrigger_sd > 0 or config.onset_offset_sd > 0


def trial_lanes(config: RelaxConfig, starts: np.ndarray, phase: np.ndarray, trials,
                start_delays: bool = True) -> Lanes:
    """The engine lanes of trials ``trials`` (study trial indices) from their starts [T, N, 5] and phases
    [T, N] (``start_poses``): the study's gait, its drawn robots' speeds, clocks and start offsets, and
    the per-cycle retrigger. Robots out of phase start one after another, each from its gait's first
    corner (``Lanes.with_start_delays``); ``start_delays=False`` runs them as versions up to 0.4.0 did,
    every clock started at t = 0 at its offset (to replay their stores)."""
    trials = np.atleast_1d(np.asarray(trials))
    lanes = config.robots().lanes(Lanes.from_gait(starts, config.gait_spec(), phase), trials,
                                  start_delays=start_delays)
    if start_delays and lanes.phase.any():
        lanes = lanes.with_start_delays()
    if retriggered(config):
        lanes = dataclasses.replace(lanes, retrigger=retrigger_of(config, trials))
    return lanes


def left_plate(poses: np.ndarray, centre: np.ndarray, half: float) -> np.ndarray:
    """[T, N] first period (1-based) ending with the robot's centre off the
    square plate of half-side ``half`` around ``centre``; 0: never."""
    off = (np.abs(poses[..., 0] - centre[0]) > half) | (np.abs(poses[..., 1] - centre[1]) > half)  # [T, K, N]
    first = np.argmax(off, axis=1) + 1
    return np.where(off.any(axis=1), first, 0).astype(np.int32)


def _rows(start, res, config: RelaxConfig) -> dict:
    half = config.plate_m / 2
    return {"start_poses": start.astype(np.float64), "valid": np.ones(len(res.index), bool),
            "status": res.status.astype(np.int32), "periods_run": res.periods_run.astype(np.int32),
            "touched": res.touched, "min_dist": res.min_dist.astype(np.float32),
            "poses": res.poses.astype(np.float32),
            "left_plate": left_plate(res.poses, np.zeros(2), half)}


@dataclasses.dataclass(frozen=True)
class RelaxJob:
    """A relaxation's row job (``executors.RowJob``): simulates any range of its trials."""

    config: RelaxConfig
    params: SceneParams
    starts: np.ndarray  # [T, N, 5] every trial's start
    phase: np.ndarray  # [T, N] every trial's per-robot phase

    def backend_key(self, nthread: int | None) -> tuple:
        return (repr(self.params), self.config.backend, self.config.n_robots, nthread)

    def open_backend(self, nthread: int | None = None):
        return open_backend(self.config.backend, self.params, self.config.n_robots, nthread=nthread,
                            **self.config.backend_options())

    def rows(self, backend, run: str, lo: int, hi: int, on_rows) -> dict:
        c = self.config
        idx = np.arange(lo, hi)
        lanes = trial_lanes(c, self.starts[idx], self.phase[idx], c.first_trial + idx)

        def on_lanes(res):
            on_rows(idx[res.index], _rows(self.starts[idx[res.index]], res, c))

        return run_lanes(backend, lanes, c.periods, batch_size=c.batch_size, chunk_periods=c.chunk_periods,
                         rule=RetireRule(quiet_periods=c.quiet_periods), on_lanes=on_lanes)


def run_relax(config: RelaxConfig, out, mode: str = "new", params: SceneParams | None = None,
              on_progress: Callable[[dict], None] | None = None, nthread: int | None = None,
              executor=None) -> RelaxSummary:
    """Run the relaxation trials into the store ``out`` (resumable: a resumed
    store simulates only the trials its journal lacks).

    ``executor``: an ``executors.Executor`` (None: this machine, ``nthread`` engine threads);
    ``DaskExecutor`` runs shards of trials elsewhere, this process stays the only writer.

    Returns:
      :class:`runner.RelaxSummary`: trials, trials stopped early, steps, wall time.
    """
    prep = prepare(config, "relax", params, executor)
    starts, phase = start_poses(config, prep.params)
    runs = {RUN: run_attrs(config.gait_spec(), prep.dt, config.periods, config.trials,
                           n_robots=config.n_robots, rows="trials")}
    job = RelaxJob(config, prep.params, starts, phase)
    local = LocalExecutor(flush_rows=None, nthread=nthread)
    timing = write_rows(job, out, prep, runs, config.trials, mode, executor, local, on_progress,
                        fields=RELAX_FIELDS)
    st = Store(out)  # every trial, including those a resumed run found in the journal
    early = int((st.run(RUN, fields=("periods_run",))["periods_run"] < config.periods).sum())
    return RelaxSummary(**dataclasses.asdict(timing), trials=config.trials, quiet_periods=config.quiet_periods,
                        stopped_early=early)

