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

from smarticle_mjx.bench import builds_preset, collect_step_checks  # noqa: F401
from smarticle_mjx.reduce import stepcheck

ROOT = pathlib.Path(__file__).resolve().parent / "results"


def main():
    checks = collect_step_checks(ROOT)
    stepcheck.TABLE.write_text(json.dumps({"criteria": {"beta_max": stepcheck.BETA_MAX,
                                                        "speed_max": stepcheck.SPEED_MAX},
                                           "checks": [{"key": stepcheck.key_of(c), **c.as_dict()} for c in checks]},
                                          indent=1) + "\n")
    for c in stepcheck.table():
        print(f"{stepcheck.key_of(c):60s} {c.status:8s} beta {c.beta.value:+.3f} {c.beta.ci95} "
              f"speed {c.net_speed.relative:+.0%}")


if __name__ == "__main__":
    main()
