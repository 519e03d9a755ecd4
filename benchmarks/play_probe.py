"""The solver probe: why crowded robots with gear play turn over (docs/relax.md, "The solver, not the play").

Each row replays the relaxation's compressed start (``--trials`` trials x ``--periods`` periods, seed 0,
model ``lab-lag``) step by step with ``mj_step``, as the native backend runs it
(``engine.native.step_lane``), and records per trial:

* ``tilt_deg``: the largest body tilt from upright (a robot past 2 deg is on its way over; the replay of a
  trial stops once one passes 30 deg);
* ``play_speed``: the fastest any arm moved through its gear play (rad/s; the servo turns at 8.7 rad/s, so
  an arm crossing its play at hundreds of rad/s has been kicked, not driven);
* ``capped_steps``: steps at which MuJoCo's constraint solver stopped at its iteration cap
  (``MjData.solver_niter`` = ``MjModel.opt.iterations``), an unconverged solve.

The rows switch one choice at a time against ``newton`` (MuJoCo's Newton solve, the presets' numerics
before the "auto" solver, with the ``backlash``
robots, out of step by s.d. 0.02 period, the combination that tipped robots in the tilt probe of
``flag_diagnosis.py --probes``): the solver and its iterations, the line search, the integrator, the step,
damping inside the play, and an inertia on the play's free side (``armature`` on the play hinge, a
diagnosis only: no source gives the HD-1440A's gear inertia). Written after one tipped trial had been
examined step by step (Newton at its cap, 20 N on a 35 g robot) and before the rows ran.

    python benchmarks/play_probe.py                   # every row, ~10 min on 2 cores
    python benchmarks/play_probe.py --only newton,cg-100 --trials 8
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))

BASE = ("backlash", 0.02)  # imperfection set, constant per-robot phase offset (s.d., periods)
# name -> (imperfection set, phase offset s.d., --set overrides, extra attributes on every play hinge)
ROWS = {
    "no play": ("none", 0.02, {"solver": "Newton"}, ""),
    "newton": (*BASE, {"solver": "Newton"}, ""),
    "newton, 200 iterations, tolerance 1e-12": (*BASE, {"solver": "Newton", "iterations": 200, "tolerance": 1e-12}, ""),
    "newton, 100 iterations, 500 line-search": (*BASE, {"solver": "Newton", "iterations": 100, "ls_iterations": 500}, ""),
    "cg-20": (*BASE, {"solver": "CG"}, ""),
    "cg-50": (*BASE, {"solver": "CG", "iterations": 50}, ""),
    "cg-100": (*BASE, {"solver": "CG", "iterations": 100}, ""),
    "auto (the default)": (*BASE, {}, ""),
    "pgs-100": (*BASE, {"solver": "PGS", "iterations": 100}, ""),
    "no play, cg-100": ("none", 0.02, {"solver": "CG", "iterations": 100}, ""),
    "newton, implicit": (*BASE, {"solver": "Newton", "integrator": "implicit"}, ""),
    "newton, RK4": (*BASE, {"solver": "Newton", "integrator": "RK4"}, ""),
    "newton, 0.125 ms": (*BASE, {"solver": "Newton", "timestep": 1.25e-4}, ""),
    "newton, play damping 1e-4 N m s": (*BASE, {"solver": "Newton"}, 'damping="0.0001"'),
    "newton, play armature 2.7e-6": (*BASE, {"solver": "Newton"}, 'armature="2.7e-06"'),
    "newton, play armature 1e-5": (*BASE, {"solver": "Newton"}, 'armature="1e-05"'),
    "newton, play armature 5e-5": (*BASE, {"solver": "Newton"}, 'armature="5e-05"'),
}
# the rows were measured with the start of versions up to 0.4.0 (each robot's clock started at t = 0 at its
# phase offset); since 0.4.1 a relaxation starts robots out of phase one after another (relax.trial_lanes)
OLD_START = False
PLAY_JOINT = re.compile(r'(<joint name="r\d+_k\d" type="hinge" axis="[^"]*" ref="0" )')


def _row(name: str, trials: int, periods: int):
    """Row ``name``'s relaxation config, scene parameters, starts, phases, MJCF and play-hinge edit."""
    from smarticle_mjx import presets
    from smarticle_mjx.engine import Scene
    from smarticle_mjx.relax import start_poses
    from smarticle_mjx.specs import RelaxConfig
    imperfections, jitter, overrides, extra = ROWS[name]
    config = RelaxConfig(trials=trials, periods=periods, imperfections=imperfections, phase_jitter=jitter)
    params = config.robots().scene(presets.apply(presets.params("lab-lag"), overrides.items()))
    starts, phase = start_poses(config, params)
    return config, params, starts, phase, Scene.mjcf(params, config.n_robots, False), extra


