"""The validation page: the paper's claims, each measured from studies in sweeps/.

``smx validate --data DIR --out docs/validation.md`` runs (or reuses, or resumes) one store per study
in ``DIR/<model>/`` (:mod:`smarticle_mjx.studies`), simulates lone robots, gathers each claim's
evidence from the stores (:mod:`.evidence`), judges every claim of the registry (:mod:`.claims`: each
states its test before the number is known; a claim that fails is reported as failing) and writes
the page with its figures (:mod:`.page`).
"""

from __future__ import annotations

import pathlib

import numpy as np

from .. import presets
from ..plots import check_out_dir
from ..scene import SceneParams
from ..specs import ScanConfig
from ..studyfile import read_study
from ..suite import DEFAULT_SUITE, STUDIES, SWEEPS, suite as suite_studies
from ..studies import ensure
from . import evidence, page
from .claims import CLAIMS, Validation
from .inputs import LoneTracks

SINGLE_AMPLITUDES = (10, 20, 30, 40, 50, 60, 70, 80, 90)
SINGLE_PERIODS = 75

__all__ = ["CLAIMS", "STUDIES", "SWEEPS", "evaluate", "run_validation", "single_robots"]


LONE_ROBOTS_DRAWN = 8  # lone robots per amplitude when the robots have imperfections (one each otherwise)


def single_robots(params: SceneParams, amplitudes=SINGLE_AMPLITUDES, periods: int = SINGLE_PERIODS,
                  imperfections: str = "none", seed: int = 0) -> dict[float, LoneTracks]:
    """Lone robots, one per amplitude (:class:`.inputs.LoneTracks`): per-period positions (W) and headings. With ``imperfections``,
    :data:`LONE_ROBOTS_DRAWN` robots drawn from that set (``seed``) per amplitude, each alone on the
    plate: ``xy`` [R, T+1, 2] and ``heading`` [R, T+1]."""
    from .. import imperfections as imp
    from ..engine.simulate import simulate
    from ..gait import GaitSpec
    ideal = imp.get(imperfections).ideal
    n = 1 if ideal else LONE_ROBOTS_DRAWN
    draw = imp.draw(imperfections, n, seed)
    out = {}
    for a in amplitudes:
        g = GaitSpec(amplitude_deg=float(a))
        a0 = g.setpoints(0.0, params.robot.servo_speed)
        xy, heading = [], []
        for i in range(n):
            robot = None if ideal else draw.robot(i)
            p = params if robot is None else robot.scene(params)
            res = simulate(p, [[0.0, 0.0, 0.0, float(a0[0]), float(a0[1])]], g, periods, imperfections=robot)
            xy.append(res.poses[:, 0, :2] / params.robot.body_length)
            heading.append(res.poses[:, 0, 2])
        out[float(a)] = LoneTracks(xy[0] if ideal else np.stack(xy), heading[0] if ideal else np.stack(heading),
                                   res.period)
    return out


def evaluate(stores: dict, singles: dict, figures: pathlib.Path, specs: dict | None = None,
             extra: dict | None = None, reading=None, claims=None, suite: str = "small") -> Validation:
    """Every claim's row (of ``claims``; None: all of them) from the stores there are (figures drawn into
    ``figures``); ``extra``: entries added to the numbers behind the rows (notes, the robots' set);
    ``reading``: the relaxation's emergence reading (reduce.emergence; None: the primary one)."""
    claims = CLAIMS if claims is None else claims
    ev, numbers, made = evidence.gather(stores, singles, figures, specs, reading, claims)
    return Validation(tuple(c.row(ev.get(c.key), stores, suite) for c in claims), {**numbers, **(extra or {})},
                      tuple(made))


def paper_claims(studies: dict) -> list:
    """The claims a suite of ``studies`` judges: those measured from studies alone, all among them."""
    return [c for c in CLAIMS if c.studies and set(c.studies) <= set(studies)]


def parse_studies(text: str | None, suite: str | None = None) -> list[str] | None:
    """'random_90, relax' -> the named studies of suite ``suite`` (None: all); ValueError naming the unknown
    ones (or an unknown suite)."""
    known = suite_studies(suite)
    if text is None:
        return None
    chosen = [x.strip() for x in text.split(",") if x.strip()]
    bad = [x for x in chosen if x not in known]
    if bad or not chosen:
        raise ValueError(f"--studies: unknown {', '.join(bad) or '(none given)'}; known: {', '.join(known)}")
    return chosen


