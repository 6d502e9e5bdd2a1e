#!/usr/bin/env bash
# Session 11, call 3 (one H200; binaries and wheel of main, see COMMIT; rtmpm_67ba962 the binary of the
# last call that timed the defaults): (1) the claymore scenes A/B against 67ba962, interleaved, to tell
# a change of code from a change of machine (call 2 read fluid 2M 0.3305 and snow 0.3025 ms/step against
# 0.2999-0.3021 and 0.2821 before, jelly unchanged); (2) the Python GPU batch loop after the batched
# poses and the puts without forced rebuilds (bench/python_batch_gpu.py with --breakdown), and the same
# benchmark with the wheel of 287e897 (before them) for the A/B; (3) the batch's put tests and the
# Python GPU batch tests.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0 PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
left() { echo $(( 540 - ($(date +%s) - T0) )); }
el "start, binaries of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader)"
B=$(cat $D/BUILD_DIR); [ -e "$B" ] || { mkdir -p "$(dirname "$B")" && ln -sfn "$PWD" "$B"; }
mkdir -p target/release && cp $D/rtmpm target/release/rtmpm
T() { local log=$1 name=$2 lim=$3; shift 3
  timeout $lim $D/$name --include-ignored --test-threads 1 --nocapture "$@" > $R/$log.log 2>&1
  echo "$log rc=$? (limit $lim s): $(grep -E '^test result' $R/$log.log | tail -1)" >> $R/sum_$log.txt
  grep -E "^test .*(ok|FAILED)$|FAILED|panicked|rebuild" $R/$log.log | head -20 >> $R/sum_$log.txt; }
# Phase 0: every program compiled at once on the 16 cores (the A/B's four, the batch tests' own).
for b in rtmpm rtmpm_67ba962; do for sc in fluid_dam_2m jelly_drop_2m; do
  timeout 200 $D/$b bench --backend cuda --scene bench/$sc.toml --steps 5 > $R/warm_${b}_$sc.log 2>&1 &
done; done
T batch test_batch 240 a_put_rebuilds_the_mapping_only_where_a_particle_leaves_its_zone \
  worlds_put_at_once_hold_what_one_put_a_world_leaves a_reset_or_blown_up_world_leaves_the_others_as_they_were &
wait; el "compiles + batch tests"
# Phase 1: A/B alone, interleaved.
L() { local label=$1; shift; local r; r=$(timeout 100 "$@" 2>&1); echo "== $label: $*" >> $R/ab.log; echo "$r" >> $R/ab.log
  echo "$label | $(echo "$r" | grep -oE '[0-9.]+ ms/step' | head -1) | $(echo "$r" | grep -E '^\s+(rebuild|p2g|grid_update|g2p2g) ' | awk '{printf "%s=%s ", $1, $2}') $(echo "$r" | grep -m1 -iE '^error')" >> $R/sum_ab.txt; }
for rep in 1 2; do for sc in fluid_dam_2m:10 snow_1m:20 jelly_drop_2m:5; do for b in rtmpm_67ba962 rtmpm; do
  L "${sc%%:*} $b #$rep" $D/$b bench --backend cuda --scene bench/${sc%%:*}.toml --frames ${sc##*:}
done; done; done
el "A/B"
ncu=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu /usr/local/cuda/bin/ncu 2>/dev/null | head -1)
for b in rtmpm_67ba962 rtmpm; do
  timeout 60 "$ncu" --kernel-name regex:'^g2p2g' --launch-skip 5 --launch-count 1 --set full \
    $D/$b bench --backend cuda --scene bench/fluid_dam_2m.toml --steps 20 > $R/ncu-fluid-$b.txt 2>&1
  echo "ncu fluid $b rc=$?" >> $R/sum_ab.txt
  grep -E "^  g2p2g|Duration|Issue Slots Busy|Registers Per|Local Memory Spilling Requests |Achieved Occupancy|L2 Hit Rate" $R/ncu-fluid-$b.txt | sed -E 's/ +/ /g' | head -9 >> $R/sum_ab.txt
done
el ncu
# Phase 2: the Python loop, new wheel then old.
# The wheels travel unpacked, their library stripped (the two wheels did not fit the call's 64 MiB).
for w in main 287e897; do rm -rf /tmp/site_$w; cp -a $D/site_$w /tmp/site_$w; done
l=$(left); PYTHONPATH=/tmp/site_main timeout $(( l < 170 ? l : 170 )) python3 bench/python_batch_gpu.py --worlds 256 --steps 200 \
  --per-call 1,10 --repeats 3 --budget 90 --breakdown --json $R/pyloop_main.json > $R/pyloop_main.txt 2>&1
echo "pyloop main rc=$?" >> $R/sum_py.txt; grep -vE "^\[|round|set-up" $R/pyloop_main.txt | tail -34 >> $R/sum_py.txt; el "pyloop main"
l=$(left); [ $l -gt 60 ] && { PYTHONPATH=/tmp/site_287e897 timeout $(( l - 40 < 120 ? l - 40 : 120 )) python3 bench/python_batch_gpu.py --worlds 256 --steps 200 \
  --per-call 1,10 --repeats 2 --budget 50 --json $R/pyloop_287e897.json > $R/pyloop_287e897.txt 2>&1
  echo "pyloop 287e897 rc=$?" >> $R/sum_py.txt; tail -14 $R/pyloop_287e897.txt >> $R/sum_py.txt; el "pyloop 287e897"; }
# Phase 3: the Python GPU batch tests with what is left.
l=$(left); [ $l -gt 20 ] && { PYTHONPATH=/tmp/site_main timeout $l python3 -m pytest -q -p no:cacheprovider crates/rtmpm-py/tests/test_batch_gpu.py > $R/pytest.log 2>&1
  echo "pytest test_batch_gpu.py rc=$?: $(tail -1 $R/pytest.log)" >> $R/sum_py.txt; grep -E "FAILED|Error|passed|failed" $R/pytest.log | head -8 >> $R/sum_py.txt; el pytest; }
{ cat $R/sum_*.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
