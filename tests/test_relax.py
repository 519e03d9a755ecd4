"""The relaxation experiment: start packing, glider detector, store, report, CLI."""

import hashlib
import json
import math

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from smarticle_mjx import configs as C, presets
from smarticle_mjx.cli import app
from smarticle_mjx.reduce import relaxation as RX
from smarticle_mjx.scene import SceneParams

W = 0.05


# ------------------------------------------------------------ synthetic tracks

def _synthetic(k=150, n=4):
    """Robots 0 and 1 glide together along +x at 0.02 W/period, anti-aligned
    (C1), touching every period; robots 2 and 3 sit 10 W away and touch each
    other for 50 periods only (too short to be a glider)."""
    poses = np.zeros((k, n, 5))
    start = np.zeros((n, 5))
    step = 0.02 * W
    for r, (y, h) in enumerate([(0.0, 0.0), (1.3 * W, math.pi)]):
        start[r, :3] = (0.0, y, h)
        poses[:, r, 0] = step * np.arange(1, k + 1)
        poses[:, r, 1] = y
        poses[:, r, 2] = h
    for r, x in ((2, 10 * W), (3, 11.2 * W)):
        start[r, :3] = (x, 10 * W, 0.0)
        poses[:, r, :3] = (x, 10 * W, 0.0)
    pairs = RX.pairs_of(n)
    touched = np.zeros((k, len(pairs)), bool)
    touched[:, 0] = True  # pair (0, 1)
    p23 = [i for i, (a, b) in enumerate(pairs) if (a, b) == (2, 3)][0]
    touched[20:70, p23] = True
    return poses, touched, start, pairs


def test_detector_finds_the_known_glider_and_rejects_the_short_pair():
    poses, touched, start, _ = _synthetic()
    eps = RX.trial_episodes(poses, touched, start, body_length=W)
    by_pair = {e.pair: e for e in eps}
    g = by_pair[(0, 1)]
    # brute force: the pair centre moves 0.02 W per period for 150 periods in a straight line
    assert g.start == 0 and g.lifetime == 150 and g.censored
    assert g.distance_W == pytest.approx(0.02 * 150, rel=1e-9)
    assert g.contour_W == pytest.approx(0.02 * 150, rel=1e-9)
    assert g.kind == "C1" and g.mean_cos_phi == pytest.approx(-1.0)
    short = by_pair[(2, 3)]
    assert short.lifetime == 50 and not short.censored
    long_enough = [e for e in eps if e.lifetime >= 100]
    assert [e.pair for e in long_enough] == [(0, 1)]


def test_a_third_robot_nearby_or_touching_breaks_the_glider():
    poses, touched, start, pairs = _synthetic()
    # robot 2 parks next to the glider for 10 periods mid-way (within 2 W), without touching
    near = poses.copy()
    near[70:80, 2, :2] = near[70:80, 0, :2] + np.array([0.0, -1.5 * W])
    eps = RX.trial_episodes(near, touched, start, body_length=W, apart_W=2.0)
    runs = sorted((e.start, e.lifetime) for e in eps if e.pair == (0, 1))
    assert runs == [(0, 70), (80, 70)]
    # touching a third robot for one period splits it the same way, whatever the distance
    t2 = touched.copy()
    p02 = [i for i, (a, b) in enumerate(pairs) if (a, b) == (0, 2)][0]
    t2[100, p02] = True
    eps = RX.trial_episodes(poses, t2, start, body_length=W)
    assert sorted((e.start, e.lifetime) for e in eps if e.pair == (0, 1)) == [(0, 100), (101, 49)]
    # a robot off the plate ends its pair's episode there
    eps = RX.trial_episodes(poses, touched, start, left_plate=np.array([0, 120, 0, 0]), body_length=W)
    g = [e for e in eps if e.pair == (0, 1)][0]
    assert g.lifetime == 119 and not g.censored


def test_aligned_pair_is_C2_and_early_stop_is_not_censored():
    poses, touched, start, _ = _synthetic()
    poses[:, 1, 2] = 0.0
    start[1, 2] = 0.0
    eps = RX.trial_episodes(poses, touched, start, body_length=W, periods_run=140)
    g = [e for e in eps if e.pair == (0, 1)][0]
    assert g.kind == "C2" and g.lifetime == 140 and not g.censored