def check_inputs(data, out_md, sweeps, single_periods: int, studies=None, suite: str | None = None) -> None:
    """ValueError, before anything runs, for an unknown suite, missing study files, unknown studies or
    unusable paths."""
    known = suite_studies(suite)
    data, out_md, sweeps = pathlib.Path(data), pathlib.Path(out_md), pathlib.Path(sweeps)
    missing = [f for f in known.values() if not (sweeps / f).is_file()]
    if missing:
        raise ValueError(f"study files missing in {sweeps}: {', '.join(missing)}")
    unknown = [s_ for s_ in (studies or []) if s_ not in known]
    if unknown:
        raise ValueError(f"unknown studies {unknown}; known: {', '.join(known)}")
    if not out_md.parent.is_dir():
        raise ValueError(f"output directory {out_md.parent} does not exist")
    check_out_dir(data)
    if single_periods < 2:
        raise ValueError("--single-periods must be >= 2")


def data_folder(data, model: str, imperfections: str = "none", overrides=()) -> pathlib.Path:
    """Where ``run_validation`` keeps a page's stores: ``data/<model>[+<set>][~<field>=<value>...]``."""
    from .. import imperfections as imp
    label = model if imp.get(imperfections).ideal else f"{model}+{imperfections}"
    return pathlib.Path(data) / (label + "".join(f"~{k}={v}" for k, v in presets.overrides(overrides)))


def run_validation(data: pathlib.Path, out_md: pathlib.Path, sweeps: pathlib.Path = SWEEPS,
                   model: str = presets.DEFAULT, on_progress=None, command: str | None = None,
                   single_periods: int = SINGLE_PERIODS, studies: list[str] | None = None,
                   imperfections: str = "none", overrides=(), reading=None, suite: str | None = None) -> Validation:
    """Run or reuse the studies of suite ``suite`` (``suite.SUITES``; None: the small one; all its studies,
    or those named in ``studies``) with model preset ``model`` in ``data/<model>/``, measure every claim
    of that suite from the complete stores there are, write the page.

    The small suite's page judges every claim (lone robots simulated beside the studies); the paper
    suite's page (:func:`.page.write_paper_page`) judges the basin-scan claims, those whose studies are all
    among its own, and adds the rebinding of pairs that came apart.

    ``imperfections``: run every study with the robots' imperfections of that set (drawn from each
    study's seed; smarticle_mjx/imperfections.py), in ``data/<model>+<set>/``. ``overrides``: scene
    fields changed in every study and lone robot (``--set``; a step, say), in
    ``data/<model>[+<set>]~<field>=<value>.../``. ``reading``: the relaxation's emergence reading the
    page judges (reduce.emergence: apart, touch, moved or pair; None: pair, the primary one)."""
    from .. import imperfections as imp
    from ..reduce.emergence import parse_reading
    reading = parse_reading(reading)
    overrides = presets.overrides(overrides)
    check_inputs(data, out_md, sweeps, single_periods, studies, suite)
    known = suite_studies(suite)
    ideal = imp.get(imperfections).ideal
    params = presets.apply(presets.params(model), overrides)
    data = data_folder(data, model, imperfections, overrides)
    data.mkdir(parents=True, exist_ok=True)
    wanted = list(known) if studies is None else list(studies)
    specs = {name: read_study(sweeps / f) for name, f in known.items()}
    stores: dict = {}
    notes: list[str] = []
    for name, spec in specs.items():
        got = ensure(spec, data, pathlib.Path(known[name]).stem, model,
                     {k: (v if isinstance(v, list) else [v]) for k, v in stores.items()}, on_progress, notes,
                     run=name in wanted, imperfections=imperfections, overrides=overrides)
        if got:
            # a scan is one store; a staged study (started-bound, relaxation) a list of them
            stores[name] = got[0] if isinstance(spec, ScanConfig) else got
    figures = out_md.parent / out_md.stem
    suite = DEFAULT_SUITE if suite is None else suite
    if suite != DEFAULT_SUITE:
        result = evaluate(stores, {}, figures, specs, {"notes": notes, "suite": suite}, reading,
                          claims=paper_claims(known), suite=suite)
        page.write_paper_page(result, stores, out_md, figures, command or page.relative_command(
            pathlib.Path(data).parent, out_md, model, imperfections=imperfections, overrides=overrides,
            reading=reading, suite=suite), model, specs, imperfections=imperfections, overrides=overrides)
        return result
    singles = single_robots(params, periods=single_periods, imperfections=imperfections)
    result = evaluate(stores, singles, figures, specs,
                      {"notes": notes, **({} if ideal else {"imperfections": {
                          "set": imperfections, "lone_robots_per_amplitude": LONE_ROBOTS_DRAWN}})}, reading)
    page.write_page(result, stores, out_md, figures,
                    command or page.relative_command(pathlib.Path(data).parent, out_md, model, imperfections=imperfections,
                                                     overrides=overrides, reading=reading),
                    model, imperfections=imperfections, overrides=overrides)
    return result
