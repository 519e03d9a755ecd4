"""What every backend shares (native, MJX, MuJoCo Warp, the DART twin): the compiled scene, lane parameters,
records, status.

A *lane* is one independent simulation of the same scene: its own initial
state, amplitude, chirality, gait kind and per-robot phase offsets. Backends
advance a batch of lanes by whole gait periods and return one
:class:`PeriodRecords` per call; nothing of size lanes x steps is kept unless
a full-rate track is asked for.
"""

from __future__ import annotations

import dataclasses
from typing import Protocol, runtime_checkable

import jax
import mujoco
import numpy as np

from .. import gait as gait_mod
from ..capabilities import require
from ..labels import CONTACT_KINDS, PARTS, Status  # noqa: F401 (the engine's names for them)
from ..scene import SceneLayout, SceneParams, build_mjcf, compile_model


# contact sensor output per pair: number of contacts, deepest distance
SENSOR_WIDTH = 2

# Collision record: the nine geom-pair kinds between robots i < j, in this
# order (robot i's part first). Each has a contact sensor reporting the
# number of contacts and the net contact force on robot i's part (world frame).
COLLISION_WIDTH = 4  # found, force x, y, z


@dataclasses.dataclass(frozen=True)
class Record:
    """What a run records beyond the per-period poses and touches.

    Attributes:
      track_stride: keep the full-rate state every this many steps (None: no track).
      collisions: keep the per-period collision record (native backend):
        for every robot pair and contact kind (:data:`CONTACT_KINDS`), per
        bin of the gait period, the steps in contact and the contact impulse
        on the pair's first robot.
      collision_bins: bins per gait period (phase resolution of that record).
    """

    track_stride: int | None = None
    collisions: bool = False
    collision_bins: int = 16

    def validate(self) -> None:
        if self.track_stride is not None and self.track_stride < 1:
            raise ValueError("track_stride must be >= 1")
        if self.collision_bins < 1:
            raise ValueError("collision_bins must be >= 1")


def collision_sensors_xml(n_robots: int) -> str:
    """Contact sensors of the collision record, pair after pair, kind after kind.

    ``body1`` is robot j's part and ``body2`` robot i's: MuJoCo's contact
    sensor reports the force that the first exerts on the second (the contact
    normal points from the first to the second), so the force is the one on
    robot i. A part is matched by its body (``r{i}`` holds only the body's
    geom, ``r{i}_arm1`` every geom of arm 1: its plate or capsule and, where
    the scene gives one, its mount), so an arm's mount counts as its arm.
    """
    def body(i: int, part: str) -> str:
        return f"r{i}" if part == "body" else f"r{i}_{part}"
    out = []
    for i in range(n_robots):
        for j in range(i + 1, n_robots):
            for a in PARTS:
                for b in PARTS:
                    out.append(f'    <contact name="coll_{i}_{j}_{a}_{b}" body1="{body(j, b)}" body2="{body(i, a)}" '
                               f'data="found force" reduce="netforce"/>')
    return "\n".join(out)


def refuse_mounts(params: SceneParams, backend: str) -> None:
    """ValueError in one line where a backend that cannot build them gets arms with mounts."""
    if params.robot.has_mount:
        require(backend, "arm_mounts")


