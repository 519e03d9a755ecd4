"""Gliders emerging from a relaxation trial (paper, Fig. 1; SI "Trajectory contour length and lifetime"):
detection, type, lifetime, distance travelled, contour length. numpy/scipy only.

Inputs are a relaxation store's per-period records for one trial: poses
[K, N, 5] at the end of every period, ``touched`` [K, P] (robots i < j of pair
p touched at least once in the period), ``left_plate`` [N] and the start poses.

Definitions (stated before any number is known):

* A pair is **bound** in a period if its robots touched in it (the paper's
  definition, the same as the scans').
* A bound pair is **apart** in a period if neither of its robots touched a
  third robot in that period and, at the period's end, every third robot's
  centre is at least ``apart_W`` (default 2 W) from both of its centres; and
  both robots are still on the plate.
* An **episode** is a maximal run of consecutive periods in which a pair is
  bound and apart; its **lifetime** is its length in periods, **censored**
  when it reaches the trial's last period.
* A **glider** is an episode of at least ``min_periods`` (default 100, the
  lab's criterion) periods. A trial "formed a glider" if it has one.
* The **track** of an episode is the pair's centre (the mean of the two body
  centres) at the end of every period of the episode, starting from the end
  of the period before it (or the start). **Distance travelled** is
  |end - start| of that track, **contour length** the sum of its steps, both
  in W.
* **Type**: C1 (anti-aligned) if the episode's mean cos(phi) < 0, else C2;
  phi is the angle between the two body normals (the same rule that names
  the scans' clusters).
* **Relaxation time** of a trial: the first period from which, until the
  trial ends, no robot touches two other robots in one period (the cluster
  has broken into pairs and singles).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import configs as C
from ..records import RelaxRecord
from . import binding

C1, C2 = "C1", "C2"


def pairs_of(n: int) -> np.ndarray:
    """[P, 2] robot pairs i < j in the engine's sensor order."""
    return np.array([(i, j) for i in range(n) for j in range(i + 1, n)], dtype=int).reshape(-1, 2)


def _partners(touched: np.ndarray, pairs: np.ndarray, n: int) -> np.ndarray:
    """[K, N]: how many other robots each robot touched in period k."""
    per_robot = np.zeros((touched.shape[0], n), int)
    for p, (i, j) in enumerate(pairs):
        per_robot[:, i] += touched[:, p]
        per_robot[:, j] += touched[:, p]
    return per_robot


