"""Observables: what a fitted value means in quantities read off the tracks.

A fitted effect is a parameter of *our* model. When the robot that made the
data differs from the model in ways the model cannot express (another servo
law, another arm shape), the fitted value absorbs part of that difference:
a 30 ms dead time on top of a servo that is slower than ours fits as less
than 30 ms, a plate tilt fits as whatever tilt gives *our* robot the
measured drift. A statistical interval says nothing about that. What can be
checked is whether the fitted model reproduces the measured quantities the
effect moves, and how much of each the effect itself accounts for:

* **arm delay** (ms): the time from the command's switch to the arm
  crossing its midpoint, averaged over every swing of every arm; it moves
  with a servo lag, a dead time, a slower or weaker servo. The average is
  taken over groups of swings
  of one arm in one direction (per trial and robot), each group weighted
  alike, with the spread measured within groups: an arm read with a
  constant angle error crosses its midpoint early on the way up and late
  on the way down by the same time, which the pairing cancels, where the
  plain average kept it in its standard error (20x larger, which hid
  delays from the delay test);
* **phase lead** (periods): how far robot i's arm swings run ahead of robot
  0's, for robots that share robot 0's gait; it moves with a phase offset
  between robots;
* **plate drift** (mm/s): the drift fixed to the plate with the body-frame
  step taken out (:mod:`calibrate.drift`); it moves with a plate tilt;
* **body step** (mm/cycle): the length of that body-frame step, and the
  **rotation** (deg/cycle) of lone robots: they move with friction, masses
  and the arms' shape;
* **arm rise** (ms): the time an
  arm takes from a quarter to three quarters of its swing, no command
  matched. A dead time leaves it; a first-order lag lengthens it, most on
  short swings; a slower servo lengthens it in proportion to the amplitude.
  It is reported beside the arm delay so that a lag and a dead time (which
  delay the midpoint alike) can be told apart on the tracks; the selection
  reads it only to choose between a lag and a dead time that both passed
  (:func:`servo_reading`).

All are computed the same way on measured tracks and on model tracks masked
like them (numpy only), each with a standard error from the spread over
swings (arm delay, phase lead) or from the drift regression.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .drift import group_key, robot_alone, group_drift
from .residuals import cycle_poses, masked

_GRID = 4096  # samples per period of the commanded (instant) gait, for its switch times
SETTLE = 0.5  # periods at the start of a track whose swings are left out
LABELS = {"arm_delay_ms": "arm delay (ms)", "phase_lead": "phase lead (periods)",
          "drift_mm_per_s": "plate drift (mm/s)", "body_step_mm": "body-frame step (mm/cycle)",
          "rotation_deg": "rotation (deg/cycle)",
          "arm_rise_ms": "arm rise, quarter to three quarters (ms)"}  # each observable's name in tables


def commanded(gait) -> np.ndarray:
    """[_GRID, 2] the command (rad): the gait at an instant servo, at the midpoints of ``_GRID`` equal steps
    of one period."""
    u = (np.arange(_GRID) + 0.5) / _GRID
    return np.asarray(gait.setpoints(u * gait.period(), 1e6), float)


def _command_switches(gait) -> list[tuple[int, int, float]]:
    """Where the commanded arms cross their midpoint: [(arm, direction, phase)], phase in [0, 1).

    The command is the gait at an instant servo (:func:`commanded`): its midpoint crossings are
    the switches (the quarter starts of a square gait).
    """
    sp = commanded(gait)  # [G, 2]
    out = []
    for k in range(2):
        s = np.sign(sp[:, k])
        for j in np.nonzero(s != np.roll(s, -1))[0]:
            if s[j] == 0:
                continue
            out.append((k, int(np.sign(s[(j + 1) % _GRID] - s[j])), float((j + 1) / _GRID % 1.0)))
    return out


def crossings(t: np.ndarray, angle: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Times and directions (+1 up, -1 down) at which an arm angle [F] crosses 0,
    by linear interpolation between consecutive tracked frames."""
    ok = np.isfinite(angle)
    tt, a = t[ok], angle[ok]
    if len(a) < 2:
        return np.zeros(0), np.zeros(0, int)
    j = np.nonzero((a[:-1] < 0) != (a[1:] < 0))[0]
    w = a[j] / (a[j] - a[j + 1])
    return tt[j] + w * (tt[j + 1] - tt[j]), np.where(a[j + 1] > a[j], 1, -1)


