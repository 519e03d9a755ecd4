"""Calibration on data the library's model did not make: an independent MuJoCo smarticle
(smarticle_mjx/calibrate/independent.py), plus the data checks that come before any simulation."""

import ast
import json
import math
import pathlib

import numpy as np
import pytest
from typer.testing import CliRunner

from smarticle_mjx.calibrate import independent as I
from smarticle_mjx.calibrate import nominal as N
from smarticle_mjx.calibrate.data import load
from smarticle_mjx.calibrate.fit import Problem, conventions, split
from smarticle_mjx.calibrate.stages import calibrate
from smarticle_mjx.cli import app
from smarticle_mjx.gait import GaitSpec



def test_the_independent_generator_imports_nothing_from_the_library():
    tree = ast.parse(pathlib.Path(I.__file__).read_text())
    names = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    names |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert not any("smarticle_mjx" in x for x in names) and {"mujoco", "numpy"} <= names


@pytest.mark.parametrize("chirality", ["ccw", "cw"])
def test_both_gaits_reach_the_same_corners_from_the_documented_conventions(chirality):
    # two implementations written apart (the library's ramps, the generator's corners) agree at every
    # quarter's end: the interchange format's conventions are stated well enough to be followed
    g = GaitSpec(amplitude_deg=40.0, chirality=chirality, period_s=1.0)
    for q in range(4):
        t_end = (q + 1) * 0.25 - 1e-6
        lib = np.degrees(g.setpoints(t_end, speed=8.727))
        ind = np.degrees(I.corner(q * 0.25 + 0.01, math.radians(40.0), 1.0, chirality))
        assert np.allclose(lib, ind, atol=1e-3), (q, lib, ind)


def test_the_independent_robot_follows_its_gait_and_a_lag_delays_it():
    t = np.arange(0, 2 * 0.4, 1 / 200)
    clean = I.simulate(1, np.zeros((1, 3)), 15.0, 0.4, t[-1], t)
    lag = I.simulate(1, np.zeros((1, 3)), 15.0, 0.4, t[-1], t, lag_s=0.03)
    # arm 1 reaches -15 deg in the first quarter; with a 30 ms lag it is still short of it when the quarter ends
    q_end = np.searchsorted(t, 0.099)
    assert np.degrees(clean[q_end, 0, 3]) == pytest.approx(-15, abs=1.5)
    assert np.degrees(lag[q_end, 0, 3]) > -13
    assert np.isfinite(clean).all() and np.abs(clean[:, 0, :2]).max() < 0.01  # a lone robot stays put


