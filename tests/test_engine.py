"""Batched engine: one interface, two backends, early exit, same answers everywhere."""

import numpy as np
import pytest

from smarticle_mjx import configs as C
from smarticle_mjx import scene as S
from smarticle_mjx.engine import Lanes, Scene, Status, make_backend
from smarticle_mjx.engine.batch import RetireRule, run_lanes
from smarticle_mjx.engine.core import Record
from smarticle_mjx.gait import GaitSpec

P = S.SceneParams()
GAIT = GaitSpec(90.0)
A0 = GAIT.setpoints(0.0, P.robot.servo_speed)


@pytest.fixture(scope="module")
def scene():
    return Scene.build(P, 2)


@pytest.fixture(scope="module")
def mjx_backend(scene):
    """One MJX backend for the module (building one traces and compiles MJX's forward)."""
    return make_backend("mjx", scene)


def _lanes(n, seed=0, r_range=(0.9, 2.0)):
    poses = C.sample_valid_pairs(n, np.random.default_rng(seed), r_range, A0[0], A0[1])
    return Lanes.from_gait(poses, GAIT)


def _collect(backend, lanes, periods, **kw):
    got = {}
    summary = run_lanes(backend, lanes, periods, on_lanes=lambda r: got.update(
        {int(i): (r.touched[k], r.poses[k], int(r.status[k]), int(r.periods_run[k])) for k, i in enumerate(r.index)}),
        **kw)
    return got, summary


def test_one_lane_alone_equals_the_same_lane_in_a_batch(scene):
    lanes = _lanes(6)
    be = make_backend("native", scene)
    _, batch, _ = be.advance(be.initial_state(lanes), lanes, 3)
    one = lanes.take([4])
    _, alone, _ = be.advance(be.initial_state(one), one, 3)
    np.testing.assert_array_equal(alone.poses[0], batch.poses[4])
    np.testing.assert_array_equal(alone.touched[0], batch.touched[4])


def test_records_do_not_depend_on_batch_size_or_threads(scene):
    lanes = _lanes(10, seed=1)
    runs = []
    for nthread, batch_size in ((1, 3), (2, 10), (2, 4)):
        be = make_backend("native", scene, nthread=nthread)
        got, _ = _collect(be, lanes, 2, batch_size=batch_size, chunk_periods=1, rule=RetireRule(quiet_periods=0))
        runs.append(got)
        be.close()
    for other in runs[1:]:
        for i in range(lanes.size):
            np.testing.assert_array_equal(other[i][0], runs[0][i][0])
            np.testing.assert_array_equal(other[i][1], runs[0][i][1])


def test_early_exit_retires_quiet_lanes_and_keeps_bound_ones(scene):
    # lane 0 far apart (never touches), lane 1 a colliding pair
    far = C.pair_poses(3.5, 1.0, 2.0, A0[0], A0[1])
    near = C.pair_poses(1.16, 6.026, 4.451, A0[0], A0[1])
    lanes = Lanes.from_gait(np.stack([far, near]), GAIT)
    be = make_backend("native", scene)
    got, summary = _collect(be, lanes, 6, batch_size=1, chunk_periods=1, rule=RetireRule(quiet_periods=2))
    assert got[0][3] == 2 and got[0][2] & Status.RETIRED
    assert np.isnan(got[0][1][2:]).all() and not got[0][0].any()
    assert got[1][0].any()
    assert summary["lane_periods"] < summary["full_lane_periods"]


def test_invalid_lanes_are_flagged_and_never_simulated(scene):
    lanes = _lanes(3, seed=2)
    valid = np.array([True, False, True])
    be = make_backend("native", scene)
    got, summary = _collect(be, lanes, 2, valid=valid, rule=RetireRule(quiet_periods=0))
    assert got[1][2] == Status.INVALID and got[1][3] == 0
    assert got[0][2] == Status.OK and got[2][3] == 2
    assert summary["lane_periods"] == 4


def test_refill_keeps_every_lane_and_matches_a_full_batch(scene):
    """Slots refilled mid-run give each lane the records it gets in a batch of its own."""
    lanes = _lanes(5, seed=3)
    be = make_backend("native", scene)
    small, _ = _collect(be, lanes, 4, batch_size=2, chunk_periods=2, rule=RetireRule(quiet_periods=0))
    _, full, _ = be.advance(be.initial_state(lanes), lanes, 4)
    assert sorted(small) == list(range(5))
    for i in range(5):
        np.testing.assert_array_equal(small[i][1], full.poses[i])


