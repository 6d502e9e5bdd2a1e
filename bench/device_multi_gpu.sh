#!/usr/bin/env bash
# Multi-GPU runs of issue 7 on a machine of 2+ GPUs (binaries built on the CPU machine, carried in
# $D): device facts, the multi-GPU tests (--gpus 2 and two processes vs one GPU on every example
# scene), every example scene on --gpus 2, a two-process run through a file rendezvous, and the
# strong/weak scaling benchmarks. Logs in $OUT; a summary is printed last.
# Usage: D=.device OUT=/tmp/out bash bench/device_multi_gpu.sh [tests|bench|all]
# (scripts/prepare_device.sh stages the binaries in .device)
set -uo pipefail
export NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1
D=${D:-.device}
OUT=${OUT:-/tmp/out}
WHAT=${1:-all}
mkdir -p "$OUT"
S="$OUT/summary.txt"
: > "$S"
say() { echo "$*" | tee -a "$S"; }
NGPU=$(nvidia-smi -L | wc -l)
# NCCL: PyTorch's wheel carries it.
if [ -z "${RTMPM_NCCL_LIB:-}" ]; then
  RTMPM_NCCL_LIB=$(find / -name 'libnccl.so.2*' -not -path '/proc/*' 2>/dev/null | head -1)
  export RTMPM_NCCL_LIB
fi
{ nvidia-smi -L; nvidia-smi topo -m; echo "NCCL: $RTMPM_NCCL_LIB"; $D/rtmpm info; } > "$OUT/device.txt" 2>&1
say "gpus $NGPU; $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1); NCCL $RTMPM_NCCL_LIB"
# The test binaries look for /work/main (where they were built): point it at this tree.
mkdir -p /work && [ -e /work/main ] || ln -sfn "$PWD" /work/main
mkdir -p target/release target/tmp && cp "$D/rtmpm" target/release/rtmpm

if [ "$WHAT" != bench ]; then
  RTMPM_MULTI_GPU_COUNTS=2,4 RTMPM_MULTI_GPU_STEPS=300 timeout 120 $D/test_multi_gpu --include-ignored --nocapture \
    > "$OUT/test_multi_gpu.log" 2>&1; say "test_multi_gpu rc=$?: $(grep -E '^test result' "$OUT/test_multi_gpu.log")"
  grep -E "steps:|1 step:|error|panicked" "$OUT/test_multi_gpu.log" | head -30 | tee -a "$S"
  timeout 150 $D/test_multi_gpu_cli --include-ignored --nocapture > "$OUT/test_cli.log" 2>&1
  say "test_multi_gpu_cli rc=$?: $(grep -E '^test result' "$OUT/test_cli.log")"
  grep -E "d com|panicked|error" "$OUT/test_cli.log" | head -30 | tee -a "$S"
  if grep -q capture "$OUT/test_multi_gpu.log" "$OUT/test_cli.log"; then
    RTMPM_MULTI_GPU_OPTIONS=graph=off RTMPM_MULTI_GPU_COUNTS=2 timeout 200 $D/test_multi_gpu --include-ignored --nocapture \
      > "$OUT/test_multi_gpu_nograph.log" 2>&1; say "graph=off: test_multi_gpu rc=$?"
    RTMPM_MULTI_GPU_OPTIONS=graph=off timeout 240 $D/test_multi_gpu_cli --include-ignored --nocapture \
      > "$OUT/test_cli_nograph.log" 2>&1; say "graph=off: test_multi_gpu_cli rc=$?"
    grep -hE "steps:|d com|panicked" "$OUT/test_multi_gpu_nograph.log" "$OUT/test_cli_nograph.log" | head -40 | tee -a "$S"
  fi
  for s in dam_break sand_column elastic_cubes snowball mixed bench_fluid_n64; do
    r=$(timeout 45 $D/rtmpm run scenes/$s.toml --gpus 2 --no-output 2>&1); rc=$?
    echo "$r" >> "$OUT/scenes.log"
    say "scene $s --gpus 2 rc=$rc: $(echo "$r" | grep -E 'steps  |wall time|^error' | tr -s ' ' | tr '\n' ' ')"
  done
  rm -f /tmp/rtmpm-rdv
  for r in 0 1; do
    timeout 45 $D/rtmpm run scenes/dam_break.toml --rendezvous file:/tmp/rtmpm-rdv --nccl-ranks 2 --nccl-rank $r \
      --out /tmp/ranks_out > "$OUT/ranks_$r.log" 2>&1 &
  done
  wait
  say "2 processes (file rendezvous) dam_break: $(grep -E 'wall time|^error' "$OUT/ranks_0.log" "$OUT/ranks_1.log" | tr -s ' ' | tr '\n' ' ') frames: $(ls /tmp/ranks_out | grep -c ply)"
fi

if [ "$WHAT" != tests ]; then
  b() { # label, timeout, args...
    local label=$1 t=$2; shift 2
    local r; r=$(timeout "$t" $D/rtmpm bench "$@" 2>&1); local rc=$?
    echo "== $label: $*" >> "$OUT/bench.log"; echo "$r" >> "$OUT/bench.log"
    say "$label rc=$rc | $(echo "$r" | grep -E 'wall time|reduction|particles  |^error' | sed -E 's/ +/ /g' | tr '\n' '|')"
  }
  b "strong 16M x1" 200 --backend cuda --scene bench/strong_16m.toml --frames 2
  b "strong 16M x2" 200 --scene bench/strong_16m.toml --frames 2 --gpus 2
  b "weak 4M x1" 150 --backend cuda --scene bench/weak_4m_x1.toml --frames 2
  b "weak 4M x2" 150 --scene bench/weak_4m_x2.toml --frames 2 --gpus 2
  b "strong 16M x2 graph=off" 200 --scene bench/strong_16m.toml --frames 2 --gpus 2 --cuda-options graph=off
  b "strong 16M x2 overlap=off" 200 --scene bench/strong_16m.toml --frames 2 --gpus 2 --cuda-options overlap=off
  b "weak 4M x2 graph=off" 150 --scene bench/weak_4m_x2.toml --frames 2 --gpus 2 --cuda-options graph=off
  b "weak 4M x2 overlap=off" 150 --scene bench/weak_4m_x2.toml --frames 2 --gpus 2 --cuda-options overlap=off
  if [ "$NGPU" -ge 4 ]; then
    b "strong 16M x4" 200 --scene bench/strong_16m.toml --frames 2 --gpus 4
    b "weak 4M x4" 200 --scene bench/weak_4m_x4.toml --frames 2 --gpus 4
  fi
fi
echo "==== summary"; cat "$S"
