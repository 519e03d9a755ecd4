"""Scene generator: robot and plate parameters plus N initial poses -> MJCF.

Conventions (used by every other module):

* Lengths in metres, angles in radians, masses in kilograms, unless a name says
  ``_deg`` or ``_W`` (units of the body length W).
* Robot body frame: +x along the body axis (from arm 1's hinge to arm 2's
  hinge), +y the side the arms fold to at positive angles. The body *normal*
  n = -y (so the paper's theta ~ 270 deg, "the direction of robot 1's normal",
  is -y in robot 1's frame).
* Arm angles alpha1 (hinge at x = -W/2) and alpha2 (hinge at x = +W/2) are 0
  when the arm extends the body axis; positive folds the arm toward +y. Equal
  values are mirror-symmetric shapes; (+a, +a) and (-a, -a) are the two U's.
* A pose is ``(x, y, heading, alpha1, alpha2)``: body centre, body-axis angle
  from world +x, arm angles.

Choices where the paper is silent (all parameters):

* Body height 2.5 cm; arms are capsules of diameter 0.3 cm (the arm
  thickness) whose axis lies ``arm_clearance + arm_radius`` above the plate,
  inside the body's height, so robot-robot contacts are exactly planar.
* Arm mass 2 g each (a 5.4 x 0.3 x ~1 cm plastic link); body takes the rest.
* Servo: a PD loop with velocity feed-forward, as a hobby servo tracking a
  ramp: a position actuator (``servo_kp``) and a velocity actuator (gain
  ``servo_kv``, critical damping by default) per hinge; the gait supplies the
  setpoint and its rate. The hinge's total actuator torque is clipped to the
  stall torque 0.078 N m (``actuatorfrcrange``), and the gearbox's reflected
  inertia ``servo_armature`` = 5e-5 kg m^2 limits the arm's acceleration to
  ~1500 rad/s^2 (full speed in ~6 ms). Softer servos or smaller armatures
  made the single robot "drift" at dt = 1 ms by numerical hopping, a drift
  that vanished at dt/4; see docs/timestep.md.
* Plate friction mu = 0.37 (DART-derived figure quoted in public code);
  robot-robot friction 0.3. The plate geom has priority, so body-plate
  contacts use exactly the plate's mu.
* Contacts: solref time constant 5 ms (critically damped), solimp
  (0.95, 0.99, 1 mm); both tested for convergence in ``benchmarks/``.
* Elliptic friction cones: pyramidal cones are anisotropic in the plane and
  break the rotation invariance a planar study needs.
"""

from __future__ import annotations

import dataclasses
import json
import math
from typing import Sequence

import mujoco
import numpy as np

# contype/conaffinity bits: the plate and the robot bodies share bit 1; every
# robot geom (and the optional wall) has bit 2. Arms carry only bit 2, so they
# can never touch the plate, whatever their height.
_PLATE_BIT = 1
_ROBOT_BIT = 2
ARM_SHAPES = ("capsule", "plate")
SERVO_CLIPS = ("joint", "actuator")


@dataclasses.dataclass(frozen=True)
class RobotQuirk:
    """How one robot of a scene departs from the preset's ideal robot
    (drawn by ``smarticle_mjx.imperfections``; SI units).

    Attributes:
      backlash_deg: free play of arm 1 and arm 2 (half-widths, deg); None: the
        preset's ``backlash_deg`` for both.
      com_offset: the body's centre of mass off its geometric centre (m), in
        the body frame (x along the body, y toward the arms' fold side).
    """

    backlash_deg: tuple[float, float] | None = None
    com_offset: tuple[float, float] = (0.0, 0.0)

    def validate(self, robot: "RobotParams") -> None:
        if self.backlash_deg is not None:
            if len(self.backlash_deg) != 2 or not all(0 <= b <= 10 for b in self.backlash_deg):
                raise ValueError(f"a robot's backlash is two half-widths in [0, 10] deg, got {self.backlash_deg}")
        dx, dy = self.com_offset
        if not (abs(dx) < robot.body_length / 2 and abs(dy) < robot.body_thickness / 2):
            raise ValueError(f"centre-of-mass offset {self.com_offset} m lies outside the body")

    def backlash(self, robot: "RobotParams") -> tuple[float, float]:
        b = self.backlash_deg
        return (robot.backlash_deg, robot.backlash_deg) if b is None else (float(b[0]), float(b[1]))


