"""MuJoCo against its DART twin, starting with a lone robot (the first rows of the cross-engine study).

For one robot of the default model on the plate, running the square gait at
90 and 10 degrees for 12 periods, in each engine and numerics:

* net drift per cycle: |end - start| of the body centre at period ends over
  periods 2-12, per cycle, in W (the paper's lab: 1.5e-3 W per cycle at 90);
* slip per edge: the mean |displacement| of the body centre over one arm
  move and its dwell (a quarter period), in W: what an arm's start and stop
  kicks move the body (the closed-form estimate for a kick from rest at full
  speed: v^2 / 2 mu g, about 1.1e-3 W).

MuJoCo runs the default model at its step and a quarter of it; DART runs the
same SceneParams with its default FCL mesh detector at 0.1 ms and 0.05 ms,
and with the primitive detectors (fcl, ode, bullet) at 0.1 ms. Resumable:
rows already in the JSON are kept (delete it to re-measure).

    python benchmarks/twin.py            # ~4 minutes on one core
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import pathlib
import time

import numpy as np

from smarticle_mjx import formatting, presets
from smarticle_mjx.bench import save_json
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.gait import GaitSpec
from smarticle_mjx.reduce import transport

OUT = pathlib.Path(__file__).parent / "results" / "twin.json"


def _measures(quarters: np.ndarray, body_length: float) -> dict:
    """From body centres at every quarter period [4K + 1, 2]: drift and slip per edge (W), skipping period 1."""
    m = transport.lone_robot(quarters, samples_per_cycle=4, skip_cycles=1, unit=body_length)
    return {"drift_W_per_cycle": m.net_W_per_cycle, "slip_per_edge_W": m.slip_per_edge_W,
            "slip_per_edge_max_W": m.slip_per_edge_max_W}


def mujoco_row(params, gait: GaitSpec, periods: int) -> dict:
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    res = simulate(params, [(0, 0, 0, a0[0], a0[1])], gait, periods, track_stride=1)
    t = np.concatenate([[0.0], res.track_t])
    xy = np.concatenate([[[0.0, 0.0]], res.track[:, 0, :2]])
    T = res.track_t[-1] / periods
    idx = [int(np.argmin(np.abs(t - q * T / 4))) for q in range(4 * periods + 1)]
    return _measures(xy[idx], params.robot.body_length)


def dart_row(params, gait: GaitSpec, periods: int, numerics) -> dict:
    from smarticle_mjx.engine.dart import DartScene
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    sc = DartScene(params, [(0, 0, 0, a0[0], a0[1])], numerics)
    xy = [sc.poses()[0, :2]]

    def at_quarters(period, step, steps):
        if step + 1 in {round(q * steps / 4) for q in range(1, 5)}:
            xy.append(sc.poses()[0, :2])

    sc.run_gait(gait, periods, on_step=at_quarters)
    return _measures(np.array(xy), params.robot.body_length)


STORES = OUT.parent / "twin_runs"  # the scans' stores (not in the repository; resumable)
GLIDE = {"n": 32, "periods": 60, "burn_in": 10, "r_range": (0.8, 2.0), "seed": 1, "bins": 16}
RELAX = {"trials": 10, "periods": 60, "min_periods": 30, "seed": 0}
PB = {"n": 64, "periods": 30, "r_range": (0.5, 2.5), "seed": 1, "amplitudes": (30.0, 50.0, 70.0, 90.0)}


def valid_starts(params, amplitude: float, n: int, r_range, seed: int) -> np.ndarray:
    """[n, 3] (|r| W, theta, phi) of the first ``n`` random starts that do not
    overlap with the arms at the gait's first corner (the same starts in both engines)."""
    from smarticle_mjx import configs as C
    a0 = GaitSpec(amplitude).setpoints(0.0, params.robot.servo_speed)
    rng = np.random.default_rng(seed)
    out = []
    while sum(map(len, out)) < n:
        cf = C.random_configs(4 * n, rng, r_range)
        ok = C.poses_valid(C.pair_poses(cf[:, 0], cf[:, 1], cf[:, 2], a0[0], a0[1], params.robot), params.robot)
        out.append(cf[ok])
    return np.concatenate(out)[:n]


