#!/usr/bin/env bash
# Session 8, call 3 (binaries and wheel of main 99898f5): batches on the GPU (tests/batch.rs, incl.
# the resumed GPU batch; the Python BatchSimulation on CUDA: test_batch_gpu.py, test_batch.py,
# test_gpu.py), then CK-MPM's fused G2P2G (ck_p2g=fused): agreement with the CPU and ms/step
# against the warp-reduced unfused kernels and MLS-MPM.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p $R/batch
timeout 130 $D/test_batch --include-ignored --test-threads 1 --nocapture --skip batch_benchmark > $R/batch/test_batch.log 2>&1
echo "test_batch rc=$?: $(grep -E '^test result' $R/batch/test_batch.log | tail -1)" > $R/batch/summary.txt
grep -E "^test |FAILED|panicked|^resumed|^world|^lockstep" $R/batch/test_batch.log | head -40 >> $R/batch/summary.txt; el batch
SITE=$(mktemp -d)
python3 -m pip install --quiet --no-index --no-deps --target "$SITE" .device/wheels/rtmpm-*.whl > $R/batch/pip.log 2>&1
export RTMPM_CLI=$PWD/.device/rtmpm
PYTHONPATH=$SITE timeout 150 python3 -m pytest -v -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py \
  crates/rtmpm-py/tests/test_batch.py crates/rtmpm-py/tests/test_gpu.py > $R/batch/pytest.log 2>&1
echo "pytest rc=$?" >> $R/batch/summary.txt
grep -E "PASSED|FAILED|SKIPPED|ERROR|passed|failed" $R/batch/pytest.log | tail -45 >> $R/batch/summary.txt; el python
left=$(( 585 - ($(date +%s) - T0) ))
OUT=$R/ck CK_AGREEMENT="ck_p2g=fused" CK_VARIANTS="ck_p2g=warp ck_p2g=fused" TEST_TIMEOUT=$(( left - 45 )) \
  timeout $left bash scripts/gpu/run.sh ck_speed > /dev/null 2>&1; el ck_speed
{
echo "==== batch"; cat $R/batch/summary.txt
echo "==== ck"; grep -vE "^(NVIDIA|== )" $R/ck/summary.txt 2>/dev/null | grep -vE "^\s*$" | tail -40
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.ply' --exclude='*.vtu' --exclude='*.vtk' --exclude='*.bin' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
