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

The error is the mean squared normalised residual, (measured - model)^2 /
SE^2 averaged over every feature: about 1 when the model agrees with the
data within measurement error.

Intervals come from the Gauss-Newton covariance at the optimum, scaled by
the reduced chi^2 when it exceeds 1.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .data import Trial
from .effects import BY_NAME, LIBRARY, Effect, EffectSet
from .residuals import Features, features, masked, residual_blocks
from .sim import simulate_trials

MIN_HELDOUT_GAIN = 0.2
UNEXPLAINED = 4.0
MAX_EFFECTS = 2
FIT_CANDIDATES = 2
MIN_SHARE = 0.25  # fit a candidate only if its signature explains >= this share of the leader's


def split(trials: list[Trial]) -> tuple[list[Trial], list[Trial]]:
    """Training and held-out trials: alternate trials (first, third, ... train)."""
    if len(trials) < 2:
        raise ValueError("calibration needs at least 2 trials (half are held out)")
    return trials[0::2], trials[1::2]


class Problem:
    """Residuals of a set of trials under any EffectSet (model runs cached)."""

    def __init__(self, trials: list[Trial]):
        self.trials = trials
        self.meas: list[Features] = [features(tr.t, tr.pose, tr.arms, tr.gait.period()) for tr in trials]
        self._cache: dict = {}
        self.runs = 0

    def model(self, eff: EffectSet):
        key = EffectSet.of({k: v for k, v in eff.as_dict().items() if not BY_NAME[k].measurement})
        if key not in self._cache:
            tracks = simulate_trials(self.trials, scene_for=lambda tr: key.scene(tr.params),
                                     phase_for=lambda tr: key.phases(tr.robots))
            feats = []
            for tr, mt in zip(self.trials, tracks):
                pose, arms = masked(mt, tr)
                feats.append(features(tr.t, pose, arms, tr.gait.period()))
            self._cache[key] = (tracks, feats)
            self.runs += 1
        return self._cache[key]

    def blocks(self, eff: EffectSet) -> list[dict[str, np.ndarray]]:
        _, feats = self.model(eff)
        return [residual_blocks(m, f, eff.noise()) for m, f in zip(self.meas, feats)]

    def vector(self, eff: EffectSet) -> np.ndarray:
        return np.concatenate([v for b in self.blocks(eff) for v in b.values()])

    def error(self, eff: EffectSet) -> float:
        """Mean squared normalised residual (about 1 when the model agrees within measurement error)."""
        v = self.vector(eff)
        return float(np.mean(v ** 2)) if len(v) else 0.0


# ------------------------------------------------------------------ parameter transforms

def _to_u(p, x):
    if p.square:
        return (x ** 2 - p.lo ** 2) / (p.hi ** 2 - p.lo ** 2)
    if p.log:
        return (math.log(x) - math.log(p.lo)) / (math.log(p.hi) - math.log(p.lo))
    return (x - p.lo) / (p.hi - p.lo)


def _from_u(p, u):
    u = min(max(u, 0.0), 1.0)
    if p.square:
        return math.sqrt(p.lo ** 2 + u * (p.hi ** 2 - p.lo ** 2))
    if p.log:
        return math.exp(math.log(p.lo) + u * (math.log(p.hi) - math.log(p.lo)))
    return p.lo + u * (p.hi - p.lo)


