"""Real robots' imperfections and the scene features behind them: backlash,
per-arm servo speeds, centre-of-mass offsets, clock drift, phase jitter, and
the actuator-level torque clip."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from smarticle_mjx import gait as G
from smarticle_mjx import imperfections as I
from smarticle_mjx import presets
from smarticle_mjx.cli import app
from smarticle_mjx.engine import Lanes, Scene
from smarticle_mjx.engine.core import lane_controls
from smarticle_mjx.engine.native import NativeBackend
from smarticle_mjx.replay import resimulate_lane
from smarticle_mjx.scan import ScanConfig, run_scan
from smarticle_mjx.scene import RobotQuirk, compile_model, build_mjcf
from smarticle_mjx.store import Store

runner = CliRunner()


def _lone(params, periods_steps: int, gait=G.GaitSpec(90.0), arm_speed=None):
    scene = Scene.build(params, 1)
    a0 = gait.setpoints(0.0, params.robot.servo_speed)
    lanes = Lanes.from_gait(np.array([[[0.0, 0.0, 0.0, a0[0], a0[1]]]]), gait)
    if arm_speed is not None:
        lanes = dataclasses.replace(lanes, arm_speed=np.asarray(arm_speed, float).reshape(1, 1, 2))
    be = NativeBackend(scene, nthread=1)
    try:
        return scene, be.step_qpos(lanes, periods_steps)[0]
    finally:
        be.close()


def test_backlash_lets_each_arm_swing_to_the_stops_of_its_play_and_no_further():
    """A servo that reverses drags its arm through the gear's free play: the
    free-play hinge travels to one stop and then the other (±1.5°), and the
    stops, rigid gear teeth, hold it there (within 0.2° past them)."""
    p = presets.params()
    p = p.replace(robot=dataclasses.replace(p.robot, backlash_deg=1.5))
    steps = int(round(1.6 / p.timestep))
    scene, q = _lone(p, steps)
    lay = scene.layout
    assert lay.play_qpos is not None and (lay.play_qpos >= 0).all()
    for k in (0, 1):
        play = np.degrees(q[:, lay.play_qpos[0, k]])
        assert play.max() > 1.2 and play.min() < -1.2, (k, play.min(), play.max())
        assert np.abs(play).max() < 1.5 + 0.2, (k, np.abs(play).max())
    # the pose reports the arm itself: driven hinge plus play
    poses = scene.poses_from_qpos(q)
    np.testing.assert_allclose(poses[:, 0, 3], q[:, lay.arm_qpos[0, 0]] + q[:, lay.play_qpos[0, 0]])


def test_a_speed_ratio_changes_one_arm_s_timing_only():
    """A robot whose arm-2 servo runs at 0.92 of the speed: arm 1's setpoints
    are untouched; arm 2 still travels 2a per move, but each move lasts 1/0.92
    as long; the engines' controls carry the same."""
    a, T, v = math.pi / 2, 1.6, 8.727
    t = np.arange(0, T, 1e-4)
    ideal = np.asarray(G.setpoints(t, a, T, v))
    slow = np.asarray(G.setpoints(t, a, T, v, ratio2=0.92))
    np.testing.assert_array_equal(ideal[:, 0], slow[:, 0])
    for sp, want in ((ideal[:, 1], 2 * a / v), (slow[:, 1], 2 * a / (0.92 * v))):
        moving = np.abs(np.diff(sp)) > 0
        # arm 2 moves in two quarters (ccw: odd ones); its moving time per move
        assert moving.sum() * 1e-4 / 2 == pytest.approx(want, rel=2e-3)
        assert sp.max() == pytest.approx(a) and sp.min() == pytest.approx(-a)
    scene = Scene.build(presets.params(), 1)
    lanes = Lanes.from_gait(np.zeros((1, 1, 5)), G.GaitSpec(90.0))
    c0 = lane_controls(scene, lanes, t[::10])
    c1 = lane_controls(scene, dataclasses.replace(lanes, arm_speed=np.array([[[1.0, 0.92]]])), t[::10])
    np.testing.assert_allclose(c0[..., [0, 2]], c1[..., [0, 2]], atol=2e-6)  # float32 gait
    assert np.abs(c0[..., 1] - c1[..., 1]).max() > 0.1
    with pytest.raises(ValueError, match="too slow for its gait"):
        lane_controls(scene, dataclasses.replace(lanes, arm_speed=np.array([[[1.0, 0.8]]])), t[::10])


