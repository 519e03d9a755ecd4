"""Binding labels from per-period contact flags.

A pair is bound in a period if its robots touched at least once in it
(paper). From the flags [M, K]:

* ``bound_end``: bound in the last period (the paper's "active at the end").
* ``bound_throughout``: bound in every period.
* ``attracted``: the basin label; bound in the last period of the trial.
* ``lifetime``: longest run of consecutive bound periods.
"""

from __future__ import annotations

import dataclasses

import numpy as np


def longest_run(flags: np.ndarray) -> np.ndarray:
    """Longest run of True along the last axis: [..., K] -> [...]."""
    flags = np.asarray(flags, bool)
    best = np.zeros(flags.shape[:-1], np.int32)
    cur = np.zeros(flags.shape[:-1], np.int32)
    for k in range(flags.shape[-1]):
        cur = np.where(flags[..., k], cur + 1, 0)
        best = np.maximum(best, cur)
    return best


# label codes for phase diagrams
INVALID, REPELLED, ATTRACTED = -1, 0, 1


def bound_end(touched) -> np.ndarray:
    return np.asarray(touched, bool)[..., -1]


def bound_throughout(touched) -> np.ndarray:
    return np.asarray(touched, bool).all(-1)


def lifetimes(touched) -> np.ndarray:
    """Longest run of consecutive bound periods (the store's ``lifetime``)."""
    return longest_run(touched)


def labels(touched, valid) -> np.ndarray:
    """ATTRACTED / REPELLED / INVALID per initial condition ([M, K], [M])."""
    valid = np.asarray(valid, bool)
    out = np.where(bound_end(touched), ATTRACTED, REPELLED)
    return np.where(valid, out, INVALID)


@dataclasses.dataclass(frozen=True)
class Runs:
    """Maximal runs of consecutive bound periods, each [R]: its ``lane``, ``start`` (first period),
    ``length`` (periods) and whether it is ``censored`` (it reaches the last period, so the pair's true
    lifetime is at least ``length``), lane-major."""

    lane: np.ndarray
    start: np.ndarray
    length: np.ndarray
    censored: np.ndarray


def bound_runs(touched) -> Runs:
    """Every maximal run of consecutive bound periods (:class:`Runs`).

    Args:
      touched: [M, K] bool, bound in period k.
    """
    t = np.asarray(touched, bool)
    m, k = t.shape
    pad = np.zeros((m, k + 2), np.int8)
    pad[:, 1:-1] = t
    d = np.diff(pad, axis=1)
    lane_s, start = np.nonzero(d == 1)
    lane_e, stop = np.nonzero(d == -1)  # both sorted lane-major, so they pair up
    assert np.array_equal(lane_s, lane_e)
    length = stop - start
    return Runs(lane_s, start, length, stop == k)


def binomial_interval(k, n, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Clopper-Pearson (exact) interval of a binomial proportion k/n."""
    from scipy.stats import beta
    k, n = np.asarray(k, float), np.asarray(n, float)
    a = (1 - level) / 2
    with np.errstate(invalid="ignore", divide="ignore"):
        lo = np.where(k > 0, beta.ppf(a, k, n - k + 1), 0.0)
        hi = np.where(k < n, beta.ppf(1 - a, k + 1, n - k), 1.0)
    return lo, hi


@dataclasses.dataclass(frozen=True)
class Proportion:
    """k of n as a fraction ``value`` with its exact interval (lo, hi); NaN when n is 0."""

    value: float
    lo: float
    hi: float
    k: int


@dataclasses.dataclass(frozen=True)
class BindingProbability:
    """P_b of one run over its ``n`` valid starts: bound at the end and bound throughout."""

    n: int
    end: Proportion
    throughout: Proportion


def binding_probability(touched, valid, level: float = 0.95) -> BindingProbability:
    """P_b from one run: bound at the end and bound throughout, with exact intervals.

    Args:
      touched: [M, K] bool; valid: [M] bool (invalid starts are excluded).
    """
    t = np.asarray(touched, bool)[np.asarray(valid, bool)]
    n = len(t)
    parts = []
    for k in (int(bound_end(t).sum()) if n else 0, int(bound_throughout(t).sum()) if n else 0):
        lo, hi = binomial_interval(k, n, level) if n else (np.nan, np.nan)
        parts.append(Proportion(k / n if n else np.nan, float(lo), float(hi), k))
    return BindingProbability(n, *parts)
