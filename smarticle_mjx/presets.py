"""Named model presets: the one place where a model's numbers are chosen.

A preset is a robot geometry and a servo, bound into one ``SceneParams``
(like Playground's ``registry.py`` binds environment variants). Every value a
preset sets cites where it comes from; sources are public smarticle code
(``shared/reference/smarticle.md``, "Beyond the paper's text") or the paper.
Nothing here was chosen to match a number the model is then checked against:
the values were fixed before the screening study (``benchmarks/fidelity_screen.py``,
``docs/fidelity.md``) ran.

Every command that builds a scene takes ``--model NAME``; every store and
track sidecar records the preset's name and its full parameters.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types

from .scene import RobotParams, SceneParams


@dataclasses.dataclass(frozen=True)
class Preset:
    """A named model: its parameters, one line about it, and the source of each value it sets."""

    name: str
    params: SceneParams
    summary: str
    sources: tuple[tuple[str, str], ...]  # (field, where the value comes from)


# ------------------------------------------------------------------ robots
_LAB_CODE = "wsavoie/ArduinoSmarticle crawlingStudy5_ThickCenter_wStatic_fast20170929.m"
_CHRONO = "wsavoie/SmarticleSim Smarticle.cpp; AkashVardhan7/smarticle_cloud_open_Boundary"
_DART = "LuningFang/smarticle_v6 main.cpp (world.skel quoted in comments)"

# geometry name -> (RobotParams changes, scene changes, sources)
_GEOMETRY = {
    "paper": ({}, {}, (
        ("body_length, arm_length, arm_thickness, body_thickness, mass", "paper (W 5.0 cm, L 5.4 cm, 0.3 cm, D 2.2 cm, 34.8 g)"),
        ("arm_mass 2 g, capsule arms, body_height 2.5 cm", "chosen where the paper is silent (docs/model.md)"),
        ("plate_friction 0.37", f"{_DART}: the DART-derived value"),
        ("robot_friction 0.3", "chosen: plastic on plastic (docs/model.md)"),
    )),
    "lab": (dict(
        body_length=0.054, arm_length=0.050, hinge_inset=0.006,
        arm_shape="plate", arm_thickness=0.0032, arm_height=0.024, arm_clearance=0.0005,
        arm_mass=0.00319,
    ), dict(robot_friction=0.37), (
        ("body_length 5.4 cm, arm_length 5.0 cm", f"{_LAB_CODE}; LuningFang/smarticle_v6 Skeleton.cpp (three codes agree)"),
        ("hinge_inset 6 mm", f"{_LAB_CODE}; wsavoie/SmarticleSim Smarticle.cpp (pivot to pivot ~4.2 cm)"),
        ("arm_shape plate, arm_thickness 3.2 mm, arm_height 0.96 of the body height", _CHRONO),
        ("arm_clearance 0.5 mm", "paper: arms 'slightly raised above the ground'; half the 1 mm the plate leaves"),
        ("arm_mass 3.19 g", f"{_LAB_CODE}; Chrono ports"),
        ("mass 34.8 g", "paper (measured; the lab code's body 24.8 g + 2 x 3.19 g = 31.2 g omits the rest)"),
        ("plate_friction 0.37", f"{_LAB_CODE} (kinetic; static 0.43: MuJoCo has one coefficient)"),
        ("robot_friction 0.37", f"{_DART}; dartsim/dart ContactConstraint.cpp (min of 0.37 and 0.37)"),
    )),
}

# servo name -> (RobotParams changes, sources)
_SERVO = {
    "pd": ({}, (
        ("servo: PD + feed-forward, kp 0.5 N m/rad, kv critical, 0.078 N m, armature 5e-5 kg m^2",
         "stall torque: Savoie's public Chrono code (wsavoie/SmarticleSim); gains and armature chosen "
         "(docs/model.md, docs/timestep.md)"),
    )),
    # DART's "SERVO" joint: a velocity constraint whose force is bounded, hard stops at
    # +-90 deg. The command is a velocity (the gait's rate): an arm a neighbour blocks does not
    # catch up afterwards; the stops reset it every half period at 90 deg. MuJoCo has no bounded
    # velocity constraint for a moving target, so it is a velocity loop (kv) clipped at the bound.
    # Its gain is capped by the implicit integrator, which linearises an actuator as its damping
    # even while the torque is clipped: dt kv must stay small against the arm's inertia
    # (2.7e-6 kg m^2), else the arm moves as if several times heavier. kv = 0.003: a 1 ms loop,
    # dt kv / I = 0.11 at DART's 0.1 ms step; a stalled arm pushes with 0.026 N m.
    # A slow trim (kp = kv / 1.6 s, one 90-deg gait period) keeps arms from drifting at
    # amplitudes whose corners lie inside the stops.
    "dart": (dict(servo_kp=0.003 / 1.6, servo_kv=0.003, servo_torque=0.03, servo_armature=0.0,
                  arm_limit_deg=90.0), (
        ("servo_torque 0.03 N m, arm_limit 90 deg (hard stops), velocity command",
         f"{_DART}; dartsim/dart JointAspect.hpp"),
        ("servo_kv 0.003 (1 ms loop), armature 0",
         "chosen: the stiffest velocity loop the implicit integrator keeps consistent while clipped "
         "(dt kv / I ~ 0.1; docs/fidelity.md)"),
        ("servo_kp kv / 1.6 s", "chosen: a trim too slow to catch up within a period (docs/fidelity.md)"),
    )),
    # The same bound and stops with a stiff position loop: the arm keeps pushing toward its
    # setpoint (a setpoint error of 1 deg saturates 0.03 N m), as a hobby servo does.
    "stiff": (dict(servo_kp=0.03 / math.radians(1.0), servo_kv=None, servo_torque=0.03, servo_armature=0.0,
                   arm_limit_deg=90.0), (
        ("servo_torque 0.03 N m, arm_limit 90 deg (hard stops)", f"{_DART}; dartsim/dart JointAspect.hpp"),
        ("servo_kp 1.72 (1 deg of error saturates the bound), kv critical, armature 0",
         "chosen: a stiff position servo within DART's bound (docs/fidelity.md)"),
    )),
    # A hobby servo is commanded by a pulse every 20 ms (50 Hz) and the lab firmware sends step
    # setpoints (wsavoie/ArduinoSmarticle cloudSmarticle.ino): the arm responds to a command on
    # average half a frame late. Modelled as a first-order lag of 10 ms on the command.
    "lag": (dict(servo_timeconst=0.010), (
        ("servo_timeconst 10 ms", "half the 20 ms command frame of a hobby servo; lab firmware sends step setpoints "
                                  "(wsavoie/ArduinoSmarticle cloudSmarticle.ino)"),
        ("servo otherwise as 'pd'", "as the pd servo: stall torque from wsavoie/SmarticleSim, gains and armature "
         "chosen (docs/model.md)"),
    )),
    # The lab's hobby servo as the twin's collision-level diagnosis names it (docs/twin.md, docs/model.md):
    # a stiff position loop that pushes at its stall torque once an arm is ~1 deg off its command
    # (a blocked arm pushes at the bound, as DART's SERVO does), the gearbox's reflected inertia and
    # the 10 ms command lag kept, each actuator clipped at the stall torque, and the gear's backlash,
    # through which the arm itself (3.19 g, no armature) strikes at each start and stop of a move.
    "hobby": (dict(servo_kp=0.078 / math.radians(1.0), servo_kv=None, servo_timeconst=0.010,
                   servo_clip="actuator", backlash_deg=1.5), (
        ("servo_kp 4.47 N m/rad (the stall torque at 1 deg of error), kv critical",
         "chosen: a hobby servo's proportional loop saturates within a degree or two; the stiff loop that "
         "gives DART's collision impulses in MuJoCo (docs/twin.md)"),
        ("servo_torque 0.078 N m, armature 5e-5 kg m^2, servo_timeconst 10 ms",
         "as the lag servo: stall torque from wsavoie/SmarticleSim, lag half the 20 ms command frame "
         "(wsavoie/ArduinoSmarticle cloudSmarticle.ino), armature chosen (docs/model.md)"),
        ("backlash_deg 1.5 (free play of each arm)", "chosen: the middle of the 1-2 deg that MuJoCo's modelling "
         "guide gives for gear backlash (docs/model.md)"),
        ("servo_clip actuator", "chosen: each actuator clipped at the stall torque, so the implicit step keeps "
         "a clipped force constant in any MuJoCo version (docs/model.md)"),
    )),
}


# numerics name -> (SceneParams changes, sources)
_NUMERICS = {
    # the values are SceneParams' own (written from them, so the text cannot fall behind)
    "default": ({}, ((f"timestep {SceneParams.timestep * 1e3:g} ms, contacts solref "
                      f"{SceneParams.contact_timeconst * 1e3:g} ms",
                      "chosen: labels, lone drift and glider transport converge against a 0.0625 ms "
                      "reference (0.5 ms converges labels and drift only; docs/timestep.md)"),)),
    # DART's time stepping is an LCP: rigid contacts, 0.1 ms steps. MuJoCo's contacts are soft;
    # the stiffest it integrates stably has a time constant of two steps.
    "rigid": (dict(timestep=1e-4, contact_timeconst=2e-4, contact_substeps=1), (
        ("timestep 0.1 ms", "the paper's SI (DART, 1e-4 s)"),
        ("contact_timeconst 0.2 ms", "chosen: as rigid as MuJoCo allows at that step (2 dt), standing in for "
         "DART's LCP (docs/fidelity.md)"),
    )),
}


def _bind(name: str, geometry: str, servo: str, summary: str, numerics: str = "default") -> Preset:
    robot_changes, scene_changes, geo_sources = _GEOMETRY[geometry]
    servo_changes, servo_sources = _SERVO[servo]
    num_changes, num_sources = _NUMERICS[numerics]
    robot = dataclasses.replace(RobotParams(), **robot_changes, **servo_changes)
    params = dataclasses.replace(SceneParams(), robot=robot, **scene_changes, **num_changes)
    params.validate()
    return Preset(name, params, summary, geo_sources + servo_sources + num_sources)


PRESETS: dict[str, Preset] = {p.name: p for p in (
    _bind("paper", "paper", "pd", "the paper's text: W 5.0 cm, L 5.4 cm, capsule arms, PD servo (the model before presets)"),
    _bind("paper-stiff", "paper", "stiff", "the paper's geometry with a stiff position servo within DART's 0.03 N m"),
    _bind("paper-dart", "paper", "dart", "the paper's geometry with DART's servo (velocity command within 0.03 N m, "
          "hard stops)"),
    _bind("lab", "lab", "pd", "the lab robot from public code: body 5.4 cm, arms 5.0 cm plates, hinges 6 mm inset; PD servo"),
    _bind("lab-stiff", "lab", "stiff", "the lab robot with a stiff position servo within DART's 0.03 N m"),
    _bind("lab-dart", "lab", "dart", "the lab robot with DART's servo (velocity command within 0.03 N m, hard stops)"),
    _bind("lab-lag", "lab", "lag", "the lab robot with a PD servo that answers its command 10 ms late (first-order lag)"),
    _bind("lab-hobby", "lab", "hobby", "the lab robot with a hobby servo: a stiff position loop within its stall "
          "torque, 10 ms command lag, gear backlash of 1.5 deg"),
    _bind("dart", "lab", "dart", "the paper's DART simulation as public code describes it: the lab robot, DART's "
          "servo, 0.1 ms steps and near-rigid contacts", numerics="rigid"),
)}


# The default model of every command. Chosen in docs/model.md from the screening study
# (docs/fidelity.md); stores record the preset that made them.
DEFAULT = "lab-lag"


def get(name: str | None = None) -> Preset:
    """The preset called ``name`` (default: :data:`DEFAULT`).

    Raises:
      ValueError: unknown name (one line naming the known ones).
    """
    name = DEFAULT if name is None else name
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown model {name!r}; choose one of {', '.join(PRESETS)}") from None


def params(name: str | None = None) -> SceneParams:
    """The ``SceneParams`` of preset ``name`` (default: :data:`DEFAULT`)."""
    return get(name).params


# ------------------------------------------------------------------ one field changed
# ``--set FIELD=VALUE`` on the command line and a ``[scene]`` table in study files change single
# fields of a preset (``robot_friction=0.1``, ``robot.servo_speed=7``) without code. The preset's
# values stay its defaults; stores and sidecars record the preset's name and the overrides.

_NOT_SETTABLE = {"robot", "quirks"}  # the robot is set field by field; quirks are drawn (imperfections)


def _fields(cls) -> dict[str, object]:
    import typing
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if f.name not in _NOT_SETTABLE}


@functools.cache
def settable() -> types.MappingProxyType:
    """Every field ``--set`` can change: scene fields by name, robot fields as ``robot.NAME``; -> type.
    Read once (every scene a spec resolves checks its overrides against it)."""
    from .scene import RobotParams
    out = dict(_fields(SceneParams))
    out.update({f"robot.{k}": t for k, t in _fields(RobotParams).items()})
    return types.MappingProxyType(out)


def _convert(field: str, kind, value):
    """``value`` (a command line's string, or a TOML value) as the type of ``field``; ValueError if not."""
    import typing
    args = typing.get_args(kind)
    optional = type(None) in args
    if optional:
        kind = next(a for a in args if a is not type(None))
    if value is None or (isinstance(value, str) and value.strip().lower() == "none"):
        if optional:
            return None
        raise ValueError(f"--set {field}: cannot be none")
    origin = typing.get_origin(kind)
    try:
        if origin is tuple:
            items = [x for x in value.split(",")] if isinstance(value, str) else list(value)
            inner = typing.get_args(kind)
            if len(inner) == 2 and inner[1] is Ellipsis:
                inner = (inner[0],) * len(items)
            if len(items) != len(inner):
                raise ValueError
            return tuple(_convert(field, t, x) for t, x in zip(inner, items))
        if kind is bool:
            if isinstance(value, bool):
                return value
            low = str(value).strip().lower()
            if low not in ("true", "false", "1", "0"):
                raise ValueError
            return low in ("true", "1")
        if kind is int:
            if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                raise ValueError
            return int(str(value).strip()) if isinstance(value, str) else int(value)
        if kind is float:
            if isinstance(value, bool):
                raise ValueError
            v = float(value)
            if not math.isfinite(v):
                raise ValueError
            return v
        if kind is str:
            if not isinstance(value, str):
                raise ValueError
            return value.strip()
    except (TypeError, ValueError):
        pass
    else:
        raise ValueError(f"--set {field}: cannot be set from the command line")
    want = {float: "a finite number", int: "an integer", bool: "true or false", str: "a name"}.get(kind)
    if origin is tuple:
        want = f"{len(typing.get_args(kind))} comma-separated values"
    raise ValueError(f"--set {field}: expected {want or kind}{' or none' if optional else ''}, got {value!r}")


def overrides(items) -> tuple[tuple[str, object], ...]:
    """Checked overrides, sorted by field: from ``FIELD=VALUE`` strings (``--set``) or (field, value)
    pairs (a study file's ``[scene]`` table, its ``robot`` sub-table flattened to ``robot.NAME``).

    Raises:
      ValueError: one line, for a malformed item, an unknown field, a field given twice or a value
        of the wrong type. Whether the values make a valid scene is checked by :func:`apply`.
    """
    known = settable()
    out = {}
    for item in items:
        if isinstance(item, str):
            field, eq, value = item.partition("=")
            field = field.strip()
            if not eq or not field:
                raise ValueError(f"--set takes FIELD=VALUE (e.g. robot_friction=0.1), got {item!r}")
        else:
            field, value = item
        if field not in known:
            near = sorted(k for k in known if field.split(".")[-1] in k) or sorted(known)
            raise ValueError(f"--set: unknown scene field {field!r}; "
                             f"{'did you mean' if len(near) < len(known) else 'known:'} {', '.join(near)}")
        if field in out:
            raise ValueError(f"--set: {field} given twice")
        out[field] = _convert(field, known[field], value)
    return tuple(sorted(out.items()))


def table_overrides(table: dict) -> tuple[tuple[str, object], ...]:
    """A study file's ``[scene]`` table (``robot`` a sub-table, or dotted keys) as checked overrides."""
    if not isinstance(table, dict):
        raise ValueError("[scene] must be a table of FIELD = VALUE")
    items = []
    for k, v in table.items():
        if k == "robot" and isinstance(v, dict):
            items += [(f"robot.{rk}", rv) for rk, rv in v.items()]
        else:
            items.append((k, v))
    return overrides(items)


def apply(params: SceneParams, changes) -> SceneParams:
    """``params`` with the overrides ``changes`` (see :func:`overrides`) applied and the scene validated."""
    changes = overrides(changes)
    if not changes:
        return params
    robot = {k[len("robot."):]: v for k, v in changes if k.startswith("robot.")}
    scene = {k: v for k, v in changes if not k.startswith("robot.")}
    out = dataclasses.replace(params, robot=dataclasses.replace(params.robot, **robot), **scene)
    try:
        out.validate()
    except ValueError as e:
        raise ValueError(f"--set {', '.join(f'{k}={v}' for k, v in changes)}: {e}") from None
    return out


def overrides_json(changes) -> dict:
    """Overrides as the store and the sidecar record them: {field: value} (tuples as lists)."""
    return {k: list(v) if isinstance(v, tuple) else v for k, v in overrides(changes)}


def describe(model: str, overrides: dict | None = None) -> str:
    """A model as pages name it: the preset's name, then the fields a store recorded as changed from it
    (its ``overrides``, {field: value}), if any."""
    if not overrides:
        return f"`{model}`"
    return f"`{model}` with " + ", ".join(f"{k} = {v}" for k, v in sorted(overrides.items()))