@dataclasses.dataclass(frozen=True)
class Scene:
    """A compiled N-robot scene: the MuJoCo model and its index maps.

    The model is built from ``params`` with placeholder poses; each lane's
    initial poses are written into its state, so one model serves a batch.
    """

    params: SceneParams
    model: mujoco.MjModel
    layout: SceneLayout
    xml: str

    collisions: bool = False  # has the collision record's sensors (after the touch sensors)

    @staticmethod
    def mjcf(params: SceneParams, n_robots: int, collisions: bool = False, sensors: str = "record") -> str:
        """The scene's MJCF: ``n_robots`` robots spaced apart (lanes set their poses), with the
        per-period record's sensors (``sensors="none"``: none, for MJX) and, with ``collisions``,
        the collision record's."""
        if n_robots < 1:
            raise ValueError("n_robots must be >= 1")
        spacing = 4 * (params.robot.body_length + 2 * params.robot.arm_length)
        poses = [(spacing * i, 0.0, 0.0, 0.0, 0.0) for i in range(n_robots)]
        extra = collision_sensors_xml(n_robots) if collisions and n_robots > 1 and sensors != "none" else ""
        return build_mjcf(params, poses, sensors=sensors, extra_sensors=extra)

    @staticmethod
    def build(params: SceneParams, n_robots: int, collisions: bool = False) -> "Scene":
        """Compile the scene; ``collisions`` adds the collision record's sensors
        (they read contact forces and change nothing in the dynamics)."""
        xml = Scene.mjcf(params, n_robots, collisions)
        model = compile_model(xml)
        return Scene(params, model, SceneLayout.of(model), xml, collisions and n_robots > 1)

    @property
    def n_robots(self) -> int:
        return self.layout.n_robots

    @property
    def n_pairs(self) -> int:
        return len(self.layout.pairs)

    def qpos_from_poses(self, poses: np.ndarray) -> np.ndarray:
        """qpos [..., nq] for poses [..., N, 5] (bodies resting on the plate)."""
        poses = np.asarray(poses, dtype=float)
        lead = poses.shape[:-2]
        q = np.broadcast_to(self.model.qpos0, lead + (self.model.nq,)).copy()
        lay = self.layout
        hz = self.params.robot.body_height / 2
        for i in range(self.n_robots):
            a = lay.free_qpos[i]
            h = poses[..., i, 2]
            q[..., a] = poses[..., i, 0]
            q[..., a + 1] = poses[..., i, 1]
            q[..., a + 2] = hz
            q[..., a + 3] = np.cos(h / 2)
            q[..., a + 4] = 0.0
            q[..., a + 5] = 0.0
            q[..., a + 6] = np.sin(h / 2)
            q[..., lay.arm_qpos[i, 0]] = poses[..., i, 3]
            q[..., lay.arm_qpos[i, 1]] = poses[..., i, 4]  # free-play hinges keep qpos0: centred
        return q

    def initial_act(self, lanes: "Lanes") -> np.ndarray:
        """Actuator activations [B, na] at t = 0: a lagging servo's filter
        starts at the command, so the arms do not lurch at the start."""
        if self.model.na == 0:
            return np.zeros((lanes.size, 0))
        if self.model.na != self.model.nu:
            raise ValueError("scene has activations on only some actuators; engines expect all or none")
        # on the step grid, as the engines advance them: a robot's own period rounded or
        # not changes the float32 gait at t = 0 by 1e-7, which an arm rattling in its
        # backlash amplifies into a different run
        return lane_controls(self, on_step_grid(lanes, self.model.opt.timestep), np.zeros(1))[:, 0]

    def poses_from_qpos(self, qpos: np.ndarray) -> np.ndarray:
        """Planar poses [..., N, 5] (x, y, heading, alpha1, alpha2) from qpos."""
        qpos = np.asarray(qpos)
        lay = self.layout
        out = []
        for i in range(self.n_robots):
            a = lay.free_qpos[i]
            w, x, y, z = (qpos[..., a + 3 + k] for k in range(4))
            heading = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
            out.append(np.stack([qpos[..., a], qpos[..., a + 1], heading, *lay.arm_angles(qpos, i)], -1))
        return np.stack(out, -2)


