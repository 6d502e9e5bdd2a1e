#!/usr/bin/env bash
# Session 11, call 2 (one H200; binary of main 287e897, whose default kernels are those of the later
# commits of this session): rtmpm against Taichi 1.7.4's mpm3d on the GPU in the same call (the fluid
# block, n = 256 and 128, interleaved), the claymore scenes with the defaults, and Nsight Compute on the
# fused kernel of the jelly and the snow (what bounds them).
set -u
R=$OUT
tar xJf .device-pack/d.tar.xz
export D=.device RTMPM_CACHE_DIR=/tmp/kcache NCCL_NVLS_ENABLE=0
T0=$(date +%s); el() { echo "[t=$(( $(date +%s) - T0 ))s] $*" | tee -a $R/times.txt; }
el "start, binary of $(cat .device/COMMIT); $(nvidia-smi --query-gpu=name,driver_version --format=csv,noheader)"
mkdir -p /tmp/site && tar xJf .device-pack/taichi-site.tar.xz -C /tmp/site && export PYTHONPATH=/tmp/site
python3 -c 'import taichi as ti; print("taichi", ti.__version__)' > $R/taichi_env.txt 2>&1; cat $R/taichi_env.txt | tail -2 >> $R/summary.txt
# label, command...: one line with the throughput (and ms/step for rtmpm).
L() { local label=$1; shift; local r; r=$(timeout 150 "$@" 2>&1); echo "== $label: $*" >> $R/runs.log; echo "$r" >> $R/runs.log
  echo "$label | $(echo "$r" | grep -m1 -E 'throughput' | tr -s ' ') | $(echo "$r" | grep -oE '[0-9.]+ ms/step' | head -1) $(echo "$r" | grep -m1 -iE '^error|Traceback|RuntimeError' )" >> $R/summary.txt; }
for rep in 1 2; do
  L "rtmpm n=256 #$rep" $D/rtmpm bench --backend cuda --n 256 --steps 500
  L "taichi n=256 #$rep" python3 bench/taichi_mpm3d.py --arch cuda --n 256 --steps 500
done
el "n=256"
L "rtmpm n=128" $D/rtmpm bench --backend cuda --n 128 --steps 500
L "taichi n=128" python3 bench/taichi_mpm3d.py --arch cuda --n 128 --steps 500
el "n=128"
for rep in 1 2; do
  for sc in fluid_dam_2m:10 jelly_drop_2m:5 snow_1m:20; do
    L "${sc%%:*} #$rep" $D/rtmpm bench --backend cuda --scene bench/${sc%%:*}.toml --frames ${sc##*:}
  done
done
el claymore
ncu=$(command -v ncu || ls /opt/nvidia/nsight-compute/*/ncu /usr/local/cuda/bin/ncu 2>/dev/null | head -1)
for sc in jelly_drop_2m snow_1m fluid_dam_2m; do
  timeout 150 "$ncu" --kernel-name regex:'^g2p2g' --launch-skip 5 --launch-count 1 --set full \
    $D/rtmpm bench --backend cuda --scene bench/$sc.toml --steps 20 > $R/ncu-$sc.txt 2>&1
  echo "ncu $sc rc=$?" >> $R/summary.txt
  grep -E "^  g2p2g|Duration|Compute \(SM\) Throughput|Memory Throughput|DRAM Throughput|Issue Slots Busy|Issued Ipc Active|Registers Per|Achieved Occupancy|Theoretical Occupancy|No Eligible|Warp Cycles Per Issued|ERROR" $R/ncu-$sc.txt | sed -E 's/ +/ /g' | head -16 >> $R/summary.txt
  el "ncu $sc"
done
{ cat $R/summary.txt; cat $R/times.txt; } > $R/report.txt
(cd $R && tar czf /tmp/all-logs.tgz --exclude=report.txt . 2>/dev/null && mv /tmp/all-logs.tgz logs.tgz)
(cd $R && find . -mindepth 1 -maxdepth 1 ! -name report.txt ! -name logs.tgz -exec rm -rf {} +)
cat $R/report.txt
