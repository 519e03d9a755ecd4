"""The paper's claims as a registry: each one its text, the paper's value, its test and a function
that measures it from evidence (plain numbers and arrays; :mod:`.evidence` reads them from stores).

A claim's function returns an :class:`Outcome` (holds: True, False or None for not measurable;
the measured text; the note on how it was measured). :meth:`Claim.row` turns it into a row of the
page. Nothing here reads a store or simulates, so each test can be checked on built data
(tests/test_claims.py: every claim where it holds and where it does not).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, Callable

import numpy as np

from .. import formatting
from ..reduce import binding, gliders as GL
from ..reduce.relaxation import CrowdSummary
from .inputs import PB_BANDS, BindingVsAmplitude, Descent, Diagonal, LoneDrift, Mirror, Polar, Relaxation

VERDICTS = {True: "holds", False: "does not hold", None: "not measurable"}

LONE_DRIFT_W = 0.0015  # the lab's lone robot at 90 deg, W per cycle (text)
LONE_DRIFT_FACTOR = 3.0
TYPE_SHARE = 0.05  # each glider type holds more than this share of the steady bound samples
BETA_PAPER, BETA_TOLERANCE = 1.8, 0.3  # gliders at 90 deg: |beta - 1.8| < 0.3
DIAGONAL_BETA, DIAGONAL_MIN_GLIDERS = 1.0, 5
POLAR_AXIS_DEG, POLAR_AXIS_TOL, POLAR_MIRROR_CORR = 270.0, 20.0, 0.7
MIRROR_THETA_TOL = 15.0
RELAX_MAX_WIDTH = 0.3  # the emergence fraction is judged once its 95 % interval is at most this wide
LAB_DISTANCE_W, LAB_DISTANCE_ERR = 2.9, 0.2
CONTOUR_R = 0.5
ALPHA = 0.05


def f(x, spec=".2f") -> str:
    """A number for the table; a dash for missing or NaN (``formatting.num``)."""
    return formatting.num(x, spec)


def finite(x) -> bool:
    return x is not None and bool(np.isfinite(x))


def ci(v, lo, hi, spec=".2f") -> str:
    return formatting.ci(v, lo, hi, spec)


@dataclasses.dataclass(frozen=True)
class Outcome:
    """What a claim's function found: ``holds`` (None: not measurable), the measured text, the note;
    ``test``, when given, replaces the claim's test on the page (a dash where nothing could be tested)."""

    holds: bool | None
    measured: str
    note: str = ""
    test: str | None = None


@dataclasses.dataclass(frozen=True)
class Claim:
    """One claim of the paper: ``text``, the ``paper``'s value, the ``test`` (stated before any number),
    the ``studies`` whose stores it needs (the first missing one is named when it cannot be measured) and
    ``measure`` (evidence -> :class:`Outcome`), and ``evidence``: the name of the builder in
    :mod:`.evidence` that reads that evidence from the stores (``evidence.BUILDERS``)."""

    key: str
    text: str
    paper: str
    test: str
    studies: tuple[str, ...]
    measure: Callable[[Any], Outcome]
    evidence: str = ""

    def outcome(self, evidence) -> Outcome:
        return self.measure(evidence)

    def row(self, evidence, stores=(), suite: str = "small") -> "ClaimRow":
        """The page's row; ``evidence`` None: a study is missing (``stores``: the studies there are; ``suite``:
        the suite the page is of, named in the command that runs the missing study)."""
        if evidence is None:
            study = next((s for s in self.studies if s not in stores), self.studies[0])
            run = "smx validate" if suite == "small" else f"smx validate --suite {suite}"
            return ClaimRow(self.text, self.paper, f"study {study} not run yet", "–", VERDICTS[None],
                            f"Run `{run} --studies {study}` (the page is written from the complete stores "
                            "there are).", run=False)
        o = self.measure(evidence)
        return ClaimRow(self.text, self.paper, o.measured, self.test if o.test is None else o.test, VERDICTS[o.holds],
                        o.note)


