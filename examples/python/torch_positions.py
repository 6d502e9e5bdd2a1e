"""PyTorch reading the particle positions on the GPU every frame, without a copy.

    python examples/python/torch_positions.py [--scene scenes/dam_break.toml] [--frames 30]

Each frame, torch.from_dlpack(sim.particles.x_device) wraps the simulation's own GPU memory as
a CUDA tensor (no transfer), and the statistics below run on the GPU. The device arrays are in
the GPU's storage order (it changes every step): id_device maps each row to its particle, used
here to follow the particles that start highest. Needs the CUDA backend and PyTorch.
"""

import argparse
import pathlib
import sys

import rtmpm

ROOT = pathlib.Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default=ROOT / "scenes" / "dam_break.toml")
    ap.add_argument("--frames", type=int, default=30)
    args = ap.parse_args()
    try:
        import torch
    except ImportError:
        sys.exit("this example needs PyTorch (pip install torch)")
    ok, why = rtmpm.cuda_available()
    if not ok:
        sys.exit(f"this example needs the CUDA backend: {why}")

    sim = rtmpm.Simulation(args.scene, backend="cuda")
    print(f"{sim.num_particles} particles on {sim.backend.name}")
    n = sim.num_particles
    # The 1% of particles that start highest, by original index.
    y0 = torch.from_numpy(sim.particles.x[:, 1]).cuda()
    top = torch.topk(y0, max(1, n // 100)).indices
    where = torch.empty(n, dtype=torch.long, device="cuda")  # original index -> device row
    for frame in sim.frames(args.frames):
        x = torch.from_dlpack(sim.particles.x_device)  # (n, 3) view, storage order
        ids = torch.from_dlpack(sim.particles.id_device).long()
        where[ids] = torch.arange(n, device="cuda")
        com = x.mean(0)
        spread = x.std(0)
        top_y = x[where[top], 1].mean()
        print(
            f"frame {frame:3d}  t = {sim.time:.3f} s  centre of mass ({com[0]:.3f}, {com[1]:.3f}, {com[2]:.3f})"
            f"  spread ({spread[0]:.3f}, {spread[1]:.3f}, {spread[2]:.3f})  top 1% at y = {top_y:.3f}"
        )


if __name__ == "__main__":
    main()
