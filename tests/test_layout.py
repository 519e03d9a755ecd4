"""The package's layout rules that a reader relies on, checked on the source."""

import ast
import pathlib

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "smarticle_mjx"


def _private_imports(path: pathlib.Path, root: pathlib.Path = PACKAGE.parent) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            out += [f"{path.relative_to(root)}:{node.lineno} imports {a.name} from {node.module}"
                    for a in node.names if a.name.startswith("_") and not a.name.startswith("__")]
    return out


def test_no_module_imports_another_s_private_names():
    """A name with a leading underscore belongs to its module: what another
    module needs is public and documented there."""
    found = [line for p in sorted(PACKAGE.rglob("*.py")) for line in _private_imports(p)]
    assert not found, "\n".join(found)


def test_the_check_sees_a_private_import(tmp_path):
    p = tmp_path / "probe.py"
    p.write_text("from __future__ import annotations\nfrom .scan import _hidden, public\n")
    assert _private_imports(p, tmp_path) == ["probe.py:2 imports _hidden from scan"]
