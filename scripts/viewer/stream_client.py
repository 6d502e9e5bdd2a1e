#!/usr/bin/env python3
"""A client of `rtmpm view --serve` that measures the stream (Python's standard library only,
so it runs on machines without network access or extra packages).

It connects to ws://HOST:PORT/ws, reads for --seconds and prints, as one JSON line and a short
table: pictures received and per second, bytes per picture, the server's own figures from the
status of every picture (draw time, JPEG time, steps/s, particle-steps/s, the session's
displayed fps) as median and max, and the pictures the session drew but this client did not
get (latest-frame-wins drops them for a slow client).

--slow SECONDS makes it a slow client: it sleeps that long after every message (and asks for
a small socket receive buffer), so the server must drop pictures for it without slowing the
simulation. --rss-pid PID samples that process's resident memory (VmRSS) every --rss-every
seconds and reports first, last and largest: flat memory under a slow client.
--send JSON (repeatable) sends commands first, e.g. --send '{"cmd":"resume"}'.
--orbit N times the picture alone: it pauses the session, then turns the camera a little
after each status it receives, N times (one redraw each, no stepping between), and reports the
draw and JPEG times of those redraws; it ends after the N-th.
"""

import argparse
import base64
import json
import os
import socket
import statistics
import struct
import sys
import time


class WebSocket:
    """The client side of RFC 6455: text out (masked), text and binary in."""

    def __init__(self, host, port, path="/ws", rcvbuf=None, timeout=30.0):
        self.sock = socket.create_connection((host, port), timeout=timeout)
        if rcvbuf:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        key = base64.b64encode(os.urandom(16)).decode()
        req = (f"GET {path} HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
               f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
               "Sec-WebSocket-Version: 13\r\n\r\n")
        self.sock.sendall(req.encode())
        self.buf = b""
        head = self._until(b"\r\n\r\n")
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            raise RuntimeError("the server refused the WebSocket: " + head.decode(errors="replace"))

    def _until(self, marker):
        while marker not in self.buf:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise EOFError("connection closed")
            self.buf += chunk
        i = self.buf.index(marker) + len(marker)
        out, self.buf = self.buf[:i], self.buf[i:]
        return out

    def _exact(self, n):
        while len(self.buf) < n:
            chunk = self.sock.recv(max(65536, n - len(self.buf)))
            if not chunk:
                raise EOFError("connection closed")
            self.buf += chunk
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def send_text(self, text):
        data = text.encode()
        mask = os.urandom(4)
        n = len(data)
        if n < 126:
            head = struct.pack("!BB", 0x81, 0x80 | n)
        elif n < 65536:
            head = struct.pack("!BBH", 0x81, 0x80 | 126, n)
        else:
            head = struct.pack("!BBQ", 0x81, 0x80 | 127, n)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(data))
        self.sock.sendall(head + mask + masked)

    def recv(self):
        """The next message as ("text", str) or ("binary", bytes); ("close", code) at the end."""
        parts, kind = [], None
        while True:
            b0, b1 = self._exact(2)
            op, n = b0 & 0x0F, b1 & 0x7F
            if n == 126:
                n = struct.unpack("!H", self._exact(2))[0]
            elif n == 127:
                n = struct.unpack("!Q", self._exact(8))[0]
            mask = self._exact(4) if b1 & 0x80 else None
            data = self._exact(n)
            if mask:
                data = bytes(b ^ mask[i % 4] for i, b in enumerate(data))
            if op == 0x8:
                code = struct.unpack("!H", data[:2])[0] if len(data) >= 2 else 1005
                return "close", code
            if op == 0x9:  # ping: answer with a pong
                self.sock.sendall(struct.pack("!BB", 0x8A, 0x80 | len(data)) + b"\0\0\0\0" + data)
                continue
            if op == 0xA:
                continue
            if op in (0x1, 0x2):
                kind = "text" if op == 0x1 else "binary"
            parts.append(data)
            if b0 & 0x80:
                data = b"".join(parts)
                return kind, data.decode() if kind == "text" else data


def rss_kib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    return None


