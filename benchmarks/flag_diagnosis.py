"""Why a relaxation trial is flagged: each flagged trial replayed step by step to its first flag, and the
event that crossed it named at the contact level.

A trial is flagged (``labels.BAD_STATUS``) when two robots interpenetrate beyond 2 mm or the state goes
non-finite. This replays a flagged trial of a relaxation store with MuJoCo's ``mj_step`` one step at a
time (the native backend's own scene, start, phases, drawn robots and per-period controls; the replay is
checked against the store's status) and stops at the first step past 2 mm or the first non-finite
acceleration. For that event it records:

* the two geoms and the depth;
* the pair's approach speed at the step its contact began (the rate its distance fell, mm/ms = m/s) and
  the depth a linear critically damped contact of the scene's time constant tau would reach from that
  speed, v tau / e (the closed form; MuJoCo's own contact reaches it within 2 % on a free sphere);
* the robots off the plate at the step before (a body with no plate contact), the largest body tilt
  (degrees from upright) so far and, if a body tipped past 2 degrees, when and what touched it then.

Each flag is classed (:func:`kind`): a robot had tipped, the contact appeared deep, a shallow-begun impact
within the linear contact's reach, or a push driven deeper. Writes results/flag_diagnosis.json and prints one row per flagged trial.

    python benchmarks/flag_diagnosis.py out/discovery_screen/lab_s00.h5 [more stores ...]   # ~1 min a trial
    python benchmarks/flag_diagnosis.py --probes    # the tilt probe, ~10 min on 2 cores
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import pathlib
import sys

import numpy as np

from smarticle_mjx.bench import save_json

ROOT = pathlib.Path(__file__).resolve().parent
FLAG_DEPTH = 0.002  # m, the engine's penetration flag
TILT_ONSET_DEG = 2.0  # a body this far from upright has tipped (a robot at rest stays within 0.1 deg)


def _normal_speed(m, d, i: int) -> float:
    """Approach speed (m/s, > 0 closing) of contact ``i``'s two geoms at the contact point, along its normal."""
    import mujoco
    c = d.contact[i]
    v = np.zeros(6)
    rel = 0.0
    for g, sign in ((c.geom1, -1.0), (c.geom2, 1.0)):
        # the velocity of the geom's body at the contact point, in the contact frame (normal first)
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_GEOM, int(g), v, 0)
        lin = v[3:] + np.cross(v[:3], c.pos - d.geom_xpos[g])
        rel += sign * float(lin @ c.frame[:3])
    return -rel  # the normal points from geom1 to geom2: closing when geom2 moves toward geom1


def _stepped(scene, lanes, periods: int):
    """The lane stepped as the native backend runs it (``engine.native.step_lane``)."""
    from smarticle_mjx.engine.native import step_lane
    return step_lane(scene, lanes, periods)


def _tilts_deg(d, bodies) -> np.ndarray:
    """Each body's tilt from upright (degrees): the angle between its z axis and the world's."""
    return np.degrees(np.arccos(np.clip(d.xmat[bodies][:, 8], -1, 1)))


@dataclasses.dataclass
class Trial:
    """One trial of a relaxation store as the native backend ran it: its configuration, scene and lane (on
    the step grid), and each geom's name and robot (-1 for the plate)."""

    config: object
    params: object
    scene: object
    lanes: object
    gname: list
    robot_of: list


