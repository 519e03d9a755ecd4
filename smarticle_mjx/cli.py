"""``smx``: the command line. Thin: parse options, call the library, print what it returns.

The library checks its inputs (specs, option values, output paths) and raises ValueError (or
StoreError, ExecutorError) with one line; every command turns those into ``error: ...`` and exit 2.
"""

from __future__ import annotations

import functools
import inspect
import pathlib
import sys
import time
from typing import Optional

import typer

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Batched simulation of smarticles and the gliders they form.")

_READING_HELP = ("relaxation: the emergence reading to lead with, apart, touch, moved or pair (default: pair, "
                 "a moving pair that is not a chain; docs/relax.md)")
_MODEL_HELP = "model preset (smx models --list; default: the default preset, docs/model.md)"
_DRAWS_HELP = ("pairs of robots drawn with the imperfections: lane i runs pair i mod K, so a result is one "
               "of the robots' population, not of one pair")
_ROBOT_SEED_HELP = "seed of the robots drawn (default: --seed); two scans with the same one run the same robots"
_IMPERFECTIONS_HELP = ("the robots' imperfections, drawn per robot from the seed (smx models --list; "
                       "default none: ideal robots)")
_CONFIGS_HELP = "random (uniform |r|, theta, phi) or polar (fixed |r| grid)"
_SET_HELP = ("change one field of the model preset, FIELD=VALUE (repeatable; robot fields dotted: "
             "robot.servo_speed=7); recorded with the preset's name")


def _sets(items) -> tuple:
    """``--set`` values as checked overrides (ValueError, one line, for an unknown field or bad value)."""
    from . import presets
    return presets.overrides(items or ())


def _fail(msg: str) -> None:
    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(2)


def _command(name: str | None = None):
    """``app.command`` whose bad input (the library's ValueError, StoreError, ExecutorError) is one line
    on stderr and exit code 2."""
    def wrap(fn):
        @functools.wraps(fn)
        def run(*args, **kw):
            from .executors import ExecutorError
            from .store import StoreError
            try:
                return fn(*args, **kw)
            except (ValueError, StoreError, ExecutorError) as e:
                _fail(str(e))
        return app.command(name)(run)
    return wrap


def _model(name: Optional[str]) -> str:
    """The preset's name (the default preset for None); ValueError with the known names."""
    from . import presets
    return presets.get(name).name


def _echo(lines) -> None:
    for line in lines:
        typer.echo(line)


