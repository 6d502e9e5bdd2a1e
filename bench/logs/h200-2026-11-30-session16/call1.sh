#!/usr/bin/env bash
# Session 16, call 1 (one H200; binaries and wheel of main, see COMMIT). A timeline of the Python
# GPU batch loop from PyTorch's profiler (trace_loop.py: every kernel, copy and memset of the
# process) in three settings (default, --overlap, --moving-tool), then the loop's table over
# several rounds, with the flush of kept poses on the calling thread (1b8077e, default) against
# every core (RTMPM_BATCH_FAN=cores), with --overlap, and once with the host timings.
set -u
R=$OUT
[ -d .device ] && [ "$(cat .device/COMMIT)" = "$(tar xJOf .device-pack/d.tar.xz .device/COMMIT 2>/dev/null)" ] || tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache PYTHONUNBUFFERED=1 CUDA_VISIBLE_DEVICES=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-560} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name --format=csv,noheader | tr '\n' ' '); nproc $(nproc)"
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
S=bench/logs/h200-2026-11-30-session16
PYTHONPATH=/tmp/site_main timeout 150 python3 bench/python_batch_gpu.py --worlds 256 --steps 20 --per-call 10 --repeats 1 > $R/py_warm.txt 2>&1; el "bench warm-up rc=$?"
for v in "plain:" "overlap:--overlap" "moving:--moving-tool"; do
  n=${v%%:*}; a=${v#*:}
  PYTHONPATH=/tmp/site_main timeout 90 python3 $S/trace_loop.py $R/trace_$n.json $a > $R/trace_$n.txt 2>&1
  echo "trace $n rc=$?" >> $R/sum_tr.txt; grep -E "ms a call|Error|error" $R/trace_$n.txt | head -8 | cut -c1-200 >> $R/sum_tr.txt
  [ -s $R/trace_$n.json ] && python3 $S/trace_summary.py $R/trace_$n.json > $R/tsum_$n.txt 2>&1 && { echo "-- $n"; cat $R/tsum_$n.txt | cut -c1-160 | head -150; } >> $R/sum_tsum.txt
  [ -s $R/trace_$n.json ] && xz -T4 -6 $R/trace_$n.json
  el "trace $n"
done
BB="python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 10 --repeats 3 --budget 12"
for v in "new_1:" "fancores_1:RTMPM_BATCH_FAN=cores" "overlap_1:OV" "new_2:" "fancores_2:RTMPM_BATCH_FAN=cores" "overlap_2:OV" "timed_1:RTMPM_STEP_TIMING=1 RTMPM_POSE_TIMING=1" "newmt_1:MT"; do
  n=${v%%:*}; e=${v#*:}; a=""; case "$e" in MT*) a="--moving-tool"; e=${e#MT};; OV*) a="--overlap"; e=${e#OV};; esac
  l=$(left 560); [ $l -gt 25 ] || break
  env $e PYTHONPATH=/tmp/site_main timeout $l $BB $a > $R/py_$n.txt 2>&1
  echo "$n rc=$? ($e $a)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop|device) " $R/py_$n.txt | head -7 | cut -c1-120 >> $R/sum_py.txt; el "$n"
done
grep -E "^RTMPM_" $R/py_timed_1.txt | tail -14 | cut -c1-220 >> $R/sum_py.txt
{ head -1 $R/times.txt; cat $R/sum_tr.txt $R/sum_py.txt $R/sum_tsum.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt --exclude='*.json.xz' . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz ! -name '*.json.xz' -exec rm -rf {} +)
cat $R/report.txt
