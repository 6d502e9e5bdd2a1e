#!/usr/bin/env bash
# Session 8, call 4 (binaries of main 27e8ebf: CK-MPM's warp P2G the default, g2p_ck's addressing
# of dee31fb, the batch fixes of 012f7a8): the GPU batch tests (incl. the resumed GPU batch) with
# a longer limit than call 3's 130 s, the rigid-body tests on one GPU (step/rigid.rs split into
# BodyLink and Bodies for several GPUs), then the CK-MPM agreement with the default warp P2G and the
# fused G2P2G at 100 steps; the granular column with CK-MPM as the case now runs it (RTMPM_AGREEMENT_STEPS; the default is 300).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
T() { local name=$1 lim=$2; shift 2
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$name.log 2>&1
  echo "$name rc=$? (limit $lim s): $(grep -E '^test result' $R/$name.log | tail -1)" >> $R/summary.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked" $R/$name.log | head -12 >> $R/summary.txt; }
T test_batch 210 --skip batch_benchmark; el batch
T test_rigid 90; el rigid
timeout 60 $D/rtmpm validate --backend cuda --case granular_column_ck --out $R/gran > $R/gran.log 2>&1
echo "validate granular_column_ck (full resolution, the case as it is now) rc=$?" >> $R/summary.txt
grep -E "PASS|FAIL|moves|passed" $R/gran.log >> $R/summary.txt; el granular
left=$(( 440 - ($(date +%s) - T0) ))
RTMPM_AGREEMENT_STEPS=100 RTMPM_CK_AGREEMENT="ck_p2g=warp;ck_p2g=fused" T test_agreement $left cuda_agrees_with_cpu_with_ck_mpm
grep -E "ck-mpm" $R/test_agreement.log >> $R/summary.txt; el ck_agreement
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
