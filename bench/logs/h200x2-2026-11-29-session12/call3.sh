#!/usr/bin/env bash
# Session 12, call 3 (two H200s, binaries of main, see COMMIT): the new default of two GPUs of one
# process (p2p, spin barrier: exchange=push without the overlap) through every multi-GPU test, the
# one-GPU-twice spread of the rigid scenes (is the NCCL floating_box miss of call 2 within what one GPU
# does run to run?), the rigid comparison twice more, then weak and strong: the new default against
# the old one spelled out (exchange=kernels,overlap=on), interleaved. pose38's batch test at the end.
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
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|runs of|runs compared|skipped|differs\"|twice #" $R/$log.log | cut -c1-330 | head -40 >> $R/sum_$log.txt; }
T a_agree test_multi_gpu_agreement 260
el agree
T b_errors test_multi_gpu_errors 100
T c_rigid test_multi_gpu_rigid 150
el rigid
T d_twice test_multi_gpu_rigid 150 one_gpu_twice_agrees_with_itself_on_the_rigid_scenes
el twice
for k in 2 3; do T e_rigid$k test_multi_gpu_rigid 100 several_gpus_agree_with_one_on_the_rigid_scenes; done
el rigid_again
T f_cli test_multi_gpu_cli 150
el cli
b() { local label=$1; shift
  local r; r=$(timeout 120 $D/rtmpm bench --backend cuda "$@" 2>&1)
  echo "== $label: $*" >> $R/bench.log; echo "$r" >> $R/bench.log
  printf '%-44s %s | %s\n' "$label" "$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1)" "$(echo "$r" | grep -E 'reduction|^error' | head -1 | cut -c1-70)" >> $R/sum_zbench.txt; }
for rep in 1 2; do
  [ $(( $(date +%s) - T0 )) -lt 470 ] || break
  b "weak 4.2M gpus=1 #$rep" --scene bench/weak_4m_x1.toml --frames 4
  b "weak gpus=2 default #$rep" --scene bench/weak_4m_x2.toml --frames 4 --gpus 2
  b "weak gpus=2 exchange=kernels,overlap=on #$rep" --scene bench/weak_4m_x2.toml --frames 4 --gpus 2 --cuda-options exchange=kernels,overlap=on
  b "strong 16.8M gpus=1 #$rep" --scene bench/strong_16m.toml --frames 2
  b "strong gpus=2 default #$rep" --scene bench/strong_16m.toml --frames 2 --gpus 2
  b "strong gpus=2 exchange=kernels,overlap=on #$rep" --scene bench/strong_16m.toml --frames 2 --gpus 2 --cuda-options exchange=kernels,overlap=on
done
el bench
[ $(( $(date +%s) - T0 )) -lt 540 ] && T g_batch_rigid test_batch_rigid 50 loads_read_from_the_device
el end
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
