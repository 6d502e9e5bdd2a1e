#!/usr/bin/env bash
# Memory over a long stream: `rtmpm view SCENE --serve` watched by scripts/viewer/stream_client.py
# on this machine for SECONDS, the server's resident memory (VmRSS) and, where nvidia-smi is
# present, its GPU memory sampled every EVERY seconds. Prints the samples at the start, the
# middle and the end, the largest, and the stream's figures; flat memory is the target.
#
#   bash scripts/viewer/view_soak.sh RTMPM BACKEND SCENE SECONDS OUTDIR [EVERY] [PORT] [SIZE]
#
# Writes OUTDIR/view_soak_memory.txt (`seconds rss_kib gpu_mib` a sample), view_soak_client.log
# and view_soak.log (the server's output). The scene runs 1000 s of simulated time here (it
# never reaches its end and pauses).
set -uo pipefail
bin=$1 backend=$2 scene=$3 secs=$4 out=$5 every=${6:-30} port=${7:-18300} size=${8:-1280x720}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$out"
tmp=$(mktemp -d)
sed 's/^duration = .*/duration = 1000.0/' "$scene" > "$tmp/soak.toml"
"$bin" view "$tmp/soak.toml" --serve "127.0.0.1:$port" --backend "$backend" --size "$size" \
  > "$out/view_soak.log" 2>&1 &
vpid=$!
for _ in $(seq 600); do
  (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
  kill -0 "$vpid" 2>/dev/null || break
  sleep 0.2
done
t0=$(date +%s)
mem="$out/view_soak_memory.txt"
( while kill -0 "$vpid" 2>/dev/null; do
    rss=$(awk '/^VmRSS/ {print $2}' "/proc/$vpid/status" 2>/dev/null)
    gpu=$(nvidia-smi --query-compute-apps=pid,used_memory --format=csv,noheader,nounits 2>/dev/null \
          | awk -F', *' -v p="$vpid" '$1 == p {print $2}')
    echo "$(( $(date +%s) - t0 )) ${rss:--} ${gpu:--}"
    sleep "$every"
  done ) > "$mem" &
mpid=$!
timeout $((secs + 120)) python3 "$here/stream_client.py" --url "127.0.0.1:$port" --seconds "$secs" \
  --label "soak $(basename "$scene" .toml)" > "$out/view_soak_client.log" 2>&1
kill -INT "$vpid" 2>/dev/null; wait "$vpid" 2>/dev/null
kill "$mpid" 2>/dev/null; wait "$mpid" 2>/dev/null
rm -rf "$tmp"
grep -vE '^\{' "$out/view_soak_client.log"
python3 - "$mem" "$secs" <<'EOF'
import sys
rows = [l.split() for l in open(sys.argv[1]) if len(l.split()) == 3]
if not rows:
    print("  soak: no memory samples (the server did not run?)")
    sys.exit(0)
def mib(x, scale):
    return "-" if x == "-" else f"{float(x) / scale:.0f}"
pick = [("start", rows[0]), ("middle", rows[len(rows) // 2]), ("end", rows[-1])]
rss = [float(r[1]) for r in rows if r[1] != "-"]
gpu = [float(r[2]) for r in rows if r[2] != "-"]
print(f"  soak over {sys.argv[2]} s, {len(rows)} samples: " + ", ".join(
    f"{what} (t={r[0]} s) host {mib(r[1], 1024)} MiB GPU {mib(r[2], 1)} MiB" for what, r in pick))
print(f"  soak largest: host {max(rss) / 1024:.0f} MiB" if rss else "  soak largest: host -",
      f"GPU {max(gpu):.0f} MiB" if gpu else "GPU -",
      f"; host end - start {(rss[-1] - rss[0]) / 1024:+.1f} MiB" if rss else "")
EOF