@dataclasses.dataclass(frozen=True)
class ClaimRow:
    """One claim's row as the page prints it: the claim, the paper's value, what was measured, the test, the
    verdict (one of :data:`VERDICTS`' words) and the note; ``run`` False where a study it needs has not run
    (rows of pages written before the field existed read back as run)."""

    claim: str
    paper: str
    measured: str
    test: str
    verdict: str
    note: str
    run: bool = True

    @property
    def holds(self) -> bool | None:
        return {w: h for h, w in VERDICTS.items()}[self.verdict]

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class Validation:
    """The claims' rows in the page's order, the numbers behind them (``extra``: their JSON form, which
    ``validation.json`` stores) and the figures drawn."""

    rows: tuple[ClaimRow, ...]
    extra: dict
    figures: tuple[str, ...] = ()

    @property
    def held(self) -> int:
        """How many claims hold."""
        return sum(r.holds is True for r in self.rows)

    @property
    def not_run(self) -> int:
        """How many claims could not be measured because a study they need has not run."""
        return sum(not r.run for r in self.rows)

    def count_words(self, held: int | None = None) -> str:
        """"**k of n claims hold**", or on a page written from a subset of the studies "**k of the m claims
        measured hold** (n − m not measured: their studies have not run)"; ``held`` replaces the count of
        claims that hold (the reference step's verdicts)."""
        held = self.held if held is None else held
        n, missing = len(self.rows), self.not_run
        if not missing:
            return f"**{held} of {n} claims hold**"
        return (f"**{held} of the {n - missing} claims measured hold** ({missing} of {n} not measured: their "
                "studies have not run)")

    def as_json(self, model: str) -> dict:
        """``validation.json``'s form."""
        return {"model": model, "rows": [r.as_dict() for r in self.rows], "extra": self.extra}

    @staticmethod
    def from_json(d: dict) -> "Validation":
        """Back from ``validation.json`` (figures are not stored there)."""
        return Validation(tuple(ClaimRow(**r) for r in d["rows"]), d["extra"])


CLAIMS: list[Claim] = []


def claim(key: str, text: str, paper: str, test: str, studies: tuple[str, ...],
          needs: Callable[[Any], Outcome | None] | None = None, *, evidence: str):
    """Register the decorated function as the measure of a claim (the page lists them in this order).
    ``needs``: a precondition checked first; the Outcome it returns (not measurable) stands for the claim's.
    ``evidence``: the builder in :mod:`.evidence` whose result the measure takes."""
    def deco(fn):
        measure = fn if needs is None else functools.wraps(fn)(lambda ev: needs(ev) or fn(ev))
        CLAIMS.append(Claim(key, text, paper, test, studies, measure, evidence))
        return measure
    return deco


def get(key: str) -> Claim:
    return next(c for c in CLAIMS if c.key == key)


# ----------------------------------------------------------------- lone robot

@claim("lone_drift", "a lone robot drifts about 0.0015 W per cycle at 90°", "0.0015 W/cycle (text)",
       "net drift within a factor 3 of 0.0015 W/cycle", (), evidence="lone_robots")
def lone_drift(ev: LoneDrift) -> Outcome:
    """``ev``: the lone robot at 90 deg (:class:`.inputs.LoneDrift`: net drift and mean step per cycle in W,
    the robots it is the mean of, the cycles run)."""
    n90 = ev.robot.net_W_per_cycle
    lo, hi = LONE_DRIFT_W / LONE_DRIFT_FACTOR, LONE_DRIFT_W * LONE_DRIFT_FACTOR
    robots = ev.robots
    what = (f"net {f(n90, '.2g')} W/cycle (mean step {f(ev.robot.step_W_per_cycle, '.2g')}; {ev.cycles} cycles"
            + (f"; mean of {robots} robots)" if robots > 1 else ")"))
    why = ("The lab robot's motor noise, backlash and marker jitter are not modelled; on a μ = 0.37 plate friction "
           "holds the model's body through most of the gait. Not tuned." if robots == 1 else
           f"Each of {robots} robots drawn with the study's imperfections runs alone; their mean. Not tuned.")
    return Outcome(bool(lo <= n90 <= hi), what,
                   "Net drift = \\|end − start\\| / cycles of the once-per-cycle body centre (a robot that jiggles "
                   "in place has a mean step but no drift). Converged in dt (docs/timestep.md). " + why)


# ----------------------------------------------------- the random study at 90 deg
# evidence: the study's reduce.analysis.RunAnalysis (typed, unrounded; rounded only where printed here)

