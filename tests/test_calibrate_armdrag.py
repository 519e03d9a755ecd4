"""Arms dragging on the plate, read off the body's heading without the model (calibrate.armdrag), and what
the calibration does with the reading (stages.drag_plan).

The physical fact: an arm clear of the plate pushes its body only while it speeds up or slows down (a kick
at each end of a swing), and friction holds the body still while the arm turns at a steady speed; an arm
resting on the plate drags on it for the whole swing and turns the body all along. Checked on heading tracks
built with numpy (no simulator) and on the independent simulator's robots (calibrate/independent.py, which
shares no code with the library's model)."""

import json
import math

import numpy as np
import pytest

from smarticle_mjx.calibrate import armdrag
from smarticle_mjx.calibrate import data as D
from smarticle_mjx.calibrate import independent as IND


def _write(path, name, amplitude, headings, t, fr, robots=1, spacing=0.3):
    """One interchange CSV + sidecar: ``robots`` robots ``spacing`` m apart along x, each with the given
    heading track per trial."""
    lines = ["trial,t,robot,x,y,theta,alpha1,alpha2"]
    for k, h in enumerate(headings):
        lines += [f"{k},{tf:.6f},{i},{i * spacing},0.0,{hf:.7f},," for tf, hf in zip(t, h) for i in range(robots)]
    (path / f"{name}.csv").write_text("\n".join(lines) + "\n")
    T = 1.6 * amplitude / 90.0
    (path / f"{name}.json").write_text(json.dumps({"robots": robots, "frame_rate_hz": fr, "plate": {"friction": 0.37},
                                                   "gait": {"kind": "square", "amplitude_deg": amplitude,
                                                            "period_s": T, "chirality": "ccw"}}))


def _heading(t, q, drag_deg_s, kick_deg, noise_deg, rng, delay=0.03):
    """A heading built from its rate: in each quarter a kick at the swing's start (+kick over ~25 ms) and one
    at its end (-0.5 kick, so that a quarter's kicks leave a net turn, as a real robot's do), and between them a steady turn of drag_deg_s whose sense follows the quarter's
    kind (+, -, -, +: which arm swings which way)."""
    fine = np.arange(0.0, t[-1] + 0.01, 1e-4)
    k = np.floor(fine / q).astype(int)
    u = fine - k * q
    swing = 0.9 * q
    sense = np.array([1.0, -1.0, -1.0, 1.0])[k % 4]
    pulse = lambda c, w: np.exp(-0.5 * ((u - c) / w) ** 2) / (w * math.sqrt(2 * math.pi))
    rate = kick_deg * sense * (pulse(delay + 0.012, 0.006) - 0.5 * pulse(delay + swing - 0.012, 0.006))
    rate += drag_deg_s * sense * ((u > delay + 0.02) & (u < delay + swing - 0.02))
    h = np.cumsum(rate) * 1e-4
    return np.radians(np.interp(t, fine, h) + rng.normal(0.0, noise_deg, len(t)))


def _built(tmp_path, drag_deg_s, fr=60.0, amplitudes=(60.0, 90.0), noise_deg=0.5, seed=0, **where):
    tmp_path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    for a in amplitudes:
        T = 1.6 * a / 90.0
        t = np.arange(0.0, 5 * T, 1.0 / fr)
        _write(tmp_path, f"a{int(a)}", a, [_heading(t, T / 4, drag_deg_s, 4.0, noise_deg, rng) for _ in range(2)],
               t, fr, **where)
    return D.load(tmp_path)


def test_a_body_that_turns_between_the_kicks_is_read_as_arms_dragging_at_its_rate(tmp_path):
    """Built tracks turning at 8 deg/s between kicks of 4 and -2 deg, with 0.5 deg of tracking noise a frame:
    present, and the steady rate read within 15 %."""
    dt = armdrag.drag_test(_built(tmp_path, 8.0))
    assert dt.present and not dt.absent
    assert dt.rate_deg_s == pytest.approx(8.0, rel=0.15)


def test_kicks_alone_are_not_read_as_drag(tmp_path):
    """The same kicks, no turning between them: with 0.1 deg of noise absent (a turn of 2 deg/s would have
    shown), with 0.5 deg never present, for three draws of the noise each. The kicks' net 2 deg a quarter
    would read present were they not left out."""
    for seed in range(3):
        dt = armdrag.drag_test(_built(tmp_path / f"fine{seed}", 0.0, seed=seed, noise_deg=0.1))
        assert dt.applicable and dt.absent and dt.upper_deg_s < armdrag.DETECTABLE
        dt = armdrag.drag_test(_built(tmp_path / f"noisy{seed}", 0.0, seed=seed))
        assert dt.applicable and not dt.present


