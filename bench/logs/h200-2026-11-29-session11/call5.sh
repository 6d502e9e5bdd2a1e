#!/usr/bin/env bash
# Session 11, call 5 (one H200; binaries of main 83dba00): compute-sanitizer memcheck on the batch's
# changed put kernel (batch_put_world: the rebuild flag set by the kernel where a put particle leaves
# its gblock's free zone), through the GPU test that exercises it.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
cs=$(command -v compute-sanitizer || ls /usr/local/cuda/bin/compute-sanitizer /opt/nvidia/*/compute-sanitizer 2>/dev/null | head -1)
timeout 330 "$cs" --tool memcheck --leak-check no --print-limit 20 $D/test_batch_resets --include-ignored --test-threads 1 --nocapture \
  a_put_rebuilds_the_mapping_only_where_a_particle_leaves_its_zone worlds_put_at_once_hold_what_one_put_a_world_leaves > $R/memcheck.log 2>&1
echo "memcheck test_batch_resets rc=$?: $(grep -E 'ERROR SUMMARY' $R/memcheck.log | tail -1) | $(grep -E '^test result' $R/memcheck.log | tail -1)" >> $R/summary.txt
grep -E "^test |Invalid|ERROR" $R/memcheck.log | head -12 >> $R/summary.txt
el memcheck
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
