#!/usr/bin/env bash
# The live view's cost per picture on a backend: for each scene, `rtmpm view --paused --serve`
# and scripts/viewer/stream_client.py --orbit N (N redraws, no stepping between): the draw time
# (the backend's own picture, or the particles read back and the CPU renderer) and the JPEG
# time, medians over the redraws, then the session running: pictures/s and steps/s with the
# view against `rtmpm run --no-output` of the same scene (the simulation with the view off).
#
#   bash scripts/viewer/frame_times.sh [RTMPM] [BACKEND] [SIZE] [SCENE...]
#
# Defaults: target/release/rtmpm, cpu, 1280x720, scenes/sandbox.toml scenes/snowball.toml.
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${1:-target/release/rtmpm}
backend=${2:-cpu}
size=${3:-1280x720}
shift $(($# < 3 ? $# : 3))
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(scenes/sandbox.toml scenes/snowball.toml)
redraws=${REDRAWS:-30}
run_seconds=${RUN_SECONDS:-20}
port=${PORT:-18300}

# Start `rtmpm view` with the given flags on $port; sets $vpid.
start() {
  "$bin" view "$@" --serve "127.0.0.1:$port" --backend "$backend" --size "$size" \
    > "/tmp/frame_times_$port.log" 2>&1 &
  vpid=$!
  for _ in $(seq 600); do
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && return 0
    kill -0 "$vpid" 2>/dev/null || break
    sleep 0.2
  done
  echo "rtmpm view did not start:"; cat "/tmp/frame_times_$port.log"; return 1
}

stop() { kill -INT "$vpid" 2>/dev/null; wait "$vpid" 2>/dev/null || true; port=$((port + 1)); }

for sc in "${scenes[@]}"; do
  for shadows in "" "--no-shadows"; do
    start "$sc" --paused $shadows
    python3 scripts/viewer/stream_client.py --url "127.0.0.1:$port" --seconds 300 \
      --orbit "$redraws" --label "$(basename "$sc" .toml) $size redraw ${shadows:-(shadows)}" \
      2>&1 >/dev/null
    stop
  done
  start "$sc"
  python3 scripts/viewer/stream_client.py --url "127.0.0.1:$port" --seconds "$run_seconds" \
    --label "$(basename "$sc" .toml) $size running" 2>&1 >/dev/null
  stop
  off=$("$bin" run "$sc" --backend "$backend" --no-output --frames 30 2>&1 | grep -E "^  (throughput|steps)")
  echo "  $(basename "$sc" .toml) without the view (rtmpm run --no-output --frames 30):" $off
done
