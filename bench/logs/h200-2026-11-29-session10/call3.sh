#!/usr/bin/env bash
# Session 10, call 3 (binaries of main 67ba962, wheel of 3113a15: the Python code is the same):
# the Python GPU batch step loop after the device rewind point and the remembered chunk
# (bench/python_batch_gpu.py, 256 worlds as measured before, then 1,024); the fused G2P2G's
# shared node halo (halo=sync|async, warp_list=sorted) against the default, and CK-MPM's new
# default, on the fluid dam 2M and the jelly 2M; the batch tests of the rewind point, the moving
# colliders per world, the Python GPU batch tests, the single-GPU kinematic tool's load.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( 510 - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
T() { local name=$1 lim=$2; shift 2
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$name.log 2>&1
  echo "$name rc=$? (limit $lim s): $(grep -E '^test result' $R/$name.log | tail -1)" >> $R/summary.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked" $R/$name.log | head -12 >> $R/summary.txt; }
python3 -m pip install -q --no-index --no-deps --target /tmp/site $D/wheels/*.whl && export PYTHONPATH=/tmp/site
timeout 150 python3 bench/python_batch_gpu.py --worlds 256 --steps 200 --per-call 1,10 --repeats 5 \
  --json $R/pyloop256.json > $R/pyloop256.txt 2>&1
echo "python_batch_gpu 256 worlds rc=$?" >> $R/summary.txt; tail -14 $R/pyloop256.txt >> $R/summary.txt
el pyloop256
KERNEL_AB_MLS="- halo=sync halo=async warp_list=sorted" KERNEL_AB_CK="ck_p2g=fused" REPS=1 \
  OUT=$R/kab timeout 170 bash scripts/gpu/run.sh kernel_ab > $R/kab.txt 2>&1
tail -9 $R/kab/summary.txt >> $R/summary.txt; el kernel_ab
T test_batch 90 many_calls_of_one_step_equal_one_call_of_as_many_steps a_blown_up_world_rewinds_to_the_device_point_as_to_the_hosts \
  the_lockstep_driver_runs_a_gpu_batch_and_freezes_a_blown_up_world a_resumed_gpu_batch_goes_on_as_the_uninterrupted_one
grep -E "bit-identical|calls of one step" $R/test_batch.log | head -6 >> $R/summary.txt; el batch
T test_batch_colliders 100; grep -E "step|world" $R/test_batch_colliders.log | tail -6 >> $R/summary.txt; el colliders
PYTHONUNBUFFERED=1 timeout 150 python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py \
  "crates/rtmpm-py/tests/test_gpu.py::test_a_single_gpu_run_reports_a_kinematic_tools_load_as_the_cpu" > $R/pytest.log 2>&1
echo "pytest test_batch_gpu.py + kinematic load rc=$?: $(tail -1 $R/pytest.log)" >> $R/summary.txt
grep -E "FAILED|Error" $R/pytest.log | head -8 >> $R/summary.txt; el pytest
l=$(left); [ $l -gt 20 ] && { T test_rigid $(( l < 100 ? l : 100 )) a_kinematic_tool_pushed_into_sand_feels_the_cpus_load_on_the_gpu;
  grep -E "mean force|reference" $R/test_rigid.log | head -4 >> $R/summary.txt; el rigid; }
l=$(left); [ $l -gt 40 ] && { timeout $l python3 bench/python_batch_gpu.py --worlds 1024 --steps 100 --per-call 1,10 --repeats 3 \
  --json $R/pyloop1024.json > $R/pyloop1024.txt 2>&1; echo "python_batch_gpu 1024 worlds rc=$?" >> $R/summary.txt;
  tail -14 $R/pyloop1024.txt >> $R/summary.txt; el pyloop1024; }
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
