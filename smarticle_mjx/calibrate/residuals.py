"""From measured and simulated tracks to residuals a physicist reads.

Two layers:

* ``features``: statistics of one track, each with a standard error from
  the measured cycle-to-cycle spread (floored at the tracking resolution):
  arm angles by gait phase, the body's within-cycle wobble by gait phase
  (in the body frame at the cycle's start), the per-cycle step in the plate
  frame, and the variance of frame-to-frame increments. ``residual_vector``
  stacks (measured - model) / SE over all of them: the fit's objective.
* ``metrics``: the numbers of the report (arm RMS error, step and rotation
  distributions with Wasserstein and KS, trajectory error, drift speed,
  heading drift, MSD exponent, pair coordinates).

Simulated tracks are sampled at the measured frame times and masked where
the measurement is missing, so both sides see the same frames.
"""

from __future__ import annotations

import dataclasses

import numpy as np

BINS = 12  # gait-phase bins per period
FLOOR = {"arm": 0.2, "xy": 0.05, "theta": 0.05}  # deg, mm, deg: resolution of a good tracker
MM, DEG = 1e3, np.degrees(1.0)
CONTACT_W = 2.2  # robots closer than this (body lengths) may touch: their body motion is chaotic


@dataclasses.dataclass
class Features:
    """Statistics of one track (values and standard errors, same shapes).

    Attributes:
      arms: [N, 2, BINS] mean arm angle (deg) per phase bin, or None.
      wobble: [N, 3, BINS] mean (dx, dy in mm, dtheta deg) since the cycle
        start, in the body frame at the cycle start.
      step: [N, 3] mean per-cycle (dx, dy in mm, plate frame; dtheta deg).
      incr: [N, 2] variance of frame increments (xy in mm^2, theta in deg^2).
      in_contact: robots came within CONTACT_W of each other.
    """

    arms: tuple | None
    wobble: tuple
    step: tuple
    incr: tuple
    in_contact: bool


def _binned(values, bins, valid, nb=BINS):
    """Mean and SE per bin of values [F] with bin index [F]."""
    mean = np.full(nb, np.nan)
    spread = np.full(nb, np.nan)
    count = np.zeros(nb, int)
    for b in range(nb):
        v = values[(bins == b) & valid]
        count[b] = len(v)
        if len(v):
            mean[b] = v.mean()
            spread[b] = v.std(ddof=1) if len(v) > 1 else 0.0
    return mean, spread, count


def _se(spread, count, floor):
    return np.sqrt(np.nan_to_num(spread) ** 2 + floor ** 2) / np.sqrt(np.maximum(count, 1))


def cycle_poses(t, pose, period):
    """Pose [C+1, 3] interpolated at whole periods inside the track, and those times."""
    ok = np.isfinite(pose).all(-1)
    t_ok = t[ok]
    c0, c1 = int(np.ceil(t_ok[0] / period - 1e-9)), int(np.floor(t_ok[-1] / period + 1e-9))
    tc = np.arange(c0, c1 + 1) * period
    out = np.stack([np.interp(tc, t_ok, pose[ok, j]) for j in range(3)], -1) if len(tc) else np.zeros((0, 3))
    return tc, out


