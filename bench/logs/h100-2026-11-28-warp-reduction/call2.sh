#!/usr/bin/env bash
# speed, device call 2: base (35a1348) against the unrolled shuffle rounds (RTMPM_P2G_REDUCE=1), two
# interleaved runs; n = 256 fluid block; ncu of the fused kernel per scene; test_materials with r1.
export D=.device-speed/d RTMPM_CACHE_DIR=$PWD/.device-speed/d/kcache TEST_TIMEOUT=60
O=$OUT; T0=$(date +%s)
el() { echo "[t=$(( $(date +%s) - T0 ))s] $*"; }
OUT=$O/a REPS=2 VARIANTS="base|rtmpm_base|| r1|rtmpm|-DRTMPM_P2G_REDUCE=1" bash $D/run.sh variants > /dev/null 2>&1; el variants done
{ for v in "rtmpm_base|" "rtmpm|-DRTMPM_P2G_REDUCE=1" "rtmpm_base|" "rtmpm|-DRTMPM_P2G_REDUCE=1"; do
    echo "== n256 ${v}"; RTMPM_KERNEL_DEFINES="${v#*|}" timeout 60 $D/${v%%|*} bench --backend cuda --n 256 --steps 300 2>&1 | grep -E "throughput|wall time|g2p2g "
  done; } > $O/n256.txt 2>&1; el n256 done
OUT=$O/p PROFILE_RUNS="fluid_r1|rtmpm|-DRTMPM_P2G_REDUCE=1|fluid_dam_2m jelly_r1|rtmpm|-DRTMPM_P2G_REDUCE=1|jelly_drop_2m snow_r1|rtmpm|-DRTMPM_P2G_REDUCE=1|snow_1m" \
  bash $D/run.sh profile > /dev/null 2>&1; el profile done
OUT=$O/t RTMPM_KERNEL_DEFINES=-DRTMPM_P2G_REDUCE=1 TESTS="test_materials" bash $D/run.sh tests > /dev/null 2>&1; el tests done
echo "==== n256"; cat $O/n256.txt; echo "==== tests"; cat $O/t/summary.txt; echo "==== profile"
grep -E "^ncu| g2p2g| Duration|Issue Slots Busy|Executed Instructions|No Eligible|Warp Cycles|long_scoreboard|_wait_|not_selected|short_scoreboard|math_pipe|op_red.sum|DRAM Throughput|L2 Cache Throughput|L1/TEX Cache Throughput|L1/TEX Hit|Registers|Achieved" $O/p/summary.txt
echo "==== variants"; cat $O/a/summary.txt
