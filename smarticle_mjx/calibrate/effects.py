"""The library of candidate effects: model extensions with parameters, bounds
and the residual signature that points at them.

A model effect changes the scene (``scene``) or the robots' gait clocks
(``phases``); a measurement effect (tracking noise) changes only what the
camera reports, and is predicted analytically in the residuals. Every
effect is absent at its parameters' ``null`` values.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

from ..scene import SceneParams


@dataclasses.dataclass(frozen=True)
class Param:
    """One fitted parameter.

    Attributes:
      name: key in the effect's values.
      lo, hi: bounds.
      null: value at which the effect is absent.
      probe: value used to measure the effect's signature.
      unit: for the report.
      log: fitted in log space (scale factors spanning decades).
      square: fitted in x^2 (noise levels: the residual is linear in variance).
    """

    name: str
    lo: float
    hi: float
    null: float
    probe: float
    unit: str
    log: bool = False
    square: bool = False


def value_to_unit(p: Param, x: float) -> float:
    """Parameter value ``x`` on the fit's unit interval (linear, log or square, as ``p`` says)."""
    if p.square:
        return (x ** 2 - p.lo ** 2) / (p.hi ** 2 - p.lo ** 2)
    if p.log:
        return (math.log(x) - math.log(p.lo)) / (math.log(p.hi) - math.log(p.lo))
    return (x - p.lo) / (p.hi - p.lo)


def unit_to_value(p: Param, u: float) -> float:
    """The value at ``u`` of the unit interval (clipped to it): the inverse of :func:`value_to_unit`."""
    u = min(max(u, 0.0), 1.0)
    if p.square:
        return math.sqrt(p.lo ** 2 + u * (p.hi ** 2 - p.lo ** 2))
    if p.log:
        return math.exp(math.log(p.lo) + u * (math.log(p.hi) - math.log(p.lo)))
    return p.lo + u * (p.hi - p.lo)


def bound_side(u: float) -> int:
    """Which bound a value on the fit's unit interval lies on: +1 the upper, -1 the lower (within 1 % of
    the range, where a bounded least-squares fit stops), 0 inside."""
    return 1 if u >= 0.99 else -1 if u <= 0.01 else 0


def on_bound_away_from_null(p: Param, u: float) -> int:
    """:func:`bound_side` of ``u``, or 0 where the effect's null lies on that same bound (a dead time at
    0 s is absent, not "at least" anything)."""
    side = bound_side(u)
    return side if side and bound_side(value_to_unit(p, p.null)) != side else 0


def _same(p: SceneParams, v: dict) -> SceneParams:
    return p


def _no_phase(v: dict, n: int, period: float) -> np.ndarray:
    return np.zeros(n)


@dataclasses.dataclass(frozen=True)
class Effect:
    """A candidate effect.

    Attributes:
      name: identifier.
      title: what a physicist calls it.
      params: fitted parameters.
      signature: the residuals it moves, in words (the report quotes it).
      measurement: True for effects of the camera, not of the robot.
      scene: (SceneParams, values) -> SceneParams.
      phases: (values, n robots, gait period s) -> [N] gait phase offsets (periods).
    """

    name: str
    title: str
    params: tuple[Param, ...]
    signature: str
    measurement: bool = False
    scene: Callable[[SceneParams, dict], SceneParams] = _same
    phases: Callable[[dict, int, float], np.ndarray] = _no_phase

    def null(self) -> dict:
        return {p.name: p.null for p in self.params}

    def probe(self) -> dict:
        return {p.name: p.probe for p in self.params}


def _servo(p: SceneParams, v: dict) -> SceneParams:
    s = v["servo_scale"]
    r = p.robot
    return p.replace(robot=dataclasses.replace(r, servo_kp=r.servo_kp * s, servo_kv=r.kv * s,
                                               servo_torque=r.servo_torque * s))


def _tilt(p: SceneParams, v: dict) -> SceneParams:
    return p.replace(plate_tilt_deg=(float(v["tilt_x_deg"]), float(v["tilt_y_deg"])))


def _friction(p: SceneParams, v: dict) -> SceneParams:
    return p.replace(plate_friction=p.plate_friction * v["friction_scale"])


def _aniso(p: SceneParams, v: dict) -> SceneParams:
    return p.replace(plate_friction_y_ratio=float(v["friction_y_ratio"]))


def _arm_plate(p: SceneParams, v: dict) -> SceneParams:
    mu = float(v["arm_plate_mu"])
    if mu <= 0:
        return p
    return p.replace(robot=dataclasses.replace(p.robot, arm_clearance=0.0), arm_plate_friction=mu)


