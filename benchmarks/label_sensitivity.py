"""How reproducible is a bound/unbound label at all? Shift robot 2 by a
distance far below any physical tolerance and count changed labels at the
same dt. This is the floor any dt-convergence agreement can reach.

    python benchmarks/label_sensitivity.py --dt 5e-4 --shift 1e-9
"""

from __future__ import annotations

import argparse
import json
import pathlib

import numpy as np

from smarticle_mjx import configs as C
from smarticle_mjx import scene as S
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.gait import GaitSpec


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=100)
    ap.add_argument("--periods", type=int, default=20)
    ap.add_argument("--dt", type=float, default=S.SceneParams().timestep)
    ap.add_argument("--shift", type=float, default=1e-9, help="m, added to robot 2's x")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=None, help="default: results/label_sensitivity_dt<dt>.json")
    args = ap.parse_args()
    params, gait = S.SceneParams(timestep=args.dt), GaitSpec(90.0)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    rng = np.random.default_rng(args.seed)  # same sample as timestep_convergence.py
    poses = C.sample_valid_pairs(args.configs, rng, (0.8, 2.0), a0[0], a0[1])
    moved = poses.copy()
    moved[:, 1, 0] += args.shift
    be = make_backend("native", Scene.build(params, 2))
    labels = []
    for p in (poses, moved):
        lanes = Lanes.from_gait(p, gait)
        _, rec, _ = be.advance(be.initial_state(lanes), lanes, args.periods)
        labels.append(rec.touched[:, :, 0])
    a, b = labels
    out = dict(dt=args.dt, shift_m=args.shift, configs=len(poses), periods=args.periods,
               agree_bound_end=float((a[:, -1] == b[:, -1]).mean()),
               agree_attracted=float((a[:, -5:].any(1) == b[:, -5:].any(1)).mean()),
               agree_per_period=[float(x) for x in (a == b).mean(0)])
    print(f"dt {args.dt}: shifting robot 2 by {args.shift} m changes the bound-at-end label of "
          f"{1 - out['agree_bound_end']:.1%} of {len(poses)} configurations "
          f"(attracted: {1 - out['agree_attracted']:.1%})")
    path = args.out or pathlib.Path(__file__).parent / "results" / f"label_sensitivity_dt{args.dt:g}.json"
    pathlib.Path(path).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
