"""smx movie: frames and sizes, the re-simulated lane is the stored lane, bad input is one line."""

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from smarticle_mjx import presets
from smarticle_mjx.cli import app
from smarticle_mjx.movie import MovieOptions, frame_times, render
from smarticle_mjx.replay import resimulate_lane
from smarticle_mjx.scan import ScanConfig, run_scan

ROBOT = presets.params().robot


def test_frame_count_and_size_follow_the_options(tmp_path):
    """A 3.2 s track at 4x real time and 10 fps is 0.8 s of movie: 9 frames
    (both ends), each the requested size."""
    t = np.linspace(0, 3.2, 161)
    poses = np.zeros((161, 2, 5))
    poses[:, 1, 0] = 0.07 + 0.01 * t
    poses[:, :, 3:] = np.pi / 2
    opts = MovieOptions(fps=10, speed=4, size_px=200)
    assert len(frame_times(t, opts)) == 9
    info = render(t, poses, ROBOT, 1.6, tmp_path / "m.gif", opts)
    im = Image.open(info.path)
    assert info.frames == 9 and im.n_frames == 9 and im.size == (200, 200)
    short = render(t, poses, ROBOT, 1.6, tmp_path / "s.gif", MovieOptions(fps=10, speed=4, size_px=200, duration=0.4))
    assert short.frames == 5


def test_mp4_through_the_packaged_ffmpeg(tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    t = np.linspace(0, 1.6, 81)
    poses = np.zeros((81, 1, 5))
    poses[:, 0, 2] = t
    info = render(t, poses, ROBOT, 1.6, tmp_path / "m.mp4", MovieOptions(fps=10, speed=2, size_px=128))
    assert info.format == "mp4" and (tmp_path / "m.mp4").read_bytes()[4:8] == b"ftyp"


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    path = tmp_path_factory.mktemp("movie") / "scan.h5"
    run_scan(ScanConfig(n=6, periods=3, r_range_W=(0.8, 1.4), seed=4), path)
    return path


def test_a_lane_simulated_again_is_the_stored_lane(store):
    """From the store's start, amplitude, gait, model and seed alone, the lane's
    per-period poses and touches come out as stored (bit for bit in float32)."""
    t, track, res, params, gait, rows = resimulate_lane(store, None, 0, track_stride=200)
    k = int(rows["periods_run"])
    assert k >= 1 and rows["valid"]
    np.testing.assert_array_equal(res.poses[1:k + 1].astype(np.float32), rows["poses"][:k])
    np.testing.assert_array_equal(res.touched[:k], rows["touched"][:k])
    assert track.shape == (len(t), 2, 5) and abs(t[-1] - 3 * gait.period()) < 1e-9


def test_smx_movie_of_a_store_lane_and_its_bad_input(store, tmp_path):
    r = CliRunner().invoke(app, ["movie", str(store), "--lane", "0", "--out", str(tmp_path / "l.gif"),
                                 "--fps", "5", "--speed", "4", "--size", "160"])
    assert r.exit_code == 0, r.output
    im = Image.open(tmp_path / "l.gif")
    assert im.size == (160, 160) and im.n_frames == len(frame_times(np.array([0, 4.8]), MovieOptions(fps=5, speed=4)))
    for args, msg in ((["--lane", "6"], "lane 6 is out of range: run a090.00 has lanes 0..5"),
                      (["--lane", "1"], "overlapping"),
                      ([], "needs --lane"),
                      (["--lane", "0", "--size", "161"], "--size must be even")):
        r = CliRunner().invoke(app, ["movie", str(store), "--out", str(tmp_path / "x.gif"), *args])
        assert r.exit_code == 2 and msg in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert not (tmp_path / "x.gif").exists()


def test_a_relaxation_trial_simulated_again_is_the_stored_trial(tmp_path):
    """From a relaxation store alone (its configuration, model, drawn robots and the trial's own random
    stream: start and phase offsets) a trial is simulated again exactly, imperfect robots included, and
    ``smx movie --trial`` draws it; a trial the store lacks, or scan options, are one line."""
    from smarticle_mjx.replay import resimulate_trial
    out = tmp_path / "r.h5"
    run = CliRunner()
    r = run.invoke(app, ["relax", "--robots", "3", "--trials", "2", "--first-trial", "3", "--periods", "3",
                         "--imperfections", "phase-jitter", "--out", str(out), "--quiet"])
    assert r.exit_code == 0, r.output
    t, track, res, params, gait, rows = resimulate_trial(out, 4, frame_interval=0.1)
    k = int(rows["periods_run"])
    assert np.array_equal(res.poses[1:k + 1].astype(np.float32), rows["poses"][:k])
    assert np.array_equal(track[0], rows["start_poses"]) and t[0] == 0
    r = run.invoke(app, ["movie", str(out), "--trial", "3", "--out", str(tmp_path / "t.gif"), "--fps", "5",
                         "--size", "120", "--duration", "1"])
    assert r.exit_code == 0 and "differs" not in r.output, r.output
    assert (tmp_path / "t.gif").stat().st_size > 0
    for args, msg in ((["--trial", "0"], "trial 0 is not in"), ([], "needs --trial"), (["--lane", "0"], "--trial, not --lane")):
        r = run.invoke(app, ["movie", str(out), "--out", str(tmp_path / "x.gif"), *args])
        assert r.exit_code == 2 and msg in r.output and r.output.strip().count("\n") == 0, (args, r.output)
