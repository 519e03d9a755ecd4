"""What the paper-size validation suite cost (smx validate --suite paper): each stage's store, its wall time
(creation to finish, from the store's attributes: a run paused and resumed counts its pause), the pair-steps
it simulated (lanes x periods each ran x steps per period) and steps per second. Reads the stores there are;
writes results/paper_suite_cost.json.

    python benchmarks/paper_suite_cost.py --data validation-data --model lab-lag
"""

from __future__ import annotations

import argparse
import datetime
import pathlib
import platform
import sys

import numpy as np

from smarticle_mjx import presets
from smarticle_mjx.bench import save_json
from smarticle_mjx.store import Store
from smarticle_mjx.suite import PAPER_STUDIES

ROOT = pathlib.Path(__file__).resolve().parent


def stage_cost(path: pathlib.Path) -> dict:
    st = Store(path)
    a = st.attrs
    t0 = datetime.datetime.fromisoformat(str(a["created"]))
    t1 = datetime.datetime.fromisoformat(str(a["finished"]))
    wall = (t1 - t0).total_seconds()
    step = float(st.config["scene"]["timestep"])
    steps = 0
    for run in st.runs:
        d = st.run(run, fields=("periods_run",))
        per_period = int(round(float(st.run_attrs[run]["period_s"]) / step))
        steps += int(np.asarray(d["periods_run"]).sum()) * per_period
    return {"store": path.name, "lanes": int(sum(st.run_attrs[r]["n_configs"] for r in st.runs)),
            "runs": len(st.runs), "wall_s": wall, "pair_steps": steps,
            "pair_steps_per_s": steps / wall if wall > 0 else float("nan"),
            "package": str(a.get("package")), "created": str(a["created"])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="validation-data", help="smx validate's --data folder")
    ap.add_argument("--model", default=presets.DEFAULT)
    ap.add_argument("--out", default=str(ROOT / "results" / "paper_suite_cost.json"))
    args = ap.parse_args(argv)
    folder = pathlib.Path(args.data) / args.model
    rows = []
    for name, f in PAPER_STUDIES.items():
        stem = pathlib.Path(f).stem
        for path in sorted(folder.glob(f"{stem}.h5")) + sorted(folder.glob(f"{stem}_a[0-9][0-9][0-9][0-9].h5")):
            st = Store(path)
            if not st.attrs.get("complete"):
                continue
            rows.append({"study": name, **stage_cost(path)})
    if not rows:
        print(f"error: no complete paper-suite store in {folder}", file=sys.stderr)
        return 2
    for r in rows:
        print(f"{r['study']:<10} {r['store']:<28} {r['lanes']:>6} lanes  {r['wall_s'] / 60:7.1f} min  "
              f"{r['pair_steps']:>13,} pair-steps  {r['pair_steps_per_s']:>9,.0f} /s")
    total = sum(r["wall_s"] for r in rows)
    print(f"total {total / 3600:.2f} h of wall time")
    save_json(args.out, {"machine": f"{platform.processor() or platform.machine()}, {platform.system()}",
                         "model": args.model, "stages": rows, "total_wall_s": total,
                         "note": "wall time from each store's creation to its finish; other jobs shared the "
                                 "machine while some stages ran (see each store's time window)"})
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
