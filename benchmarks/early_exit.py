"""Evidence for the early-exit rule: run configurations to the full length,
then replay the rule on the records and count changed labels.

Because each lane is computed independently of its batch (tests/test_engine),
replaying the rule on full-length records gives exactly what a run with early
exit would have recorded up to the retirement point. Labels: bound at the end
(touched in the last period) and attracted (touched in any of the last 5).

    python benchmarks/early_exit.py --configs 500 --periods 75
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import numpy as np

from smarticle_mjx import configs as C
from smarticle_mjx import presets
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.batch import RetireRule, run_lanes
from smarticle_mjx.gait import GaitSpec


def replay(touched, quiet, chunk):
    """Retirement period per lane (or K) for a rule checked every ``chunk``."""
    m, k = touched.shape
    stop = np.full(m, k)
    for end in range(chunk, k, chunk):
        if end < quiet:
            continue
        quiet_now = ~touched[:, end - quiet:end].any(1)
        stop = np.where((stop == k) & quiet_now, end, stop)
    return stop


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=500)
    ap.add_argument("--periods", type=int, default=75)
    ap.add_argument("--amplitude", type=float, default=90.0)
    ap.add_argument("--chunk", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--model", default=presets.DEFAULT, help="model preset (the JSON of November 2026: paper at 0.25 ms)")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "early_exit.json"))
    args = ap.parse_args()

    params, gait = presets.params(args.model), GaitSpec(args.amplitude)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    rng = np.random.default_rng(args.seed)
    cf = C.random_configs(args.configs, rng, (0.5, 2.5))
    poses = C.pair_poses(cf[:, 0], cf[:, 1], cf[:, 2], a0[0], a0[1], params.robot)
    valid = C.poses_valid(poses, params.robot)
    lanes = Lanes.from_gait(poses, gait)
    scene = Scene.build(params, 2)
    be = make_backend("native", scene)
    touched = np.zeros((args.configs, args.periods), bool)

    def keep(r):
        touched[r.index] = r.touched[:, :, 0]

    t = time.perf_counter()
    summary = run_lanes(be, lanes, args.periods, batch_size=256, chunk_periods=args.chunk, valid=valid,
                        rule=RetireRule(quiet_periods=0), on_lanes=keep,
                        on_progress=lambda d, n, lp: print(f"\r{d}/{n} lanes", end="", flush=True))
    wall = time.perf_counter() - t
    print()
    tv = touched[valid]
    end_full, att_full = tv[:, -1], tv[:, -5:].any(1)
    rows = []
    print(f"{valid.sum()} valid of {args.configs} configurations, {args.periods} periods, {wall:.0f} s wall")
    print(f"{'quiet':>5} {'changed end':>11} {'changed attr':>12} {'retired':>8} {'saved work':>10}")
    for quiet in (1, 2, 3, 5):
        stop = replay(tv, quiet, args.chunk)
        cut = np.arange(args.periods)[None, :] < stop[:, None]
        te = tv & cut
        end_e, att_e = te[:, -1], te[:, -5:].any(1)
        row = dict(quiet_periods=quiet, chunk=args.chunk,
                   changed_bound_end=float((end_e != end_full).mean()),
                   changed_attracted=float((att_e != att_full).mean()),
                   retired=float((stop < args.periods).mean()),
                   saved_work=float(1 - stop.sum() / (len(stop) * args.periods)))
        rows.append(row)
        print(f"{quiet:5d} {row['changed_bound_end']:11.4f} {row['changed_attracted']:12.4f} {row['retired']:8.3f} "
              f"{row['saved_work']:10.3f}")
    out = dict(model=args.model, timestep=params.timestep, configs=int(args.configs), valid=int(valid.sum()), periods=args.periods, amplitude=args.amplitude,
               wall_s_full=wall, lane_periods=summary["lane_periods"], bound_end_fraction=float(end_full.mean()),
               rows=rows)
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
