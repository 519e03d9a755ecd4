"""MuJoCo Warp's box-box contacts against MuJoCo C's on the same states, without a GPU.

    python benchmarks/warp_collider.py --lanes 61,85,339 --periods 2 --out benchmarks/results/warp_collider.json

The states are the pair scene's own: lanes of the paper scan (the default
model, its configurations; by default lanes the Warp scan flagged) stepped on
MuJoCo C from rest, every ``--stride``-th step kept, then each state moved by
a small random rigid offset of the second robot (``--jitter-mm``, ``--jitter-deg``;
0 keeps the states as they were; only states in which the robots touch are
kept, ``--copies`` times each) so that more arm-against-arm configurations
near touching are seen. For every state both engines compute the contacts
from the positions alone (MuJoCo C: ``mj_kinematics`` + ``mj_collision``;
MuJoCo Warp on its CPU device: ``kinematics`` + ``collision``), and the
deepest contact between the two robots is compared. Two Warp colliders are
run: the convex one (GJK/EPA, Warp's default for box pairs) and the analytic
box-box one (Warp with the NATIVECCD disable flag, which is what MuJoCo C uses
for box pairs). Reports, for each, how many states one engine finds deeper
than the other by more than ``--tol-mm`` and the depths there, in a JSON.
"""

from __future__ import annotations

import argparse
import copy
import json
import pathlib
import time

import mujoco
import numpy as np

from smarticle_mjx import __version__
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.presets import params as preset_params
from smarticle_mjx.scan import RunInputs
from smarticle_mjx.specs import ScanConfig


def robot_of_geom(m: mujoco.MjModel) -> np.ndarray:
    """Robot index of each geom (-1 for the plate and anything fixed to the world)."""
    root = m.body_rootid[m.geom_bodyid]
    roots = sorted({int(r) for r in root if r != 0})
    lut = {r: i for i, r in enumerate(roots)}
    return np.array([lut.get(int(r), -1) for r in root])


def states(model_name: str, lanes: list[int], periods: int, stride: int, n: int, seed: int) -> tuple[Scene, np.ndarray]:
    """qpos [S, nq] of the scan's lanes stepped on MuJoCo C from rest (every ``stride``-th step)."""
    params = preset_params(model_name)
    config = ScanConfig(n=n, periods=75, seed=seed, model=model_name)
    inputs = RunInputs.of(config, params, 90.0)
    idx = np.array(lanes, dtype=int)
    if not inputs.valid[idx].all():
        raise SystemExit(f"lanes {idx[~inputs.valid[idx]].tolist()} start overlapping")
    scene = Scene.build(params, 2)
    backend = make_backend("native", scene, nthread=2)
    lanes_ = config.robots(0).lanes(Lanes.from_gait(inputs.poses[idx], inputs.gait), idx)
    nsteps = int(round(periods * float(np.max(lanes_.period)) / params.timestep))
    q = backend.step_qpos(lanes_, nsteps)[:, ::stride]
    backend.close()
    return scene, q.reshape(-1, q.shape[-1])


