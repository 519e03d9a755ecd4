"""Measured-like data from the model with hidden effects (``smx synth``).

Writes one CSV + sidecar per amplitude in the interchange format. The
sidecar declares what an experimenter would write down (robots, gait,
plate friction, frame rate), never the effects: calibration must find them.
Besides the library's effects, ``arm_bias_deg`` adds an effect that is not
in the library (a constant misreading of every robot's second arm, as from
a misplaced marker), for testing that calibration says "unexplained".
"""

from __future__ import annotations

import csv
import json
import pathlib

import numpy as np

from ..configs import pose_from_relative, poses_valid
from ..gait import GaitSpec
from .. import presets
from ..plots import check_out_dir
from ..scene import SceneParams
from .data import Trial, with_numerics
from .effects import BY_NAME, EffectSet
from .sim import simulate_trials


def parse_effect(text: str) -> tuple[str, dict]:
    """'plate_tilt:tilt_x_deg=2,tilt_y_deg=0' -> ('plate_tilt', {...}) with unnamed params at null."""
    name, _, rest = text.partition(":")
    if name not in BY_NAME:
        raise ValueError(f"unknown effect {name!r} (known: {', '.join(BY_NAME)})")
    e = BY_NAME[name]
    vals = e.null()
    for item in filter(None, rest.split(",")):
        k, _, v = item.partition("=")
        if k not in vals:
            raise ValueError(f"effect {name} has no parameter {k!r} (has: {', '.join(vals)})")
        try:
            vals[k] = float(v)
        except ValueError:
            raise ValueError(f"effect {name}: {k} must be a number, got {v!r}") from None
        p = next(p for p in e.params if p.name == k)
        if not p.lo <= vals[k] <= p.hi:
            raise ValueError(f"effect {name}: {k} = {vals[k]} outside [{p.lo}, {p.hi}]")
    return name, vals


def _starts(rng, robots: int, separation_w: float, params: SceneParams, a0) -> np.ndarray:
    w = params.robot.body_length
    for _ in range(1000):
        p = np.zeros((robots, 5))
        p[0, :2] = rng.uniform(-0.05, 0.05, 2)
        p[0, 2] = rng.uniform(-np.pi, np.pi)
        for i in range(1, robots):
            ang = rng.uniform(0, 2 * np.pi)
            x, y, h = pose_from_relative(separation_w * i, ang, rng.uniform(0, 2 * np.pi), w)
            c, s = np.cos(p[0, 2]), np.sin(p[0, 2])
            p[i, :3] = p[0, 0] + c * x - s * y, p[0, 1] + s * x + c * y, p[0, 2] + h
        p[:, 3:] = a0
        if robots == 1 or poses_valid(p, params.robot):
            return p
    raise ValueError("could not place non-overlapping robots; increase the separation")


