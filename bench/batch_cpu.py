"""Many small worlds on the CPU: batched, one after another, or as one big scene.

    python bench/batch_cpu.py MODE [--worlds N] [--frames F]

MODE is one of
  batched     rtmpm.Simulation(scene, batch=N): the N worlds stepped together, frame by frame
  sequential  N separate rtmpm.Simulation objects, each run to the end before the next starts
  big         one scene holding the N sand beds side by side in one domain (one grid)

Each world is a small bed of sand (about 2,000 particles) on a sticky floor with a fixed time
step, so all three modes take the same steps of the same particles (the big scene's beds are the
worlds' beds moved apart in one domain). Prints the particle-steps per second of the stepping
alone (set-up excluded, measured inside the process with time.perf_counter); time the whole
process from outside for the set-up included (bench/RESULTS.md gives the commands).
"""

import argparse
import time

import rtmpm

DX = 0.025
BED = (0.2, 0.1, 0.2)  # m
GAP = 0.1  # m between beds of the big scene


def scene(beds, frames):
    """`beds` beds side by side along x in one domain (1: a world of the batch)."""
    width = beds * BED[0] + (beds + 1) * GAP
    bodies = []
    for b in range(beds):
        x0 = GAP + b * (BED[0] + GAP)
        bodies.append({"material": "sand", "shape": "box", "min": [x0, 0.1, GAP],
                       "max": [x0 + BED[0], 0.1 + BED[1], GAP + BED[2]], "particles_per_cell": 8})
    return {
        "name": f"beds_{beds}",
        "seed": 1,
        "domain": {"min": [0.0, 0.0, 0.0], "max": [width, 0.4, BED[2] + 2 * GAP], "dx": DX},
        "time": {"duration": frames / 50.0, "fps": 50, "dt": 4e-4},
        "walls": {"thickness": 3, "condition": "sticky"},
        "material": [{"name": "sand", "type": "drucker_prager", "density": 1600.0, "youngs_modulus": 5e5,
                      "poisson_ratio": 0.3, "friction_angle": 35.0}],
        "body": bodies,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["batched", "sequential", "big"])
    ap.add_argument("--worlds", type=int, default=16)
    ap.add_argument("--frames", type=int, default=5)
    a = ap.parse_args()
    one = rtmpm.Scene.from_dict(scene(1, a.frames))
    if a.mode == "batched":
        sims = [rtmpm.Simulation(one, batch=a.worlds, backend="cpu")]
        particles = int(sims[0].num_particles.sum())
    elif a.mode == "sequential":
        sims = [rtmpm.Simulation(one, backend="cpu") for _ in range(a.worlds)]
        particles = sum(s.num_particles for s in sims)
    else:
        sims = [rtmpm.Simulation(rtmpm.Scene.from_dict(scene(a.worlds, a.frames)), backend="cpu")]
        particles = sims[0].num_particles
    t0 = time.perf_counter()
    for s in sims:
        s.run(a.frames)
    seconds = time.perf_counter() - t0
    steps = round(a.frames / 50.0 / 4e-4)
    rate = particles * steps / seconds
    print(f"{a.mode}: {a.worlds} worlds, {particles} particles, {steps} steps in {seconds:.3f} s: "
          f"{rate / 1e6:.3f} M particle-steps/s")


if __name__ == "__main__":
    main()
