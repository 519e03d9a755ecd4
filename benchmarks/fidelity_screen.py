"""Fidelity screening: which model preset reproduces the paper's gliders?

Per preset (smarticle_mjx/presets.py), the quantities of docs/fidelity.md:

* lone robot: net drift per gait cycle at 90 and 10 deg, at dt and dt/4
  (converged when they agree);
* pairs at 90 deg from random starts (|r| 0.8-2.0 W): gliders = pairs bound
  in every period after a burn-in; their net speed, direction persistence,
  median change of direction of travel, straightness over 20 periods, beta
  over delays 5-15 (bootstrap over gliders), how long phi - 180 deg keeps its
  sign, how tightly (|r|, theta, phi) repeats, the C2 (aligned) fraction;
* P_b (bound at the end) at 30, 50, 70, 90 deg with exact 95 % intervals;
* cost: simulated seconds per wall second of a pair.

Resumable: every (preset, part, sizes) result is saved to the JSON as soon as
it is done and reused on the next run; delete an entry (or the file) to redo
it. Screen small, then confirm the leaders with larger --pairs / --periods:

  python benchmarks/fidelity_screen.py --models paper,lab,lab-dart --pairs 48 --periods 40
  python benchmarks/fidelity_screen.py --models lab-dart --pairs 160 --periods 100 --pb 0

Prints a markdown table (paper's value beside each quantity).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT.parent))

from smarticle_mjx import configs as C  # noqa: E402
from smarticle_mjx import presets  # noqa: E402
from smarticle_mjx.engine import Lanes, Scene, make_backend, steps_per_period  # noqa: E402
from smarticle_mjx.engine.batch import RetireRule, run_lanes  # noqa: E402
from smarticle_mjx.gait import GaitSpec  # noqa: E402
from smarticle_mjx.reduce import binding, gliders, transport  # noqa: E402

PAPER = {"drift90_W": 1.5e-3, "beta": 1.8, "persistence": None, "straightness": None}


def _save(path: pathlib.Path, data: dict):
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, default=float))
    os.replace(tmp, path)


def _run(params, gait: GaitSpec, poses, periods: int, quiet: int, robots=None):
    """Per-period poses [M, K, N, 5] and touches [M, K] of every lane, and the wall time.

    ``robots``: an ``imperfections.Draw`` of the scene's robots (lane i takes the phase jitter of row i)."""
    if robots is not None:
        params = robots.scene(params)
    scene = Scene.build(params, poses.shape[1])
    be = make_backend("native", scene)
    lanes = Lanes.from_gait(poses, gait)
    if robots is not None:
        lanes = robots.lanes(lanes, np.arange(len(poses)))
    m = len(poses)
    out_p = np.full((m, periods, poses.shape[1], 5), np.nan)
    out_t = np.zeros((m, periods), bool)

    def on_lanes(res):
        out_p[res.index] = res.poses
        if res.touched.shape[-1]:
            out_t[res.index] = res.touched[..., 0]

    t = time.perf_counter()
    try:
        info = run_lanes(be, lanes, periods, batch_size=64, chunk_periods=5,
                         rule=RetireRule(quiet_periods=quiet), on_lanes=on_lanes)
    finally:
        be.close()
    wall = time.perf_counter() - t
    steps = info["lane_periods"] * steps_per_period(lanes.period, params.timestep)
    return out_p, out_t, wall, steps


def lone_drift(params, amplitude: float, periods: int, imperfections: str | None = None, robots: int = 8,
               seed: int = 1) -> dict:
    """Net displacement per cycle of one robot (W), at dt and dt/4.

    With ``imperfections``: ``robots`` robots drawn from that set (seed ``seed``), each alone on the
    plate; the net drift per cycle is their mean (and every robot's value is kept)."""
    out = {}
    gait = GaitSpec(amplitude)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    W = params.robot.body_length
    draws = [None]
    if imperfections:
        from smarticle_mjx import imperfections as imp
        d = imp.draw(imperfections, robots, seed)
        draws = [dataclasses.replace(d, arm_speed=d.arm_speed[i:i + 1], clock=d.clock[i:i + 1],
                                     quirks=d.quirks[i:i + 1]) for i in range(robots)]
    for label, dt in (("dt", params.timestep), ("dt/4", params.timestep / 4)):
        p = dataclasses.replace(params, timestep=dt)
        poses = np.array([[[0.0, 0.0, 0.0, a0[0], a0[1]]]])
        net, step, turn, wall = [], [], [], 0.0
        for robot in draws:
            tr, _, w, _ = _run(p, gait, poses, periods, quiet=0, robots=robot)
            xy = np.concatenate([poses[:, None, 0, :2], tr[:, :, 0, :2]], 1)[0]
            heading = np.concatenate([[0.0], tr[0, :, 0, 2]])
            net.append(float(np.linalg.norm(xy[-1] - xy[0]) / periods / W))
            step.append(float(np.linalg.norm(np.diff(xy, axis=0), axis=1).mean() / W))
            turn.append(float(np.degrees(np.abs(transport.turning(heading)).mean())))
            wall += w
        out[label] = {"net_per_cycle_W": float(np.mean(net)), "step_per_cycle_W": float(np.mean(step)),
                      "turn_per_cycle_deg": float(np.mean(turn)), "wall_s": wall}
        if imperfections:
            out[label]["net_per_robot_W"] = net
    return out


