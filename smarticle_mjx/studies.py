"""The store cache of studies: the complete store that stands for a study's spec, and the one entry point
that runs a study of one store (:func:`run_study`).

Three kinds of study (specs in :mod:`smarticle_mjx.specs`, read from study files by
:func:`smarticle_mjx.studyfile.read_study`):

* a **scan** (random, polar or explicit starts; any ``ScanConfig`` keys) -> :class:`ScanConfig`;
* a **started-bound** study (``configs = "bound"``): pairs started as steady gliders taken from
  another study's store, run at one or several amplitudes -> :class:`BoundStudy`;
* a **relaxation** study (``configs = "relax"``): trials in stages -> :class:`RelaxStudy`.

The ``ensure_*`` functions return the complete store(s) of a study: reused when made with the same
configuration (backend and seed included), model preset and physics version (``store.PHYSICS_VERSION``: a
release that changes no stored number keeps it, so stores survive it; a store that records none, by the same
package version), resumed when interrupted, else run. A store or journal
made otherwise is moved aside (``<stem>.replaced-<created>...``), never deleted, and the study rerun.
Every stage of a staged study is a store of its own, so a killed run resumes where it stopped and a
partial run leaves complete, valid stores.
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
from typing import Callable

import numpy as np

from .reduce import analysis, gliders as GL
from .runner import RelaxSummary, ScanSummary, store_header
from .scan import run_scan
from .scene import params_json, predated_fields
from .specs import BoundStudy, RelaxConfig, RelaxStudy, ScanConfig, config_from_json, with_overrides
from .scene import SceneParams
from .store import Store, data_keys, journal_path, made_by, same_physics

def _stamp(text) -> str:
    return "".join(c for c in str(text) if c.isdigit())[:14] or "unknown"


# keys a spec's JSON omits while they hold their default (ScanConfig/RelaxConfig.to_json): a stored spec
# without one ran at the default, so the wanted spec's value is not filled in for it
_OMITTED = {"scan": ("initial", "imperfections", "overrides"),
            "relax": ("imperfections", "start", "headings", "start_phi", "retrigger_sd", "onset_offset_sd",
                      "onset_cycle", "overrides")}


def _kind(cfg: ScanConfig | RelaxConfig) -> str:
    return "scan" if isinstance(cfg, ScanConfig) else "relax"


def _normalised(config: dict, want: dict, params: SceneParams, kind: str) -> dict:
    """A stored configuration with the keys added since it was written filled in with the values they
    implicitly had (the same rule for scans and relaxations)."""
    have = json.loads(json.dumps(config))
    have.setdefault("model", "paper")  # stores from before presets
    stored = have.get(kind, {})
    have[kind] = {**want[kind], **stored}
    if "model" in want[kind]:
        have[kind]["model"] = have["model"]
    for k in _OMITTED[kind]:
        if k not in stored:
            have[kind].pop(k, None)
    defaults = params_json(params.__class__())
    have["scene"] = {**defaults, **predated_fields(have.get("scene", {})), **have.get("scene", {}),
                     "robot": {**defaults["robot"], **have.get("scene", {}).get("robot", {})}}
    return have


def _recorded(cfg: ScanConfig | RelaxConfig) -> tuple[SceneParams, dict]:
    """The scene parameters (with the drawn robots' quirks) and the configuration a store of study
    ``cfg`` records, as run_scan and run_relax write them (runner.store_header)."""
    params = cfg.robots().scene(cfg.scene_params())
    return params, json.loads(json.dumps(store_header(cfg, _kind(cfg), cfg.model, params)))


def stale_reason(cfg: ScanConfig | RelaxConfig, path: pathlib.Path) -> str | None:
    """Why the complete store at ``path`` cannot stand for study ``cfg`` (a scan or a relaxation stage:
    another model, physics version or configuration), or None if it can. One rule for every kind: what
    the study would write now against what the store holds, keys added since filled in."""
    params, want = _recorded(cfg)
    st = Store(path)
    have = _normalised(st.config, want, params, _kind(cfg))
    if have["model"] != cfg.model:
        return f"made by model {have['model']}"
    if not same_physics(st.attrs):
        return f"made by {made_by(st.attrs)}"
    if have != want:
        return "made from a different study file"
    return None


def _move_aside(path: pathlib.Path, what: pathlib.Path, why: str, created, notes: list | None) -> None:
    """Rename ``what`` (the store at ``path`` or its journal) to
    ``<stem>.replaced-<created>...``, never delete it, and note why."""
    aside = what.with_name(f"{path.stem}.replaced-{_stamp(created)}{what.name[len(path.stem):]}")
    what.rename(aside)
    if notes is not None:
        notes.append(f"{path.name}: {why}; kept as {aside.name} and rerun")


def _check_journal(cfg: ScanConfig | RelaxConfig, path: pathlib.Path, notes: list | None) -> None:
    """Move aside the journal of an interrupted run of study ``cfg`` at ``path`` that another configuration
    or physics version made (the staleness rule of :func:`stale_reason`), so that the study starts anew."""
    journal = journal_path(path)
    if not journal.exists():
        return
    meta = json.loads((journal / "meta.json").read_text()) if (journal / "meta.json").exists() else {}
    params, want = _recorded(cfg)
    if not same_physics(meta) or _normalised(meta.get("config", {}), want, params, _kind(cfg)) != want:
        _move_aside(path, journal, "an interrupted run of another configuration or version", meta.get("created"),
                    notes)
        return
    _adopt(journal, want, params, _kind(cfg), notes)


def _adopt(journal: pathlib.Path, want: dict, params: SceneParams, kind: str, notes: list | None) -> None:
    """Let a journal that the staleness rule calls current be resumed although its configuration was
    written before some key existed: the writer resumes only an identical configuration, so the journal's
    ``config.json`` is rewritten in this version's form (the keys added since, at the values they
    implicitly had) and the one it was started with is kept beside it as ``config.started.json``."""
    saved_path = journal / "config.json"
    if not saved_path.exists():
        return
    saved = json.loads(saved_path.read_text())
    now = json.loads(json.dumps(want))
    kept = {k: v for k, v in saved.items() if k not in now}  # executor keys and the like: not the study's
    if {**now, **kept} == saved or _normalised(data_keys(saved), now, params, kind) != data_keys(now):
        return  # resumable as it is, or another study: the writer refuses it in one line
    first = journal / "config.started.json"
    if not first.exists():
        first.write_text(saved_path.read_text())
    tmp = saved_path.with_name(saved_path.name + ".tmp")
    tmp.write_text(json.dumps({**now, **kept}, indent=1, sort_keys=True))
    tmp.replace(saved_path)
    if notes is not None:
        notes.append(f"{journal.name}: started before some configuration keys existed; resumed with them at "
                     f"the values they had (the original kept as {first.name})")


def adopt_journal(cfg: ScanConfig | RelaxConfig, path: pathlib.Path, notes: list | None = None) -> None:
    """Before ``--resume``: a journal of study ``cfg`` at ``path`` that the staleness rule calls current
    (same physics version, configuration equal once keys added since are filled in) is made resumable
    (:func:`_adopt`); any other journal is left for the writer to refuse in one line."""
    journal = journal_path(path)
    if not (journal / "meta.json").exists():
        return
    meta = json.loads((journal / "meta.json").read_text())
    params, want = _recorded(cfg)
    if same_physics(meta):
        _adopt(journal, want, params, _kind(cfg), notes)


def ensure_scan(cfg: ScanConfig, path: pathlib.Path, on_progress: Callable[[dict], None] | None = None,
                notes: list | None = None, run: bool = True) -> pathlib.Path | None:
    """The complete store of scan ``cfg`` at ``path``: reused if it was made
    with the same configuration, model preset and physics version; resumed
    if interrupted; else run (or, with ``run=False``, None). A store (or
    journal) made otherwise is moved aside, never deleted, and the scan is
    rerun."""
    if path.exists():
        why = stale_reason(cfg, path)
        if why is None:
            return path
        if not run:
            return None
        _move_aside(path, path, why, Store(path).attrs.get("created"), notes)
    elif not run:
        return None
    else:
        _check_journal(cfg, path, notes)
    run_scan(cfg, path, mode="resume" if journal_path(path).exists() else "new", on_progress=on_progress)
    return path


def glider_starts(store: Store, kind: str, pairs: int) -> np.ndarray:
    """[P, 3] (|r|, theta, phi) at the end of the last period of the first
    ``pairs`` lanes (lane order) that end as steady ``kind`` gliders (the glider types alone:
    ``reduce.analysis.glider_types``, with the report's default options)."""
    return _gliders(store, kind, pairs)[0]


def _gliders(store: Store, kind: str, pairs: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`glider_starts` and the lanes they ended in."""
    a = store.analysis_arrays(store.runs[0])
    o = analysis.Options.for_periods(a["periods"])
    types = analysis.glider_types(a["rel"], a["touched"], a["valid"], o.burn_in, o.clusters)
    if types is None:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    lanes = np.flatnonzero(types.final == {"C1": GL.C1, "C2": GL.C2}[kind])[:pairs]
    return a["rel"][lanes, -1].astype(np.float64), lanes


def _source_robots(source: Store, lanes: np.ndarray, imperfections: str) -> dict:
    """Where the source study ran several robot pairs: the stage keywords that start each glider on the
    pair that made it (the source's pool, one pair per start); else none (the study's own seed's pair)."""
    src = config_from_json(source.config["scan"])
    if imperfections == "none" or src.imperfections != imperfections or src.robot_draws == 1:
        return {}
    return {"robot_draws": src.robot_draws, "robot_seed": src.robot_pool().seed,
            "lane_draws": tuple(int(x) for x in src.lane_draw(lanes))}


def ensure_bound(bs: BoundStudy, stem: str, source: pathlib.Path, data: pathlib.Path, model: str,
                 on_progress=None, notes: list | None = None, run: bool = True,
                 imperfections: str = "none", overrides=()) -> list[pathlib.Path]:
    """Run (or reuse, or resume) every stage of a started-bound study; one
    store per amplitude, ``<stem>_aNNNN.h5`` (tenths of a degree). Stops
    early when no pair is left bound to carry on (continuation), or, with
    ``run=False``, at the first stage without a current complete store."""
    src = Store(source)
    starts, lanes = _gliders(src, bs.glider, bs.pairs)
    robots = _source_robots(src, lanes, imperfections)
    paths = []
    for a in bs.amplitudes_deg:
        if len(starts) == 0:
            if notes is not None:
                notes.append(f"{stem}: no {bs.glider} pair left bound before {a:g}°; later stages not run")
            break
        cfg = with_overrides(dataclasses.replace(bs.stage_config(a, starts, model, imperfections), **robots),
                             overrides)
        # amplitude in tenths of a degree: descent_a0900.h5 is 90 deg
        path = ensure_scan(cfg, pathlib.Path(data) / f"{stem}_a{int(round(a * 10)):04d}.h5", on_progress, notes,
                           run=run)
        if path is None:
            break
        paths.append(path)
        if bs.continuation:
            st = Store(path)
            d = st.run(st.runs[0], fields=("touched", "rel", "valid"))
            keep = d["valid"] & d["touched"][:, -bs.keep_window:, 0].all(1)
            starts = d["rel"][keep, -1].astype(np.float64)
            if robots:
                robots["lane_draws"] = tuple(np.asarray(robots["lane_draws"])[keep].tolist())
    return paths


def relax_stage_path(data: pathlib.Path, stem: str, stage: int) -> pathlib.Path:
    """The store of stage ``stage`` of a relaxation study: ``<stem>_sNN.h5``."""
    return pathlib.Path(data) / f"{stem}_s{stage:02d}.h5"


def ensure_relax(rs: RelaxStudy, stem: str, data: pathlib.Path, model: str, on_progress=None,
                 notes: list | None = None, run: bool = True, imperfections: str = "none",
                 overrides=()) -> list[pathlib.Path]:
    """Run (or reuse, or resume) the stages of a relaxation study in order,
    ``<stem>_sNN.h5``; with ``run=False`` stop at the first stage without a
    current complete store. A stage made by another configuration, model or
    physics version is moved aside (never deleted) and rerun."""
    from .relax import run_relax
    paths = []
    for stage in range(rs.stages):
        cfg = with_overrides(rs.stage_config(stage, model, imperfections), overrides)
        path = relax_stage_path(data, stem, stage)
        if path.exists():
            why = stale_reason(cfg, path)
            if why is None:
                paths.append(path)
                continue
            if not run:
                break
            _move_aside(path, path, why, Store(path).attrs.get("created"), notes)
        elif not run:
            break
        else:
            _check_journal(cfg, path, notes)
        run_relax(cfg, path, mode="resume" if journal_path(path).exists() else "new", on_progress=on_progress)
        paths.append(path)
    return paths


def ensure(spec: ScanConfig | BoundStudy | RelaxStudy, data: pathlib.Path, stem: str, model: str,
           sources: dict | None = None, on_progress: Callable[[dict], None] | None = None,
           notes: list | None = None, run: bool = True, imperfections: str = "none",
           overrides=()) -> list[pathlib.Path]:
    """The complete stores of study ``spec`` (file stem ``stem``) made by model ``model`` in ``data``,
    one per stage (a scan has one): reused, resumed or run as :func:`ensure_scan` says; with
    ``run=False`` only those that already stand for it. A started-bound study needs its source's
    stores in ``sources`` (study name -> stores) and returns none without them. ``imperfections``: the
    robots' imperfection set (smarticle_mjx/imperfections.py) every stage is run with, unless a relaxation
    study file names its own; ``overrides``: scene fields changed in every stage (``specs.with_overrides``)."""
    data = pathlib.Path(data)
    if isinstance(spec, RelaxStudy):
        return ensure_relax(spec, stem, data, model, on_progress, notes, run=run, imperfections=imperfections,
                            overrides=overrides)
    if isinstance(spec, BoundStudy):
        src = (sources or {}).get(spec.source)
        return ensure_bound(spec, stem, src[0], data, model, on_progress, notes, run=run,
                            imperfections=imperfections, overrides=overrides) if src else []
    got = ensure_scan(with_overrides(dataclasses.replace(spec, model=model, imperfections=imperfections), overrides),
                      data / f"{stem}.h5", on_progress, notes, run=run)
    return [got] if got is not None else []


def run_study(spec: ScanConfig | RelaxConfig, out, mode: str = "new", executor=None,
              on_progress: Callable[[dict], None] | None = None, **options) -> ScanSummary | RelaxSummary:
    """Run one study spec into the store ``out`` through its runner and ``executor`` (None: this
    machine): a scan or sweep (``scan.run_scan``; ``options``: ``flush_rows``, ``params``) or a
    relaxation (``relax.run_relax``; ``options``: ``params``, ``nthread``). Staged studies
    (:class:`BoundStudy`, :class:`RelaxStudy`) are several stores: :func:`ensure` runs them.

    Raises:
      ValueError: a spec that is not one store's study (one line).
    """
    if mode == "resume" and isinstance(spec, (ScanConfig, RelaxConfig)):
        adopt_journal(spec, pathlib.Path(out))
    if isinstance(spec, ScanConfig):
        return run_scan(spec, out, mode=mode, executor=executor, on_progress=on_progress, **options)
    if isinstance(spec, RelaxConfig):
        from .relax import run_relax
        return run_relax(spec, out, mode=mode, executor=executor, on_progress=on_progress, **options)
    raise ValueError(f"a {type(spec).__name__} is a staged study of several stores; ensure() runs it")


def store_mode(resume: bool, overwrite: bool) -> str:
    """The store's writing mode from the command line's --resume and --overwrite."""
    if resume and overwrite:
        raise ValueError("--resume and --overwrite exclude each other")
    return "resume" if resume else "overwrite" if overwrite else "new"


def summary_lines(summary: ScanSummary | RelaxSummary, out) -> list[str]:
    """What a study's run reports: bound fractions per run (scans) or early stops (relaxations), and speed."""
    speed = (f"wall {summary.wall_s:.1f} s, {summary.steps:,} steps simulated "
             f"({summary.steps_per_s:,.0f} steps/s); wrote {out}")
    if isinstance(summary, RelaxSummary):
        return [f"{summary.trials} trials, {summary.stopped_early} stopped early (no contact for "
                f"{summary.quiet_periods} periods); " + speed]
    return [f"{name}: {r.valid}/{summary.configs} valid configurations, "
            f"bound at the end: {r.bound_end_fraction:.1%}" for name, r in summary.runs.items()] + [speed]
