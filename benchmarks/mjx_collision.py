"""Does MJX find the same contacts as MuJoCo for the pair scene's geometry?

The MJX-vs-native label disagreement (docs/engine.md) sits in lanes MJX
flagged for deep penetration. This probe isolates collision detection from
dynamics: random static poses of two robots whose arms cross the other's
body or arms, one `mj_forward` (MuJoCo, float64) and one `mjx.forward`
(float32 and float64) per pose, and per geom-type pair the deepest contact
distance each finds. It repeats the comparison in float64 and with every
length in the scene multiplied by ``--scale`` (distances divided back), to
tell precision and MJX's absolute thresholds (e.g. 1e-6 on squared lengths)
from the algorithm, and finally with smarticle_mjx's own capsule–box
collider (smarticle_mjx/engine/mjx_collision.py). With ``--warp`` it also runs
MuJoCo Warp's colliders (float32, one ``mujoco_warp.forward`` over all poses
as worlds) on the same poses, for the paper's capsule arms and the lab
robot's box arms (``--warp-models``).

    python benchmarks/mjx_collision.py --poses 2000
    python benchmarks/mjx_collision.py --poses 2000 --warp --out benchmarks/results/warp_collision.json

Prints a table and writes results/mjx_collision.json.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import numpy as np

from smarticle_mjx.engine.core import Scene
from smarticle_mjx.scene import SceneParams


def random_poses(scene: Scene, n: int, rng: np.random.Generator) -> np.ndarray:
    """[n, 2, 5] poses: robot 0 at the origin, robot 1 within one arm's reach of it."""
    w = scene.params.robot.body_length
    poses = np.zeros((n, 2, 5))
    poses[:, 0, 2] = rng.uniform(-np.pi, np.pi, n)
    r = rng.uniform(0.3 * w, 2.6 * w, n)
    a = rng.uniform(-np.pi, np.pi, n)
    poses[:, 1, 0], poses[:, 1, 1] = r * np.cos(a), r * np.sin(a)
    poses[:, 1, 2] = rng.uniform(-np.pi, np.pi, n)
    poses[:, :, 3:] = rng.uniform(-np.pi / 2, np.pi / 2, (n, 2, 2))
    return poses


def cross_pairs(model) -> list[tuple[int, int, str]]:
    """Every (geom1, geom2, kind) pair of geoms on different robots (kind: 'box-capsule', ...)."""
    names = {3: "capsule", 6: "box"}
    root = model.body_rootid
    out = []
    for g1 in range(model.ngeom):
        for g2 in range(g1 + 1, model.ngeom):
            b1, b2 = model.geom_bodyid[g1], model.geom_bodyid[g2]
            if 0 in (b1, b2) or root[b1] == root[b2]:
                continue
            kind = "-".join(sorted((names[int(model.geom_type[g1])], names[int(model.geom_type[g2])])))
            out.append((g1, g2, kind))
    return out


def native_deepest(model, qpos: np.ndarray, pairs) -> np.ndarray:
    """[n, len(pairs)] deepest contact distance MuJoCo's collision finds per geom pair (inf: none)."""
    import mujoco
    index = {(g1, g2): j for j, (g1, g2, _) in enumerate(pairs)}
    d = mujoco.MjData(model)
    out = np.full((len(qpos), len(pairs)), np.inf)
    for i, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_forward(model, d)
        for c in d.contact[:d.ncon]:
            j = index.get((min(c.geom1, c.geom2), max(c.geom1, c.geom2)))
            if j is not None:
                out[i, j] = min(out[i, j], c.dist)
    return out


