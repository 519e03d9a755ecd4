"""The DART twin's scene (smarticle_mjx/engine/dart.py) against closed-form physics and MuJoCo.

The paper's simulation ran on DART; these check that the twin built from the
same SceneParams obeys what any engine must: a robot left alone stays put, a
launched robot slides the Coulomb distance, the servo follows the gait to its
corners. The slide is checked in MuJoCo too, on the same robot.
"""

import math

import mujoco
import numpy as np
import pytest

from smarticle_mjx import presets
from smarticle_mjx import scene as S
from smarticle_mjx.engine import dart as twin
from smarticle_mjx.gait import GaitSpec

needs_dart = pytest.mark.skipif(not twin.available(), reason="dartpy is not installed (pip install -e '.[dart]')")

P = presets.params()  # the default robot
GAIT = GaitSpec(90.0)
A0 = GAIT.setpoints(0.0, P.robot.servo_speed)
G = 9.81


@needs_dart
def test_a_robot_at_rest_stays_at_rest():
    """Gravity, the plate and servos holding the arms, nothing else: after
    0.5 s the body has moved less than a nanometre and turned less than a
    microradian, and the arms stay where they were held."""
    sc = twin.DartScene(P, [(0.01, -0.02, 0.3, A0[0], A0[1])])
    start = sc.poses()
    for _ in range(5000):
        sc.hold()
        sc.step()
    end = sc.poses()
    assert np.linalg.norm(end[0, :2] - start[0, :2]) < 1e-9
    assert abs(end[0, 2] - start[0, 2]) < 1e-6
    np.testing.assert_allclose(end[0, 3:], start[0, 3:], atol=1e-6)


def _mujoco_slide(params, v: float) -> float:
    """Distance a robot launched along x at ``v`` slides in MuJoCo, servos holding its arms."""
    m = S.compile_model(S.build_mjcf(params, [(0, 0, 0, A0[0], A0[1])]))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    d.qvel[0] = v
    x0 = d.qpos[0]
    for _ in range(int(round(3 * v / (params.plate_friction * G) / m.opt.timestep))):  # 3x the stopping time
        mujoco.mj_step(m, d)
    assert abs(d.qvel[0]) < 1e-4
    return d.qpos[0] - x0


def _dart_slide(params, v: float) -> float:
    sc = twin.DartScene(params, [(0, 0, 0, A0[0], A0[1])])
    sc.set_body_velocity(0, v, 0.0)
    x0 = sc.poses()[0, 0]
    for _ in range(int(round(3 * v / (params.plate_friction * G) / sc.numerics.timestep))):
        sc.hold()
        sc.step()
    assert abs(sc.robots[0][0].getVelocities()[3]) < 1e-4
    return sc.poses()[0, 0] - x0


@needs_dart
@pytest.mark.parametrize("v", [0.2, 0.05])
def test_a_launched_robot_slides_the_coulomb_distance_in_both_engines(v):
    """A robot launched along the plate at v with its arms held decelerates
    at mu g and stops after v^2 / (2 mu g): 5.5 mm at 0.2 m/s, 0.34 mm at
    0.05 m/s on mu = 0.37. Both engines within 3 %, the same robot."""
    want = v ** 2 / (2 * P.plate_friction * G)
    for engine, got in (("mujoco", _mujoco_slide(P, v)), ("dart", _dart_slide(P, v))):
        assert abs(got - want) < 0.03 * want, (engine, got, want)


