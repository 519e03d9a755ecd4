"""Early flags against the start: every flagged relaxation trial whose flag came in its first periods,
run again from its store's start, robots and phases under three readings (written before it ran):

* ``newton-old``: the constraint solver the store used before gear play got CG (Newton) and the start
  of versions up to 0.4.0 (every robot's clock started at t = 0 at its drawn offset);
* ``cg-old``: the default solver now (``auto``: CG for gear play), the old start;
* ``cg-delays``: the default solver and start delays (version 0.4.1: each robot starts from its
  gait's first corner, the one furthest ahead at t = 0, the others their offset later).

A trial counts as flagged under a reading when the engine flags it (penetration beyond 2 mm or a
non-finite state) within the periods run. The trials are those of the flag-diagnosis JSONs given
(``benchmarks/flag_diagnosis.py``) with the flag in period <= ``--max-period``.

    python benchmarks/start_delays.py benchmarks/results/flag_diagnosis_lab_s00.json \
        benchmarks/results/flag_diagnosis_lab_s01-s04.json benchmarks/results/discovery_confirm.json \
        --out benchmarks/results/start_delays.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import platform
import time

import numpy as np

from smarticle_mjx import __version__
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.relax import start_poses
from smarticle_mjx.scene import params_from_json
from smarticle_mjx.specs import relax_config_from_json
from smarticle_mjx.store import Store

READINGS = (("newton-old", "Newton", False), ("cg-old", "auto", False), ("cg-delays", "auto", True))


def flagged_trials(paths, max_period: int) -> list[dict]:
    out = []
    for path in paths:
        d = json.loads(pathlib.Path(path).read_text())
        d = d.get("flag_diagnosis", d)
        for t in d.get("trials", []):
            e = t.get("event") or {}
            if e.get("period") is not None and e["period"] <= max_period:
                out.append(dict(store=t["store"], trial=int(t["trial"]), kind=t.get("kind"), period=int(e["period"]),
                                geoms=e.get("geoms")))
    return out


def run_trial(row: dict, periods: int) -> dict:
    st = Store(row["store"])
    config = relax_config_from_json(st.config["relax"])
    stored = params_from_json(st.config["scene"])
    start, phase = start_poses(dataclasses.replace(config, first_trial=row["trial"], trials=1), stored)
    out = dict(row)
    for name, solver, delays in READINGS:
        params = dataclasses.replace(stored, solver=solver)
        t = time.perf_counter()
        res = simulate(params, start[0], config.gait_spec(), periods, phase=phase[0], imperfections=config.robots(),
                       row=row["trial"], start_delays=delays)
        d = res.min_dist[np.isfinite(res.min_dist)]
        out[name] = dict(flagged=bool(res.status), status=int(res.status),
                         deepest_mm=float(-1e3 * d.min()) if d.size else 0.0, seconds=time.perf_counter() - t)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("diagnoses", nargs="+", type=pathlib.Path)
    ap.add_argument("--max-period", type=int, default=1)
    ap.add_argument("--periods", type=int, default=3)
    ap.add_argument("--out", type=pathlib.Path, default=pathlib.Path(__file__).parent / "results" / "start_delays.json")
    a = ap.parse_args(argv)
    rows = []
    for row in flagged_trials(a.diagnoses, a.max_period):
        if not pathlib.Path(row["store"]).exists():
            print(f"skipped {row['store']} trial {row['trial']}: store not here")
            continue
        r = run_trial(row, a.periods)
        rows.append(r)
        print(f"{pathlib.Path(r['store']).name} trial {r['trial']} ({r['kind']}, period {r['period']}): " +
              ", ".join(f"{n} {'FLAGGED' if r[n]['flagged'] else 'ok'} {r[n]['deepest_mm']:.2f} mm"
                        for n, _, _ in READINGS), flush=True)
    summary = {n: dict(flagged=sum(r[n]["flagged"] for r in rows), of=len(rows),
                       deepest_mm_max=max((r[n]["deepest_mm"] for r in rows if not r[n]["flagged"]), default=None))
               for n, _, _ in READINGS}
    print(json.dumps(summary))
    a.out.write_text(json.dumps(dict(package=__version__, machine=platform.platform(), periods=a.periods,
                                     max_period=a.max_period, readings=[list(x) for x in READINGS],
                                     summary=summary, trials=rows), indent=1))


if __name__ == "__main__":
    main()
