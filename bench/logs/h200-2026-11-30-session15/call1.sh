#!/usr/bin/env bash
# Session 15, call 1 (one H200; binaries and wheel of main, see COMMIT). Phase 1, two lanes:
# the kept-image reset test (its f64 half never ran on a GPU) and the Python GPU batch loop in
# overlap mode with the host timings (RTMPM_STEP_TIMING, RTMPM_POSE_TIMING), against plain mode:
# session 14 saw overlap's pose calls take 8-12 ms a call of 10 in one round. Phase 2, alone:
# test_addressing (fused_defaults=auto against off, bit for bit), which ran out of time beside
# other lanes twice.
set -u
R=$OUT
[ -d .device ] && [ "$(cat .device/COMMIT)" = "$(tar xJOf .device-pack/d.tar.xz .device/COMMIT 2>/dev/null)" ] || tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-540} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name --format=csv,noheader | tr '\n' ' '); nproc $(nproc)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
t() { local n=$1 cap=$2; shift 2; local l; l=$(left 540); [ $l -gt 30 ] || { echo "$n not run (time)" >> $R/sum_t.txt; return; }
  [ $l -lt $cap ] && cap=$l
  timeout $cap $D/$n --include-ignored "$@" > $R/$n.log 2>&1
  echo "$n rc=$?: $(grep -E '^test result' $R/$n.log | tail -1)" >> $R/sum_t.txt
  grep -E "FAILED|panicked|compiled in|f32 only|max \|dx\|" $R/$n.log | cut -c1-200 | head -14 >> $R/sum_t.txt; el "$n"; }
( t test_batch_resets 240 --nocapture a_reset_from_the_kept_image ) &
( BB="python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 10 --repeats 2 --budget 10"
  for v in "overlap_1:--overlap" "plain_1:" "overlap_2:--overlap"; do
    n=${v%%:*}; a=${v#*:}; l=$(left 250); [ $l -gt 30 ] || break
    RTMPM_STEP_TIMING=1 RTMPM_POSE_TIMING=1 PYTHONPATH=/tmp/site_main timeout $l $BB $a > $R/py_$n.txt 2>&1
    echo "$n rc=$? ($a)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop) " $R/py_$n.txt | head -6 | cut -c1-120 >> $R/sum_py.txt
    grep -E "^RTMPM_" $R/py_$n.txt | tail -10 | cut -c1-200 >> $R/sum_py.txt; el "$n"
  done ) &
wait; el "phase 1"
t test_addressing 300 --test-threads 1 --nocapture
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
