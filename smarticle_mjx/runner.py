"""The one path from a study spec to its store, shared by scans and relaxations.

A runner (``scan.run_scan``, ``relax.run_relax``) does three things and only
the middle one is its own:

1. :func:`prepare` resolves the spec's scene (the named model with the spec's
   single-field overrides, or explicit parameters recorded as "custom"), checks the spec against it, adds the drawn
   robots' quirks, finds the engine's own step and writes the store's header;
2. the runner lays out its runs (one per amplitude, or the one run of trials)
   and builds its picklable row job;
3. :func:`write_rows` opens the journaled store, hands the job and the row
   ranges the store still lacks to the executor, journals rows as they arrive
   (in any order) and reports progress. This process is the only writer.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Callable

from .engine.core import steps_per_period
from .executors import Executor, LocalExecutor, RowJob
from .gait import GaitSpec
from .presets import overrides_json
from .scene import SceneParams
from .scene import params_json
from .store import ROW_FIELDS, Writer


@dataclasses.dataclass(frozen=True)
class Timing:
    """What simulating a store's missing rows cost: steps simulated (this call), wall time (s), steps per
    second, and the seconds inside the engine (``backend_s``; None where the executor does not measure it)."""

    steps: int
    wall_s: float
    backend_s: float | None

    @property
    def steps_per_s(self) -> float:
        return self.steps / max(self.wall_s, 1e-9)


@dataclasses.dataclass(frozen=True)
class RunCount:
    """One run of a scan store: valid starts and the fraction of them bound at the end."""

    valid: int
    bound_end_fraction: float


@dataclasses.dataclass(frozen=True)
class ScanSummary(Timing):
    """What ``scan.run_scan`` returns: its :class:`Timing`, the configurations per run and each run's
    :class:`RunCount` (by run name)."""

    configs: int
    runs: dict[str, RunCount]


@dataclasses.dataclass(frozen=True)
class RelaxSummary(Timing):
    """What ``relax.run_relax`` returns: its :class:`Timing`, the trials, the early-stop rule's quiet
    periods and how many trials it stopped early (every trial of the store, resumed ones included)."""

    trials: int
    quiet_periods: int
    stopped_early: int


@dataclasses.dataclass(frozen=True)
class Prepared:
    """A spec's resolved scene: model name, parameters (drawn robots included), engine step, header."""

    model: str
    params: SceneParams
    dt: float
    header: dict


def prepare(config, kind: str, params: SceneParams | None, executor: Executor | None) -> Prepared:
    """Resolve and check the scene of ``config`` (a ``ScanConfig`` or ``RelaxConfig``; ``kind``:
    the header key its JSON is stored under, "scan" or "relax"). Raises ValueError on a bad spec."""
    model = config.model if params is None else "custom"
    params = config.scene_params() if params is None else params
    config.validate(params)
    # the drawn robots' backlash and centres of mass, recorded with the scene (a scan of several robot
    # pairs records its first pair's there and every pair's in the drawn imperfections)
    params = config.robots().scene(params)
    params.validate()
    header = store_header(config, kind, model, params)
    where = executor.describe() if executor is not None else None
    if where is not None:
        header["executor"] = where
    dt = config.engine().timestep(params.timestep)  # the engine's own step
    return Prepared(model, params, dt, header)


def store_header(config, kind: str, model: str, params: SceneParams) -> dict:
    """What a store of ``config`` records about its scene: the preset's name, the spec (under
    ``kind``), the full parameters (drawn robots included), the single fields changed from the preset
    (``overrides``, when any) and the drawn imperfections (when not ideal)."""
    header = {"model": model, kind: config.to_json(), "scene": params_json(params)}
    if config.overrides:
        header["overrides"] = overrides_json(config.overrides)
    robots = config.robot_pool()
    if not robots.set.ideal:
        header["imperfections"] = robots.to_json()
        if getattr(config, "robot_draws", 1) > 1:
            header["imperfections"]["pairs"] = int(config.robot_draws)
    return header


def run_attrs(gait: GaitSpec, dt: float, periods: int, n_configs: int, **extra) -> dict:
    """A run's attributes in the store: amplitude, the period on the engine's step grid, gait, size."""
    return {"amplitude_deg": float(gait.amplitude_deg), "period_s": steps_per_period(gait.period(), dt) * dt,
            "chirality": gait.chirality, "gait": gait.kind, "periods": periods, "n_configs": n_configs, **extra}


def write_rows(job: RowJob, out, prep: Prepared, runs: dict[str, dict], rows: int, mode: str,
               executor: Executor | None, local: LocalExecutor,
               on_progress: Callable[[dict], None] | None = None, fields=ROW_FIELDS) -> Timing:
    """Simulate every row of ``runs`` (run name -> attributes, each with ``period_s``; ``rows`` rows
    each) that the store ``out`` lacks, on ``executor`` (None: ``local``), and journal them.

    Returns the :class:`Timing`: steps simulated (this call), wall time, steps per second and, from a
    local executor, the seconds spent inside the engine (``backend_s``).
    """
    nsteps = {name: int(round(a["period_s"] / prep.dt)) for name, a in runs.items()}
    t0 = time.perf_counter()
    summary = {"steps": 0}
    with Writer(out, prep.header, runs, mode=mode, fields=fields) as w:
        todo = {name: w.missing(name, rows) for name in runs}
        done = {name: rows - sum(b - a for a, b in todo[name]) for name in runs}

        def progress(name):
            if on_progress:
                on_progress({"run": name, "done": done[name], "total": rows,
                             "elapsed": time.perf_counter() - t0, "steps": summary["steps"]})

        def on_rows(name, lo, got):
            w.append(name, lo, got)
            done[name] += len(got["valid"])
            summary["steps"] += int(got["periods_run"].sum()) * nsteps[name]
            progress(name)

        for name in runs:
            progress(name)
        ran = (executor or local).run(job, todo, on_rows)
        w.finalize()
    wall = time.perf_counter() - t0
    return Timing(summary["steps"], wall, ran.get("backend_s"))
