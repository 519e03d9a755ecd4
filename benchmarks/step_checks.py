"""Collect the glider-quantity checks of time steps into the package's table
(smarticle_mjx/reduce/step_checks.json), which `smx report` reads to say whether a store's step has
been checked and, if it has not passed, how it biases β and glider speed.

Sources: results/glider_step.json (steps against the 0.0625 ms reference, model lab-lag, ideal robots),
results/step_mechanism.json (integrators and steps against the same reference, same starts) and
results/step_mechanism_substeps.json and step_mechanism_substeps_discrete.json (near-contact sub-stepping
with implicitfast and with discrete, against the same reference, same starts),
results/step_mechanism_discrete_against-default.json (discrete at 0.0625-0.25 ms and discrete and Euler with
near-contact sub-stepping, against the same reference, same starts),
and the `lab` imperfection set's rows, measured with today's `lab` robots (whose start delays changed in
version 0.4.1) and the solver the preset gives their gear play, against the check's 0.0625 ms reference run again
beside them (a glider there is a start's longest bound run of >= 30 periods, because the drawn robots' drifting
clocks leave no pair bound from period 10 to 100 at any step, so the steady rule of the other sources measures
nothing): results/step_mechanism_lab_runs30_stops-0.5ms_against-default.json (0.25 ms; the row names the gear
teeth's 0.5 ms that the default step builds anyway, so its scene is the preset's) and
results/step_mechanism_lab_runs30_rerun.json (0.5 ms and 1 ms RK4). The earlier `lab` files
(step_mechanism_lab_runs30.json, made with Newton, and step_mechanism_lab_runs30_cg.json, both before 0.4.1)
stay in results/ and no longer enter. Only measurements whose scene is the
preset's at their step enter (a field changed that builds the same scene, as the teeth above, does not make
another model); an integrator switch, and near-contact sub-stepping, are keys of their own.

    python benchmarks/step_checks.py        # rewrites the table; prints it
"""

from __future__ import annotations

import json
import pathlib

from glider_step import SEED
from smarticle_mjx import imperfections as imp
from smarticle_mjx import presets, scene
from smarticle_mjx.reduce import stepcheck
from step_mechanism import variant_params

ROOT = pathlib.Path(__file__).resolve().parent / "results"


def builds_preset(model: str, imperfections: str, row: dict) -> bool:
    """Does a benchmark row's scene equal the preset's at the row's step and numerics? Rows that change only
    the numerics (``stepcheck.KEYED_NUMERICS``) do; a row that changes a robot field enters only where that
    field builds the scene the preset builds anyway (the gear teeth's time constant at the 2 dt the step
    gives them), with the check's drawn robots."""
    changes = row["changes"]
    numerics = {k: v for k, v in changes.items() if k != "robot"}
    if set(numerics) - set(stepcheck.KEYED_NUMERICS):
        return False
    if not changes.get("robot"):
        return True
    robots = imp.draw(imperfections, 2, SEED) if imperfections != "none" else None
    poses = [(0.0, 0.0, 0.0, 1.0, 1.0), (0.2, 0.0, 0.5, 1.0, 1.0)]
    xml = [scene.build_mjcf(p if robots is None else robots.scene(p), poses)
           for p in (variant_params(row["dt_s"], numerics, model), variant_params(row["dt_s"], changes, model))]
    return xml[0] == xml[1]


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
    for source in ("step_mechanism.json", "step_mechanism_lab_runs30_stops-0.5ms_against-default.json",
                   "step_mechanism_lab_runs30_rerun.json",
                   "step_mechanism_substeps.json", "step_mechanism_substeps_discrete.json",
                   "step_mechanism_discrete_against-default.json"):
        if not (ROOT / source).exists():
            continue
        m = json.loads((ROOT / source).read_text())
        ref_name = m.get("reference") or next(k for k in m["runs"] if "reference" in k)
        for name, row in m["runs"].items():
            if name == ref_name or not builds_preset(m["model"], m.get("imperfections", "none"), row):
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
