"""Is MuJoCo's constraint solver converged along a trajectory?

The Newton solver stops when an iteration improves the cost by less than
``tolerance`` -- including when its line search was cut short by
``ls_iterations``, which then looks like convergence while the gradient is
still large. :func:`solver_census` steps lanes with MuJoCo C and re-solves
every multi-iteration step's state (same warm start) with a solver that
cannot stop early (1000 iterations, 1000 line-search evaluations), so the
accelerations of the two can be compared.
"""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np

from .core import Lanes, Scene, lane_controls, on_step_grid

REL_TOL = 1e-3  # unconverged: qacc off by more than this fraction of max |qacc| (or of 1 m/s^2)


@dataclasses.dataclass
class SolverCensus:
    """What the census found.

    Attributes:
      steps: steps taken (lanes x steps per lane).
      multi_iteration_solves: steps whose solve needed > 1 Newton iteration
        (contact onsets, impacts); only these are re-solved.
      unconverged: steps whose accelerations differ from the reference by
        more than ``REL_TOL`` of the largest.
      worst_relative_error: largest such difference.
      max_line_search_evals: most line-search evaluations any iteration used.
    """

    steps: int
    multi_iteration_solves: int
    unconverged: int
    worst_relative_error: float
    max_line_search_evals: int


def solver_census(scene: Scene, lanes: Lanes, nsteps: int) -> SolverCensus:
    """Step every lane ``nsteps`` from rest with ``scene``'s own solver settings."""
    m = scene.model
    ref = mujoco.MjModel.from_xml_string(scene.xml)
    ref.opt.iterations, ref.opt.ls_iterations = 1000, 1000
    d, dref = mujoco.MjData(m), mujoco.MjData(ref)
    lanes = on_step_grid(lanes, m.opt.timestep)
    ctrl = lane_controls(scene, lanes, m.opt.timestep * np.arange(nsteps))
    qpos0 = scene.qpos_from_poses(lanes.poses)
    bad = solves = max_evals = 0
    worst = 0.0
    for i in range(lanes.size):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = qpos0[i]
        for k in range(nsteps):
            d.ctrl[:] = ctrl[i, k]
            mujoco.mj_forward(m, d)
            n = int(d.solver_niter[0])
            if d.nefc and n > 1:
                solves += 1
                max_evals = max(max_evals, max(d.solver[j].neval for j in range(min(n, len(d.solver)))))
                dref.qpos[:], dref.qvel[:], dref.ctrl[:] = d.qpos, d.qvel, d.ctrl
                dref.qacc_warmstart[:], dref.time = d.qacc_warmstart, d.time
                mujoco.mj_forward(ref, dref)
                err = float(np.abs(d.qacc - dref.qacc).max() / max(1.0, np.abs(dref.qacc).max()))
                worst = max(worst, err)
                bad += err > REL_TOL
            mujoco.mj_step(m, d)
    return SolverCensus(lanes.size * nsteps, solves, bad, worst, int(max_evals))