def _max_arm_and_body_diff(params, lanes):
    scene = Scene.build(params, 2)
    nat = make_backend("native", scene).step_qpos(lanes, 100)
    mj = make_backend("mjx", scene).step_qpos(lanes, 100)
    lay = scene.layout
    arms = np.abs(mj[..., lay.arm_qpos.ravel()] - nat[..., lay.arm_qpos.ravel()]).max()
    body = max(np.abs(mj[..., a:a + 2] - nat[..., a:a + 2]).max() for a in lay.free_qpos)
    moved = np.abs(nat[:, -1, lay.arm_qpos[0]] - nat[:, 0, lay.arm_qpos[0]]).max()
    return arms, body, moved


@pytest.mark.slow  # 50 s of MJX compiling; MJX against MuJoCo C stays in the default run through
# test_presets (the default model's servo, 60 steps) and tests/test_mjx_collision.py (its contacts)
def test_mjx_agrees_with_native_step_by_step():
    """Same scene, same controls: MJX (float32) and MuJoCo C (float64) follow
    the same path over the first 100 steps: arm angles within 1 mrad
    (0.06 deg), bodies within 0.1 mm.

    Measured: 0.57 mrad and 0.014 mm. The arm gap peaks ~17 steps into the
    first move, while the servo is clamped at its stall torque (the two
    implicit integrators linearise a clamped actuator differently), then
    decays; with a servo that never saturates it is 0.2 mrad."""
    lanes = _lanes(4, seed=4)
    arms, body, moved = _max_arm_and_body_diff(P, lanes)
    assert moved > 0.1, "arms must have moved"
    assert arms < 1e-3 and body < 1e-4


def test_unknown_backend_is_refused(scene):
    with pytest.raises(ValueError, match="unknown backend"):
        make_backend("cuda", scene)


def test_mjx_refuses_an_integrator_it_does_not_implement():
    """MJX's step implements Euler, RK4 and implicitfast; 'discrete' would fail inside the first trace."""
    with pytest.raises(ValueError, match="the mjx backend integrates with"):
        make_backend("mjx", Scene.build(P.replace(integrator="discrete"), 2))


def test_mjx_and_warp_refuse_a_solver_they_do_not_implement():
    """MJX and MuJoCo Warp solve with Newton or CG; PGS is refused in one line before anything compiles
    (MJX's put_model would raise NotImplementedError from deep inside)."""
    for name in ("mjx", "warp"):
        with pytest.raises(ValueError, match=f"the {name} backend solves constraints with Newton, CG, not 'PGS'"):
            make_backend(name, Scene.build(P.replace(solver="PGS"), 2))


@pytest.mark.slow  # 50 s, mostly MJX compiling; the device-array refill itself is checked below in a second
def test_mjx_backend_runs_the_batch_runner_with_refill(scene, mjx_backend):
    """Refilling slots works on device arrays too, and the first period's
    touches match the native backend (float32 vs float64, one period)."""
    lanes = _lanes(4, seed=5)
    be = mjx_backend
    got, summary = _collect(be, lanes, 1, batch_size=2, chunk_periods=1, rule=RetireRule(quiet_periods=0))
    assert sorted(got) == [0, 1, 2, 3] and summary["lane_periods"] == 4
    nat = make_backend("native", scene)
    _, ref, _ = nat.advance(nat.initial_state(lanes), lanes, 1)
    touched = np.stack([got[i][0] for i in range(4)])
    np.testing.assert_array_equal(touched, ref.touched)
    poses = np.stack([got[i][1] for i in range(4)])
    np.testing.assert_allclose(poses[..., :2], ref.poses[..., :2], atol=2e-3)


def test_refill_writes_new_lanes_into_device_state_and_leaves_the_rest():
    """What refill does to an MJX batch (a pytree of JAX arrays): the chosen
    slots take the new lanes' state, every other slot keeps its own; taking
    slots back gives exactly what was put."""
    import jax.numpy as jnp
    from smarticle_mjx.engine.batch import _put_state, _take_state
    state = {"qpos": jnp.arange(12.0).reshape(4, 3), "act": jnp.zeros((4, 2))}
    new = {"qpos": -jnp.ones((2, 3)), "act": jnp.ones((2, 2))}
    idx = np.array([1, 3])
    out = _put_state(state, idx, new)
    np.testing.assert_array_equal(np.asarray(out["qpos"])[[0, 2]], np.arange(12.0).reshape(4, 3)[[0, 2]])
    np.testing.assert_array_equal(np.asarray(_take_state(out, idx)["qpos"]), -np.ones((2, 3)))
    np.testing.assert_array_equal(np.asarray(_take_state(out, idx)["act"]), np.ones((2, 2)))


