"""Measured trials in the interchange format (CSV + JSON sidecar, see docs/calibration.md).

CSV: one row per robot per frame, ``trial, t, robot, x, y, theta, alpha1,
alpha2`` in s, m, rad; ``alpha1``/``alpha2`` may be empty; frames need not
be evenly spaced; rows may be missing. Sidecar ``NAME.json``: robots, gait
(kind square|symmetric, amplitude_deg, period_s, chirality cw|ccw; or a list
of such, one per robot),
optional robot overrides, plate friction, frame rate, and an optional circular
boundary ``{"radius": m, "centre": [x, y]}`` (positions are shifted so that it
is centred on the origin, where the model's wall is).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import pathlib

import numpy as np

from .. import presets
from ..gait import GaitSpec
from ..scene import RobotParams, SceneParams
from ..tracks import COLUMNS


@dataclasses.dataclass
class Trial:
    """One tracked experiment.

    Attributes:
      name: ``FILE:trial``.
      t: [F] frame times (s), increasing.
      pose: [F, N, 3] x, y (m), heading (rad, unwrapped); NaN where occluded.
      arms: [F, N, 2] arm angles (rad), NaN where not tracked; None if the
        file tracks no arm angles at all.
      gait: the commanded gait of robot 0 (the trial's clock).
      params: scene parameters with the sidecar's overrides.
      frame_rate_hz: nominal frame rate from the sidecar.
      gaits: every robot's commanded gait; None: all run ``gait``.
    """

    name: str
    t: np.ndarray
    pose: np.ndarray
    arms: np.ndarray | None
    gait: GaitSpec
    params: SceneParams
    frame_rate_hz: float
    gaits: tuple[GaitSpec, ...] | None = None

    def __post_init__(self):
        n = self.pose.shape[1]
        if self.gaits is None:
            self.gaits = (self.gait,) * n
        else:
            self.gaits = tuple(self.gaits)
            if len(self.gaits) != n or self.gaits[0] != self.gait:
                raise ValueError(f"{self.name}: gaits must list {n} gaits, the first being the trial's gait")

    @property
    def robots(self) -> int:
        return self.pose.shape[1]

    @property
    def periods(self) -> np.ndarray:
        """[N] each robot's gait period (s)."""
        return np.array([g.period() for g in self.gaits])

    @property
    def one_gait(self) -> bool:
        """Whether every robot runs the same gait."""
        return len(set(self.gaits)) == 1

    def with_gaits(self, fn) -> "Trial":
        """This trial with every robot's gait replaced by ``fn(gait)``."""
        gaits = tuple(fn(g) for g in self.gaits)
        return dataclasses.replace(self, gait=gaits[0], gaits=gaits)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])


class DataError(ValueError):
    """Measured data that cannot be read as the interchange format."""


