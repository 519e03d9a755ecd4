"""The collision mechanism of a C1 glider, per period, with the collision record.

Runs one pair (default: the C1 start |r| 1.62 W, theta 222 deg, phi 180 deg at
90 deg) for K periods under each named preset, and reports per period the
sign of phi - 180 deg, the step of the centre of mass, and which of the two
mirror-image arm-arm contacts of the third quarter (robot 0's arm 2 on robot
1's arm 1, or robot 0's arm 1 on robot 1's arm 2) carried the larger impulse.
Writes results/fidelity_mechanism.json and, per preset, a figure of the
collision sequence over the two periods around the first reversal of the
direction of travel (or the last two periods) into docs/fidelity/.

  python benchmarks/fidelity_mechanism.py --models paper,lab,dart --periods 60
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent

from smarticle_mjx import configs as C, plots, presets
from smarticle_mjx.engine.core import Record
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.gait import GaitSpec
from smarticle_mjx.reduce import collisions as RC


def run(model: str, start, periods: int, bins: int = 16) -> dict:
    params = presets.params(model)
    gait = GaitSpec(90.0)
    W = params.robot.body_length
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    poses = C.pair_poses(start[0], math.radians(start[1]), math.radians(start[2]), a0[0], a0[1], params.robot)
    res = simulate(params, poses, gait, periods, record=Record(collisions=True, collision_bins=bins))
    r, th, ph = res.relative()
    com = (res.poses[:, 0, :2] + res.poses[:, 1, :2]) / 2 / W
    coll = {k: v[None] for k, v in res.collisions.items()}
    by_kind = RC.period_totals(coll).impulse_r_by_kind[0, :, 0]  # [K, kinds]
    i21, i12 = RC.KINDS.index("arm2-arm1"), RC.KINDS.index("arm1-arm2")
    dev = np.degrees(np.angle(np.exp(1j * (ph[1:] - np.pi))))
    # which mirror contact pushed harder (impulses are repulsive: more negative = harder)
    q3 = np.where(by_kind[:, i21] < by_kind[:, i12], 1, -1)
    steps = np.diff(com, axis=0)
    cosines = (steps[1:] * steps[:-1]).sum(-1) / np.maximum(
        np.linalg.norm(steps[1:], axis=1) * np.linalg.norm(steps[:-1], axis=1), 1e-12)
    reversal = int(np.argmax(cosines < 0)) + 1 if (cosines < 0).any() else None
    agree = float(np.mean(np.sign(dev) == q3)) if len(dev) else float("nan")
    attractive = {k: float((by_kind[:, j] > 0).mean()) for j, k in enumerate(RC.KINDS) if (by_kind[:, j] != 0).any()}
    return {"model": model, "start": list(start), "periods": periods, "bound": int(res.touched[:, 0].sum()),
            "phi_dev_deg": dev.round(2).tolist(), "r_W": r[1:].round(4).tolist(),
            "step_W": np.linalg.norm(steps, axis=1).round(5).tolist(),
            "net_W": float(np.linalg.norm(com[-1] - com[0])), "path_W": float(np.linalg.norm(steps, axis=1).sum()),
            "sign_flips": int((np.diff(np.sign(dev)) != 0).sum()),
            "q3_dominant_matches_sign": agree, "first_reversal": reversal,
            "impulse_r_mean_mNs": {k: float(by_kind[:, j].mean() * 1e3) for j, k in enumerate(RC.KINDS)},
            "attractive_fraction": attractive, "coll": coll}


def return_maps(track_dir: pathlib.Path, models, out_dir: pathlib.Path, burn_in: int = 10) -> dict:
    """phi - 180 deg in period n+1 against period n for every C1 glider of the
    screening study (its saved tracks), one panel per preset. A symmetric
    glider sits at the origin; one that keeps a broken symmetry sits in the
    first or third quadrant; one that swaps the lead every period sits in the
    second and fourth. Returns, per preset, the fraction of steps in each."""
    plt = plots.pyplot()
    models = [m for m in models if list(track_dir.glob(f"{m}_glide_*.npz"))]
    cols = min(4, len(models))
    rows = -(-len(models) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.0 * cols, 3.0 * rows), squeeze=False)
    for ax in axes.ravel()[len(models):]:
        ax.set_visible(False)
    out = {}
    for ax, m in zip(axes.ravel(), models):
        f = max(track_dir.glob(f"{m}_glide_*.npz"), key=lambda p: p.stat().st_size)
        d = np.load(f)
        # C1 gliders only: a C2 glider's phi - 180 deg sits at +-180 and wraps
        glide = d["touched"][:, burn_in:].all(1) & (np.cos(d["rel"][:, burn_in:, 2]) < 0).all(1)
        dev = np.degrees(np.angle(np.exp(1j * (d["rel"][glide, burn_in:, 2] - np.pi))))
        x, y = dev[:, :-1].ravel(), dev[:, 1:].ravel()
        ax.scatter(x, y, s=3, alpha=0.4)
        lim = max(30.0, float(np.nanpercentile(np.abs(dev), 98)) if dev.size else 30.0)
        ax.plot([-lim, lim], [-lim, lim], color="0.7", lw=0.6)
        ax.axhline(0, color="0.7", lw=0.6)
        ax.axvline(0, color="0.7", lw=0.6)
        ax.set(xlim=(-lim, lim), ylim=(-lim, lim), title=f"{m} ({int(glide.sum())} C1 gliders)",
               xlabel="φ−180° in period n")
        small = (np.abs(x) < 2) & (np.abs(y) < 2)
        same = (np.sign(x) == np.sign(y)) & ~small
        out[m] = {"gliders": int(glide.sum()), "samples": int(x.size),
                  "symmetric (both |.| < 2 deg)": float(small.mean()) if x.size else float("nan"),
                  "kept sign": float(same.mean()) if x.size else float("nan"),
                  "swapped sign": float((~same & ~small).mean()) if x.size else float("nan")}
    for row in axes:
        row[0].set_ylabel("φ−180° in period n+1")
    plots.save_figure(fig, out_dir, "return_map", ("png",))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", default="paper,lab,dart")
    ap.add_argument("--start", default="1.62,222,180", help="|r| (W), theta, phi (deg)")
    ap.add_argument("--periods", type=int, default=60)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "fidelity_mechanism.json")
    ap.add_argument("--figures", type=pathlib.Path, default=ROOT.parent / "docs" / "fidelity")
    ap.add_argument("--return-maps", action="store_true",
                    help="only draw the return maps from the screening study's saved tracks")
    args = ap.parse_args()
    out = json.loads(args.out.read_text()) if args.out.exists() else {}
    if args.return_maps:
        out["return_maps"] = return_maps(ROOT / "results" / "fidelity_tracks", args.models.split(","), args.figures)
        print(json.dumps(out["return_maps"], indent=1))
        args.out.write_text(json.dumps(out, indent=1))
        return
    start = tuple(float(x) for x in args.start.split(","))
    for model in args.models.split(","):
        res = run(model, start, args.periods)
        coll = res.pop("coll")
        k = res["first_reversal"] if res["first_reversal"] is not None else args.periods - 1
        pair = [max(k - 1, 0), k]
        plots.collision_sequence(coll, 0, pair, args.figures, f"collisions_{model}",
                                 title=f"{model}: C1 start {args.start}, periods {pair[0]}-{pair[1]}")
        out[f"{model}@{args.start}"] = res
        print(f"{model}: bound {res['bound']}/{args.periods}, net {res['net_W']:.3f} W of path {res['path_W']:.3f} W, "
              f"sign flips {res['sign_flips']}, Q3 mirror contact matches the sign in "
              f"{res['q3_dominant_matches_sign']:.0%} of periods, first reversal at period {res['first_reversal']}",
              flush=True)
    args.out.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
