"""Structure before numbers (calibrate.observables.delay_test), measured values as priors (the sidecar's
``measured``), and the stress suite's generator (calibrate.independent rebuilt at random), each checked
against a closed form or against the independent simulator, not against the calibration's own output."""

import json
import math
import types
import sys
import pathlib

import numpy as np
import pytest

from smarticle_mjx.calibrate import independent as I
from smarticle_mjx.calibrate.data import DataError, load, priors
from smarticle_mjx.calibrate.fit import nominal_findings
from smarticle_mjx.calibrate.nominal import NOMINAL, fit_nominal
from smarticle_mjx.calibrate.observables import DELAY_MIN_MS, DelayTest, delay_test, observables

BENCHMARKS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks"  # scripts run as a user runs them, never imported


def _rows(amps, delays_ms, se=0.1):
    return {"arm_delay_ms": [{"gait": f"{a}", "amplitude_deg": float(a), "mean": float(d), "se": se, "n": 30}
                             for a, d in zip(amps, delays_ms)]}


def test_delay_test_splits_a_constant_from_a_slope_in_amplitude():
    """Measured delays = model's + 20 ms + 30 ms/rad x amplitude: the test returns both, exactly (the
    excess lies on a line), and calls the 20 ms a constant delay; a pure slope (a slower servo) is not."""
    amps = [15, 40, 70]
    model = _rows(amps, [40.0, 90.0, 150.0])
    meas = _rows(amps, [40.0 + 20.0 + 30.0 * math.radians(a) for a, m in zip(amps, [40.0, 90.0, 150.0])])
    meas["arm_delay_ms"] = [{**r, "mean": m["mean"] + 20.0 + 30.0 * math.radians(r["amplitude_deg"])}
                            for r, m in zip(meas["arm_delay_ms"], model["arm_delay_ms"])]
    d = delay_test(meas, model)
    assert d.applicable and d.constant_delay
    assert d.constant_ms == pytest.approx(20.0, abs=1e-9) and d.per_rad_ms == pytest.approx(30.0, abs=1e-9)
    slower = _rows(amps, [m["mean"] + 60.0 * math.radians(m["amplitude_deg"]) for m in model["arm_delay_ms"]])
    d = delay_test(slower, model)
    assert d.applicable and not d.constant_delay and abs(d.constant_ms) < 1e-9
    # a constant of 0 with three 2 ms floors is not yet shown to be below 5 ms: its standard error is the
    # straight line's intercept error, sigma sqrt(sum x^2 / (n sum x^2 - (sum x)^2)) ...
    x = np.radians(amps)
    sigma = math.sqrt(2 * 0.1 ** 2 + 2.0 ** 2)
    se = sigma * math.sqrt((x ** 2).sum() / (len(x) * (x ** 2).sum() - x.sum() ** 2))
    assert not d.no_constant_delay and d.constant_se_ms == pytest.approx(se, rel=1e-9)
    # ... one 8 ms short of the model's (a servo quicker to start than the library's) is
    quicker = _rows(amps, [m["mean"] - 8.0 + 60.0 * math.radians(m["amplitude_deg"]) for m in model["arm_delay_ms"]])
    assert delay_test(quicker, model).no_constant_delay
    # one amplitude, or amplitudes too close, cannot separate the two: not applicable
    assert not delay_test(_rows([40], [120.0]), _rows([40], [90.0])).applicable
    assert not delay_test(_rows([40, 50], [120.0, 130.0]), _rows([40, 50], [90.0, 100.0])).applicable
    # a constant below DELAY_MIN_MS is not a finding however certain
    small = _rows(amps, [m["mean"] + 0.5 * DELAY_MIN_MS for m in model["arm_delay_ms"]])
    assert not delay_test(small, model).constant_delay
    # two close small amplitudes leave the constant uncertain: neither a delay nor its absence
    near = _rows([10, 20], [40.0, 60.0])
    lag = {"arm_delay_ms": [{**r, "mean": r["mean"] + 17.0 + 6.0 * k} for k, r in enumerate(near["arm_delay_ms"])]}
    d = delay_test(lag, near)
    assert d.applicable and not d.constant_delay and not d.no_constant_delay


def test_the_delay_test_finds_a_dead_time_in_the_independent_robot_and_none_in_its_clean_twin(tmp_path):
    """The independent robot (its own servo law) with and without a 30 ms dead time, against the same
    reference (the clean twin standing in for the model): the constant excess is the dead time within
    3 ms, and zero within 3 ms against itself."""
    def case(d, **kw):
        for a in (15.0, 60.0):
            I.write_case(d, amplitude_deg=a, name=f"a{int(a)}", trials=1, periods=3, seed=5 + int(a), **kw)
        return observables(load(d))
    clean, dead = case(tmp_path / "clean"), case(tmp_path / "dead", dead_s=0.03)
    d = delay_test(dead, clean)
    assert d.applicable and d.constant_delay and abs(d.constant_ms - 30.0) < 3.0, d
    assert abs(d.per_rad_ms) < 5.0
    assert not delay_test(clean, clean).constant_delay


SIDE = {"robots": 1, "gait": {"kind": "square", "amplitude_deg": 90, "period_s": 1.6, "chirality": "ccw"},
        "plate": {"friction": 0.37}, "frame_rate_hz": 30}
ROWS = "trial,t,robot,x,y,theta,alpha1,alpha2\n" + "".join(f"0,{t},0,0,0,0,,\n" for t in (0.0, 0.1, 0.2))


def _file(tmp_path, side, name="run"):
    (tmp_path / f"{name}.csv").write_text(ROWS)
    (tmp_path / f"{name}.json").write_text(json.dumps(side))
    return tmp_path / f"{name}.csv"


def test_measured_values_in_the_sidecar_become_the_models_values_and_priors(tmp_path):
    tr = load(_file(tmp_path, {**SIDE, "measured": {"mass": [0.0348, 0.0006], "arm_length": [0.053, 0.001]}}))[0]
    assert tr.params.robot.mass == 0.0348 and tr.params.robot.arm_lengths == (0.053, 0.053)
    assert priors([tr]) == {"mass": (0.0348, 0.0006), "arm_length": (0.053, 0.001), "arm2_length": (0.053, 0.001)}


@pytest.mark.parametrize("measured,msg", [
    ({"wheels": [3, 1]}, "unknown measured values"),
    ({"mass": [0.03]}, "must be \\[value, sd\\]"),
    ({"mass": [0.03, 0.0]}, "sd > 0"),
    ({"mass": ["heavy", 0.001]}, "must be \\[value, sd\\]"),
    ([1, 2], "must be an object"),
])
def test_bad_measured_values_are_refused_in_one_line(tmp_path, measured, msg):
    with pytest.raises(DataError, match=msg):
        load(_file(tmp_path, {**SIDE, "measured": measured}))


def test_two_files_measuring_one_robot_differently_are_refused(tmp_path):
    _file(tmp_path, {**SIDE, "measured": {"mass": [0.035, 0.001]}}, "a")
    _file(tmp_path, {**SIDE, "measured": {"mass": [0.030, 0.001]}}, "b")
    with pytest.raises(DataError, match="measured mass is"):
        priors(load(tmp_path))


class _Linear:
    """A fake problem whose residuals are linear in the nominal values: (mass - datum) / sd for one
    datum. With a Gaussian prior the posterior mode is the inverse-variance mean."""

    def __init__(self, params, prior, datum=0.040, sd=0.002):
        self.trials = [type("T", (), {"params": params})()]
        self.priors, self.datum, self.sd = prior, datum, sd

    def vector_with(self, values, eff=None):
        return np.array([(values["mass"] - self.datum) / self.sd])


def test_a_prior_pulls_the_fit_to_the_inverse_variance_mean_and_a_far_fit_is_a_finding(tmp_path):
    tr = load(_file(tmp_path, {**SIDE, "measured": {"mass": [0.0348, 0.0006]}}))[0]
    mass = [p for p in NOMINAL if p.name == "mass"]
    fit = fit_nominal(_Linear(tr.params, priors([tr])), params=tuple(mass), max_nfev=20)
    w_d, w_p = 1 / 0.002 ** 2, 1 / 0.0006 ** 2
    want = (0.040 * w_d + 0.0348 * w_p) / (w_d + w_p)
    assert fit.values["mass"] == pytest.approx(want, rel=1e-4)
    assert fit.measured == {"mass": [0.0348, 0.0006]}
    assert nominal_findings(fit) == []  # 0.43 sd from the measurement
    tight = fit_nominal(_Linear(tr.params, {"mass": (0.0348, 0.0001)}), params=tuple(mass), max_nfev=20)
    assert tight.values["mass"] == pytest.approx(0.0348, abs=2e-4)
    # data at 0.0435 +- 0.001 pull the mode to 0.0371, 3.8 sd from the measurement: reported
    far = fit_nominal(_Linear(tr.params, priors([tr]), datum=0.0435, sd=0.001), params=tuple(mass), max_nfev=20)
    assert far.values["mass"] == pytest.approx((0.0435 / 1e-6 + 0.0348 / 0.0006 ** 2) / (1e6 + 1 / 0.0006 ** 2),
                                               rel=1e-4)
    (f,) = nominal_findings(far)
    assert f["param"] == "mass" and f["sd_from_measured"] > 3.0


def test_the_stress_generator_draws_each_set_from_its_seed_and_keeps_two_in_five_clean():
    from smarticle_mjx.calibrate import stress as S
    a, b = S.draw_set(7, 4), S.draw_set(7, 4)
    assert a == b and a != S.draw_set(8, 4)
    sets = [S.draw_set(11, i) for i in range(50)]
    assert sum(not s["hidden"] and not s["outside"] for s in sets) == 20
    assert all(len([h for h in s["hidden"] if h in S.SERVO]) <= 1 for s in sets)
    assert all(s["robots"] == 2 for s in sets if "phase_offset" in s["hidden"])
    json.dumps(sets)  # JSON-ready


def test_the_generators_anisotropic_plate_reads_mujocos_contact_frame():
    """mu along the plate's y set twice mu along x: a robot pushed along x slides farther than one pushed
    along y (the contact frame's tangents are read from a contact, not assumed)."""
    import mujoco
    slide = {}
    for axis in (0, 1):
        frame = I._first_tangent_along_x(1, I.DEFAULT)
        mx, my = 0.2, 0.4
        m = mujoco.MjModel.from_xml_string(I._mjcf(1, aniso=(mx, my) if frame else (my, mx)))
        d = mujoco.MjData(m)
        d.qpos[:7] = [0, 0, I.BODY["height"] / 2, 1, 0, 0, 0]
        d.qvel[axis] = 0.2
        for _ in range(1000):
            mujoco.mj_step(m, d)
        slide[axis] = abs(d.qpos[axis])
    # v^2 / (2 mu g): twice the friction, half the distance
    assert slide[0] / slide[1] == pytest.approx(2.0, rel=0.1)


def test_slide_is_the_path_of_the_mean_within_cycle_motion():
    """A body moving straight at v (no rotation) has bin means v T (k + 1/2) / B since each cycle's start:
    their path from the start is v T (1 - 1/(2B)); a body turning at w without moving slides
    (L/4) w T (1 - 1/(2B)); a body that stays put, 0."""
    from smarticle_mjx.calibrate.drift import slide
    from smarticle_mjx.calibrate.residuals import BINS
    T, L = 0.8, 0.05
    t = np.arange(0.0, 6 * T, T / 480)
    f = 1.0 - 0.5 / BINS
    v, w = 0.002, 0.3  # m/s, rad/s
    pose = np.zeros((len(t), 1, 3))
    pose[:, 0, 0] = v * t
    pose[:, 0, 2] = 0.7
    ((i, s),) = slide(t, pose, T, L)
    assert s == pytest.approx(v * T * 1e3 * f, rel=2e-3)
    pose = np.zeros((len(t), 1, 3))
    pose[:, 0, 2] = w * t
    assert slide(t, pose, T, L)[0][1] == pytest.approx(L / 4 * w * T * 1e3 * f, rel=2e-3)
    assert slide(t, np.zeros((len(t), 1, 3)), T, L)[0][1] == 0.0


def test_smx_calibrate_set_changes_the_model_before_the_measured_values_and_refuses_a_bad_field(tmp_path):
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    path = _file(tmp_path, {**SIDE, "measured": {"mass": [0.0348, 0.0006]}})
    tr = load(path, overrides=(("robot.arm_length", 0.055), ("robot.mass", 0.05)))[0]
    assert tr.params.robot.arm_length == 0.055 and tr.params.robot.mass == 0.0348  # the measurement wins
    r = CliRunner().invoke(app, ["calibrate", str(path), "--out", str(tmp_path / "rep"), "--set", "robot.wheels=3"])
    assert r.exit_code == 2 and "wheels" in r.output and len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "rep").exists()