def med_max(xs):
    return (statistics.median(xs), max(xs)) if xs else (float("nan"), float("nan"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", default="127.0.0.1:8080", help="HOST:PORT of rtmpm view --serve")
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--slow", type=float, default=0.0, help="sleep after every message (s)")
    ap.add_argument("--send", action="append", default=[], help="a JSON command to send first")
    ap.add_argument("--rss-pid", type=int, help="sample this process's VmRSS")
    ap.add_argument("--rss-every", type=float, default=10.0)
    ap.add_argument("--label", default="", help="a name for this measurement in the output")
    ap.add_argument("--orbit", type=int, default=0, help="pause, then time N redraws")
    ap.add_argument("--timeout", type=float, default=120.0,
                    help="give up when nothing comes for this long (s)")
    args = ap.parse_args()
    host, port = args.url.rsplit(":", 1)
    ws = WebSocket(host, int(port), rcvbuf=16384 if args.slow else None, timeout=args.timeout)
    for c in args.send:
        ws.send_text(c)
    orbits = 0
    if args.orbit:
        ws.send_text('{"cmd":"pause"}')
    t0 = time.time()
    pictures, nbytes, statuses, rss = 0, 0, [], []
    first_seq = last_seq = None
    next_rss = t0
    closed = None
    while time.time() - t0 < args.seconds:
        if args.rss_pid and time.time() >= next_rss:
            rss.append((round(time.time() - t0, 1), rss_kib(args.rss_pid)))
            next_rss += args.rss_every
        kind, data = ws.recv()
        if kind == "close":
            closed = data
            break
        if kind == "binary":
            pictures += 1
            nbytes += len(data)
        else:
            m = json.loads(data)
            if m.get("type") == "status":
                if args.orbit and not m["paused"]:
                    continue
                m["_at"] = time.time()
                statuses.append(m)
                first_seq = m["seq"] if first_seq is None else first_seq
                last_seq = m["seq"]
                if args.orbit:
                    if orbits == args.orbit:
                        break
                    ws.send_text('{"cmd":"orbit","dx":4,"dy":0}')
                    orbits += 1
        if args.slow:
            time.sleep(args.slow)
    if args.rss_pid:
        rss.append((round(time.time() - t0, 1), rss_kib(args.rss_pid)))
    wall = time.time() - t0
    # With --orbit, the first status is the paused picture that was already drawn.
    s = statuses[1:] if args.orbit else statuses
    drawn = (last_seq - first_seq + 1) if s else 0
    # Simulated frames per second while this client listened (the frame counter of the first
    # and last status it got, over the time between them), and how many of those frames the
    # session drew and this client received: with a pace of one frame a picture, every
    # simulated frame is shown when both are 1.
    span = s[-1]["_at"] - s[0]["_at"] if len(s) > 1 else 0.0
    sim_frames = s[-1]["frame"] - s[0]["frame"] if len(s) > 1 else 0
    sim_fps = sim_frames / span if span > 0 else 0.0
    out = {
        "label": args.label,
        "seconds": round(wall, 2),
        "pictures": pictures,
        "pictures_per_s": round(pictures / wall, 2),
        "kib_per_picture": round(nbytes / max(pictures, 1) / 1024, 1),
        "session_pictures": drawn,
        "dropped_for_this_client": max(drawn - pictures, 0),
        "draw_ms": [round(x, 2) for x in med_max([x["render_ms"] for x in s])],
        "jpeg_ms": [round(x, 2) for x in med_max([x["encode_ms"] for x in s])],
        "session_fps": [round(x, 2) for x in med_max([x["fps"] for x in s])],
        "sim_frames_per_s": round(sim_fps, 2),
        "drawn_per_sim_frame": round((drawn - 1) / sim_frames, 3) if sim_frames > 0 else None,
        "received_per_sim_frame": round((len(s) - 1) / sim_frames, 3) if sim_frames > 0 else None,
        "steps_per_s": [round(x, 1) for x in med_max([x["steps_per_s"] for x in s])],
        "particle_steps_per_s": [float(f"{x:.3g}") for x in
                                 med_max([x["particle_steps_per_s"] for x in s])],
        "particles": s[-1]["particles"] if s else 0,
        "size": f"{s[-1]['width']}x{s[-1]['height']}" if s else "",
        "closed": closed,
    }
    if rss:
        kib = [r for _, r in rss if r is not None]
        out["rss_mib"] = {"first": round(kib[0] / 1024, 1), "last": round(kib[-1] / 1024, 1),
                          "max": round(max(kib) / 1024, 1)}
        out["rss_samples"] = rss
    print(json.dumps(out))
    print(f"{'':2}{args.label or 'stream'}: {pictures} pictures in {wall:.1f} s "
          f"({out['pictures_per_s']}/s, {out['kib_per_picture']} KiB each; the session drew "
          f"{drawn}, {out['dropped_for_this_client']} not sent to this client), draw "
          f"{out['draw_ms'][0]} ms, JPEG {out['jpeg_ms'][0]} ms (median), "
          f"{out['steps_per_s'][0]} steps/s, {out['sim_frames_per_s']} simulated frames/s",
          file=sys.stderr)
    if "rss_mib" in out:
        r = out["rss_mib"]
        print(f"{'':2}server memory: {r['first']} MiB at the start, {r['last']} MiB at the end, "
              f"{r['max']} MiB at most", file=sys.stderr)


if __name__ == "__main__":
    main()
