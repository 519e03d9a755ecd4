"""One scan run's measures as typed, unrounded results. numpy only.

Each part is its own function on plain per-period arrays, so a caller that
needs one part computes that part alone (picking started-bound gliders needs
:func:`glider_types`, not the MSD's bootstrap). :func:`analyse` composes them;
``report.analyse_run`` reads a store into these arrays and formats the
result; ``smx report``'s JSON is :meth:`RunAnalysis.summary`.

Arrays, for M lanes (starts) of K periods:
  * ``touched`` [M, K] bool: the pair was in contact at least once in period k
    (invalid starts already cleared);
  * ``valid`` [M] bool: the start was a valid configuration;
  * ``rel`` [M, K, 3]: (|r| in W, theta rad, phi rad) at the end of period k;
  * ``com_xy`` [M, K, 2]: the pair's centre of mass in W; ``heading`` [M, K] rad;
  * ``status`` [M] int: the engine's status bits (``store.BAD_STATUS``).

Intervals are 95 %: bootstrap over gliders or lanes, or exact binomial for
probabilities, as each field says. Nothing here is rounded.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..labels import BAD_STATUS
from . import binding as B, gliders as GL, transport as T
from .stepcheck import StepCheck


@dataclasses.dataclass(frozen=True)
class Interval:
    """A point estimate with its 95 % interval (``lo``, ``hi``; NaN where none) and the sample size ``n``."""

    value: float
    lo: float
    hi: float
    n: int

    @classmethod
    def of(cls, values, stat=np.mean) -> "Interval":
        """The statistic of the finite ``values`` and its bootstrap interval (transport.bootstrap_interval)."""
        v, lo, hi, n = T.bootstrap_interval(values, stat=stat)
        return cls(float(v), float(lo), float(hi), int(n))


@dataclasses.dataclass(frozen=True)
class Options:
    """How the reducers cut the data (periods).

    Attributes:
      burn_in: periods skipped before per-period samples count as steady state.
      glider_min_periods: a glider track is a bound run at least this long.
      steady_window: last periods over which steady |r| is averaged.
      fit_lags: MSD delays fitted for beta.
      clusters: k-means clusters of (|r|, theta, phi).
    """

    burn_in: int
    glider_min_periods: int
    steady_window: int
    fit_lags: tuple[int, int]
    clusters: int = 8

    @classmethod
    def for_periods(cls, k: int, burn_in: int | None = None, glider_min_periods: int | None = None,
                    steady_window: int | None = None, fit_lags: tuple[int, int] | None = None,
                    clusters: int = 8) -> "Options":
        """The defaults for a run of ``k`` periods, for what is not given: burn-in a third of the trial, at
        most 30 as in the paper; gliders min(30, k // 2) periods (the paper: > 30 cycles); steady |r| over
        min(20, k // 3); the paper's long delays 5 .. 15, shortened for short gliders to half their length."""
        burn = burn_in if burn_in is not None else min(30, k // 3)
        gmin = glider_min_periods if glider_min_periods is not None else max(2, min(30, k // 2))
        win = steady_window if steady_window is not None else max(1, min(20, k // 3))
        lags = fit_lags if fit_lags is not None else (min(5, max(1, gmin // 4)), max(3, min(15, gmin // 2)))
        return cls(int(burn), int(gmin), int(win), (int(lags[0]), int(lags[1])), int(clusters))


@dataclasses.dataclass(frozen=True)
class Binding:
    """P_b from one run.

    ``end``: the fraction of valid starts bound in the last period; ``throughout``:
    bound in every period (exact 95 % binomial intervals, ``n`` the valid starts).
    ``bound_runs``: maximal runs of consecutive bound periods over all lanes;
    ``bad_status``: lanes the engine flagged (penetration or a non-finite state)."""

    end: Interval
    throughout: Interval
    bound_runs: int
    bad_status: int


def binding(touched, valid, status) -> Binding:
    t = np.asarray(touched, bool)
    pb = B.binding_probability(t, valid)
    end, through = (Interval(float(p.value), float(p.lo), float(p.hi), int(pb.n)) for p in (pb.end, pb.throughout))
    bad = int(((np.asarray(status) & int(BAD_STATUS)) != 0).sum())
    return Binding(end, through, int(len(B.bound_runs(t).length)), bad)


@dataclasses.dataclass(frozen=True)
class TypeStats:
    """One glider type (C1 or C2).

    ``steady_samples``: steady-state bound periods of this type; ``basin_configs``
    and ``basin_fraction``: valid starts that end as this type (of all valid
    starts); ``runs``: bound runs typed as it; ``lifetime_mean`` / ``_median``
    (periods, NaN without runs) and ``censored_fraction``: of those runs, the
    share still bound at the trial's end."""

    name: str
    steady_samples: int
    basin_configs: int
    basin_fraction: float
    runs: int
    lifetime_mean: float
    lifetime_median: float
    censored_fraction: float


@dataclasses.dataclass(frozen=True, eq=False)
class GliderTypes:
    """The glider anatomy: k-means clusters of steady (|r|, theta, phi) samples.

    ``clusters``: ``gliders.Clusters`` (centres [C, 3] in W and rad, each
    centre's kind and size); ``kinds`` [M, K]: each period's type (C1, C2 or
    NONE); ``final`` [M]: the type each lane ends as (NONE unless bound over the
    last window); ``typed``: every bound run with its type
    (``gliders.typed_lifetimes``); ``samples`` [S, 3] and ``sample_kinds`` [S]:
    the steady samples clustered; ``c1`` and ``c2``: per-type statistics."""

    clusters: GL.Clusters
    kinds: np.ndarray
    final: np.ndarray
    typed: GL.TypedRuns
    samples: np.ndarray
    sample_kinds: np.ndarray
    c1: TypeStats
    c2: TypeStats


def steady_samples(rel, touched, burn_in: int) -> tuple[np.ndarray, np.ndarray]:
    """The steady-state mask [M, K] (bound, after ``burn_in``, finite) and its samples [S, 3]."""
    rel = np.asarray(rel, float)
    steady = GL.steady_mask(touched, burn_in) & np.isfinite(rel).all(-1)
    return steady, rel[steady]


def glider_types(rel, touched, valid, burn_in: int, clusters: int = 8, window: int = 10) -> GliderTypes | None:
    """Cluster the steady samples and type every period, run and lane's end.

    None when there are fewer than 5 samples per cluster (they would be
    clustered into noise)."""
    rel = np.asarray(rel, float)
    touched = np.asarray(touched, bool)
    steady, samples = steady_samples(rel, touched, burn_in)
    if len(samples) < 5 * clusters:
        return None
    cl = GL.find_clusters(samples, k=clusters)
    kinds = GL.period_kinds(cl, rel, touched)
    final = GL.final_type(kinds, touched, window=min(window, touched.shape[1]))
    typed = GL.typed_lifetimes(kinds, touched)
    nv = max(int(np.asarray(valid, bool).sum()), 1)

    def stats(kind: int) -> TypeStats:
        sel = typed.kind == kind
        lt = typed.length[sel]
        return TypeStats(GL.NAMES[kind], int((kinds[steady] == kind).sum()), int((final == kind).sum()),
                         float((final == kind).sum() / nv), int(sel.sum()),
                         float(lt.mean()) if len(lt) else float("nan"),
                         float(np.median(lt)) if len(lt) else float("nan"),
                         float(typed.censored[sel].mean()) if len(lt) else float("nan"))

    return GliderTypes(cl, kinds, final, typed, samples, kinds[steady], stats(GL.C1), stats(GL.C2))


@dataclasses.dataclass(frozen=True, eq=False)
class Transport:
    """Gliders' transport, measured as the paper measured it.

    A glider is a lane's bound run of at least ``min_periods`` (its per-period
    centre of mass in W). ``beta``: ``transport.Exponent`` of the centred MSD
    pooled over gliders, fitted over the ``fit_lags`` delays; ``net_speed``:
    |end - start| / periods (W/period; bootstrap over gliders); ``glide_speed``:
    transport.glide_speed's mean (W/period); ``mean_step``: the mean per-period
    displacement, per glider then bootstrapped (W/period); turning of the
    direction of travel (median change, rad per period; persistence; the
    straightness over ``straightness_periods``); ``signed_heading_turn``:
    the body heading's mean signed turn per period per glider (rad/period).
    ``tracks`` [G, L, 2] (NaN-padded), ``msd_lags`` and ``msd`` for the figures."""

    gliders: int
    beta: T.Exponent
    net_speed: Interval
    glide_speed: float
    mean_step: Interval
    median_direction_change: float
    direction_persistence: float
    straightness: float
    straightness_periods: int
    signed_heading_turn: Interval
    heading_turn_per_glider: np.ndarray
    tracks: np.ndarray
    msd_lags: np.ndarray
    msd: np.ndarray


def glider_transport(com_xy, heading, touched, min_periods: int, fit_lags: tuple[int, int]) -> Transport | None:
    """None when no lane has a bound run of ``min_periods`` periods."""
    com_xy = np.asarray(com_xy, float)
    tracks3 = GL.glider_tracks(np.concatenate([com_xy, np.asarray(heading, float)[..., None]], -1), touched,
                               min_periods=min_periods)
    if not len(tracks3):
        return None
    tracks = tracks3[..., :2]
    ex = T.msd_exponent(tracks, lag_range=fit_lags, centered=True)
    lags, m, _ = T.msd(tracks, centered=True)
    per_track_step = np.array([np.nanmean(x) for x in T.step_lengths(tracks)])
    glide = np.asarray(T.glide_speed(tracks), float)
    glide = glide[np.isfinite(glide)]
    turn = T.signed_turn_per_track(tracks3[..., 2])
    sp = min(20, tracks.shape[1] - 1)
    return Transport(len(tracks), ex, Interval.of(T.net_speed(tracks)),
                     float(glide.mean()) if len(glide) else float("nan"), Interval.of(per_track_step),
                     float(T.median_direction_change(tracks)), float(T.direction_persistence(tracks)),
                     float(T.straightness(tracks, sp)), sp, Interval.of(turn), turn, tracks, lags, m)


@dataclasses.dataclass(frozen=True)
class Separation:
    """Steady |r| (W) of the pairs bound in every one of the last ``window`` periods: mean, s.d., s.e.m., pairs."""

    mean: float
    std: float
    sem: float
    pairs: int
    window: int


def separation(rel, touched, window: int) -> Separation:
    ss = GL.steady_separation(rel, touched, window=window)
    return Separation(float(ss.mean), float(ss.std), float(ss.sem), int(ss.pairs), int(window))


def bound_heading_turn(heading, touched) -> float:
    """The body heading's mean signed turn (rad per period) over consecutive bound periods of every lane; NaN if none."""
    t = np.asarray(touched, bool)
    turn = T.turning(np.asarray(heading, float))[t[:, 1:] & t[:, :-1]]
    return float(np.nanmean(turn)) if turn.size else float("nan")


@dataclasses.dataclass(frozen=True, eq=False)
class RunAnalysis:
    """Every part of one run; ``types`` and ``transport`` are None where the run has too few samples or no glider."""

    run: str
    amplitude_deg: float
    chirality: str
    gait: str
    period_s: float
    periods: int
    configs: int
    valid: int
    options: Options
    binding: Binding
    steady_samples: int
    types: GliderTypes | None
    transport: Transport | None
    heading_turn: float
    separation: Separation
    touched: np.ndarray
    # what is known of the step that made the run's transport numbers (passed, failed with its biases, or
    # not checked and why): the store's, set by ``report.analyse_store_run``; None for arrays of no store
    step: StepCheck | None = None

    def summary(self, rnd=None) -> dict:
        """The JSON form (``smx report``'s ``report.json``); ``rnd(x, digits)`` rounds for a page (identity if None)."""
        r = rnd or (lambda x, nd=None: None if x is None or not np.isfinite(x) else float(x))
        b = self.binding
        s: dict = {"run": self.run, "amplitude_deg": self.amplitude_deg, "chirality": self.chirality,
                   "gait": self.gait, "period_s": self.period_s, "periods": self.periods, "configs": self.configs,
                   "valid": self.valid, "options": dataclasses.asdict(self.options),
                   "pb_end": [r(b.end.value), r(b.end.lo), r(b.end.hi)],
                   "pb_throughout": [r(b.throughout.value), r(b.throughout.lo), r(b.throughout.hi)],
                   "bad_status": b.bad_status, "bound_runs": b.bound_runs, "steady_samples": self.steady_samples}
        if self.types is not None:
            ty = self.types
            s["clusters"] = [{"kind": GL.NAMES[int(kd)], "r_W": r(c[0]), "theta_deg": r(np.degrees(c[1]) % 360, 1),
                              "phi_deg": r(np.degrees(c[2]) % 360, 1), "samples": int(n)}
                             for c, kd, n in zip(ty.clusters.centers, ty.clusters.kind, ty.clusters.sizes)]
            for st in (ty.c1, ty.c2):
                s[st.name] = {"steady_samples": st.steady_samples, "basin_fraction": r(st.basin_fraction),
                              "basin_configs": st.basin_configs, "runs": st.runs,
                              "lifetime_mean": r(st.lifetime_mean), "lifetime_median": r(st.lifetime_median),
                              "censored_fraction": r(st.censored_fraction)}
        tr = self.transport
        s["gliders"] = tr.gliders if tr is not None else 0
        if tr is not None:
            ex = tr.beta
            s["beta"] = {"value": r(ex.beta, 3), "err": r(ex.err, 3), "lo": r(ex.lo, 3), "hi": r(ex.hi, 3),
                         "tracks": ex.tracks, "lag_range": list(ex.lag_range), "method": ex.method, "centered": True}
            v = tr.net_speed
            s["v_com"] = {"net_W_per_period": r(v.value, 5), "net_lo": r(v.lo, 5), "net_hi": r(v.hi, 5),
                          "net_W_per_s": r(v.value / self.period_s, 5), "glide_W_per_period": r(tr.glide_speed, 5),
                          "mean_step_W_per_period": r(tr.mean_step.value, 5), "step_lo": r(tr.mean_step.lo, 5),
                          "step_hi": r(tr.mean_step.hi, 5)}
            s["turning"] = {"median_direction_change_deg": r(np.degrees(tr.median_direction_change), 2),
                            "direction_persistence": r(tr.direction_persistence, 3),
                            "straightness_20": r(tr.straightness, 3)}
            t = tr.signed_heading_turn
            s["signed_heading_turn"] = {"deg_per_period": r(np.degrees(t.value), 3), "lo": r(np.degrees(t.lo), 3),
                                        "hi": r(np.degrees(t.hi), 3),
                                        "gliders": int(np.isfinite(tr.heading_turn_per_glider).sum())}
        s["signed_heading_turn_deg_per_period"] = (r(np.degrees(self.heading_turn), 3)
                                                   if np.isfinite(self.heading_turn) else None)
        sp = self.separation
        s["steady_r"] = {"mean_W": r(sp.mean), "std_W": r(sp.std), "sem_W": r(sp.sem), "pairs": sp.pairs}
        return s

    def arrays(self) -> dict:
        """The per-period arrays the report's figures draw (the old ``analyse_run(...)["arrays"]``)."""
        a: dict = {"touched": self.touched}
        if self.types is not None:
            ty = self.types
            a.update(clusters=ty.clusters, kinds=ty.kinds, samples=ty.samples, sample_kinds=ty.sample_kinds,
                     typed=ty.typed, final=ty.final)
        if self.transport is not None:
            tr = self.transport
            a.update(msd=(tr.msd_lags, tr.msd), tracks=tr.tracks,
                     heading_turn_per_glider=np.degrees(tr.heading_turn_per_glider))
        return a


def analyse(touched, valid, rel, com_xy, heading, status, options: Options, *, run: str = "", amplitude_deg: float = float("nan"),
            chirality: str = "", gait: str = "", period_s: float = float("nan")) -> RunAnalysis:
    """Every part of one run from its per-period arrays (see the module docstring); ``touched`` is cleared
    where ``valid`` is False."""
    valid = np.asarray(valid, bool)
    touched = np.asarray(touched, bool) & valid[:, None]
    rel = np.asarray(rel, float)
    o = options
    steady, _ = steady_samples(rel, touched, o.burn_in)
    return RunAnalysis(run, float(amplitude_deg), chirality, gait, float(period_s), int(touched.shape[1]),
                       int(len(valid)), int(valid.sum()), o, binding(touched, valid, status), int(steady.sum()),
                       glider_types(rel, touched, valid, o.burn_in, o.clusters),
                       glider_transport(com_xy, heading, touched, o.glider_min_periods, o.fit_lags),
                       bound_heading_turn(heading, touched), separation(rel, touched, o.steady_window), touched)
