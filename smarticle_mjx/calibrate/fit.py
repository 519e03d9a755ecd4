"""Diagnose, fit and select effects.

1. Residual of the nominal model on the training trials.
2. Signature of every effect: the change of the residual vector when the
   effect is switched on at its probe value (one simulation per
   parameter). The fraction of the residual that a least-squares step
   along an effect's signatures removes ranks the effects.
3. The leading candidates are fitted alone (bounded least squares with
   finite differences over batched rollouts: no gradients through contact).
4. An effect is added only if it (a) lowers the training chi^2 by more than
   BIC's penalty k ln n, (b) lowers the held-out error by at least
   ``MIN_HELDOUT_GAIN`` and (c) its 95 % interval excludes the value at
   which it is absent. A second effect is then tried on top of the first
   (the first one's parameters refitted with it).
5. If the held-out error stays above ``UNEXPLAINED`` the report says
   "unexplained residual" and shows where it sits.

Before the rounds, a tilted plate is tested without the model
(:mod:`calibrate.drift`): the lone robots' per-cycle steps are split into a
body-frame step and a drift fixed to the plate. A drift significant at
``drift.P_DRIFT`` is converted into a tilt by the model's response to a
small tilt, and the tilt is added (held fixed in the rounds) if its 95 %
region excludes a level plate and it removes at least half of the drift's
chi^2. A small tilt moves each trial's features by less than the body-frame
mismatch a different robot leaves, so the rounds alone never saw it.

The error is the mean squared normalised residual, (measured - model)^2 /
SE^2 averaged over every feature: about 1 when the model agrees with the
data within measurement error.

Intervals come from the Gauss-Newton covariance at the optimum, scaled by
the reduced chi^2 when it exceeds 1.
"""

from __future__ import annotations

import dataclasses
import math
import threading

import numpy as np

from .data import Trial
from .effects import BY_NAME, Effect, EffectSet, unit_to_value, value_to_unit
from .nominal import apply as apply_nominal
from .residuals import Features, features, masked, residual_blocks
from .observables import observables
from .policy import SERVO_HYPOTHESES, UNEXPLAINED  # noqa: F401  (SERVO_HYPOTHESES: re-exported)
from .sim import pmap, simulate_trials

FIT_CANDIDATES = 2
NOMINAL_EFFECTS = ("servo_response", "friction_scale")
SERVO_NOMINAL = ("servo_speed", "servo_kp", "servo_torque", "servo_armature")  # restarted at the preset for them
# fitted jointly with the nominal parameters too: the nominal fit takes the plate's mu where the measured robot
# slides unlike the model's (an independent robot's clean twin: mu 0.09 for a true 0.33), and only there does
# an anisotropic plate change the model robot as it changes the measured one (docs/calibration.md). Arms
# dragging on the plate likewise: the nominal fit mimics their turns and steps with a slipperier plate, from
# where the arm-plate mu fitted in the rounds gains nothing. Fitted jointly it names real drags, but on clean
# sets it also absorbs a robot the library fits badly: so it is offered (``calibrate(plate_hypotheses=...)``,
# ``smx calibrate --plate-hypothesis``) and not on by default (docs/calibration.md)
PLATE_HYPOTHESES = ("anisotropic_friction",)  # the others of stages.PLATE_GRIDS may be asked for
NOMINAL_NFEV, HYPOTHESIS_NFEV = 15, 10  # least-squares iterations (each costs a Jacobian: one run per parameter)  # rescale parameters the nominal fit already fits
MEASURED_Z = 3.0  # a fitted nominal value this many of its measurement's sd away is reported as a finding
CONVENTION_FACTOR = 4.0  # an alternative convention this much better than the declared one is reported


def split(trials: list[Trial]) -> tuple[list[Trial], list[Trial]]:
    """Training and held-out trials: alternate trials (first, third, ... train)."""
    if len(trials) < 2:
        raise ValueError("calibration needs at least 2 trials (half are held out)")
    return trials[0::2], trials[1::2]