def scan_store(engine: str, name: str, starts: np.ndarray, amplitude: float, periods: int, collisions: bool,
               workers: int, model: str | None = None, params=None, dart_numerics=None) -> pathlib.Path:
    """Run (or resume) one explicit-start scan into ``twin_runs/<name>.h5``:
    DART through the Dask executor on ``workers`` processes, MuJoCo here."""
    from smarticle_mjx.scan import ScanConfig, run_scan
    STORES.mkdir(parents=True, exist_ok=True)
    out = STORES / f"{name}.h5"
    cfg = ScanConfig(configs="explicit", initial=tuple(tuple(float(v) for v in row) for row in starts),
                     amplitudes_deg=(amplitude,), periods=periods, backend="dart" if engine == "dart" else "native",
                     model=model or presets.DEFAULT, collisions=collisions, collision_bins=GLIDE["bins"],
                     batch_size=2 if engine == "dart" else 64, dart_numerics=dart_numerics)
    executor = None
    if engine == "dart":
        from smarticle_mjx.executors import DaskExecutor
        executor = DaskExecutor(workers=workers, shard_size=2)
    t = time.perf_counter()
    summary = run_scan(cfg, out, mode="resume" if out.exists() else "new", executor=executor, params=params,
                       on_progress=lambda p: print(f"  {out.name}: {p['done']}/{p['total']} "
                                                   f"({time.perf_counter() - t:.0f} s)", flush=True))
    print(f"{out.name}: {summary.wall_s:.0f} s", flush=True)
    return out


def store_tracks(path: pathlib.Path, body_length: float) -> dict:
    """Per-period tracks of a pair scan's store: com [M, K, 2] (W), rel [M, K, 3], touched [M, K]."""
    from smarticle_mjx import configs as C
    from smarticle_mjx.store import Store
    st = Store(path)
    fields = ("valid", "poses", "touched", "periods_run")
    if st.config["scan"].get("collisions"):
        fields += ("coll_steps", "coll_impulse", "coll_impulse_r")
    d = st.run(fields=fields)
    poses = np.asarray(d["poses"], float)
    r, th, ph = C.relative_coordinates(poses[:, :, 0], poses[:, :, 1], body_length)
    out = {"com": (poses[:, :, 0, :2] + poses[:, :, 1, :2]) / 2 / body_length, "rel": np.stack([r, th, ph], -1),
           "touched": np.asarray(d["touched"])[..., 0], "valid": np.asarray(d["valid"]),
           "periods_run": np.asarray(d["periods_run"])}
    if "coll_steps" in d:
        out["coll"] = {"steps": d["coll_steps"], "impulse": d["coll_impulse"], "impulse_r": d["coll_impulse_r"]}
    return out


def collision_level(coll: dict, touched: np.ndarray) -> dict:
    """The collision record per touching period (pair 0): impulse along r
    (N s; negative pushes the robots apart) in all and by the part of each
    robot, contact steps, and the fraction of touching periods with an
    attractive (positive) kind."""
    from smarticle_mjx.reduce import collisions as RC
    t = RC.period_totals(coll)
    on = touched.astype(bool)
    ir, st = t.impulse_r[..., 0][on], t.steps[..., 0][on]
    by = t.impulse_r_by_kind[..., 0, :][on]
    group = {"arm-arm": [k for k, n in enumerate(RC.KINDS) if "body" not in n],
             "arm-body": [k for k, n in enumerate(RC.KINDS) if n.count("body") == 1],
             "body-body": [RC.KINDS.index("body-body")]}
    return {"touching_periods": int(on.sum()),
            "impulse_r_per_period_Ns": float(ir.mean()) if on.any() else None,
            "abs_impulse_r_per_period_Ns": float(np.abs(by).sum(-1).mean()) if on.any() else None,
            "impulse_r_by_parts_Ns": {g: float(by[:, ks].sum(-1).mean()) for g, ks in group.items()} if on.any() else {},
            "contact_steps_per_period": float(st.mean()) if on.any() else None,
            "attractive_fraction": float((by > 0).any(-1).mean()) if on.any() else None}


