"""The warp backend (MuJoCo Warp) against MuJoCo C and against itself.

These run on Warp's CPU device where no GPU is present (CI), and on the GPU
where one is. MuJoCo Warp compiles its kernels on first use (about a minute
on two cores, cached in Warp's kernel cache afterwards), so every test here
shares one module-scoped backend of the default model (at the 0.5 ms step: see P
below). The periods are kept short (0.025 s: 50 steps) because Warp's CPU device runs these small batches
at about a hundred steps per second; the engine mechanics checked do not
need a full gait period (such a hurried gait makes the arms hit hard enough
to set the penetration flag on both backends: early exit is off there).
"""

import dataclasses

import mujoco
import numpy as np
import pytest

from smarticle_mjx import configs as C
from smarticle_mjx import presets
from smarticle_mjx.engine import Lanes, Scene, Status, make_backend
from smarticle_mjx.engine import mjwarp
from smarticle_mjx.engine.batch import RetireRule, run_lanes
from smarticle_mjx.gait import GaitSpec

needs_warp = pytest.mark.skipif(not mjwarp.available(), reason="MuJoCo Warp is not installed (pip install -e '.[gpu]')")

# Warp runs on this machine's CPU at 1-5k steps/s, so these engine checks keep the 0.5 ms step of versions
# 0.3.x (half the steps of the 0.25 ms default; the tolerances below were measured at it). What they check,
# the two engines stepping the same model alike, does not depend on which step that model has.
P = dataclasses.replace(presets.params(), timestep=5e-4)
GAIT = GaitSpec(90.0)
A0 = GAIT.setpoints(0.0, P.robot.servo_speed)
# A start whose robots hit arm-arm 44 ms and arm-body 46 ms in (MuJoCo C, default model; measured at 0.25 ms)
IMPACT = (1.1492, 5.9529, 6.2625)
SHORT = 0.025  # s: a 50-step "period" for the engine checks


@pytest.fixture(scope="module")
def scene():
    return Scene.build(P, 2)


@pytest.fixture(scope="module")
def warp(scene):
    return make_backend("warp", scene)


@pytest.fixture(scope="module")
def native(scene):
    be = make_backend("native", scene, nthread=1)
    yield be
    be.close()


def _lanes(n, seed, period=SHORT, r_range=(0.8, 1.4)):
    poses = C.sample_valid_pairs(n, np.random.default_rng(seed), r_range, A0[0], A0[1])
    lanes = Lanes.from_gait(poses, GAIT)
    return Lanes(lanes.poses, lanes.amplitude, lanes.chirality, lanes.kind, lanes.phase, period)


@needs_warp
def test_buffers_cover_every_pair_mujoco_warp_collides(scene):
    """The contact buffer is sized from the same candidate pairs MuJoCo Warp's
    own filter keeps (its nxn list without the excluded ones), at the most
    contacts each pair of geom types can produce."""
    import warp as wp
    import mujoco_warp as mjw
    with wp.ScopedDevice("cpu"):
        mw = mjw.put_model(scene.model)
    pairs = mw.nxn_geom_pair.numpy()[mw.nxn_pairid.numpy()[:, 0] != -2]
    assert sorted(map(tuple, pairs.tolist())) == mjwarp.collision_pairs(scene.model)
    nconmax, njmax = mjwarp.buffer_sizes(scene.model)
    # two bodies on the plate (4 corners each) and nine box-box robot pairs (8 each)
    assert nconmax == 2 * 4 + 9 * 8
    assert njmax >= 3 * nconmax


