"""The paper's engine as a twin: smarticles built in DART (``dartpy``), the simulator
the paper's own runs used (implicit LCP contacts, 0.1 ms steps, SERVO joints).

This module builds the same ``SceneParams`` as DART skeletons and steps them
with the gait behind the engine interface (:class:`DartBackend`; docs/twin.md).
What it builds, piece by piece as :mod:`smarticle_mjx.scene` builds it for
MuJoCo:

* the plate: a static box whose top face is z = 0;
* each robot: a free body (box ``body_length`` x ``body_thickness`` x
  ``body_height``, mass ``body_mass``) with two arms on revolute joints
  ``hinge_x`` from its centre, at the arms' height (``arm_z``), arm 1 about
  -z pointing along -x, arm 2 about +z along +x, as in the MJCF; plate arms
  are boxes, capsule arms capsules; masses and box inertias as MuJoCo
  computes them for a uniform solid;
* contacts: the plate's and every shape's friction coefficient (DART
  combines two by their minimum), no restitution; arms never touch the
  plate and a robot never touches itself (as the MJCF's contact bits);
* the servo: DART's SERVO actuator, a velocity constraint whose force is
  bounded by ``servo_torque``, commanded with the gait's rate plus a trim
  ``servo_kp / servo_kv`` times the angle error (the `dart` preset's law);
  or, with ``DartNumerics(servo="pd")``, the preset's own PD + lag law as
  joint forces; hinge stops at ``arm_limit_deg`` enforced as hard limits.

Numerics are the caller's: time step (default 0.1 ms, the paper's SI),
collision detector (``fcl-mesh``, DART's default, which treats boxes as
meshes; ``fcl``, ``ode``, ``bullet``, ``dart`` with primitive shapes) and
boxed LCP solver (``dantzig``, DART's default, or ``pgs``).
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
from typing import Sequence

import numpy as np

from ..gait import GaitSpec
from ..capabilities import require, supports
from .core import (BackendBase, check_start_delays, check_timing, PeriodRecords, Status, blank_collisions,
                   collision_bin_of, lane_controls, on_step_grid, steps_per_period)
from ..scene import RobotQuirk, SceneParams

MISSING = "the dart backend needs DART's Python package: pip install -e '.[dart]'"
DETECTORS = ("fcl-mesh", "fcl", "ode", "bullet", "dart")
LCP_SOLVERS = ("dantzig", "pgs")
SERVOS = ("constraint", "pd")
PLATE_THICKNESS = 0.02  # m; the plate is a static box whose top face is z = 0


def available() -> bool:
    return importlib.util.find_spec("dartpy") is not None


@dataclasses.dataclass(frozen=True)
class DartNumerics:
    """How DART runs the robots: its step, collision detector and LCP solver,
    and how the servo is realised: ``"constraint"``, DART's SERVO actuator (a
    velocity command held within the torque bound), or ``"pd"``, the preset's
    own PD + feed-forward + lag law applied as joint forces (the law of the
    MJCF's actuators; DART has no joint armature, so it needs a model with
    ``servo_armature`` 0)."""

    timestep: float = 1e-4
    detector: str = "fcl-mesh"
    lcp: str = "dantzig"
    servo: str = "constraint"

    def record(self) -> list:
        """As a store records it: [time step, detector, LCP solver], and the servo unless it is DART's own."""
        return [self.timestep, self.detector, self.lcp] + ([self.servo] if self.servo != "constraint" else [])

    def validate(self) -> None:
        if not self.timestep > 0:
            raise ValueError(f"DART time step must be positive, got {self.timestep}")
        if self.detector not in DETECTORS:
            raise ValueError(f"DART collision detector must be one of {', '.join(DETECTORS)}, got {self.detector!r}")
        if self.lcp not in LCP_SOLVERS:
            raise ValueError(f"DART LCP solver must be one of {', '.join(LCP_SOLVERS)}, got {self.lcp!r}")
        if self.servo not in SERVOS:
            raise ValueError(f"DART servo must be one of {', '.join(SERVOS)}, got {self.servo!r}")


