"""Warp kernels of the warp backend (:mod:`.mjwarp`): controls in, touch records out.

No ``from __future__ import annotations`` here: Warp reads the kernels'
annotations as objects.
"""

import warp as wp


@wp.kernel
def set_ctrl(table: wp.array3d(dtype=wp.float32), row: wp.array(dtype=wp.int32),
             step: wp.array(dtype=wp.int32), ctrl: wp.array2d(dtype=wp.float32)):
    """ctrl[w] = the gait table's row of world w at the current step."""
    w, u = wp.tid()
    ctrl[w, u] = table[row[w], step[0], u]


@wp.kernel
def record(sensordata: wp.array2d(dtype=wp.float32), adr: wp.array(dtype=wp.int32),
           qpos: wp.array2d(dtype=wp.float32), qvel: wp.array2d(dtype=wp.float32),
           touched: wp.array2d(dtype=wp.int32), mind: wp.array2d(dtype=wp.float32),
           finite: wp.array(dtype=wp.int32)):
    """Fold this step's touch sensors (found, dist at ``adr``) into the period's records."""
    w = wp.tid()
    for p in range(adr.shape[0]):
        a = adr[p]
        if sensordata[w, a] > 0.0:
            touched[w, p] = 1
            mind[w, p] = wp.min(mind[w, p], sensordata[w, a + 1])
    ok = int(1)
    for i in range(qpos.shape[1]):
        if not wp.isfinite(qpos[w, i]):
            ok = 0
    for i in range(qvel.shape[1]):
        if not wp.isfinite(qvel[w, i]):
            ok = 0
    if ok == 0:
        finite[w] = 0


@wp.kernel
def tick(step: wp.array(dtype=wp.int32), nper: int):
    """Next step of the gait table (it holds one period: the gait is periodic)."""
    step[0] = (step[0] + 1) % nper