def _two_robots_close(tmp_path, arms=False):
    rows = ["trial,t,robot,x,y,theta,alpha1,alpha2"]
    for tr in range(2):
        for k in range(5):
            for i in range(2):
                a = ",0.1,0.1" if arms else ",,"
                rows.append(f"{tr},{k * 0.05},{i},{0.06 * i},0,0{a}")
    (tmp_path / "pair.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "pair.json").write_text(json.dumps({"robots": 2, "gait": {"amplitude_deg": 60}}))
    return tmp_path / "pair.csv"


def test_data_with_nothing_to_compare_are_refused_before_any_simulation(tmp_path, monkeypatch):
    import smarticle_mjx.calibrate.fit as F

    def no_sim(*a, **k):
        raise AssertionError("simulated")
    monkeypatch.setattr(F, "simulate_trials", no_sim)
    path = _two_robots_close(tmp_path)
    with pytest.raises(ValueError, match="nothing to compare"):
        calibrate(load(path))
    r = CliRunner().invoke(app, ["calibrate", str(path), "--out", str(tmp_path / "out")])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and "nothing to compare" in r.output
    assert not (tmp_path / "out").exists()


def test_a_circular_boundary_in_the_sidecar_becomes_the_models_wall(tmp_path):
    path = _two_robots_close(tmp_path, arms=True)
    side = json.loads(path.with_suffix(".json").read_text())
    side["boundary"] = {"radius": 0.3, "centre": [0.5, -0.2]}
    path.with_suffix(".json").write_text(json.dumps(side))
    trials = load(path)
    assert trials[0].params.boundary_radius == 0.3
    # positions are measured from the boundary's centre
    assert np.allclose(trials[0].pose[0, :, :2], [[-0.5, 0.2], [-0.44, 0.2]])
    side["boundary"] = {"centre": [0, 0]}
    path.with_suffix(".json").write_text(json.dumps(side))
    with pytest.raises(ValueError, match="boundary needs a radius"):
        load(path)


def _independent(tmp_path, **kw):
    I.write_case(tmp_path, trials=4, periods=4, seed=3, **kw)
    return load(tmp_path)


def test_swapped_arm_columns_are_reported_in_one_line(tmp_path):
    trials = _independent(tmp_path)
    for tr in trials:
        tr.arms = tr.arms[..., ::-1].copy()
    conv = conventions(Problem(split(trials)[0]))
    assert conv["warning"] and "arms swapped" in conv["warning"]
    assert conv["alternatives"]["arms swapped"] * 4 < conv["declared"]


def test_a_clock_a_quarter_period_off_is_reported(tmp_path):
    trials = _independent(tmp_path)
    for tr in trials:
        tr.t = tr.t + tr.gait.period() / 4  # the data's t = 0 is a quarter period after the gait's start
    conv = conventions(Problem(split(trials)[0]))
    assert conv["warning"] and "quarter period earlier" in conv["warning"]


def test_correct_conventions_raise_no_warning_on_independent_data(tmp_path):
    conv = conventions(Problem(split(_independent(tmp_path))[0]))
    assert conv["warning"] is None
    assert conv["declared"] * 100 < min(conv["alternatives"].values())


def test_robots_with_their_own_gaits_are_replayed_each_with_its_own(tmp_path):
    """Two independent robots far apart, one at 20 deg ccw (period 0.36 s), the
    other at 45 deg cw (0.8 s), the sidecar listing both gaits. Replayed, each
    robot's arms follow its own commanded gait as the independent robot's do:
    arm RMS error within 5 deg for each (measured 1.1 and 3.4 deg: the other
    simulator's servo slews more slowly at 45 deg). Read with robot 0's gait
    for both, robot 1 is off by ~39 deg; the conventions check, whose
    alternative is every robot's chirality reversed, stays quiet."""
    from smarticle_mjx.calibrate.sim import simulate_trials
    I.write_case(tmp_path, robots=2, gaits=[(20.0, "ccw"), (45.0, "cw")], trials=2, periods=3, seed=3)
    trials = load(tmp_path)
    assert [g.chirality for g in trials[0].gaits] == ["ccw", "cw"]
    tracks = simulate_trials(trials, scene_for=lambda tr: tr.params)
    err = np.concatenate([np.degrees(tr.arms - trk[..., 3:]) for tr, trk in zip(trials, tracks)])
    rms = np.sqrt(np.nanmean(err ** 2, axis=(0, 2)))
    assert (rms < 5).all(), rms
    one = [_one_gait(tr) for tr in trials]
    wrong = simulate_trials(one, scene_for=lambda tr: tr.params)
    err1 = np.concatenate([np.degrees(tr.arms[:, 1] - trk[:, 1, 3:]) for tr, trk in zip(trials, wrong)])
    assert np.sqrt(np.nanmean(err1 ** 2)) > 20
    conv = conventions(Problem(trials))
    assert conv["warning"] is None and list(conv["alternatives"])[-1] == "opposite chirality"


def _one_gait(tr):
    """The trial read as if every robot ran robot 0's gait."""
    import dataclasses
    return dataclasses.replace(tr, gaits=None)


def test_the_nominal_fit_recovers_a_longer_arm_it_was_not_told_about(tmp_path):
    # the library's own model with arm 2 made 15 % longer: the fit names arm2_length, not arm_length. An
    # arm's length shows only in how the body moves, so the plate is one a lone body slides on (mu 0.15): on
    # the preset's mu 0.37 a lone body stays put once each arm move's slip is converged (the calibration's
    # discrete integrator, since 0.4.3), and the two robots' tracks are the same to 2e-4 of the noise
    from smarticle_mjx.calibrate.synth import synth
    synth(tmp_path, trials=4, periods=4, amplitudes=(60.0,), seed=2, noise_xy_mm=0.02, noise_theta_deg=0.02,
          overrides=(("plate_friction", 0.15),))
    trials = load(tmp_path)
    base = trials[0].params
    longer = base.replace(robot=base.robot.__class__(**{**base.robot.__dict__, "arm2_length": base.robot.arm_length * 1.15}))
    from smarticle_mjx.calibrate.sim import simulate_trials
    tracks = simulate_trials(trials, scene_for=lambda tr: longer)
    for tr, mt in zip(trials, tracks):  # replace the measured poses and arms with the longer-armed robot's
        ok = np.isfinite(tr.pose)
        tr.pose = np.where(ok, mt[..., :3], np.nan)
        tr.arms = np.where(np.isfinite(tr.arms), mt[..., 3:], np.nan)
    params = tuple(p for p in N.NOMINAL if p.name in ("arm_length", "arm2_length", "servo_speed"))
    nf = N.fit_nominal(Problem(split(trials)[0]), params=params, max_nfev=20)
    assert nf.err_after < 0.2 * nf.err_before
    assert nf.values["arm2_length"] == pytest.approx(base.robot.arm_length * 1.15, rel=0.04)
    assert nf.values["arm_length"] == pytest.approx(base.robot.arm_length, rel=0.04)


def _two_amplitudes(tmp_path, trials=2, periods=4, seed=5, **effects):
    for a in (15.0, 60.0):
        I.write_case(tmp_path, amplitude_deg=a, name=f"a{int(a)}", trials=trials, periods=periods,
                     seed=seed + int(a), **effects)
    return tmp_path


@pytest.fixture(scope="module")
def lag_report(tmp_path_factory):
    """`smx calibrate` on another simulator's robot with a 30 ms servo lag (a robot built differently: arm
    shape, masses, hinge, servo law, time step): 60-95 s on 2 cores, shared by the tests below."""
    tmp = tmp_path_factory.mktemp("lag")
    data = _two_amplitudes(tmp / "data", periods=3, lag_s=0.03)
    out = tmp / "report"
    r = CliRunner().invoke(app, ["calibrate", str(data), "--out", str(out)])
    assert r.exit_code == 0, r.output
    return json.loads((out / "report.json").read_text()), (out / "report.md").read_text()


@pytest.mark.slow  # the delay test (test_calibrate_structure.py) names lags in seconds, and
# benchmarks/calibration_stress.py and calibration_cases.py run this path on many builds
def test_a_hidden_servo_lag_in_another_simulators_robot_is_named_through_smx_calibrate(lag_report):
    # the nominal fit absorbs the build; the lag, fitted with it, beats it alone and is named
    rep, md = lag_report
    assert [a["effect"] for a in rep["added"]][:1] == ["servo_lag"], (rep["verdict"], rep["nominal_hypotheses"])
    lo, hi = rep["added"][0]["interval_statistical"]["extra_lag_s"]
    # the library's lag acts on its ramp, the generator's on a slewed corner: the fitted extra lag (on top of
    # the preset's 10 ms) is of the injected size, not equal to it
    assert 0.01 < lo < hi < 0.04
    # the reported interval carries the model's mismatch too (calibrate/discrepancy.py): it holds the
    # statistical one and the injected 30 ms
    tlo, thi = rep["added"][0]["interval"]["extra_lag_s"]
    assert tlo < lo and thi > hi and tlo < 0.03 < thi
    assert rep["after"]["err_heldout"] <= 0.5 * rep["before"]["err_heldout"]
    assert "## Nominal parameters" in md and "servo_armature" in md
    # on the tracks: the lag makes this robot's arms reach their midpoints ~26-30 ms later (the generator
    # without it: 39 and 143 ms at 15 and 60 deg); the preset's arms are well early, the calibrated
    # model's within a few ms
    assert "## What the fitted values mean on the tracks" in md
    rows = rep["observables"]["arm_delay_ms"]
    assert len(rows) == 2
    for row in rows:
        data = row["measured"]["mean"]
        assert row["preset"]["mean"] < data - 15, row
        assert abs(row["final"]["mean"] - data) < 4, row


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason=(
    "since the 0.25 ms default (version 0.4.0): the lag and the nominal servo, fitted together, land on a "
    "stiffer, heavier servo (kp x3.2, armature x4.8) whose lag-free version is 31 ms LATER at 15 deg "
    "(96.5 against 65.0 ms; 25.5 ms earlier at 60 deg, as expected): the split between lag and servo is not "
    "identified at 15 deg. Passed at 0.5 ms."))