def test_the_stress_scoring_on_built_summaries():
    """The frozen scoring: right = the hidden effect added first (both, with two hidden); a same-law
    size within 1.5x and an interval that holds the truth; a missed effect fails both; a tilt's size is
    its vector's length; an outside effect is reported when nothing is added and the verdict says
    unexplained; the held-out error is compared with the clean twin's."""
    from smarticle_mjx.calibrate import stress as S

    def res(added, verdict="explained", err=2.0):
        return {"added": [{"effect": e, "values": v, "interval": i} for e, v, i in added], "verdict": verdict,
                "after": {"err_heldout": err}}

    s = {"hidden": ["plate_tilt", "servo_lag"], "outside": [],
         "truth": {"plate_tilt": {"tilt_x_deg": 0.6, "tilt_y_deg": 0.8}, "servo_lag": {"extra_lag_s": 0.03}}}
    tilt = ("plate_tilt", {"tilt_x_deg": 0.9, "tilt_y_deg": 1.2},  # length 1.5: ratio 1.5, on the edge
            {"tilt_x_deg": (0.5, 1.0), "tilt_y_deg": (0.7, 1.3)})
    lag = ("servo_lag", {"extra_lag_s": 0.02}, {"extra_lag_s": (0.01, 0.03)})
    sc = S.score(s, res([lag, tilt], err=3.0), twin_err=2.0)
    assert sc["right"] and sc["heldout_vs_twin"] == 1.5
    (t,) = sc["same_law"]  # the lag is not same-law: not scored for size
    assert t["effect"] == "plate_tilt" and t["size_ratio"] == pytest.approx(1.5) and t["within_1_5"] and t["covered"]
    sc = S.score(s, res([tilt]), twin_err=2.0)
    assert not sc["right"]  # one of two hidden effects missing
    one = {**s, "hidden": ["plate_tilt"], "truth": {"plate_tilt": s["truth"]["plate_tilt"]}}
    sc = S.score(one, res([("phase_offset", {"phase_offset": 0.1}, {"phase_offset": (0.05, 0.15)}), tilt]), 2.0)
    assert not sc["right"]  # the hidden effect added second
    sc = S.score(one, res([]), 2.0)
    assert not sc["right"] and sc["same_law"][0] == {"effect": "plate_tilt", "added": False, "size_ratio": None,
                                                     "within_1_5": False, "covered": False}
    out = {"hidden": [], "outside": ["arm_bias"], "truth": {}}
    assert S.score(out, res([], "unexplained residual"), None)["outside_reported"]
    assert not S.score(out, res([], "agrees within measurement error"), None)["outside_reported"]
    assert not S.score(out, res([lag], "unexplained residual"), None)["right"]


def test_smx_synth_set_makes_data_with_the_changed_model_and_the_sidecar_says_so(tmp_path):
    """Data made with --set robot.arm_length=0.055 carry it in their sidecar, so the loader compares them
    with the same changed model; a bad field is one line, exit 2, and no folder."""
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    run = CliRunner()
    out = tmp_path / "d"
    r = run.invoke(app, ["synth", str(out), "--amplitudes", "30", "--trials", "1", "--periods", "1",
                         "--set", "robot.arm_length=0.055"])
    assert r.exit_code == 0, r.output
    side = json.loads(next(out.glob("*.json")).read_text())
    assert side["overrides"] == {"robot.arm_length": 0.055}
    assert load(out)[0].params.robot.arm_length == 0.055
    r = run.invoke(app, ["synth", str(tmp_path / "e"), "--set", "robot.wheels=3"])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and not (tmp_path / "e").exists()


def test_a_servos_timing_is_no_hypothesis_without_arm_tracks_and_none_where_the_delay_test_rules_it_out(monkeypatch):
    """Body motion alone cannot tell a servo's timing from another servo law: without any tracked arm angle
    a lag or dead time is not tried; with arms, only the delay test's 'no constant excess' rules it out.
    The stress suite's counterfactual switch (``--servo-without-arms``) lifts the first rule only."""
    import types
    from smarticle_mjx.calibrate.observables import DelayTest
    from smarticle_mjx.calibrate.stages import NO_ARMS, servo_skip_reason
    nan = float("nan")
    undecided = DelayTest((), (), (), nan, nan, nan, nan, False, False)
    none_found = DelayTest((20.0, 60.0), (0.1, 0.2), (1.0, 1.0), 0.1, 0.5, 0.1, 0.5, True, False, True)
    body_only = [types.SimpleNamespace(arms=None), types.SimpleNamespace(arms=np.full((5, 1, 2), np.nan))]
    tracked = [types.SimpleNamespace(arms=None), types.SimpleNamespace(arms=np.zeros((5, 1, 2)))]
    assert servo_skip_reason(body_only, undecided) == NO_ARMS
    assert servo_skip_reason(body_only, none_found) == NO_ARMS
    assert servo_skip_reason(tracked, undecided) is None
    assert "no constant excess" in servo_skip_reason(tracked, none_found)
    from smarticle_mjx.calibrate import policy
    monkeypatch.setattr(policy, "SERVO_WITHOUT_ARMS", True)
    assert servo_skip_reason(body_only, undecided) is None
    assert servo_skip_reason(tracked, undecided) is None
    assert "no constant excess" in servo_skip_reason(tracked, none_found)


@pytest.mark.parametrize("constant_ms, tried", [(-3.0, False), (4.0, True)])
def test_a_delay_test_reading_its_constant_below_zero_rules_a_servo_timing_out(constant_ms, tried):
    """A lag or dead time only adds to the arm's delay: an undecided delay test (two amplitudes 1.5x apart,
    so the constant's standard error is 7 ms) whose constant reads below zero rules both out (version
    0.4.16); one that reads above zero, as undecided, leaves them to the fit. Built arm delays, not a
    model's: the data's delay exceeds the model's by ``constant_ms`` plus 20 ms per radian of amplitude."""
    import types
    from smarticle_mjx.calibrate.observables import delay_test
    from smarticle_mjx.calibrate.stages import servo_skip_reason
    amps = (40.0, 60.0)
    model = {"arm_delay_ms": [{"gait": k, "amplitude_deg": a, "mean": 30.0 + 0.4 * a, "se": 0.0}
                              for k, a in enumerate(amps)]}
    data = {"arm_delay_ms": [{"gait": k, "amplitude_deg": a, "se": 0.0,
                              "mean": 30.0 + 0.4 * a + constant_ms + 20.0 * math.radians(a)}
                             for k, a in enumerate(amps)]}
    dtest = delay_test(data, model)
    assert dtest.constant_ms == pytest.approx(constant_ms)
    assert dtest.applicable and not dtest.constant_delay and not dtest.no_constant_delay  # undecided
    tracked = [types.SimpleNamespace(arms=np.zeros((5, 1, 2)))]
    reason = servo_skip_reason(tracked, dtest)
    if tried:
        assert reason is None
    else:
        assert "below zero" in reason and "no lag or dead time" in reason


def test_a_servo_timing_fitted_wholly_below_the_delay_floor_is_refused_whatever_it_gains():
    """The delay test calls a constant excess whose upper bound is below DELAY_MIN_MS no constant delay (two
    servo laws differ by a few ms); a fitted lag or dead time is held to the same floor: with the same large
    BIC and held-out gains, a 1.8 ms dead time whose interval ends at 3.4 ms is refused, one that reaches
    8 ms, or any other effect, is judged by the usual rule."""
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.stages import judged
    nan = float("nan")
    undecided = DelayTest((), (), (), nan, nan, nan, nan, False, False)
    gains = (1000.0, 900.0, 400, 4.0, 2.7, undecided)  # chi2 before/after, n, held-out before/after
    small = {"dead_time_s": (0.0002, 0.0034)}
    j, rule = judged(BY_NAME["servo_dead_time"], small, *gains)
    assert j.present and j.bic_gain > 0 and j.heldout_gain > 0.3 and not j.accepted and "floor" in rule
    j, rule = judged(BY_NAME["servo_dead_time"], {"dead_time_s": (0.0024, 0.0079)}, *gains)
    assert j.accepted and rule == "held-out gain"
    j, _ = judged(BY_NAME["servo_lag"], {"extra_lag_s": (0.0002, 0.0034)}, *gains)
    assert not j.accepted
    j, _ = judged(BY_NAME["phase_offset"], {"phase_offset": (0.0002, 0.0034)}, *gains)
    assert j.accepted  # not a timing in seconds: no floor
    assert DELAY_MIN_MS > 3.4


def test_a_servo_timing_started_absent_from_the_nulls_end_can_only_improve_on_it():
    """A joint fit is a trust-region least squares: every step it keeps lowers the training error. Started
    with the timing absent from the end of the fit without it, it therefore ends no worse in training than
    that fit, so the comparison of the two is between converged fits. Checked on a built problem whose
    residual a timing of 12 ms removes and on one that no timing helps, each started at the timing's null
    (``Effect.null``, the third start's value in ``stages.nominal_stage``: no lag, no dead time)."""
    import types
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.nominal import NOMINAL
    from smarticle_mjx.presets import params as preset_params
    ref = preset_params("lab-lag")
    params = tuple(p for p in NOMINAL if p.name in ("servo_speed", "servo_kp"))
    for name, key in (("servo_lag", "extra_lag_s"), ("servo_dead_time", "dead_time_s")):
        e = BY_NAME[name]
        start = e.null()
        assert start == {key: 0.0}

        for true in (0.012, 0.0):
            def vector_with(vals, eff, true=true):
                t = eff.as_dict().get(name, {}).get(key, 0.0)
                return np.array([(t - true) * 1e3, (vals["servo_speed"] - params[0].preset(ref)) * 10.0,
                                 (vals["servo_kp"] - params[1].preset(ref)) * 10.0])

            problem = types.SimpleNamespace(trials=[types.SimpleNamespace(params=ref)], vector_with=vector_with)
            fe = fit_nominal(problem, params, max_nfev=10, effect=e, effect_start=start)
            assert fe.err_after <= fe.err_before + 1e-12
            assert abs(fe.values[name][key] - true) < 1e-3


def test_a_third_start_that_keeps_its_timing_absent_gains_nothing_over_the_null_continued_beside_it():
    """The third start of a servo timing begins where the null's fit ended and runs the null's budget again.
    Where that fit had not converged, the third start goes on converging the nominal parameters: with the
    timing kept at its null it ends below its baseline by that alone, and judged against that baseline it
    passes the BIC (the stress suite's 2064/21: a lag at 0.03 ms, BIC gain 941). The null continued from the
    same start with the same budget (``stages.nominal_stage`` fits it beside the third starts) ends as low,
    and against it the timing gains nothing. Built: a curved valley in two servo parameters (a Rosenbrock
    residual, which ten trust-region steps from afar do not descend) and a timing nothing in the data needs."""
    from smarticle_mjx.calibrate.effects import BY_NAME, EffectSet
    from smarticle_mjx.calibrate.stages import judge
    from smarticle_mjx.presets import params as preset_params
    ref = preset_params("lab-lag")
    params = tuple(p for p in NOMINAL if p.name in ("servo_speed", "servo_kp"))
    e = BY_NAME["servo_lag"]

    def vector_with(vals, eff):
        x, y = (p.to_u(ref, vals[p.name]) * 4 - 2 for p in params)  # each in [-2, 2]
        lag = eff.as_dict().get("servo_lag", {}).get("extra_lag_s", 0.0)
        return np.array([10.0 * (y - x * x), 1.0 - x, lag * 1e3])

    problem = types.SimpleNamespace(trials=[types.SimpleNamespace(params=ref)], vector_with=vector_with)
    far = {p.name: p.from_u(ref, u) for p, u in zip(params, (0.05, 0.95))}
    base = fit_nominal(problem, params, max_nfev=10, start=far)
    assert base.err_after > 1e-3  # ten steps leave the valley's floor unreached
    end = {p.name: base.values[p.name] for p in params}
    third = fit_nominal(problem, params, max_nfev=10, effect=e, start=end, effect_start=e.null())
    continued = fit_nominal(problem, params, max_nfev=10, start=end)

    def chi2(fe, effects=()):
        v = vector_with({p.name: fe.values[p.name] for p in params},
                        EffectSet.of({k: fe.values[k] for k in effects}))
        return float(v @ v)

    n = 3 * 50  # as if each residual were 50 samples: k ln n stays below the convergence gain
    assert abs(third.values["servo_lag"]["extra_lag_s"]) < 1e-4
    assert chi2(third, ("servo_lag",)) < 0.5 * chi2(base)  # the third start went on down the valley
    iv = {"extra_lag_s": (0.001, 0.002)}  # present, so that only the baseline decides
    assert judge(e, iv, chi2(base) * 50, chi2(third, ("servo_lag",)) * 50, n, 1.0, 1.0).bic_gain > 0
    assert chi2(continued) <= chi2(third, ("servo_lag",)) + 1e-9
    assert judge(e, iv, chi2(continued) * 50, chi2(third, ("servo_lag",)) * 50, n, 1.0, 1.0).bic_gain <= 0


