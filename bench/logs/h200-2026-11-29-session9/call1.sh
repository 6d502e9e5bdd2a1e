#!/usr/bin/env bash
# Session 9, call 1 (binaries of main 77313bf = fa2dddf + `rtmpm validate --cuda-options`):
# 1. the rigid-body tests on one GPU in full (the f64 momentum variant was cut at 90 s in session 8);
# 2. compute-sanitizer memcheck on the CK-MPM kernels (warp P2G, fused G2P2G) and a rigid scene;
# 3. the CK-MPM validation cases with the default warp P2G and with the fused G2P2G;
# 4. the CK-MPM agreement with the fused G2P2G at the full 300 steps (what it needs to be a default).
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
T test_rigid 200; el rigid
cs=$(command -v compute-sanitizer || ls /usr/local/cuda/bin/compute-sanitizer 2>/dev/null | head -1)
cp bench/fluid_dam_2m.toml /tmp/fluid_ck.toml; printf '\n[solver]\ntransfer = "ck-mpm"\n' >> /tmp/fluid_ck.toml
for o in ck_p2g=warp ck_p2g=fused; do
  timeout 120 "$cs" --tool memcheck --error-exitcode 9 $D/rtmpm bench --backend cuda --scene /tmp/fluid_ck.toml \
    --steps 10 --cuda-options $o > $R/memcheck-$o.log 2>&1
  echo "memcheck CK fluid dam 2M $o, 10 steps rc=$?: $(grep -E 'ERROR SUMMARY' $R/memcheck-$o.log | tail -1)" >> $R/summary.txt
done
timeout 120 "$cs" --tool memcheck --error-exitcode 9 $D/rtmpm run scenes/rigid/floating_box.toml --backend cuda \
  --steps 40 --no-output > $R/memcheck-rigid.log 2>&1
echo "memcheck floating_box 40 steps rc=$?: $(grep -E 'ERROR SUMMARY' $R/memcheck-rigid.log | tail -1)" >> $R/summary.txt
el sanitizer
for o in ck_p2g=warp ck_p2g=fused; do
  timeout 90 $D/rtmpm validate --backend cuda --case hydrostatic_column_ck,vibrating_bar_ck,dam_break_ck,granular_column_ck \
    --cuda-options $o --out $R/val-$o > $R/validate-$o.log 2>&1
  echo "validate CK cases $o rc=$?" >> $R/summary.txt
  grep -E "PASS|FAIL|passed|could not" $R/validate-$o.log | sed -E 's/ +/ /g' >> $R/summary.txt
done
el validate
left=$(( 560 - ($(date +%s) - T0) ))
RTMPM_CK_AGREEMENT="ck_p2g=fused" T test_agreement $left cuda_agrees_with_cpu_with_ck_mpm
grep -E "ck-mpm" $R/test_agreement.log >> $R/summary.txt; el ck_agreement
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
