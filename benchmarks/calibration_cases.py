"""The two never-seen sets of docs/calibration.md rebuilt with the independent robot, calibrated as a
user would, timed (the 8-trial target: <= 5 minutes on 2 cores).

* set A: lone robots, ccw, 15/25/40/70 deg (period proportional to amplitude), 2 trials x 5 periods each,
  arms and bodies at 90 Hz; hidden: a 30 ms first-order servo lag;
* set B: lone robots, ccw, 45 and 90 deg, 4 trials x 6 periods each, bodies only at 30 Hz; hidden: the
  plate tilted 1 deg toward azimuth 200 deg.

    python benchmarks/calibration_cases.py            # both, ~5 min on 2 cores

Writes results/calibration_cases.json.
"""

from __future__ import annotations

import json
import math
import pathlib
import platform
import tempfile
import time

from smarticle_mjx import __version__
from smarticle_mjx.calibrate import independent as IND
from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.stages import calibrate

ROOT = pathlib.Path(__file__).resolve().parent
AZ = math.radians(200.0)
TILT = (math.cos(AZ), math.sin(AZ))  # 1 deg toward 200 deg, the library's (x, y)
CASES = {
    "A": dict(amps=(15, 25, 40, 70), trials=2, periods=5, frame_rate=90.0, arms=True, effects={"lag_s": 0.03},
              truth={"servo_lag": None}),
    "B": dict(amps=(45, 90), trials=4, periods=6, frame_rate=30.0, arms=False,
              effects={"tilt_deg": (-TILT[1], TILT[0])},
              truth={"plate_tilt": {"tilt_x_deg": TILT[0], "tilt_y_deg": TILT[1]}}),
}


def run(name: str) -> dict:
    c = CASES[name]
    with tempfile.TemporaryDirectory() as tmp:
        for a in c["amps"]:
            IND.write_case(tmp, amplitude_deg=float(a), name=f"a{a}", trials=c["trials"], periods=c["periods"],
                           seed=100 + a, frame_rate=c["frame_rate"], arms_tracked=c["arms"], **c["effects"])
        trials = load(tmp)
        t0 = time.perf_counter()
        lines = []
        res = calibrate(trials, on_step=lambda m: (lines.append(f"[{time.perf_counter() - t0:4.0f} s] {m}"),
                                                   print(lines[-1], flush=True))).summary
        wall = time.perf_counter() - t0
    tilt = (res["drift"].get("tilt_fit") or {})
    return {"case": name, "trials": len(trials), "wall_s": wall, "model_runs": res["model_runs"],
            "verdict": res["verdict"], "added": [(a["effect"], a["values"], a["interval"]) for a in res["added"]],
            "truth": c["truth"], "delay_test": res.get("delay_test"),
            "tilt": {k: tilt.get(k) for k in ("tilt_deg", "magnitude_deg", "magnitude_interval", "direction_deg",
                                              "size_determined", "discrepancy")} if tilt else None,
            "heldout": [res["before"]["err_heldout"], res["after_nominal"]["err_heldout"],
                        res["after"]["err_heldout"]], "progress": lines}


def main():
    import sys
    names = sys.argv[1:] or list(CASES)  # e.g. `python benchmarks/calibration_cases.py B`
    path = ROOT / "results" / "calibration_cases.json"
    kept = [r for r in json.loads(path.read_text())["rows"] if r["case"] not in names] if path.exists() else []
    rows = sorted(kept + [run(n) for n in names], key=lambda r: r["case"])
    out = {"package": __version__, "machine": platform.processor() or platform.machine(),
           "date": time.strftime("%Y-%m-%d"), "rows": rows}
    path.write_text(json.dumps(out, indent=1, default=float))
    for r in rows:
        print(f"set {r['case']}: {r['trials']} trials, {r['wall_s']:.0f} s, {r['model_runs']} runs, {r['verdict']}")


if __name__ == "__main__":
    main()
