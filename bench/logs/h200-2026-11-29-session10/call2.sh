#!/usr/bin/env bash
# Session 10, call 2 (binaries of main dcd7ef8): CK-MPM's fused kernel with ck_bound=5,ck_grid=resident
# (call 1: -4.9 % fluid, -2.6 % jelly) checked before it becomes CK-MPM's f32 default: the four CK
# validation cases at full resolution, compute-sanitizer memcheck on the CK fluid dam 2M, the
# agreement test against the CPU reference (four scenes, 300 steps, f32 and f64) with the switches.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
T() { local name=$1 lim=$2; shift 2
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$name.log 2>&1
  echo "$name rc=$? (limit $lim s): $(grep -E '^test result' $R/$name.log | tail -1)" >> $R/summary.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked" $R/$name.log | head -12 >> $R/summary.txt; }
O=ck_p2g=fused,ck_bound=5,ck_grid=resident
timeout 120 $D/rtmpm validate --backend cuda --case hydrostatic_column_ck,vibrating_bar_ck,dam_break_ck,granular_column_ck \
  --cuda-options $O --out $R/val > $R/validate.log 2>&1
echo "validate CK cases $O rc=$?" >> $R/summary.txt
grep -E "PASS|FAIL|passed|could not" $R/validate.log | sed -E 's/ +/ /g' >> $R/summary.txt
el validate
cp bench/fluid_dam_2m.toml bench/fluid_dam_2m_ck.toml
printf '\n[solver]\ntransfer = "ck-mpm"\n' >> bench/fluid_dam_2m_ck.toml
cs=$(command -v compute-sanitizer || ls /usr/local/cuda/bin/compute-sanitizer 2>/dev/null | head -1)
timeout 120 "$cs" --tool memcheck --error-exitcode 9 $D/rtmpm bench --backend cuda --scene bench/fluid_dam_2m_ck.toml \
  --steps 10 --cuda-options $O > $R/memcheck.log 2>&1
echo "memcheck CK fluid dam 2M $O, 10 steps rc=$?: $(grep -E 'ERROR SUMMARY' $R/memcheck.log | tail -1)" >> $R/summary.txt
el memcheck
RTMPM_CK_AGREEMENT="$O" T test_agreement 420 cuda_agrees_with_cpu_with_ck_mpm
grep -E "ck-mpm" $R/test_agreement.log >> $R/summary.txt
el agreement
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
