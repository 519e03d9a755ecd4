"""Glider emergence in a relaxation trial read four ways (paper, Fig. 1): the readings of the discovery's
recount, fixed with their tests (tests/test_emergence.py) before any trial was counted with them.

The paper's words: in 77 of 151 trials "a pair would move together ... for >= 100 gait periods, traveling an
average distance of 2.9 +- 0.2 W". Every reading starts from a pair's **touch run**: a maximal stretch of
consecutive periods in which the two robots touched at least once in every period (bound, the paper's
definition) and both were on the plate.

Readings (a trial *forms a glider* under a reading when one of its runs qualifies):

* ``apart`` (a): the bound-and-apart episode of :func:`smarticle_mjx.reduce.relaxation.trial_episodes`
  (no touch with a third robot and every third centre >= 2 W away, in every period), >= 100 periods. The
  rule before this recount; kept to compare.
* ``touch`` (b): a touch run of >= 100 periods, whatever third robots did (a pair inside a chain counts).
* ``moved`` (c): a ``touch`` run whose pair centre moved a net >= 0.5 W from the end of period
  ``SPREAD_PERIODS`` (30, the lab's spreading time, so being pushed while the crowd spreads does not count)
  to the run's end; 0.5 W is more than three times what a lone robot drifts in 100 periods
  (1.5e-3 W per cycle in the lab).
* ``pair`` (d), **the primary reading**: a ``moved`` run in which neither robot of the pair touched a third
  robot in at least 80 % of the run's periods: a pair, not a chain, with passing touches allowed.

The **glider's distance** under (b)-(d) is the pair centre's net displacement from the end of period 30
(or from the end of the period before the run, if it began later) to the run's end, of the trial's
longest qualifying run (the first of equal ones); under (a), the episode's net displacement, as before.

Positions: c[0] is the pair centre at the start, c[k] at the end of period k (1-based); a run over the
0-based periods s .. s + L - 1 goes from c[s] to c[s + L].
"""

from __future__ import annotations

import dataclasses
import enum

import numpy as np

from .. import configs as C
from ..records import RelaxRecord
from . import binding
from .relaxation import C1, C2, MeanSem, third_touch, trial_arrays, mean_sem, trial_episodes

GLIDER_PERIODS = 100  # the lab's criterion: together for >= 100 gait periods
SPREAD_PERIODS = 30  # the lab's spreading time (~30 periods to steady state): motion before it is not counted
MIN_NET_W = 0.5  # net displacement of a moving glider (W): > 3x a lone robot's 100-period drift (0.15 W)
PAIR_SHARE = 0.8  # share of a run's periods with no third-robot touch for it to be a pair, not a chain
KEEP_PERIODS = 10  # touch runs kept in a results file (the lab's chain lifetime, 8-10: shorter is a collision)
LAB_EMERGED, LAB_TRIALS = 77, 151  # the lab's count (paper, Fig. 1)


class Reading(str, enum.Enum):
    """The emergence readings (see the module's docstring); ``PAIR`` is the primary one."""

    APART = "apart"
    TOUCH = "touch"
    MOVED = "moved"
    PAIR = "pair"

    @property
    def label(self) -> str:
        return {"apart": "(a) bound and apart >= 100 periods",
                "touch": "(b) touching >= 100 consecutive periods",
                "moved": "(c) (b) and moved >= 0.5 W after period 30",
                "pair": "(d) (c) and a pair, not a chain (no third touch in >= 80 % of its periods)"}[self.value]


PRIMARY = Reading.PAIR


def parse_reading(text: str | None) -> Reading:
    """A reading by name (None: the primary one); ValueError naming the readings there are."""
    if text is None:
        return PRIMARY
    if isinstance(text, Reading):
        return text
    try:
        return Reading(str(text).strip().lower())
    except ValueError:
        raise ValueError(f"unknown reading {text!r}: choose one of " + ", ".join(r.value for r in Reading)
                         + f" (default {PRIMARY.value})") from None


