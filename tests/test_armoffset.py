"""The arm-offset reading (calibrate.armoffset): an arm that rests off its commanded corners by a constant,
measured without the model, taken out of the tracks and named as unexplained."""

import math

import numpy as np
import pytest

from smarticle_mjx.calibrate import armoffset as AO
from smarticle_mjx.calibrate import independent as I
from smarticle_mjx.calibrate.data import Trial, load
from smarticle_mjx.calibrate.stages import verdict
from smarticle_mjx.gait import GaitSpec
from smarticle_mjx.scene import SceneParams

GAIT = GaitSpec(amplitude_deg=40.0, period_s=0.8, chirality="ccw")


def _trial(offset_deg=(0.0, 0.0), short_deg=0.0, noise_deg=0.3, speed=6.0, periods=6, rate=90.0, seed=0):
    """A lone robot whose arms follow the gait's corners at ``speed`` rad/s, stop ``short_deg`` before each
    corner, and are read ``offset_deg`` off, with white noise: written here from the gait's corners, not by
    the model."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, periods * GAIT.period(), 1.0 / rate)
    target = np.asarray(GAIT.setpoints(t, 1e6), float)  # [F, 2], the commanded corners
    a = math.radians(GAIT.amplitude_deg - short_deg)
    arms = np.zeros_like(target)
    cur = np.sign(target[0]) * a
    for f in range(len(t)):
        goal = np.sign(target[f]) * a
        if f:
            cur = cur + np.clip(goal - cur, -speed / rate, speed / rate)
        arms[f] = cur
    arms = arms + np.radians(offset_deg) + rng.normal(0, math.radians(noise_deg), arms.shape)
    pose = np.zeros((len(t), 1, 3))
    return Trial("built:0", t, pose, arms[:, None, :], GAIT, SceneParams(), rate)


def test_an_arm_read_off_by_a_constant_is_read_to_a_tenth_of_a_degree_and_a_short_servo_is_not_an_offset():
    """Rests at +a + b and -a + b: the offset is b. A servo that stops s short of both corners rests at
    a - s and -a + s: shortfall s, no offset."""
    r = AO.read_offsets([_trial(offset_deg=(0.0, 5.0), seed=s) for s in range(2)])
    a1, a2 = r.arms
    assert a2.offset_deg == pytest.approx(5.0, abs=0.1) and a2.present
    assert abs(a1.offset_deg) < 0.1 and not a1.present
    assert r.present == (a2,)
    short = AO.read_offsets([_trial(short_deg=3.0)])
    assert all(abs(a.offset_deg) < 0.1 and a.shortfall_deg == pytest.approx(3.0, abs=0.1) and not a.present
               for a in short.arms)


def test_an_offset_needs_both_size_and_significance_and_enough_rests():
    small = AO.read_offsets([_trial(offset_deg=(0.5, 0.5))])
    assert not small.present  # under MIN_OFFSET_DEG, however sure
    noisy = AO.read_offsets([_trial(offset_deg=(1.5, 0.0), noise_deg=25.0)])
    assert not noisy.arms[0].present  # over it, but within Z standard errors of zero
    brief = AO.read_offsets([_trial(offset_deg=(5.0, 5.0), periods=1)])
    assert not brief.applicable and "often enough" in brief.describe()


def test_taking_the_offset_out_leaves_the_arm_as_commanded_and_the_other_tracks_alone():
    tr = _trial(offset_deg=(0.0, 6.0), noise_deg=0.0)
    r = AO.read_offsets([tr])
    (out,) = AO.without_offsets([tr], r)
    assert np.array_equal(out.arms[:, 0, 0], tr.arms[:, 0, 0]) and np.array_equal(out.pose, tr.pose)
    assert np.allclose(out.arms[:, 0, 1], tr.arms[:, 0, 1] - math.radians(r.arms[1].offset_deg))
    assert abs(AO.read_offsets([out]).arms[1].offset_deg) < 0.01


def test_the_independent_simulators_misread_arm_is_read_and_its_clean_robots_rest_at_their_corners(tmp_path):
    """The independent simulator (written apart from the library) reads arm 2 b off: the reading finds b on
    arm 2 alone; the same robot without the misreading rests at its corners within the threshold."""
    for name, bias in (("bias", -4.0), ("clean", 0.0)):
        I.write_case(tmp_path / name, amplitude_deg=40.0, trials=2, periods=4, frame_rate=60.0, seed=3,
                     arm2_bias_deg=bias, name=name)
        r = AO.read_offsets(load(tmp_path / name / f"{name}.csv"))
        a1, a2 = r.arms
        assert not a1.present and abs(a1.offset_deg) < AO.MIN_OFFSET_DEG
        if bias:
            assert a2.present and a2.offset_deg == pytest.approx(bias, abs=0.2)
        else:
            assert not a2.present and abs(a2.offset_deg) < AO.MIN_OFFSET_DEG


def test_the_verdict_names_an_arm_offset_first_as_unexplained():
    r = AO.read_offsets([_trial(offset_deg=(0.0, 5.0))])
    v = verdict(0.5, [], r)
    assert v.startswith("unexplained: robot 0 arm 2 rests ") and v.endswith("agrees within measurement error")
    assert float(v.split(" rests ")[1].split()[0]) == pytest.approx(5.0, abs=0.1)
    assert verdict(0.5, [], AO.read_offsets([_trial()])) == "agrees within measurement error"


def test_an_untracked_frame_does_not_cut_a_rest():
    """Frames dropped by the tracker mid-rest leave the reading as it was (a run cut there would read the
    arm's move as a rest level)."""
    tr = _trial(offset_deg=(0.0, 0.0), noise_deg=0.0)
    full = AO.read_offsets([tr])
    arms = tr.arms.copy()
    arms[5::17] = np.nan
    gappy = AO.read_offsets([Trial(tr.name, tr.t, tr.pose, arms, tr.gait, tr.params, tr.frame_rate_hz)])
    assert [a.rests for a in gappy.arms] == [a.rests for a in full.arms]
    assert all(abs(a.offset_deg) < 0.05 and abs(a.shortfall_deg) < 0.05 for a in gappy.arms)


def test_the_report_tables_every_arm_and_says_whether_an_offset_was_taken_out():
    from smarticle_mjx.calibrate.report import arm_offset_markdown
    r = AO.read_offsets([_trial(offset_deg=(0.0, 5.0))])
    md = "\n".join(arm_offset_markdown({**r.as_dict(), "taken_out": True}))
    assert "**An arm rests off its corners**" in md and ("| 0 | 2 | +4.9" in md or "| 0 | 2 | +5.0" in md)
    assert md.count("\n| 0 |") == 2 and "(present)" in md
    plain = "\n".join(arm_offset_markdown({**AO.read_offsets([_trial()]).as_dict(), "taken_out": False}))
    assert "No arm rests off its corners." in plain and "(present)" not in plain
    assert arm_offset_markdown(None) == [] and arm_offset_markdown(AO.read_offsets([]).as_dict()) == []