def exact_capsule_box(model, qpos: np.ndarray, pairs, samples: int = 4001) -> np.ndarray:
    """[n, len(pairs)] capsule-box signed distance by brute force: the box's signed distance at
    ``samples`` points along the capsule axis, minus the radius (NaN for other pair kinds).
    Independent of every collider compared here; its error is below axis length / samples."""
    import mujoco
    d = mujoco.MjData(model)
    t = np.linspace(0.0, 1.0, samples)[:, None]
    out = np.full((len(qpos), len(pairs)), np.nan)
    for i, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        for j, (g1, g2, kind) in enumerate(pairs):
            if kind != "box-capsule":
                continue
            cap, box = (g1, g2) if model.geom_type[g1] == 3 else (g2, g1)
            r, h = model.geom_size[cap][:2]
            axis = d.geom_xmat[cap].reshape(3, 3)[:, 2]
            rot = d.geom_xmat[box].reshape(3, 3)
            ends = [rot.T @ (d.geom_xpos[cap] + s * h * axis - d.geom_xpos[box]) for s in (-1, 1)]
            x = ends[0] + t * (ends[1] - ends[0])
            qd = np.abs(x) - model.geom_size[box]
            sd = np.linalg.norm(np.maximum(qd, 0), axis=1) + np.minimum(qd.max(1), 0)
            out[i, j] = sd.min() - r
    return out


def mjx_deepest(model, qpos: np.ndarray, pairs, x64: bool) -> tuple[np.ndarray, str]:
    """Same as :func:`native_deepest` from ``mjx.forward`` (vmapped), in float32 or float64."""
    import jax
    jax.config.update("jax_enable_x64", x64)
    try:
        import jax.numpy as jnp
        from mujoco import mjx
        mx = mjx.put_model(model)
        d0 = mjx.make_data(model)
        f = jax.jit(jax.vmap(lambda q: mjx.forward(mx, d0.replace(qpos=q))._impl.contact.dist))
        dist = np.asarray(f(jnp.asarray(qpos)))
        dtype = str(dist.dtype)
        geom = np.asarray(mjx.forward(mx, d0)._impl.contact.geom)
    finally:
        jax.config.update("jax_enable_x64", False)
    index = {(g1, g2): j for j, (g1, g2, _) in enumerate(pairs)}
    out = np.full((len(qpos), len(pairs)), np.inf)
    for s, (g1, g2) in enumerate(geom):
        j = index.get((min(g1, g2), max(g1, g2)))
        if j is not None:
            out[:, j] = np.minimum(out[:, j], np.where(dist[:, s] < 0, dist[:, s], np.inf))
    return out, dtype


def warp_deepest(model, qpos: np.ndarray, pairs) -> np.ndarray:
    """Same as :func:`native_deepest` from MuJoCo Warp's collision (one world per pose)."""
    import warp as wp
    wp.config.quiet = True
    import mujoco_warp as mjw
    from smarticle_mjx.engine.mjwarp import buffer_sizes
    nconmax, njmax = buffer_sizes(model)
    mw = mjw.put_model(model)
    d = mjw.make_data(model, nworld=len(qpos), nconmax=nconmax, njmax=njmax)
    d.qpos.assign(wp.array(qpos.astype(np.float32)))
    mjw.forward(mw, d)
    wp.synchronize()
    n = int(d.nacon.numpy()[0])
    if n > d.naconmax:
        raise RuntimeError(f"MuJoCo Warp's contact buffer overflowed ({n} > {d.naconmax})")
    dist, geom, world = d.contact.dist.numpy()[:n], d.contact.geom.numpy()[:n], d.contact.worldid.numpy()[:n]
    index = {(g1, g2): j for j, (g1, g2, _) in enumerate(pairs)}
    out = np.full((len(qpos), len(pairs)), np.inf)
    for c in range(n):
        j = index.get((min(geom[c]), max(geom[c])))
        if j is not None and dist[c] < 0:
            out[world[c], j] = min(out[world[c], j], dist[c])
    return out


