"""smx validate --suite paper end to end on tiny versions of its studies: the basin-scan claims only, each
beside the small suite's verdict, the rebinding table, the descent read at convergence; bad suites refused."""

import json

from typer.testing import CliRunner

from smarticle_mjx.cli import app
from smarticle_mjx.presets import DEFAULT
from smarticle_mjx.suite import PAPER_STUDIES, STUDIES
from smarticle_mjx.validate import paper_claims

TINY = {
    "random_90": 'configs = "random"\nn = 24\nr_range_W = [0.9, 1.4]\namplitudes_deg = [90]\nperiods = 8\n',
    "polar": 'configs = "polar"\nradius_W = 1.3\npositions = 4\norientations = 1\namplitudes_deg = [90]\nperiods = 2\n',
    "amplitude": 'configs = "random"\nn = 4\nr_range_W = [0.9, 1.6]\namplitudes_deg = [50, 90]\nperiods = 2\n',
    "rebind": 'configs = "random"\nn = 4\nr_range_W = [0.9, 1.6]\namplitudes_deg = [50, 90]\nperiods = 4\n'
              'quiet_periods = 0\nseed = 1\n',
    "descent": 'configs = "bound"\nsource = "random_90"\npairs = 100000\namplitudes_deg = [90, 80]\nperiods = 4\n'
               'steady_window = 2\nkeep_window = 1\nconverge_tol = 0.05\n',
}


def test_paper_suite_judges_the_basin_scan_claims_beside_the_small_suite(tmp_path):
    sweeps = tmp_path / "sweeps"
    sweeps.mkdir()
    for name, text in TINY.items():
        (sweeps / PAPER_STUDIES[name]).write_text("[study]\n" + text)
    docs = tmp_path / "docs"
    (docs / "validation").mkdir(parents=True)
    # the small suite's page: every claim "does not hold", so any claim that holds here is listed as moved
    rows = [{"claim": c.text, "paper": c.paper, "measured": "small", "test": c.test, "verdict": "does not hold",
             "note": ""} for c in paper_claims(PAPER_STUDIES)]
    (docs / "validation" / "validation.json").write_text(json.dumps({"model": DEFAULT, "rows": rows, "extra": {}}))
    out = docs / "validation-paper.md"
    args = ["validate", "--suite", "paper", "--data", tmp_path / "data", "--out", out, "--sweeps", sweeps, "--quiet"]
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 0, r.output
    got = json.loads((docs / "validation-paper" / "validation.json").read_text())
    keys = [c.key for c in paper_claims(PAPER_STUDIES)]
    # the basin-scan claims, no lone robot, relaxation, chirality or diagonal-gait claim
    assert len(got["rows"]) == len(keys) and {"lone_drift", "relax_emergence", "mirror", "diagonal_beta"}.isdisjoint(keys)
    assert {"both_types", "polar_symmetry", "pb_dip", "descent"} <= set(keys)
    page = out.read_text()
    assert f"--model {DEFAULT} --suite paper" in page and str(tmp_path) not in page
    held = [row for row in got["rows"] if row["verdict"] != "does not hold" and row["run"]]
    section = page.split("## What changed at the paper's size")[1].split("##")[0]
    assert section.count("\n- ") == len(held)  # every moved verdict listed with what differs
    # the rebinding table: one row per amplitude, counts that nest
    reb = got["extra"]["rebinding"]
    assert [x["amplitude_deg"] for x in reb] == [50.0, 90.0]
    assert all(x["valid"] >= x["ever_bound"] >= x["parted"] >= x["rebound"] >= x["rebound_at_end"] for x in reb)
    assert "## Pairs that came apart and bound again" in page
    # the descent read at convergence: every amplitude's stage ran, its row says how it was read
    desc = next(row for row in got["rows"] if row["claim"].startswith("steady-state"))
    stores = tmp_path / "data" / DEFAULT
    assert (stores / "random_90.h5").exists() and (stores / "paper_descent_a0900.h5").exists()
    assert "read where it converged" in desc["note"] and "not converged" in desc["measured"]
    # study names of the other suite, and an unknown suite: one line, exit 2, nothing written
    before = out.read_text()
    for bad in (["--studies", "relax"], ["--suite", "paper-ish"]):
        r = CliRunner().invoke(app, [str(a) for a in args[:1]] + [str(a) for a in args[1:]] + bad)
        assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1, r.output
    assert out.read_text() == before and STUDIES["relax"] not in page