def _untyped(a90) -> Outcome | None:
    """Not measurable (nothing tested) when the study has too few steady samples of both glider types."""
    if a90.types is not None:
        return None
    return Outcome(None, f"too few steady bound samples of both types to cluster ({a90.steady_samples})", "", "–")


@claim("both_types", "both C1 (φ ≈ 180°) and C2 (φ ≈ 0°) gliders form", "Fig. 2C–D, 4D",
       "each type holds > 5 % of the steady bound samples (k-means, named by φ)", ("random_90",), needs=_untyped,
       evidence="random_90")
def both_types(a90) -> Outcome:
    ty, tot, o = a90.types, a90.steady_samples, a90.options
    c1, c2 = ty.c1.steady_samples, ty.c2.steady_samples
    both = c1 > TYPE_SHARE * tot and c2 > TYPE_SHARE * tot
    cl = ty.clusters
    return Outcome(bool(both),
                   f"C1 {c1}, C2 {c2} of {tot} steady bound samples; clusters: "
                   + "; ".join(f"{GL.NAMES[int(kd)]} \\|r\\| {f(c[0], '.2f')} W, "
                               f"θ {f(np.degrees(c[1]) % 360, '.0f')}°, "
                               f"φ {f(np.degrees(c[2]) % 360, '.0f')}° ({int(n)})"
                               for c, kd, n in zip(cl.centers, cl.kind, cl.sizes)),
                   f"k-means ({o.clusters} clusters) on per-period (\\|r\\|, θ, φ) of bound pairs "
                   f"after period {o.burn_in}, each cluster named by its mean φ (C1 within 90° of "
                   f"180°). {a90.valid} valid random starts, {a90.periods} periods.")


@claim("c1_basin", "C1's basin is larger than C2's", "Fig. 4C–D (text)",
       "95 % intervals of the two basin fractions do not overlap, C1 above", ("random_90",), needs=_untyped,
       evidence="random_90")
def c1_basin(a90) -> Outcome:
    c1, c2, n = a90.types.c1, a90.types.c2, a90.valid
    lo1, hi1 = binding.binomial_interval(c1.basin_configs, n)
    lo2, hi2 = binding.binomial_interval(c2.basin_configs, n)
    return Outcome(bool(lo1 > hi2),
                   f"C1 {ci(c1.basin_fraction, lo1, hi1, '.3f')}, C2 {ci(c2.basin_fraction, lo2, hi2, '.3f')} "
                   f"of {n} valid starts",
                   "Basin = valid starts that end as that glider (bound in each of the last 10 periods, majority "
                   "type); exact binomial intervals.")


@claim("c1_lifetime", "C1 lives longer than C2", "Fig. 6B",
       "mean C1 lifetime > mean C2 lifetime, and C1 longer by a one-sided Mann–Whitney test at p < 0.05 "
       "(stricter than before)", ("random_90",), needs=_untyped,
       evidence="random_90")
def c1_lifetime(a90) -> Outcome:
    c1, c2, typed = a90.types.c1, a90.types.c2, a90.types.typed
    l1, l2 = typed.length[typed.kind == GL.C1], typed.length[typed.kind == GL.C2]
    from scipy.stats import mannwhitneyu
    p = float(mannwhitneyu(l1, l2, alternative="greater").pvalue) if len(l1) and len(l2) else np.nan
    m1 = c1.lifetime_mean if finite(c1.lifetime_mean) else 0.0
    m2 = c2.lifetime_mean if finite(c2.lifetime_mean) else 0.0
    ok = bool(m1 > m2 and p < ALPHA) if np.isfinite(p) else None
    return Outcome(ok,
                   f"mean bound-run length C1 {f(c1.lifetime_mean, '.1f')} ({len(l1)} runs), "
                   f"C2 {f(c2.lifetime_mean, '.1f')} ({len(l2)} runs) periods; one-sided Mann–Whitney p = "
                   f"{f(p, '.2g')} (still bound at the end: C1 {f(c1.censored_fraction, '.0%')}, "
                   f"C2 {f(c2.censored_fraction, '.0%')}; {a90.periods}-period trials)",
                   "Lifetime = length of a bound run typed by its majority; runs still bound at the end are cut "
                   "there (censored), which shortens the longer-lived type, so the test is conservative.")


