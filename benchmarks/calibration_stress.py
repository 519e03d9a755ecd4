"""A stress suite for ``smx calibrate`` that the calibration code did not write: data sets drawn at random
from the independent simulator (smarticle_mjx/calibrate/independent.py, which imports nothing from the
library), each calibrated as a user would, and scored by rules fixed here before any calibration rule was
tuned against them.

Each set (one index of a suite seed) draws:
  * the robot's build (independent.draw_build): box sizes, masses, hinge inset, the servo's law (a slewed
    reference, a slewed reference with velocity feed-forward, or a stepped reference whose speed the
    motor's back-EMF limits), its gains, torque and gearbox inertia, contact softness, the plate's true mu;
  * 2-4 amplitudes from 15-90 deg (period 1.6 s x amplitude / 90 deg), 2 trials x 5 periods each, one
    chirality, a frame rate of 30, 60, 90 or 120 Hz, arms tracked in 3 of 4 sets;
  * what is hidden: 2 sets in 5 are clean; the others carry 1 (60 %) or 2 (25 %) effects of the library
    at random sizes, or none of it (15 %) but one outside it; an outside effect also joins 1 in 5 of the
    sets with library effects. In the library: a servo lag (15-50 ms), a dead time (15-50 ms), a plate
    tilt (0.5-2.5 deg, any azimuth), a phase offset between two robots (0.05-0.2 period, either sign),
    anisotropic plate friction (mu_y / mu_x 1.5-2.5 or its inverse), arms resting on the plate
    (mu 0.1-0.5), tracking noise (0.2-1 mm and 0.2-1 deg). Outside it: one arm misread by a constant
    (3-8 deg, arms then tracked) or a plate whose mu under a robot depends on its heading,
    mu (1 + e cos 2h), e 0.3-0.6. At most one servo effect per set.

Scoring ("right": the first structural effect added is the hidden one; with two hidden, both added;
with none hidden, nothing added; "same-law": the generator's effect follows the library's law, which
holds for all but the servo lag, whose generator lags its own reference):
  * size within 1.5x: the fitted size (a vector's length for the tilt) over the true one in [1/1.5, 1.5];
  * covered: the 95 % interval holds the truth in every parameter;
  * both counted over every hidden same-law effect, as failed where the effect was not added (the rate
    among added effects is given beside);
  * held-out error after calibration over the clean twin's (the same set, seed and noise without its
    hidden effects, calibrated with the nominal stage alone) <= 1.5;
  * outside effects: "reported as unexplained" = nothing structural added for them and a verdict that
    names an unexplained residual.

Resumable set by set: each set's result is one JSON file under results/calibration_stress/<suite seed>/;
a set computed with another generator or scoring (their source hashes are stored) is run again.

    python benchmarks/calibration_stress.py --sets 0-59                  # the reported suite (seed 2026)
    python benchmarks/calibration_stress.py --suite-seed 7 --sets 0-9    # development seeds
    python benchmarks/calibration_stress.py --summary                    # tables of what is stored
    python benchmarks/calibration_stress.py --sets 5,9 --tag rerun       # reported sets again, kept apart
    python benchmarks/calibration_stress.py --suite-seed 2043 --sets 11 --plate-hypothesis arm_plate_contact \
        --tag armplate                                                   # arms on the plate fitted jointly
"""

from __future__ import annotations

import argparse
import hashlib
import inspect
import json
import math
import pathlib
import tempfile
import time

import numpy as np

from smarticle_mjx.calibrate import independent as IND
from smarticle_mjx.calibrate.fit import PLATE_HYPOTHESES
from smarticle_mjx.calibrate.stages import plate_hypotheses_with

ROOT = pathlib.Path(__file__).resolve().parent
RESULTS = ROOT / "results"
REPORTED_SEED = 2026  # the suite reported in docs/calibration.md; development used other seeds
AMPLITUDES = (15, 25, 40, 60, 75, 90)
FRAME_RATES = (30.0, 60.0, 90.0, 120.0)
LIBRARY = ("servo_lag", "servo_dead_time", "plate_tilt", "phase_offset", "anisotropic_friction",
           "arm_plate_contact", "tracking_noise")
