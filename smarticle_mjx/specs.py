"""Study specs: what a study is, validated, and the JSON its store records.

* :class:`ScanConfig`: a basin scan or amplitude sweep (random, polar or explicit pair starts);
* :class:`RelaxConfig`: the relaxation experiment (N robots started compressed);
* :class:`BoundStudy`: pairs started as steady gliders taken from another study's store
  (``configs = "bound"`` in a study file);
* :class:`RelaxStudy`: a relaxation study in stages (``configs = "relax"``).

Every spec validates itself against the scene it will run (``validate``) and writes the JSON its store
records (``to_json``; ``config_from_json`` and ``relax_config_from_json`` read them back). Study files
(TOML) are read by :mod:`smarticle_mjx.studyfile`, the validation suite's list is
:mod:`smarticle_mjx.suite`, a scene's JSON is :mod:`smarticle_mjx.scene`'s. Nothing here simulates or
writes a store.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import configs as C
from . import imperfections, presets
from .gait import GaitSpec
from .suite import STUDY_NAMES
from .scene import SceneParams

@dataclasses.dataclass(frozen=True)
class ScanConfig:
    """Everything that defines a scan's data; stored in full in the store.

    ``configs`` "random": ``n`` uniform (|r|, theta, phi) with |r| in
    ``r_range_W``; "polar": |r| = ``radius_W``, ``positions`` x
    ``orientations`` grid (the paper's 1000-point scan at 1.3 W);
    "explicit": the (|r| W, theta rad, phi rad) triples in ``initial``
    (pairs started in a known state, e.g. as gliders).
    """

    configs: str = "random"
    n: int = 5000
    r_range_W: tuple[float, float] = (0.5, 2.5)
    radius_W: float = 1.3
    positions: int = 1000
    orientations: int = 1
    amplitudes_deg: tuple[float, ...] = (90.0,)
    periods: int = 75
    chirality: str = "ccw"
    gait: str = "square"
    period_s: float | None = None
    backend: str = "native"
    seed: int = 0
    batch_size: int = 256
    chunk_periods: int = 5
    quiet_periods: int = 2
    model: str = presets.DEFAULT  # model preset (smarticle_mjx/presets.py)
    collisions: bool = False  # keep the per-period collision record (native and dart backends)
    collision_bins: int = 16  # its bins per gait period
    initial: tuple[tuple[float, float, float], ...] | None = None  # configs = "explicit"
    # backend "dart": (time step s, collision detector, LCP solver[, servo]); None: the DART twin's defaults
    dart_numerics: tuple | None = None
    # the robots' imperfections (smarticle_mjx/imperfections.py), drawn from ``robot_seed`` (None: ``seed``)
    imperfections: str = "none"
    # single fields of the preset changed (``--set``, a study file's [scene]): sorted (field, value)
    overrides: tuple[tuple[str, object], ...] = ()
    # pairs of robots drawn (K): lane i runs pair i mod K (robots 2k, 2k + 1 of the pool drawn from
    # ``robot_seed``), or pair ``lane_draws[i]`` where given (pairs started as another study's gliders,
    # on the robots that made them); meaningless for ideal robots, whose stores leave all three out
    robot_draws: int = 1
    robot_seed: int | None = None
    lane_draws: tuple[int, ...] | None = None

    def scene_params(self) -> SceneParams:
        """The preset's parameters with the overrides (ValueError naming the known presets if unknown,
        or for a bad override)."""
        return presets.apply(presets.params(self.model), self.overrides)

    def robot_pool(self) -> imperfections.Draw:
        """Every robot the scan runs: ``2 robot_draws`` robots drawn from the robot seed (ValueError for an
        unknown set). With one draw, the pair itself."""
        seed = self.seed if self.robot_seed is None else self.robot_seed
        return imperfections.draw(self.imperfections, 2 * self.robot_draws, seed)

    def robots(self, k: int = 0) -> imperfections.Draw:
        """Pair ``k`` of the pool (the pair of every lane when the scan draws one)."""
        return self.robot_pool().pair(k)

    def lane_draw(self, lanes) -> np.ndarray:
        """The robot pair (0 .. robot_draws - 1) each of ``lanes`` runs (0 for ideal robots: every pair is
        the same machine, so their lanes run together)."""
        lanes = np.asarray(lanes, dtype=np.int64)
        if self.imperfections == "none":
            return np.zeros_like(lanes)
        if self.lane_draws is not None:
            return np.asarray(self.lane_draws, dtype=np.int64)[lanes]
        return lanes % self.robot_draws

    def validate(self, params: SceneParams) -> None:
        imperfections.get(self.imperfections).check_backend(self.backend)
        if self.seed < 0:
            raise ValueError(f"--seed must be >= 0, got {self.seed}")
        if self.configs not in ("random", "polar", "explicit"):
            raise ValueError(f"--configs must be random, polar or explicit, got {self.configs!r}")
        if self.configs == "explicit":
            a = np.asarray(self.initial if self.initial is not None else [], float)
            if a.ndim != 2 or a.shape[1] != 3 or len(a) == 0:
                raise ValueError("explicit configurations must be a non-empty list of (|r|, theta, phi) triples")
            if not np.isfinite(a).all() or (a[:, 0] <= 0).any():
                raise ValueError("explicit configurations must be finite with |r| > 0")
        elif self.configs == "random":
            if self.n <= 0:
                raise ValueError(f"--n must be positive, got {self.n}")
            lo, hi = self.r_range_W
            if not 0 <= lo < hi:
                raise ValueError(f"|r| range must satisfy 0 <= min < max, got {self.r_range_W}")
        else:
            if self.positions <= 0 or self.orientations <= 0:
                raise ValueError("--positions and --orientations must be positive")
            if self.radius_W <= 0:
                raise ValueError(f"--radius must be positive, got {self.radius_W}")
        if self.periods <= 0:
            raise ValueError(f"--periods must be positive, got {self.periods}")
        if not self.amplitudes_deg:
            raise ValueError("no amplitudes given")
        if len(set(self.amplitudes_deg)) != len(self.amplitudes_deg):
            raise ValueError("amplitudes must be distinct")
        for a in self.amplitudes_deg:
            self.gait_spec(a).validate(params.robot.servo_speed, params.robot.arm_limit_deg)
        if self.robot_draws < 1:
            raise ValueError(f"robot draws must be >= 1, got {self.robot_draws}")
        if self.robot_seed is not None and self.robot_seed < 0:
            raise ValueError(f"robot seed must be >= 0, got {self.robot_seed}")
        if self.lane_draws is not None:
            d = np.asarray(self.lane_draws)
            if self.configs != "explicit" or len(d) != len(self.initial_configs()):
                raise ValueError("lane draws name one robot pair per explicit configuration")
            if len(d) and (d.min() < 0 or d.max() >= self.robot_draws):
                raise ValueError(f"lane draws must lie in 0 .. {self.robot_draws - 1}")
        self.engine().check(self.robots().scene(params), self.overrides, self.collisions)
        if self.batch_size <= 0 or self.chunk_periods <= 0 or self.quiet_periods < 0:
            raise ValueError("batch size and chunk periods must be positive, quiet periods >= 0")
        if self.collision_bins < 1:
            raise ValueError(f"--collision-bins must be positive, got {self.collision_bins}")

    def engine(self):
        """The study's engine (``engine.StudyEngine``): its backend with the settings only that backend reads."""
        from .engine import StudyEngine
        return StudyEngine(self.backend, self.dart_numerics)

    def backend_options(self) -> dict:
        """Keyword arguments of ``make_backend`` beyond the scene."""
        return self.engine().options()

    def gait_spec(self, amplitude_deg: float) -> GaitSpec:
        return GaitSpec(amplitude_deg=float(amplitude_deg), chirality=self.chirality, kind=self.gait,
                        period_s=self.period_s)

    def initial_configs(self) -> np.ndarray:
        """[M, 3] (|r| in W, theta, phi in rad); the same for every amplitude."""
        if self.configs == "random":
            return C.random_configs(self.n, np.random.default_rng(self.seed), self.r_range_W)
        if self.configs == "explicit":
            return np.asarray(self.initial, float).reshape(-1, 3)
        return C.polar_configs(self.radius_W, self.positions, self.orientations)

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        d["r_range_W"] = list(self.r_range_W)
        d["amplitudes_deg"] = [float(a) for a in self.amplitudes_deg]
        if self.initial is None:
            del d["initial"]  # stores of random and polar scans keep their earlier configuration
        else:
            d["initial"] = [[float(x) for x in c] for c in self.initial]
        if self.imperfections == "none":
            del d["imperfections"]  # nor do stores of ideal robots
        if self.imperfections == "none" or self.robot_draws == 1:
            del d["robot_draws"], d["lane_draws"]  # nor do stores of one pair of robots
        else:
            d["lane_draws"] = None if self.lane_draws is None else [int(x) for x in self.lane_draws]
        if self.imperfections == "none" or self.robot_seed is None or self.robot_seed == self.seed:
            del d["robot_seed"]
        _overrides_json(d, self.overrides)
        return self.engine().record(d)


