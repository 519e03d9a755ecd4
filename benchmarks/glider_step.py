"""Do the glider quantities converge in the time step? Runs at 0.25 ms and 0.5 ms
against a reference run at a fine step, from the same starts.

The validation study at 0.5 ms gave beta 1.54 [1.45, 1.62] and V_com 0.0033 W/period
where the same 400 starts at 0.25 ms gave 1.29 [1.20, 1.36] and 0.0019: intervals that
do not overlap, although only the step changed. Labels converge in dt (docs/timestep.md);
whether the glider quantities do is measured here. Starts: the fidelity confirmation's
(benchmarks/fidelity_screen.py: 128 random valid starts, seed 1, 100 periods at 90 deg,
model lab-lag), run by its ``gliding``. Each step's per-period tracks are saved in
results/fidelity_tracks/ under a name that carries the step (reused when they exist and
were run from the same starts). Prints each quantity per step with the 95 % paired
bootstrap interval of its difference from the reference (starts resampled together in
all runs; a start counts as a glider in each run where it is one).

    python benchmarks/glider_step.py                 # ~30 min on 2 cores (the reference ~21 of them)

Writes results/glider_step.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent
from smarticle_mjx.bench import STEP_CHECK_SEED, gliding, pair_starts
from smarticle_mjx import presets
from smarticle_mjx.reduce.gliders import glider_transport, steady_gliders

TRACKS = ROOT / "results" / "fidelity_tracks"
STEPS = (2.5e-4, 5e-4)  # the default before version 0.3.0, and since
POOL, SEED, PERIODS = 128, STEP_CHECK_SEED, 100  # the fidelity confirmation's starts
BURN_IN = 10


def quantities(com: np.ndarray, touched: np.ndarray) -> dict:
    """beta (centred MSD, delays 5-15), net speed and direction persistence of the gliders
    (bound in every period after the burn-in) among these starts, as the time-step study
    measures them (timestep_candidates.py)."""
    glide = steady_gliders(touched, BURN_IN)
    if glide.sum() < 3:
        return dict(gliders=int(glide.sum()), beta=np.nan, net_speed=np.nan, persistence=np.nan)
    return dict(gliders=int(glide.sum()), **dataclasses.asdict(glider_transport(com[glide, BURN_IN:].astype(float))))


def tracks(poses: np.ndarray, dt: float) -> pathlib.Path:
    """The per-period tracks of the confirmation's starts at step ``dt`` (run if missing)."""
    path = TRACKS / f"lab-lag@{dt * 1e3:g}ms_glide_{POOL}x{PERIODS}_s{SEED}.npz"
    if path.exists() and np.array_equal(np.load(path)["poses"], poses):
        print(f"reusing {path.name}")
        return path
    t = time.perf_counter()
    gliding(dataclasses.replace(presets.params("lab-lag"), timestep=dt, integrator="implicitfast", contact_substeps=1), POOL, PERIODS, SEED, BURN_IN, save=path)
    print(f"ran {POOL} starts x {PERIODS} periods at {dt * 1e3:g} ms in {time.perf_counter() - t:.0f} s")
    return path


def quantities_runs30(com: np.ndarray, touched: np.ndarray) -> dict:
    """As :func:`quantities`, but a glider is each start's longest bound run of at least 30 periods (the
    validation page's rule, ``reduce.gliders.glider_runs``), its track from the run's first period."""
    from smarticle_mjx.reduce.gliders import glider_tracks
    tr = glider_tracks(com, touched, 30)
    if len(tr) < 3:
        return dict(gliders=int(len(tr)), beta=np.nan, net_speed=np.nan, persistence=np.nan)
    return dict(gliders=int(len(tr)), **dataclasses.asdict(glider_transport(tr)))


def paired_rows(data: dict, ref: str, boot: int, width: int = 20, measure=quantities) -> dict:
    """Per run (name -> (com, touched) of the same starts): gliders and each quantity with its 95 %
    bootstrap interval and, but for the reference ``ref``, its difference from the reference with the
    paired bootstrap interval (starts resampled together in all runs). Prints a line per run."""
    rng = np.random.default_rng(0)
    idx = [rng.integers(0, POOL, POOL) for _ in range(boot)]
    point = {k: measure(*v) for k, v in data.items()}
    boots = {k: [measure(v[0][i], v[1][i]) for i in idx] for k, v in data.items()}
    rows = {}
    for k in data:
        row = {"gliders": point[k]["gliders"]}
        for q in ("beta", "net_speed", "persistence"):
            vals = np.array([b[q] for b in boots[k]])
            lo, hi = np.nanpercentile(vals, [2.5, 97.5])
            row[q] = {"value": point[k][q], "ci95": [float(lo), float(hi)]}
            if k != ref:
                d = vals - np.array([b[q] for b in boots[ref]])
                dlo, dhi = np.nanpercentile(d, [2.5, 97.5])
                row[q]["minus_reference"] = point[k][q] - point[ref][q]
                row[q]["minus_reference_ci95"] = [float(dlo), float(dhi)]
        rows[k] = row
        print(f"{k:>{width}}: {row['gliders']} gliders; " + "; ".join(
            f"{q} {row[q]['value']:.4g} [{row[q]['ci95'][0]:.4g}, {row[q]['ci95'][1]:.4g}]"
            + (f" (vs ref {row[q]['minus_reference']:+.3g} [{row[q]['minus_reference_ci95'][0]:+.3g}, "
               f"{row[q]['minus_reference_ci95'][1]:+.3g}])" if "minus_reference" in row[q] else "")
            for q in ("beta", "net_speed", "persistence")), flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dt", type=float, default=6.25e-5)
    ap.add_argument("--boot", type=int, default=1000)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "glider_step.json")
    args = ap.parse_args()
    poses = pair_starts(presets.params("lab-lag"), POOL, SEED, 90.0)
    ref_name = f"{args.dt * 1e3:g} ms (reference)"
    runs = {f"{dt * 1e3:g} ms": np.load(tracks(poses, dt)) for dt in STEPS}
    runs[ref_name] = np.load(tracks(poses, args.dt))
    data = {k: (z["com"], z["touched"]) for k, z in runs.items()}
    res = {"model": "lab-lag", "starts": POOL, "periods": PERIODS, "burn_in": BURN_IN,
           "reference_dt_s": args.dt, "runs": paired_rows(data, ref_name, args.boot)}
    args.out.write_text(json.dumps(res, indent=1, default=float))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