@needs_warp
def test_warp_follows_mujoco_c_step_by_step_through_the_first_impacts(scene, warp, native):
    """Same scene, same controls: MuJoCo Warp (float32) follows MuJoCo C
    (float64) over the first 55 ms (110 steps of 0.5 ms), which span the first arm-arm and
    arm-body impacts of the IMPACT start: arm angles within 2 mrad, body
    positions within 0.1 mm. (The impacts are where float32 contact
    resolution could part the paths; the bound is set by the arm-angle
    resolution the touch labels need, well under a degree.)"""
    poses = np.stack([C.pair_poses(*IMPACT, A0[0], A0[1])] + list(_lanes(2, 7).poses))
    lanes = Lanes.from_gait(poses, GAIT)
    nsteps = int(round(0.055 / scene.model.opt.timestep))
    qw = warp.step_qpos(lanes, nsteps)
    qn = native.step_qpos(lanes, nsteps)
    # the window does hold the impacts: MuJoCo C's robot-robot contacts, stepped by hand
    m, lay = scene.model, scene.layout
    d = mujoco.MjData(m)
    kinds = set()
    for s in range(nsteps):
        d.qpos[:] = qn[0, s]
        mujoco.mj_forward(m, d)
        for c in d.contact[:d.ncon]:
            r1, r2 = lay.geom_robot[c.geom1], lay.geom_robot[c.geom2]
            if r1 >= 0 and r2 >= 0 and r1 != r2:
                arm1 = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, c.geom1).endswith(("arm1", "arm2"))
                arm2 = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, c.geom2).endswith(("arm1", "arm2"))
                kinds.add("arm-arm" if arm1 and arm2 else "arm-body" if arm1 or arm2 else "body-body")
    assert {"arm-arm", "arm-body"} <= kinds, f"the window must span both impacts, saw {kinds}"
    arms = np.abs(qw[..., lay.arm_qpos.ravel()] - qn[..., lay.arm_qpos.ravel()]).max()
    body = max(np.abs(qw[..., a:a + 2] - qn[..., a:a + 2]).max() for a in lay.free_qpos)
    assert np.abs(qn[:, -1, lay.arm_qpos[0]] - qn[:, 0, lay.arm_qpos[0]]).max() > 0.1, "arms must have moved"
    assert arms < 2e-3 and body < 1e-4, (arms, body)


@needs_warp
def test_one_lane_alone_equals_the_same_lane_in_a_batch(scene, warp):
    """A lane's records do not depend on its batch: bit for bit on Warp's CPU
    device (kernels run in order); on a GPU the contact pool's float32
    atomics may sum in another order, which moved poses by ~1e-10 m over 200
    steps on an H100, so there the bound is 1e-6 (m and rad)."""
    lanes = _lanes(5, 1)
    _, batch, _ = warp.advance(warp.initial_state(lanes), lanes, 1)
    one = lanes.take([3])
    _, alone, _ = warp.advance(warp.initial_state(one), one, 1)
    exact = not warp.device.is_cuda
    np.testing.assert_allclose(alone.poses[0], batch.poses[3], rtol=0, atol=0 if exact else 1e-6)
    np.testing.assert_array_equal(alone.touched[0], batch.touched[3])
    np.testing.assert_allclose(alone.min_dist[0], batch.min_dist[3], rtol=0, atol=0 if exact else 1e-6)


@needs_warp
def test_refill_keeps_every_lane_and_matches_a_full_batch(scene, warp):
    """Slots refilled mid-run (a new lane's state written into a running
    batch) give each lane the records it gets in a batch of all lanes."""
    lanes = _lanes(4, 2)
    got = {}
    run_lanes(warp, lanes, 2, batch_size=2, chunk_periods=1, rule=RetireRule(quiet_periods=0, on_bad_status=False),
              on_lanes=lambda r: got.update({int(i): r.poses[k] for k, i in enumerate(r.index)}))
    _, full, _ = warp.advance(warp.initial_state(lanes), lanes, 2)
    assert sorted(got) == [0, 1, 2, 3]
    for i in range(4):
        np.testing.assert_array_equal(got[i], full.poses[i])