def beta_holds(beta) -> bool | None:
    """The beta row's test (None: no beta measured)."""
    return bool(abs(beta - BETA_PAPER) < BETA_TOLERANCE) if finite(beta) else None


@claim("beta", "gliders at 90° move nearly ballistically (β ≈ 1.8)", "Fig. 3A, 3C",
       f"|β − {BETA_PAPER:g}| < {BETA_TOLERANCE:g}", ("random_90",), evidence="random_90")
def beta(a90) -> Outcome:
    tr, o = a90.transport, a90.options
    measured = "no gliders"
    if tr is not None:
        b, v, ht = tr.beta, tr.net_speed, tr.signed_heading_turn
        measured = (f"β = {ci(b.beta, b.lo, b.hi)} ({b.tracks} gliders ≥ {o.glider_min_periods} periods, delays "
                    f"{list(b.lag_range)}); net gliding speed V_com {ci(v.value, v.lo, v.hi, '.4f')} W/period (mean "
                    f"step {f(tr.mean_step.value, '.4f')}); direction of travel turns a median "
                    f"{f(np.degrees(tr.median_direction_change), '.0f')}° per period, persistence "
                    f"{f(tr.direction_persistence)}; signed body-heading turn "
                    f"{ci(np.degrees(ht.value), np.degrees(ht.lo), np.degrees(ht.hi))}°/period")
    return Outcome(beta_holds(tr.beta.beta if tr is not None else None), measured,
                   f"Gliders = each lane's longest bound run ≥ {o.glider_min_periods} periods (the paper: > 30 "
                   "cycles); the paper's centred MSD ⟨x²⟩ − ⟨x⟩² pooled over gliders and time origins, slope over "
                   f"delays {o.fit_lags} periods; 95 % bootstrap interval over gliders. V_com = \\|end − start\\| / "
                   "periods of a glider's once-per-period centre of mass (mean over gliders, bootstrap interval).")


# ----------------------------------------------------------------- polar scan

@claim("polar_symmetry", "at |r| = 1.3 W the attracted region is nearly symmetric about θ ≈ 270°", "Fig. 7C",
       "mean θ within 20° of 270° and mirror correlation > 0.7", ("polar",), evidence="polar")
def polar_symmetry(ev: Polar) -> Outcome:
    """``ev``: the polar scan's attracted starts (:class:`.inputs.Polar`)."""
    axis, corr = ev.axis_deg, ev.mirror_correlation
    ok = bool(abs(axis - POLAR_AXIS_DEG) < POLAR_AXIS_TOL and corr > POLAR_MIRROR_CORR) \
        if np.isfinite(axis + corr) else None
    lo, hi = ev.fraction_range
    return Outcome(ok,
                   f"circular mean θ of attracted starts {f(axis, '.0f')}°; correlation of the attracted fraction "
                   f"with its mirror image about 270°: {f(corr)} ({ev.attracted} of {ev.valid} valid starts "
                   "attracted)",
                   f"{ev.positions} positions × {ev.orientations} orientations at \\|r\\| = {ev.radius_W} W, "
                   f"{ev.periods} periods (the paper: 1000 positions, 75 periods); attracted = bound in the last "
                   f"period; the attracted fraction per 10° bin of θ ranges {f(lo)}–{f(hi)}"
                   + (" (a nearly flat profile leaves the mirror correlation little shape to find)."
                      if hi - lo < 0.3 else "."))


# ----------------------------------------------------------- diagonal gait

@claim("diagonal_beta", "under the time-symmetric gait β ≈ 1", "Fig. 3C (black)",
       "|β − 1| < 0.3 from ≥ 5 gliders", ("diagonal_90", "diagonal_random"), evidence="diagonal")
