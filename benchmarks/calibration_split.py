"""Does what ``smx calibrate`` names depend on which half of the trials it holds out?

A reading, not a rule (December 2026, version 0.4.18; docs/calibration.md, "Which half is held out"). The
calibration trains on the first, third, ... trials and judges every structural hypothesis by its gain on
the others. The stress suite's sets have two trials per amplitude, so each gait is trained on one start
heading and judged on the other. This script compares, set by set, a seed's stored results
(results/calibration_stress/<seed>/) with the same sets calibrated on the swapped split
(``calibration_stress.py --swapped-split --tag swapped-split``, stored under <seed>-swapped-split/):

  * whether the effects added are the same, and whether each split is right (the suite's score);
  * for every joint hypothesis tried on both splits, its held-out gain on each and on their mean, the
    reading a two-fold judgement would make (the calibration asks 20 % of an effect).

    python benchmarks/calibration_stress.py --suite-seed 2149 --sets 0-29 --swapped-split --tag swapped-split
    python benchmarks/calibration_split.py --suite-seed 2149

Prints the tables and writes results/calibration_split_<seed>.json.
"""

from __future__ import annotations

import pathlib

import argparse
import json


from smarticle_mjx.calibrate.stress import SPLIT_BAR as BAR  # noqa: F401  (the comparison lives in the package)
from smarticle_mjx.calibrate.stress import set_kind as kind  # noqa: F401
from smarticle_mjx.calibrate.stress import split_compare as compare, split_summary as summary, stored_rows as stored  # noqa: F401
from smarticle_mjx.calibrate.stress import tried_gains as tried  # noqa: F401

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results

def tables(s: dict) -> str:
    out = ["| sets | compared | same effects added | right: rule's split | right: swapped | right: both |",
           "|---|---|---|---|---|---|"]
    for k, c in s["by_kind"].items():
        out.append(f"| {k} | {c['sets']} | {c['same_added']} | {c['right_rule']} | {c['right_swapped']} | "
                   f"{c['right_both']} |")
    out += ["", f"| joint hypothesis (first pass, tried on both splits) | hidden? | tried | gain ≥ {s['bar']:.0%}: "
                "rule's split | swapped | mean of both |", "|---|---|---|---|---|---|"]
    for e, h in s["gain_at_bar"].items():
        for w, c in h.items():
            if c["tried"]:
                out.append(f"| {e} | {w} | {c['tried']} | {c['rule']} | {c['swapped']} | {c['mean']} |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite-seed", type=int, required=True)
    ap.add_argument("--tag", default="swapped-split", help="the swapped split's tag (default swapped-split)")
    args = ap.parse_args()
    base = RESULTS / "calibration_stress"
    rule, swapped = stored(base / str(args.suite_seed)), stored(base / f"{args.suite_seed}-{args.tag}")
    lines = compare(rule, swapped)
    if not lines:
        raise SystemExit(f"no set of seed {args.suite_seed} is stored both as scored and under --tag {args.tag}")
    s = summary(lines)
    print(tables(s))
    for x in lines:
        if not x["same_added"]:
            print(f"{args.suite_seed}/{x['index']}: hidden {x['hidden']} outside {x['outside']}: rule's split "
                  f"{x['added_rule']} ({'right' if x['right_rule'] else 'wrong'}), swapped {x['added_swapped']} "
                  f"({'right' if x['right_swapped'] else 'wrong'})")
    out = RESULTS / f"calibration_split_{args.suite_seed}.json"
    out.write_text(json.dumps({"suite_seed": args.suite_seed, "tag": args.tag, "summary": s, "sets": lines},
                              indent=1))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
