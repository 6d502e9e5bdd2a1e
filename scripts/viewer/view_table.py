#!/usr/bin/env python3
"""The short table that ends the `view` suite of scripts/gpu/run.sh: the live view's figures
for each scene, against the targets of the live view (docs/viewer.md). Standard library only.

    view_table.py OUT SCENE [SCENE...]

For each SCENE it reads, in OUT (files the suite wrote; a missing one leaves its rows blank):
  view_SCENE_render.txt       the last line of render_bench (`render_bench NAME: n=... frame_off_ms=...`)
  view_SCENE_off.txt          ms/step of `rtmpm bench` on the same scene (the viewer off)
  view_SCENE_fast_client.log  scripts/viewer/stream_client.py's JSON line, a fast client
  view_SCENE_memory_client.log   the same, a slow client over a longer time (memory)
  view_SCENE_memory_gpu_memory.csv  nvidia-smi's `pid, used_memory` samples of the server

Rows: the simulation's frame time without pictures; the render stage's picture (kernels and
copy, CUDA events) as a share of it (target: at most 10 %); the frame time with a picture every
frame; the stream's simulated frames/s, pictures received/s and pictures per simulated frame
(target: every frame shown, so 1.0, at >= 60 fps where the simulation runs that fast); the
session's draw and JPEG times per picture; the step time with the viewer on (the session's
steps/s) against off (target: at most +10 %); the server's memory over the slow client's run.
"""

import json
import os
import re
import sys


def read(path):
    try:
        with open(path) as f:
            return f.read()
    except OSError:
        return None


def client(path):
    """The JSON line of a stream_client log, or None."""
    text = read(path)
    for line in (text or "").splitlines():
        if line.startswith("{"):
            try:
                return json.loads(line)
            except ValueError:
                return None
    return None


def render_line(text):
    """key=value pairs of render_bench's last line, as floats where they are numbers."""
    out = {}
    for line in (text or "").splitlines():
        if line.startswith("render_bench "):
            for k, v in re.findall(r"(\w+)=([-0-9.e+]+)", line):
                out[k] = float(v)
    return out


def gpu_memory(path):
    mib = []
    for line in (read(path) or "").splitlines():
        m = re.search(r",\s*([0-9.]+)\s*MiB", line)
        if m:
            mib.append(float(m.group(1)))
    return mib


def fmt(x, spec=".2f", unit=""):
    return "-" if x is None else f"{x:{spec}}{unit}"


def column(out, sc):
    r = render_line(read(os.path.join(out, f"view_{sc}_render.txt")))
    off_text = (read(os.path.join(out, f"view_{sc}_off.txt")) or "").strip()
    off = float(off_text) if re.fullmatch(r"[0-9.]+", off_text) else None
    fast = client(os.path.join(out, f"view_{sc}_fast_client.log"))
    mem = client(os.path.join(out, f"view_{sc}_memory_client.log"))
    gpu = gpu_memory(os.path.join(out, f"view_{sc}_memory_gpu_memory.csv"))
    c = {}
    c["particles"] = fmt(r.get("n"), ".0f")
    c["frame off (ms)"] = fmt(r.get("frame_off_ms"), ".2f")
    pic = next((v for k, v in r.items() if k.startswith("picture_") and k.endswith("_ms")), None)
    share = r.get("share_of_frame")
    c["picture 1280x720 (ms)"] = fmt(pic, ".3f")
    c["picture / frame (<=10%)"] = fmt(share, ".1f", " %")
    on = r.get("frame_on_ms")
    cost = r.get("viewer_cost")
    c["frame + picture (ms)"] = "-" if on is None else f"{on:.2f} ({cost:+.1f} %)"
    if fast:
        c["sim frames/s (stream)"] = fmt(fast.get("sim_frames_per_s"), ".1f")
        c["pictures/s received"] = fmt(fast.get("pictures_per_s"), ".1f")
        c["drawn / sim frame (1.0)"] = fmt(fast.get("drawn_per_sim_frame"), ".3f")
        c["received / sim frame"] = fmt(fast.get("received_per_sim_frame"), ".3f")
        c["draw + JPEG (ms)"] = f"{fast['draw_ms'][0]:.2f} + {fast['jpeg_ms'][0]:.2f}"
        sps = fast["steps_per_s"][0]
        step_on = 1000.0 / sps if sps and sps > 0 else None
        c["step on / off (ms)"] = f"{fmt(step_on, '.4f')} / {fmt(off, '.4f')}"
        c["viewer on (<=+10%)"] = ("-" if step_on is None or off is None
                                   else f"{100 * (step_on / off - 1):+.1f} %")
    if mem and "rss_mib" in mem:
        m = mem["rss_mib"]
        c[f"host MiB over {mem['seconds']:.0f} s"] = f"{m['first']:.0f} > {m['last']:.0f} (max {m['max']:.0f})"
        c["slow client: got / drawn"] = f"{mem['pictures']} / {mem['session_pictures']}"
    if gpu:
        c["GPU MiB (first > last)"] = f"{gpu[0]:.0f} > {gpu[-1]:.0f} (max {max(gpu):.0f})"
    return c


def main():
    if len(sys.argv) < 3:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        return 2
    out, scenes = sys.argv[1], sys.argv[2:]
    cols = [column(out, sc) for sc in scenes]
    rows = []
    for c in cols:
        rows += [k for k in c if k not in rows]
    width = max([len(r) for r in rows] + [10]) + 2
    cw = [max([len(sc)] + [len(c.get(r, "-")) for r in rows]) + 2 for sc, c in zip(scenes, cols)]
    print("view table (CUDA, 1280x720)".ljust(width) + "".join(sc.rjust(w) for sc, w in zip(scenes, cw)))
    for r in rows:
        print(r.ljust(width) + "".join(c.get(r, "-").rjust(w) for c, w in zip(cols, cw)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
