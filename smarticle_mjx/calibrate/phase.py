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

The curves are compared from one period after the trial's start on
(``SETTLE_PERIODS``, trials of at least ``3 * SETTLE_PERIODS`` periods): a
robot that starts at rest in a corner while its clock is part of a move on
makes its first move late, and aligning that first period with the steady
gait biased the reading (+0.1455 +- 0.0001 for a true 0.1494).
"""

from __future__ import annotations

import dataclasses

import numpy as np


SETTLE_PERIODS = 1.0  # a robot's first period after the trial's start may not be its steady gait


def _misfit(t, a0, ai, shift, settle: float = 0.0):
    """Mean squared difference of ai(t) and a0(t + shift) where both exist, both ``settle`` seconds or more
    after the trial's first frame."""
    settled = t >= t[0] + settle
    ok0 = np.isfinite(a0).all(-1) & settled
    if ok0.sum() < 4:
        return np.nan
    ts = t + shift
    inside = (ts >= t[ok0][0]) & (ts <= t[ok0][-1]) & np.isfinite(ai).all(-1) & settled
    if inside.sum() < 4:
        return np.nan
    ref = np.stack([np.interp(ts[inside], t[ok0], a0[ok0, k]) for k in range(a0.shape[1])], -1)
    return float(np.mean((ai[inside] - ref) ** 2))


def _aligning_shift(t, c0, ci, scale: float, shifts: np.ndarray, settle: float = 0.0) -> float | None:
    """The shift (in ``shifts``' units, times ``scale`` in seconds) at which curve ``ci`` best matches
    ``c0`` shifted, refined by a parabola through the grid's best three; None where they never overlap.
    Frames within ``settle`` seconds of the first are left out of both curves."""
    cost = np.array([_misfit(t, c0, ci, s * scale, settle) for s in shifts])
    if not np.isfinite(cost).any():
        return None
    j = int(np.nanargmin(cost))
    s = shifts[j]
    if 0 < j < len(shifts) - 1 and np.isfinite(cost[j - 1:j + 2]).all():
        c_m, c_0, c_p = cost[j - 1:j + 2]
        den = c_m - 2 * c_0 + c_p
        if den > 0:
            s = s + 0.5 * (shifts[1] - shifts[0]) * (c_m - c_p) / den
    return float(s)


def estimate_offset(trials, step: float = 0.0025, max_offset: float = 0.25) -> dict | None:
    """Phase offset (periods) per robot step, from the arms of multi-robot trials.

    Returns:
      dict: offset (periods: robot i runs i * offset ahead), per_robot
      estimates, pairs used; None without two tracked robots.
    """
    po = pair_offsets(trials, step, max_offset, heading=False)
    if po is None:
        return None
    return {"offset": float(np.median(po["per_pair"])), "per_robot": po["per_pair"], "pairs": po["n"]}


def _detrended_heading(t, theta):
    """A robot's heading with its steady rotation (a straight line through its tracked frames) taken out:
    what is left is the wobble the arms drive, whose timing follows the robot's gait."""
    ok = np.isfinite(theta)
    out = np.full_like(theta, np.nan)
    if ok.sum() < 4:
        return out
    a, b = np.polyfit(t[ok], theta[ok], 1)
    out[ok] = theta[ok] - (a * t[ok] + b)
    return out


