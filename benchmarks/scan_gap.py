"""Where a scan's throughput goes, against the engine benchmark's: the workload.

The engine benchmark (benchmarks/engine.py) times one gait period from rest of
pairs started 0.8-2.0 W apart. A basin scan runs different lanes: starts
0.5-2.5 W apart, and early exit retires the pairs that stay apart, so most of
its steps are steps of pairs in contact, whose contacts cost the solver more.
This script times, in one run on the same cores and batch size, the native
backend on

* the engine benchmark's workload (its sample, one period from rest);
* the scan's valid starts that touch during their first periods;
* the scan's valid starts that stay apart;

and writes results/scan_gap.json. With the steps/s of touching and apart
lanes, the scan's own mix predicts the rate the scan can reach inside the
engine; what the scan's wall time adds beyond its time inside the engine is
``full_scan.py``'s ``backend_s`` against its wall time.

    python benchmarks/scan_gap.py            # ~3 minutes on 2 cores

It also times single-thread ``mj_step`` on engine.py's pair scene, the unit
engine.json gives each machine's speed in.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import time

import numpy as np

from smarticle_mjx import presets
from smarticle_mjx.bench import mj_step_rate, sample_lanes
from smarticle_mjx.engine import Lanes, Scene, make_backend, steps_per_period
from smarticle_mjx.engine.batch import RetireRule, run_lanes
from smarticle_mjx.scan import RunInputs, ScanConfig



def _cpu() -> str:
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def timed(backend, lanes: Lanes, periods: int) -> float:
    """Steps per second of ``lanes`` (one batch) over ``periods`` periods from rest."""
    t = time.perf_counter()
    backend.advance(backend.initial_state(lanes), lanes, periods)
    wall = time.perf_counter() - t
    return lanes.size * periods * steps_per_period(lanes.period, backend.scene.params.timestep) / wall


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--periods", type=int, default=2, help="periods timed per workload")
    ap.add_argument("--classify-periods", type=int, default=3, help="periods that decide touching or apart")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "scan_gap.json"))
    args = ap.parse_args()
    cfg = ScanConfig()  # smx scan's defaults: 5000 starts in 0.5-2.5 W, seed 0, 90 degrees
    params = presets.params(cfg.model)
    inputs = RunInputs.of(cfg, params, 90.0)
    backend = make_backend("native", Scene.build(params, 2))
    valid = np.flatnonzero(inputs.valid)[: 4 * args.batch]
    lanes = Lanes.from_gait(inputs.poses[valid], inputs.gait)
    touched = np.zeros(len(valid), bool)

    def keep(r):
        touched[r.index] = r.touched[:, :, 0].any(1)

    run_lanes(backend, lanes, args.classify_periods, batch_size=args.batch, rule=RetireRule(quiet_periods=0),
              on_lanes=keep)
    touch_idx, apart_idx = np.flatnonzero(touched)[: args.batch], np.flatnonzero(~touched)[: args.batch]
    workloads = {
        "engine benchmark sample (0.8-2.0 W, from rest)": sample_lanes(args.batch, params, inputs.gait),
        "scan starts that touch": lanes.take(touch_idx),
        "scan starts that stay apart": lanes.take(apart_idx),
    }
    rows = {}
    for name, ln in workloads.items():
        rows[name] = {"lanes": int(ln.size), "steps_per_s": timed(backend, ln, args.periods)}
        print(f"{name}: {ln.size} lanes, {rows[name]['steps_per_s']:,.0f} steps/s", flush=True)
    backend.close()
    from smarticle_mjx import scene as S
    # the machine's speed in engine.py's own unit, so results of other machines can be scaled
    single = mj_step_rate(S.compile_model(S.build_mjcf(params, S.standard_poses("pair"))))
    print(f"single-thread mj_step, engine.py's pair scene: {single:,.0f} steps/s")
    out = {"model": cfg.model, "timestep": params.timestep, "batch": args.batch, "periods": args.periods,
           "mj_step_single_thread_steps_per_s": single, "machine": platform.platform(),
           "processor": _cpu(),
           "touching_fraction_of_first_valid": float(touched.mean()), "rows": rows}
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