def _dot_generals(jaxpr):
    """Every dot_general equation of a jaxpr, sub-jaxprs (scan, cond, pjit) included."""
    for e in jaxpr.eqns:
        if e.primitive.name == "dot_general":
            yield e
        for v in e.params.values():
            for x in v if isinstance(v, (list, tuple)) else (v,):
                inner = getattr(x, "jaxpr", x)
                if hasattr(inner, "eqns"):
                    yield from _dot_generals(inner)


def test_mjx_backend_runs_at_full_matmul_precision(scene, monkeypatch):
    """On GPUs JAX defaults to TF32 matmuls (10-bit mantissa); the MJX backend
    must not: after it is built, every matrix product in its traced gait
    period (mjx.step with our contact records, vmapped over lanes) asks for
    HIGHEST precision. The only exceptions are MJX's own: its box-box
    separating-axis test pins Precision.HIGH on two support products
    (mujoco/mjx/_src/collision_convex.py), which no global setting reaches.
    Checked on the traced program, so it holds on a CPU too, where every
    precision computes the same. (The contact-slot map, which compiles
    MJX's forward, is stubbed: the setting is made before it.)"""
    import jax
    from smarticle_mjx.engine import mjx as mjx_mod
    monkeypatch.setattr(mjx_mod, "_contact_slots", lambda scene, model, mx: np.zeros((1, 1), bool))
    jax.config.update("jax_default_matmul_precision", None)
    try:
        be = make_backend("mjx", scene)
        assert jax.config.jax_default_matmul_precision == "highest"
        lanes = Lanes.from_gait(C.sample_valid_pairs(2, np.random.default_rng(0), (0.8, 1.4), A0[0], A0[1]), GAIT)
        args, per_robot = be._lane_args(lanes)
        traced = be._period_fn(2, per_robot).trace(be.initial_state(lanes), *args)
    finally:
        jax.config.update("jax_default_matmul_precision", "highest")
    highest = (jax.lax.Precision.HIGHEST,) * 2
    dots = list(_dot_generals(traced.jaxpr.jaxpr))
    assert sum(e.params["precision"] == highest for e in dots) > 50
    others = [e for e in dots if e.params["precision"] != highest]
    for e in others:
        files = [f.file_name for f in e.source_info.traceback.frames]
        assert any(f.endswith("mjx/_src/collision_convex.py") for f in files), (e.params["precision"], files[:3])
        assert e.params["precision"] == (jax.lax.Precision.HIGH,) * 2


# ---- robots with their own gaits in one lane -------------------------------------------------
OWN_A, OWN_B = GaitSpec(22.5, "ccw"), GaitSpec(33.75, "cw")  # periods 0.4 s and 0.6 s: 3 of A take 2 of B
S_TRACK = Record(track_stride=10)


def _far_apart(a: GaitSpec, b: GaitSpec):
    """Two robots 0.5 m apart (no contact possible), each at its own gait's first corner."""
    poses = np.zeros((1, 2, 5))
    poses[0, 1, :3] = [0.5, 0.0, 1.0]
    poses[0, 0, 3:] = a.setpoints(0.0, P.robot.servo_speed)
    poses[0, 1, 3:] = b.setpoints(0.0, P.robot.servo_speed)
    return poses


def test_a_robot_with_its_own_gait_moves_as_it_does_beside_a_robot_with_the_same_gait(scene):
    """Robots that cannot touch do not influence each other, so robot 1 running
    gait B (other amplitude, chirality and period) must follow the same path
    whether robot 0 runs gait A or gait B. Over 1.2 s (3 periods of A, 2 of B:
    robot 1 is mid-period at A's period boundaries) its full-rate track must
    match; a robot 1 whose clock restarted at A's boundaries is off by tens of
    degrees after the first 0.4 s (measured: 42 deg RMS).

    Not bit for bit: the gait's setpoints are computed in float32, where an
    array of per-robot periods and one scalar period round differently (up to
    5e-7 rad in the command); a stick-slip event of the body amplifies that to
    1.7 mrad in the arms and 23 um in the body over these 1.2 s (with one gait,
    robot 0's motion changes robot 1's path by exactly 0)."""
    be = make_backend("native", scene)
    own = Lanes.from_robot_gaits(_far_apart(OWN_A, OWN_B), [OWN_A, OWN_B])
    assert own.robot_period is not None and own.period == OWN_A.period()
    same = Lanes.from_gait(_far_apart(OWN_B, OWN_B), OWN_B)
    _, _, t_own = be.advance(be.initial_state(own), own, 3, record=S_TRACK)
    _, _, t_same = be.advance(be.initial_state(same), same, 2, record=S_TRACK)
    np.testing.assert_allclose(t_own["t"], t_same["t"], atol=1e-9)
    q_own = scene.poses_from_qpos(t_own["qpos"][0])[:, 1]
    q_same = scene.poses_from_qpos(t_same["qpos"][0])[:, 1]
    assert np.ptp(q_same[:, 3]) > np.radians(60), "robot 1's arms must sweep their 2 x 33.75 deg"
    np.testing.assert_allclose(q_own[:, 3:], q_same[:, 3:], atol=5e-3)  # arms, rad
    np.testing.assert_allclose(q_own[:, :2], q_same[:, :2], atol=1e-4)  # body, m