def _values(effects: list[Effect], u) -> dict:
    out, k = {}, 0
    for e in effects:
        out[e.name] = {}
        for p in e.params:
            out[e.name][p.name] = _from_u(p, u[k])
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
                grid: int = 9, scan: int = 9) -> Fit:
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
    Two-parameter effects get two passes.
    """
    params = [(e, p) for e in effects for p in e.params]
    new = len(params) - len(effects[-1].params)
    u0 = np.array([min(max(_to_u(p, (start or {}).get(e.name, {}).get(p.name, p.null)), 0.0), 1.0)
                   for e, p in params])

    def fun(u):
        return train.vector(EffectSet.of(_values(effects, np.clip(u, 0.0, 1.0))))

    def chi2(u):
        r = fun(u)
        return float(r @ r)

    m = len(params) - new
    g = grid if m == 1 else 5
    if effects[-1].measurement:
        g = 41  # no simulation needed: the model runs are cached
    axes = [np.linspace(0.0, 1.0, g) for _ in range(m)]
    best_u, best = u0.copy(), chi2(u0)
    for point in np.array(np.meshgrid(*axes, indexing="ij")).reshape(m, -1).T:
        u = u0.copy()
        u[new:] = point
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
        ys = []
        for x in xs:
            v = u.copy()
            v[j] = x
            ys.append(chi2(v))
        ys = np.array(ys)
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
        interval.setdefault(e.name, {})[p.name] = (_from_u(p, u[j] - hw), _from_u(p, u[j] + hw))
    vals = _values(effects, u)
    return Fit([e.name for e in effects], vals, interval, c0, n, c0 / max(n, 1),
               test.error(EffectSet.of(vals)))


def signatures(train: Problem, base: dict, candidates: list[Effect]) -> list[dict]:
    """How much of the current residual each candidate's signature can remove.

    Returns rows sorted best first: effect, explained (0..1), step (the
    linear estimate of the parameters), block shares of the signature.
    """
    r0 = train.vector(EffectSet.of(base))
    rows = []
    for e in candidates:
        cols, steps = [], []
        for p in e.params:
            probe = {**base, e.name: {**e.null(), p.name: p.probe}}
            rp = train.vector(EffectSet.of(probe))
            cols.append((rp - r0) / (p.probe - p.null))
            steps.append(p)
        J = np.stack(cols, 1)
        delta, *_ = np.linalg.lstsq(J, -r0, rcond=None)
        left = r0 + J @ delta
        explained = 1.0 - float(left @ left) / max(float(r0 @ r0), 1e-300)
        est = {p.name: float(np.clip(p.null + d, p.lo, p.hi)) for p, d in zip(steps, delta)}
        rows.append({"effect": e.name, "explained": max(0.0, explained), "estimate": est,
                     "signature_norm": float(np.linalg.norm(J))})
    rows.sort(key=lambda r: -r["explained"])
    return rows


def where_residual(problem: Problem, eff: EffectSet) -> dict[str, float]:
    """Mean squared normalised residual per block (arms, wobble, step, increments)."""
    acc: dict[str, list] = {}
    for b in problem.blocks(eff):
        for k, v in b.items():
            acc.setdefault(k, []).append(v)
    return {k: float(np.mean(np.concatenate(v) ** 2)) for k, v in acc.items()}


def calibrate(trials: list[Trial], library: tuple[Effect, ...] = LIBRARY, on_step=None) -> dict:
    """The whole loop: residual -> ranked diagnosis -> fit -> selection.

    Returns a JSON-ready dict (see report.write).
    """
    say = on_step or (lambda msg: None)
    train_t, test_t = split(trials)
    train, test = Problem(train_t), Problem(test_t)
    null = EffectSet()
    before = {"err_train": train.error(null), "err_heldout": test.error(null),
              "where_heldout": where_residual(test, null)}
    say(f"nominal model: held-out error {before['err_heldout']:.2f}")
    base: dict = {}
    chosen: list[Effect] = []
    current = {"err_heldout": before["err_heldout"], "chi2_train": float(train.vector(null) @ train.vector(null))}
    rounds = []
    accepted_fit = None
    for _ in range(MAX_EFFECTS):
        remaining = [e for e in library if e not in chosen]
        ranking = signatures(train, base, remaining)
        tried = []
        lead = ranking[0]["explained"] if ranking else 0.0
        for row in ranking[:FIT_CANDIDATES]:
            e = BY_NAME[row["effect"]]
            if row["explained"] < max(0.05, MIN_SHARE * lead):
                continue
            start = {**base, e.name: row["estimate"]}
            f = fit_effects(train, test, chosen + [e], start)
            n = f.n_train
            k = sum(len(BY_NAME[x].params) for x in f.effects)
            bic_gain = current["chi2_train"] - f.chi2_train - len(e.params) * math.log(max(n, 2))
            gain = 1.0 - f.err_heldout / max(current["err_heldout"], 1e-12)
            # the effect must be present: its interval excludes the value at which it is absent
            present = any(not (lo <= p.null <= hi) for p in e.params for lo, hi in [f.interval[e.name][p.name]])
            ok = bic_gain > 0 and gain >= MIN_HELDOUT_GAIN and present
            tried.append({"effect": e.name, "values": f.values, "interval": f.interval,
                          "err_train": f.err_train, "err_heldout": f.err_heldout, "heldout_gain": gain,
                          "bic_gain": bic_gain, "params": k, "present": present, "accepted": ok, "_fit": f})
            say(f"  {e.name}: held-out error {f.err_heldout:.2f} ({gain:+.0%}), BIC gain {bic_gain:.1f}")
        best = max((t for t in tried if t["accepted"]), key=lambda t: t["heldout_gain"], default=None)
        rounds.append({"ranking": ranking, "tried": [{k: v for k, v in t.items() if k != "_fit"} for t in tried],
                       "accepted": best["effect"] if best else None})
        if best is None:
            break
        chosen.append(BY_NAME[best["effect"]])
        accepted_fit = best["_fit"]
        base = accepted_fit.values
        current = {"err_heldout": accepted_fit.err_heldout, "chi2_train": accepted_fit.chi2_train}
        say(f"added {best['effect']}")
    final = EffectSet.of(base)
    after = {"err_train": train.error(final), "err_heldout": test.error(final), "where_heldout": where_residual(test, final)}
    verdict = "agrees within measurement error"
    if after["err_heldout"] > UNEXPLAINED:
        verdict = "unexplained residual" if not chosen else "explained in part; unexplained residual remains"
    elif chosen:
        verdict = "explained by " + " + ".join(e.name for e in chosen)
    return {"trials": {"train": [t.name for t in train_t], "heldout": [t.name for t in test_t]},
            "before": before, "after": after, "rounds": rounds,
            "added": [{"effect": e.name, "title": e.title, "values": accepted_fit.values[e.name],
                       "interval": accepted_fit.interval[e.name],
                       "units": {p.name: p.unit for p in e.params}} for e in chosen] if chosen else [],
            "verdict": verdict, "model_runs": train.runs + test.runs,
            "criteria": {"min_heldout_gain": MIN_HELDOUT_GAIN, "unexplained_error": UNEXPLAINED,
                         "bic": "chi2 drop > k ln n on training trials"},
            "_effects": final}