@needs_warp
def test_touch_records_agree_with_native(scene, warp, native):
    """Bound/unbound labels over whole gait periods: pairs running the real
    square gait (45 degrees, its own 0.8 s period, every step of every arm edge
    and dwell) for two periods, from starts that touch and starts that stay
    apart. MuJoCo Warp runs in float32, MuJoCo C in float64; colliding pairs
    amplify the rounding, and after two periods the bodies differ by up to
    ~0.6 mm (measured), so a contact shallower than that is not decided by
    the model. The labels must agree in every lane and period except where
    the engine that saw a touch saw it shallower than that lane's divergence
    between the engines (a grazing contact); every label of the first period
    agrees; the deepest contact distance agrees within 0.2 mm where both
    touched; bodies end within 2 mm (4 % of W)."""
    gait = GaitSpec(45.0)
    a0 = gait.setpoints(0.0, P.robot.servo_speed)
    poses = C.sample_valid_pairs(8, np.random.default_rng(3), (0.8, 1.6), a0[0], a0[1])
    lanes = Lanes.from_gait(poses, gait)
    assert lanes.period == gait.period() == pytest.approx(0.8)
    _, w, _ = warp.advance(warp.initial_state(lanes), lanes, 2)
    _, n, _ = native.advance(native.initial_state(lanes), lanes, 2)
    wt, nt = w.touched[:, :, 0], n.touched[:, :, 0]
    assert (wt & nt).any() and (~wt & ~nt).any(), "the sample must hold touching and apart lanes"
    np.testing.assert_array_equal(wt[:, 0], nt[:, 0])
    divergence = np.abs(w.poses[..., :2] - n.poses[..., :2]).max(axis=(1, 2, 3))  # [lanes] m
    depth = np.where(wt, -w.min_dist[:, :, 0], -n.min_dist[:, :, 0])  # of the engine that saw the touch
    for lane, period in zip(*np.nonzero(wt != nt)):
        assert depth[lane, period] < divergence[lane], (lane, period, depth[lane, period], divergence[lane])
    both = w.touched & n.touched
    assert np.abs(w.min_dist[both] - n.min_dist[both]).max() < 2e-4
    np.testing.assert_allclose(w.poses[..., :2], n.poses[..., :2], atol=2e-3)
    assert not (w.status & Status.OVERFLOW).any()


@needs_warp
def test_a_buffer_overflow_is_flagged_never_silent(scene):
    """With a contact buffer too small for two bodies resting on the plate
    (4 corners each), MuJoCo Warp drops contacts: every lane says so in its
    status, and the batch runner retires it."""
    be = make_backend("warp", scene)
    be.nconmax = 2
    lanes = _lanes(2, 4)
    _, rec, _ = be.advance(be.initial_state(lanes), lanes, 1)
    assert (rec.status & Status.OVERFLOW).all()
    got = {}
    run_lanes(be, lanes, 2, batch_size=2, chunk_periods=1, rule=RetireRule(quiet_periods=0),
              on_lanes=lambda r: got.update({int(i): (int(r.status[k]), int(r.periods_run[k]))
                                             for k, i in enumerate(r.index)}))
    assert all(s & Status.OVERFLOW and s & Status.RETIRED and n == 1 for s, n in got.values())


@needs_warp
def test_scan_cli_runs_on_the_warp_backend(tmp_path):
    """``smx scan --backend warp`` writes a complete store."""
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    from smarticle_mjx.store import Store
    out = tmp_path / "w.h5"
    res = CliRunner().invoke(app, ["scan", "--n", "3", "--periods", "1", "--amplitude", "5", "--period", "0.1",
                                   "--backend", "warp",
                                   "--quiet", "--out", str(out)])
    assert res.exit_code == 0, res.output
    st = Store(out)
    d = st.run(st.runs[0], fields=("valid", "touched", "status", "poses"))
    assert d["touched"].shape[:2] == (3, 1)
    assert np.isfinite(d["poses"][d["valid"]]).all() and not (d["status"] & Status.OVERFLOW).any()
    assert st.config["scan"]["backend"] == "warp"


def test_warp_backend_without_mujoco_warp_is_one_line_exit_2(tmp_path, monkeypatch):
    """Without the gpu extra, ``--backend warp`` says what to install, exit 2, nothing written."""
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    monkeypatch.setattr(mjwarp, "available", lambda: False)
    out = tmp_path / "w.h5"
    res = CliRunner().invoke(app, ["scan", "--n", "2", "--periods", "1", "--backend", "warp", "--quiet",
                                   "--out", str(out)])
    assert res.exit_code == 2
    assert "pip install -e '.[gpu]'" in res.output and len(res.output.strip().splitlines()) == 1
    assert not out.exists()


