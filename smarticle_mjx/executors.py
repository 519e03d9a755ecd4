"""Where a scan's shards run: here (``scan.run_scan`` with no executor) or on Dask.

A *shard* is a range of one run's configurations. On Dask each shard is a
pure task (:func:`shard_rows`): it builds the scene on the worker (once per
worker process), runs the engine with early exit and refill through the same
``scan.simulate_rows`` as a local scan, and returns the rows; workers do no
I/O. The client is the only writer: it journals each shard as it arrives, in
any order (the store's journal keeps out-of-order parts), so ``--resume``
resubmits only the row ranges the journal lacks.

Faults. A worker that dies mid-shard (killed, out of memory, its node gone)
makes the scheduler run the shard elsewhere; ``allowed-failures`` bounds how
often (:data:`ALLOWED_FAILURES`). A shard that raises is not retried (the
engine is deterministic: it would raise again); either way the scan stops
with one line naming the shard, and ``--resume`` continues.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import threading

import numpy as np

MISSING = "--executor dask needs Dask: pip install -e '.[dask]'"

# How many worker deaths one shard may be involved in before Dask gives up on
# it (Dask's default is 3). 2: one death is routine on a shared cluster
# (pre-emption, a node lost, walltime), a second is chance; a shard present at
# three deaths most likely kills its worker itself (memory), and retrying it
# would take down a worker each time.
ALLOWED_FAILURES = 2


def available(jobqueue: bool = False) -> bool:
    mods = ("dask", "distributed") + (("dask_jobqueue",) if jobqueue else ())
    return all(importlib.util.find_spec(m) is not None for m in mods)


def _seconds(walltime: str) -> int:
    """Slurm's [D-]HH:MM:SS (or MM:SS, or minutes) in seconds."""
    days, _, hms = walltime.rpartition("-")
    parts = [int(x) for x in hms.split(":")]
    if len(parts) == 1:
        parts = [0, parts[0], 0]
    while len(parts) < 3:
        parts.insert(0, 0)
    h, m, sec = parts
    return (int(days) if days else 0) * 86400 + h * 3600 + m * 60 + sec