def test_robots_that_may_touch_are_not_read(tmp_path):
    """The same turning tracks on two robots 3 cm apart (they may touch: collisions turn robots between
    kicks too) give no reading; 30 cm apart they read present."""
    near = armdrag.drag_test(_built(tmp_path / "near", 8.0, robots=2, spacing=0.03))
    assert near is None or not near.applicable
    assert armdrag.drag_test(_built(tmp_path / "far", 8.0, robots=2, spacing=0.3)).present


def test_too_few_frames_per_quarter_give_no_reading(tmp_path):
    """At 30 Hz a 15 deg gait's quarter (67 ms) holds two frames: the swing's timing cannot be resolved, and
    nothing is read."""
    dt = armdrag.drag_test(_built(tmp_path, 8.0, fr=30.0, amplitudes=(15.0,)))
    assert dt is None or not dt.applicable


@pytest.mark.parametrize("arm_plate_mu, present", [(0.3, True), (0.0, False)])
def test_the_independent_simulators_arms_on_the_plate_are_read(tmp_path, arm_plate_mu, present):
    """The independent simulator's robot, 90 deg, 60 Hz, its usual tracking noise: arms resting on a plate
    of mu 0.3 are present, arms clear of it absent."""
    IND.write_case(tmp_path, robots=1, amplitude_deg=90.0, trials=2, periods=4, seed=3, frame_rate=60.0,
                   arms_tracked=False, name="a90", noise_theta_deg=0.3, arm_plate_mu=arm_plate_mu)
    dt = armdrag.drag_test(D.load(tmp_path))
    assert dt.applicable and dt.present is present


def test_the_plan_fits_dragging_arms_jointly_and_leaves_clean_ones_unfitted():
    """stages.drag_plan: present adds the joint hypothesis (which calibrate() keeps out of the rounds);
    absent takes them out of every fit unless the user asked for the joint fit; undecided and no reading
    change nothing."""
    from smarticle_mjx.calibrate.effects import LIBRARY
    from smarticle_mjx.calibrate.stages import ARM_PLATE, drag_plan
    names = lambda lib: {e.name for e in lib}
    assert ARM_PLATE in names(LIBRARY)
    yes = armdrag.DragTest(8, 500.0, 1e-50, 30.0, 40.0)
    no = armdrag.DragTest(8, 6.0, 0.65, 0.1, 0.3, 0.05)
    plates, lib, _ = drag_plan(yes, ("anisotropic_friction",), LIBRARY)
    assert plates == ("anisotropic_friction", ARM_PLATE) and lib == LIBRARY  # the joint fit draws on the library
    plates, lib, _ = drag_plan(no, ("anisotropic_friction",), LIBRARY)
    assert plates == ("anisotropic_friction",) and ARM_PLATE not in names(lib)
    plates, lib, what = drag_plan(no, ("anisotropic_friction", ARM_PLATE), LIBRARY)
    assert ARM_PLATE in plates and "asked" in what
    # a turn that misses the p threshold under heavy noise (fresh seed 2048, set 2: arms at mu 0.3 under
    # 0.8 deg of tracking noise read 16 deg/s at p = 0.0014) rules nothing out
    between = armdrag.DragTest(4, 17.7, 0.0014, 15.96, 20.0, 4.0)
    assert between.undecided and not between.absent and not between.present
    assert drag_plan(between, ("anisotropic_friction",), LIBRARY)[:2] == (("anisotropic_friction",), LIBRARY)
    few = armdrag.DragTest(2, 500.0, 1e-50, 30.0, 40.0)
    assert not few.applicable
    assert drag_plan(few, ("anisotropic_friction",), LIBRARY)[:2] == (("anisotropic_friction",), LIBRARY)
    assert drag_plan(None, ("anisotropic_friction",), LIBRARY)[:2] == (("anisotropic_friction",), LIBRARY)


def test_the_report_prints_the_reading_and_what_was_done():
    from smarticle_mjx.calibrate.report import drag_markdown
    d = {**armdrag.DragTest(8, 500.0, 1e-50, 31.25, 40.0).as_dict(), "action": "present: fitted jointly"}
    md = "\n".join(drag_markdown(d))
    assert "31.25 deg/s" in md and "**Present: fitted jointly.**" in md
    assert drag_markdown(None) == [] and drag_markdown({**d, "applicable": False}) == []
