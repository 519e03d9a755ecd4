"""Built relaxation trials for the crowd and emergence tests: touches by period and robots parked in place."""

import numpy as np

from smarticle_mjx.reduce import relaxation as RX


def touch(n, k, edges_by_period):
    """[k, P] touched from {(first, end) periods: [(i, j), ...]}."""
    pairs = [tuple(p) for p in RX.pairs_of(n)]
    t = np.zeros((k, len(pairs)), bool)
    for periods, edges in edges_by_period.items():
        for i, j in edges:
            t[periods[0]:periods[1], pairs.index((min(i, j), max(i, j)))] = True
    return t


def parked(xy, k):
    """Poses [k, N, 5] of robots parked at ``xy`` [N, 2] (m), and the start [N, 5]."""
    start = np.zeros((len(xy), 5))
    start[:, :2] = xy
    return np.repeat(start[None], k, 0), start