def test_a_hypothesis_is_fitted_a_third_time_only_where_its_best_start_ended_above_its_baseline():
    """A joint fit contains its null, so converged it ends no higher in training than the null's best fit;
    one that ended at or above it has not converged and gets a third start from that baseline's end (servo
    timings since version 0.4.5, plate hypotheses since 0.4.12). Built chi^2 values: the plate that ended
    above its baseline (the stress suite's 2142/22 shape) and the timing that ended level with its own are
    refitted, each from its own baseline; the ones below are not."""
    from smarticle_mjx.calibrate.stages import third_starts
    restart, nominal = {"plate_friction": 0.2}, {"plate_friction": 0.5}
    baselines = {"anisotropic_friction": (900.0, restart, "restarted"), "servo_lag": (1000.0, nominal, "nominal"),
                 "servo_dead_time": (1000.0, nominal, "nominal"), "arm_plate_contact": (800.0, nominal, "nominal")}
    ended = {"anisotropic_friction": 1721.0, "servo_lag": 1000.0, "servo_dead_time": 400.0,
             "arm_plate_contact": 799.9}
    got = third_starts(ended, baselines)
    assert set(got) == {"anisotropic_friction", "servo_lag"}
    assert got["anisotropic_friction"][0] is restart and got["servo_lag"] == (nominal, "nominal")
    assert third_starts({}, baselines) == {}


@pytest.mark.parametrize("true_ratio, want", [(1.0, 1.0), (0.45, 0.4), (2.2, 2.5)])
def test_a_plates_third_start_takes_the_grid_value_or_null_that_fits_best_at_the_baselines_end(true_ratio, want):
    """The third start of a plate hypothesis begins at its baseline's nominal values with the effect at
    whichever of its grid values and its null fits training best there: on a level isotropic plate the null
    (so the fit can only improve on the baseline), on a plate slipperier or rougher along one axis the grid
    value nearest in log ratio. Built: a residual that grows with the log distance to the true ratio, and is
    counted only at the nominal values it is asked at."""
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.stages import PLATE_GRIDS, plate_third_start
    e = BY_NAME["anisotropic_friction"]
    nom = {"plate_friction": 0.3}
    asked = []

    def vector_with(vals, eff):
        assert vals is nom
        r = eff.as_dict()["anisotropic_friction"]["friction_y_ratio"]
        return np.array([math.log(r / true_ratio), 0.1])

    train = types.SimpleNamespace(prefetch=asked.extend, vector_with=vector_with)
    got = plate_third_start(train, nom, e)
    assert got == {"friction_y_ratio": want}
    assert len(asked) == 1 + len(PLATE_GRIDS["anisotropic_friction"][1])  # the null and each grid value, once
    # where an earlier start ended nearer the truth, the third start begins there
    ended = [{"friction_y_ratio": true_ratio * 1.05}, {"friction_y_ratio": 1.0}]
    asked.clear()
    assert plate_third_start(train, nom, e, ended) == ({"friction_y_ratio": 1.0} if true_ratio == 1.0 else ended[0])
    assert len(asked) == 2 + len(PLATE_GRIDS["anisotropic_friction"][1])  # the null is not asked twice


def test_the_noise_estimator_reads_white_noise_and_not_smooth_motion():
    """Third differences remove motion that is quadratic over four frames and leave white noise of s.d.
    sqrt(20) sigma: a smooth track (a body swinging 3 mm at 0.6 Hz with a drift, sampled at 60 Hz) reads
    under 2 % of a 0.3 mm noise, the same track with that noise reads it within 10 %, and a few sharp
    jerks (an arm starting) do not move the median."""
    from smarticle_mjx.calibrate.noise import robust_sigma, third_differences
    t = np.arange(0, 10, 1 / 60)
    smooth = 3.0 * np.sin(2 * np.pi * 0.6 * t) + 0.1 * t
    smooth[::40] += 0.5  # a jerk every 40 frames
    rng = np.random.default_rng(1)
    assert robust_sigma(third_differences(smooth)) < 0.02 * 0.3
    assert abs(robust_sigma(third_differences(smooth + rng.normal(0, 0.3, len(t)))) / 0.3 - 1) < 0.1
    x = smooth + rng.normal(0, 0.3, len(t))
    x[100:110] = np.nan  # occluded frames are skipped, not bridged
    assert len(third_differences(x)) == len(t) - 3 - 13
    assert math.isnan(robust_sigma(np.zeros(0)))


@pytest.mark.parametrize("fr,amp,xy,th,want", [
    (60, 90, 0.02, 0.02, (False, False)),  # a good tracker's noise: absent
    (30, 60, 0.3, 0.02, (True, False)),
    (60, 45, 0.02, 0.4, (False, True)),
    (30, 20, 0.3, 0.3, None),  # 11 frames per gait period: the test does not apply
])
def test_the_noise_test_finds_tracking_noise_in_another_simulators_tracks(tmp_path, fr, amp, xy, th, want):
    """On lone robots of the independent simulator (its own robot, servo and contacts): a noise level of
    0.3-0.4 mm or deg is found and read within 20 %, a good tracker's 0.02 is not, and a gait too fast for
    the frame rate is left to the fitted effects."""
    from smarticle_mjx.calibrate.noise import noise_test
    I.write_case(tmp_path, robots=1, amplitude_deg=amp, trials=2, periods=5, seed=4, frame_rate=fr, name="a",
                 noise_xy_mm=xy, noise_theta_deg=th)
    nt = noise_test(load(tmp_path))
    if want is None:
        assert nt.trials == () and not nt.present and "does not apply" in nt.reason
        return
    assert (nt.xy.present, nt.theta.present) == want and nt.present == any(want)
    for key, truth, found in (("xy", xy, want[0]), ("theta", th, want[1])):
        lv = getattr(nt, key)
        if found:
            assert abs(lv.level / truth - 1) < 0.2 and lv.lo <= lv.level <= lv.hi


def test_measured_noise_is_added_before_any_fit_and_held(tmp_path):
    """The noise stage adds tracking_noise at the measured level as the first effect, holds it, and every
    model's frame increments are compared with the data's with it (the Problem's own noise)."""
    from smarticle_mjx.calibrate.effects import LIBRARY, EffectSet
    from smarticle_mjx.calibrate.fit import Problem
    from smarticle_mjx.calibrate.stages import Model, noise_stage
    I.write_case(tmp_path, robots=1, amplitude_deg=90, trials=2, periods=5, seed=4, frame_rate=60, name="a",
                 noise_xy_mm=0.5, noise_theta_deg=0.02)
    trials = load(tmp_path)
    train, test, model = Problem(trials[:1]), Problem(trials[1:]), Model()
    nt = noise_stage(trials, train, test, LIBRARY, model, lambda m: None)
    assert nt.applies and nt.reading.present
    assert [e.name for e in model.chosen] == ["tracking_noise"] and "tracking_noise" in model.fixed
    assert train.noise == test.noise == (model.fixed["tracking_noise"]["noise_xy_mm"],
                                         model.fixed["tracking_noise"]["noise_theta_deg"])
    assert abs(train.noise[0] / 0.5 - 1) < 0.2
    # an effect set that fits its own noise overrides the measured one; one without noise uses it
    feats = train.meas
    assert EffectSet().noise() == (0.0, 0.0) and feats
    none = noise_stage(trials, Problem(trials[:1]), Problem(trials[1:]), (), Model(), lambda m: None)
    assert none.as_dict() == {"applies": False, "reason": "tracking_noise is not in the library"}


def test_jerky_motion_is_not_read_as_tracking_noise():
    """White noise's third differences correlate -0.75 with their neighbours (coefficients 1, -3, 3, -1);
    a motion with a random jerk every few frames (stick-slip) correlates positively. The correlation reads
    white noise within 0.05 and keeps a jerky track, however large its third differences, below the
    whiteness bound."""
    from smarticle_mjx.calibrate.noise import WHITE_RHO, _runs, lag1_correlation
    rng = np.random.default_rng(3)
    white = rng.normal(0, 0.3, 5000)
    assert abs(lag1_correlation(_runs(white)) + 0.75) < 0.05
    # a track that jumps by a random step every 3 frames, then rests: piecewise constant velocity kicks
    v = np.repeat(rng.normal(0, 0.3, 1700), 3)[:5000]
    jerky = np.cumsum(np.cumsum(v)) * 0.01
    assert lag1_correlation(_runs(jerky)) > WHITE_RHO + 0.1
    x = white.copy()
    x[2000:2010] = np.nan
    assert len(_runs(x)) == 2 and sum(len(r) for r in _runs(x)) == 5000 - 3 - 13


def _vis_set(hidden, gen, amps=(15,)):
    return {"suite_seed": 0, "index": 0, "build": I.DEFAULT.as_dict(), "hidden": list(hidden), "outside": [],
            "generator": dict(gen), "truth": {}, "amplitudes": list(amps), "chirality": "ccw",
            "frame_rate_hz": 60.0, "arms_tracked": True, "robots": 1, "trials_per_amplitude": 2, "periods": 3,
            "data_seed": 11}


def test_an_effects_visibility_is_what_leaving_it_out_costs_the_generator_itself():
    """calibrate.stress.visibility (run by benchmarks/calibration_visibility.py): the generator's own noise-free tracks fit its noisy data within
    measurement error (about 1), and leaving out a dead time raises that error by its signal, which grows
    with the dead time (at 15 deg a 40 ms dead time shifts the arm by about a quarter of its swing time);
    dropping an effect the set does not hide costs nothing."""
    from smarticle_mjx.calibrate.stress import visibility
    small = visibility(_vis_set(["servo_dead_time"], {"dead_s": 0.01}))
    large = visibility(_vis_set(["servo_dead_time"], {"dead_s": 0.04}))
    for m in (small, large):
        assert m["err_full"] < 2.0
    s_small, s_large = small["effects"]["servo_dead_time"]["signal"], large["effects"]["servo_dead_time"]["signal"]
    assert s_large > 10.0 and s_large > 4 * s_small > 0
    # a tilt that the set does not hide: removing it removes nothing
    none = visibility(_vis_set(["plate_tilt"], {"dead_s": 0.04}))
    assert none["effects"]["plate_tilt"]["signal"] == pytest.approx(0.0, abs=1e-9)


class _GridTrain:
    """A training problem whose chi^2 is a bowl in (log plate mu, log effect parameter) around a chosen
    point; it records what the grid asks for and has the default preset's plate (bounds 0.2-2x its mu)."""

    def __init__(self, effect, param, mu_best, value_best):
        from smarticle_mjx import presets
        self.trials = [types.SimpleNamespace(params=presets.params())]
        self.effect, self.param, self.mu_best, self.value_best = effect, param, mu_best, value_best
        self.fetched = []

    def prefetch(self, points):
        self.fetched += list(points)

    def vector_with(self, nom, eff):
        r = eff.as_dict()[self.effect][self.param]
        return np.array([math.log(nom["plate_friction"] / self.mu_best), math.log(r / self.value_best)])

    def prior_chi2(self, nom):
        return 0.0


def test_the_plate_hypothesis_starts_from_the_best_point_of_its_grid_over_mu_and_the_anisotropy():
    """calibrate.stages.plate_grid_start: every (mu factor, ratio) of the grid is run once and the point of
    lowest training chi^2 (priors included) is the joint fit's second start; here chi^2 is a bowl around
    mu = 0.1 and ratio 2.5 that the grid holds, so that point is returned, whatever the grid's order."""
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.stages import PLATE_GRID_MU, PLATE_GRID_RATIO, plate_grid_start

    t = _GridTrain("anisotropic_friction", "friction_y_ratio", 0.1, 2.5)
    nom, eff = plate_grid_start(t, {"plate_friction": 0.4, "servo_speed": 8.0}, BY_NAME["anisotropic_friction"])
    assert len(t.fetched) == len(PLATE_GRID_MU) * len(PLATE_GRID_RATIO)
    assert nom == {"plate_friction": pytest.approx(0.1), "servo_speed": 8.0}
    assert eff == {"friction_y_ratio": 2.5}


