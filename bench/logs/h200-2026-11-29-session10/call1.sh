#!/usr/bin/env bash
# Session 10, call 1 (binaries of main dcd7ef8): the GPU batch with per-world colliders
# (tests/batch_colliders.rs, unfinished in 60 s last time: given 200 s here) and the batch tests
# (tests/batch.rs, without its benchmark); CK-MPM fused with ck_bound=5,ck_grid=resident against
# the fused default on the fluid dam 2M and the jelly 2M (two repetitions, interleaved); Nsight
# Compute on CK-MPM's fused G2P2G (g2p2g_ck) on the fluid dam 2M.
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
T test_batch_colliders 200; el batch_colliders
T test_batch 150 --skip batch_benchmark; el batch
KERNEL_AB_MLS="-" KERNEL_AB_CK="ck_p2g=fused ck_p2g=fused,ck_bound=5,ck_grid=resident" REPS=2 \
  OUT=$R/kab timeout 200 bash scripts/gpu/run.sh kernel_ab > $R/kab.txt 2>&1
tail -8 $R/kab/summary.txt >> $R/summary.txt; el kernel_ab
cp bench/fluid_dam_2m.toml bench/fluid_dam_2m_ck.toml
printf '\n[solver]\ntransfer = "ck-mpm"\n' >> bench/fluid_dam_2m_ck.toml
PROFILE_RUNS="ck|rtmpm||fluid_dam_2m_ck" OUT=$R/prof timeout 150 bash scripts/gpu/run.sh profile > $R/prof.txt 2>&1
cat $R/prof/summary.txt >> $R/summary.txt; el profile
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