def pair_starts(params, n: int, seed: int, amplitude: float, r_range=(0.8, 2.0)):
    gait = GaitSpec(amplitude)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    return C.sample_valid_pairs(n, np.random.default_rng(seed), r_range, a0[0], a0[1], params.robot)


def gliding(params, n: int, periods: int, seed: int, burn_in: int, save: pathlib.Path | None = None,
            robots=None) -> dict:
    """Glider quantities at 90 deg from ``n`` random valid starts; the
    per-period tracks go to ``save`` (.npz) so that metrics can be recomputed
    (:func:`glide_metrics`) without simulating again."""
    W = params.robot.body_length
    gait = GaitSpec(90.0)
    poses = pair_starts(params, n, seed, 90.0)
    tr, touched, wall, steps = _run(params, gait, poses, periods, quiet=2, robots=robots)
    com = (tr[:, :, 0, :2] + tr[:, :, 1, :2]) / 2 / W
    r, th, ph = C.relative_coordinates(tr[:, :, 0], tr[:, :, 1], W)
    rel = np.stack([r, th, ph], -1)
    if save is not None:
        save.parent.mkdir(parents=True, exist_ok=True)
        # float64: a glider's centre moves ~1e-3 W in some periods, which float32 positions of ~1 W blur
        # into zero or random steps (direction persistence 0.25 instead of 0.38 for lab-lag)
        np.savez_compressed(save, com=com, rel=rel, touched=touched,
                            poses=poses)
    out = {"starts": n, "periods": periods, "burn_in": burn_in, "wall_s": wall, "steps": int(steps),
           "sim_s_per_wall_s": float(steps * params.timestep / wall)}
    out.update(glide_metrics(com, rel, touched, burn_in))
    return out


def glide_metrics(com, rel, touched, burn_in: int) -> dict:
    """The glider quantities of per-period tracks (:func:`smarticle_mjx.reduce.gliders.glide_summary`)."""
    return gliders.glide_summary(com, rel, touched, burn_in)


