#!/usr/bin/env bash
# Session 7, call 4 (binaries of main 77d258c + the CK-MPM CUDA branch f7aa567, merged): the `ck`
# suite (CK-MPM against the CPU reference, the *_ck validation cases on the GPU, ms/step against
# MLS-MPM), then the f64 step with the f64 register bounds restored (against dd5a792's figures:
# fluid 0.741 before / 0.988 with the f32 bounds) and the f32 defaults once.
# (Run as it is here with the run.sh of that branch copied beside it; main has the `ck` suite since c1a4006.)
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
OUT=$R/ck TEST_TIMEOUT=200 timeout 400 bash scripts/gpu/run.sh ck > /dev/null 2>&1; el ck
for sc in fluid_dam_2m:5 jelly_drop_2m:3; do for p in f64 f32; do
  r=$(timeout 100 $D/rtmpm bench --backend cuda --precision $p --scene bench/${sc%%:*}.toml --frames ${sc##*:} 2>&1)
  echo "$r" >> $R/prec.log
  printf '%s %-14s %s\n' $p "${sc%%:*}" "$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1)" >> $R/prec.txt
done; done; el precision
{
echo "==== ck"; grep -vE "^(NVIDIA|== )" $R/ck/summary.txt
echo "==== precision"; cat $R/prec.txt
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.ply' --exclude='*.vtu' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
