#!/usr/bin/env bash
# Session 16, call 4 (two H200s; the binaries of call 3, e10df8d): the GPU tests call 3 ran out of
# its phase's time for (each its own lane, longer limits, a cold kernel cache as there).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache PYTHONUNBUFFERED=1 NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name --format=csv,noheader | tr '\n' ' '); nproc $(nproc)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
t() { local n=$1 cap=$2; shift 2; local l=$(( 300 - ($(date +%s) - T0) )); [ $l -lt $cap ] && cap=$l
  [ $cap -gt 15 ] || { echo "$n not run (time)" >> $R/sum_t.txt; return; }
  local s=$(date +%s); timeout $cap $D/$n --include-ignored "$@" > $R/$n.log 2>&1
  echo "$n rc=$? ($(( $(date +%s) - s )) s): $(grep -E '^test result' $R/$n.log | tail -1)" >> $R/sum_t.txt
  grep -E "FAILED|panicked|running for over" $R/$n.log | cut -c1-200 | head -10 >> $R/sum_t.txt; el "$n"; }
( export CUDA_VISIBLE_DEVICES=0 RAYON_NUM_THREADS=10; t test_batch_resets 290 ) &
( export CUDA_VISIBLE_DEVICES=1 RAYON_NUM_THREADS=10; t test_batch_put_slots 150; t test_rigid 150 ) &
( export CUDA_VISIBLE_DEVICES=0 RAYON_NUM_THREADS=10 RTMPM_CACHE_DIR=/tmp/kcache2; t test_agreement 290 --test-threads 1 cuda_agrees_with_cpu_on_every_example_scene ) &
wait
{ head -1 $R/times.txt; cat $R/sum_t.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
