"""A capsule–box collider for MJX that agrees with MuJoCo at the robots' scale.

MJX's own capsule–box routine (``collision_convex.capsule_convex``) clips
the arm against the box's faces with absolute tolerances (1e-6 on lengths
and squared lengths) that are not small beside a 1.5 mm arm radius. Near
contact, where a simulation lives, it missed 3 of 45 arm–body contacts in
2000 random poses and was off by up to 0.55 mm on others
(``benchmarks/mjx_collision.py``, against a brute-force distance). The same
in float64; with every length ×100 the errors vanish (≤ 0.005 mm): the
thresholds, not precision. A missed contact lets an arm sink into a body
until it is caught deeper, which is what the MJX lanes flagged for
penetration looked like.

This collider uses the exact geometry instead: the signed distance from the
capsule's axis segment to the box is convex along the segment, so a golden-
section search finds its minimum to well under a micrometre in a fixed
number of steps (vmap- and jit-friendly). It returns two contacts per
capsule–box pair, as MJX's routine does: the deepest point on each half of
the axis, the second kept only when it is distinct from the first (a line
contact: an arm lying along a face), so a corner touch is not counted twice.

:func:`install` registers it in MJX's collision table for (capsule, box);
it must run before the first trace of ``mjx.step``. That table is private
to MJX, so ``install`` checks that the entry it replaces is the routine it
was written against and refuses otherwise.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
_ITERATIONS = 36  # interval shrinks by 0.618**36 ~ 3e-8 of the axis length


def _box_signed_distance(x, half):
    """Signed distance from point ``x`` (box frame) to a box of half-sizes ``half``."""
    q = jnp.abs(x) - half
    outside = jnp.linalg.norm(jnp.maximum(q, 0.0))
    return outside + jnp.minimum(q.max(), 0.0)


def _min_on_segment(p0, p1, half, lo, hi):
    """argmin over t in [lo, hi] of the box signed distance at p0 + t (p1 - p0) (convex in t)."""
    f = lambda t: _box_signed_distance(p0 + t * (p1 - p0), half)

    def body(_, s):
        a, b = s
        c = b - _GOLDEN * (b - a)
        d = a + _GOLDEN * (b - a)
        left = f(c) <= f(d)
        return jnp.where(left, a, c), jnp.where(left, d, b)

    a, b = jax.lax.fori_loop(0, _ITERATIONS, body, (jnp.asarray(lo, p0.dtype), jnp.asarray(hi, p0.dtype)))
    t = 0.5 * (a + b)
    # the ends are candidates too (the search never evaluates them exactly)
    ts = jnp.stack([jnp.asarray(lo, p0.dtype), t, jnp.asarray(hi, p0.dtype)])
    vals = jax.vmap(f)(ts)
    return ts[jnp.argmin(vals)]


def _contact_at(x, half, radius):
    """(dist, midpoint, normal from capsule to box) for the capsule sphere at axis point ``x`` (box frame)."""
    q = jnp.abs(x) - half
    inside = (q < 0).all()
    closest = jnp.clip(x, -half, half)
    out_vec = x - closest
    out_len = jnp.linalg.norm(out_vec)
    # inside: leave through the face of least penetration
    i = jnp.argmax(q)
    face_n = jnp.zeros(3, x.dtype).at[i].set(jnp.where(x[i] >= 0, 1.0, -1.0))
    n_out = jnp.where(inside | (out_len < 1e-12), face_n, out_vec / jnp.maximum(out_len, 1e-30))
    sd = jnp.where(inside, q.max(), out_len)
    surface_box = jnp.where(inside, x + (-q.max()) * face_n, closest)
    surface_cap = x - radius * n_out
    return sd - radius, 0.5 * (surface_box + surface_cap), -n_out


def capsule_box_contacts(cap_pos, cap_mat, cap_size, box_pos, box_mat, box_size):
    """Two contacts (dist [2], pos [2, 3], normal [2, 3]) between one capsule and one box, world frame.

    dist < 0 is penetration; the normal points from the capsule to the box.
    The second contact is disabled (dist = +1) unless it is a separate
    support point: at least two capsule radii along the axis from the first.
    """
    radius, half_len = cap_size[0], cap_size[1]
    axis = cap_mat[:, 2]
    rot = box_mat.T
    p0 = rot @ (cap_pos - half_len * axis - box_pos)
    p1 = rot @ (cap_pos + half_len * axis - box_pos)
    half = box_size[:3]
    t_a = _min_on_segment(p0, p1, half, 0.0, 0.5)
    t_b = _min_on_segment(p0, p1, half, 0.5, 1.0)
    da, pa, na = _contact_at(p0 + t_a * (p1 - p0), half, radius)
    db, pb, nb = _contact_at(p0 + t_b * (p1 - p0), half, radius)
    first_a = da <= db
    d1, x1, n1 = jnp.where(first_a, da, db), jnp.where(first_a, pa, pb), jnp.where(first_a, na, nb)
    d2, x2, n2 = jnp.where(first_a, db, da), jnp.where(first_a, pb, pa), jnp.where(first_a, nb, na)
    separate = jnp.abs(t_a - t_b) * (2.0 * half_len) > 2.0 * radius
    d2 = jnp.where(separate, d2, jnp.ones_like(d2))
    dist = jnp.stack([d1, d2])
    pos = jnp.stack([x1, x2]) @ rot + box_pos  # back to world: box_mat @ x == x @ box_mat.T
    normal = jnp.stack([n1, n2]) @ rot
    return dist, pos, normal


def _make_collider():
    from mujoco.mjx._src import math as mjx_math
    from mujoco.mjx._src.collision_primitive import collider

    @collider(ncon=2)
    def capsule_box(cap, box):
        dist, pos, n = capsule_box_contacts(cap.pos, cap.mat, cap.size, box.pos, box.mat, box.size)
        return dist, pos, jax.vmap(mjx_math.make_frame)(n)

    capsule_box.smarticle_mjx = True
    return capsule_box


def install() -> None:
    """Use this collider for MJX capsule–box pairs in this process (idempotent)."""
    from mujoco.mjx._src import collision_driver as cd
    from mujoco.mjx._src.collision_convex import capsule_convex
    from mujoco.mjx._src.types import GeomType
    key = (GeomType.CAPSULE, GeomType.BOX)
    current = cd._COLLISION_FUNC.get(key)
    if getattr(current, "smarticle_mjx", False):
        return
    if current is not capsule_convex or getattr(current, "ncon", None) != 2:
        raise RuntimeError("this MJX version's capsule-box collision entry is not the one smarticle_mjx "
                           "replaces; check smarticle_mjx/engine/mjx_collision.py against it")
    cd._COLLISION_FUNC[key] = _make_collider()


def uninstall() -> None:
    """Restore MJX's own capsule–box routine (for comparisons)."""
    from mujoco.mjx._src import collision_driver as cd
    from mujoco.mjx._src.collision_convex import capsule_convex
    from mujoco.mjx._src.types import GeomType
    cd._COLLISION_FUNC[(GeomType.CAPSULE, GeomType.BOX)] = capsule_convex
