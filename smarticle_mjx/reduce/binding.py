"""Binding labels from per-period contact flags.

A pair is bound in a period if its robots touched at least once in it
(paper). From the flags [M, K]:

* ``bound_end``: bound in the last period (the paper's "active at the end").
* ``bound_throughout``: bound in every period.
* ``attracted``: the basin label; bound in the last period of the trial.
* ``lifetime``: longest run of consecutive bound periods.
"""

from __future__ import annotations

import numpy as np

from ..store import longest_run

# label codes for phase diagrams
INVALID, REPELLED, ATTRACTED = -1, 0, 1


def bound_end(touched):
    return np.asarray(touched, bool)[..., -1]


def bound_throughout(touched):
    return np.asarray(touched, bool).all(-1)


def lifetimes(touched):
    """Longest run of consecutive bound periods (the store's ``lifetime``)."""
    return longest_run(touched)


def labels(touched, valid):
    """ATTRACTED / REPELLED / INVALID per initial condition ([M, K], [M])."""
    valid = np.asarray(valid, bool)
    out = np.where(bound_end(touched), ATTRACTED, REPELLED)
    return np.where(valid, out, INVALID)
