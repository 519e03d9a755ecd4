"""``--set FIELD=VALUE`` and a study file's ``[scene]`` table: one field of a preset changed without
code, checked, recorded beside the preset's name, honoured by the engine or refused in one line."""

import dataclasses
import hashlib
import json

import h5py
import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

from smarticle_mjx import presets, scene, specs, studies, studyfile, tracks
from smarticle_mjx.cli import app
from smarticle_mjx.engine import dart


def _md5(path):
    return hashlib.md5(path.read_bytes()).hexdigest()


def test_overrides_change_one_field_and_leave_the_preset_alone():
    base = presets.params("lab-lag")
    got = presets.apply(base, presets.overrides(["robot_friction=0.1", "robot.servo_speed=7.5",
                                                 "contact_solimp=0.9,0.95,0.002", "robot.servo_kv=none"]))
    assert got.robot_friction == 0.1 and got.robot.servo_speed == 7.5
    assert got.contact_solimp == (0.9, 0.95, 0.002) and got.robot.servo_kv is None
    assert got.robot.arm_length == base.robot.arm_length and got.plate_friction == base.plate_friction
    assert presets.params("lab-lag") == base  # the preset itself is untouched
    # a study file's [scene] table, robot fields as a sub-table, gives the same overrides
    assert presets.table_overrides({"robot_friction": 0.1, "robot": {"servo_speed": 7.5}}) == \
        presets.overrides(["robot.servo_speed=7.5", "robot_friction=0.1"])


@pytest.mark.parametrize("item, says", [
    ("robot_frction=0.1", "unknown scene field 'robot_frction'"),
    ("robot.servo_sped=7", "unknown scene field 'robot.servo_sped'"),
    ("robot_friction", "FIELD=VALUE"),
    ("robot_friction=abc", "expected a finite number"),
    ("robot_friction=nan", "expected a finite number"),
    ("iterations=2.5", "expected an integer"),
    ("contact_solimp=0.9,0.95", "3 comma-separated values"),
    ("robot_friction=-1", "friction coefficients must be >= 0"),
    ("robot.mass=0.001", "must exceed the two arms' mass"),
    ("quirks=1", "unknown scene field 'quirks'"),
    ("solver=LBFGS", "solver must be one of auto, Newton, CG, PGS"),
])
def test_bad_overrides_are_one_line_errors(item, says):
    with pytest.raises(ValueError) as e:
        presets.apply(presets.params(), presets.overrides([item]))
    assert says in str(e.value) and "\n" not in str(e.value)


def test_an_override_reaches_the_compiled_model():
    # the physical fact: robot-robot friction set on the command line is the friction MuJoCo
    # combines for two robots' geoms (its default combination takes the larger of the two)
    params = presets.apply(presets.params(), presets.overrides(["robot_friction=0.11", "plate_friction=0.21"]))
    m = scene.compile_model(scene.build_mjcf(params, scene.standard_poses("pair", params.robot)))
    plate = [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE]
    robot = [g for g in range(m.ngeom) if g not in plate]
    assert plate and robot
    assert np.allclose(m.geom_friction[robot, 0], 0.11)
    base = scene.compile_model(scene.build_mjcf(presets.params(), scene.standard_poses("pair", params.robot)))
    assert not np.allclose(base.geom_friction[robot, 0], 0.11)


def test_the_solver_override_reaches_the_compiled_model():
    # MuJoCo's constraint solver and its cap, as the compiled model holds them
    params = presets.apply(presets.params(), presets.overrides(["solver=CG", "iterations=100"]))
    m = scene.compile_model(scene.build_mjcf(params, scene.standard_poses("pair", params.robot)))
    assert m.opt.solver == mujoco.mjtSolver.mjSOL_CG and m.opt.iterations == 100
    base = scene.compile_model(scene.build_mjcf(presets.params(), scene.standard_poses("pair", params.robot)))
    assert base.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON and base.opt.iterations == 20
    # "auto" (the default) solves arms with gear play with CG at 100 iterations, unless told otherwise
    for sets, want in ((["robot.backlash_deg=1.5"], (mujoco.mjtSolver.mjSOL_CG, 100)),
                       (["robot.backlash_deg=1.5", "iterations=300"], (mujoco.mjtSolver.mjSOL_CG, 300)),
                       (["robot.backlash_deg=1.5", "solver=Newton"], (mujoco.mjtSolver.mjSOL_NEWTON, 20))):
        p = presets.apply(presets.params(), presets.overrides(sets))
        m = scene.compile_model(scene.build_mjcf(p, scene.standard_poses("pair", p.robot)))
        assert (m.opt.solver, m.opt.iterations) == want, sets