def test_relaxation_time_and_fit_by_brute_force():
    n = 4
    pairs = RX.pairs_of(n)
    touched = np.zeros((50, len(pairs)), bool)
    touched[:30, 0] = touched[:30, 1] = True  # robot 0 touches 1 and 2 until period 30
    touched[:, 5] = True  # robots 2, 3 bound throughout: never a robot with two partners after 30
    assert RX.relaxation_time(touched) == (30, False)
    touched[49, 0] = touched[49, 1] = True  # robot 0 touches 1 and 2 again in the last period: still crowded
    assert RX.relaxation_time(touched) == (50, True)
    eps = [RX.Episode((0, 1), 0, L, False, 0.0, 0.01 * L + 0.2, "C1", -1.0, np.zeros((L + 1, 2))) for L in (5, 10, 40, 90)]
    fit = RX.lifetime_contour_fit(eps)
    assert fit.slope == pytest.approx(0.01) and fit.intercept == pytest.approx(0.2)
    assert fit.r == pytest.approx(1.0) and fit.n == 4


def test_analyse_counts_gliders_with_exact_interval():
    poses, touched, start, _ = _synthetic()
    t = 10
    touched = np.repeat(touched[None], t, 0)
    touched[7:, :, 0] = False  # three trials without the glider
    data = _record(poses=np.repeat(poses[None], t, 0), touched=touched,
                   start_poses=np.repeat(start[None], t, 0), left_plate=np.zeros((t, 4), np.int32),
                   periods_run=np.full(t, 150), valid=np.ones(t, bool), status=np.zeros(t, np.int32),
                   trial=np.arange(t), body_length=W, periods=150)
    a = RX.analyse_relaxation(data)
    assert (a.emerged, a.valid) == (7, 10)
    from scipy.stats import binomtest
    ci = binomtest(7, 10).proportion_ci(0.95, method="exact")
    assert a.interval == pytest.approx((ci.low, ci.high))
    assert a.distance.mean == pytest.approx(3.0) and a.distance.n == 7
    assert (a.glider_kinds.c1, a.glider_kinds.c2) == (7, 0) and a.as_json()["glider_kinds"] == {"C1": 7, "C2": 0}


# ------------------------------------------------------------ the start

@pytest.mark.parametrize("n", [2, 7, 12])
def test_packing_is_compressed_and_overlap_free(n):
    """Every robot starts at the gait's first corner, no two overlap, and the
    packing is tight: some neighbours are exactly ``gap`` apart (the lattice
    spacing is the bounding box plus the gap)."""
    from smarticle_mjx.relax import packing
    robot = presets.params().robot
    gap = 0.002
    p = packing(n, robot, (math.pi / 2, math.pi / 2), gap)
    assert p.shape == (n, 5) and np.allclose(p[:, 2:], [0, math.pi / 2, math.pi / 2])
    sep = np.array([C.pair_separation(p[i], p[j], robot) for i in range(n) for j in range(i + 1, n)])
    assert sep.min() == pytest.approx(gap, abs=2e-4)
    # compressed: the centres fit in a disc a little larger than n robots side by side would need
    r = np.linalg.norm(p[:, :2] - p[:, :2].mean(0), axis=1).max()
    assert r < 0.5 * math.sqrt(n) * 2 * robot.arm_length + robot.body_length


def test_trials_do_not_depend_on_the_stage():
    from smarticle_mjx.relax import RelaxConfig, start_poses
    params = presets.params()
    a, _ = start_poses(RelaxConfig(trials=3), params)
    b, _ = start_poses(RelaxConfig(trials=1, first_trial=2), params)
    assert np.array_equal(a[2:], b)
    assert not np.array_equal(a[0], a[1])
    assert C.poses_valid(a, params.robot).all()