def probe(args) -> tuple[str, list[dict], float]:
    name, trials, periods = args
    import flag_diagnosis as fd
    from smarticle_mjx.engine import Scene
    from smarticle_mjx.engine.core import SceneLayout, on_step_grid
    from smarticle_mjx.relax import trial_lanes
    from smarticle_mjx.scene import compile_model
    config, params, starts, phase, xml, extra = _row(name, trials, periods)
    if extra:
        xml, n = PLAY_JOINT.subn(r"\1" + extra + " ", xml)
        if not n:
            raise ValueError(f"{name}: no play hinges to change")
    m = compile_model(xml)
    scene = Scene(params, m, SceneLayout.of(m), xml, False)
    bodies = [m.geom(f"r{i}_body").bodyid[0] for i in range(config.n_robots)]
    play = np.array([m.jnt_dofadr[j] for j in range(m.njnt) if re.fullmatch(r"r\d+_k\d", m.joint(j).name)], int)
    t0 = time.perf_counter()
    out = []
    for t in range(trials):
        lanes = on_step_grid(trial_lanes(config, starts[t], phase[t], [t], start_delays=OLD_START), m.opt.timestep)
        tilt, speed, capped = 0.0, 0.0, 0
        for _, _, d in fd._stepped(scene, lanes, periods):
            tilt = max(tilt, float(fd._tilts_deg(d, bodies).max()))
            capped += int(d.solver_niter[0] >= m.opt.iterations)
            if play.size:
                speed = max(speed, float(np.abs(d.qvel[play]).max()))
            if not tilt < 30:
                break
        out.append({"tilt_deg": round(tilt, 2), "play_speed": round(speed, 1), "capped_steps": capped})
    return name, out, time.perf_counter() - t0


REF_SOLVE = ("CG", 5000, 1e-14)  # the census's reference: CG that runs until the cost stops changing


