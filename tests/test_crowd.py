"""Measures of a relaxing crowd (reduce.relaxation: area fraction, its plateau, chains, neighbours)
on built tracks whose answers are known in closed form. Written before the measures were run on
any model trial."""

import math

import numpy as np
import pytest

from smarticle_mjx.reduce import relaxation as RX

from crowdbuild import parked as _still, touch as _touch

W, D = 0.05, 0.022


# ------------------------------------------------------------------ area fraction

def test_area_fraction_of_a_hexagonal_pack_is_seven_bodies_over_the_hexagon():
    # a 1 + 6 hexagonal pack at centre spacing s: the hull of the centres is a regular hexagon of
    # side s, area 3 sqrt(3) / 2 s^2, so phi = 7 W D / that
    s = 1.4 * W
    ang = np.arange(6) * math.pi / 3
    xy = np.concatenate([[[0.0, 0.0]], s * np.c_[np.cos(ang), np.sin(ang)]])
    poses, start = _still(xy, 3)
    phi = RX.area_fraction(poses, start, W, D)
    assert phi.shape == (4,)
    assert phi == pytest.approx(7 * W * D / (1.5 * math.sqrt(3) * s ** 2), rel=1e-12)


def test_area_fraction_grows_inverse_to_the_hull_and_ignores_interior_robots():
    # four robots on a square of side a, one at its centre: hull a^2; doubling a quarters phi
    a = 2 * W
    xy = np.array([[0, 0], [a, 0], [a, a], [0, a], [a / 2, a / 2]])
    poses, start = _still(xy, 2)
    poses[1, :, :2] *= 2
    phi = RX.area_fraction(poses, start, W, D)
    assert phi[0] == pytest.approx(5 * W * D / a ** 2)
    assert phi[2] == pytest.approx(phi[0] / 4)


def test_area_fraction_ends_when_a_robot_leaves_and_holds_after_an_early_stop():
    xy = np.array([[0, 0], [W, 0], [0, W], [W, W]], float)
    poses, start = _still(xy, 30)
    left = np.array([0, 0, 12, 0])  # robot 2 off the plate at the end of period 12
    phi = RX.area_fraction(poses, start, W, D, left_plate=left)
    assert np.isfinite(phi[:12]).all() and np.isnan(phi[12:]).all()
    poses[20:] = np.nan  # an early stop after 20 periods leaves NaN poses
    phi = RX.area_fraction(poses, start, W, D, periods_run=20)
    assert np.isfinite(phi).all() and (phi[21:] == phi[20]).all()


# ------------------------------------------------------------------ plateau

def test_plateau_of_an_exponential_relaxation_matches_the_closed_form():
    # phi = 0.25 + 0.25 exp(-t / 10): the least-squares slope over a window is close to the
    # derivative at its centre, 0.025 exp(-(t + 5) / 10) per period; times the 10-period window it
    # falls to the 0.02 tolerance at t + 5 = 10 ln(12.5) = 25.3, so the plateau starts near t = 20
    t = np.arange(301)
    p = RX.phi_plateau(0.25 + 0.25 * np.exp(-t / 10))
    assert not p.censored and 19 <= p.period <= 23
    assert p.phi == pytest.approx(0.25 + 0.25 * np.exp(-(p.period + 5) / 10), abs=0.01)
    # the rule is a rate: phi changing by less than tol per window counts as steady, so a slow
    # creep (0.001 per period at most) is a plateau from the start, and what it still falls
    # afterwards is reported beside it
    creep = RX.phi_plateau(0.15 + 0.1 * np.exp(-t / 100))
    assert creep.period == 0 and creep.phi - creep.phi_end == pytest.approx(0.1 * (1 - np.exp(-3)), abs=0.01)
    assert p.phi - p.phi_end == pytest.approx(0.25 * np.exp(-(p.period + 5) / 10), abs=0.01)


def test_plateau_ignores_jiggle_but_not_a_pause_in_the_expansion():
    rng = np.random.default_rng(0)
    flat = 0.3 + rng.normal(0, 0.005, 200)  # hull jiggle at 5 mm-ish level, no trend
    assert RX.phi_plateau(flat).period == 0
    # falls 0.1 over 10 periods, pauses 12 periods, falls 0.1 again, then stays
    seg = [np.linspace(0.5, 0.4, 11)[:-1], np.full(12, 0.4), np.linspace(0.4, 0.3, 11)[:-1], np.full(100, 0.3)]
    p = RX.phi_plateau(np.concatenate(seg))
    assert p.period > 22 - RX.PLATEAU_WINDOW and p.phi == pytest.approx(0.3, abs=0.01)
    one_window = RX.phi_plateau(np.concatenate(seg), windows=1)
    assert one_window.period < p.period  # one window alone mistakes the pause for the end


