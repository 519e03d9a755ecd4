#!/usr/bin/env bash
# The GPU figures of docs/engine.md, in one command, on a machine with an NVIDIA
# GPU and the gpu extra installed (pip install -e '.[gpu]'; JAX with CUDA for mjx):
#
#   bash benchmarks/gpu.sh            # every stage
#   bash benchmarks/gpu.sh tests      # one stage: tests | throughput | mjx | mjxwarp | agreement | agreement-mjx | scan
#
# The Warp stages have run on one H100 and one H200 (at 0.25 ms: the scan stage
# took about 5 minutes); of the MJX stages the throughput (mjx) and MJX's Warp path (mjxwarp) have been
# timed on a GPU (an H200, through benchmarks/gpu_lease.sh, which carries the
# wheels to a machine without a package index). Run one stage per call where the
# machine is lent for a limited time. The default model (lab-lag) is measured.
# Results go to benchmarks/results/*_gpu.json (RESULTS=DIR to put them elsewhere).
set -euo pipefail
cd "$(dirname "$0")/.."
R=${RESULTS:-benchmarks/results}
mkdir -p "$R"
stage=${1:-all}
run() { [ "$stage" = all ] || [ "$stage" = "$1" ]; }
export PYTHONUNBUFFERED=1
if run tests; then
  # the warp backend's tests and MJX's precision setting, on the GPU
  python -m pytest -q -p no:cacheprovider tests/test_warp.py \
    "tests/test_engine.py::test_mjx_backend_runs_at_full_matmul_precision"
fi
if run throughput; then
  python benchmarks/engine.py --backends warp --model lab-lag --warp-batches 1024,4096,16384 \
    --warp-steps 2000 --out "$R/engine_gpu_warp.json"
fi
if run mjx; then
  python benchmarks/engine.py --backends mjx --model lab-lag --mjx-batches 1024,4096,16384 \
    --mjx-steps 200 --out "$R/engine_gpu_mjx.json"
fi
if run mjxwarp; then
  # MuJoCo Warp called directly against MJX's impl='warp' (and the copy of MuJoCo Warp that MJX carries)
  XLA_PYTHON_CLIENT_PREALLOCATE=false python benchmarks/mjx_warp_path.py --batches 1024,4096,16384 --out "$R/mjx_warp_path_gpu.json"
fi
if run agreement; then
  python benchmarks/backend_agreement.py --backends native,warp --model lab-lag --configs 200 --periods 20 \
    --out "$R/backend_agreement_gpu.json"
fi
if run agreement-mjx; then
  # apart: MJX on a GPU ran under 75k steps/s at 200 lanes (0.25 ms), too slow to share a stage with warp
  python benchmarks/backend_agreement.py --backends native,mjx --model lab-lag --configs 200 --periods 20 \
    --out "$R/backend_agreement_gpu_mjx.json"
fi
if run scan; then
  python benchmarks/full_scan.py --backend warp --batch-size "${BATCH:-8192}" --n 5000 --periods 75 \
    --out "$R/full_scan_gpu.json"
fi
