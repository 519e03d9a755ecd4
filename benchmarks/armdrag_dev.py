"""The arm-drag reading (smarticle_mjx.calibrate.armdrag) on every set of a stress-suite seed, without any
fit: one JSON line per set (what is hidden, the frame rate, amplitudes, whether arms are tracked, the true
arm-plate mu, the reading). Used on the seen development seeds 2042 and 2043 (results/armdrag_dev/).

    python benchmarks/armdrag_dev.py 2043 0-59 > benchmarks/results/armdrag_dev/2043.jsonl
"""

import json
import pathlib
import sys
import tempfile
import time

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))

from smarticle_mjx.calibrate import stress as CS  # noqa: E402

from smarticle_mjx.calibrate import data as D  # noqa: E402
from smarticle_mjx.calibrate.armdrag import drag_test  # noqa: E402


def main():
    seed = int(sys.argv[1])
    lo, hi = map(int, sys.argv[2].split("-"))
    for j in range(lo, hi + 1):
        s = CS.draw_set(seed, j)
        t0 = time.time()
        with tempfile.TemporaryDirectory() as d:
            CS.write_set(s, d)
            dt = drag_test(D.load(d))
        print(json.dumps({"seed": seed, "index": j, "hidden": s["hidden"], "outside": s["outside"],
                          "fr": s["frame_rate_hz"], "amps": s["amplitudes"], "arms": s["arms_tracked"],
                          "robots": s["robots"], "mu": s["truth"].get("arm_plate_contact", {}),
                          "test": None if dt is None else dt.as_dict(), "s": round(time.time() - t0, 1)}), flush=True)


if __name__ == "__main__":
    main()
