"""The loop on the lab's numbers (#93 item 2): each candidate of plan.toml scored on the training numbers
(screen), then the chosen ones at full size on the held-out numbers (``--full NAME``). Research script: it
reads plan.toml (committed before any run) and writes screen.json / full_<name>.json beside it.

  python notebook/lab_candidates/run.py                    # the screen, every candidate (resumable)
  python notebook/lab_candidates/run.py --only baseline    # some of them
  python notebook/lab_candidates/run.py --full baseline    # one candidate at full size, held-out numbers

Stores go to out/lab_candidates/ (complete stores of the same configuration are reused, interrupted ones
resumed). The scan and the lone robots of a candidate whose changes are all relaxation keys are the
baseline's (same configuration: the same store is reused).
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
import time
import tomllib

import numpy as np

from smarticle_mjx import presets
from smarticle_mjx.bench import save_json
from smarticle_mjx.reduce import chains as CH, emergence as EM, relaxation as RX, spreading as SP
from smarticle_mjx.report import analyse_store_run
from smarticle_mjx.specs import ScanConfig
from smarticle_mjx.store import Store, read_relax
from smarticle_mjx.studies import ensure_relax, ensure_scan
from smarticle_mjx.studyfile import read_relax_screen
from smarticle_mjx.validate import evidence, single_robots

HERE = pathlib.Path(__file__).resolve().parent
PLAN = HERE / "plan.toml"
LAB_DRIFT, LAB_BETA, BETA_SCALE, LAB_TAU = 1.5e-3, 1.8, 0.3, 10.0
FULL_STAGES, FULL_TRIALS, FULL_PERIODS, FULL_FIRST = 5, 20, 300, 20000  # the recount's stages
FULL_SCAN_N = 400  # the validation page's random study


def _settings(rs) -> dict:
    return dict(rs.settings)


def scan_config(plan: dict, settings: dict, n: int | None = None) -> ScanConfig:
    """The candidate's random scan at 90 deg: the plan's [scan] size, its imperfections and scene overrides."""
    sc = plan["scan"]
    return ScanConfig(configs="random", n=int(n or sc["n"]), amplitudes_deg=(90.0,), periods=int(sc["periods"]),
                      seed=0, imperfections=settings.get("imperfections", "none"),
                      overrides=tuple(settings.get("overrides", ())), robot_draws=int(sc["robot_draws"]),
                      robot_seed=int(sc["robot_seed"]), model=presets.DEFAULT)


def _scan_path(out: pathlib.Path, cfg: ScanConfig) -> pathlib.Path:
    key = "".join(f"~{k}={v}" for k, v in cfg.overrides)
    return out / "scans" / f"random{cfg.n}_{cfg.imperfections}{key}.h5"


def lone_drift(settings: dict) -> tuple[float, int]:
    """Mean net drift (W/cycle) of the candidate's lone robots at 90 deg, 75 cycles, and how many robots."""
    params = presets.apply(presets.params(presets.DEFAULT), tuple(settings.get("overrides", ())))
    singles = single_robots(params, amplitudes=(90,), periods=75, imperfections=settings.get("imperfections", "none"))
    ld = evidence.lone_robots(singles)[90.0]
    return float(ld.robot.net_W_per_cycle), int(ld.robots)


def beta_of(path: pathlib.Path) -> dict:
    st = Store(path)
    a = analyse_store_run(st, st.runs[0])
    if a.transport is None:
        return {"beta": float("nan"), "lo": float("nan"), "hi": float("nan"), "gliders": 0}
    b = a.transport.beta
    return {"beta": float(b.beta), "lo": float(b.lo), "hi": float(b.hi), "gliders": int(a.transport.gliders)}


def spreading_of(paths) -> dict:
    data = read_relax([str(p) for p in paths])
    _, crowd = RX.crowd(data)
    times = SP.study_spreading(data, crowd)
    return {"phi_tau_median": float(times.phi_tau.median), "phi_tau_n": int(times.phi_tau.n),
            "phi_at_bound": int(times.phi_at_bound), "first_period_share": float(times.first_period_share.median),
            "trials": int(data.usable.sum())}


def errors(drift: float, beta: float, tau: float) -> dict:
    e = {"e_drift": abs(math.log10(drift / LAB_DRIFT)) if drift > 0 else float("inf"),
         "e_beta": abs(beta - LAB_BETA) / BETA_SCALE if np.isfinite(beta) else float("inf"),
         "e_tau": abs(math.log10(tau / LAB_TAU)) if np.isfinite(tau) and tau > 0 else float("inf")}
    e["score"] = e["e_drift"] + e["e_beta"] + e["e_tau"]
    return e


