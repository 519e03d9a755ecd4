"""What CG at 100 iterations costs against Newton, on the workloads that carry gear play.

Runs, through the package's own runners on this machine's cores, each workload with
``--set solver=Newton`` (the solve before the "auto" solver) and with ``--set solver=CG --set iterations=100``
(what "auto" runs where arms have gear play), the two interleaved and repeated
(``--rounds``, the order alternated), and prints the ratio of wall times per round:

* ``relax``: the relaxation (seven robots from the compressed start), ``backlash`` robots, in phase;
* ``pairs``: the paper scan's random pair starts with the ``lab`` imperfections (drawn robots with play).

Writes benchmarks/results/solver_cost.json. Ratios are measured within one run (this machine is shared).

    python benchmarks/solver_cost.py                      # ~8 min on 2 cores
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent
NEWTON = (("solver", "Newton"),)
CG = (("iterations", 100), ("solver", "CG"))  # what the default ("auto") solver runs where arms have play


def run_once(kind: str, overrides: tuple, n: int, periods: int, tmp: Path) -> tuple[float, float]:
    """Wall time (s) and simulated steps of one workload."""
    from smarticle_mjx.specs import RelaxConfig, ScanConfig
    out = tmp / f"{kind}-{len(overrides)}-{time.perf_counter_ns()}.h5"
    t0 = time.perf_counter()
    if kind == "relax":
        from smarticle_mjx.relax import run_relax
        summary = run_relax(RelaxConfig(trials=n, periods=periods, imperfections="backlash", overrides=overrides), out)
    else:
        from smarticle_mjx.scan import run_scan
        summary = run_scan(ScanConfig(n=n, periods=periods, imperfections="lab", robot_draws=8,
                                      overrides=overrides), out)
    wall = time.perf_counter() - t0
    return wall, float(getattr(summary, "steps", 0))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--relax-trials", type=int, default=8)
    ap.add_argument("--relax-periods", type=int, default=30)
    ap.add_argument("--pairs", type=int, default=128)
    ap.add_argument("--pair-periods", type=int, default=20)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "solver_cost.json")
    args = ap.parse_args(argv)
    if min(args.rounds, args.relax_trials, args.relax_periods, args.pairs, args.pair_periods) < 1:
        ap.error("every count must be >= 1")
    work = {"relax": (args.relax_trials, args.relax_periods), "pairs": (args.pairs, args.pair_periods)}
    res = {k: {"newton_s": [], "cg100_s": [], "ratio": []} for k in work}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            for kind, (n, periods) in work.items():
                order = [NEWTON, CG] if r % 2 == 0 else [CG, NEWTON]
                walls = {}
                for ov in order:
                    walls[ov] = run_once(kind, ov, n, periods, Path(tmp))[0]
                res[kind]["newton_s"].append(round(walls[NEWTON], 1))
                res[kind]["cg100_s"].append(round(walls[CG], 1))
                res[kind]["ratio"].append(round(walls[CG] / walls[NEWTON], 3))
                print(f"round {r}: {kind:5s} Newton {walls[NEWTON]:.1f} s, CG-100 {walls[CG]:.1f} s, "
                      f"ratio {walls[CG] / walls[NEWTON]:.2f}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"machine": platform.processor() or platform.machine(), "rounds": args.rounds,
                                    "workloads": {k: {"n": v[0], "periods": v[1]} for k, v in work.items()},
                                    "results": res}, indent=1))


if __name__ == "__main__":
    sys.exit(main())
