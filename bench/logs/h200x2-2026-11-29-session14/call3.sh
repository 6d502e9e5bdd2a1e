#!/usr/bin/env bash
# Session 14, call 3 (binaries and wheel of main as call 2, see COMMIT): the batch's host work.
# Phase 1 (two lanes): GPU 0 the Rust batch tests (resets from the kept image, rigid, waits);
# GPU 1 the Python GPU batch tests. Phase 2, GPU 0 alone: the Python GPU batch loop, new paths
# against RTMPM_BATCH_RESET=old RTMPM_BATCH_REST=old in the same wheel, alternating, then a
# timing split run of each (RTMPM_RESET_TIMING, RTMPM_POSE_TIMING, RTMPM_STEP_TIMING).
set -u
R=$OUT
[ -d .device ] && [ "$(cat .device/COMMIT)" = "$(tar xJOf .device-pack/d.tar.xz .device/COMMIT 2>/dev/null)" ] || tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-470} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name --format=csv,noheader | tr '\n' ' '); nproc $(nproc)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
NG=$(nvidia-smi -L | wc -l); G1=$(( NG > 1 ? 1 : 0 ))
( export CUDA_VISIBLE_DEVICES=0
  timeout 200 $D/test_batch_resets --include-ignored --nocapture > $R/resets.log 2>&1
  echo "test_batch_resets rc=$?: $(grep -E '^test result' $R/resets.log)" >> $R/sum_t.txt; el resets
  for t in test_batch_rigid test_batch_waits; do [ $(left 300) -gt 30 ] || break
    timeout $(left 300) $D/$t --include-ignored --test-threads 2 > $R/$t.log 2>&1
    echo "$t rc=$?: $(grep -E '^test result' $R/$t.log)" >> $R/sum_t.txt; grep -E "FAILED|panicked" $R/$t.log | head -5 >> $R/sum_t.txt; el $t
  done ) &
( export CUDA_VISIBLE_DEVICES=$G1; [ $G1 = 0 ] && sleep 1
  PYTHONPATH=/tmp/site_main timeout 240 python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
  echo "pytest test_batch_gpu rc=$?: $(tail -1 $R/pytest.log)" >> $R/sum_t.txt; grep -E "FAILED|Error" $R/pytest.log | head -8 >> $R/sum_t.txt; el pytest ) &
wait; el "phase 1"
export CUDA_VISIBLE_DEVICES=0
BB="python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 2 --budget 16"
for v in "new_1:" "old_1:RTMPM_BATCH_RESET=old RTMPM_BATCH_REST=old" "new_2:" "old_2:RTMPM_BATCH_RESET=old RTMPM_BATCH_REST=old" "newov:--overlap" "oldov:RTMPM_BATCH_RESET=old RTMPM_BATCH_REST=old --overlap"; do
  n=${v%%:*}; e=${v#*:}; m=""; [[ $e == *--overlap ]] && { m=--overlap; e=${e% --overlap}; e=${e%--overlap}; }
  l=$(left); [ $l -gt 45 ] || break
  env $e PYTHONPATH=/tmp/site_main timeout $l $BB $m > $R/py_$n.txt 2>&1
  echo "$n rc=$? ($e $m)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop|device) " $R/py_$n.txt | head -11 | cut -c1-120 >> $R/sum_py.txt; el "$n"
done
for v in "tnew:" "told:RTMPM_BATCH_RESET=old RTMPM_BATCH_REST=old"; do
  n=${v%%:*}; e=${v#*:}; l=$(left); [ $l -gt 30 ] || break
  env $e RTMPM_RESET_TIMING=1 RTMPM_POSE_TIMING=1 RTMPM_STEP_TIMING=1 PYTHONPATH=/tmp/site_main timeout $l python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 10 --repeats 1 --budget 8 > $R/py_$n.txt 2>&1
  echo "$n rc=$?" >> $R/sum_tm.txt; grep -vE "^\[ *[0-9.]+ s\]" $R/py_$n.txt | grep -iE "timing|mean|advance|put|reset|pose|step" | tail -25 | cut -c1-160 >> $R/sum_tm.txt; el "$n"
done
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
