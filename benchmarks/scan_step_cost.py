"""What a finer step costs the paper's scan: the same basin scan (random starts, 75 periods at 90 deg,
early exit, journaled store: the whole pipeline of ``smx scan``) at the default step and at candidates,
interleaved on the same machine in one run, as wall-time ratios.

The paper scan is 5000 starts x 75 periods; this runs ``--rounds`` rounds of ``--n`` starts each (a new seed
per round, every numerics on the same starts within a round), so the ratio is measured on the paper scan's
own mix of lanes (those that part and retire early, those that stay bound all 75 periods), and the
5000-start wall time is extrapolated from each numerics' rows per second.

    python benchmarks/scan_step_cost.py --n 500 --rounds 2          # ~16 min on 2 cores

Writes results/scan_step_cost.json: per round and numerics the wall time, steps, lane-periods run and
the bound fraction; per numerics the median ratio to the default and the extrapolated 5000 x 75 time.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import platform
import resource
import statistics
import tempfile
import time

from smarticle_mjx import __version__, presets
from smarticle_mjx.specs import ScanConfig
from smarticle_mjx.scan import run_scan

ROOT = pathlib.Path(__file__).resolve().parent
CANDIDATES = {"default": (), "implicitfast-0.25ms": (("timestep", 0.00025),)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=500)
    ap.add_argument("--periods", type=int, default=75)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "scan_step_cost.json")
    args = ap.parse_args()
    default = presets.params(presets.DEFAULT)
    rows = []
    for r in range(args.rounds):
        order = list(CANDIDATES) if r % 2 == 0 else list(reversed(CANDIDATES))  # alternate who runs first
        for name in order:
            cfg = ScanConfig(n=args.n, periods=args.periods, seed=100 + r, overrides=CANDIDATES[name])
            with tempfile.TemporaryDirectory() as tmp:
                t = time.perf_counter()
                s = run_scan(cfg, pathlib.Path(tmp) / "scan.h5")
                wall = time.perf_counter() - t
            step = dict(CANDIDATES[name]).get("timestep", default.timestep)
            run = next(iter(s.runs.values()))
            rows.append({"round": r, "numerics": name, "timestep_ms": step * 1e3, "integrator": default.integrator,
                         "wall_s": wall, "steps": s.steps, "valid": run.valid,
                         "bound_end_fraction": run.bound_end_fraction})
            print(f"round {r} {name}: {wall:.0f} s, {s.steps} steps, bound {run.bound_end_fraction:.3f}", flush=True)
    summary = {}
    for name in CANDIDATES:
        ratios = [next(x for x in rows if x["round"] == r and x["numerics"] == name)["wall_s"]
                  / next(x for x in rows if x["round"] == r and x["numerics"] == "default")["wall_s"]
                  for r in range(args.rounds)]
        per_row = statistics.median(x["wall_s"] / args.n for x in rows if x["numerics"] == name)
        summary[name] = {"ratio_to_default": statistics.median(ratios), "ratios": ratios,
                         "extrapolated_5000_min": per_row * 5000 / 60}
        print(f"{name}: {statistics.median(ratios):.2f}x the default ({', '.join(f'{x:.2f}' for x in ratios)}); "
              f"5000 x {args.periods} ~ {per_row * 5000 / 60:.0f} min on this machine", flush=True)
    args.out.write_text(json.dumps({
        "what": "paper-scan workload at the default step and candidates, interleaved", "n": args.n,
        "periods": args.periods, "rounds": args.rounds, "model": presets.DEFAULT, "package": __version__,
        "machine": platform.processor() or platform.machine(), "peak_rss_mb":
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, "rows": rows, "summary": summary}, indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
