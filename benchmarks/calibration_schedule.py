"""How much the calibration gains from spreading nested model runs over the cores (version 0.4.11).

Before version 0.4.11 a ``calibrate.sim.pmap`` inside a worker ran its items one after another: the
nominal stage's five joint fits (a lag and a dead time, each from two starts, and the null restarted from
the preset servo) went two at a time on two cores, and the fifth ran alone beside an idle core. Since then
every item of a pmap, nested or not, has its own thread, and each model run holds one core's slot
(``sim.slot``); a point two fits ask for at once is run once (``fit.Problem.model``).

This script calibrates stress-suite sets (benchmarks/calibration_stress.py's draw, data written as the
suite writes them) both ways in one process, alternating which goes first, and prints the wall times and
their ratio. The two calibrations must agree in everything but the count of model runs (every run is the
same computation either way); a set where they do not is reported and the script exits non-zero.

    python benchmarks/calibration_schedule.py --set 2141/4 --set 2140/7

Writes results/calibration_schedule.json.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import tempfile
import time

from smarticle_mjx.calibrate.stress import draw_set, parse_set, write_set
from smarticle_mjx import __version__
from smarticle_mjx.calibrate import sim
from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.stages import calibrate

RESULTS = pathlib.Path(__file__).resolve().parent / "results"  # this folder's results

OUT = RESULTS / "calibration_schedule.json"


def _comparable(summary: dict) -> str:
    """The calibration's summary without its run count (the only thing the schedule may change)."""
    return json.dumps({k: v for k, v in summary.items() if k != "model_runs"}, sort_keys=True, default=str)


def timed(trials, nested: bool) -> tuple[float, dict]:
    was, sim.NESTED = sim.NESTED, nested
    try:
        t = time.perf_counter()
        res = calibrate(trials).summary
        return time.perf_counter() - t, res
    finally:
        sim.NESTED = was


def both_ways(sets, timed):
    """For each (seed, index): the set drawn and written as the stress suite writes it, then calibrated by
    ``timed(trials, way)`` both ways (False, True), the first set the old way first and each next set the
    other way round. Yields ((seed, index), set, trials, order, {way: timed's answer})."""
    for k, (seed, index) in enumerate(sets):
        s = draw_set(seed, index)
        with tempfile.TemporaryDirectory() as d:
            write_set(s, pathlib.Path(d))
            trials = load(pathlib.Path(d), None, ())
        order = (False, True) if k % 2 == 0 else (True, False)
        yield (seed, index), s, trials, order, {way: timed(trials, way) for way in order}


def finish(rows: list[dict], old: str, new: str, out: pathlib.Path) -> int:
    """Totals of both ways' wall times (rows' ``wall_s_<old>``, ``wall_s_<new>``), the JSON written to ``out``
    and a closing line; 0 if every set's two calibrations agreed (``same_result``), else 1."""
    same_all = all(r["same_result"] for r in rows)
    total_old = sum(r[f"wall_s_{old}"] for r in rows)
    total_new = sum(r[f"wall_s_{new}"] for r in rows)
    doc = {"version": __version__, "machine": platform.processor() or platform.machine(),
           "cores": os.cpu_count(), "sets": rows,
           "summary": {f"wall_s_{old}": total_old, f"wall_s_{new}": total_new, "ratio": total_new / total_old,
                       "all_identical": same_all}}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1))
    print(f"all sets: {total_old:.1f} s {old}, {total_new:.1f} s {new} (x{total_new / total_old:.2f}); "
          f"results {'identical' if same_all else 'DIFFER'} -> {out}")
    return 0 if same_all else 1


def arguments(doc: str, out: pathlib.Path) -> argparse.Namespace:
    """The command line of a both-ways benchmark: ``--set SEED/INDEX`` (repeated) and ``--out``."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--set", dest="sets", action="append", type=parse_set, required=True, metavar="SEED/INDEX")
    ap.add_argument("--out", type=pathlib.Path, default=out)
    return ap.parse_args()


def main() -> int:
    args = arguments(__doc__, OUT)
    rows = []
    for (seed, index), s, trials, order, got in both_ways(args.sets, timed):
        (t_old, r_old), (t_new, r_new) = got[False], got[True]
        same = _comparable(r_old) == _comparable(r_new)
        row = {"set": f"{seed}/{index}", "robots": s["robots"], "trials": len(trials),
               "arms_tracked": s["arms_tracked"], "first": "nested" if order[0] else "before",
               "wall_s_before": t_old, "wall_s_nested": t_new, "ratio": t_new / t_old,
               "model_runs_before": r_old["model_runs"], "model_runs_nested": r_new["model_runs"],
               "same_result": same}
        rows.append(row)
        print(f"{row['set']}: {s['robots']} robot(s), {len(trials)} trials: {t_old:6.1f} s before, "
              f"{t_new:6.1f} s nested (x{row['ratio']:.2f}); runs {row['model_runs_before']} / "
              f"{row['model_runs_nested']}; results {'identical' if same else 'DIFFER'}", flush=True)
    return finish(rows, "before", "nested", args.out)


if __name__ == "__main__":
    raise SystemExit(main())
