"""Study files (TOML, sweeps/): read into the specs of :mod:`smarticle_mjx.specs`.

:func:`read_study` reads any study file (a scan, a started-bound or a relaxation study); :func:`load_study`
only scans (``smx scan --study``); :func:`read_relax_screen` a relaxation screen (``sweeps/screens/``);
:func:`sweep_config` a sweep's spec from a study file and the command line's options. Bad files and
keys: ValueError, one line.
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import tomllib

from . import presets
from .specs import BoundStudy, RelaxConfig, RelaxStudy, ScanConfig, config_keywords, with_overrides


def parse_amplitudes(text: str) -> tuple[float, ...]:
    """'10:90:10' (inclusive range) or '10,40,90' -> amplitudes in degrees."""
    text = text.strip()
    try:
        if ":" in text:
            lo, hi, step = (float(x) for x in text.split(":"))
            if step <= 0 or hi < lo:
                raise ValueError
            n = int(math.floor((hi - lo) / step + 1e-9)) + 1
            return tuple(round(lo + k * step, 6) for k in range(n))
        return tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise ValueError(f"amplitudes must look like '10:90:10' or '10,40,90', got {text!r}") from None


def sweep_config(study=None, amplitudes: str | None = None, sets=(), **changes) -> ScanConfig:
    """A sweep's spec: the study file ``study`` (or the default scan) with ``amplitudes``
    ('10:90:10' or '10,40,90'), the non-None ``changes`` (ScanConfig fields) and the scene overrides
    ``sets`` (FIELD=VALUE, on top of the study file's [scene]) applied."""
    cfg = load_study(study) if study is not None else ScanConfig()
    cfg = with_overrides(cfg, presets.overrides(sets))
    changes = {k: v for k, v in changes.items() if v is not None}
    if amplitudes is not None:
        changes["amplitudes_deg"] = parse_amplitudes(amplitudes)
    elif study is None:
        raise ValueError("give --amplitudes or --study")
    cfg = dataclasses.replace(cfg, **changes)
    presets.get(cfg.model)
    return cfg


def _study_table(path: pathlib.Path) -> dict:
    """The ``[study]`` table of a study file (or its top level), its ``[scene]`` table as ``overrides``;
    ValueError for a missing or unreadable file or a bad override."""
    try:
        raw = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"study file {path} does not exist") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"cannot read study file {path}: {e}") from None
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"study file {path} is not valid TOML: {e}") from None
    study = dict(raw.get("study", raw))
    scene = raw.get("scene") if "study" in raw else study.pop("scene", None)
    if scene is not None:  # [scene]: single fields of the preset changed, as --set does
        try:
            study["overrides"] = presets.table_overrides(scene)
        except ValueError as e:
            raise ValueError(f"study file {path}: [scene] {e}") from None
    return study


def _scan_study(study: dict, path: pathlib.Path) -> ScanConfig:
    """A scan study's table (keys are ScanConfig fields) as its spec."""
    fields = {f.name for f in dataclasses.fields(ScanConfig)}
    unknown = set(study) - fields - {"description", "figure"}
    if unknown:
        raise ValueError(f"study file {path}: unknown keys {sorted(unknown)}")
    kw = config_keywords(study)
    try:
        return ScanConfig(**kw)
    except TypeError as e:
        raise ValueError(f"study file {path}: {e}") from None


def load_study(path) -> ScanConfig:
    """A study file (TOML) from sweeps/: keys are ScanConfig fields."""
    path = pathlib.Path(path)
    study = _study_table(path)
    if study.get("configs") == "bound":
        raise ValueError(f"study file {path} starts pairs from another study's gliders; smx validate runs it")
    if study.get("configs") == "relax":
        raise ValueError(f"study file {path} is a relaxation study (smx relax); smx validate runs it")
    return _scan_study(study, path)


def read_relax_screen(path) -> tuple[dict, dict[str, RelaxStudy]]:
    """A relaxation screen (``sweeps/screens/``): a ``[screen]`` table (trials, periods, seed,
    amplitude_deg) and ``[[variant]]`` tables, each a name, RelaxConfig keys and an optional ``set``
    list of scene overrides (``--set FIELD=VALUE``). Returns the screen table and each variant as a
    one-stage :class:`RelaxStudy`; ValueError (one line) for a bad file or variant."""
    path = pathlib.Path(path)
    try:
        raw = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise ValueError(f"screen file {path}: {e}") from None
    screen, variants = raw.get("screen"), raw.get("variant")
    if not isinstance(screen, dict) or not isinstance(variants, list) or not variants:
        raise ValueError(f"screen file {path}: needs a [screen] table and [[variant]] tables")
    known = {f.name for f in dataclasses.fields(RelaxConfig)} - {"trials", "first_trial", "model", "overrides",
                                                                   "periods", "seed", "amplitude_deg"}
    out = {}
    for v in variants:
        name = v.get("name")
        if not name or name in out:
            raise ValueError(f"screen file {path}: every variant needs a name of its own, got {name!r}")
        unknown = set(v) - known - {"name", "set"}
        if unknown:
            raise ValueError(f"screen file {path}: variant {name}: unknown keys {sorted(unknown)}")
        keys = {k: val for k, val in v.items() if k in known}
        try:
            keys.update(periods=int(screen["periods"]), seed=int(screen["seed"]),
                        amplitude_deg=float(screen["amplitude_deg"]))
            if v.get("set"):
                keys["overrides"] = presets.overrides(v["set"])
            rs = RelaxStudy(stages=1, trials=int(screen["trials"]), settings=tuple(sorted(keys.items())))
            rs.validate()
        except (KeyError, TypeError, ValueError) as e:
            raise ValueError(f"screen file {path}: variant {name}: {e}") from None
        out[name] = rs
    return screen, out


def read_study(path) -> ScanConfig | BoundStudy | RelaxStudy:
    """A study file from sweeps/: a scan (``ScanConfig`` keys), a started-bound or a relaxation study."""
    path = pathlib.Path(path)
    study = _study_table(path)
    if study.get("configs") == "relax":
        known = {f.name for f in dataclasses.fields(RelaxConfig)} - {"trials", "first_trial", "model"}
        own = {"stages", "trials", "description", "figure", "configs"}
        unknown = set(study) - known - own
        if unknown:
            raise ValueError(f"study file {path}: unknown keys {sorted(unknown)}")
        try:
            rs = RelaxStudy(stages=int(study.get("stages", 1)), trials=int(study.get("trials", 20)),
                            settings=tuple(sorted((k, v) for k, v in study.items() if k in known)),
                            description=study.get("description", ""), figure=study.get("figure", ""))
            rs.validate()
        except (TypeError, ValueError) as e:
            raise ValueError(f"study file {path}: {e}") from None
        return rs
    if study.get("configs") != "bound":
        return _scan_study(study, path)
    fields = {f.name for f in dataclasses.fields(BoundStudy)}
    unknown = set(study) - fields - {"configs"}
    if unknown:
        raise ValueError(f"study file {path}: unknown keys {sorted(unknown)}")
    kw = {k: v for k, v in study.items() if k in fields}
    if "amplitudes_deg" in kw:
        kw["amplitudes_deg"] = tuple(float(x) for x in kw["amplitudes_deg"])
    try:
        bs = BoundStudy(**kw)
    except TypeError as e:
        raise ValueError(f"study file {path}: {e}") from None
    bs.validate()
    return bs
