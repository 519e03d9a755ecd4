"""Choose the time step by convergence: does the bound/unbound outcome at dt
agree with dt/4?

For each candidate dt, a fixed sample of valid random pair configurations is
run for --periods gait periods at dt and at dt/4 (native backend, all cores).
Printed per dt: label agreement (bound at the end = touched in the last
period; attracted = touched in any of the last 5 periods), single-robot drift
per cycle at dt and dt/4, and the cost per simulated second per lane.

    python benchmarks/timestep_convergence.py --configs 100 --periods 20
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import time

import numpy as np

from smarticle_mjx import configs as C
from smarticle_mjx import scene as S
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.gait import GaitSpec


def run_batch(params, poses, gait, periods):
    scene = Scene.build(params, 2)
    be = make_backend("native", scene)
    lanes = Lanes.from_gait(poses, gait)
    t = time.perf_counter()
    _, rec, _ = be.advance(be.initial_state(lanes), lanes, periods)
    wall = time.perf_counter() - t
    be.close()
    return rec, wall


def drift(params, gait, periods=10):
    a = gait.setpoints(0.0, params.robot.servo_speed)
    r = simulate(params, [(0, 0, 0, a[0], a[1])], gait, periods=periods)
    return float(np.linalg.norm(np.diff(r.poses[2:, 0, :2], axis=0), axis=1).mean() / params.robot.body_length)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=100)
    ap.add_argument("--periods", type=int, default=20)
    ap.add_argument("--dts", default="1e-3,5e-4,2.5e-4")
    ap.add_argument("--contact-timeconst", type=float, default=S.SceneParams().contact_timeconst)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "timestep.json"))
    args = ap.parse_args()

    gait = GaitSpec(90.0)
    base = S.SceneParams(contact_timeconst=args.contact_timeconst)
    a0 = gait.setpoints(0.0, base.robot.servo_speed)
    rng = np.random.default_rng(args.seed)
    poses = C.sample_valid_pairs(args.configs, rng, (0.8, 2.0), a0[0], a0[1])

    rows = []
    print(f"{len(poses)} configurations x {args.periods} periods at 90 deg, contact timeconst {base.contact_timeconst} s")
    print(f"{'dt':>9} {'agree end':>9} {'agree attr':>10} {'bound frac':>10} {'drift W/cyc':>11} "
          f"{'drift dt/4':>10} {'ms/sim-s/lane':>13}")
    for dt in (float(x) for x in args.dts.split(",")):
        p = base.replace(timestep=dt)
        q = base.replace(timestep=dt / 4)
        rec, wall = run_batch(p, poses, gait, args.periods)
        ref, wall_ref = run_batch(q, poses, gait, args.periods)
        end, end_ref = rec.touched[:, -1, 0], ref.touched[:, -1, 0]
        att, att_ref = rec.touched[:, -5:, 0].any(1), ref.touched[:, -5:, 0].any(1)
        sim_s = len(poses) * args.periods * gait.period()
        row = dict(dt=dt, agree_bound_end=float((end == end_ref).mean()), agree_attracted=float((att == att_ref).mean()),
                   bound_fraction=float(end.mean()), bound_fraction_ref=float(end_ref.mean()),
                   drift_W_per_cycle=drift(p, gait), drift_ref=drift(q, gait),
                   cost_ms_per_sim_second=1e3 * wall / sim_s, cost_ref_ms_per_sim_second=1e3 * wall_ref / sim_s,
                   status_bad=int((rec.status != 0).sum()))
        rows.append(row)
        print(f"{dt:9.2e} {row['agree_bound_end']:9.3f} {row['agree_attracted']:10.3f} {row['bound_fraction']:10.3f} "
              f"{row['drift_W_per_cycle']:11.2e} {row['drift_ref']:10.2e} {row['cost_ms_per_sim_second']:13.2f}", flush=True)
    out = dict(configs=len(poses), periods=args.periods, contact_timeconst=base.contact_timeconst,
               machine=platform.platform(), processor=platform.processor(), rows=rows)
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