def screen(plan: dict, variants: dict, only, out: pathlib.Path) -> dict:
    results = {}
    for name, rs in variants.items():
        if only and name not in only:
            continue
        t0 = time.perf_counter()
        s = _settings(rs)
        (out / "relax").mkdir(parents=True, exist_ok=True)
        paths = ensure_relax(rs, name, out / "relax", presets.DEFAULT)
        spread = spreading_of(paths)
        cfg = scan_config(plan, s)
        spath = _scan_path(out, cfg)
        spath.parent.mkdir(parents=True, exist_ok=True)
        ensure_scan(cfg, spath)
        beta = beta_of(spath)
        drift, robots = lone_drift(s)
        sources = {**plan["sources"], **plan["sources"].get("more", {}), **plan["sources"].get("onset", {})}
        results[name] = {"settings": {k: v for k, v in s.items()}, "source": sources.get(name, ""),
                         "lone_drift_W_per_cycle": drift, "lone_robots": robots, "beta": beta, "spreading": spread,
                         "scan_store": spath.name, **errors(drift, beta["beta"], spread["phi_tau_median"]),
                         "wall_s": time.perf_counter() - t0}
        r = results[name]
        print(f"{name:<24} drift {drift:.2e} beta {beta['beta']:.2f} [{beta['lo']:.2f}, {beta['hi']:.2f}] "
              f"({beta['gliders']}) tau {spread['phi_tau_median']:.1f} (n {spread['phi_tau_n']}) -> e_drift "
              f"{r['e_drift']:.2f} e_beta {r['e_beta']:.2f} e_tau {r['e_tau']:.2f} score {r['score']:.2f} "
              f"({r['wall_s']:.0f} s)", flush=True)
    return results


def full(plan: dict, variants: dict, name: str, out: pathlib.Path) -> dict:
    """One candidate at full size: the recount's 5 stages of 20 trials x 300 periods, and a 400-start scan;
    the held-out numbers (and the training ones again at that size)."""
    from smarticle_mjx.specs import RelaxStudy
    from smarticle_mjx.validate.claims import get as claim
    rs = variants[name]
    s = {k: v for k, v in _settings(rs).items() if k not in ("periods",)}
    s.update(periods=FULL_PERIODS, first_trial=FULL_FIRST)
    study = RelaxStudy(stages=FULL_STAGES, trials=FULL_TRIALS, settings=tuple(sorted(s.items())))
    t0 = time.perf_counter()
    (out / "full").mkdir(parents=True, exist_ok=True)
    paths = ensure_relax(study, f"full_{name}", out / "full", presets.DEFAULT)
    data = read_relax([str(p) for p in paths])
    em = EM.emergence(data)
    prim = em.of(em.primary)
    lt = CH.study_chains(data)
    cfg = scan_config(plan, _settings(rs), n=FULL_SCAN_N)
    spath = _scan_path(out, cfg)
    spath.parent.mkdir(parents=True, exist_ok=True)
    ensure_scan(cfg, spath)
    st = Store(spath)
    a90 = analyse_store_run(st, st.runs[0])
    c1 = claim("c1_lifetime").measure(a90)
    res = {"candidate": name, "trials": int(data.usable.sum()), "flagged": int((~data.usable).sum()),
           "emergence_d": {"emerged": prim.emerged, "trials": prim.trials, "fraction": prim.fraction,
                           "interval": list(prim.interval), "fisher_p": prim.fisher_p,
                           "overlaps_lab": bool(prim.interval[0] <= 0.59 and prim.interval[1] >= 0.43)},
           "distance": {"mean": prim.distance.mean, "sem": prim.distance.sem, "n": prim.distance.n,
                        "within_2_sigma": bool(prim.distance.n and abs(prim.distance.mean - 2.9)
                                               <= 2 * math.hypot(prim.distance.sem if np.isfinite(prim.distance.sem)
                                                                 else 0.0, 0.2))},
           "chain_lifetime_overlap": {"mean": lt.overlap.mean, "median": lt.overlap.median,
                                      "within_2x_of_8_10": bool(4 <= lt.overlap.mean <= 20)},
           "c1_outlives_c2": {"holds": c1.holds, "measured": c1.measured},
           "training_at_full_size": {"spreading": spreading_of(paths), "beta": beta_of(spath)},
           "wall_s": time.perf_counter() - t0}
    print(json.dumps(res, indent=1, default=float))
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", help="comma-separated candidates (default: all)")
    ap.add_argument("--full", help="run this candidate at full size and read the held-out numbers")
    ap.add_argument("--out", default="out/lab_candidates", help="folder of the stores")
    args = ap.parse_args(argv)
    plan = tomllib.loads(PLAN.read_text())
    _, variants = read_relax_screen(PLAN)
    out = pathlib.Path(args.out)
    only = [x.strip() for x in args.only.split(",")] if args.only else None
    bad = [x for x in (only or []) + ([args.full] if args.full else []) if x not in variants]
    if bad:
        print(f"error: unknown candidates {bad}; known: {', '.join(variants)}", file=sys.stderr)
        return 2
    if args.full:
        save_json(HERE / f"full_{args.full}.json", full(plan, variants, args.full, out))
        return 0
    res = screen(plan, variants, only, out)
    target = HERE / "screen.json"
    prev = json.loads(target.read_text())["candidates"] if target.exists() else {}
    prev.update(res)
    ranked = sorted(prev, key=lambda k: prev[k]["score"])
    save_json(target, {"plan": "notebook/lab_candidates/plan.toml", "candidates": prev, "ranked": ranked})
    print("ranked by training score:", ", ".join(f"{k} {prev[k]['score']:.2f}" for k in ranked))
    return 0


if __name__ == "__main__":
    sys.exit(main())
