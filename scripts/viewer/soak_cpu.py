#!/usr/bin/env python3
"""Memory of `rtmpm view --serve` over a long stream with awkward clients (standard library only).

Starts `RTMPM view SCENE --serve 127.0.0.1:PORT` (CPU backend by default), waits until the
server answers (GET /status returns 200, not merely a port that accepts), then for --seconds
runs, at the same time:

* a client that connects, reads pictures for --hold seconds, disconnects, waits --gap seconds
  and connects again, over and over;
* a slow client that completes the WebSocket handshake with a small receive buffer and then
  reads nothing for --stall seconds (the server drops a client that takes nothing for 10 s);
  then it reads what is left to see whether it was dropped, and connects again;
* a sampler of the server's resident memory (VmRSS of /proc/PID/status) every --every seconds.

Prints the RSS at the start, after 1 min (the sample nearest 60 s), the largest and at the end,
the clients' counts (connections, pictures, drops), and one JSON line. Memory is called flat when
the largest RSS of the run's second half is at most the largest of its first half plus
max(8 MiB, 10 %) (the criterion was fixed before any run: steady state reached within the first
half, no growth after it); --check makes a run that is not flat, a server that died, or a
reconnecting client that received no pictures exit with status 1.
"""

import argparse
import json
import os
import re
import socket
import subprocess
import tempfile
import sys
import threading
import time
import urllib.request

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stream_client import WebSocket  # noqa: E402


def rss_kib(pid):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except OSError:
        return None
    return None


