"""``smx``: the command line. Thin: parse, build a config, call the library."""

from __future__ import annotations

import functools
import inspect
import math
import pathlib
import sys
from typing import Optional

import numpy as np
import typer

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="Batched simulation of smarticles and the gliders they form.")


class UserError(Exception):
    """Bad input: reported as one line, exit code 2."""


def _fail(msg: str) -> None:
    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(2)


_MODEL_HELP = "model preset (smx models --list; default: the default preset, docs/model.md)"
_IMPERFECTIONS_HELP = ("the robots' imperfections, drawn per robot from the seed (smx models --list; "
                       "default none: ideal robots)")


def _preset(name: Optional[str]):
    """The named preset, or UserError with the known names."""
    from . import presets
    try:
        return presets.get(name)
    except ValueError as e:
        raise UserError(str(e)) from None


def _gait(amplitude: float, chirality: str, gait: str, period: Optional[float]):
    from .gait import GaitSpec
    return GaitSpec(amplitude_deg=amplitude, chirality=chirality, kind=gait, period_s=period)


@app.command()
def simulate(
    scene: str = typer.Option("pair", help="single, pair or seven (the scenes in models/)"),
    config: Optional[str] = typer.Option(None, help="pair start as '|r|,theta,phi' (|r| in W, angles in deg)"),
    amplitude: float = typer.Option(90.0, help="alpha_max in degrees"),
    chirality: str = typer.Option("ccw", help="ccw or cw"),
    gait: str = typer.Option("square", help="square or diagonal (time-symmetric)"),
    period: Optional[float] = typer.Option(None, help="gait period in s (default: 1.6 s x amplitude / 90)"),
    periods: int = typer.Option(10, help="number of gait periods"),
    track_stride: int = typer.Option(20, help="write every this many time steps (of the backend's step)"),
    backend: str = typer.Option("native", help="native, or dart (the DART twin at 0.1 ms steps; needs the dart extra)"),
    out: pathlib.Path = typer.Option(pathlib.Path("track.csv"), help="output .csv (+ .json sidecar) or .h5"),
    overwrite: bool = typer.Option(False, help="replace an existing output file"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
):
    """Simulate one scene and write its track (the measured-data format)."""
    from . import configs, scene as scene_mod, tracks
    from .engine.simulate import simulate as run

    try:
        preset = _preset(model)
        params = preset.params
        g = _gait(amplitude, chirality, gait, period)
        g.validate(params.robot.servo_speed, params.robot.arm_limit_deg)
        if periods < 1 or track_stride < 1:
            raise UserError("--periods and --track-stride must be positive")
        if backend not in ("native", "dart"):
            raise UserError(f"--backend must be native or dart (the backends that record tracks), got {backend!r}")
        from .engine.dart import check_study, study_timestep
        check_study(backend, None)  # dart: installed
        dt = study_timestep(backend, None, params.timestep)
        if out.exists() and not overwrite:
            raise UserError(f"{out} exists; pass --overwrite to replace it")
        tracks.check_output(out)  # before simulating, not after
        a0 = g.setpoints(0.0, params.robot.servo_speed)
        if config is not None:
            try:
                r, th, ph = (float(v) for v in config.split(","))
            except ValueError:
                raise UserError(f"--config must be three numbers '|r|,theta,phi', got {config!r}") from None
            poses = configs.pair_poses(r, math.radians(th), math.radians(ph), a0[0], a0[1], params.robot)
        else:
            poses = [(x, y, h, a0[0], a0[1]) for x, y, h, _, _ in scene_mod.standard_poses(scene, params.robot)]
        res = run(params, poses, g, periods, track_stride=track_stride, backend=backend)
        meta = tracks.sidecar(len(poses), g, params.plate_friction, 1.0 / (track_stride * dt), model=preset.name)
        t = [0.0, *res.track_t]
        track = [res.poses[0], *res.track]
        written = tracks.write_track(out, t, track, meta,
                                     records={"touched": res.touched, "poses": res.poses, "min_dist": res.min_dist})
    except (UserError, ValueError) as e:
        _fail(str(e))
    n_touch = int(res.touched.any(1).sum()) if res.touched.size else 0
    typer.echo(f"{len(poses)} robots, {periods} periods of {res.period:.3g} s; "
               f"pairs touched in {n_touch}/{periods} periods; wrote {', '.join(map(str, written))}")


@app.command()
def models(
    out: pathlib.Path = typer.Option(pathlib.Path("models"), help="directory for the reference scenes"),
    check: bool = typer.Option(False, help="only report whether the stored scenes are up to date"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    list_: bool = typer.Option(False, "--list", help="list the model presets and where their values come from"),
):
    """Regenerate (or --check) the reference MJCF scenes in models/ (made by the default preset)."""
    from . import presets
    from .scene import reference_models

    if list_:
        from . import imperfections
        for p in presets.PRESETS.values():
            typer.echo(f"{p.name}{' (default)' if p.name == presets.DEFAULT else ''}: {p.summary}")
            for field, source in p.sources:
                typer.echo(f"    {field}: {source}")
        typer.echo("\nimperfections (--imperfections NAME):")
        for s in imperfections.SETS.values():
            typer.echo(f"{s.name}: {s.summary}")
            for prior, source in s.sources:
                typer.echo(f"    {prior}: {source}")
        return
    try:
        preset = _preset(model)
    except UserError as e:
        _fail(str(e))
    stale = []
    for name, xml in reference_models(preset.params).items():
        path = out / name
        if path.exists() and path.read_text() == xml:
            continue
        stale.append(name)
        if not check:
            if not out.is_dir():
                _fail(f"directory {out} does not exist")
            path.write_text(xml)
    if check and stale:
        _fail(f"stale models: {', '.join(stale)}; run `smx models`")
    typer.echo(("updated: " + ", ".join(stale)) if stale and not check else "models up to date")


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


def _executor(executor: str, scheduler: Optional[str], workers: Optional[int], threads_per_worker: int,
              shard_size: int, dashboard: bool, slurm: Optional[dict] = None):
    """None (run here) or a DaskExecutor from the command line's options (ValueError on bad ones)."""
    if executor == "local":
        if scheduler is not None:
            raise ValueError("--scheduler needs --executor dask")
        return None
    if executor not in ("dask", "slurm"):
        raise ValueError(f"--executor must be local, dask or slurm, got {executor!r}")
    from .executors import DaskExecutor, SlurmSpec
    spec = None
    if executor == "slurm":
        if not slurm or not slurm.get("memory"):
            raise ValueError("--executor slurm needs --jobs, --job-cores and --job-memory")
        spec = SlurmSpec(**slurm)
    return DaskExecutor(scheduler=scheduler, workers=workers, threads_per_worker=threads_per_worker,
                        shard_size=shard_size, dashboard=dashboard, slurm=spec)


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


def _executor_options(command):
    """Give ``command`` the executor options; it is called with ``executor`` = the executor they name
    (one line and exit 2 on bad ones, before the command runs)."""
    names = [p.name for p in _EXECUTOR_OPTIONS]

    @functools.wraps(command)
    def run(**kw):
        o = {n: kw.pop(n) for n in names}
        try:
            ex = _executor(o["executor"], o["scheduler"], o["workers"], o["threads_per_worker"], o["shard_size"],
                           o["dashboard"], dict(jobs=o["jobs"], cores=o["job_cores"], memory=o["job_memory"],
                                                walltime=o["walltime"], queue=o["queue"], account=o["account"]))
        except ValueError as e:
            _fail(str(e))
        return command(**kw, executor=ex)

    own = [p for p in inspect.signature(command).parameters.values() if p.name != "executor"]
    run.__signature__ = inspect.Signature(own + list(_EXECUTOR_OPTIONS))
    return run


def _scan_common(cfg, out: pathlib.Path, resume: bool, overwrite: bool, quiet: bool, flush_rows: int = 64,
                 executor=None):
    """Run a scan/sweep with a progress bar and print the summary."""
    from .executors import ExecutorError
    from .store import StoreError
    from .studies import run_study

    if resume and overwrite:
        _fail("--resume and --overwrite exclude each other")
    mode = "resume" if resume else "overwrite" if overwrite else "new"
    try:
        if flush_rows < 1:
            raise ValueError("--flush-rows must be positive")
        bar, progress = _progress(quiet)
        with bar:
            summary = run_study(cfg, out, mode=mode, executor=executor, on_progress=progress, flush_rows=flush_rows)
    except (ValueError, StoreError, ExecutorError) as e:
        _fail(str(e))
    for name, r in summary["runs"].items():
        typer.echo(f"{name}: {r['valid']}/{summary['configs']} valid configurations, "
                   f"bound at the end: {r['bound_end_fraction']:.1%}")
    typer.echo(f"wall {summary['wall_s']:.1f} s, {summary['steps']:,} steps simulated "
               f"({summary['steps_per_s']:,.0f} steps/s); wrote {out}")


_CONFIGS_HELP = "random (uniform |r|, theta, phi) or polar (fixed |r| grid)"


@app.command()
@_executor_options
def scan(
    configs: str = typer.Option("random", help=_CONFIGS_HELP),
    n: int = typer.Option(5000, help="random: number of configurations"),
    r_min: float = typer.Option(0.5, help="random: smallest |r| in W"),
    r_max: float = typer.Option(2.5, help="random: largest |r| in W"),
    radius: float = typer.Option(1.3, help="polar: |r| in W"),
    positions: int = typer.Option(1000, help="polar: number of theta values"),
    orientations: int = typer.Option(1, help="polar: number of phi values per position"),
    amplitude: float = typer.Option(90.0, help="alpha_max in degrees"),
    periods: int = typer.Option(75, help="gait periods per configuration"),
    chirality: str = typer.Option("ccw", help="ccw or cw"),
    gait: str = typer.Option("square", help="square or diagonal"),
    period: Optional[float] = typer.Option(None, help="gait period in s (default: 1.6 s x amplitude / 90)"),
    backend: str = typer.Option("native", help="native (MuJoCo C, all cores), mjx (JAX), warp "
                                 "(MuJoCo Warp: GPU, needs the gpu extra) or dart (the DART twin: "
                                 "the paper's engine, one core per lane; needs the dart extra)"),
    seed: int = typer.Option(0, help="seed of the random configurations"),
    batch_size: int = typer.Option(256, help="lanes simulated together"),
    out: pathlib.Path = typer.Option(pathlib.Path("scan.h5"), help="output store (.h5)"),
    resume: bool = typer.Option(False, help="continue an interrupted scan into the same store"),
    overwrite: bool = typer.Option(False, help="replace an existing store"),
    quiet: bool = typer.Option(False, help="no progress bar"),
    flush_rows: int = typer.Option(64, help="journal finished configurations in blocks of this many"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    collisions: bool = typer.Option(False, help="store the per-period collision record (native and dart backends)"),
    collision_bins: int = typer.Option(16, help="collision record: bins per gait period"),
    imperfections: str = typer.Option("none", help=_IMPERFECTIONS_HELP),
    executor=None,
):
    """One basin scan at one amplitude into an HDF5 store."""
    from .specs import ScanConfig
    try:
        name = _preset(model).name
    except (UserError, ValueError) as e:
        _fail(str(e))
    cfg = ScanConfig(configs=configs, n=n, r_range_W=(r_min, r_max), radius_W=radius, positions=positions,
                     orientations=orientations, amplitudes_deg=(amplitude,), periods=periods, chirality=chirality,
                     gait=gait, period_s=period, backend=backend, seed=seed, batch_size=batch_size, model=name,
                     collisions=collisions, collision_bins=collision_bins, imperfections=imperfections)
    _scan_common(cfg, out, resume, overwrite, quiet, flush_rows, executor=executor)


@app.command("relax")
@_executor_options
def relax(
    robots: int = typer.Option(7, help="robots per trial (the paper: 7)"),
    trials: int = typer.Option(20, help="trials (perturbed copies of the compressed start)"),
    first_trial: int = typer.Option(0, help="index of the first trial (a later stage of one study)"),
    periods: int = typer.Option(300, help="gait periods per trial (the lab: 300)"),
    amplitude: float = typer.Option(90.0, help="alpha_max in degrees"),
    chirality: str = typer.Option("ccw", help="ccw or cw"),
    gait: str = typer.Option("square", help="square or diagonal"),
    period: Optional[float] = typer.Option(None, help="gait period in s (default: 1.6 s x amplitude / 90)"),
    seed: int = typer.Option(0, help="seed of the per-trial perturbations"),
    gap_mm: float = typer.Option(2.0, help="gap between neighbours' bounding boxes in the packing (mm)"),
    jitter_mm: float = typer.Option(1.0, help="s.d. of each robot's start position per axis (mm)"),
    jitter_deg: float = typer.Option(2.0, help="s.d. of each robot's start heading (deg)"),
    phase_jitter: float = typer.Option(0.0, help="s.d. of each robot's gait phase (periods; 0: in phase)"),
    plate: float = typer.Option(0.6, help="side of the square plate (m); robots past its edge are recorded"),
    quiet_periods: int = typer.Option(10, help="stop a trial after this many periods without contact (0: never)"),
    backend: str = typer.Option("native", help="native, mjx, warp or dart (the DART twin; needs the dart extra)"),
    batch_size: int = typer.Option(4, help="trials simulated together"),
    out: pathlib.Path = typer.Option(pathlib.Path("relax.h5"), help="output store (.h5)"),
    resume: bool = typer.Option(False, help="continue an interrupted run into the same store"),
    overwrite: bool = typer.Option(False, help="replace an existing store"),
    quiet: bool = typer.Option(False, help="no progress bar"),
    model: Optional[str] = typer.Option(None, help=_MODEL_HELP),
    imperfections: str = typer.Option("none", help=_IMPERFECTIONS_HELP),
    executor=None,
):
    """The relaxation experiment: N robots start compressed and in phase; do gliders emerge? (smx report reads it)"""
    from .executors import ExecutorError
    from .specs import RelaxConfig
    from .store import StoreError
    from .studies import run_study
    if resume and overwrite:
        _fail("--resume and --overwrite exclude each other")
    try:
        name = _preset(model).name
        cfg = RelaxConfig(n_robots=robots, trials=trials, first_trial=first_trial, periods=periods,
                          amplitude_deg=amplitude, chirality=chirality, gait=gait, period_s=period, seed=seed,
                          gap_mm=gap_mm, jitter_mm=jitter_mm, jitter_deg=jitter_deg, phase_jitter=phase_jitter,
                          plate_m=plate, quiet_periods=quiet_periods, backend=backend, batch_size=batch_size,
                          model=name, imperfections=imperfections)
        mode = "resume" if resume else "overwrite" if overwrite else "new"
        bar, progress = _progress(quiet)
        with bar:
            summary = run_study(cfg, out, mode=mode, executor=executor, on_progress=progress)
    except (UserError, ValueError, StoreError, ExecutorError) as e:
        _fail(str(e))
    typer.echo(f"{summary['trials']} trials, {summary['stopped_early']} stopped early (no contact for "
               f"{quiet_periods} periods); wall {summary['wall_s']:.1f} s, {summary['steps']:,} steps "
               f"({summary['steps_per_s']:,.0f} steps/s); wrote {out}")


@app.command("sweep-amplitude")
@_executor_options
def sweep_amplitude(
    amplitudes: Optional[str] = typer.Option(None, help="'10:90:10' (inclusive) or '10,40,90' degrees"),
    study: Optional[pathlib.Path] = typer.Option(None, help="study file (TOML) from sweeps/; flags below override"),
    configs: Optional[str] = typer.Option(None, help=_CONFIGS_HELP),
    n: Optional[int] = typer.Option(None, help="random: number of configurations"),
    periods: Optional[int] = typer.Option(None, help="gait periods per configuration"),
    backend: Optional[str] = typer.Option(None, help="native, mjx, warp or dart"),
    seed: Optional[int] = typer.Option(None, help="seed of the random configurations"),
    out: pathlib.Path = typer.Option(pathlib.Path("sweep.h5"), help="output store (.h5)"),
    resume: bool = typer.Option(False, help="continue an interrupted sweep"),
    overwrite: bool = typer.Option(False, help="replace an existing store"),
    quiet: bool = typer.Option(False, help="no progress bar"),
    flush_rows: int = typer.Option(64, help="journal finished configurations in blocks of this many"),
    model: Optional[str] = typer.Option(None, help="model preset (default: the study file's, else the default preset)"),
    imperfections: Optional[str] = typer.Option(None, help="the robots' imperfections (default: the study "
                                                "file's, else none)"),
    executor=None,
):
    """The same scan over several amplitudes, one store, one group per amplitude."""
    import dataclasses

    from .specs import ScanConfig, load_study, parse_amplitudes
    try:
        cfg = load_study(study) if study is not None else ScanConfig()
        changes = {k: v for k, v in dict(configs=configs, n=n, periods=periods, backend=backend, seed=seed,
                                         model=model, imperfections=imperfections).items() if v is not None}
        if amplitudes is not None:
            changes["amplitudes_deg"] = parse_amplitudes(amplitudes)
        elif study is None:
            raise UserError("give --amplitudes or --study")
        cfg = dataclasses.replace(cfg, **changes)
        _preset(cfg.model)
    except (UserError, ValueError) as e:
        _fail(str(e))
    _scan_common(cfg, out, resume, overwrite, quiet, flush_rows, executor=executor)


@app.command("phase-diagram")
def phase_diagram(
    store: pathlib.Path = typer.Argument(..., help="a scan or sweep store (.h5)"),
    out: pathlib.Path = typer.Option(pathlib.Path("figures"), help="output folder"),
    run: Optional[str] = typer.Option(None, help="run (amplitude group) to draw; default: all"),
):
    """(theta, phi) phase diagram: attracted red, repelled cyan, invalid white (PNG + SVG)."""
    from .plots import phase_diagram as draw
    from .store import Store, StoreError
    try:
        runs = [run] if run else Store(store).runs
        if out.exists() and not out.is_dir():
            raise UserError(f"{out} is not a directory")
        written = [p for r in runs for p in draw(store, out, r)]
    except (UserError, StoreError) as e:
        _fail(str(e))
    typer.echo("wrote " + ", ".join(map(str, written)))


def _out_dir(out: pathlib.Path) -> None:
    if out.exists() and not out.is_dir():
        raise UserError(f"{out} exists and is not a directory")


@app.command("pb")
def pb(
    store: pathlib.Path = typer.Argument(..., help="a sweep store (.h5), one run per amplitude"),
    out: pathlib.Path = typer.Option(pathlib.Path("figures"), help="output folder"),
):
    """P_b(alpha_max): bound at the end and bound throughout, 95% Clopper-Pearson intervals (PNG + SVG)."""
    from . import plots
    from .report import pb_by_amplitude
    from .store import StoreError
    try:
        _out_dir(out)
        rows = pb_by_amplitude(store)
    except (UserError, StoreError) as e:
        _fail(str(e))
    typer.echo(f"{'alpha_max':>9}  {'valid':>6}  {'P_b end [95% CI]':>24}  {'P_b throughout [95% CI]':>24}")
    for a, p in rows:
        e, t = p["end"], p["throughout"]
        typer.echo(f"{a:>9g}  {p['n']:>6}  {e[0]:.3f} [{e[1]:.3f}, {e[2]:.3f}]".ljust(44)
                   + f"  {t[0]:.3f} [{t[1]:.3f}, {t[2]:.3f}]")
    written = plots.pb_curve([a for a, _ in rows], [p["end"][:3] for _, p in rows],
                             [p["throughout"][:3] for _, p in rows], out)
    typer.echo("wrote " + ", ".join(map(str, written)))


@app.command("report")
def report(
    stores: list[pathlib.Path] = typer.Argument(..., help="a scan or sweep store (.h5); or relaxation stores "
                                                "(smx relax), several if they are stages of one study"),
    out: pathlib.Path = typer.Option(pathlib.Path("report"), help="output folder"),
    burn_in: Optional[int] = typer.Option(None, help="periods before steady state (default min(30, K/3))"),
    glider_min_periods: Optional[int] = typer.Option(None, help="shortest bound run counted as a glider "
                                                     "(relaxation: default 100, the lab's criterion)"),
    apart: float = typer.Option(2.0, help="relaxation: closest a third robot may come to a glider (W)"),
):
    """Every figure and the summary table of a store: report.md, report.json and PNGs in one folder."""
    from .report import ReportOptions, write_relax_report, write_report
    from .store import Store, StoreError
    try:
        kinds = {Store(s).kind for s in stores}
        _out_dir(out)
        if (burn_in is not None and burn_in < 0) or (glider_min_periods is not None and glider_min_periods < 2):
            raise UserError("--burn-in must be >= 0 and --glider-min-periods >= 2")
        if not apart > 0:
            raise UserError("--apart must be positive")
        if kinds == {"relax"}:
            rep = write_relax_report(stores, out, min_periods=glider_min_periods or 100, apart_W=apart)
        elif len(stores) > 1:
            raise UserError("several stores are read only as stages of one relaxation study; "
                            "report scan stores one at a time")
        else:
            rep = write_report(stores[0], out, ReportOptions(burn_in=burn_in, glider_min_periods=glider_min_periods))
    except (UserError, StoreError) as e:
        _fail(str(e))
    if rep.get("kind") == "relax":
        lo, hi = rep["interval"]
        typer.echo(f"{rep['emerged']}/{rep['valid']} trials formed a glider ({rep['fraction']:.2f}, 95% CI "
                   f"{lo:.2f}-{hi:.2f}; lab 77/151); distance {rep['distance']['mean']:.2f} W "
                   f"(n = {rep['distance']['n']}; lab 2.9 W)")
    else:
        for s in rep["runs"]:
            b = (s.get("beta") or {}).get("value")
            typer.echo(f"{s['run']}: P_b end {s['pb_end'][0]}, C1 basin {(s.get('C1') or {}).get('basin_fraction')}, "
                       f"C2 basin {(s.get('C2') or {}).get('basin_fraction')}, gliders {s['gliders']}, beta {b}")
    typer.echo(f"wrote {out / 'report.md'}")


@app.command("validate")
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
):
    """Measure the paper's claims from the studies in sweeps/ and write docs/validation.md."""
    from .store import StoreError
    from .validate import STUDIES, SWEEPS, run_validation
    sweeps = sweeps or SWEEPS
    try:
        preset = _preset(model)
        missing = [f for f in STUDIES.values() if not (sweeps / f).is_file()]
        if missing:
            raise UserError(f"study files missing in {sweeps}: {', '.join(missing)}")
        chosen = None
        if studies is not None:
            chosen = [x.strip() for x in studies.split(",") if x.strip()]
            bad = [x for x in chosen if x not in STUDIES]
            if bad or not chosen:
                raise UserError(f"--studies: unknown {', '.join(bad) or '(none given)'}; known: {', '.join(STUDIES)}")
        if not out.parent.is_dir():
            raise UserError(f"output directory {out.parent} does not exist")
        if data.exists() and not data.is_dir():
            raise UserError(f"{data} exists and is not a directory")
        if single_periods < 2:
            raise UserError("--single-periods must be >= 2")
        from . import imperfections as imp
        imp.get(imperfections)
        bar, progress = _progress(quiet)
        with bar:
            res = run_validation(data, out, sweeps, model=preset.name, on_progress=progress,
                                 single_periods=single_periods, studies=chosen, imperfections=imperfections)
    except (UserError, ValueError, StoreError) as e:
        _fail(str(e))
    for r in res["rows"]:
        typer.echo(f"{r['verdict']:>16}: {r['claim']}")
    for n in res["extra"].get("notes", []):
        typer.echo(f"note: {n}")
    typer.echo(f"wrote {out}")


@app.command("movie")
def movie(
    source: pathlib.Path = typer.Argument(..., help="a scan store (.h5, with --lane) or a track from smx simulate "
                                                     "(.csv with its .json sidecar, or .h5)"),
    lane: Optional[int] = typer.Option(None, help="scan store: the lane (configuration index) to show"),
    run: Optional[str] = typer.Option(None, help="scan store: run (amplitude group); default: the first"),
    out: pathlib.Path = typer.Option(pathlib.Path("movie.mp4"), help="output .mp4 (GIF if no packaged ffmpeg) "
                                                                     "or .gif"),
    fps: float = typer.Option(20.0, help="frames per second"),
    speed: float = typer.Option(4.0, help="real-time factor: simulated seconds per movie second"),
    duration: Optional[float] = typer.Option(None, help="movie length in s (default: the whole track)"),
    size: int = typer.Option(480, help="frame width and height in pixels"),
    trail: float = typer.Option(5.0, help="trail of the body centres, in gait periods"),
):
    """Top-view movie of a simulated track, or of one lane of a scan store simulated again exactly."""
    from .movie import MovieOptions, load_track, render
    from .store import StoreError
    opts = MovieOptions(fps=fps, speed=speed, duration=duration, trail_periods=trail, size_px=size)
    try:
        opts.validate()
        if not source.exists():
            raise UserError(f"{source} does not exist")
        if out.suffix.lower() not in (".mp4", ".gif"):
            raise UserError(f"movie must end in .mp4 or .gif, got {out.name!r}")
        if not out.parent.is_dir():
            raise UserError(f"output directory {out.parent} does not exist")
        if _is_scan_store(source):
            from .scan import resimulate_lane
            if lane is None:
                raise UserError("a scan store needs --lane (the configuration index to show)")
            t, poses, res, params, gait, rows = resimulate_lane(source, run, lane,
                                                                frame_interval=min(0.05, speed / fps))
            k = int(rows["periods_run"])
            same = np.array_equal(res.poses[1:k + 1].astype(np.float32), rows["poses"][:k])
            title = f"{source.name} lane {lane}, {gait.amplitude_deg:g} deg" + ("" if same else " (differs from store!)")
            robot, period = params.robot, gait.period()
            if not same:
                typer.echo("warning: the re-simulation differs from the stored records "
                           "(another package or MuJoCo version made the store)", err=True)
        else:
            if lane is not None:
                raise UserError("--lane is for scan stores; this is a track")
            t, poses, robot, period, title = load_track(source)
        info = render(t, poses, robot, period, out, opts, title=title)
    except (UserError, ValueError, StoreError) as e:
        _fail(str(e))
    typer.echo(f"wrote {info['path']} ({info['format']}, {info['frames']} frames at {info['fps']:g} fps, "
               f"{info['size'][0]}x{info['size'][1]})")


def _is_scan_store(path: pathlib.Path) -> bool:
    if path.suffix.lower() not in (".h5", ".hdf5"):
        return False
    import h5py
    try:
        with h5py.File(path, "r") as f:
            return "runs" in f
    except OSError:
        raise UserError(f"{path} is not a readable HDF5 file") from None


@app.command("synth")
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
):
    """Measured-like data from the model with hidden effects, in the interchange format."""
    from .calibrate.synth import parse_effect, synth as make
    from .specs import parse_amplitudes
    try:
        name = _preset(model).name
        effects = dict(parse_effect(e) for e in effect)
        amps = parse_amplitudes(amplitudes)
        if "tracking_noise" in effects:
            noise_xy_mm = effects["tracking_noise"]["noise_xy_mm"]
            noise_theta_deg = effects["tracking_noise"]["noise_theta_deg"]
        if out.exists() and any(out.glob("*.csv")):
            raise UserError(f"{out} already holds data; choose an empty folder")
        written = make(out, robots=robots, trials=trials, periods=periods, amplitudes=amps,
                       effects=effects, noise_xy_mm=noise_xy_mm, noise_theta_deg=noise_theta_deg,
                       arm_noise_deg=arm_noise_deg, arms_tracked=not no_arms, frame_rate_hz=frame_rate,
                       occlusion=occlusion, arm_bias_deg=arm_bias_deg, separation_w=separation, seed=seed,
                       model=name)
    except (UserError, ValueError) as e:
        _fail(str(e))
    typer.echo("wrote " + ", ".join(map(str, written)))


@app.command("calibrate")
def calibrate(
    data: pathlib.Path = typer.Argument(..., help="a CSV with its JSON sidecar, or a folder of them"),
    out: pathlib.Path = typer.Option(pathlib.Path("calibration"), help="report folder"),
    overwrite: bool = typer.Option(False, help="replace an existing report"),
    model: Optional[str] = typer.Option(None, help="model preset to fit from (default: the sidecar's, else the "
                                                   "default preset)"),
    nominal: bool = typer.Option(True, help="fit the robot's nominal parameters first (servo, arm lengths, "
                                             "masses, plate μ); --no-nominal takes the preset's as exact"),
):
    """Residuals of the model against measured tracks, ranked candidate effects, the fit, before/after."""
    from .calibrate import fit, report
    from .calibrate.data import load
    try:
        if model is not None:
            _preset(model)
        if out.exists() and not out.is_dir():
            raise UserError(f"{out} exists and is not a directory")
        if (out / "report.md").exists() and not overwrite:
            raise UserError(f"{out} already holds a report; pass --overwrite to replace it")
        if not out.exists() and not out.parent.is_dir():
            raise UserError(f"output directory {out.parent} does not exist")
        trials = load(data, model)
        result = fit.calibrate(trials, on_step=typer.echo, nominal=nominal)
        report.write(result, trials, out)
    except (UserError, ValueError) as e:
        _fail(str(e))
    typer.echo(f"{result['verdict']}; wrote {out / 'report.md'}")


def main():  # pragma: no cover
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