@needs_dart
def test_the_twin_follows_the_gait_to_its_corners():
    """DART's SERVO arm (a velocity constraint within the torque bound,
    commanded with the gait's rate and trimmed toward the setpoint) reaches
    each corner of the 90-degree square gait within 1 degree before the next
    edge starts, and an arm moves only on its own edges."""
    params = presets.params("dart")
    sc = twin.DartScene(params, [(0, 0, 0, A0[0], A0[1])])
    T = GAIT.period()
    angles = []

    def at_corner_ends(period, step, steps):
        q = next((q for q in range(4) if step == round((q + 1) * steps / 4) - 2), None)
        if q is not None:  # two steps before the next edge starts
            want = GAIT.setpoints(step * T / steps, params.robot.servo_speed)  # the command of this step
            got = sc.poses()[0, 3:]
            assert np.degrees(np.abs(got - want)).max() < 1.0, (q, np.degrees(got), np.degrees(want))
            angles.append(got)

    sc.run_gait(GAIT, 1, on_step=at_corner_ends)
    assert len(angles) == 4
    moved = np.abs(np.diff(np.array([A0, *angles]), axis=0)) > math.radians(45)
    assert (moved.sum(1) == 1).all(), moved  # one arm per edge


@needs_dart
def test_bad_numerics_are_refused_in_one_line():
    for numerics, msg in ((twin.DartNumerics(detector="havok"), "collision detector must be one of"),
                          (twin.DartNumerics(lcp="newton"), "LCP solver must be one of"),
                          (twin.DartNumerics(timestep=0.0), "time step must be positive")):
        with pytest.raises(ValueError, match=msg):
            twin.DartScene(P, [(0, 0, 0, A0[0], A0[1])], numerics)


@needs_dart
@pytest.mark.parametrize("detector", ["fcl", "ode", "bullet"])
def test_every_detector_holds_a_resting_robot_and_slides_it(detector):
    """The primitive-shape detectors (the twin's own numerics study compares
    them with DART's default FCL mesh) hold a robot at rest and slide a
    launched one the Coulomb distance within 3 %."""
    sc = twin.DartScene(P, [(0, 0, 0, A0[0], A0[1])], twin.DartNumerics(detector=detector))
    for _ in range(1000):
        sc.hold()
        sc.step()
    assert np.linalg.norm(sc.poses()[0, :2]) < 1e-8
    v = 0.2
    sc.set_body_velocity(0, v, 0.0)
    x0 = sc.poses()[0, 0]
    for _ in range(int(round(3 * v / (P.plate_friction * G) / sc.numerics.timestep))):
        sc.hold()
        sc.step()
    want = v ** 2 / (2 * P.plate_friction * G)
    assert abs(sc.poses()[0, 0] - x0 - want) < 0.03 * want


def _lanes(n=3, amplitude=45.0, seed=3):
    from smarticle_mjx import configs as C
    from smarticle_mjx.engine import Lanes
    gait = GaitSpec(amplitude)
    a0 = gait.setpoints(0.0, P.robot.servo_speed)
    return Lanes.from_gait(C.sample_valid_pairs(n, np.random.default_rng(seed), (0.8, 1.6), a0[0], a0[1]), gait)


@needs_dart
def test_the_dart_backend_gives_native_s_touch_labels_and_one_lane_alone_equals_it_in_a_batch():
    """The engine interface on DART: lanes in, per-period records out. Over
    one real 45-degree period, on starts that touch and one that stays apart,
    the bound/unbound labels are MuJoCo C's (the depths are not compared:
    MuJoCo's soft contacts sink ~0.6 mm, DART's LCP contacts micrometres).
    Each lane is its own world, so a lane run alone gives the same records
    bit for bit as in the batch."""
    from smarticle_mjx.engine import Scene, make_backend
    scene = Scene.build(P, 2)
    lanes = _lanes()
    be = twin.DartBackend(scene, twin.DartNumerics(detector="fcl"))
    _, rec, _ = be.advance(be.initial_state(lanes), lanes, 1)
    native = make_backend("native", scene, nthread=1)
    _, ref, _ = native.advance(native.initial_state(lanes), lanes, 1)
    native.close()
    assert rec.touched.any() and (~rec.touched).any()
    np.testing.assert_array_equal(rec.touched, ref.touched)
    assert (np.abs(rec.min_dist[rec.touched]) < 1e-4).all() and (rec.status == 0).all()
    one = lanes.take(np.array([1]))
    _, alone, _ = be.advance(be.initial_state(one), one, 1)
    assert np.array_equal(alone.poses[0], rec.poses[1]) and np.array_equal(alone.touched[0], rec.touched[1])


