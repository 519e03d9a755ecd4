"""The discovery recount's readings (reduce.emergence, reduce.chains, reduce.spreading) on built tracks whose
answers are known by construction. Written, with the readings, before any model trial was counted with them."""

import json

import numpy as np
import pytest

from smarticle_mjx.reduce import chains as CH
from smarticle_mjx.reduce import emergence as EM
from smarticle_mjx.reduce import relaxation as RX
from smarticle_mjx.reduce import spreading as SP

from crowdbuild import parked as _parked, touch as _touch

W, D = 0.05, 0.022


def _move(poses, robots, v_W, first, last):
    """Robots ``robots`` move +x at v_W W per period in periods first .. last - 1 (0-based), then hold."""
    steps = np.clip(np.arange(1, len(poses) + 1) - first, 0, last - first)  # periods of motion done by each end
    poses[:, robots, 0] += (v_W * W * steps)[:, None]


def _runs(poses, touched, start, **kw):
    return EM.touch_runs(poses, touched, start, W, **kw)


# ------------------------------------------------------------------ touch runs and the four readings

def test_a_pair_carried_inside_a_chain_is_a_touch_glider_but_not_a_pair_glider():
    """Robots 0 and 1 touch in all 150 periods while robot 2 touches robot 1 in every period (a 3-robot chain);
    the three move together at 0.01 W per period. The pair qualifies under (b) and, having moved 1.2 W after
    period 30, under (c); never apart, it fails (a); its robots touch a third in every period, so it fails
    (d)."""
    n, k = 3, 150
    touched = _touch(n, k, {(0, k): [(0, 1), (1, 2)]})
    poses, start = _parked(np.array([[0, 0], [W, 0], [2 * W, 0]]), k)
    _move(poses, [0, 1, 2], 0.01, 0, k)
    runs = _runs(poses, touched, start)
    q = next(r for r in runs if r.pair == (0, 1))
    assert (q.start, q.length, q.censored, q.third_periods, q.apart_periods) == (0, 150, True, 150, 0)
    assert q.net_W == pytest.approx(1.5) and q.net_late_W == pytest.approx(1.2)
    assert q.contour_W == pytest.approx(1.5)
    assert q.qualifies(EM.Reading.TOUCH) and q.qualifies(EM.Reading.MOVED) and not q.qualifies(EM.Reading.PAIR)
    with pytest.raises(ValueError):
        q.qualifies(EM.Reading.APART)


def test_motion_while_the_crowd_spreads_does_not_count_but_motion_after_period_30_does():
    """A lone bound pair (robot 2 parked 5 W off) is pushed 2 W in periods 0-29 and then sits still for 120:
    (b) yes, (c) no (net 0 after period 30) although its whole-run displacement is 2 W. The same pair moving
    0.006 W per period from period 30 to 150 (0.72 W) passes (c) and (d); at 0.004 W per period (0.48 W)
    it fails (c)."""
    n, k = 3, 150
    touched = _touch(n, k, {(0, k): [(0, 1)]})
    poses, start = _parked(np.array([[0, 0], [W, 0], [-5 * W, 0]]), k)
    pushed = poses.copy()
    _move(pushed, [0, 1], 2 / 30, 0, 30)
    q = _runs(pushed, touched, start)[0]
    assert q.net_W == pytest.approx(2.0) and q.net_late_W == pytest.approx(0.0, abs=1e-12)
    assert q.qualifies("touch") and not q.qualifies("moved")
    for v, ok in ((0.006, True), (0.004, False)):
        late = poses.copy()
        _move(late, [0, 1], v, 30, k)
        q = _runs(late, touched, start)[0]
        assert q.net_late_W == pytest.approx(v * 120)
        assert q.qualifies("moved") is ok and q.qualifies("pair") is ok
        assert q.apart_periods == 150 and q.third_periods == 0  # apart throughout: (a) counts it too