def pb(params, amplitude: float, n: int, periods: int, seed: int, robots=None) -> dict:
    poses = pair_starts(params, n, seed, amplitude, r_range=(0.5, 2.5))
    _, touched, wall, steps = _run(params, GaitSpec(amplitude), poses, periods, quiet=2, robots=robots)
    p = binding.binding_probability(touched, np.ones(n, bool))
    return {"n": n, "periods": periods, "end": p["end"], "throughout": p["throughout"], "wall_s": wall}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", default="paper,paper-stiff,paper-dart,lab,lab-stiff,lab-dart,lab-lag,dart")
    ap.add_argument("--pairs", type=int, default=48, help="random starts at 90 deg")
    ap.add_argument("--periods", type=int, default=40)
    ap.add_argument("--burn-in", type=int, default=10)
    ap.add_argument("--pb", type=int, default=80, help="random starts per P_b amplitude (0: skip)")
    ap.add_argument("--pb-periods", type=int, default=30)
    ap.add_argument("--drift-periods", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--dt-divisor", type=int, default=1,
                    help="run the glide and P_b parts at the preset's time step / this (convergence check); "
                         "results are stored under the preset name + '@dt/N'")
    ap.add_argument("--numerics", default=None,
                    help="run the glide and P_b parts with a candidate of benchmarks/timestep_candidates.py "
                         "(its time step, integrator, solver settings); stored under the preset name + '~NAME'")
    ap.add_argument("--imperfections", default=None,
                    help="draw the robots' imperfections from this set (smarticle_mjx/imperfections.py, seed "
                         "--seed); stored under the preset name + '+NAME'")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "fidelity_screen.json")
    ap.add_argument("--tables", action="store_true", help="only print the tables of docs/fidelity.md from the JSON")
    args = ap.parse_args()
    data = json.loads(args.out.read_text()) if args.out.exists() else {}
    if args.tables:
        print(doc_tables(data))
        return
    for name in args.models.split(","):
        params = presets.params(name)
        if args.dt_divisor > 1:
            params = dataclasses.replace(params, timestep=params.timestep / args.dt_divisor)
            name = f"{name}@dt/{args.dt_divisor}"
        if args.numerics:
            from timestep_candidates import CANDIDATES
            if args.numerics not in CANDIDATES:
                raise SystemExit(f"unknown numerics {args.numerics!r}; known: {', '.join(CANDIDATES)}")
            params = dataclasses.replace(params, **CANDIDATES[args.numerics])
            params.validate()
            name = f"{name}~{args.numerics}"
        robots = None
        if args.imperfections:
            from smarticle_mjx import imperfections as imp
            robots = imp.draw(args.imperfections, 2, args.seed)
            name = f"{name}+{args.imperfections}"
        entry = data.setdefault(name, {})
        parts = {} if args.dt_divisor > 1 or args.numerics else {
            f"drift{a:g}_{args.drift_periods}": (lambda a=a: lone_drift(params, a, args.drift_periods,
                                                                        args.imperfections, seed=args.seed))
            for a in (90.0, 20.0, 10.0)}
        parts.update({
            f"glide_{args.pairs}x{args.periods}_s{args.seed}": lambda: gliding(
                params, args.pairs, args.periods, args.seed, args.burn_in, robots=robots,
                save=args.out.parent / "fidelity_tracks" / f"{name.replace('/', '')}_glide_{args.pairs}x{args.periods}_s{args.seed}.npz"),
        })
        if args.pb:
            for a in (30.0, 50.0, 70.0, 90.0):
                parts[f"pb{a:g}_{args.pb}x{args.pb_periods}_s{args.seed}"] = \
                    (lambda a=a: pb(params, a, args.pb, args.pb_periods, args.seed, robots=robots))
        for key, fn in parts.items():
            if key in entry:
                continue
            t = time.perf_counter()
            entry[key] = fn()
            print(f"{name} {key}: {time.perf_counter() - t:.0f} s", flush=True)
            _save(args.out, data)
    names = args.models.split(",")
    if args.imperfections:
        names = [f"{n}+{args.imperfections}" for n in names]
    if args.dt_divisor > 1:
        names = [f"{n}@dt/{args.dt_divisor}" for n in names]
    if args.numerics:
        names = [f"{n}~{args.numerics}" for n in names]
    print(table(data, names))


def doc_tables(data: dict) -> str:
    """The tables of docs/fidelity.md: screen, P_b with exact intervals,
    confirmation, time step (each from the samples named in its caption)."""
    order = ["paper", "paper-stiff", "paper-dart", "lab", "lab-stiff", "lab-dart", "lab-lag", "dart"]

    def strip(t):  # drift and P_b come from the screen
        return "\n".join(ln for ln in t.splitlines() if not ln.startswith(("| lone drift", "| P_b")))

    rows = ["| preset | " + " | ".join(f"P_b end {a}° [95 % exact]" for a in (30, 50, 70, 90)) + " |",
            "|" + " --- |" * 5]
    for m in order:
        cells = []
        for a in (30, 50, 70, 90):
            v = data.get(m, {}).get(f"pb{a}_80x30_s1")
            cells.append("—" if v is None else
                         f"{v['end'][0]:.2f} [{v['end'][1]:.2f}, {v['end'][2]:.2f}] ({v['end'][3]}/{v['n']})")
        rows.append(f"| `{m}` | " + " | ".join(cells) + " |")
    confirm = [m for m in ("lab-lag", "paper") if "glide_128x100_s1" in data.get(m, {})]
    dt = ["lab-lag", "lab-lag@dt/4", "lab-dart", "lab-dart@dt/4", "dart", "dart@dt/2"]
    return "\n\n".join([
        "### Screen (48 starts x 40 periods)", table(data, order, sample="48x40_s1"),
        "### P_b (80 starts x 30 periods, bound in the last period)", "\n".join(rows),
        "### Confirmation (128 starts x 100 periods)", strip(table(data, confirm, sample="128x100_s1")),
        "### Time step (24 starts x 40 periods)", strip(table(data, dt, sample="24x40_s1"))])