def test_a_centre_of_mass_offset_moves_the_mass_not_the_shape():
    """The explicit inertial puts the body's centre of mass at the offset with
    the body's mass and a box's inertia; the collision box stays centred."""
    p = presets.params().replace(quirks=(RobotQuirk(com_offset=(0.002, -0.001)),))
    ideal = compile_model(build_mjcf(presets.params(), [(0, 0, 0, 0, 0), (0.3, 0, 0, 0, 0)]))
    m = compile_model(build_mjcf(p, [(0, 0, 0, 0, 0), (0.3, 0, 0, 0, 0)]))
    b0, b1 = (mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"r{i}") for i in (0, 1))
    np.testing.assert_allclose(m.body_ipos[b0], [0.002, -0.001, 0.0], atol=1e-12)
    np.testing.assert_allclose(m.body_ipos[b1], ideal.body_ipos[b1], atol=1e-12)
    assert m.body_mass[b0] == pytest.approx(ideal.body_mass[b0])
    np.testing.assert_allclose(np.sort(m.body_inertia[b0]), np.sort(ideal.body_inertia[b0]), rtol=1e-6)
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "r0_body")
    np.testing.assert_allclose(m.geom_pos[g], ideal.geom_pos[g])


def test_a_clipped_servo_accelerates_its_arm_at_the_stall_torque_with_either_clip():
    """A stiff velocity loop (kv dt / I ~ 29) told to reverse both arms
    saturates at the stall torque. Each arm's one-step change of speed must be
    what that torque gives (the forward dynamics' acceleration): were the
    implicit step to linearise the clipped loop's damping, the arms would move
    as if ~30 times heavier. MuJoCo 4 keeps the clipped force constant whether
    each actuator's own range clips (``servo_clip="actuator"``) or only the
    joint's total (``"joint"``)."""
    for clip in ("actuator", "joint"):
        p = presets.params()
        p = p.replace(robot=dataclasses.replace(p.robot, servo_kv=0.156, servo_kp=0.0975, servo_armature=0.0,
                                                servo_timeconst=0.0, servo_clip=clip))
        m = Scene.build(p, 1).model
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, 0)
        d.ctrl[:] = [0.0, 0.0, 8.727, 8.727]  # both arms: full speed from rest
        mujoco.mj_forward(m, d)
        adr = [m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"r0_a{k}")] for k in (1, 2)]
        assert np.abs(d.qfrc_actuator[adr]) == pytest.approx([0.078, 0.078])
        forward = d.qacc[adr].copy()
        mujoco.mj_step(m, d)
        np.testing.assert_allclose(d.qvel[adr] / m.opt.timestep, forward, rtol=0.02)
        assert forward.min() > 0.5 * 0.078 / (p.robot.arm_mass * p.robot.arm_length ** 2 / 3)


def test_draws_depend_on_seed_and_robot_only_and_priors_hold():
    a, b = I.draw("lab", 2, seed=3), I.draw("lab", 7, seed=3)
    np.testing.assert_array_equal(a.arm_speed, b.arm_speed[:2])
    assert a.quirks == b.quirks[:2]
    c = I.draw("lab", 2, seed=4)
    assert not np.array_equal(a.arm_speed, c.arm_speed)
    big = I.draw("lab", 400, seed=0)
    assert (big.arm_speed >= I.MIN_SPEED_RATIO).all() and (big.arm_speed <= 2 - I.MIN_SPEED_RATIO).all()
    assert np.std(big.arm_speed) == pytest.approx(0.05, rel=0.15)
    assert (np.abs(big.clock - 1) <= 5e-3).all()
    plays = np.array([q.backlash_deg for q in big.quirks])
    assert plays.min() >= 1.0 and plays.max() <= 2.0
    none = I.draw("none", 2, seed=3)
    assert none.set.ideal and none.scene(presets.params()) == presets.params()
    # single-effect sets switch on one thing only
    assert I.draw("backlash", 2, 3).arm_speed.tolist() == [[1, 1], [1, 1]]
    assert I.draw("servo-speed", 2, 3).quirks[0].backlash_deg is None


