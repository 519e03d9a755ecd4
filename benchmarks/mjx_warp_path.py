"""MuJoCo Warp called directly (the warp backend) against MJX's ``impl='warp'``.

Both run the same lanes (valid pair configurations at rest, the gait's
controls set before every step, lab-lag by default) for the same steps on
whatever device is present (the first GPU, else Warp's CPU device). Three
paths are timed, each after a first call that builds or loads its kernels:

* ``direct``: ``mujoco_warp.step`` of the installed mujoco-warp, the warp
  backend's call;
* ``vendored``: ``mujoco_warp.step`` of the copy of MuJoCo Warp that
  mujoco-mjx carries (``mujoco.mjx.third_party.mujoco_warp``), called the same way;
* ``mjx``: ``jax.jit(lax.scan(vmap(mjx.step)))`` with ``mjx.put_model(impl='warp')``,
  which runs that vendored copy through JAX's FFI. Time spent inside Warp's
  FFI callback and in building its argument list is measured apart where
  the callback runs once per step (on the CPU it does).

So the gap between ``mjx`` and ``direct`` splits into the vendored copy's
own cost (``vendored`` vs ``direct``) and the JAX–Warp hand-over (``mjx`` vs
``vendored``). One lane is also compared with MuJoCo C after the same steps
(float32 against float64). Prints a table, writes JSON with the device name.

    python benchmarks/mjx_warp_path.py                      # CPU: 1, 16, 64, 256 worlds
    python benchmarks/mjx_warp_path.py --batches 1024,4096,16384 --out benchmarks/results/mjx_warp_path_gpu.json
"""

from __future__ import annotations

import argparse
import collections
import json
import pathlib
import platform
import time

import mujoco
import numpy as np

from smarticle_mjx import presets
from smarticle_mjx.bench import sample_lanes  # the same lanes as the throughput benchmark
from smarticle_mjx.engine import Scene
from smarticle_mjx.engine.core import lane_controls, on_step_grid
from smarticle_mjx.gait import GaitSpec


class CallbackClock:
    """Time spent in Warp's JAX FFI callback and in building its arguments (private Warp API; None if absent)."""

    def __init__(self):
        self.t = collections.defaultdict(float)
        self.calls = 0
        self.nargs = 0
        try:
            from warp._src.jax import ffi as wffi
            cls = wffi.FfiCallable
            build, cb = cls._build_arg_list, cls.ffi_callback
        except (ImportError, AttributeError):
            self.ok = False
            return
        self.ok = True
        clock = self

        def timed_build(self_, *a):
            t = time.perf_counter()
            r = build(self_, *a)
            clock.t["build_args"] += time.perf_counter() - t
            clock.nargs = len(r)
            return r

        def timed_cb(self_, *a):
            t = time.perf_counter()
            r = cb(self_, *a)
            clock.t["callback"] += time.perf_counter() - t
            clock.calls += 1
            return r

        cls._build_arg_list, cls.ffi_callback = timed_build, timed_cb

    def reset(self):
        self.t.clear()
        self.calls = 0


def warp_data(lib, wp, model, state, cuts, nconmax, njmax):
    """``lib``'s Model and a Data of one world per row of ``state`` (on the current
    Warp device), and a function that (re)loads ``state`` into it."""
    b = state.shape[0]
    mw = lib.put_model(model)
    try:
        d = lib.make_data(model, nworld=b, nconmax=nconmax, njmax=njmax)
    except TypeError:  # an older MuJoCo Warp takes the contact pool of all worlds
        d = lib.make_data(model, nworld=b, naconmax=nconmax * b, njmax=njmax)
    if hasattr(mw.opt, "warn_overflow"):
        mw.opt.warn_overflow = 0  # printed warnings would be timed; overflow is checked by the tests

    def upload():
        for k, arr in enumerate((d.qpos, d.qvel, d.act, d.qacc_warmstart)):
            if cuts[k + 1] > cuts[k]:
                arr.assign(wp.array(np.ascontiguousarray(state[:, cuts[k]:cuts[k + 1]], np.float32)))
        d.time.zero_()

    upload()
    return mw, d, upload


