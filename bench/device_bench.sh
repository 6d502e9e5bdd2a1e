#!/usr/bin/env bash
# GPU benchmarks of issue 3 (run on the device machine with the binaries carried in .device/):
# the claymore comparison scenes, the snow scene, the fluid block, and the ablation table.
set -uo pipefail
export NCCL_NVLS_ENABLE=0
D=${D:-.device}
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
b() { # label, args...
  local label=$1; shift
  local r; r=$(timeout 300 $D/rtmpm bench --backend cuda "$@" 2>&1)
  echo "$r" >> "$OUT/bench_full.log"
  local ms tp
  ms=$(echo "$r" | grep -m1 "wall time" | sed -E 's/.*\(([0-9.]+) ms\/step\).*/\1/')
  tp=$(echo "$r" | grep -m1 "throughput" | sed -E 's/.*throughput +//; s/ \(.*//')
  local k; k=$(echo "$r" | grep -E "^    (rebuild|p2g|grid_update|g2p) " | awk '{printf "%s=%s ", $1, $2}')
  local bw; bw=$(echo "$r" | grep -m1 "bandwidth" | sed -E 's/.*= ([0-9]+ %).*/\1/')
  local err; err=$(echo "$r" | grep -m1 -E "^error" || true)
  printf "%-34s %9s ms/step  %-28s floor %-5s %s %s\n" "$label" "$ms" "$tp" "$bw" "$k" "$err"
}
nvidia-smi --query-gpu=name,clocks.max.sm,clocks.max.mem --format=csv,noheader
for s in fluid_dam_2m:10 fluid_dam_4m:5 jelly_drop_2m:5 snow_1m:10; do
  b "${s%%:*}" --scene bench/${s%%:*}.toml --frames ${s##*:}
done
for n in 64 128 256; do b "fluid block n=$n" --n $n --steps 1000; done
echo "== ablations"
for s in fluid_dam_2m:10 jelly_drop_2m:5; do
  for o in free_zone=off mixed_sort=off warp_reduce=off p2g=shared graph=off fast_math=off; do
    b "${s%%:*} $o" --scene bench/${s%%:*}.toml --frames ${s##*:} --cuda-options $o
  done
done