def test_the_counterfactual_plate_start_on_the_other_side_of_one(monkeypatch):
    """calibrate.stages.plate_grid_starts: by the rule the anisotropic plate has one grid start, the grid's
    best point; with ``PLATE_BOTH_SIDES`` (the stress suite's --plate-both-sides, a counterfactual tried on
    stored sets) it also starts from the best point whose ratio lies on the other side of 1 (a plate rougher
    along x instead of y), from the same grid runs, none more; here chi^2 is a bowl around ratio 2.5 at
    mu 0.1, so the other side's best point is the ratio nearest it below 1 (0.63) at that mu. Arms on the
    plate (a drag coefficient, no two sides) keep one start."""
    from smarticle_mjx.calibrate import stages
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.stages import PLATE_GRID_MU, PLATE_GRID_RATIO, plate_grid_starts

    t = _GridTrain("anisotropic_friction", "friction_y_ratio", 0.1, 2.5)
    assert len(plate_grid_starts(t, {"plate_friction": 0.4, "servo_speed": 8.0}, BY_NAME["anisotropic_friction"])) == 1
    monkeypatch.setattr(stages, "PLATE_BOTH_SIDES", True)
    t = _GridTrain("anisotropic_friction", "friction_y_ratio", 0.1, 2.5)
    starts = plate_grid_starts(t, {"plate_friction": 0.4, "servo_speed": 8.0}, BY_NAME["anisotropic_friction"])
    assert len(t.fetched) == len(PLATE_GRID_MU) * len(PLATE_GRID_RATIO)
    assert [eff for _, eff in starts] == [{"friction_y_ratio": 2.5}, {"friction_y_ratio": 0.63}]
    assert [nom["plate_friction"] for nom, _ in starts] == [pytest.approx(0.1), pytest.approx(0.1)]
    t = _GridTrain("anisotropic_friction", "friction_y_ratio", 0.2, 0.4)
    starts = plate_grid_starts(t, {"plate_friction": 0.4, "servo_speed": 8.0}, BY_NAME["anisotropic_friction"])
    assert [eff for _, eff in starts] == [{"friction_y_ratio": 0.4}, {"friction_y_ratio": 1.6}]
    t = _GridTrain("arm_plate_contact", "arm_plate_mu", 0.4, 0.25)
    assert len(plate_grid_starts(t, {"plate_friction": 0.4, "servo_speed": 8.0}, BY_NAME["arm_plate_contact"])) == 1


def test_the_arm_plate_hypothesis_grid_raises_the_plate_mu_and_stays_where_the_fit_can_start():
    """Arms dragging on the plate are mimicked by a slipperier plate, so the arm-plate grid also raises the
    nominal fit's mu (a bowl at 4x it and arm-plate mu 0.5 is found); grid points are held within the
    nominal fit's bounds (0.2-2x the preset's mu), so the returned start is one the joint fit can start
    from: a nominal mu at the lower bound is not halved below it."""
    from smarticle_mjx import presets
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.stages import PLATE_GRIDS, plate_grid_start

    e = BY_NAME["arm_plate_contact"]
    factors, values = PLATE_GRIDS["arm_plate_contact"]
    assert max(factors) > 1.0
    mu_preset = presets.params().plate_friction
    lo = 0.2 * mu_preset
    t = _GridTrain("arm_plate_contact", "arm_plate_mu", 4 * lo, 0.5)
    nom, eff = plate_grid_start(t, {"plate_friction": lo, "servo_speed": 8.0}, e)
    assert len(t.fetched) == len(factors) * len(values)
    assert nom == {"plate_friction": pytest.approx(4 * lo), "servo_speed": 8.0}
    assert eff == {"arm_plate_mu": 0.5}
    asked = [n["plate_friction"] for _, n in t.fetched]
    assert min(asked) == pytest.approx(lo) and max(asked) <= 2.0 * mu_preset + 1e-12


@pytest.mark.slow
def test_an_anisotropic_plate_under_a_robot_that_slides_unlike_the_model_is_named_with_the_nominal_fit(tmp_path):
    """Stress set 2030/22 (the case the joint plate hypothesis was built on, ~2 min): another simulator's
    robot slides far more than the library's (its clean twin is fitted with the plate's mu at ~0.09 for a
    true 0.33), so on a plate 2.4 times rougher along y the nominal fit alone stops near the preset mu,
    where the anisotropy changes nothing. Fitted jointly from the grid's start it is named, its interval
    holds the truth, and the held-out error falls to the clean twin's level (5.7), also against a null
    given the same start."""
    from smarticle_mjx.calibrate.stress import draw_set, write_set
    from smarticle_mjx.calibrate.stages import calibrate
    s = draw_set(2030, 22)
    write_set(s, tmp_path)
    res = calibrate(load(tmp_path)).summary
    assert [a["effect"] for a in res["added"]][:1] == ["anisotropic_friction"], res["verdict"]
    lo, hi = res["added"][0]["interval"]["friction_y_ratio"]
    assert lo <= s["truth"]["anisotropic_friction"]["friction_y_ratio"] <= hi
    assert res["after"]["err_heldout"] < 0.2 * res["after_nominal"]["err_heldout"]
    # it is judged against the nominal parameters restarted at the grid's mu, which alone take most of the
    # fall (held-out 48.8 -> 9.5): the anisotropy is named for what it adds to that, not for the restart
    (h,) = [h for h in res["nominal_hypotheses"] if h["effect"] == "anisotropic_friction"]
    assert h["baseline_err_heldout"] < 0.5 * res["after_nominal"]["err_heldout"]
    assert h["err_heldout"] < 0.8 * h["baseline_err_heldout"]


def _plate_groups(kind: str, seed: int, noise_mm: float = 0.003) -> list:
    """Three gaits, two tracks each at headings at least 90 deg apart, four cycle steps per track (mm), built
    without any model: each gait's body-frame step s turned by the heading, then on a plate slipperier along
    one axis (strength 0.3, axis 30 deg: step -> (1 + E) step, E symmetric and traceless) or tilted (one
    plate-frame vector, 0.6-1.4x as large in each gait: a tilt's drift scales with how the robot slides)."""
    rng = np.random.default_rng(seed)
    e = 0.3 * np.exp(2j * math.radians(30.0))
    groups = []
    for _ in range(3):
        s = 0.1 * rng.uniform(0.5, 1.5) * np.exp(1j * rng.uniform(0, 2 * np.pi))
        h0 = rng.uniform(-np.pi, np.pi)
        size = rng.uniform(0.6, 1.4)
        hs, ds = [], []
        for h_start in (h0, h0 + rng.uniform(np.pi / 2, 3 * np.pi / 2)):
            h = h_start + np.cumsum(rng.normal(0, 0.005, 4))
            z = s * np.exp(1j * h)
            if kind == "anisotropic":
                z = z + e * np.conj(z)  # E acting on a plate-frame vector, in complex numbers
            elif kind == "grip":  # mu (1 + 0.3 cos 2(h - 30 deg)) under the robot: a step shorter by about that
                z = z * (1.0 - 0.3 * np.cos(2 * (h - math.radians(30.0))))
            elif kind == "level":  # the same steps and headings (the same draws) on a level isotropic plate
                pass
            else:
                z = z + 0.05 * size * np.exp(0.7j)
            z = z + noise_mm * (rng.normal(size=4) + 1j * rng.normal(size=4))
            hs.append(h)
            ds.append(np.column_stack([z.real, z.imag]))
        groups.append((hs, ds))
    return groups


@pytest.mark.parametrize("seed", range(4))
def test_a_plate_slipperier_along_one_axis_drifts_with_the_robots_step_and_a_tilt_does_not(seed):
    """calibrate.drift.plate_drift_models, on steps built without any model: a plate slipperier along one
    axis stretches each step along that axis, so what the per-gait regression reads as drift follows each
    gait's own step and heading, and one anisotropy K (its strength and axis: 0.3 e^{i 60 deg}) fits every
    gait's drift better than one drift vector; a tilt's drift is one vector (whatever size each gait gives
    it), and one anisotropy fits it worse. Both drifts are far beyond the noise."""
    from smarticle_mjx.calibrate.drift import plate_drift_models
    a = plate_drift_models(_plate_groups("anisotropic", seed))
    assert a.groups == 3 and a.chi2_drift > 100
    assert a.follows_the_robot and a.chi2_anisotropy < 0.25 * a.chi2_one_vector
    k = complex(*a.anisotropy)
    assert abs(k) == pytest.approx(0.3, rel=0.35)
    assert abs(np.degrees(np.angle(k / np.exp(2j * math.radians(30.0))))) < 20
    t = plate_drift_models(_plate_groups("tilt", seed))
    assert t.groups == 3 and t.chi2_drift > 100
    assert not t.follows_the_robot and t.chi2_one_vector < t.chi2_anisotropy
    assert a.anisotropic and a.chi2_anisotropy < a.chi2_grip


@pytest.mark.parametrize("seed", range(12))
def test_the_drift_a_model_leaves_is_read_for_a_tilt_beside_a_step_following_drift_the_model_holds(seed):
    """calibrate.drift.plate_drift_models with ``offsets`` (since version 0.4.10), on steps built without any
    model. Arms dragging on the plate (or an anisotropic plate) make the drift each gait's regression reads
    follow the robot's own step; a tilt beside them adds one plate-frame vector. Read on the data alone, the
    step-following part wins and the tilt is stopped by the gate. A model that holds the drag reproduces the
    step-following part at the same headings; what it leaves is the tilt's one vector, which the reading
    beyond the model finds (one vector fits better than one anisotropy). A model that does not hold it
    (its drift on a level plate nil) leaves the data's own reading, step-following, unchanged; one that holds
    half the drag leaves a rest that still follows the step, which one drift vector does not fit."""
    from smarticle_mjx.calibrate.drift import plate_drift_beyond, plate_drift_models
    follow = _plate_groups("anisotropic", seed, noise_mm=0.0)  # noise-free: what a model with the drag gives
    rng = np.random.default_rng(100 + seed)
    tilt = 0.006 * np.exp(0.7j)  # mm/cycle, under the step-following part (0.3 of steps of 0.05-0.15 mm)

    def tracked(d):  # a tracker's error: each cycle position off by 1.5 um, each step the difference of two
        return d + np.diff(0.0015 * rng.normal(size=(len(d) + 1, 2)), axis=0)

    data = [(hs, [tracked(d + np.array([tilt.real, tilt.imag])) for d in ds]) for hs, ds in follow]
    own = plate_drift_models(data)
    beyond = plate_drift_beyond(data, follow)
    assert own.groups == beyond.groups == 3
    assert own.follows_the_robot  # the data alone: the step-following part dominates, a tilt would be stopped
    assert not beyond.follows_the_robot and beyond.chi2_one_vector < 0.5 * beyond.chi2_anisotropy
    assert beyond.chi2_drift > 30  # the tilt is well beyond the noise in what the model leaves
    assert beyond.p_one_vector > 1e-3  # one vector fits what the model leaves
    nil = [(np.zeros(2), np.zeros((2, 2)))] * 3
    again = plate_drift_models(data, offsets=nil)
    assert again.follows_the_robot and again.chi2_one_vector == pytest.approx(own.chi2_one_vector)
    # a model holding half the drag leaves half the step-following drift (the regression is linear in the
    # steps, and R(h) s itself leaves none): one vector does not fit that rest, one anisotropy does
    level = _plate_groups("level", seed, noise_mm=0.0)  # the same robots' steps on a level isotropic plate
    half_model = [(hs, [0.5 * (d + d0) for d, d0 in zip(ds, ds0)]) for (hs, ds), (_, ds0) in zip(follow, level)]
    no_tilt = [(hs, [tracked(d) for d in ds]) for hs, ds in follow]
    half = plate_drift_beyond(no_tilt, half_model)
    assert half.follows_the_robot and half.p_one_vector < 0.05


@pytest.mark.parametrize("seed", range(4))
def test_a_grip_that_depends_on_the_heading_fits_its_own_model_better_than_an_anisotropy(seed):
    """calibrate.drift.PlateDrift.chi2_grip, on steps built without any model: a plate whose grip under a
    robot depends on the robot's heading (mu (1 + e cos 2h), outside the library) shortens or lengthens
    each step along itself; what the per-gait regression reads as drift then fits one such grip (two
    coefficients for every gait) better than one anisotropy, so it is not called anisotropic."""
    from smarticle_mjx.calibrate.drift import plate_drift_models
    g = plate_drift_models(_plate_groups("grip", seed))
    assert g.groups == 3 and g.chi2_drift > 100
    assert g.chi2_grip < 0.5 * g.chi2_anisotropy and not g.anisotropic


@pytest.mark.slow
def test_arms_dragging_on_the_plate_are_named_with_the_nominal_fit_when_asked(tmp_path):
    """``plate_hypotheses`` with arm_plate_contact (off by default: docs/calibration.md). Stress set 2031/12 (one of the sets the joint arm-plate hypothesis was built on, ~1 min): another
    simulator's robot whose arms rest on the plate with mu 0.40. Fitted alone, the nominal parameters mimic
    the arms' drag with a slipperier plate (mu at the bound of its range) and the arm-plate mu fitted after
    them gains nothing (held-out 68 against the clean twin's 4.5). Fitted jointly from a grid that also
    raises the plate's mu, the drag is named first and the held-out error falls to within about twice the
    clean twin's, against a null given the same start."""
    from smarticle_mjx.calibrate.stress import draw_set, write_set
    from smarticle_mjx.calibrate.stages import calibrate
    s = draw_set(2031, 12)
    write_set(s, tmp_path)
    res = calibrate(load(tmp_path), plate_hypotheses=("anisotropic_friction", "arm_plate_contact")).summary
    assert res["plate_hypotheses"] == ["anisotropic_friction", "arm_plate_contact"]
    assert [a["effect"] for a in res["added"]][:1] == ["arm_plate_contact"], res["verdict"]
    (h,) = [h for h in res["nominal_hypotheses"] if h["effect"] == "arm_plate_contact"]
    assert h["accepted"] and h["err_heldout"] < 0.8 * h["baseline_err_heldout"]
    assert res["after"]["err_heldout"] < 0.3 * res["after_nominal"]["err_heldout"]


