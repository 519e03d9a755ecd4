"""Cost of the relaxation experiment (smx relax): seconds per trial.

Two measurements, printed and written to results/relax_cost.json:

1. A timed run of ``--trials`` trials x ``--periods`` periods without the
   early stop (every trial runs its periods), on all cores: wall seconds per
   trial-period, steps per second, and the extrapolated cost of one
   300-period trial and of the 100-trial validation study.
2. Optionally (``--study DIR``), the validation study's own stages
   (validation_relax_sNN.h5 in DIR): wall time per stage from the stores'
   created/finished stamps, periods actually run (the early stop ends
   trials whose robots all went quiet), seconds per trial.

    python benchmarks/relax_cost.py --study validation-data/lab-lag
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import pathlib
import tempfile
import time

import numpy as np

from smarticle_mjx import presets, studies, studyfile, suite
from smarticle_mjx.relax import RelaxConfig, run_relax
from smarticle_mjx.store import Store


def timed(trials: int, periods: int, model: str) -> dict:
    cfg = RelaxConfig(trials=trials, periods=periods, quiet_periods=0, batch_size=trials, model=model)
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        s = run_relax(cfg, pathlib.Path(tmp) / "r.h5")
        wall = time.perf_counter() - t
    per = wall / (trials * periods)
    return {"trials": trials, "periods": periods, "cores": os.cpu_count(), "wall_s": wall,
            "s_per_trial_period": per, "steps_per_s": s.steps / wall,
            "trial_300_periods_s": 300 * per, "study_100x300_min": 100 * 300 * per / 60}


def study(folder: pathlib.Path) -> dict:
    rows = []
    # the stages' stores as smx validate names them (it keeps stores of an older
    # version beside them, validation_relax_s00.replaced-<stamp>.h5: not this study)
    name = suite.STUDIES["relax"]
    rs = studyfile.read_study(suite.SWEEPS / name)
    for p in (studies.relax_stage_path(folder, pathlib.Path(name).stem, s) for s in range(rs.stages)):
        if not p.exists():
            continue
        st = Store(p)
        t0 = datetime.datetime.fromisoformat(str(st.attrs["created"]))
        t1 = datetime.datetime.fromisoformat(str(st.attrs["finished"]))
        pr = st.run("trials", fields=("periods_run",))["periods_run"]
        wall = (t1 - t0).total_seconds()
        rows.append({"store": p.name, "trials": int(len(pr)), "wall_s": wall, "s_per_trial": wall / len(pr),
                     "periods_run_mean": float(pr.mean()), "full_length": int((pr == pr.max()).sum())})
    if not rows:
        return {}
    tot = sum(r["wall_s"] for r in rows)
    n = sum(r["trials"] for r in rows)
    return {"stages": rows, "trials": n, "wall_min": tot / 60, "s_per_trial": tot / n}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=2)
    ap.add_argument("--periods", type=int, default=20)
    ap.add_argument("--model", default=presets.DEFAULT)
    ap.add_argument("--study", type=pathlib.Path, default=None, help="folder with the study's stage stores")
    ap.add_argument("--no-timed", action="store_true", help="only read the study's stores (no timed run)")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "relax_cost.json"))
    args = ap.parse_args()
    out = {"model": args.model}
    if not args.no_timed:
        out["timed"] = t = timed(args.trials, args.periods, args.model)
        print(f"{t['trials']} trials x {t['periods']} periods on {t['cores']} cores: {t['wall_s']:.1f} s, "
              f"{t['s_per_trial_period']:.3f} s per trial-period ({t['steps_per_s']:,.0f} steps/s); "
              f"a 300-period trial {t['trial_300_periods_s']:.0f} s, 100 such trials {t['study_100x300_min']:.0f} min")
    if args.study:
        out["study"] = study(args.study)
        s = out["study"]
        if s:
            for r in s["stages"]:
                print(f"{r['store']}: {r['trials']} trials in {r['wall_s'] / 60:.1f} min ({r['s_per_trial']:.0f} s "
                      f"per trial), mean periods run {r['periods_run_mean']:.0f}, {r['full_length']} full length")
            print(f"study: {s['trials']} trials in {s['wall_min']:.0f} min, {s['s_per_trial']:.0f} s per trial")
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1, default=float))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