@dataclasses.dataclass(frozen=True)
class SlurmSpec:
    """Slurm jobs that hold Dask workers (dask-jobqueue's ``SLURMCluster``).

    Each job is one worker process on ``cores`` cores that runs one shard at
    a time with the engine on all of them. Workers retire themselves at
    ``lifetime`` (below the walltime by ``margin`` and staggered, so jobs do
    not all end together); their shard, if any, runs again elsewhere and the
    cluster keeps ``jobs`` jobs queued. The scheduler runs in the ``smx``
    process with temporary TLS credentials (written to ``shared_dir``, which
    the compute nodes must see), so only holders of them can reach it.
    """

    jobs: int
    cores: int
    memory: str
    walltime: str = "02:00:00"
    queue: str | None = None
    account: str | None = None
    shared_dir: str = "."

    def validate(self):
        if self.jobs < 1 or self.cores < 1:
            raise ValueError("--jobs and --job-cores must be positive")
        try:
            w = _seconds(self.walltime)
        except ValueError:
            raise ValueError(f"--walltime must be [D-]HH:MM:SS, got {self.walltime!r}") from None
        if w < 15 * 60:
            raise ValueError(f"--walltime {self.walltime} leaves no room for shards: use at least 00:15:00")

    def lifetime(self) -> tuple[int, int]:
        """(lifetime, stagger) in s: end 10 % (at least 5 min) before the walltime, stagger 5 % of it."""
        w = _seconds(self.walltime)
        life = w - max(300, w // 10)
        return life, max(60, life // 20)

    def cluster(self):
        from dask_jobqueue import SLURMCluster
        self.validate()
        life, stagger = self.lifetime()
        return SLURMCluster(
            cores=self.cores, processes=1, memory=self.memory, walltime=self.walltime, queue=self.queue,
            account=self.account, security=True, shared_temp_directory=self.shared_dir,
            worker_extra_args=["--lifetime", f"{life}s", "--lifetime-stagger", f"{stagger}s",
                               "--resources", "shard=1"],
            scheduler_options={"dashboard_address": None})


class ExecutorError(RuntimeError):
    """A distributed scan stopped (one line, saying that --resume continues)."""


@dataclasses.dataclass(frozen=True)
class Shard:
    run: str
    lo: int
    hi: int

    @property
    def key(self) -> str:
        return f"smx-shard-{self.run}-{self.lo}-{self.hi}"

    def __str__(self):
        return f"run {self.run} rows {self.lo}..{self.hi - 1}"


def plan_shards(todo: dict[str, list[tuple[int, int]]], size: int) -> list[Shard]:
    """Shards of at most ``size`` rows covering every missing range, run by run."""
    out = []
    for run, ranges in todo.items():
        for lo, hi in ranges:
            n = math.ceil((hi - lo) / size)
            edges = np.linspace(lo, hi, n + 1).round().astype(int) if n else []
            out += [Shard(run, int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]
    return out


_WORKER_BACKENDS: dict = {}
_WORKER_LOCK = threading.Lock()  # a worker with several Dask threads runs its shards one at a time


def shard_rows(config, params, amplitude_deg: float, lo: int, hi: int, nthread: int | None) -> dict:
    """Rows ``lo .. hi-1`` of the run at ``amplitude_deg`` (a Dask task: no I/O, result returned)."""
    with _WORKER_LOCK:
        return _shard_rows(config, params, amplitude_deg, lo, hi, nthread)


def _shard_rows(config, params, amplitude_deg, lo, hi, nthread):
    from .engine import Scene, make_backend
    from .scan import RunInputs, simulate_rows
    key = (repr(params), config.backend, config.collisions, nthread)
    if key not in _WORKER_BACKENDS:
        scene = Scene.build(params, 2, collisions=config.collisions)
        kw = {"nthread": nthread} if config.backend == "native" else config.backend_options()
        _WORKER_BACKENDS.clear()  # one scene per worker process at a time
        _WORKER_BACKENDS[key] = make_backend(config.backend, scene, **kw)
    backend = _WORKER_BACKENDS[key]
    inputs = RunInputs.of(config, params, amplitude_deg)
    got: dict[int, dict] = {}

    def on_rows(idx, rows):
        for j, i in enumerate(idx):
            got[int(i)] = {f: v[j] for f, v in rows.items()}

    simulate_rows(backend, config, params, inputs, lo, hi, on_rows)
    return {f: np.stack([got[i][f] for i in range(lo, hi)]) for f in got[lo]}


class DaskExecutor:
    """Shards on a Dask cluster: an existing one (``scheduler``) or a LocalCluster started here.

    Args:
      scheduler: address of a running scheduler ("tcp://host:8786"); None
        starts a ``LocalCluster`` on the loopback interface.
      workers: LocalCluster: worker processes (default: one per core).
      threads_per_worker: engine threads per shard (the native backend's
        ``nthread``); each worker runs one shard at a time, so a worker
        uses this many cores. LocalCluster workers get one Dask thread each.
      shard_size: configurations per shard (a few minutes of work each:
        the default 64 is ~2 minutes of a 75-period scan on one core).
      dashboard: LocalCluster: serve Dask's dashboard on 127.0.0.1:8787 (off:
        no dashboard pages; the scheduler's HTTP server, which Dask always
        starts, listens on a free loopback port).
      security: a ``distributed.Security`` for TLS to a shared scheduler.
    """

    def __init__(self, scheduler: str | None = None, workers: int | None = None, threads_per_worker: int = 1,
                 shard_size: int = 64, dashboard: bool = False, security=None, slurm: SlurmSpec | None = None):
        if not available(jobqueue=slurm is not None):
            raise ValueError(MISSING if slurm is None else "--executor slurm needs dask-jobqueue: "
                             "pip install -e '.[dask]'")
        if slurm is not None:
            slurm.validate()
            if scheduler is not None:
                raise ValueError("--executor slurm starts its own scheduler; --scheduler is for --executor dask")
            threads_per_worker = slurm.cores
        if shard_size < 1:
            raise ValueError(f"--shard-size must be positive, got {shard_size}")
        if workers is not None and workers < 1:
            raise ValueError(f"--workers must be positive, got {workers}")
        if threads_per_worker < 1:
            raise ValueError(f"--threads-per-worker must be positive, got {threads_per_worker}")
        self.scheduler = scheduler
        self.workers = workers
        self.threads_per_worker = threads_per_worker
        self.shard_size = shard_size
        self.dashboard = dashboard
        self.security = security
        self.slurm = slurm
        self.address = None  # the scheduler actually used (set while running)
        self.on_client = None  # test hook: called with the Client once connected

    def describe(self) -> dict:
        """The executor's own keys, stored beside the scan's configuration."""
        where = "slurm" if self.slurm else self.scheduler or "local"
        return {"kind": "dask", "scheduler": where, "shard_size": self.shard_size}

    @property
    def _owns_workers(self) -> bool:
        """Workers started here carry the 'shard' resource: one shard at a time each."""
        return self.scheduler is None

    def _connect(self):
        import dask
        from distributed import Client, LocalCluster
        dask.config.set({"distributed.scheduler.allowed-failures": ALLOWED_FAILURES})
        if self.slurm is not None:
            cluster = self.slurm.cluster()
            cluster.adapt(minimum_jobs=self.slurm.jobs, maximum_jobs=self.slurm.jobs)
            return cluster, Client(cluster, security=cluster.security)
        if self.scheduler is None:
            import os
            n = self.workers or max(1, (os.cpu_count() or 1) // self.threads_per_worker)
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, resources={"shard": 1},
                                   host="127.0.0.1", silence_logs=50,
                                   # off: Dask still runs its scheduler's HTTP server (health, metrics); on a free
                                   # loopback port, so that clusters side by side do not contend for 8787
                                   dashboard_address="127.0.0.1:8787" if self.dashboard else "127.0.0.1:0",
                                   scheduler_kwargs={} if self.dashboard else {"dashboard": False})
            return cluster, Client(cluster)
        try:  # waits Dask's connect timeout (distributed.comm.timeouts.connect, 30 s unless configured)
            return None, Client(self.scheduler, security=self.security)
        except (OSError, TimeoutError) as e:
            raise ExecutorError(f"cannot reach the Dask scheduler at {self.scheduler}: {e}") from None

    def run(self, config, params, runs: dict, todo: dict[str, list[tuple[int, int]]], on_shard) -> None:
        """Run every shard of ``todo``; ``on_shard(run, lo, rows)`` for each, as they finish."""
        from distributed import as_completed
        shards = plan_shards(todo, self.shard_size)
        if not shards:
            return
        cluster, client = self._connect()
        self.address = client.scheduler.address
        try:
            if self.on_client:
                self.on_client(client)
            nthread = self.threads_per_worker
            futures = {}
            for sh in shards:
                f = client.submit(shard_rows, config, params, runs[sh.run]["amplitude_deg"], sh.lo, sh.hi, nthread,
                                  key=sh.key, pure=False, retries=0,
                                  resources={"shard": 1} if self._owns_workers else None)
                futures[f] = sh
            ac = as_completed(futures)
            for f in ac:
                sh = futures[f]
                try:
                    rows = f.result()
                except Exception as e:  # noqa: BLE001 - every failure stops the scan the same way
                    for g in futures:
                        g.cancel()
                    raise ExecutorError(_failure(sh, e, self.address)) from None
                on_shard(sh.run, sh.lo, rows)
                del rows
        finally:
            try:
                client.close()
            finally:
                if cluster is not None:
                    cluster.close()


def _failure(shard: Shard, e: Exception, address) -> str:
    name = type(e).__name__
    if name == "KilledWorker":
        why = f"its worker died {ALLOWED_FAILURES + 1} times (allowed-failures {ALLOWED_FAILURES})"
    elif name in ("CancelledError", "FutureCancelledError", "CommClosedError") or isinstance(e, (OSError,
                                                                                                 TimeoutError)):
        return f"lost the Dask scheduler at {address} ({name}); --resume continues from the journal"
    else:
        why = f"{name}: {str(e).splitlines()[0] if str(e) else ''}".rstrip(": ")
    return f"shard {shard} failed: {why}; --resume continues from the journal"