def run_name(amplitude_deg: float) -> str:
    return f"a{amplitude_deg:06.2f}"


def with_overrides(cfg, overrides=()):
    """``cfg`` (a ScanConfig or RelaxConfig) with the scene ``overrides`` (checked pairs,
    ``presets.overrides``) added to its own; a field set in both takes the value given here (``--set`` on
    top of a study file's ``[scene]``)."""
    if not overrides:
        return cfg
    return dataclasses.replace(cfg, overrides=tuple(sorted({**dict(cfg.overrides), **dict(overrides)}.items())))


@dataclasses.dataclass(frozen=True)
class RelaxConfig:
    """Everything that defines a relaxation study's data; stored in full."""

    n_robots: int = 7
    trials: int = 20
    first_trial: int = 0  # trial indices first_trial .. first_trial+trials-1 (stages of one study)
    periods: int = 300  # the lab's trials ran 300 gait periods
    amplitude_deg: float = 90.0
    chirality: str = "ccw"
    gait: str = "square"
    period_s: float | None = None
    seed: int = 0
    gap_mm: float = 2.0  # gap between neighbouring robots' bounding boxes in the packing
    # the start's family: "lattice" (staggered rows of bounding boxes, the default) or "hex" (a
    # triangular lattice: for 7 robots one ringed by six); headings "aligned" (all 0, then jittered)
    # or "drawn" (uniform per robot and trial); start_phi: scale the pack to this area fraction
    # n W D / hull of the centres (None: spaced by gap_mm)
    start: str = "lattice"
    headings: str = "aligned"
    start_phi: float | None = None
    jitter_mm: float = 1.0  # per-axis standard deviation of each robot's start position
    jitter_deg: float = 2.0  # standard deviation of each robot's start heading
    phase_jitter: float = 0.0  # standard deviation of per-robot gait phase (periods); 0: in phase (paper)
    # every robot re-started each cycle with a delay drawn afresh per robot and cycle (s.d., periods), as
    # the lab firmware re-synchronised its robots on a trigger every cycle; 0: started once
    retrigger_sd: float = 0.0
    # lasting per-robot timing offsets that set in after the start (s.d., periods): every robot starts in
    # phase and from cycle onset_cycle on runs its gait late or early by its own delay, drawn once per robot
    # and trial; 0: none. Not with retrigger_sd
    onset_offset_sd: float = 0.0
    onset_cycle: int = 1
    plate_m: float = 0.6  # side of the square plate, centred on the packing
    backend: str = "native"
    batch_size: int = 4
    chunk_periods: int = 5
    quiet_periods: int = 10  # stop a trial after this many periods without any contact (0: never)
    model: str = presets.DEFAULT
    # backend "dart": (time step s, collision detector, LCP solver[, servo]); None: the DART twin's defaults
    dart_numerics: tuple | None = None
    # the robots' imperfections (smarticle_mjx/imperfections.py): the same robots in every
    # trial (drawn from ``seed``), their phase jitter drawn per trial
    imperfections: str = "none"
    # single fields of the preset changed (``--set``, a study file's [scene]): sorted (field, value)
    overrides: tuple[tuple[str, object], ...] = ()

    def robots(self) -> imperfections.Draw:
        return imperfections.draw(self.imperfections, self.n_robots, self.seed)

    def robot_pool(self) -> imperfections.Draw:
        """Every robot the study runs: the same ``n_robots`` in every trial."""
        return self.robots()

    def gait_spec(self) -> GaitSpec:
        return GaitSpec(amplitude_deg=self.amplitude_deg, chirality=self.chirality, kind=self.gait,
                        period_s=self.period_s)

    def start_words(self) -> str:
        """The start in words, for reports and pages: the pack, its spacing, the jitter and the robots'
        synchrony. A start offset comes from ``phase_jitter`` and from the imperfection set's ``phase_sd``
        (drawn independently, so their s.d. add in quadrature). A store's settings read back with
        ``relax_config_from_json``, so fields newer than the store take their defaults."""
        pack = {"lattice": "staggered lattice", "hex": "hexagonal pack"}[self.start]
        spacing = f"area fraction {self.start_phi:g}" if self.start_phi is not None else f"gap {self.gap_mm:g} mm"
        sd = math.hypot(self.phase_jitter, imperfections.get(self.imperfections).phase_sd)
        sync = f"gait start offsets of s.d. {sd:.3g} periods, drawn per robot and trial" if sd > 0 else "in phase"
        if self.retrigger_sd > 0:
            sync += f", every robot re-triggered each cycle with a delay of s.d. {self.retrigger_sd:g} periods"
        if self.onset_offset_sd > 0:
            sync += (f", lasting offsets of s.d. {self.onset_offset_sd:g} periods per robot setting in at cycle "
                     f"{self.onset_cycle}")
        return (f"compressed start ({pack}, headings {self.headings}, {spacing}, jitter {self.jitter_mm:g} mm / "
                f"{self.jitter_deg:g}°), {sync}")

    def scene_params(self) -> SceneParams:
        return presets.apply(presets.params(self.model), self.overrides)

    def validate(self, params: SceneParams) -> None:
        imperfections.get(self.imperfections).check_backend(self.backend)
        if self.seed < 0:
            raise ValueError(f"--seed must be >= 0, got {self.seed}")
        if self.n_robots < 2:
            raise ValueError(f"a relaxation needs at least 2 robots, got {self.n_robots}")
        if self.n_robots > 30:
            raise ValueError(f"at most 30 robots per trial, got {self.n_robots}")
        if self.trials < 1:
            raise ValueError(f"trials must be >= 1, got {self.trials}")
        if self.first_trial < 0:
            raise ValueError(f"first trial must be >= 0, got {self.first_trial}")
        if self.periods < 1:
            raise ValueError(f"periods must be >= 1, got {self.periods}")
        for name in ("gap_mm", "jitter_mm", "jitter_deg", "phase_jitter", "retrigger_sd", "onset_offset_sd"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name.replace('_', '-')} must be a finite number >= 0, got {v}")
        if self.onset_cycle < 1:
            raise ValueError(f"onset cycle must be >= 1 (robots start in phase), got {self.onset_cycle}")
        if self.onset_offset_sd > 0 and self.retrigger_sd > 0:
            raise ValueError("lasting offsets that set in (onset-offset-sd) and a per-cycle re-trigger (retrigger-sd) "
                             "exclude each other")
        from .capabilities import require
        if self.phase_jitter > 0:
            require(self.backend, "start_delays", "--phase-jitter: ")
        if self.retrigger_sd > 0 or self.onset_offset_sd > 0:
            require(self.backend, "retrigger", "--retrigger-sd / --onset-offset-sd: ")
        if not self.plate_m > 0:
            raise ValueError(f"plate side must be positive, got {self.plate_m}")
        if self.start not in ("lattice", "hex"):
            raise ValueError(f"--start must be lattice or hex, got {self.start!r}")
        if self.headings not in ("aligned", "drawn"):
            raise ValueError(f"--headings must be aligned or drawn, got {self.headings!r}")
        if self.start_phi is not None and not 0 < self.start_phi < 1:
            raise ValueError(f"--start-phi must lie between 0 and 1, got {self.start_phi}")
        if self.batch_size < 1 or self.chunk_periods < 1 or self.quiet_periods < 0:
            raise ValueError("batch size and chunk periods must be >= 1, quiet periods >= 0")
        self.engine().check(self.robots().scene(params), self.overrides)
        self.gait_spec().validate(params.robot.servo_speed, params.robot.arm_limit_deg)

    def engine(self):
        """The study's engine (``engine.StudyEngine``): its backend with the settings only that backend reads."""
        from .engine import StudyEngine
        return StudyEngine(self.backend, self.dart_numerics)

    def backend_options(self) -> dict:
        """Keyword arguments of ``make_backend`` beyond the scene."""
        return self.engine().options()

    def to_json(self) -> dict:
        d = dataclasses.asdict(self)
        if self.imperfections == "none":
            del d["imperfections"]  # stores of ideal robots keep their earlier configuration
        for k, default in (("start", "lattice"), ("headings", "aligned"), ("start_phi", None), ("retrigger_sd", 0.0),
                           ("onset_offset_sd", 0.0), ("onset_cycle", 1)):
            if d[k] == default:
                del d[k]  # as do stores of the start the study always had
        _overrides_json(d, self.overrides)
        return self.engine().record(d)


