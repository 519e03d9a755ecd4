"""The discovery recounted the paper's way (docs/relax.md, "The discovery read the paper's way"; the readings
and this plan were committed before it ran).

Reads the confirmation's stores (sweeps/discovery_confirm_delays.toml: five stages of 20 trials x 300
periods, `lab-resync` robots, start delays), first checks that they reproduce the recorded result of the
old rule trial by trial (results/discovery_confirm_delays.json: 17/100 and 264 episodes), and only then
counts every emergence reading (reduce.emergence), chains by exact member set and by overlap
(reduce.chains) and the spreading time constants (reduce.spreading). Stages not yet simulated are left out
and named: the study completes across runs (each stage is its own resumable store).

  for k in 0 1 2 3 4; do smx relax --model lab-lag --imperfections lab-resync --trials 20 \\
      --first-trial $((20*k)) --periods 300 --out out/discovery_confirm_delays/stage$k.h5 --quiet; done
  python benchmarks/discovery_recount.py                 # -> results/discovery_recount.json
  python benchmarks/discovery_recount.py --check-only    # the reproduction check alone

Exit 1 (and no reading printed) when a stage does not reproduce the recorded trials.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys
import time

import numpy as np

from smarticle_mjx.bench import save_json
from smarticle_mjx.reduce import chains as CH
from smarticle_mjx.reduce import emergence as EM
from smarticle_mjx.reduce import relaxation as RX
from smarticle_mjx.reduce import spreading as SP
from smarticle_mjx.report import lab_relax_fraction
from smarticle_mjx.store import read_relax

ROOT = pathlib.Path(__file__).resolve().parent
STAGES = 5
INT_KEYS = ("pair", "start", "lifetime", "censored", "kind", "trial")


def _episode_key(e: dict) -> tuple:
    return tuple(tuple(e[k]) if isinstance(e[k], (list, tuple)) else e[k] for k in INT_KEYS)


def reproduce(a: RX.RelaxAnalysis, ref: dict, trials: set[int]) -> dict:
    """Compare the old rule's per-trial rows and episodes with the recorded ones over ``trials``: every
    integer equal, every distance and contour length to 1e-9 relative."""
    got_eps = {_episode_key({k: getattr(e, k) for k in INT_KEYS}): e for e in a.episodes}
    ref_eps = [e for e in ref["episodes"] if e["trial"] in trials]
    missing = [e for e in ref_eps if _episode_key(e) not in got_eps]
    extra = len(got_eps) - (len(ref_eps) - len(missing))
    worst = 0.0
    for e in ref_eps:
        g = got_eps.get(_episode_key(e))
        if g is not None:
            for k in ("distance_W", "contour_W"):
                worst = max(worst, abs(getattr(g, k) - e[k]) / max(abs(e[k]), 1e-12))
    ref_rows = {r["trial"]: r for r in ref["per_trial"] if r["trial"] in trials}
    rows_differ = []
    for r in a.per_trial:
        q = ref_rows.get(r.trial)
        mine = (r.gliders, r.relaxation_periods, r.crowded_at_end, r.periods_run,
                None if r.glider is None else (tuple(r.glider.pair), r.glider.start, r.glider.lifetime))
        theirs = None if q is None else (q["gliders"], q["relaxation_periods"], q["crowded_at_end"], q["periods_run"],
                                         None if q["glider"] is None else
                                         (tuple(q["glider"]["pair"]), q["glider"]["start"], q["glider"]["lifetime"]))
        if mine != theirs:
            rows_differ.append(r.trial)
    ok = not missing and extra == 0 and not rows_differ and worst < 1e-9 and len(ref_rows) == len(a.per_trial)
    return {"trials": len(trials), "episodes_recorded": len(ref_eps), "episodes_missing": len(missing),
            "episodes_extra": int(extra), "rows_differ": rows_differ, "max_rel_diff": worst,
            "emerged": a.emerged, "emerged_recorded": sum(1 for r in ref_rows.values() if r["glider"] is not None),
            "reproduced": bool(ok)}


def _sigma(mean: float, sem: float, lab: float = 2.9, lab_sem: float = 0.2) -> float:
    """|model - lab| in units of the two standard errors combined."""
    return abs(mean - lab) / math.hypot(sem if np.isfinite(sem) else 0.0, lab_sem)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stores", default="out/discovery_confirm_delays", help="folder of stage0.h5 .. stage4.h5")
    ap.add_argument("--reference", default=str(ROOT / "results" / "discovery_confirm_delays.json"))
    ap.add_argument("--out", default=str(ROOT / "results" / "discovery_recount.json"))
    ap.add_argument("--check-only", action="store_true", help="the reproduction check alone")
    args = ap.parse_args(argv)
    folder = pathlib.Path(args.stores)
    paths = [folder / f"stage{k}.h5" for k in range(STAGES)]
    have = [p for p in paths if p.exists()]
    if not have:
        print(f"error: no stage store in {folder} (run the stages first: see this script's docstring)", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    data = read_relax([str(p) for p in have])
    ref = json.loads(pathlib.Path(args.reference).read_text())
    a = RX.analyse_relaxation(data)
    trials = {int(t) for t in data.trial}
    rep = reproduce(a, ref, trials)
    print(f"stages {[p.name for p in have]} ({len(trials)} trials); rule (a) {rep['emerged']} gliders "
          f"(recorded {rep['emerged_recorded']}); episodes recorded {rep['episodes_recorded']}, missing "
          f"{rep['episodes_missing']}, extra {rep['episodes_extra']}; rows differing {rep['rows_differ']}; "
          f"largest relative distance difference {rep['max_rel_diff']:.1e}: "
          f"{'reproduced' if rep['reproduced'] else 'NOT reproduced'}")
    out = {"stores": [str(p) for p in have], "missing_stages": [p.name for p in paths if not p.exists()],
           "package": data.settings.get("package") or ref.get("package"), "model": data.model,
           "imperfections": data.settings.get("imperfections"), "reproduction": rep}
    if not rep["reproduced"] or args.check_only:
        if not rep["reproduced"]:
            out["note"] = "the stores do not reproduce the recorded trials: no reading counted"
            save_json(args.out, out)
        return 0 if rep["reproduced"] else 1
    em = EM.emergence(data)
    usable = np.flatnonzero(data.usable)
    lt = CH.study_chains(data)
    _, crowd = RX.crowd(data)
    phi = [SP.phi_spreading(c.phi) for c in crowd]
    cont = [SP.fit_decay(SP.contacts_per_period(data.touched[t], data.periods_run[t]), t0=1) for t in usable]
    times = SP.spreading_times(phi, cont)
    plateau = RX.crowd_summary(crowd).plateau
    prim = em.of(em.primary)
    _, (lab_lo, lab_hi) = lab_relax_fraction()
    out.update({
        "trials": a.trials, "usable": a.valid, "flagged": a.trials - a.valid,
        "emergence": em.as_json(),
        "chains": {"overlap": vars(lt.overlap), "exact": vars(lt.exact), "overlap_changes": vars(lt.overlap_changes)},
        "spreading": {"plateau": vars(plateau), "phi_tau": vars(times.phi_tau), "phi_at_bound": times.phi_at_bound,
                      "phi_first_period_share": vars(times.first_period_share),
                      "contacts_tau": vars(times.contacts_tau), "contacts_at_bound": times.contacts_at_bound,
                      "per_trial": [{"trial": int(data.trial[t]), "phi_tau": p.fit.tau, "phi_at_bound": p.fit.at_bound,
                                     "phi_first_share": p.first_period_share, "contacts_tau": c.tau,
                                     "contacts_at_bound": c.at_bound} for t, p, c in zip(usable, phi, cont)]},
        "targets": {
            "emergence_overlaps_lab": bool(prim.interval[0] <= lab_hi and prim.interval[1] >= lab_lo),
            "distance_sigma": {r.reading.value: _sigma(r.distance.mean, r.distance.sem) for r in em.readings
                               if r.distance.n},
            "chain_overlap_mean_within_2x": bool(4 <= lt.overlap.mean <= 20)},
        "wall_s": time.perf_counter() - t0})
    save_json(args.out, out)
    print(f"{'reading':<70} {'emerged':>9} {'fraction [95 %]':>20} {'Fisher p':>9} {'distance W':>14}")
    for r in em.readings:
        star = " (primary)" if r.reading is em.primary else ""
        print(f"{r.reading.label + star:<70} {r.emerged:>4}/{r.trials:<4} {r.fraction:6.2f} "
              f"[{r.interval[0]:.2f}, {r.interval[1]:.2f}] {r.fisher_p:9.1e} "
              f"{r.distance.mean:6.2f} ± {r.distance.sem:4.2f}")
    print(f"{a.trials} trials, {a.trials - a.valid} flagged by the engine")
    print(f"chains: overlap mean {lt.overlap.mean:.1f} median {lt.overlap.median:.0f} (n {lt.overlap.n}, "
          f"{lt.overlap.censored} censored); exact mean {lt.exact.mean:.1f} median {lt.exact.median:.0f} (n {lt.exact.n})")
    print(f"spreading: plateau median {plateau.median:.0f}; phi tau median {times.phi_tau.median:.1f} "
          f"(n {times.phi_tau.n}, {times.phi_at_bound} unresolved), first period's share "
          f"{times.first_period_share.median:.2f}; contacts tau median {times.contacts_tau.median:.1f} "
          f"(n {times.contacts_tau.n}, {times.contacts_at_bound} unresolved)")
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
