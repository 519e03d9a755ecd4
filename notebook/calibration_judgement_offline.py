"""Offline reading for the closed-loop issue's item 2 (a judgement beyond the robot's misfit): on every stored
nominal-stage hypothesis of the main-run stress seeds (benchmarks/results/calibration_stress/<seed>/), how
well do judgements computable from the stored numbers alone separate hidden effects from absent ones?
Development on seen sets only: nothing here is a rate on fresh data.

    python notebook/calibration_judgement_offline.py   # prints the table, writes calibration_judgement_offline.json
"""

from __future__ import annotations

import json
import math
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[1]
STRESS = ROOT / "benchmarks" / "results" / "calibration_stress"


def hypotheses() -> list[tuple[bool, dict]]:
    out = []
    for f in sorted(STRESS.glob("*/set_*.json")):
        if not re.fullmatch(r"\d{4}", f.parent.name):  # main-run seeds only (tagged runs are counterfactuals)
            continue
        row = json.loads(f.read_text())
        hidden = set(row["set"]["hidden"])
        for h in row.get("hypotheses") or []:
            if h.get("tried") and "beside" not in h and h.get("bic_gain") is not None and h.get("baseline_err_heldout"):
                out.append((h["effect"] in hidden, h))
    return out


def rates(hyps, pred) -> dict:
    tp = sum(1 for t, h in hyps if t and pred(h))
    fn = sum(1 for t, h in hyps if t and not pred(h))
    fp = sum(1 for t, h in hyps if not t and pred(h))
    tn = sum(1 for t, h in hyps if not t and not pred(h))
    return {"tp": tp, "fn": fn, "fp": fp, "tn": tn, "tpr": tp / (tp + fn) if tp + fn else math.nan,
            "fpr": fp / (fp + tn) if fp + tn else math.nan}


RULES = {
    "the stored decision (each set's own version)": lambda h: bool(h.get("accepted")),
    "present (interval clear of the null)": lambda h: bool(h.get("present")),
    **{f"present, held-out gain > {g:g}": (lambda h, g=g: h["present"] and h["heldout_gain"] > g) for g in (0.05, 0.1, 0.2)},
    # overdispersion: the training chi^2 gain divided by the baseline's error per point (the misfit as noise),
    # the quasi-likelihood form of the BIC gain (k ln n left out: small beside these gains)
    **{f"present, BIC gain / baseline error > {q:g}": (lambda h, q=q: h["present"] and
                                                      h["bic_gain"] / h["baseline_err_heldout"] > q)
       for q in (0, 10, 30, 100)},
}


def main() -> int:
    hyps = hypotheses()
    table = {name: rates(hyps, rule) for name, rule in RULES.items()}
    print(f"{len(hyps)} stored nominal-stage hypotheses ({sum(t for t, _ in hyps)} hidden)")
    for name, r in table.items():
        print(f"{name:<48} TPR {r['tpr']:.2f}  FPR {r['fpr']:.2f}  ({r['tp']}/{r['tp'] + r['fn']}, {r['fp']}/{r['fp'] + r['tn']})")
    (pathlib.Path(__file__).with_suffix(".json")).write_text(json.dumps({"hypotheses": len(hyps), "rules": table}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