def test_imperfections_round_trip_through_a_store_and_reproduce_from_the_seed(tmp_path):
    """The store records the set, its seed and every value drawn; drawing
    again from them gives the same robots, and a lane simulated again from
    the store (speeds, clocks, jitter, backlash, centres of mass) lands
    where the scan put it."""
    cfg = ScanConfig(configs="polar", positions=4, orientations=1, periods=2, imperfections="lab", seed=5,
                     batch_size=4)
    out = tmp_path / "s.h5"
    run_scan(cfg, out)
    st = Store(out)
    rec = st.config["imperfections"]
    assert rec["name"] == "lab" and rec["seed"] == 5
    again = I.from_json(rec)
    assert again.to_json() == rec == I.draw("lab", 2, 5).to_json()
    assert [q["backlash_deg"] for q in st.config["scene"]["quirks"]] == rec["backlash_deg"]
    rows = st.run(st.runs[0], fields=("valid", "poses"))
    lane = int(np.flatnonzero(rows["valid"])[0])
    _, _, res, params, _, _ = resimulate_lane(out, None, lane)
    assert params.quirks == again.quirks
    np.testing.assert_allclose(res.poses[1:], rows["poses"][lane], atol=1e-5)
    # and the imperfections matter: the ideal robots end elsewhere
    ideal = tmp_path / "i.h5"
    run_scan(dataclasses.replace(cfg, imperfections="none"), ideal)
    p_ideal = Store(ideal).run(st.runs[0], fields=("poses",))["poses"][lane]
    assert np.abs(p_ideal[-1, :, :2] - rows["poses"][lane][-1, :, :2]).max() > 1e-4
    assert "imperfections" not in Store(ideal).config


@pytest.mark.parametrize("command", [
    ["scan", "--configs", "polar", "--positions", "2", "--periods", "1"],
    ["sweep-amplitude", "--amplitudes", "90", "--periods", "1"],
    ["relax", "--trials", "1", "--periods", "1"],
])
def test_unknown_imperfections_are_one_line_exit_2_and_create_nothing(tmp_path, command):
    r = runner.invoke(app, [str(c) for c in [*command, "--out", tmp_path / "x.h5", "--imperfections", "nope",
                                             "--quiet"]])
    assert r.exit_code == 2, r.output
    assert "unknown imperfections 'nope'" in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert list(tmp_path.iterdir()) == []


def test_models_list_names_the_imperfection_sets_and_their_sources():
    r = runner.invoke(app, ["models", "--list"])
    assert r.exit_code == 0
    for name in I.SETS:
        assert f"\n{name}: " in r.output
    assert "resonator" in r.output and "Backlash" in r.output


def test_a_backend_that_cannot_run_the_imperfections_refuses_them_before_any_store_exists(tmp_path):
    """MJX runs every arm at the model's servo speed: a scan asking it for per-arm speeds is
    one line, exit 2, and creates nothing. The DART twin builds ideal rigid arms: a model
    with backlash or per-robot quirks is refused by the same check its scenes make."""
    r = runner.invoke(app, ["scan", "--configs", "polar", "--positions", "2", "--periods", "1", "--backend", "mjx",
                            "--imperfections", "servo-speed", "--out", str(tmp_path / "x.h5"), "--quiet"])
    assert r.exit_code == 2, r.output
    assert "arms with their own servo speeds (imperfections) run on the native, warp and dart backends, not mjx" in r.output
    assert len(r.output.strip().splitlines()) == 1 and list(tmp_path.iterdir()) == []
    from smarticle_mjx.engine.dart import DartNumerics, check_model
    check_model(presets.params(), DartNumerics())  # the ideal default builds
    for params in (presets.params("lab-hobby"), I.draw("com-offset", 2, 0).scene(presets.params())):
        with pytest.raises(ValueError, match="gear backlash or centre-of-mass offsets run on the native, mjx and warp "
                                             "backends, not dart"):
            check_model(params, DartNumerics())
    with pytest.raises(ValueError, match="own gait periods in one lane .clock drift. run on the native and mjx "
                                         "backends, not dart"):
        I.get("clock-drift").check_backend("dart")