SERVO = ("servo_lag", "servo_dead_time")
SAME_LAW = ("servo_dead_time", "plate_tilt", "phase_offset", "anisotropic_friction", "arm_plate_contact",
            "tracking_noise")
OUTSIDE = ("arm_bias", "heading_friction")


def _effect(name: str, rng) -> tuple[dict, dict]:
    """(generator keywords, the truth in the library's parameters; {} outside the library)."""
    u = rng.uniform
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    if name == "servo_lag":
        lag = u(0.015, 0.05)
        return {"lag_s": lag}, {"extra_lag_s": lag}
    if name == "servo_dead_time":
        dead = u(0.015, 0.05)
        return {"dead_s": dead}, {"dead_time_s": dead}
    if name == "plate_tilt":
        mag, az = u(0.5, 2.5), u(0.0, 2 * math.pi)
        x, y = mag * math.cos(az), mag * math.sin(az)  # gravity pulls toward (x, y) (library's plate_tilt)
        return {"tilt_deg": (-y, x)}, {"tilt_x_deg": x, "tilt_y_deg": y}
    if name == "phase_offset":
        off = sign * u(0.05, 0.2)
        return {"phase_offset": off}, {"phase_offset": off}
    if name == "anisotropic_friction":
        r = math.exp(sign * u(math.log(1.5), math.log(2.5)))
        return {"friction_y_ratio": r}, {"friction_y_ratio": r}
    if name == "arm_plate_contact":
        mu = u(0.1, 0.5)
        return {"arm_plate_mu": mu}, {"arm_plate_mu": mu}
    if name == "tracking_noise":
        xy, th = u(0.2, 1.0), u(0.2, 1.0)
        return {"noise_xy_mm": xy, "noise_theta_deg": th}, {"noise_xy_mm": xy, "noise_theta_deg": th}
    if name == "arm_bias":
        return {"arm2_bias_deg": sign * u(3.0, 8.0)}, {}
    if name == "heading_friction":
        return {"heading_friction": u(0.3, 0.6)}, {}
    raise ValueError(name)


def draw_set(suite_seed: int, index: int) -> dict:
    """Everything about one set, drawn from (suite_seed, index) alone: JSON-ready."""
    rng = np.random.default_rng([suite_seed, index])
    build = IND.draw_build(rng)
    hidden, outside = [], []
    if index % 5 not in (0, 3):  # 2 sets in 5 are clean
        n_lib = int(rng.choice([0, 1, 2], p=[0.15, 0.6, 0.25]))
        pool = list(LIBRARY)
        for _ in range(n_lib):
            e = str(rng.choice(pool))
            hidden.append(e)
            pool = [p for p in pool if p != e and not (e in SERVO and p in SERVO)]
        if n_lib == 0 or rng.uniform() < 0.2:
            outside.append(str(rng.choice(OUTSIDE)))
    gen, truth = {}, {}
    for e in hidden + outside:
        kw, t = _effect(e, rng)
        gen.update(kw)
        if t:
            truth[e] = t
    k = int(rng.integers(2, 5))
    amps = sorted(int(a) for a in rng.choice(AMPLITUDES, size=k, replace=False))
    robots = 2 if "phase_offset" in hidden or rng.uniform() < 0.15 else 1
    arms = bool("arm_bias" in outside or rng.uniform() < 0.75)
    return {"suite_seed": suite_seed, "index": index, "build": build.as_dict(), "hidden": hidden,
            "outside": outside, "generator": gen, "truth": truth, "amplitudes": amps,
            "chirality": "ccw" if rng.uniform() < 0.5 else "cw", "frame_rate_hz": float(rng.choice(FRAME_RATES)),
            "arms_tracked": arms, "robots": robots, "trials_per_amplitude": 2, "periods": 5,
            "data_seed": int(rng.integers(2 ** 31))}


