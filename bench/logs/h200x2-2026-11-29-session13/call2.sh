#!/usr/bin/env bash
# Session 13, call 2 (two H200s; the 4-GPU machine was no longer lent; binaries and wheel of main, see
# COMMIT). Correctness only, everything at once (tests share the GPUs; no timings in this call):
# GPU 0: the batch tests after the host-wait cuts (waits, resets; rewind, colliders, lockstep) and
#        every validation case on the GPU (after the kernel defaults of b3fac42);
# GPU 1: the batch rigid test, the Python GPU batch tests (and with every batch in overlap),
#        test_addressing (the second round of cuts bit-identical), the CPU agreement with the cuts,
#        test_gpu and test_materials (the step parameters' upload changed, a70e062);
# both:  the new exchanges (push_update, list_push_update) against one GPU, and the rigid comparison.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 TORCH_SYMM_MEM_DISABLE_MULTICAST=1 NVSHMEM_DISABLE_NVLS=1 PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-505} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1); $(nvidia-smi -L | wc -l) GPUs"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
PY() { PYTHONPATH=/tmp/site_main timeout "$@"; }
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|runs of|skipped|first step differs|aggregates differ|waits check|frozen per call|timed out|differs|rerun" $R/$log.log | cut -c1-240 | head -24 >> $R/sum_$log.txt; }
CUTS=seg_clamp=on,zero_terms=skip,flat_checks=on,state_index=wide
( T xagree test_multi_gpu_agreement $(left) the_fused_and_pushed_exchanges_agree_with_one_gpu; el xagree
  T xrigid test_multi_gpu_rigid $(left) several_gpus_agree_with_one_on_the_rigid_scenes; el xrigid ) &
( export CUDA_VISIBLE_DEVICES=0; T waits test_batch_waits $(left); T resets test_batch_resets $(left); el "waits, resets" ) &
( export CUDA_VISIBLE_DEVICES=0; T rewind test_batch_rewind $(left); T colliders test_batch_colliders $(left); T lockstep test_batch_lockstep $(left); el "rewind, colliders, lockstep" ) &
( export CUDA_VISIBLE_DEVICES=0
  timeout $(left) $D/rtmpm validate --backend cuda --out $R/validation > $R/validate.log 2>&1
  echo "validate --backend cuda rc=$?" >> $R/sum_validate.txt; grep -E "passed|FAIL" $R/validate.log | sed -E 's/ +/ /g' | tail -12 >> $R/sum_validate.txt; el validate ) &
( export CUDA_VISIBLE_DEVICES=1; T rigid test_batch_rigid $(left); el "batch rigid" ) &
( export CUDA_VISIBLE_DEVICES=1
  PY $(left) python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
  echo "pytest test_batch_gpu.py rc=$?: $(tail -1 $R/pytest.log)" >> $R/sum_pytest.txt; grep -E "FAILED|Error|XPASS" $R/pytest.log | head -8 >> $R/sum_pytest.txt
  RTMPM_BATCH_OVERLAP=1 PY $(left) python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest_overlap.log 2>&1
  echo "RTMPM_BATCH_OVERLAP=1 pytest rc=$?: $(tail -1 $R/pytest_overlap.log)" >> $R/sum_pytest.txt; grep -E "FAILED|Error|XPASS" $R/pytest_overlap.log | head -8 >> $R/sum_pytest.txt
  T gpu test_gpu $(left); el "pytest, test_gpu" ) &
( export CUDA_VISIBLE_DEVICES=1; T addressing test_addressing $(left); T materials test_materials $(left); el "addressing, materials" ) &
( export CUDA_VISIBLE_DEVICES=1
  RTMPM_AGREEMENT_OPTIONS="$CUTS,lean_lanes=on,row_unroll=planes" T agree_cuts test_agreement $(left) cuda_agrees_with_cpu_on_every_example_scene; el "agreement with the cuts" ) &
wait; el all
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude='*.png' --exclude='*.vtu' --exclude='*.vtk' --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