def test_clock_drift_accumulates_across_chunks():
    """A robot whose clock runs fast keeps gaining phase however the run is cut into chunks: the
    per-period records of a 40-period run are the same in chunks of 5 periods as in one chunk, and the
    fast robot's arm, back at its corner every period at first, has left it by period 40
    (0.26 % fast: a tenth of a period ahead, well into its next move)."""
    from smarticle_mjx import imperfections, presets
    from smarticle_mjx.engine import Lanes, open_backend
    from smarticle_mjx.engine.batch import RetireRule, run_lanes
    from smarticle_mjx.gait import GaitSpec
    params, g = presets.params(), GaitSpec()
    draw = imperfections.draw("clock-drift", 2, 0)
    poses = np.zeros((1, 2, 5))
    poses[0, 1, 0] = 0.5  # 10 W apart: never touching
    poses[..., 3:] = g.setpoints(0.0, params.robot.servo_speed)[:2]
    lanes = draw.lanes(Lanes(poses, np.full(1, g.amplitude), np.full(1, g.chirality_sign, np.int32),
                             np.full(1, g.kind_code, np.int32), np.zeros((1, 2)), g.period()), [0])
    assert not np.allclose(lanes.robot_period, g.period())
    out = {}
    with open_backend("native", draw.scene(params), 2) as be:
        for chunk in (5, 40):
            run_lanes(be, lanes, 40, batch_size=1, chunk_periods=chunk, rule=RetireRule(quiet_periods=0),
                      on_lanes=lambda r, c=chunk: out.setdefault(c, r.poses[0]))
    np.testing.assert_allclose(out[5], out[40], rtol=0, atol=1e-9)
    arms = np.degrees(out[40][:, :, 3])  # [K, N] first arm of each robot at every period's end
    drifting = int(np.argmax(np.abs(lanes.robot_period[0] - g.period())))
    assert abs(arms[0, drifting] - arms[-1, drifting]) > 20


def test_per_cycle_retrigger_draws_fresh_delays_and_survives_chunking(tmp_path):
    """A robot re-started every cycle with a fresh delay (the lab firmware's trigger) has, at the start
    of cycle k, its phase offset plus a delay drawn from (seed, key, k): the same cycle gives the same
    delays, other cycles other ones, s.d. as asked; a relaxation's records do not depend on how the run
    is cut into chunks; and a retriggered relaxation trial replays exactly from its store."""
    from smarticle_mjx.engine import Lanes
    from smarticle_mjx.replay import resimulate_trial
    from smarticle_mjx.store import read_relax
    b, n, sd = 2, 400, 0.05
    lanes = Lanes(np.zeros((b, n, 5)), np.full(b, 1.0), np.ones(b, np.int32), np.zeros(b, np.int32),
                  np.full((b, n), 0.25), 1.6, retrigger=np.array([[sd, 0, 7], [sd, 0, 8]]))
    k3 = lanes.at_time(3 * 1.6).phase - 0.25
    assert np.array_equal(k3, lanes.at_time(3 * 1.6).phase - 0.25)
    assert not np.allclose(k3, lanes.at_time(4 * 1.6).phase - 0.25)
    assert not np.allclose(k3[0], k3[1])  # lanes (trials) draw their own delays
    d = np.mod(k3 + 0.5, 1.0) - 0.5
    assert d.std() == pytest.approx(sd, rel=0.15) and abs(d.mean()) < 4 * sd / np.sqrt(n)
    # lane 1 at cycle 4 while lane 0 is at cycle 3: per-lane times
    both = lanes.at_time(np.array([3 * 1.6, 4 * 1.6])).phase
    assert np.allclose(both[0], lanes.at_time(3 * 1.6).phase[0]) and np.allclose(both[1], lanes.at_time(4 * 1.6).phase[1])
    run = CliRunner()
    stores = {}
    for chunk in (2, 8):
        from smarticle_mjx.relax import RelaxConfig, run_relax
        out = tmp_path / f"r{chunk}.h5"
        run_relax(RelaxConfig(n_robots=3, trials=1, periods=8, retrigger_sd=0.03, chunk_periods=chunk,
                              quiet_periods=0), out)
        stores[chunk] = read_relax(out)
    assert np.array_equal(stores[2].poses, stores[8].poses)
    plain = tmp_path / "plain.h5"
    assert run.invoke(app, ["relax", "--robots", "3", "--trials", "1", "--periods", "8", "--quiet-periods", "0",
                            "--out", str(plain), "--quiet"]).exit_code == 0
    assert not np.array_equal(read_relax(plain).poses, stores[8].poses)  # the retrigger acts
    t, track, res, params, gait, rows = resimulate_trial(tmp_path / "r2.h5", 0, frame_interval=0.2)
    assert np.array_equal(res.poses[1:].astype(np.float32), rows["poses"])


