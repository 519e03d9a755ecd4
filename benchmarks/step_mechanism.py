"""Which part of the 0.5 ms step biases the glider quantities? One numerical choice switched at a time at
0.5 ms, each against the reference at 0.0625 ms, on glider_step.py's starts (128 random valid pairs,
seed 1, 100 periods at 90 deg, model lab-lag; gliders bound every period after 10).

Variants change numerics only (the robot's physical parameters stay lab-lag's):
  * the integrator: implicitfast (default) -> implicit (also linearises the Coriolis and the
    actuators' position gains), Euler (semi-implicit: joint damping only, the servo's PD explicit),
    RK4 (explicit, fourth order);
  * the servo's lag filter is already integrated exactly (dyntype filterexact), so it is not a
    candidate; the contact's solref time constant is physics (absolute seconds), so stiffer contacts
    are a model change, not a switch of this table.

Per variant: gliders, beta, net speed and direction persistence with 95 % bootstrap intervals and the
paired bootstrap interval of each difference from the reference (starts resampled together).
Resumable: each variant's per-period tracks are kept in results/step_mechanism_runs/ and reused.

    python benchmarks/step_mechanism.py              # the reference alone takes ~20 min on 2 cores
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import time

import numpy as np

from glider_step import BURN_IN, PERIODS, POOL, SEED, paired_rows
from smarticle_mjx import presets
from smarticle_mjx.bench import gliding, pair_starts, save_json

ROOT = pathlib.Path(__file__).resolve().parent
RUNS = ROOT / "results" / "step_mechanism_runs"
REFERENCE = "0.0625 ms (reference)"
VARIANTS = {  # name -> (time step s, SceneParams changes)
    REFERENCE: (6.25e-5, {}),
    "0.5 ms implicitfast (default)": (5e-4, {}),
    "0.5 ms implicit": (5e-4, {"integrator": "implicit"}),
    "0.5 ms Euler": (5e-4, {"integrator": "Euler"}),
    "0.5 ms RK4": (5e-4, {"integrator": "RK4"}),
}


def run(name: str, poses: np.ndarray) -> pathlib.Path:
    dt, changes = VARIANTS[name]
    slug = name.split(" (")[0].replace(" ", "_")
    path = RUNS / f"lab-lag_{slug}_{POOL}x{PERIODS}_s{SEED}.npz"
    if path.exists() and np.array_equal(np.load(path)["poses"], poses):
        print(f"reusing {path.name}", flush=True)
        return path
    params = dataclasses.replace(presets.params("lab-lag"), timestep=dt, **changes)
    t = time.perf_counter()
    gliding(params, POOL, PERIODS, SEED, BURN_IN, save=path)
    print(f"{name}: {POOL} starts x {PERIODS} periods in {time.perf_counter() - t:.0f} s", flush=True)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=None, help="comma-separated variant names (the reference always runs)")
    ap.add_argument("--boot", type=int, default=1000)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "step_mechanism.json")
    args = ap.parse_args()
    names = [REFERENCE] + [n for n in VARIANTS if n != REFERENCE and (not args.only or n in args.only.split(","))]
    poses = pair_starts(presets.params("lab-lag"), POOL, SEED, 90.0)
    data = {}
    for n in names:
        z = np.load(run(n, poses))
        data[n] = (z["com"], z["touched"])
    rows = paired_rows(data, REFERENCE, args.boot, width=30)
    res = {"model": "lab-lag", "starts": POOL, "periods": PERIODS, "burn_in": BURN_IN, "seed": SEED,
           "runs": {k: {"dt_s": VARIANTS[k][0], "changes": VARIANTS[k][1], **row} for k, row in rows.items()}}
    save_json(args.out, res)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
