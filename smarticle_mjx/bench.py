"""What the scripts of benchmarks/ share: result files, fixed samples of starts and lanes, candidate
numerics, the raw MuJoCo step rate. The benchmarks import the package only (this module and the
rest), never one another, so each script reads on its own and measures with the library's code.
"""

from __future__ import annotations

import json
import os
import pathlib
import time

import numpy as np

from . import configs as C
from .engine import Lanes
from .gait import GaitSpec

# Candidate numerics of the time-step study (docs/timestep.md): name -> SceneParams changes.
NUMERICS_REFERENCE = "ref"
NUMERICS: dict[str, dict] = {
    NUMERICS_REFERENCE: dict(timestep=6.25e-5),
    "implicitfast-0.25ms": dict(timestep=2.5e-4),  # the default before the study
    "implicitfast-0.5ms": dict(timestep=5e-4),
    "implicitfast-1ms": dict(timestep=1e-3),
    "implicit-0.5ms": dict(timestep=5e-4, integrator="implicit"),
    "implicit-1ms": dict(timestep=1e-3, integrator="implicit"),
    "discrete-0.5ms": dict(timestep=5e-4, integrator="discrete"),
    "discrete-1ms": dict(timestep=1e-3, integrator="discrete"),
    "Euler-0.5ms": dict(timestep=5e-4, integrator="Euler"),
    "implicitfast-0.5ms-tol1e-6": dict(timestep=5e-4, tolerance=1e-6),
    "implicitfast-0.5ms-iter5": dict(timestep=5e-4, iterations=5, ls_iterations=20),
}


def save_json(path, data: dict) -> None:
    """Write ``data`` to ``path`` atomically (a benchmark's resumable result file: an interrupted
    write leaves the previous file)."""
    path = pathlib.Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    os.replace(tmp, path)


def pair_starts(params, n: int, seed: int, amplitude: float, r_range=(0.8, 2.0)) -> np.ndarray:
    """[n, 2, 5] valid pair poses at the gait's first corner, (|r|, θ, φ) uniform with |r| in
    ``r_range`` W, from ``seed``: the fixed starts of the fidelity and time-step studies."""
    gait = GaitSpec(amplitude)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    return C.sample_valid_pairs(n, np.random.default_rng(seed), r_range, a0[0], a0[1], params.robot)


def fixed_starts(params, n: int, seed: int = 0, amplitude: float = 90.0, pool: int = 400) -> np.ndarray:
    """The first ``n`` starts of one fixed pool of ``pool`` (:func:`pair_starts`; the sampler draws in
    batches, so only a fixed pool gives every n <= pool the same first starts): the time-step study's
    configurations."""
    return pair_starts(params, max(n, pool), seed, amplitude)[:n]


_LANES: dict = {}


def sample_lanes(n: int, params, gait: GaitSpec, seed: int = 0, pool: int = 16384) -> Lanes:
    """The first ``n`` of one fixed sample of valid pair lanes (|r| 0.8-2.0 W), so that every batch
    size (and backend) of the engine benchmarks runs a prefix of the same workload."""
    key = (id(params), gait.amplitude, seed)
    if key not in _LANES or _LANES[key].size < n:
        a0 = gait.setpoints(0.0, params.robot.servo_speed)
        poses = C.sample_valid_pairs(max(n, pool), np.random.default_rng(seed), (0.8, 2.0), a0[0], a0[1])
        _LANES[key] = Lanes.from_gait(poses, gait)
    return _LANES[key].take(np.arange(n))


def mj_step_rate(model, seconds: float = 3.0) -> float:
    """Single-thread ``mj_step`` calls per second of ``model`` from its first keyframe."""
    import mujoco
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, 0)
    n, t = 0, time.perf_counter()
    while time.perf_counter() - t < seconds:
        for _ in range(1000):
            mujoco.mj_step(model, d)
        n += 1000
    return n / (time.perf_counter() - t)
