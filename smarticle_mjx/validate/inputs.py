"""What the claims measure: the typed, unrounded evidence each builder of :mod:`.evidence` makes from the
stores and each claim of :mod:`.claims` takes (built by hand in the claims' tests). Rounding happens only
where the page prints them; ``as_json`` is what ``validation.json`` records beside the page.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..reduce.chains import ChainLifetimes
from ..reduce.emergence import PRIMARY, Emergence, EmergenceReading, Reading, reading_from_analysis
from ..reduce.relaxation import CrowdSummary, RelaxAnalysis
from ..reduce.spreading import SpreadingTimes
from ..reduce.transport import Exponent, LoneRobot
from ..specs import RelaxConfig


@dataclasses.dataclass(frozen=True)
class LoneTracks:
    """A lone robot's per-period track at one amplitude: positions ``xy`` (W) and ``heading`` (rad),
    [T+1, 2] and [T+1] for one robot, [R, T+1, 2] and [R, T+1] for R robots drawn with imperfections;
    its gait period ``period_s`` (s)."""

    xy: np.ndarray
    heading: np.ndarray
    period_s: float


@dataclasses.dataclass(frozen=True)
class LoneDrift:
    """A lone robot at one amplitude (``reduce.transport.lone_robot``; with drawn imperfections each
    quantity's mean over ``robots`` robots, each alone) and the cycles it ran."""

    robot: LoneRobot
    robots: int = 1
    cycles: int = 0

    def as_json(self) -> dict:
        """What validation.json records per amplitude (the robots counted when several)."""
        return {**self.robot.as_json(), **({"robots": self.robots} if self.robots > 1 else {})}


@dataclasses.dataclass(frozen=True)
class Polar:
    """The polar scan at one |r|: the circular mean θ of its attracted starts (deg), the correlation of
    the attracted fraction per 10° bin of θ with that of the bin mirrored about 270°, the counts, the
    bins' fraction range (lo, hi) and the scan's layout."""

    axis_deg: float
    mirror_correlation: float
    attracted: int
    valid: int
    periods: int
    positions: int
    orientations: int
    radius_W: float
    fraction_range: tuple[float, float]

    def as_json(self) -> dict:
        """What validation.json records of it."""
        return {k: getattr(self, k) for k in ("axis_deg", "mirror_correlation", "attracted", "valid", "periods")}


@dataclasses.dataclass(frozen=True)
class Turn:
    """A mean signed body-heading turn per glider (deg per period) with its 95 % bootstrap interval and the
    gliders it is over."""

    mean: float
    lo: float
    hi: float
    n: int


@dataclasses.dataclass(frozen=True)
class Mirror:
    """Both chiralities at 90°: each one's mean turn per glider, C1's mean θ counter-clockwise and the
    clockwise one mirrored (180° − θ), and the clockwise study's size (valid starts, periods, the glider
    rule's minimum run)."""

    ccw: Turn
    cw: Turn
    c1_theta_ccw: float
    c1_theta_cw_mirrored: float
    cw_valid: int
    cw_periods: int
    cw_glider_min_periods: int
    # drawn robots: the pairs each study ran (0: ideal robots) and whether both ran the same ones
    robot_pairs: int = 0
    same_robots: bool = True

    def as_json(self) -> dict:
        return {"ccw": tuple(dataclasses.astuple(self.ccw)), "cw": tuple(dataclasses.astuple(self.cw)),
                "c1_theta_ccw": self.c1_theta_ccw, "c1_theta_cw_mirrored": self.c1_theta_cw_mirrored,
                "cw_summary": {"valid": self.cw_valid, "periods": self.cw_periods,
                               "options": {"glider_min_periods": self.cw_glider_min_periods}},
                **({"robots": {"pairs": self.robot_pairs, "same": self.same_robots}} if self.robot_pairs else {})}


@dataclasses.dataclass(frozen=True)
class SteadyR:
    """Steady |r| (W) of the started-bound pairs at one amplitude: the mean over the last ``window``
    periods of pairs bound in all of them (or, with a convergence tolerance, over the pairs that converged,
    each read where it did), its 95 % bootstrap interval over pairs, those pairs and the pairs started; with
    a tolerance, the pairs bound long enough to be tried that never converged."""

    amplitude_deg: float
    r_W: float
    lo: float
    hi: float
    pairs: int
    started: int
    unconverged: int = 0


@dataclasses.dataclass(frozen=True)
class Descent:
    """Steady |r| per amplitude (increasing amplitude), the window averaged, the periods of each stage (the
    most, with a convergence tolerance), whether each stage started where the previous one ended, and the
    convergence tolerance (W; 0: the last window read)."""

    sep: tuple[SteadyR, ...]
    window: int
    periods: int
    continuation: bool
    tolerance: float = 0.0

    @property
    def largest_drop(self) -> tuple[float, float] | None:
        """The neighbouring amplitudes (lower, higher) between which steady |r| falls most from one amplitude to
        the next higher one (the descent claim's reading, the figure's shading); None without two values."""
        r = np.array([s.r_W for s in self.sep], float)
        drops = r[:-1] - r[1:]
        if not np.isfinite(drops).any():
            return None
        i = int(np.nanargmax(drops))
        return self.sep[i].amplitude_deg, self.sep[i + 1].amplitude_deg


@dataclasses.dataclass(frozen=True)
class Pooled:
    """P_b at the end pooled over one group of amplitudes: the fraction, its exact 95 % interval, the starts."""

    value: float
    lo: float
    hi: float
    n: int


# the pb_dip claim's amplitude bands: (label, lowest, highest amplitude in deg)
PB_BANDS = (("10–30°", 0.0, 30.0), ("40–60°", 40.0, 60.0), ("70–90°", 70.0, 180.0))


@dataclasses.dataclass(frozen=True)
class PbBands:
    """P_b at the end pooled over each of :data:`PB_BANDS`: the low, intermediate and high amplitudes."""

    low: Pooled
    mid: Pooled
    high: Pooled

    def items(self):
        """(label, Pooled) in the bands' order, for a page."""
        return zip((label for label, _, _ in PB_BANDS), (self.low, self.mid, self.high))


@dataclasses.dataclass(frozen=True)
class BindingVsAmplitude:
    """P_b at the end per amplitude ([A, 3]: value, exact 95 % interval), valid starts per amplitude, the
    claim's groups pooled, the periods run; ``runs``: each amplitude's ``RunAnalysis`` (for figures)."""

    amplitudes_deg: np.ndarray
    pb_end: np.ndarray
    valid: np.ndarray
    pooled: PbBands
    periods: int
    runs: tuple = ()

    def pooled_json(self) -> dict:
        return {g: tuple(dataclasses.astuple(p)) for g, p in self.pooled.items()}


@dataclasses.dataclass(frozen=True)
class Diagonal:
    """Gliders under the time-symmetric gait: β of the pooled glider tracks (None without any), the delays
    fitted, one line per source of bound pairs, and each source's ``RunAnalysis`` (for figures)."""

    beta: Exponent | None
    lags: tuple | None
    parts: tuple[str, ...]
    runs: dict = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class Relaxation:
    """The relaxation study pooled over its complete stages: its numbers (``reduce.relaxation.analyse_relaxation``),
    its crowd's (None when not measured), the settings the stores ran, the lab's emergence fraction with
    its exact interval, Fisher's exact p of the model's emergence against the lab's, and the stages."""

    analysis: RelaxAnalysis
    crowd: CrowdSummary | None
    settings: RelaxConfig
    lab_fraction: float
    lab_interval: tuple[float, float]
    p_fisher: float
    stages: int
    emergence: Emergence | None = None  # every reading (reduce.emergence); None: reading (a) alone
    chains: ChainLifetimes | None = None  # chains by overlap and by exact member set (reduce.chains)
    reading: Reading = PRIMARY  # the reading the emergence and distance claims judge
    spreading: SpreadingTimes | None = None  # the crowd's fitted time constants (reduce.spreading)

    @property
    def judged(self) -> EmergenceReading:
        """The reading the claims judge (reading (a), from ``analysis``, where the others were not counted)."""
        if self.emergence is None:
            return reading_from_analysis(self.analysis)
        return self.emergence.of(self.reading)

    @property
    def rule_a(self) -> EmergenceReading:
        """Reading (a), the bound-and-apart rule the page judged by until December 2026."""
        return reading_from_analysis(self.analysis)
