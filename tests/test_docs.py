"""The Python page's snippets run as written (docs/python.md), and pages carry no machine's paths."""

import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_every_snippet_of_the_python_page_runs(tmp_path, monkeypatch, capsys):
    """Executed in order, in one namespace, in a scratch folder; each must
    print what its comments promise (checked on a few of them)."""
    pytest.importorskip("xarray")
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "python.md").read_text(), re.S)
    assert len(blocks) >= 5
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    for code in blocks:
        exec(compile(code, "docs/python.md", "exec"), ns)
    assert ns["res"].poses.shape == (11, 2, 5)
    assert sorted(ns["st"].runs) == ["a060.00", "a090.00"]
    assert (tmp_path / "figures" / "pb.png").exists() and (tmp_path / "figures" / "pb.svg").exists()
    assert 0 < ns["r_end"].where(ns["ds"].valid).mean() < 10


def test_pages_carry_no_machine_specific_paths():
    """README and docs name paths relative to the repository, never a folder
    of one machine (home folders, temporary folders, this checkout's path)."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    bad = re.compile(r"(/home/|/Users/|/tmp/|/work/|/root/|C:\\\\|/private/var/)")
    found = [f"{p.name}: {m.group(0)}" for p in pages for m in bad.finditer(p.read_text())]
    assert not found, found
