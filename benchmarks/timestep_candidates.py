"""Cheaper numerics at unchanged accuracy: integrators, steps and solver settings
against the default model at dt = 0.0625 ms.

The physics is the default preset's (servo law, contact parameters in absolute
units, geometry); a candidate changes only numerics (``CANDIDATES``). Per
candidate, on the same random valid pair configurations (|r| 0.8-2.0 W, 90 deg,
square gait, native backend, seed 0):

* labels: bound at the end (touched in the last of ``--periods`` periods),
  agreement with the reference and its exact (Clopper-Pearson) 95 % interval;
  the bound fraction against the reference's;
* lone drift: net displacement per gait cycle over 20 cycles at 90 and 10 deg;
* cost: wall seconds per simulated second per lane, measured as a ratio to the
  current default in one interleaved timing pass (``--timing``), so that the
  machine's load cancels.

Pass rule (stated before any candidate ran; docs/timestep.md): agreement lower
95 % bound >= 0.93, |bound fraction - reference| <= 0.02, lone drift at both
amplitudes within 20 % of the reference's or below 1.5e-5 W per cycle (1 % of
the paper's measured 1.5e-3), no lane non-finite or penetrating.

Resumable and staged: every (candidate, block of --block configurations) is
saved under ``--runs`` as soon as it finishes and reused; screen on a few
blocks, confirm on more:

    python benchmarks/timestep_candidates.py --candidates ref --configs 400          # the reference (~30 min)
    python benchmarks/timestep_candidates.py --candidates all --configs 100          # screen
    python benchmarks/timestep_candidates.py --candidates implicitfast-0.5ms --configs 400   # confirm
    python benchmarks/timestep_candidates.py --timing --candidates all               # cost ratios
    python benchmarks/timestep_candidates.py --table                                 # docs/timestep.md table
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import pathlib
import platform
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent

from smarticle_mjx import presets
from smarticle_mjx.reduce.gliders import glider_transport, steady_gliders
from smarticle_mjx.bench import NUMERICS, NUMERICS_REFERENCE, fixed_starts, save_json
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.gait import GaitSpec
from smarticle_mjx.reduce import transport
from smarticle_mjx.reduce.binding import binomial_interval

REFERENCE = NUMERICS_REFERENCE
CANDIDATES = NUMERICS  # name -> SceneParams changes (numerics only): smarticle_mjx/bench.py
BASELINE = "implicitfast-0.25ms"
CONFIRM = 400  # configurations a pass needs
PASS = dict(agree_lo=0.93, bound_diff=0.02, drift_rel=0.2, drift_floor=1.5e-5)


def params_of(name: str, model: str | None):
    p = presets.params(model).replace(**CANDIDATES[name])
    p.validate()
    return p


def sample(n: int, model: str | None, seed: int = 0) -> np.ndarray:
    return fixed_starts(presets.params(model), n, seed)


def run_block(params, poses, periods: int) -> dict:
    gait = GaitSpec(90.0)
    be = make_backend("native", Scene.build(params, 2))
    try:
        lanes = Lanes.from_gait(poses, gait)
        t = time.perf_counter()
        _, rec, _ = be.advance(be.initial_state(lanes), lanes, periods)
        wall = time.perf_counter() - t
    finally:
        be.close()
    return dict(touched=rec.touched[:, :, 0], end_poses=rec.poses[:, -1], status=rec.status, wall_s=np.float64(wall))


def lone_drift(params, amplitude: float, cycles: int = 20) -> float:
    gait = GaitSpec(amplitude)
    a = gait.setpoints(0.0, params.robot.servo_speed)
    r = simulate(params, [(0, 0, 0, a[0], a[1])], gait, periods=cycles + 2)
    return transport.lone_robot(r.poses[:, 0, :2], skip_cycles=2, unit=params.robot.body_length).net_W_per_cycle


def ensure_runs(names, args):
    runs = pathlib.Path(args.runs)
    runs.mkdir(parents=True, exist_ok=True)
    poses = sample(args.configs, args.model)
    nblock = (args.configs + args.block - 1) // args.block
    for b in range(nblock):  # block-major: every candidate reaches a size before any goes further
        sl = slice(b * args.block, min(args.configs, (b + 1) * args.block))
        for name in names:
            f = runs / f"{name}_p{args.periods}_b{b:03d}_{args.block}.npz"
            if f.exists():
                continue
            t = time.time()
            out = run_block(params_of(name, args.model), poses[sl], args.periods)
            tmp = f.with_name(f.stem + ".tmp.npz")
            np.savez(tmp, start_poses=poses[sl], **out)
            os.replace(tmp, f)
            print(f"{name} block {b} ({sl.stop - sl.start} configs): {time.time() - t:.0f} s, "
                  f"bound {out['touched'][:, -1].mean():.2f}", flush=True)


def load_runs(name, args):
    runs = pathlib.Path(args.runs)
    files = sorted(runs.glob(f"{name}_p{args.periods}_b*_{args.block}.npz"))
    if not files:
        return None
    d = [np.load(f) for f in files]
    blocks = [int(f.stem.split("_b")[1].split("_")[0]) for f in files]
    return dict(blocks=blocks, touched={b: x["touched"] for b, x in zip(blocks, d)},
                status={b: x["status"] for b, x in zip(blocks, d)},
                start={b: x["start_poses"] for b, x in zip(blocks, d)})


def compare(name, ref, args) -> dict | None:
    run = load_runs(name, args)
    if run is None:
        return None
    common = sorted(set(run["blocks"]) & set(ref["blocks"]))
    if not common:
        return None
    for b in common:  # both ran the same configurations
        if not np.array_equal(run["start"][b], ref["start"][b]):
            raise SystemExit(f"{name} block {b} ran other configurations than the reference; delete its runs")
    end = np.concatenate([run["touched"][b][:, -1] for b in common])
    end_ref = np.concatenate([ref["touched"][b][:, -1] for b in common])
    bad = int(sum((run["status"][b] != 0).sum() for b in common))
    k, n = int((end == end_ref).sum()), len(end)
    lo, hi = (float(x) for x in binomial_interval(k, n))
    return dict(n=n, agree=k / n, agree_lo=lo, agree_hi=hi, bound=float(end.mean()), bound_ref=float(end_ref.mean()),
                bound_diff=float(end.mean() - end_ref.mean()), status_bad=bad)


def drifts(names, args, res):
    for name in names:
        key = f"drift:{name}"
        if key in res:
            continue
        p = params_of(name, args.model)
        res[key] = {f"{a:g}": lone_drift(p, a) for a in (90.0, 10.0)}
        print(f"{name} lone drift (W/cycle): {res[key]}", flush=True)
        save_json(pathlib.Path(args.out), res)


def timing(names, args, res, repeats: int = 3, lanes: int = 32, periods: int = 2):
    """Interleaved passes over the same lanes: each candidate's wall time per simulated second per lane, and
    its ratio to the baseline's in the same pass (the machine's load cancels in the ratio)."""
    poses = sample(lanes, args.model, seed=1)
    gait = GaitSpec(90.0)
    walls = {n: [] for n in names}
    for _ in range(repeats):
        for name in names:
            out = run_block(params_of(name, args.model), poses, periods)
            walls[name].append(float(out["wall_s"]))
    sim_s = lanes * periods * gait.period()
    base = np.array(walls[BASELINE]) if BASELINE in walls else None
    for name in names:
        w = np.array(walls[name])
        row = dict(ms_per_sim_s_per_lane=1e3 * float(np.median(w)) / sim_s, lanes=lanes, periods=periods,
                   repeats=repeats)
        if base is not None:
            row["cost_vs_baseline"] = float(np.median(w / base))
        res[f"timing:{name}"] = row
        print(f"{name}: {row}", flush=True)
    save_json(pathlib.Path(args.out), res)


def _glider_tracks(path: pathlib.Path, burn_in: int = 10):
    z = np.load(path)
    return z["com"][steady_gliders(z["touched"], burn_in), burn_in:].astype(float)


def fidelity(names, args, res, n_boot: int = 400):
    """Glider quantities of the fidelity confirmation (128 starts x 100 periods at 90 deg, seed 1) with a
    candidate's numerics against the default's: the 95 % bootstrap interval (gliders resampled in both runs)
    of each difference must contain 0. Runs benchmarks/fidelity_screen.py --numerics first."""
    model = presets.get(args.model).name
    tracks = ROOT / "results" / "fidelity_tracks"
    ref_path = tracks / f"{model}_glide_128x100_s1.npz"
    if not ref_path.exists():
        raise SystemExit(f"no confirmation tracks of {model}: run benchmarks/fidelity_screen.py --models {model} "
                         "--pairs 128 --periods 100 --pb 0")
    g_ref = _glider_tracks(ref_path)
    q_ref = dataclasses.asdict(glider_transport(g_ref))
    rng = np.random.default_rng(0)
    for name in names:
        path = tracks / f"{model}~{name}_glide_128x100_s1.npz"
        if name == REFERENCE or not path.exists():
            continue
        g = _glider_tracks(path)
        q = dataclasses.asdict(glider_transport(g))
        diffs = {k: [] for k in q}
        for _ in range(n_boot):
            a = glider_transport(g[rng.integers(0, len(g), len(g))])
            b = glider_transport(g_ref[rng.integers(0, len(g_ref), len(g_ref))])
            for k in q:
                diffs[k].append(getattr(a, k) - getattr(b, k))
        row = dict(gliders=len(g), gliders_default=len(g_ref))
        for k in q:
            lo, hi = np.nanpercentile(diffs[k], [2.5, 97.5])
            row[k] = dict(candidate=q[k], default=q_ref[k], diff_lo=float(lo), diff_hi=float(hi),
                          agrees=bool(lo <= 0 <= hi))
        res[f"fidelity:{name}"] = row
        print(f"{name}: " + "; ".join(f"{k} {v['candidate']:.4g} vs {v['default']:.4g} "
                                      f"[{v['diff_lo']:+.3g}, {v['diff_hi']:+.3g}]" for k, v in row.items()
                                      if isinstance(v, dict)), flush=True)
    save_json(pathlib.Path(args.out), res)


def passes(row: dict, d: dict, d_ref: dict) -> dict:
    """The pass rule, criterion by criterion."""
    def drift_ok(a):
        x, r = d[a], d_ref[a]
        return abs(x - r) <= PASS["drift_rel"] * r or x <= PASS["drift_floor"]
    return dict(labels=row["agree_lo"] >= PASS["agree_lo"], bound=abs(row["bound_diff"]) <= PASS["bound_diff"] + 1e-9,
                drift=all(drift_ok(a) for a in d_ref), finite=row["status_bad"] == 0)


def table(res: dict, names) -> str:
    lines = ["| candidate | integrator | dt | configs | agreement [95 % exact] | bound fraction (cand. / ref.) | "
             "lone drift 90° · 10° (W/cycle) | glider quantities vs default | cost ms per sim-s per lane | "
             "cost vs 0.25 ms | passes |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    d_ref = res.get(f"drift:{REFERENCE}")
    for name in names:
        c = CANDIDATES[name]
        row = res.get(f"labels:{name}")
        d = res.get(f"drift:{name}")
        tm = res.get(f"timing:{name}", {})
        extra = ", ".join(f"{k} {v:g}" for k, v in c.items() if k not in ("timestep", "integrator"))
        integ = c.get("integrator", "implicitfast") + (f" ({extra})" if extra else "")
        lab = (f"{row['agree']:.3f} [{row['agree_lo']:.3f}, {row['agree_hi']:.3f}]" if row and name != REFERENCE
               else "reference" if name == REFERENCE else "—")
        bnd = f"{row['bound']:.3f} / {row['bound_ref']:.3f}" if row else "—"
        dr = f"{d['90']:.1e} · {d['10']:.1e}" if d else "—"
        cost = f"{tm['ms_per_sim_s_per_lane']:.1f}" if tm else "—"
        ratio = f"{tm['cost_vs_baseline']:.2f}" if "cost_vs_baseline" in tm else "—"
        fid = res.get(f"fidelity:{name}")
        fcell = "—" if not fid else ("agree" if all(v["agrees"] for v in fid.values() if isinstance(v, dict)) else
                                     "differ: " + ", ".join(k for k, v in fid.items()
                                                            if isinstance(v, dict) and not v["agrees"]))
        if name == REFERENCE:
            verdict = "—"
        elif row and d and d_ref:
            ok = passes(row, d, d_ref)
            failed = [k for k, v in ok.items() if not v]
            if fid and not all(v["agrees"] for v in fid.values() if isinstance(v, dict)):
                failed.append("gliders")
            if row["n"] < CONFIRM:  # a screen: the label bound needs the confirmation's size
                failed = [f for f in failed if f != "labels"]
                verdict = "screened only" + (" (fails " + ", ".join(failed) + ")" if failed else "")
                lines.append(f"| `{name}` | {integ} | {c['timestep'] * 1e3:g} ms | {row['n']} | {lab} | {bnd} | "
                             f"{dr} | {fcell} | {cost} | {ratio} | {verdict} |")
                continue
            verdict = ("**yes**" + ("" if fid else " (labels, drift)")) if not failed else "no (" + ", ".join(failed) + ")"
        else:
            verdict = "—"
        lines.append(f"| `{name}` | {integ} | {c['timestep'] * 1e3:g} ms | {row['n'] if row else '—'} | {lab} | {bnd} | "
                     f"{dr} | {fcell} | {cost} | {ratio} | {verdict} |")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--candidates", default="all", help="comma-separated names, or 'all'; known: " + ", ".join(CANDIDATES))
    ap.add_argument("--configs", type=int, default=100)
    ap.add_argument("--block", type=int, default=50)
    ap.add_argument("--periods", type=int, default=20)
    ap.add_argument("--model", default=None, help="preset (default: the default model)")
    ap.add_argument("--timing", action="store_true", help="measure cost ratios instead of labels")
    ap.add_argument("--fidelity", action="store_true",
                    help="compare glider quantities (after benchmarks/fidelity_screen.py --numerics NAME)")
    ap.add_argument("--table", action="store_true", help="print the table from the JSON and the saved runs")
    ap.add_argument("--runs", default=str(ROOT / "results" / "timestep_runs"))
    ap.add_argument("--out", default=str(ROOT / "results" / "timestep_candidates.json"))
    args = ap.parse_args()

    names = list(CANDIDATES) if args.candidates == "all" else [n.strip() for n in args.candidates.split(",")]
    unknown = [n for n in names if n not in CANDIDATES]
    if unknown:
        raise SystemExit(f"unknown candidate(s) {', '.join(unknown)}; known: {', '.join(CANDIDATES)}")
    if not args.table:  # a candidate SceneParams now refuses (its measurement stays in the JSON and the table)
        refused = []
        for n in names:
            try:
                params_of(n, args.model)
            except ValueError as e:
                refused.append(n)
                print(f"skipping {n}: {e}")
        names = [n for n in names if n not in refused]
    out = pathlib.Path(args.out)
    res = json.loads(out.read_text()) if out.exists() else {}
    res["meta"] = dict(model=presets.get(args.model).name, periods=args.periods, block=args.block,
                       r_range_W=[0.8, 2.0], amplitude_deg=90.0, seed=0, pass_rule=PASS, machine=platform.node(),
                       cpus=os.cpu_count())
    if args.fidelity:
        fidelity(names, args, res)
        return
    if args.timing:
        timing([n for n in names if n != REFERENCE] if BASELINE in names else names, args, res)
        return
    if not args.table:
        ensure_runs(names, args)
        drifts(names, args, res)
    ref = load_runs(REFERENCE, args)
    if ref is None:
        raise SystemExit("no reference runs yet: run --candidates ref first")
    for name in names:
        row = compare(name, ref, args)
        if row is not None:
            res[f"labels:{name}"] = row
    save_json(out, res)
    print(table(res, names))


if __name__ == "__main__":
    main()
