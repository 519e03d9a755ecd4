"""smx validate end to end on tiny studies: every claim gets a row, stores are reused, not clobbered."""

import hashlib
import json
import pathlib

from typer.testing import CliRunner

from smarticle_mjx.cli import app
from smarticle_mjx.presets import DEFAULT
from smarticle_mjx.store import Store
from smarticle_mjx.suite import STUDIES

TINY = {
    "random_90": 'configs = "random"\nn = 24\nr_range_W = [0.9, 1.4]\namplitudes_deg = [90]\nperiods = 8\n',
    "polar": 'configs = "polar"\nradius_W = 1.3\npositions = 6\norientations = 1\namplitudes_deg = [90]\nperiods = 2\n',
    "amplitude": 'configs = "random"\nn = 4\nr_range_W = [0.9, 1.6]\namplitudes_deg = [20, 50, 70, 90]\nperiods = 2\n',
    "cw_90": 'configs = "random"\nn = 4\nr_range_W = [0.9, 1.6]\namplitudes_deg = [90]\nperiods = 2\nchirality = "cw"\n',
    "descent": 'configs = "bound"\nsource = "random_90"\npairs = 2\namplitudes_deg = [90, 80]\nperiods = 2\n'
               'continuation = true\nsteady_window = 2\nkeep_window = 1\n',
    "diagonal_90": 'configs = "bound"\nsource = "random_90"\npairs = 2\namplitudes_deg = [90]\nperiods = 2\n'
                   'gait = "diagonal"\nsteady_window = 2\nkeep_window = 1\n',
    "diagonal_random": 'configs = "random"\nn = 4\nr_range_W = [0.9, 1.6]\namplitudes_deg = [90]\nperiods = 2\n'
                       'gait = "diagonal"\n',
    "relax": 'configs = "relax"\nstages = 2\ntrials = 1\nn_robots = 3\nperiods = 3\n',
}


def _sweeps(tmp_path):
    d = tmp_path / "sweeps"
    d.mkdir()
    for name, text in TINY.items():
        (d / STUDIES[name]).write_text("[study]\n" + text)
    return d


def _hashes(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in folder.glob("*.h5")}


def test_validate_writes_a_row_per_claim_and_reuses_stores(tmp_path):
    sweeps, data, out = _sweeps(tmp_path), tmp_path / "data", tmp_path / "validation.md"
    args = ["validate", "--data", data, "--out", out, "--sweeps", sweeps, "--single-periods", "3", "--quiet"]
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 0, r.output
    res = json.loads((tmp_path / "validation" / "validation.json").read_text())
    rows = res["rows"]
    assert len(rows) == 13 and res["model"] == DEFAULT
    assert all(row["verdict"] in ("holds", "does not hold", "not measurable") for row in rows)
    page = out.read_text()
    assert page.count("\n| ") >= 13 and f"smx validate --data DIR --out PAGE --model {DEFAULT}" in page
    assert str(tmp_path) not in page  # no path of this machine on the page
    # the page says which time step and package version made its data (read from the stores)
    from smarticle_mjx import __version__, presets
    assert f"time step {presets.params(DEFAULT).timestep * 1e3:g} ms" in page
    assert f"smarticle-mjx {__version__}" in page.split("## Studies")[0]
    assert (tmp_path / "validation" / "pb.png").stat().st_size > 1000
    stores = data / DEFAULT
    # the started-bound studies ran from the random study's gliders: one store per stage
    names = {p.name for p in stores.glob("*.h5")}
    assert {"validation_random.h5", "validation_descent_a0900.h5", "validation_diagonal_a0900.h5",
            "validation_relax_s00.h5", "validation_relax_s01.h5"} <= names
    # the relaxation study's two stages are pooled into its rows (2 trials: too few to judge the fraction)
    relax = [row for row in rows if "relaxation trials" in row["claim"]][0]
    assert relax["measured"].startswith("0/2") and relax["verdict"] == "not measurable"
    assert Store(stores / "validation_relax_s01.h5").config["relax"]["first_trial"] == 1
    st = Store(stores / "validation_descent_a0900.h5")
    assert st.config["scan"]["configs"] == "explicit" and st.model == DEFAULT
    assert len(st.config["scan"]["initial"]) == 2
    # a second run reuses the stores bit for bit
    before = _hashes(stores)
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 0, r.output
    assert before == _hashes(stores)
    # a changed study is rerun; the old store is kept aside, byte for byte
    (sweeps / STUDIES["polar"]).write_text("[study]\n" + TINY["polar"].replace("positions = 6", "positions = 7"))
    r = CliRunner().invoke(app, [str(a) for a in args] + ["--studies", "polar"])
    assert r.exit_code == 0, r.output
    assert "different study file" in r.output
    after = _hashes(stores)
    aside = [n for n in after if n.startswith("validation_polar.replaced-")]
    assert len(aside) == 1 and after[aside[0]] == before["validation_polar.h5"]
    assert Store(stores / "validation_polar.h5").config["scan"]["positions"] == 7
    assert {k: v for k, v in after.items() if "polar" not in k} == {k: v for k, v in before.items() if "polar" not in k}


