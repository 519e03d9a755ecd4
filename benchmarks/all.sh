#!/usr/bin/env bash
# Every benchmark in one command (about 7 hours on 2 cores; the paper-sized
# scan alone is over an hour, the fidelity study about an hour). Results land in benchmarks/results/*.json.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PY:-.venv/bin/python}
$PY benchmarks/engine.py
$PY benchmarks/mjx_warp_path.py  # MuJoCo Warp direct vs MJX's impl='warp' (needs the gpu extra; ~5 min on the CPU)
$PY benchmarks/mjx_costs.py
$PY benchmarks/mjx_collision.py
$PY benchmarks/solver_convergence.py
$PY benchmarks/backend_agreement.py --configs 200 --periods 20
# numerics (docs/timestep.md): the 0.0625 ms reference (~35 min), the screen, the confirmation, costs; resumable
$PY benchmarks/timestep_candidates.py --candidates ref --configs 400
$PY benchmarks/timestep_candidates.py --candidates all --configs 100
$PY benchmarks/timestep_candidates.py --candidates implicitfast-0.25ms,implicitfast-0.5ms,implicitfast-1ms,discrete-1ms --configs 400
$PY benchmarks/fidelity_screen.py --models lab-lag --pairs 128 --periods 100 --pb 0 --numerics implicitfast-0.5ms
$PY benchmarks/timestep_candidates.py --fidelity --candidates implicitfast-0.5ms
$PY benchmarks/timestep_candidates.py --timing --candidates all
$PY benchmarks/label_sensitivity.py --configs 200
$PY benchmarks/early_exit.py --configs 850 --periods 75
$PY benchmarks/full_scan.py --n 5000 --periods 75
$PY benchmarks/calibration.py --max-minutes 90  # both suites; about an hour
# fidelity study (docs/fidelity.md): screen, confirm, time step, mechanism; resumable
$PY benchmarks/fidelity_screen.py --pairs 48 --periods 40
$PY benchmarks/fidelity_screen.py --models lab-lag,paper --pairs 128 --periods 100 --pb 0
for m in lab-lag lab-dart dart; do $PY benchmarks/fidelity_screen.py --models $m --pairs 24 --periods 40 --pb 0; done
$PY benchmarks/fidelity_screen.py --models lab-lag,lab-dart --dt-divisor 4 --pairs 24 --periods 40 --pb 0
$PY benchmarks/fidelity_screen.py --models dart --dt-divisor 2 --pairs 24 --periods 40 --pb 0
$PY benchmarks/fidelity_mechanism.py --models paper,lab,lab-lag,lab-dart,dart --periods 60
$PY benchmarks/fidelity_mechanism.py --return-maps --models paper,paper-stiff,paper-dart,lab,lab-stiff,lab-dart,lab-lag,dart
# the validation page (docs/validation.md): about 25 minutes plus the relaxation study (100 trials x 300
# periods of 7 robots, about 1.5 hours in five resumable stages); stores reused when current
$PY -m smarticle_mjx.cli validate --data validation-data --out docs/validation.md --quiet
$PY benchmarks/relax_cost.py --study validation-data/lab-lag
# glider transport against the time step (docs/timestep.md): 0.25 and 0.5 ms against a 0.0625 ms
# reference on the fidelity confirmation's starts (~30 min), and the validation page's 90° study at the
# reference (~25 min; compared with the page's own store)
$PY benchmarks/glider_step.py
$PY benchmarks/validation_step.py --compare validation-data/lab-lag/validation_random.h5