def _sidecar(csv_path: pathlib.Path) -> dict:
    side = csv_path.with_suffix(".json")
    if not side.is_file():
        raise DataError(f"{csv_path.name} has no sidecar {side.name}")
    try:
        meta = json.loads(side.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise DataError(f"sidecar {side.name} is not valid JSON: {e}") from None
    for key in ("robots", "gait"):
        if key not in meta:
            raise DataError(f"sidecar {side.name} lacks {key!r}")
    return meta


def _one_gait(g, where: str) -> GaitSpec:
    if not isinstance(g, dict):
        raise DataError(f"{where}: a gait must be an object with amplitude_deg etc., got {g!r}")
    kind = {"square": "square", "symmetric": "diagonal", "diagonal": "diagonal"}.get(g.get("kind", "square"))
    if kind is None:
        raise DataError(f"{where}: gait kind must be square or symmetric, got {g.get('kind')!r}")
    try:
        spec = GaitSpec(amplitude_deg=float(g["amplitude_deg"]), chirality=g.get("chirality", "ccw"), kind=kind,
                        period_s=float(g["period_s"]) if g.get("period_s") is not None else None)
    except (KeyError, TypeError, ValueError) as e:
        raise DataError(f"{where}: bad gait {g}: {e}") from None
    return spec


def _gaits(meta: dict, n: int, where: str) -> tuple[GaitSpec, ...]:
    """One gait for every robot (``"gait": {...}``) or one per robot (``"gait": [{...}, ...]``)."""
    g = meta["gait"]
    if isinstance(g, list):
        if len(g) != n:
            raise DataError(f"{where}: the gait list has {len(g)} entries for {n} robots (one per robot, or one "
                            "object for all)")
        return tuple(_one_gait(x, where) for x in g)
    return (_one_gait(g, where),) * n


def _params(meta: dict, gaits, where: str, model: str | None = None) -> SceneParams:
    """The model to compare the data with: preset ``model`` if given, else the
    sidecar's ``model``, else the default preset; then the sidecar's robot and
    plate overrides."""
    try:
        base = presets.params(model if model is not None else meta.get("model"))
    except ValueError as e:
        raise DataError(f"{where}: {e}") from None
    robot = base.robot
    over = meta.get("robot") or {}
    fields = {f.name for f in dataclasses.fields(RobotParams)}
    unknown = set(over) - fields
    if unknown:
        raise DataError(f"{where}: unknown robot overrides {sorted(unknown)} (known: {', '.join(sorted(fields))})")
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
            raise DataError(f"{where}: boundary needs a radius in m, got {bnd!r}") from None
        params = params.replace(boundary_radius=radius)
    try:
        params.validate()
    except ValueError as e:
        raise DataError(f"{where}: {e}") from None
    for i, gait in enumerate(gaits):
        try:
            gait.validate(robot.servo_speed, robot.arm_limit_deg)
        except ValueError as e:
            raise DataError(f"{where}: {'' if len(set(gaits)) == 1 else f'robot {i}: '}{e}") from None
    return params


def _num(text: str, row: int, col: str, where: str, allow_empty=False) -> float:
    if text is None or text.strip() == "":
        if allow_empty:
            return math.nan
        raise DataError(f"{where} line {row}: empty {col}")
    try:
        v = float(text)
    except ValueError:
        raise DataError(f"{where} line {row}: {col} is not a number: {text!r}") from None
    if not math.isfinite(v) and not allow_empty:
        raise DataError(f"{where} line {row}: {col} is not finite")
    return v


def load_csv(path, model: str | None = None) -> list[Trial]:
    """All trials of one CSV file with its sidecar, compared with preset
    ``model`` (default: the sidecar's, else the default preset)."""
    path = pathlib.Path(path)
    where = path.name
    meta = _sidecar(path)
    try:
        n = int(meta["robots"])
    except (TypeError, ValueError):
        raise DataError(f"{where}: robots must be a whole number, got {meta['robots']!r}") from None
    if n < 1:
        raise DataError(f"{where}: robots must be >= 1")
    gaits = _gaits(meta, n, where)
    params = _params(meta, gaits, where, model)
    centre = np.zeros(2)
    if meta.get("boundary") is not None:
        try:
            centre = np.asarray(meta["boundary"].get("centre", [0.0, 0.0]), float).reshape(2)
        except (TypeError, ValueError):
            raise DataError(f"{where}: boundary centre must be [x, y] in m") from None
    rows: dict[int, dict[float, dict[int, tuple]]] = {}
    try:
        f = path.open(newline="")
    except OSError as e:
        raise DataError(f"cannot read {path}: {e.strerror}") from None
    with f:
        reader = csv.DictReader(f)
        if reader.fieldnames is None or [c.strip() for c in reader.fieldnames] != list(COLUMNS):
            raise DataError(f"{where}: columns must be {','.join(COLUMNS)}, got {reader.fieldnames}")
        for k, row in enumerate(reader, start=2):
            trial = int(_num(row["trial"], k, "trial", where))
            t = _num(row["t"], k, "t", where)
            robot = int(_num(row["robot"], k, "robot", where))
            if not 0 <= robot < n:
                raise DataError(f"{where} line {k}: robot {robot} outside 0..{n - 1}")
            vals = tuple(_num(row[c], k, c, where, allow_empty=c.startswith("alpha"))
                         for c in ("x", "y", "theta", "alpha1", "alpha2"))
            rows.setdefault(trial, {}).setdefault(t, {})[robot] = vals
    if not rows:
        raise DataError(f"{where}: no data rows")
    trials = []
    for trial, frames in sorted(rows.items()):
        times = np.array(sorted(frames))
        if len(times) < 3:
            raise DataError(f"{where} trial {trial}: fewer than 3 frames")
        data = np.full((len(times), n, 5), np.nan)
        for j, t in enumerate(times):
            for robot, v in frames[t].items():
                data[j, robot] = v
        data[..., :2] -= centre  # the model's circular wall is centred on the origin
        for i in range(n):
            if not np.isfinite(data[0, i, :3]).all():
                raise DataError(f"{where} trial {trial}: robot {i} is not tracked in the first frame "
                                "(the model starts from it)")
            ok = np.isfinite(data[:, i, 2])
            data[ok, i, 2] = np.unwrap(data[ok, i, 2])
        tracked = np.isfinite(data[..., 3:]).any()
        trials.append(Trial(f"{path.stem}:{trial}", times, data[..., :3], data[..., 3:] if tracked else None,
                            gaits[0], params, float(meta.get("frame_rate_hz", 1.0 / np.median(np.diff(times)))),
                            gaits))
    return trials


def load(path, model: str | None = None) -> list[Trial]:
    """Trials from one CSV (with sidecar) or every CSV in a directory (see :func:`load_csv` for ``model``)."""
    path = pathlib.Path(path)
    if path.is_dir():
        files = sorted(path.glob("*.csv"))
        if not files:
            raise DataError(f"{path} holds no .csv files")
        return [t for f in files for t in load_csv(f, model)]
    if not path.exists():
        raise DataError(f"no data at {path}")
    if path.suffix.lower() != ".csv":
        raise DataError(f"measured data must be .csv with a .json sidecar, got {path.name}")
    return load_csv(path, model)
