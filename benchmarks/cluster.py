"""Dask's cost: the same scan locally and on a LocalCluster with 1 and 2 workers.

Runs one random 90-degree scan four ways on this machine: the local
executor on all cores, the local executor on one thread, and
``--executor dask`` on a LocalCluster of 1 and of 2 single-threaded workers
(cluster start-up included). Prints wall times, throughput relative to the
local run on the same cores, and the overhead per shard, so that a
cluster's time can be predicted:

    wall(W workers) ~ work_1thread / W + shards / W * overhead_per_shard (+ start-up)

The overhead per shard is measured two ways: from Dask's task stream (the
workers' busy time against the wall time after the first shard started:
scheduling, transfers and journaling, whatever the machine's noise does to
the other runs), and, as before, as the 1-worker run's wall time less the
1-thread local run's, over the shards (a difference of two long runs: noise
of a few seconds swamps it at small sizes).

    python benchmarks/cluster.py                    # 1000 configurations x 20 periods
    python benchmarks/cluster.py --n 300            # smaller
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import tempfile
import time

from smarticle_mjx.executors import DaskExecutor, LocalExecutor, plan_shards
from smarticle_mjx.scan import ScanConfig, run_scan


def timed(cfg, path, **kw):
    t = time.perf_counter()
    s = run_scan(cfg, path, **kw)
    return time.perf_counter() - t, s


def timed_dask(cfg, path, executor: DaskExecutor):
    """A scan on Dask, with the task stream: wall time, summary, and where the workers' time went."""
    seen = {}

    def on_client(client):
        seen["client"] = client
        client.get_task_stream()  # starts the scheduler's recording

    def on_progress(p):  # the last call comes while the client is still open
        if p["done"] == p["total"] and "stream" not in seen:
            seen["stream"] = seen["client"].get_task_stream()

    executor.on_client = on_client
    t = time.perf_counter()
    s = run_scan(cfg, path, executor=executor, on_progress=on_progress)
    wall = time.perf_counter() - t
    tasks = [r for r in seen.get("stream", []) if str(r["key"]).startswith("smx-shard-")]
    compute = [ss for r in tasks for ss in r["startstops"] if ss["action"] == "compute"]
    busy = sum(ss["stop"] - ss["start"] for ss in compute)
    first, last = min(ss["start"] for ss in compute), max(ss["stop"] for ss in compute)
    return wall, s, dict(shards=len(tasks), compute_s=busy, first_start_to_last_stop_s=last - first,
                         transfer_s=sum(ss["stop"] - ss["start"] for r in tasks for ss in r["startstops"]
                                        if ss["action"] != "compute"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--periods", type=int, default=20)
    ap.add_argument("--shard-size", type=int, default=64)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "cluster.json"))
    args = ap.parse_args()
    cfg = ScanConfig(n=args.n, periods=args.periods)
    cores = os.cpu_count() or 1
    out = dict(machine=platform.platform(), cores=cores, n=args.n, periods=args.periods, shard_size=args.shard_size,
               model=cfg.model, shards=len(plan_shards({"a": [(0, args.n)]}, args.shard_size)))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        wall, s = timed(cfg, tmp / "local.h5")
        rows.append(dict(executor="local", workers=1, threads=cores, wall_s=wall, steps=s.steps))
        print(f"local, {cores} threads: {wall:.1f} s ({s.steps:,} steps)", flush=True)
        wall1, s = timed(cfg, tmp / "local1.h5", executor=LocalExecutor(nthread=1))
        rows.append(dict(executor="local", workers=1, threads=1, wall_s=wall1, steps=s.steps))
        print(f"local, 1 thread: {wall1:.1f} s", flush=True)
        for w in (1, 2):
            wall_w, s, stream = timed_dask(cfg, tmp / f"dask{w}.h5", DaskExecutor(workers=w, shard_size=args.shard_size))
            # the workers' time not spent computing shards, between the first shard's start and the last's end
            idle = w * stream["first_start_to_last_stop_s"] - stream["compute_s"]
            stream["overhead_per_shard_s"] = idle / stream["shards"]
            # cluster start-up, first contact, and the merge of the store after the last shard
            stream["outside_shards_s"] = wall_w - stream["first_start_to_last_stop_s"]
            rows.append(dict(executor="dask", workers=w, threads=1, wall_s=wall_w, steps=s.steps,
                             task_stream=stream))
            print(f"dask LocalCluster, {w} worker(s) x 1 thread: {wall_w:.1f} s; shards busy {stream['compute_s']:.1f} "
                  f"worker-s, {stream['overhead_per_shard_s']:.3f} s idle per shard, {stream['outside_shards_s']:.1f} s "
                  "before the first and after the last", flush=True)
    local = rows[0]["wall_s"]
    for r in rows:
        r["throughput_vs_local"] = local / r["wall_s"]
    d1 = next(r for r in rows if r["executor"] == "dask" and r["workers"] == 1)["wall_s"]
    d2 = next(r for r in rows if r["executor"] == "dask" and r["workers"] == 2)["wall_s"]
    out["overhead_per_shard_s"] = (d1 - wall1) / out["shards"]  # the earlier estimate: two long runs' difference
    out["overhead_per_shard_task_stream_s"] = {r["workers"]: r["task_stream"]["overhead_per_shard_s"]
                                               for r in rows if r["executor"] == "dask"}
    out["scaling_efficiency_2_workers"] = d1 / (2 * d2)
    out["rows"] = rows
    print(f"\n| executor | workers x threads | wall s | throughput vs local ({cores} threads) |")
    print("| --- | --- | --- | --- |")
    for r in rows:
        print(f"| {r['executor']} | {r['workers']} x {r['threads']} | {r['wall_s']:.1f} | {r['throughput_vs_local']:.2f} |")
    print(f"\n{out['shards']} shards of {args.shard_size}; overhead per shard (1 worker vs 1 local thread, "
          f"cluster start-up included): {out['overhead_per_shard_s']:.2f} s; from the task stream: "
          f"{out['overhead_per_shard_task_stream_s']}; "
          f"2-worker scaling efficiency vs 1 worker: {out['scaling_efficiency_2_workers']:.2f}")
    pathlib.Path(args.out).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