def test_passing_touches_are_allowed_up_to_a_fifth_of_the_run():
    """A moving pair whose robot 1 touches robot 2 in 30 of 150 periods (share 0.8) is a pair glider; in 31
    periods (share 0.793) it is not."""
    n, k = 3, 150
    poses, start = _parked(np.array([[0, 0], [W, 0], [2 * W, 0]]), k)
    _move(poses, [0, 1], 0.01, 0, k)
    for third, ok in ((30, True), (31, False)):
        touched = _touch(n, k, {(0, k): [(0, 1)], (40, 40 + third): [(1, 2)]})
        q = next(r for r in _runs(poses, touched, start) if r.pair == (0, 1))
        assert q.third_periods == third
        assert q.pair_share == pytest.approx(1 - third / 150)
        assert q.qualifies("pair") is ok and q.qualifies("moved")


def test_a_run_of_99_periods_is_no_glider_and_a_gap_of_one_period_splits_a_run():
    n, k = 2, 200
    poses, start = _parked(np.array([[0, 0], [W, 0]]), k)
    _move(poses, [0, 1], 0.01, 0, k)
    touched = _touch(n, k, {(0, 99): [(0, 1)], (100, 200): [(0, 1)]})
    runs = _runs(poses, touched, start)
    assert [(r.start, r.length, r.censored) for r in runs] == [(0, 99, False), (100, 100, True)]
    assert not runs[0].qualifies("touch") and runs[1].qualifies("touch")
    assert EM.glider_of(runs, EM.Reading.PAIR) is runs[1]
    assert runs[1].net_late_W == pytest.approx(1.0)  # from the end of period 100, the run's own start
    # the kept runs: a results file keeps runs >= keep_periods only
    assert _runs(poses, touched, start, min_periods=100) == (runs[1],)


def test_an_early_stop_or_a_robot_leaving_the_plate_ends_a_run():
    n, k = 2, 150
    poses, start = _parked(np.array([[0, 0], [W, 0]]), k)
    touched = _touch(n, k, {(0, k): [(0, 1)]})
    assert [(r.length, r.censored) for r in _runs(poses, touched, start, periods_run=120)] == [(120, False)]
    assert [r.length for r in _runs(poses, touched, start, left_plate=np.array([0, 101]))] == [100]


def test_the_kind_is_read_from_the_mean_orientation():
    n, k = 2, 120
    poses, start = _parked(np.array([[0, 0], [W, 0]]), k)
    touched = _touch(n, k, {(0, k): [(0, 1)]})
    assert _runs(poses, touched, start)[0].kind == "C2"
    poses[:, 1, 2] = np.pi
    assert _runs(poses, touched, start)[0].kind == "C1"


def test_fisher_p_of_the_lab_count_against_itself_is_one_and_small_far_from_it():
    assert EM.fisher_p(77, 151) == pytest.approx(1.0)
    assert EM.fisher_p(17, 100) < 1e-6
    assert EM.fisher_p(17, 100) == pytest.approx(EM.fisher_p(17, 100, 77, 151))


def _record(**kw):
    from smarticle_mjx.store import RelaxRecord
    t = len(kw["valid"])
    base = dict(min_dist=np.full(np.shape(kw["touched"]), np.inf), trial=np.arange(t), settings={}, periods=150,
                period_s=1.6, model="built", overrides={}, body_length=W, body_thickness=D, paths=())
    return RelaxRecord(**{**base, **kw})