def reading_from_analysis(a) -> "EmergenceReading":
    """Reading (a) as :func:`smarticle_mjx.reduce.relaxation.analyse_relaxation` counted it (a ``RelaxAnalysis``)."""
    gl = [r.glider for r in a.per_trial if r.glider is not None]
    return EmergenceReading(Reading.APART, a.valid, a.emerged, a.fraction, tuple(a.interval),
                            fisher_p(a.emerged, a.valid) if a.valid else float("nan"), a.distance,
                            sum(1 for g in gl if g.distance_W >= MIN_NET_W),
                            {C1: a.glider_kinds.c1, C2: a.glider_kinds.c2}, tuple(r.trial for r in a.per_trial
                                                                             if r.glider is not None))


@dataclasses.dataclass(frozen=True)
class TouchRun:
    """One touch run of one pair (see the module's docstring).

    Attributes:
      trial: the store's trial number (-1 where the caller did not say).
      pair: the robots (i, j), i < j.
      start: first period (0-based); ``length``: periods.
      censored: the run reached the last period of a trial that ran to its end.
      third_periods: periods of the run in which a robot of the pair touched a third robot (any third robot,
        on the plate or past its edge, as the bound-and-apart rule counts it).
      apart_periods: periods of the run that were bound and apart (reading (a)'s per-period rule).
      net_W: |c[s + L] - c[s]|, the pair centre's net displacement over the whole run (W).
      net_late_W: |c[s + L] - c[max(s, SPREAD_PERIODS)]|, the same from the end of period 30 (W); 0 for a
        run that ended by then.
      contour_W: the pair centre's path length over the run (W).
      mean_cos_phi, kind: mean cos(phi) over the run's periods and the type it names (C1 if < 0, else C2).
    """

    trial: int
    pair: tuple[int, int]
    start: int
    length: int
    censored: bool
    third_periods: int
    apart_periods: int
    net_W: float
    net_late_W: float
    contour_W: float
    mean_cos_phi: float
    kind: str

    @property
    def pair_share(self) -> float:
        """Share of the run's periods with no third-robot touch."""
        return 1.0 - self.third_periods / self.length

    def qualifies(self, reading: Reading, periods: int = GLIDER_PERIODS) -> bool:
        """Whether this run is a glider under ``reading`` (``TOUCH``, ``MOVED`` or ``PAIR``; ``APART`` reads
        episodes, not runs)."""
        reading = Reading(reading)
        if reading is Reading.APART:
            raise ValueError("reading (a) counts bound-and-apart episodes, not touch runs")
        if self.length < periods:
            return False
        if reading is Reading.TOUCH:
            return True
        if self.net_late_W < MIN_NET_W:
            return False
        return reading is Reading.MOVED or self.pair_share >= PAIR_SHARE

    def as_json(self) -> dict:
        d = dataclasses.asdict(self)
        d["pair"] = list(self.pair)
        return d


def touch_runs(poses, touched, start, body_length: float, left_plate=None, periods_run=None, trial: int = -1,
               min_periods: int = 1, apart_W: float = 2.0, episodes=None) -> tuple[TouchRun, ...]:
    """Every touch run of at least ``min_periods`` of one trial, in order of start and pair.

    Args:
      poses: [K, N, 5] poses at the end of each period (m, rad; NaN after an early stop).
      touched: [K, P] bool, pairs i < j in :func:`smarticle_mjx.reduce.relaxation.pairs_of` order.
      start: [N, 5] start poses.
      body_length: W (m).
      left_plate: [N] first period ending with the robot off the plate (1-based; 0: never).
      periods_run: periods simulated (default K).
      trial: the trial's number, recorded in each run.
      min_periods: shortest run returned.
      apart_W: the bound-and-apart rule's distance, for ``apart_periods``.
      episodes: the trial's bound-and-apart episodes (``relaxation.trial_episodes`` with this ``apart_W``),
        where the caller has them; found here otherwise.
    """
    poses, touched, run, pairs, on = trial_arrays(poses, touched, left_plate, periods_run)
    k, n = poses.shape[:2]
    xy = np.concatenate([np.asarray(start, float)[None, :, :2], poses[..., :2]]) / body_length  # [K + 1, N, 2]
    third = third_touch(touched, pairs)
    apart_mask = {}
    if episodes is None:
        episodes = trial_episodes(poses, touched, start, left_plate, periods_run, body_length, apart_W)
    for e in episodes:
        apart_mask.setdefault(e.pair, np.zeros(k, bool))[e.start:e.start + e.lifetime] = True
    out = []
    for p, (i, j) in enumerate(pairs):
        ok = touched[:, p] & on[:, i] & on[:, j]
        if not ok.any():
            continue
        c = (xy[:, i] + xy[:, j]) / 2
        r = binding.bound_runs(ok[None])
        for s, length, cens in zip(r.start, r.length, r.censored):
            s, length = int(s), int(length)
            if length < min_periods:
                continue
            e = s + length
            late = max(s, SPREAD_PERIODS)
            _, _, phi = C.relative_coordinates(poses[s:e, i], poses[s:e, j], body_length)
            mc = float(np.mean(np.cos(phi)))
            am = apart_mask.get((int(i), int(j)))
            out.append(TouchRun(
                int(trial), (int(i), int(j)), s, length, bool(cens and run >= k), int(third[s:e, p].sum()),
                int(am[s:e].sum()) if am is not None else 0, float(np.linalg.norm(c[e] - c[s])),
                float(np.linalg.norm(c[e] - c[late])) if e > late else 0.0,
                float(np.linalg.norm(np.diff(c[s:e + 1], axis=0), axis=1).sum()), mc, C1 if mc < 0 else C2))
    out.sort(key=lambda q: (q.start, q.pair))
    return tuple(out)


