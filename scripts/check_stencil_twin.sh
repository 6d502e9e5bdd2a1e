#!/usr/bin/env bash
# The kernels' stencil node addressing variants against each other, on the CPU (see scripts/stencil_twin.cpp).
set -euo pipefail
cd "$(dirname "$0")"
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
g++ -O2 -std=c++17 -Wall -Wextra -Werror -Wno-unknown-pragmas -o "$out/twin" stencil_twin.cpp
"$out/twin"