def _progress(quiet: bool):
    """A rich progress bar (one task per run) and the callback that feeds it."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, \
        TimeRemainingColumn

    columns = [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn()]
    bar = Progress(*columns, disable=quiet, transient=False)
    tasks = {}

    def progress(p):
        if p["run"] not in tasks:
            tasks[p["run"]] = bar.add_task(p["run"], total=p["total"], rate="")
        rate = f"{p['steps'] / max(p['elapsed'], 1e-9):,.0f} steps/s"
        bar.update(tasks[p["run"]], completed=p["done"], rate=rate)

    return bar, progress


_EXECUTOR_HELP = ("local (this machine), dask (a Dask cluster: --scheduler ADDRESS, or a local one) or slurm "
                  "(Slurm jobs as Dask workers, docs/cluster.md)")


def _option(name: str, annotation, default, help: str) -> inspect.Parameter:
    return inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, annotation=annotation,
                             default=typer.Option(default, help=help))


# The executor option group, defined once: every command that runs shards elsewhere takes it through
# ``@_executor_options`` and receives the executor object (None: this machine) as ``executor``.
_EXECUTOR_OPTIONS = (
    _option("executor", str, "local", _EXECUTOR_HELP),
    _option("scheduler", Optional[str], None, "dask: address of a running scheduler (tcp://host:8786)"),
    _option("workers", Optional[int], None, "dask, local cluster: worker processes (default: one per core)"),
    _option("threads_per_worker", int, 1, "dask: engine threads per shard (cores per worker)"),
    _option("shard_size", int, 64, "dask: configurations per shard"),
    _option("dashboard", bool, False, "dask, local cluster: serve Dask's dashboard"),
    _option("jobs", int, 4, "slurm: jobs (one worker each)"),
    _option("job_cores", int, 16, "slurm: cores per job"),
    _option("job_memory", Optional[str], None, "slurm: memory per job, e.g. 32GB"),
    _option("walltime", str, "02:00:00", "slurm: walltime per job ([D-]HH:MM:SS)"),
    _option("queue", Optional[str], None, "slurm: partition"),
    _option("account", Optional[str], None, "slurm: account"),
)


# The gait and the store options, also defined once (simulate, scan, relax; scan, sweep-amplitude, relax).
_GAIT_OPTIONS = (
    _option("amplitude", float, 90.0, "alpha_max in degrees"),
    _option("chirality", str, "ccw", "ccw or cw"),
    _option("gait", str, "square", "square or diagonal (time-symmetric)"),
    _option("period", Optional[float], None, "gait period in s (default: 1.6 s x amplitude / 90)"),
)
_STORE_OPTIONS = (
    _option("resume", bool, False, "continue an interrupted study into the same store"),
    _option("overwrite", bool, False, "replace an existing store"),
    _option("quiet", bool, False, "no progress bar"),
)


def _group(param: str, options: tuple, make=dict):
    """Give a command the option group ``options``; it receives them as one argument ``param`` =
    ``make(**values)`` (bad values: the library's one-line error, before the command runs)."""
    names = [p.name for p in options]

    def decorate(command):
        @functools.wraps(command)
        def run(**kw):
            made = make(**{n: kw.pop(n) for n in names})
            return command(**kw, **{param: made})

        own = [p for p in inspect.signature(command).parameters.values() if p.name != param]
        run.__signature__ = inspect.Signature(own + list(options))
        return run
    return decorate


def _executor(**options):
    from .executors import from_options
    return from_options(**options)


def _gait(amplitude: float, chirality: str, gait: str, period: Optional[float]):
    from .gait import GaitSpec
    return GaitSpec(amplitude_deg=amplitude, chirality=chirality, kind=gait, period_s=period)


_executor_options = _group("executor", _EXECUTOR_OPTIONS, _executor)
_gait_options = _group("gait_spec", _GAIT_OPTIONS, _gait)
_store_options = _group("store", _STORE_OPTIONS)


def _run_study(cfg, out: pathlib.Path, store: dict, executor, **options) -> None:
    """Run one study into ``out`` with a progress bar and print its summary."""
    from .studies import run_study, store_mode, summary_lines
    mode = store_mode(store["resume"], store["overwrite"])
    bar, progress = _progress(store["quiet"])
    with bar:
        summary = run_study(cfg, out, mode=mode, executor=executor, on_progress=progress, **options)
    _echo(summary_lines(summary, out))


@_command()
@_gait_options
def simulate(
    scene: str = typer.Option("pair", help="single, pair or seven (the scenes in models/)"),
    config: Optional[str] = typer.Option(None, help="pair start as '|r|,theta,phi' (|r| in W, angles in deg)"),
    periods: int = typer.Option(10, help="number of gait periods"),
    track_stride: int = typer.Option(20, help="write every this many time steps (of the backend's step)"),
    backend: str = typer.Option("native", help="native, or dart (the DART twin at 0.1 ms steps; needs the dart extra)"),
    out: pathlib.Path = typer.Option(pathlib.Path("track.csv"), help="output .csv (+ .json sidecar) or .h5"),
    overwrite: bool = typer.Option(False, help="replace an existing output file"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    set_: list[str] = typer.Option([], "--set", help=_SET_HELP),
    gait_spec=None,
):
    """Simulate one scene and write its track (the measured-data format)."""
    from .replay import simulate_track
    r = simulate_track(out, scene, config, gait_spec, periods, track_stride, backend, overwrite, model,
                       overrides=_sets(set_))
    typer.echo(f"{r.robots} robots, {periods} periods of {r.period_s:.3g} s; pairs touched in "
               f"{r.touched_periods}/{periods} periods; wrote {', '.join(map(str, r.written))}")


@_command()
def models(
    out: pathlib.Path = typer.Option(pathlib.Path("models"), help="directory for the reference scenes"),
    check: bool = typer.Option(False, help="only report whether the stored scenes are up to date"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    list_: bool = typer.Option(False, "--list", help="list the model presets and where their values come from"),
):
    """Regenerate (or --check) the reference MJCF scenes in models/ (made by the default preset)."""
    from . import imperfections, presets
    from .scene import write_reference_models
    if list_:
        return _echo(imperfections.catalogue())
    stale = write_reference_models(out, presets.get(model).params, check=check)
    typer.echo(("updated: " + ", ".join(stale)) if stale else "models up to date")


@_command()
@_executor_options
@_gait_options
@_store_options
def scan(
    configs: str = typer.Option("random", help=_CONFIGS_HELP),
    n: int = typer.Option(5000, help="random: number of configurations"),
    r_min: float = typer.Option(0.5, help="random: smallest |r| in W"),
    r_max: float = typer.Option(2.5, help="random: largest |r| in W"),
    radius: float = typer.Option(1.3, help="polar: |r| in W"),
    positions: int = typer.Option(1000, help="polar: number of theta values"),
    orientations: int = typer.Option(1, help="polar: number of phi values per position"),
    periods: int = typer.Option(75, help="gait periods per configuration"),
    backend: str = typer.Option("native", help="native (MuJoCo C, all cores), mjx (JAX), warp "
                                 "(MuJoCo Warp: GPU, needs the gpu extra) or dart (the DART twin: "
                                 "the paper's engine, one core per lane; needs the dart extra)"),
    seed: int = typer.Option(0, help="seed of the random configurations"),
    batch_size: int = typer.Option(256, help="lanes simulated together"),
    out: pathlib.Path = typer.Option(pathlib.Path("scan.h5"), help="output store (.h5)"),
    flush_rows: int = typer.Option(64, help="journal finished configurations in blocks of this many"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    collisions: bool = typer.Option(False, help="store the per-period collision record (native and dart backends)"),
    collision_bins: int = typer.Option(16, help="collision record: bins per gait period"),
    imperfections: str = typer.Option("none", help=_IMPERFECTIONS_HELP),
    robot_draws: int = typer.Option(1, help=_DRAWS_HELP),
    robot_seed: Optional[int] = typer.Option(None, help=_ROBOT_SEED_HELP),
    set_: list[str] = typer.Option([], "--set", help=_SET_HELP),
    executor=None, gait_spec=None, store=None,
):
    """One basin scan at one amplitude into an HDF5 store."""
    from .specs import ScanConfig
    cfg = ScanConfig(configs=configs, n=n, r_range_W=(r_min, r_max), radius_W=radius, positions=positions,
                     orientations=orientations, amplitudes_deg=(gait_spec.amplitude_deg,), periods=periods,
                     chirality=gait_spec.chirality, gait=gait_spec.kind, period_s=gait_spec.period_s,
                     backend=backend, seed=seed, batch_size=batch_size,
                     model=_model(model), collisions=collisions, collision_bins=collision_bins,
                     imperfections=imperfections, overrides=_sets(set_), robot_draws=robot_draws,
                     robot_seed=robot_seed)
    _run_study(cfg, out, store, executor, flush_rows=flush_rows)


@_command("relax")
@_executor_options
@_gait_options
@_store_options
def relax(
    robots: int = typer.Option(7, help="robots per trial (the paper: 7)"),
    trials: int = typer.Option(20, help="trials (perturbed copies of the compressed start)"),
    first_trial: int = typer.Option(0, help="index of the first trial (a later stage of one study)"),
    periods: int = typer.Option(300, help="gait periods per trial (the lab: 300)"),
    seed: int = typer.Option(0, help="seed of the per-trial perturbations"),
    gap_mm: float = typer.Option(2.0, help="gap between neighbours' bounding boxes in the packing (mm)"),
    start: str = typer.Option("lattice", help="start family: lattice (staggered rows) or hex (one robot ringed "
                              "by six, for 7)"),
    headings: str = typer.Option("aligned", help="start headings: aligned (all 0, jittered) or drawn (uniform)"),
    start_phi: Optional[float] = typer.Option(None, help="scale the start to this area fraction n W D / hull "
                                              "of the centres (e.g. 0.4-0.6; default: spaced by --gap-mm)"),
    jitter_mm: float = typer.Option(1.0, help="s.d. of each robot's start position per axis (mm)"),
    jitter_deg: float = typer.Option(2.0, help="s.d. of each robot's start heading (deg)"),
    phase_jitter: float = typer.Option(0.0, help="s.d. of each robot's gait phase (periods; 0: in phase); "
                                                 "robots out of phase start one after another, each from its first corner"),
    retrigger_sd: float = typer.Option(0.0, help="re-start every robot's gait each cycle with a delay drawn "
                                       "afresh per robot and cycle, this s.d. (periods; 0: started once)"),
    onset_offset_sd: float = typer.Option(0.0, help="lasting per-robot timing offsets of this s.d. (periods) that "
                                          "set in at --onset-cycle: the robots start in phase (0: none)"),
    onset_cycle: int = typer.Option(1, help="the cycle at which --onset-offset-sd's offsets set in (>= 1)"),
    plate: float = typer.Option(0.6, help="side of the square plate (m); robots past its edge are recorded"),
    quiet_periods: int = typer.Option(10, help="stop a trial after this many periods without contact (0: never)"),
    backend: str = typer.Option("native", help="native, mjx, warp or dart (the DART twin; needs the dart extra)"),
    batch_size: int = typer.Option(4, help="trials simulated together"),
    out: pathlib.Path = typer.Option(pathlib.Path("relax.h5"), help="output store (.h5)"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    imperfections: str = typer.Option("none", help=_IMPERFECTIONS_HELP),
    set_: list[str] = typer.Option([], "--set", help=_SET_HELP),
    executor=None, gait_spec=None, store=None,
):
    """The relaxation experiment: N robots start compressed and in phase; do gliders emerge? (smx report reads it)"""
    from .specs import RelaxConfig
    cfg = RelaxConfig(n_robots=robots, trials=trials, first_trial=first_trial, periods=periods,
                      amplitude_deg=gait_spec.amplitude_deg, chirality=gait_spec.chirality, gait=gait_spec.kind,
                      period_s=gait_spec.period_s, seed=seed,
                      gap_mm=gap_mm, start=start, headings=headings, start_phi=start_phi, jitter_mm=jitter_mm,
                      jitter_deg=jitter_deg, phase_jitter=phase_jitter, retrigger_sd=retrigger_sd,
                      onset_offset_sd=onset_offset_sd, onset_cycle=onset_cycle,
                      plate_m=plate, quiet_periods=quiet_periods, backend=backend, batch_size=batch_size,
                      model=_model(model), imperfections=imperfections, overrides=_sets(set_))
    _run_study(cfg, out, store, executor)


@_command("sweep-amplitude")
@_executor_options
@_store_options
def sweep_amplitude(
    amplitudes: Optional[str] = typer.Option(None, help="'10:90:10' (inclusive) or '10,40,90' degrees"),
    study: Optional[pathlib.Path] = typer.Option(None, help="study file (TOML) from sweeps/; flags below override"),
    configs: Optional[str] = typer.Option(None, help=_CONFIGS_HELP),
    n: Optional[int] = typer.Option(None, help="random: number of configurations"),
    periods: Optional[int] = typer.Option(None, help="gait periods per configuration"),
    backend: Optional[str] = typer.Option(None, help="native, mjx, warp or dart"),
    seed: Optional[int] = typer.Option(None, help="seed of the random configurations"),
    out: pathlib.Path = typer.Option(pathlib.Path("sweep.h5"), help="output store (.h5)"),
    flush_rows: int = typer.Option(64, help="journal finished configurations in blocks of this many"),
    model: Optional[str] = typer.Option(None, help="model preset (default: the study file's, else the default preset)"),
    imperfections: Optional[str] = typer.Option(None, help="the robots' imperfections (default: the study "
                                                "file's, else none)"),
    robot_draws: Optional[int] = typer.Option(None, help=_DRAWS_HELP + " (default: the study file's, else 1)"),
    robot_seed: Optional[int] = typer.Option(None, help=_ROBOT_SEED_HELP),
    set_: list[str] = typer.Option([], "--set", help=_SET_HELP + " (on top of the study file's [scene])"),
    executor=None, store=None,
):
    """The same scan over several amplitudes, one store, one group per amplitude."""
    from .studyfile import sweep_config
    cfg = sweep_config(study, amplitudes, configs=configs, n=n, periods=periods, backend=backend, seed=seed,
                       model=model, imperfections=imperfections, sets=set_, robot_draws=robot_draws,
                       robot_seed=robot_seed)
    _run_study(cfg, out, store, executor, flush_rows=flush_rows)


@_command("phase-diagram")
def phase_diagram(
    store: pathlib.Path = typer.Argument(..., help="a scan or sweep store (.h5)"),
    out: pathlib.Path = typer.Option(pathlib.Path("figures"), help="output folder"),
    run: Optional[str] = typer.Option(None, help="run (amplitude group) to draw; default: all"),
):
    """(theta, phi) phase diagram: attracted red, repelled cyan, invalid white (PNG + SVG)."""
    from .plots import check_out_dir, phase_diagram as draw
    from .store import Store
    runs = [run] if run else Store(store).runs
    check_out_dir(out)
    typer.echo("wrote " + ", ".join(str(p) for r in runs for p in draw(store, out, r)))


@_command("pb")
def pb(
    store: pathlib.Path = typer.Argument(..., help="a sweep store (.h5), one run per amplitude"),
    out: pathlib.Path = typer.Option(pathlib.Path("figures"), help="output folder"),
):
    """P_b(alpha_max): bound at the end and bound throughout, 95% Clopper-Pearson intervals (PNG + SVG)."""
    from .report import pb_table
    lines, written = pb_table(store, out)
    _echo(lines + ["wrote " + ", ".join(map(str, written))])


@_command("report")
def report(
    stores: list[pathlib.Path] = typer.Argument(..., help="a scan or sweep store (.h5); or relaxation stores "
                                                "(smx relax), several if they are stages of one study; or a "
                                                "calibration report's folder (smx calibrate)"),
    out: pathlib.Path = typer.Option(pathlib.Path("report"), help="output folder"),
    burn_in: Optional[int] = typer.Option(None, help="periods before steady state (default min(30, K/3))"),
    glider_min_periods: Optional[int] = typer.Option(None, help="shortest bound run counted as a glider "
                                                     "(relaxation: default 100, the lab's criterion)"),
    apart: float = typer.Option(2.0, help="relaxation: closest a third robot may come to a glider (W)"),
    reading: Optional[str] = typer.Option(None, help=_READING_HELP),
):
    """Every figure and the summary table of a store: report.md, report.json and PNGs in one folder. Given a
    calibration report's folder (smx calibrate), formats its report.md again from its report.json."""
    from .calibrate import report as calibration_report
    if len(stores) == 1 and calibration_report.is_report(stores[0]):
        _echo([f"wrote {calibration_report.rewrite(stores[0], out)}"])
        return
    from .report import headline, write_any
    _echo(headline(write_any(stores, out, burn_in, glider_min_periods, apart, reading))
          + [f"wrote {out / 'report.md'}"])


@_command("validate")
def validate(
    data: pathlib.Path = typer.Option(pathlib.Path("validation-data"), help="folder of the studies' stores, one "
                                      "subfolder per model (complete ones are reused, interrupted ones resumed)"),
    out: pathlib.Path = typer.Option(pathlib.Path("docs/validation.md"), help="the page to write; figures go "
                                     "into a folder of the same name"),
    sweeps: Optional[pathlib.Path] = typer.Option(None, help="folder of the study files (default: the repo's sweeps/)"),
    studies: Optional[str] = typer.Option(None, help="comma-separated studies to run (default: all); the page is "
                                          "written from every complete, current store"),
    single_periods: int = typer.Option(75, help="periods of each lone-robot run"),
    quiet: bool = typer.Option(False, help="no progress bar"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    imperfections: str = typer.Option("none", help=_IMPERFECTIONS_HELP + "; stores go to DATA/MODEL+NAME"),
    set_: list[str] = typer.Option([], "--set", help=_SET_HELP + "; every study and lone robot; stores go to "
                                   "DATA/MODEL~FIELD=VALUE"),
    reading: Optional[str] = typer.Option(None, help=_READING_HELP),
    suite: str = typer.Option("small", help="small: every claim, studies cut to a day's work "
                              "(docs/validation.md); paper: the basin-scan claims at the paper's study sizes "
                              "(docs/validation-paper.md; hours of compute, every study resumable)"),
):
    """Measure the paper's claims from the studies in sweeps/ and write docs/validation.md."""
    from .validate import SWEEPS, parse_studies, run_validation
    chosen = parse_studies(studies, suite)
    from . import presets
    overrides = _sets(set_)
    # a bad value: one line before the progress bar starts (run_validation would refuse it too, inside the bar)
    presets.apply(presets.params(_model(model)), overrides)
    from .reduce.emergence import parse_reading
    reading = parse_reading(reading).value
    bar, progress = _progress(quiet)
    with bar:
        res = run_validation(data, out, sweeps or SWEEPS, model=_model(model), on_progress=progress,
                             single_periods=single_periods, studies=chosen, imperfections=imperfections,
                             overrides=overrides, reading=reading, suite=suite)
    _echo([f"{r.verdict:>16}: {r.claim}" for r in res.rows]
          + [f"note: {n}" for n in res.extra.get("notes", [])] + [f"wrote {out}"])


@_command("movie")
def movie(
    source: pathlib.Path = typer.Argument(..., help="a scan store (.h5, with --lane), a relaxation store (with "
                                                     "--trial) or a track from smx simulate "
                                                     "(.csv with its .json sidecar, or .h5)"),
    lane: Optional[int] = typer.Option(None, help="scan store: the lane (configuration index) to show"),
    run: Optional[str] = typer.Option(None, help="scan store: run (amplitude group); default: the first"),
    trial: Optional[int] = typer.Option(None, help="relaxation store: the trial to show"),
    out: pathlib.Path = typer.Option(pathlib.Path("movie.mp4"), help="output .mp4 (GIF if no packaged ffmpeg) "
                                                                     "or .gif"),
    fps: float = typer.Option(20.0, help="frames per second"),
    speed: float = typer.Option(4.0, help="real-time factor: simulated seconds per movie second"),
    duration: Optional[float] = typer.Option(None, help="movie length in s (default: the whole track)"),
    size: int = typer.Option(480, help="frame width and height in pixels"),
    trail: float = typer.Option(5.0, help="trail of the body centres, in gait periods"),
):
    """Top-view movie of a simulated track, or of one lane of a scan store or one trial of a relaxation store
    simulated again exactly."""
    from .movie import MovieOptions, check_output, render
    from .replay import movie_track
    opts = MovieOptions(fps=fps, speed=speed, duration=duration, trail_periods=trail, size_px=size)
    opts.validate()
    check_output(out)
    t, poses, robot, period, title, same = movie_track(source, lane, run, frame_interval=min(0.05, speed / fps),
                                                       trial=trial)
    if not same:
        typer.echo("warning: the re-simulation differs from the stored records "
                   "(another package or MuJoCo version made the store)", err=True)
    info = render(t, poses, robot, period, out, opts, title=title)
    typer.echo(f"wrote {info.path} ({info.format}, {info.frames} frames at {info.fps:g} fps, "
               f"{info.size[0]}x{info.size[1]})")


@_command("synth")
def synth(
    out: pathlib.Path = typer.Argument(..., help="output folder (one CSV + JSON sidecar per amplitude)"),
    robots: int = typer.Option(1, help="robots per trial"),
    trials: int = typer.Option(6, help="trials per amplitude"),
    periods: int = typer.Option(6, help="gait periods per trial"),
    amplitudes: str = typer.Option("30,90", help="alpha_max values, e.g. '30,90' or '10:90:20'"),
    effect: list[str] = typer.Option([], help="hidden effect, e.g. 'plate_tilt:tilt_x_deg=2' (repeatable)"),
    noise_xy_mm: float = typer.Option(0.05, help="tracking noise on x, y (mm)"),
    noise_theta_deg: float = typer.Option(0.05, help="tracking noise on the heading (deg)"),
    arm_noise_deg: float = typer.Option(0.3, help="tracking noise on arm angles (deg)"),
    no_arms: bool = typer.Option(False, help="leave arm angles untracked (empty columns)"),
    frame_rate: float = typer.Option(30.0, help="camera frame rate (Hz)"),
    occlusion: float = typer.Option(0.03, help="fraction of rows dropped"),
    arm_bias_deg: float = typer.Option(0.0, help="an effect outside the library: robot arm 2 misread by this"),
    separation: float = typer.Option(3.0, help="distance between robots at the start (W)"),
    seed: int = typer.Option(0),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    set_: list[str] = typer.Option([], "--set", help=_SET_HELP),
):
    """Measured-like data from the model with hidden effects, in the interchange format."""
    from .calibrate.synth import parse_effect, synth as make
    from .studyfile import parse_amplitudes
    written = make(out, robots=robots, trials=trials, periods=periods, amplitudes=parse_amplitudes(amplitudes),
                   effects=dict(parse_effect(e) for e in effect), noise_xy_mm=noise_xy_mm,
                   noise_theta_deg=noise_theta_deg, arm_noise_deg=arm_noise_deg, arms_tracked=not no_arms,
                   frame_rate_hz=frame_rate, occlusion=occlusion, arm_bias_deg=arm_bias_deg,
                   separation_w=separation, seed=seed, model=_model(model), overrides=_sets(set_))
    typer.echo("wrote " + ", ".join(map(str, written)))


@_command("calibrate")
def calibrate(
    data: pathlib.Path = typer.Argument(..., help="a CSV with its JSON sidecar, or a folder of them"),
    out: pathlib.Path = typer.Option(pathlib.Path("calibration"), help="report folder"),
    overwrite: bool = typer.Option(False, help="replace an existing report"),
    model: Optional[str] = typer.Option(None, help="model preset to fit from (default: the sidecar's, else the "
                                                   "default preset)"),
    nominal: bool = typer.Option(True, help="fit the robot's nominal parameters first (servo, arm lengths, "
                                             "masses, plate μ); --no-nominal takes the preset's as exact"),
    set_: list[str] = typer.Option([], "--set", help=_SET_HELP + " (before the sidecar's measured values)"),
    plate_hypothesis: list[str] = typer.Option([], help="also fit this plate effect jointly with the nominal "
                                                        "parameters from a grid start (repeatable; "
                                                        "arm_plate_contact is fitted so where the body keeps "
                                                        "turning between an arm's kicks, and not at all where "
                                                        "it does not, unless named here)"),
):
    """Residuals of the model against measured tracks, ranked candidate effects, the fit, before/after."""
    from .calibrate import report
    from .calibrate.data import load
    from .calibrate.heldout import compare_heldout
    from .calibrate.stages import calibrate as run, plate_hypotheses_with
    if model is not None:
        _model(model)
    try:
        plates = plate_hypotheses_with(plate_hypothesis)
    except ValueError as e:
        raise typer.BadParameter(str(e), param_hint="--plate-hypothesis")
    report.check_output(out, overwrite)
    changes = _sets(set_)
    trials = load(data, model, changes)
    t0 = time.perf_counter()
    result = run(trials, on_step=lambda msg: typer.echo(f"[{time.perf_counter() - t0:4.0f} s] {msg}"), nominal=nominal,
                 plate_hypotheses=plates)
    report.write(result, compare_heldout(result, trials), out, overrides=dict(changes) if changes else None)
    typer.echo(f"{result.verdict}; wrote {out / 'report.md'}")


def main():  # pragma: no cover
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