def test_smx_calibrate_refuses_an_unknown_plate_hypothesis_in_one_line_and_writes_nothing(tmp_path):
    """A joint plate hypothesis the calibration does not have is a usage error: one line, exit 2, no report
    folder, whatever the data (checked before they are read)."""
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    out = tmp_path / "report"
    r = CliRunner().invoke(app, ["calibrate", str(tmp_path), "--out", str(out), "--plate-hypothesis", "plate_tilt"])
    assert r.exit_code == 2
    assert "no joint plate hypothesis" in r.output and "'plate_tilt'" in r.output
    assert not out.exists()
    from smarticle_mjx.calibrate.stages import calibrate
    with pytest.raises(ValueError, match="no joint plate hypothesis"):
        calibrate([], plate_hypotheses=("friction_scale",))


class _TwoEffects:
    """A fake problem whose residuals are linear in a dead time and a phase offset: 30 residuals
    (dead time - truth) / 1 ms and 30 of (offset - truth) / 0.002 period, each plus unit noise; the
    nominal parameters move nothing. What the fit and the rule see of two effects, without a model run."""

    def __init__(self, params, dead, phase, seed):
        self.trials = [types.SimpleNamespace(params=params)]
        self.priors = {}
        self.noise = np.random.default_rng(seed).normal(0.0, 1.0, 60)
        self.dead, self.phase = dead, phase

    def vector_with(self, values, eff):
        d = eff.as_dict()
        dt = d.get("servo_dead_time", {}).get("dead_time_s", 0.0)
        ph = d.get("phase_offset", {}).get("phase_offset", 0.0)
        return np.concatenate([np.full(30, (dt - self.dead) / 0.001), np.full(30, (ph - self.phase) / 0.002)]) + self.noise

    def prior_chi2(self, nominal):
        return 0.0


@pytest.mark.parametrize("phase", [0.1, 0.0])
def test_a_second_joint_hypothesis_beside_the_accepted_one_is_named_only_where_it_is_there(phase):
    """calibrate.stages.second_hypothesis: after a dead time was accepted in the nominal stage, a phase
    offset that is in the data (0.1 period) is fitted jointly with it and added, both sizes recovered; where
    the data have none, it is tried and not added. A lag is never tried beside a dead time (two readings of
    one servo's timing). fit_nominal takes the two effects at once."""
    from smarticle_mjx import presets
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.stages import second_hypothesis

    params = presets.params()
    train, test = _TwoEffects(params, 0.02, phase, 1), _TwoEffects(params, 0.02, phase, 2)
    dead, lag, off = BY_NAME["servo_dead_time"], BY_NAME["servo_lag"], BY_NAME["phase_offset"]
    fe1 = fit_nominal(train, effect=dead, max_nfev=10)
    assert fe1.values["servo_dead_time"]["dead_time_s"] == pytest.approx(0.02, abs=1e-3)
    nom0 = {p.name: p.preset(params) for p in NOMINAL}
    nom1 = {k: fe1.values[k] for k in fe1.preset}
    best = (fe1, 0.5, dead, nom1, {"dead_time_s": fe1.interval["dead_time_s"]})
    tasks = [("servo_lag", lag, nom0, None), ("phase_offset", off, nom0, {"phase_offset": 0.05})]
    # started from where the first pass's own fits ended (the offset fitted alone, from 0.05)
    fe_off = fit_nominal(train, effect=off, max_nfev=10, effect_start={"phase_offset": 0.05})
    first = {"servo_dead_time": fe1, "phase_offset": fe_off, "servo_lag": fe1}
    second = second_hypothesis(train, test, tasks, best, nom0, 60, types.SimpleNamespace(constant_delay=True),
                               lambda msg: None, None, first)
    assert [t.effect for t in second.tried] == ["phase_offset"]
    assert second.tried[0].beside == "servo_dead_time"
    if phase:
        assert second.effect is off
        assert second.fit.values["phase_offset"]["phase_offset"] == pytest.approx(0.1, abs=0.002)
        assert second.fit.values["servo_dead_time"]["dead_time_s"] == pytest.approx(0.02, abs=1e-3)
    else:
        assert second.effect is None and not second.tried[0].accepted


class _HiddenDeadTime(_TwoEffects):
    """As ``_TwoEffects``, but the dead time's 30 residuals are a well around the truth, flat farther than
    ~8 ms from it (10 (1 - exp(-((dt - truth) / 5 ms)^2))), with a small pull toward 0 s (0.05 per ms): from
    0 s, where a fit that did not see the well ends, no local step finds it."""

    def vector_with(self, values, eff):
        d = eff.as_dict()
        dt = d.get("servo_dead_time", {}).get("dead_time_s", 0.0)
        ph = d.get("phase_offset", {}).get("phase_offset", 0.0)
        well = 10.0 * (1.0 - np.exp(-(((dt - self.dead) / 0.005) ** 2))) + 0.05 * dt / 0.001
        return np.concatenate([np.full(30, well), np.full(30, (ph - self.phase) / 0.002)]) + self.noise


@pytest.mark.parametrize("constant_delay", [True, False])
def test_a_second_servo_timing_starts_at_the_delay_tests_reading_where_it_reads_a_constant(constant_delay):
    """calibrate.stages.second_hypothesis (version 0.4.15): a phase offset was accepted first and the dead
    time's own first-pass fit ended at 0 s (as on fresh stress set 2144/2, where the nominal servo had taken
    it up). Where the delay test reads a constant delay (27 ms here, the truth), the dead time is started
    there too, finds its well and is added beside the offset at its size; without that reading it is
    started only where its first pass ended and stays at 0 s, not added."""
    from smarticle_mjx import presets
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.stages import START_DELAY_READING, delay_reading_start, second_hypothesis

    params = presets.params()
    train, test = _HiddenDeadTime(params, 0.027, 0.1, 1), _HiddenDeadTime(params, 0.027, 0.1, 2)
    dead, lag, off = BY_NAME["servo_dead_time"], BY_NAME["servo_lag"], BY_NAME["phase_offset"]
    fe_off = fit_nominal(train, effect=off, max_nfev=10, effect_start={"phase_offset": 0.05})
    assert fe_off.values["phase_offset"]["phase_offset"] == pytest.approx(0.1, abs=0.002)
    fe_dead = fit_nominal(train, effect=dead, max_nfev=10, effect_start={"dead_time_s": 0.0})
    assert fe_dead.values["servo_dead_time"]["dead_time_s"] < 0.002  # the first pass's fit, stuck at 0 s
    nom0 = {p.name: p.preset(params) for p in NOMINAL}
    nom1 = {k: fe_off.values[k] for k in fe_off.preset}
    best = (fe_off, 0.5, off, nom1, {"phase_offset": fe_off.interval["phase_offset"]})
    tasks = [("servo_dead_time", dead, nom0, None), ("phase_offset", off, nom0, {"phase_offset": 0.05})]
    dtest = types.SimpleNamespace(constant_delay=constant_delay, constant_ms=27.0)
    assert delay_reading_start(off, dtest) is None
    assert delay_reading_start(lag, dtest) == ({"extra_lag_s": 0.027} if constant_delay else None)
    second = second_hypothesis(train, test, tasks, best, nom0, 60, dtest, lambda msg: None, None,
                               {"phase_offset": fe_off, "servo_dead_time": fe_dead})
    assert [t.effect for t in second.tried] == ["servo_dead_time"]
    got = second.tried[0].values["dead_time_s"]
    assert second.tried[0].starts == (3 if constant_delay else 2)
    if constant_delay:
        assert second.tried[0].start == START_DELAY_READING
        assert second.effect is dead
        assert got == pytest.approx(0.027, abs=1e-3)
        assert second.fit.values["phase_offset"]["phase_offset"] == pytest.approx(0.1, abs=0.002)
    else:
        assert second.effect is None and got < 0.002


def _servo_tracks(gait, speed, frame_hz, dead_s=0.0, lag_s=0.0, periods=5):
    """Arm angles [F, 2] at ``frame_hz`` of a servo that follows the gait's slewed setpoints at ``speed``,
    late by ``dead_s`` or through a first-order lag ``lag_s`` (integrated exactly on a 10 us grid) — built
    with numpy, not by any model of the package."""
    fine = np.arange(0.0, periods * gait.period(), 1e-5)
    sp = np.asarray(gait.setpoints(fine - dead_s, speed))
    if lag_s:  # y[i] = sp[i] + (y[i-1] - sp[i]) exp(-dt / lag), from y[0] = sp[0]
        from scipy.signal import lfilter
        keep = math.exp(-1e-5 / lag_s)
        sp = lfilter([1.0 - keep], [1.0, -keep], sp, axis=0, zi=keep * sp[:1])[0]
    t = np.arange(0.0, periods * gait.period(), 1.0 / frame_hz)
    return t, np.stack([np.interp(t, fine, sp[:, k]) for k in range(2)], 1)


def test_the_arm_rise_tells_a_lag_from_a_dead_time_and_from_a_slower_servo():
    """observables.swing_rise_groups: the time from a quarter to three quarters of a swing. On a slewed
    ramp it is the amplitude over the speed; a dead time leaves it so; a first-order lag lengthens it, by
    what the closed form of a ramp through a lag gives, and the more the shorter the swing (11 ms at 15 deg,
    under 1 ms at 90 deg for 30 ms); a slower servo lengthens it in proportion to the amplitude."""
    from scipy.optimize import brentq
    from smarticle_mjx.calibrate.observables import swing_rise_groups
    from smarticle_mjx.gait import GaitSpec

    w, tau = 8.7, 0.03

    def rise(g, **kw):
        x, grp = swing_rise_groups(*_servo_tracks(g, kw.pop("speed", w), 120.0, **kw), g)
        assert len(x) >= 12 and set(grp) == {0, 1, 2, 3}
        return float(np.mean(x))

    # closed form on a swing from rest (a long dwell): -a + w (t - tau (1 - exp(-t/tau))) while the ramp runs
    # (2a / w), then an exponential approach to +a
    slow_gait = GaitSpec(amplitude_deg=15, period_s=1.6)
    a = slow_gait.amplitude
    tm = 2 * a / w
    y_tm = -a + w * (tm - tau * (1 - math.exp(-tm / tau)))

    def y(t):
        return -a + w * (t - tau * (1 - math.exp(-t / tau))) if t <= tm else a - (a - y_tm) * math.exp(-(t - tm) / tau)

    closed = brentq(lambda t: y(t) - a / 2, 0, 1) - brentq(lambda t: y(t) + a / 2, 0, 1)
    assert rise(slow_gait, lag_s=tau) == pytest.approx(closed, abs=0.5e-3)
    assert rise(slow_gait) == pytest.approx(a / w, abs=1e-6)
    excess = {}
    for amp in (15, 90):
        g = GaitSpec(amplitude_deg=amp)
        ramp = rise(g)
        assert ramp == pytest.approx(g.amplitude / w, abs=1e-6)
        assert rise(g, dead_s=tau) == pytest.approx(ramp, abs=1e-6)
        excess[amp] = (rise(g, lag_s=tau) - ramp, rise(g, speed=7.0) - ramp)
    assert excess[15][0] > 0.008 and excess[90][0] < 0.001  # a lag: long at 15 deg, nearly none at 90
    assert excess[90][1] / excess[15][1] == pytest.approx(6.0, rel=0.01)  # a slower servo: in proportion