def pairs_part(engine: str, workers: int, rows: dict, servo: str = "constraint", detector: str = "fcl-mesh",
               step: float = 1e-4):
    """Gliders from ``GLIDE['n']`` random 90-degree starts and their collision record.
    DART: ``servo`` "pd" runs the default's PD + lag law as joint forces, without
    armature; ``detector`` and ``step`` other than the defaults test the twin's numerics."""
    from smarticle_mjx.reduce import gliders
    params, numerics, label = presets.params(), None, engine
    if engine == "dart" and (servo, detector, step) != ("constraint", "fcl-mesh", 1e-4):
        numerics = (step, detector, "dantzig") + ((servo,) if servo != "constraint" else ())
        label = " ".join([engine] + (["pd"] if servo == "pd" else []) + ([detector] if detector != "fcl-mesh" else [])
                         + ([f"{step * 1e3:g}ms"] if step != 1e-4 else []))
    if servo == "pd":
        params = params.replace(robot=dataclasses.replace(params.robot, servo_armature=0.0))
    name = f"glide_{GLIDE['n']}x{GLIDE['periods']}_s{GLIDE['seed']}"
    if name in rows.get(label, {}):
        return
    starts = valid_starts(params, 90.0, GLIDE["n"], GLIDE["r_range"], GLIDE["seed"])
    t = time.perf_counter()
    path = scan_store(engine, f"{label.replace(' ', '_')}_{name}", starts, 90.0, GLIDE["periods"], True, workers,
                      params=params if servo == "pd" else None, dart_numerics=numerics)
    tr = store_tracks(path, params.robot.body_length)
    summary = gliders.glide_summary(tr["com"], tr["rel"], tr["touched"], GLIDE["burn_in"]).as_json()
    summary.update({"starts": GLIDE["n"], "periods": GLIDE["periods"], "burn_in": GLIDE["burn_in"],
                    "wall_s": time.perf_counter() - t, "lane_periods": int(tr["periods_run"].sum())})
    summary["collisions"] = collision_level(tr["coll"], tr["touched"])
    rows.setdefault(label, {})[name] = summary


def pb_part(engine: str, workers: int, rows: dict, label: str | None = None, model=None, save=None):
    """P_b (bound in the last period) at 30/50/70/90 degrees from ``PB['n']`` random starts each."""
    from smarticle_mjx.reduce import binding
    params = presets.params(model)
    label = label or engine
    for a in PB["amplitudes"]:
        name = f"pb{a:g}_{PB['n']}x{PB['periods']}_s{PB['seed']}"
        if name in rows.get(label, {}):
            continue
        starts = valid_starts(params, a, PB["n"], PB["r_range"], PB["seed"])
        t = time.perf_counter()
        path = scan_store(engine, f"{label.replace(' ', '_')}_{name}", starts, a, PB["periods"], False, workers,
                          model=model)
        tr = store_tracks(path, params.robot.body_length)
        p = binding.binding_probability(tr["touched"], tr["valid"])
        rows.setdefault(label, {})[name] = {"n": p.n, "periods": PB["periods"], "end": dataclasses.astuple(p.end),
                                            "throughout": dataclasses.astuple(p.throughout),
                                            "wall_s": time.perf_counter() - t,
                                            "lane_periods": int(tr["periods_run"].sum())}
        if save:
            save()


def _relax_stage(engine: str, first: int, trials: int) -> str:
    from smarticle_mjx.relax import RelaxConfig, run_relax
    STORES.mkdir(parents=True, exist_ok=True)
    out = STORES / f"{engine}_relax_{RELAX['trials']}x{RELAX['periods']}_t{first}.h5"
    cfg = RelaxConfig(trials=trials, first_trial=first, periods=RELAX["periods"], seed=RELAX["seed"],
                      backend="dart" if engine == "dart" else "native", batch_size=1 if engine == "dart" else 4)
    run_relax(cfg, out, mode="resume" if out.exists() else "new")
    return str(out)


def relax_part(engine: str, workers: int, rows: dict):
    """The relaxation experiment (7 robots, compressed and in phase) on
    ``RELAX['trials']`` trials; DART's trials split into one stage per worker
    process. Gliders here are pairs bound and apart for >= RELAX['min_periods']
    periods (the paper keeps gliders that survive 30 cycles; the lab's 100
    do not fit in these trials)."""
    from concurrent.futures import ProcessPoolExecutor
    from smarticle_mjx.reduce import relaxation
    from smarticle_mjx.store import read_relax
    name = f"relax_{RELAX['trials']}x{RELAX['periods']}_s{RELAX['seed']}"
    if name in rows.get(engine, {}):
        return
    k = workers if engine == "dart" else 1
    cuts = np.linspace(0, RELAX["trials"], k + 1).round().astype(int)
    t = time.perf_counter()
    with ProcessPoolExecutor(k) as pool:
        paths = list(pool.map(_relax_stage, [engine] * k, cuts[:-1].tolist(), np.diff(cuts).tolist()))
    a = relaxation.analyse_relaxation(read_relax(paths), min_periods=RELAX["min_periods"]).as_json()
    rows.setdefault(engine, {})[name] = {
        "trials": a["valid"], "periods": RELAX["periods"], "min_periods": RELAX["min_periods"],
        "emerged": a["emerged"], "fraction": a["fraction"], "interval": a["interval"],
        "relaxation_periods": a["relaxation_periods"], "distance_W": a["distance"],
        "glider_lifetime": a["glider_lifetime"], "stopped_early": a["stopped_early"],
        "per_trial": [{k2: r[k2] for k2 in ("trial", "gliders", "relaxation_periods", "periods_run")}
                      for r in a["per_trial"]],
        "wall_s": time.perf_counter() - t}