def _overrides_json(d: dict, overrides) -> None:
    """A spec's overrides as its stored JSON holds them: {field: value}, absent when none (so stores
    made before ``--set`` existed keep their configuration)."""
    if overrides:
        d["overrides"] = presets.overrides_json(overrides)
    else:
        del d["overrides"]


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
      converge_tol: 0 (the default): steady |r| is the mean over the last ``steady_window`` periods.
        Otherwise (W) each pair's steady |r| is read where it has converged: the first period at which its
        mean |r| over the last ``steady_window`` periods differs by less than this from the mean over the
        ``steady_window`` periods before, the pair bound in all of them (``reduce.gliders.
        converged_separation``); ``periods`` is then the most a stage runs.
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
    converge_tol: float = 0.0
    description: str = ""
    figure: str = ""

    def validate(self) -> None:
        if not (self.converge_tol >= 0 and math.isfinite(self.converge_tol)):
            raise ValueError(f"bound study: converge_tol must be >= 0 W, got {self.converge_tol}")
        if self.converge_tol > 0 and self.periods < 2 * self.steady_window:
            raise ValueError("bound study: with converge_tol, periods must be at least twice the steady window")
        if self.source not in STUDY_NAMES:
            raise ValueError(f"bound study: unknown source study {self.source!r} (known: {', '.join(STUDY_NAMES)})")
        if self.glider not in ("C1", "C2"):
            raise ValueError(f"bound study: glider must be C1 or C2, got {self.glider!r}")
        if self.pairs <= 0 or self.periods <= 0 or not self.amplitudes_deg:
            raise ValueError("bound study: pairs, periods and amplitudes must be positive / non-empty")
        if not 0 < self.steady_window <= self.periods or not 0 < self.keep_window <= self.periods:
            raise ValueError("bound study: steady and keep windows must lie within the periods run")

    def stage_config(self, amplitude: float, initial: np.ndarray, model: str,
                     imperfections: str = "none") -> ScanConfig:
        return ScanConfig(configs="explicit", initial=tuple(tuple(float(x) for x in c) for c in initial),
                          amplitudes_deg=(float(amplitude),), periods=self.periods, gait=self.gait,
                          chirality=self.chirality, seed=self.seed, model=model, imperfections=imperfections)


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

    def stage_config(self, stage: int, model: str, imperfections: str = "none"):
        return RelaxConfig(**{"imperfections": imperfections, **dict(self.settings)}, trials=self.trials,
                           first_trial=stage * self.trials, model=model)

    def validate(self) -> None:
        if self.stages < 1 or self.trials < 1:
            raise ValueError("relax study: stages and trials must be >= 1")
        cfg = self.stage_config(0, presets.DEFAULT)
        cfg.validate(cfg.scene_params())  # with the study's overrides (a slower servo, say) applied