def test_a_store_survives_a_release_of_the_same_physics_and_is_rerun_and_kept_otherwise(tmp_path, monkeypatch):
    """Store reuse is keyed on what changes the stores: a release that keeps the physics version reuses the
    store as it is; another physics version reruns the study and keeps the old store aside; a store that
    records no physics version (written before it existed) is reused only by its own release."""
    import h5py
    from smarticle_mjx import store as S
    sweeps, data, out = _sweeps(tmp_path), tmp_path / "data", tmp_path / "v.md"
    args = ["validate", "--data", str(data), "--out", str(out), "--sweeps", str(sweeps), "--single-periods", "3",
            "--quiet", "--studies", "polar"]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    # only the chosen study ran; the others are reported as not run yet
    assert [p.name for p in (data / DEFAULT).glob("*.h5")] == ["validation_polar.h5"]
    rows = json.loads((tmp_path / "v" / "validation.json").read_text())["rows"]
    assert sum("not run yet" in row["measured"] for row in rows) == 11
    path = data / DEFAULT / "validation_polar.h5"
    assert Store(path).attrs["physics"] == S.PHYSICS_VERSION
    old = _hashes(data / DEFAULT)["validation_polar.h5"]
    monkeypatch.setattr(S, "PACKAGE", "smarticle-mjx 99.0")  # a later release, same physics: reused as it is
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0 and "made by" not in r.output, r.output
    assert _hashes(data / DEFAULT) == {"validation_polar.h5": old}
    monkeypatch.setattr(S, "PHYSICS_VERSION", S.PHYSICS_VERSION + 1)  # a release that changes stored numbers
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    assert "made by smarticle-mjx" in r.output and f"physics {S.PHYSICS_VERSION - 1}" in r.output
    h = _hashes(data / DEFAULT)
    assert len(h) == 2 and old in h.values() and h["validation_polar.h5"] != old
    assert Store(path).attrs["package"] == "smarticle-mjx 99.0" and Store(path).attrs["physics"] == S.PHYSICS_VERSION
    with h5py.File(path, "a") as f:  # as a store written before the attribute existed, by an earlier release
        del f.attrs["physics"]
        f.attrs["package"] = "smarticle-mjx 0.4.17"
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0 and "no physics version recorded" in r.output, r.output
    assert len(_hashes(data / DEFAULT)) == 3


def test_validate_rejects_an_unknown_study_in_one_line(tmp_path):
    r = CliRunner().invoke(app, ["validate", "--data", str(tmp_path / "d"), "--out", str(tmp_path / "v.md"),
                                 "--studies", "random_90,nope"])
    assert r.exit_code == 2 and "nope" in r.output and len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "d").exists() and not (tmp_path / "v.md").exists()


