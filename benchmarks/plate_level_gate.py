"""The anisotropic plate's model-free gate on stored stress-suite sets: does the plate-frame drift tell the
plates that ``smx calibrate`` named rightly from those it named where none was hidden?

Since the joint plate hypothesis (seed 2030 on), ``smx calibrate`` fitted an anisotropic plate jointly with
the nominal parameters and named it where it gained 20 % held out. It was named about as often where no
plate was hidden (taking up how the library's robot slides unlike the measured one) as where one was. A
plate slipperier along one axis stretches a lone robot's step differently at each heading, which the
plate-frame drift test (``calibrate.drift.drift_test``, no model) reads as drift; a level isotropic plate
gives none. For every stored set (benchmarks/calibration_stress.py, same draw, data written as the suite
writes them) of the given seeds that hides an anisotropic plate or had one added, and with ``--clean`` every
clean set, this script runs the drift test and records its p and whether the gate
(``stages.plate_skip_reason``: drift read and p >= ``stages.P_LEVEL``) would withhold the plate. It reads the
calibrations as they were stored (before the gate); it does not calibrate.

    python benchmarks/plate_level_gate.py --min-seed 2030 --max-seed 2058 --tag development
    python benchmarks/plate_level_gate.py --min-seed 2049 --max-seed 2058 --clean --tag clean-2049

Seeds run since the gate (2059 on) were calibrated with it: give ``--max-seed`` to read only those before.

Writes results/plate_level_gate_<tag>.json and prints the table.
"""

from __future__ import annotations

import pathlib

import argparse
import json
import math
import time

from smarticle_mjx.calibrate.stress import draw_set
from plate_drift_gate import measure
from smarticle_mjx.calibrate.stages import ANISO, P_LEVEL, plate_skip_reason

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results


def stored(min_seed: int, max_seed: int | None, clean: bool) -> list[dict]:
    """Stored stress results (reported seeds only: numeric directories) that hide or added the plate, or
    (``clean``) hide nothing at all."""
    out = []
    for d in sorted((RESULTS / "calibration_stress").iterdir()):
        if not d.name.isdigit() or int(d.name) < min_seed or (max_seed is not None and int(d.name) > max_seed):
            continue
        for f in sorted(d.glob("set_*.json")):
            r = json.loads(f.read_text())
            s, sc = r["set"], r["score"]
            is_clean = not s["hidden"] and not s["outside"]
            if ANISO in s["hidden"] or ANISO in sc["added"] or (clean and is_clean):
                out.append(r)
    return out


def kind(r: dict) -> str:
    hidden, added = ANISO in r["set"]["hidden"], ANISO in r["score"]["added"]
    if hidden:
        return "named, hidden" if added else "not named, hidden"
    if added:
        return "named, not hidden"
    return "clean, not named"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--min-seed", type=int, default=2030)
    ap.add_argument("--max-seed", type=int, default=None)
    ap.add_argument("--clean", action="store_true", help="also every clean set of those seeds")
    ap.add_argument("--tag", default="development")
    a = ap.parse_args()
    out_path = RESULTS / f"plate_level_gate_{a.tag}.json"
    done = {(r["seed"], r["index"]): r for r in (json.loads(out_path.read_text())["rows"] if out_path.exists() else [])}
    t0 = time.perf_counter()
    for r in stored(a.min_seed, a.max_seed, a.clean):
        key = (r["set"]["suite_seed"], r["set"]["index"])
        if key in done:
            continue
        s = draw_set(*key)
        m = measure(s)  # the drift test on the set's data, as the tilt gates are read
        row = {"seed": key[0], "index": key[1], "hidden": s["hidden"], "outside": s["outside"],
               "added": r["score"]["added"], "kind": kind(r), "arms_tracked": s["arms_tracked"],
               "robots": s["robots"], "version": r.get("version"), "p": m["p"], "dof": m["dof"],
               "withheld": plate_skip_reason(m) is not None}
        done[key] = row
        print(row, flush=True)
        out_path.write_text(json.dumps({"p_level": P_LEVEL, "rows": list(done.values())}, indent=1))
    rows = list(done.values())
    table = {}
    for r in rows:
        t = table.setdefault(r["kind"], {"sets": 0, "withheld": 0, "not read": 0})
        t["sets"] += 1
        t["withheld"] += int(r["withheld"])
        t["not read"] += int(not r["dof"] or not math.isfinite(r["p"]))
    summary = {"p_level": P_LEVEL, "by_kind": table, "wall_s": time.perf_counter() - t0}
    out_path.write_text(json.dumps({**summary, "rows": rows}, indent=1))
    print("| sets | stored | withheld by the gate | drift not read (gate open) |\n|---|---|---|---|")
    for k in ("named, hidden", "not named, hidden", "named, not hidden", "clean, not named"):
        if k in table:
            print(f"| {k} | {table[k]['sets']} | {table[k]['withheld']} | {table[k]['not read']} |")


if __name__ == "__main__":
    main()
