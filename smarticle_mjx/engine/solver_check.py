"""Is MuJoCo's constraint solver converged along a trajectory?

The Newton solver stops when an iteration improves the cost by less than
``tolerance`` -- including when its line search was cut short by
``ls_iterations``, which then looks like convergence while the gradient is
still large. :func:`solver_census` steps lanes with MuJoCo C and re-solves
every multi-iteration step's state (same warm start) with a solver that
cannot stop early (1000 iterations, 1000 line-search evaluations), so the
accelerations of the two can be compared.

:func:`mjx_solver_census` asks the same of MJX: it re-solves the states where
MuJoCo C needed more than one iteration with MJX at several line-search caps.
MJX's line search is a fixed-length ``scan`` (a finished lane does no-ops),
so under ``vmap`` every step pays for all ``ls_iterations`` evaluations: the
cap is MJX's cost, and the smallest cap that converges is the one to use.
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
    max_line_search_evals: int | None  # None for MJX, which does not report it


def _hard_states(scene: Scene, lanes: Lanes, nsteps: int):
    """Step lanes with MuJoCo C; yield (d, reference qacc) at every multi-iteration solve."""
    m = scene.model
    ref = mujoco.MjModel.from_xml_string(scene.xml)
    ref.opt.iterations, ref.opt.ls_iterations = 1000, 1000
    d, dref = mujoco.MjData(m), mujoco.MjData(ref)
    lanes = on_step_grid(lanes, m.opt.timestep)
    ctrl = lane_controls(scene, lanes, m.opt.timestep * np.arange(nsteps))
    qpos0 = scene.qpos_from_poses(lanes.poses)
    for i in range(lanes.size):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = qpos0[i]
        for k in range(nsteps):
            d.ctrl[:] = ctrl[i, k]
            mujoco.mj_forward(m, d)
            if d.nefc and int(d.solver_niter[0]) > 1:
                dref.qpos[:], dref.qvel[:], dref.ctrl[:] = d.qpos, d.qvel, d.ctrl
                dref.qacc_warmstart[:], dref.time = d.qacc_warmstart, d.time
                mujoco.mj_forward(ref, dref)
                yield d, dref.qacc.copy()
            mujoco.mj_step(m, d)


def _relative_error(qacc: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """|qacc - ref| as a fraction of max |ref| (or of 1 m/s^2), per state."""
    return np.abs(qacc - ref).max(-1) / np.maximum(1.0, np.abs(ref).max(-1))


def solver_census(scene: Scene, lanes: Lanes, nsteps: int) -> SolverCensus:
    """Step every lane ``nsteps`` from rest with ``scene``'s own solver settings."""
    errs, max_evals = [], 0
    for d, ref_qacc in _hard_states(scene, lanes, nsteps):
        n = int(d.solver_niter[0])
        max_evals = max(max_evals, max(d.solver[j].neval for j in range(min(n, len(d.solver)))))
        errs.append(float(_relative_error(d.qacc, ref_qacc)))
    errs = np.asarray(errs)
    return SolverCensus(lanes.size * nsteps, errs.size, int((errs > REL_TOL).sum()),
                        float(errs.max(initial=0.0)), int(max_evals))


MJX_REFERENCE = (100, 100)  # MJX's own converged solve: iterations, ls_iterations


def mjx_solver_census(scene: Scene, lanes: Lanes, nsteps: int, caps) -> dict:
    """For each MJX ``ls_iterations`` cap: MJX's solve (float32, smarticle_mjx's
    collider) of every state where MuJoCo C needed more than one iteration.

    Convergence is judged against MJX's own solve of the same state with
    ``MJX_REFERENCE`` (same contacts, same precision), so only the cut-short
    line search shows. The states come from MuJoCo C's trajectory, so MJX is
    judged on exactly the impacts C saw. Also returned, as ``"vs_c"``: how far
    MJX's converged solve is from MuJoCo C's converged one (contacts and
    precision differ; not a convergence question).

    Returns ``{cap: SolverCensus, ..., "vs_c": SolverCensus}``.
    """
    import jax
    from mujoco import mjx

    from . import mjx_collision

    mjx_collision.install()
    fields = ("qpos", "qvel", "ctrl", "qacc_warmstart")
    states = {f: [] for f in fields}
    c_ref = []
    for d, ref_qacc in _hard_states(scene, lanes, nsteps):
        for f in fields:
            states[f].append(getattr(d, f).copy())
        c_ref.append(ref_qacc)
    c_ref = np.asarray(c_ref)
    model = mujoco.MjModel.from_xml_string(Scene.mjcf(scene.params, scene.n_robots, sensors="none"))
    fwd = jax.jit(jax.vmap(mjx.forward, in_axes=(None, 0)))
    d0 = mjx.make_data(model)

    def solve(iterations: int, ls_iterations: int) -> np.ndarray:
        model.opt.iterations, model.opt.ls_iterations = iterations, ls_iterations
        mx = mjx.put_model(model)
        qacc = []
        for a in range(0, len(c_ref), 512):  # bounded batches
            sl = slice(a, a + 512)
            b = len(c_ref[sl])
            d = jax.tree_util.tree_map(lambda x: jax.numpy.broadcast_to(x, (b,) + x.shape), d0)
            d = d.replace(**{f: jax.numpy.asarray(np.asarray(states[f][sl]), dtype=d0.qpos.dtype) for f in fields})
            qacc.append(np.asarray(fwd(mx, d).qacc, dtype=np.float64))
        return np.concatenate(qacc) if qacc else np.zeros((0, model.nv))

    def census(qacc, ref) -> SolverCensus:
        errs = _relative_error(qacc, ref) if len(ref) else np.zeros(0)
        return SolverCensus(lanes.size * nsteps, len(ref), int((errs > REL_TOL).sum()),
                            float(errs.max(initial=0.0)), None)

    mjx_ref = solve(*MJX_REFERENCE)
    out = {int(cap): census(solve(scene.params.iterations, int(cap)), mjx_ref) for cap in caps}
    out["vs_c"] = census(mjx_ref, c_ref)
    return out