@dataclasses.dataclass(frozen=True)
class RobotParams:
    """Geometry, mass and servo of one smarticle (SI units)."""

    body_length: float = 0.050  # W
    body_thickness: float = 0.022  # D
    body_height: float = 0.025
    arm_length: float = 0.054  # L, hinge to tip
    arm_thickness: float = 0.003
    arm_clearance: float = 0.005  # gap between arm underside and plate
    mass: float = 0.0348
    arm_mass: float = 0.002
    arm_limit_deg: float = 100.0  # hinge range; gait corners stay inside
    servo_kp: float = 0.5  # N m / rad
    servo_kv: float | None = None  # N m s / rad; None: critically damped
    servo_torque: float = 0.078  # N m (stall torque)
    servo_speed: float = 8.727  # rad/s (0.12 s / 60 deg)
    servo_armature: float = 5e-5  # kg m^2
    joint_damping: float = 0.0
    arm2_length: float | None = None  # None: as arm_length (a manufacturing asymmetry otherwise)
    # Geometry beyond the paper's text (presets.py cites where each value comes from):
    hinge_inset: float = 0.0  # hinge axis this far inside each end of the body (m)
    arm_shape: str = "capsule"  # "capsule" (rounded rod) or "plate" (flat box, square tip)
    arm_height: float | None = None  # plate height (m); None: the arm thickness (a capsule's diameter)
    # First-order response lag of the servo (s): the commanded setpoint and its
    # rate pass through a filter of this time constant; 0: the servo follows
    # the command at once (within its gains and torque)
    servo_timeconst: float = 0.0
    # Where the stall torque clips: "joint" clips the hinge's total actuator
    # torque (actuatorfrcrange); "actuator" also clips each actuator's own force
    # (forcerange), so that MuJoCo's implicit integrator stops linearising a
    # clipped actuator's damping (MuJoCo >= 3.5 does so only for the actuator's
    # own range): a stiff velocity loop then pushes at the bound while blocked
    # instead of moving as if its arm were many times heavier
    servo_clip: str = "joint"
    # Gear backlash: each arm swings freely +-backlash_deg about the driven
    # hinge before it meets the gear (a second, unactuated hinge on the same
    # axis with that range, after MuJoCo's modelling guide; its stops as stiff
    # as the time step integrates, 2 dt); 0: no free play
    backlash_deg: float = 0.0
    # Coulomb friction inside the free play (N m, MuJoCo's frictionloss on the
    # play hinge): the torque it takes to move an arm through its play; 0 (the
    # presets): the arm swings freely between the stops. No public source
    # measures it for the lab's servos (a diagnosis knob, docs/relax.md)
    backlash_friction: float = 0.0
    # Time constant of the gear stops at the ends of the free play (s): None (the
    # presets) makes them as stiff as the step integrates (2 dt), rigid teeth; a
    # larger value makes the teeth meet compliantly (MuJoCo's solreflimit), as
    # plastic gear teeth may. No public source measures the lab servos' mesh
    # compliance (a diagnosis knob, docs/relax.md)
    backlash_stop_timeconst: float | None = None
    # The arm's mount near the hinge, as the lab's CAD arm part has it (docs/relax.md: a C-shaped mount
    # 6.75 mm wide on the part's inner 20 mm, where the plate is 2.9 mm thick): a second box of the arm,
    # from the hinge to arm_mount_length along it, arm_mount_width across, as tall as the arm; massless
    # (the arm's mass and inertia stay the arm's). 0 (the presets): no mount. Native backend only
    arm_mount_length: float = 0.0
    arm_mount_width: float = 0.0

    def validate(self) -> None:
        positive = ("body_length", "body_thickness", "body_height", "arm_length",
                    "arm_thickness", "mass", "arm_mass", "servo_torque", "servo_speed")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"robot.{name} must be positive, got {getattr(self, name)}")
        if self.mass <= 2 * self.arm_mass:
            raise ValueError("robot.mass must exceed the two arms' mass")
        if self.servo_kp < 0:
            raise ValueError("robot.servo_kp must be >= 0")
        if self.servo_kv is not None and self.servo_kv < 0:
            raise ValueError("robot.servo_kv must be >= 0")
        if self.servo_kp == 0 and not self.servo_kv:
            raise ValueError("a servo needs a position gain (servo_kp) or a velocity gain (servo_kv)")
        if self.servo_armature < 0:
            raise ValueError("robot.servo_armature must be >= 0")
        if self.arm_clearance < 0:
            raise ValueError("robot.arm_clearance must be >= 0")
        if self.arm2_length is not None and not self.arm2_length > self.arm_thickness:
            raise ValueError("arm2_length must exceed the arm thickness")
        # an arm hangs from its servo in the body, so it starts below the body's top; it may reach above it
        # (the lab's arm plates are 29-31 mm tall on a 26 mm body: docs/model.md)
        if self.arm_clearance >= self.body_height:
            raise ValueError("arms must start below the body's top (arm_clearance < body_height)")
        if not 0 < self.arm_limit_deg <= 180:
            raise ValueError("robot.arm_limit_deg must be in (0, 180]")
        if self.arm_shape not in ARM_SHAPES:
            raise ValueError(f"robot.arm_shape must be one of {', '.join(ARM_SHAPES)}, got {self.arm_shape!r}")
        if self.arm_height is not None and not self.arm_height > 0:
            raise ValueError("robot.arm_height must be positive")
        if self.arm_height is not None and self.arm_shape == "capsule" and self.arm_height != self.arm_thickness:
            raise ValueError("a capsule arm's height is its thickness; set arm_shape='plate' for a taller arm")
        if not 0 <= self.hinge_inset < self.body_length / 2:
            raise ValueError("robot.hinge_inset must be in [0, body_length / 2)")
        if self.servo_timeconst < 0:
            raise ValueError("robot.servo_timeconst must be >= 0")
        if self.servo_clip not in SERVO_CLIPS:
            raise ValueError(f"robot.servo_clip must be one of {', '.join(SERVO_CLIPS)}, got {self.servo_clip!r}")
        if not 0 <= self.backlash_deg <= 10:
            raise ValueError(f"robot.backlash_deg must be in [0, 10], got {self.backlash_deg}")
        if not 0 <= self.backlash_friction < self.servo_torque:
            raise ValueError("robot.backlash_friction must be in [0, servo_torque), "
                             f"got {self.backlash_friction}")
        if self.arm_mount_length < 0 or self.arm_mount_width < 0:
            raise ValueError("robot.arm_mount_length and robot.arm_mount_width must be >= 0")
        if self.arm_mount_length > 0:
            if self.arm_mount_length > min(self.arm_lengths):
                raise ValueError(f"robot.arm_mount_length ({self.arm_mount_length:g} m) must not exceed the arm "
                                 f"({min(self.arm_lengths):g} m)")
            if not self.arm_mount_width > self.arm_thickness:
                raise ValueError(f"robot.arm_mount_width must exceed the arm's thickness ({self.arm_thickness:g} m) "
                                 f"where arm_mount_length > 0, got {self.arm_mount_width:g}")
        elif self.arm_mount_width > 0:
            raise ValueError("robot.arm_mount_width needs robot.arm_mount_length > 0")
        if self.backlash_stop_timeconst is not None and not 0 < self.backlash_stop_timeconst <= 0.1:
            raise ValueError("robot.backlash_stop_timeconst must be in (0, 0.1] s (or None: 2 time steps), "
                             f"got {self.backlash_stop_timeconst}")

    @property
    def has_mount(self) -> bool:
        return self.arm_mount_length > 0

    @property
    def arm_radius(self) -> float:
        return 0.5 * self.arm_thickness

    @property
    def arm_extent_z(self) -> float:
        """Vertical extent of an arm: a plate's height, a capsule's diameter."""
        return self.arm_height if self.arm_height is not None else self.arm_thickness

    @property
    def arm_z(self) -> float:
        """Height of the arm's centre line above the plate."""
        return self.arm_clearance + self.arm_extent_z / 2

    @property
    def arm_lengths(self) -> tuple[float, float]:
        """Hinge-to-tip lengths of arm 1 and arm 2 (arm 2 is arm 1's unless ``arm2_length`` is set)."""
        return self.arm_length, self.arm2_length if self.arm2_length is not None else self.arm_length

    @property
    def hinge_x(self) -> float:
        """Distance of each hinge axis from the body centre, along the body."""
        return self.body_length / 2 - self.hinge_inset

    @property
    def hinge_inertia(self) -> float:
        """Arm (thin rod about its end) plus reflected servo inertia."""
        return self.arm_mass * self.arm_length ** 2 / 3 + self.servo_armature

    @property
    def kv(self) -> float:
        if self.servo_kv is not None:
            return self.servo_kv
        return 2.0 * math.sqrt(self.servo_kp * self.hinge_inertia)

    @property
    def body_mass(self) -> float:
        return self.mass - 2 * self.arm_mass


