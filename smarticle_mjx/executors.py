"""Where a study's rows run: here (:class:`LocalExecutor`) or on Dask (:class:`DaskExecutor`).

The runner (``scan.run_scan``, ``relax.run_relax``) hands an executor a *row job* and the row ranges
its store still lacks; the executor returns finished rows through a callback and never imports the
runner. A row job (:class:`RowJob`: ``scan.ScanJob``, ``relax.RelaxJob``) is a picklable object that
opens a backend for its scene and simulates any range of one run's rows on it, so a row's content does
not depend on which executor, shard or batch computed it.

On Dask a *shard* is a range of one run's rows, a pure task (:func:`shard_rows`): it opens the job's
backend on the worker (once per worker process), runs the rows and returns them; workers do no I/O.
The client is the only writer: it journals each shard as it arrives, in any order (the store's journal
keeps out-of-order parts), so ``--resume`` resubmits only the row ranges the journal lacks.

Faults. A worker that dies mid-shard (killed, out of memory, its node gone)
makes the scheduler run the shard elsewhere; ``allowed-failures`` bounds how
often (:data:`ALLOWED_FAILURES`). A shard that raises is not retried (the
engine is deterministic: it would raise again); either way the study stops
with one line naming the shard, and ``--resume`` continues.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import threading
from typing import Callable, Protocol

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


class RowJob(Protocol):
    """What an executor runs: a picklable job whose rows are simulated in ranges of one run."""

    def backend_key(self, nthread: int | None) -> tuple:
        """Equal for jobs that can share one open backend."""

    def open_backend(self, nthread: int | None = None):
        """A backend for the job's scene (the caller closes it)."""

    def rows(self, backend, run: str, lo: int, hi: int, on_rows: Callable[[np.ndarray, dict], None]) -> dict:
        """Simulate rows ``lo .. hi-1`` of ``run``; ``on_rows(row indices, rows)`` as they finish (any order).
        Returns the engine's summary (``backend_seconds``: time inside the backend)."""


OnRows = Callable[[str, int, dict], None]  # (run, first row, rows): a contiguous block to store


class Executor(Protocol):
    """Runs a row job's missing ranges and hands back the rows; the caller is the only writer."""

    def describe(self) -> dict | None:
        """The executor's own keys, stored beside the study's configuration (None: nothing to record)."""

    def run(self, job: RowJob, todo: dict[str, list[tuple[int, int]]], on_rows: OnRows) -> dict:
        """Run every range of ``todo`` (run -> [(lo, hi)]); ``on_rows`` per finished block. Returns a
        summary (``backend_s`` where the executor measures it)."""


class LocalExecutor:
    """Every missing range on this machine's cores, one backend for the whole job.

    Args:
      flush_rows: finished rows are handed back in contiguous blocks of at least this many (the
        journal's part size); None: each row as soon as it finishes, in any order (relaxation trials:
        one journal part per trial).
      nthread: the native backend's threads (None: all cores).
    """

    def __init__(self, flush_rows: int | None = 64, nthread: int | None = None):
        if flush_rows is not None and flush_rows < 1:
            raise ValueError("--flush-rows must be positive")
        self.flush_rows = flush_rows
        self.nthread = nthread

    def describe(self) -> None:
        return None

    def run(self, job: RowJob, todo: dict[str, list[tuple[int, int]]], on_rows: OnRows) -> dict:
        summary = {"backend_s": 0.0}
        if not any(todo.values()):
            return summary
        backend = job.open_backend(self.nthread)
        try:
            for name, ranges in todo.items():
                for lo, hi in ranges:
                    emit = _Blocks(name, lo, self.flush_rows, on_rows)
                    ran = job.rows(backend, name, lo, hi, emit)
                    summary["backend_s"] += ran["backend_seconds"]
                    emit.flush(force=True)
        finally:
            backend.close()
        return summary


