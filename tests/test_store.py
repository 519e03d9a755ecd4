"""Stores and the scan commands: nothing lost, bad input refused, nothing changed."""

import hashlib
import os
import pathlib
import re
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
from smarticle_mjx.reduce.binding import longest_run
from smarticle_mjx.store import SCHEMA_VERSION, Store, StoreError, Writer

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


def test_screen_files_in_sweeps_load():
    """Every relaxation screen of sweeps/screens/ reads, each variant a valid study; a bad variant is one line."""
    from smarticle_mjx.studyfile import read_relax_screen
    screens = sorted((pathlib.Path(__file__).resolve().parents[1] / "sweeps" / "screens").glob("*.toml"))
    assert screens
    for path in screens:
        screen, variants = read_relax_screen(path)
        assert variants and all(rs.stages == 1 and rs.trials == screen["trials"] for rs in variants.values())


def test_a_bad_screen_variant_is_one_line(tmp_path):
    from smarticle_mjx.studyfile import read_relax_screen
    f = tmp_path / "s.toml"
    head = '[screen]\ntrials = 2\nperiods = 3\nseed = 0\namplitude_deg = 90.0\n'
    for body, says in (('[[variant]]\nname = "a"\nstart = "ring"\n', "variant a: --start must be"),
                       ('[[variant]]\nname = "a"\nset = ["robot_fiction=0.1"]\n', "unknown scene field"),
                       ('[[variant]]\nname = "a"\ncolour = 1\n', "unknown keys ['colour']"),
                       ('[[variant]]\nname = "a"\n[[variant]]\nname = "a"\n', "a name of its own"),
                       # a servo too slow for the gait's period is refused with the override applied
                       ('[[variant]]\nname = "a"\nset = ["robot.servo_speed=7.85"]\n', "shorter than the 4 moves")):
        f.write_text(head + body)
        with pytest.raises(ValueError, match=re.escape(says)) as e:
            read_relax_screen(f)
        assert "\n" not in str(e.value)


def test_study_files_in_sweeps_load():
    from smarticle_mjx.specs import ScanConfig
    from smarticle_mjx.studyfile import load_study
    from smarticle_mjx.scene import SceneParams
    from smarticle_mjx.specs import BoundStudy, RelaxStudy
    from smarticle_mjx.studyfile import read_study
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
    """A store as version 1 wrote it, built here with h5py alone (no code of
    this package): root attributes, one group per amplitude with its
    attributes, the ten row fields as gzip-chunked datasets, no dimension
    scales or units, and a configuration from before model presets. The
    reader opens it, takes its model as "paper" (the only model then) and
    reads back every value and attribute that was written."""
    import json
    rng = np.random.default_rng(7)
    m, k = 5, 3
    rows = {"config": rng.uniform(0, 3, (m, 3)), "valid": np.array([1, 1, 0, 1, 1], bool),
            "status": np.array([0, 0, 1, 8, 0], np.int32), "periods_run": np.array([3, 3, 0, 2, 3], np.int32),
            "touched": rng.random((m, k, 1)) < 0.5, "min_dist": rng.normal(0, 1e-3, (m, k, 1)).astype(np.float32),
            "poses": rng.normal(0, 0.05, (m, k, 2, 5)).astype(np.float32),
            "rel": rng.normal(1, 0.1, (m, k, 3)).astype(np.float32),
            "com": rng.normal(0, 0.01, (m, k, 3)).astype(np.float32), "lifetime": np.array([3, 1, 0, 2, 0], np.int32)}
    config = {"scan": {"configs": "random", "n": m, "r_range_W": [0.5, 2.5], "amplitudes_deg": [90.0], "periods": k,
                       "backend": "native", "seed": 2, "batch_size": 256},
              "scene": {"timestep": 0.00025, "robot": {"body_length": 0.05}}}
    run_attrs = {"amplitude_deg": 90.0, "period_s": 1.6, "chirality": "ccw", "gait": "square", "periods": k,
                 "n_configs": m}
    out = tmp_path / "v1.h5"
    with h5py.File(out, "w") as f:
        f.attrs.update({"schema_version": 1, "package": "smarticle-mjx 0.1.0", "mujoco": "3.3.0", "jax": "0.6.0",
                        "h5py": "3.13.0", "numpy": "2.2.0", "config": json.dumps(config),
                        "created": "2026-11-18T10:00:00+00:00", "finished": "2026-11-18T10:05:00+00:00", "seed": 2,
                        "complete": True})
        g = f.create_group("runs").create_group("a090.00")
        g.attrs.update(run_attrs)
        for name, data in rows.items():
            g.create_dataset(name, data=data, maxshape=(None,) + data.shape[1:], chunks=(2,) + data.shape[1:],
                             compression="gzip", compression_opts=4, shuffle=True)
    st = Store(out)
    assert st.attrs["schema_version"] == 1 and st.model == "paper" and st.kind == "scan"
    assert st.runs == ["a090.00"] and set(st.run_fields["a090.00"]) == set(rows)
    assert {key: st.run_attrs["a090.00"][key] for key in run_attrs} == run_attrs
    got = st.run()
    for name, data in rows.items():
        assert got[name].dtype == data.dtype, name
        np.testing.assert_array_equal(got[name], data, err_msg=name)
    with h5py.File(out, "r+") as f:  # a version this reader does not know is refused in one line
        f.attrs["schema_version"] = 9
    with pytest.raises(StoreError, match="schema version 9"):
        Store(out)


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


