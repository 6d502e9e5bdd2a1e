#!/usr/bin/env bash
# Session 13, call 4 (two H200s, warm after call 3: the binaries of 457ff2a already unpacked in .device).
# GPU 0: test_addressing alone (it ran out of time in call 2 beside eight other lanes);
# GPU 1: rtmpm against Taichi 1.7.4 on the fluid block n = 256, interleaved (Taichi carried as a slim site).
set -u
R=$OUT
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-280} - ($(date +%s) - T0) )); }
[ -x $D/rtmpm ] || { echo "no .device on this machine"; exit 3; }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
( export CUDA_VISIBLE_DEVICES=0
  timeout $(left) $D/test_addressing --include-ignored --test-threads 1 --nocapture > $R/addressing.log 2>&1
  echo "addressing rc=$?: $(grep -E '^test result' $R/addressing.log)" >> $R/sum_a.txt
  grep -E "^test |FAILED|panicked|differs|rerun" $R/addressing.log | cut -c1-220 | head -30 >> $R/sum_a.txt; el addressing ) &
( export CUDA_VISIBLE_DEVICES=1
  mkdir -p /tmp/tsite && tar xJf .device-pack3/taichi-slim.tar.xz -C /tmp/tsite
  L() { local label=$1; shift; local r; r=$(timeout 100 "$@" 2>&1); echo "== $label: $*" >> $R/taichi.log; echo "$r" >> $R/taichi.log
    echo "$label | $(echo "$r" | grep -m1 -E 'throughput' | tr -s ' ') | $(echo "$r" | grep -oE '[0-9.]+ ms/step' | head -1) $(echo "$r" | grep -m1 -iE '^error|Traceback|RuntimeError|Error')" >> $R/sum_t.txt; }
  for rep in 1 2; do [ $(left) -gt 50 ] || break
    L "rtmpm n=256 #$rep" $D/rtmpm bench --backend cuda --n 256 --steps 500
    PYTHONPATH=/tmp/tsite L "taichi n=256 #$rep" python3 bench/taichi_mpm3d.py --arch cuda --n 256 --steps 500
  done; el taichi ) &
wait
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt; cat $R/report.txt
