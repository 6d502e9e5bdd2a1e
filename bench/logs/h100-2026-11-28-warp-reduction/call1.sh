#!/usr/bin/env bash
# speed, device call 1: A/B of the P2G reduction variants against 35a1348, ncu of the fused kernel,
# n = 256 fluid block, then the GPU tests with the tile reduction (RTMPM_P2G_REDUCE=3).
export D=.device-speed/d RTMPM_CACHE_DIR=$PWD/.device-speed/d/kcache TEST_TIMEOUT=${TEST_TIMEOUT:-130}
O=$OUT; T0=$(date +%s)
el() { echo "[t=$(( $(date +%s) - T0 ))s] $*"; }
OUT=$O/a REPS=1 VARIANTS="base|rtmpm_base|| r3|rtmpm|-DRTMPM_P2G_REDUCE=3 r1|rtmpm|-DRTMPM_P2G_REDUCE=1 r3mb4|rtmpm|-DRTMPM_P2G_REDUCE=3,-DG2P2G_MIN_BLOCKS=4 r3pf|rtmpm|-DRTMPM_P2G_REDUCE=3,-DRTMPM_G2P2G_PREFETCH=1" \
  bash $D/run.sh variants > /dev/null 2>&1; el variants done
{ for v in "rtmpm_base|" "rtmpm|-DRTMPM_P2G_REDUCE=3" "rtmpm_base|" "rtmpm|-DRTMPM_P2G_REDUCE=3"; do
    echo "== n256 ${v}"; RTMPM_KERNEL_DEFINES="${v#*|}" timeout 60 $D/${v%%|*} bench --backend cuda --n 256 --steps 300 2>&1 | grep -E "throughput|wall time|g2p2g "
  done; } > $O/n256.txt 2>&1; el n256 done
OUT=$O/p PROFILE_RUNS="fluid_base|rtmpm_base||fluid_dam_2m fluid_r3|rtmpm|-DRTMPM_P2G_REDUCE=3|fluid_dam_2m jelly_r3|rtmpm|-DRTMPM_P2G_REDUCE=3|jelly_drop_2m" \
  bash $D/run.sh profile > /dev/null 2>&1; el profile done
OUT=$O/t RTMPM_KERNEL_DEFINES=-DRTMPM_P2G_REDUCE=3 TESTS="test_materials test_gpu test_agreement" bash $D/run.sh tests > /dev/null 2>&1; el tests done
echo "==== n256"; cat $O/n256.txt; echo "==== tests"; cat $O/t/summary.txt; echo "==== profile"; cat $O/p/summary.txt; echo "==== variants"; cat $O/a/summary.txt
