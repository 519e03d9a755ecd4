"""The collision record against MuJoCo's own contact forces, summed by hand."""

import math

import mujoco
import numpy as np
import pytest

from smarticle_mjx import configs as C
from smarticle_mjx import presets
from smarticle_mjx.engine.core import CONTACT_KINDS, PARTS, Lanes, Record, Scene, lane_controls, on_step_grid
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.gait import GaitSpec
from smarticle_mjx.reduce import collisions as RC

GAIT = GaitSpec(90.0)


def _by_hand(params, poses, bins):
    """Step MuJoCo one step at a time (no collision sensors in the model) and
    sum every robot-robot contact's force (mj_contactForce, rotated out of the
    contact frame) on robot 0, by contact kind and bin of the period."""
    scene = Scene.build(params, 2)
    m = scene.model
    d = mujoco.MjData(m)
    lanes = on_step_grid(Lanes.from_gait(poses, GAIT), m.opt.timestep)
    nstep = int(round(lanes.period / m.opt.timestep))
    ctrl = lane_controls(scene, lanes, m.opt.timestep * np.arange(nstep))[0]
    d.qpos[:] = scene.qpos_from_poses(np.asarray(poses)[None])[0]
    mujoco.mj_forward(m, d)
    names = {mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"r{r}_{p}"): (r, p) for r in (0, 1) for p in PARTS}
    steps = np.zeros((len(CONTACT_KINDS), bins), int)
    imp = np.zeros((len(CONTACT_KINDS), bins, 2))
    imp_r = np.zeros((len(CONTACT_KINDS), bins))
    f6 = np.zeros(6)
    for s in range(nstep):
        d.ctrl[:] = ctrl[s]
        mujoco.mj_forward(m, d)  # contacts and forces of the state this step starts from
        g = min(s * bins // nstep, bins - 1)
        c0 = d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "r0")][:2]
        c1 = d.xpos[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "r1")][:2]
        rhat = (c1 - c0) / np.linalg.norm(c1 - c0)
        seen = set()
        for ci in range(d.ncon):
            con = d.contact[ci]
            a, b = names.get(con.geom[0]), names.get(con.geom[1])
            if a is None or b is None or a[0] == b[0]:
                continue
            mujoco.mj_contactForce(m, d, ci, f6)
            # mj_contactForce gives the force on geom[1] in the contact frame (rows: normal, tangents)
            on_g1 = con.frame.reshape(3, 3).T @ f6[:3]
            on_robot0 = on_g1 if b[0] == 0 else -on_g1
            part0, part1 = (b[1], a[1]) if b[0] == 0 else (a[1], b[1])
            k = CONTACT_KINDS.index(f"{part0}-{part1}")
            seen.add(k)
            imp[k, g] += on_robot0[:2] * m.opt.timestep
            imp_r[k, g] += on_robot0[:2] @ rhat * m.opt.timestep
        for k in seen:
            steps[k, g] += 1
        mujoco.mj_step(m, d)
    return steps, imp, imp_r


@pytest.mark.parametrize("model", ["paper", "lab-dart"])
def test_collision_record_matches_mujoco_contact_forces_summed_by_hand(model):
    """Per contact kind and phase bin, the record's steps in contact and the
    contact impulse on robot 0 (and its component along r) equal the sum of
    MuJoCo's own contact forces over an independently stepped period."""
    params = presets.params(model)
    a0 = GAIT.setpoints(0.0, params.robot.servo_speed)
    # an asymmetric start whose robots collide arm-arm and arm-body in the first period
    poses = C.pair_poses(1.25, math.radians(250), math.radians(170), a0[0], a0[1], params.robot)
    assert C.poses_valid(poses, params.robot)
    bins = 8
    res = simulate(params, poses, GAIT, 1, record=Record(collisions=True, collision_bins=bins))
    steps, imp, imp_r = _by_hand(params, poses, bins)
    rec = res.collisions
    assert steps.sum() > 100, "the start must collide"
    assert (steps.sum(1) > 0).sum() >= 2, "at least two kinds of contact"
    np.testing.assert_array_equal(rec["steps"][0, 0], steps)
    scale = np.abs(imp).max()
    np.testing.assert_allclose(rec["impulse"][0, 0], imp, atol=1e-4 * scale)
    np.testing.assert_allclose(rec["impulse_r"][0, 0], imp_r, atol=1e-4 * scale)
    # the reducer's per-period totals are the same sums
    tot = RC.period_totals({k: v[None] for k, v in rec.items()})
    np.testing.assert_allclose(tot.impulse_r[0, 0, 0], imp_r.sum(), atol=1e-4 * scale)