def test_the_arm_rise_reads_a_lag_or_a_dead_time_and_chooses_between_two_that_passed():
    """observables.servo_reading on the rise's excess split as constant + slope x amplitude: a constant
    above RISE_LAG_MS (a lag lengthening the short swings' rise) reads a lag, one below it (a servo law
    unlike the model's growing with the amplitude) a dead time, one amplitude nothing. stages.servo_choice
    keeps the reading's hypothesis where both passed, marks the other refused, and leaves a lone servo
    hypothesis or a set without a reading to the held-out gain."""
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.observables import RISE_LAG_MS, servo_reading
    from smarticle_mjx.calibrate.stages import Hypothesis, servo_choice

    def rise(amps, excess):
        meas = {"arm_rise_ms": [{"gait": f"{a}", "amplitude_deg": float(a), "mean": 50.0 + e, "se": 0.1, "n": 30}
                                for a, e in zip(amps, excess)]}
        model = {"arm_rise_ms": [{"gait": f"{a}", "amplitude_deg": float(a), "mean": 50.0, "se": 0.1, "n": 30}
                                 for a in amps]}
        return delay_test(meas, model, "arm_rise_ms")

    amps = [15, 40, 75]
    slope = [20.0 * math.radians(a) for a in amps]  # a servo slower than the model's: in proportion
    lag = rise(amps, [RISE_LAG_MS + 6.0 + s_ for s_ in slope])
    assert lag.constant_ms == pytest.approx(RISE_LAG_MS + 6.0) and servo_reading(lag) == "servo_lag"
    assert servo_reading(rise(amps, [1.0 + s_ for s_ in slope])) == "servo_dead_time"
    assert servo_reading(rise([40], [12.0])) is None
    lag_e, dead_e, off_e = BY_NAME["servo_lag"], BY_NAME["servo_dead_time"], BY_NAME["phase_offset"]
    passed = [("fit-lag", 0.30, lag_e), ("fit-dead", 0.35, dead_e), ("fit-off", 0.2, off_e)]
    hyps = [Hypothesis(name, True, True) for name in ("servo_lag", "servo_dead_time", "phase_offset")]
    kept, marked = servo_choice(passed, hyps, "servo_lag", lambda m: None)
    assert [c[2].name for c in kept] == ["servo_lag", "phase_offset"]
    assert marked[1].accepted is False and "reads a lag" in marked[1].reason and marked[0].accepted
    assert marked[1].as_json()["reason"] == marked[1].reason and hyps[1].accepted  # a new entry, not mutated
    assert servo_choice(passed, hyps, None, lambda m: None) == (passed, hyps)
    assert servo_choice(passed[1:], hyps, "servo_lag", lambda m: None) == (passed[1:], hyps)


def _wobbling_pair(offset, seed, amplitude_deg=40.0, frame_hz=60.0, periods=5, noise_deg=0.3):
    """A two-robot trial built with numpy: each robot turns steadily and wobbles with the gait (two
    harmonics of the period), robot 1 running ``offset`` periods ahead; headings read with Gaussian noise."""
    from smarticle_mjx import presets
    from smarticle_mjx.calibrate.data import Trial
    from smarticle_mjx.gait import GaitSpec
    g = GaitSpec(amplitude_deg=amplitude_deg, period_s=1.6 * amplitude_deg / 90.0)
    T = g.period()
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, periods * T, 1.0 / frame_hz)
    pose = np.zeros((len(t), 2, 3))
    for i, rate in enumerate((0.11, -0.07)):  # different steady rotations (rad/s): taken out
        ph = 2 * np.pi * (t / T + i * offset)
        pose[:, i, 0], pose[:, i, 1] = 0.3 * i, 0.0
        pose[:, i, 2] = rate * t + 0.05 * np.sin(ph) + 0.02 * np.sin(2 * ph + 0.7) + rng.normal(
            0.0, math.radians(noise_deg), len(t))
    return Trial(f"pair{seed}", t, pose, None, g, presets.params(), frame_hz)


@pytest.mark.parametrize("offset", [0.08, 0.0, -0.15])
def test_a_phase_offset_is_read_off_the_robots_own_heading_wobble_and_tested_against_none(offset):
    """calibrate.phase.offset_test: robots of one build on one gait wobble alike in time, each with its own
    steady rotation; a robot whose gait runs ahead wobbles ahead by as much. Read pair by pair from the
    heading alone (no arm tracked), the offset is recovered within 0.005 period and called present; in phase,
    the pairs' mean is within its t interval of zero and the offset is called absent (not fitted)."""
    from smarticle_mjx.calibrate.phase import offset_test
    trials = [_wobbling_pair(offset, s) for s in range(4)]
    ot = offset_test(trials)
    assert ot.source == "heading" and ot.n == 4
    assert ot.mean == pytest.approx(offset, abs=0.005)
    if offset:
        assert ot.present and not ot.absent
        assert ot.sd >= 0.005  # never narrower than what a reading of an offset missed the truth by
        assert ot.interval[0] < offset < ot.interval[1]
    else:
        assert ot.absent and not ot.present
    assert offset_test([_wobbling_pair(offset, 0)]).applicable is False  # one pair: no spread, no verdict


def test_a_measured_effect_value_is_held_in_the_joint_fit():
    """nominal.fit_nominal with ``problem.effect_fixed``: a phase offset measured without the model (0.07,
    interval [0.06, 0.08]) is held at that value and reported with that interval, beside a dead time that
    is still fitted; without it the fit follows the data (offset 0.1, dead time 20 ms)."""
    from smarticle_mjx import presets
    from smarticle_mjx.calibrate.effects import BY_NAME

    params = presets.params()
    both = (BY_NAME["servo_dead_time"], BY_NAME["phase_offset"])
    free, held = _TwoEffects(params, 0.02, 0.1, 3), _TwoEffects(params, 0.02, 0.1, 3)
    held.effect_fixed = {"phase_offset": (0.07, (0.06, 0.08))}
    f0 = fit_nominal(free, effect=both, max_nfev=10, effect_start={"phase_offset": 0.05})
    f1 = fit_nominal(held, effect=both, max_nfev=10, effect_start={"phase_offset": 0.05})
    assert f0.values["phase_offset"]["phase_offset"] == pytest.approx(0.1, abs=0.002)
    assert f1.values["phase_offset"]["phase_offset"] == 0.07
    assert tuple(f1.interval["phase_offset"]) == (0.06, 0.08)
    for f in (f0, f1):
        assert f.values["servo_dead_time"]["dead_time_s"] == pytest.approx(0.02, abs=1e-3)


def test_an_offset_measured_clear_of_zero_is_added_first_whatever_its_fit_gains_held_out():
    """stages.measured_structure and first_choice with phase.OffsetTest.established: an offset read off the
    robots' curves whose reported interval (spread and the reading's 0.005-period floor) excludes zero is
    accepted although its joint fit lost 10 % held out, and is added before a plate that gained 60 %; a
    reading that is present by Student's t but within what the reading may miss by is judged by the fit
    as before; other hypotheses keep their judgement."""
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.phase import OffsetTest
    from smarticle_mjx.calibrate.stages import MEASURED_OFFSET, Judgement, first_choice, measured_structure

    clear = OffsetTest("heading", 0.0978, 0.0253, 4, 3.18)   # 2047/6's reading: interval [0.047, 0.148]
    small = OffsetTest("arms", 0.008, 0.001, 6, 2.57)        # present by t, inside 1.96 x hypot(se, 0.005)
    assert clear.present and clear.established and clear.interval[0] > 0
    assert small.present and not small.established
    refused = Judgement(304.0, -0.10, True, False)
    j, rule = measured_structure("phase_offset", clear, refused, "held-out gain")
    assert j.accepted and rule == MEASURED_OFFSET
    j, rule = measured_structure("phase_offset", small, refused, "held-out gain")
    assert not j.accepted and rule == "held-out gain"
    assert measured_structure("anisotropic_friction", clear, refused, "held-out gain") == (refused, "held-out gain")
    off, plate = BY_NAME["phase_offset"], BY_NAME["anisotropic_friction"]
    passed = [(None, 0.60, plate, {}, {}), (None, -0.10, off, {}, {})]
    assert first_choice(passed, clear)[2] is off
    assert first_choice(passed, small)[2] is plate
    assert first_choice([], clear) is None


def test_arms_read_dragging_are_added_where_their_fit_sizes_them_without_losing_held_out():
    """stages.measured_structure and first_choice with armdrag.DragTest.present: arms on the plate read off the
    body's turning between kicks (seed 2048's set 26: 32 deg/s, p ~ 0) are accepted where their joint fit's
    interval is clear of no drag, although the fit gained only 16 % held out (under the 20 % rule), but not
    where the fit loses held out (seed 2050's set 1: an outside grip read as a drag, -4 %); a fit that sizes
    them absent, an undecided or absent reading, and other hypotheses keep their judgement; a measured
    offset still goes first, a read drag before a plate that gained more."""
    from smarticle_mjx.calibrate.armdrag import DragTest
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.phase import OffsetTest
    from smarticle_mjx.calibrate.stages import (ARM_PLATE, MEASURED_DRAG, MEASURED_OFFSET, Judgement,
                                                first_choice, measured_structure)

    read = DragTest(8, 900.0, 1e-80, 32.0, 58.0, 1.5)
    undecided = DragTest(4, 14.0, 0.0014, 16.0, 20.0, 6.0)   # 2048/2's first reading: not present
    absent = DragTest(12, 10.0, 0.6, 0.1, 0.3, 0.05)
    assert read.present and undecided.undecided and absent.absent
    sized = Judgement(120.0, 0.16, True, False)     # present in its fit, refused by the held-out rule
    unsized = Judgement(-3.0, 0.02, False, False)   # its fit's interval reaches no drag
    j, rule = measured_structure(ARM_PLATE, None, sized, "held-out gain", drag=read)
    assert j.accepted and rule == MEASURED_DRAG
    assert measured_structure(ARM_PLATE, None, unsized, "held-out gain", drag=read) == (unsized, "held-out gain")
    loses = Judgement(5906.0, -0.04, True, False)
    j, rule = measured_structure(ARM_PLATE, None, loses, "held-out gain", drag=read)
    assert not j.accepted and rule == MEASURED_DRAG
    for other in (undecided, absent, None):
        assert measured_structure(ARM_PLATE, None, sized, "held-out gain", drag=other) == (sized, "held-out gain")
    assert measured_structure("anisotropic_friction", None, sized, "held-out gain", drag=read) == (sized, "held-out gain")
    arm, plate, off = BY_NAME[ARM_PLATE], BY_NAME["anisotropic_friction"], BY_NAME["phase_offset"]
    passed = [(None, 0.60, plate, {}, {}), (None, 0.16, arm, {}, {})]
    assert first_choice(passed, None, read)[2] is arm
    assert first_choice(passed, None, undecided)[2] is plate
    clear = OffsetTest("heading", 0.0978, 0.0253, 4, 3.18)
    assert first_choice(passed + [(None, -0.1, off, {}, {})], clear, read)[2] is off
    assert measured_structure("phase_offset", clear, sized, "x", drag=read)[1] == MEASURED_OFFSET


def test_a_tilt_is_not_named_where_the_gaits_drifts_follow_the_robots_step():
    """stages.tilt_accepted: the drift stage's tilt is named where it is clear of zero, takes half the
    drift's chi^2 and the gaits' drifts point one way, and (since seed 2051) not where they follow the
    robot's own step as a plate slipperier along one axis makes them (seed 2049's set 11, a grip that
    depends on the heading: chi2 0.4 as one anisotropy against 75.5 as one drift vector)."""
    from smarticle_mjx.calibrate.stages import tilt_accepted
    base = {"ok": True, "chi2_before": 80.0, "chi2_after": 6.0}
    assert tilt_accepted(base, 40.0, True, False)
    assert not tilt_accepted(base, 40.0, True, True)
    assert not tilt_accepted(base, 40.0, False, False)
    assert not tilt_accepted(base, 3.0, True, False)
    assert not tilt_accepted({**base, "chi2_after": 50.0}, 40.0, True, False)
    assert not tilt_accepted({"ok": False}, 40.0, True, False)


def test_the_plate_level_gate_tries_an_anisotropic_plate_only_where_the_drift_shows_a_plate():
    """stages.plate_skip_reason: an anisotropic plate is a heading dependence of the robot's step. It is
    withheld where the plate-frame drift test reads the trials (dof > 0) and finds no drift even at the 5 %
    level, and (since version 0.4.18) where no gait's headings span enough to read them (dof 0, p NaN):
    there nothing in the data tells the plate from a robot that slides unlike the model's. Only a drift
    read and found lets it be fitted."""
    from smarticle_mjx.calibrate.drift import MIN_SPREAD_DEG
    from smarticle_mjx.calibrate.stages import P_LEVEL, plate_skip_reason
    assert P_LEVEL == 0.05
    assert "p = 0.7" in plate_skip_reason({"dof": 4, "p": 0.7})
    assert plate_skip_reason({"dof": 4, "p": P_LEVEL}) is not None
    assert plate_skip_reason({"dof": 4, "p": 0.01}) is None
    assert plate_skip_reason({"dof": 2, "p": 1e-9}) is None
    for unread in ({"dof": 0, "p": float("nan")}, {}):
        why = plate_skip_reason(unread)
        assert why is not None and "cannot be read" in why and f"{MIN_SPREAD_DEG:g} deg" in why


