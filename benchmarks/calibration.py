"""Calibration on data with hidden effects: is the right effect named, is the
truth inside the interval, how much does the held-out error fall, and how
often is an effect added to clean data.

Two suites:
* ``synth``: data the library's own model made (``smx synth``), calibrated
  with ``--no-nominal`` (the structural stage alone);
* ``mismatch``: data an independent MuJoCo smarticle made
  (smarticle_mjx/calibrate/independent.py: other arm shape, masses, hinge, servo law,
  time step), calibrated as a user would (nominal parameters first).

    python benchmarks/calibration.py                          # both suites
    python benchmarks/calibration.py --suite mismatch --cases clean lag_30ms --clean-seeds 5
    python benchmarks/calibration.py --max-minutes 60         # start no case after an hour (default: 90 min)

Writes benchmarks/results/calibration.json (or --out) and prints the tables.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import tempfile
import time

from smarticle_mjx.calibrate import independent as IND
from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.stages import calibrate
from smarticle_mjx.calibrate.observables import LABELS, observables, reproduced
from smarticle_mjx.calibrate.synth import CASES, case_truth, make_case


# mismatch cases: generator keywords per amplitude series, and the library effect that should be named
# (None: no structural effect; "nominal:<param>": a nominal finding)
MISMATCH = {
    "clean": (dict(), None),
    "lag_30ms": (dict(lag_s=0.03), "servo_lag"),
    "lag_20ms_low": (dict(lag_s=0.02, amplitudes=(10, 20)), "servo_lag"),
    "tilt_0.5deg": (dict(tilt_deg=(0.5, 0.0)), "plate_tilt"),
    "friction_0.25": (dict(friction=0.25), "nominal:plate_friction"),
    "friction_0.15": (dict(friction=0.15), "nominal:plate_friction"),
    "outside_arm2_bias": (dict(arm2_bias_deg=5.0), None),
    "dead_time_30ms": (dict(dead_s=0.03), "servo_dead_time"),
    "phase_offset_0.1": (dict(phase_offset=0.1, robots=2), "phase_offset"),
    "tilt_2deg": (dict(tilt_deg=(2.0, 0.0)), "plate_tilt"),
    "lag_10ms": (dict(lag_s=0.01), "servo_lag"),
    "tilt_0.25deg": (dict(tilt_deg=(0.25, 0.0)), "plate_tilt"),
    # two robots far apart on different gaits (15 deg ccw beside 60 deg cw, and the reverse), the sidecar
    # listing one gait per robot
    "mixed_gaits_lag_30ms": (dict(lag_s=0.03, robots=2, mixed=True), "servo_lag"),
}


# where the generator's law is the library's, the library's value that equals the generator's truth
# (the generator's tilt (tx, ty) turns gravity toward -y for tx and +x for ty; the library's
# plate_tilt_deg = (x, y) toward +x and +y); lags: the laws differ (the generator lags its slewed
# corner, the library its ramp, on top of the preset's own 10 ms), so no truth is checked
SAME_LAW = {
    "tilt_0.5deg": {"plate_tilt": {"tilt_x_deg": 0.0, "tilt_y_deg": -0.5}},
    "tilt_2deg": {"plate_tilt": {"tilt_x_deg": 0.0, "tilt_y_deg": -2.0}},
    "tilt_0.25deg": {"plate_tilt": {"tilt_x_deg": 0.0, "tilt_y_deg": -0.25}},
    "dead_time_30ms": {"servo_dead_time": {"dead_time_s": 0.03}},
    "phase_offset_0.1": {"phase_offset": {"phase_offset": 0.1}},
}


def truth_inside(r: dict):
    """True/False where the case has a same-law truth and the named effect was fitted; else None."""
    want = SAME_LAW.get(r["case"])
    if not want:
        return None
    out = []
    for e, vals in want.items():
        if e not in r["intervals"]:
            return False
        out += [r["intervals"][e][k][0] <= v <= r["intervals"][e][k][1] for k, v in vals.items()]
    return all(out)


EFFECT_KEYS = ("lag_s", "dead_s", "tilt_deg", "friction", "phase_offset", "arm2_bias_deg")  # generator effects


def make_mismatch(name: str, out, seed: int, effects: bool = True) -> None:
    """Write the case's data; ``effects`` False: its clean twin (same starts, frame times and noise)."""
    kw, _ = MISMATCH[name]
    kw = {k: v for k, v in kw.items() if effects or k not in EFFECT_KEYS}
    amps = kw.pop("amplitudes", (15, 60))
    mixed = kw.pop("mixed", False)
    for k, a in enumerate(amps):
        if mixed:  # robot 0 at this amplitude ccw, robot 1 at the other amplitude cw
            kw["gaits"] = [(float(a), "ccw"), (float(amps[1 - k]), "cw")]
        IND.write_case(out, amplitude_deg=float(a), name=f"a{a}", trials=3, periods=5, seed=seed * 100 + a, **kw)


