"""Has a store's time step been checked on the glider quantities? (numpy only.)

Labels converge at the default step; β, net glider speed and direction
persistence need a finer one (docs/timestep.md). A check runs
``benchmarks/glider_step.py``'s 128 starts x 100 periods at a step and
integrator against a fine reference and records each quantity's paired
difference with its 95 % bootstrap interval. ``benchmarks/step_checks.py``
collects those measurements into ``step_checks.json`` beside this module;
:func:`lookup` finds the one for a store's (model, imperfections, step,
integrator) and :class:`StepCheck` carries it, unrounded, to the pages.

A step has **passed** when every paired interval (β, net speed,
persistence) contains 0, |β − β_ref| <= ``BETA_MAX`` and the net speed is
at most ``SPEED_MAX`` above or below the reference's (the criteria of the
default-step issue: half of the 0.5 ms biases). A store whose model was
changed field by field (``--set``), whose robots carry imperfections no
check used, or that another engine ran with its own step, is **not
checked**: no measurement says how its step biases its transport.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib

from ..capabilities import supports

BETA_MAX = 0.068  # |beta - beta_ref|
SPEED_MAX = 0.20  # |net speed / reference - 1|
TABLE = pathlib.Path(__file__).with_name("step_checks.json")
PASSED, FAILED, NOT_CHECKED = "passed", "failed", "not checked"
QUANTITIES = ("beta", "net_speed", "persistence")  # the glider quantities a check measures
# scene fields a check is keyed by (changing them is no other model)
KEYED_NUMERICS = ("timestep", "integrator", "contact_substeps", "substep_gate")


def numerics(integrator: str, contact_substeps: int = 1, substep_gate: float | None = None) -> str:
    """The integrator as a check names it, with the native backend's near-contact sub-stepping when on
    (``implicitfast + 2 sub-steps within 4 mm``)."""
    if int(contact_substeps) <= 1:
        return integrator
    return f"{integrator} + {int(contact_substeps)} sub-steps within {float(substep_gate) * 1e3:g} mm"


@dataclasses.dataclass(frozen=True)
class Difference:
    """A quantity at the checked step minus the reference's: ``value`` with its paired 95 % interval
    ``ci95``, and the reference's value (for a relative size)."""

    value: float
    ci95: tuple[float, float]
    reference: float

    @property
    def relative(self) -> float:
        return self.value / self.reference if self.reference else float("nan")

    @property
    def contains_zero(self) -> bool:
        return self.ci95[0] <= 0.0 <= self.ci95[1]


@dataclasses.dataclass(frozen=True)
class StepCheck:
    """What is known of a store's step: ``status`` (passed, failed, not checked) and, when measured, the
    biases of β (slope), net speed (W/period) and direction persistence against ``reference_dt_s``.
    ``integrator`` names the numerics as :func:`numerics` does (sub-stepping included).

    ``why`` says, for "not checked", what no measurement covers; ``source`` names the benchmark JSON.
    """

    model: str
    imperfections: str
    timestep_s: float
    integrator: str
    status: str
    reference_dt_s: float | None = None
    beta: Difference | None = None
    net_speed: Difference | None = None
    persistence: Difference | None = None
    source: str | None = None
    why: str | None = None

    @property
    def passed(self) -> bool:
        return self.status == PASSED

    def as_dict(self) -> dict:
        """JSON-ready, each difference with its ``relative`` size beside it."""
        out = dataclasses.asdict(self)
        for k in QUANTITIES:
            if out[k] is not None:
                out[k]["relative"] = getattr(self, k).relative
        return out


def verdict(beta: Difference, net_speed: Difference, persistence: Difference) -> str:
    """PASSED when every interval contains 0 and the point biases are within BETA_MAX and SPEED_MAX."""
    ok = (all(d.contains_zero for d in (beta, net_speed, persistence)) and abs(beta.value) <= BETA_MAX
          and abs(net_speed.relative) <= SPEED_MAX)
    return PASSED if ok else FAILED


def _key(model: str, imperfections: str, timestep_s: float, integrator: str) -> str:
    return f"{model}|{imperfections}|{timestep_s * 1e3:.6g} ms|{integrator}"


def table(path: pathlib.Path = TABLE) -> tuple[StepCheck, ...]:
    """The recorded checks, each with its verdict under today's criteria (none if no table was written)."""
    if not path.exists():
        return ()
    out = []
    for e in json.loads(path.read_text())["checks"]:
        diff = {k: Difference(e[k]["value"], tuple(e[k]["ci95"]), e[k]["reference"]) for k in QUANTITIES}
        c = StepCheck(model=e["model"], imperfections=e["imperfections"], timestep_s=float(e["timestep_s"]),
                      integrator=e["integrator"], status=verdict(**diff), reference_dt_s=e["reference_dt_s"],
                      source=e["source"], **diff)
        out.append(c)
    return tuple(out)


def key_of(c: StepCheck) -> str:
    """The table's key of a check: model, imperfections, step and numerics."""
    return _key(c.model, c.imperfections, c.timestep_s, c.integrator)


def lookup(model: str, imperfections: str, timestep_s: float, integrator: str, overrides: dict | None = None,
           backend: str = "native", checks: tuple[StepCheck, ...] | None = None) -> StepCheck:
    """The check of a store's (model preset, imperfection set, step, integrator), or why there is none."""
    base = dict(model=model, imperfections=imperfections, timestep_s=float(timestep_s), integrator=integrator)
    if not supports(backend, "mujoco_numerics"):
        return StepCheck(**base, status=NOT_CHECKED, why="the DART twin runs its own step")
    # a check is keyed by the step and the integrator, so a store that changed only those (``--set
    # timestep=...``) is looked up like the preset at that step; any other change is another model
    changed = sorted(set(overrides or ()) - set(KEYED_NUMERICS))
    if changed:
        return StepCheck(**base, status=NOT_CHECKED, why="fields changed from the preset: " + ", ".join(changed))
    key = _key(model, imperfections, timestep_s, integrator)
    found = next((c for c in (table() if checks is None else checks) if key_of(c) == key), None)
    if found is None:
        return StepCheck(**base, status=NOT_CHECKED, why="no glider-quantity check at this model, step and integrator")
    return found


def entry(model: str, imperfections: str, timestep_s: float, integrator: str, reference_dt_s: float, source: str,
          runs_row: dict, reference_row: dict) -> StepCheck:
    """The check one benchmark row measured ({quantity: {value, minus_reference, minus_reference_ci95}}),
    against its reference row ({quantity: {value}}); quantities beta, net_speed, persistence.
    ``as_dict()`` is the table's JSON record of it.

    Raises:
      ValueError: a quantity is not a number (a run without gliders measures nothing; it is no check).
    """
    diff, bad = {}, []
    for k in QUANTITIES:
        value, ci95, ref = runs_row[k]["minus_reference"], runs_row[k]["minus_reference_ci95"], reference_row[k]["value"]
        if not all(math.isfinite(float(x)) for x in (value, *ci95, ref)):
            bad.append(k)
        diff[k] = Difference(float(value), (float(ci95[0]), float(ci95[1])), float(ref))
    if bad:
        raise ValueError(f"no {', '.join(bad)} measured for {model}+{imperfections} at {timestep_s * 1e3:g} ms "
                         "(no gliders in a run): not a check")
    return StepCheck(model=model, imperfections=imperfections, timestep_s=float(timestep_s), integrator=integrator,
                     status=verdict(**diff), reference_dt_s=float(reference_dt_s), source=source, **diff)
