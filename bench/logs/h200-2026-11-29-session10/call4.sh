#!/usr/bin/env bash
# Session 10, call 4 (test binaries of main a7b32f9, wheel of db75990: the same Python and batch code,
# a7b32f9 changed only the grid update's node position): the Python GPU batch loop with the resets
# put in one upload (bench/python_batch_gpu.py, 256 worlds, as call 3); the per-world moving
# colliders with their faces off the nodes and the grid update's unfused node position
# (tests/batch_colliders.rs); the Python GPU batch tests; with the time left, the batched put of
# worlds (tests/batch.rs).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( 225 - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
T() { local name=$1 lim=$2; shift 2
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$name.log 2>&1
  echo "$name rc=$? (limit $lim s): $(grep -E '^test result' $R/$name.log | tail -1)" >> $R/summary.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|^ok$" $R/$name.log | head -12 >> $R/summary.txt; }
python3 -m pip install -q --no-index --no-deps --target /tmp/site $D/wheels/*.whl && export PYTHONPATH=/tmp/site
timeout 90 python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 3 \
  --json $R/pyloop256.json > $R/pyloop256.txt 2>&1
echo "python_batch_gpu 256 worlds rc=$?" >> $R/summary.txt; tail -14 $R/pyloop256.txt >> $R/summary.txt
el pyloop256
T test_batch_colliders 80; grep -E "vs its CPU|first step|longest" $R/test_batch_colliders.log | head -8 >> $R/summary.txt; el colliders
l=$(left); PYTHONUNBUFFERED=1 timeout $(( l < 60 ? l : 60 )) python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
echo "pytest test_batch_gpu.py rc=$?: $(tail -1 $R/pytest.log)" >> $R/summary.txt
grep -E "FAILED|Error" $R/pytest.log | head -8 >> $R/summary.txt; el pytest
l=$(left); [ $l -gt 10 ] && { T test_batch $l worlds_put_at_once_hold_what_one_put_a_world_leaves; el batch; }
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
