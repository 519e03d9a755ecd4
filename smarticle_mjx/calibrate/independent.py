"""An independent smarticle simulator that writes tracked data in the interchange format.

Calibration tests must not fit data that the calibrated model made. This
module is a second model, written from the interchange format's documented
conventions (docs/calibration.md) and nothing else: it imports nothing from
``smarticle_mjx``. It differs from the library's default model on purpose:

* arms are flat boxes 5.3 cm long, 1.8 cm high, 4 mm thick, hinged 3 mm
  inside the body's ends (the library: 5.0 cm, 2.4 cm, 3.2 mm, 6 mm);
* arms weigh 4.2 g each and the body 22 g (the library: 3.19 g and 28.4 g);
* the servo is a hobby servo's loop: the controller is given the gait's
  *corner* at each quarter and slews its reference there at 7.6 rad/s,
  then a stiff PD position loop (kp 0.8 N m/rad, kv 0.004 N m s/rad,
  0.065 N m stall torque) tracks it; the library instead ramps the setpoint
  at its servo speed and adds velocity feed-forward;
* time step 0.2 ms; contacts with a 4 ms time constant (the library: 5 ms)
  and MuJoCo's default impedance; plate μ 0.40 (the sidecar says 0.37).

Effects are switched on by keyword (``lag_s``, ``dead_s``, ``tilt_deg``,
``friction``, ``phase_offset``, ``arm2_bias_deg``, and ``friction_y_ratio``,
``arm_plate_mu``, ``heading_friction``) and reported in the returned truth,
never in the sidecar. The robot itself can be rebuilt: a :class:`Build`
(body and arm boxes, masses, the servo's law: slewed or stepped reference,
with or without velocity feed-forward, its gains, torque and gearbox
inertia, contact softness, the plate's true μ, the time step) replaces the
defaults above; :func:`draw_build` draws one at random for the calibration
stress suite (benchmarks/calibration_stress.py). Conventions (shared with the
library only through the docs): body frame +x from arm 1's hinge to arm 2's;
alpha1 (hinge at -x) and alpha2 (hinge at +x) are 0 along the body axis and
positive toward +y; the square gait visits (+a,+a) -> (-a,+a) -> (-a,-a) ->
(+a,-a) counter-clockwise, one arm moving per quarter period, starting at
t = 0 from the first corner; clockwise swaps the arms' roles.
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib

import mujoco
import numpy as np

BODY = dict(length=0.052, thickness=0.023, height=0.024, mass=0.022)
ARM = dict(length=0.053, thickness=0.004, height=0.018, mass=0.0042, inset=0.003, clearance=0.001)
SERVO = dict(slew=7.6, kp=0.8, kv=0.004, torque=0.065, armature=3e-5)
TIMESTEP = 2e-4
FRICTION = 0.40
CONTACT_TIMECONST = 0.004


@dataclasses.dataclass(frozen=True)
class Build:
    """How the independent robot is built (SI units). The defaults are the module's constants.

    ``servo_slew`` None: the reference jumps to each corner and the PD loop
    (saturated at ``servo_torque``) sets the arm's speed; ``servo_ff``: the
    loop adds ``servo_kv`` times the reference's velocity (feed-forward).
    ``servo_noload`` (rad/s): a DC motor's torque falls linearly to 0 at its
    no-load speed; None: the torque limit is flat.
    ``friction``: the plate's true μ (sidecars say 0.37).
    """

    body_length: float = BODY["length"]
    body_thickness: float = BODY["thickness"]
    body_height: float = BODY["height"]
    body_mass: float = BODY["mass"]
    arm_length: float = ARM["length"]
    arm_thickness: float = ARM["thickness"]
    arm_height: float = ARM["height"]
    arm_mass: float = ARM["mass"]
    arm_inset: float = ARM["inset"]
    arm_clearance: float = ARM["clearance"]
    servo_slew: float | None = SERVO["slew"]
    servo_ff: bool = False
    servo_kp: float = SERVO["kp"]
    servo_kv: float = SERVO["kv"]
    servo_torque: float = SERVO["torque"]
    servo_armature: float = SERVO["armature"]
    servo_noload: float | None = None  # rad/s: the motor's back-EMF leaves no torque at this speed
    contact_timeconst: float = CONTACT_TIMECONST
    friction: float = FRICTION
    timestep: float = TIMESTEP

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


DEFAULT = Build()


def draw_build(rng) -> Build:
    """A robot built at random within what hobby-servo smarticles span (the ranges are the generator's,
    fixed before any calibration was tuned on them): boxes and masses, the servo's law and gains,
    contact softness, and a plate whose true μ is 0.8-1.25x the sidecar's 0.37."""
    u = rng.uniform
    law = ("slew", "slew_ff", "step")[int(rng.integers(3))]
    arm_length, arm_mass = u(0.045, 0.056), u(0.003, 0.0055)
    kp, armature = float(np.exp(u(np.log(0.4), np.log(1.2)))), float(np.exp(u(np.log(1e-5), np.log(6e-5))))
    if law == "step":  # a stepped reference: damping 0.8-1.2 of critical, speed limited by the motor
        kv = u(0.8, 1.2) * 2.0 * math.sqrt(kp * (armature + arm_mass * arm_length ** 2 / 3.0))
    else:
        kv = u(0.002, 0.006)
    return Build(
        body_length=u(0.048, 0.056), body_thickness=u(0.020, 0.026), body_height=u(0.020, 0.026),
        body_mass=u(0.018, 0.030), arm_length=arm_length, arm_thickness=u(0.003, 0.005),
        arm_height=u(0.015, 0.022), arm_mass=arm_mass, arm_inset=u(0.002, 0.007),
        arm_clearance=u(0.0005, 0.0015),
        servo_slew=None if law == "step" else u(6.5, 9.5), servo_ff=law == "slew_ff",
        servo_kp=kp, servo_kv=kv, servo_torque=u(0.05, 0.09), servo_armature=armature,
        servo_noload=u(6.5, 9.5) if law == "step" else None,
        contact_timeconst=u(0.003, 0.006), friction=0.37 * float(np.exp(u(np.log(0.8), np.log(1.25)))))


