#!/usr/bin/env bash
# Issue 6 (parts 2 and 4) on the device: the GPU tests, then the P2G strategies (scatter with warp
# reduction, shared-memory scatter, seed 001's reverse map and sort-based gathers) on the fluid
# block at three sizes, the replicated-map ablation, and constant memory on/off. Binaries built on
# the CPU machine (scripts/prepare_device.sh) and carried in $D; scenes from bench/.
set -uo pipefail
export NCCL_NVLS_ENABLE=0
D=${D:-.device}
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv,noheader | tee "$OUT/device.txt"
if [ "${SKIP_TESTS:-0}" != 1 ]; then
  echo "== gpu tests"
  timeout 150 $D/test_gpu --include-ignored --nocapture > "$OUT/gpu_tests.log" 2>&1
  echo "rc=$?"; grep -E "^test |test result|largest node|rebuilds, max|Err|panicked|capacity" "$OUT/gpu_tests.log" | cut -c1-400
  echo "== agreement (CPU vs CUDA, ${STEPS:-60} steps)"
  RTMPM_AGREEMENT_STEPS=${STEPS:-60} timeout 120 $D/test_agreement --include-ignored --nocapture > "$OUT/agreement.log" 2>&1
  echo "rc=$?"; tail -4 "$OUT/agreement.log"
fi
# label, args... : one line per run (ms/step whole run, evented P2G and its phases, extra memory).
b() {
  local label=$1; shift
  local r; r=$(timeout 150 $D/rtmpm bench --backend cuda "$@" 2>&1)
  echo "== $label: $*" >> "$OUT/bench_full.log"; echo "$r" >> "$OUT/bench_full.log"
  local ms; ms=$(echo "$r" | grep -m1 "wall time" | sed -E 's/.*\(([0-9.]+) ms\/step\).*/\1/')
  local k; k=$(echo "$r" | grep -E "^    (p2g|step) |^      p2g\." | awk '{printf "%s=%s ", $1, $2}')
  local mem; mem=$(echo "$r" | grep -m1 "p2g memory" | sed -E 's/.*: ([0-9.]+ MB extra).*grid ([0-9.]+ MB)/\1, grid \2/')
  local err; err=$(echo "$r" | grep -m1 -iE "^error|blew" || true)
  printf "%-28s %9s ms/step | %s| %s %s\n" "$label" "$ms" "$k" "$mem" "$err"
}
echo "== strategies (fluid block)"
for n in 64 128 256; do
  steps=300; [ $n = 256 ] && steps=150
  for p in warp shared reverse_map sort; do
    b "n=$n p2g=$p" --n $n --steps $steps --cuda-options p2g=$p
  done
done
echo "== replicated maps (paper: nine)"
b "n=128 reverse_map replicas=1" --n 128 --steps 300 --cuda-options p2g=reverse_map,rmap_replicas=1
echo "== constant memory on (default) / off (-DRTMPM_PARAMS_GLOBAL), alternating"
for rep in 1 2; do
  for s in fluid_dam_2m:3 jelly_drop_2m:3; do
    b "${s%%:*} const" --scene bench/${s%%:*}.toml --frames ${s##*:}
    export RTMPM_KERNEL_DEFINES=-DRTMPM_PARAMS_GLOBAL
    b "${s%%:*} global" --scene bench/${s%%:*}.toml --frames ${s##*:}
    unset RTMPM_KERNEL_DEFINES
  done
done