def _set_opt(**fields):
    def edit(model):
        for k, v in fields.items():
            setattr(model.opt, k, v)
    return edit


# Each of MuJoCo's modelling choices switched alone from the default model:
# name -> (SceneParams changes, RobotParams changes, edit of the compiled MjModel)
VARIANTS = {
    "default": ({}, {}, None),
    "armature 0": ({}, {"servo_armature": 0.0}, None),
    "servo without lag": ({}, {"servo_timeconst": 0.0}, None),
    # DART's SERVO law as a stiff velocity loop (the `dart` servo of presets.py) within the default's torque
    "velocity servo": ({}, {"servo_kv": 0.003, "servo_kp": 0.003 / 1.6, "servo_armature": 0.0,
                            "servo_timeconst": 0.0}, None),
    # a blocked arm pushes at the torque bound, as DART's SERVO constraint does: a position loop that
    # saturates 0.078 N m at 1 degree of error (the `stiff` servo of presets.py at the default's bound)
    "stiff servo": ({}, {"servo_kp": 0.078 / math.radians(1.0), "servo_kv": None, "servo_armature": 0.0,
                         "servo_timeconst": 0.0}, None),
    "pyramidal cone": ({}, {}, _set_opt(cone=0)),  # the default is elliptic
    "impratio 10": ({}, {}, _set_opt(impratio=10.0)),
    "noslip 10": ({}, {}, _set_opt(noslip_iterations=10)),
    "contacts 1 ms": ({"contact_timeconst": 1e-3}, {}, None),  # 2 steps of 0.5 ms, the stiffest stable
    "step 0.125 ms": ({"timestep": 1.25e-4}, {}, None),
    "step 0.1 ms with contacts 0.2 ms": ({"timestep": 1e-4, "contact_timeconst": 2e-4}, {}, None),
    # Fidelity part 4 (docs/model.md): the representation the diagnosis names, built into the scene.
    # Each actuator clipped at the stall torque, so the implicit step stops linearising a clipped damping
    "actuator clip": ({}, {"servo_clip": "actuator"}, None),
    # DART's SERVO law as MuJoCo can now hold it: a velocity loop stiff enough to act as a constraint
    # (0.078 N m at 0.5 rad/s of speed error), clipped per actuator, slow trim, no armature (DART has none)
    "DART law": ({}, {"servo_kv": 0.078 / 0.5, "servo_kp": 0.078 / 0.5 / 1.6, "servo_armature": 0.0,
                      "servo_timeconst": 0.0, "servo_clip": "actuator"}, None),
    # a hobby servo's position loop: saturates the stall torque at 1 degree of error, clipped per
    # actuator, keeping the gearbox's reflected inertia and the 10 ms command lag of the default
    "hobby servo": ({}, {"servo_kp": 0.078 / math.radians(1.0), "servo_kv": None, "servo_clip": "actuator"}, None),
    # gear backlash: the arm swings +-1.5 deg about the driven hinge (the middle of the 1-2 deg prior)
    "backlash 1.5 deg": ({}, {"backlash_deg": 1.5}, None),
}


def variant(name: str, combine: str | None = None):
    """SceneParams and MjModel edit of a variant (``combine``: several names joined by '+')."""
    params, edits = presets.params(), []
    for v in (combine or name).split("+"):
        sc, rb, ed = VARIANTS[v]
        params = params.replace(robot=dataclasses.replace(params.robot, **rb), **sc)
        if ed:
            edits.append(ed)
    params.validate()
    return params, (lambda m: [e(m) for e in edits])


def _native(params, n_robots: int, edit, collisions: bool):
    from smarticle_mjx.engine import Scene
    from smarticle_mjx.engine.native import NativeBackend
    scene = Scene.build(params, n_robots, collisions=collisions)
    edit(scene.model)
    return NativeBackend(scene, nthread=1)


