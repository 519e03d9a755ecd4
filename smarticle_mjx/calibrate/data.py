"""Measured trials in the interchange format (CSV + JSON sidecar, see docs/calibration.md), read by
:mod:`smarticle_mjx.tracks` (the format's one reader and writer) and held as :class:`Trial`.

CSV: one row per robot per frame, ``trial, t, robot, x, y, theta, alpha1,
alpha2`` in s, m, rad; ``alpha1``/``alpha2`` may be empty; frames need not
be evenly spaced; rows may be missing. Sidecar ``NAME.json``: robots, gait
(kind square|symmetric, amplitude_deg, period_s, chirality cw|ccw; or a list
of such, one per robot),
optional robot overrides, plate friction, frame rate, and an optional circular
boundary ``{"radius": m, "centre": [x, y]}`` (positions are shifted so that it
is centred on the origin, where the model's wall is).
"""

from __future__ import annotations

import dataclasses
import pathlib

import numpy as np

from .. import tracks
from ..gait import GaitSpec
from ..scene import SceneParams
from ..tracks import TrackError as DataError  # noqa: F401 (calibrate's name for a track it cannot read)


@dataclasses.dataclass
class Trial:
    """One tracked experiment.

    Attributes:
      name: ``FILE:trial``.
      t: [F] frame times (s), increasing.
      pose: [F, N, 3] x, y (m), heading (rad, unwrapped); NaN where occluded.
      arms: [F, N, 2] arm angles (rad), NaN where not tracked; None if the
        file tracks no arm angles at all.
      gait: the commanded gait of robot 0 (the trial's clock).
      params: scene parameters with the sidecar's overrides.
      frame_rate_hz: nominal frame rate from the sidecar.
      gaits: every robot's commanded gait; None: all run ``gait``.
      measured: the sidecar's measured nominal parameters {name: (value, sd)}
        (already the model's values in ``params``; calibrate.nominal uses
        them as priors).
    """

    name: str
    t: np.ndarray
    pose: np.ndarray
    arms: np.ndarray | None
    gait: GaitSpec
    params: SceneParams
    frame_rate_hz: float
    gaits: tuple[GaitSpec, ...] | None = None
    measured: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        n = self.pose.shape[1]
        if self.gaits is None:
            self.gaits = (self.gait,) * n
        else:
            self.gaits = tuple(self.gaits)
            if len(self.gaits) != n or self.gaits[0] != self.gait:
                raise ValueError(f"{self.name}: gaits must list {n} gaits, the first being the trial's gait")

    @property
    def robots(self) -> int:
        return self.pose.shape[1]

    @property
    def periods(self) -> np.ndarray:
        """[N] each robot's gait period (s)."""
        return np.array([g.period() for g in self.gaits])

    @property
    def one_gait(self) -> bool:
        """Whether every robot runs the same gait."""
        return len(set(self.gaits)) == 1

    def with_gaits(self, fn) -> "Trial":
        """This trial with every robot's gait replaced by ``fn(gait)``."""
        gaits = tuple(fn(g) for g in self.gaits)
        return dataclasses.replace(self, gait=gaits[0], gaits=gaits)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])


# The numerics the calibration's model runs with, unless ``--set`` names the field:
# MuJoCo's discrete integrator at the preset's step. Lone robots are what a calibration compares, and what
# moves a lone body is the slip of each arm move. With implicitfast that slip carries a term of the step
# (2.9x its converged value at 0.25 ms, docs/timestep.md "the kick level"); with discrete it is converged at
# every step (2.94e-5 W per arm move at 0.0625-1 ms). A measured robot has no such term, and nor has the
# stress suite's independent simulator, whose servo torque is explicit. smx synth makes data with the same.
NUMERICS = (("integrator", "discrete"),)


def with_numerics(overrides=()) -> tuple:
    """``overrides`` (``--set`` items or (field, value) pairs) after the calibration's ``NUMERICS``, minus
    any field that ``overrides`` names itself."""
    from .. import presets
    given = presets.overrides(overrides)
    named = {k for k, _ in given}
    return tuple((k, v) for k, v in NUMERICS if k not in named) + given


def load_csv(path, model: str | None = None, overrides=()) -> list[Trial]:
    """All trials of one CSV file with its sidecar, compared with preset
    ``model`` (default: the sidecar's, else the default preset) run with the calibration's ``NUMERICS``
    and changed by ``overrides`` (``--set``; presets.overrides), before the sidecar's measured values."""
    from .. import presets
    from .nominal import BY_NAME, apply
    out = []
    for r in tracks.read_csv(path, model):
        try:
            r = dataclasses.replace(r, params=presets.apply(r.params, with_numerics(overrides)))
        except ValueError as e:
            raise DataError(f"{pathlib.Path(path).name}: {e}") from None
        measured = {name: (v, sd) for name, v, sd in r.measured}
        if "arm_length" in measured and "arm2_length" not in measured:  # one ruler value for both arms
            measured["arm2_length"] = measured["arm_length"]
        unknown = sorted(set(measured) - set(BY_NAME))
        if unknown:
            raise DataError(f"{pathlib.Path(path).name}: unknown measured values {unknown} "
                            f"(known: {', '.join(BY_NAME)})")
        # a measured value is the model's value (the fit's bounds are set around it) and its prior
        params = r.params
        if measured:
            params = apply(params, {k: v for k, (v, _) in measured.items()})
            try:
                params.validate()
            except ValueError as e:
                raise DataError(f"{pathlib.Path(path).name}: measured values: {e}") from None
        out.append(Trial(r.name, r.t, r.poses[..., :3], r.poses[..., 3:] if r.arms_tracked else None, r.gaits[0],
                         params, r.frame_rate_hz, r.gaits, measured))
    return out


def load(path, model: str | None = None, overrides=()) -> list[Trial]:
    """Trials from one CSV (with sidecar) or every CSV in a directory (see :func:`load_csv` for ``model``
    and ``overrides``)."""
    path = pathlib.Path(path)
    if path.is_dir():
        files = sorted(path.glob("*.csv"))
        if not files:
            raise DataError(f"{path} holds no .csv files")
        return [t for f in files for t in load_csv(f, model, overrides)]
    if not path.exists():
        raise DataError(f"no data at {path}")
    if path.suffix.lower() != ".csv":
        raise DataError(f"measured data must be .csv with a .json sidecar, got {path.name}")
    return load_csv(path, model, overrides)


def priors(trials: list[Trial]) -> dict:
    """The measured values every trial's sidecar states, {name: (value, sd)}; a name measured differently
    in two files is refused (DataError): one robot, one value."""
    out: dict = {}
    for tr in trials:
        for k, v in tr.measured.items():
            if k in out and out[k] != v:
                raise DataError(f"measured {k} is {out[k]} in one file and {v} in another ({tr.name})")
            out[k] = v
    return out