@needs_dart
def test_with_the_mesh_detector_touches_are_recorded_without_a_depth():
    """DART's default detector reports non-geometric depths (24 mm where the
    primitive ones give micrometres): the touch is kept, its depth is NaN,
    and no lane is flagged as penetrating because of it."""
    from smarticle_mjx.engine import Scene
    lanes = _lanes(2)
    be = twin.DartBackend(Scene.build(P, 2))
    _, rec, _ = be.advance(be.initial_state(lanes), lanes, 1)
    assert rec.touched.any()
    assert np.isnan(rec.min_dist[rec.touched]).all() and np.isinf(rec.min_dist[~rec.touched]).all()
    assert (rec.status == 0).all()


@needs_dart
def test_smx_scan_runs_on_the_dart_backend_and_the_store_says_so(tmp_path):
    """``smx scan --backend dart`` end to end: a small random scan at 45
    degrees writes a complete store whose configuration names the engine and
    its numerics (step, detector, LCP solver); its valid lanes ran and its
    invalid ones did not; touches were recorded."""
    import json

    import h5py
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    from smarticle_mjx.store import Store
    out = tmp_path / "dart.h5"
    r = CliRunner().invoke(app, ["scan", "--backend", "dart", "--n", "4", "--r-min", "0.8", "--r-max", "1.4",
                                 "--amplitude", "45", "--periods", "1", "--seed", "2", "--quiet", "--out", str(out)])
    assert r.exit_code == 0, r.output
    st = Store(out)
    scan = st.config["scan"]
    assert scan["backend"] == "dart" and scan["dart_numerics"] == [1e-4, "fcl-mesh", "dantzig"]
    d = st.run()
    assert d["valid"].any() and (d["periods_run"][d["valid"]] == 1).all() and (d["periods_run"][~d["valid"]] == 0).all()
    assert d["touched"][d["valid"]].any()
    with h5py.File(out) as f:
        assert json.loads(f.attrs["config"])["scan"]["backend"] == "dart"


def test_the_dart_backend_without_dartpy_is_one_line_exit_2(tmp_path, monkeypatch):
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    monkeypatch.setattr(twin, "available", lambda: False)
    r = CliRunner().invoke(app, ["scan", "--backend", "dart", "--n", "2", "--periods", "1", "--quiet",
                                 "--out", str(tmp_path / "x.h5")])
    assert r.exit_code == 2 and "pip install -e '.[dart]'" in r.output
    assert len(r.output.strip().splitlines()) == 1 and not list(tmp_path.iterdir())


def test_dart_numerics_belong_to_the_dart_backend():
    from smarticle_mjx.scan import ScanConfig
    with pytest.raises(ValueError, match="dart numerics are for --backend dart"):
        ScanConfig(n=2, dart_numerics=(1e-4, "fcl", "dantzig")).validate(P)
    assert "dart_numerics" not in ScanConfig(n=2).to_json()  # other backends' stores are unchanged


@needs_dart
@pytest.mark.skipif(not __import__("smarticle_mjx.executors", fromlist=["available"]).available(),
                    reason="Dask is not installed")
def test_a_dart_scan_on_dask_writes_the_local_store(tmp_path):
    """The Dask executor runs the twin unchanged: shards on a worker give
    the store the local executor gives (tests/storecmp.py)."""
    from storecmp import assert_same_store
    from smarticle_mjx.executors import DaskExecutor
    from smarticle_mjx.scan import ScanConfig, run_scan
    cfg = ScanConfig(n=4, r_range_W=(0.8, 1.4), amplitudes_deg=(45.0,), periods=1, seed=2, backend="dart",
                     batch_size=2)
    local = run_scan(cfg, tmp_path / "local.h5")
    dask = run_scan(cfg, tmp_path / "dask.h5", executor=DaskExecutor(workers=1, shard_size=2))
    assert_same_store(tmp_path / "local.h5", tmp_path / "dask.h5")
    # steps are DART's: a 0.8 s period is 8000 steps of 0.1 ms (1600 of the scene's 0.5 ms)
    valid = sum(r.valid for r in local.runs.values())
    assert local.steps == dask.steps == valid * 8000


