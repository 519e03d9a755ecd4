"""Wall time and peak memory of a basin scan through the whole pipeline
(configurations -> engine with early exit -> journaled store).

    python benchmarks/full_scan.py --n 5000 --periods 75      # the paper's scan (hours on 2 cores)
    python benchmarks/full_scan.py --n 5000 --periods 3       # memory check, minutes
    python benchmarks/full_scan.py --backend warp --batch-size 4096 \
        --out benchmarks/results/full_scan_gpu.json               # on a GPU

Prints wall time, steps/s, lane-periods simulated vs the full count, peak
RSS, and an extrapolation of the 75-period wall time from the measured
lane-period rate and the early-exit saving in benchmarks/results/early_exit.json.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import resource
import tempfile
import time

from smarticle_mjx import __version__
from smarticle_mjx.scan import ScanConfig, run_scan
from smarticle_mjx.store import Store


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=5000)
    ap.add_argument("--periods", type=int, default=75)
    ap.add_argument("--backend", default="native")
    ap.add_argument("--batch-size", type=int, default=256, help="lanes simulated together (GPU: thousands)")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "full_scan.json"))
    ap.add_argument("--store", default=None, help="keep the scan's store at this path (default: a temporary one)")
    args = ap.parse_args()
    cfg = ScanConfig(n=args.n, periods=args.periods, backend=args.backend, batch_size=args.batch_size)
    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(args.store) if args.store else pathlib.Path(tmp) / "scan.h5"
        timeline = []  # (elapsed s, rows done, steps) as rows finish: where the time goes
        t = time.perf_counter()
        s = run_scan(cfg, path, on_progress=lambda p: timeline.append((p["elapsed"], p["done"], p["steps"])))
        wall = time.perf_counter() - t
        size = path.stat().st_size
        outcome = _outcome(path, args.periods)
        scene = Store(path).config.get("scene") or {}  # the numerics the scan ran with, as its store says
    usage = resource.getrusage(resource.RUSAGE_SELF)
    rss = usage.ru_maxrss / 1024
    cpu = usage.ru_utime + usage.ru_stime
    run = next(iter(s.runs.values()))
    out = dict(n=args.n, periods=args.periods, backend=args.backend, batch_size=args.batch_size,
               model=cfg.model, timestep_s=scene.get("timestep"), integrator=scene.get("integrator"),
               package=__version__, device=_device(args.backend), wall_s=wall, steps=s.steps,
               steps_per_s=s.steps_per_s, valid=run.valid, bound_end_fraction=run.bound_end_fraction,
               peak_rss_mib=rss, store_mib=size / 2 ** 20, cpu_s=cpu, cpu_per_wall=cpu / wall,
               backend_s=s.backend_s, tail=_tail(timeline, args.n, args.batch_size, wall),
               **outcome)
    if args.backend == "warp":  # how Warp collided box pairs: its backend's default
        from smarticle_mjx.engine.mjwarp import BOX_COLLIDER
        out["warp_box_collider"] = BOX_COLLIDER
    print(f"{args.n} configurations ({run.valid} valid) x {args.periods} periods, {args.backend}: "
          f"{wall:.0f} s wall, {s.steps:,} steps ({s.steps_per_s:,.0f}/s), peak RSS {rss:.0f} MiB, "
          f"store {size / 2 ** 20:.1f} MiB, bound at end {run.bound_end_fraction:.1%}, "
          f"CPU {cpu:.0f} s ({cpu / wall:.2f} cores busy on average)")
    ee = pathlib.Path(__file__).parent / "results" / "early_exit.json"
    if ee.exists() and args.periods < 75:
        e = json.loads(ee.read_text())
        saved = next(r["saved_work"] for r in e["rows"] if r["quiet_periods"] == cfg.quiet_periods)
        est = wall / args.periods * 75 * (1 - saved) if run.valid else float("nan")
        out["estimated_75_period_wall_s"] = est
        print(f"estimated 75-period wall time with early exit (saves {saved:.0%} of lane-periods): "
              f"{est / 3600:.1f} h")
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))


def _outcome(path, periods: int) -> dict:
    """What the store says of the lanes: periods run, work early exit saved, status counts."""
    from smarticle_mjx.store import BAD_STATUS, Store
    st = Store(path)
    d = st.run(st.runs[0], fields=("valid", "status", "periods_run"))
    v, status = d["valid"], d["status"]
    mean = float(d["periods_run"][v].mean()) if v.any() else 0.0
    return {"mean_periods_run_valid": mean, "lane_period_work_saved_by_early_exit": 1 - mean / periods,
            "status_counts": {"ok_ran_all_periods": int((v & (status == 0)).sum()),
                              "invalid_start_not_simulated": int((~v).sum()),
                              "retired_early": int((v & ((status & 8) > 0)).sum())},
            "nonfinite_or_penetration_lanes": int(((status & BAD_STATUS) > 0).sum())}


def _tail(timeline, n: int, batch: int, wall: float) -> dict:
    """When the queue ran out: from then on fewer lanes than the batch remain
    and the batch runs part-empty (rows done counts the invalid starts too,
    which are reported first; a lane's slot is refilled as soon as it
    finishes, so the last lane starts once all but a batch of rows are done)."""
    after = [t for t, done, _ in timeline if done >= n - batch]
    if not after:
        return {}
    return {"queue_empty_at_s": after[0], "tail_s": wall - after[0], "tail_fraction_of_wall": (wall - after[0]) / wall}


def _device(backend: str) -> str:
    """What ran the engine: the GPU's name for warp and mjx, else the CPU."""
    import platform
    if backend == "warp":
        import warp as wp
        return str(wp.get_device("cuda:0" if wp.is_cuda_available() else "cpu").name)
    if backend == "mjx":
        import jax
        return str(jax.devices()[0].device_kind)
    return platform.processor() or platform.machine()


if __name__ == "__main__":
    main()
