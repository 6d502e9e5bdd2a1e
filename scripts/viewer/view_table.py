#!/usr/bin/env python3
"""The short table that ends the `view` suite of scripts/gpu/run.sh: the live view's figures
for each scene, against the targets of the live view (docs/viewer.md). Standard library only.

    view_table.py OUT SCENE [SCENE...]

For each SCENE it reads, in OUT (files the suite wrote; a missing one leaves its rows blank):
  view_SCENE_render.txt        the last line of render_bench (`render_bench NAME: n=... frame_off_ms=...`)
  view_SCENE_steps.txt         scripts/viewer/view_cost.sh's runs over the same frames 2..N:
                               `off ms_per_step=...` (rtmpm bench), `noclient|client|nooverlap
                               ms_per_step=... view_timing ...` (rtmpm view --serve to frame N)
  view_SCENE_client_client.log scripts/viewer/stream_client.py's JSON line of the client run

Rows: the simulation's frame time without pictures; the render stage's picture (kernels and
copy, CUDA events) as a share of it (target: at most 10 %); the frame time with a picture every
frame; the stream's simulated frames/s, pictures received/s and pictures per simulated frame
(target: every frame shown, so 1.0, at >= 60 fps where the simulation runs that fast); the
session's draw and JPEG times per picture; the step time with the view on against `rtmpm
bench` over the same frames (target: at most +10 % with a client watching), without a client,
and without the overlap of pictures and steps; where the host's time per picture went.
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


def steps_runs(text):
    """{label: {key: value}} of view_cost.sh's lines (`LABEL key=value ...`)."""
    runs = {}
    for line in (text or "").splitlines():
        parts = line.split()
        if not parts:
            continue
        kv = {}
        for k, v in re.findall(r"(\w+)=([-0-9.e+]+|nan)", line):
            try:
                kv[k] = float(v)
            except ValueError:
                pass
        runs[parts[0]] = kv
    return runs


def fmt(x, spec=".2f", unit=""):
    return "-" if x is None else f"{x:{spec}}{unit}"


def step_rows(c, runs):
    """The view on against off over the same frames, and the host's time per picture."""
    off = runs.get("off", {}).get("ms_per_step")
    if off is None or off != off:
        off = None
    c["frames timed (steps)"] = fmt(runs.get("off", {}).get("steps"), ".0f")
    c["bench ms/step (view off)"] = fmt(off, ".4f")
    for label, row in [("noclient", "view, no client"), ("client", "view + client (<=+10%)"),
                       ("nooverlap", "view + client, no overlap")]:
        ms = runs.get(label, {}).get("ms_per_step")
        if ms is None or ms != ms:
            continue
        vs = "" if off is None else f" ({100 * (ms / off - 1):+.1f} %)"
        c[row + " ms/step"] = f"{ms:.4f}{vs}"
    t = runs.get("client", {})
    if "begin_ms" in t:
        c["stepping (ms/step, client)"] = fmt(t.get("step_ms_per_step"), ".4f")
        c["picture begin/finish/publish ms"] = (
            f"{t['begin_ms']:.2f}/{t['finish_ms']:.2f}/{t['present_ms']:.2f}")
        c["pictures overlapped"] = f"{t.get('overlapped', 0):.0f}/{t.get('pictures', 0):.0f}"


def column(out, sc):
    r = render_line(read(os.path.join(out, f"view_{sc}_render.txt")))
    fast = client(os.path.join(out, f"view_{sc}_client_client.log"))
    runs = steps_runs(read(os.path.join(out, f"view_{sc}_steps.txt")))
    c = {}
    c["particles"] = fmt(r.get("n"), ".0f")
    c["frame off (ms)"] = fmt(r.get("frame_off_ms"), ".2f")
    pic = next((v for k, v in r.items() if k.startswith("picture_") and k.endswith("_ms")), None)
    share = r.get("share_of_frame")
    c["picture 1280x720 (ms)"] = fmt(pic, ".3f")
    m = re.search(r"kernels ([0-9.]+) copy ([0-9.]+)",
                  read(os.path.join(out, f"view_{sc}_render.txt")) or "")
    if m:
        c["render / readback (events, ms)"] = f"{float(m.group(1)):.3f} / {float(m.group(2)):.3f}"
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
    step_rows(c, runs)
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