def test_emergence_counts_each_reading_over_usable_trials_and_matches_the_old_rule():
    """Three trials of 4 robots, 150 periods. Trial 0: pair (0, 1) alone 5 W from the others, moving 0.01 W
    per period (a glider under every reading). Trial 1: pair (0, 1) inside a chain with robot 2, carried
    1.5 W (b, c only). Trial 2: pair (2, 3) bound 150 periods but still ((b) only, and (a): apart and bound
    is the old rule's whole test). A fourth trial flagged by the engine is not counted."""
    n, k = 4, 150
    xy = np.array([[0, 0], [W, 0], [-5 * W, 0], [-5 * W, W]])
    p0, start = _parked(xy, k)
    _move(p0, [0, 1], 0.01, 0, k)
    t0 = _touch(n, k, {(0, k): [(0, 1)]})
    p1 = _parked(np.array([[0, 0], [W, 0], [2 * W, 0], [-8 * W, 0]]), k)[0]
    _move(p1, [0, 1, 2], 0.01, 0, k)
    t1 = _touch(n, k, {(0, k): [(0, 1), (1, 2)]})
    p2 = _parked(np.array([[0, 0], [6 * W, 0], [-5 * W, 0], [-5 * W, W]]), k)[0]
    t2 = _touch(n, k, {(0, k): [(2, 3)]})
    s1 = _parked(np.array([[0, 0], [W, 0], [2 * W, 0], [-8 * W, 0]]), k)[1]
    s2 = _parked(np.array([[0, 0], [6 * W, 0], [-5 * W, 0], [-5 * W, W]]), k)[1]
    data = _record(valid=np.ones(4, bool), status=np.array([0, 0, 0, 4]),
                   poses=np.stack([p0, p1, p2, p0]), touched=np.stack([t0, t1, t2, t0]),
                   start_poses=np.stack([start, s1, s2, start]), left_plate=np.zeros((4, n), int),
                   periods_run=np.full(4, k))
    em = EM.emergence(data)
    got = {r.reading.value: r.trial_gliders for r in em.readings}
    assert got == {"apart": (0, 2), "touch": (0, 1, 2), "moved": (0, 1), "pair": (0,)}
    assert em.primary is EM.Reading.PAIR and em.of("pair").trials == 3
    assert em.of("pair").distance.mean == pytest.approx(1.2)  # 0.01 W x 120 periods after period 30
    assert em.of("apart").distance.mean == pytest.approx((1.5 + 0.0) / 2)
    assert em.of("moved").kinds == {"C1": 0, "C2": 2}
    # reading (a) is the bound-and-apart rule of reduce.relaxation.analyse_relaxation, counted the same way
    old = RX.analyse_relaxation(data)
    assert em.of("apart").emerged == old.emerged and em.of("apart").distance.mean == pytest.approx(old.distance.mean)
    js = em.as_json()
    assert js["primary"] == "pair" and len(js["runs"]) == 3
    assert {q["pair"][0] for r in js["runs"] for q in r["runs"]} <= {0, 1, 2}
    # the runs in the JSON recompute every reading
    again = EM.Emergence.from_json(json.loads(json.dumps(js)))
    assert json.dumps(again.as_json(), sort_keys=True) == json.dumps(js, sort_keys=True)
    # a stricter reading recomputes from the kept runs alone: a glider of >= 140 periods
    assert EM.Emergence.from_json(js, periods=140).of("touch").trial_gliders == (0, 1, 2)


# ------------------------------------------------------------------ chains by overlap

def test_a_chain_that_gains_and_loses_a_member_is_one_track_but_three_exact_chains():
    per = [[(0, 1, 2)]] * 5 + [[(0, 1, 2, 3)]] * 3 + [[(1, 2, 3)]] * 2 + [[]] * 2
    tracks = CH.track_chains(per)
    assert [(c.start, c.lifetime, c.censored, c.changes) for c in tracks] == [(0, 10, False, 2)]
    assert tracks[0].first == (0, 1, 2) and tracks[0].last == (1, 2, 3) and tracks[0].robots == (0, 1, 2, 3)
    assert sorted(CH.exact_lifetimes(per)) == [(2, False), (3, False), (5, False)]


def test_a_member_swap_of_half_the_chain_ends_it():
    """(0, 1, 2, 3) -> (2, 3, 4, 5): two of four shared is not most, so a new chain starts."""
    per = [[(0, 1, 2, 3)]] * 4 + [[(2, 3, 4, 5)]] * 4
    assert [(c.start, c.lifetime, c.censored) for c in CH.track_chains(per)] == [(0, 4, False), (4, 4, True)]


