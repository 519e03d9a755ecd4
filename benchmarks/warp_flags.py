"""Which lanes of a scan store were flagged (penetration beyond the limit, a
non-finite state), and do they flag again when run alone, on another backend,
in Warp's deterministic mode or at a finer step?

    # on a GPU: the paper scan on Warp, its store kept, then its flagged lanes again
    python benchmarks/full_scan.py --backend warp --batch-size 8192 --store S.h5 --out scan.json
    python benchmarks/warp_flags.py --store S.h5 --backend warp --out warp_rerun.json
    python benchmarks/warp_flags.py --store S.h5 --backend warp --deterministic --out warp_det.json
    python benchmarks/warp_flags.py --store S.h5 --backend warp --timestep 0.000125 --out warp_half.json
    python benchmarks/warp_flags.py --store S.h5 --backend warp --box-collider convex --out warp_gjk.json
    # here, on the CPU: the same lanes on MuJoCo C (float64)
    python benchmarks/warp_flags.py --store S.h5 --backend native --out native_rerun.json

The lanes are the store's own (its scan configuration, model, amplitude and
robots, rebuilt from the store's attributes), so a rerun starts each lane
exactly where the scan started it. Each rerun runs the lanes as one batch (no
other lanes beside them) for the scan's periods with the scan's early-exit
rule; a flagged lane retires at the chunk in which it was flagged, as in the
scan. Per lane the JSON gives the store's first flagged period and deepest
inter-robot contact, and the rerun's. Nothing in the store is changed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import pathlib
import time

import numpy as np


from full_scan import _device  # what ran the engine, as the paper scan's JSON names it
from smarticle_mjx import __version__
from smarticle_mjx.engine import Lanes, Scene, make_backend
from smarticle_mjx.engine.batch import RetireRule, run_lanes
from smarticle_mjx.engine.mjwarp import BOX_COLLIDER, BOX_COLLIDERS
from smarticle_mjx.scan import RunInputs
from smarticle_mjx.scene import params_from_json
from smarticle_mjx.specs import config_from_json
from smarticle_mjx.store import BAD_STATUS, Store, StoreError

LIMIT = 0.002  # the engines' penetration flag (m)


def lane_summary(min_dist: np.ndarray, status: int, periods_run: int) -> dict:
    """One lane's flag record from its per-period deepest contacts [K, P] (m; inf where no touch)."""
    deepest = np.min(min_dist, axis=-1)  # [K], most negative signed distance per period
    past = np.flatnonzero(deepest < -LIMIT)
    finite = deepest[np.isfinite(deepest)]
    return {"status": int(status), "flagged": bool(status & BAD_STATUS),
            "first_period_past_limit": int(past[0]) if past.size else None,
            "deepest_mm": float(-finite.min() * 1e3) if finite.size else 0.0,
            "periods_run": int(periods_run)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--store", required=True, help="a scan store (HDF5)")
    ap.add_argument("--run", default=None, help="run name (default: the first)")
    ap.add_argument("--backend", default="native", help="native | warp | mjx")
    ap.add_argument("--deterministic", action="store_true", help="MuJoCo Warp's deterministic mode")
    ap.add_argument("--timestep", type=float, default=None, help="another step (s) for the rerun")
    ap.add_argument("--box-collider", choices=BOX_COLLIDERS, default=None,
                    help="Warp's box pairs: 'analytic' (the box-box collider MuJoCo C uses; the warp backend's "
                         "default since 0.4.2) or 'convex' (MuJoCo Warp's own GJK/EPA, the default before); "
                         "default: the backend's")
    ap.add_argument("--analytic-box", action="store_true", help="the same as --box-collider analytic")
    ap.add_argument("--replace", action="append", default=[], metavar="FIELD=VALUE",
                    help="change one numerical field of the stored scene for the rerun (e.g. iterations=100)")
    ap.add_argument("--lanes", default="flagged", help="'flagged' or comma-separated lane indices")
    ap.add_argument("--controls", type=int, default=0,
                    help="also rerun this many unflagged valid lanes, drawn with a fixed seed (a control)")
    ap.add_argument("--batch-size", type=int, default=256)
    ap.add_argument("--nthread", type=int, default=2, help="native backend threads")
    ap.add_argument("--sidecar", default=None, metavar="OUT.json",
                    help="run nothing: write the store's configuration and its flagged lanes (with --controls, "
                         "those too) to a small JSON that --store accepts in place of the store")
    ap.add_argument("--signature", action="store_true",
                    help="run nothing: the store's flagged lanes' depths against the robots' box sizes, and "
                         "how far the robots moved in the flagged period against the periods before")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    if args.signature:
        out = signature(args.store, args.run)
        pathlib.Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
        print(json.dumps({k: v for k, v in out.items() if k != "lanes"}, indent=1))
        return

    if args.sidecar:
        write_sidecar(args.store, args.run, args.controls, args.sidecar)
        return
    try:
        st = Sidecar(args.store) if str(args.store).endswith(".json") else Store(args.store)
    except (StoreError, OSError, ValueError) as e:
        raise SystemExit(f"error: {e}")
    run = args.run or st.runs[0]
    config = config_from_json(st.config["scan"])
    params = params_from_json(st.config["scene"])
    stored = st.run(run, fields=("valid", "status", "periods_run", "min_dist"))
    flagged = np.flatnonzero(stored["valid"] & ((stored["status"] & BAD_STATUS) > 0))
    if args.lanes == "flagged":
        idx = flagged
    else:
        idx = np.array(sorted({int(x) for x in args.lanes.split(",")}), dtype=int)
        bad = [int(i) for i in idx if not 0 <= i < stored["valid"].size or not stored["valid"][i]]
        if bad:
            raise SystemExit(f"lanes {bad} are out of range or were never simulated (overlapping start)")
    controls = np.array([], dtype=int)
    if args.controls:
        ok = np.flatnonzero(stored["valid"] & ((stored["status"] & BAD_STATUS) == 0))
        controls = np.sort(np.random.default_rng(0).choice(ok, size=min(args.controls, ok.size), replace=False))
    idx = np.concatenate([idx, controls]).astype(int)
    if idx.size == 0:
        raise SystemExit(f"{args.store}: no lanes to rerun (flagged lanes: {flagged.size})")
    if config.robot_draws != 1:
        raise SystemExit("scans that draw several robot pairs are not handled here")

    run_params = params if args.timestep is None else dataclasses.replace(params, timestep=args.timestep)
    for item in args.replace:
        field, _, value = item.partition("=")
        if not hasattr(run_params, field) or not value:
            raise SystemExit(f"--replace {item!r}: not FIELD=VALUE with a field of the scene")
        run_params = dataclasses.replace(run_params, **{field: type(getattr(run_params, field))(value)})
    inputs = RunInputs.of(config, params, float(st.run_attrs[run]["amplitude_deg"]))
    lanes = config.robots(0).lanes(Lanes.from_gait(inputs.poses[idx], inputs.gait), idx)
    options = dict(config.backend_options()) if args.backend == config.backend else {}
    if args.deterministic:
        options["deterministic"] = True
    if args.analytic_box:
        args.box_collider = "analytic"
    if args.backend == "warp":
        args.box_collider = args.box_collider or BOX_COLLIDER
        options["box_collider"] = args.box_collider
    elif args.box_collider:
        raise SystemExit("--box-collider applies to the warp backend only")
    got: dict[int, dict] = {}

    def on_lanes(res):
        for j, q in enumerate(res.index):
            got[int(idx[q])] = lane_summary(res.min_dist[j], int(res.status[j]), int(res.periods_run[j]))

    t = time.perf_counter()
    scene = Scene.build(run_params, 2)
    with make_backend(args.backend, scene, nthread=args.nthread if args.backend == "native" else None,
                      **options) as backend:
        device = _device(args.backend)
        ran = run_lanes(backend, lanes, config.periods, batch_size=args.batch_size, chunk_periods=config.chunk_periods,
                        rule=RetireRule(quiet_periods=config.quiet_periods), on_lanes=on_lanes)
    wall = time.perf_counter() - t

    rows = []
    for lane in idx:
        before = lane_summary(stored["min_dist"][lane], int(stored["status"][lane]), int(stored["periods_run"][lane]))
        rows.append({"lane": int(lane), "control": bool(lane in set(controls.tolist())),
                     "config_r_theta_phi": [float(x) for x in inputs.cfg[lane]],
                     "store": before, "rerun": got[int(lane)]})
    fl = [r for r in rows if not r["control"]]
    ct = [r for r in rows if r["control"]]
    out = dict(store=str(args.store), store_backend=config.backend, store_timestep_s=params.timestep,
               backend=args.backend, device=device, deterministic=args.deterministic,
               timestep_s=run_params.timestep, integrator=params.integrator, replaced=args.replace,
               analytic_box=args.box_collider == "analytic", box_collider=args.box_collider,
               package=__version__,
               periods=int(config.periods), lanes_flagged_in_store=int(flagged.size), wall_s=wall,
               lane_periods=int(ran.get("lane_periods", 0)),
               flagged_again=sum(r["rerun"]["flagged"] for r in fl), of_flagged=len(fl),
               controls_flagged=sum(r["rerun"]["flagged"] for r in ct), controls=len(ct),
               deepest_mm_rerun_of_flagged=_quantiles([r["rerun"]["deepest_mm"] for r in fl]),
               deepest_mm_rerun_of_controls=_quantiles([r["rerun"]["deepest_mm"] for r in ct]),
               deepest_mm_store_of_controls=_quantiles([r["store"]["deepest_mm"] for r in ct]),
               rows=rows)
    pathlib.Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"{args.backend}{' deterministic' if args.deterministic else ''} at {run_params.timestep * 1e3:g} ms on "
          f"{device}: {out['flagged_again']} of {len(fl)} flagged lanes flagged again, "
          f"{out['controls_flagged']} of {len(ct)} controls; deepest (mm) flagged {out['deepest_mm_rerun_of_flagged']}, "
          f"controls {out['deepest_mm_rerun_of_controls']}; {wall:.0f} s")


