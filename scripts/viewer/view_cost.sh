#!/usr/bin/env bash
# The simulation's step time with the live view on against off, like for like: the same scene,
# the same frames (2 to N: the first builds the backend's first mapping), the same dt and steps
# a frame, one binary. Four runs, each to the end of frame N:
#   off         rtmpm bench --scene SCENE --warmup <one frame> --frames N-1
#   no client   rtmpm view SCENE --serve --frames N (a picture every frame, nobody watching:
#               nothing is JPEG-encoded), with RTMPM_VIEW_OVERLAP=1 (pictures collected while the
#               next frame's steps run: the default, docs/viewer.md; set here so that an older
#               binary, which overlapped only when asked, is measured the same way)
#   client      the same with scripts/viewer/stream_client.py watching (every picture encoded
#               and sent); it starts paused and the client resumes it
#   no overlap  the client run with RTMPM_VIEW_OVERLAP=0: each picture drawn and published
#               before the next step (the session's loop before pictures overlapped the steps)
# The view runs print `view_timing ...` (crates/rtmpm-view, session Timing): wall time, steps,
# ms/step and the host's time per picture (begin, finish = wait + copy, heads-up + publish).
#
#   bash scripts/viewer/view_cost.sh RTMPM BACKEND SCENE FRAMES OUTDIR [PORT] [SIZE]
#
# Writes OUTDIR/view_NAME_steps.txt (one line a run: `LABEL ms_per_step=... [view_timing ...]`),
# OUTDIR/view_NAME_client_client.log (the client's JSON line) and each run's log; prints one line
# a run. NAME is the scene file's name without .toml. The scene runs 60 s of simulated time here
# (so the view never reaches its end and pauses).
set -uo pipefail
bin=$1 backend=$2 scene=$3 frames=$4 out=$5 port=${6:-18180} size=${7:-1280x720}
name=$(basename "$scene" .toml)
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
steps="$out/view_${name}_steps.txt"
: > "$steps"
tmp=$(mktemp -d)
sed 's/^duration = .*/duration = 60.0/' "$scene" > "$tmp/$name.toml"

# off: bench over frames 2..N (its warm-up is the first frame).
# Steps a frame: 1 / (fps dt) of the scene's [time] (benchmarks need a fixed dt).
spf=$(python3 -c '
import re, sys
t = open(sys.argv[1]).read()
fps = float(re.search(r"^fps\s*=\s*([0-9.eE+-]+)", t, re.M).group(1))
dt = float(re.search(r"^dt\s*=\s*([0-9.eE+-]+)", t, re.M).group(1))
print(round(1 / (fps * dt)))' "$scene") || { echo "  $name: no fps and dt in $scene"; exit 1; }
b=$(timeout 600 "$bin" bench --backend "$backend" --scene "$scene" --warmup "$spf" \
    --frames $((frames - 1)) 2>&1)
echo "$b" > "$out/view_${name}_off_bench.log"
off=$(echo "$b" | grep -oE '\(([0-9.]+) ms/step\)' | head -1 | tr -d '()' | cut -d' ' -f1)
echo "off ms_per_step=${off:-nan} steps=$(( (frames - 1) * spf ))" >> "$steps"
echo "  $name off (rtmpm bench, frames 2..$frames, $spf steps a frame): ${off:-?} ms/step"

# label, env, client?: one view run to frame N.
view_run() {
  local label=$1 envs=$2 client=$3 log="$out/view_${name}_$1.log"
  local paused=()
  [ "$client" = yes ] && paused=(--paused)
  port=$((port + 1))
  env $envs "$bin" view "$tmp/$name.toml" --serve "127.0.0.1:$port" --backend "$backend" \
    --size "$size" --frames "$frames" "${paused[@]}" > "$log" 2>&1 &
  local vpid=$!
  if [ "$client" = yes ]; then
    for _ in $(seq 600); do
      (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
      kill -0 "$vpid" 2>/dev/null || break
      sleep 0.2
    done
    timeout 900 python3 "$here/stream_client.py" --url "127.0.0.1:$port" --seconds 100000 \
      --send '{"cmd":"resume"}' --label "$name $label" > "$out/view_${name}_${label}_client.log" 2>&1
  fi
  # The view ends by itself at frame N.
  local t=0
  while kill -0 "$vpid" 2>/dev/null && [ $t -lt 6000 ]; do sleep 0.1; t=$((t + 1)); done
  kill -INT "$vpid" 2>/dev/null; wait "$vpid" 2>/dev/null
  local line; line=$(grep -E '^view_timing ' "$log" | tail -1)
  # The loop's wall time per step (` ms_per_step=`, not `step_ms_per_step=`: the step calls alone).
  local ms; ms=$(echo "$line" | sed -nE 's/.* ms_per_step=([0-9.]+).*/\1/p')
  echo "$label ms_per_step=${ms:-nan} $line" >> "$steps"
  local vs=""
  [ -n "$ms" ] && [ -n "$off" ] && vs=$(awk -v a="$ms" -v b="$off" 'BEGIN { printf " (%+.1f %% against off)", 100 * (a / b - 1) }')
  echo "  $name $label: ${ms:-?} ms/step$vs; ${line:-no view_timing line: see $log}"
}
view_run noclient "RTMPM_VIEW_OVERLAP=1" no
view_run client "RTMPM_VIEW_OVERLAP=1" yes
view_run nooverlap "RTMPM_VIEW_OVERLAP=0" yes
rm -rf "$tmp"
