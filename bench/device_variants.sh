#!/usr/bin/env bash
# A/B screening of kernel variants on the claymore scenes, interleaved: binaries in $D named
# rtmpm (this tree) and rtmpm_base (the commit before), extra compile-time defines through
# RTMPM_KERNEL_DEFINES. Logs in $OUT; one summary line per run.
# Usage: D=.device OUT=$OUT bash bench/device_variants.sh "label|binary|defines[|cuda-options]" ...
set -uo pipefail
D=${D:-.device}
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
S="$OUT/variants.txt"
echo "$(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1); commit $(cat $D/COMMIT 2>/dev/null)" | tee -a "$S"
SCENES=${SCENES:-"fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20"}
REPS=${REPS:-1}
for rep in $(seq 1 "$REPS"); do
  for sc in $SCENES; do
    scene=${sc%%:*}; frames=${sc##*:}
    for v in "$@"; do
      IFS='|' read -r label bin defines opts <<< "$v"
      r=$(RTMPM_KERNEL_DEFINES="$defines" timeout 150 "$D/$bin" bench --backend cuda --scene "bench/$scene.toml" --frames "$frames" ${opts:+--cuda-options "$opts"} 2>&1)
      echo "== $label $scene ($bin, $defines) #$rep" >> "$OUT/variants.log"; echo "$r" >> "$OUT/variants.log"
      ms=$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1 | tr -d '()' | cut -d' ' -f1)
      k=$(echo "$r" | grep -E '^\s+(rebuild|p2g|g2p|g2p2g) ' | awk '{printf "%s %s ", $1, $2}')
      err=$(echo "$r" | grep -iE '^error' | head -1)
      printf '%-14s %-10s #%s %8s ms/step | %s %s\n' "$scene" "$label" "$rep" "$ms" "$k" "$err" | tee -a "$S"
    done
  done
done