def _head_on(v: float = 0.1):
    """Two robots of the default model 1.2 W apart along robot 1's body axis,
    anti-aligned, arms at the gait's first corner; the launch velocity of
    robot 1 toward robot 2 (m/s, world x, y)."""
    from smarticle_mjx import configs as C
    poses = C.pair_poses(np.array([1.2]), np.array([0.0]), np.array([np.pi]), A0[0], A0[1], P.robot)[0]
    d = poses[1, :2] - poses[0, :2]
    return poses, v * d / np.linalg.norm(d)


def _mujoco_free_collision(poses, launch, seconds=0.3):
    """Momentum before and after, and robot 2's speed after, in MuJoCo with
    gravity off and the robots lifted 2 cm off the plate."""
    m = S.compile_model(S.build_mjcf(P, poses))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    m.opt.gravity[:] = 0
    for i in range(2):
        d.qpos[m.jnt_qposadr[m.joint(f"r{i}_free").id] + 2] += 0.02
    d.qvel[m.jnt_dofadr[m.joint("r0_free").id]:][:2] = launch
    mujoco.mj_forward(m, d)
    roots = [m.body(f"r{i}").id for i in range(2)]

    def momentum():
        mujoco.mj_subtreeVel(m, d)
        return sum(m.body_subtreemass[b] * d.subtree_linvel[b] for b in roots)

    before = momentum()
    for _ in range(int(round(seconds / m.opt.timestep))):
        mujoco.mj_step(m, d)
    return before, momentum(), float(np.linalg.norm(d.subtree_linvel[roots[1]]))


@needs_dart
def test_momentum_is_conserved_when_two_free_robots_collide():
    """No plate, no gravity: robot 1 launched at 0.1 m/s hits robot 2 head on.
    Contact impulses are equal and opposite and the servos act inside each
    robot, so the robots' total linear momentum is the same before and after
    in both engines (to 1e-9 of its 3.5e-3 kg m/s), and robot 2 was hit
    (it moves at more than 0.02 m/s)."""
    poses, launch = _head_on()
    sc = twin.DartScene(P, poses, plate=False)
    sc.set_body_velocity(0, *launch)
    before = sc.momentum()
    for _ in range(3000):
        sc.hold()
        sc.step()
    hit = np.linalg.norm(sc.robots[1][0].getSkeleton().getCOMLinearVelocity())
    results = {"dart": (before, sc.momentum(), hit), "mujoco": _mujoco_free_collision(poses, launch)}
    for engine, (p0, p1, speed) in results.items():
        np.testing.assert_allclose(p0[:2], P.robot.mass * launch, rtol=1e-9, err_msg=engine)
        assert np.abs(np.asarray(p1) - np.asarray(p0)).max() < 1e-9, (engine, p0, p1)
        assert speed > 0.02, (engine, speed)


