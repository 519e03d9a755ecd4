"""Calibration on synthetic data with hidden effects: is the right effect named,
is the truth inside the interval, how much does the held-out error fall, and
how often is an effect added to clean data.

    python benchmarks/calibration.py                 # every case, 3 clean seeds (~10 min on 2 cores)
    python benchmarks/calibration.py --cases servo_response clean

Writes benchmarks/results/calibration.json and prints a table.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import tempfile
import time

from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.fit import calibrate
from smarticle_mjx.calibrate.synth import CASES, case_truth, make_case


def run_case(name: str, seed: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        make_case(name, tmp, seed=seed)
        trials = load(tmp)
        t = time.perf_counter()
        res = calibrate(trials)
        wall = time.perf_counter() - t
    truth = case_truth(name)
    added = [a["effect"] for a in res["added"]]
    inside = {}
    for a in res["added"]:
        for k, v in truth.get(a["effect"], {}).items():
            lo, hi = a["interval"][k]
            inside[f"{a['effect']}.{k}"] = bool(lo <= v <= hi)
    b, f = res["before"]["err_heldout"], res["after"]["err_heldout"]
    return {"case": name, "seed": seed, "verdict": res["verdict"], "added": added,
            "fitted": {a["effect"]: a["values"] for a in res["added"]},
            "intervals": {a["effect"]: a["interval"] for a in res["added"]}, "truth": truth,
            "named_first": (added[:1] == list(truth)[:1]) if truth else (not added),
            "truth_inside": inside, "heldout_before": b, "heldout_after": f, "heldout_drop": 1 - f / b,
            "wall_s": wall, "model_runs": res["model_runs"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=list(CASES))
    ap.add_argument("--clean-seeds", type=int, default=3)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "calibration.json"))
    args = ap.parse_args()
    rows = []
    for name in args.cases:
        for seed in (range(1, 1 + args.clean_seeds) if name == "clean" else [1]):
            r = run_case(name, seed)
            rows.append(r)
            print(f"{name:22s} seed {seed}: {r['verdict']:45s} added {r['added']} fitted {r['fitted']} "
                  f"truth inside {r['truth_inside']} held-out {r['heldout_before']:.2f} -> {r['heldout_after']:.2f} "
                  f"({r['heldout_drop']:+.0%}) {r['wall_s']:.0f} s", flush=True)
    clean = [r for r in rows if r["case"] == "clean"]
    summary = {"false_positive_rate": (sum(bool(r["added"]) for r in clean) / len(clean)) if clean else None,
               "clean_runs": len(clean)}
    pathlib.Path(args.out).write_text(json.dumps({"rows": rows, "summary": summary}, indent=1, default=float))
    print(summary)
    print(markdown(rows))


def markdown(rows) -> str:
    """The table quoted in docs/calibration.md."""
    out = ["| case | hidden (true) | verdict | fitted [95 % interval] | truth inside | held-out error before → after |",
           "|---|---|---|---|---|---|"]
    for r in rows:
        truth = "; ".join(f"{k} = {v:g}" for e in r["truth"].values() for k, v in e.items()) or "none"
        fit = "; ".join(f"{k} = {v:.3g} [{r['intervals'][e][k][0]:.3g}, {r['intervals'][e][k][1]:.3g}]"
                        for e, vals in r["fitted"].items() for k, v in vals.items()) or "–"
        inside = "yes" if r["truth_inside"] and all(r["truth_inside"].values()) else (
            "–" if not r["truth_inside"] else "no")
        out.append(f"| {r['case']} (seed {r['seed']}) | {truth} | {r['verdict']} | {fit} | {inside} | "
                   f"{r['heldout_before']:.3g} → {r['heldout_after']:.3g} ({r['heldout_drop']:+.0%}) |")
    return "\n".join(out)


if __name__ == "__main__":
    main()
