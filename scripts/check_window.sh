#!/usr/bin/env bash
# The window of `rtmpm view` under Xvfb (an X server without a screen; the window presents
# with softbuffer, so no GL or Vulkan driver is involved): the window opens on
# scenes/sandbox.toml (CPU backend) and shows pictures: a screenshot of the X server (xwd) holds
# its picture (not an empty or uniform window: scripts/viewer/window_shot.py). Then the window's
# input, through the X server as a user's: Space pauses (two screenshots a second apart are the
# same picture), S steps (the next one differs), a right-button drag puts the tool into the
# material (the picture shows it), Space resumes (the pictures move on), and the Q key closes
# the window with the session's summary. Installs what it needs with apt when missing: xvfb,
# x11-apps (xwd), x11-utils (xwininfo), xdotool and the X11 libraries the window opens. Writes
# target/window-screenshot.png and every screenshot to target/window-shots/.
set -euo pipefail
cd "$(dirname "$0")/.."
rtmpm=${RTMPM:-target/debug/rtmpm}
# Always built (a no-op when fresh) unless RTMPM names a binary, so CI never drives a stale one.
[ -n "${RTMPM:-}" ] || cargo build --quiet -p rtmpm
need=()
command -v Xvfb >/dev/null || need+=(xvfb)
command -v xwd >/dev/null || need+=(x11-apps)
command -v xwininfo >/dev/null || need+=(x11-utils)
command -v xdotool >/dev/null || need+=(xdotool)
# The libraries the window opens at run time (winit and softbuffer load them with dlopen; the
# binary does not link to them): Xlib and its XCB bridge, the cursor and input extensions,
# XCB, and xkbcommon's X11 keymaps.
for lib in libX11.so.6:libx11-6 libX11-xcb.so.1:libx11-xcb1 libXcursor.so.1:libxcursor1 \
           libXi.so.6:libxi6 libXrandr.so.2:libxrandr2 libxcb.so.1:libxcb1 \
           libxkbcommon-x11.so.0:libxkbcommon-x11-0; do
  /sbin/ldconfig -p | grep -q "${lib%%:*} " || need+=("${lib##*:}")
