"""Model presets: cited values, exact geometry, servo variants, and --model everywhere."""

import dataclasses
import json
import math
import pathlib
import re

import mujoco
import numpy as np
import pytest
from mjgap import mujoco_gap
from typer.testing import CliRunner

from smarticle_mjx import configs as C
from smarticle_mjx import presets
from smarticle_mjx import scene as S
from smarticle_mjx.cli import app
from smarticle_mjx.engine.simulate import simulate
from smarticle_mjx.gait import GaitSpec
from smarticle_mjx.store import Store

runner = CliRunner()


def _smx(*args):
    return runner.invoke(app, [str(a) for a in args])


def _changed_fields(params: S.SceneParams) -> set[str]:
    base = S.SceneParams()
    out = {f.name for f in dataclasses.fields(params) if f.name != "robot"
           and getattr(params, f.name) != getattr(base, f.name)}
    out |= {f.name for f in dataclasses.fields(params.robot)
            if getattr(params.robot, f.name) != getattr(base.robot, f.name)}
    return out


# the public records a source may cite (shared/reference/smarticle.md, "Beyond the paper's text")
PUBLIC_CODE = ("wsavoie/ArduinoSmarticle", "wsavoie/SmarticleSim", "LuningFang/smarticle_v6",
               "AkashVardhan7/smarticle_cloud_open_Boundary", "dartsim/dart")
ROOT = pathlib.Path(__file__).resolve().parents[1]
# words of the source lines that name a parameter field, and the unit a value is written in
FIELD_ALIASES = {"kp": "servo_kp", "kv": "servo_kv", "armature": "servo_armature", "arm_limit": "arm_limit_deg",
                 "contacts solref": "contact_timeconst"}
UNITS = {"ms": 1e-3, "mm": 1e-3, "cm": 1e-2, "g": 1e-3, "deg": 1.0, "N m/rad": 1.0, "N m": 1.0, "kg m^2": 1.0}
_VALUE = re.compile(r"(contacts solref|[a-z_]+) (-?\d+(?:\.\d+)?(?:e-?\d+)?)(?![\d.e])"
                    r"(?: (N m/rad|N m|kg m\^2|ms|mm|cm|g|deg)\b)?(?! of)")


def _stated_values(text: str):
    """(field, value in SI, number as written) for every 'field value [unit]' a source line states."""
    fields = {f.name for f in dataclasses.fields(S.SceneParams)} | {f.name for f in dataclasses.fields(S.RobotParams)}
    for m in _VALUE.finditer(text):
        field = FIELD_ALIASES.get(m.group(1), m.group(1))
        if field in fields:
            yield field, float(m.group(2)) * UNITS.get(m.group(3), 1.0), m.group(2)


def _close(stated: float, actual: float, written: str) -> bool:
    """Equal to the precision the number is written with (1.72 for 1.7189; 5e-5 exactly)."""
    if "e" in written or "." not in written:
        return math.isclose(stated, actual, rel_tol=1e-9, abs_tol=1e-15)
    return abs(stated - actual) <= 0.5 * 10 ** -len(written.split(".")[1]) * (stated / float(written)) + 1e-15


