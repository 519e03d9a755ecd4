"""The validation suites' study files: where they live and which runs which study.

Two suites, each a mapping study name -> file in sweeps/, in the order they run (a started-bound study
after its source, which it names among these):

* ``small`` (``docs/validation.md``, ``docs/validation-lab.md``): every claim of the paper, each study cut to
  a size a day's work reruns;
* ``paper`` (``docs/validation-paper.md``): the basin-scan claims on the studies at the sizes the paper ran
  them (5000 random starts, the 1000-point polar scan, 1000 starts per amplitude, every steady C1 glider
  of the 5000 scan started bound), plus the rebinding of pairs that came apart.

Stores are named by file stem, so both suites can share one data folder.
"""

from __future__ import annotations

import pathlib

SWEEPS = pathlib.Path(__file__).resolve().parents[1] / "sweeps"

STUDIES = {
    "random_90": "validation_random.toml",
    "polar": "validation_polar.toml",
    "amplitude": "validation_amplitude.toml",
    "cw_90": "validation_cw.toml",
    "descent": "validation_descent.toml",
    "diagonal_90": "validation_diagonal.toml",
    "diagonal_random": "validation_diagonal_random.toml",
    "relax": "validation_relax.toml",
}

PAPER_STUDIES = {
    "random_90": "random_90.toml",
    "polar": "polar_1p3.toml",
    "amplitude": "paper_amplitude.toml",
    "rebind": "paper_rebind.toml",
    "descent": "paper_descent.toml",
}

SUITES = {"small": STUDIES, "paper": PAPER_STUDIES}
DEFAULT_SUITE = "small"
STUDY_NAMES = tuple(dict.fromkeys([*STUDIES, *PAPER_STUDIES]))  # every name a study of some suite has


def suite(name: str | None) -> dict[str, str]:
    """The studies of suite ``name`` (None: the small one); ValueError, one line, for an unknown name."""
    name = DEFAULT_SUITE if name is None else name
    if name not in SUITES:
        raise ValueError(f"--suite: unknown suite {name!r}; known: {', '.join(SUITES)}")
    return SUITES[name]