def flush_states(m_params, n: int, overlap_mm: float, yaw_mrad: float, rng) -> tuple[mujoco.MjModel, np.ndarray]:
    """Two lone arm plates (the preset's arm: length x thickness x height) face to face, as two robots'
    arms meet when their headings line up: the second shifted along the first's length by up to
    one length, overlapping it by 0..``overlap_mm`` through the thickness, turned about the vertical by
    up to ``yaw_mrad`` and raised by up to 1 mm. Returns the model and qpos [n, 14]."""
    r = m_params.robot
    half = (r.arm_length / 2, r.arm_thickness / 2, r.arm_height / 2)
    size = " ".join(f"{h:.9g}" for h in half)
    xml = f"""<mujoco><option timestep="0.00025"/><worldbody>
      <body><freejoint/><geom type="box" size="{size}" mass="0.003"/></body>
      <body><freejoint/><geom type="box" size="{size}" mass="0.003"/></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    # the second plate relative to the first
    x = rng.uniform(-r.arm_length, r.arm_length, n)
    y = r.arm_thickness - rng.uniform(0, overlap_mm, n) * 1e-3
    z = rng.uniform(-1, 1, n) * 1e-3
    yaw = rng.uniform(-yaw_mrad, yaw_mrad, n) * 1e-3
    # the pair as a whole at a random place and heading on the plate, as robots are in a scan
    turn = rng.uniform(-np.pi, np.pi, n)
    c, s_ = np.cos(turn), np.sin(turn)
    shift = rng.uniform(-0.1, 0.1, (n, 2))
    out = np.zeros((n, 14))
    out[:, 0:2] = shift
    out[:, 3], out[:, 6] = np.cos(turn / 2), np.sin(turn / 2)
    out[:, 7] = shift[:, 0] + c * x - s_ * y
    out[:, 8] = shift[:, 1] + s_ * x + c * y
    out[:, 9] = z
    both = turn + yaw
    out[:, 10], out[:, 13] = np.cos(both / 2), np.sin(both / 2)
    return m, out


def jitter(scene: Scene, q: np.ndarray, mm: float, deg: float, rng) -> np.ndarray:
    """Move the second robot's free joint rigidly by a random offset in the plane and a turn about z."""
    if mm == 0 and deg == 0:
        return q
    m = scene.model
    free = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    adr = m.jnt_qposadr[free[1]]
    q = q.copy()
    s = q.shape[0]
    q[:, adr:adr + 2] += rng.uniform(-mm, mm, (s, 2)) * 1e-3
    turn = np.deg2rad(rng.uniform(-deg, deg, s))
    dq = np.stack([np.cos(turn / 2), np.zeros(s), np.zeros(s), np.sin(turn / 2)], -1)
    quat = q[:, adr + 3:adr + 7]
    out = np.empty_like(quat)
    for i in range(s):
        mujoco.mju_mulQuat(out[i], dq[i], quat[i])
    q[:, adr + 3:adr + 7] = out
    return q


def deepest_c(m: mujoco.MjModel, q: np.ndarray, robot: np.ndarray) -> np.ndarray:
    """Deepest inter-robot contact distance (m; +inf where none) per state, MuJoCo C."""
    d = mujoco.MjData(m)
    out = np.full(q.shape[0], np.inf)
    for i, qi in enumerate(q):
        d.qpos[:] = qi
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        for c in d.contact[:d.ncon]:
            if robot[c.geom1] >= 0 and robot[c.geom2] >= 0 and robot[c.geom1] != robot[c.geom2]:
                out[i] = min(out[i], c.dist)
    return out


def deepest_warp(m: mujoco.MjModel, q: np.ndarray, robot: np.ndarray, analytic: bool, chunk: int) -> np.ndarray:
    """The same on MuJoCo Warp's CPU device; ``analytic`` selects its box-box primitive over GJK/EPA."""
    import warp as wp
    import mujoco_warp as mjw
    from smarticle_mjx.engine.mjwarp import buffer_sizes
    wp.config.quiet = True
    m = copy.deepcopy(m)
    if analytic:
        m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_NATIVECCD
    nconmax, njmax = buffer_sizes(m)
    out = np.full(q.shape[0], np.inf)
    with wp.ScopedDevice("cpu"):
        mw = mjw.put_model(m)
        for lo in range(0, q.shape[0], chunk):
            qq = q[lo:lo + chunk]
            d = mjw.make_data(m, nworld=qq.shape[0], nconmax=nconmax, njmax=njmax)
            d.qpos.assign(qq.astype(np.float32))
            mjw.kinematics(mw, d)
            mjw.collision(mw, d)
            n = int(d.nacon.numpy()[0])
            geom = d.contact.geom.numpy()[:n]
            dist = d.contact.dist.numpy()[:n].astype(np.float64)
            world = d.contact.worldid.numpy()[:n]
            r1, r2 = robot[geom[:, 0]], robot[geom[:, 1]]
            inter = (r1 >= 0) & (r2 >= 0) & (r1 != r2)
            np.minimum.at(out, lo + world[inter], dist[inter])
    return out