def diagonal_beta(ev: Diagonal) -> Outcome:
    """``ev``: β of the pooled glider tracks (or None), its delays and one line per source of bound pairs
    (:class:`.inputs.Diagonal`)."""
    bd = ev.beta
    enough = bd is not None and bd.tracks >= DIAGONAL_MIN_GLIDERS
    ok = bool(abs(bd.beta - DIAGONAL_BETA) < BETA_TOLERANCE) if enough and np.isfinite(bd.beta) else None
    return Outcome(ok,
                   (f"β = {ci(bd.beta, bd.lo, bd.hi)} ({bd.tracks} gliders, delays {list(ev.lags)}); "
                    if enough else "too few bound pairs for β: ") + "; ".join(ev.parts),
                   "Two sources of bound pairs under the diagonal gait S1 → S3 → S1 at 90°: the C1 gliders of the "
                   "90° random study started as they were and switched to this gait (the paper's Fig. 3C black "
                   "curve is for bound pairs), and random starts. β as for the square gait: centred MSD at long "
                   "delays, 95 % bootstrap interval over gliders. Under this gait the model's pairs do not stay "
                   "bound, so there is no glider to measure.")


# ----------------------------------------------------------------- chirality

@claim("mirror", "opposite chirality gives mirror-image glider trajectories", "Fig. 4E(i–ii)",
       "the 95 % bootstrap intervals of the two mean turns both exclude 0, with opposite signs (stricter than "
       "before: a sign test that can fail), and C1 θ equal to the mirrored θ within 15°", ("cw_90", "random_90"),
       evidence="mirror")
def mirror(ev: Mirror) -> Outcome:
    """``ev``: each chirality's mean signed body-heading turn per glider with its bootstrap interval, C1's
    mean θ (ccw) and the mirrored cw one (:class:`.inputs.Mirror`)."""
    (m1, lo1, hi1, n1), (m2, lo2, hi2, n2) = dataclasses.astuple(ev.ccw), dataclasses.astuple(ev.cw)
    th_ccw, mirrored = ev.c1_theta_ccw, ev.c1_theta_cw_mirrored
    dth = abs((th_ccw - mirrored + 180) % 360 - 180)
    ok = None
    if np.isfinite([lo1, hi1, lo2, hi2, dth]).all():
        sig = (lo1 > 0 and hi2 < 0) or (hi1 < 0 and lo2 > 0)
        ok = bool(sig and dth < MIRROR_THETA_TOL)
    return Outcome(ok,
                   f"signed body-heading turn per glider: ccw {ci(m1, lo1, hi1)}°/period ({n1} gliders), "
                   f"cw {ci(m2, lo2, hi2)}°/period ({n2} gliders); C1 mean θ: ccw {f(th_ccw, '.0f')}°, "
                   f"cw mirrored (180° − θ) {f(mirrored, '.0f')}°",
                   f"Clockwise random study ({ev.cw_valid} valid starts, {ev.cw_periods} periods) against the "
                   f"counter-clockwise one{_mirror_robots(ev)}; gliders = bound runs ≥ {ev.cw_glider_min_periods} "
                   "periods, one mean turn per glider; a mirror maps θ to 180° − θ and φ to −φ.")


def _mirror_robots(ev: Mirror) -> str:
    """Which drawn robots the two chiralities ran (nothing for ideal robots)."""
    if not ev.robot_pairs:
        return ""
    which = (f"{ev.robot_pairs} drawn robot pairs (lane i on pair i mod {ev.robot_pairs})" if ev.robot_pairs > 1
             else "one drawn robot pair")
    if not ev.same_robots:
        return f", each on its own {which}: the comparison mixes chirality with the robots"
    return (f", both on the same {which}" + (" (until November 2026 each chirality ran one pair of its own "
                                             "seed, so the claim compared two robot pairs)" if ev.robot_pairs > 1
                                             else ""))


# ------------------------------------------------------- steady |r| vs amplitude

@claim("descent", "steady-state |r| decreases with α_max above 45°, with a sharp drop near 85°", "Fig. 3E",
       "ρ < 0 with p < 0.05, and the largest drop between 80° and 90°", ("descent",), evidence="descent")