def choose_sets(seeds, kind, per_class: int, indices=range(60)) -> list[tuple[int, int, str]]:
    """(seed, index, class) of the first ``per_class`` sets of each class ``kind(set)`` gives (None: not
    chosen), in seed and index order: sets chosen by what they hide, before any is run."""
    out, count = [], {}
    for seed in seeds:
        for index in indices:
            k = kind(draw_set(seed, index))
            if k and count.get(k, 0) < per_class:
                count[k] = count.get(k, 0) + 1
                out.append((seed, index, k))
    return out


def write_set(s: dict, out, effects: bool = True) -> None:
    """The set's data (one CSV + sidecar per amplitude); ``effects`` False: its clean twin (same build,
    starts, frame times and noise draws)."""
    build = IND.Build(**s["build"])
    gen = dict(s["generator"]) if effects else {}
    noise = {k: gen.pop(k) for k in ("noise_xy_mm", "noise_theta_deg") if k in gen}
    for j, a in enumerate(s["amplitudes"]):
        IND.write_case(out, robots=s["robots"], amplitude_deg=float(a), trials=s["trials_per_amplitude"],
                       periods=s["periods"], seed=s["data_seed"] + j, frame_rate=s["frame_rate_hz"],
                       name=f"a{a}", arms_tracked=s["arms_tracked"], chirality=s["chirality"], build=build,
                       **noise, **gen)


def _size(name: str, fitted: dict, truth: dict) -> float:
    if name == "plate_tilt":
        return math.hypot(fitted["tilt_x_deg"], fitted["tilt_y_deg"]) / math.hypot(truth["tilt_x_deg"],
                                                                                     truth["tilt_y_deg"])
    ratios = [fitted[k] / truth[k] for k in truth]
    return max(ratios, key=lambda r: abs(math.log(abs(r))) if r else math.inf)


def score(s: dict, res: dict, twin_err: float | None) -> dict:
    """The frozen scoring of one set from its calibration summary (docstring above)."""
    added = [a["effect"] for a in res["added"]]
    hidden = s["hidden"]
    if len(hidden) == 1:
        right = added[:1] == hidden
    elif len(hidden) == 2:
        right = set(hidden) <= set(added)
    else:
        right = not added
    found = {a["effect"]: a for a in res["added"]}
    effects = []
    for e in hidden:
        if e not in SAME_LAW:
            continue
        row = {"effect": e, "added": e in found, "size_ratio": None, "within_1_5": False, "covered": False}
        if e in found:
            r = _size(e, found[e]["values"], s["truth"][e])
            row["size_ratio"] = r
            row["within_1_5"] = bool(1 / 1.5 <= r <= 1.5)
            row["covered"] = all(found[e]["interval"][k][0] <= v <= found[e]["interval"][k][1]
                                 for k, v in s["truth"][e].items())
        effects.append(row)
    err = res["after"]["err_heldout"]
    return {"right": bool(right), "added": added, "verdict": res["verdict"], "same_law": effects,
            "outside_reported": (bool(not added and "unexplained" in res["verdict"]) if s["outside"] and not hidden
                                 else None),
            "heldout_after": err, "heldout_twin": twin_err,
            "heldout_vs_twin": (err / twin_err if twin_err else None) if hidden else None}


def _plain(x):
    """numpy scalars as JSON numbers and booleans."""
    return x.item() if isinstance(x, np.generic) else float(x)


def source_hash() -> str:
    """What the stored results depend on besides the calibration: the generator and this file's draw and
    score."""
    parts = [pathlib.Path(IND.__file__).read_text()] + [inspect.getsource(f) for f in (_effect, draw_set, write_set,
                                                                                       _size, score)]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:16]


