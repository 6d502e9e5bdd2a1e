#!/usr/bin/env bash
# Session 13, call 3 (two H200s; binaries and wheel of main as call 2, see COMMIT). Timings only.
# Phase 1, one lane a GPU: GPU 0 the Python GPU batch loop, the host-wait cuts (be59f0b and after)
# against RTMPM_BATCH_WAITS=old in the same wheel, alternating, with and without --overlap;
# GPU 1 the second round of instruction cuts and the row unrolling against the default, interleaved on
# the claymore scenes. Phase 2, both GPUs alone: weak and strong, 1 and 2 GPUs, the default exchange
# (push, no overlap) against push_update and list_push_update, interleaved, twice.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-470} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
CUTS=seg_clamp=on,zero_terms=skip,flat_checks=on,state_index=wide
( export CUDA_VISIBLE_DEVICES=0
  for v in "on::--overlap" "old:RTMPM_BATCH_WAITS=old:--overlap" "on2::--overlap" "old2:RTMPM_BATCH_WAITS=old:--overlap" "off::" "offold:RTMPM_BATCH_WAITS=old:"; do
    IFS=: read n e m <<< "$v"; n=sync_$n; l=$(left 250); [ $l -gt 40 ] || break
    env RTMPM_SYNC_TRACE=1 $e PYTHONPATH=/tmp/site_main timeout $l python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 2 --budget 16 $m --json $R/$n.json > $R/$n.txt 2>&1
    echo "$n rc=$? ($e $m)" >> $R/sum_py.txt; grep -E "^\| (bare|calls|reset|pose|loop|device) |wait|^bare" $R/$n.txt | cut -c1-200 | head -30 >> $R/sum_py.txt; el "$n"
  done ) &
( export CUDA_VISIBLE_DEVICES=1
  SC="fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20"
  OPTS="- $CUTS $CUTS,lean_lanes=on row_unroll=planes row_unroll=planes,$CUTS row_unroll=all,$CUTS"
  for sf in $SC; do for o in $OPTS; do
    timeout 150 $D/rtmpm bench --backend cuda --scene bench/${sf%%:*}.toml --steps 2 $([ $o = - ] || echo --cuda-options $o) > /dev/null 2>&1 &
  done; done; wait; el "kernels compiled"
  b() { local label=$1; shift; local r; r=$(timeout 60 $D/rtmpm bench --backend cuda "$@" 2>&1)
    echo "== $label: $*" >> $R/bench.log; echo "$r" >> $R/bench.log
    printf '%-90s %s %s\n' "$label" "$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1)" "$(echo "$r" | grep -E '^error' | head -1)" >> $R/sum_kbench.txt; }
  for rep in 1 2; do for sf in $SC; do for o in $OPTS; do
    [ $(left 250) -gt 8 ] || continue
    b "${sf%%:*} $o #$rep" --scene bench/${sf%%:*}.toml --frames ${sf##*:} $([ $o = - ] || echo --cuda-options $o)
  done; done; done; el "kernel A/B" ) &
wait; el "phase 1"
bx() { local label=$1; shift
  local r; r=$(timeout 60 $D/rtmpm bench --backend cuda "$@" 2>&1)
  echo "== $label: $*" >> $R/xbench.log; echo "$r" >> $R/xbench.log
  printf '%-40s %s %s | %s\n' "$label" "$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1)" "$(echo "$r" | grep -E '^error' | head -1)" "$(echo "$r" | grep -E 'reduction' | tail -1 | sed -E 's/^ +//' | cut -c1-100)" >> $R/sum_xbench.txt; }
for rep in 1 2; do
  [ $(left) -gt 20 ] && bx "weak gpus=1 #$rep" --scene bench/weak_4m_x1.toml --frames 4
  for o in exchange=push exchange=push_update exchange=list_push_update; do
    [ $(left) -gt 15 ] && bx "weak gpus=2 $o #$rep" --scene bench/weak_4m_x2.toml --frames 4 --gpus 2 --cuda-options $o; done
  [ $(left) -gt 20 ] && bx "strong gpus=1 #$rep" --scene bench/strong_16m.toml --frames 2
  for o in exchange=push exchange=push_update exchange=list_push_update; do
    [ $(left) -gt 15 ] && bx "strong gpus=2 $o #$rep" --scene bench/strong_16m.toml --frames 2 --gpus 2 --cuda-options $o; done
  el "exchange #$rep"
done
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