def _fmt(v, spec=".2f"):
    return "—" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def table(data: dict, names, confirm: int | None = None, sample: str | None = None) -> str:
    """Markdown table of the largest glide sample and P_b of each preset
    (``confirm``: the largest sample of at least that many periods;
    ``sample``: that glide sample, e.g. "24x40_s1")."""
    rows = [("lone drift 90° (W/cycle), dt · dt/4", "1.5e-3"), ("lone drift 10° (W/cycle), dt · dt/4", "> 90°'s"),
            ("gliders / starts (periods)", "—"), ("net speed (W/period)", "2.9 W / ≥ 100 periods ≈ 0.03 (lab)"),
            ("direction persistence", "nearly ballistic (≥ 0.8 target)"), ("median direction change (°)", "small"),
            ("straightness over 20 periods", "≥ 0.8 target"), ("β (lags 5–15) ± bootstrap sd", "≈ 1.8"),
            ("C1 median \\|φ−180°\\| (°)", "deviates, consistent sign"),
            ("C1 gliders holding the sign of φ−180°", "consistent sign"), ("sign flips per period", "≈ 0"),
            ("repeat sd: \\|r\\| (W), φ (°)", "tight (limit cycle)"), ("C2 fraction of glider samples", "two clusters"),
            ("P_b end 30/50/70/90° (n)", "dip at 40–60°"), ("cost (sim s per wall s, pair)", "—")]
    cols = {}
    for n in names:
        e = data.get(n, {})
        d90 = [v for k, v in e.items() if k.startswith("drift90")]
        d10 = [v for k, v in e.items() if k.startswith("drift10")]
        gl = [v for k, v in e.items() if k.startswith("glide")]
        g = max(gl, key=lambda v: v["starts"] * v["periods"]) if gl else {}
        if confirm is not None:
            g = max((v for v in gl if v["periods"] >= confirm), key=lambda v: v["starts"], default={})
        if sample is not None:
            g = e.get(f"glide_{sample}", {})
        pbs = {k.split("_")[0][2:]: v for k, v in e.items() if k.startswith("pb")}
        col = [
            " · ".join(_fmt(d90[-1][x]["net_per_cycle_W"], ".1e") for x in ("dt", "dt/4")) if d90 else "—",
            " · ".join(_fmt(d10[-1][x]["net_per_cycle_W"], ".1e") for x in ("dt", "dt/4")) if d10 else "—",
            f"{g.get('gliders', '—')} / {g.get('starts', '—')} ({g.get('periods', '—')})",
            _fmt(g.get("net_speed_W_per_period"), ".4f"), _fmt(g.get("persistence")),
            _fmt(g.get("median_turn_deg"), ".0f"), _fmt(g.get("straightness20")),
            f"{_fmt(g.get('beta'))} ± {_fmt(g.get('beta_err'))}",
            _fmt(g.get("C1_phi_dev_deg"), ".1f"),
            f"{_fmt(g.get('C1_sign_held_frac'))} of {g.get('C1_gliders', '—')} (≥ {g.get('sign_hold_periods', '—')} periods)",
            _fmt(g.get("sign_flips_per_period"), ".3f"),
            f"{_fmt((g.get('repeat') or {}).get('r'), '.3f')}, "
            f"{_fmt(math.degrees((g.get('repeat') or {}).get('phi', float('nan'))), '.1f')}",
            _fmt(g.get("C2_fraction")),
            " / ".join(_fmt(pbs[a]["end"][0]) for a in ("30", "50", "70", "90") if a in pbs)
            + (f" ({next(iter(pbs.values()))['n']})" if pbs else ""),
            _fmt(g.get("sim_s_per_wall_s"), ".1f"),
        ]
        cols[n] = col
    head = "| quantity | paper | " + " | ".join(f"`{n}`" for n in names) + " |"
    sep = "|" + " --- |" * (2 + len(names))
    lines = [head, sep]
    for i, (q, ref) in enumerate(rows):
        lines.append(f"| {q} | {ref} | " + " | ".join(cols[n][i] for n in names) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