def wait_until_answers(port, proc, timeout):
    """True once GET /status answers 200; False if the server exits or the time runs out."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if proc.poll() is not None:
            return False
        try:
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/status", timeout=2) as r:
                if r.status == 200:
                    return True
        except OSError:
            pass
        time.sleep(0.2)
    return False


class Counts:
    def __init__(self):
        self.lock = threading.Lock()
        self.c = {"connects": 0, "pictures": 0, "errors": 0, "slow_connects": 0,
                  "slow_dropped": 0}

    def add(self, key, n=1):
        with self.lock:
            self.c[key] += n


def reconnecting_client(port, stop, hold, gap, counts):
    while not stop.is_set():
        try:
            ws = WebSocket("127.0.0.1", port, timeout=10.0)
            counts.add("connects")
            end = time.monotonic() + hold
            while time.monotonic() < end and not stop.is_set():
                kind, _ = ws.recv()
                if kind == "binary":
                    counts.add("pictures")
                elif kind == "close":
                    counts.add("errors")
                    break
            ws.sock.close()
        except (OSError, EOFError, RuntimeError):
            counts.add("errors")
        stop.wait(gap)


def slow_client(port, stop, stall, counts):
    """Handshake, then read nothing for `stall` seconds; then drain what arrived and see whether
    the server has dropped the connection (its close is queued behind the unread bytes, so it
    shows only once they are read); connect again either way."""
    while not stop.is_set():
        try:
            ws = WebSocket("127.0.0.1", port, rcvbuf=4096, timeout=10.0)
            counts.add("slow_connects")
        except (OSError, EOFError, RuntimeError):
            counts.add("errors")
            stop.wait(1.0)
            continue
        stop.wait(stall)
        # Drain for at most 3 s: the end of the stream (or a reset) means it was dropped.
        ws.sock.settimeout(0.5)
        end = time.monotonic() + 3.0
        try:
            while time.monotonic() < end:
                try:
                    if not ws.sock.recv(1 << 16):
                        counts.add("slow_dropped")
                        break
                except TimeoutError:
                    pass
        except OSError:
            counts.add("slow_dropped")
        ws.sock.close()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rtmpm", required=True)
    ap.add_argument("--scene", default="scenes/sandbox.toml")
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--threads", type=int, default=None, help="CPU worker threads of the server")
    ap.add_argument("--port", type=int, default=18400)
    ap.add_argument("--seconds", type=float, default=600.0)
    ap.add_argument("--every", type=float, default=5.0)
    ap.add_argument("--hold", type=float, default=8.0)
    ap.add_argument("--gap", type=float, default=2.0)
    ap.add_argument("--stall", type=float, default=120.0,
                    help="seconds the slow client reads nothing before it looks")
    ap.add_argument("--log", default=None, help="the server's output (default: discarded)")
    ap.add_argument("--samples", default=None, help="write `seconds rss_kib` lines here")
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args()

    # The scene runs far past its duration here, so that the view never pauses at its end.
    text = open(a.scene).read()
    text = re.sub(r"^duration\s*=.*$", "duration = 100000.0", text, flags=re.M)
    tmp = tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False)
    tmp.write(text)
    tmp.close()
    log = open(a.log, "w") if a.log else subprocess.DEVNULL
    cmd = [a.rtmpm, "view", tmp.name, "--serve", f"127.0.0.1:{a.port}", "--backend", a.backend,
           "--size", a.size]
    if a.threads:
        cmd += ["--threads", str(a.threads)]
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT)
    try:
        return run(a, proc, cmd)
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(20)
            except subprocess.TimeoutExpired:
                proc.kill()
        os.unlink(tmp.name)


def run(a, proc, cmd):
    if not wait_until_answers(a.port, proc, 120):
        print(f"soak: the server did not answer on 127.0.0.1:{a.port} ({' '.join(cmd)})")
        return 1
    counts = Counts()
    stop = threading.Event()
    threads = [
        threading.Thread(target=reconnecting_client,
                         args=(a.port, stop, a.hold, a.gap, counts), daemon=True),
        threading.Thread(target=slow_client, args=(a.port, stop, a.stall, counts), daemon=True),
    ]
    for t in threads:
        t.start()
    samples = []
    t0 = time.monotonic()
    died = False
    while True:
        t = time.monotonic() - t0
        r = rss_kib(proc.pid)
        if r is None or proc.poll() is not None:
            died = True
            break
        samples.append((t, r))
        if t >= a.seconds:
            break
        time.sleep(min(a.every, max(0.0, a.seconds - t)))
    stop.set()
    for t in threads:
        t.join(15)
    if a.samples:
        with open(a.samples, "w") as f:
            for t, r in samples:
                f.write(f"{t:.1f} {r}\n")
    return report(a, samples, counts.c, died)


def report(a, samples, c, died):
    mib = lambda k: k / 1024.0  # noqa: E731
    if not samples:
        print("soak: no samples (the server died at once)")
        return 1
    start = samples[0]
    one = min(samples, key=lambda s: abs(s[0] - 60.0))
    peak = max(samples, key=lambda s: s[1])
    end = samples[-1]
    half = end[0] / 2
    first = max(r for t, r in samples if t <= half)
    second = [r for t, r in samples if t > half]
    second_max = max(second) if second else first
    allowed = first + max(8 * 1024, 0.10 * first)
    flat = second_max <= allowed
    print(f"soak: {a.scene} on {a.backend} at {a.size}, {end[0]:.0f} s, {len(samples)} samples "
          f"every {a.every:g} s")
    print(f"  RSS start {mib(start[1]):.1f} MiB, after 1 min (t={one[0]:.0f} s) "
          f"{mib(one[1]):.1f} MiB, largest {mib(peak[1]):.1f} MiB (t={peak[0]:.0f} s), "
          f"end {mib(end[1]):.1f} MiB")
    print(f"  largest of the first half {mib(first):.1f} MiB, of the second half "
          f"{mib(second_max):.1f} MiB (flat if at most {mib(allowed):.1f} MiB): "
          f"{'flat' if flat else 'GROWING'}")
    print(f"  reconnecting client: {c['connects']} connections, {c['pictures']} pictures; "
          f"slow client that reads nothing for {a.stall:g} s: {c['slow_connects']} "
          f"connections, {c['slow_dropped']} dropped by the server; client errors {c['errors']}"
          + ("; THE SERVER DIED" if died else ""))
    print(json.dumps({"seconds": end[0], "rss_kib": {"start": start[1], "one_min": one[1],
                      "max": peak[1], "end": end[1], "first_half_max": first,
                      "second_half_max": second_max}, "flat": flat, "died": died, **c}))
    if a.check and (died or not flat or c["pictures"] == 0):
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
