"""HDF5 stores of scans and sweeps: schema, crash-safe writer, reader.

A store is one HDF5 file. While a scan runs, results go chunk by chunk into
a journal folder beside it (``NAME.h5.parts/``): each chunk is a small HDF5
file written under a temporary name and renamed, so a killed process leaves
only complete chunks. When every run is complete the journal is merged into
``NAME.h5`` (again written aside and renamed) and removed. ``--resume``
continues from the journal; a lock file held with ``flock`` refuses a second
writer, and is released by the kernel even on SIGKILL (the file itself is
removed when its writer finishes or fails; one killed leaves it, harmless).
A run that fails before it journals any row leaves nothing behind: the new
journal is removed, and the one ``--overwrite`` was replacing comes back.

Schema (version 2; version 1 lacked the dimension scales, units and long
names and is still read; see docs/store.md). Missing float values are one
NaN, the canonical quiet NaN (:func:`canonical`), whoever computed them::

    /                      attrs: schema_version, package, mujoco, jax, h5py,
                                  numpy versions, config (JSON), created, seed
    /runs/<name>/          one group per amplitude; attrs: amplitude_deg,
                                  period_s, chirality, gait, periods, pairs
        config    [M, 3]   initial (|r| in W, theta, phi in rad)
        valid     [M]      bool, False: overlapping start, never simulated
        status    [M]      int32 Status bits (engine.Status): 1 invalid start, 2 non-finite,
                           4 penetration, 8 retired early, 16 buffer overflow (warp)
        periods_run [M]    int32
        touched   [M, K, P] bool, touched at least once in period k
        min_dist  [M, K, P] float32, deepest contact (m), inf if none
        poses     [M, K, N, 5] float32, poses at the end of each period
        rel       [M, K, 3] float32, (|r| W, theta, phi) of pair 0 per period
        com       [M, K, 3] float32, pair centre of mass (x, y) and mean heading
        lifetime  [M]      int32, longest run of consecutive bound periods
      optional, when the scan asked for the collision record (``--collisions``):
        coll_steps     [M, K, P, 9, B] int32, steps in contact per contact kind and bin
        coll_impulse   [M, K, P, 9, B, 2] float32, contact impulse on robot i (N s)
        coll_impulse_r [M, K, P, 9, B] float32, its component along r (> 0 attracts)
"""

from __future__ import annotations

import datetime
import fcntl
import json
import os
import pathlib
import shutil

import h5py
import numpy as np

from . import __version__
from .labels import BAD_STATUS as _BAD_STATUS
from .labels import CONTACT_KINDS, STATUS_MEANINGS
from .records import RelaxRecord  # noqa: F401 (read_relax's result; defined where reducers may import it)

# Status bits (engine.Status) that make a lane's records untrustworthy: non-finite
# state, penetration, buffer overflow. Readers count them without importing the engine.
BAD_STATUS = int(_BAD_STATUS)

SCHEMA_VERSION = 2  # 2: dimension scales, units and long names (xarray-ready); 1 is still read
READABLE_SCHEMAS = (1, 2)
ROW_FIELDS = ("config", "valid", "status", "periods_run", "touched", "min_dist", "poses", "rel", "com", "lifetime")
OPTIONAL_FIELDS = ("coll_steps", "coll_impulse", "coll_impulse_r")
# rows of a relaxation store (smx relax): one row per trial of N robots
RELAX_FIELDS = ("start_poses", "valid", "status", "periods_run", "touched", "min_dist", "poses", "left_plate")


class StoreError(Exception):
    """A store cannot be created, resumed or read as asked."""


PACKAGE = f"smarticle-mjx {__version__}"  # a store's ``package`` attribute: which release made it
# A store's ``physics`` attribute: the version of what a study's stored numbers are for an unchanged
# configuration (scene building, engine, gait, starts, drawn robots, early exit). Raised only by a release
# that changes some stored number of some study whose configuration, model and seed stay the same; a release
# that changes reducers, reports, calibration or the CLI keeps it, so a study's stores are reused across it
# (studies.stale_reason). Stores written before it existed carry none and are reused only by their own release.
PHYSICS_VERSION = 1  # since December 2026 (package 0.4.18)