def test_validate_refuses_missing_study_files(tmp_path):
    r = CliRunner().invoke(app, ["validate", "--sweeps", str(tmp_path), "--out", str(tmp_path / "v.md")])
    assert r.exit_code == 2 and "study files missing" in r.output
    assert not pathlib.Path(tmp_path / "v.md").exists()


def _check_file(tmp_path, beta_here, beta_ref, step_here=0.5, model="lab-lag"):
    row = lambda dt, b: {"store": "x.h5", "timestep_ms": dt, "package": "p", "valid": 100, "gliders": 20,  # noqa: E731
                         "beta": [b, b - 0.1, b + 0.1], "v_com_W_per_period": [0.002, 0.001, 0.003]}
    path = tmp_path / "validation_step.json"
    path.write_text(json.dumps({"model": model, "rows": [row(0.0625, beta_ref), row(step_here, beta_here)]}))
    return path


def test_the_page_writes_its_time_step_check_itself(tmp_path):
    """The validation page's paragraph on its step is the code's, from the
    step check's file: built data where the β verdict moves between the
    page's step and the reference (1.54 holds |β − 1.8| < 0.3, 1.35 does
    not: one claim fewer), where it does not move, and files that belong to
    another model or to other stores, which the paragraph refuses to use."""
    from smarticle_mjx.validate.claims import beta_holds
    from smarticle_mjx.validate.page import step_check
    assert beta_holds(1.54) and not beta_holds(1.35) and not beta_holds(2.2) and beta_holds(float("nan")) is None
    from smarticle_mjx.validate.claims import ClaimRow, Validation
    row = lambda v: ClaimRow("a claim", "", "", "", v, "")  # noqa: E731
    result = Validation((row("holds"),) * 5 + (row("does not hold"),) * 8, {"random_90": {"beta": {"value": 1.5401}}})
    assert result.held == 5
    text = step_check(result, "lab-lag", {0.5}, _check_file(tmp_path, 1.54, 1.35))[0]
    assert "**does not hold** at the reference, so that row's verdict is the step's" in text
    assert "**4 of 13 claims hold**" in text and "β 1.35 [1.25, 1.45]" in text and "at 0.0625 ms" in text
    part = Validation((row("holds"),) * 2 + (ClaimRow("x", "", "study polar not run yet", "–", "not measurable", "",
                                                       run=False),) * 11, {})
    assert part.count_words() == ("**2 of the 2 claims measured hold** (11 of 13 not measured: their studies "
                                  "have not run)") and result.count_words() == "**5 of 13 claims hold**"
    assert Validation.from_json({"rows": [row("holds").as_dict() | {"run": False}], "extra": {}}).not_run == 1
    old_json = {k: v for k, v in row("holds").as_dict().items() if k != "run"}  # a page written before the field
    assert Validation.from_json({"rows": [old_json], "extra": {}}).not_run == 0
    result.extra["random_90"]["beta"]["value"] = 1.6
    text = step_check(result, "lab-lag", {0.5}, _check_file(tmp_path, 1.6, 1.7))[0]
    assert "holds here, the same" in text and "**5 of 13 claims hold**" in text
    assert "not made on this page's" in step_check(result, "lab-lag", {0.5}, _check_file(tmp_path, 1.3, 1.7))[0]
    assert "is of model `paper`" in step_check(result, "lab-lag", {0.5},
                                                 _check_file(tmp_path, 1.6, 1.7, model="paper"))[0]
    assert "No reference-step check" in step_check(result, "lab-lag", {0.5}, tmp_path / "none.json")[0]


