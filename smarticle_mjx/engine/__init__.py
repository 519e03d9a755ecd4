"""Rollout engine: one interface, four backends (``native``, ``mjx``, ``warp`` and ``dart``, the DART twin)."""

from __future__ import annotations

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


COLLISION_RECORD = ("native", "dart")  # backends that record the per-period collision record


def check_backend(name: str, collisions: bool = False) -> None:
    """ValueError for a backend the engine does not know, or one asked for a collision record it cannot make."""
    if name not in BACKENDS:
        raise ValueError(f"unknown backend {name!r}; choose one of {', '.join(BACKENDS)}")
    if collisions and name not in COLLISION_RECORD:
        raise ValueError("--collisions is recorded by the native and dart backends only")


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


__all__ = ["BACKENDS", "COLLISION_RECORD", "Lanes", "PeriodRecords", "Scene", "Status", "check_backend",
           "make_backend", "open_backend", "steps_per_period"]
