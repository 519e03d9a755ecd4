"""How much of a glider's time are its robots in contact, or close? The case for resolving only the contacts.

The glider quantities need about 20 contact-force evaluations per contact time constant
(docs/timestep.md); labels and lone drift converge at 0.5 ms. If a glider's robots touched most of the
time, a finer step only near contact would cost what a finer step everywhere does. This follows
``--lanes`` gliders of the glider check's starts (glider_step.py: 128 random valid starts, seed 1, 90 deg,
model lab-lag; a glider here: touched in every period from 6 to 14 at 0.5 ms) step by step with
``mj_step`` at 0.5 ms for ``--periods`` periods and, at every step, the smallest distance between the two
robots' geoms (``mj_geomDistance`` over the nine geom pairs, capped at 10 mm).

Prints and writes (results/contact_proximity.json) the fraction of steps in contact and within 2, 4 and
6 mm.

    python benchmarks/contact_proximity.py        # ~2 minutes
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import mujoco
import numpy as np

from smarticle_mjx import presets
from smarticle_mjx.bench import pair_starts, run_pairs
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.core import lane_controls, on_step_grid, steps_per_period
from smarticle_mjx.gait import GaitSpec

MARGINS = (0.002, 0.004, 0.006)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=int, default=8)
    ap.add_argument("--periods", type=int, default=6)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "contact_proximity.json"))
    args = ap.parse_args()
    params = presets.params("lab-lag").replace(contact_substeps=1)
    gait = GaitSpec(90.0)
    poses = pair_starts(params, 128, 1, 90.0)
    _, touched, _, _ = run_pairs(params, gait, poses, 14, quiet=2)
    idx = np.flatnonzero(touched[:, 6:].all(1))[: args.lanes]
    scene = Scene.build(params, 2)
    m = scene.model
    with make_backend("native", scene) as be:
        lanes = on_step_grid(Lanes.from_gait(poses[idx], gait), m.opt.timestep)
        start = be.initial_state(lanes)
    nstep = steps_per_period(lanes.period, m.opt.timestep)
    ctrl = lane_controls(scene, lanes, m.opt.timestep * np.arange(nstep))
    robot_of = {i: int(m.geom_bodyid[i] >= 4) if m.geom_bodyid[i] > 0 else -1 for i in range(m.ngeom)}
    pairs = [(a, b) for a in range(m.ngeom) for b in range(m.ngeom) if robot_of[a] == 0 and robot_of[b] == 1]
    fromto = np.zeros(6)
    d = mujoco.MjData(m)
    dist = np.empty((len(idx), args.periods * nstep))
    t = time.perf_counter()
    for lane in range(len(idx)):
        mujoco.mj_setState(m, d, start[lane], mujoco.mjtState.mjSTATE_FULLPHYSICS)
        for s in range(args.periods * nstep):
            d.ctrl[:] = ctrl[lane, s % nstep]
            mujoco.mj_step(m, d)
            dist[lane, s] = min(mujoco.mj_geomDistance(m, d, a, b, 0.01, fromto) for a, b in pairs)
    out = {"model": "lab-lag", "timestep_s": m.opt.timestep, "gliders": int(len(idx)), "periods": args.periods,
           "steps": int(dist.size), "contact_fraction": float((dist <= 0).mean()),
           "within_fraction": {f"{g * 1e3:g} mm": float((dist < g).mean()) for g in MARGINS},
           "per_glider_within_4mm": [float(x) for x in (dist < 0.004).mean(1)],
           "wall_s": time.perf_counter() - t, "date": time.strftime("%Y-%m-%d")}
    print(f"{len(idx)} gliders x {args.periods} periods: in contact {out['contact_fraction']:.3f} of steps; "
          + ", ".join(f"within {k} {v:.3f}" for k, v in out["within_fraction"].items()))
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
