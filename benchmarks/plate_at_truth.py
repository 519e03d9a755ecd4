"""Visible anisotropic plates the calibration missed: would the library's robot, on the TRUE plate, gain held out?

A reading, not a rule (December 2026, version 0.4.18; docs/calibration.md, "Anisotropic plates the data
show and the calibration missed"). For each stored stress set given (seed/index; it must hide an
anisotropic plate):

  * by default, on the calibration's own split (even trials train, odd held out) and on the swapped split:
    the nominal parameters fitted alone; the held-out error of that fit, of that fit with the true plate
    added, and of the nominal parameters fitted again with the plate held at its true ratio;
  * ``--free``: on the calibration's split, the nominal parameters and the plate's ratio fitted together
    from the nominal fit with the ratio started at its true value: where the ratio ends, the training and
    held-out errors, and the held-out gain over the nominal fit alone (the calibration names the plate at
    20 %).

One JSON line per set on standard output:

    python benchmarks/plate_at_truth.py 2148/14 2148/4 2142/19 2149/22 > results/plate_at_truth/at_truth.jsonl
    python benchmarks/plate_at_truth.py --free 2148/14 2148/4 > results/plate_at_truth/free_from_truth.jsonl
"""

from __future__ import annotations

import pathlib

import argparse
import json
import tempfile
import time

from smarticle_mjx.calibrate.stress import stored_set as _stored_set, write_set
from smarticle_mjx.calibrate.data import load, priors
from smarticle_mjx.calibrate.effects import BY_NAME, EffectSet
from smarticle_mjx.calibrate.fit import Problem, split
from smarticle_mjx.calibrate.nominal import fit_nominal

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results


def stored_set(spec: str, hides: str | None = None) -> dict:
    return _stored_set(spec, RESULTS, hides)

PLATE = "anisotropic_friction"


def _flat(values: dict) -> dict:
    """The nominal parameters of a fit's values (an effect fitted beside them sits under its name)."""
    return {k: v for k, v in values.items() if not isinstance(v, dict)}


def _problems(trials, train_t, test_t) -> tuple[Problem, Problem]:
    train, test = Problem(train_t), Problem(test_t)
    train.priors = priors(trials)
    return train, test


def at_truth(trials, true: float) -> dict:
    out = {}
    for name, (a, b) in {"even->odd": split(trials), "odd->even": split(trials)[::-1]}.items():
        train, test = _problems(trials, a, b)
        plate = EffectSet.of({PLATE: {"friction_y_ratio": true}})
        n0 = fit_nominal(train)
        test.nominal = _flat(n0.values)
        e0, e0p = test.error(EffectSet()), test.error(plate)
        train.effect_fixed = {"friction_y_ratio": (true, (true, true))}
        nt = fit_nominal(train, effect=BY_NAME[PLATE], start=_flat(n0.values))
        test.nominal = _flat(nt.values)
        out[name] = {"nominal_only": e0, "nominal_only_plus_true_plate": e0p,
                     "refit_with_true_plate": test.error(plate),
                     "train_err_nominal": n0.err_after, "train_err_true_plate": nt.err_after,
                     "mu": [n0.values.get("plate_friction"), nt.values.get("plate_friction")]}
    return out


def free_from_truth(trials, true: float) -> dict:
    train, test = _problems(trials, *split(trials))
    n0 = fit_nominal(train)
    nf = fit_nominal(train, effect=BY_NAME[PLATE], start=_flat(n0.values), effect_start={"friction_y_ratio": true})
    r = nf.values[PLATE]["friction_y_ratio"]
    test.nominal = _flat(nf.values)
    ef = test.error(EffectSet.of({PLATE: {"friction_y_ratio": r}}))
    test.nominal = _flat(n0.values)
    e0 = test.error(EffectSet())
    return {"free_from_truth_ratio": r, "train_err_free": nf.err_after, "train_err_nominal": n0.err_after,
            "heldout_free": ef, "heldout_nominal": e0, "gain": 1 - ef / e0}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sets", nargs="+", help="seed/index of stored stress sets that hide an anisotropic plate")
    ap.add_argument("--free", action="store_true", help="the ratio fitted freely from its true value")
    a = ap.parse_args()
    sets = [(spec, stored_set(spec, hides=PLATE)["set"]) for spec in a.sets]  # every spec checked first
    for spec, s in sets:
        true = s["truth"][PLATE]["friction_y_ratio"]
        t0 = time.time()
        with tempfile.TemporaryDirectory() as tmp:
            write_set(s, tmp)
            trials = load(tmp, None, ())
        head = {"set": spec, "true": true}
        if a.free:
            row = {**head, **free_from_truth(trials, true)}
        else:
            row = {**head, "hidden": s["hidden"], "amps": s["amplitudes"], **at_truth(trials, true)}
        print(json.dumps({**row, "wall": time.time() - t0}), flush=True)


if __name__ == "__main__":
    main()