# MJCF names of MuJoCo's integrators
INTEGRATORS = ("implicitfast", "implicit", "Euler", "RK4", "discrete")
# Integrators that take the servo's velocity gain explicitly (MuJoCo's Euler is implicit in joint
# damping only). Past timestep * kv / hinge inertia = 1 they misintegrate a stiff velocity loop: a lone
# robot with the stiff servo (kv / I ~ 2600 1/s) slips 0.1 W per arm move with RK4 at 0.5 ms, 1 W at
# 1 ms, against 3.5e-3 W with implicitfast (docs/timestep.md); the default servo sits at 0.2 with RK4 at 1 ms.
EXPLICIT_INTEGRATORS = ("Euler", "RK4")
# Integrators whose slip of a body per arm move does not grow with the step (docs/timestep.md, the kick
# level): only these may change their step with the robots' distance (near-contact sub-stepping). With
# implicit or implicitfast the slips, which cancel over a gait cycle at one step, become a drift that
# depends on the distance: pairs bound 0.48 against 0.41 on the label check.
SUBSTEP_INTEGRATORS = ("discrete", "Euler", "RK4")
EXPLICIT_DAMPING_MAX = 1.0
# MuJoCo's constraint solvers by their MJCF names, and "auto" (the default): Newton, which converges in
# 1-2 iterations on robots without gear play, or CG at PLAY_SOLVER_ITERATIONS (or more) on a scene whose
# arms have gear play. There Newton sometimes stops at its iteration cap with an unconverged solve of
# tens of newtons that turns a crowded robot over (the play's unactuated hinge carries only the arm's
# ~3e-6 kg m^2 beside bodies of ~0.035 kg; more iterations or a longer line search do not help), and
# CG does not (docs/relax.md, "The solver, not the play"; benchmarks/play_probe.py)
SOLVERS = ("auto", "Newton", "CG", "PGS")
PLAY_SOLVER, PLAY_SOLVER_ITERATIONS = "CG", 100


