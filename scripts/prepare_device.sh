#!/usr/bin/env bash
# Build the release binary and the GPU test binaries here, and copy them into .device/ (ignored by
# git) so that a device run can carry them: carry [".device"].
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p rtmpm
rm -rf .device && mkdir -p .device
cargo test --release -p rtmpm-cuda -p rtmpm --test gpu --test agreement --test multi_gpu --test multi_gpu_cli --no-run --message-format=json 2>/dev/null | python3 -c '
import sys, json, shutil
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["kind"] != ["bin"]:
        shutil.copy(m["executable"], ".device/test_" + m["target"]["name"])
'
cp target/release/rtmpm .device/
strip .device/*
ls -la .device