def features(t, pose, arms, period) -> Features:
    """Features of one track.

    Args:
      t: [F] frame times (s); gait phase 0 at t = 0.
      pose: [F, N, 3] x, y (m), heading (rad, unwrapped); NaN = missing.
      arms: [F, N, 2] arm angles (rad) or None.
      period: gait period (s), one for all robots or [N], each robot's.
    """
    f, n = pose.shape[:2]
    periods = np.broadcast_to(np.asarray(period, float), (n,))
    bins_of = np.minimum((np.mod(t[:, None] / periods, 1.0) * BINS).astype(int), BINS - 1)  # [F, N]
    arm_m = arm_s = None
    if arms is not None:
        m = np.full((n, 2, BINS), np.nan)
        s = np.full((n, 2, BINS), np.nan)
        for i in range(n):
            for k in range(2):
                v = arms[:, i, k] * DEG
                mean, spread, count = _binned(v, bins_of[:, i], np.isfinite(v))
                m[i, k], s[i, k] = mean, _se(spread, count, FLOOR["arm"])
        arm_m, arm_s = m, s
    wob_m = np.full((n, 3, BINS), np.nan)
    wob_s = np.full((n, 3, BINS), np.nan)
    step_m = np.full((n, 3), np.nan)
    step_s = np.full((n, 3), np.nan)
    inc_m = np.full((n, 2), np.nan)
    inc_s = np.full((n, 2), np.nan)
    for i in range(n):
        p = pose[:, i]
        ok = np.isfinite(p).all(-1)
        tc, pc = cycle_poses(t, p, periods[i])
        phase_bin = bins_of[:, i]
        if len(tc) >= 2:
            rel = np.full((f, 3), np.nan)
            for c in range(len(tc) - 1):
                sel = ok & (t >= tc[c]) & (t < tc[c + 1])
                d = p[sel] - pc[c]
                h = pc[c, 2]
                rel[sel, 0] = (np.cos(h) * d[:, 0] + np.sin(h) * d[:, 1]) * MM
                rel[sel, 1] = (-np.sin(h) * d[:, 0] + np.cos(h) * d[:, 1]) * MM
                rel[sel, 2] = d[:, 2] * DEG
            for j, fl in enumerate((FLOOR["xy"], FLOOR["xy"], FLOOR["theta"])):
                mean, spread, count = _binned(rel[:, j], phase_bin, np.isfinite(rel[:, j]))
                wob_m[i, j], wob_s[i, j] = mean, _se(spread, count, fl)
            st = np.diff(pc, axis=0) * [MM, MM, DEG]
            step_m[i] = st.mean(0)
            step_s[i] = _se(st.std(0, ddof=1) if len(st) > 1 else np.zeros(3), len(st),
                            np.array([FLOOR["xy"], FLOOR["xy"], FLOOR["theta"]]))
        tt, pp = t[ok], p[ok]
        if len(tt) > 3:
            d = np.diff(pp, axis=0)
            dxy = np.concatenate([d[:, 0], d[:, 1]]) * MM
            dth = d[:, 2] * DEG
            for j, (v, fl) in enumerate(((dxy, FLOOR["xy"]), (dth, FLOOR["theta"]))):
                inc_m[i, j] = v.var()
                inc_s[i, j] = (v.var() + fl ** 2) * np.sqrt(2.0 / len(v))
    in_contact = False
    if n > 1:
        for i in range(n):
            for j in range(i + 1, n):
                r = np.hypot(pose[:, i, 0] - pose[:, j, 0], pose[:, i, 1] - pose[:, j, 1])
                in_contact |= bool(np.nanmin(r) < CONTACT_W * 0.05)
    return Features((arm_m, arm_s) if arms is not None else None, (wob_m, wob_s), (step_m, step_s),
                    (inc_m, inc_s), in_contact)


def residual_blocks(meas: Features, model: Features, noise=(0.0, 0.0)) -> dict[str, np.ndarray]:
    """Normalised residuals (measured - model) / SE per block (NaN-free, flat).

    ``noise`` = (xy mm, theta deg) of the tracking-noise effect: white noise
    adds 2 sigma^2 to the variance of frame increments.
    """
    out = {}
    if meas.arms is not None and model.arms is not None:
        out["arms"] = (meas.arms[0] - model.arms[0]) / meas.arms[1]
    if not meas.in_contact:
        out["wobble"] = (meas.wobble[0] - model.wobble[0]) / meas.wobble[1]
        out["step"] = (meas.step[0] - model.step[0]) / meas.step[1]
        pred = model.incr[0] + 2 * np.array([noise[0] ** 2, noise[1] ** 2])
        out["increments"] = (meas.incr[0] - pred) / meas.incr[1]
    return {k: np.nan_to_num(v[np.isfinite(v)]) for k, v in out.items()}


def masked(model_track, trial):
    """A model track [F, N, 5] split like a trial and masked where the trial is missing."""
    pose = model_track[..., :3].copy()
    pose[~np.isfinite(trial.pose).all(-1)] = np.nan
    arms = None
    if trial.arms is not None:
        arms = model_track[..., 3:].copy()
        arms[~np.isfinite(trial.arms)] = np.nan
    return pose, arms


# ------------------------------------------------------------------ report metrics

def _w1(a, b):
    from scipy.stats import wasserstein_distance
    a, b = np.asarray(a)[np.isfinite(a)], np.asarray(b)[np.isfinite(b)]
    return float(wasserstein_distance(a, b)) if len(a) and len(b) else float("nan")


def _ks(a, b):
    from scipy.stats import ks_2samp
    a, b = np.asarray(a)[np.isfinite(a)], np.asarray(b)[np.isfinite(b)]
    return float(ks_2samp(a, b).pvalue) if len(a) > 1 and len(b) > 1 else float("nan")


