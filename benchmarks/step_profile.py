"""What one MuJoCo step of a glider costs, and why halving the step doubles a scan's cost.

The default-step issue asks for numerics that pass the glider check (docs/timestep.md) at no more than
the 0.5 ms default's cost; implicitfast at 0.25 ms passes and costs 1.74-1.98x. This script asks
whether any part of a step gets cheaper as the step shrinks (a warm-started solver converging in fewer
iterations, fewer contacts), which is the only way a finer step could cost less than its step count:
single-thread ``mj_step`` on the glider check's starts (``glider_step.py``: 128 random valid pairs,
seed 1, 90 deg, ``lab-lag``; the first ``--starts`` of them), ``--periods`` periods from rest, each
step's time split by MuJoCo's own stage timers (``mjData.timer``, with ``mjcb_time`` set), the
solver's iterations and the contacts per step; the numerics in interleaved passes so the machine's
load falls on all alike.

    python benchmarks/step_profile.py            # ~2 minutes on one core

Writes results/step_profile.json.
"""

from __future__ import annotations

import argparse
import pathlib
import platform
import time

import mujoco
import numpy as np

from scan_gap import _cpu
from smarticle_mjx import presets
from smarticle_mjx.bench import pair_starts, save_json
from smarticle_mjx.engine.core import Lanes, Scene, lane_controls, steps_per_period
from smarticle_mjx.gait import GaitSpec

NUMERICS = {"0.5 ms": dict(timestep=5e-4), "0.25 ms": dict(timestep=2.5e-4)}
BASE = "0.5 ms"
# MuJoCo's stage timers, grouped as a step runs them (mjtTimer; the position stage holds the collision
# and constraint-assembly timers, reported apart)
STAGES = {"position (kinematics, inertia)": ("mjTIMER_POSITION",), "collision": ("mjTIMER_POS_COLLISION",),
          "constraint assembly": ("mjTIMER_POS_MAKE", "mjTIMER_POS_PROJECT"), "velocity": ("mjTIMER_VELOCITY",),
          "actuation": ("mjTIMER_ACTUATION",), "solver": ("mjTIMER_CONSTRAINT",), "integration": ("mjTIMER_ADVANCE",)}


def profile(params, poses, gait: GaitSpec, periods: int) -> dict:
    """Single-thread mj_step over every start: in-step time, stage times, iterations, contacts."""
    sc = Scene.build(params, 2)
    m, d = sc.model, mujoco.MjData(sc.model)
    lanes = Lanes.from_gait(poses, gait)
    n = steps_per_period(gait.period(), params.timestep) * periods
    u = lane_controls(sc, lanes, np.arange(n) * params.timestep)
    qpos, act = sc.qpos_from_poses(poses), sc.initial_act(lanes)
    timer = np.zeros(len(d.timer))
    niter = ncon = steps = 0
    wall = time.perf_counter()
    for b in range(len(poses)):
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.act[:] = qpos[b], act[b]
        mujoco.mj_forward(m, d)
        for t in range(1, len(d.timer)):  # mj_forward's own time is not a step's
            d.timer[t].duration, d.timer[t].number = 0.0, 0
        for k in range(n):
            d.ctrl[:] = u[b, k]
            mujoco.mj_step(m, d)
            niter += int(d.solver_niter[0])
            ncon += d.ncon
        steps += n
        timer += np.array([x.duration for x in d.timer])
    wall = time.perf_counter() - wall
    name = [mujoco.mjtTimer(i).name for i in range(len(d.timer))]
    t = dict(zip(name, timer))
    step = t["mjTIMER_STEP"]
    stages = {s: float(sum(t[k] for k in ks)) for s, ks in STAGES.items()}
    stages["position (kinematics, inertia)"] -= stages["collision"] + stages["constraint assembly"]
    return {"steps": steps, "step_us": 1e6 * step / steps, "wall_s": wall,
            "step_s_per_sim_s": step / (steps * params.timestep),
            "solver_iterations_per_step": niter / steps, "contacts_per_step": ncon / steps,
            "stage_share": {s: v / step for s, v in stages.items()}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=16)
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--passes", type=int, default=2)
    ap.add_argument("--model", default="lab-lag")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "step_profile.json"))
    args = ap.parse_args()
    base = presets.params(args.model)
    gait = GaitSpec(90.0)
    poses = pair_starts(base, 128, 1, 90.0)[: args.starts]  # glider_step.py's starts
    mujoco.set_mjcb_time(time.perf_counter)
    try:
        runs = {n: [] for n in NUMERICS}
        names = list(NUMERICS)
        for p in range(args.passes):
            for n in names[p % 2:] + names[:p % 2]:
                runs[n].append(profile(base.replace(**NUMERICS[n]), poses, gait, args.periods))
    finally:
        mujoco.set_mjcb_time(None)
    rows = {}
    for n, rs in runs.items():
        med = lambda key: float(np.median([r[key] for r in rs]))  # noqa: E731
        rows[n] = {"numerics": {"integrator": base.integrator, **NUMERICS[n]},
                   "step_us": med("step_us"), "step_s_per_sim_s": med("step_s_per_sim_s"),
                   "solver_iterations_per_step": med("solver_iterations_per_step"),
                   "contacts_per_step": med("contacts_per_step"),
                   "stage_share": {s: float(np.median([r["stage_share"][s] for r in rs])) for s in STAGES},
                   "passes": rs}
    for n in rows:
        rows[n]["cost_vs_0.5ms"] = float(np.median([r["step_s_per_sim_s"] / b["step_s_per_sim_s"]
                                                    for r, b in zip(runs[n], runs[BASE])]))
    out = {"model": args.model, "starts": args.starts, "periods": args.periods, "passes": args.passes,
           "processor": _cpu(), "machine": platform.platform(), "mujoco": mujoco.__version__,
           "date": time.strftime("%Y-%m-%d"), "rows": rows}
    save_json(args.out, out)
    for n, r in rows.items():
        print(f"{n}: {r['step_us']:.1f} us per step, {r['cost_vs_0.5ms']:.2f}x the 0.5 ms cost per simulated "
              f"second, {r['solver_iterations_per_step']:.2f} solver iterations and {r['contacts_per_step']:.1f} "
              "contacts per step; " + ", ".join(f"{s} {100 * v:.0f} %" for s, v in r["stage_share"].items()))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
