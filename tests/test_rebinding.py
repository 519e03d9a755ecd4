"""The rebinding reading and the converged steady |r| on built flags and tracks (nothing simulated).

Physical facts checked: a pair that parts for at least the scan's early-exit gap and touches again has
rebound; contact flicker shorter than the gap is not a parting; a pair whose |r| still shrinks is not
converged, and one that levels off is read at its level."""

import numpy as np
import pytest

from smarticle_mjx.reduce import gliders as GL
from smarticle_mjx.reduce.rebinding import partings, rebinding


def flags(*rows):
    return np.array([[c == "x" for c in r] for r in rows])


def test_partings_count_gaps_of_the_early_exit_only():
    t = flags("xx..x.",   # parted 2 periods, rebound
              "x.x.x.",   # flicker: never 2 quiet periods
              "...xx.",   # quiet before the first touch is no parting; ends with one quiet period
              "xx....",   # parted, never back
              "......")   # never bound
    parted, rebound = partings(t, gap=2)
    assert parted.tolist() == [True, False, False, True, False]
    assert rebound.tolist() == [True, False, False, False, False]
    parted3, rebound3 = partings(t, gap=3)
    assert parted3.tolist() == [False, False, False, True, False] and not rebound3.any()


def test_rebinding_counts_valid_pairs_and_an_exact_interval():
    t = flags("xx..xx", "xx..x.", "xx....", "xx..xx", "......")
    valid = np.array([True, True, True, False, True])
    r = rebinding(t, valid, 50.0)
    assert (r.valid, r.ever_bound, r.parted, r.rebound, r.rebound_at_end) == (4, 3, 3, 2, 1)
    assert r.rate == pytest.approx(2 / 3) and r.lo < 2 / 3 < r.hi
    from scipy.stats import binomtest
    ci = binomtest(2, 3).proportion_ci(0.95, method="exact")
    assert (r.lo, r.hi) == pytest.approx((ci.low, ci.high))
    with pytest.raises(ValueError, match="valid"):
        rebinding(t, valid[:3], 50.0)
    none = rebinding(flags("xxxx"), np.array([True]), 90.0)
    assert none.parted == 0 and np.isnan(none.rate)


def test_partings_agree_with_a_brute_force_reading():
    rng = np.random.default_rng(4)
    t = rng.random((200, 30)) < 0.45
    parted, rebound = partings(t, 2)
    for m in range(len(t)):
        s = "".join("x" if v else "." for v in t[m])
        first = s.find("x")
        cut = s.find("..", first) if first >= 0 else -1  # the first parting begins after a touch
        assert parted[m] == (cut >= 0)
        assert rebound[m] == (cut >= 0 and "x" in s[cut:])


def test_converged_separation_reads_a_level_and_not_a_slope():
    K = 40
    level = np.r_[np.linspace(1.6, 1.3, 15), np.full(K - 15, 1.3)]   # shrinks, then steady at 1.3 W
    slope = np.linspace(1.6, 1.0, K)                                   # still shrinking 0.015 W/period
    rel = np.zeros((3, K, 3))
    rel[0, :, 0], rel[1, :, 0], rel[2, :, 0] = level, slope, 1.5
    touched = np.ones((3, K), bool)
    touched[2, ::3] = False   # never bound 20 periods in a row: not tried
    c = GL.converged_separation(rel, touched, window=10, tol=0.01)
    assert c.pairs == 1 and c.unconverged == 1
    assert c.per_pair[0] == pytest.approx(1.3) and 20 <= c.at_period[0] <= 35
    with pytest.raises(ValueError):
        GL.converged_separation(rel, touched, window=10, tol=0.0)
