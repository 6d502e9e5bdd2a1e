"""An elastic bar started with a sinusoidal velocity, against the exact solution.

    python examples/python/vibrating_bar.py [--out bar.png]

validation/vibrating_bar.toml (Bardenhagen 2002): L = 25 m, E = 100 Pa, rho = 1 kg/m^3, fixed at
x = 0, free at x = L. The scene schema gives bodies uniform velocities; here Python sets
v(x, 0) = v0 sin(pi x / 2L) on every particle before the first step. The exact centre-of-mass
velocity is (2 v0 / pi) cos(w1 t), w1 = (pi / 2L) sqrt(E / rho): period 10 s.
"""

import argparse
import math
import pathlib

import numpy as np

import rtmpm

ROOT = pathlib.Path(__file__).resolve().parents[2]
L, V0, E, RHO = 25.0, 0.1, 100.0, 1.0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--out", default="vibrating_bar.png")
    args = ap.parse_args()

    sim = rtmpm.Simulation(ROOT / "validation" / "vibrating_bar.toml", backend=args.backend)
    x = sim.particles.x
    v = np.zeros_like(x)
    v[:, 0] = V0 * np.sin(math.pi / (2 * L) * x[:, 0])
    sim.particles.v = v  # the initial velocity field

    m = sim.particles.mass.astype(np.float64)
    t, vcom = [0.0], [float((m * v[:, 0]).sum() / m.sum())]
    for _ in sim.frames():
        t.append(sim.time)
        vcom.append(float((m * sim.particles.v[:, 0]).sum() / m.sum()))
    t, vcom = np.array(t), np.array(vcom)
    w1 = math.pi / (2 * L) * math.sqrt(E / RHO)
    exact = 2 * V0 / math.pi * np.cos(w1 * t)

    # Period from the zero crossings, amplitude from the peaks between them.
    s = np.sign(vcom)
    idx = np.nonzero(s[1:] * s[:-1] < 0)[0]
    cross = t[idx] - vcom[idx] * (t[idx + 1] - t[idx]) / (vcom[idx + 1] - vcom[idx])
    period = 2 * (cross[-1] - cross[0]) / (len(cross) - 1)
    bounds = np.concatenate([[-1.0], cross])
    amplitude = np.mean([np.abs(vcom[(t > a) & (t < b)]).max() for a, b in zip(bounds, bounds[1:])])
    print(f"{sim.num_particles} particles on {sim.backend.name}, {len(t) - 1} frames")
    print(f"period     {period:.4f} s   exact {2 * math.pi / w1:.4f} s   ({100 * (period * w1 / (2 * math.pi) - 1):+.2f} %)")
    print(f"amplitude  {amplitude:.5f} m/s exact {2 * V0 / math.pi:.5f} m/s ({100 * (amplitude * math.pi / (2 * V0) - 1):+.2f} %)")
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not installed: no plot")
        return
    plt.figure(figsize=(7, 4))
    plt.plot(t, exact, "k", label="exact")
    plt.plot(t, vcom, "r--", label="rtmpm")
    plt.xlabel("t (s)")
    plt.ylabel("centre-of-mass velocity (m/s)")
    plt.legend()
    plt.tight_layout()
    plt.savefig(args.out, dpi=120)
    print(f"plot written to {args.out}")


if __name__ == "__main__":
    main()
