"""MuJoCo's own distance between two robots' geoms: the independent reference of the planar overlap tests."""

import mujoco
import numpy as np

from smarticle_mjx import scene as S


def mujoco_gap(params, poses) -> float:
    """Smallest signed distance between the two robots' geoms, from MuJoCo's own distance query."""
    m = S.compile_model(S.build_mjcf(params, poses))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    lay = S.SceneLayout.of(m)
    g0 = [g for g in range(m.ngeom) if lay.geom_robot[g] == 0]
    g1 = [g for g in range(m.ngeom) if lay.geom_robot[g] == 1]
    ft = np.zeros(6)
    return min(mujoco.mj_geomDistance(m, d, a, b, 0.2, ft) for a in g0 for b in g1)
