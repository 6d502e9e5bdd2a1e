#!/usr/bin/env bash
# Session 7, call 2: the live view's cost with `mb5r` (resident G2P2G grid + 96 registers) on, the
# view suite (render stage vs compute, step time with the view off / on with overlap / on without);
# then the A/B, interleaved twice: defaults vs mb5r on the claymore scenes and the dam with ten
# static colliders, and the build before the shape vocabulary (rtmpm_base) on the same scenes.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
printf '#!/bin/sh\nRTMPM_G2P2G_GRID=resident exec "$(dirname "$0")/rtmpm" "$@"\n' > $D/rtmpm_res; chmod +x $D/rtmpm_res
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT), base $(cat .device/BASE_COMMIT 2>/dev/null)"
( export RTMPM_G2P2G_GRID=resident RTMPM_KERNEL_DEFINES="-DG2P2G_MIN_BLOCKS=5 -DG2P2G_FLUID_MIN_BLOCKS=5"
  OUT=$R/view timeout 300 bash scripts/gpu/run.sh view > /dev/null 2>&1 ); el view
V="base|rtmpm|| mb5r|rtmpm_res|-DG2P2G_MIN_BLOCKS=5,-DG2P2G_FLUID_MIN_BLOCKS=5 before_shapes|rtmpm_base||"
OUT=$R/var REPS=2 VARIANTS="$V" VARIANT_SCENES="fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20 fluid_dam_2m_colliders:3" \
  timeout 250 bash scripts/gpu/run.sh variants > /dev/null 2>&1; el variants
{
for d in $R/view $R/var; do [ -d $d ] || continue; echo "==== $(basename $d)"; grep -vE "^(NVIDIA|== )" $d/summary.txt 2>/dev/null | grep -vE "^\s*$" | tail -60; done
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.vtu' --exclude='*.vtk' --exclude='*.ply' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