def test_plateau_is_censored_when_phi_keeps_falling_or_the_series_ends():
    falling = np.linspace(0.6, 0.1, 101)  # 0.005 per period: 0.05 per window
    p = RX.phi_plateau(falling)
    assert p.censored and p.period == 100 and math.isnan(p.phi)
    cut = np.concatenate([np.linspace(0.6, 0.3, 31), np.full(10, 0.3), np.full(50, np.nan)])
    p = RX.phi_plateau(cut)  # a robot left at 41: only 10 flat periods remain, fewer than two windows
    assert p.censored and p.defined_until == 40


# ------------------------------------------------------------------ chains and neighbours

def test_chains_their_lifetimes_loops_and_neighbours():
    n, k = 5, 30
    touched = _touch(n, k, {
        (0, 5): [(0, 1), (1, 2), (0, 2)],      # a triangle: a chain with a loop
        (5, 10): [(0, 1), (1, 2)],             # the same three robots as a line: same chain
        (10, 15): [(0, 1), (1, 2), (2, 3)],    # robot 3 joins: a new chain
        (15, 20): [(3, 4)],                    # a pair is no chain
        (20, 30): [(1, 2), (2, 4)],            # a chain that holds to the end
    })
    poses, start = _still(np.c_[np.arange(n) * W, np.zeros(n)], k)
    c = RX.crowd_trial(poses, touched, start, W, D)
    got = [(e.members, e.start, e.lifetime, e.censored, e.loop_periods) for e in c.chains]
    assert got == [((0, 1, 2), 0, 10, False, 5), ((0, 1, 2, 3), 10, 5, False, 0), ((1, 2, 4), 20, 10, True, 0)]
    assert c.degree[0].tolist() == [2, 2, 2, 0, 0] and c.degree[7].tolist() == [1, 2, 1, 0, 0]
    assert c.in_chain.tolist() == [3] * 10 + [4] * 5 + [0] * 5 + [3] * 10
    s = RX.crowd_summary([c])
    assert s.chain_lifetime.n == 3 and s.chain_lifetime.censored == 1
    assert s.chain_lifetime.mean == pytest.approx(25 / 3)
    # robot-periods in chains: 5 x (2,2,2), 5 x (1,2,1), 5 x (1,2,2,1), 10 x (1,2,1)
    assert s.neighbours_in_chain == pytest.approx((30 + 20 + 30 + 40) / (15 + 15 + 20 + 30))
    assert s.loop_fraction == pytest.approx(5 / 25)
    assert s.chained_at_end == 1


def test_a_robot_leaving_the_plate_or_an_early_stop_ends_its_chain():
    n, k = 4, 20
    touched = _touch(n, k, {(0, 20): [(0, 1), (1, 2), (2, 3)]})
    poses, start = _still(np.c_[np.arange(n) * W, np.zeros(n)], k)
    c = RX.crowd_trial(poses, touched, start, W, D, left_plate=np.array([0, 0, 0, 6]))
    got = [(e.members, e.start, e.lifetime, e.censored) for e in c.chains]
    assert got == [((0, 1, 2, 3), 0, 5, False), ((0, 1, 2), 5, 15, True)]
    assert (c.degree[5:, 3] == -1).all()
    c = RX.crowd_trial(poses, touched, start, W, D, periods_run=8)
    assert [(e.lifetime, e.censored) for e in c.chains] == [(8, False)]
    assert (c.degree[8:] == -1).all()


def test_crowd_reads_a_relaxation_store_layout_and_skips_flagged_trials():
    n, k = 3, 40
    touched = _touch(n, k, {(0, 12): [(0, 1), (1, 2)]})
    poses, start = _still(np.array([[0, 0], [W, 0], [0.5 * W, W]]), k)
    # the crowd expands: centres spread by 2 % per period for 12 periods, then stop
    grow = np.r_[1.02 ** np.arange(1, 13), np.full(k - 12, 1.02 ** 12)]
    poses[:, :, :2] *= grow[:, None, None]
    data = _record(body_length=W, body_thickness=D, valid=np.array([True, True]),
                   status=np.array([0, 4]), poses=np.stack([poses, poses]), touched=np.stack([touched, touched]),
                   start_poses=np.stack([start, start]), left_plate=np.zeros((2, n), int),
                   periods_run=np.array([k, k]), periods=k)
    s, trials = RX.crowd(data)
    assert s.trials == 1 and len(trials) == 1  # the flagged trial (penetration) is out
    assert s.contact_relaxation.median == 12 and s.chain_lifetime.median == 12
    # phi falls by 1.02^-24 over 12 periods (0.38 per 10 periods), then holds: the plateau starts
    # within a window of period 12
    assert 12 - RX.PLATEAU_WINDOW <= s.plateau.median <= 12 and s.plateau.censored == 0
    assert s.phi_plateau.median == pytest.approx(s.phi_start.median / 1.02 ** 24, rel=1e-3)


