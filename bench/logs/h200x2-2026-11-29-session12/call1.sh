#!/usr/bin/env bash
# Session 12, call 1 (two H200s, binaries of main, see COMMIT): the multi-GPU checks that only two real
# GPUs can do: the agreement and error tests on two GPUs (p2p + spin barrier, the default, after the spin
# lock's move), rigid bodies through NCCL ranks and --rendezvous processes (multi_rigid), the fused and
# pushed exchanges against one GPU, then the weak-scaling A/B of the exchange (REPS=2, no strong runs).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
nvidia-smi -L > $R/gpus.txt; nvidia-smi topo -m >> $R/gpus.txt 2>&1; head -3 $R/gpus.txt
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|runs of|skipped" $R/$log.log | head -30 >> $R/sum_$log.txt; }
T magree test_multi_gpu_agreement 240
el magree
T merrors test_multi_gpu_errors 100
el merrors
mkdir -p $R/runsh
OUT=$R/runsh timeout 200 bash scripts/gpu/run.sh multi_rigid > $R/multi_rigid.out 2>&1
echo "multi_rigid rc=$?" >> $R/sum_multi_rigid.txt; cat $R/runsh/summary.txt >> $R/sum_multi_rigid.txt 2>/dev/null
el multi_rigid
left=$(( 560 - ($(date +%s) - T0) ))
mkdir -p $R/runsh2
if [ $left -gt 60 ]; then
  OUT=$R/runsh2 REPS=2 EXCHANGE_STRONG=0 timeout $left bash scripts/gpu/run.sh exchange > $R/exchange.out 2>&1
  echo "exchange rc=$? (limit $left s)" >> $R/sum_xchange.txt; cat $R/runsh2/summary.txt >> $R/sum_xchange.txt 2>/dev/null
fi
el exchange
{ cat $R/gpus.txt | head -3; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
