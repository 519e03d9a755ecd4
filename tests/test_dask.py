"""Scans on Dask: shards anywhere, one writer, the same store as a local run, nothing lost.

The identical-store checks compare against a scan run here by the local
executor as a reader sees it (tests/storecmp.py): every dataset's values,
dtype, attributes and scales, the stored configuration equal except the
executor's own keys, and only the canonical NaN in either store. Shards are small (a few configurations, early exit
off) so that a shard runs long enough to be killed and the tests stay short.
"""

import json
import os
import signal
import threading
import time

import h5py
import numpy as np
import pytest

from smarticle_mjx import executors
from smarticle_mjx.executors import DaskExecutor, ExecutorError, plan_shards
from smarticle_mjx.scan import ScanConfig, run_scan
from smarticle_mjx.store import StoreError, Writer
from storecmp import assert_same_store

needs_dask = pytest.mark.skipif(not executors.available(), reason="Dask is not installed (pip install -e '.[dask]')")

# 16 configurations in 0.8-1.6 W: most valid and colliding; 3 periods each, no early exit
CFG = ScanConfig(n=16, r_range_W=(0.8, 1.6), periods=3, quiet_periods=0, seed=3, batch_size=4)


@pytest.fixture(scope="module")
def local_store(tmp_path_factory):
    path = tmp_path_factory.mktemp("local") / "local.h5"
    run_scan(CFG, path)
    return path


def test_shards_cover_exactly_the_missing_rows():
    shards = plan_shards({"a": [(0, 10), (14, 16)], "b": [(3, 4)]}, 4)
    rows = {(s.run, i) for s in shards for i in range(s.lo, s.hi)}
    assert rows == {("a", i) for i in (*range(10), 14, 15)} | {("b", 3)}
    assert all(s.hi - s.lo <= 4 for s in shards) and len(shards) == 3 + 1 + 1


def test_the_journal_keeps_parts_in_any_order_and_names_its_gaps(tmp_path):
    """Parts may arrive out of order; overlap is refused; a gap stops the merge
    and is what a resume runs."""
    rows = lambda lo, n: {"config": np.zeros((n, 3)), "valid": np.ones(n, bool), "status": np.zeros(n, np.int32),
                          "periods_run": np.ones(n, np.int32), "touched": np.zeros((n, 1, 1), bool),
                          "min_dist": np.zeros((n, 1, 1), np.float32), "poses": np.zeros((n, 1, 2, 5), np.float32),
                          "rel": np.zeros((n, 1, 3), np.float32), "com": np.zeros((n, 1, 3), np.float32),
                          "lifetime": np.full(n, lo, np.int32)}
    path = tmp_path / "s.h5"
    with Writer(path, {"x": 1}, {"r": {"n_configs": 10}}) as w:
        w.append("r", 6, rows(6, 4))
        w.append("r", 0, rows(0, 3))
        with pytest.raises(StoreError, match="overlap"):
            w.append("r", 2, rows(2, 2))
        assert w.missing("r", 10) == [(3, 6)] and w.done_rows("r") == 3
        with pytest.raises(StoreError, match="lacks rows 3..5"):
            w.finalize()
    with Writer(path, {"x": 1, "executor": {"kind": "dask"}}, {"r": {"n_configs": 10}}, mode="resume") as w:
        assert w.missing("r", 10) == [(3, 6)]
        w.append("r", 3, rows(3, 3))
        w.finalize()
    with h5py.File(path) as f:
        assert f["runs/r/lifetime"][()].tolist() == [0] * 3 + [3] * 3 + [6] * 4