# ------------------------------------------------------------------ pairs inside the crowd

def test_an_isolated_pair_run_its_speed_its_escape_and_what_ended_it():
    """Robots 0 and 1 touch each other alone for 20 periods while their centre moves 0.01 W per period
    straight away from robot 2, parked 3 W off: one run of 20 periods, speed 0.01 W/period, escape
    0.01 W/period (the gap grows by the full step), ended when robot 0 touches robot 2. Robots 2 and 3
    touch each other for 5 periods only (< PAIR_RUN_MIN): a passing collision, no run."""
    n, k = 4, 30
    touched = _touch(n, k, {(0, 20): [(0, 1)], (20, 22): [(0, 2)], (3, 8): [(2, 3)]})
    xy = np.array([[0.0, 0.0], [W, 0.0], [-3 * W + 0.5 * W, 0.0], [-6 * W, 0.0]])
    poses, start = _still(xy, k)
    v = 0.01 * W
    poses[:20, 0:2, 0] += v * np.arange(1, 21)[:, None]  # the pair moves +x, away from robots 2 and 3
    poses[20:, 0:2, 0] += v * 20
    runs = RX.pair_runs(poses, touched, start, W)
    assert [(q.pair, q.start, q.length, q.ended_by) for q in runs] == [((0, 1), 0, 20, "third")]
    q = runs[0]
    assert q.speed == pytest.approx(0.01) and q.escape == pytest.approx(0.01)
    assert q.gap_end == pytest.approx(3.0 + 0.2)
    assert q.kind == "C2" and q.mean_cos_phi == pytest.approx(1.0)  # both headings 0: aligned
    poses[:, 1, 2] = math.pi  # robot 1 turned round: anti-aligned, a C1 pair
    q = RX.pair_runs(poses, touched, start, W)[0]
    assert q.kind == "C1" and q.mean_cos_phi == pytest.approx(-1.0)


def test_a_pair_run_is_broken_by_a_third_touch_and_ends_censored_unbound_or_off_the_plate():
    n, k = 3, 60
    # pair (0, 1): periods 0-14 alone, period 15 robot 1 also touches robot 2 (not isolated), 16-59 alone
    touched = _touch(n, k, {(0, 60): [(0, 1)], (15, 16): [(1, 2)]})
    poses, start = _still(np.array([[0, 0], [W, 0], [5 * W, 0]]), k)
    runs = RX.pair_runs(poses, touched, start, W)
    assert [(q.start, q.length, q.ended_by) for q in runs] == [(0, 15, "third"), (16, 44, "end")]
    assert runs[0].speed == 0.0 and runs[0].escape == 0.0  # parked: no speed, no escape
    runs = RX.pair_runs(poses, touched, start, W, periods_run=40)
    assert [(q.length, q.ended_by) for q in runs] == [(15, "third"), (24, "end")]
    runs = RX.pair_runs(poses, touched, start, W, left_plate=np.array([0, 31, 0]))  # robot 1 off in period 31
    assert [(q.length, q.ended_by) for q in runs] == [(15, "third"), (14, "plate")]
    touched2 = _touch(n, k, {(0, 25): [(0, 1)]})
    assert [q.ended_by for q in RX.pair_runs(poses, touched2, start, W)] == ["unbound"]
    s = RX.pair_run_summary([RX.pair_runs(poses, touched, start, W), ()])
    assert (s.trials, s.runs, s.trials_with_run) == (2, 2, 1)
    assert s.ended_by == {"third": 1, "unbound": 0, "plate": 0, "end": 1} and s.length.censored == 1
    assert s.length.mean == pytest.approx((15 + 44) / 2)


def _record(**kw):
    """A relaxation store's record (store.RelaxRecord) built from arrays, metadata filled in."""
    from smarticle_mjx.store import RelaxRecord
    t = len(kw["valid"])
    base = dict(min_dist=np.full(np.shape(kw["touched"]), np.inf), trial=np.arange(t), settings={}, periods=150,
                period_s=1.6, model="built", overrides={}, body_thickness=0.021, paths=())
    return RelaxRecord(**{**base, **kw})
