"""Collect the glider-quantity checks of time steps into the package's table
(smarticle_mjx/reduce/step_checks.json), which `smx report` reads to say whether a store's step has
been checked and, if it has not passed, how it biases β and glider speed.

Sources: results/glider_step.json (steps against the 0.0625 ms reference, model lab-lag, ideal robots),
results/step_mechanism.json (integrators and steps against the same reference, same starts) and
results/step_mechanism_substeps.json and step_mechanism_substeps_discrete.json (near-contact sub-stepping
with implicitfast and with discrete, against the same reference, same starts),
results/step_mechanism_discrete_against-default.json (discrete at 0.0625-0.25 ms and discrete and Euler with
near-contact sub-stepping, against the same reference, same starts),
results/step_mechanism_lab_runs30.json (the same with the `lab` imperfection set, against its own
reference; a glider there is a start's longest bound run of >= 30 periods, because the drawn robots'
drifting clocks leave no pair bound from period 10 to 100 at any step, so the steady rule of the other
sources measures nothing), and results/step_mechanism_lab_runs30_cg.json (its 0.25 ms row and reference again
with the "auto" solver, which solves the `lab` robots' gear play with CG since November 2026; it comes before
the Newton file, whose 0.5 ms and RK4 rows stay). Only
measurements with no field changed from the preset but the numerics enter; an integrator switch, and
near-contact sub-stepping, are keys of their own.

    python benchmarks/step_checks.py        # rewrites the table; prints it
"""

from __future__ import annotations

import json
import pathlib

from smarticle_mjx import presets
from smarticle_mjx.reduce import stepcheck

ROOT = pathlib.Path(__file__).resolve().parent / "results"


def collect() -> list[stepcheck.StepCheck]:
    out = {}
    g = json.loads((ROOT / "glider_step.json").read_text())
    base = presets.params(g["model"])
    ref_name = next(k for k in g["runs"] if "reference" in k)
    for name, row in g["runs"].items():
        if name == ref_name:
            continue
        dt = float(name.split()[0]) * 1e-3
        e = stepcheck.entry(g["model"], "none", dt, base.integrator, g["reference_dt_s"], "glider_step.json", row,
                            g["runs"][ref_name])
        out[stepcheck.key_of(e)] = e
    for source in ("step_mechanism.json", "step_mechanism_lab_runs30_cg.json", "step_mechanism_lab_runs30.json",
                   "step_mechanism_substeps.json", "step_mechanism_substeps_discrete.json",
                   "step_mechanism_discrete_against-default.json"):
        if not (ROOT / source).exists():
            continue
        m = json.loads((ROOT / source).read_text())
        ref_name = m.get("reference") or next(k for k in m["runs"] if "reference" in k)
        for name, row in m["runs"].items():
            if name == ref_name or set(row["changes"]) - {"integrator", "contact_substeps", "substep_gate"}:
                continue
            ch = row["changes"]
            label = stepcheck.numerics(ch.get("integrator", base.integrator), ch.get("contact_substeps", 1),
                                       ch.get("substep_gate", base.substep_gate))
            e = stepcheck.entry(m["model"], m.get("imperfections", "none"), row["dt_s"], label,
                                m["runs"][ref_name]["dt_s"], source, row, m["runs"][ref_name])
            out.setdefault(stepcheck.key_of(e), e)  # glider_step's measurement of the same key comes first
    return list(out.values())


def main():
    checks = collect()
    stepcheck.TABLE.write_text(json.dumps({"criteria": {"beta_max": stepcheck.BETA_MAX,
                                                        "speed_max": stepcheck.SPEED_MAX},
                                           "checks": [{"key": stepcheck.key_of(c), **c.as_dict()} for c in checks]},
                                          indent=1) + "\n")
    for c in stepcheck.table():
        print(f"{stepcheck.key_of(c):60s} {c.status:8s} beta {c.beta.value:+.3f} {c.beta.ci95} "
              f"speed {c.net_speed.relative:+.0%}")


if __name__ == "__main__":
    main()