@needs_dask
def test_a_scan_on_a_local_dask_cluster_writes_the_local_store(tmp_path, local_store):
    """``smx scan --executor dask`` (LocalCluster, 2 workers, shards of 3) gives
    the store the local executor gives, bit for bit; its cluster listens on
    the loopback interface only, with no dashboard."""
    import psutil
    seen = {}

    def on_client(client):
        info = client.scheduler_info()
        seen["address"] = client.scheduler.address
        seen["workers"] = [w for w in info["workers"]]
        # the scheduler runs in this process: every socket it listens on
        seen["listening"] = [c.laddr.ip for c in psutil.Process().net_connections(kind="inet")
                             if c.status == psutil.CONN_LISTEN]
        seen["dashboard"] = client.run_on_scheduler(
            lambda dask_scheduler: "distributed.dashboard.scheduler" in __import__("sys").modules)

    ex = DaskExecutor(workers=2, shard_size=3)
    ex.on_client = on_client
    out = tmp_path / "dask.h5"
    run_scan(CFG, out, executor=ex)
    assert_same_store(local_store, out)
    assert seen["address"].startswith("tcp://127.0.0.1:")
    assert all(w.startswith("tcp://127.0.0.1:") for w in seen["workers"])
    assert seen["listening"] and all(ip == "127.0.0.1" for ip in seen["listening"]), seen["listening"]
    assert not seen["dashboard"]
    with h5py.File(out) as f:
        assert json.loads(f.attrs["config"])["executor"] == {"kind": "dask", "scheduler": "local", "shard_size": 3}


@needs_dask
def test_a_worker_killed_mid_shard_is_survived_with_the_identical_store(tmp_path, local_store):
    """SIGKILL to a worker while it runs a shard: the scheduler runs that shard
    again (its story shows it processing twice) and the store is identical."""
    from distributed import Client, LocalCluster
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, silence_logs=50)
    client = Client(cluster)
    killed = {}
    try:
        pids = client.run(os.getpid)

        def killer():
            deadline = time.time() + 120
            while time.time() < deadline and not killed:
                for addr, keys in client.processing().items():
                    keys = [k for k in keys if str(k).startswith("smx-shard-")]
                    if keys and addr in pids:
                        time.sleep(0.5)  # well inside the shard (a shard runs ~2 s)
                        if keys[0] in client.processing().get(addr, ()):
                            os.kill(pids[addr], signal.SIGKILL)
                            killed.update(key=keys[0], worker=addr)
                            return
                time.sleep(0.05)

        t = threading.Thread(target=killer, daemon=True)
        t.start()
        out = tmp_path / "killed.h5"
        run_scan(CFG, out, executor=DaskExecutor(scheduler=cluster.scheduler_address, shard_size=4))
        t.join(5)
        assert killed, "no shard was caught running"
        story = cluster.scheduler.story(killed["key"])
        processing = [s for s in story if len(s) > 2 and s[2] == "processing"]
        assert len(processing) >= 2, story
        assert_same_store(local_store, out)
    finally:
        client.close()
        cluster.close()


@needs_dask
def test_a_failing_shard_stops_the_scan_in_one_line_and_resume_runs_only_the_rest(tmp_path, local_store,
                                                                                     monkeypatch):
    """A shard that raises is named and the scan stops, the shards that
    finished are journaled, and ``--resume`` submits only the missing rows."""
    from distributed import LocalCluster
    real = executors._shard_rows
    calls = []

    def flaky(job, run, lo, hi, nthread):
        calls.append((lo, hi))
        if lo == 8:
            raise RuntimeError("servo on fire")
        return real(job, run, lo, hi, nthread)

    monkeypatch.setattr(executors, "_shard_rows", flaky)
    # threads in this process, so the patched shard function is the one that runs
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None,
                      silence_logs=50) as cluster:
        out = tmp_path / "flaky.h5"
        with pytest.raises(ExecutorError, match=r"shard run a090.00 rows 8..11 failed: RuntimeError: servo on fire;"
                                                r" --resume continues"):
            run_scan(CFG, out, executor=DaskExecutor(scheduler=cluster.scheduler_address, shard_size=4))
        assert not out.exists()
        calls.clear()
        monkeypatch.setattr(executors, "_shard_rows", lambda *a: (calls.append(tuple(a[2:4])), real(*a))[1])
        run_scan(CFG, out, mode="resume", executor=DaskExecutor(scheduler=cluster.scheduler_address, shard_size=4))
    assert (8, 12) in calls and len(calls) < 4, calls
    assert_same_store(local_store, out)