def mujoco_variant_lone(params, edit, amplitude: float, periods: int) -> dict:
    """Drift and slip per edge of one robot (as :func:`mujoco_row`) in an edited model."""
    from smarticle_mjx.engine import Lanes, steps_per_period
    gait = GaitSpec(amplitude)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    be = _native(params, 1, edit, False)
    try:
        nstep = steps_per_period(gait.period(), params.timestep)
        q = be.step_qpos(Lanes.from_gait(np.array([[[0.0, 0.0, 0.0, a0[0], a0[1]]]]), gait), periods * nstep)[0]
        at = be.scene.layout.free_qpos[0]
    finally:
        be.close()
    xy = np.concatenate([[[0.0, 0.0]], q[:, at:at + 2]])
    return _measures(xy[[round(k * nstep / 4) for k in range(4 * periods + 1)]], params.robot.body_length)


def mujoco_variant_pairs(params, edit, starts: np.ndarray) -> dict:
    """Gliders and the collision record of ``starts`` at 90 degrees in an edited model (as :func:`pairs_part`)."""
    from smarticle_mjx import configs as C
    from smarticle_mjx.engine import Lanes
    from smarticle_mjx.engine.core import Record
    from smarticle_mjx.engine.batch import RetireRule, run_lanes
    from smarticle_mjx.reduce import gliders
    gait, W, K = GaitSpec(90.0), params.robot.body_length, GLIDE["periods"]
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    poses = C.pair_poses(starts[:, 0], starts[:, 1], starts[:, 2], a0[0], a0[1], params.robot)
    m = len(poses)
    tr, touched, run = np.full((m, K, 2, 5), np.nan), np.zeros((m, K), bool), np.zeros(m, int)
    coll = {}

    def on_lanes(res):
        tr[res.index], touched[res.index], run[res.index] = res.poses, res.touched[..., 0], res.periods_run
        for k, v in res.collisions.items():
            coll.setdefault(k, np.zeros((m,) + v.shape[1:], v.dtype))[res.index] = v

    be = _native(params, 2, edit, True)
    t = time.perf_counter()
    try:
        run_lanes(be, Lanes.from_gait(poses, gait), K, batch_size=32, chunk_periods=5,
                  rule=RetireRule(quiet_periods=2), on_lanes=on_lanes,
                  record=Record(collisions=True, collision_bins=GLIDE["bins"]))
    finally:
        be.close()
    r, th, ph = C.relative_coordinates(tr[:, :, 0], tr[:, :, 1], W)
    out = gliders.glide_summary((tr[:, :, 0, :2] + tr[:, :, 1, :2]) / 2 / W, np.stack([r, th, ph], -1), touched,
                                GLIDE["burn_in"]).as_json()
    out.update({"starts": m, "periods": K, "burn_in": GLIDE["burn_in"], "wall_s": time.perf_counter() - t,
                "lane_periods": int(run.sum()), "collisions": collision_level(coll, touched)})
    return out


def diagnose(names, out: pathlib.Path, lone_periods: int):
    """Each variant: lone drift and slip per edge at 90 degrees, gliders and collision record of the glide starts."""
    unknown = sorted({v for name in names for v in name.split("+")} - set(VARIANTS))
    if unknown:
        raise SystemExit(f"unknown variants {unknown}; known: {', '.join(VARIANTS)}")
    starts = valid_starts(presets.params(), 90.0, GLIDE["n"], GLIDE["r_range"], GLIDE["seed"])
    for name in names:
        done = json.loads(out.read_text()) if out.exists() else {}
        row = done.get("diagnosis", {}).get(name, {})
        params, edit = variant(name, name if "+" in name else None)
        if "lone90" not in row:
            t = time.perf_counter()
            row["lone90"] = {**mujoco_variant_lone(params, edit, 90.0, lone_periods), "periods": lone_periods,
                             "wall_s": time.perf_counter() - t}
        if "glide" not in row:
            row["glide"] = mujoco_variant_pairs(params, edit, starts)
        g, lo = row["glide"], row["lone90"]
        c = g["collisions"]
        print(f"{name}: slip/edge {lo['slip_per_edge_W']:.2e} W, drift {lo['drift_W_per_cycle']:.1e} W/cycle; "
              f"gliders {g['gliders']}/{g['starts']}, net speed {g.get('net_speed_W_per_period', float('nan')):.4f}, "
              f"impulse_r/period {c['impulse_r_per_period_Ns']:.2e} N s, |impulse_r| {c['abs_impulse_r_per_period_Ns']:.2e}, "
              f"attractive {c['attractive_fraction']:.2f} ({g['wall_s']:.0f} s)", flush=True)
        _update(out, lambda done: done.setdefault("diagnosis", {}).__setitem__(name, row))


def _f(v, spec=".2f"):
    return formatting.num(v, spec, dash="—")  # the docs tables' em dash