def test_the_fitted_lag_itself_accounts_for_the_delay_at_every_amplitude(lag_report):
    # the final model without its lag: arms earlier by more than 10 ms at each amplitude
    rep, _ = lag_report
    for row in rep["observables"]["arm_delay_ms"]:
        assert row["final"]["mean"] - row["without servo_lag"]["mean"] > 10, row


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2])
def test_clean_data_from_another_simulator_get_no_structural_effect(tmp_path, seed):
    res = calibrate(load(_two_amplitudes(tmp_path, trials=3, periods=5, seed=seed))).summary
    assert res["added"] == [], (res["verdict"], res["nominal_hypotheses"])
    # what the nominal fit did absorb: most of the preset's disagreement with this robot
    assert res["after_nominal"]["err_heldout"] < 0.25 * res["before"]["err_heldout"]


def test_the_phase_offset_between_two_robots_is_read_from_their_arms_without_the_model(tmp_path):
    """Two robots of one build trace the same arm curves; the second running
    0.1 period ahead traces the first's shifted by 0.1 period (at 15 deg the
    servo's slew shortens the visible shift a little), and in phase by none."""
    from smarticle_mjx.calibrate.phase import estimate_offset, offset_test
    for off, lo, hi in ((0.1, 0.085, 0.105), (0.0, -0.004, 0.004)):
        d = tmp_path / f"o{off}"
        for a in (15.0, 60.0):
            I.write_case(d, amplitude_deg=a, name=f"a{int(a)}", trials=2, periods=3, seed=7 + int(a), robots=2,
                         phase_offset=off)
        est = estimate_offset(load(d))
        assert est["pairs"] == 4 and lo < est["offset"] < hi, est
        # and the test that gates the offset's fit (calibrate.phase.offset_test): present only where it is
        ot = offset_test(load(d))
        assert ot.source == "arms" and lo < ot.mean < hi and ot.present == bool(off) and ot.absent == (not off), ot


