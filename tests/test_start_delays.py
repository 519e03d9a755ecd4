"""Robots out of step start one after another: a robot's phase offset is a start delay, served from
its gait's first corner (``Lanes.with_start_delays``, since version 0.4.1)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from smarticle_mjx import gait as G
from smarticle_mjx import imperfections as I
from smarticle_mjx import presets
from smarticle_mjx.engine import Lanes, Scene, open_backend
from smarticle_mjx.engine.batch import RetireRule, run_lanes
from smarticle_mjx.engine.core import lane_controls
from smarticle_mjx.engine.simulate import simulate


def _lanes(phase, period=1.6, robot_period=None):
    phase = np.asarray(phase, float).reshape(1, -1)
    n = phase.shape[1]
    return Lanes(np.zeros((1, n, 5)), np.full(1, math.radians(90.0)), np.ones(1, np.int32), np.zeros(1, np.int32),
                 phase, period, robot_period=robot_period)


def test_start_offsets_become_delays_after_the_robot_furthest_ahead():
    """The robot furthest ahead starts at t = 0, every other one its offset later (hold = -phase T of its own
    period); the offsets between robots are kept; doing it twice changes nothing; offsets spanning a period
    cannot be delays."""
    lanes = _lanes([0.03, -0.01, 0.0], robot_period=np.array([[1.6, 1.6 * 1.004, 1.6 * 0.997]]))
    d = lanes.with_start_delays()
    assert d.phase.max() == 0.0 and (d.phase <= 0).all()
    np.testing.assert_allclose(np.diff(d.phase), np.diff(lanes.phase), atol=1e-15)
    np.testing.assert_allclose(d.hold[0], [0.0, 0.04 * 1.6 * 1.004, 0.03 * 1.6 * 0.997], rtol=1e-12)
    again = d.with_start_delays()
    assert np.array_equal(again.phase, d.phase) and np.array_equal(again.hold, d.hold)
    assert _lanes([0.0, 0.0]).with_start_delays().hold is None  # robots in phase wait for nobody
    with pytest.raises(ValueError, match="span a whole period"):
        _lanes([0.6, -0.45]).with_start_delays()


def test_a_robot_waits_at_its_first_corner_then_runs_its_gait_at_its_offset():
    """Before its start a delayed robot's setpoints are the gait's first corner (the square gait's
    (+alpha, +alpha), ccw) at rate 0; from its start on, they are the gait shifted by its delay,
    computed here from the gait function directly."""
    period, speed = 1.6, presets.params().robot.servo_speed
    scene = Scene.build(presets.params(), 2)
    lanes = _lanes([0.05, 0.0], period).with_start_delays()
    hold = 0.05 * period
    t = np.arange(0.0, 0.3, 0.001)
    ctrl = lane_controls(scene, lanes, t)[0].reshape(len(t), 2, 4)  # per robot: a1, a2, rate1, rate2
    before, after = t < hold, t >= hold
    a = math.radians(90.0)
    np.testing.assert_allclose(ctrl[before, 1, :2], a, atol=1e-6)
    assert (ctrl[before, 1, 2:] == 0).all()
    late = np.asarray(G.setpoints_and_rates(t[after] - hold, a, period, speed))
    np.testing.assert_allclose(ctrl[after, 1], late, atol=2e-5)
    first = np.asarray(G.setpoints_and_rates(t, a, period, speed))  # the robot ahead starts at t = 0
    np.testing.assert_allclose(ctrl[:, 0], first, atol=2e-5)


def test_a_gait_phase_just_below_zero_is_the_first_corner():
    """In float32 a phase a hair below 0 taken mod 1 rounds to 1.0; that is phase 0 (the first corner),
    not a fifth quarter of the gait."""
    a = math.radians(90.0)
    sp = np.asarray(G.setpoints(0.0, a, 1.6, 8.7, phase=-1e-9))
    np.testing.assert_allclose(sp, [a, a], atol=1e-6)


def test_a_robot_started_late_moves_its_arms_no_faster_than_its_servo():
    """A robot starts at rest at its gait's first corner. Read as a start delay, an offset ahead leaves
    its servo to follow the gait's ramps at the rated arm speed (within the lag's overshoot, 10 %); read
    as a clock started mid-move (versions up to 0.4.0), the servo must catch up a setpoint part of a move
    away, at its stall torque, and the arm swings at more than twice the rated speed."""
    params, g = presets.params(), G.GaitSpec(90.0)
    a0 = g.setpoints(0.0, params.robot.servo_speed)
    poses = np.array([[0.0, 0.0, 0.0, a0[0], a0[1]], [0.5, 0.0, 0.0, a0[0], a0[1]]])  # 10 W apart
    rated = params.robot.servo_speed
    fastest = {}
    for delays in (True, False):
        r = simulate(params, poses, g, 1, phase=np.array([0.05, 0.0]), track_stride=1, start_delays=delays)
        arms = np.concatenate([poses[None, :, 3:], r.track[:, :, 3:]], 0)
        fastest[delays] = (np.abs(np.diff(arms, axis=0)) / params.timestep).max(axis=(0, 2))
    assert (fastest[True] < 1.1 * rated).all(), fastest
    assert fastest[False][0] > 2 * rated and fastest[False][1] < 1.1 * rated, fastest


def test_start_delays_act_in_a_lane_s_first_chunk_only():
    """A relaxation cut into chunks of one period records what one chunk records (each robot waits
    only at the run's start), and the delays act (the records differ from robots started together)."""
    params, g = presets.params(), G.GaitSpec(90.0)
    a0 = g.setpoints(0.0, params.robot.servo_speed)
    poses = np.zeros((1, 3, 5))
    poses[0, :, 0] = [0.0, 0.06, 0.12]
    poses[..., 3:] = a0
    base = Lanes(poses, np.full(1, g.amplitude), np.full(1, g.chirality_sign, np.int32),
                 np.full(1, g.kind_code, np.int32), np.array([[0.04, 0.0, -0.03]]), g.period())
    out = {}
    with open_backend("native", params, 3) as be:
        for name, lanes, chunk in (("delays-1", base.with_start_delays(), 1), ("delays-3", base.with_start_delays(), 3),
                                   ("together", dataclasses.replace(base, phase=np.zeros((1, 3))), 3)):
            run_lanes(be, lanes, 3, batch_size=1, chunk_periods=chunk, rule=RetireRule(quiet_periods=0),
                      on_lanes=lambda r, k=name: out.setdefault(k, r.poses[0]))
    np.testing.assert_allclose(out["delays-1"], out["delays-3"], rtol=0, atol=1e-9)
    assert not np.allclose(out["delays-3"], out["together"], atol=1e-6)


def test_imperfections_with_start_offsets_run_as_start_delays_and_other_backends_refuse_them():
    """A drawn set's start offsets reach the engine as delays (all phases <= 0, the furthest ahead at 0);
    MJX, Warp and DART start every gait at t = 0 and refuse such sets, and such lanes, in one line."""
    draw = I.draw("lab-resync", 7, 0)
    lanes = draw.lanes(_lanes(np.zeros(7)), [2])
    raw = draw.lane_phase([2])
    np.testing.assert_allclose(lanes.phase, raw - raw.max(), atol=1e-15)
    assert lanes.hold is not None and (lanes.hold[0] == 0).sum() == 1
    old = draw.lanes(_lanes(np.zeros(7)), [2], start_delays=False)
    assert old.hold is None and np.allclose(old.phase, raw)
    for backend in ("mjx", "warp", "dart"):
        with pytest.raises(ValueError, match=f"started at different times .* run on the native backend, not {backend}"):
            I.get("phase-jitter").check_backend(backend)
    from smarticle_mjx.engine.core import check_start_delays
    with pytest.raises(ValueError, match="started at different times .* not mjx"):
        check_start_delays(lanes, "mjx")
    from smarticle_mjx.specs import RelaxConfig
    with pytest.raises(ValueError, match="--phase-jitter: robots started at different times .* run on the native backend"):
        RelaxConfig(phase_jitter=0.02, backend="mjx").validate(presets.params())


def test_a_store_made_before_start_delays_replays_with_the_old_start():
    """Stores record the package that made them: up to 0.4.0 robots out of phase started their clocks at
    t = 0, since 0.4.1 one after another; a replay runs what made the store."""
    from types import SimpleNamespace
    from smarticle_mjx.replay import made_with_start_delays
    from smarticle_mjx.store import PACKAGE
    for package, delays in (("smarticle-mjx 0.3.5", False), ("smarticle-mjx 0.4.0", False),
                            ("smarticle-mjx 0.4.1", True), ("smarticle-mjx 0.10.0", True), (PACKAGE, True)):
        assert made_with_start_delays(SimpleNamespace(attrs={"package": package})) is delays, package
