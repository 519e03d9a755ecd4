"""The package's layout rules that a reader relies on, checked on the source."""

import ast
import pathlib
import re

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


def _import_graph(package: pathlib.Path) -> dict[str, set[str]]:
    """Module -> the package's modules it imports (at the top or inside a function)."""
    mods = {}
    for p in package.rglob("*.py"):
        name = ".".join(p.relative_to(package.parent).with_suffix("").parts)
        mods[name.removesuffix(".__init__")] = p
    graph = {}
    for m, p in mods.items():
        here = m if p.name == "__init__.py" else m.rsplit(".", 1)[0]
        deps = set()
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = here.split(".")[:len(here.split(".")) - node.level + 1] if node.level else []
                target = ".".join(base + ([node.module] if node.module else []))
                deps |= {f"{target}.{a.name}" if f"{target}.{a.name}" in mods else target for a in node.names}
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names}
        graph[m] = {d for d in deps if d in mods and d != m}
    return graph


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    out = []
    for start in sorted(graph):
        stack, seen = [(start, [start])], set()
        while stack:
            v, path = stack.pop()
            for w in sorted(graph[v]):
                if w == start:
                    out.append(path + [start])
                elif w not in seen:
                    seen.add(w)
                    stack.append((w, path + [w]))
    return out


def test_no_import_circles():
    """Data flows one way: no module imports, directly or through others, a module that imports it
    (lazy imports inside functions count: they hide a circle, they do not remove it)."""
    found = _circles(_import_graph(PACKAGE))
    assert not found, "\n".join(" -> ".join(c) for c in found)


def test_the_circle_check_sees_a_lazy_circle(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "sub" / "a.py").write_text("from .b import x\n")
    (pkg / "sub" / "b.py").write_text("def f():\n    from ..c import y\n")
    (pkg / "c.py").write_text("import pkg.sub.a\n")
    assert _circles(_import_graph(pkg))[0] == ["pkg.c", "pkg.sub.a", "pkg.sub.b", "pkg.c"]
    (pkg / "c.py").write_text("")
    assert _circles(_import_graph(pkg)) == []


def test_one_number_formatter_prints_missing_values_as_a_dash():
    """Pages, reports and benchmark tables round through smarticle_mjx.formatting alone: a missing or
    non-finite value is a dash (never "nan"), an interval keeps its value when a bound is missing."""
    import math
    from smarticle_mjx import formatting, report
    from smarticle_mjx.validate import claims
    assert formatting.num(None) == formatting.num(math.nan) == formatting.num(math.inf) == "–"
    assert formatting.num(0.12345, ".3f") == "0.123" and formatting.num(2.5e-5, ".1e", dash="—") == "2.5e-05"
    assert formatting.ci(0.5, None, 0.75) == "0.50 [–, 0.75]"
    assert formatting.pm(1.0, math.nan, ".1f") == "1.0 ± –"
    assert claims.ci(0.1, 0.05, 0.2, ".2f") == formatting.ci(0.1, 0.05, 0.2)
    assert report._pm(1.0, math.nan) == "1.000 ± –" and report._ci(None, 0.0, 1.0) == "–"


def test_the_reducers_import_no_store_engine_or_page_and_the_study_runner_no_report():
    """reduce/ is numpy on plain arrays: it imports nothing that reads stores, runs the engine or writes
    pages (it may use labels and formatting-free helpers); studies/runner pick stores' contents through the
    typed layer (reduce.analysis), not through the report that formats it."""
    graph = _import_graph(PACKAGE)
    upstream = ("smarticle_mjx.store", "smarticle_mjx.engine", "smarticle_mjx.report", "smarticle_mjx.validate",
                "smarticle_mjx.studies", "smarticle_mjx.runner", "smarticle_mjx.plots", "smarticle_mjx.cli")
    bad = [f"{m} imports {d}" for m, deps in sorted(graph.items()) if m.startswith("smarticle_mjx.reduce")
           for d in sorted(deps) if d.startswith(upstream)]
    bad += [f"{m} imports {d}" for m in ("smarticle_mjx.studies", "smarticle_mjx.runner")
            for d in sorted(graph.get(m, ())) if d == "smarticle_mjx.report"]
    assert not bad, "\n".join(bad)


# Public reducers that still return dicts (or lists of dicts), to be typed as the measurement-layer issue
# asks; any other public function of reduce/ must say it returns a dataclass, an array or plain numbers.
DICT_REDUCERS_PENDING: set[str] = set()