def test_lab_resync_is_the_lab_robots_without_drifting_clocks():
    """The firmware's per-cycle re-synchronisation as a set: the same robots (servo speeds, gear play,
    centres of mass) and the same per-trial start offsets as `lab` for a seed, every clock at the nominal
    period, so a lab-resync run pairs with its lab run robot by robot and trial by trial."""
    lab, resync = I.draw("lab", 7, 3), I.draw("lab-resync", 7, 3)
    np.testing.assert_array_equal(resync.arm_speed, lab.arm_speed)
    assert resync.quirks == lab.quirks and any(q.backlash_deg for q in lab.quirks)
    assert (resync.clock == 1.0).all() and not (lab.clock == 1.0).all()
    rows = np.arange(4)
    np.testing.assert_array_equal(resync.lane_phase(rows), lab.lane_phase(rows))
    assert np.std(lab.lane_phase(rows)) > 0.005


def _pair_of(pool: I.Draw, k: int) -> I.Draw:
    """Robots 2k and 2k + 1 of ``pool``, sliced here rather than by ``Draw.pair``."""
    return dataclasses.replace(pool, arm_speed=pool.arm_speed[2 * k:2 * k + 2], clock=pool.clock[2 * k:2 * k + 2],
                               quirks=pool.quirks[2 * k:2 * k + 2])


def test_a_scan_of_several_robot_pairs_runs_each_lane_on_its_own_pair(tmp_path):
    """A scan that draws K pairs of robots runs lane i on robots 2k, 2k + 1 (k = i mod K) of the pool
    drawn from its robot seed: each lane, simulated alone on those two robots (their gear play and
    centres of mass in the scene, their servo speeds, clocks and start offsets in the gait), ends where the
    scan put it, and on the other pair it ends elsewhere (so the test can tell the pairs apart)."""
    from smarticle_mjx.engine.simulate import simulate
    from smarticle_mjx.scan import RunInputs
    cfg = ScanConfig(configs="polar", positions=6, orientations=1, periods=2, imperfections="lab", seed=5,
                     robot_draws=2, robot_seed=11, batch_size=8)
    out = tmp_path / "s.h5"
    run_scan(cfg, out)
    st = Store(out)
    rec = st.config["imperfections"]
    pool = I.draw("lab", 4, 11)
    assert rec["seed"] == 11 and rec["pairs"] == 2 and rec["clock"] == pool.clock.tolist()
    assert st.config["scan"]["robot_draws"] == 2 and st.config["scan"]["robot_seed"] == 11
    rows = st.run(st.runs[0], fields=("valid", "poses"))
    base = cfg.scene_params()
    inputs = RunInputs.of(cfg, base, 90.0)
    lanes = np.flatnonzero(rows["valid"])
    assert {int(x) % 2 for x in lanes} == {0, 1}
    for lane in lanes[:4]:
        k = int(lane) % 2
        own, other = _pair_of(pool, k), _pair_of(pool, 1 - k)
        res = simulate(own.scene(base), inputs.poses[lane], inputs.gait, 2, imperfections=own, row=int(lane))
        np.testing.assert_allclose(res.poses[1:], rows["poses"][lane], atol=1e-5)
        res = simulate(other.scene(base), inputs.poses[lane], inputs.gait, 2, imperfections=other, row=int(lane))
        assert np.abs(res.poses[-1, :, :2] - rows["poses"][lane][-1, :, :2]).max() > 1e-4
        # and the lane's replay (smx movie, smx replay) finds the same pair
        _, _, rep, params, _, _ = resimulate_lane(out, None, int(lane))
        assert params.quirks == own.quirks
        np.testing.assert_allclose(rep.poses[1:], rows["poses"][lane], atol=1e-5)


def test_one_robot_draw_is_the_pair_scans_always_ran_and_two_chiralities_share_a_pool():
    """K = 1 is robots 0 and 1 of the scan's seed, as before robot draws existed (stores unchanged: the
    configuration leaves the new keys out); studies with the same robot seed and K run the same robots
    whatever their own seeds and chiralities; ideal robots record no draws."""
    one = ScanConfig(imperfections="lab", seed=5)
    assert one.robots().to_json() == I.draw("lab", 2, 5).to_json()
    assert not {"robot_draws", "robot_seed", "lane_draws"} & set(one.to_json())
    ccw = ScanConfig(imperfections="lab", seed=0, robot_draws=10, robot_seed=0)
    cw = ScanConfig(imperfections="lab", seed=3, robot_draws=10, robot_seed=0, chirality="cw")
    assert ccw.robot_pool().to_json() == cw.robot_pool().to_json()
    assert cw.robot_pool().to_json() != ScanConfig(imperfections="lab", seed=3, robot_draws=10).robot_pool().to_json()
    assert ccw.lane_draw(np.arange(25)).tolist() == [i % 10 for i in range(25)]
    assert set(ScanConfig(robot_draws=10, robot_seed=4).to_json()) == set(ScanConfig().to_json())