class _Blocks:
    """Collects one range's finished rows and hands them on in contiguous blocks (or one by one)."""

    def __init__(self, run: str, lo: int, size: int | None, on_rows: OnRows):
        self.run, self.next_row, self.size, self.on_rows = run, lo, size, on_rows
        self.pending: dict[int, dict] = {}

    def __call__(self, idx, rows: dict) -> None:
        if self.size is None:
            for j, i in enumerate(idx):
                self.on_rows(self.run, int(i), {f: v[j:j + 1] for f, v in rows.items()})
            return
        for j, i in enumerate(idx):
            self.pending[int(i)] = {f: v[j] for f, v in rows.items()}
        self.flush()

    def flush(self, force: bool = False) -> None:
        k = self.next_row
        while k in self.pending:
            k += 1
        if k > self.next_row and (force or k - self.next_row >= self.size):
            idx = range(self.next_row, k)
            rows = {f: np.stack([self.pending[i][f] for i in idx]) for f in self.pending[self.next_row]}
            for i in idx:
                del self.pending[i]
            self.on_rows(self.run, self.next_row, rows)
            self.next_row = k


_WORKER_BACKENDS: dict = {}
_WORKER_LOCK = threading.Lock()  # a worker with several Dask threads runs its shards one at a time


def shard_rows(job: RowJob, run: str, lo: int, hi: int, nthread: int | None) -> dict:
    """Rows ``lo .. hi-1`` of ``run`` (a Dask task: no I/O, result returned)."""
    with _WORKER_LOCK:
        return _shard_rows(job, run, lo, hi, nthread)


def _shard_rows(job, run, lo, hi, nthread):
    key = job.backend_key(nthread)
    if key not in _WORKER_BACKENDS:
        _WORKER_BACKENDS.clear()  # one scene per worker process at a time
        _WORKER_BACKENDS[key] = job.open_backend(nthread)
    got: dict[int, dict] = {}

    def on_rows(idx, rows):
        for j, i in enumerate(idx):
            got[int(i)] = {f: v[j] for f, v in rows.items()}

    job.rows(_WORKER_BACKENDS[key], run, lo, hi, on_rows)
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

    def run(self, job: RowJob, todo: dict[str, list[tuple[int, int]]], on_rows: OnRows) -> dict:
        """Run every shard of ``todo``; ``on_rows(run, lo, rows)`` for each, as they finish."""
        from distributed import as_completed
        shards = plan_shards(todo, self.shard_size)
        if not shards:
            return {}
        cluster, client = self._connect()
        self.address = client.scheduler.address
        try:
            if self.on_client:
                self.on_client(client)
            nthread = self.threads_per_worker
            futures = {}
            for sh in shards:
                f = client.submit(shard_rows, job, sh.run, sh.lo, sh.hi, nthread,
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
                on_rows(sh.run, sh.lo, rows)
                del rows
            return {}
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


def from_options(executor: str = "local", scheduler: str | None = None, workers: int | None = None,
                 threads_per_worker: int = 1, shard_size: int = 64, dashboard: bool = False, jobs: int = 4,
                 job_cores: int = 16, job_memory: str | None = None, walltime: str = "02:00:00",
                 queue: str | None = None, account: str | None = None) -> "DaskExecutor | None":
    """The executor the command line's options name: None (run here) or a ``DaskExecutor``, on a Dask
    cluster or on Slurm jobs. Raises ValueError on options that do not fit together."""
    if executor == "local":
        if scheduler is not None:
            raise ValueError("--scheduler needs --executor dask")
        return None
    if executor not in ("dask", "slurm"):
        raise ValueError(f"--executor must be local, dask or slurm, got {executor!r}")
    slurm = None
    if executor == "slurm":
        if not job_memory:
            raise ValueError("--executor slurm needs --jobs, --job-cores and --job-memory")
        slurm = SlurmSpec(jobs=jobs, cores=job_cores, memory=job_memory, walltime=walltime, queue=queue,
                          account=account)
    return DaskExecutor(scheduler=scheduler, workers=workers, threads_per_worker=threads_per_worker,
                        shard_size=shard_size, dashboard=dashboard, slurm=slurm)