def warp_census(args, tol, shallow) -> list[dict]:
    """MuJoCo Warp's deepest contacts against MuJoCo C (and the exact capsule-box distance)."""
    from smarticle_mjx import presets
    from smarticle_mjx.engine.mjx import strip_sensors
    import mujoco
    rows = []
    for name in args.warp_models.split(","):
        scene = Scene.build(presets.params(name), 2)
        model = mujoco.MjModel.from_xml_string(strip_sensors(scene.xml))
        pairs = cross_pairs(model)
        kinds = sorted({k for _, _, k in pairs})
        qpos = scene.qpos_from_poses(random_poses(scene, args.poses, np.random.default_rng(args.seed)))
        nat = native_deepest(model, qpos, pairs)
        exact = exact_capsule_box(model, qpos, pairs)
        cb = np.array([p[2] == "box-capsule" for p in pairs])
        ref = np.where(cb, np.where(exact < 0, exact, np.inf), nat)
        keep = np.where(cb, np.abs(exact) <= shallow, ~np.isfinite(nat) | (nat >= -shallow))
        t = time.perf_counter()
        w = warp_deepest(model, qpos, pairs)
        for kind in kinds:
            cols = [j for j, p in enumerate(pairs) if p[2] == kind]
            r = dict(model=name, dtype="float32", collider="mujoco_warp", pair=kind,
                     reference="exact" if kind == "box-capsule" else "mujoco",
                     **compare(ref[:, cols], w[:, cols], tol, keep[:, cols]))
            rows.append(r)
            print(f"{'mujoco_warp':13s} {name:8s} {kind:16s} reference {r['reference_contacts']:5d}  "
                  f"warp {r['mjx_contacts']:5d}  missed {r['missed']:4d}  extra {r['extra']:4d}  "
                  f"max |Δdist| {r['max_abs_err_mm']:.3f} mm  > {args.tol_mm} mm: {r['frac_err_over_tol']:5.1%}  "
                  f"deeper than 2 mm: {r['mjx_deeper_than_limit']}")
        print(f"  ({time.perf_counter() - t:.0f} s)")
    return rows


def scale_model(model, k: float):
    """Multiply every length the collision sees by ``k``: body, inertial-frame and geom offsets
    (geoms that share their body's inertial frame are placed from ``body_ipos``), geom sizes."""
    m = model.__copy__()
    m.body_pos[:] *= k
    m.body_ipos[:] *= k
    m.geom_pos[:] *= k
    m.geom_size[:] *= k
    m.geom_rbound[:] *= k
    m.geom_aabb[:] *= k
    return m


