"""One robot of a flagged relaxation trial, step by step, around the moment it tips.

Replays trial T of a relaxation store with ``mj_step`` exactly as ``flag_diagnosis.py`` does (the native
backend's scene, start, phases and controls) for P periods, and records for robot R at every step: its
body's tilt from upright (deg) and height (mm), its plate contacts, the normal force other robots press on
it and the highest of those contact points (mm above the plate), which geoms of other robots touch it,
and the angles of its joints (each arm's servo hinge and, with gear play, its play hinge, in deg). Prints
the steps around the first one past 2 deg of tilt (every 10th step) and writes them to a JSON.

    python benchmarks/tip_trace.py out/discovery_long/backlash-step-0.25ms_s00.h5 7 5 6 \\
        --out benchmarks/results/tip_trace_backlash_t7.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import sys

import mujoco
import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import flag_diagnosis as FD  # noqa: E402  (the replay the flag table uses)

from smarticle_mjx.engine import Lanes, Scene  # noqa: E402
from smarticle_mjx.engine.core import on_step_grid  # noqa: E402
from smarticle_mjx.relax import start_poses  # noqa: E402
from smarticle_mjx.scene import params_from_json  # noqa: E402
from smarticle_mjx.specs import relax_config_from_json  # noqa: E402
from smarticle_mjx.store import Store  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("store")
    ap.add_argument("trial", type=int)
    ap.add_argument("periods", type=int)
    ap.add_argument("robot", type=int)
    ap.add_argument("--before", type=int, default=400, help="steps kept before the tip")
    ap.add_argument("--after", type=int, default=60, help="steps kept after it")
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    st = Store(a.store)
    config, params = relax_config_from_json(st.config["relax"]), params_from_json(st.config["scene"])
    start, phase = start_poses(dataclasses.replace(config, first_trial=a.trial, trials=1), params)
    scene = Scene.build(params, len(start[0]))
    lanes = Lanes.from_gait(start[0], config.gait_spec(), phase[0])
    if config.robots() is not None:
        lanes = config.robots().lanes(lanes, [a.trial])
    lanes = on_step_grid(lanes, params.timestep)
    m = scene.model
    gname = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, i) for i in range(m.ngeom)]
    robot_of = [int(n[1:].split("_")[0]) if n and n.startswith("r") and "_" in n else -1 for n in gname]
    jname = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
    hinges = [j for j in range(m.njnt) if jname[j] and jname[j].startswith(f"r{a.robot}_")
              and m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    body = m.geom(f"r{a.robot}_body").bodyid[0]
    f6 = np.zeros(6)
    rows = []
    for p, k, d in FD._stepped(scene, lanes, a.periods):
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
    pathlib.Path(a.out).write_text(json.dumps(out, indent=0) + "\n")
    print("joint limits (deg):", limits)
    print("first step past 2 deg:", out["tip_at"])
    for r in rows[lo:hi:10]:
        print(f"p{r['period']} k{r['step']:5d} tilt {r['tilt_deg']:6.2f} z {r['z_mm']:6.2f} mm plate {r['plate_contacts']}"
              f" push {r['push_N']:6.2f} N at {r['highest_contact_mm']:5.1f} mm "
              f"joints {[round(v, 2) for v in r['joints_deg'].values()]} {r['touching']}")


if __name__ == "__main__":
    main()