def _mjcf(n: int, tilt_deg=(0.0, 0.0), friction=None, b: Build = DEFAULT, aniso: tuple | None = None,
          arm_plate_mu: float = 0.0, body_priority: bool = False) -> str:
    """The scene's MJCF. ``aniso``: (mu along the contact frame's first tangent, along its second) for
    explicit body-plate pairs; ``arm_plate_mu`` > 0: arms resting on the plate with this mu;
    ``body_priority``: each body's own friction decides its plate contact (set per step)."""
    friction = b.friction if friction is None else friction
    tx, ty = (math.radians(a) for a in tilt_deg)
    g = 9.81
    grav = (g * math.sin(ty), -g * math.sin(tx) * math.cos(ty), -g * math.cos(tx) * math.cos(ty))
    hx = b.body_length / 2 - b.arm_inset
    clearance = 0.0 if arm_plate_mu > 0 else b.arm_clearance
    bodies, pairs = [], []
    for i in range(n):
        half_arm = b.arm_length / 2
        az = clearance + b.arm_height / 2 - b.body_height / 2
        arm = (f'size="{half_arm} {b.arm_thickness / 2} {b.arm_height / 2}" mass="{b.arm_mass}" '
               f'friction="0.3 0.005 0.0001"')
        if arm_plate_mu > 0:
            arm = arm.replace('friction="0.3 ', f'friction="{arm_plate_mu} ') + ' priority="2"'
        bprio = ' priority="2"' if body_priority else ""
        bodies.append(f"""
    <body name="r{i}" pos="{0.3 * i} 0 {b.body_height / 2}">
      <freejoint/>
      <geom name="r{i}_body" type="box" size="{b.body_length / 2} {b.body_thickness / 2} {b.body_height / 2}"
            mass="{b.body_mass}" friction="{friction} 0.005 0.0001"{bprio}/>
      <body pos="{-hx} 0 {az}">
        <joint name="r{i}_a1" type="hinge" axis="0 0 -1" armature="{b.servo_armature}" range="-100 100"/>
        <geom type="box" pos="{-half_arm} 0 0" {arm}/>
      </body>
      <body pos="{hx} 0 {az}">
        <joint name="r{i}_a2" type="hinge" axis="0 0 1" armature="{b.servo_armature}" range="-100 100"/>
        <geom type="box" pos="{half_arm} 0 0" {arm}/>
      </body>
    </body>""")
        if aniso is not None:
            pairs.append(f'\n    <exclude body1="world" body2="r{i}"/>'
                         f'\n    <pair geom1="plate" geom2="r{i}_body" condim="3" solref="{b.contact_timeconst} 1" '
                         f'friction="{aniso[0]} {aniso[1]} 0.005 0.0001 0.0001"/>')
    acts = "".join(f'\n    <motor joint="r{i}_a{k}" ctrlrange="-{b.servo_torque} {b.servo_torque}"/>'
                   for i in range(n) for k in (1, 2))
    contact = f"\n  <contact>{''.join(pairs)}\n  </contact>" if pairs else ""
    return f"""<mujoco model="independent smarticles">
  <compiler angle="degree"/>
  <option timestep="{b.timestep}" gravity="{grav[0]} {grav[1]} {grav[2]}" integrator="implicitfast" cone="elliptic"/>
  <default><geom solref="{b.contact_timeconst} 1"/></default>
  <worldbody>
    <geom name="plate" type="plane" size="1 1 0.01" friction="{friction} 0.005 0.0001" priority="1"/>{''.join(bodies)}
  </worldbody>{contact}
  <actuator>{acts}
  </actuator>
</mujoco>"""