def test_the_step_rule_gives_every_checked_claim_the_reference_verdict(tmp_path):
    """A check that ran whole studies at the reference step (the lab page's: random_90 and cw_90) carries
    the reference's verdict of every claim measured from them alone; the page takes the reference's
    verdict wherever the two differ, names those rows, and counts the claims that hold with them. Claims
    from other studies (and the lone robots, which no study holds) keep their verdicts. Built data: of
    the five claims measured from random_90 and cw_90, β holds here and not at the reference, the mirror
    the other way round, and C1's basin is the same at both."""
    from smarticle_mjx.validate.claims import CLAIMS, ClaimRow, Validation
    from smarticle_mjx.validate.page import step_check, step_check_path
    here = {"lone_drift": "holds", "both_types": "holds", "c1_basin": "holds", "c1_lifetime": "holds",
            "beta": "holds", "mirror": "does not hold", "relax_distance": "holds"}
    rows = tuple(ClaimRow(c.text, "", "", "", here.get(c.key, "does not hold"), "") for c in CLAIMS)
    result = Validation(rows, {"random_90": {"beta": {"value": 1.9501}}})
    assert result.held == 6
    path = _check_file(tmp_path, 1.95, 2.2)
    got = json.loads(path.read_text())
    got.update(studies=["random_90", "cw_90"], imperfections="lab",
               reference_verdicts={"lone_drift": "does not hold", "both_types": "holds", "c1_basin": "holds",
                                   "c1_lifetime": "holds", "beta": "does not hold", "mirror": "holds",
                                   "relax_distance": "does not hold"})
    path.write_text(json.dumps(got))
    text = step_check(result, "lab-lag", {0.5}, path)[0]
    assert "5 of 13" in text and "2 moved" in text and "**6 of 13 claims hold**" in text, text
    assert "“gliders at 90° move nearly ballistically (β ≈ 1.8)” holds here, **does not hold** at the reference" in text
    assert "**holds** at the reference" in text and "lone robot" not in text and "2.9" not in text
    assert step_check_path("lab").name == "validation_step_lab.json" and step_check_path().name == "validation_step.json"


def test_validate_with_imperfections_keeps_its_stores_apart_and_records_the_robots(tmp_path):
    """--imperfections lab runs the studies with drawn robots into DATA/MODEL+lab: the ideal model's
    stores are not touched, every store records the set and its draws, the lone-robot row is the mean
    of several drawn robots, the page names the set, and a second run reuses the stores bit for bit.
    Study files that draw K robot pairs from one robot seed: the cw and ccw stores record the same pool of
    2K robots though their configurations' seeds differ, and the mirror row and the page say so."""
    sweeps, data, out = _sweeps(tmp_path), tmp_path / "data", tmp_path / "v.md"
    for name in ("random_90", "cw_90"):
        f = sweeps / STUDIES[name]
        f.write_text(f.read_text() + ("seed = 3\n" if name == "cw_90" else "") + "robot_draws = 3\nrobot_seed = 0\n")
    args = ["validate", "--data", str(data), "--out", str(out), "--sweeps", str(sweeps), "--single-periods", "3",
            "--quiet", "--studies", "polar,relax,random_90,cw_90"]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    ideal = _hashes(data / DEFAULT)
    r = CliRunner().invoke(app, args + ["--imperfections", "lab"])
    assert r.exit_code == 0, r.output
    assert _hashes(data / DEFAULT) == ideal
    folder = data / f"{DEFAULT}+lab"
    polar = Store(folder / "validation_polar.h5")
    assert polar.config["scan"]["imperfections"] == "lab" and polar.config["imperfections"]["name"] == "lab"
    relax = Store(folder / "validation_relax_s00.h5")
    assert relax.config["relax"]["imperfections"] == "lab"
    page = out.read_text()
    assert "set `lab`" in page and "--imperfections lab" in page
    rows = json.loads((tmp_path / "v" / "validation.json").read_text())["rows"]
    assert "mean of 8 robots" in rows[0]["measured"]
    ccw, cw = (Store(folder / STUDIES[n].replace(".toml", ".h5")) for n in ("random_90", "cw_90"))
    assert cw.config["scan"]["seed"] == 3 and ccw.config["scan"]["seed"] == 0
    assert cw.config["imperfections"] == ccw.config["imperfections"]
    assert cw.config["imperfections"]["pairs"] == 3 and len(cw.config["imperfections"]["clock"]) == 6
    mirror = next(row for row in rows if row["claim"].startswith("opposite chirality"))
    assert "both on the same 3 drawn robot pairs" in mirror["note"], mirror
    assert "lane i on pair i mod K (3 pairs from robot seed 0, the same pairs in each)" in page
    ideal_cw = Store(data / DEFAULT / STUDIES["cw_90"].replace(".toml", ".h5"))
    assert "robot_draws" not in ideal_cw.config["scan"]  # ideal robots: the draws change nothing stored
    before = _hashes(folder)
    r = CliRunner().invoke(app, args + ["--imperfections", "lab"])
    assert r.exit_code == 0, r.output
    assert _hashes(folder) == before and "note:" not in r.output