def _glide_cells(g: dict) -> list[str]:
    c = g.get("collisions", {})
    iv = g.get("net_speed_interval")
    return [f"{g.get('gliders', '—')} / {g.get('starts', '—')} ({g.get('periods', '—')})",
            _f(g.get("net_speed_W_per_period"), ".4f") + (f" [{_f(iv[0], '.4f')}, {_f(iv[1], '.4f')}]" if iv else ""),
            _f(g.get("persistence")), _f(g.get("straightness20")),
            f"{_f(g.get('beta'))} ± {_f(g.get('beta_err'))}",
            f"{_f(g.get('sign_flips_per_period'), '.3f')} · {_f(g.get('sign_held_frac'))}",
            _f(g.get("C2_fraction")),
            _f(c.get("impulse_r_per_period_Ns"), ".2e"), _f(c.get("abs_impulse_r_per_period_Ns"), ".2e"),
            _f(c.get("attractive_fraction")), _f(c.get("contact_steps_per_period"), ".0f")]


GLIDE_ROWS = ["gliders / starts (periods)", "net speed (W/period) [95 % bootstrap]", "direction persistence",
              "straightness over 20 periods", "β (lags 5–15) ± bootstrap sd",
              "sign flips of φ−180° per period · gliders holding it ≥ 50 periods", "C2 fraction of glider samples",
              "impulse along r per touching period (N s)", "Σ\|impulse along r\| by kind per touching period (N s)",
              "touching periods with an attractive kind", "contact steps per touching period"]


def refresh(path: pathlib.Path) -> dict:
    """Recompute the glider rows of the JSON from their stores where these are
    here (a row written before the summary gained a quantity gets it) and save."""
    from smarticle_mjx.reduce import gliders
    done = json.loads(path.read_text())
    gname = f"glide_{GLIDE['n']}x{GLIDE['periods']}_s{GLIDE['seed']}"
    rows = {}
    for key, e in done.get("pairs", {}).items():
        store = STORES / f"{key.replace(' ', '_')}_{gname}.h5"
        if gname in e and store.exists():
            tr = store_tracks(store, presets.params(done.get("model")).robot.body_length)
            rows[key] = {gname: {**e[gname], **gliders.glide_summary(tr["com"], tr["rel"], tr["touched"],
                                                                      GLIDE["burn_in"]).as_json()}}
    _save(rows, path)
    return json.loads(path.read_text())