def _first_tangent_along_x(n: int, b: Build) -> bool:
    """Whether MuJoCo's plane-box contact frame has its first tangent along the plate's x axis (read off
    a resting robot's contact, not assumed)."""
    m = mujoco.MjModel.from_xml_string(_mjcf(n, b=b))
    d = mujoco.MjData(m)
    d.qpos[3:7] = [1, 0, 0, 0]
    mujoco.mj_forward(m, d)
    for k in range(d.ncon):
        f = d.contact[k].frame
        return abs(f[3]) > abs(f[4])
    raise RuntimeError("no body-plate contact to read the frame from")


def corner(t, amplitude, period, chirality="ccw", phase=0.0):
    """The corner the servo is sent to at time t: [2] (alpha1, alpha2), rad.

    At the start of quarter q the moving arm is sent to its next value, so
    the corner in force during quarter q is the corner the gait reaches at
    the end of it.
    """
    a = amplitude
    corners = [(-a, a), (-a, -a), (a, -a), (a, a)]  # end of quarters 0..3, counter-clockwise
    q = int(math.floor(((t / period + phase) % 1.0) * 4.0)) % 4
    c = corners[q]
    return np.array(c if chirality == "ccw" else c[::-1], float)


def simulate(n, poses, amplitude_deg, period, duration, frame_times, *, chirality="ccw", lag_s=0.0, dead_s=0.0,
             tilt_deg=(0.0, 0.0), friction=None, phase_offset=0.0, build: Build = DEFAULT,
             friction_y_ratio=1.0, arm_plate_mu=0.0, heading_friction=0.0):
    """Simulate n robots; return [F, n, 5] (x, y, heading, alpha1, alpha2) at ``frame_times``.

    Args:
      poses: [n, 3] initial (x, y, heading); arms start at the first corner.
      amplitude_deg, period, chirality: one for all robots, or a list with
        one per robot.
      lag_s, dead_s: the servo reference passes through a first-order lag of
        this time constant and a pure delay (dead time).
      phase_offset: robot i runs i * phase_offset periods ahead.
      tilt_deg: (tx, ty): gravity turned toward -y by tx and toward +x by ty.
      friction: the plate's μ (default: the build's).
      build: how the robot is built (:class:`Build`).
      friction_y_ratio: μ along the plate's y / μ along its x (explicit
        body-plate contact pairs; the contact frame's axes are read, not assumed).
      arm_plate_mu: > 0: arms rest on the plate and slide on it with this μ.
      heading_friction: e: a plate whose μ under a robot depends on the
        robot's heading h, μ (1 + e cos 2h) (outside the library's effects).
    """
    b = build
    mu = b.friction if friction is None else friction
    aniso = None
    if friction_y_ratio != 1.0:
        mx, my = mu, mu * friction_y_ratio
        aniso = (mx, my) if _first_tangent_along_x(n, b) else (my, mx)
    m = mujoco.MjModel.from_xml_string(_mjcf(n, tilt_deg, mu, b, aniso, arm_plate_mu, heading_friction != 0.0))
    d = mujoco.MjData(m)
    def each(v):
        return list(v) if isinstance(v, (list, tuple, np.ndarray)) else [v] * n
    amps, periods, chis = [math.radians(x) for x in each(amplitude_deg)], each(period), each(chirality)
    if not len(amps) == len(periods) == len(chis) == n:
        raise ValueError(f"amplitude, period and chirality need one value or {n}")
    dt = b.timestep
    for i in range(n):
        adr = m.jnt_qposadr[m.joint(f"r{i}_a1").id] - 7
        x, y, h = poses[i]
        d.qpos[adr:adr + 7] = [x, y, b.body_height / 2, math.cos(h / 2), 0, 0, math.sin(h / 2)]
        d.qpos[adr + 7:adr + 9] = amps[i]  # first corner (+a, +a)
    mujoco.mj_forward(m, d)
    ref = np.array([[a, a] for a in amps])  # slewing reference
    lagged = ref.copy()           # after the first-order lag
    delay_steps = int(round(dead_s / dt))
    history = [ref.copy()] * (delay_steps + 1)
    qadr = np.array([[m.jnt_qposadr[m.joint(f"r{i}_a{k}").id] for k in (1, 2)] for i in range(n)])
    vadr = np.array([[m.jnt_dofadr[m.joint(f"r{i}_a{k}").id] for k in (1, 2)] for i in range(n)])
    body_geoms = [m.geom(f"r{i}_body").id for i in range(n)]
    frames = np.asarray(frame_times)
    out = np.full((len(frames), n, 5), np.nan)
    k = 0
    # every frame gets a state, also one that jitter put just past the duration
    steps = int(math.ceil(max(duration, float(frames.max(initial=0.0))) / dt)) + 2
    for s in range(steps):
        t = s * dt
        while k < len(frames) and frames[k] <= t + 0.5 * dt:
            for i in range(n):
                adr = qadr[i, 0] - 7
                qw, qz = d.qpos[adr + 3], d.qpos[adr + 6]
                out[k, i] = [d.qpos[adr], d.qpos[adr + 1], 2 * math.atan2(qz, qw), d.qpos[qadr[i, 0]],
                             d.qpos[qadr[i, 1]]]
            k += 1
        if k >= len(frames):
            break
        for i in range(n):
            target = corner(t, amps[i], periods[i], chis[i], phase=i * phase_offset)
            if b.servo_slew is None:
                ref[i] = target
            else:
                ref[i] += np.clip(target - ref[i], -b.servo_slew * dt, b.servo_slew * dt)
        history.append(ref.copy())
        delayed = history.pop(0)
        before = lagged.copy()
        lagged += (delayed - lagged) * (1.0 - math.exp(-dt / lag_s)) if lag_s > 0 else (delayed - lagged)
        q, v = d.qpos[qadr], d.qvel[vadr]
        u = b.servo_kp * (lagged - q) - b.servo_kv * v
        if b.servo_ff:  # velocity feed-forward of the (slewed, delayed, lagged) reference
            u = u + b.servo_kv * (lagged - before) / dt
        if heading_friction:
            for i, gid in enumerate(body_geoms):
                adr = qadr[i, 0] - 7
                h = 2 * math.atan2(d.qpos[adr + 6], d.qpos[adr + 3])
                m.geom_friction[gid, 0] = mu * (1.0 + heading_friction * math.cos(2 * h))
        if b.servo_noload is None:
            d.ctrl[:] = np.clip(u, -b.servo_torque, b.servo_torque).ravel()
        else:  # back-EMF: the torque available in the direction of motion falls to 0 at the no-load speed
            lo = -b.servo_torque * np.clip(1.0 + v / b.servo_noload, 0.0, 2.0)
            hi = b.servo_torque * np.clip(1.0 - v / b.servo_noload, 0.0, 2.0)
            d.ctrl[:] = np.clip(u, lo, hi).ravel()
        mujoco.mj_step(m, d)
    for i in range(n):
        out[:, i, 2] = np.unwrap(out[:, i, 2])
    return out