def clean_twin(name: str, seed: int) -> dict:
    """Observables of the generator's data with every effect off (same seed: same starts, frame times
    and noise): the data minus these is what the injected effect did to the tracks, by the generator."""
    with tempfile.TemporaryDirectory() as tmp:
        make_mismatch(name, tmp, seed, effects=False)
        return observables(load(tmp))


def run_mismatch(name: str, seed: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        make_mismatch(name, tmp, seed)
        trials = load(tmp)
        t = time.perf_counter()
        res = calibrate(trials).summary
        wall = time.perf_counter() - t
    twin = clean_twin(name, seed) if any(k in MISMATCH[name][0] for k in EFFECT_KEYS) else None
    _, want = MISMATCH[name]
    added = [a["effect"] for a in res["added"]]
    findings = [f["param"] for f in res["nominal_findings"]]
    if want is None:
        ok = not added
    elif want.startswith("nominal:"):
        ok = not added and want.split(":")[1] in findings
    else:
        ok = added[:1] == [want]
    b, f = res["before"]["err_heldout"], res["after"]["err_heldout"]
    return {"suite": "mismatch", "case": name, "seed": seed, "verdict": res["verdict"], "added": added,
            "expected": want, "named_first": ok, "generator": {k: v for k, v in MISMATCH[name][0].items()},
            "fitted": {a["effect"]: a["values"] for a in res["added"]},
            "intervals": {a["effect"]: a["interval"] for a in res["added"]},
            "nominal_findings": res["nominal_findings"], "conventions_warning": res["conventions"]["warning"],
            "heldout_before": b, "heldout_after_nominal": res["after_nominal"]["err_heldout"], "heldout_after": f,
            "heldout_drop": 1 - f / b, "wall_s": wall, "model_runs": res["model_runs"],
            "observables": res["observables"], "clean_twin": twin}


def run_case(name: str, seed: int) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        make_case(name, tmp, seed=seed)
        trials = load(tmp)
        t = time.perf_counter()
        res = calibrate(trials, nominal=False).summary
        wall = time.perf_counter() - t
    truth = case_truth(name)
    added = [a["effect"] for a in res["added"]]
    inside = {}
    for a in res["added"]:
        for k, v in truth.get(a["effect"], {}).items():
            lo, hi = a["interval"][k]
            inside[f"{a['effect']}.{k}"] = bool(lo <= v <= hi)
    b, f = res["before"]["err_heldout"], res["after"]["err_heldout"]
    return {"suite": "synth", "case": name, "seed": seed, "verdict": res["verdict"], "added": added,
            "fitted": {a["effect"]: a["values"] for a in res["added"]},
            "intervals": {a["effect"]: a["interval"] for a in res["added"]}, "truth": truth,
            "named_first": (added[:1] == list(truth)[:1]) if truth else (not added),
            "truth_inside": inside, "heldout_before": b, "heldout_after": f, "heldout_drop": 1 - f / b,
            "wall_s": wall, "model_runs": res["model_runs"]}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", choices=("synth", "mismatch", "all"), default="all")
    ap.add_argument("--cases", nargs="*", default=None, help="case names (default: every case of the suite)")
    ap.add_argument("--clean-seeds", type=int, default=5)
    ap.add_argument("--max-minutes", type=float, default=90.0, help="start no case after this long (default 90)")
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parent / "results" / "calibration.json"))
    ap.add_argument("--tables", action="store_true", help="print the tables of an existing --out and stop")
    args = ap.parse_args()
    if args.tables:
        rows = json.loads(pathlib.Path(args.out).read_text())["rows"]
        print(markdown([r for r in rows if r.get("suite", "synth") == "synth"]))
        print(mismatch_markdown([r for r in rows if r.get("suite") == "mismatch"]))
        print(observables_markdown([r for r in rows if r.get("suite") == "mismatch"]))
        return
    t0 = time.perf_counter()
    plan = []
    if args.suite in ("synth", "all"):
        plan += [("synth", n) for n in (args.cases or CASES) if n in CASES]
    if args.suite in ("mismatch", "all"):
        plan += [("mismatch", n) for n in (args.cases or MISMATCH) if n in MISMATCH]
    rows = []
    for suite, name in plan:
        for seed in (range(1, 1 + args.clean_seeds) if name == "clean" else [1]):
            if args.max_minutes is not None and time.perf_counter() - t0 > 60 * args.max_minutes:
                print(f"time cap reached; {suite}/{name} seed {seed} not run", flush=True)
                continue
            r = (run_case if suite == "synth" else run_mismatch)(name, seed)
            rows.append(r)
            print(f"{suite}/{name:22s} seed {seed}: {r['verdict']:45s} added {r['added']} fitted {r['fitted']} "
                  f"held-out {r['heldout_before']:.2f} -> {r['heldout_after']:.2f} ({r['heldout_drop']:+.0%}) "
                  f"{r['wall_s']:.0f} s", flush=True)
    summary = {}
    for suite in ("synth", "mismatch"):
        clean = [r for r in rows if r["suite"] == suite and r["case"] == "clean"]
        summary[suite] = {"false_positive_rate": (sum(bool(r["added"]) for r in clean) / len(clean)) if clean
                          else None, "clean_runs": len(clean)}
    pathlib.Path(args.out).write_text(json.dumps({"rows": rows, "summary": summary}, indent=1, default=float))
    print(summary)
    print(markdown([r for r in rows if r["suite"] == "synth"]))
    print(mismatch_markdown([r for r in rows if r["suite"] == "mismatch"]))
    print(observables_markdown([r for r in rows if r["suite"] == "mismatch"]))


