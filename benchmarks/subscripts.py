"""How many times does code outside the page writers read a value by a string key?

The measurement-layer issue asks that measured results travel as typed objects, so that only the page
writers (which format them) index anything by name. This counts, per module of the package, subscripts
whose key is a string literal (``x["beta"]``, ``s["v_com"]["net_lo"]``: each ``[...]`` counts once),
outside the page writers listed below. It over-counts (a JSON header or a keyword dict read by key counts
too): the number is a trend to push down, not a verdict.

    python benchmarks/subscripts.py            # total and the 15 largest modules
    python benchmarks/subscripts.py --all      # every module
"""

from __future__ import annotations

import argparse
import ast
import pathlib

PACKAGE = pathlib.Path(__file__).resolve().parents[1] / "smarticle_mjx"
PAGE_WRITERS = ("report.py", "calibrate/report.py", "validate/page.py", "plots.py")


def count(path: pathlib.Path, writes: bool = False) -> int:
    """String subscripts that read (``x["k"]`` as a value); ``writes``: also those assigned to or deleted
    (``out["k"] = v``, the form this script counted until November 2026, which builds JSON rather than
    reading a result)."""
    tree = ast.parse(path.read_text())
    return sum(isinstance(n, ast.Subscript) and isinstance(n.slice, ast.Constant) and isinstance(n.slice.value, str)
               and (writes or isinstance(n.ctx, ast.Load)) for n in ast.walk(tree))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--all", action="store_true")
    args = ap.parse_args()
    rows = []
    for p in sorted(PACKAGE.rglob("*.py")):
        rel = p.relative_to(PACKAGE).as_posix()
        if rel in PAGE_WRITERS:
            continue
        rows.append((count(p), count(p, writes=True), rel))
    rows.sort(reverse=True)
    print(f"string subscripts read outside the page writers: {sum(c for c, _, _ in rows)} in {len(rows)} modules "
          f"({sum(w for _, w, _ in rows)} with those assigned to, the count before November 2026)")
    for c, _, rel in rows if args.all else rows[:15]:
        print(f"  {c:5d}  {rel}")


if __name__ == "__main__":
    main()
