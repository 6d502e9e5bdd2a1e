#!/usr/bin/env bash
# Session 16, call 3 (two H200s; binaries and wheel of main, see COMMIT): everything of session 16
# landed: the body table's two-table upload (RTMPM_BATCH_UPLOAD=old), the pipelined overlap calls
# (RTMPM_BATCH_PIPELINE=off), the reset's kernels over the worlds put (RTMPM_BATCH_PUT=old,
# RTMPM_BATCH_REDO=wave), kinematic rows ahead of rapier (RTMPM_KINEMATIC=eager), overlap on by
# default on the GPU (--no-overlap for off; the OV runs ask for it with --overlap). Phase 1, one lane a GPU: the GPU tests
# of those changes. Phase 2, GPU 0 alone: the Python GPU batch loop, new against old, with and
# without overlap, alternating; the timeline of the loop with overlap, new and old.
set -u
R=$OUT
[ -d .device ] && [ "$(cat .device/COMMIT)" = "$(tar xJOf .device-pack/d.tar.xz .device/COMMIT 2>/dev/null)" ] || tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache PYTHONUNBUFFERED=1 NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-560} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name --format=csv,noheader | tr '\n' ' '); nproc $(nproc)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
NG=$(nvidia-smi -L | wc -l); G1=$(( NG > 1 ? 1 : 0 ))
OLD=${OLD:-"RTMPM_BATCH_UPLOAD=old RTMPM_BATCH_PIPELINE=off RTMPM_BATCH_PUT=old RTMPM_BATCH_REDO=wave RTMPM_KINEMATIC=eager"}
NOOV=""; grep -q -- "--no-overlap" bench/python_batch_gpu.py && NOOV="--no-overlap"
P1=${P1:-300}
t() { local n=$1 cap=$2; shift 2; local l; l=$(left $P1); [ $l -gt 20 ] || { echo "$n not run (time)" >> $R/sum_t.txt; return; }
  [ $l -lt $cap ] && cap=$l
  timeout $cap $D/$n --include-ignored "$@" > $R/$n.log 2>&1
  echo "$n rc=$?: $(grep -E '^test result' $R/$n.log | tail -1)" >> $R/sum_t.txt
  grep -E "FAILED|panicked|f32 only|warning: the driver" $R/$n.log | cut -c1-200 | head -10 >> $R/sum_t.txt; el "$n"; }
py() { local n=$1 cap=$2; shift 2; local l; l=$(left $P1); [ $l -gt 20 ] || { echo "pytest $n not run (time)" >> $R/sum_t.txt; return; }
  [ $l -lt $cap ] && cap=$l
  PYTHONPATH=/tmp/site_main timeout $cap python3 -m pytest -q -p no:cacheprovider "$@" > $R/pytest_$n.log 2>&1
  echo "pytest $n rc=$?: $(tail -1 $R/pytest_$n.log)" >> $R/sum_t.txt; grep -E "^FAILED|^E  " $R/pytest_$n.log | head -8 | cut -c1-200 >> $R/sum_t.txt; el "pytest $n"; }
mc() { local n=$1 f=$2; local l; l=$(left $P1); [ $l -gt 30 ] || { echo "memcheck $n not run (time)" >> $R/sum_t.txt; return; }
  timeout $l compute-sanitizer --tool memcheck --error-exitcode 1 $D/$n --include-ignored $f --exact --nocapture > $R/memcheck_${n}.log 2>&1
  echo "memcheck $n $f rc=$?: $(grep -E 'ERROR SUMMARY|^test result' $R/memcheck_${n}.log | tr '\n' ' ')" >> $R/sum_t.txt; el "memcheck $n"; }
( export CUDA_VISIBLE_DEVICES=0 RAYON_NUM_THREADS=14
  PYTHONPATH=/tmp/site_main timeout 150 python3 bench/python_batch_gpu.py --worlds 256 --steps 20 --per-call 10 --repeats 1 > $R/py_warm.txt 2>&1; el "bench warm-up rc=$?"
  t test_batch_put_slots 60 --nocapture
  t test_batch_redo 120
  mc test_batch_put_slots a_put_over_the_gblocks_leaves_what_the_put_of_every_slot_leaves
  mc test_batch_redo the_redo_of_a_lane_an_item_leaves_the_grid_of_the_redo_of_a_warp_an_item
  t test_batch_waits 60 --nocapture
  t test_batch_rigid 90 ) &
