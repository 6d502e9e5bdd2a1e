#!/usr/bin/env bash
# Session 7, call 1: every GPU correctness suite with the occupancy switch `mb5r` (resident G2P2G
# grid + -DG2P2G_MIN_BLOCKS=5 -DG2P2G_FLUID_MIN_BLOCKS=5), in parallel, beside a long view stream
# with pictures overlapped with the steps (RTMPM_VIEW_OVERLAP=1): host and GPU memory over 540 s.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
export RTMPM_G2P2G_GRID=resident RTMPM_KERNEL_DEFINES="-DG2P2G_MIN_BLOCKS=5 -DG2P2G_FLUID_MIN_BLOCKS=5"
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT), mb5r on"
( RTMPM_VIEW_OVERLAP=1 OUT=$R/soak VIEW_SOAK_SECONDS=540 VIEW_SOAK_EVERY=30 timeout 570 bash scripts/gpu/run.sh view-soak > /dev/null 2>&1; el soak ) &
for g in "test_agreement" "test_gpu" "test_fill test_emitters test_materials" "test_rigid test_render test_steer test_cli test_render_cli" "test_batch"; do
  n=${g%% *}
  ( OUT=$R/t_$n TEST_TIMEOUT=480 TESTS="$g" bash scripts/gpu/run.sh tests > /dev/null 2>&1; el "tests $g" ) &
done
( OUT=$R/val timeout 400 bash scripts/gpu/run.sh validate > /dev/null 2>&1; el validate ) &
( OUT=$R/san SANITIZE_TOOLS=memcheck timeout 300 bash scripts/gpu/run.sh sanitize > /dev/null 2>&1; el sanitize ) &
( OUT=$R/py timeout 480 bash scripts/gpu/run.sh python > /dev/null 2>&1; el python ) &
wait; el all
{
for d in $R/t_* $R/val $R/san $R/py $R/soak; do [ -d $d ] || continue; echo "==== $(basename $d)"; grep -vE "^(NVIDIA|== )" $d/summary.txt 2>/dev/null | grep -vE "^\s*$" | grep -vE " PASS$" | tail -40; grep -c " PASS$" $d/summary.txt 2>/dev/null | sed 's/^/PASS lines: /'; done
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.png' --exclude='*.vtu' --exclude='*.vtk' --exclude='*.ply' --exclude='*.whl' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
