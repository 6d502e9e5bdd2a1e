#!/usr/bin/env bash
# The ablation table of issue 3: each seed-000 principle (and G2P2G, the fused rebuild) off in
# turn on the fluid and jelly claymore scenes, whole-run ms/step, through device_variants.sh.
# Binaries in $D (scripts/prepare_device.sh). Usage: D=.device OUT=$OUT bash bench/device_ablation.sh
set -uo pipefail
cd "$(dirname "$0")/.."
v=("default|rtmpm|")
for o in free_zone=off mixed_sort=off warp_reduce=off p2g=shared graph=off fast_math=off g2p2g=off rebuild=kernels; do
  v+=("$o|rtmpm||$o")
done
SCENES="fluid_dam_2m:10 jelly_drop_2m:5" REPS=1 bash bench/device_variants.sh "${v[@]}"