def mismatch_markdown(rows) -> str:
    """The mismatch table and its confusion table (cases × what was named) for docs/calibration.md."""
    out = ["| case (seed) | generator | expected | verdict | structural effects added [95 % interval] | nominal "
           "findings (× preset) | named right | truth inside (same law) | what it moves, final model vs data | "
           "held-out error: preset → nominal → final |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        fit = "; ".join(f"{e}: " + ", ".join(f"{k} = {v:.3g} [{r['intervals'][e][k][0]:.3g}, "
                                             f"{r['intervals'][e][k][1]:.3g}]" for k, v in vals.items())
                        for e, vals in r["fitted"].items()) or "–"
        nom = ", ".join(f"{f['param']} {f['ratio']:.2f}" for f in r["nominal_findings"]) or "–"
        gen = ", ".join(f"{k} = {v}" for k, v in r["generator"].items()) or "nothing"
        out.append(f"| {r['case']} ({r['seed']}) | {gen} | {r['expected'] or 'none'} | {r['verdict']} | {fit} | {nom} | "
                   f"{'yes' if r['named_first'] else 'no'} | "
                   f"{ {True: 'yes', False: 'no', None: '–'}[truth_inside(r)]} | {observable_agreement(r)} | "
                   f"{r['heldout_before']:.3g} → "
                   f"{r['heldout_after_nominal']:.3g} → {r['heldout_after']:.3g} |")
    names = sorted({a for r in rows for a in r["added"]} | {"(none)"})
    out += ["", "| case | runs | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for case in dict.fromkeys(r["case"] for r in rows):
        rs = [r for r in rows if r["case"] == case]
        cnt = [sum((n in r["added"][:1]) if n != "(none)" else (not r["added"]) for r in rs) for n in names]
        out.append(f"| {case} | {len(rs)} | " + " | ".join(str(c) for c in cnt) + " |")
    return "\n".join(out)


# the observable each expected effect moves (calibrate.observables)
OBSERVABLE = {"servo_lag": "arm_delay_ms", "servo_dead_time": "arm_delay_ms", "phase_offset": "phase_lead",
              "plate_tilt": "drift_mm_per_s", "nominal:plate_friction": "body_step_mm"}


def _moved(r: dict) -> str:
    """The observable the case's expected effect moves (the arm delay where none is expected)."""
    return OBSERVABLE.get(r["expected"] or "", "arm_delay_ms")


def observable_agreement(r: dict) -> str:
    """Whether the final model reproduces, within 95 %, the observable the expected effect moves, per gait."""
    obs = r.get("observables")
    if not obs:
        return "–"
    kind = _moved(r)
    marks = []
    for row in obs[kind]:
        ok = reproduced(row["measured"], row.get("final"))
        amp = row["gait"].split("°")[0] + "°" + (f" r{row['robot']}" if "robot" in row else "")
        if ok:
            marks.append(f"{amp} ✓")
        elif "v" in row["measured"]:
            marks.append(f"{amp} ✗")
        else:
            marks.append(f"{amp} {row['final']['mean'] - row['measured']['mean']:+.3g}")
    return f"{LABELS[kind]}: " + ", ".join(marks)


def observables_markdown(rows) -> str:
    """What the fitted values mean on the tracks: per case with an injected effect, the observable it moves,
    the generator's change (its data minus its clean twin), the fitted effect's share in the model (final
    minus final without it) and the final model against the data."""
    out = ["| case | observable | gait | generator: clean twin → data | model: without effect → final | "
           "effect's share (model / generator) | final − data |", "|---|---|---|---|---|---|---|"]

    def val(m, j=None):
        if m is None:
            return float("nan")
        return m["v"][j] if "v" in m else m["mean"]

    for r in rows:
        if not r.get("clean_twin") or not r.get("observables"):
            continue
        kind = _moved(r)
        j = 1 if kind == "drift_mm_per_s" else None  # the generator's tilt turns gravity toward -y
        name = LABELS[kind] + (", along y" if j else "")
        added = r["added"][:1]
        for row in r["observables"][kind]:
            twin = next((x for x in r["clean_twin"][kind] if x["gait"] == row["gait"]
                         and x.get("robot") == row.get("robot")), None)
            g0, g1 = val(twin, j), val(row["measured"], j)
            fin = val(row.get("final"), j)
            wo = val(row.get(f"without {added[0]}"), j) if added else fin
            share = (fin - wo) / (g1 - g0) if added and abs(g1 - g0) > 0 else float("nan")
            fmt = {"arm_delay_ms": ".1f", "body_step_mm": ".3f"}.get(kind, ".4f")
            out.append(f"| {r['case']} ({r['seed']}) | {name} | {row['gait']} | {g0:{fmt}} → {g1:{fmt}} | "
                       f"{wo:{fmt}} → {fin:{fmt}} | {share:.2f} | {fin - g1:+{fmt}} |")
    return "\n".join(out)


def markdown(rows) -> str:
    """The table quoted in docs/calibration.md."""
    out = ["| case | hidden (true) | verdict | fitted [95 % interval] | truth inside | held-out error before → after |",
           "|---|---|---|---|---|---|"]
    for r in rows:
        truth = "; ".join(f"{k} = {v:g}" for e in r["truth"].values() for k, v in e.items()) or "none"
        fit = "; ".join(f"{k} = {v:.3g} [{r['intervals'][e][k][0]:.3g}, {r['intervals'][e][k][1]:.3g}]"
                        for e, vals in r["fitted"].items() for k, v in vals.items()) or "–"
        inside = "yes" if r["truth_inside"] and all(r["truth_inside"].values()) else (
            "–" if not r["truth_inside"] else "no")
        out.append(f"| {r['case']} (seed {r['seed']}) | {truth} | {r['verdict']} | {fit} | {inside} | "
                   f"{r['heldout_before']:.3g} → {r['heldout_after']:.3g} ({r['heldout_drop']:+.0%}) |")
    return "\n".join(out)


if __name__ == "__main__":
    main()
