"""The stress suite's generator and scoring (run by benchmarks/calibration_stress.py): a suite for ``smx calibrate`` that the calibration code did not write: data sets drawn at random
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

"""

from __future__ import annotations

import argparse
import hashlib
import inspect
import json
import math
import pathlib
import tempfile

import numpy as np

from . import independent as IND
from .data import load
from .residuals import features, masked, residual_blocks

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


def source_hash() -> str:
    """What the stored results depend on besides the calibration: the generator and this file's draw and
    score."""
    parts = [pathlib.Path(IND.__file__).read_text()] + [inspect.getsource(f) for f in (_effect, draw_set, write_set,
                                                                                       _size, score)]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:16]


def rate(xs) -> dict:
    xs = [bool(x) for x in xs]
    return {"rate": (sum(xs) / len(xs)) if xs else None, "n": len(xs)}


def covered_statistical(row: dict, effect: str) -> bool:
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
    return {"sets": len(rows), "right_with_effects": rate(r["score"]["right"] for r in lib),
            "nothing_added_clean": rate(r["score"]["right"] for r in clean),
            "outside_reported_unexplained": rate(r["score"]["outside_reported"] for r in outside),
            "size_within_1_5": rate(e["within_1_5"] for e in same),
            "size_within_1_5_of_added": rate(e["within_1_5"] for e in same if e["added"]),
            "covered": rate(e["covered"] for e in same),
            "covered_of_added": rate(e["covered"] for e in same if e["added"]),
            "covered_statistical_of_added": rate(covered_statistical(r, e["effect"]) for r in lib
                                                  for e in r["score"]["same_law"]
                                                  if e["added"] and "intervals_statistical" in r),
            "heldout_within_1_5_of_twin": rate(x <= 1.5 for x in twin),
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


def parse_set(spec: str) -> tuple[int, int]:
    """(seed, index) of a set named "SEED/INDEX"; argparse.ArgumentTypeError in one line otherwise."""
    try:
        seed, index = spec.split("/")
        return int(seed), int(index)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a set is SEED/INDEX, e.g. 2141/4, not {spec!r}") from None


def indices(spec: str) -> list[int]:
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
    return [(seed, i) for seed in indices(seeds) for i in indices(sets)]


def pooled_rows(seeds: str, results) -> list[dict]:
    """Every stored row of the whole seeds named (e.g. "2049-2051,2058"), read from their summaries
    (``results``/calibration_stress_<seed>.json, as benchmarks/calibration_stress.py wrote them); FileNotFoundError in one line for a
    seed never summarised."""
    results = pathlib.Path(results)
    rows = []
    for seed in indices(seeds):
        path = results / f"calibration_stress_{seed}.json"
        if not path.exists():
            raise FileNotFoundError(f"no stored summary for suite seed {seed} ({path.name})")
        rows += json.loads(path.read_text())["rows"]
    return rows


# the counterfactual rules a run can take instead of the calibration's (each kept apart with --tag):
# (flag, what it does, the calibrate module holding the switch, the switch, the value it takes)
COUNTERFACTUALS = (
    ("--no-plate-level-gate", "try the anisotropic plate whatever the plate-frame drift shows (the rule before "
     "the gate)", "policy", "P_LEVEL", math.inf),  # no p reaches it: the plate is never withheld
    ("--servo-without-arms", "try a servo lag or dead time on sets without arm tracks too, as before the "
     "arm-track rule", "policy", "SERVO_WITHOUT_ARMS", True),
    ("--plate-both-sides", "also start the anisotropic plate's fit from the grid's best point on the other side "
     "of ratio 1 (tried on stored sets, not the rule)", "stages", "PLATE_BOTH_SIDES", True),
    ("--swapped-split", "calibrate with the odd trials training and the even ones held out, the other way round",
     "stages", "SPLIT_SWAPPED", True),
)


def apply_counterfactual(module: str, name: str, value) -> None:
    """Set one of :data:`COUNTERFACTUALS`' switches for the rest of this process."""
    import importlib
    setattr(importlib.import_module(f"smarticle_mjx.calibrate.{module}"), name, value)


# ------------------------------------------------------------------ readings of the suite

NOISE_KEYS = ("noise_xy_mm", "noise_theta_deg")  # the generator keywords of the tracking noise


def without_noise(s: dict) -> dict:
    """The set with its tracking noise left out (everything else as drawn)."""
    gen = {k: v for k, v in s["generator"].items() if k not in NOISE_KEYS}
    return {**s, "generator": gen}


SPLIT_BAR = 0.2  # the held-out gain the calibration asks of a joint hypothesis (stages.judged)


def stored_rows(folder) -> dict:
    """index -> stored row of every set under ``folder`` (empty where there is none)."""
    rows = [json.loads(p.read_text()) for p in sorted(folder.glob("set_*.json"))]
    return {r["set"]["index"]: r for r in rows}


def set_kind(s: dict) -> str:
    """What a set hides: "library effects", "outside only" or "clean"."""
    if s["hidden"]:
        return "library effects"
    return "outside only" if s["outside"] else "clean"


def tried_gains(row: dict) -> dict:
    """effect -> held-out gain of every joint hypothesis tried on a row's first pass."""
    return {h["effect"]: h["heldout_gain"] for h in row.get("hypotheses") or []
            if h.get("tried") and h.get("heldout_gain") is not None}


def split_compare(rule: dict, swapped: dict) -> list[dict]:
    """One line per set stored both ways: hidden, added and right on each split, and the joint hypotheses'
    gains on each."""
    out = []
    for i in sorted(set(rule) & set(swapped)):
        a, b = rule[i], swapped[i]
        ga, gb = tried_gains(a), tried_gains(b)
        out.append({"index": i, "hidden": a["set"]["hidden"], "outside": a["set"]["outside"],
                    "kind": set_kind(a["set"]), "added_rule": a["score"]["added"], "added_swapped": b["score"]["added"],
                    "same_added": a["score"]["added"] == b["score"]["added"],
                    "right_rule": bool(a["score"]["right"]), "right_swapped": bool(b["score"]["right"]),
                    "gains": {e: {"rule": ga[e], "swapped": gb[e], "mean": (ga[e] + gb[e]) / 2}
                              for e in sorted(set(ga) & set(gb))}})
    return out


def split_summary(lines: list[dict]) -> dict:
    """Per kind of set: compared, same effects, right on each split and on both; per joint hypothesis, how
    often its gain reached the bar on each split and on their mean."""
    by_kind = {}
    for k in ("library effects", "clean", "outside only"):
        ls = [x for x in lines if x["kind"] == k]
        by_kind[k] = {"sets": len(ls), "same_added": sum(x["same_added"] for x in ls),
                      "right_rule": sum(x["right_rule"] for x in ls),
                      "right_swapped": sum(x["right_swapped"] for x in ls),
                      "right_both": sum(x["right_rule"] and x["right_swapped"] for x in ls)}
    hyp = {}
    for x in lines:
        for e, g in x["gains"].items():
            h = hyp.setdefault(e, {"hidden": {"tried": 0, "rule": 0, "swapped": 0, "mean": 0},
                                   "not hidden": {"tried": 0, "rule": 0, "swapped": 0, "mean": 0}})
            c = h["hidden" if e in x["hidden"] else "not hidden"]
            c["tried"] += 1
            for w in ("rule", "swapped", "mean"):
                c[w] += g[w] >= SPLIT_BAR
    return {"by_kind": by_kind, "gain_at_bar": hyp, "bar": SPLIT_BAR}


DEFAULT_NOISE = (0.02, 0.02)  # write_case's tracking noise when no tracking_noise effect is hidden (mm, deg)
VISIBLE = 0.2  # the calibration's held-out gain rule (calibrate/fit.py MIN_HELDOUT_GAIN)


def _write_noise_free(s: dict, out, drop: set[str]) -> None:
    """The set's generator tracks with no tracking noise and without the hidden effects in ``drop``."""
    build = IND.Build(**s["build"])
    gen = {k: v for k, v in s["generator"].items() if k not in NOISE_KEYS}
    for e in drop:  # the generator keywords the suite draws for that effect (any draw names the same ones)
        for k in _effect(e, np.random.default_rng(0))[0]:
            gen.pop(k, None)
    for j, a in enumerate(s["amplitudes"]):
        IND.write_case(out, robots=s["robots"], amplitude_deg=float(a), trials=s["trials_per_amplitude"],
                       periods=s["periods"], seed=s["data_seed"] + j, frame_rate=s["frame_rate_hz"],
                       name=f"a{a}", arms_tracked=s["arms_tracked"], chirality=s["chirality"], build=build,
                       noise_xy_mm=0.0, noise_theta_deg=0.0, noise_arm_deg=0.0, **gen)


def _error(meas, model, noise) -> float:
    """The calibration's held-out error of the measured trials against generator tracks (held-out half)."""
    v = []
    for tr, mt in list(zip(meas, model))[1::2]:
        track = np.concatenate([mt.pose, mt.arms if mt.arms is not None else np.full(mt.pose.shape[:2] + (2,),
                                                                                      np.nan)], -1)
        pose, arms = masked(track, tr)
        f_meas = features(tr.t, tr.pose, tr.arms, tr.periods)
        f_mod = features(tr.t, pose, arms, tr.periods)
        v += [b for b in residual_blocks(f_meas, f_mod, noise).values()]
    v = np.concatenate(v) if v else np.zeros(0)
    return float(np.mean(v ** 2)) if len(v) else 0.0


def _noise(s: dict, without_noise: bool) -> tuple[float, float]:
    g = s["generator"]
    if without_noise or "noise_xy_mm" not in g:
        return DEFAULT_NOISE
    return g["noise_xy_mm"], g["noise_theta_deg"]


def visibility(s: dict) -> dict:
    """What leaving each hidden effect out costs a perfect model of the set's robot (the generator itself) on the
    held-out trials, by the calibration's own yardstick (benchmarks/calibration_visibility.py): ``err_full``,
    the generator's noise-free tracks against the data, and per hidden effect ``error_without`` and its
    ``signal``, the rise."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        write_set(s, tmp / "data")
        meas = load(tmp / "data")
        _write_noise_free(s, tmp / "full", set())
        full = load(tmp / "full")
        err_full = _error(meas, full, _noise(s, False))
        out = {}
        for e in s["hidden"]:
            d = tmp / f"without_{e}"
            _write_noise_free(s, d, {e})
            err_wo = _error(meas, load(d), _noise(s, e == "tracking_noise"))
            out[e] = {"error_without": err_wo, "signal": err_wo - err_full}
    return {"err_full": err_full, "effects": out}


def run_set(s: dict, plate_hypotheses: tuple[str, ...] | None = None, overrides: tuple = (), say=print) -> dict:
    """One set calibrated as ``smx calibrate`` would (``overrides``: its ``--set`` changes to the model, for
    the set and its clean twin alike), scored: the row the suite stores (``say``: each progress line)."""
    import time
    from .. import __version__
    from .fit import PLATE_HYPOTHESES
    from .stages import calibrate
    plate_hypotheses = PLATE_HYPOTHESES if plate_hypotheses is None else plate_hypotheses
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_set(s, tmp)
        trials = load(tmp, None, overrides)
        t = time.perf_counter()
        res = calibrate(trials, on_step=lambda m: say(f"    [{time.perf_counter() - t:5.0f} s] {m}"),
                        plate_hypotheses=plate_hypotheses).summary
        wall = time.perf_counter() - t
    twin = None
    if s["hidden"]:
        with tempfile.TemporaryDirectory() as tmp:
            write_set(s, tmp, effects=False)
            twin = calibrate(load(tmp, None, overrides), structural=False).summary["after"]["err_heldout"]
    return {"set": s, "score": score(s, res, twin), "wall_s": wall, "total_s": time.perf_counter() - t0,
            "model_runs": res["model_runs"], "plate_hypotheses": res.get("plate_hypotheses"),
            "fitted": {a["effect"]: a["values"] for a in res["added"]},
            "intervals": {a["effect"]: a["interval"] for a in res["added"]},
            "intervals_statistical": {a["effect"]: a.get("interval_statistical", a["interval"]) for a in res["added"]},
            "nominal_findings": res["nominal_findings"], "plate_level": res.get("plate_level"),
            # every joint hypothesis of the nominal stage as judged (values, gains, baseline, rule), and the
            # delay test, so that a miss can be read without running the set again
            "hypotheses": res.get("nominal_hypotheses"), "delay_test": res.get("delay_test"),
            # the held-out error before and with a tilt named from the drift
            "tilt_heldout": (res.get("drift") or {}).get("tilt_heldout"),
            # the invariants that fired: the tilt taken out again, the final guard
            "tilt_refused": ((res.get("drift") or {}).get("tilt_fit") or {}).get("refused"),
            "final_guard": res.get("final_guard"),
            "version": __version__, "source": source_hash(),
            **({"overrides": dict(overrides)} if overrides else {})}


def stored_set(spec: str, results, hides: str | None = None) -> dict:
    """The stored row of stress set ``spec`` ("seed/index", e.g. "2148/14") under ``results`` (the folder
    holding ``calibration_stress/``) as :func:`run_set` wrote it; SystemExit with a one-line message where
    the spec is malformed, the set was not run, or it does not hide ``hides``."""
    try:
        seed, index = parse_set(spec)
    except argparse.ArgumentTypeError as e:
        raise SystemExit(str(e)) from None
    path = pathlib.Path(results) / "calibration_stress" / str(seed) / f"set_{index:04d}.json"
    if not path.exists():
        raise SystemExit(f"no stored stress set {seed}/{index} (run benchmarks/calibration_stress.py first)")
    row = json.loads(path.read_text())
    if hides is not None and hides not in row["set"]["truth"]:
        raise SystemExit(f"stress set {seed}/{index} hides no {hides}")
    return row
