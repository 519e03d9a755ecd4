"""What the scripts of benchmarks/ share: result files, fixed samples of starts and lanes, candidate
numerics, the raw MuJoCo step rate. The benchmarks import the package only (this module and the
rest), never one another, so each script reads on its own and measures with the library's code.
"""

from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import time

import numpy as np

from . import configs as C
from .engine import Lanes, Scene, make_backend, steps_per_period
from .engine.batch import RetireRule, run_lanes
from .gait import GaitSpec
from .reduce import binding, gliders, stepcheck, transport

# Candidate numerics of the time-step study (docs/timestep.md): name -> SceneParams changes.
NUMERICS_REFERENCE = "ref"
# every candidate names its integrator, so that a preset's own numerics never leak into a candidate
NUMERICS: dict[str, dict] = {
    NUMERICS_REFERENCE: dict(timestep=6.25e-5, integrator="implicitfast"),
    "implicitfast-0.25ms": dict(timestep=2.5e-4, integrator="implicitfast"),  # the default before the study
    "implicitfast-0.5ms": dict(timestep=5e-4, integrator="implicitfast"),
    "implicitfast-1ms": dict(timestep=1e-3, integrator="implicitfast"),
    "implicit-0.5ms": dict(timestep=5e-4, integrator="implicit"),
    "implicit-1ms": dict(timestep=1e-3, integrator="implicit"),
    "discrete-0.5ms": dict(timestep=5e-4, integrator="discrete"),
    "discrete-1ms": dict(timestep=1e-3, integrator="discrete"),
    "Euler-0.5ms": dict(timestep=5e-4, integrator="Euler"),
    "implicitfast-0.5ms-tol1e-6": dict(timestep=5e-4, integrator="implicitfast", tolerance=1e-6),
    "implicitfast-0.5ms-iter5": dict(timestep=5e-4, integrator="implicitfast", iterations=5, ls_iterations=20),
    # after the kick-level mechanism (docs/timestep.md): RK4 has no implicit servo term to make the
    # contact solve inconsistent, and is converged at the kick level at 1 ms
    "RK4-1ms": dict(timestep=1e-3, integrator="RK4"),
    "RK4-1.5ms": dict(timestep=1.5e-3, integrator="RK4"),
    "RK4-2ms": dict(timestep=2e-3, integrator="RK4"),
    "implicitfast-0.35ms": dict(timestep=3.5e-4, integrator="implicitfast"),
    # near-contact sub-stepping (native backend): 0.5 ms while the robots are apart, 0.25 ms while some pair
    # may be within 4 mm (added after the contacts' family of docs/timestep.md)
    # (measured before SceneParams refused sub-stepping with implicitfast; kept to say what it measured)
    "implicitfast-0.5ms-sub2": dict(timestep=5e-4, integrator="implicitfast", contact_substeps=2, substep_gate=0.004),
    # after implicitfast-0.5ms-sub2 over-bound: discrete's slip per arm move does not depend on the step, so a
    # step that changes with the robots' distance cannot turn it into a drift (docs/timestep.md)
    "discrete-0.5ms-sub2": dict(timestep=5e-4, integrator="discrete", contact_substeps=2, substep_gate=0.004),
}
# a preset's own sub-stepping never leaks into a candidate either
for _c in NUMERICS.values():
    _c.setdefault("contact_substeps", 1)


def save_json(path, data: dict) -> None:
    """Write ``data`` to ``path`` atomically (a benchmark's resumable result file: an interrupted
    write leaves the previous file)."""
    path = pathlib.Path(path)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")  # parts running side by side each their own
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


# ---------------------------------------------------------------- the fidelity measures
# (benchmarks/fidelity_screen.py, glider_step.py; docs/fidelity.md, docs/model.md)

def run_pairs(params, gait: GaitSpec, poses, periods: int, quiet: int, robots=None):
    """Per-period poses [M, K, N, 5] and touches [M, K] of every lane, and the wall time.

    ``robots``: an ``imperfections.Draw`` of the scene's robots (lane i takes the phase jitter of row i)."""
    if robots is not None:
        params = robots.scene(params)
    scene = Scene.build(params, poses.shape[1])
    be = make_backend("native", scene)
    lanes = Lanes.from_gait(poses, gait)
    if robots is not None:
        lanes = robots.lanes(lanes, np.arange(len(poses)))
    m = len(poses)
    out_p = np.full((m, periods, poses.shape[1], 5), np.nan)
    out_t = np.zeros((m, periods), bool)

    def on_lanes(res):
        out_p[res.index] = res.poses
        if res.touched.shape[-1]:
            out_t[res.index] = res.touched[..., 0]

    t = time.perf_counter()
    try:
        info = run_lanes(be, lanes, periods, batch_size=64, chunk_periods=5,
                         rule=RetireRule(quiet_periods=quiet), on_lanes=on_lanes)
    finally:
        be.close()
    wall = time.perf_counter() - t
    steps = info["lane_periods"] * steps_per_period(lanes.period, params.timestep)
    return out_p, out_t, wall, steps