def pair_offsets(trials, step: float = 0.0025, max_offset: float = 0.25, heading: bool = True) -> dict | None:
    """Every pair's phase offset (periods: robot i runs i * offset ahead of robot 0), measured without the
    model: from the arm curves where arms are tracked (as :func:`estimate_offset`), else from the body's
    heading wobble with each robot's steady rotation taken out (``heading`` False: trials without tracked
    arms are left out). Robots of one build on one gait wobble alike in time; a robot whose gait runs ahead
    wobbles ahead by the same time.

    Returns:
      dict: source ("arms" or "heading"), per_pair estimates, mean, se (the spread over pairs / sqrt n),
      n; None without a multi-robot trial on one gait.
    """
    shifts = np.arange(-max_offset, max_offset + step / 2, step)
    est, sources = [], set()
    for tr in trials:
        if tr.robots < 2 or not tr.one_gait:
            continue
        period = tr.gait.period()
        if tr.arms is not None and np.isfinite(tr.arms).any():
            curves, sources = [tr.arms[:, i] for i in range(tr.robots)], sources | {"arms"}
        elif not heading:
            continue
        else:
            curves = [_detrended_heading(tr.t, tr.pose[:, i, 2])[:, None] for i in range(tr.robots)]
            sources |= {"heading"}
        span = (tr.t[-1] - tr.t[0]) / period
        settle = SETTLE_PERIODS * period if span >= 3 * SETTLE_PERIODS else 0.0
        for i in range(1, tr.robots):
            s = _aligning_shift(tr.t, curves[0], curves[i], i * period, shifts, settle)
            if s is not None:
                est.append(s)
    if not est:
        return None
    x = np.asarray(est)
    se = float(x.std(ddof=1) / np.sqrt(len(x))) if len(x) > 1 else float("nan")
    return {"source": "+".join(sorted(sources)), "per_pair": est, "mean": float(x.mean()), "se": se, "n": len(x)}


# what the offset read off the robots' curves may miss by beyond its spread over pairs: on development sets
# (seeds 2026-2045, seen) it missed the hidden offset by up to 0.004 period at 60 Hz and above, 0.006 at 30 Hz
OFFSET_SYSTEMATIC = 0.005


@dataclasses.dataclass
class OffsetTest:
    """Is there a phase offset between the robots, on their own curves (:func:`pair_offsets`)?

    ``present``: the mean over pairs differs from zero at 95 % (Student's t over pairs); ``absent``: it
    does not, so a phase offset fitted with the model would be the model's mismatch between the robots'
    trials, not a timing between them; neither with fewer than two pairs (the model decides, as before).
    ``sd``: the measurement's standard uncertainty, the spread's standard error and ``OFFSET_SYSTEMATIC``
    together; ``interval``: the mean +- 1.96 sd, what the calibration reports for an offset it holds at the
    measured mean."""

    source: str | None
    mean: float
    se: float
    n: int
    t95: float

    @property
    def applicable(self) -> bool:
        return self.n >= 2 and np.isfinite(self.se)

    @property
    def present(self) -> bool:
        return self.applicable and abs(self.mean) > self.t95 * self.se

    @property
    def absent(self) -> bool:
        return self.applicable and not self.present

    @property
    def established(self) -> bool:
        """Present, and its reported interval (the spread and what the reading may miss by) clear of zero:
        the calibration adds it as measured, without asking a fit to confirm it."""
        return self.present and abs(self.mean) > 1.96 * self.sd

    @property
    def sd(self) -> float:
        return float(np.hypot(self.se, OFFSET_SYSTEMATIC))

    @property
    def read_from(self) -> str:
        """What the offset was read off, in words."""
        return {"arms": "arm curves", "heading": "heading wobble (its steady rotation taken out)"}.get(
            self.source, "arm curves, and heading wobble where arms were not tracked")

    @property
    def interval(self) -> tuple[float, float]:
        return (self.mean - 1.96 * self.sd, self.mean + 1.96 * self.sd)

    def as_dict(self) -> dict:
        return {"source": self.source, "read_from": self.read_from, "mean": self.mean, "se": self.se, "n": self.n, "t95": self.t95,
                "present": self.present, "absent": self.absent, "established": self.established, "sd": self.sd,
                "interval": list(self.interval) if self.present else None}


def offset_test(trials) -> OffsetTest | None:
    """The model-free offset test of ``trials`` (None without a multi-robot trial on one gait)."""
    from scipy.stats import t as student
    po = pair_offsets(trials)
    if po is None:
        return None
    t95 = float(student.ppf(0.975, po["n"] - 1)) if po["n"] > 1 else float("inf")
    return OffsetTest(po["source"], po["mean"], po["se"], po["n"], t95)
