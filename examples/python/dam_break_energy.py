"""Dam break with its energy per frame: kinetic, potential and their sum, plotted.

    python examples/python/dam_break_energy.py                 # the whole run (45 frames)
    python examples/python/dam_break_energy.py --frames 5 --out /tmp/energy.png

The water column (scenes/dam_break.toml) falls and sloshes: potential energy turns into kinetic
energy, which the fluid and the separating walls then dissipate, so the total only decreases.
The plot needs matplotlib; without it the table is printed and written as CSV.
"""

import argparse
import pathlib

import numpy as np

import rtmpm

ROOT = pathlib.Path(__file__).resolve().parents[2]


def energies(sim, g):
    p = sim.particles
    m, x, v = p.mass.astype(np.float64), p.x.astype(np.float64), p.v.astype(np.float64)
    kinetic = 0.5 * float((m * (v**2).sum(1)).sum())
    potential = -float((m * (x @ g)).sum())  # -m g.x: m |g| y for gravity along -y
    return kinetic, potential


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=ROOT / "scenes" / "dam_break.toml")
    ap.add_argument("--frames", type=int, default=None, help="frames to run (default: the whole scene)")
    ap.add_argument("--backend", default="auto")
    ap.add_argument("--out", default="dam_break_energy.png", help="plot (PNG); the CSV goes next to it")
    args = ap.parse_args()

    sim = rtmpm.Simulation(args.scene, backend=args.backend)
    print(f"{sim.num_particles} particles on {sim.backend}")
    g = np.array(sim.scene.gravity, dtype=np.float64)
    rows = [(sim.time, *energies(sim, g))]
    for frame in sim.frames(args.frames):
        rows.append((sim.time, *energies(sim, g)))
        t, k, u = rows[-1]
        print(f"frame {frame:3d}  t = {t:.3f} s  kinetic {k:9.3f} J  potential {u:9.3f} J  total {k + u:9.3f} J")
    data = np.array(rows)
    data[:, 2] -= data[0, 2]  # potential relative to the start
    out = pathlib.Path(args.out)
    np.savetxt(out.with_suffix(".csv"), data, delimiter=",", header="t_s,kinetic_J,potential_J", comments="")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib not installed: table written to {out.with_suffix('.csv')}")
        return
    t, k, u = data.T
    plt.figure(figsize=(7, 4))
    plt.plot(t, k, label="kinetic")
    plt.plot(t, u, label="potential (from t = 0)")
    plt.plot(t, k + u, label="total", color="k")
    plt.xlabel("t (s)")
    plt.ylabel("energy (J)")
    plt.title(f"Dam break, {sim.num_particles} particles ({sim.backend.name})")
    plt.legend()
    plt.tight_layout()
    plt.savefig(out, dpi=120)
    print(f"plot written to {out}")


if __name__ == "__main__":
    main()
