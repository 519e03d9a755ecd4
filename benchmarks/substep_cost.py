"""What near-contact sub-stepping costs: the native backend at 0.5 ms (implicitfast, the default, and
discrete), discrete at 0.5 ms with 2 sub-steps while some pair may be within 4 mm, and implicitfast at
0.25 ms, timed in interleaved passes over the same lanes.

Workloads (the scan's, as benchmarks/scan_gap.py picks them: ``smx scan``'s default starts, 0.5-2.5 W,
seed 0, 90 deg, classified by whether they touch in their first ``--classify-periods`` periods):

* the scan's starts that touch (most of a scan's steps: early exit retires the others);
* the scan's starts that stay apart;

each ``--batch`` lanes run ``--periods`` periods from rest. Per pass and workload every numerics runs
once, in rotating order, so that the machine's load falls on all of them alike; the cost printed is
each numerics' wall time over the 0.5 ms run's in the same pass (median over passes), with the
fraction of full steps the sub-stepped run split (the native backend's own count).

    python benchmarks/substep_cost.py              # ~5 minutes on 2 cores

Writes results/substep_cost.json.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import time

import numpy as np

from scan_gap import _cpu
from smarticle_mjx import presets
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.batch import RetireRule, run_lanes
from smarticle_mjx.scan import RunInputs, ScanConfig

NUMERICS = {  # name -> SceneParams changes
    "0.5 ms": dict(timestep=5e-4, integrator="implicitfast", contact_substeps=1),
    "0.5 ms discrete": dict(timestep=5e-4, integrator="discrete", contact_substeps=1),
    "0.5 ms discrete + 2 sub-steps within 4 mm": dict(timestep=5e-4, integrator="discrete", contact_substeps=2,
                                                      substep_gate=0.004),
    "0.25 ms": dict(timestep=2.5e-4, integrator="implicitfast", contact_substeps=1),
}
BASE = "0.5 ms"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=256, help="lanes per workload (smx scan's batch)")
    ap.add_argument("--periods", type=int, default=2)
    ap.add_argument("--passes", type=int, default=2)
    ap.add_argument("--classify-periods", type=int, default=3)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "substep_cost.json"))
    args = ap.parse_args()
    cfg = ScanConfig()
    base = presets.params(cfg.model)
    inputs = RunInputs.of(cfg, base, 90.0)
    valid = np.flatnonzero(inputs.valid)[: 4 * args.batch]
    lanes = Lanes.from_gait(inputs.poses[valid], inputs.gait)
    touched = np.zeros(len(valid), bool)

    def keep(r):
        touched[r.index] = r.touched[:, :, 0].any(1)

    with make_backend("native", Scene.build(base.replace(**NUMERICS[BASE]), 2)) as be:
        run_lanes(be, lanes, args.classify_periods, batch_size=args.batch, rule=RetireRule(quiet_periods=0),
                  on_lanes=keep)
    workloads = {"scan starts that touch": lanes.take(np.flatnonzero(touched)[: args.batch]),
                 "scan starts that stay apart": lanes.take(np.flatnonzero(~touched)[: args.batch])}
    backends = {n: make_backend("native", Scene.build(base.replace(**c), 2)) for n, c in NUMERICS.items()}
    for be in backends.values():  # compile the gate and the gait's controls outside the clock
        ln = lanes.take(np.arange(2))
        be.advance(be.initial_state(ln), ln, 1)
    walls = {w: {n: [] for n in NUMERICS} for w in workloads}
    split = {w: None for w in workloads}
    names = list(NUMERICS)
    for p in range(args.passes):
        for w, ln in workloads.items():
            for n in names[p % len(names):] + names[:p % len(names)]:
                be = backends[n]
                before = list(getattr(be, "substep_stats", [0, 0]))
                t = time.perf_counter()
                be.advance(be.initial_state(ln), ln, args.periods)
                walls[w][n].append(time.perf_counter() - t)
                if hasattr(be, "substep_stats"):
                    whole, fine = (a - b for a, b in zip(be.substep_stats, before))
                    split[w] = fine / (whole + fine)
            print(f"pass {p} {w}: " + ", ".join(f"{n} {walls[w][n][-1]:.1f} s" for n in names), flush=True)
    for be in backends.values():
        be.close()
    rows = {}
    for w in workloads:
        rows[w] = {"lanes": int(workloads[w].size), "periods": args.periods, "wall_s": walls[w],
                   "split_fraction_of_steps": split[w],
                   "cost_vs_0.5ms": {n: float(np.median(np.array(walls[w][n]) / np.array(walls[w][BASE])))
                                     for n in names}}
        print(f"{w}: split {split[w]:.2f} of steps; cost vs 0.5 ms " +
              ", ".join(f"{n} {c:.2f}" for n, c in rows[w]["cost_vs_0.5ms"].items()))
    out = {"model": cfg.model, "numerics": NUMERICS, "passes": args.passes, "batch": args.batch,
           "processor": _cpu(), "machine": platform.platform(),
           "date": time.strftime("%Y-%m-%d"), "rows": rows}
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
