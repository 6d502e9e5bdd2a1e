#!/usr/bin/env bash
# Session 14, call 4 (two H200s; binaries and wheel of main, see COMMIT: fused_defaults=auto the
# default, the batch's host-work changes, the mended reset tests). Phase 1, one lane a GPU:
# GPU 0 test_addressing (auto against off, bit for bit), test_batch_resets, test_state_layout;
# GPU 1 the CPU agreement on every example scene with the defaults, the Python GPU batch tests.
# Phase 2, GPU 0 alone: the Python GPU batch loop, new against old paths, alternating.
set -u
R=$OUT
[ -d .device ] && [ "$(cat .device/COMMIT)" = "$(tar xJOf .device-pack/d.tar.xz .device/COMMIT 2>/dev/null)" ] || tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache PYTHONUNBUFFERED=1 NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-470} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name --format=csv,noheader | tr '\n' ' '); nproc $(nproc)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
NG=$(nvidia-smi -L | wc -l); G1=$(( NG > 1 ? 1 : 0 ))
t() { local n=$1 cap=$2; shift 2; local l; l=$(left 330); [ $l -gt 30 ] || { echo "$n not run (time)" >> $R/sum_t.txt; return; }
  [ $l -lt $cap ] && cap=$l
  timeout $cap $D/$n --include-ignored "$@" > $R/$n.log 2>&1
  echo "$n rc=$?: $(grep -E '^test result' $R/$n.log | tail -1)" >> $R/sum_t.txt
  grep -E "FAILED|panicked|compiled in|Auto" $R/$n.log | cut -c1-200 | head -14 >> $R/sum_t.txt; el "$n"; }
( export CUDA_VISIBLE_DEVICES=0
  t test_addressing 260 --test-threads 1 --nocapture
  t test_batch_resets 150 --nocapture
  t test_state_layout 120 --test-threads 2 ) &
( export CUDA_VISIBLE_DEVICES=$G1 RAYON_NUM_THREADS=14
  t test_agreement 300 --test-threads 1 cuda_agrees_with_cpu_on_every_example_scene
  l=$(left 340); [ $l -gt 40 ] && { PYTHONPATH=/tmp/site_main timeout $l python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
  echo "pytest test_batch_gpu rc=$?: $(tail -1 $R/pytest.log)" >> $R/sum_t.txt; grep -E "^FAILED|^E  " $R/pytest.log | head -8 >> $R/sum_t.txt; el pytest; } ) &
wait; el "phase 1"
export CUDA_VISIBLE_DEVICES=0
BB="python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 2 --budget 12"
for v in "new_1:" "old_1:RTMPM_BATCH_RESET=old RTMPM_BATCH_REST=old" "new_2:" "old_2:RTMPM_BATCH_RESET=old RTMPM_BATCH_REST=old"; do
  n=${v%%:*}; e=${v#*:}; l=$(left 440); [ $l -gt 40 ] || break
  env $e PYTHONPATH=/tmp/site_main timeout $l $BB > $R/py_$n.txt 2>&1
  echo "$n rc=$? ($e)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop|device) " $R/py_$n.txt | head -11 | cut -c1-120 >> $R/sum_py.txt; el "$n"
done
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
