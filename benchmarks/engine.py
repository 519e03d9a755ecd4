"""Engine throughput: single-thread mj_step, native rollout, MJX and MuJoCo Warp vs batch size.

Prints a table and writes JSON (with the device each backend ran on).
Compile time (MJX's jit, MuJoCo Warp's kernel build plus its CUDA graph
capture) is timed apart from run time; every timed run blocks until the
device is done. Also: wall time of one 75-period pair simulation, and peak
memory (max RSS) of this process.

    python benchmarks/engine.py                # default sizes (CPU: native and mjx)
    python benchmarks/engine.py --quick        # smaller sizes, for a smoke run
    python benchmarks/engine.py --backends warp,mjx --warp-batches 1024,4096,16384 \
        --mjx-batches 1024,4096,16384 --out benchmarks/results/engine_gpu.json   # on a GPU
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import resource
import time


from smarticle_mjx import configs as C
from smarticle_mjx import scene as S
from smarticle_mjx.engine import Scene, make_backend
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.bench import mj_step_rate, sample_lanes
from smarticle_mjx.gait import GaitSpec


def _versions():
    """The installed versions that decide these figures (absent ones as None)."""
    from importlib import metadata

    import smarticle_mjx
    out = {"smarticle-mjx": smarticle_mjx.__version__}
    for name in ("mujoco", "mujoco-mjx", "jax", "jaxlib", "mujoco-warp", "warp-lang"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--native-batches", default="1,4,16,64,256,1024")
    ap.add_argument("--mjx-batches", default="1,16,128,1024,4096")
    ap.add_argument("--mjx-steps", type=int, default=100)
    ap.add_argument("--warp-batches", default="16,64")
    ap.add_argument("--warp-steps", type=int, default=400)
    ap.add_argument("--warp-deterministic", default="off", choices=("off", "on", "both"),
                    help="MuJoCo Warp's deterministic mode (its scratch buffers grow with worlds x contacts)")
    ap.add_argument("--backends", default="native,mjx", help="which of native, mjx, warp to measure")
    ap.add_argument("--model", default=None, help="model preset (default: the package's default preset)")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "engine.json"))
    args = ap.parse_args()
    if args.quick:
        args.native_batches, args.mjx_batches, args.mjx_steps = "1,16,64", "1,16,128", 50

    from smarticle_mjx import presets
    params = presets.params(args.model)
    gait = GaitSpec(90.0)
    backends = args.backends.split(",")
    pair = S.compile_model(S.build_mjcf(params, S.standard_poses("pair")))
    cores = os.cpu_count() or 1
    out = dict(machine=platform.platform(), cores=cores, timestep=params.timestep,
               model=args.model or presets.DEFAULT, backends=backends,
               integrator=params.integrator, versions=_versions())

    import jax
    out["jax_device"] = str(jax.devices()[0].device_kind)
    ref = mj_step_rate(pair)
    out["mj_step_single_thread_steps_per_s"] = ref
    print(f"device: {out['jax_device']}, cores: {cores}, dt {params.timestep} s")
    print(f"single-thread mj_step, pair scene: {ref:,.0f} steps/s (x{cores} cores = {ref * cores:,.0f})")

    scene = Scene.build(params, 2)
    rows = []
    print(f"{'backend':>7} {'batch':>6} {'compile s':>9} {'run s':>7} {'env-steps/s':>12} {'vs mj_step x cores':>18}")
    nstep = int(round(gait.period() / params.timestep))
    if "warp" in backends:
        rows += warp_rows(scene, params, gait, args, ref * cores, out)
    if "native" in backends:
        rows += native_rows(scene, params, gait, args, ref, cores, nstep, out)
    if "mjx" in backends:
        rows += mjx_rows(scene, params, gait, args, ref * cores)
    out["throughput"] = rows

    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    poses = C.pair_poses(1.16, 6.026, 4.451, a0[0], a0[1])
    t = time.perf_counter()
    simulate(params, poses, gait, periods=75)
    out["pair_75_periods_wall_s"] = time.perf_counter() - t
    out["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"one 75-period pair simulation (native): {out['pair_75_periods_wall_s']:.1f} s")
    print(f"peak RSS: {out['peak_rss_mib']:.0f} MiB")
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.out}")


def warp_rows(scene, params, gait, args, cpu_ref, out):
    """MuJoCo Warp: steps/s of the gait from rest; the first call (kernel build + graph capture) apart."""
    from smarticle_mjx.engine.mjwarp import WarpBackend
    rows = []
    for det in {"off": (False,), "on": (True,), "both": (False, True)}[args.warp_deterministic]:
        be = WarpBackend(scene, deterministic=det)
        out["warp_device"] = str(getattr(be.device, "name", be.device))
        out["warp_buffers"] = dict(nconmax=be.nconmax, njmax=be.njmax)
        out["warp_box_collider"] = be.box_collider
        for b in (int(x) for x in args.warp_batches.split(",")):
            lanes = sample_lanes(b, params, gait)
            t = time.perf_counter()
            be.run_from_rest(lanes, 1)  # builds kernels (first time), allocates, captures
            first = time.perf_counter() - t
            t = time.perf_counter()
            be.run_from_rest(lanes, args.warp_steps)
            run = time.perf_counter() - t
            rate = b * args.warp_steps / run
            rows.append(dict(backend="warp", deterministic=det, batch=b, compile_s=first,
                             capture_s=be.capture_s, run_s=run, steps=args.warp_steps, steps_per_s=rate))
            print(f"{'warp' + ('' if det else '-nd'):>7} {b:>6} {first:9.1f} {run:7.2f} {rate:12,.0f} "
                  f"{rate / cpu_ref:18.2f}   (graph capture {be.capture_s:.2f} s)", flush=True)
        be.close()
    return rows


def native_rows(scene, params, gait, args, ref, cores, nstep, out):
    native = make_backend("native", scene)
    warm = sample_lanes(1, params, gait)
    native.advance(native.initial_state(warm), warm, 1)  # the gait's controls are jitted on first use: not timed
    rows = []
    for b in (int(x) for x in args.native_batches.split(",")):
        lanes = sample_lanes(b, params, gait)
        state = native.initial_state(lanes)
        t = time.perf_counter()
        native.advance(state, lanes, 1)
        dt = time.perf_counter() - t
        rate = b * nstep / dt
        rows.append(dict(backend="native", batch=b, compile_s=0.0, run_s=dt, steps_per_s=rate))
        print(f"{'native':>7} {b:>6} {0:9.1f} {dt:7.2f} {rate:12,.0f} {rate / (ref * cores):18.2f}", flush=True)
    native.close()
    # the same colliding lanes on one thread: the per-core cost of this
    # workload (the resting scene above has no robot-robot contacts)
    one = make_backend("native", scene, nthread=1)
    lanes = sample_lanes(64, params, gait)
    t = time.perf_counter()
    one.advance(one.initial_state(lanes), lanes, 1)
    single = 64 * nstep / (time.perf_counter() - t)
    one.close()
    out["native_single_thread_same_lanes_steps_per_s"] = single
    best = max(r["steps_per_s"] for r in rows)
    out["native_parallel_efficiency"] = best / (single * cores)
    print(f"native, 1 thread, same 64 colliding lanes: {single:,.0f} steps/s; "
          f"best batched rate = {out['native_parallel_efficiency']:.2f} x (that x {cores} cores)")
    return rows


def mjx_rows(scene, params, gait, args, cpu_ref):
    import jax
    rows = []
    mjx_be = make_backend("mjx", scene)
    # compile time as JAX reports it (tracing, lowering, XLA compile), not first call minus
    # second: at large batches the run's own noise exceeds the compile time
    spent = []
    jax.monitoring.register_event_duration_secs_listener(
        lambda event, secs, **kw: spent.append(secs) if event.startswith("/jax/core/compile/") else None)
    for b in (int(x) for x in args.mjx_batches.split(",")):
        lanes = sample_lanes(b, params, gait)
        spent.clear()
        t = time.perf_counter()
        mjx_be.step_qpos(lanes, args.mjx_steps)  # compiles and runs
        first = time.perf_counter() - t
        compile_s = sum(spent)
        t = time.perf_counter()
        mjx_be.step_qpos(lanes, args.mjx_steps)
        run = time.perf_counter() - t
        rate = b * args.mjx_steps / run
        rows.append(dict(backend="mjx", device=str(jax.devices()[0].device_kind), batch=b,
                         compile_s=compile_s, first_call_s=first, run_s=run, steps_per_s=rate))
        print(f"{'mjx':>7} {b:>6} {compile_s:9.1f} {run:7.2f} {rate:12,.0f} {rate / cpu_ref:18.2f}",
              flush=True)
    return rows


if __name__ == "__main__":
    main()