@needs_dart
def test_the_contact_forces_the_record_sums_are_each_robot_s_change_of_momentum():
    """No plate, no gravity: the only external force on a robot is the other
    robot's contact force, so the impulses ``robot_contacts`` reports (force
    on robot 1 times the step, normal and friction) must add up to robot 1's
    change of momentum, and their opposite to robot 2's. The launch is
    oblique (30 degrees off the line of centres), so friction acts too.
    Measured: they agree to 7e-6 of the impulse; a wrong sign, a missing
    friction part or a missing factor of the step would miss by order 1."""
    poses, launch = _head_on()
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    launch = np.array([[c, -s], [s, c]]) @ launch
    sc = twin.DartScene(P, poses, plate=False)
    sc.set_body_velocity(0, *launch)
    sk = [r[0].getSkeleton() for r in sc.robots]
    p0 = [k.getMass() * np.asarray(k.getCOMLinearVelocity())[:2] for k in sk]
    dt = sc.numerics.timestep
    imp, kinds = np.zeros(2), set()
    for _ in range(3000):
        sc.hold()
        sc.step()
        for i, j, kind, fx, fy, _ in sc.robot_contacts():
            assert (i, j) == (0, 1)
            imp += dt * np.array([fx, fy])
            kinds.add(kind)
    p1 = [k.getMass() * np.asarray(k.getCOMLinearVelocity())[:2] for k in sk]
    assert np.linalg.norm(imp) > 1e-3, "the robots must collide"
    u, w = launch / np.linalg.norm(launch), imp / np.linalg.norm(imp)
    tangent = abs(u[0] * w[1] - u[1] * w[0])
    np.testing.assert_allclose(p1[0] - p0[0], imp, atol=1e-4 * np.linalg.norm(imp))
    np.testing.assert_allclose(p1[1] - p0[1], -imp, atol=1e-4 * np.linalg.norm(imp))
    assert tangent > 0.01, "the impulse is not along the launch: friction or an oblique normal acted"


@needs_dart
def test_the_dart_collision_record_is_the_native_record_s_layout_and_its_touches(tmp_path):
    """``smx scan --backend dart --collisions`` stores the collision record:
    a lane-period has steps in contact exactly when it touched, and the
    record's impulse along r of a period is the sum over its kinds and bins.
    Contacts between robots push them apart: over the first period of every
    touching start, the net impulse along r on robot 1 is negative
    (repulsive), in DART as in MuJoCo C on the same starts."""
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    from smarticle_mjx.reduce import collisions as RC
    from smarticle_mjx.store import Store
    runs = {}
    for backend in ("dart", "native"):
        out = tmp_path / f"{backend}.h5"
        r = CliRunner().invoke(app, ["scan", "--backend", backend, "--n", "4", "--r-min", "0.8", "--r-max", "1.4",
                                     "--amplitude", "45", "--periods", "1", "--seed", "2", "--collisions",
                                     "--collision-bins", "4", "--quiet", "--out", str(out)])
        assert r.exit_code == 0, r.output
        runs[backend] = Store(out).run(fields=("valid", "touched", "coll_steps", "coll_impulse", "coll_impulse_r"))
    d = runs["dart"]
    v = d["valid"]
    assert d["coll_steps"].shape[1:] == (1, 1, 9, 4) and d["coll_impulse"].shape[1:] == (1, 1, 9, 4, 2)
    np.testing.assert_array_equal(d["coll_steps"][v].sum((-1, -2)) > 0, d["touched"][v])
    tot = {k: RC.period_totals({f: runs[k][f"coll_{f}"][v] for f in ("steps", "impulse", "impulse_r")})
           for k in runs}
    touched = d["touched"][v][:, 0, 0]
    assert touched.sum() >= 2
    for k, t in tot.items():
        assert (t.impulse_r[touched, 0, 0] < 0).all(), (k, t.impulse_r[:, 0, 0])


@needs_dart
def test_the_same_pd_servo_law_moves_the_arms_alike_in_dart_and_mujoco():
    """The pd servo applies the MJCF's own actuator law (PD + feed-forward
    through the 10 ms lag filter, clipped at the stall torque) as DART joint
    forces. Without armature, which DART cannot model, and at the same
    0.1 ms step, a lone robot's arm angles over a 90-degree period follow
    MuJoCo C's within 0.1 degree (measured: 0.016), and both reach the
    corners. A model with armature is refused."""
    import dataclasses
    from smarticle_mjx.engine.simulate import simulate
    p = P.replace(robot=dataclasses.replace(P.robot, servo_armature=0.0), timestep=1e-4)
    assert p.robot.servo_timeconst > 0, "the default servo has a lag; the filter is part of what is compared"
    sc = twin.DartScene(p, [(0, 0, 0, A0[0], A0[1])], twin.DartNumerics(servo="pd"))
    ang = []
    sc.run_gait(GAIT, 1, on_step=lambda k, s, n: ang.append(sc.poses()[0, 3:5].copy()) if s % 10 == 9 else None)
    mj = simulate(p, [(0, 0, 0, A0[0], A0[1])], GAIT, 1, track_stride=10).track[:, 0, 3:5]
    ang = np.array(ang)
    assert ang.shape == mj.shape
    assert np.degrees(np.abs(ang - mj).max()) < 0.1
    assert np.degrees(np.abs(ang).max()) > 89.5
    with pytest.raises(ValueError, match="no joint armature"):
        twin.DartScene(P, [(0, 0, 0, A0[0], A0[1])], twin.DartNumerics(servo="pd"))
    with pytest.raises(ValueError, match="servo must be one of"):
        twin.DartNumerics(servo="magic").validate()
    assert twin.DartNumerics(servo="pd").record() == [1e-4, "fcl-mesh", "dantzig", "pd"]
    assert twin.DartNumerics().record() == [1e-4, "fcl-mesh", "dantzig"]  # stores made before the option


