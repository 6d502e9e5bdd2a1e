#!/usr/bin/env bash
# Time the fluid surface reconstruction of a 1M-particle frame on the GPU machine's
# CPU (no GPU used). Build here first: cargo build --release -p rtmpm (default features), carry
# target/release/rtmpm. Prints one line per thread count; paste them into bench/RESULTS.md.
set -euo pipefail
bin=${1:-target/release/rtmpm}
for t in 16 2; do
  echo "== RAYON_NUM_THREADS=$t (machine: $(nproc) cores, $(lscpu | sed -n 's/^Model name: *//p'))"
  RAYON_NUM_THREADS=$t "$bin" mesh --bench --bench-particles 1000000
done