def metrics(trials, model_tracks) -> dict:
    """Report metrics pooled over trials: measured vs model."""
    from ..configs import relative_coordinates
    from ..reduce.transport import fit_exponent, msd
    arm_err, traj, steps_m, steps_s, rot_m, rot_s, drift_m, drift_s, head_m, head_s = ([] for _ in range(10))
    rel_m, rel_s = [], []
    cyc_m, cyc_s = [], []
    for tr, mt in zip(trials, model_tracks):
        pose_s, arms_s = masked(mt, tr)
        periods = tr.periods
        if tr.arms is not None:
            e = (tr.arms - arms_s) * DEG
            arm_err.append(e[np.isfinite(e)])
        for i in range(tr.robots):
            ok = np.isfinite(tr.pose[:, i]).all(-1)
            last = np.nonzero(ok)[0][-1]
            traj.append(np.hypot(*(tr.pose[last, i, :2] - pose_s[last, i, :2])) * MM)
            for p, st, ro, dr, hd, cy in ((tr.pose[:, i], steps_m, rot_m, drift_m, head_m, cyc_m),
                                          (pose_s[:, i], steps_s, rot_s, drift_s, head_s, cyc_s)):
                tc, pc = cycle_poses(tr.t, p, periods[i])
                if len(pc) >= 2:
                    d = np.diff(pc, axis=0)
                    st.extend(np.hypot(d[:, 0], d[:, 1]) * MM)
                    ro.extend(d[:, 2] * DEG)
                    dr.append(np.hypot(*(pc[-1, :2] - pc[0, :2])) * MM / (tc[-1] - tc[0]))
                    hd.append((pc[-1, 2] - pc[0, 2]) * DEG / (len(pc) - 1))
                    cy.append(pc[:, :2] * MM)
        if tr.robots == 2:
            for p, dest in ((tr.pose, rel_m), (pose_s, rel_s)):  # both sampled at robot 0's cycles
                _, c0 = cycle_poses(tr.t, p[:, 0], periods[0])
                _, c1 = cycle_poses(tr.t, p[:, 1], periods[0])
                k = min(len(c0), len(c1))
                if k:
                    dest.append(np.stack(relative_coordinates(c0[:k], c1[:k], tr.params.robot.body_length), -1))

    def beta(tracks):
        if not tracks:
            return float("nan")
        k = max(len(x) for x in tracks)
        if k < 8:
            return float("nan")
        arr = np.full((len(tracks), k, 2), np.nan)
        for j, x in enumerate(tracks):
            arr[j, :len(x)] = x
        lags, m, _ = msd(arr)
        return fit_exponent(lags, m, (2, max(3, k // 2)))[0]

    out = {
        "arm_rms_deg": float(np.sqrt(np.mean(np.concatenate(arm_err) ** 2))) if arm_err else None,
        "trajectory_error_mm": float(np.mean(traj)) if traj else None,
        "step_mm": {"measured": float(np.mean(steps_m)) if steps_m else None,
                    "model": float(np.mean(steps_s)) if steps_s else None,
                    "wasserstein": _w1(steps_m, steps_s), "ks_p": _ks(steps_m, steps_s)},
        "rotation_deg": {"measured": float(np.mean(rot_m)) if rot_m else None,
                         "model": float(np.mean(rot_s)) if rot_s else None,
                         "wasserstein": _w1(rot_m, rot_s), "ks_p": _ks(rot_m, rot_s)},
        "drift_mm_per_s": {"measured": float(np.mean(drift_m)) if drift_m else None,
                           "model": float(np.mean(drift_s)) if drift_s else None},
        "heading_drift_deg_per_cycle": {"measured": float(np.mean(head_m)) if head_m else None,
                                        "model": float(np.mean(head_s)) if head_s else None},
        "msd_beta": {"measured": beta(cyc_m), "model": beta(cyc_s)},
    }
    if rel_m and rel_s:
        a, b = np.concatenate(rel_m), np.concatenate(rel_s)
        out["pair_wasserstein"] = {"r_W": _w1(a[:, 0], b[:, 0]), "theta_deg": _w1(np.degrees(a[:, 1]), np.degrees(b[:, 1])),
                                   "phi_deg": _w1(np.degrees(a[:, 2]), np.degrees(b[:, 2]))}
    return out