@dataclasses.dataclass(frozen=True)
class Lanes:
    """Per-lane inputs of a batch (host numpy arrays, leading axis B).

    Attributes:
      poses: [B, N, 5] initial poses (m, rad); arm angles are usually the
        gait's setpoint at t = 0.
      amplitude: [B] alpha_max in rad, or [B, N]: one per robot.
      chirality: [B] or [B, N]: +1 (ccw) or -1 (cw).
      kind: [B] or [B, N]: 0 square, 1 diagonal.
      phase: [B, N] per-robot phase offsets, fractions of that robot's period.
      period: gait period in s, shared by the batch (it fixes the number of
        steps per period, a static shape, and where period records fall).
      robot_period: [B, N] each robot's own gait period in s, or None (every
        robot at ``period``). Robots with other periods are not at gait
        phase 0 at the period records.
      arm_speed: [B, N, 2] each arm's servo speed as a multiple of the
        model's ``servo_speed``, or None (every arm at it).
      retrigger: [B, 3] (s.d. in periods, seed, key) per lane, or None: every robot's
        gait is started again each cycle with a delay drawn afresh per robot and cycle,
        Normal(0, s.d.) periods from the stream (seed, key, cycle), as the lab's firmware
        re-synchronised its robots on an external trigger every cycle (on top of ``phase``).
        [B, 4] (s.d., seed, key, onset cycle >= 1): a lasting timing offset instead, drawn once per
        robot, Normal(0, s.d.) periods from the stream (seed, key), that sets in at the onset cycle and
        stays (every robot runs in phase before it).
      hold: [B, N] seconds, or None: each robot waits that long at the run's start, holding the
        setpoint its gait has when it starts (rate 0), then runs its gait; it applies in the run's
        first period only (the backends drop it after, :meth:`started`). Robots started at different
        times are lanes whose phases are all <= 0 with ``hold = -phase * T``
        (:meth:`with_start_delays`): each begins at its gait's first corner, as a robot triggered late does.
      start_ref: [B, N, 2] rad, or None: each robot's servo reference starts at these angles (a robot
        at rest: the arms' own angles) instead of at its gait's setpoint, and moves from there to the
        corner its gait is heading for at the arm's servo speed, a rate-limited follower of the
        gait's corners (:func:`follow_corners`), which joins the gait where it meets it. The steady
        gait is that same follower, so a reference started at the gait's setpoint is the gait; a NaN
        arm starts there. Run's first period only (:meth:`started`); not with ``hold``.
    """

    poses: np.ndarray
    amplitude: np.ndarray
    chirality: np.ndarray
    kind: np.ndarray
    phase: np.ndarray
    period: float
    robot_period: np.ndarray | None = None
    arm_speed: np.ndarray | None = None
    retrigger: np.ndarray | None = None
    hold: np.ndarray | None = None
    start_ref: np.ndarray | None = None

    def __post_init__(self):
        b, n = self.poses.shape[:2]
        for name in ("amplitude", "chirality", "kind"):
            if getattr(self, name).shape not in ((b,), (b, n)):
                raise ValueError(f"lanes.{name} must have shape ({b},) or ({b}, {n})")
        if self.phase.shape != self.poses.shape[:2]:
            raise ValueError("lanes.phase must have shape [B, N]")
        if self.robot_period is not None:
            if self.robot_period.shape != (b, n):
                raise ValueError(f"lanes.robot_period must have shape ({b}, {n})")
            if not (np.isfinite(self.robot_period).all() and (self.robot_period > 0).all()):
                raise ValueError("lanes.robot_period must be positive")
        if self.retrigger is not None:
            if self.retrigger.shape not in ((b, 3), (b, 4)) or not (np.isfinite(self.retrigger).all() and
                                                                    (self.retrigger[:, 0] >= 0).all()):
                raise ValueError(f"lanes.retrigger must be [{b}, 3] (s.d. >= 0, seed, key) or [{b}, 4] (and an onset "
                                 "cycle)")
            if self.retrigger.shape[1] == 4 and not (self.retrigger[:, 3] >= 1).all():
                raise ValueError("a lasting offset's onset cycle must be >= 1 (robots start in phase)")
        if self.hold is not None:
            if self.hold.shape != (b, n) or not (np.isfinite(self.hold).all() and (self.hold >= 0).all()):
                raise ValueError(f"lanes.hold must be [{b}, {n}] seconds >= 0")
            if (self.hold >= self.robot_gait()[3]).any():
                raise ValueError("a robot's start delay must be shorter than its gait period")
        if self.start_ref is not None:
            if self.start_ref.shape != (b, n, 2) or np.isinf(self.start_ref).any():
                raise ValueError(f"lanes.start_ref must be [{b}, {n}, 2] angles (NaN: at the gait's setpoint)")
            if self.hold is not None:
                raise ValueError("a robot's reference is held at its first corner (hold) or starts at its "
                                 "arms (start_ref), not both")
        if self.arm_speed is not None:
            if self.arm_speed.shape != (b, n, 2):
                raise ValueError(f"lanes.arm_speed must have shape ({b}, {n}, 2)")
            if not (np.isfinite(self.arm_speed).all() and (self.arm_speed > 0).all()):
                raise ValueError("lanes.arm_speed must be positive")

    @property
    def size(self) -> int:
        return self.poses.shape[0]

    @property
    def per_robot(self) -> bool:
        """Whether robots of one lane may run different gaits."""
        return self.robot_period is not None or self.arm_speed is not None or any(getattr(self, k).ndim == 2
                                                    for k in ("amplitude", "chirality", "kind"))

    def robot_gait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(amplitude, chirality, kind, period), each [B, N]."""
        shape = self.poses.shape[:2]

        def full(x):
            x = np.asarray(x)
            return np.broadcast_to(x[:, None] if x.ndim == 1 else x, shape)
        period = self.robot_period if self.robot_period is not None else np.full(shape, float(self.period))
        return full(self.amplitude), full(self.chirality), full(self.kind), period

    @staticmethod
    def _batch(poses, phase):
        """Poses [B, N, 5] (a single [N, 5] becomes one lane) and phase offsets [B, N]."""
        poses = np.asarray(poses, dtype=float)
        if poses.ndim == 2:
            poses = poses[None]
        shape = poses.shape[:2]
        return poses, np.zeros(shape) if phase is None else np.broadcast_to(np.asarray(phase, float), shape).copy()

    @staticmethod
    def from_gait(poses, spec: gait_mod.GaitSpec, phase=None) -> "Lanes":
        poses, phase = Lanes._batch(poses, phase)
        b = poses.shape[0]
        return Lanes(
            poses=poses,
            amplitude=np.full(b, spec.amplitude),
            chirality=np.full(b, spec.chirality_sign, dtype=np.int32),
            kind=np.full(b, spec.kind_code, dtype=np.int32),
            phase=phase,
            period=spec.period(),
        )

    @staticmethod
    def from_robot_gaits(poses, specs, phase=None) -> "Lanes":
        """Lanes whose robots run their own gaits: ``specs`` [N] GaitSpecs, the
        same in every lane. The batch's period (records, steps per period) is
        the first robot's."""
        poses, phase = Lanes._batch(poses, phase)
        b, n = poses.shape[:2]
        if len(specs) != n:
            raise ValueError(f"{len(specs)} gaits for {n} robots")

        def row(values, dtype=float):
            return np.broadcast_to(np.asarray(values, dtype), (b, n)).copy()
        periods = [s.period() for s in specs]
        return Lanes(
            poses=poses,
            amplitude=row([s.amplitude for s in specs]),
            chirality=row([s.chirality_sign for s in specs], np.int32),
            kind=row([s.kind_code for s in specs], np.int32),
            phase=phase,
            period=periods[0],
            robot_period=None if len(set(periods)) == 1 else row(periods),
        )

    def at_time(self, t: float) -> "Lanes":
        """The lanes ``t`` seconds into a run that started at ``t = 0``.

        Robots at the batch's period are back at their starting phase at
        every period boundary; a robot with its own period (``robot_period``)
        is ``t / T_i`` periods further on, so its phase offset moves by that
        (mod 1). Without ``robot_period`` the lanes are returned unchanged.
        ``t``: one time for every lane, or [B] (lanes that started at different times).
        With ``retrigger``, the cycle's delays (cycle = t / period, rounded) are added.
        """
        if not self.varies:
            return self
        t = np.asarray(t, float)
        t = t[:, None] if t.ndim == 1 else t
        phase = self.phase if self.robot_period is None else self.phase + t / self.robot_period
        if self.retrigger is not None:
            cycle = np.rint(np.broadcast_to(t, (self.size, 1))[:, 0] / self.period).astype(np.int64)
            phase = phase + self.retrigger_delays(cycle)
        return dataclasses.replace(self, phase=np.mod(phase, 1.0))

    def with_start_delays(self) -> "Lanes":
        """These lanes with their robots' phase offsets read as start delays: in each lane the robot
        furthest ahead starts at t = 0 and every other one ``(its lead - its phase)`` periods later,
        holding its gait's first corner until then (``hold``). The phases between robots stay as they
        were; no robot starts in the middle of a move (a phase ahead of t = 0 would put its setpoint
        part of a move away from the arms it starts with, and the servo would catch up at its stall
        torque). Idempotent."""
        period = self.robot_gait()[3]
        shifted = self.phase - self.phase.max(axis=1, keepdims=True)
        hold = -shifted * period
        if (hold >= period).any():
            raise ValueError("robots' phase offsets span a whole period or more: they cannot be start delays")
        return dataclasses.replace(self, phase=shifted, hold=None if not hold.any() else hold)

    def started(self, t) -> "Lanes":
        """The lanes at run time ``t`` (one time, or [B]) as far as their start goes: ``hold`` and
        ``start_ref`` kept for lanes at the run's start (t = 0) and dropped for the others."""
        if self.hold is None and self.start_ref is None:
            return self
        at_start = np.broadcast_to(np.asarray(t, float) == 0.0, (self.size,))
        if at_start.all():
            return self
        out = self
        if self.hold is not None:
            hold = np.where(at_start[:, None], self.hold, 0.0)
            out = dataclasses.replace(out, hold=hold if hold.any() else None)
        if self.start_ref is not None:
            if not at_start.any():
                return dataclasses.replace(out, start_ref=None)
            # lanes past their start follow their gait (NaN: the reference starts at the gait's setpoint)
            out = dataclasses.replace(out, start_ref=np.where(at_start[:, None, None], self.start_ref, np.nan))
        return out

    @property
    def starts_apart(self) -> bool:
        """Whether the run's first period has controls of its own (``hold`` or ``start_ref``)."""
        return self.hold is not None or self.start_ref is not None

    @property
    def timed(self) -> bool:
        """Whether a backend must know each lane's run time: its phases move on (:attr:`varies`) or its
        robots start differently at the run's start (``hold``, ``start_ref``)."""
        return self.varies or self.starts_apart

    def retrigger_delays(self, cycle) -> np.ndarray:
        """[B, N] each robot's delay (periods) in cycle ``cycle`` ([B] or one int) of its lane."""
        cycle = np.broadcast_to(np.asarray(cycle, np.int64), (self.size,))
        n = self.poses.shape[1]
        out = np.zeros((self.size, n))
        for b, row in enumerate(self.retrigger):
            sd, seed, key = row[:3]
            if sd <= 0:
                continue
            if len(row) == 4:  # a lasting offset: one draw per robot, from its onset cycle on
                if cycle[b] >= int(row[3]):
                    out[b] = np.random.default_rng([int(seed), int(key), 0x4C415354]).normal(0.0, sd, n)  # "LAST"
                continue
            rng = np.random.default_rng([int(seed), int(key), int(cycle[b]), 0x54524947])  # "TRIG"
            out[b] = rng.normal(0.0, sd, n)
        return out

    @property
    def varies(self) -> bool:
        """Whether a robot's phase at a period boundary changes from period to period (own clocks,
        per-cycle retriggering): the backends then recompute the controls every period."""
        return self.robot_period is not None or self.retrigger is not None

    def take(self, idx) -> "Lanes":
        return Lanes(self.poses[idx], self.amplitude[idx], self.chirality[idx], self.kind[idx],
                     self.phase[idx], self.period, None if self.robot_period is None else self.robot_period[idx],
                     None if self.arm_speed is None else self.arm_speed[idx],
                     None if self.retrigger is None else self.retrigger[idx],
                     None if self.hold is None else self.hold[idx],
                     None if self.start_ref is None else self.start_ref[idx])

    def arm_ratios(self) -> np.ndarray:
        """[B, N, 2] each arm's speed ratio (1 where the lanes give none)."""
        if self.arm_speed is None:
            return np.ones(self.poses.shape[:2] + (2,))
        return self.arm_speed