def test_dask_executor_without_dask_is_one_line_exit_2(tmp_path, monkeypatch):
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    monkeypatch.setattr(executors, "available", lambda jobqueue=False: False)
    res = CliRunner().invoke(app, ["scan", "--n", "2", "--periods", "1", "--executor", "dask", "--quiet",
                                   "--out", str(tmp_path / "x.h5")])
    assert res.exit_code == 2 and "pip install -e '.[dask]'" in res.output
    assert len(res.output.strip().splitlines()) == 1 and not (tmp_path / "x.h5").exists()


def test_unknown_executor_and_scheduler_without_dask_are_refused(tmp_path):
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    for args, msg in ((["--executor", "ray"], "--executor must be local, dask or slurm"),
                      (["--scheduler", "tcp://127.0.0.1:1"], "--scheduler needs --executor dask")):
        res = CliRunner().invoke(app, ["scan", "--n", "2", "--quiet", "--out", str(tmp_path / "x.h5"), *args])
        assert res.exit_code == 2 and msg in res.output


@pytest.mark.skipif(not executors.available(jobqueue=True), reason="dask-jobqueue is not installed")
def test_the_slurm_job_script_holds_the_settings_that_matter(tmp_path):
    """The job script dask-jobqueue writes for --executor slurm (no Slurm
    needed): cores, memory, walltime, partition and account for Slurm; one
    worker per job that takes one shard at a time; its lifetime ends before
    the walltime (10 %, at least 5 min), staggered, so no job is killed by
    Slurm mid-shard; TLS to the scheduler with credentials in the shared folder."""
    import re
    spec = executors.SlurmSpec(jobs=3, cores=32, memory="64GB", walltime="02:00:00", queue="normal",
                               account="lab", shared_dir=str(tmp_path))
    cluster = spec.cluster()
    try:
        script = cluster.job_script()
        assert cluster.scheduler_address.startswith("tls://")
    finally:
        cluster.close()
    for line in ("#SBATCH -p normal", "#SBATCH -A lab", "#SBATCH -n 1", "#SBATCH --cpus-per-task=32",
                 "#SBATCH -t 02:00:00"):
        assert line in script, line
    assert re.search(r"#SBATCH --mem=6\dG", script)
    life = int(re.search(r"--lifetime (\d+)s", script).group(1))
    stagger = int(re.search(r"--lifetime-stagger (\d+)s", script).group(1))
    assert life + stagger <= 2 * 3600 - 300 and life >= 3600
    assert "--resources shard=1" in script and "--nthreads 32" in script
    assert "--tls-ca-file " + str(tmp_path) in script and "--protocol tls://" in script
    with pytest.raises(ValueError, match="walltime"):
        executors.SlurmSpec(jobs=1, cores=1, memory="1GB", walltime="00:10:00").validate()


@needs_dask
def test_a_lost_scheduler_stops_the_scan_in_one_line_and_resume_continues(tmp_path, local_store):
    """The scheduler goes away after the first shards are journaled: one line
    saying so, the journal keeps what arrived, ``--resume`` on a new cluster
    finishes the identical store."""
    import dask
    from distributed import LocalCluster
    out = tmp_path / "lost.h5"
    with dask.config.set({"distributed.comm.timeouts.connect": "2s", "distributed.comm.retry.count": 0}):
        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None,
                               silence_logs=50)
        stopped = []

        def progress(p):
            if p["done"] >= 4 and not stopped:
                stopped.append(p["done"])
                cluster.sync(cluster.scheduler.close)

        try:
            with pytest.raises(ExecutorError, match="lost the Dask scheduler .* --resume continues from the journal"):
                run_scan(CFG, out, on_progress=progress,
                         executor=DaskExecutor(scheduler=cluster.scheduler_address, shard_size=4))
        finally:
            cluster.close()
    assert stopped and not out.exists()
    run_scan(CFG, out, mode="resume", executor=DaskExecutor(workers=1, shard_size=4))
    assert_same_store(local_store, out)


