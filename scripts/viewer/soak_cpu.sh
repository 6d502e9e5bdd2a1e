#!/usr/bin/env bash
# Memory of `rtmpm view --serve` over a long stream on this machine's CPU backend: a small scene
# (scenes/sandbox.toml at 640x360) streamed for SOAK_SECONDS (default 600) to a client that
# connects, reads for 8 s, disconnects and connects again, and to a slow client that reads
# nothing for SOAK_STALL s (default 120; then it drains what came, notes whether the server
# dropped it, and connects again); the server's RSS sampled every
# SOAK_EVERY s (default 5). Prints the RSS at the start, after 1 min, the largest and at the
# end, and whether it stayed flat (scripts/viewer/soak_cpu.py says how that is decided).
# SOAK_THREADS: the server's CPU threads (default one a core); SOAK_SCENE, SOAK_SIZE, SOAK_PORT.
#
#   bash scripts/viewer/soak_cpu.sh [--check]        # RTMPM=path/to/rtmpm to skip the build
#   SOAK_SECONDS=40 bash scripts/viewer/soak_cpu.sh --check     # the short version
#
# --check: exit 1 when memory grew, the server died or the reconnecting client got no picture.
# Writes target/soak_cpu_rss.txt (`seconds rss_kib` a sample) and target/soak_cpu_server.log.
set -euo pipefail
cd "$(dirname "$0")/../.."
rtmpm=${RTMPM:-target/debug/rtmpm}
[ -n "${RTMPM:-}" ] || cargo build --quiet -p rtmpm
mkdir -p target
exec python3 scripts/viewer/soak_cpu.py --rtmpm "$rtmpm" \
  --scene "${SOAK_SCENE:-scenes/sandbox.toml}" --size "${SOAK_SIZE:-640x360}" \
  --seconds "${SOAK_SECONDS:-600}" --every "${SOAK_EVERY:-5}" --port "${SOAK_PORT:-18400}" \
  --stall "${SOAK_STALL:-120}" ${SOAK_THREADS:+--threads "$SOAK_THREADS"} \
  --samples target/soak_cpu_rss.txt --log target/soak_cpu_server.log "$@"
