#!/usr/bin/env bash
# One device call after a merge (binaries built on the CPU machine by scripts/prepare_device.sh,
# carried in $D): the GPU tests (agreement with the CPU backend, transfers, P2G strategies, f64),
# the validation suite at full resolution on the GPU, and a short benchmark of the claymore scenes.
# Logs in $OUT; a summary is printed last.
# Usage: D=.device OUT=$OUT bash bench/device_check.sh [tests|validate|bench|all|convergence|rebuild]
set -uo pipefail
export NCCL_NVLS_ENABLE=0
D=${D:-.device}
OUT=${OUT:-/tmp/out}
WHAT=${1:-all}
mkdir -p "$OUT"
S="$OUT/summary.txt"
: > "$S"
say() { echo "$*" | tee -a "$S"; }
say "$(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1); commit $(cat $D/COMMIT 2>/dev/null)"
# The test binaries find scenes through the path they were built in (/work/main).
mkdir -p /work && [ -e /work/main ] || ln -sfn "$PWD" /work/main
mkdir -p target/release && cp "$D/rtmpm" target/release/rtmpm

if [ "$WHAT" = all ] || [ "$WHAT" = tests ]; then
  for t in test_gpu test_agreement; do
    [ -x "$D/$t" ] || { say "$t missing"; continue; }
    timeout 300 "$D/$t" --include-ignored --test-threads 1 > "$OUT/$t.log" 2>&1
    say "$t rc=$?: $(grep -E '^test result' "$OUT/$t.log")"
    grep -E "FAILED|panicked" "$OUT/$t.log" | head -10 | tee -a "$S"
  done
fi

if [ "$WHAT" = all ] || [ "$WHAT" = validate ]; then
  timeout 300 $D/rtmpm validate --backend cuda --out "$OUT/validation" > "$OUT/validate_full.log" 2>&1
  say "validate --backend cuda (full) rc=$?"
  grep -E "PASS|FAIL|passed" "$OUT/validate_full.log" | sed -E 's/ +/ /g' | tee -a "$S"
fi

if [ "$WHAT" = convergence ]; then
  timeout 300 $D/rtmpm validate --backend cuda --convergence --case vibrating_bar,vibrating_bar_gimp,hydrostatic_column \
    --out "$OUT/convergence" > "$OUT/validate_convergence.log" 2>&1
  say "validate --backend cuda --convergence rc=$?"
  grep -E "PASS|FAIL|passed|order|error at" "$OUT/validate_convergence.log" | sed -E 's/ +/ /g' | tee -a "$S"
  timeout 300 $D/rtmpm validate --backend cuda --precision f64 \
    --case vibrating_bar,vibrating_bar_gimp,hydrostatic_column,hydrostatic_column_gimp,colliding_disks,dam_break \
    --out "$OUT/f64" > "$OUT/validate_f64.log" 2>&1
  say "validate --backend cuda --precision f64 rc=$?"
  grep -E "PASS|FAIL|passed" "$OUT/validate_f64.log" | sed -E 's/ +/ /g' | tee -a "$S"
fi

if [ "$WHAT" = rebuild ]; then
  # The fused rebuild (default) against the fifteen kernels, interleaved A B A B.
  r() { # label, args...
    local label=$1; shift
    local out; out=$(timeout 120 $D/rtmpm bench --backend cuda "$@" 2>&1)
    echo "== $label: $*" >> "$OUT/bench_rebuild.log"; echo "$out" >> "$OUT/bench_rebuild.log"
    say "$label | $(echo "$out" | grep -E 'wall time|rebuild  |^error' | sed -E 's/ +/ /g' | tr '\n' '|')"
  }
  for rep in 1 2; do
    for o in rebuild=fused rebuild=kernels; do
      r "fluid_dam_2m $o #$rep" --scene bench/fluid_dam_2m.toml --frames 10 --cuda-options $o
      r "jelly_drop_2m $o #$rep" --scene bench/jelly_drop_2m.toml --frames 5 --cuda-options $o
      r "snow_1m $o #$rep" --scene bench/snow_1m.toml --frames 10 --cuda-options $o
    done
  done
  r "fluid n=128 rebuild=fused" --n 128 --steps 300 --cuda-options rebuild=fused
  r "fluid n=128 rebuild=kernels" --n 128 --steps 300 --cuda-options rebuild=kernels
  timeout 200 $D/rtmpm validate --backend cuda --case dam_break,granular_column,colliding_disks \
    --out "$OUT/validation" > "$OUT/validate_rebuild.log" 2>&1
  say "validate dam_break,granular_column,colliding_disks (fused rebuild) rc=$?: $(grep -E 'passed' "$OUT/validate_rebuild.log")"
fi

if [ "$WHAT" = all ] || [ "$WHAT" = bench ]; then
  b() { # label, args...
    local label=$1; shift
    local r; r=$(timeout 120 $D/rtmpm bench --backend cuda "$@" 2>&1)
    echo "== $label: $*" >> "$OUT/bench.log"; echo "$r" >> "$OUT/bench.log"
    say "$label | $(echo "$r" | grep -E 'wall time|throughput|^error' | sed -E 's/ +/ /g' | tr '\n' '|')"
  }
  b "fluid_dam_2m" --scene bench/fluid_dam_2m.toml --frames 10
  b "jelly_drop_2m" --scene bench/jelly_drop_2m.toml --frames 5
  b "snow_1m" --scene bench/snow_1m.toml --frames 10
  b "fluid n=128 f64" --n 128 --steps 300 --precision f64
  b "fluid n=128 p2g=reverse_map" --n 128 --steps 300 --cuda-options p2g=reverse_map
fi
echo "==== summary"; cat "$S"
