"""Backends against each other: bound/unbound labels on the same configurations.

Runs a sample of valid random pair configurations for --periods periods on
each backend named and prints, for every pair of backends, the label
agreement per period and at the end, next to the floor set by chaos
(benchmarks/label_sensitivity.py: the same backend with robot 2 shifted by 1 nm).

    python benchmarks/backend_agreement.py --configs 200 --periods 20                      # native vs mjx
    python benchmarks/backend_agreement.py --backends native,mjx,warp --model lab-lag \
        --out benchmarks/results/backend_agreement_gpu.json                                 # on a GPU
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import numpy as np

from smarticle_mjx import configs as C
from smarticle_mjx import scene as S
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.core import Status
from smarticle_mjx.gait import GaitSpec


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", type=int, default=200)
    ap.add_argument("--periods", type=int, default=20)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "backend_agreement.json"))
    ap.add_argument("--raw", default=None, help="also save per-lane records (.npz) here")
    ap.add_argument("--backends", default="native,mjx", help="comma-separated; the first is the reference")
    ap.add_argument("--model", default=None, help="model preset (default: the scene defaults of SceneParams())")
    args = ap.parse_args()
    from smarticle_mjx import presets
    params = presets.params(args.model) if args.model else S.SceneParams()
    gait = GaitSpec(90.0)
    backends = args.backends.split(",")
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    rng = np.random.default_rng(args.seed)
    poses = C.sample_valid_pairs(args.configs, rng, (0.8, 2.0), a0[0], a0[1])
    lanes = Lanes.from_gait(poses, gait)
    scene = Scene.build(params, 2)
    out = {"configs": len(poses), "periods": args.periods, "native_ls_iterations": params.ls_iterations,
           "model": args.model or "SceneParams()", "backends": backends}
    touched, status, raw = {}, {}, {}
    for name in backends:
        be = make_backend(name, scene)
        if name == "mjx":
            import jax
            out["mjx_ls_iterations"] = int(be.model.opt.ls_iterations)
            out["mjx_device"] = str(jax.devices()[0].device_kind)
        if name == "warp":
            out["warp_device"] = str(be.device.name) if hasattr(be.device, "name") else str(be.device)
            out["warp_box_collider"] = be.box_collider
        t = time.perf_counter()
        _, rec, _ = be.advance(be.initial_state(lanes), lanes, args.periods)
        out[f"{name}_wall_s"] = time.perf_counter() - t
        touched[name] = rec.touched[:, :, 0]
        out[f"{name}_bad_status"] = int((rec.status != 0).sum())
        status[name] = np.asarray(rec.status)
        raw.update({f"{name}_touched": rec.touched, f"{name}_min_dist": rec.min_dist,
                    f"{name}_status": status[name], f"{name}_poses": rec.poses})
        out[f"{name}_status_bits"] = {b.name: int(((status[name] & int(b)) != 0).sum())
                                      for b in (Status.NONFINITE, Status.PENETRATION, Status.OVERFLOW)}
        print(f"{name}: {out[f'{name}_wall_s']:.0f} s", flush=True)
        if hasattr(be, "close"):
            be.close()
    ref = backends[0]
    for other in backends[1:]:
        key = "" if (ref, other) == ("native", "mjx") else f"{other}_vs_{ref}_"
        out.update({key + k: v for k, v in compare(touched[ref], touched[other], status[ref], status[other],
                                                     ref, other).items()})
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))
    if args.raw:
        np.savez_compressed(args.raw, initial_poses=poses, **raw)


def compare(a, b, sa, sb, ref: str, other: str) -> dict:
    """Label agreement of ``other`` with ``ref`` (touched [lanes, periods], status [lanes])."""
    out = {}
    out["agree_per_period"] = [float(x) for x in (a == b).mean(0)]
    out["agree_bound_end"] = float((a[:, -1] == b[:, -1]).mean())
    out["agree_attracted"] = float((a[:, -5:].any(1) == b[:, -5:].any(1)).mean())
    out[f"bound_end_{ref}"], out[f"bound_end_{other}"] = float(a[:, -1].mean()), float(b[:, -1].mean())
    # is the disagreement in lanes one backend flagged (non-finite, deep penetration)?
    ok = (sa == 0) & (sb == 0)
    out["lanes_ok_on_both"] = int(ok.sum())
    out["agree_bound_end_ok_lanes"] = float((a[ok, -1] == b[ok, -1]).mean()) if ok.any() else None
    out["disagreements_in_flagged_lanes"] = int(((a[:, -1] != b[:, -1]) & ~ok).sum())
    out["disagreements"] = int((a[:, -1] != b[:, -1]).sum())
    print(f"{other} vs {ref}, {a.shape[0]} configurations, {a.shape[1]} periods")
    print("agreement per period:", " ".join(f"{x:.2f}" for x in out["agree_per_period"]))
    print(f"bound at the end: agree {out['agree_bound_end']:.3f} ({ref} {out[f'bound_end_{ref}']:.3f}, "
          f"{other} {out[f'bound_end_{other}']:.3f}); attracted: agree {out['agree_attracted']:.3f}")
    print(f"{out['disagreements_in_flagged_lanes']} of {out['disagreements']} disagreements are in flagged lanes; "
          f"agreement on the {out['lanes_ok_on_both']} lanes unflagged on both: {out['agree_bound_end_ok_lanes']}")
    return out


if __name__ == "__main__":
    main()