def test_scan_records_preset_and_overrides_and_bad_set_touches_nothing(tmp_path):
    run = CliRunner()
    out = tmp_path / "scan.h5"
    r = run.invoke(app, ["scan", "--n", "2", "--periods", "1", "--out", str(out), "--quiet",
                         "--set", "robot_friction=0.12", "--set", "robot.servo_speed=8"])
    assert r.exit_code == 0, r.output
    with h5py.File(out, "r") as f:
        cfg = json.loads(f.attrs["config"])
    assert cfg["model"] == presets.DEFAULT
    assert cfg["overrides"] == {"robot.servo_speed": 8.0, "robot_friction": 0.12}
    assert cfg["scene"]["robot_friction"] == 0.12 and cfg["scene"]["robot"]["servo_speed"] == 8.0
    assert cfg["scan"]["overrides"] == cfg["overrides"]
    rep = tmp_path / "rep"
    assert run.invoke(app, ["report", str(out), "--out", str(rep)]).exit_code == 0
    assert "robot_friction = 0.12" in (rep / "report.md").read_text()
    before = _md5(out)
    for bad in (["--set", "robot_frction=0.1"], ["--set", "robot_friction=x"], ["--set", "robot.mass=-1"]):
        r = run.invoke(app, ["scan", "--n", "2", "--periods", "1", "--out", str(out), "--quiet", "--overwrite", *bad])
        assert r.exit_code == 2 and r.output.startswith("error:") and r.output.strip().count("\n") == 0, r.output
    assert _md5(out) == before


def test_a_store_made_with_other_overrides_is_stale(tmp_path):
    cfg = specs.ScanConfig(n=2, periods=1)
    out = tmp_path / "s.h5"
    studies.run_study(cfg, out)
    assert studies.stale_reason(cfg, out) is None
    changed = specs.ScanConfig(n=2, periods=1, overrides=presets.overrides(["robot_friction=0.2"]))
    assert studies.stale_reason(changed, out) == "made from a different study file"


def test_study_file_scene_table(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[study]\nconfigs = "random"\nn = 4\nperiods = 2\n\n[scene]\nrobot_friction = 0.15\n'
                 '[scene.robot]\nservo_speed = 7.0\n')
    cfg = studyfile.load_study(f)
    assert dict(cfg.overrides) == {"robot_friction": 0.15, "robot.servo_speed": 7.0}
    assert cfg.scene_params().robot.servo_speed == 7.0
    # --set goes on top of the file's table
    sw = studyfile.sweep_config(f, "90", sets=["robot_friction=0.2"])
    assert dict(sw.overrides) == {"robot_friction": 0.2, "robot.servo_speed": 7.0}
    f.write_text('[study]\nconfigs = "relax"\nstages = 1\ntrials = 2\nperiods = 3\n\n[scene]\nplate_friction = 0.3\n')
    rs = studyfile.read_study(f)
    assert rs.stage_config(0, presets.DEFAULT).scene_params().plate_friction == 0.3
    f.write_text('[study]\nconfigs = "random"\n\n[scene]\nrobot_fiction = 0.15\n')
    with pytest.raises(ValueError, match=r"\[scene\] --set: unknown scene field 'robot_fiction'"):
        studyfile.load_study(f)


def test_relax_and_simulate_record_overrides(tmp_path):
    run = CliRunner()
    out = tmp_path / "relax.h5"
    r = run.invoke(app, ["relax", "--robots", "3", "--trials", "1", "--periods", "2", "--out", str(out), "--quiet",
                         "--set", "contact_dampratio=0.3"])
    assert r.exit_code == 0, r.output
    rep = tmp_path / "rep"
    assert run.invoke(app, ["report", str(out), "--out", str(rep), "--glider-min-periods", "2"]).exit_code == 0
    assert "contact_dampratio = 0.3" in (rep / "report.md").read_text()
    track = tmp_path / "t.csv"
    r = run.invoke(app, ["simulate", "--scene", "single", "--periods", "1", "--out", str(track),
                         "--set", "robot.arm_mass=0.004"])
    assert r.exit_code == 0, r.output
    meta = json.loads(track.with_suffix(".json").read_text())
    assert meta["overrides"] == {"robot.arm_mass": 0.004}
    # the track reads back with the robot that made it
    assert tracks.read_csv(track)[0].params.robot.arm_mass == 0.004


def test_the_dart_twin_refuses_fields_it_does_not_read():
    with pytest.raises(ValueError, match="the DART twin does not read"):
        dart.check_study("dart", None, None, presets.overrides(["contact_timeconst=0.01"]))
    dart.check_study("native", None, None, presets.overrides(["contact_timeconst=0.01"]))  # MuJoCo reads it