class Problem:
    """Residuals of a set of trials under any EffectSet (model runs cached).

    ``nominal`` holds fitted nominal parameters (calibrate.nominal), applied
    to every trial's scene before any effect.
    """

    def __init__(self, trials: list[Trial]):
        self.trials = trials
        self.meas: list[Features] = [features(tr.t, tr.pose, tr.arms, tr.periods) for tr in trials]
        self._cache: dict = {}
        self._lock = threading.Lock()
        self._running: dict = {}  # cache keys being run now, each with an event set when it is stored
        self.runs = 0
        self.nominal: dict = {}
        self.priors: dict = {}  # {name: (measured value, sd)}: priors of the nominal fit (calibrate.data.priors)
        # {effect parameter: (value, (lo, hi))} measured without the model (a phase offset read off the robots'
        # own curves, calibrate.phase): held at that value in every joint fit of its effect (calibrate.nominal)
        self.effect_fixed: dict = {}
        # tracking noise (xy mm, theta deg) measured without the model (calibrate.noise): what every model's
        # frame increments are compared with, unless the effects fitted set their own
        self.noise: tuple[float, float] = (0.0, 0.0)

    def prior_chi2(self, nominal: dict) -> float:
        """The priors' share of chi^2 at these nominal values."""
        return float(sum(((nominal[k] - m) / sd) ** 2 for k, (m, sd) in self.priors.items() if k in nominal))

    def _key(self, eff: EffectSet, nominal: dict | None):
        nom = self.nominal if nominal is None else nominal
        key = EffectSet.of({k: v for k, v in eff.as_dict().items() if not BY_NAME[k].measurement})
        return key, nom, (key, tuple(sorted(nom.items())))

    def prefetch(self, points) -> None:
        """Run the model at every (EffectSet, nominal values or None) not yet cached, side by side
        (calibrate.sim.pmap); the sequential code that follows then reads the cache."""
        todo = {}
        for eff, nom in points:
            _, _, ck = self._key(eff, nom)
            if ck not in self._cache:
                todo[ck] = (eff, nom)
        pmap(lambda en: self.model(*en), list(todo.values()))

    def model(self, eff: EffectSet, nominal: dict | None = None):
        key, nom, ck = self._key(eff, nominal)
        with self._lock:
            hit = self._cache.get(ck)
            if hit is not None:
                return hit
            running = self._running.get(ck)
            if running is None:
                running = self._running[ck] = threading.Event()
                mine = True
            else:
                mine = False
        if not mine:  # another thread is running this very point (two fits side by side): wait for it
            running.wait()
            return self.model(eff, nominal)
        try:
            tracks = simulate_trials(self.trials, scene_for=lambda tr: key.scene(apply_nominal(tr.params, nom)),
                                     phase_for=lambda tr: key.phases(tr.robots, tr.periods))
            feats = []
            for tr, mt in zip(self.trials, tracks):
                pose, arms = masked(mt, tr)
                feats.append(features(tr.t, pose, arms, tr.periods))
            with self._lock:
                self._cache[ck] = (tracks, feats)
                self.runs += 1
        finally:
            with self._lock:
                del self._running[ck]
            running.set()
        return self._cache[ck]

    def blocks(self, eff: EffectSet, nominal: dict | None = None) -> list[dict[str, np.ndarray]]:
        _, feats = self.model(eff, nominal)
        noise = eff.noise() if "tracking_noise" in eff.as_dict() else self.noise
        return [residual_blocks(m, f, noise) for m, f in zip(self.meas, feats)]

    def vector(self, eff: EffectSet) -> np.ndarray:
        return np.concatenate([v for b in self.blocks(eff) for v in b.values()])

    def vector_with(self, nominal: dict, eff: EffectSet | None = None) -> np.ndarray:
        """The residual vector of the model with these nominal values (and effects; default none)."""
        return np.concatenate([v for b in self.blocks(eff or EffectSet(), nominal) for v in b.values()])

    def error(self, eff: EffectSet) -> float:
        """Mean squared normalised residual (about 1 when the model agrees within measurement error)."""
        v = self.vector(eff)
        return float(np.mean(v ** 2)) if len(v) else 0.0


# ------------------------------------------------------------------ parameter transforms

def _values(effects: list[Effect], u) -> dict:
    out, k = {}, 0
    for e in effects:
        out[e.name] = {}
        for p in e.params:
            out[e.name][p.name] = unit_to_value(p, u[k])
            k += 1
    return out


@dataclasses.dataclass
class Fit:
    effects: list[str]
    values: dict
    interval: dict  # {effect: {param: (lo, hi)}} 95 %
    chi2_train: float
    n_train: int
    err_train: float
    err_heldout: float


