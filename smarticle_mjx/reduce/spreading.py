"""How fast a compressed crowd spreads, read as a time constant. Fixed with its tests
(tests/test_emergence.py) before any trial was measured with it.

The plateau rule (:func:`smarticle_mjx.reduce.relaxation.phi_plateau`) returns the first period at which the
area fraction phi stops changing faster than a set rate; on an exponential approach it answers a multiple
of the time constant that depends on the drop's size. This module fits the approach itself:

    y(t) = y_inf + (y_0 - y_inf) exp(-t / tau),  t in periods (0 = the start)

by least squares over the series' defined prefix, for phi (index 0 the start, k the end of period k) and
for the crowd's contacts (touching pairs per period, k = 1 .. periods run). ``3 tau`` is when 95 % of the
change is done: the number to set beside the lab's "about 30 periods to steady state".

phi is fitted from the end of period 1 on, and the first period's share of the whole drop,
(phi_0 - phi_1) / (phi_0 - phi_inf), is reported beside tau: in the model most of the drop happens in the
first period (each arm's first sweep pushes the neighbour it faces out of the 2 mm lattice), a step no
exponential sampled once a period resolves. A tau under ``TAU_MIN`` (more than 98 % of the change within
one period) or at ``TAU_MAX`` is reported as unresolved, never as a time.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .relaxation import Spread

TAU_MIN = 0.25  # periods: exp(-1 / 0.25) < 0.02, the change is done within one sample
TAU_MAX = 1000.0  # periods: a fit that runs to this bound found no decay within the series


@dataclasses.dataclass(frozen=True)
class DecayFit:
    """One exponential approach (see the module's docstring).

    Attributes:
      tau: the time constant (periods); NaN where the fit failed or the series is too short.
      y0, y_inf: the fitted start and end values.
      rmse: root mean square residual.
      n: points fitted.
      at_bound: tau is unresolved, below TAU_MIN or at TAU_MAX (the fit's bounds are 0.05 and TAU_MAX
        periods): report it as such, not as a time.
    """

    tau: float
    y0: float
    y_inf: float
    rmse: float
    n: int
    at_bound: bool


def fit_decay(y, t0: int = 0) -> DecayFit:
    """Fit ``y`` [M] sampled at periods t0, t0 + 1, ... (NaN ends the series)."""
    y = np.asarray(y, float)
    bad = np.flatnonzero(~np.isfinite(y))
    y = y[:bad[0]] if len(bad) else y
    nan = float("nan")
    if len(y) < 4 or np.ptp(y) == 0:
        return DecayFit(nan, float(y[0]) if len(y) else nan, float(y[-1]) if len(y) else nan, nan, len(y), False)
    from scipy.optimize import curve_fit
    t = np.arange(len(y), dtype=float) + t0

    def f(x, a, b, tau):
        return b + (a - b) * np.exp(-(x - t0) / tau)

    tail = float(np.mean(y[-max(1, len(y) // 5):]))
    lo, hi = 0.05, TAU_MAX
    best = None
    for tau0 in (1.0, 5.0, 20.0, 80.0):  # several starts: the loss is not convex in tau
        try:
            p, _ = curve_fit(f, t, y, p0=(float(y[0]), tail, tau0),
                             bounds=([-np.inf, -np.inf, lo], [np.inf, np.inf, hi]), maxfev=5000)
        except (RuntimeError, ValueError):
            continue
        r = float(np.sqrt(np.mean((f(t, *p) - y) ** 2)))
        if best is None or r < best[1]:
            best = (p, r)
    if best is None:
        return DecayFit(nan, float(y[0]), float(y[-1]), nan, len(y), False)
    (a, b, tau), r = best
    return DecayFit(float(tau), float(a), float(b), r, len(y), bool(tau < TAU_MIN or tau >= hi * 0.99))


@dataclasses.dataclass(frozen=True)
class PhiSpreading:
    """phi's spreading in one trial: the fit from the end of period 1 on, and the first period's share of
    the whole drop (phi_0 - phi_1) / (phi_0 - fit.y_inf) (NaN where the fit failed or nothing dropped)."""

    fit: DecayFit
    first_period_share: float


def phi_spreading(phi) -> PhiSpreading:
    """:class:`PhiSpreading` of phi [K + 1] (index 0 the start; NaN ends the series)."""
    phi = np.asarray(phi, float)
    f = fit_decay(phi[1:], t0=1)
    drop = phi[0] - f.y_inf
    share = float((phi[0] - phi[1]) / drop) if np.isfinite(drop) and drop > 0 else float("nan")
    return PhiSpreading(f, share)


def contacts_per_period(touched, periods_run=None) -> np.ndarray:
    """[periods run] touching pairs in each period (periods 1 .. periods run)."""
    touched = np.asarray(touched, bool)
    k = touched.shape[0] if periods_run is None else int(periods_run)
    return touched[:k].sum(1).astype(float)


@dataclasses.dataclass(frozen=True)
class SpreadingTimes:
    """A study's spreading time constants over its trials (periods).

    Attributes:
      phi_tau: phi's fitted tau per trial (fits at a bound left out, and counted in ``phi_at_bound``).
      contacts_tau: the contacts' fitted tau per trial (the same).
      first_period_share: phi's first-period share of its drop per trial (:class:`PhiSpreading`).
    """

    phi_tau: Spread
    phi_at_bound: int
    contacts_tau: Spread
    contacts_at_bound: int
    first_period_share: Spread


def study_spreading(data, crowd_trials) -> SpreadingTimes:
    """:func:`spreading_times` of a relaxation study's usable trials (``smarticle_mjx.store.read_relax``
    output), from their ``reduce.relaxation.CrowdTrial`` (``crowd_trials``, the same trials in order)."""
    usable = np.flatnonzero(data.usable)
    return spreading_times([phi_spreading(c.phi) for c in crowd_trials],
                           [fit_decay(contacts_per_period(data.touched[t], data.periods_run[t]), t0=1) for t in usable])


def spreading_times(phi: list[PhiSpreading], contact_fits: list[DecayFit]) -> SpreadingTimes:
    ok = lambda fits: [f.tau for f in fits if np.isfinite(f.tau) and not f.at_bound]  # noqa: E731
    fits = [p.fit for p in phi]
    return SpreadingTimes(Spread.of(ok(fits)), sum(f.at_bound for f in fits),
                          Spread.of(ok(contact_fits)), sum(f.at_bound for f in contact_fits),
                          Spread.of([p.first_period_share for p in phi if np.isfinite(p.first_period_share)]))
