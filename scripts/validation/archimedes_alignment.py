#!/usr/bin/env python3
"""Archimedes at several grid spacings and alignments of the water surface with the grid.

For each grid spacing dx and raise r (a fraction of dx), writes a copy of
validation/archimedes.toml with that dx (walls kept 0.06 m thick) and with the water's top and
the box's start raised by r * dx, runs `rtmpm validate --quick --case archimedes --scenes <copy>`
(the copy's own dx), and prints the submerged fractions of the boxes of density 250, 500 and 750
against the density ratios, then the mean and the spread over the raises.

    python3 scripts/validation/archimedes_alignment.py --rtmpm target/release/rtmpm \
        --backend cuda --dx 0.01,0.005 --raises 0,0.25,0.5,0.75 --out /tmp/arch
"""
import argparse, os, re, subprocess, sys, time

HERE = os.path.dirname(os.path.abspath(__file__))
BASE = os.path.join(HERE, "..", "..", "validation", "archimedes.toml")


def variant(text, dx, r, duration=None):
    """The scene at grid spacing dx, water top and box raised by r * dx (and run for `duration`
    seconds instead of the scene's)."""
    lift = r * dx
    t = re.sub(r"(?m)^dx = .*$", f"dx = {dx}", text)
    if duration:
        t = re.sub(r"(?m)^duration = .*$", f"duration = {duration}", t)
    t = re.sub(r"(?m)^thickness = .*$", f"thickness = {round(0.06 / dx)}", t)
    # the water body: max = [x, y, z]; the rigid body: min and max.
    def raise_y(m, amount):
        x, y, z = (float(v) for v in m.group(2).split(","))
        return f"{m.group(1)}[{x}, {y + amount:.9g}, {z}]"
    head, body = t.split("[[body]]")
    water, rest = body.split("[[rigid_body]]")
    water = re.sub(r"(?m)^(max = )\[([^\]]*)\]", lambda m: raise_y(m, lift), water)
    rest = re.sub(r"(?m)^((?:min|max) = )\[([^\]]*)\]", lambda m: raise_y(m, lift), rest)
    return head + "[[body]]" + water + "[[rigid_body]]" + rest


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rtmpm", default="target/release/rtmpm")
    ap.add_argument("--base", default=BASE, help="the scene to vary (validation/archimedes.toml)")
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--dx", default="0.02")
    ap.add_argument("--raises", default="0,0.25,0.5,0.75")
    ap.add_argument("--out", default="target/archimedes-alignment")
    ap.add_argument("--extra", default="", help="more arguments for rtmpm validate")
    ap.add_argument("--duration", type=float, help="seconds simulated (the scene's: 1.5)")
    a = ap.parse_args()
    text = open(a.base).read()
    rows = []
    for dx in [float(v) for v in a.dx.split(",")]:
        for r in [float(v) for v in a.raises.split(",")]:
            d = os.path.join(a.out, f"dx{dx}_r{r}")
            os.makedirs(d, exist_ok=True)
            with open(os.path.join(d, "archimedes.toml"), "w") as f:
                f.write(variant(text, dx, r, a.duration))
            cmd = [a.rtmpm, "validate", "--backend", a.backend, "--quick", "--case", "archimedes",
                   "--scenes", d, "--out", os.path.join(d, "out")] + a.extra.split()
            t0 = time.time()
            p = subprocess.run(cmd, capture_output=True, text=True)
            with open(os.path.join(d, "validate.log"), "w") as f:
                f.write(p.stdout + p.stderr)
            fr, vol = {}, {}
            for m in re.finditer(r"submerged fraction, density (\d+), dx = \S+\s+[\d.]+\s+([\d.]+)", p.stdout):
                fr[int(m.group(1))] = float(m.group(2))
            for m in re.finditer(r"submerged volume fraction, density (\d+) \(mean tilt ([\d.]+) deg\)\s+[\d.]+\s+([\d.]+)", p.stdout):
                vol[int(m.group(1))] = (float(m.group(3)), float(m.group(2)))
            if vol:
                print(f"dx {dx} raise {r}: volume fraction (mean tilt) "
                      + " ".join(f"{k}: {v:.4f} ({100 * (v / (k / 1000) - 1):+.1f} %, {t:.1f} deg)"
                                 for k, (v, t) in sorted(vol.items())), flush=True)
            print(f"dx {dx} raise {r}: rc {p.returncode} {time.time() - t0:.0f} s "
                  + " ".join(f"{k}: {v:.4f}" for k, v in sorted(fr.items())), flush=True)
            rows.append((dx, r, fr))
    print("\n| dx | raise | density 250 | density 500 | density 750 |\n| --- | --- | --- | --- | --- |")
    for dx, r, fr in rows:
        cells = [f"{fr[k]:.4f} ({100 * (fr[k] / (k / 1000) - 1):+.1f} %)" if k in fr else "-" for k in (250, 500, 750)]
        print(f"| {dx} | {r} | " + " | ".join(cells) + " |")
    for dx in sorted({r[0] for r in rows}, reverse=True):
        sel = [fr for d, _, fr in rows if d == dx]
        out = []
        for k in (250, 500, 750):
            v = [fr[k] for fr in sel if k in fr]
            if v:
                out.append(f"{k}: mean {sum(v) / len(v):.4f} ({100 * (sum(v) / len(v) / (k / 1000) - 1):+.1f} %), spread {max(v) - min(v):.4f}, worst {max(abs(x / (k / 1000) - 1) for x in v) * 100:.1f} %")
        print(f"dx {dx}: " + "; ".join(out))


if __name__ == "__main__":
    sys.exit(main())
