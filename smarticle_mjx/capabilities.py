"""What each engine backend can run, in one table: every option a backend cannot run is refused by one rule
(:func:`require`) with one message naming the backends that run it. Nothing else in the package checks a
backend by its name (tests/test_layout.py keeps it so), beyond choosing the backend's class
(``engine.make_backend``)."""

from __future__ import annotations

import dataclasses


@dataclasses.dataclass(frozen=True)
class Feature:
    """An option some backends run: its key and the words a refusal names it with (a plural noun phrase)."""

    key: str
    what: str


FEATURES = {f.key: f for f in (
    Feature("per_arm_speeds", "arms with their own servo speeds (imperfections)"),
    Feature("start_delays", "robots started at different times (imperfections' start offsets, a relaxation's phase "
                            "jitter)"),
    Feature("own_clocks", "robots with their own gait periods in one lane (clock drift)"),
    Feature("retrigger", "robots whose timing changes after the start (a per-cycle re-trigger, lasting offsets "
                         "that set in)"),
    Feature("start_ref", "servo references started at the arms (a replay of measured trials)"),
    Feature("arm_mounts", "arms with mounts (robot.arm_mount_length > 0)"),
    Feature("robot_quirks", "robots with gear backlash or centre-of-mass offsets"),
    Feature("collision_record", "collision records (--collisions)"),
    Feature("full_rate_tracks", "full-rate tracks"),
    Feature("mujoco_numerics", "MuJoCo's numerics (the scene's step, integrator and contacts)"),
    Feature("own_numerics", "numerics of the backend's own (dart_numerics)"),
)}

# backend -> the features it runs
CAPABILITIES: dict[str, frozenset[str]] = {
    "native": frozenset(FEATURES) - {"own_numerics"},
    "mjx": frozenset({"own_clocks", "retrigger", "robot_quirks", "mujoco_numerics"}),
    "warp": frozenset({"per_arm_speeds", "robot_quirks", "mujoco_numerics"}),
    "dart": frozenset({"per_arm_speeds", "collision_record", "full_rate_tracks", "own_numerics"}),
}


def supports(backend: str, feature: str) -> bool:
    """Whether ``backend`` runs ``feature`` (a key of :data:`FEATURES`; KeyError for an unknown one)."""
    FEATURES[feature]
    return feature in CAPABILITIES.get(backend, frozenset())


def backends_with(feature: str) -> tuple[str, ...]:
    """The backends that run ``feature``, in the table's order."""
    return tuple(b for b, can in CAPABILITIES.items() if feature in can)


def refusal(backend: str, feature: str) -> str:
    """The one message refusing ``feature`` on ``backend``."""
    ok = backends_with(feature)
    where = ok[0] if len(ok) == 1 else ", ".join(ok[:-1]) + " and " + ok[-1]
    return f"{FEATURES[feature].what} run on the {where} backend{'s' if len(ok) > 1 else ''}, not {backend}"


def require(backend: str, feature: str, prefix: str = "") -> None:
    """ValueError (one line: ``prefix`` and :func:`refusal`) unless ``backend`` runs ``feature``."""
    if not supports(backend, feature):
        raise ValueError(prefix + refusal(backend, feature))


def markdown() -> list[str]:
    """The table as docs/engine.md prints it (a test keeps the page equal to it)."""
    backends = list(CAPABILITIES)
    lines = ["| option | " + " | ".join(backends) + " |", "|---|" + "---|" * len(backends)]
    for f in FEATURES.values():
        cells = ("yes" if f.key in CAPABILITIES[b] else "–" for b in backends)
        lines.append(f"| {f.what} | " + " | ".join(cells) + " |")
    return lines