def synth(out_dir, robots: int = 1, trials: int = 6, periods: int = 6, amplitudes=(30.0, 90.0),
          effects: dict | None = None, noise_xy_mm: float = 0.0, noise_theta_deg: float = 0.0,
          arm_noise_deg: float = 0.3, arms_tracked: bool = True, frame_rate_hz: float = 30.0,
          jitter_s: float = 0.002, occlusion: float = 0.03, arm_bias_deg: float = 0.0,
          separation_w: float = 3.0, chirality: str = "ccw", seed: int = 0,
          model: str | None = None, overrides=()) -> list[pathlib.Path]:
    """Write trials per amplitude into ``out_dir`` (created if absent); returns the CSV paths.

    ``model`` is the preset that makes the data (default: the default
    preset), changed field by field by ``overrides`` (``--set``,
    presets.overrides); both go into every sidecar. The model runs with the
    numerics ``smx calibrate`` runs it with (``data.NUMERICS``, where
    ``overrides`` does not name the field), so that the data and the
    calibration's model differ only by what is hidden in the data.

    Trials of every amplitude are interleaved in the files' trial ids so
    that a held-out split sees every amplitude.
    """
    out_dir = pathlib.Path(out_dir)
    noise = (effects or {}).get("tracking_noise")  # the effect sets the noise levels
    if noise:
        noise_xy_mm, noise_theta_deg = noise["noise_xy_mm"], noise["noise_theta_deg"]
    preset = presets.get(model)
    overrides = presets.overrides(overrides)
    params = presets.apply(preset.params, with_numerics(overrides))  # the numerics smx calibrate runs
    if robots < 1 or trials < 1 or periods < 1:
        raise ValueError("robots, trials and periods must be >= 1")
    if not frame_rate_hz > 0 or not 0 <= occlusion < 0.5 or jitter_s < 0 or jitter_s * frame_rate_hz >= 0.5:
        raise ValueError("frame rate must be positive, occlusion in [0, 0.5), jitter below half a frame")
    if min(noise_xy_mm, noise_theta_deg, arm_noise_deg) < 0:
        raise ValueError("noise levels must be >= 0")
    gaits = [GaitSpec(amplitude_deg=float(a), chirality=chirality) for a in amplitudes]
    for gait in gaits:
        gait.validate(params.robot.servo_speed, params.robot.arm_limit_deg)
    if not out_dir.parent.is_dir():
        raise ValueError(f"output directory {out_dir.parent} does not exist")
    check_out_dir(out_dir)
    if out_dir.exists() and any(out_dir.glob("*.csv")):
        raise ValueError(f"{out_dir} already holds data; choose an empty folder")
    out_dir.mkdir(exist_ok=True)  # only once every input is known to be good
    rng = np.random.default_rng(seed)
    eff = EffectSet.of({k: v for k, v in (effects or {}).items() if k != "tracking_noise"})
    written = []
    for amp, gait in zip(amplitudes, gaits):
        T = gait.period()
        templates = []
        for k in range(trials):
            nf = int(periods * T * frame_rate_hz) + 1
            t = np.arange(nf) / frame_rate_hz
            t[1:] += rng.uniform(-jitter_s, jitter_s, nf - 1)
            pose = np.full((nf, robots, 3), np.nan)
            start = _starts(rng, robots, separation_w, params, gait.setpoints(0.0, params.robot.servo_speed))
            pose[0] = start[:, :3]
            arms = np.full((nf, robots, 2), np.nan)
            arms[0] = start[:, 3:]
            templates.append(Trial(f"synth:{k}", t, pose, arms, gait, params, frame_rate_hz))
        tracks = simulate_trials(templates, scene_for=lambda tr: eff.scene(tr.params),
                                 phase_for=lambda tr: eff.phases(tr.robots, tr.periods))
        path = out_dir / f"a{amp:05.1f}.csv"
        tmp = path.with_name(path.name + ".part")
        with open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["trial", "t", "robot", "x", "y", "theta", "alpha1", "alpha2"])
            for k, (tpl, tr) in enumerate(zip(templates, tracks)):
                tr = tr.copy()
                tr[..., :2] += rng.normal(0, noise_xy_mm / 1e3, tr[..., :2].shape)
                tr[..., 2] += rng.normal(0, np.radians(noise_theta_deg), tr[..., 2].shape)
                tr[..., 3:] += rng.normal(0, np.radians(arm_noise_deg), tr[..., 3:].shape)
                tr[..., 4] += np.radians(arm_bias_deg)
                for j, tj in enumerate(tpl.t):
                    for i in range(robots):
                        if j > 0 and rng.random() < occlusion:
                            continue
                        x, y, h, a1, a2 = tr[j, i]
                        arm = [f"{a1:.6f}", f"{a2:.6f}"] if arms_tracked else ["", ""]
                        w.writerow([k, f"{tj:.5f}", i, f"{x:.7f}", f"{y:.7f}", f"{h:.6f}", *arm])
        side = {"robots": robots, "model": preset.name,
                **({"overrides": presets.overrides_json(overrides)} if overrides else {}),
                "gait": {"kind": "square", "amplitude_deg": float(amp), "period_s": T, "chirality": chirality},
                "plate": {"friction": params.plate_friction}, "frame_rate_hz": frame_rate_hz}
        path.with_suffix(".json").write_text(json.dumps(side, indent=2))
        tmp.replace(path)
        written.append(path)
    return written


# Reference cases: each hides one effect (or none, or one outside the library)
# in single-robot trials at 30 deg (pairs, far apart, for the phase offset).
# Sizes are chosen to be visible above a good tracker's resolution.
BASE_CASE = dict(trials=6, periods=8, amplitudes=(30.0,), noise_xy_mm=0.02, noise_theta_deg=0.02)
CASES: dict[str, dict] = {
    "servo_response": dict(effects={"servo_response": {"servo_scale": 0.35}}),
    "servo_lag": dict(effects={"servo_lag": {"extra_lag_s": 0.03}}),
    "servo_dead_time": dict(effects={"servo_dead_time": {"dead_time_s": 0.03}}),
    "phase_offset": dict(robots=2, effects={"phase_offset": {"phase_offset": 0.1}}),
    "plate_tilt": dict(effects={"plate_tilt": {"tilt_x_deg": 3.5, "tilt_y_deg": -1.0}}),
    "friction_scale": dict(effects={"friction_scale": {"friction_scale": 0.55}}),
    "anisotropic_friction": dict(effects={"anisotropic_friction": {"friction_y_ratio": 0.5}}),
    "arm_plate_contact": dict(effects={"arm_plate_contact": {"arm_plate_mu": 0.2}}),
    "tracking_noise": dict(noise_xy_mm=0.5, noise_theta_deg=1.0),
    "clean": dict(noise_xy_mm=0.0, noise_theta_deg=0.0),
    "unexplained_arm_bias": dict(arm_bias_deg=5.0),
}


def case_truth(name: str) -> dict:
    """{effect: {param: true value}} hidden in a reference case."""
    c = CASES[name]
    if name == "tracking_noise":
        return {"tracking_noise": {"noise_xy_mm": c["noise_xy_mm"], "noise_theta_deg": c["noise_theta_deg"]}}
    return c.get("effects", {})


def make_case(name: str, out_dir, seed: int = 1) -> list[pathlib.Path]:
    """Write the data of a reference case."""
    return synth(out_dir, **{**BASE_CASE, **CASES[name], "seed": seed})
