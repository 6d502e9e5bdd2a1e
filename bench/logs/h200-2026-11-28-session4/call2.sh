#!/usr/bin/env bash
# Final check of main, call 2: the agreement test again (a batch file among the example scenes is now
# left to tests/batch.rs), with the defaults and with the occupancy variant, and the Python package's
# GPU tests in parallel; then read_particles and the live view one at a time.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT) + the agreement test's scene filter"
OUT=$R/t_agreement TEST_TIMEOUT=260 TESTS="test_agreement" bash scripts/gpu/run.sh tests > /dev/null 2>&1 &
( export RTMPM_G2P2G_GRID=resident RTMPM_KERNEL_DEFINES="-DG2P2G_MIN_BLOCKS=5 -DG2P2G_FLUID_MIN_BLOCKS=5"
  OUT=$R/tv_agreement TEST_TIMEOUT=260 TESTS="test_agreement" bash scripts/gpu/run.sh tests > /dev/null 2>&1 ) &
OUT=$R/py PY_K="view or render_gpu or setter or C_and_F or nan or batch" timeout 260 bash scripts/gpu/run.sh python > /dev/null 2>&1 &
wait; el correctness
OUT=$R/read timeout 80 bash scripts/gpu/run.sh read > /dev/null 2>&1; el read
OUT=$R/view STREAM_SECONDS=8 STREAM_MEMORY_SECONDS=20 timeout 150 bash scripts/gpu/run.sh view > /dev/null 2>&1; el view
{
for d in $R/t_* $R/tv_* $R/py $R/read $R/view; do [ -d $d ] || continue; echo "==== $(basename $d)"; grep -vE "^(NVIDIA|== )" $d/summary.txt 2>/dev/null | grep -vE "^\s*$" | tail -45; done
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.png' --exclude='*.vtu' --exclude='*.vtk' --exclude='*.ply' --exclude='*.whl' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