def trial_of(st, trial: int) -> Trial:
    """Trial ``trial`` of the relaxation store ``st``: its start, phases, drawn robots and re-triggers."""
    import mujoco
    from smarticle_mjx.engine import Scene
    from smarticle_mjx.engine.core import on_step_grid
    from smarticle_mjx.relax import start_poses, trial_lanes
    from smarticle_mjx.replay import made_with_start_delays
    from smarticle_mjx.scene import params_from_json
    from smarticle_mjx.specs import relax_config_from_json
    config, params = relax_config_from_json(st.config["relax"]), params_from_json(st.config["scene"])
    start, phase = start_poses(dataclasses.replace(config, first_trial=trial, trials=1), params)
    scene = Scene.build(params, len(start[0]))
    lanes = on_step_grid(trial_lanes(config, start, phase, [trial], start_delays=made_with_start_delays(st)),
                         params.timestep)
    m = scene.model
    gname = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, i) for i in range(m.ngeom)]
    robot_of = [int(n[1:].split("_")[0]) if n and n.startswith("r") and "_" in n else -1 for n in gname]
    return Trial(config, params, scene, lanes, gname, robot_of)


def replay_to_flag(path, trial: int) -> dict:
    import mujoco
    from smarticle_mjx.relax import RUN
    from smarticle_mjx.store import Store
    st = Store(path)
    tr = trial_of(st, trial)
    config, params, scene, lanes, gname, robot_of = tr.config, tr.params, tr.scene, tr.lanes, tr.gname, tr.robot_of
    lo = config.first_trial
    rows = st.run(RUN, fields=("periods_run", "status"))
    m = scene.model
    nstep = int(round(lanes.period / m.opt.timestep))
    n_rob = scene.n_robots
    bodies = [m.geom(f"r{i}_body").bodyid[0] for i in range(n_rob)]
    onset: dict = {}  # robot-robot geom pair -> (approach speed, depth, step) when its contact began
    last: dict = {}
    tilt_max, tilt_onset = 0.0, None
    on_plate = np.zeros(n_rob, bool)  # robots with a plate contact before the step (none before the first)
    out = {"store": str(path), "trial": trial, "stored_status": int(rows["status"][trial - lo]),
           "stored_periods_run": int(rows["periods_run"][trial - lo]), "timeconst_s": params.contact_timeconst}
    for p, k, d in _stepped(scene, lanes, int(rows["periods_run"][trial - lo]) + 1):
        tilt = _tilts_deg(d, bodies)
        tilt_max = max(tilt_max, float(tilt.max()))
        if tilt_onset is None and tilt_max > TILT_ONSET_DEG:  # the first robot to tip: what touched it
            r = int(np.argmax(tilt))
            touching = sorted({gname[g] for i in range(d.ncon) for g in (d.contact.geom1[i], d.contact.geom2[i])
                               if robot_of[d.contact.geom1[i]] >= 0 and robot_of[d.contact.geom2[i]] >= 0
                               and r in (robot_of[d.contact.geom1[i]], robot_of[d.contact.geom2[i]])
                               and robot_of[d.contact.geom1[i]] != robot_of[d.contact.geom2[i]]})
            tilt_onset = {"period": p, "step": k, "robot": r, "touching_geoms": touching,
                          "on_plate": bool(on_plate[r])}
        now = {}
        for i in range(d.ncon):
            g1, g2 = int(d.contact.geom1[i]), int(d.contact.geom2[i])
            if robot_of[g1] < 0 or robot_of[g2] < 0 or robot_of[g1] == robot_of[g2]:
                continue
            key = (min(g1, g2), max(g1, g2))
            if key not in now or d.contact.dist[i] < now[key][0]:
                now[key] = (float(d.contact.dist[i]), i)
        for key, (dist, i) in now.items():
            if key not in last:  # the pair's contact began this step: its approach speed along the normal
                onset[key] = (_normal_speed(m, d, i), -dist, p * nstep + k)
        last = now
        bad = not np.isfinite(d.qacc).all() or d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0
        deep = min(now.items(), key=lambda kv: kv[1][0]) if now else None
        if bad or (deep is not None and deep[1][0] < -FLAG_DEPTH):
            ev = {"period": p, "step": k, "t_s": float(d.time), "nonfinite": bool(bad),
                  "airborne_robots": [int(i) for i in np.flatnonzero(~on_plate)], "tilt_max_deg": tilt_max,
                  "tilt_onset": tilt_onset}
            if deep is not None:
                (g1, g2), (dist, _) = deep
                v, first_depth, first_step = onset[(g1, g2)]
                ev.update(geoms=[gname[g1], gname[g2]], depth_mm=-dist * 1e3, onset_speed_m_s=v,
                          onset_depth_mm=first_depth * 1e3, steps_in_contact=p * nstep + k - first_step,
                          closed_form_depth_mm=v * params.contact_timeconst / math.e * 1e3)
            out["event"] = ev
            return out
        on_plate = np.zeros(n_rob, bool)
        for i in range(d.ncon):
            r1, r2 = robot_of[d.contact.geom1[i]], robot_of[d.contact.geom2[i]]
            if r1 < 0 or r2 < 0:
                on_plate[max(r1, r2)] = True
    out["event"] = None
    return out