def test_the_offset_of_a_robot_that_starts_its_first_move_late_is_read_from_its_steady_gait(tmp_path, monkeypatch):
    """The independent simulator starts every robot at rest in its first corner: one whose clock is 0.149
    period ahead (mid-move at t = 0) makes its first move from there, later than its steady gait would.
    Read from one period after the start on, the offset is the hidden one within 0.001 period; read over
    every frame (as before version 0.4.4) the late first move pulls it below 0.1445."""
    from smarticle_mjx.calibrate import phase
    for a in (40.0, 60.0):
        I.write_case(tmp_path, amplitude_deg=a, name=f"a{int(a)}", trials=2, periods=4, seed=3 + int(a), robots=2,
                     phase_offset=0.149, frame_rate=90.0)
    trials = load(tmp_path)
    po = phase.pair_offsets(trials)
    assert po["n"] == 4 and abs(po["mean"] - 0.149) < 0.001, po
    monkeypatch.setattr(phase, "SETTLE_PERIODS", 1e9)  # every frame
    assert phase.pair_offsets(trials)["mean"] < 0.1445


@pytest.mark.slow
def test_a_phase_offset_between_two_independent_robots_is_named(tmp_path):
    """Two robots of another build, the second running 0.1 period ahead. Fitted
    after the nominal servo it came out at a third of that and was rejected
    (the servo had bent to split the difference between the robots); fitted
    jointly with the nominal parameters it is named, near the truth."""
    res = calibrate(load(_two_amplitudes(tmp_path, trials=3, periods=5, seed=1, robots=2, phase_offset=0.1))).summary
    assert [a["effect"] for a in res["added"]][:1] == ["phase_offset"], (res["verdict"], res["nominal_hypotheses"])
    assert 0.08 < res["added"][0]["values"]["phase_offset"] < 0.12
    assert res["after"]["err_heldout"] <= 0.5 * res["after_nominal"]["err_heldout"]


