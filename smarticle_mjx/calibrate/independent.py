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
``friction``, ``phase_offset``, ``arm2_bias_deg``) and reported in the
returned truth, never in the sidecar. Conventions (shared with the
library only through the docs): body frame +x from arm 1's hinge to arm 2's;
alpha1 (hinge at -x) and alpha2 (hinge at +x) are 0 along the body axis and
positive toward +y; the square gait visits (+a,+a) -> (-a,+a) -> (-a,-a) ->
(+a,-a) counter-clockwise, one arm moving per quarter period, starting at
t = 0 from the first corner; clockwise swaps the arms' roles.
"""

from __future__ import annotations

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


def _mjcf(n: int, tilt_deg=(0.0, 0.0), friction=FRICTION) -> str:
    tx, ty = (math.radians(a) for a in tilt_deg)
    g = 9.81
    grav = (g * math.sin(ty), -g * math.sin(tx) * math.cos(ty), -g * math.cos(tx) * math.cos(ty))
    hx = BODY["length"] / 2 - ARM["inset"]
    bodies = []
    for i in range(n):
        half_arm = ARM["length"] / 2
        az = ARM["clearance"] + ARM["height"] / 2 - BODY["height"] / 2
        arm = (f'size="{half_arm} {ARM["thickness"] / 2} {ARM["height"] / 2}" mass="{ARM["mass"]}" '
               f'friction="0.3 0.005 0.0001"')
        bodies.append(f"""
    <body name="r{i}" pos="{0.3 * i} 0 {BODY['height'] / 2}">
      <freejoint/>
      <geom type="box" size="{BODY['length'] / 2} {BODY['thickness'] / 2} {BODY['height'] / 2}"
            mass="{BODY['mass']}" friction="{friction} 0.005 0.0001"/>
      <body pos="{-hx} 0 {az}">
        <joint name="r{i}_a1" type="hinge" axis="0 0 -1" armature="{SERVO['armature']}" range="-100 100"/>
        <geom type="box" pos="{-half_arm} 0 0" {arm}/>
      </body>
      <body pos="{hx} 0 {az}">
        <joint name="r{i}_a2" type="hinge" axis="0 0 1" armature="{SERVO['armature']}" range="-100 100"/>
        <geom type="box" pos="{half_arm} 0 0" {arm}/>
      </body>
    </body>""")
    acts = "".join(f'\n    <motor joint="r{i}_a{k}" ctrlrange="-{SERVO["torque"]} {SERVO["torque"]}"/>'
                   for i in range(n) for k in (1, 2))
    return f"""<mujoco model="independent smarticles">
  <compiler angle="degree"/>
  <option timestep="{TIMESTEP}" gravity="{grav[0]} {grav[1]} {grav[2]}" integrator="implicitfast" cone="elliptic"/>
  <default><geom solref="0.004 1"/></default>
  <worldbody>
    <geom type="plane" size="1 1 0.01" friction="{friction} 0.005 0.0001" priority="1"/>{''.join(bodies)}
  </worldbody>
  <actuator>{acts}
  </actuator>
</mujoco>"""


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
             tilt_deg=(0.0, 0.0), friction=FRICTION, phase_offset=0.0):
    """Simulate n robots; return [F, n, 5] (x, y, heading, alpha1, alpha2) at ``frame_times``.

    Args:
      poses: [n, 3] initial (x, y, heading); arms start at the first corner.
      amplitude_deg, period, chirality: one for all robots, or a list with
        one per robot.
      lag_s, dead_s: the servo reference passes through a first-order lag of
        this time constant and a pure delay (dead time).
      phase_offset: robot i runs i * phase_offset periods ahead.
    """
    m = mujoco.MjModel.from_xml_string(_mjcf(n, tilt_deg, friction))
    d = mujoco.MjData(m)
    def each(v):
        return list(v) if isinstance(v, (list, tuple, np.ndarray)) else [v] * n
    amps, periods, chis = [math.radians(x) for x in each(amplitude_deg)], each(period), each(chirality)
    if not len(amps) == len(periods) == len(chis) == n:
        raise ValueError(f"amplitude, period and chirality need one value or {n}")
    for i in range(n):
        adr = m.jnt_qposadr[m.joint(f"r{i}_a1").id] - 7
        x, y, h = poses[i]
        d.qpos[adr:adr + 7] = [x, y, BODY["height"] / 2, math.cos(h / 2), 0, 0, math.sin(h / 2)]
        d.qpos[adr + 7:adr + 9] = amps[i]  # first corner (+a, +a)
    mujoco.mj_forward(m, d)
    ref = np.array([[a, a] for a in amps])  # slewing reference
    lagged = ref.copy()           # after the first-order lag
    delay_steps = int(round(dead_s / TIMESTEP))
    history = [ref.copy()] * (delay_steps + 1)
    qadr = np.array([[m.jnt_qposadr[m.joint(f"r{i}_a{k}").id] for k in (1, 2)] for i in range(n)])
    vadr = np.array([[m.jnt_dofadr[m.joint(f"r{i}_a{k}").id] for k in (1, 2)] for i in range(n)])
    frames = np.asarray(frame_times)
    out = np.full((len(frames), n, 5), np.nan)
    k = 0
    steps = int(math.ceil(duration / TIMESTEP)) + 1
    for s in range(steps):
        t = s * TIMESTEP
        while k < len(frames) and frames[k] <= t + 0.5 * TIMESTEP:
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
            ref[i] += np.clip(target - ref[i], -SERVO["slew"] * TIMESTEP, SERVO["slew"] * TIMESTEP)
        history.append(ref.copy())
        delayed = history.pop(0)
        lagged += (delayed - lagged) * (1.0 - math.exp(-TIMESTEP / lag_s)) if lag_s > 0 else (delayed - lagged)
        q, v = d.qpos[qadr], d.qvel[vadr]
        d.ctrl[:] = np.clip(SERVO["kp"] * (lagged - q) - SERVO["kv"] * v, -SERVO["torque"], SERVO["torque"]).ravel()
        mujoco.mj_step(m, d)
    for i in range(n):
        out[:, i, 2] = np.unwrap(out[:, i, 2])
    return out


def write_case(out_dir, *, robots=1, amplitude_deg=30.0, trials=6, periods=8, seed=0, frame_rate=30.0,
               noise_xy_mm=0.02, noise_theta_deg=0.02, noise_arm_deg=0.3, drop=0.03, jitter_s=0.002,
               arm2_bias_deg=0.0, name="independent", gaits=None, **effects) -> dict:
    """Write ``name.csv`` + ``name.json`` (interchange format) into ``out_dir``.

    The sidecar states what a user would know: robots, the commanded gait,
    the plate's nominal μ 0.37 and the frame rate, never the effects.
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
                lines.append(f"{trial},{tf:.6f},{i},{x:.7f},{y:.7f},{h:.7f},{a1:.6f},{a2:.6f}")
    (out / f"{name}.csv").write_text("\n".join(lines) + "\n")
    sides = [{"kind": "square", "amplitude_deg": a, "period_s": T, "chirality": c}
             for a, c, T in zip(amps, chis, gait_periods)]
    side = {"robots": robots, "gait": sides[0] if len(set(map(json.dumps, sides))) == 1 else sides,
            "plate": {"friction": 0.37}, "frame_rate_hz": frame_rate}
    (out / f"{name}.json").write_text(json.dumps(side, indent=1))
    return {"effects": effects, "arm2_bias_deg": arm2_bias_deg,
            "noise_xy_mm": noise_xy_mm, "noise_theta_deg": noise_theta_deg}
