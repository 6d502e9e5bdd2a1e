#!/usr/bin/env bash
# Session 11, call 4 (one H200; binaries and wheel of main, see COMMIT): (1) the GPU tests after they
# were split by concept (every batch_* binary whole, and the multi-GPU binaries as two ranks on the one
# GPU), in lanes at once (tests, not timings); (2) the Python GPU batch loop after the host-side puts
# and poses (kept memory, parallel pack, serial poses below 4,096 worlds), with --breakdown, against
# the wheel of 287e897 in the same call; with every mode's tool moving if time is left; (3) the Python
# GPU batch tests.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( 520 - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked" $R/$log.log | head -20 >> $R/sum_$log.txt; }
T isolation test_batch_isolation 240 &
T resets test_batch_resets 240 &
T rewind test_batch_rewind 240 &
T lockstep test_batch_lockstep 240 &
T colliders test_batch_colliders 240 &
T rigidb test_batch_rigid 240 &
( export RTMPM_MULTI_GPU_DEVICES=0,0
  T magree test_multi_gpu_agreement 200; T merrors test_multi_gpu_errors 100; T mrigid test_multi_gpu_rigid 150 ) &
wait; el "tests"
for w in main 287e897; do rm -rf /tmp/site_$w; cp -a $D/site_$w /tmp/site_$w; done
l=$(left); PYTHONPATH=/tmp/site_main timeout $(( l < 130 ? l : 130 )) python3 bench/python_batch_gpu.py --worlds 256 --steps 200 \
  --per-call 1,10 --repeats 3 --budget 80 --breakdown --json $R/pyloop_main.json > $R/pyloop_main.txt 2>&1
echo "pyloop main rc=$?" >> $R/sum_py.txt; grep -vE "^\[|round|set-up" $R/pyloop_main.txt | tail -34 >> $R/sum_py.txt; el "pyloop main"
l=$(left); [ $l -gt 70 ] && { PYTHONPATH=/tmp/site_287e897 timeout 90 python3 bench/python_batch_gpu.py --worlds 256 --steps 200 \
  --per-call 1,10 --repeats 2 --budget 50 --json $R/pyloop_287e897.json > $R/pyloop_287e897.txt 2>&1
  echo "pyloop 287e897 rc=$?" >> $R/sum_py.txt; tail -14 $R/pyloop_287e897.txt >> $R/sum_py.txt; el "pyloop 287e897"; }
l=$(left); [ $l -gt 30 ] && { PYTHONPATH=/tmp/site_main timeout $(( l - 15 )) python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
  echo "pytest test_batch_gpu.py rc=$?: $(tail -1 $R/pytest.log)" >> $R/sum_py.txt; grep -E "FAILED|Error" $R/pytest.log | head -8 >> $R/sum_py.txt; el pytest; }
l=$(left); [ $l -gt 60 ] && { PYTHONPATH=/tmp/site_main timeout $(( l - 5 )) python3 bench/python_batch_gpu.py --worlds 256 --steps 200 \
  --per-call 10 --repeats 3 --budget 40 --breakdown --moving-tool --json $R/pyloop_moving.json > $R/pyloop_moving.txt 2>&1
  echo "pyloop main --moving-tool rc=$?" >> $R/sum_py.txt; grep -vE "^\[|round|set-up" $R/pyloop_moving.txt | tail -18 >> $R/sum_py.txt; el "pyloop moving"; }
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