def test_validate_rejects_unknown_imperfections_in_one_line(tmp_path):
    r = CliRunner().invoke(app, ["validate", "--data", str(tmp_path / "d"), "--out", str(tmp_path / "v.md"),
                                 "--imperfections", "wobbly"])
    assert r.exit_code == 2 and "wobbly" in r.output and len(r.output.strip().splitlines()) == 1
    assert not (tmp_path / "d").exists() and not (tmp_path / "v.md").exists()


def test_validate_with_set_runs_every_study_with_the_change_and_keeps_its_stores_apart(tmp_path):
    """--set timestep=0.00025 (the step the default-step study names) runs the studies and lone robots with
    that field changed, into DATA/MODEL~timestep=0.00025 (the default model's folder is not made), each
    store records the override and the step, the page names the change and its regenerate command carries
    it; a bad field is one line, exit 2, before anything is written."""
    sweeps, data, out = _sweeps(tmp_path), tmp_path / "data", tmp_path / "v.md"
    args = ["validate", "--data", str(data), "--out", str(out), "--sweeps", str(sweeps), "--single-periods", "3",
            "--quiet", "--studies", "polar,relax"]
    r = CliRunner().invoke(app, args + ["--set", "timestep=0.00025"])
    assert r.exit_code == 0, r.output
    assert {p.name for p in data.iterdir()} == {f"{DEFAULT}~timestep=0.00025"}
    folder = data / f"{DEFAULT}~timestep=0.00025"
    polar = Store(folder / "validation_polar.h5")
    assert polar.config["scan"]["overrides"] == {"timestep": 0.00025}
    assert polar.config["scene"]["timestep"] == 0.00025
    relax = Store(folder / "validation_relax_s00.h5")
    assert relax.config["relax"]["overrides"] == {"timestep": 0.00025}
    page = out.read_text()
    assert "`timestep=0.00025` changed from the preset" in page and "--set timestep=0.00025" in page
    assert "time step 0.25 ms" in page
    # a page of two studies counts only the claims it could measure, and says how many it could not
    rows = json.loads((tmp_path / "v" / "validation.json").read_text())["rows"]
    unrun = sum("not run yet" in row["measured"] for row in rows)
    assert 0 < unrun < len(rows) and sum(not row["run"] for row in rows) == unrun
    assert f"claims measured hold** ({unrun} of {len(rows)} not measured: their studies have not run)" in page
    before = {p.name for p in data.iterdir()}
    for bad, says in (("robot.wobble=1", "wobble"), ("robot.mass=0.001", "must exceed the two arms' mass")):
        r = CliRunner().invoke(app, args + ["--set", bad])
        assert r.exit_code == 2 and says in r.output and len(r.output.strip().splitlines()) == 1, r.output
        assert {p.name for p in data.iterdir()} == before
