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
import pathlib
import time


ROOT = pathlib.Path(__file__).resolve().parent

from smarticle_mjx import formatting, presets
from smarticle_mjx.bench import NUMERICS, gliding, lone_drift, pb, relaxation, save_json

PAPER = {"drift90_W": 1.5e-3, "beta": 1.8, "persistence": None, "straightness": None}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--models", default="paper,paper-stiff,paper-dart,lab,lab-stiff,lab-dart,lab-lag,dart")
    ap.add_argument("--pairs", type=int, default=48, help="random starts at 90 deg")
    ap.add_argument("--periods", type=int, default=40)
    ap.add_argument("--burn-in", type=int, default=10)
    ap.add_argument("--pb", type=int, default=80, help="random starts per P_b amplitude (0: skip)")
    ap.add_argument("--pb-periods", type=int, default=30)
    ap.add_argument("--relax", type=int, default=0,
                    help="relaxation trials (7 robots x 300 periods at 90 deg, seed --seed; 0: skip)")
    ap.add_argument("--drift-periods", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--dt-divisor", type=int, default=1,
                    help="run the glide and P_b parts at the preset's time step / this (convergence check); "
                         "results are stored under the preset name + '@dt/N'")
    ap.add_argument("--numerics", default=None,
                    help="run the glide and P_b parts with a candidate of smarticle_mjx/bench.py NUMERICS "
                         "(its time step, integrator, solver settings); stored under the preset name + '~NAME'")
    ap.add_argument("--imperfections", default=None,
                    help="draw the robots' imperfections from this set (smarticle_mjx/imperfections.py, seed "
                         "--seed); stored under the preset name + '+NAME'")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "fidelity_screen.json")
    ap.add_argument("--tables", action="store_true", help="only print the tables of docs/fidelity.md from the JSON")
    args = ap.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
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
            if args.numerics not in NUMERICS:
                raise SystemExit(f"unknown numerics {args.numerics!r}; known: {', '.join(NUMERICS)}")
            params = dataclasses.replace(params, **NUMERICS[args.numerics])
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
        if args.relax and not (args.dt_divisor > 1 or args.numerics):
            base = name.split("+")[0]
            parts[f"relax_{args.relax}_s{args.seed}"] = lambda: relaxation(
                base, args.relax, args.seed, args.imperfections,
                args.out.parent / "fidelity_relax" / f"{name}_relax_{args.relax}_s{args.seed}.h5")
        for key, fn in parts.items():
            if key in entry:
                continue
            t = time.perf_counter()
            entry[key] = fn()
            print(f"{name} {key}: {time.perf_counter() - t:.0f} s", flush=True)
            save_json(args.out, data)
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
    return formatting.num(v, spec, dash="—")  # the docs tables' em dash


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
