#!/usr/bin/env bash
# The compact state's device codec against its generic path, on the CPU (see scripts/codec_twin.cpp).
set -euo pipefail
cd "$(dirname "$0")"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for flags in "-O2" "-O2 -ffast-math"; do
  g++ $flags -std=c++17 -o "$out/twin" codec_twin.cpp
  "$out/twin"
done
