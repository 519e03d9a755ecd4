"""The model-mismatch term of a calibrated effect's size (calibrate/discrepancy.py): its arithmetic, its
estimator on built cases of known spread, and its frozen table against the estimate from the stored
stress-suite results it was made from."""

import math
import pathlib

import numpy as np
import pytest

from smarticle_mjx.calibrate import discrepancy as D
from smarticle_mjx.calibrate.effects import BY_NAME
from smarticle_mjx.calibrate.stages import added_entry

RESULTS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "results"  # the stored stress-suite rows


def test_without_a_term_the_interval_is_the_statistical_one():
    assert D.widen(0.02, (0.015, 0.03), 0.0) == (0.015, 0.03)
    assert D.widen(0.0, (-0.01, 0.01), 0.4) == (-0.01, 0.01)
    assert D.widen(0.02, (0.015, math.inf), 0.4) == (0.015, math.inf)


def test_each_side_adds_the_mismatch_in_quadrature_in_ln_units():
    v, a_lo, a_hi, sd = 0.03, 0.1, 0.25, 0.2
    lo, hi = D.widen(v, (v * math.exp(-a_lo), v * math.exp(a_hi)), sd)
    assert math.log(v / lo) == pytest.approx(math.hypot(a_lo, 1.96 * sd), rel=1e-12)
    assert math.log(hi / v) == pytest.approx(math.hypot(a_hi, 1.96 * sd), rel=1e-12)
    # a negative value (a phase offset of the other sign) is the mirror image
    nlo, nhi = D.widen(-v, (-v * math.exp(a_hi), -v * math.exp(-a_lo)), sd)
    assert (nlo, nhi) == pytest.approx((-hi, -lo), rel=1e-12)


def test_a_side_that_reaches_zero_keeps_its_statistical_end():
    # the data allow no effect on that side: a mismatch factor cannot move a bound through zero
    lo, hi = D.widen(0.01, (-0.002, 0.02), 0.4)
    assert lo == -0.002 and hi > 0.02
    lo, hi = D.widen(-0.01, (-0.02, 0.001), 0.4)
    assert hi == 0.001 and lo < -0.02


def _rows(log_ratios, s_stat, effect="servo_dead_time", param="dead_time_s", true=0.03):
    rows = []
    for lr, s in zip(log_ratios, s_stat):
        v = true * math.exp(lr)
        rows.append({"set": {"truth": {effect: {param: true}}}, "fitted": {effect: {param: v}},
                     "intervals": {effect: {param: (v * (1 - 1.96 * s), v * (1 + 1.96 * s))}}})
    return rows


def test_the_method_of_moments_recovers_a_known_mismatch_on_built_cases():
    # built cases: ln(fitted/true) = mismatch (sd 0.3) + statistical error (sd s, known per case)
    rng = np.random.default_rng(3)
    s = rng.uniform(0.02, 0.15, 4000)
    lr = rng.normal(0.0, 0.3, 4000) + rng.normal(0.0, s)
    got = D.estimate(_rows(lr, s))["servo_dead_time"]["dead_time_s"]
    assert got["source"] == "own" and got["n"] == 4000
    assert got["log_sd"] == pytest.approx(0.3, abs=0.015)
    # a systematic offset counts as mismatch: the mean square, not the variance
    off = D.estimate(_rows(lr + 0.3, s))["servo_dead_time"]["dead_time_s"]["log_sd"]
    assert off == pytest.approx(math.hypot(0.3, 0.3), abs=0.02)


def test_the_widened_interval_covers_95_percent_where_the_statistical_one_does_not():
    # the same built population: statistical intervals alone hold the truth far less often than 95 %;
    # with the estimated term, about 95 % (binomial sd over 4000 cases: 0.34 %)
    rng = np.random.default_rng(4)
    s = rng.uniform(0.02, 0.15, 4000)
    lr = rng.normal(0.0, 0.3, 4000) + rng.normal(0.0, s)
    sd = D.estimate(_rows(lr, s))["servo_dead_time"]["dead_time_s"]["log_sd"]
    true, v = 0.03, 0.03 * np.exp(lr)
    stat = [(x * math.exp(-1.96 * si), x * math.exp(1.96 * si)) for x, si in zip(v, s)]
    cov_stat = np.mean([lo <= true <= hi for lo, hi in stat])
    cov = np.mean([lo <= true <= hi for lo, hi in (D.widen(x, iv, sd) for x, iv in zip(v, stat))])
    assert cov_stat < 0.5
    assert 0.93 <= cov <= 0.97


def test_a_family_with_few_cases_takes_the_pooled_estimate():
    rows = _rows([0.5, -0.5, 0.5], [0.01] * 3, effect="arm_plate_contact", param="arm_plate_mu", true=0.3)
    rows += _rows([0.1] * 10, [0.01] * 10)
    t = D.estimate(rows)
    assert t["arm_plate_contact"]["arm_plate_mu"]["source"] == "pooled"
    assert t["arm_plate_contact"]["arm_plate_mu"]["n"] == 13
    assert t["servo_dead_time"]["dead_time_s"]["source"] == "own"


