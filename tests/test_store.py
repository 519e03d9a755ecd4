"""Stores and the scan commands: nothing lost, bad input refused, nothing changed."""

import hashlib
import os
import pathlib
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from smarticle_mjx.cli import app
from smarticle_mjx import presets
from smarticle_mjx.store import SCHEMA_VERSION, Store, StoreError, Writer, longest_run

runner = CliRunner()
SMALL = ["--n", "16", "--periods", "3", "--batch-size", "8", "--quiet"]


def _digest(path):
    return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest()


def _arrays(path):
    st = Store(path)
    return {r: st.run(r) for r in st.runs}


def _smx(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_longest_run():
    flags = np.array([[1, 1, 0, 1, 1, 1, 0], [0, 0, 0, 0, 0, 0, 0], [1, 1, 1, 1, 1, 1, 1]], bool)
    np.testing.assert_array_equal(longest_run(flags), [3, 0, 7])


def test_scan_store_schema_and_reader(tmp_path):
    out = tmp_path / "scan.h5"
    r = _smx("scan", *SMALL, "--out", out)
    assert r.exit_code == 0, r.output
    assert "bound at the end" in r.output
    with h5py.File(out) as f:  # plain h5py can read it
        assert f.attrs["schema_version"] == SCHEMA_VERSION
        assert {"mujoco", "jax", "package", "config", "created", "seed"} <= set(f.attrs)
        g = f["runs/a090.00"]
        assert g.attrs["amplitude_deg"] == 90.0 and g["touched"].shape == (16, 3, 1)
        assert g["touched"].chunks is not None and g["touched"].compression == "gzip"
        assert g["touched"].maxshape[0] is None
    d = Store(out).run()
    assert d["valid"].dtype == bool and (d["periods_run"][~d["valid"]] == 0).all()
    assert (d["status"][~d["valid"]] == 1).all()
    np.testing.assert_array_equal(d["lifetime"], longest_run(d["touched"][:, :, 0]))
    assert not (out.parent / "scan.h5.parts").exists()


def test_sweep_has_one_group_per_amplitude(tmp_path):
    out = tmp_path / "sweep.h5"
    r = _smx("sweep-amplitude", "--amplitudes", "60,90", "--n", "8", "--periods", "2", "--quiet", "--out", out)
    assert r.exit_code == 0, r.output
    st = Store(out)
    assert st.runs == ["a060.00", "a090.00"]
    # the period is put on the model's step grid: within half a step of the gait's
    half_step = presets.params().timestep / 2
    assert st.run_attrs["a060.00"]["period_s"] == pytest.approx(1.6 * 60 / 90, abs=half_step)
    # the same initial configurations at every amplitude
    np.testing.assert_array_equal(st.run("a060.00")["config"], st.run("a090.00")["config"])


def test_study_files_in_sweeps_load():
    from smarticle_mjx.scan import ScanConfig, load_study
    from smarticle_mjx.scene import SceneParams
    from smarticle_mjx.validation import BoundStudy, RelaxStudy, read_study
    studies = sorted((pathlib.Path(__file__).resolve().parents[1] / "sweeps").glob("*.toml"))
    assert studies
    kinds = set()
    for path in studies:
        spec = read_study(path)
        kinds.add(type(spec))
        if isinstance(spec, ScanConfig):
            spec.validate(SceneParams())
        else:  # a started-bound or relaxation study is not a scan: smx scan --study refuses it in one line
            spec.validate()
            with pytest.raises(ValueError, match="smx validate runs it"):
                load_study(path)
    assert kinds == {ScanConfig, BoundStudy, RelaxStudy}


def test_kill_and_resume_gives_the_uninterrupted_store(tmp_path):
    """SIGKILL mid-scan, then --resume: the final store equals an uninterrupted run."""
    args = ["--n", "48", "--periods", "3", "--batch-size", "8", "--flush-rows", "4", "--quiet"]
    ref = tmp_path / "ref.h5"
    assert _smx("scan", *args, "--out", ref).exit_code == 0
    out = tmp_path / "killed.h5"
    parts = tmp_path / "killed.h5.parts"
    cmd = [sys.executable, "-m", "smarticle_mjx.cli", "scan", *args, "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 120
    while time.time() < deadline and len(list(parts.glob("*--*.h5"))) < 2 and proc.poll() is None:
        time.sleep(0.05)
    assert proc.poll() is None, "scan finished before it could be killed"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not out.exists() and parts.exists()
    done_before = len(list(parts.glob("*--*.h5")))
    r = _smx("scan", *args, "--out", out, "--resume")
    assert r.exit_code == 0, r.output
    assert done_before >= 2
    a, b = _arrays(ref), _arrays(out)
    for run in a:
        for k in a[run]:
            np.testing.assert_array_equal(a[run][k], b[run][k], err_msg=k)


def test_second_writer_is_refused(tmp_path):
    out = tmp_path / "busy.h5"
    with Writer(out, {"x": 1}, {"r": {}}):
        r = _smx("scan", *SMALL, "--out", out)
        assert r.exit_code == 2
        assert "another process" in r.output
    with pytest.raises(StoreError, match="another process"):
        with Writer(out, {"x": 1}, {"r": {}}, mode="resume"):
            with Writer(out, {"x": 1}, {"r": {}}, mode="resume"):
                pass


def test_resume_with_a_different_configuration_is_refused(tmp_path):
    out = tmp_path / "s.h5"
    with Writer(out, {"scan": {"periods": 3}}, {"a090.00": {}}):
        pass  # leaves an empty journal, as a killed run would
    before = sorted(p.name for p in (tmp_path / "s.h5.parts").iterdir())
    r = _smx("scan", *SMALL, "--out", out, "--resume")
    assert r.exit_code == 2 and "different configuration" in r.output
    assert sorted(p.name for p in (tmp_path / "s.h5.parts").iterdir()) == before


@pytest.mark.parametrize("args,message", [
    (["scan", "--amplitude", "120"], "amplitude"),
    (["scan", "--amplitude", "-5"], "amplitude"),
    (["scan", "--n", "0"], "--n must be positive"),
    (["scan", "--periods", "0"], "--periods must be positive"),
    (["scan", "--configs", "polar", "--positions", "0"], "positive"),
    (["scan", "--backend", "gpu"], "backend"),
    (["sweep-amplitude", "--amplitudes", "10:abc"], "amplitudes must look like"),
    (["sweep-amplitude", "--amplitudes", "30,95"], "amplitude"),
    (["sweep-amplitude"], "--amplitudes or --study"),
])
def test_bad_input_is_one_line_exit_2_and_creates_nothing(tmp_path, args, message):
    out = tmp_path / "x.h5"
    r = _smx(*args, "--out", out, "--quiet")
    assert r.exit_code == 2, r.output
    assert message in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_unreadable_study_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("this is = = not toml")
    for study, msg in ((bad, "not valid TOML"), (tmp_path / "missing.toml", "does not exist")):
        r = _smx("sweep-amplitude", "--study", study, "--out", tmp_path / "x.h5", "--quiet")
        assert r.exit_code == 2 and msg in r.output
    assert not (tmp_path / "x.h5").exists()
    unknown = tmp_path / "unknown.toml"
    unknown.write_text("[study]\namplitudes_deg = [90]\nfrobnicate = 1\n")
    r = _smx("sweep-amplitude", "--study", unknown, "--out", tmp_path / "x.h5", "--quiet")
    assert r.exit_code == 2 and "unknown keys" in r.output


def test_unwritable_output_is_refused(tmp_path):
    r = _smx("scan", *SMALL, "--out", tmp_path / "no" / "such" / "dir.h5")
    assert r.exit_code == 2 and "does not exist" in r.output
    afile = tmp_path / "plain.txt"
    afile.write_text("x")
    r = _smx("scan", *SMALL, "--out", afile / "x.h5")
    assert r.exit_code == 2 and "not a directory" in r.output
    assert afile.read_text() == "x"
    r = _smx("scan", *SMALL, "--out", "/proc/x.h5")
    assert r.exit_code == 2
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("running as a user who can write anywhere")
        r = _smx("scan", *SMALL, "--out", ro / "x.h5")
        assert r.exit_code == 2 and "not writable" in r.output
    finally:
        ro.chmod(0o700)


def test_existing_store_is_never_touched_without_resume_or_overwrite(tmp_path):
    out = tmp_path / "keep.h5"
    assert _smx("scan", *SMALL, "--out", out).exit_code == 0
    digest = _digest(out)
    r = _smx("scan", *SMALL, "--out", out)
    assert r.exit_code == 2 and "exists" in r.output
    r = _smx("scan", *SMALL, "--out", out, "--resume")
    assert r.exit_code == 2 and "already complete" in r.output
    r = _smx("scan", "--n", "0", "--out", out, "--overwrite")
    assert r.exit_code == 2
    assert _digest(out) == digest
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.h5"]  # no lock file left behind
    r = _smx("scan", *SMALL, "--out", out, "--overwrite", "--periods", "2")
    assert r.exit_code == 0 and Store(out).run()["touched"].shape[1] == 2


def test_reader_refuses_unfinished_and_foreign_files(tmp_path):
    with pytest.raises(StoreError, match="no store"):
        Store(tmp_path / "none.h5")
    junk = tmp_path / "junk.h5"
    junk.write_text("not hdf5")
    with pytest.raises(StoreError, match="not a readable"):
        Store(junk)


def test_xarray_opens_a_run_group_with_named_dimensions_units_and_booleans(tmp_path):
    """``xarray.open_dataset(store, group="runs/a090.00", engine="h5netcdf")``:
    every variable has named dimensions with coordinates (no phony ones),
    units and a long name; fields that mix quantities carry their units per
    component; booleans read back as booleans; values equal the reader's."""
    xr = pytest.importorskip("xarray")
    pytest.importorskip("h5netcdf")
    from smarticle_mjx.scan import ScanConfig, run_scan
    out = tmp_path / "x.h5"
    run_scan(ScanConfig(n=4, periods=2, r_range_W=(0.8, 1.5), seed=1), out)
    ds = xr.open_dataset(out, group="runs/a090.00", engine="h5netcdf")
    assert not [d for d in ds.dims if str(d).startswith("phony")]
    assert dict(ds.sizes) == {"lane": 4, "period": 2, "pair": 1, "robot": 2, "pose_var": 5, "rel_var": 3,
                              "com_var": 3, "config_var": 3}
    assert ds["poses"].dims == ("lane", "period", "robot", "pose_var")
    assert list(ds["pose_var"].values) == ["x", "y", "heading", "alpha1", "alpha2"]
    assert list(ds["rel_units"].values) == ["W", "rad", "rad"] and "rel_units" in ds["rel"].coords
    assert ds["min_dist"].attrs["units"] == "m" and ds["touched"].dtype == bool and ds["valid"].dtype == bool
    assert all("long_name" in ds[v].attrs for v in ds.data_vars)
    assert list(ds["period"].values) == [1, 2]
    ref = Store(out).run()
    for k in ("touched", "rel", "poses", "status"):
        np.testing.assert_array_equal(ds[k].values, ref[k])
    assert ds["status"].attrs["flag_meanings"].split()[2] == "penetration"


def test_a_schema_1_store_still_opens(tmp_path):
    """Stores written before the labels (schema 1) are read as before."""
    from smarticle_mjx.scan import ScanConfig, run_scan
    out = tmp_path / "old.h5"
    run_scan(ScanConfig(n=3, periods=1, r_range_W=(0.8, 1.5), seed=2), out)
    with h5py.File(out, "r+") as f:  # strip schema 2's additions: what an old store is
        f.attrs["schema_version"] = 1
        g = f["runs/a090.00"]
        for k in list(g.keys()):
            if k not in ("config", "valid", "status", "periods_run", "touched", "min_dist", "poses", "rel", "com",
                         "lifetime"):
                del g[k]
    st = Store(out)
    assert st.run()["touched"].shape == (3, 1, 1) and set(st.run_fields[st.runs[0]]) >= {"rel", "com"}


def test_a_stale_lock_file_of_a_killed_writer_is_reused_and_removed(tmp_path):
    """A SIGKILLed writer leaves its lock file (the kernel drops only the lock):
    the next writer takes it over, and removes it when done."""
    out = tmp_path / "s.h5"
    stale = tmp_path / "s.h5.lock"
    stale.write_text("")
    with Writer(out, {"x": 1}, {"r": {}}):
        assert stale.exists()
        with pytest.raises(StoreError, match="another process"):
            with Writer(out, {"x": 1}, {"r": {}}, mode="resume"):
                pass
        assert stale.exists()  # the refused writer did not remove the holder's file
    assert not stale.exists()
