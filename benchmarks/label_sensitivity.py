"""How reproducible is a bound/unbound label at all? Shift robot 2 by a
distance far below any physical tolerance and count changed labels at the
same dt. This is the floor any dt-convergence agreement can reach.

    python benchmarks/label_sensitivity.py --configs 400 --shift 1e-9

The configurations are those of benchmarks/timestep_candidates.py (default
model, |r| 0.8-2.0 W, 90 deg, seed 0), at the model's own step unless --dt.
"""

from __future__ import annotations

import argparse
import json
import pathlib


ROOT = pathlib.Path(__file__).resolve().parent

from smarticle_mjx import presets
from smarticle_mjx.bench import fixed_starts
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.gait import GaitSpec


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=100)
    ap.add_argument("--periods", type=int, default=20)
    ap.add_argument("--model", default=None, help="preset (default: the default model)")
    ap.add_argument("--dt", type=float, default=None, help="s (default: the model's)")
    ap.add_argument("--shift", type=float, default=1e-9, help="m, added to robot 2's x")
    ap.add_argument("--out", default=None, help="default: results/label_sensitivity_dt<dt>.json")
    args = ap.parse_args()
    params, gait = presets.params(args.model), GaitSpec(90.0)
    if args.dt is not None:
        params = params.replace(timestep=args.dt)
    args.dt = params.timestep
    poses = fixed_starts(presets.params(args.model), args.configs)
    moved = poses.copy()
    moved[:, 1, 0] += args.shift
    be = make_backend("native", Scene.build(params, 2))
    labels = []
    for p in (poses, moved):
        lanes = Lanes.from_gait(p, gait)
        _, rec, _ = be.advance(be.initial_state(lanes), lanes, args.periods)
        labels.append(rec.touched[:, :, 0])
    a, b = labels
    out = dict(model=presets.get(args.model).name, dt=args.dt, shift_m=args.shift, configs=len(poses), periods=args.periods,
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