@needs_dask
def test_progress_gives_rate_and_eta_as_shards_arrive_from_two_workers(tmp_path):
    """The progress bar ``smx scan`` shows is fed per shard from whichever
    worker finished it: rows done climb to the total, the rate is the steps
    the shards actually simulated (their periods run x steps per period, read
    back from the store) over the wall time, and an ETA exists mid-scan."""
    from smarticle_mjx.cli import _progress
    from smarticle_mjx.engine import steps_per_period
    from smarticle_mjx.store import Store
    bar, feed = _progress(quiet=True)  # rich computes speed and ETA for a disabled bar too
    seen = []

    def progress(p):
        feed(p)
        task = bar.tasks[0]
        seen.append((task.completed, p["steps"], p["elapsed"], task.fields["rate"], task.time_remaining))

    out = tmp_path / "progress.h5"
    with bar:
        run_scan(CFG, out, on_progress=progress, executor=DaskExecutor(workers=2, shard_size=3))
    done = [s[0] for s in seen]
    assert done == sorted(done) and done[-1] == CFG.n and len(seen) >= 1 + 6  # the start, then one per shard
    d = Store(out).run(fields=("periods_run",))
    per_period = steps_per_period(CFG.gait_spec(90.0).period(), CFG.scene_params().timestep)
    assert seen[-1][1] == int(d["periods_run"].sum()) * per_period
    _, steps, elapsed, rate, _ = seen[-1]
    assert rate == f"{steps / elapsed:,.0f} steps/s"
    assert any(eta is not None and 0 < eta < 3600 for c, *_, eta in seen if 0 < c < CFG.n)


@needs_dask
def test_sweep_amplitude_on_dask_writes_the_local_sweep(tmp_path):
    """``smx sweep-amplitude --executor dask`` shards every amplitude's rows
    and writes the store a local sweep writes, group by group."""
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    args = ["sweep-amplitude", "--amplitudes", "60,90", "--n", "6", "--periods", "2", "--seed", "4", "--quiet"]
    local, dask_out = tmp_path / "local.h5", tmp_path / "dask.h5"
    assert CliRunner().invoke(app, [*args, "--out", str(local)]).exit_code == 0
    r = CliRunner().invoke(app, [*args, "--out", str(dask_out), "--executor", "dask", "--workers", "1",
                                 "--shard-size", "4"])
    assert r.exit_code == 0, r.output
    assert_same_store(local, dask_out)
    with h5py.File(dask_out) as f:
        assert sorted(f["runs"]) == ["a060.00", "a090.00"]
        assert json.loads(f.attrs["config"])["executor"]["kind"] == "dask"


@needs_dask
def test_a_relaxation_on_dask_writes_the_local_store(tmp_path):
    """Relaxations run through the same executors as scans: trials sharded over a threaded
    LocalCluster (shards of 2 of 5 trials, one with the lab's imperfections) give the store the local
    executor gives, trial for trial, and the store names its executor."""
    from distributed import LocalCluster
    from smarticle_mjx.relax import RelaxConfig, run_relax
    cfg = RelaxConfig(n_robots=3, trials=5, periods=6, batch_size=2, imperfections="lab")
    run_relax(cfg, tmp_path / "local.h5")
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None,
                      silence_logs=50) as cluster:
        run_relax(cfg, tmp_path / "dask.h5", executor=DaskExecutor(scheduler=cluster.scheduler_address, shard_size=2))
    assert_same_store(tmp_path / "local.h5", tmp_path / "dask.h5")
    with h5py.File(tmp_path / "dask.h5") as f:
        assert json.loads(f.attrs["config"])["executor"]["shard_size"] == 2
