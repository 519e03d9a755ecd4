"""Visible anisotropic plates the calibration missed: would the library's robot, on the TRUE plate, gain held out?

A reading, not a rule (December 2026, version 0.4.18; docs/calibration.md, "Anisotropic plates the data
show and the calibration missed"). For each stored stress set given (seed/index; it must hide an
anisotropic plate), on the calibration's own split (even trials train, odd held out) and on the swapped
split: the nominal parameters fitted alone; the held-out error of that fit, of that fit with the true plate
added, and of the nominal parameters fitted again with the plate held at its true ratio.

    python benchmarks/plate_at_truth.py 2148/14 2148/4 2142/19 2149/22 > results/plate_at_truth/at_truth.jsonl
"""
import json, pathlib, sys, tempfile, time  # noqa: E401
sys.path.insert(0, str(pathlib.Path(__file__).parent))
import calibration_stress as CS
from smarticle_mjx.calibrate.data import load, priors
from smarticle_mjx.calibrate.fit import split, Problem
from smarticle_mjx.calibrate.nominal import fit_nominal
from smarticle_mjx.calibrate.effects import EffectSet, BY_NAME

for spec in sys.argv[1:]:
    s = CS.stored_set(spec, hides='anisotropic_friction')['set']
    true = s['truth']['anisotropic_friction']['friction_y_ratio']
    t0 = time.time()
    with tempfile.TemporaryDirectory() as tmp:
        CS.write_set(s, tmp); trials = load(tmp, None, ())
    out = {'set': spec, 'true': true, 'hidden': s['hidden'], 'amps': s['amplitudes']}
    for name, (a, b) in {'even->odd': split(trials), 'odd->even': split(trials)[::-1]}.items():
        train, test = Problem(a), Problem(b)
        train.priors = priors(trials)
        plate = EffectSet.of({'anisotropic_friction': {'friction_y_ratio': true}})
        n0 = fit_nominal(train)
        test.nominal = {k: v for k, v in n0.values.items() if not isinstance(v, dict)}
        e0, e0p = test.error(EffectSet()), test.error(plate)
        train.effect_fixed = {'friction_y_ratio': (true, (true, true))}
        nt = fit_nominal(train, effect=BY_NAME['anisotropic_friction'], start={k: v for k, v in n0.values.items() if not isinstance(v, dict)})
        test.nominal = {k: v for k, v in nt.values.items() if not isinstance(v, dict)}
        et = test.error(plate)
        out[name] = {'nominal_only': e0, 'nominal_only_plus_true_plate': e0p, 'refit_with_true_plate': et,
                     'train_err_nominal': n0.err_after, 'train_err_true_plate': nt.err_after,
                     'mu': [n0.values.get('plate_friction'), nt.values.get('plate_friction')]}
    out['wall'] = time.time() - t0
    print(json.dumps(out), flush=True)