def compare(ref: np.ndarray, mj: np.ndarray, tol: float, keep: np.ndarray) -> dict:
    """Agreement of deepest contact distances (inf: no contact) with a reference over the
    (pose, geom pair) entries ``keep``: near contact, the depths a simulation visits (random
    static poses also pierce a body with an arm, where colliders legitimately differ)."""
    a, b = ref[keep], mj[keep]
    ha, hb = np.isfinite(a), np.isfinite(b)
    both = ha & hb
    err = np.abs(a[both] - b[both])
    return dict(entries=int(keep.sum()), reference_contacts=int(ha.sum()), mjx_contacts=int(hb.sum()),
                missed=int((ha & ~hb).sum()), extra=int((~ha & hb).sum()),
                max_abs_err_mm=float(err.max() * 1e3) if both.any() else 0.0,
                frac_err_over_tol=float((err > tol).mean()) if both.any() else 0.0,
                mjx_deeper_than_limit=int((b < -0.002).sum()))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--poses", type=int, default=2000)
    ap.add_argument("--scale", type=float, default=100.0)
    ap.add_argument("--tol-mm", type=float, default=0.05, help="distance difference still counted as agreement")
    ap.add_argument("--shallow-mm", type=float, default=1.0,
                    help="compare where the reference distance is within this of touching")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "mjx_collision.json"))
    ap.add_argument("--warp", action="store_true", help="census of MuJoCo Warp's colliders instead of MJX's")
    ap.add_argument("--warp-models", default="paper,lab-lag", help="model presets for --warp")
    args = ap.parse_args()
    if args.warp:
        rows = warp_census(args, args.tol_mm * 1e-3, args.shallow_mm * 1e-3)
        pathlib.Path(args.out).write_text(json.dumps(dict(poses=args.poses, tol_mm=args.tol_mm,
                                                          shallow_mm=args.shallow_mm, rows=rows), indent=2))
        return
    scene = Scene.build(SceneParams(), 2)
    from smarticle_mjx.engine.mjx import strip_sensors
    import mujoco
    model = mujoco.MjModel.from_xml_string(strip_sensors(scene.xml))
    pairs = cross_pairs(model)
    kinds = sorted({k for _, _, k in pairs})
    poses = random_poses(scene, args.poses, np.random.default_rng(args.seed))
    qpos = scene.qpos_from_poses(poses)
    free = [int(model.jnt_qposadr[j]) for j in range(model.njnt) if model.jnt_type[j] == 0]
    tol, shallow = args.tol_mm * 1e-3, args.shallow_mm * 1e-3
    rows = []
    exact = ref = keep = None
    from smarticle_mjx.engine import mjx_collision as ours
    variants = [(1.0, False, "mjx"), (1.0, True, "mjx"), (args.scale, False, "mjx"), (1.0, False, "smarticle_mjx")]
    native = {}  # MuJoCo's contacts depend on the scale only
    for k, x64, collider in variants:
        (ours.install if collider == "smarticle_mjx" else ours.uninstall)()
        m = scale_model(model, k) if k != 1.0 else model
        q = qpos.copy()
        for a in free:
            q[:, a:a + 3] *= k
        t = time.perf_counter()
        if k not in native:
            native[k] = native_deepest(m, q, pairs) / k
        nat = native[k]
        if k == 1.0 and exact is None:
            exact = exact_capsule_box(m, q, pairs)
            cb = np.array([p[2] == "box-capsule" for p in pairs])
            # reference: the exact distance for capsule-box (contact where negative), MuJoCo elsewhere
            ref = np.where(cb, np.where(exact < 0, exact, np.inf), nat)
            keep = np.where(cb, np.abs(exact) <= shallow, ~np.isfinite(nat) | (nat >= -shallow))
            cols = np.flatnonzero(cb)
            r = dict(scale=1.0, dtype="float64", collider="mujoco", pair="box-capsule",
                     **compare(ref[:, cols], nat[:, cols], tol, keep[:, cols]))
            rows.append(r)
            print(f"{'mujoco':13s} vs exact  box-capsule  missed {r['missed']}  extra {r['extra']}  "
                  f"max |Δdist| {r['max_abs_err_mm']:.3f} mm  > {args.tol_mm} mm: {r['frac_err_over_tol']:5.1%}")
        mj, dtype = mjx_deepest(m, q, pairs, x64)
        mj /= k
        for name in kinds:
            cols = [j for j, p in enumerate(pairs) if p[2] == name]
            r = dict(scale=k, dtype=dtype, collider=collider, pair=name,
                     **compare(ref[:, cols], mj[:, cols], tol, keep[:, cols]))
            rows.append(r)
            print(f"{collider:13s} scale {k:>5g}  {dtype}  {name:16s} reference {r['reference_contacts']:5d}  "
                  f"MJX {r['mjx_contacts']:5d}  missed {r['missed']:4d}  extra {r['extra']:4d}  "
                  f"max |Δdist| {r['max_abs_err_mm']:.3f} mm  > {args.tol_mm} mm: {r['frac_err_over_tol']:5.1%}  "
                  f"deeper than 2 mm: {r['mjx_deeper_than_limit']}")
        print(f"  ({time.perf_counter() - t:.0f} s)")
    ours.install()
    pathlib.Path(args.out).write_text(json.dumps(dict(poses=args.poses, tol_mm=args.tol_mm,
                                                      shallow_mm=args.shallow_mm, rows=rows), indent=2))


if __name__ == "__main__":
    main()