def glider_of(runs, reading: Reading, periods: int = GLIDER_PERIODS) -> TouchRun | None:
    """The trial's glider under ``reading``: its longest qualifying run (the first of equal ones), or None."""
    best = None
    for q in runs:
        if q.qualifies(reading, periods) and (best is None or q.length > best.length):
            best = q
    return best


@dataclasses.dataclass(frozen=True)
class EmergenceReading:
    """One reading over a study's usable trials.

    Attributes:
      reading: which reading.
      trials: usable trials; ``emerged``: trials that formed a glider under it.
      fraction, interval: emerged / trials and its exact (Clopper-Pearson) 95 % interval.
      fisher_p: two-sided Fisher's exact test of emerged / trials against the lab's 77 / 151.
      distance: the glider's distance (W) over the trials that formed one (see the module's docstring).
      moved: those of them whose distance is >= MIN_NET_W.
      kinds: C1 and C2 gliders.
      trial_gliders: trial numbers that formed one.
    """

    reading: Reading
    trials: int
    emerged: int
    fraction: float
    interval: tuple[float, float]
    fisher_p: float
    distance: MeanSem
    moved: int
    kinds: dict
    trial_gliders: tuple[int, ...]

    def as_json(self) -> dict:
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["reading"] = self.reading.value
        d["label"] = self.reading.label
        d["distance"] = dataclasses.asdict(self.distance)
        d["interval"] = list(self.interval)
        d["trial_gliders"] = list(self.trial_gliders)
        return d


def fisher_p(k: int, n: int, k_ref: int = LAB_EMERGED, n_ref: int = LAB_TRIALS) -> float:
    """Two-sided Fisher's exact p of k / n against k_ref / n_ref."""
    from scipy.stats import fisher_exact
    return float(fisher_exact([[k, n - k], [k_ref, n_ref - k_ref]]).pvalue)


def reading_of(reading: Reading, gliders: dict[int, float | None], kinds: dict[int, str | None],
               level: float = 0.95) -> EmergenceReading:
    """An :class:`EmergenceReading` from each usable trial's glider distance (None: no glider) and kind."""
    n = len(gliders)
    hit = [t for t, d in gliders.items() if d is not None]
    k = len(hit)
    lo, hi = binding.binomial_interval(k, n, level) if n else (np.nan, np.nan)
    dist = np.array([gliders[t] for t in hit], float)
    return EmergenceReading(Reading(reading), n, k, k / n if n else float("nan"), (float(lo), float(hi)),
                            fisher_p(k, n) if n else float("nan"), mean_sem(dist), int((dist >= MIN_NET_W).sum()),
                            {C1: sum(kinds[t] == C1 for t in hit), C2: sum(kinds[t] == C2 for t in hit)},
                            tuple(int(t) for t in hit))


