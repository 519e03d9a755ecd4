"""The track interchange format, measured and simulated: its one writer and its one reader.

CSV: one row per robot per frame, columns ``trial, t, robot, x, y, theta,
alpha1, alpha2`` (SI units: s, m, rad; arm angles may be empty; frames need
not be evenly spaced; rows may be missing), plus a JSON sidecar ``NAME.json``
describing robots, gait (kind square|symmetric, amplitude_deg, period_s,
chirality; or a list of such, one per robot), optional robot overrides,
plate friction, frame rate and an optional circular boundary. HDF5 (written
by ``smx simulate``): the same columns as datasets, the sidecar as an
attribute, plus the per-period records. Calibration (``calibrate.data``)
and movies (``movie``) read tracks only through here.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import pathlib

import numpy as np

from . import presets
from .gait import GaitSpec
from .scene import RobotParams, SceneParams

COLUMNS = ("trial", "t", "robot", "x", "y", "theta", "alpha1", "alpha2")


def sidecar(n_robots: int, gait, plate_friction: float, frame_rate_hz: float, model: str | None = None,
            overrides=()) -> dict:
    """The JSON sidecar of a track; ``model`` names the preset that simulated it, ``overrides`` the
    single fields changed from it (``--set``; recorded as {field: value} when any)."""
    return {
        "robots": n_robots,
        **({"model": model} if model is not None else {}),
        **({"overrides": presets.overrides_json(overrides)} if overrides else {}),
        "gait": {"kind": "symmetric" if gait.kind == "diagonal" else gait.kind,
                 "amplitude_deg": gait.amplitude_deg, "period_s": gait.period(),
                 "chirality": gait.chirality},
        "plate": {"friction": plate_friction},
        "frame_rate_hz": frame_rate_hz,
    }


def check_output(path) -> None:
    """Raise ValueError unless ``path`` is a writable .csv/.h5/.hdf5 target."""
    path = pathlib.Path(path)
    if path.suffix.lower() not in (".csv", ".h5", ".hdf5"):
        raise ValueError(f"output must end in .csv, .h5 or .hdf5, got {path.name!r}")
    if not path.parent.is_dir():
        raise ValueError(f"output directory {path.parent} does not exist")


def write_track(path, t, poses, meta: dict, records: dict | None = None, trial: int = 0) -> list[pathlib.Path]:
    """Write a track [S, N, 5] sampled at times ``t`` [S] to ``path``.

    ``.csv`` writes the CSV and its JSON sidecar; ``.h5``/``.hdf5`` writes one
    HDF5 file (``records``, if given, goes into group ``periods``). The file
    is written next to its final name and renamed, so a failed write leaves
    no half file. Returns the paths written.
    """
    path = pathlib.Path(path)
    t = np.asarray(t, dtype=float)
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 3 or poses.shape[0] != t.shape[0] or poses.shape[2] != 5:
        raise ValueError("track must be [S, N, 5] with S times")
    check_output(path)
    suffix = path.suffix.lower()
    tmp = path.with_name(path.name + ".part")
    written = [path]
    s, n = poses.shape[:2]
    if suffix == ".csv":
        with open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(COLUMNS)
            for k in range(s):
                for i in range(n):
                    x, y, h, a1, a2 = poses[k, i]
                    w.writerow([trial, f"{t[k]:.6f}", i, f"{x:.9g}", f"{y:.9g}", f"{h:.9g}", f"{a1:.9g}", f"{a2:.9g}"])
        side = path.with_suffix(".json")
        side_tmp = side.with_name(side.name + ".part")
        side_tmp.write_text(json.dumps(meta, indent=2))
        tmp.replace(path)
        side_tmp.replace(side)
        written.append(side)
    else:
        import h5py
        with h5py.File(tmp, "w") as f:
            f.attrs["meta"] = json.dumps(meta)
            f["t"] = t
            for j, name in enumerate(("x", "y", "theta", "alpha1", "alpha2")):
                f[name] = poses[:, :, j]
            if records:
                g = f.create_group("periods")
                for k, v in records.items():
                    g[k] = v
        tmp.replace(path)
    return written


@dataclasses.dataclass(frozen=True)
class TrackedTrial:
    """One trial of a track file: frame times [F], poses [F, N, 5] (x, y, heading unwrapped, arm
    angles; NaN where occluded or untracked), whether any arm angle is tracked, every robot's gait,
    the scene to compare with and the nominal frame rate."""

    name: str
    t: np.ndarray
    poses: np.ndarray
    arms_tracked: bool
    gaits: tuple
    params: SceneParams
    frame_rate_hz: float
    measured: tuple = ()  # ((name, value, sd), ...): the sidecar's measured values with their uncertainties


class TrackError(ValueError):
    """A file that cannot be read as the interchange format."""


def read_sidecar(csv_path: pathlib.Path) -> dict:
    side = csv_path.with_suffix(".json")
    if not side.is_file():
        raise TrackError(f"{csv_path.name} has no sidecar {side.name}")
    try:
        meta = json.loads(side.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise TrackError(f"sidecar {side.name} is not valid JSON: {e}") from None
    for key in ("robots", "gait"):
        if key not in meta:
            raise TrackError(f"sidecar {side.name} lacks {key!r}")
    return meta


def sidecar_gait(g, where: str) -> GaitSpec:
    if not isinstance(g, dict):
        raise TrackError(f"{where}: a gait must be an object with amplitude_deg etc., got {g!r}")
    kind = {"square": "square", "symmetric": "diagonal", "diagonal": "diagonal"}.get(g.get("kind", "square"))
    if kind is None:
        raise TrackError(f"{where}: gait kind must be square or symmetric, got {g.get('kind')!r}")
    try:
        spec = GaitSpec(amplitude_deg=float(g["amplitude_deg"]), chirality=g.get("chirality", "ccw"), kind=kind,
                        period_s=float(g["period_s"]) if g.get("period_s") is not None else None)
    except (KeyError, TypeError, ValueError) as e:
        raise TrackError(f"{where}: bad gait {g}: {e}") from None
    return spec


def _gaits(meta: dict, n: int, where: str) -> tuple[GaitSpec, ...]:
    """One gait for every robot (``"gait": {...}``) or one per robot (``"gait": [{...}, ...]``)."""
    g = meta["gait"]
    if isinstance(g, list):
        if len(g) != n:
            raise TrackError(f"{where}: the gait list has {len(g)} entries for {n} robots (one per robot, or one "
                            "object for all)")
        return tuple(sidecar_gait(x, where) for x in g)
    return (sidecar_gait(g, where),) * n


def _sidecar_model(meta: dict, model: str | None = None) -> SceneParams:
    """Preset ``model`` if given, else the sidecar's ``model``, else the default preset, with the
    fields ``smx simulate --set`` changed (the sidecar's ``overrides``); ValueError if unknown or bad."""
    base = presets.params(model if model is not None else meta.get("model"))
    return presets.apply(base, presets.table_overrides(meta.get("overrides") or {}))


def _params(meta: dict, gaits, where: str, model: str | None = None) -> SceneParams:
    """The model to compare the data with: preset ``model`` if given, else the
    sidecar's ``model``, else the default preset, with the fields ``smx simulate --set`` changed
    (``overrides``); then the sidecar's robot and plate overrides."""
    try:
        base = _sidecar_model(meta, model)
    except ValueError as e:
        raise TrackError(f"{where}: {e}") from None
    robot = base.robot
    over = meta.get("robot") or {}
    fields = {f.name for f in dataclasses.fields(RobotParams)}
    unknown = set(over) - fields
    if unknown:
        raise TrackError(f"{where}: unknown robot overrides {sorted(unknown)} (known: {', '.join(sorted(fields))})")
    robot = dataclasses.replace(robot, **over)
    params = base.replace(robot=robot)
    plate = meta.get("plate") or {}
    if "friction" in plate:
        params = params.replace(plate_friction=float(plate["friction"]))
    bnd = meta.get("boundary")
    if bnd is not None:
        try:
            radius = float(bnd["radius"])
        except (KeyError, TypeError, ValueError):
            raise TrackError(f"{where}: boundary needs a radius in m, got {bnd!r}") from None
        params = params.replace(boundary_radius=radius)
    try:
        params.validate()
    except ValueError as e:
        raise TrackError(f"{where}: {e}") from None
    for i, gait in enumerate(gaits):
        try:
            gait.validate(robot.servo_speed, robot.arm_limit_deg)
        except ValueError as e:
            raise TrackError(f"{where}: {'' if len(set(gaits)) == 1 else f'robot {i}: '}{e}") from None
    return params


def _measured(meta: dict, where: str) -> tuple:
    """The sidecar's ``measured`` values: {name: [value, sd]} (sd > 0, both finite) -> ((name, value, sd), ...)."""
    m = meta.get("measured") or {}
    if not isinstance(m, dict):
        raise TrackError(f"{where}: measured must be an object {{name: [value, sd]}}, got {m!r}")
    out = []
    for name, pair in sorted(m.items()):
        try:
            value, sd = (float(x) for x in pair)
        except (TypeError, ValueError):
            raise TrackError(f"{where}: measured {name} must be [value, sd], got {pair!r}") from None
        if not (math.isfinite(value) and math.isfinite(sd) and sd > 0):
            raise TrackError(f"{where}: measured {name} needs a finite value and an sd > 0, got {pair!r}")
        out.append((str(name), value, sd))
    return tuple(out)


def _num(text: str, row: int, col: str, where: str, allow_empty=False) -> float:
    if text is None or text.strip() == "":
        if allow_empty:
            return math.nan
        raise TrackError(f"{where} line {row}: empty {col}")
    try:
        v = float(text)
    except ValueError:
        raise TrackError(f"{where} line {row}: {col} is not a number: {text!r}") from None
    if not math.isfinite(v) and not allow_empty:
        raise TrackError(f"{where} line {row}: {col} is not finite")
    return v


def read_csv(path, model: str | None = None) -> list[TrackedTrial]:
    """All trials of one CSV file with its sidecar, with the scene to compare them with: preset
    ``model`` (default: the sidecar's, else the default preset) and the sidecar's overrides.
    Positions are shifted so that a boundary's centre is the origin; headings are unwrapped."""
    path = pathlib.Path(path)
    where = path.name
    meta = read_sidecar(path)
    try:
        n = int(meta["robots"])
    except (TypeError, ValueError):
        raise TrackError(f"{where}: robots must be a whole number, got {meta['robots']!r}") from None
    if n < 1:
        raise TrackError(f"{where}: robots must be >= 1")
    gaits = _gaits(meta, n, where)
    params = _params(meta, gaits, where, model)
    measured = _measured(meta, where)
    centre = np.zeros(2)
    if meta.get("boundary") is not None:
        try:
            centre = np.asarray(meta["boundary"].get("centre", [0.0, 0.0]), float).reshape(2)
        except (TypeError, ValueError):
            raise TrackError(f"{where}: boundary centre must be [x, y] in m") from None
    rows: dict[int, dict[float, dict[int, tuple]]] = {}
    try:
        f = path.open(newline="")
    except OSError as e:
        raise TrackError(f"cannot read {path}: {e.strerror}") from None
    with f:
        reader = csv.DictReader(f)
        if reader.fieldnames is None or [c.strip() for c in reader.fieldnames] != list(COLUMNS):
            raise TrackError(f"{where}: columns must be {','.join(COLUMNS)}, got {reader.fieldnames}")
        for k, row in enumerate(reader, start=2):
            trial = int(_num(row["trial"], k, "trial", where))
            t = _num(row["t"], k, "t", where)
            robot = int(_num(row["robot"], k, "robot", where))
            if not 0 <= robot < n:
                raise TrackError(f"{where} line {k}: robot {robot} outside 0..{n - 1}")
            vals = tuple(_num(row[c], k, c, where, allow_empty=c.startswith("alpha"))
                         for c in ("x", "y", "theta", "alpha1", "alpha2"))
            rows.setdefault(trial, {}).setdefault(t, {})[robot] = vals
    if not rows:
        raise TrackError(f"{where}: no data rows")
    trials = []
    for trial, frames in sorted(rows.items()):
        times = np.array(sorted(frames))
        if len(times) < 3:
            raise TrackError(f"{where} trial {trial}: fewer than 3 frames")
        data = np.full((len(times), n, 5), np.nan)
        for j, t in enumerate(times):
            for robot, v in frames[t].items():
                data[j, robot] = v
        data[..., :2] -= centre  # the model's circular wall is centred on the origin
        for i in range(n):
            if not np.isfinite(data[0, i, :3]).all():
                raise TrackError(f"{where} trial {trial}: robot {i} is not tracked in the first frame "
                                "(the model starts from it)")
            ok = np.isfinite(data[:, i, 2])
            data[ok, i, 2] = np.unwrap(data[ok, i, 2])
        trials.append(TrackedTrial(f"{path.stem}:{trial}", times, data, bool(np.isfinite(data[..., 3:]).any()),
                                   gaits, params, float(meta.get("frame_rate_hz", 1.0 / np.median(np.diff(times)))),
                                   measured))
    return trials


def read_h5(path) -> tuple:
    """(t [S], poses [S, N, 5], gait, robot) of a track that ``smx simulate`` wrote as HDF5."""
    import h5py
    path = pathlib.Path(path)
    with h5py.File(path, "r") as f:
        if "t" not in f or "meta" not in f.attrs:
            raise TrackError(f"{path} is neither a scan store nor a track from smx simulate")
        meta = json.loads(f.attrs["meta"])
        t = f["t"][()]
        poses = np.stack([f[k][()] for k in ("x", "y", "theta", "alpha1", "alpha2")], -1)
    try:
        params = _sidecar_model(meta)
    except ValueError as e:
        raise TrackError(f"{path}: {e}") from None
    return t, poses, sidecar_gait(meta["gait"], path.name), params.robot
