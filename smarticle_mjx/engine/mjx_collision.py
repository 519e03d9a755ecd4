"""Capsule–box and capsule–capsule colliders for MJX that agree with MuJoCo at the robots' scale.

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

MJX's capsule–capsule (arm–arm) routine has the same kind of flaw: its
closest point on a segment divides by ``|ab|^2 + 1e-6``, and an arm's axis
is 52.5 mm long, so ``|ab|^2`` is only 2.8e-3 and the point lands up to
~20 µm off along the arm. Beside a 3 mm centre distance that tilts the
contact normal by up to ~0.4°, so every arm–arm contact's force came out in
a slightly wrong direction: MJX's converged accelerations at arm–arm
impacts differed from MuJoCo's by up to 2 % of the largest (float64 as well).
:func:`capsule_capsule_contact` computes the exact closest points of two
segments (the smallest of six candidate pairs: the lines' solution and
the four end projections cover every case; none is ill-conditioned near
parallel) and one contact, as MJX's routine does.

:func:`install` registers both in MJX's collision table for (capsule, box)
and (capsule, capsule); it must run before the first trace of ``mjx.step``.
That table is private to MJX, so ``install`` checks that the entries it
replaces are the routines it was written against and refuses otherwise.
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


def segment_closest_points(a0, a1, b0, b1):
    """Exact closest points of segments a0-a1 and b0-b1.

    The smallest of six candidate pairs, each a pair of points on the two
    segments, so none is closer than the true closest pair and the true one
    is among them: the lines' closest points (the minimum when it is
    interior), each of the four ends projected onto the other segment (the
    minimum when it lies on an end), and, first so that it wins ties, the
    middle of the segments' overlap along a (parallel segments, whose closest
    pairs are not unique). No step is ill-conditioned for near-parallel axes:
    there the line solution is inaccurate but then it is not the smallest.
    """
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a, e, b = d1 @ d1, d2 @ d2, d1 @ d2
    c, f = d1 @ r, d2 @ r
    denom = a * e - b * b
    on_a = lambda x: jnp.clip((x - a0) @ d1 / a, 0.0, 1.0)  # parameter of x's projection onto segment a
    on_b = lambda x: jnp.clip((x - b0) @ d2 / e, 0.0, 1.0)
    sb0, sb1 = -c / a, (b - c) / a  # b's ends projected onto a's line
    s_mid = jnp.clip(0.5 * (jnp.maximum(0.0, jnp.minimum(sb0, sb1)) + jnp.minimum(1.0, jnp.maximum(sb0, sb1))), 0, 1)
    s_line = jnp.clip((b * f - c * e) / jnp.where(denom > 0, denom, 1.0), 0.0, 1.0)
    t_line = jnp.clip((b * s_line + f) / e, 0.0, 1.0)
    p_mid = a0 + s_mid * d1
    ps = jnp.stack([p_mid, a0 + s_line * d1, a0, a1, a0 + on_a(b0) * d1, a0 + on_a(b1) * d1])
    qs = jnp.stack([b0 + on_b(p_mid) * d2, b0 + t_line * d2, b0 + on_b(a0) * d2, b0 + on_b(a1) * d2, b0, b1])
    k = jnp.argmin(((ps - qs) ** 2).sum(-1))
    return ps[k], qs[k]


def capsule_capsule_contact(pos1, mat1, size1, pos2, mat2, size2):
    """One contact (dist, pos, normal from capsule 1 to capsule 2) between two capsules, world frame."""
    h1, h2 = size1[1] * mat1[:, 2], size2[1] * mat2[:, 2]
    p1, p2 = segment_closest_points(pos1 - h1, pos1 + h1, pos2 - h2, pos2 + h2)
    v = p2 - p1
    length = jnp.linalg.norm(v)
    # axes that cross (deep overlap): leave along their common perpendicular
    cross = jnp.cross(mat1[:, 2], mat2[:, 2])
    cross_len = jnp.linalg.norm(cross)
    fallback = jnp.where(cross_len > 0, cross / jnp.maximum(cross_len, 1e-30), jnp.array([1.0, 0.0, 0.0], v.dtype))
    n = jnp.where(length > 0, v / jnp.maximum(length, 1e-30), fallback)
    dist = length - size1[0] - size2[0]
    return dist, p1 + n * (size1[0] + 0.5 * dist), n


def _make_capsule_capsule():
    from mujoco.mjx._src import math as mjx_math
    from mujoco.mjx._src.collision_primitive import collider

    @collider(ncon=1)
    def capsule_capsule(cap1, cap2):
        dist, pos, n = capsule_capsule_contact(cap1.pos, cap1.mat, cap1.size, cap2.pos, cap2.mat, cap2.size)
        return dist, pos, mjx_math.make_frame(n)

    capsule_capsule.smarticle_mjx = True
    return capsule_capsule


def _make_collider():
    from mujoco.mjx._src import math as mjx_math
    from mujoco.mjx._src.collision_primitive import collider

    @collider(ncon=2)
    def capsule_box(cap, box):
        dist, pos, n = capsule_box_contacts(cap.pos, cap.mat, cap.size, box.pos, box.mat, box.size)
        return dist, pos, jax.vmap(mjx_math.make_frame)(n)

    capsule_box.smarticle_mjx = True
    return capsule_box


def _entries():
    """(key, MJX's routine, its ncon, our factory) for each entry replaced."""
    from mujoco.mjx._src.collision_convex import capsule_convex
    from mujoco.mjx._src.collision_primitive import capsule_capsule
    from mujoco.mjx._src.types import GeomType
    return [((GeomType.CAPSULE, GeomType.BOX), capsule_convex, 2, _make_collider),
            ((GeomType.CAPSULE, GeomType.CAPSULE), capsule_capsule, 1, _make_capsule_capsule)]


def install() -> None:
    """Use these colliders for MJX capsule–box and capsule–capsule pairs in this process (idempotent)."""
    from mujoco.mjx._src import collision_driver as cd
    entries = _entries()
    for key, theirs, ncon, _ in entries:  # check all before changing any
        current = cd._COLLISION_FUNC.get(key)
        if getattr(current, "smarticle_mjx", False):
            continue
        if current is not theirs or getattr(current, "ncon", None) != ncon:
            raise RuntimeError(f"this MJX version's {key[0].name.lower()}-{key[1].name.lower()} collision entry is "
                               "not the one smarticle_mjx replaces; check smarticle_mjx/engine/mjx_collision.py "
                               "against it")
    for key, _, _, make in entries:
        if not getattr(cd._COLLISION_FUNC.get(key), "smarticle_mjx", False):
            cd._COLLISION_FUNC[key] = make()


def uninstall() -> None:
    """Restore MJX's own capsule–box and capsule–capsule routines (for comparisons)."""
    from mujoco.mjx._src import collision_driver as cd
    for key, theirs, _, _ in _entries():
        cd._COLLISION_FUNC[key] = theirs
