#!/usr/bin/env bash
# Session 15, call 3 (two H200s; binaries and wheel of main, see COMMIT: the backend loads
# NVRTC's cubin, kinematic-only worlds without rapier, the partial P2G redo with its clear kernel
# reworked). Phase 1, one lane a GPU: GPU 0 the load time of a kernel set as cubin against PTX
# (the driver's cache off), the redo's tests and memcheck, the waits; GPU 1 the rigid tests, the
# Python GPU batch tests, the CPU agreement on every example scene. Phase 2, GPU 0 alone: the
# Python GPU batch loop, new against the old paths, with the host timings once.
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
t() { local n=$1 cap=$2; shift 2; local l; l=$(left 330); [ $l -gt 20 ] || { echo "$n not run (time)" >> $R/sum_t.txt; return; }
  [ $l -lt $cap ] && cap=$l
  timeout $cap $D/$n --include-ignored "$@" > $R/$n.log 2>&1
  echo "$n rc=$?: $(grep -E '^test result' $R/$n.log | tail -1)" >> $R/sum_t.txt
  grep -E "FAILED|panicked|f32 only|warning: the driver" $R/$n.log | cut -c1-200 | head -10 >> $R/sum_t.txt; el "$n"; }
py() { local n=$1 cap=$2; shift 2; local l; l=$(left 330); [ $l -gt 20 ] || { echo "pytest $n not run (time)" >> $R/sum_t.txt; return; }
  [ $l -lt $cap ] && cap=$l
  PYTHONPATH=/tmp/site_main timeout $cap python3 -m pytest -q -p no:cacheprovider "$@" > $R/pytest_$n.log 2>&1
  echo "pytest $n rc=$?: $(tail -1 $R/pytest_$n.log)" >> $R/sum_t.txt; grep -E "^FAILED|^E  " $R/pytest_$n.log | head -8 | cut -c1-200 >> $R/sum_t.txt; el "pytest $n"; }
( export CUDA_VISIBLE_DEVICES=0 RAYON_NUM_THREADS=14
  # A process's load of one kernel set: fill a fresh cache, then PTX (the driver compiles it)
  # against cubin (loaded as it is), twice each; the driver's own cache off throughout.
  for v in fill: ptx:RTMPM_KERNEL_IMAGE=ptx cubin: ptx2:RTMPM_KERNEL_IMAGE=ptx cubin2:; do
    n=${v%%:*}; e=${v#*:}; s=$(date +%s.%N)
    env $e CUDA_CACHE_DISABLE=1 RTMPM_CACHE_DIR=/tmp/kc3 timeout 150 $D/rtmpm run scenes/dam_break.toml --backend cuda --steps 5 --out /tmp/o_$n > $R/load_$n.log 2>&1
    echo "load $n rc=$? ($e): $(python3 -c "print(round($(date +%s.%N) - $s, 2))") s" >> $R/sum_t.txt; el "load $n"
  done
  ls -la /tmp/kc3 >> $R/load_fill.log
  t test_batch_redo 200 --nocapture
  l=$(left 330); [ $l -gt 30 ] && { timeout $l compute-sanitizer --tool memcheck --error-exitcode 1 $D/test_batch_redo --include-ignored the_redo_of_the_worlds_put_leaves_the_others_nodes_bit_for_bit --exact --nocapture > $R/memcheck_redo.log 2>&1
    echo "memcheck redo (redo_clear reworked) rc=$?: $(grep -E 'ERROR SUMMARY|^test result' $R/memcheck_redo.log | tr '\n' ' ')" >> $R/sum_t.txt; el memcheck; }
  t test_batch_waits 80 ) &
( export CUDA_VISIBLE_DEVICES=$G1 RAYON_NUM_THREADS=14
  PYTHONPATH=/tmp/site_main timeout 150 python3 bench/python_batch_gpu.py --worlds 256 --steps 20 --per-call 10 --repeats 1 > $R/py_warm.txt 2>&1; el "bench warm-up rc=$?"
  py batch_gpu 200 crates/rtmpm-py/tests/test_batch_gpu.py
  py gpu_rigid 100 crates/rtmpm-py/tests/test_gpu.py -k "kinematic or rigid"
  t test_rigid 150
  t test_agreement 200 --test-threads 1 cuda_agrees_with_cpu_on_every_example_scene ) &
wait; el "phase 1"
export CUDA_VISIBLE_DEVICES=0
BB="python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 2 --budget 10"
OLD="RTMPM_KINEMATIC=rapier RTMPM_BATCH_REDO=old"
for v in "new_1:" "old_1:$OLD" "newmt_1:MT" "oldmt_1:MT $OLD" "new_2:" "fancores_1:RTMPM_BATCH_FAN=cores" "timed_1:RTMPM_STEP_TIMING=1 RTMPM_POSE_TIMING=1" "old_2:$OLD"; do
  n=${v%%:*}; e=${v#*:}; a=""; case "$e" in MT*) a="--moving-tool"; e=${e#MT};; esac
  l=$(left 555); [ $l -gt 25 ] || break
  env $e PYTHONPATH=/tmp/site_main timeout $l $BB $a > $R/py_$n.txt 2>&1
  echo "$n rc=$? ($e $a)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop) " $R/py_$n.txt | head -10 | cut -c1-120 >> $R/sum_py.txt; el "$n"
done
grep -E "^RTMPM_" $R/py_timed_1.txt | tail -14 | cut -c1-220 >> $R/sum_py.txt
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
