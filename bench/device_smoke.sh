#!/usr/bin/env bash
# First GPU run: device facts, the GPU tests, the CPU/GPU agreement test, each example scene on
# CUDA, and the fluid-block benchmark. Binaries are built on the CPU machine and carried in .device/.
set -uo pipefail
export NCCL_NVLS_ENABLE=0
D=.device
OUT=${OUT:-/tmp/out}
mkdir -p "$OUT"
nvidia-smi --query-gpu=name,memory.total,driver_version,clocks.max.sm --format=csv | tee "$OUT/device.txt"
$D/rtmpm info 2>&1 | tee -a "$OUT/device.txt"
echo "== gpu tests"; $D/test_gpu --include-ignored --nocapture 2>&1 | tail -40 | tee "$OUT/gpu_tests.log"
echo "== unit tests"; $D/test_rtmpm_cuda --include-ignored 2>&1 | tail -5
echo "== agreement"; RTMPM_AGREEMENT_STEPS=${STEPS:-200} $D/test_agreement --include-ignored --nocapture 2>&1 | tail -30 | tee "$OUT/agreement.log"
for s in dam_break sand_column elastic_cubes snowball mixed; do
  echo "== scene $s"; timeout 120 $D/rtmpm run scenes/$s.toml --backend cuda --no-output 2>&1 | tail -9
done
echo "== bench"; timeout 120 $D/rtmpm bench --backend cuda --n 128 2>&1 | tail -14
