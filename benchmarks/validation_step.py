"""The validation page's 90-degree random study (sweeps/validation_random.toml, model
lab-lag) at a reference time step, against the same study at other steps: are the
page's glider verdicts the model's or the step's?

Runs the study's 400 starts x 75 periods at ``--dt`` (default 0.0625 ms, the reference of
docs/timestep.md) into ``--store`` (resumed if interrupted), then reduces it and every
``--compare`` store exactly as `smx validate` does (report.analyse_store_run): gliders, beta
(centred MSD over delays 5-15, bootstrap interval over gliders), net gliding speed, bound
fraction at the end. Writes results/validation_step.json.

    python benchmarks/validation_step.py --compare validation-data/lab-lag/validation_random.h5 \\
        --compare validation-data/lab-lag/validation_random.replaced-<stamp>.h5     # ~25 min on 2 cores

With ``--imperfections SET`` (the page of robots with that set, ``smx validate --imperfections SET``) it runs
the studies named by ``--studies`` (default random_90 and cw_90) at the reference step through ``smx
validate`` itself (``--set timestep=...``, stores in ``--data``), and writes, besides the 90-degree study's
numbers, the reference's verdict of every claim measured from those studies alone
(results/validation_step_SET.json). The page applies the rule: a claim whose verdict differs between its
step and the reference takes the reference's (``smarticle_mjx.validate.page.step_check``).

    python benchmarks/validation_step.py --imperfections lab \\
        --compare validation-data/lab-lag+lab/validation_random.h5                  # ~1 h on 2 cores
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import time

ROOT = pathlib.Path(__file__).resolve().parent
from smarticle_mjx import presets
from smarticle_mjx.report import analyse_store_run
from smarticle_mjx.scan import run_scan
from smarticle_mjx.studyfile import load_study
from smarticle_mjx.store import Store

STUDY = ROOT.parent / "sweeps" / "validation_random.toml"


def reduce(path: pathlib.Path) -> dict:
    st = Store(path)
    s = analyse_store_run(st, st.runs[0]).summary()  # one amplitude, one run, unrounded, as smx validate reads it
    b, v = s.get("beta") or {}, s.get("v_com") or {}
    return {"store": path.name, "timestep_ms": float(st.config["scene"]["timestep"]) * 1e3,
            "package": str(st.attrs.get("package")), "valid": s["valid"], "gliders": s["gliders"],
            "beta": [b.get("value"), b.get("lo"), b.get("hi")],
            "v_com_W_per_period": [v.get("net_W_per_period"), v.get("net_lo"), v.get("net_hi")],
            "pb_end": s.get("pb_end")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dt", type=float, default=6.25e-5)
    ap.add_argument("--store", type=pathlib.Path, default=ROOT / "results" / "validation_random_ref.h5")
    ap.add_argument("--compare", type=pathlib.Path, action="append", default=[])
    ap.add_argument("--out", type=pathlib.Path, default=None,
                    help="default results/validation_step.json, or validation_step_SET.json with --imperfections")
    ap.add_argument("--imperfections", default="none", help="the page's imperfection set (default none: ideal robots)")
    ap.add_argument("--studies", default="random_90,cw_90", help="with --imperfections: the studies run at the reference")
    ap.add_argument("--data", type=pathlib.Path, default=ROOT / "results" / "validation_step_data",
                    help="with --imperfections: where smx validate keeps the reference's stores (resumable)")
    ap.add_argument("--sweeps", type=pathlib.Path, default=ROOT.parent / "sweeps", help="the study files")
    args = ap.parse_args()
    if args.imperfections != "none":
        return with_verdicts(args)
    args.out = args.out or ROOT / "results" / "validation_step.json"
    cfg = dataclasses.replace(load_study(STUDY), model="lab-lag")
    params = dataclasses.replace(presets.params("lab-lag"), timestep=args.dt)
    if not (args.store.exists() and Store(args.store).attrs.get("complete")):
        t = time.perf_counter()
        run_scan(cfg, args.store, mode="resume" if args.store.exists() else "new", params=params)
        print(f"ran {STUDY.name} at {args.dt * 1e3:g} ms in {time.perf_counter() - t:.0f} s", flush=True)
    rows = [reduce(p) for p in [args.store, *args.compare]]
    for r in rows:
        b, v = r["beta"], r["v_com_W_per_period"]
        print(f"{r['timestep_ms']:g} ms ({r['package']}): {r['gliders']} gliders of {r['valid']} valid; "
              f"beta {b[0]} [{b[1]}, {b[2]}]; V_com {v[0]} [{v[1]}, {v[2]}] W/period")
    args.out.write_text(json.dumps({"study": STUDY.name, "model": "lab-lag", "rows": rows}, indent=1, default=float))
    print(f"wrote {args.out}")


def with_verdicts(args) -> None:
    """The page of robots with ``args.imperfections``: its studies ``args.studies`` at the reference step,
    run and measured by ``smx validate`` itself, their claims' verdicts there, and the 90-degree study's
    numbers at the reference beside every ``--compare`` store."""
    from smarticle_mjx.validate import data_folder, parse_studies, run_validation
    from smarticle_mjx.validate.claims import CLAIMS
    from smarticle_mjx.validate.page import step_check_path
    studies = parse_studies(args.studies)
    if "random_90" not in studies:
        raise SystemExit("--studies must include random_90 (the page matches the check to its stores by its beta)")
    out = args.out or ROOT / "results" / step_check_path(args.imperfections).name
    args.data.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    overrides = [f"timestep={args.dt!r}"]
    result = run_validation(args.data, args.data / "reference.md", args.sweeps, model="lab-lag", studies=studies,
                            imperfections=args.imperfections, overrides=overrides, single_periods=2)
    wall = time.perf_counter() - t
    folder = data_folder(args.data, "lab-lag", args.imperfections, overrides)
    rows = [reduce(p) for p in [folder / "validation_random.h5", *args.compare]]
    verdicts = {c.key: r.verdict for c, r in zip(CLAIMS, result.rows) if c.studies and set(c.studies) <= set(studies)}
    for r in rows:
        b, v = r["beta"], r["v_com_W_per_period"]
        print(f"{r['timestep_ms']:g} ms ({r['package']}): {r['gliders']} gliders of {r['valid']} valid; "
              f"beta {b[0]} [{b[1]}, {b[2]}]; V_com {v[0]} [{v[1]}, {v[2]}] W/period")
    for k, v in verdicts.items():
        print(f"reference verdict {k}: {v}")
    out.write_text(json.dumps({"study": STUDY.name, "model": "lab-lag", "imperfections": args.imperfections,
                               "studies": studies, "reference_ms": args.dt * 1e3, "reference_wall_s": wall,
                               "rows": rows, "reference_verdicts": verdicts}, indent=1, default=float))
    print(f"wrote {out} ({wall:.0f} s at the reference)")


if __name__ == "__main__":
    main()