done
if [ ${#need[@]} -gt 0 ]; then
  sudo_=""
  [ "$(id -u)" -eq 0 ] || sudo_="sudo"
  $sudo_ apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_ apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
fi
work=$(mktemp -d)
# A display number no other X server uses here.
n=97
while [ -e "/tmp/.X11-unix/X$n" ] || [ -e "/tmp/.X$n-lock" ]; do n=$((n + 1)); done
export DISPLAY=":$n"
# -noreset: an X server resets when its last client disconnects, and a client connecting during
# the reset is refused ("Failed to open connection to X server"); the polling below connects and
# disconnects many times while rtmpm is still starting.
Xvfb "$DISPLAY" -screen 0 1024x768x24 -nolisten tcp -noreset > "$work/xvfb.log" 2>&1 &
xvfb=$!
view=""
cleanup() {
  [ -n "$view" ] && kill "$view" 2>/dev/null || true
  kill "$xvfb" 2>/dev/null || true
  rm -rf "$work"
}
trap cleanup EXIT
# Ready when it answers a client (its socket file appears before it has set up its screen).
ready=0
for _ in $(seq 200); do
  kill -0 "$xvfb" 2>/dev/null || break
  xdpyinfo > /dev/null 2>&1 && { ready=1; break; }
  sleep 0.1
done
[ "$ready" -eq 1 ] || { cat "$work/xvfb.log"; echo "FAIL: Xvfb did not start"; exit 1; }

"$rtmpm" view scenes/sandbox.toml --backend cpu --threads 2 --size 400x300 > "$work/view.log" 2>&1 &
view=$!
# The window appears (named after the scene) once the session drew its first picture.
id=""
for _ in $(seq 600); do
  id=$(xdotool search --name "rtmpm view" 2>/dev/null | head -1 || true)
  [ -n "$id" ] && break
  kill -0 "$view" 2>/dev/null || break
  sleep 0.1
done
if [ -z "$id" ]; then
  cat "$work/view.log"
  echo "-- Xvfb's log:"; cat "$work/xvfb.log"
  echo "FAIL: no window appeared"
  exit 1
fi
# Let it show a few pictures, then take the X server's screenshot.
sleep 3
geom=$(xwininfo -id "$id")
x=$(echo "$geom" | awk '/Absolute upper-left X/ {print $4}')
y=$(echo "$geom" | awk '/Absolute upper-left Y/ {print $4}')
w=$(echo "$geom" | awk '/Width:/ {print $2}')
h=$(echo "$geom" | awk '/Height:/ {print $2}')
# shot NAME: the window's picture now (checked: not empty), its digest on stdout.
shot() {
  xwd -root -silent -out "$work/$1.xwd"
  python3 scripts/viewer/window_shot.py "$work/$1.xwd" "$x" "$y" "$w" "$h" --png "$work/$1.png" \
    > "$work/$1.txt" || { cat "$work/$1.txt" "$work/view.log"; echo "FAIL: screenshot $1"; exit 1; }
  head -1 "$work/$1.txt" >&2
  mkdir -p target/window-shots && cp "$work/$1.png" target/window-shots/
  awk '/^digest/ {print $2}' "$work/$1.txt"
}
first=$(shot first)
cp "$work/first.png" target/window-screenshot.png
# The window's input. XTEST input to the focused window (winit ignores synthetic events sent to
# a window), the pointer inside it.
xdotool windowfocus --sync "$id" 2>/dev/null || xdotool windowfocus "$id" || true
xdotool mousemove --window "$id" 50 50
# Space pauses: a second later and two seconds later, the same picture.
xdotool key space
sleep 1
paused1=$(shot paused1)
sleep 1
paused2=$(shot paused2)
[ "$paused1" = "$paused2" ] || { cat "$work/view.log"; echo "FAIL: the pictures changed while paused (Space)"; exit 1; }
# S steps once: another picture (time and particles moved), then it stays.
xdotool key s
sleep 1
stepped=$(shot stepped)
[ "$stepped" != "$paused2" ] || { cat "$work/view.log"; echo "FAIL: S did not step"; exit 1; }
# A right-button drag across the material puts the tool into it (drawn in the paused picture);
# Space resumes: the pictures move on.
xdotool mousemove --window "$id" $((w / 4)) $((h * 3 / 5)) mousedown 3
for k in $(seq 1 10); do xdotool mousemove --window "$id" $((w / 4 + k * w / 20)) $((h * 3 / 5)); sleep 0.05; done
sleep 0.5
dragged=$(shot dragged)
[ "$dragged" != "$stepped" ] || { cat "$work/view.log"; echo "FAIL: the tool drag changed nothing"; exit 1; }
xdotool mouseup 3 key space
sleep 1
resumed=$(shot resumed)
[ "$resumed" != "$dragged" ] || { cat "$work/view.log"; echo "FAIL: Space did not resume"; exit 1; }
echo "window input: Space paused ($paused1 twice), S stepped ($stepped), the drag drew the tool ($dragged), Space resumed ($resumed)"
# Q closes the window and ends the session, which prints its summary.
xdotool key q
for _ in $(seq 100); do kill -0 "$view" 2>/dev/null || break; sleep 0.1; done
if kill -0 "$view" 2>/dev/null; then
  cat "$work/view.log"
  echo "FAIL: the window did not close on Q"
  exit 1
fi
wait "$view" && rc=0 || rc=$?
view=""
cat "$work/view.log"
[ "$rc" -eq 0 ] || { echo "FAIL: rtmpm view exited with $rc"; exit 1; }
grep -q "pictures" "$work/view.log" || { echo "FAIL: no summary"; exit 1; }
echo "window check passed"