def test_hex_start_is_one_robot_ringed_by_six_at_the_closest_clear_spacing():
    from smarticle_mjx.relax import hex_pack
    robot = presets.params().robot
    p = hex_pack(7, robot, (math.pi / 2, math.pi / 2), None, 0.002)
    d = np.linalg.norm(p[:, :2] - p[:, :2].mean(0), axis=1)
    centre = int(np.argmin(d))
    ring = np.delete(d, centre)
    assert d[centre] == pytest.approx(0, abs=1e-12) and np.allclose(ring, ring[0])  # a regular hexagon
    ang = np.sort(np.degrees(np.arctan2(*(p[:, 1::-1][np.arange(7) != centre] - p[centre, 1::-1]).T)) % 360)
    assert np.allclose(np.diff(ang), 60)
    # the closest clear spacing plus 2 mm along the line of centres (at 60 deg to the faces that
    # meet, so 2 mm x cos 30 deg between them), overlapping 3 mm closer
    sep = [C.pair_separation(p[i], p[j], robot) for i in range(7) for j in range(i + 1, 7)]
    assert 0.002 * math.cos(math.pi / 6) - 2e-4 <= min(sep) <= 0.002 + 2e-4
    closer = hex_pack(7, robot, (math.pi / 2, math.pi / 2), ring[0] - 0.003, 0.0)
    assert not C.poses_valid(closer, robot)


@pytest.mark.parametrize("start", ["lattice", "hex"])
@pytest.mark.parametrize("phi", [0.4, 0.6])
def test_start_family_is_scaled_to_its_area_fraction_and_overlap_free(start, phi):
    from smarticle_mjx.relax import RelaxConfig, area_fraction_of, base_start, start_poses
    from smarticle_mjx.reduce.relaxation import hull_area
    params = presets.params()
    cfg = RelaxConfig(trials=2, start=start, start_phi=phi)
    base = base_start(cfg, params.robot, (math.pi / 2, math.pi / 2))
    # Savoie's phi of the unperturbed start, by the hull's shoelace area as a second computation
    hull = hull_area(base[:, :2])
    assert area_fraction_of(base, params.robot) == pytest.approx(phi, rel=1e-9)
    assert 7 * params.robot.body_length * params.robot.body_thickness / hull == pytest.approx(phi, rel=1e-9)
    starts, _ = start_poses(cfg, params)
    assert C.poses_valid(starts, params.robot).all()
    drawn, _ = start_poses(RelaxConfig(trials=2, start=start, start_phi=phi, headings="drawn"), params)
    assert C.poses_valid(drawn, params.robot).all()
    assert np.ptp(np.mod(drawn[..., 2], 2 * math.pi)) > math.pi  # headings spread round the circle
    # the aligned trials keep the stream they had before headings could be drawn
    assert np.array_equal(start_poses(RelaxConfig(trials=2), params)[0],
                          start_poses(RelaxConfig(trials=2, headings="aligned"), params)[0])


def test_bad_start_is_one_line():
    from smarticle_mjx.relax import RelaxConfig, start_poses
    params = presets.params()
    for cfg, says in ((RelaxConfig(start_phi=0.95), "overlaps; lower --start-phi"),
                      (RelaxConfig(start="ring"), "--start must be lattice or hex"),
                      (RelaxConfig(headings="random"), "--headings must be aligned or drawn"),
                      (RelaxConfig(start_phi=1.5), "--start-phi must lie between 0 and 1")):
        with pytest.raises(ValueError, match=says):
            cfg.validate(params)
            start_poses(cfg, params)
    assert "start" not in RelaxConfig().to_json() and "start_phi" not in RelaxConfig().to_json()
    assert RelaxConfig(start="hex", start_phi=0.5).to_json()["start_phi"] == 0.5


# ------------------------------------------------------------ end to end

