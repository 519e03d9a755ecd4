"""What tracking noise leaves of a tilt's drift: the model-free drift test on stress-suite sets that hide a plate
tilt, read on the set's data and on the same data written without its tracking noise.

On every stored stress seed, a tilt hidden beside tracking noise was missed (docs/calibration.md, "A tilt
beside tracking noise"), where tilts alone were named. The drift test (``calibrate.drift.drift_test``) needs
no model, so the question "is it the data or the calibration?" can be asked of it directly: for each set of
the given suite seeds and indices (benchmarks/calibration_stress.py's draw, data written as the suite writes
them) that hides ``plate_tilt``, the test is run on the data as drawn and on the data with the tracking noise
left out (the same build, starts, frame times and other effects; for a set without noise the two are the
same), and the drift chi^2, its p and whether the gaits' drifts point one way are recorded. The tilt stage
fits a tilt only where p < ``drift.P_DRIFT`` and names it only where the model's fit then passes
``stages.tilt_accepted``; this script stops before the model.

    python benchmarks/tilt_noise.py --suite-seeds 2026-2031,2040-2051,2058-2060 --sets 0-59

Writes results/tilt_noise.json and prints one line per set.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import tempfile

from smarticle_mjx.calibrate.stress import draw_set, seed_indices, write_set
from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.drift import P_DRIFT, drift_test
from smarticle_mjx.calibrate.stress import NOISE_KEYS, without_noise  # noqa: F401

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results

NOISE = NOISE_KEYS


def read(s: dict) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        write_set(s, tmp)
        d = drift_test(load(tmp))
    return {"chi2": d["chi2"], "dof": d["dof"], "p": d["p"], "significant": d["significant"],
            "one_direction": bool(d["directions"]["consistent"]), "groups_drifting": d["directions"]["groups"]}


def stored_outcome(seed: int, index: int) -> dict | None:
    """What the suite's stored calibration of this set added (None where the set was not run)."""
    path = RESULTS / "calibration_stress" / str(seed) / f"set_{index:04d}.json"
    if not path.exists():
        return None
    row = json.loads(path.read_text())
    return {"added": row["score"]["added"], "tilt_named": "plate_tilt" in row["score"]["added"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite-seeds", default="2026-2031,2040-2051,2058-2060")
    ap.add_argument("--sets", default="0-59")
    ap.add_argument("--only-run", action="store_true", help="only sets the suite has calibrated (stored)")
    ap.add_argument("--out", default=str(RESULTS / "tilt_noise.json"))
    args = ap.parse_args()
    rows = []
    for seed, i in seed_indices(args.suite_seeds, args.sets):
        s = draw_set(seed, i)
        if "plate_tilt" not in s["hidden"]:
            continue
        outcome = stored_outcome(seed, i)
        if args.only_run and outcome is None:
            continue
        noisy = "tracking_noise" in s["hidden"]
        row = {"suite_seed": seed, "index": i, "hidden": s["hidden"], "outside": s["outside"],
               "tilt_deg": list(s["generator"]["tilt_deg"]), "frame_rate_hz": s["frame_rate_hz"],
               "arms_tracked": s["arms_tracked"], "amplitudes": s["amplitudes"],
               "noise": {k: s["generator"][k] for k in NOISE} if noisy else None,
               "as_drawn": read(s), "without_noise": read(without_noise(s)) if noisy else None,
               "stored": outcome}
        rows.append(row)
        w = row["without_noise"]
        print(f"{seed}/{i:<3} {'+'.join(s['hidden']):<40} p {row['as_drawn']['p']:9.2g} "
              f"(chi2 {row['as_drawn']['chi2']:8.1f} / {row['as_drawn']['dof']})"
              + (f"  without noise p {w['p']:9.2g} (chi2 {w['chi2']:8.1f})" if w else "")
              + (f"  stored: {'named' if outcome['tilt_named'] else 'not named'}" if outcome else ""),
               flush=True)

    def count(sel):
        return {"sets": len(sel), "significant": sum(r["as_drawn"]["significant"] for r in sel),
                "significant_without_noise": sum((r["without_noise"] or r["as_drawn"])["significant"] for r in sel),
                "run": sum(r["stored"] is not None for r in sel),
                "named": sum(bool(r["stored"] and r["stored"]["tilt_named"]) for r in sel)}
    summary = {"p_drift": P_DRIFT,
               "beside_noise": count([r for r in rows if r["noise"]]),
               "without_noise_hidden": count([r for r in rows if not r["noise"]])}
    pathlib.Path(args.out).write_text(json.dumps({"summary": summary, "rows": rows}, indent=1, default=float))
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