def write_sidecar(store, run, controls: int, out) -> None:
    """The store's scan configuration, scene, amplitude and, for its flagged lanes (and ``controls``
    unflagged valid lanes drawn as a rerun draws them), the per-lane records a rerun compares with."""
    st = Store(store)
    run = run or st.runs[0]
    d = st.run(run, fields=("valid", "status", "periods_run", "min_dist"))
    flagged = np.flatnonzero(d["valid"] & ((d["status"] & BAD_STATUS) > 0))
    ok = np.flatnonzero(d["valid"] & ((d["status"] & BAD_STATUS) == 0))
    ctl = np.sort(np.random.default_rng(0).choice(ok, size=min(controls, ok.size), replace=False)) if controls else []
    lanes = sorted(set(flagged.tolist()) | {int(x) for x in ctl})
    md = d["min_dist"][lanes].astype(float)
    side = {"from_store": str(store), "run": run, "config": {k: st.config[k] for k in ("scan", "scene")},
            "run_attrs": {k: (v.item() if hasattr(v, "item") else v) for k, v in st.run_attrs[run].items()
                          if k == "amplitude_deg"},
            "n_lanes": int(d["valid"].size), "lanes": lanes,
            "valid": d["valid"][lanes].tolist(), "status": d["status"][lanes].tolist(),
            "periods_run": d["periods_run"][lanes].tolist(),
            "min_dist_mm": np.where(np.isfinite(md), md * 1e3, None).tolist()}
    pathlib.Path(out).write_text(json.dumps(side) + "\n")
    print(f"{out}: {len(flagged)} flagged lanes and {len(ctl)} controls of {store}")


