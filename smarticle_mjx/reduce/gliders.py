"""Glider anatomy: C1/C2 clusters of per-period (|r|, theta, phi), basins,
lifetimes, glider tracks and steady-state separation. numpy/scipy only.

C1 is the anti-aligned glider (phi near 180 deg), C2 the aligned one (phi
near 0 deg). The clusters are found, not imposed: k-means on the
per-period relative coordinates of bound pairs, in features that respect
the angles' periodicity; each cluster is then named C1 or C2 by its
circular-mean phi (C1 if within 90 deg of 180 deg).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from . import binding
from . import transport as _transport

NONE, C1, C2 = 0, 1, 2
NAMES = {NONE: "none", C1: "C1", C2: "C2"}


def _features(rel, r_scale: float):
    r, th, ph = np.asarray(rel, float).T
    return np.column_stack([np.cos(ph), np.sin(ph), np.cos(th), np.sin(th), r / r_scale])


def circular_mean(a, axis=None) -> np.ndarray | float:
    return np.angle(np.exp(1j * np.asarray(a, float)).mean(axis=axis))


@dataclasses.dataclass(frozen=True)
class Clusters:
    """k-means clusters of per-period relative coordinates.

    Attributes:
      centers: [k, 3] cluster centres as (|r| W, theta, phi rad).
      kind: [k] C1 or C2 per cluster.
      sizes: [k] samples per cluster.
      r_scale: |r| scale of the features (W).
      features_centers: [k, 5] centres in feature space (for classifying).
      radius: [k] a sample farther than this from every centre (feature
        units; 3x the cluster's RMS spread) is a transient, not a glider.
    """

    centers: np.ndarray
    kind: np.ndarray
    sizes: np.ndarray
    r_scale: float
    features_centers: np.ndarray
    radius: np.ndarray

    def assign(self, rel) -> np.ndarray:
        """Cluster index of each (|r|, theta, phi) sample [S, 3] -> [S], -1 if
        it lies outside every cluster's radius."""
        f = _features(np.reshape(rel, (-1, 3)), self.r_scale)
        dist = np.sqrt(((f[:, None] - self.features_centers[None]) ** 2).sum(-1))
        j = np.argmin(dist, axis=1)
        return np.where(dist[np.arange(len(f)), j] <= self.radius[j], j, -1)

    def classify(self, rel) -> np.ndarray:
        """C1 / C2 (NONE for transients) of each sample [..., 3] -> [...]."""
        rel = np.asarray(rel, float)
        j = self.assign(rel)
        return np.where(j >= 0, self.kind[j], NONE).reshape(rel.shape[:-1])


def find_clusters(samples, k: int = 4, r_scale: float = 0.25, seed: int = 0) -> Clusters:
    """Cluster per-period (|r|, theta, phi) samples of bound pairs.

    Args:
      samples: [S, 3] (|r| W, theta, phi rad).
      k: number of k-means clusters (several per glider type, since the C1
        attractor has two mirror-related lobes in the paper).
      r_scale: |r| difference (W) that counts as much as a unit of
        cos/sin; 0.25 W separates the paper's glider separations.
    """
    from scipy.cluster.vq import kmeans2
    samples = np.asarray(samples, float)
    samples = samples[np.isfinite(samples).all(-1)]
    if len(samples) < k:
        raise ValueError(f"need at least {k} bound samples to find clusters, got {len(samples)}")
    f = _features(samples, r_scale)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # empty clusters are dropped below
        centers, lab = kmeans2(f, k, minit="++", seed=seed)
    keep = np.array([(lab == j).any() for j in range(k)])
    centers = centers[keep]
    lab = np.searchsorted(np.nonzero(keep)[0], lab)
    sizes = np.bincount(lab, minlength=len(centers))
    rel_c = np.array([[samples[lab == j, 0].mean(), circular_mean(samples[lab == j, 1]),
                       circular_mean(samples[lab == j, 2])] for j in range(len(centers))])
    kind = np.where(np.cos(rel_c[:, 2]) < 0, C1, C2)
    rms = np.array([np.sqrt(((f[lab == j] - centers[j]) ** 2).sum(-1).mean()) for j in range(len(centers))])
    return Clusters(rel_c, kind, sizes, r_scale, centers, 3 * np.maximum(rms, 1e-3))


def period_kinds(clusters: Clusters, rel, touched) -> np.ndarray:
    """[M, K] glider type of every period: C1/C2 if bound, else NONE."""
    rel, t = np.asarray(rel, float), np.asarray(touched, bool)
    ok = t & np.isfinite(rel).all(-1)
    out = np.full(t.shape, NONE, int)
    if ok.any():
        out[ok] = clusters.classify(rel[ok])
    return out


def steady_mask(touched, burn_in: int) -> np.ndarray:
    """[M, K] bound periods at or after ``burn_in`` (steady-state samples)."""
    t = np.asarray(touched, bool).copy()
    t[:, :burn_in] = False
    return t


def final_type(kinds, touched, window: int = 10) -> np.ndarray:
    """Glider type at the end of each trial [M]: the majority type over the
    last ``window`` periods if the pair is bound in all of them, else NONE.
    """
    kinds, t = np.asarray(kinds), np.asarray(touched, bool)
    last_k, last_t = kinds[:, -window:], t[:, -window:]
    n1 = ((last_k == C1) & last_t).sum(1)
    n2 = ((last_k == C2) & last_t).sum(1)
    out = np.where(n1 >= n2, C1, C2)
    return np.where(last_t.all(1), out, NONE)


@dataclasses.dataclass(frozen=True)
class TypedRuns(binding.Runs):
    """Bound runs (:class:`binding.Runs`) and each run's ``kind`` [R]: C1, C2 or NONE."""

    kind: np.ndarray


def typed_lifetimes(kinds, touched) -> TypedRuns:
    """Lifetimes of bound runs, each run typed by the majority of its periods
    (NONE when most of them are transients outside both clusters)."""
    runs = binding.bound_runs(touched)
    kinds = np.asarray(kinds)
    kind = np.array([np.bincount(kinds[m, s:s + n], minlength=3).argmax()
                     for m, s, n in zip(runs.lane, runs.start, runs.length)], dtype=int)
    return TypedRuns(runs.lane, runs.start, runs.length, runs.censored, kind)


def glider_runs(touched, min_periods: int = 30) -> list[tuple[int, int, int]]:
    """Each lane's longest bound run if it lasts at least ``min_periods``
    periods (the paper keeps gliders that survive more than 30 cycles), as
    (lane, first period, length), in lane order."""
    runs = binding.bound_runs(touched)
    best: dict[int, tuple[int, int]] = {}
    for m, s, n in zip(runs.lane, runs.start, runs.length):
        if n >= min_periods and n > best.get(m, (0, 0))[1]:
            best[int(m)] = (int(s), int(n))
    return [(m, s, n) for m, (s, n) in sorted(best.items())]


def glider_tracks(com, touched, min_periods: int = 30) -> np.ndarray:
    """Per-period tracks of gliders (see :func:`glider_runs`).

    Args:
      com: [M, K, D] per-period values, e.g. the pair centre of mass (D = 2)
        or (x, y, heading) (D = 3); every column is kept.
      touched: [M, K] bool.

    Returns:
      [G, L, D] tracks, NaN-padded to the longest.
    """
    com = np.asarray(com, float)
    runs = glider_runs(touched, min_periods)
    if not runs:
        return np.zeros((0, 0, com.shape[-1]))
    out = np.full((len(runs), max(n for _, _, n in runs), com.shape[-1]), np.nan)
    for g, (m, s, n) in enumerate(runs):
        out[g, :n] = com[m, s:s + n]
    return out


@dataclasses.dataclass(frozen=True)
class SteadyPairs:
    """Steady-state |r| (W) of the pairs bound in every one of the last periods: the mean, the s.d. over
    pairs, the s.e.m. (NaN below two pairs), the pairs and each one's mean [G]."""

    mean: float
    std: float
    sem: float
    pairs: int
    per_pair: np.ndarray


def steady_separation(rel, touched, window: int = 20) -> SteadyPairs:
    """Steady-state |r| of pairs bound in every one of the last ``window`` periods (:class:`SteadyPairs`)."""
    rel, t = np.asarray(rel, float), np.asarray(touched, bool)
    sel = t[:, -window:].all(1)
    per = rel[sel, -window:, 0].mean(1) if sel.any() else np.zeros(0)
    n = len(per)
    return SteadyPairs(float(per.mean()) if n else np.nan, float(per.std(ddof=1)) if n > 1 else np.nan,
                       float(per.std(ddof=1) / np.sqrt(n)) if n > 1 else np.nan, n, per)


@dataclasses.dataclass(frozen=True)
class ConvergedPairs:
    """Steady |r| (W) of pairs read where each converged (:func:`converged_separation`): the pairs that
    converged, each one's steady |r| [G] and the period it was read at [G] (the end of its window), and
    the pairs bound through some pair of windows but never converged within the periods run."""

    per_pair: np.ndarray
    at_period: np.ndarray
    unconverged: int

    @property
    def pairs(self) -> int:
        return len(self.per_pair)


def converged_separation(rel, touched, window: int = 10, tol: float = 0.01) -> ConvergedPairs:
    """Each pair's steady |r| read where it has converged: the first period t (t >= 2 ``window``) at which
    the mean |r| over periods [t - window, t) differs from the mean over [t - 2 window, t - window) by less
    than ``tol`` (W), the pair bound in every one of those 2 ``window`` periods; its steady |r| is the later
    window's mean. ``rel`` [M, K, 3] once per period (|r| first), ``touched`` [M, K]."""
    rel, t = np.asarray(rel, float), np.asarray(touched, bool)
    M, K = t.shape
    if window < 1 or tol <= 0:
        raise ValueError(f"converged_separation: window >= 1 and tol > 0 expected, got {window} and {tol}")
    r = rel[..., 0]
    per, at, unconverged = [], [], 0
    for m in range(M):
        tried = False
        for end in range(2 * window, K + 1):
            if not t[m, end - 2 * window:end].all():
                continue
            tried = True
            later, earlier = r[m, end - window:end].mean(), r[m, end - 2 * window:end - window].mean()
            if abs(later - earlier) < tol:
                per.append(later)
                at.append(end)
                break
        else:
            unconverged += tried
    return ConvergedPairs(np.asarray(per, float), np.asarray(at, np.int64), int(unconverged))


def sign_runs(phi) -> np.ndarray:
    """Lengths (periods) of the runs in which phi - 180 deg keeps its sign.

    Args:
      phi: [K] relative orientation once per period (rad), NaN = missing
        (a missing sample ends a run).

    Returns:
      [R] run lengths. The first and last runs are censored by the track's
      ends; :func:`sign_persistence` reports them as such.
    """
    dev = np.angle(np.exp(1j * (np.asarray(phi, float) - np.pi)))
    s = np.where(np.isfinite(dev), np.sign(dev), 0)
    runs, cur, prev = [], 0, 0
    for v in s:
        if v != 0 and v == prev:
            cur += 1
        else:
            if cur:
                runs.append(cur)
            cur = 1 if v != 0 else 0
        prev = v
    if cur:
        runs.append(cur)
    return np.array(runs, int)


@dataclasses.dataclass(frozen=True)
class SignPersistence:
    """How gliders keep the sign of phi - 180 deg: sign changes per glider-period, the mean run length
    (periods, censored runs included, so a lower bound), the fraction of gliders holding it (longest run
    >= the hold or the whole track), and per glider [G] its longest run and its track's length."""

    flips_per_period: float
    mean_run: float
    held: float
    longest: np.ndarray
    length: np.ndarray


def sign_persistence(rel_tracks, hold: int = 50) -> SignPersistence:
    """How long gliders keep the sign of phi - 180 deg (the paper: the sign
    sets the direction of travel and stays).

    Args:
      rel_tracks: [G, L, 3] per-period (|r|, theta, phi) of G gliders (NaN-padded).
      hold: periods a glider must keep its sign to count as holding it.

    Returns: :class:`SignPersistence`.
    """
    rel_tracks = np.asarray(rel_tracks, float)
    longest, lengths, flips, runs_all = [], [], 0, []
    for tr in rel_tracks:
        ph = tr[:, 2]
        ok = np.isfinite(ph)
        if ok.sum() < 2:
            continue
        runs = sign_runs(ph[ok])
        runs_all += list(runs)
        flips += len(runs) - 1
        longest.append(int(runs.max()))
        lengths.append(int(ok.sum()))
    longest, lengths = np.array(longest), np.array(lengths)
    n = int(lengths.sum())
    return SignPersistence(flips / max(n - len(lengths), 1) if len(lengths) else np.nan,
                           float(np.mean(runs_all)) if runs_all else np.nan,
                           float(np.mean((longest >= hold) | (longest == lengths))) if len(lengths) else np.nan,
                           longest, lengths)


@dataclasses.dataclass(frozen=True)
class Repeatability:
    """Median over gliders of the spread of their once-per-period |r| (W, s.d.), theta and phi (rad,
    circular s.d.); NaN without a glider of three samples."""

    r: float
    theta: float
    phi: float


def repeatability(rel_tracks) -> Repeatability:
    """How tightly the once-per-period (|r|, theta, phi) of a glider repeats
    (a limit cycle repeats exactly): per glider the standard deviation of |r|
    (W) and the circular standard deviations of theta and phi (rad),
    then the median over gliders."""
    out = {"r": [], "theta": [], "phi": []}
    for tr in np.asarray(rel_tracks, float):
        tr = tr[np.isfinite(tr).all(-1)]
        if len(tr) < 3:
            continue
        out["r"].append(tr[:, 0].std())
        for k, name in ((1, "theta"), (2, "phi")):
            R = np.abs(np.exp(1j * tr[:, k]).mean())
            out[name].append(np.sqrt(-2 * np.log(min(max(R, 1e-12), 1.0))))  # R rounds above 1 for a constant angle
    return Repeatability(*(float(np.median(out[k])) if out[k] else np.nan for k in ("r", "theta", "phi")))


def steady_gliders(touched, burn_in: int) -> np.ndarray:
    """[M] bool: pairs bound (touching) in every period after ``burn_in`` of their [M, K] record.

    The gliders of the fidelity, twin and time-step studies (a fixed window, so that runs of one
    length compare). The validation page and ``smx report`` count instead each lane's longest bound
    run of at least N periods (the paper's "> 30 cycles"; ``report.ReportOptions``), which also
    admits pairs that bind late or part before the end."""
    return np.asarray(touched)[:, burn_in:].all(1)


@dataclasses.dataclass(frozen=True)
class GliderQuantities:
    """What the time-step study compares: net speed (mean over gliders, W/period), direction persistence
    and beta (centred MSD over delays 5-15, no bootstrap)."""

    net_speed: float
    persistence: float
    beta: float


def glider_transport(tracks) -> GliderQuantities:
    """Net speed (mean over gliders, W/period), direction persistence and beta (centred MSD over
    delays 5-15, no bootstrap) of gliders' [G, K, 2] centre tracks: the quantities the time-step
    study compares between steps."""
    return GliderQuantities(float(np.nanmean(_transport.net_speed(tracks))),
                            _transport.direction_persistence(tracks),
                            _transport.msd_exponent(tracks, lag_range=(5, 15), centered=True, n_boot=0).beta)


@dataclasses.dataclass(frozen=True)
class GlideSummary:
    """The glider quantities of pairs' per-period tracks (:func:`glide_summary`), unrounded.

    ``gliders`` and ``bound_end`` always; the rest is None without gliders, and the ``C1_`` fields are None
    without C1 (anti-aligned) gliders. Units: W per period for speeds and steps, degrees for angles,
    periods for runs; ``net_speed_interval`` is the 95 % bootstrap interval over gliders (NaN below 3).
    """

    gliders: int
    bound_end: int
    net_speed_W_per_period: float | None = None
    net_speed_interval: tuple[float, float] | None = None
    mean_step_W_per_period: float | None = None
    persistence: float | None = None
    median_turn_deg: float | None = None
    straightness20: float | None = None
    beta: float | None = None
    beta_err: float | None = None
    beta_lags: tuple[int, int] | None = None
    sign_flips_per_period: float | None = None
    sign_mean_run: float | None = None
    sign_held_frac: float | None = None
    sign_hold_periods: int | None = None
    repeat: Repeatability | None = None
    C2_fraction: float | None = None
    C1_gliders: int | None = None
    steady_r_W: float | None = None
    C1_phi_dev_deg: float | None = None  # symmetry breaking: 0 for a symmetric C1
    C1_sign_held_frac: float | None = None
    C1_straightness20: float | None = None

    def as_json(self) -> dict:
        """The fidelity and twin benchmarks' JSON record: the quantities measured (None ones left out)."""
        out = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if v is None:
                continue
            if isinstance(v, Repeatability):
                v = dataclasses.asdict(v)
            elif isinstance(v, tuple):
                v = list(v)
            out[f.name] = v
        return out


def glide_summary(com, rel, touched, burn_in: int) -> GlideSummary:
    """The glider quantities of pairs' per-period tracks, as docs/fidelity.md
    and docs/twin.md report them.

    A glider here is a pair bound (touching) in every period after
    ``burn_in``; its quantities are taken over those periods.

    Args:
      com: [M, K, 2] the pair's centre at each period end (W).
      rel: [M, K, 3] (|r| in W, theta, phi) at each period end.
      touched: [M, K] bool, the pair touched in that period.
      burn_in: periods skipped before a pair must stay bound.

    Returns:
      :class:`GlideSummary`: gliders and pairs bound at the end; for the gliders: net speed (with a
      95 % bootstrap interval over gliders) and mean step (W/period), direction persistence, median change of
      direction (deg), straightness over 20 periods, beta over delays 5-15
      (centred MSD, bootstrap sd), sign persistence of phi - 180 deg,
      repeatability of (|r|, phi), the C2 (aligned) fraction of samples,
      and for C1 gliders their median |phi - 180 deg|.
    """
    periods = touched.shape[1]
    glide = steady_gliders(touched, burn_in)
    g_com, g_rel = com[glide, burn_in:], rel[glide, burn_in:]
    counts = dict(gliders=int(glide.sum()), bound_end=int(touched[:, -1].sum()))
    if glide.sum() == 0:
        return GlideSummary(**counts)
    ns = _transport.net_speed(g_com)
    beta = _transport.msd_exponent(g_com, lag_range=(5, min(15, periods - burn_in - 2)), centered=True)
    hold = min(50, periods - burn_in)
    sp = sign_persistence(g_rel, hold=hold)
    aligned = np.cos(g_rel[..., 2]) > 0
    c1 = ~aligned.any(1)
    _, ns_lo, ns_hi, _ = _transport.bootstrap_interval(ns)
    c1_parts = {}
    if c1.any():
        dev = np.degrees(np.abs(np.angle(np.exp(1j * (g_rel[c1, :, 2] - np.pi)))))
        c1_parts = dict(C1_phi_dev_deg=float(np.median(dev)),
                        C1_sign_held_frac=sign_persistence(g_rel[c1], hold=hold).held,
                        C1_straightness20=_transport.straightness(g_com[c1], 20))
    return GlideSummary(
        **counts,
        net_speed_W_per_period=float(np.nanmean(ns)),
        net_speed_interval=(float(ns_lo), float(ns_hi)),
        mean_step_W_per_period=float(np.nanmean(_transport.step_lengths(g_com))),
        persistence=_transport.direction_persistence(g_com),
        median_turn_deg=float(np.degrees(_transport.median_direction_change(g_com))),
        straightness20=_transport.straightness(g_com, 20),
        beta=beta.beta, beta_err=beta.err, beta_lags=tuple(beta.lag_range),
        sign_flips_per_period=sp.flips_per_period, sign_mean_run=sp.mean_run,
        sign_held_frac=sp.held, sign_hold_periods=hold,
        repeat=repeatability(g_rel),
        C2_fraction=float(aligned.mean()),
        C1_gliders=int(c1.sum()),
        steady_r_W=float(np.nanmean(g_rel[..., 0])),
        **c1_parts)