def write_case(out_dir, *, robots=1, amplitude_deg=30.0, trials=6, periods=8, seed=0, frame_rate=30.0,
               noise_xy_mm=0.02, noise_theta_deg=0.02, noise_arm_deg=0.3, drop=0.03, jitter_s=0.002,
               arm2_bias_deg=0.0, name="independent", gaits=None, arms_tracked=True, **effects) -> dict:
    """Write ``name.csv`` + ``name.json`` (interchange format) into ``out_dir``.

    The sidecar states what a user would know: robots, the commanded gait,
    the plate's nominal μ 0.37 and the frame rate, never the effects.
    ``arms_tracked`` False: the arm columns are left empty (a body-only
    tracker). ``build`` (a :class:`Build`, among ``effects``) rebuilds the robot.
    Returns the truth (effects and noise) for the test to check against.
    """
    rng = np.random.default_rng(seed)
    if gaits is None:
        gaits = [(amplitude_deg, effects.get("chirality", "ccw"))] * robots
    elif len(gaits) != robots:
        raise ValueError(f"{len(gaits)} gaits for {robots} robots")
    amps = [float(g[0]) for g in gaits]
    chis = [g[1] for g in gaits]
    gait_periods = [1.6 * a / 90.0 for a in amps]
    effects = {k: v for k, v in effects.items() if k != "chirality"}
    out = pathlib.Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    lines = ["trial,t,robot,x,y,theta,alpha1,alpha2"]
    for trial in range(trials):
        duration = periods * gait_periods[0]  # whole periods of robot 0
        t = np.arange(0.0, duration, 1.0 / frame_rate)
        t[1:] += rng.uniform(-jitter_s, jitter_s, len(t) - 1)
        t = np.sort(t)
        poses = np.array([[0.3 * i + rng.uniform(-0.01, 0.01), rng.uniform(-0.01, 0.01), rng.uniform(-math.pi, math.pi)]
                          for i in range(robots)])
        tr = simulate(robots, poses, amps, gait_periods, duration, t, chirality=chis, **effects)
        for f, tf in enumerate(t):
            for i in range(robots):
                if f > 0 and rng.uniform() < drop:
                    continue
                x, y, h, a1, a2 = tr[f, i]
                x += rng.normal(0, noise_xy_mm * 1e-3)
                y += rng.normal(0, noise_xy_mm * 1e-3)
                h += rng.normal(0, math.radians(noise_theta_deg))
                a1 += rng.normal(0, math.radians(noise_arm_deg))
                a2 += rng.normal(0, math.radians(noise_arm_deg)) + math.radians(arm2_bias_deg)
                arms = f"{a1:.6f},{a2:.6f}" if arms_tracked else ","
                lines.append(f"{trial},{tf:.6f},{i},{x:.7f},{y:.7f},{h:.7f},{arms}")
    (out / f"{name}.csv").write_text("\n".join(lines) + "\n")
    sides = [{"kind": "square", "amplitude_deg": a, "period_s": T, "chirality": c}
             for a, c, T in zip(amps, chis, gait_periods)]
    side = {"robots": robots, "gait": sides[0] if len(set(map(json.dumps, sides))) == 1 else sides,
            "plate": {"friction": 0.37}, "frame_rate_hz": frame_rate}
    (out / f"{name}.json").write_text(json.dumps(side, indent=1))
    if "build" in effects:
        effects = {**effects, "build": effects["build"].as_dict()}
    return {"effects": effects, "arm2_bias_deg": arm2_bias_deg,
            "noise_xy_mm": noise_xy_mm, "noise_theta_deg": noise_theta_deg}