def _parabola(x, y):
    """Least-squares parabola through (x, y): vertex, curvature a (y = a (x - v)^2 + c), scatter."""
    coef = np.polyfit(x, y, 2)
    a = coef[0]
    v = -coef[1] / (2 * a) if a > 0 else x[int(np.argmin(y))]
    scatter = float(np.std(y - np.polyval(coef, x), ddof=3)) if len(x) > 3 else 0.0
    return float(v), float(a), scatter


def fit_effects(train: Problem, test: Problem, effects: list[Effect], start: dict | None = None,
                grid: int = 9, scan: int = 9, fixed: dict | None = None) -> Fit:
    """Fit the last effect's parameters, the earlier effects held at ``start``.

    Contact makes chi^2 rough in the parameters: a 1 % change of friction
    can flip a stick-slip event and move chi^2 by more than the data's
    statistical resolution. Gradients and line searches then chase the
    roughness, so the fit is: a coarse grid over the new parameters (in
    normalised units), then for each parameter a scan of ``scan`` points
    across the best grid cell, and a least-squares parabola through it.
    The estimate is the parabola's vertex; the 95 % interval is where the
    parabola rises by max(3.84 x reduced chi^2, 2 x the points' scatter
    about it): the statistical interval, widened to the objective's
    roughness; of several passes over a parameter the widest counts.
    Two-parameter effects get two passes. ``fixed``: effects switched on
    at these values and not refitted (a tilt fitted to the plate-frame drift).
    """
    fixed = dict(fixed or {})
    params = [(e, p) for e in effects for p in e.params]
    new = len(params) - len(effects[-1].params)
    u0 = np.array([min(max(value_to_unit(p, (start or {}).get(e.name, {}).get(p.name, p.null)), 0.0), 1.0)
                   for e, p in params])

    def effset(u):
        return EffectSet.of({**fixed, **_values(effects, np.clip(u, 0.0, 1.0))})

    def fun(u):
        return train.vector(effset(u))

    def chi2(u):
        r = fun(u)
        return float(r @ r)

    m = len(params) - new
    g = grid if m == 1 else 5
    if effects[-1].measurement:
        g = 41  # no simulation needed: the model runs are cached
    axes = [np.linspace(0.0, 1.0, g) for _ in range(m)]
    best_u, best = u0.copy(), chi2(u0)
    grid_u = []
    for point in np.array(np.meshgrid(*axes, indexing="ij")).reshape(m, -1).T:
        u = u0.copy()
        u[new:] = point
        grid_u.append(u)
    train.prefetch([(effset(u), None) for u in grid_u])
    for u in grid_u:
        c = chi2(u)
        if c < best:
            best_u, best = u, c
    cell = 1.0 / (g - 1)
    u = best_u.copy()
    n = len(fun(u))
    half = {}
    # earlier effects get one pass to settle with the new one; the new
    # parameters get passes over a shrinking range (rough, asymmetric valleys)
    plan = [(j, 1.0 / (grid - 1)) for j in range(new)]  # a coarse-grid cell, whatever the new effect's grid
    for width in (cell, cell / 2):
        plan += [(j, width) for j in range(new, len(params))]
    if m == 2:
        plan += [(j, cell / 4) for j in range(new, len(params))]
    for j, width in plan:
        xs = np.unique(np.clip(np.linspace(u[j] - width, u[j] + width, scan), 0.0, 1.0))
        vs = []
        for x in xs:
            v = u.copy()
            v[j] = x
            vs.append(v)
        train.prefetch([(effset(v), None) for v in vs])
        ys = np.array([chi2(v) for v in vs])
        vtx, a, scatter = _parabola(xs, ys)
        u[j] = min(max(vtx, xs[0]), xs[-1])
        red = max(1.0, float(ys.min()) / max(n - len(params), 1))
        thresh = max(3.84 * red, 2 * scatter)
        # the widest of the passes: a narrow scan of a rough valley understates it
        half[j] = max(half.get(j, 0.0), min(math.sqrt(thresh / a), 1.0) if a > 0 else 1.0)
    c0 = chi2(u)
    interval: dict = {}
    for j, (e, p) in enumerate(params):
        hw = half.get(j, 0.0)
        interval.setdefault(e.name, {})[p.name] = (unit_to_value(p, u[j] - hw), unit_to_value(p, u[j] + hw))
    vals = {**fixed, **_values(effects, u)}
    return Fit([e.name for e in effects], vals, interval, c0, n, c0 / max(n, 1),
               test.error(EffectSet.of(vals)))