def _rows(n, nan_bits=0xFFC00000):
    """Journal rows whose missing values carry the NaN ``nan_bits`` (x86's default NaN: sign bit set)."""
    neg = np.array([nan_bits], np.uint32).view(np.float32)[0]
    rel = np.zeros((n, 2, 3), np.float32)
    rel[:, 1] = neg  # a period not run
    poses = np.zeros((n, 2, 2, 5), np.float32)
    poses[:, 1] = neg
    config = np.zeros((n, 3))
    config[0, 0] = np.array([0xFFF8000000000001], np.uint64).view(np.float64)[0]  # negative NaN, payload 1
    return {"config": config, "valid": np.ones(n, bool), "status": np.zeros(n, np.int32),
            "periods_run": np.ones(n, np.int32), "touched": np.zeros((n, 2, 1), bool),
            "min_dist": np.full((n, 2, 1), np.inf, np.float32), "poses": poses, "rel": rel,
            "com": np.zeros((n, 2, 3), np.float32), "lifetime": np.zeros(n, np.int32)}


def test_missing_values_are_stored_as_one_nan_whoever_computed_them(tmp_path):
    """NaNs made by arithmetic carry the CPU's sign and payload: the writer
    stores the canonical quiet NaN instead, in the journal and in the merged
    store, so two executors' stores of one scan are the same bits on any
    machine. Values read back as NaN where they were NaN, and nowhere else."""
    from storecmp import non_canonical_nans
    path = tmp_path / "s.h5"
    with Writer(path, {"x": 1}, {"r": {"n_configs": 3}}) as w:
        w.append("r", 0, _rows(3))
        part = next(w.parts.glob("r--*.h5"))
        with h5py.File(part) as f:
            assert f["rel"][0, 1].view(np.uint32).tolist() == [0x7FC00000] * 3
        w.finalize()
    assert non_canonical_nans(path) == []
    d = Store(path).run()
    assert np.isnan(d["rel"][:, 1]).all() and not np.isnan(d["rel"][:, 0]).any()
    assert np.isnan(d["config"][0, 0]) and np.isinf(d["min_dist"]).all()


def test_the_store_comparison_sees_a_nan_of_another_pattern(tmp_path):
    """The check the Dask tests rely on is not blind: a store written around
    the canonicalisation (h5py directly) is flagged, and two stores that
    differ in one value or one attribute are told apart."""
    from storecmp import assert_same_store, non_canonical_nans
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    for path in (a, b):
        with Writer(path, {"x": 1}, {"r": {"n_configs": 2}}) as w:
            w.append("r", 0, _rows(2))
            w.finalize()
    assert_same_store(a, b)
    with h5py.File(b, "r+") as f:
        f["runs/r/rel"][0, 1, 0] = np.array([0xFFC00000], np.uint32).view(np.float32)[0]
    bad = non_canonical_nans(b)
    assert len(bad) == 1 and bad[0].startswith("runs/r/rel:") and "0xffc00000" in bad[0], bad
    with pytest.raises(AssertionError, match="non-canonical"):
        assert_same_store(a, b)
    with h5py.File(b, "r+") as f:
        f["runs/r/rel"][0, 1, 0] = np.nan
        f["runs/r/lifetime"][1] = 3
    with pytest.raises(AssertionError, match="lifetime"):
        assert_same_store(a, b)
    with h5py.File(b, "r+") as f:
        f["runs/r/lifetime"][1] = 0
        f["runs/r"].attrs["n_configs"] = 5
    with pytest.raises(AssertionError, match="attributes of runs/r"):
        assert_same_store(a, b)


def test_a_scan_whose_scheduler_cannot_be_reached_leaves_nothing_behind(tmp_path):
    """``smx scan --executor dask --scheduler ADDRESS`` with nobody listening:
    one line, exit 2, no store, no journal, no lock file. With --overwrite the
    store and the unfinished journal it would have replaced are left as they were."""
    pytest.importorskip("distributed")
    import dask
    out = tmp_path / "x.h5"
    args = ["scan", *SMALL, "--executor", "dask", "--scheduler", "tcp://127.0.0.1:1", "--out", out]
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        r = _smx(*args)
        assert r.exit_code == 2 and "cannot reach the Dask scheduler" in r.output, r.output
        assert len(r.output.strip().splitlines()) == 1
        assert sorted(tmp_path.iterdir()) == []
        # an existing store and an unfinished journal of another scan at the same path
        assert _smx("scan", *SMALL, "--out", out).exit_code == 0
        parts = tmp_path / "x.h5.parts"
        parts.mkdir()
        (parts / "config.json").write_text("{}")
        before = _digest(out)
        r = _smx(*args, "--overwrite")
        assert r.exit_code == 2 and "cannot reach the Dask scheduler" in r.output, r.output
    assert _digest(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.h5", "x.h5.parts"]
    assert [p.name for p in parts.iterdir()] == ["config.json"] and (parts / "config.json").read_text() == "{}"


def test_numpy_numbers_in_a_configuration_are_stored_as_numbers(tmp_path):
    """A library caller's configuration may hold numpy scalars and arrays
    (a plate side computed from float32 poses, say): the store keeps them
    as the JSON numbers and lists they are, and refuses what JSON cannot hold."""
    import json
    path = tmp_path / "s.h5"
    with Writer(path, {"side": np.float32(0.5), "n": np.int64(3), "xs": np.arange(2)}, {"r": {"n_configs": 2}}) as w:
        w.append("r", 0, _rows(2))
        w.finalize()
    assert json.loads(Store(path).attrs["config"]) == {"side": 0.5, "n": 3, "xs": [0, 1]}
    with pytest.raises(TypeError, match="holds object"):
        Writer(tmp_path / "t.h5", {"x": object()}, {"r": {}})