def test_a_plate_rougher_along_one_axis_shows_in_the_drift_and_a_level_isotropic_one_does_not(tmp_path):
    """The independent robot (another simulator's, not the library's) on a plate twice as rough along y as
    along x: its step stretches differently at each start heading, which the model-free drift test reads
    (p ~1e-29 here), so the gate lets the anisotropic plate be fitted; the same robot, starts and gaits on a
    level isotropic plate drift at p ~0.75, and the gate withholds it. (At other starts a plate as rough
    shows less: seed 300 drifts at p 0.31 and would be withheld; docs/calibration.md counts that price.)"""
    from smarticle_mjx.calibrate.drift import drift_test
    from smarticle_mjx.calibrate.stages import plate_skip_reason
    for name, kw in (("aniso", dict(friction_y_ratio=2.0)), ("level", {})):
        d = tmp_path / name
        for a in (40, 90):
            I.write_case(d, amplitude_deg=float(a), name=f"a{a}", trials=3, periods=5, seed=100 + a, **kw)
        res = drift_test(load(d))
        assert res["dof"] == 4
        if name == "aniso":
            assert res["p"] < 1e-6 and plate_skip_reason(res) is None, res["p"]
        else:
            assert res["p"] > 0.2 and "level and isotropic" in plate_skip_reason(res), res["p"]


def test_no_anisotropic_plate_is_fitted_to_a_clean_set_whose_drift_shows_a_level_plate(tmp_path):
    """Stress set 2058/13 (another simulator's robot, nothing hidden, bodies only at 120 Hz): without the
    gate the anisotropic plate, fitted jointly with the nominal parameters, gained 38 % held out and was
    named (ratio 0.73), taking up how the library's robot slides unlike this one. Its plate-frame drift is
    at p 0.75: the plate is not tried, the report says why, and nothing is added."""
    from smarticle_mjx.calibrate.stress import draw_set, write_set
    from smarticle_mjx.calibrate import report
    from smarticle_mjx.calibrate.stages import calibrate
    s = draw_set(2058, 13)
    assert not s["hidden"] and not s["outside"]
    write_set(s, tmp_path / "data")
    trials = load(tmp_path / "data")
    cal = calibrate(trials)
    res = cal.summary
    assert res["added"] == [], res["verdict"]
    assert res["plate_level"]["p"] > 0.05 and not res["plate_level"]["anisotropic_plate_tried"]
    (h,) = [h for h in res["nominal_hypotheses"] if h["effect"] == "anisotropic_friction"]
    assert not h["tried"] and "level and isotropic" in h["reason"]
    assert "anisotropic_friction" not in res["plate_hypotheses"]
    from smarticle_mjx.calibrate.heldout import compare_heldout
    report.write(cal, compare_heldout(cal, trials), tmp_path / "report")
    assert "An anisotropic plate was not tried" in (tmp_path / "report" / "report.md").read_text()


def test_the_stress_suite_refuses_a_model_change_without_a_tag_or_with_a_bad_field_and_writes_nothing():
    """A stress run with a changed model (--set) is kept apart from the suite's own results: without --tag,
    or with a field the model does not have, it stops in one line before anything is written."""
    import subprocess
    script = BENCHMARKS / "calibration_stress.py"
    folder = BENCHMARKS / "results" / "calibration_stress"
    before = sorted(p.name for p in folder.iterdir())
    for args, msg in ((["--set", "integrator=discrete"], "--set needs --tag"),
                      (["--set", "integratr=discrete", "--tag", "x"], "unknown scene field 'integratr'")):
        r = subprocess.run([sys.executable, str(script), "--suite-seed", "987654", "--sets", "0", *args],
                           capture_output=True, text=True)
        assert r.returncode == 2
        assert msg in r.stderr.strip().splitlines()[-1]
    assert sorted(p.name for p in folder.iterdir()) == before


def test_the_tilt_noise_reading_leaves_out_the_tracking_noise_and_nothing_else():
    from smarticle_mjx.calibrate import stress as S
    s = next(S.draw_set(2047, i) for i in range(60) if "tracking_noise" in S.draw_set(2047, i)["hidden"])
    w = S.without_noise(s)
    assert not set(S.NOISE_KEYS) & set(w["generator"])
    assert {k: v for k, v in s["generator"].items() if k not in S.NOISE_KEYS} == w["generator"]
    assert {k: v for k, v in s.items() if k != "generator"} == {k: v for k, v in w.items() if k != "generator"}


def test_the_calibrations_model_runs_the_discrete_integrator_unless_set_and_synth_makes_data_the_same_way(
        tmp_path):
    """The calibration compares lone robots, whose bodies move by each arm move's slip; with the discrete
    integrator that slip is converged at the preset's step (tests/test_physics.py checks the fact), so the
    calibration's model runs it unless --set names the integrator, and smx synth makes data with it."""
    from smarticle_mjx.calibrate.data import NUMERICS, with_numerics
    from smarticle_mjx.calibrate.synth import synth
    from smarticle_mjx.scene import SceneParams
    assert dict(NUMERICS)["integrator"] == "discrete" != SceneParams().integrator
    path = _file(tmp_path, SIDE)
    assert load(path)[0].params.integrator == "discrete"
    assert load(path, overrides=("integrator=implicitfast",))[0].params.integrator == "implicitfast"
    assert with_numerics((("plate_friction", 0.2),)) == (("integrator", "discrete"), ("plate_friction", 0.2))
    (csv,) = synth(tmp_path / "s", trials=1, periods=1, amplitudes=(60.0,), seed=1)
    side = json.loads(csv.with_suffix(".json").read_text())
    assert "integrator" not in (side.get("overrides") or {})  # the data record the robot, not the numerics
    assert load(csv)[0].params.integrator == "discrete"


def test_the_stress_split_by_condition_takes_the_first_condition_a_draw_meets():
    """The report's split (not a rule): a timing without arm tracks is 'body only' before anything else; a
    lag behind a stepped reference next (a dead time behind one is not); a tilt beside tracking noise
    before an outside effect; an anisotropic plate only where nothing earlier applies; clean sets and
    outside-only sets have no condition; by_condition counts right and held-out per condition."""
    from smarticle_mjx.calibrate import stress as S
    base = {"hidden": [], "outside": [], "arms_tracked": True, "build": {"servo_slew": 8.0}}

    def c(**kw):
        return S.condition({**base, **kw})

    names = list(S.CONDITIONS)
    assert c() is None and c(outside=["arm_bias"]) is None
    assert c(hidden=["servo_lag"], arms_tracked=False, build={"servo_slew": None}, outside=["arm_bias"]) == names[0]
    assert c(hidden=["servo_dead_time"], arms_tracked=False) == names[0]
    assert c(hidden=["plate_tilt"], arms_tracked=False) == names[5]  # body only matters for a timing
    assert c(hidden=["servo_lag"], build={"servo_slew": None}) == names[1]
    assert c(hidden=["servo_dead_time"], build={"servo_slew": None}) == names[5]
    assert c(hidden=["tracking_noise", "plate_tilt"], outside=["heading_friction"]) == names[2]
    assert c(hidden=["anisotropic_friction"], outside=["heading_friction"]) == names[3]
    assert c(hidden=["anisotropic_friction", "phase_offset"]) == names[4]
    assert c(hidden=["servo_lag"]) == names[5]
    rows = [{"set": {**base, "hidden": h}, "score": {"right": r, "heldout_vs_twin": x}}
            for h, r, x in ((["servo_lag"], True, 1.2), (["servo_lag"], False, 2.0), (["plate_tilt"], True, None),
                            (["anisotropic_friction"], False, 1.5), ([], True, None))]
    by = S.by_condition(rows)
    assert by[names[5]] == {"sets": 3, "right": 2, "heldout_within_1_5_of_twin": 1, "with_twin": 2}
    assert by[names[4]] == {"sets": 1, "right": 0, "heldout_within_1_5_of_twin": 1, "with_twin": 1}
    assert sum(v["sets"] for v in by.values()) == 4


def test_the_stress_split_by_effect_counts_what_was_added_and_scores_only_the_librarys_laws(tmp_path):
    """The per-effect table (a report, not a rule): a servo timing is split by how it was recorded (arms and
    the servo's reference, or body only), every other effect is not; an effect counts as added wherever it
    was added, first or not; size and coverage count over added same-law effects only, and a lag (not the
    library's law) has none. Pooling reads whole seeds' stored summaries and names a missing seed."""
    from smarticle_mjx.calibrate import stress as S

    def row(hidden, added, same_law=(), arms=True, slew=8.0):
        return {"set": {"hidden": hidden, "arms_tracked": arms, "build": {"servo_slew": slew}},
                "score": {"added": added, "same_law": [{"effect": e, "added": e in added, "within_1_5": w,
                                                        "covered": c} for e, w, c in same_law]}}

    rows = [row(["servo_dead_time"], ["servo_dead_time"], [("servo_dead_time", True, False)]),
            row(["servo_dead_time"], [], [("servo_dead_time", False, False)], slew=None),
            row(["servo_dead_time"], [], [("servo_dead_time", False, False)], arms=False),
            row(["servo_lag", "plate_tilt"], ["plate_tilt", "servo_lag"], [("plate_tilt", False, True)]),
            row(["plate_tilt"], ["tracking_noise"], [("plate_tilt", False, False)], arms=False)]
    by = S.by_effect(rows)
    assert by[("servo_dead_time", "arms, slewed reference")] == {"hidden": 1, "added": 1, "within_1_5": 1,
                                                                  "covered": 0}
    assert by[("servo_dead_time", "arms, stepped reference")]["added"] == 0
    assert by[("servo_dead_time", "body only")]["hidden"] == 1
    assert by[("servo_lag", "arms, slewed reference")] == {"hidden": 1, "added": 1, "within_1_5": None,
                                                            "covered": None}
    assert by[("plate_tilt", "")] == {"hidden": 2, "added": 1, "within_1_5": 0, "covered": 1}
    assert "| plate_tilt | - | 2 | 1 | 0 | 1 |" in S.effect_table(rows)
    (tmp_path / "calibration_stress_5.json").write_text(json.dumps({"rows": rows[:2]}))
    (tmp_path / "calibration_stress_6.json").write_text(json.dumps({"rows": rows[2:]}))
    assert S.pooled_rows("5-6", tmp_path) == rows
    with pytest.raises(FileNotFoundError, match="suite seed 7"):
        S.pooled_rows("5-7", tmp_path)


def test_the_stress_speed_table_counts_sets_by_their_trials_against_five_minutes():
    """The speed split (a report): sets grouped by their trial count (amplitudes x trials per amplitude),
    each group's median and slowest calibration wall time, and how many ran within 300 s (300 s itself
    is within)."""
    from smarticle_mjx.calibrate import stress as S

    def row(amps, per, wall):
        return {"set": {"amplitudes": amps, "trials_per_amplitude": per}, "wall_s": wall}

    rows = [row([15, 40, 60, 90], 2, 100.0), row([15, 40], 4, 300.0), row([15, 40, 60, 90], 2, 451.0),
            row([15, 40], 2, 20.0)]
    by = S.by_trials(rows)
    assert list(by) == [4, 8]
    assert by[8] == {"sets": 3, "median_s": 300.0, "slowest_s": 451.0, "within_5_min": 2}
    assert by[4] == {"sets": 1, "median_s": 20.0, "slowest_s": 20.0, "within_5_min": 1}
    assert "| 8 | 3 | 300 s | 451 s | 2 |" in S.speed_table(rows)


def test_the_stress_pool_reads_stored_results_only_and_refuses_in_one_line():
    import subprocess
    script = BENCHMARKS / "calibration_stress.py"
    for args, msg in ((["--pool", "2073"], "--pool needs --summary"),
                      (["--summary", "--pool", "987654"], "no stored summary for suite seed 987654"),
                      (["--summary", "--pool", "2049-x"], "not a list of numbers and ranges: '2049-x'"),
                      (["--suite-seed", "987654", "--sets", "0,a"], "not a list of numbers and ranges: '0,a'")):
        r = subprocess.run([sys.executable, str(script), *args], capture_output=True, text=True)
        assert r.returncode == 2 and msg in r.stderr.strip().splitlines()[-1]


