"""An arm read off its commanded corners by a constant, measured without the model.

A servo at rest holds its arm where its reference is: a position loop leaves no error once the arm has
stopped (nothing loads a hinge about its vertical axis at rest), and a servo that falls short of its
corners falls short of both alike. So a tracked arm that rests at +a + b and -a + b, where the gait
commands +a and -a, is read (or mounted) b off: a tracker's marker set beside the hinge's axis, an angle
zero taken from a photograph. That is outside the library's effects: the model's arm goes where it is
sent, and an arm whose every frame is b off adds b over the arm's noise to every arm residual. Beside
it, a servo lag or dead time gained nothing held out (stress seed 2062, set 22: +0 % where the misread arm
left a held-out error of 1377; docs/calibration.md).

The reading: each frame is assigned to the commanded corner angle nearest it; a run of consecutive frames
on one corner (from the arm crossing toward it to the arm crossing away) is one *rest*, whose middle third
gives its level, the median angle there minus the corner: the arm has arrived by then and not yet left (a
square gait's arm crosses half-way through its move and leaves at the next switch, so it rests through the
middle half of a run even where the move fills its whole quarter). Per robot and arm, over every trial,

    offset    = (mean level of rests at the upper corner + mean level at the lower) / 2
    shortfall = (mean level at the lower corner - mean level at the upper) / 2

(a servo that stops short has shortfall > 0 and no offset). The offset's standard error comes from the
spread of the levels. An offset is *present* where it exceeds ``MIN_OFFSET_DEG`` and ``Z`` standard errors.
:func:`without_offsets` takes present offsets out of the arm tracks; the calibration then fits the model
to arms read as the gait commands them, and reports the offset as a finding outside the library.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .observables import commanded

MIN_OFFSET_DEG = 1.0
Z = 5.0
MIN_RESTS = 4  # rests at each corner an arm needs for a reading


@dataclasses.dataclass(frozen=True)
class ArmOffset:
    """One robot's arm (``arm`` 0 = alpha1, 1 = alpha2), all angles in degrees, unrounded."""

    robot: int
    arm: int
    offset_deg: float
    se_deg: float
    shortfall_deg: float
    rests: int

    @property
    def present(self) -> bool:
        return bool(abs(self.offset_deg) > MIN_OFFSET_DEG and abs(self.offset_deg) > Z * self.se_deg)

    def as_dict(self) -> dict:
        return {**dataclasses.asdict(self), "present": self.present}


@dataclasses.dataclass(frozen=True)
class ArmOffsetReading:
    """Every tracked arm's reading; ``applicable`` False where no arm has ``MIN_RESTS`` rests at each corner."""

    arms: tuple[ArmOffset, ...]

    @property
    def applicable(self) -> bool:
        return bool(self.arms)

    @property
    def present(self) -> tuple[ArmOffset, ...]:
        return tuple(a for a in self.arms if a.present)

    def describe(self) -> str:
        """One line a report prints."""
        if not self.applicable:
            return "no arm rests at its corners often enough to read an offset"
        if not self.present:
            worst = max(self.arms, key=lambda a: abs(a.offset_deg))
            return (f"every tracked arm rests at its commanded corners (largest offset {worst.offset_deg:+.2f} "
                    f"+- {worst.se_deg:.2f} deg)")
        return "; ".join(f"robot {a.robot} arm {a.arm + 1} rests {a.offset_deg:+.2f} +- {a.se_deg:.2f} deg off its "
                         f"commanded corners ({a.rests} rests)" for a in self.present)

    def as_dict(self) -> dict:
        return {"applicable": self.applicable, "arms": [a.as_dict() for a in self.arms],
                "min_offset_deg": MIN_OFFSET_DEG, "z": Z}


def corners(gait) -> list[np.ndarray]:
    """Per arm, the angles (rad, sorted) it is commanded to rest at: the values of the command
    (``observables.commanded``, the gait at an instant servo)."""
    sp = commanded(gait)
    return [np.unique(np.round(sp[:, k], 9)) for k in range(2)]


def rest_levels(angle: np.ndarray, corner_angles: np.ndarray) -> list[tuple[int, float]]:
    """(corner index, level in rad) of each rest of one arm's track [F] (NaN where not tracked): runs of
    tracked frames nearest one corner (an untracked frame does not end a run: the tracked frames on either
    side of it tell whether the arm crossed); a run's level is the median of its middle third minus the
    corner. The first and last runs of the track are left out (cut by the track's ends)."""
    angle = angle[np.isfinite(angle)]
    near = np.argmin(np.abs(angle[:, None] - corner_angles[None, :]), axis=1)
    out = []
    edges = np.flatnonzero(np.diff(near)) + 1
    starts, ends = np.r_[0, edges], np.r_[edges, len(angle)]
    for s, e in list(zip(starts, ends))[1:-1]:
        n = e - s
        if n < 3:
            continue
        c = near[s]
        out.append((int(c), float(np.median(angle[s + n // 3:e - n // 3]) - corner_angles[c])))
    return out


def read_offsets(trials) -> ArmOffsetReading:
    """Each tracked arm's offset from its commanded corners, pooled over ``trials`` (robot by robot: the
    same robot index is taken to be the same robot in every trial)."""
    levels: dict = {}
    for tr in trials:
        if tr.arms is None:
            continue
        for i in range(tr.robots):
            cs = corners(tr.gaits[i])
            for k in range(2):
                if len(cs[k]) != 2:  # an arm commanded to more than two angles: no upper and lower corner
                    continue
                for c, lv in rest_levels(tr.arms[:, i, k], cs[k]):
                    levels.setdefault((i, k), ([], []))[c].append(lv)
    arms = []
    for (i, k), (low, up) in sorted(levels.items()):
        if len(low) < MIN_RESTS or len(up) < MIN_RESTS:
            continue
        low, up = np.degrees(low), np.degrees(up)
        se = 0.5 * math.sqrt(np.var(low, ddof=1) / len(low) + np.var(up, ddof=1) / len(up))
        arms.append(ArmOffset(i, k, float(0.5 * (np.mean(low) + np.mean(up))), float(se),
                              float(0.5 * (np.mean(low) - np.mean(up))), len(low) + len(up)))
    return ArmOffsetReading(tuple(arms))


def without_offsets(trials, reading: ArmOffsetReading) -> list:
    """``trials`` with each present offset taken out of its arm's track (every trial; others unchanged)."""
    if not reading.present:
        return list(trials)
    out = []
    for tr in trials:
        if tr.arms is None:
            out.append(tr)
            continue
        arms = tr.arms.copy()
        for a in reading.present:
            if a.robot < tr.robots:
                arms[:, a.robot, a.arm] -= math.radians(a.offset_deg)
        out.append(dataclasses.replace(tr, arms=arms))
    return out
