"""Rollout engine: one interface, four backends (``native``, ``mjx``, ``warp`` and ``dart``, the DART twin)."""

from __future__ import annotations

import dataclasses

from ..capabilities import CAPABILITIES, backends_with, require, supports
from .core import Lanes, PeriodRecords, Scene, Status, steps_per_period

BACKENDS = ("native", "mjx", "warp", "dart")


def make_backend(name: str, scene: Scene, nthread: int | None = None, **kw):
    """Backend by name. ``nthread`` applies to the native backend only."""
    if name == "native":
        from .native import NativeBackend
        return NativeBackend(scene, nthread=nthread, **kw)
    if name == "mjx":
        from .mjx import MjxBackend
        return MjxBackend(scene, **kw)
    if name == "warp":
        from .mjwarp import WarpBackend
        return WarpBackend(scene, **kw)
    if name == "dart":
        from .dart import DartBackend
        return DartBackend(scene, **kw)
    raise ValueError(f"unknown backend {name!r}; choose one of {', '.join(BACKENDS)}")


COLLISION_RECORD = backends_with("collision_record")  # backends that record the per-period collision record
TRACK_RECORD = backends_with("full_rate_tracks")  # backends that record full-rate tracks


def check_backend(name: str, collisions: bool = False, tracks: bool = False) -> None:
    """ValueError for a backend the engine does not know, or one asked for a record it cannot make (the
    collision record, full-rate tracks; ``capabilities.require``)."""
    if name not in BACKENDS:
        raise ValueError(f"unknown backend {name!r}; choose one of {', '.join(BACKENDS)}")
    if collisions:
        require(name, "collision_record")
    if tracks:
        require(name, "full_rate_tracks")


@dataclasses.dataclass(frozen=True)
class StudyEngine:
    """The engine a study runs on: a backend's name and the backend's own settings, which only the engine
    reads (the DART twin's numerics, as a spec carries them: (time step s, collision detector, LCP
    solver[, servo]), None for its defaults; no other backend takes any). A spec holds the two values and
    hands them here whole: :meth:`check` is the one check of a study's backend, :meth:`options` what
    ``make_backend`` takes beyond the scene, :meth:`timestep` the step the engine takes, :meth:`record`
    what a store records of them. MuJoCo's own numerics stay in the scene's presets."""

    backend: str = "native"
    settings: tuple | None = None

    def check(self, params=None, overrides=(), collisions: bool = False, tracks: bool = False) -> None:
        """ValueError (one line) for a backend the engine does not know, a record it cannot make (the
        collision record, full-rate tracks), settings it does not take or cannot build ``params`` with, a
        field of ``overrides`` it does not read, or a backend whose package is not installed."""
        check_backend(self.backend, collisions, tracks)
        from .dart import check_study
        check_study(self.backend, self.settings, params, overrides)
        if self.backend == "warp":  # the backend registry: the one place that names backends
            from . import mjwarp
            if not mjwarp.available():
                raise ValueError(mjwarp.MISSING)

    def options(self) -> dict:
        """Keyword arguments of ``make_backend`` beyond the scene."""
        from .dart import study_options
        return study_options(self.backend, self.settings)

    def timestep(self, scene_timestep: float) -> float:
        """The step the engine takes: its own settings' on the DART twin, the scene's on MuJoCo."""
        from .dart import study_timestep
        return study_timestep(self.backend, self.settings, scene_timestep)

    def record(self, spec_json: dict) -> dict:
        """``spec_json`` (a spec's stored JSON, holding the settings as given) as a store records it: the
        settings resolved where the backend takes them, absent elsewhere (stores keep their old form)."""
        from .dart import study_json
        return study_json(spec_json, self.backend)


def open_backend(name: str, params, n_robots: int, *, collisions: bool = False, nthread: int | None = None,
                 **options):
    """A backend ``name`` for a scene of ``n_robots`` robots built with the sensors its records need
    (the per-period touch record; with ``collisions``, the collision record's force sensors).
    Refuses, before building anything, a backend it does not know or a record the backend cannot
    make. ``nthread``: the native backend's threads; ``options``: the backend's own keywords.
    Use it as a context manager, or close it."""
    check_backend(name, collisions)
    scene = Scene.build(params, n_robots, collisions=collisions)
    return make_backend(name, scene, nthread=nthread, **options)


__all__ = ["BACKENDS", "CAPABILITIES", "COLLISION_RECORD", "Lanes", "PeriodRecords", "Scene", "Status", "StudyEngine",
           "check_backend", "make_backend", "open_backend", "require", "steps_per_period", "supports"]
