#!/usr/bin/env bash
# Final check of main, call 1: correctness in parallel (every GPU test, batch tests, validation,
# memcheck, Python view/render_gpu, and test_agreement with the faster occupancy variant), then
# the A/B of that variant against the defaults.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
printf '#!/bin/sh\nRTMPM_G2P2G_GRID=resident exec "$(dirname "$0")/rtmpm" "$@"\n' > $D/rtmpm_res; chmod +x $D/rtmpm_res
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
for g in "test_agreement" "test_gpu" "test_fill test_emitters test_materials" "test_rigid test_render test_steer test_cli test_render_cli" "test_batch"; do
  n=${g%% *}
  OUT=$R/t_$n TEST_TIMEOUT=280 TESTS="$g" bash scripts/gpu/run.sh tests > /dev/null 2>&1 &
done
( export RTMPM_G2P2G_GRID=resident RTMPM_KERNEL_DEFINES="-DG2P2G_MIN_BLOCKS=5 -DG2P2G_FLUID_MIN_BLOCKS=5"
  OUT=$R/tv_agreement TEST_TIMEOUT=280 TESTS="test_agreement" bash scripts/gpu/run.sh tests > /dev/null 2>&1 ) &
OUT=$R/val timeout 290 bash scripts/gpu/run.sh validate > /dev/null 2>&1 &
OUT=$R/san SANITIZE_TOOLS=memcheck timeout 200 bash scripts/gpu/run.sh sanitize > /dev/null 2>&1 &
wait; el correctness
V="base|rtmpm|| res_mb5|rtmpm_res|-DG2P2G_MIN_BLOCKS=5,-DG2P2G_FLUID_MIN_BLOCKS=5 res_mb5_stream|rtmpm_res|-DG2P2G_MIN_BLOCKS=5,-DG2P2G_FLUID_MIN_BLOCKS=5,-DRTMPM_STATE_STREAM=1"
OUT=$R/var REPS=1 VARIANTS="$V" timeout 150 bash scripts/gpu/run.sh variants > /dev/null 2>&1; el variants
{
for d in $R/t_* $R/tv_* $R/val $R/san $R/var; do [ -d $d ] || continue; echo "==== $(basename $d)"; grep -vE "^(NVIDIA|== )" $d/summary.txt 2>/dev/null | grep -vE "^\s*$" | tail -40; done
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.png' --exclude='*.vtu' --exclude='*.vtk' --exclude='*.ply' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