@pytest.mark.parametrize("kind", ["scan", "relax"])
def test_one_staleness_rule_for_scans_and_relaxations(tmp_path, kind):
    """A store stands for a study when what the study would write now equals what the store holds, keys
    added since it was written filled in with the values they implicitly had: the same for both kinds.
    A scene field the store predates (dropped from its header here) is its default; a spec key written
    only away from its default (a relaxation's hex start, a scan's imperfections) is not filled in."""
    if kind == "scan":
        cfg = specs.ScanConfig(n=2, periods=1)
        other = dataclasses.replace(cfg, imperfections="lab")
    else:
        cfg = specs.RelaxConfig(trials=1, periods=2)
        other = dataclasses.replace(cfg, start="hex")
    out = tmp_path / "s.h5"
    studies.run_study(cfg, out)
    assert studies.stale_reason(cfg, out) is None
    assert studies.stale_reason(other, out) == "made from a different study file"
    assert studies.stale_reason(dataclasses.replace(cfg, periods=3), out) == "made from a different study file"
    with h5py.File(out, "r+") as f:  # as if written before the scene had contact_dampratio
        c = json.loads(f.attrs["config"])
        del c["scene"]["contact_dampratio"]
        f.attrs["config"] = json.dumps(c)
    assert studies.stale_reason(cfg, out) is None
    with h5py.File(out, "r+") as f:  # ... but a changed value is a change
        c = json.loads(f.attrs["config"])
        c["scene"]["contact_dampratio"] = 0.5
        f.attrs["config"] = json.dumps(c)
    assert studies.stale_reason(cfg, out) == "made from a different study file"


def test_a_store_from_before_the_solver_field_reads_back_as_what_made_it():
    """Stores written before the scene recorded its solver were solved with Newton: read back (replays,
    movies, staleness) they keep Newton where arms have gear play, and are the default ("auto", which is
    Newton there) where none has."""
    with_play = scene.params_json(presets.apply(presets.params(), presets.overrides(["robot.backlash_deg=1.5"])))
    ideal = scene.params_json(presets.params())
    for d in (with_play, ideal):
        del d["solver"]
    assert scene.params_from_json(with_play).constraint_solver(2) == ("Newton", 20)
    assert scene.params_from_json(ideal) == presets.params()
    drawn = scene.params_json(presets.params().replace(quirks=(scene.RobotQuirk(backlash_deg=(1.2, 1.7)),)))
    del drawn["solver"]
    assert scene.params_from_json(drawn).solver == "Newton"


def test_a_journal_started_before_a_scene_field_existed_resumes(tmp_path):
    """An interrupted run whose journal predates a scene field (robot_dampratio, added with the default that
    leaves every contact as it was) is the same study by the staleness rule, so --resume continues it to the
    store an uninterrupted run writes; the configuration it was started with is kept beside it. A journal
    whose recorded value differs from the study's is still refused in one line."""
    from smarticle_mjx.store import StoreError, read_relax
    cfg = specs.RelaxConfig(n_robots=3, trials=3, periods=2, batch_size=1)
    whole = tmp_path / "whole.h5"
    studies.run_study(cfg, whole)

    class Killed(Exception):
        pass

    def die(p):
        if p["done"] >= 1:
            raise Killed

    def cut_journal(name, edit):
        out = tmp_path / name
        with pytest.raises(Killed):
            studies.run_study(cfg, out, on_progress=die)
        saved = out.with_name(out.name + ".parts") / "config.json"
        c = json.loads(saved.read_text())
        edit(c["scene"])
        saved.write_text(json.dumps(c))
        return out

    old = cut_journal("old.h5", lambda sc: sc.pop("robot_dampratio"))
    studies.run_study(cfg, old, mode="resume")
    a, b = read_relax(whole), read_relax(old)
    for k in ("poses", "touched", "start_poses", "periods_run"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    assert studies.stale_reason(cfg, old) is None
    other = cut_journal("other.h5", lambda sc: sc.update(robot_dampratio=0.05))
    with pytest.raises(StoreError, match="different configuration"):
        studies.run_study(cfg, other, mode="resume")
    assert (tmp_path / "other.h5.parts").exists() and not other.exists()


def test_stages_written_before_and_after_a_scene_field_existed_pool(tmp_path):
    """read_relax pools stages of one study; a stage whose recorded scene predates a field (robot_dampratio,
    at the default that changes nothing) is the same study as one that records it, as the staleness rule
    says; a stage recording another value is not."""
    from smarticle_mjx.store import StoreError, read_relax
    s0, s1 = tmp_path / "s0.h5", tmp_path / "s1.h5"
    studies.run_study(specs.RelaxConfig(n_robots=3, trials=1, periods=2, batch_size=1), s0)
    studies.run_study(specs.RelaxConfig(n_robots=3, trials=1, first_trial=1, periods=2, batch_size=1), s1)

    def edit(path, change):
        with h5py.File(path, "r+") as f:
            c = json.loads(f.attrs["config"])
            change(c["scene"])
            f.attrs["config"] = json.dumps(c)

    edit(s0, lambda sc: sc.pop("robot_dampratio"))  # as written before the field existed
    assert list(read_relax([s0, s1]).trial) == [0, 1]
    edit(s0, lambda sc: sc.update(robot_dampratio=0.05))
    with pytest.raises(StoreError, match="not stages of one study"):
        read_relax([s0, s1])