@pytest.mark.parametrize("true_ratio", [4.0, 0.2])
def test_an_effect_that_ends_on_the_librarys_bound_away_from_its_null_gets_a_one_sided_interval(true_ratio):
    """Least squares inside bounds stops on a bound where the data want more than the library allows: an
    anisotropic plate rougher along one axis than the ratio 3.0 allows (or slipperier than 0.3). The data
    then say the effect is at least that large, so its 95 % interval runs from the Gauss-Newton spread
    inward to the bound and excludes the isotropic plate (``is_present``); until version 0.4.13 it had no
    interval there, and a clear plate was refused (stress set 2143/1). Built: a residual linear in the log
    ratio with 1 % noise-free scatter per sample, so the inward end is known in closed form, and two servo
    parameters the data pin at their presets."""
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.policy import is_present
    from smarticle_mjx.calibrate.stages import at_library_bound
    from smarticle_mjx.presets import params as preset_params
    ref = preset_params("lab-lag")
    params = tuple(p for p in NOMINAL if p.name in ("servo_speed", "servo_kp"))
    e = BY_NAME["anisotropic_friction"]
    q = e.params[0]
    slope = 20.0  # residual per unit of ln ratio, each of 50 samples

    def vector_with(vals, eff):
        r = eff.as_dict().get("anisotropic_friction", {}).get("friction_y_ratio", 1.0)
        data = np.full(50, slope * math.log(r / true_ratio)) + 0.01 * np.sin(np.arange(50))
        return np.concatenate([data, [(vals[p.name] - p.preset(ref)) * 10.0 for p in params]])

    problem = types.SimpleNamespace(trials=[types.SimpleNamespace(params=ref)], vector_with=vector_with)
    fe = fit_nominal(problem, params, max_nfev=20, effect=e)
    bound = q.hi if true_ratio > 1 else q.lo
    assert fe.values["anisotropic_friction"]["friction_y_ratio"] == pytest.approx(bound, rel=0.02)
    lo, hi = fe.interval["friction_y_ratio"]
    assert np.isfinite([lo, hi]).all()
    inward, at = (lo, hi) if true_ratio > 1 else (hi, lo)
    assert at == pytest.approx(bound)
    # closed form: sd of ln r = sqrt(red / (50 slope^2)), red = chi^2 / (n - k) at the bound
    n_res = 52
    chi2 = 50 * (slope * math.log(bound / true_ratio)) ** 2
    sd = math.sqrt(max(1.0, chi2 / (n_res - 3)) / (50 * slope ** 2))
    assert 0.01 < 1.96 * sd < 0.5 * abs(math.log(bound))  # an interval short of the isotropic plate
    assert math.log(inward) == pytest.approx(math.log(bound) - math.copysign(1.96 * sd, math.log(bound)),
                                             abs=0.1 * 1.96 * sd)
    assert is_present(e, {"friction_y_ratio": (lo, hi)})
    assert at_library_bound(e, fe.values["anisotropic_friction"]) == ["friction_y_ratio"]


def test_an_effect_at_its_null_on_a_bound_gets_no_interval():
    """A servo dead time the data do not want ends at 0 s, which is both its null and the library's lower
    bound: there the effect is absent, and no one-sided interval is made for it (it would say "at least
    nothing"). Built: a residual that only a negative dead time would lower."""
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.policy import is_present
    from smarticle_mjx.calibrate.stages import at_library_bound
    from smarticle_mjx.presets import params as preset_params
    ref = preset_params("lab-lag")
    params = tuple(p for p in NOMINAL if p.name in ("servo_speed", "servo_kp"))
    e = BY_NAME["servo_dead_time"]

    def vector_with(vals, eff):
        t = eff.as_dict().get("servo_dead_time", {}).get("dead_time_s", 0.0)
        return np.concatenate([np.full(50, (t + 0.01) * 1e3),
                               [(vals[p.name] - p.preset(ref)) * 10.0 for p in params]])

    problem = types.SimpleNamespace(trials=[types.SimpleNamespace(params=ref)], vector_with=vector_with)
    fe = fit_nominal(problem, params, max_nfev=20, effect=e, effect_start={"dead_time_s": 0.02})
    assert fe.values["servo_dead_time"]["dead_time_s"] < 1e-3
    assert not np.isfinite(fe.interval["dead_time_s"]).any()
    assert not is_present(e, {"dead_time_s": fe.interval["dead_time_s"]})
    assert at_library_bound(e, fe.values["servo_dead_time"]) == []


def test_the_counterfactual_swapped_split_trains_on_the_odd_trials(monkeypatch):
    """calibrate.stages.calibrate: by the rule the first, third, ... trials train and the others are held out;
    with ``SPLIT_SWAPPED`` (the stress suite's --swapped-split, a reading of how much a calibration depends
    on which half is held out) the odd trials train. The trials' order reaches the Problem built for each
    half, recorded here before the calibration goes on (stopped there)."""
    from smarticle_mjx.calibrate import stages

    class Stop(Exception):
        pass

    made = []

    def problem(trials):
        made.append([tr.name for tr in trials])
        if len(made) == 2:
            raise Stop
        return types.SimpleNamespace(trials=trials)

    trials = [types.SimpleNamespace(name=f"t{i}") for i in range(4)]
    monkeypatch.setattr(stages, "read_offsets", lambda trials: types.SimpleNamespace(present=False))
    monkeypatch.setattr(stages, "Problem", problem)
    for swapped, train in ((False, ["t0", "t2"]), (True, ["t1", "t3"])):
        made.clear()
        monkeypatch.setattr(stages, "SPLIT_SWAPPED", swapped)
        with pytest.raises(Stop):
            stages.calibrate(trials)
        assert made[0] == train and sorted(made[0] + made[1]) == ["t0", "t1", "t2", "t3"]


def test_the_split_reading_compares_the_sets_stored_both_ways_and_a_two_fold_gain(tmp_path):
    """calibrate.stress.split_compare (run by benchmarks/calibration_split.py) on rows built here: a set is compared only where stored both ways;
    the same effects added, right on each split, and a joint hypothesis's gain at the 20 % bar on each split
    and on their mean (0.3 and 0.15 -> mean 0.225 passes; 0.3 and 0.05 -> 0.175 does not) are counted by
    whether the set hides the effect."""
    from smarticle_mjx.calibrate import stress as S

    def row(i, hidden, added, right, gains):
        return {"set": {"index": i, "hidden": hidden, "outside": []}, "score": {"added": added, "right": right},
                "hypotheses": [{"effect": e, "tried": True, "heldout_gain": g} for e, g in gains.items()]}

    aniso = "anisotropic_friction"
    rule = {0: row(0, [aniso], [aniso], True, {aniso: 0.3}), 1: row(1, [], [], True, {aniso: 0.3}),
            2: row(2, [], [], True, {})}
    swapped = {0: row(0, [aniso], [], False, {aniso: 0.15}), 1: row(1, [], [], True, {aniso: 0.05})}
    for k, r in rule.items():
        (tmp_path / "a").mkdir(exist_ok=True)
        (tmp_path / "a" / f"set_{k:04d}.json").write_text(json.dumps(r))
    assert S.stored_rows(tmp_path / "a") == rule and S.stored_rows(tmp_path / "none") == {}
    lines = S.split_compare(rule, swapped)
    assert [x["index"] for x in lines] == [0, 1]
    s = S.split_summary(lines)
    assert s["by_kind"]["library effects"] == {"sets": 1, "same_added": 0, "right_rule": 1, "right_swapped": 0,
                                               "right_both": 0}
    assert s["by_kind"]["clean"]["same_added"] == 1 and s["by_kind"]["clean"]["right_both"] == 1
    assert s["gain_at_bar"][aniso]["hidden"] == {"tried": 1, "rule": 1, "swapped": 0, "mean": 1}
    assert s["gain_at_bar"][aniso]["not hidden"] == {"tried": 1, "rule": 1, "swapped": 0, "mean": 0}


def test_every_counterfactual_of_the_stress_suite_changes_a_rule_the_calibration_has():
    """benchmarks/calibration_stress.py's counterfactual flags each set one of calibrate.policy's or
    calibrate.stages' own switches (a misspelt name would set a new attribute that no rule reads, and the run
    would be the rule's, unnoticed), and each changes its value from the rule's; a switch set through
    apply_counterfactual is the one the rule reads."""
    import importlib

    from smarticle_mjx.calibrate import policy
    from smarticle_mjx.calibrate import stress as S

    assert len(S.COUNTERFACTUALS) == len({c[0] for c in S.COUNTERFACTUALS}) >= 4
    for flag, _, module, name, value in S.COUNTERFACTUALS:
        mod = importlib.import_module(f"smarticle_mjx.calibrate.{module}")
        assert hasattr(mod, name), flag
        assert getattr(mod, name) != value, flag
    before = policy.P_LEVEL
    try:
        S.apply_counterfactual("policy", "P_LEVEL", float("inf"))
        assert policy.plate_skip_reason({"dof": 4, "p": 0.99}) is None  # the gate reads the switch
    finally:
        policy.P_LEVEL = before
    assert policy.plate_skip_reason({"dof": 4, "p": 0.99}) is not None


def test_the_invariants_refuse_an_effect_that_raises_the_held_out_error_or_ended_on_its_bound():
    """Over every rule (policy.invariants): an accepted hypothesis whose held-out gain is below zero is refused
    whatever test proposed it (a measured offset, a servo after the delay test); one whose size ended on its
    bound away from its null is reported at its bound and refused; a dead time ending at 0 s (its null's own
    bound) or one inside its range keeps its judgement."""
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.policy import AT_BOUND, RAISES_HELDOUT, Judgement, at_bound, floor_note, invariants
    aniso, dead = BY_NAME["anisotropic_friction"], BY_NAME["servo_dead_time"]
    (pa,), (pd,) = aniso.params, dead.params
    ok = Judgement(50.0, 0.3, True, True)
    inside = {pa.name: 0.5 * (pa.lo + pa.hi)}
    assert invariants(aniso, inside, ok, "held-out gain") == (ok, "held-out gain")
    lost = Judgement(50.0, -0.02, True, True)
    j, rule = invariants(aniso, inside, lost, "measured")
    assert not j.accepted and rule == RAISES_HELDOUT and "raises the held-out error" in floor_note(rule)
    top = {pa.name: pa.hi}
    assert at_bound(aniso, top) == [pa.name]
    j, rule = invariants(aniso, top, ok, "held-out gain")
    assert not j.accepted and rule == AT_BOUND and "bound" in floor_note(rule)
    assert at_bound(dead, {pd.name: pd.null}) == []  # absent at its own bound: nothing claimed
    refused = Judgement(50.0, -0.5, True, False)
    assert invariants(aniso, top, refused, "held-out gain") == (refused, "held-out gain")  # only acceptances change


def test_an_effect_taken_out_again_leaves_the_model_as_before_it():
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.stages import FinalGuard, Model
    m = Model()
    m.add(BY_NAME["servo_lag"], {"lag_s": 0.02}, {"lag_s": (0.01, 0.03)})
    m.base = {"servo_lag": {"lag_s": 0.02}}
    m.add(BY_NAME["plate_tilt"], {"tilt_x_deg": 1.0, "tilt_y_deg": 0.0}, {})
    m.base = {**m.base, "plate_tilt": {"tilt_x_deg": 1.0, "tilt_y_deg": 0.0}}
    m.fixed["plate_tilt"] = m.base["plate_tilt"]
    m.drop("plate_tilt")
    assert [e.name for e in m.chosen] == ["servo_lag"] and set(m.base) == {"servo_lag"} and not m.fixed
    assert set(m.found) == {"servo_lag"}
    g = FinalGuard(12.0, 9.0, ("servo_lag",))
    from smarticle_mjx.calibrate.report import final_guard_markdown
    text = "\n".join(final_guard_markdown(g.as_dict()))
    assert "(servo_lag)" in text and "to 12," in text and "own 9;" in text and "none is kept" in text
    assert final_guard_markdown(None) == []


def test_a_drift_named_tilt_that_raises_the_held_out_error_is_not_kept(tmp_path):
    """Stress set 2147/22 (another simulator's robot with a tilted plate): the model-free drift test names a
    tilt, but with it the held-out error rises (15.3 -> 17.1: the model's tilt does not carry the drift to
    the held-out trials). Whatever test proposed it, an effect that raises the held-out error is not kept:
    the tilt is refused by that invariant, the report says so, and the final held-out error is not above
    the nominal fit's. (Here the hidden effect was the tilt: the invariant costs this set its right answer,
    which the closed-loop issue's item 2, a judgement beyond the robot's misfit, is to win back.)"""
    from smarticle_mjx.calibrate import report
    from smarticle_mjx.calibrate.policy import RAISES_HELDOUT
    from smarticle_mjx.calibrate.stages import calibrate
    from smarticle_mjx.calibrate.stress import draw_set, write_set
    s = draw_set(2147, 22)
    assert s["hidden"] == ["plate_tilt"]
    write_set(s, tmp_path / "data")
    cal = calibrate(load(tmp_path / "data"))
    r = cal.summary
    th, tf = r["drift"]["tilt_heldout"], r["drift"]["tilt_fit"]
    assert th["rose"] and tf["refused"] == RAISES_HELDOUT and not tf["accepted"]
    assert "plate_tilt" not in [a["effect"] for a in r["added"]] and "plate_tilt" not in cal.added
    assert r["after"]["err_heldout"] <= r["after_nominal"]["err_heldout"]
    text = "\n".join(report.drift_markdown(r["drift"], r["plate_level"]))
    assert "**It rose**" in text and "so the tilt was not kept" in text
