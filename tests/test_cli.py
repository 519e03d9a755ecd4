"""smx simulate, smx models, smx phase-diagram, and the track format."""

import csv
import json

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from smarticle_mjx import gait as G
from smarticle_mjx import presets
from smarticle_mjx.cli import app

runner = CliRunner()


def _smx(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_simulate_writes_the_interchange_format(tmp_path):
    out = tmp_path / "pair.csv"
    r = _smx("simulate", "--scene", "pair", "--periods", "2", "--track-stride", "100", "--out", out)
    assert r.exit_code == 0, r.output
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == ["trial", "t", "robot", "x", "y", "theta", "alpha1", "alpha2"]
    t = sorted({float(row["t"]) for row in rows})
    assert len(rows) == 2 * len(t) and t[-1] == pytest.approx(3.2)
    meta = json.loads((tmp_path / "pair.json").read_text())
    assert meta["robots"] == 2 and meta["gait"]["amplitude_deg"] == 90.0
    assert meta["frame_rate_hz"] == pytest.approx(1 / (100 * presets.params().timestep))
    # the arms follow the gait in the written track
    a1 = np.array([float(row["alpha1"]) for row in rows if row["robot"] == "0"])
    assert a1.min() < -1.4 and a1.max() > 1.4


def test_simulate_hdf5_and_config(tmp_path):
    out = tmp_path / "t.h5"
    r = _smx("simulate", "--config", "1.3,270,180", "--periods", "1", "--out", out)
    assert r.exit_code == 0, r.output
    with h5py.File(out) as f:
        assert f["x"].shape[1] == 2 and f["periods/touched"].shape == (1, 1)


@pytest.mark.parametrize("args,msg", [
    (["--config", "1,2"], "three numbers"),
    (["--config", "0.1,0,0"], "overlap"),
    (["--periods", "0"], "positive"),
    (["--amplitude", "95"], "amplitude"),
    (["--chirality", "left"], "chirality"),
    (["--gait", "zigzag"], "gait kind"),
    (["--period", "0.5"], "shorter than"),
    (["--scene", "eight"], "unknown standard scene"),
])
def test_simulate_bad_input(tmp_path, args, msg):
    out = tmp_path / "x.csv"
    r = _smx("simulate", *args, "--out", out)
    assert r.exit_code == 2 and msg in r.output, r.output
    assert not out.exists()


def test_simulate_does_not_overwrite(tmp_path):
    out = tmp_path / "x.csv"
    out.write_text("keep")
    r = _smx("simulate", "--periods", "1", "--out", out)
    assert r.exit_code == 2 and out.read_text() == "keep"


def test_models_check():
    r = _smx("models", "--check")
    assert r.exit_code == 0 and "up to date" in r.output


def test_phase_diagram_from_a_polar_scan(tmp_path):
    store = tmp_path / "p.h5"
    r = _smx("scan", "--configs", "polar", "--positions", "6", "--orientations", "3", "--periods", "2",
             "--out", store, "--quiet")
    assert r.exit_code == 0, r.output
    r = _smx("phase-diagram", store, "--out", tmp_path / "fig")
    assert r.exit_code == 0, r.output
    png = tmp_path / "fig" / "phase_diagram_a090.00.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "fig" / "phase_diagram_a090.00.svg").exists()
    r = _smx("phase-diagram", tmp_path / "missing.h5")
    assert r.exit_code == 2 and "no store" in r.output


def test_gait_rates_are_the_derivative_of_the_setpoints():
    t = np.linspace(0.01, 3.1, 777)
    out = np.asarray(G.setpoints_and_rates(t, np.radians(70), 1.6 * 70 / 90, 8.727, -1, 0, 0.1))
    h = 1e-3  # float32 setpoints: a larger step keeps round-off below 1e-3 rad/s
    fd = (np.asarray(G.setpoints(t + h, np.radians(70), 1.6 * 70 / 90, 8.727, -1, 0, 0.1))
          - np.asarray(G.setpoints(t - h, np.radians(70), 1.6 * 70 / 90, 8.727, -1, 0, 0.1))) / (2 * h)
    smooth = np.abs(fd - out[:, 2:]).max(1) < 1e-2  # away from ramp corners
    assert smooth.mean() > 0.97
    np.testing.assert_allclose(out[smooth, 2:], fd[smooth], atol=2e-2)
    speeds = np.abs(out[:, 2:]).ravel()
    assert np.all(np.isclose(speeds, 0.0) | np.isclose(speeds, 8.727, rtol=1e-5))


@pytest.mark.parametrize("command", [["scan", "--configs", "polar", "--positions", "2"],
                                     ["relax", "--trials", "1"]])
def test_a_negative_seed_is_one_line_naming_the_option_exit_2_and_writes_nothing(tmp_path, command):
    out = tmp_path / "x.h5"
    r = _smx(*command, "--periods", "1", "--seed", "-1", "--out", out, "--quiet")
    assert r.exit_code == 2, r.output
    assert "--seed must be >= 0" in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert list(tmp_path.iterdir()) == []