@dataclasses.dataclass(frozen=True)
class SceneParams:
    """Plate, contacts and solver settings for an N-robot scene."""

    robot: RobotParams = RobotParams()
    plate_friction: float = 0.37
    robot_friction: float = 0.3
    contact_timeconst: float = 0.005  # s; solref[0] for every contact
    contact_dampratio: float = 1.0
    # damping ratio of contacts that do not involve the plate (robot on robot, robot on a wall); None: as
    # every contact, contact_dampratio. Below 1 they bounce: a linear contact of damping ratio z returns
    # e = exp(-pi z / sqrt(1 - z^2)) of the approach speed (MuJoCo has no bounce threshold: a contact
    # bounces at every speed). The plate keeps contact_dampratio (its solmix outweighs the robots')
    robot_dampratio: float | None = None
    # solimp (dmin, dmax, width): stiff enough that a stalled servo pressing an
    # arm into a neighbour penetrates ~0.1 mm, not the ~2 mm of the defaults
    contact_solimp: tuple[float, float, float] = (0.95, 0.99, 0.001)
    # the cheapest numerics that keep labels, lone drift and the glider quantities (beta, net speed,
    # persistence) of the 0.0625 ms reference (benchmarks/glider_step.py, docs/timestep.md): about 20
    # contact evaluations per contact time constant. 0.5 ms in versions 0.3.x (labels converged, glider
    # transport biased: beta +0.14, speed +39 %); 0.25 ms again since version 0.4.0 (November 2026)
    timestep: float = 2.5e-4
    # MuJoCo's integrator (docs/timestep.md compares them); "discrete" merges the
    # constraint solve and the implicit velocity update (MuJoCo >= 3.13; native and warp, not MJX)
    integrator: str = "implicitfast"
    # Near-contact sub-stepping (native backend; docs/timestep.md): while two robots of a lane may be
    # closer than ``substep_gate`` (m), its steps are split into this many, so contacts between robots
    # are resolved at timestep / contact_substeps and the robots apart run at the full step. 1: off.
    # Needs an integrator of SUBSTEP_INTEGRATORS (implicitfast's step-dependent slip would become a drift).
    contact_substeps: int = 1
    substep_gate: float = 0.004
    # MuJoCo's constraint solver (SOLVERS; "auto": Newton, or CG where arms have gear play) and its
    # iteration cap (with "auto" and gear play, at least PLAY_SOLVER_ITERATIONS)
    solver: str = "auto"
    iterations: int = 20
    # MuJoCo's default. At the impact of an arm on a body the C solver's line
    # search needs up to ~23 evaluations; capped at 10 it stopped early with
    # the gradient still large on ~1 % of a colliding pair's steps, qacc off
    # by up to 2.5x (benchmarks/solver_convergence.py). MJX converged anyway,
    # so this was the seed of most MJX-vs-native label differences.
    ls_iterations: int = 50
    tolerance: float = 1e-8
    boundary_radius: float | None = None  # optional circular wall (m)
    boundary_segments: int = 48
    # Departures from the ideal plate, off by default (calibration's candidate effects):
    plate_tilt_deg: tuple[float, float] = (0.0, 0.0)  # downhill slope along plate x and y
    plate_friction_y_ratio: float = 1.0  # mu along plate y / mu along x (a brushed plate)
    # > 0: arms and plate collide, with this mu: with robot.arm_clearance 0 the arms rest and slide on the
    # plate; with a clearance they touch it only when their robot tilts (an arm held out sideways meets the
    # plate once its robot leans about 0.6 deg over its 0.5 mm clearance)
    arm_plate_friction: float = 0.0
    # Per-robot departures from the ideal robot, robot i taking quirks[i] (robots
    # beyond the tuple are ideal); drawn by smarticle_mjx.imperfections
    quirks: tuple[RobotQuirk, ...] = ()

    def validate(self) -> None:
        self.robot.validate()
        for q in self.quirks:
            if not isinstance(q, RobotQuirk):
                raise ValueError(f"quirks must be RobotQuirk objects, got {type(q).__name__}")
            q.validate(self.robot)
        if not self.timestep > 0:
            raise ValueError("timestep must be positive")
        if self.integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {', '.join(INTEGRATORS)}, got {self.integrator!r}")
        if self.integrator in EXPLICIT_INTEGRATORS:
            stiff = self.timestep * self.robot.kv / self.robot.hinge_inertia
            if stiff > EXPLICIT_DAMPING_MAX:
                raise ValueError(
                    f"integrator {self.integrator} takes the servo's velocity gain explicitly and "
                    f"timestep * kv / hinge inertia = {stiff:.3g} > {EXPLICIT_DAMPING_MAX:g} would misintegrate it; "
                    "use implicitfast or a smaller timestep")
        if not (isinstance(self.contact_substeps, int) and 1 <= self.contact_substeps <= 16):
            raise ValueError(f"contact_substeps must be a whole number in 1-16, got {self.contact_substeps!r}")
        if not self.substep_gate > 0:
            raise ValueError(f"substep_gate must be positive (m), got {self.substep_gate!r}")
        if self.contact_substeps > 1 and self.integrator not in SUBSTEP_INTEGRATORS:
            raise ValueError(f"near-contact sub-stepping needs an integrator whose per-step error does not depend "
                             f"on the step ({', '.join(SUBSTEP_INTEGRATORS)}), not {self.integrator!r}: "
                             "docs/timestep.md")
        if self.contact_timeconst < 2 * self.timestep:
            raise ValueError(
                f"contact_timeconst {self.contact_timeconst} < 2 * timestep {self.timestep}: "
                "MuJoCo would silently stiffen nothing and soften contacts; lower the timestep")
        if self.robot_dampratio is not None and not (math.isfinite(self.robot_dampratio) and self.robot_dampratio > 0):
            raise ValueError(f"robot_dampratio must be a positive number (or unset), got {self.robot_dampratio!r}")
        dmin, dmax, width = self.contact_solimp
        if not (0 < dmin <= dmax < 1 and width > 0):
            raise ValueError("contact_solimp must satisfy 0 < dmin <= dmax < 1 and width > 0")
        if self.plate_friction < 0 or self.robot_friction < 0:
            raise ValueError("friction coefficients must be >= 0")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {self.solver!r}")
        if self.iterations < 1 or self.ls_iterations < 1:
            raise ValueError("solver iterations must be >= 1")
        if self.boundary_radius is not None and self.boundary_radius <= 0:
            raise ValueError("boundary_radius must be positive")
        tx, ty = self.plate_tilt_deg
        if not (abs(tx) < 45 and abs(ty) < 45):
            raise ValueError(f"plate tilt must be below 45 deg, got {self.plate_tilt_deg}")
        if not self.plate_friction_y_ratio > 0:
            raise ValueError("plate_friction_y_ratio must be positive")
        if self.arm_plate_friction < 0:
            raise ValueError("arm_plate_friction must be >= 0")

    @property
    def sub_timestep(self) -> float:
        """The step near contacts: ``timestep / contact_substeps`` (the step everywhere when 1)."""
        return self.timestep / self.contact_substeps

    @property
    def gravity(self) -> tuple[float, float, float]:
        """Gravity in plate coordinates (m/s^2): the plate tilts, gravity does not."""
        gx, gy = (9.81 * math.sin(math.radians(a)) for a in self.plate_tilt_deg)
        return gx, gy, -math.sqrt(9.81 ** 2 - gx ** 2 - gy ** 2)

    @property
    def explicit_plate_contacts(self) -> bool:
        """Anisotropic plate friction or arms on the plate need explicit contact pairs."""
        return self.plate_friction_y_ratio != 1.0 or self.arm_plate_friction > 0

    def replace(self, **changes) -> "SceneParams":
        return dataclasses.replace(self, **changes)

    def has_play(self, n_robots: int) -> bool:
        """Whether any arm of the first ``n_robots`` robots has gear play (its own or the robot's)."""
        return any(b > 0 for i in range(n_robots) for b in self.quirk(i).backlash(self.robot))

    def constraint_solver(self, n_robots: int) -> tuple[str, int]:
        """MuJoCo's solver and iteration cap for a scene of ``n_robots`` robots: ``solver`` and
        ``iterations`` as set, or for "auto" Newton without gear play and CG at no fewer than
        PLAY_SOLVER_ITERATIONS with it (SOLVERS says why)."""
        if self.solver != "auto":
            return self.solver, self.iterations
        if self.has_play(n_robots):
            return PLAY_SOLVER, max(self.iterations, PLAY_SOLVER_ITERATIONS)
        return "Newton", self.iterations

    def quirk(self, i: int) -> RobotQuirk:
        """Robot ``i``'s departures from the ideal robot (none beyond the quirks given)."""
        return self.quirks[i] if i < len(self.quirks) else RobotQuirk()


