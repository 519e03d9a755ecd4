"""Do the arms drag on the plate? Read off the body's heading, without the model.

A robot whose arms clear the plate gets no horizontal force from outside but the plate's friction on its
body. Its arm swings push it only where an arm speeds up or slows down (a kick at each end of a swing);
between the kicks the arm turns at a steady speed, nothing pushes the body and friction holds it still
within milliseconds. An arm that rests on the plate drags on it the whole swing: the plate's friction on the
arm, passed through the hinge, turns (and pushes) the body for as long as the arm moves, in the same sense
every time that arm swings that way. So the signature is a body that keeps turning between the kicks of a
swing, the same way in every repeat of that quarter of the gait. No other effect of the library does this: a
tilt, an anisotropic plate, a servo lag or dead time, a phase offset and tracking noise all leave a robot at
rest while its arm turns steadily.

How it is read (fixed on the independent simulator's tracks built for the tests, before any stress set was
read with it):

* each lone robot's heading rate between consecutive tracked frames (no smoothing), placed by its time
  within the gait's quarter (the commanded gait's clock); a robot that comes within ``CONTACT_W`` body
  lengths of another in a trial is left out of that trial (collisions turn it);
* one group per (file, robot, quarter of the gait): the quarters of that kind after the first half period,
  folded onto bins of at least one frame each (at most 12 bins, quarters with fewer than 6 frames are not
  used);
* the kicks are where the group's mean rate peaks: the two bins of largest mean |rate|, and every bin whose
  centre lies within ``KICK_S`` of either (a servo reaches its speed in 20-35 ms on the independent
  simulator's robots); what is left is the steady part of the swing (groups with fewer than 2 such bins are
  not used);
* per quarter, the mean rate over the steady bins; over the quarters of a group its mean and standard
  error; z = mean / se per group, chi^2 = sum of z^2 over groups against chi^2 with one degree of freedom
  per group (the steady rate is zero without drag);
* **present**: chi^2's p < ``P_PRESENT`` and the median |steady rate| over groups above ``RATE_FLOOR``
  (a floor against a slow creep a real plate or tracker may show, far under the 20-90 deg/s that arms
  dragging at mu 0.3 give);
* **absent**: at least ``MIN_GROUPS`` groups, not present, and a drag of ``DETECTABLE`` would have shown:
  the median rate plus twice the groups' median standard error stays under it;
* **undecided** otherwise (the calibration then does what it did without a reading); nothing with fewer
  groups.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from .drift import robot_alone

KICK_S = 0.04         # s either side of a kick's peak that is not the steady swing
MAX_BINS = 12
MIN_FRAMES = 6        # frames per quarter below which its timing cannot be resolved
MIN_QUARTERS = 3      # repeats of a quarter's kind for a group's standard error
MIN_GROUPS = 4
P_PRESENT = 1e-3
RATE_FLOOR = 0.5      # deg/s
DETECTABLE = 2.0      # deg/s: under the weakest drag read on the development seeds (2.5 deg/s, mu 0.11)


@dataclasses.dataclass
class DragTest:
    """The model-free test of arms dragging on the plate (:func:`drag_test`)."""

    groups: int
    chi2: float
    p: float
    rate_deg_s: float          # median over groups of |steady heading rate|
    max_rate_deg_s: float
    se_deg_s: float = 0.0      # median over groups of the steady rate's standard error

    @property
    def applicable(self) -> bool:
        return self.groups >= MIN_GROUPS

    @property
    def present(self) -> bool:
        return self.applicable and self.p < P_PRESENT and self.rate_deg_s > RATE_FLOOR

    @property
    def upper_deg_s(self) -> float:
        """What the steady turn may be at most: the median rate plus twice its median standard error."""
        return self.rate_deg_s + 2.0 * self.se_deg_s

    @property
    def absent(self) -> bool:
        return self.applicable and not self.present and self.upper_deg_s < DETECTABLE

    @property
    def undecided(self) -> bool:
        return self.applicable and not self.present and not self.absent

    def as_dict(self) -> dict:
        return {"groups": self.groups, "chi2": self.chi2, "p": self.p, "rate_deg_s": self.rate_deg_s,
                "max_rate_deg_s": self.max_rate_deg_s, "se_deg_s": self.se_deg_s, "upper_deg_s": self.upper_deg_s,
                "present": self.present, "absent": self.absent, "undecided": self.undecided,
                "applicable": self.applicable,
                "rule": {"kick_s": KICK_S, "p_present": P_PRESENT, "rate_floor_deg_s": RATE_FLOOR,
                         "detectable_deg_s": DETECTABLE, "min_groups": MIN_GROUPS}}


def _steady_bins(mean_rate: np.ndarray, q: float) -> np.ndarray:
    """Indices of the bins that are not a kick: the two peaks of |mean rate| and every bin whose centre lies
    within KICK_S of either (circular within the quarter: the last bins of one quarter meet the first of the
    next)."""
    nb = len(mean_rate)
    ok = np.isfinite(mean_rate)
    if ok.sum() < 3:
        return np.array([], int)
    peaks = np.argsort(-np.where(ok, np.abs(mean_rate), -1.0))[:2]
    centres = (np.arange(nb) + 0.5) / nb * q
    keep = ok.copy()
    for p in peaks:
        d = np.abs(centres - centres[p])
        d = np.minimum(d, q - d)
        keep &= d > KICK_S
    return np.flatnonzero(keep)


def quarter_groups(trials) -> dict:
    """{(file, robot, kind of quarter, bins, quarter's length in s): per repeat of that quarter, the mean
    heading rate (rad/s) in each bin (NaN where no frame fell)}."""
    groups: dict = {}
    for tr in trials:
        gaits = tr.gaits or (tr.gait,) * tr.robots
        for i in range(tr.robots):
            if not robot_alone(tr.pose, i, tr.params.robot.body_length):
                continue  # robots that may touch turn each other: their headings say nothing of the plate
            q = gaits[i].period() / 4.0
            nb = min(MAX_BINS, int(math.floor(q * tr.frame_rate_hz)))
            if nb < MIN_FRAMES:
                continue
            h = tr.pose[:, i, 2]
            ok = np.isfinite(h)
            t, h = tr.t[ok], h[ok]
            if len(t) < 3:
                continue
            dt = np.diff(t)
            adjacent = dt <= 1.6 / tr.frame_rate_hz  # no dropped frame between
            rate = np.diff(h)[adjacent] / dt[adjacent]
            mid = (0.5 * (t[1:] + t[:-1]))[adjacent]
            k = np.floor(mid / q).astype(int)
            b = np.minimum(((mid / q - k) * nb).astype(int), nb - 1)
            first = 2  # the first half period: the robot starts at rest at its first corner
            key0 = (tr.name.split(":")[0], i)
            for kk in np.unique(k[k >= first]):
                sel = k == kk
                row = np.full(nb, np.nan)
                for bb in np.unique(b[sel]):
                    row[bb] = rate[sel & (b == bb)].mean()
                groups.setdefault(key0 + (int(kk % 4), nb, q), []).append(row)
    return groups


def drag_test(trials) -> DragTest | None:
    """Arms dragging on the plate, read off the body's heading between the kicks of each swing (module
    docstring). None where no quarter has ``MIN_FRAMES`` frames."""
    from scipy.stats import chi2 as chi2_dist
    groups = quarter_groups(trials)
    if not groups:
        return None
    zs, rates, ses = [], [], []
    for (_, _, _, nb, q), rows in groups.items():
        a = np.array(rows)
        if len(a) < MIN_QUARTERS:
            continue
        with warnings.catch_warnings():  # a bin no repeat has a frame in is NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            mean_rate = np.nanmean(a, 0)
        keep = _steady_bins(mean_rate, q)
        if len(keep) < 2:
            continue
        sub = a[:, keep]
        per_q = np.array([np.nanmean(r) for r in sub if np.isfinite(r).any()])
        if len(per_q) < MIN_QUARTERS:
            continue
        se = per_q.std(ddof=1) / math.sqrt(len(per_q))
        if not se > 0:
            continue
        zs.append(per_q.mean() / se)
        rates.append(abs(per_q.mean()))
        ses.append(se)
    if not zs:
        return DragTest(0, float("nan"), float("nan"), float("nan"), float("nan"))
    z = np.asarray(zs)
    c2 = float(z @ z)
    return DragTest(len(z), c2, float(chi2_dist.sf(c2, len(z))), float(np.degrees(np.median(rates))),
                    float(np.degrees(np.max(rates))), float(np.degrees(np.median(ses))))