def test_merging_chains_continue_at_most_one_and_a_split_keeps_the_majority():
    # (0,1,2,3) and (4,5,6) merge into all seven: 4 of 7 shared keeps the first; the second ends
    per = [[(0, 1, 2, 3), (4, 5, 6)]] * 3 + [[(0, 1, 2, 3, 4, 5, 6)]] * 3
    t = CH.track_chains(per)
    assert [(c.start, c.lifetime, c.first) for c in t] == [(0, 6, (0, 1, 2, 3)), (0, 3, (4, 5, 6))]
    # equal halves (0,1,2) + (3,4,5) -> all six: 3 of 6 is not most, both end, a new chain starts
    per = [[(0, 1, 2), (3, 4, 5)]] * 2 + [[(0, 1, 2, 3, 4, 5)]] * 2
    assert sorted((c.start, c.lifetime) for c in CH.track_chains(per)) == [(0, 2), (0, 2), (2, 2)]
    # a split: (0..5) -> (0,1,2,3) + (4,5,6): the four continue the chain, the three are new
    per = [[(0, 1, 2, 3, 4, 5)]] * 2 + [[(0, 1, 2, 3), (4, 5, 6)]] * 2
    assert sorted((c.start, c.lifetime, c.first) for c in CH.track_chains(per)) == [(0, 4, (0, 1, 2, 3, 4, 5)),
                                                                                     (2, 2, (4, 5, 6))]


def test_chains_per_period_from_touches_and_both_readings_pooled():
    """Robots 0-1-2 chained for 6 periods, robot 3 joining in periods 2-3 (by touching 2); then only a pair:
    one overlap track of 6, three exact chains (2, 2, 2)."""
    n, k = 4, 10
    touched = _touch(n, k, {(0, 6): [(0, 1), (1, 2)], (2, 4): [(2, 3)], (6, 10): [(0, 1)]})
    per = CH.chains_per_period(touched)
    assert per[0] == [(0, 1, 2)] and per[2] == [(0, 1, 2, 3)] and per[7] == []
    lt = CH.chain_lifetimes([(touched, None, k)])
    assert (lt.overlap.n, lt.overlap.median, lt.exact.n, lt.exact.mean) == (1, 6.0, 3, 2.0)
    # the exact reading is reduce.relaxation's chain rule
    poses = np.zeros((k, n, 5))
    rx = RX.crowd_trial(poses + np.arange(n)[None, :, None] * 0.01, touched, np.zeros((n, 5)) + 0.01, W, D)
    assert sorted(e.lifetime for e in rx.chains) == sorted(x[0] for x in CH.exact_lifetimes(per))
    lt = CH.chain_lifetimes([(touched, None, 5)])  # stopped after period 5: the track is cut, not censored
    assert (lt.overlap.median, lt.overlap.censored) == (5.0, 0)


# ------------------------------------------------------------------ spreading time constants

def test_the_fitted_time_constant_of_an_exponential_approach():
    """phi(t) = 0.35 + 0.25 exp(-t / 7) over 100 periods, with jiggle of s.d. 0.003: tau within 5 % of 7."""
    rng = np.random.default_rng(3)
    t = np.arange(101)
    y = 0.35 + 0.25 * np.exp(-t / 7) + rng.normal(0, 0.003, len(t))
    f = SP.fit_decay(y)
    assert f.tau == pytest.approx(7, rel=0.05) and f.y_inf == pytest.approx(0.35, abs=0.003) and not f.at_bound
    # a step in period 1 (a tenth of a period's time constant) is at the fit's lower bound, and said so
    step = np.r_[0.6, np.full(100, 0.35)]
    assert SP.fit_decay(step).at_bound
    assert np.isnan(SP.fit_decay(np.full(50, 0.4)).tau)  # nothing to fit
    assert SP.fit_decay(np.r_[y[:20], np.nan, y[21:]]).n == 20  # NaN ends the series


def test_contacts_per_period_and_their_decay():
    n, k = 4, 60
    edges = {(0, 60): [(0, 1)], (0, 10): [(1, 2), (2, 3)], (0, 3): [(0, 3)]}
    c = SP.contacts_per_period(_touch(n, k, edges))
    assert c[0] == 4 and c[5] == 3 and c[20] == 1 and len(c) == 60
    assert len(SP.contacts_per_period(_touch(n, k, edges), periods_run=30)) == 30
    times = SP.spreading_times([SP.phi_spreading(0.3 + 0.2 * np.exp(-np.arange(81) / 9))],
                               [SP.fit_decay(1 + 3 * np.exp(-np.arange(1, 81) / 4), t0=1)])
    assert times.phi_tau.median == pytest.approx(9, rel=1e-3) and times.contacts_tau.median == pytest.approx(4, rel=1e-3)
    assert times.first_period_share.median == pytest.approx(1 - np.exp(-1 / 9), rel=1e-3)