def _fmt(*values: float) -> str:
    return " ".join(f"{v:.9g}" for v in values)


def _arm_geom_xml(name: str, p: RobotParams, sign: int, length: float) -> str:
    """One arm's geom in its hinge frame; ``sign`` -1 points it along -x."""
    common = f'name="{name}" mass="{p.arm_mass:.9g}" contype="{_ROBOT_BIT}" conaffinity="{_ROBOT_BIT}" rgba="0.3 0.3 0.3 1"'
    if p.arm_shape == "plate":
        half = length / 2
        size = _fmt(half, p.arm_thickness / 2, p.arm_extent_z / 2)
        return f'<geom {common} type="box" pos="{_fmt(sign * half, 0, 0)}" size="{size}"/>'
    tip = length - p.arm_radius  # capsule ends exactly at the arm length
    return f'<geom {common} type="capsule" fromto="{_fmt(0, 0, 0, sign * tip, 0, 0)}" size="{p.arm_radius:.9g}"/>'


def _mount_geom_xml(name: str, p: RobotParams, sign: int) -> str:
    """The arm's mount (``RobotParams.arm_mount_length``), a massless box from the hinge; "" without one."""
    if not p.has_mount:
        return ""
    half = p.arm_mount_length / 2
    return (f'\n        <geom name="{name}_mount" type="box" mass="0" contype="{_ROBOT_BIT}" conaffinity="{_ROBOT_BIT}" '
            f'rgba="0.3 0.3 0.3 1" pos="{_fmt(sign * half, 0, 0)}" '
            f'size="{_fmt(half, p.arm_mount_width / 2, p.arm_extent_z / 2)}"/>')


def _robot_xml(i: int, s: SceneParams, pose: Sequence[float], plate_bits: int = 0) -> str:
    p = s.robot
    x, y, heading, a1, a2 = (float(v) for v in pose)
    hw, hd, hh = p.body_length / 2, p.body_thickness / 2, p.body_height / 2
    hx = p.hinge_x
    arm_dz = p.arm_z - hh  # arm centre line relative to the body centre
    len1, len2 = p.arm_lengths
    lim = math.radians(p.arm_limit_deg)  # the compiler reads angles in radians
    quat = _fmt(math.cos(heading / 2), 0, 0, math.sin(heading / 2))
    rgba = "0.85 0.35 0.2 1" if i == 0 else "0.2 0.45 0.85 1"
    # hinge stops are as stiff as the contacts (MuJoCo's default limit is 20 ms soft)
    stiff = (f'solreflimit="{_fmt(s.contact_timeconst, s.contact_dampratio)}" '
             f'solimplimit="{_fmt(*s.contact_solimp)}"')
    joint = (f'armature="{p.servo_armature:.9g}" damping="{p.joint_damping:.9g}" ref="0" '
             f'range="{-lim:.9g} {lim:.9g}" {stiff} '
             f'actuatorfrcrange="{-p.servo_torque:.9g} {p.servo_torque:.9g}"')
    quirk = s.quirk(i)
    play = quirk.backlash(p)

    def free_play(k: int) -> str:
        # the gear's free play: an unactuated hinge on the driven hinge's axis, no
        # armature (the arm alone swings through it), stops as stiff as contacts
        b = math.radians(play[k - 1])
        if b <= 0:
            return ""
        axis = "0 0 -1" if k == 1 else "0 0 1"
        # gear teeth are rigid: the stops are as stiff as the step integrates (2 dt), with the contacts' solimp
        # (robot.backlash_stop_timeconst, when given: compliant teeth; never stiffer than 2 dt)
        stop = 2 * s.timestep if p.backlash_stop_timeconst is None else max(p.backlash_stop_timeconst, 2 * s.timestep)
        teeth = (f'solreflimit="{_fmt(stop, 1.0)}" solimplimit="{_fmt(*s.contact_solimp)}"')
        # the friction as firm as the stops, and nearly hard (MuJoCo's friction loss is a soft constraint: at
        # its defaults an arm as light as this one creeps through its play under half the friction torque)
        mesh = (f' frictionloss="{p.backlash_friction:.9g}" solreffriction="{_fmt(2 * s.timestep, 1.0)}" '
                'solimpfriction="0.999 0.9999 0.001"' if p.backlash_friction > 0 else "")
        return (f'\n        <joint name="r{i}_k{k}" type="hinge" axis="{axis}" ref="0" '
                f'range="{-b:.9g} {b:.9g}" {teeth}{mesh}/>')
    inertial = ""
    if quirk.com_offset != (0.0, 0.0):
        # an explicit inertial moves the body's centre of mass, not its shape
        m = p.body_mass
        ixx, iyy, izz = (m / 12 * (u * u + v * v) for u, v in
                         ((p.body_thickness, p.body_height), (p.body_length, p.body_height),
                          (p.body_length, p.body_thickness)))
        inertial = (f'\n      <inertial pos="{_fmt(*quirk.com_offset, 0.0)}" mass="{m:.9g}" '
                    f'diaginertia="{_fmt(ixx, iyy, izz)}"/>')
    return f"""
    <body name="r{i}" pos="{_fmt(x, y, hh)}" quat="{quat}">
      <freejoint name="r{i}_free"/>{inertial}
      <geom name="r{i}_body" type="box" size="{_fmt(hw, hd, hh)}" mass="{p.body_mass:.9g}"
            contype="{plate_bits | _ROBOT_BIT}" conaffinity="{plate_bits | _ROBOT_BIT}" rgba="{rgba}"/>
      <body name="r{i}_arm1" pos="{_fmt(-hx, 0, arm_dz)}">
        <joint name="r{i}_a1" type="hinge" axis="0 0 -1" {joint}/>{free_play(1)}
        {_arm_geom_xml(f"r{i}_arm1", p, -1, len1)}{_mount_geom_xml(f"r{i}_arm1", p, -1)}
      </body>
      <body name="r{i}_arm2" pos="{_fmt(hx, 0, arm_dz)}">
        <joint name="r{i}_a2" type="hinge" axis="0 0 1" {joint}/>{free_play(2)}
        {_arm_geom_xml(f"r{i}_arm2", p, 1, len2)}{_mount_geom_xml(f"r{i}_arm2", p, 1)}
      </body>
    </body>""", (a1, a2)