def census(args) -> tuple[str, dict]:
    """Along one trial (``trial``, ``periods``) of row ``name``: every ``every``-th step and every step at the
    iteration cap re-solved from the same state and warm start with REF_SOLVE; the relative error of the
    accelerations (``solver_check._relative_error``: of max |qacc| or 1 m/s^2), as the solver census does."""
    name, trial, periods, every = args
    import mujoco
    import flag_diagnosis as fd
    from smarticle_mjx.engine import Scene
    from smarticle_mjx.engine.core import SceneLayout, on_step_grid
    from smarticle_mjx.engine.solver_check import REL_TOL, _relative_error
    from smarticle_mjx.relax import trial_lanes
    from smarticle_mjx.scene import compile_model
    config, params, starts, phase, xml, extra = _row(name, trial + 1, periods)
    if extra:
        raise ValueError(f"{name}: the census runs rows without play-hinge edits")
    m = compile_model(xml)
    ref = compile_model(xml)
    ref.opt.solver = getattr(mujoco.mjtSolver, "mjSOL_" + REF_SOLVE[0])
    ref.opt.iterations, ref.opt.tolerance = REF_SOLVE[1], REF_SOLVE[2]
    dref = mujoco.MjData(ref)
    scene = Scene(params, m, SceneLayout.of(m), xml, False)
    lanes = on_step_grid(trial_lanes(config, starts[trial], phase[trial], [trial], start_delays=OLD_START),
                         m.opt.timestep)
    errs, capped_errs, prev = [], [], mujoco.MjData(m)
    for n, (_, _, d) in enumerate(fd._stepped(scene, lanes, periods)):
        # the solve of this step was made from prev's state: redo it with the reference solver
        if n and (n % every == 0 or d.solver_niter[0] >= m.opt.iterations):
            dref.qpos[:], dref.qvel[:], dref.ctrl[:], dref.act[:] = prev.qpos, prev.qvel, prev.ctrl, prev.act
            dref.qacc_warmstart[:], dref.time = prev.qacc_warmstart, prev.time
            mujoco.mj_forward(ref, dref)
            e = float(_relative_error(d.qacc, dref.qacc))
            (capped_errs if d.solver_niter[0] >= m.opt.iterations else errs).append(e)
        mujoco.mj_copyData(prev, m, d)
    errs, capped_errs = np.asarray(errs), np.asarray(capped_errs)
    return name, {"trial": trial, "periods": periods, "sampled_every": every, "reference": list(REF_SOLVE),
                  "sampled_steps": int(errs.size), "sampled_unconverged": int((errs > REL_TOL).sum()),
                  "capped_steps": int(capped_errs.size), "capped_unconverged": int((capped_errs > REL_TOL).sum()),
                  "worst_relative_error": float(max(errs.max(initial=0), capped_errs.max(initial=0)))}