def steps_per_period(period: float, timestep: float) -> int:
    """Whole time steps in one gait period (the period is rounded to them)."""
    n = int(round(period / timestep))
    if n < 1:
        raise ValueError(f"gait period {period} s is shorter than a time step {timestep} s")
    return n


def on_step_grid(lanes: "Lanes", timestep: float) -> "Lanes":
    """Lanes whose period is rounded to a whole number of time steps.

    The change is at most dt/2 and comes out of the dwell at the corners, so
    period boundaries stay at gait phase 0 exactly, however many periods run.
    Robots' own periods (``robot_period``) are rounded the same way.
    """
    period = steps_per_period(lanes.period, timestep) * timestep
    rp = lanes.robot_period
    if rp is not None:
        rp = np.maximum(np.round(rp / timestep), 1) * timestep
    return dataclasses.replace(lanes, period=period, robot_period=rp)


_controls = jax.jit(gait_mod.setpoints_and_rates)


def distinct_gaits(lanes: Lanes) -> tuple[np.ndarray, np.ndarray]:
    """(first, row): a lane index for each distinct gait among the lanes (amplitude,
    chirality, kind, period and phase of every robot), and each lane's gait as
    an index into ``first``."""
    hold = lanes.hold if lanes.hold is not None else np.zeros(lanes.phase.shape)
    parts = [*lanes.robot_gait(), lanes.phase, hold, lanes.arm_ratios().reshape(lanes.size, -1)]
    if lanes.start_ref is not None:
        parts.append(np.nan_to_num(lanes.start_ref.reshape(lanes.size, -1), nan=1e9))  # NaN: one key
    key = np.concatenate(parts, axis=1)  # [B, 8N] (10N with start_ref)
    _, first, row = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return first, np.asarray(row).reshape(-1)


