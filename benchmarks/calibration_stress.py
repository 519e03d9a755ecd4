"""A stress suite for ``smx calibrate`` that the calibration code did not write: data sets drawn at random
from the independent simulator, each calibrated as a user would, and scored by rules fixed before any
calibration rule was tuned against them. What a set draws and how it is scored: the docstring of
smarticle_mjx/calibrate/stress.py, where the generator and the scoring live.

Resumable set by set: each set's result is one JSON file under results/calibration_stress/<suite seed>/;
a set computed with another generator or scoring (their source hashes are stored) is run again.

    python benchmarks/calibration_stress.py --sets 0-59                  # the reported suite (seed 2026)
    python benchmarks/calibration_stress.py --suite-seed 7 --sets 0-9    # development seeds
    python benchmarks/calibration_stress.py --summary                    # tables of what is stored
    python benchmarks/calibration_stress.py --sets 5,9 --tag rerun       # reported sets again, kept apart
    python benchmarks/calibration_stress.py --suite-seed 2043 --sets 11 --plate-hypothesis arm_plate_contact \
        --tag armplate                                                   # arms on the plate fitted jointly
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import numpy as np

from smarticle_mjx.calibrate.fit import PLATE_HYPOTHESES
from smarticle_mjx.calibrate.stages import plate_hypotheses_with
# the generator, its scoring and the set runner live in the package (smarticle_mjx/calibrate/stress.py)
from smarticle_mjx.calibrate.stress import (
    COUNTERFACTUALS, apply_counterfactual, condition_table, confusion, coverage, draw_set, effect_table,
    source_hash, speed_table, summarise)
from smarticle_mjx.calibrate.stress import indices as _indices
from smarticle_mjx.calibrate.stress import pooled_rows as _pooled_rows, run_set as _run_set


ROOT = pathlib.Path(__file__).resolve().parent
RESULTS = ROOT / "results"
REPORTED_SEED = 2026  # the suite reported in docs/calibration.md; development used other seeds


def _plain(x):
    """numpy scalars as JSON numbers and booleans."""
    return x.item() if isinstance(x, np.generic) else float(x)


def pooled_rows(seeds: str, results=None) -> list[dict]:
    """Every stored row of the seeds named, from results/ unless ``results`` names another folder."""
    return _pooled_rows(seeds, RESULTS if results is None else results)


def run_set(s: dict, plate_hypotheses: tuple[str, ...] = PLATE_HYPOTHESES, overrides: tuple = ()) -> dict:
    """``calibrate.stress.run_set`` with its progress printed."""
    return _run_set(s, plate_hypotheses, overrides, say=lambda m: print(m, flush=True))


def print_summary(rows: list[dict], summary: dict | None = None) -> None:
    """The summary (``summarise``, unless given) and every table, as a run and ``--summary --pool`` print them."""
    print(json.dumps(summarise(rows) if summary is None else summary, indent=1))
    for table in (confusion, coverage, condition_table, effect_table, speed_table):
        print(table(rows))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite-seed", type=int, default=REPORTED_SEED)
    ap.add_argument("--sets", default="0-59", help="indices, e.g. 0-59 or 0,3,7-9")
    ap.add_argument("--max-minutes", type=float, default=None, help="start no set after this long")
    ap.add_argument("--summary", action="store_true", help="print the tables of what is stored and stop")
    ap.add_argument("--draw-only", action="store_true", help="print what each set hides and stop")
    ap.add_argument("--pool", default=None, metavar="SEEDS",
                    help="with --summary: pool the stored summaries of these whole seeds (e.g. 2049-2051,2058) "
                         "and print their tables instead of one seed's")
    ap.add_argument("--plate-hypothesis", action="append", default=[],
                    help="also fit this plate effect jointly with the nominal parameters (smx calibrate's option)")
    ap.add_argument("--tag", default="", help="keep this run's results apart (calibration_stress/<seed>-<tag>/): "
                                              "sets of a reported seed run again under later rules")
    for flag, text, *_ in COUNTERFACTUALS:
        ap.add_argument(flag, action="store_true", help=f"{text} (for a counterfactual run, with --tag)")
    ap.add_argument("--set", dest="set_", action="append", default=[], metavar="FIELD=VALUE",
                    help="change the library's model as smx calibrate --set does (for the set and its clean twin; "
                         "needs --tag, so that the results stay apart)")
    args = ap.parse_args()
    try:
        sets = _indices(args.sets)
    except ValueError as e:
        ap.error(str(e))
    if args.pool is not None:
        if not args.summary:
            ap.error("--pool needs --summary: it reads stored results and runs nothing")
        try:
            rows = pooled_rows(args.pool)
        except (FileNotFoundError, ValueError) as e:
            ap.error(str(e))
        print(f"{len(rows)} sets of suite seeds {args.pool}, versions "
              f"{', '.join(sorted({r.get('version', '?') for r in rows}))}")
        print_summary(rows)
        return
    from smarticle_mjx import presets
    try:
        overrides = presets.overrides(args.set_)
    except ValueError as e:
        ap.error(str(e))
    if overrides and not args.tag:
        ap.error("--set needs --tag: results made with a changed model are kept apart")
    chosen = [switch for flag, _, *switch in COUNTERFACTUALS if getattr(args, flag[2:].replace("-", "_"))]
    if chosen and not args.tag:
        ap.error("a counterfactual rule needs --tag: its results are kept apart")
    for switch in chosen:
        apply_counterfactual(*switch)
    try:
        plates = plate_hypotheses_with(args.plate_hypothesis)
    except ValueError as e:
        ap.error(str(e))
    name = str(args.suite_seed) + (f"-{args.tag}" if args.tag else "")
    folder = RESULTS / "calibration_stress" / name
    folder.mkdir(parents=True, exist_ok=True)
    src = source_hash()
    t0 = time.perf_counter()
    for i in sets:
        if args.summary:
            break
        s = draw_set(args.suite_seed, i)
        if args.draw_only:
            print(i, s["hidden"], s["outside"], s["truth"], s["amplitudes"], s["frame_rate_hz"], s["arms_tracked"])
            continue
        path = folder / f"set_{i:04d}.json"
        if path.exists() and json.loads(path.read_text()).get("source") == src:
            continue
        if args.max_minutes is not None and time.perf_counter() - t0 > 60 * args.max_minutes:
            print(f"time cap reached; set {i} not run", flush=True)
            break
        print(f"set {i}: hidden {s['hidden']} outside {s['outside']} amplitudes {s['amplitudes']} "
              f"{s['frame_rate_hz']:g} Hz arms {s['arms_tracked']}", flush=True)
        r = run_set(s, plates, overrides)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(r, indent=1, default=_plain))
        tmp.replace(path)
        print(f"  -> added {r['score']['added']} right {r['score']['right']} {r['wall_s']:.0f} s", flush=True)
    if args.draw_only:
        return
    rows = [json.loads(p.read_text()) for p in sorted(folder.glob("set_*.json"))]
    rows = [r for r in rows if r.get("source") == src]
    summary = summarise(rows)
    out = RESULTS / f"calibration_stress_{name}.json"
    out.write_text(json.dumps({"suite_seed": args.suite_seed, "source": src, "summary": summary,
                               "rows": rows}, indent=1, default=_plain))
    print_summary(rows, summary)


if __name__ == "__main__":
    main()