def run_set(s: dict, plate_hypotheses: tuple[str, ...] = PLATE_HYPOTHESES, overrides: tuple = ()) -> dict:
    """One set calibrated as ``smx calibrate`` would (``overrides``: its ``--set`` changes to the model, for
    the set and its clean twin alike), scored."""
    from smarticle_mjx import __version__
    from smarticle_mjx.calibrate.data import load
    from smarticle_mjx.calibrate.stages import calibrate
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_set(s, tmp)
        trials = load(tmp, None, overrides)
        t = time.perf_counter()
        res = calibrate(trials, on_step=lambda m: print(f"    [{time.perf_counter() - t:5.0f} s] {m}", flush=True),
                        plate_hypotheses=plate_hypotheses).summary
        wall = time.perf_counter() - t
    twin = None
    if s["hidden"]:
        with tempfile.TemporaryDirectory() as tmp:
            write_set(s, tmp, effects=False)
            twin = calibrate(load(tmp, None, overrides), structural=False).summary["after"]["err_heldout"]
    return {"set": s, "score": score(s, res, twin), "wall_s": wall, "total_s": time.perf_counter() - t0,
            "model_runs": res["model_runs"], "plate_hypotheses": res.get("plate_hypotheses"), "fitted": {a["effect"]: a["values"] for a in res["added"]},
            "intervals": {a["effect"]: a["interval"] for a in res["added"]},
            "intervals_statistical": {a["effect"]: a.get("interval_statistical", a["interval"]) for a in res["added"]},
            "nominal_findings": res["nominal_findings"], "plate_level": res.get("plate_level"),
            # every joint hypothesis of the nominal stage as judged (values, gains, baseline, rule), and the
            # delay test, so that a miss can be read without running the set again (stored after 0.4.3)
            "hypotheses": res.get("nominal_hypotheses"), "delay_test": res.get("delay_test"),
            # the held-out error before and with a tilt named from the drift (stored since 0.4.14)
            "tilt_heldout": (res.get("drift") or {}).get("tilt_heldout"),
            "version": __version__, "source": source_hash(),
            **({"overrides": dict(overrides)} if overrides else {})}


def _rate(xs) -> dict:
    xs = [bool(x) for x in xs]
    return {"rate": (sum(xs) / len(xs)) if xs else None, "n": len(xs)}


def _covered_statistical(row: dict, effect: str) -> bool:
    """Whether the statistical interval alone (before the model-mismatch term, calibrate/discrepancy.py)
    holds the truth in every parameter; rows of runs before the term have none."""
    iv = row["intervals_statistical"][effect]
    return all(iv[k][0] <= v <= iv[k][1] for k, v in row["set"]["truth"][effect].items())


def summarise(rows: list[dict]) -> dict:
    lib = [r for r in rows if r["set"]["hidden"]]
    clean = [r for r in rows if not r["set"]["hidden"] and not r["set"]["outside"]]
    outside = [r for r in rows if r["set"]["outside"] and not r["set"]["hidden"]]
    same = [e for r in lib for e in r["score"]["same_law"]]
    twin = [r["score"]["heldout_vs_twin"] for r in lib if r["score"]["heldout_vs_twin"] is not None]
    return {"sets": len(rows), "right_with_effects": _rate(r["score"]["right"] for r in lib),
            "nothing_added_clean": _rate(r["score"]["right"] for r in clean),
            "outside_reported_unexplained": _rate(r["score"]["outside_reported"] for r in outside),
            "size_within_1_5": _rate(e["within_1_5"] for e in same),
            "size_within_1_5_of_added": _rate(e["within_1_5"] for e in same if e["added"]),
            "covered": _rate(e["covered"] for e in same),
            "covered_of_added": _rate(e["covered"] for e in same if e["added"]),
            "covered_statistical_of_added": _rate(_covered_statistical(r, e["effect"]) for r in lib
                                                  for e in r["score"]["same_law"]
                                                  if e["added"] and "intervals_statistical" in r),
            "heldout_within_1_5_of_twin": _rate(x <= 1.5 for x in twin),
            "wall_s_median": float(np.median([r["wall_s"] for r in rows])) if rows else None,
            "wall_s_by_trials": {str(k): v for k, v in by_trials(rows).items()},
            "by_condition": by_condition(rows),
            "targets": {"right_with_effects": 0.9, "nothing_added_clean": 0.95, "size_within_1_5": 0.8,
                        "covered": 0.8, "heldout_within_1_5_of_twin": 1.0}}


