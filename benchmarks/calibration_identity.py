"""Identity check of a calibration refactor: stored stress-suite sets calibrated again with today's code must give
the stored hypotheses, values, intervals and scores bit for bit (timings and the package version aside).

Each set is drawn and written again from its seed and index (calibrate.stress), calibrated as the stress suite
calibrates it (calibration_stress.run_set, with its clean twin) and compared key by key with its stored row
(results/calibration_stress/<seed>/set_<index>.json) after a JSON round trip, so floats compare exactly as
stored (a NaN equals a NaN: a test that did not apply stores NaN). Prints one line per set and writes results/calibration_identity.json; exit 1 if any set differs.

    python benchmarks/calibration_identity.py --sets 2148/23,2148/29,2149/27
"""

from __future__ import annotations

import pathlib

import argparse
import json
import math
import sys
import time

from smarticle_mjx.calibrate.stress import parse_set, run_set as _run_set
from smarticle_mjx.bench import save_json
from smarticle_mjx.calibrate.stress import draw_set

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results


def run_set(s: dict) -> dict:
    return _run_set(s, say=lambda m: print(m, flush=True))

IGNORED = ("wall_s", "total_s", "version")  # timings, and the package version a refactor may bump


def compare(stored: dict, again: dict) -> list[str]:
    """The keys (nested, dotted) whose values differ between a stored row and the same set run again."""
    def walk(a, b, path):
        if isinstance(a, dict) and isinstance(b, dict):
            out = []
            for k in sorted(set(a) | set(b)):
                if not path and k in IGNORED:
                    continue
                if not path and k not in a and b.get(k) is None:
                    continue  # a field rows store since after the stored one ran, empty here
                out += walk(a.get(k, "<missing>"), b.get(k, "<missing>"), f"{path}.{k}" if path else k)
            return out
        if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
            return [d for i, (x, y) in enumerate(zip(a, b)) for d in walk(x, y, f"{path}[{i}]")]
        same = a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))
        return [] if same else [path]
    return walk(stored, json.loads(json.dumps(again)), "")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", required=True, help="comma-separated SEED/INDEX, e.g. 2148/23,2149/27")
    ap.add_argument("--out", default=str(RESULTS / "calibration_identity.json"))
    args = ap.parse_args(argv)
    try:
        specs = [parse_set(x.strip()) for x in args.sets.split(",") if x.strip()]
    except argparse.ArgumentTypeError as e:
        ap.error(str(e))
    rows = []
    for seed, index in specs:
        path = RESULTS / "calibration_stress" / str(seed) / f"set_{index:04d}.json"
        if not path.exists():
            ap.error(f"no stored stress set {seed}/{index}")
    for seed, index in specs:
        stored = json.loads((RESULTS / "calibration_stress" / str(seed) / f"set_{index:04d}.json").read_text())
        s = draw_set(seed, index)
        if json.loads(json.dumps(s)) != stored["set"]:
            rows.append({"set": f"{seed}/{index}", "identical": False, "differ": ["set (the draw)"]})
            print(f"{seed}/{index}: the draw differs from the stored set", flush=True)
            continue
        t0 = time.perf_counter()
        again = run_set(s)
        diff = compare(stored, again)
        rows.append({"set": f"{seed}/{index}", "identical": not diff, "differ": diff[:20],
                     "added": again["score"]["added"], "stored_version": stored["version"],
                     "wall_s": time.perf_counter() - t0})
        print(f"{seed}/{index}: {'identical' if not diff else 'DIFFERS in ' + ', '.join(diff[:5])} "
              f"(added {again['score']['added']}; {time.perf_counter() - t0:.0f} s)", flush=True)
        save_json(args.out, {"sets": rows, "ignored": list(IGNORED)})
    same = sum(r["identical"] for r in rows)
    print(f"{same} of {len(rows)} sets identical")
    return 0 if same == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