def descent(ev: Descent) -> Outcome:
    """``ev``: steady |r| per amplitude in increasing amplitude, the window averaged, the periods per stage
    and whether stages continued (:class:`.inputs.Descent`)."""
    sep, win = ev.sep, ev.window
    x = np.array([s_.amplitude_deg for s_ in sep])
    y = np.array([s_.r_W for s_ in sep], float)
    ok = np.isfinite(y)
    from scipy.stats import spearmanr
    rho, p = spearmanr(x[ok], y[ok]) if ok.sum() >= 3 else (np.nan, np.nan)
    drop = ev.largest_drop
    where = f"{drop[0]:g}→{drop[1]:g}°" if drop is not None else "–"
    near85 = where in ("80→85°", "85→90°", "80→90°")
    if ev.tolerance > 0:
        read = (f"pairs converged to {f(ev.tolerance, 'g')} W over {win} periods; not converged in brackets after "
                "the slash")
        counts = lambda s_: f"{s_.pairs}/{s_.unconverged}"  # noqa: E731
        how = (f"each pair's steady \\|r\\| read where it converged: the first period at which its mean over "
               f"the last {win} periods differs by less than {f(ev.tolerance, 'g')} W from the mean over the {win} "
               f"before, bound in all of them (at most {ev.periods} periods per amplitude; pairs that parted or never "
               "converged are not in the mean; 95 % bootstrap intervals over pairs in the figure)")
    else:
        read = f"pairs bound through the last {win} periods"
        counts = lambda s_: f"{s_.pairs}"  # noqa: E731
        how = (f"steady \\|r\\| = mean over the last {win} periods of pairs bound in all of them (pair count in "
               "brackets; 95 % bootstrap intervals over pairs in the figure)")
    started = sep[-1].started if sep else 0
    return Outcome(bool(rho < 0 and p < ALPHA and near85) if np.isfinite(rho) else None,
                   ", ".join(f"{s_.amplitude_deg:g}°: {f(s_.r_W)} ({counts(s_)})" for s_ in sep)
                   + f" W ({read}); Spearman ρ = {f(rho)} (p = {f(p, '.2g')}); largest drop {where}",
                   f"Pairs started bound, as the paper did: {started} steady C1 gliders of the 90° "
                   f"random study, run {ev.periods} periods at each amplitude "
                   + ("(each stage starting where the pairs still bound at the end of the previous one ended)"
                      if ev.continuation else
                      "(each amplitude started from those gliders at rest, arms at the gait's first corner; stepping "
                      "down with each stage starting where the previous one ended was tried first: all 32 pairs "
                      "stayed bound at 85° and all parted within a period at 80°)")
                   + f"; {how}. Before (model `paper`, November 2026), pairs found bound among random starts gave "
                     "ρ = −0.60, p = 0.28.")


# ----------------------------------------------------------- P_b vs amplitude

