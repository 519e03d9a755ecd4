"""What the calibration gains from computing the replay's servo references on the host (version 0.4.17).

A replay of tracked arms starts each servo's reference where the arms rest and lets it follow the gait's
corners (``engine.core.follow_corners``); that follower asks the gait for its corners six times per
model run, and the model's starting activations ask again. Before version 0.4.17 each ask was an eager
call of the JAX gait function (``gait.setpoints``): some sixty array operations, each dispatched by JAX,
several milliseconds a call (measured with this script: calibrations 15-30 % slower on 2 cores than
with the host gait, results/host_gait_cost.json; docs/calibration.md). Since then the same
operations run in numpy in the same float type (``gait.host_setpoints``), bit for bit the same numbers
(tests/test_gait.py), so every model run is the same computation and the calibration's result is too.

This script calibrates stress-suite sets (benchmarks/calibration_stress.py's draw, data written as the
suite writes them) both ways in one process, alternating which goes first, and prints the wall times and
their ratio. The two calibrations must agree in everything, the count of model runs included; a set
where they do not is reported and the script exits non-zero.

    python benchmarks/host_gait_cost.py --set 2144/17 --set 2140/0

Writes results/host_gait_cost.json.
"""

from __future__ import annotations

import pathlib

import contextlib
import json
import time

import numpy as np

from calibration_schedule import arguments, both_ways, finish

from smarticle_mjx import gait
from smarticle_mjx.calibrate.stages import calibrate

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results

OUT = RESULTS / "host_gait_cost.json"
HOST = gait.host_setpoints


def _eager(*args, **kw):
    """The replay's gait as it was computed before version 0.4.17: the JAX function called eagerly."""
    return np.asarray(gait.setpoints(*args, **kw))


@contextlib.contextmanager
def replay_gait(host: bool):
    gait.host_setpoints = HOST if host else _eager
    try:
        yield
    finally:
        gait.host_setpoints = HOST


def timed(trials, host: bool) -> tuple[float, dict]:
    with replay_gait(host):
        t = time.perf_counter()
        res = calibrate(trials).summary
        return time.perf_counter() - t, res


def main() -> int:
    args = arguments(__doc__, OUT)
    rows = []
    for (seed, index), s, trials, order, got in both_ways(args.sets, timed):
        (t_old, r_old), (t_new, r_new) = got[False], got[True]
        same = json.dumps(r_old, sort_keys=True, default=str) == json.dumps(r_new, sort_keys=True, default=str)
        row = {"set": f"{seed}/{index}", "robots": s["robots"], "trials": len(trials),
               "arms_tracked": s["arms_tracked"], "first": "host" if order[0] else "eager",
               "wall_s_eager": t_old, "wall_s_host": t_new, "ratio": t_new / t_old,
               "model_runs": r_new["model_runs"], "same_result": same}
        rows.append(row)
        print(f"{row['set']}: {s['robots']} robot(s), {len(trials)} trials, arms "
              f"{'tracked' if s['arms_tracked'] else 'not tracked'}: {t_old:6.1f} s eager JAX gait, "
              f"{t_new:6.1f} s host gait (x{row['ratio']:.2f}); {row['model_runs']} runs; results "
              f"{'identical' if same else 'DIFFER'}", flush=True)
    return finish(rows, "eager", "host", args.out)


if __name__ == "__main__":
    raise SystemExit(main())