def warp_direct(lib, wp, model, state, cuts, ctrl, nconmax, njmax, device):
    """Run ``ctrl`` [T, B, nu] through ``lib.step``; (first call s, run s, qpos [B, nq])."""
    nstep = ctrl.shape[0]
    with wp.ScopedDevice(device):
        mw, d, upload = warp_data(lib, wp, model, state, cuts, nconmax, njmax)
        table = wp.array(ctrl.astype(np.float32))
        t = time.perf_counter()
        d.ctrl.assign(table[0])
        lib.step(mw, d)
        wp.synchronize_device(device)
        first = time.perf_counter() - t
        upload()
        t = time.perf_counter()
        for i in range(nstep):
            d.ctrl.assign(table[i])
            lib.step(mw, d)
        wp.synchronize_device(device)
        return first, time.perf_counter() - t, d.qpos.numpy()


STAGES = ("collision", "fwd_position", "solve", "step")


def stage_times(lib, wp, model, state, cuts, ctrl, nconmax, njmax, device, n=20):
    """ms per call of MuJoCo Warp's pipeline stages on the state after the timed run's first step."""
    with wp.ScopedDevice(device):
        mw, d, _ = warp_data(lib, wp, model, state, cuts, nconmax, njmax)
        d.ctrl.assign(wp.array(ctrl[0].astype(np.float32)))
        lib.step(mw, d)
        out = {}
        for name in STAGES:
            f = getattr(lib, name, None)
            if f is None:
                continue
            f(mw, d)
            wp.synchronize_device(device)
            t = time.perf_counter()
            for _ in range(n):
                f(mw, d)
            wp.synchronize_device(device)
            out[name] = 1e3 * (time.perf_counter() - t) / n
            if name == "solve":  # the same iterations at a higher cost each, or more iterations?
                out["solver_iterations_mean"] = float(d.solver_niter.numpy().mean())
        return out


def mjx_warp(model, state, cuts, ctrl, nconmax, njmax, clock):
    """The same through ``mjx.step`` with ``impl='warp'``; (compile s, run s, qpos)."""
    import jax
    import jax.numpy as jp
    from mujoco import mjx
    nstep, b, _ = ctrl.shape
    mx = mjx.put_model(model, impl="warp")

    def init(s):
        d = mjx.make_data(model, impl="warp", naconmax=nconmax * b, njmax=njmax)
        return d.replace(qpos=s[cuts[0]:cuts[1]], qvel=s[cuts[1]:cuts[2]], act=s[cuts[2]:cuts[3]],
                         qacc_warmstart=s[cuts[3]:cuts[4]])

    d0 = jax.jit(jax.vmap(init))(jp.asarray(state, jp.float32))
    vstep = jax.vmap(mjx.step, in_axes=(None, 0))

    @jax.jit
    def run(d, ctrl):
        def body(d, c):
            return vstep(mx, d.replace(ctrl=c)), None
        return jax.lax.scan(body, d, ctrl)[0]

    table = jp.asarray(ctrl, jp.float32)
    t = time.perf_counter()
    compiled = run.lower(d0, table).compile()
    jax.block_until_ready(compiled(d0, table[:1].repeat(nstep, 0)))
    first = time.perf_counter() - t
    clock.reset()
    t = time.perf_counter()
    d = compiled(d0, table)
    jax.block_until_ready(d)
    return first, time.perf_counter() - t, np.asarray(d.qpos)