def numerics_of(spec) -> DartNumerics:
    """The numerics a study names as (time step s, collision detector, LCP solver[, servo]); None: the defaults."""
    if spec is None:
        return DartNumerics()
    if len(spec) not in (3, 4):
        raise ValueError(f"dart numerics are (time step, detector, LCP solver[, servo]), got {list(spec)}")
    timestep, detector, lcp, *servo = spec
    return DartNumerics(timestep=float(timestep), detector=str(detector), lcp=str(lcp),
                        servo=str(servo[0]) if servo else "constraint")


def check_model(params: SceneParams, numerics: DartNumerics) -> None:
    """ValueError for a model the twin cannot build: armature under its pd servo, backlash or
    per-robot quirks (DART builds ideal rigid arms on one hinge each)."""
    if numerics.servo == "pd" and params.robot.servo_armature > 0:
        raise ValueError("DART has no joint armature: its pd servo needs a model with servo_armature 0, "
                         f"got {params.robot.servo_armature:g} kg m^2")
    if params.robot.has_mount:
        require("dart", "arm_mounts")  # the twin builds one shape per arm
    if params.robot.backlash_deg > 0 or any(q != RobotQuirk() for q in params.quirks):
        require("dart", "robot_quirks")  # the twin builds ideal rigid arms on one hinge each


# Scene fields the twin does not read: MuJoCo's numerics (DART steps and resolves contacts by its own
# numerics, ``dart_numerics``) and plate departures it does not build. ``--set`` on one of them is
# refused on the twin rather than silently ignored.
NOT_BUILT = ("timestep", "integrator", "contact_substeps", "substep_gate", "solver", "iterations", "ls_iterations",
             "tolerance", "contact_timeconst", "contact_dampratio", "robot_dampratio", "contact_solimp",
             "boundary_radius", "boundary_segments", "plate_friction_y_ratio", "arm_plate_friction",
             "robot.backlash_friction", "robot.backlash_stop_timeconst")


def check_study(backend: str, spec, params: SceneParams | None = None, overrides=()) -> None:
    """A study's backend and DART numerics agree, DART is installed when it runs on it, can build
    ``params`` when given and reads every field the study's ``overrides`` change (ValueError)."""
    if supports(backend, "own_numerics"):
        ignored = sorted(k for k, _ in overrides if k in NOT_BUILT)
        if ignored:
            raise ValueError(f"--set {', '.join(ignored)}: the DART twin does not read "
                             f"{'this field' if len(ignored) == 1 else 'these fields'} (its step and contacts "
                             "come from dart_numerics); run it on a MuJoCo backend")
        if not available():
            raise ValueError(MISSING)
        numerics = numerics_of(spec)
        numerics.validate()
        if params is not None:
            check_model(params, numerics)
    elif spec is not None:
        raise ValueError("dart numerics are for --backend dart")


def study_options(backend: str, spec) -> dict:
    """Keyword arguments of ``make_backend`` beyond the scene for a study on ``backend`` (DART's numerics)."""
    return {"numerics": numerics_of(spec)} if supports(backend, "own_numerics") else {}


def study_timestep(backend: str, spec, scene_timestep: float) -> float:
    """The step the study's engine takes: DART's numerics' on the twin, the scene's on MuJoCo."""
    return numerics_of(spec).timestep if supports(backend, "own_numerics") else scene_timestep


def study_json(d: dict, backend: str) -> dict:
    """A study's stored settings ``d`` (its ``dart_numerics`` as given): on the twin the
    numerics resolved, so the store says what ran; other backends' stores keep
    the settings they had before the twin existed (no such key)."""
    spec = d.pop("dart_numerics")
    if supports(backend, "own_numerics"):
        d["dart_numerics"] = numerics_of(spec).record()
    return d


def _box_inertia(mass: float, sx: float, sy: float, sz: float) -> tuple[float, float, float]:
    """Principal moments of a uniform solid box of full sides sx, sy, sz."""
    return (mass * (sy ** 2 + sz ** 2) / 12, mass * (sx ** 2 + sz ** 2) / 12, mass * (sx ** 2 + sy ** 2) / 12)