def lane_controls(scene: Scene, lanes: Lanes, t: np.ndarray) -> np.ndarray:
    """Controls [B, len(t), nu] for every lane at times ``t`` (host numpy).

    Per robot: setpoints (alpha1, alpha2) then their rates, as the scene's
    actuators expect. Each distinct gait among the lanes (amplitude,
    chirality, kind, period and phase of every robot) is evaluated once and
    shared: a scan's lanes usually have one, so the jitted gait function
    sees the same shapes whatever the batch size and compiles once, not once
    per batch size.
    """
    first, row = distinct_gaits(lanes)
    u = lanes.take(first)
    if u.per_robot:
        amp, chi, kind, period = (x[:, None, :] for x in u.robot_gait())
    else:
        amp, chi, kind = (x[:, None, None] for x in (u.amplitude, u.chirality, u.kind))
        period = u.period
    ratios = u.arm_ratios()[:, None]  # [U, 1, N, 2]
    speed = scene.params.robot.servo_speed
    if u.arm_speed is not None:
        gait_mod.check_fit(amp, period, speed, kind, ratios)
    t = t[None, :, None]
    hold = None if u.hold is None else u.hold[:, None, :]
    # a robot not yet started holds the setpoint it starts with, at rate 0
    sp = np.asarray(_controls(t if hold is None else np.maximum(t, hold), amp, period, speed, chi, kind,
                              u.phase[:, None, :], ratios[..., 0], ratios[..., 1]))  # [U, T, N, 4]
    if hold is not None:
        sp = np.array(sp)
        sp[..., 2:] *= (t >= hold)[..., None]
    if u.start_ref is not None:
        sp = follow_corners(u.start_ref, t, amp, period, speed * ratios, chi, kind, u.phase[:, None, :], sp)
    return sp.reshape(sp.shape[0], sp.shape[1], -1)[row]


