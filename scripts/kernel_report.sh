#!/usr/bin/env bash
# Registers, stack frame and spills of every kernel, without a GPU: the PTX that NVRTC makes
# (crates/rtmpm-cuda/examples/ptx.rs) assembled by ptxas -v for sm_90. NVRTC and ptxas come
# from the PyPI wheels nvidia-cuda-nvrtc / nvidia-cuda-nvcc 13.0 (installed into target/ci-tools).
# Usage: bash scripts/kernel_report.sh [f64] [no_fast_math] [layout=N] [ck_bound=N]
# (layout N: StateLayout::code, 1 = fluid; ck_bound: the CUDA option of that name)
# (RTMPM_KERNEL_DEFINES, e.g. "-DRTMPM_P2G_REDUCE=1", reaches the compile as in the backend)
set -euo pipefail
cd "$(dirname "$0")/.."
tools="$PWD/target/ci-tools"
[ -e "$tools/nvidia/cu13/lib/libnvrtc.so.13" ] || python3 -m pip install -q --target "$tools" "nvidia-cuda-nvrtc==13.0.88"
[ -e "$tools/nvcc/nvidia/cu13/bin/ptxas" ] || python3 -m pip install -q --no-deps --target "$tools/nvcc" "nvidia-cuda-nvcc==13.0.88"
export RTMPM_NVRTC_LIB="$tools/nvidia/cu13/lib/libnvrtc.so.13" LD_LIBRARY_PATH="$tools/nvidia/cu13/lib"
export RTMPM_CACHE_DIR="$PWD/target/kernel-report-cache"
out="$PWD/target/kernel-report"
mkdir -p "$out"
cargo run -q -p rtmpm-cuda --example ptx -- "$@" > "$out/program.ptx"
"$tools/nvcc/nvidia/cu13/bin/ptxas" -arch=sm_90 -v -o "$out/program.cubin" "$out/program.ptx" 2> "$out/ptxas.txt"
python3 - "$out/ptxas.txt" <<'PY'
import re, sys
rows, cur = {}, None
for line in open(sys.argv[1]):
    m = re.search(r"Compiling entry function '(\w+)'", line)
    if m:
        cur = m.group(1)
    m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
    if m and cur:
        rows.setdefault(cur, {})["stack"] = m.groups()
    m = re.search(r"Used (\d+) registers", line)
    if m and cur:
        rows.setdefault(cur, {})["regs"] = m.group(1)
        m = re.search(r"(\d+) bytes smem", line)
        rows[cur]["smem"] = m.group(1) if m else "0"
print(f"{'kernel':26} {'regs':>5} {'stack':>6} {'spill st':>9} {'spill ld':>9} {'smem':>6}")
for k in sorted(rows):
    r = rows[k]; st = r.get("stack", ("?", "?", "?"))
    print(f"{k:26} {r.get('regs', '?'):>5} {st[0]:>6} {st[1]:>9} {st[2]:>9} {r.get('smem', '?'):>6}")
PY
