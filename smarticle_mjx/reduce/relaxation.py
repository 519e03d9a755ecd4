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

import numpy as np

from .. import configs as C
from ..labels import BAD_STATUS
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


def _third_touch(touched: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """[K, P]: a robot of pair p touched a robot outside the pair in period k."""
    per_robot = _partners(touched, pairs, int(pairs.max()) + 1)
    own = touched.astype(int)
    return (per_robot[:, pairs[:, 0]] - own > 0) | (per_robot[:, pairs[:, 1]] - own > 0)


def trial_episodes(poses, touched, start, left_plate=None, periods_run=None, body_length: float = 0.05,
                   apart_W: float = 2.0) -> list[dict]:
    """Every bound-and-apart episode of one trial.

    Args:
      poses: [K, N, 5] poses at the end of each period (NaN after an early stop).
      touched: [K, P] bool.
      start: [N, 5] start poses.
      left_plate: [N] first period off the plate (0: never); None: all stayed.
      periods_run: periods simulated (default K).
      body_length: W in metres.
      apart_W: closest a third robot's centre may come (W).

    Returns:
      one dict per episode: pair (i, j), start (0-based first period),
      lifetime, censored, distance_W, contour_W, kind, mean_cos_phi,
      track [lifetime + 1, 2] (W).
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
    third = _third_touch(touched, pairs)
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
        for s, length, cens in zip(runs["start"], runs["length"], runs["censored"]):
            s, length = int(s), int(length)
            prev = start if s == 0 else poses[s - 1]
            seg = np.concatenate([prev[None], poses[s:s + length]])  # [L+1, N, 5]
            track = (seg[:, i, :2] + seg[:, j, :2]) / 2 / body_length
            steps = np.linalg.norm(np.diff(track, axis=0), axis=1)
            _, _, phi = C.relative_coordinates(poses[s:s + length, i], poses[s:s + length, j], body_length)
            mc = float(np.mean(np.cos(phi)))
            out.append({"pair": (int(i), int(j)), "start": s, "lifetime": length,
                        "censored": bool(cens and k == k_all),
                        "distance_W": float(np.linalg.norm(track[-1] - track[0])),
                        "contour_W": float(steps.sum()), "kind": C1 if mc < 0 else C2, "mean_cos_phi": mc,
                        "track": track})
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


def analyse(data: dict, min_periods: int = 100, apart_W: float = 2.0, min_episode: int = 2,
            level: float = 0.95) -> dict:
    """The relaxation study's numbers from :func:`smarticle_mjx.store.read_relax` output.

    Args:
      min_periods: shortest episode counted as a glider (the lab: 100 periods).
      apart_W: see :func:`trial_episodes`.
      min_episode: shortest episode kept for the lifetime-contour scatter.

    Returns:
      dict: trials, valid, gliders (trials that formed one) with the exact
      interval, per-trial glider rows, distance statistics, the lifetime vs
      contour-length fit over every episode, typed lifetimes, relaxation
      times, robots that left the plate.
    """
    if min_periods < 1 or min_episode < 1 or not apart_W > 0:
        raise ValueError("min_periods and min_episode must be >= 1 and apart_W > 0")
    W = float(data["body_length"])
    periods = int(data["periods"])
    ok_status = (np.asarray(data["status"]) & int(BAD_STATUS)) == 0
    valid = np.asarray(data["valid"], bool) & ok_status
    episodes, per_trial, relax_t = [], [], []
    for t in np.flatnonzero(valid):
        eps = trial_episodes(data["poses"][t], data["touched"][t], data["start_poses"][t], data["left_plate"][t],
                             data["periods_run"][t], W, apart_W)
        for e in eps:
            e["trial"] = int(data["trial"][t])
        episodes += [e for e in eps if e["lifetime"] >= min_episode]
        gl = [e for e in eps if e["lifetime"] >= min_periods]
        best = max(gl, key=lambda e: e["lifetime"]) if gl else None
        rt, crowded = relaxation_time(data["touched"][t], data["periods_run"][t])
        per_trial.append({"trial": int(data["trial"][t]), "gliders": len(gl), "glider": best,
                          "relaxation_periods": rt, "crowded_at_end": crowded,
                          "periods_run": int(data["periods_run"][t])})
        relax_t.append(rt)
    n = int(valid.sum())
    k = sum(1 for r in per_trial if r["glider"] is not None)
    lo, hi = binding.binomial_interval(k, n, level) if n else (np.nan, np.nan)
    gl = [r["glider"] for r in per_trial if r["glider"] is not None]
    dist = np.array([g["distance_W"] for g in gl])
    out = {"trials": int(len(data["valid"])), "valid": n, "emerged": k,
           "fraction": k / n if n else float("nan"), "interval": (float(lo), float(hi)),
           "min_periods": min_periods, "apart_W": apart_W, "periods": periods,
           "per_trial": per_trial, "episodes": episodes}
    out["distance"] = _mean_sem(dist)
    out["glider_contour"] = _mean_sem(np.array([g["contour_W"] for g in gl]))
    out["glider_lifetime"] = _mean_sem(np.array([g["lifetime"] for g in gl], float))
    out["glider_censored"] = int(sum(g["censored"] for g in gl))
    out["glider_kinds"] = {C1: sum(g["kind"] == C1 for g in gl), C2: sum(g["kind"] == C2 for g in gl)}
    out["fit"] = lifetime_contour_fit(episodes)
    out["typed"] = typed_lifetimes(episodes)
    rt = np.array(relax_t, float)
    out["relaxation_periods"] = {"median": float(np.median(rt)) if len(rt) else float("nan"),
                                 "q25": float(np.percentile(rt, 25)) if len(rt) else float("nan"),
                                 "q75": float(np.percentile(rt, 75)) if len(rt) else float("nan"),
                                 "crowded_at_end": int(sum(r["crowded_at_end"] for r in per_trial))}
    lp = np.asarray(data["left_plate"])[valid]
    out["left_plate"] = {"robots": int((lp > 0).sum()), "trials": int((lp > 0).any(1).sum())}
    out["stopped_early"] = int((np.asarray(data["periods_run"])[valid] < periods).sum())
    return out


def _mean_sem(v: np.ndarray) -> dict:
    v = np.asarray(v, float)
    if len(v) == 0:
        return {"n": 0, "mean": float("nan"), "sem": float("nan"), "median": float("nan")}
    sem = float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else float("nan")
    return {"n": int(len(v)), "mean": float(v.mean()), "sem": sem, "median": float(np.median(v))}


def lifetime_contour_fit(episodes: list[dict]) -> dict:
    """Least-squares line contour = slope * lifetime + intercept over every
    episode, with Pearson's r and its p-value (the paper's SI reports a
    linear correlation)."""
    if len(episodes) < 3:
        return {"n": len(episodes), "slope": float("nan"), "intercept": float("nan"), "r": float("nan"),
                "p": float("nan"), "slope_stderr": float("nan")}
    from scipy.stats import linregress
    x = np.array([e["lifetime"] for e in episodes], float)
    y = np.array([e["contour_W"] for e in episodes], float)
    if np.ptp(x) == 0:
        return {"n": len(x), "slope": float("nan"), "intercept": float("nan"), "r": float("nan"),
                "p": float("nan"), "slope_stderr": float("nan")}
    f = linregress(x, y)
    return {"n": int(len(x)), "slope": float(f.slope), "intercept": float(f.intercept), "r": float(f.rvalue),
            "p": float(f.pvalue), "slope_stderr": float(f.stderr)}


def typed_lifetimes(episodes: list[dict]) -> dict:
    """Lifetimes of C1 and C2 episodes (mean, median, censored count) and a
    one-sided Mann-Whitney test that C1 lives longer."""
    out = {}
    for kind in (C1, C2):
        v = np.array([e["lifetime"] for e in episodes if e["kind"] == kind], float)
        out[kind] = {**_mean_sem(v), "censored": int(sum(e["censored"] for e in episodes if e["kind"] == kind))}
    a = [e["lifetime"] for e in episodes if e["kind"] == C1]
    b = [e["lifetime"] for e in episodes if e["kind"] == C2]
    if a and b:
        from scipy.stats import mannwhitneyu
        out["p_c1_longer"] = float(mannwhitneyu(a, b, alternative="greater").pvalue)
    else:
        out["p_c1_longer"] = float("nan")
    return out
