"""The delay test (calibrate.observables.delay_test) on stress-suite sets that hide a servo lag or dead
time beside an arm read with a constant error, with the arm delay grouped by arm and direction (since
November 2026, after version 0.4.0) and with the plain average over all swings it replaced.

The sets are drawn by the stress suite's generator on suite seeds nobody had run, chosen by what they
hide alone (an arm misreading and a servo effect, arms tracked), before any was calibrated:

    python benchmarks/delay_test_arm_bias.py          # writes results/delay_test_arm_bias.json

Per set: the delay test's constant (ms, with its standard error) against the preset model, and its
decision (a constant delay / none / undecided), both ways. The plain way is the grouped estimator with
every swing in one group, which is what the code before the change computed.
"""

from __future__ import annotations

import json
import pathlib
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
from smarticle_mjx.calibrate import stress as CS  # noqa: E402

from smarticle_mjx import __version__  # noqa: E402
from smarticle_mjx.calibrate import observables as OB  # noqa: E402
from smarticle_mjx.calibrate.data import load  # noqa: E402
from smarticle_mjx.calibrate.effects import EffectSet  # noqa: E402
from smarticle_mjx.calibrate.fit import Problem, split, stage_tracks  # noqa: E402

# (suite seed, set index): every set of seeds 2032-2039 (indices 0-59) that hides a servo lag or dead time
# beside an arm misread by a constant, found with --draw-only
SETS = ((2032, 7), (2034, 24), (2035, 14), (2035, 22), (2036, 17), (2037, 12), (2037, 39), (2038, 42))


def decision(t: OB.DelayTest) -> str:
    if not t.applicable:
        return "not applicable"
    return "constant delay" if t.constant_delay else "no constant delay" if t.no_constant_delay else "undecided"


def one(seed: int, index: int) -> dict:
    s = CS.draw_set(seed, index)
    with tempfile.TemporaryDirectory() as tmp:
        CS.write_set(s, tmp)
        trials = load(tmp)
    train_t, test_t = split(trials)
    train, test = Problem(train_t), Problem(test_t)  # the preset model's tracks (no nominal values, no priors)
    model = OB.observables(trials, stage_tracks(train, test, trials, {}, EffectSet()))
    out = {"suite_seed": seed, "index": index, "hidden": s["hidden"], "truth": s["truth"],
           "arm_bias_deg": s["generator"].get("arm2_bias_deg"), "amplitudes": s["amplitudes"]}
    grouped = OB.grouped_mean_se
    for way in ("grouped", "plain"):
        if way == "plain":  # every swing in one group: the plain mean and standard error
            OB.grouped_mean_se = lambda x, groups: grouped(x, np.zeros(len(np.asarray(x)), int))
        try:
            t = OB.delay_test(OB.observables(trials), model)
        finally:
            OB.grouped_mean_se = grouped
        out[way] = {"constant_ms": t.constant_ms, "constant_se_ms": t.constant_se_ms, "decision": decision(t),
                    "se_ms": list(t.se_ms)}
    return out


def main():
    rows = []
    for seed, index in SETS:
        r = one(seed, index)
        rows.append(r)
        print(f"{seed}/{index} {r['hidden']} bias {r['arm_bias_deg']:+.1f} deg: "
              f"grouped {r['grouped']['constant_ms']:.1f} +- {r['grouped']['constant_se_ms']:.1f} ms "
              f"({r['grouped']['decision']}), plain {r['plain']['constant_ms']:.1f} +- "
              f"{r['plain']['constant_se_ms']:.1f} ms ({r['plain']['decision']})", flush=True)
    out = {"package": __version__, "sets": rows}
    (ROOT / "results" / "delay_test_arm_bias.json").write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
