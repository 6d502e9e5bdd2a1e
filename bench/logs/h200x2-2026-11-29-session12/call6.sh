#!/usr/bin/env bash
# Session 12, call 6 (one H200, the last 198 s of the session's device time; wheel of main, see
# COMMIT): the Python GPU batch loop with overlap, the rigid bodies' table and the puts through
# page-locked memory (default since the commit of this call) against both from pageable memory
# (RTMPM_BATCH_PAGEABLE_PUT=1), same wheel, calls of 10 steps; then the tool tests of the Python GPU
# batch and the overlap test, if time is left.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, wheel of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name --format=csv,noheader)"
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
for env in "RTMPM_BATCH_PAGEABLE_PUT=0" "RTMPM_BATCH_PAGEABLE_PUT=1" "RTMPM_BATCH_PAGEABLE_PUT=0"; do
  [ $(( $(date +%s) - T0 )) -lt 75 ] || break
  env $env PYTHONPATH=/tmp/site_main timeout 45 python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 10 \
    --repeats 1 --budget 8 --overlap > $R/loop_$env.txt 2>&1
  echo "== $env rc=$?" >> $R/sum_loop.txt; grep -E "^\| (bare|calls|reset|pose|loop) " $R/loop_$env.txt >> $R/sum_loop.txt; el "$env"
done
left=$(( 112 - ($(date +%s) - T0) ))
[ $left -gt 15 ] && { PYTHONPATH=/tmp/site_main timeout $left python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py \
  -k "tool or overlap" > $R/pytest.log 2>&1; echo "pytest -k 'tool or overlap' rc=$?: $(tail -1 $R/pytest.log)" >> $R/sum_pytest.txt; }
el end
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
