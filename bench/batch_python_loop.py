"""What a Python step loop costs a batch: per-world tool poses and resets every step.

    python bench/batch_python_loop.py [--worlds 64] [--steps 40] [--resets 2] [--repeats 5]

A batch of ``--worlds`` small worlds (a bed of sand, about 1,000 particles, and a kinematic box,
the tool, pressing into it), on the CPU backend. Two ways to take the same number of steps,
all timed in turn in the same process (each repeat builds a fresh batch, set-up not timed):

  bare    ``sim.step(steps)``: one call, no Python between the steps
  loop    every step from Python, as a learning environment drives it: the tool posed in every
          world (``set_rigid_body`` with one row per world: position and velocity), ``--resets``
          worlds (a different few each step) put back to their initial state with ``reset``,
          then ``sim.step()``
  step    and pose: the parts of loop (``sim.step()`` alone each step; the poses and the step)

Both do the same physics work per step (a reset world starts again from time 0 with as many
particles), so the difference is the Python loop's overhead: the calls, the argument
conversions, the resets' new backends and each call's read-back of the particles. Prints the
process CPU seconds (user + system, all threads: the figure to read on a shared machine) and
the wall seconds of each, min / median / max over the repeats, and loop / bare of the medians.
Needs a module built with the ``rigid`` feature (docs/python.md).
"""

import argparse
import statistics
import sys
import time

import numpy as np

import rtmpm

BED_TOP = 0.15  # m
HALF = 0.03  # m, the tool's half size
SPEED = 0.2  # m/s, downwards


def scene(worlds):
    return {
        "name": "python_loop",
        "seed": 1,
        "domain": {"min": [0.0, 0.0, 0.0], "max": [0.4, 0.35, 0.4], "dx": 0.025},
        "time": {"duration": 1.0, "fps": 50, "dt": 4e-4},
        "walls": {"thickness": 3, "condition": "sticky"},
        "material": [{"name": "sand", "type": "drucker_prager", "density": 1600.0, "youngs_modulus": 5e5,
                      "poisson_ratio": 0.3, "friction_angle": 35.0}],
        "body": [{"material": "sand", "shape": "box", "min": [0.1, 0.1, 0.1], "max": [0.3, BED_TOP, 0.3],
                  "particles_per_cell": 8}],
        "rigid_body": [{"name": "tool", "shape": "box", "type": "kinematic", "condition": "slip", "density": 1000.0,
                        "min": [0.2 - HALF, BED_TOP + 0.04, 0.2 - HALF],
                        "max": [0.2 + HALF, BED_TOP + 0.04 + 2 * HALF, 0.2 + HALF]}],
        "batch": {"count": worlds},
    }


def bare(sim, steps):
    sim.step(steps)


def loop(sim, steps, resets, pose=True):
    n = len(sim)
    vel = np.tile(np.array([0.0, -SPEED, 0.0], np.float32), (n, 1))
    pos = np.empty((n, 3), np.float32)
    for s in range(steps):
        if pose:
            t = sim.time  # (N,) each world's time: reset worlds run behind
            pos[:, 0] = 0.2
            pos[:, 1] = BED_TOP + 0.04 + HALF - SPEED * t
            pos[:, 2] = 0.2
            sim.set_rigid_body("tool", position=pos, velocity=vel)
        if resets:
            sim.reset([(s * resets + k) % n for k in range(resets)])
        sim.step()


MODES = {
    "bare": "sim.step(steps), one call",
    "step": "sim.step() from Python each step, nothing else",
    "pose": "each step: the tool posed in every world, then sim.step()",
    "loop": "each step: the tool posed in every world, a few worlds reset, then sim.step()",
}


def run_mode(mode, sim, steps, resets):
    if mode == "bare":
        bare(sim, steps)
    else:
        loop(sim, steps, resets if mode == "loop" else 0, pose=mode != "step")


def timed(fn):
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def summary(xs):
    return f"{min(xs):.3f} / {statistics.median(xs):.3f} / {max(xs):.3f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worlds", type=int, default=64)
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--resets", type=int, default=2, help="worlds reset every step (default 2)")
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    if "rigid" not in rtmpm.features:
        sys.exit("this benchmark needs rtmpm built with the `rigid` feature (docs/python.md)")
    one = rtmpm.Scene.from_dict(scene(a.worlds))
    times = {m: [] for m in MODES}
    particles = 0
    for r in range(a.repeats + 1):  # the first round warms up, not counted
        for mode in list(MODES) if r % 2 == 0 else list(MODES)[::-1]:
            sim = rtmpm.Simulation(one, backend="cpu")
            particles = int(sim.num_particles.sum())
            t = timed(lambda: run_mode(mode, sim, a.steps, a.resets))
            if r > 0:
                times[mode].append(t)
    print(f"{a.worlds} worlds, {particles} particles, {a.steps} steps, {a.resets} resets a step, "
          f"{a.repeats} repeats; min / median / max")
    med = {m: statistics.median(c for c, _ in times[m]) for m in times}
    medw = {m: statistics.median(w for _, w in times[m]) for m in times}
    for mode, what in MODES.items():
        cpu = [c for c, _ in times[mode]]
        wall = [w for _, w in times[mode]]
        print(f"{mode:5s} cpu s {summary(cpu)}, wall s {summary(wall)}; / bare: cpu "
              f"{med[mode] / med['bare']:.3f}, wall {medw[mode] / medw['bare']:.3f}  ({what})")


if __name__ == "__main__":
    main()
