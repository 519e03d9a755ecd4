"""One robot of a flagged relaxation trial, step by step, around the moment it tips.

Replays trial T of a relaxation store with ``mj_step`` exactly as ``flag_diagnosis.py`` does (the native
backend's scene, start, phases and controls) for P periods, and records for robot R at every step: its
body's tilt from upright (deg) and height (mm), its plate contacts, the normal force other robots press on
it and the highest of those contact points (mm above the plate), which geoms of other robots touch it,
and the angles of its joints (each arm's servo hinge and, with gear play, its play hinge, in deg). Prints
the steps around the first one past 2 deg of tilt (every 10th step) and writes them to a JSON.

    python benchmarks/tip_trace.py out/discovery_long/backlash-step-0.25ms_s00.h5 7 5 6 \\
        --out benchmarks/results/tip_trace/backlash_t7.json

With ``--switch K --steps N`` it then continues from the state before step K of the last period (the
period index P - 1), N steps, once as stored and once per variant with one thing changed at that moment
(gear stops' time constant, solver iterations, integrator, robot-robot friction, the robot's own gear
play locked, every robot's play locked, each other robot's play locked, half and a quarter of the step
with every time constant kept), and records robot R's largest tilt, height and push in each.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import flag_diagnosis as FD  # noqa: E402  (the replay the flag table uses)

from smarticle_mjx.store import Store  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("trial", type=int)
    ap.add_argument("periods", type=int)
    ap.add_argument("robot", type=int)
    ap.add_argument("--before", type=int, default=400, help="steps kept before the tip")
    ap.add_argument("--after", type=int, default=60, help="steps kept after it")
    ap.add_argument("--switch", type=int, default=None, help="continue from before this step of the last period")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    tr = FD.trial_of(Store(a.store), a.trial)  # the replay the flag table uses: start, phases, robots, re-triggers
    scene, lanes, gname, robot_of = tr.scene, tr.lanes, tr.gname, tr.robot_of
    m = scene.model
    jname = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    hinges = [j for j in range(m.njnt) if jname[j] and jname[j].startswith(f"r{a.robot}_")
              and m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    body = m.geom(f"r{a.robot}_body").bodyid[0]
    f6 = np.zeros(6)
    rows = []
    saved = None
    for p, k, d in FD._stepped(scene, lanes, a.periods):
        if a.switch is not None and p == a.periods - 1 and k == a.switch - 1:
            saved = np.zeros(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))
            mujoco.mj_getState(m, d, saved, mujoco.mjtState.mjSTATE_FULLPHYSICS)
            saved = (saved, d.qacc_warmstart.copy())
        plate, push, high, touching = 0, 0.0, 0.0, set()
        for i in range(d.ncon):
            g1, g2 = int(d.contact.geom1[i]), int(d.contact.geom2[i])
            r1, r2 = robot_of[g1], robot_of[g2]
            if a.robot not in (r1, r2) or r1 == r2:
                continue
            if r1 < 0 or r2 < 0:
                plate += 1
                continue
            mujoco.mj_contactForce(m, d, i, f6)
            push += abs(float(f6[0]))
            high = max(high, float(d.contact.pos[i][2]))
            touching.add(gname[g2] if r1 == a.robot else gname[g1])
        rows.append({"period": p, "step": k,
                     "tilt_deg": float(np.degrees(np.arccos(np.clip(d.xmat[body][8], -1, 1)))),
                     "z_mm": float(d.xpos[body][2] * 1e3), "plate_contacts": plate, "push_N": push,
                     "highest_contact_mm": high * 1e3, "touching": sorted(touching),
                     "joints_deg": {jname[j]: float(np.degrees(d.qpos[m.jnt_qposadr[j]])) for j in hinges}})
    tilt = np.array([r["tilt_deg"] for r in rows])
    tip = int(np.argmax(tilt > FD.TILT_ONSET_DEG)) if (tilt > FD.TILT_ONSET_DEG).any() else None
    lo, hi = (0, len(rows)) if tip is None else (max(0, tip - a.before), min(len(rows), tip + a.after))
    limits = {jname[j]: [float(np.degrees(x)) for x in m.jnt_range[j]] for j in hinges if m.jnt_limited[j]}
    out = {"store": a.store, "trial": a.trial, "robot": a.robot, "timestep_s": float(m.opt.timestep),
           "tip_index": tip, "tip_at": None if tip is None else [rows[tip]["period"], rows[tip]["step"]],
           "joint_limits_deg": limits, "rows": rows[lo:hi]}
    if saved is not None:
        out["switch"] = switch(scene, lanes, a, saved, robot_of, jname, body)
    pathlib.Path(a.out).write_text(json.dumps(out, indent=0) + "\n")
    print("joint limits (deg):", limits)
    print("first step past 2 deg:", out["tip_at"])
    for r in rows[lo:hi:10]:
        print(f"p{r['period']} k{r['step']:5d} tilt {r['tilt_deg']:6.2f} z {r['z_mm']:6.2f} mm plate {r['plate_contacts']}"
              f" push {r['push_N']:6.2f} N at {r['highest_contact_mm']:5.1f} mm "
              f"joints {[round(v, 2) for v in r['joints_deg'].values()]} {r['touching']}")


def switch(scene, lanes, a, saved, robot_of, jname, body) -> dict:
    """From the saved state, ``a.steps`` steps as stored and with one thing changed (see the module doc)."""
    import copy
    from smarticle_mjx.engine.core import lane_controls
    m0 = scene.model
    dt = m0.opt.timestep
    nstep = int(round(lanes.period / dt))
    p = a.periods - 1
    ctrl = lane_controls(scene, lanes.at_time(p * lanes.period), dt * np.arange(nstep))[0]
    play = [j for j in range(m0.njnt) if jname[j] and "_k" in jname[j]]
    own = [j for j in play if jname[j].startswith(f"r{a.robot}_")]

    def set_opt(**kw):
        return lambda m: [setattr(m.opt, k, v) for k, v in kw.items()]

    def stops(tc):
        return lambda m: [m.jnt_solref.__setitem__(j, [tc, 1.0]) for j in play]

    qpos = saved[0][1:1 + m0.nq]  # the full-physics state starts with time, then qpos

    def lock(js):  # each play hinge held where it is at that moment (a range of +-1e-5 rad about it)
        return lambda m: [m.jnt_range.__setitem__(j, qpos[m.jnt_qposadr[j]] + np.array([-1e-5, 1e-5])) for j in js]

    def robot_mu(mu):
        def edit(m):
            for g in range(m.ngeom):
                if robot_of[g] >= 0:
                    m.geom_friction[g][0] = mu
            for q in range(m.npair):  # explicit pairs between robots (the plate's own keep theirs)
                if robot_of[m.pair_geom1[q]] >= 0 and robot_of[m.pair_geom2[q]] >= 0:
                    m.pair_friction[q][:2] = mu
        return edit

    variants = {"as stored": lambda m: None, "gear stops 5 ms (not 2 dt)": stops(0.005),
                "gear stops 1 ms": stops(0.001),
                "solver: 200 iterations, tolerance 1e-12": set_opt(iterations=200, ls_iterations=200, tolerance=1e-12),
                "implicit integrator": set_opt(integrator=mujoco.mjtIntegrator.mjINT_IMPLICIT),
                "robot-robot friction 0": robot_mu(0.0),
                "the robot's own gear play locked": lock(own), "every robot's gear play locked": lock(play),
                "every other robot's gear play locked": lock([j for j in play if j not in own])}
    for r in sorted({int(jname[j][1:].split("_")[0]) for j in play} - {a.robot}):
        variants[f"robot {r}'s gear play locked"] = lock([j for j in play if jname[j].startswith(f"r{r}_")])
    res = {}
    f6 = np.zeros(6)
    # the same model at a finer step: every time constant kept as the default step compiled it (the gear
    # stops' 2 dt = 0.5 ms among them), so only the integration is refined
    refine = {f"step / {r} (time constants kept)": r for r in (2, 4)}
    for name in refine:
        variants[name] = lambda m, r=refine[name]: setattr(m.opt, "timestep", dt / r)
    for name, edit in variants.items():
        r = refine.get(name, 1)
        c = ctrl if r == 1 else lane_controls(scene, lanes.at_time(p * lanes.period), dt / r * np.arange(nstep * r))[0]
        m = copy.deepcopy(m0)
        edit(m)
        d = mujoco.MjData(m)
        mujoco.mj_setState(m, d, saved[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
        d.qacc_warmstart[:] = saved[1]
        tilt = z = push = 0.0
        for k in range(a.switch * r, min((a.switch + a.steps) * r, nstep * r)):
            d.ctrl[:] = c[k]
            mujoco.mj_step(m, d)
            for i in range(d.ncon):
                r1, r2 = robot_of[d.contact.geom1[i]], robot_of[d.contact.geom2[i]]
                if a.robot in (r1, r2) and min(r1, r2) >= 0 and r1 != r2:
                    mujoco.mj_contactForce(m, d, i, f6)
                    push = max(push, abs(float(f6[0])))
            tilt = max(tilt, float(np.degrees(np.arccos(np.clip(d.xmat[body][8], -1, 1)))))
            z = max(z, float(d.xpos[body][2] * 1e3))
        res[name] = {"largest_tilt_deg": tilt, "highest_body_mm": z, "largest_push_N": push}
        print(f"{name:42s} robot {a.robot}: largest tilt {tilt:6.2f} deg, body up to {z:6.2f} mm, "
              f"largest push {push:6.2f} N")
    return {"from": [p, a.switch], "steps": a.steps, "variants": res}


if __name__ == "__main__":
    main()