def _boundary_xml(s: SceneParams) -> str:
    if s.boundary_radius is None:
        return ""
    n = s.boundary_segments
    half_len = s.boundary_radius * math.tan(math.pi / n) * 1.02
    h = s.robot.body_height
    parts = []
    for k in range(n):
        ang = 2 * math.pi * k / n
        cx = (s.boundary_radius + 0.005) * math.cos(ang)
        cy = (s.boundary_radius + 0.005) * math.sin(ang)
        parts.append(
            f'    <geom name="wall{k}" type="box" size="{_fmt(0.005, half_len, h)}" pos="{_fmt(cx, cy, h)}" '
            f'euler="0 0 {math.degrees(ang):.9g}" contype="{_ROBOT_BIT}" conaffinity="{_ROBOT_BIT}" '
            f'rgba="0.6 0.6 0.6 0.4"/>')
    return "\n".join(parts)


def _servo_xml(i: int, rp: RobotParams, lim: float) -> list[str]:
    """Actuators of robot i: per hinge a position loop (ctrl: setpoint) and a
    velocity loop (ctrl: the setpoint's rate, the feed-forward), in that order.

    With a response lag both controls pass through MuJoCo's exact first-order
    filter (dyntype filterexact, time constant ``servo_timeconst``); the
    filter state is the actuator's activation, which engines initialise to
    the controls at t = 0.
    """
    out = []
    tau = rp.servo_timeconst
    # each actuator clipped at the stall torque as well ("actuator" clip): MuJoCo
    # then treats a clipped actuator's force as a constant in the implicit step
    clip = (f' forcerange="{-rp.servo_torque:.9g} {rp.servo_torque:.9g}"' if rp.servo_clip == "actuator" else "")
    for k in (1, 2):
        if tau > 0:
            out.append(f'    <general name="r{i}_p{k}" joint="r{i}_a{k}" dyntype="filterexact" dynprm="{tau:.9g}" '
                       f'gainprm="{rp.servo_kp:.9g}" biastype="affine" biasprm="0 {-rp.servo_kp:.9g} 0" '
                       f'ctrlrange="{-lim:.9g} {lim:.9g}"{clip}/>')
        else:
            out.append(f'    <position name="r{i}_p{k}" joint="r{i}_a{k}" kp="{rp.servo_kp:.9g}" '
                       f'ctrlrange="{-lim:.9g} {lim:.9g}"{clip}/>')
    for k in (1, 2):
        if tau > 0:
            out.append(f'    <general name="r{i}_v{k}" joint="r{i}_a{k}" dyntype="filterexact" dynprm="{tau:.9g}" '
                       f'gainprm="{rp.kv:.9g}" biastype="affine" biasprm="0 0 {-rp.kv:.9g}"{clip}/>')
        else:
            out.append(f'    <velocity name="r{i}_v{k}" joint="r{i}_a{k}" kv="{rp.kv:.9g}"{clip}/>')
    return out