def test_the_reducers_return_typed_results_not_dicts():
    """Every public function of reduce/ annotates what it returns, and no dict unless it is listed as still
    pending above (the list only shrinks: a reducer typed since must leave it)."""
    import importlib
    import inspect
    import pkgutil
    import smarticle_mjx.reduce as R
    found = set()
    for m in pkgutil.iter_modules(R.__path__):
        mod = importlib.import_module(f"smarticle_mjx.reduce.{m.name}")
        for name, fn in inspect.getmembers(mod, inspect.isfunction):
            if fn.__module__ != mod.__name__ or name.startswith("_"):
                continue
            ann = inspect.signature(fn).return_annotation
            assert ann is not inspect.Signature.empty, f"reduce.{m.name}.{name} does not say what it returns"
            if "dict" in str(ann):
                found.add(f"{m.name}.{name}")
    assert found <= DICT_REDUCERS_PENDING, f"new dict-returning reducers: {sorted(found - DICT_REDUCERS_PENDING)}"
    assert found == DICT_REDUCERS_PENDING, f"typed since, leave the pending list: {sorted(DICT_REDUCERS_PENDING - found)}"


def _benchmark_imports(test_file: pathlib.Path, names: set[str]) -> list[str]:
    """What a test file imports of the benchmark scripts ``names``, and any change it makes to sys.path."""
    tree = ast.parse(test_file.read_text())
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            bad += [a.name for a in node.names if a.name.split(".")[0] in names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in names:
            bad.append(node.module)
        elif isinstance(node, ast.Attribute) and node.attr in ("insert", "append") and \
                isinstance(node.value, ast.Attribute) and node.value.attr == "path" and \
                isinstance(node.value.value, ast.Name) and node.value.value.id == "sys":
            bad.append("sys.path")
    return bad


def test_no_test_imports_a_benchmark_script():
    """Tests check the package; a benchmark's logic that a test needs lives in the package (the stress
    suite's generator and scoring in calibrate.stress, the mismatch table's estimate in calibrate.discrepancy,
    the step checks' collection in bench). A test may run a script as a user does, never import it."""
    root = pathlib.Path(__file__).resolve().parents[1]
    names = {p.stem for p in (root / "benchmarks").glob("*.py")}
    assert "calibration_stress" in names
    bad = {p.name: b for p in sorted((root / "tests").glob("*.py")) if (b := _benchmark_imports(p, names))}
    assert not bad, bad


def test_the_benchmark_import_check_sees_one(tmp_path):
    t = tmp_path / "test_x.py"
    t.write_text("import sys\nsys.path.insert(0, 'benchmarks')\ndef f():\n    import calibration_stress as S\n"
                 "    from glider_step import SEED\n")
    assert sorted(_benchmark_imports(t, {"calibration_stress", "glider_step"})) == ["calibration_stress",
                                                                                    "glider_step", "sys.path"]


def _dict_stages(source: str) -> list[str]:
    """Stage functions (``*_stage``, ``calibrate``) of a module's source that do not annotate a return, or
    annotate a dict or a list of dicts."""
    bad = []
    for node in ast.parse(source).body:
        if isinstance(node, ast.FunctionDef) and (node.name.endswith("_stage") or node.name == "calibrate"):
            ret = ast.unparse(node.returns) if node.returns is not None else ""
            if not ret or ret.startswith(("dict", "list[dict")) or ret == "list":
                bad.append(f"{node.name} -> {ret or '?'}")
    return bad


def test_the_calibration_stages_return_typed_results():
    """Each stage of the calibration loop (calibrate/stages.py) returns a dataclass (or a tuple of them),
    never a dict: what a stage found is read by name, and the report's JSON is made from it in one place."""
    root = pathlib.Path(__file__).resolve().parents[1]
    src = (root / "smarticle_mjx" / "calibrate" / "stages.py").read_text()
    assert "def calibrate(" in src and "def rounds_stage(" in src
    assert not _dict_stages(src), _dict_stages(src)
    assert _dict_stages("def noise_stage(x) -> dict:\n    pass\ndef tilt_stage(x) -> list[dict]:\n    pass\n"
                        "def calibrate(x):\n    pass\ndef helper(x) -> dict:\n    pass\n") == [
        "noise_stage -> dict", "tilt_stage -> list[dict]", "calibrate -> ?"]


_HISTORY = re.compile(r"(version \d+\.\d+\.\d+|(since|after|until) (fresh )?seed \d{4}|(since|after) (November|December) "
                      r"20\d\d)", re.I)


def _history_lines(src: str) -> list[str]:
    """Lines of ``src`` whose comments or docstrings date a rule by a package version or a seed."""
    return [line.strip() for line in src.splitlines() if _HISTORY.search(line)]


def test_the_calibration_code_keeps_no_version_history():
    """When and on which sets a step of the calibration came in is research history: it lives in
    notebook/calibration-rules.md, and the code states the step and its reason only."""
    root = pathlib.Path(__file__).resolve().parents[1]
    found = {p.name: _history_lines(p.read_text()) for p in (root / "smarticle_mjx" / "calibrate").glob("*.py")
             if p.name != "stress.py"}  # the stress suite records which version ran which seed: its data
    assert not any(found.values()), {k: v for k, v in found.items() if v}
    assert _history_lines("x = 1  # since version 0.4.3\n# (since seed 2051)\ny = 2\n") == [
        "x = 1  # since version 0.4.3", "# (since seed 2051)"]
    assert (root / "notebook" / "calibration-rules.md").is_file()


def test_the_calibration_report_only_formats():
    """calibrate/report.py formats what the stages found: it imports nothing that simulates or fits (the
    held-out comparison is a stage of its own, calibrate/heldout.py)."""
    root = pathlib.Path(__file__).resolve().parents[1]
    tree = ast.parse((root / "smarticle_mjx" / "calibrate" / "report.py").read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert not imported & {"sim", "fit", "stages", "nominal", "heldout.compare_heldout", "..engine.simulate"}, imported
    assert not any("simulate" in a.name or "fit_" in a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                   for a in n.names)


_BY_NAME = re.compile(r"backend\w*\)?\s*(==|!=|not in|in)\s*\(?\s*[\"'](native|mjx|warp|dart)[\"']")


def test_no_backend_is_checked_by_name_outside_the_capability_table():
    """What a backend can run is read from one table (smarticle_mjx/capabilities.py), so an unsupported option
    is refused by one rule with one message; only the backend registry (engine/__init__.py) names backends."""
    root = pathlib.Path(__file__).resolve().parents[1] / "smarticle_mjx"
    allowed = {root / "capabilities.py", root / "engine" / "__init__.py"}
    found = [f"{p.relative_to(root)}:{i}" for p in root.rglob("*.py") if p not in allowed
             for i, line in enumerate(p.read_text().splitlines(), 1) if _BY_NAME.search(line)]
    assert not found, found
    assert _BY_NAME.search('    if backend == "dart":') and _BY_NAME.search('if self.backend in ("mjx", "warp"):')
    assert not _BY_NAME.search('for m in ("warp", "mujoco_warp")')


def test_every_backend_has_a_row_in_the_capability_table():
    from smarticle_mjx.capabilities import CAPABILITIES, FEATURES, refusal, supports
    from smarticle_mjx.engine import BACKENDS
    assert set(CAPABILITIES) == set(BACKENDS) and all(set(c) <= set(FEATURES) for c in CAPABILITIES.values())
    assert supports("native", "start_delays") and not supports("mjx", "start_delays")
    assert refusal("warp", "collision_record") == ("collision records (--collisions) run on the native and dart "
                                                   "backends, not warp")


def test_the_engine_page_prints_the_capability_table_the_code_reads():
    from smarticle_mjx.capabilities import markdown
    page = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "engine.md").read_text()
    assert "\n".join(markdown()) in page


# benchmarks that still import another benchmark (research readings to move to notebook/, the house issue's
# item 1): the list may only shrink
_BENCHMARK_IMPORTS_LEFT = {"host_gait_cost.py", "plate_level_gate.py", "play_probe.py", "step_mechanism.py",
                           "step_profile.py", "substep_cost.py", "tip_trace.py", "warp_flags.py"}


def test_benchmarks_import_the_package_not_each_other():
    """A benchmark's shared logic lives in the package (the stress suite's set runner in calibrate.stress):
    no benchmark imports benchmarks/calibration_stress.py, and no new one imports another benchmark."""
    root = pathlib.Path(__file__).resolve().parents[1]
    names = {p.stem for p in (root / "benchmarks").glob("*.py")}
    importing = {p.name for p in sorted((root / "benchmarks").glob("*.py"))
                 if [b for b in _benchmark_imports(p, names - {p.stem}) if b != "sys.path"]}
    assert importing <= _BENCHMARK_IMPORTS_LEFT, importing - _BENCHMARK_IMPORTS_LEFT
