"""The arm rise (calibrate.observables.swing_rise_groups) on development sets of the stress suite: does its
excess over the preset model tell a servo lag from a dead time on robots built by the independent simulator,
whose own servo laws shape a swing too?

Development only: the sets come from suite seeds already run and read (2040-2044), chosen by what they hide
alone (arms tracked; a servo lag, a dead time, or nothing at all), before this script looked at any of them;
no rule of the selection reads the rise. Per set and gait: the rise's and the arm delay's excess over the
preset model (ms, with standard errors).

    python benchmarks/arm_rise_dev.py            # writes results/arm_rise_dev.json (~10 minutes on 2 cores)
"""

from __future__ import annotations

import json
import math
import pathlib
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
from smarticle_mjx.calibrate import stress as CS  # noqa: E402

from smarticle_mjx import __version__  # noqa: E402
from smarticle_mjx.calibrate import observables as OB  # noqa: E402
from smarticle_mjx.calibrate.data import load  # noqa: E402
from smarticle_mjx.calibrate.effects import EffectSet  # noqa: E402
from smarticle_mjx.calibrate.fit import Problem, split, stage_tracks  # noqa: E402

SEEDS = (2040, 2041, 2042, 2043, 2044)
PER_CLASS = 6  # sets of each class, in seed and index order


def kind(s: dict) -> str | None:
    """The set's class: 'lag', 'dead time' (either alone, no outside effect) or 'clean'; None otherwise."""
    if not s["arms_tracked"] or s["outside"]:
        return None
    if not s["hidden"]:
        return "clean"
    if s["hidden"] == ["servo_lag"]:
        return "lag"
    if s["hidden"] == ["servo_dead_time"]:
        return "dead time"
    return None


def chosen() -> list[tuple[int, int, str]]:
    return CS.choose_sets(SEEDS, kind, PER_CLASS)


def excess(data: list, model: list) -> list[dict]:
    rows = []
    for r in data:
        m = next((x for x in model if x["gait"] == r["gait"]), None)
        if m is None:
            continue
        se = math.hypot(r["se"] if math.isfinite(r["se"]) else 0.0, m["se"] if math.isfinite(m["se"]) else 0.0)
        rows.append({"amplitude_deg": r["amplitude_deg"], "excess_ms": r["mean"] - m["mean"], "se_ms": se,
                     "measured_ms": r["mean"], "preset_ms": m["mean"]})
    return sorted(rows, key=lambda x: x["amplitude_deg"])


def one(seed: int, index: int, k: str) -> dict:
    s = CS.draw_set(seed, index)
    with tempfile.TemporaryDirectory() as tmp:
        CS.write_set(s, tmp)
        trials = load(tmp)
    train_t, test_t = split(trials)
    train, test = Problem(train_t), Problem(test_t)  # the preset model (no nominal values, no priors)
    data = OB.observables(trials)
    model = OB.observables(trials, stage_tracks(train, test, trials, {}, EffectSet()))
    return {"suite_seed": seed, "index": index, "class": k, "truth": s["truth"], "build_servo_ff": s["build"]["servo_ff"],
            "build_servo_slew": s["build"]["servo_slew"] is not None,
            "rise": excess(data["arm_rise_ms"], model["arm_rise_ms"]),
            "delay": excess(data["arm_delay_ms"], model["arm_delay_ms"])}


def main():
    rows = []
    for seed, index, k in chosen():
        r = one(seed, index, k)
        rows.append(r)
        size = next(iter(next(iter(r["truth"].values())).values())) * 1e3 if r["truth"] else 0.0
        print(f"{seed}/{index} {k} {size:.0f} ms: "
              + "; ".join(f"{x['amplitude_deg']:g} deg rise {x['excess_ms']:+.1f} +- {x['se_ms']:.1f}"
                          for x in r["rise"])
              + " | delay " + ", ".join(f"{x['excess_ms']:+.1f}" for x in r["delay"]), flush=True)
    out = {"package": __version__, "seeds": SEEDS, "sets": rows}
    (ROOT / "results" / "arm_rise_dev.json").write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