def test_an_effect_fitted_onto_its_null_bound_is_not_present():
    from smarticle_mjx.calibrate.effects import BY_NAME
    from smarticle_mjx.calibrate.policy import is_present
    lag = BY_NAME["servo_lag"]
    assert not is_present(lag, {"extra_lag_s": (float("nan"), float("nan"))})   # on the bound: no interval
    assert not is_present(lag, {"extra_lag_s": (0.0, 0.01)})                    # includes 0: absent
    assert is_present(lag, {"extra_lag_s": (0.02, 0.03)})


# ------------------------------------------------------------ plate-frame drift (tilt)

def test_drift_regression_separates_body_and_plate_frame_and_its_interval_covers():
    """Brute force: steps made as R(h) s + v plus a per-step variation and
    the difference of noisy cycle positions. The estimate recovers v whatever
    s is, and its 95 % interval covers the truth in ~95 % of 300 draws (the
    lag-1 anticorrelation of differenced positions taken into account)."""
    from smarticle_mjx.calibrate.drift import regress
    rng = np.random.default_rng(3)
    s_true, v_true = np.array([0.4, -0.15]), np.array([0.02, -0.03])
    hits, errs = 0, []
    for _ in range(300):
        tracks = []
        for h0 in rng.uniform(-math.pi, math.pi) + np.arange(4) * math.pi / 2 + rng.normal(0, 0.3, 4):
            k = 6
            h = h0 + 0.05 * np.arange(k)  # the robot turns a little every cycle
            rot = np.stack([np.cos(h) * s_true[0] - np.sin(h) * s_true[1],
                            np.sin(h) * s_true[0] + np.cos(h) * s_true[1]], -1)
            pos_noise = rng.normal(0, 0.03, (k + 1, 2))
            steps = rot + v_true + rng.normal(0, 0.01, (k, 2)) + np.diff(pos_noise, axis=0)
            tracks.append((h, steps))
        r = regress(tracks)
        se = np.sqrt(np.diag(r["cov_v"]))
        hits += int((np.abs(r["v"] - v_true) <= 1.96 * se).all())
        errs.append(r["v"] - v_true)
    assert np.allclose(np.mean(errs, axis=0), 0, atol=0.003)
    assert 0.87 <= hits / 300 <= 0.99
    assert regress([(np.full(6, 0.3), np.ones((6, 2)))]) is None  # one heading: s and v not separable


@pytest.mark.parametrize("tilt_deg,amplitudes,seed,noise", [
    (0.5, (15, 60), 100, {}),
    (1.5, (40, 90), 300, dict(noise_xy_mm=0.6, noise_theta_deg=0.5, frame_rate=120.0)),
], ids=["half-degree", "through-0.6mm-noise"])
def test_a_tilt_of_another_simulators_plate_is_detected_and_a_level_plate_is_not(tmp_path, tilt_deg, amplitudes,
                                                                                  seed, noise):
    """The independent robot on a tilted plate (gravity toward -y in its convention) drifts toward -y
    whatever its heading, every gait the same way; on a level plate it does not, although its body-frame
    step is not the library's. Half a degree is found on tracks of 0.02 mm noise. Tracking noise of
    0.6 mm per frame is 4-10 times what the robot drifts per cycle on a plate tilted 1.5 deg
    (0.06-0.14 mm): one frame per cycle boundary cannot see that drift (p 0.8 with it), but a whole
    cycle's frames (120 Hz: 96-192 per cycle) average the noise away while the cycle's wobble repeats,
    and the same noise on a level plate is not read as drift."""
    from smarticle_mjx.calibrate.drift import drift_test
    for name, kw in (("tilt", dict(tilt_deg=(tilt_deg, 0.0))), ("level", {})):
        d = tmp_path / name
        for a in amplitudes:
            I.write_case(d, amplitude_deg=float(a), name=f"a{a}", trials=3, periods=5, seed=seed + a, **noise, **kw)
        res = drift_test(load(d))
        if name == "tilt":
            assert res["significant"], res
            for g in res["groups"]:
                assert g["v_mm"][1] < -2 * g["se_mm"][1]  # downhill: -y
            assert res["directions"]["compared"] and res["directions"]["consistent"], res["directions"]
        else:
            assert not res["significant"] and res["p"] > 0.01, res


