#!/usr/bin/env bash
# Session 7, call 3 (binaries of dd5a792: the resident grid and 96 registers are the default, the
# lockstep batch driver): test_batch (with the lockstep driver's GPU test) and test_gpu in
# parallel; `rtmpm run` of the wedge batch on the GPU and on the CPU; then the new default
# against the previous one (wave grid, ptxas's registers) on the claymore scenes, f32 and f64.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
printf '#!/bin/sh\nRTMPM_G2P2G_GRID=wave exec "$(dirname "$0")/rtmpm" "$@"\n' > $D/rtmpm_wave; chmod +x $D/rtmpm_wave
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
( OUT=$R/t_batch TEST_TIMEOUT=280 TESTS="test_batch" bash scripts/gpu/run.sh tests > /dev/null 2>&1; el test_batch ) &
( OUT=$R/t_gpu TEST_TIMEOUT=280 TESTS="test_gpu" bash scripts/gpu/run.sh tests > /dev/null 2>&1; el test_gpu ) &
wait
for be in cuda cpu; do
  /usr/bin/time -f "%e s wall, %M KiB" timeout 200 $D/rtmpm run scenes/wedge_slump.toml --backend $be --out $R/wedge_$be > $R/wedge_$be.log 2>&1
  echo "== wedge_slump --backend $be rc=$?" >> $R/wedge.txt; tail -4 $R/wedge_$be.log >> $R/wedge.txt
  cut -d, -f1,4- $R/wedge_$be/batch.csv >> $R/wedge.txt 2>/dev/null
done
el wedge
V="old|rtmpm_wave|-DG2P2G_MIN_BLOCKS=0,-DG2P2G_FLUID_MIN_BLOCKS=4 new|rtmpm||"
OUT=$R/var REPS=2 VARIANTS="$V" timeout 150 bash scripts/gpu/run.sh variants > /dev/null 2>&1; el variants
for rep in 1 2; do for v in old new; do for sc in fluid_dam_2m:5 jelly_drop_2m:3; do
  if [ $v = old ]; then bin=rtmpm_wave; def="-DG2P2G_MIN_BLOCKS=0 -DG2P2G_FLUID_MIN_BLOCKS=4"; else bin=rtmpm; def=""; fi
  r=$(RTMPM_KERNEL_DEFINES="$def" timeout 120 $D/$bin bench --backend cuda --precision f64 --scene bench/${sc%%:*}.toml --frames ${sc##*:} 2>&1)
  echo "$r" >> $R/f64.log
  printf 'f64 %-14s %-4s %s\n' "${sc%%:*}" $v "$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1)" >> $R/f64.txt
done; done; done; el f64
{
for d in $R/t_batch $R/t_gpu; do echo "==== $(basename $d)"; grep -vE "^(NVIDIA|== )" $d/summary.txt 2>/dev/null | grep -vE "^\s*$" | tail -20; done
(cd $R/t_batch && tar xzf logs.tgz 2>/dev/null; grep -hE "lockstep|^test " $R/t_batch/*.log 2>/dev/null | tail -20)
echo "==== wedge"; cat $R/wedge.txt
echo "==== variants"; grep -vE "^(NVIDIA|== )" $R/var/summary.txt
echo "==== f64"; cat $R/f64.txt
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.ply' --exclude='*.vtu' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
