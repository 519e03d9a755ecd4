"""Would withholding the anisotropic plate where the drift reads as one vector have helped? (a reading)

Stress set 2140/19 hides a tilt; the anisotropic plate's joint hypothesis, tried in the nominal stage
before the tilt stage, was added first, although the plate-frame drift fitted one drift vector far better
than one anisotropy of the robot's step (``drift.PlateDrift``: chi2 45 against 3306). The lead was to
withhold the plate where the drift says one vector. This script reads, without any model, the drift of
every stored set of the given whole seeds where the plate was added (their stored summaries,
``calibrate.stress.pooled_rows``; data written again as the suite writes them), so that the rule's price can be counted before anyone runs it: a set whose plate was named
rightly and whose drift fits one vector at least as well as one anisotropy would lose its plate.

    python benchmarks/plate_vs_vector.py --pool 2049-2051,2058-2066,2073,2140-2142

Writes results/plate_vs_vector.json and prints one line a set. It changes no rule.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import tempfile

from smarticle_mjx.calibrate.stress import draw_set, pooled_rows as _pooled_rows, write_set
from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.drift import drift_test

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results


def pooled_rows(seeds: str) -> list[dict]:
    return _pooled_rows(seeds, RESULTS)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pool", required=True, metavar="SEEDS")
    args = ap.parse_args()
    try:
        stored = pooled_rows(args.pool)
    except (FileNotFoundError, ValueError) as e:
        ap.error(str(e))
    rows = []
    for d in stored:
        if "anisotropic_friction" not in d["score"]["added"]:
            continue
        s = draw_set(d["set"]["suite_seed"], d["set"]["index"])
        with tempfile.TemporaryDirectory() as t:
            write_set(s, pathlib.Path(t))
            drift = drift_test(load(pathlib.Path(t)))
        m = drift["plate_models"]
        row = {"set": f"{s['suite_seed']}/{s['index']}", "hidden": s["hidden"], "outside": s["outside"],
               "added": d["score"]["added"], "plate_right": "anisotropic_friction" in s["hidden"],
               "drift_p": drift["p"], "groups": m["groups"], "chi2_one_vector": m["chi2_one_vector"],
               "chi2_anisotropy": m["chi2_anisotropy"], "p_one_vector": m["p_one_vector"],
               "one_vector_fits_better": bool(m["applicable"] and not m["follows_the_robot"])}
        rows.append(row)
        print(f"{row['set']}: hidden {s['hidden']} outside {s['outside']} added {row['added']}: "
              f"{m['groups']} gaits drift, chi2 one vector {m['chi2_one_vector']:.1f}, one anisotropy "
              f"{m['chi2_anisotropy']:.1f}", flush=True)
    lost = [r["set"] for r in rows if r["plate_right"] and r["one_vector_fits_better"]]
    saved = [r["set"] for r in rows if not r["plate_right"] and r["one_vector_fits_better"]]
    out = {"pool": args.pool, "rows": rows,
           "summary": {"plates_added": len(rows), "right": sum(r["plate_right"] for r in rows),
                       "withheld_right": lost, "withheld_wrong": saved}}
    path = RESULTS / "plate_vs_vector.json"
    path.write_text(json.dumps(out, indent=1))
    print(f"{len(rows)} plates added ({out['summary']['right']} hidden); withheld where one vector fits better: "
          f"{len(lost)} right ({', '.join(lost)}), {len(saved)} wrong ({', '.join(saved)}) -> {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