def follow_corners(start, t, amplitude, period, speed, chirality, kind, phase, steady) -> np.ndarray:
    """A servo reference that starts at ``start`` and follows the gait's corners at the arms' speed.

    The gait's setpoint is a rate-limited follower of a corner target that changes at each quarter
    (square) or half (diagonal) period of the robot's phase, each move starting at the change: the
    target in force is the setpoint at the end of the current quarter. This is that follower
    started from ``start`` at t = 0 instead of from the gait's own setpoint, segment by segment in
    closed form: within a segment of constant target c that it enters at r_s, it is
    c + sign(r_s - c) max(|r_s - c| - speed (t - t_s), 0). Once it meets the gait it stays with it.

    Args (broadcast as in :func:`lane_controls`): start [U, N, 2] rad (NaN: the gait's setpoint at
      t = 0); t [1, T, 1] s from the run's
      start; amplitude, period, chirality, kind, phase [U, 1, N]; speed [U, 1, N, 2] each arm's rad/s;
      steady [U, T, N, 4] the gait's setpoints and rates at ``t``.

    Returns:
      [U, T, N, 4] setpoints and rates, the follower's where it has not yet met the gait.
    """
    steady = np.array(steady, dtype=float)
    u_n, tt, n = steady.shape[0], steady.shape[1], steady.shape[2]
    tv = np.broadcast_to(np.asarray(t, float), (1, tt, 1))[0, :, 0]  # [T]
    shp = (u_n, 1, n)
    a, per, chi, kd, ph = (np.broadcast_to(np.asarray(x, float), shp)[:, 0] for x in
                           (amplitude, period, chirality, kind, phase))  # [U, N]
    w = np.broadcast_to(np.asarray(speed, float), (u_n, 1, n, 2))[:, 0]  # [U, N, 2]
    q = np.where(kd == gait_mod.DIAGONAL, 2.0, 4.0)  # segments per period
    base = np.mod(ph, 1.0)
    m0 = np.floor(base * q + 1e-12)  # segment the robot starts in
    r_s = np.array(np.broadcast_to(start, (u_n, n, 2)), float)
    at0 = gait_mod.host_setpoints(np.zeros(a.shape), a, per, 1.0, chi, kd, ph, w[..., 0], w[..., 1])
    r_s = np.where(np.isnan(r_s), at0, r_s)  # NaN: from the gait's own setpoint
    # the rate: the servo's speed while the reference still has a step or more to go, else 0 (a catch-up
    # shorter than a step, e.g. from a start that differs from the gait's setpoint by tracking noise, is
    # a small jump of the reference, not a velocity feed-forward of the servo's full speed for a step)
    h = float(tv[1] - tv[0]) if tt > 1 else 0.0
    ref = np.full((u_n, tt, n, 2), np.nan)
    rate = np.zeros((u_n, tt, n, 2))
    t_s = np.zeros((u_n, n))
    for j in range(5):  # a period spans at most 5 segments (4 whole, 2 partial)
        t_e = ((m0 + j + 1) / q - base) * per  # [U, N] end of segment j
        # the target: the gait's setpoint at the segment's end (each move fits in its segment)
        tgt = gait_mod.host_setpoints(t_e - 1e-9 * per, a, per, 1.0, chi, kd, ph, w[..., 0], w[..., 1])
        inside = ((tv[None, :, None] >= t_s[:, None]) & (tv[None, :, None] < t_e[:, None]))[..., None]  # [U, T, N, 1]
        d = r_s - tgt  # [U, N, 2]
        left = np.abs(d)[:, None] - w[:, None] * (tv[None, :, None, None] - t_s[:, None, :, None])
        ref = np.where(inside, tgt[:, None] + np.sign(d)[:, None] * np.maximum(left, 0.0), ref)
        rate = np.where(inside, np.where(left > w[:, None] * h, -np.sign(d)[:, None] * w[:, None], 0.0), rate)
        r_s = tgt + np.sign(d) * np.maximum(np.abs(d) - w * (t_e - t_s)[..., None], 0.0)
        t_s = t_e
    past = tv[None, :, None] >= t_s[:, None]  # after five segments: the gait
    ref = np.where(past[..., None], steady[..., :2], ref)
    rate = np.where(past[..., None], steady[..., 2:], rate)
    # where the follower has met the gait it is the gait (the same numbers, without round-off)
    met = np.abs(ref - steady[..., :2]) <= 1e-5  # float32 gait against float64 follower
    steady[..., :2] = np.where(met, steady[..., :2], ref)
    steady[..., 2:] = np.where(met, steady[..., 2:], rate)
    return steady