class Sidecar:
    """A sidecar written by ``--sidecar`` read as the store it came from (only its lanes are valid)."""

    def __init__(self, path):
        self.d = json.loads(pathlib.Path(path).read_text())
        self.runs = [self.d["run"]]
        self.config = self.d["config"]
        self.run_attrs = {self.d["run"]: self.d["run_attrs"]}

    def run(self, run, fields):
        n, lanes = self.d["n_lanes"], np.array(self.d["lanes"], int)
        k = len(self.d["min_dist_mm"][0])
        md = np.full((n, k, len(self.d["min_dist_mm"][0][0])), np.inf)
        md[lanes] = np.array([[[np.inf if x is None else x / 1e3 for x in per] for per in lane]
                              for lane in self.d["min_dist_mm"]])
        out = {"valid": np.zeros(n, bool), "status": np.zeros(n, np.int32), "periods_run": np.zeros(n, np.int32),
               "min_dist": md}
        out["valid"][lanes] = self.d["valid"]
        out["status"][lanes] = self.d["status"]
        out["periods_run"][lanes] = self.d["periods_run"]
        return {f: out[f] for f in fields}


def signature(store, run=None) -> dict:
    """The flagged lanes' depth at their first flagged period, each named by the box size (a whole
    thickness, height or length of an arm or a body; sums of two) it equals within 0.05 mm, and the
    largest robot displacement and heading change in that period against the lane's median before it."""
    st = Store(store)
    run = run or st.runs[0]
    params = params_from_json(st.config["scene"])
    r = params.robot
    sizes = {"arm thickness": r.arm_thickness, "arm height": r.arm_height, "arm length": r.arm_length,
             "body thickness": r.body_thickness, "body height": r.body_height, "body length": r.body_length}
    sizes.update({f"2 x {k}": 2 * v for k, v in list(sizes.items())})
    d = st.run(run, fields=("valid", "status", "min_dist", "poses"))
    flagged = np.flatnonzero(d["valid"] & ((d["status"] & BAD_STATUS) > 0))
    lanes, named, moves = [], {}, []
    for lane in flagged:
        deepest = d["min_dist"][lane].min(-1)
        past = np.flatnonzero(deepest < -LIMIT)
        if not past.size:  # flagged as non-finite, not by depth
            lanes.append({"lane": int(lane), "status": int(d["status"][lane]), "depth_mm": None})
            continue
        k = int(past[0])
        depth = float(-deepest[k])
        name = next((n for n, v in sizes.items() if abs(depth - v) < 5e-5), None)
        named[name or "none"] = named.get(name or "none", 0) + 1
        p = d["poses"][lane].astype(float)
        step = np.linalg.norm(np.diff(p[:, :, :2], axis=0), axis=-1).max(-1)  # [K-1] largest robot move
        row = {"lane": int(lane), "status": int(d["status"][lane]), "period": k, "depth_mm": depth * 1e3,
               "equals": name}
        if k >= 3:
            row.update(move_mm=float(step[k - 1] * 1e3), median_move_before_mm=float(np.median(step[:k - 1]) * 1e3))
            moves.append(step[k - 1] / np.median(step[:k - 1]))
        lanes.append(row)
    return {"store": str(store), "timestep_s": params.timestep, "lanes_flagged": int(flagged.size),
            "depth_equals": named, "sizes_mm": {k: v * 1e3 for k, v in sizes.items()},
            "move_in_flag_period_over_median_before": _quantiles(moves), "lanes": lanes}


def _quantiles(x) -> dict | None:
    if not x:
        return None
    q = np.quantile(np.asarray(x, float), [0.0, 0.5, 0.9, 1.0])
    return {"min": float(q[0]), "median": float(q[1]), "p90": float(q[2]), "max": float(q[3])}


if __name__ == "__main__":
    main()