@pytest.mark.parametrize("name", list(presets.PRESETS))
def test_every_preset_value_cites_a_source(name):
    """Each parameter a preset changes from the base model is named in one of
    its source lines; each line cites the paper, a public repository of the
    reference table, or, for a value chosen here, the page of this
    repository that argues the choice (and that page exists); and every value
    a line states ('timestep 0.5 ms', 'arm_mass 3.19 g') is the preset's
    value, so no line can say 0.25 ms of a 0.5 ms model."""
    p = presets.get(name)
    cited = " ".join(field for field, _ in p.sources)
    changed = _changed_fields(p.params)
    aliases = {"servo_kp": "kp", "servo_kv": "kv", "servo_torque": "torque", "servo_armature": "armature",
               "arm_limit_deg": "arm_limit", "contact_timeconst": "contact_timeconst"}
    missing = [f for f in changed if f not in cited and aliases.get(f, f) not in cited]
    assert not missing, f"{name}: no source for {missing}"
    for field, source in p.sources:
        assert "no source" not in source, f"{name}: {field}: {source}"
        pages = re.findall(r"docs/[\w-]+\.md", source)
        assert all((ROOT / page).exists() for page in pages), f"{name}: {source}: no such page"
        public = re.search(r"\bpaper\b", source) or any(repo in source for repo in PUBLIC_CODE)
        assert public or pages, f"{name}: {field}: {source!r} cites neither the paper, public code nor a docs page"
        if "chosen" in source:
            assert pages, f"{name}: {field}: a chosen value must name the page that argues it: {source!r}"
        for f, stated, written in _stated_values(field):
            actual = getattr(p.params.robot, f) if hasattr(p.params.robot, f) else getattr(p.params, f)
            assert _close(stated, actual, written), f"{name}: {field!r} states {f} = {written}, the preset has {actual}"


def test_the_source_check_reads_values_as_written():
    """The value check is not blind: it finds a stale step and passes a rounded one."""
    got = {f: (v, w) for f, v, w in _stated_values("timestep 0.25 ms, contacts solref 5 ms, arm_height 0.96 of x")}
    assert got == {"timestep": (0.00025, "0.25"), "contact_timeconst": (0.005, "5")}
    assert not _close(0.00025, 0.0005, "0.25") and _close(1.72, 0.03 / math.radians(1), "1.72")


def test_unknown_preset_is_one_line():
    with pytest.raises(ValueError, match="unknown model 'nope'; choose one of paper"):
        presets.get("nope")