def _translation(xyz) -> "object":
    import dartpy as dart
    t = dart.math.Isometry3()
    t.set_translation(np.asarray(xyz, float))
    return t


def _contact_shape(node, shape, mu: float, name: str, at=(0.0, 0.0, 0.0), rotation=None):
    sn = node.createShapeNode(shape, name)
    sn.createCollisionAspect()
    dyn = sn.createDynamicsAspect()
    dyn.setFrictionCoeff(mu)
    dyn.setRestitutionCoeff(0.0)
    if rotation is not None:
        sn.setRelativeRotation(rotation)
    sn.setRelativeTranslation(np.asarray(at, float))
    return sn


class DartScene:
    """N smarticles on a plate in one DART world.

    Args:
      params: the scene (robot geometry, masses, servo, friction).
      poses: [N, 5] (x, y, heading, alpha1, alpha2) per robot; bodies rest on the plate.
      numerics: DART's step, collision detector, LCP solver and servo.
      plate: False builds the robots in free space, without gravity (for
        checks of conservation laws); poses then give their heights as on
        the plate.
    """

    def __init__(self, params: SceneParams, poses: Sequence[Sequence[float]],
                 numerics: DartNumerics = DartNumerics(), plate: bool = True):
        if not available():
            raise ValueError(MISSING)
        import dartpy as dart
        numerics.validate()
        params.validate()
        check_model(params, numerics)
        self.params, self.numerics = params, numerics
        self._act = None  # the pd servo's filtered (setpoint, rate) per robot and arm
        D = dart.dynamics
        self.world = world = dart.simulation.World()
        world.setGravity(np.asarray(params.gravity, float) if plate else np.zeros(3))
        world.setTimeStep(numerics.timestep)
        self._set_numerics(dart)
        ground = D.Skeleton("plate")
        _, plate_node = ground.createWeldJointAndBodyNodePair(None)
        if plate:
            _contact_shape(plate_node, D.BoxShape([2.0, 2.0, PLATE_THICKNESS]), params.plate_friction,
                           "plate", at=(0, 0, -PLATE_THICKNESS / 2))
        world.addSkeleton(ground)
        self.plate = plate_node
        rp = params.robot
        self.robots = []  # (free joint, body node, (arm joint 1, arm joint 2), (arm node 1, arm node 2))
        lim = math.radians(rp.arm_limit_deg)
        filt = dart.collision.BodyNodeCollisionFilter()
        for i, pose in enumerate(np.asarray(poses, float).reshape(-1, 5)):
            sk = D.Skeleton(f"r{i}")
            free, body = sk.createFreeJointAndBodyNodePair(None)
            body.setMass(rp.body_mass)
            body.setMomentOfInertia(*_box_inertia(rp.body_mass, rp.body_length, rp.body_thickness, rp.body_height))
            _contact_shape(body, D.BoxShape([rp.body_length, rp.body_thickness, rp.body_height]),
                           params.robot_friction, f"r{i}_body")
            joints, arms = [], []
            for k, (sign, length) in enumerate(zip((-1, 1), rp.arm_lengths)):
                props = D.RevoluteJointProperties()
                props.mName = f"r{i}_a{k + 1}"
                props.mAxis = np.array([0.0, 0.0, float(sign)])
                props.mT_ParentBodyToJoint = _translation((sign * rp.hinge_x, 0.0, rp.arm_z - rp.body_height / 2))
                joint, arm = sk.createRevoluteJointAndBodyNodePair(body, props)
                arm.setMass(rp.arm_mass)
                if rp.arm_shape == "plate":
                    size = (length, rp.arm_thickness, rp.arm_extent_z)
                    arm.setMomentOfInertia(*_box_inertia(rp.arm_mass, *size))
                    arm.setLocalCOM(np.array([sign * length / 2, 0.0, 0.0]))
                    _contact_shape(arm, D.BoxShape(list(size)), params.robot_friction, f"r{i}_arm{k + 1}",
                                   at=(sign * length / 2, 0, 0))
                else:
                    r = rp.arm_radius
                    tip = length - r  # the capsule ends exactly at the arm length, as in the MJCF
                    m = rp.arm_mass
                    arm.setMomentOfInertia(m * r * r / 2, m * (3 * r * r + tip * tip) / 12 + m * (tip / 2) ** 2,
                                           m * (3 * r * r + tip * tip) / 12 + m * (tip / 2) ** 2)
                    arm.setLocalCOM(np.array([sign * tip / 2, 0.0, 0.0]))
                    y90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # capsule z -> x
                    _contact_shape(arm, D.CapsuleShape(r, tip), params.robot_friction, f"r{i}_arm{k + 1}",
                                   at=(sign * tip / 2, 0, 0),
                                   rotation=y90)
                joint.setActuatorType(D.ActuatorType.SERVO if numerics.servo == "constraint"
                                      else D.ActuatorType.FORCE)
                joint.setDampingCoefficient(0, rp.joint_damping)
                joint.setForceLowerLimit(0, -rp.servo_torque)
                joint.setForceUpperLimit(0, rp.servo_torque)
                joint.setPositionLowerLimit(0, -lim)
                joint.setPositionUpperLimit(0, lim)
                joint.setLimitEnforcement(True)
                filt.addBodyNodePairToBlackList(arm, plate_node)  # arms ride above the plate (the MJCF filters them)
                joints.append(joint)
                arms.append(arm)
            filt.addBodyNodePairToBlackList(arms[0], arms[1])  # a robot never touches itself
            sk.setSelfCollisionCheck(False)
            x, y, heading, a1, a2 = pose
            free.setPositions(np.array([0.0, 0.0, heading, x, y, rp.body_height / 2]))
            joints[0].setPosition(0, a1)
            joints[1].setPosition(0, a2)
            world.addSkeleton(sk)
            self.robots.append((free, body, tuple(joints), tuple(arms)))
        world.getConstraintSolver().getCollisionOption().collisionFilter = filt
        # the shape nodes (kept alive, so that DART's contacts hand back these very Python objects),
        # and id(shape node) -> (robot, part); names cost a string copy per call, identities nothing
        self._shapes = [plate_node.getShapeNode(0)] if plate else []
        self._part = {}
        for i, (_, body, _, arms) in enumerate(self.robots):
            for q, node in enumerate((body, *arms)):
                sn = node.getShapeNode(0)
                self._shapes.append(sn)
                self._part[id(sn)] = (i, q)
        self._filter = filt  # the option holds a reference; keep the filter alive with the scene

    def _set_numerics(self, dart):
        det = self.numerics.detector
        if det.startswith("fcl"):
            detector = dart.collision.FCLCollisionDetector()
            detector.setPrimitiveShapeType(dart.collision.FCLCollisionDetector.MESH if det == "fcl-mesh"
                                           else dart.collision.FCLCollisionDetector.PRIMITIVE)
        else:
            detector = {"ode": dart.collision.OdeCollisionDetector, "bullet": dart.collision.BulletCollisionDetector,
                        "dart": dart.collision.DARTCollisionDetector}[det]()
        solver = self.world.getConstraintSolver()
        solver.setCollisionDetector(detector)
        # DART's default: Dantzig's pivoting solver, PGS as its fallback when it fails
        if self.numerics.lcp == "pgs":
            solver.setBoxedLcpSolver(dart.constraint.PgsBoxedLcpSolver())

    # ------------------------------------------------------------------ state
    def poses(self) -> np.ndarray:
        """[N, 5] (x, y, heading, alpha1, alpha2) of every robot now."""
        out = np.empty((len(self.robots), 5))
        for i, (free, body, joints, _) in enumerate(self.robots):
            t = body.getWorldTransform()
            rot, pos = np.asarray(t.rotation()), np.asarray(t.translation())
            out[i] = (pos[0], pos[1], math.atan2(rot[1, 0], rot[0, 0]), joints[0].getPosition(0),
                      joints[1].getPosition(0))
        return out

    def set_body_velocity(self, robot: int, vx: float, vy: float, wz: float = 0.0) -> None:
        """Launch a robot's body: world-frame planar velocity (m/s) and yaw rate (rad/s)."""
        free, body, _, _ = self.robots[robot]
        rot = np.asarray(body.getWorldTransform().rotation())
        v_body = rot.T @ np.array([vx, vy, 0.0])  # the free joint's velocities are in the body frame
        w_body = rot.T @ np.array([0.0, 0.0, wz])
        free.setVelocities(np.concatenate([w_body, v_body]))

    # ------------------------------------------------------------------ servo
    def command(self, setpoints: np.ndarray, rates: np.ndarray) -> None:
        """Command every arm for the next step with its setpoint and the
        setpoint's rate ([N, 2] each, rad and rad/s).

        ``constraint`` servo: a SERVO velocity command, the rate plus the trim
        ``servo_kp / servo_kv`` x (setpoint - angle). ``pd`` servo: the joint
        torque clip(kp (s - q) + kv (v - qdot), +-servo_torque), where (s, v)
        pass through the MJCF's exact first-order filter of time constant
        ``servo_timeconst`` (started at the first command, and, as MuJoCo's
        actuator activation, applied to this step before the filter takes in
        this step's command)."""
        if self.numerics.servo == "pd":
            return self._pd(np.asarray(setpoints, float), np.asarray(rates, float))
        rp = self.params.robot
        trim = rp.servo_kp / rp.kv if rp.kv else 0.0
        for (_, _, joints, _), sp, rate in zip(self.robots, np.asarray(setpoints), np.asarray(rates)):
            for k in range(2):
                # in float64 whatever the controls' dtype (float32 from the gait function)
                joints[k].setCommand(0, float(rate[k]) + trim * (float(sp[k]) - joints[k].getPosition(0)))

    def _pd(self, sp: np.ndarray, rate: np.ndarray) -> None:
        rp = self.params.robot
        u = np.stack([sp, rate], -1)  # [N, 2 arms, (setpoint, rate)]
        if self._act is None:
            self._act = u.copy()
        act = self._act
        for (_, _, joints, _), a in zip(self.robots, act):
            for k in range(2):
                j = joints[k]
                tau = rp.servo_kp * (a[k, 0] - j.getPosition(0)) + rp.kv * (a[k, 1] - j.getVelocity(0))
                j.setCommand(0, min(max(tau, -rp.servo_torque), rp.servo_torque))
        tau_f = rp.servo_timeconst
        self._act = u if tau_f <= 0 else act + (u - act) * -math.expm1(-self.numerics.timestep / tau_f)

    def hold(self) -> None:
        """Command every arm to stay where it is (the servo at rest)."""
        p = self.poses()
        self.command(p[:, 3:5], np.zeros((len(self.robots), 2)))

    def robot_contacts(self) -> list[tuple[int, int, int, float, float, float]]:
        """The robot-robot contacts of the last step: (i, j, kind, fx, fy, depth)
        with i < j, ``kind`` the index of (robot i's part, robot j's part) in
        the engine's CONTACT_KINDS, (fx, fy) DART's contact force on robot i
        (normal and friction, N, world frame) and the depth FCL reports (m)."""
        out = []
        part = self._part
        for c in self.world.getLastCollisionResult().getContacts():
            a = part.get(id(c.collisionObject1.getShapeFrame()))
            if a is None:  # the plate
                continue
            b = part.get(id(c.collisionObject2.getShapeFrame()))
            if b is None:
                continue
            (ri, pa), (rj, pb) = a, b
            if ri == rj:
                continue
            f = np.asarray(c.force)  # DART's contact force acts on collisionObject1
            if ri > rj:
                ri, pa, rj, pb, f = rj, pb, ri, pa, -f
            out.append((ri, rj, 3 * pa + pb, float(f[0]), float(f[1]), float(c.penetrationDepth)))
        return out

    def momentum(self) -> np.ndarray:
        """Total linear momentum of the robots (kg m/s, world frame)."""
        return sum(free.getSkeleton().getMass() * np.asarray(free.getSkeleton().getCOMLinearVelocity())
                   for free, _, _, _ in self.robots)

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            self.world.step()

    def run_gait(self, gait: GaitSpec, periods: int, on_step=None) -> np.ndarray:
        """Step the gait (every robot in phase) for ``periods`` periods from t = 0.

        ``on_step(period, step, steps)``, when given, is called after each
        step (``step`` counts from 0 within the period, of ``steps``).

        Returns poses at the start and at the end of each period, [periods + 1, N, 5].
        """
        from .. import gait as G
        dt = self.numerics.timestep
        T = gait.period()
        nstep = steps_per_period(T, dt)
        ctrl = np.asarray(G.setpoints_and_rates(dt * np.arange(nstep), gait.amplitude, T,
                                                self.params.robot.servo_speed, gait.chirality_sign,
                                                gait.kind_code, 0.0), float)
        n = len(self.robots)
        sp, rate = np.repeat(ctrl[:, None, :2], n, 1), np.repeat(ctrl[:, None, 2:4], n, 1)
        out = [self.poses()]
        for k in range(periods):
            for s in range(nstep):
                self.command(sp[s], rate[s])
                self.world.step()
                if on_step is not None:
                    on_step(k, s, nstep)
            out.append(self.poses())
        return np.stack(out)


