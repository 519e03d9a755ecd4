"""Observables read off tracks (calibrate.observables), checked against references our model did not make:
an arm trajectory written by hand, and the independent simulator's robots with known delays, phase
offsets and tilts."""

import math

import numpy as np
import pytest

from smarticle_mjx.calibrate import independent as I
from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.observables import crossings, observables, swing_delays
from smarticle_mjx.gait import GaitSpec



def _slewed(t, amplitude_deg, period, rate, delay, chirality="ccw"):
    """Arm angles [F, 2] that slew at ``rate`` toward the documented gait's corner, ``delay`` late
    (integrated on a fine grid, then sampled at t): written from the interchange format's conventions."""
    a = math.radians(amplitude_deg)
    fine = np.arange(0.0, t[-1] + 1e-3, 1e-5)
    x = np.empty((len(fine), 2))
    cur = np.array([a, a])
    for k, tf in enumerate(fine):
        target = I.corner(tf - delay, a, period, chirality) if tf >= delay else np.array([a, a])
        cur = cur + np.clip(target - cur, -rate * 1e-5, rate * 1e-5)
        x[k] = cur
    return np.stack([np.interp(t, fine, x[:, j]) for j in range(2)], -1)


@pytest.mark.parametrize("chirality", ["ccw", "cw"])
def test_swing_delay_of_a_hand_written_arm_is_the_delay_plus_half_a_swing(chirality):
    """An arm that starts its swing ``d`` after the command switches and
    slews at w reaches its midpoint d + a / w after the switch: read from
    30 Hz frames with a tenth of them missing, within 0.5 ms."""
    rng = np.random.default_rng(0)
    T, amp, w, d = 0.8, 30.0, 6.0, 0.021
    t = np.arange(0.0, 4 * T, 1 / 30)
    t = np.sort(t + rng.uniform(0, 0.002, len(t)))
    arms = _slewed(t, amp, T, w, d, chirality)
    arms[rng.uniform(size=arms.shape) < 0.1] = np.nan
    got = swing_delays(t, arms, GaitSpec(amplitude_deg=amp, chirality=chirality, period_s=T))
    want = d + math.radians(amp) / w
    assert len(got) >= 12
    assert np.abs(got - want).max() < 5e-4, (got, want)
    # read with the other chirality, every swing is matched to the wrong arm: a quarter period off
    other = GaitSpec(amplitude_deg=amp, chirality="cw" if chirality == "ccw" else "ccw", period_s=T)
    assert np.abs(np.abs(swing_delays(t, arms, other) - want) - T / 4).max() < 5e-4


def test_crossings_interpolate_between_frames_and_give_the_direction():
    t = np.array([0.0, 1.0, 2.0, 3.0])
    tc, d = crossings(t, np.array([-1.0, 3.0, np.nan, -2.0]))
    assert np.allclose(tc, [0.25, 1.0 + 2.0 * 3 / 5]) and list(d) == [1, -1]


def _case(tmp, name, robots=1, **effects):
    d = tmp / name
    for a in (15.0, 60.0):
        I.write_case(d, amplitude_deg=a, name=f"a{int(a)}", trials=2, periods=4, seed=11 + int(a), robots=robots,
                     **effects)
    return observables(load(d))


def test_a_dead_time_of_the_independent_robot_delays_its_swings_by_that_time(tmp_path):
    """The independent robot's servo acting on its command 30 ms late swings
    30 ms later at every amplitude than its twin without it (same starts,
    frames and noise): a pure delay moves the whole arm trajectory."""
    clean = _case(tmp_path, "clean")
    late = _case(tmp_path, "late", dead_s=0.03)
    assert len(clean["arm_delay_ms"]) == 2
    for c, l in zip(clean["arm_delay_ms"], late["arm_delay_ms"]):
        assert c["gait"] == l["gait"] and c["n"] >= 20
        assert l["mean"] - c["mean"] == pytest.approx(30.0, abs=1.0), (c, l)
        assert c["se"] < 0.5


def test_a_phase_offset_of_the_independent_robots_is_their_swings_lead(tmp_path):
    """Two robots of one build, the second commanded 0.1 period ahead: after
    the start its swings lead by 0.1 period (its first swing, begun at rest,
    does not and is left out); in phase, by nothing. Within 0.004 period: at
    15 deg this servo's slew never quite reaches its corner, and the start
    transient fades over a few swings (measured 0.098 there, 0.1001 at 60)."""
    ahead = _case(tmp_path, "ahead", robots=2, phase_offset=0.1)
    level = _case(tmp_path, "same", robots=2)
    assert len(ahead["phase_lead"]) == 2
    for r in ahead["phase_lead"]:
        assert r["robot"] == 1 and r["mean"] == pytest.approx(0.1, abs=0.004), r
    for r in level["phase_lead"]:
        assert abs(r["mean"]) < 0.002, r


def test_agreement_is_within_the_combined_error_of_data_and_model():
    from smarticle_mjx.calibrate.observables import reproduced
    data = {"mean": 10.0, "se": 0.3}
    assert reproduced(data, {"mean": 10.7, "se": 0.4})          # 0.7 < 1.96 * 0.5
    assert not reproduced(data, {"mean": 11.1, "se": 0.4})      # 1.1 > 0.98
    assert reproduced(data, {"mean": 10.5, "se": float("nan")})  # a model value without error: the data's alone
    vec = {"v": [0.0, -0.02], "se": [0.003, 0.003]}
    assert reproduced(vec, {"v": [0.001, -0.019], "se": [0.001, 0.001]})
    assert not reproduced(vec, {"v": [0.0, 0.0], "se": [0.001, 0.001]})  # one component off: not reproduced
    assert reproduced(data, None) is None