def tables(done: dict) -> str:
    """docs/twin.md's tables from the JSON."""
    lone, pairs = done.get("lone", {}), done.get("pairs", {})
    params = presets.params()
    gname = f"glide_{GLIDE['n']}x{GLIDE['periods']}_s{GLIDE['seed']}"
    rname = f"relax_{RELAX['trials']}x{RELAX['periods']}_s{RELAX['seed']}"
    cols = {"dart": ("DART twin (fcl-mesh, 0.1 ms)", "dart fcl-mesh 0.1 ms"),
            "dart 0.05ms": ("DART, fcl-mesh, 0.05 ms", "dart fcl-mesh 0.05 ms"),
            "dart fcl": ("DART, FCL primitives", "dart fcl 0.1 ms"),
            "dart pd": ("DART, the default's PD + lag servo, no armature", "dart pd fcl-mesh 0.1 ms"),
            "mujoco": (f"MuJoCo `{done.get('model', presets.DEFAULT)}` ({params.timestep * 1e3:g} ms)",
                       f"mujoco {params.timestep * 1e3:g} ms")}
    cols = {k: v for k, v in cols.items() if k in pairs}
    rows = {"lone drift 90° (W/cycle)": ["1.5e-3 (lab)"], "lone drift 10° (W/cycle)": ["larger than at 90° (SI)"],
            "slip of the body per arm move, 90° (W)": ["—"]}
    paper = ["—", "≈ 0.03 (lab: 2.9 W over ≥ 100 periods)", "nearly ballistic", "—", "≈ 1.8", "consistent sign",
             "two clusters (C1, C2)", "< 0 (repulsive)", "—", "attractive collisions bind (Fig. 4)", "—"]
    for q, ref in zip(GLIDE_ROWS, paper):
        rows[q] = [ref]
    for a in PB["amplitudes"]:
        rows[f"P_b bound at the end, {a:g}° [95 % exact] (starts)"] = ["dip at 40–60° (Fig. 3B)"]
    rows[f"relaxation: trials with a pair bound and apart ≥ {RELAX['min_periods']} periods [95 %]"] = \
        ["77/151 pairs glide ≥ 100 periods (lab)"]
    rows["relaxation time (periods, median [IQR]; trial length caps it)"] = ["≈ 30 (lab)"]
    rows["cost: lane-periods simulated per wall s of the study"] = ["—"]
    for key, (_, lone_key) in cols.items():
        e = pairs.get(key, {})
        l90, l10 = lone.get(f"{lone_key}, 90 deg", {}), lone.get(f"{lone_key}, 10 deg", {})
        rows["lone drift 90° (W/cycle)"].append(_f(l90.get("drift_W_per_cycle"), ".1e"))
        rows["lone drift 10° (W/cycle)"].append(_f(l10.get("drift_W_per_cycle"), ".1e"))
        rows["slip of the body per arm move, 90° (W)"].append(_f(l90.get("slip_per_edge_W"), ".1e"))
        g = e.get(gname, {})
        for q, cell in zip(GLIDE_ROWS, _glide_cells(g)):
            rows[q].append(cell)
        for a in PB["amplitudes"]:
            v = e.get(f"pb{a:g}_{PB['n']}x{PB['periods']}_s{PB['seed']}")
            rows[f"P_b bound at the end, {a:g}° [95 % exact] (starts)"].append(
                "—" if v is None else f"{v['end'][0]:.2f} [{v['end'][1]:.2f}, {v['end'][2]:.2f}] ({v['n']})")
        r = e.get(rname)
        rows[f"relaxation: trials with a pair bound and apart ≥ {RELAX['min_periods']} periods [95 %]"].append(
            "—" if r is None else f"{r['emerged']}/{r['trials']} [{r['interval'][0]:.2f}, {r['interval'][1]:.2f}]")
        rows["relaxation time (periods, median [IQR]; trial length caps it)"].append(
            "—" if r is None else f"{r['relaxation_periods']['median']:.0f} [{r['relaxation_periods']['q25']:.0f}, "
                                  f"{r['relaxation_periods']['q75']:.0f}] of {r['periods']}")
        rows["cost: lane-periods simulated per wall s of the study"].append(
            _f(g["lane_periods"] / g["wall_s"], ".2f") if g.get("wall_s") else "—")
    head = "| quantity | paper / lab | " + " | ".join(c[0] for c in cols.values()) + " |"
    out = [head, "|" + " --- |" * (2 + len(cols))] + [f"| {q} | " + " | ".join(v) + " |" for q, v in rows.items()]
    diag = done.get("diagnosis", {})
    if diag:
        out += ["", "| engine, variant | slip per arm move 90° (W) | lone drift 90° (W/cycle) | "
                "gliders / starts (periods) | net speed (W/period) | direction persistence | β | impulse along r per touching period (N s) | "
                "Σ\|impulse along r\| (N s) | attractive periods |", "|" + " --- |" * 10]
        twins = [("**DART twin**", {"lone90": lone.get("dart fcl-mesh 0.1 ms, 90 deg", {}),
                                    "glide": pairs.get("dart", {}).get(gname, {})})]
        if "dart pd" in pairs:
            twins.append(("**DART, PD + lag servo, armature 0**",
                          {"lone90": lone.get("dart pd fcl-mesh 0.1 ms, 90 deg", {}),
                           "glide": pairs["dart pd"].get(gname, {})}))
        for name, row in twins + [(f"MuJoCo: {k}", v) for k, v in diag.items()]:
            lo, g = row.get("lone90", {}), row.get("glide", {})
            c = _glide_cells(g)
            out.append(f"| {name} | {_f(lo.get('slip_per_edge_W'), '.1e')} | {_f(lo.get('drift_W_per_cycle'), '.1e')} | "
                       f"{c[0]} | {_f(g.get('net_speed_W_per_period'), '.4f')} | {c[2]} | {_f(g.get('beta'))} | "
                       f"{c[7]} | {c[8]} | {c[9]} |")
    return "\n".join(out)


def _update(path: pathlib.Path, change) -> None:
    """Apply ``change(data)`` to the JSON as it is now (another part may have
    written it while this one ran) and replace the file atomically."""
    done = json.loads(path.read_text()) if path.exists() else {"model": presets.DEFAULT}
    change(done)
    save_json(path, done)


