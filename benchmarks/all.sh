#!/usr/bin/env bash
# Every benchmark in one command (about 3 hours on 2 cores; the paper-sized
# scan alone is over an hour). Results land in benchmarks/results/*.json.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
$PY benchmarks/engine.py
$PY benchmarks/mjx_costs.py
$PY benchmarks/mjx_collision.py
$PY benchmarks/solver_convergence.py
$PY benchmarks/backend_agreement.py --configs 200 --periods 20
$PY benchmarks/timestep_convergence.py --configs 100 --periods 20
$PY benchmarks/label_sensitivity.py
$PY benchmarks/early_exit.py --configs 850 --periods 75
$PY benchmarks/full_scan.py --n 5000 --periods 75
$PY benchmarks/calibration.py