@dataclasses.dataclass(frozen=True)
class Emergence:
    """Every reading of a relaxation study and the touch runs they were counted from.

    Attributes:
      readings: one :class:`EmergenceReading` per :class:`Reading`, in the enum's order.
      primary: the page's reading.
      runs: per usable trial, its touch runs of at least ``keep_periods`` (what a results file keeps: any
        reading with thresholds >= ``keep_periods`` recomputes from them without simulating again).
      apart: per usable trial, its reading-(a) glider as (distance W, kind), or None.
      keep_periods: the shortest run kept.
    """

    readings: tuple[EmergenceReading, ...]
    primary: Reading
    runs: dict[int, tuple[TouchRun, ...]]
    apart: dict[int, tuple[float, str] | None]
    keep_periods: int

    def of(self, reading: Reading | str) -> EmergenceReading:
        reading = Reading(reading)
        return next(r for r in self.readings if r.reading is reading)

    def as_json(self, with_runs: bool = True) -> dict:
        d = {"primary": self.primary.value, "readings": {r.reading.value: r.as_json() for r in self.readings},
             "keep_periods": self.keep_periods,
             "rules": {"glider_periods": GLIDER_PERIODS, "spread_periods": SPREAD_PERIODS, "min_net_W": MIN_NET_W,
                       "pair_share": PAIR_SHARE, "lab": [LAB_EMERGED, LAB_TRIALS]}}
        if with_runs:
            d["runs"] = [{"trial": t, "apart": None if self.apart[t] is None else list(self.apart[t]),
                          "runs": [q.as_json() for q in runs]} for t, runs in self.runs.items()]
        return d

    @classmethod
    def from_json(cls, d: dict, periods: int = GLIDER_PERIODS) -> "Emergence":
        """The readings recomputed from a results file's ``runs`` (what :meth:`as_json` wrote); ``periods``
        applies to readings (b)-(d), reading (a) keeps the glider stored with each trial."""
        runs = {int(r["trial"]): tuple(TouchRun(**{**q, "pair": tuple(q["pair"])}) for q in r["runs"])
                for r in d["runs"]}
        apart = {int(r["trial"]): None if r["apart"] is None else (float(r["apart"][0]), str(r["apart"][1]))
                 for r in d["runs"]}
        return emergence_from_runs(runs, apart, int(d["keep_periods"]), periods)


def emergence_from_runs(runs: dict[int, tuple[TouchRun, ...]], apart: dict[int, tuple[float, str] | None],
                        keep_periods: int = KEEP_PERIODS, periods: int = GLIDER_PERIODS) -> Emergence:
    """The four readings from each usable trial's touch runs and its reading-(a) glider (distance, kind; or
    None). Trials are the keys of ``runs``; ``apart`` must have the same keys."""
    if set(runs) != set(apart):
        raise ValueError("runs and apart must name the same trials")
    readings = [reading_of(Reading.APART, {t: None if a is None else a[0] for t, a in apart.items()},
                           {t: None if a is None else a[1] for t, a in apart.items()})]
    for rd in (Reading.TOUCH, Reading.MOVED, Reading.PAIR):
        g = {t: glider_of(rs, rd, periods) for t, rs in runs.items()}
        readings.append(reading_of(rd, {t: None if q is None else q.net_late_W for t, q in g.items()},
                                   {t: None if q is None else q.kind for t, q in g.items()}))
    return Emergence(tuple(readings), PRIMARY, dict(runs), dict(apart), keep_periods)


def emergence(data: RelaxRecord, keep_periods: int = KEEP_PERIODS, periods: int = GLIDER_PERIODS,
              apart_W: float = 2.0) -> Emergence:
    """Every reading of :func:`smarticle_mjx.store.read_relax` output over its usable trials (the trials
    :func:`smarticle_mjx.reduce.relaxation.analyse_relaxation` counts)."""
    if keep_periods < 1 or periods < keep_periods:
        raise ValueError("keep_periods must be >= 1 and no longer than the glider's periods")
    W = float(data.body_length)
    runs, apart = {}, {}
    for t in np.flatnonzero(data.usable):
        tr = int(data.trial[t])
        episodes = trial_episodes(data.poses[t], data.touched[t], data.start_poses[t], data.left_plate[t],
                                  data.periods_run[t], W, apart_W, trial=tr)
        runs[tr] = touch_runs(data.poses[t], data.touched[t], data.start_poses[t], W, data.left_plate[t],
                              data.periods_run[t], tr, keep_periods, apart_W, episodes)
        eps = [e for e in episodes if e.lifetime >= periods]
        best = max(eps, key=lambda e: e.lifetime) if eps else None
        apart[tr] = None if best is None else (best.distance_W, best.kind)
    return emergence_from_runs(runs, apart, keep_periods, periods)