def build_mjcf(params: SceneParams, poses: Sequence[Sequence[float]], name: str = "smarticles",
               sensors: str = "touch", extra_sensors: str = "") -> str:
    """Return the MJCF text of a scene with one robot per pose.

    Args:
      params: scene parameters (validated here).
      poses: N poses ``(x, y, heading, alpha1, alpha2)`` in m and rad.
      name: model name.

    Returns:
      MJCF XML text. Arm angles of the poses become the hinges' initial
      ``qpos`` through a keyframe named ``init``. Controls per robot are
      ``(alpha1, alpha2, rate1, rate2)``: setpoints (rad) then their rates
      (rad/s), robot after robot. For every robot pair (i < j) a contact
      sensor ``touch_i_j`` counts the contacts between the two robots.
      sensors: "touch" (that count), "record" (the count and the pair's smallest
        distance, as the engines' per-period record reads it) or "none" (no
        sensor block: MJX has no subtree contact sensor).
      extra_sensors: MJCF sensor lines appended after the touch sensors (the
        engine's collision record).
    """
    if sensors not in ("touch", "record", "none"):
        raise ValueError(f"sensors must be touch, record or none, got {sensors!r}")
    params.validate()
    poses = [tuple(p) for p in poses]
    if len(poses) < 1:
        raise ValueError("a scene needs at least one robot pose")
    for p in poses:
        if len(p) != 5 or not all(math.isfinite(float(v)) for v in p):
            raise ValueError(f"a pose is 5 finite numbers (x, y, heading, alpha1, alpha2), got {p}")
    rp = params.robot
    lim = math.radians(rp.arm_limit_deg)
    bodies, arms = [], []
    explicit = params.explicit_plate_contacts
    for i, pose in enumerate(poses):
        xml, a = _robot_xml(i, params, pose, plate_bits=0 if explicit else _PLATE_BIT)
        if max(abs(a[0]), abs(a[1])) > lim:
            raise ValueError(f"robot {i}: initial arm angles {a} exceed the hinge limit {rp.arm_limit_deg} deg")
        bodies.append(xml)
        arms.append(a)
    n = len(poses)
    acts = []
    for i in range(n):
        acts += _servo_xml(i, rp, lim)
    sensor_lines = []
    for i in range(n):
        for j in range(i + 1, n):
            data = 'data="found" num="1"' if sensors == "touch" else 'data="found dist" num="1" reduce="mindist"'
            sensor_lines.append(f'    <contact name="touch_{i}_{j}" subtree1="r{i}" subtree2="r{j}" {data}/>')
    if extra_sensors:
        sensor_lines.append(extra_sensors)
    sensor_block = "" if sensors == "none" else "  <sensor>\n" + "\n".join(sensor_lines) + "\n  </sensor>\n"
    excludes = "\n".join(f'    <exclude body1="r{i}_arm1" body2="r{i}_arm2"/>' for i in range(n))
    if explicit:
        # body-plate contacts as explicit pairs: the plane's contact frame has its
        # first tangent along plate y and its second along x (checked in
        # tests/test_scene.py), so two sliding coefficients are an anisotropic
        # plate; bodies no longer collide with it dynamically
        mu = params.plate_friction
        sol = f'solref="{_fmt(params.contact_timeconst, params.contact_dampratio)}" solimp="{_fmt(*params.contact_solimp)}"'
        pairs = [f'    <pair geom1="plate" geom2="r{i}_body" condim="3" {sol} '
                 f'friction="{_fmt(mu * params.plate_friction_y_ratio, mu, 0.005, 0.0001, 0.0001)}"/>'
                 for i in range(n)]
        if params.arm_plate_friction > 0:
            pairs += [f'    <pair geom1="plate" geom2="r{i}_arm{k}" condim="3" {sol} '
                      f'friction="{_fmt(params.arm_plate_friction, params.arm_plate_friction, 0.005, 0.0001, 0.0001)}"/>'
                      for i in range(n) for k in (1, 2)]
        excludes += "\n" + "\n".join(pairs)
    gravity = "" if params.plate_tilt_deg == (0.0, 0.0) else f' gravity="{_fmt(*params.gravity)}"'
    qpos = []
    for i, pose in enumerate(poses):
        x, y, heading = (float(v) for v in pose[:3])
        qpos += [x, y, rp.body_height / 2, math.cos(heading / 2), 0, 0, math.sin(heading / 2), *arms[i]]
    ctrl = [c for pair in arms for c in (*pair, 0.0, 0.0)]
    act = f' act="{_fmt(*ctrl)}"' if rp.servo_timeconst > 0 else ""
    # contacts not involving the plate take the default class's solref; the plate's own solref and a solmix
    # that outweighs the robots' (MuJoCo mixes two geoms' solref by solmix) keep robot-plate contacts at
    # contact_dampratio when robot_dampratio differs
    robot_dr = params.contact_dampratio if params.robot_dampratio is None else params.robot_dampratio
    solref = _fmt(params.contact_timeconst, robot_dr)
    plate_sol = ("" if params.robot_dampratio is None else
                 f' solref="{_fmt(params.contact_timeconst, params.contact_dampratio)}" solmix="1e9"')
    solver, iterations = params.constraint_solver(len(poses))
    plate = 2.0 if params.boundary_radius is None else params.boundary_radius + 0.1
    return f"""<mujoco model="{name}">
  <!-- generated by smarticle_mjx.scene.build_mjcf; do not edit by hand -->
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{params.timestep:.9g}" integrator="{params.integrator}" cone="elliptic" solver="{solver}"{gravity}
          iterations="{iterations}" ls_iterations="{params.ls_iterations}" tolerance="{params.tolerance:.9g}"/>
  <default>
    <geom condim="3" friction="{params.robot_friction:.9g} 0.005 0.0001" solref="{solref}"
          solimp="{_fmt(*params.contact_solimp)}"/>
  </default>
  <worldbody>
    <light pos="0 0 1" dir="0 0 -1"/>
    <geom name="plate" type="plane" size="{plate:.9g} {plate:.9g} 0.01" priority="1"
          friction="{params.plate_friction:.9g} 0.005 0.0001" contype="{_PLATE_BIT}" conaffinity="{_PLATE_BIT}"{plate_sol}
          rgba="0.8 0.8 0.8 1"/>
{_boundary_xml(params)}{''.join(bodies)}
  </worldbody>
  <contact>
{excludes}
  </contact>
  <actuator>
{chr(10).join(acts)}
  </actuator>
{sensor_block}  <keyframe>
    <key name="init" qpos="{_fmt(*qpos)}" ctrl="{_fmt(*ctrl)}"{act}/>
  </keyframe>
</mujoco>
"""


def compile_model(xml: str) -> mujoco.MjModel:
    """Compile MJCF text; raise ValueError with MuJoCo's message on failure."""
    try:
        return mujoco.MjModel.from_xml_string(xml)
    except Exception as e:  # mujoco raises a bare ValueError/Exception
        raise ValueError(f"MJCF does not compile: {e}") from e


