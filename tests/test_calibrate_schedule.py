"""The calibration's model runs side by side (calibrate.sim.pmap, sim.slot; fit.Problem.model), since 0.4.11.

Every item of a pmap, nested or not, gets a thread; what keeps the cores from being oversubscribed is the
slot a model run holds. These tests check the schedule's promises on counters and events, not on time:
runs never exceed the slots, nested items do run side by side, results keep their order, a point asked
for by two threads at once is run once, and a batch of model runs gives the same tracks either way.
"""

from __future__ import annotations

import threading
import time
import types

import numpy as np
import pytest

from smarticle_mjx.calibrate import sim


class _Meter:
    def __init__(self):
        self.lock = threading.Lock()
        self.now = 0
        self.most = 0

    def run(self, x, hold=0.02):
        with sim.slot():
            with self.lock:
                self.now += 1
                self.most = max(self.most, self.now)
            time.sleep(hold)
            with self.lock:
                self.now -= 1
        return x * x


@pytest.fixture
def two_slots(monkeypatch):
    monkeypatch.setattr(sim, "_SLOTS", threading.BoundedSemaphore(2))
    monkeypatch.setattr(sim.os, "cpu_count", lambda: 2)


def test_nested_runs_share_the_cores_and_never_exceed_them(two_slots):
    """Three outer items, each a pmap of four runs: twelve runs on two slots. At most two hold a slot at
    once, and every result comes back in order."""
    m = _Meter()
    out = sim.pmap(lambda i: sim.pmap(lambda j: m.run(10 * i + j), range(4)), range(3))
    assert out == [[(10 * i + j) ** 2 for j in range(4)] for i in range(3)]
    assert m.most == 2


def _one_busy_worker(m):
    """Two outer items in workers: the first makes four runs, the second none (it ends at once, as a fit
    that converged early leaves its core)."""
    return sim.pmap(lambda i: sim.pmap(lambda j: m.run(j), range(4)) if i == 0 else [], range(2))


def test_a_workers_own_runs_take_the_core_another_worker_left(two_slots):
    """Nested runs go side by side: the busy worker's four runs use both slots once the other is done."""
    m = _Meter()
    assert _one_busy_worker(m) == [[0, 1, 4, 9], []]
    assert m.most == 2


def test_the_earlier_schedule_runs_a_workers_items_in_order(two_slots, monkeypatch):
    """NESTED = False (the schedule before 0.4.11, kept for benchmarks/calibration_schedule.py): the busy
    worker's runs go one after another beside the idle core."""
    monkeypatch.setattr(sim, "NESTED", False)
    m = _Meter()
    assert _one_busy_worker(m) == [[0, 1, 4, 9], []]
    assert m.most == 1


def test_a_run_outside_any_worker_takes_no_slot(two_slots):
    """The caller's own run (no pmap around it) has every core: it must not wait for a slot, even with
    every slot taken."""
    for _ in range(2):
        sim._SLOTS.acquire()
    try:
        with sim.slot():
            pass  # would block forever if it took a slot
    finally:
        for _ in range(2):
            sim._SLOTS.release()


def _bare_problem(F, monkeypatch, n):
    """A fit.Problem built the usual way over ``n`` stand-in trials, its features and masks stubbed (the
    tests below are about who runs a point, not about what it gives)."""
    monkeypatch.setattr(F, "features", lambda *a, **k: "features")
    monkeypatch.setattr(F, "masked", lambda mt, tr: (None, None))
    return F.Problem([types.SimpleNamespace(t=None, pose=None, arms=None, periods=None)] * n)


def test_a_point_two_threads_ask_for_at_once_is_run_once(monkeypatch):
    """Two fits side by side asking for the same (effects, nominal values) share one model run: the
    second waits for the first's and reads it from the cache."""
    from smarticle_mjx.calibrate import fit as F
    from smarticle_mjx.calibrate.effects import EffectSet

    calls = []
    started = threading.Event()

    def slow_sim(trials, scene_for, phase_for=None, nthread=None):
        calls.append(1)
        started.set()
        time.sleep(0.2)
        return [None] * len(trials)

    monkeypatch.setattr(F, "simulate_trials", slow_sim)
    p = _bare_problem(F, monkeypatch, 2)
    got = []
    first = threading.Thread(target=lambda: got.append(p.model(EffectSet())))
    first.start()
    started.wait(5)
    second = threading.Thread(target=lambda: got.append(p.model(EffectSet())))
    second.start()
    first.join(5)
    second.join(5)
    assert len(calls) == 1 and p.runs == 1
    assert len(got) == 2 and got[0] is got[1]
    assert not p._running


def test_a_failed_run_is_not_left_waited_on(monkeypatch):
    """A run that raises is not cached, and nothing is left marked as running: the next ask runs it."""
    from smarticle_mjx.calibrate import fit as F
    from smarticle_mjx.calibrate.effects import EffectSet

    def broken(trials, scene_for, phase_for=None, nthread=None):
        raise RuntimeError("model failed")

    monkeypatch.setattr(F, "simulate_trials", broken)
    p = _bare_problem(F, monkeypatch, 1)
    with pytest.raises(RuntimeError):
        p.model(EffectSet())
    assert not p._running and not p._cache
    with pytest.raises(RuntimeError):
        p.model(EffectSet())


def test_model_runs_give_the_same_tracks_on_either_schedule(tmp_path, monkeypatch):
    """The same trials (two robots of the independent simulator, two gaits) run by Jacobian-like batches of
    nominal values, once with nested runs side by side and once in the earlier order: the tracks agree to
    the last bit, as each run is the same computation on one thread."""
    from smarticle_mjx.calibrate import independent as I
    from smarticle_mjx.calibrate.data import load
    from smarticle_mjx.calibrate.effects import EffectSet
    from smarticle_mjx.calibrate.fit import Problem

    I.write_case(tmp_path, robots=2, gaits=[(30.0, "ccw"), (60.0, "ccw")], trials=2, periods=2, seed=5)
    trials = load(tmp_path)
    points = [(EffectSet(), {"servo_speed": v}) for v in (7.0, 8.0, 9.0)]

    def tracks(nested):
        monkeypatch.setattr(sim, "NESTED", nested)
        p = Problem(trials)
        out = sim.pmap(lambda pt: p.model(*pt)[0], points)
        return out

    a, b = tracks(True), tracks(False)
    for x, y in zip(a, b):
        for u, v in zip(x, y):
            np.testing.assert_array_equal(u, v)
    assert not np.array_equal(a[0][0], a[2][0])  # the servo speed does move the arms


def test_the_schedule_benchmark_refuses_a_malformed_set_in_one_line():
    """benchmarks/calibration_schedule.py names a set SEED/INDEX; anything else stops before any run,
    with one line naming what was given and exit status 2."""
    import pathlib
    import subprocess
    import sys
    script = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "calibration_schedule.py"
    r = subprocess.run([sys.executable, str(script), "--set", "2141-4"], capture_output=True, text=True)
    assert r.returncode == 2
    assert "a set is SEED/INDEX, e.g. 2141/4, not '2141-4'" in r.stderr.strip().splitlines()[-1]
