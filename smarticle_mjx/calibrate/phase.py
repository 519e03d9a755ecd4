"""Gait phase offsets between robots, measured without the model.

Robots of one build running one gait trace the same arm-angle curves; a
robot whose gait runs ahead by a fraction ``o`` of the period traces robot
0's curve shifted in time: alpha_i(t) = alpha_0(t + i o T) (the library's
``phase_offset`` convention: robot i runs i * offset periods ahead). The
shift that best aligns each robot's tracked arm angles with robot 0's, over
every frame where both are tracked, estimates ``o`` with no model at all.
It starts the joint fit of the ``phase_offset`` hypothesis: started at a
fixed probe, the least-squares fit stalled in a side minimum of the rough
objective (0.05 for a true 0.1).
"""

from __future__ import annotations

import numpy as np


def _misfit(t, a0, ai, shift):
    """Mean squared difference of ai(t) and a0(t + shift) where both exist."""
    ok0 = np.isfinite(a0).all(-1)
    if ok0.sum() < 4:
        return np.nan
    ts = t + shift
    inside = (ts >= t[ok0][0]) & (ts <= t[ok0][-1]) & np.isfinite(ai).all(-1)
    if inside.sum() < 4:
        return np.nan
    ref = np.stack([np.interp(ts[inside], t[ok0], a0[ok0, k]) for k in range(a0.shape[1])], -1)
    return float(np.mean((ai[inside] - ref) ** 2))


def estimate_offset(trials, step: float = 0.0025, max_offset: float = 0.25) -> dict | None:
    """Phase offset (periods) per robot step, from the arms of multi-robot trials.

    Returns:
      dict: offset (periods: robot i runs i * offset ahead), per_robot
      estimates, pairs used; None without two tracked robots.
    """
    shifts = np.arange(-max_offset, max_offset + step / 2, step)
    est = []
    for tr in trials:
        if tr.robots < 2 or tr.arms is None or not tr.one_gait:
            continue  # robots' arm curves are compared only where they run the same gait
        period = tr.gait.period()
        for i in range(1, tr.robots):
            cost = np.array([_misfit(tr.t, tr.arms[:, 0], tr.arms[:, i], i * s * period) for s in shifts])
            if not np.isfinite(cost).any():
                continue
            j = int(np.nanargmin(cost))
            s = shifts[j]
            if 0 < j < len(shifts) - 1 and np.isfinite(cost[j - 1:j + 2]).all():
                c_m, c_0, c_p = cost[j - 1:j + 2]
                den = c_m - 2 * c_0 + c_p
                if den > 0:
                    s = s + 0.5 * step * (c_m - c_p) / den
            est.append(float(s))
    if not est:
        return None
    return {"offset": float(np.median(est)), "per_robot": est, "pairs": len(est)}