@dataclasses.dataclass
class PeriodRecords:
    """Records of ``K`` gait periods for ``B`` lanes.

    Attributes:
      poses: [B, K, N, 5] poses at the end of each period (gait phase 0).
      touched: [B, K, P] bool, robots of pair p touched at least once.
      min_dist: [B, K, P] deepest inter-robot contact distance (m, negative
        is penetration); +inf where they did not touch.
      status: [B] Status bits accumulated over these periods.
      collisions: None, or the collision record (``Record.collisions``):
        ``steps`` [B, K, P, 9, bins] time steps in contact per contact kind
        (:data:`CONTACT_KINDS`) and bin of the gait period; ``impulse``
        [B, K, P, 9, bins, 2] contact impulse (N s, world x, y) on the pair's
        first robot i; ``impulse_r`` [B, K, P, 9, bins] its component along
        r = c_j - c_i at each step (N s): positive pulls robot i toward robot
        j, the paper's attraction criterion (I_N + I_F) . r > 0.
    """

    poses: np.ndarray
    touched: np.ndarray
    min_dist: np.ndarray
    status: np.ndarray
    collisions: dict | None = None


def collision_bin_of(nstep: int, bins: int) -> np.ndarray:
    """[nstep] the collision record's phase bin of every step of a period."""
    return np.minimum((np.arange(nstep) * bins) // nstep, bins - 1)


def blank_collisions(b: int, k: int, p: int, bins: int) -> dict:
    """A collision record of ``b`` lanes and ``k`` periods with nothing in it."""
    n = len(CONTACT_KINDS)
    return {"steps": np.zeros((b, k, p, n, bins), np.int32),
            "impulse": np.zeros((b, k, p, n, bins, 2), np.float32),
            "impulse_r": np.zeros((b, k, p, n, bins), np.float32)}


# How the batch runner (batch.run_lanes) advances a batch whose slots are not all
# occupied: "occupied" runs only the occupied slots (idle ones would cost real
# work: native, dart); "pow2" runs them padded to a power of two (each size
# allocates device buffers and captures a graph once: warp); "fixed" keeps
# every slot running (a finished lane keeps going, so the batch shape, and the
# compiled function, stays the same: mjx).
BATCHING = ("occupied", "pow2", "fixed")


@runtime_checkable
class Backend(Protocol):
    """What every engine backend offers the batch runner, scans and relaxations.

    ``advance`` runs whole gait periods of every lane from ``state`` and
    returns the new state, their :class:`PeriodRecords` and, when the record
    asks for one, a full-rate track (else None). A backend is a context
    manager: leaving the block releases its threads or device buffers.
    """

    name: str
    scene: Scene
    batching: str

    def initial_state(self, lanes: Lanes): ...

    def advance(self, state, lanes: Lanes, n_periods: int, *, t0: float = 0.0, record: Record | None = None): ...

    def close(self) -> None: ...

    def __enter__(self): ...

    def __exit__(self, *exc) -> None: ...


class BackendBase:
    """Shared by the backends: nothing to release by default, and the context manager."""

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def check_start_delays(lanes: Lanes, backend: str) -> None:
    """ValueError (one line) for lanes whose robots start at different times (``Lanes.hold``) or whose servo
    references start at the arms (``Lanes.start_ref``) on a backend that does not run them."""
    if lanes.hold is not None:
        require(backend, "start_delays")
    if lanes.start_ref is not None:
        require(backend, "start_ref")


def check_records(record, backend: str) -> None:
    """ValueError (one line) for a record (``Record``: full-rate tracks, the collision record) the backend
    does not make."""
    if record is not None and record.track_stride:
        require(backend, "full_rate_tracks")
    if record is not None and record.collisions:
        require(backend, "collision_record")


def check_timing(lanes: Lanes, backend: str) -> None:
    """ValueError (one line) for lanes whose robots' phases move on after the start (own clocks, a per-cycle
    re-trigger or lasting offsets) on a backend that holds one period's controls."""
    if lanes.robot_period is not None:
        require(backend, "own_clocks")
    if lanes.retrigger is not None:
        require(backend, "retrigger")


def check_solver(scene: Scene, backend: str, solvers) -> None:
    """ValueError (one line) when the constraint solver ``scene`` resolves to (``SceneParams.constraint_solver``)
    is not among the backend's ``solvers``."""
    solver = scene.params.constraint_solver(scene.n_robots)[0]
    if solver not in solvers:
        raise ValueError(f"the {backend} backend solves constraints with {', '.join(solvers)}, not "
                         f"{solver!r}; use the native backend")