def test_the_frozen_table_is_the_estimate_from_the_stored_stress_suite_results():
    table = D.estimate(D.load_rows(RESULTS))
    assert set(table) == set(D.MISMATCH_LOG_SD)
    for e, params in table.items():
        assert set(params) == set(D.MISMATCH_LOG_SD[e]) == {p.name for p in BY_NAME[e].params}
        for k, t in params.items():
            sd, n, source = D.MISMATCH_LOG_SD[e][k]
            assert (round(t["log_sd"], 3), t["n"], t["source"]) == (sd, n, source), (e, k)


def test_a_reported_effect_carries_both_intervals():
    e = BY_NAME["servo_dead_time"]
    got = added_entry(e, {"dead_time_s": 0.025}, {"dead_time_s": (0.023, 0.027)})
    lo, hi = got["interval"]["dead_time_s"]
    assert got["interval_statistical"]["dead_time_s"] == [0.023, 0.027]
    assert lo < 0.023 and hi > 0.027 and got["mismatch_log_sd"] == {"dead_time_s": D.MISMATCH_LOG_SD["servo_dead_time"]["dead_time_s"][0]}
    # the drift stage's tilt already carries its mismatch: reported as given, its statistical one beside it
    t = BY_NAME["plate_tilt"]
    iv, st = {"tilt_x_deg": (0.1, 3.0), "tilt_y_deg": (-1.0, 1.0)}, {"tilt_x_deg": (0.8, 1.2), "tilt_y_deg": (-0.2, 0.2)}
    got = added_entry(t, {"tilt_x_deg": 1.0, "tilt_y_deg": 0.0}, iv, statistical=st)
    assert got["interval"]["tilt_x_deg"] == [0.1, 3.0] and got["interval_statistical"]["tilt_x_deg"] == [0.8, 1.2]


def test_the_report_lists_the_joint_hypotheses_and_what_each_was_fitted_beside():
    """The nominal stage's hypotheses, as calibrate() records them, are a table of the report: one tried
    alone and added, one fitted beside it and refused, one not tried with its reason."""
    from smarticle_mjx.calibrate.report import hypotheses_markdown
    hyps = [{"effect": "servo_dead_time", "tried": True, "values": {"dead_time_s": 0.031}, "heldout_gain": 0.68,
             "bic_gain": 380.2, "rule": "delay test", "accepted": True},
            {"effect": "phase_offset", "beside": "servo_dead_time", "tried": True, "values": {"phase_offset": 0.004},
             "heldout_gain": 0.03, "bic_gain": -2.0, "rule": "held-out gain", "accepted": False},
            {"effect": "servo_lag", "tried": False, "accepted": False, "reason": "no arm angles were tracked"}]
    md = hypotheses_markdown(hyps)
    rows = [x for x in md if x.startswith("| ") and not x.startswith("| effect")]
    assert rows[0].startswith("| servo_dead_time | – | dead_time_s 0.031 | +68% |") and rows[0].endswith("**yes** |")
    assert rows[1].startswith("| phase_offset | servo_dead_time | phase_offset 0.004 | +3% |") and rows[1].endswith("| no |")
    assert "not tried: no arm angles were tracked" in rows[2]
    assert hypotheses_markdown([]) == []


def test_the_report_says_whether_the_robots_own_curves_show_a_phase_offset():
    """calibrate.report.offset_markdown, from the summary's ``offset_test`` (phase.OffsetTest.as_dict): a
    present offset is printed with the interval it is held at, an absent one says it was not fitted, and
    nothing is printed without two pairs to read."""
    from smarticle_mjx.calibrate.phase import OffsetTest
    from smarticle_mjx.calibrate.report import offset_markdown
    here = OffsetTest("heading", 0.1203, 0.0011, 4, 3.18).as_dict()
    md = "\n".join(offset_markdown(here))
    lo, hi = here["interval"]
    assert lo < 0.1203 < hi and f"[{lo:+.4f}, {hi:+.4f}]" in md and "holds it there" in md and "+0.1203" in md
    none = OffsetTest("arms", 0.0004, 0.0009, 6, 2.57).as_dict()
    assert none["absent"] and "not fitted" in "\n".join(offset_markdown(none))
    assert offset_markdown(OffsetTest("arms", 0.1, float("nan"), 1, float("inf")).as_dict()) == []
    assert offset_markdown(None) == []


def test_coverage_reads_each_table_on_the_stored_statistical_intervals():
    """calibration_discrepancy.coverage widens a row's statistical interval by each table's spread: a
    noise sized at 0.94x with a +-2 % statistical interval is missed with no term and held with a spread
    of 0.041 (1.96 x 0.041 = 8 % in ln units); rows that keep the statistical interval apart are read from
    it, not from the reported one."""
    true, v = 1.0, 0.94
    row = {"set": {"truth": {"tracking_noise": {"noise_theta_deg": true}}},
           "fitted": {"tracking_noise": {"noise_theta_deg": v}},
           "intervals": {"tracking_noise": {"noise_theta_deg": [0.5, 2.0]}},  # reported: wide, not read
           "intervals_statistical": {"tracking_noise": {"noise_theta_deg": [v * 0.98, v * 1.02]}}}
    got = D.coverage([row], {"none": {"tracking_noise": {"noise_theta_deg": 0.0}},
                              "some": {"tracking_noise": {"noise_theta_deg": 0.041}}})
    assert got == {"tracking_noise": {"cases": 1, "none": 0, "some": 1}}