# Conditions under which the calibration is known to miss an effect, each documented on earlier seeds
# (docs/calibration.md, "Where the misses are"): read off the draw alone, in this order, the first that
# applies. A split for the report, beside the frozen targets; no rule of the calibration reads it (written
# before seed 2066 ran).
CONDITIONS = (
    "servo timing, body only",  # a lag or dead time where no arm is tracked: not tried (the arm-track rule)
    "lag behind a stepped reference",  # the arm runs at its speed limit; its delay moves by a few ms
    "tilt beside tracking noise",  # the noise takes the plate-frame drift's chi2 down 100-400x
    "beside an outside effect",  # an arm misread or a heading-dependent grip beside a library effect
    "anisotropic plate",  # a plate slipperier along one axis, seen at two or three headings per gait
    "none of these",
)


def condition(s: dict) -> str | None:
    """The first of ``CONDITIONS`` that a set with hidden library effects meets, from its draw alone;
    None for a clean set or one that hides only an outside effect."""
    hidden = set(s["hidden"])
    if not hidden:
        return None
    met = (bool(hidden & set(SERVO)) and not s["arms_tracked"],
           "servo_lag" in hidden and s["build"]["servo_slew"] is None,
           {"plate_tilt", "tracking_noise"} <= hidden,
           bool(s["outside"]),
           "anisotropic_friction" in hidden,
           True)
    return CONDITIONS[met.index(True)]


def by_condition(rows: list[dict]) -> dict:
    """Per condition (``CONDITIONS``, in order): sets, right, held-out within 1.5x of the twin."""
    out = {}
    for name in CONDITIONS:
        rs = [r for r in rows if condition(r["set"]) == name]
        twin = [r["score"]["heldout_vs_twin"] for r in rs if r["score"]["heldout_vs_twin"] is not None]
        out[name] = {"sets": len(rs), "right": sum(bool(r["score"]["right"]) for r in rs),
                     "heldout_within_1_5_of_twin": sum(x <= 1.5 for x in twin), "with_twin": len(twin)}
    return out


def condition_table(rows: list[dict]) -> str:
    lines = ["| condition (first that applies) | sets with effects | right | held-out within 1.5x of twin |",
             "|---|---|---|---|"]
    for name, c in by_condition(rows).items():
        lines.append(f"| {name} | {c['sets']} | {c['right']} | {c['heldout_within_1_5_of_twin']} of {c['with_twin']} |")
    return "\n".join(lines)


def recording(s: dict, effect: str) -> str:
    """How a set records what an effect shows in: a servo timing needs the arms and depends on the servo's
    reference ("arms, slewed reference", "arms, stepped reference", "body only"); every other effect, ""."""
    if effect not in SERVO:
        return ""
    if not s["arms_tracked"]:
        return "body only"
    return "arms, " + ("stepped" if s["build"]["servo_slew"] is None else "slewed") + " reference"


def by_effect(rows: list[dict]) -> dict:
    """Per hidden library effect and recording (``recording``): sets hiding it, sets where it was added
    (first or not), and of those added, for a same-law effect, sizes within 1.5x and intervals that hold the
    truth (None for an effect whose law is not the library's)."""
    out: dict = {}
    for r in rows:
        added = r["score"]["added"]
        law = {e["effect"]: e for e in r["score"]["same_law"]}
        for e in r["set"]["hidden"]:
            key = (e, recording(r["set"], e))
            t = out.setdefault(key, {"hidden": 0, "added": 0, "within_1_5": 0 if e in SAME_LAW else None,
                                     "covered": 0 if e in SAME_LAW else None})
            t["hidden"] += 1
            if e in added:
                t["added"] += 1
                if e in SAME_LAW:
                    t["within_1_5"] += bool(law[e]["within_1_5"])
                    t["covered"] += bool(law[e]["covered"])
    return dict(sorted(out.items()))