def test_drifts_pointing_different_ways_in_different_gaits_are_not_one_tilt():
    """A tilt pulls every gait's robots downhill; drifts of different gaits that point apart by more than
    the allowed spread are not one tilt. Only drifts beyond twice their error are compared, weighted by
    |v| / se, and with fewer than two of them nothing is compared."""
    from smarticle_mjx.calibrate.drift import MAX_DIRECTION_SPREAD_DEG, directions

    def row(deg, size=0.1, se=0.005):
        a = math.radians(deg)
        return {"v_mm": [size * math.cos(a), size * math.sin(a)], "se_mm": [se, se]}

    d = directions([row(30), row(50), row(40, size=0.2)])
    assert d["compared"] and d["consistent"] and d["groups"] == 3
    assert abs(d["mean_deg"] - 40) < 1 and abs(d["max_angle_deg"] - 10) < 1
    d = directions([row(-150), row(30)])  # opposite ways
    assert d["compared"] and not d["consistent"] and d["max_angle_deg"] > MAX_DIRECTION_SPREAD_DEG
    d = directions([row(179), row(-179)])  # 2 deg apart across the cut at 180 deg
    assert d["consistent"] and d["max_angle_deg"] < 2
    d = directions([row(0), row(120, size=0.008)])  # the second within twice its error: not compared
    assert not d["compared"] and d["consistent"] and d["groups"] == 1
    # the weights: a sharp drift holds the mean, so the vaguer one is the one far from it
    d = directions([row(0, se=0.001), row(60, se=0.04)])
    assert d["angles_deg"][0] < 5 and d["angles_deg"][1] > MAX_DIRECTION_SPREAD_DEG and not d["consistent"]


def test_a_coulomb_slider_drifts_downhill_whatever_way_it_slides():
    """Brute force, written here: a puck on a plate with Coulomb friction (kinetic mu g while it moves,
    held while the pull is under static friction) is kicked along a few fixed ways, each kick from rest.
    A small pull along the plate (a tilt) changes where each slide ends; over the kicks the extra
    displacement per unit pull is the drift response R. Whatever the ways it slides (here along one axis
    mostly, as a robot's body does), the drift has a non-negative component along the pull: u . R u >= 0
    for every u, which ``drift.downhill`` asks of a model's response along the data's drift. The same
    response reversed, or turned 150 degrees, is not downhill."""
    from smarticle_mjx.calibrate.drift import downhill
    mu_g, dt = 3.6, 1e-4  # m/s^2 (mu 0.37), s
    kicks = [(0.05, 0.0), (0.04, 0.3), (0.06, -0.2), (0.03, math.pi + 0.1), (0.05, math.pi)]  # speed m/s, way

    def slide(pull):
        total = np.zeros(2)
        for speed, way in kicks:
            x, v = np.zeros(2), speed * np.array([math.cos(way), math.sin(way)])
            while np.hypot(*v) > 0:
                sp = np.hypot(*v)
                a = np.asarray(pull) - mu_g * v / sp
                v_new = v + a * dt
                if v_new @ v <= 0:  # stopped within the step; static friction holds the small pull
                    v_new = np.zeros(2)
                x = x + 0.5 * (v + v_new) * dt
                v = v_new
            total += x
        return total

    eps = 0.02  # m/s^2: about a third of a degree of tilt
    base = slide((0.0, 0.0))
    r = np.column_stack([(slide((eps, 0.0)) - base) / eps, (slide((0.0, eps)) - base) / eps])
    for ang in np.radians(np.arange(0, 360, 10)):
        u = np.array([math.cos(ang), math.sin(ang)])
        assert u @ r @ u >= -1e-9 * np.abs(r).max()
        if abs(math.sin(ang)) > 0.2:  # off the axis it mostly slides along, clearly downhill
            assert downhill(r, u)
        assert not downhill(-r, u)
    c, s = math.cos(math.radians(150)), math.sin(math.radians(150))
    turned = np.array([[c, -s], [s, c]]) @ r
    assert not downhill(turned, (0.0, 1.0)) and downhill(r, (0.0, 1.0))