def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_relax_cli_store_report_and_bad_input(tmp_path):
    run = CliRunner()
    out = tmp_path / "relax.h5"
    r = run.invoke(app, ["relax", "--robots", "3", "--trials", "2", "--periods", "4", "--out", str(out), "--quiet"])
    assert r.exit_code == 0, r.output
    with h5py.File(out, "r") as f:
        g = f["runs/trials"]
        assert g["poses"].shape == (2, 4, 3, 5) and g["touched"].shape == (2, 4, 3)
        assert g["start_poses"].shape == (2, 3, 5) and g["left_plate"].shape == (2, 3)
        assert g["lane"].attrs["long_name"] == "trial index"
        assert json.loads(f.attrs["config"])["relax"]["n_robots"] == 3
    import xarray as xr
    with xr.open_dataset(out, group="runs/trials", engine="h5netcdf") as ds:  # named dimensions, as for scans
        assert ds.poses.dims == ("lane", "period", "robot", "pose_var") and ds.left_plate.dims == ("lane", "robot")
    rep = tmp_path / "rep"
    r = run.invoke(app, ["report", str(out), "--out", str(rep), "--glider-min-periods", "2"])
    assert r.exit_code == 0, r.output
    j = json.loads((rep / "report.json").read_text())
    assert j["kind"] == "relax" and j["trials"] == 2 and (rep / "relax_tracks.png").exists()
    assert "77/151" in (rep / "report.md").read_text()
    # the crowd's measures: every usable trial measured, their rows beside the lab's, their figure
    assert j["crowd"]["trials"] == 2 and j["crowd"]["plateau"]["n"] == 2 and (rep / "crowd.png").exists()
    assert "chain lifetime" in (rep / "report.md").read_text() and "8–10 periods" in (rep / "report.md").read_text()
    # the emergence reading it leads with is named (the primary by default), the others are printed, and every
    # usable trial's touch runs are kept (each pair of 3 robots touching >= 2 periods in a row: keep_periods
    # follows a --glider-min-periods below 10)
    assert j["reading"] == "pair" and set(j["emergence"]["readings"]) == {"apart", "touch", "moved", "pair"}
    assert [r["trial"] for r in j["emergence"]["runs"]] == [0, 1] and j["emergence"]["keep_periods"] == 2
    assert "reading (d)" in r.output and "other readings (--reading): apart" in r.output
    md = (rep / "report.md").read_text()
    assert "| trials forming a glider, (d)" in md and md.count("(primary)") == 1
    # chains followed by overlap beside the exact rule, and the crowd's fitted spreading time constants
    assert j["chains"]["overlap"]["n"] >= 0 and set(j["spreading"]) >= {"phi_tau", "contacts_tau", "first_period_share"}
    assert "followed by overlap" in md and "spreading time constant τ" in md
    r = run.invoke(app, ["report", str(out), "--out", str(tmp_path / "rep_a"), "--reading", "apart",
                         "--glider-min-periods", "2"])
    assert r.exit_code == 0 and "reading (a) bound and apart" in r.output, r.output
    assert json.loads((tmp_path / "rep_a" / "report.json").read_text())["reading"] == "apart"
    r = run.invoke(app, ["report", str(out), "--out", str(tmp_path / "rep_x"), "--reading", "loose"])
    assert r.exit_code == 2 and r.output.startswith("error: unknown reading 'loose'") and r.output.count("\n") == 1
    assert not (tmp_path / "rep_x").exists()
    # the glider's distance is a transport number: its row says what is known of the store's step. The
    # default step passed the glider check (reduce.stepcheck); the 0.5 ms step of versions 0.3.x did not
    row = next(ln for ln in (rep / "report.md").read_text().splitlines() if ln.startswith("| distance travelled"))
    assert f"{SceneParams.timestep * 1e3:g} ms implicitfast: checked, passed" in row, row
    assert j["step_check"]["status"] == "passed"
    old = tmp_path / "relax_05.h5"
    r = run.invoke(app, ["relax", "--robots", "3", "--trials", "1", "--periods", "2", "--out", str(old), "--quiet",
                         "--set", "timestep=0.0005"])
    assert r.exit_code == 0, r.output
    r = run.invoke(app, ["report", str(old), "--out", str(tmp_path / "rep05"), "--glider-min-periods", "2"])
    assert r.exit_code == 0, r.output
    row = next(ln for ln in (tmp_path / "rep05" / "report.md").read_text().splitlines()
               if ln.startswith("| distance travelled"))
    assert "0.5 ms implicitfast: biased against 0.0625 ms, β +0.14" in row and "net speed +39%" in row, row
    before = _digest(out)
    for args in (["--robots", "1"], ["--jitter-mm", "-1"], ["--trials", "0"], ["--amplitude", "120"], []):
        r = run.invoke(app, ["relax", "--trials", "2", "--periods", "4", "--out", str(out), "--quiet", *args])
        assert r.exit_code == 2, (args, r.output)
        assert r.output.strip().count("\n") == 0 and r.output.startswith("error:"), r.output
    assert _digest(out) == before  # nothing stored was touched
    scan = tmp_path / "scan.h5"
    assert run.invoke(app, ["scan", "--n", "2", "--periods", "1", "--out", str(scan), "--quiet"]).exit_code == 0
    r = run.invoke(app, ["report", str(out), str(scan), "--out", str(rep)])
    assert r.exit_code == 2 and "stages of one relaxation study" in r.output


