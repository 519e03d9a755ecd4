"""How the package prints a measured number: the one formatter of pages, reports and benchmark tables.

Measured quantities travel unrounded (``reduce/``, ``validate/claims``); they are rounded only here,
where a page, a report or a benchmark's table prints them. A missing or non-finite value prints as a
dash, never as ``nan``.
"""

from __future__ import annotations

import math

DASH = "–"  # en dash: pages and reports; benchmark tables in docs/ pass their own (an em dash)


def _missing(x) -> bool:
    if x is None:
        return True
    try:
        return not math.isfinite(float(x))
    except (TypeError, ValueError):
        return False


def num(x, spec: str = ".2f", dash: str = DASH) -> str:
    """``x`` in format ``spec`` (``".3f"``, ``".1e"``, ``".0%"``...); ``dash`` for None or a non-finite value."""
    return dash if _missing(x) else format(x, spec)


def ci(value, lo, hi, spec: str = ".2f", dash: str = DASH) -> str:
    """``value [lo, hi]``, each in ``spec`` (an interval bound that is missing prints as ``dash``)."""
    return f"{num(value, spec, dash)} [{num(lo, spec, dash)}, {num(hi, spec, dash)}]"


def pm(value, err, spec: str = ".2f", dash: str = DASH) -> str:
    """``value ± err``, each in ``spec``."""
    return f"{num(value, spec, dash)} ± {num(err, spec, dash)}"
