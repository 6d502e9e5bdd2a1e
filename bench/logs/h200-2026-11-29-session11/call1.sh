#!/usr/bin/env bash
# Session 11, call 1 (one H200: the 4- and 2-GPU kinds were withdrawn before the call; binaries of main,
# see COMMIT): the single-GPU checks left open, in two lanes on the one GPU at the same time (tests, not
# timings): the agreement after the node-placement change; the kinematic tool's load in both fast-math
# modes, the batch pusher and freeze tests.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binaries of $(cat .device/COMMIT)"
nvidia-smi -L > $R/gpus.txt; nvidia-smi topo -m >> $R/gpus.txt 2>&1
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
# T log-name binary limit args...: one test binary, its result lines into the lane's summary.
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked" $R/$log.log | head -30 >> $R/sum_$log.txt; }
( T agree test_agreement 380 cuda_agrees_with_cpu_on_every_example_scene cuda_agrees_with_cpu_on_the_rigid_body_scenes
  el lane_agree ) &
( T rigid test_rigid 140 a_kinematic_tool_pushed_into_sand_feels_the_cpus_load_on_the_gpu
  grep -hE "mean force|reference" $R/rigid.log | head -6 >> $R/sum_rigid.txt
  T pusher test_batch_colliders 120 worlds_whose_pushers_move_differently_agree_with_their_cuda_and_cpu_runs
  T freeze test_batch 140 the_lockstep_driver_runs_a_gpu_batch_and_freezes_a_blown_up_world worlds_put_at_once_hold_what_one_put_a_world_leaves
  el lane_rigid_batch ) &
wait; el "tests done"
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