def lone_drift(params, amplitude: float, periods: int, imperfections: str | None = None, robots: int = 8,
               seed: int = 1) -> dict:
    """One robot's drift, mean step and absolute heading turn per cycle (W, deg;
    :func:`smarticle_mjx.reduce.transport.lone_robot`), at dt and dt/4.

    With ``imperfections``: ``robots`` robots drawn from that set (seed ``seed``), each alone on the
    plate; the net drift per cycle is their mean (and every robot's value is kept)."""
    out = {}
    gait = GaitSpec(amplitude)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    W = params.robot.body_length
    draws = [None]
    if imperfections:
        from . import imperfections as imp
        d = imp.draw(imperfections, robots, seed)
        draws = [d.robot(i) for i in range(robots)]
    for label, dt in (("dt", params.timestep), ("dt/4", params.timestep / 4)):
        p = dataclasses.replace(params, timestep=dt)
        poses = np.array([[[0.0, 0.0, 0.0, a0[0], a0[1]]]])
        net, step, turn, wall = [], [], [], 0.0
        for robot in draws:
            tr, _, w, _ = run_pairs(p, gait, poses, periods, quiet=0, robots=robot)
            xy = np.concatenate([poses[:, None, 0, :2], tr[:, :, 0, :2]], 1)[0]
            heading = np.concatenate([[0.0], tr[0, :, 0, 2]])
            m = transport.lone_robot(xy, heading, unit=W)
            net.append(m.net_W_per_cycle)
            step.append(m.step_W_per_cycle)
            turn.append(m.abs_heading_deg_per_cycle)
            wall += w
        out[label] = {"net_per_cycle_W": float(np.mean(net)), "step_per_cycle_W": float(np.mean(step)),
                      "turn_per_cycle_deg": float(np.mean(turn)), "wall_s": wall}
        if imperfections:
            out[label]["net_per_robot_W"] = net
    return out


def gliding(params, n: int, periods: int, seed: int, burn_in: int, save: pathlib.Path | None = None,
            robots=None, poses=None) -> dict:
    """Glider quantities at 90 deg from ``n`` random valid starts (or the starts ``poses`` [n, 2, 5] given);
    the per-period tracks go to ``save`` (.npz) so that metrics can be recomputed
    (``gliders.glide_summary``, ``gliders.glider_transport``) without simulating again."""
    W = params.robot.body_length
    gait = GaitSpec(90.0)
    poses = pair_starts(params, n, seed, 90.0) if poses is None else np.asarray(poses, float)
    tr, touched, wall, steps = run_pairs(params, gait, poses, periods, quiet=2, robots=robots)
    com = (tr[:, :, 0, :2] + tr[:, :, 1, :2]) / 2 / W
    r, th, ph = C.relative_coordinates(tr[:, :, 0], tr[:, :, 1], W)
    rel = np.stack([r, th, ph], -1)
    if save is not None:
        save.parent.mkdir(parents=True, exist_ok=True)
        # float64: a glider's centre moves ~1e-3 W in some periods, which float32 positions of ~1 W blur
        # into zero or random steps (direction persistence 0.25 instead of 0.38 for lab-lag)
        np.savez_compressed(save, com=com, rel=rel, touched=touched,
                            poses=poses)
    out = {"starts": n, "periods": periods, "burn_in": burn_in, "wall_s": wall, "steps": int(steps),
           "sim_s_per_wall_s": float(steps * params.timestep / wall)}
    out.update(gliders.glide_summary(com, rel, touched, burn_in).as_json())
    return out


