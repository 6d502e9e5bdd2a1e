#!/usr/bin/env python3
"""Do small and near-neutral rigid spheres sink in water? A sweep of radius (in cells) and density.

For each density and radius, writes a copy of validation/archimedes.toml (dx = 0.02 m, 0.2 m of
still water) with its box replaced by a sphere whose centre starts at y = 0.3 m, runs
`rtmpm run` for `--duration` seconds without frame files, and reads the sphere's height from
bodies.csv. A sphere denser than water should come to rest on the floor (centre at 0.06 m plus
its radius); one that stops in mid-water instead is held by the coupling, which loads a body
through the grid nodes inside it (docs/scene-format.md, "Resolution of rigid bodies").

    python3 scripts/validation/small_bodies.py --rtmpm target/release/rtmpm \
        --densities 1200,1500,2500 --radii 0.5,0.75,1,1.5,2,2.5,3 --out /tmp/small
"""
import argparse, csv, os, re, subprocess, sys

HERE = os.path.dirname(os.path.abspath(__file__))
BASE = os.path.join(HERE, "..", "..", "validation", "archimedes.toml")
FLOOR = 0.06  # the walls' inner node plane (3 cells of 0.02 m)


def scene(text, density, radius, duration, damping):
    t = re.sub(r"(?m)^duration = .*$", f"duration = {duration}", text)
    if damping is not None:
        t = re.sub(r"(?m)^damping = .*$", f"damping = {damping}", t)
    head = t.split("[[rigid_body]]")[0]
    return head + (
        "[[rigid_body]]\nname = \"sphere\"\nshape = \"sphere\"\ncenter = [0.3, 0.3, 0.3]\n"
        f"radius = {radius:.9g}\ndensity = {density}\ncondition = \"separate\"\n\n"
        "[output]\nformats = []\n"
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rtmpm", default="target/release/rtmpm")
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--densities", default="1200,1500,2500")
    ap.add_argument("--radii", default="0.5,0.75,1,1.5,2,2.5,3", help="in cells of dx")
    ap.add_argument("--duration", type=float, default=2.0)
    ap.add_argument("--damping", type=float, help="the scene's time.damping (archimedes: 4)")
    ap.add_argument("--out", default="target/small-bodies")
    a = ap.parse_args()
    text = open(BASE).read()
    dx = float(re.search(r"(?m)^dx = (.*)$", text).group(1))
    rows = []
    for density in [float(v) for v in a.densities.split(",")]:
        for rc in [float(v) for v in a.radii.split(",")]:
            r = rc * dx
            d = os.path.join(a.out, f"d{density:g}_r{rc:g}")
            os.makedirs(d, exist_ok=True)
            path = os.path.join(d, "sphere.toml")
            with open(path, "w") as f:
                f.write(scene(text, density, r, a.duration, a.damping))
            cmd = [a.rtmpm, "run", path, "--backend", a.backend, "--out", os.path.join(d, "out"),
                   "--overwrite"]
            p = subprocess.run(cmd, capture_output=True, text=True)
            if p.returncode != 0:
                sys.exit(f"{' '.join(cmd)} failed:\n{p.stderr}")
            with open(os.path.join(d, "out", "bodies.csv")) as f:
                ys = [float(row["y"]) for row in csv.DictReader(f)]
            rest = FLOOR + r
            # Descent over the second half of the run: a sphere that has not reached the floor
            # and went down less than half a cell in that time is held.
            descent = ys[len(ys) // 2] - ys[-1]
            state = "floor" if ys[-1] < rest + 0.25 * dx else (
                "held" if descent < 0.5 * dx else "sinking")
            # Excess weight over the weight of water a layer of x cells thick over its surface
            # would have: |s - 1| V / (A dx) for a sphere is |s - 1| r / (3 dx).
            layer = abs(density / 1000.0 - 1.0) * rc / 3.0
            rows.append((density, rc, ys[-1], rest, descent, layer, state))
            print(f"density {density:g} radius {rc:g} dx: y = {ys[-1]:.4f} m "
                  f"(floor rest {rest:.4f}), descent {descent * 1000:.2f} mm "
                  f"in the second half: {state}", flush=True)
    print("\n| density | radius (cells) | \\|s - 1\\| V / (A dx) | final y (m) | on the floor at (m) "
          "| descent over the second half (mm) | state |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for density, rc, y, rest, descent, layer, state in rows:
        print(f"| {density:g} | {rc:g} | {layer:.3f} | {y:.4f} | {rest:.4f} | "
              f"{descent * 1000:.1f} | {state} |")


if __name__ == "__main__":
    main()
