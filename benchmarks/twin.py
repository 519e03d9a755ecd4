"""MuJoCo against its DART twin, starting with a lone robot (the first rows of the cross-engine study).

For one robot of the default model on the plate, running the square gait at
90 and 10 degrees for 12 periods, in each engine and numerics:

* net drift per cycle: |end - start| of the body centre at period ends over
  periods 2-12, per cycle, in W (the paper's lab: 1.5e-3 W per cycle at 90);
* slip per edge: the mean |displacement| of the body centre over one arm
  move and its dwell (a quarter period), in W: what an arm's start and stop
  kicks move the body (the closed-form estimate for a kick from rest at full
  speed: v^2 / 2 mu g, about 1.1e-3 W).

MuJoCo runs the default model at its step and a quarter of it; DART runs the
same SceneParams with its default FCL mesh detector at 0.1 ms and 0.05 ms,
and with the primitive detectors (fcl, ode, bullet) at 0.1 ms. Resumable:
rows already in the JSON are kept (delete it to re-measure).

    python benchmarks/twin.py            # ~4 minutes on one core
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import numpy as np

from smarticle_mjx import presets
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.gait import GaitSpec

OUT = pathlib.Path(__file__).parent / "results" / "twin.json"


def _measures(quarters: np.ndarray, body_length: float) -> dict:
    """From body centres at every quarter period [4K + 1, 2]: drift and slip per edge (W), skipping period 1."""
    per_period = quarters[::4]
    drift = np.linalg.norm(per_period[-1] - per_period[1]) / (len(per_period) - 2) / body_length
    edges = np.linalg.norm(np.diff(quarters[4:], axis=0), axis=1) / body_length
    return {"drift_W_per_cycle": float(drift), "slip_per_edge_W": float(edges.mean()),
            "slip_per_edge_max_W": float(edges.max())}


def mujoco_row(params, gait: GaitSpec, periods: int) -> dict:
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    res = simulate(params, [(0, 0, 0, a0[0], a0[1])], gait, periods, track_stride=1)
    t = np.concatenate([[0.0], res.track_t])
    xy = np.concatenate([[[0.0, 0.0]], res.track[:, 0, :2]])
    T = res.track_t[-1] / periods
    idx = [int(np.argmin(np.abs(t - q * T / 4))) for q in range(4 * periods + 1)]
    return _measures(xy[idx], params.robot.body_length)


def dart_row(params, gait: GaitSpec, periods: int, numerics) -> dict:
    from smarticle_mjx.engine.dart import DartScene
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    sc = DartScene(params, [(0, 0, 0, a0[0], a0[1])], numerics)
    xy = [sc.poses()[0, :2]]

    def at_quarters(period, step, steps):
        if step + 1 in {round(q * steps / 4) for q in range(1, 5)}:
            xy.append(sc.poses()[0, :2])

    sc.run_gait(gait, periods, on_step=at_quarters)
    return _measures(np.array(xy), params.robot.body_length)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=int, default=12)
    ap.add_argument("--out", type=pathlib.Path, default=OUT)
    args = ap.parse_args()
    from smarticle_mjx.engine.dart import DartNumerics
    params = presets.params()
    done = json.loads(args.out.read_text()) if args.out.exists() else {"model": presets.DEFAULT, "lone": {}}
    rows = done["lone"]
    runs = {f"mujoco {params.timestep * 1e3:g} ms": lambda g: mujoco_row(params, g, args.periods),
            f"mujoco {params.timestep / 4 * 1e3:g} ms": lambda g: mujoco_row(params.replace(timestep=params.timestep / 4),
                                                                              g, args.periods)}
    for det, dt in (("fcl-mesh", 1e-4), ("fcl-mesh", 5e-5), ("fcl", 1e-4), ("ode", 1e-4), ("bullet", 1e-4)):
        runs[f"dart {det} {dt * 1e3:g} ms"] = (lambda d, s: lambda g: dart_row(params, g, args.periods,
                                                                               DartNumerics(timestep=s, detector=d)))(det, dt)
    for name, run in runs.items():
        for amp in (90.0, 10.0):
            key = f"{name}, {amp:g} deg"
            if key in rows:
                continue
            t = time.perf_counter()
            rows[key] = {**run(GaitSpec(amp)), "wall_s": time.perf_counter() - t}
            r = rows[key]
            print(f"{key}: drift {r['drift_W_per_cycle']:.2e} W/cycle, slip per edge {r['slip_per_edge_W']:.2e} W "
                  f"(max {r['slip_per_edge_max_W']:.2e}), {r['wall_s']:.0f} s", flush=True)
            done["periods"] = args.periods
            args.out.write_text(json.dumps(done, indent=1))


if __name__ == "__main__":
    main()
