"""Does MuJoCo's constraint solver converge at the impacts a pair sees?

For each ``ls_iterations`` cap, steps colliding pairs through their first
gait periods with MuJoCo C and, at every step where the solver ran more than
one iteration, re-solves the same state (same warm start) with a tightly
converged solver (1000 iterations, 1000 line-search evaluations). A step is
*unconverged* when its accelerations differ from the reference by more than
0.1 % of the largest one. Also times the native backend with each cap on the
same lanes, interleaved, so the cost is a ratio measured in one run.

Then the same for MJX (--mjx-caps): MJX's solve of those same hard states at
each cap against MJX's own converged solve (same contacts and precision), and
MJX's step rate with each cap on the same lanes. MJX's line search is a
fixed-length scan, so under vmap its cost grows with the cap whether a lane
needs the evaluations or not.

    python benchmarks/solver_convergence.py --configs 8 --periods 1
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import time

import numpy as np

from smarticle_mjx import configs as C
from smarticle_mjx import scene as S
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.core import on_step_grid
from smarticle_mjx.engine.solver_check import MJX_REFERENCE, REL_TOL, mjx_solver_census, solver_census
from smarticle_mjx.gait import GaitSpec

def interleaved_walls(backends: dict, lanes, periods: int, repeats: int) -> dict:
    """Wall seconds per backend, ``repeats`` rounds with the backends interleaved
    (so a ratio is measured in one run on a noisy machine)."""
    wall = {k: [] for k in backends}
    for _ in range(repeats):
        for k, be in backends.items():
            t = time.perf_counter()
            be.advance(be.initial_state(lanes), lanes, periods)
            wall[k].append(time.perf_counter() - t)
    return wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=8)
    ap.add_argument("--periods", type=int, default=1)
    ap.add_argument("--caps", default="10,20,30,50")
    ap.add_argument("--mjx-caps", default="2,4,6,8,10,20", help="MJX caps ('' to skip MJX)")
    ap.add_argument("--repeats", type=int, default=3, help="interleaved timing rounds")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "solver_convergence.json"))
    args = ap.parse_args()
    caps = [int(c) for c in args.caps.split(",")]
    base, gait = S.SceneParams(), GaitSpec(90.0)
    a0 = gait.setpoints(0.0, base.robot.servo_speed)
    # the agreement benchmark's sample (same seed and range): pairs that start close
    poses = C.sample_valid_pairs(args.configs, np.random.default_rng(args.seed), (0.8, 2.0), a0[0], a0[1])
    lanes = on_step_grid(Lanes.from_gait(poses, gait), base.timestep)
    nsteps = args.periods * int(round(lanes.period / base.timestep))
    scenes = {ls: Scene.build(dataclasses.replace(base, ls_iterations=ls), 2) for ls in caps}
    rows = []
    for ls in caps:
        t = time.perf_counter()
        row = dict(ls_iterations=ls, **dataclasses.asdict(solver_census(scenes[ls], lanes, nsteps)))
        row["unconverged_fraction"] = row["unconverged"] / row["steps"]
        row["census_s"] = time.perf_counter() - t
        rows.append(row)
        print(f"ls_iterations {ls:3d}: {row['unconverged']:4d} of {row['steps']} steps unconverged "
              f"({row['unconverged_fraction']:.2%}), worst {row['worst_relative_error']:.1e} of max|qacc|, "
              f"line search used up to {row['max_line_search_evals']} evaluations", flush=True)
    # cost: the native backend on the same lanes, caps interleaved
    wall = interleaved_walls({ls: make_backend("native", scenes[ls]) for ls in caps}, lanes, args.periods,
                             args.repeats)
    ref_cap = base.ls_iterations
    for row in rows:
        ls = row["ls_iterations"]
        row["native_steps_per_s"] = nsteps * lanes.size / min(wall[ls])
        row["native_cost_vs_default"] = min(wall[ls]) / min(wall[ref_cap]) if ref_cap in wall else None
    print("\n| ls_iterations | unconverged steps | worst error (of max |qacc|) | native steps/s | cost vs default |")
    print("| --- | --- | --- | --- | --- |")
    for r in rows:
        cost = f"{r['native_cost_vs_default']:.2f}" if r["native_cost_vs_default"] else "—"
        print(f"| {r['ls_iterations']} | {r['unconverged']} ({r['unconverged_fraction']:.2%}) | "
              f"{r['worst_relative_error']:.1e} | {r['native_steps_per_s'] / 1e3:.1f}k | {cost} |")
    out = dict(configs=lanes.size, periods=args.periods, iterations=base.iterations, default_cap=ref_cap,
               rel_tol=REL_TOL, rows=rows)
    if args.mjx_caps:
        out["mjx"] = mjx_rows(base, lanes, nsteps, [int(c) for c in args.mjx_caps.split(",")], args)
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))


def mjx_rows(base, lanes, nsteps, caps, args):
    """MJX census and step rate per cap (one row per cap, plus MJX vs C)."""
    from smarticle_mjx.engine.mjx import LS_ITERATIONS

    scene = Scene.build(base, 2)
    t = time.perf_counter()
    census = mjx_solver_census(scene, lanes, nsteps, caps)
    census_s = time.perf_counter() - t
    backends = {c: make_backend("mjx", scene, ls_iterations=c) for c in caps}
    for be in backends.values():  # compile outside the timing
        be.advance(be.initial_state(lanes), lanes, 1)
    wall = interleaved_walls(backends, lanes, 1, args.repeats)
    period_steps = int(round(lanes.period / base.timestep)) * lanes.size
    ref = LS_ITERATIONS if LS_ITERATIONS in wall else caps[-1]
    rows = []
    print(f"\nMJX (float32), same hard states, against MJX's own solve with {MJX_REFERENCE} iterations:")
    print("| MJX ls_iterations | unconverged steps | worst error (of max |qacc|) | MJX steps/s | cost vs default |")
    print("| --- | --- | --- | --- | --- |")
    for c in caps:
        r = dict(ls_iterations=c, **dataclasses.asdict(census[c]), mjx_steps_per_s=period_steps / min(wall[c]),
                 mjx_cost_vs_default=min(wall[c]) / min(wall[ref]))
        rows.append(r)
        print(f"| {c} | {r['unconverged']} | {r['worst_relative_error']:.1e} | {r['mjx_steps_per_s'] / 1e3:.2f}k | "
              f"{r['mjx_cost_vs_default']:.2f} |")
    vs_c = dataclasses.asdict(census["vs_c"])
    print(f"MJX's converged solve vs MuJoCo C's converged solve: {vs_c['unconverged']} of "
          f"{vs_c['multi_iteration_solves']} hard states differ by more than {REL_TOL:.1%} of max |qacc| "
          f"(worst {vs_c['worst_relative_error']:.1e}): contacts and precision, not convergence")
    return dict(default_cap=LS_ITERATIONS, reference=MJX_REFERENCE, census_s=census_s, rows=rows, vs_c=vs_c,
                batch=lanes.size)


if __name__ == "__main__":
    main()
