"""Does a tilt's size follow the robots' slides? A check of the correction the calibration does not make.

A tilt pulls a robot along its slope; a robot whose contacts slide held by Coulomb friction drifts by about
tan(tilt) / mu times the path its contacts slide (docs/calibration.md, "A tilt's size and the model robot's
mismatch"). The calibration sizes a tilt by the model robot's drift per degree, so if that law held for the
measured robot and the model robot alike, the fitted tilt would be off the truth by the ratio of their
slides over their frictions, and dividing by the measured/model slide ratio (``calibrate.drift.slide``,
which the tilt's mismatch term already reads) would correct it: the correction issue #44 suggests.

For each stored stress-suite set given (benchmarks/calibration_stress.py, data written as the suite writes
them), this script

  * calibrates the set again as ``smx calibrate`` does and reads the tilt stage's fit: the tilt (before the
    library's bound), and per gait the measured and the model robot's slide per cycle (the model with its
    fitted nominal parameters, the one that sized the tilt), and the fitted plate friction;
  * fits the tilt once more with the preset model (no nominal fit), with its slides;
  * and reports, against the truth, the size as fitted, divided by the slide ratio, and divided by the
    slide ratio times the model's over the generator's plate friction (the whole law, with the friction the
    suite knows and a user would not).

It corrects nothing and changes no rule: it describes whether the law holds. It was written after stored
sets of seeds 2140-2148 had been read with a scratch version of the same computation.

    python benchmarks/tilt_slide_law.py 2140/21 2143/22 2144/9          # seed/index of stored sets
    python benchmarks/tilt_slide_law.py --tilt-sets 2140-2148            # every stored one-robot tilt set

Writes results/tilt_slide_law.json (set by set, resumable) and prints a table.
"""

from __future__ import annotations

import pathlib

import argparse
import json
import math
import tempfile
import time

import numpy as np

from smarticle_mjx.calibrate.stress import indices as _indices, stored_set as _stored_set, write_set
from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.drift import fit_tilt
from smarticle_mjx.calibrate.effects import EffectSet
from smarticle_mjx.calibrate.sim import simulate_trials
from smarticle_mjx.calibrate.stages import calibrate

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results


def stored_set(spec: str, hides: str | None = None) -> dict:
    return _stored_set(spec, RESULTS, hides)

OUT = RESULTS / "tilt_slide_law.json"


def _slide_ratio(per_group: list[dict]) -> float | None:
    """Geometric mean over the gaits of the measured robots' slide over the model's."""
    logs = [math.log(a / b) for a, b in (g["slide_mm"] for g in per_group if "slide_mm" in g) if a > 0 and b > 0]
    return math.exp(float(np.mean(logs))) if logs else None


def measure(s: dict) -> dict:
    """The readings of one stored set (its ``set`` entry, which hides a tilt)."""
    tr = s["truth"]["plate_tilt"]
    true = math.hypot(tr["tilt_x_deg"], tr["tilt_y_deg"])
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_set(s, tmp)
        trials = load(tmp, None, ())
    res = calibrate(trials).summary
    row = {"set": key_of(s), "hidden": s["hidden"], "amplitudes": s["amplitudes"],
           "frame_rate_hz": s["frame_rate_hz"], "true_deg": true, "mu_generator": s["build"]["friction"]}
    fit = (res.get("drift") or {}).get("tilt_fit") or {}
    if fit.get("ok"):
        groups = fit["discrepancy"]["per_group"]
        mu_model = (res["nominal"] or {}).get("values", {}).get("plate_friction")
        ratio = math.hypot(*fit["tilt_deg_unbounded"]) / true
        sr = _slide_ratio(groups)
        row["nominal"] = {"size_ratio": ratio, "slides_mm": [g.get("slide_mm") for g in groups],
                          "slide_ratio": sr, "mu_model": mu_model,
                          "slide_corrected": ratio / sr if sr else None,
                          "law_corrected": (ratio / (sr * mu_model / row["mu_generator"])
                                            if sr and mu_model else None)}

    def preset(tx, ty):
        eff = EffectSet.of({"plate_tilt": {"tilt_x_deg": tx, "tilt_y_deg": ty}})
        return simulate_trials(trials, scene_for=lambda t: eff.scene(t.params))

    pre = fit_tilt(trials, preset)
    if pre.get("ok"):
        groups = pre["discrepancy"]["per_group"]
        ratio = math.hypot(*pre["tilt_deg_unbounded"]) / true
        sr = _slide_ratio(groups)
        row["preset"] = {"size_ratio": ratio, "slides_mm": [g.get("slide_mm") for g in groups], "slide_ratio": sr,
                         "slide_corrected": ratio / sr if sr else None}
    row["wall_s"] = time.perf_counter() - t0
    return row


def key_of(s: dict) -> str:
    return f"{s['suite_seed']}/{s['index']}"


def tilt_sets(seeds: list[int]) -> list[dict]:
    """Stored one-robot sets of these seeds that hide a tilt (their ``set`` entries)."""
    out = []
    for seed in seeds:
        for f in sorted((RESULTS / "calibration_stress" / str(seed)).glob("set_*.json")):
            s = json.loads(f.read_text())["set"]
            if "plate_tilt" in s["hidden"] and s["robots"] == 1:
                out.append(s)
    return out


def _fmt(x: float | None) -> str:
    return "–" if x is None else f"{x:.2f}"


def table(rows: list[dict]) -> str:
    lines = ["| set | hidden | gaits | model | size / truth | measured / model slide | slide-corrected | "
             "with the friction too |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        for which in ("nominal", "preset"):
            m = r.get(which)
            if not m:
                continue
            lines.append(f"| {r['set']} | {' + '.join(r['hidden'])} | {', '.join(map(str, r['amplitudes']))}° | "
                         f"{which} | {_fmt(m['size_ratio'])} | {_fmt(m['slide_ratio'])} | "
                         f"{_fmt(m['slide_corrected'])} | {_fmt(m.get('law_corrected'))} |")
    within = {}
    for which, key in (("nominal", "size_ratio"), ("nominal", "slide_corrected"), ("nominal", "law_corrected")):
        xs = [r[which][key] for r in rows if r.get(which) and r[which].get(key)]
        within[f"{which} {key}"] = f"{sum(1 / 1.5 <= x <= 1.5 for x in xs)} of {len(xs)} within 1.5x"
    return "\n".join(lines) + "\n" + json.dumps(within, indent=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sets", nargs="*", help="seed/index of stored stress sets")
    ap.add_argument("--tilt-sets", default=None, help="every stored one-robot tilt set of these seeds (2140-2148)")
    a = ap.parse_args()
    sets = [stored_set(x, hides="plate_tilt")["set"] for x in a.sets]
    if a.tilt_sets:
        sets += tilt_sets(_indices(a.tilt_sets))
    store = json.loads(OUT.read_text()) if OUT.exists() else {}
    for s in sets:
        key = key_of(s)
        if key not in store:
            store[key] = measure(s)
            OUT.write_text(json.dumps(store, indent=1))
            print(f"{key}: {json.dumps({k: store[key].get(k) for k in ('nominal', 'preset')})[:300]}", flush=True)
    print(table([store[key_of(s)] for s in sets]))


if __name__ == "__main__":
    main()
