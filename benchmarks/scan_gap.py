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
    python benchmarks/scan_gap.py --rounds 3 --reference-lanes 0 --same-lanes   # the fraction on
        # exactly the same work, three interleaved rounds (median and spread)

Each workload is also timed with single-thread ``mj_step`` (MuJoCo's rollout on
one MjData, controls computed beforehand) over the same lanes and periods (a
prefix of ``--reference-lanes``): the fraction printed is the backend's rate
over threads x that, what the native path (gait controls, sensors, slicing,
Python between calls) keeps of the physics' own speed on the same work. The
default-step issue's target is >= 0.9 on the touching lanes. ``--timestep``
times another step.

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


def mj_step_same_lanes(scene: Scene, lanes: Lanes, periods: int) -> float:
    """Steps per second of single-thread ``mj_step`` (MuJoCo's rollout on one MjData, no Python between
    steps) over the same lanes and periods from rest, the controls computed before the clock starts: what
    the physics alone costs on this workload."""
    import mujoco
    from mujoco import rollout as mj_rollout
    from smarticle_mjx.engine.core import lane_controls
    from smarticle_mjx.engine.native import NativeBackend
    m = scene.model
    nstep = steps_per_period(lanes.period, m.opt.timestep)
    be = NativeBackend(scene, nthread=1)
    state = be.initial_state(lanes)
    be.close()
    ctrl = lane_controls(scene, lanes, m.opt.timestep * np.arange(nstep))  # one period serves every period
    d = mujoco.MjData(m)
    t, steps = 0.0, 0
    for i in range(lanes.size):
        init = state[i:i + 1]
        for _ in range(periods):
            t0 = time.perf_counter()
            states, _ = mj_rollout.rollout(m, d, init, ctrl[i:i + 1], nstep=nstep)
            t += time.perf_counter() - t0
            init = states[:, -1]
            steps += nstep
    return steps / t


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--periods", type=int, default=2, help="periods timed per workload")
    ap.add_argument("--classify-periods", type=int, default=3, help="periods that decide touching or apart")
    ap.add_argument("--timestep", type=float, default=None, help="the scene's step (default: the preset's)")
    ap.add_argument("--reference-lanes", type=int, default=32,
                    help="lanes of each workload timed with single-thread mj_step (a prefix of the batch); "
                         "0: all of them")
    ap.add_argument("--rounds", type=int, default=1,
                    help="timings of each workload, backend and reference alternating (which goes first "
                         "alternates too); the fraction is given per round, with the median")
    ap.add_argument("--same-lanes", action="store_true",
                    help="time the backend on the reference's lanes only (not the whole batch), so both "
                         "time exactly the same work")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "scan_gap.json"))
    args = ap.parse_args()
    cfg = ScanConfig()  # smx scan's defaults: 5000 starts in 0.5-2.5 W, seed 0, 90 degrees
    params = presets.params(cfg.model)
    if args.timestep is not None:
        import dataclasses
        params = dataclasses.replace(params, timestep=args.timestep)
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
    threads = backend.nthread
    for name, ln in workloads.items():
        nref = ln.size if args.reference_lanes <= 0 else min(ln.size, args.reference_lanes)
        ref_lanes = ln.take(np.arange(nref))
        timed_lanes = ref_lanes if args.same_lanes else ln
        rates, refs = [], []
        for k in range(max(1, args.rounds)):
            # the same lanes' physics alone: single-thread mj_step over a prefix of them (same periods from
            # rest), timed next to the backend, first or second by turns
            if k % 2:
                refs.append(mj_step_same_lanes(backend.scene, ref_lanes, args.periods))
                rates.append(timed(backend, timed_lanes, args.periods))
            else:
                rates.append(timed(backend, timed_lanes, args.periods))
                refs.append(mj_step_same_lanes(backend.scene, ref_lanes, args.periods))
        fr = [a / (threads * b) for a, b in zip(rates, refs)]
        rate, ref = float(np.median(rates)), float(np.median(refs))
        rows[name] = {"lanes": int(timed_lanes.size), "steps_per_s": rate, "mj_step_same_lanes_steps_per_s": ref,
                      "reference_lanes": int(nref), "same_lanes": bool(args.same_lanes),
                      "fraction_of_threads_x_mj_step": float(np.median(fr)),
                      "rounds": [{"steps_per_s": a, "mj_step_same_lanes_steps_per_s": b, "fraction": f}
                                 for a, b, f in zip(rates, refs, fr)]}
        spread = f" (rounds {min(fr):.2f}-{max(fr):.2f})" if len(fr) > 1 else ""
        print(f"{name}: {timed_lanes.size} lanes, {rate:,.0f} steps/s on {threads} threads; single-thread "
              f"mj_step on {nref} of them {ref:,.0f} steps/s: {rows[name]['fraction_of_threads_x_mj_step']:.2f} "
              f"of {threads}x{spread}", flush=True)
    backend.close()
    from smarticle_mjx import scene as S
    # the machine's speed in engine.py's own unit, so results of other machines can be scaled
    single = mj_step_rate(S.compile_model(S.build_mjcf(params, S.standard_poses("pair"))))
    print(f"single-thread mj_step, engine.py's pair scene: {single:,.0f} steps/s")
    out = {"model": cfg.model, "timestep": params.timestep, "integrator": params.integrator, "threads": threads,
           "batch": args.batch, "periods": args.periods,
           "mj_step_single_thread_steps_per_s": single, "machine": platform.platform(),
           "processor": _cpu(),
           "touching_fraction_of_first_valid": float(touched.mean()), "rows": rows}
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
