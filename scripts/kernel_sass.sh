#!/usr/bin/env bash
# The fused G2P2G kernels' instructions without a GPU: the PTX that NVRTC makes
# (crates/rtmpm-cuda/examples/ptx.rs, with line info) assembled by ptxas for sm_90, disassembled
# by nvdisasm, then counted by scripts/sass_entry_count.py (static, and an estimate per warp-list
# entry at 0, 3 and 4 shuffle rounds). Tools from the PyPI wheels (nvidia-cuda-nvrtc /
# nvidia-cuda-nvcc 13.0, nvidia-cuda-nvdisasm), installed into target/ci-tools.
# Usage: bash scripts/kernel_sass.sh [ptx example arguments, e.g. layout=1 seg_clamp row_unroll=2]
# (default kernel g2p2g_fluid; KERNEL=g2p2g for the general one; the listing stays in
# target/kernel-sass/program.dis)
set -euo pipefail
cd "$(dirname "$0")/.."
tools="$PWD/target/ci-tools"
[ -e "$tools/nvidia/cu13/lib/libnvrtc.so.13" ] || python3 -m pip install -q --target "$tools" "nvidia-cuda-nvrtc==13.0.88"
[ -e "$tools/nvcc/nvidia/cu13/bin/ptxas" ] || python3 -m pip install -q --no-deps --target "$tools/nvcc" "nvidia-cuda-nvcc==13.0.88"
[ -e "$tools/dis/nvidia/cu13/bin/nvdisasm" ] || python3 -m pip install -q --no-deps --target "$tools/dis" "nvidia-cuda-nvdisasm==13.2.78"
export RTMPM_NVRTC_LIB="$tools/nvidia/cu13/lib/libnvrtc.so.13" LD_LIBRARY_PATH="$tools/nvidia/cu13/lib"
out="$PWD/target/kernel-sass"
mkdir -p "$out"
cargo run -q -p rtmpm-cuda --example ptx -- sm_90 lineinfo "$@" > "$out/program.ptx"
"$tools/nvcc/nvidia/cu13/bin/ptxas" -arch=sm_90 -v -o "$out/program.cubin" "$out/program.ptx" 2> "$out/ptxas.txt"
"$tools/dis/nvidia/cu13/bin/nvdisasm" -g -c "$out/program.cubin" > "$out/program.dis"
k=${KERNEL:-g2p2g_fluid}
grep -A3 "entry function '$k'" "$out/ptxas.txt" | grep -E "spill|registers" || true
python3 scripts/sass_entry_count.py "$out/program.dis" "$k"