def signatures(train: Problem, base: dict, candidates: list[Effect], points: int = 4) -> list[dict]:
    """Rank the candidates by the gain each actually achieves.

    For every candidate: a coarse grid over its parameters (``points`` per
    parameter in normalised units, 3 x 3 for two; for a measurement effect,
    which needs no model run, 9 log-spaced points per parameter from 0.25 %
    of its range), the lowest training chi^2
    on it, and the linear projection of its probe signature (the change of
    the residual when it is switched on at its probe value). A nonlinear
    effect whose linear signature explains nothing (a servo lag: it moves
    the arms by a whole phase bin, not a little) still shows its real gain
    on the grid.

    Returns rows sorted by the achieved gain, best first: effect,
    grid_gain (1 - best chi^2 / current chi^2 over the grid), estimate
    (the best grid point), explained (the linear share, 0..1).
    """
    r0 = train.vector(EffectSet.of(base))
    c0 = max(float(r0 @ r0), 1e-300)
    rows = []

    def grid(e) -> list[dict]:
        """The candidate's grid of values."""
        if e.measurement:  # no model run: log-spaced down to small levels (0.25 mm of noise is u = 0.0025)
            axes = [0.0025 * 2.0 ** np.arange(9) for _ in e.params]
        else:
            g = points if len(e.params) == 1 else 3
            axes = [(np.arange(g) + 0.5) / g for _ in e.params]
        return [{p.name: unit_to_value(p, x) for p, x in zip(e.params, point)}
                for point in np.array(np.meshgrid(*axes, indexing="ij")).reshape(len(e.params), -1).T]

    plans = {}  # every candidate's probes and grid points, built once: run side by side, then read
    for e in candidates:
        plans[e.name] = ([EffectSet.of({**base, e.name: {**e.null(), p.name: p.probe}}) for p in e.params],
                         [(v, EffectSet.of({**base, e.name: v})) for v in grid(e)])
    train.prefetch([(x, None) for probes, pts in plans.values() for x in probes + [es for _, es in pts]])
    for e in candidates:
        probes, pts = plans[e.name]
        cols = [(train.vector(x) - r0) / (p.probe - p.null) for x, p in zip(probes, e.params)]
        J = np.stack(cols, 1)
        delta, *_ = np.linalg.lstsq(J, -r0, rcond=None)
        left = r0 + J @ delta
        explained = 1.0 - float(left @ left) / c0
        best, best_v = c0, e.null()
        for v, es in pts:
            r = train.vector(es)
            c = float(r @ r)
            if c < best:
                best, best_v = c, v
        rows.append({"effect": e.name, "grid_gain": max(0.0, 1.0 - best / c0), "estimate": best_v,
                     "explained": max(0.0, explained), "signature_norm": float(np.linalg.norm(J))})
    rows.sort(key=lambda r: -r["grid_gain"])
    return rows


def conventions(problem: Problem) -> dict:
    """Do the arm data fit the declared gait, or a convention mix-up far better?

    Compares the arms block of the preset model under the declared gait with
    the same data read with the arms swapped, with the angle signs flipped,
    with both, with the opposite chirality, and with the gait clock a
    quarter period off either way (three more model runs). The interchange
    format's conventions are in docs/calibration.md.

    Returns {"declared": error, "alternatives": {name: error}, "warning":
    one line or None}.
    """
    with_arms = [k for k, tr in enumerate(problem.trials) if tr.arms is not None]
    if not with_arms:
        return {"declared": None, "alternatives": {}, "warning": None}
    _, feats = problem.model(EffectSet(), {})

    def arms_error(meas, model_feats):
        v = [residual_blocks(m, f)["arms"] for m, f in zip(meas, model_feats)
             if m.arms is not None and f.arms is not None]
        v = np.concatenate(v) if v else np.zeros(0)
        return float(np.mean(v ** 2)) if len(v) else float("nan")

    declared = arms_error(problem.meas, feats)
    alt = {}
    for name, fn in (("arms swapped", lambda a: a[..., ::-1]), ("angle signs flipped", lambda a: -a),
                     ("arms swapped and signs flipped", lambda a: -a[..., ::-1])):
        meas = [features(tr.t, tr.pose, fn(tr.arms) if tr.arms is not None else None, tr.periods)
                for tr in problem.trials]
        alt[name] = arms_error(meas, feats)
    other = [tr.with_gaits(lambda g: dataclasses.replace(g, chirality="cw" if g.chirality == "ccw" else "ccw"))
             for tr in problem.trials]
    variants = {"opposite chirality": other}
    # the clock: t = 0 should be phase 0 (the first corner); a quarter period off starts at another corner
    # (a shift of the trial's clock is a quarter of every robot's period only where they share one)
    if all(len(set(tr.periods)) == 1 for tr in problem.trials):
        for sign, word in ((1, "later"), (-1, "earlier")):
            variants[f"the gait a quarter period {word}"] = [
                dataclasses.replace(tr, t=tr.t + sign * tr.gait.period() / 4) for tr in problem.trials]
    for name, trs in variants.items():
        po = Problem(trs)
        alt[name] = arms_error(po.meas, po.model(EffectSet(), {})[1])
        problem.runs += po.runs
    best = min(alt, key=lambda k: alt[k] if np.isfinite(alt[k]) else np.inf)
    warning = None
    if np.isfinite(alt[best]) and alt[best] * CONVENTION_FACTOR < declared and declared > UNEXPLAINED:
        warning = (f"the arm data fit the gait far better read with {best} (arm error {alt[best]:.3g} against "
                   f"{declared:.3g} as declared): check the data's conventions (docs/calibration.md)")
    return {"declared": declared, "alternatives": alt, "warning": warning}


