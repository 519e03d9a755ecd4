"""The discovery diagnosis at the collision level: what one arm hit slides a struck robot
(sweeps/probes/discovery_hits.toml, written before it ran, says why and what was predicted).

Every trial of each variant is simulated again from the spread screen's own configuration (the same starts,
robots, start delays and per-cycle retrigger as its relaxation stores), recording the collision record and a
full-rate track, and read by ``reduce.collisions.arm_hits``. Per variant: the hits counted and left out,
median [quartiles] of the slide, push and coast per hit, and the coast share with a 95 % bootstrap interval
over trials.

    python benchmarks/discovery_hits.py [--probe sweeps/probes/discovery_hits.toml]
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import sys
import time
import tomllib

import numpy as np

from smarticle_mjx import presets
from smarticle_mjx.bench import save_json
from smarticle_mjx.engine.core import Record
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.reduce import collisions as RC
from smarticle_mjx.relax import retrigger_of, start_poses
from smarticle_mjx.studyfile import read_relax_screen

ROOT = pathlib.Path(__file__).resolve().parent


def trial_hits(cfg, params, trial: int, periods: int, bins: int, track_ms: float) -> RC.HitSlides:
    one = dataclasses.replace(cfg, first_trial=trial, trials=1)
    start, phase = start_poses(one, params)
    stride = max(1, int(round(track_ms * 1e-3 / params.timestep)))
    res = simulate(params, start[0], cfg.gait_spec(), periods, phase=phase[0],
                   record=Record(track_stride=stride, collisions=True, collision_bins=bins),
                   imperfections=cfg.robots(), row=trial, start_delays=True,
                   retrigger=retrigger_of(cfg, trial)[0] if cfg.retrigger_sd > 0 else None)
    t = np.concatenate([[0.0], res.track_t])
    poses = np.concatenate([start[0][None], res.track], 0)
    return RC.arm_hits(res.collisions["steps"], res.pairs, res.period, t, poses)


def boot_share(per_trial: list[RC.HitSlides], rng, n: int = 2000) -> tuple[float, float]:
    out = []
    for _ in range(n):
        pick = rng.integers(0, len(per_trial), len(per_trial))
        push = sum(h.push_mm for i in pick for h in per_trial[i].hits)
        coast = sum(h.coast_mm for i in pick for h in per_trial[i].hits)
        out.append(coast / (push + coast) if push + coast > 0 else np.nan)
    lo, hi = np.nanpercentile(out, [2.5, 97.5])
    return float(lo), float(hi)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--probe", type=pathlib.Path, default=ROOT.parent / "sweeps/probes/discovery_hits.toml")
    ap.add_argument("--model", default=presets.DEFAULT)
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "results" / "discovery_hits.json")
    args = ap.parse_args()
    try:
        probe = tomllib.loads(args.probe.read_text())["probe"]
        _, studies = read_relax_screen(ROOT.parent / probe["study"])
        missing = [k for k in ("variants", "trials", "periods", "bins", "track_ms") if k not in probe]
        if missing:
            raise KeyError(", ".join(missing))
        unknown = [v for v in probe["variants"] if v not in studies]
        if unknown:
            raise ValueError(f"{args.probe}: variants {unknown} are not in {probe['study']}")
    except KeyError as e:
        sys.exit(f"error: {args.probe} lacks {e} in its [probe] table")
    except (OSError, ValueError, tomllib.TOMLDecodeError) as e:
        sys.exit(f"error: {e}")
    res = {"probe": probe, "model": args.model, "variants": {}}
    for name in probe["variants"]:
        t0 = time.perf_counter()
        cfg = studies[name].stage_config(0, args.model)
        params = cfg.robots().scene(cfg.scene_params())
        per = [trial_hits(cfg, params, k, probe["periods"], probe["bins"], probe["track_ms"])
               for k in range(probe["trials"])]
        allh = sum(per[1:], per[0])
        row = allh.as_dict()
        row["coast_share_ci"] = boot_share(per, np.random.default_rng(0))
        row["hits_per_trial"] = [len(p.hits) for p in per]
        row["wall_s"] = time.perf_counter() - t0
        res["variants"][name] = row
        save_json(args.out, res)
        s, pu, co = row["slide_mm"], row["push_mm"], row["coast_mm"]
        print(f"{name}: {row['hits']} hits ({row['left_out']} left out); slide {s['median']:.2f} "
              f"[{s['q25']:.2f}, {s['q75']:.2f}] mm, push {pu['median']:.2f}, coast {co['median']:.3f} mm; "
              f"coast share {row['coast_share']:.3f} [{row['coast_share_ci'][0]:.3f}, {row['coast_share_ci'][1]:.3f}]"
              f" ({row['wall_s']:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
