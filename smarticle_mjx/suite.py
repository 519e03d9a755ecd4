"""The validation suite's study files (docs/validation.md): where they live and which runs which study."""

from __future__ import annotations

import pathlib

SWEEPS = pathlib.Path(__file__).resolve().parents[1] / "sweeps"

# The validation suite's studies (docs/validation.md): name -> file in sweeps/, in the order they run
# (each started-bound study after its source, which it names among these).
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
