#!/usr/bin/env bash
# Issue 7, transport=p2p on a machine of 2 GPUs (binaries built elsewhere, carried in $D): the
# multi-GPU agreement test in its three modes (p2p+spin, p2p+events, nccl), the strong and weak
# scaling benchmarks for every transport x barrier x overlap, then the CLI test (--gpus 2 with the
# default transport, two processes with NCCL). Logs in $OUT; a summary is printed last.
# Usage: D=.device-p2p OUT=/tmp/out bash $D/device_p2p.sh [tests|bench|all]
# The test binaries look for the tree they were built in (/work/wt-p2p): point it at this one.
set -uo pipefail
export NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1
D=${D:-.device-p2p}
OUT=${OUT:-/tmp/out}
WHAT=${1:-all}
mkdir -p "$OUT"
S="$OUT/summary.txt"
: > "$S"
say() { echo "$*" | tee -a "$S"; }
T0=$(date +%s)
el() { echo "$(( $(date +%s) - T0 )) s"; }
if [ -z "${RTMPM_NCCL_LIB:-}" ]; then
  for c in /usr/lib/x86_64-linux-gnu/libnccl.so.2 /usr/local/lib/libnccl.so.2; do
    [ -e "$c" ] && RTMPM_NCCL_LIB=$c && break
  done
  [ -z "${RTMPM_NCCL_LIB:-}" ] && RTMPM_NCCL_LIB=$(find / -name 'libnccl.so.2*' -not -path '/proc/*' 2>/dev/null | head -1)
  export RTMPM_NCCL_LIB
fi
{ nvidia-smi -L; nvidia-smi topo -m; nvidia-smi topo -p2p rw; nvidia-smi topo -p2p a; echo "NCCL: $RTMPM_NCCL_LIB"; } > "$OUT/device.txt" 2>&1
say "$(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1) x$(nvidia-smi -L | wc -l); NCCL $RTMPM_NCCL_LIB"
mkdir -p /work && ln -sfn "$PWD" /work/wt-p2p
mkdir -p target/release target/tmp && cp "$D/rtmpm" target/release/rtmpm

if [ "$WHAT" != bench ]; then
  r=$(timeout 30 "$D/rtmpm" run scenes/dam_break.toml --gpus 2 --frames 2 --no-output 2>&1)
  say "default transport, dam_break --gpus 2 rc=$? ($(el)): $(echo "$r" | grep -E 'backend|wall time|^error' | tr -s ' ' | tr '\n' '|')"
  RTMPM_MULTI_GPU_COUNTS=2 RTMPM_MULTI_GPU_STEPS=300 timeout 150 "$D/test_multi_gpu" --include-ignored --nocapture \
    > "$OUT/test_multi_gpu.log" 2>&1
  say "test_multi_gpu rc=$? ($(el)): $(grep -E '^test result' "$OUT/test_multi_gpu.log")"
  grep -E "steps:|1 step:|error|panicked|skipped|runs of" "$OUT/test_multi_gpu.log" | head -60 | tee -a "$S"
fi

if [ "$WHAT" != tests ]; then
  b() { # label, timeout, args...
    local label=$1 t=$2; shift 2
    local r; r=$(timeout "$t" "$D/rtmpm" bench "$@" 2>&1); local rc=$?
    echo "== $label: $*" >> "$OUT/bench.log"; echo "$r" >> "$OUT/bench.log"
    say "$label rc=$rc ($(el)) | $(echo "$r" | grep -E 'backend|wall time|reduction|^error' | sed -E 's/\[CudaOptions.*\]//; s/ +/ /g' | tr '\n' '|')"
  }
  for sc in strong_16m weak_4m_x2; do
    for o in "transport=p2p,barrier=spin" "transport=p2p,barrier=events" "transport=nccl"; do
      for ov in on off; do
        b "$sc $o overlap=$ov" 35 --scene bench/$sc.toml --frames 2 --gpus 2 --cuda-options "$o,overlap=$ov"
      done
    done
  done
fi

if [ "$WHAT" = all ]; then
  RTMPM_MULTI_GPU_FRAMES=2 timeout 100 "$D/test_multi_gpu_cli" --include-ignored --nocapture > "$OUT/test_cli.log" 2>&1
  say "test_multi_gpu_cli rc=$? ($(el)): $(grep -E '^test result' "$OUT/test_cli.log")"
  grep -E "d com|panicked|error" "$OUT/test_cli.log" | head -30 | tee -a "$S"
fi
echo "==== summary ($(el))"; cat "$S"
