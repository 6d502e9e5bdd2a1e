"""A spoon steered by a script: a kinematic rigid body moved frame by frame from Python.

    python examples/python/scripted_spoon.py                  # 60 frames (2 s)
    python examples/python/scripted_spoon.py --frames 5 --out /tmp/spoon.csv

A tank of water (a scene given as a dict) and a kinematic sphere, the spoon, which the script
drives round a circle at one turn per second with ``Simulation.set_rigid_body``: at each frame
it puts the spoon on the circle and gives it the velocity that reaches the next frame's point,
as a game would from its input. The water cannot push a kinematic body, but the body pushes the
water, which starts to swirl: each row of the CSV is a frame's time, the spoon's centre and the
water's angular momentum about the tank's vertical axis (kg m^2/s), which grows in the spoon's
sense of turning. Needs a module built with the ``rigid`` feature (docs/python.md).
"""

import argparse
import csv
import math
import pathlib
import sys

import numpy as np

import rtmpm

CENTRE = (0.3, 0.3)  # the tank's vertical axis (x, z), m
RADIUS = 0.12  # of the spoon's circle, m
TURNS_PER_SECOND = 1.0

SCENE = {
    "name": "scripted_spoon",
    "domain": {"min": [0.0, 0.0, 0.0], "max": [0.6, 0.45, 0.6], "dx": 0.025},
    "time": {"duration": 2.0, "fps": 30, "cfl": 0.4},
    "walls": {"thickness": 3, "condition": "slip"},
    "material": [{"name": "water", "type": "fluid", "density": 1000.0, "bulk_modulus": 4e4}],
    "body": [{"material": "water", "shape": "box", "min": [0.075, 0.075, 0.075], "max": [0.525, 0.2, 0.525]}],
    "rigid_body": [
        {"name": "spoon", "shape": "sphere", "center": [CENTRE[0] + RADIUS, 0.16, CENTRE[1]], "radius": 0.05,
         "density": 1000.0, "type": "kinematic", "condition": "sticky"}
    ],
}


def on_circle(t):
    """The spoon's centre at time t (s)."""
    a = 2.0 * math.pi * TURNS_PER_SECOND * t
    return (CENTRE[0] + RADIUS * math.cos(a), 0.16, CENTRE[1] + RADIUS * math.sin(a))


def swirl(sim):
    """The water's angular momentum about the tank's vertical axis (kg m^2/s), positive in the
    spoon's sense of turning (from +x towards +z)."""
    p = sim.particles
    rx, rz = p.x[:, 0] - CENTRE[0], p.x[:, 2] - CENTRE[1]
    return float(np.sum(p.mass * (rz * p.v[:, 0] - rx * p.v[:, 2])) * -1.0)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=None, help="frames to run (default: the whole scene)")
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--out", default="scripted_spoon.csv")
    args = ap.parse_args()
    if "rigid" not in rtmpm.features:
        sys.exit("this rtmpm module was built without rigid bodies: rebuild it with --features rigid (docs/python.md)")

    sim = rtmpm.Simulation(SCENE, backend=args.backend)
    print(f"{sim.num_particles} particles and a scripted spoon on {sim.backend}")
    frames = args.frames if args.frames is not None else sim.scene.frames
    rows = []
    for _ in range(frames):
        t0, t1 = sim.time, sim.time + sim.frame_duration
        a, b = on_circle(t0), on_circle(t1)
        velocity = [(b[k] - a[k]) / sim.frame_duration for k in range(3)]
        sim.set_rigid_body("spoon", position=a, velocity=velocity)
        sim.run_frame()
        (spoon,) = sim.rigid_bodies
        rows.append([sim.time, *spoon["position"], swirl(sim)])
        t, x, y, z, l = rows[-1]
        print(f"frame {sim.frame:3d}  t = {t:.3f} s  spoon ({x:.3f}, {y:.3f}, {z:.3f}) m  "
              f"water's angular momentum {l:+.4f} kg m^2/s")
    out = pathlib.Path(args.out)
    with open(out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "x_m", "y_m", "z_m", "angular_momentum_kg_m2_s"])
        w.writerows(rows)
    print(f"table written to {out}")


if __name__ == "__main__":
    main()
