"""smx validate end to end on tiny studies: every claim gets a row, stores are reused, not clobbered."""

import hashlib
import json
import pathlib

from typer.testing import CliRunner

from smarticle_mjx.cli import app
from smarticle_mjx.validation import STUDIES

TINY = {
    "random_90": 'configs = "random"\nn = 10\nr_range_W = [0.9, 1.6]\namplitudes_deg = [90]\nperiods = 3\n',
    "polar": 'configs = "polar"\nradius_W = 1.3\npositions = 6\norientations = 1\namplitudes_deg = [90]\nperiods = 2\n',
    "amplitude": 'configs = "random"\nn = 4\nr_range_W = [0.9, 1.6]\namplitudes_deg = [20, 50, 70, 90]\nperiods = 2\n',
    "cw_90": 'configs = "random"\nn = 4\nr_range_W = [0.9, 1.6]\namplitudes_deg = [90]\nperiods = 2\nchirality = "cw"\n',
    "diagonal_90": 'configs = "random"\nn = 4\nr_range_W = [0.9, 1.6]\namplitudes_deg = [90]\nperiods = 2\n'
                   'gait = "diagonal"\n',
}


def _sweeps(tmp_path):
    d = tmp_path / "sweeps"
    d.mkdir()
    for name, text in TINY.items():
        (d / STUDIES[name]).write_text("[study]\n" + text)
    return d


def test_validate_writes_a_row_per_claim_and_reuses_stores(tmp_path):
    sweeps, data, out = _sweeps(tmp_path), tmp_path / "data", tmp_path / "validation.md"
    args = ["validate", "--data", data, "--out", out, "--sweeps", sweeps, "--single-periods", "3", "--quiet"]
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 0, r.output
    rows = json.loads((tmp_path / "validation" / "validation.json").read_text())["rows"]
    assert len(rows) == 10
    assert all(row["verdict"] in ("holds", "does not hold", "not measurable") for row in rows)
    page = out.read_text()
    assert page.count("\n| ") >= 10 and "smx validate --data" in page
    assert (tmp_path / "validation" / "pb.png").stat().st_size > 1000
    # a second run reuses the stores bit for bit
    before = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in data.glob("*.h5")}
    assert len(before) == len(STUDIES)
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 0, r.output
    assert before == {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in data.glob("*.h5")}
    # a changed study never overwrites the old store
    (sweeps / STUDIES["polar"]).write_text("[study]\n" + TINY["polar"].replace("positions = 6", "positions = 7"))
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 2 and "different study" in r.output
    assert before == {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in data.glob("*.h5")}


def test_validate_refuses_missing_study_files(tmp_path):
    r = CliRunner().invoke(app, ["validate", "--sweeps", str(tmp_path), "--out", str(tmp_path / "v.md")])
    assert r.exit_code == 2 and "study files missing" in r.output
    assert not pathlib.Path(tmp_path / "v.md").exists()
