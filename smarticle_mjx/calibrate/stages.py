"""The calibration loop as stages: preset -> conventions -> tracking noise -> nominal parameters -> plate tilt ->
effect rounds -> observables -> verdict.

Each stage is a function that returns a dataclass; :func:`calibrate` runs them in order and returns a
:class:`Calibration` (the fitted model and the JSON-ready summary that ``report`` writes). Every effect
fitted through the model, a nominal hypothesis or a round's candidate, passes the one acceptance rule of
:func:`judge` (docstring of :mod:`calibrate.fit`). The plate tilt is estimated without the model, from
the plate-frame drift (:mod:`calibrate.drift`), and kept by that test's own criterion (``TILT_Z2``). Every
acceptance rule lives in :mod:`calibrate.policy`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

from .data import Trial, priors
from .discrepancy import carry, log_sd
from .armoffset import read_offsets, without_offsets
from .drift import drift_test, fit_tilt
from .noise import NoiseReading, effect_values as noise_values, noise_test
from .effects import BY_NAME, LIBRARY, Effect, EffectSet, on_bound_away_from_null, value_to_unit
from .fit import (FIT_CANDIDATES, HYPOTHESIS_NFEV, NOMINAL_EFFECTS, NOMINAL_NFEV, PLATE_HYPOTHESES,
                  SERVO_HYPOTHESES, SERVO_NOMINAL, Fit, Problem, conventions, fit_effects, nominal_findings,
                  observable_stages, signatures, split, stage_tracks, where_residual)
from . import policy
from .policy import (  # noqa: F401  (the acceptance rules; re-exported for the readings that name them here)
    ANISO, ARM_PLATE, BELOW_FLOOR, MAX_EFFECTS, MEASURED_DRAG, MEASURED_OFFSET, MIN_HELDOUT_GAIN, MIN_SHARE,
    NO_ARMS, P_LEVEL, P_ONE_VECTOR, TILT_Z2, UNEXPLAINED, Judgement, below_delay_floor, first_choice, floor_note,
    follows_the_robot, invariants, is_present, judge, judged, measured_structure, plate_skip_reason, servo_choice,
    servo_skip_reason, tilt_accepted, verdict)
from .observables import DelayTest, delay_test, observables, servo_reading
from .nominal import BY_NAME as NOMINAL_BY_NAME, apply as apply_nominal, fit_nominal
from .armdrag import DragTest, drag_test
from .phase import OffsetTest, estimate_offset, offset_test
from .residuals import CONTACT_W
from .sim import pmap, simulate_trials


def scores(train: Problem, test: Problem, fe, names=()) -> tuple[dict, EffectSet, float, float]:
    """A joint fit's nominal values, its effects ``names`` (their fitted values), its training chi^2 with
    the priors, and its held-out error."""
    nom = {k: fe.values[k] for k in fe.preset}
    eff = EffectSet.of({k: fe.values[k] for k in names})
    v = train.vector_with(nom, eff)
    return nom, eff, float(v @ v) + train.prior_chi2(nom), float(np.mean(test.vector_with(nom, eff) ** 2))


@dataclasses.dataclass(frozen=True)
class Errors:
    """A model's errors (the mean squared normalised residual: about 1 within measurement error) on the
    training and the held-out trials, and the held-out error per kind of feature."""

    err_train: float
    err_heldout: float
    where_heldout: dict[str, float]

    def as_dict(self) -> dict:
        return {"err_train": self.err_train, "err_heldout": self.err_heldout, "where_heldout": self.where_heldout}


def errors(train: Problem, test: Problem, eff: EffectSet) -> Errors:
    return Errors(train.error(eff), test.error(eff), where_residual(test, eff))


@dataclasses.dataclass
class Model:
    """The model as the stages build it: effects chosen so far, their values, and what was found."""

    chosen: list = dataclasses.field(default_factory=list)  # Effect, in the order added
    base: dict = dataclasses.field(default_factory=dict)  # effect -> values
    found: dict = dataclasses.field(default_factory=dict)  # effect -> (values, interval) of its latest fit
    fixed: dict = dataclasses.field(default_factory=dict)  # effects held at values fitted outside the rounds

    def add(self, e: Effect, values, interval) -> None:
        self.chosen.append(e)
        self.found[e.name] = (values, interval)

    def drop(self, name: str) -> None:
        """Take effect ``name`` out again (an invariant refused it after it was added)."""
        self.chosen = [e for e in self.chosen if e.name != name]
        for d in (self.base, self.found, self.fixed):
            d.pop(name, None)


@dataclasses.dataclass(frozen=True)
class Hypothesis:
    """One joint hypothesis of the nominal stage as judged (an entry of the report's nominal hypotheses).

    Three kinds: not tried (``tried`` False, with the ``reason``); tried in the first pass (fitted with the
    nominal parameters); tried ``beside`` the accepted first one (the second hypothesis, with whether the
    first stayed present and which ``start`` it came from). A tried one carries its fitted ``values`` and
    ``interval``, its held-out error against the ``baseline_err_heldout``, the gains the rule read
    (``policy.judged``), whether it is ``present``, ``accepted`` and by which ``rule``, and the fit's cost;
    a first-pass hypothesis refused after passing (``policy.servo_choice``) gains a ``reason``."""

    effect: str
    tried: bool
    accepted: bool
    reason: str | None = None
    beside: str | None = None
    values: dict | None = None
    interval: dict | None = None
    err_heldout: float | None = None
    heldout_gain: float | None = None
    bic_gain: float | None = None
    present: bool | None = None
    first_present: bool | None = None
    rule: str | None = None
    baseline_err_heldout: float | None = None
    evaluations: int | None = None
    starts: int | None = None
    start: str | None = None

    _FIRST = ("effect", "tried", "values", "interval", "err_heldout", "heldout_gain", "bic_gain", "present",
              "accepted", "rule", "baseline_err_heldout", "evaluations", "starts")
    _BESIDE = ("effect", "beside", "tried", "values", "interval", "err_heldout", "heldout_gain", "bic_gain",
               "present", "first_present", "accepted", "rule", "baseline_err_heldout", "evaluations", "starts",
               "start")

    @classmethod
    def skipped(cls, effect: str, reason: str) -> "Hypothesis":
        """A hypothesis not tried, and why."""
        return cls(effect, False, False, reason)

    def as_json(self) -> dict:
        """``report.json``'s entry (the keys of its kind, in the report's order)."""
        if not self.tried:
            return {"effect": self.effect, "tried": False, "accepted": self.accepted, "reason": self.reason}
        keys = self._BESIDE if self.beside is not None else self._FIRST
        out = {k: getattr(self, k) for k in keys}
        if self.reason is not None:
            out["reason"] = self.reason
        return out


@dataclasses.dataclass(frozen=True)
class NominalStage:
    """The nominal stage: the robot's nominal parameters fitted (with the joint hypotheses accepted), their
    values fitted alone and the errors then, every joint hypothesis as judged (the report's entries), and the
    delay and rise tests read before it."""

    fit: object  # nominal.NominalFit (with an accepted hypothesis's nominal values), or None
    start: dict  # the nominal values fitted alone
    errors: Errors  # with the nominal values alone
    hypotheses: tuple[Hypothesis, ...]
    delay: DelayTest  # the measured arm delay against the preset model's, by amplitude
    rise: DelayTest | None = None  # the arm rise's excess over the preset model's, split the same way




def drag_plan(dtest: DragTest | None, plate_hypotheses: tuple[str, ...], library) -> tuple[tuple, tuple, str]:
    """What the arm-drag test (``armdrag.drag_test``) changes: (plate hypotheses, library, what was done).

    present: arms on the plate become a joint hypothesis of the nominal stage (fitted with the nominal
    parameters from the grid's start; calibrate() leaves the joint hypotheses out of the rounds), accepted
    where that fit sizes them present and does not lose held out (:func:`measured_structure`); absent: no
    fit tries them, unless asked for as a joint hypothesis (a user who knows the arms touch); undecided or
    not applicable: as asked (the rounds may still try them)."""
    if dtest is None or not dtest.applicable:
        return plate_hypotheses, library, "not read"
    if dtest.undecided:
        return plate_hypotheses, library, "undecided: left to the rounds, as without a reading"
    if dtest.present:
        if ARM_PLATE in plate_hypotheses:
            return plate_hypotheses, library, ("present: fitted jointly with the nominal parameters (as asked) and added "
                                               "where the fit sizes it clear of no drag without losing held out")
        # the joint hypotheses are tried from the library; calibrate() takes them out of the rounds after it
        return plate_hypotheses + (ARM_PLATE,), library, ("present: fitted jointly with the nominal parameters and "
                                                          "added where the fit sizes it clear of no drag without "
                                                          "losing held out")
    if ARM_PLATE in plate_hypotheses:
        return plate_hypotheses, library, "absent, fitted jointly all the same (asked for)"
    return (plate_hypotheses, tuple(e for e in library if e.name != ARM_PLATE),
            "absent: arms on the plate are not fitted")


def offset_absent_reason(otest: OffsetTest) -> str:
    return (f"the robots' own {otest.read_from} align at "
            f"{otest.mean:+.4f} +- {otest.se:.4f} periods ({otest.n} pairs): no phase offset between them")


def nominal_stage(train: Problem, test: Problem, trials: list[Trial], library, model: Model, say,
                  plate_hypotheses: tuple[str, ...] = PLATE_HYPOTHESES,
                  otest: OffsetTest | None = None, drag: DragTest | None = None) -> NominalStage:
    """Fit the robot's nominal parameters, then each joint hypothesis (a servo lag or dead time, a phase
    offset between robots) with them; keep the best accepted hypothesis."""
    null = EffectSet()
    nominal_fit = fit_nominal(train, max_nfev=NOMINAL_NFEV)
    nom0 = {k: nominal_fit.values[k] for k in nominal_fit.preset}
    train.nominal = test.nominal = dict(nom0)
    err0 = test.error(null)
    v0 = train.vector(null)
    chi2_0, n = float(v0 @ v0) + train.prior_chi2(nom0), len(v0)
    say(f"nominal parameters fitted ({nominal_fit.evaluations} runs): held-out error {err0:.2f}")
    alone = errors(train, test, null)
    # structure before numbers: does the measured arm delay exceed the preset model's by a constant (a lag
    # or dead time) or by a part growing with the amplitude (a slower servo, which the nominal fit covers)?
    data_obs, preset_obs = observables(trials), observables(trials, stage_tracks(train, test, trials, {}, null))
    dtest = delay_test(data_obs, preset_obs)
    # and which servo timing the arm's rise reads, to choose between a lag and a dead time that both pass
    rtest = delay_test(data_obs, preset_obs, "arm_rise_ms")
    reading = servo_reading(rtest)
    if dtest.applicable:
        say(f"arm delay beyond the preset model's: {dtest.constant_ms:.1f} +- {dtest.constant_se_ms:.1f} ms constant, "
            f"{dtest.per_rad_ms:.1f} +- {dtest.per_rad_se_ms:.1f} ms per rad of amplitude: "
            + ("a constant delay" if dtest.constant_delay else "no constant delay" if dtest.no_constant_delay
               else "undecided"))
    if reading is not None:
        say(f"arm rise beyond the preset model's: {rtest.constant_ms:.1f} +- {rtest.constant_se_ms:.1f} ms constant: "
            f"reads a {'lag' if reading == 'servo_lag' else 'dead time'}, should both pass")
    # a servo lag or dead time changes the arms like a slower, softer servo does at one amplitude:
    # each is fitted jointly with the nominal parameters and kept only if it beats them alone.
    # With several robots, a gait phase offset between them moves the arms of all but the first
    # in time; fitted after the nominal servo, it found a third of a 0.1-period offset (the servo
    # had bent to split the difference between the robots), so it is a joint hypothesis too,
    # started from the offset at which the robots' own arm curves align
    # An anisotropic plate changes the model robot's wobble and steps only where the model robot slides
    # like the measured one, which the nominal fit reaches by the plate's mu (with the anisotropy) or
    # not at all (without it): a joint hypothesis too, started from the nominal fit and from a grid over both.
    # Arms dragging on the plate the same way: the nominal fit has made the plate slipperier to mimic them
    joint = (SERVO_HYPOTHESES + (("phase_offset",) if max(tr.robots for tr in trials) > 1 else ())
             + tuple(plate_hypotheses))
    servo_skip = servo_skip_reason(trials, dtest)  # why a lag or dead time is not tried here, or None
    if servo_skip == NO_ARMS:
        say("no arm angles tracked: a servo lag or dead time is not tried (body motion alone cannot tell a "
            "servo's timing from its law)")
    elif servo_skip is not None:
        say(f"a servo lag or dead time is not tried: {servo_skip}")
    hypotheses, passed, tasks, first = [], [], [], {}
    preset_servo = servo_at_preset(nom0)  # the second start of a timing
    for name in joint:
        if name not in {e.name for e in library}:
            continue
        e, e_start = BY_NAME[name], None
        if name in SERVO_HYPOTHESES and servo_skip is not None:
            hypotheses.append(Hypothesis.skipped(name, servo_skip))
            continue
        if name == "phase_offset" and otest is not None and otest.absent:
            hypotheses.append(Hypothesis.skipped(name, offset_absent_reason(otest)))
            continue
        # a present offset is held at its reading (train.effect_fixed, set by calibrate): nothing to start
        if name == "phase_offset" and not (otest is not None and otest.present):
            # started where the robots' arm curves align (model-free)
            est = estimate_offset(train.trials)
            e_start = {"phase_offset": est["offset"]} if est else None
            if est:
                say(f"  robots' arm curves align at a phase offset of {est['offset']:.3f} periods")
        tasks.append((name, e, nom0, e_start))
        # (a servo timing's third start, absent from its baseline where needed, comes after these fits)
        # the nominal fit alone bends the servo to mimic a lag or dead time (a 30 ms dead time: speed
        # x0.83, gain x0.52) and, started there, the joint fit stays in that valley (14 ms); so it is
        # started a second time from the preset's servo, and the start that ends with the lower training
        # error is kept. A phase offset between robots likewise: the nominal fit bends the servo to split
        # the robots' timing, and at the 0.25 ms step a 0.1-period offset started there ended at 0.066
        # (held-out gain 11 %, rejected), where at 0.5 ms it had reached 0.109
        if name in plate_hypotheses:
            # from the nominal fit, mu and the anisotropy each alone barely move the model robot (it hardly
            # slides); the second start is the best point of a coarse grid over the two together
            grid = plate_grid_starts(train, nom0, e)
            for k, (start_k, e_start_k) in enumerate(grid):
                say(f"  nominal + {name}: {'grid start' if k == 0 else 'grid start on the other side of 1'} "
                    f"plate_friction {start_k['plate_friction']:.3g}, "
                    f"{', '.join(f'{k_} {v:.3g}' for k_, v in e_start_k.items())}")
                tasks.append((name, e, start_k, e_start_k))
            start = grid[0][0]
            # and the null gets the same chance: the nominal parameters alone, restarted at the grid's mu
            # (a restart that helps without the anisotropy is not the anisotropy's gain)
            tasks.append((name, None, {**nom0, "plate_friction": start["plate_friction"]}, None))
            continue
        tasks.append((name, e, preset_servo, e_start))
    if any(t[0] in SERVO_HYPOTHESES for t in tasks):
        # and the null the same chance: the nominal parameters alone, their servo restarted at the preset, once
        # for both timings (a restart that helps without the timing is not the timing's gain)
        tasks.append((SERVO_NULL, None, preset_servo, None))
    # every joint fit at once, one thread each (each fit's own runs then go one after another)
    fits = pmap(lambda t: fit_nominal(train, effect=t[1], start=t[2], max_nfev=HYPOTHESIS_NFEV, effect_start=t[3]),
                tasks)
    done, nulls = {}, {}
    for (name, e, _, _), fe in zip(tasks, fits):
        if e is None:  # the null's restart beside a plate hypothesis, or the servo's from the preset
            nulls[name] = fe
            continue
        done.setdefault(name, (e, []))[1].append(fe)
    restarts = {name: scores(train, test, fe) for name, fe in nulls.items()}  # each null's restart, scored once
    # a servo timing whose two probe starts both ended above its baseline in training (which a converged fit,
    # containing the baseline, cannot) is fitted a third time, started absent from that baseline; it does not
    # replace the probe's starts (started absent alone, a timing can stay in the bent servo's valley below the
    # delay floor). A plate hypothesis the same way: fitted a third time from that baseline's end, the effect
    # started at whichever of its null, its grid values and the values its two starts ended at fits best there,
    # and judged against the null continued beside it

    # the baseline of each hypothesis: the better in training of the nominal fit and its restart (at the grid's
    # mu, or from the preset servo): hypothesis -> (training chi^2, nominal values, in words, held-out error)
    baselines = {}
    for name in done:
        null_name = SERVO_NULL if name in SERVO_HYPOTHESES else name
        baselines[name] = (chi2_0, nom0, "the nominal fit", err0)
        if null_name in restarts and restarts[null_name][2] < chi2_0:
            nom_n, _, chi2_n, err_n = restarts[null_name]
            where = ("the nominal fit's restart from the preset servo" if null_name == SERVO_NULL
                     else f"the nominal parameters restarted at plate_friction {nom_n['plate_friction']:.3g}")
            baselines[name] = (chi2_n, nom_n, where, err_n)
    ended = {name: scores(train, test, min(fes, key=lambda f: f.err_after), (name,))[2]
             for name, (_, fes) in done.items() if name in SERVO_HYPOTHESES or name in plate_hypotheses}
    third = {}  # hypothesis -> (nominal values, effect values) of its third start
    from_null = {}  # hypothesis -> where its third start began, in words
    for name, (start, where) in third_starts(ended, baselines).items():
        e = BY_NAME[name]
        e_start = (e.null() if name in SERVO_HYPOTHESES
                   else plate_third_start(train, start, e, [f.values[name] for f in done[name][1]]))
        third[name] = (start, e_start)
        from_null[name] = (f"absent from {where}" if e_start == e.null()
                           else f"at {', '.join(f'{k} {v:.3g}' for k, v in e_start.items())} from {where}")
    # and the null continued from the same start with the same budget, beside them: a third start that keeps its
    # effect at the null is the baseline fitted further, and ends below it by that alone. So a hypothesis fitted
    # a third time is judged against that continued null where it fits better
    third_baselines = {}  # hypothesis -> (chi^2, held-out error, training error) of the null continued beside it
    if third:
        starts = {}  # one continued null per distinct start
        for name, (start, _) in third.items():
            starts.setdefault(id(start), (start, []))[1].append(name)
        runs = ([(BY_NAME[name], start, e_start) for name, (start, e_start) in third.items()]
                + [(None, start, None) for start, _ in starts.values()])  # the nulls last
        again = pmap(lambda r: fit_nominal(train, effect=r[0], start=r[1], max_nfev=HYPOTHESIS_NFEV,
                                           effect_start=r[2]), runs)
        for name, fe in zip(third, again):
            done[name][1].append(fe)
        for (start, names), fe in zip(starts.values(), again[len(third):]):
            _, _, chi2_c, err_c = scores(train, test, fe)
            for name in names:
                third_baselines[name] = (chi2_c, err_c, fe.err_after)
    for name, (e, fes) in done.items():
        fe = fes[0]
        if len(fes) >= 2:
            probes = ["from the nominal fit"] + (["from the grid's start", "from the grid's start on the other side of 1"]
                                                 if name in plate_hypotheses else ["from the preset servo"])
            probes = probes[:len(fes) - (name in from_null)] + ([from_null[name]] if name in from_null else [])
            say(f"  nominal + {name}: training error "
                + ", ".join(f"{f.err_after:.2f} {'started ' * (k == 0)}{w}" for k, (f, w) in enumerate(zip(fes, probes))))
            runs = sum(f.evaluations for f in fes)
            fe = dataclasses.replace(min(fes, key=lambda f: f.err_after), evaluations=runs)
        first[name] = fe
        nom_e, _, chi2_e, err_e = scores(train, test, fe, (name,))
        interval = {p.name: fe.interval[p.name] for p in e.params}
        base_chi2, _, where, base_err = baselines[name]
        if base_chi2 < chi2_0:
            say(f"  {where}: held-out error {base_err:.2f}, the baseline for {name}")
        if name in third_baselines and third_baselines[name][0] < base_chi2:  # fitted a third time: the null
            # continued from the same start, where it ended below the baseline
            base_chi2, base_err, train_err = third_baselines[name]
            say(f"  nominal parameters continued beside the third start: training error {train_err:.2f}, "
                f"held-out error {base_err:.2f}, the baseline for {name}")
        j, rule = measured_structure(name, otest, *judged(e, fe.interval, base_chi2, chi2_e, n, base_err, err_e,
                                                          dtest), drag=drag)
        j, rule = invariants(e, fe.values[name], j, rule)
        hypotheses.append(Hypothesis(name, True, j.accepted, values=fe.values[name], interval=interval,
                                     err_heldout=err_e, heldout_gain=j.heldout_gain, bic_gain=j.bic_gain,
                                     present=j.present, rule=rule, baseline_err_heldout=base_err,
                                     evaluations=fe.evaluations, starts=len(fes)))
        say(f"  nominal + {name}: held-out error {err_e:.2f} ({j.heldout_gain:+.0%}), BIC gain {j.bic_gain:.1f}"
            + floor_note(rule))
        if j.accepted:
            passed.append((fe, j.heldout_gain, e, nom_e, interval))
    passed, hypotheses = servo_choice(passed, hypotheses, reading, say)
    best = first_choice(passed, otest, drag)
    if best is not None:
        fe, _, e, nom_e, interval = best
        model.add(e, fe.values[e.name], interval)
        model.base = {**model.base, e.name: fe.values[e.name]}  # beside what was measured before the fit
        train.nominal = test.nominal = dict(nom_e)
        nominal_fit = dataclasses.replace(fe, values=dict(nom_e))
        say(f"added {e.name} (fitted with the nominal parameters)")
        second = second_hypothesis(train, test, tasks, best, nom0, n, dtest, say, reading, first, drag)
        hypotheses += second.tried
        if second.fit is not None:
            fe2, e2 = second.fit, second.effect
            nom_2 = {k: fe2.values[k] for k in fe2.preset}
            model.found[e.name] = (fe2.values[e.name], {p.name: fe2.interval[p.name] for p in e.params})
            model.add(e2, fe2.values[e2.name], {p.name: fe2.interval[p.name] for p in e2.params})
            model.base = {**model.base, e.name: fe2.values[e.name], e2.name: fe2.values[e2.name]}
            train.nominal = test.nominal = dict(nom_2)
            nominal_fit = dataclasses.replace(fe2, values=dict(nom_2))
            say(f"added {e2.name} beside {e.name} (both fitted with the nominal parameters)")
    return NominalStage(nominal_fit, nom0, alone, tuple(hypotheses), dtest, rtest)


SERVO_NULL = "servo restarted"  # the key of the nominal fit restarted from the preset servo, without an effect


@dataclasses.dataclass(frozen=True)
class SecondHypothesis:
    """A second joint hypothesis tried beside the accepted one: the joint fit where one was accepted."""

    fit: object  # nominal.NominalFit of the nominal parameters with both effects, or None: none accepted
    effect: Effect | None
    tried: list  # Hypothesis entries for the report's nominal hypotheses, each ``beside`` the first


def second_hypothesis(train: Problem, test: Problem, tasks: list, best: tuple, nom0: dict, n: int,
                      dtest: DelayTest, say, reading: str | None, first: dict,
                      drag: DragTest | None = None) -> SecondHypothesis:
    """A second joint hypothesis beside the accepted one.

    The joint hypotheses are alternatives in the first pass: the best accepted one is kept. But two can be
    there at once (a dead time and a phase offset, a lag and an anisotropic plate), and the rounds after
    the nominal stage never try the others again (they rescale what the nominal fit fits). So each other
    joint hypothesis is fitted once more, jointly with the nominal parameters *and* the accepted one, and
    judged by the same rule
    against the accepted model (the nominal parameters with the first effect) as its baseline: BIC gain,
    held-out gain >= ``MIN_HELDOUT_GAIN`` (a servo hypothesis after a positive delay test: not a loss),
    present; and the first effect must stay present. A second servo hypothesis beside a first is not tried
    (a lag and a dead time are two readings of one servo's timing).

    Each starts from where its own first-pass fit (``first``: name -> that fit) ended, its own value with
    the accepted effect's: once at the accepted fit's nominal values, once at its own fit's (the two basins
    the first pass found; started from the first pass's starts instead, a second effect can stay in the
    nominal fit's valley). Where the delay test reads a constant delay, a servo timing gets a third start:
    the timing at the test's constant, the servo at its preset, the other nominal values at the accepted
    fit's (``delay_reading_start``), since its first-pass fits were made without the accepted effect, which
    the nominal servo may have taken up. A plate hypothesis's null
    restart (``tasks`` without an effect) is run again with the accepted effect, moved to its values like the
    first pass's start, as that hypothesis's baseline."""
    fe1, _, e1, nom_e1, _ = best
    v1 = dict(fe1.values[e1.name])
    _, _, chi2_1, err_1 = scores(train, test, fe1, (e1.name,))

    def other(name):
        return name != e1.name and not (name in SERVO_HYPOTHESES and e1.name in SERVO_HYPOTHESES)

    # the null restarts: their departures from the nominal fit kept (a plate's grid mu), the rest at the
    # accepted fit's values
    # (the servo's null is not: a second servo hypothesis starts from its own first fit, not the preset)
    todo = [(name, None, {k: (st[k] if st[k] != nom0.get(k) else nom_e1[k]) for k in st}, v1, None)
            for name, e, st, _ in tasks if e is None and name != SERVO_NULL and other(name)]
    for name, fe2 in first.items():
        if other(name):
            todo.append((name, BY_NAME[name], dict(nom_e1), {**v1, **fe2.values[name]}, START_ACCEPTED))
            todo.append((name, BY_NAME[name], {k: fe2.values[k] for k in fe2.preset}, {**v1, **fe2.values[name]},
                         START_OWN))
            at = delay_reading_start(BY_NAME[name], dtest)
            if at is not None:  # a third start: the timing at the delay test's reading, the servo at its preset
                todo.append((name, BY_NAME[name], servo_at_preset(nom_e1), {**v1, **at}, START_DELAY_READING))
    if not todo:
        return SecondHypothesis(None, None, [])
    fits = pmap(lambda t: fit_nominal(train, effect=(e1,) if t[1] is None else (e1, t[1]), start=t[2],
                                      max_nfev=HYPOTHESIS_NFEV, effect_start=t[3]), todo)
    done, nulls = {}, {}
    for (name, e, _, _, label), fe in zip(todo, fits):
        if e is None:
            nulls[name] = fe
        else:
            done.setdefault(name, (e, []))[1].append((fe, label))
    tried, passed = [], []
    for name, (e, fes) in done.items():
        fe, label = min(fes, key=lambda f: f[0].err_after)
        fe = dataclasses.replace(fe, evaluations=sum(f.evaluations for f, _ in fes))
        _, _, chi2, err = scores(train, test, fe, (e1.name, name))
        base_chi2, base_err = chi2_1, err_1
        if name in nulls:  # the accepted model restarted at the grid's mu: the baseline if it fits better
            _, _, chi2_n, err_n = scores(train, test, nulls[name], (e1.name,))
            if chi2_n < chi2_1:
                base_chi2, base_err = chi2_n, err_n
        interval = {p.name: fe.interval[p.name] for p in e.params}
        j, rule = measured_structure(name, None, *judged(e, interval, base_chi2, chi2, n, base_err, err, dtest),
                                     drag=drag)
        j, rule = invariants(e, fe.values[name], j, rule)
        first_present = is_present(e1, {p.name: fe.interval[p.name] for p in e1.params})
        ok = j.accepted and first_present
        tried.append(Hypothesis(name, True, ok, beside=e1.name, values=fe.values[name], interval=interval,
                                err_heldout=err, heldout_gain=j.heldout_gain, bic_gain=j.bic_gain, present=j.present,
                                first_present=first_present, rule=rule, baseline_err_heldout=base_err,
                                evaluations=fe.evaluations, starts=len(fes), start=label))
        say(f"  nominal + {e1.name} + {name}: held-out error {err:.2f} ({j.heldout_gain:+.0%} over "
            f"{e1.name} alone), BIC gain {j.bic_gain:.1f}" + ("" if first_present else f"; {e1.name} no longer shown")
            + ("; started at the delay test's reading" if label == START_DELAY_READING else "") + floor_note(rule))
        if ok:
            passed.append((fe, j.heldout_gain, e))
    passed, tried = servo_choice(passed, tried, reading, say)
    pick = max(passed, key=lambda c: c[1], default=None)
    if pick is None:
        return SecondHypothesis(None, None, tried)
    return SecondHypothesis(pick[0], pick[2], tried)


# where a second-pass hypothesis's best start began (its stored entry's "start")
START_ACCEPTED = "the accepted fit's nominal values"
START_OWN = "its own first-pass fit's nominal values"
START_DELAY_READING = "the delay test's reading, the servo at its preset"


def servo_at_preset(nominal: dict) -> dict:
    """Nominal start values with the servo's parameters (``SERVO_NOMINAL``) left out, so that a fit starts
    them at the preset: where a servo timing starts, away from the servo the nominal fit bent to mimic it."""
    return {k: v for k, v in nominal.items() if k not in SERVO_NOMINAL}


def delay_reading_start(e: Effect, dtest) -> dict | None:
    """A servo timing's values at the delay test's reading: its one parameter at the test's constant delay
    (within the parameter's bounds), where the test reads a constant delay; None for any other effect or
    reading. A lag delays an arm's midpoint crossing by about its time constant, a dead time by itself, so
    the constant is where either starts."""
    if e.name not in SERVO_HYPOTHESES or not dtest.constant_delay:
        return None
    (p,) = e.params
    return {p.name: float(np.clip(dtest.constant_ms / 1e3, p.lo, p.hi))}


# each plate hypothesis's grid: the plate's mu at these factors of the nominal fit's, times its parameter's
# start values. An anisotropic plate matters where the model robot slides more (mu lower), either axis
# rougher; arms dragging on the plate make the measured robot turn and step more, which the nominal fit
# mimics by a slipperier plate, so its grid also raises mu
PLATE_GRIDS = {"anisotropic_friction": ((1.0, 0.5, 0.25), (0.4, 0.63, 1.6, 2.5)),
               "arm_plate_contact": ((0.5, 1.0, 2.0, 4.0), (0.1, 0.25, 0.5))}
PLATE_GRID_MU, PLATE_GRID_RATIO = PLATE_GRIDS["anisotropic_friction"]
# True: the anisotropic plate also starts from the grid's best point on the other side of 1
# (plate_grid_starts; a counterfactual for the stress suite's --plate-both-sides, run apart with --tag; not the rule)
PLATE_BOTH_SIDES = False


def plate_hypotheses_with(extra=()) -> tuple[str, ...]:
    """The default joint plate hypotheses and ``extra`` (in that order, each once); ValueError in one line
    for a name that has no grid in ``PLATE_GRIDS``."""
    unknown = [h for h in extra if h not in PLATE_GRIDS]
    if unknown:
        raise ValueError(f"no joint plate hypothesis {unknown[0]!r}; choose from {', '.join(PLATE_GRIDS)}")
    return tuple(dict.fromkeys(PLATE_HYPOTHESES + tuple(extra)))


def plate_grid_start(train: Problem, nom0: dict, e: Effect) -> tuple[dict, dict]:
    """(nominal values, effect values) of the grid point with the lowest training chi^2: the plate's mu at
    the effect's factors (``PLATE_GRIDS``) times the nominal fit's (within the nominal bounds), the
    effect's one parameter at its start values (12 model runs, side by side)."""
    return plate_grid_starts(train, nom0, e)[0]


def plate_grid_starts(train: Problem, nom0: dict, e: Effect) -> list[tuple[dict, dict]]:
    """The grid's starts for a plate hypothesis, each (nominal values, effect values): first the point with
    the lowest training chi^2 (:func:`plate_grid_start`); with ``PLATE_BOTH_SIDES`` (a counterfactual for
    the stress suite's --plate-both-sides, not the rule), for the anisotropic plate also the best point whose
    ratio lies on the other side of 1 (the other axis rougher), from the same grid runs.

    Not the rule: where the fit had gone to the wrong side of 1, the start on the true side ended above it in
    training, and the model-free drift does not say the side either (its history and numbers:
    notebook/calibration-rules.md)."""
    (p,) = e.params
    factors, values = PLATE_GRIDS[e.name]
    lo, hi = NOMINAL_BY_NAME["plate_friction"].bounds(train.trials[0].params)  # where the fit can start
    points = [({**nom0, "plate_friction": float(np.clip(nom0["plate_friction"] * f, lo, hi))},
               EffectSet.of({e.name: {p.name: r}})) for f in factors for r in values]
    train.prefetch([(eff, nom) for nom, eff in points])
    chi2 = [float(np.sum(train.vector_with(nom, eff) ** 2)) + train.prior_chi2(nom) for nom, eff in points]
    order = np.argsort(chi2, kind="stable")
    best = int(order[0])
    out = [best]
    if e.name == ANISO and PLATE_BOTH_SIDES:
        ratio = [eff.as_dict()[e.name][p.name] for _, eff in points]
        other = [int(i) for i in order if (ratio[int(i)] > 1.0) != (ratio[best] > 1.0)]
        out += other[:1]
    return [(points[i][0], points[i][1].as_dict()[e.name]) for i in out]


def third_starts(ended: dict, baselines: dict) -> dict:
    """The joint hypotheses to fit a third time: those whose best start ended at or above their baseline's
    training chi^2, which a converged fit containing the baseline cannot. ``ended``: hypothesis -> training
    chi^2 of its best start; ``baselines``: hypothesis -> (chi^2, nominal values, where in words, ...). Returns
    hypothesis -> (the baseline's nominal values, where in words), the third start's nominal values."""
    return {name: baselines[name][1:3] for name, chi2 in ended.items() if chi2 >= baselines[name][0]}


def plate_third_start(train: Problem, nom: dict, e: Effect, ended=()) -> dict:
    """A plate hypothesis's effect values for its third start at ``nom`` (the end of its baseline): whichever of
    its null, its grid values (``PLATE_GRIDS``) and the values its earlier starts ended at (``ended``) fits
    training best there (one model run each, side by side). Started at the null, the fit can only end below
    the baseline's start."""
    (p,) = e.params
    candidates = [e.null()] + [{p.name: r} for r in PLATE_GRIDS[e.name][1]]
    candidates += [dict(v) for v in ended if dict(v) not in candidates]
    points = [(EffectSet.of({e.name: c}), nom) for c in candidates]
    train.prefetch(points)
    chi2 = [float(np.sum(train.vector_with(nom, eff) ** 2)) for eff, _ in points]
    return candidates[int(np.argmin(chi2))]


# True: the odd trials train and the even ones are held out, the other way round from the rule's split (a
# counterfactual for the stress suite's --swapped-split, run apart with --tag: does what is named depend on
# which half of the trials is held out?)
SPLIT_SWAPPED = False


@dataclasses.dataclass(frozen=True)
class TiltStage:
    """The plate-tilt stage: the model-free drift test, the tilt fitted to a significant drift (``drift.
    fit_tilt``'s result, as it returned it), the decision on it (None where nothing was fitted), its runs."""

    drift: dict  # the model-free drift test
    fit: dict | None  # the tilt fitted to a significant drift
    runs: int  # model runs it took
    decision: "TiltDecision | None" = None

    @property
    def tilt(self) -> dict | None:
        """The fit with the decision's readings beside it (report.json's ``tilt_fit``)."""
        if self.fit is None:
            return None
        return {**self.fit, **(self.decision.as_dict() if self.decision is not None else {})}


@dataclasses.dataclass(frozen=True)
class FinalGuard:
    """The invariant on the final model (``policy``): its held-out error ended above the nominal fit's (the
    preset model's without one), so the effects it had added were dropped."""

    final_err_heldout: float
    nominal_err_heldout: float
    dropped: tuple[str, ...]

    def as_dict(self) -> dict:
        return {"final_err_heldout": self.final_err_heldout, "nominal_err_heldout": self.nominal_err_heldout,
                "dropped": list(self.dropped)}


@dataclasses.dataclass(frozen=True)
class TiltDecision:
    """What decides a fitted tilt (``policy.tilt_accepted``): its z^2 from zero, whether the gaits' drifts
    point one way, whether the gate reads the drift beyond the model's own on a level plate (the model drags
    its arms on the plate or holds an anisotropic plate), whether that drift follows the robot's own step,
    and the verdict."""

    z2: float
    one_direction: bool
    gate_beyond_model: bool
    follows_the_robot: bool
    accepted: bool
    refused: str | None = None  # the invariant that took an accepted tilt out again (policy.RAISES_HELDOUT)

    def as_dict(self) -> dict:
        return {"z2": self.z2, "one_direction": self.one_direction, "gate_beyond_model": self.gate_beyond_model,
                "follows_the_robot": self.follows_the_robot, "accepted": self.accepted,
                **({"refused": self.refused} if self.refused else {})}


@dataclasses.dataclass(frozen=True)
class TiltHeldout:
    """What the tilt named from the drift does to the held-out trials: their error with the model as it
    stood before the tilt stage and with the tilt added (the same nominal values and effects otherwise).

    The tilt is named without the model (the drift test) and sized by the model's drift per degree, so no
    held-out rule decides it. Where it raises the held-out error the drift is real but the model's tilt does
    not carry it to other trials. Reported, used by no rule."""

    without: float  # held-out error before the tilt (1 = measurement noise)
    with_tilt: float  # and with it

    @property
    def rose(self) -> bool:
        return self.with_tilt > self.without

    @property
    def gain(self) -> float:
        """Relative held-out gain of the tilt (negative where it rose)."""
        return 1.0 - self.with_tilt / self.without if self.without > 0 else float("nan")

    def as_dict(self) -> dict:
        return {"without": self.without, "with_tilt": self.with_tilt, "rose": self.rose, "gain": self.gain}


def tilt_stage(trials: list[Trial], train: Problem, model: Model, say, drift: dict | None = None) -> TiltStage:
    """A tilted plate: tested without the model (plate-frame drift with the body-frame step taken out,
    calibrate.drift) on every trial (``drift``: that test, if already run), fitted by the model's linear
    response to a small tilt."""
    drift = drift_test(trials) if drift is None else drift
    say(f"plate-frame drift: chi2 {drift['chi2']:.1f} on {drift['dof']} dof, p = {drift['p']:.2g}")
    if not drift["significant"]:
        return TiltStage(drift, None, 0)
    nom_now, base_now = dict(train.nominal), dict(model.base)

    def run_model(tx, ty):
        eff = EffectSet.of({**base_now, "plate_tilt": {"tilt_x_deg": tx, "tilt_y_deg": ty}})
        return simulate_trials(trials, scene_for=lambda tr: eff.scene(apply_nominal(tr.params, nom_now)),
                               phase_for=lambda tr: eff.phases(tr.robots, tr.periods))

    tilt = fit_tilt(trials, run_model)
    for g in tilt.get("uphill_groups", []):
        say(f"  the model robot drifts uphill on a tilted plate at {g['amplitude_deg']:g} deg {g['chirality']}: "
            "that gait does not size the tilt")
    for g in (tilt.get("discrepancy") or {}).get("per_group", []):
        say(f"  model drift per degree of tilt at {g['amplitude_deg']:g} deg {g['chirality']}: "
            f"{np.round(g['response_mm_per_deg'], 4).tolist()} mm/cycle"
            + (f"; this gait alone: {np.round(g['tilt_deg'], 2).tolist()} deg" if g.get("tilt_deg") else ""))
    if not tilt.get("ok") and tilt.get("uphill_groups"):
        say("  plate_tilt not fitted: in no gait does the model robot drift downhill")
    if not tilt.get("ok"):
        return TiltStage(drift, tilt, 3)
    t_vec = np.array(tilt["tilt_deg"])
    z2 = float(t_vec @ np.linalg.solve(np.diag(np.square(tilt["se_deg"])), t_vec))
    one_direction = bool(drift["directions"]["consistent"])
    # a plate slipperier along one axis, or a grip that depends on the robot's heading, drifts with each
    # gait's own step (calibrate.drift.PlateDrift): the tilt's gate (policy.tilt_accepted)
    # where the model already drags its arms on the plate or holds an anisotropic plate, its own drift on a
    # level plate follows the robot's step, and the gate reads the drift the model leaves. That drift is
    # stopped only where one drift vector does not fit it
    # (p < P_ONE_VECTOR) and one anisotropy fits it better: the model already holds a step-following
    # drift, so a step-following rest must show. Elsewhere the data's own reading, as before.
    beyond = ARM_PLATE in model.base or ANISO in model.base
    read = tilt["plate_models_beyond_model"] if beyond else drift["plate_models"]
    follows = follows_the_robot(read, beyond)
    if beyond:
        say(f"  the drift beyond the model's on a level plate: one drift vector chi2 {read['chi2_one_vector']:.1f}"
            f" (p {read['p_one_vector']:.2g}), one anisotropy of the robot's step {read['chi2_anisotropy']:.1f}"
            f" (the data's own: {drift['plate_models']['chi2_one_vector']:.1f} and "
            f"{drift['plate_models']['chi2_anisotropy']:.1f})")
    accepted = tilt_accepted(tilt, z2, one_direction, follows)
    decision = TiltDecision(z2, one_direction, beyond, follows, accepted)
    say(f"  plate_tilt from the drift: {t_vec.round(2).tolist()} deg, accepted: {accepted}"
        + ("" if one_direction else
           f" (the gaits' drifts point up to {drift['directions']['max_angle_deg']:.0f} deg apart: "
           "a plate not level in another way)")
        + ("" if not follows else
           " (the gaits' drifts" + (" beyond the model's" if beyond else "")
           + " follow the robot's own step, as on a plate slipperier along one axis, not "
           f"one drift vector as a tilt's: chi2 {read['chi2_anisotropy']:.1f} against "
           f"{read['chi2_one_vector']:.1f})"))
    if accepted:
        vals = {"tilt_x_deg": float(t_vec[0]), "tilt_y_deg": float(t_vec[1])}
        model.add(BY_NAME["plate_tilt"], vals, tilt["interval"])
        model.base = {**model.base, "plate_tilt": vals}
        model.fixed["plate_tilt"] = vals
        say("added plate_tilt (plate-frame drift)")
    return TiltStage(drift, tilt, 3, decision)


@dataclasses.dataclass(frozen=True)
class NoiseStage:
    """The tracking-noise stage: whether it applies (``tracking_noise`` is in the library and the test read some
    trial), the test's reading (None where the effect is not in the library) and why it does not apply."""

    applies: bool
    reading: NoiseReading | None
    reason: str | None = None

    def as_dict(self) -> dict:
        if self.reading is None:
            return {"applies": self.applies, "reason": self.reason}
        return {**self.reading.as_dict(), "applies": self.applies}


def noise_stage(trials: list[Trial], train: Problem, test: Problem, library, model: Model, say) -> NoiseStage:
    """Tracking noise, measured without the model (third differences of the tracks, calibrate.noise) before
    any fit: where present, added at the measured level and held there, and every model's frame increments
    are compared with the data's with it (the nominal fit's included). ``applies``: the test read some
    trial (a gait period of enough frames) and ``tracking_noise`` is in the library."""
    if "tracking_noise" not in {e.name for e in library}:
        return NoiseStage(False, None, "tracking_noise is not in the library")
    nt = noise_test(trials)
    stage = NoiseStage(bool(nt.trials), nt)
    if not stage.applies:
        say(f"tracking noise: {nt.reason}")
        return stage
    say(f"tracking noise (third differences, {len(nt.trials)} trials): "
        f"{nt.xy.level:.3f} [{nt.xy.lo:.3f}, {nt.xy.hi:.3f}] mm, "
        f"{nt.theta.level:.3f} [{nt.theta.lo:.3f}, {nt.theta.hi:.3f}] deg: "
        + ("present" if nt.present else "above a good tracker's resolution but not white (the robot's motion)"
           if any(getattr(nt, k).lo > nt.threshold[k] for k in ("xy", "theta")) else "within a good tracker's resolution"))
    if nt.present:
        values, interval = noise_values(nt)
        model.add(BY_NAME["tracking_noise"], values, interval)
        model.base = {**model.base, "tracking_noise": values}
        model.fixed["tracking_noise"] = values
        train.noise = test.noise = (values["noise_xy_mm"], values["noise_theta_deg"])
        say("added tracking_noise (third differences of the tracks)")
    return stage


@dataclasses.dataclass(frozen=True)
class Tried:
    """One candidate effect fitted in a round (with the effects already chosen) and judged (``policy.judge``)."""

    effect: str
    values: dict
    interval: dict
    err_train: float
    err_heldout: float
    heldout_gain: float
    bic_gain: float
    params: int
    present: bool
    accepted: bool

    def as_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


@dataclasses.dataclass(frozen=True)
class Round:
    """One round: the remaining effects ranked by their signatures (``fit.signatures`` rows), the candidates
    fitted, and the one added (None: none was accepted, the rounds end)."""

    ranking: tuple[dict, ...]
    tried: tuple[Tried, ...]
    accepted: str | None

    def as_dict(self) -> dict:
        return {"ranking": list(self.ranking), "tried": [t.as_dict() for t in self.tried], "accepted": self.accepted}


def rounds_stage(train: Problem, test: Problem, library, model: Model, current: dict, say) -> tuple[Round, ...]:
    """Up to ``MAX_EFFECTS`` rounds: rank the remaining effects by their signatures, fit the leaders
    (with the effects already chosen), add the accepted one with the largest held-out gain."""
    rounds = []
    for _ in range(MAX_EFFECTS):
        ranking = signatures(train, model.base, [e for e in library if e not in model.chosen])
        tried, fits = [], {}
        lead = ranking[0]["grid_gain"] if ranking else 0.0
        for row in ranking[:FIT_CANDIDATES]:
            e = BY_NAME[row["effect"]]
            if row["grid_gain"] < max(0.05, MIN_SHARE * lead):
                continue
            f: Fit = fit_effects(train, test, [c for c in model.chosen if c.name not in model.fixed] + [e],
                                 {**model.base, e.name: row["estimate"]}, fixed=model.fixed)
            j = judge(e, f.interval[e.name], current["chi2_train"], f.chi2_train, f.n_train,
                      current["err_heldout"], f.err_heldout)
            fits[e.name] = f
            tried.append(Tried(e.name, f.values, f.interval, f.err_train, f.err_heldout, j.heldout_gain, j.bic_gain,
                               sum(len(BY_NAME[x].params) for x in f.effects), j.present, j.accepted))
            say(f"  {e.name}: held-out error {f.err_heldout:.2f} ({j.heldout_gain:+.0%}), BIC gain {j.bic_gain:.1f}")
        best = max((t for t in tried if t.accepted), key=lambda t: t.heldout_gain, default=None)
        rounds.append(Round(tuple(ranking), tuple(tried), best.effect if best else None))
        if best is None:
            break
        f = fits[best.effect]
        model.chosen.append(BY_NAME[best.effect])
        model.base = f.values
        for name in f.effects:
            model.found[name] = (f.values[name], f.interval[name])
        current = {"err_heldout": f.err_heldout, "chi2_train": f.chi2_train}
        say(f"added {best.effect}")
    return tuple(rounds)


@dataclasses.dataclass(frozen=True)
class Calibration:
    """What the loop found: the fitted model (``effects`` on top of the ``nominal`` values), the verdict, each
    stage's typed result, and the JSON-ready ``summary`` that report.json records (the same results, as
    report.write formats them, with the held-out comparison of ``heldout.compare_heldout`` and the command's
    ``--set`` changes beside).

    Attributes:
      before, after_nominal, after: the model's errors with the preset, the nominal values (with what the
        nominal stage added) and the final model.
      nominal_stage: the nominal parameters and joint hypotheses (None with ``nominal=False``).
      noise: the tracking-noise stage; tilt: the plate-tilt stage; rounds: the effect rounds.
      added: the structural effects added, in order.
    """

    summary: dict
    effects: EffectSet
    nominal: dict
    verdict: str
    before: Errors
    after_nominal: Errors
    after: Errors
    nominal_stage: NominalStage | None
    noise: NoiseStage
    tilt: TiltStage
    rounds: tuple[Round, ...]
    added: tuple[str, ...]


def added_entry(e: Effect, values: dict, interval: dict, statistical: dict | None = None) -> dict:
    """One added effect as the summary reports it: its 95 % interval carries the model's mismatch
    (``discrepancy.py``), the statistical one beside it. ``statistical`` is given where ``interval``
    already carries it (the drift stage's plate tilt, ``drift.py``); the table has no term for a tilt the
    rounds fitted."""
    if statistical is not None:
        total, interval, sds = dict(interval), statistical, {}
    else:
        total = carry(e.name, values, interval)
        sds = {k: log_sd(e.name, k) for k in interval}
    return {"effect": e.name, "title": e.title, "values": values,
            "interval": {k: list(v) for k, v in total.items()},
            "interval_statistical": {k: list(v) for k, v in interval.items()},
            "mismatch_log_sd": sds, "units": {p.name: p.unit for p in e.params},
            "at_bound": at_library_bound(e, values)}


def at_library_bound(e: Effect, values: dict) -> list:
    """The parameters of ``e`` whose value lies on one of the library's bounds (within 1 % of the fit's
    unit range) away from the effect's null: the data want at least that much, and the interval is
    one-sided (``nominal.fit_nominal``)."""
    return [p.name for p in e.params if p.name in values and math.isfinite(values[p.name])
            and on_bound_away_from_null(p, value_to_unit(p, values[p.name]))]


def calibrate(trials: list[Trial], library: tuple[Effect, ...] = LIBRARY, on_step: Callable | None = None,
              nominal: bool = True, structural: bool = True,
              plate_hypotheses: tuple[str, ...] = PLATE_HYPOTHESES) -> Calibration:
    """The whole loop: conventions -> nominal parameters -> plate tilt -> ranked diagnosis -> fit ->
    selection -> observables. ``structural`` False: the nominal parameters alone (no effect is tried;
    what a data set's clean twin is calibrated with in the stress suite). ``plate_hypotheses``: the plate
    effects fitted jointly with the nominal parameters from a grid start (``PLATE_GRIDS``; default the
    anisotropic plate; ``arm_plate_contact`` may be added), left out of the rounds."""
    plate_hypotheses_with(plate_hypotheses)  # every name has a grid
    if not structural:
        library = ()
    say = on_step or (lambda msg: None)
    # is an arm read off its commanded corners by a constant? Read off the arms' rests before anything else
    # (calibrate.armoffset): outside the library, so reported as unexplained, and taken
    # out of the arm tracks, where it would add itself to every arm residual of every fit
    aoff = read_offsets(trials)
    if aoff.present:
        say(f"arm offset (model-free): {aoff.describe()}: outside the library, taken out of the arm tracks")
        trials = without_offsets(trials, aoff)
    train_t, test_t = split(trials)
    if SPLIT_SWAPPED:  # the counterfactual: odd trials train, even held out
        train_t, test_t = test_t, train_t
    train, test = Problem(train_t), Problem(test_t)
    train.priors = priors(trials)  # measured values: priors of the nominal fit
    if all(m.arms is None and m.in_contact for m in train.meas + test.meas):
        raise ValueError("nothing to compare: no arm angles are tracked and in every trial the robots come within "
                         f"{CONTACT_W} W of each other, where body motion is chaotic and not compared")
    null = EffectSet()
    before = errors(train, test, null)
    say(f"preset model: held-out error {before.err_heldout:.2f}")
    conv = conventions(train)
    if conv.get("warning"):
        say(conv["warning"])
    model = Model()
    noise = noise_stage(trials, train, test, library, model, say)
    if noise.applies:  # measured without the model: the rounds do not fit it again
        library = tuple(e for e in library if e.name != "tracking_noise")
    # is there a phase offset between the robots? Read off their own curves before any fit: where it is absent,
    # no fit tries one (a model fit names the model's mismatch between two robots' trials an offset)
    otest = offset_test(train.trials) if max(tr.robots for tr in trials) > 1 else None
    if otest is not None and otest.applicable:
        say(f"phase offset on the robots' own {otest.read_from}: {otest.mean:+.4f} +- {otest.se:.4f} periods "
            f"({otest.n} pairs): " + ("present" if otest.present else "absent, not fitted"))
    if otest is not None and otest.present:
        # a timing between robots of one build, measured: held there in every joint fit of the offset, which
        # the model's mismatch would bend (it sized offsets 0.5-0.8x on development sets; as a prior of the
        # measured width, 0.84x on one of them)
        train.effect_fixed = {"phase_offset": (otest.mean, otest.interval)}
    # do the arms drag on the plate? Read off the body's heading between the kicks of each swing, before any
    # fit: where they do, the arm-plate friction is fitted jointly with the nominal parameters; where they do
    # not, no fit tries it
    dtest = drag_test(train.trials)
    plate_hypotheses, library, drag_action = drag_plan(dtest, tuple(plate_hypotheses), library)
    # is the plate other than level and isotropic at all? The plate-frame drift, read before any fit: where it
    # reads the trials and finds none, no fit tries an anisotropic plate
    drift = drift_test(trials)
    aniso_asked = ANISO in {e.name for e in library}
    plate_skip = plate_skip_reason(drift) if aniso_asked else None
    if plate_skip:
        say(f"anisotropic plate not tried: {plate_skip}")
        plate_hypotheses = tuple(h for h in plate_hypotheses if h != ANISO)
        library = tuple(e for e in library if e.name != ANISO)
    if dtest is not None and dtest.applicable:
        say(f"arms on the plate, from the body's turning between kicks: {dtest.rate_deg_s:.2f} deg/s "
            f"(p {dtest.p:.2g}, {dtest.groups} quarters' kinds): {drag_action}")
    nom = (nominal_stage(train, test, trials, library, model, say, tuple(plate_hypotheses), otest, dtest) if nominal
           else None)
    if nom and plate_skip:
        nom = dataclasses.replace(nom, hypotheses=nom.hypotheses + (Hypothesis.skipped(ANISO, plate_skip),))
    if nominal:  # the library's effects that rescale a fitted nominal parameter would fit it twice
        library = tuple(e for e in library if e.name not in NOMINAL_EFFECTS and e.name not in SERVO_HYPOTHESES
                        and e.name not in plate_hypotheses
                        and e not in model.chosen)
    if max(tr.robots for tr in trials) == 1 or (otest is not None and otest.applicable):
        # no second robot; or the offset was read off the robots' curves: none to fit, or one held at its
        # reading and judged by the nominal stage
        library = tuple(e for e in library if e.name != "phase_offset")
    before_tilt = None  # the held-out error of the model as it stood, where the tilt stage adds a tilt
    if "plate_tilt" in {e.name for e in library}:
        base_before = dict(model.base)
        library_with_tilt = library
        tilt = tilt_stage(trials, train, model, say, drift)
        if "plate_tilt" in model.fixed and "plate_tilt" not in base_before:
            before_tilt = test.error(EffectSet.of(base_before))
        library = tuple(x for x in library if not (x.name == "plate_tilt" and "plate_tilt" in model.fixed))
    else:
        tilt = TiltStage(drift, None, 0)
    after_nominal = nom.errors if nom else before  # the nominal parameters alone, or the preset
    v = train.vector(EffectSet.of(model.base))
    # the rounds' baseline is the model as it stands: the nominal parameters with what the nominal stage and
    # the tilt stage added (the nominal parameters alone would credit a round with a joint hypothesis's gain)
    current = {"err_heldout": test.error(EffectSet.of(model.base)), "chi2_train": float(v @ v)}
    tilt_heldout = None if before_tilt is None else TiltHeldout(before_tilt, current["err_heldout"])
    if tilt_heldout is not None:
        say(f"  held-out error {tilt_heldout.without:.3g} -> {tilt_heldout.with_tilt:.3g} with the tilt"
            + (" (it rose: the model's tilt does not carry the drift to the held-out trials; not kept, as no "
               "effect that raises the held-out error is)" if tilt_heldout.rose else ""))
    if tilt_heldout is not None and tilt_heldout.rose:  # policy's invariant: whatever test proposed it
        model.drop("plate_tilt")
        tilt = dataclasses.replace(tilt, decision=dataclasses.replace(tilt.decision, accepted=False,
                                                                      refused=policy.RAISES_HELDOUT))
        library = library_with_tilt  # the rounds may fit a tilt and judge it held out, as any effect
        v = train.vector(EffectSet.of(model.base))
        current = {"err_heldout": test.error(EffectSet.of(model.base)), "chi2_train": float(v @ v)}
    rounds = rounds_stage(train, test, library, model, current, say)
    final = EffectSet.of(model.base)
    after = errors(train, test, final)
    guard = None
    if model.chosen and after.err_heldout > after_nominal.err_heldout:
        # policy's invariant: the final held-out error is never above the nominal fit's (the preset's without one)
        guard = FinalGuard(after.err_heldout, after_nominal.err_heldout, tuple(e.name for e in model.chosen))
        say(f"the final held-out error {after.err_heldout:.3g} is above the "
            f"{'nominal fit' if nom else 'preset model'}'s {after_nominal.err_heldout:.3g}: "
            f"{', '.join(guard.dropped)} not kept")
        for name in guard.dropped:
            model.drop(name)
        train.nominal = test.nominal = dict(nom.start) if nom else dict(train.nominal)
        train.effect_fixed = {}
        final = EffectSet.of(model.base)
        after = errors(train, test, final)
    # what the fitted values mean on the tracks: arm delay, phase lead, plate drift of the data and of the
    # model at each stage, and of the final model without each added effect (that effect's share)
    stages = {"preset": ({}, null)}
    if nom:
        stages["nominal"] = (nom.start, null)
    stages["final"] = (dict(train.nominal), final)
    for e in model.chosen:
        stages[f"without {e.name}"] = (dict(train.nominal),
                                       EffectSet.of({k: x for k, x in model.base.items() if k != e.name}))
    runs_before = train.runs + test.runs
    obs = observable_stages(train, test, trials, stages)
    say(f"observables of the data and of {len(stages)} model stages ({train.runs + test.runs - runs_before} more runs)")
    nominal_fit = nom.fit if nom else None

    def measured_interval(name: str) -> dict | None:
        """The statistical interval of an effect sized without the model's fit, whose reported interval
        already is what was measured (no mismatch term): the drift stage's tilt, an offset held at its
        reading; None for a fitted effect."""
        if name == "plate_tilt" and "plate_tilt" in model.fixed:
            return (tilt.tilt or {}).get("interval_statistical")
        if name == "phase_offset" and "phase_offset" in train.effect_fixed:
            return model.found[name][1]
        return None

    answer = verdict(after.err_heldout, model.chosen, aoff)
    summary = {
        "trials": {"train": [t.name for t in train_t], "heldout": [t.name for t in test_t]},
        "conventions": conv, "nominal": nominal_fit.as_dict() if nominal_fit else None,
        "nominal_findings": nominal_findings(nominal_fit) if nominal_fit else [],
        "measured": {k: list(v) for k, v in train.priors.items()},
        "before": before.as_dict(), "after_nominal": after_nominal.as_dict(), "after": after.as_dict(),
        "rounds": [r.as_dict() for r in rounds],
        "nominal_hypotheses": [h.as_json() for h in nom.hypotheses] if nom else [],
        "plate_hypotheses": list(plate_hypotheses),
        "delay_test": nom.delay.as_dict() if nom else None,
        "offset_test": otest.as_dict() if otest is not None else None,
        "arm_offset": {**aoff.as_dict(), "taken_out": bool(aoff.present)},
        "drag_test": ({**dtest.as_dict(), "action": drag_action} if dtest is not None and dtest.applicable
                      else None),
        "rise_test": ({**nom.rise.as_dict(), "reading": servo_reading(nom.rise)} if nom and nom.rise else None),
        "added": [added_entry(e, *model.found[e.name], statistical=measured_interval(e.name))
                  for e in model.chosen],
        "verdict": answer, "model_runs": train.runs + test.runs + tilt.runs,
        "drift": {**tilt.drift, "tilt_fit": tilt.tilt,
                  "tilt_heldout": tilt_heldout.as_dict() if tilt_heldout is not None else None},
        "noise_test": noise.as_dict(), "observables": obs,
        **({"final_guard": guard.as_dict()} if guard is not None else {}),
        "plate_level": {"p": drift["p"], "dof": drift["dof"], "threshold_p": policy.P_LEVEL,
                        "anisotropic_plate_tried": aniso_asked and plate_skip is None, "reason": plate_skip},
        "criteria": {"min_heldout_gain": MIN_HELDOUT_GAIN, "unexplained_error": UNEXPLAINED,
                     "bic": "chi2 drop > k ln n on training trials"},
        "numerics": sorted({(t.params.integrator, t.params.timestep) for t in trials})}
    return Calibration(summary, final, dict(train.nominal), answer, before, after_nominal, after, nom, noise, tilt,
                       rounds, tuple(e.name for e in model.chosen))