( export CUDA_VISIBLE_DEVICES=$G1 RAYON_NUM_THREADS=14
  PYTHONPATH=/tmp/site_main timeout 150 python3 bench/python_batch_gpu.py --worlds 16 --steps 20 --per-call 10 --repeats 1 > $R/py_warm1.txt 2>&1; el "warm-up 1 rc=$?"
  py batch_gpu 150 crates/rtmpm-py/tests/test_batch_gpu.py
  RTMPM_BATCH_OVERLAP=0 py batch_gpu_overlap0 150 crates/rtmpm-py/tests/test_batch_gpu.py
  t test_batch_resets 90
  l=$(left $P1); [ $l -gt 40 ] && { RTMPM_BATCH_PUT=old RTMPM_BATCH_REDO=wave timeout $l $D/test_batch_resets --include-ignored > $R/old_resets.log 2>&1; echo "test_batch_resets (PUT=old REDO=wave) rc=$?: $(grep -E '^test result' $R/old_resets.log | tail -1)" >> $R/sum_t.txt; el "old resets"; }
  t test_batch_rewind 60
  t test_rigid 100
  t test_agreement 120 --test-threads 1 cuda_agrees_with_cpu_on_every_example_scene ) &
wait; el "phase 1"
export CUDA_VISIBLE_DEVICES=0
BB="python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 10 --repeats 3 --budget 10"
PUTOLD="RTMPM_BATCH_PUT=old RTMPM_BATCH_REDO=wave"
for v in "ov_new_1:OV" "ov_old_1:OV $OLD" "plain_new_1:NO" "plain_old_1:NO $OLD" "ov_putold_1:OV $PUTOLD" "ov_new_2:OV" "ov_old_2:OV $OLD" "ovmt_new_1:OVMT" "ovmt_old_1:OVMT $OLD" "ov_new_3:OV" "ov_old_3:OV $OLD" "plain_new_2:NO" "plain_old_2:NO $OLD" "ov_putold_2:OV $PUTOLD" "ov_new_4:OV" "ov_old_4:OV $OLD"; do
  n=${v%%:*}; e=${v#*:}; a=""
  case "$e" in OVMT*) a="--overlap --moving-tool"; e=${e#OVMT};; OV*) a="--overlap"; e=${e#OV};; NO*) a="$NOOV"; e=${e#NO};; esac
  l=$(left 525); [ $l -gt 20 ] || break
  env $e PYTHONPATH=/tmp/site_main timeout $l $BB $a > $R/py_$n.txt 2>&1
  echo "$n rc=$? ($e $a)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop|device) " $R/py_$n.txt | head -7 | cut -c1-120 >> $R/sum_py.txt; el "$n"
  grep -E "^RTMPM_" $R/py_$n.txt | tail -8 | cut -c1-220 >> $R/sum_py.txt
done
for v in "new:" "old:$OLD"; do
  n=${v%%:*}; e=${v#*:}; l=$(left 585); [ $l -gt 20 ] || break
  env $e PYTHONPATH=/tmp/site_main timeout $l python3 bench/python_batch_trace.py --overlap --trace $R/trace_ov_$n.json > $R/tsum_ov_$n.txt 2>&1
  echo "trace ov $n rc=$? ($e)" >> $R/sum_tr.txt; [ -s $R/trace_ov_$n.json ] && xz -T4 -6 $R/trace_ov_$n.json; el "trace $n"
done
{ head -1 $R/times.txt; cat $R/sum_t.txt $R/sum_py.txt $R/sum_tr.txt; for f in $R/tsum_ov_*.txt; do echo "-- $f"; grep -E "^==|^   (kernel|gpu_)|host " $f | head -40 | cut -c1-150; done; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt --exclude='*.json.xz' . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz ! -name '*.json.xz' -exec rm -rf {} +)
cat $R/report.txt
