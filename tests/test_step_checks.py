"""The package's table of time-step checks (smarticle_mjx/reduce/step_checks.json) and what enters it
(benchmarks/step_checks.py)."""

import json
import pathlib
import sys

from smarticle_mjx import bench
from smarticle_mjx.reduce import stepcheck

RESULTS = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "results"


def test_a_row_enters_the_table_only_where_its_scene_is_the_presets_at_its_step():
    """A check measures one model at one step. The `lab` robots' gear teeth are built as stiff as the step
    integrates (2 dt), so a row that names teeth of 0.5 ms at 0.25 ms builds the preset's own scene and
    enters; the same teeth at 0.0625 ms are another robot (the preset builds 0.125 ms teeth there) and do
    not, nor does a changed mass; a change of numerics alone always enters."""
    teeth = {"integrator": "implicitfast", "contact_substeps": 1, "robot": {"backlash_stop_timeconst": 5e-4}}
    assert bench.builds_preset("lab-lag", "lab", {"dt_s": 2.5e-4, "changes": teeth})
    assert not bench.builds_preset("lab-lag", "lab", {"dt_s": 6.25e-5, "changes": teeth})
    assert not bench.builds_preset("lab-lag", "lab", {"dt_s": 2.5e-4, "changes": {"robot": {"mass": 0.03}}})
    assert bench.builds_preset("lab-lag", "none", {"dt_s": 5e-4, "changes": {"integrator": "RK4"}})
    assert not bench.builds_preset("lab-lag", "none", {"dt_s": 5e-4, "changes": {"contact_timeconst": 0.002}})


def test_the_packages_table_is_what_its_sources_give():
    """The table a report reads is the one benchmarks/step_checks.py collects from the committed results,
    key by key and number by number (a source rerun without the table rewritten, or the reverse, fails
    here). The `lab` robots at the default step take the measurement made on today's robots (after
    version 0.4.1's start delays), not the one made on the robots before them."""
    table = {e["key"]: e for e in json.loads(stepcheck.TABLE.read_text())["checks"]}
    collected = {stepcheck.key_of(c): json.loads(json.dumps(c.as_dict())) for c in bench.collect_step_checks(RESULTS)}
    assert set(table) == set(collected)
    for key, e in table.items():
        assert {k: v for k, v in e.items() if k != "key"} == collected[key], key
    lab = table["lab-lag|lab|0.25 ms|implicitfast"]
    assert lab["source"] == "step_mechanism_lab_runs30_stops-0.5ms_against-default.json"


def test_the_mechanism_study_refuses_a_variant_it_does_not_have(tmp_path):
    """`step_mechanism.py --only` with a name that is no variant stops with one line naming it, before any
    run and without writing a results file (it used to run only the reference, silently)."""
    import subprocess
    root = pathlib.Path(__file__).resolve().parents[1]
    out = tmp_path / "never.json"
    p = subprocess.run([sys.executable, str(root / "benchmarks" / "step_mechanism.py"),
                        "--only", "0.25 ms implicitfast,0.3 ms nothing", "--out", str(out)],
                       capture_output=True, text=True, timeout=120, cwd=root,
                       env={**__import__("os").environ, "PYTHONPATH": str(root)})
    assert p.returncode != 0
    err = p.stderr.strip().splitlines()
    named, listed = err[0].split("the variants are")
    assert len(err) == 1 and "'0.3 ms nothing'" in named and "'0.25 ms implicitfast'" not in named
    assert "'0.25 ms implicitfast'" in listed
    assert not out.exists()
