#!/usr/bin/env bash
# Session 15, call 2 (two H200s; binaries and wheel of main, see COMMIT: kinematic-only rigid
# worlds advanced without rapier's pipeline, the batch's host advance fanned by cost, the P2G redo
# after a put limited to the worlds put). Phase 1, one lane a GPU: GPU 0 the redo's tests, its
# memcheck, the put paths' tests; GPU 1 the rigid tests (kinematic tools) and the Python GPU batch
# tests; a warm-up of the benchmark's kernels. Phase 2, GPU 0 alone: the Python GPU batch loop,
# new against the old paths (RTMPM_KINEMATIC=rapier, RTMPM_BATCH_REDO=old), alternating.
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
t() { local n=$1 cap=$2; shift 2; local l; l=$(left 300); [ $l -gt 20 ] || { echo "$n not run (time)" >> $R/sum_t.txt; return; }
  [ $l -lt $cap ] && cap=$l
  timeout $cap $D/$n --include-ignored "$@" > $R/$n.log 2>&1
  echo "$n rc=$?: $(grep -E '^test result' $R/$n.log | tail -1)" >> $R/sum_t.txt
  grep -E "FAILED|panicked|f32 only" $R/$n.log | cut -c1-200 | head -10 >> $R/sum_t.txt; el "$n"; }
py() { local n=$1; shift; local l; l=$(left 300); [ $l -gt 20 ] || { echo "pytest $n not run (time)" >> $R/sum_t.txt; return; }
  PYTHONPATH=/tmp/site_main timeout $l python3 -m pytest -q -p no:cacheprovider "$@" > $R/pytest_$n.log 2>&1
  echo "pytest $n rc=$?: $(tail -1 $R/pytest_$n.log)" >> $R/sum_t.txt; grep -E "^FAILED|^E  " $R/pytest_$n.log | head -8 | cut -c1-200 >> $R/sum_t.txt; el "pytest $n"; }
( export CUDA_VISIBLE_DEVICES=0 RAYON_NUM_THREADS=14
  t test_batch_redo 150 --nocapture
  l=$(left 300); [ $l -gt 30 ] && { timeout $l compute-sanitizer --tool memcheck --error-exitcode 1 $D/test_batch_redo --include-ignored the_redo_of_the_worlds_put_leaves_the_others_nodes_bit_for_bit --exact --nocapture > $R/memcheck_redo.log 2>&1
    echo "memcheck redo rc=$?: $(grep -E 'ERROR SUMMARY|^test result' $R/memcheck_redo.log | tr '\n' ' ')" >> $R/sum_t.txt; el memcheck; }
  t test_batch_resets 150 --nocapture
  t test_batch_lockstep 80
  t test_batch_rewind 80 ) &
( export CUDA_VISIBLE_DEVICES=$G1 RAYON_NUM_THREADS=14
  PYTHONPATH=/tmp/site_main timeout 150 python3 bench/python_batch_gpu.py --worlds 256 --steps 20 --per-call 10 --repeats 1 > $R/py_warm.txt 2>&1; el "bench warm-up rc=$?"
  # The driver's JIT of the kernel PTX the warm-up compiled (its cache off): what loading a
  # cubin from NVRTC instead of PTX would save each process's first backend.
  CUDA_CACHE_DISABLE=1 timeout 120 python3 -c "
import glob, os, time
from cupy.cuda import function
for p in sorted(glob.glob('/tmp/kcache/*.ptx')):
    m = function.Module(); t = time.time(); m.load_file(p)
    print('jit', os.path.basename(p), os.path.getsize(p), 'bytes', round(time.time() - t, 2), 's')
" > $R/jit.txt 2>&1; cat $R/jit.txt | head -8 >> $R/sum_t.txt; el jit
  t test_batch_rigid 150 --nocapture
  t test_rigid 120
  t test_batch_waits 80
  py batch_gpu crates/rtmpm-py/tests/test_batch_gpu.py
  py gpu_rigid crates/rtmpm-py/tests/test_gpu.py -k "kinematic or rigid" ) &
wait; el "phase 1"
export CUDA_VISIBLE_DEVICES=0
BB="python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 2 --budget 10"
OLD="RTMPM_KINEMATIC=rapier RTMPM_BATCH_REDO=old"
for v in "new_1:" "old_1:$OLD" "kin_only_1:RTMPM_BATCH_REDO=old" "redo_only_1:RTMPM_KINEMATIC=rapier" "new_2:" "old_2:$OLD" "newmt_1:MT" "oldmt_1:MT $OLD" "new_3:" "newmt_2:MT"; do
  n=${v%%:*}; e=${v#*:}; a=""; case "$e" in MT*) a="--moving-tool"; e=${e#MT};; esac
  l=$(left 545); [ $l -gt 25 ] || break
  env $e PYTHONPATH=/tmp/site_main timeout $l $BB $a > $R/py_$n.txt 2>&1
  echo "$n rc=$? ($e $a)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop) " $R/py_$n.txt | head -10 | cut -c1-120 >> $R/sum_py.txt; el "$n"
done
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
