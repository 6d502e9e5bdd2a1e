#!/usr/bin/env bash
# Session 14, call 1 (one H200; wheel of main, see COMMIT): py-spy --native samples of the Python
# GPU batch loop (256 worlds of 1,024 particles; 4 resets and 256 poses a call) by mode, to see
# where the host's own time a call goes.
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache PYTHONUNBUFFERED=1
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, wheel of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader | head -1); nproc $(nproc)"
rm -rf /tmp/site_main; cp -a $D/site_main /tmp/site_main
python3 -m pip install --no-index --no-deps -q -t /tmp/pyspy $D/py_spy*.whl 2>&1 | tail -2
SPY=$(ls /tmp/pyspy/bin/py-spy 2>/dev/null || find /tmp/pyspy -name py-spy -type f | head -1); chmod +x $SPY
el "py-spy: $SPY $($SPY --version 2>&1)"
P=bench/logs/h200-2026-11-29-session14/profile_loop.py
# Warm-up: kernel compiles into the cache.
PYTHONPATH=/tmp/site_main timeout 120 python3 $P loop 10 2 > $R/warm.txt 2>&1; el "warm rc=$?"
for v in "loop 10 --overlap" "loop 10" "reset 1" "pose 1" "calls 1"; do
  n=$(echo $v | tr ' ' '_' | tr -d '-')
  PYTHONPATH=/tmp/site_main timeout 60 $SPY record --native --rate 1000 --format raw -o $R/$n.raw -- python3 $P ${v% --overlap} 12 $( [[ $v == *overlap ]] && echo --overlap ) > $R/$n.txt 2>&1
  echo "$n rc=$?: $(grep -E 'ms a call|tool:' $R/$n.txt | tr '\n' ' ')" >> $R/sum.txt; el "$n"
  # Without py-spy, the same run's time a call (the sampler's own cost).
  PYTHONPATH=/tmp/site_main timeout 30 python3 $P ${v% --overlap} 6 $( [[ $v == *overlap ]] && echo --overlap ) > $R/${n}_plain.txt 2>&1
  echo "$n plain: $(grep -E 'ms a call' $R/${n}_plain.txt)" >> $R/sum.txt
done
which perf gdb 2>/dev/null >> $R/sum.txt
{ head -1 $R/times.txt; cat $R/sum.txt; tail -3 $R/times.txt; } > $R/report.txt
cat $R/report.txt