def effect_table(rows: list[dict]) -> str:
    lines = ["| hidden effect | recorded | sets | added | of added: size within 1.5x | of added: interval covers |",
             "|---|---|---|---|---|---|"]
    for (e, rec), t in by_effect(rows).items():
        law = ("not scored: not the library's law", "not scored") if t["within_1_5"] is None else (t["within_1_5"], t["covered"])
        lines.append(f"| {e} | {rec or '-'} | {t['hidden']} | {t['added']} | {law[0]} | {law[1]} |")
    return "\n".join(lines)


def pooled_rows(seeds: str, results=None) -> list[dict]:
    """Every stored row of the whole seeds named (e.g. "2049-2051,2058"), read from their summaries
    (results/calibration_stress_<seed>.json, as the runs wrote them); FileNotFoundError in one line for a
    seed never summarised."""
    results = RESULTS if results is None else results
    rows = []
    for seed in _indices(seeds):
        path = results / f"calibration_stress_{seed}.json"
        if not path.exists():
            raise FileNotFoundError(f"no stored summary for suite seed {seed} ({path.name})")
        rows += json.loads(path.read_text())["rows"]
    return rows


def confusion(rows: list[dict]) -> str:
    """Hidden (first library effect, or clean / outside) x first structural effect added."""
    names = sorted({(r["score"]["added"] or ["(none)"])[0] for r in rows} | {"(none)"})
    table: dict = {}
    for r in rows:
        h = r["set"]["hidden"]
        key = " + ".join(h) if h else ("outside: " + r["set"]["outside"][0] if r["set"]["outside"] else "clean")
        first = (r["score"]["added"] or ["(none)"])[0]
        table.setdefault(key, {}).setdefault(first, 0)
        table[key][first] += 1
    lines = ["| hidden | sets | " + " | ".join(names) + " |", "|---|---|" + "---|" * len(names)]
    for key in sorted(table):
        row = table[key]
        lines.append(f"| {key} | {sum(row.values())} | " + " | ".join(str(row.get(n, 0)) for n in names) + " |")
    return "\n".join(lines)


def coverage(rows: list[dict]) -> str:
    """Per same-law effect: how often added, within 1.5x, covered."""
    by: dict = {}
    for r in rows:
        for e in r["score"]["same_law"]:
            by.setdefault(e["effect"], []).append(e)
    lines = ["| effect (same law) | hidden | added | size within 1.5x | interval covers | size ratios |",
             "|---|---|---|---|---|---|"]
    for name, es in sorted(by.items()):
        ratios = ", ".join(f"{e['size_ratio']:.2f}" for e in es if e["size_ratio"] is not None) or "-"
        lines.append(f"| {name} | {len(es)} | {sum(e['added'] for e in es)} | {sum(e['within_1_5'] for e in es)} | "
                     f"{sum(e['covered'] for e in es)} | {ratios} |")
    return "\n".join(lines)


SPEED_TARGET_S = 300.0  # an 8-trial set calibrated within 5 minutes on 2 cores (issue #44)


def trials_of(s: dict) -> int:
    return len(s["amplitudes"]) * s["trials_per_amplitude"]


def by_trials(rows: list[dict]) -> dict:
    """Per count of trials in a set: sets, median and slowest wall time of the calibration (the clean twin's
    not counted), and how many ran within ``SPEED_TARGET_S``."""
    out = {}
    for k in sorted({trials_of(r["set"]) for r in rows}):
        w = [r["wall_s"] for r in rows if trials_of(r["set"]) == k]
        out[k] = {"sets": len(w), "median_s": float(np.median(w)), "slowest_s": float(max(w)),
                  "within_5_min": sum(x <= SPEED_TARGET_S for x in w)}
    return out