def swing_delays(t: np.ndarray, arms: np.ndarray, gait, settle: float = SETTLE) -> np.ndarray:
    """Delays (s) of one robot's arm swings [F frames, 2 arms] behind the command.

    Each crossing is matched to the nearest command switch of the same arm
    and direction, the delay wrapped into (-T/2, T/2]. Crossings within
    ``settle`` periods of the track's first frame are left out (the start
    transient: the arms start at rest, wherever the servo's state is).
    """
    return swing_delay_groups(t, arms, gait, settle)[0]


def swing_delay_groups(t: np.ndarray, arms: np.ndarray, gait, settle: float = SETTLE
                       ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`swing_delays` and each swing's group [S]: 2 arm + (1 if the arm swung up), 0-3."""
    T = gait.period()
    sw = _command_switches(gait)
    out, grp = [], []
    for k in range(2):
        tc, dirs = crossings(t, arms[:, k])
        keep = tc >= t[0] + settle * T
        tc, dirs = tc[keep], dirs[keep]
        for d in (1, -1):
            ref = [p for (kk, dd, p) in sw if kk == k and dd == d]
            if not ref or not (dirs == d).any():
                continue
            u = np.mod(tc[dirs == d] / T, 1.0)
            diff = np.stack([np.mod(u - r + 0.5, 1.0) - 0.5 for r in ref])  # to each switch, wrapped
            out.append(diff[np.argmin(np.abs(diff), 0), np.arange(diff.shape[1])] * T)
            grp.append(np.full(len(out[-1]), 2 * k + (d > 0)))
    if not out:
        return np.zeros(0), np.zeros(0, int)
    return np.concatenate(out), np.concatenate(grp)


def swing_rise_groups(t: np.ndarray, arms: np.ndarray, gait, settle: float = SETTLE
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Rise times (s) of one robot's arm swings [F frames, 2 arms]: from the arm crossing a quarter of its
    commanded swing to its crossing three quarters (angles -a/2 then +a/2 on the way up, the reverse on the
    way down, a the gait's amplitude), and each swing's group, 2 arm + (1 if up). Model-free: no command
    is matched. A dead time leaves the rise as it was; a first-order lag lengthens it, the more the shorter
    the swing (a lag as long as the move smears it); a slower servo lengthens it in proportion to the
    amplitude. Swings that do not reach both levels, or that start within ``settle`` periods of the first
    frame, give none."""
    T = gait.period()
    half = 0.5 * gait.amplitude
    out, grp = [], []
    for k in range(2):
        lo_t, lo_d = crossings(t, arms[:, k] + half)  # the arm crosses -a/2
        hi_t, hi_d = crossings(t, arms[:, k] - half)  # ... and +a/2
        for d in (1, -1):
            first, last = (lo_t[lo_d == 1], hi_t[hi_d == 1]) if d > 0 else (hi_t[hi_d == -1], lo_t[lo_d == -1])
            first = first[first >= t[0] + settle * T]
            if not len(first) or not len(last):
                continue
            j = np.searchsorted(first, last) - 1  # the latest first-level crossing before each second one
            ok = j >= 0
            rise = last[ok] - first[j[ok]]
            rise = rise[(rise > 0) & (rise < 0.5 * T)]
            out.append(rise)
            grp.append(np.full(len(rise), 2 * k + (d > 0)))
    if not out:
        return np.zeros(0), np.zeros(0, int)
    return np.concatenate(out), np.concatenate(grp)


def grouped_mean_se(x, groups) -> dict:
    """The mean of per-group means (every group weighted alike) and its standard error from the spread
    within groups (pooled), for values ``x`` [S] in groups ``groups`` [S] (any hashable labels).

    An offset shared by one group's values (an arm read with a constant error, on its way up) moves
    that group's mean and not the spread; with groups that cancel in pairs (up and down) it leaves the
    mean too. Groups of one value count in the mean, not in the spread; with no spread to measure the
    error is NaN.
    """
    x = np.asarray(x, float)
    g = np.asarray(groups)
    ok = np.isfinite(x)
    x, g = x[ok], g[ok]
    if len(x) == 0:
        return {"mean": float("nan"), "se": float("nan"), "n": 0}
    labels, inv = np.unique(g, return_inverse=True, axis=0) if g.ndim > 1 else np.unique(g, return_inverse=True)
    inv = inv.reshape(-1)
    n_g = np.bincount(inv, minlength=len(labels)).astype(float)
    means = np.bincount(inv, weights=x, minlength=len(labels)) / n_g
    dof = len(x) - len(labels)
    if dof < 1:
        se = float("nan")
    else:
        s2 = float(np.sum((x - means[inv]) ** 2) / dof)
        se = float(math.sqrt(s2 * np.sum(1.0 / n_g)) / len(labels))
    return {"mean": float(means.mean()), "se": se, "n": int(len(x))}


def _mean_se(x) -> dict:
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    if len(x) == 0:
        return {"mean": float("nan"), "se": float("nan"), "n": 0}
    se = float(x.std(ddof=1) / math.sqrt(len(x))) if len(x) > 1 else float("nan")
    return {"mean": float(x.mean()), "se": se, "n": int(len(x))}


def _key_label(key) -> str:
    """A gait group's row label, from its key (drift.group_key)."""
    return f"{key[0]:g}° {key[1]} {key[2]}, T = {key[3]:.4g} s"


def _gait_label(g) -> str:
    return _key_label(group_key(g))


def observables(trials, tracks=None) -> dict:
    """The observables of measured trials (``tracks`` None) or of model tracks
    [F, N, 5] aligned with ``trials`` (masked where the measurement is missing).

    Returns:
      dict of lists, one row per gait: ``arm_delay_ms`` (gait, mean, se, n
      swings) from each trial's robot 0 and every robot on another gait than
      its trial's robot 0; ``phase_lead`` (gait, robot, mean, se, n swings,
      in periods) of each robot that shares robot 0's gait, against robot 0
      swing by swing; ``drift_mm_per_s`` (gait, v [2], se [2]) from the
      plate-frame drift regression; ``body_step_mm`` (gait, mean, se, n
      cycles): the body-frame step's length from the same regression;
      ``rotation_deg`` (gait, mean, se, n cycles) per cycle of lone robots; ``arm_rise_ms`` (gait,
      amplitude, mean, se, n swings) of every robot's swings (:func:`swing_rise_groups`), grouped like
      the delays.
    """
    delays: dict = {}
    lead: dict = {}
    rot: dict = {}
    rises: dict = {}
    for k, tr in enumerate(trials):
        pose, arms = (tr.pose, tr.arms) if tracks is None else masked(tracks[k], tr)
        for i, g in enumerate(tr.gaits):  # lone robots' rotation per cycle
            if robot_alone(pose, i, tr.params.robot.body_length):
                _, pc = cycle_poses(tr.t, pose[:, i], tr.periods[i])
                if len(pc) >= 2:
                    rot.setdefault(g, []).append(np.degrees(np.diff(pc[:, 2])))
        if arms is None:
            continue
        # each swing's group: (trial, robot, arm, direction), so that one arm's constant misreading cancels
        def labelled(i, gr):
            return np.column_stack([np.full(len(gr), k), np.full(len(gr), i), gr])

        per = [swing_delay_groups(tr.t, arms[:, i], tr.gaits[i]) for i in range(tr.robots)]
        label = [labelled(i, gr) for i, (_, gr) in enumerate(per)]
        for i, g in enumerate(tr.gaits):  # every robot's rise, grouped like its delays
            x, gr = swing_rise_groups(tr.t, arms[:, i], g)
            rises.setdefault(g, []).append((x, labelled(i, gr)))
        d0 = grouped_mean_se(per[0][0], label[0])["mean"]
        for i, g in enumerate(tr.gaits):
            if i == 0 or g != tr.gaits[0]:
                delays.setdefault(g, []).append((per[i][0], label[i]))
            elif len(per[i][0]) and np.isfinite(d0):
                # robot 0's mean delay minus this robot's: how far ahead it swings (periods)
                lead.setdefault((g, i), []).append(((d0 - per[i][0]) / g.period(), label[i]))
    out: dict = {"arm_delay_ms": [], "phase_lead": [], "drift_mm_per_s": [], "body_step_mm": [], "rotation_deg": [],
                 "arm_rise_ms": []}

    def pooled(parts, scale=1.0):
        return grouped_mean_se(np.concatenate([p[0] for p in parts]) * scale,
                               np.concatenate([p[1] for p in parts]))

    for g, parts in delays.items():
        out["arm_delay_ms"].append({"gait": _gait_label(g), "amplitude_deg": float(g.amplitude_deg),
                                    **pooled(parts, 1e3)})
    for (g, i), parts in lead.items():
        out["phase_lead"].append({"gait": _gait_label(g), "robot": i, **pooled(parts)})
    for key, r in sorted(group_drift(trials, tracks).items()):
        T = key[3]
        out["drift_mm_per_s"].append({"gait": _key_label(key), "v": (np.asarray(r["v"]) / T).tolist(),
                                      "se": (np.sqrt(np.diag(r["cov_v"])) / T).tolist()})
        # the step's length in the body frame, its error propagated from the step's covariance
        s, cs = np.asarray(r["s"]), np.asarray(r["cov_s"])
        n = float(np.hypot(*s))
        se = float(np.sqrt(s @ cs @ s) / n) if n > 0 else float(np.sqrt(np.trace(cs)))
        out["body_step_mm"].append({"gait": _key_label(key), "mean": n, "se": se, "n": r["cycles"]})
    for g, parts in rot.items():
        out["rotation_deg"].append({"gait": _gait_label(g), **_mean_se(np.concatenate(parts))})
    for g, parts in rises.items():
        if sum(len(p[0]) for p in parts):
            out["arm_rise_ms"].append({"gait": _gait_label(g), "amplitude_deg": float(g.amplitude_deg),
                                       **pooled(parts, 1e3)})
    return out


def reproduced(measured: dict, model: dict | None, z: float = 1.96) -> bool | None:
    """Whether a model observable agrees with the measured one within z combined standard errors."""
    if model is None:
        return None
    if "v" in measured:
        d = np.subtract(measured["v"], model["v"])
        s = np.hypot(measured["se"], model["se"])
        return bool(np.all(np.abs(d) <= z * s))
    s = math.hypot(measured["se"], model["se"]) if np.isfinite(model["se"]) else measured["se"]
    return bool(abs(measured["mean"] - model["mean"]) <= z * s)


# The delay test (calibrate.stages judges servo hypotheses by it). A lag or dead time delays every swing
# by the same time whatever its amplitude; a slower servo delays it in proportion to the amplitude (its
# arm takes amplitude / speed to get there). The measured delay's excess over the preset model's, per
# gait, is fitted as constant + slope x amplitude; a constant above DELAY_MIN_MS, at least DELAY_Z of its
# standard errors from 0, is a delay the model's servo does not have; a constant whose upper bound (DELAY_Z
# standard errors up) stays below DELAY_MIN_MS is none; between the two the test does not decide (two close
# small amplitudes: a lag shorter than the arm's swing looks like a slower servo there). Each gait's excess carries a floor
# DELAY_FLOOR_MS for what a straight line in amplitude cannot follow (two servo laws' delays differ by a
# few ms in a way no line removes; docs/calibration.md), so a handful of swings cannot make it certain.
DELAY_MIN_MS = 5.0
DELAY_Z = 2.5
DELAY_FLOOR_MS = 2.0
DELAY_SPAN = 1.5  # the largest amplitude must be this many times the smallest


@dataclasses.dataclass(frozen=True)
class DelayTest:
    """The measured arm delay's excess over a model's, split into a constant and a part that grows with
    the amplitude (unrounded; ms and ms per radian of amplitude).

    Attributes:
      amplitudes_deg, excess_ms, se_ms: per gait (arm delays measured on several gaits).
      constant_ms, constant_se_ms: the excess at zero amplitude (a lag or dead time adds to it).
      per_rad_ms, per_rad_se_ms: its growth per radian of amplitude (a slower servo adds to it).
      applicable: at least two gaits whose amplitudes span ``DELAY_SPAN``.
      constant_delay: applicable, constant_ms > ``DELAY_MIN_MS`` and > ``DELAY_Z`` standard errors.
      no_constant_delay: applicable and constant_ms + ``DELAY_Z`` standard errors < ``DELAY_MIN_MS``.
    """

    amplitudes_deg: tuple
    excess_ms: tuple
    se_ms: tuple
    constant_ms: float
    constant_se_ms: float
    per_rad_ms: float
    per_rad_se_ms: float
    applicable: bool
    constant_delay: bool
    no_constant_delay: bool = False

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def delay_test(measured: dict, model: dict, key: str = "arm_delay_ms") -> DelayTest:
    """:class:`DelayTest` from the ``arm_delay_ms`` rows of :func:`observables` of the data and of a model
    (rows matched by gait); ``key`` "arm_rise_ms": the same split of the arm rise's excess
    (:func:`servo_reading` reads it)."""
    rows = []
    for r in measured.get(key, []):
        m = next((x for x in model.get(key, []) if x["gait"] == r["gait"]), None)
        if m is None or not (np.isfinite(r["mean"]) and np.isfinite(m["mean"])):
            continue
        se = math.sqrt(np.nan_to_num(r["se"]) ** 2 + np.nan_to_num(m["se"]) ** 2 + DELAY_FLOOR_MS ** 2)
        rows.append((r["amplitude_deg"], r["mean"] - m["mean"], se))
    nan = float("nan")
    amps = np.array([x[0] for x in rows], float)
    if len(rows) < 2 or len(set(amps)) < 2 or amps.max() < DELAY_SPAN * amps.min():
        return DelayTest(tuple(amps.tolist()), tuple(x[1] for x in rows), tuple(x[2] for x in rows),
                         nan, nan, nan, nan, False, False)
    a = np.column_stack([np.ones(len(rows)), np.radians(amps)])
    y = np.array([x[1] for x in rows])
    w = 1.0 / np.square([x[2] for x in rows])
    cov = np.linalg.inv(a.T @ (a * w[:, None]))
    c, b = cov @ (a.T @ (w * y))
    red = float(np.sum(w * (y - a @ np.array([c, b])) ** 2)) / max(len(rows) - 2, 1)
    cov = cov * max(1.0, red) if len(rows) > 2 else cov  # scatter about the line beyond the errors widens it
    sc, sb = math.sqrt(cov[0, 0]), math.sqrt(cov[1, 1])
    return DelayTest(tuple(amps.tolist()), tuple(y.tolist()), tuple(x[2] for x in rows), float(c), sc, float(b), sb,
                     True, bool(c > DELAY_MIN_MS and c > DELAY_Z * sc), bool(c + DELAY_Z * sc < DELAY_MIN_MS))


# The arm rise's reading of a servo's timing (thresholds set on development sets of suite seeds 2040-2044,
# benchmarks/arm_rise_dev.py). A dead time moves a swing whole and leaves its
# rise (a quarter to three quarters) as the servo makes it; a first-order lag smears the swing, and most the
# shortest swings, so the rise's excess over the preset model, split as constant + slope x amplitude (the
# delay test's split, :func:`delay_test` with key "arm_rise_ms"), has a constant above what a servo law
# unlike the model's leaves there. On the development sets: lags 6.0-26.4 ms (where two amplitudes at least
# 1.5x apart include one below 30 deg; 3.8 +- 7.2 ms from 60 and 90 deg alone), dead times -0.1 to 2.3 ms,
# clean robots -5.0 to 1.4 ms. RISE_LAG_MS sits between the two groups.
RISE_LAG_MS = 4.0


def servo_reading(rise: DelayTest) -> str | None:
    """Which servo timing the arm rise reads: "servo_lag" (the rise's constant above ``RISE_LAG_MS``),
    "servo_dead_time" (below it), or None where the split does not apply (one amplitude, or amplitudes
    less than ``DELAY_SPAN`` apart). Read only to choose between a lag and a dead time that both passed."""
    if not rise.applicable or not math.isfinite(rise.constant_ms):
        return None
    return "servo_lag" if rise.constant_ms > RISE_LAG_MS else "servo_dead_time"
