#!/usr/bin/env bash
# Session 11, call 6 (one H200; rtmpm built from main after the last kernel change of the session,
# 5c35ad9's removal of the lost experiments): the claymore scenes with the defaults, twice.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
echo "binary of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader)" > $R/report.txt
for rep in 1 2; do for sc in fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20; do
  r=$(timeout 120 $D/rtmpm bench --backend cuda --scene bench/${sc%%:*}.toml --frames ${sc##*:} 2>&1); echo "$r" >> $R/bench.log
  echo "${sc%%:*} #$rep | $(echo "$r" | grep -oE '[0-9.]+ ms/step' | head -1) | $(echo "$r" | grep -m1 throughput | tr -s ' ') $(echo "$r" | grep -m1 -iE '^error')" >> $R/report.txt
done; done
cat $R/report.txt