def speed_table(rows: list[dict]) -> str:
    lines = ["| trials in the set | sets | median | slowest | within 5 minutes |", "|---|---|---|---|---|"]
    for k, v in by_trials(rows).items():
        lines.append(f"| {k} | {v['sets']} | {v['median_s']:.0f} s | {v['slowest_s']:.0f} s | {v['within_5_min']} |")
    return "\n".join(lines)


def print_summary(rows: list[dict], summary: dict | None = None) -> None:
    """The summary (``summarise``, unless given) and every table, as a run and ``--summary --pool`` print them."""
    print(json.dumps(summarise(rows) if summary is None else summary, indent=1))
    for table in (confusion, coverage, condition_table, effect_table, speed_table):
        print(table(rows))


def parse_set(spec: str) -> tuple[int, int]:
    """(seed, index) of a set named "SEED/INDEX"; argparse.ArgumentTypeError in one line otherwise."""
    try:
        seed, index = spec.split("/")
        return int(seed), int(index)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a set is SEED/INDEX, e.g. 2141/4, not {spec!r}") from None


def stored_set(spec: str, hides: str | None = None) -> dict:
    """The stored result of stress set ``spec`` ("seed/index", e.g. "2148/14") as run_set wrote it; exits with
    a one-line message where the spec is malformed, the set was not run, or it does not hide ``hides``."""
    try:
        seed, index = parse_set(spec)
    except argparse.ArgumentTypeError as e:
        raise SystemExit(str(e)) from None
    path = RESULTS / "calibration_stress" / str(seed) / f"set_{index:04d}.json"
    if not path.exists():
        raise SystemExit(f"no stored stress set {seed}/{index} (run benchmarks/calibration_stress.py first)")
    row = json.loads(path.read_text())
    if hides is not None and hides not in row["set"]["truth"]:
        raise SystemExit(f"stress set {seed}/{index} hides no {hides}")
    return row


def _indices(spec: str) -> list[int]:
    """The integers a spec such as "0-29" or "2049-2051,2058" names; ValueError in one line otherwise."""
    out = []
    for part in spec.split(","):
        a, _, b = part.partition("-")
        try:
            out += list(range(int(a), int(b or a) + 1))
        except ValueError:
            raise ValueError(f"not a list of numbers and ranges: {spec!r} (e.g. 0-29 or 2049-2051,2058)") from None
    return out


def seed_indices(seeds: str, sets: str) -> list[tuple[int, int]]:
    """(suite seed, index) of every set the two specs name (e.g. "2061-2065", "0-29"), seed by seed."""
    return [(seed, i) for seed in _indices(seeds) for i in _indices(sets)]