def test_grouped_mean_weights_groups_alike_and_measures_spread_within_them():
    """Built values: group a = 1 + e (four values), group b = 10 + e (two), group c = 4 (one). The mean
    is the mean of the group means, 5.0, not the pooled mean; the error is the within-group spread
    pooled over 7 - 3 = 4 degrees of freedom, s sqrt(sum 1/n_g) / 3; one value per group: no spread."""
    from smarticle_mjx.calibrate.observables import grouped_mean_se
    e = np.array([-0.1, 0.1, -0.2, 0.2])
    x = np.concatenate([1.0 + e, [9.9, 10.1], [4.0]])
    g = np.array(["a"] * 4 + ["b"] * 2 + ["c"])
    r = grouped_mean_se(x, g)
    s2 = (np.sum(e ** 2) + 0.02) / 4
    assert r["mean"] == pytest.approx(5.0) and r["n"] == 7
    assert r["se"] == pytest.approx(math.sqrt(s2 * (1 / 4 + 1 / 2 + 1)) / 3)
    assert math.isnan(grouped_mean_se([1.0, 2.0], ["a", "b"])["se"])
    # rows of labels (trial, robot, group) work as labels, NaNs are dropped
    lab = np.array([[0, 0, 1], [0, 0, 1], [1, 0, 1], [1, 0, 1]])
    r = grouped_mean_se([1.0, 3.0, 5.0, np.nan], lab)
    assert r["mean"] == pytest.approx(3.5) and r["n"] == 3


def test_an_arm_read_with_a_constant_error_keeps_its_delay_and_its_error_small():
    """A hand-written arm pair slewing at 6 rad/s, 21 ms late, its second arm read 6 deg too high: that
    arm crosses its midpoint 17 ms early on the way up and 17 ms late on the way down. Grouped by arm
    and direction the mean delay is the true d + a / w within 0.5 ms and its error stays under 0.5 ms,
    where the plain standard error over all swings carries the misreading (over 2 ms)."""
    from smarticle_mjx.calibrate.observables import grouped_mean_se, swing_delay_groups
    rng = np.random.default_rng(1)
    T, amp, w, d = 0.8, 30.0, 6.0, 0.021
    t = np.sort(np.arange(0.0, 5 * T, 1 / 60) + rng.uniform(0, 0.002, int(np.ceil(5 * T * 60))))
    arms = _slewed(t, amp, T, w, d)
    arms[:, 1] += math.radians(6.0)
    x, g = swing_delay_groups(t, arms, GaitSpec(amplitude_deg=amp, chirality="ccw", period_s=T))
    assert sorted(set(g.tolist())) == [0, 1, 2, 3]
    r = grouped_mean_se(x, g)
    assert r["mean"] == pytest.approx(d + math.radians(amp) / w, abs=5e-4)
    assert r["se"] < 5e-4
    assert x.std(ddof=1) / math.sqrt(len(x)) > 2e-3


def test_the_independent_robots_dead_time_is_read_through_an_arm_misread_by_a_constant(tmp_path):
    """The independent robot with a 30 ms dead time and its second arm read 6 deg off, against its twin
    without either (same starts, frames and noise): its swings are 30 ms later (within 1 ms); the
    misreading alone moves the delay by under 0.5 ms, and the error stays under 0.5 ms (the twin's:
    0.1-0.14) and under a quarter of the plain standard error over all swings, which carries the
    misreading (about 2 ms). At 15 deg the misread arm crosses its reading's midpoint 40 % of the way
    through a swing that barely reaches its corner, where swing-to-swing noise weighs more: there the
    error is about three times the twin's."""
    from smarticle_mjx.calibrate.observables import swing_delays

    def plain_se(name):
        trials = load(tmp_path / name)
        out = {}
        for g in {tr.gaits[0] for tr in trials}:
            x = np.concatenate([swing_delays(tr.t, tr.arms[:, 0], g) for tr in trials if tr.gaits[0] == g]) * 1e3
            out[g.amplitude_deg] = x.std(ddof=1) / math.sqrt(len(x))
        return out

    clean = _case(tmp_path, "clean")
    both = _case(tmp_path, "both", dead_s=0.03, arm2_bias_deg=6.0)
    misread = _case(tmp_path, "misread", arm2_bias_deg=6.0)
    plain = {"both": plain_se("both"), "misread": plain_se("misread")}
    for c, b, m in zip(clean["arm_delay_ms"], both["arm_delay_ms"], misread["arm_delay_ms"]):
        assert c["gait"] == b["gait"] == m["gait"]
        assert b["mean"] - c["mean"] == pytest.approx(30.0, abs=1.0), (c, b)
        assert abs(m["mean"] - c["mean"]) < 0.5, (c, m)
        for name, r in (("both", b), ("misread", m)):
            assert r["se"] < 0.5 and r["se"] < plain[name][c["amplitude_deg"]] / 4, (name, c, r, plain)
