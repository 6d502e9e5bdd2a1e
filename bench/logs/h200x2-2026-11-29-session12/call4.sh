#!/usr/bin/env bash
# Session 12, call 4 (one H200; binaries of main, see COMMIT): the fused kernels' new defaults (pair
# addressing of the stencil nodes, c66cac4; the warp loop over warp-uniform values, b3fac42) against the
# kernels before them in the same binary (--cuda-options addressing=blocks,uniform_loop=off: main's PTX
# before both, byte for byte) on the claymore scenes, interleaved; then, in two lanes on the GPU (tests,
# not timings): the addressing tests and the CPU/GPU agreement on every example scene; the one-GPU-twice
# rigid test under its new tolerance, the batch rigid tests (sums and poses kept, add0a59 and 2b55b45) and
# compute-sanitizer memcheck of the fused step with the new kernels.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( $1 - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
SC="fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20"
OLD="addressing=blocks,uniform_loop=off"
for sf in $SC; do for o in "" "--cuda-options $OLD"; do
  timeout 150 $D/rtmpm bench --backend cuda --scene bench/${sf%%:*}.toml --steps 2 $o > /dev/null 2>&1 &
done; done; wait
el "kernels compiled"
b() { local label=$1; shift
  local r; r=$(timeout 100 $D/rtmpm bench --backend cuda "$@" 2>&1)
  echo "== $label: $*" >> $R/bench.log; echo "$r" >> $R/bench.log
  printf '%-34s %s %s\n' "$label" "$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1)" "$(echo "$r" | grep -E '^error' | head -1)" >> $R/sum_abench.txt; }
for rep in 1 2; do for sf in $SC; do
  b "${sf%%:*} old: $OLD #$rep" --scene bench/${sf%%:*}.toml --frames ${sf##*:} --cuda-options $OLD
  b "${sf%%:*} new default #$rep" --scene bench/${sf%%:*}.toml --frames ${sf##*:}
done; done
el "bench"
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|differs|twice #|bit for bit|identical" $R/$log.log | cut -c1-260 | head -30 >> $R/sum_$log.txt; }
( T c_agree test_agreement $(left 550) cuda_agrees_with_cpu_on_every_example_scene
  el lane_agree ) &
( T b_addr test_addressing $(left 540)
  T d_twice test_multi_gpu_rigid $(left 560) one_gpu_twice_agrees_with_itself_on_the_rigid_scenes
  el lane_addr ) &
( T e_brigid test_batch_rigid 200
  cs=$(command -v compute-sanitizer || ls /usr/local/cuda/bin/compute-sanitizer 2>/dev/null | head -1)
  for a in "--scene bench/snow_1m.toml --steps 20" "--n 64 --steps 20"; do
    [ $(left 520) -gt 30 ] || break
    timeout $(left 540) "$cs" --tool memcheck --error-exitcode 9 $D/rtmpm bench --backend cuda $a > $R/memcheck.log 2>&1
    echo "memcheck rtmpm bench $a rc=$?: $(grep -E 'ERROR SUMMARY' $R/memcheck.log | tail -1)" >> $R/sum_f_memcheck.txt
  done
  el lane_rigid_memcheck ) &
wait
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