def _save(rows: dict, path: pathlib.Path):
    """Merge the pair rows into the JSON."""
    def merge(done):
        for label, entries in rows.items():
            done.setdefault("pairs", {}).setdefault(label, {}).update(entries)
        done["glide_design"], done["pb_design"], done["relax_design"] = GLIDE, PB, RELAX
    _update(path, merge)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("part", nargs="?", default="lone", choices=("lone", "pairs", "pb", "relax", "diagnose", "table"),
                    help="lone: one robot in every engine and numerics; pairs: gliders and their collision "
                         "record from random 90-degree starts; pb: P_b at 30/50/70/90 degrees; diagnose: "
                         "MuJoCo's modelling choices switched one at a time (--variants)")
    ap.add_argument("--variants", default=",".join(VARIANTS),
                    help="diagnose: comma-separated names of VARIANTS (join names with '+' to combine them)")
    ap.add_argument("--engine", default="mujoco", choices=("mujoco", "dart"), help="pairs, pb: the engine")
    ap.add_argument("--workers", type=int, default=2, help="DART's Dask worker processes")
    ap.add_argument("--servo", default="constraint", choices=("constraint", "pd"),
                    help="pairs, DART: its SERVO constraint, or the default model's PD + lag law as joint forces "
                         "(armature 0, which DART cannot model)")
    ap.add_argument("--detector", default="fcl-mesh", help="pairs, DART: collision detector (sensitivity)")
    ap.add_argument("--step", type=float, default=1e-4, help="pairs, DART: time step in s (sensitivity)")
    ap.add_argument("--periods", type=int, default=12, help="lone: periods per robot")
    ap.add_argument("--out", type=pathlib.Path, default=OUT)
    ap.add_argument("--doc", type=pathlib.Path, default=None, help="table: write the tables into this page")
    args = ap.parse_args()
    if args.part == "lone":
        return lone(args)
    if args.part == "table":
        text = tables(refresh(args.out))
        if args.doc:  # replace the tables between the page's markers
            page = args.doc.read_text()
            for k, t in zip(("cross", "diagnosis"), text.split("\n\n")):
                a, b = f"<!-- twin.py table: {k} -->\n", f"\n<!-- end of table: {k} -->"
                i, j = page.index(a) + len(a), page.index(b)
                page = page[:i] + t.strip() + page[j:]
            args.doc.write_text(page)
        return print(text)
    if args.part == "diagnose":
        return diagnose(args.variants.split(","), args.out, args.periods)
    rows = {}
    if args.part == "pairs":
        pairs_part(args.engine, args.workers, rows, servo=args.servo, detector=args.detector, step=args.step)
    elif args.part == "relax":
        relax_part(args.engine, args.workers, rows)
    else:
        pb_part(args.engine, args.workers, rows, save=lambda: _save(rows, args.out))
    _save(rows, args.out)


def lone(args):
    from smarticle_mjx.engine.dart import DartNumerics
    params = presets.params()
    done = json.loads(args.out.read_text()) if args.out.exists() else {}
    rows = done.get("lone", {})
    runs = {f"mujoco {params.timestep * 1e3:g} ms": lambda g: mujoco_row(params, g, args.periods),
            f"mujoco {params.timestep / 4 * 1e3:g} ms": lambda g: mujoco_row(params.replace(timestep=params.timestep / 4),
                                                                              g, args.periods)}
    for det, dt in (("fcl-mesh", 1e-4), ("fcl-mesh", 5e-5), ("fcl", 1e-4), ("ode", 1e-4), ("bullet", 1e-4)):
        runs[f"dart {det} {dt * 1e3:g} ms"] = (lambda d, s: lambda g: dart_row(params, g, args.periods,
                                                                               DartNumerics(timestep=s, detector=d)))(det, dt)
    # the default's own PD + lag servo as joint forces in DART (armature 0, which DART cannot model)
    no_arm = params.replace(robot=dataclasses.replace(params.robot, servo_armature=0.0))
    runs["dart pd fcl-mesh 0.1 ms"] = lambda g: dart_row(no_arm, g, args.periods, DartNumerics(servo="pd"))
    for name, run in runs.items():
        for amp in (90.0, 10.0):
            key = f"{name}, {amp:g} deg"
            if key in rows:
                continue
            t = time.perf_counter()
            rows[key] = {**run(GaitSpec(amp)), "wall_s": time.perf_counter() - t}
            r = rows[key]
            print(f"{key}: drift {r['drift_W_per_cycle']:.2e} W/cycle, slip per edge {r['slip_per_edge_W']:.2e} W "
                  f"(max {r['slip_per_edge_max_W']:.2e}), {r['wall_s']:.0f} s", flush=True)
            _update(args.out, lambda d: (d.setdefault("lone", {}).update({key: r}), d.update(periods=args.periods)))


if __name__ == "__main__":
    main()