@needs_dart
def test_smx_simulate_writes_a_dart_track_at_dart_s_step(tmp_path):
    """``smx simulate --backend dart`` writes the measured-data track format:
    frames every 100 steps of DART's 0.1 ms (100 frames per s in the
    sidecar), the track's last frame is the period-end pose the per-period
    record holds, and its arms reach the gait's 45-degree corners."""
    import json
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    from smarticle_mjx.engine.simulate import simulate
    out = tmp_path / "t.csv"
    r = CliRunner().invoke(app, ["simulate", "--scene", "single", "--backend", "dart", "--periods", "1",
                                 "--amplitude", "45", "--track-stride", "100", "--out", str(out)])
    assert r.exit_code == 0, r.output
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["frame_rate_hz"] == pytest.approx(100.0)  # 100 steps of 0.1 ms a frame (native: of 0.5 ms)
    g = GaitSpec(45.0)
    a0 = g.setpoints(0.0, P.robot.servo_speed)
    res = simulate(P, [(0, 0, 0, a0[0], a0[1])], g, 1, track_stride=100, backend="dart")
    assert len(res.track_t) == 80 and np.allclose(np.diff(res.track_t), 0.01)
    np.testing.assert_allclose(res.track[-1], res.poses[-1], atol=1e-12)
    assert np.degrees(np.abs(res.track[:, 0, 3:5]).max()) > 44.5
    bad = CliRunner().invoke(app, ["simulate", "--backend", "mjx", "--out", str(tmp_path / "m.csv")])
    assert bad.exit_code == 2 and "run on the native and dart backends, not" in bad.output


@needs_dart
def test_smx_relax_runs_on_the_dart_backend_and_the_store_records_its_numerics(tmp_path):
    """The relaxation experiment on the twin: three robots packed in phase
    touch in their first period, and the store names the engine, its
    numerics and a step count at DART's step. Numerics on another backend
    are refused in one line."""
    import json

    import h5py
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    from smarticle_mjx.relax import RelaxConfig
    from smarticle_mjx.store import Store
    out = tmp_path / "r.h5"
    r = CliRunner().invoke(app, ["relax", "--backend", "dart", "--robots", "3", "--trials", "1", "--periods", "1",
                                 "--amplitude", "45", "--quiet", "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert "8,000 steps" in r.output  # one 0.8 s period at DART's 0.1 ms step
    with h5py.File(out) as f:
        cfg = json.loads(f.attrs["config"])["relax"]
    assert cfg["backend"] == "dart" and cfg["dart_numerics"] == [1e-4, "fcl-mesh", "dantzig"]
    d = Store(out).run("trials", fields=("periods_run", "touched"))
    assert d["periods_run"][0] == 1 and d["touched"][0, 0].any()
    with pytest.raises(ValueError, match="dart numerics are for --backend dart"):
        RelaxConfig(dart_numerics=(1e-4, "fcl", "dantzig")).validate(P)
    assert "dart_numerics" not in RelaxConfig().to_json()  # native relaxation stores are unchanged
