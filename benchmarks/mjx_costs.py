"""Where MJX's time goes on this CPU: the pair scene with one cost removed at
a time, same batch, same steps, ratios against the full model in one run
(the full model uses smarticle_mjx's capsule-box collider, as the engine does;
one row puts MJX's own back).

    python benchmarks/mjx_costs.py --batch 128 --steps 100
"""

from __future__ import annotations

import argparse
import json
import pathlib
import time

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from smarticle_mjx import scene as S
from smarticle_mjx.engine import mjx_collision
from smarticle_mjx.engine.mjx import strip_sensors

VARIANTS = {
    "full model": lambda x: x,
    "pyramidal cone": lambda x: x.replace('cone="elliptic"', 'cone="pyramidal"'),
    "no body-body collision": lambda x: x.replace("</contact>", '<exclude body1="r0" body2="r1"/></contact>'),
    "solver 1 iteration": lambda x: x.replace('iterations="20" ls_iterations="50"', 'iterations="1" ls_iterations="1"'),
    # the same full model with MJX's own capsule-box routine (see engine/mjx_collision.py)
    "MJX's capsule-box": lambda x: x,
    # (disabling contacts altogether crashes MJX 3.17's solver on an empty
    # constraint set, so the contact cost is bounded by the rows above)
}


def rate(xml, batch, steps):
    m = mujoco.MjModel.from_xml_string(xml)
    mx = mjx.put_model(m)
    d0 = mjx.make_data(m).replace(qpos=jnp.asarray(m.key_qpos[0]), ctrl=jnp.asarray(m.key_ctrl[0]))
    d = jax.tree_util.tree_map(lambda x: jnp.broadcast_to(x, (batch,) + x.shape), d0)

    def roll(d):
        return jax.lax.scan(lambda d, _: (mjx.step(mx, d), None), d, None, length=steps)[0]

    f = jax.jit(jax.vmap(roll))
    t = time.perf_counter()
    jax.block_until_ready(f(d))
    compile_s = time.perf_counter() - t
    t = time.perf_counter()
    jax.block_until_ready(f(d))
    return batch * steps / (time.perf_counter() - t), compile_s


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=128)
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "mjx_costs.json"))
    args = ap.parse_args()
    base = strip_sensors(S.build_mjcf(S.SceneParams(), S.standard_poses("pair")))
    rows = {}
    print(f"MJX on {jax.devices()[0].device_kind}, pair scene, batch {args.batch}, {args.steps} steps")
    for name, edit in VARIANTS.items():
        (mjx_collision.uninstall if name == "MJX's capsule-box" else mjx_collision.install)()
        r, c = rate(edit(base), args.batch, args.steps)
        rows[name] = {"steps_per_s": r, "compile_s": c}
        print(f"{name:>24}: {r:9,.0f} steps/s  (x{r / rows['full model']['steps_per_s']:.2f})  compile {c:.0f} s",
              flush=True)
    pathlib.Path(args.out).write_text(json.dumps(dict(batch=args.batch, steps=args.steps, rows=rows), indent=2))


if __name__ == "__main__":
    main()