def config_from_json(d: dict) -> ScanConfig:
    """The ScanConfig a store recorded (its ``config["scan"]``)."""
    return ScanConfig(**config_keywords(d))


def relax_config_from_json(d: dict) -> RelaxConfig:
    """The RelaxConfig a relaxation store recorded (its ``config["relax"]``), lists back to tuples."""
    return RelaxConfig(**config_keywords(d, RelaxConfig))


def config_keywords(d: dict, spec=ScanConfig) -> dict:
    """Keywords of ``spec`` (ScanConfig or RelaxConfig) from a study file's or a store's dict: its
    fields, lists back to tuples, stored overrides ({field: value}) back to checked pairs."""
    fields = {f.name for f in dataclasses.fields(spec)}
    kw = {k: v for k, v in d.items() if k in fields}
    for k in ("r_range_W", "amplitudes_deg"):
        if k in kw:
            kw[k] = tuple(float(x) for x in kw[k])
    if kw.get("initial") is not None:
        kw["initial"] = tuple(tuple(float(x) for x in c) for c in kw["initial"])
    if kw.get("lane_draws") is not None:
        kw["lane_draws"] = tuple(int(x) for x in kw["lane_draws"])
    if kw.get("dart_numerics") is not None:
        kw["dart_numerics"] = tuple(kw["dart_numerics"])
    if "overrides" in kw:
        kw["overrides"] = _as_overrides(kw["overrides"])
    return kw


def _as_overrides(value) -> tuple[tuple[str, object], ...]:
    """Overrides from a store's {field: value} or already checked (field, value) pairs (a study file's)."""
    return presets.table_overrides(value) if isinstance(value, dict) else presets.overrides(value)


