#!/usr/bin/env bash
# The GPU figures of #42 (MJX's throughput curve beside MuJoCo Warp's, and the
# paper scan on Warp at the default step) on a lent GPU machine that reaches no
# package index, in two consecutive calls on the same warm machine:
#
#   bash benchmarks/gpu_lease.sh 1   # install the carried wheels, time MJX (1k-16k worlds)
#   bash benchmarks/gpu_lease.sh 2   # finish Warp's library, time Warp, run the 5000 x 75 scan
#   bash benchmarks/gpu_lease.sh merge DIR OUT.json   # here: the three JSONs of DIR into one
#
# Why Warp flags lanes the native backend does not (benchmarks/warp_flags.py), in
# two or three calls on the same warm machine:
#
#   bash benchmarks/gpu_lease.sh install  # install the carried wheels only
#   bash benchmarks/gpu_lease.sh flags    # finish Warp, the 5000 x 75 scan on Warp with its store kept
#                                         # (the one of 27 November 2026, its flagged lanes and 108 controls: results/warp_scan_h200_flagged_lanes.json)
#   bash benchmarks/gpu_lease.sh flags2   # (after install and the second wheel half; STORE=... or that
#                                         # store) its flagged lanes and as many controls, box pairs through
#                                         # the analytic collider (MuJoCo C's); a call of its own (run 28 November
#                                         # 2026: none flagged, results/warp_flags_analytic_box_h200.json)
#   bash benchmarks/gpu_lease.sh flags2convex  # the same lanes again through GJK/EPA (run 27 November 2026:
#                                         # results/warp_flags_convex_again_h200.json)
#   bash benchmarks/gpu_lease.sh flags3   # GJK/EPA in deterministic mode, and at half the step (not yet run)
#
# Since 0.4.2 the warp backend collides box pairs analytically, as MuJoCo C does (the flags above were
# GJK/EPA's phantoms). The paper scan at the default, its store kept, after `install`:
#
#   bash benchmarks/gpu_lease.sh scan     # (28 November 2026: results/full_scan_gpu_analytic_h200.json)
#   bash benchmarks/gpu_lease.sh mjxwarp  # MJX's impl='warp' against the direct call (4096 and 16384 worlds)
#   bash benchmarks/gpu_lease.sh analytic # Warp's throughput curve and its labels against native's (600 x 20;
#                                         # 28 November 2026: results/*_analytic_h200.json)
#
# Here, on a machine with pip, once: the two carried folders (about 51 and 54 MB; the repository itself
# travels beside each, so each call stays under the 64 MiB a call may carry):
#
#   bash benchmarks/gpu_lease.sh prepare
# What travels (ignored folders, prepared on a machine with pip):
#   .whl1/  mujoco 4.0.0 (+ mujoco-core), mujoco-mjx 3.17.0, mujoco-warp 4.0.0,
#           glfw, PyOpenGL, trimesh wheels; warp_py.tar.xz (warp-lang 1.19.0's
#           Python files, without its two shared libraries and examples);
#           warpso.part1 (the first bytes of warp/bin/warp.so, xz-compressed)
#   .whl2/  warpso.part2 (the rest)
# warp-clang.so (Warp's CPU compiler, 69 MB) is left behind: Warp loads it only
# if present and needs it only for its CPU device. JAX is the machine's own
# (its version goes into the JSON). Results go to $OUT (or RESULTS).
set -euo pipefail
cd "$(dirname "$0")/.."
R=${OUT:-${RESULTS:-benchmarks/results}}
SITE=/tmp/site
export PYTHONUNBUFFERED=1 PYTHONPATH=$SITE:$PWD JAX_COMPILATION_CACHE_DIR=/tmp/jaxcache
install_wheels() {
  mkdir -p /tmp/keep "$SITE"
  cp .whl1/warpso.part1 /tmp/keep/
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target "$SITE" .whl1/*.whl
  tar -xJf .whl1/warp_py.tar.xz -C "$SITE"
  nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv | tee "$R/gpu_lease_smi.txt"
}
finish_warp() {
  [ -s "$SITE/warp/bin/warp.so" ] || cat /tmp/keep/warpso.part1 .whl2/warpso.part2 \
    | python3 -c "import lzma, sys; sys.stdout.buffer.write(lzma.decompress(sys.stdin.buffer.read()))" \
    > "$SITE/warp/bin/warp.so"
  python3 -c "import warp; warp.init(); print('warp', warp.__version__, warp.get_cuda_device())"
}
case "${1:-}" in
prepare)
  W=$(mktemp -d)
  grep -qx '/.whl1/' .git/info/exclude 2>/dev/null || printf '/.whl1/\n/.whl2/\n' >> .git/info/exclude
  for p in mujoco==4.0.0 mujoco-core==4.0.0 mujoco-mjx==3.17.0 mujoco-warp==4.0.0 glfw==2.11.0 \
           PyOpenGL==3.1.10 trimesh==5.2.0 warp-lang==1.19.0; do
    python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
      --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
      --platform manylinux2014_x86_64 --platform any -d "$W" "$p"
  done
  (cd "$W" && mkdir wx && cd wx && unzip -q ../warp_lang-*.whl && xz -9e -T2 -c warp/bin/warp.so > ../warpso.xz &&
   tar --exclude=warp/bin/warp.so --exclude=warp/bin/warp-clang.so --exclude=warp/examples \
     -cJf ../warp_py.tar.xz warp warp_lang-*.dist-info)
  rm -rf .whl1 .whl2 && mkdir -p .whl1 .whl2
  cp "$W"/*.whl .whl1/ && rm .whl1/warp_lang-*.whl && cp "$W/warp_py.tar.xz" .whl1/
  total=$(stat -c %s "$W/warpso.xz"); second=53500000  # the repository (about 12 MB) travels beside it
  head -c $((total - second)) "$W/warpso.xz" > .whl1/warpso.part1
  tail -c $second "$W/warpso.xz" > .whl2/warpso.part2
  rm -rf "$W"; du -sb .whl1 .whl2
  ;;
scan)
  finish_warp
  timeout "${SCAN_LIMIT:-380}" python3 benchmarks/full_scan.py --backend warp --batch-size 8192 \
    --n 5000 --periods 75 --store /tmp/keep/scan.h5 --out "$R/full_scan_gpu_analytic.json" || true
  cp /tmp/keep/scan.h5 "$R/warp_scan_analytic.h5" || true
  ;;
analytic)
  # after install: Warp's throughput curve and its label agreement with the native backend with 0.4.2's
  # analytic box pairs (both were measured with GJK/EPA before)
  finish_warp
  python3 benchmarks/engine.py --backends warp --model lab-lag --warp-batches 1024,4096,16384 \
    --warp-steps 2000 --out "$R/engine_gpu_warp_analytic.json"
  timeout "${AGREE_LIMIT:-330}" python3 benchmarks/backend_agreement.py --backends native,warp --model lab-lag \
    --configs ${AGREE_CONFIGS:-600} --periods 20 --out "$R/backend_agreement_gpu_analytic.json" || true
  ;;
mjxwarp)
  # after install: MuJoCo Warp called directly against MJX's impl='warp' (and the copy MJX carries)
  finish_warp
  XLA_PYTHON_CLIENT_PREALLOCATE=false timeout "${MJXWARP_LIMIT:-420}" python3 benchmarks/mjx_warp_path.py \
    --batches ${MJXWARP_BATCHES:-4096,16384} --out "$R/mjx_warp_path_gpu.json" || true
  ;;
install)
  install_wheels
  python3 -c "import jax, mujoco; print('jax', jax.__version__, jax.devices(), 'mujoco', mujoco.__version__)"
  ;;
flags)
  finish_warp
  mkdir -p /tmp/keep/scan
  timeout "${SCAN_LIMIT:-450}" python3 benchmarks/full_scan.py --backend warp --batch-size 8192 \
    --n 5000 --periods 75 --store /tmp/keep/scan/warp_scan.h5 --out "$R/full_scan_gpu_flags.json"
  cp /tmp/keep/scan/warp_scan.h5 "$R/"
  ;;
flags2)
  finish_warp
  S=${STORE:-benchmarks/results/warp_scan_h200_flagged_lanes.json}
  # all flagged lanes and as many unflagged controls, as one batch, through the analytic box-box
  # collider: about 4.5 min of lanes after a kernel build of about 2 min (an empty kernel cache), so it
  # takes a call of its own (27 November 2026: run beside the convex rerun in one call, it was cut at
  # 280 s and wrote nothing; the convex rerun alone took 263 s, results/warp_flags_convex_again_h200.json)
  timeout "${FLAG_LIMIT:-540}" python3 benchmarks/warp_flags.py --store $S --backend warp --analytic-box \
    --controls 108 --batch-size 256 --out "$R/warp_flags_analytic_box.json" || true
  ;;
flags2convex)
  finish_warp
  S=${STORE:-benchmarks/results/warp_scan_h200_flagged_lanes.json}
  timeout "${FLAG_LIMIT:-540}" python3 benchmarks/warp_flags.py --store $S --backend warp --box-collider convex \
    --controls 108 --batch-size 256 --out "$R/warp_flags_convex_again.json" || true
  ;;
flags3)
  finish_warp
  S=${STORE:-benchmarks/results/warp_scan_h200_flagged_lanes.json}
  timeout "${RERUN_LIMIT:-150}" python3 benchmarks/warp_flags.py --store $S --backend warp --box-collider convex --deterministic \
    --out "$R/warp_flags_deterministic.json" || true
  timeout "${RERUN_LIMIT:-150}" python3 benchmarks/warp_flags.py --store $S --backend warp --box-collider convex --timestep 0.000125 \
    --out "$R/warp_flags_half_step.json" || true
  ;;
1)
  install_wheels
  python3 -c "import jax, mujoco, mujoco.mjx; print('jax', jax.__version__, jax.devices(), 'mujoco', mujoco.__version__)"
  timeout "${MJX_LIMIT:-330}" python3 benchmarks/engine.py --backends mjx --model lab-lag \
    --mjx-batches 1024,4096,16384 --mjx-steps 200 --out "$R/engine_gpu_mjx.json"
  ;;
2)
  finish_warp
  python3 benchmarks/engine.py --backends warp --model lab-lag --warp-batches 1024,4096,16384 \
    --warp-steps 2000 --out "$R/engine_gpu_warp.json"
  timeout "${SCAN_LIMIT:-420}" python3 benchmarks/full_scan.py --backend warp --batch-size 8192 \
    --n 5000 --periods 75 --out "$R/full_scan_gpu.json"
  ;;
merge)
  python3 - "$2" "$3" <<'PY'
import json, pathlib, sys
d = pathlib.Path(sys.argv[1])
mjx = json.loads((d / "engine_gpu_mjx.json").read_text())
warp = json.loads((d / "engine_gpu_warp.json").read_text())
scan = json.loads((d / "full_scan_gpu.json").read_text())
devices = {mjx["jax_device"], warp["warp_device"], scan["device"]}
if len(devices) != 1:
    sys.exit(f"the three runs name different devices: {sorted(devices)}")
rate = {(r["backend"], r["batch"]): r["steps_per_s"] for r in mjx["throughput"] + warp["throughput"]}
curve = [dict(batch=b, mjx_steps_per_s=rate[("mjx", b)], warp_steps_per_s=rate[("warp", b)],
              warp_over_mjx=rate[("warp", b)] / rate[("mjx", b)])
         for b in sorted({b for _, b in rate}) if ("mjx", b) in rate and ("warp", b) in rate]
out = dict(device=devices.pop(), timestep=scan["timestep_s"], integrator=scan["integrator"],
           model=scan["model"], versions=warp["versions"],
           how="bash benchmarks/gpu_lease.sh 1, then 2, on the same warm machine",
           curve=curve,
           paper_scan=dict(n=scan["n"], periods=scan["periods"], wall_s=scan["wall_s"],
                           steps_per_s=scan["steps_per_s"], peak_rss_mib=scan["peak_rss_mib"],
                           bound_end_fraction=scan["bound_end_fraction"]),
           runs=dict(mjx=mjx, warp=warp, scan=scan))
pathlib.Path(sys.argv[2]).write_text(json.dumps(out, indent=2) + "\n")
for c in curve:
    print(f"{c['batch']:>6} worlds: mjx {c['mjx_steps_per_s']:>10,.0f}  warp {c['warp_steps_per_s']:>10,.0f}"
          f"  warp/mjx {c['warp_over_mjx']:.1f}")
print(f"paper scan on warp: {scan['wall_s']:.0f} s, {out['device']}, dt {scan['timestep_s']} s")
PY
  ;;
*)
  echo "usage: bash benchmarks/gpu_lease.sh 1|2|merge DIR OUT.json" >&2
  exit 2
  ;;
esac
