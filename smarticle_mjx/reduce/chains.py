"""Chains in a relaxing crowd tracked by overlap: a chain lives while most of its robots stay in it.
Fixed with its tests (tests/test_emergence.py) before any trial was counted with it.

A **chain** in a period is a connected component of that period's touch graph (robots that touched at least
once in the period) with at least ``CHAIN_MIN`` (3) robots on the plate, as in
:func:`smarticle_mjx.reduce.relaxation.crowd_trial`. That function ends a chain whenever its member set
changes (the *exact* reading): a robot joining or leaving for one period ends it, so its lifetimes measure
contact flicker.

The **overlap** reading: a chain of period t + 1 continues a chain of period t when the robots they share
are a strict majority of *both* member sets ("most": more than half, so a chain of 3 keeps going when a 4th
joins or one of 4 leaves, and two chains that merge continue at most one of them). Each chain continues at
most one and is continued by at most one; candidate links are taken in order of most robots shared, then
the older chain, then the lower member list. A chain's lifetime is the number of consecutive periods its
track lasted; censored when the track reached the last period of a trial that ran to its end.

Why overlap is the reading of a "characteristic lifetime of 8-10 periods" (Vardhan et al., APS March
Meeting 2023, G18.2): the lab named chain-like *structures* from video of robots whose contacts open and
close within a period (every arm sweeps through its neighbours); an observer follows the structure while it
keeps most of its robots, not while no contact flickers. The exact reading is kept beside it.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .relaxation import CHAIN_MIN, Spread, touch_components, touch_graph, trial_arrays


@dataclasses.dataclass(frozen=True)
class ChainTrack:
    """One chain followed by overlap.

    Attributes:
      start: first period (0-based); ``lifetime``: periods.
      censored: it reached the last period of a trial that ran to its end.
      first, last: its member sets in its first and last period.
      robots: every robot that was in it at some period.
      changes: periods (after the first) in which its member set differed from the period before.
    """

    start: int
    lifetime: int
    censored: bool
    first: tuple[int, ...]
    last: tuple[int, ...]
    robots: tuple[int, ...]
    changes: int


def chains_per_period(touched, left_plate=None, periods_run=None, n: int | None = None) -> list[list[tuple[int, ...]]]:
    """The chains (sorted member tuples, >= CHAIN_MIN robots) of every period of one trial.

    Args:
      touched: [K, P] bool, pairs i < j in order.
      left_plate: [N] first period off the plate (1-based; 0: never).
      periods_run: periods simulated (default K); later periods hold no chains.
      n: robots (default: from P).
    """
    touched = np.asarray(touched, bool)
    k, p = touched.shape
    if n is None:
        n = int(round((1 + np.sqrt(1 + 8 * p)) / 2))
    _, touched, run, pairs, on = trial_arrays(np.zeros((k, n, 2)), touched, left_plate, periods_run)
    return [[tuple(c) for c in touch_components(touch_graph(touched[t], on[t], pairs), on[t]) if len(c) >= CHAIN_MIN]
            for t in range(k)]


def track_chains(per_period: list[list[tuple[int, ...]]], periods_run: int | None = None) -> tuple[ChainTrack, ...]:
    """Chains followed by overlap (see the module's docstring) from :func:`chains_per_period`."""
    k = len(per_period)
    run = k if periods_run is None else int(periods_run)
    live: list[dict] = []  # open tracks: start, first, last, robots, changes
    done: list[ChainTrack] = []

    def close(tr, end, censored):
        done.append(ChainTrack(tr["start"], end - tr["start"], censored, tr["first"], tr["last"],
                               tuple(sorted(tr["robots"])), tr["changes"]))

    for t in range(min(run, k)):
        now = [tuple(sorted(c)) for c in per_period[t]]
        links = []
        for a, tr in enumerate(live):
            old = set(tr["last"])
            for b, m in enumerate(now):
                shared = len(old & set(m))
                if 2 * shared > len(old) and 2 * shared > len(m):
                    links.append((-shared, tr["start"], tr["last"], m, a, b))
        links.sort()
        used_a, used_b, nxt = set(), set(), []
        for _, _, _, _, a, b in links:
            if a in used_a or b in used_b:
                continue
            used_a.add(a)
            used_b.add(b)
            tr, m = live[a], now[b]
            tr["changes"] += int(m != tr["last"])
            tr["last"] = m
            tr["robots"] |= set(m)
            nxt.append(tr)
        for a, tr in enumerate(live):
            if a not in used_a:
                close(tr, t, False)
        for b, m in enumerate(now):
            if b not in used_b:
                nxt.append({"start": t, "first": m, "last": m, "robots": set(m), "changes": 0})
        live = nxt
    end = min(run, k)
    for tr in live:
        close(tr, end, run >= k)
    done.sort(key=lambda c: (c.start, c.first))
    return tuple(done)


def exact_lifetimes(per_period: list[list[tuple[int, ...]]], periods_run: int | None = None) -> list[tuple[int, bool]]:
    """(lifetime, censored) of every chain by exact member set (the rule of
    :func:`smarticle_mjx.reduce.relaxation.crowd_trial`), from :func:`chains_per_period`."""
    k = len(per_period)
    run = k if periods_run is None else int(periods_run)
    open_: dict[tuple[int, ...], int] = {}
    out = []
    for t in range(min(run, k)):
        now = {tuple(sorted(c)) for c in per_period[t]}
        for m in [m for m in open_ if m not in now]:
            out.append((t - open_.pop(m), False))
        for m in now:
            open_.setdefault(m, t)
    for s in open_.values():
        out.append((min(run, k) - s, run >= k))
    return out


@dataclasses.dataclass(frozen=True)
class ChainLifetimes:
    """Chain lifetimes of a study under both readings (periods; ``censored``: still alive at a trial's end).

    Attributes:
      overlap: tracked by overlap (the page's reading).
      exact: by exact member set.
      overlap_changes: member-set changes per overlap track.
    """

    overlap: Spread
    exact: Spread
    overlap_changes: Spread


def study_chains(data) -> ChainLifetimes:
    """:func:`chain_lifetimes` of a relaxation study's usable trials (``smarticle_mjx.store.read_relax``
    output)."""
    return chain_lifetimes([(data.touched[t], data.left_plate[t], data.periods_run[t])
                            for t in np.flatnonzero(data.usable)])


def chain_lifetimes(trials) -> ChainLifetimes:
    """Pool both readings over trials, each given as (touched [K, P], left_plate [N] or None, periods_run)."""
    tracks, exact = [], []
    for touched, left_plate, periods_run in trials:
        pp = chains_per_period(touched, left_plate, periods_run)
        tracks += track_chains(pp, periods_run)
        exact += exact_lifetimes(pp, periods_run)
    return ChainLifetimes(Spread.of([c.lifetime for c in tracks], sum(c.censored for c in tracks)),
                          Spread.of([e[0] for e in exact], sum(e[1] for e in exact)),
                          Spread.of([c.changes for c in tracks]))
