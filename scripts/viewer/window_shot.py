#!/usr/bin/env python3
"""Check a screenshot of an X server (the XWD file of `xwd -root`) for a window's picture: the
window's rectangle (X, Y, W, H from `xwininfo`) must hold a real picture, not an empty or
uniform one. Writes the rectangle as a PNG for people to look at. Standard library only.

    window_shot.py SHOT.xwd X Y W H --png OUT.png [--min-colours N]

Exit status 0 when the picture passes, 1 (with the reason) when it does not. The last line
printed is `digest HEX`, a hash of the rectangle's pixels, to tell whether two screenshots of
the window show the same picture.
"""

import argparse
import hashlib
import struct
import sys
import zlib


def read_xwd(path):
    """Width, height and a function giving the (r, g, b) of pixel (x, y) of an XWD file of a
    TrueColor visual (what Xvfb's root window is)."""
    data = open(path, "rb").read()
    if len(data) < 100:
        raise ValueError(f"{path}: {len(data)} bytes, not an XWD file")
    h = struct.unpack(">25I", data[:100])
    (header_size, version, _fmt, _depth, width, height, _xoff, byte_order, _unit, _bit_order,
     _pad, bpp, bytes_per_line, visual_class, red_mask, green_mask, blue_mask, _bits_per_rgb,
     _entries, ncolors) = h[:20]
    if version != 7:
        raise ValueError(f"{path}: XWD version {version}, expected 7")
    if visual_class not in (4, 5) or bpp not in (24, 32):
        raise ValueError(f"{path}: visual class {visual_class}, {bpp} bits a pixel: not TrueColor")
    start = header_size + 12 * ncolors
    pixels = data[start:start + bytes_per_line * height]
    if len(pixels) < bytes_per_line * height:
        raise ValueError(f"{path}: truncated ({len(pixels)} of {bytes_per_line * height} bytes)")
    step = bpp // 8
    order = "little" if byte_order == 0 else "big"

    def shift(mask):
        s = 0
        while mask and not mask & 1:
            mask >>= 1
            s += 1
        return s

    shifts = [(m, shift(m)) for m in (red_mask, green_mask, blue_mask)]

    def rgb(x, y):
        o = y * bytes_per_line + x * step
        v = int.from_bytes(pixels[o:o + step], order)
        return tuple(((v & m) >> s) & 0xFF for m, s in shifts)

    return width, height, rgb


def write_png(path, w, h, rows):
    """An 8-bit RGB PNG of `rows` (h lists of w (r, g, b))."""
    raw = b"".join(b"\x00" + bytes(c for p in row for c in p) for row in rows)

    def chunk(kind, body):
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))

    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))
    open(path, "wb").write(png)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("xwd")
    ap.add_argument("x", type=int)
    ap.add_argument("y", type=int)
    ap.add_argument("w", type=int)
    ap.add_argument("h", type=int)
    ap.add_argument("--png", required=True)
    ap.add_argument("--min-colours", type=int, default=50)
    a = ap.parse_args()
    width, height, rgb = read_xwd(a.xwd)
    x0, y0 = max(a.x, 0), max(a.y, 0)
    x1, y1 = min(a.x + a.w, width), min(a.y + a.h, height)
    if x1 - x0 < 16 or y1 - y0 < 16:
        print(f"the window ({a.w}x{a.h} at {a.x},{a.y}) is not on the {width}x{height} screen")
        return 1
    rows = [[rgb(x, y) for x in range(x0, x1)] for y in range(y0, y1)]
    write_png(a.png, x1 - x0, y1 - y0, rows)
    colours = {p for row in rows for p in row}
    black = sum(p == (0, 0, 0) for row in rows for p in row)
    n = (x1 - x0) * (y1 - y0)
    print(f"window {x1 - x0}x{y1 - y0} at {x0},{y0}: {len(colours)} colours, "
          f"{100.0 * black / n:.1f} % black; picture in {a.png}")
    digest = hashlib.sha256(b"".join(bytes(c for p in row for c in p) for row in rows))
    ok = True
    if len(colours) < a.min_colours:
        print(f"FAIL: {len(colours)} colours, at least {a.min_colours} expected: no picture")
        ok = False
    elif black > 0.5 * n:
        print("FAIL: the window is mostly black: no picture")
        ok = False
    print(f"digest {digest.hexdigest()[:16]}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
