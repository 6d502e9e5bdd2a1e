#!/usr/bin/env bash
# Final check of main on one GPU: correctness in parallel, then the kernel defaults' A/B, then the view suite.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
for g in "test_agreement" "test_gpu" "test_fill test_emitters test_materials" "test_rigid test_render test_steer test_cli test_render_cli"; do
  n=${g%% *}
  OUT=$R/t_$n TEST_TIMEOUT=290 TESTS="$g" bash scripts/gpu/run.sh tests > /dev/null 2>&1 &
done
OUT=$R/val timeout 300 bash scripts/gpu/run.sh validate > /dev/null 2>&1 &
OUT=$R/san SANITIZE_TOOLS=memcheck timeout 200 bash scripts/gpu/run.sh sanitize > /dev/null 2>&1 &
wait; el correctness
OUT=$R/var REPS=1 VARIANTS="old|rtmpm|-DRTMPM_P2G_REDUCE=0,-DRTMPM_G2P_GATHER=0,-DRTMPM_P2G_NODES=0 new|rtmpm||" \
  timeout 110 bash scripts/gpu/run.sh variants > /dev/null 2>&1; el variants
OUT=$R/view STREAM_SECONDS=12 STREAM_MEMORY_SECONDS=45 timeout 200 bash scripts/gpu/run.sh view > /dev/null 2>&1; el view
{
for d in $R/t_* $R/val $R/san $R/var $R/view; do echo "==== $(basename $d)"; grep -vE "^(NVIDIA|== )" $d/summary.txt 2>/dev/null | grep -vE "^\s*$" | tail -60; done
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf logs.tgz --exclude='*.png' --exclude=report.txt --exclude=logs.tgz . 2>/dev/null)
cat $R/report.txt