def nominal_findings(nf) -> list[dict]:
    """Nominal parameters whose 95 % interval excludes the preset value (what the data say differs),
    leaving out those without an interval, at a bound or correlated above 0.9 with another: the data do
    not identify them."""
    out = []
    tangled = {c[0] for c in nf.correlated} | {c[1] for c in nf.correlated} | set(nf.at_bound)
    for name, v in nf.values.items():
        if name in nf.measured:  # measured: a finding when the fit moves it far from the measurement
            m, sd = nf.measured[name]
            z = (v - m) / sd
            if abs(z) > MEASURED_Z:
                out.append({"param": name, "value": v, "interval": list(nf.interval.get(name, (np.nan, np.nan))),
                            "preset": m, "ratio": v / m if m else float("nan"), "at_bound": name in nf.at_bound,
                            "correlated": [c for c in nf.correlated if name in c[:2]], "measured": [m, sd],
                            "sd_from_measured": z})
            continue
        lo, hi = nf.interval[name]
        pre = nf.preset[name]
        if np.isfinite([lo, hi]).all() and not lo <= pre <= hi and name not in tangled:
            out.append({"param": name, "value": v, "interval": [lo, hi], "preset": pre,
                        "ratio": v / pre if pre else float("nan"), "at_bound": name in nf.at_bound,
                        "correlated": [c for c in nf.correlated if name in c[:2]]})
    return out


def where_residual(problem: Problem, eff: EffectSet) -> dict[str, float]:
    """Mean squared normalised residual per block (arms, wobble, step, increments)."""
    acc: dict[str, list] = {}
    for b in problem.blocks(eff):
        for k, v in b.items():
            acc.setdefault(k, []).append(v)
    return {k: float(np.mean(np.concatenate(v) ** 2)) for k, v in acc.items()}


def stage_tracks(train: Problem, test: Problem, trials: list[Trial], nom: dict, eff: EffectSet) -> list:
    """Model tracks of every trial, in ``trials``' order, from the two problems' caches."""
    order = {t.name: k for k, t in enumerate(trials)}
    out = [None] * len(trials)
    for prob in (train, test):
        trk, _ = prob.model(eff, nom)
        for tr, x in zip(prob.trials, trk):
            out[order[tr.name]] = x
    return out


def observable_stages(train: Problem, test: Problem, trials: list[Trial], stages: dict) -> dict:
    """Observables (calibrate.observables) of the data and of the model at each stage.

    ``stages``: {label: (nominal values, EffectSet)}. Model tracks come from
    the problems' caches (the fit already ran most of them). Rows of the
    model are matched to the data's by gait (and robot).
    """
    data = observables(trials)
    model = {label: observables(trials, stage_tracks(train, test, trials, nom, eff))
             for label, (nom, eff) in stages.items()}

    def key(row):
        return (row["gait"], row.get("robot"))

    rows = {}
    for kind in data:
        out = []
        for r in data[kind]:
            k = key(r)
            row = {"gait": r["gait"], "measured": r}
            if "robot" in r:
                row["robot"] = r["robot"]
            for label, o in model.items():
                row[label] = next((m for m in o[kind] if key(m) == k), None)
            out.append(row)
        rows[kind] = out
    return rows
