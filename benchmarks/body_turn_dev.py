"""Can a servo's timing be read off a lone robot's body where no arm is tracked? A development probe on the
stress suite, kept because its answer (no, not this way) decides a rule of the calibration.

The calibration tries no servo lag or dead time on sets that track no arm (docs/calibration.md, "Structure
before numbers"). A lone robot's body turns a little each time an arm starts or stops and rests between, so
the turns carry the arms' timing. This probe reads it the way the delay test reads the arms: per gait, the
**body turn time** is the centroid, weighted by the squared heading rate above its median (the tracker's
noise floor), of the frames within half a quarter either side of each commanded switch, per switch and
cycle, averaged over groups (trial, robot, switch) like the arm delay; its excess over the preset model's
(the same reading on the model's tracks at the data's frames) goes through the delay test's split
(constant + slope x amplitude, thresholds unchanged). Beside it, per set: the delay test on the arms (every
set is written with its arms tracked; the body's track is the same either way) and how far the body turns per
switch in the data and in the preset model.

Development only: sets of suite seeds already run and read (2040-2044), chosen by what they hide before any
was read: a servo lag alone, a dead time alone, nothing, or library effects other than a servo timing (no
outside effect), up to ``--per-class`` of each in seed and index order.

    python benchmarks/body_turn_dev.py [--per-class 8]    # ~10 s a set on one core; results/body_turn_dev.json
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import tempfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
from smarticle_mjx.calibrate import stress as CS  # noqa: E402

from smarticle_mjx import __version__  # noqa: E402
from smarticle_mjx.calibrate import observables as OB  # noqa: E402
from smarticle_mjx.calibrate.data import load  # noqa: E402
from smarticle_mjx.calibrate.drift import robot_alone  # noqa: E402
from smarticle_mjx.calibrate.effects import EffectSet  # noqa: E402
from smarticle_mjx.calibrate.fit import Problem, split, stage_tracks  # noqa: E402

SEEDS = (2040, 2041, 2042, 2043, 2044)
KEY = "body_turn_ms"


def kind(s: dict) -> str | None:
    if s["outside"]:
        return None
    h = s["hidden"]
    if not h:
        return "clean"
    if h == ["servo_lag"]:
        return "lag"
    if h == ["servo_dead_time"]:
        return "dead time"
    if not set(h) & set(CS.SERVO):
        return "other"
    return None


def chosen(per_class: int) -> list[tuple[int, int, str]]:
    return CS.choose_sets(SEEDS, kind, per_class)


def turns(trials, tracks=None) -> tuple[dict, float]:
    """({KEY: rows per gait}, median turn per switch in degrees) of measured trials or of model tracks."""
    per, sizes = {}, []
    for k, tr in enumerate(trials):
        pose = tr.pose if tracks is None else tracks[k][..., :3]
        t0 = float(tr.t[0])
        for i, g in enumerate(tr.gaits):
            if not robot_alone(tr.pose, i, tr.params.robot.body_length):
                continue
            T = g.period()
            h = pose[:, i, 2]
            ok = np.isfinite(h) & (tr.t >= t0 + OB.SETTLE * T)
            t, hh = tr.t[ok], h[ok]
            dt = np.diff(t)
            adj = dt <= 1.6 / tr.frame_rate_hz
            r = (np.diff(hh) / dt)[adj]
            m = (0.5 * (t[1:] + t[:-1]))[adj]
            r = r - np.median(r)
            w = np.clip(r ** 2 - np.median(r ** 2), 0.0, None)
            u = (m - t0) / T
            for j, (_, _, p) in enumerate(OB._command_switches(g)):
                rel = np.mod(u - p + 0.5, 1.0) - 0.5
                cyc = np.round(u - p - rel).astype(int)
                sel = np.abs(rel) < 0.125
                for c in np.unique(cyc[sel]):
                    s2 = sel & (cyc == c)
                    sizes.append(float(np.degrees(np.abs(np.sum(r[s2] * dt[adj][s2])))))
                    if w[s2].sum() > 0:
                        per.setdefault(g, []).append((1e3 * T * np.sum(w[s2] * rel[s2]) / w[s2].sum(), (k, i, j)))
    rows = []
    for g, v in per.items():
        x = np.array([a for a, _ in v])
        grp = np.array([b for _, b in v])
        rows.append({"gait": OB._gait_label(g), "amplitude_deg": float(g.amplitude_deg), **OB.grouped_mean_se(x, grp)})
    return {KEY: rows}, float(np.median(sizes)) if sizes else float("nan")


def verdict(d) -> str:
    if not d.applicable:
        return "n/a"
    return "delay" if d.constant_delay else "none" if d.no_constant_delay else "undecided"


def one(seed: int, index: int, k: str) -> dict:
    s = {**CS.draw_set(seed, index), "arms_tracked": True}
    with tempfile.TemporaryDirectory() as tmp:
        CS.write_set(s, tmp)
        trials = load(tmp)
    train_t, test_t = split(trials)
    train, test = Problem(train_t), Problem(test_t)
    mt = stage_tracks(train, test, trials, {}, EffectSet())
    (d, size_d), (m, size_m) = turns(trials), turns(trials, mt)
    body = OB.delay_test(d, m, KEY)
    arm = OB.delay_test(OB.observables(trials), OB.observables(trials, mt))
    size = next(iter(next(iter(s["truth"].values())).values())) * 1e3 if k in ("lag", "dead time") else 0.0
    return {"suite_seed": seed, "index": index, "class": k, "hidden": s["hidden"], "size_ms": size,
            "frame_rate_hz": s["frame_rate_hz"], "servo_ff": s["build"]["servo_ff"],
            "servo_slew": s["build"]["servo_slew"] is not None, "turn_deg_data": size_d, "turn_deg_model": size_m,
            "body": {**body.as_dict(), "verdict": verdict(body)}, "arm": {**arm.as_dict(), "verdict": verdict(arm)}}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--per-class", type=int, default=8)
    args = ap.parse_args()
    rows = []
    for seed, index, k in chosen(args.per_class):
        r = one(seed, index, k)
        rows.append(r)
        b, a = r["body"], r["arm"]
        print(f"{seed}/{index} {k} {r['size_ms']:.0f} ms {r['frame_rate_hz']:.0f} Hz: turn per switch "
              f"{r['turn_deg_data']:.3f} deg (model {r['turn_deg_model']:.4f}); body constant "
              f"{b['constant_ms']:+.1f} +- {b['constant_se_ms']:.1f} {b['verdict']} | arm constant "
              f"{a['constant_ms']:+.1f} +- {a['constant_se_ms']:.1f} {a['verdict']}", flush=True)
    table = {}
    for r in rows:
        t = table.setdefault(r["class"], {})
        key = f"body {r['body']['verdict']}, arm {r['arm']['verdict']}"
        t[key] = t.get(key, 0) + 1
    for c, t in table.items():
        print(c, t)
    out = {"package": __version__, "seeds": SEEDS, "per_class": args.per_class, "table": table, "sets": rows}
    (ROOT / "results" / "body_turn_dev.json").write_text(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