@dataclasses.dataclass(frozen=True)
class SceneLayout:
    """Index maps from a compiled scene, computed once per model."""

    n_robots: int
    free_qpos: np.ndarray  # (N,) start of each robot's free-joint qpos
    free_qvel: np.ndarray  # (N,) start of each robot's free-joint qvel
    arm_qpos: np.ndarray  # (N, 2) qpos address of the two hinges
    arm_qvel: np.ndarray  # (N, 2)
    geom_robot: np.ndarray  # (ngeom,) robot owning each geom, -1 for world geoms
    pairs: np.ndarray  # (P, 2) robot index pairs i < j, sensor order
    # (N, 2) qpos address of each arm's free-play (backlash) hinge, -1 where it has none;
    # an arm's angle is its driven hinge's plus this one's
    play_qpos: np.ndarray | None = None

    def arm_angles(self, qpos: np.ndarray, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Robot ``i``'s arm angles (alpha1, alpha2) from qpos [..., nq]: driven hinge plus free play."""
        out = []
        for k in (0, 1):
            a = qpos[..., self.arm_qpos[i, k]]
            if self.play_qpos is not None and self.play_qpos[i, k] >= 0:
                a = a + qpos[..., self.play_qpos[i, k]]
            out.append(a)
        return out[0], out[1]

    @staticmethod
    def of(model: mujoco.MjModel) -> "SceneLayout":
        n = 0
        while mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"r{n}") >= 0:
            n += 1
        if n == 0:
            raise ValueError("model has no smarticle bodies named r0, r1, ...")
        fq, fv, aq, av, pq = [], [], [], [], []
        for i in range(n):
            play = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"r{i}_k{k}") for k in (1, 2)]
            pq.append([model.jnt_qposadr[k] if k >= 0 else -1 for k in play])
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"r{i}_free")
            fq.append(model.jnt_qposadr[j])
            fv.append(model.jnt_dofadr[j])
            ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"r{i}_a{k}") for k in (1, 2)]
            aq.append([model.jnt_qposadr[k] for k in ids])
            av.append([model.jnt_dofadr[k] for k in ids])
        geom_robot = np.full(model.ngeom, -1, dtype=np.int32)
        for g in range(model.ngeom):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
            if name.startswith("r") and "_" in name:
                geom_robot[g] = int(name[1:name.index("_")])
        pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)], dtype=np.int32).reshape(-1, 2)
        pq = np.array(pq, dtype=np.int64)
        return SceneLayout(n, np.array(fq), np.array(fv), np.array(aq), np.array(av), geom_robot, pairs,
                           pq if (pq >= 0).any() else None)


def standard_poses(kind: str, robot: RobotParams = RobotParams()) -> list[tuple[float, ...]]:
    """Initial poses of the reference scenes in ``models/``.

    ``single``: one robot at the origin. ``pair``: a C1-like anti-aligned pair
    (|r| = 1.3 W, theta = 270 deg, phi = 180 deg). ``seven``: the paper's
    compressed relaxation start, 7 robots side by side on a hexagonal patch,
    arms at the gait's first corner.
    """
    a = math.pi / 2
    if kind == "single":
        return [(0.0, 0.0, 0.0, a, a)]
    if kind == "pair":
        p1 = (0.0, 0.0, 0.0, a, a)
        # |r| = 1.3 W at theta = 270 deg (robot 1's normal, -y), phi = 180 deg
        return [p1, (0.0, -1.3 * robot.body_length, math.pi, a, a)]
    if kind == "seven":
        # Arms folded to (+90, +90): each robot is a U about W+2L... wide; pack
        # the U's in staggered rows with a small gap.
        w = robot.body_length + 2 * robot.arm_thickness + 0.004
        depth = robot.arm_length + robot.body_thickness / 2 + 0.004
        spots = [(-w, 0), (0, 0), (w, 0), (-w / 2, -depth), (w / 2, -depth), (-w / 2, depth), (w / 2, depth)]
        return [(x, y, 0.0, a, a) for x, y in spots]
    raise ValueError(f"unknown standard scene {kind!r} (single, pair, seven)")


REFERENCE_SCENES = ("single", "pair", "seven")


def reference_models(params: SceneParams = SceneParams()) -> dict[str, str]:
    """MJCF text of the reference scenes stored in ``models/``, by file name."""
    return {f"{k}.xml": build_mjcf(params, standard_poses(k, params.robot), name=f"smarticles_{k}")
            for k in REFERENCE_SCENES}


def write_reference_models(out, params: SceneParams = SceneParams(), check: bool = False) -> list[str]:
    """Write the reference scenes into the folder ``out`` where they differ (``check``: write nothing);
    returns the names that were stale. Raises ValueError for a missing folder, or with ``check``
    for stale scenes."""
    import pathlib
    out = pathlib.Path(out)
    stale = [name for name, xml in reference_models(params).items()
             if not ((out / name).exists() and (out / name).read_text() == xml)]
    if check and stale:
        raise ValueError(f"stale models: {', '.join(stale)}; run `smx models`")
    if stale and not out.is_dir():
        raise ValueError(f"directory {out} does not exist")
    for name, xml in reference_models(params).items():
        if name in stale:
            (out / name).write_text(xml)
    return stale


def _quirks_from_json(d: dict) -> tuple[RobotQuirk, ...]:
    return tuple(RobotQuirk(backlash_deg=None if q.get("backlash_deg") is None else tuple(q["backlash_deg"]),
                            com_offset=tuple(q.get("com_offset", (0.0, 0.0)))) for q in d.get("quirks", ()))


def predated_fields(d: dict) -> dict:
    """Scene fields a store's recorded scene ``d`` (``config["scene"]``) predates whose value then was not
    today's default: the solver, "auto" since it was added (November 2026, after version 0.4.0), was
    Newton before, which "auto" still is for robots without gear play."""
    if "solver" in d:
        return {}
    quirks = _quirks_from_json(d)
    robot = RobotParams(**{k: v for k, v in d.get("robot", {}).items() if k == "backlash_deg"})
    play = SceneParams(robot=robot, quirks=quirks).has_play(max(1, len(quirks)))
    return {"solver": "Newton" if play else "auto"}


def params_from_json(d: dict) -> SceneParams:
    """The SceneParams a store recorded (its ``config["scene"]``), lists back to tuples; a field the store
    predates takes the value it implicitly had (:func:`predated_fields`), else its default."""
    robot = RobotParams(**d["robot"])
    d = {**predated_fields(d), **d}
    rest = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items() if k not in ("robot", "quirks")}
    return SceneParams(robot=robot, quirks=_quirks_from_json(d), **rest)


def params_json(params: SceneParams) -> dict:
    """The SceneParams as a store records them (``config["scene"]``; :func:`params_from_json` reads them back)."""
    # through JSON: tuples become lists, as a resumed store's saved copy has them
    return json.loads(json.dumps(dataclasses.asdict(params)))
