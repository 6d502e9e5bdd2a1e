#!/usr/bin/env bash
# Session 14, call 2 (two H200s; binaries of main, see COMMIT). Phase 1, one lane a GPU:
# GPU 0 the per-kernel-set defaults (fused_defaults=auto) and the idle lanes' stencil base:
# test_addressing (all), CPU agreement with auto, memcheck with auto and with every cut;
# GPU 1 programmatic dependent launch (pdl=on): test_pdl, compute-sanitizer with pdl=on.
# Phase 2, one lane a GPU, timings (graph replay), interleaved, two rounds: GPU 0 fused_defaults
# off / auto / the explicit planes+cuts; GPU 1 pdl off / on (and auto+pdl on the fluid).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( ${1:-565} - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1); nproc $(nproc)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
CS=$(command -v compute-sanitizer || ls /usr/local/cuda/bin/compute-sanitizer /opt/nvidia/*/compute-sanitizer 2>/dev/null | head -1)
ALL=row_unroll=planes,seg_clamp=on,zero_terms=skip,flat_checks=on,state_index=wide,lean_lanes=on
REF=row_unroll=planes,seg_clamp=on,zero_terms=skip,flat_checks=on,state_index=wide
( export CUDA_VISIBLE_DEVICES=0
  ( timeout 300 $D/test_addressing --include-ignored --test-threads 1 --nocapture > $R/addressing.log 2>&1
    echo "addressing rc=$?: $(grep -E '^test result' $R/addressing.log)" >> $R/sum_a.txt
    grep -E "compiled in|Auto|FAILED|panicked|rerun" $R/addressing.log | cut -c1-200 | head -30 >> $R/sum_a.txt; el addressing ) &
  ( RTMPM_AGREEMENT_OPTIONS=fused_defaults=auto timeout 300 $D/test_agreement --include-ignored --test-threads 1 cuda_agrees_with_cpu_on_every_example_scene > $R/agree_auto.log 2>&1
    echo "agreement fused_defaults=auto rc=$?: $(grep -E '^test result' $R/agree_auto.log)" >> $R/sum_b.txt; el agreement ) &
  ( for sc in fluid_dam_2m jelly_drop_2m snow_1m; do for o in fused_defaults=off fused_defaults=auto $ALL $REF; do
      timeout 200 $D/rtmpm bench --backend cuda --scene bench/$sc.toml --steps 2 --cuda-options $o > /dev/null 2>&1 &
    done; done; wait; el "kernel sets compiled"
    for sc in fluid_dam_2m jelly_drop_2m; do for o in fused_defaults=auto $ALL; do
      ( timeout 250 $CS --tool memcheck --error-exitcode 9 $D/rtmpm bench --backend cuda --scene bench/$sc.toml --steps 10 --cuda-options $o > $R/mc_${sc}_${o%%=*}.log 2>&1
        echo "memcheck $sc $o rc=$?: $(grep -m1 'ERROR SUMMARY' $R/mc_${sc}_${o%%=*}.log)" >> $R/sum_c.txt ) &
    done; done; wait; el memcheck ) &
  wait ) &
( export CUDA_VISIBLE_DEVICES=1
  timeout 400 $D/test_pdl --include-ignored --nocapture > $R/pdl.log 2>&1
  echo "test_pdl rc=$?: $(grep -E '^test result' $R/pdl.log)" >> $R/sum_p.txt
  grep -E "FAILED|panicked|max|rerun" $R/pdl.log | cut -c1-200 | head -20 >> $R/sum_p.txt; el test_pdl
  for tool in memcheck synccheck racecheck; do
    timeout 120 $CS --tool $tool --error-exitcode 9 $D/rtmpm bench --backend cuda --n 32 --steps 20 --cuda-options pdl=on > $R/cs_pdl_$tool.log 2>&1
    echo "$tool n=32 pdl=on rc=$?: $(grep -hE 'ERROR SUMMARY|RACECHECK SUMMARY' $R/cs_pdl_$tool.log | tail -1)" >> $R/sum_p.txt
  done
  timeout 150 $CS --tool memcheck --error-exitcode 9 $D/rtmpm bench --backend cuda --scene bench/snow_1m.toml --steps 5 --cuda-options pdl=on > $R/cs_pdl_snow.log 2>&1
  echo "memcheck snow pdl=on rc=$?: $(grep -hE 'ERROR SUMMARY' $R/cs_pdl_snow.log | tail -1)" >> $R/sum_p.txt
  for sc in fluid_dam_2m jelly_drop_2m snow_1m; do for o in pdl=on fused_defaults=auto,pdl=on; do
    timeout 200 $D/rtmpm bench --backend cuda --scene bench/$sc.toml --steps 2 --cuda-options $o > /dev/null 2>&1 &
  done; done; wait; el "pdl sanitizer + compiles" ) &
wait; el "phase 1"
b() { local f=$1 label=$2; shift 2; local r; r=$(timeout 60 $D/rtmpm bench --backend cuda "$@" 2>&1)
  echo "== $label: $*" >> $R/bench.log; echo "$r" >> $R/bench.log
  printf '%-50s %s %s\n' "$label" "$(echo "$r" | grep -oE '\(([0-9.]+) ms/step\)' | head -1)" "$(echo "$r" | grep -E '^error' | head -1)" >> $R/$f; }
( export CUDA_VISIBLE_DEVICES=0
  for rep in 1 2; do for sf in fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20; do for fd in off auto; do
    [ $(left) -gt 10 ] && b sum_d.txt "${sf%%:*} fused_defaults=$fd #$rep" --scene bench/${sf%%:*}.toml --frames ${sf##*:} --cuda-options fused_defaults=$fd
  done; done; [ $(left) -gt 10 ] && b sum_d.txt "fluid_dam_2m explicit planes+CUTS #$rep" --scene bench/fluid_dam_2m.toml --frames 10 --cuda-options $REF; done; el "fused_defaults A/B" ) &
( export CUDA_VISIBLE_DEVICES=1
  for rep in 1 2; do for sf in fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20; do for o in pdl=off pdl=on; do
    [ $(left) -gt 10 ] && b sum_e.txt "${sf%%:*} $o #$rep" --scene bench/${sf%%:*}.toml --frames ${sf##*:} --cuda-options $o
  done; [ $(left) -gt 10 ] && b sum_e.txt "${sf%%:*} auto,pdl=on #$rep" --scene bench/${sf%%:*}.toml --frames ${sf##*:} --cuda-options fused_defaults=auto,pdl=on
  done; done; el "pdl A/B" ) &
wait
# Phase 3, both GPUs: the scaling benchmarks with pdl off / on, interleaved.
for rep in 1 2; do for o in pdl=off pdl=on; do
  [ $(left) -gt 20 ] && b sum_f.txt "weak gpus=1 $o #$rep" --scene bench/weak_4m_x1.toml --frames 4 --cuda-options $o
  [ $(left) -gt 20 ] && b sum_f.txt "weak gpus=2 $o #$rep" --scene bench/weak_4m_x2.toml --frames 4 --gpus 2 --cuda-options $o
  [ $(left) -gt 20 ] && b sum_f.txt "strong gpus=2 $o #$rep" --scene bench/strong_16m.toml --frames 2 --gpus 2 --cuda-options $o
done; done; el "scaling pdl A/B"
{ head -1 $R/times.txt; cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
