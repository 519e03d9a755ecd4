"""Transport of tracks sampled once per gait period: MSD, exponent beta, speed.

Tracks are ``[M, K, 2]`` positions (any length unit) with NaN where a track
has no sample (before it starts, after it ends, or occluded). Every function
here is numpy only.
"""

from __future__ import annotations

import dataclasses

import numpy as np


def _as_tracks(xy) -> np.ndarray:
    """[M, K, D] float tracks; a single [K, D] track becomes [1, K, D]."""
    xy = np.asarray(xy, float)
    return xy[None] if xy.ndim == 2 else xy


def msd(xy, max_lag: int | None = None, centered: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean-square displacement vs delay, pooled over tracks and time origins.

    Args:
      xy: [M, K, 2] positions once per period (NaN = missing).
      max_lag: largest delay in periods (default K - 1).
      centered: subtract the squared mean displacement, the paper's
        <sigma^2> = <x^2> - <x>^2 (the plain MSD otherwise).

    Returns:
      lags [L] (periods), msd [L], counts [L] (displacements averaged).
    """
    xy = _as_tracks(xy)
    k = xy.shape[1]
    max_lag = k - 1 if max_lag is None else min(max_lag, k - 1)
    lags = np.arange(1, max_lag + 1)
    out = np.full(len(lags), np.nan)
    counts = np.zeros(len(lags), int)
    for i, lag in enumerate(lags):
        d = (xy[:, lag:] - xy[:, :-lag]).reshape(-1, xy.shape[-1])
        d = d[np.isfinite(d).all(-1)]
        counts[i] = len(d)
        if len(d):
            out[i] = (d ** 2).sum(-1).mean()
            if centered:
                out[i] -= (d.mean(0) ** 2).sum()
    return lags, out, counts


def fit_exponent(lags, values, lag_range) -> tuple[float, float, float]:
    """Least-squares slope of log(values) vs log(lags) over ``lag_range``.

    Returns:
      (beta, standard error of the slope, prefactor), NaN if < 3 points.
    """
    lags, values = np.asarray(lags, float), np.asarray(values, float)
    lo, hi = lag_range
    sel = (lags >= lo) & (lags <= hi) & np.isfinite(values) & (values > 0)
    if sel.sum() < 3:
        return np.nan, np.nan, np.nan
    x, y = np.log(lags[sel]), np.log(values[sel])
    slope, icpt = np.polyfit(x, y, 1)
    resid = y - (slope * x + icpt)
    se = np.sqrt((resid ** 2).sum() / (len(x) - 2) / ((x - x.mean()) ** 2).sum())
    return float(slope), float(se), float(np.exp(icpt))


@dataclasses.dataclass(frozen=True)
class Exponent:
    """MSD exponent beta and how it was measured.

    Attributes:
      beta: slope of log MSD vs log delay over ``lag_range`` (periods).
      err: its uncertainty: the standard deviation over bootstrap resamples
        of whole tracks when there are >= 5 tracks, else the regression
        standard error (``method`` says which).
      tracks: number of tracks used.
      lo, hi: the 95 % percentile interval over the bootstrap resamples of
        whole tracks (NaN with fewer than 5 tracks).
      centered: whether the MSD was the paper's centred form.
    """

    beta: float
    err: float
    tracks: int
    lag_range: tuple[int, int]
    method: str
    lo: float = np.nan
    hi: float = np.nan
    centered: bool = False


def msd_exponent(xy, lag_range=(5, 15), centered: bool = True, n_boot: int = 200, seed: int = 0) -> Exponent:
    """beta from the long-delay slope of the MSD, with an uncertainty.

    The defaults are the paper's: the centred MSD <x^2> - <x>^2 fitted at
    long delays (5 to 15 periods, within the > 30-period tracks it keeps).

    Args:
      xy: [M, K, 2] tracks (NaN = missing).
      lag_range: delays (periods) over which the slope is fitted.
      centered: see :func:`msd`.
      n_boot: bootstrap resamples of whole tracks.
    """
    xy = _as_tracks(xy)
    hi = int(lag_range[1])
    lags, m, _ = msd(xy, hi, centered)
    beta, se, _ = fit_exponent(lags, m, lag_range)
    if len(xy) < 5:
        return Exponent(beta, se, len(xy), tuple(lag_range), "regression", centered=centered)
    rng = np.random.default_rng(seed)
    boots = []
    for _ in range(n_boot):
        idx = rng.integers(0, len(xy), len(xy))
        b = fit_exponent(*msd(xy[idx], hi, centered)[:2], lag_range)[0]
        if np.isfinite(b):
            boots.append(b)
    err = float(np.std(boots, ddof=1)) if len(boots) > 1 else np.nan
    lo, up = (np.percentile(boots, [2.5, 97.5]) if len(boots) > 1 else (np.nan, np.nan))
    return Exponent(beta, err, len(xy), tuple(lag_range), "bootstrap over tracks", float(lo), float(up), centered)


def bootstrap_interval(values, stat=np.mean, level: float = 0.95, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float, int]:
    """Percentile bootstrap interval of ``stat`` over independent units.

    Args:
      values: [N] one number per unit (a glider, a trial); NaNs dropped.
      stat: statistic of a 1-D sample.

    Returns:
      (estimate, lo, hi, n); NaN interval with fewer than 3 units.
    """
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return np.nan, np.nan, np.nan, 0
    est = float(stat(v))
    if len(v) < 3:
        return est, np.nan, np.nan, len(v)
    rng = np.random.default_rng(seed)
    boots = np.array([stat(v[rng.integers(0, len(v), len(v))]) for _ in range(n_boot)])
    a = (1 - level) / 2 * 100
    lo, hi = np.percentile(boots, [a, 100 - a])
    return est, float(lo), float(hi), len(v)


def step_lengths(xy) -> np.ndarray:
    """[M, K-1] distance moved in each period (NaN where a sample is missing)."""
    xy = np.asarray(xy, float)
    return np.linalg.norm(np.diff(xy, axis=-2), axis=-1)


def turning(heading) -> np.ndarray:
    """[M, K-1] change of heading per period (rad, wrapped to (-pi, pi])."""
    h = np.asarray(heading, float)
    return np.angle(np.exp(1j * np.diff(h, axis=-1)))


def track_turning(xy) -> np.ndarray:
    """[M, K-2] signed turn of the direction of travel per period (rad).

    Positive is counter-clockwise; NaN where the track stands still or a
    sample is missing. Mirror-image trajectories have opposite turning.
    """
    d = np.diff(np.asarray(xy, float), axis=-2)
    ang = np.arctan2(d[..., 1], d[..., 0])
    return np.angle(np.exp(1j * np.diff(ang, axis=-1)))


# ------------------------------------------------------ straight gliding
# The once-per-period track of a glider that glides is a line of equal
# steps; one that shuttles or zig-zags has steps of the same length whose
# direction flips. A mean step length cannot tell them apart; these can.

def _steps(xy):
    d = np.diff(np.asarray(xy, float), axis=-2)
    return d, np.linalg.norm(d, axis=-1)


def direction_persistence(xy) -> float:
    """Mean cosine between successive once-per-period steps, pooled over
    tracks: 1 for a straight line, 0 for a random walk, -1 for a shuttle
    that reverses every period. NaN where there are no two steps."""
    d, n = _steps(xy)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = (d[..., 1:, :] * d[..., :-1, :]).sum(-1) / (n[..., 1:] * n[..., :-1])
    cos = cos[np.isfinite(cos)]
    return float(cos.mean()) if cos.size else np.nan


def median_direction_change(xy) -> float:
    """Median absolute change of the direction of travel from one period to
    the next (rad), pooled over tracks."""
    t = np.abs(track_turning(xy))
    t = t[np.isfinite(t)]
    return float(np.median(t)) if t.size else np.nan


def straightness(xy, window: int = 20) -> float:
    """Net displacement over ``window`` periods divided by the once-per-period
    path length over them, averaged over every complete window of every
    track (1: a straight line)."""
    xy = _as_tracks(xy)
    _, n = _steps(xy)
    vals = []
    for tr, st in zip(xy, n):
        for s in range(0, tr.shape[0] - window):
            seg = tr[s:s + window + 1]
            if not np.isfinite(seg).all():
                continue
            path = st[s:s + window].sum()
            if path > 0:
                vals.append(np.linalg.norm(seg[-1] - seg[0]) / path)
    return float(np.mean(vals)) if vals else np.nan


def net_speed(xy) -> np.ndarray:
    """[M] net gliding speed per track: |last - first| / periods between them
    (units per period), over the track's finite samples; NaN if < 2.
    A zig-zag or a shuttle has a large mean step but a small net speed."""
    xy = _as_tracks(xy)
    out = np.full(len(xy), np.nan)
    for g, tr in enumerate(xy):
        ok = np.flatnonzero(np.isfinite(tr).all(-1))
        if len(ok) >= 2:
            out[g] = np.linalg.norm(tr[ok[-1]] - tr[ok[0]]) / (ok[-1] - ok[0])
    return out


def glide_speed(xy) -> np.ndarray:
    """[M] gliding speed per track along its mean direction of travel: the
    least-squares slope of the displacement projected on the unit vector from
    the first to the last finite sample, vs period (units per period; NaN if
    < 3 samples). Unlike the mean step it is ~0 for a shuttle; unlike
    :func:`net_speed` it uses every sample, not only the two ends."""
    xy = _as_tracks(xy)
    out = np.full(len(xy), np.nan)
    for g, tr in enumerate(xy):
        ok = np.flatnonzero(np.isfinite(tr).all(-1))
        if len(ok) < 3:
            continue
        d = tr[ok[-1]] - tr[ok[0]]
        n = np.linalg.norm(d)
        if n == 0:
            out[g] = 0.0
            continue
        proj = (tr[ok] - tr[ok[0]]) @ (d / n)
        out[g] = float(np.polyfit(ok.astype(float), proj, 1)[0])
    return out


def signed_turn_per_track(angles) -> np.ndarray:
    """[M] mean signed change per period of an angle track (rad; counter-
    clockwise positive), e.g. a glider's body heading; NaN where a track has
    no two consecutive samples."""
    t = turning(np.atleast_2d(np.asarray(angles, float)))
    with np.errstate(invalid="ignore"):
        return np.array([np.nanmean(r) if np.isfinite(r).any() else np.nan for r in t])


@dataclasses.dataclass(frozen=True)
class LoneRobot:
    """A lone robot's transport (:func:`lone_robot`), per cycle in the unit asked for; None: not measured
    (no period, no heading, one sample per cycle)."""

    net_W_per_cycle: float
    step_W_per_cycle: float
    beta: float
    beta_err: float
    speed_W_per_s: float | None = None
    heading_deg_per_cycle: float | None = None
    abs_heading_deg_per_cycle: float | None = None
    slip_per_edge_W: float | None = None
    slip_per_edge_max_W: float | None = None

    _ORDER = ("net_W_per_cycle", "step_W_per_cycle", "speed_W_per_s", "beta", "beta_err", "heading_deg_per_cycle",
              "abs_heading_deg_per_cycle", "slip_per_edge_W", "slip_per_edge_max_W")

    def as_json(self) -> dict:
        """As a page's JSON records it: the measured quantities only, in the order they are measured."""
        return {k: getattr(self, k) for k in self._ORDER if getattr(self, k) is not None}


def lone_robot(xy, heading=None, period_s: float | None = None, *, samples_per_cycle: int = 1,
               skip_cycles: int = 0, unit: float = 1.0) -> "LoneRobot":
    """A lone robot's transport: the package's one measure of lone drift (validation, reports, benchmarks).

    Args:
      xy: [T * s + 1, 2] body centre sampled ``s = samples_per_cycle`` times per gait cycle, the start
        first (s = 4: at every quarter, i.e. after each arm move and its dwell).
      heading: [T * s + 1] body heading (rad), or None.
      period_s: the gait period (s), for the speed; None leaves it out.
      skip_cycles: cycles left out at the start (the start-up transient).
      unit: the length unit of the results in ``xy``'s units (the body length W: results in W).

    Returns a :class:`LoneRobot`, over the cycles after ``skip_cycles``, per cycle and in ``unit``:
      ``net_W_per_cycle``: |end − start| / cycles (a robot that jiggles in place has a mean step but
      no drift); ``step_W_per_cycle``: the mean step between once-per-cycle samples; ``speed_W_per_s``:
      the net drift over the period; ``beta``, ``beta_err``: the plain MSD exponent of the once-per-cycle
      track over delays 5..min(25, T/3 + 3) (NaN for fewer than 3 delays); ``heading_deg_per_cycle``
      and ``abs_heading_deg_per_cycle``: the mean signed and absolute heading turn per cycle; with
      ``s > 1``, ``slip_per_edge_W`` and ``slip_per_edge_max_W``: the mean and largest displacement
      between consecutive samples (s = 4: what one arm move and its start and stop kicks slip the body);
      the quantities not measured are None.
    """
    s = int(samples_per_cycle)
    if s < 1 or skip_cycles < 0:
        raise ValueError("samples_per_cycle must be >= 1 and skip_cycles >= 0")
    xy = np.asarray(xy, float)[s * skip_cycles:]
    cycles = xy[::s]
    if len(cycles) < 2:
        raise ValueError(f"a lone robot's track needs two cycle ends after {skip_cycles} skipped cycles")
    net = float(net_speed(cycles)[0] / unit)
    ex = msd_exponent(cycles, (5, min(25, len(cycles) // 3 + 3)), centered=False)  # one track: plain MSD
    out = {"net_W_per_cycle": net, "step_W_per_cycle": float(np.nanmean(step_lengths(cycles)) / unit)}
    if period_s is not None:
        out["speed_W_per_s"] = net / period_s
    out.update(beta=ex.beta, beta_err=ex.err)
    if heading is not None:
        turn = turning(np.asarray(heading, float)[s * skip_cycles::s])
        out["heading_deg_per_cycle"] = float(np.degrees(np.mean(turn)))
        out["abs_heading_deg_per_cycle"] = float(np.degrees(np.mean(np.abs(turn))))
    if s > 1:
        edges = step_lengths(xy) / unit
        out["slip_per_edge_W"] = float(edges.mean())
        out["slip_per_edge_max_W"] = float(edges.max())
    return LoneRobot(**out)