# the counterfactual rules a run can take instead of the calibration's (each kept apart with --tag):
# (flag, what it does, how it sets calibrate.stages)
COUNTERFACTUALS = (
    ("--no-plate-level-gate", "try the anisotropic plate whatever the plate-frame drift shows (the rule before "
     "the gate)", lambda st: setattr(st, "P_LEVEL", math.inf)),  # no p reaches it: the plate is never withheld
    ("--servo-without-arms", "try a servo lag or dead time on sets without arm tracks too, as before the "
     "arm-track rule", lambda st: setattr(st, "SERVO_WITHOUT_ARMS", True)),
    ("--plate-both-sides", "also start the anisotropic plate's fit from the grid's best point on the other side "
     "of ratio 1 (tried on stored sets, not the rule)", lambda st: setattr(st, "PLATE_BOTH_SIDES", True)),
    ("--swapped-split", "calibrate with the odd trials training and the even ones held out, the other way round",
     lambda st: setattr(st, "SPLIT_SWAPPED", True)),
)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite-seed", type=int, default=REPORTED_SEED)
    ap.add_argument("--sets", default="0-59", help="indices, e.g. 0-59 or 0,3,7-9")
    ap.add_argument("--max-minutes", type=float, default=None, help="start no set after this long")
    ap.add_argument("--summary", action="store_true", help="print the tables of what is stored and stop")
    ap.add_argument("--draw-only", action="store_true", help="print what each set hides and stop")
    ap.add_argument("--pool", default=None, metavar="SEEDS",
                    help="with --summary: pool the stored summaries of these whole seeds (e.g. 2049-2051,2058) "
                         "and print their tables instead of one seed's")
    ap.add_argument("--plate-hypothesis", action="append", default=[],
                    help="also fit this plate effect jointly with the nominal parameters (smx calibrate's option)")
    ap.add_argument("--tag", default="", help="keep this run's results apart (calibration_stress/<seed>-<tag>/): "
                                              "sets of a reported seed run again under later rules")
    for flag, text, _ in COUNTERFACTUALS:
        ap.add_argument(flag, action="store_true", help=f"{text} (for a counterfactual run, with --tag)")
    ap.add_argument("--set", dest="set_", action="append", default=[], metavar="FIELD=VALUE",
                    help="change the library's model as smx calibrate --set does (for the set and its clean twin; "
                         "needs --tag, so that the results stay apart)")
    args = ap.parse_args()
    try:
        sets = _indices(args.sets)
    except ValueError as e:
        ap.error(str(e))
    if args.pool is not None:
        if not args.summary:
            ap.error("--pool needs --summary: it reads stored results and runs nothing")
        try:
            rows = pooled_rows(args.pool)
        except (FileNotFoundError, ValueError) as e:
            ap.error(str(e))
        print(f"{len(rows)} sets of suite seeds {args.pool}, versions "
              f"{', '.join(sorted({r.get('version', '?') for r in rows}))}")
        print_summary(rows)
        return
    from smarticle_mjx import presets
    try:
        overrides = presets.overrides(args.set_)
    except ValueError as e:
        ap.error(str(e))
    if overrides and not args.tag:
        ap.error("--set needs --tag: results made with a changed model are kept apart")
    chosen = [apply for flag, _, apply in COUNTERFACTUALS if getattr(args, flag[2:].replace("-", "_"))]
    if chosen and not args.tag:
        ap.error("a counterfactual rule needs --tag: its results are kept apart")
    from smarticle_mjx.calibrate import stages
    for apply in chosen:
        apply(stages)
    try:
        plates = plate_hypotheses_with(args.plate_hypothesis)
    except ValueError as e:
        ap.error(str(e))
    name = str(args.suite_seed) + (f"-{args.tag}" if args.tag else "")
    folder = RESULTS / "calibration_stress" / name
    folder.mkdir(parents=True, exist_ok=True)
    src = source_hash()
    t0 = time.perf_counter()
    for i in sets:
        if args.summary:
            break
        s = draw_set(args.suite_seed, i)
        if args.draw_only:
            print(i, s["hidden"], s["outside"], s["truth"], s["amplitudes"], s["frame_rate_hz"], s["arms_tracked"])
            continue
        path = folder / f"set_{i:04d}.json"
        if path.exists() and json.loads(path.read_text()).get("source") == src:
            continue
        if args.max_minutes is not None and time.perf_counter() - t0 > 60 * args.max_minutes:
            print(f"time cap reached; set {i} not run", flush=True)
            break
        print(f"set {i}: hidden {s['hidden']} outside {s['outside']} amplitudes {s['amplitudes']} "
              f"{s['frame_rate_hz']:g} Hz arms {s['arms_tracked']}", flush=True)
        r = run_set(s, plates, overrides)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(r, indent=1, default=_plain))
        tmp.replace(path)
        print(f"  -> added {r['score']['added']} right {r['score']['right']} {r['wall_s']:.0f} s", flush=True)
    if args.draw_only:
        return
    rows = [json.loads(p.read_text()) for p in sorted(folder.glob("set_*.json"))]
    rows = [r for r in rows if r.get("source") == src]
    summary = summarise(rows)
    out = RESULTS / f"calibration_stress_{name}.json"
    out.write_text(json.dumps({"suite_seed": args.suite_seed, "source": src, "summary": summary,
                               "rows": rows}, indent=1, default=_plain))
    print_summary(rows, summary)


if __name__ == "__main__":
    main()
