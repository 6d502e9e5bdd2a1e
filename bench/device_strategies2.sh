#!/usr/bin/env bash
# Issue 6, second device run: the GPU tests again (slot-major entry layout), the gather strategies
# against the scatter at three sizes, the replicated-map ablation at two sizes, and the scatter of
# main (binary in $D/main/, before the p2g_particle.cuh refactor and constant memory) against this
# branch, alternating in one run.
set -uo pipefail
export NCCL_NVLS_ENABLE=0
D=${D:-.device}
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv,noheader | tee "$OUT/device.txt"
echo "== gpu tests"
timeout 150 $D/test_gpu --include-ignored --nocapture > "$OUT/gpu_tests.log" 2>&1
echo "rc=$?"; grep -E "^test |test result|largest node|panicked" "$OUT/gpu_tests.log" | cut -c1-300
# bin, label, args...
b() {
  local bin=$1 label=$2; shift 2
  local r; r=$(timeout 150 $bin bench --backend cuda "$@" 2>&1)
  echo "== $label: $*" >> "$OUT/bench_full.log"; echo "$r" >> "$OUT/bench_full.log"
  local ms; ms=$(echo "$r" | grep -m1 "wall time" | sed -E 's/.*\(([0-9.]+) ms\/step\).*/\1/')
  local k; k=$(echo "$r" | grep -E "^    (p2g|step) |^      p2g\." | awk '{printf "%s=%s ", $1, $2}')
  local mem; mem=$(echo "$r" | grep -m1 "p2g memory" | sed -E 's/.*: ([0-9.]+ MB extra).*grid ([0-9.]+ MB)/\1, grid \2/')
  local err; err=$(echo "$r" | grep -m1 -iE "^error|blew" || true)
  printf "%-30s %9s ms/step | %s| %s %s\n" "$label" "$ms" "$k" "$mem" "$err"
}
echo "== strategies (fluid block)"
for n in 64 128 256; do
  steps=300; [ $n = 256 ] && steps=150
  for p in warp reverse_map sort; do
    b $D/rtmpm "n=$n p2g=$p" --n $n --steps $steps --cuda-options p2g=$p
  done
done
echo "== replicated maps (paper: nine)"
for n in 128 256; do
  steps=300; [ $n = 256 ] && steps=150
  for r in 1 9; do b $D/rtmpm "n=$n reverse_map replicas=$r" --n $n --steps $steps --cuda-options p2g=reverse_map,rmap_replicas=$r; done
done
echo "== scatter: main vs this branch, alternating"
for rep in 1 2; do
  for s in fluid_dam_2m:3 jelly_drop_2m:3; do
    b $D/main/rtmpm "${s%%:*} main" --scene bench/${s%%:*}.toml --frames ${s##*:}
    b $D/rtmpm "${s%%:*} branch" --scene bench/${s%%:*}.toml --frames ${s##*:}
  done
  b $D/main/rtmpm "n=256 main" --n 256 --steps 300
  b $D/rtmpm "n=256 branch" --n 256 --steps 300
done