def test_a_first_period_drop_then_a_slow_tail_is_read_as_its_share_and_the_tail_s_time_constant():
    """phi drops 78 % of the way in period 1, then the rest on tau = 10 (the shape the model's crowd showed
    before this reading was fixed): the tail's tau is 10 and the first period's share 0.78."""
    t = np.arange(1, 121)
    phi = np.r_[0.60, 0.35 + 0.25 * 0.22 * np.exp(-(t - 1) / 10)]
    s = SP.phi_spreading(phi)
    assert s.fit.tau == pytest.approx(10, rel=1e-3) and s.first_period_share == pytest.approx(0.78, rel=1e-3)


def test_a_bad_reading_is_one_line_and_exit_2_before_anything_runs(tmp_path):
    from typer.testing import CliRunner
    from smarticle_mjx.cli import app
    r = CliRunner().invoke(app, ["validate", "--data", str(tmp_path / "d"), "--out", str(tmp_path / "p.md"),
                                 "--reading", "glides", "--quiet"])
    assert r.exit_code == 2 and r.output.startswith("error: unknown reading 'glides'") and r.output.count("\n") == 1
    assert not (tmp_path / "d").exists() and not (tmp_path / "p.md").exists()
    assert EM.parse_reading(None) is EM.PRIMARY is EM.Reading.PAIR and EM.parse_reading(" Apart") is EM.Reading.APART


def test_touch_runs_agree_with_a_period_by_period_count_on_random_trials():
    """An independent count, period by period in plain Python, of every pair's runs of consecutive touches,
    their third-robot periods and the pair centre's net displacement from the end of period 30, on random
    trials of 5 robots (touches flickering at random, robots walking at random, one leaving the plate)."""
    rng = np.random.default_rng(11)
    n, k = 5, 160
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    for _ in range(5):
        touched = rng.uniform(size=(k, len(pairs))) < rng.uniform(0.5, 0.97, len(pairs))
        start = np.zeros((n, 5))
        start[:, :2] = rng.normal(0, 0.05, (n, 2))
        poses = np.repeat(start[None], k, 0)
        poses[:, :, :2] += np.cumsum(rng.normal(0, 0.002, (k, n, 2)), axis=0)
        left = np.zeros(n, int)
        left[3] = 120  # robot 3 ends period 120 off the plate: its pairs' runs stop before it
        got = {(q.pair, q.start): q for q in EM.touch_runs(poses, touched, start, W, left_plate=left)}
        want = {}
        xy = np.concatenate([start[None, :, :2], poses[..., :2]]) / W
        for p, (i, j) in enumerate(pairs):
            t = 0
            while t < k:
                ok = lambda u: touched[u, p] and not ((i == 3 or j == 3) and u >= 119)  # noqa: E731
                if not ok(t):
                    t += 1
                    continue
                s = t
                while t < k and ok(t):
                    t += 1
                third = 0
                for u in range(s, t):
                    others = [q for q, (a, b) in enumerate(pairs) if q != p and ({a, b} & {i, j})]
                    # a touch with a third robot counts as the bound-and-apart rule counts it, wherever that
                    # robot is (the simulated plane goes on past the plate's edge)
                    third += any(touched[u, q] for q in others)
                c = (xy[:, i] + xy[:, j]) / 2
                late = max(s, 30)
                net_late = float(np.hypot(*(c[t] - c[late]))) if t > late else 0.0
                want[((i, j), s)] = (t - s, third, float(np.hypot(*(c[t] - c[s]))), net_late)
        assert set(got) == set(want)
        for key, (length, third, net, net_late) in want.items():
            q = got[key]
            assert (q.length, q.third_periods) == (length, third), key
            assert q.net_W == pytest.approx(net, abs=1e-12) and q.net_late_W == pytest.approx(net_late, abs=1e-12)