def test_a_gait_whose_model_drifts_uphill_does_not_size_the_tilt(tmp_path):
    """The independent robot on a plate tilted 1.6 deg (the library's (1.5, 0.5)), two gaits. Sized with the
    same simulator as its model, both gaits drift downhill and the tilt comes back. With a model that drifts
    uphill in the 90 deg gait (its response reversed there, as a model robot whose trajectories move for
    another reason can give), that gait is left out and named, and the 40 deg gait alone still gives the
    tilt; with both gaits reversed there is no fit at all."""
    from smarticle_mjx.calibrate.drift import fit_tilt
    truth = (1.5, 0.5)
    amps = (40, 90)
    quiet = dict(noise_xy_mm=0.0, noise_theta_deg=0.0, noise_arm_deg=0.0)

    def write(d, a, tilt, **kw):
        x, y = tilt  # the library's plate_tilt: gravity pulls toward (x, y); the generator's own convention
        I.write_case(d, amplitude_deg=float(a), name=f"a{a}", trials=3, periods=5, seed=300 + a,
                     tilt_deg=(-y, x), **kw)

    for a in amps:
        write(tmp_path / "data", a, truth)
    trials = load(tmp_path / "data")
    assert [tr.gaits[0].amplitude_deg for tr in trials] == [40] * 3 + [90] * 3
    cache = {}

    def tracks(a, tilt):  # the generator's tracks of one gait, without noise (the same starts and frames)
        if (a, tilt) not in cache:
            d = tmp_path / f"model_{a}_{len(cache)}"
            write(d, a, tilt, **quiet)
            cache[a, tilt] = [np.concatenate([tr.pose, tr.arms], -1) for tr in load(d)]
        return cache[a, tilt]

    def model(sign):
        return lambda tx, ty: [t for a in amps for t in tracks(a, (sign[a] * tx, sign[a] * ty))]

    honest = fit_tilt(trials, model({40: 1, 90: 1}))
    assert honest["ok"] and honest["uphill_groups"] == [] and honest["groups"] == 2
    assert np.allclose(honest["tilt_deg"], truth, atol=0.35), honest["tilt_deg"]
    one = fit_tilt(trials, model({40: 1, 90: -1}))
    assert one["ok"] and [g["amplitude_deg"] for g in one["uphill_groups"]] == [90]
    assert one["groups"] == 1 and np.allclose(one["tilt_deg"], truth, atol=0.5), one["tilt_deg"]
    none = fit_tilt(trials, model({40: -1, 90: -1}))
    assert not none["ok"] and len(none["uphill_groups"]) == 2


def test_the_report_names_a_gait_left_out_of_the_tilt_and_a_tilt_not_fitted():
    """The drift section lists a gait whose model robot drifts uphill as left out, beside the gaits that
    sized the tilt, and says so where no gait was left to fit one."""
    from smarticle_mjx.calibrate.report import drift_markdown
    g = {"amplitude_deg": 25.0, "v_mm": [-1.49, -1.66], "se_mm": [0.43, 0.43], "cycles": 7, "spread_deg": 81.0}
    up = {"amplitude_deg": 75.0, "chirality": "ccw", "period_s": 1.33,
          "response_mm_per_deg": [[1.2, -2.5], [-2.0, -0.4]]}
    fit = {"ok": True, "tilt_deg": [-0.82, -0.78], "se_deg": [0.4, 0.5], "chi2_before": 9.0, "chi2_after": 0.0,
           "accepted": False, "magnitude_deg": 1.13, "magnitude_interval": [0.2, 3.0], "size_determined": False,
           "direction_deg": 224.0, "uphill_groups": [up],
           "discrepancy": {"log_sd": 0.1, "log_sd_gaits": 0.0, "log_sd_slide": 0.1,
                           "per_group": [{"amplitude_deg": 25.0, "chirality": "ccw", "tilt_deg": [-0.82, -0.78],
                                          "slide_mm": [20.6, 21.9]}]}}
    dr = {"dof": 4, "chi2": 40.7, "p": 3e-8, "threshold_p": 1e-3, "groups": [g], "directions": {},
          "tilt_fit": fit}
    md = "\n".join(drift_markdown(dr, None))
    assert "| 25° ccw | (-0.82, -0.78) |" in md
    assert "| 75° ccw | left out: the model robot drifts uphill" in md
    md = "\n".join(drift_markdown({**dr, "tilt_fit": {"ok": False, "uphill_groups": [up]}}, None))
    assert "No tilt fitted: in no gait does the model robot drift downhill" in md and "| 75° ccw |" not in md
    assert drift_markdown(None, None) == [] and drift_markdown({"dof": 0}, None) == []
    # a drift that cannot be read withholds the anisotropic plate (since version 0.4.18), and the report says so
    from smarticle_mjx.calibrate.stages import plate_skip_reason
    why = plate_skip_reason({"dof": 0, "p": float("nan")})
    md = "\n".join(drift_markdown({"dof": 0, "p": float("nan")}, {"dof": 0, "reason": why}))
    assert "Not read" in md and why in md


