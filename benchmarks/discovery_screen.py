"""The discovery experiment's diagnosis screen: seven robots from a compressed start, one physical
choice switched at a time (sweeps/screens/discovery.toml, written before it ran; later stages appended
to it, each saying why).

Per variant: one relaxation store of T trials x K periods (resumable: a complete store of the same
configuration is reused, an interrupted one resumed), then the crowd's measures
(reduce.relaxation.crowd: area-fraction plateau, chain lifetime, neighbours, loops), the contact rule's
relaxation time, trials the engine flagged, and pairs that stayed bound and apart >= 30 periods (a
screen-length indicator, not the lab's 100-period glider). Intervals: 95 % bootstrap over trials
(medians and pooled means), exact binomial for counts.

  python benchmarks/discovery_screen.py                      # every variant of the study file
  python benchmarks/discovery_screen.py --only baseline,lab  # some of them
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
import tomllib

import numpy as np

from smarticle_mjx import presets
from smarticle_mjx.bench import save_json
from smarticle_mjx.labels import BAD_STATUS
from smarticle_mjx.reduce import binding, relaxation as RX
from smarticle_mjx.studyfile import read_relax_screen
from smarticle_mjx import formatting
from smarticle_mjx.store import read_relax
from smarticle_mjx.studies import ensure_relax

ROOT = pathlib.Path(__file__).resolve().parent
APART_PERIODS = 30  # the screen's bound-and-apart indicator (fixed with the study file)


def _boot(values_per_trial, stat, rng, n=2000) -> tuple[float, float]:
    """95 % bootstrap interval of ``stat`` over trials (each a list of values)."""
    t = len(values_per_trial)
    if t == 0:
        return float("nan"), float("nan")
    out = []
    for _ in range(n):
        pick = rng.integers(0, t, t)
        v = np.concatenate([np.asarray(values_per_trial[i], float) for i in pick])
        out.append(stat(v) if len(v) else np.nan)
    lo, hi = np.nanpercentile(out, [2.5, 97.5])
    return float(lo), float(hi)


def measure(data: dict, seed: int = 0) -> dict:
    """The screen's numbers of one variant's store."""
    rng = np.random.default_rng(seed)
    summary, trials = RX.crowd(data)
    flagged = int(((np.asarray(data.status) & int(BAD_STATUS)) != 0).sum())
    usable = len(trials)
    a = RX.analyse_relaxation(data, min_periods=APART_PERIODS)
    apart = a.emerged
    # the lab's own rule (bound and apart >= 100 periods), where the trials are long enough for it
    lab_rule = RX.analyse_relaxation(data, min_periods=100).emerged if int(np.max(data.periods_run)) >= 100 else None
    plateau = [[np.nan if t.plateau.censored else t.plateau.period] for t in trials]
    plateau_c = [[t.plateau.period] for t in trials]  # censored ones at their (lower-bound) end
    chains = [[e.lifetime for e in t.chains] for t in trials]
    deg = [t.chain_degrees() for t in trials]
    contact = [[t.contact_relaxation[0]] for t in trials]
    moved = []
    for i in np.flatnonzero(data.usable):
        k = int(data.periods_run[i])
        d = np.linalg.norm(data.poses[i][k - 1, :, :2] - data.start_poses[i][:, :2], axis=1)
        moved.append([float(d.mean() / data.body_length)])
    lo, hi = binding.binomial_interval(apart, usable) if usable else (np.nan, np.nan)
    # the deepest robot-robot penetration of each trial (flagged ones included) and, for flagged
    # trials, the first period past the 2 mm flag: a tail of the depth distribution or a cliff?
    md = np.asarray(data.min_dist, float)  # [T, K, P] m, +inf without contact
    md = np.where(np.isfinite(md), md, np.inf)
    depth_mm = -1e3 * np.minimum(md.min(axis=(1, 2)), 0.0)
    first_flag = [int(np.argmax((md[i] < -2e-3).any(-1))) + 1 for i in range(len(md)) if (md[i] < -2e-3).any()]
    # pairs inside the crowd (reduce.relaxation.pair_runs; added after the first screens, defined before it ran
    # on any of them): runs >= 10 periods in which a pair touched only itself, how fast its centre moved,
    # whether it drew away from the nearest third robot, and what ended the run
    pr, per_trial = RX.crowd_pairs(data)
    rng_pairs = np.random.default_rng(seed + 1)  # its own stream: the other rows' intervals stay as they were
    pairs = {"runs": pr.runs, "trials_with_run": pr.trials_with_run, "length_median": pr.length.median,
             "length_censored": pr.length.censored, "speed_median": pr.speed.median,
             "speed_median_ci": _boot([[q.speed for q in t] for t in per_trial], np.median, rng_pairs),
             "escape_median": pr.escape.median,
             "escape_median_ci": _boot([[q.escape for q in t if np.isfinite(q.escape)] for t in per_trial],
                                       np.median, rng_pairs),
             "gap_end_max": max((q.gap_end for t in per_trial for q in t if np.isfinite(q.gap_end)),
                                default=float("nan")),
             "ended_by": pr.ended_by,
             # which kind of pair (PairRun.kind, added after the first rows were measured)
             "kinds": {k: sum(1 for t in per_trial for q in t if q.kind == k) for k in ("C1", "C2")},
             "speed_median_by_kind": {k: float(np.median(v)) if (v := [q.speed for t in per_trial for q in t
                                                                         if q.kind == k]) else float("nan")
                                      for k in ("C1", "C2")}}
    return {
        "pairs": pairs,
        "depth_mm_median": float(np.median(depth_mm)), "depth_mm_max": float(depth_mm.max()),
        "depth_mm": [float(x) for x in depth_mm], "first_flag_period": first_flag,
        "trials": int(len(data.valid)), "flagged": flagged, "usable": usable,
        "plateau_median": summary.plateau.median, "plateau_ci": _boot(plateau_c, np.median, rng),
        "plateau_censored": summary.plateau.censored,
        "phi_start": summary.phi_start.median, "phi_plateau": summary.phi_plateau.median,
        "phi_creep": summary.phi_creep.median,
        "chain_lifetime_median": summary.chain_lifetime.median, "chain_lifetime_mean": summary.chain_lifetime.mean,
        "chain_lifetime_mean_ci": _boot(chains, np.mean, rng), "chains": summary.chain_lifetime.n,
        "chains_censored": summary.chain_lifetime.censored,
        "neighbours_in_chain": summary.neighbours_in_chain, "neighbours_in_chain_ci": _boot(deg, np.mean, rng),
        "loop_fraction": summary.loop_fraction, "chained_at_end": summary.chained_at_end,
        "contact_relaxation_median": summary.contact_relaxation.median,
        "contact_relaxation_ci": _boot(contact, np.median, rng),
        "apart_30": apart, "apart_30_ci": (float(lo), float(hi)), "apart_100": lab_rule,
        "moved_W": float(np.mean([m[0] for m in moved])) if moved else float("nan"),
        "moved_W_ci": _boot(moved, np.mean, rng),
        "plateau_values": [p[0] for p in plateau],
    }


def f(x, nd=1):
    return formatting.num(x, f".{nd}f")


def table(rows: dict, screen: dict) -> list[str]:
    out = [f"Screen: {screen['trials']} trials x {screen['periods']} periods per variant, seed {screen['seed']}, "
           f"{screen['amplitude_deg']:g} deg; medians with 95 % bootstrap intervals over trials.", "",
           "| variant | flagged | φ start → plateau | plateau start (periods) | chain lifetime mean (periods) | "
           "neighbours in chain | loops | contact relaxation | chained at end | apart ≥ 30 | moved (W) |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in rows.items():
        pc, cc, nc, rc, mc = (r["plateau_ci"], r["chain_lifetime_mean_ci"], r["neighbours_in_chain_ci"],
                              r["contact_relaxation_ci"], r["moved_W_ci"])
        out.append(
            f"| {name} | {r['flagged']}/{r['trials']} | {f(r['phi_start'], 2)} → {f(r['phi_plateau'], 2)} | "
            f"{f(r['plateau_median'], 0)} [{f(pc[0], 0)}, {f(pc[1], 0)}] ({r['plateau_censored']} none) | "
            f"{f(r['chain_lifetime_mean'])} [{f(cc[0])}, {f(cc[1])}] (n {r['chains']}) | "
            f"{f(r['neighbours_in_chain'], 2)} [{f(nc[0], 2)}, {f(nc[1], 2)}] | {f(100 * r['loop_fraction'], 0)} % | "
            f"{f(r['contact_relaxation_median'], 0)} [{f(rc[0], 0)}, {f(rc[1], 0)}] | "
            f"{r['chained_at_end']}/{r['usable']} | {r['apart_30']}/{r['usable']} | "
            f"{f(r['moved_W'], 2)} [{f(mc[0], 2)}, {f(mc[1], 2)}] |")
    return out


def pair_table(rows: dict) -> list[str]:
    """Pairs inside the crowd: runs of >= 10 periods in which a pair touched only itself."""
    out = ["| variant | runs (trials with one) | C1 / C2 | length median (censored) | speed median (W/period) | "
           "speed median C1 · C2 | escape median (W/period) | largest gap at a run's end (W) | ended by a third "
           "robot / unbinding / plate / trial's end | apart ≥ 100 (the lab's rule) |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for name, r in rows.items():
        p = r.get("pairs")
        if not p:
            continue
        sc, ec, e = p["speed_median_ci"], p["escape_median_ci"], p["ended_by"]
        kd, sk = p.get("kinds", {}), p.get("speed_median_by_kind", {})
        out.append(f"| {name} | {p['runs']} ({p['trials_with_run']}/{r['usable']}) | {kd.get('C1', '–')} / "
                   f"{kd.get('C2', '–')} | {f(p['length_median'], 0)} "
                   f"({p['length_censored']}) | {f(p['speed_median'], 4)} [{f(sc[0], 4)}, {f(sc[1], 4)}] | "
                   f"{f(sk.get('C1'), 4)} · {f(sk.get('C2'), 4)} | "
                   f"{f(p['escape_median'], 4)} [{f(ec[0], 4)}, {f(ec[1], 4)}] | {f(p['gap_end_max'], 2)} | "
                   f"{e['third']} / {e['unbound']} / {e['plate']} / {e['end']} | "
                   + (f"{r['apart_100']}/{r['usable']} |" if r.get("apart_100") is not None else "– |"))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--study", type=pathlib.Path, default=ROOT.parent / "sweeps" / "screens" / "discovery.toml")
    ap.add_argument("--only", default=None, help="comma-separated variant names")
    ap.add_argument("--stores", type=pathlib.Path, default=ROOT.parent / "out" / "discovery_screen")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "discovery_screen.json")
    ap.add_argument("--model", default=presets.DEFAULT)
    args = ap.parse_args(argv)
    try:
        screen, studies = read_relax_screen(args.study)
    except ValueError as e:
        sys.exit(f"error: {e}")
    raw = tomllib.loads(args.study.read_text())["variant"]
    variants = [dict(v) for v in raw]
    names = list(studies)
    only = set(args.only.split(",")) if args.only else set(names)
    if only - set(names):
        sys.exit(f"error: unknown variants {sorted(only - set(names))}")
    args.stores.mkdir(parents=True, exist_ok=True)
    res = json.loads(args.out.read_text()) if args.out.exists() else {}
    res.setdefault("variants", {})
    res.update(screen=screen, model=args.model, study=str(args.study.resolve().relative_to(ROOT.parent)))
    for v in variants:
        if v["name"] not in only:
            continue
        t0 = time.perf_counter()
        try:
            paths = ensure_relax(studies[v["name"]], v["name"], args.stores, args.model)
        except ValueError as e:  # a variant the model refuses is reported, the others still run
            print(f"{v['name']}: refused: {e}", flush=True)
            res["variants"][v["name"]] = {"refused": str(e), "variant": {k: val for k, val in v.items() if k != "name"}}
            save_json(args.out, res)
            continue
        row = measure(read_relax(paths))
        row.update(variant={k: val for k, val in v.items() if k != "name"}, wall_s=time.perf_counter() - t0)
        res["variants"][v["name"]] = row
        save_json(args.out, res)
        print(f"{v['name']}: done in {row['wall_s']:.0f} s", flush=True)
    rows = {n: res["variants"][n] for n in names if n in res["variants"] and "refused" not in res["variants"][n]}
    print("\n".join(table(rows, screen)))
    print()
    print("\n".join(pair_table(rows)))


if __name__ == "__main__":
    main()