def test_a_run_split_into_calls_continues_each_robots_own_clock(scene):
    """Advancing 1 period and then 2 more (t0 = one period) is the same run as
    3 periods at once, for robots whose period is not the batch's."""
    be = make_backend("native", scene)
    own = Lanes.from_robot_gaits(_far_apart(OWN_A, OWN_B), [OWN_A, OWN_B])
    _, whole, _ = be.advance(be.initial_state(own), own, 3)
    s, first, _ = be.advance(be.initial_state(own), own, 1)
    _, rest, _ = be.advance(s, own, 2, t0=OWN_A.period())
    np.testing.assert_array_equal(np.concatenate([first.poses, rest.poses], 1), whole.poses)


def test_lanes_refuse_gaits_that_do_not_fit_the_robots():
    with pytest.raises(ValueError, match="3 gaits for 2 robots"):
        Lanes.from_robot_gaits(np.zeros((1, 2, 5)), [OWN_A] * 3)
    with pytest.raises(ValueError, match="amplitude must have shape"):
        Lanes(np.zeros((1, 2, 5)), np.zeros((1, 3)), np.ones(1, np.int32), np.zeros(1, np.int32),
              np.zeros((1, 2)), 0.4)


@pytest.mark.slow  # MJX compiling
def test_mjx_runs_robots_with_their_own_gaits_like_native(scene, mjx_backend):
    """The MJX backend takes per-robot amplitude, chirality and period as traced
    inputs; over 3 periods of robot 0 its arm angles at the period ends match
    MuJoCo C within float32 (robot 1 is then at 1/3 and 2/3 of its period)."""
    own = Lanes.from_robot_gaits(_far_apart(OWN_A, OWN_B), [OWN_A, OWN_B])
    nat = make_backend("native", scene)
    _, ref, _ = nat.advance(nat.initial_state(own), own, 3)
    _, got, _ = mjx_backend.advance(mjx_backend.initial_state(own), own, 3)
    np.testing.assert_allclose(got.poses[..., 3:], ref.poses[..., 3:], atol=2e-3)
    np.testing.assert_allclose(got.poses[..., :2], ref.poses[..., :2], atol=1e-4)


def test_lane_controls_are_each_lanes_own_gait_and_compile_once_per_shape():
    """Each lane gets the controls of its own gait (amplitude, chirality, kind,
    phase, its robots' own periods) whatever else shares its batch, checked
    against the gait function evaluated for that robot alone; and lanes that
    share one gait evaluate it once, so batches of 3, 5 and 17 such lanes do
    not each compile the gait function anew."""
    from smarticle_mjx import gait as G
    from smarticle_mjx.engine import core
    params = S.SceneParams()
    scene = Scene.build(params, 2)
    rng = np.random.default_rng(3)
    g = GaitSpec(90.0)
    a0 = g.setpoints(0.0, params.robot.servo_speed)
    poses = C.sample_valid_pairs(9, rng, (0.8, 2.0), a0[0], a0[1])
    t = params.timestep * np.arange(0, 3200, 7)
    mixed = Lanes(poses, rng.choice([0.6, 1.2, 1.5], size=(9, 2)), rng.choice([-1, 1], size=(9, 2)),
                  rng.choice([0, 1], size=(9, 2)), rng.choice([0.0, 0.1, 0.25], size=(9, 2)), 1.6,
                  rng.choice([1.6, 1.7], size=(9, 2)))
    got = core.lane_controls(scene, mixed, t)
    amp, chi, kind, period = mixed.robot_gait()
    for i in range(9):
        for r in range(2):
            ref = np.asarray(G.setpoints_and_rates(t, amp[i, r], period[i, r], params.robot.servo_speed,
                                                   chi[i, r], kind[i, r], mixed.phase[i, r]))
            np.testing.assert_allclose(got[i, :, 4 * r:4 * r + 4], ref, rtol=0, atol=1e-5)
    one = Lanes.from_gait(C.sample_valid_pairs(17, rng, (0.8, 2.0), a0[0], a0[1]), g)
    core.lane_controls(scene, one.take(np.arange(3)), t)
    compiled = core._controls._cache_size()
    outs = [core.lane_controls(scene, one.take(np.arange(n)), t) for n in (5, 17)]
    assert core._controls._cache_size() == compiled
    assert outs[1].shape[0] == 17 and np.array_equal(outs[1][:5], outs[0])
    assert np.array_equal(outs[1][0], outs[1][16])  # one gait, one set of controls