def versions() -> dict:
    import jax
    import mujoco

    return {"package": PACKAGE, "physics": PHYSICS_VERSION, "mujoco": mujoco.__version__, "jax": jax.__version__,
            "h5py": h5py.__version__, "numpy": np.__version__}


# Missing float values are stored as this one NaN (the positive quiet NaN,
# float32 0x7fc00000, float64 0x7ff8000000000000). NaNs made by arithmetic
# carry whatever sign and payload the CPU's vector unit gives them (x86's
# default NaN has the sign bit set), so the same rows computed by another
# executor, batch split or CPU would otherwise differ bit for bit.
def canonical(data: np.ndarray) -> np.ndarray:
    """``data`` with every NaN replaced by the canonical quiet NaN (other dtypes unchanged)."""
    data = np.asarray(data)
    if data.dtype.kind != "f":
        return data
    nan = np.isnan(data)
    if not nan.any():
        return data
    out = data.copy()
    out[nan] = np.array(np.nan, data.dtype)
    return out


def _plain(x):
    """numpy scalars and arrays in a configuration as the Python numbers and lists JSON stores."""
    if isinstance(x, (np.generic, np.ndarray)):
        return x.tolist()
    raise TypeError(f"a store's configuration holds {type(x).__name__}, which JSON cannot store")


def journal_path(path: pathlib.Path) -> pathlib.Path:
    return path.with_name(path.name + ".parts")


