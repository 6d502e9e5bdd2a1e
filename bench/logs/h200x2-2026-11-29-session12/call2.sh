#!/usr/bin/env bash
# Session 12, call 2 (two H200s, binaries of main c7515ff): is exchange=push with overlap=off a safe and
# faster default for two GPUs? (call 1: weak 4.2M a GPU 0.5913-0.5943 ms/step against the default's
# 0.6187-0.6216). The agreement test on every example scene in those modes, then strong 16.8M with
# every combination interleaved (REPS 2), then weak once more with the combinations.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|runs of|skipped" $R/$log.log | head -30 >> $R/sum_$log.txt; }
RTMPM_MULTI_GPU_MODES="transport=p2p,barrier=spin,exchange=push,overlap=off;transport=p2p,barrier=spin,overlap=off" \
  T agree_push_off test_multi_gpu_agreement 200 several_gpus_agree_with_one_on_every_example_scene
el agree
RTMPM_MULTI_GPU_OPTIONS="exchange=push,overlap=off" T rigid_push_off test_multi_gpu_rigid 120
el rigid
b() { local label=$1; shift
  local r; r=$(timeout 120 $D/rtmpm bench --backend cuda "$@" 2>&1)
  echo "== $label: $*" >> $R/bench.log; echo "$r" >> $R/bench.log
  printf '%-34s %s | %s\n' "$label" "$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1)" "$(echo "$r" | grep -E 'reduction|^error' | head -1 | cut -c1-60)" >> $R/sum_zbench.txt; }
for rep in 1 2; do
  [ $(( $(date +%s) - T0 )) -lt 470 ] || break
  b "strong 16.8M gpus=1 #$rep" --scene bench/strong_16m.toml --frames 2
  for o in exchange=kernels overlap=off exchange=push exchange=push,overlap=off; do
    b "strong gpus=2 $o #$rep" --scene bench/strong_16m.toml --frames 2 --gpus 2 --cuda-options $o
  done
done
el strong
for rep in 1 2; do
  [ $(( $(date +%s) - T0 )) -lt 530 ] || break
  b "weak 4.2M gpus=1 #$rep" --scene bench/weak_4m_x1.toml --frames 4
  for o in exchange=kernels exchange=push,overlap=off; do
    b "weak gpus=2 $o #$rep" --scene bench/weak_4m_x2.toml --frames 4 --gpus 2 --cuda-options $o
  done
done
el weak
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
