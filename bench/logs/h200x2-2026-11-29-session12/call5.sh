#!/usr/bin/env bash
# Session 12, call 5 (one H200; binaries and wheel of main, see COMMIT): (1) the Python GPU batch loop
# with its step calls returning before their check (BatchSimulation.overlap, --overlap) against without,
# same wheel, interleaved by mode; (2) in lanes (tests, not timings): the batch test binaries after the
# page-locked asynchronous puts, the deferred checks and the kept poses (resets, rewind, lockstep, the
# rigid kept-sums test as fixed after call 4), the Python GPU batch tests, then again with every batch in
# overlap mode.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-370} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
PY() { PYTHONPATH=/tmp/site_main timeout "$@"; }
for mode in "" "--overlap"; do
  n=pyloop${mode:+_overlap}
  PY 75 python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 2 --budget 25 $mode \
    --json $R/$n.json > $R/$n.txt 2>&1
  echo "$n rc=$?" >> $R/sum_py.txt; grep -vE "^\[|round|set-up" $R/$n.txt | tail -16 >> $R/sum_py.txt; el "$n"
done
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|run again|body_sums at read" $R/$log.log | cut -c1-240 | head -20 >> $R/sum_$log.txt; }
T resets test_batch_resets $(left) &
( T rigid test_batch_rigid $(left) kept_sums_and_kept_poses; T rewind test_batch_rewind $(left) ) &
T lockstep test_batch_lockstep $(left) &
( PY $(left 360) python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
  echo "pytest test_batch_gpu.py rc=$?: $(tail -1 $R/pytest.log)" >> $R/sum_pytest.txt; grep -E "FAILED|Error" $R/pytest.log | head -8 >> $R/sum_pytest.txt
  [ $(left) -gt 40 ] && { RTMPM_BATCH_OVERLAP=1 PY $(left 360) python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest_overlap.log 2>&1
  echo "RTMPM_BATCH_OVERLAP=1 pytest test_batch_gpu.py rc=$?: $(tail -1 $R/pytest_overlap.log)" >> $R/sum_pytest.txt; grep -E "FAILED|Error" $R/pytest_overlap.log | head -8 >> $R/sum_pytest.txt; }
  el pytest ) &
wait; el "tests"
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
