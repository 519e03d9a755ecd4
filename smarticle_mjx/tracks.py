"""Write simulated tracks in the interchange format measured data also uses.

CSV: one row per robot per frame, columns ``trial, t, robot, x, y, theta,
alpha1, alpha2`` (SI units: s, m, rad), plus a JSON sidecar ``NAME.json``
describing robots, gait, plate and frame rate. HDF5: the same columns as
datasets, plus the per-period records.
"""

from __future__ import annotations

import csv
import json
import pathlib

import numpy as np

COLUMNS = ("trial", "t", "robot", "x", "y", "theta", "alpha1", "alpha2")


def sidecar(n_robots: int, gait, plate_friction: float, frame_rate_hz: float, model: str | None = None) -> dict:
    """The JSON sidecar of a track; ``model`` names the preset that simulated it."""
    return {
        "robots": n_robots,
        **({"model": model} if model is not None else {}),
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
