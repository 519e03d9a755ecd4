"""Full-rate tracks: one scene simulated and written in the track format (``smx simulate``), or one lane of
a scan store or one trial of a relaxation store simulated again exactly (``smx movie``)."""

from __future__ import annotations

import dataclasses
import math
import pathlib
import re

import numpy as np

from .scan import RunInputs
from .scene import params_from_json
from .specs import config_from_json, relax_config_from_json


def made_with_start_delays(st) -> bool:
    """Whether store ``st`` ran robots out of phase as start delays (package 0.4.1 on; ``Lanes.with_start_delays``)
    rather than as clocks all started at t = 0 (up to 0.4.0), so that a replay runs what made it."""
    version = str(st.attrs.get("package", "0"))
    parts = tuple(int(x) for x in re.findall(r"\d+", version)[:3])
    return parts >= (0, 4, 1)


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
    robots = config.robots(int(config.lane_draw([lane])[0]))  # the lane's robot pair
    params = robots.scene(params)
    res = simulate(params, inputs.poses[lane], inputs.gait, int(config.periods), track_stride=track_stride,
                   imperfections=robots, row=lane, start_delays=made_with_start_delays(st))
    # the track starts after its first stride: put the start in front
    t = np.concatenate([[0.0], res.track_t])
    track = np.concatenate([inputs.poses[lane][None], res.track], 0)
    return t, track, res, params, inputs.gait, rows


@dataclasses.dataclass(frozen=True)
class SimulatedTrack:
    """What ``smx simulate`` wrote: robots, periods, the gait period (s), the files, and in how many periods
    some pair touched."""

    robots: int
    periods: int
    period_s: float
    written: tuple
    touched_periods: int


def simulate_track(out, scene: str = "pair", config: str | None = None, gait=None, periods: int = 10,
                   track_stride: int = 20, backend: str = "native", overwrite: bool = False,
                   model: str | None = None, overrides=()) -> "SimulatedTrack":
    """Simulate one scene (a standard scene, or a pair started at ``config`` = '|r|,theta,phi' in W and
    degrees) and write its track to ``out`` (.csv with a .json sidecar, or .h5). Every input is checked
    before anything is simulated. ``overrides``: single fields of the preset changed (``--set``), recorded
    in the sidecar. Returns the :class:`SimulatedTrack`."""
    from . import configs, presets, scene as scene_mod, tracks
    from .engine import StudyEngine
    from .engine.simulate import simulate
    from .gait import GaitSpec
    preset = presets.get(model)
    overrides = presets.overrides(overrides)
    params, g = presets.apply(preset.params, overrides), gait or GaitSpec()
    g.validate(params.robot.servo_speed, params.robot.arm_limit_deg)
    if periods < 1 or track_stride < 1:
        raise ValueError("--periods and --track-stride must be positive")
    engine = StudyEngine(backend)
    engine.check(overrides=overrides, tracks=True)  # records tracks; dart: installed, reads what --set changes
    dt = engine.timestep(params.timestep)
    if pathlib.Path(out).exists() and not overwrite:
        raise ValueError(f"{out} exists; pass --overwrite to replace it")
    tracks.check_output(out)
    a0 = g.setpoints(0.0, params.robot.servo_speed)
    if config is not None:
        try:
            r, th, ph = (float(v) for v in config.split(","))
        except ValueError:
            raise ValueError(f"--config must be three numbers '|r|,theta,phi', got {config!r}") from None
        poses = configs.pair_poses(r, math.radians(th), math.radians(ph), a0[0], a0[1], params.robot)
    else:
        poses = [(x, y, h, a0[0], a0[1]) for x, y, h, _, _ in scene_mod.standard_poses(scene, params.robot)]
    res = simulate(params, poses, g, periods, track_stride=track_stride, backend=backend)
    meta = tracks.sidecar(len(poses), g, params.plate_friction, 1.0 / (track_stride * dt), model=preset.name,
                          overrides=overrides)
    written = tracks.write_track(out, [0.0, *res.track_t], [res.poses[0], *res.track], meta,
                                 records={"touched": res.touched, "poses": res.poses, "min_dist": res.min_dist})
    return SimulatedTrack(len(poses), periods, res.period, tuple(written),
                          int(res.touched.any(1).sum()) if res.touched.size else 0)