def _overlap_by_sampling(params, pose1, pose2, h=2.5e-4):
    """Independent reference: grid points inside robot 2's outline (matplotlib's
    point-in-polygon for the body and plates, distance to the axis for
    capsules) tested for containment in robot 1's outline."""
    from matplotlib.path import Path
    rp = params.robot
    r = C.arm_piece_radius(rp)

    def inside(pts, pose):
        corners, arms = C.robot_outline(pose, rp)
        hit = Path(corners).contains_points(pts)
        for arm in arms:
            if len(arm) > 2:
                hit |= Path(arm).contains_points(pts)
            else:
                a, b = arm
                t = np.clip(((pts - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
                hit |= np.linalg.norm(pts - (a + t[:, None] * (b - a)), axis=1) <= r
        return hit

    corners, arms = C.robot_outline(pose2, rp)
    allpts = np.concatenate([corners, arms.reshape(-1, 2)])
    lo, hi = allpts.min(0) - r, allpts.max(0) + r
    gx, gy = np.meshgrid(np.arange(lo[0], hi[0], h), np.arange(lo[1], hi[1], h))
    pts = np.stack([gx.ravel(), gy.ravel()], -1)
    pts = pts[inside(pts, pose2)]
    return bool(inside(pts, pose1).any())


@pytest.mark.parametrize("name", ["lab", "paper"])
def test_planar_overlap_test_is_exact_for_the_preset_geometry(name):
    """configs.pair_separation (plates or capsules, inset hinges) equals
    MuJoCo's own geom distance wherever the robots are apart; where it says
    they overlap, a brute-force point sampling agrees (MuJoCo's distance
    query is not reliable for an arm deep inside a body, so it is not the
    reference there) except within the grid spacing of grazing."""
    params = presets.params(name)
    rng = np.random.default_rng(7)
    n = 150
    cf = C.random_configs(n, rng, r_range_W=(0.4, 2.2))
    arms = rng.uniform(-math.pi / 2, math.pi / 2, (n, 2))
    poses = C.pair_poses(cf[:, 0], cf[:, 1], cf[:, 2], arms[:, 0], arms[:, 1], params.robot)
    ours = C.pair_separation(poses[:, 0], poses[:, 1], params.robot)
    ref = np.array([mujoco_gap(params, p) for p in poses])
    apart = ours > 0
    assert 20 < apart.sum() < n - 20, "the sample should hold both outcomes"
    np.testing.assert_allclose(ours[apart], ref[apart], atol=1e-6)
    sampled = np.array([_overlap_by_sampling(params, p[0], p[1]) for p in poses[~apart][:40]])
    assert np.all(sampled | (np.abs(ours[~apart][:40]) < 5e-4))


def test_lab_geometry_is_in_the_scene():
    """Hinges 6 mm inside the 5.4 cm body, 5.0 cm plate arms reaching 4.7 cm
    beyond the body end when straight, as tall as 0.96 of the body."""
    params = presets.params("lab")
    m = S.compile_model(S.build_mjcf(params, [(0, 0, 0, 0.0, 0.0)]))
    d = mujoco.MjData(m)
    mujoco.mj_resetDataKeyframe(m, d, 0)
    mujoco.mj_forward(m, d)
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "r0_arm2")
    assert m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX
    tip = d.geom_xpos[g][0] + m.geom_size[g][0]
    assert tip == pytest.approx(0.027 - 0.006 + 0.050, abs=1e-9)
    assert 2 * m.geom_size[g][2] == pytest.approx(0.96 * params.robot.body_height, rel=1e-6)
    assert m.body_mass[1:].sum() == pytest.approx(0.0348)


def _arm_track(name, amplitude):
    params = presets.params(name)
    g = GaitSpec(amplitude)
    a0 = g.setpoints(0.0, params.robot.servo_speed)
    res = simulate(params, [(0, 0, 0, a0[0], a0[1])], g, 2, track_stride=4, nthread=1)
    cmd = g.setpoints(res.track_t, params.robot.servo_speed)
    return res.track[:, 0, 3:], cmd, g


def test_lagging_servo_overlaps_the_arms_motions_at_small_amplitude():
    """The paper's SI: at 10 deg the real arm had not finished its move when
    the other arm started. With a 10 ms response lag, arm 1 is still more than
    a tenth of its swing short of the corner when arm 2 starts (a quarter
    period in), at least twice as far as the same robot's prompt PD servo."""
    gaps = {}
    a = math.radians(10.0)
    for name in ("lab-lag", "lab"):
        arms, cmd, g = _arm_track(name, 10.0)
        t = np.arange(1, len(arms) + 1) * 4 * presets.params(name).timestep
        q = int(np.argmin(np.abs(t - g.period() / 4)))
        gaps[name] = abs(arms[q, 0] - (-a))  # ccw: arm 1 moves +a -> -a in the first quarter
    assert gaps["lab-lag"] > 0.1 * 2 * a, math.degrees(gaps["lab-lag"])
    assert gaps["lab-lag"] > 2 * gaps["lab"], {k: math.degrees(v) for k, v in gaps.items()}


def test_dart_servo_stops_at_its_hard_stops():
    """DART's hinges end at +-90 deg: the arms reach the stops at the 90-deg
    corners and pass them by no more than a critically damped stop with the
    contacts' time constant allows an arm arriving at full speed (v tau / e)."""
    arms, cmd, g = _arm_track("lab-dart", 90.0)
    p = presets.params("lab-dart")
    assert np.abs(arms).max() < math.radians(90.0) + p.robot.servo_speed * p.contact_timeconst / math.e
    assert np.abs(arms).max() > math.radians(89.0)


def test_a_preset_round_trips_through_a_store_and_a_sidecar(tmp_path):
    out = tmp_path / "s.h5"
    r = _smx("scan", "--configs", "polar", "--positions", "3", "--periods", "1", "--model", "lab",
             "--out", out, "--quiet")
    assert r.exit_code == 0, r.output
    st = Store(out)
    assert st.model == "lab" and st.config["scan"]["model"] == "lab"
    assert st.config["scene"]["robot"]["arm_shape"] == "plate"
    assert st.config["scene"]["robot"]["hinge_inset"] == pytest.approx(0.006)
    csv = tmp_path / "t.csv"
    r = _smx("simulate", "--scene", "single", "--periods", "1", "--model", "lab-lag", "--out", csv)
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "t.json").read_text())["model"] == "lab-lag"
    from smarticle_mjx.calibrate.data import NUMERICS, load
    # the calibration compares the data with the sidecar's preset run with its own numerics (the discrete
    # integrator, since 0.4.3), and with another preset where asked
    trials = load(csv)
    assert trials[0].params == presets.apply(presets.params("lab-lag"), NUMERICS)
    assert load(csv, "paper")[0].params == presets.apply(presets.params("paper"), NUMERICS)
    assert load(csv, overrides=("integrator=implicitfast",))[0].params == presets.params("lab-lag")


