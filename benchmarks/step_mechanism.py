"""Which part of the 0.5 ms step biases the glider quantities? One numerical choice switched at a time at
0.5 ms, each against the reference at 0.0625 ms, on glider_step.py's starts (128 random valid pairs,
seed 1, 100 periods at 90 deg, model lab-lag; gliders bound every period after 10).

Variants change numerics only (the robot's physical parameters stay lab-lag's):
  * the integrator: implicitfast (default) -> implicit (also linearises the Coriolis and the
    actuators' position gains), Euler (semi-implicit: joint damping only, the servo's PD explicit),
    RK4 (explicit, fourth order);
  * the servo's lag filter is already integrated exactly (dyntype filterexact), so it is not a
    candidate; the contact's solref time constant is physics (absolute seconds), so stiffer contacts
    are a model change, not a switch of this table.

The kick level (``--kicks``, seconds): a lone robot's slip per arm move at 90 deg (12 periods, the
body's mean displacement per quarter period, twin.py's measure) for each integrator and step, and with
the servo's velocity gain kv halved and doubled and without armature at a fine and the default step
(a probe of the mechanism, not a model change). Writes results/step_kicks.json.

``--family contacts-2ms``: contacts of 2 ms time constant instead of 5 ms at 0.5 and 0.25 ms against
their own 0.0625 ms reference (results/step_mechanism_contacts-2ms.json): the contacts' softness relative
to the step. ``--family discrete --default-reference``: discrete at 0.0625 ms (no kick artefact) as the
reference, against implicitfast's 0.0625 ms reference and discrete with near-contact sub-stepping;
``--against-default`` pairs a family's runs with the check's reference instead (for the step-check table).
``--replicas``: the default numerics again from starts moved by 1e-9 m, the check's noise floor
(results/step_replicas.json).

Per variant: gliders, beta, net speed and direction persistence with 95 % bootstrap intervals and the
paired bootstrap interval of each difference from the reference (starts resampled together).
Resumable: each variant's per-period tracks are kept in results/step_mechanism_runs/ and reused.

    python benchmarks/step_mechanism.py              # the reference alone takes ~20 min on 2 cores
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import time

import numpy as np

from glider_step import BURN_IN, PERIODS, POOL, SEED, paired_rows, quantities, quantities_runs30
from smarticle_mjx import presets
from smarticle_mjx.bench import gliding, pair_starts, save_json, variant_params

ROOT = pathlib.Path(__file__).resolve().parent
RUNS = ROOT / "results" / "step_mechanism_runs"
REFERENCE = "0.0625 ms (reference)"
VARIANTS = {  # name -> (time step s, SceneParams changes)
    REFERENCE: (6.25e-5, {"integrator": "implicitfast"}),
    "0.5 ms implicitfast (default)": (5e-4, {"integrator": "implicitfast"}),
    "0.5 ms implicit": (5e-4, {"integrator": "implicit"}),
    "0.5 ms Euler": (5e-4, {"integrator": "Euler"}),
    "0.5 ms RK4": (5e-4, {"integrator": "RK4"}),
    # candidates for a default that keeps the paper scan under twice today's cost (added after the rows
    # above had been measured): a smaller implicitfast step, and RK4 at a larger one
    "0.35 ms implicitfast": (3.5e-4, {"integrator": "implicitfast"}),
    "0.25 ms implicitfast": (2.5e-4, {"integrator": "implicitfast"}),  # glider_step.py's row, here for --imperfections
    # MuJoCo's "discrete" integrator solves the constraints with the implicit velocity update (MuJoCo >= 3.13):
    # the kick level's slip is the converged one at every step (added after the kick table)
    "0.5 ms discrete": (5e-4, {"integrator": "discrete"}),
    "1 ms RK4": (1e-3, {"integrator": "RK4"}),
    # after the kick level showed RK4's slip per arm move the same from 0.5 to 2.5 ms
    "1.5 ms RK4": (1.5e-3, {"integrator": "RK4"}),
    "2 ms RK4": (2e-3, {"integrator": "RK4"}),
    # near-contact sub-stepping (native backend, added after the contacts' family showed the bias following
    # the step against the contacts' time constant): the 0.5 ms step while the robots are apart, 0.25 ms
    # while some pair may be within 4 mm (a glider's robots are, a third of the time)
    "0.5 ms + 2 sub-steps within 4 mm": (5e-4, {"integrator": "implicitfast", "contact_substeps": 2,
                                                "substep_gate": 0.004}),
    # the same with MuJoCo's discrete integrator (added after the implicitfast row over-bound the label check's
    # pairs, 0.482 against 0.407: implicitfast slips a body by an amount that grows with the step at every arm
    # move, and a gate that changes the step with the robots' distance turns those slips, which cancel over a
    # cycle at one step, into a drift that depends on the distance; discrete slips the same at every step)
    "0.5 ms discrete + 2 sub-steps within 4 mm": (5e-4, {"integrator": "discrete", "contact_substeps": 2,
                                                         "substep_gate": 0.004}),
}

# The contacts' softness relative to the step (--family contacts-2ms; added after the integrator and step rows
# above, when the discovery screen showed contacts of 2 ms time constant removing the crowd's penetration
# flags): the solref time constant is physics (absolute seconds), so its own family is judged against its
# own 0.0625 ms reference, and that reference against the 5 ms reference above says what the softness does
# to the converged gliders.
CONTACTS_2MS = {"integrator": "implicitfast", "contact_timeconst": 0.002}
FAMILIES = {
    "contacts-2ms": {
        "0.0625 ms, contacts 2 ms (reference)": (6.25e-5, CONTACTS_2MS),
        "0.5 ms, contacts 2 ms": (5e-4, CONTACTS_2MS),
        "0.25 ms, contacts 2 ms": (2.5e-4, CONTACTS_2MS),
    },
    # Is the reference itself converged? (--family discrete; added after discrete with near-contact
    # sub-stepping converged beta and net speed but not the direction persistence, +0.098, the same offset
    # discrete and Euler give at 0.5 ms without sub-stepping, while RK4 at 0.5-1 ms gives +0.02-0.03.) The
    # implicitfast reference at 0.0625 ms still slips a lone robot 18 % more per arm move than the converged
    # 2.93e-5 W (the kick level); discrete slips the converged amount at every step. So discrete at 0.0625 ms
    # is a reference converged in both the contacts (80 evaluations per time constant) and the kick, and
    # paired with the implicitfast reference (--default-reference) it says whether the persistence offset is
    # the candidate's error or the reference's.
    "discrete": {
        "0.0625 ms discrete (reference)": (6.25e-5, {"integrator": "discrete"}),
        "0.5 ms discrete + 2 sub-steps within 4 mm": VARIANTS["0.5 ms discrete + 2 sub-steps within 4 mm"],
        # discrete's own step curve (added after the two references differed on persistence by +0.08 and three
        # replicas of the default put the check's noise floor at +-0.03, before these ran): implicitfast's
        # persistence is 0.39 at 0.0625 ms, 0.5 ms and 0.5 ms sub-stepped alike, discrete's 0.31 at 0.0625 ms and
        # 0.49-0.50 at 0.5 ms (sub-stepped or not); where discrete lies between says which converges
        "0.25 ms discrete": (2.5e-4, {"integrator": "discrete"}),
        "0.125 ms discrete": (1.25e-4, {"integrator": "discrete"}),
        # Euler with the same sub-stepping (added after discrete's persistence fell with every halving of the
        # step, 0.49 / 0.44 / 0.38 / 0.31 at 0.5 / 0.25 / 0.125 / 0.0625 ms, while implicitfast gave 0.39 at
        # 0.0625, 0.25 and 0.5 ms and RK4 0.41-0.42 at 0.5 and 1 ms; before it ran): Euler slips a lone robot
        # the converged amount per arm move, as discrete does, costs 0.78x the default where discrete costs
        # 1.1-1.3x, and gave persistence 0.47 at 0.5 ms without sub-stepping
        "0.5 ms Euler + 2 sub-steps within 4 mm": (5e-4, {"integrator": "Euler", "contact_substeps": 2,
                                                          "substep_gate": 0.004}),
    },
    # The gear stops' stiffness held fixed (added after the lab robots' persistence at 0.25 ms missed the check
    # by 0.004 with every other quantity agreeing, before these ran): the stops of the lab robots' gear play are
    # built as stiff as the step integrates (solreflimit 2 dt), so the 0.0625 ms reference holds teeth of 0.125
    # ms where 0.25 ms holds 0.5 ms -- a different robot, not only a finer step. Here both steps build the
    # teeth at 0.5 ms (robot.backlash_stop_timeconst), the stiffness the default step builds; only the step
    # differs. Without gear play (ideal robots) the family is the default's.
    "stops-0.5ms": {
        "0.0625 ms, gear stops 0.5 ms (reference)": (6.25e-5, {"integrator": "implicitfast",
                                                              "robot": {"backlash_stop_timeconst": 5e-4}}),
        "0.25 ms, gear stops 0.5 ms": (2.5e-4, {"integrator": "implicitfast",
                                                "robot": {"backlash_stop_timeconst": 5e-4}}),
    },
    # Gear teeth as soft as the contacts (added after the 0.5 ms teeth missed, persistence -0.070 [-0.099,
    # -0.043], before these ran): teeth of 0.5 ms are a constraint of 2 evaluations per time constant at 0.25 ms,
    # unresolved there and resolved at 0.0625 ms, so holding them fixed still compares a resolved robot with an
    # unresolved one. Teeth of 5 ms, the contacts' time constant, are resolved at both steps by the contacts'
    # own rule (about 20 evaluations per time constant): does 0.25 ms then agree with its reference?
    "stops-5ms": {
        "0.0625 ms, gear stops 5 ms (reference)": (6.25e-5, {"integrator": "implicitfast",
                                                            "robot": {"backlash_stop_timeconst": 5e-3}}),
        "0.25 ms, gear stops 5 ms": (2.5e-4, {"integrator": "implicitfast",
                                              "robot": {"backlash_stop_timeconst": 5e-3}}),
    },
}
# How far apart do two runs of the same numerics land? (--replicas; added after the discrete reference at
# 0.0625 ms agreed with implicitfast's on beta and net speed and differed on persistence by +0.08
# [+0.03, +0.13], before any replica ran.) A glider is chaotic: the per-start speeds of two numerics
# correlate 0.06-0.37, so each run is one realisation per start. A replica runs the default numerics from
# the same starts with robot 0 moved by REPLICA_SHIFT (a billionth of a metre, in a direction drawn per start
# from the replica's seed): the same physics and numerics, another realisation. Its paired differences
# from the unmoved run are the check's noise floor; a check whose intervals exclude 0 for a replica is
# measuring realisations, not bias.
REPLICA_NUMERICS = "0.5 ms implicitfast (default)"
REPLICA_SHIFT = 1e-9  # m
REPLICA_SEEDS = (1, 2, 3)


def replica_poses(poses: np.ndarray, seed: int) -> np.ndarray:
    """``poses`` [n, 2, 5] with robot 0 moved by REPLICA_SHIFT in a direction drawn per start from ``seed``."""
    ang = np.random.default_rng([seed, 7919]).uniform(0.0, 2 * np.pi, len(poses))
    out = np.array(poses, float, copy=True)
    out[:, 0, 0] += REPLICA_SHIFT * np.cos(ang)
    out[:, 0, 1] += REPLICA_SHIFT * np.sin(ang)
    return out


FAMILY_ONLY = {n for f in FAMILIES.values() for n in f if n not in VARIANTS}  # the main table keeps its own rows
for _family in FAMILIES.values():
    VARIANTS.update(_family)
for _dt, _changes in VARIANTS.values():  # every variant names its sub-stepping: a preset's own never leaks in
    _changes.setdefault("contact_substeps", 1)


def run(name: str, poses: np.ndarray, imperfections: str | None = None, replica: int | None = None) -> pathlib.Path:
    """Variant ``name``'s tracks from ``poses`` (reused when kept); ``replica``: from those starts moved as
    :func:`replica_poses` moves them with that seed."""
    dt, changes = VARIANTS[name]
    slug = name.split(" (")[0].replace(",", "").replace(" ", "_")
    model = "lab-lag" + (f"+{imperfections}" if imperfections else "") + (f"_replica{replica}" if replica else "")
    if replica:
        poses = replica_poses(poses, replica)
    params = variant_params(dt, changes)
    robots = None
    if imperfections:  # the same two drawn robots in every start, as fidelity_screen.py --imperfections
        from smarticle_mjx import imperfections as imp
        robots = imp.draw(imperfections, 2, SEED)
    # tracks solved with another solver than Newton (the "auto" solver with gear play: CG) carry its name, so
    # that tracks made with Newton before the solver field existed are never reused for them
    solver = (robots.scene(params) if robots is not None else params).constraint_solver(2)[0]
    path = RUNS / f"{model}_{slug}{'' if solver == 'Newton' else '_' + solver}_{POOL}x{PERIODS}_s{SEED}.npz"
    if path.exists() and np.array_equal(np.load(path)["poses"], poses):
        print(f"reusing {path.name}", flush=True)
        return path
    t = time.perf_counter()
    gliding(params, POOL, PERIODS, SEED, BURN_IN, save=path, robots=robots, poses=poses if replica else None)
    print(f"{name}{f' replica {replica}' if replica else ''}: {POOL} starts x {PERIODS} periods in "
          f"{time.perf_counter() - t:.0f} s", flush=True)
    return path


# kick level: name -> (time step s, integrator, RobotParams changes as factors of lab-lag's kv or values)
KICKS = {f"implicitfast {dt * 1e3:g} ms": (dt, "implicitfast", {}) for dt in (6.25e-5, 1.25e-4, 2.5e-4, 3.5e-4, 5e-4, 1e-3)}
KICKS.update({f"{i} 0.5 ms": (5e-4, i, {}) for i in ("implicit", "Euler", "RK4")})
KICKS.update({f"discrete {dt * 1e3:g} ms": (dt, "discrete", {}) for dt in (6.25e-5, 2.5e-4, 5e-4, 1e-3)})
KICKS["kv x2, discrete 0.5 ms"] = (5e-4, "discrete", {"kv_factor": 2.0})
KICKS["armature 0, discrete 0.5 ms"] = (5e-4, "discrete", {"servo_armature": 0.0})
KICKS.update({f"RK4 {dt * 1e3:g} ms": (dt, "RK4", {}) for dt in (1e-3, 1.5e-3, 2e-3, 2.5e-3)})
for _f in (0.5, 2.0):
    for _dt, _i in ((6.25e-5, "implicitfast"), (5e-4, "implicitfast"), (5e-4, "RK4")):
        KICKS[f"kv x{_f:g}, {_i} {_dt * 1e3:g} ms"] = (_dt, _i, {"kv_factor": _f})
for _dt, _i in ((6.25e-5, "implicitfast"), (5e-4, "implicitfast"), (5e-4, "RK4"), (1e-3, "RK4")):
    KICKS[f"armature 0, {_i} {_dt * 1e3:g} ms"] = (_dt, _i, {"servo_armature": 0.0})


def kicks(out: pathlib.Path, periods: int = 12) -> dict:
    """The lone robot's slip per arm move and drift for every row of ``KICKS``; writes ``out``."""
    from twin import mujoco_variant_lone
    base = presets.params("lab-lag")
    rows = {}
    for name, (dt, integrator, rb) in KICKS.items():
        rb = dict(rb)
        if "kv_factor" in rb:
            rb["servo_kv"] = base.robot.kv * rb.pop("kv_factor")
        p = dataclasses.replace(base, timestep=dt, integrator=integrator, robot=dataclasses.replace(base.robot, **rb))
        p.validate()
        t = time.perf_counter()
        r = mujoco_variant_lone(p, lambda m: None, 90.0, periods)
        rows[name] = {"dt_s": dt, "integrator": integrator, "kv": p.robot.kv, "armature": p.robot.servo_armature,
                      "slip_per_edge_W": r["slip_per_edge_W"], "drift_W_per_cycle": r["drift_W_per_cycle"],
                      "wall_s": time.perf_counter() - t}
        print(f"{name:>34}: slip per arm move {r['slip_per_edge_W']:.3e} W, drift {r['drift_W_per_cycle']:.1e} W/cycle",
              flush=True)
    save_json(out, {"model": "lab-lag", "amplitude_deg": 90.0, "periods": periods, "rows": rows})
    print(f"wrote {out}")
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kicks", action="store_true", help="the kick level only (a lone robot; seconds)")
    ap.add_argument("--only", default=None, help="comma-separated variant names (the reference always runs)")
    ap.add_argument("--boot", type=int, default=1000)
    ap.add_argument("--replicas", action="store_true",
                    help="the check's noise floor: the default numerics again from starts moved by 1e-9 m "
                         "(results/step_replicas.json)")
    ap.add_argument("--imperfections", default=None, help="robots drawn from this imperfection set (e.g. lab)")
    ap.add_argument("--rule", choices=("steady", "runs30"), default="steady",
                    help="a glider: bound every period after the burn-in (steady, the check's rule) or each start's "
                         "longest bound run of >= 30 periods (runs30; added when the drawn lab robots, whose clocks "
                         "drift apart, gave no steady glider at any step)")
    ap.add_argument("--family", choices=sorted(FAMILIES), default=None,
                    help="run one family of variants against its own 0.0625 ms reference (and that reference "
                         "against the default's)")
    ap.add_argument("--default-reference", action="store_true",
                    help="with --family: also the default's 0.0625 ms reference, paired with the family's")
    ap.add_argument("--against-default", action="store_true",
                    help="with --family: the family's runs paired with the default's 0.0625 ms reference (the glider "
                         "check's) instead of the family's own (results/step_mechanism_<family>_against-default.json)")
    ap.add_argument("--out", type=pathlib.Path, default=None,
                    help="default results/step_mechanism.json (results/step_mechanism_<set>.json with --imperfections)")
    args = ap.parse_args()
    if args.kicks:
        kicks(ROOT / "results" / "step_kicks.json")
        return
    if args.replicas:
        poses = pair_starts(presets.params("lab-lag"), POOL, SEED, 90.0)
        z = np.load(run(REPLICA_NUMERICS, poses))
        data = {REPLICA_NUMERICS: (z["com"], z["touched"])}
        for s in REPLICA_SEEDS:
            z = np.load(run(REPLICA_NUMERICS, poses, replica=s))
            data[f"replica {s} (robot 0 moved {REPLICA_SHIFT:g} m)"] = (z["com"], z["touched"])
        rows = paired_rows(data, REPLICA_NUMERICS, args.boot, width=36)
        out = ROOT / "results" / "step_replicas.json"
        save_json(out, {"model": "lab-lag", "numerics": REPLICA_NUMERICS, "shift_m": REPLICA_SHIFT,
                        "reference": REPLICA_NUMERICS, "starts": POOL, "periods": PERIODS, "burn_in": BURN_IN,
                        "seed": SEED, "runs": rows})
        print(f"wrote {out}")
        return
    if args.out is None:
        args.out = ROOT / "results" / ("step_mechanism" + (f"_{args.imperfections}" if args.imperfections else "")
                                       + ("" if args.rule == "steady" else f"_{args.rule}")
                                       + (f"_{args.family}" if args.family else "")
                                       + ("_against-default" if args.family and args.against_default else "") + ".json")
    family = FAMILIES.get(args.family, {})
    reference = next((n for n in family if "(reference)" in n), REFERENCE)
    pool = family or {n: v for n, v in VARIANTS.items() if n not in FAMILY_ONLY}
    wanted = [w.strip() for w in args.only.split(",")] if args.only else []
    unknown = [w for w in wanted if w not in pool]
    if unknown:
        raise SystemExit(f"error: --only names no variant {', '.join(map(repr, unknown))} here; "
                         f"the variants are {', '.join(map(repr, pool))}")
    names = [n for n in pool if n != reference and (not wanted or n in wanted)] + [reference]
    if family and (args.default_reference or args.against_default):
        names.append(REFERENCE)  # the family's reference against the default's: what the change does converged
    if family and args.against_default:
        reference = REFERENCE
    poses = pair_starts(presets.params("lab-lag"), POOL, SEED, 90.0)
    data = {}
    for n in names:
        z = np.load(run(n, poses, args.imperfections))
        data[n] = (z["com"], z["touched"])
    rows = paired_rows(data, reference, args.boot, width=30,
                       measure=quantities if args.rule == "steady" else quantities_runs30)
    res = {"model": "lab-lag", "imperfections": args.imperfections or "none", "rule": args.rule,
           "reference": reference, "starts": POOL, "periods": PERIODS, "burn_in": BURN_IN, "seed": SEED,
           "runs": {k: {"dt_s": VARIANTS[k][0], "changes": VARIANTS[k][1], **row} for k, row in rows.items()}}
    save_json(args.out, res)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