def lane_track(store_path, run: str | None, lane: int | None, frame_interval: float) -> tuple:
    """A scan store's lane simulated again for a movie: (times, poses, robot, period, title, same),
    ``same`` telling whether the re-simulation reproduces the stored records."""
    if lane is None:
        raise ValueError("a scan store needs --lane (the configuration index to show)")
    t, poses, res, params, gait, rows = resimulate_lane(store_path, run, lane, frame_interval=frame_interval)
    k = int(rows["periods_run"])
    same = bool(np.array_equal(res.poses[1:k + 1].astype(np.float32), rows["poses"][:k]))
    title = (f"{pathlib.Path(store_path).name} lane {lane}, {gait.amplitude_deg:g} deg"
             + ("" if same else " (differs from store!)"))
    return t, poses, params.robot, gait.period(), title, same


def resimulate_trial(store_path, trial: int, frame_interval: float):
    """Simulate trial ``trial`` of a relaxation store again, from its stored configuration and model:
    the start (checked against the stored one), per-robot phases and drawn robots of that trial.

    Returns (times [S], poses [S, N, 5] from the start, ``SimResult``, params, gait, the stored rows of
    that trial). Raises ValueError for a trial the store does not hold."""
    from .engine.simulate import simulate
    from .relax import RUN, retrigger_of, retriggered, start_poses
    from .store import Store
    st = Store(store_path)
    config = relax_config_from_json(st.config["relax"])
    params = params_from_json(st.config["scene"])
    lo, hi = config.first_trial, config.first_trial + config.trials
    if not lo <= trial < hi:
        raise ValueError(f"trial {trial} is not in {store_path}: it holds trials {lo}..{hi - 1}")
    rows = st.run(RUN, fields=("start_poses", "poses", "periods_run", "status"))
    rows = {k: v[trial - lo] for k, v in rows.items()}
    start, phase = start_poses(dataclasses.replace(config, first_trial=trial, trials=1), params)
    if not np.array_equal(start[0], rows["start_poses"]):
        raise ValueError(f"trial {trial}'s start cannot be rebuilt (another package version made the store)")
    gait = config.gait_spec()
    stride = max(1, int(round(frame_interval / params.timestep)))
    res = simulate(params, start[0], gait, max(int(rows["periods_run"]), 1), phase=phase[0], track_stride=stride,
                   imperfections=config.robots(), row=trial, start_delays=made_with_start_delays(st),
                   retrigger=retrigger_of(config, trial)[0] if retriggered(config) else None)
    t = np.concatenate([[0.0], res.track_t])
    return t, np.concatenate([start[0][None], res.track], 0), res, params, gait, rows


def trial_track(store_path, trial: int | None, frame_interval: float) -> tuple:
    """A relaxation store's trial simulated again for a movie: (times, poses, robot, period, title, same),
    ``same`` telling whether the re-simulation reproduces the stored per-period poses."""
    if trial is None:
        raise ValueError("a relaxation store needs --trial (the trial index to show)")
    t, poses, res, params, gait, rows = resimulate_trial(store_path, trial, frame_interval)
    k = int(rows["periods_run"])
    same = bool(np.array_equal(res.poses[1:k + 1].astype(np.float32), rows["poses"][:k]))
    title = (f"{pathlib.Path(store_path).name} trial {trial}, {gait.amplitude_deg:g} deg"
             + ("" if same else " (differs from store!)"))
    return t, poses, params.robot, gait.period(), title, same


def movie_track(source, lane: int | None, run: str | None, frame_interval: float,
                trial: int | None = None) -> tuple:
    """What ``smx movie`` shows: one lane of a scan store simulated again (:func:`lane_track`), or a track
    written by ``smx simulate`` (:func:`smarticle_mjx.movie.load_track`, ``same`` True). ValueError for a
    missing source or a ``lane`` given for a track."""
    from .movie import load_track
    from .store import is_scan_store
    if not pathlib.Path(source).exists():
        raise ValueError(f"{source} does not exist")
    if is_scan_store(source):
        from .store import Store
        if Store(source).kind == "relax":
            if lane is not None or run is not None:
                raise ValueError("a relaxation store takes --trial, not --lane or --run")
            return trial_track(source, trial, frame_interval)
        if trial is not None:
            raise ValueError("--trial is for relaxation stores; a scan store takes --lane")
        return lane_track(source, run, lane, frame_interval)
    if trial is not None:
        raise ValueError("--trial is for relaxation stores; this is a track")
    if lane is not None:
        raise ValueError("--lane is for scan stores; this is a track")
    return (*load_track(source), True)
