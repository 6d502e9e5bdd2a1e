#!/usr/bin/env bash
# The ablation table of issue 3: each seed-000 principle (and G2P2G) off in turn on the fluid
# and jelly claymore scenes, whole-run ms/step. Binaries in $D (scripts/prepare_device.sh).
# Usage: D=.device OUT=$OUT bash bench/device_ablation.sh
set -uo pipefail
D=${D:-.device}
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
S="$OUT/ablation.txt"
echo "$(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1); commit $(cat $D/COMMIT 2>/dev/null)" | tee -a "$S"
for sc in fluid_dam_2m:10 jelly_drop_2m:5; do
  scene=${sc%%:*}; frames=${sc##*:}
  for o in "" free_zone=off mixed_sort=off warp_reduce=off p2g=shared graph=off fast_math=off g2p2g=off rebuild=kernels; do
    r=$(timeout 150 "$D/rtmpm" bench --backend cuda --scene "bench/$scene.toml" --frames "$frames" ${o:+--cuda-options "$o"} 2>&1)
    echo "== $scene ${o:-default}" >> "$OUT/ablation.log"; echo "$r" >> "$OUT/ablation.log"
    ms=$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1 | tr -d '()' | cut -d' ' -f1)
    k=$(echo "$r" | grep -E '^\s+(rebuild|p2g|g2p|g2p2g) ' | awk '{printf "%s %s ", $1, $2}')
    printf '%-14s %-16s %8s ms/step | %s\n' "$scene" "${o:-default}" "$ms" "$k" | tee -a "$S"
  done
done