def pb_groups(amps: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Masks of ``amps`` in the low, intermediate and high bands (:data:`.inputs.PB_BANDS`)."""
    amps = np.asarray(amps)
    return tuple((amps >= lo) & (amps <= hi) for _, lo, hi in PB_BANDS)


@claim("pb_dip", "P_b(α_max) is lower at intermediate amplitudes (40–60°)", "Fig. 3B",
       "every P_b(end) at 40–60° below the means at 10–30° and at 70–90°, and the pooled 40–60° interval below "
       "both pooled flank intervals (stricter than before)", ("amplitude",), evidence="amplitude")
def pb_dip(ev: BindingVsAmplitude) -> Outcome:
    """``ev``: P_b at the end per amplitude with its interval, valid starts per amplitude and the groups
    pooled (:class:`.inputs.BindingVsAmplitude`)."""
    amps, pe, n, pooled = np.asarray(ev.amplitudes_deg), np.asarray(ev.pb_end, float), np.asarray(ev.valid), \
        ev.pooled
    low, mid, high = pb_groups(amps)
    ok = None
    if low.any() and mid.any() and high.any():
        below_means = bool(pe[mid, 0].max() < pe[low, 0].mean() and pe[mid, 0].max() < pe[high, 0].mean())
        separated = pooled.mid.hi < min(pooled.low.lo, pooled.high.lo)
        ok = bool(below_means and separated)
    half = np.nanmax((pe[:, 2] - pe[:, 1]) / 2) if len(pe) else np.nan
    return Outcome(ok,
                   ", ".join(f"{a:g}°: {f(p0)} [{f(lo)}, {f(hi)}]" for a, (p0, lo, hi) in zip(amps, pe))
                   + "; pooled " + ", ".join(f"{g} {ci(v.value, v.lo, v.hi)}" for g, v in pooled.items()),
                   f"{int(n.min())}–{int(n.max())} valid random starts per amplitude (widest 95 % half-width "
                   f"{f(half)}), {ev.periods} periods (the paper: 5000 × 75); bound at the end; exact binomial "
                   "intervals.")


# ----------------------------------------------------------------- relaxation
# evidence: .inputs.Relaxation (reduce.relaxation.analyse_relaxation of the pooled stages, its crowd, the stores'
# settings, the lab's fraction and Fisher's exact test of the model's emergence against it)

RULE_WORDS = {  # each reading's glider, as the page's notes state it (reduce.emergence)
    "apart": "a pair bound every period for ≥ 100 consecutive periods, no touch with a third robot and every "
             "third robot ≥ {apart_W:g} W away (reading (a), fixed November 2026)",
    "touch": "a pair touching in every one of ≥ 100 consecutive periods, whatever third robots did (reading (b), "
             "fixed 7 December 2026)",
    "moved": "a pair touching in every one of ≥ 100 consecutive periods whose centre moved a net ≥ 0.5 W from "
             "period 30 on (reading (c), fixed 7 December 2026)",
    "pair": "a pair touching in every one of ≥ 100 consecutive periods whose centre moved a net ≥ 0.5 W from "
            "period 30 on, neither robot touching a third robot in ≥ 80 % of those periods: a pair, not a chain "
            "(reading (d), the primary one, fixed 7 December 2026)",
}


def _emergence_holds(r, alpha: float = ALPHA) -> bool | None:
    """A reading's emergence verdict: Fisher's p >= alpha, once its interval is at most RELAX_MAX_WIDTH wide."""
    measurable = r.trials and r.interval[1] - r.interval[0] <= RELAX_MAX_WIDTH
    return bool(r.fisher_p >= alpha) if measurable else None


def _distance_holds(d) -> bool | None:
    return bool(abs(d.mean - LAB_DISTANCE_W) <= 2 * math.hypot(d.sem, LAB_DISTANCE_ERR)) if d.n >= 2 else None


@claim("relax_emergence", "in about half of the relaxation trials a pair glides away together for ≥ 100 periods",
       "77 of 151 trials (Fig. 1)", "model and lab fractions do not differ (Fisher's exact test p ≥ 0.05); "
       "measurable once the model's 95 % interval is at most 0.3 wide", ("relax",), evidence="relax")
def relax_emergence(ev: Relaxation) -> Outcome:
    a, s, r = ev.analysis, ev.settings, ev.judged
    rt = a.relaxation_periods
    measured = (f"{r.emerged}/{r.trials} = {ci(r.fraction, *r.interval)} (lab {ci(ev.lab_fraction, *ev.lab_interval)}; "
                f"Fisher's p = {r.fisher_p:.2g}); C1 {r.kinds['C1']}, C2 {r.kinds['C2']}")
    beside = ""
    if r.reading.value != "apart":
        old = ev.rule_a
        moved = _emergence_holds(old) != _emergence_holds(r)
        beside = (f" Read by the bound-and-apart rule (a), the page's reading until December 2026: {old.emerged}/"
                  f"{old.trials} = {ci(old.fraction, *old.interval)}, {VERDICTS[_emergence_holds(old)]}"
                  f"{' (this reading moves the verdict)' if moved else ''}.")
    if ev.emergence is not None:
        beside += " All readings: " + "; ".join(f"({'abcd'[i]}) {x.emerged}/{x.trials}"
                                                for i, x in enumerate(ev.emergence.readings)) + "."
    return Outcome(_emergence_holds(r), measured,
                   f"{r.trials} trials ({ev.stages} stages) of {s.n_robots} robots × {s.periods} periods at "
                   f"{s.amplitude_deg:g}°, {s.start_words()}. Glider: "
                   + RULE_WORDS[r.reading.value].format(apart_W=a.apart_W) + "." + beside +
                   f" Relaxation (last period with a robot touching two others): median "
                   f"{f(rt.median, '.0f')} periods [IQR {f(rt.q25, '.0f')}–{f(rt.q75, '.0f')}] (paper: "
                   f"about 30); {a.stopped_early} trials stopped early, all robots apart and quiet for "
                   f"{s.quiet_periods} periods." + crowd_note(ev.crowd, ev.chains, ev.spreading)
                   + (f" {a.trials - a.valid} of {a.trials} trials were flagged by the engine (penetration or a "
                      "non-finite state) and are left out." if a.trials > a.valid else ""))


def crowd_note(c: CrowdSummary | None, chains=None, spreading=None) -> str:
    """The crowd's measures (reduce.relaxation.CrowdSummary, and reduce.chains.ChainLifetimes and
    reduce.spreading.SpreadingTimes where counted) in one sentence for a claim's notes."""
    if not c:
        return ""
    tau = (f" φ's fitted time constant from period 1 on: median {f(spreading.phi_tau.median, '.1f')} periods (3τ "
           f"{f(3 * spreading.phi_tau.median, '.0f')}; {spreading.phi_at_bound} trials unresolved), the first "
           f"period taking {f(spreading.first_period_share.median)} of the drop; the contacts' "
           f"{f(spreading.contacts_tau.median, '.1f')} periods." if spreading else "")
    pl, cl = c.plateau, c.chain_lifetime
    tracked = (f"; followed by overlap (a chain lives while most of its robots stay), {f(chains.overlap.mean, '.1f')} "
               f"periods (median {f(chains.overlap.median, '.0f')}, {chains.overlap.n} chains)" if chains else "")
    return (f" Relaxation read off the area fraction's plateau (docs/relax.md): median {f(pl.median, '.0f')} "
            f"periods [IQR {f(pl.q25, '.0f')}–{f(pl.q75, '.0f')}], {pl.censored} trials without one "
            f"(paper: about 30); chains of ≥ 3 robots with the same members live {f(cl.mean, '.1f')} periods on "
            f"average{tracked}, with {f(c.neighbours_in_chain)} neighbours per robot (lab: 8–10 periods, about 4)."
            + tau)


