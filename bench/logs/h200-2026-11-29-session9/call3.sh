#!/usr/bin/env bash
# Session 9, call 3 (binaries and wheel of main 6cb9051): the GPU batch with rigid bodies per world
# (tests/batch_rigid.rs: kinematic tools posed per world against separate runs and the CPU load,
# dynamic bodies, a reset world's tool), the Python GPU batch tests (device arrays, tools posed
# per world, batch_push.py on the GPU, and the five of session 8), the batch benchmark with each
# world's set-up counted, and the Python step loop of a GPU batch (bench/python_batch_gpu.py).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
T() { local name=$1 lim=$2; shift 2
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$name.log 2>&1
  echo "$name rc=$? (limit $lim s): $(grep -E '^test result' $R/$name.log | tail -1)" >> $R/summary.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked" $R/$name.log | head -12 >> $R/summary.txt; }
T test_batch_rigid 150; el batch_rigid
grep -iE "world|force|load|agree" $R/test_batch_rigid.log | head -20 >> $R/summary.txt
SITE=$(mktemp -d)
python3 -m pip install --quiet --no-index --no-deps --target "$SITE" .device/wheels/rtmpm-*.whl
export PYTHONPATH="$SITE" RTMPM_CLI=$PWD/.device/rtmpm
timeout 200 python3 -m pytest -v -p no:cacheprovider --durations=0 crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
echo "pytest test_batch_gpu.py rc=$? (limit 200 s): $(grep -E 'passed|failed' $R/pytest.log | tail -1)" >> $R/summary.txt
grep -E "PASSED|FAILED|SKIPPED|ERROR|^[0-9.]+s call" $R/pytest.log | sed -E 's/ +\[ *[0-9]+%\]//' >> $R/summary.txt
el python
BATCH_WORLDS=1024 BATCH_STEPS=200 BATCH_ALONE=16 T test_batch 90 --exact batch_benchmark
grep -E "BENCH" $R/test_batch.log >> $R/summary.txt; el batch_benchmark
left=$(( 550 - ($(date +%s) - T0) ))
timeout $left python3 bench/python_batch_gpu.py --repeats 2 --json $R/python_batch_gpu.json > $R/python_batch_gpu.txt 2>&1
echo "python_batch_gpu.py --repeats 2 rc=$? (limit $left s)" >> $R/summary.txt; tail -30 $R/python_batch_gpu.txt >> $R/summary.txt
el python_bench
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
