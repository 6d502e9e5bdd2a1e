"""A tool pushed into N sand beds at once, and the force on it in each bed.

    python examples/python/batch_push.py                      # 8 beds, 0.5 s
    python examples/python/batch_push.py --worlds 3 --frames 4 --out /tmp/push.csv
    python examples/python/batch_push.py --plot batch_push.png    # + the forces plotted
    python examples/python/batch_push.py --backend cuda          # every bed in the same GPU kernels

One scene (a dict) with a ``[batch]`` of N worlds: each a bed of sand whose friction angle is
swept from 20 to 45 degrees, and a kinematic box, the tool, above it. Every step the script
poses the tool in every world at once (``BatchSimulation.set_rigid_body`` with one row per
world), as a robot's controller would: it presses down at 0.25 m/s to 5 cm deep, then drags
sideways at 0.25 m/s. After each frame it reads the force the sand puts on the tool in every
world (``BatchSimulation.rigid_force``, an ``(N, 3)`` array). Each CSV row is a frame's time, a
world, its friction angle, the tool's depth and the force (N): the steeper the friction angle,
the harder the sand resists the drag. ``--backend``: ``cpu`` (each bed a simulation of its
own), ``cuda`` (every bed in the same GPU kernels, each with its own tool pose and force) or
``auto`` (the default: the GPU when one is usable). Needs a module built with the ``rigid``
feature (docs/python.md); ``--plot`` needs matplotlib.
"""

import argparse
import csv
import pathlib
import sys

import numpy as np

import rtmpm

BED_TOP = 0.15  # m
TOOL_HALF = 0.03  # m
SPEED = 0.25  # m/s, down then sideways
DEPTH = 0.05  # m below the bed's top


def scene(worlds, duration):
    return {
        "name": "batch_push",
        "domain": {"min": [0.0, 0.0, 0.0], "max": [0.5, 0.36, 0.3], "dx": 0.02},
        "time": {"duration": duration, "fps": 50, "dt": 2e-4},
        "walls": {"thickness": 3, "condition": "sticky"},
        "material": [{"name": "sand", "type": "drucker_prager", "density": 1600.0, "youngs_modulus": 5e5,
                      "poisson_ratio": 0.3, "friction_angle": 30.0}],
        "body": [{"material": "sand", "shape": "box", "min": [0.06, 0.06, 0.06], "max": [0.44, BED_TOP, 0.24],
                  "particles_per_cell": 4}],
        "rigid_body": [{"name": "tool", "shape": "box", "type": "kinematic", "condition": "slip", "density": 1000.0,
                        "min": [0.12 - TOOL_HALF, BED_TOP + 0.01, 0.15 - TOOL_HALF],
                        "max": [0.12 + TOOL_HALF, BED_TOP + 0.01 + 2 * TOOL_HALF, 0.15 + TOOL_HALF]}],
        "batch": {"count": worlds, "sweep": {"material[0].friction_angle": {"from": 20.0, "to": 45.0}}},
    }


def tool_motion(t):
    """The tool's centre and velocity at time t: down to DEPTH, then sideways (+x)."""
    y0 = BED_TOP + 0.01 + TOOL_HALF
    y_end = BED_TOP - DEPTH + TOOL_HALF
    t_down = (y0 - y_end) / SPEED
    if t < t_down:
        return np.array([0.12, y0 - SPEED * t, 0.15]), np.array([0.0, -SPEED, 0.0])
    return np.array([0.12 + SPEED * (t - t_down), y_end, 0.15]), np.array([SPEED, 0.0, 0.0])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worlds", type=int, default=8, help="sand beds (default 8)")
    ap.add_argument("--frames", type=int, default=25, help="frames of 20 ms (default 25)")
    ap.add_argument("--out", type=pathlib.Path, default=pathlib.Path("batch_push.csv"))
    ap.add_argument("--plot", type=pathlib.Path, help="also plot the drag force per world (PNG; needs matplotlib)")
    ap.add_argument("--backend", default="auto", choices=["auto", "cpu", "cuda"],
                    help="cpu, cuda (every world in the same GPU kernels) or auto (default)")
    a = ap.parse_args()
    if "rigid" not in rtmpm.features:
        sys.exit("this example needs rtmpm built with the `rigid` feature (docs/python.md)")
    sim = rtmpm.Simulation(scene(a.worlds, a.frames / 50.0), backend=a.backend)
    angles = [float(label.split("=")[1]) for label in sim.labels]
    print(f"{len(sim)} sand beds of {int(sim.num_particles[0])} particles; {sim.backend}")
    rows = []
    reported = set()  # worlds whose freeze was printed
    steps_per_frame = round(1.0 / 50.0 / 2e-4)
    for frame in range(1, a.frames + 1):
        for _ in range(steps_per_frame):
            # Every world's tool at this step's pose and velocity (the same path in each here;
            # one row per world, so each could follow its own).
            pos, vel = tool_motion(float(sim.time[0]))
            sim.set_rigid_body("tool", position=np.tile(pos, (len(sim), 1)).astype(np.float32),
                               velocity=np.tile(vel, (len(sim), 1)).astype(np.float32))
            # On the GPU `step` returns with the step queued (`sim.overlap`, the default there):
            # a blow-up in it is returned by the next `step()`, or seen by reading `running`.
            for w in sim.step():
                reported.add(w)
                print(f"world {w} froze: {sim.status[w]['reason']}")
        force = sim.rigid_force("tool")
        for w in range(len(sim)):
            rows.append([f"{sim.time[w]:.4f}", w, angles[w], f"{BED_TOP - (pos[1] - TOOL_HALF):.4f}",
                         *(f"{c:.4f}" for c in force[w])])
        print(f"frame {frame}: drag force (N) per world: " + " ".join(f"{-f:.2f}" for f in force[:, 0]))
    # The last step's blow-up, which no later `step()` returns on the GPU: reading `running`
    # waits for that step's check.
    for w in np.flatnonzero(~sim.running):
        if int(w) not in reported:
            print(f"world {w} froze: {sim.status[w]['reason']}")
    with open(a.out, "w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["time", "world", "friction_angle", "depth", "fx", "fy", "fz"])
        out.writerows(rows)
    print(f"wrote {a.out} ({len(rows)} rows)")
    if a.plot:
        plot(rows, angles, a.plot)


def plot(rows, angles, path):
    """The drag force (-fx) on the tool against time, one line per world."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no plot")
        return
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=100)
    cmap = plt.get_cmap("viridis")
    for w, angle in enumerate(angles):
        mine = [r for r in rows if r[1] == w]
        ax.plot([float(r[0]) for r in mine], [-float(r[4]) for r in mine],
                color=cmap(w / max(1, len(angles) - 1)), label=f"{angle:.1f} deg")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("drag force on the tool (N)")
    ax.set_title(f"{len(angles)} sand beds at once: friction angle swept")
    ax.legend(fontsize=7, ncol=2, title="friction angle", title_fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    print(f"plot written to {path}")


if __name__ == "__main__":
    main()
