"""Nominal parameters first: fit the robot's continuous parameters before judging structural effects.

Real tracks come from a robot whose arm lengths, masses, servo and plate
differ from the preset's. Left unfitted, those differences show up as a
residual that the structural library then either fails to explain or,
worse, explains with the wrong effect. So the calibration first fits the
continuous parameters of the model it already has:

* servo: ramp speed, position gain, stall torque, the gearbox's reflected
  inertia (armature: it sets how much of an arm's acceleration torque the
  body feels as a reaction, hence how much the body turns within a cycle);
* geometry and mass: each arm's length (separately: a manufacturing
  asymmetry is then named as such), arm mass, total mass;
* plate friction μ.

Method: bounded least squares (``scipy.optimize.least_squares``, trust
region reflective) on the normalised residual vector of the training trials,
in normalised coordinates (log for scales), with forward differences of 2 %
of each range: wide enough that a single stick-slip flip does not dominate
a derivative (see docs/calibration.md on roughness). Every evaluation is one
batched native rollout of all training trials. Intervals come from the
Gauss-Newton covariance at the optimum, scaled by the reduced chi^2 when it
exceeds 1; parameters at a bound and pairs correlated above 0.9 are flagged
(their intervals then mean little on their own).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..scene import SceneParams


@dataclasses.dataclass(frozen=True)
class NominalParam:
    """A continuous model parameter, bounded relative to its preset value.

    Attributes:
      name: ``RobotParams`` field, or ``plate_friction``.
      lo, hi: bounds as factors of the preset value.
      log: fitted in log space.
      unit: for the report.
    """

    name: str
    lo: float
    hi: float
    log: bool
    unit: str

    def preset(self, p: SceneParams) -> float:
        if self.name == "plate_friction":
            return p.plate_friction
        if self.name == "arm2_length":
            return p.robot.arm_lengths[1]
        return float(getattr(p.robot, self.name))

    def bounds(self, p: SceneParams) -> tuple[float, float]:
        v = self.preset(p)
        return v * self.lo, v * self.hi

    def to_u(self, p: SceneParams, x: float) -> float:
        lo, hi = self.bounds(p)
        if self.log:
            return (math.log(x) - math.log(lo)) / (math.log(hi) - math.log(lo))
        return (x - lo) / (hi - lo)

    def from_u(self, p: SceneParams, u: float) -> float:
        lo, hi = self.bounds(p)
        u = min(max(float(u), 0.0), 1.0)
        if self.log:
            return math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo)))
        return lo + u * (hi - lo)


NOMINAL: tuple[NominalParam, ...] = (
    NominalParam("servo_speed", 0.6, 1.4, False, "rad/s"),
    NominalParam("servo_kp", 0.25, 4.0, True, "N m/rad"),
    NominalParam("servo_torque", 0.5, 2.0, True, "N m"),
    NominalParam("servo_armature", 0.1, 10.0, True, "kg m^2"),
    NominalParam("arm_length", 0.8, 1.2, False, "m"),
    NominalParam("arm2_length", 0.8, 1.2, False, "m"),
    NominalParam("arm_mass", 0.5, 2.0, True, "kg"),
    NominalParam("mass", 0.7, 1.3, False, "kg"),
    NominalParam("plate_friction", 0.2, 2.0, True, ""),
)
BY_NAME = {p.name: p for p in NOMINAL}


def apply(p: SceneParams, values: dict) -> SceneParams:
    """Scene parameters with nominal values replaced ({name: value})."""
    robot = {k: v for k, v in values.items() if k != "plate_friction"}
    out = p.replace(robot=dataclasses.replace(p.robot, **robot)) if robot else p
    if "plate_friction" in values:
        out = out.replace(plate_friction=float(values["plate_friction"]))
    return out


@dataclasses.dataclass
class NominalFit:
    """The fitted nominal parameters (JSON-ready through ``as_dict``)."""

    values: dict  # {name: fitted value}
    preset: dict  # {name: preset value}
    interval: dict  # {name: (lo, hi)} 95 %
    at_bound: list  # names
    correlated: list  # [(a, b, r)] with |r| > 0.9
    err_before: float
    err_after: float
    evaluations: int
    measured: dict = dataclasses.field(default_factory=dict)  # {name: [value, sd]} the fit used as priors

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def one_sided_sd(J: np.ndarray, free: list, j: int, red: float) -> float:
    """Gauss-Newton standard deviation (normalised units) of parameter ``j``, on a bound, jointly with the
    parameters ``free`` inside theirs: from the Jacobian ``J`` (its column ``j`` the difference toward the
    inside) and the reduced chi^2 ``red``; nan where the data do not constrain it."""
    cols = list(free) + [j]
    H = J[:, cols].T @ J[:, cols]
    w, V = np.linalg.eigh(H)
    flat = w < 1e-8 * max(float(w.max()), 1e-300)
    if flat.any() and (np.abs(V[-1, flat]) > 0.1).any():  # as for the parameters inside their bounds
        return float("nan")
    return float(np.sqrt(max(np.linalg.pinv(H)[-1, -1] * red, 0.0)))


def fit_nominal(problem, params: tuple[NominalParam, ...] = NOMINAL, max_nfev: int = 40, effect=None,
                start: dict | None = None, effect_start: dict | None = None) -> NominalFit:
    """Fit ``params`` on ``problem`` (a ``fit.Problem`` of training trials).

    Args:
      effect: optionally a structural effect (``effects.Effect``), or a
        tuple of them, fitted jointly with the nominal parameters, the
        values of each then in ``values[effect.name]`` (a servo lag must be
        fitted with the servo's speed and gain, or those absorb it).
      start: nominal values to start from (default: the preset's).
      effect_start: the effect's values to start from (default: its probe).

    The reference scene is the first trial's (all trials of a data set share
    a model preset). Returns the fit; ``problem`` is left at the preset.
    """
    from scipy.optimize import least_squares
    from .effects import EffectSet, bound_side, on_bound_away_from_null, unit_to_value, value_to_unit
    ref = problem.trials[0].params
    start = start or {}
    effs = () if effect is None else tuple(effect) if isinstance(effect, (tuple, list)) else (effect,)
    # an effect's value measured without the model (``problem.effect_fixed``: {parameter: (value, interval)},
    # a phase offset read off the robots' own curves, calibrate.phase) is held there, not fitted
    fixed = getattr(problem, "effect_fixed", {})
    eparams = tuple(q for e in effs for q in e.params if q.name not in fixed)
    u0 = np.array([min(max(p.to_u(ref, start.get(p.name, p.preset(ref))), 0.0), 1.0) for p in params]
                  + [min(max(value_to_unit(q, (effect_start or {}).get(q.name, q.probe)), 0.0), 1.0) for q in eparams])
    calls = {"n": 0}
    kn = len(params)

    def values(u):
        return {p.name: p.from_u(ref, x) for p, x in zip(params, u[:kn])}

    def effects(u):
        out, j = {}, kn
        for e in effs:
            out[e.name] = {}
            for q in e.params:
                if q.name in fixed:
                    out[e.name][q.name] = fixed[q.name][0]
                else:
                    out[e.name][q.name] = unit_to_value(q, u[j])
                    j += 1
        return EffectSet.of(out)

    # measured values (the sidecar's "measured", calibrate.data.priors) enter as Gaussian priors: one
    # residual (fitted - measured) / sd each, beside the data's
    priors = {k: v for k, v in getattr(problem, "priors", {}).items() if k in {p.name for p in params}}

    def vec(u):
        vals = values(u)
        data = problem.vector_with(vals, effects(u))
        if not priors:
            return data
        return np.concatenate([data, [(vals[k] - m) / sd for k, (m, sd) in priors.items()]])

    last: dict = {}
    step = 0.02  # of each normalised range

    def fun(u):
        u = np.clip(np.asarray(u, float), 0.0, 1.0)
        key = u.tobytes()
        if key not in last:
            calls["n"] += 1
            last.clear()
            last[key] = vec(u)
        return last[key]

    def jac(u):
        u = np.clip(np.asarray(u, float), 0.0, 1.0)
        f0 = fun(u)
        cols, pts = [], []
        for j in range(len(u)):
            h = step if u[j] + step <= 1.0 else -step  # forward, backward at the upper bound
            v = u.copy()
            v[j] += h
            pts.append((j, h, v))
        if hasattr(problem, "prefetch"):  # the columns' model runs side by side
            problem.prefetch([(effects(v), values(v)) for _, _, v in pts])
        for j, h, v in pts:
            calls["n"] += 1
            cols.append((vec(v) - f0) / h)
        return np.stack(cols, 1)

    r0 = fun(u0).copy()
    res = least_squares(fun, u0, jac=jac, bounds=(0.0, 1.0), method="trf", max_nfev=max_nfev, x_scale=1.0)
    u = np.clip(res.x, 0.0, 1.0)
    r = res.fun
    names = [p.name for p in params] + [q.name for q in eparams]
    n, k = len(r), len(names)
    J = res.jac
    red = max(1.0, float(r @ r) / max(n - k, 1))
    at_bound = [nm for nm, x in zip(names, u) if bound_side(x)]
    free = [j for j, nm in enumerate(names) if nm not in at_bound]
    # the covariance of the parameters inside their bounds (one on a bound has no Gauss-Newton interval)
    sd = np.full(k, np.nan)
    cc = np.full((k, k), np.nan)
    if free:
        Jf = J[:, free]
        H = Jf.T @ Jf
        cov = np.linalg.pinv(H) * red
        s_f = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        # directions the data do not constrain (JtJ singular there): the parameters along them get no interval
        w, V = np.linalg.eigh(H)
        flat = w < 1e-8 * max(float(w.max()), 1e-300)
        if flat.any():
            s_f[(np.abs(V[:, flat]) > 0.1).any(1)] = np.nan
        sd[free] = s_f
        with np.errstate(invalid="ignore", divide="ignore"):
            cc[np.ix_(free, free)] = np.clip(cov / np.outer(s_f, s_f), -1.0, 1.0)

    def conv(j, x):
        return params[j].from_u(ref, x) if j < kn else unit_to_value(eparams[j - kn], x)

    interval = {}
    for j, (nm, x, s_) in enumerate(zip(names, u, sd)):
        if np.isfinite(s_):
            interval[nm] = (conv(j, x - 1.96 * s_), conv(j, x + 1.96 * s_))
        else:  # on a bound: no Gauss-Newton interval
            interval[nm] = (float("nan"), float("nan"))
    # an effect's parameter that ended on a bound away from its null: the data want the effect at least that
    # large, so its interval is one-sided, from the Gauss-Newton spread inward (the Jacobian's column there is
    # the inward difference) to the bound; without it the effect could not be "present" however clear it is
    for j in range(kn, k):
        side = on_bound_away_from_null(eparams[j - kn], u[j])
        if not side:
            continue
        s_j = one_sided_sd(J, free, j, red)
        if np.isfinite(s_j):
            inward = conv(j, min(max(u[j] - side * 1.96 * s_j, 0.0), 1.0))
            interval[names[j]] = (inward, conv(j, 1.0)) if side > 0 else (conv(j, 0.0), inward)
    interval.update({q.name: tuple(fixed[q.name][1]) for e in effs for q in e.params if q.name in fixed})
    corr = [(names[a], names[b], float(cc[a, b])) for a in range(k) for b in range(a + 1, k)
            if np.isfinite(cc[a, b]) and abs(cc[a, b]) > 0.9]
    vals = values(u)
    vals.update(effects(u).as_dict())
    nd = len(r) - len(priors)  # the data's residuals (the priors' come last)
    return NominalFit(vals, {p.name: p.preset(ref) for p in params}, interval, at_bound, corr,
                      float(np.mean(r0[:nd] ** 2)), float(np.mean(r[:nd] ** 2)), calls["n"],
                      {k: list(v) for k, v in priors.items()})