def pb(params, amplitude: float, n: int, periods: int, seed: int, robots=None) -> dict:
    poses = pair_starts(params, n, seed, amplitude, r_range=(0.5, 2.5))
    _, touched, wall, steps = run_pairs(params, GaitSpec(amplitude), poses, periods, quiet=2, robots=robots)
    p = binding.binding_probability(touched, np.ones(n, bool))
    return {"n": n, "periods": periods, "end": dataclasses.astuple(p.end), "throughout": dataclasses.astuple(p.throughout),
            "wall_s": wall}


# ------------------------------------------------------------------ time-step checks
# (run by benchmarks/step_mechanism.py and benchmarks/step_checks.py; here so that a test checks the package's
# table against its sources without importing a benchmark)

STEP_CHECK_SEED = 1  # the glider-step check's starts and drawn robots (benchmarks/glider_step.py SEED)


def variant_params(dt: float, changes: dict, model: str = "lab-lag"):
    """The scene a variant runs: ``model``'s preset at step ``dt`` with ``changes`` (scene fields, and under
    "robot" robot fields: a robot parameter that is numerics in disguise, the gear stops' 2 dt)."""
    from . import presets
    changes = dict(changes)
    robot_changes = changes.pop("robot", {})
    params = dataclasses.replace(presets.params(model), timestep=dt, **changes)
    if robot_changes:
        params = dataclasses.replace(params, robot=dataclasses.replace(params.robot, **robot_changes))
    return params


def builds_preset(model: str, imperfections: str, row: dict, seed: int = STEP_CHECK_SEED) -> bool:
    """Does a benchmark row's scene equal the preset's at the row's step and numerics? Rows that change only
    the numerics (``stepcheck.KEYED_NUMERICS``) do; a row that changes a robot field enters only where that
    field builds the scene the preset builds anyway (the gear teeth's time constant at the 2 dt the step
    gives them), with the check's drawn robots (``seed``: the glider-step check's starts and robots)."""
    from . import imperfections as imp, scene
    changes = row["changes"]
    numerics = {k: v for k, v in changes.items() if k != "robot"}
    if set(numerics) - set(stepcheck.KEYED_NUMERICS):
        return False
    if not changes.get("robot"):
        return True
    robots = imp.draw(imperfections, 2, seed) if imperfections != "none" else None
    poses = [(0.0, 0.0, 0.0, 1.0, 1.0), (0.2, 0.0, 0.5, 1.0, 1.0)]
    xml = [scene.build_mjcf(p if robots is None else robots.scene(p), poses)
           for p in (variant_params(row["dt_s"], numerics, model), variant_params(row["dt_s"], changes, model))]
    return xml[0] == xml[1]


def collect_step_checks(results) -> list:
    """The glider-quantity checks of time steps that benchmarks/step_checks.py writes into the package's
    table (reduce/step_checks.json), read from the benchmark results in folder ``results`` (its docstring
    names the sources and what enters)."""
    from . import presets
    ROOT = pathlib.Path(results)
    out = {}
    g = json.loads((ROOT / "glider_step.json").read_text())
    base = presets.params(g["model"])
    ref_name = next(k for k in g["runs"] if "reference" in k)
    for name, row in g["runs"].items():
        if name == ref_name:
            continue
        dt = float(name.split()[0]) * 1e-3
        e = stepcheck.entry(g["model"], "none", dt, base.integrator, g["reference_dt_s"], "glider_step.json", row,
                            g["runs"][ref_name])
        out[stepcheck.key_of(e)] = e
    for source in ("step_mechanism.json", "step_mechanism_lab_runs30_stops-0.5ms_against-default.json",
                   "step_mechanism_lab_runs30_rerun.json",
                   "step_mechanism_substeps.json", "step_mechanism_substeps_discrete.json",
                   "step_mechanism_discrete_against-default.json"):
        if not (ROOT / source).exists():
            continue
        m = json.loads((ROOT / source).read_text())
        ref_name = m.get("reference") or next(k for k in m["runs"] if "reference" in k)
        for name, row in m["runs"].items():
            if name == ref_name or not builds_preset(m["model"], m.get("imperfections", "none"), row):
                continue
            ch = row["changes"]
            label = stepcheck.numerics(ch.get("integrator", base.integrator), ch.get("contact_substeps", 1),
                                       ch.get("substep_gate", base.substep_gate))
            e = stepcheck.entry(m["model"], m.get("imperfections", "none"), row["dt_s"], label,
                                m["runs"][ref_name]["dt_s"], source, row, m["runs"][ref_name])
            out.setdefault(stepcheck.key_of(e), e)  # glider_step's measurement of the same key comes first
    return list(out.values())