def test_lane_draws_are_checked_and_survive_the_store_record():
    """Explicit per-lane pairs (pairs started as another study's gliders, on the robots that made them):
    one per configuration, each naming a drawn pair; read back from the stored configuration unchanged."""
    from smarticle_mjx.specs import config_from_json
    init = ((1.3, 0.5, 3.1), (1.4, 4.0, 0.1), (1.2, 2.0, 3.0))
    cfg = ScanConfig(configs="explicit", initial=init, imperfections="lab", robot_draws=4, lane_draws=(3, 0, 3))
    cfg.validate(cfg.scene_params())
    assert cfg.lane_draw([0, 1, 2]).tolist() == [3, 0, 3]
    assert config_from_json(json_round(cfg.to_json())) == cfg
    for bad, msg in ((dict(lane_draws=(3, 0)), "one robot pair per explicit configuration"),
                     (dict(lane_draws=(4, 0, 1)), "lane draws must lie in 0 .. 3"),
                     (dict(robot_draws=0, lane_draws=None), "robot draws must be >= 1")):
        with pytest.raises(ValueError, match=msg):
            c = dataclasses.replace(cfg, **bad)
            c.validate(c.scene_params())
    with pytest.raises(ValueError, match="one robot pair per explicit configuration"):
        c = ScanConfig(n=3, imperfections="lab", robot_draws=4, lane_draws=(0, 1, 2))
        c.validate(c.scene_params())


def json_round(d):
    import json
    return json.loads(json.dumps(d))


@pytest.mark.parametrize("option,msg", [(["--robot-draws", "0"], "robot draws must be >= 1"),
                                        (["--robot-seed", "-1"], "robot seed must be >= 0")])
def test_a_bad_robot_draw_is_one_line_exit_2_and_writes_nothing(tmp_path, option, msg):
    r = runner.invoke(app, ["scan", "--configs", "polar", "--positions", "2", "--periods", "1", "--imperfections",
                            "lab", *option, "--out", str(tmp_path / "x.h5"), "--quiet"])
    assert r.exit_code == 2, r.output
    assert msg in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert list(tmp_path.iterdir()) == []


def test_pairs_started_from_another_studys_gliders_keep_the_robots_that_made_them(tmp_path):
    """A started-bound study (descent, diagonal) whose source scan ran several robot pairs starts each
    glider on the pair of the lane it came from: the stage's lane draws are the source lanes' pairs, from
    the source's pool; with one pair, or ideal robots, nothing changes."""
    from smarticle_mjx.studies import _source_robots
    src = ScanConfig(configs="polar", positions=5, orientations=1, periods=1, imperfections="lab", seed=2,
                     robot_draws=3, batch_size=8)
    out = tmp_path / "src.h5"
    run_scan(src, out)
    got = _source_robots(Store(out), np.array([4, 0, 2]), "lab")
    assert got == {"robot_draws": 3, "robot_seed": 2, "lane_draws": (1, 0, 2)}
    stage = dataclasses.replace(ScanConfig(configs="explicit", initial=((1.3, 0.1, 3.0),) * 3, imperfections="lab"),
                                **got)
    assert stage.robot_pool().to_json() == src.robot_pool().to_json()
    assert stage.robots(int(stage.lane_draw([0])[0])).to_json() == src.robots(1).to_json()
    assert _source_robots(Store(out), np.array([4, 0]), "none") == {}
    one = tmp_path / "one.h5"
    run_scan(dataclasses.replace(src, robot_draws=1), one)
    assert _source_robots(Store(one), np.array([4, 0]), "lab") == {}


def test_ideal_robots_run_every_lane_together_whatever_the_draws():
    """Ideal robots are one machine: a study file's robot draws change neither their lanes' grouping nor
    their stores."""
    cfg = ScanConfig(robot_draws=10, robot_seed=0, seed=3)
    assert cfg.lane_draw(np.arange(30)).tolist() == [0] * 30
    assert cfg.to_json() == ScanConfig(seed=3).to_json()


