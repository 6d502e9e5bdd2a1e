#!/usr/bin/env bash
# Session 13, call 1 (four H200s; binaries and wheel of main, see COMMIT).
# Phase 1, one GPU per lane (tests in lanes; the loop's timing on GPU 0 while the other lanes run tests
# on other GPUs): the body table through page-locked memory (56f584b) and the PartTimes timers
# (99024ca) had not run on a GPU: the Python loop with the reset and pose breakdowns, the same with
# RTMPM_BATCH_PAGEABLE_PUT=1 (the old pageable path), with --overlap; the batch test binaries and the
# Python GPU batch tests. Phase 2, all four GPUs: the multi-GPU agreement at 2 and 4 GPUs, then the
# exchange suite's timings at 1, 2 and 4 GPUs (REPS=1, strong too) with the exchange defaults of f99a13a.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1 PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-560} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1); $(nvidia-smi -L | wc -l) GPUs"
nvidia-smi topo -m > $R/topo.txt 2>&1
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
PY() { PYTHONPATH=/tmp/site_main timeout "$@"; }
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|run again|body_sums at read|runs of|skipped" $R/$log.log | cut -c1-240 | head -24 >> $R/sum_$log.txt; }
# ---- phase 1: lanes, one GPU each
( export CUDA_VISIBLE_DEVICES=0
  n=pyloop_timing; RTMPM_RESET_TIMING=1 RTMPM_POSE_TIMING=1 PY 90 python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 2 --budget 30 --breakdown --json $R/$n.json > $R/$n.txt 2>&1
  echo "$n rc=$?" >> $R/sum_py.txt; grep -vE "^\[|round|set-up" $R/$n.txt | grep -vi timing | tail -22 >> $R/sum_py.txt; el "$n"
  for v in "pageable:RTMPM_BATCH_PAGEABLE_PUT=1:" "pinned::" "overlap::--overlap" "overlap_pageable:RTMPM_BATCH_PAGEABLE_PUT=1:--overlap"; do
    IFS=: read n e m <<< "$v"; n=pyloop_$n
    env $e PYTHONPATH=/tmp/site_main timeout 60 python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 2 --budget 18 $m --json $R/$n.json > $R/$n.txt 2>&1
    echo "$n rc=$? ($e $m)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop|device) " $R/$n.txt >> $R/sum_py.txt; el "$n"
  done
  PY $(left 330) python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
  echo "pytest test_batch_gpu.py rc=$?: $(tail -1 $R/pytest.log)" >> $R/sum_pytest.txt; grep -E "FAILED|Error|XPASS|xfail" $R/pytest.log | head -8 >> $R/sum_pytest.txt
  el pytest ) &
( export CUDA_VISIBLE_DEVICES=1; T resets test_batch_resets $(left 330); T rewind test_batch_rewind $(left 330); el "lane 1" ) &
( export CUDA_VISIBLE_DEVICES=2; T rigid test_batch_rigid $(left 330); el "lane 2" ) &
( export CUDA_VISIBLE_DEVICES=3; T lockstep test_batch_lockstep $(left 330); el "lane 3" ) &
wait; el "phase 1"
# ---- phase 2: all four GPUs
T magree test_multi_gpu_agreement $(left 400)
el magree
l=$(left 575)
if [ $l -gt 60 ]; then
  mkdir -p $R/runsh
  OUT=$R/runsh REPS=1 timeout $l bash scripts/gpu/run.sh exchange > $R/exchange.out 2>&1
  echo "exchange rc=$? (limit $l s)" >> $R/sum_xchange.txt; cat $R/runsh/summary.txt >> $R/sum_xchange.txt 2>/dev/null
fi
el exchange
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
