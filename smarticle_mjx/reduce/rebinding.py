"""Rebinding: how often a pair that came apart binds again.

A scan retires a lane once its pair has gone ``quiet_periods`` periods without contact (2 by default), so
a pair that parts and later meets again is invisible in P_b: it is counted as unbound at the end. On a
scan run with that early exit off (``quiet_periods = 0``) every pair runs every period, and from its
per-period contact flags [M, K] (bound in a period = touched at least once in it):

* a pair **parted** when, after a bound period, it went at least ``gap`` consecutive periods unbound
  (``gap`` = the scan's default early exit, 2: exactly the partings a default scan retires);
* it **rebound** when it was bound again in some period after such a parting;
* of the pairs that rebound, how many are bound in the last period (the ones a default scan lost from
  P_b at the end).

The rate is rebound / parted with its exact (Clopper-Pearson) interval. Defined and tested on built
flags (tests/test_rebinding.py) before any scan was read.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .binding import binomial_interval

GAP_PERIODS = 2  # the scan's default early exit (ScanConfig.quiet_periods)


def partings(touched, gap: int = GAP_PERIODS) -> tuple[np.ndarray, np.ndarray]:
    """Per pair ([M, K] flags -> two [M] bools): whether it parted (a bound period followed by at least
    ``gap`` unbound periods in a row) and whether it was bound again in a period after its first parting."""
    t = np.asarray(touched, bool)
    M, K = t.shape
    parted, rebound = np.zeros(M, bool), np.zeros(M, bool)
    for m in range(M):
        seen, quiet = False, 0
        for k in range(K):
            if t[m, k]:
                if parted[m]:
                    rebound[m] = True
                    break
                seen, quiet = True, 0
            elif seen:
                quiet += 1
                if quiet >= gap:
                    parted[m] = True
    return parted, rebound


@dataclasses.dataclass(frozen=True)
class Rebinding:
    """One amplitude's rebinding: valid pairs, pairs bound in some period, pairs that parted, of those the
    ones that rebound (rate and exact 95 % interval) and the ones bound at the end, the gap that counts as
    parting and the periods run."""

    amplitude_deg: float
    valid: int
    ever_bound: int
    parted: int
    rebound: int
    rebound_at_end: int
    rate: float
    lo: float
    hi: float
    gap: int
    periods: int

    def as_json(self) -> dict:
        return dataclasses.asdict(self)


def rebinding(touched, valid, amplitude_deg: float, gap: int = GAP_PERIODS) -> Rebinding:
    """:class:`Rebinding` of a scan run's valid pairs (``touched`` [M, K], ``valid`` [M]); ValueError when
    the flags and the mask disagree in size or the gap is below one period."""
    t, v = np.asarray(touched, bool), np.asarray(valid, bool)
    if t.ndim != 2 or v.shape != t.shape[:1]:
        raise ValueError(f"rebinding: touched [M, K] and valid [M] expected, got {t.shape} and {v.shape}")
    if gap < 1:
        raise ValueError(f"rebinding: the gap must be at least one period, got {gap}")
    t = t[v]
    parted, rebound = partings(t, gap)
    k, n = int(rebound.sum()), int(parted.sum())
    lo, hi = binomial_interval(k, n) if n else (np.nan, np.nan)
    return Rebinding(float(amplitude_deg), int(v.sum()), int(t.any(1).sum()), n, k,
                     int((rebound & t[:, -1]).sum()) if t.shape[1] else 0, k / n if n else float("nan"),
                     float(lo), float(hi), int(gap), int(t.shape[1]))