@needs_warp
def test_robots_with_their_own_amplitude_and_chirality_run_as_on_native(scene, warp, native):
    """Per-robot amplitude and chirality (one period) go through Warp's control
    table like per-lane gaits: after 0.2 s (robot 0 at 45 deg ccw, robot 1 at
    30 deg cw, 0.5 m apart) the arm angles agree with MuJoCo C within 2 mrad
    (float32); different periods in one lane are refused in one line."""
    g0, g1 = GaitSpec(45.0, "ccw", period_s=0.1), GaitSpec(30.0, "cw", period_s=0.1)
    poses = np.zeros((2, 2, 5))
    poses[:, 1, :3] = [0.5, 0.0, 1.0]
    poses[:, 0, 3:] = g0.setpoints(0.0, P.robot.servo_speed)
    poses[:, 1, 3:] = g1.setpoints(0.0, P.robot.servo_speed)
    poses[1, :, 2] += 0.7
    lanes = Lanes.from_robot_gaits(poses, [g0, g1])
    _, w, _ = warp.advance(warp.initial_state(lanes), lanes, 2)
    _, n, _ = native.advance(native.initial_state(lanes), lanes, 2)
    assert np.abs(n.poses[:, :, 0, 3:] - n.poses[:, :, 1, 3:]).max() > np.radians(5), "the two gaits must differ"
    np.testing.assert_allclose(w.poses[..., 3:], n.poses[..., 3:], atol=2e-3)
    other = Lanes.from_robot_gaits(poses, [g0, GaitSpec(30.0, "cw", period_s=0.15)])
    with pytest.raises(ValueError, match="own gait periods in one lane .clock drift. run on the native and mjx backends, not warp"):
        warp.advance(warp.initial_state(other), other, 1)


@needs_warp
def test_warp_collides_box_pairs_as_mujoco_c_does(scene, warp, native):
    """The backend's box pairs go through MuJoCo Warp's port of the analytic
    box-box collider, MuJoCo C's (its default since 0.4.2; Warp's own GJK/EPA
    made rare phantom contacts a box's thickness deep on a GPU, docs/engine.md).
    At every state of the IMPACT start where MuJoCo C finds robots touching,
    the backend's model finds the same contacts: per geom pair the same count,
    each depth within 10 um (float32), and the scene's own model is left as built."""
    import warp as wp
    import mujoco_warp as mjw
    assert warp.box_collider == "analytic"
    assert warp.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_NATIVECCD
    assert not scene.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_NATIVECCD
    lanes = Lanes.from_gait(np.array([C.pair_poses(*IMPACT, A0[0], A0[1])]), GAIT)
    q = native.step_qpos(lanes, int(round(0.08 / scene.model.opt.timestep)))[0]
    m, robot = scene.model, scene.layout.geom_robot
    d = mujoco.MjData(m)
    want, touching = [], []
    for i, qi in enumerate(q):
        d.qpos[:] = qi
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        pairs = {}
        for c in d.contact[:d.ncon]:
            g1, g2 = sorted((int(c.geom1), int(c.geom2)))
            if robot[g1] >= 0 and robot[g2] >= 0 and robot[g1] != robot[g2]:
                pairs.setdefault((g1, g2), []).append(float(c.dist))
        if pairs:
            touching.append(i)
            want.append(pairs)
    assert len(touching) >= 10, "the start must hold robot-robot contacts"
    nconmax, njmax = mjwarp.buffer_sizes(m)
    with wp.ScopedDevice("cpu"):
        mw = mjw.put_model(warp.model)
        dw = mjw.make_data(warp.model, nworld=len(touching), nconmax=nconmax, njmax=njmax)
        dw.qpos.assign(q[touching].astype(np.float32))
        mjw.kinematics(mw, dw)
        mjw.collision(mw, dw)
    n = int(dw.nacon.numpy()[0])
    geom, dist, world = dw.contact.geom.numpy()[:n], dw.contact.dist.numpy()[:n], dw.contact.worldid.numpy()[:n]
    got = [{} for _ in touching]
    for (g1, g2), x, w in zip(np.sort(geom, axis=1), dist, world):
        if robot[g1] >= 0 and robot[g2] >= 0 and robot[g1] != robot[g2]:
            got[w].setdefault((int(g1), int(g2)), []).append(float(x))
    for k, (a, b) in enumerate(zip(want, got)):
        assert a.keys() == b.keys(), (touching[k], a, b)
        for pair in a:
            assert len(a[pair]) == len(b[pair]), (touching[k], pair, a[pair], b[pair])
            assert np.allclose(sorted(a[pair]), sorted(b[pair]), atol=1e-5), (touching[k], pair, a[pair], b[pair])


def test_warp_backend_refuses_an_unknown_box_collider(scene):
    """A box collider the backend does not know is a one-line ValueError naming the choices, raised
    before MuJoCo Warp is imported."""
    with pytest.raises(ValueError, match="analytic, convex"):
        mjwarp.WarpBackend(scene, box_collider="gjk")