def pair_census(args) -> tuple[str, dict]:
    """``n`` random valid pair starts (the step check's: seed 1, 90 deg) with two robots drawn from the
    ``lab`` set (seed 1, as step_mechanism.py --imperfections lab draws them), ``periods`` periods each,
    stepped with ``solver``: capped solves, the fastest crossing of a play, the largest tilt."""
    solver, n, periods = args
    import flag_diagnosis as fd
    from smarticle_mjx import imperfections as imp
    from smarticle_mjx import presets
    from smarticle_mjx.bench import pair_starts
    from smarticle_mjx.engine import Lanes, Scene
    from smarticle_mjx.engine.core import on_step_grid
    from smarticle_mjx.gait import GaitSpec
    base = presets.apply(presets.params("lab-lag"), [("solver", solver)])
    robots = imp.draw("lab", 2, 1)
    params = robots.scene(base)
    scene = Scene.build(params, 2)
    m = scene.model
    bodies = [m.geom(f"r{i}_body").bodyid[0] for i in range(2)]
    play = np.array([m.jnt_dofadr[j] for j in range(m.njnt) if re.fullmatch(r"r\d+_k\d", m.joint(j).name)], int)
    poses = pair_starts(base, n, 1, 90.0)
    lanes = on_step_grid(robots.lanes(Lanes.from_gait(poses, GaitSpec(90.0)), np.arange(n)), m.opt.timestep)
    capped, steps, speed, tilt = [], 0, [], []
    for i in range(n):
        c, v, t = 0, 0.0, 0.0
        for _, _, d in fd._stepped(scene, lanes.take(np.array([i])), periods):
            c += int(d.solver_niter[0] >= m.opt.iterations)
            v = max(v, float(np.abs(d.qvel[play]).max()))
            t = max(t, float(fd._tilts_deg(d, bodies).max()))
            steps += 1
        capped.append(c), speed.append(round(v, 1)), tilt.append(round(t, 2))
    return solver, {"starts": n, "periods": periods, "steps": steps, "constraint_solver": list(params.constraint_solver(2)),
                    "capped_steps": int(sum(capped)), "starts_with_capped": int(sum(c > 0 for c in capped)),
                    "play_speed_max": max(speed), "starts_over_50_rad_s": int(sum(v > 50 for v in speed)),
                    "tilt_max_deg": max(tilt), "per_start": {"capped": capped, "play_speed": speed, "tilt_deg": tilt}}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=16)
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--only", default=None, help="comma-separated row names (the JSON keeps the others)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "play_probe.json")
    ap.add_argument("--census", type=int, default=None, metavar="TRIAL",
                    help="instead: the solver census of rows 'newton' and 'cg-100' along this trial")
    ap.add_argument("--census-every", type=int, default=50)
    ap.add_argument("--pairs", type=int, default=None, metavar="N",
                    help="instead: N pairs of lab robots stepped with Newton and with the default solver")
    args = ap.parse_args(argv)
    if args.pairs is not None:
        if args.pairs < 1:
            ap.error("--pairs takes a count >= 1")
        with Pool(2) as pool:
            got = dict(pool.map(pair_census, [(sv, args.pairs, args.periods) for sv in ("Newton", "auto")]))
        for sv, c in got.items():
            print(f"{sv:6s} ({c['constraint_solver'][0]}): {c['starts']} pairs x {c['periods']} periods, capped "
                  f"{c['capped_steps']} of {c['steps']} steps in {c['starts_with_capped']} pairs; play crossed "
                  f"> 50 rad/s in {c['starts_over_50_rad_s']} (fastest {c['play_speed_max']}); tilt max "
                  f"{c['tilt_max_deg']} deg", flush=True)
        out = args.out.with_name(args.out.stem + "_pairs.json")
        out.write_text(json.dumps(got, indent=1))
        return
    if args.census is not None:
        if args.census < 0 or args.census_every < 1:
            ap.error("--census takes a trial index >= 0 and --census-every a step count >= 1")
        with Pool(2) as pool:
            got = dict(pool.map(census, [(n, args.census, args.periods, args.census_every)
                                         for n in ("newton", "cg-100")]))
        for n, c in got.items():
            print(f"{n:8s} trial {c['trial']}: sampled {c['sampled_steps']} steps, {c['sampled_unconverged']} "
                  f"unconverged; capped {c['capped_steps']}, {c['capped_unconverged']} unconverged; "
                  f"worst {c['worst_relative_error']:.3g}", flush=True)
        out = args.out.with_name(args.out.stem + "_census.json")
        kept = json.loads(out.read_text()) if out.exists() else {}
        kept[f"trial {args.census}"] = got
        out.write_text(json.dumps(kept, indent=1))
        return
    names = list(ROWS) if not args.only else [n.strip() for n in args.only.split(",")]
    unknown = [n for n in names if n not in ROWS]
    if unknown:
        ap.error(f"unknown row(s): {', '.join(unknown)}; rows: {', '.join(ROWS)}")
    if args.trials < 1 or args.periods < 1:
        ap.error("--trials and --periods must be >= 1")
    kept = json.loads(args.out.read_text())["rows"] if args.out.exists() else {}
    with Pool(2) as pool:
        for name, trials, wall in pool.imap_unordered(probe, [(n, args.trials, args.periods) for n in names]):
            tipped = sum(t["tilt_deg"] > 2 for t in trials)
            kicked = sum(t["play_speed"] > 50 for t in trials)
            with_cap = sum(t["capped_steps"] > 0 for t in trials)
            print(f"{name:42s} tipped {tipped:2d}/{len(trials)}  play > 50 rad/s {kicked:2d}  "
                  f"trials with capped solves {with_cap:2d}  ({wall:.0f} s)", flush=True)
            imperfections, jitter, overrides, extra = ROWS[name]
            kept[name] = {"imperfections": imperfections, "phase_sd": jitter, "overrides": overrides,
                          "play_hinge_extra": extra, "tipped": tipped, "play_over_50_rad_s": kicked,
                          "trials_with_capped_solves": with_cap, "trials": trials, "wall_s": round(wall, 1)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"model": "lab-lag", "trials": args.trials, "periods": args.periods,
                                    "seed": 0, "tipped_above_deg": 2.0,
                                    "rows": {n: kept[n] for n in ROWS if n in kept}}, indent=1))


if __name__ == "__main__":
    main()
