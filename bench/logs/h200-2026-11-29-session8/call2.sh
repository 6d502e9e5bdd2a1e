#!/usr/bin/env bash
# Session 8, call 2 (binaries of main 03a3472): the multi-GPU code with two ranks on one GPU
# (devices=0:0), incl. rigid bodies on several GPUs and the bad-particle report (`multi1`); then the
# CK-MPM warp-reduced P2G (ck_p2g=warp): its agreement with the CPU and ms/step against the direct
# kernel and MLS-MPM (`ck_speed`).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
OUT=$R/multi1 TEST_TIMEOUT=230 timeout 300 bash scripts/gpu/run.sh multi1 > /dev/null 2>&1; el multi1
left=$(( 585 - ($(date +%s) - T0) ))
OUT=$R/ck TEST_TIMEOUT=$(( left - 120 )) timeout $left bash scripts/gpu/run.sh ck_speed > /dev/null 2>&1; el ck_speed
{
for d in $R/multi1 $R/ck; do [ -d $d ] || continue; echo "==== $(basename $d)"; grep -vE "^(NVIDIA|== )" $d/summary.txt 2>/dev/null | grep -vE "^\s*$" | tail -70; done
cat $R/times.txt
} > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.ply' --exclude='*.vtu' --exclude='*.vtk' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