def test_collision_record_needs_the_native_backend_and_sensors():
    params = presets.params("paper")
    scene = Scene.build(params, 2)
    from smarticle_mjx.engine.native import NativeBackend
    be = NativeBackend(scene, nthread=1)
    try:
        lanes = Lanes.from_gait(np.array(C.pair_poses(1.5, 4.7, 3.1, 1.57, 1.57, params.robot))[None], GAIT)
        with pytest.raises(ValueError, match="collision record"):
            be.advance(be.initial_state(lanes), lanes, 1, record=Record(collisions=True))
    finally:
        be.close()
    with pytest.raises(ValueError, match="collision_bins"):
        Record(collisions=True, collision_bins=0).validate()


def test_collision_record_through_a_scan_store_and_report(tmp_path):
    """smx scan --collisions stores the record; a period has contacts in it
    exactly when the independent touch sensor saw the robots touch; smx report
    draws the collision sequence; a store without it says how to get it."""
    from typer.testing import CliRunner

    from smarticle_mjx.cli import app
    from smarticle_mjx.store import Store, StoreError

    out = tmp_path / "c.h5"
    r = CliRunner().invoke(app, ["scan", "--configs", "polar", "--radius", "1.2", "--positions", "6",
                                 "--periods", "3", "--collisions", "--collision-bins", "4", "--out", str(out),
                                 "--quiet"])
    assert r.exit_code == 0, r.output
    st = Store(out)
    d = st.run(fields=("valid", "touched", "coll_steps", "coll_impulse", "coll_impulse_r"))
    m = len(d["valid"])
    assert d["coll_steps"].shape == (m, 3, 1, 9, 4) and d["coll_impulse"].shape == (m, 3, 1, 9, 4, 2)
    assert d["touched"].any(), "some start must touch"
    np.testing.assert_array_equal(d["coll_steps"].sum((-1, -2)) > 0, d["touched"])
    assert RC.KINDS == CONTACT_KINDS
    rep = CliRunner().invoke(app, ["report", str(out), "--out", str(tmp_path / "rep")])
    assert rep.exit_code == 0, rep.output
    assert list((tmp_path / "rep").glob("collisions_*.png"))
    plain = tmp_path / "p.h5"
    CliRunner().invoke(app, ["scan", "--configs", "polar", "--positions", "2", "--periods", "1",
                             "--out", str(plain), "--quiet"])
    with pytest.raises(StoreError, match="--collisions"):
        Store(plain).run(fields=("coll_steps",))
    bad = CliRunner().invoke(app, ["scan", "--configs", "polar", "--positions", "2", "--periods", "1",
                                   "--collisions", "--backend", "mjx", "--out", str(tmp_path / "m.h5")])
    assert bad.exit_code == 2 and "collision records (--collisions) run on the native and dart backends, not" in bad.output


def test_sequence_and_kind_summary_of_a_built_record():
    """A built record of one lane, two periods, 8 bins: in period 0 an arm-arm contact in bins 2-4 that
    attracts (+1e-4 N s along r per bin) and a body-body contact in bin 7 that repels; in period 1 the
    arm-arm contact alone, repelling. The sequence lists the two runs of period 0 in gait order with their
    summed steps and impulses; the kind summary counts arm-arm in both periods (attractive in one of two)
    and body-body in one (never attractive)."""
    bins, n = 8, len(CONTACT_KINDS)
    coll = {"steps": np.zeros((1, 2, 1, n, bins), np.int32), "impulse": np.zeros((1, 2, 1, n, bins, 2)),
            "impulse_r": np.zeros((1, 2, 1, n, bins))}
    aa, bb = CONTACT_KINDS.index("arm1-arm1"), CONTACT_KINDS.index("body-body")
    coll["steps"][0, 0, 0, aa, 2:5] = 3
    coll["impulse_r"][0, 0, 0, aa, 2:5] = 1e-4
    coll["impulse"][0, 0, 0, aa, 2:5] = (1e-4, 0.0)
    coll["steps"][0, 0, 0, bb, 7] = 2
    coll["impulse_r"][0, 0, 0, bb, 7] = -5e-5
    coll["steps"][0, 1, 0, aa, 0] = 1
    coll["impulse_r"][0, 1, 0, aa, 0] = -2e-4
    seq = RC.sequence(coll, 0, 0)
    assert [(c.kind, c.first_bin, c.last_bin, c.steps) for c in seq] == [("arm1-arm1", 2, 4, 9), ("body-body", 7, 7, 2)]
    assert seq[0].phase == 2 / bins and seq[0].impulse_r == pytest.approx(3e-4) and seq[0].impulse == pytest.approx((3e-4, 0))
    assert RC.sequence(coll, 0, 0, min_steps=3)[0].kind == "arm1-arm1" and len(RC.sequence(coll, 0, 0, min_steps=3)) == 1
    summary = {k.kind: k for k in RC.kind_summary(coll)}
    assert tuple(summary) == tuple(CONTACT_KINDS)
    assert summary["arm1-arm1"].periods_with_contact == 1.0 and summary["arm1-arm1"].attractive_fraction == 0.5
    assert summary["arm1-arm1"].mean_impulse_r == pytest.approx((3e-4 - 2e-4) / 2)
    assert summary["body-body"].periods_with_contact == 0.5 and summary["body-body"].attractive_fraction == 0.0
    assert summary["arm2-arm2"].periods_with_contact == 0.0 and math.isnan(summary["arm2-arm2"].attractive_fraction)
    only_first = {k.kind: k for k in RC.kind_summary(coll, mask=np.array([[True, False]]))}
    assert only_first["arm1-arm1"].attractive_fraction == 1.0