def _phase(v: dict, n: int, period: float) -> np.ndarray:
    # robot i runs i * offset periods ahead of robot 0
    return np.arange(n) * v["phase_offset"]


def _lag(p: SceneParams, v: dict) -> SceneParams:
    # an extra first-order lag on top of the model's own (the default preset already has 10 ms)
    r = p.robot
    return p.replace(robot=dataclasses.replace(r, servo_timeconst=r.servo_timeconst + float(v["extra_lag_s"])))


def _delay(v: dict, n: int, period: float) -> np.ndarray:
    # a dead time: every robot's servo acts on the command of delay seconds ago
    return np.full(n, -float(v["dead_time_s"]) / period)


LIBRARY: tuple[Effect, ...] = (
    Effect("servo_response", "servo response limit (weaker, slower servo: gain and stall torque scaled)",
           (Param("servo_scale", 0.12, 1.0, 1.0, 0.4, "× nominal", log=True),),
           "arm angles lag and fall short of the commanded gait, most at small amplitudes; both arms, all robots",
           scene=_servo),
    Effect("servo_lag", "servo response lag (first-order, beyond the model's own)",
           (Param("extra_lag_s", 0.0, 0.1, 0.0, 0.02, "s"),),
           "arms follow the command late and round its corners, most visibly at small amplitudes, where a lag "
           "is a larger part of each move; both arms, all robots",
           scene=_lag),
    Effect("servo_dead_time", "servo dead time (the command acts late by a fixed time)",
           (Param("dead_time_s", 0.0, 0.1, 0.0, 0.02, "s"),),
           "the whole arm trajectory shifted later in time, by the same time at every amplitude; all robots",
           phases=_delay),
    Effect("phase_offset", "gait phase offset between robots",
           (Param("phase_offset", -0.25, 0.25, 0.0, 0.08, "periods"),),
           "arm-angle error in every robot but the first, a time shift of the whole gait; none for lone robots",
           phases=_phase),
    Effect("plate_tilt", "plate tilt",
           (Param("tilt_x_deg", -4.0, 4.0, 0.0, 2.0, "deg"), Param("tilt_y_deg", -4.0, 4.0, 0.0, 2.0, "deg")),
           "a drift of every robot in one plate direction, whatever its heading",
           scene=_tilt),
    Effect("friction_scale", "plate friction coefficient scale",
           (Param("friction_scale", 0.3, 3.0, 1.0, 0.7, "× nominal", log=True),),
           "within-cycle body wobble and per-cycle steps grow as friction falls, the same in every heading",
           scene=_friction),
    Effect("anisotropic_friction", "anisotropic plate friction (μ along plate y / along x)",
           (Param("friction_y_ratio", 0.3, 3.0, 1.0, 0.6, "ratio", log=True),),
           "body wobble and steps that depend on the robot's heading on the plate",
           scene=_aniso),
    Effect("arm_plate_contact", "arms touching the plate",
           (Param("arm_plate_mu", 0.0, 0.6, 0.0, 0.1, "μ"),),
           "large body rotations and steps driven by the arms' drag on the plate",
           scene=_arm_plate),
    Effect("tracking_noise", "tracking noise (camera, not robot)",
           (Param("noise_xy_mm", 0.0, 5.0, 0.0, 0.3, "mm", square=True),
            Param("noise_theta_deg", 0.0, 5.0, 0.0, 0.5, "deg", square=True)),
           "frame-to-frame jitter: excess variance of frame increments with no change of the cycle-averaged motion",
           measurement=True),
)

BY_NAME = {e.name: e for e in LIBRARY}


@dataclasses.dataclass(frozen=True)
class EffectSet:
    """Effects switched on, with their values: {effect name: {param: value}}."""

    values: tuple[tuple[str, tuple[tuple[str, float], ...]], ...] = ()

    @staticmethod
    def of(d: dict) -> "EffectSet":
        return EffectSet(tuple(sorted((k, tuple(sorted(v.items()))) for k, v in d.items())))

    def as_dict(self) -> dict:
        return {k: dict(v) for k, v in self.values}

    def scene(self, p: SceneParams) -> SceneParams:
        for name, v in self.as_dict().items():
            p = BY_NAME[name].scene(p, v)
        return p

    def phases(self, n: int, period: float) -> np.ndarray:
        out = np.zeros(n)
        for name, v in self.as_dict().items():
            out = out + BY_NAME[name].phases(v, n, period)
        return out

    def noise(self) -> tuple[float, float]:
        """Tracking noise (mm, deg)."""
        v = self.as_dict().get("tracking_noise", {})
        return float(v.get("noise_xy_mm", 0.0)), float(v.get("noise_theta_deg", 0.0))
