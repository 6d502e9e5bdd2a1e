#!/usr/bin/env bash
# Build, on this (CPU) machine, everything a GPU run needs, into .device/ (ignored by git), which a
# device call carries: the release binary, the GPU test binaries and the commit they were built at.
# With BASE=<commit>, also the release binary of that commit as .device/rtmpm_base, for the A/B
# benchmark of scripts/gpu/run.sh (built in a detached worktree under target/base).
# Usage: bash scripts/gpu/prepare.sh [BASE=<commit>]
set -euo pipefail
cd "$(dirname "$0")/../.."
# With the rigid bodies (`[[rigid_body]]`, cargo feature `rigid`: rapier3d) so the GPU runs them.
cargo build --release -p rtmpm --features rigid
rm -rf .device && mkdir -p .device
cargo test --release -p rtmpm-cuda -p rtmpm --features rtmpm/rigid,rtmpm-cuda/rigid --no-run --message-format=json 2>/dev/null | python3 -c '
import sys, json, shutil
for line in sys.stdin:
    m = json.loads(line)
    if m.get("reason") == "compiler-artifact" and m.get("executable") and m["target"]["kind"] == ["test"]:
        shutil.copy(m["executable"], ".device/test_" + m["target"]["name"])
'
cp target/release/rtmpm .device/
# The render stage's benchmark (the `view` suite).
cargo build --release -p rtmpm-cuda --example render_bench
cp target/release/examples/render_bench .device/
git rev-parse --short HEAD > .device/COMMIT
pwd > .device/BUILD_DIR   # the test binaries find the repository through the path they were built in
if [ -n "${BASE:-}" ]; then
  wt=target/base
  [ -d "$wt" ] || git worktree add --detach "$wt" "$BASE"
  git -C "$wt" checkout --detach "$BASE"
  (cd "$wt" && CARGO_TARGET_DIR="$PWD/target" cargo build --release -p rtmpm)
  cp "$wt/target/release/rtmpm" .device/rtmpm_base
  git -C "$wt" rev-parse --short HEAD > .device/BASE_COMMIT
fi
strip .device/rtmpm* .device/test_* .device/render_bench 2>/dev/null || true
ls -la .device
