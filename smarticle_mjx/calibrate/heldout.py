"""The held-out trials simulated with the preset model and with the calibrated one: what the report's
metrics and figures compare with what the camera saw. A stage of its own (:func:`compare_heldout`), run
after the calibration and before its report, so that the report only formats (``report.write``)."""

from __future__ import annotations

import dataclasses

import numpy as np

from .data import Trial
from .effects import EffectSet
from .nominal import apply as apply_nominal
from .residuals import metrics
from .sim import simulate_trials

NOISE_SEED = 0  # the seed of the fitted tracking noise added to the calibrated model's tracks


@dataclasses.dataclass(frozen=True)
class HeldoutComparison:
    """The held-out trials (in the calibration's order), the model's tracks of each ([T, R, 5] poses and arm
    angles) with the preset parameters (``before``) and with the calibrated model (``after``: its nominal
    values and added effects, with a fitted tracking noise drawn onto the tracks, seeded, since the camera
    would see that noise too), and the report's metrics of each against the measured tracks
    (``residuals.metrics``)."""

    trials: tuple[Trial, ...]
    before: tuple[np.ndarray, ...]
    after: tuple[np.ndarray, ...]
    metrics_before: dict
    metrics_after: dict

    def metrics_json(self) -> dict:
        """``report.json``'s ``metrics_heldout``."""
        return {"before": self.metrics_before, "after": self.metrics_after}


def compare_heldout(cal, trials: list[Trial]) -> HeldoutComparison:
    """:class:`HeldoutComparison` of a ``stages.calibrate`` result ``cal`` over the held-out ones of
    ``trials`` (those ``cal`` names held out)."""
    names = set(cal.summary["trials"]["heldout"])
    held = [t for t in trials if t.name in names]
    final: EffectSet = cal.effects
    before = simulate_trials(held, scene_for=lambda tr: tr.params)
    after = simulate_trials(held, scene_for=lambda tr: final.scene(apply_nominal(tr.params, cal.nominal)),
                            phase_for=lambda tr: final.phases(tr.robots, tr.periods))
    sxy, sth = final.noise()
    if sxy or sth:
        rng = np.random.default_rng(NOISE_SEED)
        for trk in after:
            trk[..., :2] += rng.normal(0, sxy / 1e3, trk[..., :2].shape)
            trk[..., 2] += rng.normal(0, np.radians(sth), trk[..., 2].shape)
    return HeldoutComparison(tuple(held), tuple(before), tuple(after), metrics(held, before), metrics(held, after))