# The tilt probe (--probes): which choice lets a crowd tip its robots? Each variant runs the relaxation's
# compressed start (4 trials x 3 periods, seed 0) and records each trial's largest body tilt. Written after
# the flag table showed tipped robots only with the lab set; the last four rows switch one numerical or
# contact choice with the combination that tipped (added after it did).
CAD_ARMS = {"robot.arm_height": 0.031, "robot.arm_thickness": 0.0029}
PROBES = {  # name -> (imperfection set, phase_jitter in periods, scene overrides (--set fields), teeth stop time constant s)
    "ideal": ("none", 0.0, {}, None),
    "backlash": ("backlash", 0.0, {}, None),
    "drivetrain": ("drivetrain", 0.0, {}, None),
    "com-offset": ("com-offset", 0.0, {}, None),
    "phase-jitter (lab set: 0.02 period)": ("phase-jitter", 0.0, {}, None),
    "lab": ("lab", 0.0, {}, None),
    "backlash + phase 0.02": ("backlash", 0.02, {}, None),
    "com-offset + phase 0.02": ("com-offset", 0.02, {}, None),
    "backlash + phase 0.02, teeth stops 5 ms": ("backlash", 0.02, {}, 0.005),
    "backlash + phase 0.02, 0.25 ms": ("backlash", 0.02, {"timestep": 2.5e-4}, None),
    "backlash + phase 0.02, robot mu 0": ("backlash", 0.02, {"robot_friction": 0.0}, None),
    "backlash + phase 0.02, robot mu 0.1": ("backlash", 0.02, {"robot_friction": 0.1}, None),
    # The arms as the lab's CAD shows them (wsavoie/ArduinoSmarticle, solidworks/smarticle stls, the arm part
    # "Servo - Solar Arm": 64.2 x 6.75 x 32.5 mm; a plate 2.9 mm thick and 30.8 mm tall over its outer part,
    # a C-shaped mount 32.5 mm tall around the servo at the hinge), taller than the 25-26 mm body, where the
    # presets' plate is 24 mm tall: the tipped robot was pushed at the top edges of the 24 mm plates.
    # Added after the rows above, before it ran.
    "backlash + phase 0.02, CAD arms (31 mm plate)": ("backlash", 0.02, CAD_ARMS, None),
    "lab, CAD arms (31 mm plate)": ("lab", 0.0, CAD_ARMS, None),
    # Arms that meet the plate when their robot leans (added after the CAD rows still tipped, before it ran):
    # the presets' collision filter lets arms pass through the plate, but a lab robot's arm hangs 0.5 mm
    # above it, so a robot leaning about 0.6 deg toward an arm held out sideways puts that arm on the plate,
    # which props it; mu as the body's on the plate (0.37).
    "backlash + phase 0.02, arms meet the plate": ("backlash", 0.02, {"arm_plate_friction": 0.37}, None),
    "lab, arms meet the plate": ("lab", 0.0, {"arm_plate_friction": 0.37}, None),
    # The squeeze that turned a robot over pressed at the servos' stall torque (0.078 N m, the HD-1440A's
    # rating at 4.8 V). The lab ran it on a 1S LiPo (3.7 V), and a DC motor's stall torque scales with its
    # voltage: about 0.06 N m; DART's SERVO bound in the paper's model is 0.03 N m. Added after the rows
    # above still tipped, before it ran.
    "lab, stall torque 0.06 N m (3.7 V)": ("lab", 0.0, {"robot.servo_torque": 0.06}, None),
    "lab, stall torque 0.03 N m (DART's bound)": ("lab", 0.0, {"robot.servo_torque": 0.03}, None),
}