def mujoco_c(model, state, cuts, ctrl):
    """Lane 0 in MuJoCo C (float64), the reference."""
    d = mujoco.MjData(model)
    s = state[0]
    d.qpos[:], d.qvel[:] = s[cuts[0]:cuts[1]], s[cuts[1]:cuts[2]]
    if model.na:
        d.act[:] = s[cuts[2]:cuts[3]]
    for i in range(ctrl.shape[0]):
        d.ctrl[:] = ctrl[i, 0]
        mujoco.mj_step(model, d)
    return d.qpos.copy()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batches", default="1,16,64,256")
    ap.add_argument("--steps", type=int, default=200, help="steps per timed run (0.1 s at dt 0.5 ms)")
    ap.add_argument("--model", default="lab-lag")
    ap.add_argument("--amplitude", type=float, default=90.0)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "mjx_warp_path.json"))
    args = ap.parse_args()

    clock = CallbackClock()  # before JAX traces anything through Warp
    import jax
    import warp as wp
    wp.config.quiet = True
    import mujoco_warp as mjw
    import mujoco.mjx.third_party.mujoco_warp as vendored

    from smarticle_mjx.engine.mjwarp import WarpBackend, buffer_sizes

    params = presets.params(args.model)
    gait = GaitSpec(args.amplitude)
    scene = Scene.build(params, 2)
    model = scene.model
    dt = float(model.opt.timestep)
    nconmax, njmax = buffer_sizes(model)
    device = wp.get_device("cuda:0" if wp.is_cuda_available() else "cpu")
    be = WarpBackend(scene, device=str(device))
    cuts = be.cuts
    out = dict(machine=platform.platform(), warp_device=str(device.name), jax_device=str(jax.devices()[0].device_kind),
               model=args.model, timestep=dt, amplitude=args.amplitude, steps=args.steps,
               mujoco=mujoco.__version__, mujoco_warp=getattr(mjw, "__version__", "?"),
               mjx=_version("mujoco-mjx"), warp=wp.config.version, jax=jax.__version__,
               buffers=dict(nconmax=nconmax, njmax=njmax), rows=[])
    print(f"device: {out['warp_device']} (JAX: {out['jax_device']}), model {args.model}, dt {dt}, "
          f"{args.steps} steps per run")
    print(f"{'worlds':>6} {'path':>9} {'first s':>8} {'ms/step':>8} {'steps/s':>10} {'vs direct':>9}  notes")
    for b in (int(x) for x in args.batches.split(",")):
        lanes = on_step_grid(sample_lanes(b, params, gait), dt)
        state = be.initial_state(lanes)
        ctrl = np.ascontiguousarray(np.swapaxes(lane_controls(scene, lanes, dt * np.arange(args.steps)), 0, 1))
        res = {}
        res["direct"] = warp_direct(mjw, wp, model, state, cuts, ctrl, nconmax, njmax, device)
        res["vendored"] = warp_direct(vendored, wp, model, state, cuts, ctrl, nconmax, njmax, device)
        res["mjx"] = mjx_warp(model, state, cuts, ctrl, nconmax, njmax, clock)
        cb = dict(clock.t)
        calls = clock.calls
        ref = mujoco_c(model, state, cuts, ctrl) if b == 1 else None
        base = res["direct"][1]
        for path, (first, run, qpos) in res.items():
            row = dict(path=path, worlds=b, first_call_s=first, run_s=run, ms_per_step=1e3 * run / args.steps,
                       steps_per_s=b * args.steps / run, vs_direct=run / base)
            note = ""
            if path == "mjx" and clock.ok and calls == args.steps:  # one callback per step (not replayed as a graph)
                row.update(callback_calls=calls, ffi_args=clock.nargs,
                           callback_ms_per_step=1e3 * cb.get("callback", 0.0) / calls,
                           build_args_ms_per_step=1e3 * cb.get("build_args", 0.0) / calls)
                note = (f"in Warp's callback {row['callback_ms_per_step']:.1f} ms/step, of which building "
                        f"{clock.nargs} arguments {row['build_args_ms_per_step']:.1f}")
            if ref is not None:
                row["max_abs_dqpos_vs_mujoco_c"] = float(np.max(np.abs(qpos[0] - ref)))
                note += f"  |qpos - MuJoCo C| <= {row['max_abs_dqpos_vs_mujoco_c']:.1e}"
            out["rows"].append(row)
            print(f"{b:>6} {path:>9} {first:8.1f} {row['ms_per_step']:8.2f} {row['steps_per_s']:10,.0f} "
                  f"{row['vs_direct']:9.2f}  {note}", flush=True)
        out["rows"][-1]["max_abs_dqpos_mjx_vs_direct"] = float(np.max(np.abs(res["mjx"][2] - res["direct"][2])))
        pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(args.out).write_text(json.dumps(out, indent=2))  # each batch as it ends (a lease may end first)
    # where the vendored copy's time goes: its pipeline stages against the installed release's, largest batch
    out["stages_ms"] = {name: stage_times(lib, wp, model, state, cuts, ctrl, nconmax, njmax, device)
                        for name, lib in (("direct", mjw), ("vendored", vendored))}
    out["stages_worlds"] = b
    print(f"stages at {b} worlds, ms per call: " + "; ".join(
        f"{st} direct {out['stages_ms']['direct'].get(st, float('nan')):.1f} / vendored "
        f"{out['stages_ms']['vendored'].get(st, float('nan')):.1f}" for st in STAGES)
        + "; solver iterations (mean over worlds) direct {:.2f} / vendored {:.2f}".format(
            out["stages_ms"]["direct"].get("solver_iterations_mean", float("nan")),
            out["stages_ms"]["vendored"].get("solver_iterations_mean", float("nan"))))
    pathlib.Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.out}")


def _version(dist):
    from importlib import metadata
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


if __name__ == "__main__":
    main()