def test_every_backend_offers_the_written_interface(scene):
    """Each backend the package builds (those importable here) is an
    engine.core.Backend with a batching policy the batch runner knows, and
    a context manager that releases it: the native backend's thread pool is
    gone after the block."""
    from smarticle_mjx.engine import BACKENDS
    from smarticle_mjx.engine.core import BATCHING, Backend
    built = 0
    for name in BACKENDS:
        try:
            be = make_backend(name, scene)
        except (ValueError, ImportError, RuntimeError):  # an optional extra that is not installed, or no device
            continue
        with be as entered:
            assert entered is be and isinstance(be, Backend), name
            assert be.name == name and be.batching in BATCHING and be.scene is scene
        built += 1
    assert built >= 2  # native and mjx are always here
    with make_backend("native", scene, nthread=2) as native:
        assert native.pool is not None
    assert native.pool is None


def test_open_backend_builds_the_sensors_its_records_need_and_refuses_what_it_cannot_record(monkeypatch):
    """The touch record's sensors report the contact count and the smallest distance; the collision
    record adds force sensors; MJX's scene has none (it reads the contact list). A record a backend
    cannot make, or an unknown backend, is refused before any scene is compiled."""
    import mujoco
    from smarticle_mjx import engine
    from smarticle_mjx.engine import Scene, open_backend
    params = S.SceneParams()
    plain = mujoco.MjModel.from_xml_string(Scene.mjcf(params, 2))
    assert plain.nsensor == 1 and plain.sensor_dim[0] == 2  # found, dist
    with_coll = mujoco.MjModel.from_xml_string(Scene.mjcf(params, 2, collisions=True))
    assert with_coll.nsensor > 1
    assert mujoco.MjModel.from_xml_string(Scene.mjcf(params, 2, sensors="none")).nsensor == 0
    built = []
    monkeypatch.setattr(engine.Scene, "build", lambda *a, **k: built.append(a))
    with pytest.raises(ValueError, match="collision records .--collisions. run on the native and dart backends, not mjx"):
        open_backend("mjx", params, 2, collisions=True)
    with pytest.raises(ValueError, match="unknown backend 'bullet'"):
        open_backend("bullet", params, 2)
    assert built == []
    monkeypatch.undo()
    with open_backend("native", params, 2, collisions=True, nthread=1) as be:
        assert be.name == "native" and be.scene.collisions


def test_a_mujoco_reset_after_a_blow_up_is_flagged_not_taken_for_physics():
    """MuJoCo answers a NaN, Inf or huge acceleration by resetting the data to the model's rest state
    and going on with finite numbers, so the robots jump to the scene's placeholder poses. A violently
    unstable servo (stiff, undamped, unbounded, at a 2 ms step) makes it happen; the lane must carry
    NONFINITE, as a NaN would, instead of a finite jump that looks like motion."""
    import dataclasses
    from smarticle_mjx import presets
    from smarticle_mjx.engine.core import Status
    from smarticle_mjx.engine.simulate import simulate
    from smarticle_mjx.gait import GaitSpec
    from smarticle_mjx.scene import standard_poses
    p = presets.params()
    p = dataclasses.replace(p, timestep=2e-3, robot=dataclasses.replace(
        p.robot, servo_kp=5e4, servo_kv=0.0, servo_armature=0.0, servo_torque=1e4))
    r = simulate(p, standard_poses("pair", p.robot), GaitSpec(), 2)
    assert np.isfinite(r.poses).all()  # the reset leaves finite numbers behind
    assert r.status & Status.NONFINITE
    ok = simulate(presets.params(), standard_poses("pair", presets.params().robot), GaitSpec(), 2)
    assert ok.status == 0  # an ordinary run's clock always advances