def test_lasting_offsets_set_in_at_their_onset_cycle_and_stay(tmp_path):
    """Lasting per-robot timing offsets that set in after the start: every robot runs in phase until the
    onset cycle, then each keeps one offset (drawn once per robot and trial, s.d. as asked) in every later
    cycle. Physical fact: a lone robot with such a phase offset d has its arms, from the onset on, where the
    robot without it has them d periods later (checked against the plain run, sampled at full rate);
    a relaxation with them replays exactly from its store, and they exclude a per-cycle re-trigger."""
    from smarticle_mjx.engine import Lanes
    from smarticle_mjx.engine.simulate import simulate
    from smarticle_mjx.gait import GaitSpec
    from smarticle_mjx.presets import DEFAULT, params as preset_params
    from smarticle_mjx.relax import RelaxConfig, run_relax
    from smarticle_mjx.replay import resimulate_trial
    b, n, sd = 2, 400, 0.05
    lanes = Lanes(np.zeros((b, n, 5)), np.full(b, 1.0), np.ones(b, np.int32), np.zeros(b, np.int32),
                  np.zeros((b, n)), 1.6, retrigger=np.array([[sd, 0, 7, 2], [sd, 0, 8, 2]], float))
    assert not lanes.at_time(1.6).phase.any()  # before the onset: in phase
    k2, k5 = (np.mod(lanes.at_time(k * 1.6).phase + 0.5, 1.0) - 0.5 for k in (2, 5))
    assert np.array_equal(k2, k5) and not np.allclose(k2[0], k2[1])  # lasting, and each trial its own
    assert k2.std() == pytest.approx(sd, rel=0.15)
    with pytest.raises(ValueError, match="onset cycle"):
        Lanes(np.zeros((1, 2, 5)), np.ones(1), np.ones(1, np.int32), np.zeros(1, np.int32), np.zeros((1, 2)),
              1.6, retrigger=np.array([[sd, 0, 1, 0]], float))
    # a lone robot: with offset d from cycle 1 on, its arms at time t follow the undelayed robot's at t - d T
    p = preset_params(DEFAULT)
    g = GaitSpec(amplitude_deg=60.0)
    a0 = g.setpoints(0.0, p.robot.servo_speed)
    start = [[0.0, 0.0, 0.0, float(a0[0]), float(a0[1])]]
    row = np.array([0.04, 3, 1, 1], float)
    d = float(np.mod(Lanes(np.zeros((1, 1, 5)), np.ones(1), np.ones(1, np.int32), np.zeros(1, np.int32),
                           np.zeros((1, 1)), 1.6, retrigger=row[None]).at_time(1.6).phase[0, 0] + 0.5, 1) - 0.5)
    assert abs(d) > 0.005
    late = simulate(p, start, g, 4, retrigger=row, track_stride=8)
    plain = simulate(p, start, g, 4, track_stride=8)
    T, t = late.period, late.track_t
    assert np.array_equal(t, plain.track_t) and t[-1] > 3.5 * T
    for tt in (2.3 * T, 2.7 * T, 3.4 * T):  # well after the onset, away from the onset's own transient
        i = int(np.argmin(np.abs(t - tt)))
        j = int(np.argmin(np.abs(t - (t[i] + d * T))))  # a phase offset d leads by d periods
        assert np.degrees(np.abs(late.track[i, 0, 3:5] - plain.track[j, 0, 3:5])).max() < 2.0, (tt, d)
    before = t < 0.9 * T
    assert np.abs(late.track[before, 0, 3:5] - plain.track[before, 0, 3:5]).max() == 0.0  # in phase before it
    out = tmp_path / "onset.h5"
    run_relax(RelaxConfig(n_robots=3, trials=1, periods=6, onset_offset_sd=0.04, onset_cycle=2, quiet_periods=0), out)
    _, _, res, _, _, rows = resimulate_trial(out, 0, frame_interval=0.2)
    assert np.array_equal(res.poses[1:].astype(np.float32), rows["poses"])
    with pytest.raises(ValueError, match="exclude each other"):
        RelaxConfig(onset_offset_sd=0.04, retrigger_sd=0.02).validate(preset_params(DEFAULT))
