"""Why does the arm-plate joint fit end at its grid start? One stress set's nominal stage with the arm-plate
hypothesis on, then the training chi^2 (and the held-out error) along the arm-plate mu with the nominal values
the joint fit ended at, and the arm-plate mu values the fits asked the model for.

    python benchmarks/armplate_profile.py 2042 36     # ~5 min on 2 cores; results/armplate_profile_2042_36.json
"""
import argparse
import json
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from smarticle_mjx.calibrate.stress import draw_set, write_set  # noqa: E402
from smarticle_mjx.calibrate.data import load, priors  # noqa: E402
from smarticle_mjx.calibrate.effects import EffectSet  # noqa: E402
from smarticle_mjx.calibrate.fit import Problem, split  # noqa: E402
from smarticle_mjx.calibrate.stages import LIBRARY, Model, nominal_stage  # noqa: E402

PROFILE = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("suite_seed", type=int)
    ap.add_argument("index", type=int, help="the set's index in the seed (calibration_stress.py --draw-only lists them)")
    args = ap.parse_args()
    seed, idx = args.suite_seed, args.index
    s = draw_set(seed, idx)
    if "arm_plate_contact" not in s["hidden"]:
        ap.error(f"set {seed}/{idx} hides no arms on the plate (it hides {s['hidden'] or 'nothing'})")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_set(s, tmp)
        trials = load(tmp)
    train_t, test_t = split(trials)
    train, test = Problem(train_t), Problem(test_t)
    train.priors = priors(trials)
    asked = []
    plain = train.vector_with

    def recording(nom, eff=None):
        d = eff.as_dict() if eff is not None else {}
        if "arm_plate_contact" in d:
            asked.append((d["arm_plate_contact"]["arm_plate_mu"], nom.get("plate_friction")))
        return plain(nom, eff)

    train.vector_with = recording
    model = Model()
    nominal_stage(train, test, trials, LIBRARY, model, lambda m: print(f"[{time.perf_counter() - t0:4.0f} s] {m}",
                                                                       flush=True),
                  ("anisotropic_friction", "arm_plate_contact"))
    out = {"suite_seed": seed, "index": idx, "truth": s["truth"], "asked_mu_plate_mu": asked}
    if "arm_plate_contact" in model.base:
        nom = dict(train.nominal)  # test.nominal is the same: the accepted joint fit's (nominal_stage)
        fitted = model.base["arm_plate_contact"]["arm_plate_mu"]
        rows = []
        for mu in (fitted,) + PROFILE:
            eff = EffectSet.of({"arm_plate_contact": {"arm_plate_mu": float(mu)}})
            v = plain(nom, eff)
            rows.append({"arm_plate_mu": float(mu), "chi2_train": float(v @ v),
                         "err_heldout": test.error(eff)})
            print(f"mu {mu:.5f}: training chi2 {rows[-1]['chi2_train']:.0f}, held-out {rows[-1]['err_heldout']:.2f}",
                  flush=True)
        out.update(fitted=fitted, nominal=nom, profile=rows)
    path = pathlib.Path(__file__).parent / "results" / f"armplate_profile_{seed}_{idx}.json"
    path.write_text(json.dumps(out, indent=1, default=float) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