def max_tilts(imperfections: str, phase_jitter: float, overrides: dict, teeth: float | None,
              trials: int = 4, periods: int = 3, model: str = "lab-lag") -> list[float]:
    """Each trial's largest body tilt (degrees from upright) over ``periods`` periods from the relaxation's
    compressed start (seed 0), ``teeth`` replacing the gear-teeth stops' time constant (2 dt) when given."""
    from smarticle_mjx import presets
    from smarticle_mjx.engine import Scene
    from smarticle_mjx.engine.core import SceneLayout, on_step_grid
    from smarticle_mjx.relax import start_poses, trial_lanes
    from smarticle_mjx.scene import compile_model
    from smarticle_mjx.specs import RelaxConfig
    config = RelaxConfig(trials=trials, periods=periods, imperfections=imperfections, phase_jitter=phase_jitter)
    # the probe's rows were measured with MuJoCo's Newton solver, the scenes' only solver then, and with the
    # start of versions up to 0.4.0 (clocks started at t = 0 at their offsets); the default "auto" solver
    # (CG where arms have gear play) and start delays came after them (play_probe.py)
    overrides = {"solver": "Newton", **overrides}
    params = config.robots().scene(presets.apply(presets.params(model), overrides.items()))
    starts, phase = start_poses(config, params)
    xml = Scene.mjcf(params, config.n_robots, False)
    if teeth is not None:
        old = f'solreflimit="{2 * params.timestep:.9g} 1"'
        if old not in xml:
            raise ValueError("no gear-teeth stops in this scene")
        xml = xml.replace(old, f'solreflimit="{teeth:.9g} 1"')
    m = compile_model(xml)
    scene = Scene(params, m, SceneLayout.of(m), xml, False)
    bodies = [m.geom(f"r{i}_body").bodyid[0] for i in range(config.n_robots)]
    out = []
    for t in range(trials):
        lanes = on_step_grid(trial_lanes(config, starts[t], phase[t], [t], start_delays=False), m.opt.timestep)
        tilt = 0.0
        for _, _, d in _stepped(scene, lanes, periods):
            tilt = max(tilt, float(_tilts_deg(d, bodies).max()))
        out.append(tilt)
    return out


def _probe(name: str) -> tuple[str, list[float]]:
    return name, max_tilts(*PROBES[name])


