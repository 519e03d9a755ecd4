"""Visible anisotropic plates the calibration missed: the plate's free joint fit started at the truth.

A reading beside benchmarks/plate_at_truth.py (December 2026, version 0.4.18): on the calibration's split,
the nominal parameters and the plate's ratio fitted together from the nominal fit with the ratio started at
its true value; where the ratio ends, the training and held-out errors, and the held-out gain over the
nominal fit alone (the calibration names the plate at 20 %).

    python benchmarks/plate_free_from_truth.py 2148/14 2148/4 > results/plate_at_truth/free_from_truth.jsonl
"""
import json, pathlib, sys, tempfile, time  # noqa: E401
sys.path.insert(0, str(pathlib.Path(__file__).parent))
import calibration_stress as CS
from smarticle_mjx.calibrate.data import load, priors
from smarticle_mjx.calibrate.fit import split, Problem
from smarticle_mjx.calibrate.nominal import fit_nominal
from smarticle_mjx.calibrate.effects import EffectSet, BY_NAME

def flat(v): return {k: x for k, x in v.items() if not isinstance(x, dict)}
for spec in sys.argv[1:]:
    s = CS.stored_set(spec, hides='anisotropic_friction')['set']
    true = s['truth']['anisotropic_friction']['friction_y_ratio']
    t0 = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        CS.write_set(s, tmp); trials = load(tmp, None, ())
    a, b = split(trials)
    train, test = Problem(a), Problem(b)
    train.priors = priors(trials)
    n0 = fit_nominal(train)
    e = BY_NAME['anisotropic_friction']
    nf = fit_nominal(train, effect=e, start=flat(n0.values), effect_start={'friction_y_ratio': true})
    r = nf.values['anisotropic_friction']['friction_y_ratio']
    test.nominal = flat(nf.values)
    ef = test.error(EffectSet.of({'anisotropic_friction': {'friction_y_ratio': r}}))
    test.nominal = flat(n0.values)
    e0 = test.error(EffectSet())
    print(json.dumps({'set': spec, 'true': true, 'free_from_truth_ratio': r, 'train_err_free': nf.err_after,
                      'train_err_nominal': n0.err_after, 'heldout_free': ef, 'heldout_nominal': e0,
                      'gain': 1 - ef / e0, 'wall': time.time() - t0}), flush=True)