class DartBackend(BackendBase):
    """The engine interface on DART: lanes in, per-period records out.

    Each lane is its own DART world (a :class:`DartScene`); the state is an
    object array of them, so the batch runner's take/put of slots works
    unchanged, and lanes run one after another on one core (a scan uses
    more cores through the Dask executor's workers). Records are those of
    the other backends: poses at period ends, per pair whether the robots
    touched and the deepest contact (-penetration depth, m), status bits
    for non-finite states and penetration beyond ``penetration_limit``.
    The collision record (``Record.collisions``) is that of the native
    backend, from DART's contact forces (normal and friction, N) times the
    step. Full-rate tracks (``Record.track_stride``) are the planar poses
    every ``track_stride`` steps, as MuJoCo qpos (bodies resting on the plate).

    With DART's default detector (``fcl-mesh``: boxes as meshes) the contact
    depths FCL reports are not geometric: 24 mm for arm-body contacts that
    the primitive detectors (fcl, ode, bullet) report 5-14 micrometres deep
    (measured on the same starts). There the backend records the touch and
    NaN for its depth, and sets no penetration status from it.

    Args:
      scene: the engine's Scene (its parameters and robot pairs; the MJCF is not used).
      numerics: DART's step, collision detector, LCP solver and servo.
    """

    name = "dart"
    batching = "occupied"  # see engine.core.BATCHING

    def __init__(self, scene, numerics: DartNumerics = DartNumerics(), penetration_limit: float = 0.002):
        if not available():
            raise ValueError(MISSING)
        numerics.validate()
        self.scene = scene
        self.numerics = numerics
        self.penetration_limit = penetration_limit
        self._pair = {tuple(p): k for k, p in enumerate(scene.layout.pairs.tolist())}
        self._depth_measured = numerics.detector != "fcl-mesh"

    def initial_state(self, lanes) -> np.ndarray:
        out = np.empty(lanes.size, dtype=object)
        for b in range(lanes.size):
            out[b] = DartScene(self.scene.params, lanes.poses[b], self.numerics)
        return out

    def _contacts(self, sc: "DartScene", touched: np.ndarray, depth: np.ndarray, kinds=None, forces=None) -> bool:
        """Fold the robot-robot contacts of the step just taken into ``touched`` and
        ``depth`` [P]; with ``kinds`` [P, 9] (bool) and ``forces`` [P, 9, 2],
        also which contact kinds touched and the net contact force on each
        pair's first robot. True if any robot touched another."""
        found = sc.robot_contacts()
        for i, j, kind, fx, fy, d in found:
            k = self._pair[(i, j)]
            touched[k] = True
            depth[k] = max(depth[k], d)
            if kinds is not None:
                kinds[k, kind] = True
                forces[k, kind] += (fx, fy)
        return bool(found)

    def advance(self, state: np.ndarray, lanes, n_periods: int, *, t0: float = 0.0, record=None):
        """Advance every lane's world by ``n_periods`` gait periods (same contract as the
        native backend). ``record.collisions`` keeps the collision record: per
        pair, contact kind and bin of the period, the steps in contact, the
        contact impulse on robot i (DART's contact force, normal and friction,
        times the step) and its component along r = c_j - c_i, with the body
        centres taken after the step (they move ~1e-6 of |r| in one step)."""
        check_start_delays(lanes, "dart")
        check_timing(lanes, "dart")
        dt = self.numerics.timestep
        lanes = on_step_grid(lanes, dt)
        nstep = steps_per_period(lanes.period, dt)
        b, n, p = lanes.size, self.scene.n_robots, self.scene.n_pairs
        u = lane_controls(self.scene, lanes, dt * np.arange(nstep)).reshape(b, nstep, n, 4)
        poses = np.empty((b, n_periods, n, 5))
        touched = np.zeros((b, n_periods, p), bool)
        min_dist = np.full((b, n_periods, p), np.inf)
        status = np.zeros(b, np.int32)
        bins = record.collision_bins if record is not None and record.collisions else 0
        coll = blank_collisions(b, n_periods, p, bins) if bins else None
        bin_of = collision_bin_of(nstep, bins) if bins else None
        pairs = self.scene.layout.pairs
        stride = record.track_stride if record is not None else None
        tq = np.empty((b, n_periods, nstep // stride if stride else 0, n, 5))
        for lane in range(b):
            sc = state[lane]
            bodies = [r[1] for r in sc.robots]
            for k in range(n_periods):
                depth = np.full(p, -np.inf)
                kinds, forces = (np.zeros((p, 9), bool), np.zeros((p, 9, 2))) if bins else (None, None)
                for s in range(nstep):
                    sc.command(u[lane, s, :, :2], u[lane, s, :, 2:])
                    sc.world.step()
                    if stride and (s + 1) % stride == 0:
                        tq[lane, k, (s + 1) // stride - 1] = sc.poses()
                    if self._contacts(sc, touched[lane, k], depth, kinds, forces) and bins:
                        centres = np.array([np.asarray(bd.getWorldTransform().translation())[:2] for bd in bodies])
                        g = bin_of[s]
                        for q in np.flatnonzero(kinds.any(1)):
                            i, j = pairs[q]
                            r = centres[j] - centres[i]
                            imp = forces[q] * dt
                            coll["steps"][lane, k, q, :, g] += kinds[q]
                            coll["impulse"][lane, k, q, :, g] += imp
                            coll["impulse_r"][lane, k, q, :, g] += imp @ (r / max(np.linalg.norm(r), 1e-12))
                        kinds[:] = False
                        forces[:] = 0.0
                poses[lane, k] = sc.poses()
                min_dist[lane, k] = np.where(touched[lane, k], -depth if self._depth_measured else np.nan, np.inf)
                if not np.isfinite(poses[lane, k]).all():
                    status[lane] |= int(Status.NONFINITE)
                if self._depth_measured and (min_dist[lane, k] < -self.penetration_limit).any():
                    status[lane] |= int(Status.PENETRATION)
        track = None
        if stride:  # as the native backend samples it: after every stride-th step of each period
            t = t0 + np.arange(n_periods)[:, None] * nstep * dt + dt * (stride * np.arange(1, nstep // stride + 1))
            track = {"t": t.ravel(), "qpos": self.scene.qpos_from_poses(tq.reshape(b, -1, n, 5))}
        return state, PeriodRecords(poses, touched, min_dist, status, coll), track