def test_the_report_says_which_reading_of_the_drift_the_tilt_gate_used():
    """Beside a tilt fit, the drift section says whether the gaits' drifts follow the robot's own step, read
    on the data alone, or, where the model drags its arms on the plate, on the drift the model leaves
    (since version 0.4.10), with the two chi^2's that decided it."""
    from smarticle_mjx.calibrate.report import drift_markdown
    g = {"amplitude_deg": 25.0, "v_mm": [-1.49, -1.66], "se_mm": [0.43, 0.43], "cycles": 7, "spread_deg": 81.0}
    own = {"applicable": True, "chi2_one_vector": 31.1, "chi2_anisotropy": 6.7, "p_one_vector": 1e-6}
    left = {"applicable": True, "chi2_one_vector": 3.6, "chi2_anisotropy": 0.8, "p_one_vector": 0.46}
    fit = {"ok": True, "tilt_deg": [-0.32, 0.46], "se_deg": [0.1, 0.1], "chi2_before": 54.0, "chi2_after": 5.0,
           "accepted": True, "follows_the_robot": False, "gate_beyond_model": True,
           "plate_models_beyond_model": left}
    dr = {"dof": 6, "chi2": 54.2, "p": 7e-10, "threshold_p": 1e-3, "groups": [g], "directions": {},
          "plate_models": own, "tilt_fit": fit}
    md = "\n".join(drift_markdown(dr, None))
    assert "Read on the drift the model leaves" in md and "one vector χ² 3.6 (p 0.46), one anisotropy χ² 0.8" in md
    assert "one vector, as a tilt's." in md
    md = "\n".join(drift_markdown({**dr, "tilt_fit": {**fit, "gate_beyond_model": False, "follows_the_robot": True,
                                                       "accepted": False}}, None))
    assert "Read on the data alone: one vector χ² 31.1" in md and "**it follows the step**" in md


def test_the_report_says_where_the_tilt_named_from_the_drift_raised_the_held_out_error():
    """The tilt is named without the model and sized by it, so no held-out rule decides it; the drift section
    gives the held-out error before and with it, and says so in bold where it rose (``stages.TiltHeldout``):
    the drift is there, but the model's tilt does not carry it to the held-out trials."""
    from smarticle_mjx.calibrate.report import drift_markdown
    from smarticle_mjx.calibrate.stages import TiltHeldout
    rose, fell = TiltHeldout(43.7, 45.5), TiltHeldout(69.1, 33.6)
    assert rose.rose and not fell.rose
    assert rose.gain == pytest.approx(1 - 45.5 / 43.7) and fell.gain == pytest.approx(1 - 33.6 / 69.1)
    g = {"amplitude_deg": 25.0, "v_mm": [-1.49, -1.66], "se_mm": [0.43, 0.43], "cycles": 7, "spread_deg": 81.0}
    fit = {"ok": True, "tilt_deg": [-0.32, 0.46], "se_deg": [0.1, 0.1], "chi2_before": 54.0, "chi2_after": 5.0,
           "accepted": True}
    dr = {"dof": 6, "chi2": 54.2, "p": 7e-10, "threshold_p": 1e-3, "groups": [g], "directions": {},
          "tilt_fit": fit, "tilt_heldout": rose.as_dict()}
    md = "\n".join(drift_markdown(dr, None))
    assert "before the tilt: 43.7; with the tilt: 45.5. **It rose**" in md
    md = "\n".join(drift_markdown({**dr, "tilt_heldout": fell.as_dict()}, None))
    assert "before the tilt: 69.1; with the tilt: 33.6." in md and "It rose" not in md
    assert "before the tilt" not in "\n".join(drift_markdown({**dr, "tilt_heldout": None}, None))