def third_touch(touched: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """[K, P]: a robot of pair p touched a robot outside the pair in period k."""
    per_robot = _partners(touched, pairs, int(pairs.max()) + 1)
    own = touched.astype(int)
    return (per_robot[:, pairs[:, 0]] - own > 0) | (per_robot[:, pairs[:, 1]] - own > 0)


@dataclasses.dataclass(frozen=True)
class Episode:
    """One bound-and-apart episode of a trial (:func:`trial_episodes`).

    Attributes:
      pair: the two robots (i < j).
      start: first period (0-based) of the episode.
      lifetime: its periods.
      censored: it ran to the trial's last period.
      distance_W, contour_W: the pair centre's net and path displacement over the episode (W).
      kind: C1 (anti-aligned, mean cos phi < 0) or C2.
      mean_cos_phi: mean of cos(phi) over the episode.
      track: [lifetime + 1, 2] the pair centre from the period before the episode (W).
      trial: the store's trial number (-1 where the caller did not say).
    """

    pair: tuple[int, int]
    start: int
    lifetime: int
    censored: bool
    distance_W: float
    contour_W: float
    kind: str
    mean_cos_phi: float
    track: np.ndarray
    trial: int = -1


@dataclasses.dataclass(frozen=True)
class TrialRow:
    """One valid trial of :func:`analyse_relaxation`: its gliders (episodes of at least ``min_periods``), the longest
    of them (None without), the contact rule's relaxation time and whether it was still crowded at the
    end, and the periods it ran."""

    trial: int
    gliders: int
    glider: Episode | None
    relaxation_periods: int
    crowded_at_end: bool
    periods_run: int


def trial_episodes(poses, touched, start, left_plate=None, periods_run=None, body_length: float = 0.05,
                   apart_W: float = 2.0, trial: int = -1) -> list[Episode]:
    """Every bound-and-apart episode of one trial.

    Args:
      poses: [K, N, 5] poses at the end of each period (NaN after an early stop).
      touched: [K, P] bool.
      start: [N, 5] start poses.
      left_plate: [N] first period off the plate (0: never); None: all stayed.
      periods_run: periods simulated (default K).
      body_length: W in metres.
      apart_W: closest a third robot's centre may come (W).
      trial: the trial's number, recorded in each episode.

    Returns:
      one :class:`Episode` per episode, pair by pair in order of start.
    """
    poses = np.asarray(poses, float)
    touched = np.asarray(touched, bool)
    k_all, n = poses.shape[:2]
    k = k_all if periods_run is None else int(periods_run)
    poses, touched = poses[:k], touched[:k]
    pairs = pairs_of(n)
    if touched.shape[1] != len(pairs):
        raise ValueError(f"touched has {touched.shape[1]} pairs, {n} robots have {len(pairs)}")
    xy = poses[..., :2] / body_length  # [K, N, 2] in W
    d = np.linalg.norm(xy[:, :, None] - xy[:, None, :], axis=-1)  # [K, N, N]
    on = np.ones((k, n), bool)
    if left_plate is not None:
        for r, lp in enumerate(np.asarray(left_plate)):
            if lp > 0:
                on[lp - 1:, r] = False
    third = third_touch(touched, pairs)
    out = []
    start = np.asarray(start, float)
    for p, (i, j) in enumerate(pairs):
        others = [c for c in range(n) if c not in (i, j)]
        if others:
            near = (np.minimum(d[:, i, others], d[:, j, others]) < apart_W).any(1)
        else:
            near = np.zeros(k, bool)
        ok = touched[:, p] & ~third[:, p] & ~near & on[:, i] & on[:, j]
        if not ok.any():
            continue
        runs = binding.bound_runs(ok[None])
        for s, length, cens in zip(runs.start, runs.length, runs.censored):
            s, length = int(s), int(length)
            prev = start if s == 0 else poses[s - 1]
            seg = np.concatenate([prev[None], poses[s:s + length]])  # [L+1, N, 5]
            track = (seg[:, i, :2] + seg[:, j, :2]) / 2 / body_length
            steps = np.linalg.norm(np.diff(track, axis=0), axis=1)
            _, _, phi = C.relative_coordinates(poses[s:s + length, i], poses[s:s + length, j], body_length)
            mc = float(np.mean(np.cos(phi)))
            out.append(Episode((int(i), int(j)), s, length, bool(cens and k == k_all),
                               float(np.linalg.norm(track[-1] - track[0])), float(steps.sum()),
                               C1 if mc < 0 else C2, mc, track, int(trial)))
    return out


def relaxation_time(touched, periods_run=None) -> tuple[int, bool]:
    """Periods until the cluster has relaxed: the number of the last period
    in which some robot touched two others (0 if never), and whether that
    was the trial's last period (still crowded: the time is censored)."""
    touched = np.asarray(touched, bool)
    k = touched.shape[0] if periods_run is None else int(periods_run)
    touched = touched[:k]
    n = int(round((1 + np.sqrt(1 + 8 * touched.shape[1])) / 2))
    crowded = (_partners(touched, pairs_of(n), n) >= 2).any(1)
    if not crowded.any():
        return 0, False
    last = int(np.nonzero(crowded)[0][-1] + 1)
    return last, last == k


def analyse(*args, **kwargs) -> "RelaxAnalysis":
    """Deprecated name of :func:`analyse_relaxation` (one name per public function; ``reduce.analysis.analyse``
    is the scan's). Kept for one release with a DeprecationWarning."""
    import warnings
    warnings.warn("smarticle_mjx.reduce.relaxation.analyse is now analyse_relaxation; the old name goes in the "
                  "next release", DeprecationWarning, stacklevel=2)
    return analyse_relaxation(*args, **kwargs)


def analyse_relaxation(data: RelaxRecord, min_periods: int = 100, apart_W: float = 2.0, min_episode: int = 2,
                       level: float = 0.95) -> "RelaxAnalysis":
    """The relaxation study's numbers (:class:`RelaxAnalysis`) from :func:`smarticle_mjx.store.read_relax` output.

    Args:
      min_periods: shortest episode counted as a glider (the lab: 100 periods).
      apart_W: see :func:`trial_episodes`.
      min_episode: shortest episode kept for the lifetime-contour scatter.

    Returns:
      :class:`RelaxAnalysis`: trials, valid, gliders (trials that formed one) with the exact
      interval, per-trial glider rows, distance statistics, the lifetime vs
      contour-length fit over every episode, typed lifetimes, relaxation
      times, robots that left the plate.
    """
    if min_periods < 1 or min_episode < 1 or not apart_W > 0:
        raise ValueError("min_periods and min_episode must be >= 1 and apart_W > 0")
    W = float(data.body_length)
    periods = int(data.periods)
    valid = data.usable
    episodes, per_trial, relax_t = [], [], []
    for t in np.flatnonzero(valid):
        eps = trial_episodes(data.poses[t], data.touched[t], data.start_poses[t], data.left_plate[t],
                             data.periods_run[t], W, apart_W, trial=int(data.trial[t]))
        episodes += [e for e in eps if e.lifetime >= min_episode]
        gl = [e for e in eps if e.lifetime >= min_periods]
        best = max(gl, key=lambda e: e.lifetime) if gl else None
        rt, crowded = relaxation_time(data.touched[t], data.periods_run[t])
        per_trial.append(TrialRow(int(data.trial[t]), len(gl), best, rt, crowded, int(data.periods_run[t])))
        relax_t.append(rt)
    n = int(valid.sum())
    k = sum(1 for r in per_trial if r.glider is not None)
    lo, hi = binding.binomial_interval(k, n, level) if n else (np.nan, np.nan)
    gl = [r.glider for r in per_trial if r.glider is not None]
    rt = np.array(relax_t, float)
    nan = float("nan")
    lp = np.asarray(data.left_plate)[valid]
    return RelaxAnalysis(
        trials=int(len(data.valid)), valid=n, emerged=k, fraction=k / n if n else nan,
        interval=(float(lo), float(hi)), min_periods=min_periods, apart_W=apart_W, periods=periods,
        per_trial=per_trial, episodes=episodes,
        distance=mean_sem(np.array([g.distance_W for g in gl])),
        glider_contour=mean_sem(np.array([g.contour_W for g in gl])),
        glider_lifetime=mean_sem(np.array([g.lifetime for g in gl], float)),
        glider_censored=int(sum(g.censored for g in gl)),
        glider_kinds=KindCounts(sum(g.kind == C1 for g in gl), sum(g.kind == C2 for g in gl)),
        fit=lifetime_contour_fit(episodes), typed=typed_lifetimes(episodes),
        relaxation_periods=RelaxationTimes(float(np.median(rt)) if len(rt) else nan,
                                           float(np.percentile(rt, 25)) if len(rt) else nan,
                                           float(np.percentile(rt, 75)) if len(rt) else nan,
                                           int(sum(r.crowded_at_end for r in per_trial))),
        left_plate=LeftPlate(int((lp > 0).sum()), int((lp > 0).any(1).sum())),
        stopped_early=int((np.asarray(data.periods_run)[valid] < periods).sum()))


def _json(obj):
    """A typed result's JSON form (its own ``as_json``, else its fields in order), as stores' reports record it."""
    if hasattr(obj, "as_json"):
        return obj.as_json()
    return dataclasses.asdict(obj) if dataclasses.is_dataclass(obj) else obj


@dataclasses.dataclass(frozen=True)
class MeanSem:
    """A sample's size, mean, standard error (NaN below two values) and median (NaN when empty)."""

    n: int
    mean: float
    sem: float
    median: float


def mean_sem(v) -> MeanSem:
    v = np.asarray(v, float)
    if len(v) == 0:
        return MeanSem(0, float("nan"), float("nan"), float("nan"))
    sem = float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")
    return MeanSem(int(len(v)), float(v.mean()), sem, float(np.median(v)))


@dataclasses.dataclass(frozen=True)
class ContourFit:
    """The least-squares line contour = slope x lifetime + intercept (W, periods) over ``n`` episodes, with
    Pearson's r, its p-value and the slope's standard error (NaN below three episodes or one lifetime)."""

    n: int
    slope: float
    intercept: float
    r: float
    p: float
    slope_stderr: float


def lifetime_contour_fit(episodes: list[Episode]) -> ContourFit:
    """Least-squares line contour = slope * lifetime + intercept over every
    episode, with Pearson's r and its p-value (the paper's SI reports a
    linear correlation)."""
    nan = float("nan")
    if len(episodes) < 3:
        return ContourFit(len(episodes), nan, nan, nan, nan, nan)
    from scipy.stats import linregress
    x = np.array([e.lifetime for e in episodes], float)
    y = np.array([e.contour_W for e in episodes], float)
    if np.ptp(x) == 0:
        return ContourFit(len(x), nan, nan, nan, nan, nan)
    f = linregress(x, y)
    return ContourFit(int(len(x)), float(f.slope), float(f.intercept), float(f.rvalue), float(f.pvalue),
                      float(f.stderr))


@dataclasses.dataclass(frozen=True)
class KindLifetimes:
    """Lifetimes (periods) of one glider type's episodes and how many were still running at the end."""

    n: int
    mean: float
    sem: float
    median: float
    censored: int


@dataclasses.dataclass(frozen=True)
class TypedLifetimes:
    """C1's and C2's episode lifetimes and the one-sided Mann-Whitney p-value that C1 lives longer (NaN
    without both)."""

    c1: KindLifetimes
    c2: KindLifetimes
    p_c1_longer: float

    def as_json(self) -> dict:
        return {C1: _json(self.c1), C2: _json(self.c2), "p_c1_longer": self.p_c1_longer}


def typed_lifetimes(episodes: list[Episode]) -> TypedLifetimes:
    """Lifetimes of C1 and C2 episodes (mean, median, censored count) and a
    one-sided Mann-Whitney test that C1 lives longer."""
    kinds = []
    for kind in (C1, C2):
        v = np.array([e.lifetime for e in episodes if e.kind == kind], float)
        ms = mean_sem(v)
        kinds.append(KindLifetimes(ms.n, ms.mean, ms.sem, ms.median,
                                   int(sum(e.censored for e in episodes if e.kind == kind))))
    a = [e.lifetime for e in episodes if e.kind == C1]
    b = [e.lifetime for e in episodes if e.kind == C2]
    p = float("nan")
    if a and b:
        from scipy.stats import mannwhitneyu
        p = float(mannwhitneyu(a, b, alternative="greater").pvalue)
    return TypedLifetimes(kinds[0], kinds[1], p)


@dataclasses.dataclass(frozen=True)
class KindCounts:
    """Gliders (each trial's longest) of each type."""

    c1: int
    c2: int

    def as_json(self) -> dict:
        return {C1: self.c1, C2: self.c2}


@dataclasses.dataclass(frozen=True)
class RelaxationTimes:
    """The contact rule's relaxation time over trials (periods: median and quartiles; the last period a
    robot touched two others) and the trials still crowded at their end."""

    median: float
    q25: float
    q75: float
    crowded_at_end: int


@dataclasses.dataclass(frozen=True)
class LeftPlate:
    """Robots that left the plate, and the trials they left in."""

    robots: int
    trials: int


@dataclasses.dataclass(frozen=True)
class RelaxAnalysis:
    """The relaxation study's numbers (:func:`analyse_relaxation`): trials (all, valid: unflagged), the trials in
    which a glider emerged with its exact interval, the rule's ``min_periods`` and ``apart_W``, the
    periods run; per-trial rows (:class:`TrialRow`) and every episode (:class:`Episode`, with its
    track); the gliders' distance, contour length and lifetime (W, W, periods), how many were still
    bound at the end and of which type; the lifetime-contour fit over episodes; typed lifetimes; the
    contact rule's relaxation times; robots that left the plate; trials stopped early."""

    trials: int
    valid: int
    emerged: int
    fraction: float
    interval: tuple[float, float]
    min_periods: int
    apart_W: float
    periods: int
    per_trial: list[TrialRow]
    episodes: list[Episode]
    distance: MeanSem
    glider_contour: MeanSem
    glider_lifetime: MeanSem
    glider_censored: int
    glider_kinds: KindCounts
    fit: ContourFit
    typed: TypedLifetimes
    relaxation_periods: RelaxationTimes
    left_plate: LeftPlate
    stopped_early: int

    def as_json(self) -> dict:
        """The report's form: every field under its name, typed parts as dicts, in field order (an
        episode's track stays an array)."""
        out = {f.name: _json(getattr(self, f.name)) for f in dataclasses.fields(self)
               if f.name not in ("per_trial", "episodes")}
        out["per_trial"] = [{**dataclasses.asdict(dataclasses.replace(r, glider=None)),
                             "glider": None if r.glider is None else _episode_json(r.glider)} for r in self.per_trial]
        out["episodes"] = [_episode_json(e) for e in self.episodes]
        return {f.name: out[f.name] for f in dataclasses.fields(self)}


def _episode_json(e: Episode) -> dict:
    return {f.name: getattr(e, f.name) for f in dataclasses.fields(e)}


# ------------------------------------------------------------------ the crowd
# Measures of the crowd itself (chains, neighbours, area fraction and its plateau), typed results.
# Definitions and their constants were fixed, with the tests in tests/test_crowd.py, before any model
# trial was measured with them (docs/relax.md, "Measures of the crowd").

PLATEAU_WINDOW = 10  # periods per window of the area-fraction plateau rule
PLATEAU_TOL = 0.02  # largest change of phi over one window (least-squares slope x window), absolute
PLATEAU_WINDOWS = 2  # consecutive windows that must each pass (a plateau lasts >= 2 windows)
CHAIN_MIN = 3  # robots in a chain (a pair is a glider candidate, not a chain)


@dataclasses.dataclass(frozen=True)
class ChainEpisode:
    """One chain held by the same robots over consecutive periods.

    Attributes:
      members: the robots (sorted indices), >= CHAIN_MIN of them.
      start: first period (0-based) in which this member set formed one connected component.
      lifetime: consecutive periods (>= 1) with exactly this member set.
      censored: the run reached the last period simulated (the chain may have lived on).
      loop_periods: periods of the episode in which the chain's touch graph held a closed loop
        (at least as many touching pairs as members).
    """

    members: tuple[int, ...]
    start: int
    lifetime: int
    censored: bool
    loop_periods: int


@dataclasses.dataclass(frozen=True)
class Plateau:
    """The area fraction's plateau (the relaxation time read off phi(t)).

    Attributes:
      period: first period of the plateau (phi(t) is indexed by periods, 0 = the start);
        if none was found, the last period on which phi is defined (then ``censored``).
      censored: no plateau before phi's series ended (the crowd was still relaxing).
      phi: median phi over the plateau's first window (NaN if censored).
      phi_end: phi on the last period it is defined (what a slow creep below the rule's rate
        still took off after the plateau began: ``phi - phi_end``).
      defined_until: last period on which phi is defined (plate-exit rule).
      window, tol: the rule's constants.
    """

    period: int
    censored: bool
    phi: float
    phi_end: float
    defined_until: int
    window: int = PLATEAU_WINDOW
    tol: float = PLATEAU_TOL


@dataclasses.dataclass(frozen=True, eq=False)
class CrowdTrial:
    """Crowd measures of one trial, per period.

    Attributes:
      phi: [K + 1] area fraction n W D / (convex-hull area of the body centres), index 0 the start,
        index k the end of period k; NaN from the first period a robot is off the plate.
      degree: [K, N] robots each robot touched in period k (-1 once off the plate or after an early stop).
      in_chain: [K] robots belonging to a chain in period k.
      chains: every chain episode.
      plateau: phi's plateau.
      contact_relaxation: the contact-based relaxation time (:func:`relaxation_time`) and whether censored.
    """

    phi: np.ndarray
    degree: np.ndarray
    in_chain: np.ndarray
    chains: tuple[ChainEpisode, ...]
    plateau: Plateau
    contact_relaxation: tuple[int, bool]

    def chain_degrees(self) -> np.ndarray:
        """Touch degree of every robot in a chain in every period of its chain, pooled (the
        neighbours-in-chain sample)."""
        d = [self.degree[e.start:e.start + e.lifetime][:, list(e.members)].ravel() for e in self.chains]
        return np.concatenate(d) if d else np.zeros(0, int)


def hull_area(xy: np.ndarray) -> float:
    """Area of the convex hull of points [M, 2] (0 for fewer than 3 or collinear points)."""
    xy = np.asarray(xy, float)
    if len(xy) < 3:
        return 0.0
    from scipy.spatial import ConvexHull, QhullError
    try:
        return float(ConvexHull(xy).volume)  # in 2-D, ``volume`` is the area
    except QhullError:
        return 0.0


def area_fraction_at(xy, body_length: float, body_thickness: float) -> float:
    """phi = n W D / (convex-hull area of the n body centres ``xy`` [n, >=2], m); NaN for a degenerate hull."""
    xy = np.asarray(xy, float)
    area = hull_area(xy[:, :2])
    return len(xy) * body_length * body_thickness / area if area > 0 else float("nan")


def area_fraction(poses, start, body_length: float, body_thickness: float, left_plate=None,
                  periods_run=None) -> np.ndarray:
    """Savoie's area fraction of a crowd, phi = n W D / A_hull, per period.

    Args:
      poses: [K, N, >=2] body centres (m) at the end of each period.
      start: [N, >=2] start poses.
      body_length, body_thickness: W and D (m): the body's footprint, as the lab's analysis used it
        (wsavoie/ArduinoSmarticle cloudSmarticle/matlabScripts/plotCloudData.m, A = l w of the body).
      left_plate: [N] first period (1-based) ending with the robot off the plate; 0: never.
      periods_run: periods simulated (an early-stopped trial repeats its last state: phi is held).

    Returns:
      [K + 1] phi (index 0: the start); NaN from the first period a robot was off the plate
      (the hull would jump to the lost robot; the lab's camera loses it).
    """
    poses = np.asarray(poses, float)
    k = poses.shape[0]
    run = k if periods_run is None else int(periods_run)
    xy = np.concatenate([np.asarray(start, float)[None, :, :2], poses[:, :, :2]])  # [K+1, N, 2]
    phi = np.full(k + 1, np.nan)
    for t in range(min(run, k) + 1):
        phi[t] = area_fraction_at(xy[t], body_length, body_thickness)
    if run < k:
        phi[run + 1:] = phi[run]  # no contact for many periods: every later period repeats the last
    if left_plate is not None:
        lp = np.asarray(left_plate)
        if (lp > 0).any():
            phi[int(lp[lp > 0].min()):] = np.nan
    return phi


def phi_plateau(phi, window: int = PLATEAU_WINDOW, tol: float = PLATEAU_TOL,
                windows: int = PLATEAU_WINDOWS) -> Plateau:
    """The first period t at which phi has stopped changing: for each of ``windows`` consecutive
    windows [t + i w, t + (i + 1) w] the least-squares line through phi changes by at most
    ``tol`` across the window. Only phi's defined prefix is read (NaN ends it).

    The rule is a rate (tol / window per period, 0.002 with the defaults: a fifth of the lab's
    mean expansion rate, Savoie's clouds losing ~0.3 of phi in ~30 periods), chosen so that a
    pair gliding away at the lab's ~0.03 W per period, which keeps stretching the hull, does not
    keep the crowd "relaxing" for ever. Its price: a crowd creeping slower than that counts as
    steady, so ``phi_end`` is reported beside the plateau's phi.

    A slope rule (not a range rule) so that period-to-period jiggle of the hull does not hide a
    plateau, and two windows so that a pause in the expansion is not taken for its end.
    """
    phi = np.asarray(phi, float)
    bad = np.flatnonzero(~np.isfinite(phi))
    end = int(bad[0]) - 1 if len(bad) else len(phi) - 1
    last = float(phi[end]) if end >= 0 else float("nan")
    x = np.arange(window + 1, dtype=float)
    x -= x.mean()

    def flat(t):
        y = phi[t:t + window + 1]
        return abs(float(np.dot(x, y - y.mean()) / np.dot(x, x))) * window <= tol

    span = windows * window
    for t in range(0, end - span + 1):
        if all(flat(t + i * window) for i in range(windows)):
            return Plateau(t, False, float(np.median(phi[t:t + window + 1])), last, end, window, tol)
    return Plateau(max(end, 0), True, float("nan"), last, end, window, tol)


def touch_graph(touched_t: np.ndarray, on_t: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """[N, N] symmetric adjacency of one period's touches (``touched_t`` [P]) between robots on the plate
    (``on_t`` [N])."""
    n = len(on_t)
    adj = np.zeros((n, n), bool)
    live = touched_t & on_t[pairs[:, 0]] & on_t[pairs[:, 1]]
    adj[pairs[live, 0], pairs[live, 1]] = True
    return adj | adj.T


def touch_components(adj: np.ndarray, alive: np.ndarray) -> list[list[int]]:
    """Connected components (sorted member lists) of the graph ``adj`` [N, N] over robots ``alive``."""
    n = len(adj)
    seen = ~alive.copy()
    out = []
    for r in range(n):
        if seen[r]:
            continue
        comp, todo = [], [r]
        seen[r] = True
        while todo:
            a = todo.pop()
            comp.append(a)
            for b in np.flatnonzero(adj[a] & ~seen):
                seen[b] = True
                todo.append(int(b))
        out.append(sorted(comp))
    return out


def trial_arrays(poses, touched, left_plate,
                 periods_run) -> tuple[np.ndarray, np.ndarray, int, np.ndarray, np.ndarray]:
    """One trial's arrays checked: poses [K, N, 5], touched [K, P], the periods run, the pairs and
    on [K, N] (a robot on the plate and the trial still running in period k)."""
    poses = np.asarray(poses, float)
    touched = np.asarray(touched, bool)
    k, n = poses.shape[:2]
    run = k if periods_run is None else int(periods_run)
    pairs = pairs_of(n)
    if touched.shape != (k, len(pairs)):
        raise ValueError(f"touched has shape {touched.shape}, {n} robots over {k} periods need {(k, len(pairs))}")
    on = np.ones((k, n), bool)
    if left_plate is not None:
        for r, lp in enumerate(np.asarray(left_plate)):
            if lp > 0:
                on[lp - 1:, r] = False
    on[run:] = False
    return poses, touched, run, pairs, on


def crowd_trial(poses, touched, start, body_length: float, body_thickness: float, left_plate=None,
                periods_run=None) -> CrowdTrial:
    """Chains, neighbours, area fraction and plateau of one relaxation trial.

    Args:
      poses: [K, N, 5] poses at the end of each period (m, rad).
      touched: [K, P] bool, pairs i < j in :func:`pairs_of` order.
      start: [N, 5] start poses.
      body_length, body_thickness: W and D (m).
      left_plate: [N] first period off the plate (1-based; 0: never); a robot is out of the touch
        graph from that period on.
      periods_run: periods simulated (default K); later periods hold no touches and no chains.
    """
    poses, touched, run, pairs, on = trial_arrays(poses, touched, left_plate, periods_run)
    k, n = poses.shape[:2]
    degree = np.full((k, n), -1, int)
    in_chain = np.zeros(k, int)
    episodes: list[ChainEpisode] = []
    open_: dict[tuple[int, ...], list[int]] = {}  # members -> [start, loop_periods]
    for t in range(k):
        adj = touch_graph(touched[t], on[t], pairs)
        degree[t] = np.where(on[t], adj.sum(1), -1)
        now = {}
        for comp in touch_components(adj, on[t]):
            if len(comp) >= CHAIN_MIN:
                edges = int(adj[np.ix_(comp, comp)].sum()) // 2
                now[tuple(comp)] = edges >= len(comp)
        in_chain[t] = sum(len(m) for m in now)
        for m in list(open_):
            if m not in now:
                s, loops = open_.pop(m)
                episodes.append(ChainEpisode(m, s, t - s, False, loops))
        for m, loop in now.items():
            if m in open_:
                open_[m][1] += int(loop)
            else:
                open_[m] = [t, int(loop)]
    last = min(run, k)
    for m, (s, loops) in open_.items():
        episodes.append(ChainEpisode(m, s, last - s, run >= k, loops))
    episodes.sort(key=lambda e: (e.start, e.members))
    phi = area_fraction(poses, start, body_length, body_thickness, left_plate, run)
    return CrowdTrial(phi, degree, in_chain, tuple(episodes), phi_plateau(phi), relaxation_time(touched, run))


@dataclasses.dataclass(frozen=True)
class Spread:
    """A sample's size, mean, standard error and quartiles, and how many of its values are censored
    (lower bounds). NaN where the sample is too small."""

    n: int
    mean: float
    sem: float
    median: float
    q25: float
    q75: float
    censored: int = 0

    @classmethod
    def of(cls, values, censored: int = 0) -> "Spread":
        v = np.asarray(values, float)
        if len(v) == 0:
            return cls(0, *(float("nan"),) * 5, censored)
        sem = float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")
        q25, q50, q75 = (float(x) for x in np.percentile(v, [25, 50, 75]))
        return cls(int(len(v)), float(v.mean()), sem, q50, q25, q75, int(censored))


@dataclasses.dataclass(frozen=True)
class CrowdSummary:
    """A relaxation study's crowd, over its usable trials.

    Attributes:
      trials: usable trials measured.
      chain_lifetime: lifetimes (periods) of every chain episode; ``censored`` counts those still
        holding when the trial ended (their lifetime is a lower bound).
      chain_robots: robots per chain episode.
      neighbours_in_chain: mean touch-graph degree of a robot in a chain, pooled over robot-periods.
      neighbours_all: mean degree over every robot on the plate and period (the same pooling).
      loop_fraction: share of chain-periods whose touch graph holds a closed loop.
      chained_at_end: trials with a chain in their last simulated period.
      plateau: relaxation times (periods) read off phi's plateau; ``censored``: trials with none.
      contact_relaxation: the contact rule's times (last period a robot touched two others).
      phi_start, phi_plateau: phi at the start and on the plateau (trials with one).
      phi_creep: phi's further fall from the plateau to the end of its series (trials with a plateau).
      phi_cut_by_plate: trials whose phi series ends early because a robot left the plate.
    """

    trials: int
    chain_lifetime: Spread
    chain_robots: Spread
    neighbours_in_chain: float
    neighbours_all: float
    loop_fraction: float
    chained_at_end: int
    plateau: Spread
    contact_relaxation: Spread
    phi_start: Spread
    phi_plateau: Spread
    phi_creep: Spread
    phi_cut_by_plate: int


def crowd_summary(trials: list[CrowdTrial]) -> CrowdSummary:
    """Pool :func:`crowd_trial` results of one study."""
    eps = [e for t in trials for e in t.chains]
    life = [e.lifetime for e in eps]
    deg_all = np.concatenate([t.degree[t.degree >= 0] for t in trials]) if trials else np.zeros(0)
    deg_chain = np.concatenate([t.chain_degrees() for t in trials]) if trials else np.zeros(0)
    chain_periods = sum(e.lifetime for e in eps)
    loop_periods = sum(e.loop_periods for e in eps)
    mean = lambda v: float(v.mean()) if len(v) else float("nan")  # noqa: E731
    ran = [int((t.degree >= 0).any(1).sum()) for t in trials]  # periods with a robot on the plate
    plateaus = [t.plateau for t in trials]
    contact = [t.contact_relaxation for t in trials]
    return CrowdSummary(
        trials=len(trials),
        chain_lifetime=Spread.of(life, sum(e.censored for e in eps)),
        chain_robots=Spread.of([len(e.members) for e in eps]),
        neighbours_in_chain=mean(deg_chain), neighbours_all=mean(deg_all),
        loop_fraction=loop_periods / chain_periods if chain_periods else float("nan"),
        chained_at_end=sum(1 for t, r in zip(trials, ran) if r and t.in_chain[r - 1] > 0),
        plateau=Spread.of([p.period for p in plateaus], sum(p.censored for p in plateaus)),
        contact_relaxation=Spread.of([c[0] for c in contact], sum(c[1] for c in contact)),
        phi_start=Spread.of([t.phi[0] for t in trials if np.isfinite(t.phi[0])]),
        phi_plateau=Spread.of([p.phi for p in plateaus if not p.censored]),
        phi_creep=Spread.of([p.phi - p.phi_end for p in plateaus if not p.censored]),
        phi_cut_by_plate=sum(1 for t in trials if not np.isfinite(t.phi[-1])))


# ----------------------------------------------------------------- pairs inside the crowd
# (added November 2026, after version 0.3.5, for the discovery issue's collision-level diagnosis; defined
# and tested on built tracks before any model trial was measured with it)

PAIR_RUN_MIN = 10  # periods: the lab's chain lifetime (8-10); a shorter bound episode is a passing collision


@dataclasses.dataclass(frozen=True)
class PairRun:
    """One pair bound on its own inside or beside the crowd.

    A pair is *isolated-bound* in a period when its two robots touched each other in it, neither touched
    a third robot in it, and both were on the plate; a run is a maximal stretch of consecutive such
    periods of at least ``PAIR_RUN_MIN``. Unlike a glider episode (:func:`trial_episodes`) no distance
    from the rest is asked: this is the pair before it has (or has not) left.

    Attributes:
      pair: the robots (i, j), i < j.
      start: first period (0-based); ``length``: periods.
      ended_by: what ended it: "third" (in the next period a robot of the pair touched a third robot),
        "unbound" (the two stopped touching and neither touched a third), "plate" (a robot left the
        plate) or "end" (the trial ended: censored).
      speed: |c_end - c_before| / length, W per period; c is the pair's centre (the mean of the two body
        centres) at the end of a period, c_before at the end of the period before the run (the start).
      escape: (g_end - g_before) / length, W per period; g is the distance from c to the nearest body
        centre of a third robot on the plate (NaN with no third robot): > 0 when the pair moved away
        from the rest.
      gap_end: g at the run's last period (W).
      mean_cos_phi, kind: the mean cos(phi) over the run's periods and the type it names, C1
        (anti-aligned, < 0) or C2, as for a glider episode (added after the first screen rows had been
        measured, to tell which kind of pair sits still; the other fields' definitions are unchanged).
    """

    pair: tuple[int, int]
    start: int
    length: int
    ended_by: str
    speed: float
    escape: float
    gap_end: float
    mean_cos_phi: float = float("nan")
    kind: str = ""


def pair_runs(poses, touched, start, body_length: float, left_plate=None, periods_run=None,
              min_periods: int = PAIR_RUN_MIN) -> tuple[PairRun, ...]:
    """Every isolated bound pair run of one trial (see :class:`PairRun`), in order of start and pair.

    Args: as :func:`crowd_trial` (poses [K, N, 5] in m, touched [K, P], start [N, 5], left_plate [N]
    1-based first period off the plate, 0 never; periods_run the periods simulated)."""
    poses, touched, run, pairs, on = trial_arrays(poses, touched, left_plate, periods_run)
    k, n = poses.shape[:2]
    xy = np.concatenate([np.asarray(start, float)[None, :, :2], poses[..., :2]]) / body_length  # [K + 1, N, 2]
    live_on = np.concatenate([np.ones((1, n), bool), on])
    third = third_touch(touched, pairs)
    out = []
    for p, (i, j) in enumerate(pairs):
        ok = touched[:, p] & ~third[:, p] & on[:, i] & on[:, j]
        if not ok.any():
            continue
        others = [c for c in range(n) if c not in (i, j)]
        c = (xy[:, i] + xy[:, j]) / 2  # [K + 1, 2], index 0 the start
        if others:
            d = np.linalg.norm(xy[:, others] - c[:, None], axis=-1)
            d = np.where(live_on[:, others], d, np.inf).min(1)
            gap = np.where(np.isfinite(d), d, np.nan)
        else:
            gap = np.full(k + 1, np.nan)
        r = binding.bound_runs(ok[None])
        for s0, length in zip(r.start, r.length):
            s0, length = int(s0), int(length)
            if length < min_periods:
                continue
            e = s0 + length  # first period after the run (0-based)
            if e >= run:
                why = "end"
            elif not (on[e, i] and on[e, j]):
                why = "plate"
            elif third[e, p]:
                why = "third"
            else:
                why = "unbound"
            _, _, phi = C.relative_coordinates(poses[s0:e, i], poses[s0:e, j], body_length)
            mc = float(np.mean(np.cos(phi)))
            out.append(PairRun((int(i), int(j)), s0, length, why,
                               float(np.linalg.norm(c[e] - c[s0]) / length),
                               float((gap[e] - gap[s0]) / length), float(gap[e]), mc, C1 if mc < 0 else C2))
    out.sort(key=lambda q: (q.start, q.pair))
    return tuple(out)


@dataclasses.dataclass(frozen=True)
class PairRunSummary:
    """Isolated bound pair runs pooled over a study's usable trials.

    Attributes:
      trials: trials measured; ``runs``: runs in all; ``trials_with_run``: trials with at least one.
      length: run lengths (periods; ``censored`` those cut by the trial's end).
      speed, escape: per run, W per period (:class:`PairRun`).
      ended_by: run count per cause ("third", "unbound", "plate", "end").
    """

    trials: int
    runs: int
    trials_with_run: int
    length: Spread
    speed: Spread
    escape: Spread
    ended_by: dict


def pair_run_summary(per_trial: list[tuple[PairRun, ...]]) -> PairRunSummary:
    runs = [q for t in per_trial for q in t]
    causes = {c: sum(1 for q in runs if q.ended_by == c) for c in ("third", "unbound", "plate", "end")}
    esc = [q.escape for q in runs if np.isfinite(q.escape)]
    return PairRunSummary(len(per_trial), len(runs), sum(1 for t in per_trial if t),
                          Spread.of([q.length for q in runs], causes["end"]), Spread.of([q.speed for q in runs]),
                          Spread.of(esc), causes)


def crowd_pairs(data: RelaxRecord, min_periods: int = PAIR_RUN_MIN) -> tuple[PairRunSummary, list[tuple[PairRun, ...]]]:
    """:func:`pair_runs` of every usable trial of :func:`smarticle_mjx.store.read_relax` output (the trials
    :func:`crowd` measures), and their summary."""
    W = float(data.body_length)
    per = [pair_runs(data.poses[t], data.touched[t], data.start_poses[t], W, data.left_plate[t],
                     data.periods_run[t], min_periods) for t in np.flatnonzero(data.usable)]
    return pair_run_summary(per), per


def crowd(data: RelaxRecord) -> tuple[CrowdSummary, list[CrowdTrial]]:
    """The crowd measures of every usable trial of :func:`smarticle_mjx.store.read_relax` output
    (the trials :func:`analyse_relaxation` counts: valid, no bad status)."""
    W, D = float(data.body_length), float(data.body_thickness)
    trials = [crowd_trial(data.poses[t], data.touched[t], data.start_poses[t], W, D,
                          data.left_plate[t], data.periods_run[t]) for t in np.flatnonzero(data.usable)]
    return crowd_summary(trials), trials