# ------------------------------------------------------------------ arm hits (built records and tracks)

def _hit_record(k=2, b=8, n=3):
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)])
    return np.zeros((k, len(pairs), len(RC.KINDS), b), np.int32), pairs


def _track(moves, n=3, t_end=2.0, dt=0.001):
    """A track of n resting robots; ``moves``: (robot, t0, t1, dx in m) moves it along x linearly."""
    t = np.arange(0.0, t_end + dt / 2, dt)
    poses = np.zeros((len(t), n, 3))
    poses[:, :, 1] = np.arange(n) * 0.1
    for r, t0, t1, dx in moves:
        poses[:, r, 0] += dx * np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return t, poses


def test_arm_hit_push_and_coast_built():
    """Robot 1's arm on robot 0's body in bins 3-4 of the first period (T = 1 s, 8 bins: 0.375-0.625 s):
    robot 0 moves 2 mm while touched and coasts 1 mm in the next 50 ms; the hit says so, and who hit whom."""
    steps, pairs = _hit_record()
    steps[0, 0, RC.KINDS.index("body-arm1"), 3:5] = 5
    t, poses = _track([(0, 0.375, 0.625, 0.002), (0, 0.625, 0.675, 0.001)])
    res = RC.arm_hits(steps, pairs, 1.0, t, poses)
    assert res.left_out == 0 and len(res.hits) == 1
    h = res.hits[0]
    assert (h.striker, h.struck) == (1, 0)
    assert (h.start_s, h.end_s) == pytest.approx((0.375, 0.625))
    assert (h.push_mm, h.coast_mm, h.slide_mm) == pytest.approx((2.0, 1.0, 3.0), abs=1e-9)
    assert res.coast_share == pytest.approx(1 / 3)


def test_arm_hit_other_direction_and_across_period_end():
    """Robot 0's arm 2 on robot 2's body (pair (0, 2), kind arm2-body) in the last bin of period 0 and the
    first of period 1 is one hit of robot 2, 0.875-1.125 s; nothing moved, so it slid nothing."""
    steps, pairs = _hit_record()
    q = [tuple(p) for p in pairs].index((0, 2))
    steps[0, q, RC.KINDS.index("arm2-body"), 7] = 1
    steps[1, q, RC.KINDS.index("arm2-body"), 0] = 3
    t, poses = _track([])
    res = RC.arm_hits(steps, pairs, 1.0, t, poses)
    assert len(res.hits) == 1
    h = res.hits[0]
    assert (h.striker, h.struck) == (0, 2)
    assert (h.start_s, h.end_s) == pytest.approx((0.875, 1.125))
    assert h.slide_mm == pytest.approx(0.0)


def test_arm_hit_left_out_when_not_alone():
    """A hit counts only where what the struck robot moved is the hit's: a third robot touching it during
    the hit, or anything touching it in the settling after, leaves it out; so does a track that ends first."""
    steps, pairs = _hit_record()
    steps[0, 0, RC.KINDS.index("body-arm1"), 3] = 1  # robot 1's arm on robot 0 ...
    q02 = [tuple(p) for p in pairs].index((0, 2))
    steps[0, q02, RC.KINDS.index("arm1-arm1"), 3] = 1  # ... while robot 2 touches robot 0
    t, poses = _track([])
    assert RC.arm_hits(steps, pairs, 1.0, t, poses).left_out == 1
    steps, pairs = _hit_record()
    steps[0, 0, RC.KINDS.index("body-arm1"), 3] = 1
    steps[0, q02, RC.KINDS.index("body-body"), 4] = 1  # robot 2 touches robot 0 within 0.1 s after the hit
    assert RC.arm_hits(steps, pairs, 1.0, t, poses).left_out == 1
    steps, pairs = _hit_record()
    steps[0, 0, RC.KINDS.index("body-arm1"), 3] = 1
    assert len(RC.arm_hits(steps, pairs, 1.0, t, poses).hits) == 1  # alone: counted
    t_short, p_short = _track([], t_end=0.45)
    assert RC.arm_hits(steps, pairs, 1.0, t_short, p_short).left_out == 1  # the track ends in the settling


def test_arm_hit_records_are_checked():
    with pytest.raises(ValueError, match="contact kinds"):
        RC.arm_hits(np.zeros((1, 1, 4, 8)), np.array([[0, 1]]), 1.0, np.arange(3.0), np.zeros((3, 2, 3)))