@claim("relax_distance", "the glider travels 2.9 ± 0.2 W on average", "2.9 ± 0.2 W (text)",
       "|model − 2.9| ≤ 2 √(SEM² + 0.2²)", ("relax",), evidence="relax")
def relax_distance(ev: Relaxation) -> Outcome:
    a, r = ev.analysis, ev.judged
    d = r.distance
    how = ("\\|end − start\\| of the pair centre over the glider's bound-and-apart run (the longest one of the "
           "trial)" if r.reading.value == "apart" else
           "\\|end − start\\| of the pair centre from period 30 (or the run's start, if later) to the end of the "
           "trial's longest qualifying run")
    beside = ""
    if r.reading.value != "apart":
        old = ev.rule_a.distance
        beside = (f" By the bound-and-apart rule (a), the page's reading until December 2026: {f(old.mean)} ± "
                  f"{f(old.sem)} W (n = {old.n}), {VERDICTS[_distance_holds(old)]}.")
    return Outcome(_distance_holds(d),
                   f"{f(d.mean)} ± {f(d.sem)} W (n = {d.n} gliders; median {f(d.median)}); "
                   f"{r.moved} of them ≥ 0.5 W",
                   f"Glider: {RULE_WORDS[r.reading.value].format(apart_W=a.apart_W)}. Distance = {how}; the lab's ± "
                   "read as a standard error." + beside)


@claim("contour", "bound pairs' contour length grows linearly with their lifetime", "SI, contour length vs time",
       "Pearson r > 0.5 and p < 0.05", ("relax",), evidence="relax")
def contour(ev: Relaxation) -> Outcome:
    fit, ty = ev.analysis.fit, ev.analysis.typed
    ok = bool(finite(fit.r) and fit.r > CONTOUR_R and fit.p < ALPHA) if fit.n >= 3 else None
    return Outcome(ok,
                   f"slope {f(fit.slope, '.4f')} W/period, r = {f(fit.r)} (p = {fit.p:.2g}, {fit.n} "
                   f"episodes ≥ 2 periods); C1 episodes {f(ty.c1.mean, '.1f')} vs C2 "
                   f"{f(ty.c2.mean, '.1f')} periods (one-sided Mann–Whitney p = {ty.p_c1_longer:.2g})",
                   "Every episode of a pair bound and apart from the rest, its contour length (sum of the pair "
                   "centre's per-period steps) against its lifetime; figure lifetime_contour.png.")
