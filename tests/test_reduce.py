"""Reducers and the report, on synthetic data whose answers are known by construction."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from smarticle_mjx.cli import app
from smarticle_mjx.reduce import binding, gliders as GL, transport
from smarticle_mjx.report import ReportOptions, analyse_run
from smarticle_mjx.scene import params_json
from smarticle_mjx.specs import ScanConfig, run_name
from smarticle_mjx.scene import SceneParams
from smarticle_mjx.store import Store, Writer

W = SceneParams().robot.body_length


# ----------------------------------------------------------------- binding

def test_bound_runs_finds_every_run_and_marks_censored_ones():
    t = np.array([[1, 1, 0, 1, 1, 1],
                  [0, 0, 0, 0, 0, 0],
                  [0, 1, 0, 1, 0, 0]], bool)
    r = binding.bound_runs(t)
    got = sorted(zip(r.lane, r.start, r.length, r.censored))
    assert got == [(0, 0, 2, False), (0, 3, 3, True), (2, 1, 1, False), (2, 3, 1, False)]
    # the longest run per lane is the store's lifetime
    longest = np.zeros(3, int)
    np.maximum.at(longest, r.lane, r.length)
    assert np.array_equal(longest, binding.lifetimes(t))


def test_clopper_pearson_interval():
    # textbook value: 5 of 10 -> [0.187, 0.813]
    lo, hi = binding.binomial_interval(5, 10)
    assert lo == pytest.approx(0.1871, abs=1e-3) and hi == pytest.approx(0.8129, abs=1e-3)
    lo, hi = binding.binomial_interval(0, 20)
    assert lo == 0 and 0 < hi < 0.2
    # coverage: the exact interval covers the true p at least 95 % of the time
    rng = np.random.default_rng(1)
    k = rng.binomial(40, 0.3, 2000)
    lo, hi = binding.binomial_interval(k, 40)
    assert ((lo <= 0.3) & (0.3 <= hi)).mean() >= 0.95


def test_binding_probability_ignores_invalid_starts():
    t = np.zeros((6, 4), bool)
    t[0] = True            # bound throughout
    t[1, 2:] = True        # bound at the end only
    t[5] = True            # invalid: must not count
    p = binding.binding_probability(t, np.array([1, 1, 1, 1, 1, 0], bool))
    assert p.n == 5 and p.end.k == 2 and p.throughout.k == 1
    assert p.end.value == pytest.approx(0.4) and p.end.lo < 0.4 < p.end.hi


# ----------------------------------------------------------------- transport

def test_ballistic_track_has_beta_two_and_known_speed():
    k = np.arange(60)
    xy = np.stack([0.05 * k, 0.02 * k], -1)[None]      # v = |(0.05, 0.02)| W per period
    lags, m, _ = transport.msd(xy)
    assert np.allclose(m, (0.05 ** 2 + 0.02 ** 2) * lags ** 2)
    ex = transport.msd_exponent(xy, (5, 25), centered=False)  # one track: its centred MSD is zero
    assert ex.beta == pytest.approx(2.0, abs=1e-9)
    v = np.hypot(0.05, 0.02)
    assert transport.net_speed(xy)[0] == pytest.approx(v) and np.allclose(transport.step_lengths(xy), v)


def test_random_walks_are_diffusive():
    rng = np.random.default_rng(0)
    xy = np.cumsum(rng.normal(size=(200, 80, 2)), axis=1)
    ex = transport.msd_exponent(xy, (5, 25), n_boot=100)
    assert abs(ex.beta - 1.0) < max(3 * ex.err, 0.05) and ex.err < 0.1
    assert ex.method.startswith("bootstrap") and ex.centered
    assert ex.lo < ex.beta < ex.hi and ex.lo < 1.0 < ex.hi


def test_ballistic_gliders_in_all_directions_have_centred_beta_two():
    # the paper's <x^2> - <x>^2 over an ensemble: straight gliders heading every way are ballistic,
    # and a common drift added to all of them does not change that
    rng = np.random.default_rng(4)
    ang = rng.uniform(0, 2 * np.pi, 40)
    k = np.arange(50)[None, :, None]
    xy = 0.03 * k * np.stack([np.cos(ang), np.sin(ang)], -1)[:, None, :] + 0.01 * k * np.array([1.0, 0.0])
    ex = transport.msd_exponent(xy)
    assert ex.lag_range == (5, 15) and ex.beta == pytest.approx(2.0, abs=1e-6)
    # the interval comes from resampling whole gliders: a mixed ensemble's interval covers its estimate
    mixed = np.concatenate([xy[:20], np.cumsum(rng.normal(scale=0.03, size=(20, 50, 2)), 1)])
    m = transport.msd_exponent(mixed)
    assert 1.0 < m.beta < 2.0 and m.lo <= m.beta <= m.hi and m.hi - m.lo > 0.01


def test_centered_msd_removes_a_common_drift():
    # every track moves the same way: the paper's <x^2> - <x>^2 sees no spread
    k = np.arange(30)
    xy = np.repeat(np.stack([0.1 * k, 0 * k], -1)[None], 5, 0)
    assert np.allclose(transport.msd(xy, centered=True)[1], 0, atol=1e-12)
    assert transport.msd(xy)[1][9] == pytest.approx((0.1 * 10) ** 2)


def test_missing_samples_are_skipped_not_zero():
    k = np.arange(20.0)
    xy = np.stack([k, 0 * k], -1)[None].copy()
    xy[0, 5:8] = np.nan
    lags, m, counts = transport.msd(xy)
    assert np.allclose(m, lags ** 2) and counts[0] == 19 - 4


def test_a_shuttle_has_a_mean_step_but_no_net_speed_and_a_straight_glider_persists():
    k = np.arange(41)
    shuttle = np.stack([0.05 * (k % 2), 0 * k], -1).astype(float)   # back and forth every period
    zigzag = np.stack([0.01 * k, 0.05 * (k % 2)], -1).astype(float)  # slow net motion, large steps
    line = np.stack([0.03 * k, 0.01 * k], -1).astype(float)
    assert transport.step_lengths(shuttle).mean() == pytest.approx(0.05)
    assert transport.net_speed(shuttle)[0] < 0.05 / 40 + 1e-12 and abs(transport.glide_speed(shuttle)[0]) < 1e-3
    assert transport.direction_persistence(shuttle) == pytest.approx(-1.0)
    assert transport.net_speed(zigzag)[0] == pytest.approx(0.01, rel=0.15)
    assert transport.glide_speed(zigzag)[0] == pytest.approx(0.01, rel=0.15)
    assert transport.step_lengths(zigzag).mean() > 4 * transport.net_speed(zigzag)[0]
    v = np.hypot(0.03, 0.01)
    assert transport.net_speed(line)[0] == pytest.approx(v) and transport.glide_speed(line)[0] == pytest.approx(v)
    assert transport.direction_persistence(line) == pytest.approx(1.0)
    assert transport.median_direction_change(line) == pytest.approx(0.0, abs=1e-12)
    assert transport.straightness(line[None], 20) == pytest.approx(1.0)
    # a random walk: persistence near 0, median turn near 90 deg
    rng = np.random.default_rng(2)
    walk = np.cumsum(rng.normal(size=(20, 200, 2)), 1)
    assert abs(transport.direction_persistence(walk)) < 0.05
    assert np.degrees(transport.median_direction_change(walk)) == pytest.approx(90, abs=6)


def test_signed_turn_per_track_and_bootstrap_interval():
    k = np.arange(30.0)
    heading = np.stack([np.radians(2.0) * k, -np.radians(3.0) * k])   # one turns ccw, one cw
    t = np.degrees(transport.signed_turn_per_track(heading))
    assert t == pytest.approx([2.0, -3.0])
    # an interval that must cover the true mean ~95 % of the time and exclude 0 for a clear effect
    rng = np.random.default_rng(5)
    cover = [transport.bootstrap_interval(rng.normal(1.0, 2.0, 40), n_boot=400, seed=i) for i in range(200)]
    frac = np.mean([lo <= 1.0 <= hi for _, lo, hi, _ in cover])
    assert 0.88 <= frac <= 0.99
    est, lo, hi, n = transport.bootstrap_interval(rng.normal(1.0, 0.5, 40))
    assert n == 40 and lo > 0 and lo < est < hi
    assert np.isnan(transport.bootstrap_interval([1.0, 2.0])[1])


def test_lone_robot_measures_drift_slip_and_turn_of_built_tracks():
    """A robot that moves 3 mm per cycle in a straight line, in four equal slips of 0.75 mm (one per arm
    move), and turns 2 deg per cycle: drift = mean step = 3 mm per cycle, slip per edge 0.75 mm, beta 2
    (ballistic); a start-up jump in cycle 1 counts unless that cycle is skipped."""
    W, quarters, cycles = 0.05, 4, 20
    q = np.arange(quarters * cycles + 1)
    xy = np.stack([0.75e-3 * q, np.zeros_like(q, float)], -1)
    heading = np.radians(2.0) * q / quarters
    m = transport.lone_robot(xy, heading, 1.6, samples_per_cycle=quarters, unit=W)
    assert m.net_W_per_cycle == pytest.approx(3e-3 / W)
    assert m.step_W_per_cycle == pytest.approx(3e-3 / W)
    assert m.speed_W_per_s == pytest.approx(3e-3 / W / 1.6)
    assert m.slip_per_edge_W == pytest.approx(0.75e-3 / W) == m.slip_per_edge_max_W
    assert m.beta == pytest.approx(2.0, abs=1e-9)
    assert m.heading_deg_per_cycle == pytest.approx(2.0) == m.abs_heading_deg_per_cycle

    kicked = xy.copy()
    kicked[1:] += [0.0, 10e-3]  # a 10 mm jump in the first quarter, then the same straight line
    first = transport.lone_robot(kicked, samples_per_cycle=quarters, unit=W)
    assert first.slip_per_edge_max_W > 10e-3 / W > first.net_W_per_cycle > 3e-3 / W
    later = transport.lone_robot(kicked, samples_per_cycle=quarters, skip_cycles=1, unit=W)
    assert later.net_W_per_cycle == pytest.approx(3e-3 / W)
    assert later.slip_per_edge_max_W == pytest.approx(0.75e-3 / W)
    assert later.speed_W_per_s is None and later.heading_deg_per_cycle is None  # not measured: no period, no heading
    assert "speed_W_per_s" not in later.as_json() and list(later.as_json())[:2] == ["net_W_per_cycle", "step_W_per_cycle"]


def test_a_lone_robot_that_jiggles_has_steps_and_slip_but_no_drift():
    """Back and forth 1 mm every quarter, turning +5 then -5 deg per cycle: it slips 1 mm per edge,
    steps 0 mm per cycle (it is back at each cycle's end), drifts 0 and turns 5 deg per cycle but 0 net."""
    q = np.arange(4 * 10 + 1)
    xy = np.stack([1e-3 * (q % 2), np.zeros(len(q))], -1)
    heading = np.radians(5.0) * ((q // 4) % 2)
    m = transport.lone_robot(xy, heading, samples_per_cycle=4)
    assert m.slip_per_edge_W == pytest.approx(1e-3)
    assert m.net_W_per_cycle == 0 == m.step_W_per_cycle
    assert m.abs_heading_deg_per_cycle == pytest.approx(5.0)
    assert abs(m.heading_deg_per_cycle) < 1e-12
    once = transport.lone_robot(xy[::2], samples_per_cycle=2)  # the same robot seen at half periods
    assert once.slip_per_edge_W == 0 and once.net_W_per_cycle == 0
    with pytest.raises(ValueError, match="two cycle ends"):
        transport.lone_robot(xy[:5], samples_per_cycle=4, skip_cycles=1)
    with pytest.raises(ValueError, match="samples_per_cycle"):
        transport.lone_robot(xy, samples_per_cycle=0)


def test_mirror_tracks_turn_the_other_way():
    t = np.linspace(0, np.pi, 40)
    ccw = np.stack([np.cos(t), np.sin(t)], -1)
    cw = ccw * [1, -1]
    a, b = transport.track_turning(ccw), transport.track_turning(cw)
    assert np.all(a > 0) and np.allclose(a, -b)


# ----------------------------------------------------------------- gliders

C1_REL = (1.6, np.radians(230), np.radians(190))
C2_REL = (1.1, np.radians(275), np.radians(8))


def _noisy(centre, n, rng, spread=0.03):
    return np.asarray(centre) + rng.normal(scale=spread, size=(n, 3))


def test_clusters_recover_c1_and_c2_and_name_them_by_phi():
    rng = np.random.default_rng(2)
    samples = np.concatenate([_noisy(C1_REL, 300, rng), _noisy(C2_REL, 120, rng)])
    truth = np.r_[np.full(300, GL.C1), np.full(120, GL.C2)]
    cl = GL.find_clusters(samples, k=4)
    got = cl.classify(samples)
    # no sample gets the wrong type; Gaussian tails beyond 3x a cluster's RMS spread may be left untyped
    assert np.all((got == truth) | (got == GL.NONE)) and (got == truth).mean() > 0.99
    # phi near 360 deg is aligned too (periodicity respected)
    assert cl.classify(np.array([[1.1, np.radians(275), np.radians(355)]]))[0] == GL.C2
    # a sample far from both attractors is a transient, not a glider
    assert cl.classify(np.array([[2.4, np.radians(60), np.radians(90)]]))[0] == GL.NONE


def test_final_type_and_typed_lifetimes():
    kinds = np.array([[1, 1, 1, 1, 1, 1], [2, 2, 2, 0, 0, 0], [0, 0, 1, 2, 2, 2], [0, 0, 0, 0, 0, 0]])
    t = kinds > 0
    t[3, 1:3] = True   # a transient contact outside both clusters
    assert list(GL.final_type(kinds, t, window=3)) == [GL.C1, GL.NONE, GL.C2, GL.NONE]
    runs = GL.typed_lifetimes(kinds, t)
    got = sorted(zip(runs.lane, runs.length, runs.kind, runs.censored))
    assert got == [(0, 6, GL.C1, True), (1, 3, GL.C2, False), (2, 4, GL.C2, True), (3, 2, GL.NONE, False)]


def test_glider_tracks_keep_long_bound_runs_only():
    com = np.cumsum(np.ones((3, 50, 2)), 1)
    t = np.zeros((3, 50), bool)
    t[0] = True
    t[1, 10:25] = True          # 15 periods: too short
    t[2, 5:45] = True
    tr = GL.glider_tracks(com, t, min_periods=30)
    assert tr.shape == (2, 50, 2) and np.isnan(tr[1, 40:]).all() and np.isfinite(tr[1, :40]).all()


# ----------------------------------------------------------------- a synthetic store

M, K = 40, 60


def _synthetic_rows(rng, v=0.05):
    """10 C1 gliders bound throughout (ballistic, v W/period), 5 C2 gliders
    bound in periods 20-45 only, 20 pairs that touch twice and part, 5
    invalid starts."""
    touched = np.zeros((M, K), bool)
    rel = np.full((M, K, 3), np.nan)
    com = np.zeros((M, K, 3))
    touched[:10] = True
    rel[:10] = _noisy(C1_REL, 10 * K, rng, 0.02).reshape(10, K, 3)
    ang = rng.uniform(0, 2 * np.pi, 10)
    com[:10, :, 0] = np.cos(ang)[:, None] * v * np.arange(K)
    com[:10, :, 1] = np.sin(ang)[:, None] * v * np.arange(K)
    com[:10, :, 2] = np.radians(1.5) * np.arange(K)  # body heading turns 1.5 deg per period, ccw
    touched[10:15, 20:46] = True
    rel[10:15] = _noisy(C2_REL, 5 * K, rng, 0.02).reshape(5, K, 3)
    touched[15:35, :2] = True
    rel[15:35] = (2.5, 1.0, 1.0)
    valid = np.arange(M) < 35
    touched[~valid] = False
    rel[~valid] = np.nan
    com[:, :, :2] *= W
    return {"config": rng.uniform(size=(M, 3)), "valid": valid, "status": np.where(valid, 0, 1).astype(np.int32),
            "periods_run": np.where(valid, K, 0).astype(np.int32), "touched": touched[..., None],
            "min_dist": np.where(touched, -1e-4, np.inf)[..., None].astype(np.float32),
            "poses": np.zeros((M, K, 2, 5), np.float32), "rel": rel.astype(np.float32),
            "com": com.astype(np.float32), "lifetime": binding.lifetimes(touched).astype(np.int32)}


@pytest.fixture
def synthetic_store(tmp_path):
    path = tmp_path / "synth.h5"
    cfg = ScanConfig(n=M, periods=K, amplitudes_deg=(50.0, 90.0))
    runs = {run_name(a): {"amplitude_deg": a, "period_s": 1.6 * a / 90, "chirality": "ccw", "gait": "square",
                          "periods": K, "n_configs": M} for a in cfg.amplitudes_deg}
    rng = np.random.default_rng(3)
    with Writer(path, {"scan": cfg.to_json(), "scene": params_json(SceneParams())}, runs) as w:
        for i, run in enumerate(runs):
            w.append(run, 0, _synthetic_rows(rng, v=0.05 * (i + 1)))
        w.finalize()
    return path


def test_analyse_run_recovers_the_constructed_answers(synthetic_store):
    st = Store(synthetic_store)
    s = analyse_run(st, "a090.00", ReportOptions())["summary"]
    assert s["valid"] == 35
    assert s["pb_end"][0] == pytest.approx(10 / 35, abs=1e-4)  # the summary keeps 4 decimals
    assert s["pb_throughout"][0] == pytest.approx(10 / 35, abs=1e-4)
    assert s["C1"]["basin_configs"] == 10 and s["C2"]["basin_configs"] == 0
    assert s["C1"]["lifetime_mean"] == K and s["C1"]["censored_fraction"] == 1.0
    assert s["C2"]["lifetime_mean"] == 26 and s["C2"]["censored_fraction"] == 0.0
    assert s["gliders"] == 10
    assert s["beta"]["value"] == pytest.approx(2.0, abs=1e-3)
    assert s["v_com"]["net_W_per_period"] == pytest.approx(0.10, rel=1e-3)
    assert s["v_com"]["mean_step_W_per_period"] == pytest.approx(0.10, rel=1e-3)
    assert s["turning"]["direction_persistence"] == pytest.approx(1.0, abs=1e-3)
    assert s["signed_heading_turn"]["deg_per_period"] == pytest.approx(1.5, abs=1e-3)
    assert s["signed_heading_turn"]["gliders"] == 10
    assert s["steady_r"]["mean_W"] == pytest.approx(1.6, abs=0.01) and s["steady_r"]["pairs"] == 10


def test_the_typed_parts_carry_the_constructed_answers_unrounded(synthetic_store):
    """The typed layer (reduce.analysis) on the built store's arrays: each part is a frozen dataclass of
    unrounded numbers, the glider types alone give the same lanes as the whole analysis, and the store's
    JSON summary is the rounded serialisation of the same object."""
    import dataclasses

    from smarticle_mjx.reduce import analysis
    from smarticle_mjx.studies import glider_starts
    st = Store(synthetic_store)
    a = st.analysis_arrays("a090.00")
    o = analysis.Options.for_periods(a["periods"])
    res = analysis.analyse(a["touched"], a["valid"], a["rel"], a["com_xy"], a["heading"], a["status"], o,
                           run="a090.00", amplitude_deg=a["amplitude_deg"], chirality=a["chirality"], gait=a["gait"],
                           period_s=a["period_s"])
    for part in (res, res.binding, res.types, res.types.c1, res.transport, res.separation, res.binding.end):
        assert dataclasses.is_dataclass(part) and type(part).__dataclass_params__.frozen
    assert res.binding.end.value == 10 / 35 and res.binding.end.n == 35  # exactly, not to 4 decimals
    assert res.binding.end.lo < 10 / 35 < res.binding.end.hi
    assert res.binding.bad_status == 0 and res.valid == 35
    assert (res.types.c1.basin_configs, res.types.c2.basin_configs) == (10, 0)
    assert res.types.c2.lifetime_mean == 26.0 and res.types.c2.censored_fraction == 0.0
    assert res.transport.gliders == 10 and abs(res.transport.net_speed.value - 0.10) < 1e-6
    assert np.degrees(res.transport.signed_heading_turn.value) == pytest.approx(1.5, abs=1e-4)
    alone = analysis.glider_types(a["rel"], a["touched"], a["valid"], o.burn_in, o.clusters)
    np.testing.assert_array_equal(alone.final, res.types.final)
    c1_lanes = np.flatnonzero(res.types.final == GL.C1)
    assert list(c1_lanes) == list(range(10))
    run0 = st.runs[0]  # glider_starts reads the store's first run (50 deg here), by the glider types alone
    b = st.analysis_arrays(run0)
    first = analysis.glider_types(b["rel"], b["touched"], b["valid"], o.burn_in, o.clusters)
    want = b["rel"][np.flatnonzero(first.final == GL.C1)[:4], -1]
    np.testing.assert_allclose(glider_starts(st, "C1", 4), want)
    assert analyse_run(st, "a090.00", ReportOptions())["summary"] == res.summary(lambda x, nd=4: (
        None if x is None or not np.isfinite(x) else round(float(x), nd)))


def test_the_amplitude_figures_draw_the_unrounded_numbers(synthetic_store):
    """P_b vs amplitude and the beta / V_com / |r| panels take the typed values, not the report's rows
    rounded to 4 decimals: 10/35 = 0.285714... is drawn as that, not as 0.2857."""
    from smarticle_mjx.report import amplitude_panels, analyse_store_run, pb_rows
    st = Store(synthetic_store)
    runs = [analyse_store_run(st, r) for r in st.runs]
    end, through = pb_rows(runs)
    assert end[1][0] == 10 / 35 and end[1][0] != round(10 / 35, 4)
    assert end[1][1] < 10 / 35 < end[1][2] and through[1][0] == runs[1].binding.throughout.value
    panels = amplitude_panels(runs)
    (beta, beta_err), (v, v_err), (r, r_sd) = panels.values()
    assert beta[1] == runs[1].transport.beta.beta and beta_err[1] == runs[1].transport.beta.err
    ns = runs[1].transport.net_speed
    assert v[1] == ns.value and v_err[1] == (ns.value - ns.lo, ns.hi - ns.value)
    assert r[1] == runs[1].separation.mean and r_sd[1] == runs[1].separation.std
    for a, b_, e in zip(runs, beta, beta_err):  # a run without gliders is a gap (NaN), not a zero
        assert (a.transport is None) == bool(np.isnan(b_))


def test_smx_report_writes_every_figure_and_the_table(synthetic_store, tmp_path):
    out = tmp_path / "rep"
    r = CliRunner().invoke(app, ["report", str(synthetic_store), "--out", str(out)])
    assert r.exit_code == 0, r.output
    rep = json.loads((out / "report.json").read_text())
    assert [s["run"] for s in rep["runs"]] == ["a050.00", "a090.00"]
    for name in ("msd.png", "pb.png", "pb.svg", "vs_amplitude.png", "phase_diagram_a090.00.png",
                 "relcoords_a090.00.png", "lifetimes_a090.00.png", "gliders_a090.00.png"):
        assert (out / name).stat().st_size > 1000, name
    md = (out / "report.md").read_text()
    assert "| 90° | 35/40 |" in md and "![pb.png](pb.png)" in md


def test_smx_pb_prints_both_curves(synthetic_store, tmp_path):
    r = CliRunner().invoke(app, ["pb", str(synthetic_store), "--out", str(tmp_path / "f")])
    assert r.exit_code == 0, r.output
    assert "0.286" in r.output and (tmp_path / "f" / "pb.png").exists()


@pytest.mark.parametrize("cmd", ["report", "pb"])
def test_reducer_commands_refuse_bad_input(tmp_path, cmd):
    r = CliRunner().invoke(app, [cmd, str(tmp_path / "missing.h5"), "--out", str(tmp_path / "o")])
    assert r.exit_code == 2 and "no store" in r.output and not (tmp_path / "o").exists()
    f = tmp_path / "afile"
    f.write_text("keep me")
    bad = tmp_path / "bad.h5"
    bad.write_text("not hdf5")
    r = CliRunner().invoke(app, [cmd, str(bad), "--out", str(f)])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1
    assert f.read_text() == "keep me"


def test_glide_summary_of_built_tracks():
    """Two pairs bound in every period that move straight at 0.01 W per
    period, one along x and one along y, are gliders: net speed 0.01
    W/period, direction persistence and straightness 1, ballistic (centred)
    MSD, beta 2; C1 (anti-aligned) gliders that keep the sign of
    phi - 180 deg. A pair that lets go for one period after the burn-in and
    one that never touches are not gliders."""
    from smarticle_mjx.reduce.gliders import glide_summary
    K, burn = 40, 10
    com = np.zeros((4, K, 2))
    com[0, :, 0] = 0.01 * np.arange(K)
    com[3, :, 1] = 0.01 * np.arange(K)
    com[1, :, 1] = 0.02 * np.arange(K)
    rel = np.zeros((4, K, 3))
    rel[..., 0], rel[..., 2] = 1.3, np.pi + 0.1
    touched = np.ones((4, K), bool)
    touched[1, 25] = False
    touched[2] = False
    s = glide_summary(com, rel, touched, burn)
    assert s.gliders == 2 and s.bound_end == 3
    assert s.net_speed_W_per_period == pytest.approx(0.01, rel=1e-9)
    assert s.persistence == pytest.approx(1.0) and s.straightness20 == pytest.approx(1.0)
    assert s.beta == pytest.approx(2.0, abs=1e-6)
    assert s.C2_fraction == 0 and s.C1_gliders == 2 and s.C1_sign_held_frac == 1.0
    assert s.sign_flips_per_period == 0
    assert s.C1_phi_dev_deg == pytest.approx(np.degrees(0.1))
    # the benchmarks' JSON record: every measured quantity under its name, nothing unmeasured
    j = s.as_json()
    assert j["beta"] == s.beta and j["beta_lags"] == list(s.beta_lags) and j["repeat"]["phi"] == s.repeat.phi
    # the same pairs stepping back and forth do not travel and are not ballistic
    com[0, :, 0] = 0.01 * (np.arange(K) % 2)
    com[3, :, 1] = 0.01 * (np.arange(K) % 2)
    s = glide_summary(com, rel, touched, burn)
    assert s.net_speed_W_per_period < 0.001 and s.beta < 0.5
    # no glider: the counts alone
    touched[:, 20] = False
    s = glide_summary(com, rel, touched, burn)
    assert s.gliders == 0 and s.beta is None and s.as_json() == {"gliders": 0, "bound_end": 3}


def _store_with(tmp_path, name, model=None, timestep=5e-4, overrides=None, scene=None):
    path = tmp_path / f"{name}.h5"
    cfg = ScanConfig(n=M, periods=K, amplitudes_deg=(90.0,))
    runs = {run_name(90.0): {"amplitude_deg": 90.0, "period_s": 1.6, "chirality": "ccw", "gait": "square",
                             "periods": K, "n_configs": M}}
    header = {"scan": cfg.to_json(), "scene": params_json(SceneParams(timestep=timestep, **(scene or {})))}
    if model:
        header["model"] = model
    if overrides:
        header["overrides"] = overrides
    with Writer(path, header, runs) as w:
        w.append(run_name(90.0), 0, _synthetic_rows(np.random.default_rng(3), v=0.05))
        w.finalize()
    return path


@pytest.mark.parametrize("model,timestep,overrides,want", [
    ("lab-lag", 5e-4, None, "biased against 0.0625 ms, β +0.14 [+0.01, +0.27], net speed +39%"),
    ("lab-lag", 2.5e-4, None, "checked, passed"),
    ("lab-lag", 5e-4, {"robot.mass": 0.03}, "step not checked (fields changed from the preset: robot.mass)"),
    ("lab-lag", 2.5e-4, {"timestep": 2.5e-4}, "checked, passed"),  # --set timestep: the check at that step
    ("lab-lag", 2.5e-4, {"timestep": 2.5e-4, "robot.mass": 0.03}, "step not checked (fields changed from the preset: robot.mass)"),
    ("paper", 5e-4, None, "step not checked (no glider-quantity check"),
])
def test_a_stores_step_check_is_read_from_its_header(tmp_path, model, timestep, overrides, want):
    """A store of a (model, step) whose glider quantities were measured against a fine reference carries
    that measurement, read from the package's table (benchmarks/step_checks.py); a changed model or an
    unmeasured step is 'step not checked'."""
    from smarticle_mjx.report import step_note, store_step_check
    c = store_step_check(Store(_store_with(tmp_path, "s", model, timestep, overrides)))
    assert want in step_note(c.as_dict())
    assert c.status == ("passed" if "passed" in want else "failed" if "biased" in want else "not checked")


def test_a_sub_stepped_store_is_looked_up_under_its_own_numerics(tmp_path):
    """Near-contact sub-stepping is part of the numerics a check is keyed by: a store made with
    --set integrator=discrete --set contact_substeps=2 carries that measurement (failed, on persistence),
    not the plain 0.5 ms one, and is not 'fields changed from the preset'."""
    from smarticle_mjx.report import step_note, store_step_check
    changes = {"integrator": "discrete", "contact_substeps": 2}
    c = store_step_check(Store(_store_with(tmp_path, "s", "lab-lag", 5e-4, changes, scene=changes)))
    assert c.integrator == "discrete + 2 sub-steps within 4 mm" and c.status == "failed"
    assert not c.persistence.contains_zero and c.beta.contains_zero and abs(c.net_speed.relative) < 0.2
    assert "discrete + 2 sub-steps within 4 mm: biased" in step_note(c.as_dict())


def test_smx_report_puts_the_steps_check_on_the_line_of_every_transport_number(tmp_path):
    out = tmp_path / "rep"
    r = CliRunner().invoke(app, ["report", str(_store_with(tmp_path, "s", "lab-lag", 5e-4)), "--out", str(out)])
    assert r.exit_code == 0, r.output
    row = next(line for line in (out / "report.md").read_text().splitlines() if line.startswith("| 90° |"))
    assert "β +0.14 [+0.01, +0.27], net speed +39%" in row, row
    assert json.loads((out / "report.json").read_text())["step_check"]["status"] == "failed"


def test_a_runs_typed_result_carries_its_stores_step_check(tmp_path):
    """The step check is a field of the typed run result (``RunAnalysis.step``), the one the report's
    transport numbers are printed beside: a failed step with its measured biases, a changed model not checked."""
    from smarticle_mjx.report import analyse_store_run
    st = Store(_store_with(tmp_path, "a", "lab-lag", 5e-4))
    a = analyse_store_run(st, st.runs[0])
    assert a.step is not None and a.step.status == "failed" and a.step.beta.value > 0.068
    st = Store(_store_with(tmp_path, "b", "lab-lag", 5e-4, {"robot.mass": 0.03}))
    b = analyse_store_run(st, st.runs[0])
    assert b.step.status == "not checked" and "robot.mass" in b.step.why


def test_a_step_passes_only_when_every_interval_holds_zero_and_the_biases_are_small():
    from smarticle_mjx.reduce.stepcheck import BETA_MAX, Difference, verdict
    ok = Difference(0.0, (-0.1, 0.1), 1.0)
    assert verdict(ok, Difference(0.1, (-0.1, 0.3), 1.0), ok) == "passed"
    assert verdict(ok, Difference(0.1, (0.01, 0.3), 1.0), ok) == "failed"  # speed interval excludes 0
    assert verdict(Difference(BETA_MAX * 1.1, (-0.1, 0.3), 1.0), ok, ok) == "failed"  # beta bias too large
    assert verdict(ok, Difference(0.25, (-0.1, 0.6), 1.0), ok) == "failed"  # +25 % speed