def test_relax_resumes_after_a_kill_and_stages_pool(tmp_path):
    """A run stopped after its first trial was journaled resumes to the same
    store as an uninterrupted run; two stages read together equal one store."""
    from smarticle_mjx.relax import RelaxConfig, run_relax
    from smarticle_mjx.store import read_relax
    cfg = RelaxConfig(n_robots=3, trials=3, periods=3, batch_size=1)
    whole = tmp_path / "whole.h5"
    run_relax(cfg, whole)

    class Killed(Exception):
        pass

    def die(p):
        if p["done"] >= 1:
            raise Killed

    cut = tmp_path / "cut.h5"
    with pytest.raises(Killed):
        run_relax(cfg, cut, on_progress=die)
    assert not cut.exists() and (tmp_path / "cut.h5.parts").exists()
    run_relax(cfg, cut, mode="resume")
    a, b = read_relax(whole), read_relax(cut)
    for k in ("poses", "touched", "start_poses", "left_plate", "periods_run"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    s0, s1 = tmp_path / "s0.h5", tmp_path / "s1.h5"
    run_relax(RelaxConfig(n_robots=3, trials=1, periods=3, batch_size=1), s0)
    run_relax(RelaxConfig(n_robots=3, trials=2, first_trial=1, periods=3, batch_size=1), s1)
    c = read_relax([s1, s0])
    assert np.array_equal(c.trial, [0, 1, 2])
    for k in ("poses", "touched", "start_poses"):
        assert np.array_equal(getattr(a, k), getattr(c, k)), k
    other = tmp_path / "other.h5"
    run_relax(RelaxConfig(n_robots=3, trials=1, periods=3, seed=5), other)
    from smarticle_mjx.store import StoreError
    with pytest.raises(StoreError, match="not stages of one study"):
        read_relax([s0, other])


def test_robots_leaving_a_small_plate_are_recorded(tmp_path):
    """The plate is a record, not a wall: a robot whose centre crosses its
    edge during the run is recorded at the period it first ends outside, and
    the motion is the same whatever the plate's size. A first trial on the
    lab's 0.6 m plate (nobody leaves) gives the robots' paths; the edge is
    then put between where a robot is at the end of period 1 and where it
    goes later, at least 1 mm from every robot's position at every period
    end, so crossing mid-run is exercised and no crossing is a rounding call."""
    from smarticle_mjx.relax import RelaxConfig, run_relax
    from smarticle_mjx.store import read_relax
    big, small = tmp_path / "big.h5", tmp_path / "small.h5"
    run_relax(RelaxConfig(trials=1, periods=6), big)
    ref = read_relax(big)
    assert (ref.left_plate == 0).all()
    start = np.abs(ref.start_poses[0][:, :2]).max(-1)  # [N] distance from the centre along the worse axis
    dist = np.abs(ref.poses[0][:, :, :2]).max(-1)  # [K, N] the same at each period end
    edges = np.sort(dist[1:].ravel())
    half = next(h for h in (edges[:-1] + edges[1:]) / 2
                if np.abs(dist - h).min() > 1e-3 and (start < h).all()
                and ((dist[0] < h) & (dist.max(0) > h)).any() and (dist.max(0) < h).any())
    want = np.where((dist > half).any(0), np.argmax(dist > half, 0) + 1, 0)
    assert (want >= 2).any() and (want == 0).any()
    run_relax(RelaxConfig(trials=1, periods=6, plate_m=float(2 * half)), small)
    got = read_relax(small)
    np.testing.assert_array_equal(got.poses, ref.poses)
    np.testing.assert_array_equal(got.left_plate[0], want)


def test_run_study_runs_a_scan_or_a_relaxation_and_refuses_a_staged_study(tmp_path):
    """One entry point for a study of one store: the same store as the runner called directly;
    a staged study (several stores) is refused in one line."""
    from storecmp import assert_same_store
    from smarticle_mjx.relax import run_relax
    from smarticle_mjx.specs import RelaxConfig, RelaxStudy, ScanConfig
    from smarticle_mjx.scan import run_scan
    from smarticle_mjx.studies import run_study
    cfg = RelaxConfig(n_robots=3, trials=2, periods=3)
    run_relax(cfg, tmp_path / "a.h5")
    run_study(cfg, tmp_path / "b.h5")
    assert_same_store(tmp_path / "a.h5", tmp_path / "b.h5")
    sc = ScanConfig(n=6, periods=2)
    run_scan(sc, tmp_path / "c.h5")
    run_study(sc, tmp_path / "d.h5", flush_rows=2)
    assert_same_store(tmp_path / "c.h5", tmp_path / "d.h5")
    with pytest.raises(ValueError, match="staged study"):
        run_study(RelaxStudy(stages=2, trials=1), tmp_path / "e.h5")


def _record(**kw):
    """A relaxation store's record (store.RelaxRecord) built from arrays, metadata filled in."""
    from smarticle_mjx.store import RelaxRecord
    t = len(kw["valid"])
    base = dict(min_dist=np.full(np.shape(kw["touched"]), np.inf), trial=np.arange(t), settings={}, periods=150,
                period_s=1.6, model="built", overrides={}, body_thickness=0.021, paths=())
    return RelaxRecord(**{**base, **kw})


def test_a_relaxation_page_says_which_start_and_synchrony_its_stores_ran():
    """Reports and validation pages describe the start from the stored settings, not as the paper's
    in-phase start whatever ran: start offsets from --phase-jitter and from an imperfection set are named
    with their combined s.d., the per-cycle retrigger, the hexagonal pack, drawn headings and an area
    fraction; a store written before the start family existed reads as the default lattice."""
    from smarticle_mjx.specs import RelaxConfig, relax_config_from_json
    ideal = RelaxConfig().start_words()
    assert "in phase" in ideal and "staggered lattice" in ideal and "gap 2 mm" in ideal and "offsets" not in ideal
    lab = RelaxConfig(imperfections="lab-resync").start_words()
    assert "s.d. 0.02 periods" in lab and "in phase" not in lab
    both = RelaxConfig(imperfections="lab", phase_jitter=0.03, retrigger_sd=0.01, start="hex", headings="drawn",
                       start_phi=0.5).start_words()
    assert "s.d. 0.0361 periods" in both  # hypot(0.02, 0.03)
    assert "re-triggered each cycle" in both and "hexagonal pack" in both and "headings drawn" in both
    assert "area fraction 0.5" in both and "gap" not in both
    old = {k: v for k, v in RelaxConfig().to_json().items()
           if k not in ("start", "headings", "start_phi", "retrigger_sd")}
    assert relax_config_from_json(old).start_words() == ideal


def test_the_old_name_of_the_relaxation_analysis_warns_and_gives_the_same_numbers(tmp_path):
    """One name per public function: reduce.relaxation.analyse is now analyse_relaxation (the scan's is
    reduce.analysis.analyse); the old name works for one release, with a DeprecationWarning."""
    import warnings
    from smarticle_mjx.reduce import relaxation as RX2
    from smarticle_mjx.relax import RelaxConfig, run_relax
    from smarticle_mjx.store import read_relax
    out = tmp_path / "r.h5"
    run_relax(RelaxConfig(n_robots=3, trials=1, periods=3, quiet_periods=0), out)
    data = read_relax(out)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        old = RX2.analyse(data, min_periods=2)
    assert any(issubclass(w.category, DeprecationWarning) and "analyse_relaxation" in str(w.message) for w in caught)
    import json
    assert json.dumps(old.as_json()) == json.dumps(RX2.analyse_relaxation(data, min_periods=2).as_json())
