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


__all__ = ["BACKENDS", "Lanes", "PeriodRecords", "Scene", "Status", "make_backend", "steps_per_period"]