@pytest.mark.parametrize("command", [
    ["simulate", "--periods", "1"],
    ["scan", "--configs", "polar", "--positions", "2", "--periods", "1"],
    ["sweep-amplitude", "--amplitudes", "90", "--periods", "1"],
    ["relax", "--trials", "1", "--periods", "1"],
    ["models", "--check"],
    ["validate"],
    ["synth", "SYNTH"],
    ["calibrate", "DATA"],
])
def test_unknown_model_is_one_line_exit_2_and_creates_nothing(tmp_path, command):
    command = [c.replace("SYNTH", str(tmp_path / "synth")).replace("DATA", str(tmp_path)) for c in command]
    before = sorted(tmp_path.iterdir())
    extra = [] if command[0] in ("models", "synth", "calibrate") else ["--out", tmp_path / "x.h5"]
    if command[0] == "simulate":
        extra = ["--out", tmp_path / "x.csv"]
    if command[0] == "validate":
        extra = ["--data", tmp_path / "d", "--out", tmp_path / "v.md"]
    r = _smx(*command, *extra, "--model", "nope")
    assert r.exit_code == 2, r.output
    assert "unknown model 'nope'" in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert sorted(tmp_path.iterdir()) == before


def test_models_list_names_every_preset_and_its_sources():
    r = _smx("models", "--list")
    assert r.exit_code == 0
    for name in presets.PRESETS:
        assert f"{name}" in r.output
    assert "smarticle_v6" in r.output


def test_mjx_runs_the_lagging_servo_like_mujoco_c():
    """The default's servo lag is an actuator filter state; MJX must carry it:
    a lone robot's arms over the first 60 steps agree with MuJoCo C to 1e-3
    rad, while the lag itself (against the prompt servo, MuJoCo C) is ten
    times that, so an MJX that dropped the filter would fail."""
    from smarticle_mjx.engine import Lanes, Scene, make_backend
    g = GaitSpec(30.0)
    out = {}
    for name, backends in (("lab-lag", ("native", "mjx")), ("lab", ("native",))):
        params = presets.params(name)
        a0 = g.setpoints(0.0, params.robot.servo_speed)
        lanes = Lanes.from_gait(np.array([[[0.0, 0.0, 0.0, a0[0], a0[1]]]]), g)
        scene = Scene.build(params, 1)
        for backend in backends:
            be = make_backend(backend, scene)
            q = np.asarray(be.step_qpos(lanes, 60))[0, :, scene.layout.arm_qpos[0]]
            out[name, backend] = q
            if hasattr(be, "close"):
                be.close()
    np.testing.assert_allclose(out["lab-lag", "mjx"], out["lab-lag", "native"], atol=1e-3)
    lag = out["lab", "native"] - out["lab-lag", "native"]
    assert np.abs(lag).max() > 0.01  # 15 ms into arm 1's move the lagging arm is ~0.07 rad behind
