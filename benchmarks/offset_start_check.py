"""Does a named phase offset's held-out excess come from how the replay starts a robot that runs ahead?

The stress suite's generator starts every robot at rest in its first corner, its servo reference slewing
from there toward the corner its own clock names; the calibration's replay (calibrate/sim.py) sends the
servo the steady gait's setpoint at the robot's phase, mid-move for a robot 0.15 period ahead. After the
first period both are in steady gait. So each set is calibrated as the suite does (``calibrate`` with the
library; its clean twin with the nominal stage alone), once whole and once with the first ``--cut`` gait
periods of every trial left out (each trial then starts at its first fully tracked frame after that; 1.15
periods puts a robot without an offset mid-dwell, not just after a setpoint jump), and the held-out errors
set beside each other. Results: results/offset_start_check.json (one entry per set, written after each).

    python benchmarks/offset_start_check.py --suite-seed 2062 --sets 7,19 --cut 1.15
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from smarticle_mjx.calibrate import stress as CS  # noqa: E402

OUT = pathlib.Path(__file__).parent / "results" / "offset_start_check.json"


def cut(trials, periods: float):
    """Each trial from its first fully tracked frame ``periods`` gait periods after its start."""
    out = []
    for tr in trials:
        k = int(np.searchsorted(tr.t, tr.t[0] + periods * float(np.max(tr.periods))))
        ok = np.isfinite(tr.pose).all(axis=(1, 2))
        if tr.arms is not None:
            ok &= np.isfinite(tr.arms).all(axis=(1, 2))
        if not ok[k:].any():
            raise ValueError(f"{tr.name}: no fully tracked frame after {periods} periods")
        k += int(np.argmax(ok[k:]))
        out.append(dataclasses.replace(tr, t=tr.t[k:], pose=tr.pose[k:],
                                       arms=None if tr.arms is None else tr.arms[k:]))
    return out


def main():
    from smarticle_mjx import __version__
    from smarticle_mjx.bench import save_json
    from smarticle_mjx.calibrate.data import load
    from smarticle_mjx.calibrate.stages import calibrate
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite-seed", type=int, default=2062)
    ap.add_argument("--sets", default="7,19")
    ap.add_argument("--cut", type=float, default=1.15, help="gait periods left out at each trial's start")
    args = ap.parse_args()
    if not args.cut > 0:
        sys.exit("--cut must be a positive number of gait periods")
    results = json.loads(OUT.read_text()) if OUT.exists() else {}
    for idx in CS.indices(args.sets):
        path = pathlib.Path(__file__).resolve().parent / "results" / "calibration_stress" / str(args.suite_seed) / f"set_{idx:04d}.json"
        if not path.exists():
            sys.exit(f"{path}: no stored set (run calibration_stress.py for it first)")
        stored = json.loads(path.read_text())
        s = stored["set"]
        row = {"suite_seed": args.suite_seed, "set": idx, "cut_periods": args.cut, "truth": s["truth"],
               "whole": {"heldout": stored["score"]["heldout_after"],
                         "twin": stored["score"]["heldout_after"] / stored["score"]["heldout_vs_twin"]
                         if stored["score"]["heldout_vs_twin"] else None}}
        t0 = time.perf_counter()
        for key, effects in (("set", True), ("twin", False)):
            with tempfile.TemporaryDirectory() as tmp:
                CS.write_set(s, tmp, effects=effects)
                r = calibrate(cut(load(tmp, None), args.cut), structural=effects).summary
            row.setdefault("cut", {})[key] = r["after"]["err_heldout"]
            if effects:
                row["cut"]["added"] = [a["effect"] for a in r["added"]]
        row["cut"]["ratio"] = row["cut"]["set"] / row["cut"]["twin"]
        if row["whole"]["twin"]:
            row["whole"]["ratio"] = row["whole"]["heldout"] / row["whole"]["twin"]
        row["wall_s"] = time.perf_counter() - t0
        row["version"] = __version__
        results[f"{args.suite_seed}/{idx}/{args.cut:g}"] = row
        save_json(OUT, results)  # atomic: an interrupted run keeps the sets already written
        print(f"{args.suite_seed}/{idx}: whole {row['whole']['heldout']:.2f} against twin "
              f"{row['whole']['twin'] or float('nan'):.2f}; first {args.cut:g} periods left out: "
              f"{row['cut']['set']:.2f} against {row['cut']['twin']:.2f} (x{row['cut']['ratio']:.2f}), "
              f"added {row['cut']['added']}, {row['wall_s']:.0f} s", flush=True)


if __name__ == "__main__":
    main()