class Writer:
    """Crash-safe writer of one store. Use as a context manager.

    Args:
      path: the final ``.h5`` path.
      config: the full configuration (JSON-serialisable); a resumed store
        must have been started with exactly the same configuration.
      runs: {run name: group attrs} in the order they are run.
      mode: "new" (refuse an existing store or journal), "resume" or
        "overwrite".
      fields: the row fields every part must carry (:data:`ROW_FIELDS` for
        scans, :data:`RELAX_FIELDS` for relaxation trials).
    """

    def __init__(self, path, config: dict, runs: dict[str, dict], mode: str = "new",
                 fields: tuple[str, ...] = ROW_FIELDS):
        self.path = pathlib.Path(path)
        self.fields = tuple(fields)
        self.config = json.loads(json.dumps(config, default=_plain))  # normalised
        self.runs = runs
        self.mode = mode
        self.parts = journal_path(self.path)
        self._lock = None
        self._done: dict[str, int] = {}
        self._created = False  # this writer made the journal (new or overwrite)
        self._appended = False  # and journaled rows into it
        self._aside = None  # the journal --overwrite replaces, kept until the first rows arrive

    # -------------------------------------------------------------- set-up
    def __enter__(self):
        if self.path.suffix.lower() not in (".h5", ".hdf5"):
            raise StoreError(f"store must end in .h5 or .hdf5, got {self.path.name!r}")
        if self.path.parent.exists() and not self.path.parent.is_dir():
            raise StoreError(f"output location {self.path.parent} is not a directory")
        if not self.path.parent.is_dir():
            raise StoreError(f"output directory {self.path.parent} does not exist")
        if not os.access(self.path.parent, os.W_OK):
            raise StoreError(f"output directory {self.path.parent} is not writable")
        lock_path = self.path.with_name(self.path.name + ".lock")
        # The lock file exists only while a writer holds it: the holder removes
        # it before unlocking. A writer that opened the old file just before it
        # was removed would then lock a file nobody else sees, so after locking
        # it checks that its file is still the one at the path, else retries.
        for _ in range(100):
            try:
                fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise StoreError(f"cannot create lock file {lock_path}: {e.strerror}") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                raise StoreError(f"{self.path} is being written by another process") from None
            try:
                same = os.stat(lock_path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        else:
            raise StoreError(f"cannot lock {lock_path}: it keeps being replaced")
        self._lock = (fd, lock_path)
        try:
            self._prepare()
        except BaseException as e:
            self.__exit__(type(e), e, e.__traceback__)
            raise
        return self

    def _prepare(self):
        exists = self.path.exists()
        journal = self.parts.exists()
        if self.mode == "new":
            if exists or journal:
                what = "store" if exists else "unfinished store (journal)"
                raise StoreError(f"{what} {self.path} exists; pass --resume to continue it or --overwrite to replace it")
        elif self.mode == "resume":
            if exists and not journal:
                raise StoreError(f"{self.path} is already complete; nothing to resume")
            if not journal:
                raise StoreError(f"nothing to resume at {self.path} (no journal {self.parts.name})")
            saved = json.loads((self.parts / "config.json").read_text())
            if data_keys(saved) != data_keys(self.config):
                mine = data_keys(self.config)
                saved = data_keys(saved)
                diff = sorted(k for k in set(saved) | set(mine) if saved.get(k) != mine.get(k))
                raise StoreError(f"{self.path} was started with a different configuration ({', '.join(diff)}); "
                                 "refusing to append")
        elif self.mode != "overwrite":
            raise ValueError(f"unknown mode {self.mode!r}")
        if self.mode == "overwrite" and journal:
            self._aside = self.parts.with_name(self.parts.name + ".replaced")
            if self._aside.exists():
                shutil.rmtree(self._aside)
            os.replace(self.parts, self._aside)
        if self.mode != "resume":
            self.parts.mkdir()
            self._created = True
            meta = {"config": self.config, "runs": self.runs, "created": _now(), **versions()}
            _atomic_text(self.parts / "meta.json", json.dumps(meta, indent=1))
            _atomic_text(self.parts / "config.json", json.dumps(self.config, indent=1, sort_keys=True))

    def _release(self):
        if self._lock:
            fd, lock_path = self._lock
            try:
                os.unlink(lock_path)  # still held: no other writer can be using it
            except OSError:
                pass
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)
            self._lock = None

    def __exit__(self, exc_type, *exc):
        try:
            if exc_type is not None and self._created and not self._appended and self.parts.exists():
                shutil.rmtree(self.parts)  # nothing was computed: nothing is left behind
                if self._aside is not None:
                    os.replace(self._aside, self.parts)
                    self._aside = None
        finally:
            self._release()
        return False

    def _drop_aside(self):
        if self._aside is not None:
            shutil.rmtree(self._aside, ignore_errors=True)
            self._aside = None

    # -------------------------------------------------------------- journal
    def done_ranges(self, run: str) -> list[tuple[int, int]]:
        """Row ranges [start, stop) of ``run`` already journaled, sorted (parts
        may arrive in any order: shards of a distributed scan finish so)."""
        if run not in self._done:
            ranges = []
            for part in self._parts(run):
                with h5py.File(part, "r") as f:
                    ranges.append((int(f.attrs["start"]), int(f.attrs["stop"])))
            self._done[run] = sorted(ranges)
        return self._done[run]

    def done_rows(self, run: str) -> int:
        """Rows of ``run`` journaled as one unbroken prefix 0..n-1."""
        n = 0
        for a, b in self.done_ranges(run):
            if a > n:
                break
            n = max(n, b)
        return n

    def missing(self, run: str, total: int) -> list[tuple[int, int]]:
        """Row ranges [start, stop) of ``run`` in 0..total-1 not journaled yet."""
        out, n = [], 0
        for a, b in self.done_ranges(run):
            if a > n:
                out.append((n, min(a, total)))
            n = max(n, b)
        if n < total:
            out.append((n, total))
        return [(a, b) for a, b in out if b > a]

    def _parts(self, run):
        return sorted(self.parts.glob(f"{run}--*.h5"))

    def append(self, run: str, start: int, rows: dict[str, np.ndarray]):
        """Journal rows ``start .. start+len-1`` of ``run`` atomically."""
        if run not in self.runs:
            raise StoreError(f"unknown run {run!r}")
        missing = set(self.fields) - set(rows)
        if missing:
            raise StoreError(f"rows lack fields {sorted(missing)}")
        n = len(rows[self.fields[0]])
        if any(len(v) != n for v in rows.values()):
            raise StoreError("all row fields must have the same length")
        for a, b in self.done_ranges(run):
            if start < b and a < start + n:
                raise StoreError(f"rows {start}..{start + n - 1} of run {run} overlap journaled rows {a}..{b - 1}")
        unknown = set(rows) - set(self.fields) - set(OPTIONAL_FIELDS)
        if unknown:
            raise StoreError(f"rows have unknown fields {sorted(unknown)}")
        final = self.parts / f"{run}--{start:09d}.h5"
        tmp = final.with_name(final.name + ".tmp")
        with h5py.File(tmp, "w") as f:
            f.attrs["start"], f.attrs["stop"] = start, start + n
            for k in self.fields + OPTIONAL_FIELDS:
                if k in rows:
                    f.create_dataset(k, data=canonical(rows[k]))
        os.replace(tmp, final)
        self._appended = True
        self._drop_aside()
        self._done[run] = sorted(self.done_ranges(run) + [(start, start + n)])

    # -------------------------------------------------------------- finalise
    def finalize(self):
        """Merge the journal into the final store (atomically) and remove it."""
        meta = json.loads((self.parts / "meta.json").read_text())
        tmp = self.path.with_name(self.path.name + ".tmp")
        with h5py.File(tmp, "w") as out:
            out.attrs["schema_version"] = SCHEMA_VERSION
            for k, v in versions().items():
                out.attrs[k] = v
            out.attrs["config"] = json.dumps(meta["config"])
            out.attrs["created"] = meta["created"]
            out.attrs["finished"] = _now()
            out.attrs["seed"] = int(meta["config"].get("seed", 0))
            runs = out.create_group("runs")
            for run, attrs in meta["runs"].items():
                g = runs.create_group(run)
                for k, v in attrs.items():
                    g.attrs[k] = v
                parts = self._parts(run)
                if not parts:
                    raise StoreError(f"run {run} has no results")
                total = attrs.get("n_configs")
                gaps = self.missing(run, int(total) if total is not None else self.done_ranges(run)[-1][1])
                if gaps:
                    a, b = gaps[0]
                    raise StoreError(f"run {run} lacks rows {a}..{b - 1}; --resume completes it")
                fields = None
                for part in parts:
                    with h5py.File(part, "r") as f:
                        have = [k for k in self.fields + OPTIONAL_FIELDS if k in f]
                        if fields is not None and have != fields:
                            raise StoreError(f"journal of run {run} mixes parts with fields {fields} and {have}")
                        fields = have
                        for k in have:
                            _append_rows(g, k, canonical(f[k][()]))  # journals of older versions too
                _label_run(g)
            out.attrs["complete"] = True
        os.replace(tmp, self.path)
        shutil.rmtree(self.parts)
        self._appended = True
        self._drop_aside()


