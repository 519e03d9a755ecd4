"""MJX vs native: bound/unbound labels on the same configurations.

Runs a sample of valid random pair configurations for --periods periods on
both backends and prints the label agreement per period and at the end, next
to the floor set by chaos (benchmarks/label_sensitivity.py: the same backend
with robot 2 shifted by 1 nm).

    python benchmarks/backend_agreement.py --configs 200 --periods 20
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
    args = ap.parse_args()
    params, gait = S.SceneParams(), GaitSpec(90.0)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    rng = np.random.default_rng(args.seed)
    poses = C.sample_valid_pairs(args.configs, rng, (0.8, 2.0), a0[0], a0[1])
    lanes = Lanes.from_gait(poses, gait)
    scene = Scene.build(params, 2)
    out = {"configs": len(poses), "periods": args.periods, "native_ls_iterations": params.ls_iterations}
    touched, status, raw = {}, {}, {}
    for name in ("native", "mjx"):
        be = make_backend(name, scene)
        if name == "mjx":
            out["mjx_ls_iterations"] = int(be.model.opt.ls_iterations)
        t = time.perf_counter()
        _, rec, _ = be.advance(be.initial_state(lanes), lanes, args.periods)
        out[f"{name}_wall_s"] = time.perf_counter() - t
        touched[name] = rec.touched[:, :, 0]
        out[f"{name}_bad_status"] = int((rec.status != 0).sum())
        status[name] = np.asarray(rec.status)
        raw.update({f"{name}_touched": rec.touched, f"{name}_min_dist": rec.min_dist,
                    f"{name}_status": status[name], f"{name}_poses": rec.poses})
        out[f"{name}_status_bits"] = {b.name: int(((status[name] & int(b)) != 0).sum())
                                      for b in (Status.NONFINITE, Status.PENETRATION)}
        print(f"{name}: {out[f'{name}_wall_s']:.0f} s", flush=True)
    a, b = touched["native"], touched["mjx"]
    out["agree_per_period"] = [float(x) for x in (a == b).mean(0)]
    out["agree_bound_end"] = float((a[:, -1] == b[:, -1]).mean())
    out["agree_attracted"] = float((a[:, -5:].any(1) == b[:, -5:].any(1)).mean())
    out["bound_end_native"], out["bound_end_mjx"] = float(a[:, -1].mean()), float(b[:, -1].mean())
    # is the disagreement in lanes one backend flagged (non-finite, deep penetration)?
    ok = (status["native"] == 0) & (status["mjx"] == 0)
    out["lanes_ok_on_both"] = int(ok.sum())
    out["agree_bound_end_ok_lanes"] = float((a[ok, -1] == b[ok, -1]).mean()) if ok.any() else None
    out["disagreements_in_flagged_lanes"] = int(((a[:, -1] != b[:, -1]) & ~ok).sum())
    out["disagreements"] = int((a[:, -1] != b[:, -1]).sum())
    print(f"{len(poses)} configurations, {args.periods} periods")
    print("agreement per period:", " ".join(f"{x:.2f}" for x in out["agree_per_period"]))
    print(f"bound at the end: agree {out['agree_bound_end']:.3f} (native {out['bound_end_native']:.3f}, "
          f"mjx {out['bound_end_mjx']:.3f}); attracted: agree {out['agree_attracted']:.3f}")
    print(f"flagged lanes: native {out['native_status_bits']}, mjx {out['mjx_status_bits']}; "
          f"{out['disagreements_in_flagged_lanes']} of {out['disagreements']} disagreements are in flagged lanes; "
          f"agreement on the {out['lanes_ok_on_both']} lanes unflagged on both: {out['agree_bound_end_ok_lanes']}")
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))
    if args.raw:
        np.savez_compressed(args.raw, initial_poses=poses, **raw)


if __name__ == "__main__":
    main()