def kind(ev: dict | None) -> str:
    """The flag's class: ``tipped`` when a body was >= 2 deg from upright by then; ``appeared deep`` when
    the contact was >= 1 mm deep at the first step it was seen (the bodies met faster than 2 m/s, beyond any
    servo-driven speed: a jump of the box-box contact's geometry, or a lifted robot coming down); ``impact``
    when it began shallow and went no deeper than 1.25 x the linear contact's reach from its approach
    speed, v tau / e; else ``push`` (driven deeper than its approach explains); ``not reproduced`` when the
    replay passed no flag. Written after the first lab rows had been read; ``appeared deep`` split off
    ``push`` after the whole table had (docs/relax.md says so)."""
    if ev is None:
        return "not reproduced"
    if ev["tilt_max_deg"] >= TILT_ONSET_DEG or "depth_mm" not in ev:
        return "tipped"
    if ev["onset_depth_mm"] >= 1.0:
        return "appeared deep"
    if ev["depth_mm"] <= 1.25 * ev["closed_form_depth_mm"]:
        return "impact"
    return "push"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stores", nargs="*", type=pathlib.Path)
    ap.add_argument("--probes", action="store_true", help="the tilt probe instead (results/flag_tilt_probe.json)")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "flag_diagnosis.json")
    ap.add_argument("--workers", type=int, default=2, help="trials replayed at once (one core each)")
    ap.add_argument("--only", default=None, help="with --probes: semicolon-separated probe names (the others kept)")
    args = ap.parse_args(argv)
    from concurrent.futures import ProcessPoolExecutor
    if args.probes:
        out = ROOT / "results" / "flag_tilt_probe.json"
        names = [n for n in PROBES if not args.only or n in args.only.split(";")]
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            res = dict(pool.map(_probe, names))
        for name, tilts in res.items():
            print(f"{name}: largest tilt per trial " + ", ".join(f"{x:.2f}" for x in tilts) + " deg")
        kept = json.loads(out.read_text())["variants"] if out.exists() and args.only else {}
        kept.update({n: {"imperfections": PROBES[n][0], "phase_jitter": PROBES[n][1], "overrides": PROBES[n][2],
                         "teeth_timeconst_s": PROBES[n][3], "max_tilt_deg": res[n]} for n in names})
        save_json(out, {"trials": 4, "periods": 3, "seed": 0, "model": "lab-lag",
                        "variants": {n: kept[n] for n in PROBES if n in kept}})
        return
    if not args.stores:
        sys.exit("error: name the relaxation stores whose flagged trials to replay (or --probes)")
    from smarticle_mjx.labels import BAD_STATUS
    from smarticle_mjx.store import read_relax
    jobs = []
    for path in args.stores:
        try:
            data = read_relax(path)
        except Exception as e:  # noqa: BLE001 - one line for a bad store
            sys.exit(f"error: {path}: {e}")
        jobs += [(path, int(t)) for t, st in zip(data.trial, data.status) if int(st) & int(BAD_STATUS)]
    with ProcessPoolExecutor(max_workers=args.workers) as pool:  # one trial per core, in store order
        rows = list(pool.map(replay_to_flag, *zip(*jobs))) if jobs else []
    for r in rows:
        r["kind"] = kind(r["event"])
        ev = r["event"] or {}
        print(f"{pathlib.Path(r['store']).stem} trial {r['trial']} [{r['kind']}]: " + (
            "not reproduced" if not ev else
            f"period {ev['period']}, {'non-finite' if ev['nonfinite'] else 'depth'} "
            f"{ev.get('depth_mm', float('nan')):.2f} mm between {'/'.join(ev.get('geoms', ['?']))}, "
            f"after {ev.get('steps_in_contact', -1)} steps in contact from {ev.get('onset_depth_mm', float('nan')):.2f} mm, "
            f"approach {ev.get('onset_speed_m_s', float('nan')):.2f} m/s (v tau/e "
            f"{ev.get('closed_form_depth_mm', float('nan')):.2f} mm), off the plate "
            f"{ev['airborne_robots']}, tilt max {ev['tilt_max_deg']:.1f} deg"
            + (f", robot {ev['tilt_onset']['robot']} tipped first in period {ev['tilt_onset']['period']} touching "
               f"{', '.join(ev['tilt_onset']['touching_geoms']) or 'no robot'}" if ev.get("tilt_onset") else "")),
            flush=True)
    counts: dict = {}
    for r in rows:
        c = counts.setdefault(pathlib.Path(r["store"]).stem, {})
        c[r["kind"]] = c.get(r["kind"], 0) + 1
    for store, c in counts.items():
        print(f"{store}: " + ", ".join(f"{k} {n}" for k, n in sorted(c.items())))
    save_json(args.out, {"flag_depth_m": FLAG_DEPTH, "tilt_onset_deg": TILT_ONSET_DEG, "counts": counts,
                         "trials": rows})
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