# configuration keys that say how a store was computed, not what it holds: a
# scan started on one executor may be resumed on another
EXECUTOR_KEYS = ("executor",)


def same_physics(attrs) -> bool:
    """Whether a store or journal (its root attributes, or its journal's meta) holds what this release would
    store for its configuration: the same ``physics`` version; where none is recorded (written before the
    attribute existed), the same release."""
    if "physics" in attrs:
        return int(attrs["physics"]) == PHYSICS_VERSION
    return attrs.get("package") == PACKAGE


def made_by(attrs) -> str:
    """Which release and physics version made a store (for a one-line reason)."""
    phys = attrs.get("physics")
    return f"{attrs.get('package')}" + (f" (physics {phys}, this release's is {PHYSICS_VERSION})" if phys is not None
                                        else f" (no physics version recorded; this release is {PACKAGE})")


def data_keys(config: dict) -> dict:
    """A store's configuration without how it was run (the executor): what decides whether two runs are one study."""
    return {k: v for k, v in config.items() if k not in EXECUTOR_KEYS}


def _append_rows(group, name, data):
    if name not in group:
        chunk_rows = max(1, min(256, int(2 ** 20 // max(1, data[0].nbytes if len(data) else 1))))
        group.create_dataset(name, data=data, maxshape=(None,) + data.shape[1:],
                             chunks=(chunk_rows,) + data.shape[1:], compression="gzip", compression_opts=4,
                             shuffle=True)
        return
    ds = group[name]
    if ds.shape[1:] != data.shape[1:] or ds.dtype != data.dtype:
        raise StoreError(f"schema mismatch appending {name}: {ds.shape[1:]}/{ds.dtype} vs {data.shape[1:]}/{data.dtype}")
    n = ds.shape[0]
    ds.resize(n + len(data), axis=0)
    ds[n:] = data


# ---------------------------------------------------------------- labels
# Dimension names of every row field (none is a field's name), and what each
# field holds. Fields that mix quantities carry their units per component in a
# coordinate along their last dimension (e.g. rel_units: W, rad, rad).
DIMS = {
    "config": ("lane", "config_var"), "valid": ("lane",), "status": ("lane",), "periods_run": ("lane",),
    "touched": ("lane", "period", "pair"), "min_dist": ("lane", "period", "pair"),
    "poses": ("lane", "period", "robot", "pose_var"), "rel": ("lane", "period", "rel_var"),
    "com": ("lane", "period", "com_var"), "lifetime": ("lane",),
    "start_poses": ("lane", "robot", "pose_var"), "left_plate": ("lane", "robot"),
    "coll_steps": ("lane", "period", "pair", "contact_kind", "phase_bin"),
    "coll_impulse": ("lane", "period", "pair", "contact_kind", "phase_bin", "xy"),
    "coll_impulse_r": ("lane", "period", "pair", "contact_kind", "phase_bin"),
}
LABELS = {  # field: (long_name, units; None where per component)
    "config": ("initial configuration (|r|, theta, phi)", None),
    "valid": ("initial configuration free of overlap (simulated)", "1"),
    "status": ("engine status bits", "1"),
    "periods_run": ("gait periods simulated (early exit stops sooner)", "periods"),
    "touched": ("robots of the pair touched at least once in the period", "1"),
    "min_dist": ("deepest contact distance between the pair in the period (negative: penetration)", "m"),
    "poses": ("pose of each robot at the end of the period", None),
    "rel": ("relative coordinates of the pair at the end of the period", None),
    "com": ("pair centre of mass and mean heading at the end of the period", None),
    "lifetime": ("longest run of consecutive bound periods", "periods"),
    "start_poses": ("initial pose of each robot (the perturbed packing)", None),
    "left_plate": ("first period at whose end the robot's centre was off the plate (0: never)", "periods"),
    "coll_steps": ("time steps in contact, per contact kind and gait-phase bin", "steps"),
    "coll_impulse": ("contact impulse on the pair's first robot (world x, y)", "N s"),
    "coll_impulse_r": ("contact impulse on the pair's first robot along r (> 0 attracts)", "N s"),
}
COMPONENTS = {  # dimension: (labels, units per label or None)
    "config_var": (("r", "theta", "phi"), ("W", "rad", "rad")),
    "pose_var": (("x", "y", "heading", "alpha1", "alpha2"), ("m", "m", "rad", "rad", "rad")),
    "rel_var": (("r", "theta", "phi"), ("W", "rad", "rad")),
    "com_var": (("x", "y", "heading"), ("m", "m", "rad")),
    "xy": (("x", "y"), None),
}
STATUS_BITS = tuple((int(bit), meaning) for bit, meaning in STATUS_MEANINGS.items())


def _label_run(g) -> None:
    """Dimension scales, coordinates, units and long names for one finished run group."""
    sizes: dict[str, int] = {}
    for k, dims in DIMS.items():
        if k in g:
            for d, n in zip(dims, g[k].shape):
                sizes[d] = n
    scales = {}
    for d, n in sizes.items():
        if d in COMPONENTS:
            labels, units = COMPONENTS[d]
            ds = g.create_dataset(d, data=np.array(labels[:n], dtype=h5py.string_dtype()))
        elif d == "contact_kind":
            kinds = list(CONTACT_KINDS)
            ds = g.create_dataset(d, data=np.array(kinds[:n], dtype=h5py.string_dtype()))
        else:
            ds = g.create_dataset(d, data=np.arange(1, n + 1) if d == "period" else np.arange(n))
        ds.make_scale(d)
        ds.attrs["long_name"] = {"lane": "trial index" if g.attrs.get("rows") == "trials" else "configuration index", "period": "gait periods completed",
                                 "pair": "robot pair index", "robot": "robot index",
                                 "phase_bin": "bin of the gait period"}.get(d, d.replace("_", " "))
        scales[d] = ds
    for d, (labels, units) in COMPONENTS.items():
        if d in scales and units is not None:
            u = g.create_dataset(d.replace("_var", "") + "_units", data=np.array(units, dtype=h5py.string_dtype()))
            u.dims[0].attach_scale(scales[d])
    for k, dims in DIMS.items():
        if k not in g:
            continue
        ds = g[k]
        for i, d in enumerate(dims):
            ds.dims[i].attach_scale(scales[d])
        long_name, units = LABELS[k]
        ds.attrs["long_name"] = long_name
        last = dims[-1]
        if units is None and last in COMPONENTS and COMPONENTS[last][1] is not None:
            ds.attrs["coordinates"] = last.replace("_var", "") + "_units"
            ds.attrs["units"] = "per component: " + ", ".join(
                f"{a} {b}" for a, b in zip(*COMPONENTS[last]))
        elif units is not None:
            ds.attrs["units"] = units
    if "status" in g:
        g["status"].attrs["flag_masks"] = np.array([b for b, _ in STATUS_BITS], np.int32)
        g["status"].attrs["flag_meanings"] = " ".join(m for _, m in STATUS_BITS)


def _now() -> str:
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def _atomic_text(path: pathlib.Path, text: str):
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


# ------------------------------------------------------------------ reader

class Store:
    """Read-only view of a finished store: ``Store(path).run(name)[field]``."""

    def __init__(self, path):
        self.path = pathlib.Path(path)
        if not self.path.exists():
            if journal_path(self.path).exists():
                raise StoreError(f"{self.path} is unfinished; complete it with --resume")
            raise StoreError(f"no store at {self.path}")
        try:
            with h5py.File(self.path, "r") as f:
                self.attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
                self.runs = list(f["runs"].keys()) if "runs" in f else []
                self.run_attrs = {r: dict(f["runs"][r].attrs) for r in self.runs}
                # row fields only (schema 2 adds dimension scales and unit coordinates beside them)
                self.run_fields = {r: tuple(k for k in f["runs"][r].keys() if k in DIMS) for r in self.runs}
        except OSError as e:
            raise StoreError(f"{self.path} is not a readable HDF5 store: {e}") from None
        if self.attrs.get("schema_version") not in READABLE_SCHEMAS:
            raise StoreError(f"{self.path}: schema version {self.attrs.get('schema_version')} "
                             f"(this reader knows {', '.join(map(str, READABLE_SCHEMAS))})")
        self.config = json.loads(self.attrs["config"])
        # the model preset that made the store (stores from before presets: "paper")
        self.model = self.config.get("model", "paper")
        # single fields changed from that preset (--set, a study file's [scene]); {} when none
        self.overrides = dict(self.config.get("overrides", {}))
        # what the rows are: "scan" (pair configurations) or "relax" (N-robot relaxation trials)
        self.kind = "relax" if "relax" in self.config else "scan"

    def run(self, name: str | None = None, fields=ROW_FIELDS) -> dict[str, np.ndarray]:
        """Named arrays of one run (default: the first)."""
        name = name or self.runs[0]
        if name not in self.runs:
            raise StoreError(f"{self.path} has no run {name!r} (runs: {', '.join(self.runs)})")
        missing = [k for k in fields if k not in self.run_fields[name]]
        if missing:
            hint = " (run the scan with --collisions)" if set(missing) & set(OPTIONAL_FIELDS) else ""
            raise StoreError(f"{self.path} run {name} has no {', '.join(missing)}{hint}")
        with h5py.File(self.path, "r") as f:
            g = f["runs"][name]
            return {k: g[k][()] for k in fields}

    def analysis_arrays(self, name: str | None = None) -> dict:
        """One scan run's per-period arrays as ``reduce.analysis`` reads them (its module docstring) and the
        run's attributes: ``touched`` (invalid starts cleared), ``valid``, ``rel``, ``com_xy`` (in body
        lengths W), ``heading``, ``status``, ``periods``, ``period_s``, ``amplitude_deg``, ``chirality``,
        ``gait``."""
        name = name or self.runs[0]
        d = self.run(name, fields=("valid", "touched", "rel", "com", "status"))
        attrs = self.run_attrs[name]
        w = float(self.config["scene"]["robot"]["body_length"])
        valid = d["valid"].astype(bool)
        return {"touched": d["touched"][:, :, 0] & valid[:, None], "valid": valid, "rel": d["rel"].astype(float),
                "com_xy": d["com"][..., :2].astype(float) / w, "heading": d["com"][..., 2].astype(float),
                "status": d["status"], "periods": int(attrs["periods"]), "period_s": float(attrs["period_s"]),
                "amplitude_deg": float(attrs["amplitude_deg"]), "chirality": str(attrs["chirality"]),
                "gait": str(attrs["gait"])}


# stage-independent settings of a relaxation store: two stores with the same
# values of everything else are stages of one study
_STAGE_KEYS = ("trials", "first_trial", "batch_size", "backend")


def read_relax(paths) -> RelaxRecord:
    """Rows of one or several relaxation stores (stages of one study; ``smx
    relax``), trials concatenated in trial order (:class:`RelaxRecord`); StoreError for stores
    that are not stages of one study or hold a trial twice."""
    paths = [paths] if not isinstance(paths, (list, tuple)) else list(paths)
    if not paths:
        raise StoreError("no relaxation store given")
    parts, stores = [], []
    for p in paths:
        st = Store(p)
        if st.kind != "relax":
            raise StoreError(f"{p} is a scan store, not a relaxation store (smx relax)")
        cfg = st.config["relax"]
        d = st.run("trials", fields=RELAX_FIELDS)
        d["trial"] = int(cfg.get("first_trial", 0)) + np.arange(len(d["valid"]))
        parts.append(d)
        stores.append(st)
    from .scene import params_from_json, params_json

    # the scene as its parameters read back: a field a store predates takes the value it had (so a stage
    # written before a scene field existed pools with one written after, where the field is at that value)
    same = lambda st: ({k: v for k, v in st.config["relax"].items() if k not in _STAGE_KEYS},  # noqa: E731
                       st.model, params_json(params_from_json(st.config["scene"])))
    for st in stores[1:]:
        if same(st) != same(stores[0]):
            raise StoreError(f"{st.path} and {stores[0].path} are not stages of one study (settings or model differ)")
    out = {k: np.concatenate([d[k] for d in parts]) for k in parts[0]}
    if len(np.unique(out["trial"])) != len(out["trial"]):
        raise StoreError("the stores hold the same trial twice")
    order = np.argsort(out["trial"], kind="stable")
    out = {k: v[order] for k, v in out.items()}
    st0 = stores[0]
    relax, robot = st0.config["relax"], st0.config["scene"]["robot"]
    return RelaxRecord(**out, settings=dict(relax), periods=int(relax["periods"]),
                       period_s=float(st0.run_attrs["trials"]["period_s"]), model=st0.model,
                       overrides=st0.overrides, body_length=float(robot["body_length"]),
                       body_thickness=float(robot["body_thickness"]), paths=tuple(str(p) for p in paths))


def is_scan_store(path) -> bool:
    """Whether ``path`` is an HDF5 store of runs (a scan, sweep or relaxation), not a track file.
    Raises StoreError for a .h5 file that HDF5 cannot read."""
    path = pathlib.Path(path)
    if path.suffix.lower() not in (".h5", ".hdf5"):
        return False
    try:
        with h5py.File(path, "r") as f:
            return "runs" in f
    except OSError:
        raise StoreError(f"{path} is not a readable HDF5 file") from None