def compare(c: np.ndarray, w: np.ndarray, tol: float) -> dict:
    both = np.isfinite(c) & np.isfinite(w)
    deeper_w = both & (w < c - tol)
    deeper_c = both & (c < w - tol)
    return {"states_with_contact_in_both": int(both.sum()),
            "contact_only_in_c": int((np.isfinite(c) & ~np.isfinite(w)).sum()),
            "contact_only_in_warp": int((np.isfinite(w) & ~np.isfinite(c)).sum()),
            "warp_deeper_by_more_than_tol": int(deeper_w.sum()),
            "c_deeper_by_more_than_tol": int(deeper_c.sum()),
            "warp_past_2mm": int((w < -0.002).sum()), "c_past_2mm": int((c < -0.002).sum()),
            "deepest_warp_mm_where_warp_deeper": sorted(float(-x * 1e3) for x in w[deeper_w])[-20:],
            "c_mm_there": [float(-x * 1e3) for x in c[deeper_w]][:20],
            "median_abs_diff_mm": float(np.median(np.abs(w[both] - c[both])) * 1e3) if both.any() else None}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", default="lab-lag")
    ap.add_argument("--lanes", default="61,85,339,346,433,1049", help="scan lanes (default: six the Warp scan flagged)")
    ap.add_argument("--n", type=int, default=5000, help="the scan's size (its configurations depend on it)")
    ap.add_argument("--seed", type=int, default=0, help="the scan's seed")
    ap.add_argument("--periods", type=int, default=2)
    ap.add_argument("--stride", type=int, default=4)
    ap.add_argument("--jitter-mm", type=float, default=0.5)
    ap.add_argument("--jitter-deg", type=float, default=1.0)
    ap.add_argument("--copies", type=int, default=1, help="jittered copies of each state")
    ap.add_argument("--tol-mm", type=float, default=0.5)
    ap.add_argument("--chunk", type=int, default=20000)
    ap.add_argument("--flush", type=int, default=0,
                    help="instead of the scan's states: this many pairs of lone arm plates face to face")
    ap.add_argument("--overlap-mm", type=float, default=0.1, help="--flush: largest overlap")
    ap.add_argument("--yaw-mrad", type=float, default=1.0, help="--flush: largest turn between the plates")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    t = time.perf_counter()
    lanes = [int(x) for x in args.lanes.split(",")]
    rng = np.random.default_rng(1)
    if args.flush:
        m, q = flush_states(preset_params(args.model), args.flush, args.overlap_mm, args.yaw_mrad, rng)
        q0, touching = q, np.ones(q.shape[0], bool)
        robot = robot_of_geom(m)
    else:
        scene, q0 = states(args.model, lanes, args.periods, args.stride, args.n, args.seed)
        m = scene.model
        robot = robot_of_geom(m)
        touching = np.isfinite(deepest_c(m, q0, robot))  # only states in which the robots touch are copied
        q = np.concatenate([jitter(scene, q0[touching], args.jitter_mm, args.jitter_deg, rng)
                            for _ in range(args.copies)])
    c = deepest_c(m, q, robot)
    t_c = time.perf_counter()
    rows = {}
    for name, analytic in (("convex (GJK/EPA, Warp's default)", False), ("analytic box-box (NATIVECCD off)", True)):
        w = deepest_warp(m, q, robot, analytic, args.chunk)
        rows[name] = compare(c, w, args.tol_mm * 1e-3)
        print(name, {k: v for k, v in rows[name].items() if not isinstance(v, list)})
        print("   deepest Warp (mm) where Warp is deeper:", [round(x, 2) for x in rows[name]["deepest_warp_mm_where_warp_deeper"]])
    out = dict(model=args.model, lanes=None if args.flush else lanes, flush=args.flush,
               overlap_mm=args.overlap_mm if args.flush else None, yaw_mrad=args.yaw_mrad if args.flush else None, scan_n=args.n, scan_seed=args.seed, periods=args.periods,
               stride=args.stride, jitter_mm=args.jitter_mm, jitter_deg=args.jitter_deg, copies=args.copies,
               stepped_states=int(q0.shape[0]), touching_states=int(touching.sum()), states=int(q.shape[0]), tol_mm=args.tol_mm, package=__version__, mujoco=mujoco.__version__,
               wall_s=time.perf_counter() - t, c_collision_s=t_c - t, results=rows)
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
